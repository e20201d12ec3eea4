//! The GPU backend: the CPU backend's two passes as wgpu compute kernels.
//!
//! Split: a horizon pass (wgsl/horizon.wgsl, `horizon.rs`) lists each vertex's samples above
//! its horizon on the device; a visibility pass (wgsl/visibility.wgsl, one invocation per
//! vertex–sample pair, so an invocation traces exactly one ray and stays far below llvmpipe's
//! 65,535-iteration loop cap) writes one bit per ray; a projection pass (wgsl/project.wgsl,
//! one invocation per vertex–coefficient pair) sums cosine-weighted SH over the set bits. The bits are also what
//! tests compare with the CPU ray for ray.
//!
//! Work is cut into chunks of vertices and of samples so that every binding fits the adapter's
//! limits and no submission runs long (real GPUs reset after about two seconds of one dispatch).

use rayon::prelude::*;
use std::time::Instant;

use super::bounce::{GatherMatrix, Hit};
use super::{DirectInputs, Mode, Progress};
use crate::bvh::gpu::{GpuBvh, LEAF_FLAG};
use crate::device::{self, DeviceChoice, GpuContext};
use crate::error::{Error, Result};
use crate::ray::NO_HIT;
use crate::sampling::{DirectionFrame, ReceiverTurns};
use crate::sh::coeff_count;
use crate::shaders::{self, FRAMES_TANGENT, FRAMES_TURNED, FRAMES_WORLD, WORKGROUP_SIZE};

pub mod denoise;
mod division;
mod gather;
mod horizon;
mod kernels;
pub use division::Division;
pub use gather::*;
pub use horizon::HorizonParams;
pub use kernels::*;

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
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuRun {
    pub rays_cast: u64,
    pub submissions: u32,
    pub vertex_chunks: u32,
    pub sample_chunks: u32,
    /// Seconds the host waited for the kernels of its chunks to finish.
    pub kernel_wait_seconds: f64,
    /// Seconds of the whole run, uploads, read-backs and the rest of the host's work included.
    pub run_seconds: f64,
    /// Seconds the horizon, visibility and projection passes took on the device, summed over
    /// the chunks, where the device writes timestamps.
    pub kernel_seconds: Option<[f64; PassTimer::PASSES as usize]>,
}

/// An open device with the bake's kernels compiled (once; compiling is slow on lavapipe).
///
/// Each pipeline's bind-group layout is derived from its kernel's WGSL declarations, so a
/// binding is declared once, in the shader; the host binds buffers in binding order.
pub struct GpuBaker {
    pub context: GpuContext,
    horizon: wgpu::ComputePipeline,
    visibility: wgpu::ComputePipeline,
    project: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    division: Division,
}

impl GpuBaker {
    /// Compiles the kernels, dividing as [`Division::probe`] finds the adapter can.
    pub fn new(context: GpuContext) -> Result<Self> {
        let division = Division::probe(&context)?;
        GpuBaker::dividing(context, division)
    }

    /// Compiles the kernels to divide as `division` says (tests force the emulation).
    pub fn dividing(context: GpuContext, division: Division) -> Result<Self> {
        let ctx = &context;
        let traversal = division.constants();
        let (horizon, visibility, project, gather) =
            ctx.checked("compiling the kernels", || {
                (
                    pipeline_with(ctx, "horizon", shaders::horizon_kernel(), &traversal),
                    pipeline_with(ctx, "visibility", shaders::visibility_kernel(), &traversal),
                    pipeline(ctx, "project", shaders::project_kernel()),
                    pipeline(ctx, "gather", shaders::gather_kernel()),
                )
            })?;
        Ok(GpuBaker {
            context,
            horizon,
            visibility,
            project,
            gather,
            division,
        })
    }

    /// How the traversal kernels divide.
    pub fn division(&self) -> Division {
        self.division
    }

    /// Opens the device for `choice` (see [`device::open`]) and compiles the kernels; `None`
    /// means the CPU backend bakes.
    pub fn open(choice: DeviceChoice, adapter: Option<&str>) -> Result<Option<GpuBaker>> {
        device::open(choice, adapter)?
            .map(GpuBaker::new)
            .transpose()
    }

