//! Baking to an error target (`--target-error E`): each receiver casts batches of samples until
//! the estimated standard error of its transfer is below the target, so that a receiver under
//! open sky stops after a few batches and one deep in a crevice takes many.
//!
//! Honest estimates need independent batches: batch b draws its directions with its own seed
//! (a lattice or a sphere set turned by its own random shift), shared by all receivers, so the
//! batch estimates of one receiver are independent and unbiased, their mean is the estimate, and
//! the spread between them estimates its error:
//!
//! `SE^2 = sum_k var_k / n`, `var_k = sum_b (t_bk - mean_k)^2 / (n - 1)`.
//!
//! Each batch estimates only what is blocked, against the closed-form unoccluded transfer (the
//! control variate), with the strategy's directions (cosine-distributed by default, the best
//! per sample): a receiver under open sky is then exact and stops after [`MIN_BATCHES`], and
//! the variance a receiver has is that of its occlusion.
//!
//! **What the error means.** E is that standard error in the L2 norm of the (albedo-free)
//! transfer vector, relative to the norm of unoccluded transfer (the same for every normal). By
//! Cauchy–Schwarz it bounds the relit radiance's error under any light, relative to what the
//! same light could at most give an open receiver: no light is assumed.
//!
//! **Interreflection.** Every batch's rays are cast once for their closest hits, which give
//! both its visibility and its gather rows, and a receiver's gather row is the mean of its
//! batches' rows, as its direct transfer is the mean of their estimates: the bounces gather
//! through the rays the target chose. The target measures the direct (shadowed) transfer; the
//! bounces, which add a fraction of it per bounce (the albedo's), are as many rays' worth.

use rayon::prelude::*;

use glam::Vec3;

use super::bounce::{summed_by_column, GatherMatrix};
use super::cpu::{finish_transfer, transfer_scale};
use super::{Backend, BakeInputs, DirectInputs, DirectPass, Mode, NoProgress, Progress};
use crate::error::{Error, Result};
use crate::sampling::{Estimator, SampleSet, Sampling};
use crate::sh::{coeff_count, unshadowed_transfer, ShTable};

/// Samples in one batch.
pub const BATCH_SAMPLES: u32 = 128;

/// Batches every receiver casts before its spread is trusted (the estimate of the error has
/// `MIN_BATCHES - 1` degrees of freedom).
pub const MIN_BATCHES: u32 = 4;

/// Batches after which a receiver none of whose rays was blocked stops: its control-variate
/// estimate is the closed form, exact.
pub const OPEN_BATCHES: u32 = 2;

/// What an error-targeted bake is asked.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TargetError {
    /// The standard error to reach, relative to unoccluded transfer's norm.
    pub relative: f64,
    /// The most samples one receiver casts (a multiple of [`BATCH_SAMPLES`]).
    pub max_samples: u32,
}

impl TargetError {
    pub fn validate(&self) -> Result<()> {
        if !(self.relative.is_finite() && self.relative > 0.0 && self.relative < 1.0) {
            return Err(Error::Options(format!(
                "--target-error {} must lie in (0, 1)",
                self.relative
            )));
        }
        let min = MIN_BATCHES * BATCH_SAMPLES;
        if self.max_samples < min || self.max_samples > crate::sampling::MAX_SAMPLES {
            return Err(Error::Options(format!(
                "--max-samples {} is out of range ({min} to {})",
                self.max_samples,
                crate::sampling::MAX_SAMPLES
            )));
        }
        Ok(())
    }

    fn max_batches(&self) -> u32 {
        (self.max_samples / BATCH_SAMPLES).max(MIN_BATCHES)
    }
}

/// How an error-targeted bake went, for the summary line.
#[derive(Clone, Debug, PartialEq)]
pub struct AdaptiveReport {
    /// Samples per receiver: fewest, median, most; and the mean.
    pub samples_min: u32,
    pub samples_median: u32,
    pub samples_max: u32,
    pub samples_mean: f64,
    /// Receivers that reached the sample cap before the target.
    pub at_cap: usize,
    /// Estimated relative standard error per receiver: median, 90th percentile, largest.
    pub error_median: f64,
    pub error_p90: f64,
    pub error_max: f64,
    /// Samples each receiver cast, in the receivers' order.
    pub per_receiver: Vec<u32>,
}

