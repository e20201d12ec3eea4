//! The GPU backend: the CPU backend's two passes as wgpu compute kernels.
//!
//! Split: a visibility pass (wgsl/visibility.wgsl, one invocation per vertex–sample pair, so an
//! invocation traces exactly one ray and stays far below llvmpipe's 65,535-iteration loop cap)
//! writes one bit per ray; a projection pass (wgsl/project.wgsl, one invocation per
//! vertex–coefficient pair) sums cosine-weighted SH over the set bits. The bits are also what
//! tests compare with the CPU ray for ray.
//!
//! Work is cut into chunks of vertices and of samples so that every binding fits the adapter's
//! limits and no submission runs long (real GPUs reset after about two seconds of one dispatch).

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::bounce::{GatherMatrix, Hit, NO_HIT};
use super::{DirectInputs, Mode, Progress};
use crate::bvh::{Bvh, BvhTriangle};
use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::sampling::{DirectionFrame, Estimator, VertexDirections};
use crate::sh::coeff_count;
use crate::shaders::{self, WORKGROUP_SIZE};

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
    /// The grid of the node boxes ([`GpuBvh`]): world = grid_origin + q * grid_step.
    pub grid_origin: [f32; 3],
    pub grid_step: f32,
    /// 1: sample directions are in each vertex's tangent frame (`sampling::tangent_frame`).
    pub tangent_frames: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
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
    /// `ESTIMATOR_*` flags of wgsl/project.wgsl: which samples enter the sum, their weight.
    pub estimator: u32,
}

/// The project kernel's flags (its `ESTIMATOR_*` constants): bit 0 sums blocked rays, bit 1
/// drops the cosine (tangent-frame sets with cosine density).
fn estimator_flags(estimator: Estimator, frame: DirectionFrame) -> u32 {
    (estimator == Estimator::Blocked) as u32 | ((frame == DirectionFrame::Tangent) as u32) << 1
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

/// Matrix entries one gather invocation sums in one pass (its loop count).
const GATHER_ENTRIES_PER_PASS: u32 = 16_384;

/// Traversal steps allowed per ray: under llvmpipe's silent cap of 65,535 loop iterations per
/// invocation with room to spare. A real mesh needs a few hundred; a ray that needs more is
/// reported as an error, never returned as a wrong answer.
pub const MAX_TRAVERSAL_STEPS: u32 = 60_000;

/// Vertex–sample pairs per submission: a few milliseconds on a desktop GPU, well inside any
/// driver watchdog even on slow hardware.
const PAIRS_PER_SUBMISSION: u64 = 1 << 22;

/// Samples per chunk. A projection invocation loops over a chunk's samples (plus one
/// iteration per word), so this bounds its loop count far below the cap too. Multiple of 32.
const MAX_SAMPLES_PER_CHUNK: u32 = 16_384;

/// Limits on chunk sizes, for tests that force many small chunks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Chunking {
    pub max_vertices: Option<u32>,
    /// Rounded up to a multiple of 32.
    pub max_samples: Option<u32>,
    /// Overrides MAX_TRAVERSAL_STEPS (tests prove the overflow is reported).
    pub max_steps: Option<u32>,
}

/// What a GPU bake returns besides the transfer.
#[derive(Clone, Debug, Default)]
pub struct GpuRun {
    pub rays_cast: u64,
    pub submissions: u32,
    pub vertex_chunks: u32,
    pub sample_chunks: u32,
}

/// An open device with the bake's kernels compiled (once; compiling is slow on lavapipe).
pub struct GpuBaker {
    pub context: GpuContext,
    visibility: wgpu::ComputePipeline,
    visibility_layout: wgpu::BindGroupLayout,
    project: wgpu::ComputePipeline,
    project_layout: wgpu::BindGroupLayout,
    gather: wgpu::ComputePipeline,
    gather_layout: wgpu::BindGroupLayout,
}

