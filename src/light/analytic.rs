//! Closed-form SH projections of analytic lights, in the basis of `sh` (world frame, +Y up).
//!
//! Every light here except the directional one is zonal: a function `f(t)` of the cosine `t`
//! between the direction and an axis. Its zonal coefficients about +Z are
//! `z_l = 2 pi K_l integral_{-1}^{1} f(t) P_l(t) dt` (`K_l = sqrt((2l+1) / (4 pi))`), and
//! `sh::rotate_zonal` turns them to the axis (Funk–Hecke). Radiances are per colour channel.

use super::ShLight;
use crate::error::{Error, Result};
use crate::sh;
use glam::DVec3;
use std::f64::consts::PI;

/// A delta of total `intensity` (W/m^2-like: the integral of radiance over the sphere) arriving
/// from `direction`: `l_k = intensity * y_k(direction)`.
pub fn directional(bands: u32, direction: DVec3, intensity: [f32; 3]) -> Result<ShLight> {
    sh::check_bands(bands)?;
    let dir = unit(direction, "light direction")?;
    let y = sh::basis(bands, dir);
    Ok(from_channels(bands, |c| {
        y.iter().map(|v| v * intensity[c] as f64).collect()
    }))
}

/// Uniform `radiance` inside the cone of half-angle `half_angle` (radians, in (0, pi]) about
/// `axis`, zero outside: `integral_{cos a}^{1} P_l = (P_{l-1}(cos a) - P_{l+1}(cos a)) / (2l+1)`.
pub fn cone(bands: u32, axis: DVec3, half_angle: f64, radiance: [f32; 3]) -> Result<ShLight> {
    sh::check_bands(bands)?;
    let axis = unit(axis, "cone axis")?;
    if !(half_angle > 0.0 && half_angle <= PI) {
        return Err(Error::Options(format!(
            "cone half-angle must be in (0, pi] radians, not {half_angle}"
        )));
    }
    let shape: Vec<f64> = (0..bands)
        .map(|l| zonal_scale(l) * cap_legendre_integral(l, half_angle.cos()))
        .collect();
    Ok(rotated(bands, &shape, axis, radiance))
}

/// A sphere of angular radius `angular_radius` and uniform `radiance` seen from the centre of
/// the scene: the same as a cone.
pub fn spherical(
    bands: u32,
    centre: DVec3,
    angular_radius: f64,
    radiance: [f32; 3],
) -> Result<ShLight> {
    cone(bands, centre, angular_radius, radiance)
}

/// A sun disk of half-angle `half_angle` whose radiance integrates to `irradiance` over the
/// disk, so that it tends to `directional(irradiance)` as the disk shrinks.
pub fn sun_disk(
    bands: u32,
    direction: DVec3,
    half_angle: f64,
    irradiance: [f32; 3],
) -> Result<ShLight> {
    let solid_angle = 2.0 * PI * (1.0 - half_angle.cos());
    if solid_angle.is_nan() || solid_angle <= 0.0 {
        return Err(Error::Options(format!(
            "sun half-angle must be in (0, pi] radians, not {half_angle}"
        )));
    }
    cone(
        bands,
        direction,
        half_angle,
        irradiance.map(|e| (e as f64 / solid_angle) as f32),
    )
}

/// `sky` radiance above the horizon (y > 0), `ground` below, about the world's +Y up axis.
pub fn hemisphere(bands: u32, sky: [f32; 3], ground: [f32; 3]) -> Result<ShLight> {
    sh::check_bands(bands)?;
    // The upper half about +Z, then turned to +Y; the lower half is its mirror, (-1)^l.
    let upper: Vec<f64> = (0..bands)
        .map(|l| zonal_scale(l) * cap_legendre_integral(l, 0.0))
        .collect();
    let zonal = |c: usize| -> Vec<f64> {
        upper
            .iter()
            .enumerate()
            .map(|(l, u)| {
                let sign = if l % 2 == 0 { 1.0 } else { -1.0 };
                u * (sky[c] as f64 + sign * ground[c] as f64)
            })
            .collect()
    };
    Ok(from_channels(bands, |c| {
        sh::rotate_zonal(&zonal(c), DVec3::Y)
    }))
}

