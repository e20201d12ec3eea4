//! Rotation of real SH coefficients for any band count.
//!
//! A rotation never mixes bands, so its matrix is block diagonal with one `(2l+1) x (2l+1)`
//! block per band. The blocks come from the Ivanic–Ruedenberg recurrence (J. Phys. Chem. 100,
//! 6342 (1996), with the erratum J. Phys. Chem. A 102, 9099 (1998)): band `l` is a sum of
//! products of the band-1 block with band `l - 1`, so no Wigner d-functions, Euler angles or
//! trigonometry are needed, and the error grows only slowly with `l`.
//!
//! **Semantics.** Rotating a lighting function `f` by the 3x3 rotation `R` gives
//! `g(w) = f(R^-1 w)`: whatever `f` had at direction `d`, `g` has at `R d` (a light along `d`
//! ends up along `R d`). [`ShRotation::apply`] maps the coefficients of `f` to those of `g`.
//!
//! **This basis versus the paper's.** Ivanic–Ruedenberg use real harmonics without the
//! Condon–Shortley phase, whose band 1 is `(y, z, x)` up to a positive factor. The basis of
//! [`crate::sh`] carries `(-1)^m`, so its band 1 is `(-y, z, -x)`: `y_lm = (-1)^m y'_lm` for
//! every band, i.e. `Y = S Y'` with `S = diag((-1)^m)`. A rotation block `D'` of the paper's
//! basis therefore becomes `D = S D' S`, entry `(m, n)` multiplied by `(-1)^(m+n)`. The
//! recurrence runs in the paper's basis (where its formulas hold as printed) and the sign
//! change is applied once per finished block.
//!
//! Band 1 in the paper's basis: `y'_1(R^-1 w) = c P R^T w` with `P` the permutation
//! `(x, y, z) -> (y, z, x)`, and since `R^T = R^-1` the coefficients move by `P R P^T`:
//! block entry `(m, n)` is `R[axis(m)][axis(n)]` with `axis(-1) = y`, `axis(0) = z`,
//! `axis(1) = x`.

use glam::DMat3;

use super::coeff_count;

/// The world axis that the paper's band-1 function `y'_1m` is proportional to.
const fn band1_axis(m: i32) -> usize {
    match m {
        -1 => 1,
        0 => 2,
        _ => 0,
    }
}

/// Position of entry `(m, n)` of the band-`l` block, row-major, `-l <= m, n <= l`.
const fn block_index(l: i32, m: i32, n: i32) -> usize {
    ((m + l) * (2 * l + 1) + (n + l)) as usize
}

/// Rotation matrix for real SH coefficients: block diagonal, one block per band.
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation {
    bands: u32,
    /// `blocks[l]` is the `(2l+1) x (2l+1)` block of band `l`, row-major; entry `(m, n)`
    /// (rows and columns ordered `-l..=l`, like the coefficient index `l(l+1) + m`) says how
    /// much input coefficient `(l, n)` contributes to output coefficient `(l, m)`.
    blocks: Vec<Vec<f64>>,
}

/// Recurrence coefficients `(u, v, w)` of Ivanic–Ruedenberg Table 1 for entry `(m, n)`.
fn uvw(l: i32, m: i32, n: i32) -> (f64, f64, f64) {
    let d = if m == 0 { 1.0 } else { 0.0 };
    let lf = l as f64;
    let am = m.abs() as f64;
    let denom = if n.abs() == l {
        2.0 * lf * (2.0 * lf - 1.0)
    } else {
        ((l + n) * (l - n)) as f64
    };
    let u = (((l + m) * (l - m)) as f64 / denom).sqrt();
    let v = 0.5 * ((1.0 + d) * (lf + am - 1.0) * (lf + am) / denom).sqrt() * (1.0 - 2.0 * d);
    let w = -0.5 * ((lf - am - 1.0) * (lf - am) / denom).sqrt() * (1.0 - d);
    (u, v, w)
}

/// The paper's auxiliary `P^l_{i; a, b}`: band-1 row `i` against band `l - 1`, where the edge
/// columns `b = +-l` (absent from band `l - 1`) combine its two edge columns.
fn p(i: i32, l: i32, a: i32, b: i32, r1: &[f64], prev: &[f64]) -> f64 {
    let r = |m: i32, n: i32| r1[block_index(1, m, n)];
    let q = |m: i32, n: i32| prev[block_index(l - 1, m, n)];
    if b == l {
        r(i, 1) * q(a, l - 1) - r(i, -1) * q(a, 1 - l)
    } else if b == -l {
        r(i, 1) * q(a, 1 - l) + r(i, -1) * q(a, l - 1)
    } else {
        r(i, 0) * q(a, b)
    }
}

