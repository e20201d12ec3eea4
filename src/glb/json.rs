//! The baked file's JSON: container constants (glTF 2.0, "GLB File Format Specification"), and
//! the document as structs rather than maps, so the key order, and with it the bytes, never
//! change; unknown fields are ignored on reading, as glTF asks of readers.

use super::*;

pub(super) const GLB_MAGIC: u32 = 0x4654_6C67;
pub(super) const GLB_VERSION: u32 = 2;
pub(super) const CHUNK_JSON: u32 = 0x4E4F_534A;
pub(super) const CHUNK_BIN: u32 = 0x004E_4942;
pub(super) const FLOAT: u32 = 5126;
pub(super) const UNSIGNED_INT: u32 = 5125;
pub(super) const TRIANGLES: u32 = 4;
pub(super) const ARRAY_BUFFER: u32 = 34962;
pub(super) const ELEMENT_ARRAY_BUFFER: u32 = 34963;
pub(super) const TRANSFER_VIEW: usize = 4;
pub(super) const TEXCOORD_VIEW: usize = 5;

// ---------------------------------------------------------------------------------------------
// JSON. Structs rather than maps so the key order, and with it the bytes, never change; unknown
// fields are ignored on reading, as glTF asks of readers.

#[derive(Serialize, Deserialize)]
pub(super) struct Document<X> {
    pub(super) asset: AssetJson,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) scene: Option<usize>,
    #[serde(default)]
    pub(super) scenes: Vec<SceneJson>,
    #[serde(default)]
    pub(super) nodes: Vec<NodeJson>,
    #[serde(default)]
    pub(super) meshes: Vec<MeshJson<X>>,
    #[serde(default)]
    pub(super) accessors: Vec<AccessorJson>,
    #[serde(default, rename = "bufferViews")]
    pub(super) buffer_views: Vec<BufferViewJson>,
    #[serde(default)]
    pub(super) buffers: Vec<BufferJson>,
    /// The root's: a scene baked in place keeps its `prt` here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) extras: Option<serde_json::Value>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct AssetJson {
    pub(super) version: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) generator: Option<String>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct SceneJson {
    #[serde(default)]
    pub(super) nodes: Vec<usize>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct NodeJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) mesh: Option<usize>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct MeshJson<X> {
    pub(super) primitives: Vec<PrimitiveJson>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) extras: Option<X>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct PrimitiveJson {
    pub(super) attributes: BTreeMap<String, usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) indices: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) mode: Option<u32>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct AccessorJson {
    #[serde(
        default,
        rename = "bufferView",
        skip_serializing_if = "Option::is_none"
    )]
    pub(super) buffer_view: Option<usize>,
    #[serde(default, rename = "byteOffset")]
    pub(super) byte_offset: u64,
    #[serde(rename = "componentType")]
    pub(super) component_type: u32,
    pub(super) count: u64,
    #[serde(rename = "type")]
    pub(super) kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) min: Option<Vec<f32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) max: Option<Vec<f32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) sparse: Option<serde_json::Value>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct BufferViewJson {
    pub(super) buffer: usize,
    #[serde(default, rename = "byteOffset")]
    pub(super) byte_offset: u64,
    #[serde(rename = "byteLength")]
    pub(super) byte_length: u64,
    #[serde(
        default,
        rename = "byteStride",
        skip_serializing_if = "Option::is_none"
    )]
    pub(super) byte_stride: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) target: Option<u32>,
}

#[derive(Serialize, Deserialize)]
pub(super) struct BufferJson {
    #[serde(rename = "byteLength")]
    pub(super) byte_length: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) uri: Option<String>,
}

#[derive(Serialize)]
pub(super) struct MeshExtras<'a> {
    pub(super) prt: PrtExtras<'a>,
}

#[derive(Serialize)]
pub(super) struct PrtExtras<'a> {
    #[serde(flatten)]
    pub(super) metadata: &'a BakeMetadata,
    pub(super) vertices: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) transfer_buffer_view: Option<usize>,
    pub(super) transfer_layout: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) transfer_precision: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) lightmap: Option<LightmapExtras>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) cpca: Option<CpcaExtras>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) probes: Option<probes::ProbesExtras>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) zonal: Option<zonal::ZonalExtras>,
}

#[derive(Deserialize)]
pub(super) struct PrtExtrasIn {
    #[serde(flatten)]
    pub(super) metadata: BakeMetadata,
    pub(super) vertices: usize,
    #[serde(default)]
    pub(super) transfer_buffer_view: Option<usize>,
    pub(super) transfer_layout: String,
    #[serde(default)]
    pub(super) transfer_precision: Option<String>,
    #[serde(default)]
    pub(super) lightmap: Option<LightmapExtras>,
    #[serde(default)]
    pub(super) cpca: Option<CpcaExtras>,
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
