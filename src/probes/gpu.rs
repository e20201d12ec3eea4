//! Relighting probes on the GPU: the matrices uploaded once, then per frame the light
//! uploaded, one invocation per (probe, row) (`wgsl/probes_relight.wgsl`, in dispatches of at
//! most [`PROBES_PER_DISPATCH`] probes), the relit SH read back. CPU twin:
//! `probes::ProbeSet::relight`.

use bytemuck::{Pod, Zeroable};

use super::ProbeSet;
use crate::bake::gpu::{encode_pass, pipeline};
use crate::device::GpuContext;
use crate::error::{Error, Result};
use crate::sh::coeff_count;
use crate::shaders::{self, WORKGROUP_SIZE};

/// The relighting kernel's uniforms, 32 bytes; WGSL twin in wgsl/probes_relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ProbeRelightParams {
    pub probes: u32,
    pub rows: u32,
    pub coeffs: u32,
    pub channels: u32,
    pub first_probe: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// Probes one dispatch relights: its invocations (probes x rows, at most 1,024 rows) stay
/// within 65,535 workgroups.
pub const PROBES_PER_DISPATCH: u32 = 4096;

/// A probe set on the device, ready for frames.
pub struct GpuProbes<'c> {
    context: &'c GpuContext,
    kernel: wgpu::ComputePipeline,
    matrices: wgpu::Buffer,
    params: ProbeRelightParams,
}

impl<'c> GpuProbes<'c> {
    /// Uploads `probes`' matrices; refuses a set larger than one storage binding.
    pub fn new(context: &'c GpuContext, probes: &ProbeSet) -> Result<GpuProbes<'c>> {
        let bytes = 4 * probes.matrices.len() as u64;
        let limits = &context.limits;
        let max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if bytes > max {
            return Err(Error::Gpu(format!(
                "{} probes take {bytes} bytes of matrices; the adapter binds at most {max}",
                probes.len()
            )));
        }
        let kernel = context.checked("compiling the probe relighting kernel", || {
            pipeline(context, "probes relight", shaders::probes_relight_kernel())
        })?;
        Ok(GpuProbes {
            context,
            kernel,
            // A binding may not be empty.
            matrices: context.storage("probe matrices", &padded(&probes.matrices)),
            params: ProbeRelightParams {
                probes: probes.len() as u32,
                rows: probes.rows as u32,
                coeffs: coeff_count(probes.bands) as u32,
                channels: probes.channels,
                ..ProbeRelightParams::default()
            },
        })
    }

    /// Every probe relit by `light` (`[k]` RGB, at least the probes' coefficients), as
    /// [`ProbeSet::relight`]: `[probe][row]` RGB.
    pub fn relight(&self, light: &[[f32; 3]]) -> Result<Vec<[f32; 3]>> {
        let ctx = self.context;
        if self.params.probes == 0 {
            return Ok(Vec::new());
        }
        let coeffs = self.params.coeffs as usize;
        if light.len() < coeffs {
            return Err(Error::Gpu(format!(
                "a light of {} coefficients for probes of {coeffs}",
                light.len()
            )));
        }
        let light: Vec<f32> = light[..coeffs].iter().flatten().copied().collect();
        let light = ctx.storage("probe light", &light);
        let values = self.params.probes as u64 * self.params.rows as u64 * 3;
        let relit = ctx.output("relit probes", 4 * values);
        let uniform = ctx.uniform("probe relight params", &self.params);
        let group = ctx.checked("binding the probe relighting buffers", || {
            let buffers = [&uniform, &self.matrices, &light, &relit];
            let layout = self.kernel.get_bind_group_layout(0);
            ctx.bind_buffers("probes relight", &layout, &buffers)
        })?;
        for first_probe in (0..self.params.probes).step_by(PROBES_PER_DISPATCH as usize) {
            let params = ProbeRelightParams {
                first_probe,
                ..self.params
            };
            ctx.queue
                .write_buffer(&uniform, 0, bytemuck::bytes_of(&params));
            let probes = PROBES_PER_DISPATCH.min(self.params.probes - first_probe);
            let groups = (probes * self.params.rows).div_ceil(WORKGROUP_SIZE);
            ctx.checked("relighting probes", || {
                let mut encoder =
                    ctx.device
                        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                            label: Some("probes relight"),
                        });
                encode_pass(
                    &mut encoder,
                    "probes relight",
                    &self.kernel,
                    &group,
                    [groups, 1, 1],
                );
                ctx.queue.submit([encoder.finish()]);
            })?;
            ctx.wait()?;
        }
        let values: Vec<f32> = ctx.read_back(&relit, 4 * values)?;
        Ok(values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }
}

/// `values`, or one zero where there are none.
fn padded(values: &[f32]) -> Vec<f32> {
    if values.is_empty() {
        vec![0.0]
    } else {
        values.to_vec()
    }
}
