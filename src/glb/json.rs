//! The baked file's JSON: container constants (glTF 2.0, "GLB File Format Specification"), the
//! document in gltf-json's types (every glTF the tool writes is, a scene baked in place's too)
//! and the `extras.prt` it carries.

use super::*;

pub(super) const GLB_MAGIC: u32 = 0x4654_6C67;
pub(super) const GLB_VERSION: u32 = 2;
pub(super) const CHUNK_JSON: u32 = 0x4E4F_534A;
pub(super) const CHUNK_BIN: u32 = 0x004E_4942;
pub(super) const TRANSFER_VIEW: usize = 4;
pub(super) const TEXCOORD_VIEW: usize = 5;

// ---------------------------------------------------------------------------------------------
// Written through `encode_document`, keys in name order, so the bytes never change; unknown
// fields are ignored on reading, as glTF asks of readers.

pub(super) use gltf_json::accessor::{ComponentType, GenericComponentType, Type};
pub(super) use gltf_json::buffer::{Stride, Target};
pub(super) use gltf_json::mesh::{Mode, Semantic};
pub(super) use gltf_json::validation::{Checked, USize64};
pub(super) use gltf_json::Index;

/// A baked file's glTF document.
pub(super) type Document = gltf_json::Root;
pub(super) type AccessorJson = gltf_json::Accessor;
pub(super) type BufferViewJson = gltf_json::buffer::View;
pub(super) type PrimitiveJson = gltf_json::mesh::Primitive;
/// A primitive's attributes: semantic name to accessor.
pub(super) type Attributes = BTreeMap<Checked<Semantic>, Index<AccessorJson>>;

/// An attribute's semantic from its name (`_PRT_R_0`, `TEXCOORD_0`, ...), as gltf-json reads it.
pub(super) fn semantic(name: &str) -> Checked<Semantic> {
    use serde::de::{value::StrDeserializer, IntoDeserializer};
    let name: StrDeserializer<serde::de::value::Error> = name.into_deserializer();
    Checked::deserialize(name).unwrap_or(Checked::Invalid)
}

/// The accessor of `primitive`'s attribute `name`.
pub(super) fn attribute(primitive: &PrimitiveJson, name: &str) -> Option<usize> {
    match semantic(name) {
        Checked::Valid(semantic) => primitive
            .attributes
            .get(&Checked::Valid(semantic))
            .map(Index::value),
        Checked::Invalid => None,
    }
}

/// Index `i` of a glTF array (every array of a .glb is far below 2^32 entries).
pub(super) fn index<T>(i: usize) -> Index<T> {
    Index::new(u32::try_from(i).expect("a .glb holds fewer than 2^32 of anything"))
}

/// Where a view starts in the buffer.
pub(super) fn view_start(view: &BufferViewJson) -> u64 {
    view.byte_offset.map_or(0, |offset| offset.0)
}

/// Where an accessor starts in its view.
pub(super) fn accessor_start(accessor: &AccessorJson) -> u64 {
    accessor.byte_offset.map_or(0, |offset| offset.0)
}

/// An accessor's element type and component type, as a message names them.
pub(super) fn accessor_kind(accessor: &AccessorJson) -> String {
    let kind = match accessor.type_ {
        Checked::Valid(kind) => serde_json::to_value(kind)
            .ok()
            .and_then(|k| k.as_str().map(String::from))
            .unwrap_or_default(),
        Checked::Invalid => "an invalid type".into(),
    };
    match accessor.component_type {
        Checked::Valid(GenericComponentType(component)) => {
            format!("{kind} of component type {}", component.as_gl_enum())
        }
        Checked::Invalid => format!("{kind} of an invalid component type"),
    }
}

/// Whether `accessor` holds `kind` elements of `component`.
pub(super) fn accessor_is(accessor: &AccessorJson, component: ComponentType, kind: Type) -> bool {
    matches!(accessor.component_type, Checked::Valid(GenericComponentType(c)) if c == component)
        && accessor.type_ == Checked::Valid(kind)
}

/// A document's `extras` (the root's or a mesh's) as a JSON value.
pub(super) fn extras_value(extras: &gltf_json::Extras) -> Option<serde_json::Value> {
    serde_json::from_str(extras.as_ref()?.get()).ok()
}

/// `extras.prt` of the document's first mesh, where a baked mesh keeps it.
pub(super) fn mesh_prt(doc: &Document) -> Option<serde_json::Value> {
    let mut extras = extras_value(&doc.meshes.first()?.extras)?;
    Some(extras.get_mut("prt")?.take())
}

/// `values` as JSON numbers that print as serde prints an `f32` (the shortest decimal that
/// reads back as it) rather than as the `f64` a `serde_json::Value` holds.
pub(super) fn f32_values(values: &[f32]) -> serde_json::Value {
    let text = serde_json::to_string(values).expect("finite floats serialize");
    serde_json::from_str(&text).expect("serde_json reads what it writes")
}

/// The JSON chunk of `doc`: every glTF the tool writes is encoded here. gltf-json writes some
/// absent optional properties as null (`KHR_texture_transform`'s `texCoord`), which glTF does
/// not allow, so they are dropped; the keys come out in name order.
pub(super) fn encode_document(doc: &Document) -> Result<Vec<u8>> {
    fn drop_nulls(value: &mut serde_json::Value) {
        match value {
            serde_json::Value::Object(fields) => {
                fields.retain(|_, v| !v.is_null());
                fields.values_mut().for_each(drop_nulls);
            }
            serde_json::Value::Array(items) => items.iter_mut().for_each(drop_nulls),
            _ => {}
        }
    }
    let encode =
        |e: serde_json::Error| Error::Geometry(format!("cannot encode the glTF JSON: {e}"));
    let mut value = serde_json::to_value(doc).map_err(encode)?;
    drop_nulls(&mut value);
    serde_json::to_vec(&value).map_err(encode)
}

/// `extras` as the raw JSON gltf-json keeps.
pub(super) fn raw_extras<X: Serialize>(extras: &X) -> Result<gltf_json::Extras> {
    serde_json::value::to_raw_value(extras)
        .map(Some)
        .map_err(|e| Error::Geometry(format!("cannot encode the glTF JSON: {e}")))
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
