//! Lightmaps in bounded memory (`--memory-limit`). A whole lightmap bake holds every texel's
//! transfer as one image from the rays to the file; a 2048² map of 4 bands in colour is 805 MB
//! of it. Here no stage holds more than a part of it:
//!
//! - the covered texels bake a chunk at a time, each chunk's transfer appended to a scratch
//!   file ([`crate::bake::spill`]) and let go; with `--fit least-squares`, so do the fit's
//!   points ([`HeldPoints`]);
//! - the clean-up — denoising, dilation, the wide leaks put back, seam stitching or the
//!   least-squares fit — runs a group of coefficients at a time on an image of that group
//!   alone, read from the scratch file. Every one of these stages treats each coefficient on
//!   its own with weights that do not depend on the values (the denoiser's are the guide's,
//!   the dilation's the mask's, the stitching's and the fit's matrices the seams' and the
//!   points' taps), so a group gives the bits the whole image gives;
//! - each group's finished image goes back to the scratch file, and the OpenEXR encoder reads
//!   the map from there a block of scan lines at a time ([`HeldLightmap`] is its
//!   [`TexelRows`]).
//!
//! What every texel keeps throughout is its receiver, its flags, its chart and the denoiser's
//! guide: about a hundred bytes, whatever the bands.

use std::borrow::Cow;
use std::fmt;
use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::Vec3;

use super::fit::{run_points, write_by_group, HeldPoints};
use super::{
    chart_owners, denoise_guide, seam_anchors, texel_receivers, TexelReport, TexelSites,
    DILATION_PASSES,
};
use crate::bake::spill::Spill;
use crate::bake::stream::{format_bytes, gather_row_bytes, MemoryNeed, MIN_CHUNK};
use crate::bake::{
    bake_at_in_chunks, Backend, BakeOptions, Fit, Mode, Progress, TexelBake, Transfer,
};
use crate::bvh::Bvh;
use crate::error::{Error, Result};
use crate::lightmap::{LightmapShape, TexelRows};
use crate::receivers::atlas::Atlas;
use crate::receivers::dilation::plan_dilation;
use crate::receivers::texel_fit::TexelSystem;
use crate::receivers::texels::TexelPoints;
use crate::receivers::Receivers;
use crate::receivers::{seams, texel_fit};
use crate::scene::Scene;
use crate::sh;

/// A lightmap's finished texels, waiting in a scratch file a group of coefficients at a time:
/// group `g`'s image (`[texel row-major][column of the group]`, f32) from `offsets[g]`. Its
/// clones read the same file.
#[derive(Clone)]
pub struct HeldLightmap {
    /// The map as read: its bands those kept ([`HeldLightmap::truncated`]).
    shape: LightmapShape,
    /// Bands of the texels in the file.
    stored_bands: u32,
    /// Each group's columns of a texel's `[channel][k]` values as stored.
    groups: Vec<Range<usize>>,
    offsets: Vec<u64>,
    file: Arc<Mutex<Spill>>,
}

impl HeldLightmap {
    pub fn shape(&self) -> LightmapShape {
        self.shape
    }

    /// The map cut to its first `bands` bands (`--bands auto`), when it is read.
    pub fn truncated(&self, bands: u32) -> HeldLightmap {
        HeldLightmap {
            shape: LightmapShape {
                bands: bands.min(self.stored_bands),
                ..self.shape
            },
            ..self.clone()
        }
    }
}

impl fmt::Debug for HeldLightmap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("HeldLightmap")
            .field("shape", &self.shape)
            .field("groups", &self.groups)
            .finish_non_exhaustive()
    }
}

/// Held lightmaps are equal where they read the same file as the same shape.
impl PartialEq for HeldLightmap {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.file, &other.file) && self.shape == other.shape
    }
}

impl TexelRows for HeldLightmap {
    fn shape(&self) -> LightmapShape {
        self.shape
    }

