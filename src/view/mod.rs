//! The web viewer: one self-contained HTML file that relights baked files in a browser with
//! WebGL2, the run-time half of PRT for anyone to look at and for engine integrators to read.
//!
//! The page is our own JavaScript and GLSL (`assets/viewer/`, included verbatim so they stay
//! readable files) plus the data, embedded as JSON with the binary arrays in base64: every
//! vertex's position, its transfer exactly as the .glb stores it (channel-major, `bands^2`
//! floats per channel), the albedo where the transfer leaves it out, and the light's SH
//! coefficients (a lightmapped file: its texels' transfer and lightmap coordinates instead).
//! The page does what `render` does — one dot product per vertex and channel, interpolated
//! across triangles (or per texel, looked up bilinearly), tone mapped per pixel, the SH light
//! drawn behind as a sky (the environment map itself, as a small lat-long copy, where the
//! light is one) —
//! and rotates the light in the page with the same SH rotation as `sh::rotation`.

use std::path::Path;

use base64::Engine;
use glam::Vec3;
use half::f16;
use serde::Serialize;

use crate::bake::{BakedMesh, TexelBake};
use crate::error::{Error, Result};
use crate::fs::write_atomically;
use crate::light::sky::latlong_copy;
use crate::light::{EnvImage, Mapping, ShLight};
use crate::probes::ProbeSet;
use crate::render::{bounds, Camera};
use crate::scene::Scene;
use crate::zonal::ZonalTransfer;

mod probes;

/// The page: markup and style, with `{{TITLE}}`, `{{SHADERS}}`, `{{DATA}}` and `{{SCRIPT}}`
/// replaced when the file is written.
const PAGE: &str = include_str!("../../assets/viewer/viewer.html");
/// The SH rotation (the Ivanic–Ruedenberg recurrence of `sh::rotation`) and basis.
const SH_SCRIPT: &str = include_str!("../../assets/viewer/sh.js");
/// Camera, input handling and drawing.
const VIEWER_SCRIPT: &str = include_str!("../../assets/viewer/viewer.js");
/// The probes' lookup and the test sphere they light.
const PROBES_SCRIPT: &str = include_str!("../../assets/viewer/probes.js");
/// The shaders, each embedded as a `<script type="x-shader/...">` element of this id.
const SHADERS: [(&str, &str); 13] = [
    (
        "tone-map",
        include_str!("../../assets/viewer/tone_map.glsl"),
    ),
    (
        "transfer",
        include_str!("../../assets/viewer/transfer.glsl"),
    ),
    (
        "bend-function",
        include_str!("../../assets/viewer/bend.glsl"),
    ),
    (
        "zonal-relight",
        include_str!("../../assets/viewer/zonal.glsl"),
    ),
    ("mesh-vertex", include_str!("../../assets/viewer/mesh.vert")),
    (
        "mesh-fragment",
        include_str!("../../assets/viewer/mesh.frag"),
    ),
    (
        "lightmap-vertex",
        include_str!("../../assets/viewer/lightmap.vert"),
    ),
    (
        "lightmap-fragment",
        include_str!("../../assets/viewer/lightmap.frag"),
    ),
    ("sh-sum", include_str!("../../assets/viewer/sh_sum.glsl")),
    (
        "probe-sphere-vertex",
        include_str!("../../assets/viewer/probe_sphere.vert"),
    ),
    ("sky-vertex", include_str!("../../assets/viewer/sky.vert")),
    ("sky-fragment", include_str!("../../assets/viewer/sky.frag")),
    (
        "sky-map-fragment",
        include_str!("../../assets/viewer/sky_map.frag"),
    ),
];

/// The widest lat-long copy of an environment map the page embeds (half as high): 512 x 256
/// texels of three half floats, about 1 MB of base64.
pub const SKY_MAP_MAX_WIDTH: usize = 512;

/// An environment map to draw as the sky: the map, its mapping, and the rotation (yaw, pitch,
/// roll in degrees, as `ShLight::rotated`) the light was given before the page turns it.
pub struct ViewerSky<'a> {
    pub image: &'a EnvImage,
    pub mapping: Mapping,
    pub yaw_pitch_roll: [f64; 3],
}

