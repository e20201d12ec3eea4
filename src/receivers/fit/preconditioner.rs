//! The fit's preconditioner: an incomplete Cholesky factor of its normal matrix.

use rayon::prelude::*;

use super::SparseMatrix;

/// `L L^T ≈ A + shift diag(A)`, with `L` lower triangular on `A`'s own pattern (incomplete
/// Cholesky without fill). On 2CylinderEngine.glb it cut the direct solve's iterations from 262
/// (the diagonal alone, Jacobi) to 94, and a bounce's from 1,428 to 464 (docs/performance.md).
/// The normal matrix is not an M-matrix (neighbouring vertices' hat functions overlap
/// positively), so the factorization can meet a pivot that is not positive; the diagonal is then
/// raised a little more until none is (Manteuffel's shift; the engine's needs 0.256).
pub(super) struct IncompleteCholesky {
    /// `L` below the diagonal and `L^T` above it, on the matrix's pattern; the diagonal unused.
    factor: SparseMatrix,
    /// Where each row's diagonal entry is in `factor`.
    diagonal_at: Vec<usize>,
    /// `1 / L_ii`.
    inverse_diagonal: Vec<f64>,
}

impl IncompleteCholesky {
    /// Shifts tried in turn, as fractions of the diagonal: none first.
    const SHIFTS: [f64; 9] = [0.0, 1e-3, 4e-3, 0.016, 0.064, 0.256, 1.024, 4.096, 16.384];

    /// The factor with the smallest shift in [`Self::SHIFTS`] that keeps every pivot positive;
    /// should none, the diagonal alone (Jacobi). A zero row (a vertex nothing constrains)
    /// factors as the identity.
    pub(super) fn of(matrix: &SparseMatrix) -> IncompleteCholesky {
        let diagonal_at = matrix.diagonal_positions();
        for shift in Self::SHIFTS {
            if let Some(factor) = Self::factor(matrix, &diagonal_at, shift) {
                return factor;
            }
        }
        let inverse_diagonal = diagonal_at
            .iter()
            .map(|&at| match matrix.values[at] {
                d if d > 0.0 => 1.0 / d.sqrt(),
                _ => 1.0,
            })
            .collect();
        IncompleteCholesky {
            factor: SparseMatrix {
                row_offsets: matrix.row_offsets.clone(),
                columns: matrix.columns.clone(),
                values: vec![0.0; matrix.values.len()],
            },
            diagonal_at,
            inverse_diagonal,
        }
    }

    /// Row by row: `L_ij = (a_ij - sum_(k<j) L_ik L_jk) / L_jj` for `j < i` on the pattern,
    /// then `L_ii = sqrt((1 + shift) a_ii - sum_(k<i) L_ik^2)`; `None` where that is not
    /// positive.
    fn factor(
        matrix: &SparseMatrix,
        diagonal_at: &[usize],
        shift: f64,
    ) -> Option<IncompleteCholesky> {
        let rows = diagonal_at.len();
        let mut values = vec![0.0; matrix.values.len()];
        let mut diagonal = vec![0.0; rows];
        for i in 0..rows {
            let row_start = matrix.row_offsets[i];
            for e in row_start..diagonal_at[i] {
                let j = matrix.columns[e] as usize;
                // sum_(k<j) L_ik L_jk over the columns rows i and j share below j.
                let row_j = matrix.row_offsets[j]..diagonal_at[j];
                let shared = merged_dot(
                    (&matrix.columns[row_start..e], &values[row_start..e]),
                    (&matrix.columns[row_j.clone()], &values[row_j]),
                );
                values[e] = (matrix.values[e] - shared) / diagonal[j];
                // L^T's entry (j, i), in row j's part above its diagonal.
                let upper = diagonal_at[j] + 1..matrix.row_offsets[j + 1];
                let at = matrix.columns[upper.clone()]
                    .binary_search(&(i as u32))
                    .expect("the pattern is symmetric");
                values[upper.start + at] = values[e];
            }
            let squares: f64 = values[row_start..diagonal_at[i]]
                .iter()
                .map(|l| l * l)
                .sum();
            let a = matrix.values[diagonal_at[i]];
            let pivot = (1.0 + shift) * a - squares;
            diagonal[i] = match (a > 0.0, pivot > 0.0) {
                (true, true) => pivot.sqrt(),
                (true, false) => return None,
                // A zero row: nothing to factor.
                (false, _) => 1.0,
            };
        }
        Some(IncompleteCholesky {
            factor: SparseMatrix {
                row_offsets: matrix.row_offsets.clone(),
                columns: matrix.columns.clone(),
                values,
            },
            diagonal_at: diagonal_at.to_vec(),
            inverse_diagonal: diagonal.iter().map(|d| 1.0 / d).collect(),
        })
    }

