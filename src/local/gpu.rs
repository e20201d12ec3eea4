//! The compressed direct-to-indirect operator on the GPU: the operator uploaded once (its
//! responses in runs of receiver clusters that each fit a storage binding), then per frame the
//! irradiance uploaded, the projection (`wgsl/compressed_project.wgsl`, passes of at most
//! [`TERMS_PER_PASS`] members), per run the responses (`wgsl/compressed_respond.wgsl`, passes
//! of at most [`TERMS_PER_PASS`] terms), the indirect radiance read back.
//! CPU twin: local::operator::CompressedOperator::indirect.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::operator::CompressedOperator;
use crate::bake::gpu::{encode_pass, pipeline, GpuBaker};
use crate::error::{Error, Result};
use crate::shaders::{self, WORKGROUP_SIZE};

/// Uniforms of both compressed-operator kernels, 32 bytes; WGSL twin in
/// wgsl/compressed_common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CompressedParams {
    pub clusters: u32,
    pub components: u32,
    pub members: u32,
    pub entry_begin: u32,
    pub entry_limit: u32,
    pub accumulate: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// Terms one invocation sums in one pass (its loop count), far below llvmpipe's cap.
pub const TERMS_PER_PASS: u32 = 16_384;

/// The operator on the device, ready for frames.
pub struct GpuCompressed<'b> {
    baker: &'b GpuBaker,
    project: wgpu::ComputePipeline,
    respond: wgpu::ComputePipeline,
    /// members, offsets, means, bases (the projection's inputs besides the irradiance).
    projection_inputs: [wgpu::Buffer; 4],
    /// terms, term_offsets, mean_response (every chunk's).
    response_inputs: [wgpu::Buffer; 3],
    /// Receiver clusters in runs whose responses fit one storage binding.
    chunks: Vec<ResponseChunk>,
    clusters: u32,
    components: u32,
    members: u32,
    largest_cluster: u32,
    /// Terms per pass ([`TERMS_PER_PASS`]; smaller in tests, to exercise the passes that add).
    pub terms_per_pass: u32,
}

/// A run of receiver clusters: its members' info and its responses.
struct ResponseChunk {
    member_info: wgpu::Buffer,
    responses: wgpu::Buffer,
    members: u32,
    widest_row: u32,
}

/// Runs of receiver clusters `[first, end)` whose responses take at most `max_floats` each.
fn chunk_clusters(op: &CompressedOperator, max_floats: u64) -> Result<Vec<(usize, usize)>> {
    let offsets = &op.response_offsets;
    let mut runs = Vec::new();
    let mut first = 0;
    while first < op.clusters() {
        let mut end = first;
        while end < op.clusters() && offsets[end + 1] - offsets[first] <= max_floats {
            end += 1;
        }
        if end == first {
            return Err(Error::Gpu(format!(
                "receiver cluster {first}'s responses ({} MB) exceed one storage binding \
                 ({} MB) on this adapter",
                4 * (offsets[first + 1] - offsets[first]) / 1_000_000,
                4 * max_floats / 1_000_000
            )));
        }
        runs.push((first, end));
        first = end;
    }
    Ok(runs)
}

/// Per member of clusters `[first, end)`: its receiver, its cluster and where its responses
/// start within the run's.
fn member_info(op: &CompressedOperator, first: usize, end: usize) -> Vec<[u32; 4]> {
    let base = op.response_offsets[first];
    let mut info = Vec::new();
    for r in first..end {
        let width = 3 * (op.term_offsets[r + 1] - op.term_offsets[r]) as u64;
        for (i, &p) in op.cluster_members(r).iter().enumerate() {
            let start = op.response_offsets[r] - base + i as u64 * width;
            info.push([p, r as u32, start as u32, 0]);
        }
    }
    info
}

impl<'b> GpuCompressed<'b> {
    /// Uploads the operator, its responses in runs that fit the adapter's storage bindings.
    pub fn new(baker: &'b GpuBaker, op: &CompressedOperator) -> Result<Self> {
        let limits = &baker.context.limits;
        let max_binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        Self::with_binding_limit(baker, op, max_binding)
    }

