//! Bakes in bounded memory: the receivers' transfer computed a chunk at a time, each chunk
//! handed on (to the file being written) before the next, so that peak memory is the mesh, its
//! BVH and one chunk rather than every vertex's transfer. A chunk's transfer depends only on
//! its receivers, so a chunked bake writes the bytes of the whole one.
//!
//! Only bakes whose vertex values are their own receivers' can stream: transfer at the
//! vertices, no fit or lightmap (a fit solves for all vertices at once; its points bake in
//! runs instead, `points::PointChunks`, and [`MemoryNeed::points_chunked`] is their need). An
//! error target
//! streams too: each receiver's batches depend on it alone.
//! Interreflection streams its direct pass; each bounce then reads every vertex's previous
//! bounce, so the bake holds one transfer of every vertex (the previous bounce) and keeps the
//! gather rows, the sum so far and the next bounce in a scratch file ([`super::spill`]), a
//! chunk at a time in memory. Every value is computed as the whole bake computes it, so the
//! file's bytes are the same.

use std::ops::Range;

use super::adaptive::ReceiverErrors;
use super::bounce::{self, GatherMatrix};
use super::spill::Spill;
use super::{
    check_given, direct_or_adaptive, metadata_for, plan, tint_by_albedo, Advancing, Backend,
    BakeMetadata, BakeOptions, BounceStat, DirectPass, Fit, GivenDirect, Mode, Progress, Storage,
    Transfer,
};
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::sh::coeff_count;

/// Whether a bake with `options` can be computed in chunks ([module docs](self)).
pub fn streams(options: &BakeOptions) -> bool {
    options.fit == Fit::Point && options.lightmap.is_none()
}

/// Bytes a bake needs, estimated from the mesh's size before it starts: what it holds
/// whatever the chunking (mesh, BVH, ray origins), and what each receiver adds when all are
/// held at once and when they stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryNeed {
    pub fixed: u64,
    /// A glTF scene's buffers and images (0 for a mesh): held as read, and copied into the
    /// written file's BIN chunk.
    pub document: u64,
    /// Probes baked around the scene (`probes::memory_need`; 0 without).
    pub probes: u64,
    /// What a streamed bake holds for every vertex whatever the chunk: an interreflected
    /// bake's previous bounce.
    pub held_streamed: u64,
    pub per_receiver_whole: u64,
    pub per_receiver_streamed: u64,
    pub receivers: u64,
    /// What a whole bake adds beside its vertices' transfer: a lightmap's texels and image
    /// ([`MemoryNeed::with_lightmap`]), which do not stream.
    pub beside_vertices: u64,
    /// A least-squares fit's points and its solve ([`MemoryNeed::with_fit_points`]).
    pub fit: Option<FitNeed>,
    /// Clustered PCA's model and each vertex's clusters and weights
    /// ([`MemoryNeed::with_compression`]), held whole and streamed alike.
    pub compression: u64,
    /// What each row of a streamed bake's chunk costs while clustered PCA reads it back.
    pub compression_per_row: u64,
    /// What the bake holds that is let go before clustered PCA starts: the BVH.
    pub bvh: u64,
    /// A lightmap's texels held in a scratch file ([`MemoryNeed::with_lightmap`]).
    pub lightmap: Option<super::texels::LightmapNeed>,
    /// A merge's largest part ([`MemoryNeed::with_merge_part`]), read whole (its checksum is
    /// of the whole) while the receivers it holds are joined or streamed.
    pub merge_part: u64,
}

