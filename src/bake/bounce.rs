//! Interreflected transfer (Sloan, Kautz & Snyder 2002): each bounce gathers the previous
//! bounce's transfer where a vertex's blocked rays hit the scene,
//!
//! `T^b_p = (rho_p / pi) integral (1 - V_p(w)) T^(b-1)(q(p, w)) max(0, n_p . w) dw`,
//!
//! with `T^(b-1)(q)` interpolated from the hit triangle's vertices. The hits never change
//! between bounces, so they are found once and folded into a sparse gather matrix: row p lists
//! (vertex j, weight) with `T^b_p = rho_p sum_j weight_pj T^(b-1)_j`. A bounce is then a sparse
//! matrix product and costs no rays; the matrix is what both backends build from their hits.
//!
//! Back faces: a ray that reaches the back of a surface (the side its interpolated vertex
//! normal points away from) is blocked for direct light but gathers nothing: the transfer
//! baked at those vertices describes their front side, and the back of an open surface
//! receives no light of its own in this model.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use rayon::prelude::*;

use super::{cpu, DirectInputs, Mode, Progress};
use crate::ray::{barycentrics, blend_at, NO_HIT};
use crate::sampling::DirectionFrame;
use crate::sh::coeff_count;

/// The closest hit of one ray, 12 bytes; WGSL twin `Hit` in wgsl/samples.wgsl. `u`, `v`:
/// barycentrics of the triangle's second and third vertices.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Hit {
    /// Index into the scene's triangles, or [`NO_HIT`].
    pub triangle: u32,
    pub u: f32,
    pub v: f32,
}
const _: () = assert!(std::mem::size_of::<Hit>() == 12);

/// Compressed sparse rows: row p holds `columns[row_offsets[p]..row_offsets[p+1]]` and their
/// `weights`, columns ascending and distinct.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GatherMatrix {
    pub row_offsets: Vec<u32>,
    pub columns: Vec<u32>,
    pub weights: Vec<f32>,
}

impl GatherMatrix {
    pub fn rows(&self) -> usize {
        self.row_offsets.len().saturating_sub(1)
    }

    pub fn row(&self, p: usize) -> (&[u32], &[f32]) {
        let range = self.row_offsets[p] as usize..self.row_offsets[p + 1] as usize;
        (&self.columns[range.clone()], &self.weights[range])
    }

    /// The longest row: bounds the loop of the GPU gather kernel.
    pub fn max_row_len(&self) -> usize {
        self.row_offsets
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }

    pub(crate) fn from_rows(rows: Vec<Vec<(u32, f32)>>) -> Self {
        // Sized once: grown by doubling, the two arrays would briefly take three times their
        // size, which a bake in bounded memory cannot spare.
        let entries = rows.iter().map(Vec::len).sum();
        let mut matrix = GatherMatrix {
            row_offsets: Vec::with_capacity(rows.len() + 1),
            columns: Vec::with_capacity(entries),
            weights: Vec::with_capacity(entries),
        };
        matrix.row_offsets.push(0);
        for row in rows {
            for (column, weight) in row {
                matrix.columns.push(column);
                matrix.weights.push(weight);
            }
            matrix.row_offsets.push(matrix.columns.len() as u32);
        }
        matrix
    }
}

/// The gather row of receiver `vertex` from the hits of its blocked rays, `(sample, hit)`.
///
/// Each front-facing hit adds `(w / pi) cos(n_p, w_s) b_j` (without the cosine when the
/// sample density carries it) to the weight of each hit-triangle vertex j with barycentric
/// `b_j`. Entries of one vertex are merged, so a row is as long as
/// the number of distinct vertices the rays land near, not three per ray.
pub fn gather_row(inputs: &DirectInputs, vertex: usize, hits: &[(u32, Hit)]) -> Vec<(u32, f32)> {
    let normal = inputs.normals[vertex];
    let to_world = inputs.directions_of(vertex);
    let scale = cpu::transfer_scale(inputs);
    let mut entries: Vec<(u32, f64)> = Vec::with_capacity(hits.len() * 3);
    for &(sample, hit) in hits {
        if hit.triangle == NO_HIT {
            continue;
        }
        let direction = to_world.world(inputs.samples.directions[sample as usize]);
        let cosine = normal.dot(direction);
        let corners = inputs.triangles[hit.triangle as usize];
        let shading_normal = blend_at(inputs.vertex_normals, corners, hit.u, hit.v);
        if cosine <= 0.0 || shading_normal.dot(direction) >= 0.0 {
            continue;
        }
        let density_weight = match inputs.samples.frame {
            DirectionFrame::World => cosine as f64,
            DirectionFrame::Tangent => 1.0,
        };
        for (&j, b) in corners.iter().zip(barycentrics(hit.u, hit.v)) {
            entries.push((j, scale * density_weight * b.max(0.0) as f64));
        }
    }
    summed_by_column(entries)
        .into_iter()
        .filter(|&(_, weight)| weight > 0.0)
        .map(|(column, weight)| (column, weight as f32))
        .collect()
}

