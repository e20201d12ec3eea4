//! The top eigenvectors of a symmetric positive semi-definite matrix (a cluster's covariance).
//!
//! Small problems are diagonalised whole: Householder reduction to a tridiagonal matrix, then
//! implicit QR steps with Wilkinson's shift. Large ones (a 768-dimensional covariance of which
//! only the top 8 directions are wanted) use subspace iteration with Rayleigh–Ritz: a block a
//! little wider than the directions wanted is multiplied by the matrix, re-orthonormalised and
//! rotated onto the Ritz vectors of the block's small projected matrix (diagonalised whole)
//! until every wanted Ritz pair has a small residual. Its cost per step is `n^2 p` instead of
//! the whole diagonalisation's `n^3`, and a warm start (the previous CPCA round's basis)
//! usually converges in a step or two.
//!
//! Everything is sequential f64 in a fixed order, so the result is a function of the input.

use crate::sampling::Pcg32;

/// Implicit QR steps per eigenvalue before giving up; with Wilkinson's shift an eigenvalue
/// typically deflates in two or three.
const MAX_STEPS_PER_VALUE: usize = 30;
/// Subspace-iteration steps before settling for the block reached (still a valid orthonormal
/// basis, only not the optimal one; the caller keeps the better of it and its previous basis).
const MAX_STEPS: usize = 300;
/// A Ritz pair is converged when `|C u - theta u| <= RESIDUAL_TOLERANCE * theta_max`; the
/// captured variance is then optimal to about the square of it.
const RESIDUAL_TOLERANCE: f64 = 1e-10;
/// The fixed seed of the random vectors that start or refill a block: the result must not
/// depend on anything but the matrix and the warm start.
const BLOCK_SEED: u64 = 0x5eed_c0de_cafe;

/// Eigenvalues (descending) and eigenvectors (`vectors[i * n..(i + 1) * n]` belongs to
/// `values[i]`) of the symmetric `n x n` row-major matrix `a`: Householder reflections reduce it
/// to a tridiagonal `T = Q^T A Q`, and implicit QR steps with Wilkinson's shift diagonalise `T`,
/// their rotations gathered into `Q` (Golub & Van Loan, "Matrix Computations", 8.3). About
/// `7 n^3` operations where cyclic Jacobi took `6 n^3` per sweep and four or five sweeps.
pub fn symmetric_eigen(a: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    let Tridiagonal {
        mut diagonal,
        mut off_diagonal,
        mut basis,
    } = tridiagonalize(a, n);
    diagonalize_tridiagonal(&mut diagonal, &mut off_diagonal, &mut basis, n);
    let mut order: Vec<usize> = (0..n).collect();
    // Stable sort by descending eigenvalue; total_cmp keeps it a total order even for NaN.
    order.sort_by(|&i, &j| diagonal[j].total_cmp(&diagonal[i]));
    let values = order.iter().map(|&i| diagonal[i]).collect();
    let vectors = order
        .iter()
        .flat_map(|&i| (0..n).map(move |r| (r, i)))
        .map(|(r, i)| basis[r * n + i])
        .collect();
    (values, vectors)
}

fn identity(n: usize) -> Vec<f64> {
    let mut m = vec![0.0; n * n];
    (0..n).for_each(|i| m[i * n + i] = 1.0);
    m
}

/// `A = Q T Q^T` with `T` tridiagonal.
struct Tridiagonal {
    diagonal: Vec<f64>,
    /// `off_diagonal[i]` is `T[i][i + 1]`; the last entry is unused (0).
    off_diagonal: Vec<f64>,
    /// `Q`, row-major: its columns are the basis `T` is expressed in.
    basis: Vec<f64>,
}

