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
use super::rows::{for_each_block, read_row, Points, Rows};
use crate::error::Result;
use crate::packet::{on_widest_unit, Kernel};
use crate::sampling::Pcg32;

/// Vertices per parallel work item: large enough that rayon's bookkeeping stays small, fixed
/// so that the split does not depend on the thread count.
const CHUNK: usize = 256;

/// Points the assignment scores together (see [`Model::best_clusters_of_lanes`]): four f64
/// fill an AVX2 register, and four independent chains hide an addition's latency.
const LANES: usize = 4;

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

    /// [`Model::best_cluster`] of [`LANES`] points at once, `xs[i][lane]` coordinate i of
    /// point `lane`: each point's residuals are the same sums in the same order as its own
    /// (so the same bits), interleaved so that the points' chains of additions overlap and
    /// share vector registers where one chain would wait on each addition.
    #[inline]
    fn best_clusters_of_lanes(&self, xs: &[[f64; LANES]]) -> [(u32, f64); LANES] {
        let mut best = [(0, f64::INFINITY); LANES];
        for cluster in 0..self.clusters() {
            let residuals = self.residuals_of_lanes(cluster, xs);
            for (best, residual) in best.iter_mut().zip(residuals) {
                if residual < best.1 {
                    *best = (cluster as u32, residual);
                }
            }
        }
        best
    }

    /// [`Model::residual`] of [`LANES`] points (see [`Model::best_clusters_of_lanes`]).
    #[inline]
    fn residuals_of_lanes(&self, cluster: usize, xs: &[[f64; LANES]]) -> [f64; LANES] {
        let mut distance = [0.0f64; LANES];
        for (x, m) in xs.iter().zip(self.mean(cluster)) {
            for lane in 0..LANES {
                let d = x[lane] - m;
                distance[lane] += d * d;
            }
        }
        let offsets = &self.offsets[cluster * self.components..(cluster + 1) * self.components];
        let mut captured = [0.0f64; LANES];
        for (b, offset) in self
            .basis(cluster)
            .chunks_exact(self.dimension)
            .zip(offsets)
        {
            let dots = dot_lanes(b, xs);
            for lane in 0..LANES {
                let w = dots[lane] - offset;
                captured[lane] += w * w;
            }
        }
        std::array::from_fn(|lane| (distance[lane] - captured[lane]).max(0.0))
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
    /// Every row's best cluster and residual under `model` (ties: the lower index).
    fn assign(&self, rows: &mut dyn Rows, model: &Model) -> Result<(Vec<u32>, Vec<f64>)>;
}

/// The assignment on the CPU, in f64: the reference.
pub struct CpuAssigner;

impl Assigner for CpuAssigner {
    fn assign(&self, rows: &mut dyn Rows, model: &Model) -> Result<(Vec<u32>, Vec<f64>)> {
        let mut clusters = Vec::with_capacity(rows.len());
        let mut residuals = Vec::with_capacity(rows.len());
        for_each_block(rows, |_, block| {
            let (c, r) = assign(block, model);
            clusters.extend(c);
            residuals.extend(r);
            Ok(())
        })?;
        Ok((clusters, residuals))
    }
}

/// Every point's best cluster and residual under `model`: [`LANES`] points at a time, those
/// left over one by one (the same bits either way).
pub fn assign(points: Points, model: &Model) -> (Vec<u32>, Vec<f64>) {
    let mut best = vec![(0u32, 0.0f64); points.len()];
    best.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let first = chunk * CHUNK;
            on_widest_unit(AssignChunk {
                points,
                model,
                first,
                out,
            });
        });
    best.into_iter().unzip()
}

/// The points `first..` of one chunk assigned into `out`, compiled for the widest vector unit
/// (the same bits on each: no copy fuses a product and a sum).
struct AssignChunk<'a> {
    points: Points<'a>,
    model: &'a Model,
    first: usize,
    out: &'a mut [(u32, f64)],
}

