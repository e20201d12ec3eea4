//! The distant-light bake against an independent path tracer: Mitsuba 3 (`testing::oracle`).
//!
//! The light is a band-limited sky of 3 bands, `L(w) = sum_k c_k y_k(w)` in the baker's SH
//! convention, which the oracle renders as a lat-long environment map. A bake of 4 bands holds
//! every band the sky has, so relit transfer `sum_k c_k t_k` is exact in the bands and whatever
//! differs from the path tracer is the baker's (or noise): shadowed transfer against direct
//! light only, interreflected transfer against two bounces, and least-squares vertices
//! interpolated at random surface points against the path tracer at those points.
//!
//! Tolerances come from the statistics, not from trial: the oracle's standard error (its own
//! share of the RMS, as `oracle::relative_rms` gives it), the baker's sampling error (from two
//! bakes with different seeds: the RMS of their difference over sqrt 2 is one bake's noise),
//! combined in quadrature and multiplied by [`SIGMAS`]; and, for interpolated vertex values
//! only, the representation's own error, measured and explained where it is used.
//!
//! Where Mitsuba is missing, `oracle::path_trace` says so and each test returns (under CI it
//! panics instead).

mod common;

use common::sky::sky;

use std::sync::OnceLock;

use glam::Vec3;
use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::texels::{bake_atlas, plan_atlas};
use prt_gpu::bake::{bake, bake_at, BakeOptions, CpuBackend, Fit, Mode, NoProgress, Transfer};
use prt_gpu::receivers::{self, Receivers};
use prt_gpu::scene::{builtin, prepare::prepare, Scene};
use prt_gpu::surface::texel_transfer_at;
use prt_gpu::testing::oracle::{self, OracleLight, OracleRadiance, SurfacePoint};

/// The multiplier of the combined standard error that a comparison may reach. The RMS of
/// independent noise over hundreds of points (N values, three channels each) is itself nearly
/// exact (its relative spread is about `sqrt(1 / 2N)`, 2% for 384 points), so an exact baker
/// reads close to 1 sigma; 3 leaves room for that spread many times over, and lets a bias through only up to `sqrt(3^2 - 1)` = 2.8 sigma,
/// which is why the sample counts below keep sigma small.
const SIGMAS: f64 = 3.0;

/// Every how many-th measurable vertex is measured, and the oracle's paths per point: the
/// oracle's noise falls as one over the root of the paths, and its time grows with points
/// times paths, so fewer points with more paths each give a tighter tolerance in the same time.
const VERTEX_STRIDE: usize = 16;
const PATHS: u32 = 8192;
const PATHS_BOUNCED: u32 = 8192;
/// Surface points drawn for the least-squares test (a few are left out, see
/// [`held_out_points`]).
const HELD_OUT: usize = 400;

/// Exit radiance of receiver `r` under the sky: per channel `sum_k c_k t_k`. The transfer is
/// RGB with the albedo in it (`bake::tint_by_albedo`; the default `Storage::Rgb`), and has more
/// bands than the sky, whose coefficients past its own bands are zero.
fn relight(transfer: &Transfer, r: usize, sky: &[Vec3]) -> Vec3 {
    assert_eq!(transfer.channels(), 3, "RGB transfer, albedo included");
    assert!(transfer.coeffs_per_channel() >= sky.len());
    let channel = |c: usize| -> f32 {
        let t = transfer.vertex_channel(r, c);
        sky.iter().zip(t).map(|(l, t)| l[c] * t).sum()
    };
    Vec3::new(channel(0), channel(1), channel(2))
}

/// The built-in scene, prepared (welded, Morton-ordered, normals computed): the geometry both
/// the baker and the oracle see.
fn scene() -> Scene {
    prepare(builtin::default_scene()).unwrap().0
}

/// A CPU bake of the built-in scene, checked to be of the prepared `scene` the oracle is given,
/// vertex for vertex (the bake prepares its input itself; preparing twice would reorder it).
fn bake_with(scene: &Scene, options: &BakeOptions) -> Transfer {
    let input = builtin::default_scene();
    let (baked, _) = bake(input, options, &CpuBackend, &NoProgress).unwrap();
    assert!(
        baked.scene == *scene,
        "the bake's prepared scene is not the oracle's"
    );
    baked.transfer
}

