//! The baked file: one self-contained glTF 2.0 binary (`.glb`).
//!
//! Why glTF: engines load it as is (the transfer travels as standard custom vertex attributes),
//! and a reader needs nothing but a JSON parser and a way to view little-endian floats
//! (see [`PYTHON_READER`]).
//!
//! Layout (byte for byte deterministic: no timestamps, struct-ordered JSON keys):
//! - one buffer, the BIN chunk, holding five 4-byte aligned buffer views:
//!   0 positions, 1 normals, 2 albedo (`COLOR_0`), all `VEC3` float; 3 indices (`u32`);
//!   4 the transfer coefficients.
//! - the transfer view is planar, in groups of four coefficients:
//!   `[channel][group][vertex][lane]` float32, coefficient `k = 4 * group + lane`, lanes past
//!   `bands^2` zero. Each `(channel, group)` block is the `VEC4` custom attribute
//!   `_PRT_<R|G|B>_<group>` (`_PRT_<group>` for one channel), so a shader reads one `vec4`
//!   per group and channel.
//! - mesh `extras.prt` holds every [`BakeMetadata`] field, plus `vertices`,
//!   `transfer_buffer_view` and `transfer_layout` ([`TRANSFER_LAYOUT`]).
//! - with a lightmap (`bake --lightmap`): a sixth view, the lightmap coordinates as
//!   `TEXCOORD_0` (`VEC2` float, one pair per vertex; every triangle corner is its own vertex),
//!   and `extras.prt.lightmap` = `{uri, width, height, texcoord: 0, layout}`, `uri` naming the
//!   OpenEXR file beside the .glb that holds the per-texel transfer (`crate::lightmap`).

use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::{self, Read};
use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bake::{BakeMetadata, BakedMesh, TexelBake, Transfer};
use crate::compress::Cpca;
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};
use compressed::CpcaExtras;

pub mod compressed;
pub mod local;
pub mod relit;
pub mod scene;
pub mod stream;
use crate::scene::Scene;

/// `extras.prt.transfer_precision` of a half-float transfer view.
const FLOAT16: &str = "float16";

/// How the transfer buffer view is laid out; written into `extras.prt.transfer_layout` and
/// checked on reading, so a future layout change cannot be misread silently.
pub const TRANSFER_LAYOUT: &str = "planar [channel][group][vertex][4] float32 little-endian, \
coefficient k = 4*group + lane, lanes past bands^2 are zero";

/// The layout of a half-float transfer view (`bake --precision f16`), which no accessor
/// describes: glTF has no half-float component type, so the `_PRT_*` attributes are left out
/// and `extras.prt.transfer_precision` is `"float16"`.
pub const TRANSFER_LAYOUT_F16: &str = "planar [channel][group][vertex][4] float16 little-endian, \
coefficient k = 4*group + lane, lanes past bands^2 are zero";

pub use crate::precision::Precision;

/// `transfer` as a half-float file stores it: every coefficient rounded to the nearest f16.
pub fn rounded_to_f16(transfer: &Transfer) -> Transfer {
    Transfer {
        coeffs: Precision::F16.round_all(&transfer.coeffs),
        ..transfer.clone()
    }
}

/// Reads a baked file with Python and numpy alone: `python3 reader.py file.glb`.
///
/// Gives `positions` (V, 3), `indices` (T, 3) and `transfer` (V, channels, bands^2), and prints
/// their shapes and the last vertex's transfer as JSON.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
bv, acc = gltf["bufferViews"], gltf["accessors"]
view = lambda i, dtype: np.frombuffer(binary, dtype, bv[i]["byteLength"] // np.dtype(dtype).itemsize, bv[i].get("byteOffset", 0))
prim, prt = gltf["meshes"][0]["primitives"][0], gltf["meshes"][0]["extras"]["prt"]
positions = view(acc[prim["attributes"]["POSITION"]]["bufferView"], "<f4").reshape(-1, 3)
indices = view(acc[prim["indices"]]["bufferView"], "<u4").reshape(-1, 3)
V, C, K, f = prt["vertices"], prt["channels"], prt["bands"] ** 2, "<f2" if prt.get("transfer_precision") == "float16" else "<f4"
transfer = view(prt["transfer_buffer_view"], f).astype(np.float32).reshape(C, -1, V, 4).transpose(2, 0, 1, 3).reshape(V, C, -1)[:, :, :K]
print(json.dumps({"positions": positions.shape, "indices": indices.shape, "transfer": transfer.shape, "last_vertex": transfer[-1].tolist()}))
"#;

/// Name of the custom vertex attribute holding coefficients `4 * group .. 4 * group + 3` of
/// `channel`.
pub fn transfer_attribute_name(channels: u32, channel: u32, group: usize) -> String {
    if channels == 1 {
        format!("_PRT_{group}")
    } else {
        let name = ["R", "G", "B"]
            .get(channel as usize)
            .copied()
            .unwrap_or("X");
        format!("_PRT_{name}_{group}")
    }
}

/// Writes `baked` to `path` atomically: a temporary file in the same directory, synced, then
/// renamed over the target, so readers never see a half-written file.
///
/// With a lightmap, its OpenEXR file ([`lightmap_file_name`]) is written beside, first; should
/// the .glb then fail, the lightmap is removed again, so that no half of a bake is left.
pub fn write_glb(path: &Path, baked: &BakedMesh) -> Result<()> {
    write_glb_with(path, baked, None)
}

/// [`write_glb`], with the transfer stored compressed ([`compressed`]) when `cpca` is given
/// (which must be the compression of `baked.transfer`).
pub fn write_glb_with(path: &Path, baked: &BakedMesh, cpca: Option<&Cpca>) -> Result<()> {
    write_glb_as(path, baked, cpca, Precision::F32)
}

/// [`write_glb_with`], the transfer (per vertex, or compressed) stored at `precision` (float16
/// refuses lightmaps, which have their own storage).
pub fn write_glb_as(
    path: &Path,
    baked: &BakedMesh,
    cpca: Option<&Cpca>,
    precision: Precision,
) -> Result<()> {
    validate(baked)?;
    if precision == Precision::F16 && baked.lightmap.is_some() {
        return Err(Error::Options(
            "--precision f16 stores per-vertex or compressed transfer; lightmaps have their own \
             storage"
                .into(),
        ));
    }
    if let Some(cpca) = cpca {
        validate_cpca(baked, cpca).map_err(Error::Geometry)?;
    }
    // Fails before encoding, so a typo in the directory costs no work.
    check_destination(path)?;
    let Some(texels) = &baked.lightmap else {
        return write_atomically(path, &encode_valid(baked, None, cpca, precision)?);
    };
    let name = lightmap_file_name(path);
    let bytes = encode_valid(baked, Some(&name), cpca, precision)?;
    let exr_path = path.with_file_name(&name);
    check_destination(&exr_path)?;
    crate::lightmap::write_lightmap(&exr_path, &lightmap_of(texels))?;
    write_atomically(path, &bytes).inspect_err(|_| {
        let _ = fs::remove_file(&exr_path);
    })
}

/// The name of the lightmap file written beside `glb`: `scene.prt.glb` -> `scene.prt.lightmap.exr`.
pub fn lightmap_file_name(glb: &Path) -> String {
    let name = glb
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "baked".into());
    let stem = match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name,
    };
    format!("{stem}.lightmap.exr")
}

/// The file form of a texel bake.
fn lightmap_of(texels: &TexelBake) -> crate::lightmap::Lightmap {
    crate::lightmap::Lightmap {
        width: texels.width,
        height: texels.height,
        bands: texels.transfer.bands,
        channels: texels.transfer.channels,
        coefficients: texels.transfer.coeffs.clone(),
    }
}

/// Reads and fully validates a baked file.
/// Reads and fully validates a baked file, and the lightmap it refers to.
pub fn read_glb(path: &Path) -> Result<BakedMesh> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        return scene::read_scene_glb(path);
    }
    let (mut baked, lightmap, _) = decode_parts(&bytes, path)?;
    if let Some((extras, texcoords)) = lightmap {
        baked.lightmap = Some(read_texels(path, &baked, extras, texcoords)?);
    }
    Ok(baked)
}

/// Reads a baked file and, where it holds its transfer compressed, the compressed form (the
/// mesh's `transfer` is then its reconstruction).
pub fn read_glb_compressed(path: &Path) -> Result<(BakedMesh, Option<Cpca>)> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        return Ok((scene::read_scene_glb(path)?, None));
    }
    let (mut baked, lightmap, cpca) = decode_parts(&bytes, path)?;
    if let Some((extras, texcoords)) = lightmap {
        baked.lightmap = Some(read_texels(path, &baked, extras, texcoords)?);
    }
    Ok((baked, cpca))
}

