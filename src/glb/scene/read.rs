//! Reading a scene baked in place back (`info`, `render`, `view`): every placement's geometry
//! and its transfer — planar, half-float or compressed — and the lightmap it names.

use std::path::Path;

use gltf_json::mesh::Semantic;
use gltf_json::validation::Checked;
use gltf_json::Root;
use serde_json::{json, Value};

use crate::bake::{BakeMetadata, BakedMesh, Transfer};
use crate::error::{Error, Result};
use crate::glb::compressed::{self, CpcaExtras};
use crate::glb::zonal::{groups_of, zonal_attribute_name, ZonalExtras, AXIS_ATTRIBUTE};
use crate::glb::{groups, transfer_attribute_name, LightmapExtras, References, FLOAT16};
use crate::precision::Precision;
use crate::scene::gltf::accessor::{dense, view_bytes};
use crate::scene::gltf::{self, GltfScene};
use crate::scene::Scene;
use crate::zonal::{ZonalAxis, ZonalTransfer};

/// Whether `root` is a scene written by [`write_scene_glb`](super::write_scene_glb).
pub fn is_baked_in_place(root: &Root) -> bool {
    root.extras
        .as_ref()
        .and_then(|raw| serde_json::from_str::<Value>(raw.get()).ok())
        .is_some_and(|v| v["prt"]["baked_in_place"] == json!(true))
}

/// What a scene file (`bytes`, one that [`crate::glb::is_scene_file`] accepts) says about how
/// its transfer is stored, its JSON parsed once: the precision and compression of its first
/// baked mesh's `extras.prt` (every primitive's are alike), and the lightmap the root's
/// `extras.prt.lightmap` names.
pub(crate) fn stored_references(bytes: &[u8]) -> std::result::Result<References, String> {
    let document = json_of(bytes);
    let first_prt = |field: &str| -> Option<Value> {
        document["meshes"].as_array().and_then(|meshes| {
            meshes
                .iter()
                .map(|mesh| &mesh["extras"]["prt"][field])
                .find(|value| !value.is_null())
                .cloned()
        })
    };
    let precision = match first_prt("transfer_precision")
        .as_ref()
        .and_then(Value::as_str)
    {
        Some(FLOAT16) => Precision::F16,
        _ => Precision::F32,
    };
    let cpca = first_prt("cpca")
        .map(|cpca| {
            serde_json::from_value(cpca).map_err(|e| format!("invalid extras.prt.cpca: {e}"))
        })
        .transpose()?;
    Ok(References {
        precision,
        lightmap: lightmap_extras(&document)?,
        cpca,
    })
}

fn lightmap_extras(document: &Value) -> std::result::Result<Option<LightmapExtras>, String> {
    match &document["extras"]["prt"]["lightmap"] {
        Value::Null => Ok(None),
        extras => serde_json::from_value(extras.clone())
            .map(Some)
            .map_err(|e| format!("invalid extras.prt.lightmap: {e}")),
    }
}

/// The lightmap the root's `extras.prt.lightmap` of a loaded scene names, if any.
fn scene_lightmap(gltf: &GltfScene) -> std::result::Result<Option<LightmapExtras>, String> {
    let root_extras: Value = match &gltf.root.extras {
        Some(raw) => serde_json::from_str(raw.get()).map_err(|e| e.to_string())?,
        None => Value::Null,
    };
    lightmap_extras(&json!({ "extras": root_extras }))
}

/// The JSON chunk of a .glb, `Null` where there is none to parse.
fn json_of(bytes: &[u8]) -> Value {
    let json = bytes.get(12..20).and_then(|head| {
        let len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]) as usize;
        bytes.get(20..20usize.checked_add(len)?)
    });
    json.and_then(|json| serde_json::from_slice(json).ok())
        .unwrap_or(Value::Null)
}

/// Reads a scene written by [`write_scene_glb`](super::write_scene_glb) as one baked mesh in world space: every
/// placement's geometry and its transfer, for relighting and rendering. A scene with a lightmap
/// comes split at its triangle corners, each carrying its lightmap coordinates (its vertices'
/// own coordinates, shared by the corners).
pub fn read_scene_glb(path: &Path) -> Result<BakedMesh> {
    let (gltf, baked) = read_scene_vertices(path)?;
    with_scene_lightmap(path, &gltf, baked)
}