    fn read_rows(&self, rows: Range<usize>) -> Result<Cow<'_, [f32]>> {
        let width = self.shape.width as usize;
        let stored = LightmapShape {
            bands: self.stored_bands,
            ..self.shape
        };
        let stride = stored.stride();
        let texels = rows.len() * width;
        let mut values = vec![0.0f32; texels * stride];
        let mut file = self.file.lock().expect("no reader panics holding the file");
        let mut part = Vec::new();
        // A group holding none of the kept bands' coefficients is not read.
        let (count, kept) = (
            sh::coeff_count(self.stored_bands),
            sh::coeff_count(self.shape.bands),
        );
        let holds_kept = |columns: &Range<usize>| columns.clone().any(|c| c % count < kept);
        for (columns, &offset) in self.groups.iter().zip(&self.offsets) {
            if !holds_kept(columns) {
                continue;
            }
            let group = columns.len();
            part.resize(texels * group, 0.0f32);
            let at = offset + (rows.start * width * group * 4) as u64;
            file.read_at(at, &mut part)?;
            for (texel, from) in values
                .chunks_exact_mut(stride)
                .zip(part.chunks_exact(group))
            {
                texel[columns.clone()].copy_from_slice(from);
            }
        }
        if self.shape.bands == self.stored_bands {
            return Ok(Cow::Owned(values));
        }
        // Each channel's first coefficients: those of the bands kept.
        Ok(Cow::Owned(
            values
                .chunks_exact(count)
                .flat_map(|channel| channel[..kept].iter().copied())
                .collect(),
        ))
    }
}

/// How a lightmap bake in bounded memory divides its work: texels baked at once, and
/// coefficients (columns of a texel's `[channel][k]`) cleaned up at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TexelGroups {
    pub chunk: usize,
    pub columns: usize,
}

/// [`super::bake_atlas`] in bounded memory (see the module's notes): the same texels, bit for
/// bit, held in a scratch file rather than in memory ([`TexelBake::held`]).
pub fn bake_atlas_held(
    (scene, vertex_transfer, atlas): (&Scene, &Transfer, &Atlas),
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
    divided: TexelGroups,
) -> Result<(TexelBake, TexelReport)> {
    let started = Instant::now();
    let TexelSites {
        texels,
        receivers,
        bvh,
        leaking,
        cover,
    } = texel_receivers(scene, atlas);
    let turned = options.clone().with_turns(options.denoise);
    let casting = Instant::now();
    let stride = 3 * sh::coeff_count(options.bands);
    let groups: Vec<Range<usize>> = (0..stride)
        .step_by(divided.columns.max(1))
        .map(|first| first..stride.min(first + divided.columns.max(1)))
        .collect();
    let baked = bake_in_chunks(
        (scene, vertex_transfer),
        (&receivers, bvh),
        (&turned, backend, progress),
        (&leaking, divided.chunk, &groups),
    )?;
    let transfer_seconds = casting.elapsed().as_secs_f64();
    let valid = texels.valid_mask(&leaking)?;
    let guide = options.denoise.then(|| {
        let dc = |i: usize, _| Vec3::from_array(baked.dc[i]);
        denoise_guide((atlas, &texels, &receivers), dc, options, &valid)
    });
    // The receivers are let go once they have guided the denoiser.
    drop(receivers);
    let owner = chart_owners(atlas, &texels);
    let anchor = seam_anchors(atlas, &texels, &valid);
    let seams = seams::seams(scene, atlas);
    let cleanup = Cleanup {
        atlas,
        texels: &texels,
        valid: &valid,
        owner: &owner,
        anchor: &anchor,
        seams: &seams,
        guide: guide.as_ref(),
        bands: options.bands,
    };
    // A least-squares map's points bake once the texels have (their receivers let go), and
    // each group's clean-up fits that group to them.
    let points = match options.fit {
        Fit::LeastSquares => {
            let at = (scene, vertex_transfer, atlas);
            let with = (backend, progress);
            Some(HeldPoints::bake(
                at,
                cover,
                &turned,
                with,
                (divided.chunk, &groups),
            )?)
        }
        Fit::Point => None,
    };
    let fitted = points.as_ref().map(|p| p.baked);
    let (held, rays_cast) = cleanup.run((baked, points), &groups, (backend, progress))?;
    let rays_cast = rays_cast + fitted.map_or(0, |f| f.rays_cast);
    let transfer_seconds = transfer_seconds + fitted.map_or(0.0, |f| f.transfer_seconds);
    let texels_of = (scene, atlas, &texels);
    let report = TexelReport {
        fit_points: fitted.map(|f| f.points),
        ..TexelReport::of(texels_of, (&seams, &leaking), options.denoise, rays_cast)
    }
    .timed(transfer_seconds, started);
    let texels = TexelBake {
        width: atlas.width,
        height: atlas.height,
        texcoords: super::atlas_texcoords(atlas),
        set: 0,
        transfer: Transfer::new(options.bands, 3, 0, Vec::new()).expect("no texels in memory"),
        held: Some(held),
    };
    Ok((texels, report))
}