/// What a least-squares fit adds to a bake's need: its points, held whatever the chunking,
/// their values and gather rows, all at once or a run of points at a time
/// (`points::PointChunks`), and its solve over every vertex, which does not shrink.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitNeed {
    pub points: u64,
    /// Each point throughout: as spread and as kept, its receiver twice (candidate and kept),
    /// its ray origin and normal.
    pub per_point_held: u64,
    /// Each point's direct pass: its albedo-free transfer and, where light bounces, its gather
    /// row (held to the end of a whole bake).
    pub per_point_direct: u64,
    /// Each point's RGB values while they are summed (twice while a bounce gathers them).
    pub per_point_values: u64,
    /// The right-hand sides summed while points bake a run at a time: each vertex's RGB
    /// values and albedo-free ones, in f64.
    pub sums: u64,
    /// The solve: the conjugate gradients' f64 vectors over every vertex's RGB coefficients,
    /// the sparse normal matrix and its incomplete Cholesky factor (about seven entries a row,
    /// 12 bytes each, and a row's offsets) and the factor's per-row tables.
    pub solving: u64,
}

impl FitNeed {
    /// Every point at once, as a whole bake holds them.
    pub fn whole(&self) -> u64 {
        self.points * (self.per_point_held + self.per_point_direct)
            + (self.points * self.per_point_values).max(self.solving)
    }

    /// `chunk` points at a time, their gather rows in a scratch file.
    pub fn chunked(&self, chunk: u64) -> u64 {
        let run = chunk.min(self.points) * (self.per_point_direct + self.per_point_values);
        self.points * self.per_point_held + (run + self.sums).max(self.solving)
    }
}

/// Receivers of the smallest chunk worth streaming: below it, per-chunk overheads dominate.
pub const MIN_CHUNK: usize = 256;

impl MemoryNeed {
    /// The estimate for a bake with `options` of a mesh of `vertices` and `triangles`. Upper
    /// bounds from the sizes of what the bake allocates, checked against measured peaks in
    /// docs/performance.md.
    pub fn estimate(vertices: usize, triangles: usize, options: &BakeOptions) -> MemoryNeed {
        let (v, t) = (vertices as u64, triangles as u64);
        let coeffs = coeff_count(options.bands) as u64;
        // Positions, normals, albedo as loaded and as prepared (36 B each), indices twice.
        let mesh = 2 * (36 * v + 12 * t);
        // Leaf-ordered triangles (48 B), nodes (at most two per triangle, 32 B each) and the
        // build's scratch (centroids, bounds, indices).
        let bvh = 48 * t + 64 * t + 48 * t;
        // Ray origins and normals of the receivers, and the file's mesh views being written.
        let samples = options.samples_used() as u64;
        let sample_tables = samples * (16 + 4 * coeffs);
        let fixed = BASELINE + mesh + bvh + 24 * v + (36 * v + 12 * t) + sample_tables;
        let transfer = 4 * coeffs * 3;
        let groups = coeffs.div_ceil(4);
        let file_transfer = 16 * groups * 3;
        // Interreflection: each receiver's gather row (a column and a weight per blocked ray
        // at most, as the rays find it and as the matrix holds it), and the previous and next
        // bounce; streamed, the previous bounce of every vertex stays in memory.
        let gather = gather_row_bytes(options);
        let (bounces_whole, bounces_held) = match options.mode {
            Mode::Interreflected => (2 * transfer, transfer),
            _ => (0, 0),
        };
        // An error target: each receiver's sums and sums of squares (f64) while it bakes,
        // and its samples and error, which every bake keeps for all receivers (counted with
        // the mesh).
        let (batches, errors) = match options.target_error {
            Some(_) => (2 * 8 * coeffs + 64, 12),
            None => (0, 0),
        };
        MemoryNeed {
            fixed: fixed + v * errors,
            document: 0,
            probes: 0,
            held_streamed: v * bounces_held,
            // The direct pass, its RGB transfer, and the file's bytes twice (encoded BIN,
            // then the whole container).
            per_receiver_whole: 4 * coeffs
                + transfer
                + 2 * file_transfer
                + gather
                + bounces_whole
                + batches,
            // The same for one chunk, and its file blocks.
            per_receiver_streamed: 4 * coeffs
                + transfer
                + file_transfer
                + gather
                + bounces_whole
                + batches,
            receivers: v,
            beside_vertices: 0,
            fit: None,
            compression: 0,
            compression_per_row: 0,
            bvh,
            lightmap: None,
            merge_part: 0,
        }
    }

