//! Least-squares texels in the texel bake (`--fit least-squares` with a lightmap): the points
//! of [`texel_fit`] baked like the texels, summed chunk by chunk, and the map fitted to them;
//! or, in bounded memory ([`HeldPoints`]), their values held in a scratch file a group of
//! coefficients after another, for each group's fit.

use std::ops::Range;
use std::time::Instant;

use super::{scattered_texels, sites_in, stitch, TexelsOf};
use crate::bake::spill::Spill;
use crate::bake::{
    bake_at_in, bake_run_in_chunks, Advancing, Backend, BakeOptions, Fit, Progress, Transfer,
};
use crate::bvh::Bvh;
use crate::error::Result;
use crate::receivers::atlas::Atlas;
use crate::receivers::texel_fit::TexelSystem;
use crate::receivers::{seams, texel_fit, Receivers, SurfacePoint};
use crate::scene::Scene;

/// Stitches the seams whose `seam_rows` are given in `image` (`stride` values a texel, each
/// held as firmly as `anchor` says), or with `--fit least-squares` fits its texels, the seams
/// pulled together in the same solve ([`fit_texels`]): what the fit did, where it ran.
pub(super) fn stitch_or_fit(
    (at, scatter): TexelsOf,
    cover: f32,
    options: &BakeOptions,
    (backend, progress): (&dyn Backend, &dyn Progress),
    (image, stride, anchor, seam_rows): (&mut [f32], usize, &[f32], &[seams::Row]),
) -> Result<Option<TexelFit>> {
    let atlas = at.2;
    if options.fit == Fit::Point {
        let size = (atlas.width, atlas.height);
        stitch(seam_rows, stride, size, (image, anchor), progress);
        return Ok(None);
    }
    // Each point turns its samples by its own angle where the sampling can, as a vertex fit's
    // points do: the fit averages a texel's points, and errors the points shared would not
    // average out.
    let turned = options.clone().with_turns_where_possible();
    let fitting = (image, stride, anchor, seam_rows);
    let fitted = fit_texels((at, scatter), cover, &turned, (backend, progress), fitting)?;
    Ok(Some(fitted))
}

/// Fits the texels of `image` (`stride` values a texel; baked at their centres, filled, each
/// held as firmly as `anchor` says) to transfer baked at points spread over the charts
/// ([`texel_fit`]), their seams pulled together by `seam_rows`; the points are baked with
/// `options` in chunks. Points inside geometry are left out, and so are those nearer a sheet
/// than `cover` except where most of their texel is (`texel_fit::PointTaps::new`).
fn fit_texels(
    (at, scatter): TexelsOf,
    cover: f32,
    options: &BakeOptions,
    (backend, progress): (&dyn Backend, &dyn Progress),
    (image, stride, anchor, seam_rows): (&mut [f32], usize, &[f32], &[seams::Row]),
) -> Result<TexelFit> {
    let (scene, vertex_transfer, atlas) = at;
    let points = texel_fit::fit_points(atlas);
    let surface: Vec<SurfacePoint> = points.iter().map(|p| p.surface).collect();
    let receivers = Receivers::at_points(scene, &surface);
    // Built again rather than kept from the texels' bake, which owns its tree: one tree is held
    // at a time, and building it is a small share of a bake that casts rays from every point.
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let sites = sites_in(scene, &bvh, &receivers, cover);
    let casting = Instant::now();
    let size = (atlas.width, atlas.height);
    let mut sums = texel_fit::PointSums::new(size, stride, &points, &sites);
    let rays_cast = match scatter {
        // Scattering spreads light between points, so the points bake all at once.
        Some(scatter) => {
            let at = (&receivers, bvh);
            let (received, rays) =
                bake_at_in(scene, at, options, backend, Some(vertex_transfer), progress)?;
            let points = ((scene, atlas), &surface[..], &receivers);
            let scattered = scattered_texels(points, received, scatter, options, backend)?;
            sums.add(0, scattered.coeffs());
            rays
        }
        None => {
            let chunk = crate::bake::GATHER_CHUNK;
            let each = &mut |first, transfer: Transfer| {
                sums.add(first, transfer.coeffs());
                Ok(())
            };
            let with = (options, backend, Some(vertex_transfer));
            crate::bake::bake_at_in_chunks(scene, (&receivers, bvh), with, (progress, chunk), each)?
        }
    };
    let transfer_seconds = casting.elapsed().as_secs_f64();
    let count = points.len();
    drop((receivers, surface, points, sites));
    progress.stage("fit", stride as u64);
    let solved = &mut |coefficients| progress.advance(coefficients);
    sums.fit(image, anchor, seam_rows, solved);
    Ok(TexelFit {
        points: count,
        rays_cast,
        transfer_seconds,
    })
}

