//! A lightmap atlas generated for a prepared scene: meshes need not carry UVs, so every triangle
//! gets its own chart.
//!
//! A chart is the triangle laid flat at its true shape (edge lengths kept, times the texel
//! density), its longest edge along +x and its third corner above it, so its bounding box is as
//! low as the triangle allows. Two triangles whose longest edge is the same shared edge (the two
//! halves of a quad, split along its diagonal) share one chart, unfolded about that edge and
//! turned to the smallest bounding box: half the texels of two charts for a rectangle, and no
//! seam along the diagonal. A tiny triangle is scaled up until its longest edge spans
//! [`MIN_CHART_EDGE`] texels, so every triangle gets texels of its own.
//!
//! Charts are packed on shelves (rows): sorted by height, tallest first, ties by chart order
//! (that of their lowest triangle index),
//! each shelf filled left to right up to the atlas width. The width is chosen so the atlas comes
//! out about square. Every chart is kept [`GUTTER`] empty texels away from the others and from
//! the border, so neither bilinear filtering nor dilation ([`super::texels::dilate`]) mixes two
//! charts.
//!
//! Texel `(x, y)` covers `[x, x+1) x [y, y+1)` in the atlas' texel units; its centre is
//! `(x + 0.5, y + 0.5)`.

use std::collections::HashMap;

use glam::{DVec2, DVec3, Vec2};

use crate::error::{Error, Result};
use crate::scene::Scene;

/// The largest atlas side accepted (texels): larger would not fit a GPU texture.
pub const MAX_ATLAS_SIZE: u32 = 16384;

/// Empty texels kept between any two charts and between a chart and the border. Two: the ring
/// one texel around a chart (the reach of bilinear filtering) is then filled by dilation from
/// that chart alone, never from a neighbour.
pub const GUTTER: u32 = 2;

/// The shortest a chart's longest edge may be, in texels.
pub const MIN_CHART_EDGE: f32 = 2.0;

/// A packed atlas: its size and every triangle's corners in it.
#[derive(Clone, Debug, PartialEq)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    /// Per triangle (in the scene's order), the atlas positions of its three corners, in texel
    /// units.
    pub corners: Vec<[Vec2; 3]>,
    /// Per triangle, the chart it lies in (two triangles of a quad share one).
    pub chart_of: Vec<u32>,
}

/// One triangle, or two sharing an edge, laid flat: each one's corners (in the triangle's own
/// order), the bounding box's lower corner at the origin, scaled to texels.
#[derive(Clone, Debug, PartialEq)]
struct Chart {
    members: Vec<(u32, [Vec2; 3])>,
    /// Texels the chart's footprint spans (see [`footprint`]).
    size: [u32; 2],
}

/// Lays out and packs a chart for every triangle of `scene` at `texels_per_unit` texels per
/// scene unit of length. Refuses densities that are not positive and finite, scenes without
/// triangles or with non-finite positions, and atlases over [`MAX_ATLAS_SIZE`] a side.
pub fn generate_atlas(scene: &Scene, texels_per_unit: f32) -> Result<Atlas> {
    let charts = lay_out_charts(scene, texels_per_unit)?;
    let packing = pack_square(&charts)?;
    let mut corners = vec![[Vec2::ZERO; 3]; scene.triangles.len()];
    let mut chart_of = vec![0; scene.triangles.len()];
    for (c, (chart, &[x, y])) in charts.iter().zip(&packing.origins).enumerate() {
        // Half a texel in, so that a corner sits on a texel centre, never on a texel edge:
        // which texels the chart touches is then unambiguous (see `footprint`).
        let offset = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        for &(t, flat) in &chart.members {
            corners[t as usize] = flat.map(|p| p + offset);
            chart_of[t as usize] = c as u32;
        }
    }
    Ok(Atlas {
        width: packing.width,
        height: packing.height,
        corners,
        chart_of,
    })
}

