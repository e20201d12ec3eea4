//! Clustered principal component analysis (CPCA) of per-vertex transfer: Sloan, Hall, Hart
//! and Snyder 2003, "Clustered Principal Components for Precomputed Radiance Transfer" (what
//! Direct3D's PRT engine calls `NumClusters` and `NumPCA`).
//!
//! Each vertex's transfer vector (all channels, `channels * bands^2` floats) is approximated
//! as its cluster's mean plus a weighted sum of the cluster's few orthonormal directions:
//! `t_v ~ mean[c] + sum_j w[v][j] basis[c][j]`. Relighting then dots the light into each
//! cluster's mean and directions once, and each vertex costs `components` multiply-adds per
//! channel instead of `bands^2`.
//!
//! Measured (`tests.rs`, `dragon_compression_time_size_and_error`, 2 shared cores): the dragon
//! (22,982 vertices, 4 bands RGB, 4.4 MB as float32) at 64 clusters x 8 components takes 3.0 s
//! and 0.89 MB (4.9x smaller) with a coefficient error of 2.9% and a relit error of 1.8%;
//! 64 x 4: 2.0 s, 9.3x, 7.8% / 5.0%. Its grey albedo makes the three channels proportional,
//! so 16 components reconstruct it exactly. At 768 floats per vertex (16 bands RGB) a round
//! takes about 0.25 ms per vertex at 64 x 8.
//!
//! - `cluster.rs` runs the iteration (k-means++ seeding, assignment, refits);
//! - `eigen.rs` finds a cluster's principal directions (Jacobi, subspace iteration);
//! - `rows.rs` is where the rows come from: the transfer in memory, or the scratch file of a
//!   bake in bounded memory, read a block at a time with the same bits.

mod cluster;
pub mod eigen;
pub mod gpu;
mod rows;

use rayon::prelude::*;

use crate::bake::Transfer;
use crate::error::{Error, Result};
use crate::light::ShLight;
use crate::precision::Precision;
pub use cluster::{covariance_group, Assigner, CpuAssigner, Model};
pub use rows::{for_each_block, Points, Rows};

/// How hard to compress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CpcaOptions {
    /// Clusters (at least 1, at most the vertex count).
    pub clusters: u32,
    /// Principal directions per cluster (0: the cluster mean alone, vector quantisation; at
    /// most `channels * bands^2`, which reconstructs exactly).
    pub components: u32,
    /// Most fit-and-reassign rounds; fewer when the assignment stops changing.
    pub iterations: u32,
    /// Seed of the k-means++ seeding: the same seed and inputs give the same bits.
    pub seed: u64,
}

impl Default for CpcaOptions {
    /// Sloan et al.'s typical operating point for 5-band transfer is 8 directions in a few
    /// hundred clusters; 64 clusters suits meshes of tens of thousands of vertices.
    fn default() -> Self {
        CpcaOptions {
            clusters: 64,
            components: 8,
            iterations: 20,
            seed: 1,
        }
    }
}

/// Compressed transfer.
#[derive(Clone, Debug, PartialEq)]
pub struct Cpca {
    pub bands: u32,
    pub channels: u32,
    /// Floats per vertex: `channels * bands^2`, channel-major as in [`Transfer`].
    pub dimension: usize,
    pub components: usize,
    /// clusters x dimension.
    pub means: Vec<f32>,
    /// clusters x components x dimension; a cluster's rows are orthonormal.
    pub bases: Vec<f32>,
    /// Each vertex's cluster.
    pub assignment: Vec<u32>,
    /// vertices x components: each vertex's coordinates along its cluster's directions.
    pub weights: Vec<f32>,
}

/// Compresses `transfer`: k-means++ seeding from `options.seed`, then CPCA rounds.
pub fn compress(transfer: &Transfer, options: &CpcaOptions) -> Result<Cpca> {
    compress_with(transfer, options, &CpuAssigner)
}

/// [`compress`] with the assignment steps on `assigner` (a GPU's: [`gpu::GpuAssigner`]). The
/// same assigner, seed and inputs give the same bits; a GPU assigns in f32 where the CPU uses
/// f64, so near-ties may go the other way and the two results differ slightly.
pub fn compress_with(
    transfer: &Transfer,
    options: &CpcaOptions,
    assigner: &dyn Assigner,
) -> Result<Cpca> {
    let shape = (transfer.bands(), transfer.channels());
    compress_from(&mut Points::of_transfer(transfer), shape, options, assigner)
}

