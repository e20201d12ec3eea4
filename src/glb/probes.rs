//! Probes in a baked file: three views of its BIN chunk named by `extras.prt.probes` (a baked
//! mesh's first mesh's, a scene baked in place's root's) — positions, status codes, matrices —
//! and how to read them back.

use super::*;
use crate::probes::{ProbeForm, ProbeGrid, ProbeSet, ProbeStatus};
use crate::sh::coeff_count;

/// The matrices' layout, as `extras.prt.probes.layout` states it.
pub const PROBE_LAYOUT: &str = "matrices [probe][channel][row][k] float32 little-endian: \
    incident SH coefficient `row` = sum_k m[row][k] * light[k]; positions [probe][3] float32; \
    status [probe] uint8 (0 placed, 1 moved, 2 invalid: zero matrix, leave it out)";

/// `extras.prt.probes`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbesExtras {
    pub count: usize,
    pub bands: u32,
    pub channels: u32,
    /// `radiance` (rows: bands^2) or `irradiance` (rows: the first three bands,
    /// cosine-convolved).
    pub form: String,
    pub rows: usize,
    pub samples: u32,
    pub positions_buffer_view: usize,
    pub status_buffer_view: usize,
    pub matrices_buffer_view: usize,
    pub layout: String,
    /// The grid the probes were placed on (absent for the user's points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<GridExtras>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridExtras {
    pub origin: [f32; 3],
    pub spacing: f32,
    /// Probes along x, y, z; probe `x + dims[0] * (y + dims[1] * z)`.
    pub dims: [u32; 3],
}

/// `probes`' three views, each appended by `push_view` (which returns its index); what
/// `extras.prt.probes` says of them. A baked mesh appends them to its BIN chunk, a scene baked
/// in place to its own.
pub(super) fn encode(
    probes: &ProbeSet,
    mut push_view: impl FnMut(Vec<u8>) -> usize,
) -> ProbesExtras {
    let mut positions = Vec::with_capacity(12 * probes.len());
    put_f32s(
        &mut positions,
        probes.positions.iter().flat_map(|p| p.to_array()),
    );
    let positions = push_view(positions);
    let status = push_view(probes.status.iter().map(|s| s.code()).collect());
    let mut matrices = Vec::with_capacity(4 * probes.matrices.len());
    put_f32s(&mut matrices, probes.matrices.iter().copied());
    let matrices = push_view(matrices);
    ProbesExtras {
        count: probes.len(),
        bands: probes.bands,
        channels: probes.channels,
        form: probes.form.name().to_string(),
        rows: probes.rows,
        samples: probes.samples,
        positions_buffer_view: positions,
        status_buffer_view: status,
        matrices_buffer_view: matrices,
        layout: PROBE_LAYOUT.to_string(),
        grid: probes.grid.map(|g| GridExtras {
            origin: g.origin.to_array(),
            spacing: g.spacing,
            dims: g.dims,
        }),
    }
}

/// The probes of the baked file at `path`, `None` when it has none.
pub fn read_probes(path: &Path) -> Result<Option<ProbeSet>> {
    let bytes = fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    decode_probes(&bytes, path)
}

/// [`read_probes`] of a file's bytes; `path` names it in errors. Every count and view is
/// checked against the BIN chunk before anything is read.
pub fn decode_probes(bytes: &[u8], path: &Path) -> Result<Option<ProbeSet>> {
    let (json, bin) = split_chunks(bytes, path)?;
    let doc = parse_document(json, path)?;
    // A baked mesh's first mesh holds them; a scene baked in place, its root.
    fn probes_in(extras: &gltf_json::Extras) -> Option<serde_json::Value> {
        Some(extras_value(extras)?.get("prt")?.get("probes")?.clone())
    }
    let Some(value) = (doc.meshes.first())
        .and_then(|mesh| probes_in(&mesh.extras))
        .or_else(|| probes_in(&doc.extras))
    else {
        return Ok(None);
    };
    let bad = |message: String| Error::baked(path, message);
    let extras: ProbesExtras = serde_json::from_value(value)
        .map_err(|e| bad(format!("invalid extras.prt.probes: {e}")))?;
    decode_with(&doc, bin, &extras).map(Some).map_err(bad)
}

