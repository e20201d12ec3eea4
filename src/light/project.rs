//! Projection of an environment map onto the SH basis:
//! `l_k = sum over pixels L(pixel) integral_pixel y_k dw`, the exact projection of the image
//! read as constant over each pixel, with each pixel's integral taken by the quadrature nodes of
//! `mapping::pixel_nodes` (their weights add up to the pixel's exact solid angle).

use super::envmap::EnvImage;
use super::mapping::{latlong_row_nodes, pixel_nodes, Layout, Mapping, CROSS_HORIZONTAL};
use super::ShLight;
use crate::error::{Error, Result};
use crate::sh;
use glam::DVec3;
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProjectOptions {
    /// Give NaN or infinite pixels zero weight (and count them) instead of failing.
    pub skip_invalid: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Projection {
    pub light: ShLight,
    /// Pixels left out because they were NaN or infinite.
    pub skipped: usize,
}

/// Projects `image` with the default options (invalid pixels are an error).
pub fn project(image: &EnvImage, mapping: Mapping, bands: u32) -> Result<ShLight> {
    project_with(image, mapping, bands, &ProjectOptions::default()).map(|p| p.light)
}

pub fn project_with(
    image: &EnvImage,
    mapping: Mapping,
    bands: u32,
    options: &ProjectOptions,
) -> Result<Projection> {
    sh::check_bands(bands)?;
    mapping
        .check_size(image.width, image.height)
        .map_err(|m| Error::light(&image.source, m))?;
    let skipped = check_finite(image, options.skip_invalid)?;

    let total = if mapping == Mapping::Latlong {
        latlong_separable(image, bands)
    } else {
        by_pixel_nodes(image, mapping, bands)
    };
    let coeffs: Vec<[f32; 3]> = total.iter().map(|t| t.map(|v| v as f32)).collect();
    if coeffs.iter().flatten().any(|c| !c.is_finite()) {
        let brightest = image
            .pixels
            .iter()
            .flatten()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        return Err(Error::light(
            &image.source,
            format!(
                "its radiance is too large to project: the coefficients overflow 32-bit floats \
                 (its brightest value is {brightest:e})"
            ),
        ));
    }
    Ok(Projection {
        light: ShLight { bands, coeffs },
        skipped,
    })
}

/// Sums per-row partial results in row order, so the total does not depend on how rayon
/// splits the rows.
fn sum_rows(
    height: usize,
    n: usize,
    row: impl Fn(usize) -> Vec<[f64; 3]> + Sync + Send,
) -> Vec<[f64; 3]> {
    let rows: Vec<Vec<[f64; 3]>> = (0..height).into_par_iter().map(row).collect();
    let mut total = vec![[0.0f64; 3]; n];
    for row in &rows {
        for (t, r) in total.iter_mut().zip(row) {
            for c in 0..3 {
                t[c] += r[c];
            }
        }
    }
    total
}

/// Any mapping: the basis evaluated at every quadrature node of every pixel.
fn by_pixel_nodes(image: &EnvImage, mapping: Mapping, bands: u32) -> Vec<[f64; 3]> {
    let layout = Layout::new(mapping, image.width, image.height);
    sum_rows(image.height, sh::coeff_count(bands), |y| {
        row_sum(image, &layout, bands, y)
    })
}

/// Lat-long, the same nodes as `by_pixel_nodes` but factored. In the frame `d' = (x, z, y)`
/// (y and z swapped, so the map's pole +Y becomes the SH polar axis) every basis function is
/// `A_l|m|(row) trig(m azimuth)`: a row reduces to 2 bands - 1 weighted sums over its pixels,
/// and the basis is evaluated only twice per row. The swap is orthogonal, so the world
/// coefficients are `M c'` with `M_kj = integral y_k(swap d) y_j(d) dw`, block-diagonal per band.
fn latlong_separable(image: &EnvImage, bands: u32) -> Vec<[f64; 3]> {
    let (width, height) = (image.width, image.height);
    let harmonics = 2 * bands as usize - 1;
    // Per column: 1, cos a, sin a, cos 2a, sin 2a, ...
    let trig: Vec<f64> = (0..width)
        .flat_map(|x| {
            let a =
                2.0 * std::f64::consts::PI * (x as f64 + 0.5) / width as f64 - std::f64::consts::PI;
            (0..harmonics).map(move |j| {
                let m = j.div_ceil(2);
                if j == 0 {
                    1.0
                } else if j % 2 == 1 {
                    (m as f64 * a).cos()
                } else {
                    (m as f64 * a).sin()
                }
            })
        })
        .collect();
    let n = sh::coeff_count(bands);
    let swapped = sum_rows(height, n, |y| {
        let mut sums = vec![[0.0f64; 3]; harmonics];
        for x in 0..width {
            let p = image.pixel(x, y);
            if !is_valid(&p) || p == [0.0; 3] {
                continue;
            }
            for (s, t) in sums
                .iter_mut()
                .zip(&trig[x * harmonics..(x + 1) * harmonics])
            {
                for c in 0..3 {
                    s[c] += p[c] as f64 * t;
                }
            }
        }
        let mut acc = vec![[0.0f64; 3]; n];
        for (sin_e, cos_e, weight) in latlong_row_nodes(width, height, y) {
            // Azimuth 0 in the swapped frame: y_lm for m > 0 is A_lm, for m < 0 zero.
            let a = sh::basis(bands, DVec3::new(cos_e, 0.0, sin_e));
            for l in 0..bands as i32 {
                for m in -l..=l {
                    let j = if m >= 0 {
                        2 * m as usize - (m > 0) as usize
                    } else {
                        2 * (-m) as usize
                    };
                    let factor = weight * a[sh::index(l, m.abs())];
                    let out = &mut acc[sh::index(l, m)];
                    for c in 0..3 {
                        out[c] += factor * sums[j][c];
                    }
                }
            }
        }
        acc
    });
    let mut world = vec![[0.0f64; 3]; n];
    for l in 0..bands as i32 {
        let block = swap_yz_block(bands, l);
        let size = (2 * l + 1) as usize;
        let first = sh::index(l, -l);
        for i in 0..size {
            for j in 0..size {
                for c in 0..3 {
                    world[first + i][c] += block[i * size + j] * swapped[first + j][c];
                }
            }
        }
    }
    world
}

/// Band `l` of `M_kj = integral y_k(x, z, y) y_j(x, y, z) dw`, by a product rule exact for
/// the degree-2l polynomials involved (Gauss–Legendre in z times uniform azimuth).
fn swap_yz_block(bands: u32, l: i32) -> Vec<f64> {
    let size = (2 * l + 1) as usize;
    let first = sh::index(l, -l);
    let azimuths = 2 * bands as usize + 2;
    let mut block = vec![0.0; size * size];
    for (z, wz) in crate::sh::legendre::gauss_legendre(bands as usize + 1) {
        let s = (1.0 - z * z).sqrt();
        for q in 0..azimuths {
            let p = 2.0 * std::f64::consts::PI * (q as f64 + 0.5) / azimuths as f64;
            let d = DVec3::new(s * p.cos(), s * p.sin(), z);
            let w = wz * 2.0 * std::f64::consts::PI / azimuths as f64;
            let plain = sh::basis(l as u32 + 1, d);
            let swapped = sh::basis(l as u32 + 1, DVec3::new(d.x, d.z, d.y));
            for i in 0..size {
                for j in 0..size {
                    block[i * size + j] += w * swapped[first + i] * plain[first + j];
                }
            }
        }
    }
    block
}

/// Projects six square faces given in the order +X, -X, +Y, -Y, +Z, -Z, each oriented as in the
/// horizontal cross (see `mapping::CROSS_HORIZONTAL`).
pub fn project_faces(
    faces: [&EnvImage; 6],
    bands: u32,
    options: &ProjectOptions,
) -> Result<Projection> {
    let cross = cross_from_faces(faces)?;
    project_with(&cross, Mapping::CrossHorizontal, bands, options)
}

/// Lays six faces (+X, -X, +Y, -Y, +Z, -Z) out as a horizontal cross, zero outside the faces.
pub fn cross_from_faces(faces: [&EnvImage; 6]) -> Result<EnvImage> {
    let n = faces[0].width;
    for face in faces {
        if face.width != face.height || face.width != n {
            return Err(Error::light(
                &face.source,
                format!(
                    "cube faces must be square and of one size: this one is {}x{}, the +X face {n}x{}",
                    face.width, face.height, faces[0].height
                ),
            ));
        }
    }
    let (width, height) = (4 * n, 3 * n);
    let mut pixels = vec![[0.0f32; 3]; width * height];
    for (face, slot) in faces.iter().zip(CROSS_HORIZONTAL) {
        for y in 0..n {
            let start = (slot.row * n + y) * width + slot.col * n;
            pixels[start..start + n].copy_from_slice(&face.pixels[y * n..(y + 1) * n]);
        }
    }
    EnvImage::new(width, height, pixels, faces[0].source.clone())
}

fn is_valid(p: &[f32; 3]) -> bool {
    p.iter().all(|v| v.is_finite())
}

/// Counts NaN/inf pixels; an error naming the first unless they may be skipped.
fn check_finite(image: &EnvImage, skip_invalid: bool) -> Result<usize> {
    let count = image.pixels.iter().filter(|p| !is_valid(p)).count();
    if count == 0 || skip_invalid {
        return Ok(count);
    }
    let first = image.pixels.iter().position(|p| !is_valid(p)).unwrap_or(0);
    Err(Error::light(
        &image.source,
        format!(
            "{count} pixel(s) are NaN or infinite, the first at x = {}, y = {}; \
             skip them with --skip-invalid",
            first % image.width,
            first / image.width
        ),
    ))
}

fn row_sum(image: &EnvImage, layout: &Layout, bands: u32, y: usize) -> Vec<[f64; 3]> {
    let n = sh::coeff_count(bands);
    let mut acc = vec![[0.0f64; 3]; n];
    let mut basis = vec![0.0f64; n];
    let mut nodes = Vec::new();
    for x in 0..image.width {
        let p = image.pixel(x, y);
        if !is_valid(&p) || p == [0.0; 3] {
            continue;
        }
        let radiance = p.map(f64::from);
        pixel_nodes(layout, x, y, &mut nodes);
        for &(dir, weight) in &nodes {
            sh::eval_basis(bands, dir, &mut basis);
            let weighted = radiance.map(|c| c * weight);
            for (a, b) in acc.iter_mut().zip(&basis) {
                a[0] += weighted[0] * b;
                a[1] += weighted[1] * b;
                a[2] += weighted[2] * b;
            }
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::super::mapping::test_support::{size_for, ALL};
    use super::super::mapping::{pixel_direction, pixel_solid_angle};
    use super::*;
    use std::f64::consts::PI;

    fn constant(mapping: Mapping, n: usize, rgb: [f32; 3]) -> EnvImage {
        let (w, h) = size_for(mapping, n);
        EnvImage::from_fn(w, h, |x, y| {
            if pixel_solid_angle(mapping, w, h, x, y) > 0.0 {
                rgb
            } else {
                // Outside the disc or the cross: must not count whatever it holds.
                [7.0, 7.0, 7.0]
            }
        })
        .unwrap()
    }

    /// Pixels near the largest float are finite, but their integral is not: refused in one
    /// line rather than written as a light of infinities (a flipped exponent bit in an EXR).
    #[test]
    fn radiance_whose_integral_overflows_is_refused() {
        let image = constant(Mapping::Latlong, 16, [3.0e38, 1.0, 1.0]);
        let error = project(&image, Mapping::Latlong, 3)
            .unwrap_err()
            .to_string();
        assert!(error.contains("too large to project"), "{error}");
        assert!(error.contains("3e38"), "{error}");
    }

    #[test]
    fn constant_map_projects_to_the_dc_term_alone_in_every_mapping() {
        let rgb = [1.0f32, 0.5, 2.0];
        for (mapping, n) in [
            (Mapping::Latlong, 256),
            (Mapping::Angular, 512),
            (Mapping::MirrorBall, 512),
            (Mapping::CrossHorizontal, 128),
            (Mapping::CrossVertical, 128),
        ] {
            let light = project(&constant(mapping, n, rgb), mapping, 4).unwrap();
            let expected = ShLight::constant(4, rgb);
            let worst = (1..16)
                .flat_map(|k| (0..3).map(move |c| (k, c)))
                .map(|(k, c)| (light.coeffs[k][c] / expected.coeffs[0][c]).abs())
                .fold(0.0f32, f32::max);
            eprintln!("{mapping:?} {n}: largest |l_k| / l_00 = {worst:e}");
            for c in 0..3 {
                let dc = light.coeffs[0][c] as f64;
                let want = expected.coeffs[0][c] as f64;
                assert!(
                    (dc - want).abs() < 1e-6 * want,
                    "{mapping:?} dc {dc} vs {want}"
                );
                for (k, v) in light.coeffs.iter().enumerate().skip(1) {
                    assert!(
                        (v[c] as f64).abs() < 1e-6 * want,
                        "{mapping:?} k = {k} channel {c}: {} vs dc {want}",
                        v[c]
                    );
                }
            }
        }
    }

    /// `integral_pixel y_k dw` by a fine sub-grid, independent of `pixel_nodes`: the pixel is
    /// split into `s x s` sub-pixels, each weighted by the exact solid angle of a same-sized
    /// pixel of a `s`-times finer map and pointed along that pixel's centre.
    fn fine_pixel_integral(mapping: Mapping, w: usize, h: usize, x: usize, y: usize) -> Vec<f64> {
        let s = 16;
        let mut sum = vec![0.0; 16];
        for j in 0..s {
            for i in 0..s {
                let (fx, fy) = (x * s + i, y * s + j);
                let omega = pixel_solid_angle(mapping, w * s, h * s, fx, fy);
                if let Some(d) = pixel_direction(mapping, w * s, h * s, fx, fy) {
                    for (a, b) in sum.iter_mut().zip(sh::basis(4, d)) {
                        *a += omega * b;
                    }
                }
            }
        }
        sum
    }

    #[test]
    fn one_bright_pixel_projects_to_its_solid_angle_times_its_direction() {
        let value = [3.0f32, 2.0, 1.0];
        for mapping in ALL {
            let (w, h) = size_for(mapping, 32);
            // A pixel off every axis so that orientation or handedness errors show.
            let (x, y) = match mapping {
                Mapping::Latlong => (41, 9),
                Mapping::Angular | Mapping::MirrorBall => (20, 9),
                Mapping::CrossHorizontal => (3 * 32 + 5, 32 + 11),
                Mapping::CrossVertical => (32 + 7, 3 * 32 + 20),
            };
            let image = EnvImage::from_fn(
                w,
                h,
                |px, py| {
                    if (px, py) == (x, y) {
                        value
                    } else {
                        [0.0; 3]
                    }
                },
            )
            .unwrap();
            let light = project(&image, mapping, 4).unwrap();
            let omega = pixel_solid_angle(mapping, w, h, x, y);
            let dir = pixel_direction(mapping, w, h, x, y).unwrap();
            let at_centre = sh::basis(4, dir);
            let fine = fine_pixel_integral(mapping, w, h, x, y);
            for (c, &v) in value.iter().enumerate() {
                let v = v as f64;
                let dc = light.coeffs[0][c] as f64;
                assert!((dc - v * omega * at_centre[0]).abs() < 1e-6 * dc.abs());
                for k in 0..16 {
                    let got = light.coeffs[k][c] as f64;
                    // Centre-point rule: off by the pixel's curvature, second order in its size.
                    let centre_rule = v * omega * at_centre[k];
                    assert!(
                        (got - centre_rule).abs() < 0.01 * v * omega,
                        "{mapping:?} k = {k}: {got} vs {centre_rule}"
                    );
                    let reference = v * fine[k];
                    assert!(
                        (got - reference).abs() < 2e-3 * v * omega,
                        "{mapping:?} k = {k}: {got} vs sub-grid {reference}"
                    );
                }
            }
        }
    }

    /// `y_lm` with m != 0 and l up to 3, mixed with distinct weights per channel.
    fn band_limited(d: DVec3) -> [f64; 3] {
        let y = sh::basis(4, d);
        [
            1.0 * y[0] + 0.7 * y[2] - 0.4 * y[5] + 0.3 * y[11] + 0.2 * y[15],
            0.5 * y[1] - 0.8 * y[3] + 0.6 * y[6] + 0.25 * y[9],
            0.9 * y[4] - 0.3 * y[8] + 0.45 * y[12] - 0.35 * y[13],
        ]
    }

    #[test]
    fn band_limited_latlong_map_reconstructs_its_coefficients() {
        let (w, h) = (1024, 512);
        let image = EnvImage::from_fn(w, h, |x, y| {
            let d = pixel_direction(Mapping::Latlong, w, h, x, y).unwrap();
            band_limited(d).map(|v| v as f32)
        })
        .unwrap();
        let light = project(&image, Mapping::Latlong, 4).unwrap();
        let mut expected = vec![[0.0f64; 3]; 16];
        for (k, v) in [(0, 1.0), (2, 0.7), (5, -0.4), (11, 0.3), (15, 0.2)] {
            expected[k][0] = v;
        }
        for (k, v) in [(1, 0.5), (3, -0.8), (6, 0.6), (9, 0.25)] {
            expected[k][1] = v;
        }
        for (k, v) in [(4, 0.9), (8, -0.3), (12, 0.45), (13, -0.35)] {
            expected[k][2] = v;
        }
        for (k, want) in expected.iter().enumerate() {
            for (c, &want) in want.iter().enumerate() {
                let got = light.coeffs[k][c] as f64;
                assert!(
                    (got - want).abs() < 1e-4,
                    "k = {k} channel {c}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn separable_latlong_agrees_with_per_node_evaluation() {
        let (w, h) = (128, 64);
        let image = EnvImage::from_fn(w, h, |x, y| {
            [
                (x * 7 % 13) as f32,
                (y * 3 % 5) as f32 + 0.5,
                ((x * y) % 11) as f32,
            ]
        })
        .unwrap();
        for bands in [1, 3, 6] {
            let fast = latlong_separable(&image, bands);
            let slow = by_pixel_nodes(&image, Mapping::Latlong, bands);
            let scale = slow[0][0].abs();
            for (k, (f, s)) in fast.iter().zip(&slow).enumerate() {
                for c in 0..3 {
                    assert!((f[c] - s[c]).abs() < 1e-10 * scale, "bands {bands} k {k}");
                }
            }
        }
    }

    #[test]
    fn invalid_pixels_fail_or_are_skipped() {
        let (w, h) = (64, 32);
        let image = EnvImage::from_fn(w, h, |x, y| match (x, y) {
            (5, 3) => [f32::NAN, 1.0, 1.0],
            (9, 20) => [1.0, f32::INFINITY, 1.0],
            _ => [1.0; 3],
        })
        .unwrap();
        let e = project(&image, Mapping::Latlong, 3)
            .unwrap_err()
            .to_string();
        assert!(!e.contains('\n'));
        assert!(
            e.contains("2 pixel(s)") && e.contains("x = 5, y = 3"),
            "{e}"
        );
        let skipping = ProjectOptions { skip_invalid: true };
        let p = project_with(&image, Mapping::Latlong, 3, &skipping).unwrap();
        assert_eq!(p.skipped, 2);
        let missing = pixel_solid_angle(Mapping::Latlong, w, h, 5, 3)
            + pixel_solid_angle(Mapping::Latlong, w, h, 9, 20);
        let dc = p.light.coeffs[0][1] as f64;
        let expected = (4.0 * PI - missing) / (4.0 * PI).sqrt();
        assert!((dc - expected).abs() < 1e-5, "{dc} vs {expected}");
    }

    #[test]
    fn wrong_aspect_and_bad_bands_are_errors() {
        let image = EnvImage::from_fn(100, 50, |_, _| [1.0; 3]).unwrap();
        let e = project(&image, Mapping::MirrorBall, 3)
            .unwrap_err()
            .to_string();
        assert!(e.contains("100x50") && e.contains("mirror-ball"), "{e}");
        assert!(project(&image, Mapping::Latlong, 0).is_err());
        assert!(project(&image, Mapping::Latlong, sh::MAX_BANDS + 1).is_err());
    }

    #[test]
    fn projection_is_deterministic() {
        let image = EnvImage::from_fn(256, 128, |x, y| {
            [
                (x * 7 % 13) as f32,
                (y * 3 % 5) as f32,
                ((x + y) % 11) as f32,
            ]
        })
        .unwrap();
        let a = project(&image, Mapping::Latlong, 5).unwrap();
        let b = project(&image, Mapping::Latlong, 5).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn six_faces_project_like_the_cross_they_form() {
        let n = 16;
        let face = |i: usize| {
            EnvImage::from_fn(n, n, move |x, y| {
                [(i + 1) as f32, (x % 3) as f32, (y % 5) as f32]
            })
            .unwrap()
        };
        let faces: Vec<EnvImage> = (0..6).map(face).collect();
        let refs = [
            &faces[0], &faces[1], &faces[2], &faces[3], &faces[4], &faces[5],
        ];
        let p = project_faces(refs, 3, &ProjectOptions::default()).unwrap();
        // Red is 1 on +X and 2 on -X: y_11 = -c x, so its coefficient is positive only if
        // the faces landed on the right sides.
        assert!(p.light.coeffs[3][0] > 0.0);
        let cross = cross_from_faces(refs).unwrap();
        assert_eq!((cross.width, cross.height), (64, 48));
        assert_eq!(cross.pixel(2 * n, n), faces[0].pixel(0, 0));
        let wrong = EnvImage::from_fn(8, 8, |_, _| [0.0; 3]).unwrap();
        let bad = [
            &faces[0], &faces[1], &wrong, &faces[3], &faces[4], &faces[5],
        ];
        assert!(project_faces(bad, 3, &ProjectOptions::default()).is_err());
    }
}
