//! The local-lights bake in a `.glb` (`bake --mode local`): the prepared mesh as in every
//! baked file (views 0–3: `POSITION`, `NORMAL`, `COLOR_0` = albedo, indices), no per-vertex
//! transfer, and in mesh `extras.prt` (`mode: "local"`) the key `local`, which names the
//! buffer views that hold what a run time needs ([`LOCAL_LAYOUT`]):
//!
//! - `depth`: the hemispherical depth maps, compressed, in the four views of
//!   `extras.prt.cpca` ([`super::compressed`]) with `dimension = grid_side^2`: receiver v's
//!   map is `means[a] + sum_j weights[v][j] bases[a][j]`, `a = assignment[v]`; cell
//!   `(i, j)` (index `j * grid_side + i`) looks along the tangent-frame direction of the
//!   hemi-octahedral square's point `u = 2 (i + 0.5) / side - 1`, `v = 2 (j + 0.5) / side - 1`
//!   (`local::depth`), rays leaving the scene store `open_depth`;
//! - `gather`: the gather matrix in compressed sparse rows, `row_offsets` (u32, vertices + 1),
//!   `columns` (u32), `weights` (f32): one bounce is `next[p] = albedo[p] sum weights * prev`;
//! - `operator`: the compressed direct-to-indirect operator (`local::operator`): `members`
//!   and `offsets` (u32, the receivers by cluster), `means` (f32, per member), `bases` (f32,
//!   projection rows per cluster `[component][member]`: a frame's coordinates are
//!   `bases . (E - means)`), `mean_response` (f32 `[vertex][3]`), `terms` and
//!   `term_offsets` (u32, the terms `sender * components + component` kept per receiver
//!   cluster), `responses`
//!   (f32, per receiver cluster, per member `[channel][kept sender][component]`) and
//!   `response_offsets` (u32, where each receiver cluster's responses start, in floats).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::compressed::{self, floats, u32s, CpcaExtras};
use super::{
    accessor_is, accessor_start, encode_mesh_views, mesh_accessors, mesh_glb, mesh_prt,
    parse_document, split_chunks, BufferViewJson, ComponentType, Document, Type,
};
use crate::bake::bounce::GatherMatrix;
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};
use crate::local::build::OperatorShape;
use crate::local::depth::{DirectionGrid, MAX_GRID_SIDE};
use crate::local::operator::CompressedOperator;
use crate::local::{LocalBake, LocalOptions};
use crate::precision::Precision;
use crate::scene::Scene;

/// The layout of `extras.prt.local`'s views; written and checked on reading.
pub const LOCAL_LAYOUT: &str = "depth: cpca rows of grid_side^2 hemi-octahedral cells; \
gather: csr row_offsets u32, columns u32, weights f32; operator: members u32, offsets u32, \
means f32, bases f32 [cluster][component][member], mean_response f32 [vertex][3], terms u32 \
(sender * components + component), term_offsets u32, responses f32 \
[cluster][member][channel][term], response_offsets u32; little-endian";

/// Radiometry of local lights, as written into the file.
pub const LOCAL_RADIOMETRY: &str = "point light of intensity I (W/sr): irradiance E = I V \
cos(theta) / r^2; direct exit radiance albedo E / pi; indirect = (T + ... + T^bounces) direct, \
T = diag(albedo) gather";

