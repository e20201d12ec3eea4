//! Legendre polynomials and Gauss–Legendre quadrature: the one copy the closed forms, windows
//! and quadrature-based tests share.

use glam::DVec3;
use std::f64::consts::PI;

/// `(P_0(x), ..., P_n(x))` by Bonnet's recurrence `(k+1) P_{k+1} = (2k+1) x P_k - k P_{k-1}`.
pub fn legendre_all(n: usize, x: f64) -> Vec<f64> {
    let mut p = vec![1.0; n + 1];
    if n >= 1 {
        p[1] = x;
    }
    for k in 1..n {
        let kf = k as f64;
        p[k + 1] = ((2.0 * kf + 1.0) * x * p[k] - kf * p[k - 1]) / (kf + 1.0);
    }
    p
}

/// `P_n(x)`.
pub fn legendre(n: usize, x: f64) -> f64 {
    legendre_all(n, x)[n]
}

/// `(P_n(x), P_n'(x))`, with `P_n' = n (x P_n - P_{n-1}) / (x^2 - 1)` (inside (-1, 1)).
pub fn legendre_and_derivative(n: usize, x: f64) -> (f64, f64) {
    if n == 0 {
        return (1.0, 0.0);
    }
    let p = legendre_all(n, x);
    (p[n], n as f64 * (x * p[n] - p[n - 1]) / (x * x - 1.0))
}

/// Gauss–Legendre nodes and weights on `[-1, 1]`, exact for polynomials of degree `< 2n`
/// (Newton iteration on `P_n` from the usual cosine guesses).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..100 {
                let (p, dp) = legendre_and_derivative(n, x);
                let dx = p / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let (_, dp) = legendre_and_derivative(n, x);
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Gauss–Legendre in cos(theta) times the uniform rule in phi (`n` and `2n` points): exact for
/// every spherical polynomial of degree `< 2n`, so for products of two functions of `n` bands.
pub fn sphere_product_rule(n: usize) -> Vec<(DVec3, f64)> {
    let azimuths = 2 * n;
    let mut rule = Vec::with_capacity(n * azimuths);
    for (z, weight) in gauss_legendre(n) {
        let s = (1.0 - z * z).sqrt();
        for j in 0..azimuths {
            let phi = 2.0 * PI * (j as f64 + 0.5) / azimuths as f64;
            rule.push((
                DVec3::new(s * phi.cos(), s * phi.sin(), z),
                weight * 2.0 * PI / azimuths as f64,
            ));
        }
    }
    rule
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polynomials_and_quadrature_are_right() {
        assert!((legendre(2, 0.3) - (3.0 * 0.09 - 1.0) / 2.0).abs() < 1e-15);
        assert!((legendre(3, -0.7) - (5.0 * (-0.7f64).powi(3) - 3.0 * -0.7) / 2.0).abs() < 1e-15);
        // 7 nodes integrate x^12 exactly: 2/13.
        let sum: f64 = gauss_legendre(7).iter().map(|(x, w)| w * x.powi(12)).sum();
        assert!((sum - 2.0 / 13.0).abs() < 1e-14);
        let area: f64 = sphere_product_rule(5).iter().map(|(_, w)| w).sum();
        assert!((area - 4.0 * PI).abs() < 1e-12);
    }
}
