//! Zonal harmonics about an axis: the closest function circularly symmetric about a direction
//! to an SH function, and relighting from one (Sloan, Luna & Snyder 2005, "Local, Deformable
//! Precomputed Radiance Transfer").
//!
//! A zonal function with coefficients `z_l` about the axis `a` has, in band `l`, the SH
//! coefficients `z_l g_l(a)` with `g_lm(a) = sqrt(4 pi / (2l+1)) y_lm(a)` (`super::rotate_zonal`).
//! By the addition theorem `|g_l(a)| = 1`, so band by band the least-squares fit of `f` is the
//! projection `z_l = <f_l, g_l(a)>`, and what the fit leaves out is `|f|^2 - sum_l z_l^2`. Under
//! a light `L` a zonal lobe gives `sum_l z_l <L_l, g_l(a)>`: the light evaluated at the axis,
//! band `l` weighted by `z_l sqrt(4 pi / (2l+1))`. Turning the surface turns only `a`.

use glam::DVec3;

use super::{basis, coeff_count, index};

/// `sqrt(4 pi / (2l+1))`: from a zonal coefficient to its lobe's SH coefficients at the axis's
/// basis values.
pub fn lobe_scale(l: u32) -> f64 {
    (4.0 * std::f64::consts::PI / (2 * l + 1) as f64).sqrt()
}

/// The zonal coefficients about the axis whose basis values are `axis_basis` (at least
/// `zonal_bands^2` of them) that fit `coeffs` best in the least-squares sense:
/// `z_l = sqrt(4 pi / (2l+1)) sum_m f_lm y_lm(a)`, for `l < zonal_bands`. `coeffs` may have more
/// bands than the fit, or fewer (missing bands are zero).
pub fn fit(coeffs: &[f32], axis_basis: &[f64], zonal_bands: u32, out: &mut [f64]) {
    let bands_given = (coeffs.len() as f64).sqrt() as u32;
    for l in 0..zonal_bands {
        out[l as usize] = if l < bands_given {
            let l = l as i32;
            let dot: f64 = (-l..=l)
                .map(|m| coeffs[index(l, m)] as f64 * axis_basis[index(l, m)])
                .sum();
            lobe_scale(l as u32) * dot
        } else {
            0.0
        };
    }
}

/// What a zonal lobe `zonal` about the axis with basis values `axis_basis` sends back under the
/// light coefficients `light` (one channel, at least `zonal.len()^2` of them or zero past them):
/// `sum_l z_l sqrt(4 pi / (2l+1)) sum_m L_lm y_lm(a)`.
pub fn relight<Z: Copy + Into<f64>>(zonal: &[Z], axis_basis: &[f64], light: &[f64]) -> f64 {
    zonal
        .iter()
        .enumerate()
        .map(|(l, &z)| {
            let l = l as i32;
            let band: f64 = (-l..=l)
                .filter_map(|m| Some(light.get(index(l, m))? * axis_basis[index(l, m)]))
                .sum();
            z.into() * lobe_scale(l as u32) * band
        })
        .sum()
}

/// The energy the zonal fits about `axis` of every function in `channels` (each its SH
/// coefficients) keep, summed: `sum_c sum_l z_cl^2`. The best axis is the one that keeps most.
pub fn kept_energy(channels: &[&[f32]], zonal_bands: u32, axis: DVec3) -> f64 {
    let y = basis(zonal_bands, axis);
    let mut zonal = vec![0.0; zonal_bands as usize];
    channels
        .iter()
        .map(|coeffs| {
            fit(coeffs, &y, zonal_bands, &mut zonal);
            zonal.iter().map(|z| z * z).sum::<f64>()
        })
        .sum()
}