/// [`read_scene_glb`] and [`read_scene_zonal`] from one reading of the file.
pub fn read_scene_with_zonal(path: &Path) -> Result<(BakedMesh, Option<ZonalTransfer>)> {
    let (gltf, baked) = read_scene_vertices(path)?;
    let zonal = scene_zonal(path, &gltf, &baked)?;
    let corners = baked.scene.triangles.as_flattened().to_vec();
    let baked = with_scene_lightmap(path, &gltf, baked)?;
    let split = baked.lightmap.is_some();
    Ok((baked, zonal.map(|zonal| at_corners(zonal, &corners, split))))
}

/// A lightmapped scene is read split at its corners ([`read_scene_glb`]), and so is its zonal
/// transfer, each corner its vertex's (`corners`: the vertex of each triangle corner).
fn at_corners(zonal: ZonalTransfer, corners: &[u32], lightmapped: bool) -> ZonalTransfer {
    match lightmapped {
        true => zonal.select(corners),
        false => zonal,
    }
}

/// `baked` (a scene's vertices as read) with the scene's lightmap, if it has one: split at its
/// triangle corners, each carrying its lightmap coordinates.
fn with_scene_lightmap(path: &Path, gltf: &GltfScene, mut baked: BakedMesh) -> Result<BakedMesh> {
    let bad = |message: String| Error::baked(path, message);
    if let Some(extras) = scene_lightmap(gltf).map_err(bad)? {
        let uvs = gltf::texcoords(gltf, extras.texcoord)
            .map_err(bad)?
            .ok_or_else(|| {
                bad(format!(
                    "its lightmap lies on TEXCOORD_{}, which a baked primitive lacks",
                    extras.texcoord
                ))
            })?;
        let (scene, transfer) = crate::bake::split::split_corners(&baked.scene, &baked.transfer);
        let texcoords = baked
            .scene
            .triangles
            .iter()
            .flatten()
            .map(|&i| uvs[i as usize])
            .collect();
        baked.scene = scene;
        baked.transfer = transfer;
        baked.lightmap = Some(crate::glb::read_texels(path, &baked, extras, texcoords)?);
    }
    Ok(baked)
}

/// A scene written by [`write_scene_glb`](super::write_scene_glb) as read, and its baked mesh
/// in world space with one vertex per vertex of its primitives, in the order of the scene's
/// primitive spans (a lightmap, if any, not read).
pub fn read_scene_vertices(path: &Path) -> Result<(GltfScene, BakedMesh)> {
    let (gltf, scene) = gltf::load(path)?;
    let bad = |message: String| Error::baked(path, message);
    let metadata = scene_metadata(&gltf.root).map_err(bad)?;
    let transfer = gather_transfer(&gltf, &scene, &metadata).map_err(bad)?;
    let mut scene = scene;
    if scene.normals.is_none() {
        scene.normals = Some(crate::scene::prepare::smooth_normals(
            &scene.positions,
            &scene.triangles,
        ));
    }
    let baked = BakedMesh {
        scene,
        transfer,
        metadata,
        lightmap: None,
    };
    // What the single-mesh reader refuses value by value (a NaN position, an infinite
    // coefficient) is refused here for the scene as a whole.
    crate::glb::validate(&baked).map_err(|e| match e {
        Error::Geometry(message) => Error::baked(path, message),
        other => other,
    })?;
    Ok((gltf, baked))
}

/// The metadata of the first baked mesh.
fn scene_metadata(root: &Root) -> std::result::Result<BakeMetadata, String> {
    let extras = root
        .meshes
        .iter()
        .filter_map(|m| m.extras.as_ref())
        .find_map(|raw| {
            let value: Value = serde_json::from_str(raw.get()).ok()?;
            value.get("prt").cloned()
        })
        .ok_or("no mesh has extras.prt")?;
    let metadata =
        serde_json::from_value(extras).map_err(|e| format!("invalid extras.prt: {e}"))?;
    crate::glb::check_shape(&metadata)?;
    Ok(metadata)
}

