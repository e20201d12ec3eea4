//! The kernels' uniforms (each the twin of a WGSL struct, checked by `shaders`' tests) and how
//! a pipeline is made and a pass recorded.

use bytemuck::{Pod, Zeroable};

use crate::device::GpuContext;
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
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups(workgroups[0], workgroups[1], workgroups[2]);
}

/// Records one compute pass whose workgroup counts a kernel wrote to `counts` (x, y, z).
pub(super) fn encode_indirect_pass(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    counts: &wgpu::Buffer,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups_indirect(counts, 0);
}
