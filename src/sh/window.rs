//! Ringing control: per-band windows applied to SH coefficients.
//!
//! Truncating a sharp lighting function (a small sun, a bright window in an environment map)
//! to a few bands rings like a Fourier series at a step (Gibbs): the reconstruction overshoots
//! and goes negative, which shows up as dark or coloured halos. Multiplying every coefficient
//! of band `l` by a factor `h_l` that falls smoothly from `h_0 = 1` trades sharpness for less
//! ringing. `h_0 = 1` keeps the mean radiance (and so the white-furnace balance) unchanged, and
//! a per-band factor commutes with rotation, so windowing and [`super::rotation`] can be
//! applied in either order.
//!
//! The windows, for `bands` bands and width `w` (factors are 0 for `l >= w`):
//! - Hanning: `h_l = (1 + cos(pi l / w)) / 2`;
//! - Lanczos sigma factors: `h_l = sin(pi l / w) / (pi l / w)`, `h_0 = 1`;
//!
//! both with `w = bands`: the first band that would get factor 0 is the one already cut off,
//! so every kept band is attenuated as little as the window shape allows.
//! `NonNegative` depends on the coefficients, see [`non_negative_factors`]. It does not search
//! Hanning widths: for a small sun no Hanning width between 1.75 and 11 brings the 8-band
//! reconstruction above -0.16 times its mean (measured while writing this), only widths below
//! 1.7 do, which drop every band above 1. Instead it blends the identity with a window that is
//! non-negative by construction and takes the smallest blend that suffices.
//!
//! The positive window. A zonal kernel `K(t) >= 0` on `[-1, 1]` of degree `< bands` acts on a
//! band-limited projection exactly as convolution of the *true* function with `K` (the bands
//! it drops are those the projection lacks), so for any non-negative lighting the result is
//! non-negative, whatever the ringing. Its factors are the Legendre moments
//! `h_l = integral K P_l dt / integral K dt` (Funk–Hecke). The kernel used is the spherical
//! analogue of Fejér's: `K(t) = (1 + t)^e p_n(t)^2` with `p_n = sum_{j<=n} (2j+1) P_j` (the
//! band-limited delta of `n + 1` bands) and `2n + e = bands - 1`, `e` in {0, 1}, the highest
//! degree that fits.

use glam::DVec3;
use std::f64::consts::PI;

use super::legendre::{gauss_legendre, legendre_all};
use super::{coeff_count, eval_basis};

/// Which window to apply to lighting coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Window {
    /// Plain truncation.
    #[default]
    None,
    /// Hanning window of width `bands`.
    Hanning,
    /// Lanczos sigma factors of width `bands`.
    Lanczos,
    /// The least blend towards a non-negative kernel that makes the reconstruction non-negative.
    NonNegative,
}

/// `(1 + cos(pi l / w)) / 2` for `l < w`, else 0.
fn hanning(l: f64, width: f64) -> f64 {
    if l >= width {
        0.0
    } else {
        0.5 * (1.0 + (PI * l / width).cos())
    }
}

/// `sinc(pi l / w)` for `l < w`, else 0.
fn lanczos(l: f64, width: f64) -> f64 {
    if l == 0.0 {
        1.0
    } else if l >= width {
        0.0
    } else {
        let x = PI * l / width;
        x.sin() / x
    }
}

/// One factor per band `0..bands` for the data-independent windows.
///
/// `NonNegative` cannot be decided without the coefficients: here it gives all ones (no
/// window, where its search starts); use [`factors_for`] or [`non_negative_factors`].
pub fn window_factors(window: Window, bands: u32) -> Vec<f64> {
    let width = bands as f64;
    (0..bands)
        .map(|l| match window {
            Window::None | Window::NonNegative => 1.0,
            Window::Hanning => hanning(l as f64, width),
            Window::Lanczos => lanczos(l as f64, width),
        })
        .collect()
}

/// The factors `window` gives for these coefficients (`NonNegative` searches, the others are
/// [`window_factors`]).
pub fn factors_for(window: Window, coeffs: &[[f32; 3]], bands: u32) -> Vec<f64> {
    match window {
        Window::NonNegative => non_negative_factors(coeffs, bands),
        other => window_factors(other, bands),
    }
}

