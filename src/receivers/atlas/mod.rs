//! A lightmap atlas generated for a prepared scene: meshes need not carry UVs, so the baker
//! cuts the surface into charts, lays each flat and packs them.
//!
//! - Charts (`segment`): connected patches whose normals stay within [`CHART_CONE`] of their
//!   mean, grown across manifold edges; a flat region is one chart, a box six.
//! - Laying flat (`flatten`): least-squares conformal maps, so texels keep their shape; a
//!   chart that would fold or overlap itself is cut in two, again and again, down to single
//!   triangles where need be, which always lie flat. Each chart keeps its true area at the
//!   texel density (times its gain, below) and is turned to its smallest bounding box; a tiny
//!   chart is enlarged until its box's longer side spans [`MIN_CHART_EDGE`] texels, so that
//!   every chart gets texels of its own.
//! - Density (`density`): a chart near other geometry, where the light changes within a short
//!   distance, gets up to [`density::MAX_DENSITY_GAIN`] times the texels per unit length.
//! - Packing (`pack`): by the texels each chart meets, on a skyline, charts largest first,
//!   each turned a quarter where that keeps it lower; small charts first into the room the
//!   large ones leave (under their overhangs, above their slopes). Every chart is kept [`GUTTER`] empty
//!   texels away from the others and from the border, so neither bilinear filtering nor
//!   dilation ([`super::texels::dilate`]) mixes two charts.
//!
//! Texel `(x, y)` covers `[x, x+1) x [y, y+1)` in the atlas' texel units; its centre is
//! `(x + 0.5, y + 0.5)`.

pub mod density;
mod flatten;
mod pack;
mod segment;

use glam::{DVec2, Vec2};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::scene::Scene;
use pack::{pack, placed_corners, Placement, TexelChart};
use segment::Surface;

/// The largest atlas side accepted (texels): larger would not fit a GPU texture.
pub const MAX_ATLAS_SIZE: u32 = 16384;

/// Empty texels kept between any two charts and between a chart and the border. Two: the ring
/// one texel around a chart (the reach of bilinear filtering) is then filled by dilation from
/// that chart alone, never from a neighbour.
pub const GUTTER: u32 = 2;

/// The shortest the longer side of a chart's box may be, in texels.
pub const MIN_CHART_EDGE: f32 = 2.0;

/// The widest a chart's normals may stray from its mean normal as it grows, in radians (50
/// degrees): wide enough that a smooth scan falls into large charts, narrow enough that laying
/// them flat stretches little.
pub const CHART_CONE: f64 = 50.0 * std::f64::consts::PI / 180.0;

/// A packed atlas: its size and every triangle's corners in it.
#[derive(Clone, Debug, PartialEq)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    /// Per triangle (in the scene's order), the atlas positions of its three corners, in texel
    /// units.
    pub corners: Vec<[Vec2; 3]>,
    /// Per triangle, the chart it lies in.
    pub chart_of: Vec<u32>,
}

impl Atlas {
    /// How many charts the atlas holds.
    pub fn chart_count(&self) -> usize {
        self.chart_of.iter().max().map_or(0, |&c| c as usize + 1)
    }