/// The transfer of every placement, in the order of `scene`'s vertices.
fn gather_transfer(
    gltf: &GltfScene,
    scene: &Scene,
    metadata: &BakeMetadata,
) -> std::result::Result<Transfer, String> {
    let (bands, channels) = (metadata.bands, metadata.channels);
    let per_channel = (bands * bands) as usize;
    let groups = groups(bands);
    let mut coeffs = vec![0.0f32; scene.positions.len() * channels as usize * per_channel];
    for instance in &gltf.instances {
        let mesh = &gltf.root.meshes[instance.mesh];
        for span in &instance.primitives {
            let primitive = &mesh.primitives[span.primitive];
            if span.count == 0 {
                continue;
            }
            let in_mesh = |why: String| format!("mesh {}: {why}", instance.mesh);
            if let Some((extras, precision)) = clusters_of(primitive).map_err(in_mesh)? {
                let view = |index: usize, what: &str| {
                    view_bytes(&gltf.root, &gltf.buffers, index)
                        .map_err(|e| format!("the {what} view: {e}"))
                };
                let shape = (span.count, bands, channels);
                let cpca =
                    compressed::decode_with(&view, &extras, shape, precision).map_err(in_mesh)?;
                let stride = channels as usize * per_channel;
                coeffs[span.first * stride..(span.first + span.count) * stride]
                    .copy_from_slice(cpca.reconstruct().coeffs());
                continue;
            }
            let shape = (channels as usize, groups, span.count);
            let planar = match half_float_view(primitive)? {
                Some(view) => half_float_blocks(gltf, view, shape),
                None => attribute_blocks(gltf, primitive, shape),
            }
            .map_err(|why| format!("mesh {}: {why}", instance.mesh))?;
            // planar[(channel * groups + group) * count + v][lane]
            for (block, values) in planar.chunks_exact(4 * span.count).enumerate() {
                let (channel, group) = (block / groups, block % groups);
                for (v, lanes) in values.chunks_exact(4).enumerate() {
                    let row = ((span.first + v) * channels as usize + channel) * per_channel;
                    for (lane, &value) in lanes.iter().enumerate() {
                        let k = 4 * group + lane;
                        if k < per_channel {
                            coeffs[row + k] = value;
                        }
                    }
                }
            }
        }
    }
    Ok(
        Transfer::new(bands, channels, scene.positions.len(), coeffs)
            .expect("one row of coefficients for every scene vertex"),
    )
}

/// The compressed transfer a primitive's `extras.prt.cpca` describes, if any, and its precision.
fn clusters_of(
    primitive: &gltf_json::mesh::Primitive,
) -> std::result::Result<Option<(CpcaExtras, Precision)>, String> {
    let Some(raw) = &primitive.extras else {
        return Ok(None);
    };
    let extras: Value = serde_json::from_str(raw.get()).map_err(|e| e.to_string())?;
    let prt = &extras["prt"];
    if prt["cpca"].is_null() {
        return Ok(None);
    }
    let cpca = serde_json::from_value(prt["cpca"].clone())
        .map_err(|e| format!("invalid extras.prt.cpca: {e}"))?;
    let precision = match prt["transfer_precision"].as_str() {
        Some(FLOAT16) => Precision::F16,
        _ => Precision::F32,
    };
    Ok(Some((cpca, precision)))
}

/// The view a primitive's `extras.prt` names as its half-float transfer, if it has one.
fn half_float_view(
    primitive: &gltf_json::mesh::Primitive,
) -> std::result::Result<Option<usize>, String> {
    let Some(raw) = &primitive.extras else {
        return Ok(None);
    };
    let prt: Value = serde_json::from_str(raw.get()).map_err(|e| e.to_string())?;
    match prt["prt"]["transfer_precision"].as_str() {
        None => Ok(None),
        Some(FLOAT16) => prt["prt"]["transfer_buffer_view"]
            .as_u64()
            .map(|view| Some(view as usize))
            .ok_or_else(|| "a float16 primitive names no transfer_buffer_view".to_string()),
        Some(other) => Err(format!(
            "extras.prt.transfer_precision {other:?} is not one this reader knows (float16)"
        )),
    }
}

