//! Relightable probes: transfer at points in the space around a static scene, so that what
//! moves through it is lit by the scene's shadowing and bounced light under whatever distant
//! light is current (Direct3D's `ComputeVolumeSamples`). Each probe stores the linear map from
//! the light's SH coefficients to the SH of the radiance arriving there (`transfer.rs`); the
//! rays it casts over the whole sphere come from the bake's backend, as every other ray does.
//!
//! Placement (`placement.rs`): a probe whose rays mostly reach the backs of surfaces is inside
//! geometry; it is moved just past the nearest of those surfaces when that lies within half a
//! grid cell, as engines do, and marked invalid otherwise.

mod exit;
pub mod gpu;
mod lookup;
mod placement;
pub mod transfer;

pub use exit::ExitLight;
pub use placement::{grid_points, ProbeGrid, ProbeStatus, BACK_FACE_LIMIT, POINT_REACH};
pub use transfer::{cosine_convolution, IRRADIANCE_BANDS};

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::bounce::Hit;
use crate::bake::{Backend, BakedMesh, DirectInputs, Progress};
use crate::bvh::Bvh;
use crate::error::{Error, Result};
use crate::sampling::{stratified_sphere, Estimator, SampleSet, Sampling};
use crate::scene::Scene;
use crate::sh::rotation::EulerShRotation;
use crate::sh::{coeff_count, ShTable};
pub use crate::spec::{ProbeForm, ProbePlacement, ProbeSpec, MAX_PROBES};
use transfer::{probe_matrix, BlockedRay};

/// Probes baked: where each is, what became of it, and its transfer.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeSet {
    pub bands: u32,
    /// 1 where the light's colour passes unchanged (shadowed, or every albedo grey), else 3.
    pub channels: u32,
    pub form: ProbeForm,
    /// Rows per channel: `bands^2` for radiance, up to 9 for irradiance.
    pub rows: usize,
    /// The grid the probes were placed on, when they were (`None`: the user's points).
    pub grid: Option<ProbeGrid>,
    /// Where each probe was baked: its grid point or given point, or where it was moved to.
    pub positions: Vec<Vec3>,
    pub status: Vec<ProbeStatus>,
    /// `[probe][channel][row][k]`; zero for invalid probes.
    pub matrices: Vec<f32>,
    /// Sample directions each probe cast over the sphere.
    pub samples: u32,
}

impl ProbeSet {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Values per probe: channels x rows x bands^2.
    pub fn per_probe(&self) -> usize {
        self.channels as usize * self.rows * coeff_count(self.bands)
    }

    /// One probe at the origin that sees nothing: the identity at `bands`, one channel.
    pub fn open_sky(bands: u32) -> ProbeSet {
        let n = coeff_count(bands);
        ProbeSet {
            bands,
            channels: 1,
            form: ProbeForm::Radiance,
            rows: n,
            grid: None,
            positions: vec![Vec3::ZERO],
            status: vec![ProbeStatus::Placed],
            matrices: (0..n * n)
                .map(|e| if e / n == e % n { 1.0 } else { 0.0 })
                .collect(),
            samples: 0,
        }
    }

    /// One line: how many probes, what became of them, what each stores.
    pub fn describe(&self) -> String {
        let count = |status| self.status.iter().filter(|&&s| s == status).count();
        let n = coeff_count(self.bands);
        format!(
            "{} probes ({} placed, {} moved out of geometry, {} invalid), {} form: {} channel(s) \
             x {} x {} float32, {} bytes each{}",
            self.len(),
            count(ProbeStatus::Placed),
            count(ProbeStatus::Moved),
            count(ProbeStatus::Invalid),
            self.form.name(),
            self.channels,
            self.rows,
            n,
            4 * self.per_probe(),
            match self.grid {
                Some(g) => format!(
                    "; a {} x {} x {} grid {} apart",
                    g.dims[0], g.dims[1], g.dims[2], g.spacing
                ),
                None => String::new(),
            }
        )
    }