/// A row's entries with one per column, columns ascending: the weights of a column summed in
/// the order given.
pub(crate) fn summed_by_column(mut entries: Vec<(u32, f64)>) -> Vec<(u32, f64)> {
    entries.sort_by_key(|&(column, _)| column);
    let mut row: Vec<(u32, f64)> = Vec::with_capacity(entries.len());
    for (column, weight) in entries {
        match row.last_mut() {
            Some((last, sum)) if *last == column => *sum += weight,
            _ => row.push((column, weight)),
        }
    }
    row
}

/// Closest hits of the blocked rays of one vertex, on the CPU: `(sample, hit)` for every
/// sample above the horizon whose bit in `visible` (the vertex's visibility bits, from
/// [`cpu::trace_visibility`] or its packets) is clear. The packets find which rays are blocked
/// far faster than a closest-hit traversal, and the open rays, most of them on a typical mesh
/// and the ones that cross the whole tree, then need no closest hit at all.
pub fn blocked_hits(inputs: &DirectInputs, vertex: usize, visible: &[u32]) -> Vec<(u32, Hit)> {
    let mut blocked = cpu::samples_above_horizon(inputs, vertex);
    blocked.retain(|&s| visible[s as usize / 32] & (1 << (s % 32)) == 0);
    // A blocked ray always has a closest hit: both queries run the same tests.
    cpu::closest_hits_of(inputs, vertex, &blocked)
}

/// Albedo-free direct transfer `[vertex][k]` and the gather matrix, on the CPU: visibility
/// from the packets of the shadowed bake, then the blocked rays' closest hits
/// ([`cpu::closest_hits_of`]).
/// Returns them and the rays cast (one per sample above the horizon, as in shadowed mode).
pub fn direct_transfer_and_gather_matrix_cpu(
    inputs: &DirectInputs,
    progress: &dyn Progress,
) -> (Vec<f32>, GatherMatrix, u64) {
    let n = coeff_count(inputs.table.bands);
    let words = cpu::words_per_vertex(inputs.samples.len());
    let vertex_count = inputs.origins.len();
    /// One task's direct transfer, gather rows and rays cast.
    type TaskResult = (Vec<f32>, Vec<Vec<(u32, f32)>>, u64);
    let per_task: Vec<TaskResult> = (0..vertex_count)
        .step_by(cpu::VERTICES_PER_TASK)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|first| {
            let count = cpu::VERTICES_PER_TASK.min(vertex_count - first);
            let mut bits = vec![0u32; count * words];
            let rays = cpu::trace_visibility_of(inputs, Mode::Shadowed, first, &mut bits);
            let mut transfer = Vec::with_capacity(count * n);
            let mut rows = Vec::with_capacity(count);
            let mut sums = vec![0.0f64; n];
            for (i, visible) in bits.chunks(words).enumerate() {
                let v = first + i;
                cpu::project_visibility(inputs, v, visible, &mut sums);
                cpu::finish_transfer(inputs, v, &mut sums);
                transfer.extend(sums.iter().map(|&t| t as f32));
                rows.push(gather_row(inputs, v, &blocked_hits(inputs, v, visible)));
            }
            progress.advance(count as u64);
            (transfer, rows, rays)
        })
        .collect();
    let mut transfer = Vec::with_capacity(vertex_count * n);
    let mut rows = Vec::with_capacity(vertex_count);
    let mut rays = 0;
    for (t, task_rows, r) in per_task {
        transfer.extend(t);
        rows.extend(task_rows);
        rays += r;
    }
    (transfer, GatherMatrix::from_rows(rows), rays)
}

/// The gather matrix from the blocked rays' hits of every vertex, `(sample, hit)` per vertex
/// (what the GPU's closest-hit pass returns).
pub fn gather_matrix_from_vertex_hits(
    inputs: &DirectInputs,
    hits: &[Vec<(u32, Hit)>],
) -> GatherMatrix {
    let rows = hits
        .par_iter()
        .enumerate()
        .map(|(v, own)| gather_row(inputs, v, own))
        .collect();
    GatherMatrix::from_rows(rows)
}

/// One bounce on the CPU: `next[p][c][k] = albedo[p][c] sum_j weight_pj previous[j][c][k]`,
/// for RGB transfer `[vertex][3][coeffs]`. Sums in f64 in column order.
pub fn apply_cpu(
    matrix: &GatherMatrix,
    previous: &[f32],
    albedo: &[Vec3],
    coeffs: usize,
) -> Vec<f32> {
    let stride = 3 * coeffs;
    let mut next = vec![0.0f32; matrix.rows() * stride];
    // One accumulator per rayon job, not per row: at one coefficient (local lights' frames)
    // the allocation cost as much as the row.
    next.par_chunks_mut(stride)
        .enumerate()
        .with_min_len(64)
        .for_each_init(
            || vec![0.0f64; stride],
            |acc, (p, out)| {
                acc.fill(0.0);
                let (columns, weights) = matrix.row(p);
                for (&j, &w) in columns.iter().zip(weights) {
                    let source = &previous[j as usize * stride..(j as usize + 1) * stride];
                    for (a, &t) in acc.iter_mut().zip(source) {
                        *a += w as f64 * t as f64;
                    }
                }
                for c in 0..3 {
                    for k in 0..coeffs {
                        out[c * coeffs + k] = (albedo[p][c] as f64 * acc[c * coeffs + k]) as f32;
                    }
                }
            },
        );
    next
}