/// [`compress_with`] of transfer rows of `(bands, channels)` read from `rows` (a scratch file
/// of a bake in bounded memory, a block at a time): the bits [`compress_with`] gives for the
/// same rows in memory.
pub fn compress_from(
    rows: &mut dyn Rows,
    shape: (u32, u32),
    options: &CpcaOptions,
    assigner: &dyn Assigner,
) -> Result<Cpca> {
    compress_watched(rows, shape, options, (assigner, &mut |_| {}))
}

/// The steps [`compress_watched`] reports: the seeding, then each round.
pub fn compress_steps(options: &CpcaOptions) -> u64 {
    options.iterations.max(1) as u64 + 1
}

/// [`compress_from`], telling `watch` how many of its [`compress_steps`] are done after each
/// (all of them once the assignment stops changing).
pub fn compress_watched(
    rows: &mut dyn Rows,
    (bands, channels): (u32, u32),
    options: &CpcaOptions,
    (assigner, watch): (&dyn Assigner, &mut dyn FnMut(u64)),
) -> Result<Cpca> {
    check_rows(rows)?;
    check_options(options, rows.dimension(), rows.len())?;
    let (model, assignment) = compress_points(rows, options, (assigner, watch))?;
    finish((bands, channels), rows, &model, assignment)
}

/// Compresses any rows of `dimension` floats (hemispherical depth maps, clustering
/// features), as [`compress`] compresses transfer vectors. The result's `bands` and
/// `channels` are 0: its rows are not SH transfer, so it has no [`Cpca::relight`] (which
/// refuses it) and [`Cpca::reconstruct`] gives the rows back flat.
pub fn compress_rows(rows: &[f32], dimension: usize, options: &CpcaOptions) -> Result<Cpca> {
    if dimension == 0 || !rows.len().is_multiple_of(dimension) {
        return Err(Error::Options(format!(
            "compress: {} floats are not rows of {dimension}",
            rows.len()
        )));
    }
    if let Some(i) = rows.iter().position(|x| !x.is_finite()) {
        return Err(Error::Options(format!(
            "compress: value {} of row {} is {}",
            i % dimension,
            i / dimension,
            rows[i]
        )));
    }
    let mut points = Points {
        data: rows,
        dimension,
    };
    compress_from(&mut points, (0, 0), options, &CpuAssigner)
}

/// k-means++ seeding from `options.seed`, then CPCA rounds: the model and the assignment.
fn compress_points(
    rows: &mut dyn Rows,
    options: &CpcaOptions,
    (assigner, watch): (&dyn Assigner, &mut dyn FnMut(u64)),
) -> Result<(Model, Vec<u32>)> {
    let clusters = options.clusters as usize;
    let seeds = cluster::kmeans_plus_plus(rows, clusters, options.seed)?;
    let mut seed_means = Vec::with_capacity(clusters * rows.dimension());
    for &v in &seeds {
        seed_means.extend(rows::read_row(rows, v)?);
    }
    let mut seeding = Model::new(rows.dimension(), 0, seed_means, Vec::new());
    let (mut assignment, mut residuals) = assigner.assign(rows, &seeding)?;
    cluster::fill_empty_clusters(rows, &mut seeding, &mut assignment, &mut residuals)?;
    watch(1);
    cluster::iterate(
        rows,
        assignment,
        (clusters, options.components as usize),
        options.iterations,
        None,
        (assigner, &mut |round| watch(round.max(1) as u64 + 1)),
    )
}

