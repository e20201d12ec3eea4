//! The CPCA assignment step on a GPU (`wgsl/cpca_assign.wgsl`): nearly all of a compression's
//! time is finding each vertex's nearest cluster subspace, `vertices x clusters x
//! (components + 1) x dimension` multiply-adds a round, and every vertex is independent. The points are
//! uploaded once; each round uploads the model and reads back one index and residual per
//! vertex. The fits (means, covariances, eigenvectors) stay on the CPU, in f64.
//!
//! The kernel works in f32 where `cluster::assign` works in f64, so a vertex whose two best
//! clusters are within rounding of each other may go the other way; the result is
//! deterministic for one device and close to the CPU's in error (tests).

use bytemuck::{Pod, Zeroable};

use super::cluster::{Assigner, Model};
use super::rows::Rows;
use crate::bake::gpu::{encode_pass, pipeline};
use crate::device::GpuContext;
use crate::error::{Error, Result};
use crate::shaders::{cpca_assign_kernel, WORKGROUP_SIZE};

/// Uniforms of the assignment kernel, 32 bytes; WGSL twin in wgsl/cpca_assign.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct AssignParams {
    pub vertex_count: u32,
    pub dimension: u32,
    pub components: u32,
    pub cluster_begin: u32,
    pub cluster_end: u32,
    pub accumulate: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// Loop iterations one invocation may run in one pass: llvmpipe stops every loop of an
/// invocation after 65,535 iterations in all, silently (DESIGN.md), so a pass stays at a
/// quarter of that.
pub const ITERATIONS_PER_PASS: usize = 16_384;

/// Clusters one pass tries per vertex: each costs `dimension * (components + 1)` inner
/// iterations plus `components + 1` loop heads. `None` when even one cluster is too much.
pub fn clusters_per_pass(dimension: usize, components: usize) -> Option<usize> {
    let per_cluster = dimension * (components + 1) + components + 1;
    let clusters = ITERATIONS_PER_PASS / per_cluster;
    (clusters > 0).then_some(clusters)
}

/// The assignment on one GPU for one set of points, uploaded once in vertex chunks that fit
/// the adapter's bindings and dispatch limits.
pub struct GpuAssigner<'c> {
    context: &'c GpuContext,
    kernel: wgpu::ComputePipeline,
    dimension: usize,
    /// `(first vertex, vertex count, points)` per chunk.
    chunks: Vec<(usize, usize, wgpu::Buffer)>,
}

impl<'c> GpuAssigner<'c> {
    /// Uploads `rows`, a block at a time. Refuses rows too long for one cluster per pass.
    pub fn new(context: &'c GpuContext, rows: &mut dyn Rows, components: usize) -> Result<Self> {
        let dimension = rows.dimension();
        if clusters_per_pass(dimension, components).is_none() {
            return Err(Error::Options(format!(
                "compress on a GPU: {dimension} floats per vertex with {components} components \
                 exceed one pass of the assignment kernel"
            )));
        }
        let kernel = context.checked("compiling the CPCA kernel", || {
            pipeline(context, "cpca assign", cpca_assign_kernel())
        })?;
        let row_bytes = (dimension * 4) as u64;
        let by_binding = (context.limits.max_storage_buffer_binding_size / row_bytes) as usize;
        let by_dispatch =
            context.limits.max_compute_workgroups_per_dimension as usize * WORKGROUP_SIZE as usize;
        let per_chunk = by_binding.min(by_dispatch).max(1);
        let mut chunks = Vec::new();
        for first in (0..rows.len()).step_by(per_chunk) {
            let count = per_chunk.min(rows.len() - first);
            chunks.push((first, count, upload(context, rows, first..first + count)?));
        }
        Ok(GpuAssigner {
            context,
            kernel,
            dimension,
            chunks,
        })
    }

    /// The assigner a bake on `context` clusters with: `None` on a software adapter
    /// (lavapipe), which runs on the same cores as the CPU path and took 7-12 times as long
    /// (docs/performance.md), and where rows are too long for the kernel (the reason is
    /// returned beside it, for a note).
    pub fn where_it_pays(
        context: &'c GpuContext,
        rows: &mut dyn Rows,
        components: usize,
    ) -> Result<(Option<Self>, Option<String>)> {
        if context.adapter.is_software() {
            return Ok((None, None));
        }
        match GpuAssigner::new(context, rows, components) {
            Ok(assigner) => Ok((Some(assigner), None)),
            Err(Error::Options(why)) => Ok((None, Some(why))),
            Err(e) => Err(e),
        }
    }

    /// The adapter it runs on, for reports.
    pub fn label(&self) -> String {
        self.context.adapter.label()
    }