/// Every `stride`-th of the vertices `oracle::measurable_vertices` keeps (no crease within 10
/// degrees, no contact with another triangle): a rule of geometry alone.
fn measured_vertices(scene: &Scene, stride: usize) -> Vec<usize> {
    let keep = oracle::measurable_vertices(scene, 10.0);
    let kept: Vec<usize> = (0..scene.vertex_count()).filter(|&v| keep[v]).collect();
    println!(
        "measurable vertices: {} of {} ({} left out), every {stride}th measured: {}",
        kept.len(),
        keep.len(),
        keep.len() - kept.len(),
        kept.len().div_ceil(stride)
    );
    kept.into_iter().step_by(stride).collect()
}

/// What a comparison measured, each relative to the RMS of the oracle's radiance.
struct Figures {
    /// RMS of ours minus the oracle's.
    error: f64,
    /// The oracle's standard error (RMS over the points).
    oracle_noise: f64,
    /// One bake's sampling error, from two seeds.
    bake_noise: f64,
}

impl Figures {
    /// `ours` (seed 1) and `again` (another seed) against the oracle at the same points.
    fn of(ours: &[Vec3], again: &[Vec3], oracle: &OracleRadiance) -> Figures {
        let keep = vec![true; ours.len()];
        let (error, oracle_noise) = oracle::relative_rms(ours, oracle, &keep);
        let norm: f64 = oracle
            .radiance
            .iter()
            .map(|r| r.length_squared() as f64)
            .sum();
        let spread: f64 = ours
            .iter()
            .zip(again)
            .map(|(a, b)| (*a - *b).length_squared() as f64)
            .sum();
        Figures {
            error,
            oracle_noise,
            bake_noise: (spread / 2.0 / norm).sqrt(),
        }
    }

    /// The combined standard error of ours minus the oracle's.
    fn sigma(&self) -> f64 {
        self.oracle_noise.hypot(self.bake_noise)
    }

    /// What the error would read with the noise taken out (zero where the noise explains it all).
    fn excess(&self) -> f64 {
        (self.error.powi(2) - self.sigma().powi(2)).max(0.0).sqrt()
    }

    fn print(&self, what: &str, tolerance: f64) {
        self.print_with_floor(what, tolerance, None);
    }

    /// [`Figures::print`] for a tolerance of 3 sigma widened by a representation's `floor`.
    fn print_with_floor(&self, what: &str, tolerance: f64, floor: Option<f64>) {
        println!(
            "{what}: error {:.4}, oracle noise {:.4}, bake noise {:.4}, combined sigma {:.4}, \
             excess over the noise {:.4}, tolerance {tolerance:.4}",
            self.error,
            self.oracle_noise,
            self.bake_noise,
            self.sigma(),
            self.excess()
        );
        // One row of docs/accuracy.md (ci/accuracy.sh collects them).
        println!(
            "accuracy-row | distant light, {what} | {:.2}% | {:.2}% | bake noise \
             {:.2}%; bound {:.2}% (3 sigma{}) |",
            100.0 * self.error,
            100.0 * self.oracle_noise,
            100.0 * self.bake_noise,
            100.0 * tolerance,
            floor.map_or(String::new(), |f| format!(
                " and the floor {:.2}%, in quadrature",
                100.0 * f
            ))
        );
    }
}

/// The oracle's radiance at `points`, or `None` (printed) where Mitsuba is missing.
fn path_trace(
    scene: &Scene,
    points: &[SurfacePoint],
    light: &OracleLight,
    bounces: u32,
    paths: u32,
) -> Option<OracleRadiance> {
    let Some(traced) = oracle::path_trace(scene, points, light, bounces, paths) else {
        println!("skipping: the Mitsuba oracle is not available");
        return None;
    };
    println!(
        "oracle: {} points, {paths} paths each, {bounces} bounces, {:.1} s ({})",
        points.len(),
        traced.seconds,
        traced.variant
    );
    Some(traced)
}

