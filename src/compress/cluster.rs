//! The CPCA iteration itself: k-means++ seeding, assignment to the cluster that reconstructs a
//! point best, and per-cluster refits of the mean and principal directions.
//!
//! Determinism: points are processed in parallel only where each result depends on one point
//! (assignment, seeding distances) or on one cluster (a fit sums its members sequentially in
//! vertex order); every sum across points runs sequentially in f64. The output is therefore the
//! same whatever the thread count.
//!
//! Why the error never rises within a run: the assignment step moves a point only to a cluster
//! that reconstructs it strictly better; a refit is the optimal mean and subspace for the
//! cluster's members (the mean minimises the residual for any subspace, the leading
//! eigenvectors of the covariance maximise the variance captured), and a refit that would
//! capture less than the cluster's previous basis keeps that basis; an emptied cluster is
//! re-seeded with the worst-reconstructed point as its mean, which removes that point's error
//! and only takes a member from a cluster of several.

use rayon::prelude::*;

use super::eigen::{dot, top_eigenvectors};
use crate::error::Result;
use crate::sampling::Pcg32;

/// The transfer vectors, one row of `dimension` floats per vertex.
#[derive(Clone, Copy)]
pub struct Points<'a> {
    pub data: &'a [f32],
    pub dimension: usize,
}

impl Points<'_> {
    pub fn len(&self) -> usize {
        self.data.len() / self.dimension
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn row(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.data[i * self.dimension..(i + 1) * self.dimension]
            .iter()
            .map(|&x| x as f64)
    }

    fn row_f64(&self, i: usize) -> Vec<f64> {
        self.row(i).collect()
    }
}

/// Vertices per parallel work item: large enough that rayon's bookkeeping stays small, fixed
/// so that the split does not depend on the thread count.
const CHUNK: usize = 256;

/// Per cluster: a mean and `components` orthonormal directions, in f64.
#[derive(Clone, Debug)]
pub struct Model {
    pub dimension: usize,
    pub components: usize,
    /// clusters x dimension.
    pub means: Vec<f64>,
    /// clusters x components x dimension.
    pub bases: Vec<f64>,
    /// clusters x components: each direction dotted with its cluster's mean, so that a
    /// coordinate is one dot product with the point, `b . x - b . mean`.
    offsets: Vec<f64>,
}

impl Model {
    pub fn new(dimension: usize, components: usize, means: Vec<f64>, bases: Vec<f64>) -> Self {
        let mut model = Model {
            dimension,
            components,
            means,
            bases,
            offsets: Vec::new(),
        };
        model.offsets = (0..model.clusters())
            .flat_map(|c| {
                let mean = model.mean(c);
                model
                    .basis(c)
                    .chunks_exact(dimension)
                    .map(move |b| dot(b, mean))
            })
            .collect::<Vec<_>>();
        model
    }

    pub fn clusters(&self) -> usize {
        self.means.len() / self.dimension
    }

    pub fn mean(&self, cluster: usize) -> &[f64] {
        &self.means[cluster * self.dimension..(cluster + 1) * self.dimension]
    }

    pub fn basis(&self, cluster: usize) -> &[f64] {
        let size = self.components * self.dimension;
        &self.bases[cluster * size..(cluster + 1) * size]
    }

    /// The point's coordinates along the cluster's directions.
    pub fn coordinates<'s>(
        &'s self,
        cluster: usize,
        x: &'s [f64],
    ) -> impl Iterator<Item = f64> + 's {
        let offsets = &self.offsets[cluster * self.components..(cluster + 1) * self.components];
        self.basis(cluster)
            .chunks_exact(self.dimension)
            .zip(offsets)
            .map(move |(b, offset)| dot(b, x) - offset)
    }

    /// Squared distance from the point to the cluster's affine subspace: its distance to the
    /// mean less what the (orthonormal) directions capture.
    pub fn residual(&self, cluster: usize, x: &[f64]) -> f64 {
        let distance: f64 = x
            .iter()
            .zip(self.mean(cluster))
            .map(|(x, m)| (x - m) * (x - m))
            .sum();
        let captured: f64 = self.coordinates(cluster, x).map(|w| w * w).sum();
        (distance - captured).max(0.0)
    }

    /// The cluster reconstructing `x` best and its residual (ties: the lower index).
    fn best_cluster(&self, x: &[f64]) -> (u32, f64) {
        let mut best = (0, f64::INFINITY);
        for cluster in 0..self.clusters() {
            let residual = self.residual(cluster, x);
            if residual < best.1 {
                best = (cluster as u32, residual);
            }
        }
        best
    }

    /// Makes `x` the cluster's mean: the point is then reconstructed exactly.
    fn recentre(&mut self, cluster: usize, x: &[f64]) {
        let n = self.dimension;
        self.means[cluster * n..(cluster + 1) * n].copy_from_slice(x);
        let offsets: Vec<f64> = self
            .basis(cluster)
            .chunks_exact(n)
            .map(|b| dot(b, x))
            .collect();
        let m = self.components;
        self.offsets[cluster * m..(cluster + 1) * m].copy_from_slice(&offsets);
    }
}

