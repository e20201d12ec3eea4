//! Least-squares vertex values (Kavan, Bargteil & Sloan, "Least Squares Vertex Baking", 2011):
//! given values baked at points on the triangles, the vertex values whose linear interpolation
//! best matches them over the surface,
//!
//! `min_x  sum_i w_i |sum_j b_ij x_j - v_i|^2 + lambda sum_(edges uv) (x_u - x_v)^2`,
//!
//! with `b_ij` point i's barycentric weight of vertex j and `w_i` the area it stands for (its
//! triangle's area over the triangle's point count), so that the first sum approximates the
//! integral of the squared error over the surface. The small edge term keeps the system
//! definite where a vertex has little support. The normal equations
//! `(B^T W B + lambda L) x = B^T W v` share one sparse symmetric positive-definite matrix with
//! the mesh's vertex adjacency as its pattern across all right-hand sides (bands² × channels),
//! solved together by conjugate gradients in f64, preconditioned by an incomplete Cholesky
//! factor (`IncompleteCholesky`).

use rayon::prelude::*;

mod preconditioner;

use preconditioner::IncompleteCholesky;

use super::{triangle_areas, SurfacePoint};
use crate::error::{Error, Result};
use crate::scene::Scene;

/// How the fit is solved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Weight of the edge term, relative to the mean diagonal of the data term.
    pub smoothness: f64,
    /// Stop once every column's residual is below this fraction of its right-hand side.
    pub tolerance: f64,
    pub max_iterations: u32,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            smoothness: 1e-6,
            tolerance: 1e-9,
            max_iterations: 2000,
        }
    }
}

/// What the solve did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitReport {
    pub iterations: u32,
    /// The largest final residual over the columns, relative to its right-hand side.
    pub relative_residual: f64,
    /// Non-zero entries of the system matrix.
    pub matrix_entries: usize,
}

/// Symmetric sparse matrix in compressed rows (every entry stored, both triangles).
struct SparseMatrix {
    row_offsets: Vec<usize>,
    columns: Vec<u32>,
    values: Vec<f64>,
}

impl SparseMatrix {
    /// The pattern of a mesh's vertex adjacency plus the diagonal, all zeros.
    fn adjacency(vertex_count: usize, triangles: &[[u32; 3]]) -> SparseMatrix {
        let mut neighbours: Vec<Vec<u32>> = (0..vertex_count as u32).map(|v| vec![v]).collect();
        for t in triangles {
            for i in 0..3 {
                for j in 0..3 {
                    neighbours[t[i] as usize].push(t[j]);
                }
            }
        }
        let mut matrix = SparseMatrix {
            row_offsets: vec![0],
            columns: Vec::new(),
            values: Vec::new(),
        };
        for mut row in neighbours {
            row.sort_unstable();
            row.dedup();
            matrix.columns.extend(row);
            matrix.row_offsets.push(matrix.columns.len());
        }
        matrix.values = vec![0.0; matrix.columns.len()];
        matrix
    }

    fn entry_mut(&mut self, row: u32, column: u32) -> &mut f64 {
        let range = self.row_offsets[row as usize]..self.row_offsets[row as usize + 1];
        let at = self.columns[range.clone()]
            .binary_search(&column)
            .expect("entry in the adjacency pattern");
        &mut self.values[range.start + at]
    }

    fn diagonal(&self) -> Vec<f64> {
        self.diagonal_positions()
            .into_iter()
            .map(|at| self.values[at])
            .collect()
    }

    /// Where each row's diagonal entry is in `values`.
    fn diagonal_positions(&self) -> Vec<usize> {
        (0..self.row_offsets.len() - 1)
            .map(|r| {
                let range = self.row_offsets[r]..self.row_offsets[r + 1];
                let at = self.columns[range.clone()]
                    .binary_search(&(r as u32))
                    .expect("every row of the normal matrix holds its diagonal");
                range.start + at
            })
            .collect()
    }