    /// The L2 stretch of the atlas over `scene`'s surface (Sander et al. 2001): the root mean
    /// square, over the surface, of the singular values of the map from the atlas to the
    /// surface, each chart at its own mean scale. 1 where every texel covers the same square of
    /// surface; more where texels are drawn out in some direction or, across a chart, grow and
    /// shrink (surface is then undersampled somewhere). Triangles of no area, on the surface or
    /// in the atlas, are left out.
    pub fn stretch(&self, scene: &Scene) -> f64 {
        let charts = self.chart_count();
        let (mut surface_area, mut flat_area) = (vec![0.0; charts], vec![0.0; charts]);
        let mut squares = vec![0.0; charts];
        for ((t, corners), &chart) in scene
            .triangles
            .iter()
            .zip(&self.corners)
            .zip(&self.chart_of)
        {
            let [a, b, c] = t.map(|v| scene.positions[v as usize].as_dvec3());
            let (e1, e2) = (b - a, c - a);
            let twice_area = e1.cross(e2).length();
            let [p, q, r] = corners.map(|c| c.as_dvec2());
            let (f1, f2) = (q - p, r - p);
            let twice_flat = f1.perp_dot(f2).abs();
            if !(twice_area > 0.0 && twice_flat > 0.0) {
                continue;
            }
            // The squared singular values' sum of the map to the atlas, trace of
            // (F^T F)(E^T E)^-1; the map back has the reciprocal values, whose squares sum to
            // that over the squared determinant.
            let sum = (f1.length_squared() * e2.length_squared() - 2.0 * f1.dot(f2) * e1.dot(e2)
                + f2.length_squared() * e1.length_squared())
                / (twice_area * twice_area);
            let determinant = twice_flat / twice_area;
            let sum_back = sum / (determinant * determinant);
            let c = chart as usize;
            surface_area[c] += 0.5 * twice_area;
            flat_area[c] += 0.5 * twice_flat;
            squares[c] += 0.5 * twice_area * sum_back / 2.0;
        }
        let total: f64 = surface_area.iter().sum();
        if total <= 0.0 {
            return 1.0;
        }
        // Per chart, the mean square over its area times its mean scale squared.
        let weighted: f64 = (0..charts)
            .filter(|&c| surface_area[c] > 0.0)
            .map(|c| squares[c] * (flat_area[c] / surface_area[c]))
            .sum();
        (weighted / total).sqrt()
    }
}

/// A chart laid flat in scene units: its triangles and their corners, turned to its smallest
/// bounding box, whose lower corner is at the origin.
#[derive(Clone, Debug, PartialEq)]
struct FlatChart {
    triangles: Vec<u32>,
    corners: Vec<[DVec2; 3]>,
    size: DVec2,
}

/// Cuts `scene` into charts and packs them at `texels_per_unit` texels per scene unit of
/// length (more near other geometry, [`density`]), in an atlas about square. Refuses
/// densities that are not positive and finite, scenes without triangles or with non-finite
/// positions, and atlases over [`MAX_ATLAS_SIZE`] a side.
pub fn generate_atlas(scene: &Scene, texels_per_unit: f32) -> Result<Atlas> {
    check_density(texels_per_unit)?;
    let (charts, areas) = lay_out_charts(scene)?;
    let gains = chart_gains(scene, (&charts, &areas), 1.0 / texels_per_unit as f64);
    let texel_charts = at_density(&charts, texels_per_unit as f64, &gains);
    let cells: f64 = texel_charts
        .iter()
        .map(|c| (c.size.x + 1.0 + GUTTER as f64) * (c.size.y + 1.0 + GUTTER as f64))
        .sum();
    let widest = texel_charts
        .iter()
        .map(|c| c.size.x.min(c.size.y))
        .fold(0.0, f64::max);
    let width = cells.sqrt().max(widest + 2.0).ceil() as u64 + 2 * GUTTER as u64 + 1;
    if width > MAX_ATLAS_SIZE as u64 {
        return Err(too_large(width, width));
    }
    let (placements, width, height) =
        pack(&texel_charts, width as u32).ok_or_else(|| too_large(width, width))?;
    if height > MAX_ATLAS_SIZE {
        return Err(too_large(width as u64, height as u64));
    }
    Ok(assemble(
        scene,
        &charts,
        &texel_charts,
        &placements,
        width,
        height,
    ))
}