    /// Every vertex of one chunk: its best cluster and residual, pass after pass over the
    /// clusters.
    fn assign_chunk(
        &self,
        (count, points): (usize, &wgpu::Buffer),
        model: &Model,
        (means, bases): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Result<(Vec<u32>, Vec<f32>)> {
        let ctx = self.context;
        let clusters = model.clusters();
        let per_pass = clusters_per_pass(model.dimension, model.components).unwrap_or(1);
        let best_cluster = ctx.output("cpca best cluster", count as u64 * 4);
        let best_residual = ctx.output("cpca best residual", count as u64 * 4);
        let params = ctx.uniform("cpca params", &AssignParams::default());
        let group = ctx.checked("binding the CPCA buffers", || {
            let layout = self.kernel.get_bind_group_layout(0);
            let buffers = [&params, points, means, bases, &best_cluster, &best_residual];
            ctx.bind_buffers("cpca assign", &layout, &buffers)
        })?;
        for begin in (0..clusters).step_by(per_pass) {
            let pass = AssignParams {
                vertex_count: count as u32,
                dimension: model.dimension as u32,
                components: model.components as u32,
                cluster_begin: begin as u32,
                cluster_end: (begin + per_pass).min(clusters) as u32,
                accumulate: (begin > 0) as u32,
                ..AssignParams::default()
            };
            ctx.queue
                .write_buffer(&params, 0, bytemuck::bytes_of(&pass));
            ctx.checked("running the CPCA kernel", || {
                let mut encoder =
                    ctx.device
                        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                            label: Some("cpca assign"),
                        });
                let workgroups = (count as u32).div_ceil(WORKGROUP_SIZE);
                encode_pass(
                    &mut encoder,
                    "cpca assign",
                    &self.kernel,
                    &group,
                    [workgroups, 1, 1],
                );
                ctx.queue.submit([encoder.finish()]);
            })?;
            ctx.wait()?;
        }
        Ok((
            ctx.read_back(&best_cluster, count as u64 * 4)?,
            ctx.read_back(&best_residual, count as u64 * 4)?,
        ))
    }
}

impl Assigner for GpuAssigner<'_> {
    fn assign(&self, rows: &mut dyn Rows, model: &Model) -> Result<(Vec<u32>, Vec<f64>)> {
        let uploaded: usize = self.chunks.iter().map(|c| c.1).sum();
        if rows.dimension() != self.dimension || rows.len() != uploaded {
            return Err(Error::Options(format!(
                "compress on a GPU: {} rows of {} floats, but {uploaded} of {} were uploaded",
                rows.len(),
                rows.dimension(),
                self.dimension
            )));
        }
        let narrow = |values: &[f64]| values.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let ctx = self.context;
        let means = ctx.storage("cpca means", &narrow(&model.means));
        let bases = ctx.storage("cpca bases", &narrow(&model.bases));
        let mut clusters = Vec::with_capacity(rows.len());
        let mut residuals = Vec::with_capacity(rows.len());
        for (_, count, buffer) in &self.chunks {
            let (c, r) = self.assign_chunk((*count, buffer), model, (&means, &bases))?;
            clusters.extend(c);
            residuals.extend(r.into_iter().map(f64::from));
        }
        Ok((clusters, residuals))
    }
}