    /// `out = self * x` for `columns` right-hand sides stored row-major.
    fn multiply(&self, x: &[f64], columns: usize, out: &mut [f64]) {
        out.par_chunks_mut(columns)
            .enumerate()
            .for_each(|(r, out_row)| {
                out_row.fill(0.0);
                for e in self.row_offsets[r]..self.row_offsets[r + 1] {
                    let c = self.columns[e] as usize;
                    let a = self.values[e];
                    for (o, &xv) in out_row.iter_mut().zip(&x[c * columns..(c + 1) * columns]) {
                        *o += a * xv;
                    }
                }
            });
    }
}

/// The vertex values (`[vertex][column]`, `columns` per vertex) that best fit `values`
/// (`[point][column]`) baked at `points` on the triangles of `scene`.
///
/// The result does not depend on the order of the points: they are accumulated in a canonical
/// order (by triangle, then barycentrics).
pub fn fit_vertices(
    scene: &Scene,
    points: &[SurfacePoint],
    values: &[f32],
    columns: usize,
    options: &FitOptions,
) -> Result<(Vec<f32>, FitReport)> {
    let system = FitSystem::of(scene, points, options);
    let mut rhs = system.right_hand_side(columns);
    system.add(&mut rhs, scene, points, values)?;
    Ok(system.solve(rhs, options))
}

/// The fit's matrix, `B^T W B + lambda L`: it depends on the points alone, so one serves the
/// direct light and every bounce, whose values at the points give only new right-hand sides.
pub struct FitSystem {
    matrix: SparseMatrix,
    /// Each triangle's weight per point: its area over its point count (`w_i`).
    weights: Vec<f64>,
}

/// A right-hand side of the fit, `B^T W v`, `columns` per vertex, summed from the values at
/// the points a run at a time ([`FitSystem::add`]).
pub struct RightHandSide {
    sums: Vec<f64>,
    columns: usize,
}

impl FitSystem {
    /// The system of a fit to `points` on the triangles of `scene`.
    pub fn of(scene: &Scene, points: &[SurfacePoint], options: &FitOptions) -> FitSystem {
        let mut per_triangle = vec![0u32; scene.triangle_count()];
        for p in points {
            per_triangle[p.triangle as usize] += 1;
        }
        let weights = triangle_areas(scene)
            .iter()
            .zip(&per_triangle)
            .map(|(&area, &count)| area / count.max(1) as f64)
            .collect();
        let mut system = FitSystem {
            matrix: SparseMatrix::adjacency(scene.vertex_count(), &scene.triangles),
            weights,
        };
        for &i in &canonical_order(points) {
            let p = points[i];
            let corners = scene.triangles[p.triangle as usize];
            let weight = system.weights[p.triangle as usize];
            for a in 0..3 {
                let wa = weight * p.barycentrics[a] as f64;
                for b in 0..3 {
                    *system.matrix.entry_mut(corners[a], corners[b]) +=
                        wa * p.barycentrics[b] as f64;
                }
            }
        }
        add_edge_term(&mut system.matrix, options.smoothness);
        system
    }

    /// A right-hand side of `columns` per vertex, all zeros.
    pub fn right_hand_side(&self, columns: usize) -> RightHandSide {
        RightHandSide {
            sums: vec![0.0; (self.matrix.row_offsets.len() - 1) * columns],
            columns,
        }
    }

    /// Adds `values` (`[point][column]`) at `points` to `rhs`. The points are summed in the
    /// canonical order, so runs of whole triangles' points, added in the order of their
    /// triangles, sum to the bytes of all of them added at once.
    pub fn add(
        &self,
        rhs: &mut RightHandSide,
        scene: &Scene,
        points: &[SurfacePoint],
        values: &[f32],
    ) -> Result<()> {
        let columns = rhs.columns;
        if values.len() != points.len() * columns {
            return Err(Error::Options(format!(
                "least-squares fit: {} values for {} points of {columns} columns",
                values.len(),
                points.len()
            )));
        }
        for i in canonical_order(points) {
            let p = points[i];
            let corners = scene.triangles[p.triangle as usize];
            let weight = self.weights[p.triangle as usize];
            let value = &values[i * columns..(i + 1) * columns];
            for (&corner, &barycentric) in corners.iter().zip(&p.barycentrics) {
                let wa = weight * barycentric as f64;
                let vertex = corner as usize;
                let row = &mut rhs.sums[vertex * columns..(vertex + 1) * columns];
                for (r, &v) in row.iter_mut().zip(value) {
                    *r += wa * v as f64;
                }
            }
        }
        Ok(())
    }

