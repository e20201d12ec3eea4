//! An edge-aware filter for lightmaps (`--denoise`): each texel becomes a weighted mean of
//! the texels of its own chart within [`DENOISE_RADIUS`] texels, weighed by how near they lie
//! in the atlas, how near the texel's tangent plane they lie on the surface, how alike their
//! normals are, and how alike their unshadowed fractions are against the noise those carry
//! (so that a step the noise cannot explain is kept: at many samples the filter does little).
//! Every SH coefficient is filtered with the same weights, so a relit map is the filtered map
//! relit.
//!
//! Averaging pays only where neighbouring texels' errors are independent: the texels of a map
//! to be denoised turn their sample sets each by its own angle (`sampling::ReceiverTurns`).
//! A texel never reads a texel of another chart (charts that touch on the surface meet at a
//! seam, which `receivers::seams` stitches afterwards), nor an invalid one (uncovered, or
//! found inside geometry: dilation fills those afterwards). Light that steps where geometry
//! does not (a hard shadow on a floor) is blurred where the noise hides the step, and never
//! by more than the footprint: a texel reads nothing farther than [`DENOISE_RADIUS`] texels
//! along either axis.
//!
//! wgsl/denoise.wgsl is the GPU twin, function for function, summing in the same order.

use glam::Vec3;
use rayon::prelude::*;

/// The filter's footprint: a texel reads the texels up to this many texels away along each
/// axis of the atlas (inside the disk the spatial weight leaves non-zero).
pub const DENOISE_RADIUS: u32 = 2;

/// Texels of the footprint's square, the most a texel reads.
pub const FOOTPRINT_TEXELS: u32 = (2 * DENOISE_RADIUS + 1) * (2 * DENOISE_RADIUS + 1);

/// How many standard deviations of their noise two texels' levels may differ by before the
/// range weight falls to zero.
pub const RANGE_SIGMAS: f32 = 1.5;

/// The chart of a texel the filter neither reads nor writes.
pub const NO_CHART: u32 = u32::MAX;

/// The power of the cosine between two normals in the weight: 8 keeps a neighbour whose
/// normal is 20 degrees off at 0.61 of its weight, one 45 degrees off at 0.06.
pub const NORMAL_POWER_SQUARINGS: u32 = 3;

/// What the filter knows of each texel of a `width x height` map, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct DenoiseGuide {
    pub width: u32,
    pub height: u32,
    /// Where the texel was baked, on the surface.
    pub positions: Vec<Vec3>,
    /// Its unit shading normal.
    pub normals: Vec<Vec3>,
    /// Its chart, or [`NO_CHART`] where the texel is not to be read or written.
    pub charts: Vec<u32>,
    /// Its level (the fraction of its cosine-weighted hemisphere left open, as baked) and the
    /// standard deviation of that level's noise ([`texel_level`]).
    pub levels: Vec<f32>,
    pub noise: Vec<f32>,
    /// The length one texel spans on the surface: the tangent-plane distance at which a
    /// neighbour's weight falls to zero.
    pub texel_length: f32,
}

impl DenoiseGuide {
    /// A guide whose texel length is the median distance on the surface between texels next to
    /// each other along a row of one chart (infinite where no two are: no plane limits).
    pub fn new(
        (width, height): (u32, u32),
        (positions, normals): (Vec<Vec3>, Vec<Vec3>),
        charts: Vec<u32>,
        (levels, noise): (Vec<f32>, Vec<f32>),
    ) -> Self {
        let mut steps: Vec<f32> = (0..positions.len())
            .filter(|&i| {
                (i as u32 % width) + 1 < width
                    && charts[i] != NO_CHART
                    && charts[i] == charts[i + 1]
            })
            .map(|i| positions[i].distance(positions[i + 1]))
            .collect();
        let texel_length = if steps.is_empty() {
            f32::INFINITY
        } else {
            let middle = steps.len() / 2;
            *steps.select_nth_unstable_by(middle, f32::total_cmp).1
        };
        DenoiseGuide {
            width,
            height,
            positions,
            normals,
            charts,
            levels,
            noise,
            texel_length,
        }
    }

