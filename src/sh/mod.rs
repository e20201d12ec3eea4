//! Real spherical harmonics: the one place where the basis is defined.
//!
//! Convention (also written into every baked file, see [`CONVENTION`]):
//! - real, orthonormal on the unit sphere: `integral y_i y_j dw = delta_ij`;
//! - index `k = l(l+1) + m`, `0 <= l < bands`, `-l <= m <= l`, so `bands^2` coefficients;
//! - associated Legendre functions carry the Condon–Shortley phase `(-1)^m`;
//! - polar angle theta measured from +Z, azimuth phi from +X towards +Y, in world space
//!   (`x = sin t cos p`, `y = sin t sin p`, `z = cos t`);
//! - `y_lm = sqrt2 K_l^m P_l^m(cos t) cos(m p)` for m > 0, `sqrt2 K_l^|m| P_l^|m|(cos t) sin(|m| p)`
//!   for m < 0, `K_l^0 P_l^0(cos t)` for m = 0, with `K_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!)`.
//!
//! Evaluation never forms a factorial: the normalised functions `K_l^m P_l^m / sin^m t` obey a
//! three-term recurrence whose coefficients stay near 1, and `sin^m t cos(m p)`, `sin^m t sin(m p)`
//! are the real and imaginary parts of `(x + i y)^m`, built by repeated complex multiplication.
//! That keeps every band finite and orthonormal in f64 and f32 alike, and needs no trigonometry.

use glam::DVec3;

pub mod legendre;
pub mod rotation;
pub mod window;
pub mod zonal;

/// The basis in one line, for file metadata and `prt-gpu info`.
pub const CONVENTION: &str = "real orthonormal SH, k = l(l+1)+m, Condon-Shortley phase, \
theta from +Z, phi from +X towards +Y (world space, Y up)";

/// The largest band count the baker accepts.
pub const MAX_BANDS: u32 = 32;

/// `y_0`, the constant band's basis function: `1 / (2 sqrt(pi))`.
pub const Y00: f64 = 0.282_094_791_773_878_14;

/// `Ok` for a band count the baker supports (1 to [`MAX_BANDS`]).
pub fn check_bands(bands: u32) -> crate::Result<()> {
    if bands == 0 || bands > MAX_BANDS {
        return Err(crate::Error::Options(format!(
            "bands must be between 1 and {MAX_BANDS}, not {bands}"
        )));
    }
    Ok(())
}

/// Number of coefficients for `bands` bands.
pub const fn coeff_count(bands: u32) -> usize {
    (bands * bands) as usize
}

/// Flat index of coefficient (l, m).
pub const fn index(l: i32, m: i32) -> usize {
    (l * (l + 1) + m) as usize
}

/// Evaluates all `bands^2` basis functions at the unit direction `dir` into `out`.
///
/// `out.len()` must be at least `coeff_count(bands)`.
pub fn eval_basis(bands: u32, dir: DVec3, out: &mut [f64]) {
    let n = coeff_count(bands);
    assert!(
        out.len() >= n,
        "eval_basis: output holds {} < {n}",
        out.len()
    );
    if bands == 0 {
        return;
    }
    let (x, y, z) = (dir.x, dir.y, dir.z);

    // cos_m, sin_m = Re, Im of (x + i y)^m = sin^m(t) (cos m p, sin m p).
    let (mut cos_m, mut sin_m) = (1.0f64, 0.0f64);
    // diag = K_m^m P_m^m / sin^m(t), carried from one m to the next.
    let mut diag = (1.0 / (4.0 * std::f64::consts::PI)).sqrt();

    for m in 0..bands as i32 {
        if m > 0 {
            diag *= -((2 * m + 1) as f64 / (2 * m) as f64).sqrt();
            let next_cos = x * cos_m - y * sin_m;
            sin_m = x * sin_m + y * cos_m;
            cos_m = next_cos;
        }
        // Walk l upwards from m with the normalised three-term recurrence.
        let mut p_prev = 0.0;
        let mut p = diag;
        for l in m..bands as i32 {
            if l == m + 1 {
                p_prev = p;
                p *= ((2 * m + 3) as f64).sqrt() * z;
            } else if l > m + 1 {
                let (lf, mf) = (l as f64, m as f64);
                let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
                let b = (((lf - 1.0) * (lf - 1.0) - mf * mf)
                    / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0))
                    .sqrt();
                let next = a * (z * p - b * p_prev);
                p_prev = p;
                p = next;
            }
            if m == 0 {
                out[index(l, 0)] = p;
            } else {
                out[index(l, m)] = std::f64::consts::SQRT_2 * p * cos_m;
                out[index(l, -m)] = std::f64::consts::SQRT_2 * p * sin_m;
            }
        }
    }
}