/// The texel density that makes the atlas of `scene` about `target_size` texels on its longer
/// side (within a few percent, never over). Refuses a target of zero or over
/// [`MAX_ATLAS_SIZE`], a target too small for the charts' minimum size and gutters at any
/// density, and scenes [`generate_atlas`] refuses.
pub fn texels_per_unit_for_size(scene: &Scene, target_size: u32) -> Result<f32> {
    if target_size == 0 || target_size > MAX_ATLAS_SIZE {
        return Err(Error::Options(format!(
            "lightmap size must be between 1 and {MAX_ATLAS_SIZE} texels, not {target_size}"
        )));
    }
    check_scene(scene)?;
    let total_area: f64 = (0..scene.triangles.len() as u32)
        .map(|t| twice_area(corner_positions(scene, t)) * 0.5)
        .sum();
    // Charts' boxes are about twice the triangles' area: a first guess to bisect around.
    let guess = (target_size as f64 / (2.0 * total_area).sqrt().max(1e-30)) as f32;
    let side = |density: f32| -> Option<u32> {
        let charts = lay_out_charts(scene, density).ok()?;
        pack_square(&charts).ok().map(|p| p.width.max(p.height))
    };
    // Bracket on a log scale, then bisect: the side grows with the density, in steps.
    let (mut low, mut high) = (guess, guess);
    for _ in 0..64 {
        if side(low).is_some_and(|s| s <= target_size) || !is_positive(low * 0.5) {
            break;
        }
        low *= 0.5;
    }
    for _ in 0..64 {
        if side(high).is_none_or(|s| s > target_size) || !is_positive(high * 2.0) {
            break;
        }
        high *= 2.0;
    }
    for _ in 0..24 {
        let middle = (low * high).sqrt();
        if side(middle).is_some_and(|s| s <= target_size) {
            low = middle;
        } else {
            high = middle;
        }
    }
    match side(low) {
        Some(s) if s <= target_size => Ok(low),
        smallest => Err(Error::Options(format!(
            "a lightmap of {target_size} texels a side is too small for {} triangles \
             (they need at least {} with their gutters)",
            scene.triangles.len(),
            smallest.map_or("more".to_string(), |s| s.to_string())
        ))),
    }
}

fn is_positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

fn check_scene(scene: &Scene) -> Result<()> {
    if scene.triangles.is_empty() {
        return Err(Error::Geometry(
            "the scene has no triangles to lay out in a lightmap".into(),
        ));
    }
    let vertices = scene.positions.len();
    for (t, corners) in scene.triangles.iter().enumerate() {
        if corners.iter().any(|&c| c as usize >= vertices) {
            return Err(Error::Geometry(format!(
                "triangle {t} has a corner index past the {vertices} vertices"
            )));
        }
    }
    if let Some(v) = scene.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::Geometry(format!("vertex {v} is not finite")));
    }
    Ok(())
}

fn lay_out_charts(scene: &Scene, texels_per_unit: f32) -> Result<Vec<Chart>> {
    if !is_positive(texels_per_unit) {
        return Err(Error::Options(format!(
            "lightmap texel density must be positive and finite, not {texels_per_unit}"
        )));
    }
    check_scene(scene)?;
    let density = texels_per_unit as f64;
    let partners = partners(scene);
    let mut charts = Vec::with_capacity(scene.triangles.len());
    for (t, partner) in partners.into_iter().enumerate() {
        let t = t as u32;
        match partner {
            // Laid out with the lower index of the two.
            Some(p) if p < t => {}
            Some(p) => match lay_flat_pair(scene, t, p, density) {
                Some(chart) => charts.push(chart),
                None => {
                    charts.push(lay_flat(scene, t, density));
                    charts.push(lay_flat(scene, p, density));
                }
            },
            None => charts.push(lay_flat(scene, t, density)),
        }
    }
    Ok(charts)
}

/// A triangle's corners in f64 (lengths of needles and tiny triangles stay exact enough).
fn corner_positions(scene: &Scene, t: u32) -> [DVec3; 3] {
    scene.triangles[t as usize].map(|i| scene.positions[i as usize].as_dvec3())
}

fn twice_area([a, b, c]: [DVec3; 3]) -> f64 {
    (b - a).cross(c - a).length()
}

/// The corner that starts the longest edge (to the next corner; ties keep the lowest, for
/// determinism), and that edge's length.
fn longest_edge(p: [DVec3; 3]) -> (usize, f64) {
    let lengths = [0, 1, 2].map(|i| (p[(i + 1) % 3] - p[i]).length());
    let first = (0..3).fold(
        0,
        |best, i| if lengths[i] > lengths[best] { i } else { best },
    );
    (first, lengths[first])
}