/// The covered texels' transfer as baked, in a scratch file a group of coefficients after
/// another (group `columns` from `covered * columns.start` values in: `[texel][column of the
/// group]` in covered order), so that each group's clean-up reads its own values alone; with
/// what the clean-up needs of it beside.
struct BakedTexels {
    file: Spill,
    /// Each covered texel's first coefficient of each channel, for the denoiser's guide (empty
    /// when the bake is not denoised).
    dc: Vec<[f32; 3]>,
    /// The values as baked of the texels flagged as leaking, by covered index.
    leaks: Vec<(usize, Vec<f32>)>,
    rays_cast: u64,
}

fn bake_in_chunks(
    (scene, vertex_transfer): (&Scene, &Transfer),
    at: (&Receivers, Bvh),
    (options, backend, progress): (&BakeOptions, &dyn Backend, &dyn Progress),
    (leaking, chunk, groups): (&[bool], usize, &[Range<usize>]),
) -> Result<BakedTexels> {
    let covered = at.0.len();
    let mut baked = BakedTexels {
        file: Spill::new()?,
        dc: Vec::with_capacity(if options.denoise { covered } else { 0 }),
        leaks: Vec::new(),
        rays_cast: 0,
    };
    let per_channel = sh::coeff_count(options.bands);
    let stride = 3 * per_channel;
    let mut block: Vec<f32> = Vec::new();
    baked.rays_cast = bake_at_in_chunks(
        scene,
        at,
        (options, backend, Some(vertex_transfer)),
        (progress, chunk),
        &mut |first, transfer| {
            for (i, values) in (first..).zip(transfer.coeffs().chunks_exact(stride)) {
                if options.denoise {
                    baked.dc.push([0, 1, 2].map(|c| values[c * per_channel]));
                }
                if leaking[i] {
                    baked.leaks.push((i, values.to_vec()));
                }
            }
            let values = (transfer.coeffs(), stride);
            write_by_group(
                &mut baked.file,
                (covered, first),
                values,
                groups,
                &mut block,
            )
        },
    )?;
    Ok(baked)
}

/// What the clean-up of every group shares: the atlas and its texels, the texels valid as
/// baked, their charts, anchors, seams and the denoiser's guide.
struct Cleanup<'a> {
    atlas: &'a Atlas,
    texels: &'a TexelPoints,
    valid: &'a [bool],
    owner: &'a [u32],
    anchor: &'a [f32],
    seams: &'a [seams::Seam],
    guide: Option<&'a crate::receivers::denoise::DenoiseGuide>,
    bands: u32,
}

