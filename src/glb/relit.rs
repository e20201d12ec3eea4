//! Relit radiance baked into vertex colours (`render ... -o relit.glb`): a copy of a baked
//! file whose `COLOR_0` holds each vertex's relit exit radiance (linear RGB) in place of its
//! albedo, and whose `extras.prt.relit` says so and under what light. Everything else is the
//! file as it was, so an engine shows the lit scene with no shader of ours, and a relit bake
//! can be compared with another renderer number for number.
//!
//! glTF keeps float colours in [0, 1] (the Khronos validator reports anything else as an
//! error), so the radiance is divided by `extras.prt.relit.scale`, the largest component
//! where that exceeds 1 (else 1): radiance = `COLOR_0 * scale`. Negative values (a
//! compressed operator's ringing in the dark) are stored as 0.

use std::path::Path;

use super::{check_bin_head, check_head, glb_container, FLOAT};
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};

/// `extras.prt.relit.color_0`: what `COLOR_0` now holds.
pub const RELIT_COLOR: &str =
    "relit exit radiance / scale, linear RGB, negative values as 0 (was the albedo)";

/// The baked file `bytes` with `COLOR_0` replaced by `radiance` (one per vertex) and
/// `extras.prt.relit = {color_0, light}`.
pub fn with_relit_colors(
    bytes: &[u8],
    path: &Path,
    radiance: &[[f32; 3]],
    light: &str,
) -> Result<Vec<u8>> {
    let damaged = |message: String| Error::baked(path, message);
    let head = bytes
        .get(..20)
        .ok_or_else(|| damaged("too short to be a glTF binary (.glb) file".into()))?;
    let json_len = check_head(head, bytes.len() as u64, path)?;
    let bin_start = 20 + json_len;
    let bin_head = bytes
        .get(bin_start..bin_start + 8)
        .ok_or_else(|| damaged("no BIN chunk after the JSON chunk".into()))?;
    let bin_len = check_bin_head(bin_head, bin_start as u64, bytes.len() as u64, path)?;
    let mut bin = bytes[bin_start + 8..bin_start + 8 + bin_len].to_vec();
    let mut doc: serde_json::Value = serde_json::from_slice(&bytes[20..bin_start])
        .map_err(|e| damaged(format!("invalid glTF JSON: {e}")))?;
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
        serde_json::json!({ "color_0": RELIT_COLOR, "scale": scale, "light": light }),
    );
    let json = serde_json::to_vec(&doc)
        .map_err(|e| Error::Geometry(format!("cannot encode the glTF JSON: {e}")))?;
    glb_container(json, bin)
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

/// Writes [`with_relit_colors`] of the file at `source` to `output`, atomically.
pub fn write_relit_copy(
    source: &Path,
    output: &Path,
    radiance: &[[f32; 3]],
    light: &str,
) -> Result<()> {
    check_destination(output)?;
    let bytes = std::fs::read(source).map_err(|e| Error::io(source, e))?;
    write_atomically(output, &with_relit_colors(&bytes, source, radiance, light)?)
}
