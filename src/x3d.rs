//! X3D export: a baked mesh as an X3D scene that an existing X3D browser relights, with the
//! minimal set of parts of the PRT-for-X3D paper (`../shared/references/x3d-prt-nodes.txt`):
//! the transfer as per-vertex attributes (`FloatVertexAttribute`), the light as a field of a
//! `ComposedShader` whose GLSL dots the two, per colour channel. The tone mapping is the
//! viewer's (`assets/viewer/tone_map.glsl`), so the browser's image matches `prt-gpu render`.

use std::fmt::Write as _;
use std::path::Path;

use glam::{Mat3, Quat, Vec3};

use crate::bake::BakedMesh;
use crate::error::{Error, Result};
use crate::fs::write_atomically;
use crate::light::ShLight;
use crate::render::{Camera, ToneMap};

const VERTEX_SHADER: &str = include_str!("../assets/x3d/prt.vert");
const TONE_MAP: &str = include_str!("../assets/viewer/tone_map.glsl");
const FRAGMENT_SHADER: &str = "in vec3 radiance;\nout vec4 color;\n\nvoid main() {\n    color = display_color(radiance);\n}\n";

/// WebGL2 guarantees 16 vertex attributes; the vertex and its colour take two.
pub const MAX_TRANSFER_ATTRIBUTES: usize = 14;

/// What the scene shows besides the mesh: the light, the viewpoint and the display transform.
pub struct X3dOptions {
    pub camera: Camera,
    pub exposure_stops: f32,
    pub tone_map: ToneMap,
}

/// Writes `baked` under `light` as an X3D (XML encoding) file, atomically.
pub fn write_x3d(
    path: &Path,
    baked: &BakedMesh,
    light: &ShLight,
    options: &X3dOptions,
) -> Result<()> {
    let text = x3d_scene(baked, light, options)?;
    write_atomically(path, text.as_bytes())
}

/// The transfer attributes a bake needs: its floats per vertex, four to an attribute.
pub fn transfer_attributes(baked: &BakedMesh) -> usize {
    let transfer = &baked.transfer;
    (transfer.channels() as usize * transfer.coeffs_per_channel()).div_ceil(4)
}

/// The X3D document, checked: per-vertex transfer within the attribute budget, a light with
/// at least the bake's bands, finite values.
pub fn x3d_scene(baked: &BakedMesh, light: &ShLight, options: &X3dOptions) -> Result<String> {
    check(baked, light)?;
    options.camera.validate()?;
    let transfer = &baked.transfer;
    let coeffs = transfer.coeffs_per_channel();
    let attributes = transfer_attributes(baked);
    let mut out = String::new();
    out.push_str(&header(baked));
    out.push_str(&viewpoint(&options.camera));
    out.push_str("    <Shape>\n      <Appearance>\n");
    out.push_str(&shader(baked, light, options, attributes));
    out.push_str("      </Appearance>\n");
    let index = numbers(
        baked
            .scene
            .triangles
            .iter()
            .flatten()
            .map(|i| i.to_string()),
    );
    let _ = writeln!(
        out,
        "      <IndexedTriangleSet solid='false' index='{index}'>"
    );
    let points = numbers(
        baked
            .scene
            .positions
            .iter()
            .flat_map(|p| p.to_array())
            .map(float),
    );
    let _ = writeln!(out, "        <Coordinate point='{points}'/>");
    if baked.metadata.albedo_free {
        let colors = numbers(
            baked
                .scene
                .albedo
                .iter()
                .flat_map(|a| a.to_array())
                .map(float),
        );
        let _ = writeln!(out, "        <Color color='{colors}'/>");
    }
    let per_vertex = transfer.channels() as usize * coeffs;
    for a in 0..attributes {
        let values = transfer
            .coeffs()
            .chunks_exact(per_vertex)
            .flat_map(|vertex| {
                (4 * a..4 * a + 4).map(move |i| vertex.get(i).copied().unwrap_or(0.0))
            });
        let _ = writeln!(
            out,
            "        <FloatVertexAttribute name='transfer{a}' numComponents='4' value='{}'/>",
            numbers(values.map(float))
        );
    }
    out.push_str("      </IndexedTriangleSet>\n    </Shape>\n  </Scene>\n</X3D>\n");
    Ok(out)
}

