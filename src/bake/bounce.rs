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

use super::{cpu, DirectInputs, Progress};
use crate::packet::{on_widest_unit, Kernel};
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

/// Gather rows one receiver at a time, `(column, weight)` with columns ascending and distinct,
/// before they are packed into a [`GatherMatrix`].
pub type GatherRows = Vec<Vec<(u32, f32)>>;

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
/// the order given. Sorted as keys of column and position, which no two entries share, so an
/// unstable sort keeps each column's order (and no merge sort's buffer is allocated).
pub(crate) fn summed_by_column(entries: Vec<(u32, f64)>) -> Vec<(u32, f64)> {
    let mut keys: Vec<u64> = entries
        .iter()
        .enumerate()
        .map(|(position, &(column, _))| (u64::from(column) << 32) | position as u64)
        .collect();
    keys.sort_unstable();
    let mut row: Vec<(u32, f64)> = Vec::with_capacity(entries.len());
    for key in keys {
        let (column, weight) = entries[key as u32 as usize];
        match row.last_mut() {
            Some((last, sum)) if *last == column => *sum += weight,
            _ => row.push((column, weight)),
        }
    }
    row
}

/// The closest hits of one vertex's rays above its horizon, `(sample, hit)` for the rays that
/// hit something, on the CPU, with its visibility bits in `visible` (set for the rays above
/// the horizon that hit nothing, as [`cpu::trace_visibility`] sets them), and the rays cast.
/// One closest-hit traversal per ray, in fans (`SampleSet::fan_runs`), gives both: on
/// dragon_vrip_res3 and the built-in scene it took 0.77x and 0.72x the time of any-hit
/// packets for the visibility followed by closest hits of the blocked rays only, whose fans
/// (directions the open rays leave gaps between) hold together less (docs/performance.md).
pub fn hits_and_visibility(
    inputs: &DirectInputs,
    vertex: usize,
    visible: &mut [u32],
) -> (Vec<(u32, Hit)>, u64) {
    let above = cpu::samples_above_horizon(inputs, vertex);
    let hits = cpu::closest_hits_of(inputs, vertex, &above);
    visible.fill(0);
    for &s in &above {
        visible[s as usize / 32] |= 1 << (s % 32);
    }
    for &(s, _) in &hits {
        visible[s as usize / 32] &= !(1 << (s % 32));
    }
    (hits, above.len() as u64)
}

/// Albedo-free direct transfer `[vertex][k]` and the gather matrix, on the CPU, from each ray's
/// closest hit ([`hits_and_visibility`]). Returns them and the rays cast (one per sample above
/// the horizon, as in shadowed mode).
pub fn direct_transfer_and_gather_matrix_cpu(
    inputs: &DirectInputs,
    progress: &dyn Progress,
) -> (Vec<f32>, GatherMatrix, u64) {
    let (per_vertex, rays) = project_and_gather_cpu(inputs, progress, |v, sums, row| {
        cpu::finish_transfer(inputs, v, sums);
        (sums.iter().map(|&t| t as f32).collect::<Vec<f32>>(), row)
    });
    let n = coeff_count(inputs.table.bands);
    let mut transfer = Vec::with_capacity(per_vertex.len() * n);
    let mut rows = Vec::with_capacity(per_vertex.len());
    for (vertex_transfer, row) in per_vertex {
        transfer.extend(vertex_transfer);
        rows.push(row);
    }
    (transfer, GatherMatrix::from_rows(rows), rays)
}

/// The projected sums `[vertex][k]` of the shadowed bake (before `cpu::finish_transfer`) and
/// each vertex's gather row, on the CPU, and the rays cast: what an interreflected bake to an
/// error target adds up batch by batch.
pub fn projected_sums_and_gather_rows_cpu(
    inputs: &DirectInputs,
    progress: &dyn Progress,
) -> (Vec<f64>, GatherRows, u64) {
    let (per_vertex, rays) =
        project_and_gather_cpu(inputs, progress, |_, sums, row| (sums.to_vec(), row));
    let (sums, rows): (Vec<Vec<f64>>, Vec<_>) = per_vertex.into_iter().unzip();
    (sums.concat(), rows, rays)
}

/// Traces every vertex's rays for their closest hits, a task of vertices at a time, and hands
/// `per_vertex` each vertex's projected sums of shadowed visibility and its gather row
/// ([`hits_and_visibility`]). Returns what it made, in vertex order, and the rays cast.
fn project_and_gather_cpu<T: Send>(
    inputs: &DirectInputs,
    progress: &dyn Progress,
    per_vertex: impl Fn(usize, &mut [f64], Vec<(u32, f32)>) -> T + Sync,
) -> (Vec<T>, u64) {
    let n = coeff_count(inputs.table.bands);
    let vertex_count = inputs.origins.len();
    let per_task: Vec<(Vec<T>, u64)> = (0..vertex_count)
        .step_by(cpu::VERTICES_PER_TASK)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|first| {
            let count = cpu::VERTICES_PER_TASK.min(vertex_count - first);
            let mut rays = 0;
            let mut sums = vec![0.0f64; n];
            let mut visible = vec![0u32; cpu::words_per_vertex(inputs.samples.len())];
            let made = (first..first + count)
                .map(|v| {
                    let (hits, cast) = hits_and_visibility(inputs, v, &mut visible);
                    rays += cast;
                    cpu::project_visibility(inputs, v, &visible, &mut sums);
                    per_vertex(v, &mut sums, gather_row(inputs, v, &hits))
                })
                .collect();
            progress.advance(count as u64);
            (made, rays)
        })
        .collect();
    let mut made = Vec::with_capacity(vertex_count);
    let mut rays = 0;
    for (task_made, task_rays) in per_task {
        made.extend(task_made);
        rays += task_rays;
    }
    (made, rays)
}

