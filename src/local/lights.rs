//! Point and spot lights inside the scene, and the direct light they give each receiver.
//!
//! Radiometry: a point light of intensity `I` (W/sr, the same in every direction) gives a
//! surface at distance `r` whose normal makes angle `theta` with the direction to the light
//! the irradiance `E = I cos(theta) / r^2` where it is visible; a Lambertian surface of albedo
//! `rho` then leaves with radiance `rho E / pi`. A spot light is a point light whose intensity
//! is `I` inside a cone about its direction and 0 outside (a hard edge).

use glam::Vec3;
use rayon::prelude::*;

use super::depth::{visibility, DepthLookup, DirectionGrid};
use crate::bvh::Bvh;
use crate::error::{Error, Result};
use crate::ray::Ray;

/// A light at a point of the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalLight {
    pub position: Vec3,
    /// Radiant intensity, W/sr.
    pub intensity: f32,
    pub spot: Option<Spot>,
}

/// A spot light's cone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// Unit direction the cone opens towards.
    pub direction: Vec3,
    /// Cosine of the cone's half angle.
    pub cos_half_angle: f32,
}

impl LocalLight {
    pub fn point(position: Vec3, intensity: f32) -> Self {
        LocalLight {
            position,
            intensity,
            spot: None,
        }
    }

    /// Checks that the light is finite, its intensity non-negative and any cone sensible.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: String| Err(Error::Options(what));
        if !self.position.is_finite() || !self.intensity.is_finite() || self.intensity < 0.0 {
            return bad(format!(
                "light at {} of intensity {}: need a finite position and an intensity >= 0",
                self.position, self.intensity
            ));
        }
        if let Some(spot) = self.spot {
            let unit = (spot.direction.length() - 1.0).abs() < 1e-3;
            if !unit || !(-1.0..=1.0).contains(&spot.cos_half_angle) {
                return bad(format!(
                    "spot light at {}: its direction must be a unit vector and its half angle \
                     within 0 to 180 degrees",
                    self.position
                ));
            }
        }
        Ok(())
    }

    /// Intensity towards `point` (the cone's edge is hard).
    pub fn intensity_towards(&self, point: Vec3) -> f32 {
        match self.spot {
            None => self.intensity,
            Some(spot) => {
                let out = (point - self.position).normalize_or_zero();
                if out.dot(spot.direction) >= spot.cos_half_angle {
                    self.intensity
                } else {
                    0.0
                }
            }
        }
    }

    /// Unshadowed irradiance at a surface point with unit normal `normal`: `I cos / r^2`.
    pub fn unshadowed_irradiance(&self, point: Vec3, normal: Vec3) -> f32 {
        let to_light = self.position - point;
        let r2 = to_light.length_squared();
        if r2 == 0.0 {
            return 0.0;
        }
        let cosine = normal.dot(to_light) / r2.sqrt();
        if cosine <= 0.0 {
            return 0.0;
        }
        self.intensity_towards(point) * cosine / r2
    }
}

/// What the direct light of a receiver depends on: where it is, where its rays start, and
/// its tangent frame (the depth maps' frame).
pub struct ReceiverFrames<'a> {
    pub positions: &'a [Vec3],
    pub normals: &'a [Vec3],
    pub origins: &'a [Vec3],
    pub frames: &'a [[Vec3; 3]],
}

/// Irradiance at every receiver from `lights`: each light's unshadowed irradiance times
/// `visible(receiver, light)` (asked only where the light reaches the receiver's front).
fn irradiance_with(
    receivers: &ReceiverFrames,
    lights: &[LocalLight],
    visible: impl Fn(usize, &LocalLight) -> f32 + Sync,
) -> Vec<f32> {
    (0..receivers.positions.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|p| {
            lights
                .iter()
                .map(|light| {
                    let open =
                        light.unshadowed_irradiance(receivers.positions[p], receivers.normals[p]);
                    if open == 0.0 {
                        0.0
                    } else {
                        open * visible(p, light)
                    }
                })
                .sum()
        })
        .collect()
}