fn decode_with(
    doc: &Document,
    bin: &[u8],
    extras: &ProbesExtras,
) -> std::result::Result<ProbeSet, String> {
    if extras.layout != PROBE_LAYOUT {
        return Err(format!("unsupported probe layout \"{}\"", extras.layout));
    }
    let form = match extras.form.as_str() {
        "radiance" => ProbeForm::Radiance,
        "irradiance" => ProbeForm::Irradiance,
        other => return Err(format!("unknown probe form \"{other}\"")),
    };
    crate::sh::check_bands(extras.bands).map_err(|e| e.to_string())?;
    let n = coeff_count(extras.bands);
    if !matches!(extras.channels, 1 | 3) || extras.rows != crate::probes::rows(form, extras.bands) {
        return Err(format!(
            "probes of {} channels and {} rows do not fit {} bands of the {} form",
            extras.channels, extras.rows, extras.bands, extras.form
        ));
    }
    let count = extras.count;
    let per_probe = extras.channels as usize * extras.rows * n;
    let sizes = [
        count.checked_mul(12),
        Some(count),
        count.checked_mul(per_probe).and_then(|v| v.checked_mul(4)),
    ];
    let indices = [
        extras.positions_buffer_view,
        extras.status_buffer_view,
        extras.matrices_buffer_view,
    ];
    let mut parts = Vec::with_capacity(3);
    for (view, size) in indices.into_iter().zip(sizes) {
        let size = size.ok_or("the probe count overflows")?;
        parts.push(view_bytes(doc, bin, view, size)?);
    }
    let floats = |bytes: &[u8]| -> Vec<f32> {
        bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    };
    let positions: Vec<Vec3> = floats(parts[0])
        .chunks_exact(3)
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    let status = parts[1]
        .iter()
        .map(|&code| ProbeStatus::from_code(code).ok_or(format!("unknown probe status {code}")))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let matrices = floats(parts[2]);
    if positions.iter().any(|p| !p.is_finite()) || matrices.iter().any(|m| !m.is_finite()) {
        return Err("a probe's position or matrix is not finite".into());
    }
    Ok(ProbeSet {
        bands: extras.bands,
        channels: extras.channels,
        form,
        rows: extras.rows,
        grid: extras.grid.as_ref().map(|g| ProbeGrid {
            origin: Vec3::from(g.origin),
            spacing: g.spacing,
            dims: g.dims,
        }),
        positions,
        status,
        matrices,
        samples: extras.samples,
    })
}

/// The `size` bytes of view `index`, which must hold exactly them.
fn view_bytes<'b>(
    doc: &Document,
    bin: &'b [u8],
    index: usize,
    size: usize,
) -> std::result::Result<&'b [u8], String> {
    let view = doc.buffer_views.get(index).ok_or(format!(
        "extras.prt.probes names view {index}, which does not exist"
    ))?;
    let length = view.byte_length.0;
    if length != size as u64 {
        return Err(format!(
            "probe view {index} holds {length} bytes where its probes need {size}"
        ));
    }
    let start = usize::try_from(view_start(view)).map_err(|_| "a view's offset overflows")?;
    bin.get(start..start.checked_add(size).ok_or("a view's end overflows")?)
        .ok_or(format!("probe view {index} runs past the BIN chunk"))
}

/// Reads a baked file's probes with Python and numpy alone: `python3 reader.py file.glb`
/// prints, as JSON, the probes' positions, status codes and the incident radiance's SH under a
/// constant white sky of radiance 1 (`light[0] = sqrt(4 pi)`), `[probe][channel][row]`.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
prt = gltf["meshes"][0].get("extras", {}).get("prt", {})  # a baked mesh's; a scene baked in place: the root's
bv, probes = gltf["bufferViews"], prt.get("probes") or gltf["extras"]["prt"]["probes"]
view = lambda i, dtype: np.frombuffer(binary, dtype, bv[i]["byteLength"] // np.dtype(dtype).itemsize, bv[i].get("byteOffset", 0))
P, C, R, B = probes["count"], probes["channels"], probes["rows"], probes["bands"]
positions = view(probes["positions_buffer_view"], "<f4").reshape(P, 3)
status = view(probes["status_buffer_view"], "u1")  # 0 placed, 1 moved, 2 invalid
matrices = view(probes["matrices_buffer_view"], "<f4").reshape(P, C, R, B * B)
light = np.zeros(B * B); light[0] = np.sqrt(4 * np.pi)  # one channel's light coefficients
incident = matrices @ light  # [probe][channel][row]: the incident radiance's SH
print(json.dumps({"positions": positions.tolist(), "status": status.tolist(), "incident": incident.tolist()}))
"#;
