//! Per-texel transfer (lightmaps, as D3DX's per-texel PRT and the SH lightmaps of Godot and
//! Bakery): the texels of a generated atlas (`receivers::atlas`) baked as surface points, their
//! leaks marked, the map dilated (each texel from the chart it is nearest) so that bilinear
//! filtering never reads an unbaked texel, and its seams stitched (`receivers::seams`) or, with
//! `--fit least-squares`, the map fitted to points spread over its charts (`fit`).
//!
//! A texel whose rays mostly reach the back of a surface sits inside other geometry (a floor
//! under a wall, an intersecting box): its value would be dark and, filtered, bleed into the
//! texels around it. Such texels are marked invalid and refilled from their neighbours, as
//! lightmappers do against leaks.

use std::time::Instant;

use glam::{DVec2, Vec3};
use rayon::prelude::*;

use super::{bake_at_in, subsurface, Backend, BakeOptions, Progress, TexelBake, Transfer};
use crate::bvh::{Bvh, PointPath};
use crate::error::Result;
use crate::packet::{self, FanPacket, ALL_LANES, LANES};
use crate::ray::{offset_ray_origin, RAY_T_MAX};
use crate::receivers::atlas::{atlas_for_size, Atlas, GUTTER};
use crate::receivers::denoise::{texel_level, DenoiseGuide, NO_CHART};
use crate::receivers::face_normal;
use crate::receivers::texel_fit::Site;
use crate::receivers::texels::{
    bilinear_taps, dilate_by_owner, nearest_owner, rasterize, TexelPoints,
};
use crate::receivers::{seams, Receivers, SurfacePoint};
use crate::sampling::{cosine_hemisphere, SampleSet, VertexDirections};
use crate::scene::Scene;

mod fit;
mod held;

use fit::stitch_or_fit;
pub use held::{bake_atlas_held, HeldFitNeed, HeldLightmap, LightmapNeed, TexelGroups};

/// Rays per texel of the leak test.
pub const LEAK_RAYS: u32 = 16;

/// A texel leaks when more than this fraction of its leak-test rays hit back faces.
pub const LEAK_FRACTION: f32 = 0.5;

/// A texel's leak-test ray that hits any face nearer than this many texels counts as a leak
/// too: a sheet lying just above the texel's point covers it, whichever face the ray reports.
/// (The dragon scan holds double-sided fins, two triangles on the same three vertices with
/// opposite windings, folded flat onto a neighbour a few micrometres above it: a ray meets
/// both at one distance and the back-face count is a coin toss.) A tenth of a texel: a
/// quarter also took texels in the folds of the scan that no sheet covers, whose refilled
/// values raised the error at held-out points, plain and as seen (docs/performance.md).
pub const COVER_TEXELS: f32 = 0.1;

/// Dilation rings: well past the gutter (so that a bilinear footprint reaching past a chart's
/// edge reads filled texels), and enough to refill leaks from their valid neighbours; a leak
/// wider than this keeps its own (dark) values.
pub const DILATION_PASSES: u32 = 32 * GUTTER;

/// How firmly a texel dilation filled, or one baked at a point of its chart's edge, keeps its
/// value when seams are stitched, against 1 for a texel baked at its own centre.
pub const FILLED_ANCHOR: f32 = 0.01;

/// What the texel bake did, for the summary line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelReport {
    pub width: u32,
    pub height: u32,
    /// Texels some triangle covers (each baked once).
    pub covered: usize,
    /// Charts of the atlas, and its L2 stretch ([`Atlas::stretch`]: 1 where texels keep
    /// their shape on the surface).
    pub charts: usize,
    pub stretch: f64,
    /// Seam edges: surface edges on two charts ([`crate::receivers::seams`]).
    pub seams: usize,
    /// Covered texels found inside geometry and refilled from their neighbours.
    pub leaking: usize,
    /// Whether the texels were denoised (`receivers::denoise`).
    pub denoised: bool,
    /// Least-squares texels: the points they were fitted to
    /// ([`crate::receivers::texel_fit`]).
    pub fit_points: Option<usize>,
    pub rays_cast: u64,
    /// Seconds the texels' transfer took (their rays, and the gather where light bounces),
    /// of the stage's `seconds`.
    pub transfer_seconds: f64,
    pub seconds: f64,
}

