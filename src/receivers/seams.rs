//! Seams: edges of the surface that lie in the atlas twice, once on each of two charts (or at
//! two places of one chart, where a UV set is cut). Bilinear lookups on the two sides read
//! different texels, baked at different points, and disagree: the light steps along the seam.
//!
//! [`stitch`] moves the texels those lookups read, least squares, so that the two sides agree
//! at points along every seam edge while each texel stays near its bake: minimise
//! `sum_texels |x - baked|^2 + SEAM_WEIGHT * sum_points |lookup_a(x) - lookup_b(x)|^2`, the same
//! weights for every coefficient (lightmappers' seam stitching). The normal equations are
//! symmetric positive definite and solved by conjugate gradients, every coefficient at once.

use std::collections::HashMap;

use glam::DVec2;

use super::atlas::Atlas;
use super::texels::bilinear_taps;
use crate::scene::Scene;

/// How much agreement across a seam weighs against a texel keeping its baked value.
pub const SEAM_WEIGHT: f64 = 10.0;

/// Lookups per texel of a seam edge's length (on its longer side), so that every texel along
/// the seam is constrained.
const POINTS_PER_TEXEL: f64 = 2.0;

/// Conjugate-gradient steps at most.
const MAX_STEPS: usize = 200;

/// One seam edge: its two ends in the atlas on one side (`a`) and the other (`b`), in texel
/// units, the ends paired by the surface point they stand for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seam {
    pub a: [DVec2; 2],
    pub b: [DVec2; 2],
}

impl Seam {
    /// The points of the seam looked up on each side: `(a, b)` pairs at the same surface points.
    pub fn points(&self) -> Vec<(DVec2, DVec2)> {
        let length = self.a[0]
            .distance(self.a[1])
            .max(self.b[0].distance(self.b[1]));
        let count = (length * POINTS_PER_TEXEL).ceil().max(1.0) as usize + 1;
        (0..count)
            .map(|k| {
                let t = k as f64 / (count - 1) as f64;
                (self.a[0].lerp(self.a[1], t), self.b[0].lerp(self.b[1], t))
            })
            .collect()
    }
}

/// The seams of `scene` in `atlas`: edges shared by exactly two triangles, through the same two
/// vertices, whose corners at the edge lie at different places in the atlas. An edge whose
/// sides hold different copies of a vertex (a crease: split normals; an albedo border) is no
/// seam: the light may step there.
pub fn seams(scene: &Scene, atlas: &Atlas) -> Vec<Seam> {
    // Per edge (its vertices, lower first), each triangle's corners at its two ends.
    let mut by_edge: HashMap<(u32, u32), Vec<(DVec2, DVec2)>> = HashMap::new();
    for (t, corners) in scene.triangles.iter().enumerate() {
        let flat = atlas.corners[t].map(|c| c.as_dvec2());
        for i in 0..3 {
            let j = (i + 1) % 3;
            let (u, v) = (corners[i], corners[j]);
            if u == v {
                continue;
            }
            let ends = if u < v {
                (flat[i], flat[j])
            } else {
                (flat[j], flat[i])
            };
            by_edge.entry((u.min(v), u.max(v))).or_default().push(ends);
        }
    }
    // Apart by more than rounding: a thousandth of a texel.
    const APART: f64 = 1e-3;
    let mut seams: Vec<((u32, u32), Seam)> = by_edge
        .into_iter()
        .filter_map(|(edge, sides)| match sides.as_slice() {
            &[a, b] if a.0.distance(b.0) > APART || a.1.distance(b.1) > APART => Some((
                edge,
                Seam {
                    a: [a.0, a.1],
                    b: [b.0, b.1],
                },
            )),
            _ => None,
        })
        .collect();
    // The map's order must not reach the stitching.
    seams.sort_unstable_by_key(|&(edge, _)| edge);
    seams.into_iter().map(|(_, seam)| seam).collect()
}