    /// The vertex values that solve the system for `rhs`, and what the solve did.
    pub fn solve(&self, rhs: RightHandSide, options: &FitOptions) -> (Vec<f32>, FitReport) {
        self.solve_to_scale(rhs, options, None, &mut |_| {})
    }

    /// [`solve`](Self::solve), each column's residual measured against `scale` (one norm a
    /// column) where that is larger than the column's own right-hand side: values that add to
    /// larger ones (a bounce's, added to the direct light's) need the accuracy of the sum, not
    /// of their own. A bounce's right-hand side is a fraction of the direct light's, and noisier
    /// (rougher, which conjugate gradients resolve last), so held to its own norm it took six
    /// times the direct solve's iterations for a change far below the bake's noise.
    /// `watch` is told the largest relative residual after every iteration
    /// ([`solved_fraction`] turns it into progress).
    pub fn solve_to_scale(
        &self,
        rhs: RightHandSide,
        options: &FitOptions,
        scale: Option<&[f64]>,
        watch: &mut dyn FnMut(f64),
    ) -> (Vec<f32>, FitReport) {
        let system = (&self.matrix, rhs.columns);
        let (solution, iterations, relative_residual) =
            conjugate_gradients(system, rhs.sums, options, scale, watch);
        let report = FitReport {
            iterations,
            relative_residual,
            matrix_entries: self.matrix.values.len(),
        };
        (solution.iter().map(|&x| x as f32).collect(), report)
    }
}

impl RightHandSide {
    /// The norm of each column: the scale a solve measures its residual against.
    pub fn column_norms(&self) -> Vec<f64> {
        column_norms(&self.sums, self.columns)
    }
}

/// The norm of each column of `values` (`columns` a row).
fn column_norms(values: &[f64], columns: usize) -> Vec<f64> {
    column_dots(values, values, columns)
        .into_iter()
        .map(f64::sqrt)
        .collect()
}

/// Each column's dot product of `a` and `b` (`columns` a row), summed row by row, in order:
/// the same bits on any number of threads.
fn column_dots(a: &[f64], b: &[f64], columns: usize) -> Vec<f64> {
    let mut dots = vec![0.0; columns];
    for (ra, rb) in a.chunks(columns).zip(b.chunks(columns)) {
        for (dot, (a, b)) in dots.iter_mut().zip(ra.iter().zip(rb)) {
            *dot += a * b;
        }
    }
    dots
}

/// The order the fit sums `points` in: by triangle, then barycentrics (stable, so equal
/// points keep theirs).
fn canonical_order(points: &[SurfacePoint]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&i| {
        let p = &points[i];
        (p.triangle, p.barycentrics.map(f32::to_bits))
    });
    order
}

/// Adds `lambda (x_u - x_v)^2` for every edge, lambda relative to the mean data diagonal.
fn add_edge_term(matrix: &mut SparseMatrix, smoothness: f64) {
    let diagonal = matrix.diagonal();
    let mean = diagonal.iter().sum::<f64>() / diagonal.len().max(1) as f64;
    let lambda = smoothness * mean;
    if lambda == 0.0 {
        return;
    }
    for r in 0..matrix.row_offsets.len() - 1 {
        for e in matrix.row_offsets[r]..matrix.row_offsets[r + 1] {
            let c = matrix.columns[e] as usize;
            if c != r {
                matrix.values[e] -= lambda;
                let d = matrix.entry_mut(r as u32, r as u32);
                *d += lambda;
            }
        }
    }
}

