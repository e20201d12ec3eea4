//! A chart laid flat with little distortion: least-squares conformal maps (Lévy et al. 2002).
//!
//! The map from the surface to the plane is conformal on a triangle when the gradient of `v` is
//! the gradient of `u` turned a quarter: `grad v = R90 grad u`. Over the triangle's own flat
//! coordinates the gradients are linear in the corners' `(u, v)`, so the area-weighted squared
//! mismatch summed over the chart is a least-squares problem in the vertices' coordinates. Two
//! vertices far apart are pinned where the chart's projection on its mean plane puts them (the
//! energy is zero for any similarity, so two pins fix position, turn and scale), and conjugate
//! gradients, preconditioned by the diagonal and started from that projection, find the rest.
//!
//! The result is kept where every triangle keeps its winding and the boundary does not cross
//! itself; otherwise the projection is (its triangles cannot flip: the chart's normals lie in
//! an open hemisphere, `segment`), under the same check. A chart neither passes is returned as
//! `None` for the caller to split. Coordinates are scaled so the flat area equals the surface
//! area.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::segment::Surface;
use crate::scene::Scene;

/// Conjugate-gradient steps at most per chart, beyond the vertex count's square root times
/// this: a map stopped early is still checked, and only less conformal.
const MAX_STEPS_PER_ROOT: usize = 40;

/// Stop once the residual has fallen this far below where the projection left it.
const TOLERANCE: f64 = 1e-8;

/// The flat corners of each triangle of `chart` (in its order), in scene units, or `None`
/// where neither the conformal map nor the projection lays it flat without folds.
pub fn flatten(scene: &Scene, surface: &Surface, chart: &[u32]) -> Option<Vec<[DVec2; 3]>> {
    let patch = Patch::of(scene, surface, chart);
    let projected = patch.projection(surface, chart);
    let mut conformal = projected.clone();
    if patch.triangles.len() > 1 {
        patch.solve_conformal(&mut conformal);
    }
    [conformal, projected]
        .into_iter()
        .find(|uv| patch.lies_flat(uv))
        .map(|uv| patch.corners_at_true_area(&uv))
}

/// A chart's triangles over its own vertices (joined by position), with the data the energy
/// needs.
struct Patch {
    positions: Vec<DVec3>,
    triangles: Vec<[usize; 3]>,
    /// Per triangle, the gradients of its corners' barycentric functions in the triangle's own
    /// flat frame, times the square root of its area: the energy's rows.
    gradients: Vec<[DVec2; 3]>,
    areas: Vec<f64>,
}

