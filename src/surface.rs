//! The surface error: what a viewer sees between the vertices. At held-out points drawn
//! uniformly by area, the radiance a representation gives (vertex transfer interpolated as a
//! renderer interpolates it) against a high-sample bake *at those points*, both relit by one
//! light. The per-vertex error of `sweep` is exact at the vertices and blind in between; this
//! one sees the interpolation too.
//!
//! Points inside other geometry (by the lightmap's leak test, `bake::texels::leaking_receivers`:
//! most of their rays reach back faces) are left out: no viewer sees them, and a lightmap
//! deliberately refills its texels there from their visible neighbours.
//!
//! A point a viewer barely sees counts for little: besides the plain RMS over the points, each
//! error is also given *as seen* ([`seen_fractions`]), every point weighted by how much of it
//! viewers around it see. On scans, whose sheets touch and fold within a fraction of a texel of
//! each other, the plain error is mostly that of points in such cracks (on dragon_vrip_res3,
//! 1% of the points hold 97% of a lightmap's squared error), where the transfer steps inside a
//! texel and where no viewer looks.

use std::time::Instant;

use rayon::prelude::*;

use crate::bake::texels::{fans_from, leaking_receivers_in, sample_bilinear};
use crate::bake::{bake_at_in, Backend, BakeOptions, NoProgress, TexelBake, Transfer};
use crate::bvh::Bvh;
use crate::error::Result;
use crate::light::ShLight;
use crate::packet;
use crate::receivers::{uniform_points, Receivers, SurfacePoint};
use crate::render::relight;
use crate::sampling::cosine_hemisphere;
use crate::scene::Scene;

/// The reference radiance at held-out surface points.
#[derive(Clone, Debug)]
pub struct SurfaceReference {
    pub points: Vec<SurfacePoint>,
    /// Points drawn but left out as inside other geometry.
    pub hidden: usize,
    /// Relit radiance, `[point][channel]` flattened.
    pub radiance: Vec<f32>,
    /// RMS of `radiance`: the scale errors are reported against.
    pub rms: f64,
    /// Per point, how much of it viewers see ([`seen_fractions`]): its weight in errors as seen.
    pub seen: Vec<f32>,
    /// RMS of `radiance` as seen: the scale errors as seen are reported against.
    pub seen_rms: f64,
    pub rays: u64,
    pub seconds: f64,
}