    /// The need with a least-squares fit to `points` surface points (`options` the bake's),
    /// as [`FitNeed`] counts it. The conjugate gradients hold five f64 vectors and the
    /// solution; six are counted.
    pub fn with_fit_points(self, points: u64, options: &BakeOptions) -> MemoryNeed {
        let coeffs = coeff_count(options.bands) as u64;
        let bounce = match options.mode {
            Mode::Interreflected => 2,
            _ => 1,
        };
        let fit = FitNeed {
            points,
            per_point_held: 2 * 16 + 2 * 48 + 24 + 8,
            per_point_direct: 4 * coeffs + gather_row_bytes(options),
            per_point_values: 12 * coeffs * bounce,
            sums: self.receivers * 8 * 4 * coeffs,
            solving: self.receivers * (6 * 8 * 3 * coeffs + 2 * 8 * 12 + 48),
        };
        MemoryNeed {
            fit: Some(fit),
            // The vertices gather nothing: the points do.
            per_receiver_whole: self.per_receiver_whole - gather_row_bytes(options),
            ..self
        }
    }

    /// The need with the transfer compressed by clustered PCA (`--compress`) into `clusters`
    /// of `components` directions, its rows of `dimension` floats (RGB), `group` covariances
    /// accumulated at once (`compress::covariance_group`) and `reconstructed_rows` rebuilt at
    /// once to measure the error (`compress::RECONSTRUCTED_ROWS`). It holds the model in f64
    /// (and the previous round's), the covariances, and for each vertex its clusters (three
    /// assignments), its residual and seeding distance in f64, its weights as fitted and
    /// rounded, and their bytes in the file twice; the file then holds no per-vertex transfer.
    /// Whole, the error is measured on rows reconstructed a run at a time. Streamed, the
    /// clustering runs once the last chunk is baked, each chunk read back from the scratch file
    /// (cut to the bands kept in place) beside its reconstruction: two copies.
    pub fn with_compression(
        self,
        (clusters, components): (u64, u64),
        dimension: u64,
        (group, reconstructed_rows): (u64, u64),
    ) -> MemoryNeed {
        let model = 2 * 8 * clusters * dimension * (components + 1);
        let covariances = clusters.min(group) * 8 * dimension * dimension;
        let reconstructed = reconstructed_rows.min(self.receivers) * 4 * dimension;
        let per_vertex = 3 * 4 + 2 * 8 + 2 * 4 * components + 2 * (4 * components + 4);
        let file_transfer = 16 * (dimension / 3).div_ceil(4) * 3;
        MemoryNeed {
            compression: model + covariances + self.receivers * per_vertex,
            compression_per_row: 2 * 4 * dimension,
            beside_vertices: self.beside_vertices + reconstructed,
            per_receiver_whole: self.per_receiver_whole.saturating_sub(2 * file_transfer),
            per_receiver_streamed: self.per_receiver_streamed.saturating_sub(file_transfer),
            ..self
        }
    }

    /// The need with probes of `bytes` (`probes::memory_need`), held whatever the chunking.
    pub fn with_probes(self, bytes: u64) -> MemoryNeed {
        MemoryNeed {
            probes: bytes,
            ..self
        }
    }

    /// The need with zonal transfer of `bands` bands beside the SH transfer (`--zonal`): each
    /// receiver's lobes (RGB) and axis as fitted and as collected, and their file bytes (twice
    /// whole, as the transfer's; once a chunk, streamed).
    pub fn with_zonal(self, bands: u32) -> MemoryNeed {
        let bands = bands as u64;
        let lobes = 2 * (4 * 3 * bands + 12) + 24;
        let file = 16 * 3 * bands.div_ceil(4) + 12;
        MemoryNeed {
            per_receiver_whole: self.per_receiver_whole + lobes + 2 * file,
            per_receiver_streamed: self.per_receiver_streamed + lobes + file,
            ..self
        }
    }

