//! Charts: the triangles of a scene grouped into connected patches of similar orientation, each
//! to be laid flat on its own.
//!
//! A chart grows from a seed across edges shared by exactly two triangles wound the same way
//! (through the edge in opposite directions), taking a neighbour while its normal stays within
//! a cone about the chart's area-weighted mean normal and within [`SEED_CONE`] of the seed's.
//! The second bound keeps every chart inside an open hemisphere: it cannot close on itself (a
//! sphere, a tube), and projecting it on the plane of its mean normal never flips a triangle,
//! so it can always be laid flat. Seeds are taken in triangle order, neighbours first in
//! first out, so the charts are a pure function of the scene.
//!
//! Vertices are joined by position, not index: a prepared scene keeps apart the copies of a
//! vertex whose attributes differ (an albedo seam), and a chart may cross them.

use std::collections::{HashMap, VecDeque};

use glam::DVec3;

use crate::scene::Scene;

/// The widest a chart's normals may stray from its first triangle's, in radians (80 degrees).
pub const SEED_CONE: f64 = 80.0 * std::f64::consts::PI / 180.0;

/// The connectivity a chart grows over, built once per scene.
pub struct Surface {
    /// Per scene vertex, the index of the first vertex at its position.
    pub welded: Vec<u32>,
    /// Per triangle, its unit face normal (zero for a degenerate triangle) and its area.
    pub normals: Vec<DVec3>,
    pub areas: Vec<f64>,
    /// Per triangle, the triangles across its edges that a chart may cross to.
    neighbours: Vec<Vec<u32>>,
}

impl Surface {
    pub fn of(scene: &Scene) -> Surface {
        let welded = weld_by_position(scene);
        let mut normals = Vec::with_capacity(scene.triangles.len());
        let mut areas = Vec::with_capacity(scene.triangles.len());
        for t in &scene.triangles {
            let [a, b, c] = t.map(|v| scene.positions[v as usize].as_dvec3());
            let cross = (b - a).cross(c - a);
            areas.push(0.5 * cross.length());
            normals.push(cross.normalize_or_zero());
        }
        let neighbours = neighbours(&welded, &scene.triangles);
        Surface {
            welded,
            normals,
            areas,
            neighbours,
        }
    }
}

/// Per vertex of `scene`, the index of the first vertex at its position: vertices joined by
/// position, where a prepared scene keeps apart copies whose attributes differ.
fn weld_by_position(scene: &Scene) -> Vec<u32> {
    let mut first: HashMap<[u32; 3], u32> = HashMap::new();
    scene
        .positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            // +0.0 and -0.0 are one position.
            let key = p.to_array().map(|c| (c + 0.0).to_bits());
            *first.entry(key).or_insert(v as u32)
        })
        .collect()
}