/// Continues CPCA rounds from an earlier result `start` (its assignment and bases), with
/// `options`' cluster and component counts (`options.seed` is not used).
///
/// With at least `start`'s clusters and components, the result reconstructs `transfer` at
/// least as well as `start` does (up to the eigen-solver's tolerance): the first refit is
/// optimal for `start`'s assignment, every round after it lowers the error or keeps it, and
/// new clusters begin empty and are seeded with the worst-reconstructed vertex. Growing a
/// solution this way gives errors that fall monotonically, which separate [`compress`] runs
/// (local optima from different seedings) do not promise.
pub fn refine(transfer: &Transfer, start: &Cpca, options: &CpcaOptions) -> Result<Cpca> {
    check_transfer(transfer)?;
    let mut points = Points::of_transfer(transfer);
    check_options(options, points.dimension, transfer.vertex_count())?;
    check_start(transfer, start, options)?;
    let warm = Model::new(
        start.dimension,
        start.components,
        widen(&start.means),
        widen(&start.bases),
    );
    let (model, assignment) = cluster::iterate(
        &mut points,
        start.assignment.clone(),
        (options.clusters as usize, options.components as usize),
        options.iterations,
        Some(warm),
        (&CpuAssigner, &mut |_| {}),
    )?;
    finish(
        (transfer.bands(), transfer.channels()),
        &mut points,
        &model,
        assignment,
    )
}

fn widen(values: &[f32]) -> Vec<f64> {
    values.iter().map(|&x| x as f64).collect()
}

/// The model in f32 with every row's coordinates, the rows read a block at a time.
fn finish(
    (bands, channels): (u32, u32),
    rows: &mut dyn Rows,
    model: &Model,
    assignment: Vec<u32>,
) -> Result<Cpca> {
    let components = model.components;
    let mut weights = vec![0.0f32; assignment.len() * components];
    if components > 0 {
        for_each_block(rows, |first, block| {
            let end = first + block.len();
            weights[first * components..end * components]
                .par_chunks_mut(components)
                .zip(&assignment[first..end])
                .enumerate()
                .for_each(|(i, (w, &c))| {
                    let x = block.row_f64(i);
                    w.iter_mut()
                        .zip(model.coordinates(c as usize, &x))
                        .for_each(|(w, x)| *w = x as f32);
                });
            Ok(())
        })?;
    }
    Ok(Cpca {
        bands,
        channels,
        dimension: model.dimension,
        components,
        means: narrow(&model.means),
        bases: narrow(&model.bases),
        assignment,
        weights,
    })
}

fn narrow(values: &[f64]) -> Vec<f32> {
    values.iter().map(|&x| x as f32).collect()
}

/// Refuses a non-finite coefficient (the shape holds by construction).
fn check_transfer(transfer: &Transfer) -> Result<()> {
    check_rows(&mut Points::of_transfer(transfer))
}

/// Refuses a non-finite value, naming its row.
fn check_rows(rows: &mut dyn Rows) -> Result<()> {
    let n = rows.dimension();
    for_each_block(rows, |first, block| {
        match block.data.iter().position(|c| !c.is_finite()) {
            Some(i) => Err(Error::Options(format!(
                "compress: transfer coefficient {} of vertex {} is {}",
                i % n,
                first + i / n,
                block.data[i]
            ))),
            None => Ok(()),
        }
    })
}

fn check_options(options: &CpcaOptions, dimension: usize, vertices: usize) -> Result<()> {
    if options.clusters == 0 || options.clusters as usize > vertices {
        return Err(Error::Options(format!(
            "compress: {} clusters for {vertices} vertices (need 1 to the vertex count)",
            options.clusters
        )));
    }
    if options.components as usize > dimension {
        return Err(Error::Options(format!(
            "compress: {} components exceed the {dimension} floats per vertex",
            options.components
        )));
    }
    if options.iterations == 0 {
        return Err(Error::Options(
            "compress: 0 iterations (need at least 1 fit)".into(),
        ));
    }
    Ok(())
}

fn check_start(transfer: &Transfer, start: &Cpca, options: &CpcaOptions) -> Result<()> {
    let same_layout = start.bands == transfer.bands()
        && start.channels == transfer.channels()
        && start.vertex_count() == transfer.vertex_count();
    if !same_layout {
        return Err(Error::Options(format!(
            "refine: a start of {} bands, {} channels, {} vertices for a transfer of {}, {}, {}",
            start.bands,
            start.channels,
            start.vertex_count(),
            transfer.bands(),
            transfer.channels(),
            transfer.vertex_count()
        )));
    }
    start.check_shape()?;
    if start.cluster_count() > options.clusters as usize {
        return Err(Error::Options(format!(
            "refine: cannot go from {} clusters down to {}",
            start.cluster_count(),
            options.clusters
        )));
    }
    Ok(())
}