    /// The need with a glTF scene's document of `bytes` (its buffers and images).
    pub fn with_document(self, bytes: usize) -> MemoryNeed {
        MemoryNeed {
            document: bytes as u64,
            ..self
        }
    }

    /// What a streamed bake holds whatever its chunk: the mesh, its BVH, the document as read
    /// and in the file's BIN chunk (written in place, not wrapped again), the previous bounce,
    /// the probes.
    fn held(&self) -> u64 {
        self.fixed + 2 * self.document + self.held_streamed + self.probes + self.merge_part
    }

    /// The need of a merge whose largest part takes `bytes`.
    pub fn with_merge_part(self, bytes: u64) -> MemoryNeed {
        MemoryNeed {
            merge_part: bytes,
            ..self
        }
    }

    /// The whole bake's need, every receiver at once.
    pub fn whole(&self) -> u64 {
        // The document as read, in the BIN chunk, and in the container around it.
        self.fixed
            + 3 * self.document
            + self.probes
            + self.merge_part
            + self.receivers * self.per_receiver_whole
            + self.beside_vertices
            + self.compression
            + self.fit.map_or(0, |fit| fit.whole())
    }

    /// The need of a least-squares bake whose points bake `chunk` at a time (the rest whole).
    pub fn points_chunked(&self, chunk: usize) -> u64 {
        self.beside_fit() + self.fit.map_or(0, |fit| fit.chunked(chunk as u64))
    }

    /// The whole bake's need but for its fit's.
    fn beside_fit(&self) -> u64 {
        self.whole() - self.fit.map_or(0, |fit| fit.whole())
    }

    /// The largest run of points that keeps a least-squares bake within `limit` bytes, or the
    /// error that says how much the smallest needs (the solve over every vertex does not
    /// shrink with the runs).
    pub fn point_chunk_within(&self, limit: u64) -> Result<usize> {
        let Some(fit) = self.fit else {
            return Err(Error::Options(
                "only a least-squares fit bakes points".into(),
            ));
        };
        let per_point = fit.per_point_direct + fit.per_point_values;
        let smallest = MIN_CHUNK.min(fit.points as usize).max(1);
        if self.points_chunked(smallest) > limit {
            return Err(Error::Options(format!(
                "--memory-limit {}: this bake needs at least {} (the mesh, its BVH and its \
                 vertices' transfer {}, the fit's {} points {}, and the larger of its solve over \
                 every vertex {} and one run of {smallest} points with the sums {})",
                format_bytes(limit),
                format_bytes(self.points_chunked(smallest)),
                format_bytes(self.beside_fit()),
                fit.points,
                format_bytes(fit.points * fit.per_point_held),
                format_bytes(fit.solving),
                format_bytes(smallest as u64 * per_point + fit.sums)
            )));
        }
        // The need grows with the run (once the run outgrows the solve): the largest run
        // that fits, by bisection.
        let (mut low, mut high) = (smallest, (fit.points as usize).max(smallest));
        while low < high {
            let middle = low + (high - low).div_ceil(2);
            match self.points_chunked(middle) <= limit {
                true => low = middle,
                false => high = middle - 1,
            }
        }
        Ok(low)
    }

    /// The need of a bake streamed `chunk` receivers at a time.
    ///
    /// Clustered PCA runs once the last chunk is written to the scratch file, in the room the
    /// chunks leave.
    pub fn streamed(&self, chunk: usize) -> u64 {
        let chunk = chunk as u64;
        // The BVH is let go before the clustering starts.
        let clustering = match self.compression {
            0 => 0,
            held => (held + chunk * self.compression_per_row).saturating_sub(self.bvh),
        };
        self.held() + (chunk * self.per_receiver_streamed).max(clustering)
    }

    /// The need of one of `shards` shards of the bake: the mesh and its BVH, and
    /// its share of the receivers at a whole bake's cost each (for interreflection their
    /// gather rows too, in the pass and in the part file). A least-squares fit's receivers are
    /// its points: the shard holds them all and bakes its share's direct pass.
    pub fn shard(&self, shards: u32) -> u64 {
        let share = |receivers: u64| receivers.div_ceil(shards.max(1) as u64);
        match self.fit {
            Some(fit) => {
                self.fixed
                    + fit.points * fit.per_point_held
                    + share(fit.points) * fit.per_point_direct
            }
            None => self.fixed + share(self.receivers) * self.per_receiver_whole,
        }
    }