/// For each triangle, the one it shares its longest edge with when that edge is the other's
/// longest too and no third triangle has it (a quad's diagonal on a manifold mesh).
fn partners(scene: &Scene) -> Vec<Option<u32>> {
    let mut by_edge: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (t, corners) in scene.triangles.iter().enumerate() {
        let p = corner_positions(scene, t as u32);
        let (first, longest) = longest_edge(p);
        if longest > 0.0 && twice_area(p) > 0.0 {
            let (u, v) = (corners[first], corners[(first + 1) % 3]);
            by_edge
                .entry((u.min(v), u.max(v)))
                .or_default()
                .push(t as u32);
        }
    }
    let mut partners = vec![None; scene.triangles.len()];
    // Each edge's list is settled on its own, so the map's order does not matter.
    for pair in by_edge.values().filter(|list| list.len() == 2) {
        partners[pair[0] as usize] = Some(pair[1]);
        partners[pair[1] as usize] = Some(pair[0]);
    }
    partners
}

/// A point at distances from the ends of the edge from `from` to `to` (lying along +x from the
/// origin, `length` long) that match `point`'s in space, on the side `sign` of the edge.
/// Both base angles of a longest edge are acute, so the point projects inside the edge.
fn unfold(from: DVec3, to: DVec3, point: DVec3, length: f64, sign: f64) -> DVec2 {
    let along = (point - from).dot(to - from) / length;
    let across = (to - from).cross(point - from).length() / length;
    DVec2::new(along.clamp(0.0, length), sign * across)
}

/// The scale from scene units to texels for a chart whose longest edge is `longest` long: the
/// density, or more for a tiny chart, which is enlarged so that it still gets texels.
fn chart_scale(longest: f64, texels_per_unit: f64) -> f64 {
    if longest > 0.0 {
        texels_per_unit.max(MIN_CHART_EDGE as f64 / longest)
    } else {
        texels_per_unit
    }
}

/// One triangle flat in the plane, scaled to texels: its longest edge on the x axis from the
/// origin, the third corner above it, so the bounding box is `[0, longest] x [0, height]`.
fn lay_flat(scene: &Scene, t: u32, texels_per_unit: f64) -> Chart {
    let p = corner_positions(scene, t);
    let (first, longest) = longest_edge(p);
    let (second, third) = ((first + 1) % 3, (first + 2) % 3);
    let mut flat = [DVec2::ZERO; 3];
    if longest > 0.0 {
        flat[second] = DVec2::new(longest, 0.0);
        flat[third] = unfold(p[first], p[second], p[third], longest, 1.0);
    }
    let scale = chart_scale(longest, texels_per_unit);
    finish_chart(vec![(t, flat.map(|c| c * scale))], DVec2::X)
}

/// Triangles `a` and `b`, which share `a`'s longest edge, unfolded about it into one chart and
/// turned to the smallest footprint. `None` where `b` does not hold that edge's two vertices
/// and a third (a malformed triangle).
fn lay_flat_pair(scene: &Scene, a: u32, b: u32, texels_per_unit: f64) -> Option<Chart> {
    let pa = corner_positions(scene, a);
    let (first, longest) = longest_edge(pa);
    let corners_a = scene.triangles[a as usize];
    let corners_b = scene.triangles[b as usize];
    let (u, v) = (corners_a[first], corners_a[(first + 1) % 3]);
    let at_u = corners_b.iter().position(|&c| c == u)?;
    let at_v = corners_b.iter().position(|&c| c == v)?;
    let at_w = (0..3).find(|&i| corners_b[i] != u && corners_b[i] != v)?;
    let pb = corner_positions(scene, b);
    let mut flat_a = [DVec2::ZERO; 3];
    flat_a[(first + 1) % 3] = DVec2::new(longest, 0.0);
    flat_a[(first + 2) % 3] = unfold(
        pa[first],
        pa[(first + 1) % 3],
        pa[(first + 2) % 3],
        longest,
        1.0,
    );
    let mut flat_b = [DVec2::ZERO; 3];
    flat_b[at_v] = DVec2::new(longest, 0.0);
    flat_b[at_w] = unfold(pb[at_u], pb[at_v], pb[at_w], longest, -1.0);
    let scale = chart_scale(longest, texels_per_unit);
    let (flat_a, flat_b) = (flat_a.map(|c| c * scale), flat_b.map(|c| c * scale));
    let direction = smallest_box_direction(&[flat_a[0], flat_a[1], flat_a[2], flat_b[at_w]]);
    Some(finish_chart(vec![(a, flat_a), (b, flat_b)], direction))
}