impl Cleanup<'_> {
    /// Every group of `groups` cleaned up in turn (a stage of `progress`, a step a
    /// coefficient), its image written after the texels as baked; the held lightmap and the
    /// rays the texels cast. With a least-squares fit's `points`, each group is fitted to
    /// them, its seams pulled together in the same solve, where it would be stitched.
    fn run(
        &self,
        (mut baked, points): (BakedTexels, Option<HeldPoints>),
        groups: &[Range<usize>],
        (backend, progress): (&dyn Backend, &dyn Progress),
    ) -> Result<(HeldLightmap, u64)> {
        let stride = groups.last().map_or(0, |g| g.end);
        let (width, height) = (self.atlas.width, self.atlas.height);
        let texel_count = width as usize * height as usize;
        let rows = seams::seam_rows(width, height, self.seams);
        let mut seams_solve = match points {
            Some(points) => SeamSolve::Fitted(points.system(self.anchor, &rows), points),
            None => SeamSolve::Stitched(seams::Stitching::new(&rows, self.anchor)),
        };
        // Which texels dilation fills, and from which, depends on the mask alone.
        let mut dilated = self.valid.to_vec();
        let dilation = plan_dilation((width, height), &mut dilated, self.owner, DILATION_PASSES);
        progress.stage("clean-up", stride as u64);
        let mut offsets = Vec::with_capacity(groups.len());
        let mut end = (self.texels.texels.len() * stride * 4) as u64;
        for columns in groups {
            let group = columns.len();
            let mut image = self.group_as_baked(&mut baked, columns.clone())?;
            if let Some(guide) = self.guide {
                image = backend.denoise(guide, &image, group)?;
            }
            dilation.apply(&mut image, group);
            for (i, values) in &baked.leaks {
                let (x, y) = self.texels.texels[*i];
                let at = y as usize * width as usize + x as usize;
                if !dilated[at] {
                    image[at * group..(at + 1) * group].copy_from_slice(&values[columns.clone()]);
                }
            }
            match &mut seams_solve {
                SeamSolve::Stitched(stitching) => {
                    stitching.solve((width, height), (&mut image, group), &mut |_| {});
                }
                SeamSolve::Fitted(system, points) => {
                    let sums = points.sums(columns.clone())?;
                    system.solve((&mut image, group), &sums, &mut |_| {});
                }
            }
            baked.file.write_at(end, &image)?;
            offsets.push(end);
            end += (texel_count * group * 4) as u64;
            progress.advance(group as u64);
        }
        let held = HeldLightmap {
            shape: LightmapShape {
                width,
                height,
                bands: self.bands,
                channels: 3,
            },
            stored_bands: self.bands,
            groups: groups.to_vec(),
            offsets,
            file: Arc::new(Mutex::new(baked.file)),
        };
        Ok((held, baked.rays_cast))
    }

    /// The image of coefficients `columns` as baked: each covered texel's values from the
    /// scratch file, zero elsewhere.
    fn group_as_baked(&self, baked: &mut BakedTexels, columns: Range<usize>) -> Result<Vec<f32>> {
        let group = columns.len();
        let width = self.atlas.width as usize;
        let covered = &self.texels.texels;
        let mut image = vec![0.0f32; width * self.atlas.height as usize * group];
        let mut block = vec![0.0f32; READ_TEXELS * group];
        let start = covered.len() * columns.start;
        for first in (0..covered.len()).step_by(READ_TEXELS) {
            let count = READ_TEXELS.min(covered.len() - first);
            let values = &mut block[..count * group];
            baked
                .file
                .read_at(((start + first * group) * 4) as u64, values)?;
            for (&(x, y), texel) in covered[first..].iter().zip(values.chunks_exact(group)) {
                let at = y as usize * width + x as usize;
                image[at * group..(at + 1) * group].copy_from_slice(texel);
            }
        }
        Ok(image)
    }
}

/// How a group's clean-up ends: its seams stitched, or (least squares) its texels fitted to
/// the points, the seams pulled together in the same solve.
enum SeamSolve<'a> {
    Stitched(seams::Stitching<'a>),
    Fitted(TexelSystem, HeldPoints),
}

/// Covered texels read back from the scratch file at a time.
const READ_TEXELS: usize = 4096;