/// What fitting the texels did: the points it baked, their rays and the seconds they took.
#[derive(Clone, Copy)]
pub(super) struct TexelFit {
    pub(super) points: usize,
    pub(super) rays_cast: u64,
    pub(super) transfer_seconds: f64,
}

/// A least-squares lightmap's fit points baked in bounded memory ([`super::bake_atlas_held`]):
/// their values in a scratch file a group of coefficients after another (group `columns` from
/// `points * columns.start` values in, `[point][column of the group]`), and their taps, so
/// that each group of the clean-up sums its own values alone.
pub(super) struct HeldPoints {
    file: Spill,
    taps: texel_fit::PointTaps,
    /// The points baked, their rays and the seconds they took.
    pub(super) baked: TexelFit,
}

impl HeldPoints {
    /// The fit points of `at`'s atlas baked with `options` (turned where the sampling can, as
    /// [`stitch_or_fit`] turns them) and left out as [`fit_texels`] leaves them out, each
    /// chunk's values (`chunk` points) written by `groups` of coefficients and let go. The
    /// points' receivers are made a run at a time: what every point keeps is its place, what
    /// its leak test found and, once every run has said which points its texel keeps, its taps.
    pub(super) fn bake(
        (scene, vertex_transfer, atlas): (&Scene, &Transfer, &Atlas),
        cover: f32,
        options: &BakeOptions,
        (backend, progress): (&dyn Backend, &dyn Progress),
        (chunk, groups): (usize, &[Range<usize>]),
    ) -> Result<HeldPoints> {
        let turned = options.clone().with_turns_where_possible();
        let points = texel_fit::fit_points(atlas);
        let count = points.len();
        let mut sites = Vec::with_capacity(count);
        let mut bvh = Bvh::build(&scene.positions, &scene.triangles);
        let stride = groups.last().map_or(0, |g| g.end);
        let mut file = Spill::new()?;
        let mut block = Vec::new();
        // As the whole fit times its points: their bake, not their leak test.
        let mut transfer_seconds = 0.0;
        let mut rays_cast = 0;
        progress.stage("transfer", count as u64);
        let run_length = run_points(chunk);
        for (index, run) in points.chunks(run_length).enumerate() {
            let first = index * run_length;
            let surface: Vec<SurfacePoint> = run.iter().map(|p| p.surface).collect();
            let receivers = Receivers::at_points(scene, &surface);
            sites.extend(sites_in(scene, &bvh, &receivers, cover));
            let casting = Instant::now();
            let (cast, tree) = bake_run_in_chunks(
                scene,
                (&receivers, bvh, first),
                (&turned, backend, Some(vertex_transfer)),
                (&Advancing(progress), chunk),
                &mut |first, transfer| {
                    let values = (transfer.coeffs(), stride);
                    write_by_group(&mut file, (count, first), values, groups, &mut block)
                },
            )?;
            transfer_seconds += casting.elapsed().as_secs_f64();
            rays_cast += cast;
            bvh = tree;
        }
        let taps = texel_fit::PointTaps::new((atlas.width, atlas.height), &points, &sites);
        let baked = TexelFit {
            points: count,
            rays_cast,
            transfer_seconds,
        };
        Ok(HeldPoints { file, taps, baked })
    }

    /// The fit's system ([`texel_fit::PointTaps::system`]).
    pub(super) fn system(&self, anchor: &[f32], seam_rows: &[seams::Row]) -> TexelSystem {
        self.taps.system(anchor, seam_rows)
    }

    /// The points' sums of coefficients `columns` (one of the groups they were written by),
    /// read back a block of points at a time.
    pub(super) fn sums(&mut self, columns: Range<usize>) -> Result<Vec<f32>> {
        let group = columns.len();
        let mut sums = self.taps.empty_sums(group);
        let mut block = vec![0.0f32; READ_POINTS * group];
        let count = self.baked.points;
        let start = count * columns.start;
        for first in (0..count).step_by(READ_POINTS) {
            let values = &mut block[..READ_POINTS.min(count - first) * group];
            self.file
                .read_at(((start + first * group) * 4) as u64, values)?;
            self.taps.add(&mut sums, group, first, values);
        }
        Ok(sums)
    }
}

/// The fit points whose receivers a held bake makes at once, baked `chunk` at a time: at
/// least [`RUN_POINTS`], so that each run's setup (the samples and their SH) is a small share.
pub(super) fn run_points(chunk: usize) -> usize {
    chunk.max(RUN_POINTS)
}

/// The fewest fit points a held bake's run makes receivers for.
const RUN_POINTS: usize = 4096;

/// Points read back from the scratch file at a time.
const READ_POINTS: usize = 4096;

