//! Compressed transfer in the baked file (`bake --compress`): clustered PCA (`crate::compress`)
//! stored in place of the per-vertex `_PRT_*` attributes, as four buffer views that
//! `extras.prt.cpca` names:
//!
//! - `means_buffer_view`: `[cluster][dimension]`;
//! - `bases_buffer_view`: `[cluster][component][dimension]`, each cluster's rows orthonormal;
//! - `assignment_buffer_view`: `[vertex]`, each vertex's cluster;
//! - `weights_buffer_view`: `[vertex][component]`;
//!
//! with `dimension = channels * bands^2` in the transfer's order (`[channel][k]`). Vertex v's
//! transfer is `means[a] + sum_j weights[v][j] * bases[a][j]`, `a = assignment[v]`; a run-time
//! dots the light into every cluster's mean and basis once and then does a few multiply-adds
//! per vertex (`Cpca::relight`).
//!
//! Two layouts: float32 values with u32 cluster indices ([`CPCA_LAYOUT`]), and, with
//! `--precision f16` (`extras.prt.transfer_precision` `"float16"`), half-float values with the
//! narrowest index that holds every cluster, `assignment_bytes` of 1, 2 or 4
//! ([`CPCA_LAYOUT_F16`]; `compress::index_bytes`). Each view starts on a 4-byte boundary.

use serde::{Deserialize, Serialize};

use super::{append_view, view_start, BufferViewJson, Document};
use crate::compress::{index_bytes, Cpca};
use crate::precision::Precision;

/// Reads a compressed baked file with Python and numpy alone: `python3 reader.py file.glb`.
/// Gives `transfer` (V, channels, bands^2) reconstructed from the clusters, and prints its shape
/// and the last vertex's transfer as JSON.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
bv, prt = gltf["bufferViews"], gltf["meshes"][0]["extras"]["prt"]
view = lambda i, t: np.frombuffer(binary, t, bv[i]["byteLength"] // np.dtype(t).itemsize, bv[i].get("byteOffset", 0))
c = prt["cpca"]; V, D, M = prt["vertices"], c["dimension"], c["components"]
f = "<f2" if prt.get("transfer_precision") == "float16" else "<f4"  # --precision f16: half floats
means, bases = view(c["means_buffer_view"], f).reshape(-1, D), view(c["bases_buffer_view"], f).reshape(-1, M, D)
a, w = view(c["assignment_buffer_view"], "<u%d" % c.get("assignment_bytes", 4)), view(c["weights_buffer_view"], f).reshape(V, M)
transfer = (means[a].astype(np.float64) + np.einsum("vm,vmd->vd", w.astype(np.float64), bases[a])).reshape(V, prt["channels"], -1)
print(json.dumps({"transfer": transfer.shape, "last_vertex": transfer[-1].tolist()}))
"#;

/// How the float32 compressed views are laid out; written into `extras.prt.cpca.layout` and
/// checked on reading.
pub const CPCA_LAYOUT: &str =
    "means [cluster][dimension] f32, bases [cluster][component][dimension] \
f32, assignment [vertex] u32, weights [vertex][component] f32, little-endian; dimension = \
channels * bands^2 as [channel][k]";

/// How the half-float compressed views are laid out (`bake --compress … --precision f16`).
pub const CPCA_LAYOUT_F16: &str =
    "means [cluster][dimension] f16, bases [cluster][component][dimension] \
f16, assignment [vertex] unsigned of assignment_bytes (1, 2 or 4), weights [vertex][component] \
f16, little-endian, each view 4-byte aligned; dimension = channels * bands^2 as [channel][k]";

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
    /// Bytes of one cluster index in the half-float layout (absent: u32).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub assignment_bytes: Option<usize>,
}

/// The layout string of `precision`.
pub fn layout(precision: Precision) -> &'static str {
    match precision {
        Precision::F32 => CPCA_LAYOUT,
        Precision::F16 => CPCA_LAYOUT_F16,
    }
}

