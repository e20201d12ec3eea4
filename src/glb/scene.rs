//! Bake in place: a glTF scene written back as it came — its nodes, meshes, materials,
//! textures, cameras, skins, animations and names — in one `.glb`, with the transfer added to
//! every baked primitive as the `_PRT_*` attributes of the single-mesh format (module
//! [`super`]), so `prt-gpu info`, `render` and the numpy recipe read it as they read that.
//!
//! What changes, and why:
//! - every accessor gets a buffer view of its own in the one BIN buffer, densely packed
//!   (sparse accessors substituted, vertex attributes padded to 4-byte elements); external
//!   and `data:` resources, images included, are embedded;
//! - POSITION and NORMAL accessors become float and index accessors unsigned 32-bit (same
//!   values), so a reader needs to know no quantization to find the geometry;
//! - a mesh shown by several nodes sees different occlusion at each place: every placement
//!   after the first gets its own copy of the mesh (sharing all but the transfer);
//! - `extras.prt` of each baked mesh holds the bake's metadata and, for its first primitive,
//!   `vertices` and `transfer_buffer_view`; each baked primitive's own `extras.prt` holds its
//!   `vertices` and `transfer_buffer_view`; the root's `extras.prt.baked_in_place` is true;
//! - half-float transfer (`--precision f16`) has no accessor type in glTF: each primitive's
//!   view is named by its `extras.prt` alone, with `transfer_precision: "float16"`, and it has
//!   no `_PRT_*` attributes. Lean transfer leaves out the material's base colour.
//!
//! The transfer of a placement is in world space: it relights the scene as placed.

use std::collections::BTreeSet;
use std::path::Path;

use gltf_json::accessor::{ComponentType, GenericComponentType, Type};
use gltf_json::buffer::{Stride, Target};
use gltf_json::mesh::Semantic;
use gltf_json::validation::{Checked, USize64};
use gltf_json::{Index, Root};
use serde_json::{json, Value};

use super::{
    glb_container, groups, transfer_attribute_name, FLOAT16, TRANSFER_LAYOUT, TRANSFER_LAYOUT_F16,
};
use crate::bake::{BakeMetadata, BakedMesh, Transfer};
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};
use crate::precision::Precision;
use crate::scene::gltf::accessor::{component_size, dense, Dense};
use crate::scene::gltf::{self, GltfScene};
use crate::scene::prepare::DROPPED;
use crate::scene::Scene;

/// What writing a scene did, for the report line.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SceneWrite {
    pub primitives_baked: usize,
    /// Meshes copied because several nodes show them.
    pub mesh_copies: usize,
    /// Accessors whose NaN or infinite values were written repaired, one line each.
    pub repaired: Vec<String>,
}

/// Writes `gltf` with the transfer of `baked` (whose vertex `vertex_map[i]` is vertex `i` of
/// the scene `gltf` was loaded into) to `path`, atomically.
pub fn write_scene_glb(
    path: &Path,
    gltf: &GltfScene,
    baked: &BakedMesh,
    vertex_map: &[u32],
    precision: Precision,
) -> Result<SceneWrite> {
    check_destination(path)?;
    let (bytes, report) = encode_scene_glb(gltf, baked, vertex_map, precision)?;
    write_atomically(path, &bytes)?;
    Ok(report)
}

/// [`write_scene_glb`] in memory.
pub fn encode_scene_glb(
    gltf: &GltfScene,
    baked: &BakedMesh,
    vertex_map: &[u32],
    precision: Precision,
) -> Result<(Vec<u8>, SceneWrite)> {
    let bad = |message: String| Error::Geometry(format!("cannot write the scene: {message}"));
    let mut root = gltf.root.clone();
    let mut bin = Bin::default();
    let repaired = embed_accessors(&mut root, &gltf.buffers, &mut bin).map_err(bad)?;
    embed_images(&mut root, gltf, &mut bin);
    let report = SceneWrite {
        repaired,
        ..add_transfer(&mut root, gltf, (baked, precision), vertex_map, &mut bin).map_err(bad)?
    };
    root.buffers = vec![gltf_json::Buffer {
        byte_length: USize64(bin.bytes.len() as u64),
        name: None,
        uri: None,
        extensions: None,
        extras: None,
    }];
    root.buffer_views = bin.views;
    root.extras = raw(&json!({ "prt": { "baked_in_place": true } }))?;
    root.asset.generator = Some(format!(
        "prt-gpu {} (bake in place)",
        env!("CARGO_PKG_VERSION")
    ));
    let encode =
        |e: serde_json::Error| Error::Geometry(format!("cannot encode the glTF JSON: {e}"));
    let mut document = serde_json::to_value(&root).map_err(encode)?;
    // gltf-json writes some absent optional properties as null, which glTF does not allow.
    drop_nulls(&mut document);
    let json_bytes = serde_json::to_vec(&document).map_err(encode)?;
    Ok((glb_container(json_bytes, bin.bytes)?, report))
}