/// Writes the values of a chunk of `count` receivers from `first` on (`stride` a receiver) to
/// `file` by `groups` of coefficients: group `columns` from `count * columns.start` values in,
/// `[receiver][column of the group]`. `block` is scratch room.
pub(super) fn write_by_group(
    file: &mut Spill,
    (count, first): (usize, usize),
    (values, stride): (&[f32], usize),
    groups: &[Range<usize>],
    block: &mut Vec<f32>,
) -> Result<()> {
    for columns in groups {
        let at = (count * columns.start + first * columns.len()) as u64 * 4;
        if columns.len() == stride {
            file.write_at(at, values)?;
            continue;
        }
        block.clear();
        block.extend(
            values
                .chunks_exact(stride)
                .flat_map(|values| &values[columns.clone()]),
        );
        file.write_at(at, block)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec3};

    use super::super::{bake_atlas, bake_atlas_held, plan_atlas, TexelGroups};
    use crate::bake::backend::CpuBackend;
    use crate::bake::{bake, BakeOptions, Fit, NoProgress};
    use crate::lightmap::TexelRows;
    use crate::receivers::texel_fit::fit_points;
    use crate::receivers::texels::bilinear_taps;
    use crate::scene::{builtin, Scene};

    /// A 4 x 4 floor with a 2 x 2 sheet lying flat `2e-5` above its middle, both of its faces
    /// listed (as a scan's fins are), the one facing the floor first.
    fn floor_under_a_sheet() -> Scene {
        let floor = builtin::grid_plane(Vec3::ZERO, Vec3::X * 2.0, Vec3::NEG_Z * 2.0, 4, Vec3::ONE);
        let lift = 2e-5;
        let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        let positions: Vec<Vec3> = corners
            .iter()
            .chain(&corners)
            .map(|&(x, z)| Vec3::new(x, lift, z))
            .collect();
        let sheet = Scene {
            normals: Some([[Vec3::NEG_Y; 4], [Vec3::Y; 4]].concat()),
            albedo: vec![Vec3::ONE; 8],
            positions,
            triangles: vec![[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]],
        };
        builtin::merge(&[floor, sheet])
    }

    #[test]
    fn texels_wholly_under_a_sheet_are_fitted_dark_as_the_points_under_it_are() {
        let options = BakeOptions {
            samples: 64,
            bands: 2,
            ..BakeOptions::default()
        };
        let (baked, _) = bake(floor_under_a_sheet(), &options, &CpuBackend, &NoProgress).unwrap();
        let size = 64;
        let atlas = plan_atlas(&baked.scene, size).unwrap();
        let options = BakeOptions {
            lightmap: Some(size),
            fit: Fit::LeastSquares,
            ..options
        };
        let at = (&baked.scene, &baked.transfer, &atlas);
        let (map, _) = bake_atlas(at.0, at.1, &options, at.2, &CpuBackend, &NoProgress).unwrap();
        // The first coefficient looked up at the fit points on the floor, under the sheet's
        // middle and well away from it.
        let stride = map.transfer.coeffs().len() / (map.width * map.height) as usize;
        let lookup = |p: Vec2| -> f32 {
            bilinear_taps(map.width, map.height, p)
                .iter()
                .map(|&(t, w)| w * map.transfer.coeffs()[t * stride])
                .sum()
        };
        let (mut under, mut open) = (Vec::new(), Vec::new());
        for point in fit_points(&atlas) {
            let corners = baked.scene.triangles[point.surface.triangle as usize];
            let position: Vec3 = (0..3)
                .map(|i| baked.scene.positions[corners[i] as usize] * point.surface.barycentrics[i])
                .sum();
            let reach = position.x.abs().max(position.z.abs());
            if position.y > 1e-6 {
                continue;
            } else if reach < 0.6 {
                under.push(lookup(point.atlas));
            } else if reach > 1.5 {
                open.push(lookup(point.atlas));
            }
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        assert!(
            under.len() > 100 && open.len() > 100,
            "{} {}",
            under.len(),
            open.len()
        );
        let (under, open) = (mean(&under), mean(&open));
        assert!(open > 0.1, "open floor {open}");
        assert!(
            under.abs() < 0.02 * open,
            "under the sheet {under}, open floor {open}"
        );
        // Held in bounded memory, its points decided in runs, the fit is the same.
        let groups = TexelGroups {
            chunk: 97,
            columns: usize::MAX,
        };
        let (held, _) = bake_atlas_held(at, &options, &CpuBackend, &NoProgress, groups).unwrap();
        let held = held.held.expect("held in the scratch file");
        let rows = held.read_rows(0..map.height as usize).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(&rows) == bits(map.transfer.coeffs()));
    }
}