/// Of the directions of the segments between `points`, the one along which the points' box
/// has the smallest footprint (gutters included); the smallest box of a convex polygon has a
/// side along one of its edges. The first wins ties.
fn smallest_box_direction(points: &[DVec2]) -> DVec2 {
    let mut best = (u64::MAX, DVec2::X);
    for (i, &p) in points.iter().enumerate() {
        for &q in &points[i + 1..] {
            let Some(direction) = (q - p).try_normalize() else {
                continue;
            };
            let turned = points.iter().map(|&c| turn(c, direction));
            let extent = box_extent(turned);
            let cells = extent.map(|e| footprint(e as f32) as u64 + GUTTER as u64);
            if cells[0] * cells[1] < best.0 {
                best = (cells[0] * cells[1], direction);
            }
        }
    }
    best.1
}

/// `point` in the frame whose x axis is the unit `direction`.
fn turn(point: DVec2, direction: DVec2) -> DVec2 {
    DVec2::new(point.dot(direction), point.dot(direction.perp()))
}

fn box_extent(points: impl Iterator<Item = DVec2>) -> [f64; 2] {
    let (lo, hi) = points.fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    });
    (hi - lo).to_array()
}

/// The chart of `members` (corners in texels) turned so that `direction` is +x, moved so its
/// box's lower corner is at the origin.
fn finish_chart(members: Vec<(u32, [DVec2; 3])>, direction: DVec2) -> Chart {
    let turned: Vec<(u32, [DVec2; 3])> = members
        .into_iter()
        .map(|(t, c)| (t, c.map(|p| turn(p, direction))))
        .collect();
    let lo = turned
        .iter()
        .flat_map(|(_, c)| c)
        .fold(DVec2::INFINITY, |m, &p| m.min(p));
    let members: Vec<(u32, [Vec2; 3])> = turned
        .into_iter()
        .map(|(t, c)| (t, c.map(|p| (p - lo).as_vec2())))
        .collect();
    let extent = members
        .iter()
        .flat_map(|(_, c)| c)
        .fold(Vec2::ZERO, |m, &p| m.max(p))
        .to_array();
    Chart {
        members,
        size: extent.map(footprint),
    }
}

/// Texels spanned by an extent `[0, e]` placed half a texel into its first texel: the texels
/// whose closed squares meet `[0.5, 0.5 + e]`, from the first to `floor(0.5 + e)`.
fn footprint(extent: f32) -> u32 {
    // Placed in the atlas, the far corner is rounded to f32 again (an error of up to a
    // thousandth of a texel at 16384): an extent that ends just short of a texel's edge may
    // land on it, and touch the next texel. The margin counts that texel in.
    const ROUNDING_MARGIN: f64 = 0.01;
    // Saturates for absurd extents; the packer then refuses the atlas as too large.
    (0.5 + extent as f64 + ROUNDING_MARGIN)
        .floor()
        .min(u32::MAX as f64 / 4.0) as u32
        + 1
}

/// Charts placed: each chart's lower-left texel, and the atlas size.
#[derive(Clone, Debug, PartialEq)]
struct Packing {
    origins: Vec<[u32; 2]>,
    width: u32,
    height: u32,
}