/// What a lightmap adds to a bake's need ([`MemoryNeed::with_lightmap`]): baked whole, its
/// texels and image; held ([`bake_atlas_held`]), what every texel keeps and the larger of one
/// chunk's bake and one group's image (the chunk sized to the group's room).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightmapNeed {
    /// Texels of the map (covered or not; the map is at most `size` on a side).
    pub texels: u64,
    /// Values of a texel: every coefficient of every channel.
    pub stride: u64,
    /// What every texel keeps while it is held: its receiver (position, ray start, normal,
    /// albedo), its place and surface point, its flags (leaking, valid, and valid again for
    /// each group), chart, anchor and first coefficients, and the denoiser's guide.
    pub per_texel_held: u64,
    /// What a group's image costs a texel and a coefficient: the image, its denoised copy, the
    /// dilation's averages, and the seam solve's vectors for the texels on seams.
    pub per_texel_column: u64,
    /// What each texel costs while its chunk bakes: its albedo-free and RGB transfer (and,
    /// interreflected, its gather row and what it gathers).
    pub per_chunk_texel: u64,
    /// With `--fit least-squares`, what its points and solve add.
    pub fit: Option<HeldFitNeed>,
}

/// What a least-squares fit adds to a held lightmap (`fit::HeldPoints`): while its points bake
/// (a run's receivers at a time, in the texels' chunks) what each keeps and what each of a run
/// costs; through the clean-up, their taps and the fit's system, and for each coefficient of a
/// group its sums and, for those solved at once, its solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldFitNeed {
    pub points: u64,
    pub per_point_baking: u64,
    pub per_run_point: u64,
    pub kept: u64,
    pub per_column: u64,
    pub per_solved_column: u64,
}

impl LightmapNeed {
    /// Held, cleaned up `columns` coefficients at a time (and baked in chunks no larger).
    pub fn held(&self, columns: u64) -> u64 {
        let columns = columns.min(self.stride);
        let chunk_texels = self.chunk(columns);
        let chunk = chunk_texels as u64 * self.per_chunk_texel;
        let cleaning = self.texels * columns * self.per_texel_column;
        let (baking, cleaning) = match self.fit {
            None => (chunk, cleaning),
            Some(fit) => {
                let in_flight = rayon::current_num_threads().clamp(1, seams::GROUPS_IN_FLIGHT);
                let solved = columns.min((in_flight * seams::COLUMNS) as u64);
                let fitting = fit.kept + fit.per_column * columns + fit.per_solved_column * solved;
                let run = (run_points(chunk_texels) as u64).min(fit.points);
                // Each point's place and taps, the map's texel numbering, a run's receivers.
                let points =
                    fit.points * fit.per_point_baking + self.texels * 4 + run * fit.per_run_point;
                (chunk + points, cleaning + fitting)
            }
        };
        self.texels * self.per_texel_held + baking.max(cleaning)
    }

    /// The texels baked at once beside a clean-up of `columns` coefficients: as many as its
    /// image's room holds, between [`MIN_CHUNK`] and [`crate::bake::GATHER_CHUNK`].
    pub fn chunk(&self, columns: u64) -> usize {
        let room = self.texels * columns.min(self.stride) * self.per_texel_column;
        let chunk = room / self.per_chunk_texel.max(1);
        (chunk as usize).clamp(MIN_CHUNK, crate::bake::GATHER_CHUNK)
    }
}

