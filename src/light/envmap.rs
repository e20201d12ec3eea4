//! Environment maps as linear RGB f32 images: OpenEXR through `exr`, Radiance .hdr and
//! sRGB PNG/JPEG through `image` (Radiance files signed `#?RGBE` or by any other program too).
//! The format is told by the file's magic bytes, not its name; a name that says another
//! format gets a warning ([`load_with_warnings`]).

use crate::color::srgb_to_linear;
use crate::error::{one_line, Error, Result};
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// A linear RGB image, row 0 at the top, `pixels[y * width + x]`.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
    /// Where the pixels came from, for error messages (`<memory>` for built images).
    pub source: PathBuf,
}

impl EnvImage {
    pub fn new(
        width: usize,
        height: usize,
        pixels: Vec<[f32; 3]>,
        source: impl Into<PathBuf>,
    ) -> Result<Self> {
        let source = source.into();
        if width == 0 || height == 0 {
            return Err(Error::light(
                source,
                format!("the image is empty ({width}x{height})"),
            ));
        }
        if pixels.len() != width * height {
            return Err(Error::light(
                source,
                format!("{} pixels for a {width}x{height} image", pixels.len()),
            ));
        }
        Ok(EnvImage {
            width,
            height,
            pixels,
            source,
        })
    }

    /// An in-memory image with `pixel(x, y)` at every pixel.
    pub fn from_fn(
        width: usize,
        height: usize,
        mut pixel: impl FnMut(usize, usize) -> [f32; 3],
    ) -> Result<Self> {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| pixel(x, y))
            .collect();
        EnvImage::new(width, height, pixels, "<memory>")
    }

    pub fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[y * self.width + x]
    }
}

/// Reads an environment map file.
pub fn load(path: &Path) -> Result<EnvImage> {
    load_with_warnings(path).map(|(image, _)| image)
}

/// [`load`], also giving a line to show the user when the file's extension names another
/// format than its content (a PNG named `.exr`): it is read as what it holds, as a renamed
/// file usually is meant to be, and the line says so.
pub fn load_with_warnings(path: &Path) -> Result<(EnvImage, Vec<String>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let image = decode(&bytes, path)?;
    let warnings = misnamed(&bytes, path)
        .into_iter()
        .chain(unusual_radiance_program(&bytes))
        .collect();
    Ok((image, warnings))
}

/// What to say when a Radiance file's signature names a program other than `RADIANCE` or
/// `RGBE` (the format allows any, and the file is read; a damaged or foreign file may start
/// with `#?` too).
fn unusual_radiance_program(bytes: &[u8]) -> Option<String> {
    radiance_renamed(bytes)?;
    let line = bytes.split(|&b| b == b'\n').next()?;
    let name = String::from_utf8_lossy(&line[2..]);
    (name != "RGBE").then(|| {
        format!("its Radiance signature names the program {name:?}, not RADIANCE or RGBE; read as Radiance")
    })
}

/// What to say when `path`'s extension names a format other than the one `bytes` hold;
/// `None` when they agree or the extension names no image format.
pub fn misnamed(bytes: &[u8], path: &Path) -> Option<String> {
    let extension = path.extension()?.to_str()?.to_ascii_lowercase();
    let named = match extension.as_str() {
        "exr" => "OpenEXR",
        "hdr" | "pic" | "rgbe" => "Radiance HDR",
        "png" => "PNG",
        "jpg" | "jpeg" => "JPEG",
        _ => return None,
    };
    let held = if bytes.starts_with(&EXR_MAGIC) {
        "OpenEXR"
    } else if bytes.starts_with(b"#?") {
        "Radiance HDR"
    } else {
        match image::guess_format(bytes).ok()? {
            image::ImageFormat::Png => "PNG",
            image::ImageFormat::Jpeg => "JPEG",
            image::ImageFormat::Hdr => "Radiance HDR",
            _ => return None,
        }
    };
    (named != held)
        .then(|| format!("named .{extension}, but its content is {held}; read as {held}"))
}

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Decodes an environment map held in memory; `path` only names it in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<EnvImage> {
    if bytes.is_empty() {
        return Err(Error::light(path, "the file is empty"));
    }
    if bytes.starts_with(&EXR_MAGIC) {
        return decode_exr(bytes, path);
    }
    match radiance_renamed(bytes) {
        Some(renamed) => decode_with_image(&renamed, path),
        None => decode_with_image(bytes, path),
    }
}