fn check(baked: &BakedMesh, light: &ShLight) -> Result<()> {
    let transfer = &baked.transfer;
    let refuse = |why: String| Err(Error::Options(format!("export x3d: {why}")));
    if baked.lightmap.is_some() {
        return refuse(
            "per-texel transfer (a lightmap) has no X3D form here; bake per vertex".into(),
        );
    }
    if transfer.vertex_count() == 0 || baked.scene.triangles.is_empty() {
        return refuse("the file holds no transfer or no triangles".into());
    }
    if transfer_attributes(baked) > MAX_TRANSFER_ATTRIBUTES {
        return refuse(format!(
            "{} bands x {} channels need {} vertex attributes, more than WebGL's {MAX_TRANSFER_ATTRIBUTES} left for transfer: bake fewer bands or --storage lean",
            transfer.bands(),
            transfer.channels(),
            transfer_attributes(baked)
        ));
    }
    if light.bands < transfer.bands() {
        return refuse(format!(
            "the light has {} bands, the bake {}: project the light at {} bands or more",
            light.bands,
            transfer.bands(),
            transfer.bands()
        ));
    }
    let finite = transfer.coeffs().iter().all(|c| c.is_finite())
        && baked.scene.positions.iter().all(|p| p.is_finite())
        && light.coeffs.iter().flatten().all(|c| c.is_finite());
    if !finite {
        return refuse("non-finite positions, transfer or light".into());
    }
    Ok(())
}

fn header(baked: &BakedMesh) -> String {
    let m = &baked.metadata;
    format!(
        "<?xml version='1.0' encoding='UTF-8'?>\n\
         <!DOCTYPE X3D PUBLIC 'ISO//Web3D//DTD X3D 4.0//EN' 'https://www.web3d.org/specifications/x3d-4.0.dtd'>\n\
         <X3D profile='Interchange' version='4.0' xmlns:xsd='http://www.w3.org/2001/XMLSchema-instance' \
         xsd:noNamespaceSchemaLocation='https://www.web3d.org/specifications/x3d-4.0.xsd'>\n\
         \x20 <head>\n\
         \x20   <component name='Shaders' level='1'/>\n\
         \x20   <meta name='generator' content='{} {}'/>\n\
         \x20   <meta name='prt' content='{} transfer, {} bands, {} channel(s){}; {}'/>\n\
         \x20 </head>\n\
         \x20 <Scene>\n\
         \x20   <NavigationInfo headlight='false' type='\"EXAMINE\" \"ANY\"'/>\n\
         \x20   <Background skyColor='0 0 0'/>\n",
        m.tool,
        m.tool_version,
        m.mode.name(),
        m.bands,
        m.channels,
        if m.albedo_free { " (albedo-free: times Color)" } else { "" },
        xml_attribute(&m.sh_convention),
    )
}

/// The camera as an X3D viewpoint: X3D cameras look down their -Z with +Y up, turned by an
/// axis and angle; the field of view is the smaller extent's, the vertical one in a landscape
/// window, as render's is.
fn viewpoint(camera: &Camera) -> String {
    let (axis, angle) = orientation(camera);
    format!(
        "    <Viewpoint description='prt-gpu camera' position='{}' orientation='{} {}' fieldOfView='{}' centerOfRotation='{}'/>\n",
        vector(camera.eye),
        vector(axis),
        float(angle),
        float(camera.vertical_fov_deg.to_radians()),
        vector(camera.target)
    )
}

/// The rotation that takes X3D's default view (looking down -Z, +Y up) to the camera's.
pub fn orientation(camera: &Camera) -> (Vec3, f32) {
    let (forward, right, up) = camera.view_basis();
    let (axis, angle) = Quat::from_mat3(&Mat3::from_cols(right, up, -forward))
        .normalize()
        .to_axis_angle();
    if angle.abs() < 1e-7 {
        (Vec3::Z, 0.0)
    } else {
        (axis, angle)
    }
}

