//! Base-colour textures turned into one albedo per vertex: decoding (sRGB PNG or JPEG to
//! linear), bilinear sampling with the glTF wrap modes, `KHR_texture_transform`, and the filter
//! that averages a texture over the surface around each vertex.
//!
//! Conventions (glTF 2.0, "Images"): UV (0, 0) is the top-left corner of the image, u runs
//! right and v runs down. Texel (x, y) covers [x, x + 1]/width × [y, y + 1]/height and its
//! centre is at ((x + ½)/width, (y + ½)/height), as in OpenGL and every GPU sampler.
//!
//! Why a filter: the baker stores one albedo per vertex and interpolates it linearly across
//! each triangle. A point sample of the texture at the vertex's UV aliases as soon as a triangle
//! spans more than a texel (a fine checkerboard comes out black or white by chance), so each
//! vertex takes the texture averaged over its triangles, weighted by the vertex's hat function.

use glam::Vec3;
use rayon::prelude::*;

use crate::color::srgb_to_linear;
use crate::error::{Error, Result};

/// What a sampler does with a texel index outside the image (the glTF sampler's `wrapS` and
/// `wrapT`; the index rules of OpenGL 4.6 §8.14.2, table 8.20).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// The image tiles the plane (glTF's default).
    #[default]
    Repeat,
    /// The edge texels extend to infinity.
    ClampToEdge,
    /// The image tiles the plane, every other copy mirrored.
    MirroredRepeat,
}

impl Wrap {
    /// The mode a glTF sampler names by its OpenGL enum (10497, 33071, 33648); `None` for any
    /// other number, which the loader reports.
    pub fn from_gl(code: u32) -> Option<Wrap> {
        match code {
            10497 => Some(Wrap::Repeat),
            33071 => Some(Wrap::ClampToEdge),
            33648 => Some(Wrap::MirroredRepeat),
            _ => None,
        }
    }

    /// Any integer texel index wrapped into `0..size` (`size` ≥ 1).
    fn texel_index(self, index: i64, size: u32) -> usize {
        let size = i64::from(size);
        // Inside the image every mode is the identity; skip the divisions.
        if (0..size).contains(&index) {
            return index as usize;
        }
        let wrapped = match self {
            Wrap::Repeat => index.rem_euclid(size),
            Wrap::ClampToEdge => index.clamp(0, size - 1),
            // Period 2·size: the first copy as is, the second reversed.
            Wrap::MirroredRepeat => {
                let m = index.rem_euclid(2 * size);
                if m < size {
                    m
                } else {
                    2 * size - 1 - m
                }
            }
        };
        wrapped as usize
    }
}

/// An image of linear RGB and alpha, sampled bilinearly with its wrap modes.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    /// Row by row from the top row, `width × height` of them: linear RGB, linear alpha.
    texels: Vec<[f32; 4]>,
    wrap_s: Wrap,
    wrap_t: Wrap,
}

impl Texture {
    /// A texture from linear texels, row by row from the top; both wraps `Repeat`.
    /// `what` names the image in errors (a glTF image index or URI).
    pub fn new(width: u32, height: u32, texels: Vec<[f32; 4]>, what: &str) -> Result<Texture> {
        if width == 0 || height == 0 {
            return Err(Error::mesh(
                what,
                format!("the image has no texels ({width}×{height})"),
            ));
        }
        let expected = width as usize * height as usize;
        if texels.len() != expected {
            return Err(Error::mesh(
                what,
                format!(
                    "{width}×{height} image with {} texels instead of {expected}",
                    texels.len()
                ),
            ));
        }
        Ok(Texture {
            width,
            height,
            texels,
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
        })
    }

    /// Decodes a PNG (8 or 16 bits a channel) or JPEG base-colour image. RGB is sRGB-encoded
    /// (glTF 2.0, "Metallic-Roughness Material") and is decoded to linear; alpha is linear
    /// already and is kept. Grey images become grey RGB, images without alpha get alpha 1.
    pub fn decode(bytes: &[u8], what: &str) -> Result<Texture> {
        if bytes.is_empty() {
            return Err(Error::mesh(what, "the image is empty"));
        }
        let (format, name) = match image::guess_format(bytes) {
            Ok(image::ImageFormat::Png) => (image::ImageFormat::Png, "PNG"),
            Ok(image::ImageFormat::Jpeg) => (image::ImageFormat::Jpeg, "JPEG"),
            _ => return Err(Error::mesh(what, "not a PNG or JPEG image")),
        };
        let decoded = crate::images::decode(bytes, format)
            .map_err(|e| Error::mesh(what, format!("{name}: {e}")))?;
        let (width, height) = (decoded.width(), decoded.height());
        Texture::new(width, height, linear_texels(decoded), what)
    }

