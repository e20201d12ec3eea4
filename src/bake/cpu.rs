//! The CPU reference backend. It runs the same two passes as the GPU kernels, function for
//! function: `trace_visibility` (wgsl/visibility.wgsl) sets one bit per sample that is above
//! the horizon and unblocked, `project_visibility` (wgsl/project.wgsl) sums cosine-weighted SH
//! over the set bits. Sums are f64 in sample order, so a bake is bit-for-bit repeatable however
//! rayon schedules the vertices.
//!
//! The bake traces in ray packets (`crate::packet`), which set the same bits as
//! `trace_visibility`, the readable one-ray-at-a-time reference kept beside it: for a set
//! shared by all vertices, each direction is cast from 16 Morton-adjacent vertices at once
//! (`trace_visibility_packets`); for a tangent-frame set, each vertex casts a run of 16
//! samples that form a small cone at once from its origin (`trace_visibility_fans`,
//! `SampleSet::fan_runs`). Bits are set by sample index, so the order of the runs cannot change
//! a sum.

use rayon::prelude::*;

use super::bounce::Hit;
use super::{DirectInputs, Mode, Progress};
use crate::packet::{self, lane_mask, FanPacket, LaneMask, PacketOrigins, RayPacket, LANES};
use crate::ray::{Ray, TriangleHit, RAY_T_MAX};
use crate::sampling::{DirectionFrame, Estimator, FAN_RUN};
use crate::sh::{coeff_count, unshadowed_transfer};

/// Vertices handed to one rayon task: large enough to amortise scheduling, small enough for
/// smooth progress and load balance on scenes with uneven occlusion. A multiple of the packet
/// width, so that only the last task has a partly filled packet.
pub const VERTICES_PER_TASK: usize = 4 * LANES;

/// Words of visibility bits per vertex for `samples` samples.
pub fn words_per_vertex(samples: usize) -> usize {
    samples.div_ceil(32)
}

/// Sets bit s of `bits` (word s/32, bit s%32) when sample s is above the horizon of `vertex`
/// and, in shadowed and interreflected mode, nothing blocks it. Returns the number of rays cast.
pub fn trace_visibility(inputs: &DirectInputs, mode: Mode, vertex: usize, bits: &mut [u32]) -> u64 {
    let normal = inputs.normals[vertex];
    let origin = inputs.origins[vertex];
    let mut rays = 0;
    bits.fill(0);
    let to_world = inputs.directions_of(vertex);
    for (s, &sample) in inputs.samples.directions.iter().enumerate() {
        let direction = to_world.world(sample);
        if normal.dot(direction) <= 0.0 {
            continue;
        }
        if mode != Mode::Unshadowed {
            rays += 1;
            if inputs.bvh.occluded(&Ray::new(origin, direction), RAY_T_MAX) {
                continue;
            }
        }
        bits[s / 32] |= 1 << (s % 32);
    }
    rays
}

/// [`trace_visibility`] of the vertices `first..first + count` (`bits`: `count` rows of
/// [`words_per_vertex`] words), traced direction-major in packets of [`LANES`] vertices.
/// World directions only.
/// Returns the number of rays cast, the same count as the single-ray order.
pub fn trace_visibility_packets(
    inputs: &DirectInputs,
    mode: Mode,
    first: usize,
    bits: &mut [u32],
) -> u64 {
    let words = words_per_vertex(inputs.samples.len());
    let count = bits.len() / words;
    bits.fill(0);
    let mut rays = 0;
    for start in (0..count).step_by(LANES) {
        let lanes = LANES.min(count - start);
        let vertices = first + start..first + start + lanes;
        let origins = PacketOrigins::new(&inputs.origins[vertices.clone()]);
        let normals = normal_lanes(&inputs.normals[vertices]);
        let rows = &mut bits[start * words..(start + lanes) * words];
        for (s, &direction) in inputs.samples.directions.iter().enumerate() {
            let above = above_horizon(&normals, direction) & origins.filled;
            let visible = if mode == Mode::Unshadowed || above == 0 {
                above
            } else {
                rays += above.count_ones() as u64;
                let packet = RayPacket::new(&origins, direction, above);
                above & !packet::occluded(inputs.bvh, &packet, RAY_T_MAX)
            };
            set_bit_per_lane(rows, words, s, visible);
        }
    }
    rays
}

