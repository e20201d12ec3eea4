//! Building the compressed direct-to-indirect operator (the meshless PCA paper, sections
//! 4.3.1 and 4.3.2): cluster the receivers, find per cluster a basis of the irradiance that
//! example lights placed across the scene give it (chosen for its first bounce, see
//! `cluster_fit`), and send every basis vector (and the examples' mean) through the sparse
//! bounces once.

use glam::Vec3;
use rayon::prelude::*;

use super::operator::{sparse_indirect_columns, CompressedOperator};
use crate::bake::bounce::GatherMatrix;
use crate::compress::eigen::top_eigenvectors;
use crate::compress::{compress_rows, CpcaOptions};
use crate::error::Result;

pub use crate::spec::OperatorShape;

/// Columns sent through the bounces together (bounds the bake's memory).
pub(crate) const COLUMNS_PER_BATCH: usize = 64;

/// The linear operator the compressed form approximates: the gather matrix, the albedo and
/// the bounce count.
pub struct SparseOperator<'a> {
    pub matrix: &'a GatherMatrix,
    pub albedo: &'a [Vec3],
    pub bounces: u32,
}

/// Builds the compressed operator. `features` are `[receiver][feature_dimension]` rows the
/// receivers are clustered by (position and normal); `examples` is `[light][receiver]`: the
/// irradiance each example light gives each receiver.
pub fn build_compressed(
    operator: &SparseOperator,
    features: &[f32],
    feature_dimension: usize,
    examples: &[f32],
    shape: OperatorShape,
) -> Result<CompressedOperator> {
    let n = operator.albedo.len();
    let cpca = compress_rows(
        features,
        feature_dimension,
        &CpcaOptions {
            clusters: shape.clusters.min(n as u32).max(1),
            components: 0,
            iterations: 10,
            seed: shape.seed,
        },
    )?;
    let clusters = cpca.cluster_count();
    let (members, offsets) = members_by_cluster(&cpca.assignment, clusters);
    let m = shape.components as usize;
    let lights = examples.len() / n.max(1);
    let first_bounce = FirstBounce::new(operator.matrix, operator.albedo);
    let fits: Vec<ClusterFit> = (0..clusters)
        .into_par_iter()
        .map(|c| {
            let own = &members[offsets[c] as usize..offsets[c + 1] as usize];
            cluster_fit(own, examples, n, lights, m, &first_bounce)
        })
        .collect();
    drop(first_bounce);
    let mut result = CompressedOperator {
        components: m,
        members,
        offsets,
        ..Default::default()
    };
    let mut basis = Vec::with_capacity(n * m);
    for fit in fits {
        result.means.extend(fit.mean);
        result.bases.extend(fit.projection);
        basis.extend(fit.basis);
    }
    let all = responses(operator, &basis, &mut result);
    let power = coordinate_power(&result, examples, n);
    sparsify(&mut result, all, &power, shape.sparsity);
    Ok(result)
}

/// Receivers sorted by cluster (stable) and each cluster's start.
fn members_by_cluster(assignment: &[u32], clusters: usize) -> (Vec<u32>, Vec<u32>) {
    let mut members: Vec<u32> = (0..assignment.len() as u32).collect();
    members.sort_by_key(|&p| assignment[p as usize]);
    let mut offsets = vec![0u32; clusters + 1];
    for &a in assignment {
        offsets[a as usize + 1] += 1;
    }
    for c in 0..clusters {
        offsets[c + 1] += offsets[c];
    }
    (members, offsets)
}

/// The gather matrix by columns (who receives from each receiver), with the weights of the
/// first bounce's irradiance-to-radiance map: `rho_p G[p, q] rho_q / pi` (albedo as the mean
/// of its channels), the metric the bases are chosen in.
struct FirstBounce {
    column_offsets: Vec<u32>,
    rows: Vec<u32>,
    weights: Vec<f32>,
}