/// All basis functions at `dir`, as a new vector.
pub fn basis(bands: u32, dir: DVec3) -> Vec<f64> {
    let mut out = vec![0.0; coeff_count(bands)];
    eval_basis(bands, dir, &mut out);
    out
}

/// The basis evaluated at every direction of a sample set: row `s` holds the `bands^2` values
/// at direction `s` (the tutorial's per-sample SH table). Stored as f32, the precision the GPU
/// reads; evaluated in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct ShTable {
    pub bands: u32,
    pub sample_count: usize,
    pub values: Vec<f32>,
}

impl ShTable {
    pub fn new(bands: u32, directions: &[glam::Vec3]) -> Self {
        let n = coeff_count(bands);
        let mut values = vec![0.0f32; directions.len() * n];
        let mut row = vec![0.0f64; n];
        for (dir, out) in directions.iter().zip(values.chunks_exact_mut(n)) {
            eval_basis(bands, dir.as_dvec3(), &mut row);
            for (o, v) in out.iter_mut().zip(&row) {
                *o = *v as f32;
            }
        }
        ShTable {
            bands,
            sample_count: directions.len(),
            values,
        }
    }

    pub fn row(&self, sample: usize) -> &[f32] {
        let n = coeff_count(self.bands);
        &self.values[sample * n..(sample + 1) * n]
    }
}

/// `integral max(0, cos t) y_l0 dw`: the zonal coefficients of the clamped cosine about +Z.
///
/// With `K_l = sqrt((2l+1)/(4 pi))` this is `2 pi K_l integral_0^1 t P_l(t) dt`, and the
/// Legendre integral has the closed form
/// - l = 0: 1/2; l = 1: 1/3; odd l > 1: 0 (t P_l(t) is even and P_l is orthogonal to t^0 ... t^(l-1));
/// - even l >= 2: `(-1)^(l/2 + 1) (l-2)! / (2^l (l/2 - 1)! (l/2 + 1)!)`.
///
/// The ratio of factorials is built as a running product so it stays finite for any l.
pub fn clamped_cosine_zonal(l: u32) -> f64 {
    let legendre_moment = match l {
        0 => 0.5,
        1 => 1.0 / 3.0,
        l if l % 2 == 1 => 0.0,
        l => {
            let h = l / 2;
            // (l-2)! / ((h-1)! (h+1)! 2^l), multiplied out term by term.
            let mut value = 1.0 / 8.0; // l = 2
            for j in 2..=h {
                // Going from l' = 2j-2 to 2j multiplies by (2j-3)(2j-2) / ((j-1)(j+1) * 4).
                let jf = j as f64;
                value *= (2.0 * jf - 3.0) * (2.0 * jf - 2.0) / ((jf - 1.0) * (jf + 1.0) * 4.0);
            }
            if h % 2 == 0 {
                -value
            } else {
                value
            }
        }
    };
    let k_l = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
    2.0 * std::f64::consts::PI * k_l * legendre_moment
}

/// Coefficients of a zonal function (zonal coefficients `zonal[l]` about +Z) turned so that its
/// axis points along `axis`: `sqrt(4 pi / (2l+1)) zonal[l] y_lm(axis)` (Funk–Hecke).
pub fn rotate_zonal(zonal: &[f64], axis: DVec3) -> Vec<f64> {
    zonal::lobe_coeffs(zonal, &basis(zonal.len() as u32, axis.normalize()))
}

