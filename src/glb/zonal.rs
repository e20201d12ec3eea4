//! Zonal transfer in a baked mesh (`bake --zonal`): its coefficients as vertex attributes
//! `_PRT_ZH_<channel>_<group>` (`_PRT_ZH_<group>` for one channel), `VEC4` float, laid out
//! like the SH transfer, `[channel][group][vertex][4]`, band `l = 4 group + lane`; with a fitted
//! axis, the axis per vertex as `_PRT_ZH_AXIS` (`VEC3` float). `extras.prt.zonal` names both
//! views and says what they hold.

use super::*;
use crate::zonal::{ZonalAxis, ZonalTransfer};

/// The coefficients' layout, as `extras.prt.zonal.layout` states it.
pub const ZONAL_LAYOUT: &str = "planar [channel][group][vertex][4] float32 little-endian, \
    band l = 4*group + lane, lanes past bands are zero; exit radiance = sum_l z_l \
    sqrt(4 pi/(2l+1)) sum_m light_lm y_lm(axis); axes [vertex][3] float32 (fitted axis; \
    absent: the NORMAL attribute)";

/// `extras.prt.zonal`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZonalExtras {
    pub bands: u32,
    pub channels: u32,
    /// `normal` (the lobes are about `NORMAL`) or `fitted` (about `_PRT_ZH_AXIS`).
    pub axis: String,
    pub coefficients_buffer_view: usize,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes_buffer_view: Option<usize>,
    pub layout: String,
}

/// Name of the attribute holding bands `4 group .. 4 group + 3` of `channel`.
pub fn zonal_attribute_name(channels: u32, channel: u32, group: usize) -> String {
    transfer_attribute_name(channels, channel, group).replacen("_PRT_", "_PRT_ZH_", 1)
}

/// The attribute of a fitted axis.
pub const AXIS_ATTRIBUTE: &str = "_PRT_ZH_AXIS";

/// `zonal`'s views, each appended by `push_view` (which takes the bytes and the stride of the
/// view, and returns its index); what `extras.prt.zonal` says of them.
pub(super) fn encode(
    zonal: &ZonalTransfer,
    mut push_view: impl FnMut(Vec<u8>, Option<usize>) -> usize,
) -> ZonalExtras {
    let shape = (zonal.bands(), zonal.channels(), zonal.axis());
    let mut coefficients = Vec::new();
    for channel in 0..zonal.channels() as usize {
        for group in 0..groups_of(zonal.bands() as usize) {
            coefficients.extend(coefficient_block(zonal, channel, group));
        }
    }
    let axes = axes_bytes(zonal);
    let mut views = [coefficients, axes].into_iter();
    reserve(shape, zonal.vertex_count(), |len, stride| {
        let bytes = views.next().expect("two views at most");
        debug_assert_eq!(bytes.len(), len);
        push_view(bytes, stride)
    })
}

/// The views of a zonal transfer of `bands`, `channels` and `axis` over `vertices` vertices,
/// each laid out by `push_view` (which takes the view's length and stride, and returns its
/// index): the coefficients, then the axes where they are fitted; what `extras.prt.zonal`
/// says of them. A streamed file reserves them before any vertex is fitted.
pub(super) fn reserve(
    (bands, channels, axis): (u32, u32, ZonalAxis),
    vertices: usize,
    mut push_view: impl FnMut(usize, Option<usize>) -> usize,
) -> ZonalExtras {
    let blocks = channels as usize * groups_of(bands as usize);
    // Several accessors read the coefficients' view, so the spec asks for its stride.
    let coefficients_buffer_view = push_view(16 * blocks * vertices, Some(16));
    let axes_buffer_view = (axis == ZonalAxis::Fitted).then(|| push_view(12 * vertices, None));
    ZonalExtras {
        bands,
        channels,
        axis: axis.name().to_string(),
        coefficients_buffer_view,
        axes_buffer_view,
        layout: ZONAL_LAYOUT.to_string(),
    }
}

/// One of a zonal transfer's views.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ZonalView {
    Coefficients,
    /// Present where the axes are fitted.
    Axes,
}

/// Writes the fit of a run of vertices (`zonal`, vertex `first` on of a view of `vertices`)
/// into its `view` with `write(offset in the view, bytes)`: a streamed file's chunks go to
/// their places this way.
pub(super) fn write_run(
    zonal: &ZonalTransfer,
    view: ZonalView,
    (vertices, first): (usize, usize),
    write: &mut dyn FnMut(usize, &[u8]) -> Result<()>,
) -> Result<()> {
    match view {
        ZonalView::Coefficients => {
            let groups = groups_of(zonal.bands() as usize);
            for channel in 0..zonal.channels() as usize {
                for group in 0..groups {
                    let block = coefficient_block(zonal, channel, group);
                    write(16 * ((channel * groups + group) * vertices + first), &block)?;
                }
            }
            Ok(())
        }
        ZonalView::Axes => write(12 * first, &axes_bytes(zonal)),
    }
}

