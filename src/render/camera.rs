//! The camera: a pinhole looking at a target, its automatic framing of a mesh, and its
//! command-line form.

use std::str::FromStr;

use glam::{Mat4, Vec3};

use crate::error::{Error, Result};
use crate::scene::Scene;

/// Vertical field of view of framed and parsed cameras unless one is given.
pub const DEFAULT_FOV_DEG: f32 = 40.0;

/// The framing view direction: from the front (+Z, where glTF models face) and a little to the
/// right and above, the usual three-quarter product shot.
const FRAMING_AZIMUTH_DEG: f32 = 35.0;
const FRAMING_ELEVATION_DEG: f32 = 25.0;
/// Room left around the bounding sphere, so silhouettes do not touch the image border.
const FRAMING_MARGIN: f32 = 1.1;

/// A pinhole camera, right-handed world, looking from `eye` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub vertical_fov_deg: f32,
}

impl Camera {
    /// A three-quarter view (Y up) that fits the bounding sphere of the box in a square image
    /// (wider images get more room at the sides), aimed at the box centre.
    pub fn framing(bounds_min: Vec3, bounds_max: Vec3) -> Camera {
        let center = (bounds_min + bounds_max) * 0.5;
        let radius = usable_radius((bounds_max - bounds_min).length() * 0.5, center);
        let half_fov = (DEFAULT_FOV_DEG * 0.5).to_radians();
        let distance = FRAMING_MARGIN * radius / half_fov.sin();
        let (azimuth, elevation) = (
            FRAMING_AZIMUTH_DEG.to_radians(),
            FRAMING_ELEVATION_DEG.to_radians(),
        );
        let direction = Vec3::new(
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
            elevation.cos() * azimuth.cos(),
        );
        Camera {
            eye: center + direction * distance,
            target: center,
            up: Vec3::Y,
            vertical_fov_deg: DEFAULT_FOV_DEG,
        }
    }

    /// Frames every position of `scene` (see [`Camera::framing`]).
    pub fn framing_scene(scene: &Scene) -> Camera {
        let (min, max) = bounds(&scene.positions);
        Camera::framing(min, max)
    }

    /// Refuses cameras that give no image: non-finite values, eye on the target, zero up
    /// vector, field of view outside (0, 180) degrees.
    pub fn validate(&self) -> Result<()> {
        let finite = self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && self.vertical_fov_deg.is_finite();
        if !finite {
            return Err(Error::Options(format!(
                "camera: every value must be finite (eye {}, target {}, up {}, fov {})",
                self.eye, self.target, self.up, self.vertical_fov_deg
            )));
        }
        if (self.target - self.eye).length_squared() == 0.0 || self.up.length_squared() == 0.0 {
            return Err(Error::Options(
                "camera: eye equals target, or up is zero".to_string(),
            ));
        }
        if !(self.vertical_fov_deg > 0.0 && self.vertical_fov_deg < 180.0) {
            return Err(Error::Options(format!(
                "camera: field of view {} must lie in (0, 180) degrees",
                self.vertical_fov_deg
            )));
        }
        Ok(())
    }

    /// World to clip space for wgpu (WebGPU NDC: Y up, depth 0 at `near`, 1 at `far`).
    pub fn clip_from_world(&self, aspect: f32, near: f32, far: f32) -> Mat4 {
        use glam::camera::rh::{proj::directx, view};
        let projection =
            directx::perspective(self.vertical_fov_deg.to_radians(), aspect, near, far);
        projection * view::look_at_mat4(self.eye, self.target, self.usable_up())
    }

    /// The camera's unit forward, right and up vectors (right-handed: right = forward x up).
    pub fn view_basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.usable_up()).normalize();
        (forward, right, right.cross(forward))
    }

    /// `up` unless it is parallel to the view direction (looking straight down, say), where
    /// look-at would divide by zero; then any perpendicular-enough axis does.
    fn usable_up(&self) -> Vec3 {
        let forward = (self.target - self.eye).normalize();
        [self.up.normalize(), Vec3::Z, Vec3::X]
            .into_iter()
            .find(|up| forward.cross(*up).length() > 1e-3)
            .unwrap_or(Vec3::Y)
    }
}

/// Parses `eye_x,eye_y,eye_z,target_x,target_y,target_z[,fov_deg]` (Y up).
impl FromStr for Camera {
    type Err = Error;