/// The lightmap `extras` names, beside `glb`, checked against the mesh it belongs to.
fn read_texels(
    glb: &Path,
    baked: &BakedMesh,
    extras: LightmapExtras,
    texcoords: Vec<[f32; 2]>,
) -> Result<TexelBake> {
    let uri_is_plain = !extras.uri.is_empty()
        && !extras.uri.contains(['/', '\\', ':'])
        && extras.uri != ".."
        && extras.uri != ".";
    if !uri_is_plain {
        return Err(Error::baked(
            glb,
            format!(
                "extras.prt.lightmap.uri \"{}\" is not a file name beside it",
                extras.uri
            ),
        ));
    }
    let exr_path = glb.with_file_name(&extras.uri);
    let map = crate::lightmap::read_lightmap(&exr_path)?;
    let expected = (
        extras.width,
        extras.height,
        baked.transfer.bands,
        baked.transfer.channels,
    );
    if (map.width, map.height, map.bands, map.channels) != expected {
        return Err(Error::baked(
            &exr_path,
            format!(
                "is {}x{} texels of {} bands and {} channels, but {} expects {}x{} of {} and {}",
                map.width,
                map.height,
                map.bands,
                map.channels,
                glb.display(),
                expected.0,
                expected.1,
                expected.2,
                expected.3
            ),
        ));
    }
    Ok(TexelBake {
        width: map.width,
        height: map.height,
        texcoords,
        set: extras.texcoord,
        transfer: Transfer {
            bands: map.bands,
            channels: map.channels,
            vertex_count: (map.width * map.height) as usize,
            coeffs: map.coefficients,
        },
    })
}

/// Whether `bytes` are a glTF scene baked in place ([`scene`]) rather than a single mesh.
pub fn is_scene_file(bytes: &[u8]) -> bool {
    let Some(head) = bytes.get(..20) else {
        return false;
    };
    let Ok(json_len) = check_head(head, bytes.len() as u64, Path::new("")) else {
        return false;
    };
    serde_json::from_slice::<serde_json::Value>(&bytes[20..20 + json_len])
        .is_ok_and(|doc| doc["extras"]["prt"]["baked_in_place"] == serde_json::json!(true))
}

/// Reads only the header and JSON of a baked file: metadata, vertex count, triangle count.
///
/// The layout is validated against the BIN chunk's length, but its contents are not read, so
/// this stays fast on large bakes.
pub fn read_metadata(path: &Path) -> Result<(BakeMetadata, usize, usize)> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        let baked = scene::read_scene_glb(path)?;
        let (vertices, triangles) = (baked.scene.positions.len(), baked.scene.triangles.len());
        return Ok((baked.metadata, vertices, triangles));
    }
    let mut file = File::open(path).map_err(|e| Error::io(path, e))?;
    let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut read = |buf: &mut [u8], what: &str| -> Result<()> {
        file.read_exact(buf).map_err(|e| match e.kind() {
            io::ErrorKind::UnexpectedEof => Error::baked(path, format!("file ends inside {what}")),
            _ => Error::io(path, e),
        })
    };
    let mut head = [0u8; 20];
    read(&mut head, "the glTF binary header")?;
    let json_len = check_head(&head, file_len, path)?;
    let mut json = vec![0u8; json_len];
    read(&mut json, "the JSON chunk")?;
    let mut bin_head = [0u8; 8];
    read(&mut bin_head, "the BIN chunk header")?;
    let bin_len = check_bin_head(&bin_head, 20 + json_len as u64, file_len, path)?;
    let doc = parse_document(&json, path)?;
    let plan = plan(&doc, bin_len, path)?;
    Ok((plan.metadata, plan.vertices, plan.triangles))
}

/// What a single-mesh baked file refers to beside its transfer: its lightmap
/// (`extras.prt.lightmap`) and how its transfer is compressed (`extras.prt.cpca`), each if
/// any; the JSON only is parsed.
pub fn read_references(path: &Path) -> Result<References> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        return scene::stored_references(&bytes).map_err(|m| Error::baked(path, m));
    }
    let prt = mesh_prt_extras(&bytes, path)?;
    Ok(References {
        precision: match prt.transfer_precision.as_deref() {
            Some(FLOAT16) => Precision::F16,
            _ => Precision::F32,
        },
        lightmap: prt.lightmap,
        cpca: prt.cpca,
    })
}

/// What a baked file's `extras.prt` says about where and how its transfer is stored.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct References {
    pub lightmap: Option<LightmapExtras>,
    pub cpca: Option<CpcaExtras>,
    pub precision: Precision,
}

/// `extras.prt` of the single-mesh baked file `bytes` (read from `path`).
fn mesh_prt_extras(bytes: &[u8], path: &Path) -> Result<PrtExtrasIn> {
    let head = bytes
        .get(..20)
        .ok_or_else(|| Error::baked(path, "too short to be a glTF binary (.glb) file"))?;
    let json_len = check_head(head, bytes.len() as u64, path)?;
    let doc = parse_document(&bytes[20..20 + json_len], path)?;
    let mesh = doc
        .meshes
        .first()
        .ok_or_else(|| Error::baked(path, "the file contains no mesh"))?;
    prt_extras(mesh).map_err(|m| Error::baked(path, m))
}

/// Encodes `baked` as a `.glb` in memory, after checking that its parts agree. A lightmap is
/// referred to as [`DEFAULT_LIGHTMAP_URI`] (it is [`write_glb`] that names and writes it).
pub fn encode_glb(baked: &BakedMesh) -> Result<Vec<u8>> {
    validate(baked)?;
    encode_valid(baked, None, None, Precision::F32)
}

/// The lightmap reference of a file encoded without a name for it.
pub const DEFAULT_LIGHTMAP_URI: &str = "lightmap.exr";

/// Decodes and validates a `.glb`; `path` only names the file in error messages. A lightmap the
/// file refers to is not loaded (see [`read_glb`]).
pub fn decode_glb(bytes: &[u8], path: &Path) -> Result<BakedMesh> {
    decode_parts(bytes, path).map(|(baked, _, _)| baked)
}

/// A lightmap's reference and the lightmap coordinates of every vertex.
type LightmapParts = Option<(LightmapExtras, Vec<[f32; 2]>)>;

/// The JSON and BIN chunks of a `.glb`, their headers checked against the file's length.
fn split_chunks<'b>(bytes: &'b [u8], path: &Path) -> Result<(&'b [u8], &'b [u8])> {
    let head = bytes
        .get(..20)
        .ok_or_else(|| Error::baked(path, "too short to be a glTF binary (.glb) file"))?;
    let json_len = check_head(head, bytes.len() as u64, path)?;
    let bin_start = 20 + json_len;
    let bin_head = bytes
        .get(bin_start..bin_start + 8)
        .ok_or_else(|| Error::baked(path, "no BIN chunk after the JSON chunk"))?;
    let bin_len = check_bin_head(bin_head, bin_start as u64, bytes.len() as u64, path)?;
    Ok((
        &bytes[20..bin_start],
        &bytes[bin_start + 8..bin_start + 8 + bin_len],
    ))
}

fn decode_parts(bytes: &[u8], path: &Path) -> Result<(BakedMesh, LightmapParts, Option<Cpca>)> {
    let (json, bin) = split_chunks(bytes, path)?;
    let bin_len = bin.len();
    let doc = parse_document(json, path)?;
    let plan = plan(&doc, bin_len, path)?;
    let v = plan.vertices;
    let damaged = |what: &str, i: usize| Error::baked(path, format!("non-finite {what} at {i}"));

    let read_vec3s = |span: &Span, what: &str| -> Result<Vec<Vec3>> {
        let data = span_bytes(bin, span, 12, path)?;
        (0..span.count)
            .map(|i| {
                let at = i * span.stride;
                let p = Vec3::new(f32_at(data, at), f32_at(data, at + 4), f32_at(data, at + 8));
                if p.is_finite() {
                    Ok(p)
                } else {
                    Err(damaged(what, i))
                }
            })
            .collect()
    };
    let positions = read_vec3s(&plan.positions, "position")?;
    let normals = read_vec3s(&plan.normals, "normal")?;
    let albedo = read_vec3s(&plan.albedo, "albedo")?;

    let data = span_bytes(bin, &plan.indices, 4, path)?;
    let mut triangles = Vec::with_capacity(plan.triangles);
    for t in 0..plan.triangles {
        let mut tri = [0u32; 3];
        for (j, index) in tri.iter_mut().enumerate() {
            *index = u32_at(data, (3 * t + j) * plan.indices.stride);
            if *index as usize >= v {
                return Err(Error::baked(
                    path,
                    format!("triangle {t} uses vertex {index} but there are only {v} vertices"),
                ));
            }
        }
        triangles.push(tri);
    }

    let channels = plan.metadata.channels as usize;
    let n = plan.coeffs_per_channel;
    let cpca = match &plan.cpca {
        Some(extras) => {
            let shape = (v, plan.metadata.bands, plan.metadata.channels);
            let precision = match plan.half {
                true => Precision::F16,
                false => Precision::F32,
            };
            let cpca = compressed::decode(&doc, bin, extras, shape, precision);
            Some(cpca.map_err(|m| Error::baked(path, m))?)
        }
        None => None,
    };
    let mut coeffs = match &cpca {
        Some(cpca) => cpca.reconstruct().coeffs,
        None => vec![0f32; v * channels * n],
    };
    read_planar_transfer(bin, &plan, path, &mut coeffs)?;

    let lightmap = match (plan.lightmap, &plan.texcoords) {
        (Some(extras), Some(span)) => Some((extras, read_texcoords(bin, span, path)?)),
        _ => None,
    };
    let baked = BakedMesh {
        scene: Scene {
            positions,
            normals: Some(normals),
            albedo,
            triangles,
        },
        transfer: Transfer {
            bands: plan.metadata.bands,
            channels: plan.metadata.channels,
            vertex_count: v,
            coeffs,
        },
        metadata: plan.metadata,
        lightmap: None,
    };
    Ok((baked, lightmap, cpca))
}

