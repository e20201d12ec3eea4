//! Decoding a baked file. Every offset and count comes from untrusted bytes: all arithmetic is
//! checked and every range is proven inside the BIN chunk before anything is allocated or read.

use super::*;

/// A lightmap's reference and the lightmap coordinates of every vertex.
pub(super) type LightmapParts = Option<(LightmapExtras, Vec<[f32; 2]>)>;

/// The JSON and BIN chunks of a `.glb`, their headers checked against the file's length.
pub(super) fn split_chunks<'b>(bytes: &'b [u8], path: &Path) -> Result<(&'b [u8], &'b [u8])> {
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

pub(super) fn decode_parts(
    bytes: &[u8],
    path: &Path,
) -> Result<(BakedMesh, LightmapParts, Option<Cpca>)> {
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
    let mut transfer = match &cpca {
        Some(cpca) => cpca.reconstruct(),
        None => {
            let zeros = vec![0f32; v * channels * n];
            let shape = (plan.metadata.bands, plan.metadata.channels);
            Transfer::new(shape.0, shape.1, v, zeros)
                .map_err(|e| Error::baked(path, e.to_string()))?
        }
    };
    read_planar_transfer(bin, &plan, path, transfer.coeffs_mut())?;

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
        transfer,
        metadata: plan.metadata,
        lightmap: None,
    };
    Ok((baked, lightmap, cpca))
}

/// The per-vertex transfer of the planar `_PRT_*` attributes into `coeffs`
/// (`[vertex][channel][k]`), each value finite.
pub(super) fn read_planar_transfer(
    bin: &[u8],
    plan: &Plan,
    path: &Path,
    coeffs: &mut [f32],
) -> Result<()> {
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
pub(super) fn read_texcoords(bin: &[u8], span: &Span, path: &Path) -> Result<Vec<[f32; 2]>> {
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

pub(super) fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

pub(super) fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(bytes, at))
}

