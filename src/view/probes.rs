//! A bake's probes in the page: what `probes.js` needs to light a test sphere moved through
//! the scene as `render --probe-sphere` lights it — the probes' positions, which are valid,
//! their matrices as the file stores them, the grid they lie on, and each row's
//! clamped-cosine factor, so the page computes no SH convolution of its own.

use glam::Vec3;
use serde::Serialize;

use super::{base64_f32, base64_u32};
use crate::probes::{ProbeSet, ProbeStatus};
use crate::render::{bounds, default_sphere_radius, unit_sphere, SPHERE_ALBEDO};
use crate::scene::Scene;

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct PageProbes {
    bands: u32,
    channels: u32,
    /// Rows per channel of each matrix (`bands^2` radiance, up to 9 irradiance).
    rows: usize,
    /// What each row is multiplied by to give the irradiance's SH (`ProbeSet::row_factor`).
    row_factors: Vec<f64>,
    grid: Option<PageGrid>,
    count: usize,
    /// Base64 of little-endian f32 x, y, z per probe.
    positions: String,
    /// One byte per probe: 1 valid, 0 invalid (left out, as `ProbeSet::interpolate` does).
    valid: Vec<u8>,
    /// Base64 of little-endian f32, `channels * rows * bands^2` per probe (the file's layout).
    matrices: String,
    /// Where the sphere starts: the valid probe nearest the middle of them all.
    sphere_centre: [f32; 3],
    /// `render --probe-sphere`'s default radius.
    sphere_radius: f32,
}

#[derive(Serialize)]
struct PageGrid {
    origin: [f32; 3],
    spacing: f32,
    dims: [u32; 3],
}

/// The unit test sphere, once per page: the page moves and scales it.
#[derive(Serialize)]
pub(super) struct PageSphere {
    /// Base64 of little-endian f32 x, y, z per vertex (unit length: also the normal).
    positions: String,
    /// Base64 of little-endian u32, three per triangle.
    indices: String,
    triangles: usize,
    albedo: f32,
}

/// The page's copy of `probes`, or why the page could not light a sphere with them.
pub(super) fn page_probes(
    probes: &ProbeSet,
    scene: &Scene,
    light_bands: u32,
) -> std::result::Result<PageProbes, String> {
    if probes.bands > light_bands {
        return Err(format!(
            "its probes have {} bands, but the light only {light_bands}",
            probes.bands
        ));
    }
    if let Some(why) = probes.broken() {
        return Err(why.into());
    }
    let valid: Vec<bool> = probes
        .status
        .iter()
        .map(|&s| s != ProbeStatus::Invalid)
        .collect();
    let sphere_centre =
        middle_valid_probe(&probes.positions, &valid).ok_or("none of its probes is valid")?;
    Ok(PageProbes {
        bands: probes.bands,
        channels: probes.channels,
        rows: probes.rows,
        row_factors: (0..probes.rows).map(|i| probes.row_factor(i)).collect(),
        grid: probes.grid.map(|g| PageGrid {
            origin: g.origin.to_array(),
            spacing: g.spacing,
            dims: g.dims,
        }),
        count: probes.len(),
        positions: base64_f32(probes.positions.iter().flat_map(Vec3::to_array)),
        valid: valid.iter().map(|&v| u8::from(v)).collect(),
        matrices: base64_f32(probes.matrices.iter().copied()),
        sphere_centre: sphere_centre.to_array(),
        sphere_radius: default_sphere_radius(scene),
    })
}

/// The valid probe nearest the middle of the probes' bounding box.
fn middle_valid_probe(positions: &[Vec3], valid: &[bool]) -> Option<Vec3> {
    let (lo, hi) = bounds(positions);
    let middle = (lo + hi) * 0.5;
    positions
        .iter()
        .zip(valid)
        .filter(|(_, &v)| v)
        .map(|(&p, _)| p)
        .min_by(|a, b| {
            a.distance_squared(middle)
                .total_cmp(&b.distance_squared(middle))
        })
}

pub(super) fn page_sphere() -> PageSphere {
    let sphere = unit_sphere();
    PageSphere {
        positions: base64_f32(sphere.positions.iter().flat_map(Vec3::to_array)),
        indices: base64_u32(sphere.triangles.iter().flatten().copied()),
        triangles: sphere.triangles.len(),
        albedo: SPHERE_ALBEDO,
    }
}
