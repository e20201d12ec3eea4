//! Encoding a baked mesh: the BIN chunk's views, the JSON, the container.

use super::*;

pub(super) fn put_f32s(bin: &mut Vec<u8>, values: impl IntoIterator<Item = f32>) {
    for x in values {
        bin.extend_from_slice(&x.to_le_bytes());
    }
}

/// The baked mesh's .glb of `stored`, its lightmap named `lightmap_uri`, after checking that
/// the mesh carries the transfer.
pub(super) fn encode_valid(stored: Stored, lightmap_uri: Option<&str>) -> Result<Vec<u8>> {
    let (baked, cpca, precision) = (stored.baked(), stored.cpca(), stored.precision());
    let shape = Shape {
        transfer: stored.transfer_shape(),
        ..Shape::of(baked)
    };
    validate_shape(shape)?;
    let (mut bin, mut views) = encode_bin(baked, cpca.is_none(), precision);
    let cpca_extras = cpca.map(|cpca| compressed::encode(cpca, precision, &mut bin, &mut views));
    let probes = stored.probes().map(|set| {
        probes::encode(set, |bytes| {
            append_view(&mut bin, &mut views, |bin| bin.extend(bytes))
        })
    });
    let zonal = stored.zonal().map(|zonal| {
        zonal::encode(zonal, |bytes, stride| {
            let index = append_view(&mut bin, &mut views, |bin| bin.extend(bytes));
            views[index].byte_stride = stride.map(Stride);
            index
        })
    });
    bin.resize(bin.len().next_multiple_of(4), 0);
    let extras = Extras {
        cpca: cpca_extras,
        probes,
        zonal,
    };
    let json = encode_json(shape, lightmap_uri, extras, views, bin.len(), precision)?;
    glb_container(json, bin)
}

/// What `extras.prt` says of views appended after the mesh's and the transfer's.
#[derive(Default)]
pub(super) struct Extras {
    pub(super) cpca: Option<CpcaExtras>,
    pub(super) probes: Option<probes::ProbesExtras>,
    pub(super) zonal: Option<zonal::ZonalExtras>,
}