    /// The same texture with the given wrap modes for u (`wrap_s`) and v (`wrap_t`).
    pub fn with_wrap(self, wrap_s: Wrap, wrap_t: Wrap) -> Texture {
        Texture {
            wrap_s,
            wrap_t,
            ..self
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// The wrap modes for u and v.
    pub fn wrap(&self) -> (Wrap, Wrap) {
        (self.wrap_s, self.wrap_t)
    }

    /// The texture at `uv`, interpolated bilinearly between the four nearest texel centres,
    /// indices outside the image wrapped by the texture's modes.
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 4] {
        self.sample_at([f64::from(uv[0]), f64::from(uv[1])])
    }

    /// [`Texture::sample`] at a double-precision UV: the filter's UVs can be far outside [0, 1]
    /// (tiled textures), where an f32 texel coordinate would lose its fraction.
    fn sample_at(&self, uv: [f64; 2]) -> [f32; 4] {
        // Texel centres sit at half-integers: after the half-texel shift, the integer part
        // names the centre left of (above) the point and the fraction is the weight of the next.
        let x = uv[0] * f64::from(self.width) - 0.5;
        let y = uv[1] * f64::from(self.height) - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        // `as i64` saturates (NaN gives 0), so no UV, however wild, can panic here.
        let (x0, y0) = (x0 as i64, y0 as i64);
        let xs = [x0, x0.saturating_add(1)].map(|i| self.wrap_s.texel_index(i, self.width));
        let ys = [y0, y0.saturating_add(1)].map(|i| self.wrap_t.texel_index(i, self.height));
        let lerp =
            |a: [f32; 4], b: [f32; 4], t: f32| std::array::from_fn(|c| a[c] + t * (b[c] - a[c]));
        let top = lerp(self.texel(xs[0], ys[0]), self.texel(xs[1], ys[0]), fx);
        let bottom = lerp(self.texel(xs[0], ys[1]), self.texel(xs[1], ys[1]), fx);
        lerp(top, bottom, fy)
    }

    fn texel(&self, x: usize, y: usize) -> [f32; 4] {
        self.texels[y * self.width as usize + x]
    }

    /// The next level of a mip pyramid: ⌈width/2⌉ × ⌈height/2⌉ texels, each the exact area
    /// average of the texels it covers (fractional coverage at the borders of odd sizes), so
    /// every level has the base's mean and its texels stay registered to the same UV square.
    fn downsampled(&self) -> Texture {
        let (width, height) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let (columns, rows) = (box_taps(self.width, width), box_taps(self.height, height));
        // Separable: horizontally into `narrow` (width × self.height), then vertically.
        let narrow: Vec<[f32; 4]> = (0..self.height as usize)
            .flat_map(|y| {
                columns
                    .iter()
                    .map(move |taps| weighted_sum(taps, |x| self.texel(x, y)))
            })
            .collect();
        let texels = rows
            .iter()
            .flat_map(|taps| {
                let narrow = &narrow;
                (0..width as usize)
                    .map(move |x| weighted_sum(taps, |y| narrow[y * width as usize + x]))
            })
            .collect();
        Texture {
            width,
            height,
            texels,
            ..*self
        }
    }
}

/// Decoded pixels to linear texels: RGB through the sRGB curve, alpha scaled to [0, 1].
fn linear_texels(image: image::DynamicImage) -> Vec<[f32; 4]> {
    use image::ColorType::{La16, Rgb16, Rgba16, L16};
    // One table entry per code value: a 16-bit image has more texels than codes.
    if matches!(image.color(), L16 | La16 | Rgb16 | Rgba16) {
        let table = srgb_table(u16::MAX as usize);
        let to_texel = |p: &image::Rgba<u16>| {
            let [r, g, b, a] = p.0.map(usize::from);
            [table[r], table[g], table[b], a as f32 / f32::from(u16::MAX)]
        };
        image.into_rgba16().pixels().map(to_texel).collect()
    } else {
        let table = srgb_table(u8::MAX as usize);
        let to_texel = |p: &image::Rgba<u8>| {
            let [r, g, b, a] = p.0.map(usize::from);
            [table[r], table[g], table[b], a as f32 / f32::from(u8::MAX)]
        };
        image.into_rgba8().pixels().map(to_texel).collect()
    }
}

/// Linear values of the sRGB codes 0..=max, computed in f64 and rounded once.
fn srgb_table(max: usize) -> Vec<f32> {
    (0..=max)
        .map(|code| srgb_to_linear(code as f64 / max as f64) as f32)
        .collect()
}

/// For each of `dst` equal cells over `src` texels, the texels it overlaps and the fraction of
/// the cell each covers (the fractions of a cell sum to 1).
fn box_taps(src: u32, dst: u32) -> Vec<Vec<(usize, f64)>> {
    let ratio = f64::from(src) / f64::from(dst);
    (0..dst)
        .map(|cell| {
            let (start, end) = (f64::from(cell) * ratio, f64::from(cell + 1) * ratio);
            let first = start.floor() as usize;
            let last = (end.ceil() as usize).min(src as usize);
            (first..last)
                .map(|i| {
                    let overlap = end.min(i as f64 + 1.0) - start.max(i as f64);
                    (i, overlap / ratio)
                })
                .filter(|&(_, weight)| weight > 0.0)
                .collect()
        })
        .collect()
}

fn weighted_sum(taps: &[(usize, f64)], texel: impl Fn(usize) -> [f32; 4]) -> [f32; 4] {
    let mut sum = [0.0f64; 4];
    for &(i, weight) in taps {
        let value = texel(i);
        for c in 0..4 {
            sum[c] += weight * f64::from(value[c]);
        }
    }
    sum.map(|s| s as f32)
}

/// The `KHR_texture_transform` extension: UVs are scaled, then rotated, then offset.
///
/// In matrix form `uv' = T · R · S · (u, v, 1)` with `T` the translation by `offset`, `S` the
/// scale and `R` = `[[cos, sin, 0], [-sin, cos, 0], [0, 0, 1]]` read row by row:
/// u' = cos·u + sin·v, v' = −sin·u + cos·v. That is the rotation the extension's prose and
/// example mean ("counter-clockwise" in UV space, whose v axis points down; the example maps
/// the unit square onto the image's lower-left quadrant), and what Babylon.js, three.js and
/// Blender implement. The README's GLSL listing, read column-major as GLSL does, is the
/// transpose; KhronosGroup/glTF issue #1563 records that the listing is the odd one out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub offset: [f32; 2],
    /// Radians.
    pub rotation: f32,
    pub scale: [f32; 2],
}

