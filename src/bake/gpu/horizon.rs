//! The horizon pass (wgsl/horizon.wgsl): each chunk's sample lists, built on the device. The
//! visibility pass walks them so that its SIMD groups trace rays instead of idling below the
//! horizon; listing them on the device leaves the host no per-ray work (on an NVIDIA H200 the
//! host's lists took 30–40% of a shadowed GPU bake, docs/performance.md).

use bytemuck::{Pod, Zeroable};

/// Uniforms of the horizon kernel, 32 bytes; WGSL twin in wgsl/horizon.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct HorizonParams {
    pub vertex_offset: u32,
    pub vertex_count: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    /// `shaders::FRAMES_*`, as [`super::VisibilityParams::frames`].
    pub frames: u32,
    /// 1: the visibility pass records hits, and the samples left out get NO_HIT.
    pub record_hits: u32,
    /// As [`super::VisibilityParams::turn_seed`] and `turn_first`.
    pub turn_seed: u32,
    pub turn_first: u32,
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use crate::bake::BakeInputs;
    use crate::sampling::{Sampling, VertexDirections};
    use crate::scene::{builtin, prepare::prepare};
    use crate::shaders::NO_SAMPLE;
    use std::ops::Range;

    /// The lists as the host built them before the horizon pass: for each vertex of
    /// `vertices`, the samples of `samples` above its horizon by the CPU backend's test, as
    /// indices from `samples.start`, ascending, padded with NO_SAMPLE to rows of
    /// `samples.len()`.
    fn host_lists(
        inputs: &DirectInputs,
        vertices: Range<usize>,
        samples: Range<usize>,
    ) -> Vec<u32> {
        let width = samples.len();
        let mut lists = vec![NO_SAMPLE; vertices.len() * width];
        for (row, &normal) in lists.chunks_mut(width).zip(&inputs.normals[vertices]) {
            let to_world = VertexDirections::new(inputs.samples.frame, normal);
            let above = inputs.samples.directions[samples.clone()]
                .iter()
                .enumerate()
                .filter(|(_, &sample)| normal.dot(to_world.world(sample)) > 0.0);
            for (slot, (s, _)) in row.iter_mut().zip(above) {
                *slot = s as u32;
            }
        }
        lists
    }

    /// The device's lists, counts and indirect workgroup counts against the host's, chunk by
    /// chunk, for a world-frame set (half the samples below each horizon) and a tangent-frame
    /// one, with sample chunks that end inside a workgroup's tile of samples.
    #[test]
    fn the_device_lists_the_hosts_samples() {
        let Some(context) = crate::device::any_adapter_or_skip() else {
            return;
        };
        let baker = GpuBaker::new(context).unwrap();
        let ctx = &baker.context;
        let (scene, _) = prepare(builtin::default_scene()).unwrap();
        for sampling in [Sampling::Fibonacci, Sampling::Cosine] {
            let owned = BakeInputs::with_sampling(&scene, 3, 200, 5, sampling);
            let inputs = owned.view();
            let spec = RunSpec {
                inputs: &inputs,
                mode: Mode::Interreflected,
                keep_bits: false,
                max_steps: MAX_TRAVERSAL_STEPS,
                coeffs: coeff_count(3) as u32,
            };
            let (vertex_chunk, sample_chunk) = (300, 96);
            let gpu_bvh = GpuBvh::new(inputs.bvh);
            let buffers =
                RunBuffers::new(&baker, &spec, &gpu_bvh, vertex_chunk, sample_chunk).unwrap();
            let (vertices, samples) = (inputs.origins.len() as u32, inputs.samples.len() as u32);
            let mut expected_listed = 0;
            let mut stats = GpuRun::default();
            for vertex_offset in (0..vertices).step_by(vertex_chunk as usize) {
                for sample_offset in (0..samples).step_by(sample_chunk as usize) {
                    let chunk = Chunk {
                        vertex_offset,
                        vertices: vertex_chunk.min(vertices - vertex_offset),
                        sample_offset,
                        samples: sample_chunk.min(samples - sample_offset),
                        accumulate: sample_offset > 0,
                    };
                    buffers.dispatch(&baker, &spec, chunk, &mut stats).unwrap();
                    let range =
                        |offset: u32, count: u32| offset as usize..(offset + count) as usize;
                    let expected = host_lists(
                        &inputs,
                        range(chunk.vertex_offset, chunk.vertices),
                        range(chunk.sample_offset, chunk.samples),
                    );
                    let lists: Vec<u32> = ctx
                        .read_back(&buffers.sample_lists, expected.len() as u64 * 4)
                        .unwrap();
                    assert_eq!(lists, expected, "{sampling:?}, chunk {chunk:?}");
                    let rows = expected.chunks(chunk.samples as usize);
                    let longest = rows
                        .clone()
                        .map(|row| row.iter().take_while(|&&s| s != NO_SAMPLE).count())
                        .max()
                        .unwrap() as u32;
                    let groups: Vec<u32> = ctx.read_back(&buffers.visibility_groups, 12).unwrap();
                    assert_eq!(
                        groups,
                        [longest.div_ceil(WORKGROUP_SIZE), chunk.vertices, 1]
                    );
                    expected_listed += expected.iter().filter(|&&s| s != NO_SAMPLE).count() as u64;
                }
            }
            assert_eq!(buffers.samples_listed(ctx).unwrap(), expected_listed);
            if sampling == Sampling::Fibonacci {
                let pairs = vertices as u64 * samples as u64;
                assert!(
                    expected_listed < pairs * 3 / 4,
                    "{expected_listed} of {pairs}"
                );
            }
        }
    }
}