    /// A bind group for `pipeline` with `buffers` at bindings 0, 1, 2, ... of group 0.
    fn bind(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let layout = pipeline.get_bind_group_layout(0);
        self.context.bind_buffers(label, &layout, buffers)
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
    .expect("a list of seven limits has a least")
    .min(chunking.max_vertices.unwrap_or(u32::MAX) as u64)
    .min(vertices as u64)
    .max(1) as u32;
    (vertex_chunk, sample_chunk.max(32))
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

/// What a run computes: the inputs, and which of the outputs are kept.
struct RunSpec<'i, 'a> {
    inputs: &'i DirectInputs<'a>,
    mode: Mode,
    keep_bits: bool,
    max_steps: u32,
    coeffs: u32,
}

impl RunSpec<'_, '_> {
    fn record_hits(&self) -> bool {
        self.mode == Mode::Interreflected
    }
}

/// One chunk of a run: vertices `vertex_offset..+vertices`, samples `sample_offset..+samples`.
#[derive(Clone, Copy, Debug)]
struct Chunk {
    vertex_offset: u32,
    vertices: u32,
    sample_offset: u32,
    samples: u32,
    /// Later sample chunks of the same vertices add to the projected sums.
    accumulate: bool,
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
    let spec = RunSpec {
        inputs,
        mode,
        keep_bits,
        max_steps: chunking.max_steps.unwrap_or(MAX_TRAVERSAL_STEPS),
        coeffs: coeff_count(inputs.table.bands) as u32,
    };
    let vertex_count = inputs.origins.len() as u32;
    let sample_count = inputs.samples.len() as u32;
    let (vertex_chunk, sample_chunk) = plan_chunks(
        ctx,
        vertex_count,
        sample_count,
        spec.coeffs,
        spec.record_hits(),
        chunking,
    );
    let started = Instant::now();
    let gpu_bvh = GpuBvh::new(inputs.bvh);
    check_bindings(ctx, inputs, &gpu_bvh)?;
    let buffers = RunBuffers::new(baker, &spec, &gpu_bvh, vertex_chunk, sample_chunk)?;
    let mut out = RunOutput::empty(&spec);
    for vertex_offset in (0..vertex_count).step_by(vertex_chunk as usize) {
        let vertices = vertex_chunk.min(vertex_count - vertex_offset);
        out.stats.vertex_chunks += 1;
        for (index, sample_offset) in (0..sample_count).step_by(sample_chunk as usize).enumerate() {
            let chunk = Chunk {
                vertex_offset,
                vertices,
                sample_offset,
                samples: sample_chunk.min(sample_count - sample_offset),
                accumulate: index > 0,
            };
            out.stats.sample_chunks += (vertex_offset == 0) as u32;
            buffers.dispatch(baker, &spec, chunk, &mut out.stats)?;
            out.collect_chunk(ctx, &spec, &buffers, chunk)?;
        }
        let chunk_sums: Vec<f32> =
            ctx.read_back(&buffers.transfer, vertices as u64 * spec.coeffs as u64 * 4)?;
        let first = vertex_offset as usize * spec.coeffs as usize;
        out.sums[first..][..chunk_sums.len()].copy_from_slice(&chunk_sums);
        progress.advance(vertices as u64);
    }
    buffers.check_no_ray_exhausted(ctx, spec.max_steps)?;
    if mode != Mode::Unshadowed {
        out.stats.rays_cast = buffers.samples_listed(ctx)?;
    }
    out.stats.run_seconds = started.elapsed().as_secs_f64();
    Ok(out)
}

/// Fails early when a whole-run array does not fit one storage binding of the adapter.
fn check_bindings(ctx: &GpuContext, inputs: &DirectInputs, gpu_bvh: &GpuBvh) -> Result<()> {
    let needs_binding = |name: &str, bytes: u64| -> Result<()> {
        if bytes > ctx.limits.max_storage_buffer_binding_size {
            return Err(Error::Gpu(format!(
                "{name} needs {bytes} bytes, more than {}'s storage binding limit of {} bytes",
                ctx.adapter.name, ctx.limits.max_storage_buffer_binding_size
            )));
        }
        Ok(())
    };
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
    needs_binding("the SH table", (inputs.table.values.len() * 4) as u64)
}

/// The device buffers of one run, sized for its chunks, and the two passes' bind groups.
struct RunBuffers {
    bits: wgpu::Buffer,
    transfer: wgpu::Buffer,
    exhausted: wgpu::Buffer,
    hits: wgpu::Buffer,
    /// The horizon pass's buffers; the visibility pass reads its sample lists and is sized
    /// by its workgroup counts.
    horizon: horizon::HorizonBuffers,
    visibility_params: wgpu::Buffer,
    project_params: wgpu::Buffer,
    horizon_group: wgpu::BindGroup,
    visibility_group: wgpu::BindGroup,
    project_group: wgpu::BindGroup,
    grid_origin: [f32; 3],
    grid_step: f32,
    /// Bit words per vertex row of a chunk.
    chunk_words: u32,
    timer: Option<PassTimer>,
}

impl RunBuffers {
    fn new(
        baker: &GpuBaker,
        spec: &RunSpec,
        gpu_bvh: &GpuBvh,
        vertex_chunk: u32,
        sample_chunk: u32,
    ) -> Result<RunBuffers> {
        let ctx = &baker.context;
        let inputs = spec.inputs;
        let chunk_words = sample_chunk / 32;
        let rows = vertex_chunk as u64;
        let pairs = rows * sample_chunk as u64;
        let nodes = ctx.storage("bvh nodes", &gpu_bvh.nodes);
        let triangles = ctx.storage("bvh triangles", &gpu_bvh.triangles);
        let origins = ctx.storage("origins", &as_vec4(inputs.origins));
        let normals = ctx.storage("normals", &as_vec4(inputs.normals));
        let directions = ctx.storage("directions", &as_vec4(&inputs.samples.directions));
        let sh_table = ctx.storage("sh table", &inputs.table.values);
        let bits = ctx.output("visibility bits", rows * chunk_words as u64 * 4);
        let transfer = ctx.output("transfer", rows * spec.coeffs as u64 * 4);
        let exhausted = ctx.output("exhausted rays", 4);
        // Every pair's closest hit; one placeholder where no hit is recorded.
        let hits = ctx.output(
            "hits",
            std::mem::size_of::<Hit>() as u64 * if spec.record_hits() { pairs } else { 1 },
        );
        let horizon = horizon::buffers(ctx, pairs, inputs.samples, sample_chunk);
        let visibility_params = ctx.uniform("visibility params", &VisibilityParams::default());
        let project_params = ctx.uniform("project params", &ProjectParams::default());

        let (horizon_group, visibility_group, project_group) =
            ctx.checked("binding the buffers", || {
                (
                    baker.bind(
                        "horizon",
                        &baker.horizon,
                        &[
                            &horizon.params,
                            &triangles,
                            &normals,
                            &directions,
                            &horizon.sample_lists,
                            &horizon.listed,
                            &horizon.visibility_groups,
                            &hits,
                            &horizon.listing_order,
                        ],
                    ),
                    baker.bind(
                        "visibility",
                        &baker.visibility,
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
                            &horizon.sample_lists,
                        ],
                    ),
                    baker.bind(
                        "project",
                        &baker.project,
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
        Ok(RunBuffers {
            bits,
            transfer,
            exhausted,
            hits,
            horizon,
            visibility_params,
            project_params,
            horizon_group,
            visibility_group,
            project_group,
            grid_origin: gpu_bvh.grid_origin,
            grid_step: gpu_bvh.grid_step,
            chunk_words,
            timer: PassTimer::new(ctx),
        })
    }

    /// Sets the chunk's parameters, runs the horizon, visibility and projection passes on it
    /// and waits.
    fn dispatch(
        &self,
        baker: &GpuBaker,
        spec: &RunSpec,
        chunk: Chunk,
        stats: &mut GpuRun,
    ) -> Result<()> {
        let ctx = &baker.context;
        let inputs = spec.inputs;
        let (frames, turns) = frame_params(inputs);
        let horizon = HorizonParams {
            vertex_offset: chunk.vertex_offset,
            vertex_count: chunk.vertices,
            sample_offset: chunk.sample_offset,
            sample_count: chunk.samples,
            frames,
            record_hits: spec.record_hits() as u32,
            turn_seed: turns.seed,
            turn_first: turns.first,
        };
        ctx.queue
            .write_buffer(&self.horizon.params, 0, bytemuck::bytes_of(&horizon));
        // The horizon pass raises x to the longest list's workgroups.
        ctx.queue.write_buffer(
            &self.horizon.visibility_groups,
            0,
            bytemuck::cast_slice(&[0, chunk.vertices, 1]),
        );
        let visibility = VisibilityParams {
            vertex_offset: chunk.vertex_offset,
            vertex_count: chunk.vertices,
            sample_offset: chunk.sample_offset,
            sample_count: chunk.samples,
            words_per_vertex: self.chunk_words,
            max_steps: spec.max_steps,
            shadowed: (spec.mode != Mode::Unshadowed) as u32,
            record_hits: spec.record_hits() as u32,
            grid_origin: self.grid_origin,
            grid_step: self.grid_step,
            frames,
            turn_seed: turns.seed,
            turn_first: turns.first,
            ..Default::default()
        };
        let project = ProjectParams {
            vertex_offset: chunk.vertex_offset,
            vertex_count: chunk.vertices,
            sample_offset: chunk.sample_offset,
            sample_count: chunk.samples,
            // The row stride of the bits; words past the chunk's samples are zero.
            words_per_vertex: self.chunk_words,
            coeff_count: spec.coeffs,
            accumulate: chunk.accumulate as u32,
            estimator: estimator_flags(inputs.estimator, inputs.samples.frame),
        };
        ctx.queue
            .write_buffer(&self.visibility_params, 0, bytemuck::bytes_of(&visibility));
        ctx.queue
            .write_buffer(&self.project_params, 0, bytemuck::bytes_of(&project));
        ctx.checked("running the kernels", || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("bake chunk"),
                });
            self.encode_passes(&mut encoder, baker, spec.coeffs, chunk.vertices);
            ctx.queue.submit([encoder.finish()]);
        })?;
        let waiting = Instant::now();
        ctx.wait()?;
        stats.kernel_wait_seconds += waiting.elapsed().as_secs_f64();
        if let Some(timer) = &self.timer {
            let seconds = timer.seconds(ctx)?;
            let summed = stats.kernel_seconds.get_or_insert(Default::default());
            for (sum, pass) in summed.iter_mut().zip(seconds) {
                *sum += pass;
            }
        }
        stats.submissions += 1;
        Ok(())
    }

    /// Records a chunk's passes over `vertices` vertices (its parameters written): the bits
    /// cleared, then the horizon, visibility and projection passes, timed where the device
    /// writes timestamps.
    fn encode_passes(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        baker: &GpuBaker,
        coeffs: u32,
        vertices: u32,
    ) {
        encoder.clear_buffer(&self.bits, 0, None);
        let writes = |pass| self.timer.as_ref().map(|timer| timer.writes(pass));
        encode_timed_pass(
            encoder,
            ("horizon", &baker.horizon, &self.horizon_group),
            Dispatch::Direct([1, vertices, 1]),
            writes(0),
        );
        encode_timed_pass(
            encoder,
            ("visibility", &baker.visibility, &self.visibility_group),
            Dispatch::Indirect(&self.horizon.visibility_groups),
            writes(1),
        );
        encode_timed_pass(
            encoder,
            ("project", &baker.project, &self.project_group),
            Dispatch::Direct([(vertices * coeffs).div_ceil(WORKGROUP_SIZE), 1, 1]),
            writes(2),
        );
        if let Some(timer) = &self.timer {
            timer.resolve(encoder);
        }
    }

    /// The samples the horizon pass listed over the run: the rays a shadowed run cast.
    fn samples_listed(&self, ctx: &GpuContext) -> Result<u64> {
        let words: Vec<u32> = ctx.read_back(&self.horizon.listed, 8)?;
        Ok(words[0] as u64 | (words[1] as u64) << 32)
    }

    /// The error a run must end with when any ray ran out of traversal steps.
    fn check_no_ray_exhausted(&self, ctx: &GpuContext, max_steps: u32) -> Result<()> {
        let exhausted_rays: Vec<u32> = ctx.read_back(&self.exhausted, 4)?;
        if exhausted_rays[0] > 0 {
            return Err(Error::Gpu(format!(
                "{} rays needed more than {max_steps} traversal steps; the GPU result would be \
                 wrong (use --device cpu)",
                exhausted_rays[0]
            )));
        }
        Ok(())
    }
}

impl RunOutput {
    fn empty(spec: &RunSpec) -> RunOutput {
        let vertices = spec.inputs.origins.len();
        let words = spec.inputs.samples.len().div_ceil(32);
        RunOutput {
            sums: vec![0.0; vertices * spec.coeffs as usize],
            bits: if spec.keep_bits {
                vec![0; vertices * words]
            } else {
                Vec::new()
            },
            hits: if spec.record_hits() {
                vec![Vec::new(); vertices]
            } else {
                Vec::new()
            },
            stats: GpuRun::default(),
        }
    }

    /// Reads back what the run keeps of a finished chunk: its bits and its hits.
    fn collect_chunk(
        &mut self,
        ctx: &GpuContext,
        spec: &RunSpec,
        buffers: &RunBuffers,
        chunk: Chunk,
    ) -> Result<()> {
        let samples = chunk.samples as usize;
        if spec.keep_bits {
            let chunk_words = buffers.chunk_words as usize;
            let chunk_bits: Vec<u32> = ctx.read_back(
                &buffers.bits,
                chunk.vertices as u64 * chunk_words as u64 * 4,
            )?;
            let total_words = spec.inputs.samples.len().div_ceil(32);
            let first_word = (chunk.sample_offset / 32) as usize;
            let words = samples.div_ceil(32);
            for v in 0..chunk.vertices as usize {
                let row = (chunk.vertex_offset as usize + v) * total_words + first_word;
                self.bits[row..row + words]
                    .copy_from_slice(&chunk_bits[v * chunk_words..][..words]);
            }
        }
        if spec.record_hits() {
            let hit_size = std::mem::size_of::<Hit>() as u64;
            let chunk_hits: Vec<Hit> = ctx.read_back(
                &buffers.hits,
                chunk.vertices as u64 * chunk.samples as u64 * hit_size,
            )?;
            // Every sample's hit was written: NO_HIT below the horizon (the horizon pass), the
            // closest hit or NO_HIT above it (the visibility pass).
            for (v, row) in chunk_hits.chunks(samples).enumerate() {
                let own = &mut self.hits[chunk.vertex_offset as usize + v];
                for (s, &hit) in row.iter().enumerate() {
                    if hit.triangle != NO_HIT {
                        own.push((chunk.sample_offset + s as u32, hit));
                    }
                }
            }
        }
        Ok(())
    }
}

/// The kernels' `frames` flag for the inputs' sample set, and the turns they read with it.
fn frame_params(inputs: &DirectInputs) -> (u32, ReceiverTurns) {
    let frames = match (inputs.samples.frame, inputs.turns) {
        (DirectionFrame::World, _) => FRAMES_WORLD,
        (DirectionFrame::Tangent, None) => FRAMES_TANGENT,
        (DirectionFrame::Tangent, Some(_)) => FRAMES_TURNED,
    };
    let turns = inputs.turns.unwrap_or(ReceiverTurns { seed: 0, first: 0 });
    (frames, turns)
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
    let out = closest_hit_run(baker, inputs, chunking, progress)?;
    let matrix = super::bounce::gather_matrix_from_vertex_hits(inputs, &out.hits);
    Ok((scaled(out.sums, inputs), matrix, out.stats))
}

/// The projected sums of every vertex's shadowed visibility, `[vertex][k]`, before
/// `cpu::finish_transfer`, and its gather row, from one closest-hit pass: what an
/// interreflected bake to an error target adds up batch by batch.
pub fn projected_sums_and_gather_rows(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<(Vec<f32>, super::bounce::GatherRows, GpuRun)> {
    let out = closest_hit_run(baker, inputs, chunking, progress)?;
    let rows = super::bounce::gather_rows(inputs, &out.hits);
    Ok((out.sums, rows, out.stats))
}

/// The closest hit of every ray that hits something, `(sample, hit)` per receiver, from the
/// closest-hit pass (what interreflection gathers from; local lights' depth maps measure it).
pub fn closest_hits(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<Vec<Vec<(u32, Hit)>>> {
    Ok(closest_hit_run(baker, inputs, chunking, progress)?.hits)
}

/// Both passes with the closest-hit traversal, the hits kept.
fn closest_hit_run(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<RunOutput> {
    let mode = Mode::Interreflected;
    run(baker, inputs, mode, chunking, false, progress)
}

/// The projected sums of every vertex, `[vertex][k]`, before `cpu::finish_transfer`,
/// computed on the GPU: what an error-targeted bake adds up batch by batch.
pub fn projected_sums(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    mode: Mode,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<(Vec<f32>, GpuRun)> {
    let out = run(baker, inputs, mode, chunking, false, progress)?;
    Ok((out.sums, out.stats))
}

/// Albedo-free direct transfer of every vertex, `[vertex][k]`, computed on the GPU.
pub fn direct_transfer(
    baker: &GpuBaker,
    inputs: &DirectInputs,
    mode: Mode,
    chunking: Chunking,
    progress: &dyn Progress,
) -> Result<(Vec<f32>, GpuRun)> {
    let (sums, stats) = projected_sums(baker, inputs, mode, chunking, progress)?;
    Ok((scaled(sums, inputs), stats))
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