/// Appends the four views of `cpca` at `precision` to `bin` and `views`; returns their
/// description.
pub(super) fn encode(
    cpca: &Cpca,
    precision: Precision,
    bin: &mut Vec<u8>,
    views: &mut Vec<BufferViewJson>,
) -> CpcaExtras {
    let first = views.len();
    let index_width = index_bytes(cpca.cluster_count(), precision);
    // A view of one-byte indices may end off a 4-byte boundary; the next starts on one.
    let mut push = |write: &dyn Fn(&mut Vec<u8>)| {
        append_view(bin, views, write);
    };
    push(&|bytes| precision.encode(&cpca.means, bytes));
    push(&|bytes| precision.encode(&cpca.bases, bytes));
    push(&|bytes| {
        cpca.assignment
            .iter()
            .for_each(|a| bytes.extend(&a.to_le_bytes()[..index_width]))
    });
    push(&|bytes| precision.encode(&cpca.weights, bytes));
    bin.resize(bin.len().next_multiple_of(4), 0);
    CpcaExtras {
        clusters: cpca.cluster_count(),
        components: cpca.components,
        dimension: cpca.dimension,
        means_buffer_view: first,
        bases_buffer_view: first + 1,
        assignment_buffer_view: first + 2,
        weights_buffer_view: first + 3,
        layout: layout(precision).to_string(),
        assignment_bytes: (precision == Precision::F16).then_some(index_width),
    }
}

/// Reads the compressed transfer `extras` describes from the BIN chunk, checking every size and
/// value; `vertices`, `bands` and `channels` come from the rest of the file, and `precision`
/// from `extras.prt.transfer_precision`, which the layout must agree with.
pub(super) fn decode(
    doc: &Document,
    bin: &[u8],
    extras: &CpcaExtras,
    shape: (usize, u32, u32),
    precision: Precision,
) -> Result<Cpca, String> {
    decode_with(
        &|index, what| doc_view(doc, bin, index, what),
        extras,
        shape,
        precision,
    )
}

/// The bytes of a buffer view, by its index, for a message naming `what` it holds.
pub(super) type ViewBytes<'b, 'f> = &'f dyn Fn(usize, &str) -> Result<&'b [u8], String>;

/// [`decode`] from views that `view` gives (those of a glTF scene baked in place too).
pub(super) fn decode_with(
    view: ViewBytes,
    extras: &CpcaExtras,
    (vertices, bands, channels): (usize, u32, u32),
    precision: Precision,
) -> Result<Cpca, String> {
    if extras.layout != layout(precision) {
        return Err(format!(
            "unsupported compressed layout \"{}\" for {} transfer",
            extras.layout,
            match precision {
                Precision::F32 => "float32",
                Precision::F16 => "float16",
            }
        ));
    }
    let dimension = channels as usize * (bands * bands) as usize;
    if extras.dimension != dimension {
        return Err(format!(
            "extras.prt.cpca has dimension {} for {channels} channels of {bands} bands",
            extras.dimension
        ));
    }
    let rows = decode_rows_with(view, extras, vertices)?;
    Ok(Cpca {
        bands,
        channels,
        ..rows
    })
}

/// The precision and index width of a compressed layout.
fn storage_of(extras: &CpcaExtras) -> Result<(Precision, usize), String> {
    match (extras.layout.as_str(), extras.assignment_bytes) {
        (CPCA_LAYOUT, None) => Ok((Precision::F32, 4)),
        (CPCA_LAYOUT_F16, Some(width)) if width == index_bytes(extras.clusters, Precision::F16) => {
            Ok((Precision::F16, width))
        }
        (CPCA_LAYOUT_F16, width) => Err(format!(
            "assignment_bytes {width:?} for {} clusters (expected {})",
            extras.clusters,
            index_bytes(extras.clusters, Precision::F16)
        )),
        (other, _) => Err(format!("unsupported compressed layout \"{other}\"")),
    }
}

/// Reads compressed rows of `extras.dimension` floats (`compress::compress_rows`; `bands` and
/// `channels` 0), one per vertex, in either layout.
pub(super) fn decode_rows(
    doc: &Document,
    bin: &[u8],
    extras: &CpcaExtras,
    vertices: usize,
) -> Result<Cpca, String> {
    decode_rows_with(
        &|index, what| doc_view(doc, bin, index, what),
        extras,
        vertices,
    )
}