/// What fitting the texels of a map of `texels` takes beside its image
/// ([`crate::receivers::texel_fit`], `coeffs` a channel, `gather` a receiver's interreflected
/// gather), at the largest of its peaks, beside the texels' sums of the points' values. While
/// the points bake: each point's place, surface point, receiver, flags and taps, and a
/// chunk's transfer. While the solve's matrix is built from the taps: the taps and each
/// texel's stencil (nine weights and neighbours), anchor and diagonal. While it solves: the
/// stencils and the five vectors of `seams::COLUMNS` coefficients a texel of each group in
/// flight. The texels the fit reads are counted as [`FIT_SHARE`] of the map, four points each.
fn fit_need(texels: u64, coeffs: u64, gather: u64) -> u64 {
    let (fitted, points) = fit_counts(texels);
    let sums = fitted * 12 * coeffs;
    let chunk =
        points.min(crate::bake::GATHER_CHUNK as u64) * (4 * coeffs + 2 * 12 * coeffs + gather);
    let baking = points * POINT_BAKING + chunk;
    let stencils = fitted * STENCIL;
    let building = points * 32 + stencils;
    let groups = rayon::current_num_threads().clamp(1, seams::GROUPS_IN_FLIGHT);
    let solving = stencils + fitted * (groups * 5 * seams::COLUMNS * 8) as u64;
    sums + baking.max(building).max(solving)
}

/// What a held least-squares fit of a map of `texels` adds ([`HeldFitNeed`]): while its points
/// bake, each point's place and taps, and a run's surface points, receivers (and their copy
/// in the bake's inputs) and flags; through the clean-up, the taps, the system's stencils and
/// the map's two texel numberings; a coefficient's sums a texel it reads, and its solve's five
/// vectors.
fn held_fit_need(texels: u64) -> HeldFitNeed {
    let (fitted, points) = fit_counts(texels);
    HeldFitNeed {
        points,
        per_point_baking: 24 + 32 + 4,
        per_run_point: 16 + (24 + 48 + 24) + 24 + 1,
        kept: points * (32 + 4) + fitted * STENCIL + texels * 2 * 4,
        per_column: fitted * 4,
        per_solved_column: fitted * 5 * 8,
    }
}

/// The texels a least-squares fit of a map of `texels` reads, at most, and its points.
fn fit_counts(texels: u64) -> (u64, u64) {
    let fitted = (FIT_SHARE * texels as f64) as u64;
    let points = (texel_fit::POINTS_PER_SIDE * texel_fit::POINTS_PER_SIDE) as u64 * fitted;
    (fitted, points)
}

/// What a fit point costs while the points bake: its place and surface point, its receiver
/// (position, ray start, normal), its flags and taps.
const POINT_BAKING: u64 = 24 + 16 + (24 + 48 + 24) + 5 + 32;

/// What a texel of the fit's system costs: nine weights and neighbours, its anchor and diagonal.
const STENCIL: u64 = 9 * 8 + 9 * 4 + 16;

/// The share of a map's texels a least-squares fit reads, at most: the charts cover 55–87%
/// of the generated atlases measured (docs/performance.md), and the fit reads a ring past
/// their edges.
const FIT_SHARE: f64 = 0.8;

impl MemoryNeed {
    /// The need with a lightmap of at most `size` x `size` texels (`options` the bake's).
    /// Whole, at the larger of its two peaks: while its texels bake (each texel a receiver, as
    /// a fitted point is, with its transfer; interreflected, one chunk's gather rows at a time,
    /// [`crate::bake::GATHER_CHUNK`]) and while it is written (the image in f32; the encoder
    /// takes a block of scan lines at a time and writes it to the file), beside the per-texel
    /// flags and chart labels of the clean-up. Held, as [`LightmapNeed`] counts it.
    pub fn with_lightmap(self, size: u32, options: &BakeOptions) -> MemoryNeed {
        let coeffs = sh::coeff_count(options.bands) as u64;
        let texels = size as u64 * size as u64;
        let baking = 24 + 48 + 24 + 4 * coeffs + 12 * coeffs;
        let writing = 12 * coeffs;
        let gather = match options.mode {
            Mode::Interreflected => gather_row_bytes(options) + 24 * coeffs,
            _ => 0,
        };
        // Interreflected, one chunk's gather rows and the bounce they gather.
        let gathering = texels.min(crate::bake::GATHER_CHUNK as u64) * gather;
        let guide = if options.denoise { 36 } else { 0 };
        let lightmap = LightmapNeed {
            texels,
            stride: 3 * coeffs,
            per_texel_held: 48 + 24 + 3 + 4 + 4 + 12 + guide + 16,
            // The image and, denoised, its filtered copy; the seam solve's six f64 vectors
            // for the texels on seams (a sixth of a dragon's 1024² map; a quarter counted).
            per_texel_column: 4 + if options.denoise { 4 } else { 0 } + (6 * 8) / 4,
            per_chunk_texel: 4 * coeffs + 2 * 12 * coeffs + gather,
            fit: (options.fit == Fit::LeastSquares).then(|| held_fit_need(texels)),
        };
        let fitting = match options.fit {
            Fit::LeastSquares => texels * (writing + 16) + fit_need(texels, coeffs, gather),
            Fit::Point => 0,
        };
        let texel_peak = (texels * (baking.max(writing) + 16) + gathering).max(fitting);
        MemoryNeed {
            beside_vertices: self.beside_vertices + texel_peak,
            lightmap: Some(lightmap),
            ..self
        }
    }

