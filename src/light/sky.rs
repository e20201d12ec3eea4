//! An environment map as a sky to look at (the web viewer draws it behind the model): a small
//! lat-long copy of a map of any mapping, and bilinear lookups in it along directions.

use glam::DVec3;

use super::envmap::EnvImage;
use super::mapping::{latlong_position, pixel_direction, pixel_solid_angle, Mapping};
use crate::error::Result;

/// A lat-long copy of `image` (laid out by `mapping`) at most `max_width` pixels wide (and
/// half as high), never wider than the map's own detail: a lat-long map that fits is copied
/// unchanged. Each texel is the solid-angle-weighted mean of the map's pixels whose centres
/// fall in it (a box filter on the sphere: for a lat-long map downsampled by a whole factor,
/// exactly its blocks of pixels). Texels that no pixel centre falls in (near the poles, where
/// lat-long texels are small) take the nearest filled texel of their row, or row.
pub fn latlong_copy(image: &EnvImage, mapping: Mapping, max_width: usize) -> Result<EnvImage> {
    let width = copy_width(image, mapping, max_width);
    if mapping == Mapping::Latlong && width == image.width {
        return Ok(image.clone());
    }
    let height = width / 2;
    let mut sums = vec![[0.0f64; 4]; width * height];
    for y in 0..image.height {
        for x in 0..image.width {
            let pixel = image.pixel(x, y);
            let Some(direction) = pixel_direction(mapping, image.width, image.height, x, y) else {
                continue;
            };
            if !pixel.iter().all(|c| c.is_finite()) {
                continue;
            }
            let weight = pixel_solid_angle(mapping, image.width, image.height, x, y);
            let (px, py) = latlong_position(width, height, direction);
            let tx = (px.floor() as isize).rem_euclid(width as isize) as usize;
            let ty = (py.floor().max(0.0) as usize).min(height - 1);
            let sum = &mut sums[ty * width + tx];
            for c in 0..3 {
                sum[c] += weight * pixel[c] as f64;
            }
            sum[3] += weight;
        }
    }
    fill_empty_texels(&mut sums, width);
    let pixels = sums
        .iter()
        .map(|s| {
            [0, 1, 2].map(|c| {
                if s[3] > 0.0 {
                    (s[c] / s[3]) as f32
                } else {
                    0.0
                }
            })
        })
        .collect();
    EnvImage::new(width, height, pixels, image.source.clone())
}

/// The copy's width: even, at most `max_width` (at least 2), and no more than the map has
/// pixels around its equator (lat-long: its width; crosses: four faces; discs: their width).
fn copy_width(image: &EnvImage, mapping: Mapping, max_width: usize) -> usize {
    let detail = match mapping {
        Mapping::Latlong => image.width,
        Mapping::CrossHorizontal => image.width,
        Mapping::CrossVertical => image.width / 3 * 4,
        Mapping::Angular | Mapping::MirrorBall => image.width,
    };
    (detail.min(max_width) / 2 * 2).max(2)
}

/// Texels with no weight take their row's nearest weighted texel (around the row); a row with
/// none takes the nearest row that has some.
fn fill_empty_texels(sums: &mut [[f64; 4]], width: usize) {
    let height = sums.len() / width;
    for y in 0..height {
        let row: Vec<[f64; 4]> = sums[y * width..(y + 1) * width].to_vec();
        for x in 0..width {
            if row[x][3] > 0.0 {
                continue;
            }
            let nearest = (1..=width / 2)
                .flat_map(|step| [(x + step) % width, (x + width - step) % width])
                .find(|&i| row[i][3] > 0.0);
            if let Some(i) = nearest {
                sums[y * width + x] = row[i];
            }
        }
    }
    let filled: Vec<usize> = (0..height).filter(|&y| sums[y * width][3] > 0.0).collect();
    for y in 0..height {
        if sums[y * width][3] > 0.0 {
            continue;
        }
        if let Some(&from) = filled.iter().min_by_key(|&&f| f.abs_diff(y)) {
            let copy = sums[from * width..(from + 1) * width].to_vec();
            sums[y * width..(y + 1) * width].copy_from_slice(&copy);
        }
    }
}