impl Default for UvTransform {
    /// The identity: the extension's defaults (offset 0, rotation 0, scale 1).
    fn default() -> Self {
        UvTransform {
            offset: [0.0, 0.0],
            rotation: 0.0,
            scale: [1.0, 1.0],
        }
    }
}

impl UvTransform {
    /// The transformed UV.
    pub fn apply(&self, uv: [f32; 2]) -> [f32; 2] {
        self.apply_f64(uv).map(|c| c as f32)
    }

    /// [`UvTransform::apply`] in double precision, for the filter (see [`Texture::sample_at`]).
    fn apply_f64(&self, uv: [f32; 2]) -> [f64; 2] {
        let (sin, cos) = f64::from(self.rotation).sin_cos();
        let u = f64::from(uv[0]) * f64::from(self.scale[0]);
        let v = f64::from(uv[1]) * f64::from(self.scale[1]);
        [
            cos * u + sin * v + f64::from(self.offset[0]),
            -sin * u + cos * v + f64::from(self.offset[1]),
        ]
    }
}

/// Sub-triangle edges per texel of a triangle's longest UV edge: sub-triangles at most half a
/// texel across, so samples are at most half a texel apart in every direction and none of the
/// texels the triangle covers is skipped, slivers included. Per texel of area that is at least
/// 4 / (√3/4) ≈ 9.2 samples (a triangle's area is at most √3/4 of its longest edge squared).
/// The longest edge, not the area, sets the count: a sliver 100 texels long has almost no area.
const SUBDIVISIONS_PER_TEXEL: f64 = 2.0;

/// The fewest subdivisions of an edge: 16 samples, enough for the hat weights of a triangle
/// smaller than a texel (the texture is nearly linear across it).
const MIN_SUBDIVISIONS: u32 = 4;

/// The most subdivisions of an edge: 256² = 65,536 samples a triangle, about a millisecond of
/// bilinear lookups on one core. That covers triangles whose longest edge spans up to 128
/// texels at full resolution; larger ones (a two-triangle floor under a tiled texture can span
/// 10⁴ texels and would need 4·10⁸ samples) are sampled on the finest mip level where they span
/// at most 128. Its texels are exact area averages, so past the cap the average is blurred
/// (isotropically, like a GPU mip level), never aliased; below the cap no level is built.
const MAX_SUBDIVISIONS: u32 = 256;

