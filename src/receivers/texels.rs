//! The texels of a lightmap atlas as receivers, and the clean-up of the baked map.
//!
//! [`rasterize`] is conservative: a texel belongs to a chart when its (closed) square meets the
//! chart at all, not only when its centre is inside, so that bilinear filtering anywhere on a
//! triangle reads texels baked for its chart (that triangle, or the other half of its quad),
//! and needle triangles narrower than a texel still get texels. A texel's receiver is the
//! point of the triangle nearest its centre.
//!
//! [`dilate`] then fills the texels around the charts (and those whose bake is not to be
//! trusted, [`mark_invalid`]) from their valid neighbours, so filtering near a chart's edge
//! never reads an unbaked texel.

use glam::{DVec2, Vec2};

use super::atlas::Atlas;
use super::SurfacePoint;
use crate::error::{Error, Result};

pub use super::dilation::{dilate, dilate_by_owner, plan_dilation, DilationPlan};

/// The covered texels of an atlas and, for each, its receiver. Row-major order (by `y`, then
/// `x`), each texel once.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TexelPoints {
    pub width: u32,
    pub height: u32,
    /// `(x, y)` of each covered texel.
    pub texels: Vec<(u32, u32)>,
    /// The receiver of each texel: the point of its triangle nearest the texel's centre.
    pub points: Vec<SurfacePoint>,
}

impl TexelPoints {
    /// Per texel of the whole atlas (row-major), whether it is covered and its receiver is not
    /// flagged in `leaking` (one flag per receiver, such as "most of its rays hit back faces";
    /// empty for none): the `valid` mask [`dilate`] starts from.
    pub fn valid_mask(&self, leaking: &[bool]) -> Result<Vec<bool>> {
        if !leaking.is_empty() && leaking.len() != self.texels.len() {
            return Err(Error::Options(format!(
                "{} leak flags for {} texels",
                leaking.len(),
                self.texels.len()
            )));
        }
        let mut valid = vec![false; self.width as usize * self.height as usize];
        for &(x, y) in &self.texels {
            valid[self.index(x, y)] = true;
        }
        if !leaking.is_empty() {
            let at: Vec<usize> = self.texels.iter().map(|&(x, y)| self.index(x, y)).collect();
            mark_invalid(&mut valid, &at, leaking);
        }
        Ok(valid)
    }

