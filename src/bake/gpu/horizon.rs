//! The horizon pass (wgsl/horizon.wgsl): each chunk's sample lists, built on the device. The
//! visibility pass walks them so that its SIMD groups trace rays instead of idling below the
//! horizon; listing them on the device leaves the host no per-ray work (on an NVIDIA H200 the
//! host's lists took 30–40% of a shadowed GPU bake, docs/performance.md).

use bytemuck::{Pod, Zeroable};

use crate::device::GpuContext;
use crate::sampling::SampleSet;

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

/// The order the horizon pass lists samples in, per chunk of `sample_chunk` samples: at
/// `sample_offset + position`, the chunk's samples (indices from `sample_offset`) in the order
/// of the set's fan runs ([`SampleSet::fan_runs`]). A SIMD group of the visibility pass then
/// traces directions of one small cone, as a CPU fan packet does; the bits and hits it writes
/// go by sample index, so the order changes no result.
pub fn listing_order(samples: &SampleSet, sample_chunk: u32) -> Vec<u32> {
    let chunk = sample_chunk as usize;
    let mut order = vec![0; samples.len()];
    let mut listed = vec![0; samples.len().div_ceil(chunk)];
    for &sample in samples.fan_runs().flatten() {
        let index = sample as usize / chunk;
        order[index * chunk + listed[index]] = sample - (index * chunk) as u32;
        listed[index] += 1;
    }
    order
}

/// The horizon pass's own buffers.
pub(super) struct HorizonBuffers {
    /// The sample lists of every vertex–sample pair of a chunk, which the visibility pass
    /// reads.
    pub sample_lists: wgpu::Buffer,
    /// (low, high) words of the samples listed in the run.
    pub listed: wgpu::Buffer,
    /// The visibility pass's workgroup counts, which the pass writes for an indirect dispatch.
    pub visibility_groups: wgpu::Buffer,
    /// The pass's [`HorizonParams`], written before each chunk.
    pub params: wgpu::Buffer,
    /// The order it lists samples in ([`listing_order`]).
    pub listing_order: wgpu::Buffer,
}

/// [`HorizonBuffers`] for `pairs` vertex–sample pairs of `samples` in chunks of
/// `sample_chunk`.
pub(super) fn buffers(
    ctx: &GpuContext,
    pairs: u64,
    samples: &SampleSet,
    sample_chunk: u32,
) -> HorizonBuffers {
    let visibility_groups = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("visibility workgroups"),
        size: 12,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::INDIRECT
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    HorizonBuffers {
        sample_lists: ctx.output("sample lists", pairs * 4),
        listed: ctx.output("samples listed", 8),
        visibility_groups,
        params: ctx.uniform("horizon params", &HorizonParams::default()),
        listing_order: ctx.storage("listing order", &listing_order(samples, sample_chunk)),
    }
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
    /// indices from `samples.start`, in the order of the set's fan runs, padded with NO_SAMPLE
    /// to rows of `samples.len()`.
    fn host_lists(
        inputs: &DirectInputs,
        vertices: Range<usize>,
        samples: Range<usize>,
    ) -> Vec<u32> {
        let width = samples.len();
        let in_run_order: Vec<usize> = inputs
            .samples
            .fan_runs()
            .flatten()
            .map(|&s| s as usize)
            .filter(|s| samples.contains(s))
            .collect();
        let mut lists = vec![NO_SAMPLE; vertices.len() * width];
        for (row, &normal) in lists.chunks_mut(width).zip(&inputs.normals[vertices]) {
            let to_world = VertexDirections::new(inputs.samples.frame, normal);
            let above = in_run_order
                .iter()
                .filter(|&&s| normal.dot(to_world.world(inputs.samples.directions[s])) > 0.0);
            for (slot, &s) in row.iter_mut().zip(above) {
                *slot = (s - samples.start) as u32;
            }
        }
        lists
    }

    #[test]
    fn the_listing_order_is_each_chunks_samples_in_run_order() {
        let set = crate::sampling::cosine_hemisphere(200, 3);
        let order = super::super::horizon::listing_order(&set, 96);
        let runs: Vec<u32> = set.fan_runs().flatten().copied().collect();
        for (index, chunk) in order.chunks(96).enumerate() {
            let first = index as u32 * 96;
            let global: Vec<u32> = chunk.iter().map(|&s| first + s).collect();
            let expected: Vec<u32> = runs
                .iter()
                .copied()
                .filter(|s| (first..first + 96).contains(s))
                .collect();
            assert_eq!(global, expected, "chunk {index}");
        }
        // Runs cross chunks here, so a chunk's order is not its ascending indices.
        assert_ne!(order[..96], (0..96).collect::<Vec<u32>>()[..]);
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
                        .read_back(&buffers.horizon.sample_lists, expected.len() as u64 * 4)
                        .unwrap();
                    assert_eq!(lists, expected, "{sampling:?}, chunk {chunk:?}");
                    let rows = expected.chunks(chunk.samples as usize);
                    let longest = rows
                        .clone()
                        .map(|row| row.iter().take_while(|&&s| s != NO_SAMPLE).count())
                        .max()
                        .unwrap() as u32;
                    let groups: Vec<u32> = ctx
                        .read_back(&buffers.horizon.visibility_groups, 12)
                        .unwrap();
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