/// Packs with the shelf width that makes the atlas closest to square (a few trials, as the
/// shelves' waste depends on the width), refusing atlases over [`MAX_ATLAS_SIZE`].
fn pack_square(charts: &[Chart]) -> Result<Packing> {
    let cell = |c: &Chart| c.size.map(|s| s as u64 + GUTTER as u64);
    let area: u64 = charts.iter().map(|c| cell(c)[0] * cell(c)[1]).sum();
    let widest = charts.iter().map(|c| cell(c)[0]).max().unwrap_or(0) + GUTTER as u64;
    let limit = MAX_ATLAS_SIZE as u64;
    if area > limit * limit || widest > limit {
        return Err(too_large(area.isqrt(), widest));
    }
    let order = shelf_order(charts);
    let mut width = (area as f64).sqrt().ceil() as u64 + GUTTER as u64;
    let mut best: Option<Packing> = None;
    for _ in 0..8 {
        let packing = pack_shelves(charts, &order, width.clamp(widest, limit) as u32);
        let side = |p: &Packing| p.width.max(p.height);
        let (w, h) = (packing.width as u64, packing.height as u64);
        if best.as_ref().is_none_or(|b| side(&packing) < side(b)) {
            best = Some(packing);
        }
        if h <= w {
            break;
        }
        // Too tall: widen towards the square of the same area.
        width = ((w * h) as f64).sqrt().ceil() as u64 + 1;
    }
    let best = best.expect("at least one packing");
    if best.width > MAX_ATLAS_SIZE || best.height > MAX_ATLAS_SIZE {
        return Err(too_large(best.width as u64, best.height as u64));
    }
    Ok(best)
}

fn too_large(width: u64, height: u64) -> Error {
    Error::Options(format!(
        "lightmap atlas of about {width} x {height} texels exceeds {MAX_ATLAS_SIZE} a side; \
         lower the texel density"
    ))
}

/// The packing order: tallest first, ties by chart order.
fn shelf_order(charts: &[Chart]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..charts.len() as u32).collect();
    // A stable sort keeps equal heights in index order.
    order.sort_by_key(|&i| std::cmp::Reverse(charts[i as usize].size[1]));
    order
}