    /// The need of a bake whose lightmap is held, cleaned up `columns` coefficients at a time.
    /// A least-squares fit at the vertices (its points, their values, its solve; whole, or a
    /// run of points at a time where [`MemoryNeed::fit_run`] says) is let go before the texels
    /// bake, so the larger of the two counts.
    pub fn lightmap_held(&self, columns: u64) -> u64 {
        let Some(lightmap) = self.lightmap else {
            return self.whole();
        };
        self.beside_lightmap() + self.vertex_fit().max(lightmap.held(columns))
    }

    /// What a bake holds through its lightmap's: all but the lightmap and the vertices' fit.
    pub fn beside_lightmap(&self) -> u64 {
        self.beside_fit() - self.beside_vertices
    }

    /// A least-squares fit's at the vertices, whole or in runs (0 without one).
    fn vertex_fit(&self) -> u64 {
        self.fit.map_or(0, |fit| match self.fit_run {
            Some(run) => fit.chunked(run),
            None => fit.whole(),
        })
    }

    /// The most coefficients a held lightmap may clean up at once within `limit` bytes, and
    /// its chunk; or the error that says how much one coefficient at a time needs.
    pub fn texel_groups_within(&self, limit: u64) -> Result<TexelGroups> {
        let Some(lightmap) = self.lightmap else {
            return Err(Error::Options("only a lightmap holds texels".into()));
        };
        if self.lightmap_held(1) > limit {
            let held = format!(
                "what each of the map's {} texels keeps {}, and the larger of a chunk's bake and \
                 one coefficient's image{} {}",
                lightmap.texels,
                format_bytes(lightmap.texels * lightmap.per_texel_held),
                match lightmap.fit {
                    Some(_) => ", with the least-squares fit's points or its solve",
                    None => "",
                },
                format_bytes(lightmap.held(1) - lightmap.texels * lightmap.per_texel_held)
            );
            let beside = match self.vertex_fit() {
                0 => held,
                fit => format!(
                    "and the larger of the vertices' least-squares fit {}{}, let go before the \
                     lightmap, and the lightmap's: {held}",
                    format_bytes(fit),
                    self.fit_run
                        .map_or(String::new(), |run| format!(" in runs of {run} points"))
                ),
            };
            return Err(Error::Options(format!(
                "--memory-limit {}: this bake needs at least {} with its lightmap held in a \
                 scratch file (the mesh, its BVH and its vertices' transfer {}, {beside})",
                format_bytes(limit),
                format_bytes(self.lightmap_held(1)),
                format_bytes(self.beside_lightmap()),
            )));
        }
        // Whole groups of the seam solve's columns where they fit: one walk over the seams
        // serves each group of `seams::COLUMNS`.
        let whole_groups = (1..=lightmap.stride / seams::COLUMNS as u64)
            .rev()
            .map(|groups| groups * seams::COLUMNS as u64);
        let columns = std::iter::once(lightmap.stride)
            .chain(whole_groups)
            .chain((1..seams::COLUMNS as u64).rev())
            .find(|&columns| self.lightmap_held(columns) <= limit)
            .unwrap_or(1);
        Ok(TexelGroups {
            chunk: lightmap.chunk(columns),
            columns: columns as usize,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::{bake_atlas, plan_atlas};
    use super::*;
    use crate::bake::backend::CpuBackend;
    use crate::bake::{bake, NoProgress};
    use crate::scene::builtin;

    /// The built-in scene's `size` lightmap baked in bounded memory, in chunks and groups of
    /// several sizes, against the whole bake: the same bits in every texel, the same report.
    fn held_is_whole(
        options: BakeOptions,
        (size, denoise, fit): (u32, bool, Fit),
        divisions: &[TexelGroups],
    ) {
        let (baked, _) =
            bake(builtin::default_scene(), &options, &CpuBackend, &NoProgress).unwrap();
        let atlas = plan_atlas(&baked.scene, size).unwrap();
        let options = BakeOptions {
            lightmap: Some(size),
            denoise,
            fit,
            ..options
        };
        let (whole, report) = bake_atlas(
            &baked.scene,
            &baked.transfer,
            &options,
            &atlas,
            &CpuBackend,
            &NoProgress,
        )
        .unwrap();
        let at = (&baked.scene, &baked.transfer, &atlas);
        if let Some(points) = report.fit_points {
            // Several runs of points in the smallest chunks.
            assert!(
                points > 2 * run_points(divisions[0].chunk),
                "{points} points"
            );
        }
        for &divided in divisions {
            let (held, held_report) =
                bake_atlas_held(at, &options, &CpuBackend, &NoProgress, divided).unwrap();
            assert_eq!(held.texcoords, whole.texcoords);
            let held = held.held.expect("held in the scratch file");
            assert_eq!(held.shape().width, whole.width);
            assert_eq!(held.shape().height, whole.height);
            let rows = held.read_rows(0..whole.height as usize).unwrap();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(
                bits(&rows) == bits(whole.transfer.coeffs()),
                "{divided:?}: the held texels differ from the whole bake's"
            );
            // Rows read in pieces are the same rows.
            let middle = whole.height as usize / 2;
            let top = held.read_rows(0..middle).unwrap();
            assert_eq!(bits(&top), bits(&rows[..top.len()]));
            let times = |r: &TexelReport| TexelReport {
                seconds: 0.0,
                transfer_seconds: 0.0,
                ..*r
            };
            assert_eq!(times(&held_report), times(&report), "{divided:?}");
        }
    }

    const DIVISIONS: [TexelGroups; 3] = [
        TexelGroups {
            chunk: 97,
            columns: 5,
        },
        TexelGroups {
            chunk: 1000,
            columns: 4,
        },
        TexelGroups {
            chunk: usize::MAX,
            columns: usize::MAX,
        },
    ];

    #[test]
    fn a_shadowed_lightmap_held_in_chunks_and_groups_is_the_whole_bake() {
        let options = BakeOptions {
            samples: 64,
            ..BakeOptions::default()
        };
        held_is_whole(options, (64, false, Fit::Point), &DIVISIONS);
    }

    /// Fitted by least squares, each group of coefficients fitted on its own to the points'
    /// values read back from their scratch file, with groups that split the solve's fours.
    #[test]
    fn a_least_squares_lightmap_held_is_the_whole_bake() {
        let options = BakeOptions {
            samples: 32,
            ..BakeOptions::default()
        };
        held_is_whole(options, (96, false, Fit::LeastSquares), &DIVISIONS);
    }

    #[test]
    fn an_interreflected_denoised_lightmap_held_is_the_whole_bake() {
        let options = BakeOptions {
            samples: 64,
            mode: Mode::Interreflected,
            bands: 3,
            ..BakeOptions::default()
        };
        held_is_whole(options, (48, true, Fit::Point), &DIVISIONS[..2]);
    }
}