    /// `z = (L L^T)^-1 r` for `columns` right-hand sides stored row-major: `L y = r` from the
    /// first row down, then `L^T z = y` from the last up. Each runs row after row; the columns
    /// are independent, so groups of them run on separate threads (every column's arithmetic
    /// is the same whatever the groups).
    pub(super) fn solve(&self, r: &[f64], columns: usize, z: &mut [f64]) {
        let groups = rayon::current_num_threads().clamp(1, columns.max(1));
        let width = columns.div_ceil(groups);
        // Each group's part of every row of z.
        let mut parts: Vec<Vec<&mut [f64]>> = (0..groups)
            .map(|_| Vec::with_capacity(self.diagonal_at.len()))
            .collect();
        for row in z.chunks_mut(columns) {
            let mut rest = row;
            for part in parts.iter_mut() {
                let (head, tail) = rest.split_at_mut(width.min(rest.len()));
                part.push(head);
                rest = tail;
            }
        }
        parts
            .into_par_iter()
            .enumerate()
            .for_each(|(group, mut z_rows)| {
                let first = group * width;
                let r_rows = r.chunks(columns).map(|row| &row[first.min(row.len())..]);
                self.forward(r_rows, &mut z_rows);
                self.backward(&mut z_rows);
            });
    }

    /// `y_i = (r_i - sum_(j<i) L_ij y_j) / L_ii`, for one group of columns (`r_rows` start at
    /// the group's first column).
    fn forward<'r>(&self, r_rows: impl Iterator<Item = &'r [f64]>, y_rows: &mut [&mut [f64]]) {
        let f = &self.factor;
        for (i, r_row) in r_rows.enumerate() {
            let (done, rest) = y_rows.split_at_mut(i);
            let y = &mut *rest[0];
            y.copy_from_slice(&r_row[..y.len()]);
            for e in f.row_offsets[i]..self.diagonal_at[i] {
                let l = f.values[e];
                let y_j = &done[f.columns[e] as usize];
                y.iter_mut()
                    .zip(y_j.iter())
                    .for_each(|(y, &y_j)| *y -= l * y_j);
            }
            let d = self.inverse_diagonal[i];
            y.iter_mut().for_each(|y| *y *= d);
        }
    }

    /// `z_i = (y_i - sum_(j>i) L_ji z_j) / L_ii`, `y` replaced by `z` from the last row up.
    fn backward(&self, rows: &mut [&mut [f64]]) {
        let f = &self.factor;
        for i in (0..rows.len()).rev() {
            let (head, later) = rows.split_at_mut(i + 1);
            let z = &mut *head[i];
            for e in self.diagonal_at[i] + 1..f.row_offsets[i + 1] {
                let l = f.values[e];
                let z_j = &later[f.columns[e] as usize - i - 1];
                z.iter_mut()
                    .zip(z_j.iter())
                    .for_each(|(z, &z_j)| *z -= l * z_j);
            }
            let d = self.inverse_diagonal[i];
            z.iter_mut().for_each(|z| *z *= d);
        }
    }
}

