//! Transfer against closed forms: the clamped cosine's SH projection and the white furnace.

mod common;

use glam::{DVec3, Vec3};
use prt_gpu::bake::{bake, Backend, BakeOptions, DirectInputs, Mode, NoProgress};
use prt_gpu::bvh::Bvh;
use prt_gpu::sampling::{stratified_sphere, Estimator};
use prt_gpu::scene::builtin;
use prt_gpu::sh::rotation::EulerShRotation;
use prt_gpu::sh::{coeff_count, unshadowed_transfer, ShTable};

/// Monte-Carlo transfer of an unoccluded vertex with its per-coefficient standard error.
///
/// The standard error is that of plain Monte Carlo with the same sample count, estimated from
/// the samples themselves; stratification only lowers the true error, so this bound is safe.
fn estimate_with_error(
    backend: &dyn Backend,
    bands: u32,
    normal: Vec3,
    samples: u32,
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let set = stratified_sphere(samples, seed);
    let table = ShTable::new(bands, &set.directions);
    let bvh = Bvh::default();
    let inputs = DirectInputs {
        origins: &[Vec3::ZERO],
        normals: &[normal],
        triangles: &[],
        vertex_normals: &[],
        bvh: &bvh,
        samples: &set,
        table: &table,
        estimator: Estimator::Visible,
        tangent_to_world: &EulerShRotation::new(bands),
        turns: None,
    };
    let n = coeff_count(bands);
    let (transfer, _) = backend
        .direct_transfer(&inputs, Mode::Unshadowed, &NoProgress)
        .unwrap();
    let estimate: Vec<f64> = transfer.iter().map(|&t| t as f64).collect();

    // Per-sample integrand values f = (4 pi / pi) max(0, n.w) y_k(w): the estimate is their mean.
    let mut sum_sq = vec![0.0; n];
    for (s, dir) in set.directions.iter().enumerate() {
        let c = normal.dot(*dir).max(0.0) as f64;
        for (acc, &y) in sum_sq.iter_mut().zip(table.row(s)) {
            let f = 4.0 * c * y as f64;
            *acc += f * f;
        }
    }
    let count = set.len() as f64;
    let std_error = (0..n)
        .map(|k| ((sum_sq[k] / count - estimate[k] * estimate[k]).max(0.0) / count).sqrt())
        .collect();
    (estimate, std_error)
}

#[test]
fn unshadowed_transfer_matches_the_clamped_cosine_projection() {
    let bands = 4;
    let normals = [
        Vec3::Z,
        Vec3::new(0.3, 0.4, -0.866).normalize(),
        Vec3::Y,
        Vec3::new(-0.7, 0.1, 0.2).normalize(),
    ];
    for backend in common::backends() {
        for (i, &normal) in normals.iter().enumerate() {
            let exact = unshadowed_transfer(bands, normal.as_dvec3());
            let (estimate, std_error) =
                estimate_with_error(backend.as_ref(), bands, normal, 1024, 10 + i as u64);
            for k in 0..coeff_count(bands) {
                let err = (estimate[k] - exact[k]).abs();
                assert!(
                    err <= 3.0 * std_error[k] + 1e-6,
                    "{}: normal {normal}, k = {k}: |{} - {}| = {err} > 3 x {}",
                    backend.describe(),
                    estimate[k],
                    exact[k],
                    std_error[k]
                );
            }
            // The bound must be tight enough to mean something.
            assert!(
                std_error[0] < 0.02,
                "standard error {} too loose",
                std_error[0]
            );
        }
    }
}

#[test]
fn zonal_values_vanish_for_odd_bands_above_one() {
    let exact = unshadowed_transfer(6, DVec3::Z);
    for l in [3, 5] {
        assert_eq!(exact[(l * (l + 1)) as usize], 0.0, "l = {l}");
    }
    // And only m = 0 survives for a normal on the polar axis.
    for l in 0..6i32 {
        for m in (-l..=l).filter(|&m| m != 0) {
            assert!(exact[(l * (l + 1) + m) as usize].abs() < 1e-15);
        }
    }
}

#[test]
fn white_furnace_gives_unit_exit_radiance_for_any_normal() {
    let unit_light_dc = (4.0 * std::f64::consts::PI).sqrt();
    for backend in common::backends() {
        let mut rng = prt_gpu::sampling::Pcg32::new(99);
        for i in 0..32 {
            let normal = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                .normalize_or(Vec3::X);
            let (estimate, std_error) = estimate_with_error(backend.as_ref(), 2, normal, 1024, i);
            let radiance = estimate[0] * unit_light_dc;
            let tolerance = 3.0 * std_error[0] * unit_light_dc;
            assert!(
                (radiance - 1.0).abs() <= tolerance,
                "{}: normal {normal}: exit radiance {radiance}, tolerance {tolerance}",
                backend.describe()
            );
        }
    }
}

#[test]
fn white_furnace_through_the_whole_pipeline() {
    // A convex mesh, albedo 1, unshadowed: every vertex reflects the unit light it receives.
    let sphere = builtin::icosphere(Vec3::ZERO, 1.0, 2);
    let options = BakeOptions {
        bands: 3,
        samples: 4096,
        mode: Mode::Unshadowed,
        albedo: Some(Vec3::ONE),
        ..BakeOptions::default()
    };
    for backend in common::backends() {
        let (baked, _) = bake(sphere.clone(), &options, backend.as_ref(), &NoProgress).unwrap();
        let unit_light_dc = (4.0 * std::f32::consts::PI).sqrt();
        for v in 0..baked.transfer.vertex_count() {
            for c in 0..3 {
                let radiance = baked.transfer.vertex_channel(v, c)[0] * unit_light_dc;
                // 4096 stratified samples: plain-MC standard error of the furnace is ~0.015.
                assert!(
                    (radiance - 1.0).abs() < 0.045,
                    "{}: vertex {v}: {radiance}",
                    backend.describe()
                );
            }
        }
    }
}
