//! Compressed transfer in the baked file (`bake --compress`): clustered PCA (`crate::compress`)
//! stored in place of the per-vertex `_PRT_*` attributes, as four buffer views that
//! `extras.prt.cpca` names:
//!
//! - `means_buffer_view`: float32 `[cluster][dimension]`;
//! - `bases_buffer_view`: float32 `[cluster][component][dimension]`, each cluster's rows
//!   orthonormal;
//! - `assignment_buffer_view`: uint32 `[vertex]`, each vertex's cluster;
//! - `weights_buffer_view`: float32 `[vertex][component]`;
//!
//! with `dimension = channels * bands^2` in the transfer's order (`[channel][k]`). Vertex v's
//! transfer is `means[a] + sum_j weights[v][j] * bases[a][j]`, `a = assignment[v]`; a run-time
//! dots the light into every cluster's mean and basis once and then does a few multiply-adds
//! per vertex (`Cpca::relight`).

use serde::{Deserialize, Serialize};

use super::{BufferViewJson, Document, ARRAY_BUFFER};
use crate::compress::Cpca;

/// Reads a compressed baked file with Python and numpy alone: `python3 reader.py file.glb`.
/// Gives `transfer` (V, channels, bands^2) reconstructed from the clusters, and prints its shape
/// and the last vertex's transfer as JSON.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
bv, prt = gltf["bufferViews"], gltf["meshes"][0]["extras"]["prt"]
view = lambda i, dtype: np.frombuffer(binary, dtype, bv[i]["byteLength"] // 4, bv[i].get("byteOffset", 0))
c = prt["cpca"]; V, D, M = prt["vertices"], c["dimension"], c["components"]
means, bases = view(c["means_buffer_view"], "<f4").reshape(-1, D), view(c["bases_buffer_view"], "<f4").reshape(-1, M, D)
a, w = view(c["assignment_buffer_view"], "<u4"), view(c["weights_buffer_view"], "<f4").reshape(V, M)
transfer = (means[a] + np.einsum("vm,vmd->vd", w, bases[a])).reshape(V, prt["channels"], -1)
print(json.dumps({"transfer": transfer.shape, "last_vertex": transfer[-1].tolist()}))
"#;

/// How the compressed views are laid out; written into `extras.prt.cpca.layout` and checked on
/// reading.
pub const CPCA_LAYOUT: &str =
    "means [cluster][dimension] f32, bases [cluster][component][dimension] \
f32, assignment [vertex] u32, weights [vertex][component] f32, little-endian; dimension = \
channels * bands^2 as [channel][k]";

/// `extras.prt.cpca`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CpcaExtras {
    pub clusters: usize,
    pub components: usize,
    pub dimension: usize,
    pub means_buffer_view: usize,
    pub bases_buffer_view: usize,
    pub assignment_buffer_view: usize,
    pub weights_buffer_view: usize,
    pub layout: String,
}

/// Appends the four views of `cpca` to `bin` and `views`; returns their description.
pub(super) fn encode(
    cpca: &Cpca,
    bin: &mut Vec<u8>,
    views: &mut Vec<BufferViewJson>,
) -> CpcaExtras {
    let first = views.len();
    let mut push = |bytes: &mut Vec<u8>, write: &dyn Fn(&mut Vec<u8>)| {
        let start = bytes.len();
        write(bytes);
        views.push(BufferViewJson {
            buffer: 0,
            byte_offset: start as u64,
            byte_length: (bytes.len() - start) as u64,
            byte_stride: None,
            target: Some(ARRAY_BUFFER),
        });
    };
    let floats = |values: &[f32]| {
        let values = values.to_vec();
        move |bytes: &mut Vec<u8>| values.iter().for_each(|x| bytes.extend(x.to_le_bytes()))
    };
    push(bin, &floats(&cpca.means));
    push(bin, &floats(&cpca.bases));
    push(bin, &|bytes: &mut Vec<u8>| {
        cpca.assignment
            .iter()
            .for_each(|a| bytes.extend(a.to_le_bytes()))
    });
    push(bin, &floats(&cpca.weights));
    CpcaExtras {
        clusters: cpca.cluster_count(),
        components: cpca.components,
        dimension: cpca.dimension,
        means_buffer_view: first,
        bases_buffer_view: first + 1,
        assignment_buffer_view: first + 2,
        weights_buffer_view: first + 3,
        layout: CPCA_LAYOUT.to_string(),
    }
}

