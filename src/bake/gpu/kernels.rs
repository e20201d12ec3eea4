//! The kernels' uniforms (each the twin of a WGSL struct, checked by `shaders`' tests) and how
//! a pipeline is made and a pass recorded.

use bytemuck::{Pod, Zeroable};

use crate::device::GpuContext;
use crate::error::Result;
use crate::sampling::{DirectionFrame, Estimator};
use crate::shaders::{ESTIMATOR_BLOCKED, ESTIMATOR_TANGENT};

/// Uniforms of the visibility kernel, 64 bytes; WGSL twin in wgsl/visibility.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct VisibilityParams {
    pub vertex_offset: u32,
    pub vertex_count: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    pub words_per_vertex: u32,
    /// Traversal steps one ray may take before it reports itself exhausted.
    pub max_steps: u32,
    /// 1: trace rays; 0: every sample above the horizon is visible.
    pub shadowed: u32,
    /// 1: closest-hit traversal, hits written for interreflection.
    pub record_hits: u32,
    /// The grid of the node boxes ([`crate::bvh::gpu::GpuBvh`]): world = grid_origin + q * grid_step.
    pub grid_origin: [f32; 3],
    pub grid_step: f32,
    /// `shaders::FRAMES_*`: world directions, each vertex's tangent frame, or that frame
    /// turned by the vertex's own angle.
    pub frames: u32,
    /// [`crate::sampling::ReceiverTurns`]: vertex `v` turns by
    /// `receiver_turn(turn_seed, turn_first + v)`.
    pub turn_seed: u32,
    pub turn_first: u32,
    pub pad0: u32,
}

/// Uniforms of the projection kernel, 32 bytes; WGSL twin in wgsl/project.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ProjectParams {
    pub vertex_offset: u32,
    pub vertex_count: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    pub words_per_vertex: u32,
    pub coeff_count: u32,
    pub accumulate: u32,
    /// `shaders::ESTIMATOR_*` flags: which samples enter the sum, and their weight.
    pub estimator: u32,
}

/// The project kernel's `estimator` flags for a strategy's estimator and direction frame.
pub(super) fn estimator_flags(estimator: Estimator, frame: DirectionFrame) -> u32 {
    let blocked = if estimator == Estimator::Blocked {
        ESTIMATOR_BLOCKED
    } else {
        0
    };
    let tangent = if frame == DirectionFrame::Tangent {
        ESTIMATOR_TANGENT
    } else {
        0
    };
    blocked | tangent
}

/// Uniforms of the bounce (gather) kernel, 32 bytes; WGSL twin in wgsl/gather.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GatherParams {
    pub row_offset: u32,
    pub row_count: u32,
    pub coeff_count: u32,
    pub entry_begin: u32,
    pub entry_limit: u32,
    pub accumulate: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// A compute pipeline for the kernel's `main`, its layout derived from the WGSL.
pub(crate) fn pipeline(ctx: &GpuContext, label: &str, source: String) -> wgpu::ComputePipeline {
    pipeline_with(ctx, label, source, &[])
}

/// [`pipeline`] with the kernel's `override` constants set to `constants`.
pub(crate) fn pipeline_with(
    ctx: &GpuContext,
    label: &str,
    source: String,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    let module = ctx
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
    ctx.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                ..Default::default()
            },
            cache: None,
        })
}

/// Records one compute pass: `pipeline` over `workgroups` with `group` at binding set 0.
pub(crate) fn encode_pass(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    workgroups: [u32; 3],
) {
    encode_timed_pass(
        encoder,
        (label, pipeline, group),
        Dispatch::Direct(workgroups),
        None,
    );
}

/// How a pass's workgroups are counted: given, or read from a buffer a kernel wrote (x, y, z).
pub(super) enum Dispatch<'b> {
    Direct([u32; 3]),
    Indirect(&'b wgpu::Buffer),
}

/// Records one compute pass of `pipeline` with `group` at binding set 0, writing a timestamp
/// where it starts and ends when `timestamps` is given.
pub(super) fn encode_timed_pass(
    encoder: &mut wgpu::CommandEncoder,
    (label, pipeline, group): (&str, &wgpu::ComputePipeline, &wgpu::BindGroup),
    dispatch: Dispatch,
    timestamps: Option<wgpu::ComputePassTimestampWrites>,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: timestamps,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    match dispatch {
        Dispatch::Direct([x, y, z]) => pass.dispatch_workgroups(x, y, z),
        Dispatch::Indirect(counts) => pass.dispatch_workgroups_indirect(counts, 0),
    }
}

/// The start and end timestamps of a chunk's passes (horizon, visibility, projection),
/// resolved into a buffer the host reads after the chunk.
pub(super) struct PassTimer {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
}

impl PassTimer {
    /// Passes timed per chunk.
    pub const PASSES: u32 = 3;

    /// A timer on `ctx`'s device, where it writes timestamps.
    pub fn new(ctx: &GpuContext) -> Option<PassTimer> {
        if !ctx.has_timestamps() {
            return None;
        }
        let queries = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("pass timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2 * Self::PASSES,
        });
        let resolved = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("resolved pass timestamps"),
            size: 2 * Self::PASSES as u64 * 8,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(PassTimer { queries, resolved })
    }

    /// Where pass `pass` writes its start and end.
    pub fn writes(&self, pass: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(2 * pass),
            end_of_pass_write_index: Some(2 * pass + 1),
        }
    }

    /// Records the resolve of every pass's timestamps, after the passes.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.queries, 0..2 * Self::PASSES, &self.resolved, 0);
    }

    /// Each pass's seconds on the device, read once the chunk has finished.
    pub fn seconds(&self, ctx: &GpuContext) -> Result<[f64; Self::PASSES as usize]> {
        let ticks: Vec<u64> = ctx.read_back(&self.resolved, 2 * Self::PASSES as u64 * 8)?;
        let nanoseconds_per_tick = ctx.queue.get_timestamp_period() as f64;
        Ok(std::array::from_fn(|pass| {
            let (start, end) = (ticks[2 * pass], ticks[2 * pass + 1]);
            end.saturating_sub(start) as f64 * nanoseconds_per_tick * 1e-9
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use crate::bake::{BakeInputs, NoProgress};
    use crate::sampling::Sampling;
    use crate::scene::{builtin, prepare::prepare};

    /// On a device that writes timestamps (lavapipe does), every pass of a bake is timed and
    /// took a positive, finite time; on one that does not, no figure is made up.
    #[test]
    fn passes_are_timed_where_the_device_writes_timestamps() {
        let Some(context) = crate::device::any_adapter_or_skip() else {
            return;
        };
        let baker = GpuBaker::new(context).unwrap();
        let (scene, _) = prepare(builtin::default_scene()).unwrap();
        let owned = BakeInputs::with_sampling(&scene, 3, 64, 5, Sampling::Cosine);
        let (_, run) = direct_transfer(
            &baker,
            &owned.view(),
            Mode::Shadowed,
            Chunking::default(),
            &NoProgress,
        )
        .unwrap();
        match run.kernel_seconds {
            Some(passes) => {
                assert!(baker.context.has_timestamps());
                assert!(
                    passes.iter().all(|s| s.is_finite() && *s > 0.0),
                    "{passes:?}"
                );
            }
            None => assert!(!baker.context.has_timestamps()),
        }
    }
}