impl Cpca {
    pub fn cluster_count(&self) -> usize {
        self.means.len() / self.dimension.max(1)
    }

    pub fn vertex_count(&self) -> usize {
        self.assignment.len()
    }

    /// Whether the arrays agree with each other (a `Cpca` is plain data anyone can build).
    fn check_shape(&self) -> Result<()> {
        let clusters = self.cluster_count();
        let consistent = self.dimension
            == self.channels as usize * (self.bands * self.bands) as usize
            && self.means.len() == clusters * self.dimension
            && self.bases.len() == clusters * self.components * self.dimension
            && self.weights.len() == self.vertex_count() * self.components
            && self.assignment.iter().all(|&c| (c as usize) < clusters);
        if consistent {
            Ok(())
        } else {
            Err(Error::Options(format!(
                "cpca: arrays of {} means, {} basis and {} weight floats do not fit {} clusters of {} components in {} dimensions for {} vertices (or an assignment is out of range)",
                self.means.len(),
                self.bases.len(),
                self.weights.len(),
                clusters,
                self.components,
                self.dimension,
                self.vertex_count()
            )))
        }
    }

    /// Value `index` of row `vertex` as reconstructed, `mean + sum_j w_j basis_j` at that one
    /// index: what a run-time reads when it needs a few values of a row, not all of them.
    pub fn entry(&self, vertex: usize, index: usize) -> f32 {
        let (n, m) = (self.dimension, self.components);
        let c = self.assignment[vertex] as usize;
        let weights = &self.weights[vertex * m..(vertex + 1) * m];
        let basis = &self.bases[c * m * n..(c + 1) * m * n];
        weights
            .iter()
            .zip(basis[index..].iter().step_by(n))
            .fold(self.means[c * n + index], |sum, (w, b)| sum + w * b)
    }

    /// The transfer the compressed form stands for: `mean + sum_j w_j basis_j` per vertex.
    pub fn reconstruct(&self) -> Transfer {
        let coeffs = self.reconstruct_rows(0..self.vertex_count());
        Transfer::new(self.bands, self.channels, self.vertex_count(), coeffs)
            .expect("one reconstructed row for each vertex")
    }

    /// The rows of the vertices `range` as [`Cpca::reconstruct`] gives them.
    pub fn reconstruct_rows(&self, range: std::ops::Range<usize>) -> Vec<f32> {
        let n = self.dimension;
        let m = self.components;
        let mut coeffs = vec![0.0f32; range.len() * n];
        coeffs
            .par_chunks_mut(n.max(1))
            .zip(&self.assignment[range.clone()])
            .enumerate()
            .for_each(|(i, (out, &c))| {
                let (v, c) = (range.start + i, c as usize);
                let mut sum: Vec<f64> = widen(&self.means[c * n..(c + 1) * n]);
                let weights = &self.weights[v * m..(v + 1) * m];
                let basis = &self.bases[c * m * n..(c + 1) * m * n];
                for (w, b) in weights.iter().zip(basis.chunks_exact(n)) {
                    sum.iter_mut()
                        .zip(b)
                        .for_each(|(s, b)| *s += *w as f64 * *b as f64);
                }
                out.iter_mut().zip(&sum).for_each(|(o, s)| *o = *s as f32);
            });
        coeffs
    }

    /// Per-vertex exit radiance as a run-time computes it: the light dotted into each
    /// cluster's mean and directions once, then `mean_dot + sum_j w_j * basis_dot_j` per
    /// vertex. Equals relighting [`Cpca::reconstruct`] (`render::relight`) to float rounding,
    /// with the same conventions: bands both sides have, a one-channel transfer lighting all
    /// three channels.
    pub fn relight(&self, light: &ShLight) -> Result<Vec<[f32; 3]>> {
        self.check_shape()?;
        check_light(light)?;
        let n = self.dimension;
        // Per cluster: the mean's radiance, then each direction's.
        let dots: Vec<[f32; 3]> = self
            .means
            .chunks_exact(n)
            .enumerate()
            .flat_map(|(c, mean)| {
                let basis = &self.bases[c * self.components * n..(c + 1) * self.components * n];
                std::iter::once(mean)
                    .chain(basis.chunks_exact(n))
                    .map(|t| self.radiance(t, light))
            })
            .collect();
        let m = self.components;
        Ok(self
            .assignment
            .par_iter()
            .enumerate()
            .with_min_len(1024)
            .map(|(v, &c)| {
                let cluster = &dots[c as usize * (m + 1)..(c as usize + 1) * (m + 1)];
                let weights = &self.weights[v * m..(v + 1) * m];
                std::array::from_fn(|k| {
                    weights
                        .iter()
                        .zip(&cluster[1..])
                        .fold(cluster[0][k], |sum, (w, d)| sum + w * d[k])
                })
            })
            .collect())
    }