    /// The fewest shards, at most one a receiver, each within `limit` bytes; `None` when the
    /// mesh and its BVH (and a fit's points) alone exceed it.
    pub fn shards_within(&self, limit: u64) -> Option<u32> {
        let receivers = self.fit.map_or(self.receivers, |fit| fit.points);
        let most = receivers.clamp(1, u32::MAX as u64) as u32;
        if self.shard(most) > limit {
            return None;
        }
        // The need falls as the shard count grows: the first count that fits, by bisection.
        let (mut low, mut high) = (1u32, most);
        while low < high {
            let middle = low + (high - low) / 2;
            match self.shard(middle) <= limit {
                true => high = middle,
                false => low = middle + 1,
            }
        }
        Some(low)
    }

    /// The largest chunk that keeps a streamed bake within `limit` bytes, or the error that
    /// says how much the smallest chunk needs.
    pub fn chunk_within(&self, limit: u64) -> Result<usize> {
        let held = self.held();
        let room = limit.saturating_sub(held) / self.per_receiver_streamed.max(1);
        let clustering_room = match self.compression {
            0 => u64::MAX,
            clusters => {
                (limit + self.bvh).saturating_sub(held + clusters) / self.compression_per_row.max(1)
            }
        };
        let chunk = (room.min(clustering_room) as usize).min(self.receivers as usize);
        if chunk < MIN_CHUNK.min(self.receivers as usize) {
            let bounce = match self.held_streamed {
                0 => String::new(),
                held => format!(", the previous bounce {}", format_bytes(held)),
            };
            let document = match self.document {
                0 => String::new(),
                bytes => format!(
                    ", the scene's buffers and images {}",
                    format_bytes(2 * bytes)
                ),
            };
            let probes = match self.probes {
                0 => String::new(),
                bytes => format!(", the probes {}", format_bytes(bytes)),
            };
            let part = match self.merge_part {
                0 => String::new(),
                bytes => format!(", the largest part {}", format_bytes(bytes)),
            };
            let one_chunk = format_bytes(MIN_CHUNK as u64 * self.per_receiver_streamed);
            let chunk_or_clusters = match self.compression {
                0 => format!("one chunk of {MIN_CHUNK} receivers {one_chunk}"),
                clusters => format!(
                    "the larger of one chunk of {MIN_CHUNK} receivers {one_chunk} and the \
                     clustering's model, clusters and weights read back with it, less the BVH {}",
                    format_bytes(
                        (clusters + MIN_CHUNK as u64 * self.compression_per_row)
                            .saturating_sub(self.bvh)
                    )
                ),
            };
            return Err(Error::Options(format!(
                "--memory-limit {}: this bake needs at least {} (the mesh and its BVH \
                 {}{document}{bounce}{probes}{part}, {chunk_or_clusters})",
                format_bytes(limit),
                format_bytes(self.streamed(MIN_CHUNK)),
                format_bytes(self.fixed),
            )));
        }
        Ok(chunk.max(1))
    }
}

/// A receiver's gather row where light bounces (a column and a weight per blocked ray at
/// most, as the rays find it and as the matrix holds it); 0 otherwise.
pub(super) fn gather_row_bytes(options: &BakeOptions) -> u64 {
    // An error target may take any receiver to its most samples.
    let samples = options
        .target_error
        .map_or(options.samples_used(), |target| target.max_samples);
    match options.mode {
        Mode::Interreflected => 2 * 8 * samples as u64,
        _ => 0,
    }
}

/// What the process holds before it loads anything: code, thread stacks, the allocator's
/// arenas (measured: docs/performance.md).
const BASELINE: u64 = 8 << 20;