/// The per-vertex transfer of the planar `_PRT_*` attributes into `coeffs`
/// (`[vertex][channel][k]`), each value finite.
fn read_planar_transfer(bin: &[u8], plan: &Plan, path: &Path, coeffs: &mut [f32]) -> Result<()> {
    let (v, channels, n) = (
        plan.vertices,
        plan.metadata.channels as usize,
        plan.coeffs_per_channel,
    );
    let damaged = |i: usize| {
        Error::baked(
            path,
            format!("non-finite transfer coefficient of vertex at {i}"),
        )
    };
    let size = if plan.half { 2 } else { 4 };
    let value_at = |data: &[u8], at: usize| match plan.half {
        true => half::f16::from_le_bytes([data[at], data[at + 1]]).to_f32(),
        false => f32_at(data, at),
    };
    for (block, span) in plan.transfer.iter().enumerate() {
        let (channel, group) = (block / plan.groups, block % plan.groups);
        let data = span_bytes(bin, span, 4 * size, path)?;
        for vertex in 0..v {
            for lane in 0..4 {
                let k = 4 * group + lane;
                if k < n {
                    let x = value_at(data, vertex * span.stride + size * lane);
                    if !x.is_finite() {
                        return Err(damaged(vertex));
                    }
                    coeffs[(vertex * channels + channel) * n + k] = x;
                }
            }
        }
    }

    Ok(())
}

/// The lightmap coordinates `span` locates, each finite.
fn read_texcoords(bin: &[u8], span: &Span, path: &Path) -> Result<Vec<[f32; 2]>> {
    let data = span_bytes(bin, span, 8, path)?;
    (0..span.count)
        .map(|i| {
            let at = i * span.stride;
            let uv = [f32_at(data, at), f32_at(data, at + 4)];
            if uv.iter().all(|x| x.is_finite()) {
                Ok(uv)
            } else {
                Err(Error::baked(
                    path,
                    format!("non-finite lightmap coordinate at {i}"),
                ))
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Container constants (glTF 2.0 spec, "GLB File Format Specification").

const GLB_MAGIC: u32 = 0x4654_6C67;
const GLB_VERSION: u32 = 2;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const TRIANGLES: u32 = 4;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const TRANSFER_VIEW: usize = 4;
const TEXCOORD_VIEW: usize = 5;

// ---------------------------------------------------------------------------------------------
// JSON. Structs rather than maps so the key order, and with it the bytes, never change; unknown
// fields are ignored on reading, as glTF asks of readers.

#[derive(Serialize, Deserialize)]
struct Document<X> {
    asset: AssetJson,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scene: Option<usize>,
    #[serde(default)]
    scenes: Vec<SceneJson>,
    #[serde(default)]
    nodes: Vec<NodeJson>,
    #[serde(default)]
    meshes: Vec<MeshJson<X>>,
    #[serde(default)]
    accessors: Vec<AccessorJson>,
    #[serde(default, rename = "bufferViews")]
    buffer_views: Vec<BufferViewJson>,
    #[serde(default)]
    buffers: Vec<BufferJson>,
}

#[derive(Serialize, Deserialize)]
struct AssetJson {
    version: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    generator: Option<String>,
}

#[derive(Serialize, Deserialize)]
struct SceneJson {
    #[serde(default)]
    nodes: Vec<usize>,
}

#[derive(Serialize, Deserialize)]
struct NodeJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mesh: Option<usize>,
}

#[derive(Serialize, Deserialize)]
struct MeshJson<X> {
    primitives: Vec<PrimitiveJson>,
    #[serde(skip_serializing_if = "Option::is_none")]
    extras: Option<X>,
}

#[derive(Serialize, Deserialize)]
struct PrimitiveJson {
    attributes: BTreeMap<String, usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    indices: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mode: Option<u32>,
}

#[derive(Serialize, Deserialize)]
struct AccessorJson {
    #[serde(
        default,
        rename = "bufferView",
        skip_serializing_if = "Option::is_none"
    )]
    buffer_view: Option<usize>,
    #[serde(default, rename = "byteOffset")]
    byte_offset: u64,
    #[serde(rename = "componentType")]
    component_type: u32,
    count: u64,
    #[serde(rename = "type")]
    kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    min: Option<Vec<f32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    max: Option<Vec<f32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sparse: Option<serde_json::Value>,
}

#[derive(Serialize, Deserialize)]
struct BufferViewJson {
    buffer: usize,
    #[serde(default, rename = "byteOffset")]
    byte_offset: u64,
    #[serde(rename = "byteLength")]
    byte_length: u64,
    #[serde(
        default,
        rename = "byteStride",
        skip_serializing_if = "Option::is_none"
    )]
    byte_stride: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    target: Option<u32>,
}

#[derive(Serialize, Deserialize)]
struct BufferJson {
    #[serde(rename = "byteLength")]
    byte_length: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    uri: Option<String>,
}

#[derive(Serialize)]
struct MeshExtras<'a> {
    prt: PrtExtras<'a>,
}

#[derive(Serialize)]
struct PrtExtras<'a> {
    #[serde(flatten)]
    metadata: &'a BakeMetadata,
    vertices: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    transfer_buffer_view: Option<usize>,
    transfer_layout: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    transfer_precision: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lightmap: Option<LightmapExtras>,
    #[serde(skip_serializing_if = "Option::is_none")]
    cpca: Option<CpcaExtras>,
}

#[derive(Deserialize)]
struct PrtExtrasIn {
    #[serde(flatten)]
    metadata: BakeMetadata,
    vertices: usize,
    #[serde(default)]
    transfer_buffer_view: Option<usize>,
    transfer_layout: String,
    #[serde(default)]
    transfer_precision: Option<String>,
    #[serde(default)]
    lightmap: Option<LightmapExtras>,
    #[serde(default)]
    cpca: Option<CpcaExtras>,
}

/// `extras.prt.lightmap`: where the per-texel transfer is and how to read it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightmapExtras {
    /// The OpenEXR file, beside the .glb.
    pub uri: String,
    pub width: u32,
    pub height: u32,
    /// The `TEXCOORD_n` set holding the lightmap coordinates.
    pub texcoord: u32,
    /// The file's channel layout (`crate::lightmap`).
    pub layout: String,
}

// ---------------------------------------------------------------------------------------------
// Encoding.

/// Checks everything `encode_valid` relies on, so encoding itself cannot fail halfway.
fn validate(baked: &BakedMesh) -> Result<()> {
    validate_shape(Shape::of(baked))?;
    let (v, transfer) = (baked.scene.positions.len(), &baked.transfer);
    let expected = transfer_len(v, transfer.channels, transfer.bands);
    if expected != Some(transfer.coeffs.len()) {
        return Err(Error::Geometry(format!(
            "the transfer holds {} coefficients, expected {v} vertices x {} channels x {} = {}",
            transfer.coeffs.len(),
            transfer.channels,
            transfer.bands * transfer.bands,
            expected.map_or_else(|| "too many".to_string(), |n| n.to_string())
        )));
    }
    check_finite_coeffs(transfer, 0)
}

/// Refuses a non-finite coefficient, naming its vertex (`first` is the first vertex's index).
fn check_finite_coeffs(transfer: &Transfer, first: usize) -> Result<()> {
    if let Some(i) = transfer.coeffs.iter().position(|x| !x.is_finite()) {
        let per_vertex = (transfer.channels * transfer.bands * transfer.bands) as usize;
        return Err(Error::Geometry(format!(
            "non-finite transfer coefficient at vertex {}",
            first + i / per_vertex
        )));
    }
    Ok(())
}

/// A baked mesh without its coefficients: what the JSON chunk and the checks read. A streamed
/// file (`stream`) is described by one before its coefficients exist.
#[derive(Clone, Copy)]
struct Shape<'a> {
    pub scene: &'a Scene,
    /// Bands, channels and vertex count; the coefficients are not read.
    pub transfer: &'a Transfer,
    pub metadata: &'a BakeMetadata,
    pub lightmap: Option<&'a TexelBake>,
}