/// The axis (a unit vector, on the side of `normal`) about which the zonal fits of `channels`
/// keep the most energy: the best of the normal, the direction band 1 points along and a
/// spread of directions, refined by a pattern search on the sphere. The energy is the same for
/// `a` and `-a` (odd bands change sign), so the side is a convention: that of a normal, which
/// a runtime turns with the surface as it turns the normal.
pub fn best_axis(channels: &[&[f32]], zonal_bands: u32, normal: DVec3) -> DVec3 {
    let energy = |axis: DVec3| kept_energy(channels, zonal_bands, axis);
    let mut candidates = vec![normal];
    candidates.extend(band_one_direction(channels));
    candidates.extend(spread_directions(SPREAD_DIRECTIONS));
    let (mut axis, mut best) = candidates
        .into_iter()
        .map(|axis| (axis, energy(axis)))
        .fold(
            (normal, f64::NEG_INFINITY),
            |a, b| if b.1 > a.1 { b } else { a },
        );
    // Pattern search: step along the tangent plane's four directions while one gains, else
    // halve the step.
    let mut step = 0.25;
    while step > AXIS_TOLERANCE {
        let (t, b) = tangents(axis);
        let moved = [t, -t, b, -b]
            .into_iter()
            .map(|d| (axis + step * d).normalize())
            .map(|a| (a, energy(a)))
            .fold((axis, best), |a, b| if b.1 > a.1 { b } else { a });
        if moved.1 > best {
            (axis, best) = moved;
        } else {
            step *= 0.5;
        }
    }
    if axis.dot(normal) < 0.0 {
        -axis
    } else {
        axis
    }
}

/// Directions of the sphere [`best_axis`] starts from besides the normal and band 1's.
const SPREAD_DIRECTIONS: usize = 32;

/// Where [`best_axis`]'s search stops: its step, in radians (about 0.003 degrees).
const AXIS_TOLERANCE: f64 = 5e-5;

/// The direction along which band 1 of `channels` keeps most energy: the principal
/// eigenvector of `sum_c v_c v_c^T`, `v_c` the band-1 coefficients as a vector
/// (`y_1,-1 ~ y`, `y_10 ~ z`, `y_11 ~ -x`). None when band 1 is absent or zero.
fn band_one_direction(channels: &[&[f32]]) -> Option<DVec3> {
    let vectors: Vec<DVec3> = channels
        .iter()
        .filter(|c| c.len() >= 4)
        .map(|c| DVec3::new(-c[3] as f64, -c[1] as f64, c[2] as f64))
        .collect();
    let matrix = vectors.iter().fold(glam::DMat3::ZERO, |m, v| {
        m + glam::DMat3::from_cols(*v * v.x, *v * v.y, *v * v.z)
    });
    // Power iteration from the largest vector converges for a positive semidefinite matrix.
    let mut direction = vectors.iter().copied().max_by(|a, b| {
        a.length_squared()
            .partial_cmp(&b.length_squared())
            .unwrap_or(std::cmp::Ordering::Equal)
    })?;
    for _ in 0..32 {
        direction = (matrix * direction).try_normalize()?;
    }
    Some(direction)
}

/// `count` directions spread evenly over the sphere (a spherical Fibonacci set).
fn spread_directions(count: usize) -> impl Iterator<Item = DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count).map(move |i| {
        let z = 1.0 - (2 * i + 1) as f64 / count as f64;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * i as f64;
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    })
}

/// Two unit vectors that with `axis` make an orthonormal frame.
fn tangents(axis: DVec3) -> (DVec3, DVec3) {
    let t = axis.any_orthonormal_vector();
    (t, axis.cross(t))
}

