//! The CPU reference backend. It runs the same two passes as the GPU kernels, function for
//! function: `trace_visibility` (wgsl/visibility.wgsl) sets one bit per sample that is above
//! the horizon and unblocked, `project_visibility` (wgsl/project.wgsl) sums cosine-weighted SH
//! over the set bits. Sums are f64 in sample order, so a bake is bit-for-bit repeatable however
//! rayon schedules the vertices.

use rayon::prelude::*;

use super::{DirectInputs, Mode, Progress};
use crate::ray::{Ray, RAY_T_MAX};
use crate::sampling::{tangent_frame, world_direction, DirectionFrame, Estimator};
use crate::sh::rotation::ShRotation;
use crate::sh::{coeff_count, unshadowed_transfer};

/// Vertices handed to one rayon task: large enough to amortise scheduling, small enough for
/// smooth progress and load balance on scenes with uneven occlusion.
const VERTICES_PER_TASK: usize = 64;

/// Words of visibility bits per vertex for `samples` samples.
pub fn words_per_vertex(samples: usize) -> usize {
    samples.div_ceil(32)
}

/// Sets bit s of `bits` (word s/32, bit s%32) when sample s is above the horizon of `vertex`
/// and, in shadowed and interreflected mode, nothing blocks it. Returns the number of rays cast.
pub fn trace_visibility(inputs: &DirectInputs, mode: Mode, vertex: usize, bits: &mut [u32]) -> u64 {
    let normal = inputs.normals[vertex];
    let origin = inputs.origins[vertex];
    let mut rays = 0;
    bits.fill(0);
    for (s, &sample) in inputs.samples.directions.iter().enumerate() {
        let direction = world_direction(inputs.samples.frame, normal, sample);
        if normal.dot(direction) <= 0.0 {
            continue;
        }
        if mode != Mode::Unshadowed {
            rays += 1;
            if inputs.bvh.occluded(&Ray::new(origin, direction), RAY_T_MAX) {
                continue;
            }
        }
        bits[s / 32] |= 1 << (s % 32);
    }
    rays
}

/// Whether sample `s` enters the sum: its visibility bit is set, or, when the estimator sums
/// blocked rays, it is above the horizon and its bit is clear.
fn selected(estimator: Estimator, visible: bool, cosine: f32) -> bool {
    if estimator.sums_blocked() {
        cosine > 0.0 && !visible
    } else {
        visible
    }
}

/// `sum over selected s of w(s) y_k(w_s)` with `w(s) = n.w_s` (or 1 for the cosine density),
/// per 32-sample word then added (the GPU's order), into `out` (length bands^2). Not yet
/// scaled: see [`finish_transfer`].
pub fn project_visibility(inputs: &DirectInputs, vertex: usize, bits: &[u32], out: &mut [f64]) {
    let n = coeff_count(inputs.table.bands);
    let normal = inputs.normals[vertex];
    let estimator = inputs.estimator;
    let sample_count = inputs.samples.len();
    out.fill(0.0);
    let mut partial = vec![0.0f64; n];
    for (word, &mask) in bits.iter().enumerate() {
        if mask == 0 && !estimator.sums_blocked() {
            continue;
        }
        partial.fill(0.0);
        for bit in 0..32.min(sample_count - word * 32) {
            let s = word * 32 + bit;
            let direction = inputs.samples.directions[s];
            let cosine = match inputs.samples.frame {
                DirectionFrame::World => normal.dot(direction),
                DirectionFrame::Tangent => direction.z,
            };
            if !selected(estimator, mask & (1 << bit) != 0, cosine) {
                continue;
            }
            let weight = match inputs.samples.frame {
                DirectionFrame::World => cosine as f64,
                DirectionFrame::Tangent => 1.0,
            };
            for (acc, &y) in partial.iter_mut().zip(inputs.table.row(s)) {
                *acc += weight * y as f64;
            }
        }
        for (o, p) in out.iter_mut().zip(&partial) {
            *o += p;
        }
    }
}

/// Scale from a projected sum to transfer: sample weight (4 pi / N, or pi / N for the cosine
/// density) over pi.
pub fn transfer_scale(inputs: &DirectInputs) -> f64 {
    inputs.samples.weight / std::f64::consts::PI
}

/// Turns the projected sums of one vertex into its transfer, in place: scaled, rotated from
/// the tangent frame to the world where the set lives there, and for the control variate
/// subtracted from the closed-form unoccluded transfer.
pub fn finish_transfer(inputs: &DirectInputs, vertex: usize, sums: &mut [f64]) {
    let scale = transfer_scale(inputs);
    let bands = inputs.table.bands;
    let normal = inputs.normals[vertex];
    sums.iter_mut().for_each(|t| *t *= scale);
    if inputs.samples.frame == DirectionFrame::Tangent {
        let [t, b, n] = tangent_frame(normal).map(|axis| axis.as_dvec3());
        let to_world = ShRotation::new(bands, glam::DMat3::from_cols(t, b, n));
        let world = to_world.apply(sums);
        sums.copy_from_slice(&world);
    }
    if inputs.estimator == Estimator::Blocked {
        let unoccluded = unshadowed_transfer(bands, normal.as_dvec3());
        for (t, open) in sums.iter_mut().zip(unoccluded) {
            *t = open - *t;
        }
    }
}

/// Albedo-free direct transfer of one vertex, the estimate of
/// `(1/pi) integral V(w) max(0, n.w) y_k(w) dw`, into `out`. Returns the rays cast.
pub fn vertex_direct_transfer(
    inputs: &DirectInputs,
    mode: Mode,
    vertex: usize,
    out: &mut [f64],
) -> u64 {
    let mut bits = vec![0u32; words_per_vertex(inputs.samples.len())];
    let rays = trace_visibility(inputs, mode, vertex, &mut bits);
    project_visibility(inputs, vertex, &bits, out);
    finish_transfer(inputs, vertex, out);
    rays
}

/// Direct transfer of every vertex, albedo-free, `[vertex][k]`. Returns (transfer, rays cast).
pub fn direct_transfer(
    inputs: &DirectInputs,
    mode: Mode,
    progress: &dyn Progress,
) -> (Vec<f32>, u64) {
    let n = coeff_count(inputs.table.bands);
    let mut transfer = vec![0.0f32; inputs.origins.len() * n];
    let rays: u64 = transfer
        .par_chunks_mut(n * VERTICES_PER_TASK)
        .enumerate()
        .map(|(task, chunk)| {
            let mut acc = vec![0.0f64; n];
            let mut rays = 0;
            for (i, out) in chunk.chunks_exact_mut(n).enumerate() {
                rays +=
                    vertex_direct_transfer(inputs, mode, task * VERTICES_PER_TASK + i, &mut acc);
                for (o, a) in out.iter_mut().zip(&acc) {
                    *o = *a as f32;
                }
            }
            progress.advance((chunk.len() / n) as u64);
            rays
        })
        .sum();
    (transfer, rays)
}

/// Visibility bits of every vertex, `[vertex][word]`: what the GPU's visibility pass must
/// reproduce ray for ray.
pub fn visibility_bits(inputs: &DirectInputs, mode: Mode) -> Vec<u32> {
    let words = words_per_vertex(inputs.samples.len());
    let mut bits = vec![0u32; inputs.origins.len() * words];
    bits.par_chunks_mut(words).enumerate().for_each(|(v, out)| {
        trace_visibility(inputs, mode, v, out);
    });
    bits
}