/// Householder reduction: column `k` below the subdiagonal is reflected onto the subdiagonal
/// by `H = I - beta v v^T` applied from both sides, `k = 0 .. n - 2`; `Q` gathers the `H`s.
fn tridiagonalize(a: &[f64], n: usize) -> Tridiagonal {
    let mut a = a.to_vec();
    let mut q = identity(n);
    for k in 0..n.saturating_sub(2) {
        let below = k + 1;
        let mut v: Vec<f64> = (below..n).map(|i| a[i * n + k]).collect();
        if v[1..].iter().all(|&x| x == 0.0) {
            continue;
        }
        let length = norm(&v);
        // The reflection's image has the sign opposite to v[0], so that v[0] - alpha does not
        // cancel.
        let alpha = if v[0] >= 0.0 { -length } else { length };
        v[0] -= alpha;
        let beta = 2.0 / dot(&v, &v);
        let m = v.len();
        // S <- H S H for the trailing block S: with p = beta S v and
        // w = p - (beta p.v / 2) v, that is S - v w^T - w v^T.
        let p: Vec<f64> = (0..m)
            .map(|i| beta * dot(&a[(below + i) * n + below..][..m], &v))
            .collect();
        let half = 0.5 * beta * dot(&p, &v);
        let w: Vec<f64> = p.iter().zip(&v).map(|(p, v)| p - half * v).collect();
        for i in 0..m {
            let row = &mut a[(below + i) * n + below..][..m];
            for j in 0..m {
                row[j] -= v[i] * w[j] + w[i] * v[j];
            }
        }
        a[below * n + k] = alpha;
        a[k * n + below] = alpha;
        for i in below + 1..n {
            a[i * n + k] = 0.0;
            a[k * n + i] = 0.0;
        }
        // Q <- Q H.
        for row in q.chunks_exact_mut(n) {
            let tail = &mut row[below..];
            let t = beta * dot(tail, &v);
            tail.iter_mut().zip(&v).for_each(|(x, v)| *x -= t * v);
        }
    }
    Tridiagonal {
        diagonal: (0..n).map(|i| a[i * n + i]).collect(),
        off_diagonal: (0..n)
            .map(|i| if i + 1 < n { a[i * n + i + 1] } else { 0.0 })
            .collect(),
        basis: q,
    }
}

/// Implicit symmetric QR on the tridiagonal `(diagonal, off_diagonal)`, each step's rotations
/// also applied to the columns of `basis`. The trailing eigenvalue of the unreduced block is
/// split off once its off-diagonal entry is below rounding of its neighbours.
fn diagonalize_tridiagonal(
    diagonal: &mut [f64],
    off_diagonal: &mut [f64],
    basis: &mut [f64],
    n: usize,
) {
    let negligible = |e: f64, a: f64, b: f64| e.abs() <= f64::EPSILON * (a.abs() + b.abs());
    let mut steps_left = MAX_STEPS_PER_VALUE * n;
    let mut last = n.saturating_sub(1);
    while last > 0 && steps_left > 0 {
        if negligible(off_diagonal[last - 1], diagonal[last - 1], diagonal[last]) {
            off_diagonal[last - 1] = 0.0;
            last -= 1;
            continue;
        }
        let mut first = last - 1;
        while first > 0
            && !negligible(
                off_diagonal[first - 1],
                diagonal[first - 1],
                diagonal[first],
            )
        {
            first -= 1;
        }
        let shift = wilkinson_shift(diagonal[last - 1], diagonal[last], off_diagonal[last - 1]);
        qr_step(diagonal, off_diagonal, basis, n, first..=last, shift);
        steps_left -= 1;
    }
}

/// The eigenvalue of `[[a, b], [b, c]]` nearer `c`.
fn wilkinson_shift(a: f64, c: f64, b: f64) -> f64 {
    let delta = 0.5 * (a - c);
    let sign = if delta >= 0.0 { 1.0 } else { -1.0 };
    c - b * b / (delta + sign * delta.hypot(b))
}

/// One implicit QR step with `shift` on the unreduced block `range`: the first rotation is
/// the one QR of `T - shift I` would start with, and each next one chases the bulge it leaves
/// below the off-diagonal down and out of the block.
fn qr_step(
    diagonal: &mut [f64],
    off_diagonal: &mut [f64],
    basis: &mut [f64],
    n: usize,
    range: std::ops::RangeInclusive<usize>,
    shift: f64,
) {
    let (first, last) = (*range.start(), *range.end());
    let mut x = diagonal[first] - shift;
    let mut z = off_diagonal[first];
    for k in first..last {
        // R = [[c, s], [-s, c]] maps (x, z) onto (r, 0).
        let r = x.hypot(z);
        let (c, s) = if r == 0.0 { (1.0, 0.0) } else { (x / r, z / r) };
        if k > first {
            off_diagonal[k - 1] = r;
        }
        // T <- R T R^T on rows and columns k, k + 1.
        let (a, b, d) = (diagonal[k], off_diagonal[k], diagonal[k + 1]);
        diagonal[k] = c * c * a + 2.0 * c * s * b + s * s * d;
        diagonal[k + 1] = s * s * a - 2.0 * c * s * b + c * c * d;
        off_diagonal[k] = c * s * (d - a) + (c * c - s * s) * b;
        if k + 1 < last {
            // The rotation of row k + 1 puts s e[k+1] at (k, k + 2): the bulge.
            x = off_diagonal[k];
            z = s * off_diagonal[k + 1];
            off_diagonal[k + 1] *= c;
        }
        // Q <- Q R^T.
        for row in basis.chunks_exact_mut(n) {
            let (p, q) = (row[k], row[k + 1]);
            row[k] = c * p + s * q;
            row[k + 1] = c * q - s * p;
        }
    }
}