/// What an error-targeted direct pass says about each of its receivers: the samples it cast
/// and the relative standard error it reached (in the receivers' order). A sharded bake
/// carries it in its parts, so that the merge reports what the whole bake would have.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReceiverErrors {
    pub samples: Vec<u32>,
    pub errors: Vec<f64>,
}

impl ReceiverErrors {
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// `other`'s receivers after these.
    pub fn extend(&mut self, other: ReceiverErrors) {
        self.samples.extend(other.samples);
        self.errors.extend(other.errors);
    }
}

/// The seed of batch `b` of a bake seeded `seed`: distinct streams, none equal to `seed`.
pub fn batch_seed(seed: u64, batch: u32) -> u64 {
    seed ^ (batch as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// The direct pass of the receivers `range` of `base` to the target error, on `backend`:
/// albedo-free direct transfer (`[receiver][k]`), in interreflected mode the gather matrix of
/// the same rays' closest hits, the rays cast, and each receiver's samples and error. `base`
/// supplies the geometry and receivers; its own sample set is not used. Batch by batch, the
/// receivers still short of the target cast the batch's samples; a receiver's result depends
/// only on the receiver, the seed and the backend, so any split of the receivers gives the
/// same values for each.
pub fn adaptive_direct_pass(
    backend: &dyn Backend,
    base: &BakeInputs,
    range: std::ops::Range<usize>,
    (sampling, seed, mode): (Sampling, u64, Mode),
    target: &TargetError,
    progress: &dyn Progress,
) -> Result<DirectPass> {
    target.validate()?;
    // Interreflection's direct light is shadowed transfer, summed with the gather rows of the
    // same rays' hits; its bounces come from the rows.
    let mut rows = (mode == Mode::Interreflected).then(|| vec![Vec::new(); range.len()]);
    let bands = base.table.bands;
    let n = coeff_count(bands);
    let view = base.view();
    // Every normal's unoccluded transfer has the same norm.
    let open_norm = norm(&unshadowed_transfer(bands, glam::DVec3::Z));
    let mut receivers: Vec<ReceiverBatches> =
        range.map(|index| ReceiverBatches::new(index, n)).collect();
    let mut rays = 0;
    let mut first_batch = None;
    for b in 0..target.max_batches() {
        let active: Vec<usize> = (0..receivers.len())
            .filter(|&i| !receivers[i].done)
            .collect();
        if active.is_empty() {
            break;
        }
        let samples = sampling.directions(BATCH_SAMPLES, batch_seed(seed, b));
        let table = ShTable::new(bands, &samples.directions);
        let origins: Vec<Vec3> = active
            .iter()
            .map(|&i| view.origins[receivers[i].index])
            .collect();
        let normals: Vec<Vec3> = active
            .iter()
            .map(|&i| view.normals[receivers[i].index])
            .collect();
        let batch = DirectInputs {
            origins: &origins,
            normals: &normals,
            samples: &samples,
            table: &table,
            // The control variate: what is open is exact, only what is blocked is estimated.
            estimator: Estimator::Blocked,
            // A batch holds the receivers still short of their target, not a range of them,
            // so it casts in the plain frames ([`DirectInputs::turns`] numbers a range); its
            // own fresh set decorrelates neighbours anyway.
            turns: None,
            ..view
        };
        let (sums, batch_rays) = match &mut rows {
            Some(rows) => {
                let (sums, batch_rows, batch_rays) =
                    backend.projected_sums_and_gather_rows(&batch, &NoProgress)?;
                for (&i, row) in active.iter().zip(batch_rows) {
                    rows[i].extend(row);
                }
                (sums, batch_rays)
            }
            None => backend.projected_sums(&batch, mode, &NoProgress)?,
        };
        rays += batch_rays;
        let scale = transfer_scale(&batch);
        let last = b + 1 == target.max_batches();
        for (estimate, &i) in sums.chunks_exact(n).zip(&active) {
            let receiver = &mut receivers[i];
            receiver.add(estimate, scale, target.relative * open_norm);
            if receiver.done || last {
                receiver.done = true;
                progress.advance(1);
            }
        }
        first_batch.get_or_insert((samples, table));
    }
    let first_batch = first_batch.expect("a target has batches");
    let transfer = finish_means(&view, first_batch, &receivers, n);
    let matrix = rows.map(|rows| mean_rows(rows, &receivers));
    let receivers = ReceiverErrors {
        samples: receivers.iter().map(|r| r.count * BATCH_SAMPLES).collect(),
        errors: receivers.iter().map(|r| r.error / open_norm).collect(),
    };
    Ok(DirectPass {
        scalar: transfer,
        matrix,
        rays_cast: rays,
        adaptive: Some(receivers),
    })
}

/// The gather matrix whose row i is the mean of receiver i's batch rows (`rows[i]`, their
/// entries one after another): each column's weights summed over the batches, over the
/// receiver's batch count, columns ascending as a [`GatherMatrix`] keeps them.
fn mean_rows(rows: Vec<Vec<(u32, f32)>>, receivers: &[ReceiverBatches]) -> GatherMatrix {
    let means = rows
        .into_par_iter()
        .zip(receivers)
        .map(|(entries, receiver)| {
            let entries = entries.into_iter().map(|(c, w)| (c, w as f64)).collect();
            let count = receiver.count.max(1) as f64;
            summed_by_column(entries)
                .into_iter()
                .map(|(column, sum)| (column, (sum / count) as f32))
                .collect()
        })
        .collect();
    GatherMatrix::from_rows(means)
}

/// Every receiver's transfer from the mean of its batches' projected sums, `[receiver][k]`
/// (`n` coefficients), finished with the first batch's `(samples, table)`.
///
/// Batches are summed as projected (for a tangent-frame set, in the receiver's own frame)
/// and finished once, on their mean: finishing is affine (a scale, a rotation, for the
/// control variate a closed form minus the sum), so the mean of finished batches is the
/// finished mean, and the rotation keeps the L2 norm the error is measured in.
fn finish_means(
    view: &DirectInputs,
    (samples, table): (SampleSet, ShTable),
    receivers: &[ReceiverBatches],
    n: usize,
) -> Vec<f32> {
    let finishing = DirectInputs {
        samples: &samples,
        table: &table,
        estimator: Estimator::Blocked,
        // The frames the batches were cast in.
        turns: None,
        ..*view
    };
    let mut transfer = vec![0.0f32; receivers.len() * n];
    transfer
        .par_chunks_mut(n)
        .zip(receivers)
        .for_each(|(out, receiver)| {
            let mut mean: Vec<f64> = receiver
                .sum
                .iter()
                .map(|s| s / receiver.count as f64)
                .collect();
            finish_transfer(&finishing, receiver.index, &mut mean);
            out.iter_mut().zip(&mean).for_each(|(o, m)| *o = *m as f32);
        });
    transfer
}

/// One receiver's batches so far: the sums and sums of squares of its projected estimates.
struct ReceiverBatches {
    index: usize,
    sum: Vec<f64>,
    sum_squares: Vec<f64>,
    count: u32,
    /// The standard error of the transfer (not relative), infinite before [`MIN_BATCHES`].
    error: f64,
    done: bool,
}

impl ReceiverBatches {
    fn new(index: usize, coeffs: usize) -> ReceiverBatches {
        ReceiverBatches {
            index,
            sum: vec![0.0; coeffs],
            sum_squares: vec![0.0; coeffs],
            count: 0,
            error: f64::INFINITY,
            done: false,
        }
    }

    /// Adds one batch's projected `estimate` (transfer `scale` times it), and is done when
    /// nothing was blocked after [`OPEN_BATCHES`] or, after [`MIN_BATCHES`], when the standard
    /// error is at most `target_norm`.
    fn add(&mut self, estimate: &[f64], scale: f64, target_norm: f64) {
        for ((s, q), &e) in self.sum.iter_mut().zip(&mut self.sum_squares).zip(estimate) {
            *s += e;
            *q += e * e;
        }
        self.count += 1;
        if self.count == OPEN_BATCHES && self.sum.iter().all(|&s| s == 0.0) {
            self.error = 0.0;
            self.done = true;
        } else if self.count >= MIN_BATCHES {
            self.error = scale * standard_error(&self.sum, &self.sum_squares, self.count);
            self.done = self.error <= target_norm;
        }
    }
}

/// The standard error (L2 over coefficients) of the mean of `count` batch estimates, from
/// their sums and sums of squares.
fn standard_error(sum: &[f64], sum_squares: &[f64], count: u32) -> f64 {
    let n = count as f64;
    let variance: f64 = sum
        .iter()
        .zip(sum_squares)
        .map(|(&s, &q)| ((q - s * s / n) / (n - 1.0)).max(0.0))
        .sum();
    (variance / n).sqrt()
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

impl AdaptiveReport {
    /// The summary of a whole error-targeted bake from its receivers'.
    pub fn of(receivers: &ReceiverErrors, target: &TargetError) -> AdaptiveReport {
        let mut samples = receivers.samples.clone();
        let mut errors = receivers.errors.clone();
        samples.sort_unstable();
        errors.sort_by(f64::total_cmp);
        let at = |len: usize, q: f64| ((len.max(1) - 1) as f64 * q).round() as usize;
        let mean = samples.iter().map(|&s| s as f64).sum::<f64>() / samples.len().max(1) as f64;
        AdaptiveReport {
            samples_min: samples.first().copied().unwrap_or(0),
            samples_median: samples.get(at(samples.len(), 0.5)).copied().unwrap_or(0),
            samples_max: samples.last().copied().unwrap_or(0),
            samples_mean: mean,
            at_cap: receivers
                .samples
                .iter()
                .filter(|&&s| s >= target.max_batches() * BATCH_SAMPLES)
                .count(),
            error_median: errors.get(at(errors.len(), 0.5)).copied().unwrap_or(0.0),
            error_p90: errors.get(at(errors.len(), 0.9)).copied().unwrap_or(0.0),
            error_max: errors.last().copied().unwrap_or(0.0),
            per_receiver: receivers.samples.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_standard_error_of_identical_batches_is_zero_and_of_spread_ones_is_their_spread() {
        // Batches 1 and 3 in one coefficient: variance 2, standard error sqrt(2 / 2) = 1.
        assert_eq!(standard_error(&[4.0], &[10.0], 2), 1.0);
        assert_eq!(standard_error(&[6.0, 3.0], &[12.0, 3.0], 3), 0.0);
    }

    #[test]
    fn batch_seeds_differ_from_each_other_and_from_the_seed() {
        let seeds: Vec<u64> = (0..100).map(|b| batch_seed(7, b)).collect();
        let mut unique = seeds.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), 100);
        assert!(!seeds.contains(&7));
    }

    #[test]
    fn a_target_casts_in_plain_frames_whatever_turns_the_inputs_carry() {
        use crate::bake::{BakeOptions, CpuBackend, NoProgress};
        use crate::receivers::Receivers;
        use crate::scene::{builtin, prepare::prepare};
        let scene = prepare(builtin::default_scene()).unwrap().0;
        let options = BakeOptions::default();
        let receivers = Receivers::vertices(&scene);
        let plain = BakeInputs::for_receivers(&scene, &receivers, &options);
        let turned =
            BakeInputs::for_receivers(&scene, &receivers, &options.clone().with_turns(true));
        assert!(turned.turns.is_some());
        let target = TargetError {
            relative: 0.05,
            max_samples: 1024,
        };
        let run = |inputs: &BakeInputs| {
            let how = (options.sampling, options.seed, Mode::Shadowed);
            adaptive_direct_pass(&CpuBackend, inputs, 100..400, how, &target, &NoProgress)
                .unwrap()
                .scalar
        };
        assert_eq!(run(&plain), run(&turned));
    }

    #[test]
    fn targets_out_of_range_are_refused() {
        for (relative, max_samples) in [(0.0, 4096), (1.5, 4096), (f64::NAN, 4096), (0.01, 8)] {
            let target = TargetError {
                relative,
                max_samples,
            };
            assert!(target.validate().is_err(), "{target:?}");
        }
    }
}