/// `U^l_{mn} = P^l_{0; m, n}`.
fn big_u(l: i32, m: i32, n: i32, r1: &[f64], prev: &[f64]) -> f64 {
    p(0, l, m, n, r1, prev)
}

/// `V^l_{mn}` as corrected in the 1998 erratum (the `m < 0` case).
fn big_v(l: i32, m: i32, n: i32, r1: &[f64], prev: &[f64]) -> f64 {
    let delta = |a: i32, b: i32| if a == b { 1.0f64 } else { 0.0 };
    if m == 0 {
        p(1, l, 1, n, r1, prev) + p(-1, l, -1, n, r1, prev)
    } else if m > 0 {
        p(1, l, m - 1, n, r1, prev) * (1.0 + delta(m, 1)).sqrt()
            - p(-1, l, 1 - m, n, r1, prev) * (1.0 - delta(m, 1))
    } else {
        p(1, l, m + 1, n, r1, prev) * (1.0 - delta(m, -1))
            + p(-1, l, -m - 1, n, r1, prev) * (1.0 + delta(m, -1)).sqrt()
    }
}

/// `W^l_{mn}` (its coefficient `w` vanishes for `m = 0`, so that case never reaches here).
fn big_w(l: i32, m: i32, n: i32, r1: &[f64], prev: &[f64]) -> f64 {
    if m > 0 {
        p(1, l, m + 1, n, r1, prev) + p(-1, l, -m - 1, n, r1, prev)
    } else {
        p(1, l, m - 1, n, r1, prev) - p(-1, l, 1 - m, n, r1, prev)
    }
}

/// Band 1 in the paper's basis: `P R P^T`.
fn band1_block(rotation: &DMat3) -> Vec<f64> {
    let mut block = vec![0.0; 9];
    for m in -1..=1 {
        for n in -1..=1 {
            block[block_index(1, m, n)] = rotation.col(band1_axis(n))[band1_axis(m)];
        }
    }
    block
}

/// Band `l >= 2` in the paper's basis: `D^l_{mn} = u U + v V + w W`.
fn next_block(l: i32, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let size = (2 * l + 1) as usize;
    let mut block = vec![0.0; size * size];
    for m in -l..=l {
        for n in -l..=l {
            let (u, v, w) = uvw(l, m, n);
            // A zero coefficient multiplies a term whose indices fall outside band l - 1,
            // so the term must be skipped rather than evaluated.
            let mut value = 0.0;
            if u != 0.0 {
                value += u * big_u(l, m, n, r1, prev);
            }
            if v != 0.0 {
                value += v * big_v(l, m, n, r1, prev);
            }
            if w != 0.0 {
                value += w * big_w(l, m, n, r1, prev);
            }
            block[block_index(l, m, n)] = value;
        }
    }
    block
}

/// `D = S D' S` with `S = diag((-1)^m)`: from the paper's basis to the Condon–Shortley one.
fn to_condon_shortley(l: i32, block: &[f64]) -> Vec<f64> {
    let mut out = block.to_vec();
    for m in -l..=l {
        for n in -l..=l {
            if (m + n) % 2 != 0 {
                out[block_index(l, m, n)] = -out[block_index(l, m, n)];
            }
        }
    }
    out
}

impl ShRotation {
    /// The SH rotation for the 3x3 rotation `rotation` (see the module docs for what it does to
    /// a lighting function).
    ///
    /// Preconditions: `rotation` is a proper rotation (orthonormal, determinant +1); anything
    /// else gives a meaningless result (non-finite input gives non-finite blocks), never a
    /// panic. `bands = 0` gives the empty rotation. Any band count works, but time and memory
    /// grow as `bands^3` (about 0.25 ms at 16 bands, 2.3 ms at [`super::MAX_BANDS`] = 32).
    pub fn new(bands: u32, rotation: DMat3) -> Self {
        let mut paper_blocks: Vec<Vec<f64>> = Vec::with_capacity(bands as usize);
        for l in 0..bands as i32 {
            let block = match l {
                0 => vec![1.0],
                1 => band1_block(&rotation),
                _ => next_block(l, &paper_blocks[1], &paper_blocks[l as usize - 1]),
            };
            paper_blocks.push(block);
        }
        let blocks = paper_blocks
            .iter()
            .enumerate()
            .map(|(l, block)| to_condon_shortley(l as i32, block))
            .collect();
        ShRotation { bands, blocks }
    }

