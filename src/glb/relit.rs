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

use std::path::Path;

use super::{glb_container, split_chunks, FLOAT};
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};

/// `extras.prt.relit.color_0`: what `COLOR_0` now holds.
pub const RELIT_COLOR: &str =
    "relit exit radiance / scale, linear RGB, negative values as 0 (was the albedo)";

/// The attribute that holds the relit radiance unscaled.
pub const RADIANCE_ATTRIBUTE: &str = "_RADIANCE";

/// `extras.prt.relit.radiance`: what [`RADIANCE_ATTRIBUTE`] holds.
pub const RELIT_RADIANCE: &str = "relit exit radiance, linear RGB, unscaled (W/(m^2 sr))";

/// The baked file `bytes` with `COLOR_0` replaced by `radiance / scale` (one per vertex),
/// `radiance` itself added as [`RADIANCE_ATTRIBUTE`], and `extras.prt.relit = {color_0,
/// scale, radiance, light}`; and the scale.
pub fn with_relit_colors(
    bytes: &[u8],
    path: &Path,
    radiance: &[[f32; 3]],
    light: &str,
) -> Result<(Vec<u8>, f32)> {
    let damaged = |message: String| Error::baked(path, message);
    let (json, bin) = split_chunks(bytes, path)?;
    let mut bin = bin.to_vec();
    let mut doc: serde_json::Value =
        serde_json::from_slice(json).map_err(|e| damaged(format!("invalid glTF JSON: {e}")))?;
    let range = color_range(&doc, radiance.len()).map_err(damaged)?;
    let target = bin
        .get_mut(range)
        .ok_or_else(|| damaged("COLOR_0 runs past the BIN chunk".into()))?;
    let scale = radiance
        .iter()
        .flatten()
        .fold(1.0f32, |largest, &x| largest.max(x));
    if !scale.is_finite() {
        return Err(Error::Options("the relit radiance is not finite".into()));
    }
    for (slot, value) in target.chunks_exact_mut(4).zip(radiance.iter().flatten()) {
        slot.copy_from_slice(&(value.max(0.0) / scale).to_le_bytes());
    }
    let prt = doc
        .pointer_mut("/meshes/0/extras/prt")
        .and_then(|p| p.as_object_mut())
        .ok_or_else(|| damaged("no extras.prt: not a baked file".into()))?;
    prt.insert(
        "relit".into(),
        serde_json::json!({
            "color_0": RELIT_COLOR,
            "scale": scale,
            "radiance": RELIT_RADIANCE,
            "light": light,
        }),
    );
    append_radiance(&mut doc, &mut bin, radiance).map_err(damaged)?;
    let json = serde_json::to_vec(&doc)
        .map_err(|e| Error::Geometry(format!("cannot encode the glTF JSON: {e}")))?;
    Ok((glb_container(json, bin)?, scale))
}

/// Appends `radiance` to the BIN chunk as a new buffer view and float `VEC3` accessor, the
/// first primitive's [`RADIANCE_ATTRIBUTE`].
fn append_radiance(
    doc: &mut serde_json::Value,
    bin: &mut Vec<u8>,
    radiance: &[[f32; 3]],
) -> std::result::Result<(), String> {
    bin.resize(bin.len().next_multiple_of(4), 0);
    let offset = bin.len();
    bin.extend(radiance.iter().flatten().flat_map(|x| x.to_le_bytes()));
    let mut push = |array: &str, item: serde_json::Value| -> std::result::Result<usize, String> {
        let list = doc
            .get_mut(array)
            .and_then(|a| a.as_array_mut())
            .ok_or(format!("the file has no {array}"))?;
        list.push(item);
        Ok(list.len() - 1)
    };
    let view = push(
        "bufferViews",
        serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": 12 * radiance.len()}),
    )?;
    let accessor = push(
        "accessors",
        serde_json::json!({
            "bufferView": view, "componentType": FLOAT, "count": radiance.len(), "type": "VEC3"
        }),
    )?;
    let attributes = doc
        .pointer_mut("/meshes/0/primitives/0/attributes")
        .and_then(|a| a.as_object_mut())
        .ok_or("the file has no primitive attributes")?;
    attributes.insert(RADIANCE_ATTRIBUTE.into(), accessor.into());
    let buffer = doc
        .pointer_mut("/buffers/0")
        .and_then(|b| b.as_object_mut())
        .ok_or("the file has no buffer")?;
    buffer.insert("byteLength".into(), bin.len().into());
    Ok(())
}

/// The BIN byte range of the first primitive's `COLOR_0`, which must be tightly packed float
/// `VEC3`, one per vertex.
fn color_range(
    doc: &serde_json::Value,
    vertices: usize,
) -> std::result::Result<std::ops::Range<usize>, String> {
    let index = doc
        .pointer("/meshes/0/primitives/0/attributes/COLOR_0")
        .and_then(|i| i.as_u64())
        .ok_or("the file has no COLOR_0 to hold the radiance")?;
    let accessor = doc
        .pointer(&format!("/accessors/{index}"))
        .ok_or("COLOR_0's accessor does not exist")?;
    let field = |name: &str| accessor.get(name).and_then(|v| v.as_u64());
    let is_vec3 = accessor.get("type").and_then(|t| t.as_str()) == Some("VEC3");
    if field("componentType") != Some(FLOAT as u64)
        || !is_vec3
        || field("count") != Some(vertices as u64)
    {
        return Err(format!("COLOR_0 is not {vertices} float VEC3 values"));
    }
    let view = field("bufferView").ok_or("COLOR_0 has no buffer view")?;
    let view = doc
        .pointer(&format!("/bufferViews/{view}"))
        .ok_or("COLOR_0's buffer view does not exist")?;
    let stride = view
        .get("byteStride")
        .and_then(|s| s.as_u64())
        .unwrap_or(12);
    if stride != 12 {
        return Err(format!("COLOR_0 is interleaved (stride {stride})"));
    }
    let start = view.get("byteOffset").and_then(|o| o.as_u64()).unwrap_or(0)
        + field("byteOffset").unwrap_or(0);
    let start = start as usize;
    Ok(start..start + 12 * vertices)
}

/// Writes [`with_relit_colors`] of the file at `source` to `output`, atomically; gives the
/// scale `COLOR_0` was divided by.
pub fn write_relit_copy(
    source: &Path,
    output: &Path,
    radiance: &[[f32; 3]],
    light: &str,
) -> Result<f32> {
    check_destination(output)?;
    let bytes = std::fs::read(source).map_err(|e| Error::io(source, e))?;
    let (relit, scale) = with_relit_colors(&bytes, source, radiance, light)?;
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
            transfer: Transfer {
                bands: 1,
                channels: 1,
                vertex_count: v,
                coeffs: vec![0.5; v],
            },
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
            },
            scene,
            lightmap: None,
        };
        (super::super::encode_glb(&baked).unwrap(), v)
    }

    #[test]
    fn colours_are_radiance_over_the_scale_and_the_rest_is_kept() {
        let (bytes, v) = baked_bytes();
        let mut radiance = vec![[0.25f32, 0.5, 0.75]; v];
        radiance[1] = [4.0, -1.0, 2.0];
        let (relit, scale) =
            with_relit_colors(&bytes, Path::new("a.glb"), &radiance, "test").unwrap();
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
        let error =
            with_relit_colors(&bytes, Path::new("a.glb"), &vec![[0.0; 3]; v + 1], "x").unwrap_err();
        assert!(error.to_string().contains("COLOR_0"), "{error}");
    }
}
