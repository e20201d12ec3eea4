//! Image encoding: side-by-side panels, tone mapping, 8-bit sRGB, and PNG or EXR files.

use std::io::Cursor;
use std::path::Path;

use crate::color::srgb_encode;
use crate::error::{Error, Result};
use crate::fs::{format_by_extension, write_atomically};

/// Panels placed left to right (e.g. unshadowed | shadowed | interreflected), each
/// `width x height`; the result is `images.len() * width` wide.
///
/// Returns a `Result` rather than panicking on a panel of the wrong size.
pub fn side_by_side(images: &[Vec<[f32; 4]>], width: u32, height: u32) -> Result<Vec<[f32; 4]>> {
    let panel = width as usize * height as usize;
    if images.is_empty() || panel == 0 {
        return Err(Error::Options(
            "side by side: no panels, or panels of zero size".into(),
        ));
    }
    if let Some(i) = images.iter().position(|image| image.len() != panel) {
        return Err(Error::Options(format!(
            "side by side: panel {i} has {} pixels, not {width}x{height}",
            images[i].len()
        )));
    }
    let w = width as usize;
    Ok((0..height as usize)
        .flat_map(|y| images.iter().flat_map(move |image| &image[y * w..][..w]))
        .copied()
        .collect())
}

/// How linear radiance becomes display values before sRGB encoding (PNG only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ToneMap {
    /// Clamp to [0, 1]: radiance 1 is white, brighter is clipped.
    None,
    /// `x / (1 + x)` per channel: nothing clips, highlights compress.
    #[default]
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve per channel: more contrast than Reinhard.
    Aces,
}

/// Linear radiance → display-linear value in [0, 1], after scaling by `2^exposure_stops`.
pub fn tone_map(value: f32, tone: ToneMap, exposure_stops: f32) -> f32 {
    let x = (value * exposure_stops.exp2()).max(0.0);
    let mapped = match tone {
        ToneMap::None => x,
        ToneMap::Reinhard => x / (1.0 + x),
        ToneMap::Aces => (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14),
    };
    mapped.clamp(0.0, 1.0)
}

fn to_byte(unit: f32) -> u8 {
    // NaN clamps to NaN, which `as` turns into 0: a black pixel, not a panic.
    (unit.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// 8-bit sRGB RGBA: colour tone-mapped and encoded, alpha (coverage) kept linear.
pub fn to_rgba8(pixels: &[[f32; 4]], tone: ToneMap, exposure_stops: f32) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|p| {
            let [r, g, b] =
                [p[0], p[1], p[2]].map(|c| to_byte(srgb_encode(tone_map(c, tone, exposure_stops))));
            [r, g, b, to_byte(p[3])]
        })
        .collect()
}

/// Writes `pixels` (`width x height` linear RGBA, row 0 at the top) atomically, in the format
/// the extension names: `.png` tone-mapped 8-bit sRGB with alpha, `.exr` linear 32-bit float
/// RGBA (tone map and exposure do not apply: an HDR file keeps the radiance).
pub fn write_image(
    path: &Path,
    pixels: &[[f32; 4]],
    width: u32,
    height: u32,
    tone: ToneMap,
    exposure_stops: f32,
) -> Result<()> {
    if width == 0 || height == 0 || pixels.len() != width as usize * height as usize {
        return Err(Error::Options(format!(
            "{}: {} pixels do not make a {width}x{height} image",
            path.display(),
            pixels.len()
        )));
    }
    if !exposure_stops.is_finite() {
        return Err(Error::Options(format!(
            "exposure {exposure_stops} is not finite"
        )));
    }
    let bytes = match ImageFormat::of(path)? {
        ImageFormat::Png => encode_png(pixels, width, height, tone, exposure_stops),
        ImageFormat::Exr => encode_exr(pixels, width, height),
    }
    .map_err(|message| Error::io(path, std::io::Error::other(message)))?;
    write_atomically(path, &bytes)
}

/// The extensions of the image files [`write_image`] writes, which choose the format.
pub const IMAGE_EXTENSIONS: [&str; 2] = ["png", "exr"];