impl GpuBaker {
    pub fn new(context: GpuContext) -> Result<Self> {
        let ctx = &context;

        let ((visibility, visibility_layout), (project, project_layout), (gather, gather_layout)) =
            ctx.checked("compiling the kernels", || {
                let visibility = pipeline(
                    ctx,
                    "visibility",
                    shaders::visibility_kernel(),
                    &[
                        uniform_entry(0),
                        storage_entry(1, true),
                        storage_entry(2, true),
                        storage_entry(3, true),
                        storage_entry(4, true),
                        storage_entry(5, true),
                        storage_entry(6, false),
                        storage_entry(7, false),
                        storage_entry(8, false),
                        storage_entry(9, true),
                    ],
                );
                let project = pipeline(
                    ctx,
                    "project",
                    shaders::project_kernel(),
                    &[
                        uniform_entry(0),
                        storage_entry(1, true),
                        storage_entry(2, true),
                        storage_entry(3, true),
                        storage_entry(4, true),
                        storage_entry(5, false),
                    ],
                );
                let gather = pipeline(
                    ctx,
                    "gather",
                    shaders::gather_kernel(),
                    &[
                        uniform_entry(0),
                        storage_entry(1, true),
                        storage_entry(2, true),
                        storage_entry(3, true),
                        storage_entry(4, true),
                        storage_entry(5, true),
                        storage_entry(6, false),
                    ],
                );
                (visibility, project, gather)
            })?;
        Ok(GpuBaker {
            context,
            visibility,
            visibility_layout,
            project,
            project_layout,
            gather,
            gather_layout,
        })
    }
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn pipeline(
    ctx: &GpuContext,
    label: &str,
    source: String,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    let device = &ctx.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some("main"),
        compilation_options: wgpu::PipelineCompilationOptions::default(),
        cache: None,
    });
    (pipeline, layout)
}

/// Marks a child reference in a [`GpuNode`] as a leaf (the rest is its first triangle).
pub const LEAF_FLAG: u32 = 1 << 31;
/// `BvhTriangle::pad1` of the last triangle of a leaf in [`GpuBvh::triangles`].
pub const LAST_IN_LEAF: u32 = 1;

/// One interior node of the CPU tree as the visibility kernel reads it, 32 bytes (WGSL layout
/// in wgsl/bvh.wgsl): both children's boxes on the grid of [`GpuBvh`], and their references
/// (an interior child's index in [`GpuBvh::nodes`], or `LEAF_FLAG | first triangle`).
///
/// A traversal step on llvmpipe pays per storage-buffer load (a loop over the SIMD lanes with
/// a bounds check per lane and component): this layout gives a step two 16-byte loads where
/// `BvhNode`s take six loads (the node, then both children's corners).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNode {
    /// (min.x, min.y), (min.z, max.x), (max.y, max.z) as pairs of u16, low half first.
    pub left_box: [u32; 3],
    pub left: u32,
    pub right_box: [u32; 3],
    pub right: u32,
}
const _: () = assert!(std::mem::size_of::<GpuNode>() == 32);

/// The BVH in the visibility kernel's layout. Boxes are quantized to 16 bits per coordinate
/// on a grid whose step is a power of two and whose points `grid_origin + q * grid_step` are
/// all exact f32 values, rounded outwards: every box holds its exact box, so the kernel tests
/// the triangles the CPU tests (and perhaps a few more, which cannot change an answer).
/// Nodes come in the CPU tree's order and the near child is chosen the same way, so a
/// closest-hit query finds the same triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuBvh {
    pub nodes: Vec<GpuNode>,
    /// `bvh.triangles` with [`LAST_IN_LEAF`] in `pad1` of each leaf's last triangle.
    pub triangles: Vec<BvhTriangle>,
    pub grid_origin: [f32; 3],
    pub grid_step: f32,
}

const GRID_MAX: f64 = 65535.0;

