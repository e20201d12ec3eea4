//! Bounces on the GPU: the gather matrix uploaded in row chunks that fit a binding, and each
//! bounce a sparse product per chunk (`wgsl/gather.wgsl`).

use super::*;

/// Matrix entries one gather invocation sums in one pass (its loop count).
pub(super) const GATHER_ENTRIES_PER_PASS: u32 = 16_384;

/// The gather matrix uploaded for bounce passes: row chunks that fit the adapter's bindings.
pub struct GpuGatherMatrix {
    chunks: Vec<RowChunk>,
    albedo: wgpu::Buffer,
    rows: u32,
    coeffs: u32,
}

pub(super) struct RowChunk {
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
                self.bind("gather", &self.gather, &buffers)
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
