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
use std::ops::Range;
use std::path::Path;

use gltf_json::accessor::{ComponentType, GenericComponentType, Type};
use gltf_json::buffer::{Stride, Target};
use gltf_json::mesh::Semantic;
use gltf_json::validation::{Checked, USize64};
use gltf_json::{Index, Root};
use serde_json::{json, Value};

mod embed;
mod read;
pub mod stream;

use embed::{embed_accessors, embed_images};
pub(crate) use read::stored_references;
pub use read::{
    is_baked_in_place, read_scene_glb, read_scene_vertices, read_scene_with_zonal, read_scene_zonal,
};

use super::compressed::{self, CpcaExtras};
use super::zonal::{groups_of, zonal_attribute_name, ZonalExtras, ZonalView, AXIS_ATTRIBUTE};
use super::{
    glb_container, groups, raw_extras, transfer_attribute_name, LightmapExtras, Stored, FLOAT16,
    TRANSFER_LAYOUT, TRANSFER_LAYOUT_F16,
};
use crate::bake::{BakeMetadata, Transfer};
use crate::compress::{index_bytes, Cpca};
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};
use crate::precision::Precision;
use crate::scene::gltf::GltfScene;
use crate::scene::prepare::DROPPED;
use crate::zonal::ZonalTransfer;

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
/// the scene `gltf` was loaded into) to `path`, atomically, and its lightmap (if any) beside
/// it; neither stays where the other cannot be written.
pub fn write_scene_glb(
    path: &Path,
    gltf: &GltfScene,
    stored: Stored,
    vertex_map: &[u32],
) -> Result<SceneWrite> {
    check_destination(path)?;
    let baked = stored.baked();
    let Some(texels) = &baked.lightmap else {
        let (bytes, report) = encode_scene_glb(gltf, stored, vertex_map, None)?;
        write_atomically(path, &bytes)?;
        return Ok(report);
    };
    let name = super::lightmap_file_name(path);
    let (bytes, report) = encode_scene_glb(gltf, stored, vertex_map, Some(&name))?;
    let exr_path = path.with_file_name(&name);
    check_destination(&exr_path)?;
    super::write_texels(&exr_path, texels)?;
    write_atomically(path, &bytes).inspect_err(|_| {
        let _ = std::fs::remove_file(&exr_path);
    })?;
    Ok(report)
}

/// [`write_scene_glb`] in memory: the lightmap, if `baked` has one, is named `lightmap_uri`
/// in the root's `extras.prt.lightmap`.
pub fn encode_scene_glb(
    gltf: &GltfScene,
    stored: Stored,
    vertex_map: &[u32],
    lightmap_uri: Option<&str>,
) -> Result<(Vec<u8>, SceneWrite)> {
    let (json, bin, report) = encode_scene(gltf, stored, vertex_map, lightmap_uri, Bin::default())?;
    Ok((glb_container(json, bin.bytes)?, report))
}

/// The scene's JSON and its BIN chunk, built on `bin` (which may reserve the transfer's
/// views: [`stream::SceneStream`]).
fn encode_scene(
    gltf: &GltfScene,
    stored: Stored,
    vertex_map: &[u32],
    lightmap_uri: Option<&str>,
    mut bin: Bin,
) -> Result<(Vec<u8>, Bin, SceneWrite)> {
    let baked = stored.baked();
    let bad = |message: String| Error::Geometry(format!("cannot write the scene: {message}"));
    let mut root = gltf.root.clone();
    let repaired = embed_accessors(&mut root, &gltf.buffers, &mut bin).map_err(bad)?;
    embed_images(&mut root, gltf, &mut bin);
    // Before the transfer: a streamed bake reserves its views last.
    let probes = stored
        .probes()
        .map(|set| crate::glb::probes::encode(set, |bytes| bin.push(&bytes, None, None) as usize));
    let report = SceneWrite {
        repaired,
        ..add_transfer(&mut root, gltf, stored, vertex_map, &mut bin).map_err(bad)?
    };
    root.buffers = vec![gltf_json::Buffer {
        byte_length: USize64(bin.len() as u64),
        name: None,
        uri: None,
        extensions: None,
        extras: None,
    }];
    root.buffer_views = std::mem::take(&mut bin.views);
    let mut prt = json!({ "baked_in_place": true });
    if let Some(texels) = &baked.lightmap {
        let uri = lightmap_uri.ok_or_else(|| bad("the lightmap has no file name".into()))?;
        prt["lightmap"] = json!(LightmapExtras {
            uri: uri.into(),
            width: texels.width,
            height: texels.height,
            texcoord: texels.set,
            layout: crate::lightmap::LAYOUT.to_string(),
        });
    }
    if let Some(probes) = probes {
        prt["probes"] = json!(probes);
    }
    root.extras = raw_extras(&json!({ "prt": prt }))?;
    root.asset.generator = Some(format!(
        "prt-gpu {} (bake in place)",
        env!("CARGO_PKG_VERSION")
    ));
    Ok((super::encode_document(&root)?, bin, report))
}

