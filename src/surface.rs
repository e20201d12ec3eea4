//! The surface error: what a viewer sees between the vertices. At held-out points drawn
//! uniformly by area, the radiance a representation gives (vertex transfer interpolated as a
//! renderer interpolates it) against a high-sample bake *at those points*, both relit by one
//! light. The per-vertex error of `sweep` is exact at the vertices and blind in between; this
//! one sees the interpolation too.
//!
//! Points inside other geometry (by the lightmap's leak test, `bake::texels::leaking_receivers`:
//! most of their rays reach back faces) are left out: no viewer sees them, and a lightmap
//! deliberately refills its texels there from their visible neighbours.

use std::time::Instant;

use crate::bake::texels::{leaking_receivers_in, sample_bilinear};
use crate::bake::{bake_at_in, Backend, BakeOptions, NoProgress, TexelBake, Transfer};
use crate::bvh::Bvh;
use crate::error::Result;
use crate::light::ShLight;
use crate::receivers::{uniform_points, Receivers, SurfacePoint};
use crate::render::relight;
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
    pub rays: u64,
    pub seconds: f64,
}

/// Bakes the visible ones of `count` uniformly drawn points of the prepared `scene` with `options` (a high sample
/// count) and relights them. Interreflected mode gathers from `vertex_transfer` (see
/// [`bake_at`]).
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
    let at = (&receivers, bvh);
    let (transfer, rays) = bake_at_in(scene, at, options, backend, vertex_transfer, &NoProgress)?;
    let radiance = flat_radiance(&transfer, light)?;
    Ok(SurfaceReference {
        rms: root_mean_square(radiance.iter().map(|&x| x as f64)),
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

/// RMS over the reference's points and channels of the radiance error of a lightmap looked up
/// there ([`texel_transfer_at`]).
pub fn texel_surface_rms(
    reference: &SurfaceReference,
    texels: &TexelBake,
    light: &ShLight,
) -> Result<f64> {
    let radiance = flat_radiance(&texel_transfer_at(texels, &reference.points), light)?;
    Ok(root_mean_square(
        radiance
            .iter()
            .zip(&reference.radiance)
            .map(|(&a, &b)| a as f64 - b as f64),
    ))
}

/// RMS over the reference's points and channels of the radiance error of `vertex_transfer`
/// interpolated there.
pub fn surface_rms(
    reference: &SurfaceReference,
    scene: &Scene,
    vertex_transfer: &Transfer,
    light: &ShLight,
) -> Result<f64> {
    let at_points = interpolate(vertex_transfer, scene, &reference.points);
    let radiance = flat_radiance(&at_points, light)?;
    Ok(root_mean_square(
        radiance
            .iter()
            .zip(&reference.radiance)
            .map(|(&a, &b)| a as f64 - b as f64),
    ))
}

fn flat_radiance(transfer: &Transfer, light: &ShLight) -> Result<Vec<f32>> {
    Ok(relight(transfer, light)?.into_iter().flatten().collect())
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
}
