//! Relit radiance baked into vertex colours (`render ... -o relit.glb`): a copy of a baked
//! file whose `COLOR_0` holds each vertex's relit exit radiance (linear RGB) in place of its
//! albedo, and whose `extras.prt.relit` says so and under what light. Everything else is the
//! file as it was, so an engine shows the lit scene with no shader of ours, and a relit bake
//! can be compared with another renderer number for number.
//!
//! glTF keeps float colours in [0, 1] (the Khronos validator reports anything else as an
//! error), so `COLOR_0` holds the radiance divided by `extras.prt.relit.scale`, the largest
//! component where that exceeds 1 (else 1), negative values (a compressed operator's ringing
//! in the dark) as 0. The radiance itself, unscaled and as computed, is the float `VEC3`
//! attribute `_RADIANCE` (an application-specific attribute, which viewers ignore): read that
//! to compare with another renderer. (A scale easy to miss once made a relit interior look
//! 31% and 61% too dark against a path tracer.)
//!
//! A glTF scene baked in place keeps its materials, and glTF multiplies `COLOR_0` by a
//! material's base colour. So each baked primitive's new `COLOR_0` holds its relit shading —
//! the radiance over the vertex's albedo, the light its material's colour multiplies — over
//! the scale, `_RADIANCE` the radiance itself, and the materials of the baked primitives become
//! unlit (`KHR_materials_unlit`, listed in `extensionsUsed` but not required): a viewer then
//! shows base colour × `COLOR_0`, the relit scene with its textures, and one without the
//! extension falls back to its own lighting. The root's `extras.prt.relit` says so.
//!
//! A lightmapped file's texels are relit too, into an RGB OpenEXR image beside the copy that
//! `extras.prt.relit.lightmap` names ([`RelitLightmap`]): the radiance for a baked mesh, which
//! has no material; the shading, radiance over the texel's albedo, for a scene, whose
//! materials multiply by their base colour ([`RELIT_LIGHTMAP`], [`RELIT_SCENE_LIGHTMAP`]).

use std::collections::BTreeSet;
use std::path::Path;

use serde_json::{json, Value};

use super::{
    accessor, accessor_is, accessor_start, array_view, attribute, encode_document, extras_value,
    glb_container, index, parse_document, raw_extras, semantic, split_chunks, view_start,
    ComponentType, Document, Target, Type, USize64,
};
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};
use crate::scene::gltf::GltfScene;

/// `extras.prt.relit.color_0`: what `COLOR_0` now holds.
pub const RELIT_COLOR: &str =
    "relit exit radiance / scale, linear RGB, negative values as 0 (was the albedo)";

/// The attribute that holds the relit radiance unscaled.
pub const RADIANCE_ATTRIBUTE: &str = "_RADIANCE";

/// `extras.prt.relit.radiance`: what [`RADIANCE_ATTRIBUTE`] holds.
pub const RELIT_RADIANCE: &str = "relit exit radiance, linear RGB, unscaled (W/(m^2 sr))";

/// `extras.prt.relit.color_0` of a relit scene: what each baked primitive's `COLOR_0` holds.
pub const RELIT_SCENE_COLOR: &str = "relit shading: exit radiance over the vertex's albedo (what \
the material's base colour multiplies) / scale, linear RGB, negative values as 0";

/// `extras.prt.relit.lightmap.layout`: what a relit lightmap holds and how an engine shows it.
pub const RELIT_LIGHTMAP: &str = "exit radiance at the lightmap's texels (the SH lightmap \
relit), linear RGB, OpenEXR float32 R, G, B and A = 1, row 0 at v = 0, on the texcoord set \
named; shown as baked by an unlit material that adds a light map, e.g. three.js \
MeshBasicMaterial({ color: white, lightMap, lightMapIntensity: Math.PI }) (three divides a basic \
material's light map by pi)";

/// A lightmapped file's texels relit, written beside its relit copy and named in the copy's
/// `extras.prt.relit.lightmap`.
#[derive(Clone, Debug, PartialEq)]
pub struct RelitLightmap {
    /// The image's name, relative to the copy.
    pub uri: String,
    pub width: u32,
    pub height: u32,
    /// The `TEXCOORD_n` set it is laid on.
    pub texcoord: u32,
}