    /// The weight texel `from` (at atlas offset `(dx, dy)` from `to`) has in the mean at `to`.
    pub fn weight(&self, to: usize, from: usize, (dx, dy): (i32, i32)) -> f32 {
        if self.charts[from] != self.charts[to] || self.charts[to] == NO_CHART {
            return 0.0;
        }
        let normal = self.normals[to];
        let along_normal = normal.dot(self.positions[from] - self.positions[to]);
        spatial_weight(dx, dy)
            * plane_weight(along_normal, self.texel_length)
            * normal_weight(normal.dot(self.normals[from]))
            * range_weight(
                self.levels[from] - self.levels[to],
                self.noise[to],
                self.noise[from],
            )
    }
}

/// A texel's level and its noise from its baked DC coefficients `dc` (one per channel), its
/// albedo and the samples it cast: the level is `dc / (albedo Y_0)` averaged over channels,
/// clamped to [0, 1] (an open hemisphere's DC is `albedo Y_0`), and its noise that of the
/// fraction of N cosine-distributed rays that escape, `sqrt(p (1 - p) / N)`, kept at least
/// `1 / N`.
pub fn texel_level(dc: Vec3, albedo: Vec3, samples: u32) -> (f32, f32) {
    let open = albedo.element_sum() * crate::sh::Y00 as f32;
    let level = if open > 0.0 {
        (dc.element_sum() / open).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let n = samples.max(1) as f32;
    let noise = (level * (1.0 - level) / n).sqrt().max(1.0 / n);
    (level, noise)
}

/// `(1 - r^2)^2` of `r = difference / (RANGE_SIGMAS sqrt(noise_a^2 + noise_b^2))`: alike
/// levels mix, levels further apart than the noise explains do not.
pub fn range_weight(difference: f32, noise_a: f32, noise_b: f32) -> f32 {
    let scale = RANGE_SIGMAS * RANGE_SIGMAS * (noise_a * noise_a + noise_b * noise_b);
    let falloff = (1.0 - difference * difference / scale).max(0.0);
    falloff * falloff
}

/// `(1 - r^2 / (R + 1)^2)^2` of the atlas distance r in texels: 1 at the texel, falling
/// smoothly to 0 before the square's corners.
pub fn spatial_weight(dx: i32, dy: i32) -> f32 {
    let reach = (DENOISE_RADIUS + 1) as f32;
    let falloff = 1.0 - (dx * dx + dy * dy) as f32 / (reach * reach);
    let falloff = falloff.max(0.0);
    falloff * falloff
}

/// `(1 - (h / l)^2)^2` of a neighbour's height h above the tangent plane, l one texel's
/// length: texels across a crease or a step within the chart do not mix.
pub fn plane_weight(height: f32, texel_length: f32) -> f32 {
    let relative = height / texel_length;
    let falloff = (1.0 - relative * relative).max(0.0);
    falloff * falloff
}

/// `max(0, cos)^8` of the angle between two normals.
pub fn normal_weight(cosine: f32) -> f32 {
    let mut weight = cosine.max(0.0);
    for _ in 0..NORMAL_POWER_SQUARINGS {
        weight *= weight;
    }
    weight
}

/// `image` (`stride` floats a texel, row-major) filtered under `guide`: each texel whose chart
/// is not [`NO_CHART`] the weighted mean of its footprint, the others as they were. Sums run
/// in f32, over the footprint row by row, as the GPU's do.
pub fn denoise(guide: &DenoiseGuide, image: &[f32], stride: usize) -> Vec<f32> {
    let width = guide.width as usize;
    let mut out = image.to_vec();
    out.par_chunks_mut(stride * width)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, texel) in row.chunks_exact_mut(stride).enumerate() {
                denoise_texel(guide, image, stride, (x, y), texel);
            }
        });
    out
}