/// Triangles integrated in parallel before their sums are added in order: bounds the memory
/// of the per-triangle results, which are kept so the additions happen in triangle order.
const TRIANGLES_PER_BLOCK: usize = 4096;

/// One albedo per vertex (linear RGB and alpha): the texture averaged over the surface around
/// the vertex.
///
/// Each vertex takes the texture averaged over the triangles around it, weighted by the
/// vertex's hat function (its barycentric coordinate, 1 at the vertex and 0 at the far edge) and
/// by world-space area: `albedo_v = Σ ∫ λ_v · tex(uv) dA / Σ ∫ λ_v dA`, the least-squares
/// projection's lumped form of the texture onto the mesh's linear interpolation. Each triangle is
/// integrated at the centroids of a regular subdivision with sub-triangles at most half a texel
/// across (16 to 65,536 samples; beyond that on a mip level), so the average neither aliases
/// nor depends on chance.
///
/// UVs go through `transform` first. A vertex in no triangle, or only in zero-area triangles,
/// takes a point sample at its own UV. Triangles naming a vertex outside `positions` or `uvs`
/// are skipped (the loader reports them); a vertex without a UV is sampled at UV (0, 0).
/// Deterministic: the triangles are integrated in parallel, their sums added in triangle order.
pub fn vertex_averages(
    positions: &[Vec3],
    uvs: &[[f32; 2]],
    triangles: &[[u32; 3]],
    texture: &Texture,
    transform: &UvTransform,
) -> Vec<[f32; 4]> {
    let uv = |i: usize| transform.apply_f64(uvs.get(i).copied().unwrap_or_default());
    let usable = |t: &[u32; 3]| {
        let corners = t.map(|i| i as usize);
        corners
            .iter()
            .all(|&i| i < positions.len() && i < uvs.len())
            .then_some(corners)
    };

    // 1. The pyramid, as deep as the largest triangle needs (most meshes: the base alone).
    let dims = level_dims(texture.width, texture.height);
    let deepest = triangles
        .par_iter()
        .filter_map(usable)
        .map(|c| sampling_plan(&c.map(uv), &dims).0)
        .max()
        .unwrap_or(0);
    let pyramid = Pyramid::new(texture, deepest);

    // 2. Integrals of λ_v · tex and λ_v per triangle, added per vertex in triangle order.
    let mut moments = vec![[0.0f64; 4]; positions.len()];
    let mut weights = vec![0.0f64; positions.len()];
    for block in triangles.chunks(TRIANGLES_PER_BLOCK) {
        let integrals: Vec<_> = block
            .par_iter()
            .map(|t| {
                let corners = usable(t)?;
                integrate_triangle(
                    corners.map(|i| positions[i]),
                    corners.map(uv),
                    &pyramid,
                    &dims,
                )
                .map(|integral| (corners, integral))
            })
            .collect();
        for (corners, integral) in integrals.into_iter().flatten() {
            for (k, &v) in corners.iter().enumerate() {
                weights[v] += integral.weights[k];
                for (sum, add) in moments[v].iter_mut().zip(integral.moments[k]) {
                    *sum += add;
                }
            }
        }
    }

    // 3. The ratio, or the point sample where there is no surface to average over.
    (0..positions.len())
        .map(|v| {
            if weights[v] > 0.0 {
                moments[v].map(|m| (m / weights[v]) as f32)
            } else {
                texture.sample_at(uv(v))
            }
        })
        .collect()
}

/// ∫ λ_k · tex dA and ∫ λ_k dA over one triangle, for its corners k = 0, 1, 2.
#[derive(Clone, Copy, Debug)]
struct TriangleIntegral {
    moments: [[f64; 4]; 3],
    weights: [f64; 3],
}

/// The texture and its coarser levels, the base borrowed.
struct Pyramid<'a> {
    base: &'a Texture,
    coarser: Vec<Texture>,
}