    fn from_str(text: &str) -> Result<Camera> {
        let numbers = text
            .split(',')
            .map(|part| part.trim().parse::<f32>())
            .collect::<std::result::Result<Vec<f32>, _>>()
            .map_err(|e| Error::Options(format!("camera {text:?}: {e}")))?;
        let camera = match numbers[..] {
            [ex, ey, ez, tx, ty, tz] => (ex, ey, ez, tx, ty, tz, DEFAULT_FOV_DEG),
            [ex, ey, ez, tx, ty, tz, fov] => (ex, ey, ez, tx, ty, tz, fov),
            _ => {
                return Err(Error::Options(format!(
                    "camera {text:?}: expected eye_x,eye_y,eye_z,target_x,target_y,target_z[,fov]"
                )))
            }
        };
        let (ex, ey, ez, tx, ty, tz, fov) = camera;
        let camera = Camera {
            eye: Vec3::new(ex, ey, ez),
            target: Vec3::new(tx, ty, tz),
            up: Vec3::Y,
            vertical_fov_deg: fov,
        };
        camera.validate()?;
        Ok(camera)
    }
}

/// A positive radius even for a single point, so framing any finite box gives a camera that
/// `validate` accepts.
pub(super) fn usable_radius(radius: f32, center: Vec3) -> f32 {
    let floor = 1e-3 * center.abs().max_element().max(1.0);
    if radius.is_finite() {
        radius.max(floor)
    } else {
        1.0
    }
}

/// Axis-aligned bounds of `positions` (an empty slice gives the origin).
pub fn bounds(positions: &[Vec3]) -> (Vec3, Vec3) {
    if positions.is_empty() {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    crate::scene::bounds_of(positions)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_centres_the_mesh_and_keeps_it_in_view() {
        let (min, max) = (Vec3::new(3.0, -1.0, 10.0), Vec3::new(5.0, 4.0, 11.0));
        let camera = Camera::framing(min, max);
        camera.validate().unwrap();
        let center = (min + max) * 0.5;
        assert_eq!(camera.target, center);
        // A three-quarter view: in front (+Z), to the right (+X) and above.
        let offset = camera.eye - center;
        assert!(offset.x > 0.0 && offset.y > 0.0 && offset.z > offset.x);
        let clip = camera.clip_from_world(1.0, 0.1, 100.0);
        let ndc = clip.project_point3(center);
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5, "{ndc}");
        for i in 0..8 {
            let corner = Vec3::select(
                glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0),
                max,
                min,
            );
            let p = clip.project_point3(corner);
            assert!(p.x.abs() < 1.0 && p.y.abs() < 1.0, "corner {corner} at {p}");
        }
    }

    #[test]
    fn framing_a_point_still_gives_a_valid_camera() {
        Camera::framing(Vec3::ONE, Vec3::ONE).validate().unwrap();
        Camera::framing(Vec3::ZERO, Vec3::splat(f32::INFINITY))
            .validate()
            .unwrap_err();
    }

    #[test]
    fn camera_parses_from_the_command_line_form() {
        let camera: Camera = "0,1,5, 0,0,0".parse().unwrap();
        assert_eq!(camera.eye, Vec3::new(0.0, 1.0, 5.0));
        assert_eq!(camera.target, Vec3::ZERO);
        assert_eq!(camera.up, Vec3::Y);
        assert_eq!(camera.vertical_fov_deg, DEFAULT_FOV_DEG);
        let wide: Camera = "1,2,3,4,5,6,75".parse().unwrap();
        assert_eq!(wide.vertical_fov_deg, 75.0);
        for bad in [
            "",
            "1,2,3",
            "1,2,3,4,5,6,7,8",
            "a,0,0,0,0,0",
            "0,0,0,0,0,0",
            "0,0,1,0,0,0,180",
            "0,0,1,0,0,0,NaN",
        ] {
            assert!(bad.parse::<Camera>().is_err(), "{bad:?} was accepted");
        }
    }

    #[test]
    fn looking_straight_down_still_has_a_view() {
        let camera: Camera = "0,5,0,0,0,0".parse().unwrap();
        let m = camera.clip_from_world(1.0, 0.1, 10.0);
        assert!(m.is_finite());
        assert!(m.project_point3(Vec3::ZERO).truncate().length() < 1e-5);
    }
}