/// The filtered value of texel `(x, y)` into `out` (left as it is where it is not filtered).
fn denoise_texel(
    guide: &DenoiseGuide,
    image: &[f32],
    stride: usize,
    (x, y): (usize, usize),
    out: &mut [f32],
) {
    let to = y * guide.width as usize + x;
    if guide.charts[to] == NO_CHART {
        return;
    }
    let radius = DENOISE_RADIUS as i32;
    let mut total = 0.0f32;
    out.fill(0.0);
    for dy in -radius..=radius {
        for dx in -radius..=radius {
            let (fx, fy) = (x as i32 + dx, y as i32 + dy);
            if fx < 0 || fy < 0 || fx >= guide.width as i32 || fy >= guide.height as i32 {
                continue;
            }
            let from = fy as usize * guide.width as usize + fx as usize;
            let weight = guide.weight(to, from, (dx, dy));
            if weight > 0.0 {
                total += weight;
                for (o, &v) in out
                    .iter_mut()
                    .zip(&image[from * stride..(from + 1) * stride])
                {
                    *o += weight * v;
                }
            }
        }
    }
    // The texel's own weight is 1, so the total is at least 1.
    out.iter_mut().for_each(|o| *o /= total);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat `size x size` map in the z = 0 plane, one texel a unit, every texel chart 0.
    fn flat(size: u32) -> DenoiseGuide {
        let positions = (0..size * size)
            .map(|i| Vec3::new((i % size) as f32, (i / size) as f32, 0.0))
            .collect();
        let texels = (size * size) as usize;
        DenoiseGuide::new(
            (size, size),
            (positions, vec![Vec3::Z; texels]),
            vec![0; texels],
            (vec![0.5; texels], vec![1.0; texels]),
        )
    }

    #[test]
    fn weights_fall_with_distance_height_and_turn_and_stop_at_the_footprint() {
        assert_eq!(spatial_weight(0, 0), 1.0);
        assert!(spatial_weight(1, 0) > spatial_weight(2, 0));
        let reach = DENOISE_RADIUS as i32;
        assert!(spatial_weight(reach, 0) > 0.0 && spatial_weight(reach, reach) > 0.0);
        assert_eq!(spatial_weight(reach + 1, 0), 0.0);
        assert_eq!(range_weight(0.0, 0.1, 0.1), 1.0);
        assert!(range_weight(0.1, 0.1, 0.1) > range_weight(0.2, 0.1, 0.1));
        assert!(range_weight(0.2, 0.1, 0.1) > 0.0);
        assert_eq!(
            range_weight(RANGE_SIGMAS * 0.1 * 2f32.sqrt(), 0.1, 0.1),
            0.0
        );
        // Levels: an open texel is 1, a black one 0, the noise never below 1/N.
        let (open, noise) = texel_level(
            Vec3::splat(0.5 * crate::sh::Y00 as f32),
            Vec3::splat(0.5),
            64,
        );
        assert!((open - 1.0).abs() < 1e-6 && noise == 1.0 / 64.0);
        let (half, noise) = texel_level(
            Vec3::splat(0.25 * crate::sh::Y00 as f32),
            Vec3::splat(0.5),
            64,
        );
        assert!((half - 0.5).abs() < 1e-6 && (noise - 0.0625).abs() < 1e-6);
        assert_eq!(plane_weight(0.0, 2.0), 1.0);
        assert!(plane_weight(1.0, 2.0) > plane_weight(1.5, 2.0));
        assert_eq!(plane_weight(2.0, 2.0), 0.0);
        assert_eq!(normal_weight(1.0), 1.0);
        assert!((normal_weight(0.5) - 0.5f32.powi(8)).abs() < 1e-9);
        assert_eq!(normal_weight(-0.5), 0.0);
        let guide = flat(8);
        assert_eq!(guide.texel_length, 1.0);
    }

    #[test]
    fn a_constant_map_stays_constant_and_a_ramp_stays_a_ramp_inside() {
        let guide = flat(16);
        let stride = 2;
        let image: Vec<f32> = (0..16 * 16).flat_map(|i| [0.5, (i % 16) as f32]).collect();
        let out = denoise(&guide, &image, stride);
        for (i, texel) in out.chunks(stride).enumerate() {
            assert!((texel[0] - 0.5).abs() < 1e-6, "texel {i}: {texel:?}");
            // Symmetric weights keep a linear ramp away from the map's edges.
            let x = i % 16;
            if (3..13).contains(&x) {
                assert!((texel[1] - x as f32).abs() < 1e-4, "texel {i}: {texel:?}");
            }
        }
    }

    #[test]
    fn noise_shrinks_and_charts_and_invalid_texels_do_not_mix() {
        let size = 32;
        let mut guide = flat(size);
        // Chart 1 on the right half, and a column of invalid texels in the left half.
        for i in 0..(size * size) as usize {
            if i % size as usize >= 16 {
                guide.charts[i] = 1;
            }
            if i % size as usize == 8 {
                guide.charts[i] = NO_CHART;
            }
        }
        let mut rng = crate::sampling::Pcg32::new(5);
        let image: Vec<f32> = guide
            .charts
            .iter()
            .map(|&c| match c {
                0 => 1.0 + (rng.next_f32() - 0.5),
                1 => 10.0 + (rng.next_f32() - 0.5),
                _ => 1000.0,
            })
            .collect();
        let out = denoise(&guide, &image, 1);
        let spread = |values: &[f32], chart: u32| {
            let chosen: Vec<f32> = values
                .iter()
                .zip(&guide.charts)
                .filter(|&(_, &c)| c == chart)
                .map(|(&v, _)| v)
                .collect();
            let mean = chosen.iter().sum::<f32>() / chosen.len() as f32;
            let variance =
                chosen.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / chosen.len() as f32;
            (mean, variance.sqrt())
        };
        for chart in [0, 1] {
            let (mean_in, noise_in) = spread(&image, chart);
            let (mean_out, noise_out) = spread(&out, chart);
            assert!((mean_in - mean_out).abs() < 0.05, "chart {chart}");
            assert!(
                noise_out < 0.4 * noise_in,
                "chart {chart}: {noise_in} -> {noise_out}"
            );
        }
        for ((&c, &before), &after) in guide.charts.iter().zip(&image).zip(&out) {
            match c {
                0 => assert!((0.5..1.5).contains(&after)),
                1 => assert!((9.5..10.5).contains(&after)),
                _ => assert_eq!(after, before),
            }
        }
    }

    #[test]
    fn nothing_crosses_a_step_farther_than_the_footprint() {
        // A step at x = 16 that the noise hides (levels within it, so the range weight mixes
        // the sides): no texel more than DENOISE_RADIUS from the step reads across it, and
        // the texels nearer do.
        let size = 32;
        let mut guide = flat(size);
        let mut rng = crate::sampling::Pcg32::new(9);
        let left_of_step = |i: usize| i % (size as usize) < 16;
        for (i, (level, noise)) in guide.levels.iter_mut().zip(&mut guide.noise).enumerate() {
            *level = if left_of_step(i) { 0.5 } else { 0.55 } + 0.1 * (rng.next_f32() - 0.5);
            *noise = 0.1;
        }
        let image: Vec<f32> = guide.levels.clone();
        let brighter: Vec<f32> = image
            .iter()
            .enumerate()
            .map(|(i, &v)| if left_of_step(i) { v } else { v + 100.0 })
            .collect();
        let (out, out_brighter) = (denoise(&guide, &image, 1), denoise(&guide, &brighter, 1));
        let reach = DENOISE_RADIUS as usize;
        for (i, (a, b)) in out.iter().zip(&out_brighter).enumerate() {
            let x = i % size as usize;
            if x + reach < 16 {
                assert_eq!(a, b, "texel {i} read across the step");
            }
            if x < 16 && x + reach >= 16 && x + 1 < 16 + reach {
                assert_ne!(a, b, "texel {i} is within the footprint of the step");
            }
        }
    }

    #[test]
    fn texels_across_a_crease_do_not_mix() {
        // A map folded at x = 8 into a right angle: the left part lies in z = 0 facing +z,
        // the right part climbs the wall x = 8 facing -x; both one chart.
        let size = 16u32;
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        for i in 0..size * size {
            let (x, y) = ((i % size) as f32, (i / size) as f32);
            if x < 8.0 {
                positions.push(Vec3::new(x, y, 0.0));
                normals.push(Vec3::Z);
            } else {
                positions.push(Vec3::new(8.0, y, x - 7.0));
                normals.push(Vec3::NEG_X);
            }
        }
        let levels = (vec![0.5; 256], vec![1.0; 256]);
        let guide = DenoiseGuide::new((size, size), (positions, normals), vec![0; 256], levels);
        let image: Vec<f32> = (0..256)
            .map(|i| if i % 16 < 8 { 1.0 } else { 5.0 })
            .collect();
        let out = denoise(&guide, &image, 1);
        for (a, b) in out.iter().zip(&image) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }
}