    /// Row `i` of `matrix` (one probe's) for colour `rgb` times the light's coefficients.
    pub(crate) fn row_times_light(
        &self,
        matrix: &[f32],
        i: usize,
        rgb: usize,
        light: &[[f32; 3]],
    ) -> f64 {
        let n = coeff_count(self.bands);
        let c = rgb.min(self.channels as usize - 1);
        let row = &matrix[(c * self.rows + i) * n..(c * self.rows + i + 1) * n];
        row.iter()
            .zip(light)
            .map(|(&m, l)| m as f64 * l[rgb] as f64)
            .sum()
    }

    /// Every probe relit by `light` (`[k]` RGB): what a run-time computes once a frame,
    /// `[probe][row]` RGB — the incident radiance's SH, or for the irradiance form the
    /// irradiance's.
    pub fn relight(&self, light: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let mut out = vec![[0.0f32; 3]; self.len() * self.rows];
        out.par_chunks_mut(self.rows)
            .zip(self.matrices.par_chunks(self.per_probe().max(1)))
            .for_each(|(relit, matrix)| {
                for (i, value) in relit.iter_mut().enumerate() {
                    *value = std::array::from_fn(|rgb| {
                        self.row_times_light(matrix, i, rgb, light) as f32
                    });
                }
            });
        out
    }

    /// Why the set's arrays cannot be stored or shown, if they cannot: a position, status or
    /// matrix missing for a probe, or a value that is not finite.
    pub fn broken(&self) -> Option<&'static str> {
        if self.matrices.len() != self.len() * self.per_probe() || self.status.len() != self.len() {
            return Some("the probes' arrays do not match their count");
        }
        let finite = self.matrices.iter().all(|m| m.is_finite())
            && self.positions.iter().all(|p| p.is_finite());
        (!finite).then_some("the probes hold values that are not finite")
    }

    /// Probe `p`'s matrix, `[channel][row][k]`.
    pub fn matrix(&self, p: usize) -> &[f32] {
        let n = self.per_probe();
        &self.matrices[p * n..(p + 1) * n]
    }
}

/// The points of a probe file: one `x y z` per line, blank lines and `#` comments skipped.
pub fn read_points(path: &std::path::Path) -> Result<Vec<[f32; 3]>> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_points(&text).map_err(|message| Error::Mesh {
        path: path.to_path_buf(),
        message,
    })
}

/// [`read_points`] of a file's text.
pub fn parse_points(text: &str) -> std::result::Result<Vec<[f32; 3]>, String> {
    let mut points = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let values: Vec<f32> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|word| !word.is_empty())
            .map(|word| word.parse::<f32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| format!("line {}: {e}", number + 1))?;
        match values[..] {
            [x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) => points.push([x, y, z]),
            _ => {
                return Err(format!(
                    "line {}: a probe point is three finite numbers, x y z",
                    number + 1
                ))
            }
        }
    }
    Ok(points)
}

/// Bytes baking `spec`'s probes around `scene` at `bands` from `samples` directions holds at
/// most (the bake's memory estimate adds them, streamed or whole): every probe's matrix as
/// stored (three channels at most) with its position and status; a batch's hits and full
/// matrices in flight; the tree the probes cast through and their sample tables; and an
/// interreflected bake's exit light.
pub fn memory_need(
    spec: &ProbeSpec,
    scene: &Scene,
    (bands, samples): (u32, u32),
    interreflected: bool,
) -> u64 {
    let count = match &spec.placement {
        ProbePlacement::Grid { spacing } => ProbeGrid::over(scene, *spacing)
            .map_or(0, |grid| grid.dims.iter().map(|&d| d as u64).product()),
        ProbePlacement::Points(points) => points.len() as u64,
    };
    let n = coeff_count(bands) as u64;
    let rows = rows(spec.form, bands) as u64;
    let samples = Sampling::Stratified.samples_used(samples) as u64;
    // Three channels only where interreflected light comes off coloured surfaces.
    let channels = if interreflected && !scene.all_grey() {
        3
    } else {
        1
    };
    let stored = count * (channels * rows * n * 4 + 13);
    // Each hit of 16 bytes (with its sample) as the backend answers it (where a growing
    // vector may hold twice its length) and joined per probe, and the batch's matrices until
    // they join the set; per thread, one probe's f64 matrix before it is shaped.
    let hits = 3 * 16 * samples;
    let batch = count.min(PROBES_PER_BATCH as u64) * (hits + channels * rows * n * 4);
    let threads = rayon::current_num_threads() as u64 * channels * n * n * 8;
    let tree = 160 * scene.triangle_count() as u64;
    let tables = samples * (16 + 4 * n);
    let exit = match interreflected {
        true => scene.vertex_count() as u64 * channels * n * 4,
        false => 0,
    };
    stored + batch + threads + tree + tables + exit
}