/// `extras.prt.relit.lightmap.layout` of a relit scene: its texels hold the shading a
/// material's base colour multiplies, as the scene's `COLOR_0` does.
pub const RELIT_SCENE_LIGHTMAP: &str = "relit shading at the lightmap's texels: exit radiance \
over the albedo the texel was baked with (what the material's base colour multiplies), linear \
RGB, OpenEXR float32 R, G, B and A = 1, row 0 at v = 0, on the texcoord set named; shown as \
baked by an unlit material with the base colour and a light map, e.g. three.js \
MeshBasicMaterial({ color, map, lightMap, lightMapIntensity: Math.PI }) without vertex colours";

/// `extras.prt.relit.lightmap` for `lightmap`, its texels described by `layout`.
fn lightmap_extras(lightmap: &RelitLightmap, layout: &str) -> Value {
    json!({
        "uri": lightmap.uri,
        "width": lightmap.width,
        "height": lightmap.height,
        "texcoord": lightmap.texcoord,
        "layout": layout,
    })
}

/// The relit lightmap's name beside the relit copy `glb`: `relit.glb` -> `relit.radiance.exr`.
pub fn relit_lightmap_file_name(glb: &Path) -> String {
    let name = super::lightmap_file_name(glb);
    let stem = name.strip_suffix(".lightmap.exr").unwrap_or(&name);
    format!("{stem}.radiance.exr")
}

/// The extension that makes a relit scene's baked materials show `COLOR_0` as it is.
pub const UNLIT: &str = "KHR_materials_unlit";

/// The baked file `bytes` with `COLOR_0` replaced by `radiance / scale` (one per vertex),
/// `radiance` itself added as [`RADIANCE_ATTRIBUTE`], and `extras.prt.relit = {color_0,
/// scale, radiance, light}`; and the scale.
pub fn with_relit_colors(
    bytes: &[u8],
    path: &Path,
    radiance: &[[f32; 3]],
    (light, lightmap): (&str, Option<&RelitLightmap>),
) -> Result<(Vec<u8>, f32)> {
    let damaged = |message: String| Error::baked(path, message);
    let (json, bin) = split_chunks(bytes, path)?;
    let mut bin = bin.to_vec();
    let mut doc = parse_document(json, path)?;
    let range = color_range(&doc, radiance.len()).map_err(damaged)?;
    let target = bin
        .get_mut(range)
        .ok_or_else(|| damaged("COLOR_0 runs past the BIN chunk".into()))?;
    let scale = color_scale(radiance)?;
    for (slot, value) in target.chunks_exact_mut(4).zip(radiance.iter().flatten()) {
        slot.copy_from_slice(&(value.max(0.0) / scale).to_le_bytes());
    }
    let mut relit = json!({
        "color_0": RELIT_COLOR,
        "scale": scale,
        "radiance": RELIT_RADIANCE,
        "light": light,
    });
    if let Some(lightmap) = lightmap {
        relit["lightmap"] = lightmap_extras(lightmap, RELIT_LIGHTMAP);
    }
    let mesh = doc.meshes.first_mut();
    let extras = mesh.map(|mesh| &mut mesh.extras);
    add_relit(extras, relit).ok_or_else(|| damaged("no extras.prt: not a baked file".into()))?;
    let accessor = append_vec3s(&mut doc, &mut bin, radiance.iter().copied());
    set_attribute(&mut doc, 0, 0, RADIANCE_ATTRIBUTE, accessor).map_err(damaged)?;
    finish(doc, bin, scale)
}

/// `extras` with `relit` added to its `prt` object; `None` where it has none.
fn add_relit(extras: Option<&mut gltf_json::Extras>, relit: Value) -> Option<()> {
    let extras = extras?;
    let mut value = extras_value(extras)?;
    value
        .get_mut("prt")?
        .as_object_mut()?
        .insert("relit".into(), relit);
    *extras = raw_extras(&value).ok()?;
    Some(())
}

/// The largest component of `values` where it exceeds 1, else 1: what `COLOR_0` is divided by
/// to stay in [0, 1].
fn color_scale(values: &[[f32; 3]]) -> Result<f32> {
    let scale = values
        .iter()
        .flatten()
        .fold(1.0f32, |largest, &x| largest.max(x));
    match scale.is_finite() {
        true => Ok(scale),
        false => Err(Error::Options("the relit radiance is not finite".into())),
    }
}