/// Per triangle, the triangles sharing an edge with it where exactly two triangles share that
/// edge and pass it in opposite directions (a manifold edge between consistently wound faces).
fn neighbours(welded: &[u32], triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    // Keyed by the edge's ends, lower first; each entry the triangle and whether it passes
    // the edge from the lower end.
    let mut by_edge: HashMap<(u32, u32), Vec<(u32, bool)>> = HashMap::new();
    for (t, corners) in triangles.iter().enumerate() {
        let w = corners.map(|v| welded[v as usize]);
        for i in 0..3 {
            let (from, to) = (w[i], w[(i + 1) % 3]);
            if from != to {
                by_edge
                    .entry((from.min(to), from.max(to)))
                    .or_default()
                    .push((t as u32, from < to));
            }
        }
    }
    let mut neighbours = vec![Vec::new(); triangles.len()];
    for sharing in by_edge.values() {
        if let &[(a, forward_a), (b, forward_b)] = sharing.as_slice() {
            if forward_a != forward_b && a != b {
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
    }
    // The map's order must not reach the charts.
    for list in &mut neighbours {
        list.sort_unstable();
    }
    neighbours
}

/// The charts of the triangles `members` (ascending), grown within them only: each a list of
/// triangles in the order they joined, the seed first. `cone` bounds the angle between a
/// member's normal and the chart's mean normal as the member joins (radians).
pub fn grow_charts(surface: &Surface, members: &[u32], cone: f64) -> Vec<Vec<u32>> {
    let mut allowed = HashMap::with_capacity(members.len());
    for &t in members {
        allowed.insert(t, true);
    }
    let (cos_cone, cos_seed) = (cone.cos(), SEED_CONE.min(cone).cos());
    let mut charts = Vec::new();
    let mut queue = VecDeque::new();
    for &seed in members {
        if allowed.get(&seed) != Some(&true) {
            continue;
        }
        allowed.insert(seed, false);
        let seed_normal = surface.normals[seed as usize];
        let mut sum = seed_normal * surface.areas[seed as usize];
        let mut chart = vec![seed];
        queue.clear();
        queue.extend(surface.neighbours[seed as usize].iter().copied());
        while let Some(t) = queue.pop_front() {
            if allowed.get(&t) != Some(&true) {
                continue;
            }
            let normal = surface.normals[t as usize];
            let joins = normal.dot(seed_normal) >= cos_seed
                && normal.dot(sum.normalize_or_zero()) >= cos_cone;
            if joins {
                allowed.insert(t, false);
                sum += normal * surface.areas[t as usize];
                chart.push(t);
                queue.extend(surface.neighbours[t as usize].iter().copied());
            }
        }
        charts.push(chart);
    }
    adopt_lone_triangles(surface, &mut charts, cos_seed);
    charts
}

/// Moves each chart of one triangle into the neighbouring chart whose seed's normal is nearest
/// its own, where that is within the seed cone: a triangle that joined no chart (its
/// neighbours' charts grew away from it) would otherwise cost the atlas a chart and a gutter
/// ring of its own.
fn adopt_lone_triangles(surface: &Surface, charts: &mut Vec<Vec<u32>>, cos_seed: f64) {
    let mut chart_of: HashMap<u32, usize> = HashMap::new();
    for (c, chart) in charts.iter().enumerate() {
        for &t in chart {
            chart_of.insert(t, c);
        }
    }
    for c in 0..charts.len() {
        let &[t] = charts[c].as_slice() else {
            continue;
        };
        let normal = surface.normals[t as usize];
        let adopter = surface.neighbours[t as usize]
            .iter()
            .filter_map(|n| chart_of.get(n).copied())
            .filter(|&other| other != c && charts[other].len() > 1)
            .map(|other| {
                (
                    normal.dot(surface.normals[charts[other][0] as usize]),
                    other,
                )
            })
            .filter(|&(agreement, _)| agreement >= cos_seed)
            .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
        if let Some((_, other)) = adopter {
            charts[c].clear();
            charts[other].push(t);
            chart_of.insert(t, other);
        }
    }
    charts.retain(|chart| !chart.is_empty());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    fn charts_of(scene: &Scene, cone_degrees: f64) -> Vec<Vec<u32>> {
        let surface = Surface::of(scene);
        let all: Vec<u32> = (0..scene.triangles.len() as u32).collect();
        grow_charts(&surface, &all, cone_degrees.to_radians())
    }

    #[test]
    fn a_box_falls_into_its_six_faces() {
        let scene = prepare(builtin::closed_box(Vec3::ZERO, Vec3::new(2.0, 1.0, 3.0), 4))
            .unwrap()
            .0;
        let charts = charts_of(&scene, 40.0);
        assert_eq!(charts.len(), 6);
        let surface = Surface::of(&scene);
        for chart in &charts {
            let n = surface.normals[chart[0] as usize];
            assert!(chart
                .iter()
                .all(|&t| surface.normals[t as usize].dot(n) > 0.999));
        }
        let mut all: Vec<u32> = charts.concat();
        all.sort_unstable();
        assert_eq!(all, (0..scene.triangles.len() as u32).collect::<Vec<_>>());
    }

    #[test]
    fn a_sphere_is_cut_into_charts_within_the_seed_cone() {
        let scene = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 3)).unwrap().0;
        let surface = Surface::of(&scene);
        for cone in [30.0, 60.0, 90.0] {
            let charts = charts_of(&scene, cone);
            assert!(charts.len() >= 2, "a closed surface in one chart");
            for chart in &charts {
                let seed = surface.normals[chart[0] as usize];
                for &t in chart {
                    let angle = surface.normals[t as usize]
                        .dot(seed)
                        .clamp(-1.0, 1.0)
                        .acos();
                    assert!(angle <= SEED_CONE.min(cone.to_radians()) + 1e-9);
                }
            }
        }
        // A wider cone makes fewer charts.
        assert!(charts_of(&scene, 60.0).len() < charts_of(&scene, 30.0).len());
    }

    #[test]
    fn charts_do_not_cross_non_manifold_or_flipped_edges() {
        // A fin: three triangles on one edge; and a triangle wound against its neighbour.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 0.0, 1.0),
        ];
        let scene = Scene {
            positions: p.to_vec(),
            normals: None,
            albedo: vec![Vec3::ONE; 5],
            triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        };
        let charts = charts_of(&scene, 89.0);
        assert_eq!(charts.len(), 3, "{charts:?}");
        let flipped = Scene {
            triangles: vec![[0, 1, 2], [0, 1, 3]],
            ..scene
        };
        assert_eq!(charts_of(&flipped, 89.0).len(), 2);
    }

    #[test]
    fn copies_of_a_vertex_are_one_point_of_the_surface() {
        // Two coplanar triangles sharing an edge through distinct copies of its vertices.
        let scene = Scene {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::X,
                Vec3::Y,
                Vec3::new(1.0, 1.0, 0.0),
            ],
            normals: None,
            albedo: vec![Vec3::ONE; 6],
            triangles: vec![[0, 1, 2], [3, 5, 4]],
        };
        assert_eq!(charts_of(&scene, 10.0), vec![vec![0, 1]]);
    }
}
