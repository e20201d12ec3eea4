//! Local lights by direct-to-indirect transfer (Lehmann-style meshless PCA PRT; the paper in
//! `../shared/references/meshless-pca-prt.txt`): point and spot lights that move *inside* the
//! scene, where everything else in this tool assumes distant light.
//!
//! Bake (`prt-gpu bake --mode local`), per receiver (the prepared mesh's vertices):
//! - a hemispherical depth map (`depth.rs`), compressed per cluster of receivers by PCA
//!   (`compress::compress_rows`), so that the direct light of any light position can be
//!   evaluated with a handful of dot products;
//! - the direct-to-indirect operator (`operator.rs`): the gather matrix of interreflection
//!   (`bake::bounce`) bounced B times (sparse form), and its compression by PCA of example
//!   direct light (`build.rs`).
//!
//! Run time ([`Relighter`]): irradiance per receiver from the lights and the compressed depth
//! maps, direct radiance `albedo E / pi`, indirect radiance from the operator, their sum.

pub mod build;
pub mod depth;
pub mod gpu;
pub mod lights;
pub mod operator;

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::bounce::GatherMatrix;
use crate::bake::{self, Backend, BakeInputs, BakeOptions, Mode, Progress};
use crate::bvh::Bvh;
use crate::compress::{compress_rows, stored_bytes, Cpca, CpcaOptions};
use crate::error::Result;
use crate::precision::Precision;
use crate::ray::{blend_at, Ray, RAY_T_MAX};
use crate::receivers::vertex_ray_starts;
use crate::sampling::{tangent_frame, DirectionFrame, Pcg32, SampleSet, Sampling};
use crate::scene::prepare::prepare;
use crate::scene::Scene;
use crate::sh::ShTable;
use build::{build_compressed, SparseOperator};
use depth::{DepthLookup, DepthMaps, DirectionGrid};
use lights::{
    direct_radiance, irradiance_by_shadow_rays, irradiance_from_depth, LocalLight, ReceiverFrames,
};
use operator::{sparse_indirect, CompressedOperator};

mod relight;
pub use relight::*;

pub use crate::spec::LocalOptions;

/// A local-lights bake: the prepared scene and everything a run time needs.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalBake {
    pub scene: Scene,
    pub options: LocalOptions,
    /// The depth maps' grid and the depth of rays that leave the scene.
    pub grid: DirectionGrid,
    pub open_depth: f32,
    /// Compressed depth maps, one row of `grid.len()` per receiver.
    pub depth: Cpca,
    /// The gather matrix (the sparse operator with `options.bounces`).
    pub matrix: GatherMatrix,
    pub operator: CompressedOperator,
}

/// What a local bake did.
#[derive(Clone, Debug, Default)]
pub struct LocalReport {
    pub receivers: usize,
    pub triangles: usize,
    pub rays_cast: u64,
    pub seconds_gather: f64,
    pub seconds_depth: f64,
    pub seconds_depth_compress: f64,
    pub seconds_examples: f64,
    pub seconds_operator: f64,
    /// RMS of the compressed depths' error over the RMS depth.
    pub depth_error: f64,
    pub depth_bytes_uncompressed: usize,
    pub depth_bytes: usize,
    pub gather_entries: usize,
    pub operator_bytes: usize,
    /// Sender blocks kept over all blocks.
    pub operator_kept: f64,
    /// The compressed operator's indirect light against the sparse operator's, relative RMS,
    /// mean over [`HELD_OUT_LIGHTS`] lights placed as the examples are but from another seed.
    pub operator_error: f64,
    pub example_lights: usize,
    pub backend: String,
}

impl LocalReport {
    pub fn seconds(&self) -> f64 {
        self.seconds_gather
            + self.seconds_depth
            + self.seconds_depth_compress
            + self.seconds_examples
            + self.seconds_operator
    }
}

/// The bake's inputs for a prepared scene: the gather bake's (cosine samples, one band) and
/// the receivers' tangent frames.
pub struct LocalInputs {
    pub bake: BakeInputs,
    pub frames: Vec<[Vec3; 3]>,
}