impl TexelReport {
    /// What a bake of `texels` on `atlas` did: its seams and `leaking` texels, whether it
    /// `denoised`, the rays it cast; its times not yet stated.
    fn of(
        (scene, atlas, texels): (&Scene, &Atlas, &TexelPoints),
        (seams, leaking): (&[seams::Seam], &[bool]),
        denoised: bool,
        rays_cast: u64,
    ) -> TexelReport {
        TexelReport {
            width: atlas.width,
            height: atlas.height,
            covered: texels.texels.len(),
            charts: atlas.chart_count(),
            seams: seams.len(),
            stretch: atlas.stretch(scene),
            leaking: leaking.iter().filter(|&&l| l).count(),
            denoised,
            fit_points: None,
            rays_cast,
            transfer_seconds: 0.0,
            seconds: 0.0,
        }
    }

    /// The report with its rays' seconds, and the seconds since the bake `started`.
    fn timed(self, transfer_seconds: f64, started: Instant) -> TexelReport {
        TexelReport {
            transfer_seconds,
            seconds: started.elapsed().as_secs_f64(),
            ..self
        }
    }
}

/// Where every texel bake starts: the covered texels of an atlas and their receivers, the
/// scene's tree, which texels leak (inside geometry or covered by a sheet, charts with no other
/// texel kept), and the distance under which a sheet covers a point.
struct TexelSites {
    texels: TexelPoints,
    receivers: Receivers,
    bvh: Bvh,
    leaking: Vec<bool>,
    cover: f32,
}

/// The [`TexelSites`] of `atlas` on `scene`.
fn texel_receivers(scene: &Scene, atlas: &Atlas) -> TexelSites {
    let texels = rasterize(atlas);
    let receivers = Receivers::at_points(scene, &texels.points);
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let cover = COVER_TEXELS * texel_length(scene, atlas);
    let mut leaking = leaking_or_covered_in(scene, &bvh, &receivers, cover);
    keep_charts_with_no_valid_texel(atlas, &texels.points, &mut leaking);
    TexelSites {
        texels,
        receivers,
        bvh,
        leaking,
        cover,
    }
}

/// The atlas of a lightmap about `size` texels on its longer side for the prepared `scene`;
/// fails (before any ray is cast) where the charts cannot fit that size.
pub fn plan_atlas(scene: &Scene, size: u32) -> Result<Atlas> {
    atlas_for_size(scene, size)
}