fn drop_nulls(value: &mut Value) {
    match value {
        Value::Object(fields) => {
            fields.retain(|_, v| !v.is_null());
            fields.values_mut().for_each(drop_nulls);
        }
        Value::Array(items) => items.iter_mut().for_each(drop_nulls),
        _ => {}
    }
}

fn raw(value: &Value) -> Result<gltf_json::Extras> {
    serde_json::value::to_raw_value(value)
        .map(Some)
        .map_err(|e| Error::Geometry(format!("cannot encode extras: {e}")))
}

/// The BIN chunk being built and its buffer views.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<gltf_json::buffer::View>,
}

impl Bin {
    /// Appends `bytes` as a new 4-byte aligned view; returns its index.
    fn push(&mut self, bytes: &[u8], stride: Option<usize>, target: Option<Target>) -> u32 {
        self.bytes.resize(self.bytes.len().next_multiple_of(4), 0);
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(bytes);
        self.views.push(gltf_json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64(bytes.len() as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: stride.map(Stride),
            name: None,
            target: target.map(Checked::Valid),
            extensions: None,
            extras: None,
        });
        (self.views.len() - 1) as u32
    }
}

/// How each accessor is used by the meshes, which decides how it is written.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
struct Use {
    vertex_attribute: bool,
    /// POSITION or NORMAL of a primitive: written as float.
    geometry: bool,
    indices: bool,
    /// The NORMAL of this primitive (mesh, primitive): repaired from its geometry.
    normal_of: Option<(usize, usize)>,
}

fn accessor_uses(root: &Root) -> Vec<Use> {
    let mut uses = vec![Use::default(); root.accessors.len()];
    let mut mark = |index: usize, f: &dyn Fn(&mut Use)| {
        if let Some(u) = uses.get_mut(index) {
            f(u)
        }
    };
    let primitives = root.meshes.iter().enumerate().flat_map(|(m, mesh)| {
        mesh.primitives
            .iter()
            .enumerate()
            .map(move |(p, primitive)| ((m, p), primitive))
    });
    for (place, primitive) in primitives {
        for (semantic, accessor) in &primitive.attributes {
            let geometry = matches!(
                semantic,
                Checked::Valid(Semantic::Positions | Semantic::Normals)
            );
            let normal = matches!(semantic, Checked::Valid(Semantic::Normals));
            mark(accessor.value(), &|u| {
                u.vertex_attribute = true;
                u.geometry |= geometry;
                if normal {
                    u.normal_of.get_or_insert(place);
                }
            });
        }
        for target in primitive.targets.iter().flatten() {
            for accessor in [&target.positions, &target.normals, &target.tangents]
                .into_iter()
                .flatten()
            {
                mark(accessor.value(), &|u| u.vertex_attribute = true);
            }
        }
        if let Some(indices) = primitive.indices {
            mark(indices.value(), &|u| u.indices = true);
        }
    }
    uses
}

