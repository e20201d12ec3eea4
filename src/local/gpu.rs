//! The compressed direct-to-indirect operator on the GPU: the operator uploaded once, then per
//! frame the irradiance uploaded, one projection pass per cluster chunk of members
//! (`wgsl/compressed_project.wgsl`) and one response pass per chunk of kept terms
//! (`wgsl/compressed_respond.wgsl`), the indirect radiance read back.
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
    /// member_info, terms, term_offsets, responses, mean_response.
    response_inputs: [wgpu::Buffer; 5],
    clusters: u32,
    components: u32,
    members: u32,
    largest_cluster: u32,
    widest_row: u32,
    /// Terms per pass ([`TERMS_PER_PASS`]; smaller in tests, to exercise the passes that add).
    pub terms_per_pass: u32,
}

/// Per member (in `members` order): its receiver, its cluster and where its responses start.
fn member_info(op: &CompressedOperator) -> Result<Vec<[u32; 4]>> {
    let mut info = Vec::with_capacity(op.members.len());
    for r in 0..op.clusters() {
        let width = 3 * (op.term_offsets[r + 1] - op.term_offsets[r]) as u64;
        for (i, &p) in op.cluster_members(r).iter().enumerate() {
            let start = op.response_offsets[r] + i as u64 * width;
            let start = u32::try_from(start).map_err(|_| {
                Error::Gpu("the compressed operator's responses exceed 2^32 floats".into())
            })?;
            info.push([p, r as u32, start, 0]);
        }
    }
    Ok(info)
}

impl<'b> GpuCompressed<'b> {
    pub fn new(baker: &'b GpuBaker, op: &CompressedOperator) -> Result<Self> {
        let ctx = &baker.context;
        let max_binding = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size);
        if 4 * op.responses.len() as u64 > max_binding {
            return Err(Error::Gpu(format!(
                "the compressed operator's responses ({} MB) exceed one storage binding \
                 ({} MB) on this adapter",
                4 * op.responses.len() / 1_000_000,
                max_binding / 1_000_000
            )));
        }
        let info = member_info(op)?;
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
        let widest_row = (0..op.clusters())
            .map(|r| op.term_offsets[r + 1] - op.term_offsets[r])
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
                ctx.storage("operator member info", &info),
                ctx.storage("operator terms", &op.terms),
                ctx.storage("operator sender offsets", &op.term_offsets),
                ctx.storage("operator responses", &op.responses),
                ctx.storage("operator mean response", &mean_response),
            ],
            clusters: op.clusters() as u32,
            components: op.components as u32,
            members: op.members.len() as u32,
            largest_cluster,
            widest_row,
            terms_per_pass: TERMS_PER_PASS,
        })
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
        let params = ctx.uniform("compressed params", &CompressedParams::default());
        let [members, offsets, means, bases] = &self.projection_inputs;
        let project_group = ctx.checked("binding the projection buffers", || {
            let buffers = [
                &params,
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
        let [info, terms, term_offsets, responses, mean_response] = &self.response_inputs;
        let respond_group = ctx.checked("binding the response buffers", || {
            let buffers = [
                &params,
                info,
                terms,
                term_offsets,
                responses,
                mean_response,
                &coordinates,
                &indirect,
            ];
            ctx.bind_buffers(
                "compressed respond",
                &self.respond.get_bind_group_layout(0),
                &buffers,
            )
        })?;
        let kernels = [
            (
                &self.project,
                &project_group,
                coordinates_count,
                self.largest_cluster,
            ),
            (
                &self.respond,
                &respond_group,
                3 * self.members,
                self.widest_row,
            ),
        ];
        for (kernel, group, invocations, longest) in kernels {
            for pass in 0..longest.div_ceil(self.terms_per_pass.max(1)).max(1) {
                self.run_pass(kernel, group, &params, invocations, pass)?;
            }
        }
        let values: Vec<f32> = ctx.read_back(&indirect, bytes)?;
        Ok(values
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect())
    }

    /// One pass of a kernel over terms `pass * terms_per_pass ..`, adding to the passes before.
    fn run_pass(
        &self,
        kernel: &wgpu::ComputePipeline,
        group: &wgpu::BindGroup,
        params: &wgpu::Buffer,
        invocations: u32,
        pass: u32,
    ) -> Result<()> {
        let ctx = &self.baker.context;
        ctx.queue.write_buffer(
            params,
            0,
            bytemuck::bytes_of(&CompressedParams {
                clusters: self.clusters,
                components: self.components,
                members: self.members,
                entry_begin: pass * self.terms_per_pass.max(1),
                entry_limit: self.terms_per_pass.max(1),
                accumulate: (pass > 0) as u32,
                pad0: 0,
                pad1: 0,
            }),
        );
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