/// Exact unshadowed diffuse transfer for a surface with normal `normal` and albedo 1:
/// `t_k = (1/pi) integral max(0, n.w) y_k(w) dw`.
pub fn unshadowed_transfer(bands: u32, normal: DVec3) -> Vec<f64> {
    let zonal: Vec<f64> = (0..bands)
        .map(|l| clamped_cosine_zonal(l) / std::f64::consts::PI)
        .collect();
    rotate_zonal(&zonal, normal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// A product quadrature exact for spherical polynomials of degree < 2 * bands.
    fn sphere_quadrature(bands: usize) -> Vec<(DVec3, f64)> {
        legendre::sphere_product_rule(bands + 1)
    }

    fn gram_error(bands: u32, eval: impl Fn(DVec3) -> Vec<f64>) -> f64 {
        let n = coeff_count(bands);
        let mut gram = vec![0.0; n * n];
        for (dir, w) in sphere_quadrature(bands as usize) {
            let y = eval(dir);
            for i in 0..n {
                for j in 0..n {
                    gram[i * n + j] += w * y[i] * y[j];
                }
            }
        }
        let mut worst: f64 = 0.0;
        for i in 0..n {
            for j in 0..n {
                let expected = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((gram[i * n + j] - expected).abs());
            }
        }
        worst
    }

    #[test]
    fn orthonormal_in_f64_up_to_max_bands() {
        for bands in [1, 2, 3, 4, 8, 16, MAX_BANDS] {
            let err = gram_error(bands, |d| basis(bands, d));
            assert!(err < 1e-10, "bands {bands}: Gram matrix off by {err}");
        }
    }

    #[test]
    fn orthonormal_as_f32_table_up_to_16_bands() {
        for bands in [4, 8, 12, 16] {
            let err = gram_error(bands, |d| {
                let table = ShTable::new(bands, &[d.as_vec3()]);
                table.values.iter().map(|&v| v as f64).collect()
            });
            assert!(err < 1e-5, "bands {bands}: f32 Gram matrix off by {err}");
        }
    }

    #[test]
    fn matches_closed_forms_up_to_band_2() {
        let c0 = 0.5 * (1.0 / PI).sqrt();
        let c1 = (3.0 / (4.0 * PI)).sqrt();
        let c2 = 0.5 * (15.0 / PI).sqrt();
        let c20 = 0.25 * (5.0 / PI).sqrt();
        let c22 = 0.25 * (15.0 / PI).sqrt();
        for dir in [
            DVec3::new(0.3, -0.5, 0.8),
            DVec3::new(-0.9, 0.1, -0.2),
            DVec3::Z,
            DVec3::NEG_Y,
            DVec3::new(1.0, 1.0, 1.0),
        ] {
            let d = dir.normalize();
            let (x, y, z) = (d.x, d.y, d.z);
            let expected = [
                c0,
                -c1 * y,
                c1 * z,
                -c1 * x,
                c2 * x * y,
                -c2 * y * z,
                c20 * (3.0 * z * z - 1.0),
                -c2 * x * z,
                c22 * (x * x - y * y),
            ];
            let got = basis(3, d);
            for (k, (g, e)) in got.iter().zip(expected).enumerate() {
                assert!((g - e).abs() < 1e-6, "{d}: k = {k}: {g} != {e}");
            }
        }
    }

    #[test]
    fn finite_at_the_poles_for_high_bands() {
        for dir in [DVec3::Z, DVec3::NEG_Z] {
            let y = basis(MAX_BANDS, dir);
            assert!(y.iter().all(|v| v.is_finite()));
            // Only m = 0 survives on the axis, where y_l0 = (+-1)^l sqrt((2l+1)/(4 pi)).
            for l in 0..MAX_BANDS as i32 {
                let expected = (dir.z.powi(l)) * ((2 * l + 1) as f64 / (4.0 * PI)).sqrt();
                assert!((y[index(l, 0)] - expected).abs() < 1e-9 * expected.abs().max(1.0));
                for m in 1..=l {
                    assert!(y[index(l, m)].abs() < 1e-12 && y[index(l, -m)].abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn clamped_cosine_zonal_matches_quadrature() {
        // integral max(0, t) P_l(t) on [0, 1] by Gauss–Legendre on the half interval.
        let nodes = legendre::gauss_legendre(64);
        for l in 0..20u32 {
            let mut moment = 0.0;
            for &(x, w) in &nodes {
                let t = 0.5 * (x + 1.0);
                let p = legendre::legendre(l as usize, t);
                moment += 0.5 * w * t * p;
            }
            let k_l = ((2 * l + 1) as f64 / (4.0 * PI)).sqrt();
            let expected = 2.0 * PI * k_l * moment;
            let got = clamped_cosine_zonal(l);
            assert!(
                (got - expected).abs() < 1e-12,
                "l = {l}: {got} != {expected}"
            );
            if l % 2 == 1 && l > 1 {
                assert_eq!(got, 0.0);
            }
        }
    }

    #[test]
    fn unshadowed_transfer_reconstructs_the_clamped_cosine_band_limit() {
        // Furnace: constant unit light has l_00 = sqrt(4 pi); exit radiance must be 1.
        for normal in [
            DVec3::Z,
            DVec3::new(0.2, -0.7, 0.4).normalize(),
            DVec3::NEG_Y,
        ] {
            let t = unshadowed_transfer(4, normal);
            let radiance = t[0] * (4.0 * PI).sqrt();
            assert!((radiance - 1.0).abs() < 1e-12, "{normal}: {radiance}");
            // Rotation invariance: each band's energy does not depend on the normal.
            let t_z = unshadowed_transfer(4, DVec3::Z);
            for l in 0..4 {
                let band =
                    |v: &[f64]| -> f64 { (-l..=l).map(|m| v[index(l, m)].powi(2)).sum::<f64>() };
                assert!((band(&t) - band(&t_z)).abs() < 1e-12);
            }
        }
    }
}