/// Bakes the visible ones of `count` uniformly drawn points of the prepared `scene` with `options` (a high sample
/// count) and relights them. Interreflected mode gathers from `vertex_transfer` (see
/// [`crate::bake::bake_at`]).
pub fn surface_reference(
    scene: &Scene,
    count: usize,
    seed: u64,
    options: &BakeOptions,
    backend: &dyn Backend,
    light: &ShLight,
    vertex_transfer: Option<&Transfer>,
) -> Result<SurfaceReference> {
    let started = Instant::now();
    let drawn = uniform_points(scene, count, seed);
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let inside = leaking_receivers_in(scene, &bvh, &Receivers::at_points(scene, &drawn));
    let points: Vec<SurfacePoint> = drawn
        .iter()
        .zip(&inside)
        .filter(|(_, &inside)| !inside)
        .map(|(&p, _)| p)
        .collect();
    let receivers = Receivers::at_points(scene, &points);
    let seen = seen_fractions(&bvh, &receivers);
    let at = (&receivers, bvh);
    let (transfer, rays) = bake_at_in(scene, at, options, backend, vertex_transfer, &NoProgress)?;
    let radiance = flat_radiance(&transfer, light)?;
    let zero = vec![0.0; radiance.len()];
    Ok(SurfaceReference {
        rms: root_mean_square(radiance.iter().map(|&x| x as f64)),
        seen_rms: weighted_rms(&radiance, &zero, &seen),
        seen,
        hidden: drawn.len() - points.len(),
        points,
        radiance,
        rays,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Vertex transfer interpolated at surface points with their barycentrics, as a renderer
/// interpolates vertex attributes.
pub fn interpolate(transfer: &Transfer, scene: &Scene, points: &[SurfacePoint]) -> Transfer {
    let stride = transfer.channels() as usize * transfer.coeffs_per_channel();
    let mut coeffs = Vec::with_capacity(points.len() * stride);
    for p in points {
        let corners = scene.triangles[p.triangle as usize];
        for i in 0..stride {
            let value: f32 = corners
                .iter()
                .zip(p.barycentrics)
                .map(|(&v, b)| b * transfer.coeffs()[v as usize * stride + i])
                .sum();
            coeffs.push(value);
        }
    }
    Transfer::new(transfer.bands(), transfer.channels(), points.len(), coeffs)
        .expect("one interpolated row for each point")
}

/// Per-texel transfer looked up bilinearly at surface points, as a renderer samples a lightmap:
/// each point's lightmap coordinates interpolated from its triangle's corners (`scene` is the
/// prepared scene the lightmap was baked for, whose triangle t has the lightmap corners
/// `3t..3t + 3`).
pub fn texel_transfer_at(texels: &TexelBake, points: &[SurfacePoint]) -> Transfer {
    let map = &texels.transfer;
    let stride = map.channels() as usize * map.coeffs_per_channel();
    let mut coeffs = Vec::with_capacity(points.len() * stride);
    for p in points {
        let corner = |i: usize| texels.texcoords[3 * p.triangle as usize + i];
        let uv = [0, 1].map(|axis| (0..3).map(|i| p.barycentrics[i] * corner(i)[axis]).sum());
        coeffs.extend(sample_bilinear(
            map.coeffs(),
            stride,
            texels.width,
            texels.height,
            uv,
        ));
    }
    Transfer::new(map.bands(), map.channels(), points.len(), coeffs)
        .expect("one looked-up row for each point")
}

/// Cosine-weighted rays per point that [`seen_fractions`] casts.
pub const SEEN_RAYS: u32 = 128;

/// How far from a point, as a fraction of the scene's extent, a viewer stands.
pub const VIEWER_REACH: f32 = 0.01;

/// Per receiver, how much of it viewers see: the cosine-weighted fraction of [`SEEN_RAYS`]
/// directions about its normal along which nothing lies within [`VIEWER_REACH`] of the scene's
/// extent. Viewers spread over every direction, at least that far away, see a point with a
/// projected area in proportion to it: 1 on an open surface, 0 under a sheet lying on it (a
/// crack a viewer cannot stand in), a half at the edge of one.
pub fn seen_fractions(bvh: &Bvh, receivers: &Receivers) -> Vec<f32> {
    let extent = bvh.extent();
    let reach = VIEWER_REACH * extent;
    let directions = cosine_hemisphere(SEEN_RAYS, 0x5ee);
    (0..receivers.len())
        .into_par_iter()
        .map(|r| {
            let mut open = 0;
            fans_from(bvh, receivers, r, &directions, |fan, path, world| {
                let blocked = packet::occluded_fan(bvh, fan, path, reach);
                open += world.len() - blocked.count_ones() as usize;
            });
            open as f32 / directions.directions.len() as f32
        })
        .collect()
}

/// A representation's radiance error at a reference's points: the plain RMS over points and
/// channels, and the same weighted by how much of each point viewers see.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceError {
    pub rms: f64,
    pub seen_rms: f64,
}

impl SurfaceError {
    /// The error of `radiance` (`[point][channel]` flattened) at `reference`'s points.
    fn of(reference: &SurfaceReference, radiance: &[f32]) -> SurfaceError {
        SurfaceError {
            rms: root_mean_square(
                radiance
                    .iter()
                    .zip(&reference.radiance)
                    .map(|(&a, &b)| a as f64 - b as f64),
            ),
            seen_rms: weighted_rms(radiance, &reference.radiance, &reference.seen),
        }
    }
}

/// The radiance error of a lightmap looked up at the reference's points
/// ([`texel_transfer_at`]).
pub fn texel_surface_error(
    reference: &SurfaceReference,
    texels: &TexelBake,
    light: &ShLight,
) -> Result<SurfaceError> {
    let radiance = flat_radiance(&texel_transfer_at(texels, &reference.points), light)?;
    Ok(SurfaceError::of(reference, &radiance))
}

/// The radiance error of `vertex_transfer` interpolated at the reference's points.
pub fn surface_error(
    reference: &SurfaceReference,
    scene: &Scene,
    vertex_transfer: &Transfer,
    light: &ShLight,
) -> Result<SurfaceError> {
    let at_points = interpolate(vertex_transfer, scene, &reference.points);
    let radiance = flat_radiance(&at_points, light)?;
    Ok(SurfaceError::of(reference, &radiance))
}

fn flat_radiance(transfer: &Transfer, light: &ShLight) -> Result<Vec<f32>> {
    Ok(relight(transfer, light)?.into_iter().flatten().collect())
}

/// RMS of `a - b` (`[point][channel]` flattened) over points weighted by `weights`, one a
/// point; 0 where no point weighs anything.
fn weighted_rms(a: &[f32], b: &[f32], weights: &[f32]) -> f64 {
    let channels = a.len() / weights.len().max(1);
    let (mut sum, mut total) = (0.0, 0.0);
    for ((a, b), &w) in a
        .chunks_exact(channels.max(1))
        .zip(b.chunks_exact(channels.max(1)))
        .zip(weights)
    {
        let squares: f64 = a
            .iter()
            .zip(b)
            .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
            .sum();
        sum += w as f64 * squares;
        total += w as f64 * channels as f64;
    }
    if total > 0.0 {
        (sum / total).sqrt()
    } else {
        0.0
    }
}

fn root_mean_square(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = values.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (sum / count.max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::receivers::spread_points;

    #[test]
    fn interpolation_weights_the_corners_by_barycentrics() {
        let scene = Scene {
            positions: vec![glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y],
            normals: Some(vec![glam::Vec3::Z; 3]),
            albedo: vec![glam::Vec3::ONE; 3],
            triangles: vec![[0, 1, 2]],
        };
        // One band, one channel: the vertices hold 1, 2 and 4.
        let transfer = Transfer::new(1, 1, 3, vec![1.0, 2.0, 4.0])
            .expect("one value for each of three vertices");
        let points = [SurfacePoint {
            triangle: 0,
            barycentrics: [0.5, 0.25, 0.25],
        }];
        assert_eq!(interpolate(&transfer, &scene, &points).coeffs(), vec![2.0]);
        let spread = spread_points(&scene, Default::default(), 1);
        let at = interpolate(&transfer, &scene, &spread);
        assert!(at.coeffs().iter().all(|&x| (1.0..=4.0).contains(&x)));
    }

    /// A 10 x 10 floor at z = 0 and, at `height` above it, a sheet over its half x > 0.
    fn floor_under_a_sheet(height: f32) -> Bvh {
        let quad = |x0: f32, x1: f32, z: f32| {
            [[x0, -5.0], [x1, -5.0], [x1, 5.0], [x0, 5.0]].map(|[x, y]| glam::Vec3::new(x, y, z))
        };
        let positions: Vec<glam::Vec3> = [quad(-5.0, 5.0, 0.0), quad(0.0, 5.0, height)].concat();
        let triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        Bvh::build(&positions, &triangles)
    }

    fn floor_receivers(xs: &[f32]) -> Receivers {
        let positions: Vec<glam::Vec3> = xs.iter().map(|&x| glam::Vec3::new(x, 0.0, 0.0)).collect();
        Receivers {
            ray_starts: positions.clone(),
            normals: vec![glam::Vec3::Z; xs.len()],
            albedo: vec![glam::Vec3::ONE; xs.len()],
            positions,
        }
    }

    #[test]
    fn a_point_under_a_sheet_is_unseen_and_one_at_its_edge_half_seen() {
        // The sheet a thousandth above the floor: a crack no viewer stands in.
        let seen = seen_fractions(
            &floor_under_a_sheet(1e-3),
            &floor_receivers(&[-2.5, 2.5, 0.0]),
        );
        assert_eq!(seen[0], 1.0, "open floor: {seen:?}");
        assert_eq!(seen[1], 0.0, "under the sheet: {seen:?}");
        // At the sheet's edge, the half of the directions towards x < 0 are open.
        assert!((seen[2] - 0.5).abs() < 0.05, "at the edge: {seen:?}");
        // The sheet ten times the viewers' reach (0.1 here) above the floor: room to stand.
        let seen = seen_fractions(&floor_under_a_sheet(1.0), &floor_receivers(&[2.5]));
        assert_eq!(seen, [1.0]);
    }

    #[test]
    fn errors_as_seen_weigh_points_by_how_much_of_them_viewers_see() {
        // Two points: one seen wholly with error 1, one half seen with error 3, one channel.
        let reference = SurfaceReference {
            points: Vec::new(),
            hidden: 0,
            radiance: vec![0.0, 0.0],
            rms: 0.0,
            seen: vec![1.0, 0.5],
            seen_rms: 0.0,
            rays: 0,
            seconds: 0.0,
        };
        let error = SurfaceError::of(&reference, &[1.0, 3.0]);
        assert!((error.rms - 5.0f64.sqrt()).abs() < 1e-12);
        // (1 * 1 + 0.5 * 9) / 1.5 = 11 / 3.
        assert!((error.seen_rms - (11.0f64 / 3.0).sqrt()).abs() < 1e-12);
        // No point seen at all: no error to speak of.
        let unseen = SurfaceReference {
            seen: vec![0.0, 0.0],
            ..reference
        };
        assert_eq!(SurfaceError::of(&unseen, &[1.0, 3.0]).seen_rms, 0.0);
    }
}