/// Solves `matrix x = rhs` for every column at once (each with its own step lengths), from
/// x = 0, preconditioned by [`IncompleteCholesky`], until each column's residual is within the
/// tolerance of its right-hand side's norm (or of `scale`'s, where larger). Returns x, the
/// iterations run and the largest relative residual.
fn conjugate_gradients(
    (matrix, columns): (&SparseMatrix, usize),
    rhs: Vec<f64>,
    options: &FitOptions,
    scale: Option<&[f64]>,
    watch: &mut dyn FnMut(f64),
) -> (Vec<f64>, u32, f64) {
    let rows = rhs.len() / columns.max(1);
    let factor = IncompleteCholesky::of(matrix);
    let precondition = |r: &[f64], z: &mut [f64]| factor.solve(r, columns, z);
    // Two dot products at once where a pass can give both, in column_dots' order.
    let column_dots_rz_rr = |r: &[f64], z: &[f64]| -> (Vec<f64>, Vec<f64>) {
        let (mut rz, mut rr) = (vec![0.0; columns], vec![0.0; columns]);
        for (r_row, z_row) in r.chunks(columns).zip(z.chunks(columns)) {
            let sums = rz.iter_mut().zip(rr.iter_mut());
            for ((rz, rr), (&r, &z)) in sums.zip(r_row.iter().zip(z_row)) {
                *rz += r * z;
                *rr += r * r;
            }
        }
        (rz, rr)
    };
    let mut rhs_norms = column_norms(&rhs, columns);
    if let Some(scale) = scale {
        rhs_norms
            .iter_mut()
            .zip(scale)
            .for_each(|(own, &s)| *own = own.max(s));
    }
    let mut x = vec![0.0; rows * columns];
    // From x = 0 the residual starts as the right-hand side, which is not needed again.
    let mut r = rhs;
    let mut z = vec![0.0; rows * columns];
    precondition(&r, &mut z);
    let mut p = z.clone();
    let (mut rz, rr) = column_dots_rz_rr(&r, &z);
    let mut ap = vec![0.0; rows * columns];
    let worst_of = |rr: &[f64]| -> f64 {
        rr.iter()
            .zip(&rhs_norms)
            .map(|(&rr, &n)| if n > 0.0 { rr.sqrt() / n } else { 0.0 })
            .fold(0.0, f64::max)
    };
    let mut worst = worst_of(&rr);
    let mut iterations = 0;
    while worst > options.tolerance && iterations < options.max_iterations {
        matrix.multiply(&p, columns, &mut ap);
        let pap = column_dots(&p, &ap, columns);
        let alpha: Vec<f64> = rz
            .iter()
            .zip(&pap)
            .map(|(&rz, &pap)| if pap > 0.0 { rz / pap } else { 0.0 })
            .collect();
        x.par_chunks_mut(columns)
            .zip(r.par_chunks_mut(columns))
            .zip(p.par_chunks(columns).zip(ap.par_chunks(columns)))
            .for_each(|((x, r), (p, ap))| {
                for c in 0..columns {
                    x[c] += alpha[c] * p[c];
                    r[c] -= alpha[c] * ap[c];
                }
            });
        precondition(&r, &mut z);
        let (rz_next, rr) = column_dots_rz_rr(&r, &z);
        let beta: Vec<f64> = rz
            .iter()
            .zip(&rz_next)
            .map(|(&rz, &next)| if rz > 0.0 { next / rz } else { 0.0 })
            .collect();
        p.par_chunks_mut(columns)
            .zip(z.par_chunks(columns))
            .for_each(|(p, z)| {
                for c in 0..columns {
                    p[c] = z[c] + beta[c] * p[c];
                }
            });
        rz = rz_next;
        iterations += 1;
        worst = worst_of(&rr);
        watch(worst);
    }
    (x, iterations, worst)
}