impl FirstBounce {
    fn new(matrix: &GatherMatrix, albedo: &[Vec3]) -> Self {
        let n = matrix.rows();
        let grey: Vec<f32> = albedo.iter().map(|a| (a.x + a.y + a.z) / 3.0).collect();
        let mut column_offsets = vec![0u32; n + 1];
        for &q in &matrix.columns {
            column_offsets[q as usize + 1] += 1;
        }
        for q in 0..n {
            column_offsets[q + 1] += column_offsets[q];
        }
        let mut next = column_offsets.clone();
        let mut rows = vec![0u32; matrix.columns.len()];
        let mut weights = vec![0.0f32; matrix.columns.len()];
        for p in 0..n {
            let (columns, row_weights) = matrix.row(p);
            for (&q, &w) in columns.iter().zip(row_weights) {
                let slot = next[q as usize] as usize;
                next[q as usize] += 1;
                rows[slot] = p as u32;
                weights[slot] = grey[p] * w * grey[q as usize] / std::f32::consts::PI;
            }
        }
        FirstBounce {
            column_offsets,
            rows,
            weights,
        }
    }

    /// `(receiver, member index, weight)` of every entry whose sender is one of `members`,
    /// sorted by receiver.
    fn entries_from(&self, members: &[u32]) -> Vec<(u32, u32, f32)> {
        let mut entries = Vec::new();
        for (i, &q) in members.iter().enumerate() {
            let range = self.column_offsets[q as usize] as usize
                ..self.column_offsets[q as usize + 1] as usize;
            for (&p, &w) in self.rows[range.clone()].iter().zip(&self.weights[range]) {
                entries.push((p, i as u32, w));
            }
        }
        entries.sort_unstable_by_key(|e| e.0);
        entries
    }
}

/// One cluster's fit: the examples' mean over its members, the `m` projection rows
/// `[k][member]` a frame's irradiance is projected with, and the `m` basis vectors
/// `[k][member]` whose responses are stored.
struct ClusterFit {
    mean: Vec<f32>,
    projection: Vec<f32>,
    basis: Vec<f32>,
}

/// One sender cluster's fit, chosen for what the operator does with its irradiance rather
/// than for the irradiance itself. A close light leaves a sharp spot that a few basis
/// vectors of irradiance cannot follow (PCA of the examples' irradiance left 68% of a new
/// light's irradiance unexplained on the interior), but the bounce blurs it, so the error
/// that matters is the residual's response. With `F` the cluster's first bounce
/// ([`FirstBounce`]) and `X` the centred examples, the basis is `B = X V S^-1` from the
/// leading eigenpairs `(V, S^2)` of `(F X)^T (F X)`, so `U = F B` are the leading left
/// singular vectors of the examples' first-bounce responses; the projection rows are
/// `U^T F`, so a frame's coordinates give the best `m`-term approximation of its own first
/// bounce in that span (reduced-rank regression). Eigenvalues below `1e-12` of the largest
/// leave zero vectors.
fn cluster_fit(
    members: &[u32],
    examples: &[f32],
    n: usize,
    lights: usize,
    m: usize,
    first_bounce: &FirstBounce,
) -> ClusterFit {
    let size = members.len();
    let mut mean = vec![0.0f64; size];
    for l in 0..lights {
        for (a, &p) in mean.iter_mut().zip(members) {
            *a += examples[l * n + p as usize] as f64;
        }
    }
    mean.iter_mut().for_each(|a| *a /= lights.max(1) as f64);
    // Centred examples by member, `[member][light]`.
    let centred: Vec<f64> = members
        .iter()
        .zip(&mean)
        .flat_map(|(&p, mu)| (0..lights).map(move |l| examples[l * n + p as usize] as f64 - mu))
        .collect();
    let entries = first_bounce.entries_from(members);
    let gram = response_gram(&entries, &centred, lights);
    let wanted = m.min(lights);
    let (values, vectors) = top_eigenvectors(&gram, lights, wanted, &[]);
    let largest = values.first().copied().unwrap_or(0.0);
    let mut basis = vec![0.0f64; m * size];
    for k in 0..wanted {
        if !(values[k] > 1e-12 * largest && values[k] > 0.0) {
            continue;
        }
        let v = &vectors[k * lights..(k + 1) * lights];
        let scale = 1.0 / values[k].sqrt();
        for (i, out) in basis[k * size..(k + 1) * size].iter_mut().enumerate() {
            let x = &centred[i * lights..(i + 1) * lights];
            *out = scale * x.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
        }
    }
    let projection = projection_rows(&entries, &basis, size, m);
    let to_f32 = |v: &[f64]| v.iter().map(|&x| x as f32).collect();
    ClusterFit {
        mean: to_f32(&mean),
        projection: to_f32(&projection),
        basis: to_f32(&basis),
    }
}

