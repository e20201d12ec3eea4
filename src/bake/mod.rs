//! The bake: options in, one [`Transfer`] out, whichever backend computes it.

pub mod adaptive;
mod at_receivers;
mod backend;
mod baked;
mod bands;
pub mod bounce;
pub mod cpu;
pub mod gpu;
mod inputs;
mod need;
mod options;
mod points;
mod shard;
pub mod spill;
pub mod split;
pub mod stream;
pub mod subsurface;
pub mod texels;
mod vertices;

// The bake's parts, each in its own file; their items are the module's.
pub use at_receivers::*;
pub use backend::*;
pub use baked::*;
pub use bands::*;
pub use inputs::*;
pub use options::*;
pub use shard::*;

use std::borrow::Cow;
use std::time::Instant;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bvh::Bvh;
use crate::error::{Error, Result};
use crate::ray::offset_ray_origin;
use crate::receivers;
use crate::receivers::fit::FitReport;
use crate::receivers::uv_set::UvSet;
use crate::receivers::{spread_points, PointDensity, Receivers, SurfacePoint};
use crate::sampling::{
    Estimator, ReceiverTurns, SampleSet, Sampling, VertexDirections, MAX_SAMPLES,
};
use crate::scene::prepare::{kept_triangles, prepare_mapped, PrepareReport, VertexMap};
use crate::scene::Scene;
use crate::sh::rotation::EulerShRotation;
use crate::sh::{coeff_count, ShTable, CONVENTION, MAX_BANDS};
use points::{Fitting, PointChunks};
use vertices::{vertex_transfer, AtReceivers, Scattered, VertexTransfer};

/// Receives progress from long stages; the CLI draws it, tests ignore it.
pub trait Progress: Sync {
    /// A stage of `total` work items begins.
    fn stage(&self, _name: &str, _total: u64) {}
    /// `done` more items of the current stage are finished.
    fn advance(&self, _done: u64) {}
    /// What the current stage is doing now, in a few words ("" for nothing more than its
    /// name): a long step inside one of its items.
    fn detail(&self, _text: &str) {}
}

/// Progress that goes nowhere.
pub struct NoProgress;

impl Progress for NoProgress {}