/// `bytes` as a person reads it: "1.5 GiB", "320 MiB", "12 KiB".
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    match unit {
        0 => format!("{bytes} B"),
        _ => format!("{value:.1} {}", UNITS[unit]),
    }
}

/// A bake planned for streaming: the prepared scene and what the backends read, ready to
/// compute any run of its receivers (the vertices).
pub struct StreamedBake {
    planned: super::Planned,
    options: BakeOptions,
    /// The direct pass, where it was computed elsewhere (a merge's parts): read a chunk at a
    /// time instead of cast.
    given: Option<Box<dyn GivenDirect>>,
}

impl StreamedBake {
    /// Prepares `scene` and builds its BVH for a bake with `options`, which must stream.
    pub fn plan(scene: Scene, options: &BakeOptions) -> Result<StreamedBake> {
        options.validate()?;
        if !streams(options) {
            return Err(Error::Options(
                "only bakes at the vertices stream in chunks (no least-squares fit or \
                 lightmap)"
                    .into(),
            ));
        }
        Ok(StreamedBake {
            planned: plan(scene, options)?,
            options: options.clone(),
            given: None,
        })
    }

    /// The bake with its direct pass `given`, read a chunk at a time (a streamed merge).
    pub fn with_given(self, given: Box<dyn GivenDirect>) -> Result<StreamedBake> {
        if given.receivers() != self.receivers() {
            return Err(Error::Merge(format!(
                "the given direct pass holds {} receivers, and the mesh has {}",
                given.receivers(),
                self.receivers()
            )));
        }
        Ok(StreamedBake {
            given: Some(given),
            ..self
        })
    }

    /// The direct pass of the receivers `range`: given, or cast on `backend`. Progress
    /// advances per receiver.
    fn direct(
        &self,
        range: Range<usize>,
        backend: &dyn Backend,
        progress: &dyn Progress,
    ) -> Result<DirectPass> {
        let Some(given) = &self.given else {
            let inputs = &self.planned.inputs;
            return direct_or_adaptive(inputs, range, &self.options, backend, &Advancing(progress));
        };
        let direct = given.direct(range.clone())?;
        check_given(&direct, range.len(), &self.options)?;
        progress.advance(range.len() as u64);
        Ok(direct)
    }

    pub fn scene(&self) -> &Scene {
        &self.planned.scene
    }

    /// The prepared scene, once the bake is done.
    pub fn into_scene(self) -> Scene {
        self.planned.scene
    }

    pub fn receivers(&self) -> usize {
        self.planned.receivers.len()
    }

    pub fn bands(&self) -> u32 {
        self.options.bands
    }

    /// The stored transfer's channels, by the whole bake's lean rule: one for direct
    /// transfer (albedo-free), and for interreflected transfer when every albedo is grey.
    pub fn channels(&self) -> u32 {
        match (self.options.storage, self.options.mode) {
            (Storage::Rgb, _) => 3,
            (Storage::Lean, Mode::Interreflected) if !self.all_grey() => 3,
            (Storage::Lean, _) => 1,
        }
    }

    fn all_grey(&self) -> bool {
        self.planned.scene.all_grey()
    }

    pub fn mode(&self) -> Mode {
        self.options.mode
    }

    /// The error target each receiver bakes to, if any.
    pub fn target_error(&self) -> Option<super::adaptive::TargetError> {
        self.options.target_error
    }

    /// What the baked file records, as the whole bake on `backend` would, after `bounces`.
    pub fn metadata(&self, backend: &dyn Backend, bounces: usize) -> BakeMetadata {
        let samples = self.planned.inputs.samples.len();
        BakeMetadata {
            channels: self.channels(),
            albedo_free: self.options.albedo_free(),
            backend: match &self.given {
                Some(given) => given.ran_on(),
                None => backend.describe(),
            },
            ..metadata_for(&self.options, samples, bounces, None)
        }
    }