/// Multiplies every coefficient of band `l` by `factors[l]`.
///
/// Bands that `factors` does not reach are outside the window and become zero; coefficients
/// past the last complete band of `coeffs` are treated the same way as any other of their band.
pub fn apply_window(coeffs: &mut [[f32; 3]], factors: &[f64]) {
    for (k, rgb) in coeffs.iter_mut().enumerate() {
        let factor = factors.get(band_of(k)).copied().unwrap_or(0.0);
        *rgb = rgb.map(|c| (c as f64 * factor) as f32);
    }
}

/// The band `l` of flat index `k = l(l+1) + m`, i.e. `floor(sqrt(k))`.
fn band_of(k: usize) -> usize {
    let mut l = (k as f64).sqrt() as usize;
    // The float square root can land one off for large k; settle it exactly.
    while l * l > k {
        l -= 1;
    }
    while (l + 1) * (l + 1) <= k {
        l += 1;
    }
    l
}

/// `n` nearly uniform directions on the Fibonacci spiral.
fn fibonacci_directions(n: usize) -> Vec<DVec3> {
    let golden_angle = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden_angle * i as f64;
            DVec3::new(s * phi.cos(), s * phi.sin(), z)
        })
        .collect()
}

/// Enough directions that every lobe of `bands` bands (about `pi / bands` wide) holds many.
fn direction_count(bands: u32) -> usize {
    (40 * coeff_count(bands)).max(4096)
}

/// The reconstruction split by band: `sum_m c_lm y_lm(w)` for each band `l` and channel, so
/// that any window is a cheap weighted sum of these partial sums.
struct BandSums {
    bands: usize,
    coeffs: Vec<[f64; 3]>,
    directions: Vec<DVec3>,
    /// `sums[i * bands + l]`: band `l` at `directions[i]`.
    sums: Vec<[f64; 3]>,
}

impl BandSums {
    /// Uses the complete bands that both `bands` and `coeffs` provide.
    fn new(coeffs: &[[f32; 3]], bands: u32) -> Self {
        let complete = (0..=bands)
            .take_while(|&b| coeff_count(b) <= coeffs.len())
            .last()
            .unwrap_or(0);
        let coeffs: Vec<[f64; 3]> = coeffs[..coeff_count(complete)]
            .iter()
            .map(|c| c.map(f64::from))
            .collect();
        let directions = fibonacci_directions(direction_count(complete));
        let mut this = BandSums {
            bands: complete as usize,
            coeffs,
            directions: Vec::new(),
            sums: Vec::new(),
        };
        this.sums = directions.iter().flat_map(|&d| this.at(d)).collect();
        this.directions = directions;
        this
    }

    /// Per-band partial sums at one direction.
    fn at(&self, dir: DVec3) -> Vec<[f64; 3]> {
        let mut y = vec![0.0; self.coeffs.len()];
        eval_basis(self.bands as u32, dir, &mut y);
        (0..self.bands)
            .map(|l| {
                let band = l * l..(l + 1) * (l + 1);
                let mut sum = [0.0; 3];
                for (c, y) in self.coeffs[band.clone()].iter().zip(&y[band]) {
                    for ch in 0..3 {
                        sum[ch] += c[ch] * y;
                    }
                }
                sum
            })
            .collect()
    }

    fn windowed(partial: &[[f64; 3]], factors: &[f64], channel: usize) -> f64 {
        partial
            .iter()
            .zip(factors)
            .map(|(p, h)| p[channel] * h)
            .sum()
    }

    /// Lowest windowed value per channel over the samples, then refined by local descent from
    /// the lowest well-separated samples, since a minimum between samples can be deeper.
    fn minimum(&self, factors: &[f64]) -> [f64; 3] {
        let mut result = [0.0; 3];
        if self.bands == 0 {
            return result;
        }
        let spacing = (4.0 * PI / self.directions.len() as f64).sqrt();
        for (channel, out) in result.iter_mut().enumerate() {
            let values: Vec<f64> = self
                .sums
                .chunks_exact(self.bands)
                .map(|p| Self::windowed(p, factors, channel))
                .collect();
            let mut order: Vec<usize> = (0..values.len()).collect();
            order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
            let mut starts: Vec<DVec3> = Vec::new();
            for &i in &order {
                let d = self.directions[i];
                // Several samples near one minimum would all descend into the same basin.
                if starts.iter().all(|s| s.angle_between(d) > 4.0 * spacing) {
                    starts.push(d);
                }
                if starts.len() == 8 {
                    break;
                }
            }
            let f = |d: DVec3| Self::windowed(&self.at(d), factors, channel);
            *out = starts
                .iter()
                .map(|&s| descend(&f, s, spacing))
                .fold(values[order[0]], f64::min);
        }
        result
    }
}

