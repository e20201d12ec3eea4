//! The stages that shape what a transfer bake stores: the bands `--bands auto` keeps, clustered
//! PCA, and what half-float rounding costs.

use std::fmt;
use std::time::Instant;

use crate::bake::{self, BakedMesh, Progress, StagePosition};
use crate::compress::{self, Cpca, CpcaOptions};
use crate::device::GpuContext;
use crate::precision::Precision;
use crate::spec::{Compression, AUTO_MAX_BANDS};
use crate::{glb, light, render, Result};

/// What `--bands auto` chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BandsChosen {
    pub bands: u32,
    /// The fraction of the transfer's energy in the bands left out.
    pub beyond: f64,
    pub threshold: f64,
}

impl fmt::Display for BandsChosen {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let BandsChosen {
            bands,
            beyond,
            threshold,
        } = *self;
        write!(
            f,
            "bands auto: {bands} ({:.2}% of the transfer's energy lies in bands {bands} to {}, \
             below --bands-threshold {threshold})",
            100.0 * beyond,
            AUTO_MAX_BANDS - 1,
        )
    }
}

/// `--bands auto`: the baked mesh cut to the bands the threshold asks for.
pub(super) fn choose_auto_bands(baked: &mut BakedMesh, threshold: f64) -> BandsChosen {
    let (bands, beyond) = bake::choose_bands(&baked.transfer, threshold);
    bake::truncate_baked(baked, bands);
    BandsChosen {
        bands,
        beyond,
        threshold,
    }
}

/// What clustered PCA made of the transfer: its shape, where and how fast it ran, the sizes
/// and the errors of the stored form.
#[derive(Clone, Debug, PartialEq)]
pub struct Compressed {
    pub clusters: u32,
    pub components: u32,
    pub seconds: f64,
    pub ran_on: String,
    pub precision: Precision,
    pub bytes: usize,
    pub bytes_uncompressed: usize,
    pub coefficient_error: f64,
    /// Under the preview light.
    pub relit_error: f64,
}

impl fmt::Display for Compressed {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let half = match self.precision {
            Precision::F32 => "",
            Precision::F16 => " as half floats",
        };
        write!(
            f,
            "compressed: {} clusters x {} components in {:.2} s ({}), {} bytes{half} of {} \
             ({:.1}x smaller); coefficient error {:.2}%, relit error {:.2}% under the preview \
             light",
            self.clusters,
            self.components,
            self.seconds,
            self.ran_on,
            self.bytes,
            self.bytes_uncompressed,
            self.bytes_uncompressed as f64 / self.bytes as f64,
            100.0 * self.coefficient_error,
            100.0 * self.relit_error
        )
    }
}