/// The BIN chunk being built and its buffer views. A streamed bake's transfer views are
/// reserved (their place kept, their bytes written later by [`stream::SceneStream`]); they
/// come last, after every view that holds bytes here.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<gltf_json::buffer::View>,
    /// Whether the per-vertex transfer's views are reserved rather than encoded.
    streaming: bool,
    /// The reserved views: each one's offset in the chunk, the scene vertices it holds and
    /// what of theirs.
    reserved: Vec<(usize, Range<usize>, Holds)>,
    reserved_bytes: usize,
}

/// What a reserved view holds of its vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Holds {
    /// Their SH transfer, planar.
    Transfer,
    /// A view of their zonal transfer (`glb::zonal`).
    Zonal(ZonalView),
}

impl Bin {
    /// Appends `bytes` as a new 4-byte aligned view; returns its index.
    fn push(&mut self, bytes: &[u8], stride: Option<usize>, target: Option<Target>) -> u32 {
        assert_eq!(
            self.reserved_bytes, 0,
            "views with bytes come before reserved ones"
        );
        self.bytes.resize(self.bytes.len().next_multiple_of(4), 0);
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(bytes);
        self.add_view(offset, bytes.len(), stride, target)
    }

    /// Appends a 4-byte aligned view of `len` bytes (a multiple of 4) for what `holds` of the
    /// scene vertices `vertices`, to be written later; returns its index.
    fn reserve(
        &mut self,
        len: usize,
        (vertices, holds): (Range<usize>, Holds),
        stride: Option<usize>,
        target: Option<Target>,
    ) -> u32 {
        debug_assert_eq!(len % 4, 0);
        self.bytes.resize(self.bytes.len().next_multiple_of(4), 0);
        let offset = self.bytes.len() + self.reserved_bytes;
        self.reserved.push((offset, vertices.clone(), holds));
        self.reserved_bytes += len;
        self.add_view(offset, len, stride, target)
    }

    /// The chunk's length: its bytes and the reserved views after them.
    fn len(&self) -> usize {
        self.bytes.len() + self.reserved_bytes
    }

