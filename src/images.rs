//! PNG, JPEG and Radiance images decoded within a bound of the bytes that hold them.
//!
//! A header may declare any size; the decoders reserve the declared image before reading a
//! row. No image data of these formats expands by more than deflate's 1032 to 1 (Radiance's
//! run-length code, 127 bytes in 2, a float RGB pixel from 4 bytes, stays below it; so does
//! JPEG's least entropy-coded block), so a declared image that would decode to more than
//! [`MAX_EXPANSION`] times the file's bytes is refused before anything is reserved for it.

use std::io::Cursor;

use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader};

use crate::error::image_error;

/// The most decoded bytes per byte of file an image of these formats can hold.
pub const MAX_EXPANSION: u64 = 1032;

/// Headers, palettes and chunk framing: allowed beyond the expansion of the data.
const HEADER_ALLOWANCE: u64 = 64 << 10;

/// The largest decoded image (in the decoder's own bytes) that `file_bytes` can hold.
pub fn decodable_bytes(file_bytes: usize) -> u64 {
    MAX_EXPANSION * file_bytes as u64 + HEADER_ALLOWANCE
}

/// Decodes `bytes` as `format`, refusing in plain words (on one line) a header that declares
/// more than the file can hold.
pub fn decode(bytes: &[u8], format: ImageFormat) -> Result<DynamicImage, String> {
    let decoder = ImageReader::with_format(Cursor::new(bytes), format)
        .into_decoder()
        .map_err(|e| image_error(&e))?;
    let declared = decoder.total_bytes();
    if declared > decodable_bytes(bytes.len()) {
        let (width, height) = decoder.dimensions();
        return Err(format!(
            "its header declares {width}x{height} pixels, more than its {} bytes can hold \
             (truncated or damaged)",
            bytes.len()
        ));
    }
    DynamicImage::from_decoder(decoder).map_err(|e| image_error(&e))
}

/// Puts the attributes of a single-part OpenEXR header in name order, as the OpenEXR library
/// writes them. The exr crate writes them in the order of a `HashMap`, which differs from run
/// to run, and every image the tool writes must give the same bytes every time. The header keeps its length, so the
/// offset table after it still points at the chunks.
pub fn sort_exr_header_attributes(bytes: &mut [u8]) -> std::result::Result<(), String> {
    const MULTIPART_OR_DEEP: u32 = 0x1800;
    let flags = bytes
        .get(4..8)
        .map(|v| u32::from_le_bytes([v[0], v[1], v[2], v[3]]))
        .ok_or("no OpenEXR version field")?;
    if flags & MULTIPART_OR_DEEP != 0 {
        return Err("only a single-part scan-line image's header is sorted".into());
    }
    let mut attributes: Vec<&[u8]> = Vec::new();
    let mut at = 8;
    let broken = || "the encoder wrote a header that does not parse".to_string();
    while *bytes.get(at).ok_or_else(broken)? != 0 {
        let name_end = at + nul_position(&bytes[at..]).ok_or_else(broken)?;
        let kind_end = name_end + 1 + nul_position(&bytes[name_end + 1..]).ok_or_else(broken)?;
        let size_at = kind_end + 1;
        let size = bytes
            .get(size_at..size_at + 4)
            .map(|v| u32::from_le_bytes([v[0], v[1], v[2], v[3]]) as usize)
            .ok_or_else(broken)?;
        let end = size_at + 4 + size;
        attributes.push(bytes.get(at..end).ok_or_else(broken)?);
        at = end;
    }
    attributes.sort_by_key(|attribute| &attribute[..nul_position(attribute).unwrap_or(0)]);
    let header: Vec<u8> = attributes.concat();
    bytes[8..8 + header.len()].copy_from_slice(&header);
    Ok(())
}

pub(crate) fn nul_position(bytes: &[u8]) -> Option<usize> {
    bytes.iter().position(|&b| b == 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(width: u32, height: u32) -> Vec<u8> {
        let mut bytes = Vec::new();
        image::RgbImage::from_fn(width, height, |x, y| image::Rgb([x as u8, y as u8, 7]))
            .write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
            .unwrap();
        bytes
    }

    /// A 64x64 PNG whose header says 60000x60000: refused on its size, before decoding.
    #[test]
    fn a_header_larger_than_its_data_is_refused() {
        let mut bytes = png(64, 64);
        bytes[16..20].copy_from_slice(&60000u32.to_be_bytes());
        bytes[20..24].copy_from_slice(&60000u32.to_be_bytes());
        let bytes = crate::testing::hostile::resealed(crate::testing::hostile::Reader::Png, &bytes);
        let error = decode(&bytes, ImageFormat::Png).unwrap_err();
        assert!(error.contains("declares 60000x60000 pixels"), "{error}");
        assert!(!error.contains('\n'));
    }

    /// A flat image compresses as far as deflate goes, and still decodes.
    #[test]
    fn a_flat_image_compressed_to_the_limit_is_read() {
        let mut bytes = Vec::new();
        image::GrayImage::new(2048, 2048)
            .write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
            .unwrap();
        assert!(
            decodable_bytes(bytes.len()) >= 2048 * 2048,
            "{} bytes",
            bytes.len()
        );
        let image = decode(&bytes, ImageFormat::Png).unwrap();
        assert_eq!((image.width(), image.height()), (2048, 2048));
    }
}