/// Where the assignment step — nearly all of a compression's time — runs.
pub trait Assigner {
    /// Every point's best cluster and residual under `model` (ties: the lower index).
    fn assign(&self, points: Points, model: &Model) -> Result<(Vec<u32>, Vec<f64>)>;
}

/// The assignment on the CPU, in f64: the reference.
pub struct CpuAssigner;

impl Assigner for CpuAssigner {
    fn assign(&self, points: Points, model: &Model) -> Result<(Vec<u32>, Vec<f64>)> {
        Ok(assign(points, model))
    }
}

/// Every point's best cluster and residual under `model`.
pub fn assign(points: Points, model: &Model) -> (Vec<u32>, Vec<f64>) {
    let mut best = vec![(0u32, 0.0f64); points.len()];
    best.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            for (i, slot) in out.iter_mut().enumerate() {
                *slot = model.best_cluster(&points.row_f64(chunk * CHUNK + i));
            }
        });
    best.into_iter().unzip()
}

/// k-means++ (Arthur & Vassilvitskii 2007): the first centre uniformly, each next one with
/// probability proportional to the squared distance to the nearest centre so far, which
/// spreads the seeds over the data. Returns the seeds' vertex indices.
pub fn kmeans_plus_plus(points: Points, clusters: usize, seed: u64) -> Vec<usize> {
    let mut rng = Pcg32::new(seed);
    let count = points.len();
    let first = ((rng.next_u32() as u64 * count as u64) >> 32) as usize;
    let mut centres = vec![first];
    let mut nearest = vec![f64::INFINITY; count];
    while centres.len() < clusters {
        let centre = points.row_f64(*centres.last().expect("the first centre is chosen above"));
        nearest
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                for (i, d) in out.iter_mut().enumerate() {
                    let to_centre: f64 = points
                        .row(chunk * CHUNK + i)
                        .zip(&centre)
                        .map(|(x, c)| (x - c) * (x - c))
                        .sum();
                    *d = d.min(to_centre);
                }
            });
        centres.push(draw_proportional(&nearest, &centres, &mut rng));
    }
    centres
}

/// An index drawn with probability proportional to `weights`; when all are zero (fewer
/// distinct points than clusters) the first index not yet chosen.
fn draw_proportional(weights: &[f64], chosen: &[usize], rng: &mut Pcg32) -> usize {
    let total: f64 = weights.iter().sum();
    if total > 0.0 {
        let target = unit_f64(rng) * total;
        let mut sum = 0.0;
        let mut last_positive = 0;
        for (i, w) in weights.iter().enumerate() {
            if *w > 0.0 {
                sum += w;
                last_positive = i;
                if sum > target {
                    return i;
                }
            }
        }
        // Rounding left the target at the very end.
        return last_positive;
    }
    (0..weights.len())
        .find(|i| !chosen.contains(i))
        .unwrap_or(0)
}

/// Uniform in [0, 1) with 48 random bits (one 24-bit float is too coarse to pick among
/// tens of thousands of weights).
fn unit_f64(rng: &mut Pcg32) -> f64 {
    let high = (rng.next_u32() >> 8) as f64;
    let low = (rng.next_u32() >> 8) as f64;
    (high * 16_777_216.0 + low) / 281_474_976_710_656.0
}

/// The mean and leading directions of every cluster's members (see [`fit_cluster`]).
pub fn fit(
    points: Points,
    assignment: &[u32],
    clusters: usize,
    components: usize,
    warm: Option<&Model>,
) -> Model {
    let members = members(assignment, clusters);
    let fits: Vec<(Vec<f64>, Vec<f64>)> = members
        .par_iter()
        .enumerate()
        .map(|(cluster, members)| {
            let warm = warm
                .filter(|w| cluster < w.clusters())
                .map(|w| w.basis(cluster))
                .unwrap_or(&[]);
            fit_cluster(points, members, components, warm)
        })
        .collect();
    let (means, bases): (Vec<_>, Vec<_>) = fits.into_iter().unzip();
    Model::new(points.dimension, components, means.concat(), bases.concat())
}

/// Each cluster's members in vertex order.
fn members(assignment: &[u32], clusters: usize) -> Vec<Vec<u32>> {
    let mut members = vec![Vec::new(); clusters];
    for (vertex, &cluster) in assignment.iter().enumerate() {
        members[cluster as usize].push(vertex as u32);
    }
    members
}