/// The relit vertices of `measured` from a CPU bake with `options`, seed 1 and seed 2.
fn relit_vertices(
    scene: &Scene,
    measured: &[usize],
    sky: &[Vec3],
    options: &BakeOptions,
) -> (Vec<Vec3>, Vec<Vec3>) {
    let relit = |seed| {
        let transfer = bake_with(
            scene,
            &BakeOptions {
                seed,
                ..options.clone()
            },
        );
        measured
            .iter()
            .map(|&v| relight(&transfer, v, sky))
            .collect::<Vec<Vec3>>()
    };
    (relit(1), relit(2))
}

/// The measured vertices as the oracle's points: each on the first face that uses it.
fn oracle_points(scene: &Scene, measured: &[usize]) -> Vec<SurfacePoint> {
    let all = oracle::vertex_points(scene);
    assert_eq!(all.len(), scene.vertex_count());
    measured.iter().map(|&v| all[v]).collect()
}

/// Shadowed transfer, 4 bands, direct light only: exact in the bands, so the relit vertices
/// differ from the path tracer by noise alone.
#[test]
fn shadowed_vertices_match_the_path_tracer() {
    let scene = scene();
    let (sky, light) = sky();
    let measured = measured_vertices(&scene, VERTEX_STRIDE);
    let points = oracle_points(&scene, &measured);
    let Some(traced) = path_trace(&scene, &points, &light, 0, PATHS) else {
        return;
    };
    let options = BakeOptions {
        bands: 4,
        mode: Mode::Shadowed,
        ..BakeOptions::default()
    };
    let (ours, again) = relit_vertices(&scene, &measured, &sky, &options);
    let figures = Figures::of(&ours, &again, &traced);
    let tolerance = SIGMAS * figures.sigma();
    figures.print("built-in scene: shadowed vertices, 4 bands", tolerance);
    assert!(
        figures.error <= tolerance,
        "shadowed transfer is off the path tracer by {:.4} > {tolerance:.4}",
        figures.error
    );
}

/// Interreflected transfer, 4 bands and 2 bounces, against the path tracer's paths of up to
/// two bounces; at 1024 samples a vertex and to an error target. The bounces gather the vertices' transfer interpolated where each ray lands,
/// which is not exact where the light changes within a triangle; but the bounced light is
/// smooth and a small share of the whole, and measured, the error's excess over the noise is
/// 0.2% (printed) against a tolerance of 1.6%, so no floor is added.
#[test]
fn interreflected_vertices_match_the_path_tracer_with_two_bounces() {
    let scene = scene();
    let (sky, light) = sky();
    let measured = measured_vertices(&scene, VERTEX_STRIDE);
    let points = oracle_points(&scene, &measured);
    let Some(traced) = path_trace(&scene, &points, &light, 2, PATHS_BOUNCED) else {
        return;
    };
    let options = |bounces| BakeOptions {
        bands: 4,
        mode: Mode::Interreflected,
        bounces,
        ..BakeOptions::default()
    };
    let (ours, again) = relit_vertices(&scene, &measured, &sky, &options(2));
    let figures = Figures::of(&ours, &again, &traced);
    let tolerance = SIGMAS * figures.sigma();
    figures.print(
        "built-in scene: interreflected vertices, 4 bands, 2 bounces",
        tolerance,
    );
    // The comparison must be able to see the second bounce: without it the bake reads above
    // the tolerance.
    let (one_bounce, _) = relit_vertices(&scene, &measured, &sky, &options(1));
    let keep = vec![true; one_bounce.len()];
    let (error_one_bounce, _) = oracle::relative_rms(&one_bounce, &traced, &keep);
    println!("the same bake with 1 bounce: error {error_one_bounce:.4}");
    assert!(
        figures.error <= tolerance,
        "interreflected transfer is off the path tracer by {:.4} > {tolerance:.4}",
        figures.error
    );
    assert!(
        error_one_bounce > tolerance,
        "the comparison cannot tell 1 bounce from 2: {error_one_bounce:.4} <= {tolerance:.4}"
    );
    // To an error target, the bounces gathered through the rays the target chose: the same
    // rule against the same paths.
    let targeted = BakeOptions {
        target_error: Some(TargetError {
            relative: 0.01,
            max_samples: 8192,
        }),
        ..options(2)
    };
    let (ours, again) = relit_vertices(&scene, &measured, &sky, &targeted);
    let figures = Figures::of(&ours, &again, &traced);
    let tolerance = SIGMAS * figures.sigma();
    figures.print(
        "built-in scene: interreflected vertices to an error target of 1%, 4 bands, 2 bounces",
        tolerance,
    );
    assert!(
        figures.error <= tolerance,
        "interreflected transfer to an error target is off the path tracer by {:.4} > \
         {tolerance:.4}",
        figures.error
    );
}