/// Constant radiance from every direction.
pub fn constant(bands: u32, rgb: [f32; 3]) -> Result<ShLight> {
    sh::check_bands(bands)?;
    Ok(ShLight::constant(bands, rgb))
}

/// The tutorial's two-light test function (Slomp et al., §6.2.4, after Green's "Spherical
/// Harmonic Lighting: the gritty details"), monochrome, in the spherical coordinates of `sh`
/// (theta from +Z, phi from +X towards +Y):
/// `max(0, 5 cos t - 4) + max(0, -4 sin(t - pi) cos(p - 2.5) - 3)`.
pub fn tutorial_two_lights_radiance(direction: DVec3) -> f64 {
    let d = direction.normalize();
    let theta = d.z.clamp(-1.0, 1.0).acos();
    let phi = d.y.atan2(d.x);
    (5.0 * theta.cos() - 4.0).max(0.0)
        + (-4.0 * (theta - PI).sin() * (phi - 2.5).cos() - 3.0).max(0.0)
}

/// Exact SH projection of [`tutorial_two_lights_radiance`], white.
///
/// The function is two clamped linear lobes: `max(0, 5 t - 4)` with `t = d.z`, and, since
/// `-sin(t - pi) cos(p - 2.5) = d . (cos 2.5, sin 2.5, 0)`, `max(0, 4 t' - 3)` with `t'` the
/// cosine to that horizontal axis (90 degrees from +Z). Each lobe's zonal integral
/// `integral_c^1 (a t - b) P_l(t) dt` is a polynomial of degree l + 1 on [c, 1], which
/// Gauss–Legendre with `bands + 1` nodes integrates exactly; no sphere sampling is involved.
pub fn tutorial_two_lights(bands: u32) -> Result<ShLight> {
    sh::check_bands(bands)?;
    let second_axis = DVec3::new(2.5f64.cos(), 2.5f64.sin(), 0.0);
    let mut total = vec![0.0; sh::coeff_count(bands)];
    for (axis, slope, offset) in [(DVec3::Z, 5.0, 4.0), (second_axis, 4.0, 3.0)] {
        let zonal = clamped_linear_zonal(bands, slope, offset);
        for (t, v) in total.iter_mut().zip(sh::rotate_zonal(&zonal, axis)) {
            *t += v;
        }
    }
    Ok(from_channels(bands, |_| total.clone()))
}

/// Zonal coefficients of `max(0, slope t - offset)` about +Z (requires 0 < offset < slope).
fn clamped_linear_zonal(bands: u32, slope: f64, offset: f64) -> Vec<f64> {
    let start = offset / slope;
    let nodes = crate::sh::legendre::gauss_legendre(bands as usize + 1);
    (0..bands)
        .map(|l| {
            let half = 0.5 * (1.0 - start);
            let integral: f64 = nodes
                .iter()
                .map(|&(x, w)| {
                    let t = start + half * (x + 1.0);
                    half * w * (slope * t - offset) * legendre(l, t)
                })
                .sum();
            zonal_scale(l) * integral
        })
        .collect()
}

/// `2 pi K_l`: turns `integral f P_l dt` into a zonal coefficient.
fn zonal_scale(l: u32) -> f64 {
    2.0 * PI * ((2 * l + 1) as f64 / (4.0 * PI)).sqrt()
}

/// `integral_c^1 P_l(t) dt`, from `(2l+1) P_l = P'_{l+1} - P'_{l-1}` and `P_n(1) = 1`.
fn cap_legendre_integral(l: u32, c: f64) -> f64 {
    if l == 0 {
        1.0 - c
    } else {
        (legendre(l - 1, c) - legendre(l + 1, c)) / (2 * l + 1) as f64
    }
}

/// P_l(x), for the closed forms above.
fn legendre(l: u32, x: f64) -> f64 {
    crate::sh::legendre::legendre(l as usize, x)
}