/// The `m` leading eigenvectors (rows, orthonormal) of the symmetric PSD `n x n` matrix `c`,
/// with their eigenvalues. `warm` (rows of length `n`, any number, ideally near the answer)
/// starts the subspace iteration; it does not change the answer beyond the tolerance, signs
/// included: each vector's component of largest magnitude is positive.
pub fn top_eigenvectors(c: &[f64], n: usize, m: usize, warm: &[f64]) -> (Vec<f64>, Vec<f64>) {
    if m == 0 {
        return (Vec::new(), Vec::new());
    }
    let block = block_size(n, m);
    let (values, mut vectors) = if block == n {
        // Nothing to gain from a block as wide as the space: diagonalise whole.
        let (values, vectors) = symmetric_eigen(c, n);
        (values[..m].to_vec(), vectors[..m * n].to_vec())
    } else {
        subspace_iteration(c, n, m, block, warm)
    };
    with_positive_largest_component(&mut vectors, n);
    (values, vectors)
}

/// Negates each row of `vectors` (length `n`) whose component of largest magnitude (the first
/// of equals) is negative. An eigenvector's sign is arbitrary; left to the solver, it follows
/// the warm start and the order of rounding, and flipped signs change every byte of a
/// compressed basis and its weights without changing what they reconstruct.
fn with_positive_largest_component(vectors: &mut [f64], n: usize) {
    for row in vectors.chunks_exact_mut(n) {
        let largest = row
            .iter()
            .copied()
            .reduce(|best, x| if x.abs() > best.abs() { x } else { best });
        if largest.is_some_and(|x| x < 0.0) {
            row.iter_mut().for_each(|x| *x = -*x);
        }
    }
}

/// Twice the directions wanted plus a few: the convergence rate of the m-th direction is
/// `lambda_(block+1) / lambda_m`, so slack in the block buys speed; at half the space or more,
/// a whole diagonalisation is as cheap.
fn block_size(n: usize, m: usize) -> usize {
    let block = 2 * m + 4;
    if 2 * block >= n {
        n
    } else {
        block
    }
}

fn subspace_iteration(
    c: &[f64],
    n: usize,
    m: usize,
    block: usize,
    warm: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Pcg32::new(BLOCK_SEED);
    let mut start: Vec<f64> = warm.iter().copied().take(block * n).collect();
    while start.len() < block * n {
        start.push(symmetric_unit(&mut rng));
    }
    let mut basis = orthonormalize(start, n, &mut rng);
    let mut ritz = rayleigh_ritz(c, n, &basis);
    for _ in 0..MAX_STEPS {
        if ritz.converged(n, m) {
            break;
        }
        basis = orthonormalize(ritz.product, n, &mut rng);
        ritz = rayleigh_ritz(c, n, &basis);
    }
    (ritz.values[..m].to_vec(), ritz.vectors[..m * n].to_vec())
}

/// Ritz pairs of a block: `vectors` (rows) span the block, `product` holds `C` times each.
struct Ritz {
    values: Vec<f64>,
    vectors: Vec<f64>,
    product: Vec<f64>,
}

impl Ritz {
    fn converged(&self, n: usize, m: usize) -> bool {
        let scale = self.values[0].abs();
        (0..m).all(|i| {
            let u = &self.vectors[i * n..(i + 1) * n];
            let cu = &self.product[i * n..(i + 1) * n];
            let residual: f64 = u
                .iter()
                .zip(cu)
                .map(|(u, cu)| (cu - self.values[i] * u).powi(2))
                .sum();
            residual.sqrt() <= RESIDUAL_TOLERANCE * scale
        })
    }
}

/// Rotates the orthonormal rows of `basis` onto the eigenvectors of `B C B^T`, best first.
fn rayleigh_ritz(c: &[f64], n: usize, basis: &[f64]) -> Ritz {
    let block = basis.len() / n;
    let product: Vec<f64> = basis.chunks_exact(n).flat_map(|b| mat_vec(c, b)).collect();
    let mut projected = vec![0.0; block * block];
    for i in 0..block {
        for j in 0..block {
            projected[i * block + j] = dot(&basis[i * n..(i + 1) * n], &product[j * n..][..n]);
        }
    }
    // Symmetric up to rounding; make it exactly so.
    for i in 0..block {
        for j in 0..i {
            let mean = 0.5 * (projected[i * block + j] + projected[j * block + i]);
            projected[i * block + j] = mean;
            projected[j * block + i] = mean;
        }
    }
    let (values, small) = symmetric_eigen(&projected, block);
    Ritz {
        values,
        vectors: combine(&small, basis, block, n),
        product: combine(&small, &product, block, n),
    }
}