/// The signature the `image` crate's Radiance decoder requires as the first line.
const RADIANCE_SIGNATURE: &[u8] = b"#?RADIANCE";

/// A Radiance file whose first line names another program (`#?RGBE`, as Mitsuba writes), with
/// that line rewritten to `#?RADIANCE`, the only one `image` reads; the format allows any program
/// name after `#?`. `None` for everything else, signed `#?RADIANCE` files included.
fn radiance_renamed(bytes: &[u8]) -> Option<Vec<u8>> {
    let rest = bytes.strip_prefix(b"#?")?;
    // A program name: a short word, then the end of the line.
    let name_len = rest.iter().take(65).position(|&b| b == b'\n')?;
    let name = &rest[..name_len];
    let word = |b: &u8| b.is_ascii_alphanumeric() || b"_-.+".contains(b);
    if name.is_empty() || !name.iter().all(word) || bytes.starts_with(RADIANCE_SIGNATURE) {
        return None;
    }
    Some([RADIANCE_SIGNATURE, &rest[name_len..]].concat())
}

/// The most pixels an OpenEXR environment map may declare: 16384 x 16384, 3 GiB as RGB floats.
/// A header is a few bytes, so its data window alone justifies no allocation.
pub const MAX_EXR_PIXELS: usize = 1 << 28;

/// The most pixels an OpenEXR file may declare per byte it holds, beyond
/// [`EXR_PIXELS_ANY_FILE`]: 190 times the 5.4 of the most compressed map here (DWAB), above
/// what deflate leaves of half-float RGB (172).
pub const EXR_PIXELS_PER_BYTE: usize = 1024;

/// Pixels any OpenEXR file may declare, however small (a flat map compresses to almost nothing).
pub const EXR_PIXELS_ANY_FILE: usize = 1 << 20;

/// The most pixels an OpenEXR file of `file_bytes` may declare.
pub fn exr_pixels_allowed(file_bytes: usize) -> usize {
    file_bytes
        .saturating_mul(EXR_PIXELS_PER_BYTE)
        .saturating_add(EXR_PIXELS_ANY_FILE)
        .min(MAX_EXR_PIXELS)
}

/// Pixels of the first valid layer, largest resolution level; R, G, B must be present and any
/// alpha is ignored. Half, float and uint samples all arrive as f32. A file without R, G, B
/// whose first layer with a Y channel has no chroma (RY, BY) is read as grey, R = G = B = Y.
fn decode_exr(bytes: &[u8], path: &Path) -> Result<EnvImage> {
    let fail =
        |e: exr::error::Error| Error::light(path, format!("OpenEXR: {}", one_line(&e.to_string())));
    // The header's data window is checked before the decoder allocates it.
    if let Ok(meta) = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false) {
        for header in &meta.headers {
            let size = header.layer_size;
            let pixels = size.width().saturating_mul(size.height());
            if pixels > MAX_EXR_PIXELS {
                return Err(Error::light(
                    path,
                    format!(
                        "OpenEXR: its data window is {} x {} pixels, more than the {} an \
                         environment map may have",
                        size.width(),
                        size.height(),
                        MAX_EXR_PIXELS
                    ),
                ));
            }
            if pixels > exr_pixels_allowed(bytes.len()) {
                return Err(Error::light(
                    path,
                    format!(
                        "OpenEXR: its data window is {} x {} pixels, more than its {} bytes \
                         can hold (truncated or damaged)",
                        size.width(),
                        size.height(),
                        bytes.len()
                    ),
                ));
            }
        }
    }
    let rgb_error = match decode_exr_channels(bytes, ["R", "G", "B"]) {
        Ok((width, height, pixels)) => return EnvImage::new(width, height, pixels, path),
        Err(e) => e,
    };
    // Only when no layer has R, G and B: the luminance layer, or what the layers do have.
    let Ok(meta) = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false) else {
        return Err(fail(rgb_error));
    };
    let has = |header: &exr::meta::header::Header, name: &str| {
        header.channels.list.iter().any(|c| c.name == *name)
    };
    let layers = || meta.headers.iter().filter(|h| !h.deep);
    if layers().any(|h| ["R", "G", "B"].iter().all(|n| has(h, n))) {
        return Err(fail(rgb_error));
    }
    match layers().find(|h| has(h, "Y")) {
        Some(h) if !has(h, "RY") && !has(h, "BY") => {
            let (width, height, pixels) =
                decode_exr_channels(bytes, ["Y", "Y", "Y"]).map_err(fail)?;
            EnvImage::new(width, height, pixels, path)
        }
        Some(_) => Err(Error::light(
            path,
            "OpenEXR: a luminance-chroma image (Y, RY, BY), which prt-gpu does not read; \
             convert it to RGB",
        )),
        None => {
            let names: Vec<String> = layers()
                .flat_map(|h| h.channels.list.iter().map(|c| c.name.to_string()))
                .collect();
            Err(Error::light(
                path,
                format!(
                    "OpenEXR: an environment map needs R, G and B channels (or a Y channel \
                     for grey), and this file has {}",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            ))
        }
    }
}

