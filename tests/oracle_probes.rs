//! Probes against an independent oracle: Mitsuba 3's path tracer (`testing::oracle`) measures
//! the irradiance at free points around the dragon standing on a ground plane, under the
//! band-limited sky of tests/oracle_distant.rs, for random surface normals — with the scene a
//! black occluder (shadowed probes) and with up to three reflections on the way (probes of an
//! interreflected bake with two bounces: the surfaces' exit light holds the direct light and
//! two bounces, one reflection more reaches the probe).
//!
//! Probes baked at the points themselves hold the path tracer within the combined noise of both
//! sides (the oracle's standard error, and the baker's own from a twin bake with another seed)
//! times [`SIGMAS`], plus the band limit: the probes keep 8 bands of the incident radiance, and
//! the clamped cosine's bands from 8 on carry below 0.8% of its first ([`BAND_LIMIT`]).
//!
//! Probes of a grid, interpolated trilinearly to the same points, carry the interpolation's
//! error besides; a grid of half the spacing must come closer to the path tracer. Both
//! errors, and the interpolation's own (interpolated against the probes baked at the points),
//! are printed: docs/accuracy.md quotes them.

mod common;

use common::sky::sky;
use glam::Vec3;
use prt_gpu::bake::{CpuBackend, DirectSource, Mode, NoProgress};
use prt_gpu::probes::{ProbeForm, ProbePlacement, ProbeSet, ProbeSpec, ProbeStatus};
use prt_gpu::sampling::Pcg32;
use prt_gpu::scene::{self, builtin, Scene};
use prt_gpu::spec::{BakeSpec, Bands};
use prt_gpu::testing::oracle::{self, SurfacePoint};

const SIGMAS: f64 = 3.0;
/// `A_8 / A_0`: the clamped cosine's share in band 8, the first the probes leave out (the
/// bands beyond fall faster still).
const BAND_LIMIT: f64 = 0.008;
const BANDS: u32 = 8;
const POINTS: usize = 96;
const PATHS: u32 = 4096;

/// The dragon's bounding box.
fn dragon_bounds() -> (Vec3, Vec3) {
    bounds(&dragon().positions)
}

fn dragon() -> Scene {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/dragon_vrip_res3.ply.gz"
    );
    scene::load(std::path::Path::new(path)).unwrap()
}

/// The dragon (grey, albedo 0.7) on a ground plane twice its size (albedo 0.5).
fn dragon_on_ground() -> Scene {
    let mut dragon = dragon();
    dragon.normals = None;
    dragon.albedo = vec![Vec3::splat(0.7); dragon.positions.len()];
    let (lo, hi) = bounds(&dragon.positions);
    let centre = 0.5 * (lo + hi);
    let size = (hi - lo).max_element();
    let ground = builtin::grid_plane(
        Vec3::new(centre.x, lo.y, centre.z),
        Vec3::new(0.0, 0.0, size),
        Vec3::new(size, 0.0, 0.0),
        8,
        Vec3::splat(0.5),
    );
    builtin::merge(&[ground, dragon])
}

fn bounds(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    )
}

fn spec(mode: Mode, seed: u64, placement: ProbePlacement) -> BakeSpec {
    let mut spec = BakeSpec::default();
    spec.transfer.bands = Bands::Fixed(BANDS);
    spec.transfer.mode = mode;
    spec.transfer.bounces = 2;
    spec.transfer.samples = 1024;
    spec.transfer.seed = seed;
    spec.probes = Some(ProbeSpec {
        placement,
        form: ProbeForm::Radiance,
    });
    spec
}

/// The prepared scene and its probes.
fn bake(spec: &BakeSpec) -> (Scene, ProbeSet) {
    let baked = prt_gpu::pipeline::run(
        spec,
        dragon_on_ground(),
        None,
        &CpuBackend,
        DirectSource::Compute,
        &NoProgress,
    )
    .and_then(prt_gpu::pipeline::Bake::into_transfer)
    .unwrap();
    (baked.mesh.scene, baked.probes.unwrap())
}