/// One baked file for the viewer, named as the page lists it, with its probes where it has
/// them (the page then moves a test sphere through the scene lit by them).
pub struct ViewerBake<'a> {
    pub name: String,
    pub baked: &'a BakedMesh,
    pub probes: Option<&'a ProbeSet>,
    /// Its zonal transfer, where it has one (the page then relights from it on request, and
    /// bends the mesh).
    pub zonal: Option<&'a ZonalTransfer>,
}

/// The page's data: what `viewer.js` reads from the `prt-data` element.
#[derive(Serialize)]
struct PageData {
    light: PageLight,
    /// The camera when the URL gives none: `render`'s framing of the first file.
    camera: PageCamera,
    bakes: Vec<PageBake>,
    /// The unit test sphere, where a file has probes.
    sphere: Option<probes::PageSphere>,
}

#[derive(Serialize)]
struct PageLight {
    bands: u32,
    coeffs: Vec<[f32; 3]>,
    /// The environment map as a lat-long sky, where the light is one.
    map: Option<PageSkyMap>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct PageSkyMap {
    width: usize,
    height: usize,
    /// Base64 of little-endian IEEE half floats r, g, b per texel, row-major, row 0 the top
    /// (+Y), laid out as `light::mapping`'s lat-long.
    rgb: String,
    /// The rotation the light was given before the page's, in degrees.
    yaw_pitch_roll: [f64; 3],
}

#[derive(Serialize)]
struct PageCamera {
    eye: [f32; 3],
    target: [f32; 3],
    fov: f32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct PageBake {
    name: String,
    mode: &'static str,
    bands: u32,
    channels: u32,
    vertices: usize,
    triangles: usize,
    bounds_min: [f32; 3],
    bounds_max: [f32; 3],
    /// Base64 of little-endian f32 x, y, z per vertex.
    positions: String,
    /// Base64 of little-endian u32, three per triangle.
    indices: String,
    /// Base64 of little-endian f32, `channels * bands^2` per vertex, channel-major (the file's
    /// layout).
    transfer: String,
    /// Base64 of little-endian f32 r, g, b per vertex where the transfer is albedo-free.
    albedo: Option<String>,
    /// Per-texel transfer, where the file has a lightmap: it replaces `transfer` in the page.
    lightmap: Option<PageLightmap>,
    probes: Option<probes::PageProbes>,
    zonal: Option<PageZonal>,
}

/// Zonal transfer (`bake --zonal`) for the page's LDPRT relighting.
#[derive(Serialize)]
struct PageZonal {
    bands: u32,
    channels: u32,
    /// Base64 of little-endian f32 x, y, z per vertex: each lobe's axis in the rest pose.
    axes: String,
    /// Base64 of little-endian f32, `channels * bands` per vertex, channel-major.
    coeffs: String,
}

#[derive(Serialize)]
struct PageLightmap {
    width: u32,
    height: u32,
    /// Base64 of little-endian f32 u, v per vertex (glTF's convention).
    texcoords: String,
    /// Base64 of little-endian f32, `channels * bands^2` per texel, row-major, channel-major.
    transfer: String,
}

/// Checks every input and writes the viewer to `path` atomically (nothing on failure).
pub fn write_viewer(
    path: &Path,
    bakes: &[ViewerBake],
    light: &ShLight,
    sky: Option<&ViewerSky>,
) -> Result<()> {
    let html = viewer_html(bakes, light, sky)?;
    write_atomically(path, html.as_bytes())
}

/// The viewer page for `bakes` under `light`, checked: the light must have at least as many
/// bands as every bake (the page dots the bake's `bands^2` coefficients with the light's).
/// With `sky`, the page also embeds a lat-long copy of the map (at most
/// [`SKY_MAP_MAX_WIDTH`] wide) and draws it behind the model.
pub fn viewer_html(
    bakes: &[ViewerBake],
    light: &ShLight,
    sky: Option<&ViewerSky>,
) -> Result<String> {
    let first = bakes
        .first()
        .ok_or_else(|| Error::Options("view: no baked files".into()))?;
    check_light(light)?;
    let page_bakes = bakes
        .iter()
        .map(|bake| page_bake(bake, light.bands))
        .collect::<Result<Vec<_>>>()?;
    let camera = Camera::framing_scene(&first.baked.scene);
    let data = PageData {
        light: PageLight {
            bands: light.bands,
            coeffs: light.coeffs.clone(),
            map: sky.map(page_sky_map).transpose()?,
        },
        camera: PageCamera {
            eye: camera.eye.to_array(),
            target: camera.target.to_array(),
            fov: camera.vertical_fov_deg,
        },
        sphere: bakes
            .iter()
            .any(|b| b.probes.is_some())
            .then(probes::page_sphere),
        bakes: page_bakes,
    };
    let json = serde_json::to_string(&data)
        .map_err(|e| Error::Options(format!("view: cannot encode the page data: {e}")))?;
    let title = bakes
        .iter()
        .map(|b| b.name.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    Ok(PAGE
        .replace("{{TITLE}}", &escape_html(&title))
        .replace("{{SHADERS}}", &shader_elements())
        .replace(
            "{{SCRIPT}}",
            &format!("{SH_SCRIPT}\n{PROBES_SCRIPT}\n{VIEWER_SCRIPT}"),
        )
        .replace("{{DATA}}", &script_safe(&json)))
}

fn check_light(light: &ShLight) -> Result<()> {
    let finite = light.coeffs.iter().flatten().all(|c| c.is_finite());
    if light.bands == 0 || light.coeffs.len() != crate::sh::coeff_count(light.bands) || !finite {
        return Err(Error::Options(format!(
            "view: the light ({} bands, {} coefficients) is not a finite SH light",
            light.bands,
            light.coeffs.len()
        )));
    }
    Ok(())
}

/// The map's lat-long copy as half floats (radiance beyond what a half float holds saturates
/// at 65504).
fn page_sky_map(sky: &ViewerSky) -> Result<PageSkyMap> {
    let copy = latlong_copy(sky.image, sky.mapping, SKY_MAP_MAX_WIDTH)?;
    let bytes: Vec<u8> = copy
        .pixels
        .iter()
        .flatten()
        .flat_map(|&c| f16::from_f32(c.clamp(0.0, f16::MAX.to_f32())).to_le_bytes())
        .collect();
    Ok(PageSkyMap {
        width: copy.width,
        height: copy.height,
        rgb: base64::engine::general_purpose::STANDARD.encode(bytes),
        yaw_pitch_roll: sky.yaw_pitch_roll,
    })
}

/// One file's arrays, refused where the page could not show it as baked.
fn page_bake(bake: &ViewerBake, light_bands: u32) -> Result<PageBake> {
    let baked = bake.baked;
    let transfer = &baked.transfer;
    let refuse = |why: String| Err(Error::Options(format!("view: {}: {why}", bake.name)));
    if transfer.vertex_count() == 0 {
        return refuse("holds no transfer".into());
    }
    if transfer.bands() > light_bands {
        return refuse(format!(
            "baked with {} bands, but the light has only {light_bands}: project the light at {} bands or more",
            transfer.bands(), transfer.bands()
        ));
    }
    if !matches!(transfer.channels(), 1 | 3)
        || transfer.vertex_count() != baked.scene.vertex_count()
    {
        return refuse("its transfer does not match its vertices".into());
    }
    if baked.scene.triangles.is_empty() {
        return refuse("has no triangles".into());
    }
    if !transfer.coeffs().iter().all(|c| c.is_finite())
        || !baked.scene.positions.iter().all(|p| p.is_finite())
    {
        return refuse("holds non-finite positions or transfer".into());
    }
    let lightmap = baked
        .lightmap
        .as_ref()
        .map(|texels| page_lightmap(texels, &baked.scene))
        .transpose();
    let lightmap = match lightmap {
        Ok(lightmap) => lightmap,
        Err(why) => return refuse(why),
    };
    let probes = bake
        .probes
        .map(|p| probes::page_probes(p, &baked.scene, light_bands))
        .transpose();
    let probes = match probes {
        Ok(probes) => probes,
        Err(why) => return refuse(why),
    };
    let zonal = match bake.zonal {
        Some(zonal) if zonal.vertex_count() != transfer.vertex_count() => {
            return refuse("its zonal transfer does not match its vertices".into())
        }
        Some(zonal) => Some(PageZonal {
            bands: zonal.bands(),
            channels: zonal.channels(),
            axes: base64_f32(zonal.axes().iter().flat_map(Vec3::to_array)),
            coeffs: base64_f32(zonal.coeffs().iter().copied()),
        }),
        None => None,
    };
    let (min, max) = bounds(&baked.scene.positions);
    let albedo = baked
        .metadata
        .albedo_free
        .then(|| base64_f32(baked.scene.albedo.iter().flat_map(Vec3::to_array)));
    Ok(PageBake {
        name: bake.name.clone(),
        mode: baked.metadata.mode.name(),
        bands: transfer.bands(),
        channels: transfer.channels(),
        vertices: transfer.vertex_count(),
        triangles: baked.scene.triangles.len(),
        bounds_min: min.to_array(),
        bounds_max: max.to_array(),
        positions: base64_f32(baked.scene.positions.iter().flat_map(Vec3::to_array)),
        indices: base64_u32(baked.scene.triangles.iter().flatten().copied()),
        transfer: base64_f32(transfer.coeffs().iter().copied()),
        albedo,
        lightmap,
        probes,
        zonal,
    })
}

/// A lightmap's texels for the page, and its coordinates per vertex of `scene`; refused where
/// they do not match the mesh.
fn page_lightmap(texels: &TexelBake, scene: &Scene) -> std::result::Result<PageLightmap, String> {
    let transfer = &texels.transfer;
    let texel_count = texels.width as usize * texels.height as usize;
    if texel_count == 0 || transfer.vertex_count() != texel_count {
        return Err("its lightmap's texels do not match its size".into());
    }
    let texcoords = (texels.texcoords.len() == 3 * scene.triangles.len())
        .then(|| texels.vertex_texcoords(scene))
        .flatten()
        .ok_or("its lightmap's coordinates do not match its vertices")?;
    if !transfer.coeffs().iter().all(|c| c.is_finite()) {
        return Err("its lightmap holds non-finite transfer".into());
    }
    Ok(PageLightmap {
        width: texels.width,
        height: texels.height,
        texcoords: base64_f32(texcoords.iter().flatten().copied()),
        transfer: base64_f32(transfer.coeffs().iter().copied()),
    })
}

fn base64_f32(values: impl Iterator<Item = f32>) -> String {
    let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn base64_u32(values: impl Iterator<Item = u32>) -> String {
    let bytes: Vec<u8> = values.flat_map(u32::to_le_bytes).collect();
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn shader_elements() -> String {
    SHADERS
        .iter()
        .map(|(id, source)| {
            format!("<script type=\"x-shader/glsl\" id=\"{id}\">\n{source}</script>\n")
        })
        .collect()
}

/// JSON made safe inside a `<script>` element: `<` only occurs in strings, where `\u003c`
/// means the same, so no `</script>` can end the element early.
fn script_safe(json: &str) -> String {
    json.replace('<', "\\u003c")
}

fn escape_html(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{bake, BakeOptions, CpuBackend, Mode, NoProgress};
    use crate::scene::builtin::icosphere;

    fn sphere(bands: u32) -> BakedMesh {
        let options = BakeOptions {
            bands,
            samples: 64,
            mode: Mode::Unshadowed,
            ..BakeOptions::default()
        };
        bake(
            icosphere(Vec3::ZERO, 1.0, 1),
            &options,
            &CpuBackend,
            &NoProgress,
        )
        .unwrap()
        .0
    }

    /// The base64 string of `key` in the page data of `html`, decoded.
    fn embedded_floats(html: &str, key: &str) -> Vec<f32> {
        let start = html.find("id=\"prt-data\">").unwrap() + "id=\"prt-data\">".len();
        let end = start + html[start..].find("</script>").unwrap();
        let data: serde_json::Value = serde_json::from_str(&html[start..end]).unwrap();
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(data["bakes"][0][key].as_str().unwrap())
            .unwrap();
        bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    }

    #[test]
    fn the_page_embeds_the_files_arrays_bit_for_bit() {
        let baked = sphere(3);
        let light = ShLight::constant(3, [1.0; 3]);
        let name = "a</script><b>.glb".to_string();
        let html = viewer_html(
            &[ViewerBake {
                name,
                baked: &baked,
                probes: None,
                zonal: None,
            }],
            &light,
            None,
        )
        .unwrap();
        assert_eq!(embedded_floats(&html, "transfer"), baked.transfer.coeffs());
        let positions: Vec<f32> = baked
            .scene
            .positions
            .iter()
            .flat_map(|p| p.to_array())
            .collect();
        assert_eq!(embedded_floats(&html, "positions"), positions);
        // A hostile name cannot end the data's script element or add markup.
        assert_eq!(html.matches("</script>").count(), SHADERS.len() + 2);
        assert!(!html.contains("<b>"));
        for (id, _) in SHADERS {
            assert!(html.contains(&format!("id=\"{id}\"")), "{id}");
        }
    }

    #[test]
    fn the_viewer_refuses_what_the_page_could_not_show() {
        let baked = sphere(3);
        let viewer = |baked: &BakedMesh, light: &ShLight| {
            let bake = ViewerBake {
                name: "x.glb".into(),
                baked,
                probes: None,
                zonal: None,
            };
            viewer_html(&[bake], light, None)
        };
        assert!(viewer(&baked, &ShLight::constant(3, [1.0; 3])).is_ok());
        assert!(viewer(&baked, &ShLight::constant(5, [1.0; 3])).is_ok());
        let narrow = viewer(&baked, &ShLight::constant(2, [1.0; 3])).unwrap_err();
        assert!(narrow.to_string().contains("only 2"), "{narrow}");
        let mut nan = ShLight::constant(3, [1.0; 3]);
        nan.coeffs[4][1] = f32::NAN;
        assert!(viewer(&baked, &nan).is_err());
        let mut texels = baked.clone();
        texels.lightmap = Some(TexelBake {
            width: 1,
            height: 1,
            texcoords: vec![[0.5; 2]; 3 * baked.scene.triangle_count()],
            set: 0,
            transfer: baked.transfer.clone(),
            held: None,
        });
        let refused = viewer(&texels, &ShLight::constant(3, [1.0; 3])).unwrap_err();
        assert!(refused.to_string().contains("lightmap"), "{refused}");
        texels.lightmap.as_mut().unwrap().transfer = crate::bake::Transfer::zeros(3, 3, 1);
        assert!(viewer(&texels, &ShLight::constant(3, [1.0; 3])).is_ok());
        let mut empty = baked.clone();
        empty.transfer = crate::bake::Transfer::zeros(3, 3, 0);
        assert!(viewer(&empty, &ShLight::constant(3, [1.0; 3])).is_err());
        assert!(viewer_html(&[], &ShLight::constant(3, [1.0; 3]), None).is_err());
    }

    #[test]
    fn the_viewer_refuses_probes_it_could_not_light_a_sphere_with() {
        let baked = sphere(3);
        let light = ShLight::constant(3, [1.0; 3]);
        let with = |probes: &ProbeSet| {
            let bake = ViewerBake {
                name: "p.glb".into(),
                baked: &baked,
                probes: Some(probes),
                zonal: None,
            };
            viewer_html(&[bake], &light, None)
        };
        let html = with(&ProbeSet::open_sky(3)).unwrap();
        assert!(html.contains("\"probes\":{") && html.contains("\"sphere\":{"));
        let wider = with(&ProbeSet::open_sky(4)).unwrap_err();
        assert!(wider.to_string().contains("probes have 4 bands"), "{wider}");
        let mut invalid = ProbeSet::open_sky(3);
        invalid.status[0] = crate::probes::ProbeStatus::Invalid;
        let none = with(&invalid).unwrap_err();
        assert!(none.to_string().contains("none of its probes"), "{none}");
        let mut broken = ProbeSet::open_sky(3);
        broken.matrices[4] = f32::INFINITY;
        assert!(with(&broken).is_err());
        broken.matrices.pop();
        assert!(with(&broken).is_err());
    }
}