    /// The transfer of the receivers `range` (`[vertex][channel][k]`), the rays cast, and
    /// with an error target each receiver's samples and error. Progress advances per
    /// receiver, without starting a stage of its own.
    pub fn chunk(
        &self,
        range: Range<usize>,
        backend: &dyn Backend,
        progress: &dyn Progress,
    ) -> Result<(Transfer, u64, Option<ReceiverErrors>)> {
        let direct = self.direct(range.clone(), backend, progress)?;
        let bands = self.options.bands;
        let transfer = match self.options.storage {
            Storage::Lean => Transfer::new(bands, 1, range.len(), direct.scalar)
                .expect("the direct pass's row for every receiver"),
            Storage::Rgb => {
                let albedo = &self.planned.receivers.albedo[range];
                tint_by_albedo(&direct.scalar, albedo, bands)
            }
        };
        Ok((transfer, direct.rays_cast, direct.adaptive))
    }

    /// Interreflected transfer in bounded memory ([module docs](self)): the direct pass
    /// `chunk` receivers at a time, then each bounce a chunk of gather rows at a time. Returns
    /// the RGB transfer in the scratch file, each bounce's share and the rays cast.
    pub fn interreflected(
        &self,
        chunk: usize,
        backend: &dyn Backend,
        progress: &dyn Progress,
    ) -> Result<Interreflected> {
        let receivers = self.receivers();
        let bands = self.options.bands;
        let coeffs = coeff_count(bands);
        let stride = 3 * coeffs;
        let albedo = &self.planned.receivers.albedo;
        let ranges: Vec<Range<usize>> = (0..receivers)
            .step_by(chunk.max(1))
            .map(|first| first..(first + chunk).min(receivers))
            .collect();
        let mut spill = Spill::new()?;
        // The scratch file: the transfer so far, the next bounce, then each chunk's rows.
        let (total_at, next_at) = (0, (receivers * stride * 4) as u64);
        spill.reserve(2 * next_at);
        let mut previous = vec![0.0f32; receivers * stride];
        let mut rows = Vec::with_capacity(ranges.len());
        let mut rays_cast = 0;
        let mut gather_entries = 0;
        let mut adaptive: Option<ReceiverErrors> = None;
        progress.stage("transfer", receivers as u64);
        for range in &ranges {
            let direct = self.direct(range.clone(), backend, progress)?;
            if let Some(errors) = direct.adaptive {
                adaptive
                    .get_or_insert_with(ReceiverErrors::default)
                    .extend(errors);
            }
            let matrix = direct.matrix.expect("an interreflected pass gathers");
            let tinted = tint_by_albedo(&direct.scalar, &albedo[range.clone()], bands);
            previous[range.start * stride..range.end * stride].copy_from_slice(tinted.coeffs());
            rows.push(SpilledRows::put(&mut spill, &matrix)?);
            rays_cast += direct.rays_cast;
            gather_entries += matrix.columns.len();
        }
        spill.write_at(total_at, &previous)?;

        progress.stage("bounces", self.options.bounces as u64);
        let mut bounces = Vec::new();
        for _ in 0..self.options.bounces {
            let started = std::time::Instant::now();
            let (mut added, mut before) = (0.0, 0.0);
            for (range, spilled) in ranges.iter().zip(&rows) {
                let matrix = spilled.read(&mut spill)?;
                let albedo = &albedo[range.clone()];
                let next = backend
                    .gatherer(&matrix, albedo, bands)?
                    .gather(&previous)?;
                let at = (range.start * stride * 4) as u64;
                let mut total: Vec<f32> = spill.read_vec(total_at + at, next.len())?;
                added = bounce::dc_energy(added, &next, coeffs);
                before = bounce::dc_energy(before, &total, coeffs);
                total.iter_mut().zip(&next).for_each(|(t, n)| *t += n);
                spill.write_at(total_at + at, &total)?;
                spill.write_at(next_at + at, &next)?;
            }
            spill.read_at(next_at, &mut previous)?;
            let relative_energy = bounce::energy_ratio(added, before);
            bounces.push(BounceStat {
                relative_energy,
                seconds: started.elapsed().as_secs_f64(),
                fit_iterations: None,
            });
            progress.advance(1);
            if relative_energy < self.options.bounce_tolerance {
                break;
            }
        }
        Ok(Interreflected {
            spill,
            total_at,
            bands,
            bounces,
            rays_cast,
            gather_entries,
            adaptive,
        })
    }