/// Coefficients of a zonal shape (per unit radiance) turned to `axis`, scaled per channel.
fn rotated(bands: u32, shape: &[f64], axis: DVec3, radiance: [f32; 3]) -> ShLight {
    let unit = sh::rotate_zonal(shape, axis);
    from_channels(bands, |c| {
        unit.iter().map(|v| v * radiance[c] as f64).collect()
    })
}

fn from_channels(bands: u32, channel: impl Fn(usize) -> Vec<f64>) -> ShLight {
    let [r, g, b] = [channel(0), channel(1), channel(2)];
    let coeffs = (0..sh::coeff_count(bands))
        .map(|k| [r[k] as f32, g[k] as f32, b[k] as f32])
        .collect();
    ShLight { bands, coeffs }
}

fn unit(v: DVec3, what: &str) -> Result<DVec3> {
    let length = v.length();
    if !(length.is_finite() && length > 0.0) {
        return Err(Error::Options(format!(
            "{what} must be a finite non-zero vector, not {v}"
        )));
    }
    Ok(v / length)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `integral f(w) y_k(w) dw` by brute force in the world frame: Gauss–Legendre in z times
    /// uniform azimuth, with no knowledge of the function's axis.
    fn brute_force(bands: u32, f: impl Fn(DVec3) -> [f64; 3]) -> Vec<[f64; 3]> {
        let (rings, azimuths) = (600, 1200);
        let mut out = vec![[0.0; 3]; sh::coeff_count(bands)];
        let mut y = vec![0.0; sh::coeff_count(bands)];
        for (z, wz) in crate::sh::legendre::gauss_legendre(rings) {
            let s = (1.0 - z * z).sqrt();
            for j in 0..azimuths {
                let p = 2.0 * PI * (j as f64 + 0.5) / azimuths as f64;
                let d = DVec3::new(s * p.cos(), s * p.sin(), z);
                let w = wz * 2.0 * PI / azimuths as f64;
                let value = f(d);
                sh::eval_basis(bands, d, &mut y);
                for (o, yk) in out.iter_mut().zip(&y) {
                    for c in 0..3 {
                        o[c] += w * value[c] * yk;
                    }
                }
            }
        }
        out
    }

    fn assert_matches(name: &str, light: &ShLight, reference: &[[f64; 3]], tol: f64) {
        let scale = reference
            .iter()
            .flatten()
            .fold(0.0f64, |a, b| a.max(b.abs()));
        for (k, (got, want)) in light.coeffs.iter().zip(reference).enumerate() {
            for c in 0..3 {
                assert!(
                    (got[c] as f64 - want[c]).abs() < tol * scale,
                    "{name}: k = {k} channel {c}: {} vs {}",
                    got[c],
                    want[c]
                );
            }
        }
    }

    #[test]
    fn cone_matches_brute_force() {
        let axis = DVec3::new(0.3, 0.8, -0.5).normalize();
        let (a, rgb) = (0.6, [2.0f32, 1.0, 0.5]);
        let light = cone(5, axis, a, rgb).unwrap();
        let reference = brute_force(5, |d| {
            let inside = d.dot(axis) >= a.cos();
            rgb.map(|v| if inside { v as f64 } else { 0.0 })
        });
        assert_matches("cone", &light, &reference, 2e-3);
        // A full-sphere cone is the constant light.
        let all = cone(3, axis, PI, [1.0; 3]).unwrap();
        assert_matches(
            "full cone",
            &all,
            &ShLight::constant(3, [1.0; 3])
                .coeffs
                .iter()
                .map(|c| c.map(f64::from))
                .collect::<Vec<_>>(),
            1e-6,
        );
    }

    #[test]
    fn spherical_light_and_sun_disk_are_cones() {
        let dir = DVec3::new(-0.2, 0.9, 0.4);
        let sphere = spherical(4, dir, 0.1, [1.0, 2.0, 3.0]).unwrap();
        let reference = brute_force(4, |d| {
            let inside = d.dot(dir.normalize()) >= 0.1f64.cos();
            [1.0, 2.0, 3.0].map(|v| if inside { v } else { 0.0 })
        });
        assert_matches("sphere", &sphere, &reference, 1e-2);
        // A shrinking sun tends to the directional light of the same irradiance.
        let sun = sun_disk(4, dir, 1e-3, [5.0; 3]).unwrap();
        let delta = directional(4, dir, [5.0; 3]).unwrap();
        assert_matches(
            "sun",
            &sun,
            &delta
                .coeffs
                .iter()
                .map(|c| c.map(f64::from))
                .collect::<Vec<_>>(),
            1e-5,
        );
    }

    #[test]
    fn directional_matches_a_normalised_narrow_cap_by_brute_force() {
        let dir = DVec3::new(0.5, -0.3, 0.8).normalize();
        let light = directional(3, dir, [1.0, 0.5, 0.25]).unwrap();
        let a: f64 = 0.15;
        let solid_angle = 2.0 * PI * (1.0 - a.cos());
        let reference = brute_force(3, |d| {
            let inside = d.dot(dir) >= a.cos();
            [1.0, 0.5, 0.25].map(|v| if inside { v / solid_angle } else { 0.0 })
        });
        // The cap's own blur is second order in its radius: (l(l+1)/4) a^2 ~ 3.4% at l = 2.
        assert_matches("directional", &light, &reference, 0.04);
        assert_eq!(
            light.coeffs[0][0] as f64,
            (1.0 / (4.0 * PI).sqrt()) as f32 as f64
        );
    }

    #[test]
    fn hemisphere_matches_brute_force_about_y() {
        let (sky, ground) = ([0.8f32, 0.9, 1.0], [0.3f32, 0.2, 0.1]);
        let light = hemisphere(4, sky, ground).unwrap();
        let reference = brute_force(4, |d| {
            let c = if d.y > 0.0 { sky } else { ground };
            c.map(f64::from)
        });
        assert_matches("hemisphere", &light, &reference, 2e-3);
        // Up is +Y: the y-moment (y_1,-1 = -c y) is negative when the sky is brighter.
        assert!(light.coeffs[sh::index(1, -1)][0] < 0.0);
        assert!(light.coeffs[sh::index(1, 0)][0].abs() < 1e-7);
    }

    #[test]
    fn tutorial_two_lights_match_brute_force() {
        let light = tutorial_two_lights(6).unwrap();
        let reference = brute_force(6, |d| [tutorial_two_lights_radiance(d); 3]);
        assert_matches("two lights", &light, &reference, 1e-4);
        // Lobe peaks: 1 at +Z, 1 at the second axis, 90 degrees apart.
        assert!((tutorial_two_lights_radiance(DVec3::Z) - 1.0).abs() < 1e-12);
        let second = DVec3::new(2.5f64.cos(), 2.5f64.sin(), 0.0);
        assert!((tutorial_two_lights_radiance(second) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn constant_and_bad_inputs() {
        assert_eq!(
            constant(3, [1.0, 2.0, 3.0]).unwrap(),
            ShLight::constant(3, [1.0, 2.0, 3.0])
        );
        assert!(cone(3, DVec3::ZERO, 0.5, [1.0; 3]).is_err());
        assert!(cone(3, DVec3::Y, 0.0, [1.0; 3]).is_err());
        assert!(cone(3, DVec3::Y, f64::NAN, [1.0; 3]).is_err());
        assert!(directional(0, DVec3::Y, [1.0; 3]).is_err());
        assert!(sun_disk(3, DVec3::Y, -1.0, [1.0; 3]).is_err());
    }

    #[test]
    fn legendre_helpers_are_right() {
        // P_2 = (3x^2 - 1)/2; integral_0^1 P_2 = 0; integral_0.5^1 P_1 = 3/8.
        assert!((legendre(2, 0.3) - (3.0 * 0.09 - 1.0) / 2.0).abs() < 1e-15);
        assert!(cap_legendre_integral(2, 0.0).abs() < 1e-15);
        assert!((cap_legendre_integral(1, 0.5) - 0.375).abs() < 1e-15);
        let sum: f64 = crate::sh::legendre::gauss_legendre(7)
            .iter()
            .map(|(x, w)| w * x.powi(12))
            .sum();
        assert!((sum - 2.0 / 13.0).abs() < 1e-14);
    }
}
