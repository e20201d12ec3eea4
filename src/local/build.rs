//! Building the compressed direct-to-indirect operator (the meshless PCA paper, sections
//! 4.3.1 and 4.3.2): cluster the receivers, find per cluster a PCA basis of the irradiance
//! that example lights placed across the scene give it, and send every basis vector (and the
//! examples' mean) through the sparse bounces once.

use glam::Vec3;
use rayon::prelude::*;

use super::operator::{sparse_indirect_columns, CompressedOperator};
use crate::bake::bounce::GatherMatrix;
use crate::compress::eigen::top_eigenvectors;
use crate::compress::{compress_rows, CpcaOptions};
use crate::error::Result;

/// The compressed operator's shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OperatorShape {
    /// Clusters of receivers (senders and receivers alike).
    pub clusters: u32,
    /// Basis vectors of example irradiance per cluster.
    pub components: u32,
    /// A sender cluster's response in a receiver cluster is dropped when its energy is below
    /// `sparsity^2` of that receiver cluster's total (0 keeps every non-zero block).
    pub sparsity: f32,
    /// Seed of the clustering.
    pub seed: u64,
}

/// Columns sent through the bounces together (bounds the bake's memory).
const COLUMNS_PER_BATCH: usize = 64;

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
    let fits: Vec<(Vec<f32>, Vec<f32>)> = (0..clusters)
        .into_par_iter()
        .map(|c| {
            let own = &members[offsets[c] as usize..offsets[c + 1] as usize];
            cluster_basis(own, examples, n, lights, m)
        })
        .collect();
    let mut result = CompressedOperator {
        components: m,
        members,
        offsets,
        ..Default::default()
    };
    for (mean, basis) in fits {
        result.means.extend(mean);
        result.bases.extend(basis);
    }
    let all = responses(operator, &mut result);
    sparsify(&mut result, all, shape.sparsity);
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

/// One cluster's mean example irradiance and `m` orthonormal basis vectors over its
/// members (`[k][member]`): the leading eigenvectors of the examples' covariance, found from
/// their `lights x lights` Gram matrix (as many lights as a few hundred, members as many as a
/// few thousand). Directions the examples do not span are zero vectors.
fn cluster_basis(
    members: &[u32],
    examples: &[f32],
    n: usize,
    lights: usize,
    m: usize,
) -> (Vec<f32>, Vec<f32>) {
    let size = members.len();
    let rows: Vec<Vec<f64>> = (0..lights)
        .map(|l| {
            members
                .iter()
                .map(|&p| examples[l * n + p as usize] as f64)
                .collect()
        })
        .collect();
    let mut mean = vec![0.0f64; size];
    for row in &rows {
        mean.iter_mut().zip(row).for_each(|(a, x)| *a += x);
    }
    mean.iter_mut().for_each(|a| *a /= lights.max(1) as f64);
    let centred: Vec<Vec<f64>> = rows
        .into_iter()
        .map(|row| row.iter().zip(&mean).map(|(x, mu)| x - mu).collect())
        .collect();
    let mut gram = vec![0.0f64; lights * lights];
    for i in 0..lights {
        for j in 0..=i {
            let g: f64 = centred[i].iter().zip(&centred[j]).map(|(a, b)| a * b).sum();
            gram[i * lights + j] = g;
            gram[j * lights + i] = g;
        }
    }
    let wanted = m.min(lights);
    let (values, vectors) = top_eigenvectors(&gram, lights, wanted, &[]);
    let largest = values.first().copied().unwrap_or(0.0);
    let mut basis = vec![0.0f32; m * size];
    for k in 0..wanted {
        if !(values[k] > 1e-12 * largest && values[k] > 0.0) {
            continue;
        }
        let u = &vectors[k * lights..(k + 1) * lights];
        let mut b = vec![0.0f64; size];
        for (weight, row) in u.iter().zip(&centred) {
            b.iter_mut().zip(row).for_each(|(b, x)| *b += weight * x);
        }
        let norm = b.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > 0.0 {
            for (out, x) in basis[k * size..(k + 1) * size].iter_mut().zip(&b) {
                *out = (x / norm) as f32;
            }
        }
    }
    (mean.iter().map(|&x| x as f32).collect(), basis)
}

/// The operator applied to the means (column 0) and to every cluster's basis vectors
/// (column `1 + c * m + k`), as irradiance turned into direct radiance `albedo E / pi`:
/// `[receiver][3][column]` (receiver order). Sets `result.mean_response`.
fn responses(operator: &SparseOperator, result: &mut CompressedOperator) -> Vec<f32> {
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
        result.bases[start * m + k * size + (index - start)]
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

/// Keeps, per receiver cluster, the sender clusters whose responses there carry more than
/// `sparsity^2` of the cluster's response energy, and stores their responses compactly.
fn sparsify(result: &mut CompressedOperator, all: Vec<f32>, sparsity: f32) {
    let m = result.components;
    let clusters = result.clusters();
    let columns = 1 + clusters * m;
    let kept: Vec<Vec<u32>> = (0..clusters)
        .into_par_iter()
        .map(|r| {
            let mut energy = vec![0.0f64; clusters];
            for &p in result.cluster_members(r) {
                let row = &all[p as usize * 3 * columns..(p as usize + 1) * 3 * columns];
                for c in 0..3 {
                    for (s, e) in energy.iter_mut().enumerate() {
                        let start = c * columns + 1 + s * m;
                        *e += row[start..start + m]
                            .iter()
                            .map(|&x| (x as f64) * (x as f64))
                            .sum::<f64>();
                    }
                }
            }
            let total: f64 = energy.iter().sum();
            let floor = (sparsity as f64).powi(2) * total;
            (0..clusters as u32)
                .filter(|&s| energy[s as usize] > floor)
                .collect()
        })
        .collect();
    result.sender_offsets = vec![0];
    result.response_offsets = vec![0];
    for (r, senders) in kept.iter().enumerate() {
        let members = &result.members[result.offsets[r] as usize..result.offsets[r + 1] as usize];
        for &p in members {
            let row = &all[p as usize * 3 * columns..(p as usize + 1) * 3 * columns];
            for c in 0..3 {
                for &s in senders {
                    let start = c * columns + 1 + s as usize * m;
                    result.responses.extend_from_slice(&row[start..start + m]);
                }
            }
        }
        result.senders.extend(senders);
        result.sender_offsets.push(result.senders.len() as u32);
        result.response_offsets.push(result.responses.len() as u64);
    }
}