/// The SH coefficients (`zonal.len()^2`) of the zonal lobe `zonal` turned to the axis whose
/// basis values are `axis_basis`.
pub fn lobe_coeffs<Z: Copy + Into<f64>>(zonal: &[Z], axis_basis: &[f64]) -> Vec<f64> {
    let bands = zonal.len() as u32;
    let mut out = vec![0.0; coeff_count(bands)];
    for (l, &z) in zonal.iter().enumerate() {
        let scale = z.into() * lobe_scale(l as u32);
        let l = l as i32;
        for m in -l..=l {
            out[index(l, m)] = scale * axis_basis[index(l, m)];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;
    use crate::sh::rotate_zonal;

    fn random_unit(rng: &mut Pcg32) -> DVec3 {
        loop {
            let v = DVec3::new(
                2.0 * rng.next_f32() as f64 - 1.0,
                2.0 * rng.next_f32() as f64 - 1.0,
                2.0 * rng.next_f32() as f64 - 1.0,
            );
            if (0.01..1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }

    fn as_f32(v: &[f64]) -> Vec<f32> {
        v.iter().map(|&x| x as f32).collect()
    }

    /// A zonal function turned to any axis is fitted exactly about that axis, and what the
    /// fit keeps is its whole energy.
    #[test]
    fn a_turned_zonal_function_is_fitted_exactly_about_its_axis() {
        let mut rng = Pcg32::new(71);
        for _ in 0..20 {
            let zonal: Vec<f64> = (0..5).map(|_| rng.next_f32() as f64 - 0.3).collect();
            let axis = random_unit(&mut rng);
            let coeffs = as_f32(&rotate_zonal(&zonal, axis));
            let mut fitted = vec![0.0; 5];
            fit(&coeffs, &basis(5, axis), 5, &mut fitted);
            for (f, z) in fitted.iter().zip(&zonal) {
                assert!((f - z).abs() < 1e-6, "{fitted:?} against {zonal:?}");
            }
            let energy: f64 = coeffs.iter().map(|&c| c as f64 * c as f64).sum();
            let kept = kept_energy(&[&coeffs], 5, axis);
            assert!((kept - energy).abs() < 1e-5 * energy, "{kept} of {energy}");
        }
    }

    /// Relighting a lobe from its zonal coefficients is the dot product of the light with its
    /// SH coefficients, and the fit's residual is orthogonal to every zonal lobe about the axis
    /// (it is the least-squares fit).
    #[test]
    fn relighting_is_the_lobes_dot_product_and_the_residual_is_orthogonal() {
        let mut rng = Pcg32::new(113);
        let bands = 4;
        let n = coeff_count(bands);
        for _ in 0..20 {
            let coeffs: Vec<f32> = (0..n).map(|_| rng.next_f32() - 0.5).collect();
            let axis = random_unit(&mut rng);
            let y = basis(bands, axis);
            let mut zonal = vec![0.0; bands as usize];
            fit(&coeffs, &y, bands, &mut zonal);
            let lobe = lobe_coeffs(&zonal, &y);
            let light: Vec<f64> = (0..n).map(|_| rng.next_f32() as f64 - 0.5).collect();
            let dot: f64 = lobe.iter().zip(&light).map(|(a, b)| a * b).sum();
            assert!((relight(&zonal, &y, &light) - dot).abs() < 1e-9);
            for l in 0..bands as usize {
                let mut unit = vec![0.0; bands as usize];
                unit[l] = 1.0;
                let other = lobe_coeffs(&unit, &y);
                let residual: f64 = (0..n)
                    .map(|k| (coeffs[k] as f64 - lobe[k]) * other[k])
                    .sum();
                assert!(residual.abs() < 1e-6, "band {l}: {residual}");
            }
        }
    }

    /// The search finds the axis of a turned zonal function far from the normal it starts
    /// at, on the normal's side, and with RGB lobes about one axis, that axis.
    #[test]
    fn the_best_axis_is_the_axis_of_a_turned_lobe() {
        let mut rng = Pcg32::new(59);
        for _ in 0..10 {
            let axis = random_unit(&mut rng);
            let channels: Vec<Vec<f32>> = (0..3)
                .map(|_| {
                    // Even bands only: band 1 gives no hint of the axis.
                    let zonal = [0.8, 0.0, 0.5 + rng.next_f32() as f64, 0.0];
                    as_f32(&rotate_zonal(&zonal, axis))
                })
                .collect();
            let views: Vec<&[f32]> = channels.iter().map(Vec::as_slice).collect();
            let normal = random_unit(&mut rng);
            let found = best_axis(&views, 4, normal);
            assert!(found.dot(normal) >= 0.0);
            assert!(found.dot(axis).abs() > 1.0 - 1e-6, "{found} against {axis}");
        }
    }
}