/// [`trace_visibility`] of one vertex, its samples cast a run at a time
/// ([`crate::sampling::SampleSet::fan_runs`]) as one fan packet from the vertex. For
/// tangent-frame sets, whose directions no two vertices share. Returns the number of rays
/// cast, the same count as [`trace_visibility`].
pub fn trace_visibility_fans(
    inputs: &DirectInputs,
    mode: Mode,
    vertex: usize,
    bits: &mut [u32],
) -> u64 {
    packet::on_widest_unit(VertexFans {
        inputs,
        mode,
        vertex,
        bits,
    })
}

/// [`trace_visibility_fans`]' work, compiled for each vector unit: building the packets (five
/// divisions and the axis choice per lane) ran on SSE2 alone and took 8% of the bake.
struct VertexFans<'i, 'a, 'b> {
    inputs: &'i DirectInputs<'a>,
    mode: Mode,
    vertex: usize,
    bits: &'b mut [u32],
}

impl packet::Kernel for VertexFans<'_, '_, '_> {
    type Output = u64;

    #[inline(always)]
    fn run(self) -> u64 {
        let VertexFans {
            inputs,
            mode,
            vertex,
            bits,
        } = self;
        let normal = inputs.normals[vertex];
        let origin = inputs.origins[vertex];
        let to_world = inputs.directions_of(vertex);
        let path = inputs.bvh.path_to(origin);
        let mut rays = 0;
        bits.fill(0);
        // A run fills one packet.
        const _: () = assert!(FAN_RUN == LANES);
        let mut world = [glam::Vec3::ZERO; LANES];
        for run in inputs.samples.fan_runs() {
            let world = to_world.world_run(inputs.samples, run, &mut world);
            let above = lane_mask(|l| l < world.len() && normal.dot(world[l]) > 0.0);
            let visible = if mode == Mode::Unshadowed || above == 0 {
                above
            } else {
                rays += above.count_ones() as u64;
                let packet = FanPacket::new(origin, world, above);
                above & !packet::occluded_fan(inputs.bvh, &packet, &path, RAY_T_MAX)
            };
            set_run_bits(bits, run, visible);
        }
        rays
    }
}

/// [`trace_visibility`] of the vertices `first..first + count` (`bits`: `count` rows): in
/// parallel packets across vertices where all vertices share the directions, in fan packets
/// per vertex where each vertex turns them into its own tangent frame.
pub fn trace_visibility_of(
    inputs: &DirectInputs,
    mode: Mode,
    first: usize,
    bits: &mut [u32],
) -> u64 {
    match inputs.samples.frame {
        DirectionFrame::World => trace_visibility_packets(inputs, mode, first, bits),
        DirectionFrame::Tangent => {
            let words = words_per_vertex(inputs.samples.len());
            bits.chunks_mut(words)
                .enumerate()
                .map(|(i, row)| trace_visibility_fans(inputs, mode, first + i, row))
                .sum()
        }
    }
}

/// Normals by axis, `[axis][lane]`; empty lanes get zero normals (never above the horizon).
fn normal_lanes(normals: &[glam::Vec3]) -> [[f32; LANES]; 3] {
    let mut lanes = [[0.0; LANES]; 3];
    for (lane, n) in normals.iter().enumerate() {
        for axis in 0..3 {
            lanes[axis][lane] = n[axis];
        }
    }
    lanes
}