fn decode_rows_with(view: ViewBytes, extras: &CpcaExtras, vertices: usize) -> Result<Cpca, String> {
    let dimension = extras.dimension;
    if dimension == 0 || extras.clusters == 0 || extras.components > dimension {
        return Err(format!(
            "compressed rows of dimension {dimension} in {} clusters of {} components",
            extras.clusters, extras.components
        ));
    }
    let (precision, index_width) = storage_of(extras)?;
    let (k, m) = (extras.clusters, extras.components);
    let count = |a: usize, b: usize| {
        a.checked_mul(b)
            .ok_or_else(|| format!("{a} x {b} values overflow"))
    };
    let values = |index: usize, count: usize, what: &str| {
        finite(
            sized(view(index, what)?, count, precision.bytes(), what)?,
            precision,
            what,
        )
    };
    let means = values(extras.means_buffer_view, count(k, dimension)?, "mean")?;
    let bases = values(
        extras.bases_buffer_view,
        count(count(k, m)?, dimension)?,
        "basis",
    )?;
    let weights = values(extras.weights_buffer_view, count(vertices, m)?, "weight")?;
    let assignment_bytes = view(extras.assignment_buffer_view, "assignment")?;
    let assignment: Vec<u32> = sized(assignment_bytes, vertices, index_width, "assignment")?
        .chunks_exact(index_width)
        .map(|b| {
            let mut word = [0u8; 4];
            word[..index_width].copy_from_slice(b);
            u32::from_le_bytes(word)
        })
        .collect();
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
pub(super) fn view_bytes<'b>(
    doc: &Document,
    bin: &'b [u8],
    index: usize,
    count: usize,
    what: &str,
) -> Result<&'b [u8], String> {
    sized_view_bytes(doc, bin, (index, count), 4, what)
}

/// The bytes of buffer view `index`, which must hold exactly `count` values of `width` bytes.
fn sized_view_bytes<'b>(
    doc: &Document,
    bin: &'b [u8],
    (index, count): (usize, usize),
    width: usize,
    what: &str,
) -> Result<&'b [u8], String> {
    sized(doc_view(doc, bin, index, what)?, count, width, what)
}

/// The bytes of the single-mesh file's buffer view `index`.
fn doc_view<'b>(
    doc: &Document,
    bin: &'b [u8],
    index: usize,
    what: &str,
) -> Result<&'b [u8], String> {
    let view = doc
        .buffer_views
        .get(index)
        .ok_or(format!("the {what} buffer view does not exist"))?;
    let start = usize::try_from(view_start(view))
        .map_err(|_| format!("the {what} buffer view's offset overflows"))?;
    usize::try_from(view.byte_length.0)
        .ok()
        .and_then(|length| start.checked_add(length))
        .and_then(|end| bin.get(start..end))
        .ok_or(format!("the {what} buffer view runs past the BIN chunk"))
}

/// `bytes`, checked to hold exactly `count` values of `width` bytes.
fn sized<'b>(bytes: &'b [u8], count: usize, width: usize, what: &str) -> Result<&'b [u8], String> {
    if Some(bytes.len()) != count.checked_mul(width) {
        return Err(format!(
            "the {what} view has {} bytes, expected {width} x {count}",
            bytes.len()
        ));
    }
    Ok(bytes)
}

/// `count` finite little-endian float32 values from buffer view `index`.
pub(super) fn floats(
    doc: &Document,
    bin: &[u8],
    index: usize,
    count: usize,
    what: &str,
) -> Result<Vec<f32>, String> {
    values_at(doc, bin, (index, count), Precision::F32, what)
}

/// `count` finite little-endian values at `precision` from buffer view `index`.
fn values_at(
    doc: &Document,
    bin: &[u8],
    (index, count): (usize, usize),
    precision: Precision,
    what: &str,
) -> Result<Vec<f32>, String> {
    let bytes = sized_view_bytes(doc, bin, (index, count), precision.bytes(), what)?;
    finite(bytes, precision, what)
}

/// The values of `bytes` at `precision`, each finite.
fn finite(bytes: &[u8], precision: Precision, what: &str) -> Result<Vec<f32>, String> {
    let values = precision.decode(bytes);
    match values.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(format!("non-finite {what} value at {i}")),
        None => Ok(values),
    }
}

/// `count` little-endian u32 from buffer view `index`.
pub(super) fn u32s(
    doc: &Document,
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