/// Rows `sum_j coefficients[i][j] * rows[j]`.
fn combine(coefficients: &[f64], rows: &[f64], block: usize, n: usize) -> Vec<f64> {
    let mut out = vec![0.0; block * n];
    for (i, target) in out.chunks_exact_mut(n).enumerate() {
        for (j, row) in rows.chunks_exact(n).enumerate() {
            let weight = coefficients[i * block + j];
            target
                .iter_mut()
                .zip(row)
                .for_each(|(t, r)| *t += weight * r);
        }
    }
    out
}

fn mat_vec(c: &[f64], x: &[f64]) -> Vec<f64> {
    c.chunks_exact(x.len()).map(|row| dot(row, x)).collect()
}

/// A dot product with four running sums: vectorisable, and still one fixed order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0f64; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            sums[k] += x[k] * y[k];
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + tail
}

/// Orthonormal rows spanning what `rows` span, by modified Gram–Schmidt applied twice (once
/// is not enough in floating point for nearly dependent rows). A row that is (nearly) in the
/// span of those before it is replaced by a random one, so the block keeps its width.
pub fn orthonormalize(mut rows: Vec<f64>, n: usize, rng: &mut Pcg32) -> Vec<f64> {
    let count = rows.len() / n;
    for i in 0..count {
        let original = norm(&rows[i * n..(i + 1) * n]);
        let mut attempts = 0;
        loop {
            let (done, rest) = rows.split_at_mut(i * n);
            let row = &mut rest[..n];
            for _ in 0..2 {
                for previous in done.chunks_exact(n) {
                    let projection = dot(previous, row);
                    row.iter_mut()
                        .zip(previous)
                        .for_each(|(r, p)| *r -= projection * p);
                }
            }
            let length = norm(row);
            // Below 1e-10 of what it was, the row was dependent and its direction is noise.
            if length > 1e-10 * original && length > 0.0 {
                row.iter_mut().for_each(|r| *r /= length);
                break;
            }
            attempts += 1;
            assert!(
                attempts < 100,
                "no independent direction found in {n} dimensions"
            );
            row.iter_mut().for_each(|r| *r = symmetric_unit(rng));
        }
    }
    rows
}

fn norm(x: &[f64]) -> f64 {
    dot(x, x).sqrt()
}

