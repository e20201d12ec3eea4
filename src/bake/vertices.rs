//! A bake's vertex transfer from the values at its receivers: the direct light at the vertices
//! or fitted from the fit's points (whole, or summed a run at a time), a translucent medium's
//! scattering, and the bounces, each gathered at the receivers and taken back to the
//! vertices.

use std::time::Instant;

use glam::Vec3;

use super::points::{Fitting, Light, PointChunks};
use super::{
    adaptive, bounce, subsurface, tint_by_albedo, Backend, BakeOptions, BounceStat, DirectPass,
    Fit, Progress, Transfer,
};
use crate::error::Result;
use crate::receivers::fit::FitReport;
use crate::scene::Scene;
use crate::sh::coeff_count;

/// Where the values at a bake's receivers come from.
pub(super) enum AtReceivers {
    /// The whole direct pass, at the vertices or at the fit's points.
    Whole(DirectPass),
    /// The fit's points baked a run at a time, their values summed as they come.
    Chunked(PointChunks),
}

impl AtReceivers {
    /// With an error target, each receiver's samples and error.
    pub(super) fn adaptive(&self) -> Option<&adaptive::ReceiverErrors> {
        match self {
            AtReceivers::Whole(direct) => direct.adaptive.as_ref(),
            AtReceivers::Chunked(chunks) => chunks.adaptive.as_ref(),
        }
    }

    /// The rays cast, and the gather rows' entries.
    pub(super) fn counts(&self) -> (u64, usize) {
        match self {
            AtReceivers::Whole(direct) => (
                direct.rays_cast,
                direct.matrix.as_ref().map_or(0, |m| m.columns.len()),
            ),
            AtReceivers::Chunked(chunks) => (chunks.rays_cast, chunks.gather_entries),
        }
    }

    /// The direct light's RGB vertex values (`albedo` each receiver's), fitted where there is
    /// a `fitting`, and the fit's report.
    fn direct_at_vertices(
        &mut self,
        fitting: Option<&Fitting>,
        albedo: &[Vec3],
        bands: u32,
    ) -> Result<(Vec<f32>, Option<FitReport>)> {
        match (self, fitting) {
            (AtReceivers::Chunked(chunks), Some(fitting)) => {
                let (values, report) = chunks.direct_at_vertices(fitting);
                Ok((values, Some(report)))
            }
            (AtReceivers::Whole(direct), fitting) => {
                let values = tint_by_albedo(&direct.scalar, albedo, bands).into_coeffs();
                match fitting {
                    None => Ok((values, None)),
                    Some(fitting) => {
                        let columns = 3 * coeff_count(bands);
                        let (values, report) = fitting.fit(values, columns, Light::Direct)?;
                        Ok((values, Some(report)))
                    }
                }
            }
            (AtReceivers::Chunked(_), None) => unreachable!("points are chunked for a fit"),
        }
    }

    /// Lean direct transfer's albedo-free vertex values, fitted where there is a `fitting`.
    pub(super) fn albedo_free_at_vertices(
        &mut self,
        fitting: Option<&Fitting>,
        bands: u32,
    ) -> Result<Vec<f32>> {
        match (self, fitting) {
            (AtReceivers::Chunked(chunks), Some(fitting)) => {
                Ok(chunks.albedo_free_at_vertices(fitting))
            }
            (AtReceivers::Whole(direct), None) => Ok(direct.scalar.clone()),
            (AtReceivers::Whole(direct), Some(fitting)) => {
                let rhs = fitting.right_hand_side(&direct.scalar, coeff_count(bands))?;
                Ok(fitting.solve(rhs).0)
            }
            (AtReceivers::Chunked(_), None) => unreachable!("points are chunked for a fit"),
        }
    }
}