/// The rows `range` in one storage buffer: in one piece where a block holds them all (the
/// transfer in memory), else block by block, each flushed before the next is read so that one
/// block at a time waits in the queue's staging memory.
fn upload(
    context: &GpuContext,
    rows: &mut dyn Rows,
    range: std::ops::Range<usize>,
) -> Result<wgpu::Buffer> {
    let (n, block) = (rows.dimension(), rows.block().max(1));
    if range.len() <= block {
        return Ok(context.storage("cpca points", &rows.read(range)?));
    }
    let buffer = context.output("cpca points", (range.len() * n * 4) as u64);
    for first in range.clone().step_by(block) {
        let end = (first + block).min(range.end);
        let offset = ((first - range.start) * n * 4) as u64;
        let piece = rows.read(first..end)?;
        context
            .queue
            .write_buffer(&buffer, offset, bytemuck::cast_slice(&piece));
        context.queue.submit([]);
    }
    Ok(buffer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{bake, BakeOptions, CpuBackend, NoProgress, Transfer};
    use crate::compress::rows::InBlocks;
    use crate::compress::Points;
    use crate::compress::{compress, compress_with, relative_error, CpcaOptions, CpuAssigner};
    use crate::scene::builtin::default_scene;

    fn transfer() -> Transfer {
        let options = BakeOptions {
            samples: 64,
            ..BakeOptions::default()
        };
        bake(default_scene(), &options, &CpuBackend, &NoProgress)
            .unwrap()
            .0
            .transfer
    }

    #[test]
    fn a_pass_stays_within_the_iteration_budget() {
        for (dimension, components) in [(16, 0), (48, 8), (768, 16), (3, 1)] {
            let per_pass = clusters_per_pass(dimension, components).unwrap();
            let per_cluster = dimension * (components + 1) + components + 1;
            assert!(per_pass * per_cluster <= ITERATIONS_PER_PASS);
            assert!((per_pass + 1) * per_cluster > ITERATIONS_PER_PASS);
        }
        assert_eq!(clusters_per_pass(16_384, 1), None);
    }

    /// The kernel's choices against the CPU's, for a fitted model, in one pass and in several
    /// (200 clusters of 4 directions in 48 dimensions take 4 passes).
    #[test]
    fn gpu_assignment_matches_the_cpu_up_to_rounding() {
        let Some(context) = crate::device::any_adapter_or_skip() else {
            return;
        };
        let transfer = transfer();
        let mut points = Points::of_transfer(&transfer);
        for clusters in [40, 200] {
            let options = CpcaOptions {
                clusters,
                components: 4,
                iterations: 3,
                seed: 5,
            };
            let cpca = compress(&transfer, &options).unwrap();
            let widen = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<f64>>();
            let model = Model::new(points.dimension, 4, widen(&cpca.means), widen(&cpca.bases));
            let (cpu_clusters, cpu_residuals) = CpuAssigner.assign(&mut points, &model).unwrap();
            let gpu = GpuAssigner::new(&context, &mut points, 4).unwrap();
            let (gpu_clusters, gpu_residuals) = gpu.assign(&mut points, &model).unwrap();
            let mut differ = 0;
            for v in 0..points.len() {
                let x: Vec<f64> = points.data[v * points.dimension..(v + 1) * points.dimension]
                    .iter()
                    .map(|&x| x as f64)
                    .collect();
                // f32 rounding of distances of the size of the point's and the mean's norms
                // (and of stored f32 transfer, for points near zero).
                let norm2 = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
                let mean = model.mean(cpu_clusters[v] as usize);
                let tolerance = 1e-5 * (norm2(&x) + norm2(mean)) + 1e-10;
                assert!(
                    (gpu_residuals[v] - cpu_residuals[v]).abs() <= tolerance,
                    "vertex {v}: gpu {} cpu {}",
                    gpu_residuals[v],
                    cpu_residuals[v]
                );
                if gpu_clusters[v] != cpu_clusters[v] {
                    differ += 1;
                    // Only a near-tie may go the other way.
                    let chosen = model.residual(gpu_clusters[v] as usize, &x);
                    assert!(chosen - cpu_residuals[v] <= tolerance, "vertex {v}");
                }
            }
            assert!(
                differ * 100 <= points.len(),
                "{differ} of {} differ",
                points.len()
            );
        }
    }

    #[test]
    fn gpu_compression_is_deterministic_and_as_good_as_the_cpu() {
        let Some(context) = crate::device::any_adapter_or_skip() else {
            return;
        };
        let transfer = transfer();
        // Six rounds, not the default twenty: what is checked (the same bits however the
        // points were uploaded, an error no worse than the CPU's) holds after any number of
        // rounds, and each round's assignment takes seconds on lavapipe.
        let options = CpcaOptions {
            clusters: 32,
            components: 6,
            iterations: 6,
            ..CpcaOptions::default()
        };
        let gpu = GpuAssigner::new(&context, &mut Points::of_transfer(&transfer), 6).unwrap();
        let first = compress_with(&transfer, &options, &gpu).unwrap();
        // Uploaded a block at a time (a streamed bake's scratch file) into another assigner,
        // the same bits: the run is deterministic, whatever the upload.
        let mut blocks = InBlocks {
            points: Points::of_transfer(&transfer),
            block: 100,
        };
        let uploaded_in_blocks = GpuAssigner::new(&context, &mut blocks, 6).unwrap();
        let in_blocks = compress_with(&transfer, &options, &uploaded_in_blocks).unwrap();
        assert!(
            in_blocks == first,
            "uploaded in blocks: another compression"
        );
        let on_cpu = compress(&transfer, &options).unwrap();
        let (gpu_error, cpu_error) = (
            relative_error(&transfer, &first),
            relative_error(&transfer, &on_cpu),
        );
        eprintln!("relative error: gpu {gpu_error:.5}, cpu {cpu_error:.5}");
        assert!(
            gpu_error <= 1.02 * cpu_error + 1e-6,
            "{gpu_error} vs {cpu_error}"
        );
        // Other points than were uploaded are refused, not misread.
        let half = Points {
            data: &transfer.coeffs()[..transfer.coeffs().len() / 2],
            dimension: Points::of_transfer(&transfer).dimension,
        };
        assert!(compress_with(
            &Transfer::new(
                transfer.bands(),
                transfer.channels(),
                transfer.vertex_count() / 2,
                half.data.to_vec()
            )
            .expect("the first half of the vertices"),
            &options,
            &gpu
        )
        .is_err());
    }
}