/// How far a solve that starts at a relative residual of 1 has come on its way down to
/// `tolerance`, in [0, 1]: the decades done over the decades to go (conjugate gradients lose
/// residual at a roughly steady rate a decade, not a unit).
pub fn solved_fraction(relative_residual: f64, tolerance: f64) -> f64 {
    if relative_residual <= tolerance {
        return 1.0;
    }
    let under_way = (0.0..1.0).contains(&relative_residual);
    let meaningful = tolerance > 0.0 && tolerance < 1.0;
    if !(under_way && meaningful) {
        return 0.0;
    }
    (relative_residual.ln() / tolerance.ln()).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::receivers::{spread_points, PointDensity, Receivers};
    use crate::sampling::Pcg32;
    use crate::scene::builtin;
    use crate::scene::prepare::prepare;
    use glam::Vec3;

    /// A bumpy irregular surface: an icosphere, prepared.
    fn sphere() -> Scene {
        prepare(builtin::icosphere(Vec3::ZERO, 1.0, 2)).unwrap().0
    }

    /// Values of a field at the points: each column linear over every triangle, from
    /// arbitrary values at the vertices.
    fn piecewise_linear(
        scene: &Scene,
        points: &[SurfacePoint],
        vertex_values: &[f32],
        columns: usize,
    ) -> Vec<f32> {
        let mut values = Vec::with_capacity(points.len() * columns);
        for p in points {
            let corners = scene.triangles[p.triangle as usize];
            for c in 0..columns {
                values.push(
                    corners
                        .iter()
                        .zip(p.barycentrics)
                        .map(|(&v, b)| vertex_values[v as usize * columns + c] * b)
                        .sum(),
                );
            }
        }
        values
    }

    #[test]
    fn a_field_linear_over_each_triangle_is_reproduced() {
        let scene = sphere();
        let columns = 5;
        let mut rng = Pcg32::new(4);
        let truth: Vec<f32> = (0..scene.vertex_count() * columns)
            .map(|_| rng.next_f32() * 2.0 - 1.0)
            .collect();
        let points = spread_points(&scene, PointDensity::default(), 1);
        let values = piecewise_linear(&scene, &points, &truth, columns);
        let (fitted, report) =
            fit_vertices(&scene, &points, &values, columns, &FitOptions::default()).unwrap();
        let worst = fitted
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        // f32 values in, f32 out: a few ulps of 1 plus the 1e-6 edge term.
        assert!(worst < 2e-5, "largest error {worst}, {report:?}");
        assert!(report.relative_residual <= FitOptions::default().tolerance);
    }

    #[test]
    fn a_solve_held_to_a_larger_scale_stops_sooner_and_to_a_smaller_one_is_unchanged() {
        let scene = sphere();
        let columns = 3;
        let mut rng = Pcg32::new(9);
        // Rough values (noise at every point), as a bounce's are.
        let points = spread_points(&scene, PointDensity::default(), 5);
        let values: Vec<f32> = (0..points.len() * columns)
            .map(|_| 0.01 * rng.next_f32())
            .collect();
        let options = FitOptions::default();
        let system = FitSystem::of(&scene, &points, &options);
        let rhs = || {
            let mut rhs = system.right_hand_side(columns);
            system.add(&mut rhs, &scene, &points, &values).unwrap();
            rhs
        };
        let own = rhs().column_norms();
        let (plain, plain_report) = system.solve(rhs(), &options);
        // A scale below every column's own norm changes nothing, bit for bit.
        let smaller: Vec<f64> = own.iter().map(|n| 0.5 * n).collect();
        let mut watched = Vec::new();
        let (same, same_report) =
            system.solve_to_scale(rhs(), &options, Some(&smaller), &mut |r| watched.push(r));
        assert_eq!(same, plain);
        assert_eq!(same_report, plain_report);
        // The watch sees every iteration's residual, the last the report's.
        assert_eq!(watched.len(), plain_report.iterations as usize);
        assert_eq!(watched.last(), Some(&plain_report.relative_residual));
        // A hundred times larger: fewer iterations, the residual within the tolerance of it.
        let larger: Vec<f64> = own.iter().map(|n| 100.0 * n).collect();
        let (looser, looser_report) =
            system.solve_to_scale(rhs(), &options, Some(&larger), &mut |_| {});
        assert!(
            looser_report.iterations < plain_report.iterations,
            "{looser_report:?} against {plain_report:?}"
        );
        assert!(looser_report.relative_residual <= options.tolerance);
        // And the answer moves by about the looser residual's worth, far below the values.
        let moved = looser
            .iter()
            .zip(&plain)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(moved < 1e-6, "moved by {moved}");
    }

    #[test]
    fn a_solve_is_as_far_along_as_the_decades_its_residual_has_fallen() {
        let tolerance = 1e-9;
        assert_eq!(solved_fraction(1.0, tolerance), 0.0);
        assert_eq!(solved_fraction(3.0, tolerance), 0.0);
        assert_eq!(solved_fraction(f64::NAN, tolerance), 0.0);
        assert!((solved_fraction(1e-3, tolerance) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(solved_fraction(1e-9, tolerance), 1.0);
        assert_eq!(solved_fraction(0.0, tolerance), 1.0);
        let mut last = 0.0;
        for decade in 0..=9 {
            let fraction = solved_fraction(10f64.powi(-decade), tolerance);
            assert!(fraction >= last, "{decade}: {fraction} < {last}");
            last = fraction;
        }
    }

    #[test]
    fn a_constant_field_is_reproduced_with_any_smoothness() {
        let scene = sphere();
        let points = spread_points(&scene, PointDensity::default(), 2);
        let values = vec![0.75f32; points.len()];
        let options = FitOptions {
            smoothness: 10.0,
            ..FitOptions::default()
        };
        let (fitted, _) = fit_vertices(&scene, &points, &values, 1, &options).unwrap();
        assert!(fitted.iter().all(|&x| (x - 0.75).abs() < 1e-6));
    }

    #[test]
    fn the_fit_does_not_depend_on_the_order_of_the_points() {
        let scene = sphere();
        let points = spread_points(&scene, PointDensity::default(), 3);
        let receivers = Receivers::at_points(&scene, &points);
        // A smooth nonlinear field: not representable, so the fit is a genuine compromise.
        let values: Vec<f32> = receivers
            .positions
            .iter()
            .flat_map(|p| [(3.0 * p.x).sin() * p.y, p.z * p.z])
            .collect();
        let (forward, _) =
            fit_vertices(&scene, &points, &values, 2, &FitOptions::default()).unwrap();
        let mut order: Vec<usize> = (0..points.len()).collect();
        let mut rng = Pcg32::new(8);
        for i in (1..order.len()).rev() {
            order.swap(i, rng.next_u32() as usize % (i + 1));
        }
        let shuffled_points: Vec<SurfacePoint> = order.iter().map(|&i| points[i]).collect();
        let shuffled_values: Vec<f32> = order
            .iter()
            .flat_map(|&i| [values[2 * i], values[2 * i + 1]])
            .collect();
        let (shuffled, _) = fit_vertices(
            &scene,
            &shuffled_points,
            &shuffled_values,
            2,
            &FitOptions::default(),
        )
        .unwrap();
        assert_eq!(forward, shuffled);
    }

    #[test]
    fn the_fit_beats_point_values_on_a_field_it_cannot_represent() {
        // Least squares minimises the interpolant's error over the surface; sampling the field
        // at the vertices cannot do better in that norm.
        let scene = sphere();
        let field = |p: Vec3| (4.0 * p.x).sin() + p.y * p.z;
        let points = spread_points(
            &scene,
            PointDensity {
                per_vertex: 16.0,
                min_per_triangle: 3,
            },
            4,
        );
        let at = Receivers::at_points(&scene, &points);
        let values: Vec<f32> = at.positions.iter().map(|&p| field(p)).collect();
        let (fitted, _) =
            fit_vertices(&scene, &points, &values, 1, &FitOptions::default()).unwrap();
        let sampled: Vec<f32> = scene.positions.iter().map(|&p| field(p)).collect();
        let held_out = crate::receivers::uniform_points(&scene, 5000, 9);
        let truth: Vec<f32> = Receivers::at_points(&scene, &held_out)
            .positions
            .iter()
            .map(|&p| field(p))
            .collect();
        let error = |vertex_values: &[f32]| -> f64 {
            let interpolated = piecewise_linear(&scene, &held_out, vertex_values, 1);
            let sum: f64 = interpolated
                .iter()
                .zip(&truth)
                .map(|(a, b)| ((a - b) as f64).powi(2))
                .sum();
            (sum / truth.len() as f64).sqrt()
        };
        let (fit_error, sampled_error) = (error(&fitted), error(&sampled));
        assert!(
            fit_error < 0.9 * sampled_error,
            "fit {fit_error}, sampled {sampled_error}"
        );
    }

    #[test]
    fn mismatched_lengths_are_an_error() {
        let scene = sphere();
        let points = spread_points(&scene, PointDensity::default(), 1);
        assert!(fit_vertices(&scene, &points, &[0.0; 3], 1, &FitOptions::default()).is_err());
    }
}