/// `(F X)^T (F X)` for the first-bounce entries of a cluster (sorted by receiver) and its
/// centred examples `[member][light]`: one receiver's response row at a time.
fn response_gram(entries: &[(u32, u32, f32)], centred: &[f64], lights: usize) -> Vec<f64> {
    let mut gram = vec![0.0f64; lights * lights];
    let mut response = vec![0.0f64; lights];
    for run in entries.chunk_by(|a, b| a.0 == b.0) {
        response.fill(0.0);
        for &(_, i, w) in run {
            let x = &centred[i as usize * lights..(i as usize + 1) * lights];
            response
                .iter_mut()
                .zip(x)
                .for_each(|(r, x)| *r += w as f64 * x);
        }
        for i in 0..lights {
            let ri = response[i];
            if ri == 0.0 {
                continue;
            }
            let row = &mut gram[i * lights..i * lights + i + 1];
            row.iter_mut()
                .zip(&response[..=i])
                .for_each(|(g, rj)| *g += ri * rj);
        }
    }
    for i in 0..lights {
        for j in 0..i {
            gram[j * lights + i] = gram[i * lights + j];
        }
    }
    gram
}

/// `(F B)^T F`, `[k][member]`: the rows that project a frame's irradiance onto the span of
/// the basis's first-bounce responses.
fn projection_rows(entries: &[(u32, u32, f32)], basis: &[f64], size: usize, m: usize) -> Vec<f64> {
    let mut rows = vec![0.0f64; m * size];
    let mut response = vec![0.0f64; m];
    for run in entries.chunk_by(|a, b| a.0 == b.0) {
        response.fill(0.0);
        for &(_, i, w) in run {
            for (k, r) in response.iter_mut().enumerate() {
                *r += w as f64 * basis[k * size + i as usize];
            }
        }
        for &(_, i, w) in run {
            for (k, r) in response.iter().enumerate() {
                rows[k * size + i as usize] += w as f64 * r;
            }
        }
    }
    rows
}

/// The operator applied to the means (column 0) and to every cluster's basis vectors
/// (column `1 + c * m + k`), as irradiance turned into direct radiance `albedo E / pi`:
/// `[receiver][3][column]` (receiver order). Sets `result.mean_response`.
fn responses(
    operator: &SparseOperator,
    basis: &[f32],
    result: &mut CompressedOperator,
) -> Vec<f32> {
    let n = operator.albedo.len();
    let m = result.components;
    let clusters = result.clusters();
    let columns = 1 + clusters * m;
    // For each receiver: its cluster and its index among the members.
    let mut place = vec![(0usize, 0usize); n];
    for c in 0..clusters {
        let start = result.offsets[c] as usize;
        for (i, &p) in result.members[start..result.offsets[c + 1] as usize]
            .iter()
            .enumerate()
        {
            place[p as usize] = (c, start + i);
        }
    }
    let value = |p: usize, column: usize| -> f32 {
        let (c, index) = place[p];
        if column == 0 {
            return result.means[index];
        }
        let (s, k) = ((column - 1) / m.max(1), (column - 1) % m.max(1));
        if s != c {
            return 0.0;
        }
        let start = result.offsets[c] as usize;
        let size = result.offsets[c + 1] as usize - start;
        basis[start * m + k * size + (index - start)]
    };
    let mut all = vec![0.0f32; n * 3 * columns];
    for first in (0..columns).step_by(COLUMNS_PER_BATCH) {
        let width = COLUMNS_PER_BATCH.min(columns - first);
        let mut direct = vec![0.0f32; n * 3 * width];
        direct
            .par_chunks_mut(3 * width)
            .enumerate()
            .for_each(|(p, row)| {
                let rho = operator.albedo[p] / std::f32::consts::PI;
                for j in 0..width {
                    let e = value(p, first + j);
                    for c in 0..3 {
                        row[c * width + j] = rho[c] * e;
                    }
                }
            });
        let out = sparse_indirect_columns(
            operator.matrix,
            operator.albedo,
            operator.bounces,
            direct,
            width,
        );
        all.par_chunks_mut(3 * columns)
            .zip(out.par_chunks(3 * width))
            .for_each(|(row, batch)| {
                for c in 0..3 {
                    row[c * columns + first..c * columns + first + width]
                        .copy_from_slice(&batch[c * width..(c + 1) * width]);
                }
            });
    }
    result.mean_response = all
        .chunks_exact(3 * columns)
        .map(|row| Vec3::new(row[0], row[columns], row[2 * columns]))
        .collect();
    all
}