    /// The radiance of one transfer vector (all channels) under `light`.
    fn radiance(&self, t: &[f32], light: &ShLight) -> [f32; 3] {
        vector_radiance(t, self.channels as usize, light)
    }

    /// Bytes the baked file stores this in at `precision` ([`stored_bytes`]).
    pub fn byte_size(&self, precision: Precision) -> usize {
        stored_bytes(
            (self.cluster_count(), self.components),
            self.dimension,
            self.vertex_count(),
            precision,
        )
    }

    /// This as stored at `precision` and read back: means, bases and weights rounded (the
    /// assignment is exact at any precision).
    pub fn rounded(&self, precision: Precision) -> Cpca {
        Cpca {
            means: precision.round_all(&self.means),
            bases: precision.round_all(&self.bases),
            weights: precision.round_all(&self.weights),
            ..self.clone()
        }
    }
}

/// Bytes of a compressed transfer of `(clusters, components)` in the baked file: means, bases
/// and weights at `precision`, `precision.bytes() * (clusters * dimension * (1 + components) +
/// vertices * components)`, plus `index_bytes(clusters, precision)` per vertex.
pub fn stored_bytes(
    (clusters, components): (usize, usize),
    dimension: usize,
    vertices: usize,
    precision: Precision,
) -> usize {
    precision.bytes() * (clusters * dimension * (1 + components) + vertices * components)
        + index_bytes(clusters, precision) * vertices
}

/// Bytes of one vertex's cluster index: a float32 file keeps u32 (its layout since the first
/// compressed files); a half-float file the narrowest that holds every cluster, u8 up to 256
/// clusters, u16 up to 65,536, else u32.
pub fn index_bytes(clusters: usize, precision: Precision) -> usize {
    match precision {
        Precision::F32 => 4,
        Precision::F16 if clusters <= 1 << 8 => 1,
        Precision::F16 if clusters <= 1 << 16 => 2,
        Precision::F16 => 4,
    }
}

/// Bytes of the transfer rows as float32: 4 per coefficient.
pub fn uncompressed_bytes(rows: &dyn Rows) -> usize {
    4 * rows.len() * rows.dimension()
}

/// `L_c = sum_k light[k][c] * t[c][k]` over the bands both have; channel `c` of a
/// one-channel vector is its only channel. Summed in f64 (once per cluster, so cheap).
fn vector_radiance(t: &[f32], channels: usize, light: &ShLight) -> [f32; 3] {
    let per_channel = t.len() / channels;
    let shared = per_channel.min(light.coeffs.len());
    std::array::from_fn(|c| {
        let start = c.min(channels - 1) * per_channel;
        t[start..start + shared]
            .iter()
            .zip(&light.coeffs)
            .map(|(t, l)| *t as f64 * l[c] as f64)
            .sum::<f64>() as f32
    })
}

fn check_light(light: &ShLight) -> Result<()> {
    if light.bands == 0 || light.coeffs.len() != crate::sh::coeff_count(light.bands) {
        return Err(Error::Options(format!(
            "relight: light with {} bands holds {} coefficients (need bands >= 1 and bands^2)",
            light.bands,
            light.coeffs.len()
        )));
    }
    Ok(())
}

/// RMS of the coefficient difference over the RMS of the original coefficients (0 for an
/// all-zero original reconstructed exactly; infinite if only the original is zero).
pub fn relative_error(original: &Transfer, cpca: &Cpca) -> f64 {
    relative_error_of(&mut Points::of_transfer(original), cpca).expect("rows in memory read")
}

/// Rows [`relative_error_of`] reconstructs at once: the transfer in memory is not copied whole.
pub const RECONSTRUCTED_ROWS: usize = 4096;