/// The baked scene `bytes` (read from `path` as `gltf`) relit ([module docs](self)): each baked
/// primitive's `COLOR_0` becomes its vertices' `shading / scale` (negative values as 0),
/// `radiance` its [`RADIANCE_ATTRIBUTE`], its material unlit; `radiance` and `shading` hold
/// one value per vertex of the scene as read, in the order of `gltf`'s primitive spans. Gives
/// the bytes and the scale.
pub fn with_relit_scene_colors(
    bytes: &[u8],
    path: &Path,
    gltf: &GltfScene,
    radiance: &[[f32; 3]],
    shading: &[[f32; 3]],
    (light, lightmap): (&str, Option<&RelitLightmap>),
) -> Result<(Vec<u8>, f32)> {
    let damaged = |message: String| Error::baked(path, message);
    let (json, bin) = split_chunks(bytes, path)?;
    let mut bin = bin.to_vec();
    let mut doc = parse_document(json, path)?;
    let one_buffer = matches!(&doc.buffers[..], [buffer] if buffer.uri.is_none());
    if !one_buffer {
        return Err(damaged(
            "a scene baked in place holds one buffer, its BIN chunk; this one does not".into(),
        ));
    }
    let scale = color_scale(shading)?;
    let mut meshes = BTreeSet::new();
    let mut materials = BTreeSet::new();
    let mut unmaterialled = Vec::new();
    for instance in &gltf.instances {
        if !meshes.insert(instance.mesh) {
            return Err(damaged(format!(
                "mesh {} is shown by several nodes, which a scene baked in place never is",
                instance.mesh
            )));
        }
        for span in &instance.primitives {
            let range = span.first..span.first + span.count;
            let (Some(shaded), Some(radiant)) = (shading.get(range.clone()), radiance.get(range))
            else {
                return Err(damaged(format!(
                    "the relit values cover {} vertices; mesh {} needs more",
                    radiance.len().min(shading.len()),
                    instance.mesh
                )));
            };
            let colors = shaded.iter().map(|c| c.map(|x| x.max(0.0) / scale));
            let color = append_vec3s(&mut doc, &mut bin, colors);
            let radiant = append_vec3s(&mut doc, &mut bin, radiant.iter().copied());
            let (mesh, primitive) = (instance.mesh, span.primitive);
            set_attribute(&mut doc, mesh, primitive, "COLOR_0", color).map_err(damaged)?;
            let material = set_attribute(&mut doc, mesh, primitive, RADIANCE_ATTRIBUTE, radiant)
                .map_err(damaged)?;
            match material {
                Some(material) => {
                    materials.insert(material);
                }
                None => unmaterialled.push((mesh, primitive)),
            }
        }
    }
    make_unlit(&mut doc, &materials, &unmaterialled).map_err(damaged)?;
    let mut relit = json!({
        "color_0": RELIT_SCENE_COLOR,
        "scale": scale,
        "radiance": RELIT_RADIANCE,
        "materials": format!("{UNLIT} on every baked primitive's material"),
        "light": light,
    });
    if let Some(lightmap) = lightmap {
        relit["lightmap"] = lightmap_extras(lightmap, RELIT_SCENE_LIGHTMAP);
    }
    add_relit(Some(&mut doc.extras), relit)
        .ok_or_else(|| damaged("no extras.prt: not a scene baked in place".into()))?;
    finish(doc, bin, scale)
}

/// The materials `materials` made unlit, and the primitives `unmaterialled` given one white
/// unlit material of their own; the extension listed as used.
fn make_unlit(
    doc: &mut Document,
    materials: &BTreeSet<usize>,
    unmaterialled: &[(usize, usize)],
) -> std::result::Result<(), String> {
    let unlit = |material: &mut gltf_json::Material| {
        let extensions = material.extensions.get_or_insert_with(Default::default);
        extensions.others.insert(UNLIT.into(), json!({}));
    };
    for &material in materials {
        let material = doc
            .materials
            .get_mut(material)
            .ok_or(format!("material {material} does not exist"))?;
        unlit(material);
    }
    if !unmaterialled.is_empty() {
        let mut white = gltf_json::Material {
            name: Some("prt-gpu relit (unlit white)".into()),
            ..Default::default()
        };
        unlit(&mut white);
        doc.materials.push(white);
        let white = index(doc.materials.len() - 1);
        for &(mesh, primitive) in unmaterialled {
            doc.meshes[mesh].primitives[primitive].material = Some(white);
        }
    }
    if !doc.extensions_used.iter().any(|name| name == UNLIT) {
        doc.extensions_used.push(UNLIT.into());
    }
    Ok(())
}

