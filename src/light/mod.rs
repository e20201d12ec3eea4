//! Lighting in the SH basis: what a baked transfer is dotted with.
//!
//! - [`envmap`] reads environment-map files as linear RGB images;
//! - [`mapping`] says how each parameterization maps pixels to directions and solid angles;
//! - [`mod@project`] turns an environment map into SH coefficients;
//! - [`sky`] makes a small lat-long copy of a map to draw as a sky, and looks it up;
//! - [`analytic`] gives closed-form projections of analytic lights;
//! - [`mod@file`] reads and writes light.json.

pub mod analytic;
pub mod envmap;
pub mod file;
pub mod mapping;
pub mod project;
pub mod sky;

pub use envmap::EnvImage;
pub use file::{read_json, write_json};
pub use mapping::Mapping;
pub use project::{project, project_faces, project_with, ProjectOptions, Projection};

use std::path::Path;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::sh::rotation::ShRotation;
use crate::sh::window::{apply_window, factors_for, Window};

/// RGB lighting coefficients `l_k = integral L_in(w) y_k(w) dw` in the basis of `sh`
/// (`coeffs[k] = [r, g, b]`, `k = l(l+1) + m`, `bands^2` entries).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShLight {
    pub bands: u32,
    pub coeffs: Vec<[f32; 3]>,
}

impl ShLight {
    /// Constant radiance `rgb` from every direction: only the DC term, `rgb * sqrt(4 pi)`.
    pub fn constant(bands: u32, rgb: [f32; 3]) -> Self {
        let mut coeffs = vec![[0.0; 3]; crate::sh::coeff_count(bands)];
        let dc = (4.0 * std::f32::consts::PI).sqrt();
        coeffs[0] = rgb.map(|c| c * dc);
        ShLight { bands, coeffs }
    }
}

impl ShLight {
    /// The light turned by yaw (about +Y), pitch (about +X) and roll (about +Z), in degrees,
    /// as `sh::rotation::ShRotation::from_yaw_pitch_roll` composes them.
    pub fn rotated(&self, yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> ShLight {
        let rotation = ShRotation::from_yaw_pitch_roll(self.bands, yaw_deg, pitch_deg, roll_deg);
        ShLight {
            bands: self.bands,
            coeffs: rotation.apply_rgb(&self.coeffs),
        }
    }

    /// The light with `window` applied against ringing.
    pub fn windowed(&self, window: Window) -> ShLight {
        let mut coeffs = self.coeffs.clone();
        apply_window(&mut coeffs, &factors_for(window, &self.coeffs, self.bands));
        ShLight {
            bands: self.bands,
            coeffs,
        }
    }

    /// The sum of two lights of the same band count.
    pub fn plus(&self, other: &ShLight) -> Result<ShLight> {
        if self.bands != other.bands {
            return Err(Error::Options(format!(
                "cannot add lights of {} and {} bands",
                self.bands, other.bands
            )));
        }
        let coeffs = self
            .coeffs
            .iter()
            .zip(&other.coeffs)
            .map(|(a, b)| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
            .collect();
        Ok(ShLight {
            bands: self.bands,
            coeffs,
        })
    }
}

/// What `load` read, besides the light.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedLight {
    pub light: ShLight,
    /// The parameterization used for an environment map (`None` for light.json).
    pub mapping: Option<Mapping>,
    /// NaN or infinite pixels skipped (with `skip_invalid`).
    pub skipped_pixels: usize,
    /// What the user should hear about the files read, one line each, naming its file (an
    /// environment map whose extension names another format than it holds).
    pub warnings: Vec<String>,
}

/// A light from a file: light.json as written by `prt-gpu light`, or an environment map
/// (EXR, HDR, PNG, JPEG) projected at `bands` with `mapping` (auto-detected when `None`).
pub fn load(
    path: &Path,
    bands: u32,
    mapping: Option<Mapping>,
    skip_invalid: bool,
) -> Result<LoadedLight> {
    load_with_image(path, bands, mapping, skip_invalid).map(|(light, _)| light)
}

/// [`load`], also giving the environment map it projected (`None` for light.json), for a
/// caller that shows the map itself (the viewer's sky) without reading the file again.
pub fn load_with_image(
    path: &Path,
    bands: u32,
    mapping: Option<Mapping>,
    skip_invalid: bool,
) -> Result<(LoadedLight, Option<EnvImage>)> {
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if is_json {
        let light = read_json(path)?;
        let loaded = LoadedLight {
            light,
            mapping: None,
            skipped_pixels: 0,
            warnings: Vec::new(),
        };
        return Ok((loaded, None));
    }
    let (image, warnings) = envmap::load_with_warnings(path)?;
    let mapping =
        Mapping::resolve(mapping, image.width, image.height).map_err(|m| Error::light(path, m))?;
    let projection = project_with(&image, mapping, bands, &ProjectOptions { skip_invalid })?;
    let loaded = LoadedLight {
        light: projection.light,
        mapping: Some(mapping),
        skipped_pixels: projection.skipped,
        warnings: naming(path, warnings),
    };
    Ok((loaded, Some(image)))
}

/// A light from six cube faces, +X, -X, +Y, -Y, +Z, -Z (each oriented as in the horizontal
/// cross, see `mapping::CROSS_HORIZONTAL`), projected at `bands`.
pub fn load_faces(
    paths: &[std::path::PathBuf],
    bands: u32,
    skip_invalid: bool,
) -> Result<LoadedLight> {
    if paths.len() != 6 {
        return Err(Error::Options(format!(
            "--faces needs six images (+X,-X,+Y,-Y,+Z,-Z), not {}",
            paths.len()
        )));
    }
    let mut images = Vec::new();
    let mut warnings = Vec::new();
    for path in paths {
        let (image, said) = envmap::load_with_warnings(path)?;
        images.push(image);
        warnings.extend(naming(path, said));
    }
    let faces = [
        &images[0], &images[1], &images[2], &images[3], &images[4], &images[5],
    ];
    let projection = project_faces(faces, bands, &ProjectOptions { skip_invalid })?;
    Ok(LoadedLight {
        light: projection.light,
        mapping: Some(Mapping::CrossHorizontal),
        skipped_pixels: projection.skipped,
        warnings,
    })
}

fn naming(path: &Path, lines: Vec<String>) -> Vec<String> {
    lines
        .into_iter()
        .map(|line| format!("{}: {line}", path.display()))
        .collect()
}

/// The light `bake --preview` uses: a blue-white sky over a dim ground and a warm sun from
/// above the front right, soft enough for a few bands to render without ringing.
pub fn preview_light(bands: u32) -> Result<ShLight> {
    let sky = analytic::hemisphere(bands, [0.55, 0.65, 0.8], [0.12, 0.1, 0.08])?;
    let sun_direction = DVec3::new(0.5, 0.8, 0.6).normalize();
    let sun = analytic::sun_disk(bands, sun_direction, 0.2, [2.2, 2.0, 1.7])?;
    sky.plus(&sun)
}