/// Reads a local-lights file with Python and numpy alone: `python3 reader.py file.glb`.
/// Reconstructs the last receiver's depth map, bounces a uniform unit direct radiance once
/// through the gather matrix (the first rows), and applies the compressed operator to a
/// uniform unit irradiance (the first receivers); prints them as JSON.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
bv, prt = gltf["bufferViews"], gltf["meshes"][0]["extras"]["prt"]
view = lambda i, dtype: np.frombuffer(binary, dtype, bv[i]["byteLength"] // 4, bv[i].get("byteOffset", 0))
local, V = prt["local"], prt["vertices"]
d = local["depth"]; D, M = d["dimension"], d["components"]
means, bases = view(d["means_buffer_view"], "<f4").reshape(-1, D), view(d["bases_buffer_view"], "<f4").reshape(-1, M, D)
a, w = view(d["assignment_buffer_view"], "<u4"), view(d["weights_buffer_view"], "<f4").reshape(V, M)
last_depth = means[a[-1]] + w[-1] @ bases[a[-1]]
g = local["gather"]; offsets, columns, weights = (view(g["row_offsets_buffer_view"], "<u4"),
    view(g["columns_buffer_view"], "<u4"), view(g["weights_buffer_view"], "<f4"))
row_sums = [float(weights[offsets[p]:offsets[p + 1]].sum()) for p in range(5)]
o = local["operator"]; K = o["components"]; u = lambda k: view(o[k + "_buffer_view"], "<u4")
f = lambda k: view(o[k + "_buffer_view"], "<f4")
members, offs, mu, B, terms, to, R, ro = (u("members"), u("offsets"), f("means"), f("bases"),
    u("terms"), u("term_offsets"), f("responses"), u("response_offsets"))
E, I = np.ones(V), f("mean_response").reshape(V, 3).astype(np.float64)
C = len(offs) - 1
coords = np.zeros((C, K))
for c in range(C):
    m = members[offs[c]:offs[c + 1]]
    coords[c] = B[offs[c] * K:offs[c + 1] * K].reshape(K, len(m)) @ (E[m] - mu[offs[c]:offs[c + 1]])
for r in range(C):
    m, t = members[offs[r]:offs[r + 1]], terms[to[r]:to[r + 1]]
    I[m] += R[ro[r]:ro[r + 1]].reshape(len(m), 3, len(t)) @ coords.reshape(-1)[t]
print(json.dumps({"last_depth": last_depth.tolist(), "row_sums": row_sums, "indirect": I[:5].tolist()}))
"#;

/// `extras.prt` of a local-lights file.
#[derive(Serialize, Deserialize)]
struct LocalPrtExtras {
    mode: String,
    tool: String,
    tool_version: String,
    vertices: usize,
    radiometry: String,
    local: LocalExtras,
}

/// `extras.prt.local`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LocalExtras {
    pub layout: String,
    pub samples: u32,
    pub seed: u64,
    pub bounces: u32,
    pub grid_side: u32,
    pub open_depth: f32,
    pub example_lights: u32,
    pub depth: CpcaExtras,
    pub gather: GatherExtras,
    pub operator: OperatorExtras,
}

/// `extras.prt.local.gather`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GatherExtras {
    pub entries: usize,
    pub row_offsets_buffer_view: usize,
    pub columns_buffer_view: usize,
    pub weights_buffer_view: usize,
}

/// `extras.prt.local.operator`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OperatorExtras {
    pub clusters: usize,
    pub components: usize,
    pub sparsity: f32,
    pub seed: u64,
    pub terms: usize,
    pub responses: usize,
    pub members_buffer_view: usize,
    pub offsets_buffer_view: usize,
    pub means_buffer_view: usize,
    pub bases_buffer_view: usize,
    pub mean_response_buffer_view: usize,
    pub terms_buffer_view: usize,
    pub term_offsets_buffer_view: usize,
    pub responses_buffer_view: usize,
    pub response_offsets_buffer_view: usize,
}

/// Appends one view of 4-byte values to `bin`; returns its index.
fn push_view(bin: &mut Vec<u8>, views: &mut Vec<BufferViewJson>, words: &[[u8; 4]]) -> usize {
    super::append_view(bin, views, |bin| {
        words.iter().for_each(|w| bin.extend_from_slice(w))
    })
}

fn f32_words(values: &[f32]) -> Vec<[u8; 4]> {
    values.iter().map(|x| x.to_le_bytes()).collect()
}

fn u32_words(values: &[u32]) -> Vec<[u8; 4]> {
    values.iter().map(|x| x.to_le_bytes()).collect()
}