/// Reads the compressed transfer `extras` describes from the BIN chunk, checking every size and
/// value; `vertices`, `bands` and `channels` come from the rest of the file.
pub(super) fn decode<X>(
    doc: &Document<X>,
    bin: &[u8],
    extras: &CpcaExtras,
    (vertices, bands, channels): (usize, u32, u32),
) -> Result<Cpca, String> {
    if extras.layout != CPCA_LAYOUT {
        return Err(format!(
            "unsupported compressed layout \"{}\"",
            extras.layout
        ));
    }
    let dimension = channels as usize * (bands * bands) as usize;
    if extras.dimension != dimension {
        return Err(format!(
            "extras.prt.cpca has dimension {} for {channels} channels of {bands} bands",
            extras.dimension
        ));
    }
    let rows = decode_rows(doc, bin, extras, vertices)?;
    Ok(Cpca {
        bands,
        channels,
        ..rows
    })
}

/// Reads compressed rows of `extras.dimension` floats (`compress::compress_rows`; `bands` and
/// `channels` 0), one per vertex.
pub(super) fn decode_rows<X>(
    doc: &Document<X>,
    bin: &[u8],
    extras: &CpcaExtras,
    vertices: usize,
) -> Result<Cpca, String> {
    let dimension = extras.dimension;
    if dimension == 0 || extras.clusters == 0 || extras.components > dimension {
        return Err(format!(
            "compressed rows of dimension {dimension} in {} clusters of {} components",
            extras.clusters, extras.components
        ));
    }
    let (k, m) = (extras.clusters, extras.components);
    let count = |a: usize, b: usize| {
        a.checked_mul(b)
            .ok_or_else(|| format!("{a} x {b} values overflow"))
    };
    let means = floats(
        doc,
        bin,
        extras.means_buffer_view,
        count(k, dimension)?,
        "mean",
    )?;
    let bases = floats(
        doc,
        bin,
        extras.bases_buffer_view,
        count(count(k, m)?, dimension)?,
        "basis",
    )?;
    let weights = floats(
        doc,
        bin,
        extras.weights_buffer_view,
        count(vertices, m)?,
        "weight",
    )?;
    let assignment = u32s(
        doc,
        bin,
        extras.assignment_buffer_view,
        vertices,
        "assignment",
    )?;
    if let Some(v) = assignment.iter().position(|&a| a as usize >= k) {
        return Err(format!(
            "vertex {v} is assigned to cluster {} but there are only {k}",
            assignment[v]
        ));
    }
    Ok(Cpca {
        bands: 0,
        channels: 0,
        dimension,
        components: m,
        means,
        bases,
        assignment,
        weights,
    })
}

/// The bytes of buffer view `index`, which must hold exactly `count` 4-byte values.
pub(super) fn view_bytes<'b, X>(
    doc: &Document<X>,
    bin: &'b [u8],
    index: usize,
    count: usize,
    what: &str,
) -> Result<&'b [u8], String> {
    let view = doc
        .buffer_views
        .get(index)
        .ok_or(format!("the {what} buffer view does not exist"))?;
    let start = view.byte_offset as usize;
    let bytes = start
        .checked_add(view.byte_length as usize)
        .and_then(|end| bin.get(start..end))
        .ok_or(format!("the {what} buffer view runs past the BIN chunk"))?;
    if Some(bytes.len()) != count.checked_mul(4) {
        return Err(format!(
            "the {what} view has {} bytes, expected 4 x {count}",
            bytes.len()
        ));
    }
    Ok(bytes)
}

/// `count` finite little-endian floats from buffer view `index`.
pub(super) fn floats<X>(
    doc: &Document<X>,
    bin: &[u8],
    index: usize,
    count: usize,
    what: &str,
) -> Result<Vec<f32>, String> {
    let values: Vec<f32> = view_bytes(doc, bin, index, count, what)?
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    match values.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(format!("non-finite {what} value at {i}")),
        None => Ok(values),
    }
}

/// `count` little-endian u32 from buffer view `index`.
pub(super) fn u32s<X>(
    doc: &Document<X>,
    bin: &[u8],
    index: usize,
    count: usize,
    what: &str,
) -> Result<Vec<u32>, String> {
    Ok(view_bytes(doc, bin, index, count, what)?
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}
