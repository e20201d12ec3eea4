//! What a baked mesh must satisfy before it is encoded, so encoding itself cannot fail
//! halfway: its shape, finite values, a compression or lightmap that belongs to it, and the
//! sizes the file will have.

use super::*;

/// Checks a baked mesh whole: the mesh, and the transfer it carries.
pub(super) fn validate(baked: &BakedMesh) -> Result<()> {
    validate_mesh(baked)?;
    check_finite_coeffs(&baked.transfer, 0)
}

/// Checks what `encode_valid` relies on besides the transfer's values (which [`Stored::new`]
/// checked), so encoding itself cannot fail halfway: the mesh, and that it carries the
/// transfer's shape.
pub(super) fn validate_mesh(baked: &BakedMesh) -> Result<()> {
    validate_shape(Shape::of(baked))
}

/// Refuses a non-finite coefficient, naming its vertex (`first` is the first vertex's index).
pub(super) fn check_finite_coeffs(transfer: &Transfer, first: usize) -> Result<()> {
    if let Some(i) = transfer.coeffs().iter().position(|x| !x.is_finite()) {
        let per_vertex = (transfer.channels() * transfer.bands() * transfer.bands()) as usize;
        return Err(Error::Geometry(format!(
            "non-finite transfer coefficient at vertex {}",
            first + i / per_vertex
        )));
    }
    Ok(())
}

/// A baked mesh without its coefficients: what the JSON chunk and the checks read. A streamed
/// file (`stream`) is described by one before its coefficients exist.
#[derive(Clone, Copy)]
pub(super) struct Shape<'a> {
    pub scene: &'a Scene,
    pub transfer: TransferShape,
    pub metadata: &'a BakeMetadata,
    pub lightmap: Option<&'a TexelBake>,
}

impl<'a> Shape<'a> {
    pub fn of(baked: &'a BakedMesh) -> Shape<'a> {
        Shape {
            scene: &baked.scene,
            transfer: baked.transfer.shape(),
            metadata: &baked.metadata,
            lightmap: baked.lightmap.as_ref(),
        }
    }
}

/// Checks everything but the transfer's coefficients: the mesh, the transfer's shape and
/// metadata, the lightmap, the file's size.
pub(super) fn validate_shape(shape: Shape) -> Result<()> {
    let bad = |message: String| Err(Error::Geometry(message));
    let (scene, transfer, meta) = (shape.scene, shape.transfer, shape.metadata);
    let v = scene.positions.len();
    if v == 0 || scene.triangles.is_empty() {
        return bad(format!(
            "cannot write a mesh with {v} vertices and {} triangles (glTF needs at least one of each)",
            scene.triangles.len()
        ));
    }
    if v > u32::MAX as usize {
        return bad(format!("{v} vertices do not fit 32-bit indices"));
    }
    let Some(normals) = &scene.normals else {
        return bad("the mesh has no normals (prepare it before writing)".into());
    };
    if normals.len() != v || scene.albedo.len() != v {
        return bad(format!(
            "{v} positions but {} normals and {} albedo values",
            normals.len(),
            scene.albedo.len()
        ));
    }
    for (name, values) in [
        ("position", &scene.positions),
        ("normal", normals),
        ("albedo", &scene.albedo),
    ] {
        if let Some(i) = values.iter().position(|p| !p.is_finite()) {
            return bad(format!("non-finite {name} at vertex {i}"));
        }
    }
    for (t, tri) in scene.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= v) {
            return bad(format!(
                "triangle {t} uses vertex {i} but there are only {v} vertices"
            ));
        }
    }
    if transfer.vertex_count != v {
        return bad(format!(
            "the transfer covers {} vertices but the mesh has {v}",
            transfer.vertex_count
        ));
    }
    if transfer.bands == 0 || transfer.bands > crate::sh::MAX_BANDS {
        return bad(format!(
            "transfer has {} bands (1 to {} supported)",
            transfer.bands,
            crate::sh::MAX_BANDS
        ));
    }
    if transfer.channels != 1 && transfer.channels != 3 {
        return bad(format!(
            "transfer has {} channels (1 or 3 supported)",
            transfer.channels
        ));
    }
    if meta.bands != transfer.bands || meta.channels != transfer.channels {
        return bad(format!(
            "metadata says {} bands and {} channels but the transfer has {} and {}",
            meta.bands, meta.channels, transfer.bands, transfer.channels
        ));
    }
    if let Some(texels) = shape.lightmap {
        validate_lightmap(texels, transfer, scene).map_err(Error::Geometry)?;
    }
    let bin = bin_len(v, scene.triangles.len(), transfer.channels, transfer.bands);
    // A GLB records its total length in 32 bits; keep a margin for the header and the JSON.
    if bin.is_none_or(|b| b > u32::MAX as usize - (64 << 20)) {
        return bad(format!(
            "{v} vertices with {} bands and {} channels exceed the 4 GiB limit of a .glb file",
            transfer.bands, transfer.channels
        ));
    }
    Ok(())
}