    /// The SH rotation for `R = Ry(yaw) Rx(pitch) Rz(roll)` (angles in degrees, right-handed,
    /// counter-clockwise when looking down the axis towards the origin): roll about +Z acts
    /// first, then pitch about the world +X, then yaw about the world +Y (up). A yaw of +90°
    /// turns a light at +X to -Z, and one at +Z to +X.
    pub fn from_yaw_pitch_roll(bands: u32, yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> Self {
        let r = DMat3::from_rotation_y(yaw_deg.to_radians())
            * DMat3::from_rotation_x(pitch_deg.to_radians())
            * DMat3::from_rotation_z(roll_deg.to_radians());
        Self::new(bands, r)
    }

    pub fn bands(&self) -> u32 {
        self.bands
    }

    /// The block of band `l` (row-major, see the field docs), or `None` past the last band.
    pub fn block(&self, l: u32) -> Option<&[f64]> {
        self.blocks.get(l as usize).map(Vec::as_slice)
    }

    /// Coefficients of the rotated function, `coeff_count(self.bands())` of them.
    ///
    /// `coeffs` should hold `coeff_count(self.bands())` values; a shorter input is read as if
    /// padded with zeros (a function with fewer bands), a longer one is truncated to the
    /// rotation's bands.
    pub fn apply(&self, coeffs: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; coeff_count(self.bands)];
        let input = |k: usize| coeffs.get(k).copied().unwrap_or(0.0);
        for (l, block) in self.blocks.iter().enumerate() {
            let l = l as i32;
            let start = (l * l) as usize;
            let size = (2 * l + 1) as usize;
            for (row, o) in block.chunks_exact(size).zip(&mut out[start..start + size]) {
                *o = row
                    .iter()
                    .enumerate()
                    .map(|(j, d)| d * input(start + j))
                    .sum();
            }
        }
        out
    }

    /// [`apply`](Self::apply) for RGB coefficients such as `ShLight::coeffs`, computed in f64.
    pub fn apply_rgb(&self, coeffs: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let channel = |c: usize| -> Vec<f64> {
            let values: Vec<f64> = coeffs.iter().map(|rgb| rgb[c] as f64).collect();
            self.apply(&values)
        };
        let (r, g, b) = (channel(0), channel(1), channel(2));
        r.iter()
            .zip(&g)
            .zip(&b)
            .map(|((r, g), b)| [*r as f32, *g as f32, *b as f32])
            .collect()
    }
}

/// Many rotations of one band count, each used once: the tangent-to-world turn of every vertex
/// of a cosine bake. [`ShRotation::new`] runs the recurrence for every rotation, `O(bands^3)`
/// with a large constant (2.3 ms at 32 bands). Here a rotation is split into Euler angles,
/// `R = Rz(alpha) Ry(beta) Rz(gamma)`, with `Ry(beta) = Rx(-90°) Rz(beta) Rx(90°)`: only the
/// two fixed quarter turns about x need full blocks, built once, and a turn about z mixes just
/// the pairs `(l, m)`, `(l, -m)`, `O(bands^2)`. Per rotation that leaves two block products.
#[derive(Clone, Debug)]
pub struct EulerShRotation {
    quarter_turn_x: ShRotation,
    quarter_turn_back_x: ShRotation,
}

impl EulerShRotation {
    pub fn new(bands: u32) -> Self {
        let quarter = std::f64::consts::FRAC_PI_2;
        EulerShRotation {
            quarter_turn_x: ShRotation::new(bands, DMat3::from_rotation_x(quarter)),
            quarter_turn_back_x: ShRotation::new(bands, DMat3::from_rotation_x(-quarter)),
        }
    }

    /// What `ShRotation::new(bands, rotation).apply(coeffs)` gives (to rounding), in place.
    pub fn apply(&self, rotation: &DMat3, coeffs: &mut [f64]) {
        let (alpha, beta, gamma) = zyz_angles(rotation);
        rotate_about_z(coeffs, gamma);
        let turned = self.quarter_turn_x.apply(coeffs);
        coeffs.copy_from_slice(&turned);
        rotate_about_z(coeffs, beta);
        let turned = self.quarter_turn_back_x.apply(coeffs);
        coeffs.copy_from_slice(&turned);
        rotate_about_z(coeffs, alpha);
    }
}