impl Kernel for AssignChunk<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let AssignChunk {
            points,
            model,
            first,
            out,
        } = self;
        let done = out.len() - out.len() % LANES;
        let mut xs = vec![[0.0f64; LANES]; points.dimension];
        for (group, slots) in out.chunks_exact_mut(LANES).enumerate() {
            for lane in 0..LANES {
                let row = points.row(first + group * LANES + lane);
                xs.iter_mut()
                    .zip(row)
                    .for_each(|(x, value)| x[lane] = value);
            }
            slots.copy_from_slice(&model.best_clusters_of_lanes(&xs));
        }
        for (i, slot) in out.iter_mut().enumerate().skip(done) {
            *slot = model.best_cluster(&points.row_f64(first + i));
        }
    }
}

/// [`dot`] of `b` with each of [`LANES`] points (`xs[i][lane]`), each the same four running
/// sums and tail, in the same order, as [`dot`] gives it.
#[inline]
fn dot_lanes(b: &[f64], xs: &[[f64; LANES]]) -> [f64; LANES] {
    let mut sums = [[0.0f64; LANES]; 4];
    let (b4, x4) = (b.chunks_exact(4), xs.chunks_exact(4));
    let tail: [f64; LANES] = std::array::from_fn(|lane| {
        let remainder = b4.remainder().iter().zip(x4.remainder());
        remainder.map(|(b, x)| b * x[lane]).sum()
    });
    for (b, x) in b4.zip(x4) {
        for k in 0..4 {
            for lane in 0..LANES {
                sums[k][lane] += b[k] * x[k][lane];
            }
        }
    }
    std::array::from_fn(|lane| {
        (sums[0][lane] + sums[1][lane]) + (sums[2][lane] + sums[3][lane]) + tail[lane]
    })
}

/// k-means++ (Arthur & Vassilvitskii 2007): the first centre uniformly, each next one with
/// probability proportional to the squared distance to the nearest centre so far, which
/// spreads the seeds over the data. Returns the seeds' vertex indices.
pub fn kmeans_plus_plus(rows: &mut dyn Rows, clusters: usize, seed: u64) -> Result<Vec<usize>> {
    let mut rng = Pcg32::new(seed);
    let count = rows.len();
    let first = ((rng.next_u32() as u64 * count as u64) >> 32) as usize;
    let mut centres = vec![first];
    let mut nearest = vec![f64::INFINITY; count];
    while centres.len() < clusters {
        let last = *centres.last().expect("the first centre is chosen above");
        let centre = read_row(rows, last)?;
        for_each_block(rows, |first, block| {
            nearest[first..first + block.len()]
                .par_chunks_mut(CHUNK)
                .enumerate()
                .for_each(|(chunk, out)| {
                    for (i, d) in out.iter_mut().enumerate() {
                        let to_centre: f64 = block
                            .row(chunk * CHUNK + i)
                            .zip(&centre)
                            .map(|(x, c)| (x - c) * (x - c))
                            .sum();
                        *d = d.min(to_centre);
                    }
                });
            Ok(())
        })?;
        centres.push(draw_proportional(&nearest, &centres, &mut rng));
    }
    Ok(centres)
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

/// Covariances a fit accumulates at once, in bytes, beyond one per thread: a cluster's is
/// `dimension^2` f64 (4.7 MB at 16 bands RGB), so clusters of long rows are fitted a group
/// at a time, each group a pass over the rows.
const COVARIANCE_BYTES: usize = 32 << 20;

/// The clusters one pass of `fit` accumulates the covariances of, for rows of `dimension`.
pub fn covariance_group(dimension: usize) -> usize {
    let one = (dimension * dimension * 8).max(1);
    (COVARIANCE_BYTES / one).max(rayon::current_num_threads())
}

/// The mean and leading directions of every cluster's members (see [`fit_cluster`]): one pass
/// over the rows for the means, then one for each [`covariance_group`] of clusters.
pub fn fit(
    rows: &mut dyn Rows,
    assignment: &[u32],
    (clusters, components): (usize, usize),
    warm: Option<&Model>,
) -> Result<Model> {
    let group = covariance_group(rows.dimension());
    fit_in_groups(rows, assignment, (clusters, components), warm, group)
}

/// [`fit`], the covariances of `group` clusters accumulated in each pass over the rows.
pub(super) fn fit_in_groups(
    rows: &mut dyn Rows,
    assignment: &[u32],
    (clusters, components): (usize, usize),
    warm: Option<&Model>,
    group: usize,
) -> Result<Model> {
    let n = rows.dimension();
    let members = members(assignment, clusters);
    let means = member_means(rows, &members)?;
    let mut bases = Vec::with_capacity(clusters);
    for first in (0..clusters).step_by(group.max(1)) {
        let in_group = first..(first + group).min(clusters);
        let covariances =
            member_covariances(rows, &members[in_group.clone()], &means[in_group.clone()])?;
        let fitted: Vec<Vec<f64>> = covariances
            .par_iter()
            .zip(in_group)
            .map(|(covariance, cluster)| {
                let warm = warm
                    .filter(|w| cluster < w.clusters())
                    .map(|w| w.basis(cluster))
                    .unwrap_or(&[]);
                fit_cluster(covariance, n, components, warm)
            })
            .collect();
        bases.extend(fitted);
    }
    Ok(Model::new(n, components, means.concat(), bases.concat()))
}

/// Each cluster's members in vertex order.
fn members(assignment: &[u32], clusters: usize) -> Vec<Vec<u32>> {
    let mut members = vec![Vec::new(); clusters];
    for (vertex, &cluster) in assignment.iter().enumerate() {
        members[cluster as usize].push(vertex as u32);
    }
    members
}

/// The members of one cluster that lie in the block ending before row `end`, from `next` on
/// (which moves past them): the blocks come in order, so each cluster's members are visited in
/// vertex order.
fn members_before<'m>(members: &'m [u32], next: &mut usize, end: usize) -> &'m [u32] {
    let start = *next;
    while *next < members.len() && (members[*next] as usize) < end {
        *next += 1;
    }
    &members[start..*next]
}