/// A primitive's half-float transfer view decoded: `(channels, groups, vertices)` planar
/// blocks of four lanes.
fn half_float_blocks(
    gltf: &GltfScene,
    view: usize,
    (channels, groups, vertices): (usize, usize, usize),
) -> std::result::Result<Vec<f32>, String> {
    let view = gltf
        .root
        .buffer_views
        .get(view)
        .ok_or_else(|| format!("transfer_buffer_view {view} does not exist"))?;
    let buffer = gltf
        .buffers
        .get(view.buffer.value())
        .ok_or("the transfer view's buffer does not exist")?;
    let start = view.byte_offset.map_or(0, |o| o.0) as usize;
    let expected = channels * groups * vertices * 4 * Precision::F16.bytes();
    if view.byte_length.0 as usize != expected {
        return Err(format!(
            "its float16 transfer view holds {} bytes where {expected} are needed",
            view.byte_length.0
        ));
    }
    let bytes = start
        .checked_add(expected)
        .and_then(|end| buffer.get(start..end))
        .ok_or("the transfer view runs past its buffer")?;
    Ok(Precision::F16.decode(bytes))
}

/// A primitive's `_PRT_*` attributes as `(channels, groups, vertices)` planar blocks.
fn attribute_blocks(
    gltf: &GltfScene,
    primitive: &gltf_json::mesh::Primitive,
    (channels, groups, vertices): (usize, usize, usize),
) -> std::result::Result<Vec<f32>, String> {
    let mut planar = Vec::with_capacity(channels * groups * vertices * 4);
    for channel in 0..channels as u32 {
        for group in 0..groups {
            let name = transfer_attribute_name(channels as u32, channel, group);
            let semantic = Semantic::Extras(name.trim_start_matches('_').to_string());
            let accessor = primitive
                .attributes
                .get(&Checked::Valid(semantic))
                .ok_or_else(|| format!("no attribute {name}"))?;
            let values = dense(&gltf.root, &gltf.buffers, accessor.value())?.vectors::<4>(&name)?;
            if values.len() != vertices {
                return Err(format!("{name} has the wrong length"));
            }
            planar.extend(values.iter().flatten());
        }
    }
    Ok(planar)
}

/// The zonal transfer of a scene written by [`write_scene_glb`](super::write_scene_glb) with
/// `--zonal`, every placement's, in the order of [`read_scene_vertices`]' vertices: each baked
/// primitive's `_PRT_ZH_*` attributes (and `_PRT_ZH_AXIS`, or its normals) as its
/// `extras.prt.zonal` describes them; split at the corners, as [`read_scene_glb`] reads it,
/// where the scene has a lightmap. `None` where the scene has none.
pub fn read_scene_zonal(path: &Path) -> Result<Option<ZonalTransfer>> {
    let (gltf, baked) = read_scene_vertices(path)?;
    let zonal = scene_zonal(path, &gltf, &baked)?;
    let lightmapped = scene_lightmap(&gltf)
        .map_err(|message| Error::baked(path, message))?
        .is_some();
    let corners = baked.scene.triangles.as_flattened();
    Ok(zonal.map(|zonal| at_corners(zonal, corners, lightmapped)))
}