    /// Per-receiver values (`[receiver][channel]`) spread into a row-major image
    /// (`[texel][channel]`), zero where no texel is covered. The image is `values` itself,
    /// grown and spread in place: a texel's place in the image is never before its place
    /// among the covered texels (both are row-major), so moving texels from the last to the
    /// first never overwrites one not yet moved, and a map never needs room for two copies.
    pub fn scatter(&self, mut values: Vec<f32>, channels: usize) -> Result<Vec<f32>> {
        if values.len() != self.texels.len() * channels {
            return Err(Error::Options(format!(
                "{} values for {} texels of {channels} channels",
                values.len(),
                self.texels.len()
            )));
        }
        values.resize(self.width as usize * self.height as usize * channels, 0.0);
        // Where the texel after the one being moved starts: everything from there to the
        // previous texel's end is a gap left uncovered.
        let mut gap_end = values.len();
        for (i, &(x, y)) in self.texels.iter().enumerate().rev() {
            let at = self.index(x, y) * channels;
            debug_assert!(at >= i * channels, "covered texels are in row-major order");
            values.copy_within(i * channels..(i + 1) * channels, at);
            values[at + channels..gap_end].fill(0.0);
            gap_end = at;
        }
        values[..gap_end].fill(0.0);
        Ok(values)
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}

/// The four texels a bilinear lookup at `p` (atlas texel units; texel centres at `+0.5`) reads
/// and their weights, as `(row-major index, weight)`, clamped at the borders.
pub fn bilinear_taps(width: u32, height: u32, p: Vec2) -> [(usize, f32); 4] {
    let (x, y) = (p.x - 0.5, p.y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let clamp = |v: f32, n: u32| (v.max(0.0) as u32).min(n - 1) as usize;
    let at = |dx: f32, dy: f32| clamp(y0 + dy, height) * width as usize + clamp(x0 + dx, width);
    [
        (at(0.0, 0.0), (1.0 - fx) * (1.0 - fy)),
        (at(1.0, 0.0), fx * (1.0 - fy)),
        (at(0.0, 1.0), (1.0 - fx) * fy),
        (at(1.0, 1.0), fx * fy),
    ]
}

/// Per texel of a `width` x `height` image, the label of the nearest seed (Chebyshev distance,
/// ties to the seed reached first, seeds taken in the order given); `u32::MAX` with no seeds.
/// `seeds` are `(row-major texel, label)`.
pub fn nearest_owner(width: u32, height: u32, seeds: &[(usize, u32)]) -> Vec<u32> {
    let (w, h) = (width as usize, height as usize);
    let mut owner = vec![u32::MAX; w * h];
    let mut queue = std::collections::VecDeque::new();
    for &(texel, label) in seeds {
        if texel < owner.len() && owner[texel] == u32::MAX {
            owner[texel] = label;
            queue.push_back(texel);
        }
    }
    while let Some(texel) = queue.pop_front() {
        let (x, y) = (texel % w, texel / w);
        for ny in y.saturating_sub(1)..(y + 2).min(h) {
            for nx in x.saturating_sub(1)..(x + 2).min(w) {
                let n = ny * w + nx;
                if owner[n] == u32::MAX {
                    owner[n] = owner[texel];
                    queue.push_back(n);
                }
            }
        }
    }
    owner
}

/// Marks texels invalid, so that [`dilate`] fills them from their neighbours: `valid[at[i]]`
/// becomes false wherever `flags[i]` is set (out-of-range entries are ignored).
pub fn mark_invalid(valid: &mut [bool], at: &[usize], flags: &[bool]) {
    for (&texel, &flag) in at.iter().zip(flags) {
        if flag {
            if let Some(v) = valid.get_mut(texel) {
                *v = false;
            }
        }
    }
}

/// How one triangle reaches one texel, compared to pick the texel's owner where charts overlap
/// (only with overlapping charts; a packed atlas has none).
#[derive(Clone, Copy, Debug)]
struct Candidate {
    triangle: u32,
    barycentrics: [f32; 3],
    /// Squared distance in texels from the texel's centre to the triangle; zero when inside.
    distance2: f64,
}

impl Candidate {
    /// Centre inside wins, then the smaller distance, then the lower triangle index.
    fn beats(&self, other: &Candidate) -> bool {
        let inside = |c: &Candidate| c.distance2 == 0.0;
        (!inside(self), self.distance2, self.triangle)
            < (!inside(other), other.distance2, other.triangle)
    }
}

/// Every texel whose square meets some chart of `atlas`, with its receiver.
pub fn rasterize(atlas: &Atlas) -> TexelPoints {
    let (width, height) = (atlas.width as usize, atlas.height as usize);
    // Which candidate owns each texel, as an index into `found`.
    let mut owner = vec![u32::MAX; width * height];
    let mut found: Vec<(usize, Candidate)> = Vec::new();
    for (t, corners) in atlas.corners.iter().enumerate() {
        let corners = corners.map(|c| c.as_dvec2());
        for (x, y) in texels_meeting(corners, atlas.width, atlas.height) {
            let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let (barycentrics, distance2) = closest_point(corners, centre);
            let candidate = Candidate {
                triangle: t as u32,
                barycentrics,
                distance2,
            };
            let texel = y as usize * width + x as usize;
            match owner[texel] {
                u32::MAX => {
                    owner[texel] = found.len() as u32;
                    found.push((texel, candidate));
                }
                slot if candidate.beats(&found[slot as usize].1) => {
                    found[slot as usize].1 = candidate;
                }
                _ => {}
            }
        }
    }
    found.sort_unstable_by_key(|&(texel, _)| texel);
    TexelPoints {
        width: atlas.width,
        height: atlas.height,
        texels: found
            .iter()
            .map(|&(texel, _)| ((texel % width) as u32, (texel / width) as u32))
            .collect(),
        points: found
            .iter()
            .map(|(_, c)| SurfacePoint {
                triangle: c.triangle,
                barycentrics: c.barycentrics,
            })
            .collect(),
    }
}

/// The texels (inside the atlas) whose closed squares meet the closed triangle `corners`.
fn texels_meeting(corners: [DVec2; 3], width: u32, height: u32) -> Vec<(u32, u32)> {
    if corners.iter().any(|c| !c.is_finite()) {
        return Vec::new();
    }
    let lo = corners[0].min(corners[1]).min(corners[2]);
    let hi = corners[0].max(corners[1]).max(corners[2]);
    // Closed squares: texel x meets [lo, hi] for ceil(lo) - 1 <= x <= floor(hi).
    let range = |lo: f64, hi: f64, size: u32| {
        let first = (lo.ceil() - 1.0).max(0.0);
        let last = hi.floor().min(size as f64 - 1.0);
        (first as u32, last as i64)
    };
    let (x0, x1) = range(lo.x, hi.x, width);
    let (y0, y1) = range(lo.y, hi.y, height);
    let mut texels = Vec::new();
    for y in y0 as i64..=y1 {
        for x in x0 as i64..=x1 {
            if square_meets_triangle(DVec2::new(x as f64, y as f64), corners) {
                texels.push((x as u32, y as u32));
            }
        }
    }
    texels
}

/// Whether the closed unit square at `origin` meets the closed triangle (separating axes: the
/// square's two and the triangle's three edge normals). A zero-length edge gives a zero axis,
/// which separates nothing, so degenerate triangles (segments, points) are handled too.
fn square_meets_triangle(origin: DVec2, corners: [DVec2; 3]) -> bool {
    // Touching counts: a tolerance well under a texel, above rounding.
    const SLACK: f64 = 1e-9;
    let square = [
        origin,
        origin + DVec2::X,
        origin + DVec2::Y,
        origin + DVec2::ONE,
    ];
    let edge_normals = [0, 1, 2].map(|i| (corners[(i + 1) % 3] - corners[i]).perp());
    [DVec2::X, DVec2::Y]
        .iter()
        .chain(&edge_normals)
        .all(|&axis| {
            let (a_lo, a_hi) = project(&square, axis);
            let (b_lo, b_hi) = project(&corners, axis);
            let slack = SLACK * axis.length().max(1.0);
            a_lo <= b_hi + slack && b_lo <= a_hi + slack
        })
}

fn project(points: &[DVec2], axis: DVec2) -> (f64, f64) {
    points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let d = p.dot(axis);
            (lo.min(d), hi.max(d))
        })
}