/// One lookup pair's difference as taps: `+w` on side a's texels, `-w` on side b's.
type Row = [(usize, f64); 8];

fn rows(seams: &[Seam], width: u32, height: u32) -> Vec<Row> {
    let mut rows = Vec::new();
    for seam in seams {
        for (a, b) in seam.points() {
            let (ta, tb) = (
                bilinear_taps(width, height, a.as_vec2()),
                bilinear_taps(width, height, b.as_vec2()),
            );
            let mut row = [(0, 0.0); 8];
            for k in 0..4 {
                row[k] = (ta[k].0, ta[k].1 as f64);
                row[k + 4] = (tb[k].0, -tb[k].1 as f64);
            }
            rows.push(row);
        }
    }
    rows
}

/// Stitches the seams of a `width` x `height` image of `stride` values a texel (row-major),
/// in place (see the module's notes). Texels no seam lookup reads keep their values.
pub fn stitch(width: u32, height: u32, image: &mut [f32], stride: usize, seams: &[Seam]) {
    let rows = rows(seams, width, height);
    if rows.is_empty() || stride == 0 {
        return;
    }
    // The texels the lookups read, numbered densely in first-use order.
    let mut index: HashMap<usize, usize> = HashMap::new();
    let mut texels = Vec::new();
    let rows: Vec<[(usize, f64); 8]> = rows
        .iter()
        .map(|row| {
            row.map(|(texel, w)| {
                let i = *index.entry(texel).or_insert_with(|| {
                    texels.push(texel);
                    texels.len() - 1
                });
                (i, w)
            })
        })
        .collect();
    let n = texels.len();
    let baked: Vec<f64> = texels
        .iter()
        .flat_map(|&t| {
            image[t * stride..(t + 1) * stride]
                .iter()
                .map(|&v| v as f64)
        })
        .collect();
    // (I + w C^T C) x, columns side by side: x[i * stride + c].
    let apply = |x: &[f64], out: &mut [f64]| {
        out.copy_from_slice(x);
        let mut difference = vec![0.0; stride];
        for row in &rows {
            difference.fill(0.0);
            for &(i, w) in row {
                for (d, v) in difference.iter_mut().zip(&x[i * stride..(i + 1) * stride]) {
                    *d += w * v;
                }
            }
            for &(i, w) in row {
                for (o, d) in out[i * stride..(i + 1) * stride]
                    .iter_mut()
                    .zip(&difference)
                {
                    *o += SEAM_WEIGHT * w * d;
                }
            }
        }
    };
    let x = conjugate_gradients(apply, &baked, n * stride);
    for (k, &t) in texels.iter().enumerate() {
        for c in 0..stride {
            image[t * stride + c] = x[k * stride + c] as f32;
        }
    }
}