/// The lat-long `image` looked up bilinearly along `direction`: between the four pixel centres
/// around its position, wrapping around horizontally and clamped at the top and bottom rows
/// (as a GPU samples the texture with repeat and clamp-to-edge).
pub fn sample_latlong(image: &EnvImage, direction: DVec3) -> [f32; 3] {
    let (px, py) = latlong_position(image.width, image.height, direction);
    let (fx, fy) = (px - 0.5, py - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let column = |x: f64| (x as isize).rem_euclid(image.width as isize) as usize;
    let row = |y: f64| y.clamp(0.0, image.height as f64 - 1.0) as usize;
    let mut out = [0.0f32; 3];
    for (x, wx) in [(x0, 1.0 - tx), (x0 + 1.0, tx)] {
        for (y, wy) in [(y0, 1.0 - ty), (y0 + 1.0, ty)] {
            let pixel = image.pixel(column(x), row(y));
            for c in 0..3 {
                out[c] += (wx * wy) as f32 * pixel[c];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn total(image: &EnvImage, mapping: Mapping) -> [f64; 3] {
        let mut sum = [0.0; 3];
        for y in 0..image.height {
            for x in 0..image.width {
                let w = pixel_solid_angle(mapping, image.width, image.height, x, y);
                for (total, value) in sum.iter_mut().zip(image.pixel(x, y)) {
                    *total += w * value as f64;
                }
            }
        }
        sum
    }

    #[test]
    fn latlong_position_inverts_pixel_directions() {
        let (w, h) = (64, 32);
        for (x, y) in [(0, 0), (10, 5), (31, 16), (63, 31), (40, 20)] {
            let d = pixel_direction(Mapping::Latlong, w, h, x, y).unwrap();
            let (px, py) = latlong_position(w, h, d);
            assert!((px - (x as f64 + 0.5)).abs() < 1e-9, "{x}: {px}");
            assert!((py - (y as f64 + 0.5)).abs() < 1e-9, "{y}: {py}");
        }
    }

    #[test]
    fn a_whole_factor_downsample_averages_blocks_weighted_by_solid_angle() {
        let image = EnvImage::from_fn(16, 8, |x, y| [x as f32, y as f32, (x * y) as f32]).unwrap();
        let copy = latlong_copy(&image, Mapping::Latlong, 8).unwrap();
        assert_eq!((copy.width, copy.height), (8, 4));
        for ty in 0..4 {
            for tx in 0..8 {
                let mut sum = [0.0f64; 4];
                for (x, y) in
                    [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(i, j)| (2 * tx + i, 2 * ty + j))
                {
                    let w = pixel_solid_angle(Mapping::Latlong, 16, 8, x, y);
                    for (total, value) in sum.iter_mut().zip(image.pixel(x, y)) {
                        *total += w * value as f64;
                    }
                    sum[3] += w;
                }
                for c in 0..3 {
                    let expected = sum[c] / sum[3];
                    assert!((copy.pixel(tx, ty)[c] as f64 - expected).abs() < 1e-5);
                }
            }
        }
        // The copy carries the same light: its integral over the sphere is the map's (to f32
        // rounding of the means).
        let (a, b) = (
            total(&image, Mapping::Latlong),
            total(&copy, Mapping::Latlong),
        );
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() < 1e-6 * a[c].abs().max(1.0),
                "{a:?} {b:?}"
            );
        }
        // A map that fits is kept as it is.
        assert_eq!(latlong_copy(&image, Mapping::Latlong, 512).unwrap(), image);
    }

    #[test]
    fn a_cross_becomes_a_latlong_map_of_the_same_directions() {
        // Radiance that varies smoothly with direction, laid out as a cross.
        let radiance = |d: DVec3| [(1.0 + d.x) as f32, (2.0 + d.y) as f32, (3.0 + d.z) as f32];
        let n = 32;
        let (w, h) = (4 * n, 3 * n);
        let cross = EnvImage::from_fn(w, h, |x, y| {
            pixel_direction(Mapping::CrossHorizontal, w, h, x, y)
                .map(radiance)
                .unwrap_or([f32::NAN; 3])
        })
        .unwrap();
        let copy = latlong_copy(&cross, Mapping::CrossHorizontal, 64).unwrap();
        assert_eq!((copy.width, copy.height), (64, 32));
        // Every texel near the radiance along its centre (a texel spans about 0.1 radians).
        for y in 0..copy.height {
            for x in 0..copy.width {
                let d = pixel_direction(Mapping::Latlong, 64, 32, x, y).unwrap();
                let (got, want) = (copy.pixel(x, y), radiance(d));
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 0.1, "{x},{y}: {got:?} {want:?}");
                }
            }
        }
        // And a bilinear lookup along a pixel centre is that pixel.
        let d = pixel_direction(Mapping::Latlong, 64, 32, 20, 9).unwrap();
        assert_eq!(sample_latlong(&copy, d), copy.pixel(20, 9));
    }

    #[test]
    fn bilinear_lookups_blend_neighbours_and_wrap_around() {
        let image = EnvImage::from_fn(8, 4, |x, _| [x as f32, 0.0, 1.0]).unwrap();
        // Halfway between the centres of columns 2 and 3, and across the seam 7 | 0.
        let between = |x: f64| {
            let azimuth = 2.0 * std::f64::consts::PI * x / 8.0 - std::f64::consts::PI;
            DVec3::new(azimuth.cos(), 0.0, azimuth.sin())
        };
        assert!((sample_latlong(&image, between(3.0))[0] - 2.5).abs() < 1e-5);
        assert!((sample_latlong(&image, between(8.0))[0] - 3.5).abs() < 1e-5);
        assert!((sample_latlong(&image, DVec3::Y)[2] - 1.0).abs() < 1e-6);
    }
}