/// Shelf packing in `order` into rows at most `max_width` texels wide (gutters included).
/// Each shelf is as tall as its first (tallest) chart.
fn pack_shelves(charts: &[Chart], order: &[u32], max_width: u32) -> Packing {
    let mut origins = vec![[0u32; 2]; charts.len()];
    let (mut x, mut y, mut shelf_height, mut width) = (GUTTER, GUTTER, 0, 0);
    for &i in order {
        let [w, h] = charts[i as usize].size;
        if x > GUTTER && x.saturating_add(w).saturating_add(GUTTER) > max_width {
            y = y.saturating_add(shelf_height).saturating_add(GUTTER);
            x = GUTTER;
            shelf_height = 0;
        }
        origins[i as usize] = [x, y];
        x = x.saturating_add(w).saturating_add(GUTTER);
        width = width.max(x);
        shelf_height = shelf_height.max(h);
    }
    Packing {
        origins,
        width,
        height: y.saturating_add(shelf_height).saturating_add(GUTTER),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    /// A prepared (welded) scene of quads, split along their diagonals, that pair into charts,
    /// and near-equilateral triangles, of which few do.
    pub(crate) fn quad_scene() -> Scene {
        let parts = [
            builtin::grid_plane(Vec3::new(0.0, -3.0, 0.0), Vec3::X, Vec3::Z, 4, Vec3::ONE),
            builtin::closed_box(Vec3::splat(-2.0), Vec3::new(2.0, 0.5, 3.0), 3),
            builtin::icosphere(Vec3::ZERO, 1.0, 2),
        ];
        prepare(builtin::merge(&parts)).unwrap().0
    }

    pub(crate) fn scene_of(triangles: &[[Vec3; 3]]) -> Scene {
        let positions: Vec<Vec3> = triangles.iter().flatten().copied().collect();
        Scene {
            normals: Some(vec![Vec3::Z; positions.len()]),
            albedo: vec![Vec3::ONE; positions.len()],
            triangles: (0..triangles.len() as u32)
                .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
                .collect(),
            positions,
        }
    }

    /// Triangles of many shapes and sizes, some far from one another, one a needle, one tiny.
    pub(crate) fn assorted_scene() -> Scene {
        let mut triangles = Vec::new();
        for i in 0..40 {
            let f = i as f32;
            let a = Vec3::new(f * 3.0, (f * 0.7).sin(), f * 0.1);
            let b = a + Vec3::new(1.0 + (f * 1.3).cos().abs(), 0.2 * f.sin(), 0.5);
            let c = a + Vec3::new(0.3 * f.cos(), 0.4 + (f * 0.37).sin().abs(), -0.2);
            triangles.push([a, b, c]);
        }
        triangles.push([
            Vec3::ZERO,
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(2.5, 0.001, 0.0),
        ]);
        triangles.push([
            Vec3::ZERO,
            Vec3::new(1e-4, 0.0, 0.0),
            Vec3::new(0.0, 1e-4, 1e-5),
        ]);
        scene_of(&triangles)
    }

    fn edge_lengths_2d(c: [Vec2; 3]) -> [f32; 3] {
        [0, 1, 2].map(|i| (c[(i + 1) % 3] - c[i]).length())
    }

    #[test]
    fn charts_keep_edge_lengths_at_the_density() {
        for scene in [assorted_scene(), quad_scene()] {
            keeps_edge_lengths(&scene, 7.0);
        }
    }

    fn keeps_edge_lengths(scene: &Scene, density: f32) {
        let atlas = generate_atlas(scene, density).unwrap();
        for (t, corners) in scene.triangles.iter().enumerate() {
            let p = corners.map(|i| scene.positions[i as usize]);
            let lengths_3d = [0, 1, 2].map(|i| (p[(i + 1) % 3] - p[i]).length());
            let longest = lengths_3d.iter().copied().fold(0.0, f32::max);
            let scale = density.max(MIN_CHART_EDGE / longest);
            for (flat, real) in edge_lengths_2d(atlas.corners[t]).iter().zip(lengths_3d) {
                assert!(
                    (flat - real * scale).abs() <= 1e-3 * (1.0 + real * scale),
                    "triangle {t}: {flat} vs {}",
                    real * scale
                );
            }
        }
    }

    #[test]
    fn charts_lie_inside_with_gutters_between_their_boxes() {
        for scene in [assorted_scene(), quad_scene()] {
            for density in [3.0, 4.5, 5.0, 9.0, 12.25, 17.3] {
                gutters_between_boxes(&scene, density);
            }
        }
    }

    fn gutters_between_boxes(scene: &Scene, density: f32) {
        let atlas = generate_atlas(scene, density).unwrap();
        let charts = *atlas.chart_of.iter().max().unwrap() as usize + 1;
        let mut lo = vec![Vec2::INFINITY; charts];
        let mut hi = vec![Vec2::NEG_INFINITY; charts];
        for (corners, &c) in atlas.corners.iter().zip(&atlas.chart_of) {
            for &p in corners {
                lo[c as usize] = lo[c as usize].min(p);
                hi[c as usize] = hi[c as usize].max(p);
            }
        }
        // Each chart's texel box: the texels its closed bounding box meets.
        let boxes: Vec<[i64; 4]> = lo
            .iter()
            .zip(&hi)
            .map(|(lo, hi)| {
                [
                    lo.x.ceil() as i64 - 1,
                    lo.y.ceil() as i64 - 1,
                    hi.x.floor() as i64,
                    hi.y.floor() as i64,
                ]
            })
            .collect();
        let g = GUTTER as i64;
        for (i, a) in boxes.iter().enumerate() {
            assert!(a[0] >= g && a[1] >= g, "chart {i} too near the border");
            assert!(a[2] < atlas.width as i64 - g && a[3] < atlas.height as i64 - g);
            for b in &boxes[i + 1..] {
                let apart =
                    a[2] + g < b[0] || b[2] + g < a[0] || a[3] + g < b[1] || b[3] + g < a[1];
                assert!(apart, "boxes {a:?} and {b:?} closer than the gutter");
            }
        }
    }

    #[test]
    fn the_halves_of_a_quad_share_a_chart_as_large_as_the_quad() {
        let flat = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z, 4, Vec3::ONE);
        let scene = prepare(flat).unwrap().0;
        let atlas = generate_atlas(&scene, 10.0).unwrap();
        let mut members = vec![Vec::new(); scene.triangles.len()];
        for (t, &c) in atlas.chart_of.iter().enumerate() {
            members[c as usize].push(t);
        }
        assert_eq!(members.iter().filter(|m| !m.is_empty()).count(), 16);
        for pair in members.iter().filter(|m| !m.is_empty()) {
            let &[a, b] = pair.as_slice() else {
                panic!("chart of {pair:?}")
            };
            // Shared vertices sit at one place in the atlas: no seam along the diagonal.
            let mut shared = 0;
            for (i, v) in scene.triangles[a].iter().enumerate() {
                if let Some(j) = scene.triangles[b].iter().position(|w| w == v) {
                    let gap = atlas.corners[a][i].distance(atlas.corners[b][j]);
                    assert!(gap < 1e-4, "{gap}");
                    shared += 1;
                }
            }
            assert_eq!(shared, 2);
            // The 0.5 x 0.5 cell at 10 texels a unit, turned square to the axes.
            let points = || atlas.corners[a].iter().chain(&atlas.corners[b]);
            let lo = points().fold(Vec2::INFINITY, |m, &p| m.min(p));
            let hi = points().fold(Vec2::NEG_INFINITY, |m, &p| m.max(p));
            assert!(
                ((hi - lo) - Vec2::splat(5.0)).abs().max_element() < 1e-3,
                "{lo} {hi}"
            );
        }
    }

    #[test]
    fn atlas_is_about_square_and_deterministic() {
        let scene = assorted_scene();
        let atlas = generate_atlas(&scene, 20.0).unwrap();
        let (w, h) = (atlas.width as f32, atlas.height as f32);
        assert!(w / h < 1.5 && h / w < 1.5, "{w} x {h}");
        assert_eq!(atlas, generate_atlas(&scene, 20.0).unwrap());
    }

    #[test]
    fn tiny_triangles_get_a_minimum_chart() {
        let scene = assorted_scene();
        let atlas = generate_atlas(&scene, 1.0).unwrap();
        for corners in &atlas.corners {
            let longest = edge_lengths_2d(*corners).into_iter().fold(0.0, f32::max);
            assert!(longest >= MIN_CHART_EDGE * 0.999, "{longest}");
        }
    }

    #[test]
    fn density_for_size_hits_the_target() {
        let scene = assorted_scene();
        for target in [256, 1000, 4096] {
            let density = texels_per_unit_for_size(&scene, target).unwrap();
            let atlas = generate_atlas(&scene, density).unwrap();
            let side = atlas.width.max(atlas.height);
            assert!(side <= target, "{side} > {target}");
            assert!(side as f32 >= 0.95 * target as f32, "{side} << {target}");
        }
    }

    #[test]
    fn absurd_requests_are_one_line_errors() {
        let scene = assorted_scene();
        let errors = [
            generate_atlas(&scene, 1e6).unwrap_err(),
            generate_atlas(&scene, 0.0).unwrap_err(),
            generate_atlas(&scene, f32::NAN).unwrap_err(),
            generate_atlas(&scene, f32::INFINITY).unwrap_err(),
            texels_per_unit_for_size(&scene, 0).unwrap_err(),
            texels_per_unit_for_size(&scene, MAX_ATLAS_SIZE + 1).unwrap_err(),
            // 42 charts of at least 3 x 1 texels, 5 x 3 with gutters, do not fit in 16 x 16.
            texels_per_unit_for_size(&scene, 16).unwrap_err(),
            generate_atlas(&Scene::default(), 1.0).unwrap_err(),
            generate_atlas(&scene_of(&[[Vec3::NAN, Vec3::X, Vec3::Y]]), 1.0).unwrap_err(),
        ];
        for e in errors {
            let message = e.to_string();
            assert!(!message.contains('\n'), "{message}");
        }
        let mut bad_index = scene_of(&[[Vec3::ZERO, Vec3::X, Vec3::Y]]);
        bad_index.triangles[0][2] = 7;
        assert!(generate_atlas(&bad_index, 1.0).is_err());
    }

    #[test]
    fn a_point_triangle_gets_a_texel() {
        let scene = scene_of(&[[Vec3::ONE, Vec3::ONE, Vec3::ONE]]);
        let atlas = generate_atlas(&scene, 4.0).unwrap();
        let g = GUTTER as f32 + 0.5;
        assert_eq!(atlas.corners[0], [Vec2::splat(g); 3]);
        assert_eq!(
            (atlas.width, atlas.height),
            (2 * GUTTER + 1, 2 * GUTTER + 1)
        );
    }
}