/// Refuses, before any work, an image output (`option` names it) that [`write_image`] could
/// not write: one whose name ends in neither `.png` nor `.exr`.
pub fn check_image_output(option: &str, path: &Path) -> Result<()> {
    crate::fs::check_named_format(
        crate::fs::Output { option, path },
        &IMAGE_EXTENSIONS,
        "images are PNG (tone-mapped) or OpenEXR (linear)",
    )
}

#[derive(Clone, Copy)]
enum ImageFormat {
    Png,
    Exr,
}

impl ImageFormat {
    fn of(path: &Path) -> Result<ImageFormat> {
        format_by_extension(
            path,
            &[("png", ImageFormat::Png), ("exr", ImageFormat::Exr)],
            "image files",
        )
    }
}

fn encode_png(
    pixels: &[[f32; 4]],
    width: u32,
    height: u32,
    tone: ToneMap,
    exposure_stops: f32,
) -> std::result::Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(
            &to_rgba8(pixels, tone, exposure_stops),
            width,
            height,
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| e.to_string())?;
    Ok(bytes)
}

fn encode_exr(
    pixels: &[[f32; 4]],
    width: u32,
    height: u32,
) -> std::result::Result<Vec<u8>, String> {
    use exr::prelude::{Encoding, Image, LineOrder, SpecificChannels, Vec2, WritableImage};
    let w = width as usize;
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let [r, g, b, a] = pixels[y * w + x];
        (r, g, b, a)
    });
    // Blocks in increasing order, not in the order the threads compressing them finish: the
    // same image is the same bytes.
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::default()
    };
    let mut bytes = Cursor::new(Vec::new());
    Image::from_encoded_channels((w, height as usize), encoding, channels)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| e.to_string())?;
    let mut bytes = bytes.into_inner();
    crate::images::sort_exr_header_attributes(&mut bytes)?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::entries;

    #[test]
    fn an_exr_is_the_same_bytes_every_time() {
        // The exr crate orders header attributes by a HashMap's iteration order, and writes the
        // blocks of a large image in the order its threads finish compressing them.
        for (width, height) in [(4, 3), (256, 255)] {
            let pixels: Vec<[f32; 4]> = (0..width * height)
                .map(|i| [(i % 97) as f32, 0.5, (i / 7) as f32, 1.0])
                .collect();
            let first = encode_exr(&pixels, width, height).unwrap();
            for _ in 0..16 {
                assert_eq!(encode_exr(&pixels, width, height).unwrap(), first);
            }
        }
    }

    #[test]
    fn tone_maps_behave_at_their_landmarks() {
        assert_eq!(tone_map(0.25, ToneMap::None, 0.0), 0.25);
        assert_eq!(tone_map(0.25, ToneMap::None, 1.0), 0.5);
        assert_eq!(tone_map(3.0, ToneMap::None, 0.0), 1.0);
        assert_eq!(tone_map(-1.0, ToneMap::None, 0.0), 0.0);
        assert_eq!(tone_map(1.0, ToneMap::Reinhard, 0.0), 0.5);
        assert!(tone_map(1e6, ToneMap::Reinhard, 0.0) > 0.999);
        assert_eq!(tone_map(0.0, ToneMap::Aces, 0.0), 0.0);
        assert!((tone_map(0.18, ToneMap::Aces, 0.0) - 0.2670).abs() < 1e-3);
        assert_eq!(tone_map(100.0, ToneMap::Aces, 0.0), 1.0);
        for tone in [ToneMap::None, ToneMap::Reinhard, ToneMap::Aces] {
            let values: Vec<f32> = (0..200)
                .map(|i| tone_map(i as f32 * 0.05, tone, 0.0))
                .collect();
            assert!(
                values.windows(2).all(|w| w[0] <= w[1]),
                "{tone:?} is not monotonic"
            );
        }
    }

    #[test]
    fn rgba8_pixels_are_srgb_encoded_with_linear_alpha() {
        assert_eq!(
            to_rgba8(&[[0.5, 1.0, 0.0, 1.0]], ToneMap::None, 0.0),
            [188, 255, 0, 255]
        );
        assert_eq!(
            to_rgba8(&[[f32::NAN, 0.0, 0.0, 0.0]], ToneMap::None, 0.0),
            [0, 0, 0, 0]
        );
    }

    #[test]
    fn side_by_side_places_panels_left_to_right() {
        let panel = |v: f32| vec![[v, v, v, 1.0]; 6];
        let mut first = panel(1.0);
        first[3] = [9.0; 4]; // (x 0, y 1) of a 3x2 panel
        let joined = side_by_side(&[first, panel(2.0), panel(3.0)], 3, 2).unwrap();
        assert_eq!(joined.len(), 18);
        let row0: Vec<f32> = joined[..9].iter().map(|p| p[0]).collect();
        assert_eq!(row0, [1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0]);
        assert_eq!(joined[9], [9.0; 4]);
        assert!(side_by_side(&[], 3, 2).is_err());
        assert!(side_by_side(&[panel(1.0), vec![[0.0; 4]; 5]], 3, 2).is_err());
        assert!(side_by_side(&[Vec::new()], 0, 2).is_err());
    }

    #[test]
    fn png_has_the_size_mean_and_centre_asked_for() {
        let scratch = tempfile::tempdir().unwrap();
        let (w, h) = (5u32, 3u32);
        // Left columns linear 0.5 (sRGB byte 188), the rest black and transparent.
        let pixels: Vec<[f32; 4]> = (0..w * h)
            .map(|i| {
                if i % w < 3 {
                    [0.5, 0.5, 0.5, 1.0]
                } else {
                    [0.0; 4]
                }
            })
            .collect();
        let path = scratch.path().join("preview.png");
        write_image(&path, &pixels, w, h, ToneMap::None, 0.0).unwrap();
        let png = image::open(&path).unwrap().into_rgba8();
        assert_eq!(png.dimensions(), (w, h));
        assert_eq!(png.get_pixel(2, 1).0, [188, 188, 188, 255]);
        let mean_red = png.pixels().map(|p| p.0[0] as f64).sum::<f64>() / (w * h) as f64;
        assert!((mean_red - 188.0 * 3.0 / 5.0).abs() < 1e-9, "{mean_red}");
        assert_eq!(entries(scratch.path()), ["preview.png"]);
    }

    #[test]
    fn exr_keeps_linear_hdr_values() {
        let scratch = tempfile::tempdir().unwrap();
        let pixels = vec![
            [0.25, 7.5, 1000.0, 1.0],
            [0.0; 4],
            [1.0, 2.0, 3.0, 0.5],
            [-1.0, 0.0, 0.0, 1.0],
        ];
        let path = scratch.path().join("preview.exr");
        write_image(&path, &pixels, 2, 2, ToneMap::Aces, 3.0).unwrap();
        let image = exr::prelude::read_first_rgba_layer_from_file(
            &path,
            |size, _| vec![[0.0f32; 4]; size.0 * size.1],
            |out: &mut Vec<[f32; 4]>, pos, (r, g, b, a): (f32, f32, f32, f32)| {
                out[pos.1 * 2 + pos.0] = [r, g, b, a];
            },
        )
        .unwrap();
        assert_eq!(image.layer_data.channel_data.pixels, pixels);
    }

    #[test]
    fn bad_image_writes_fail_without_leaving_files() {
        let scratch = tempfile::tempdir().unwrap();
        let pixels = vec![[1.0; 4]; 4];
        let png = scratch.path().join("a.png");
        assert!(write_image(&png, &pixels, 3, 2, ToneMap::None, 0.0).is_err());
        assert!(write_image(&png, &pixels, 0, 0, ToneMap::None, 0.0).is_err());
        assert!(write_image(&png, &pixels, 2, 2, ToneMap::None, f32::NAN).is_err());
        assert!(write_image(
            &scratch.path().join("a.jpg"),
            &pixels,
            2,
            2,
            ToneMap::None,
            0.0
        )
        .is_err());
        assert!(write_image(&scratch.path().join("a"), &pixels, 2, 2, ToneMap::None, 0.0).is_err());
        let missing = scratch.path().join("missing").join("a.png");
        assert!(write_image(&missing, &pixels, 2, 2, ToneMap::None, 0.0).is_err());
        assert!(
            entries(scratch.path()).is_empty(),
            "{:?}",
            entries(scratch.path())
        );
    }
}
