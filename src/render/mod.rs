//! Relighting and preview images: the run-time half of PRT.
//!
//! `relight` turns a baked [`Transfer`](crate::bake::Transfer) and an
//! [`ShLight`](crate::light::ShLight) into per-vertex exit radiance (one dot product per vertex
//! and channel); `render` rasterises the mesh with that radiance interpolated across triangles
//! into a linear HDR image on any wgpu adapter (lavapipe included); `write_image` stores it as a
//! tone-mapped 8-bit sRGB PNG or as a linear `.exr`.
//!
//! - `relight`: the transfer-times-light dot products and the checks of both inputs.
//! - `camera`: the pinhole [`Camera`], its automatic framing of a mesh and its command-line form.
//! - `raster`: the wgpu render pipeline, its colour target and the read-back (`preview`,
//!   `render`).
//! - `image`: side-by-side panels, tone mapping, sRGB bytes and the PNG and EXR files.
//! - `sky`: the light drawn behind the model, as a sky dome.
//! - `probes`: test spheres lit by a bake's probes, as a dynamic object is.

mod camera;
mod image;
mod probes;
mod raster;
mod relight;
mod sky;
#[cfg(test)]
mod test_support;

pub use self::image::{
    check_image_output, side_by_side, to_rgba8, tone_map, write_image, ToneMap, IMAGE_EXTENSIONS,
};
pub use camera::{bounds, Camera, DEFAULT_FOV_DEG};
pub use probes::{
    default_sphere_radius, probes_at, unit_sphere, with_probe_spheres, ProbeSphere, SPHERE_ALBEDO,
};
pub use raster::{preview, render, RenderParams};
pub use relight::{apply_albedo, relight, relight_baked, tint_by};
pub use sky::{draw_sky, pixel_ray, sky_radiance};