/// Lanes whose normal has `n.w > 0`, with the single-ray test's arithmetic (`Vec3::dot`:
/// `x*x' + y*y' + z*z'`, left to right) so that the horizon is the same bit for bit.
fn above_horizon(normals: &[[f32; LANES]; 3], w: glam::Vec3) -> LaneMask {
    lane_mask(|l| normals[0][l] * w.x + normals[1][l] * w.y + normals[2][l] * w.z > 0.0)
}

/// Sets the bit of sample `run[lane]` in `bits` for every lane in `lanes`.
fn set_run_bits(bits: &mut [u32], run: &[u32], mut lanes: LaneMask) {
    while lanes != 0 {
        let s = run[lanes.trailing_zeros() as usize] as usize;
        bits[s / 32] |= 1 << (s % 32);
        lanes &= lanes - 1;
    }
}

/// Sets bit `sample` in the row of every lane in `lanes` (`rows`: one row of `words` per lane).
fn set_bit_per_lane(rows: &mut [u32], words: usize, sample: usize, mut lanes: LaneMask) {
    let (word, bit) = (sample / 32, 1 << (sample % 32));
    while lanes != 0 {
        let lane = lanes.trailing_zeros() as usize;
        rows[lane * words + word] |= bit;
        lanes &= lanes - 1;
    }
}

/// `sum over selected s of w(s) y_k(w_s)` with `w(s) = n.w_s` (or 1 for the cosine density),
/// per 32-sample word then added (the GPU's order), into `out` (length bands^2). Selected are
/// the set bits, or, when the estimator sums blocked rays, the clear bits above the horizon.
/// Not yet scaled: see [`finish_transfer`].
pub fn project_visibility(inputs: &DirectInputs, vertex: usize, bits: &[u32], out: &mut [f64]) {
    packet::on_widest_unit(Projection {
        inputs,
        vertex,
        bits,
        out,
    })
}

/// [`project_visibility`]'s work, compiled for each vector unit (its sums run along the
/// coefficients, in the same order on every unit).
struct Projection<'i, 'a, 'b> {
    inputs: &'i DirectInputs<'a>,
    vertex: usize,
    bits: &'b [u32],
    out: &'b mut [f64],
}

impl packet::Kernel for Projection<'_, '_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let Projection {
            inputs,
            vertex,
            bits,
            out,
        } = self;
        let n = coeff_count(inputs.table.bands);
        let normal = inputs.normals[vertex];
        let estimator = inputs.estimator;
        let sample_count = inputs.samples.len();
        out.fill(0.0);
        let mut partial = vec![0.0f64; n];
        for (word, &mask) in bits.iter().enumerate() {
            if mask == 0 && !estimator.sums_blocked() {
                continue;
            }
            partial.fill(0.0);
            // Candidate samples in ascending order, without a branch per bit.
            let samples_in_word = (sample_count - word * 32).min(32);
            let in_word = u32::MAX >> (32 - samples_in_word);
            let mut rest = if estimator.sums_blocked() {
                !mask & in_word
            } else {
                mask
            };
            while rest != 0 {
                let s = word * 32 + rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let direction = inputs.samples.directions[s];
                let (cosine, weight) = match inputs.samples.frame {
                    DirectionFrame::World => {
                        let cosine = normal.dot(direction);
                        (cosine, cosine as f64)
                    }
                    DirectionFrame::Tangent => (direction.z, 1.0),
                };
                // A clear bit below the horizon was never cast: it is not blocked.
                if estimator.sums_blocked() && cosine <= 0.0 {
                    continue;
                }
                for (acc, &y) in partial.iter_mut().zip(inputs.table.row(s)) {
                    *acc += weight * y as f64;
                }
            }
            for (o, p) in out.iter_mut().zip(&partial) {
                *o += p;
            }
        }
    }
}

/// Scale from a projected sum to transfer: sample weight (4 pi / N, or pi / N for the cosine
/// density) over pi.
pub fn transfer_scale(inputs: &DirectInputs) -> f64 {
    inputs.samples.weight / std::f64::consts::PI
}

