//! Screenshots against renders: the tolerance a browser's software rasteriser (SwiftShader)
//! and `prt-gpu render` (wgpu) agree within on the same bake, camera, light and exposure —
//! pixels differ along silhouettes and by rounding. Used by the web viewer's tests and the
//! engines' (three.js) test of relit lightmaps.

use image::RgbImage;

/// A pixel counts as different when a channel differs by more than this (of 255): well above
/// rounding and the software rasterisers' interpolation, well below what shading changes do.
pub const PIXEL_THRESHOLD: u8 = 12;
/// At most this fraction of pixels may differ: silhouette pixels, where the two rasterisers'
/// coverage rules and depth precision disagree.
pub const MAX_DIFFERENT_FRACTION: f64 = 0.005;
/// Mean absolute difference over all pixels and channels, in 8-bit steps (seen: about 0.013,
/// with 0.01% of pixels beyond the threshold, on the teapot at 320x240).
pub const MAX_MEAN_DIFFERENCE: f64 = 0.25;

#[derive(Debug)]
pub struct Difference {
    pub mean: f64,
    pub different_fraction: f64,
}

impl Difference {
    pub fn of(a: &RgbImage, b: &RgbImage) -> Difference {
        assert_eq!(a.dimensions(), b.dimensions());
        let mut sum = 0u64;
        let mut different = 0usize;
        for (p, q) in a.pixels().zip(b.pixels()) {
            let channel = |c: usize| p.0[c].abs_diff(q.0[c]);
            sum += (0..3).map(|c| channel(c) as u64).sum::<u64>();
            different += usize::from((0..3).any(|c| channel(c) > PIXEL_THRESHOLD));
        }
        let pixels = a.pixels().len();
        Difference {
            mean: sum as f64 / (3 * pixels) as f64,
            different_fraction: different as f64 / pixels as f64,
        }
    }

    pub fn within_tolerance(&self) -> bool {
        self.mean <= MAX_MEAN_DIFFERENCE && self.different_fraction <= MAX_DIFFERENT_FRACTION
    }
}

/// Whether the render is not empty: some pixels lit, some not (so agreeing means something).
pub fn has_contrast(image: &RgbImage) -> bool {
    let luma: Vec<u8> = image.pixels().map(|p| p.0[1]).collect();
    let (lo, hi) = (luma.iter().min().unwrap(), luma.iter().max().unwrap());
    hi - lo > 100
}