/// The options of the gather bake a local-lights bake starts with: cosine samples, one band,
/// interreflected (its gather matrix is the sparse operator's).
pub fn gather_options(options: &LocalOptions) -> BakeOptions {
    BakeOptions {
        bands: 1,
        samples: options.samples,
        sampling: Sampling::Cosine,
        seed: options.seed,
        mode: Mode::Interreflected,
        ..BakeOptions::default()
    }
}

/// The bytes a local-lights bake of `receivers` receivers holds at its peak beyond the gather
/// bake's own (`bake::stream::MemoryNeed` of [`gather_options`]): per receiver, the operator's
/// responses to each of its basis vectors, RGB, and while they are sparsified the kept ones'
/// copy (counted as if all were kept), a batch of them in bounces (four buffers), the example
/// and held-out lights' irradiance, the depth maps and the tangent frames; and the compressed
/// maps as `compress::stored_bytes` counts them. The responses dominate: 24 kB of the about
/// 29 kB a receiver at the defaults.
pub fn memory_need(receivers: u64, options: &LocalOptions) -> u64 {
    let operator_clusters = (options.operator.clusters as u64).min(receivers).max(1);
    let components = options.operator.components as u64;
    let columns = 1 + operator_clusters * components;
    let responses = 2 * 3 * 4 * columns;
    let batch = 4 * 3 * 4 * build::COLUMNS_PER_BATCH as u64;
    let lights = 4 * (options.example_lights + HELD_OUT_LIGHTS) as u64;
    let cells = options.grid_side as u64 * options.grid_side as u64;
    // The basis and its projection rows, the means, the frames.
    let operator = 4 * 2 * components + 4 + 36;
    let depth_clusters = (options.depth_clusters as u64).min(receivers).max(1);
    let shape = (depth_clusters as usize, options.depth_components as usize);
    let compressed = stored_bytes(shape, cells as usize, receivers as usize, Precision::F32);
    receivers * (responses + batch + lights + 4 * cells + operator) + compressed as u64
}

impl LocalInputs {
    pub fn new(scene: &Scene, options: &LocalOptions) -> Self {
        let bake = BakeInputs::for_options(scene, &gather_options(options));
        let frames = bake.normals.iter().map(|&n| tangent_frame(n)).collect();
        LocalInputs { bake, frames }
    }
}