/// The named channels of the first layer that has them all, as (width, height, pixels); a
/// channel named twice is read once and repeated (`Y` as grey).
fn decode_exr_channels(
    bytes: &[u8],
    [r, g, b]: [&str; 3],
) -> std::result::Result<(usize, usize, Vec<[f32; 3]>), exr::error::Error> {
    use exr::prelude::*;
    if r == g && g == b {
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .specific_channels()
            .required(r)
            .collect_pixels(
                |size: Vec2<usize>, _| (size.width(), vec![[0.0f32; 3]; size.area()]),
                |(width, pixels): &mut (usize, Vec<[f32; 3]>), at: Vec2<usize>, (y,): (f32,)| {
                    pixels[at.y() * *width + at.x()] = [y; 3];
                },
            )
            .first_valid_layer()
            .all_attributes()
            .from_buffered(Cursor::new(bytes))?;
        let size = image.layer_data.size;
        let (_, pixels) = image.layer_data.channel_data.pixels;
        return Ok((size.width(), size.height(), pixels));
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required(r)
        .required(g)
        .required(b)
        .collect_pixels(
            |size: Vec2<usize>, _| (size.width(), vec![[0.0f32; 3]; size.area()]),
            |(width, pixels): &mut (usize, Vec<[f32; 3]>),
             at: Vec2<usize>,
             (r, g, b): (f32, f32, f32)| {
                pixels[at.y() * *width + at.x()] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))?;
    let size = image.layer_data.size;
    let (_, pixels) = image.layer_data.channel_data.pixels;
    Ok((size.width(), size.height(), pixels))
}

fn decode_with_image(bytes: &[u8], path: &Path) -> Result<EnvImage> {
    let format = image::guess_format(bytes).map_err(|_| {
        Error::light(
            path,
            "not an environment map this program reads (OpenEXR, Radiance .hdr, PNG, JPEG)",
        )
    })?;
    let decoded = crate::images::decode(bytes, format).map_err(|e| Error::light(path, e))?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    let rgb = decoded.into_rgb32f();
    // Radiance files hold linear radiance; 8- and 16-bit formats hold sRGB-encoded values.
    let linear = format == image::ImageFormat::Hdr;
    let pixels = rgb
        .pixels()
        .map(|p| {
            if linear {
                p.0
            } else {
                p.0.map(|c| srgb_to_linear(c as f64) as f32)
            }
        })
        .collect();
    EnvImage::new(width, height, pixels, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn studio() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/studio.exr")
    }

    fn assert_one_line(e: &Error) -> String {
        let text = e.to_string();
        assert!(!text.contains('\n'), "{text}");
        text
    }

    #[test]
    fn loads_the_dwab_half_float_exr_copy() {
        let image = load(&studio()).unwrap();
        assert_eq!((image.width, image.height), (1024, 512));
        assert!(image.pixels.iter().flatten().all(|v| v.is_finite()));
        let mean: f64 = image
            .pixels
            .iter()
            .flatten()
            .map(|&v| v as f64)
            .sum::<f64>()
            / (3 * image.pixels.len()) as f64;
        assert!(mean > 0.01 && mean < 100.0, "mean {mean}");
    }

    #[test]
    fn loads_the_shared_real_maps_when_present() {
        let dir = Path::new("/work/shared/data/envmaps");
        for (name, peak_at_least) in [("forest.exr", 1.0f32), ("sunrise.exr", 30_000.0)] {
            let path = dir.join(name);
            if !path.exists() {
                eprintln!("skipping {}: not on this machine", path.display());
                continue;
            }
            let image = load(&path).unwrap();
            assert_eq!((image.width, image.height), (1024, 512));
            let peak = image.pixels.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
            assert!(peak >= peak_at_least, "{name}: peak {peak}");
        }
    }

    #[test]
    fn truncated_exr_is_a_one_line_error() {
        let bytes = std::fs::read(studio()).unwrap();
        for keep in [4, 100, bytes.len() / 2] {
            let e = decode(&bytes[..keep], Path::new("cut.exr")).unwrap_err();
            let text = assert_one_line(&e);
            assert!(text.starts_with("cut.exr: OpenEXR"), "{text}");
        }
    }

    #[test]
    fn empty_and_unknown_files_are_errors() {
        let e = decode(&[], Path::new("empty.hdr")).unwrap_err();
        assert_eq!(assert_one_line(&e), "empty.hdr: the file is empty");
        let e = decode(b"hello world", Path::new("x.txt")).unwrap_err();
        assert!(assert_one_line(&e).contains("not an environment map"));
        let e = EnvImage::new(0, 4, vec![], "zero.exr").unwrap_err();
        assert_eq!(assert_one_line(&e), "zero.exr: the image is empty (0x4)");
        assert!(EnvImage::from_fn(0, 0, |_, _| [0.0; 3]).is_err());
    }

    /// A channel's name and its value at pixel (x, y).
    type Channel = (&'static str, fn(usize, usize) -> f32);

    /// A 4x2 OpenEXR file of float channels.
    fn exr_with_channels(channels: &[Channel]) -> Vec<u8> {
        use exr::prelude::*;
        let list = channels
            .iter()
            .map(|&(name, value)| {
                let samples = (0..8).map(|i| value(i % 4, i / 4)).collect();
                AnyChannel::new(name, FlatSamples::F32(samples))
            })
            .collect();
        let mut bytes = Cursor::new(Vec::new());
        Image::from_channels((4, 2), AnyChannels::sort(list))
            .write()
            .to_buffered(&mut bytes)
            .unwrap();
        bytes.into_inner()
    }

    #[test]
    fn a_luminance_exr_is_read_as_grey() {
        let bytes = exr_with_channels(&[("Y", |x, y| (x + 10 * y) as f32)]);
        let image = decode(&bytes, Path::new("y.exr")).unwrap();
        assert_eq!((image.width, image.height), (4, 2));
        assert_eq!(image.pixel(3, 1), [13.0; 3]);
        assert_eq!(image.pixel(1, 0), [1.0; 3]);
        // With R, G and B beside it, those are read.
        let rgb: [Channel; 4] = [
            ("Y", |_, _| 9.0),
            ("R", |_, _| 1.0),
            ("G", |_, _| 2.0),
            ("B", |_, _| 3.0),
        ];
        let image = decode(&exr_with_channels(&rgb), Path::new("rgby.exr")).unwrap();
        assert_eq!(image.pixel(0, 0), [1.0, 2.0, 3.0]);
    }

    /// A header that declares a data window of 2^32 pixels is refused from the header (the
    /// decoder once allocated it whole before reading a pixel, and the process aborted).
    #[test]
    fn an_exr_declaring_a_huge_data_window_is_refused_before_decoding() {
        let mut bytes = exr_with_channels(&[("Y", |_, _| 1.0)]);
        let name = b"dataWindow\0box2i\0";
        let at = bytes
            .windows(name.len())
            .position(|w| w == name)
            .expect("a data window attribute")
            + name.len()
            + 4;
        // xMin, yMin, xMax, yMax: 65536 x 65536 pixels.
        for (i, value) in [0i32, 0, 65535, 65535].iter().enumerate() {
            bytes[at + 4 * i..at + 4 * i + 4].copy_from_slice(&value.to_le_bytes());
        }
        let e = decode(&bytes, Path::new("huge.exr")).unwrap_err();
        assert!(
            assert_one_line(&e).contains("data window is 65536 x 65536"),
            "{e}"
        );
    }

    /// The fuzzer's corpus held an EXR of 2 KB declaring 2^27 pixels, within the cap: 1.6 GB
    /// were reserved before a pixel was read. Now the data window is weighed against the file.
    #[test]
    fn an_exr_declaring_more_than_its_bytes_hold_is_refused() {
        let mut bytes = exr_with_channels(&[("Y", |_, _| 1.0)]);
        for name in [&b"dataWindow\0box2i\0"[..], b"displayWindow\0box2i\0"] {
            let at = bytes.windows(name.len()).position(|w| w == name).unwrap() + name.len() + 4;
            bytes[at + 8..at + 12].copy_from_slice(&16383i32.to_le_bytes());
            bytes[at + 12..at + 16].copy_from_slice(&8191i32.to_le_bytes());
        }
        const { assert!(16384 * 8192 <= MAX_EXR_PIXELS) };
        let e = decode(&bytes, Path::new("dense.exr")).unwrap_err();
        let said = assert_one_line(&e);
        assert!(
            said.contains("16384 x 8192 pixels, more than its"),
            "{said}"
        );
        // The real maps are far from the bound: 1024 x 512 in 97,867 bytes.
        assert!(exr_pixels_allowed(97_867) > 512 * 1024 * 100);
    }

    #[test]
    fn an_exr_without_colour_channels_says_what_it_has() {
        let bytes = exr_with_channels(&[("A", |_, _| 1.0), ("Z", |_, _| 2.0)]);
        let e = decode(&bytes, Path::new("az.exr")).unwrap_err();
        assert_eq!(
            assert_one_line(&e),
            "az.exr: OpenEXR: an environment map needs R, G and B channels (or a Y channel \
             for grey), and this file has A, Z"
        );
        let chroma: [Channel; 3] = [("Y", |_, _| 1.0), ("RY", |_, _| 0.1), ("BY", |_, _| 0.1)];
        let e = decode(&exr_with_channels(&chroma), Path::new("yc.exr")).unwrap_err();
        assert!(assert_one_line(&e).contains("luminance-chroma"), "{e}");
    }

    #[test]
    fn a_map_named_for_another_format_is_read_with_a_warning() {
        let mut png = Vec::new();
        image::RgbImage::from_pixel(4, 2, image::Rgb([188, 0, 128]))
            .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let exr = exr_with_channels(&[("Y", |_, _| 1.0)]);
        let tmp = tempfile::tempdir().unwrap();
        for (name, bytes, said) in [
            (
                "map.exr",
                &png,
                Some("named .exr, but its content is PNG; read as PNG"),
            ),
            ("map.PNG", &png, None),
            (
                "map.hdr",
                &exr,
                Some("named .hdr, but its content is OpenEXR; read as OpenEXR"),
            ),
            ("map.exr", &exr, None),
            ("map.bin", &png, None),
        ] {
            let path = tmp.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            let (image, warnings) = load_with_warnings(&path).unwrap();
            assert_eq!(image, decode(bytes, &path).unwrap());
            assert_eq!(warnings, said.into_iter().collect::<Vec<_>>(), "{name}");
        }
    }

    #[test]
    fn png_is_decoded_from_srgb() {
        let mut png = Vec::new();
        let source = image::RgbImage::from_fn(4, 2, |x, _| {
            image::Rgb([if x == 0 { 255 } else { 188 }, 0, 128])
        });
        source
            .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let image = decode(&png, Path::new("t.png")).unwrap();
        assert_eq!((image.width, image.height), (4, 2));
        let [r, g, b] = image.pixel(1, 1);
        // sRGB 188 is about linear 0.5; 128 about 0.2158.
        assert!((r - 0.5029).abs() < 1e-3 && g == 0.0 && (b - 0.2158).abs() < 1e-3);
        assert_eq!(image.pixel(0, 0)[0], 1.0);
    }

    /// A 3x2 Radiance file written by hand: flat (not run-length encoded) RGBE pixels, first
    /// line `#?{program}`.
    fn hand_written_hdr(program: &str) -> Vec<u8> {
        let mut hdr =
            format!("#?{program}\n# a comment\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 3\n").into_bytes();
        // RGBE: value = mantissa * 2^(exponent - 136).
        for (x, y) in [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1)] {
            hdr.extend_from_slice(&[128 + 40 * x, 64 * y, 200, 129 + x]);
        }
        hdr
    }

    #[test]
    fn radiance_files_signed_by_another_program_are_read() {
        let radiance = hand_written_hdr("RADIANCE");
        let rgbe = hand_written_hdr("RGBE");
        let tmp = tempfile::tempdir().unwrap();
        let (radiance_path, rgbe_path) = (tmp.path().join("r.hdr"), tmp.path().join("m.hdr"));
        std::fs::write(&radiance_path, &radiance).unwrap();
        std::fs::write(&rgbe_path, &rgbe).unwrap();

        let expected = load(&radiance_path).unwrap();
        assert_eq!((expected.width, expected.height), (3, 2));
        // (2, 1): mantissas 208, 64, 200 with exponent 131, a scale of 2^-5.
        assert_eq!(expected.pixel(2, 1), [6.5, 2.0, 6.25]);
        let read = load(&rgbe_path).unwrap();
        assert_eq!(read.pixels, expected.pixels);
        assert_eq!(read.source, rgbe_path);

        // What the image crate's encoder writes (run-length encoded rows), renamed likewise.
        let from_crate_encoder = {
            let mut hdr = Vec::new();
            let source = image::Rgb32FImage::from_fn(4, 2, |x, y| {
                image::Rgb([x as f32 + 0.25, y as f32 * 3.0, 0.5])
            });
            image::DynamicImage::ImageRgb32F(source)
                .write_to(&mut Cursor::new(&mut hdr), image::ImageFormat::Hdr)
                .unwrap();
            hdr
        };
        let line_end = from_crate_encoder.iter().position(|&b| b == b'\n').unwrap();
        assert_eq!(&from_crate_encoder[..line_end], RADIANCE_SIGNATURE);
        let renamed = [b"#?RGBE", &from_crate_encoder[line_end..]].concat();
        let a = decode(&from_crate_encoder, Path::new("a.hdr")).unwrap();
        let b = decode(&renamed, Path::new("b.hdr")).unwrap();
        assert_eq!(a.pixels, b.pixels);
    }

    #[test]
    fn a_radiance_file_with_garbage_after_the_signature_is_an_error() {
        let good = hand_written_hdr("RGBE");
        let garbage = [b"#?\xff\x00 not a name", &good[6..]].concat();
        let e = decode(&garbage, Path::new("g.hdr")).unwrap_err();
        assert!(assert_one_line(&e).contains("not an environment map"));
        // A program name, but no header after it.
        let e = decode(b"#?RGBE\n-Y 2 +X 3", Path::new("h.hdr")).unwrap_err();
        assert!(assert_one_line(&e).starts_with("h.hdr: "));
        // No end of line after the name.
        assert!(decode(b"#?RGBE", Path::new("i.hdr")).is_err());
    }

    /// Any program name after `#?` is valid Radiance, so `#?GARBAGE` is read, with a warning;
    /// `#?RGBE` (Mitsuba's) and `#?RADIANCE` say nothing.
    #[test]
    fn a_radiance_file_signed_by_an_unknown_program_is_read_with_a_warning() {
        let tmp = tempfile::tempdir().unwrap();
        let good = hand_written_hdr("RGBE");
        let body = &good[b"#?RGBE".len()..];
        for (name, said) in [("RGBE", false), ("RADIANCE", false), ("GARBAGE", true)] {
            let path = tmp.path().join(format!("{name}.hdr"));
            std::fs::write(&path, [format!("#?{name}").as_bytes(), body].concat()).unwrap();
            let (_, warnings) = load_with_warnings(&path).unwrap();
            assert_eq!(warnings.len(), said as usize, "{name}: {warnings:?}");
            if said {
                assert!(warnings[0].contains("\"GARBAGE\""), "{warnings:?}");
            }
        }
    }

    #[test]
    fn radiance_hdr_stays_linear() {
        let mut hdr = Vec::new();
        let source =
            image::Rgb32FImage::from_fn(4, 2, |x, _| image::Rgb([x as f32 * 2.0, 0.5, 100.0]));
        image::DynamicImage::ImageRgb32F(source)
            .write_to(&mut Cursor::new(&mut hdr), image::ImageFormat::Hdr)
            .unwrap();
        let image = decode(&hdr, Path::new("t.hdr")).unwrap();
        let [r, g, b] = image.pixel(3, 0);
        assert!((r - 6.0).abs() < 0.05 && (g - 0.5).abs() < 0.01 && (b - 100.0).abs() < 1.0);
    }
}