/// Cuts `scene` into charts and packs them at the highest density whose atlas fits `target`
/// texels a side (its width that, its height at most that), charts near other geometry
/// denser by their gains ([`density`]) against the uniform atlas of that size. Refuses a
/// target of zero or over [`MAX_ATLAS_SIZE`], one too small for the charts' minimum size and
/// gutters at any density, and scenes [`generate_atlas`] refuses.
pub fn atlas_for_size(scene: &Scene, target: u32) -> Result<Atlas> {
    if target == 0 || target > MAX_ATLAS_SIZE {
        return Err(Error::Options(format!(
            "lightmap size must be between 1 and {MAX_ATLAS_SIZE} texels, not {target}"
        )));
    }
    let (charts, areas) = lay_out_charts(scene)?;
    let too_small = || {
        Error::Options(format!(
            "a lightmap of {target} texels a side is too small for the {} charts of {} \
             triangles with their gutters",
            charts.len(),
            scene.triangles.len(),
        ))
    };
    let uniform = vec![1.0; charts.len()];
    let guess = filling_density(&charts, &uniform, target);
    let (uniform_density, fitted) =
        densest_fit(&charts, &uniform, target, (guess, 2.0)).ok_or_else(too_small)?;
    let gains = chart_gains(scene, (&charts, &areas), 1.0 / uniform_density);
    let (texel_charts, placements, height) = if gains == uniform {
        fitted
    } else {
        // The uniform search's density, scaled as the boxes' filling density is: within a few
        // percent of the answer, so the search steps by 5% rather than doubling.
        let scaled = filling_density(&charts, &gains, target) / guess;
        let near = (uniform_density * scaled, 1.05);
        densest_fit(&charts, &gains, target, near)
            .ok_or_else(too_small)?
            .1
    };
    Ok(assemble(
        scene,
        &charts,
        &texel_charts,
        &placements,
        target,
        height,
    ))
}

/// Charts scaled to texels and packed: their texel charts, placements and the atlas' height.
type Fitted = (Vec<TexelChart>, Vec<Placement>, u32);

/// The highest density (within 1%) at which `charts`, each at the density times its gain,
/// pack into an atlas `target` texels wide and at most that high, and the charts so packed;
/// searched from `guess` by factors of `step` either way, then by halving the bracket.
fn densest_fit(
    charts: &[FlatChart],
    gains: &[f64],
    target: u32,
    (guess, step): (f64, f64),
) -> Option<(f64, Fitted)> {
    let fits = |density: f64| -> Option<Fitted> {
        let texel_charts = at_density(charts, density, gains);
        let (placements, _, height) = pack(&texel_charts, target)?;
        (height <= target).then_some((texel_charts, placements, height))
    };
    let (mut low, mut high) = (guess, guess);
    let mut at_low = None;
    for _ in 0..64 {
        at_low = fits(low);
        if at_low.is_some() || low / step <= 0.0 {
            break;
        }
        low /= step;
    }
    for _ in 0..64 {
        if fits(high).is_none() || !(high * step).is_finite() {
            break;
        }
        high *= step;
    }
    while high > low * 1.01 {
        let middle = (low * high).sqrt();
        match fits(middle) {
            Some(fitted) => (low, at_low) = (middle, Some(fitted)),
            None => high = middle,
        }
    }
    at_low.map(|fitted| (low, fitted))
}

/// The charts' boxes (each side times its gain) filling a square `target` texels a side: the
/// density a search starts from.
fn filling_density(charts: &[FlatChart], gains: &[f64], target: u32) -> f64 {
    let area: f64 = charts
        .iter()
        .zip(gains)
        .map(|(c, g)| c.size.x * c.size.y * g * g)
        .sum();
    target as f64 / area.sqrt().max(1e-30)
}

/// Per chart, what its density is multiplied by where it lies near other geometry
/// ([`density`]), against a uniform atlas of texels `texel_length` long; `areas` are the
/// triangles'.
fn chart_gains(
    scene: &Scene,
    (charts, areas): (&[FlatChart], &[f64]),
    texel_length: f64,
) -> Vec<f64> {
    let reach = density::REACH_TEXELS * texel_length;
    let inverse = density::inverse_distances(scene, reach as f32);
    let triangles = charts.iter().map(|c| c.triangles.iter().copied());
    density::density_gains(triangles, (&inverse, areas), texel_length)
}