/// Held-out points drawn uniformly by area, and the rule for those left out: a point that a
/// triangle other than its own passes within `1e-5` of the scene's extent (the contact rule
/// `oracle::measurable_vertices` applies to vertices, applied at the point): the ground under
/// the box and the box's bottom, which lie in one plane and which no viewer sees, and points in
/// contact with another part, where the radiance is a step. Geometry alone decides, nothing of
/// the baker's. Creases need no rule here: a point inside a face has one radiance, and the
/// oracle's ray lands on that face.
fn held_out_points(scene: &Scene, count: usize, seed: u64) -> Vec<receivers::SurfacePoint> {
    let drawn = receivers::uniform_points(scene, count, seed);
    let (lo, hi) = scene.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let epsilon = 1e-5 * (hi - lo).max_element();
    let corners = |t: usize| scene.triangles[t].map(|i| scene.positions[i as usize]);
    let boxes: Vec<(Vec3, Vec3)> = (0..scene.triangle_count())
        .map(|t| {
            let [a, b, c] = corners(t);
            (a.min(b).min(c) - epsilon, a.max(b).max(c) + epsilon)
        })
        .collect();
    let kept: Vec<receivers::SurfacePoint> = drawn
        .iter()
        .filter(|point| {
            let p = position(scene, point);
            !boxes.iter().enumerate().any(|(t, (lo, hi))| {
                t != point.triangle as usize
                    && p.cmpge(*lo).all()
                    && p.cmple(*hi).all()
                    && oracle::distance_to_triangle(p, corners(t)) <= epsilon
            })
        })
        .copied()
        .collect();
    println!(
        "held-out points: {} drawn, {} in contact with another triangle left out",
        drawn.len(),
        drawn.len() - kept.len()
    );
    kept
}

/// Where a point lies.
fn position(scene: &Scene, point: &receivers::SurfacePoint) -> Vec3 {
    interpolate(scene, point, &scene.positions)
}

/// A vertex attribute interpolated at a point with its barycentrics, as a renderer does.
fn interpolate(scene: &Scene, point: &receivers::SurfacePoint, values: &[Vec3]) -> Vec3 {
    scene.triangles[point.triangle as usize]
        .iter()
        .zip(point.barycentrics)
        .map(|(&v, b)| values[v as usize] * b)
        .sum()
}

/// RMS of `a - b` relative to the RMS of `scale`, with `noise` (relative, in quadrature) taken
/// out: what is left of a difference once the sampling noise in it is accounted for.
fn beyond_noise(a: &[Vec3], b: &[Vec3], scale: &[Vec3], noise: f64) -> f64 {
    let square = |x: &mut dyn Iterator<Item = Vec3>| x.map(|d| d.length_squared() as f64).sum();
    let difference: f64 = square(&mut a.iter().zip(b).map(|(x, y)| *x - *y));
    let norm: f64 = square(&mut scale.iter().copied());
    (difference / norm - noise * noise).max(0.0).sqrt()
}

/// Held-out surface points of the built-in scene, the path tracer there, and the baker's own
/// transfer at the points themselves (the same receivers a fit or a lightmap bakes, placed at
/// the points, default samples, seeds 1 and 2) against it: shared by the tests of what is
/// interpolated between them (least-squares vertices, lightmap texels).
struct Surface {
    scene: Scene,
    held: Vec<receivers::SurfacePoint>,
    traced: OracleRadiance,
    direct: Vec<Vec3>,
    direct_figures: Figures,
}