/// The shader node: its fields, and its two parts inline as `data:` URLs in CDATA sections
/// (X3D's XML form of inline shader source; the part's text is its `url` field).
fn shader(baked: &BakedMesh, light: &ShLight, options: &X3dOptions, attributes: usize) -> String {
    let transfer = &baked.transfer;
    let coeffs = transfer.coeffs_per_channel();
    let light_values = numbers(light.coeffs[..coeffs].iter().flatten().copied().map(float));
    let tone = match options.tone_map {
        ToneMap::None => 0,
        ToneMap::Reinhard => 1,
        ToneMap::Aces => 2,
    };
    let declarations: String = (0..attributes)
        .map(|a| format!("in vec4 transfer{a};\n"))
        .collect();
    let array = format!(
        "vec4[ATTRIBUTES]({})",
        (0..attributes)
            .map(|a| format!("transfer{a}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let albedo = if baked.metadata.albedo_free {
        "x3d_Color.rgb"
    } else {
        "vec3(1.0)"
    };
    let prelude = "#version 300 es\nprecision highp float;\nprecision highp int;\n";
    let vertex = format!(
        "{prelude}#define COEFFS {coeffs}\n#define CHANNELS {}\n#define ATTRIBUTES {attributes}\n#define ALBEDO {albedo}\n#define TRANSFER_ARRAY {array}\n{}",
        transfer.channels(),
        VERTEX_SHADER.replace("TRANSFER_ATTRIBUTES\n", &declarations)
    );
    let fragment = format!("{prelude}{TONE_MAP}\n{FRAGMENT_SHADER}");
    format!(
        "        <ComposedShader DEF='prt' language='GLSL'>\n\
         \x20         <field name='light' type='MFVec3f' accessType='inputOutput' value='{light_values}'/>\n\
         \x20         <field name='exposure_stops' type='SFFloat' accessType='inputOutput' value='{}'/>\n\
         \x20         <field name='tone_map_kind' type='SFInt32' accessType='inputOutput' value='{tone}'/>\n\
         \x20         <ShaderPart type='VERTEX'><![CDATA[data:x-shader/x-vertex,{vertex}]]></ShaderPart>\n\
         \x20         <ShaderPart type='FRAGMENT'><![CDATA[data:x-shader/x-fragment,{fragment}]]></ShaderPart>\n\
         \x20       </ComposedShader>\n",
        float(options.exposure_stops)
    )
}

/// Shortest text that reads back as the same f32.
fn float(value: f32) -> String {
    format!("{value}")
}

fn vector(v: Vec3) -> String {
    format!("{} {} {}", float(v.x), float(v.y), float(v.z))
}

fn numbers(values: impl Iterator<Item = String>) -> String {
    values.collect::<Vec<_>>().join(" ")
}

fn xml_attribute(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('\'', "&apos;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point `distance` along X3D's default view direction, -Z, lands on the camera's view
    /// axis once turned by the Viewpoint's orientation, and +Y lands on the camera's up.
    #[test]
    fn the_viewpoint_orientation_turns_the_default_view_onto_the_camera() {
        for text in [
            "3,2,4,0,0.5,0",
            "0,5,0,0,0,0",
            "-2,-1,0.5,1,1,1",
            "0,0,5,0,0,0",
        ] {
            let camera: Camera = text.parse().unwrap();
            let (axis, angle) = orientation(&camera);
            let turn = Quat::from_axis_angle(axis, angle);
            let (forward, _, up) = camera.view_basis();
            assert!((turn * Vec3::NEG_Z - forward).length() < 1e-5, "{text}");
            assert!((turn * Vec3::Y - up).length() < 1e-5, "{text}");
            assert!((axis.length() - 1.0).abs() < 1e-5);
        }
    }
}