/// Solves `A x = b` for the symmetric positive definite `A` given as `apply`, from `x = b`
/// (the baked values: near the answer where the seams nearly agree already).
fn conjugate_gradients(apply: impl Fn(&[f64], &mut [f64]), b: &[f64], n: usize) -> Vec<f64> {
    let mut x = b.to_vec();
    let mut product = vec![0.0; n];
    apply(&x, &mut product);
    let mut residual: Vec<f64> = b.iter().zip(&product).map(|(b, p)| b - p).collect();
    let mut direction = residual.clone();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
    let mut rr = dot(&residual, &residual);
    let floor = 1e-20 * dot(b, b).max(f64::MIN_POSITIVE);
    for _ in 0..MAX_STEPS {
        if rr <= floor {
            break;
        }
        apply(&direction, &mut product);
        let alpha = rr / dot(&direction, &product);
        for i in 0..n {
            x[i] += alpha * direction[i];
            residual[i] -= alpha * product[i];
        }
        let next = dot(&residual, &residual);
        let beta = next / rr;
        rr = next;
        for i in 0..n {
            direction[i] = residual[i] + beta * direction[i];
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::receivers::atlas::generate_atlas;
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    #[test]
    fn seams_are_the_smooth_edges_between_charts() {
        let sphere = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 3)).unwrap().0;
        let atlas = generate_atlas(&sphere, 20.0).unwrap();
        assert!(atlas.chart_count() > 1);
        let found = seams(&sphere, &atlas);
        assert_eq!(found.len(), sphere_edges_between_charts(&sphere, &atlas));
        // Each seam's two sides are one surface edge: about equal lengths in the atlas.
        for seam in &found {
            let (a, b) = (seam.a[0].distance(seam.a[1]), seam.b[0].distance(seam.b[1]));
            assert!((a / b - 1.0).abs() < 0.2, "{a} {b}");
        }
        let grid = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z, 4, Vec3::ONE);
        let grid = prepare(grid).unwrap().0;
        assert!(seams(&grid, &generate_atlas(&grid, 10.0).unwrap()).is_empty());
    }

    fn sphere_edges_between_charts(scene: &Scene, atlas: &Atlas) -> usize {
        let mut owners: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for (t, c) in scene.triangles.iter().enumerate() {
            for i in 0..3 {
                let (u, v) = (c[i], c[(i + 1) % 3]);
                owners
                    .entry((u.min(v), u.max(v)))
                    .or_default()
                    .push(atlas.chart_of[t]);
            }
        }
        owners
            .values()
            .filter(|c| c.len() == 2 && c[0] != c[1])
            .count()
    }

    /// RMS over the seams' points of the difference between the two sides' lookups.
    fn seam_difference(
        seams: &[Seam],
        width: u32,
        height: u32,
        image: &[f32],
        stride: usize,
    ) -> f64 {
        let rows = rows(seams, width, height);
        let mut sum = 0.0;
        for row in &rows {
            for c in 0..stride {
                let d: f64 = row
                    .iter()
                    .map(|&(t, w)| w * image[t * stride + c] as f64)
                    .sum();
                sum += d * d;
            }
        }
        (sum / (rows.len() * stride) as f64).sqrt()
    }

    #[test]
    fn stitching_makes_the_sides_agree_and_leaves_other_texels() {
        let cube = prepare(builtin::closed_box(Vec3::ZERO, Vec3::ONE, 2))
            .unwrap()
            .0;
        let atlas = generate_atlas(&cube, 12.0).unwrap();
        let found = seams(&cube, &atlas);
        let (w, h) = (atlas.width, atlas.height);
        // Two coefficients a texel: each chart's own constant, and a ramp across the atlas.
        let texels = crate::receivers::texels::rasterize(&atlas);
        let mut image = vec![0.0f32; (w * h) as usize * 2];
        let mut valid = vec![false; (w * h) as usize];
        for (&(x, y), p) in texels.texels.iter().zip(&texels.points) {
            let at = (y * w + x) as usize;
            image[at * 2] = atlas.chart_of[p.triangle as usize] as f32;
            image[at * 2 + 1] = x as f32 * 0.1 - y as f32 * 0.05;
            valid[at] = true;
        }
        crate::receivers::texels::dilate(w, h, &mut image, 2, &mut valid, 4).unwrap();
        let before = seam_difference(&found, w, h, &image, 2);
        let baked = image.clone();
        stitch(w, h, &mut image, 2, &found);
        let after = seam_difference(&found, w, h, &image, 2);
        assert!(before > 0.5, "{before}");
        assert!(after < 0.1 * before, "{before} -> {after}");
        // Texels no lookup reads keep their values; deterministic.
        let read: std::collections::HashSet<usize> = rows(&found, w, h)
            .iter()
            .flat_map(|row| row.map(|(t, _)| t))
            .collect();
        for t in (0..(w * h) as usize).filter(|t| !read.contains(t)) {
            assert_eq!(image[2 * t..2 * t + 2], baked[2 * t..2 * t + 2]);
        }
        let mut again = baked.clone();
        stitch(w, h, &mut again, 2, &found);
        assert_eq!(again, image);
    }
}