/// What the oracle is given of surface points: position, shading normal, face.
fn points_for_the_oracle(scene: &Scene, held: &[receivers::SurfacePoint]) -> Vec<SurfacePoint> {
    let normals = scene.normals.as_deref().unwrap();
    held.iter()
        .map(|p| SurfacePoint {
            position: position(scene, p),
            normal: interpolate(scene, p, normals).normalize(),
            face: p.triangle,
        })
        .collect()
}

/// The baker's own shadowed transfer (4 bands, default samples) at the points `held`, relit
/// under the sky.
fn shadowed_at_points(
    scene: &Scene,
    held: &[receivers::SurfacePoint],
    seed: u64,
    sky: &[Vec3],
) -> Vec<Vec3> {
    let receivers = Receivers::at_points(scene, held);
    let options = BakeOptions {
        seed,
        bands: 4,
        mode: Mode::Shadowed,
        ..BakeOptions::default()
    };
    let backend = CpuBackend;
    let (transfer, _) = bake_at(scene, &receivers, &options, &backend, None, &NoProgress).unwrap();
    (0..held.len())
        .map(|r| relight(&transfer, r, sky))
        .collect()
}

/// [`Surface`], made once; `None` where Mitsuba is missing.
fn surface() -> Option<&'static Surface> {
    static SURFACE: OnceLock<Option<Surface>> = OnceLock::new();
    SURFACE
        .get_or_init(|| {
            let scene = scene();
            let (sky, light) = sky();
            let held = held_out_points(&scene, HELD_OUT, 5);
            let points = points_for_the_oracle(&scene, &held);
            let traced = path_trace(&scene, &points, &light, 0, PATHS)?;
            let at_points = |seed| shadowed_at_points(&scene, &held, seed, &sky);
            // The baker at the points: noise alone.
            let (direct, direct_again) = (at_points(1), at_points(2));
            let direct_figures = Figures::of(&direct, &direct_again, &traced);
            direct_figures.print(
                "built-in scene: shadowed surface points, 4 bands",
                SIGMAS * direct_figures.sigma(),
            );
            Some(Surface {
                scene,
                held,
                traced,
                direct,
                direct_figures,
            })
        })
        .as_ref()
}

