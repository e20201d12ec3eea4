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
