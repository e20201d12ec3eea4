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
    direct_run, metadata_for, plan, tint_by_albedo, Backend, BakeMetadata, BakeOptions, BounceStat,
    DirectPass, Fit, GivenDirect, Mode, Progress, Storage, Transfer,
};
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::sh::coeff_count;

/// Whether a bake with `options` can be computed in chunks ([module docs](self)).
pub fn streams(options: &BakeOptions) -> bool {
    options.fit == Fit::Point && options.lightmap.is_none()
}

// What a bake needs in memory, whole and streamed, lives in `need.rs`; its paths stay here.
pub(super) use super::need::gather_row_bytes;
pub use super::need::{format_bytes, FitNeed, MemoryNeed, MIN_CHUNK};

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
        let at = (&self.planned.inputs, range);
        direct_run(self.given.as_deref(), at, &self.options, backend, progress)
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