/// Euler angles `(alpha, beta, gamma)` with `rotation = Rz(alpha) Ry(beta) Rz(gamma)`. Where
/// `sin(beta) = 0` only `alpha + gamma` (or `alpha - gamma`) is defined, and `gamma = 0`.
fn zyz_angles(rotation: &DMat3) -> (f64, f64, f64) {
    let r = |row: usize, col: usize| rotation.col(col)[row];
    let sin_beta = r(0, 2).hypot(r(1, 2));
    let beta = sin_beta.atan2(r(2, 2));
    if sin_beta > 1e-12 {
        (r(1, 2).atan2(r(0, 2)), beta, r(2, 1).atan2(-r(2, 0)))
    } else if r(2, 2) > 0.0 {
        (r(1, 0).atan2(r(0, 0)), beta, 0.0)
    } else {
        ((-r(0, 1)).atan2(r(1, 1)), beta, 0.0)
    }
}

/// Turns the function by `angle` about +z, in place: `g(phi) = f(phi - angle)` mixes the
/// `cos(m phi)` and `sin(m phi)` coefficients of each band and order.
fn rotate_about_z(coeffs: &mut [f64], angle: f64) {
    let bands = (coeffs.len() as f64).sqrt() as i32;
    for l in 1..bands {
        let centre = (l * (l + 1)) as usize;
        for m in 1..=l as usize {
            let (sin, cos) = (m as f64 * angle).sin_cos();
            let (c, s) = (coeffs[centre + m], coeffs[centre - m]);
            coeffs[centre + m] = c * cos - s * sin;
            coeffs[centre - m] = c * sin + s * cos;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::{basis, index, rotate_zonal};
    use glam::{DQuat, DVec3};

    /// A small deterministic generator (SplitMix64) so failures reproduce.
    struct Rng(u64);

    impl Rng {
        fn next_f64(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }

        fn signed(&mut self) -> f64 {
            2.0 * self.next_f64() - 1.0
        }

        /// A uniformly random rotation from a normalised Gaussian-ish quaternion.
        fn rotation(&mut self) -> DMat3 {
            loop {
                let q =
                    DQuat::from_xyzw(self.signed(), self.signed(), self.signed(), self.signed());
                let len = q.length();
                if len > 0.1 && len <= 1.0 {
                    return DMat3::from_quat(q / len);
                }
            }
        }

        fn coeffs(&mut self, bands: u32) -> Vec<f64> {
            (0..coeff_count(bands)).map(|_| self.signed()).collect()
        }
    }

    fn band_energy(coeffs: &[f64], l: i32) -> f64 {
        (-l..=l).map(|m| coeffs[index(l, m)].powi(2)).sum()
    }

    /// Exact for products of two functions of `n - 1` bands.
    fn product_quadrature(n: usize) -> Vec<(DVec3, f64)> {
        crate::sh::legendre::sphere_product_rule(n)
    }

    fn block_product(l: i32, a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; a.len()];
        for m in -l..=l {
            for n in -l..=l {
                out[block_index(l, m, n)] = (-l..=l)
                    .map(|k| a[block_index(l, m, k)] * b[block_index(l, k, n)])
                    .sum();
            }
        }
        out
    }

    #[test]
    fn euler_rotation_equals_the_recurrence_up_to_32_bands() {
        let mut rng = Rng(11);
        let tangent_frame_of = |n: glam::Vec3| {
            let [t, b, n] = crate::sampling::tangent_frame(n.normalize());
            DMat3::from_cols(t.as_dvec3(), b.as_dvec3(), n.as_dvec3())
        };
        // Random rotations, the tangent frames of cosine bakes (normals along and near the
        // poles, where the Euler angles degenerate), and pure turns about z.
        let mut rotations: Vec<DMat3> = (0..6).map(|_| rng.rotation()).collect();
        for n in [
            glam::Vec3::Z,
            glam::Vec3::NEG_Z,
            glam::Vec3::new(1e-7, 0.0, 1.0),
            glam::Vec3::new(0.0, -1e-7, -1.0),
            glam::Vec3::new(0.3, -0.5, 0.8),
            glam::Vec3::X,
        ] {
            rotations.push(tangent_frame_of(n));
        }
        rotations.push(DMat3::from_rotation_z(1.1));
        rotations.push(DMat3::from_rotation_z(-2.0) * DMat3::from_rotation_y(std::f64::consts::PI));
        // f32 tangent frames are orthonormal only to about 1e-8, which the recurrence amplifies
        // with the band (3e-6 at 32 bands), while Euler angles always describe a rotation: the
        // two are compared on the exact rotations nearest the frames.
        let exact = |r: &DMat3| DMat3::from_quat(DQuat::from_mat3(r).normalize());
        for bands in [1, 2, 4, 9, 32] {
            let euler = EulerShRotation::new(bands);
            for rotation in rotations.iter().map(exact) {
                let coeffs = rng.coeffs(bands);
                let expected = ShRotation::new(bands, rotation).apply(&coeffs);
                let mut got = coeffs.clone();
                euler.apply(&rotation, &mut got);
                let worst = got
                    .iter()
                    .zip(&expected)
                    .map(|(g, e)| (g - e).abs())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-11, "{bands} bands, {rotation:?}: off by {worst}");
            }
        }
    }

    #[test]
    fn composition_matches_product_of_rotations() {
        let mut rng = Rng(1);
        for bands in 1..=8u32 {
            for _ in 0..5 {
                let (a, b) = (rng.rotation(), rng.rotation());
                let (ra, rb, rab) = (
                    ShRotation::new(bands, a),
                    ShRotation::new(bands, b),
                    ShRotation::new(bands, a * b),
                );
                let mut worst: f64 = 0.0;
                for l in 0..bands {
                    let product =
                        block_product(l as i32, ra.block(l).unwrap(), rb.block(l).unwrap());
                    for (x, y) in product.iter().zip(rab.block(l).unwrap()) {
                        worst = worst.max((x - y).abs());
                    }
                }
                assert!(worst < 1e-10, "bands {bands}: R(a)R(b) - R(ab) = {worst}");
                // The same through apply: rotating by b then a equals rotating by ab.
                let c = rng.coeffs(bands);
                let twice = ra.apply(&rb.apply(&c));
                let once = rab.apply(&c);
                let diff = twice
                    .iter()
                    .zip(&once)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                assert!(
                    diff < 1e-10,
                    "bands {bands}: apply composition off by {diff}"
                );
            }
        }
    }

    #[test]
    fn band_energy_is_preserved_up_to_16_bands() {
        let mut rng = Rng(2);
        let bands = 16u32;
        for _ in 0..4 {
            let rotation = ShRotation::new(bands, rng.rotation());
            let c = rng.coeffs(bands);
            let rotated = rotation.apply(&c);
            for l in 0..bands as i32 {
                let (before, after) = (band_energy(&c, l), band_energy(&rotated, l));
                assert!(
                    (before - after).abs() < 1e-6 * before,
                    "f64 band {l}: {before} -> {after}"
                );
            }
            // Through the f32 RGB helper: each channel keeps its band energies.
            let rgb: Vec<[f32; 3]> = (0..coeff_count(bands))
                .map(|_| {
                    [
                        rng.signed() as f32,
                        rng.signed() as f32,
                        rng.signed() as f32,
                    ]
                })
                .collect();
            let rotated = rotation.apply_rgb(&rgb);
            assert_eq!(rotated.len(), rgb.len());
            for ch in 0..3 {
                let before: Vec<f64> = rgb.iter().map(|v| v[ch] as f64).collect();
                let after: Vec<f64> = rotated.iter().map(|v| v[ch] as f64).collect();
                for l in 0..bands as i32 {
                    let (e0, e1) = (band_energy(&before, l), band_energy(&after, l));
                    assert!(
                        (e0 - e1).abs() < 1e-6 * e0,
                        "f32 channel {ch} band {l}: {e0} -> {e1}"
                    );
                }
            }
        }
    }

    #[test]
    fn rotated_coefficients_equal_projection_of_rotated_function() {
        let mut rng = Rng(3);
        for bands in [1u32, 2, 3, 5, 8] {
            let r = rng.rotation();
            let r_inv = r.transpose();
            let c = rng.coeffs(bands);
            let n = coeff_count(bands);
            // g_k = integral f(R^-1 w) y_k(w) dw, f = sum_j c_j y_j.
            let mut projected = vec![0.0; n];
            for (w, weight) in product_quadrature(bands as usize + 1) {
                let f_at: f64 = basis(bands, r_inv * w)
                    .iter()
                    .zip(&c)
                    .map(|(y, c)| y * c)
                    .sum();
                for (g, y) in projected.iter_mut().zip(basis(bands, w)) {
                    *g += weight * f_at * y;
                }
            }
            let rotated = ShRotation::new(bands, r).apply(&c);
            for (k, (a, b)) in rotated.iter().zip(&projected).enumerate() {
                assert!((a - b).abs() < 1e-9, "bands {bands} k {k}: {a} != {b}");
            }
        }
    }

    #[test]
    fn band1_block_is_signed_permutation_of_the_matrix() {
        let mut rng = Rng(4);
        let r = rng.rotation();
        let at = |i: usize, j: usize| r.col(j)[i];
        let (x, y, z) = (0, 1, 2);
        // Rows/columns (-1, 0, 1) ~ (-y, z, -x): entry (m, n) = s_m s_n R[axis m][axis n].
        let expected = [
            [at(y, y), -at(y, z), at(y, x)],
            [-at(z, y), at(z, z), -at(z, x)],
            [at(x, y), -at(x, z), at(x, x)],
        ];
        let block = ShRotation::new(2, r).block(1).unwrap().to_vec();
        for (i, row) in expected.iter().enumerate() {
            for (j, e) in row.iter().enumerate() {
                assert!((block[i * 3 + j] - e).abs() < 1e-15, "({i}, {j})");
            }
        }
    }

    #[test]
    fn identity_rotation_is_identity() {
        let rotation = ShRotation::new(12, DMat3::IDENTITY);
        for l in 0..12i32 {
            let block = rotation.block(l as u32).unwrap();
            for m in -l..=l {
                for n in -l..=l {
                    let expected = if m == n { 1.0 } else { 0.0 };
                    let got = block[block_index(l, m, n)];
                    assert!((got - expected).abs() < 1e-14, "l {l} ({m}, {n}): {got}");
                }
            }
        }
        assert!(rotation.block(12).is_none());
        assert!(ShRotation::new(0, DMat3::IDENTITY).apply(&[1.0]).is_empty());
    }

    #[test]
    fn yaw_of_90_degrees_moves_a_light_from_plus_x_to_minus_z() {
        let bands = 6;
        // A sharp-ish zonal lobe (clamped cosine powers would do; any zonal shape works).
        let zonal: Vec<f64> = (0..bands).map(|l| 1.0 / (1.0 + l as f64)).collect();
        let light = rotate_zonal(&zonal, DVec3::X);
        let rotated = ShRotation::from_yaw_pitch_roll(bands as u32, 90.0, 0.0, 0.0).apply(&light);
        let expected = rotate_zonal(&zonal, DVec3::NEG_Z);
        for (a, b) in rotated.iter().zip(&expected) {
            assert!((a - b).abs() < 1e-12, "{a} != {b}");
        }
        // Pitch 90° about +X takes +Y (up) to +Z; roll 90° about +Z takes +X to +Y.
        let up = rotate_zonal(&zonal, DVec3::Y);
        let pitched = ShRotation::from_yaw_pitch_roll(bands as u32, 0.0, 90.0, 0.0).apply(&up);
        let to_z = rotate_zonal(&zonal, DVec3::Z);
        let rolled = ShRotation::from_yaw_pitch_roll(bands as u32, 0.0, 0.0, 90.0).apply(&light);
        for (a, b) in pitched.iter().zip(&to_z).chain(rolled.iter().zip(&up)) {
            assert!((a - b).abs() < 1e-12, "{a} != {b}");
        }
        // Order: roll first, then pitch, then yaw. +X -roll-> +Y -pitch-> +Z -yaw-> +X.
        let all = ShRotation::from_yaw_pitch_roll(bands as u32, 90.0, 90.0, 90.0).apply(&light);
        for (a, b) in all.iter().zip(&light) {
            assert!((a - b).abs() < 1e-12, "{a} != {b}");
        }
    }

    #[test]
    fn mismatched_lengths_do_not_panic() {
        let rotation = ShRotation::from_yaw_pitch_roll(3, 10.0, 20.0, 30.0);
        assert_eq!(rotation.apply(&[1.0, 2.0]).len(), 9);
        assert_eq!(rotation.apply(&[0.5; 20]).len(), 9);
        assert_eq!(rotation.apply_rgb(&[]).len(), 9);
        // Zero-padding: a DC-only input stays DC-only.
        let dc = rotation.apply(&[2.0]);
        assert!((dc[0] - 2.0).abs() < 1e-15 && dc[1..].iter().all(|v| v.abs() < 1e-15));
        let nan = ShRotation::new(4, DMat3::from_cols_array(&[f64::NAN; 9]));
        assert_eq!(nan.apply(&[1.0; 16]).len(), 16);
    }
}