impl<'a> Shape<'a> {
    pub fn of(baked: &'a BakedMesh) -> Shape<'a> {
        Shape {
            scene: &baked.scene,
            transfer: &baked.transfer,
            metadata: &baked.metadata,
            lightmap: baked.lightmap.as_ref(),
        }
    }
}

/// Checks everything but the transfer's coefficients: the mesh, the transfer's shape and
/// metadata, the lightmap, the file's size.
fn validate_shape(shape: Shape) -> Result<()> {
    let bad = |message: String| Err(Error::Geometry(message));
    let (scene, transfer, meta) = (shape.scene, shape.transfer, shape.metadata);
    let v = scene.positions.len();
    if v == 0 || scene.triangles.is_empty() {
        return bad(format!(
            "cannot write a mesh with {v} vertices and {} triangles (glTF needs at least one of each)",
            scene.triangles.len()
        ));
    }
    if v > u32::MAX as usize {
        return bad(format!("{v} vertices do not fit 32-bit indices"));
    }
    let Some(normals) = &scene.normals else {
        return bad("the mesh has no normals (prepare it before writing)".into());
    };
    if normals.len() != v || scene.albedo.len() != v {
        return bad(format!(
            "{v} positions but {} normals and {} albedo values",
            normals.len(),
            scene.albedo.len()
        ));
    }
    for (name, values) in [
        ("position", &scene.positions),
        ("normal", normals),
        ("albedo", &scene.albedo),
    ] {
        if let Some(i) = values.iter().position(|p| !p.is_finite()) {
            return bad(format!("non-finite {name} at vertex {i}"));
        }
    }
    for (t, tri) in scene.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= v) {
            return bad(format!(
                "triangle {t} uses vertex {i} but there are only {v} vertices"
            ));
        }
    }
    if transfer.vertex_count != v {
        return bad(format!(
            "the transfer covers {} vertices but the mesh has {v}",
            transfer.vertex_count
        ));
    }
    if transfer.bands == 0 || transfer.bands > crate::sh::MAX_BANDS {
        return bad(format!(
            "transfer has {} bands (1 to {} supported)",
            transfer.bands,
            crate::sh::MAX_BANDS
        ));
    }
    if transfer.channels != 1 && transfer.channels != 3 {
        return bad(format!(
            "transfer has {} channels (1 or 3 supported)",
            transfer.channels
        ));
    }
    if meta.bands != transfer.bands || meta.channels != transfer.channels {
        return bad(format!(
            "metadata says {} bands and {} channels but the transfer has {} and {}",
            meta.bands, meta.channels, transfer.bands, transfer.channels
        ));
    }
    if let Some(texels) = shape.lightmap {
        validate_lightmap(texels, transfer, v).map_err(Error::Geometry)?;
    }
    let bin = bin_len(v, scene.triangles.len(), transfer.channels, transfer.bands);
    // A GLB records its total length in 32 bits; keep a margin for the header and the JSON.
    if bin.is_none_or(|b| b > u32::MAX as usize - (64 << 20)) {
        return bad(format!(
            "{v} vertices with {} bands and {} channels exceed the 4 GiB limit of a .glb file",
            transfer.bands, transfer.channels
        ));
    }
    Ok(())
}

/// Checks that compressed transfer matches the mesh and transfer it stands for.
fn validate_cpca(baked: &BakedMesh, cpca: &Cpca) -> std::result::Result<(), String> {
    let t = &baked.transfer;
    if baked.lightmap.is_some() {
        return Err("a lightmapped bake cannot be stored compressed".into());
    }
    if (cpca.bands, cpca.channels, cpca.vertex_count()) != (t.bands, t.channels, t.vertex_count) {
        return Err(format!(
            "the compressed transfer has {} vertices of {} bands and {} channels, the mesh {} \
             of {} and {}",
            cpca.vertex_count(),
            cpca.bands,
            cpca.channels,
            t.vertex_count,
            t.bands,
            t.channels
        ));
    }
    Ok(())
}

/// Checks that a lightmap fits the mesh it belongs to: one coordinate pair per vertex, and
/// texels of the vertex transfer's bands and channels.
fn validate_lightmap(
    texels: &TexelBake,
    transfer: &Transfer,
    v: usize,
) -> std::result::Result<(), String> {
    let map = &texels.transfer;
    if texels.texcoords.len() != v {
        return Err(format!(
            "{} lightmap coordinates for {v} vertices",
            texels.texcoords.len()
        ));
    }
    if texels.texcoords.iter().flatten().any(|x| !x.is_finite()) {
        return Err("non-finite lightmap coordinates".into());
    }
    if (map.bands, map.channels) != (transfer.bands, transfer.channels)
        || map.vertex_count != texels.width as usize * texels.height as usize
    {
        return Err(format!(
            "the lightmap holds {} texels of {} bands and {} channels for a {}x{} map of {} and {}",
            map.vertex_count,
            map.bands,
            map.channels,
            texels.width,
            texels.height,
            transfer.bands,
            transfer.channels
        ));
    }
    Ok(())
}

fn transfer_len(v: usize, channels: u32, bands: u32) -> Option<usize> {
    v.checked_mul(channels as usize)?
        .checked_mul((bands as usize).checked_mul(bands as usize)?)
}

pub(crate) fn groups(bands: u32) -> usize {
    (bands as usize * bands as usize).div_ceil(4)
}

fn transfer_bytes(v: usize, channels: u32, bands: u32) -> Option<usize> {
    v.checked_mul(channels as usize)?
        .checked_mul(groups(bands))?
        .checked_mul(16)
}

fn bin_len(v: usize, t: usize, channels: u32, bands: u32) -> Option<usize> {
    v.checked_mul(36)?
        .checked_add(t.checked_mul(12)?)?
        .checked_add(transfer_bytes(v, channels, bands)?)
}

fn put_f32s(bin: &mut Vec<u8>, values: impl IntoIterator<Item = f32>) {
    for x in values {
        bin.extend_from_slice(&x.to_le_bytes());
    }
}

fn encode_valid(
    baked: &BakedMesh,
    lightmap_uri: Option<&str>,
    cpca: Option<&Cpca>,
    precision: Precision,
) -> Result<Vec<u8>> {
    let (mut bin, mut views) = match (precision, cpca) {
        (Precision::F16, None) => encode_bin_f16(baked),
        _ => encode_bin(baked, cpca.is_none()),
    };
    let cpca_extras = cpca.map(|cpca| compressed::encode(cpca, precision, &mut bin, &mut views));
    let shape = Shape::of(baked);
    let json = encode_json(
        shape,
        lightmap_uri,
        cpca_extras,
        views,
        bin.len(),
        precision,
    )?;
    glb_container(json, bin)
}

