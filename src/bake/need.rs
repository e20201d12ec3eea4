//! What a bake needs in memory, estimated from the mesh's size before it starts: whole, streamed
//! in chunks ([`super::stream`]), a least-squares fit's points in runs, a lightmap held, a
//! shard, a merge; and how that reads to a person.

use super::{BakeOptions, Mode};
use crate::error::{Error, Result};
use crate::sh::coeff_count;

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
    /// Beside a held lightmap, the fit's points baked this many at a time
    /// ([`MemoryNeed::with_fit_run`]); `None`: all at once.
    pub fit_run: Option<u64>,
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
            fit_run: None,
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

    /// The need with the fit's points baked `run` at a time beside a held lightmap
    /// ([`MemoryNeed::lightmap_held`] counts the fit so).
    pub fn with_fit_run(self, run: u64) -> MemoryNeed {
        MemoryNeed {
            fit_run: Some(run),
            ..self
        }
    }

    /// The largest run of the fit's points that keeps what the fit holds, beside `beside`
    /// bytes, within `limit` (the smallest run where none does); `None` without a fit.
    pub fn fit_run_within(&self, beside: u64, limit: u64) -> Option<u64> {
        let fit = self.fit?;
        let smallest = (MIN_CHUNK as u64).min(fit.points).max(1);
        let (mut low, mut high) = (smallest, fit.points.max(smallest));
        while low < high {
            let middle = low + (high - low).div_ceil(2);
            match beside + fit.chunked(middle) <= limit {
                true => low = middle,
                false => high = middle - 1,
            }
        }
        Some(low)
    }

    /// The whole bake's need but for its fit's.
    pub(crate) fn beside_fit(&self) -> u64 {
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
pub(crate) fn gather_row_bytes(options: &BakeOptions) -> u64 {
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