impl GpuBvh {
    pub fn new(bvh: &Bvh) -> Self {
        let Some(root) = bvh.nodes.first() else {
            // No triangles: one node whose children are a leaf holding a degenerate triangle
            // (zero determinant: never hit).
            return GpuBvh {
                nodes: vec![GpuNode {
                    left: LEAF_FLAG,
                    right: LEAF_FLAG,
                    ..GpuNode::default()
                }],
                triangles: vec![BvhTriangle {
                    source_index: super::bounce::NO_HIT,
                    pad1: LAST_IN_LEAF,
                    ..BvhTriangle::default()
                }],
                grid_origin: [0.0; 3],
                grid_step: 1.0,
            };
        };
        let (lo, hi) = (root.min.map(f64::from), root.max.map(f64::from));
        let magnitude = (0..3).fold(0.0f64, |m, a| m.max(lo[a].abs()).max(hi[a].abs()));
        let extent = (0..3).fold(0.0f64, |m, a| m.max(hi[a] - lo[a]));
        // The smallest power of two that spans the scene in GRID_MAX steps (plus one for the
        // origin's rounding down) and keeps origin + q * step exact in f32 (24-bit mantissa).
        let mut step = f64::from(f32::MIN_POSITIVE);
        while extent > (GRID_MAX - 1.0) * step || magnitude + extent >= step * (1u64 << 23) as f64 {
            step *= 2.0;
        }
        let origin = lo.map(|v| (v / step).floor() * step);
        let grid = |v: f32, axis: usize, up: bool| -> u32 {
            let q = (f64::from(v) - origin[axis]) / step;
            (if up { q.ceil() } else { q.floor() }).clamp(0.0, GRID_MAX) as u32
        };
        let quantize = |index: u32| -> [u32; 3] {
            let n = &bvh.nodes[index as usize];
            let q = [
                grid(n.min[0], 0, false),
                grid(n.min[1], 1, false),
                grid(n.min[2], 2, false),
                grid(n.max[0], 0, true),
                grid(n.max[1], 1, true),
                grid(n.max[2], 2, true),
            ];
            [q[0] | q[1] << 16, q[2] | q[3] << 16, q[4] | q[5] << 16]
        };

        let mut triangles = bvh.triangles.clone();
        let mut gpu_index = vec![u32::MAX; bvh.nodes.len()];
        let mut interior = Vec::new();
        if root.is_leaf() {
            // A one-leaf tree: a node whose two children are that leaf.
            interior.push((0, 0));
        } else {
            // Interior nodes in the CPU tree's order.
            for (i, n) in bvh.nodes.iter().enumerate() {
                if !n.is_leaf() {
                    gpu_index[i] = interior.len() as u32;
                    interior.push((n.left_or_first, n.left_or_first + 1));
                }
            }
        }
        let reference = |child: u32, triangles: &mut Vec<BvhTriangle>| -> u32 {
            let n = &bvh.nodes[child as usize];
            if n.is_leaf() {
                triangles[(n.left_or_first + n.triangle_count - 1) as usize].pad1 = LAST_IN_LEAF;
                LEAF_FLAG | n.left_or_first
            } else {
                gpu_index[child as usize]
            }
        };
        let nodes = interior
            .iter()
            .map(|&(left, right)| GpuNode {
                left_box: quantize(left),
                left: reference(left, &mut triangles),
                right_box: quantize(right),
                right: reference(right, &mut triangles),
            })
            .collect();
        GpuBvh {
            nodes,
            triangles,
            grid_origin: origin.map(|v| v as f32),
            grid_step: step as f32,
        }
    }

    /// A box of `nodes` back in world space, as the kernel computes it.
    pub fn decode(&self, q: [u32; 3]) -> ([f32; 3], [f32; 3]) {
        let g = |v: u32, a: usize| self.grid_origin[a] + (v as f32) * self.grid_step;
        (
            [g(q[0] & 0xffff, 0), g(q[0] >> 16, 1), g(q[1] & 0xffff, 2)],
            [g(q[1] >> 16, 0), g(q[2] & 0xffff, 1), g(q[2] >> 16, 2)],
        )
    }
}

/// Chunk sizes that respect the adapter's limits and the per-submission budget.
fn plan_chunks(
    ctx: &GpuContext,
    vertices: u32,
    samples: u32,
    coeffs: u32,
    record_hits: bool,
    chunking: Chunking,
) -> (u32, u32) {
    let max_binding = ctx
        .limits
        .max_storage_buffer_binding_size
        .min(ctx.limits.max_buffer_size);
    let max_groups = ctx.limits.max_compute_workgroups_per_dimension as u64;

    let sample_limit = chunking
        .max_samples
        .unwrap_or(MAX_SAMPLES_PER_CHUNK)
        .min(MAX_SAMPLES_PER_CHUNK)
        .min(max_groups as u32)
        .max(1);
    // Whole words per chunk, so chunk bits land on word boundaries of the full bit array.
    let sample_chunk = (samples.min(sample_limit).div_ceil(32) * 32).min(samples.div_ceil(32) * 32);
    let words = sample_chunk.div_ceil(32) as u64;

    let by_budget = (PAIRS_PER_SUBMISSION / sample_chunk as u64).max(1);
    let by_bits = max_binding / (words * 4);
    let by_transfer = max_binding / (coeffs as u64 * 4);
    let hit_bytes = if record_hits {
        std::mem::size_of::<Hit>() as u64
    } else {
        0
    };
    let by_hits = max_binding / (sample_chunk as u64 * hit_bytes).max(1);
    let by_lists = max_binding / (sample_chunk as u64 * 4);
    let by_visibility_dispatch = max_groups;
    let by_project_dispatch = max_groups * WORKGROUP_SIZE as u64 / coeffs as u64;
    let vertex_chunk = [
        by_budget,
        by_bits,
        by_transfer,
        by_hits,
        by_lists,
        by_visibility_dispatch,
        by_project_dispatch,
    ]
    .into_iter()
    .min()
    .unwrap()
    .min(chunking.max_vertices.unwrap_or(u32::MAX) as u64)
    .min(vertices as u64)
    .max(1) as u32;
    (vertex_chunk, sample_chunk.max(32))
}

