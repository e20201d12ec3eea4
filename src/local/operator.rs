//! The direct-to-indirect operator: from the direct radiance a frame's lights leave at the
//! receivers to the indirect radiance that reaches them after 1 to B bounces,
//! `I = (T + T^2 + ... + T^B) D`, `T = diag(albedo) G`, with `G` the bake's gather matrix
//! (row p: what p receives from the surfaces its rays hit; `bake::bounce`).
//!
//! Two forms, as the meshless PCA paper has them:
//!
//! - **sparse**: B sparse matrix products a frame (exact for the gather matrix);
//! - **compressed**: receivers in clusters; per cluster the mean of example irradiance
//!   (lights placed across the scene), basis vectors `b_sk` spanned by the centred examples
//!   and projection rows `w_sk` (`build.rs` chooses both for the first bounce of the
//!   examples, not for their irradiance); the operator applied once at bake time to every
//!   basis vector and to the means. A frame projects its irradiance with each cluster's rows
//!   (`a_sk = w_sk . (E_s - mu_s)`; the file's `bases`) and sums the stored responses,
//!   `I = K mu + sum_s sum_k a_sk K b_sk`, keeping in each receiver cluster only the terms
//!   `(s, k)` that are not negligible there.

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::bounce::{apply_cpu, GatherMatrix};

/// `I = (T + ... + T^B) D` on the CPU, RGB per receiver.
pub fn sparse_indirect(
    matrix: &GatherMatrix,
    albedo: &[Vec3],
    bounces: u32,
    direct: &[Vec3],
) -> Vec<Vec3> {
    let mut previous: Vec<f32> = direct.iter().flat_map(|d| d.to_array()).collect();
    let mut total = vec![0.0f32; previous.len()];
    for _ in 0..bounces {
        previous = apply_cpu(matrix, &previous, albedo, 1);
        total.iter_mut().zip(&previous).for_each(|(t, b)| *t += b);
    }
    total
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect()
}

/// `(T + ... + T^B)` applied to `columns` RGB vectors at once, laid out `[receiver][3][columns]`
/// (the layout `apply_cpu` bounces transfer in): the bake's batched responses.
pub fn sparse_indirect_columns(
    matrix: &GatherMatrix,
    albedo: &[Vec3],
    bounces: u32,
    direct: Vec<f32>,
    columns: usize,
) -> Vec<f32> {
    let mut previous = direct;
    let mut total = vec![0.0f32; previous.len()];
    for _ in 0..bounces {
        previous = apply_cpu(matrix, &previous, albedo, columns);
        total.iter_mut().zip(&previous).for_each(|(t, b)| *t += b);
    }
    total
}

/// The compressed operator (see the module's comment).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CompressedOperator {
    /// Basis vectors per cluster (zero vectors where a cluster's examples span fewer).
    pub components: usize,
    /// Receivers ordered by cluster; cluster c holds `members[offsets[c]..offsets[c + 1]]`.
    pub members: Vec<u32>,
    pub offsets: Vec<u32>,
    /// The examples' mean irradiance, per member (in `members` order).
    pub means: Vec<f32>,
    /// Projection rows per cluster `[component][member]`, clusters one after another
    /// (cluster c starts at `offsets[c] * components`); not orthonormal.
    pub bases: Vec<f32>,
    /// `K mu` per receiver (receiver order), RGB.
    pub mean_response: Vec<Vec3>,
    /// Per receiver cluster r, the terms kept: indices `s * components + k` into the
    /// coordinates, `terms[term_offsets[r]..term_offsets[r + 1]]`, ascending.
    pub terms: Vec<u32>,
    pub term_offsets: Vec<u32>,
    /// Per member of each receiver cluster (in `members` order), `[channel][kept term]`;
    /// member i of cluster r starts at `response_offsets[r] + i * 3 * kept_r`.
    pub responses: Vec<f32>,
    pub response_offsets: Vec<u64>,
}

impl CompressedOperator {
    pub fn clusters(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    pub(super) fn cluster_members(&self, c: usize) -> &[u32] {
        &self.members[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }

    /// The irradiance's coordinates in every cluster's basis, `[cluster][k]`.
    pub fn project(&self, irradiance: &[f32]) -> Vec<f32> {
        let m = self.components;
        (0..self.clusters())
            .into_par_iter()
            .flat_map_iter(|c| {
                let start = self.offsets[c] as usize;
                let members = self.cluster_members(c);
                let basis = &self.bases[start * m..(start + members.len()) * m];
                let centred: Vec<f32> = members
                    .iter()
                    .zip(&self.means[start..start + members.len()])
                    .map(|(&p, mean)| irradiance[p as usize] - mean)
                    .collect();
                (0..m).map(move |k| {
                    let row = &basis[k * members.len()..(k + 1) * members.len()];
                    row.iter().zip(&centred).map(|(b, x)| b * x).sum::<f32>()
                })
            })
            .collect()
    }

    /// Indirect radiance per receiver (receiver order) for the irradiance `irradiance`.
    pub fn indirect(&self, irradiance: &[f32]) -> Vec<Vec3> {
        let coordinates = self.project(irradiance);
        let mut out = self.mean_response.clone();
        let per_cluster: Vec<Vec<(u32, Vec3)>> = (0..self.clusters())
            .into_par_iter()
            .map(|r| {
                let terms =
                    &self.terms[self.term_offsets[r] as usize..self.term_offsets[r + 1] as usize];
                let gathered: Vec<f32> = terms.iter().map(|&t| coordinates[t as usize]).collect();
                let width = gathered.len();
                let base = self.response_offsets[r] as usize;
                self.cluster_members(r)
                    .iter()
                    .enumerate()
                    .map(|(i, &p)| {
                        let row = &self.responses[base + i * 3 * width..base + (i + 1) * 3 * width];
                        let channel = |c: usize| dot(&row[c * width..(c + 1) * width], &gathered);
                        (p, Vec3::new(channel(0), channel(1), channel(2)))
                    })
                    .collect()
            })
            .collect();
        for (p, add) in per_cluster.into_iter().flatten() {
            out[p as usize] += add;
        }
        out
    }

    /// Stored floats: means, bases, mean responses, responses (plus the small index arrays).
    pub fn byte_size(&self) -> usize {
        4 * (self.means.len()
            + self.bases.len()
            + 3 * self.mean_response.len()
            + self.responses.len()
            + self.members.len()
            + self.offsets.len()
            + self.terms.len()
            + self.term_offsets.len())
            + 8 * self.response_offsets.len()
    }
}

/// A dot product in eight independent lanes (so the compiler vectorises it).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let (a_chunks, b_chunks) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = a_chunks
        .remainder()
        .iter()
        .zip(b_chunks.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a_chunks.zip(b_chunks) {
        for i in 0..8 {
            lanes[i] += x[i] * y[i];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// RMS of the difference over the RMS of the reference, over receivers and channels.
pub fn relative_rms(reference: &[Vec3], other: &[Vec3]) -> f64 {
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for (r, o) in reference.iter().zip(other) {
        diff += (*r - *o).length_squared() as f64;
        norm += r.length_squared() as f64;
    }
    if norm == 0.0 {
        diff.sqrt()
    } else {
        (diff / norm).sqrt()
    }
}
