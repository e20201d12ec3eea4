//! Transfer at receivers other than the vertices (a lightmap's texels, a fit's points): whole,
//! or a chunk at a time with each chunk's values handed on and let go, and, interreflected,
//! one final gather from the vertices' transfer.

use super::*;

/// Transfer at `receivers` on a prepared `scene` (RGB, `[receiver][channel][k]`; the
/// receivers' albedo unless `options.albedo` replaces it), and the rays cast. Interreflected
/// mode adds one final gather of `vertex_transfer` (the scene's baked vertex transfer, bounces
/// included) where each receiver's blocked rays land, as lightmappers gather from a coarser
/// solution: the receivers then carry one bounce more than the vertices.
pub fn bake_at(
    scene: &Scene,
    receivers: &Receivers,
    options: &BakeOptions,
    backend: &dyn Backend,
    vertex_transfer: Option<&Transfer>,
    progress: &dyn Progress,
) -> Result<(Transfer, u64)> {
    let bvh = Bvh::build(&scene.positions, &scene.triangles);
    let at = (receivers, bvh);
    bake_at_in(scene, at, options, backend, vertex_transfer, progress)
}

/// [`bake_at`] with the scene's tree already built.
pub fn bake_at_in(
    scene: &Scene,
    at: (&Receivers, Bvh),
    options: &BakeOptions,
    backend: &dyn Backend,
    vertex_transfer: Option<&Transfer>,
    progress: &dyn Progress,
) -> Result<(Transfer, u64)> {
    let with = (options, backend, vertex_transfer);
    bake_at_gathering(scene, at, with, progress, GATHER_CHUNK)
}

/// [`bake_at_in`], gathering `chunk` receivers at a time.
pub(super) fn bake_at_gathering(
    scene: &Scene,
    (receivers, bvh): (&Receivers, Bvh),
    (options, backend, vertex_transfer): (&BakeOptions, &dyn Backend, Option<&Transfer>),
    progress: &dyn Progress,
    chunk: usize,
) -> Result<(Transfer, u64)> {
    if options.mode != Mode::Interreflected {
        options.validate()?;
        let owned = BakeInputs::with_tree(scene, receivers, bvh, options);
        let direct = backend.direct_pass(&owned.view(), options.mode, progress)?;
        let transfer = tint_by_albedo(
            &direct.scalar,
            &receiver_albedo(receivers, options),
            options.bands,
        );
        return Ok((transfer, direct.rays_cast));
    }
    let mut coeffs = Vec::with_capacity(receivers.len() * 3 * coeff_count(options.bands));
    let at = (receivers, bvh);
    let rays_cast = bake_at_in_chunks(
        scene,
        at,
        (options, backend, vertex_transfer),
        (progress, chunk),
        &mut |_, transfer| {
            coeffs.extend(transfer.into_coeffs());
            Ok(())
        },
    )?;
    let transfer = Transfer::new(options.bands, 3, receivers.len(), coeffs)
        .expect("three channels of every receiver's coefficients");
    Ok((transfer, rays_cast))
}

/// Each receiver's albedo: `options.albedo` where it replaces the receivers'.
fn receiver_albedo(receivers: &Receivers, options: &BakeOptions) -> Vec<Vec3> {
    match options.albedo {
        Some(albedo) => vec![albedo; receivers.len()],
        None => receivers.albedo.clone(),
    }
}

/// [`bake_at_in`] `chunk` receivers at a time, each chunk's transfer handed to `each` with
/// its first receiver and let go: no more than a chunk's transfer (and, interreflected, its
/// gather rows) is held. A receiver's values are its own, whatever the chunk. Returns the
/// rays cast.
pub fn bake_at_in_chunks(
    scene: &Scene,
    (receivers, bvh): (&Receivers, Bvh),
    with: (&BakeOptions, &dyn Backend, Option<&Transfer>),
    chunked: (&dyn Progress, usize),
    each: &mut dyn FnMut(usize, Transfer) -> Result<()>,
) -> Result<u64> {
    let (rays_cast, _) = bake_run_in_chunks(scene, (receivers, bvh, 0), with, chunked, each)?;
    Ok(rays_cast)
}

/// [`bake_at_in_chunks`] of a run of a bake's receivers, `first` the number of its first in
/// the whole: each keeps its turn in the whole, and `each` is told the whole's numbers. The
/// tree comes back for the next run.
pub fn bake_run_in_chunks(
    scene: &Scene,
    (receivers, bvh, first_in_whole): (&Receivers, Bvh, usize),
    (options, backend, vertex_transfer): (&BakeOptions, &dyn Backend, Option<&Transfer>),
    (progress, chunk): (&dyn Progress, usize),
    each: &mut dyn FnMut(usize, Transfer) -> Result<()>,
) -> Result<(u64, Bvh)> {
    options.validate()?;
    let mut owned = BakeInputs::with_tree(scene, receivers, bvh, options);
    owned.turns = owned
        .turns
        .map(|turns| turns.skipping(first_in_whole as u32));
    let albedo = receiver_albedo(receivers, options);
    let vertices = match options.mode {
        Mode::Interreflected => Some(
            vertex_transfer
                .filter(|t| t.vertex_count() == scene.vertex_count() && t.bands() == options.bands)
                .ok_or_else(|| {
                    Error::Options(
                        "interreflected transfer at surface points gathers from the vertices' \
                         transfer, and none of this scene and band count was given"
                            .into(),
                    )
                })?,
        ),
        _ => None,
    };
    // Each receiver's gather row holds an entry per blocked ray, so the rows of a large
    // lightmap's texels would take gigabytes at once; a chunk's rows are gathered and dropped
    // before the next chunk's rays.
    progress.stage("transfer", receivers.len() as u64);
    let mut rays_cast = 0;
    for first in (0..receivers.len()).step_by(chunk.max(1)) {
        let chunk = first..receivers.len().min(first.saturating_add(chunk.max(1)));
        let part = owned.view().part(chunk.clone());
        let direct = backend.direct_pass(&part, options.mode, &Advancing(progress))?;
        rays_cast += direct.rays_cast;
        let mut transfer = tint_by_albedo(&direct.scalar, &albedo[chunk.clone()], options.bands);
        if let Some(vertices) = vertices {
            let matrix = direct
                .matrix
                .expect("an interreflected pass gives its gather matrix");
            let gathered = backend
                .gatherer(&matrix, &receivers.albedo[chunk], options.bands)?
                .gather(vertices.coeffs())?;
            transfer
                .coeffs_mut()
                .iter_mut()
                .zip(gathered)
                .for_each(|(t, g)| *t += g);
        }
        each(first_in_whole + first, transfer)?;
    }
    Ok((rays_cast, owned.bvh))
}

/// Receivers whose gather rows [`bake_at_in`] holds at once.
pub const GATHER_CHUNK: usize = 1 << 16;