/// Records one compute pass: `pipeline` over `workgroups` with `group` at binding set 0.
fn encode_pass(
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

fn as_vec4(values: &[glam::Vec3]) -> Vec<[f32; 4]> {
    values.iter().map(|v| [v.x, v.y, v.z, 0.0]).collect()
}

/// What one run of the visibility and projection passes gives back.
struct RunOutput {
    /// Raw projected sums `[vertex][k]`, not yet scaled by the sample weight.
    sums: Vec<f32>,
    /// Visibility bits `[vertex][word]`, when asked for.
    bits: Vec<u32>,
    /// Per vertex, `(sample, hit)` of every blocked ray (interreflected mode only).
    hits: Vec<Vec<(u32, Hit)>>,
    stats: GpuRun,
}

/// Runs both passes over every chunk.
fn run(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    mode: Mode,
    chunking: Chunking,
    keep_bits: bool,
    progress: &dyn Progress,
) -> Result<RunOutput> {
    let ctx = &baker.context;
    let record_hits = mode == Mode::Interreflected;
    let vertex_count = inputs.origins.len() as u32;
    let sample_count = inputs.samples.len() as u32;
    let coeffs = coeff_count(inputs.table.bands) as u32;
    let total_words = sample_count.div_ceil(32) as usize;
    let (vertex_chunk, sample_chunk) = plan_chunks(
        ctx,
        vertex_count,
        sample_count,
        coeffs,
        record_hits,
        chunking,
    );
    let chunk_words = sample_chunk / 32;

    let needs_binding = |name: &str, bytes: u64| -> Result<()> {
        if bytes > ctx.limits.max_storage_buffer_binding_size {
            return Err(Error::Gpu(format!(
                "{name} needs {bytes} bytes, more than {}'s storage binding limit of {} bytes",
                ctx.adapter.name, ctx.limits.max_storage_buffer_binding_size
            )));
        }
        Ok(())
    };
    let gpu_bvh = GpuBvh::new(inputs.bvh);
    needs_binding(
        "the BVH triangles",
        std::mem::size_of_val(gpu_bvh.triangles.as_slice()) as u64,
    )?;
    needs_binding(
        "the BVH nodes",
        std::mem::size_of_val(gpu_bvh.nodes.as_slice()) as u64,
    )?;
    if inputs.bvh.triangles.len() as u64 > LEAF_FLAG as u64 {
        return Err(Error::Gpu(format!(
            "{} triangles: the GPU BVH holds at most {LEAF_FLAG}",
            inputs.bvh.triangles.len()
        )));
    }
    needs_binding("the SH table", (inputs.table.values.len() * 4) as u64)?;

    let nodes = ctx.storage("bvh nodes", &gpu_bvh.nodes);
    let triangles = ctx.storage("bvh triangles", &gpu_bvh.triangles);
    let origins = ctx.storage("origins", &as_vec4(inputs.origins));
    let normals = ctx.storage("normals", &as_vec4(inputs.normals));
    let directions = ctx.storage("directions", &as_vec4(&inputs.samples.directions));
    let sh_table = ctx.storage("sh table", &inputs.table.values);
    let bits_bytes = vertex_chunk as u64 * chunk_words as u64 * 4;
    let transfer_bytes = vertex_chunk as u64 * coeffs as u64 * 4;
    let bits = ctx.output("visibility bits", bits_bytes);
    let transfer = ctx.output("transfer", transfer_bytes);
    let exhausted = ctx.output("exhausted rays", 4);
    let hit_size = std::mem::size_of::<Hit>() as u64;
    let hits = ctx.output(
        "hits",
        if record_hits {
            vertex_chunk as u64 * sample_chunk as u64 * hit_size
        } else {
            hit_size
        },
    );
    let sample_lists = ctx.output(
        "sample lists",
        vertex_chunk as u64 * sample_chunk as u64 * 4,
    );
    let visibility_params = ctx.uniform("visibility params", &VisibilityParams::default());
    let project_params = ctx.uniform("project params", &ProjectParams::default());

    let (visibility_group, project_group) = ctx.checked("binding the buffers", || {
        let bind = |layout: &wgpu::BindGroupLayout, buffers: &[&wgpu::Buffer]| {
            ctx.bind_buffers("bake", layout, buffers)
        };
        (
            bind(
                &baker.visibility_layout,
                &[
                    &visibility_params,
                    &nodes,
                    &triangles,
                    &origins,
                    &normals,
                    &directions,
                    &bits,
                    &exhausted,
                    &hits,
                    &sample_lists,
                ],
            ),
            bind(
                &baker.project_layout,
                &[
                    &project_params,
                    &normals,
                    &directions,
                    &sh_table,
                    &bits,
                    &transfer,
                ],
            ),
        )
    })?;

    let mut sums = vec![0.0f32; vertex_count as usize * coeffs as usize];
    let mut all_bits = if keep_bits {
        vec![0u32; vertex_count as usize * total_words]
    } else {
        Vec::new()
    };
    let mut vertex_hits: Vec<Vec<(u32, Hit)>> = if record_hits {
        vec![Vec::new(); vertex_count as usize]
    } else {
        Vec::new()
    };
    let mut stats = GpuRun::default();
    let max_steps = chunking.max_steps.unwrap_or(MAX_TRAVERSAL_STEPS);

    for vertex_offset in (0..vertex_count).step_by(vertex_chunk as usize) {
        let vertices = vertex_chunk.min(vertex_count - vertex_offset);
        stats.vertex_chunks += 1;
        for (chunk_index, sample_offset) in
            (0..sample_count).step_by(sample_chunk as usize).enumerate()
        {
            let samples = sample_chunk.min(sample_count - sample_offset);
            stats.sample_chunks += (vertex_offset == 0) as u32;
            let (lists, longest, listed) = sample_lists_above_horizon(
                inputs,
                vertex_offset as usize..(vertex_offset + vertices) as usize,
                sample_offset as usize..(sample_offset + samples) as usize,
            );
            if mode != Mode::Unshadowed {
                stats.rays_cast += listed;
            }
            ctx.queue
                .write_buffer(&sample_lists, 0, bytemuck::cast_slice(&lists));
            ctx.queue.write_buffer(
                &visibility_params,
                0,
                bytemuck::bytes_of(&VisibilityParams {
                    vertex_offset,
                    vertex_count: vertices,
                    sample_offset,
                    sample_count: samples,
                    words_per_vertex: chunk_words,
                    max_steps,
                    shadowed: (mode != Mode::Unshadowed) as u32,
                    record_hits: record_hits as u32,
                    grid_origin: gpu_bvh.grid_origin,
                    grid_step: gpu_bvh.grid_step,
                    tangent_frames: (inputs.samples.frame == DirectionFrame::Tangent) as u32,
                    ..Default::default()
                }),
            );
            ctx.queue.write_buffer(
                &project_params,
                0,
                bytemuck::bytes_of(&ProjectParams {
                    vertex_offset,
                    vertex_count: vertices,
                    sample_offset,
                    sample_count: samples,
                    // The row stride of the bits; words past the chunk's samples are zero.
                    words_per_vertex: chunk_words,
                    coeff_count: coeffs,
                    accumulate: (chunk_index > 0) as u32,
                    estimator: estimator_flags(inputs.estimator, inputs.samples.frame),
                }),
            );
            ctx.checked("running the kernels", || {
                let mut encoder =
                    ctx.device
                        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                            label: Some("bake chunk"),
                        });
                encoder.clear_buffer(&bits, 0, None);
                encode_pass(
                    &mut encoder,
                    "visibility",
                    &baker.visibility,
                    &visibility_group,
                    [longest.div_ceil(WORKGROUP_SIZE), vertices, 1],
                );
                encode_pass(
                    &mut encoder,
                    "project",
                    &baker.project,
                    &project_group,
                    [(vertices * coeffs).div_ceil(WORKGROUP_SIZE), 1, 1],
                );
                ctx.queue.submit([encoder.finish()]);
            })?;
            ctx.wait()?;
            stats.submissions += 1;
            if keep_bits {
                let chunk_bits: Vec<u32> =
                    ctx.read_back(&bits, vertices as u64 * chunk_words as u64 * 4)?;
                let first_word = (sample_offset / 32) as usize;
                let words = samples.div_ceil(32) as usize;
                for v in 0..vertices as usize {
                    let row = (vertex_offset as usize + v) * total_words + first_word;
                    all_bits[row..row + words]
                        .copy_from_slice(&chunk_bits[v * chunk_words as usize..][..words]);
                }
            }
            if record_hits {
                let chunk_hits: Vec<Hit> =
                    ctx.read_back(&hits, vertices as u64 * samples as u64 * hit_size)?;
                // Only listed samples were written.
                for (v, (row, list)) in chunk_hits
                    .chunks(samples as usize)
                    .zip(lists.chunks(samples as usize))
                    .enumerate()
                {
                    let own = &mut vertex_hits[(vertex_offset as usize) + v];
                    for &s in list.iter().take_while(|&&s| s != NO_SAMPLE) {
                        let hit = row[s as usize];
                        if hit.triangle != NO_HIT {
                            own.push((sample_offset + s, hit));
                        }
                    }
                }
            }
        }
        let chunk_sums: Vec<f32> = ctx.read_back(&transfer, vertices as u64 * coeffs as u64 * 4)?;
        sums[(vertex_offset * coeffs) as usize..][..chunk_sums.len()].copy_from_slice(&chunk_sums);
        progress.advance(vertices as u64);
    }

    let exhausted_rays: Vec<u32> = ctx.read_back(&exhausted, 4)?;
    if exhausted_rays[0] > 0 {
        return Err(Error::Gpu(format!(
            "{} rays needed more than {max_steps} traversal steps; the GPU result would be wrong \
             (use --device cpu)",
            exhausted_rays[0]
        )));
    }
    Ok(RunOutput {
        sums,
        bits: all_bits,
        hits: vertex_hits,
        stats,
    })
}