/// Least-squares vertices (`--fit least-squares`, with the README's `--samples 128`: the rays
/// of a default point bake), interpolated at held-out points as a renderer interpolates them,
/// against the path tracer at those points; shadowed, 4 bands.
///
/// Interpolated vertex values are not exact between the vertices: a linear field per triangle
/// cannot follow a shadow edge or a crease inside it. That representation error is measured:
/// the baker's own transfer at the points themselves (the same receivers the fit bakes, placed
/// at the held-out points, 1024 samples) is checked against the path tracer by noise alone, and
/// the RMS difference between it and the interpolated fit, the noise of both taken out, is the
/// floor. It is not added to the tolerance because it is below one combined sigma (asserted):
/// errors add in quadrature, so the fit's expected error stays under sqrt 2 sigma, well inside
/// [`SIGMAS`]. A fit (or an interpolation) that went wrong between the vertices fails there.
/// And the floor must lie below that of point-sampled vertices baked with the same rays:
/// what the fit is for.
#[test]
fn least_squares_vertices_match_the_path_tracer_between_the_vertices() {
    let Some(surface) = surface() else {
        return;
    };
    let (scene, held, traced) = (&surface.scene, &surface.held, &surface.traced);
    let (sky, _) = sky();
    let base = BakeOptions {
        bands: 4,
        mode: Mode::Shadowed,
        ..BakeOptions::default()
    };
    let density = base.point_density.per_vertex;
    let fit = BakeOptions {
        fit: Fit::LeastSquares,
        samples: (base.samples as f32 / density) as u32,
        ..base.clone()
    };
    // Vertex transfer relit at the vertices, then interpolated (relighting is linear).
    let interpolated = |options: &BakeOptions, seed| -> Vec<Vec3> {
        let transfer = bake_with(
            scene,
            &BakeOptions {
                seed,
                ..options.clone()
            },
        );
        let relit: Vec<Vec3> = (0..scene.vertex_count())
            .map(|v| relight(&transfer, v, &sky))
            .collect();
        held.iter().map(|p| interpolate(scene, p, &relit)).collect()
    };
    let (direct, direct_figures) = (&surface.direct, &surface.direct_figures);
    let direct_tolerance = SIGMAS * direct_figures.sigma();

    // The fit, interpolated.
    let (fitted, fitted_again) = (interpolated(&fit, 1), interpolated(&fit, 2));
    let figures = Figures::of(&fitted, &fitted_again, traced);
    let fit_floor = beyond_noise(
        &fitted,
        direct,
        &traced.radiance,
        figures.bake_noise.hypot(direct_figures.bake_noise),
    );
    let tolerance = SIGMAS * figures.sigma();
    figures.print(
        "built-in scene: least-squares vertices at the points",
        tolerance,
    );
    println!(
        "least-squares vertices against the baker at the points: representation floor \
         {fit_floor:.4}, at most one sigma {:.4}",
        figures.sigma()
    );

    // Point-sampled vertices with the same rays, interpolated: their floor.
    let (point, point_again) = (interpolated(&base, 1), interpolated(&base, 2));
    let point_figures = Figures::of(&point, &point_again, traced);
    let point_floor = beyond_noise(
        &point,
        direct,
        &traced.radiance,
        point_figures.bake_noise.hypot(direct_figures.bake_noise),
    );
    println!(
        "point-sampled vertices at the points: error {:.4}, representation floor {point_floor:.4}",
        point_figures.error
    );

    assert!(
        direct_figures.error <= direct_tolerance,
        "transfer at surface points is off the path tracer by {:.4} > {direct_tolerance:.4}",
        direct_figures.error
    );
    assert!(
        figures.error <= tolerance,
        "least-squares vertices are off the path tracer by {:.4} > {tolerance:.4}",
        figures.error
    );
    assert!(
        fit_floor <= figures.sigma(),
        "the fit's representation floor {fit_floor:.4} is above one sigma {:.4}",
        figures.sigma()
    );
    assert!(
        fit_floor < point_floor,
        "the fit's representation floor {fit_floor:.4} is not below point sampling's \
         {point_floor:.4}"
    );
}