    /// The tree's node count, for the report.
    pub fn bvh_nodes(&self) -> usize {
        self.planned.inputs.bvh.nodes.len()
    }

    pub fn samples_used(&self) -> usize {
        self.planned.inputs.samples.len()
    }

    /// What preparing the mesh and building the BVH took.
    pub fn prepared(
        &self,
    ) -> (
        &crate::scene::prepare::PrepareReport,
        &crate::scene::prepare::VertexMap,
        f64,
    ) {
        (
            &self.planned.prepare,
            &self.planned.vertex_map,
            self.planned.seconds,
        )
    }
}

/// A streamed interreflected bake's transfer, RGB `[vertex][channel][k]` in its scratch file,
/// and what the report says of it.
pub struct Interreflected {
    spill: Spill,
    total_at: u64,
    bands: u32,
    pub bounces: Vec<BounceStat>,
    pub rays_cast: u64,
    pub gather_entries: usize,
    /// With an error target, each receiver's samples and error.
    pub adaptive: Option<ReceiverErrors>,
}

impl Interreflected {
    /// The stored transfer of the receivers `range`, `channels` of it (1: the lean form of
    /// grey albedo, the red channel).
    pub fn chunk(&mut self, range: Range<usize>, channels: u32) -> Result<Transfer> {
        let coeffs = coeff_count(self.bands);
        let stride = 3 * coeffs;
        let at = self.total_at + (range.start * stride * 4) as u64;
        let rgb: Vec<f32> = self.spill.read_vec(at, range.len() * stride)?;
        let coeffs = match channels {
            1 => rgb
                .chunks_exact(stride)
                .flat_map(|v| v[..coeffs].iter().copied())
                .collect(),
            _ => rgb,
        };
        Ok(Transfer::new(self.bands, channels, range.len(), coeffs)
            .expect("the spilled chunk's rows"))
    }
}

/// Where one chunk's gather rows lie in the scratch file.
pub(super) struct SpilledRows {
    offsets_at: u64,
    columns_at: u64,
    weights_at: u64,
    rows: usize,
    entries: usize,
}

impl SpilledRows {
    pub(super) fn put(spill: &mut Spill, matrix: &GatherMatrix) -> Result<SpilledRows> {
        Ok(SpilledRows {
            offsets_at: spill.append(&matrix.row_offsets)?,
            columns_at: spill.append(&matrix.columns)?,
            weights_at: spill.append(&matrix.weights)?,
            rows: matrix.rows(),
            entries: matrix.columns.len(),
        })
    }

    pub(super) fn read(&self, spill: &mut Spill) -> Result<GatherMatrix> {
        Ok(GatherMatrix {
            row_offsets: spill.read_vec(self.offsets_at, self.rows + 1)?,
            columns: spill.read_vec(self.columns_at, self.entries)?,
            weights: spill.read_vec(self.weights_at, self.entries)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_fit_the_limit_and_a_limit_below_one_chunk_is_refused() {
        let need = MemoryNeed::estimate(100_000, 200_000, &BakeOptions::default());
        assert!(need.whole() > need.streamed(need.receivers as usize / 2));
        let limit = need.fixed + 1000 * need.per_receiver_streamed + 7;
        let chunk = need.chunk_within(limit).unwrap();
        assert_eq!(chunk, 1000);
        assert!(need.streamed(chunk) <= limit);
        assert_eq!(need.chunk_within(u64::MAX).unwrap(), 100_000);
        let error = need.chunk_within(need.fixed).unwrap_err().to_string();
        assert!(error.contains("needs at least"), "{error}");
    }

    #[test]
    fn bytes_read_as_people_write_them() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(1536), "1.5 KiB");
        assert_eq!(format_bytes(3 << 30), "3.0 GiB");
    }
}