/// Compass search on the sphere: try steps along two tangent directions, halve the step when
/// none improves. Derivative-free, so it works for any band count without differentiating the
/// basis.
fn descend(f: &impl Fn(DVec3) -> f64, start: DVec3, step: f64) -> f64 {
    let (mut p, mut fp, mut step) = (start, f(start), step);
    for _ in 0..400 {
        if step < 1e-9 || !fp.is_finite() {
            break;
        }
        let (t1, t2) = p.any_orthonormal_pair();
        let better = [t1, -t1, t2, -t2]
            .into_iter()
            .map(|t| (p + t * step).normalize())
            .map(|q| (q, f(q)))
            .find(|&(_, fq)| fq < fp);
        match better {
            Some((q, fq)) => (p, fp) = (q, fq),
            None => step *= 0.5,
        }
    }
    fp
}

/// Minimum of the reconstruction `sum_k c_k y_k(w)` over all channels and a dense direction set
/// (at least 4096 Fibonacci directions, about 40 per coefficient) with its lowest local minima
/// refined by descent. Uses the complete bands that both `bands` and `coeffs` provide; zero
/// bands give the zero function, minimum 0.
pub fn min_reconstruction(coeffs: &[[f32; 3]], bands: u32) -> f64 {
    let sums = BandSums::new(coeffs, bands);
    let ones = vec![1.0; sums.bands];
    sums.minimum(&ones)
        .into_iter()
        .fold(f64::INFINITY, f64::min)
}

/// The Fejér-type kernel `(1 + t)^e p_n(t)^2`, `p_n = sum_{j<=n} (2j+1) P_j`, `2n + e = bands - 1`.
fn positive_kernel(bands: usize, t: f64) -> f64 {
    let degree = bands.saturating_sub(1);
    let (e, n) = (degree % 2, degree / 2);
    let p_n: f64 = legendre_all(n, t)
        .iter()
        .enumerate()
        .map(|(j, p)| (2 * j + 1) as f64 * p)
        .sum();
    (1.0 + t).powi(e as i32) * p_n * p_n
}

/// Window factors of [`positive_kernel`]: `h_l = integral K P_l dt / integral K dt`.
fn positive_kernel_factors(bands: usize) -> Vec<f64> {
    if bands == 0 {
        return Vec::new();
    }
    // K P_l has degree <= 2 (bands - 1): `bands` nodes integrate it exactly.
    let mut moments = vec![0.0; bands];
    for (t, w) in gauss_legendre(bands) {
        let k = positive_kernel(bands, t);
        for (m, p) in moments.iter_mut().zip(legendre_all(bands - 1, t)) {
            *m += w * k * p;
        }
    }
    let k0 = moments[0];
    moments.iter().map(|m| m / k0).collect()
}

/// `(1 - s) + s h_l`: the straight path from no window (`s = 0`) to the window `h` (`s = 1`).
fn blend(h: &[f64], s: f64) -> Vec<f64> {
    h.iter().map(|h| (1.0 - s) + s * h).collect()
}