impl Patch {
    fn of(scene: &Scene, surface: &Surface, chart: &[u32]) -> Patch {
        let mut local: HashMap<u32, usize> = HashMap::new();
        let mut positions = Vec::new();
        let triangles: Vec<[usize; 3]> = chart
            .iter()
            .map(|&t| {
                scene.triangles[t as usize].map(|v| {
                    let w = surface.welded[v as usize];
                    *local.entry(w).or_insert_with(|| {
                        positions.push(scene.positions[w as usize].as_dvec3());
                        positions.len() - 1
                    })
                })
            })
            .collect();
        let mut gradients = Vec::with_capacity(triangles.len());
        let mut areas = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let flat = own_frame(t.map(|v| positions[v]));
            let twice_area = (flat[1] - flat[0]).perp_dot(flat[2] - flat[0]);
            areas.push(0.5 * twice_area);
            gradients.push(if twice_area > 0.0 {
                let weight = (0.5 * twice_area).sqrt() / twice_area;
                [0, 1, 2].map(|j| (flat[(j + 2) % 3] - flat[(j + 1) % 3]).perp() * weight)
            } else {
                [DVec2::ZERO; 3]
            });
        }
        Patch {
            positions,
            triangles,
            gradients,
            areas,
        }
    }

    /// The vertices projected on the plane of the chart's area-weighted mean normal.
    fn projection(&self, surface: &Surface, chart: &[u32]) -> Vec<DVec2> {
        let mean = chart
            .iter()
            .map(|&t| surface.normals[t as usize] * surface.areas[t as usize])
            .sum::<DVec3>()
            .normalize_or_zero();
        let normal = if mean == DVec3::ZERO { DVec3::Z } else { mean };
        let (e1, e2) = normal.any_orthonormal_pair();
        self.positions
            .iter()
            .map(|p| DVec2::new(p.dot(e1), p.dot(e2)))
            .collect()
    }

    /// The conformal energy's residual rows for coordinates `uv` (two per triangle).
    fn residual(&self, uv: &[DVec2], rows: &mut [DVec2]) {
        for ((t, g), row) in self.triangles.iter().zip(&self.gradients).zip(rows) {
            // grad u = sum u_j g_j, grad v = sum v_j g_j; residual grad v - R90 grad u.
            *row = (0..3)
                .map(|j| {
                    let (u, v) = (uv[t[j]].x, uv[t[j]].y);
                    DVec2::new(v * g[j].x + u * g[j].y, v * g[j].y - u * g[j].x)
                })
                .sum();
        }
    }

    /// The residual rows carried back to the vertices (the transpose of [`Self::residual`]).
    fn gather(&self, rows: &[DVec2], out: &mut [DVec2]) {
        out.fill(DVec2::ZERO);
        for ((t, g), r) in self.triangles.iter().zip(&self.gradients).zip(rows) {
            for j in 0..3 {
                out[t[j]] += DVec2::new(r.x * g[j].y - r.y * g[j].x, r.x * g[j].x + r.y * g[j].y);
            }
        }
    }

    /// Minimises the conformal energy over `uv`, two vertices held where `uv` has them.
    fn solve_conformal(&self, uv: &mut [DVec2]) {
        let n = uv.len();
        let pins = farthest_pair(uv);
        let mut diagonal = vec![0.0; n];
        for (t, g) in self.triangles.iter().zip(&self.gradients) {
            for j in 0..3 {
                diagonal[t[j]] += g[j].length_squared();
            }
        }
        let free = |i: usize| i != pins.0 && i != pins.1 && diagonal[i] > 0.0;
        let mut rows = vec![DVec2::ZERO; self.triangles.len()];
        let mut step = vec![DVec2::ZERO; n];
        // Minus half the gradient of the energy, zero at the pins.
        let mut residual = vec![DVec2::ZERO; n];
        self.residual(uv, &mut rows);
        self.gather(&rows, &mut residual);
        for (i, r) in residual.iter_mut().enumerate() {
            *r = if free(i) { -*r } else { DVec2::ZERO };
        }
        let precondition = |r: &[DVec2], z: &mut Vec<DVec2>| {
            z.clear();
            z.extend(r.iter().zip(&diagonal).map(
                |(r, &d)| {
                    if d > 0.0 {
                        *r / d
                    } else {
                        DVec2::ZERO
                    }
                },
            ));
        };
        let mut z = Vec::with_capacity(n);
        precondition(&residual, &mut z);
        let dot = |a: &[DVec2], b: &[DVec2]| a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum::<f64>();
        let mut direction = z.clone();
        let mut rz = dot(&residual, &z);
        let start = rz;
        let steps = MAX_STEPS_PER_ROOT * ((n as f64).sqrt() as usize + 1);
        for _ in 0..steps {
            // Also stops on NaN: a chart that broke the solve fails the flatness check.
            if rz.is_nan() || rz <= TOLERANCE * TOLERANCE * start {
                break;
            }
            self.residual(&direction, &mut rows);
            let curvature: f64 = rows.iter().map(|r| r.length_squared()).sum();
            if curvature.is_nan() || curvature <= 0.0 {
                break;
            }
            self.gather(&rows, &mut step);
            let alpha = rz / curvature;
            for i in 0..n {
                uv[i] += alpha * direction[i];
                residual[i] -= if free(i) {
                    alpha * step[i]
                } else {
                    DVec2::ZERO
                };
            }
            precondition(&residual, &mut z);
            let next = dot(&residual, &z);
            let beta = next / rz;
            rz = next;
            for i in 0..n {
                direction[i] = z[i] + beta * direction[i];
            }
        }
    }

    /// Whether `uv` keeps every triangle's winding (and more than a sliver of its area) and its
    /// boundary never crosses itself: the chart lies flat without folds or overlaps.
    fn lies_flat(&self, uv: &[DVec2]) -> bool {
        if uv.iter().any(|p| !p.is_finite()) {
            return false;
        }
        let flat_area: f64 = self.triangles.iter().map(|t| signed_area(t, uv)).sum();
        let true_area: f64 = self.areas.iter().sum();
        // A triangle may shrink, not turn over: its flat area over its true one, in units of
        // the chart's, stays above this.
        const LEAST_SCALE: f64 = 1e-6;
        let keeps_winding = self.triangles.iter().zip(&self.areas).all(|(t, &area)| {
            area <= 0.0 || signed_area(t, uv) * true_area > LEAST_SCALE * area * flat_area
        });
        keeps_winding && flat_area > 0.0 && !boundary_crosses(&self.triangles, uv)
    }

    /// Each triangle's corners, the coordinates scaled so the flat area is the true area.
    fn corners_at_true_area(&self, uv: &[DVec2]) -> Vec<[DVec2; 3]> {
        let flat: f64 = self.triangles.iter().map(|t| signed_area(t, uv)).sum();
        let true_area: f64 = self.areas.iter().sum();
        let scale = if flat > 0.0 && true_area > 0.0 {
            (true_area / flat).sqrt()
        } else {
            1.0
        };
        self.triangles
            .iter()
            .map(|t| t.map(|v| uv[v] * scale))
            .collect()
    }
}