/// The members' mean and the `components` leading eigenvectors of their covariance. `warm`
/// (the cluster's previous basis, possibly with fewer rows) starts the eigen-solver; with as
/// many rows as wanted, it is kept if it captures more variance than what the solver found.
fn fit_cluster(
    points: Points,
    members: &[u32],
    components: usize,
    warm: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let n = points.dimension;
    let mean = member_mean(points, members);
    let covariance = member_covariance(points, members, &mean);
    let (values, basis) = top_eigenvectors(&covariance, n, components, warm);
    if warm.len() == basis.len() && !warm.is_empty() {
        let captured_before: f64 = warm
            .chunks_exact(n)
            .map(|b| dot(b, &mat_vec(&covariance, b)))
            .sum();
        if captured_before > values.iter().sum::<f64>() {
            return (mean, warm.to_vec());
        }
    }
    (mean, basis)
}

fn member_mean(points: Points, members: &[u32]) -> Vec<f64> {
    let mut sum = vec![0.0; points.dimension];
    for &v in members {
        sum.iter_mut()
            .zip(points.row(v as usize))
            .for_each(|(s, x)| *s += x);
    }
    let count = members.len().max(1) as f64;
    sum.iter_mut().for_each(|s| *s /= count);
    sum
}

/// `sum (x - mean)(x - mean)^T` over the members (not divided by the count: only the
/// directions matter, and the eigenvalues are then the variance captured in absolute terms).
fn member_covariance(points: Points, members: &[u32], mean: &[f64]) -> Vec<f64> {
    let n = points.dimension;
    let mut covariance = vec![0.0; n * n];
    let mut centred = vec![0.0; n];
    for &v in members {
        centred
            .iter_mut()
            .zip(points.row(v as usize).zip(mean))
            .for_each(|(c, (x, m))| *c = x - m);
        // The upper triangle only; mirrored below.
        for i in 0..n {
            let ci = centred[i];
            let row = &mut covariance[i * n + i..(i + 1) * n];
            row.iter_mut()
                .zip(&centred[i..])
                .for_each(|(a, cj)| *a += ci * cj);
        }
    }
    for i in 0..n {
        for j in 0..i {
            covariance[i * n + j] = covariance[j * n + i];
        }
    }
    covariance
}

fn mat_vec(c: &[f64], x: &[f64]) -> Vec<f64> {
    c.chunks_exact(x.len()).map(|row| dot(row, x)).collect()
}

/// Gives every empty cluster one point: the worst-reconstructed point among clusters with more
/// than one member, made that cluster's mean. There is always such a point while a cluster is
/// empty, because there are at least as many points as clusters.
pub fn fill_empty_clusters(
    points: Points,
    model: &mut Model,
    assignment: &mut [u32],
    residuals: &mut [f64],
) {
    let mut counts = vec![0usize; model.clusters()];
    assignment.iter().for_each(|&c| counts[c as usize] += 1);
    for cluster in 0..model.clusters() {
        if counts[cluster] > 0 {
            continue;
        }
        let mut worst: Option<usize> = None;
        for (v, &r) in residuals.iter().enumerate() {
            let movable = counts[assignment[v] as usize] > 1;
            if movable && worst.is_none_or(|w| r > residuals[w]) {
                worst = Some(v);
            }
        }
        let Some(v) = worst else { return };
        counts[assignment[v] as usize] -= 1;
        counts[cluster] = 1;
        assignment[v] = cluster as u32;
        residuals[v] = 0.0;
        model.recentre(cluster, &points.row_f64(v));
    }
}

/// CPCA rounds from `assignment`: fit, then reassign (and re-seed emptied clusters), for at
/// most `rounds` rounds or until the assignment stops changing. Ends on an assignment step,
/// which never raises the error, so the model and assignment returned belong together.
pub fn iterate(
    points: Points,
    mut assignment: Vec<u32>,
    (clusters, components): (usize, usize),
    rounds: u32,
    warm: Option<Model>,
    assigner: &dyn Assigner,
) -> Result<(Model, Vec<u32>)> {
    let mut model = warm;
    for _ in 0..rounds.max(1) {
        let mut fitted = fit(points, &assignment, clusters, components, model.as_ref());
        let (mut next, mut residuals) = assigner.assign(points, &fitted)?;
        fill_empty_clusters(points, &mut fitted, &mut next, &mut residuals);
        model = Some(fitted);
        let converged = next == assignment;
        assignment = next;
        if converged {
            break;
        }
    }
    Ok((model.expect("at least one round"), assignment))
}