/// The document and BIN chunk as a .glb, the buffer's length brought up to date.
fn finish(mut doc: Document, bin: Vec<u8>, scale: f32) -> Result<(Vec<u8>, f32)> {
    let mut bin = bin;
    bin.resize(bin.len().next_multiple_of(4), 0);
    if let Some(buffer) = doc.buffers.first_mut() {
        buffer.byte_length = USize64::from(bin.len());
    }
    Ok((glb_container(encode_document(&doc)?, bin)?, scale))
}

/// Appends `values` to the BIN chunk as a new buffer view (of vertex data, so its target is
/// set) and float `VEC3` accessor; gives the accessor's index.
fn append_vec3s(
    doc: &mut Document,
    bin: &mut Vec<u8>,
    values: impl ExactSizeIterator<Item = [f32; 3]>,
) -> usize {
    let count = values.len();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let offset = bin.len();
    bin.extend(values.flatten().flat_map(|x| x.to_le_bytes()));
    let view = doc.buffer_views.len();
    doc.buffer_views
        .push(array_view(offset, 12 * count, None, Target::ArrayBuffer));
    let vec3s = accessor(view, 0, ComponentType::F32, count, Type::Vec3);
    doc.accessors.push(gltf_json::Accessor {
        byte_offset: None,
        ..vec3s
    });
    doc.accessors.len() - 1
}

/// Points attribute `name` of mesh `mesh`'s primitive `primitive` at `accessor`; gives the
/// primitive's material.
fn set_attribute(
    doc: &mut Document,
    mesh: usize,
    primitive: usize,
    name: &str,
    accessor: usize,
) -> std::result::Result<Option<usize>, String> {
    let primitive = doc
        .meshes
        .get_mut(mesh)
        .and_then(|mesh| mesh.primitives.get_mut(primitive))
        .ok_or(format!("mesh {mesh} has no primitive {primitive}"))?;
    primitive.attributes.insert(semantic(name), index(accessor));
    Ok(primitive.material.map(|material| material.value()))
}

/// The BIN byte range of the first primitive's `COLOR_0`, which must be tightly packed float
/// `VEC3`, one per vertex.
fn color_range(
    doc: &Document,
    vertices: usize,
) -> std::result::Result<std::ops::Range<usize>, String> {
    let primitive = doc.meshes.first().and_then(|mesh| mesh.primitives.first());
    let index = primitive
        .and_then(|primitive| attribute(primitive, "COLOR_0"))
        .ok_or("the file has no COLOR_0 to hold the radiance")?;
    let accessor = doc
        .accessors
        .get(index)
        .ok_or("COLOR_0's accessor does not exist")?;
    if !accessor_is(accessor, ComponentType::F32, Type::Vec3) || accessor.count.0 != vertices as u64
    {
        return Err(format!("COLOR_0 is not {vertices} float VEC3 values"));
    }
    let view = accessor
        .buffer_view
        .ok_or("COLOR_0 has no buffer view")?
        .value();
    let view = doc
        .buffer_views
        .get(view)
        .ok_or("COLOR_0's buffer view does not exist")?;
    let stride = view.byte_stride.map_or(12, |stride| stride.0);
    if stride != 12 {
        return Err(format!("COLOR_0 is interleaved (stride {stride})"));
    }
    let start = view_start(view) + accessor_start(accessor);
    let start = usize::try_from(start).map_err(|_| "COLOR_0's offset overflows")?;
    Ok(start..start + 12 * vertices)
}

/// Writes [`with_relit_colors`] of the file at `source` to `output`, atomically; gives the
/// scale `COLOR_0` was divided by.
pub fn write_relit_copy(
    source: &Path,
    output: &Path,
    radiance: &[[f32; 3]],
    light_and_lightmap: (&str, Option<&RelitLightmap>),
) -> Result<f32> {
    check_destination(output)?;
    let bytes = std::fs::read(source).map_err(|e| Error::io(source, e))?;
    let (relit, scale) = with_relit_colors(&bytes, source, radiance, light_and_lightmap)?;
    write_atomically(output, &relit)?;
    Ok(scale)
}

