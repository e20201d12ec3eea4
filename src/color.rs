//! The sRGB transfer function (IEC 61966-2-1) both ways: 8-bit colours in meshes and
//! environment maps are decoded to linear, previews are encoded for display.

/// An sRGB-encoded value in [0, 1] to linear.
pub fn srgb_to_linear(encoded: f64) -> f64 {
    if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

/// A display-linear value in [0, 1] to sRGB encoding.
pub fn srgb_encode(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_encoding_matches_the_standard() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_encode(0.5) - 0.735_357).abs() < 1e-5);
        assert!((srgb_encode(0.002) - 0.02584).abs() < 1e-6);
    }

    #[test]
    fn decoding_inverts_encoding() {
        for i in 0..=100 {
            let linear = i as f32 / 100.0;
            let back = srgb_to_linear(srgb_encode(linear) as f64) as f32;
            assert!((back - linear).abs() < 2e-6, "{linear} -> {back}");
        }
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-12);
    }
}