/// A triangle's corners in its own plane: the first at the origin, the second along +x, the
/// third above (counter-clockwise).
pub(super) fn own_frame([a, b, c]: [DVec3; 3]) -> [DVec2; 3] {
    let along = (b - a).normalize_or_zero();
    let normal = (b - a).cross(c - a);
    let up = normal.cross(b - a).normalize_or_zero();
    [
        DVec2::ZERO,
        DVec2::new((b - a).length(), 0.0),
        DVec2::new((c - a).dot(along), (c - a).dot(up)),
    ]
}

fn signed_area(t: &[usize; 3], uv: &[DVec2]) -> f64 {
    0.5 * (uv[t[1]] - uv[t[0]]).perp_dot(uv[t[2]] - uv[t[0]])
}

/// Two points far apart: the extremes along the longer side of the points' box.
fn farthest_pair(uv: &[DVec2]) -> (usize, usize) {
    let (lo, hi) = uv
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let axis = if hi.x - lo.x >= hi.y - lo.y {
        DVec2::X
    } else {
        DVec2::Y
    };
    let key = |i: &usize| uv[*i].dot(axis);
    let by = |a: &usize, b: &usize| key(a).total_cmp(&key(b));
    let first = (0..uv.len()).min_by(by).unwrap_or(0);
    let last = (0..uv.len()).max_by(by).unwrap_or(0);
    (first, last)
}