/// The mean square of each coordinate `s * m + k` over the example lights: how much each
/// term carries for lights like them.
fn coordinate_power(result: &CompressedOperator, examples: &[f32], n: usize) -> Vec<f64> {
    let mut power = vec![0.0f64; result.clusters() * result.components];
    let lights = examples.len() / n.max(1);
    for irradiance in examples.chunks_exact(n.max(1)) {
        for (p, a) in power.iter_mut().zip(result.project(irradiance)) {
            *p += (a as f64) * (a as f64) / lights as f64;
        }
    }
    power
}

/// Keeps, per receiver cluster, the terms `(s, k)` that matter there: a term's expected
/// energy is its response's energy over the cluster's members and channels times its
/// coordinate's mean square over the examples (`power`); the smallest terms are dropped as
/// long as what they carry together stays within `sparsity^2` of the cluster's total, so the
/// dropped part's RMS is at most `sparsity` of the kept part's, for lights like the examples.
/// Stores the kept terms' responses compactly.
fn sparsify(result: &mut CompressedOperator, all: Vec<f32>, power: &[f64], sparsity: f32) {
    let terms = power.len();
    let columns = 1 + terms;
    let kept: Vec<Vec<u32>> = (0..result.clusters())
        .into_par_iter()
        .map(|r| {
            let mut energy = vec![0.0f64; terms];
            for &p in result.cluster_members(r) {
                let row = &all[p as usize * 3 * columns..(p as usize + 1) * 3 * columns];
                for c in 0..3 {
                    let responses = &row[c * columns + 1..(c + 1) * columns];
                    for (e, &x) in energy.iter_mut().zip(responses) {
                        *e += (x as f64) * (x as f64);
                    }
                }
            }
            energy.iter_mut().zip(power).for_each(|(e, p)| *e *= p);
            let budget = (sparsity as f64).powi(2) * energy.iter().sum::<f64>();
            let mut order: Vec<usize> = (0..terms).collect();
            order.sort_by(|&a, &b| energy[a].total_cmp(&energy[b]));
            let mut dropped = 0.0;
            let mut keep = vec![true; terms];
            for t in order {
                if dropped + energy[t] > budget {
                    break;
                }
                dropped += energy[t];
                keep[t] = false;
            }
            (0..terms as u32).filter(|&t| keep[t as usize]).collect()
        })
        .collect();
    result.term_offsets = vec![0];
    result.response_offsets = vec![0];
    for (r, own) in kept.iter().enumerate() {
        let members = &result.members[result.offsets[r] as usize..result.offsets[r + 1] as usize];
        for &p in members {
            let row = &all[p as usize * 3 * columns..(p as usize + 1) * 3 * columns];
            for c in 0..3 {
                let responses = &row[c * columns + 1..(c + 1) * columns];
                result
                    .responses
                    .extend(own.iter().map(|&t| responses[t as usize]));
            }
        }
        result.terms.extend(own);
        result.term_offsets.push(result.terms.len() as u32);
        result.response_offsets.push(result.responses.len() as u64);
    }
}