/// The bake: prepare the scene, then [`bake_prepared`].
pub fn bake_local(
    scene: Scene,
    options: &LocalOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(LocalBake, LocalReport)> {
    bake_prepared(prepare(scene)?.0, options, backend, progress)
}

/// Gather matrix, depth maps, their compression, example lights and the compressed operator
/// for a prepared scene.
pub fn bake_prepared(
    scene: Scene,
    options: &LocalOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<(LocalBake, LocalReport)> {
    options.validate()?;
    let mut report = LocalReport {
        receivers: scene.positions.len(),
        triangles: scene.triangles.len(),
        backend: backend.describe(),
        ..Default::default()
    };
    let mut inputs = LocalInputs::new(&scene, options);
    let started = Instant::now();
    let pass = backend.direct_pass(&inputs.bake.view(), Mode::Interreflected, progress)?;
    let matrix = pass
        .matrix
        .expect("interreflected passes build the gather matrix");
    report.rays_cast = pass.rays_cast;
    report.gather_entries = matrix.columns.len();
    report.seconds_gather = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let grid = DirectionGrid {
        side: options.grid_side,
    };
    progress.stage("depth maps", 1);
    let maps = depth_maps(&scene, &mut inputs, grid, backend)?;
    progress.advance(1);
    report.rays_cast += (maps.receivers() * grid.len()) as u64;
    report.seconds_depth = started.elapsed().as_secs_f64();

    // The steps after the rays take longer than the rays (on the built-in interior, about ten
    // seconds to compress the maps and as many to build the operator, against under two for
    // the rays): a stage each says which runs.
    let started = Instant::now();
    progress.stage("compress depth maps", 1);
    let depth = compress_depth_maps(&maps, options)?;
    progress.advance(1);
    report.depth_error = depth_error(&maps, &depth);
    report.depth_bytes_uncompressed = 4 * maps.depths.len();
    report.depth_bytes = depth.byte_size(Precision::F32);
    report.seconds_depth_compress = started.elapsed().as_secs_f64();

    let started = Instant::now();
    progress.stage("example lights", 1);
    let positions = example_light_positions(&scene, &inputs.bake.bvh, options);
    report.example_lights = positions.len();
    let examples = example_irradiance(&scene, &inputs, &maps, &positions);
    progress.advance(1);
    report.seconds_examples = started.elapsed().as_secs_f64();

    let started = Instant::now();
    progress.stage("operator", 2);
    let sparse = SparseOperator {
        matrix: &matrix,
        albedo: &scene.albedo,
        bounces: options.bounces,
    };
    let features = clustering_features(&scene, inputs.bake.bvh.extent());
    let operator = build_compressed(&sparse, &features, 6, &examples, options.operator)?;
    report.operator_bytes = operator.byte_size();
    let all_terms = operator.clusters() * operator.clusters() * operator.components;
    report.operator_kept = operator.terms.len() as f64 / all_terms.max(1) as f64;
    report.seconds_operator = started.elapsed().as_secs_f64();
    progress.advance(1);
    report.operator_error = held_out_error(&scene, &inputs, &maps, &sparse, &operator, options);
    progress.advance(1);
    let open_depth = maps.open_depth;
    Ok((
        LocalBake {
            scene,
            options: options.clone(),
            grid,
            open_depth,
            depth,
            matrix,
            operator,
        },
        report,
    ))
}

/// Depth maps of the receivers of `inputs` on the backend: the closest hits along the grid's
/// directions in each receiver's tangent frame.
pub fn depth_maps(
    scene: &Scene,
    inputs: &mut LocalInputs,
    grid: DirectionGrid,
    backend: &dyn Backend,
) -> Result<DepthMaps> {
    let owned = &mut inputs.bake;
    let open_depth = depth::open_depth(&owned.bvh);
    // The gather bake's inputs with the grid's directions as a tangent-frame set.
    let grid_set = SampleSet::new(grid.directions(), 1.0, DirectionFrame::Tangent);
    let table = ShTable::new(1, &grid_set.directions);
    let samples = std::mem::replace(&mut owned.samples, grid_set);
    let table = std::mem::replace(&mut owned.table, table);
    let depths = backend.closest_hit_distances(&owned.view(), scene, open_depth, &bake::NoProgress);
    owned.samples = samples;
    owned.table = table;
    Ok(DepthMaps {
        grid,
        open_depth,
        depths: depths?,
    })
}

/// The depth maps compressed by clustered PCA.
pub fn compress_depth_maps(maps: &DepthMaps, options: &LocalOptions) -> Result<Cpca> {
    compress_rows(
        &maps.depths,
        maps.grid.len(),
        &CpcaOptions {
            clusters: options.depth_clusters.min(maps.receivers() as u32).max(1),
            components: options.depth_components,
            iterations: 4,
            seed: options.seed,
        },
    )
}

/// The most clusters of `components` components whose compression of `receivers` depth maps
/// of `cells` directions each takes no more bytes than the maps themselves (float32 both);
/// `None` where not even one cluster does. Few receivers cannot pay for many clusters' bases.
pub fn depth_clusters_within_maps(
    receivers: usize,
    cells: usize,
    components: usize,
) -> Option<u32> {
    let maps = 4 * receivers * cells;
    let stored = |clusters| stored_bytes((clusters, components), cells, receivers, Precision::F32);
    let per_cluster = stored(1) - stored(0);
    let clusters = maps.checked_sub(stored(0))? / per_cluster;
    (clusters >= 1).then(|| clusters.min(u32::MAX as usize) as u32)
}

/// RMS error of the compressed depths over the RMS depth.
pub fn depth_error(maps: &DepthMaps, depth: &Cpca) -> f64 {
    let cells = maps.grid.len();
    let (diff, norm) = (0..maps.receivers())
        .into_par_iter()
        .map(|p| {
            (0..cells).fold((0.0f64, 0.0f64), |(d, n), cell| {
                let exact = maps.depth(p, cell) as f64;
                let e = depth.depth(p, cell) as f64 - exact;
                (d + e * e, n + exact * exact)
            })
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    (diff / norm.max(f64::MIN_POSITIVE)).sqrt()
}

/// Positions for the example lights: uniform in the scene's box (shrunk by 5% each side),
/// kept where none of six axis rays first meets the back of a surface (the point is not
/// inside an object); at most 64 draws per light kept.
pub fn example_light_positions(scene: &Scene, bvh: &Bvh, options: &LocalOptions) -> Vec<Vec3> {
    let (lo, hi) = scene.bounds();
    let margin = (hi - lo) * 0.05;
    let (lo, hi) = (lo + margin, hi - margin);
    let normals = scene.normals.as_deref().unwrap_or_default();
    let mut rng = Pcg32::new(options.seed ^ 0x11_6874);
    let wanted = options.example_lights as usize;
    let mut kept = Vec::with_capacity(wanted);
    for _ in 0..wanted * 64 {
        if kept.len() == wanted {
            break;
        }
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let p = lo + (hi - lo) * u;
        if in_free_space(scene, normals, bvh, p) {
            kept.push(p);
        }
    }
    kept
}

/// Whether none of the six axis rays from `p` first meets the back of a surface.
pub fn in_free_space(scene: &Scene, normals: &[Vec3], bvh: &Bvh, p: Vec3) -> bool {
    [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ]
    .iter()
    .all(|&d| match bvh.closest_hit(&Ray::new(p, d), RAY_T_MAX) {
        None => true,
        Some((triangle, hit)) => {
            let corners = scene.triangles[triangle as usize];
            blend_at(normals, corners, hit.u, hit.v).dot(d) < 0.0
        }
    })
}

/// Lights the bake's report measures the compressed operator's error with.
pub const HELD_OUT_LIGHTS: u32 = 8;

/// The compressed operator's error against the sparse one (see [`LocalReport::operator_error`]).
fn held_out_error(
    scene: &Scene,
    inputs: &LocalInputs,
    maps: &DepthMaps,
    sparse: &SparseOperator,
    operator: &CompressedOperator,
    options: &LocalOptions,
) -> f64 {
    let held_out = LocalOptions {
        example_lights: HELD_OUT_LIGHTS,
        seed: options.seed.wrapping_add(0x9e37_79b9),
        ..options.clone()
    };
    let positions = example_light_positions(scene, &inputs.bake.bvh, &held_out);
    let examples = example_irradiance(scene, inputs, maps, &positions);
    let n = scene.positions.len();
    let errors: Vec<f64> = examples
        .chunks_exact(n.max(1))
        .map(|irradiance| {
            let direct = direct_radiance(irradiance, &scene.albedo);
            let exact = sparse_indirect(sparse.matrix, sparse.albedo, sparse.bounces, &direct);
            operator::relative_rms(&exact, &operator.indirect(irradiance))
        })
        .collect();
    errors.iter().sum::<f64>() / errors.len().max(1) as f64
}

/// `[light][receiver]` irradiance of unit point lights at `positions`, visibility from the
/// exact depth maps.
fn example_irradiance(
    scene: &Scene,
    inputs: &LocalInputs,
    maps: &DepthMaps,
    positions: &[Vec3],
) -> Vec<f32> {
    let normals = scene.normals.as_deref().unwrap_or_default();
    let frames = ReceiverFrames {
        positions: &scene.positions,
        normals,
        origins: &inputs.bake.origins,
        frames: &inputs.frames,
    };
    positions
        .iter()
        .flat_map(|&p| {
            irradiance_from_depth(&frames, maps, &maps.grid, &[LocalLight::point(p, 1.0)])
        })
        .collect()
}

/// Per receiver: position over the scene's extent, and normal at a quarter of that weight
/// (clusters stay compact in space and do not mix a floor with the wall beside it).
fn clustering_features(scene: &Scene, extent: f32) -> Vec<f32> {
    let normals = scene.normals.as_deref().unwrap_or_default();
    scene
        .positions
        .iter()
        .zip(normals)
        .flat_map(|(&p, &n)| {
            let p = p / extent.max(f32::MIN_POSITIVE);
            let n = n * 0.25;
            [p.x, p.y, p.z, n.x, n.y, n.z]
        })
        .collect()
}

#[cfg(test)]
mod tests;
