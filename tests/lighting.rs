//! Lighting against the bake: relighting equals brute force, and windowed real maps stay
//! non-negative.

mod common;

use std::path::PathBuf;

use glam::{DVec3, Vec3};
use prt_gpu::bake::{cpu, tint_by_albedo, BakeInputs, Mode};
use prt_gpu::light::{self, ShLight};
use prt_gpu::scene::{self, prepare::prepare};
use prt_gpu::sh::{self, window::Window};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

#[test]
fn relighting_equals_brute_force_integration_of_a_band_limited_light() {
    // With a light that is exactly band-limited to the transfer's bands, the SH dot product
    // must equal the Monte-Carlo integral of light x visibility x cosine over the same samples:
    // sum_k l_k t_k = (rho/pi) sum_s L(w_s) V_s cos_s (4 pi / N), term for term.
    let bands = 4;
    let (mesh, _) = prepare(scene::load(&data("bunny.obj")).unwrap()).unwrap();
    let owned = BakeInputs::new(&mesh, bands, 1024, 5);
    let inputs = owned.view();
    let (scalar, _) = cpu::direct_transfer(&inputs, Mode::Shadowed, &prt_gpu::bake::NoProgress);
    let albedo = vec![Vec3::new(0.9, 0.6, 0.3); mesh.positions.len()];
    let transfer = tint_by_albedo(&scalar, &albedo, bands);

    // A band-limited light: a few SH terms per channel, positive on average.
    let n = sh::coeff_count(bands);
    let coeffs: Vec<[f32; 3]> = (0..n)
        .map(|k| {
            let x = (k as f32 * 0.37).sin();
            if k == 0 {
                [3.0, 2.5, 2.0]
            } else {
                [0.3 * x, -0.2 * x, 0.25 * x.cos()]
            }
        })
        .collect();
    let light = ShLight { bands, coeffs };
    let radiance_at = |w: DVec3, c: usize| -> f64 {
        let y = sh::basis(bands, w);
        (0..n).map(|k| light.coeffs[k][c] as f64 * y[k]).sum()
    };

    let relit = prt_gpu::render::relight(&transfer, &light).unwrap();
    let bits = cpu::visibility_bits(&inputs, Mode::Shadowed);
    let words = cpu::words_per_vertex(inputs.samples.len());
    let mut checked = 0;
    for v in (0..mesh.positions.len()).step_by(97) {
        for c in 0..3 {
            let mut brute = 0.0;
            for (s, w) in inputs.samples.directions.iter().enumerate() {
                if bits[v * words + s / 32] & (1 << (s % 32)) != 0 {
                    let cosine = inputs.normals[v].dot(*w) as f64;
                    brute += radiance_at(w.as_dvec3(), c) * cosine;
                }
            }
            brute *= albedo[v][c] as f64 * inputs.samples.weight / std::f64::consts::PI;
            let got = relit[v][c] as f64;
            assert!(
                (got - brute).abs() <= 1e-5 * brute.abs().max(0.1),
                "vertex {v} channel {c}: {got} vs {brute}"
            );
            checked += 1;
        }
    }
    assert!(checked > 50);
}

#[test]
fn windowed_sunrise_has_no_negative_radiance() {
    // sunrise.exr: a sun ~70,000 times brighter than the mean sky. Its plain projection rings
    // below zero; the non-negative window must remove every negative lobe.
    for bands in [3, 4, 6] {
        let loaded = light::load(&data("sunrise.exr"), bands, None, false).unwrap();
        let raw = sh::window::min_reconstruction(&loaded.light.coeffs, bands);
        let windowed = loaded.light.windowed(Window::NonNegative);
        let min = sh::window::min_reconstruction(&windowed.coeffs, bands);
        let dc = windowed.coeffs[0].iter().fold(f32::MAX, |a, &b| a.min(b)) as f64;
        eprintln!(
            "sunrise at {bands} bands: min radiance {raw:.4} raw, {min:.6} windowed (DC {dc:.3})"
        );
        assert!(
            raw < 0.0,
            "the raw projection should ring negative at {bands} bands"
        );
        assert!(min >= -1e-6 * dc, "windowed reconstruction dips to {min}");
    }
}

#[test]
fn a_rotated_light_relights_like_a_rotated_scene() {
    // Turning the light by R about the vertical is the same as turning an unshadowed vertex's
    // normal by R^-1: compare relit radiance of a constant-albedo normal both ways.
    let bands = 4;
    let light = light::load(&data("studio.exr"), bands, None, false)
        .unwrap()
        .light;
    let yaw = 70.0f64;
    let rotated = light.rotated(yaw, 0.0, 0.0);
    let turn = glam::DMat3::from_rotation_y(yaw.to_radians());
    for normal in [
        DVec3::X,
        DVec3::new(0.3, 0.8, -0.5).normalize(),
        DVec3::NEG_Z,
    ] {
        let t_rotated_normal = sh::unshadowed_transfer(bands, turn.transpose() * normal);
        let t_normal = sh::unshadowed_transfer(bands, normal);
        for c in 0..3 {
            let a: f64 = (0..16)
                .map(|k| rotated.coeffs[k][c] as f64 * t_normal[k])
                .sum();
            let b: f64 = (0..16)
                .map(|k| light.coeffs[k][c] as f64 * t_rotated_normal[k])
                .sum();
            assert!(
                (a - b).abs() < 1e-4 * a.abs().max(1e-3),
                "normal {normal}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn rotating_the_light_equals_projecting_the_rotated_map() {
    // A band-limited function drawn into a lat-long map, and the same function turned by R
    // drawn into another (pixel values f(R^-1 w), exact, so no resampling error): projecting
    // the second must give the rotated coefficients of the first.
    use prt_gpu::light::{mapping::pixel_direction, project, EnvImage, Mapping};
    let bands = 4;
    let n = sh::coeff_count(bands);
    let coefficients: Vec<f64> = (0..n)
        .map(|k| {
            if k == 0 {
                2.0
            } else {
                0.4 * ((k * 7) as f64).sin()
            }
        })
        .collect();
    let f = |w: DVec3| -> f32 {
        let y = sh::basis(bands, w);
        (0..n).map(|k| coefficients[k] * y[k]).sum::<f64>() as f32
    };
    let (width, height) = (512, 256);
    let draw = |turn: glam::DMat3| {
        EnvImage::from_fn(width, height, |x, y| {
            let w = pixel_direction(Mapping::Latlong, width, height, x, y).unwrap();
            let v = f(turn.transpose() * w);
            [v, v, v]
        })
        .unwrap()
    };
    let (yaw, pitch, roll) = (40.0f64, -25.0f64, 10.0f64);
    let turn = glam::DMat3::from_rotation_y(yaw.to_radians())
        * glam::DMat3::from_rotation_x(pitch.to_radians())
        * glam::DMat3::from_rotation_z(roll.to_radians());
    let original = project(&draw(glam::DMat3::IDENTITY), Mapping::Latlong, bands).unwrap();
    let rotated_map = project(&draw(turn), Mapping::Latlong, bands).unwrap();
    let rotated_light = original.rotated(yaw, pitch, roll);
    for k in 0..n {
        let (a, b) = (rotated_light.coeffs[k][0], rotated_map.coeffs[k][0]);
        assert!(
            (a - b).abs() < 1e-4 * 2.0,
            "k = {k}: rotated light {a}, projected rotated map {b}"
        );
    }
}