    /// [`Self::new`] with responses split into runs of at most `max_binding` bytes (tests
    /// use a small one to exercise the runs); indices stay within u32.
    pub fn with_binding_limit(
        baker: &'b GpuBaker,
        op: &CompressedOperator,
        max_binding: u64,
    ) -> Result<Self> {
        let ctx = &baker.context;
        let max_floats = (max_binding / 4).min(u32::MAX as u64);
        let chunks = chunk_clusters(op, max_floats)?
            .into_iter()
            .map(|(first, end)| ResponseChunk {
                member_info: ctx.storage("operator member info", &member_info(op, first, end)),
                responses: ctx.storage(
                    "operator responses",
                    &op.responses
                        [op.response_offsets[first] as usize..op.response_offsets[end] as usize],
                ),
                members: op.offsets[end] - op.offsets[first],
                widest_row: (first..end)
                    .map(|r| op.term_offsets[r + 1] - op.term_offsets[r])
                    .max()
                    .unwrap_or(0),
            })
            .collect();
        let (project, respond) =
            ctx.checked("compiling the compressed-operator kernels", || {
                (
                    pipeline(
                        ctx,
                        "compressed project",
                        shaders::compressed_project_kernel(),
                    ),
                    pipeline(
                        ctx,
                        "compressed respond",
                        shaders::compressed_respond_kernel(),
                    ),
                )
            })?;
        let mean_response: Vec<f32> = op.mean_response.iter().flat_map(|v| v.to_array()).collect();
        let largest_cluster = (0..op.clusters())
            .map(|c| op.offsets[c + 1] - op.offsets[c])
            .max()
            .unwrap_or(0);
        Ok(GpuCompressed {
            baker,
            project,
            respond,
            projection_inputs: [
                ctx.storage("operator members", &op.members),
                ctx.storage("operator offsets", &op.offsets),
                ctx.storage("operator means", &op.means),
                ctx.storage("operator bases", &op.bases),
            ],
            response_inputs: [
                ctx.storage("operator terms", &op.terms),
                ctx.storage("operator term offsets", &op.term_offsets),
                ctx.storage("operator mean response", &mean_response),
            ],
            chunks,
            clusters: op.clusters() as u32,
            components: op.components as u32,
            members: op.members.len() as u32,
            largest_cluster,
            terms_per_pass: TERMS_PER_PASS,
        })
    }

    /// How many runs the responses are uploaded in.
    pub fn response_runs(&self) -> usize {
        self.chunks.len()
    }

    /// Indirect radiance per receiver for `irradiance`, as [`CompressedOperator::indirect`].
    pub fn indirect(&self, irradiance: &[f32]) -> Result<Vec<Vec3>> {
        let ctx = &self.baker.context;
        if irradiance.len() != self.members as usize {
            return Err(Error::Gpu(format!(
                "{} irradiance values for an operator of {} receivers",
                irradiance.len(),
                self.members
            )));
        }
        let coordinates_count = (self.clusters * self.components).max(1);
        let irradiance = ctx.storage("frame irradiance", irradiance);
        let coordinates = ctx.output("operator coordinates", 4 * coordinates_count as u64);
        let bytes = 4 * 3 * self.members as u64;
        let indirect = ctx.output("indirect radiance", bytes);
        let uniform = ctx.uniform("compressed params", &CompressedParams::default());
        let [members, offsets, means, bases] = &self.projection_inputs;
        let project_group = ctx.checked("binding the projection buffers", || {
            let buffers = [
                &uniform,
                members,
                offsets,
                means,
                bases,
                &irradiance,
                &coordinates,
            ];
            ctx.bind_buffers(
                "compressed project",
                &self.project.get_bind_group_layout(0),
                &buffers,
            )
        })?;
        for pass in 0..self.passes(self.largest_cluster) {
            let params = self.params(self.members, pass);
            self.run_pass(
                &self.project,
                &project_group,
                &uniform,
                &params,
                coordinates_count,
            )?;
        }
        let [terms, term_offsets, mean_response] = &self.response_inputs;
        for chunk in &self.chunks {
            let respond_group = ctx.checked("binding the response buffers", || {
                let buffers = [
                    &uniform,
                    &chunk.member_info,
                    terms,
                    term_offsets,
                    &chunk.responses,
                    mean_response,
                    &coordinates,
                    &indirect,
                ];
                let layout = self.respond.get_bind_group_layout(0);
                ctx.bind_buffers("compressed respond", &layout, &buffers)
            })?;
            for pass in 0..self.passes(chunk.widest_row) {
                let params = self.params(chunk.members, pass);
                self.run_pass(
                    &self.respond,
                    &respond_group,
                    &uniform,
                    &params,
                    3 * chunk.members,
                )?;
            }
        }
        let values: Vec<f32> = ctx.read_back(&indirect, bytes)?;
        Ok(values
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect())
    }

    /// Passes for loops of up to `longest` terms.
    fn passes(&self, longest: u32) -> u32 {
        longest.div_ceil(self.terms_per_pass.max(1)).max(1)
    }

    /// The uniforms of pass `pass` over `members` members, adding to the passes before.
    fn params(&self, members: u32, pass: u32) -> CompressedParams {
        let per_pass = self.terms_per_pass.max(1);
        CompressedParams {
            clusters: self.clusters,
            components: self.components,
            members,
            entry_begin: pass * per_pass,
            entry_limit: per_pass,
            accumulate: (pass > 0) as u32,
            pad0: 0,
            pad1: 0,
        }
    }

    /// One pass of a kernel with `params`, `invocations` invocations.
    fn run_pass(
        &self,
        kernel: &wgpu::ComputePipeline,
        group: &wgpu::BindGroup,
        uniform: &wgpu::Buffer,
        params: &CompressedParams,
        invocations: u32,
    ) -> Result<()> {
        let ctx = &self.baker.context;
        ctx.queue
            .write_buffer(uniform, 0, bytemuck::bytes_of(params));
        ctx.checked("running the compressed-operator kernels", || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("compressed operator"),
                });
            let groups = invocations.div_ceil(WORKGROUP_SIZE);
            encode_pass(
                &mut encoder,
                "compressed operator",
                kernel,
                group,
                [groups, 1, 1],
            );
            ctx.queue.submit([encoder.finish()]);
        })?;
        ctx.wait()
    }
}