/// Irradiance at every receiver from `lights`, visibility from the depth maps.
pub fn irradiance_from_depth(
    receivers: &ReceiverFrames,
    lookup: &dyn DepthLookup,
    grid: &DirectionGrid,
    lights: &[LocalLight],
) -> Vec<f32> {
    irradiance_with(receivers, lights, |p, light| {
        let origin = receivers.origins[p];
        visibility(
            lookup,
            grid,
            p,
            &receivers.frames[p],
            origin,
            light.position,
        )
    })
}

/// Whether the segment from a receiver's ray origin to `light` is blocked: the shadow ray
/// the depth maps stand in for.
pub fn shadow_ray_blocked(bvh: &Bvh, origin: Vec3, light: Vec3) -> bool {
    let to_light = light - origin;
    let distance = to_light.length();
    distance > 0.0 && bvh.occluded(&Ray::new(origin, to_light / distance), distance)
}

/// Irradiance at every receiver from `lights` with a real shadow ray per receiver and light:
/// the reference the depth maps are tested against.
pub fn irradiance_by_shadow_rays(
    receivers: &ReceiverFrames,
    bvh: &Bvh,
    lights: &[LocalLight],
) -> Vec<f32> {
    irradiance_with(receivers, lights, |p, light| {
        if shadow_ray_blocked(bvh, receivers.origins[p], light.position) {
            0.0
        } else {
            1.0
        }
    })
}

/// Direct exit radiance `rho E / pi` per receiver, RGB.
pub fn direct_radiance(irradiance: &[f32], albedo: &[Vec3]) -> Vec<Vec3> {
    irradiance
        .iter()
        .zip(albedo)
        .map(|(&e, &rho)| rho * (e / std::f32::consts::PI))
        .collect()
}

/// Parses `X,Y,Z[,I]` (intensity 1 when left out).
pub fn parse_point_light(text: &str) -> Result<LocalLight> {
    let v = numbers(text, "--point-light")?;
    let light = match v[..] {
        [x, y, z] => LocalLight::point(Vec3::new(x, y, z), 1.0),
        [x, y, z, i] => LocalLight::point(Vec3::new(x, y, z), i),
        _ => {
            return Err(Error::Options(format!(
                "--point-light {text:?}: expected X,Y,Z[,INTENSITY]"
            )))
        }
    };
    light.validate().map(|_| light)
}

/// Parses `X,Y,Z,DX,DY,DZ,ANGLE[,I]`: position, the direction the cone opens towards (any
/// length), the cone's half angle in degrees, the intensity (1 when left out).
pub fn parse_spot_light(text: &str) -> Result<LocalLight> {
    let v = numbers(text, "--spot-light")?;
    if !(7..=8).contains(&v.len()) {
        return Err(Error::Options(format!(
            "--spot-light {text:?}: expected X,Y,Z,DX,DY,DZ,HALF_ANGLE_DEGREES[,INTENSITY]"
        )));
    }
    let direction = Vec3::new(v[3], v[4], v[5]).normalize_or_zero();
    if direction == Vec3::ZERO || !(0.0..=180.0).contains(&v[6]) {
        return Err(Error::Options(format!(
            "--spot-light {text:?}: the direction must not be zero and the half angle must lie \
             in 0 to 180 degrees"
        )));
    }
    let light = LocalLight {
        position: Vec3::new(v[0], v[1], v[2]),
        intensity: v.get(7).copied().unwrap_or(1.0),
        spot: Some(Spot {
            direction,
            cos_half_angle: v[6].to_radians().cos(),
        }),
    };
    light.validate().map(|_| light)
}

fn numbers(text: &str, flag: &str) -> Result<Vec<f32>> {
    text.split(',')
        .map(|part| part.trim().parse::<f32>())
        .collect::<std::result::Result<Vec<f32>, _>>()
        .map_err(|e| Error::Options(format!("{flag} {text:?}: {e}")))
}

/// The lights of frame `frame` of `frames` on a circle: each turned about the vertical axis
/// through `centre` by `360 * frame / frames` degrees (spot directions turned with them).
pub fn on_circle(lights: &[LocalLight], centre: Vec3, frame: u32, frames: u32) -> Vec<LocalLight> {
    let angle = std::f32::consts::TAU * frame as f32 / frames.max(1) as f32;
    let turn = glam::Quat::from_rotation_y(angle);
    lights
        .iter()
        .map(|light| LocalLight {
            position: centre + turn * (light.position - centre),
            spot: light.spot.map(|spot| Spot {
                direction: turn * spot.direction,
                ..spot
            }),
            ..*light
        })
        .collect()
}

