//! The sky behind the model: each background pixel shows the light's radiance in the direction
//! its camera ray leaves, as a sky dome does. The light drawn is the SH light the model is lit
//! by (after rotation and windowing), so the backdrop and the shading always agree; it is as
//! smooth as the light's band count.

use glam::{DVec3, Vec4};

use super::camera::Camera;
use crate::light::ShLight;
use crate::sh::{coeff_count, eval_basis};

/// Radiance of `light` arriving from `direction` (unit), clamped at zero (ringing).
pub fn sky_radiance(light: &ShLight, direction: DVec3) -> [f32; 3] {
    let mut basis = vec![0.0; coeff_count(light.bands)];
    eval_basis(light.bands, direction, &mut basis);
    let mut rgb = [0.0f64; 3];
    for (y, l) in basis.iter().zip(&light.coeffs) {
        for c in 0..3 {
            rgb[c] += y * l[c] as f64;
        }
    }
    rgb.map(|v| v.max(0.0) as f32)
}

/// The world direction of the ray through the centre of pixel (x, y) (row 0 at the top).
pub fn pixel_ray(camera: &Camera, width: u32, height: u32, x: u32, y: u32) -> DVec3 {
    let clip_from_world = camera.clip_from_world(width as f32 / height as f32, 0.1, 10.0);
    let world_from_clip = clip_from_world.inverse();
    let ndc_x = 2.0 * (x as f32 + 0.5) / width as f32 - 1.0;
    let ndc_y = 1.0 - 2.0 * (y as f32 + 0.5) / height as f32;
    let far = world_from_clip * Vec4::new(ndc_x, ndc_y, 1.0, 1.0);
    (far.truncate() / far.w - camera.eye).as_dvec3().normalize()
}

/// Fills every uncovered pixel (alpha 0) of a rendered image with the sky behind it, opaque:
/// an image with its sky has no background left to composite over.
pub fn draw_sky(image: &mut [[f32; 4]], width: u32, height: u32, camera: &Camera, light: &ShLight) {
    for y in 0..height {
        for x in 0..width {
            let pixel = &mut image[(y * width + x) as usize];
            if pixel[3] == 0.0 {
                let [r, g, b] = sky_radiance(light, pixel_ray(camera, width, height, x, y));
                *pixel = [r, g, b, 1.0];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::analytic;
    use glam::Vec3;

    fn camera() -> Camera {
        Camera {
            eye: Vec3::new(0.0, 0.0, 5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            vertical_fov_deg: 60.0,
        }
    }

    #[test]
    fn the_centre_pixel_looks_at_the_target_and_the_top_row_looks_up() {
        let centre = pixel_ray(&camera(), 101, 101, 50, 50);
        assert!((centre - DVec3::NEG_Z).length() < 1e-5, "{centre}");
        let top = pixel_ray(&camera(), 101, 101, 50, 0);
        // Half the vertical field of view above the axis, less half a pixel.
        let expected = (30.0f64 * (100.0 / 101.0)).to_radians();
        let angle = top.y.atan2(-top.z);
        assert!((angle - expected).abs() < 2e-3, "{angle} vs {expected}");
    }

    #[test]
    fn a_constant_sky_fills_the_background_and_leaves_the_model() {
        let light = ShLight::constant(3, [0.5, 1.0, 2.0]);
        let mut image = vec![[0.0; 4]; 4 * 3];
        image[5] = [7.0, 7.0, 7.0, 1.0];
        draw_sky(&mut image, 4, 3, &camera(), &light);
        assert_eq!(image[5], [7.0, 7.0, 7.0, 1.0]);
        for (i, p) in image.iter().enumerate().filter(|(i, _)| *i != 5) {
            for (c, expected) in [0.5, 1.0, 2.0].iter().enumerate() {
                assert!((p[c] - expected).abs() < 1e-5, "pixel {i}: {p:?}");
            }
            assert_eq!(p[3], 1.0);
        }
    }

    #[test]
    fn a_bright_sky_over_dark_ground_is_bright_above_the_horizon() {
        let light = analytic::hemisphere(4, [1.0; 3], [0.1; 3]).unwrap();
        let up = sky_radiance(&light, DVec3::Y);
        let down = sky_radiance(&light, DVec3::NEG_Y);
        assert!(up[0] > 0.8 && down[0] < 0.3, "{up:?} {down:?}");
    }
}