/// Rewrites every accessor into a view of its own in `bin`; says which had NaN or infinite
/// values, written repaired.
fn embed_accessors(
    root: &mut Root,
    buffers: &[Vec<u8>],
    bin: &mut Bin,
) -> std::result::Result<Vec<String>, String> {
    let uses = accessor_uses(root);
    let mut repaired = Vec::new();
    for (index, usage) in uses.iter().enumerate() {
        let data = dense(root, buffers, index)?;
        let (mut data, mut recompute_bounds) = if usage.geometry && !usage.indices {
            (
                as_float(&data),
                data.component != ComponentType::F32 || data.normalized,
            )
        } else if usage.indices && !usage.vertex_attribute {
            (as_u32(&data)?, false)
        } else {
            (data, false)
        };
        if let Some(said) = repair_non_finite(root, buffers, index, usage, &mut data) {
            repaired.push(said);
            recompute_bounds |= root.accessors[index].min.is_some();
        }
        let accessor = &mut root.accessors[index];
        let element = data.components * component_size(data.component);
        let (bytes, stride) = if usage.vertex_attribute && !element.is_multiple_of(4) {
            (
                pad_elements(&data.bytes, element),
                Some(element.next_multiple_of(4)),
            )
        } else {
            (data.bytes.clone(), None)
        };
        let target = if usage.vertex_attribute {
            Some(Target::ArrayBuffer)
        } else if usage.indices {
            Some(Target::ElementArrayBuffer)
        } else {
            None
        };
        let view = bin.push(&bytes, stride, target);
        accessor.buffer_view = Some(Index::new(view));
        accessor.byte_offset = None;
        accessor.sparse = None;
        accessor.component_type = Checked::Valid(GenericComponentType(data.component));
        accessor.normalized = data.normalized;
        if recompute_bounds {
            let (min, max) = bounds(&data);
            accessor.min = Some(json!(min));
            accessor.max = Some(json!(max));
        } else if usage.indices && !usage.vertex_attribute {
            accessor.min = None;
            accessor.max = None;
        }
    }
    Ok(repaired)
}

/// Replaces what a reader cannot use in accessor `index`: a primitive's normals that are NaN,
/// infinite or zero by the smooth normals of its triangles (`prepare` baked with computed
/// ones too), any other NaN or infinite float by zero (a morph target's zero moves nothing).
/// Says what it did; `None` where nothing needed it.
fn repair_non_finite(
    root: &Root,
    buffers: &[Vec<u8>],
    index: usize,
    usage: &Use,
    data: &mut Dense,
) -> Option<String> {
    if data.component != ComponentType::F32 {
        return None;
    }
    let mut values = data.floats();
    let name = root.accessors[index].name.as_deref().unwrap_or("");
    let unusable = |e: &[f32]| !e.iter().all(|v| v.is_finite()) || e.iter().all(|&v| v == 0.0);
    if let Some((mesh, primitive)) = usage.normal_of.filter(|_| data.components == 3) {
        let bad = values.chunks_exact(3).filter(|e| unusable(e)).count();
        let computed = (bad > 0)
            .then(|| primitive_normals(root, buffers, mesh, primitive))
            .flatten()
            .filter(|normals| normals.len() == data.count);
        if let Some(normals) = computed {
            for (element, normal) in values.chunks_exact_mut(3).zip(normals) {
                if unusable(element) {
                    element.copy_from_slice(&normal.to_array());
                }
            }
            data.bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            return Some(format!(
                "accessor {index} {name:?} had {bad} normal(s) NaN, infinite or zero, written \
                 as the normals computed from its triangles"
            ));
        }
    }
    let bad = values.iter().filter(|v| !v.is_finite()).count();
    if bad == 0 {
        return None;
    }
    values
        .iter_mut()
        .filter(|v| !v.is_finite())
        .for_each(|v| *v = 0.0);
    data.bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    Some(format!(
        "accessor {index} {name:?} had {bad} NaN or infinite value(s), written as zeros"
    ))
}

/// The smooth normals of a primitive's own triangles, in its own space; `None` where its
/// geometry does not give them.
fn primitive_normals(
    root: &Root,
    buffers: &[Vec<u8>],
    mesh: usize,
    primitive: usize,
) -> Option<Vec<glam::Vec3>> {
    let primitive = root.meshes.get(mesh)?.primitives.get(primitive)?;
    let positions = primitive
        .attributes
        .get(&Checked::Valid(Semantic::Positions))?;
    let positions: Vec<glam::Vec3> = dense(root, buffers, positions.value())
        .ok()?
        .vectors::<3>("POSITION")
        .ok()?
        .into_iter()
        .map(glam::Vec3::from_array)
        .collect();
    if !positions.iter().all(|p| p.is_finite()) {
        return None;
    }
    let triangles = gltf::triangle_list(root, buffers, primitive, "primitive").ok()??;
    let normals = crate::scene::prepare::smooth_normals(&positions, &triangles);
    // A vertex in no triangle has no normal to compute: any unit vector is as good as another.
    Some(
        normals
            .into_iter()
            .map(|n| {
                if n.is_finite() && n != glam::Vec3::ZERO {
                    n
                } else {
                    glam::Vec3::Z
                }
            })
            .collect(),
    )
}