/// The bytes of `zonal`'s block `(channel, group)`: each vertex's four lanes, bands past its
/// own zero. Block `b = channel * groups + group` of a file's `v` vertices starts `16 b v`
/// bytes into the coefficients' view.
fn coefficient_block(zonal: &ZonalTransfer, channel: usize, group: usize) -> Vec<u8> {
    let mut block = Vec::with_capacity(16 * zonal.vertex_count());
    for vertex in 0..zonal.vertex_count() {
        let lobe = zonal.vertex_channel(vertex, channel);
        let lanes = (0..4).map(|lane| lobe.get(4 * group + lane).copied().unwrap_or(0.0));
        put_f32s(&mut block, lanes);
    }
    block
}

/// The bytes of `zonal`'s axes view, empty unless they are fitted.
fn axes_bytes(zonal: &ZonalTransfer) -> Vec<u8> {
    let mut axes = Vec::new();
    if zonal.axis() == ZonalAxis::Fitted {
        put_f32s(&mut axes, zonal.axes().iter().flat_map(|a| a.to_array()));
    }
    axes
}

/// Four bands a group.
pub(crate) fn groups_of(bands: usize) -> usize {
    bands.div_ceil(4)
}

/// The accessors of `extras`' views over `vertices` vertices, appended to `accessors`, and the
/// attributes that name them.
pub(super) fn add_accessors(
    extras: &ZonalExtras,
    vertices: usize,
    (accessors, attributes): (&mut Vec<AccessorJson>, &mut Attributes),
) {
    let groups = groups_of(extras.bands as usize);
    for channel in 0..extras.channels as usize {
        for group in 0..groups {
            let block = channel * groups + group;
            let name = zonal_attribute_name(extras.channels, channel as u32, group);
            attributes.insert(semantic(&name), index(accessors.len()));
            let view = extras.coefficients_buffer_view;
            let offset = block * vertices * 16;
            accessors.push(accessor(
                view,
                offset,
                ComponentType::F32,
                vertices,
                Type::Vec4,
            ));
        }
    }
    if let Some(view) = extras.axes_buffer_view {
        attributes.insert(semantic(AXIS_ATTRIBUTE), index(accessors.len()));
        accessors.push(accessor(view, 0, ComponentType::F32, vertices, Type::Vec3));
    }
}

/// The zonal transfer of the baked mesh at `path`, `None` when it has none; the lobes of an
/// axis `normal` file are about its normals.
pub fn read_zonal(path: &Path) -> Result<Option<ZonalTransfer>> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    decode_zonal(&bytes, path)
}

/// [`read_zonal`] of a file's bytes; `path` names it in errors. A glTF scene baked in place
/// is read from `path` ([`scene::read_scene_zonal`]): every placement's, in the order of its
/// vertices as read.
pub fn decode_zonal(bytes: &[u8], path: &Path) -> Result<Option<ZonalTransfer>> {
    if is_scene_file(bytes) {
        return scene::read_scene_zonal(path);
    }
    decode_mesh_zonal(bytes, path, || {
        Ok(decode_glb(bytes, path)?.scene.normals.unwrap_or_default())
    })
}

/// A baked mesh's zonal transfer from its bytes, its lobes about `normals()` where its axis
/// is the normal.
pub(super) fn decode_mesh_zonal(
    bytes: &[u8],
    path: &Path,
    normals: impl FnOnce() -> Result<Vec<Vec3>>,
) -> Result<Option<ZonalTransfer>> {
    let (json, bin) = split_chunks(bytes, path)?;
    let doc = parse_document(json, path)?;
    let bad = |message: String| Error::baked(path, message);
    let mesh = doc
        .meshes
        .first()
        .ok_or(bad("the file has no mesh".into()))?;
    let Some(value) =
        extras_value(&mesh.extras).and_then(|extras| extras.get("prt")?.get("zonal").cloned())
    else {
        return Ok(None);
    };
    let extras: ZonalExtras =
        serde_json::from_value(value).map_err(|e| bad(format!("invalid extras.prt.zonal: {e}")))?;
    let normals = match extras.axes_buffer_view {
        Some(_) => None,
        None => Some(normals()?),
    };
    decode_with(&doc, bin, &extras, normals)
        .map(Some)
        .map_err(bad)
}

impl ZonalExtras {
    /// Refuses a layout, band count or channel count this reader does not read.
    pub(crate) fn check(&self) -> std::result::Result<(), String> {
        if self.layout != ZONAL_LAYOUT {
            return Err(format!("unsupported zonal layout \"{}\"", self.layout));
        }
        crate::sh::check_bands(self.bands).map_err(|e| e.to_string())?;
        if !matches!(self.channels, 1 | 3) {
            return Err(format!(
                "zonal transfer of {} channels (1 or 3)",
                self.channels
            ));
        }
        Ok(())
    }

