//! What moves, lit by probes: test spheres placed in a baked scene, each a diffuse ball lit
//! by the probes at its centre (interpolated on a grid, the nearest valid probe otherwise),
//! as an engine lights a dynamic object from its probe volume.

use glam::Vec3;

use crate::error::{Error, Result};
use crate::light::ShLight;
use crate::probes::ProbeSet;
use crate::scene::{builtin, Scene};

/// The albedo of a test sphere.
pub const SPHERE_ALBEDO: f32 = 0.8;
/// Subdivisions of a test sphere's icosahedron (642 vertices).
const SPHERE_SUBDIVISIONS: u32 = 3;

/// A test sphere's radius where none is given: 5% of the scene's largest side.
pub fn default_sphere_radius(scene: &Scene) -> f32 {
    0.05 * scene.extent()
}

/// The test sphere at the origin with radius 1, as `with_probe_spheres` tessellates it: the
/// web viewer draws this mesh moved and scaled.
pub fn unit_sphere() -> Scene {
    builtin::icosphere(Vec3::ZERO, 1.0, SPHERE_SUBDIVISIONS)
}

/// A test sphere: where it is and how big.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSphere {
    pub centre: Vec3,
    pub radius: f32,
}

/// The transfer at `point` a run-time uses: trilinear on a grid, else the nearest valid probe.
pub fn probes_at(probes: &ProbeSet, point: Vec3) -> Option<Vec<f32>> {
    if probes.grid.is_some() {
        return probes.interpolate(point);
    }
    let nearest = (0..probes.len())
        .filter(|&p| probes.status[p] != crate::probes::ProbeStatus::Invalid)
        .min_by(|&a, &b| {
            let distance = |p: usize| probes.positions[p].distance_squared(point);
            distance(a).total_cmp(&distance(b))
        })?;
    Some(probes.matrix(nearest).to_vec())
}

/// `scene` with `spheres` added and every vertex's radiance: `radiance` for the scene's own,
/// for a sphere's `albedo / pi` times the irradiance the probes at its centre give for the
/// vertex's normal under `light`.
pub fn with_probe_spheres(
    scene: &Scene,
    radiance: Vec<[f32; 3]>,
    probes: &ProbeSet,
    spheres: &[ProbeSphere],
    light: &ShLight,
) -> Result<(Scene, Vec<[f32; 3]>)> {
    if light.bands < probes.bands {
        return Err(Error::Options(format!(
            "the light has {} bands and the probes {}",
            light.bands, probes.bands
        )));
    }
    let mut parts = vec![scene.clone()];
    let mut radiance = radiance;
    for sphere in spheres {
        let matrix = probes_at(probes, sphere.centre).ok_or_else(|| {
            Error::Options(format!(
                "no valid probe lights a sphere at {},{},{}",
                sphere.centre.x, sphere.centre.y, sphere.centre.z
            ))
        })?;
        let mut ball = builtin::icosphere(sphere.centre, sphere.radius, SPHERE_SUBDIVISIONS);
        let normals: Vec<Vec3> = ball
            .positions
            .iter()
            .map(|&p| (p - sphere.centre).normalize_or(Vec3::Y))
            .collect();
        for &n in &normals {
            let e = probes.irradiance(&matrix, &light.coeffs, n.as_dvec3());
            let scale = SPHERE_ALBEDO as f64 / std::f64::consts::PI;
            radiance.push(e.map(|e| (scale * e) as f32));
        }
        ball.albedo = vec![Vec3::splat(SPHERE_ALBEDO); normals.len()];
        ball.normals = Some(normals);
        parts.push(ball);
    }
    Ok((builtin::merge(&parts), radiance))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::probes::ProbeStatus;

    #[test]
    fn a_sphere_under_a_constant_sky_shows_its_albedo_times_the_sky() {
        let light = ShLight::constant(2, [1.0, 0.5, 0.25]);
        let sphere = ProbeSphere {
            centre: Vec3::new(3.0, 1.0, 0.0),
            radius: 0.5,
        };
        let scene = builtin::icosphere(Vec3::ZERO, 1.0, 1);
        let own = vec![[9.0; 3]; scene.positions.len()];
        let (merged, radiance) =
            with_probe_spheres(&scene, own, &ProbeSet::open_sky(2), &[sphere], &light).unwrap();
        assert_eq!(merged.positions.len(), radiance.len());
        assert_eq!(
            radiance[..scene.positions.len()],
            vec![[9.0; 3]; scene.positions.len()]
        );
        for value in &radiance[scene.positions.len()..] {
            for (c, expected) in [1.0, 0.5, 0.25].iter().enumerate() {
                let expected = SPHERE_ALBEDO * expected;
                assert!((value[c] - expected).abs() < 1e-5, "{value:?}");
            }
        }
    }

    #[test]
    fn a_sphere_with_no_valid_probe_is_refused() {
        let mut probes = ProbeSet::open_sky(2);
        probes.status[0] = ProbeStatus::Invalid;
        let sphere = ProbeSphere {
            centre: Vec3::ZERO,
            radius: 1.0,
        };
        let light = ShLight::constant(2, [1.0; 3]);
        let scene = builtin::icosphere(Vec3::ZERO, 1.0, 0);
        let own = vec![[0.0; 3]; scene.positions.len()];
        let refused = with_probe_spheres(&scene, own, &probes, &[sphere], &light).unwrap_err();
        assert!(refused.to_string().contains("no valid probe"), "{refused}");
    }
}