/// Turns the projected sums of one vertex into its transfer, in place: scaled, rotated from
/// the tangent frame to the world where the set lives there, and for the control variate
/// subtracted from the closed-form unoccluded transfer.
pub fn finish_transfer(inputs: &DirectInputs, vertex: usize, sums: &mut [f64]) {
    let scale = transfer_scale(inputs);
    let bands = inputs.table.bands;
    let normal = inputs.normals[vertex];
    sums.iter_mut().for_each(|t| *t *= scale);
    if let Some(axes) = inputs.directions_of(vertex).axes() {
        let [t, b, n] = axes.map(|axis| axis.as_dvec3());
        let frame = glam::DMat3::from_cols(t, b, n);
        inputs.tangent_to_world.apply(&frame, sums);
    }
    if inputs.estimator == Estimator::Blocked {
        let unoccluded = unshadowed_transfer(bands, normal.as_dvec3());
        for (t, open) in sums.iter_mut().zip(unoccluded) {
            *t = open - *t;
        }
    }
}

/// Albedo-free direct transfer of one vertex, the estimate of
/// `(1/pi) integral V(w) max(0, n.w) y_k(w) dw`, into `out`. Returns the rays cast.
pub fn vertex_direct_transfer(
    inputs: &DirectInputs,
    mode: Mode,
    vertex: usize,
    out: &mut [f64],
) -> u64 {
    let mut bits = vec![0u32; words_per_vertex(inputs.samples.len())];
    let rays = trace_visibility(inputs, mode, vertex, &mut bits);
    project_visibility(inputs, vertex, &bits, out);
    finish_transfer(inputs, vertex, out);
    rays
}

/// Direct transfer of every vertex, albedo-free, `[vertex][k]`. Returns (transfer, rays cast).
pub fn direct_transfer(
    inputs: &DirectInputs,
    mode: Mode,
    progress: &dyn Progress,
) -> (Vec<f32>, u64) {
    let n = coeff_count(inputs.table.bands);
    let mut transfer = vec![0.0f32; inputs.origins.len() * n];
    let rays = project_each(
        inputs,
        mode,
        progress,
        &mut transfer,
        |vertex, sums, out| {
            finish_transfer(inputs, vertex, sums);
            for (o, s) in out.iter_mut().zip(sums.iter()) {
                *o = *s as f32;
            }
        },
    );
    (transfer, rays)
}

/// The projected sums of every vertex, `[vertex][k]`, before [`finish_transfer`]: what an
/// error-targeted bake adds up batch by batch. Returns (sums, rays cast).
pub fn projected_sums(
    inputs: &DirectInputs,
    mode: Mode,
    progress: &dyn Progress,
) -> (Vec<f64>, u64) {
    let n = coeff_count(inputs.table.bands);
    let mut sums = vec![0.0f64; inputs.origins.len() * n];
    let rays = project_each(inputs, mode, progress, &mut sums, |_, projected, out| {
        out.copy_from_slice(projected);
    });
    (sums, rays)
}

/// Traces and projects every vertex in packets, handing each vertex's projected sums to
/// `write` with its row of `out` (`[vertex][k]`). Returns the rays cast.
fn project_each<T: Send>(
    inputs: &DirectInputs,
    mode: Mode,
    progress: &dyn Progress,
    out: &mut [T],
    write: impl Fn(usize, &mut [f64], &mut [T]) + Sync,
) -> u64 {
    let n = coeff_count(inputs.table.bands);
    let words = words_per_vertex(inputs.samples.len());
    out.par_chunks_mut(n * VERTICES_PER_TASK)
        .enumerate()
        .map(|(task, chunk)| {
            let first = task * VERTICES_PER_TASK;
            let count = chunk.len() / n;
            let mut bits = vec![0u32; count * words];
            let rays = trace_visibility_of(inputs, mode, first, &mut bits);
            let mut acc = vec![0.0f64; n];
            for (i, (row_out, row)) in chunk
                .chunks_exact_mut(n)
                .zip(bits.chunks(words))
                .enumerate()
            {
                project_visibility(inputs, first + i, row, &mut acc);
                write(first + i, &mut acc, row_out);
            }
            progress.advance(count as u64);
            rays
        })
        .sum()
}