/// Random points around the dragon (above the ground, up to half its height over it) and a
/// random unit normal each.
fn random_points(count: usize) -> Vec<(Vec3, Vec3)> {
    let (lo, hi) = dragon_bounds();
    let size = hi - lo;
    let mut random = Pcg32::new(11);
    let mut next = || random.next_f32();
    (0..count)
        .map(|_| {
            let t = Vec3::new(next(), next(), next());
            let at = lo - Vec3::new(0.25, 0.0, 0.25) * size
                + Vec3::new(1.5, 1.5, 1.5) * size * t
                + Vec3::new(0.0, 0.02 * size.y, 0.0);
            let z = 1.0 - 2.0 * next();
            let phi = 2.0 * std::f32::consts::PI * next();
            let r = (1.0 - z * z).max(0.0).sqrt();
            (at, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect()
}

/// Irradiance through `matrix` (a probe's or an interpolated one) for `normal` under the sky.
fn irradiance(probes: &ProbeSet, matrix: &[f32], normal: Vec3, sky: &[Vec3]) -> Vec3 {
    let mut light = vec![[0.0f32; 3]; (BANDS * BANDS) as usize];
    for (l, c) in light.iter_mut().zip(sky) {
        *l = c.to_array();
    }
    let e = probes.irradiance(matrix, &light, normal.as_dvec3());
    Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32)
}

/// RMS of `a - b` over the RMS of `b`.
fn relative_rms(a: &[Vec3], b: &[Vec3]) -> f64 {
    let error: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared() as f64)
        .sum();
    let norm: f64 = b.iter().map(|y| y.length_squared() as f64).sum();
    (error / norm).sqrt()
}

fn check(mode: Mode, reflections: u32) {
    let (sky_coefficients, light) = sky();
    let (scene, _) = bake(&spec(mode, 1, ProbePlacement::Points(vec![[0.0; 3]])));
    let candidates = random_points(2 * POINTS);
    let at = |points: &[(Vec3, Vec3)]| {
        ProbePlacement::Points(points.iter().map(|(p, _)| p.to_array()).collect())
    };
    // Free points only: a probe inside the dragon (or one whose rays mostly meet its back
    // faces) measures nothing the path tracer would agree on.
    let (_, first) = bake(&spec(mode, 1, at(&candidates)));
    let points: Vec<(Vec3, Vec3)> = candidates
        .iter()
        .zip(&first.status)
        .filter(|(_, &s)| s == ProbeStatus::Placed)
        .map(|(p, _)| *p)
        .take(POINTS)
        .collect();
    assert!(points.len() == POINTS, "only {} free points", points.len());
    let (_, direct) = bake(&spec(mode, 1, at(&points)));
    let (_, twin) = bake(&spec(mode, 2, at(&points)));
    let ours = |probes: &ProbeSet| -> Vec<Vec3> {
        (0..POINTS)
            .map(|p| irradiance(probes, probes.matrix(p), points[p].1, &sky_coefficients))
            .collect()
    };
    let (baked, baked_twin) = (ours(&direct), ours(&twin));
    let query: Vec<SurfacePoint> = points
        .iter()
        .map(|&(position, normal)| SurfacePoint {
            position,
            normal,
            face: 0,
        })
        .collect();
    let Some(truth) = oracle::irradiance(&scene, &query, &light, reflections, PATHS) else {
        return;
    };
    let keep = vec![true; POINTS];
    let (rms, oracle_noise) = oracle::relative_rms(&baked, &truth, &keep);
    let bake_noise = relative_rms(&baked, &baked_twin) / 2f64.sqrt();
    let bound = SIGMAS * oracle_noise.hypot(bake_noise) + BAND_LIMIT;
    eprintln!(
        "{mode:?}: probes at the points {:.2}% from the path tracer ({}, {:.1} s); noise: \
         oracle {:.2}%, bake {:.2}%; bound {:.2}%",
        100.0 * rms,
        truth.variant,
        truth.seconds,
        100.0 * oracle_noise,
        100.0 * bake_noise,
        100.0 * bound
    );
    let what = match mode {
        Mode::Shadowed => "shadowed (the sky alone)",
        _ => "interreflected, 2 bounces (up to 3 reflections)",
    };
    println!(
        "accuracy-row | distant light, probes around the dragon on a ground plane: irradiance \
         for random normals at {POINTS} free points, probes there, {what}, {BANDS} bands | \
         {:.2}% | {:.2}% | bake noise {:.2}%; bound {:.2}% (3 sigma and the band limit {:.1}%) |",
        100.0 * rms,
        100.0 * oracle_noise,
        100.0 * bake_noise,
        100.0 * bound,
        100.0 * BAND_LIMIT
    );
    assert!(rms < bound, "{mode:?}: {rms} beyond {bound}");

    let (lo, hi) = dragon_bounds();
    let coarse = 0.25 * (hi - lo).max_element();
    let mut errors = Vec::new();
    for spacing in [coarse, 0.5 * coarse] {
        // A quarter of the samples: the interpolation's error (several percent) dwarfs the
        // probes' own noise, and the finer grid holds 1,536 probes of 8 bands.
        let mut grid_spec = spec(mode, 1, ProbePlacement::Grid { spacing });
        grid_spec.transfer.samples = 256;
        let (_, grid) = bake(&grid_spec);
        let interpolated: Vec<Vec3> = points
            .iter()
            .map(|&(at, normal)| {
                let m = grid
                    .interpolate(at)
                    .expect("every point lies among valid probes");
                irradiance(&grid, &m, normal, &sky_coefficients)
            })
            .collect();
        let interpolation = relative_rms(&interpolated, &baked);
        let (rms_grid, _) = oracle::relative_rms(&interpolated, &truth, &keep);
        eprintln!(
            "{mode:?}: a grid of {spacing:.4} ({} probes, {} moved, {} invalid) interpolated: \
             {:.2}% from the path tracer; the interpolation's own error {:.2}%",
            grid.len(),
            grid.status
                .iter()
                .filter(|&&s| s == ProbeStatus::Moved)
                .count(),
            grid.status
                .iter()
                .filter(|&&s| s == ProbeStatus::Invalid)
                .count(),
            100.0 * rms_grid,
            100.0 * interpolation,
        );
        println!(
            "accuracy-row | distant light, probes around the dragon: a grid {spacing:.4} apart \
             ({} probes), trilinear at the same points, {} | {:.2}% | | the interpolation's \
             own error {:.2}% (against the probes at the points); finer grid closer (asserted) |",
            grid.len(),
            match mode {
                Mode::Shadowed => "shadowed",
                _ => "2 bounces",
            },
            100.0 * rms_grid,
            100.0 * interpolation
        );
        errors.push(rms_grid);
    }
    assert!(
        errors[1] < errors[0],
        "{mode:?}: halving the spacing did not bring the probes closer: {errors:?}"
    );
}

#[test]
fn shadowed_probes_match_the_path_tracer() {
    check(Mode::Shadowed, 0);
}

#[test]
fn interreflected_probes_match_the_path_tracer_with_two_bounces() {
    check(Mode::Interreflected, 3);
}