/// The zonal transfer of the scene `gltf` at its vertices as read (`baked`), `None` where it
/// has none.
fn scene_zonal(path: &Path, gltf: &GltfScene, baked: &BakedMesh) -> Result<Option<ZonalTransfer>> {
    let bad = |message: String| Error::baked(path, message);
    let normals = baked.scene.normals.as_deref().unwrap_or_default();
    let mut shape: Option<ZonalExtras> = None;
    let (mut axes, mut coeffs) = (Vec::new(), Vec::new());
    for instance in &gltf.instances {
        let mesh = &gltf.root.meshes[instance.mesh];
        for span in &instance.primitives {
            let primitive = &mesh.primitives[span.primitive];
            let in_mesh = |why: String| bad(format!("mesh {}: {why}", instance.mesh));
            let Some(extras) = primitive_zonal(primitive).map_err(in_mesh)? else {
                if shape.is_some() {
                    return Err(in_mesh("a baked primitive has no extras.prt.zonal".into()));
                }
                continue;
            };
            let first = shape.get_or_insert_with(|| extras.clone());
            if (first.bands, first.channels, &first.axis)
                != (extras.bands, extras.channels, &extras.axis)
            {
                return Err(in_mesh(
                    "primitives with zonal transfer of different shapes".into(),
                ));
            }
            let span_normals = &normals[span.first..span.first + span.count];
            let (span_axes, span_coeffs) =
                primitive_zonal_values(gltf, primitive, &extras, span_normals).map_err(in_mesh)?;
            axes.extend(span_axes);
            coeffs.extend(span_coeffs);
        }
    }
    let Some(shape) = shape else {
        return Ok(None);
    };
    if axes.len() != baked.scene.vertex_count() {
        return Err(bad("zonal transfer on some baked primitives only".into()));
    }
    let axis = match shape.axis.as_str() {
        "fitted" => ZonalAxis::Fitted,
        _ => ZonalAxis::Normal,
    };
    ZonalTransfer::new((shape.bands, shape.channels, axis), axes, coeffs)
        .map(Some)
        .map_err(bad)
}

/// A primitive's `extras.prt.zonal`, if any.
fn primitive_zonal(
    primitive: &gltf_json::mesh::Primitive,
) -> std::result::Result<Option<ZonalExtras>, String> {
    let Some(raw) = &primitive.extras else {
        return Ok(None);
    };
    let extras: Value = serde_json::from_str(raw.get()).map_err(|e| e.to_string())?;
    let zonal = &extras["prt"]["zonal"];
    if zonal.is_null() {
        return Ok(None);
    }
    let zonal: ZonalExtras = serde_json::from_value(zonal.clone())
        .map_err(|e| format!("invalid extras.prt.zonal: {e}"))?;
    zonal.check()?;
    Ok(Some(zonal))
}

/// A primitive's zonal axes (its `_PRT_ZH_AXIS`, or `normals` about the normal) and
/// coefficients, `[vertex][channel][l]`, from its attributes.
fn primitive_zonal_values(
    gltf: &GltfScene,
    primitive: &gltf_json::mesh::Primitive,
    extras: &ZonalExtras,
    normals: &[glam::Vec3],
) -> std::result::Result<(Vec<glam::Vec3>, Vec<f32>), String> {
    let vertices = normals.len();
    let attribute = |name: &str| {
        let semantic = Semantic::Extras(name.trim_start_matches('_').to_string());
        primitive
            .attributes
            .get(&Checked::Valid(semantic))
            .ok_or_else(|| format!("no attribute {name}"))
            .and_then(|accessor| dense(&gltf.root, &gltf.buffers, accessor.value()))
    };
    let (bands, channels) = (extras.bands as usize, extras.channels as usize);
    let mut coeffs = vec![0.0f32; vertices * channels * bands];
    for channel in 0..channels {
        for group in 0..groups_of(bands) {
            let name = zonal_attribute_name(extras.channels, channel as u32, group);
            let values = attribute(&name)?.vectors::<4>(&name)?;
            if values.len() != vertices {
                return Err(format!("{name} has the wrong length"));
            }
            let lanes = values.iter().map(|lanes| &lanes[..]);
            extras.unpack_block(&mut coeffs, (channel, group), lanes);
        }
    }
    let axes = match extras.axis.as_str() {
        "fitted" => {
            let axes = attribute(AXIS_ATTRIBUTE)?.vectors::<3>(AXIS_ATTRIBUTE)?;
            if axes.len() != vertices {
                return Err(format!("{AXIS_ATTRIBUTE} has the wrong length"));
            }
            axes.into_iter().map(glam::Vec3::from_array).collect()
        }
        "normal" => normals.to_vec(),
        other => return Err(format!("extras.prt.zonal: axis \"{other}\"")),
    };
    Ok((axes, coeffs))
}