/// The point of the closed triangle nearest `p`: its barycentrics (non-negative, summing to
/// one) and its squared distance from `p` (exactly zero when `p` is inside).
fn closest_point(corners: [DVec2; 3], p: DVec2) -> ([f32; 3], f64) {
    let [a, b, c] = corners;
    let area2 = (b - a).perp_dot(c - a);
    if area2.abs() > 1e-12 * (b - a).length_squared().max((c - a).length_squared()) {
        let w = [
            (c - b).perp_dot(p - b),
            (a - c).perp_dot(p - c),
            (b - a).perp_dot(p - a),
        ]
        .map(|x| x / area2);
        if w.iter().all(|&x| x >= 0.0) {
            return (normalized(w), 0.0);
        }
    }
    // Outside (or a degenerate triangle): the nearest point of the three edges; ties go to the
    // first edge, for determinism.
    let mut best = ([1.0, 0.0, 0.0], f64::INFINITY);
    for i in 0..3 {
        let j = (i + 1) % 3;
        let edge = corners[j] - corners[i];
        let length2 = edge.length_squared();
        let s = if length2 > 0.0 {
            ((p - corners[i]).dot(edge) / length2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let distance2 = (corners[i] + edge * s).distance_squared(p);
        if distance2 < best.1 {
            let mut w = [0.0; 3];
            w[i] = 1.0 - s;
            w[j] = s;
            best = (w, distance2);
        }
    }
    (normalized(best.0), best.1)
}

/// f64 weights clamped to non-negative and scaled to sum to one, as f32.
fn normalized(w: [f64; 3]) -> [f32; 3] {
    let w = w.map(|x| x.max(0.0));
    let sum: f64 = w.iter().sum();
    if sum > 0.0 {
        w.map(|x| (x / sum) as f32)
    } else {
        [1.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::super::atlas::tests::{quad_scene, scene_of};
    use super::super::atlas::{generate_atlas, GUTTER};
    use super::*;
    use crate::scene::Scene;
    use glam::{Vec2, Vec3};

    /// Assorted triangles: random shapes, a needle, a tiny one, a right triangle on the grid.
    fn assorted_scene() -> Scene {
        let mut triangles = Vec::new();
        let mut rng = crate::sampling::Pcg32::new(12345);
        let mut next = || rng.next_f32();
        for _ in 0..60 {
            let p = [(); 3].map(|_| Vec3::new(next(), next(), next()) * 3.0);
            triangles.push(p);
        }
        triangles.push([
            Vec3::ZERO,
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(2.5, 0.001, 0.0),
        ]);
        triangles.push([
            Vec3::ZERO,
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(6.0, 1e-7, 0.0),
        ]);
        triangles.push([
            Vec3::ZERO,
            Vec3::new(1e-4, 0.0, 0.0),
            Vec3::new(0.0, 1e-4, 1e-5),
        ]);
        triangles.push([Vec3::ZERO, Vec3::X, Vec3::Y]);
        scene_of(&triangles)
    }

    /// Whether the square of texel (x, y) meets the triangle, by dense sampling of the square's
    /// closed area (an independent check of the separating-axis test, not a proof).
    fn sampled_overlap(corners: [Vec2; 3], x: u32, y: u32) -> bool {
        let inside = |p: DVec2| {
            let c = corners.map(|c| c.as_dvec2());
            let d = [0, 1, 2].map(|i| (c[(i + 1) % 3] - c[i]).perp_dot(p - c[i]));
            d.iter().all(|&v| v >= 0.0) || d.iter().all(|&v| v <= 0.0)
        };
        let n = 16;
        (0..=n).any(|i| {
            (0..=n).any(|j| {
                inside(DVec2::new(
                    x as f64 + i as f64 / n as f64,
                    y as f64 + j as f64 / n as f64,
                ))
            })
        })
    }

    const ORIGIN_POINT: SurfacePoint = SurfacePoint {
        triangle: 0,
        barycentrics: [1.0, 0.0, 0.0],
    };

    #[test]
    fn scattering_in_place_puts_every_texel_where_a_fresh_image_would() {
        let mut rng = crate::sampling::Pcg32::new(7);
        for (width, height, channels, share) in [(7, 5, 3, 0.3), (16, 9, 1, 0.9), (4, 4, 2, 1.0)] {
            let all = (0..height).flat_map(|y| (0..width).map(move |x| (x, y)));
            let texels: Vec<(u32, u32)> = all.filter(|_| rng.next_f32() < share).collect();
            let points = vec![ORIGIN_POINT; texels.len()];
            let map = TexelPoints {
                width,
                height,
                texels,
                points,
            };
            let values: Vec<f32> = (0..map.texels.len() * channels)
                .map(|i| i as f32 + 1.0)
                .collect();
            let mut fresh = vec![0.0; (width * height) as usize * channels];
            for (i, &(x, y)) in map.texels.iter().enumerate() {
                let at = (y * width + x) as usize * channels;
                fresh[at..at + channels].copy_from_slice(&values[i * channels..][..channels]);
            }
            assert_eq!(map.scatter(values, channels).unwrap(), fresh);
        }
        let map = TexelPoints {
            width: 2,
            height: 2,
            texels: vec![(0, 0)],
            points: vec![ORIGIN_POINT],
        };
        assert!(map.scatter(vec![1.0; 3], 2).is_err());
    }

    #[test]
    fn every_texel_a_chart_overlaps_is_covered_by_it() {
        for scene in [assorted_scene(), quad_scene()] {
            covers_overlapped_texels(&scene, 6.0);
        }
    }

    /// Each texel a triangle overlaps is covered, by it or by the other triangle of its chart
    /// (along a quad's diagonal, the one that holds the texel's centre).
    fn covers_overlapped_texels(scene: &Scene, density: f32) {
        let atlas = generate_atlas(scene, density).unwrap();
        let texels = rasterize(&atlas);
        let chart_of = |t: u32| atlas.chart_of[t as usize];
        let owner: std::collections::HashMap<(u32, u32), u32> = texels
            .texels
            .iter()
            .zip(&texels.points)
            .map(|(&t, p)| (t, chart_of(p.triangle)))
            .collect();
        for (t, &corners) in atlas.corners.iter().enumerate() {
            let lo = corners.iter().fold(Vec2::INFINITY, |m, &c| m.min(c));
            let hi = corners.iter().fold(Vec2::NEG_INFINITY, |m, &c| m.max(c));
            for y in lo.y.floor() as u32..=hi.y.floor() as u32 {
                for x in lo.x.floor() as u32..=hi.x.floor() as u32 {
                    if sampled_overlap(corners, x, y) {
                        let chart = chart_of(t as u32);
                        assert_eq!(owner.get(&(x, y)), Some(&chart), "texel {x} {y}");
                    }
                }
            }
        }
    }

    #[test]
    fn texels_are_unique_row_major_and_their_points_nearest_the_centre() {
        for scene in [assorted_scene(), quad_scene()] {
            points_nearest_the_centres(&scene, 6.0);
        }
    }

    fn points_nearest_the_centres(scene: &Scene, density: f32) {
        let atlas = generate_atlas(scene, density).unwrap();
        let texels = rasterize(&atlas);
        let keys: Vec<(u32, u32)> = texels.texels.iter().map(|&(x, y)| (y, x)).collect();
        assert!(
            keys.windows(2).all(|w| w[0] < w[1]),
            "not strictly row-major"
        );
        for (&(x, y), p) in texels.texels.iter().zip(&texels.points) {
            let b = p.barycentrics;
            assert!(b.iter().all(|&w| w >= 0.0) && (b.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            let c = atlas.corners[p.triangle as usize];
            let at = c[0] * b[0] + c[1] * b[1] + c[2] * b[2];
            let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            // No sampled point of the triangle is nearer the centre than the receiver.
            let nearest = (0..=40)
                .flat_map(|i| (0..=40 - i).map(move |j| (i, j)))
                .map(|(i, j)| {
                    let (u, v) = (i as f32 / 40.0, j as f32 / 40.0);
                    (c[0] * (1.0 - u - v) + c[1] * u + c[2] * v).distance(centre)
                })
                .fold(f32::INFINITY, f32::min);
            assert!(at.distance(centre) <= nearest + 1e-3, "texel {x} {y}");
        }
    }

    #[test]
    fn needles_get_texels_along_their_length() {
        let scene = assorted_scene();
        let atlas = generate_atlas(&scene, 6.0).unwrap();
        let texels = rasterize(&atlas);
        // The two needles (5 and 6 units long, at most 0.006 texels wide) and the tiny one.
        for (t, min_texels) in [(60, 30), (61, 36), (62, 2)] {
            let count = texels.points.iter().filter(|p| p.triangle == t).count();
            assert!(count >= min_texels, "triangle {t}: {count} texels");
        }
        // Every triangle has texels.
        let mut seen = vec![false; scene.triangles.len()];
        texels
            .points
            .iter()
            .for_each(|p| seen[p.triangle as usize] = true);
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn no_two_charts_come_within_the_gutter() {
        for scene in [assorted_scene(), quad_scene()] {
            // Densities that put corners on and near texel edges.
            for density in [3.0, 4.5, 9.0, 12.25, 17.3] {
                charts_apart(&scene, density);
            }
        }
    }

    fn charts_apart(scene: &Scene, density: f32) {
        let atlas = generate_atlas(scene, density).unwrap();
        let texels = rasterize(&atlas);
        let (w, h) = (atlas.width as usize, atlas.height as usize);
        let chart_of = |t: u32| atlas.chart_of[t as usize];
        let mut owner = vec![u32::MAX; w * h];
        for (&(x, y), p) in texels.texels.iter().zip(&texels.points) {
            owner[y as usize * w + x as usize] = chart_of(p.triangle);
        }
        // Any two covered texels of different charts are more than GUTTER texels apart
        // (Chebyshev distance), so GUTTER empty texels lie between them.
        let reach = GUTTER as i64;
        for (&(x, y), p) in texels.texels.iter().zip(&texels.points) {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    assert!(nx >= 0 && ny >= 0 && nx < w as i64 && ny < h as i64);
                    let other = owner[ny as usize * w + nx as usize];
                    let chart = chart_of(p.triangle);
                    assert!(other == u32::MAX || other == chart, "{x} {y}");
                }
            }
        }
    }

    #[test]
    fn overlapping_charts_pick_one_owner_by_the_rules() {
        // Two charts laid over one another by hand: the centre-inside one wins, then the nearer.
        let big = [
            Vec2::new(0.5, 0.5),
            Vec2::new(8.5, 0.5),
            Vec2::new(0.5, 8.5),
        ];
        let small = [
            Vec2::new(0.5, 0.5),
            Vec2::new(2.5, 0.5),
            Vec2::new(0.5, 2.5),
        ];
        let atlas = Atlas {
            width: 10,
            height: 10,
            corners: vec![small, big, small],
            chart_of: vec![0, 1, 2],
        };
        let texels = rasterize(&atlas);
        let owner = |x, y| {
            let i = texels.texels.iter().position(|&t| t == (x, y)).unwrap();
            texels.points[i].triangle
        };
        assert_eq!(owner(0, 0), 0, "both inside: the lower index");
        assert_eq!(owner(5, 1), 1, "only the big one");
        assert_eq!(
            owner(2, 0),
            0,
            "centre on the small one's edge: inside both"
        );
        assert_eq!(
            owner(2, 1),
            1,
            "met by both, centre inside the big one only"
        );
        assert_eq!(texels.texels.len(), texels.points.len());
    }

    #[test]
    fn receivers_are_as_far_apart_on_the_surface_as_in_the_atlas() {
        use super::super::Receivers;
        // Flat charts, none enlarged: the atlas is the surface at the density.
        let scene = super::super::atlas::tests::flat_scene();
        let density = 20.0;
        let atlas = generate_atlas(&scene, density).unwrap();
        let texels = rasterize(&atlas);
        let receivers = Receivers::at_points(&scene, &texels.points);
        let mut first_of = vec![None; scene.triangles.len()];
        for (i, p) in texels.points.iter().enumerate() {
            let t = p.triangle as usize;
            let c = atlas.corners[t];
            let b = p.barycentrics;
            let flat = c[0] * b[0] + c[1] * b[1] + c[2] * b[2];
            let Some((first_flat, first_3d)) = first_of[t] else {
                first_of[t] = Some((flat, receivers.positions[i]));
                continue;
            };
            let scale = density;
            let in_atlas = flat.distance(first_flat);
            let on_surface = receivers.positions[i].distance(first_3d) * scale;
            assert!(
                (in_atlas - on_surface).abs() < 1e-3 * (1.0 + in_atlas),
                "triangle {t}"
            );
        }
        assert!(
            first_of.iter().all(Option::is_some),
            "a triangle without texels"
        );
    }

    #[test]
    fn dilation_fills_the_bilinear_footprint_of_every_covered_texel() {
        // Every other texel of the needle (triangle 60) flagged as leaking.
        fills_footprints(&assorted_scene(), |i, p| p.triangle == 60 && i % 2 == 0);
        fills_footprints(&quad_scene(), |_, _| false);
    }

    fn fills_footprints(scene: &Scene, leaks: impl Fn(usize, &SurfacePoint) -> bool) {
        let atlas = generate_atlas(scene, 6.0).unwrap();
        let texels = rasterize(&atlas);
        let leaking: Vec<bool> = texels
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| leaks(i, p))
            .collect();
        let mut valid = texels.valid_mask(&leaking).unwrap();
        let chart_of = |p: &SurfacePoint| atlas.chart_of[p.triangle as usize] as f32;
        let values: Vec<f32> = texels.points.iter().map(chart_of).collect();
        let mut image = texels.scatter(values, 1).unwrap();
        let (w, h) = (atlas.width, atlas.height);
        let seeds: Vec<(usize, u32)> = texels
            .texels
            .iter()
            .zip(&texels.points)
            .map(|(&(x, y), p)| ((y * w + x) as usize, atlas.chart_of[p.triangle as usize]))
            .collect();
        let owner = nearest_owner(w, h, &seeds);
        dilate_by_owner(w, h, &mut image, 1, &mut valid, &owner, 2).unwrap();
        for (&(x, y), p) in texels.texels.iter().zip(&texels.points) {
            // Any 2x2 block holding the texel lies in its 3x3 neighbourhood.
            for ny in y - 1..=y + 1 {
                for nx in x - 1..=x + 1 {
                    let n = (ny * w + nx) as usize;
                    assert!(valid[n], "texel {nx} {ny} next to {x} {y}");
                    // Filled from its own chart only (the values are chart indices).
                    assert_eq!(image[n], chart_of(p), "texel {nx} {ny}");
                }
            }
        }
    }

    #[test]
    fn dilation_averages_valid_neighbours_and_spreads_a_ring_per_pass() {
        let (w, h) = (5u32, 5u32);
        let mut values = vec![0.0f32; 25 * 2];
        let mut valid = vec![false; 25];
        for (texel, value) in [(12usize, 4.0f32), (13, 8.0)] {
            valid[texel] = true;
            values[texel * 2] = value;
            values[texel * 2 + 1] = -value;
        }
        dilate(w, h, &mut values, 2, &mut valid, 1).unwrap();
        // (3, 1) sees (2, 2) and (3, 2); (1, 2) sees (2, 2) alone; (0, 0) sees nothing yet.
        assert_eq!(&values[8 * 2..8 * 2 + 2], &[6.0, -6.0]);
        assert_eq!(values[11 * 2], 4.0);
        assert!(!valid[0] && valid[8] && valid[14]);
        dilate(w, h, &mut values, 2, &mut valid, 1).unwrap();
        assert!(valid.iter().all(|&v| v));
        let mut bad = vec![true; 3];
        assert!(dilate(w, h, &mut values, 2, &mut bad, 1).is_err());
        assert!(dilate(w, h, &mut values[..3], 2, &mut valid, 1).is_err());
        assert!(texels_meeting([DVec2::NAN; 3], 4, 4).is_empty());
    }
}