/// [`direct_transfer`] in the vertex-major, one-ray-at-a-time order of [`trace_visibility`]:
/// the same numbers (up to edge-grazing rays), kept to measure what the packets gain.
pub fn direct_transfer_single_rays(
    inputs: &DirectInputs,
    mode: Mode,
    progress: &dyn Progress,
) -> (Vec<f32>, u64) {
    let n = coeff_count(inputs.table.bands);
    let mut transfer = vec![0.0f32; inputs.origins.len() * n];
    let rays: u64 = transfer
        .par_chunks_mut(n * VERTICES_PER_TASK)
        .enumerate()
        .map(|(task, chunk)| {
            let mut acc = vec![0.0f64; n];
            let mut rays = 0;
            for (i, out) in chunk.chunks_exact_mut(n).enumerate() {
                rays +=
                    vertex_direct_transfer(inputs, mode, task * VERTICES_PER_TASK + i, &mut acc);
                for (o, a) in out.iter_mut().zip(&acc) {
                    *o = *a as f32;
                }
            }
            progress.advance((chunk.len() / n) as u64);
            rays
        })
        .sum();
    (transfer, rays)
}

/// Visibility bits of every vertex, `[vertex][word]`: what the GPU's visibility pass must
/// reproduce ray for ray.
pub fn visibility_bits(inputs: &DirectInputs, mode: Mode) -> Vec<u32> {
    let words = words_per_vertex(inputs.samples.len());
    let mut bits = vec![0u32; inputs.origins.len() * words];
    bits.par_chunks_mut(words * VERTICES_PER_TASK)
        .enumerate()
        .for_each(|(task, rows)| {
            trace_visibility_of(inputs, mode, task * VERTICES_PER_TASK, rows);
        });
    bits
}

/// The closest hits of one vertex's rays along `samples` (indices into the sample set, each
/// above the horizon), handed to `visit(sample, triangle, hit)` for those that hit something.
/// Tangent-frame sets are cast as fan packets ([`packet::closest_fan`]), each the members of
/// `samples` in one of the set's runs (`SampleSet::fan_runs`), and visited in the order of
/// `samples`; world sets one ray at a time. Either way a hit is bit for bit the one of
/// `Bvh::closest_hit`, ties between triangles at one distance included (`ray::replaces`).
pub fn visit_closest_hits(
    inputs: &DirectInputs,
    vertex: usize,
    samples: &[u32],
    mut visit: impl FnMut(u32, u32, TriangleHit),
) {
    let origin = inputs.origins[vertex];
    let to_world = inputs.directions_of(vertex);
    let direction = |s: u32| to_world.world(inputs.samples.directions[s as usize]);
    if inputs.samples.frame == DirectionFrame::World {
        for &s in samples {
            let ray = Ray::new(origin, direction(s));
            if let Some((triangle, hit)) = inputs.bvh.closest_hit(&ray, RAY_T_MAX) {
                visit(s, triangle, hit);
            }
        }
        return;
    }
    packet::on_widest_unit(ClosestFans {
        inputs,
        vertex,
        samples,
        visit,
    });
}

/// [`visit_closest_hits`]' fans, compiled for each vector unit: building the packets and
/// taking their hits apart ran as SSE2 code, 7.5% of an interreflected bake of the dragon.
struct ClosestFans<'i, 'a, 's, F> {
    inputs: &'i DirectInputs<'a>,
    vertex: usize,
    samples: &'s [u32],
    visit: F,
}