/// End of a vertex's list in [`sample_lists_above_horizon`].
const NO_SAMPLE: u32 = u32::MAX;

/// For each vertex of `vertices`, the samples of `samples` above its horizon (by the CPU
/// backend's test, so both trace the same rays) as indices from `samples.start`, ascending,
/// padded with NO_SAMPLE to rows of `samples.len()`; the longest list's length; and the
/// lists' total length (the rays a shadowed pass casts for this chunk).
///
/// About half of all vertex–sample pairs are below the horizon. Listing the others first
/// keeps llvmpipe's 8-wide SIMD groups full of rays (a group straddling the horizon would
/// run masked lanes) and lets the dispatch skip groups with nothing to trace.
fn sample_lists_above_horizon(
    inputs: &DirectInputs,
    vertices: std::ops::Range<usize>,
    samples: std::ops::Range<usize>,
) -> (Vec<u32>, u32, u64) {
    let width = samples.len();
    let mut lists = vec![NO_SAMPLE; vertices.len() * width];
    let (longest, listed) = lists
        .par_chunks_mut(width.max(1))
        .zip(&inputs.normals[vertices])
        .map(|(row, &normal)| {
            let to_world = VertexDirections::new(inputs.samples.frame, normal);
            let mut count = 0;
            for (s, &sample) in inputs.samples.directions[samples.clone()]
                .iter()
                .enumerate()
            {
                let direction = to_world.world(sample);
                if normal.dot(direction) > 0.0 {
                    row[count] = s as u32;
                    count += 1;
                }
            }
            count as u32
        })
        .map(|count| (count, count as u64))
        .reduce(|| (0, 0), |a, b| (a.0.max(b.0), a.1 + b.1));
    (lists, longest, listed)
}