/// Uniform in [-1, 1).
fn symmetric_unit(rng: &mut Pcg32) -> f64 {
    2.0 * rng.next_f32() as f64 - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random orthogonal matrix (rows) and `Q^T diag(values) Q`.
    fn known_matrix(values: &[f64], seed: u64) -> (Vec<f64>, Vec<f64>) {
        let n = values.len();
        let mut rng = Pcg32::new(seed);
        let random: Vec<f64> = (0..n * n).map(|_| symmetric_unit(&mut rng)).collect();
        let q = orthonormalize(random, n, &mut rng);
        let mut a = vec![0.0; n * n];
        for (k, value) in values.iter().enumerate() {
            let qk = &q[k * n..(k + 1) * n];
            for i in 0..n {
                for j in 0..n {
                    a[i * n + j] += value * qk[i] * qk[j];
                }
            }
        }
        (q, a)
    }

    fn assert_vectors_match(got: &[f64], expected: &[f64], n: usize, count: usize, tol: f64) {
        for i in 0..count {
            let alignment = dot(&got[i * n..(i + 1) * n], &expected[i * n..(i + 1) * n]).abs();
            assert!(
                (alignment - 1.0).abs() < tol,
                "eigenvector {i}: |u . q| = {alignment}"
            );
        }
    }

    #[test]
    fn whole_diagonalisation_recovers_a_known_decomposition() {
        let values: Vec<f64> = (0..30).map(|i| 10.0 * 0.7f64.powi(i) - 0.5).collect();
        let (q, a) = known_matrix(&values, 7);
        let (got_values, got_vectors) = symmetric_eigen(&a, 30);
        for (got, expected) in got_values.iter().zip(&values) {
            assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
        }
        assert_vectors_match(&got_vectors, &q, 30, 30, 1e-9);
    }

    #[test]
    fn eigenpairs_rebuild_the_matrix_with_orthonormal_vectors() {
        let mut rng = Pcg32::new(5);
        let random = |n: usize, rng: &mut Pcg32| {
            let mut a = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..=i {
                    let x = symmetric_unit(rng);
                    a[i * n + j] = x;
                    a[j * n + i] = x;
                }
            }
            a
        };
        let mut cases: Vec<(usize, Vec<f64>)> =
            [1, 2, 3, 52].map(|n| (n, random(n, &mut rng))).into();
        // Already diagonal (nothing to reflect or rotate), a repeated eigenvalue, and zero.
        cases.push((
            4,
            vec![
                3.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0,
            ],
        ));
        cases.push((20, known_matrix(&[[1.0; 10], [-2.0; 10]].concat(), 9).1));
        cases.push((5, vec![0.0; 25]));
        for (n, a) in cases {
            let (values, vectors) = symmetric_eigen(&a, n);
            assert!(values.windows(2).all(|w| w[0] >= w[1]), "{values:?}");
            let scale = a.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            for i in 0..n {
                for j in 0..n {
                    let u = |k: usize| &vectors[k * n..(k + 1) * n];
                    let d = dot(u(i), u(j));
                    let expected = if i == j { 1.0 } else { 0.0 };
                    assert!((d - expected).abs() < 1e-12, "n {n}, rows {i}, {j}: {d}");
                    let rebuilt: f64 = (0..n).map(|k| values[k] * u(k)[i] * u(k)[j]).sum();
                    let error = (rebuilt - a[i * n + j]).abs();
                    assert!(error < 1e-12 * scale, "n {n}, ({i}, {j}): off by {error}");
                }
            }
        }
    }

    #[test]
    fn subspace_iteration_finds_the_leading_directions() {
        // Slowly decaying spectrum: lambda_(block+1) / lambda_m = 0.9^12, many steps.
        let values: Vec<f64> = (0..80).map(|i| 0.9f64.powi(i)).collect();
        let (q, a) = known_matrix(&values, 11);
        for warm in [Vec::new(), q[..3 * 80].to_vec()] {
            let (got_values, got_vectors) = top_eigenvectors(&a, 80, 6, &warm);
            assert_eq!(got_vectors.len(), 6 * 80);
            for (got, expected) in got_values.iter().zip(&values) {
                assert!((got - expected).abs() < 1e-10, "{got} vs {expected}");
            }
            assert_vectors_match(&got_vectors, &q, 80, 6, 1e-8);
        }
    }

    #[test]
    fn leading_directions_have_one_sign_whatever_the_start() {
        // Both solvers (a small space is diagonalised whole, a large one iterated), started
        // cold, from the answer and from the answer negated.
        for (n, m) in [(12, 4), (80, 6)] {
            let values: Vec<f64> = (0..n).map(|i| 0.8f64.powi(i as i32)).collect();
            let (q, a) = known_matrix(&values, 13);
            let negated: Vec<f64> = q[..m * n].iter().map(|x| -x).collect();
            let starts = [Vec::new(), q[..m * n].to_vec(), negated];
            let answers: Vec<Vec<f64>> = starts
                .iter()
                .map(|warm| top_eigenvectors(&a, n, m, warm).1)
                .collect();
            for row in answers[0].chunks_exact(n) {
                let largest = row
                    .iter()
                    .fold(0.0f64, |b, &x| if x.abs() > b.abs() { x } else { b });
                assert!(largest > 0.0, "n {n}: largest component {largest}");
            }
            for other in &answers[1..] {
                for (x, y) in answers[0].iter().zip(other) {
                    assert!((x - y).abs() < 1e-8, "n {n}: {x} against {y}");
                }
            }
        }
    }

    #[test]
    fn rank_deficient_matrices_get_a_full_orthonormal_basis() {
        // Rank 2 in 60 dimensions, 5 directions asked for: 3 of them span part of the null
        // space, and all 5 must still be orthonormal.
        let mut values = vec![0.0; 60];
        values[0] = 3.0;
        values[1] = 1.0;
        let (q, a) = known_matrix(&values, 3);
        let (got_values, vectors) = top_eigenvectors(&a, 60, 5, &[]);
        assert!((got_values[0] - 3.0).abs() < 1e-12 && (got_values[1] - 1.0).abs() < 1e-12);
        assert_vectors_match(&vectors, &q, 60, 2, 1e-10);
        for i in 0..5 {
            for j in 0..5 {
                let d = dot(&vectors[i * 60..][..60], &vectors[j * 60..][..60]);
                let expected = if i == j { 1.0 } else { 0.0 };
                assert!((d - expected).abs() < 1e-12, "rows {i}, {j}: {d}");
            }
        }
        // The zero matrix too.
        let (_, zero) = top_eigenvectors(&vec![0.0; 3600], 60, 5, &[]);
        assert!((norm(&zero[..60]) - 1.0).abs() < 1e-12);
    }
}