/// Energy a bounce adds relative to all transfer so far: the ratio of the summed DC terms
/// (what a vertex reflects under constant white light), over all vertices and channels.
pub fn relative_energy(added: &[f32], total: &[f32], coeffs: usize) -> f64 {
    energy_ratio(dc_energy(0.0, added, coeffs), dc_energy(0.0, total, coeffs))
}

/// `sum`, plus the summed DC terms `|t[c][0]|` of `transfer` in order: continued over the
/// chunks of a transfer, it gives the sum over the whole, to the last bit.
pub fn dc_energy(sum: f64, transfer: &[f32], coeffs: usize) -> f64 {
    transfer
        .iter()
        .step_by(coeffs)
        .fold(sum, |sum, &x| sum + x.abs() as f64)
}

/// The energy a bounce `added` over the `total` before it (zero when there was none).
pub fn energy_ratio(added: f64, total: f64) -> f64 {
    if total == 0.0 {
        0.0
    } else {
        added / total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::{Ray, RAY_T_MAX};

    #[test]
    fn packet_visibility_gives_the_single_ray_transfer_and_hits() {
        use crate::bake::{BakeInputs, NoProgress};
        use crate::sampling::Sampling;
        use crate::scene::{self, prepare::prepare};
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
        let (mesh, _) = prepare(scene::load(&path).unwrap()).unwrap();
        for sampling in [Sampling::Stratified, Sampling::Cosine] {
            let owned = BakeInputs::with_sampling(&mesh, 3, 144, 2, sampling);
            let inputs = owned.view();
            let (transfer, matrix, rays) =
                direct_transfer_and_gather_matrix_cpu(&inputs, &NoProgress);
            let (shadowed, shadowed_rays) =
                cpu::direct_transfer(&inputs, Mode::Shadowed, &NoProgress);
            assert_eq!(transfer, shadowed, "{sampling:?}");
            assert_eq!(rays, shadowed_rays, "{sampling:?}");
            // Rows from closest hits of every ray above the horizon, one ray at a time.
            let mut entries = 0;
            for v in 0..inputs.origins.len() {
                let normal = inputs.normals[v];
                let to_world = inputs.directions_of(v);
                let hits: Vec<(u32, Hit)> = (0..inputs.samples.len())
                    .filter_map(|s| {
                        let direction = to_world.world(inputs.samples.directions[s]);
                        if normal.dot(direction) <= 0.0 {
                            return None;
                        }
                        let ray = Ray::new(inputs.origins[v], direction);
                        let (triangle, hit) = inputs.bvh.closest_hit(&ray, RAY_T_MAX)?;
                        Some((
                            s as u32,
                            Hit {
                                triangle,
                                u: hit.u,
                                v: hit.v,
                            },
                        ))
                    })
                    .collect();
                let row = gather_row(&inputs, v, &hits);
                let (columns, weights) = matrix.row(v);
                let expected: (Vec<u32>, Vec<f32>) = row.into_iter().unzip();
                assert_eq!(
                    (columns, weights),
                    (&expected.0[..], &expected.1[..]),
                    "vertex {v}"
                );
                entries += columns.len();
            }
            assert!(entries > 0, "{sampling:?}: nothing gathered");
        }
    }

    #[test]
    fn rows_merge_duplicate_columns_and_keep_them_sorted() {
        let matrix =
            GatherMatrix::from_rows(vec![vec![(2, 0.5), (7, 0.25)], vec![], vec![(0, 1.0)]]);
        assert_eq!(matrix.rows(), 3);
        assert_eq!(matrix.row(0), (&[2u32, 7][..], &[0.5f32, 0.25][..]));
        assert_eq!(matrix.row(1).0.len(), 0);
        assert_eq!(matrix.max_row_len(), 2);
    }

    #[test]
    fn a_bounce_scales_by_albedo_and_weights() {
        // Vertex 0 gathers half of vertex 1's transfer; vertex 1 gathers nothing.
        let matrix = GatherMatrix::from_rows(vec![vec![(1, 0.5)], vec![]]);
        let coeffs = 1;
        let previous = vec![0.0, 0.0, 0.0, 1.0, 2.0, 4.0];
        let albedo = [Vec3::new(1.0, 0.5, 0.25), Vec3::ONE];
        let next = apply_cpu(&matrix, &previous, &albedo, coeffs);
        assert_eq!(next, vec![0.5, 0.5, 0.5, 0.0, 0.0, 0.0]);
    }
}