/// Whether two edges of the chart's boundary (edges of one triangle only) that share no vertex
/// meet, looked up through a grid of about one edge's length.
fn boundary_crosses(triangles: &[[usize; 3]], uv: &[DVec2]) -> bool {
    let mut count: HashMap<(usize, usize), u32> = HashMap::new();
    for t in triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut boundary: Vec<(usize, usize)> = count
        .into_iter()
        .filter(|&(_, n)| n == 1)
        .map(|(edge, _)| edge)
        .collect();
    boundary.sort_unstable();
    if boundary.len() < 4 {
        return false;
    }
    let length: f64 = boundary
        .iter()
        .map(|&(a, b)| uv[a].distance(uv[b]))
        .sum::<f64>()
        / boundary.len() as f64;
    let cell = length.max(f64::MIN_POSITIVE);
    let cell_of = |p: DVec2| ((p.x / cell).floor() as i64, (p.y / cell).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    for (e, &(a, b)) in boundary.iter().enumerate() {
        let (lo, hi) = (cell_of(uv[a].min(uv[b])), cell_of(uv[a].max(uv[b])));
        // A degenerate map can put an edge over countless cells; it is not flat anyway.
        if (hi.0 - lo.0 + 1) * (hi.1 - lo.1 + 1) > 4096 {
            return true;
        }
        for x in lo.0..=hi.0 {
            for y in lo.1..=hi.1 {
                grid.entry((x, y)).or_default().push(e as u32);
            }
        }
    }
    grid.values().any(|edges| {
        edges.iter().enumerate().any(|(i, &e)| {
            edges[i + 1..].iter().any(|&f| {
                let (a, b) = boundary[e as usize];
                let (c, d) = boundary[f as usize];
                let shared = a == c || a == d || b == c || b == d;
                !shared && segments_meet(uv[a], uv[b], uv[c], uv[d])
            })
        })
    })
}

/// Whether the closed segments `ab` and `cd` meet.
fn segments_meet(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let side = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (d1, d2) = (side(c, d, a), side(c, d, b));
    let (d3, d4) = (side(a, b, c), side(a, b, d));
    let within = |p: DVec2, q: DVec2, r: DVec2| {
        r.x >= p.x.min(q.x) && r.x <= p.x.max(q.x) && r.y >= p.y.min(q.y) && r.y <= p.y.max(q.y)
    };
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    (d1 == 0.0 && within(c, d, a))
        || (d2 == 0.0 && within(c, d, b))
        || (d3 == 0.0 && within(a, b, c))
        || (d4 == 0.0 && within(a, b, d))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    fn whole(scene: &Scene) -> (Surface, Vec<u32>) {
        (
            Surface::of(scene),
            (0..scene.triangles.len() as u32).collect(),
        )
    }

    /// Per triangle, the singular values of the map from the surface to the plane.
    fn singular_values(scene: &Scene, chart: &[u32], flat: &[[DVec2; 3]]) -> Vec<(f64, f64)> {
        chart
            .iter()
            .zip(flat)
            .map(|(&t, uv)| {
                let own = own_frame(
                    scene.triangles[t as usize].map(|v| scene.positions[v as usize].as_dvec3()),
                );
                let (e1, e2) = (own[1] - own[0], own[2] - own[0]);
                let (f1, f2) = (uv[1] - uv[0], uv[2] - uv[0]);
                let det = e1.x * e2.y - e1.y * e2.x;
                // J maps own-frame to flat: [f1 f2] = J [e1 e2].
                let inv = [[e2.y / det, -e2.x / det], [-e1.y / det, e1.x / det]];
                let j = [
                    [
                        f1.x * inv[0][0] + f2.x * inv[1][0],
                        f1.x * inv[0][1] + f2.x * inv[1][1],
                    ],
                    [
                        f1.y * inv[0][0] + f2.y * inv[1][0],
                        f1.y * inv[0][1] + f2.y * inv[1][1],
                    ],
                ];
                let (a, b, c, d) = (j[0][0], j[0][1], j[1][0], j[1][1]);
                let s = a * a + b * b + c * c + d * d;
                let root = ((a * a + b * b - c * c - d * d).powi(2)
                    + 4.0 * (a * c + b * d).powi(2))
                .sqrt();
                (
                    ((s + root) / 2.0).sqrt(),
                    ((s - root).max(0.0) / 2.0).sqrt(),
                )
            })
            .collect()
    }

    #[test]
    fn a_flat_grid_keeps_its_shape() {
        let scene = prepare(builtin::grid_plane(
            Vec3::ZERO,
            Vec3::X,
            Vec3::Z,
            6,
            Vec3::ONE,
        ))
        .unwrap()
        .0;
        let (surface, chart) = whole(&scene);
        let flat = flatten(&scene, &surface, &chart).unwrap();
        for (s1, s2) in singular_values(&scene, &chart, &flat) {
            assert!(
                (s1 - 1.0).abs() < 1e-9 && (s2 - 1.0).abs() < 1e-9,
                "{s1} {s2}"
            );
        }
    }

    #[test]
    fn a_cap_of_a_sphere_is_nearer_conformal_than_its_projection() {
        // The triangles of an icosphere above 40 degrees of latitude.
        let sphere = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 4)).unwrap().0;
        let surface = Surface::of(&sphere);
        let cap: Vec<u32> = (0..sphere.triangles.len() as u32)
            .filter(|&t| surface.normals[t as usize].y > 0.64)
            .collect();
        let patch = Patch::of(&sphere, &surface, &cap);
        let projected = patch.projection(&surface, &cap);
        let mut conformal = projected.clone();
        patch.solve_conformal(&mut conformal);
        let ratio = |uv: &[DVec2]| {
            let flat = patch.corners_at_true_area(uv);
            let values = singular_values(&sphere, &cap, &flat);
            values.iter().map(|(a, b)| a / b).fold(0.0, f64::max)
        };
        let (conformal, projected) = (ratio(&conformal), ratio(&projected));
        assert!(conformal < 1.05, "angle distortion {conformal}");
        assert!(projected > 1.2, "projection's {projected}");
        assert!(patch.lies_flat(&patch_uv(&patch, &surface, &cap)));
    }

    fn patch_uv(patch: &Patch, surface: &Surface, chart: &[u32]) -> Vec<DVec2> {
        let mut uv = patch.projection(surface, chart);
        patch.solve_conformal(&mut uv);
        uv
    }

    #[test]
    fn true_area_is_kept() {
        let sphere = prepare(builtin::icosphere(Vec3::ZERO, 2.0, 3)).unwrap().0;
        let surface = Surface::of(&sphere);
        let cap: Vec<u32> = (0..sphere.triangles.len() as u32)
            .filter(|&t| surface.normals[t as usize].z > 0.5)
            .collect();
        let flat = flatten(&sphere, &surface, &cap).unwrap();
        let flat_area: f64 = flat
            .iter()
            .map(|c| 0.5 * (c[1] - c[0]).perp_dot(c[2] - c[0]))
            .sum();
        let true_area: f64 = cap.iter().map(|&t| surface.areas[t as usize]).sum();
        assert!((flat_area / true_area - 1.0).abs() < 1e-9);
    }

    #[test]
    fn folds_and_crossings_are_seen() {
        let square = [
            DVec2::ZERO,
            DVec2::X,
            DVec2::ONE,
            DVec2::Y,
            DVec2::new(0.5, 0.5),
        ];
        let fan: Vec<[usize; 3]> = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        let patch = |uv: &[DVec2]| Patch {
            positions: uv.iter().map(|p| p.extend(0.0)).collect(),
            triangles: fan.clone(),
            gradients: vec![[DVec2::ZERO; 3]; 4],
            areas: vec![0.25; 4],
        };
        assert!(patch(&square).lies_flat(&square));
        let mut folded = square;
        folded[4] = DVec2::new(1.5, 0.5);
        assert!(!patch(&square).lies_flat(&folded));
        assert!(segments_meet(DVec2::ZERO, DVec2::ONE, DVec2::X, DVec2::Y));
        assert!(!segments_meet(DVec2::ZERO, DVec2::X, DVec2::Y, DVec2::ONE));
        // A strip of triangles wound round onto itself: no triangle turns over, the boundary
        // crosses.
        let mut spiral = Vec::new();
        let mut strip = Vec::new();
        for i in 0..=24 {
            let angle = i as f64 * 0.35;
            let radius = 1.0 + 0.01 * i as f64;
            spiral.push(DVec2::from_angle(angle) * radius);
            spiral.push(DVec2::from_angle(angle) * (radius + 0.3));
            if i > 0 {
                let (a, b, c, d) = (2 * i - 2, 2 * i - 1, 2 * i, 2 * i + 1);
                strip.push([a, b, c]);
                strip.push([b, d, c]);
            }
        }
        assert!(strip.iter().all(|t| signed_area(t, &spiral) > 0.0));
        assert!(boundary_crosses(&strip, &spiral));
        assert!(!boundary_crosses(&strip[..20], &spiral));
    }
}