/// The BIN chunk and its views with the transfer as half floats: the mesh's views, then the
/// planar transfer at two bytes a coefficient.
fn encode_bin_f16(baked: &BakedMesh) -> (Vec<u8>, Vec<BufferViewJson>) {
    let mut bin = Vec::new();
    let mut views = encode_mesh_views(&baked.scene, &mut bin);
    let start = bin.len();
    let transfer = &baked.transfer;
    for channel in 0..transfer.channels as usize {
        for group in 0..groups(transfer.bands) {
            for vertex in 0..transfer.vertex_count {
                let coeffs = transfer.vertex_channel(vertex, channel);
                for k in 4 * group..4 * group + 4 {
                    let x = half::f16::from_f32(coeffs.get(k).copied().unwrap_or(0.0));
                    bin.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
    }
    // Each block is 8 bytes a vertex, so the view's length is a multiple of 4 already.
    views.push(array_view(start, bin.len() - start, None, ARRAY_BUFFER));
    (bin, views)
}

/// The JSON chunk of `baked` with the BIN chunk's `views` (`bin_len` bytes in all).
fn encode_json(
    shape: Shape,
    lightmap_uri: Option<&str>,
    cpca_extras: Option<CpcaExtras>,
    views: Vec<BufferViewJson>,
    bin_len: usize,
    precision: Precision,
) -> Result<Vec<u8>> {
    let attributes_hold_transfer = cpca_extras.is_none() && precision == Precision::F32;
    let accessors = accessors_and_attributes(shape, attributes_hold_transfer);
    let extras = MeshExtras {
        prt: PrtExtras {
            metadata: shape.metadata,
            vertices: shape.scene.positions.len(),
            transfer_buffer_view: cpca_extras.is_none().then_some(TRANSFER_VIEW),
            transfer_layout: match precision {
                Precision::F32 => TRANSFER_LAYOUT,
                Precision::F16 => TRANSFER_LAYOUT_F16,
            },
            transfer_precision: (precision == Precision::F16).then_some(FLOAT16),
            cpca: cpca_extras,
            lightmap: shape.lightmap.map(|texels| LightmapExtras {
                uri: lightmap_uri.unwrap_or(DEFAULT_LIGHTMAP_URI).to_string(),
                width: texels.width,
                height: texels.height,
                texcoord: 0,
                layout: crate::lightmap::LAYOUT.to_string(),
            }),
        },
    };
    mesh_json(extras, accessors, views, bin_len)
}

/// The .glb of every baked file: one scene, one node, one mesh of one triangle primitive
/// (indices in accessor 3) carrying `extras`, one buffer, the BIN chunk `bin`.
fn mesh_glb<X: Serialize>(
    extras: X,
    accessors: (Vec<AccessorJson>, BTreeMap<String, usize>),
    views: Vec<BufferViewJson>,
    bin: Vec<u8>,
) -> Result<Vec<u8>> {
    let json = mesh_json(extras, accessors, views, bin.len())?;
    glb_container(json, bin)
}

/// The JSON chunk of [`mesh_glb`], for a BIN chunk of `bin_len` bytes.
fn mesh_json<X: Serialize>(
    extras: X,
    (accessors, attributes): (Vec<AccessorJson>, BTreeMap<String, usize>),
    views: Vec<BufferViewJson>,
    bin_len: usize,
) -> Result<Vec<u8>> {
    let doc = Document {
        asset: AssetJson {
            version: "2.0".into(),
            generator: Some(format!("prt-gpu {}", env!("CARGO_PKG_VERSION"))),
        },
        scene: Some(0),
        scenes: vec![SceneJson { nodes: vec![0] }],
        nodes: vec![NodeJson { mesh: Some(0) }],
        meshes: vec![MeshJson {
            primitives: vec![PrimitiveJson {
                attributes,
                indices: Some(3),
                mode: Some(TRIANGLES),
            }],
            extras: Some(extras),
        }],
        accessors,
        buffer_views: views,
        buffers: vec![BufferJson {
            byte_length: bin_len as u64,
            uri: None,
        }],
    };
    serde_json::to_vec(&doc)
        .map_err(|e| Error::Geometry(format!("cannot encode the glTF JSON: {e}")))
}

/// The BIN chunk and its views: positions, normals, albedo, indices, then (with `planar`) the
/// per-vertex transfer and, with a lightmap, its coordinates.
fn encode_bin(baked: &BakedMesh, planar: bool) -> (Vec<u8>, Vec<BufferViewJson>) {
    let (scene, transfer) = (&baked.scene, &baked.transfer);
    let capacity = bin_len(
        scene.positions.len(),
        scene.triangles.len(),
        transfer.channels,
        transfer.bands,
    );
    let mut bin = Vec::with_capacity(capacity.unwrap_or(0));
    let mut views = encode_mesh_views(scene, &mut bin);
    if !planar {
        return (bin, views);
    }
    let start = bin.len();
    put_planar_transfer(&mut bin, transfer);
    views.push(transfer_view(start, bin.len() - start));
    if let Some(texels) = &baked.lightmap {
        let start = bin.len();
        put_f32s(&mut bin, texels.texcoords.iter().flatten().copied());
        views.push(array_view(start, bin.len() - start, None, ARRAY_BUFFER));
    }
    let expected_views = TRANSFER_VIEW + 1 + baked.lightmap.is_some() as usize;
    debug_assert_eq!(views.len(), expected_views);
    const { assert!(TEXCOORD_VIEW == TRANSFER_VIEW + 1) };
    (bin, views)
}

/// Appends the mesh's positions, normals, albedo and indices to `bin`; their four views.
fn encode_mesh_views(scene: &Scene, bin: &mut Vec<u8>) -> Vec<BufferViewJson> {
    let normals = scene.normals.as_deref().unwrap_or_default();
    let mut views = Vec::new();
    for vectors in [&scene.positions[..], normals, &scene.albedo[..]] {
        let start = bin.len();
        put_f32s(bin, vectors.iter().flat_map(|p| p.to_array()));
        views.push(array_view(start, bin.len() - start, None, ARRAY_BUFFER));
    }
    let start = bin.len();
    for &i in scene.triangles.iter().flatten() {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    views.push(array_view(
        start,
        bin.len() - start,
        None,
        ELEMENT_ARRAY_BUFFER,
    ));
    debug_assert_eq!(views.len(), TRANSFER_VIEW);
    views
}

/// The transfer's view, `len` bytes from `start`. Several accessors share it, so the spec
/// requires an explicit stride.
fn transfer_view(start: usize, len: usize) -> BufferViewJson {
    array_view(start, len, Some(16), ARRAY_BUFFER)
}

/// Appends to `bin`, from its next 4-byte boundary, what `write` puts there, and a view of it
/// to `views`; returns the view's index. Every extras-named view of a baked file (compressed
/// transfer, local lights) is added this way.
fn append_view(
    bin: &mut Vec<u8>,
    views: &mut Vec<BufferViewJson>,
    write: impl FnOnce(&mut Vec<u8>),
) -> usize {
    bin.resize(bin.len().next_multiple_of(4), 0);
    let start = bin.len();
    write(bin);
    views.push(array_view(start, bin.len() - start, None, ARRAY_BUFFER));
    views.len() - 1
}

fn array_view(start: usize, len: usize, stride: Option<u64>, target: u32) -> BufferViewJson {
    BufferViewJson {
        buffer: 0,
        byte_offset: start as u64,
        byte_length: len as u64,
        byte_stride: stride,
        target: Some(target),
    }
}

/// Appends `transfer` in the planar layout ([`TRANSFER_LAYOUT`]).
fn put_planar_transfer(bin: &mut Vec<u8>, transfer: &Transfer) {
    for channel in 0..transfer.channels as usize {
        for group in 0..groups(transfer.bands) {
            put_planar_block(bin, transfer, channel, group);
        }
    }
}

/// Appends the `(channel, group)` block of `transfer`'s vertices: four coefficients each.
fn put_planar_block(bin: &mut Vec<u8>, transfer: &Transfer, channel: usize, group: usize) {
    for vertex in 0..transfer.vertex_count {
        let coeffs = transfer.vertex_channel(vertex, channel);
        put_f32s(
            bin,
            (4 * group..4 * group + 4).map(|k| coeffs.get(k).copied().unwrap_or(0.0)),
        );
    }
}

/// The accessors of the views [`encode_bin`] lays out, and the primitive's attributes.
fn accessors_and_attributes(
    shape: Shape,
    planar: bool,
) -> (Vec<AccessorJson>, BTreeMap<String, usize>) {
    let (scene, transfer) = (shape.scene, shape.transfer);
    let v = scene.positions.len();
    let groups = groups(transfer.bands);
    let (mut accessors, mut attributes) = mesh_accessors(scene);
    let planar_channels = if planar {
        transfer.channels as usize
    } else {
        0
    };
    for channel in 0..planar_channels {
        for group in 0..groups {
            let block = channel * groups + group;
            let name = transfer_attribute_name(transfer.channels, channel as u32, group);
            attributes.insert(name, accessors.len());
            accessors.push(accessor(TRANSFER_VIEW, block * v * 16, FLOAT, v, "VEC4"));
        }
    }
    if shape.lightmap.is_some() {
        attributes.insert("TEXCOORD_0".into(), accessors.len());
        accessors.push(accessor(TEXCOORD_VIEW, 0, FLOAT, v, "VEC2"));
    }
    (accessors, attributes)
}

/// An accessor of `count` elements of `kind` at `offset` in view `view`, without bounds.
fn accessor(view: usize, offset: usize, component: u32, count: usize, kind: &str) -> AccessorJson {
    AccessorJson {
        buffer_view: Some(view),
        byte_offset: offset as u64,
        component_type: component,
        count: count as u64,
        kind: kind.to_string(),
        min: None,
        max: None,
        sparse: None,
    }
}

/// The accessors of [`encode_mesh`]'s views and the primitive's `POSITION`, `NORMAL` and
/// `COLOR_0` attributes.
fn mesh_accessors(scene: &Scene) -> (Vec<AccessorJson>, BTreeMap<String, usize>) {
    let v = scene.positions.len();
    let (min, max) = scene.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let accessors = vec![
        AccessorJson {
            min: Some(min.to_array().to_vec()),
            max: Some(max.to_array().to_vec()),
            ..accessor(0, 0, FLOAT, v, "VEC3")
        },
        accessor(1, 0, FLOAT, v, "VEC3"),
        accessor(2, 0, FLOAT, v, "VEC3"),
        accessor(3, 0, UNSIGNED_INT, 3 * scene.triangles.len(), "SCALAR"),
    ];
    let attributes: BTreeMap<String, usize> = [("POSITION", 0), ("NORMAL", 1), ("COLOR_0", 2)]
        .into_iter()
        .map(|(name, index)| (name.to_string(), index))
        .collect();
    (accessors, attributes)
}

/// The glTF binary container: header, JSON chunk (space-padded), BIN chunk (zero-padded).
pub(crate) fn glb_container(mut json: Vec<u8>, mut bin: Vec<u8>) -> Result<Vec<u8>> {
    json.resize(json.len().next_multiple_of(4), b' ');
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let total32 = u32::try_from(total)
        .map_err(|_| Error::Geometry("the baked file would exceed the 4 GiB .glb limit".into()))?;
    let mut out = Vec::with_capacity(total);
    for word in [
        GLB_MAGIC,
        GLB_VERSION,
        total32,
        json.len() as u32,
        CHUNK_JSON,
    ] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json);
    for word in [bin.len() as u32, CHUNK_BIN] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&bin);
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Decoding. Every offset and count comes from untrusted bytes: all arithmetic is checked and
// every range is proven inside the BIN chunk before anything is allocated or read.

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(bytes, at))
}

/// Checks the 12-byte header and the JSON chunk header; returns the JSON chunk length.
fn check_head(head: &[u8], file_len: u64, path: &Path) -> Result<usize> {
    let bad = |message: String| Err(Error::baked(path, message));
    if u32_at(head, 0) != GLB_MAGIC {
        return bad("not a glTF binary (.glb) file: bad magic".into());
    }
    let version = u32_at(head, 4);
    if version != GLB_VERSION {
        return bad(format!(
            "glTF binary version {version}, only version 2 is supported"
        ));
    }
    let declared = u64::from(u32_at(head, 8));
    if declared != file_len {
        return bad(format!(
            "header declares {declared} bytes but the file has {file_len} (truncated or damaged)"
        ));
    }
    let json_len = u32_at(head, 12);
    if u32_at(head, 16) != CHUNK_JSON {
        return bad("the first chunk is not the JSON chunk".into());
    }
    if !json_len.is_multiple_of(4) {
        return bad(format!(
            "JSON chunk length {json_len} is not a multiple of 4"
        ));
    }
    if 20 + u64::from(json_len) + 8 > file_len {
        return bad("the JSON chunk runs past the end of the file, or no BIN chunk follows".into());
    }
    Ok(json_len as usize)
}

/// Checks the BIN chunk header found at `start`; returns the BIN chunk length.
fn check_bin_head(head: &[u8], start: u64, file_len: u64, path: &Path) -> Result<usize> {
    let bad = |message: String| Err(Error::baked(path, message));
    let len = u32_at(head, 0);
    if u32_at(head, 4) != CHUNK_BIN {
        return bad("the second chunk is not the BIN chunk".into());
    }
    if !len.is_multiple_of(4) {
        return bad(format!("BIN chunk length {len} is not a multiple of 4"));
    }
    if start + 8 + u64::from(len) > file_len {
        return bad("the BIN chunk runs past the end of the file".into());
    }
    Ok(len as usize)
}

fn parse_document(json: &[u8], path: &Path) -> Result<Document<serde_json::Value>> {
    serde_json::from_slice(json).map_err(|e| Error::baked(path, format!("invalid glTF JSON: {e}")))
}

/// Where one accessor's elements lie in the BIN chunk.
struct Span {
    offset: usize,
    stride: usize,
    count: usize,
}

/// Everything `decode_glb` needs to read the BIN chunk, already checked against its length.
struct Plan {
    metadata: BakeMetadata,
    vertices: usize,
    triangles: usize,
    coeffs_per_channel: usize,
    groups: usize,
    positions: Span,
    normals: Span,
    albedo: Span,
    indices: Span,
    /// One per `(channel, group)`, channel-major.
    transfer: Vec<Span>,
    /// Whether the transfer is stored as half floats (then `transfer`'s spans have stride 8).
    half: bool,
    lightmap: Option<LightmapExtras>,
    /// `TEXCOORD_0`, present with a lightmap.
    texcoords: Option<Span>,
    /// Compressed transfer, in place of `transfer`.
    cpca: Option<CpcaExtras>,
}

fn plan(doc: &Document<serde_json::Value>, bin_len: usize, path: &Path) -> Result<Plan> {
    let bad = |message: String| Error::baked(path, message);
    let buffer_len = check_buffer(doc, bin_len).map_err(bad)?;
    let mesh = doc
        .meshes
        .first()
        .ok_or_else(|| bad("the file contains no mesh".into()))?;
    let primitive = mesh
        .primitives
        .first()
        .ok_or_else(|| bad("the mesh has no primitive".into()))?;
    if primitive.mode.unwrap_or(TRIANGLES) != TRIANGLES {
        return Err(bad("the primitive is not a triangle list".into()));
    }
    let prt = prt_extras(mesh).map_err(bad)?;

    let locate = |what: &str, index: Option<usize>, component: u32, kind: &str, comps: u64| {
        locate(doc, buffer_len, what, index, component, kind, comps).map_err(bad)
    };
    let attribute = |name: &str| primitive.attributes.get(name).copied();
    let positions = locate("POSITION", attribute("POSITION"), FLOAT, "VEC3", 3)?;
    let v = positions.count;
    let normals = same_count(
        locate("NORMAL", attribute("NORMAL"), FLOAT, "VEC3", 3)?,
        v,
        "NORMAL",
    )
    .map_err(bad)?;
    let albedo = same_count(
        locate("COLOR_0", attribute("COLOR_0"), FLOAT, "VEC3", 3)?,
        v,
        "COLOR_0",
    )
    .map_err(bad)?;
    let indices = locate("indices", primitive.indices, UNSIGNED_INT, "SCALAR", 1)?;
    if indices.count % 3 != 0 {
        return Err(bad(format!(
            "{} indices do not make whole triangles",
            indices.count
        )));
    }
    if prt.vertices != v {
        return Err(bad(format!(
            "extras.prt.vertices is {} but POSITION has {v} elements",
            prt.vertices
        )));
    }
    let half = match prt.transfer_precision.as_deref() {
        None => false,
        Some(FLOAT16) => true,
        Some(other) => {
            return Err(bad(format!(
                "extras.prt.transfer_precision {other:?} is not one this reader knows (float16)"
            )))
        }
    };
    let transfer = match (&prt.cpca, prt.transfer_buffer_view) {
        (None, Some(view)) if half => half_transfer_spans(doc, &prt, view, v).map_err(bad)?,
        (None, Some(view)) => {
            transfer_spans(doc, buffer_len, primitive, &prt, view, v).map_err(bad)?
        }
        (Some(_), None) => Vec::new(),
        _ => {
            return Err(bad(
                "extras.prt needs exactly one of transfer_buffer_view and cpca".into(),
            ))
        }
    };
    let texcoords = match &prt.lightmap {
        Some(lightmap) => {
            let name = format!("TEXCOORD_{}", lightmap.texcoord);
            let span = locate(&name, attribute(&name), FLOAT, "VEC2", 2)?;
            Some(same_count(span, v, &name).map_err(bad)?)
        }
        None => None,
    };
    let meta = prt.metadata;
    Ok(Plan {
        half,
        cpca: prt.cpca,
        lightmap: prt.lightmap,
        texcoords,
        vertices: v,
        triangles: indices.count / 3,
        coeffs_per_channel: (meta.bands * meta.bands) as usize,
        groups: groups(meta.bands),
        metadata: meta,
        positions,
        normals,
        albedo,
        indices,
        transfer,
    })
}

/// Checks the document's one buffer against the BIN chunk; returns the buffer's length.
fn check_buffer(
    doc: &Document<serde_json::Value>,
    bin_len: usize,
) -> std::result::Result<u64, String> {
    if doc.asset.version.split('.').next() != Some("2") {
        return Err(format!("glTF version {} is not 2.x", doc.asset.version));
    }
    let [buffer] = &doc.buffers[..] else {
        return Err(format!(
            "{} buffers, expected exactly one (the BIN chunk)",
            doc.buffers.len()
        ));
    };
    if buffer.uri.is_some() {
        return Err("the buffer refers to an external file".into());
    }
    if buffer.byte_length > bin_len as u64 {
        return Err(format!(
            "the buffer declares {} bytes but the BIN chunk has {bin_len}",
            buffer.byte_length
        ));
    }
    Ok(buffer.byte_length)
}

/// The mesh's `extras.prt`, with a layout, band count and channel count this reader knows.
fn prt_extras(mesh: &MeshJson<serde_json::Value>) -> std::result::Result<PrtExtrasIn, String> {
    let prt = mesh
        .extras
        .as_ref()
        .and_then(|extras| extras.get("prt"))
        .ok_or("not a prt-gpu file: the mesh has no extras.prt")?;
    if prt.get("mode").and_then(|m| m.as_str()) == Some("local") {
        return Err(
            "a local-lights bake (--mode local) holds no SH transfer: render it alone \
             with --point-light or --spot-light"
                .into(),
        );
    }
    let prt: PrtExtrasIn =
        serde_json::from_value(prt.clone()).map_err(|e| format!("invalid extras.prt: {e}"))?;
    let layout = match prt.transfer_precision.as_deref() {
        Some(FLOAT16) => TRANSFER_LAYOUT_F16,
        _ => TRANSFER_LAYOUT,
    };
    if prt.transfer_layout != layout {
        return Err(format!(
            "unsupported transfer layout \"{}\"",
            prt.transfer_layout
        ));
    }
    check_shape(&prt.metadata)?;
    Ok(prt)
}

/// The bands and channels a baked file's `extras.prt` declares, checked before any size is
/// computed from them.
pub(crate) fn check_shape(meta: &BakeMetadata) -> std::result::Result<(), String> {
    if meta.bands == 0 || meta.bands > crate::sh::MAX_BANDS {
        return Err(format!(
            "extras.prt.bands is {}, expected 1 to {}",
            meta.bands,
            crate::sh::MAX_BANDS
        ));
    }
    if meta.channels != 1 && meta.channels != 3 {
        return Err(format!(
            "extras.prt.channels is {}, expected 1 or 3",
            meta.channels
        ));
    }
    Ok(())
}

/// `span` if it has the `vertices` elements every vertex attribute must have.
fn same_count(span: Span, vertices: usize, what: &str) -> std::result::Result<Span, String> {
    if span.count == vertices {
        Ok(span)
    } else {
        Err(format!(
            "{what} has {} elements but POSITION has {vertices}",
            span.count
        ))
    }
}

/// The spans of the `_PRT_*` attributes, one per `(channel, group)`, checked to follow the
/// planar layout that `extras.prt` promises (what non-glTF readers rely on).
/// The blocks of a half-float transfer view, which no accessor describes: checked against the
/// view's length and the buffer (the view itself was checked by `check_buffer`).
fn half_transfer_spans(
    doc: &Document<serde_json::Value>,
    prt: &PrtExtrasIn,
    transfer_view: usize,
    v: usize,
) -> std::result::Result<Vec<Span>, String> {
    let meta = &prt.metadata;
    let view = doc
        .buffer_views
        .get(transfer_view)
        .ok_or("extras.prt.transfer_buffer_view does not exist")?;
    let blocks = meta.channels as usize * groups(meta.bands);
    let expected = transfer_bytes(v, meta.channels, meta.bands).map(|n| n / 2);
    if expected.map(|n| n as u64) != Some(view.byte_length) {
        return Err(format!(
            "the half-float transfer view has {} bytes, expected {v} vertices x {blocks} blocks x 8",
            view.byte_length
        ));
    }
    let start = view.byte_offset as usize;
    Ok((0..blocks)
        .map(|block| Span {
            offset: start + block * v * 8,
            stride: 8,
            count: v,
        })
        .collect())
}

fn transfer_spans(
    doc: &Document<serde_json::Value>,
    buffer_len: u64,
    primitive: &PrimitiveJson,
    prt: &PrtExtrasIn,
    transfer_view: usize,
    v: usize,
) -> std::result::Result<Vec<Span>, String> {
    let meta = &prt.metadata;
    let groups = groups(meta.bands);
    let view = doc
        .buffer_views
        .get(transfer_view)
        .ok_or("extras.prt.transfer_buffer_view does not exist")?;
    let expected = transfer_bytes(v, meta.channels, meta.bands);
    if expected.map(|n| n as u64) != Some(view.byte_length) {
        return Err(format!(
            "the transfer buffer view has {} bytes, expected {v} vertices x {} channels x {groups} groups x 16",
            view.byte_length, meta.channels
        ));
    }
    let mut transfer = Vec::with_capacity(meta.channels as usize * groups);
    for channel in 0..meta.channels {
        for group in 0..groups {
            let name = transfer_attribute_name(meta.channels, channel, group);
            let index = primitive.attributes.get(&name).copied();
            let span = locate(doc, buffer_len, &name, index, FLOAT, "VEC4", 4)?;
            let span = same_count(span, v, &name)?;
            let block = channel as usize * groups + group;
            let accessor = &doc.accessors[index.unwrap_or_default()];
            if accessor.buffer_view != Some(transfer_view)
                || accessor.byte_offset != (block * v * 16) as u64
                || span.stride != 16
            {
                return Err(format!(
                    "attribute {name} does not follow the planar transfer layout"
                ));
            }
            transfer.push(span);
        }
    }
    Ok(transfer)
}

/// Resolves accessor `index` to a span of `count` elements of `comps` 4-byte components,
/// proven to lie inside the buffer (whose length was already checked against the BIN chunk).
fn locate<X>(
    doc: &Document<X>,
    buffer_len: u64,
    what: &str,
    index: Option<usize>,
    component: u32,
    kind: &str,
    comps: u64,
) -> std::result::Result<Span, String> {
    let index = index.ok_or_else(|| format!("the primitive has no {what} accessor"))?;
    let accessor = doc
        .accessors
        .get(index)
        .ok_or_else(|| format!("{what} refers to missing accessor {index}"))?;
    if accessor.component_type != component || accessor.kind != kind {
        return Err(format!(
            "{what} is {} of component type {}, expected {kind} of {component}",
            accessor.kind, accessor.component_type
        ));
    }
    if accessor.sparse.is_some() {
        return Err(format!(
            "{what} is a sparse accessor, which is not supported"
        ));
    }
    let view_index = accessor
        .buffer_view
        .ok_or_else(|| format!("{what} has no buffer view"))?;
    let view = doc
        .buffer_views
        .get(view_index)
        .ok_or_else(|| format!("{what} refers to missing buffer view {view_index}"))?;
    if view.buffer != 0 {
        return Err(format!(
            "buffer view {view_index} refers to a missing buffer"
        ));
    }
    let view_end = view.byte_offset.checked_add(view.byte_length);
    if view_end.is_none_or(|end| end > buffer_len) {
        return Err(format!(
            "buffer view {view_index} runs past the end of the buffer"
        ));
    }
    let element = 4 * comps;
    let stride = view.byte_stride.unwrap_or(element);
    if stride < element || stride % 4 != 0 {
        return Err(format!(
            "buffer view {view_index} has an invalid stride {stride}"
        ));
    }
    if accessor.count == 0 {
        return Err(format!("{what} has no elements"));
    }
    // The last element must end inside the view.
    let end = (accessor.count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(element))
        .and_then(|x| x.checked_add(accessor.byte_offset));
    if end.is_none_or(|end| end > view.byte_length) {
        return Err(format!(
            "{what} runs past the end of buffer view {view_index}"
        ));
    }
    let offset = view.byte_offset + accessor.byte_offset;
    if offset % 4 != 0 {
        return Err(format!("{what} is not 4-byte aligned"));
    }
    // In range of usize: everything is bounded by the buffer, which is inside the file.
    Ok(Span {
        offset: offset as usize,
        stride: stride as usize,
        count: accessor.count as usize,
    })
}

/// The bytes from a span's first element to the end of its last, with `element` bytes each.
fn span_bytes<'a>(bin: &'a [u8], span: &Span, element: usize, path: &Path) -> Result<&'a [u8]> {
    let len = (span.count - 1) * span.stride + element;
    bin.get(span.offset..span.offset + len)
        .ok_or_else(|| Error::baked(path, "an accessor runs past the BIN chunk"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::Mode;
    use crate::testing::entries;

    /// Three vertices, one triangle; bands 3 (9 coefficients, not a multiple of 4), RGB, every
    /// coefficient distinct and not exactly representable in decimal.
    fn sample(channels: u32) -> BakedMesh {
        let bands = 3;
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, -0.25, 0.1),
            Vec3::new(-0.3, 2.0, 0.7),
        ];
        let v = positions.len();
        let n = (bands * bands) as usize;
        let coeffs = (0..v * channels as usize * n)
            .map(|i| 0.1 * i as f32 - 1.7 / (i as f32 + 3.0))
            .collect();
        BakedMesh {
            scene: Scene {
                positions,
                normals: Some(vec![Vec3::Z, Vec3::Y, Vec3::new(0.6, 0.0, 0.8)]),
                albedo: vec![Vec3::splat(0.8), Vec3::new(0.1, 0.2, 0.3), Vec3::ONE],
                triangles: vec![[0, 1, 2]],
            },
            transfer: Transfer {
                bands,
                channels,
                vertex_count: v,
                coeffs,
            },
            metadata: BakeMetadata {
                tool: "prt-gpu".into(),
                tool_version: env!("CARGO_PKG_VERSION").into(),
                bands,
                channels,
                mode: Mode::Shadowed,
                samples: 1024,
                sampling: "stratified 32x32".into(),
                seed: 0xDEAD_BEEF_CAFE_F00D,
                backend: "cpu".into(),
                sh_convention: crate::sh::CONVENTION.into(),
                radiometry: "L_o = sum_k l_k t_k".into(),
                bounces: 0,
                fit: crate::bake::Fit::Point,
                fit_points: None,
                target_error: None,
                albedo_free: false,
            },
            lightmap: None,
        }
    }

    fn json_of(bytes: &[u8]) -> serde_json::Value {
        let len = u32_at(bytes, 12) as usize;
        serde_json::from_slice(&bytes[20..20 + len]).unwrap()
    }

    #[test]
    fn round_trip_is_exact() {
        for channels in [1, 3] {
            let baked = sample(channels);
            let bytes = encode_glb(&baked).unwrap();
            let decoded = decode_glb(&bytes, Path::new("mem.glb")).unwrap();
            assert_eq!(decoded, baked);
        }
    }

    #[test]
    fn encoding_is_deterministic() {
        let baked = sample(3);
        assert_eq!(
            encode_glb(&baked).unwrap(),
            encode_glb(&baked.clone()).unwrap()
        );
    }

    #[test]
    fn layout_follows_the_spec() {
        let baked = sample(3);
        let bytes = encode_glb(&baked).unwrap();
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(u32_at(&bytes, 8) as usize, bytes.len());
        let json_len = u32_at(&bytes, 12) as usize;
        assert_eq!(json_len % 4, 0);
        assert_eq!(u32_at(&bytes, 16), CHUNK_JSON);
        assert_eq!(u32_at(&bytes, 20 + json_len + 4), CHUNK_BIN);
        assert_eq!(u32_at(&bytes, 20 + json_len) % 4, 0);

        let doc = json_of(&bytes);
        assert_eq!(doc["asset"]["version"], "2.0");
        let attributes = &doc["meshes"][0]["primitives"][0]["attributes"];
        // bands^2 = 9 needs three groups of four per channel.
        for name in ["R", "G", "B"] {
            for group in 0..3 {
                assert!(attributes.get(format!("_PRT_{name}_{group}")).is_some());
            }
            assert!(attributes.get(format!("_PRT_{name}_3")).is_none());
        }
        let pos = &doc["accessors"][attributes["POSITION"].as_u64().unwrap() as usize];
        assert_eq!(pos["min"], serde_json::json!([-0.3, -0.25, 0.0]));
        assert_eq!(pos["max"], serde_json::json!([1.0, 2.0, 0.7]));
        let prt = &doc["meshes"][0]["extras"]["prt"];
        assert_eq!(prt["vertices"], 3);
        assert_eq!(prt["seed"], 0xDEAD_BEEF_CAFE_F00Du64);
        assert_eq!(prt["mode"], "shadowed");
        assert_eq!(prt["transfer_layout"], TRANSFER_LAYOUT);

        // Lane 1 of group 2 in channel 0 is coefficient 9: padding, so zero.
        let view = &doc["bufferViews"][prt["transfer_buffer_view"].as_u64().unwrap() as usize];
        let bin = 28 + json_len + view["byteOffset"].as_u64().unwrap() as usize;
        let at = |c: usize, g: usize, vtx: usize, lane: usize| {
            f32_at(&bytes, bin + ((c * 3 + g) * 3 + vtx) * 16 + 4 * lane)
        };
        assert_eq!(at(0, 2, 1, 1), 0.0);
        assert_eq!(at(0, 2, 1, 0), baked.transfer.vertex_channel(1, 0)[8]);
        assert_eq!(at(2, 1, 2, 3), baked.transfer.vertex_channel(2, 2)[7]);
    }

    #[test]
    fn invalid_meshes_are_refused() {
        let mut no_normals = sample(3);
        no_normals.scene.normals = None;
        let mut short = sample(3);
        short.transfer.coeffs.pop();
        let mut count = sample(3);
        count.transfer.vertex_count = 4;
        let mut index = sample(3);
        index.scene.triangles[0][2] = 3;
        let mut nan = sample(3);
        nan.transfer.coeffs[5] = f32::NAN;
        let mut meta = sample(3);
        meta.metadata.bands = 4;
        for baked in [no_normals, short, count, index, nan, meta] {
            let err = encode_glb(&baked).unwrap_err().to_string();
            assert!(!err.contains('\n'), "{err}");
        }
    }

    #[test]
    fn damaged_files_are_errors_not_panics() {
        let bytes = encode_glb(&sample(3)).unwrap();
        let path = Path::new("damaged.glb");
        for len in 0..bytes.len() {
            assert!(
                decode_glb(&bytes[..len], path).is_err(),
                "truncated to {len}"
            );
        }
        let json_len = u32_at(&bytes, 12) as usize;
        let mut rejected = 0;
        for bit in 0..bytes.len() * 8 {
            let mut flipped = bytes.clone();
            flipped[bit / 8] ^= 1 << (bit % 8);
            let result = decode_glb(&flipped, path);
            // Headers carry no redundancy to spare: any flip there must be caught.
            let byte = bit / 8;
            if byte < 20 || (20 + json_len..28 + json_len).contains(&byte) {
                assert!(result.is_err(), "flip of bit {bit} accepted");
            }
            if let Err(e) = result {
                assert!(!e.to_string().contains('\n'));
                rejected += 1;
            }
        }
        assert!(rejected > 0);
        let mut extended = bytes.clone();
        extended.extend_from_slice(&[0; 4]);
        assert!(decode_glb(&extended, path).is_err());
    }

    #[test]
    fn foreign_gltf_is_refused() {
        let bytes = encode_glb(&sample(3)).unwrap();
        let mut doc = json_of(&bytes);
        doc["meshes"][0].as_object_mut().unwrap().remove("extras");
        let mut json = serde_json::to_vec(&doc).unwrap();
        json.resize(json.len().next_multiple_of(4), b' ');
        let json_len = u32_at(&bytes, 12) as usize;
        let bin = &bytes[20 + json_len..];
        let mut out = Vec::new();
        let total = (20 + json.len() + bin.len()) as u32;
        for word in [GLB_MAGIC, GLB_VERSION, total, json.len() as u32, CHUNK_JSON] {
            out.extend_from_slice(&word.to_le_bytes());
        }
        out.extend_from_slice(&json);
        out.extend_from_slice(bin);
        let err = decode_glb(&out, Path::new("x.glb"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("extras.prt"), "{err}");
    }

    #[test]
    fn write_into_missing_directory_fails_cleanly() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("nope").join("out.glb");
        let err = write_glb(&target, &sample(3)).unwrap_err().to_string();
        assert!(err.contains("does not exist"), "{err}");
        assert!(!target.exists());
        assert!(entries(tmp.path()).is_empty());
    }

    #[test]
    fn write_then_read_round_trip() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("mesh.glb");
        let baked = sample(3);
        write_glb(&target, &baked).unwrap();
        // Overwriting an existing file goes through the same rename.
        write_glb(&target, &baked).unwrap();
        assert_eq!(entries(tmp.path()), ["mesh.glb"]);
        assert_eq!(read_glb(&target).unwrap(), baked);
        assert_eq!(fs::read(&target).unwrap(), encode_glb(&baked).unwrap());
        let (metadata, vertices, triangles) = read_metadata(&target).unwrap();
        assert_eq!((metadata, vertices, triangles), (baked.metadata, 3, 1));
    }

    #[test]
    fn failed_write_leaves_no_temporary_file() {
        let tmp = tempfile::tempdir().unwrap();
        // Renaming a file over a directory fails after the temporary file is complete.
        let target = tmp.path().join("taken.glb");
        fs::create_dir(&target).unwrap();
        let err = write_glb(&target, &sample(3)).unwrap_err();
        assert!(
            matches!(err, Error::Io { ref path, .. } if path == &target),
            "{err}"
        );
        assert_eq!(entries(tmp.path()), ["taken.glb"]);
        assert!(target.is_dir());

        // Invalid input fails before anything is created.
        let mut bad = sample(3);
        bad.transfer.coeffs.clear();
        assert!(write_glb(&tmp.path().join("bad.glb"), &bad).is_err());
        assert_eq!(entries(tmp.path()), ["taken.glb"]);
    }

    #[test]
    fn the_khronos_validator_finds_no_errors() {
        let tmp = tempfile::tempdir().unwrap();
        // One channel and three: the attribute names differ; bands 3 pads the last group.
        for channels in [1, 3] {
            let target = tmp.path().join(format!("mesh-{channels}.glb"));
            write_glb(&target, &sample(channels)).unwrap();
            let Some(report) = crate::gltf_validator::validate_or_skip(&target) else {
                return;
            };
            assert_eq!(report.num_errors, 0, "{}", report.listing());
            assert_eq!(report.num_warnings, 0, "{}", report.listing());
        }
    }

    #[test]
    fn read_metadata_rejects_truncated_files() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("cut.glb");
        let bytes = encode_glb(&sample(1)).unwrap();
        for len in [0, 10, 30, bytes.len() - 4] {
            fs::write(&target, &bytes[..len]).unwrap();
            assert!(read_metadata(&target).is_err(), "truncated to {len}");
        }
    }

    #[test]
    fn readme_quotes_the_python_readers_verbatim() {
        let readme = include_str!("../../README.md");
        for (reader, name) in [
            (PYTHON_READER, "glb::PYTHON_READER"),
            (compressed::PYTHON_READER, "glb::compressed::PYTHON_READER"),
            (local::PYTHON_READER, "glb::local::PYTHON_READER"),
        ] {
            assert!(
                readme.contains(reader),
                "README.md's snippet differs from {name}"
            );
        }
    }

    #[test]
    fn python_reader_reads_the_file() {
        let line_count = PYTHON_READER.lines().count();
        assert!(line_count <= 12, "{line_count} lines");
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("mesh.glb");
        let baked = sample(3);
        write_glb(&target, &baked).unwrap();
        let Some(printed) = crate::testing::numpy_reader_output(&target) else {
            return;
        };
        assert_eq!(printed["positions"], serde_json::json!([3, 3]));
        assert_eq!(printed["indices"], serde_json::json!([1, 3]));
        assert_eq!(printed["transfer"], serde_json::json!([3, 3, 9]));
        for channel in 0..3 {
            let row: Vec<f32> = printed["last_vertex"][channel]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap() as f32)
                .collect();
            assert_eq!(row, baked.transfer.vertex_channel(2, channel));
        }
    }
}