/// Vertex transfer from the values `at` the receivers (fitted, for the least-squares fit;
/// `albedo` each receiver's) and its bounces; what each bounce added, the first fit's report
/// and the direct fit's time.
pub(super) fn vertex_transfer(
    (scene, vertex_map): (&Scene, &[u32]),
    (at, fitting, albedo): (&mut AtReceivers, Option<&Fitting>, &[Vec3]),
    options: &BakeOptions,
    backend: &dyn Backend,
    progress: &dyn Progress,
) -> Result<VertexTransfer> {
    let started = Instant::now();
    let bands = options.bands;
    let media = media_of(scene, vertex_map, options);
    let scatter = match &media {
        Some((materials, of_vertex)) => {
            Some(subsurface::Scatter::new(scene, (materials, of_vertex))?)
        }
        None => None,
    };
    // What arrives at the vertices, summed over the direct light and the bounces: a
    // lightmap's texels scatter it too.
    let mut incoming: Option<Vec<f32>> = None;
    let keep_incoming = options.lightmap.is_some();
    let scattering = scatter.as_ref().map(|s| s.on(bands, backend));
    let scattering = scattering.transpose()?;
    let mut scattered = |values: Vec<f32>| -> Result<Vec<f32>> {
        let Some(scattering) = &scattering else {
            return Ok(values);
        };
        if keep_incoming {
            match &mut incoming {
                Some(sum) => sum.iter_mut().zip(&values).for_each(|(s, v)| *s += v),
                None => incoming = Some(values.clone()),
            }
        }
        scattering.apply(&values)
    };
    let (direct, fit_report) = at.direct_at_vertices(fitting, albedo, bands)?;
    let mut transfer = Transfer::new(bands, 3, scene.vertex_count(), scattered(direct)?)
        .expect("the vertex values hold every vertex's coefficients");
    let seconds_fit = match options.fit {
        Fit::Point => 0.0,
        Fit::LeastSquares => started.elapsed().as_secs_f64(),
    };
    let columns = 3 * coeff_count(bands);
    let bounces = match at {
        AtReceivers::Whole(DirectPass {
            matrix: Some(matrix),
            ..
        }) => {
            let gatherer = backend.gatherer(matrix, albedo, bands)?;
            let mut next_bounce = |previous: &[f32]| -> Result<Bounce> {
                let gathered = gatherer.gather(previous)?;
                let (fitted, iterations) = match fitting {
                    Some(fitting) => {
                        let (fitted, report) = fitting.fit(gathered, columns, Light::Bounce)?;
                        (fitted, Some(report.iterations))
                    }
                    None => (gathered, None),
                };
                Ok((scattered(fitted)?, iterations))
            };
            add_bounces(&mut transfer, &mut next_bounce, options, progress)?
        }
        AtReceivers::Chunked(chunks) if chunks.gathers() => {
            let fitting = fitting.expect("points are chunked for a fit");
            let mut next_bounce = |previous: &[f32]| -> Result<Bounce> {
                let (fitted, report) =
                    chunks.bounce((fitting, albedo), previous, bands, backend)?;
                Ok((scattered(fitted)?, Some(report.iterations)))
            };
            add_bounces(&mut transfer, &mut next_bounce, options, progress)?
        }
        _ => Vec::new(),
    };
    let subsurface = scatter.as_ref().map(|scatter| scatter.report);
    let scattered = media
        .zip(incoming)
        .map(|((materials, of_vertex), incoming)| Scattered {
            materials,
            of_vertex,
            incoming,
        });
    Ok(VertexTransfer {
        transfer,
        bounces,
        fit_report,
        seconds_fit,
        subsurface,
        scattered,
    })
}

/// The media of the prepared `scene`'s vertices: the one the options give it, or its own
/// materials' (`vertex_map` giving the prepared vertex each loaded one became), and each
/// vertex's index among them or [`subsurface::OPAQUE`]; `None` where it has neither.
fn media_of(
    scene: &Scene,
    vertex_map: &[u32],
    options: &BakeOptions,
) -> Option<(Vec<subsurface::SubsurfaceMaterial>, Vec<u32>)> {
    let vertices = scene.vertex_count();
    match (&options.subsurface, &options.scene_media) {
        (Some(material), _) => Some((vec![*material], vec![0; vertices])),
        (None, Some(media)) => Some((media.materials(), media.on_prepared(vertex_map, vertices))),
        (None, None) => None,
    }
}

/// What a lightmap's texels scatter: the vertices' media and the light arriving at them.
pub(super) struct Scattered {
    pub(super) materials: Vec<subsurface::SubsurfaceMaterial>,
    pub(super) of_vertex: Vec<u32>,
    pub(super) incoming: Vec<f32>,
}

/// What [`vertex_transfer`] made.
pub(super) struct VertexTransfer {
    pub(super) transfer: Transfer,
    pub(super) bounces: Vec<BounceStat>,
    pub(super) fit_report: Option<FitReport>,
    pub(super) seconds_fit: f64,
    pub(super) subsurface: Option<subsurface::SubsurfaceReport>,
    /// Where a lightmap is baked in a medium: what its texels scatter.
    pub(super) scattered: Option<Scattered>,
}

/// A bounce's vertex values, and the iterations of their fit's solve where there is one.
type Bounce = (Vec<f32>, Option<u32>);

/// Adds `options.bounces` bounces to the vertex `transfer` in place (stopping early below
/// `options.bounce_tolerance`). Each bounce is `next_bounce` of the previous one's vertex
/// values: gathered at the receivers and taken back to the vertices.
fn add_bounces(
    transfer: &mut Transfer,
    next_bounce: &mut dyn FnMut(&[f32]) -> Result<Bounce>,
    options: &BakeOptions,
    progress: &dyn Progress,
) -> Result<Vec<BounceStat>> {
    let coeffs = coeff_count(transfer.bands());
    progress.stage("bounces", options.bounces as u64);
    let mut previous = transfer.coeffs().to_vec();
    let mut stats = Vec::new();
    for _ in 0..options.bounces {
        let started = Instant::now();
        let (next, fit_iterations) = next_bounce(&previous)?;
        let relative_energy = bounce::relative_energy(&next, transfer.coeffs(), coeffs);
        transfer
            .coeffs_mut()
            .iter_mut()
            .zip(&next)
            .for_each(|(t, n)| *t += n);
        stats.push(BounceStat {
            relative_energy,
            seconds: started.elapsed().as_secs_f64(),
            fit_iterations,
        });
        progress.advance(1);
        previous = next;
        if relative_energy < options.bounce_tolerance {
            break;
        }
    }
    Ok(stats)
}