/// Lightmap texels (`--lightmap`, shadowed, 4 bands, the default samples per texel), looked up
/// bilinearly at the held-out points as a renderer samples a lightmap
/// (`surface::texel_transfer_at`), against the path tracer there.
///
/// A texel is the transfer at one point a texel wide, so bilinear texels are not exact between
/// the texel centres, as interpolated vertices are not between the vertices: the floor (texels
/// against the baker at the points themselves, the noise of both taken out) is measured, and
/// the tolerance is [`SIGMAS`] sigma widened by it in quadrature. The floor is the lightmap's
/// own, so it is held to what it must do: shrink as the texels do (a lookup that read the
/// wrong texels, or charts that leaked, would not). Beside it the floor of point-sampled
/// vertices is printed: the atlas of one chart per triangle reaches it only at 768 texels a
/// side (1.85% against 1.84% when written), its texels near every triangle's edge read from
/// the gutter. Least-squares texels (`--fit least-squares`: fitted to four points a texel,
/// each at a quarter of the samples) must match the path tracer too, with a floor below the
/// point-sampled texels' at the same size.
#[test]
fn lightmap_texels_match_the_path_tracer_at_surface_points() {
    let Some(surface) = surface() else {
        return;
    };
    let (scene, held, traced) = (&surface.scene, &surface.held, &surface.traced);
    let (sky, _) = sky();
    let options = BakeOptions {
        bands: 4,
        mode: Mode::Shadowed,
        ..BakeOptions::default()
    };
    let vertex = |seed| {
        bake_with(
            scene,
            &BakeOptions {
                seed,
                ..options.clone()
            },
        )
    };
    let vertices = [vertex(1), vertex(2)];
    let floors: Vec<f64> = LIGHTMAP_SIZES
        .into_iter()
        .map(|size| {
            let what = format!("lightmap {size} texels");
            let floor = lightmap_matches_the_path_tracer(surface, &vertices, &options, size, &what);
            println!("lightmap {size}: representation floor {floor:.4}");
            floor
        })
        .collect();
    // Least-squares texels (`--fit least-squares`) at the coarse size, four points a texel at
    // a quarter of the samples each: the same rays a texel area, a lower floor.
    let size = LIGHTMAP_SIZES[0];
    let fitted = BakeOptions {
        fit: Fit::LeastSquares,
        samples: options.samples / 4,
        ..options.clone()
    };
    let what = format!("least-squares lightmap {size} texels");
    let fitted_floor = lightmap_matches_the_path_tracer(surface, &vertices, &fitted, size, &what);
    assert!(
        fitted_floor < floors[0],
        "least-squares floor {fitted_floor:.4}, point-sampled texels' {:.4}",
        floors[0]
    );
    let relit: Vec<Vec3> = (0..scene.vertex_count())
        .map(|v| relight(&vertices[0], v, &sky))
        .collect();
    let at_points: Vec<Vec3> = held.iter().map(|p| interpolate(scene, p, &relit)).collect();
    let vertex_floor = beyond_noise(&at_points, &surface.direct, &traced.radiance, 0.0);
    println!("lightmap floors {floors:?}; point-sampled vertices' floor {vertex_floor:.4}");
    println!(
        "accuracy-row | distant light, built-in scene: point-sampled vertices interpolated at \
         the points, representation floor | {:.2}% | | beside the lightmaps' floors {:.2}% ({}), \
         {:.2}% ({}) |",
        100.0 * vertex_floor,
        100.0 * floors[0],
        LIGHTMAP_SIZES[0],
        100.0 * floors[1],
        LIGHTMAP_SIZES[1]
    );
    assert!(floors[1] < 0.75 * floors[0], "{floors:?}");
}

/// Bakes a lightmap of `size` texels with `options` twice (seeds 1 and 2, on the vertices
/// baked with the same seeds), looks it up bilinearly at the held-out points, and asserts it
/// matches the path tracer there within [`SIGMAS`] sigma widened by its representation floor;
/// returns that floor. `what` names the map in the figures printed.
fn lightmap_matches_the_path_tracer(
    surface: &Surface,
    vertices: &[Transfer; 2],
    options: &BakeOptions,
    size: u32,
    what: &str,
) -> f64 {
    let (scene, held, traced) = (&surface.scene, &surface.held, &surface.traced);
    let (sky, _) = sky();
    let atlas = plan_atlas(scene, size).unwrap();
    let looked_up = |seed: u64| -> Vec<Vec3> {
        let options = BakeOptions {
            seed,
            ..options.clone()
        };
        let vertices = &vertices[seed as usize - 1];
        let (lightmap, _) =
            bake_atlas(scene, vertices, &options, &atlas, &CpuBackend, &NoProgress).unwrap();
        let transfer = texel_transfer_at(&lightmap, held);
        (0..held.len())
            .map(|r| relight(&transfer, r, &sky))
            .collect()
    };
    let (texels, texels_again) = (looked_up(1), looked_up(2));
    let figures = Figures::of(&texels, &texels_again, traced);
    let noise = figures.bake_noise.hypot(surface.direct_figures.bake_noise);
    let floor = beyond_noise(&texels, &surface.direct, &traced.radiance, noise);
    let tolerance = (SIGMAS * figures.sigma()).hypot(floor);
    figures.print_with_floor(
        &format!("built-in scene: {what}, bilinear at the points"),
        tolerance,
        Some(floor),
    );
    assert!(
        figures.error <= tolerance,
        "the {what} is off the path tracer by {:.4} > {tolerance:.4}",
        figures.error
    );
    floor
}

/// Lightmap sizes for the texel test: a coarse and a fine one.
const LIGHTMAP_SIZES: [u32; 2] = [256, 512];