fn as_float(data: &Dense) -> Dense {
    Dense {
        count: data.count,
        components: data.components,
        component: ComponentType::F32,
        normalized: false,
        bytes: data.floats().iter().flat_map(|f| f.to_le_bytes()).collect(),
    }
}

fn as_u32(data: &Dense) -> std::result::Result<Dense, String> {
    Ok(Dense {
        count: data.count,
        components: 1,
        component: ComponentType::U32,
        normalized: false,
        bytes: data
            .indices()?
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
    })
}

fn pad_elements(bytes: &[u8], element: usize) -> Vec<u8> {
    let padded = element.next_multiple_of(4);
    let mut out = Vec::with_capacity(bytes.len() / element.max(1) * padded);
    for item in bytes.chunks_exact(element) {
        out.extend_from_slice(item);
        out.resize(out.len() + padded - element, 0);
    }
    out
}

/// Per-component minimum and maximum of float data.
fn bounds(data: &Dense) -> (Vec<f32>, Vec<f32>) {
    let floats = data.floats();
    let mut min = vec![f32::INFINITY; data.components];
    let mut max = vec![f32::NEG_INFINITY; data.components];
    for element in floats.chunks_exact(data.components) {
        for (c, &v) in element.iter().enumerate() {
            min[c] = min[c].min(v);
            max[c] = max[c].max(v);
        }
    }
    (min, max)
}

/// Every image as a view of its encoded bytes.
fn embed_images(root: &mut Root, gltf: &GltfScene, bin: &mut Bin) {
    for (image, encoded) in root.images.iter_mut().zip(&gltf.images) {
        let view = bin.push(&encoded.bytes, None, None);
        image.buffer_view = Some(Index::new(view));
        image.uri = None;
        image.mime_type = Some(gltf_json::image::MimeType(encoded.mime_type.clone()));
    }
}

/// Adds the transfer of every baked primitive, copying meshes shown twice: the `_PRT_*`
/// attributes of its float32 view, or (float16, which no accessor can describe) the view alone,
/// named in the primitive's `extras.prt`.
fn add_transfer(
    root: &mut Root,
    gltf: &GltfScene,
    (baked, precision): (&BakedMesh, Precision),
    vertex_map: &[u32],
    bin: &mut Bin,
) -> std::result::Result<SceneWrite, String> {
    let mut report = SceneWrite::default();
    let mut baked_meshes = BTreeSet::new();
    for instance in &gltf.instances {
        let mesh = if baked_meshes.insert(instance.mesh) {
            instance.mesh
        } else {
            let copy = root.meshes[instance.mesh].clone();
            root.meshes.push(copy);
            report.mesh_copies += 1;
            root.meshes.len() - 1
        };
        root.nodes[instance.node].mesh = Some(Index::new(mesh as u32));
        let mut first_primitive = None;
        for span in &instance.primitives {
            let map = &vertex_map[span.first..span.first + span.count];
            let view = push_transfer(bin, &baked.transfer, map, precision);
            let primitive = &mut root.meshes[mesh].primitives[span.primitive];
            let mut prt = json!({
                "vertices": span.count,
                "transfer_buffer_view": view,
            });
            match precision {
                Precision::F32 => add_attributes(
                    &mut root.accessors,
                    primitive,
                    &baked.transfer,
                    view,
                    span.count,
                ),
                Precision::F16 => prt["transfer_precision"] = json!(FLOAT16),
            }
            primitive.extras = raw(&json!({ "prt": prt })).map_err(|e| e.to_string())?;
            first_primitive.get_or_insert((span.count, view));
            report.primitives_baked += 1;
        }
        if let Some((vertices, view)) = first_primitive {
            root.meshes[mesh].extras = mesh_extras(&baked.metadata, vertices, view, precision)?;
        }
    }
    Ok(report)
}

fn mesh_extras(
    metadata: &BakeMetadata,
    vertices: usize,
    view: u32,
    precision: Precision,
) -> std::result::Result<gltf_json::Extras, String> {
    let mut prt = serde_json::to_value(metadata).map_err(|e| e.to_string())?;
    if let Value::Object(fields) = &mut prt {
        fields.insert("vertices".into(), json!(vertices));
        fields.insert("transfer_buffer_view".into(), json!(view));
        let layout = match precision {
            Precision::F32 => TRANSFER_LAYOUT,
            Precision::F16 => {
                fields.insert("transfer_precision".into(), json!(FLOAT16));
                TRANSFER_LAYOUT_F16
            }
        };
        fields.insert("transfer_layout".into(), json!(layout));
    }
    raw(&json!({ "prt": prt })).map_err(|e| e.to_string())
}