/// [`relative_error`] of the original rows read from `rows`, summed in the same order.
pub fn relative_error_of(rows: &mut dyn Rows, cpca: &Cpca) -> Result<f64> {
    let mut sums = RelativeRms::default();
    let n = rows.dimension();
    for_each_block(rows, |first, block| {
        for start in (0..block.len()).step_by(RECONSTRUCTED_ROWS) {
            let end = (start + RECONSTRUCTED_ROWS).min(block.len());
            let reconstructed = cpca.reconstruct_rows(first + start..first + end);
            sums.add(
                block.data[start * n..end * n].iter().map(|&x| x as f64),
                reconstructed.iter().map(|&x| x as f64),
            );
        }
        Ok(())
    })?;
    Ok(sums.value())
}

/// The relit-radiance error under `light`: RMS over vertices and channels of the difference
/// between relighting the original and the compressed transfer, over the RMS radiance of the
/// original.
pub fn relit_error(original: &Transfer, cpca: &Cpca, light: &ShLight) -> Result<f64> {
    check_transfer(original)?;
    relit_error_of(
        &mut Points::of_transfer(original),
        original.channels(),
        cpca,
        light,
    )
}

/// [`relit_error`] of the original rows of `channels` channels read from `rows`.
pub fn relit_error_of(
    rows: &mut dyn Rows,
    channels: u32,
    cpca: &Cpca,
    light: &ShLight,
) -> Result<f64> {
    let approximate = cpca.relight(light)?;
    if approximate.len() != rows.len() {
        return Err(Error::Options(format!(
            "relit error: {} compressed vertices for {} original ones",
            approximate.len(),
            rows.len()
        )));
    }
    let mut sums = RelativeRms::default();
    for_each_block(rows, |first, block| {
        let reference = rows_radiance(block, channels as usize, light);
        sums.add_radiance(&reference, &approximate[first..first + block.len()]);
        Ok(())
    })?;
    Ok(sums.value())
}

/// Every vertex's radiance from `transfer` (one or three channels) under `light`, summed in
/// f64: the reference the compressed and the zonal forms are measured against.
pub fn radiance(transfer: &Transfer, light: &ShLight) -> Vec<[f32; 3]> {
    rows_radiance(
        Points::of_transfer(transfer),
        transfer.channels() as usize,
        light,
    )
}

fn rows_radiance(rows: Points, channels: usize, light: &ShLight) -> Vec<[f32; 3]> {
    rows.data
        .par_chunks_exact(rows.dimension.max(1))
        .map(|t| vector_radiance(t, channels, light))
        .collect()
}

/// RMS over vertices and channels of `approximate - reference`, over the RMS of `reference`.
pub fn radiance_error(reference: &[[f32; 3]], approximate: &[[f32; 3]]) -> f64 {
    let mut sums = RelativeRms::default();
    sums.add_radiance(reference, approximate);
    sums.value()
}

/// The sums of a relative RMS error, added to a run of values at a time: a file written in
/// chunks reports the error the whole file would, summed in the same order.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelativeRms {
    difference: f64,
    magnitude: f64,
}

impl RelativeRms {
    /// Adds `other`'s squared differences from `reference`, and `reference`'s squares.
    pub fn add(&mut self, reference: impl Iterator<Item = f64>, other: impl Iterator<Item = f64>) {
        for (r, o) in reference.zip(other) {
            self.difference += (o - r) * (o - r);
            self.magnitude += r * r;
        }
    }

    /// Adds the radiance error of `approximate` against `reference` ([`radiance_error`]).
    pub fn add_radiance(&mut self, reference: &[[f32; 3]], approximate: &[[f32; 3]]) {
        self.add(
            reference.iter().flatten().map(|&x| x as f64),
            approximate.iter().flatten().map(|&x| x as f64),
        );
    }

    /// sqrt(sum of squared differences / sum of squares); 0 where nothing differs.
    pub fn value(&self) -> f64 {
        if self.difference == 0.0 {
            0.0
        } else {
            (self.difference / self.magnitude).sqrt()
        }
    }
}

