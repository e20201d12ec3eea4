//! Lightmap denoising on the GPU (`wgsl/denoise.wgsl`): the filter of
//! `receivers::denoise`, in bands of rows whose image and guide (the band and the rows its
//! footprint reaches) fit one binding, each texel's coefficients in groups of
//! [`COEFFS_PER_INVOCATION`].

use super::*;
use crate::receivers::denoise::{DenoiseGuide, DENOISE_RADIUS};
use crate::shaders::{denoise_kernel, COEFFS_PER_INVOCATION};
use bytemuck::{Pod, Zeroable};

/// Uniforms of the denoising kernel, 32 bytes; WGSL twin in wgsl/denoise.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DenoiseParams {
    pub width: u32,
    pub height: u32,
    /// Floats per texel.
    pub stride: u32,
    /// The rows the pass writes.
    pub row_first: u32,
    pub row_count: u32,
    /// The first row the guide and image buffers hold.
    pub input_row_first: u32,
    pub texel_length: f32,
    pub pad0: u32,
}

/// [`crate::receivers::denoise::denoise`] on `baker`'s device.
pub fn denoise(
    baker: &GpuBaker,
    guide: &DenoiseGuide,
    image: &[f32],
    stride: usize,
) -> Result<Vec<f32>> {
    let rows = rows_per_band(&baker.context, guide.width as usize, stride)?;
    denoise_in_bands(baker, guide, (image, stride), rows)
}

/// [`denoise()`] in bands of `rows` rows (tests choose them).
pub fn denoise_in_bands(
    baker: &GpuBaker,
    guide: &DenoiseGuide,
    (image, stride): (&[f32], usize),
    rows: usize,
) -> Result<Vec<f32>> {
    let ctx = &baker.context;
    let (width, height) = (guide.width as usize, guide.height as usize);
    if width * height == 0 {
        return Ok(image.to_vec());
    }
    let kernel = ctx.checked("compiling the denoising kernel", || {
        pipeline(ctx, "denoise", denoise_kernel())
    })?;
    let reach = DENOISE_RADIUS as usize;
    let row_floats = width * stride;
    let params = ctx.uniform("denoise params", &DenoiseParams::default());
    let mut denoised = Vec::with_capacity(image.len());
    for first in (0..height).step_by(rows) {
        let count = rows.min(height - first);
        let inputs = first.saturating_sub(reach)..(first + count + reach).min(height);
        let texels = inputs.start * width..inputs.end * width;
        let with_w = |points: &[glam::Vec3], w: &[f32]| -> Vec<[f32; 4]> {
            points[texels.clone()]
                .iter()
                .zip(&w[texels.clone()])
                .map(|(p, &w)| [p.x, p.y, p.z, w])
                .collect()
        };
        let positions = ctx.storage(
            "denoise positions",
            &with_w(&guide.positions, &guide.levels),
        );
        let normals = ctx.storage("denoise normals", &with_w(&guide.normals, &guide.noise));
        let charts = ctx.storage("denoise charts", &guide.charts[texels.clone()]);
        let values = ctx.storage(
            "denoise image",
            &image[texels.start * stride..texels.end * stride],
        );
        let bytes = (count * row_floats * 4) as u64;
        let out = ctx.output("denoised", bytes);
        ctx.queue.write_buffer(
            &params,
            0,
            bytemuck::bytes_of(&DenoiseParams {
                width: width as u32,
                height: height as u32,
                stride: stride as u32,
                row_first: first as u32,
                row_count: count as u32,
                input_row_first: inputs.start as u32,
                texel_length: guide.texel_length,
                pad0: 0,
            }),
        );
        let group = ctx.checked("binding the denoising buffers", || {
            let buffers = [&params, &positions, &normals, &charts, &values, &out];
            baker.bind("denoise", &kernel, &buffers)
        })?;
        let groups = [
            ((count * width) as u32).div_ceil(WORKGROUP_SIZE),
            (stride as u32).div_ceil(COEFFS_PER_INVOCATION),
            1,
        ];
        ctx.checked("running the denoising kernel", || {
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("denoise"),
                });
            encode_pass(&mut encoder, "denoise", &kernel, &group, groups);
            ctx.queue.submit([encoder.finish()]);
        })?;
        ctx.wait()?;
        denoised.extend(ctx.read_back::<f32>(&out, bytes)?);
    }
    Ok(denoised)
}

/// Rows one pass writes: as many as keep the rows it reads (its own and the footprint's
/// reach above and below) within one binding and its texels within one dispatch.
fn rows_per_band(ctx: &GpuContext, width: usize, stride: usize) -> Result<usize> {
    let max_binding = ctx
        .limits
        .max_storage_buffer_binding_size
        .min(ctx.limits.max_buffer_size) as usize;
    let row_bytes = width * stride.max(4) * 4;
    let by_binding = (max_binding / row_bytes).saturating_sub(2 * DENOISE_RADIUS as usize);
    let by_dispatch =
        ctx.limits.max_compute_workgroups_per_dimension as usize * WORKGROUP_SIZE as usize / width;
    let rows = by_binding.min(by_dispatch);
    if rows == 0 {
        return Err(Error::Gpu(format!(
            "a lightmap row of {width} texels of {stride} floats is too wide for one binding"
        )));
    }
    Ok(rows)
}