/// The whole bake: prepare the mesh, build the BVH, choose the receivers, draw samples,
/// compute transfer at the receivers and, for the least-squares fit, the vertex values that
/// best match it.
pub fn bake(
    scene: Scene,
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(BakedMesh, BakeReport)> {
    bake_from(
        scene,
        options,
        backend,
        DirectSource::Compute,
        None,
        progress,
    )
}

/// The atlas of the lightmap the options ask for on the prepared `scene`: on its own UV set
/// (given per prepared triangle), or generated.
fn lightmap_atlas(
    scene: &Scene,
    options: &BakeOptions,
    uv_set: Option<&UvSet>,
) -> Result<Option<receivers::atlas::Atlas>> {
    match (options.lightmap, uv_set) {
        (Some(size), Some(set)) => {
            if set.corners.len() != scene.triangles.len() {
                return Err(Error::Geometry(format!(
                    "the lightmap's UV set has {} triangles, the prepared scene {}",
                    set.corners.len(),
                    scene.triangles.len()
                )));
            }
            Ok(Some(set.atlas(size)))
        }
        (Some(size), None) => Ok(Some(texels::plan_atlas(scene, size)?)),
        (None, _) => Ok(None),
    }
}

/// Where a bake's direct pass comes from.
pub enum DirectSource {
    /// Computed here, on the bake's backend.
    Compute,
    /// Already computed (by the shards of a sharded bake, merged), on the backend its
    /// `ran_on` describes: the rest of the bake (fit, bounces, lightmap) runs here.
    Given(Box<dyn GivenDirect>),
}

impl DirectSource {
    /// The given pass, if any.
    fn given(&self) -> Option<&dyn GivenDirect> {
        match self {
            DirectSource::Compute => None,
            DirectSource::Given(given) => Some(given.as_ref()),
        }
    }

    /// What the direct pass runs (or ran) on: `backend`, or what the given pass records.
    fn ran_on(&self, backend: &dyn Backend) -> String {
        match self {
            DirectSource::Compute => backend.describe(),
            DirectSource::Given(given) => given.ran_on(),
        }
    }
}

/// What every bake does before its direct pass: the prepared scene, its receivers, and what
/// the backends read.
struct Planned {
    scene: Scene,
    prepare: PrepareReport,
    vertex_map: VertexMap,
    receivers: Receivers,
    points: Vec<SurfacePoint>,
    inputs: BakeInputs,
    seconds: f64,
}

/// What a bake's report keeps of its [`Planned`] once the vertices are baked: the counts of
/// its receivers (a least-squares fit's points), samples and tree, and what preparing did.
struct PlanReport {
    prepare: PrepareReport,
    vertex_map: VertexMap,
    receivers: usize,
    points: usize,
    samples_used: usize,
    bvh_nodes: usize,
    seconds: f64,
}

impl Planned {
    /// The scene and what the report needs, the receivers and their tree let go (before a
    /// lightmap bakes its own).
    fn let_go(self) -> (Scene, PlanReport) {
        let report = PlanReport {
            prepare: self.prepare,
            vertex_map: self.vertex_map,
            receivers: self.receivers.len(),
            points: self.points.len(),
            samples_used: self.inputs.samples.len(),
            bvh_nodes: self.inputs.bvh.nodes.len(),
            seconds: self.seconds,
        };
        (self.scene, report)
    }
}

fn plan(scene: Scene, options: &BakeOptions) -> Result<Planned> {
    let started = Instant::now();
    let (scene, prepare, vertex_map) = prepare_with_albedo(scene, options)?;
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let (receivers, points) = choose_receivers(&scene, &bvh, options);
    let inputs = BakeInputs::with_tree(&scene, &receivers, bvh, &receivers_turning(options));
    Ok(Planned {
        scene,
        prepare,
        vertex_map,
        receivers,
        points,
        inputs,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// [`bake`] with its direct pass from `source`, and its lightmap (when the options ask for one)
/// on `uv_set` (given per triangle of `scene`), or on a generated atlas without one.
pub fn bake_from(
    scene: Scene,
    options: &BakeOptions,
    backend: &dyn Backend,
    source: DirectSource,
    uv_set: Option<&UvSet>,
    progress: &dyn Progress,
) -> Result<(BakedMesh, BakeReport)> {
    options.validate()?;
    let uv_set = uv_set.map(|set| set.kept(&kept_triangles(&scene)));
    let planned = plan(scene, options)?;
    // A lightmap that cannot fit fails now, not after the vertices are baked.
    let atlas = lightmap_atlas(&planned.scene, options, uv_set.as_ref())?;
    // A generated atlas gives a vertex on a chart seam coordinates on each chart, and the mesh
    // is split there to carry them; a scene's own set keeps them on its vertices.
    let set = uv_set.as_ref().map(|set| set.set);

    let (scene, receivers, points) = (&planned.scene, &planned.receivers, &planned.points);
    let fitting = (options.fit == Fit::LeastSquares).then(|| Fitting::new(scene, points, progress));
    let albedo = reflecting_albedo(receivers, options);

    let started = Instant::now();
    let at = (fitting.as_ref(), &albedo[..]);
    let (mut at_receivers, ran_on) =
        values_at_receivers(&planned, at, source, options, backend, progress)?;
    let adaptive_report = options
        .target_error
        .zip(at_receivers.adaptive())
        .map(|(target, receivers)| adaptive::AdaptiveReport::of(receivers, &target));
    let seconds_transfer = started.elapsed().as_secs_f64();

    let on_scene = (scene, &planned.vertex_map[..]);
    let at = (&mut at_receivers, fitting.as_ref(), &albedo[..]);
    let fitted = vertex_transfer(on_scene, at, options, backend, progress)?;
    let VertexTransfer {
        transfer,
        bounces,
        fit_report,
        seconds_fit,
        subsurface,
        scattered,
    } = fitted;
    let albedo_free = match options.albedo_free() {
        true => Some(at_receivers.albedo_free_at_vertices(fitting.as_ref(), options.bands)?),
        false => None,
    };
    let (rays_cast, gather_entries) = at_receivers.counts();
    drop((fitting, at_receivers, albedo));
    let (transfer, albedo_free) = stored(transfer, albedo_free, scene, options);
    let (scene, planned) = planned.let_go();
    let (scene, transfer, lightmap, texel_report) = match &atlas {
        None => (scene, transfer, None, None),
        Some(atlas) => {
            let at = (atlas, set, scattered.as_ref());
            add_lightmap(scene, transfer, at, options, backend, progress)?
        }
    };
    let fit_points = (options.fit == Fit::LeastSquares).then_some(planned.points as u32);
    let samples_used = planned.samples_used;
    // An error-targeted bake records the mean over receivers.
    let samples = adaptive_report
        .as_ref()
        .map_or(samples_used, |r| r.samples_mean.round() as usize);
    let metadata = BakeMetadata {
        channels: transfer.channels(),
        albedo_free,
        backend: ran_on,
        subsurface: SubsurfaceMetadata::of(options, subsurface),
        ..metadata_for(options, samples, bounces.len(), fit_points)
    };
    let report = BakeReport {
        prepare: planned.prepare,
        vertex_map: planned.vertex_map,
        receivers: planned.receivers,
        samples_used: samples_used as u32,
        rays_cast,
        bvh_nodes: planned.bvh_nodes,
        seconds_prepare: planned.seconds,
        seconds_transfer,
        seconds_fit,
        fit: fit_report,
        texels: texel_report,
        adaptive: adaptive_report,
        bounces,
        gather_entries,
        backend: backend.describe(),
        subsurface,
    };
    Ok((
        BakedMesh {
            scene,
            transfer,
            metadata,
            lightmap,
        },
        report,
    ))
}

/// The albedo each receiver reflects with: its own, or white in a translucent medium, whose
/// scattering from vertex to vertex replaces it.
fn reflecting_albedo<'a>(receivers: &'a Receivers, options: &BakeOptions) -> Cow<'a, [Vec3]> {
    match options.subsurface.is_some() || options.scene_media.is_some() {
        true => Cow::Owned(vec![Vec3::ONE; receivers.len()]),
        false => Cow::Borrowed(&receivers.albedo),
    }
}

/// The values at `planned`'s receivers: a fit's points baked in runs where the options ask
/// (or, given, read in runs), else the whole direct pass, computed or given; and what it ran
/// on.
fn values_at_receivers(
    planned: &Planned,
    (fitting, albedo): (Option<&Fitting>, &[Vec3]),
    source: DirectSource,
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(AtReceivers, String)> {
    match (fitting, options.point_chunk, source) {
        (Some(fitting), Some(chunk), source) => {
            let ran_on = source.ran_on(backend);
            let (at, runs) = ((fitting, albedo), (chunk, &source));
            let chunks = PointChunks::bake(planned, at, runs, options, backend, progress)?;
            Ok((AtReceivers::Chunked(chunks), ran_on))
        }
        (_, _, source) => {
            let (direct, ran_on) = direct_pass(source, planned, options, backend, progress)?;
            Ok((AtReceivers::Whole(direct), ran_on))
        }
    }
}

/// The direct pass of `planned`'s receivers, computed on `backend` or given (and checked), and
/// what it ran on.
fn direct_pass(
    source: DirectSource,
    planned: &Planned,
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(DirectPass, String)> {
    let ran_on = source.ran_on(backend);
    let direct = match source {
        DirectSource::Compute => {
            let all = 0..planned.receivers.len();
            direct_or_adaptive(&planned.inputs, all, options, backend, progress)?
        }
        DirectSource::Given(given) => {
            let direct = given.direct(0..given.receivers())?;
            check_given(&direct, planned.receivers.len(), options)?;
            direct
        }
    };
    Ok((direct, ran_on))
}

/// The direct pass of the receivers `range`, a run of a bake streamed or fitted in runs: cast
/// on `backend` (from `inputs`), or read from `given` and checked. Progress advances per
/// receiver either way.
pub(super) fn direct_run(
    given: Option<&dyn GivenDirect>,
    (inputs, range): (&BakeInputs, std::ops::Range<usize>),
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<DirectPass> {
    let Some(given) = given else {
        return direct_or_adaptive(inputs, range, options, backend, &Advancing(progress));
    };
    let direct = given.direct(range.clone())?;
    check_given(&direct, range.len(), options)?;
    progress.advance(range.len() as u64);
    Ok(direct)
}

/// Refuses a given direct pass of `given` receivers where the bake has `receivers`.
pub(super) fn check_given_count(given: usize, receivers: usize) -> Result<()> {
    match given == receivers {
        true => Ok(()),
        false => Err(Error::Options(format!(
            "the given direct pass covers {given} receivers, and this bake has {receivers}"
        ))),
    }
}

/// Refuses a given direct pass that is not one of `receivers` receivers' (wrong count, or no
/// gather matrix for interreflection).
pub(super) fn check_given(
    direct: &DirectPass,
    receivers: usize,
    options: &BakeOptions,
) -> Result<()> {
    let expected = receivers * coeff_count(options.bands);
    let rows_fit = match (&direct.matrix, options.mode) {
        (Some(matrix), Mode::Interreflected) => matrix.rows() == receivers,
        (None, Mode::Interreflected) => false,
        (_, _) => true,
    };
    let adaptive_fits = match (&direct.adaptive, options.target_error) {
        (Some(receivers_of), Some(_)) => receivers_of.len() == receivers,
        (None, None) => true,
        _ => false,
    };
    if !adaptive_fits {
        return Err(Error::Options(format!(
            "the given direct pass {} each receiver's samples and error, which an error target \
             {} ({} receivers)",
            if direct.adaptive.is_some() {
                "carries"
            } else {
                "lacks"
            },
            if options.target_error.is_some() {
                "needs for all"
            } else {
                "would not give"
            },
            receivers
        )));
    }
    if direct.scalar.len() != expected || !rows_fit {
        return Err(Error::Options(format!(
            "the given direct pass holds {} values for {} receivers of {} coefficients",
            direct.scalar.len(),
            receivers,
            coeff_count(options.bands)
        )));
    }
    Ok(())
}

/// The transfer as `options.storage` stores it, and whether it left the albedo out. Lean: one
/// channel where one suffices: direct transfer becomes the albedo-free vertex values
/// (`albedo_free`, fitted as the RGB was); interreflected transfer keeps its red channel when
/// every albedo is grey.
fn stored(
    rgb: Transfer,
    albedo_free: Option<Vec<f32>>,
    scene: &Scene,
    options: &BakeOptions,
) -> (Transfer, bool) {
    if options.storage == Storage::Rgb {
        return (rgb, false);
    }
    let n = coeff_count(rgb.bands());
    if options.mode != Mode::Interreflected {
        let coeffs = albedo_free.expect("lean direct transfer's albedo-free values");
        let transfer = Transfer::new(rgb.bands(), 1, rgb.vertex_count(), coeffs)
            .expect("one channel of the vertices' coefficients");
        return (transfer, true);
    }
    if scene.albedo.iter().any(|a| a.x != a.y || a.y != a.z) {
        return (rgb, false);
    }
    let coeffs = rgb
        .coeffs()
        .chunks_exact(3 * n)
        .flat_map(|v| v[..n].iter().copied())
        .collect();
    let transfer = Transfer::new(rgb.bands(), 1, rgb.vertex_count(), coeffs)
        .expect("one channel of the vertices' coefficients");
    (transfer, false)
}

/// The scene, its transfer and its lightmap's bake: the texels of `atlas` baked, and the mesh
/// split where its charts meet to carry their coordinates, unless they are the scene's own
/// `set`.
fn add_lightmap(
    scene: Scene,
    transfer: Transfer,
    (atlas, set, scattered): (&receivers::atlas::Atlas, Option<u32>, Option<&Scattered>),
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(
    Scene,
    Transfer,
    Option<TexelBake>,
    Option<texels::TexelReport>,
)> {
    let at = (&scene, &transfer, atlas);
    let scatter = scattered.map(|s| subsurface::PointScatter {
        media: &s.materials,
        of_vertex: &s.of_vertex,
        incoming: &s.incoming,
    });
    let (mut lightmap, report) = match options.texel_groups {
        Some(divided) if scatter.is_none() => {
            texels::bake_atlas_held(at, options, backend, progress, divided)?
        }
        _ => texels::bake_atlas_in(at, scatter.as_ref(), options, backend, progress)?,
    };
    lightmap.set = set.unwrap_or(0);
    let (scene, transfer) = match set {
        None => split::split_at_seams(&scene, &transfer, &lightmap.texcoords),
        Some(_) => (scene, transfer),
    };
    Ok((scene, transfer, Some(lightmap), Some(report)))
}

/// The scene prepared for the bake, its albedo replaced where the options say so.
fn prepare_with_albedo(
    scene: Scene,
    options: &BakeOptions,
) -> Result<(Scene, PrepareReport, VertexMap)> {
    let (mut scene, report, map) = prepare_mapped(scene)?;
    if let Some(albedo) = options.albedo {
        scene.albedo.iter_mut().for_each(|a| *a = albedo);
    }
    Ok((scene, report, map))
}

/// The direct pass of the receivers `range` of `owned`: a fixed sample count on the backend,
/// or to the options' error target (with each receiver's samples and error).
pub(super) fn direct_or_adaptive(
    owned: &BakeInputs,
    range: std::ops::Range<usize>,
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<DirectPass> {
    let Some(target) = &options.target_error else {
        let view = owned.view();
        let part = view.part(range);
        return backend.direct_pass(&part, options.mode, progress);
    };
    progress.stage("transfer", range.len() as u64);
    adaptive::adaptive_direct_pass(
        backend,
        owned,
        range,
        (options.sampling, options.seed, options.mode),
        target,
        progress,
    )
}

/// `options` with the receivers' turns a bake's receivers cast with: a least-squares fit's
/// points each turn their samples by their own angle where the sampling can
/// ([`BakeOptions::with_turns_where_possible`]), so that the errors of a vertex's points are
/// independent and its fit averages them out.
fn receivers_turning(options: &BakeOptions) -> BakeOptions {
    match options.fit {
        Fit::LeastSquares => options.clone().with_turns_where_possible(),
        Fit::Point => options.clone(),
    }
}

/// The receivers of a bake: the vertices, or (least-squares fit) the points spread over the
/// triangles, which it also returns.
fn choose_receivers(
    scene: &Scene,
    bvh: &Bvh,
    options: &BakeOptions,
) -> (Receivers, Vec<SurfacePoint>) {
    match options.fit {
        Fit::Point => (Receivers::vertices(scene), Vec::new()),
        Fit::LeastSquares => {
            let spread = spread_points(scene, options.point_density, options.seed);
            // Points inside other geometry are never seen and would pull their vertices dark.
            let candidates = Receivers::at_points(scene, &spread);
            let inside = texels::leaking_receivers_in(scene, bvh, &candidates);
            let points: Vec<SurfacePoint> = spread
                .into_iter()
                .zip(inside)
                .filter(|(_, inside)| !inside)
                .map(|(p, _)| p)
                .collect();
            (Receivers::at_points(scene, &points), points)
        }
    }
}

/// Progress that passes on advances but not stages: chunks advance one stage of the whole.
pub(crate) struct Advancing<'a>(pub(crate) &'a dyn Progress);

impl Progress for Advancing<'_> {
    fn advance(&self, done: u64) {
        self.0.advance(done);
    }

    fn detail(&self, text: &str) {
        self.0.detail(text);
    }
}

/// A stage's position, moved to where a step says it is rather than by increments (a solve's
/// share of its decades, a search's place in its grid); it never moves back.
pub struct StagePosition<'a> {
    progress: &'a dyn Progress,
    at: u64,
}

impl<'a> StagePosition<'a> {
    /// At the start of the stage just begun on `progress`.
    pub fn new(progress: &'a dyn Progress) -> StagePosition<'a> {
        StagePosition { progress, at: 0 }
    }

    /// Advances the stage to `position`, where that is further on.
    pub fn move_to(&mut self, position: u64) {
        if position > self.at {
            self.progress.advance(position - self.at);
            self.at = position;
        }
    }
}

/// What the direct pass gives: albedo-free transfer `[receiver][k]`, the gather matrix
/// (interreflected mode: rows are receivers, columns the scene's vertices), the rays cast,
/// and for an error-targeted pass each receiver's samples and error.
pub struct DirectPass {
    pub scalar: Vec<f32>,
    pub matrix: Option<bounce::GatherMatrix>,
    pub rays_cast: u64,
    pub adaptive: Option<adaptive::ReceiverErrors>,
}

/// RGB transfer from albedo-free scalar transfer: channel c of vertex v is `albedo[v][c]` times it.
pub fn tint_by_albedo(scalar: &[f32], albedo: &[Vec3], bands: u32) -> Transfer {
    let n = coeff_count(bands);
    let mut coeffs = Vec::with_capacity(scalar.len() * 3);
    for (t, a) in scalar.chunks_exact(n).zip(albedo) {
        for c in 0..3 {
            coeffs.extend(t.iter().map(|x| x * a[c]));
        }
    }
    Transfer::new(bands, 3, albedo.len(), coeffs)
        .expect("one albedo for each receiver's bands^2 coefficients")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::receivers::{spread_points, PointDensity};
    use crate::scene::builtin::default_scene;

    #[test]
    fn points_gathered_a_chunk_at_a_time_get_the_whole_gathers_bytes() {
        let options = BakeOptions {
            mode: Mode::Interreflected,
            samples: 64,
            ..BakeOptions::default()
        };
        let (baked, _) = bake(default_scene(), &options, &CpuBackend, &NoProgress).unwrap();
        let scene = &baked.scene;
        let points = spread_points(scene, PointDensity::default(), 3);
        let receivers = Receivers::at_points(scene, &points);
        let at = |chunk: usize| {
            let bvh = Bvh::build(&scene.positions, &scene.triangles);
            let vertices = Some(&baked.transfer);
            let at = (&receivers, bvh);
            let with = (&options, &CpuBackend as &dyn Backend, vertices);
            bake_at_gathering(scene, at, with, &NoProgress, chunk).unwrap()
        };
        let whole = at(receivers.len());
        assert!(receivers.len() > 3 * 1000, "{} points", receivers.len());
        for chunk in [1000, 777] {
            let (transfer, rays) = at(chunk);
            assert_eq!(rays, whole.1, "rays in chunks of {chunk}");
            assert!(transfer == whole.0, "transfer in chunks of {chunk}");
        }
    }

    /// What a bake told its progress: stages with the items advanced in each, and details.
    #[derive(Default)]
    struct Recorded {
        stages: std::sync::Mutex<Vec<(String, u64, u64)>>,
        details: std::sync::Mutex<Vec<String>>,
    }

    impl Progress for Recorded {
        fn stage(&self, name: &str, total: u64) {
            self.stages.lock().unwrap().push((name.into(), total, 0));
        }

        fn advance(&self, done: u64) {
            if let Some(stage) = self.stages.lock().unwrap().last_mut() {
                stage.2 += done;
            }
        }

        fn detail(&self, text: &str) {
            self.details.lock().unwrap().push(text.into());
        }
    }

    #[test]
    fn a_least_squares_solve_shows_how_far_it_has_come() {
        let options = BakeOptions {
            mode: Mode::Interreflected,
            bounces: 1,
            samples: 16,
            fit: Fit::LeastSquares,
            ..BakeOptions::default()
        };
        let recorded = Recorded::default();
        bake(default_scene(), &options, &CpuBackend, &recorded).unwrap();
        let stages = recorded.stages.into_inner().unwrap();
        // The direct light's solve is a stage of its own, run to its end.
        let fit = stages.iter().find(|(name, ..)| name == "fit");
        assert_eq!(
            fit.map(|(_, total, done)| (*total, *done)),
            Some((100, 100))
        );
        // The bounce's is a detail of the bounces' stage, rising, then cleared.
        let bounces = stages.last().unwrap();
        assert_eq!((bounces.0.as_str(), bounces.2), ("bounces", 1));
        let details = recorded.details.into_inner().unwrap();
        let percents: Vec<u64> = details
            .iter()
            .filter_map(|d| {
                d.strip_prefix("(fitting, ")?
                    .strip_suffix("%)")?
                    .parse()
                    .ok()
            })
            .collect();
        assert!(!percents.is_empty(), "{details:?}");
        assert!(percents.windows(2).all(|w| w[0] < w[1]), "{percents:?}");
        assert_eq!(percents.last(), Some(&100));
        assert_eq!(details.last().map(String::as_str), Some(""));
    }
}