impl<F: FnMut(u32, u32, TriangleHit)> packet::Kernel for ClosestFans<'_, '_, '_, F> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let ClosestFans {
            inputs,
            vertex,
            samples,
            mut visit,
        } = self;
        let origin = inputs.origins[vertex];
        let to_world = inputs.directions_of(vertex);
        let path = inputs.bvh.path_to(origin);
        // Cast run by run (`SampleSet::fan_runs`), the members of `samples` in each; visited
        // in the order of `samples`.
        let set = inputs.samples;
        let mut wanted = vec![false; set.len()];
        for &s in samples {
            wanted[s as usize] = true;
        }
        let mut hits: Vec<Option<(u32, TriangleHit)>> = vec![None; set.len()];
        let mut world = [glam::Vec3::ZERO; LANES];
        let mut group = [0u32; LANES];
        for run in set.fan_runs() {
            let mut members = 0;
            for &s in run {
                group[members] = s;
                members += wanted[s as usize] as usize;
            }
            if members == 0 {
                continue;
            }
            let group = &group[..members];
            let world = to_world.world_run(set, group, &mut world);
            let packet = FanPacket::new(origin, world, crate::packet::ALL_LANES);
            let closest = packet::closest_fan(inputs.bvh, &packet, &path, RAY_T_MAX);
            for (lane, &s) in group.iter().enumerate() {
                if let Some((u, v)) = closest.barycentrics(lane) {
                    let tri = &inputs.bvh.triangles[closest.triangle[lane] as usize];
                    let t = closest.t[lane];
                    hits[s as usize] = Some((tri.source_index, TriangleHit { t, u, v }));
                }
            }
        }
        for &s in samples {
            if let Some((triangle, hit)) = hits[s as usize] {
                visit(s, triangle, hit);
            }
        }
    }
}

/// [`visit_closest_hits`] collected: `(sample, hit)` for the rays that hit something.
pub fn closest_hits_of(inputs: &DirectInputs, vertex: usize, samples: &[u32]) -> Vec<(u32, Hit)> {
    let mut hits = Vec::new();
    visit_closest_hits(inputs, vertex, samples, |s, triangle, hit| {
        let (u, v) = (hit.u, hit.v);
        hits.push((s, Hit { triangle, u, v }));
    });
    hits
}

/// The samples of `vertex` above its horizon, in order.
pub fn samples_above_horizon(inputs: &DirectInputs, vertex: usize) -> Vec<u32> {
    let normal = inputs.normals[vertex];
    let to_world = inputs.directions_of(vertex);
    (0..inputs.samples.len() as u32)
        .filter(|&s| normal.dot(to_world.world(inputs.samples.directions[s as usize])) > 0.0)
        .collect()
}