/// Writes [`with_relit_scene_colors`] of the scene at `source` (read as `gltf`) to `output`,
/// atomically; gives the scale `COLOR_0` was divided by.
pub fn write_relit_scene_copy(
    source: &Path,
    output: &Path,
    gltf: &GltfScene,
    radiance: &[[f32; 3]],
    shading: &[[f32; 3]],
    light_and_lightmap: (&str, Option<&RelitLightmap>),
) -> Result<f32> {
    check_destination(output)?;
    let bytes = std::fs::read(source).map_err(|e| Error::io(source, e))?;
    let (relit, scale) =
        with_relit_scene_colors(&bytes, source, gltf, radiance, shading, light_and_lightmap)?;
    write_atomically(output, &relit)?;
    Ok(scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{BakeMetadata, BakedMesh, Mode, Transfer};
    use crate::scene::builtin;

    fn baked_bytes() -> (Vec<u8>, usize) {
        let scene = builtin::icosphere(glam::Vec3::ZERO, 1.0, 1);
        let (scene, _) = crate::scene::prepare::prepare(scene).unwrap();
        let v = scene.positions.len();
        let baked = BakedMesh {
            transfer: Transfer::new(1, 1, v, vec![0.5; v])
                .expect("a test transfer of its own shape"),
            metadata: BakeMetadata {
                tool: "prt-gpu".into(),
                tool_version: "test".into(),
                bands: 1,
                channels: 1,
                mode: Mode::Shadowed,
                samples: 1,
                sampling: "cosine".into(),
                seed: 1,
                backend: "cpu".into(),
                sh_convention: String::new(),
                radiometry: String::new(),
                bounces: 0,
                fit: Default::default(),
                fit_points: None,
                target_error: None,
                albedo_free: false,
                subsurface: None,
            },
            scene,
            lightmap: None,
        };
        (
            super::super::encode_glb(super::super::Stored::plain(&baked).unwrap()).unwrap(),
            v,
        )
    }

    #[test]
    fn colours_are_radiance_over_the_scale_and_the_rest_is_kept() {
        let (bytes, v) = baked_bytes();
        let mut radiance = vec![[0.25f32, 0.5, 0.75]; v];
        radiance[1] = [4.0, -1.0, 2.0];
        let (relit, scale) =
            with_relit_colors(&bytes, Path::new("a.glb"), &radiance, ("test", None)).unwrap();
        assert_eq!(scale, 4.0);
        // The radiance itself, unscaled and negative values kept, as _RADIANCE.
        let (json, bin) = split_chunks(&relit, Path::new("a.glb")).unwrap();
        let doc: serde_json::Value = serde_json::from_slice(json).unwrap();
        let accessor = &doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]
            [RADIANCE_ATTRIBUTE]
            .as_u64()
            .unwrap() as usize];
        let view = &doc["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap() as usize;
        let stored: Vec<f32> = bin[start..start + 12 * v]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!(
            stored,
            radiance.iter().flatten().copied().collect::<Vec<_>>()
        );
        assert_eq!(
            doc["buffers"][0]["byteLength"].as_u64(),
            Some(bin.len() as u64)
        );
        let back = super::super::decode_glb(&relit, Path::new("a.glb")).unwrap();
        let original = super::super::decode_glb(&bytes, Path::new("a.glb")).unwrap();
        assert_eq!(back.transfer, original.transfer);
        assert_eq!(back.scene.positions, original.scene.positions);
        assert_eq!(back.scene.albedo[0], glam::Vec3::new(0.0625, 0.125, 0.1875));
        assert_eq!(back.scene.albedo[1], glam::Vec3::new(1.0, 0.0, 0.5));
    }

    #[test]
    fn a_wrong_vertex_count_is_an_error() {
        let (bytes, v) = baked_bytes();
        let error = with_relit_colors(
            &bytes,
            Path::new("a.glb"),
            &vec![[0.0; 3]; v + 1],
            ("x", None),
        )
        .unwrap_err();
        assert!(error.to_string().contains("COLOR_0"), "{error}");
    }
}