/// The gather matrix from the blocked rays' hits of every vertex, `(sample, hit)` per vertex
/// (what the GPU's closest-hit pass returns).
pub fn gather_matrix_from_vertex_hits(
    inputs: &DirectInputs,
    hits: &[Vec<(u32, Hit)>],
) -> GatherMatrix {
    GatherMatrix::from_rows(gather_rows(inputs, hits))
}

/// Every vertex's gather row ([`gather_row`]) from its rays' hits, `(sample, hit)` per vertex.
pub fn gather_rows(inputs: &DirectInputs, hits: &[Vec<(u32, Hit)>]) -> GatherRows {
    hits.par_iter()
        .enumerate()
        .map(|(v, own)| gather_row(inputs, v, own))
        .collect()
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
                let (columns, weights) = matrix.row(p);
                on_widest_unit(GatherRow {
                    row: (columns, weights),
                    previous,
                    albedo: albedo[p],
                    acc,
                    out,
                });
            },
        );
    next
}

/// One row of [`apply_cpu`], compiled for the widest vector unit (the same bits on each: no
/// copy fuses a product and a sum): its columns' transfer summed by weight into `acc`, then
/// scaled by the row's albedo into `out`.
struct GatherRow<'a> {
    row: (&'a [u32], &'a [f32]),
    previous: &'a [f32],
    albedo: Vec3,
    acc: &'a mut [f64],
    out: &'a mut [f32],
}

impl Kernel for GatherRow<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let GatherRow {
            row: (columns, weights),
            previous,
            albedo,
            acc,
            out,
        } = self;
        let stride = acc.len();
        let coeffs = stride / 3;
        acc.fill(0.0);
        for (&j, &w) in columns.iter().zip(weights) {
            let source = &previous[j as usize * stride..(j as usize + 1) * stride];
            for (a, &t) in acc.iter_mut().zip(source) {
                *a += w as f64 * t as f64;
            }
        }
        for c in 0..3 {
            for k in 0..coeffs {
                out[c * coeffs + k] = (albedo[c] as f64 * acc[c * coeffs + k]) as f32;
            }
        }
    }
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
    use crate::bake::Mode;
    use crate::ray::{Ray, RAY_T_MAX};

    #[test]
    fn a_rows_weights_are_summed_per_column_in_the_order_given() {
        // Sums that rounding makes depend on their order: 1 + 1e16 + 1 - 1e16 is 0 in f64 left
        // to right, 1 right to left.
        let entries = vec![
            (7, 1.0),
            (3, 0.5),
            (7, 1e16),
            (2, 4.0),
            (7, 1.0),
            (3, 0.25),
            (7, -1e16),
        ];
        let in_order = |column: u32| {
            let weights = entries.iter().filter(|e| e.0 == column);
            weights.fold(None, |sum: Option<f64>, e| {
                Some(sum.map_or(e.1, |s| s + e.1))
            })
        };
        let row = summed_by_column(entries.clone());
        assert_eq!(row.iter().map(|e| e.0).collect::<Vec<_>>(), [2, 3, 7]);
        for (column, sum) in row {
            assert_eq!(Some(sum), in_order(column));
        }
        assert_eq!(in_order(7), Some(0.0));
        assert_eq!(-1e16 + 1.0 + 1e16 + 1.0, 1.0);
    }

    /// The bounce compiled for this machine's widest vector unit gives the bits of the plain
    /// sum written out here (compiled for the baseline unit): weights times transfer summed
    /// in f64 in column order, then times the albedo.
    #[test]
    fn a_bounce_on_the_widest_unit_gives_the_plain_sums_bits() {
        let mut rng = crate::sampling::Pcg32::new(23);
        let (rows, coeffs) = (300, 5);
        let stride = 3 * coeffs;
        let previous: Vec<f32> = (0..rows * stride).map(|_| rng.next_f32() - 0.3).collect();
        let albedo: Vec<Vec3> = (0..rows)
            .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
            .collect();
        let matrix = GatherMatrix::from_rows(
            (0..rows)
                .map(|_| {
                    let mut columns: Vec<u32> = (0..1 + (rng.next_u32() % 40))
                        .map(|_| rng.next_u32() % rows as u32)
                        .collect();
                    columns.sort_unstable();
                    columns.dedup();
                    columns.into_iter().map(|c| (c, rng.next_f32())).collect()
                })
                .collect(),
        );
        let bounced = apply_cpu(&matrix, &previous, &albedo, coeffs);
        for p in 0..rows {
            let (columns, weights) = matrix.row(p);
            for i in 0..stride {
                let mut sum = 0.0f64;
                for (&j, &w) in columns.iter().zip(weights) {
                    sum += w as f64 * previous[j as usize * stride + i] as f64;
                }
                let expected = (albedo[p][i / coeffs] as f64 * sum) as f32;
                assert_eq!(
                    bounced[p * stride + i].to_bits(),
                    expected.to_bits(),
                    "row {p}"
                );
            }
        }
    }

    #[test]
    fn closest_hit_visibility_gives_the_shadowed_transfer_and_single_ray_hits() {
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
            // The error-targeted form: sums before they are finished, and the same rows.
            let (sums, rows, sum_rays) = projected_sums_and_gather_rows_cpu(&inputs, &NoProgress);
            let (shadowed_sums, _) = cpu::projected_sums(&inputs, Mode::Shadowed, &NoProgress);
            assert_eq!(sums, shadowed_sums, "{sampling:?}");
            assert_eq!(sum_rays, rays, "{sampling:?}");
            assert_eq!(GatherMatrix::from_rows(rows), matrix, "{sampling:?}");
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