/// The closest hit of every ray of the direct pass (`(sample, triangle)` per receiver, for the
/// rays that hit something) and the rays cast: what `prt-gpu bench --ray-sets` times as its
/// diffuse ray set (an interreflected bake casts the same rays, its visibility taken from their
/// hits: `bounce::hits_and_visibility`).
pub fn closest_hit_triangles(inputs: &DirectInputs) -> (Vec<Vec<(u32, u32)>>, u64) {
    let per_receiver: Vec<(Vec<(u32, u32)>, u64)> = (0..inputs.origins.len())
        .into_par_iter()
        .map(|vertex| {
            let above = samples_above_horizon(inputs, vertex);
            let mut triangles = Vec::new();
            visit_closest_hits(inputs, vertex, &above, |s, triangle, _| {
                triangles.push((s, triangle))
            });
            (triangles, above.len() as u64)
        })
        .collect();
    let rays = per_receiver.iter().map(|(_, rays)| rays).sum();
    (
        per_receiver.into_iter().map(|(hits, _)| hits).collect(),
        rays,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{BakeInputs, NoProgress};
    use crate::scene::{self, prepare::prepare};

    fn bunny(samples: u32) -> BakeInputs {
        bunny_sampled(samples, crate::sampling::Sampling::Stratified)
    }

    fn bunny_sampled(samples: u32, sampling: crate::sampling::Sampling) -> BakeInputs {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
        let (mesh, _) = prepare(scene::load(&path).unwrap()).unwrap();
        BakeInputs::with_sampling(&mesh, 3, samples, 5, sampling)
    }

    #[test]
    fn packets_set_the_bits_of_single_rays() {
        // 100 samples: words end in a partly used word; the bunny's vertex count is not a
        // multiple of the packet width, so the last packet is partly filled.
        let owned = bunny(100);
        let inputs = owned.view();
        assert_ne!(inputs.origins.len() % LANES, 0);
        let words = words_per_vertex(inputs.samples.len());
        for mode in [Mode::Unshadowed, Mode::Shadowed] {
            let bits = visibility_bits(&inputs, mode);
            let mut row = vec![0u32; words];
            for v in 0..inputs.origins.len() {
                trace_visibility(&inputs, mode, v, &mut row);
                assert_eq!(
                    &bits[v * words..(v + 1) * words],
                    &row[..],
                    "vertex {v} {mode:?}"
                );
            }
        }
    }

    #[test]
    fn fans_set_the_bits_of_single_rays() {
        // 100 samples: the last packet of each vertex is partly filled (100 = 6 x 16 + 4).
        let owned = bunny_sampled(100, crate::sampling::Sampling::Cosine);
        let inputs = owned.view();
        let words = words_per_vertex(inputs.samples.len());
        let (mut fans, mut single) = (vec![0u32; words], vec![0u32; words]);
        let mut blocked = 0;
        for mode in [Mode::Unshadowed, Mode::Shadowed] {
            for v in 0..inputs.origins.len() {
                let rays = trace_visibility_fans(&inputs, mode, v, &mut fans);
                assert_eq!(rays, trace_visibility(&inputs, mode, v, &mut single));
                assert_eq!(fans, single, "vertex {v} {mode:?}");
                let visible: u64 = fans.iter().map(|w| w.count_ones() as u64).sum();
                blocked += rays.saturating_sub(visible);
            }
        }
        assert!(blocked > 0);
    }

    #[test]
    fn closest_hits_are_found_on_exactly_the_blocked_rays() {
        let owned = bunny(100);
        let inputs = owned.view();
        let bits = visibility_bits(&inputs, Mode::Shadowed);
        let words = words_per_vertex(inputs.samples.len());
        let (hits, rays) = closest_hit_triangles(&inputs);
        let (_, shadowed_rays) = direct_transfer(&inputs, Mode::Shadowed, &NoProgress);
        assert_eq!(rays, shadowed_rays);
        let mut blocked = 0;
        for (v, own) in hits.iter().enumerate() {
            let normal = inputs.normals[v];
            let to_world = inputs.directions_of(v);
            let expected: Vec<u32> = (0..inputs.samples.len() as u32)
                .filter(|&s| {
                    let above = normal.dot(to_world.world(inputs.samples.directions[s as usize]));
                    above > 0.0 && bits[v * words + s as usize / 32] & (1 << (s % 32)) == 0
                })
                .collect();
            let with_hits: Vec<u32> = own.iter().map(|&(s, _)| s).collect();
            assert_eq!(with_hits, expected, "vertex {v}");
            blocked += expected.len();
        }
        assert!(
            blocked > 1000,
            "too few blocked rays ({blocked}) to test anything"
        );
    }

    #[test]
    fn direct_transfer_matches_the_single_ray_order() {
        let owned = bunny(256);
        let inputs = owned.view();
        for mode in [Mode::Unshadowed, Mode::Shadowed] {
            let (packets, rays) = direct_transfer(&inputs, mode, &NoProgress);
            let (single, single_rays) = direct_transfer_single_rays(&inputs, mode, &NoProgress);
            assert_eq!(rays, single_rays, "{mode:?}");
            assert_eq!(rays == 0, mode == Mode::Unshadowed);
            assert_eq!(packets, single, "{mode:?}");
        }
    }
}