/// Bakes a lightmap of about `size` texels on its longer side for the prepared `scene`, whose
/// vertex transfer (bounces included) `vertex_transfer` is: interreflected texels gather from
/// it ([`crate::bake::bake_at`]).
pub fn bake_texels(
    scene: &Scene,
    vertex_transfer: &Transfer,
    options: &BakeOptions,
    size: u32,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(TexelBake, TexelReport)> {
    let started = Instant::now();
    let atlas = plan_atlas(scene, size)?;
    let (bake, mut report) =
        bake_atlas(scene, vertex_transfer, options, &atlas, backend, progress)?;
    report.seconds = started.elapsed().as_secs_f64();
    Ok((bake, report))
}

/// Bakes the texels of `atlas` (see [`bake_texels`]), its seams stitched
/// ([`crate::receivers::seams`]).
pub fn bake_atlas(
    scene: &Scene,
    vertex_transfer: &Transfer,
    options: &BakeOptions,
    atlas: &Atlas,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(TexelBake, TexelReport)> {
    let at = (scene, vertex_transfer, atlas);
    bake_atlas_with_seams(at, options, backend, progress, Seams::Stitched)
}

/// Whether a texel bake stitches its seams ([`crate::receivers::seams`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seams {
    Stitched,
    /// As baked: what stitching changes, measured.
    AsBaked,
}

/// [`bake_atlas`] with its seams stitched or left as baked.
pub fn bake_atlas_with_seams(
    at: (&Scene, &Transfer, &Atlas),
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
    stitching: Seams,
) -> Result<(TexelBake, TexelReport)> {
    let at = (at, None);
    bake_atlas_scattering(at, options, backend, progress, stitching)
}

/// [`bake_atlas`], the texels in a translucent medium where `scatter` says (the surface
/// scatters the light they receive, [`subsurface::PointScatter`]).
pub fn bake_atlas_in(
    at: (&Scene, &Transfer, &Atlas),
    scatter: Option<&subsurface::PointScatter>,
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(TexelBake, TexelReport)> {
    bake_atlas_scattering((at, scatter), options, backend, progress, Seams::Stitched)
}

fn bake_atlas_scattering(
    ((scene, vertex_transfer, atlas), scatter): TexelsOf,
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
    stitching: Seams,
) -> Result<(TexelBake, TexelReport)> {
    let started = Instant::now();
    let TexelSites {
        texels,
        receivers,
        bvh,
        leaking,
        cover,
    } = texel_receivers(scene, atlas);
    let at = (&receivers, bvh);
    // Texels to be denoised each turn their samples by their own angle, so that their errors
    // are independent and the filter averages them out. In a medium they receive as white
    // surfaces, and the medium's scattering replaces their albedo.
    let mut turned = options.clone().with_turns(options.denoise);
    if scatter.is_some() {
        turned.albedo = Some(Vec3::ONE);
    }
    let casting = Instant::now();
    let (at_texels, rays_cast) =
        bake_at_in(scene, at, &turned, backend, Some(vertex_transfer), progress)?;
    let transfer_seconds = casting.elapsed().as_secs_f64();
    let at_texels = match scatter {
        Some(scatter) => {
            let at = ((scene, atlas), &texels.points[..], &receivers);
            scattered_texels(at, at_texels, scatter, options, backend)?
        }
        None => at_texels,
    };
    let stride = at_texels.channels() as usize * at_texels.coeffs_per_channel();
    let (bands, channels) = (at_texels.bands(), at_texels.channels());
    let leaks = leaks_as_baked((&texels, at_texels.coeffs(), &leaking[..]), stride);
    let mut image = texels.scatter(at_texels.into_coeffs(), stride)?;
    let mut valid = texels.valid_mask(&leaking)?;
    let (width, height) = (atlas.width, atlas.height);
    if options.denoise {
        progress.stage("denoise", 1);
        let per_channel = stride / 3;
        let dc = |_, at: usize| {
            Vec3::from_array([0, 1, 2].map(|c| image[at * stride + c * per_channel]))
        };
        let guide = denoise_guide((atlas, &texels, &receivers), dc, options, &valid);
        image = backend.denoise(&guide, &image, stride)?;
        progress.advance(1);
    }
    let owner = chart_owners(atlas, &texels);
    let anchor = seam_anchors(atlas, &texels, &valid);
    dilate_by_owner(
        width,
        height,
        &mut image,
        stride,
        &mut valid,
        &owner,
        DILATION_PASSES,
    )?;
    keep_wide_leaks(leaks, (&mut image, stride), &mut valid);
    let seams = seams::seams(scene, atlas);
    let seam_rows = match stitching {
        Seams::Stitched => seams::seam_rows(width, height, &seams),
        Seams::AsBaked => Vec::new(),
    };
    let at = ((scene, vertex_transfer, atlas), scatter);
    let image_of = (&mut image[..], stride, &anchor[..], &seam_rows[..]);
    let fitted = stitch_or_fit(at, cover, &turned, (backend, progress), image_of)?;
    let rays_cast = rays_cast + fitted.as_ref().map_or(0, |f| f.rays_cast);
    let transfer_seconds = transfer_seconds + fitted.as_ref().map_or(0.0, |f| f.transfer_seconds);
    let texels_of = (scene, atlas, &texels);
    let report = TexelReport {
        fit_points: fitted.map(|f| f.points),
        ..TexelReport::of(texels_of, (&seams, &leaking), options.denoise, rays_cast)
    }
    .timed(transfer_seconds, started);
    let bake = TexelBake {
        width,
        height,
        texcoords: atlas_texcoords(atlas),
        set: 0,
        transfer: Transfer::new(bands, channels, (width * height) as usize, image)
            .expect("one row of coefficients for every texel"),
        held: None,
    };
    Ok((bake, report))
}

/// Every triangle corner's coordinates on `atlas`, in [0, 1] ([`TexelBake::texcoords`]).
pub fn atlas_texcoords(atlas: &Atlas) -> Vec<[f32; 2]> {
    let size = glam::Vec2::new(atlas.width as f32, atlas.height as f32);
    atlas
        .corners
        .iter()
        .flatten()
        .map(|c| [c.x / size.x, c.y / size.y])
        .collect()
}

/// Stitches the seams whose `rows` ([`seams::seam_rows`]) are given in `image` (`stride`
/// values a texel), each texel held to its value as firmly as `anchor` says: a stage of
/// `progress`, a step a coefficient.
fn stitch(
    rows: &[seams::Row],
    stride: usize,
    size: (u32, u32),
    (image, anchor): (&mut [f32], &[f32]),
    progress: &dyn Progress,
) {
    progress.stage("seams", seams::solve_steps(stride, rows));
    let solved = &mut |coefficients| progress.advance(coefficients);
    seams::solve(size, (image, stride), rows, anchor, solved);
}

/// A texel bake's scene, vertex transfer and atlas, and the medium its texels are in.
type TexelsOf<'a> = (
    (&'a Scene, &'a Transfer, &'a Atlas),
    Option<&'a subsurface::PointScatter<'a>>,
);

/// The values as baked (`values`, `stride` floats a texel of `texels`) of the texels flagged
/// in `leaking`, by their row-major index in the image: what [`keep_wide_leaks`] puts back.
fn leaks_as_baked(
    (texels, values, leaking): (&TexelPoints, &[f32], &[bool]),
    stride: usize,
) -> Vec<(usize, Vec<f32>)> {
    texels
        .texels
        .iter()
        .zip(values.chunks_exact(stride))
        .zip(leaking)
        .filter(|(_, &leak)| leak)
        .map(|((&(x, y), values), _)| ((y * texels.width + x) as usize, values.to_vec()))
        .collect()
}

/// Leaks too wide for dilation to fill keep what was baked there: each leaking texel
/// ([`leaks_as_baked`]) still invalid in `image` (`stride` floats a texel) after the dilation
/// gets its own values back.
fn keep_wide_leaks(
    leaks: Vec<(usize, Vec<f32>)>,
    (image, stride): (&mut [f32], usize),
    valid: &mut [bool],
) {
    for (at, values) in leaks {
        if !valid[at] {
            image[at * stride..(at + 1) * stride].copy_from_slice(&values);
            valid[at] = true;
        }
    }
}

/// The texels' transfer in `scatter`'s medium, from what they received as white surfaces
/// (`received`).
fn scattered_texels(
    (at, points, receivers): ((&Scene, &Atlas), &[SurfacePoint], &Receivers),
    received: Transfer,
    scatter: &subsurface::PointScatter,
    options: &BakeOptions,
    backend: &dyn Backend,
) -> Result<Transfer> {
    let scene = at.0;
    let points = scatter_points(at, points, receivers, options);
    let own = (received.coeffs(), received.bands());
    let coeffs = scatter.at_points(scene, &points, own, backend)?;
    Ok(Transfer::new(received.bands(), 3, points.len(), coeffs)
        .expect("one row of coefficients for every texel"))
}

/// The texels at `points` of `atlas` as points of the surface to scatter at: each stands for
/// the disc of one texel's area in the scene (its triangle's area over its area in the atlas),
/// its albedo the options' or the receivers'.
fn scatter_points(
    (scene, atlas): (&Scene, &Atlas),
    points: &[SurfacePoint],
    receivers: &Receivers,
    options: &BakeOptions,
) -> Vec<subsurface::ScatterPoint> {
    points
        .iter()
        .enumerate()
        .map(|(i, point)| {
            let triangle = scene.triangles[point.triangle as usize];
            let [a, b, c] = triangle.map(|v| scene.positions[v as usize].as_dvec3());
            let area = 0.5 * (b - a).cross(c - a).length();
            let [p, q, r] = atlas.corners[point.triangle as usize].map(|c| c.as_dvec2());
            let texels = 0.5 * (q - p).perp_dot(r - p).abs();
            let texel_area = if texels > 0.0 { area / texels } else { 0.0 };
            subsurface::ScatterPoint {
                position: receivers.positions[i],
                vertex: triangle[0],
                own_radius: (texel_area / std::f64::consts::PI).sqrt(),
                albedo: options.albedo.unwrap_or(receivers.albedo[i]),
            }
        })
        .collect()
}

/// Per texel of the atlas, the chart whose covered texels are nearest: gutter texels take the
/// values of that chart, never of a neighbour reached first through a chart's refilled leaks.
fn chart_owners(atlas: &Atlas, texels: &TexelPoints) -> Vec<u32> {
    let seeds: Vec<(usize, u32)> = texels
        .texels
        .iter()
        .zip(&texels.points)
        .map(|(&(x, y), p)| {
            let at = y as usize * atlas.width as usize + x as usize;
            (at, atlas.chart_of[p.triangle as usize])
        })
        .collect();
    nearest_owner(atlas.width, atlas.height, &seeds)
}

/// What guides the denoiser at each texel of `atlas`: where its receiver lies, its normal, its
/// level and noise (from its first coefficient of each channel as baked, `dc` of its covered
/// index and its row-major index, and the `samples` each cast), and its chart where it is
/// `valid` ([`NO_CHART`] elsewhere: neither read nor written).
fn denoise_guide(
    (atlas, texels, receivers): (&Atlas, &TexelPoints, &Receivers),
    dc: impl Fn(usize, usize) -> Vec3,
    options: &BakeOptions,
    valid: &[bool],
) -> DenoiseGuide {
    let count = (atlas.width * atlas.height) as usize;
    let (mut positions, mut normals) = (vec![Vec3::ZERO; count], vec![Vec3::Z; count]);
    let (mut levels, mut noise) = (vec![0.0; count], vec![1.0; count]);
    let mut charts = vec![NO_CHART; count];
    for (i, (&(x, y), point)) in texels.texels.iter().zip(&texels.points).enumerate() {
        let at = (y * atlas.width + x) as usize;
        positions[at] = receivers.positions[i];
        normals[at] = receivers.normals[i];
        let dc = dc(i, at);
        let albedo = options.albedo.unwrap_or(receivers.albedo[i]);
        (levels[at], noise[at]) = texel_level(dc, albedo, options.samples_used());
        if valid[at] {
            charts[at] = atlas.chart_of[point.triangle as usize];
        }
    }
    let size = (atlas.width, atlas.height);
    DenoiseGuide::new(size, (positions, normals), charts, (levels, noise))
}

/// How firmly each texel keeps its value when seams are stitched: texels baked at their own
/// centres hold firm; texels baked at a point on a chart's edge, and those dilation fills
/// (not `valid` before it), take what stitching gives them.
fn seam_anchors(atlas: &Atlas, texels: &TexelPoints, valid: &[bool]) -> Vec<f32> {
    let mut anchor: Vec<f32> = valid
        .iter()
        .map(|&baked| if baked { 1.0 } else { FILLED_ANCHOR })
        .collect();
    for texel in off_centre_texels(atlas, texels) {
        anchor[texel] = FILLED_ANCHOR;
    }
    anchor
}

/// The texels baked at a point of their chart's edge rather than at their centre (a chart
/// covers only part of them), as row-major indices.
fn off_centre_texels(atlas: &Atlas, texels: &TexelPoints) -> Vec<usize> {
    // Off the centre by more than rounding.
    const OFF_CENTRE: f64 = 1e-3;
    texels
        .texels
        .iter()
        .zip(&texels.points)
        .filter(|&(&(x, y), p)| {
            let c = atlas.corners[p.triangle as usize].map(|c| c.as_dvec2());
            let b = p.barycentrics.map(|b| b as f64);
            let point = c[0] * b[0] + c[1] * b[1] + c[2] * b[2];
            point.distance(DVec2::new(x as f64 + 0.5, y as f64 + 0.5)) > OFF_CENTRE
        })
        .map(|(&(x, y), _)| y as usize * atlas.width as usize + x as usize)
        .collect()
}

/// The albedo at each texel of `texels` over `scene` (the mesh the lightmap's corner
/// coordinates belong to, as a lightmapped file is read): the albedo interpolated at the point
/// of the texel's triangle the bake placed it at, and whether a triangle covers the texel at
/// all (`false`: a gutter texel dilation filled). What a relit lightmap's texels are divided
/// by to give the shading a material's base colour multiplies.
pub fn texel_albedo(scene: &Scene, texels: &TexelBake) -> (Vec<Vec3>, Vec<bool>) {
    let size = glam::Vec2::new(texels.width as f32, texels.height as f32);
    let atlas = Atlas {
        width: texels.width,
        height: texels.height,
        corners: texels
            .texcoords
            .chunks_exact(3)
            .map(|c| [0, 1, 2].map(|i| glam::Vec2::from_array(c[i]) * size))
            .collect(),
        chart_of: (0..scene.triangles.len() as u32).collect(),
    };
    let points = rasterize(&atlas);
    let receivers = Receivers::at_points(scene, &points.points);
    let count = (texels.width * texels.height) as usize;
    let (mut albedo, mut covered) = (vec![Vec3::ZERO; count], vec![false; count]);
    for (&(x, y), a) in points.texels.iter().zip(&receivers.albedo) {
        let at = (y * texels.width + x) as usize;
        albedo[at] = *a;
        covered[at] = true;
    }
    (albedo, covered)
}

/// Per receiver, whether more than [`LEAK_FRACTION`] of [`LEAK_RAYS`] cosine-distributed rays
/// about its normal first hit the back of a triangle (by the triangle's winding).
pub fn leaking_receivers(scene: &Scene, receivers: &Receivers) -> Vec<bool> {
    leaking_receivers_in(
        scene,
        &Bvh::build(&scene.positions, &scene.triangles),
        receivers,
    )
}

/// The length in the scene of one texel at the atlas' density (the largest over the charts:
/// tiny triangles' charts are enlarged, which makes their texels shorter).
fn texel_length(scene: &Scene, atlas: &Atlas) -> f32 {
    scene
        .triangles
        .iter()
        .zip(&atlas.corners)
        .map(|(t, c)| {
            let flat = c[0].distance(c[1]);
            let real = scene.positions[t[0] as usize].distance(scene.positions[t[1] as usize]);
            if flat > 0.0 {
                real / flat
            } else {
                0.0
            }
        })
        .fold(0.0, f32::max)
}

/// Unflags every texel of a chart none of whose texels is valid: dilation would otherwise fill
/// the whole chart from a neighbouring chart (its rings cross the gutter within two passes),
/// where keeping its own bake is what a leak too wide to fill should do.
fn keep_charts_with_no_valid_texel(atlas: &Atlas, points: &[SurfacePoint], leaking: &mut [bool]) {
    let charts = atlas.chart_count();
    let mut any_valid = vec![false; charts];
    for (p, &leak) in points.iter().zip(leaking.iter()) {
        any_valid[atlas.chart_of[p.triangle as usize] as usize] |= !leak;
    }
    for (p, leak) in points.iter().zip(leaking.iter_mut()) {
        *leak &= any_valid[atlas.chart_of[p.triangle as usize] as usize];
    }
}

/// [`leaking_receivers`] with the scene's tree already built.
pub fn leaking_receivers_in(scene: &Scene, bvh: &Bvh, receivers: &Receivers) -> Vec<bool> {
    leaking_or_covered_in(scene, bvh, receivers, 0.0)
}

/// [`leaking_receivers_in`], a ray that hits any face nearer than `cover` counting as well.
pub fn leaking_or_covered_in(
    scene: &Scene,
    bvh: &Bvh,
    receivers: &Receivers,
    cover: f32,
) -> Vec<bool> {
    let sites = sites_in(scene, bvh, receivers, cover);
    sites.into_iter().map(|site| site != Site::Open).collect()
}

/// What each receiver's leak test finds: inside geometry where more than [`LEAK_FRACTION`] of
/// its rays hit back faces; else covered where more than that share hit a back face or any
/// face nearer than `cover`; else open.
pub fn sites_in(scene: &Scene, bvh: &Bvh, receivers: &Receivers, cover: f32) -> Vec<Site> {
    let directions = cosine_hemisphere(LEAK_RAYS, 0x1eaf);
    let limit = (LEAK_FRACTION * LEAK_RAYS as f32) as usize;
    (0..receivers.len())
        .into_par_iter()
        .map(|r| {
            let (mut back_hits, mut back_or_near_hits) = (0, 0);
            fans_from(bvh, receivers, r, &directions, |fan, path, world| {
                let closest = packet::closest_fan(bvh, fan, path, RAY_T_MAX);
                for (lane, &direction) in world.iter().enumerate() {
                    let Some(hit) = bvh.triangles.get(closest.triangle[lane] as usize) else {
                        continue;
                    };
                    let corners = scene.triangles[hit.source_index as usize];
                    let back = face_normal(&scene.positions, corners).dot(direction) > 0.0;
                    back_hits += back as usize;
                    back_or_near_hits += (back || closest.t[lane] < cover) as usize;
                }
            });
            if back_hits > limit {
                Site::Inside
            } else if back_or_near_hits > limit {
                Site::Covered
            } else {
                Site::Open
            }
        })
        .collect()
}

/// Casts the tangent-frame set `directions` about receiver `r`'s normal from its ray origin
/// in `bvh`'s scene, a run at a time (`SampleSet::fan_runs`, at most [`LANES`]): `cast` gets
/// each fan packet, the tree's path to its origin and its world directions. The rays share
/// their origin, so fan packets, whose hits are those of single rays bit for bit, at three to
/// four times their speed.
pub fn fans_from(
    bvh: &Bvh,
    receivers: &Receivers,
    r: usize,
    directions: &SampleSet,
    mut cast: impl FnMut(&FanPacket, &PointPath, &[Vec3]),
) {
    let normal = receivers.normals[r];
    let origin = offset_ray_origin(receivers.positions[r], normal, bvh.extent());
    let path = bvh.path_to(origin);
    let to_world = VertexDirections::new(directions.frame, normal);
    let mut world = [Vec3::ZERO; LANES];
    for run in directions.fan_runs() {
        let world = to_world.world_run(directions, run, &mut world);
        cast(&FanPacket::new(origin, world, ALL_LANES), &path, world);
    }
}

/// Bilinear lookup of per-texel values (`[texel][channel]`, row-major, `channels` each) at
/// lightmap coordinates `uv` (glTF's convention, see [`TexelBake::texcoords`]), clamped at the
/// borders.
pub fn sample_bilinear(
    values: &[f32],
    channels: usize,
    width: u32,
    height: u32,
    uv: [f32; 2],
) -> Vec<f32> {
    let taps = bilinear_taps(
        width,
        height,
        glam::Vec2::new(uv[0] * width as f32, uv[1] * height as f32),
    );
    (0..channels)
        .map(|c| {
            taps.iter()
                .map(|&(i, w)| w * values[i * channels + c])
                .sum()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;
    use crate::scene::prepare::prepare;

    #[test]
    fn bilinear_lookup_hits_texel_centres_and_blends_between() {
        // 2 x 1 texels, one channel: 1 and 3.
        let values = [1.0, 3.0];
        let centre = |x: f32| [(x + 0.5) / 2.0, 0.5];
        assert_eq!(sample_bilinear(&values, 1, 2, 1, centre(0.0)), vec![1.0]);
        assert_eq!(sample_bilinear(&values, 1, 2, 1, centre(1.0)), vec![3.0]);
        assert_eq!(sample_bilinear(&values, 1, 2, 1, centre(0.5)), vec![2.0]);
        // Clamped past the border.
        assert_eq!(sample_bilinear(&values, 1, 2, 1, [0.0, 0.0]), vec![1.0]);
    }

    #[test]
    fn texels_inside_a_closed_box_leak_and_those_outside_do_not() {
        // A floor through a closed box: the floor's part inside the box sees only the box's
        // inner (back) faces.
        let floor = builtin::grid_plane(Vec3::ZERO, Vec3::X * 2.0, Vec3::NEG_Z * 2.0, 4, Vec3::ONE);
        let cage = builtin::closed_box(Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.5, 0.5), 1);
        let (scene, _) = prepare(builtin::merge(&[floor, cage])).unwrap();
        let points = [Vec3::ZERO, Vec3::new(1.5, 0.0, 1.5)];
        let receivers = Receivers {
            positions: points.to_vec(),
            ray_starts: points.to_vec(),
            normals: vec![Vec3::Y; 2],
            albedo: vec![Vec3::ONE; 2],
        };
        assert_eq!(leaking_receivers(&scene, &receivers), vec![true, false]);
        let bvh = Bvh::build(&scene.positions, &scene.triangles);
        let sites = sites_in(&scene, &bvh, &receivers, 1e-3);
        assert_eq!(sites, vec![Site::Inside, Site::Open]);
    }

    #[test]
    fn texels_under_a_double_sided_fin_are_covered_and_those_beside_it_are_not() {
        // A scan's fin: two triangles on the same three corners with opposite windings, lying
        // flat 2e-5 above a floor. A ray from under it meets both faces at one distance, so
        // the back-face count alone is a coin toss; any hit nearer than `cover` decides.
        let floor = builtin::grid_plane(Vec3::ZERO, Vec3::X * 2.0, Vec3::NEG_Z * 2.0, 4, Vec3::ONE);
        let lift = 2e-5;
        let corners = [
            Vec3::new(-0.5, lift, -0.5),
            Vec3::new(0.5, lift, -0.5),
            Vec3::new(0.0, lift, 0.5),
        ];
        let fin = Scene {
            positions: corners.to_vec(),
            normals: None,
            albedo: vec![Vec3::ONE; 3],
            triangles: vec![[0, 1, 2], [0, 2, 1]],
        };
        let scene = builtin::merge(&[floor, fin]);
        let bvh = Bvh::build(&scene.positions, &scene.triangles);
        let receivers = Receivers {
            positions: vec![Vec3::new(0.0, 0.0, -0.1), Vec3::new(1.5, 0.0, 1.5)],
            ray_starts: vec![Vec3::new(0.0, 0.0, -0.1), Vec3::new(1.5, 0.0, 1.5)],
            normals: vec![Vec3::Y; 2],
            albedo: vec![Vec3::ONE; 2],
        };
        let covered = leaking_or_covered_in(&scene, &bvh, &receivers, 1e-3);
        assert_eq!(covered, vec![true, false]);
        let sites = sites_in(&scene, &bvh, &receivers, 1e-3);
        assert_eq!(sites, vec![Site::Covered, Site::Open]);
    }
}