/// `sum_k a_k b_k` over the columns two sorted sparse rows share.
fn merged_dot((a_columns, a): (&[u32], &[f64]), (b_columns, b): (&[u32], &[f64])) -> f64 {
    let (mut p, mut q, mut sum) = (0, 0, 0.0);
    while p < a_columns.len() && q < b_columns.len() {
        match a_columns[p].cmp(&b_columns[q]) {
            std::cmp::Ordering::Less => p += 1,
            std::cmp::Ordering::Greater => q += 1,
            std::cmp::Ordering::Equal => {
                sum += a[p] * b[q];
                p += 1;
                q += 1;
            }
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric matrix from its lower triangle's entries `(row, column, value)`, `row >=
    /// column`, each stored on both sides.
    fn symmetric(rows: usize, lower: &[(usize, usize, f64)]) -> SparseMatrix {
        let mut entries: Vec<Vec<(u32, f64)>> = vec![Vec::new(); rows];
        for &(r, c, v) in lower {
            entries[r].push((c as u32, v));
            if r != c {
                entries[c].push((r as u32, v));
            }
        }
        let mut matrix = SparseMatrix {
            row_offsets: vec![0],
            columns: Vec::new(),
            values: Vec::new(),
        };
        for mut row in entries {
            row.sort_by_key(|&(c, _)| c);
            for (c, v) in row {
                matrix.columns.push(c);
                matrix.values.push(v);
            }
            matrix.row_offsets.push(matrix.columns.len());
        }
        matrix
    }

    fn right_hand_sides(rows: usize, columns: usize) -> Vec<f64> {
        (0..rows * columns)
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect()
    }

    #[test]
    fn on_a_matrix_without_fill_the_factor_solves_exactly() {
        // A path's matrix is tridiagonal: its Cholesky factor has no fill, so the incomplete
        // factor is the complete one.
        let (rows, columns) = (57, 5);
        let mut lower = Vec::new();
        for i in 0..rows {
            lower.push((i, i, 2.0 + (i % 3) as f64));
            if i > 0 {
                lower.push((i, i - 1, if i % 2 == 0 { -1.0 } else { 0.7 }));
            }
        }
        let matrix = symmetric(rows, &lower);
        let r = right_hand_sides(rows, columns);
        let mut z = vec![0.0; rows * columns];
        IncompleteCholesky::of(&matrix).solve(&r, columns, &mut z);
        let mut back = vec![0.0; rows * columns];
        matrix.multiply(&z, columns, &mut back);
        for (b, r) in back.iter().zip(&r) {
            assert!((b - r).abs() < 1e-12, "{b} against {r}");
        }
    }

    #[test]
    fn the_solve_has_the_same_bits_on_any_number_of_threads() {
        // A denser pattern than a path (fill is dropped), with positive off-diagonals.
        let rows = 40;
        let mut lower = Vec::new();
        for i in 0..rows {
            lower.push((i, i, 1.0));
            for back in [1, 3, 7] {
                if i >= back {
                    lower.push((i, i - back, 0.12 * (1.0 + (i % back) as f64)));
                }
            }
        }
        let matrix = symmetric(rows, &lower);
        let factor = IncompleteCholesky::of(&matrix);
        let columns = 7;
        let r = right_hand_sides(rows, columns);
        let solve_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let mut z = vec![0.0; rows * columns];
            pool.install(|| factor.solve(&r, columns, &mut z));
            z.iter().map(|z| z.to_bits()).collect::<Vec<_>>()
        };
        let one = solve_on(1);
        assert!(one.iter().all(|&z| f64::from_bits(z).is_finite()));
        for threads in [2, 3, 8] {
            assert_eq!(solve_on(threads), one, "{threads} threads");
        }
    }

    #[test]
    fn a_pivot_that_is_not_positive_is_shifted_away_and_a_zero_row_passes_through() {
        // Kershaw's matrix (1978): positive definite (eigenvalues 3 ± 2√2), yet its incomplete
        // factor's last pivot is -5 without a shift. Row 4 is zero (its diagonal stored, as the
        // fit's pattern stores every diagonal).
        let matrix = symmetric(
            5,
            &[
                (0, 0, 3.0),
                (1, 0, -2.0),
                (1, 1, 3.0),
                (2, 1, -2.0),
                (2, 2, 3.0),
                (3, 0, 2.0),
                (3, 2, -2.0),
                (3, 3, 3.0),
                (4, 4, 0.0),
            ],
        );
        let diagonal_at = matrix.diagonal_positions();
        assert!(IncompleteCholesky::factor(&matrix, &diagonal_at, 0.0).is_none());
        let factor = IncompleteCholesky::of(&matrix);
        // With a shift the factor approximates A; preconditioned, A's residual direction is
        // kept: r · z > 0 for r ≠ 0 (the factor is positive definite).
        let r = [1.0, -2.0, 0.5, 3.0, 4.0];
        let mut z = [0.0; 5];
        factor.solve(&r, 1, &mut z);
        assert!(z.iter().all(|z| z.is_finite()), "{z:?}");
        assert!(r.iter().zip(&z).map(|(r, z)| r * z).sum::<f64>() > 0.0);
        assert_eq!(z[4], 4.0, "a zero row passes its value through");
    }
}