/// Rows per channel of a probe's matrix at `bands` in `form`: `bands^2` for radiance, the
/// first [`IRRADIANCE_BANDS`] bands' for irradiance.
pub fn rows(form: ProbeForm, bands: u32) -> usize {
    match form {
        ProbeForm::Radiance => coeff_count(bands),
        ProbeForm::Irradiance => coeff_count(bands.min(IRRADIANCE_BANDS)),
    }
}

/// Probes per batch of rays: bounds the hits held at once (about 6 KiB per probe at 1,024
/// samples).
const PROBES_PER_BATCH: usize = 4096;

/// Bakes probes around `baked` (its prepared scene and its transfer, which gives the exit
/// light of the surfaces a probe sees in interreflected mode) as `spec` asks, `samples`
/// stratified directions over the sphere from `seed`, on `backend`.
pub fn bake_probes(
    baked: &BakedMesh,
    spec: &ProbeSpec,
    sampling: (u32, u64),
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<ProbeSet> {
    let exit = ExitLight::of(baked);
    let around = (&baked.scene, baked.transfer.bands(), exit.as_ref());
    bake_probes_around(around, spec, sampling, backend, progress)
}

/// Bakes probes around a prepared `scene` at `bands`, `exit` the light its surfaces send on
/// (an interreflected bake's; `None`: they send none), as `spec` asks. What
/// [`bake_probes`] does for a whole bake, and a streamed bake does with its scratch file.
pub fn bake_probes_around(
    (scene, bands, exit): (&Scene, u32, Option<&ExitLight>),
    spec: &ProbeSpec,
    (samples, seed): (u32, u64),
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<ProbeSet> {
    spec.validate()?;
    let (grid, points) = match &spec.placement {
        ProbePlacement::Grid { spacing } => {
            let grid = ProbeGrid::over(scene, *spacing)?;
            (Some(grid), grid.points())
        }
        ProbePlacement::Points(points) => (None, points.iter().map(|&p| Vec3::from(p)).collect()),
    };
    let samples = Sampling::Stratified.samples_used(samples);
    let directions = stratified_sphere(samples, seed);
    let sight = Sight::new(scene, bands, directions);
    let reach = grid.map_or(POINT_REACH * sight.bvh.extent(), |g| 0.5 * g.spacing);
    progress.stage("probes", points.len() as u64);
    let mut positions = Vec::with_capacity(points.len());
    let mut status = Vec::with_capacity(points.len());
    let n = coeff_count(bands);
    let rows = rows(spec.form, bands);
    let channels = exit.map_or(1, |e| e.channels);
    let mut matrices = Vec::with_capacity(points.len() * channels * rows * n);
    for batch in points.chunks(PROBES_PER_BATCH) {
        let seen = sight.cast(batch, backend)?;
        let placed = placement::place(batch, seen, reach, &sight, backend)?;
        let batch_matrices: Vec<Vec<f32>> = placed
            .par_iter()
            .map(|probe| match probe.status {
                ProbeStatus::Invalid => vec![0.0; channels * rows * n],
                _ => {
                    let full = sight.matrix(&probe.hits, exit, channels);
                    shaped(full, spec.form, n, channels)
                }
            })
            .collect();
        for (probe, m) in placed.into_iter().zip(batch_matrices) {
            positions.push(probe.position);
            status.push(probe.status);
            matrices.extend(m);
        }
        progress.advance(batch.len() as u64);
    }
    Ok(ProbeSet {
        bands,
        channels: channels as u32,
        form: spec.form,
        rows,
        grid,
        positions,
        status,
        matrices,
        samples,
    })
}

/// The full matrix in `form`, as float32.
fn shaped(full: Vec<f64>, form: ProbeForm, n: usize, channels: usize) -> Vec<f32> {
    let kept = match form {
        ProbeForm::Radiance => full,
        ProbeForm::Irradiance => transfer::irradiance_rows(&full, n, channels).1,
    };
    kept.into_iter().map(|x| x as f32).collect()
}

/// What a probe's rays are cast with: the scene's tree, the sphere's directions split into
/// two hemispheres (each probe is two receivers, facing +Z and -Z, so the backends' horizon
/// test gives each ray to exactly one of them) and their SH.
pub(crate) struct Sight<'s> {
    scene: &'s Scene,
    normals: &'s [Vec3],
    bvh: Bvh,
    samples: SampleSet,
    table: ShTable,
    rotation: EulerShRotation,
}

/// A probe's closest hits over the sphere, `(sample, hit)`, samples ascending within each
/// hemisphere.
pub(crate) type ProbeHits = Vec<(u32, Hit)>;

impl<'s> Sight<'s> {
    fn new(scene: &'s Scene, bands: u32, samples: SampleSet) -> Sight<'s> {
        let normals = scene
            .normals
            .as_deref()
            .expect("a prepared scene has normals");
        let table = ShTable::new(bands, &samples.directions);
        Sight {
            scene,
            normals,
            bvh: Bvh::build(&scene.positions, &scene.triangles),
            samples,
            table,
            rotation: EulerShRotation::new(bands),
        }
    }

    /// The closest hits of every probe at `points`.
    fn cast(&self, points: &[Vec3], backend: &dyn Backend) -> Result<Vec<ProbeHits>> {
        let origins: Vec<Vec3> = points.iter().flat_map(|&p| [p, p]).collect();
        let normals: Vec<Vec3> = points.iter().flat_map(|_| [Vec3::Z, -Vec3::Z]).collect();
        let inputs = DirectInputs {
            origins: &origins,
            normals: &normals,
            triangles: &self.scene.triangles,
            vertex_normals: self.normals,
            bvh: &self.bvh,
            samples: &self.samples,
            table: &self.table,
            estimator: Estimator::Visible,
            tangent_to_world: &self.rotation,
            turns: None,
        };
        let halves = backend.closest_hits(&inputs, &crate::bake::NoProgress)?;
        if halves.len() != origins.len() {
            return Err(Error::Gpu(format!(
                "the backend answered {} receivers of {}",
                halves.len(),
                origins.len()
            )));
        }
        Ok(halves
            .chunks(2)
            .map(|pair| {
                let mut hits = Vec::with_capacity(pair.iter().map(Vec::len).sum());
                pair.iter().for_each(|half| hits.extend_from_slice(half));
                hits
            })
            .collect())
    }

    fn direction(&self, sample: u32) -> Vec3 {
        self.samples.directions[sample as usize]
    }

    /// Where `hit` of sample `sample` lies and whether it reaches a back face.
    fn hit_point_and_side(&self, sample: u32, hit: Hit) -> (Vec3, bool) {
        let triangle = self.scene.triangles[hit.triangle as usize];
        let direction = self.direction(sample);
        transfer::hit_point_and_side(
            &self.scene.positions,
            self.normals,
            triangle,
            hit,
            direction,
        )
    }

    /// The probe's full matrix `[channel][i][k]` from its hits.
    fn matrix(&self, hits: &ProbeHits, exit: Option<&ExitLight>, channels: usize) -> Vec<f64> {
        let n = coeff_count(self.table.bands);
        let exits: Vec<Option<Vec<f64>>> = hits
            .iter()
            .map(|&(sample, hit)| {
                let exit = exit?;
                let (_, back) = self.hit_point_and_side(sample, hit);
                let triangle = self.scene.triangles[hit.triangle as usize];
                (!back).then(|| {
                    transfer::interpolate_exit(&exit.values, exit.channels * n, triangle, hit)
                })
            })
            .collect();
        let blocked = hits
            .iter()
            .zip(&exits)
            .map(|(&(sample, _), exit)| BlockedRay {
                sh: self.table.row(sample as usize),
                exit: exit.as_deref(),
            });
        probe_matrix(n, channels, self.samples.weight, blocked)
    }
}