/// The JSON chunk of `baked` with the BIN chunk's `views` (`bin_len` bytes in all).
pub(super) fn encode_json(
    shape: Shape,
    lightmap_uri: Option<&str>,
    Extras {
        cpca: cpca_extras,
        probes,
        zonal,
    }: Extras,
    views: Vec<BufferViewJson>,
    bin_len: usize,
    precision: Precision,
) -> Result<Vec<u8>> {
    let attributes_hold_transfer = cpca_extras.is_none() && precision == Precision::F32;
    let mut accessors = accessors_and_attributes(shape, attributes_hold_transfer);
    if let Some(zonal) = &zonal {
        let vertices = shape.scene.positions.len();
        zonal::add_accessors(zonal, vertices, (&mut accessors.0, &mut accessors.1));
    }
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
            probes,
            zonal,
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
pub(super) fn mesh_glb<X: Serialize>(
    extras: X,
    accessors: (Vec<AccessorJson>, Attributes),
    views: Vec<BufferViewJson>,
    bin: Vec<u8>,
) -> Result<Vec<u8>> {
    let json = mesh_json(extras, accessors, views, bin.len())?;
    glb_container(json, bin)
}

/// The JSON chunk of [`mesh_glb`], for a BIN chunk of `bin_len` bytes.
pub(super) fn mesh_json<X: Serialize>(
    extras: X,
    (accessors, attributes): (Vec<AccessorJson>, Attributes),
    views: Vec<BufferViewJson>,
    bin_len: usize,
) -> Result<Vec<u8>> {
    let primitive = PrimitiveJson {
        attributes,
        indices: Some(index(3)),
        mode: Checked::Valid(Mode::Triangles),
        extensions: None,
        extras: None,
        material: None,
        targets: None,
    };
    let doc = Document {
        asset: gltf_json::Asset {
            version: "2.0".into(),
            generator: Some(format!("prt-gpu {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        scene: Some(index(0)),
        scenes: vec![gltf_json::Scene {
            nodes: vec![index(0)],
            extensions: None,
            extras: None,
            name: None,
        }],
        nodes: vec![gltf_json::Node {
            mesh: Some(index(0)),
            ..Default::default()
        }],
        meshes: vec![gltf_json::Mesh {
            primitives: vec![primitive],
            extras: raw_extras(&extras)?,
            extensions: None,
            name: None,
            weights: None,
        }],
        accessors,
        buffer_views: views,
        buffers: vec![gltf_json::Buffer {
            byte_length: USize64::from(bin_len),
            uri: None,
            name: None,
            extensions: None,
            extras: None,
        }],
        ..Default::default()
    };
    encode_document(&doc)
}

/// The BIN chunk and its views: positions, normals, albedo, indices, then (with `planar`) the
/// per-vertex transfer at `precision` and, with a lightmap, its coordinates.
pub(super) fn encode_bin(
    baked: &BakedMesh,
    planar: bool,
    precision: Precision,
) -> (Vec<u8>, Vec<BufferViewJson>) {
    let (scene, transfer) = (&baked.scene, &baked.transfer);
    let capacity = bin_len(
        scene.positions.len(),
        scene.triangles.len(),
        transfer.channels(),
        transfer.bands(),
    );
    let mut bin = Vec::with_capacity(capacity.unwrap_or(0));
    let mut views = encode_mesh_views(scene, &mut bin);
    if !planar {
        return (bin, views);
    }
    let start = bin.len();
    put_planar_transfer(&mut bin, transfer, precision);
    views.push(planar_view(start, bin.len() - start, precision));
    if let Some(texels) = &baked.lightmap {
        let start = bin.len();
        let per_vertex = texels
            .vertex_texcoords(scene)
            .expect("validate_lightmap found the corners of each vertex agree");
        put_f32s(&mut bin, per_vertex.iter().flatten().copied());
        views.push(array_view(
            start,
            bin.len() - start,
            None,
            Target::ArrayBuffer,
        ));
    }
    let expected_views = TRANSFER_VIEW + 1 + baked.lightmap.is_some() as usize;
    debug_assert_eq!(views.len(), expected_views);
    const { assert!(TEXCOORD_VIEW == TRANSFER_VIEW + 1) };
    (bin, views)
}

/// Appends the mesh's positions, normals, albedo and indices to `bin`; their four views.
pub(super) fn encode_mesh_views(scene: &Scene, bin: &mut Vec<u8>) -> Vec<BufferViewJson> {
    let normals = scene.normals.as_deref().unwrap_or_default();
    let mut views = Vec::new();
    for vectors in [&scene.positions[..], normals, &scene.albedo[..]] {
        let start = bin.len();
        put_f32s(bin, vectors.iter().flat_map(|p| p.to_array()));
        views.push(array_view(
            start,
            bin.len() - start,
            None,
            Target::ArrayBuffer,
        ));
    }
    let start = bin.len();
    for &i in scene.triangles.iter().flatten() {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    views.push(array_view(
        start,
        bin.len() - start,
        None,
        Target::ElementArrayBuffer,
    ));
    debug_assert_eq!(views.len(), TRANSFER_VIEW);
    views
}

/// The transfer's view, `len` bytes from `start`. At float32 several accessors share it, so
/// the spec requires an explicit stride; no accessor reads half floats, so that view has none.
pub(super) fn planar_view(start: usize, len: usize, precision: Precision) -> BufferViewJson {
    let stride = match precision {
        Precision::F32 => Some(16),
        Precision::F16 => None,
    };
    array_view(start, len, stride, Target::ArrayBuffer)
}

/// Appends to `bin`, from its next 4-byte boundary, what `write` puts there, and a view of it
/// to `views`; returns the view's index. Every extras-named view of a baked file (compressed
/// transfer, local lights) is added this way.
pub(super) fn append_view(
    bin: &mut Vec<u8>,
    views: &mut Vec<BufferViewJson>,
    write: impl FnOnce(&mut Vec<u8>),
) -> usize {
    bin.resize(bin.len().next_multiple_of(4), 0);
    let start = bin.len();
    write(bin);
    views.push(array_view(
        start,
        bin.len() - start,
        None,
        Target::ArrayBuffer,
    ));
    views.len() - 1
}

pub(super) fn array_view(
    start: usize,
    len: usize,
    stride: Option<usize>,
    target: Target,
) -> BufferViewJson {
    BufferViewJson {
        buffer: index(0),
        byte_offset: Some(USize64::from(start)),
        byte_length: USize64::from(len),
        byte_stride: stride.map(Stride),
        target: Some(Checked::Valid(target)),
        name: None,
        extensions: None,
        extras: None,
    }
}

/// Appends `transfer` in the planar layout at `precision` ([`TRANSFER_LAYOUT`],
/// [`TRANSFER_LAYOUT_F16`]).
pub(super) fn put_planar_transfer(bin: &mut Vec<u8>, transfer: &Transfer, precision: Precision) {
    for channel in 0..transfer.channels() as usize {
        for group in 0..groups(transfer.bands()) {
            put_planar_block(bin, transfer, channel, group, precision);
        }
    }
}

/// Appends the `(channel, group)` block of `transfer`'s vertices: four coefficients each, at
/// `precision`.
pub(super) fn put_planar_block(
    bin: &mut Vec<u8>,
    transfer: &Transfer,
    channel: usize,
    group: usize,
    precision: Precision,
) {
    for vertex in 0..transfer.vertex_count() {
        let coeffs = transfer.vertex_channel(vertex, channel);
        let lanes = std::array::from_fn::<f32, 4, _>(|lane| {
            coeffs.get(4 * group + lane).copied().unwrap_or(0.0)
        });
        precision.encode(&lanes, bin);
    }
}

/// The accessors of the views [`encode_bin`] lays out, and the primitive's attributes.
pub(super) fn accessors_and_attributes(
    shape: Shape,
    planar: bool,
) -> (Vec<AccessorJson>, Attributes) {
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
            attributes.insert(semantic(&name), index(accessors.len()));
            let offset = block * v * 16;
            accessors.push(accessor(
                TRANSFER_VIEW,
                offset,
                ComponentType::F32,
                v,
                Type::Vec4,
            ));
        }
    }
    if shape.lightmap.is_some() {
        let texcoords = Checked::Valid(Semantic::TexCoords(0));
        attributes.insert(texcoords, index(accessors.len()));
        accessors.push(accessor(
            TEXCOORD_VIEW,
            0,
            ComponentType::F32,
            v,
            Type::Vec2,
        ));
    }
    (accessors, attributes)
}

/// An accessor of `count` elements of `kind` at `offset` in view `view`, without bounds.
pub(super) fn accessor(
    view: usize,
    offset: usize,
    component: ComponentType,
    count: usize,
    kind: Type,
) -> AccessorJson {
    AccessorJson {
        buffer_view: Some(index(view)),
        byte_offset: Some(USize64::from(offset)),
        component_type: Checked::Valid(GenericComponentType(component)),
        count: USize64::from(count),
        type_: Checked::Valid(kind),
        min: None,
        max: None,
        name: None,
        normalized: false,
        sparse: None,
        extensions: None,
        extras: None,
    }
}

/// The accessors of [`encode_mesh`]'s views and the primitive's `POSITION`, `NORMAL` and
/// `COLOR_0` attributes.
pub(super) fn mesh_accessors(scene: &Scene) -> (Vec<AccessorJson>, Attributes) {
    let v = scene.positions.len();
    let (min, max) = scene.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let vec3s = |view| accessor(view, 0, ComponentType::F32, v, Type::Vec3);
    let accessors = vec![
        AccessorJson {
            min: Some(f32_values(&min.to_array())),
            max: Some(f32_values(&max.to_array())),
            ..vec3s(0)
        },
        vec3s(1),
        vec3s(2),
        accessor(
            3,
            0,
            ComponentType::U32,
            3 * scene.triangles.len(),
            Type::Scalar,
        ),
    ];
    let attributes = [Semantic::Positions, Semantic::Normals, Semantic::Colors(0)]
        .into_iter()
        .enumerate()
        .map(|(i, semantic)| (Checked::Valid(semantic), index(i)))
        .collect();
    (accessors, attributes)
}

/// The glTF binary container: header, JSON chunk (space-padded), BIN chunk (zero-padded).
pub(crate) fn glb_container(json: Vec<u8>, mut bin: Vec<u8>) -> Result<Vec<u8>> {
    bin.resize(bin.len().next_multiple_of(4), 0);
    let mut out = glb_head(json, bin.len())?;
    out.extend_from_slice(&bin);
    Ok(out)
}

/// A .glb up to its BIN chunk's bytes: the header, the JSON chunk (padded with spaces) and the
/// BIN chunk's header for `bin_len` bytes (a multiple of 4), which a writer appends.
pub(crate) fn glb_head(mut json: Vec<u8>, bin_len: usize) -> Result<Vec<u8>> {
    debug_assert_eq!(bin_len % 4, 0);
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + json.len() + 8 + bin_len;
    let total32 = u32::try_from(total)
        .map_err(|_| Error::Geometry("the baked file would exceed the 4 GiB .glb limit".into()))?;
    let mut out = Vec::with_capacity(28 + json.len());
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
    for word in [bin_len as u32, CHUNK_BIN] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    Ok(out)
}
