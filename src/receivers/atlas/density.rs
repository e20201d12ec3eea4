//! Texels where the light changes: a chart near other geometry gets a denser share of the
//! atlas.
//!
//! Near an occluder the transfer changes over about the distance to it: under a scan's fin
//! folded onto the surface, at a crease's mouth, where one part stands on another. Ward's
//! irradiance cache spaces its records by the same measure, the harmonic mean distance `R` to
//! the geometry a point sees. A chart's texels are made finer by `texel / R` (its area's mean of
//! `1 / R`), at least 1 and at most [`MAX_DENSITY_GAIN`], so that where the light steps within a
//! texel of the uniform atlas, the texels shrink towards that step. Away from other geometry
//! (a convex mesh, an open floor) every gain is 1 and the atlas is the uniform one.

use rayon::prelude::*;

use crate::bvh::Bvh;
use crate::ray::Ray;
use crate::sampling::{cosine_hemisphere, tangent_frame};
use crate::scene::Scene;

/// The most a chart's texels per unit length are multiplied by. Measured on dragon_vrip_res3 at
/// 1024² (docs/performance.md, "Texels where the light changes").
pub const MAX_DENSITY_GAIN: f64 = 4.0;

/// Cosine-weighted rays from each triangle's centroid that measure its distance to other
/// geometry.
pub const DISTANCE_RAYS: u32 = 32;

/// How far the rays reach, in texels of the uniform atlas: a hit farther adds less than
/// `1 / REACH_TEXELS` to a chart's gain, which counts only above 1, and long rays are most of
/// the cost on a large scan.
pub const REACH_TEXELS: f64 = 32.0;

/// Where the rays start above the centroid, as a fraction of the scene's extent: clear of the
/// triangle itself, well below any texel.
const RAY_LIFT: f32 = 1e-5;

/// Per triangle of `scene`, the mean over [`DISTANCE_RAYS`] cosine-weighted directions about its
/// face normal of one over the distance to the nearest surface (0 for a ray that meets none
/// within `reach`, or a triangle of no area): one over the harmonic mean distance.
pub fn inverse_distances(scene: &Scene, reach: f32) -> Vec<f64> {
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let lift = RAY_LIFT * bvh.extent();
    let nearest = lift as f64;
    let directions = cosine_hemisphere(DISTANCE_RAYS, 0xd15);
    scene
        .triangles
        .par_iter()
        .map(|triangle| {
            let [a, b, c] = triangle.map(|v| scene.positions[v as usize]);
            let Some(normal) = (b - a).cross(c - a).try_normalize() else {
                return 0.0;
            };
            let [tangent, bitangent, normal] = tangent_frame(normal);
            let origin = (a + b + c) / 3.0 + normal * lift;
            let sum: f64 = directions
                .directions
                .iter()
                .filter_map(|d| {
                    let direction = tangent * d.x + bitangent * d.y + normal * d.z;
                    let (_, hit) = bvh.closest_hit(&Ray::new(origin, direction), reach)?;
                    Some(1.0 / (hit.t as f64).max(nearest))
                })
                .sum();
            sum / directions.directions.len() as f64
        })
        .collect()
}

/// Per chart (its triangles), what its texel density is multiplied by: `texel_length` (of
/// the uniform atlas) times the area-weighted mean of its triangles' `inverse_distances`,
/// within `[1, MAX_DENSITY_GAIN]`. `areas` are the triangles' areas.
pub fn density_gains(
    charts: impl Iterator<Item = impl IntoIterator<Item = u32>>,
    (inverse_distances, areas): (&[f64], &[f64]),
    texel_length: f64,
) -> Vec<f64> {
    charts
        .map(|triangles| {
            let (mut area, mut weighted) = (0.0, 0.0);
            for t in triangles {
                area += areas[t as usize];
                weighted += areas[t as usize] * inverse_distances[t as usize];
            }
            let mean = if area > 0.0 { weighted / area } else { 0.0 };
            (texel_length * mean).clamp(1.0, MAX_DENSITY_GAIN)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Two 1 x 1 squares facing each other `gap` apart along z, and a third far off.
    fn facing_squares(gap: f32) -> Scene {
        let square = |z: f32, up: bool, x: f32| {
            let p = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
                .map(|[u, v]| Vec3::new(u + x, v, z));
            (p, up)
        };
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for (p, up) in [
            square(0.0, true, 0.0),
            square(gap, false, 0.0),
            square(0.0, true, 10.0),
        ] {
            let base = positions.len() as u32;
            positions.extend(p);
            let quad = if up {
                [[0, 1, 2], [0, 2, 3]]
            } else {
                [[0, 2, 1], [0, 3, 2]]
            };
            triangles.extend(quad.map(|t| t.map(|i| i + base)));
        }
        Scene {
            albedo: vec![Vec3::ONE; positions.len()],
            normals: None,
            positions,
            triangles,
        }
    }

    #[test]
    fn a_surface_facing_another_sees_it_near_and_an_open_one_sees_nothing() {
        let gap = 0.01;
        let inverse = inverse_distances(&facing_squares(gap as f32), 1.0);
        // The facing squares' centroids see each other `gap / cos` away (a cosine-weighted
        // mean of `cos / gap`: two thirds of `1 / gap`; a few grazing rays slip out past the
        // edges).
        for (t, &x) in inverse[..4].iter().enumerate() {
            assert!(x > 0.5 / gap && x < 1.0 / gap, "triangle {t}: {x}");
        }
        assert_eq!(&inverse[4..], &[0.0, 0.0], "the far square sees nothing");
        // Within a reach shorter than the gap, nothing is seen.
        let short = inverse_distances(&facing_squares(gap as f32), 0.5 * gap as f32);
        assert!(short.iter().all(|&x| x == 0.0), "{short:?}");
    }

    #[test]
    fn gains_follow_the_texel_over_the_distance_within_their_bounds() {
        let areas = [1.0, 3.0, 1.0];
        let inverse = [10.0, 2.0, 0.0];
        let charts = [vec![0u32, 1], vec![2], vec![0]];
        let gains = density_gains(charts.iter().cloned(), (&inverse, &areas), 0.5);
        // Chart 0: the area-weighted mean (10 + 6) / 4 = 4, times 0.5.
        assert_eq!(gains, vec![2.0, 1.0, MAX_DENSITY_GAIN]);
    }

    #[test]
    fn charts_facing_each_other_get_the_most_texels_and_an_open_one_the_uniform_share() {
        // At 10 texels a unit a texel is 0.1 long, ten times the gap: the facing squares' gain
        // is capped, the far square's is 1.
        let scene = facing_squares(0.01);
        let atlas = super::super::generate_atlas(&scene, 10.0).unwrap();
        let texels_a_unit = |t: usize| {
            let [a, b, _] = scene.triangles[t].map(|v| scene.positions[v as usize]);
            let flat = atlas.corners[t][1] - atlas.corners[t][0];
            flat.length() as f64 / (b - a).length() as f64
        };
        for t in 0..4 {
            let density = texels_a_unit(t);
            assert!(
                (density - 10.0 * MAX_DENSITY_GAIN).abs() < 1e-3,
                "triangle {t}: {density}"
            );
        }
        for t in 4..6 {
            assert!((texels_a_unit(t) - 10.0).abs() < 1e-3, "triangle {t}");
        }
    }
}