/// The least smoothing that makes the reconstruction of every channel non-negative, one factor
/// per band `0..bands`: `h_l = (1 - s) + s k_l` with `k_l` the factors of a non-negative kernel
/// (see the module docs) and the smallest `s` in `[0, 1]` that passes.
///
/// Why bisection on `s` is exact: the reconstruction at each direction is linear in `s`, so its
/// minimum over directions is concave in `s` and the passing `s` form an interval; it contains
/// `s = 1` whenever the coefficients are the projection of a non-negative function. To keep
/// `s = 1` passing strictly, the kernel's factors are mixed with 1e-4 of the mean-only window.
///
/// "Non-negative" means `min >= 1e-5 * mean` per channel over the directions of
/// [`min_reconstruction`]; the margin absorbs rounding the windowed coefficients to f32. No
/// window is applied (all factors 1) when none is needed. A channel with a negative mean
/// cannot be made non-negative by any window with `h_0 = 1`; it gets the mean-only window,
/// the closest there is. Bands of `0..bands` that `coeffs` does not fully hold get factor 0.
pub fn non_negative_factors(coeffs: &[[f32; 3]], bands: u32) -> Vec<f64> {
    let sums = BandSums::new(coeffs, bands);
    let n = sums.bands;
    let mean_only: Vec<f64> = (0..n).map(|l| if l == 0 { 1.0 } else { 0.0 }).collect();
    let pad = |mut factors: Vec<f64>| {
        factors.resize(bands as usize, 0.0);
        factors
    };
    if n == 0 {
        return pad(mean_only);
    }
    let mean = sums.coeffs[0].map(|c| c * 0.5 / PI.sqrt());
    // NaN counts as negative: no window can repair it.
    if mean.iter().any(|m| m.is_nan() || *m < 0.0) {
        return pad(mean_only);
    }
    let positive: Vec<f64> = positive_kernel_factors(n)
        .iter()
        .zip(&mean_only)
        .map(|(k, e0)| (1.0 - 1e-4) * k + 1e-4 * e0)
        .collect();
    let acceptable = |s: f64| {
        let min = sums.minimum(&blend(&positive, s));
        (0..3).all(|c| min[c] >= 1e-5 * mean[c])
    };
    if acceptable(0.0) {
        return pad(vec![1.0; n]);
    }
    // lo fails, hi passes (or is the guaranteed end of the path).
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if acceptable(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    pad(blend(&positive, hi))
}

#[cfg(test)]
mod tests {
    use super::super::legendre::legendre;
    use super::*;
    use crate::sh::rotate_zonal;

    /// Zonal coefficients of the unit-radiance cone of half-angle `a` about +Z:
    /// `2 pi K_l integral_{cos a}^1 P_l(t) dt`, where `integral_x^1 P_l = (P_{l-1}(x) -
    /// P_{l+1}(x)) / (2l + 1)` for l >= 1 (from `(2l+1) P_l = P'_{l+1} - P'_{l-1}` and
    /// `P_l(1) = 1`) and `1 - x` for l = 0.
    fn cone_zonal(bands: u32, half_angle: f64) -> Vec<f64> {
        let x = half_angle.cos();
        (0..bands as usize)
            .map(|l| {
                let integral = if l == 0 {
                    1.0 - x
                } else {
                    (legendre(l - 1, x) - legendre(l + 1, x)) / (2 * l + 1) as f64
                };
                let k_l = ((2 * l + 1) as f64 / (4.0 * PI)).sqrt();
                2.0 * PI * k_l * integral
            })
            .collect()
    }

    /// A colored 5° sun at 8 bands, in no special direction.
    fn sun(bands: u32) -> Vec<[f32; 3]> {
        let axis = DVec3::new(0.3, 0.8, -0.5).normalize();
        let scalar = rotate_zonal(&cone_zonal(bands, 5f64.to_radians()), axis);
        scalar
            .iter()
            .map(|&c| [c as f32, (0.5 * c) as f32, (2.0 * c) as f32])
            .collect()
    }

    /// The reconstruction's minimum on a latitude-longitude grid: independent of the Fibonacci
    /// set and the descent used by the code under test.
    fn grid_minimum(coeffs: &[[f32; 3]], bands: u32) -> f64 {
        let mut y = vec![0.0; coeff_count(bands)];
        let mut lowest = f64::INFINITY;
        for i in 0..=360 {
            let theta = PI * i as f64 / 360.0;
            for j in 0..720 {
                let phi = 2.0 * PI * j as f64 / 720.0;
                let d = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                eval_basis(bands, d, &mut y);
                for ch in 0..3 {
                    let v: f64 = coeffs.iter().zip(&y).map(|(c, y)| c[ch] as f64 * y).sum();
                    lowest = lowest.min(v);
                }
            }
        }
        lowest
    }

    #[test]
    fn cone_zonal_matches_quadrature() {
        // Midpoint rule on [cos a, 1] with many points as an independent check.
        let (bands, a) = (8u32, 5f64.to_radians());
        let zonal = cone_zonal(bands, a);
        let steps = 20000;
        for (l, z) in zonal.iter().enumerate() {
            let h = (1.0 - a.cos()) / steps as f64;
            let integral: f64 = (0..steps)
                .map(|i| legendre(l, a.cos() + (i as f64 + 0.5) * h) * h)
                .sum();
            let expected = 2.0 * PI * ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * integral;
            assert!((z - expected).abs() < 1e-9, "l {l}: {z} != {expected}");
        }
        // Band 0 carries the solid angle: c_00 / sqrt(4 pi) * 4 pi = 2 pi (1 - cos a).
        let solid_angle = zonal[0] * (4.0 * PI).sqrt();
        assert!((solid_angle - 2.0 * PI * (1.0 - a.cos())).abs() < 1e-12);
    }

    #[test]
    fn fixed_windows_start_at_one_and_decrease() {
        for bands in [2u32, 3, 8, 16] {
            for window in [Window::Hanning, Window::Lanczos] {
                let h = window_factors(window, bands);
                assert_eq!(h.len(), bands as usize);
                assert_eq!(h[0], 1.0, "{window:?}");
                for l in 1..bands as usize {
                    assert!(h[l] < h[l - 1] && h[l] > 0.0, "{window:?} {bands}: {h:?}");
                }
            }
            assert!(window_factors(Window::None, bands)
                .iter()
                .all(|&h| h == 1.0));
        }
        // Hanning at w = bands = 4: (1 + cos(pi l / 4)) / 2.
        let h = window_factors(Window::Hanning, 4);
        let expected = [1.0, 0.853_553_390_593_273_8, 0.5, 0.146_446_609_406_726_2];
        for (a, b) in h.iter().zip(expected) {
            assert!((a - b).abs() < 1e-15);
        }
        // Lanczos at w = 4, l = 2: sin(pi/2) / (pi/2).
        assert!((window_factors(Window::Lanczos, 4)[2] - 2.0 / PI).abs() < 1e-15);
    }

    #[test]
    fn apply_window_scales_each_band() {
        let mut c = vec![[1.0f32, 2.0, 3.0]; 9];
        apply_window(&mut c, &[1.0, 0.5]);
        assert_eq!(c[0], [1.0, 2.0, 3.0]);
        assert!(c[1..4].iter().all(|v| *v == [0.5, 1.0, 1.5]));
        // Band 2 has no factor: outside the window.
        assert!(c[4..].iter().all(|v| *v == [0.0; 3]));
        assert_eq!(band_of(15), 3);
        assert_eq!(band_of(16), 4);
    }

    #[test]
    fn non_negative_window_removes_the_ringing_of_a_small_sun() {
        let bands = 8;
        let raw = sun(bands);
        let dc = raw[0].into_iter().fold(f32::INFINITY, f32::min) as f64;
        let before = min_reconstruction(&raw, bands);
        assert!(
            before < -0.01 * dc,
            "truncated sun should ring: min {before}, dc {dc}"
        );

        let factors = factors_for(Window::NonNegative, &raw, bands);
        assert_eq!(factors.len(), bands as usize);
        let mut windowed = raw.clone();
        apply_window(&mut windowed, &factors);
        let after = min_reconstruction(&windowed, bands);
        assert!(after >= -1e-6 * dc, "windowed min {after}, dc {dc}");
        let grid = grid_minimum(&windowed, bands);
        assert!(grid >= -1e-6 * dc, "windowed grid min {grid}, dc {dc}");
        // It must still be a sun, not just the mean: the search should not over-smooth.
        assert_eq!(factors[0], 1.0);
        assert!(factors[1] > 0.5, "{factors:?}");
        println!("non-negative factors for a 5 deg sun at 8 bands: {factors:?}");
        println!("min before {before:.4e}, after {after:.3e} (grid {grid:.3e}), dc {dc:.4e}");
    }

    #[test]
    fn non_negative_window_is_minimal() {
        let bands = 8;
        let raw = sun(bands);
        let factors = non_negative_factors(&raw, bands);
        let kernel = positive_kernel_factors(bands as usize);
        // Blend back from h_1 = (1 - s) + s k_1 (k mixed with 1e-4 of the mean, as in the code).
        let k1 = (1.0 - 1e-4) * kernel[1];
        let blend_s = (1.0 - factors[1]) / (1.0 - k1);
        assert!(blend_s > 0.0 && blend_s <= 1.0, "{factors:?}");
        let mean = raw[0][1] as f64 * 0.5 / PI.sqrt();
        // Bisection stops at the boundary: 2% less blending must fail the search's test...
        let mut less = raw.clone();
        let mixed: Vec<f64> = kernel
            .iter()
            .enumerate()
            .map(|(l, k)| (1.0 - 1e-4) * k + if l == 0 { 1e-4 } else { 0.0 })
            .collect();
        apply_window(&mut less, &blend(&mixed, 0.98 * blend_s));
        assert!(min_reconstruction(&less, bands) < 1e-5 * mean);
        // ...and the fixed windows are not enough for such a sharp sun.
        for window in [Window::Hanning, Window::Lanczos] {
            let mut fixed = raw.clone();
            apply_window(&mut fixed, &window_factors(window, bands));
            assert!(min_reconstruction(&fixed, bands) < 0.0, "{window:?}");
        }
        println!("blend s = {blend_s:.4}, kernel factors {kernel:?}");
    }

    #[test]
    fn positive_kernel_is_non_negative_with_decreasing_factors() {
        for bands in 1..=16usize {
            for i in 0..=2000 {
                let t = -1.0 + i as f64 / 1000.0;
                assert!(positive_kernel(bands, t) >= 0.0);
            }
            let h = positive_kernel_factors(bands);
            assert_eq!(h.len(), bands);
            assert!((h[0] - 1.0).abs() < 1e-14);
            for l in 1..bands {
                assert!(h[l] < h[l - 1] && h[l] > 0.0, "bands {bands}: {h:?}");
            }
        }
        // bands = 2: K = 1 + t, h_1 = integral (1 + t) t / integral (1 + t) = 1/3.
        assert!((positive_kernel_factors(2)[1] - 1.0 / 3.0).abs() < 1e-14);
        // A delta (all y_lm(axis) with K = 1) windowed by it reconstructs >= 0 everywhere.
        let bands = 9u32;
        let axis = DVec3::new(-0.4, 0.2, 0.9).normalize();
        let delta: Vec<[f32; 3]> = crate::sh::basis(bands, axis)
            .iter()
            .map(|&y| [y as f32; 3])
            .collect();
        let mut windowed = delta.clone();
        apply_window(&mut windowed, &positive_kernel_factors(bands as usize));
        let peak = (0..bands as usize)
            .map(|l| (2 * l + 1) as f64 / (4.0 * PI))
            .sum::<f64>();
        assert!(min_reconstruction(&windowed, bands) >= -1e-6 * peak);
        assert!(min_reconstruction(&delta, bands) < -0.05 * peak);
    }

    #[test]
    fn non_negative_window_leaves_non_negative_functions_alone() {
        // Unit mean plus small wiggles: sum_k |c_k| max|y_k| <= 8 * 0.1 * 0.63 < 1, so the
        // function stays positive. (The 3-band clamped cosine would not do: it dips to -0.04.)
        let mut c = vec![[0.1f32, -0.1, 0.05]; 9];
        c[0] = [(4.0 * PI).sqrt() as f32; 3];
        assert!(min_reconstruction(&c, 3) >= 0.0);
        assert_eq!(non_negative_factors(&c, 3), vec![1.0; 3]);
    }

    #[test]
    fn bad_input_does_not_panic() {
        assert_eq!(min_reconstruction(&[], 4), 0.0);
        assert_eq!(non_negative_factors(&[], 3), vec![0.0; 3]);
        let short = vec![[1.0f32; 3]; 5]; // band 2 incomplete
        assert_eq!(non_negative_factors(&short, 3).len(), 3);
        let negative = vec![[-1.0f32; 3]; 9];
        assert_eq!(non_negative_factors(&negative, 3), vec![1.0, 0.0, 0.0]);
        let nan = vec![[f32::NAN; 3]; 9];
        assert_eq!(non_negative_factors(&nan, 3).len(), 3);
        assert!(window_factors(Window::Hanning, 0).is_empty());
    }
}