/// Transfer from the kernels' raw sums, finished per vertex as the CPU finishes its own.
fn scaled(mut sums: Vec<f32>, inputs: &DirectInputs) -> Vec<f32> {
    let n = coeff_count(inputs.table.bands);
    sums.par_chunks_mut(n).enumerate().for_each(|(v, row)| {
        let mut wide: Vec<f64> = row.iter().map(|&t| t as f64).collect();
        super::cpu::finish_transfer(inputs, v, &mut wide);
        row.iter_mut().zip(&wide).for_each(|(t, w)| *t = *w as f32);
    });
    sums
}

/// Albedo-free direct transfer `[vertex][k]` and the gather matrix of the closest hits, from
/// one closest-hit traversal per ray on the GPU (interreflected mode).
pub fn direct_transfer_and_gather_matrix(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<(Vec<f32>, GatherMatrix, GpuRun)> {
    let out = run(
        baker,
        inputs,
        Mode::Interreflected,
        chunking,
        false,
        progress,
    )?;
    let matrix = super::bounce::gather_matrix_from_vertex_hits(inputs, &out.hits);
    Ok((scaled(out.sums, inputs), matrix, out.stats))
}

/// Albedo-free direct transfer of every vertex, `[vertex][k]`, computed on the GPU.
pub fn direct_transfer(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    mode: Mode,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<(Vec<f32>, GpuRun)> {
    let out = run(baker, inputs, mode, chunking, false, progress)?;
    Ok((scaled(out.sums, inputs), out.stats))
}

/// The GPU's visibility bits `[vertex][word]` and its transfer, for comparison with
/// `cpu::visibility_bits` ray for ray.
pub fn visibility_bits_and_transfer(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    mode: Mode,
    chunking: Chunking,
) -> Result<(Vec<u32>, Vec<f32>)> {
    let out = run(baker, inputs, mode, chunking, true, &super::NoProgress)?;
    Ok((out.bits, scaled(out.sums, inputs)))
}

/// The gather matrix uploaded for bounce passes: row chunks that fit the adapter's bindings.
pub struct GpuGatherMatrix {
    chunks: Vec<RowChunk>,
    albedo: wgpu::Buffer,
    rows: u32,
    coeffs: u32,
}

struct RowChunk {
    row_offset: u32,
    row_count: u32,
    max_row_len: u32,
    offsets: wgpu::Buffer,
    columns: wgpu::Buffer,
    weights: wgpu::Buffer,
}

impl GpuBaker {
    /// Uploads `matrix` and the albedo for bounces of `bands`-band RGB transfer.
    pub fn upload_gather_matrix(
        &self,
        matrix: &GatherMatrix,
        albedo: &[glam::Vec3],
        bands: u32,
    ) -> Result<GpuGatherMatrix> {
        let ctx = &self.context;
        let coeffs = coeff_count(bands) as u32;
        let per_row = 3 * coeffs as u64;
        let max_binding = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size);
        let max_entries = (max_binding / 4) as usize;
        let max_rows = (ctx.limits.max_compute_workgroups_per_dimension as u64
            * WORKGROUP_SIZE as u64
            / per_row)
            .min(max_binding / (per_row * 4)) as usize;
        let rows = matrix.rows();
        let mut chunks = Vec::new();
        let mut first = 0;
        while first < rows {
            // Grow the chunk while its entries fit one binding.
            let start_entry = matrix.row_offsets[first] as usize;
            let mut last = first + 1;
            while last < rows
                && last - first < max_rows
                && matrix.row_offsets[last + 1] as usize - start_entry <= max_entries
            {
                last += 1;
            }
            let end_entry = matrix.row_offsets[last] as usize;
            if end_entry - start_entry > max_entries {
                return Err(Error::Gpu(format!(
                    "gather row {first} has {} entries, more than one binding holds",
                    end_entry - start_entry
                )));
            }
            let offsets: Vec<u32> = matrix.row_offsets[first..=last]
                .iter()
                .map(|&o| o - start_entry as u32)
                .collect();
            let max_row_len = offsets.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
            chunks.push(RowChunk {
                row_offset: first as u32,
                row_count: (last - first) as u32,
                max_row_len,
                offsets: ctx.storage("gather row offsets", &offsets),
                columns: ctx.storage("gather columns", &matrix.columns[start_entry..end_entry]),
                weights: ctx.storage("gather weights", &matrix.weights[start_entry..end_entry]),
            });
            first = last;
        }
        Ok(GpuGatherMatrix {
            chunks,
            albedo: ctx.storage("albedo", &as_vec4(albedo)),
            rows: rows as u32,
            coeffs,
        })
    }

    /// One bounce on the GPU: `next[p][c][k] = albedo[p][c] sum_j weight_pj previous[j][c][k]`.
    pub fn bounce(&self, matrix: &GpuGatherMatrix, previous: &[f32]) -> Result<Vec<f32>> {
        let ctx = &self.context;
        let per_row = 3 * matrix.coeffs;
        let bytes = matrix.rows as u64 * per_row as u64 * 4;
        let previous = ctx.storage("previous bounce", previous);
        let next = ctx.output("next bounce", bytes);
        let params = ctx.uniform("gather params", &GatherParams::default());
        for chunk in &matrix.chunks {
            let group = ctx.checked("binding the gather buffers", || {
                let buffers = [
                    &params,
                    &chunk.offsets,
                    &chunk.columns,
                    &chunk.weights,
                    &matrix.albedo,
                    &previous,
                    &next,
                ];
                ctx.bind_buffers("gather", &self.gather_layout, &buffers)
            })?;
            let passes = chunk.max_row_len.div_ceil(GATHER_ENTRIES_PER_PASS).max(1);
            for pass_index in 0..passes {
                ctx.queue.write_buffer(
                    &params,
                    0,
                    bytemuck::bytes_of(&GatherParams {
                        row_offset: chunk.row_offset,
                        row_count: chunk.row_count,
                        coeff_count: matrix.coeffs,
                        entry_begin: pass_index * GATHER_ENTRIES_PER_PASS,
                        entry_limit: GATHER_ENTRIES_PER_PASS,
                        accumulate: (pass_index > 0) as u32,
                        pad0: 0,
                        pad1: 0,
                    }),
                );
                ctx.checked("running the gather kernel", || {
                    let mut encoder =
                        ctx.device
                            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                                label: Some("bounce"),
                            });
                    encode_pass(
                        &mut encoder,
                        "gather",
                        &self.gather,
                        &group,
                        [(chunk.row_count * per_row).div_ceil(WORKGROUP_SIZE), 1, 1],
                    );
                    ctx.queue.submit([encoder.finish()]);
                })?;
                ctx.wait()?;
            }
        }
        ctx.read_back(&next, bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::{intersect_box, intersect_triangle, Ray, RAY_T_MAX};
    use crate::sampling::Pcg32;
    use crate::scene::builtin;
    use glam::Vec3;

    fn default_bvh() -> Bvh {
        let scene = builtin::default_scene();
        Bvh::build(&scene.positions, &scene.triangles)
    }

    /// The kernel's traversal (wgsl/bvh.wgsl `trace`), step for step, on the CPU.
    fn gpu_closest_hit(g: &GpuBvh, ray: &Ray, any_hit: bool) -> Option<(u32, f32)> {
        let mut t_max = RAY_T_MAX;
        let mut best = None;
        let mut stack = Vec::new();
        let mut node = 0u32;
        loop {
            let mut descend = false;
            if node & LEAF_FLAG != 0 {
                let mut i = (node & !LEAF_FLAG) as usize;
                loop {
                    let t = &g.triangles[i];
                    let [v0, v1, v2] = t.vertices();
                    if let Some(hit) = intersect_triangle(ray, v0, v1, v2, 0.0, t_max) {
                        best = Some((t.source_index, hit.t));
                        if any_hit {
                            return best;
                        }
                        t_max = hit.t;
                    }
                    if t.pad1 != 0 {
                        break;
                    }
                    i += 1;
                }
            } else {
                let n = &g.nodes[node as usize];
                let test = |q| {
                    let (lo, hi) = g.decode(q);
                    intersect_box(ray, Vec3::from(lo), Vec3::from(hi), 0.0, t_max)
                };
                match (test(n.left_box), test(n.right_box)) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b {
                            (n.left, n.right)
                        } else {
                            (n.right, n.left)
                        };
                        stack.push(far);
                        node = near;
                        descend = true;
                    }
                    (Some(_), None) => (node, descend) = (n.left, true),
                    (None, Some(_)) => (node, descend) = (n.right, true),
                    (None, None) => {}
                }
            }
            if !descend {
                match stack.pop() {
                    Some(next) => node = next,
                    None => return best,
                }
            }
        }
    }

    #[test]
    fn grid_boxes_hold_the_exact_boxes() {
        let bvh = default_bvh();
        let g = GpuBvh::new(&bvh);
        let interior: Vec<_> = bvh.nodes.iter().filter(|n| !n.is_leaf()).collect();
        assert_eq!(interior.len(), g.nodes.len());
        for (n, gn) in interior.iter().zip(&g.nodes) {
            for (child, q) in [
                (n.left_or_first, gn.left_box),
                (n.left_or_first + 1, gn.right_box),
            ] {
                let exact = &bvh.nodes[child as usize];
                let (lo, hi) = g.decode(q);
                for a in 0..3 {
                    assert!(lo[a] <= exact.min[a] && hi[a] >= exact.max[a]);
                    // Rounded outwards by less than two grid steps.
                    assert!(exact.min[a] - lo[a] <= 2.0 * g.grid_step);
                    assert!(hi[a] - exact.max[a] <= 2.0 * g.grid_step);
                }
            }
        }
    }

    #[test]
    fn gpu_layout_traversal_matches_the_cpu_tree() {
        let bvh = default_bvh();
        let g = GpuBvh::new(&bvh);
        let mut rng = Pcg32::new(3);
        let root = &bvh.nodes[0];
        for _ in 0..20_000 {
            let mut r = || rng.next_f32();
            let origin = Vec3::from(root.min)
                + (Vec3::from(root.max) - Vec3::from(root.min)) * Vec3::new(r(), r(), r());
            let direction = (Vec3::new(r(), r(), r()) * 2.0 - 1.0).normalize_or(Vec3::Y);
            let ray = Ray::new(origin, direction);
            assert_eq!(
                gpu_closest_hit(&g, &ray, true).is_some(),
                bvh.occluded(&ray, RAY_T_MAX)
            );
            assert_eq!(
                gpu_closest_hit(&g, &ray, false),
                bvh.closest_hit(&ray, RAY_T_MAX).map(|(i, h)| (i, h.t))
            );
        }
    }

    #[test]
    fn an_empty_or_one_leaf_tree_has_a_gpu_layout() {
        let empty = GpuBvh::new(&Bvh::default());
        assert_eq!(empty.nodes.len(), 1);
        let ray = Ray::new(Vec3::ZERO, Vec3::Y);
        assert_eq!(gpu_closest_hit(&empty, &ray, true), None);
        let one = Bvh::build(
            &[
                Vec3::new(-1.0, 1.0, -1.0),
                Vec3::new(1.0, 1.0, -1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            &[[0, 1, 2]],
        );
        let g = GpuBvh::new(&one);
        assert_eq!(gpu_closest_hit(&g, &ray, false).map(|h| h.0), Some(0));
    }
}