/// A glTF scene's own lightmap UV set (`TEXCOORD_1` of a ground and a card floating over it,
/// each laid out by a planar projection): the lightmap the CLI bakes on that set, read back
/// from its files and looked up through the set at held-out points of the ground (in and out
/// of the card's shadow), against the path tracer at those points; shadowed, 4 bands, under
/// the sky. The tolerance is [`SIGMAS`] sigma widened in quadrature by the texels'
/// representation floor, measured as in [`lightmap_texels_match_the_path_tracer_at_surface_points`]
/// against the baker's own transfer at the points.
#[test]
fn a_gltf_lightmap_on_its_own_uv_set_matches_the_path_tracer() {
    const SIZE: &str = "128";
    let dir = tempfile::tempdir().unwrap();
    let input = common::gltf_builder::ground_and_card_gltf(dir.path(), Some(1), true, false);
    // The prepared scene keeps the loaded triangles in order (none is degenerate): the ground
    // is its first 128.
    let (_, loaded) = prt_gpu::scene::gltf::load(&input).unwrap();
    let scene = prepare(loaded).unwrap().0;
    let held = common::points_on(0..128, HELD_OUT);
    let points = points_for_the_oracle(&scene, &held);
    let (sky, light) = sky();
    let Some(traced) = path_trace(&scene, &points, &light, 0, PATHS) else {
        return;
    };
    let looked_up = |seed: u64| -> Vec<Vec3> {
        let output = format!("lit{seed}.prt.glb");
        let seed = seed.to_string();
        let out = common::prt_gpu(
            &[
                "bake",
                input.to_str().unwrap(),
                "--lightmap",
                SIZE,
                "--seed",
                &seed,
                "--device",
                "cpu",
                "-o",
                &output,
            ],
            dir.path(),
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let baked = prt_gpu::glb::read_glb(&dir.path().join(&output)).unwrap();
        let texels = baked.lightmap.expect("the lightmap is read back");
        assert_eq!(texels.set, 1, "looked up through TEXCOORD_1");
        let transfer = texel_transfer_at(&texels, &held);
        (0..held.len())
            .map(|r| relight(&transfer, r, &sky))
            .collect()
    };
    let at_points = |seed| shadowed_at_points(&scene, &held, seed, &sky);
    let (direct, direct_again) = (at_points(1), at_points(2));
    let direct_figures = Figures::of(&direct, &direct_again, &traced);
    let (texels, texels_again) = (looked_up(1), looked_up(2));
    let figures = Figures::of(&texels, &texels_again, &traced);
    let floor = beyond_noise(
        &texels,
        &direct,
        &traced.radiance,
        figures.bake_noise.hypot(direct_figures.bake_noise),
    );
    let tolerance = (SIGMAS * figures.sigma()).hypot(floor);
    direct_figures.print(
        "ground and card glTF: shadowed surface points",
        SIGMAS * direct_figures.sigma(),
    );
    figures.print_with_floor(
        &format!("ground and card glTF: lightmap {SIZE} texels on its own TEXCOORD_1"),
        tolerance,
        Some(floor),
    );
    assert!(
        direct_figures.error <= SIGMAS * direct_figures.sigma(),
        "points off the path tracer by {:.4}",
        direct_figures.error
    );
    assert!(
        figures.error <= tolerance,
        "the UV-set lightmap is off the path tracer by {:.4} > {tolerance:.4}",
        figures.error
    );
    // The control: the same lookups held to the path tracer at the points mirrored across the
    // card's shadow (a lookup through the wrong set, or a lightmap of the wrong scene, reads so).
    let mirrored_points: Vec<_> = held
        .iter()
        .map(|p| {
            let at = position(&scene, p);
            common::nearest_point_on_ground(&scene, Vec3::new(-at.x, 0.0, at.z))
        })
        .collect();
    let control_points = points_for_the_oracle(&scene, &mirrored_points);
    let control_truth = path_trace(&scene, &control_points, &light, 0, PATHS / 8).unwrap();
    let (control, _) = oracle::relative_rms(&texels, &control_truth, &vec![true; held.len()]);
    println!("control: the lookups against the mirrored points {control:.4}");
    assert!(
        control > 4.0 * tolerance,
        "control {control} against {tolerance}"
    );
}