/// One line naming the lights, for reports and the relit file.
pub fn describe(lights: &[LocalLight]) -> String {
    lights
        .iter()
        .map(|l| {
            let p = l.position;
            match l.spot {
                None => format!("point light at {},{},{} of intensity {} W/sr", p.x, p.y, p.z, l.intensity),
                Some(s) => format!(
                    "spot light at {},{},{} towards {},{},{}, half angle {:.1} deg, intensity {} W/sr",
                    p.x,
                    p.y,
                    p.z,
                    s.direction.x,
                    s.direction.y,
                    s.direction.z,
                    s.cos_half_angle.clamp(-1.0, 1.0).acos().to_degrees(),
                    l.intensity
                ),
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn irradiance_falls_with_the_square_of_distance_and_the_cosine() {
        let light = LocalLight::point(Vec3::new(0.0, 2.0, 0.0), 8.0);
        let up = Vec3::Y;
        assert!((light.unshadowed_irradiance(Vec3::ZERO, up) - 2.0).abs() < 1e-6);
        // 60 degrees off the normal at distance 2: 8 * 0.5 / 4.
        let tilted = Vec3::new(3f32.sqrt() / 2.0, 0.5, 0.0);
        assert!((light.unshadowed_irradiance(Vec3::ZERO, tilted) - 1.0).abs() < 1e-5);
        assert_eq!(light.unshadowed_irradiance(Vec3::ZERO, -up), 0.0);
    }

    #[test]
    fn a_spot_lights_only_its_cone() {
        let mut light = LocalLight::point(Vec3::new(0.0, 1.0, 0.0), 1.0);
        light.spot = Some(Spot {
            direction: -Vec3::Y,
            cos_half_angle: (30f32).to_radians().cos(),
        });
        assert!(light.validate().is_ok());
        assert_eq!(light.intensity_towards(Vec3::new(0.5, 0.0, 0.0)), 1.0);
        assert_eq!(light.intensity_towards(Vec3::new(0.6, 0.0, 0.0)), 0.0);
        light.intensity = f32::NAN;
        assert!(light.validate().is_err());
    }

    #[test]
    fn lights_parse_and_bad_ones_are_one_line_errors() {
        let point = parse_point_light("1,2,3").unwrap();
        assert_eq!(
            (point.position, point.intensity),
            (Vec3::new(1.0, 2.0, 3.0), 1.0)
        );
        let spot = parse_spot_light("0,1,0,0,-2,0,60,5").unwrap();
        let cone = spot.spot.unwrap();
        assert_eq!((cone.direction, spot.intensity), (-Vec3::Y, 5.0));
        assert!((cone.cos_half_angle - 0.5).abs() < 1e-6);
        for bad in ["1,2", "1,2,3,-1", "a,b,c", "1,2,3,4,5", "1,2,3,nan"] {
            let error = parse_point_light(bad).unwrap_err().to_string();
            assert!(!error.contains('\n'), "{error}");
        }
        for bad in ["0,1,0,0,0,0,30", "0,1,0,0,-1,0,200", "0,1,0,0,-1,0"] {
            assert!(parse_spot_light(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_circle_turns_lights_about_the_vertical_axis() {
        let mut light = LocalLight::point(Vec3::new(3.0, 1.0, 2.0), 1.0);
        light.spot = Some(Spot {
            direction: Vec3::X,
            cos_half_angle: 0.5,
        });
        let centre = Vec3::new(1.0, 5.0, 2.0);
        let quarter = on_circle(&[light], centre, 1, 4)[0];
        // A quarter turn about +Y takes +X to -Z.
        assert!((quarter.position - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-5);
        assert!((quarter.spot.unwrap().direction - Vec3::NEG_Z).length() < 1e-5);
        assert_eq!(on_circle(&[light], centre, 0, 4)[0], light);
    }
}