/// Checks the 12-byte header and the JSON chunk header; returns the JSON chunk length.
pub(super) fn check_head(head: &[u8], file_len: u64, path: &Path) -> Result<usize> {
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
pub(super) fn check_bin_head(head: &[u8], start: u64, file_len: u64, path: &Path) -> Result<usize> {
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

pub(super) fn parse_document(json: &[u8], path: &Path) -> Result<Document> {
    Document::from_slice(json).map_err(|e| Error::baked(path, format!("invalid glTF JSON: {e}")))
}

/// Where one accessor's elements lie in the BIN chunk.
pub(super) struct Span {
    pub(super) offset: usize,
    pub(super) stride: usize,
    pub(super) count: usize,
}

/// Everything `decode_glb` needs to read the BIN chunk, already checked against its length.
pub(super) struct Plan {
    pub(super) metadata: BakeMetadata,
    pub(super) vertices: usize,
    pub(super) triangles: usize,
    pub(super) coeffs_per_channel: usize,
    pub(super) groups: usize,
    pub(super) positions: Span,
    pub(super) normals: Span,
    pub(super) albedo: Span,
    pub(super) indices: Span,
    /// One per `(channel, group)`, channel-major.
    pub(super) transfer: Vec<Span>,
    /// Whether the transfer is stored as half floats (then `transfer`'s spans have stride 8).
    pub(super) half: bool,
    pub(super) lightmap: Option<LightmapExtras>,
    /// `TEXCOORD_0`, present with a lightmap.
    pub(super) texcoords: Option<Span>,
    /// Compressed transfer, in place of `transfer`.
    pub(super) cpca: Option<CpcaExtras>,
}

pub(super) fn plan(doc: &Document, bin_len: usize, path: &Path) -> Result<Plan> {
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
    if primitive.mode != Checked::Valid(Mode::Triangles) {
        return Err(bad("the primitive is not a triangle list".into()));
    }
    let prt = prt_extras(doc).map_err(bad)?;

    let locate = |what: &str, index: Option<usize>, component, kind| {
        locate(doc, buffer_len, what, index, (component, kind)).map_err(bad)
    };
    let attribute = |name: &str| attribute(primitive, name);
    let (float, vec3) = (ComponentType::F32, Type::Vec3);
    let positions = locate("POSITION", attribute("POSITION"), float, vec3)?;
    let v = positions.count;
    let normals = same_count(
        locate("NORMAL", attribute("NORMAL"), float, vec3)?,
        v,
        "NORMAL",
    )
    .map_err(bad)?;
    let albedo = same_count(
        locate("COLOR_0", attribute("COLOR_0"), float, vec3)?,
        v,
        "COLOR_0",
    )
    .map_err(bad)?;
    let index_accessor = primitive.indices.map(|i| i.value());
    let indices = locate("indices", index_accessor, ComponentType::U32, Type::Scalar)?;
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
            let span = locate(&name, attribute(&name), float, Type::Vec2)?;
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
pub(super) fn check_buffer(doc: &Document, bin_len: usize) -> std::result::Result<u64, String> {
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
    let declared = buffer.byte_length.0;
    if declared > bin_len as u64 {
        return Err(format!(
            "the buffer declares {declared} bytes but the BIN chunk has {bin_len}"
        ));
    }
    Ok(declared)
}

/// The first mesh's `extras.prt`, with a layout, band count and channel count this reader
/// knows.
pub(super) fn prt_extras(doc: &Document) -> std::result::Result<PrtExtrasIn, String> {
    let prt = mesh_prt(doc).ok_or("not a prt-gpu file: the mesh has no extras.prt")?;
    if prt.get("mode").and_then(|m| m.as_str()) == Some("local") {
        return Err(
            "a local-lights bake (--mode local) holds no SH transfer: render it alone \
             with --point-light or --spot-light"
                .into(),
        );
    }
    let prt: PrtExtrasIn =
        serde_json::from_value(prt).map_err(|e| format!("invalid extras.prt: {e}"))?;
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
pub(super) fn same_count(
    span: Span,
    vertices: usize,
    what: &str,
) -> std::result::Result<Span, String> {
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
pub(super) fn half_transfer_spans(
    doc: &Document,
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
    let expected = planar_bytes(v, meta.channels, meta.bands, Precision::F16);
    let length = view.byte_length.0;
    if expected.map(|n| n as u64) != Some(length) {
        return Err(format!(
            "the half-float transfer view has {length} bytes, expected {v} vertices x {blocks} blocks x 8"
        ));
    }
    let start = view_start(view) as usize;
    Ok((0..blocks)
        .map(|block| Span {
            offset: start + block * v * 8,
            stride: 8,
            count: v,
        })
        .collect())
}

pub(super) fn transfer_spans(
    doc: &Document,
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
    let length = view.byte_length.0;
    if expected.map(|n| n as u64) != Some(length) {
        return Err(format!(
            "the transfer buffer view has {length} bytes, expected {v} vertices x {} channels x {groups} groups x 16",
            meta.channels
        ));
    }
    let mut transfer = Vec::with_capacity(meta.channels as usize * groups);
    for channel in 0..meta.channels {
        for group in 0..groups {
            let name = transfer_attribute_name(meta.channels, channel, group);
            let index = attribute(primitive, &name);
            let vec4s = (ComponentType::F32, Type::Vec4);
            let span = locate(doc, buffer_len, &name, index, vec4s)?;
            let span = same_count(span, v, &name)?;
            let block = channel as usize * groups + group;
            let accessor = &doc.accessors[index.unwrap_or_default()];
            if accessor.buffer_view.map(|view| view.value()) != Some(transfer_view)
                || accessor_start(accessor) != (block * v * 16) as u64
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

/// Resolves accessor `index` to a span of its elements, checked to be `kind` of `component`
/// (4 bytes each) and proven to lie inside the buffer (whose length was already checked
/// against the BIN chunk).
pub(super) fn locate(
    doc: &Document,
    buffer_len: u64,
    what: &str,
    index: Option<usize>,
    (component, kind): (ComponentType, Type),
) -> std::result::Result<Span, String> {
    let index = index.ok_or_else(|| format!("the primitive has no {what} accessor"))?;
    let accessor = doc
        .accessors
        .get(index)
        .ok_or_else(|| format!("{what} refers to missing accessor {index}"))?;
    if !accessor_is(accessor, component, kind) {
        let expected = accessor_kind(&super::accessor(0, 0, component, 0, kind));
        return Err(format!(
            "{what} is {}, expected {expected}",
            accessor_kind(accessor)
        ));
    }
    if accessor.sparse.is_some() {
        return Err(format!(
            "{what} is a sparse accessor, which is not supported"
        ));
    }
    let view_index = accessor
        .buffer_view
        .map(|view| view.value())
        .ok_or_else(|| format!("{what} has no buffer view"))?;
    let view = doc
        .buffer_views
        .get(view_index)
        .ok_or_else(|| format!("{what} refers to missing buffer view {view_index}"))?;
    if view.buffer.value() != 0 {
        return Err(format!(
            "buffer view {view_index} refers to a missing buffer"
        ));
    }
    let (view_offset, view_length) = (view_start(view), view.byte_length.0);
    let view_end = view_offset.checked_add(view_length);
    if view_end.is_none_or(|end| end > buffer_len) {
        return Err(format!(
            "buffer view {view_index} runs past the end of the buffer"
        ));
    }
    let element = 4 * kind.multiplicity() as u64;
    let stride = view.byte_stride.map_or(element, |stride| stride.0 as u64);
    if stride < element || stride % 4 != 0 {
        return Err(format!(
            "buffer view {view_index} has an invalid stride {stride}"
        ));
    }
    let count = accessor.count.0;
    if count == 0 {
        return Err(format!("{what} has no elements"));
    }
    // The last element must end inside the view.
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(element))
        .and_then(|x| x.checked_add(accessor_start(accessor)));
    if end.is_none_or(|end| end > view_length) {
        return Err(format!(
            "{what} runs past the end of buffer view {view_index}"
        ));
    }
    let offset = view_offset + accessor_start(accessor);
    if !offset.is_multiple_of(4) {
        return Err(format!("{what} is not 4-byte aligned"));
    }
    // In range of usize: everything is bounded by the buffer, which is inside the file.
    Ok(Span {
        offset: offset as usize,
        stride: stride as usize,
        count: count as usize,
    })
}

/// The bytes from a span's first element to the end of its last, with `element` bytes each.
pub(super) fn span_bytes<'a>(
    bin: &'a [u8],
    span: &Span,
    element: usize,
    path: &Path,
) -> Result<&'a [u8]> {
    let len = (span.count - 1) * span.stride + element;
    bin.get(span.offset..span.offset + len)
        .ok_or_else(|| Error::baked(path, "an accessor runs past the BIN chunk"))
}