/// The transfer of the vertices `map` names, planar `[channel][group][vertex][4]` as in the
/// single-mesh format, at `precision`; dropped vertices (in no baked triangle) get zeros.
fn push_transfer(bin: &mut Bin, transfer: &Transfer, map: &[u32], precision: Precision) -> u32 {
    let groups = groups(transfer.bands);
    let vertices = map.len();
    let mut bytes =
        Vec::with_capacity(transfer.channels as usize * groups * vertices * 4 * precision.bytes());
    for channel in 0..transfer.channels as usize {
        for group in 0..groups {
            for &vertex in map {
                let coeffs =
                    (vertex != DROPPED).then(|| transfer.vertex_channel(vertex as usize, channel));
                let lanes: [f32; 4] = std::array::from_fn(|lane| {
                    coeffs
                        .and_then(|c| c.get(4 * group + lane).copied())
                        .unwrap_or(0.0)
                });
                precision.encode(&lanes, &mut bytes);
            }
        }
    }
    match precision {
        Precision::F32 => bin.push(&bytes, Some(16), Some(Target::ArrayBuffer)),
        Precision::F16 => bin.push(&bytes, None, None),
    }
}

/// One VEC4 float accessor per `(channel, group)` into `view`, named as attributes.
fn add_attributes(
    accessors: &mut Vec<gltf_json::Accessor>,
    primitive: &mut gltf_json::mesh::Primitive,
    transfer: &Transfer,
    view: u32,
    vertices: usize,
) {
    let groups = groups(transfer.bands);
    for channel in 0..transfer.channels {
        for group in 0..groups {
            let block = channel as usize * groups + group;
            accessors.push(gltf_json::Accessor {
                buffer_view: Some(Index::new(view)),
                byte_offset: Some(USize64((block * vertices * 16) as u64)),
                count: USize64(vertices as u64),
                component_type: Checked::Valid(GenericComponentType(ComponentType::F32)),
                extensions: None,
                extras: None,
                type_: Checked::Valid(Type::Vec4),
                min: None,
                max: None,
                name: None,
                normalized: false,
                sparse: None,
            });
            let name = transfer_attribute_name(transfer.channels, channel, group);
            let semantic = Semantic::Extras(name.trim_start_matches('_').to_string());
            primitive.attributes.insert(
                Checked::Valid(semantic),
                Index::new((accessors.len() - 1) as u32),
            );
        }
    }
}

/// Whether `root` is a scene written by [`write_scene_glb`].
pub fn is_baked_in_place(root: &Root) -> bool {
    root.extras
        .as_ref()
        .and_then(|raw| serde_json::from_str::<Value>(raw.get()).ok())
        .is_some_and(|v| v["prt"]["baked_in_place"] == json!(true))
}

/// How the transfer of a scene file (`bytes`, one that [`super::is_scene_file`] accepts) is
/// stored, from its first baked mesh's `extras.prt`.
pub(crate) fn stored_precision(bytes: &[u8]) -> Precision {
    let json = bytes.get(12..20).and_then(|head| {
        let len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]) as usize;
        bytes.get(20..20usize.checked_add(len)?)
    });
    let document: Value = json
        .and_then(|json| serde_json::from_slice(json).ok())
        .unwrap_or(Value::Null);
    let half = document["meshes"].as_array().is_some_and(|meshes| {
        meshes
            .iter()
            .find_map(|mesh| mesh["extras"]["prt"]["transfer_precision"].as_str())
            == Some(FLOAT16)
    });
    match half {
        true => Precision::F16,
        false => Precision::F32,
    }
}

/// Reads a scene written by [`write_scene_glb`] as one baked mesh in world space: every
/// placement's geometry and its transfer, for relighting and rendering.
pub fn read_scene_glb(path: &Path) -> Result<BakedMesh> {
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
    super::validate(&baked).map_err(|e| match e {
        Error::Geometry(message) => Error::baked(path, message),
        other => other,
    })?;
    Ok(baked)
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
    super::check_shape(&metadata)?;
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
    Ok(Transfer {
        bands,
        channels,
        vertex_count: scene.positions.len(),
        coeffs,
    })
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