/// Checks that compressed transfer matches the mesh and transfer it stands for.
pub(super) fn validate_cpca(baked: &BakedMesh, cpca: &Cpca) -> std::result::Result<(), String> {
    let t = &baked.transfer;
    if baked.lightmap.is_some() {
        return Err("a lightmapped bake cannot be stored compressed".into());
    }
    if (cpca.bands, cpca.channels, cpca.vertex_count())
        != (t.bands(), t.channels(), t.vertex_count())
    {
        return Err(format!(
            "the compressed transfer has {} vertices of {} bands and {} channels, the mesh {} \
             of {} and {}",
            cpca.vertex_count(),
            cpca.bands,
            cpca.channels,
            t.vertex_count(),
            t.bands(),
            t.channels()
        ));
    }
    Ok(())
}

/// Checks that a lightmap fits the mesh it belongs to: one coordinate pair per triangle corner,
/// the same at every corner of a vertex (a file holds them per vertex), and texels of the
/// vertex transfer's bands and channels.
pub(super) fn validate_lightmap(
    texels: &TexelBake,
    transfer: TransferShape,
    scene: &Scene,
) -> std::result::Result<(), String> {
    let map = &texels.transfer;
    let corners = 3 * scene.triangles.len();
    if texels.texcoords.len() != corners {
        return Err(format!(
            "{} lightmap coordinates for {corners} triangle corners",
            texels.texcoords.len()
        ));
    }
    if texels.texcoords.iter().flatten().any(|x| !x.is_finite()) {
        return Err("non-finite lightmap coordinates".into());
    }
    if texels.vertex_texcoords(scene).is_none() {
        return Err(
            "the corners of a vertex have different lightmap coordinates; \
                    the mesh must be split where its charts meet"
                .into(),
        );
    }
    let held = texels.held.as_ref().map(|held| held.shape());
    let texel_count = match held {
        // Held in a scratch file, checked as the file is written.
        Some(shape) if (shape.width, shape.height) == (texels.width, texels.height) => 0,
        _ => texels.width as usize * texels.height as usize,
    };
    if (map.bands(), map.channels()) != (transfer.bands, transfer.channels)
        || held.is_some_and(|shape| (shape.bands, shape.channels) != (map.bands(), map.channels()))
        || map.vertex_count() != texel_count
    {
        return Err(format!(
            "the lightmap holds {} texels of {} bands and {} channels for a {}x{} map of {} and {}",
            map.vertex_count(),
            map.bands(),
            map.channels(),
            texels.width,
            texels.height,
            transfer.bands,
            transfer.channels
        ));
    }
    Ok(())
}

pub(crate) fn groups(bands: u32) -> usize {
    (bands as usize * bands as usize).div_ceil(4)
}

pub(super) fn transfer_bytes(v: usize, channels: u32, bands: u32) -> Option<usize> {
    v.checked_mul(channels as usize)?
        .checked_mul(groups(bands))?
        .checked_mul(16)
}

/// The bytes of the planar transfer view at `precision`.
pub(super) fn planar_bytes(
    v: usize,
    channels: u32,
    bands: u32,
    precision: Precision,
) -> Option<usize> {
    Some(transfer_bytes(v, channels, bands)? / 4 * precision.bytes())
}

pub(super) fn bin_len(v: usize, t: usize, channels: u32, bands: u32) -> Option<usize> {
    v.checked_mul(36)?
        .checked_add(t.checked_mul(12)?)?
        .checked_add(transfer_bytes(v, channels, bands)?)
}