/// The leading `components` eigenvectors of a cluster's `covariance` (`n` x `n`). `warm` (the
/// cluster's previous basis, possibly with fewer rows) starts the eigen-solver; with as many
/// rows as wanted, it is kept if it captures more variance than what the solver found.
fn fit_cluster(covariance: &[f64], n: usize, components: usize, warm: &[f64]) -> Vec<f64> {
    let (values, basis) = top_eigenvectors(covariance, n, components, warm);
    if warm.len() == basis.len() && !warm.is_empty() {
        let captured_before: f64 = warm
            .chunks_exact(n)
            .map(|b| dot(b, &mat_vec(covariance, b)))
            .sum();
        if captured_before > values.iter().sum::<f64>() {
            return warm.to_vec();
        }
    }
    basis
}

/// Every cluster's mean: its members summed in vertex order, over their count.
fn member_means(rows: &mut dyn Rows, members: &[Vec<u32>]) -> Result<Vec<Vec<f64>>> {
    let mut sums = vec![vec![0.0; rows.dimension()]; members.len()];
    let mut next = vec![0usize; members.len()];
    for_each_block(rows, |first, block| {
        let end = first + block.len();
        sums.par_iter_mut()
            .zip(&mut next)
            .zip(members)
            .for_each(|((sum, next), members)| {
                for &v in members_before(members, next, end) {
                    sum.iter_mut()
                        .zip(block.row(v as usize - first))
                        .for_each(|(s, x)| *s += x);
                }
            });
        Ok(())
    })?;
    for (sum, members) in sums.iter_mut().zip(members) {
        let count = members.len().max(1) as f64;
        sum.iter_mut().for_each(|s| *s /= count);
    }
    Ok(sums)
}