/// The smallest [`Cpca`] (by [`Cpca::byte_size`] at float32) on a grid of cluster and component counts
/// whose [`relative_error`] is at most `target_relative_error`, with the options that made it.
///
/// The grid is clusters 1, 4, 16, 64, 256 by components 1, 2, 4, 8, 16, ... (within the
/// vertex count and the dimension), tried from the smallest size up; a shape no bigger in
/// either count than one that missed the target is skipped, since error falls with both.
/// One cluster with as many components as the dimension closes the grid and reconstructs
/// exactly, so only a target below float rounding goes unmet.
pub fn choose(
    transfer: &Transfer,
    target_relative_error: f64,
    seed: u64,
) -> Result<(Cpca, CpcaOptions)> {
    let shape = (transfer.bands(), transfer.channels());
    choose_from(
        &mut Points::of_transfer(transfer),
        shape,
        target_relative_error,
        (seed, &CpuAssigner),
        &mut |_, _| {},
    )
}

/// The shapes [`choose`] may try for rows of `dimension` floats of `vertices` vertices, in
/// order: what `trying` counts up to.
pub fn choose_steps(dimension: usize, vertices: usize) -> usize {
    grid(dimension, vertices).len()
}

/// [`choose`] of transfer rows of `(bands, channels)` read from `rows`, with the assignment
/// steps on `assigner`; `trying` is told of each shape before it is tried, with its place
/// among the [`choose_steps`] (a shape skipped has one too).
pub fn choose_from(
    rows: &mut dyn Rows,
    shape: (u32, u32),
    target_relative_error: f64,
    (seed, assigner): (u64, &dyn Assigner),
    trying: &mut dyn FnMut(usize, &CpcaOptions),
) -> Result<(Cpca, CpcaOptions)> {
    if !(target_relative_error >= 0.0 && target_relative_error.is_finite()) {
        return Err(Error::Options(format!(
            "choose: target relative error {target_relative_error} (need a finite number >= 0)"
        )));
    }
    check_rows(rows)?;
    let (dimension, vertices) = (rows.dimension(), rows.len());
    let mut missed: Vec<(u32, u32)> = Vec::new();
    let mut best_missed = f64::INFINITY;
    for (step, (clusters, components)) in grid(dimension, vertices).into_iter().enumerate() {
        if missed
            .iter()
            .any(|&(k, m)| clusters <= k && components <= m)
        {
            continue;
        }
        let options = CpcaOptions {
            clusters,
            components,
            seed,
            ..CpcaOptions::default()
        };
        trying(step, &options);
        let cpca = compress_from(rows, shape, &options, assigner)?;
        let error = relative_error_of(rows, &cpca)?;
        if error <= target_relative_error {
            return Ok((cpca, options));
        }
        best_missed = best_missed.min(error);
        missed.push((clusters, components));
    }
    Err(Error::Options(format!(
        "choose: no compression reaches relative error {target_relative_error} (best {best_missed:.3e})"
    )))
}

/// The most clusters and the most components of any shape [`choose`] may try for rows of
/// `dimension` floats of `vertices` vertices: what its memory is bounded by.
pub fn largest_search_shape(dimension: usize, vertices: usize) -> (usize, usize) {
    grid(dimension, vertices)
        .into_iter()
        .fold((0, 0), |(k, m), (clusters, components)| {
            (k.max(clusters as usize), m.max(components as usize))
        })
}

/// (clusters, components) shapes to try, smallest stored size first.
fn grid(dimension: usize, vertices: usize) -> Vec<(u32, u32)> {
    let clusters = [1usize, 4, 16, 64, 256]
        .into_iter()
        .filter(|&k| k <= vertices);
    let components: Vec<usize> = std::iter::successors(Some(1usize), |m| Some(m * 2))
        .take_while(|&m| m < dimension)
        .collect();
    let mut shapes: Vec<(usize, usize)> = clusters
        .flat_map(|k| components.iter().map(move |&m| (k, m)))
        .collect();
    shapes.sort_by_key(|&(k, m)| {
        let bytes = stored_bytes((k, m), dimension, vertices, Precision::F32);
        (bytes, k, m)
    });
    if vertices > 0 {
        shapes.push((1, dimension));
    }
    shapes
        .into_iter()
        .map(|(k, m)| (k as u32, m as u32))
        .collect()
}

#[cfg(test)]
mod tests;