fn check_density(texels_per_unit: f32) -> Result<()> {
    if texels_per_unit.is_finite() && texels_per_unit > 0.0 {
        Ok(())
    } else {
        Err(Error::Options(format!(
            "lightmap texel density must be positive and finite, not {texels_per_unit}"
        )))
    }
}

fn too_large(width: u64, height: u64) -> Error {
    Error::Options(format!(
        "lightmap atlas of about {width} x {height} texels exceeds {MAX_ATLAS_SIZE} a side; \
         lower the texel density"
    ))
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

/// The scene's charts laid flat, in the order of their first triangles, and every triangle's
/// area (the surface they were grown on already has them; the density gains weigh by them).
fn lay_out_charts(scene: &Scene) -> Result<(Vec<FlatChart>, Vec<f64>)> {
    check_scene(scene)?;
    let surface = Surface::of(scene);
    let all: Vec<u32> = (0..scene.triangles.len() as u32).collect();
    let grown = segment::grow_charts(&surface, &all, CHART_CONE);
    let laid: Vec<Vec<FlatChart>> = grown
        .par_iter()
        .map(|chart| lay_flat_or_cut(scene, &surface, chart))
        .collect();
    let mut charts: Vec<FlatChart> = laid.into_iter().flatten().collect();
    charts.sort_by_key(|c| c.triangles.iter().min().copied());
    Ok((charts, surface.areas))
}

/// `chart` laid flat, or, where it will not lie flat, cut in two and each part laid flat or
/// cut again: the first half of its triangles in the order they joined (connected, as the
/// chart grew outwards from its seed), and the rest grown into charts again.
fn lay_flat_or_cut(scene: &Scene, surface: &Surface, chart: &[u32]) -> Vec<FlatChart> {
    let flat = match chart {
        &[t] => Some(vec![flatten::own_frame(
            scene.triangles[t as usize].map(|v| scene.positions[v as usize].as_dvec3()),
        )]),
        _ => flatten::flatten(scene, surface, chart),
    };
    if let Some(corners) = flat {
        return vec![smallest_box(chart.to_vec(), corners)];
    }
    let (first, rest) = chart.split_at(chart.len() / 2);
    let mut rest = rest.to_vec();
    rest.sort_unstable();
    std::iter::once(first.to_vec())
        .chain(segment::grow_charts(surface, &rest, CHART_CONE))
        .flat_map(|part| lay_flat_or_cut(scene, surface, &part))
        .collect()
}

/// The chart turned so that its bounding box is smallest (one side of the smallest box lies
/// along an edge of the points' convex hull), its lower corner moved to the origin.
fn smallest_box(triangles: Vec<u32>, corners: Vec<[DVec2; 3]>) -> FlatChart {
    let points: Vec<DVec2> = corners.iter().flatten().copied().collect();
    let hull = convex_hull(&points);
    let mut best = (f64::INFINITY, DVec2::X);
    for (i, &p) in hull.iter().enumerate() {
        let Some(direction) = (hull[(i + 1) % hull.len()] - p).try_normalize() else {
            continue;
        };
        let [w, h] = box_extent(hull.iter().map(|&q| turn(q, direction)));
        if w * h < best.0 {
            best = (w * h, direction);
        }
    }
    let turned: Vec<[DVec2; 3]> = corners.iter().map(|c| c.map(|p| turn(p, best.1))).collect();
    let lo = turned
        .iter()
        .flatten()
        .fold(DVec2::INFINITY, |m, &p| m.min(p));
    let corners: Vec<[DVec2; 3]> = turned.iter().map(|c| c.map(|p| p - lo)).collect();
    let size = corners.iter().flatten().fold(DVec2::ZERO, |m, &p| m.max(p));
    FlatChart {
        triangles,
        corners,
        size,
    }
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

/// The convex hull of `points`, counter-clockwise (Andrew's monotone chain); fewer than three
/// points where they are.
fn convex_hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    sorted.dedup();
    if sorted.len() < 3 {
        return sorted;
    }
    let mut hull: Vec<DVec2> = Vec::with_capacity(sorted.len() + 1);
    for pass in [sorted.clone(), sorted.iter().rev().copied().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2 {
                let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                if (b - a).perp_dot(p - a) > 0.0 {
                    break;
                }
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Each chart scaled to texels: the density times its gain, or more for a chart so small that
/// its box's longer side would span fewer than [`MIN_CHART_EDGE`] texels.
fn at_density(charts: &[FlatChart], texels_per_unit: f64, gains: &[f64]) -> Vec<TexelChart> {
    charts
        .iter()
        .zip(gains)
        .map(|(chart, gain)| {
            let density = texels_per_unit * gain;
            let longest = chart.size.max_element();
            let scale = if longest > 0.0 {
                density.max(MIN_CHART_EDGE as f64 / longest)
            } else {
                density
            };
            TexelChart {
                corners: chart.corners.iter().map(|c| c.map(|p| p * scale)).collect(),
                size: chart.size * scale,
            }
        })
        .collect()
}

fn assemble(
    scene: &Scene,
    charts: &[FlatChart],
    texel_charts: &[TexelChart],
    placements: &[Placement],
    width: u32,
    height: u32,
) -> Atlas {
    let mut corners = vec![[Vec2::ZERO; 3]; scene.triangles.len()];
    let mut chart_of = vec![0; scene.triangles.len()];
    for (c, ((chart, texels), place)) in charts.iter().zip(texel_charts).zip(placements).enumerate()
    {
        let offset = DVec2::new(place.origin[0] as f64, place.origin[1] as f64);
        for (&t, flat) in chart
            .triangles
            .iter()
            .zip(placed_corners(texels, place.turned))
        {
            corners[t as usize] = flat.map(|p| (p + offset).as_vec2());
            chart_of[t as usize] = c as u32;
        }
    }
    Atlas {
        width,
        height,
        corners,
        chart_of,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    /// A prepared (welded) scene of flat charts (a grid of quads and a box) and a curved one
    /// (an icosphere).
    pub(crate) fn quad_scene() -> Scene {
        let parts = [
            builtin::grid_plane(Vec3::new(0.0, -3.0, 0.0), Vec3::X, Vec3::Z, 4, Vec3::ONE),
            builtin::closed_box(Vec3::splat(-2.0), Vec3::new(2.0, 0.5, 3.0), 3),
            builtin::icosphere(Vec3::ZERO, 1.0, 2),
        ];
        prepare(builtin::merge(&parts)).unwrap().0
    }

    /// Flat faces only: a grid of quads and a box.
    pub(crate) fn flat_scene() -> Scene {
        let parts = [
            builtin::grid_plane(Vec3::new(0.0, -3.0, 0.0), Vec3::X, Vec3::Z, 4, Vec3::ONE),
            builtin::closed_box(Vec3::splat(-2.0), Vec3::new(2.0, 0.5, 3.0), 3),
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

    /// Per chart, the longer side of its box in the atlas.
    fn chart_sides(atlas: &Atlas) -> Vec<f32> {
        let mut lo = vec![Vec2::INFINITY; atlas.chart_count()];
        let mut hi = vec![Vec2::NEG_INFINITY; atlas.chart_count()];
        for (corners, &c) in atlas.corners.iter().zip(&atlas.chart_of) {
            for &p in corners {
                lo[c as usize] = lo[c as usize].min(p);
                hi[c as usize] = hi[c as usize].max(p);
            }
        }
        lo.iter()
            .zip(&hi)
            .map(|(l, h)| (*h - *l).max_element())
            .collect()
    }

    #[test]
    fn flat_charts_keep_edge_lengths_at_the_density() {
        for scene in [assorted_scene(), flat_scene()] {
            let density = 7.0;
            let atlas = generate_atlas(&scene, density).unwrap();
            let sides = chart_sides(&atlas);
            for (t, corners) in scene.triangles.iter().enumerate() {
                let p = corners.map(|i| scene.positions[i as usize]);
                let lengths_3d = [0, 1, 2].map(|i| (p[(i + 1) % 3] - p[i]).length());
                // Enlarged charts aside, every length is the density's.
                if sides[atlas.chart_of[t] as usize] <= MIN_CHART_EDGE * 1.001 {
                    continue;
                }
                for (flat, real) in edge_lengths_2d(atlas.corners[t]).iter().zip(lengths_3d) {
                    assert!(
                        (flat - real * density).abs() <= 1e-3 * (1.0 + real * density),
                        "triangle {t}: {flat} vs {}",
                        real * density
                    );
                }
            }
        }
    }

    #[test]
    fn a_flat_grid_is_one_chart_and_a_box_six() {
        let grid = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z, 4, Vec3::ONE);
        let scene = prepare(grid).unwrap().0;
        let atlas = generate_atlas(&scene, 10.0).unwrap();
        assert_eq!(atlas.chart_count(), 1);
        // The 2 x 2 grid at 10 texels a unit: a 20-texel square, half a texel in.
        let sides = chart_sides(&atlas);
        assert!((sides[0] - 20.0).abs() < 1e-3, "{sides:?}");
        assert!((atlas.stretch(&scene) - 1.0).abs() < 1e-6);
        let cube = builtin::closed_box(Vec3::ZERO, Vec3::ONE, 3);
        let scene = prepare(cube).unwrap().0;
        let atlas = generate_atlas(&scene, 10.0).unwrap();
        assert_eq!(atlas.chart_count(), 6);
    }

    #[test]
    fn a_sphere_lies_flat_in_a_few_charts_with_little_stretch() {
        let scene = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 4)).unwrap().0;
        let atlas = atlas_for_size(&scene, 256).unwrap();
        let charts = atlas.chart_count();
        assert!((4..=40).contains(&charts), "{charts} charts");
        let stretch = atlas.stretch(&scene);
        assert!(stretch < 1.05, "stretch {stretch}");
        // No triangle turned over: the atlas keeps every chart's winding.
        for c in &atlas.corners {
            assert!((c[1] - c[0]).perp_dot(c[2] - c[0]) > 0.0);
        }
        // Covered texels over the atlas' (0.598 when written).
        let texels = super::super::texels::rasterize(&atlas);
        let used = texels.texels.len() as f64 / (atlas.width * atlas.height) as f64;
        assert!(used > 0.55, "texel use {used}");
    }

    /// A ramp winding one and a half times round an axis, rising slowly: its normals stay near
    /// the axis, so it grows as one chart, which laid flat would overlap itself.
    fn spiral_ramp() -> Scene {
        let mut triangles = Vec::new();
        let steps = 54;
        let at = |i: usize, radius: f32| {
            let angle = i as f32 / steps as f32 * 3.0 * std::f32::consts::PI;
            Vec3::new(radius * angle.cos(), 0.02 * angle, radius * angle.sin())
        };
        for i in 0..steps {
            let (a, b) = (at(i, 1.0), at(i, 1.5));
            let (c, d) = (at(i + 1, 1.0), at(i + 1, 1.5));
            triangles.push([a, c, b]);
            triangles.push([b, c, d]);
        }
        prepare(scene_of(&triangles)).unwrap().0
    }

    #[test]
    fn a_chart_that_would_overlap_itself_is_cut() {
        let scene = spiral_ramp();
        let surface = Surface::of(&scene);
        let all: Vec<u32> = (0..scene.triangles.len() as u32).collect();
        assert_eq!(segment::grow_charts(&surface, &all, CHART_CONE).len(), 1);
        let atlas = generate_atlas(&scene, 20.0).unwrap();
        assert!(atlas.chart_count() >= 2 && atlas.chart_count() <= 8);
        // No triangle's centroid lies inside another triangle of the atlas.
        let inside = |p: Vec2, c: [Vec2; 3]| {
            (0..3).all(|i| (c[(i + 1) % 3] - c[i]).perp_dot(p - c[i]) > 1e-4)
        };
        for (t, a) in atlas.corners.iter().enumerate() {
            let centroid = (a[0] + a[1] + a[2]) / 3.0;
            for (u, b) in atlas.corners.iter().enumerate() {
                assert!(u == t || !inside(centroid, *b), "{t} inside {u}");
            }
            assert!((a[1] - a[0]).perp_dot(a[2] - a[0]) > 0.0);
        }
    }

    #[test]
    fn corners_lie_inside_the_gutters() {
        for scene in [assorted_scene(), quad_scene()] {
            for density in [3.0, 4.5, 5.0, 9.0, 12.25, 17.3] {
                let atlas = generate_atlas(&scene, density).unwrap();
                let g = GUTTER as f32;
                for p in atlas.corners.iter().flatten() {
                    assert!(p.x >= g && p.y >= g, "{p}");
                    assert!(p.x <= atlas.width as f32 - g && p.y <= atlas.height as f32 - g);
                }
            }
        }
    }

    #[test]
    fn atlas_is_about_square_and_deterministic() {
        for scene in [assorted_scene(), quad_scene()] {
            let atlas = generate_atlas(&scene, 20.0).unwrap();
            let (w, h) = (atlas.width as f32, atlas.height as f32);
            assert!(w / h < 1.5 && h / w < 1.5, "{w} x {h}");
            assert_eq!(atlas, generate_atlas(&scene, 20.0).unwrap());
        }
    }

    #[test]
    fn tiny_charts_get_a_minimum_size() {
        let scene = assorted_scene();
        let atlas = generate_atlas(&scene, 1.0).unwrap();
        for side in chart_sides(&atlas) {
            assert!(side >= MIN_CHART_EDGE * 0.999, "{side}");
        }
    }

    #[test]
    fn an_atlas_for_a_size_fills_it() {
        for scene in [assorted_scene(), quad_scene()] {
            for target in [256, 1000, 4096] {
                let atlas = atlas_for_size(&scene, target).unwrap();
                assert_eq!(atlas.width, target);
                assert!(atlas.height <= target, "{} > {target}", atlas.height);
                assert!(
                    atlas.height as f32 >= 0.9 * target as f32,
                    "{} << {target}",
                    atlas.height
                );
            }
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
            atlas_for_size(&scene, 0).unwrap_err(),
            atlas_for_size(&scene, MAX_ATLAS_SIZE + 1).unwrap_err(),
            // 42 charts of at least 3 x 1 texels, 5 x 3 with gutters, do not fit in 16 x 16.
            atlas_for_size(&scene, 16).unwrap_err(),
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

    #[test]
    fn hull_and_smallest_box() {
        let square = [
            DVec2::ZERO,
            DVec2::X,
            DVec2::ONE,
            DVec2::Y,
            DVec2::splat(0.5),
        ];
        assert_eq!(convex_hull(&square).len(), 4);
        // A unit square turned 30 degrees comes back square to the axes.
        let turned = DVec2::from_angle(std::f64::consts::FRAC_PI_6);
        let corners = vec![
            [DVec2::ZERO, DVec2::X, DVec2::ONE].map(|p| turned.rotate(p)),
            [DVec2::ZERO, DVec2::ONE, DVec2::Y].map(|p| turned.rotate(p)),
        ];
        let chart = smallest_box(vec![0, 1], corners);
        assert!(
            (chart.size - DVec2::ONE).abs().max_element() < 1e-9,
            "{}",
            chart.size
        );
    }
}