    /// Puts the `(channel, group)` block's lanes (a vertex's four bands each) into `coeffs`,
    /// `[vertex][channel][l]`; lanes past the bands are left out.
    pub(crate) fn unpack_block<'a>(
        &self,
        coeffs: &mut [f32],
        (channel, group): (usize, usize),
        lanes: impl Iterator<Item = &'a [f32]>,
    ) {
        let (bands, channels) = (self.bands as usize, self.channels as usize);
        for (vertex, lanes) in lanes.enumerate() {
            for (lane, &value) in lanes.iter().enumerate().take(bands - 4 * group) {
                coeffs[(vertex * channels + channel) * bands + 4 * group + lane] = value;
            }
        }
    }
}

fn decode_with(
    doc: &Document,
    bin: &[u8],
    extras: &ZonalExtras,
    normals: Option<Vec<Vec3>>,
) -> std::result::Result<ZonalTransfer, String> {
    extras.check()?;
    let axis = match (extras.axis.as_str(), &normals) {
        ("normal", Some(_)) => ZonalAxis::Normal,
        ("fitted", None) => ZonalAxis::Fitted,
        (other, _) => {
            return Err(format!(
                "extras.prt.zonal: axis \"{other}\" with{} an axes view",
                if normals.is_some() { "out" } else { "" }
            ))
        }
    };
    let vertices = doc
        .accessors
        .first()
        .and_then(|a| usize::try_from(a.count.0).ok())
        .ok_or("the file has no POSITION accessor")?;
    let (bands, channels) = (extras.bands as usize, extras.channels as usize);
    let groups = groups_of(bands);
    let count = (channels * groups)
        .checked_mul(vertices)
        .and_then(|v| v.checked_mul(4))
        .ok_or("the zonal coefficients' count overflows")?;
    let planar = compressed::floats(
        doc,
        bin,
        extras.coefficients_buffer_view,
        count,
        "zonal coefficients",
    )?;
    let mut coeffs = vec![0.0; vertices * channels * bands];
    for channel in 0..channels {
        for group in 0..groups {
            let block = &planar[(channel * groups + group) * vertices * 4..][..vertices * 4];
            extras.unpack_block(&mut coeffs, (channel, group), block.chunks_exact(4));
        }
    }
    let axes = match (normals, extras.axes_buffer_view) {
        (Some(normals), _) => normals,
        (None, Some(view)) => compressed::floats(doc, bin, view, 3 * vertices, "zonal axes")?
            .chunks_exact(3)
            .map(|a| Vec3::new(a[0], a[1], a[2]))
            .collect(),
        (None, None) => unreachable!("a fitted axis has its view"),
    };
    if axes.len() != vertices {
        return Err(format!(
            "zonal transfer about {} axes for {vertices} vertices",
            axes.len()
        ));
    }
    ZonalTransfer::new((extras.bands, extras.channels, axis), axes, coeffs)
}

/// Reads a baked file's zonal transfer with Python and numpy alone (`python3 reader.py
/// file.glb`) and relights it about the rest pose's axes under the sky `L(w) = 1 + w_y`.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
bv, acc = gltf["bufferViews"], gltf["accessors"]
view = lambda i, dtype: np.frombuffer(binary, dtype, bv[i]["byteLength"] // np.dtype(dtype).itemsize, bv[i].get("byteOffset", 0))
prim, zh = gltf["meshes"][0]["primitives"][0], gltf["meshes"][0]["extras"]["prt"]["zonal"]
V, C, N = acc[prim["attributes"]["POSITION"]]["count"], zh["channels"], zh["bands"]
zonal = view(zh["coefficients_buffer_view"], "<f4").reshape(C, -1, V, 4).transpose(2, 0, 1, 3).reshape(V, C, -1)[:, :, :N]
axes = view(zh["axes_buffer_view"] if zh["axis"] == "fitted" else acc[prim["attributes"]["NORMAL"]]["bufferView"], "<f4").reshape(V, 3)
# radiance = sum_l z_l sqrt(4 pi / (2l+1)) L_l(axis), L_l the light's band l as a function; a
# deformed mesh turns `axes` as it turns its normals. For L(w) = 1 + w_y: L_0 = 1, L_1(a) = a_y.
band = [np.full(V, np.sqrt(4 * np.pi)), np.sqrt(4 * np.pi / 3) * axes[:, 1]]
radiance = sum(zonal[:, :, l] * band[l][:, None] for l in range(min(N, 2)))
print(json.dumps({"zonal": zonal.shape, "axis": zh["axis"], "radiance": radiance.tolist()}))
"#;
