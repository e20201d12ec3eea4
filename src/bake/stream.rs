//! Bakes in bounded memory: the receivers' transfer computed a chunk at a time, each chunk
//! handed on (to the file being written) before the next, so that peak memory is the mesh, its
//! BVH and one chunk rather than every vertex's transfer. A chunk's transfer depends only on
//! its receivers, so a chunked bake writes the bytes of the whole one.
//!
//! Only bakes whose vertex values are their own receivers' can stream: shadowed or unshadowed
//! transfer at the vertices, no fit, lightmap or error target. Interreflection needs every
//! receiver's gather row for each bounce, and a fit solves for all vertices at once.

use std::ops::Range;

use super::{
    direct_pass, metadata_for, plan, tint_by_albedo, Backend, BakeMetadata, BakeOptions,
    DirectInputs, Fit, Mode, Progress, Storage, Transfer,
};
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::sh::coeff_count;

/// Whether a bake with `options` can be computed in chunks ([module docs](self)).
pub fn streams(options: &BakeOptions) -> bool {
    options.mode != Mode::Interreflected
        && options.fit == Fit::Point
        && options.lightmap.is_none()
        && options.target_error.is_none()
}

/// Bytes a bake needs, estimated from the mesh's size before it starts: what it holds
/// whatever the chunking (mesh, BVH, ray origins), and what each receiver adds when all are
/// held at once and when they stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryNeed {
    pub fixed: u64,
    pub per_receiver_whole: u64,
    pub per_receiver_streamed: u64,
    pub receivers: u64,
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
        MemoryNeed {
            fixed,
            // The direct pass, its RGB transfer, and the file's bytes twice (encoded BIN,
            // then the whole container).
            per_receiver_whole: 4 * coeffs + transfer + 2 * file_transfer,
            // The same for one chunk, and its file blocks.
            per_receiver_streamed: 4 * coeffs + transfer + file_transfer,
            receivers: v,
        }
    }

    /// The whole bake's need, every receiver at once.
    pub fn whole(&self) -> u64 {
        self.fixed + self.receivers * self.per_receiver_whole
    }

    /// The need of a bake streamed `chunk` receivers at a time.
    pub fn streamed(&self, chunk: usize) -> u64 {
        self.fixed + chunk as u64 * self.per_receiver_streamed
    }

    /// The need of one of `shards` shards of a bake with `options`: the mesh and its BVH, and
    /// its share of the receivers at a whole bake's cost each, plus for interreflection their
    /// gather rows (a column and a weight per sample, in the pass and in the part file).
    pub fn shard(&self, shards: u32, options: &BakeOptions) -> u64 {
        let share = self.receivers.div_ceil(shards.max(1) as u64);
        let gather = match options.mode {
            Mode::Interreflected => 2 * 8 * options.samples_used() as u64,
            _ => 0,
        };
        self.fixed + share * (self.per_receiver_whole + gather)
    }

    /// The fewest shards, at most `receivers`, each within `limit` bytes; `None` when the mesh
    /// and its BVH alone exceed it.
    pub fn shards_within(&self, limit: u64, options: &BakeOptions) -> Option<u32> {
        let most = self.receivers.clamp(1, u32::MAX as u64) as u32;
        if self.shard(most, options) > limit {
            return None;
        }
        // The need falls as the shard count grows: the first count that fits, by bisection.
        let (mut low, mut high) = (1u32, most);
        while low < high {
            let middle = low + (high - low) / 2;
            match self.shard(middle, options) <= limit {
                true => high = middle,
                false => low = middle + 1,
            }
        }
        Some(low)
    }

    /// The largest chunk that keeps a streamed bake within `limit` bytes, or the error that
    /// says how much the smallest chunk needs.
    pub fn chunk_within(&self, limit: u64) -> Result<usize> {
        let room = limit.saturating_sub(self.fixed) / self.per_receiver_streamed.max(1);
        let chunk = (room as usize).min(self.receivers as usize);
        if chunk < MIN_CHUNK.min(self.receivers as usize) {
            return Err(Error::Options(format!(
                "--memory-limit {}: this bake needs at least {} (the mesh and its BVH {}, one \
                 chunk of {MIN_CHUNK} receivers {})",
                format_bytes(limit),
                format_bytes(self.streamed(MIN_CHUNK)),
                format_bytes(self.fixed),
                format_bytes(MIN_CHUNK as u64 * self.per_receiver_streamed)
            )));
        }
        Ok(chunk.max(1))
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
}

impl StreamedBake {
    /// Prepares `scene` and builds its BVH for a bake with `options`, which must stream.
    pub fn plan(scene: Scene, options: &BakeOptions) -> Result<StreamedBake> {
        options.validate()?;
        if !streams(options) {
            return Err(Error::Options(
                "only shadowed and unshadowed bakes at the vertices stream in chunks (no \
                 interreflection, fit, lightmap or error target)"
                    .into(),
            ));
        }
        Ok(StreamedBake {
            planned: plan(scene, options)?,
            options: options.clone(),
        })
    }

    pub fn scene(&self) -> &Scene {
        &self.planned.scene
    }

    pub fn receivers(&self) -> usize {
        self.planned.receivers.len()
    }

    /// The transfer's shape: bands and channels (one for lean storage).
    pub fn channels(&self) -> u32 {
        match self.options.storage {
            Storage::Lean => 1,
            Storage::Rgb => 3,
        }
    }

    /// What the baked file records, as the whole bake on `backend` would.
    pub fn metadata(&self, backend: &Backend) -> BakeMetadata {
        BakeMetadata {
            channels: self.channels(),
            albedo_free: self.options.storage == Storage::Lean,
            backend: backend.describe(),
            ..metadata_for(&self.options, self.planned.inputs.samples.len(), 0, None)
        }
    }

    /// The transfer of the receivers `range` (`[vertex][channel][k]`), and the rays cast.
    /// Progress advances per receiver, without starting a stage of its own.
    pub fn chunk(
        &self,
        range: Range<usize>,
        backend: &Backend,
        progress: &dyn Progress,
    ) -> Result<(Transfer, u64)> {
        let view = self.planned.inputs.view();
        let part = DirectInputs {
            origins: &view.origins[range.clone()],
            normals: &view.normals[range.clone()],
            ..view
        };
        let direct = direct_pass(&part, self.options.mode, backend, &Advancing(progress))?;
        let bands = self.options.bands;
        let transfer = match self.options.storage {
            Storage::Lean => Transfer {
                bands,
                channels: 1,
                vertex_count: range.len(),
                coeffs: direct.scalar,
            },
            Storage::Rgb => {
                let albedo = &self.planned.receivers.albedo[range];
                tint_by_albedo(&direct.scalar, albedo, bands)
            }
        };
        Ok((transfer, direct.rays_cast))
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

/// Progress that passes on advances but not stages: chunks advance one stage of the whole.
struct Advancing<'a>(&'a dyn Progress);

impl Progress for Advancing<'_> {
    fn advance(&self, done: u64) {
        self.0.advance(done);
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
