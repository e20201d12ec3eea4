//! Least-squares texels in the texel bake (`--fit least-squares` with a lightmap): the points
//! of [`texel_fit`] baked like the texels, summed chunk by chunk, and the map fitted to them.

use std::time::Instant;

use super::{leaking_or_covered_in, scattered_texels, stitch, TexelsOf};
use crate::bake::{bake_at_in, Backend, BakeOptions, Fit, Progress, Transfer};
use crate::bvh::Bvh;
use crate::error::Result;
use crate::receivers::{seams, texel_fit, Receivers, SurfacePoint};

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
/// `options` in chunks, those nearer a sheet than `cover` left out, as texels are.
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
    let skip = leaking_or_covered_in(scene, &bvh, &receivers, cover);
    let casting = Instant::now();
    let mut sums = texel_fit::PointSums::new((atlas.width, atlas.height), stride, &points, &skip);
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
    drop((receivers, surface, points, skip));
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
pub(super) struct TexelFit {
    pub(super) points: usize,
    pub(super) rays_cast: u64,
    pub(super) transfer_seconds: f64,
}