/// `sum (x - mean)(x - mean)^T` over each cluster's members (not divided by the count: only
/// the directions matter, and the eigenvalues are then the variance captured in absolute
/// terms).
fn member_covariances(
    rows: &mut dyn Rows,
    members: &[Vec<u32>],
    means: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>> {
    let n = rows.dimension();
    let mut covariances = vec![vec![0.0; n * n]; members.len()];
    let mut next = vec![0usize; members.len()];
    for_each_block(rows, |first, block| {
        let end = first + block.len();
        covariances
            .par_iter_mut()
            .zip(&mut next)
            .zip(members.par_iter().zip(means.par_iter()))
            .for_each(|((covariance, next), (members, mean))| {
                let mut centred = vec![0.0; n];
                for &v in members_before(members, next, end) {
                    centred
                        .iter_mut()
                        .zip(block.row(v as usize - first).zip(mean))
                        .for_each(|(c, (x, m))| *c = x - m);
                    add_upper_outer(covariance, &centred);
                }
            });
        Ok(())
    })?;
    covariances.iter_mut().for_each(|c| mirror_upper(c, n));
    Ok(covariances)
}

/// Adds `x x^T` to the upper triangle of `covariance`.
fn add_upper_outer(covariance: &mut [f64], x: &[f64]) {
    let n = x.len();
    for i in 0..n {
        let xi = x[i];
        let row = &mut covariance[i * n + i..(i + 1) * n];
        row.iter_mut()
            .zip(&x[i..])
            .for_each(|(a, xj)| *a += xi * xj);
    }
}

/// Copies the upper triangle below the diagonal.
fn mirror_upper(covariance: &mut [f64], n: usize) {
    for i in 0..n {
        for j in 0..i {
            covariance[i * n + j] = covariance[j * n + i];
        }
    }
}

fn mat_vec(c: &[f64], x: &[f64]) -> Vec<f64> {
    c.chunks_exact(x.len()).map(|row| dot(row, x)).collect()
}

/// Gives every empty cluster one point: the worst-reconstructed point among clusters with more
/// than one member, made that cluster's mean. There is always such a point while a cluster is
/// empty, because there are at least as many points as clusters.
pub fn fill_empty_clusters(
    rows: &mut dyn Rows,
    model: &mut Model,
    assignment: &mut [u32],
    residuals: &mut [f64],
) -> Result<()> {
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
        let Some(v) = worst else { return Ok(()) };
        counts[assignment[v] as usize] -= 1;
        counts[cluster] = 1;
        assignment[v] = cluster as u32;
        residuals[v] = 0.0;
        model.recentre(cluster, &read_row(rows, v)?);
    }
    Ok(())
}

/// CPCA rounds from `assignment`: fit, then reassign (and re-seed emptied clusters), for at
/// most `rounds` rounds or until the assignment stops changing. Ends on an assignment step,
/// which never raises the error, so the model and assignment returned belong together.
///
/// `each_round` is told how many rounds are done after each one (and `rounds` once converged).
pub fn iterate(
    rows: &mut dyn Rows,
    mut assignment: Vec<u32>,
    (clusters, components): (usize, usize),
    rounds: u32,
    warm: Option<Model>,
    (assigner, each_round): (&dyn Assigner, &mut dyn FnMut(u32)),
) -> Result<(Model, Vec<u32>)> {
    let mut model = warm;
    for round in 1..=rounds.max(1) {
        let mut fitted = fit(rows, &assignment, (clusters, components), model.as_ref())?;
        let (mut next, mut residuals) = assigner.assign(rows, &fitted)?;
        fill_empty_clusters(rows, &mut fitted, &mut next, &mut residuals)?;
        model = Some(fitted);
        let converged = next == assignment;
        assignment = next;
        each_round(if converged { rounds } else { round });
        if converged {
            break;
        }
    }
    Ok((model.expect("at least one round"), assignment))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points scored four at a time, compiled for this machine's widest vector unit, get the
    /// bits each gets alone on the baseline unit: on rows of a length with a tail after the
    /// dot products' fours (7), a count that leaves points over after the fours and spans
    /// chunks, and a model with and without directions.
    #[test]
    fn points_scored_in_lanes_get_the_bits_each_gets_alone() {
        let mut rng = Pcg32::new(17);
        let mut uniform =
            |n: usize| -> Vec<f64> { (0..n).map(|_| 2.0 * rng.next_f32() as f64 - 1.0).collect() };
        let (dimension, clusters) = (7, 5);
        let count = 2 * CHUNK + 3 * LANES + 2;
        let data: Vec<f32> = uniform(count * dimension)
            .iter()
            .map(|&x| x as f32)
            .collect();
        let points = Points {
            data: &data,
            dimension,
        };
        for components in [0, 1, 3] {
            let means = uniform(clusters * dimension);
            let bases = uniform(clusters * components * dimension);
            let model = Model::new(dimension, components, means, bases);
            let (chosen, residuals) = assign(points, &model);
            for v in 0..count {
                let (alone, residual) = model.best_cluster(&points.row_f64(v));
                assert_eq!(chosen[v], alone, "point {v}, {components} directions");
                assert_eq!(residuals[v].to_bits(), residual.to_bits(), "point {v}");
            }
        }
    }
}