    fn add_view(
        &mut self,
        offset: usize,
        len: usize,
        stride: Option<usize>,
        target: Option<Target>,
    ) -> u32 {
        self.views.push(gltf_json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64(len as u64),
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

/// Adds the transfer of every baked primitive, copying meshes shown twice: the `_PRT_*`
/// attributes of its float32 view, or (float16, which no accessor can describe) the view alone,
/// named in the primitive's `extras.prt`.
fn add_transfer(
    root: &mut Root,
    gltf: &GltfScene,
    stored: Stored,
    vertex_map: &[u32],
    bin: &mut Bin,
) -> std::result::Result<SceneWrite, String> {
    let (baked, precision) = (stored.baked(), stored.precision());
    // The clusters' means and bases, once for the scene; each primitive's vertices get their
    // clusters and weights.
    let shared = stored.cpca().map(|cpca| {
        let mut encoded = |values: &[f32]| {
            let mut bytes = Vec::new();
            precision.encode(values, &mut bytes);
            bin.push(&bytes, None, None) as usize
        };
        (cpca, encoded(&cpca.means), encoded(&cpca.bases))
    });
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
        let mut first_cpca = None;
        let mut first_zonal = None;
        for span in &instance.primitives {
            let vertices = span.first..span.first + span.count;
            let map = &vertex_map[vertices.clone()];
            let zonal = stored.zonal().map(|zonal| {
                let primitive = &mut root.meshes[mesh].primitives[span.primitive];
                add_zonal(
                    bin,
                    &mut root.accessors,
                    primitive,
                    zonal,
                    (vertex_map, vertices.clone()),
                )
            });
            if let Some(zonal) = &zonal {
                first_zonal.get_or_insert(zonal.clone());
            }
            if let Some((cpca, means, bases)) = shared {
                let extras = push_clusters(bin, cpca, (means, bases), map, precision);
                let mut prt = json!({ "vertices": span.count, "cpca": extras });
                if precision == Precision::F16 {
                    prt["transfer_precision"] = json!(FLOAT16);
                }
                if let Some(zonal) = &zonal {
                    prt["zonal"] = json!(zonal);
                }
                let primitive = &mut root.meshes[mesh].primitives[span.primitive];
                primitive.extras = raw_extras(&json!({ "prt": prt })).map_err(|e| e.to_string())?;
                first_cpca.get_or_insert((span.count, extras));
                report.primitives_baked += 1;
                continue;
            }
            let view = push_transfer(bin, &baked.transfer, (vertex_map, vertices), precision);
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
            if let Some(zonal) = &zonal {
                prt["zonal"] = json!(zonal);
            }
            primitive.extras = raw_extras(&json!({ "prt": prt })).map_err(|e| e.to_string())?;
            first_primitive.get_or_insert((span.count, view));
            report.primitives_baked += 1;
        }
        let first = match (first_primitive, first_cpca) {
            (Some((vertices, view)), _) => Some((vertices, StoredAt::Planar(view))),
            (None, Some((vertices, cpca))) => Some((vertices, StoredAt::Clusters(cpca))),
            (None, None) => None,
        };
        if let Some((vertices, stored)) = first {
            let at = (vertices, stored, first_zonal);
            root.meshes[mesh].extras = mesh_extras(&baked.metadata, at, precision)?;
        }
    }
    Ok(report)
}

/// Where a mesh's first primitive keeps its transfer.
enum StoredAt {
    Planar(u32),
    Clusters(CpcaExtras),
}

/// A baked mesh's `extras.prt`: the bake's metadata, and where its first primitive keeps its
/// `vertices`' transfer and zonal transfer.
fn mesh_extras(
    metadata: &BakeMetadata,
    (vertices, stored, zonal): (usize, StoredAt, Option<ZonalExtras>),
    precision: Precision,
) -> std::result::Result<gltf_json::Extras, String> {
    let mut prt = serde_json::to_value(metadata).map_err(|e| e.to_string())?;
    if let Value::Object(fields) = &mut prt {
        fields.insert("vertices".into(), json!(vertices));
        if let Some(zonal) = zonal {
            fields.insert("zonal".into(), json!(zonal));
        }
        if precision == Precision::F16 {
            fields.insert("transfer_precision".into(), json!(FLOAT16));
        }
        match stored {
            StoredAt::Planar(view) => {
                fields.insert("transfer_buffer_view".into(), json!(view));
                let layout = match precision {
                    Precision::F32 => TRANSFER_LAYOUT,
                    Precision::F16 => TRANSFER_LAYOUT_F16,
                };
                fields.insert("transfer_layout".into(), json!(layout));
            }
            StoredAt::Clusters(cpca) => {
                fields.insert("cpca".into(), json!(cpca));
            }
        }
    }
    raw_extras(&json!({ "prt": prt })).map_err(|e| e.to_string())
}

/// The clusters and weights of the vertices `map` names, as the views of a compressed
/// primitive (the scene's shared `means` and `bases` views beside them); a dropped vertex (in
/// no baked triangle) takes cluster 0 with zero weights.
fn push_clusters(
    bin: &mut Bin,
    cpca: &Cpca,
    (means, bases): (usize, usize),
    map: &[u32],
    precision: Precision,
) -> CpcaExtras {
    let m = cpca.components;
    let width = index_bytes(cpca.cluster_count(), precision);
    let mut assignment = Vec::with_capacity(map.len() * width);
    let mut weights = Vec::with_capacity(map.len() * m);
    for &vertex in map {
        match vertex {
            DROPPED => {
                assignment.extend(&0u32.to_le_bytes()[..width]);
                weights.extend(std::iter::repeat_n(0.0, m));
            }
            v => {
                let v = v as usize;
                assignment.extend(&cpca.assignment[v].to_le_bytes()[..width]);
                weights.extend_from_slice(&cpca.weights[v * m..(v + 1) * m]);
            }
        }
    }
    let assignment_view = bin.push(&assignment, None, None) as usize;
    let mut encoded = Vec::new();
    precision.encode(&weights, &mut encoded);
    let weights_view = bin.push(&encoded, None, None) as usize;
    CpcaExtras {
        clusters: cpca.cluster_count(),
        components: m,
        dimension: cpca.dimension,
        means_buffer_view: means,
        bases_buffer_view: bases,
        assignment_buffer_view: assignment_view,
        weights_buffer_view: weights_view,
        layout: compressed::layout(precision).to_string(),
        assignment_bytes: (precision == Precision::F16).then_some(width),
    }
}

/// The transfer of the scene vertices `vertices` (baked vertex `vertex_map[i]` each), planar
/// `[channel][group][vertex][4]` as in the single-mesh format, at `precision`; reserved for
/// later where `bin` is streaming.
fn push_transfer(
    bin: &mut Bin,
    transfer: &Transfer,
    (vertex_map, vertices): (&[u32], Range<usize>),
    precision: Precision,
) -> u32 {
    let groups = groups(transfer.bands());
    let (stride, target) = match precision {
        Precision::F32 => (Some(16), Some(Target::ArrayBuffer)),
        Precision::F16 => (None, None),
    };
    let len = transfer.channels() as usize * groups * vertices.len() * 4 * precision.bytes();
    if bin.streaming {
        return bin.reserve(len, (vertices, Holds::Transfer), stride, target);
    }
    let map = &vertex_map[vertices];
    let mut bytes = Vec::with_capacity(len);
    for channel in 0..transfer.channels() as usize {
        for group in 0..groups {
            put_plane(&mut bytes, transfer, map, (channel, group), precision);
        }
    }
    bin.push(&bytes, stride, target)
}

/// The `(channel, group)` plane of the vertices `map` names, four lanes a vertex at
/// `precision`: zeros for a dropped vertex (in no baked triangle) and past the last
/// coefficient.
fn put_plane(
    out: &mut Vec<u8>,
    transfer: &Transfer,
    map: &[u32],
    (channel, group): (usize, usize),
    precision: Precision,
) {
    for &vertex in map {
        let coeffs = (vertex != DROPPED).then(|| transfer.vertex_channel(vertex as usize, channel));
        let lanes: [f32; 4] = std::array::from_fn(|lane| {
            coeffs
                .and_then(|c| c.get(4 * group + lane).copied())
                .unwrap_or(0.0)
        });
        precision.encode(&lanes, out);
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
    let groups = groups(transfer.bands());
    for channel in 0..transfer.channels() {
        for group in 0..groups {
            let block = channel as usize * groups + group;
            let name = transfer_attribute_name(transfer.channels(), channel, group);
            let at = (view, block * vertices * 16, vertices);
            add_attribute((accessors, primitive), &name, at, Type::Vec4);
        }
    }
}

/// The views of `zonal` at the scene vertices `vertices` (which `vertex_map` maps to baked
/// ones) in `bin`, and the primitive's `_PRT_ZH_*` attributes over them, as in the single-mesh
/// format; what its `extras.prt.zonal` says. Reserved where the bin streams (`zonal` is then
/// only its shape).
fn add_zonal(
    bin: &mut Bin,
    accessors: &mut Vec<gltf_json::Accessor>,
    primitive: &mut gltf_json::mesh::Primitive,
    zonal: &ZonalTransfer,
    (vertex_map, vertices): (&[u32], Range<usize>),
) -> ZonalExtras {
    let target = Some(Target::ArrayBuffer);
    let extras = match bin.streaming {
        true => {
            let shape = (zonal.bands(), zonal.channels(), zonal.axis());
            let mut holds = [ZonalView::Coefficients, ZonalView::Axes]
                .map(Holds::Zonal)
                .into_iter();
            super::zonal::reserve(shape, vertices.len(), |len, stride| {
                let at = (vertices.clone(), holds.next().expect("two views at most"));
                bin.reserve(len, at, stride, target) as usize
            })
        }
        false => super::zonal::encode(
            &zonal.select(&vertex_map[vertices.clone()]),
            |bytes, stride| bin.push(&bytes, stride, target) as usize,
        ),
    };
    let vertices = vertices.len();
    let groups = groups_of(extras.bands as usize);
    for channel in 0..extras.channels {
        for group in 0..groups {
            let block = channel as usize * groups + group;
            let name = zonal_attribute_name(extras.channels, channel, group);
            let view = extras.coefficients_buffer_view as u32;
            let at = (view, block * vertices * 16, vertices);
            add_attribute((accessors, primitive), &name, at, Type::Vec4);
        }
    }
    if let Some(view) = extras.axes_buffer_view {
        let at = (view as u32, 0, vertices);
        add_attribute((accessors, primitive), AXIS_ATTRIBUTE, at, Type::Vec3);
    }
    extras
}

/// A float accessor of `count` elements of `kind` at `offset` in `view`, and the primitive's
/// attribute `name` (`_`-prefixed, as glTF's application-specific attributes are) naming it.
fn add_attribute(
    (accessors, primitive): (
        &mut Vec<gltf_json::Accessor>,
        &mut gltf_json::mesh::Primitive,
    ),
    name: &str,
    (view, offset, count): (u32, usize, usize),
    kind: Type,
) {
    accessors.push(gltf_json::Accessor {
        buffer_view: Some(Index::new(view)),
        byte_offset: Some(USize64(offset as u64)),
        count: USize64(count as u64),
        component_type: Checked::Valid(GenericComponentType(ComponentType::F32)),
        extensions: None,
        extras: None,
        type_: Checked::Valid(kind),
        min: None,
        max: None,
        name: None,
        normalized: false,
        sparse: None,
    });
    let semantic = Semantic::Extras(name.trim_start_matches('_').to_string());
    primitive.attributes.insert(
        Checked::Valid(semantic),
        Index::new((accessors.len() - 1) as u32),
    );
}