/// The file's bytes.
pub fn encode_local_glb(bake: &LocalBake) -> Result<Vec<u8>> {
    let mut bin = Vec::new();
    let mut views = encode_mesh_views(&bake.scene, &mut bin);
    let depth = compressed::encode(&bake.depth, Precision::F32, &mut bin, &mut views);
    let m = &bake.matrix;
    let gather = GatherExtras {
        entries: m.columns.len(),
        row_offsets_buffer_view: push_view(&mut bin, &mut views, &u32_words(&m.row_offsets)),
        columns_buffer_view: push_view(&mut bin, &mut views, &u32_words(&m.columns)),
        weights_buffer_view: push_view(&mut bin, &mut views, &f32_words(&m.weights)),
    };
    let operator = encode_operator(&bake.operator, &bake.options.operator, &mut bin, &mut views)?;
    let (accessors, attributes) = mesh_accessors(&bake.scene);
    let options = &bake.options;
    let prt = LocalPrtExtras {
        mode: "local".into(),
        tool: "prt-gpu".into(),
        tool_version: env!("CARGO_PKG_VERSION").into(),
        vertices: bake.scene.positions.len(),
        radiometry: LOCAL_RADIOMETRY.into(),
        local: LocalExtras {
            layout: LOCAL_LAYOUT.into(),
            samples: options.samples,
            seed: options.seed,
            bounces: options.bounces,
            grid_side: bake.grid.side,
            open_depth: bake.open_depth,
            example_lights: options.example_lights,
            depth,
            gather,
            operator,
        },
    };
    mesh_glb(
        serde_json::json!({ "prt": prt }),
        (accessors, attributes),
        views,
        bin,
    )
}

fn encode_operator(
    op: &CompressedOperator,
    shape: &OperatorShape,
    bin: &mut Vec<u8>,
    views: &mut Vec<BufferViewJson>,
) -> Result<OperatorExtras> {
    let response_offsets: Vec<u32> = op
        .response_offsets
        .iter()
        .map(|&o| u32::try_from(o))
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::Geometry("the operator's responses exceed a .glb".into()))?;
    let mean_response: Vec<f32> = op.mean_response.iter().flat_map(|v| v.to_array()).collect();
    let mut push_f32 = |values: &[f32]| push_view(bin, views, &f32_words(values));
    let means = push_f32(&op.means);
    let bases = push_f32(&op.bases);
    let mean_response = push_f32(&mean_response);
    let responses = push_f32(&op.responses);
    let mut push_u32 = |values: &[u32]| push_view(bin, views, &u32_words(values));
    Ok(OperatorExtras {
        clusters: op.clusters(),
        components: op.components,
        sparsity: shape.sparsity,
        seed: shape.seed,
        terms: op.terms.len(),
        responses: op.responses.len(),
        members_buffer_view: push_u32(&op.members),
        offsets_buffer_view: push_u32(&op.offsets),
        means_buffer_view: means,
        bases_buffer_view: bases,
        mean_response_buffer_view: mean_response,
        terms_buffer_view: push_u32(&op.terms),
        term_offsets_buffer_view: push_u32(&op.term_offsets),
        responses_buffer_view: responses,
        response_offsets_buffer_view: push_u32(&response_offsets),
    })
}

/// Writes the bake atomically.
pub fn write_local_glb(path: &Path, bake: &LocalBake) -> Result<()> {
    check_destination(path)?;
    write_atomically(path, &encode_local_glb(bake)?)
}

/// Whether the bytes are a local-lights file (`extras.prt.mode` is `"local"`).
pub fn is_local_file(bytes: &[u8]) -> bool {
    let Some(head) = bytes.get(..20) else {
        return false;
    };
    let json_len = u32::from_le_bytes([head[12], head[13], head[14], head[15]]) as usize;
    let Some(json) = bytes.get(20..20usize.saturating_add(json_len)) else {
        return false;
    };
    serde_json::from_slice::<serde_json::Value>(json)
        .ok()
        .and_then(|doc| {
            doc.pointer("/meshes/0/extras/prt/mode")
                .and_then(|m| m.as_str().map(|m| m == "local"))
        })
        .unwrap_or(false)
}

/// Reads and validates a local-lights file.
pub fn read_local_glb(path: &Path) -> Result<LocalBake> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode_local_glb(&bytes, path)
}

/// Decodes a local-lights file; `path` names it in errors.
pub fn decode_local_glb(bytes: &[u8], path: &Path) -> Result<LocalBake> {
    let (json, bin) = split_chunks(bytes, path)?;
    let doc = parse_document(json, path)?;
    decode_parts(&doc, bin).map_err(|message| Error::baked(path, message))
}