impl<'a> Pyramid<'a> {
    /// The base and `levels` coarser levels.
    fn new(base: &'a Texture, levels: usize) -> Pyramid<'a> {
        let mut coarser: Vec<Texture> = Vec::with_capacity(levels);
        for _ in 0..levels {
            let next = coarser.last().unwrap_or(base).downsampled();
            coarser.push(next);
        }
        Pyramid { base, coarser }
    }

    fn level(&self, level: usize) -> &Texture {
        match level {
            0 => self.base,
            _ => &self.coarser[level - 1],
        }
    }
}

/// Width and height of every pyramid level, the base first and 1 × 1 last.
fn level_dims(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut dims = vec![(width, height)];
    while let Some(&(w, h)) = dims.last().filter(|&&d| d != (1, 1)) {
        dims.push((w.div_ceil(2), h.div_ceil(2)));
    }
    dims
}

/// The pyramid level a triangle is sampled on and the subdivisions of its edges: the base
/// level unless the triangle's longest UV edge needs more than [`MAX_SUBDIVISIONS`] there, else
/// the finest level where it does not (the coarsest level if none).
fn sampling_plan(uv: &[[f64; 2]; 3], dims: &[(u32, u32)]) -> (usize, u32) {
    for (level, &(width, height)) in dims.iter().enumerate() {
        let (width, height) = (f64::from(width), f64::from(height));
        let longest = (0..3)
            .map(|k| {
                let (a, b) = (uv[k], uv[(k + 1) % 3]);
                ((b[0] - a[0]) * width).hypot((b[1] - a[1]) * height)
            })
            .fold(0.0, f64::max);
        // `max` before the comparison: a NaN UV gets the minimum, not an endless plan.
        let wanted = (SUBDIVISIONS_PER_TEXEL * longest)
            .ceil()
            .max(f64::from(MIN_SUBDIVISIONS));
        if wanted <= f64::from(MAX_SUBDIVISIONS) || level + 1 == dims.len() {
            return (level, wanted.min(f64::from(MAX_SUBDIVISIONS)) as u32);
        }
    }
    (0, MIN_SUBDIVISIONS)
}

/// Integrates one triangle at the centroids of its regular subdivision; `None` when it has no
/// area (or its positions are not finite), so that it carries no weight.
fn integrate_triangle(
    positions: [Vec3; 3],
    uv: [[f64; 2]; 3],
    pyramid: &Pyramid,
    dims: &[(u32, u32)],
) -> Option<TriangleIntegral> {
    let [p0, p1, p2] = positions.map(|p| p.as_dvec3());
    let area = 0.5 * (p1 - p0).cross(p2 - p0).length();
    if !(area > 0.0 && area.is_finite()) {
        return None;
    }
    let (level, subdivisions) = sampling_plan(&uv, dims);
    let texture = pyramid.level(level);
    let mut integral = TriangleIntegral {
        moments: [[0.0; 4]; 3],
        weights: [0.0; 3],
    };
    for [b1, b2] in subtriangle_centroids(subdivisions) {
        let lambda = [1.0 - b1 - b2, b1, b2];
        let at = |c: usize| lambda[0] * uv[0][c] + lambda[1] * uv[1][c] + lambda[2] * uv[2][c];
        let value = texture.sample_at([at(0), at(1)]);
        let corners = integral.weights.iter_mut().zip(&mut integral.moments);
        for ((weight, moment), l) in corners.zip(lambda) {
            *weight += l;
            for (m, x) in moment.iter_mut().zip(value) {
                *m += l * f64::from(x);
            }
        }
    }
    // Every sub-triangle has the same area: the affine map to world space keeps area ratios.
    let sample_area = area / f64::from(subdivisions * subdivisions);
    integral.weights = integral.weights.map(|w| w * sample_area);
    integral.moments = integral.moments.map(|m| m.map(|x| x * sample_area));
    Some(integral)
}

/// Barycentric coordinates (λ1, λ2) of the centroids of the n² congruent sub-triangles that
/// cut each edge into n: the n(n+1)/2 upright ones and the n(n−1)/2 inverted ones. The centroid
/// rule is exact for the linear hat functions and converges like a midpoint rule for the rest.
fn subtriangle_centroids(n: u32) -> impl Iterator<Item = [f64; 2]> {
    let third = 1.0 / (3.0 * f64::from(n));
    (0..n).flat_map(move |i| {
        (0..n - i).flat_map(move |j| {
            // The last cell of a row has no inverted sub-triangle: it would lie outside.
            let has_inverted = j + 1 < n - i;
            let (i, j) = (f64::from(i), f64::from(j));
            let upright = [(3.0 * i + 1.0) * third, (3.0 * j + 1.0) * third];
            let inverted = [(3.0 * i + 2.0) * third, (3.0 * j + 2.0) * third];
            std::iter::once(upright).chain(has_inverted.then_some(inverted))
        })
    })
}

#[cfg(test)]
mod tests;
