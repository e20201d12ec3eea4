//! A probe's transfer: the linear map from the distant light's SH coefficients to the SH
//! coefficients of the radiance arriving at the probe,
//!
//! `L_in(w) = V(w) L(w) + (1 - V(w)) L_out(q(w), -w)`,
//!
//! with `V` the probe's visibility of the sky and `L_out(q) = sum_k E_k(q) l_k` the exit
//! radiance of the surface point `q` a blocked ray reaches (its interreflected transfer,
//! interpolated from the hit triangle's vertices; zero in shadowed mode and on back faces).
//! Projected onto `y_i`, with the light `L = sum_k l_k y_k`:
//!
//! `M_ik = integral V y_i y_k dw + integral (1 - V) y_i E_k(q) dw`.
//!
//! The visible part is estimated as the identity minus its blocked part (a control variate:
//! `integral y_i y_k dw = delta_ik` exactly), so a probe with nothing around it is exactly the
//! identity and only blocked rays carry noise.

use glam::Vec3;

use crate::bake::bounce::Hit;
use crate::ray::{barycentrics, blend_at};

/// What one blocked ray of a probe contributes: its direction's SH row and, where it reaches
/// the front of a surface that reflects light, the exit transfer there (`[channel][k]`).
pub struct BlockedRay<'a> {
    pub sh: &'a [f32],
    pub exit: Option<&'a [f64]>,
}

/// `M[c][i][k]` for `channels` channels of `n = bands^2` coefficients, from the probe's
/// blocked rays, each standing for `weight` steradians. The sky's part (the identity minus
/// what is blocked) is the same for every channel and summed once; the reflected part is
/// summed per channel.
pub fn probe_matrix<'a>(
    n: usize,
    channels: usize,
    weight: f64,
    blocked: impl IntoIterator<Item = BlockedRay<'a>>,
) -> Vec<f64> {
    let mut sky = vec![0.0; n * n];
    (0..n).for_each(|i| sky[i * n + i] = 1.0);
    let mut reflected = vec![0.0; channels * n * n];
    for ray in blocked {
        for i in 0..n {
            let yi = ray.sh[i] as f64 * weight;
            for (m, &yk) in sky[i * n..(i + 1) * n].iter_mut().zip(ray.sh) {
                *m -= yi * yk as f64;
            }
            let Some(exit) = ray.exit else {
                continue;
            };
            for c in 0..channels {
                let row = &mut reflected[(c * n + i) * n..(c * n + i + 1) * n];
                for (m, e) in row.iter_mut().zip(&exit[c * n..(c + 1) * n]) {
                    *m += yi * e;
                }
            }
        }
    }
    for (c_row, r) in reflected.iter_mut().enumerate() {
        *r += sky[c_row % (n * n)];
    }
    reflected
}

/// Where a ray's hit point is and whether it reaches the surface's back (the side its
/// interpolated vertex normal points away from).
pub fn hit_point_and_side(
    positions: &[Vec3],
    normals: &[Vec3],
    triangle: [u32; 3],
    hit: Hit,
    direction: Vec3,
) -> (Vec3, bool) {
    let point = blend_at(positions, triangle, hit.u, hit.v);
    let normal = blend_at(normals, triangle, hit.u, hit.v);
    (point, normal.dot(direction) >= 0.0)
}

/// The exit transfer at a hit, `[channel][k]`: the corners' `exit` (`[vertex][channel][k]`,
/// `per_vertex` values each) weighted by the hit's barycentrics.
pub fn interpolate_exit(exit: &[f32], per_vertex: usize, triangle: [u32; 3], hit: Hit) -> Vec<f64> {
    let mut out = vec![0.0; per_vertex];
    for (&j, b) in triangle.iter().zip(barycentrics(hit.u, hit.v)) {
        let corner = &exit[j as usize * per_vertex..(j as usize + 1) * per_vertex];
        for (o, &e) in out.iter_mut().zip(corner) {
            *o += b as f64 * e as f64;
        }
    }
    out
}

/// The rows of `matrix` (`[c][i][k]`, `n` coefficients) a run-time needs for irradiance: the
/// first three bands (or all of fewer), each scaled by the clamped cosine's convolution
/// factor `A_l = sqrt(4 pi / (2l + 1)) z_l`, so that `E(n) = sum_i y_i(n) (M l)_i` is the
/// irradiance at a surface of normal `n` (Ramamoorthi and Hanrahan 2001).
pub fn irradiance_rows(matrix: &[f64], n: usize, channels: usize) -> (usize, Vec<f64>) {
    let bands = (n as f64).sqrt() as usize;
    let kept_bands = bands.min(IRRADIANCE_BANDS as usize);
    let rows = kept_bands * kept_bands;
    let mut out = Vec::with_capacity(channels * rows * n);
    for c in 0..channels {
        for i in 0..rows {
            let l = (i as f64).sqrt() as u32;
            let factor = cosine_convolution(l);
            let row = &matrix[(c * n + i) * n..(c * n + i + 1) * n];
            out.extend(row.iter().map(|m| m * factor));
        }
    }
    (rows, out)
}

/// The bands an irradiance probe keeps: beyond the third, the clamped cosine's factors are
/// below 4% of the first (`A_3 = 0`, `A_4 = -pi/24`).
pub const IRRADIANCE_BANDS: u32 = 3;

/// `A_l`: what convolving with the clamped cosine multiplies band `l` by.
pub fn cosine_convolution(l: u32) -> f64 {
    (4.0 * std::f64::consts::PI / (2 * l + 1) as f64).sqrt() * crate::sh::clamped_cosine_zonal(l)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn nothing_blocked_is_the_identity() {
        let m = probe_matrix(9, 3, 0.1, std::iter::empty());
        for c in 0..3 {
            for i in 0..9 {
                for k in 0..9 {
                    let expected = if i == k { 1.0 } else { 0.0 };
                    assert_eq!(m[(c * 9 + i) * 9 + k], expected);
                }
            }
        }
    }

    #[test]
    fn cosine_convolution_has_the_known_factors() {
        assert!((cosine_convolution(0) - PI).abs() < 1e-12);
        assert!((cosine_convolution(1) - 2.0 * PI / 3.0).abs() < 1e-12);
        assert!((cosine_convolution(2) - PI / 4.0).abs() < 1e-12);
        assert!(cosine_convolution(3).abs() < 1e-12);
        assert!((cosine_convolution(4) + PI / 24.0).abs() < 1e-12);
    }

    #[test]
    fn a_blocked_ray_removes_its_own_projection_and_adds_its_exit_light() {
        let sh = [0.5f32, 0.25];
        let exit = [2.0, 4.0];
        let ray = BlockedRay {
            sh: &sh,
            exit: Some(&exit),
        };
        let m = probe_matrix(2, 1, 0.5, [ray]);
        // M_ik = delta_ik - w y_i y_k + w y_i e_k
        let expect = |i: usize, k: usize| {
            let delta = if i == k { 1.0 } else { 0.0 };
            delta - 0.5 * sh[i] as f64 * sh[k] as f64 + 0.5 * sh[i] as f64 * exit[k]
        };
        for i in 0..2 {
            for k in 0..2 {
                assert!((m[i * 2 + k] - expect(i, k)).abs() < 1e-12);
            }
        }
    }
}