/// The baked transfer, rows of `(bands, channels)` read from `rows` (in memory, or a streamed
/// bake's scratch file), compressed as `compression` asks and rounded as a file at `precision`
/// stores it. The assignment steps run on `gpu` where it pays
/// (`GpuAssigner::where_it_pays`; where it does not for a reason, a note says so). A search
/// for the shape that meets an error is a stage, a step a shape.
pub(super) fn compress_transfer(
    rows: &mut dyn compress::Rows,
    (bands, channels): (u32, u32),
    (compression, precision): (Compression, Precision),
    gpu: Option<&GpuContext>,
    notes: &mut Vec<String>,
    progress: &dyn Progress,
) -> Result<(Cpca, Compressed)> {
    let started = Instant::now();
    let (dimension, vertices) = (rows.dimension(), rows.len());
    let most_components = match compression {
        Compression::Shape { components, .. } => components as usize,
        Compression::Target { .. } => dimension,
    };
    let gpu_assigner = match gpu {
        Some(context) => {
            let (assigner, why_not) =
                compress::gpu::GpuAssigner::where_it_pays(context, rows, most_components)?;
            if let Some(why) = why_not {
                notes.push(format!("{why}; clustering on the CPU"));
            }
            assigner
        }
        None => None,
    };
    let (assigner, ran_on): (&dyn compress::Assigner, String) = match &gpu_assigner {
        Some(assigner) => (assigner, format!("gpu: {}", assigner.label())),
        None => (&compress::CpuAssigner, "cpu".into()),
    };
    let (cpca, options) = match compression {
        Compression::Shape {
            clusters,
            components,
        } => {
            let options = CpcaOptions {
                clusters,
                components,
                ..CpcaOptions::default()
            };
            progress.stage("compress", compress::compress_steps(&options));
            let mut position = StagePosition::new(progress);
            let watch = &mut |step: u64| position.move_to(step);
            let shape = (bands, channels);
            let cpca = compress::compress_watched(rows, shape, &options, (assigner, watch))?;
            (cpca, options)
        }
        Compression::Target { error } => {
            let steps = compress::choose_steps(dimension, vertices);
            progress.stage("compress", steps as u64);
            let mut position = StagePosition::new(progress);
            let trying = &mut |step: usize, options: &CpcaOptions| {
                position.move_to(step as u64);
                let (k, m) = (options.clusters, options.components);
                progress.detail(&format!("({k} clusters x {m} components)"));
            };
            let seed = CpcaOptions::default().seed;
            let searching = (seed, assigner);
            compress::choose_from(rows, (bands, channels), error, searching, trying)?
        }
    };
    let cpca = cpca.rounded(precision);
    let seconds = started.elapsed().as_secs_f64();
    let light = light::preview_light(bands)?;
    let compressed = Compressed {
        clusters: options.clusters,
        components: options.components,
        seconds,
        ran_on,
        precision,
        bytes: cpca.byte_size(precision),
        bytes_uncompressed: compress::uncompressed_bytes(rows),
        coefficient_error: compress::relative_error_of(rows, &cpca)?,
        relit_error: compress::relit_error_of(rows, channels, &cpca, &light)?,
    };
    Ok((cpca, compressed))
}

/// What storing per-vertex transfer as half floats costs: bytes, and the relit error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfFloatCost {
    pub bytes: usize,
    pub bytes_f32: usize,
    /// Under the preview light.
    pub relit_error: f64,
    /// The largest relative rounding of a coefficient of magnitude 1e-4 or more.
    pub worst_coefficient: f32,
}

impl fmt::Display for HalfFloatCost {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(
            f,
            "precision f16: transfer {} bytes instead of {}; relit error {:.1e} under the preview \
             light, worst coefficient {:.1e} relative (of those above 1e-4)",
            self.bytes, self.bytes_f32, self.relit_error, self.worst_coefficient
        )
    }
}

pub(super) fn half_float_cost(baked: &BakedMesh) -> Result<HalfFloatCost> {
    let mut tally = HalfFloatTally::new(baked.transfer.bands())?;
    tally.add(&baked.transfer)?;
    Ok(tally.cost())
}

/// [`HalfFloatCost`] summed over runs of vertices in order: the whole transfer at once, or the
/// chunks of a streamed bake, give the same figures.
pub(super) struct HalfFloatTally {
    light: light::ShLight,
    relit: compress::RelativeRms,
    worst_coefficient: f32,
    values: usize,
}

impl HalfFloatTally {
    pub(super) fn new(bands: u32) -> Result<HalfFloatTally> {
        Ok(HalfFloatTally {
            light: light::preview_light(bands)?,
            relit: compress::RelativeRms::default(),
            worst_coefficient: 0.0,
            values: 0,
        })
    }

    pub(super) fn add(&mut self, transfer: &bake::Transfer) -> Result<()> {
        let rounded = glb::rounded_to_f16(transfer);
        let exact = render::relight(transfer, &self.light)?;
        let stored = render::relight(&rounded, &self.light)?;
        self.relit.add_radiance(&exact, &stored);
        self.worst_coefficient = transfer
            .coeffs()
            .iter()
            .zip(rounded.coeffs())
            .filter(|(x, _)| x.abs() >= 1e-4)
            .map(|(x, r)| ((r - x) / x).abs())
            .fold(self.worst_coefficient, f32::max);
        self.values += transfer.coeffs().len();
        Ok(())
    }

    pub(super) fn cost(&self) -> HalfFloatCost {
        HalfFloatCost {
            bytes: self.values * Precision::F16.bytes(),
            bytes_f32: self.values * Precision::F32.bytes(),
            relit_error: self.relit.value(),
            worst_coefficient: self.worst_coefficient,
        }
    }
}