fn decode_parts(doc: &Document, bin: &[u8]) -> std::result::Result<LocalBake, String> {
    let extras = mesh_prt(doc).ok_or("no extras.prt: not a baked file")?;
    let prt: LocalPrtExtras = serde_json::from_value(extras)
        .map_err(|e| format!("extras.prt is not a local-lights bake: {e}"))?;
    let local = &prt.local;
    if prt.mode != "local" || local.layout != LOCAL_LAYOUT {
        return Err(format!(
            "unsupported local-lights layout \"{}\" (mode {})",
            local.layout, prt.mode
        ));
    }
    let v = prt.vertices;
    let scene = decode_mesh(doc, bin, v)?;
    if !(2..=MAX_GRID_SIDE).contains(&local.grid_side)
        || local.depth.dimension != (local.grid_side * local.grid_side) as usize
        || !(local.open_depth.is_finite() && local.open_depth > 0.0)
    {
        return Err(format!(
            "depth maps of {} values for a grid of side {} (open depth {})",
            local.depth.dimension, local.grid_side, local.open_depth
        ));
    }
    let depth = compressed::decode_rows(doc, bin, &local.depth, v)?;
    let matrix = decode_gather(doc, bin, &local.gather, v)?;
    let operator = decode_operator(doc, bin, &local.operator, v)?;
    let options = LocalOptions {
        samples: local.samples,
        seed: local.seed,
        bounces: local.bounces,
        grid_side: local.grid_side,
        depth_clusters: local.depth.clusters as u32,
        depth_components: local.depth.components as u32,
        operator: OperatorShape {
            clusters: local.operator.clusters as u32,
            components: local.operator.components as u32,
            sparsity: local.operator.sparsity,
            seed: local.operator.seed,
        },
        example_lights: local.example_lights,
    };
    Ok(LocalBake {
        scene,
        options,
        grid: DirectionGrid {
            side: local.grid_side,
        },
        open_depth: local.open_depth,
        depth,
        matrix,
        operator,
    })
}

/// The mesh of views 0–3 as [`encode_mesh_views`] writes them (accessors 0–3, tightly packed).
fn decode_mesh(doc: &Document, bin: &[u8], v: usize) -> std::result::Result<Scene, String> {
    let vec3s = (ComponentType::F32, Type::Vec3, Some(v));
    let expected = [
        vec3s,
        vec3s,
        vec3s,
        (ComponentType::U32, Type::Scalar, None),
    ];
    for (i, (component, kind, count)) in expected.into_iter().enumerate() {
        let accessor = doc
            .accessors
            .get(i)
            .ok_or(format!("accessor {i} is missing"))?;
        let fits = accessor.buffer_view.map(|view| view.value()) == Some(i)
            && accessor_start(accessor) == 0
            && accessor_is(accessor, component, kind)
            && count.is_none_or(|count| accessor.count.0 == count as u64)
            && doc
                .buffer_views
                .get(i)
                .is_some_and(|view| view.byte_stride.is_none());
        if !fits {
            return Err(format!(
                "accessor {i} is not the mesh layout this tool writes"
            ));
        }
    }
    let vec3s = |index: usize, what: &str| -> std::result::Result<Vec<glam::Vec3>, String> {
        Ok(floats(doc, bin, index, 3 * v, what)?
            .chunks_exact(3)
            .map(|c| glam::Vec3::new(c[0], c[1], c[2]))
            .collect())
    };
    let index_count = usize::try_from(doc.accessors[3].count.0)
        .map_err(|_| "the index count overflows".to_string())?;
    if !index_count.is_multiple_of(3) {
        return Err(format!("{index_count} indices are not whole triangles"));
    }
    let indices = u32s(doc, bin, 3, index_count, "index")?;
    if let Some(i) = indices.iter().position(|&i| i as usize >= v) {
        return Err(format!("index {i} names vertex {} of {v}", indices[i]));
    }
    Ok(Scene {
        positions: vec3s(0, "position")?,
        normals: Some(vec3s(1, "normal")?),
        albedo: vec3s(2, "albedo")?,
        triangles: indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    })
}

/// Offsets that start at 0, never fall and end at `total`.
fn check_offsets(offsets: &[u32], total: usize, what: &str) -> std::result::Result<(), String> {
    let monotone = offsets.first() == Some(&0) && offsets.windows(2).all(|w| w[0] <= w[1]);
    if !monotone || offsets.last().map(|&o| o as usize) != Some(total) {
        return Err(format!("the {what} offsets are not a partition of {total}"));
    }
    Ok(())
}

fn decode_gather(
    doc: &Document,
    bin: &[u8],
    extras: &GatherExtras,
    v: usize,
) -> std::result::Result<GatherMatrix, String> {
    let row_offsets = u32s(
        doc,
        bin,
        extras.row_offsets_buffer_view,
        v + 1,
        "gather row offset",
    )?;
    check_offsets(&row_offsets, extras.entries, "gather row")?;
    let columns = u32s(
        doc,
        bin,
        extras.columns_buffer_view,
        extras.entries,
        "gather column",
    )?;
    if let Some(i) = columns.iter().position(|&c| c as usize >= v) {
        return Err(format!(
            "gather entry {i} names vertex {} of {v}",
            columns[i]
        ));
    }
    let weights = floats(
        doc,
        bin,
        extras.weights_buffer_view,
        extras.entries,
        "gather weight",
    )?;
    Ok(GatherMatrix {
        row_offsets,
        columns,
        weights,
    })
}

fn decode_operator(
    doc: &Document,
    bin: &[u8],
    e: &OperatorExtras,
    v: usize,
) -> std::result::Result<CompressedOperator, String> {
    let (k, m) = (e.clusters, e.components);
    if k == 0 || k > v.max(1) || m == 0 {
        return Err(format!(
            "an operator of {k} clusters of {m} components for {v} vertices"
        ));
    }
    let members = u32s(doc, bin, e.members_buffer_view, v, "member")?;
    let mut seen = vec![false; v];
    for &p in &members {
        match seen.get_mut(p as usize) {
            Some(s) if !*s => *s = true,
            _ => {
                return Err(format!(
                    "the operator's members are not each vertex once ({p})"
                ))
            }
        }
    }
    let offsets = u32s(doc, bin, e.offsets_buffer_view, k + 1, "cluster offset")?;
    check_offsets(&offsets, v, "cluster")?;
    let terms = u32s(doc, bin, e.terms_buffer_view, e.terms, "term")?;
    if terms.iter().any(|&t| t as usize >= k * m) {
        return Err("a kept term is out of range".into());
    }
    let term_offsets = u32s(doc, bin, e.term_offsets_buffer_view, k + 1, "term offset")?;
    check_offsets(&term_offsets, e.terms, "term")?;
    let response_offsets = u32s(
        doc,
        bin,
        e.response_offsets_buffer_view,
        k + 1,
        "response offset",
    )?;
    check_offsets(&response_offsets, e.responses, "response")?;
    for r in 0..k {
        let size = (offsets[r + 1] - offsets[r]) as u64;
        let kept = (term_offsets[r + 1] - term_offsets[r]) as u64;
        if (response_offsets[r + 1] - response_offsets[r]) as u64 != size * 3 * kept {
            return Err(format!(
                "receiver cluster {r}'s responses have the wrong length"
            ));
        }
    }
    let mean_response = floats(
        doc,
        bin,
        e.mean_response_buffer_view,
        3 * v,
        "mean response",
    )?;
    Ok(CompressedOperator {
        components: m,
        means: floats(doc, bin, e.means_buffer_view, v, "operator mean")?,
        bases: floats(doc, bin, e.bases_buffer_view, v * m, "operator basis")?,
        mean_response: mean_response
            .chunks_exact(3)
            .map(|c| glam::Vec3::new(c[0], c[1], c[2]))
            .collect(),
        responses: floats(doc, bin, e.responses_buffer_view, e.responses, "response")?,
        response_offsets: response_offsets.iter().map(|&o| o as u64).collect(),
        members,
        offsets,
        terms,
        term_offsets,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_that_is_not_a_local_bake_is_not_taken_for_one() {
        assert!(!is_local_file(b"glTF"));
        assert!(!is_local_file(&[0u8; 64]));
    }
}
