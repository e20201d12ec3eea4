//! Local, deformable PRT (`bake --zonal N`; Sloan, Luna & Snyder 2005): each vertex's transfer
//! as `N` zonal-harmonic coefficients per channel about one axis — its shading normal, or the
//! axis that keeps most of the transfer's energy. A lobe circularly symmetric about an axis
//! needs no frame, so a mesh that bends or is skinned keeps its soft self-shadowing by turning
//! the axis with the surface, as it turns the normal, instead of being baked again. The math
//! is `sh::zonal`'s; this module fits a whole transfer and relights the result.

use std::fmt;
use std::time::Instant;

use glam::{DVec3, Quat, Vec3};
use rayon::prelude::*;

use crate::bake::Transfer;
use crate::error::{Error, Result};
use crate::light::{self, ShLight};
use crate::scene::prepare::DROPPED;
use crate::sh::{basis, coeff_count, eval_basis, zonal};
pub use crate::spec::{ZonalAxis, ZonalSpec};

/// Zonal transfer: per vertex, an axis and `channels x bands` zonal coefficients.
#[derive(Clone, Debug, PartialEq)]
pub struct ZonalTransfer {
    bands: u32,
    channels: u32,
    axis: ZonalAxis,
    /// Per vertex, in the rest pose: the shading normal, or the fitted axis.
    axes: Vec<Vec3>,
    /// `[vertex][channel][l]`.
    coeffs: Vec<f32>,
}

impl ZonalTransfer {
    /// Zonal transfer of `bands` bands about `axes` (unit vectors, one per vertex), with its
    /// coefficients `[vertex][channel][l]`. Refuses a shape that does not hold, values that
    /// are not finite and axes that are not unit vectors.
    pub fn new(
        (bands, channels, axis): (u32, u32, ZonalAxis),
        axes: Vec<Vec3>,
        coeffs: Vec<f32>,
    ) -> std::result::Result<ZonalTransfer, String> {
        crate::sh::check_bands(bands).map_err(|e| e.to_string())?;
        if !matches!(channels, 1 | 3) {
            return Err(format!("zonal transfer of {channels} channels (1 or 3)"));
        }
        let expected = axes.len().checked_mul((channels * bands) as usize);
        if expected != Some(coeffs.len()) {
            return Err(format!(
                "{} zonal coefficients for {} vertices of {channels} channels and {bands} bands",
                coeffs.len(),
                axes.len()
            ));
        }
        if coeffs.iter().any(|c| !c.is_finite()) {
            return Err("a zonal coefficient is not finite".into());
        }
        let unit = |a: &Vec3| a.is_finite() && (a.length() - 1.0).abs() < 1e-3;
        if !axes.iter().all(unit) {
            return Err("a zonal axis is not a unit vector".into());
        }
        Ok(ZonalTransfer {
            bands,
            channels,
            axis,
            axes,
            coeffs,
        })
    }

    /// The zonal fit of `transfer` as `spec` asks: per vertex, the axis (its normal in
    /// `normals`, or the best one) and the coefficients that fit each channel best about it.
    pub fn fit(transfer: &Transfer, normals: &[Vec3], spec: ZonalSpec) -> Result<ZonalTransfer> {
        if normals.len() != transfer.vertex_count() {
            return Err(Error::Options(format!(
                "zonal fit: {} normals for {} vertices",
                normals.len(),
                transfer.vertex_count()
            )));
        }
        let bands = spec.bands.min(transfer.bands());
        let channels = transfer.channels() as usize;
        let fitted: Vec<(Vec3, Vec<f32>)> = normals
            .par_iter()
            .enumerate()
            .with_min_len(256)
            .map(|(vertex, normal)| {
                let views: Vec<&[f32]> = (0..channels)
                    .map(|c| transfer.vertex_channel(vertex, c))
                    .collect();
                let normal = normal.as_dvec3().try_normalize().unwrap_or(DVec3::Z);
                let axis = match spec.axis {
                    ZonalAxis::Normal => normal,
                    ZonalAxis::Fitted => zonal::best_axis(&views, bands, normal),
                };
                let y = basis(bands, axis);
                let mut lobe = vec![0.0; bands as usize];
                let mut coeffs = Vec::with_capacity(channels * bands as usize);
                for view in views {
                    zonal::fit(view, &y, bands, &mut lobe);
                    coeffs.extend(lobe.iter().map(|&z| z as f32));
                }
                (axis.as_vec3(), coeffs)
            })
            .collect();
        let (axes, coeffs): (Vec<Vec3>, Vec<Vec<f32>>) = fitted.into_iter().unzip();
        let shape = (bands, transfer.channels(), spec.axis);
        ZonalTransfer::new(shape, axes, coeffs.concat()).map_err(Error::Geometry)
    }

    /// Adds `more`'s vertices after this one's (the next run of a streamed bake, fitted with
    /// the same spec).
    pub fn append(&mut self, more: ZonalTransfer) {
        assert_eq!(
            (self.bands, self.channels, self.axis),
            (more.bands, more.channels, more.axis),
            "runs of one zonal fit"
        );
        self.axes.extend(more.axes);
        self.coeffs.extend(more.coeffs);
    }

    pub fn bands(&self) -> u32 {
        self.bands
    }

    pub fn channels(&self) -> u32 {
        self.channels
    }

    pub fn axis(&self) -> ZonalAxis {
        self.axis
    }

    pub fn vertex_count(&self) -> usize {
        self.axes.len()
    }

    /// The zonal transfer of the vertices `map` names, in its order: a vertex that is
    /// [`DROPPED`] (in no baked triangle) gets zero coefficients about the z axis.
    pub fn select(&self, map: &[u32]) -> ZonalTransfer {
        let per_vertex = (self.channels * self.bands) as usize;
        let mut coeffs = Vec::with_capacity(map.len() * per_vertex);
        let mut axes = Vec::with_capacity(map.len());
        for &vertex in map {
            match vertex {
                DROPPED => {
                    coeffs.extend(std::iter::repeat_n(0.0, per_vertex));
                    axes.push(Vec3::Z);
                }
                v => {
                    let v = v as usize;
                    coeffs.extend_from_slice(&self.coeffs[v * per_vertex..(v + 1) * per_vertex]);
                    axes.push(self.axes[v]);
                }
            }
        }
        ZonalTransfer {
            axes,
            coeffs,
            ..*self
        }
    }

    /// Each vertex's axis in the rest pose.
    pub fn axes(&self) -> &[Vec3] {
        &self.axes
    }

    /// `[vertex][channel][l]`.
    pub fn coeffs(&self) -> &[f32] {
        &self.coeffs
    }

    /// The `bands` coefficients of `channel` at `vertex`.
    pub fn vertex_channel(&self, vertex: usize, channel: usize) -> &[f32] {
        let bands = self.bands as usize;
        let start = (vertex * self.channels as usize + channel) * bands;
        &self.coeffs[start..start + bands]
    }

    /// Exit radiance at every vertex under `light`, each lobe turned to its axis in `axes` (the
    /// rest pose's [`Self::axes`], or the axes turned with a deformed surface). A one-channel
    /// transfer applies to all three of the light's channels.
    pub fn relight(&self, axes: &[Vec3], light: &ShLight) -> Result<Vec<[f32; 3]>> {
        self.check_axes(axes)?;
        let used = coeff_count(self.bands).min(light.coeffs.len());
        let light: [Vec<f64>; 3] =
            std::array::from_fn(|c| light.coeffs[..used].iter().map(|l| l[c] as f64).collect());
        let channels = self.channels as usize;
        Ok(axes
            .par_iter()
            .enumerate()
            .with_min_len(1024)
            .map_init(
                || vec![0.0; coeff_count(self.bands)],
                |y, (vertex, axis)| {
                    eval_basis(self.bands, axis.as_dvec3().normalize(), y);
                    std::array::from_fn(|c| {
                        let lobe = self.vertex_channel(vertex, c.min(channels - 1));
                        zonal::relight(lobe, y, &light[c]) as f32
                    })
                },
            )
            .collect())
    }

    /// The SH transfer the zonal lobes make when turned to `axes`: what a bake of the
    /// deformed surface is compared with, and what any SH relighting code can use.
    pub fn lobes(&self, axes: &[Vec3]) -> Result<Transfer> {
        self.check_axes(axes)?;
        let coeffs: Vec<f32> = axes
            .par_iter()
            .enumerate()
            .flat_map_iter(|(vertex, axis)| {
                let y = basis(self.bands, axis.as_dvec3().normalize());
                (0..self.channels as usize).flat_map(move |c| {
                    let lobe = self.vertex_channel(vertex, c);
                    zonal::lobe_coeffs(lobe, &y).into_iter().map(|x| x as f32)
                })
            })
            .collect();
        Transfer::new(self.bands, self.channels, axes.len(), coeffs)
            .map_err(|e| Error::Geometry(e.to_string()))
    }

    fn check_axes(&self, axes: &[Vec3]) -> Result<()> {
        if axes.len() != self.axes.len() {
            return Err(Error::Options(format!(
                "zonal transfer of {} vertices turned to {} axes",
                self.axes.len(),
                axes.len()
            )));
        }
        Ok(())
    }
}

/// A bend of a mesh along its height (+Y) in the x-y plane, the deformation `render --bend`
/// and the viewer show zonal transfer under: height `y` above the mesh's lowest point turns by
/// `angle * y / height` about a line parallel to +Z, `height / angle` beside the mesh's middle
/// (towards +X), so the top turns by `angle`. Every point turns by its height's angle about +Z
/// (clockwise), and so do the normals and axes there. `assets/viewer/bend.glsl` (drawing) and
/// `bendPoint` in `viewer.js` (the bent bounds) mirror it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bend {
    /// The top's turn, in radians.
    pub angle: f32,
    /// The middle of the mesh in x at its lowest y.
    pub origin: Vec3,
    pub height: f32,
}

impl Bend {
    /// The bend of the mesh whose bounds are `(low, high)` by `degrees` at its top.
    pub fn of_bounds((low, high): (Vec3, Vec3), degrees: f32) -> Bend {
        Bend {
            angle: degrees.to_radians(),
            origin: Vec3::new(0.5 * (low.x + high.x), low.y, 0.0),
            height: high.y - low.y,
        }
    }

    /// Where `position` goes, and the turn of the surface there.
    pub fn place(&self, position: Vec3) -> (Vec3, Quat) {
        if self.angle == 0.0 || self.height <= 0.0 {
            return (position, Quat::IDENTITY);
        }
        let local = position - self.origin;
        let radius = self.height / self.angle;
        let angle = local.y / radius;
        let arm = radius - local.x;
        let bent = Vec3::new(radius - arm * angle.cos(), arm * angle.sin(), local.z);
        (self.origin + bent, Quat::from_rotation_z(-angle))
    }
}

/// What a zonal fit costs: the energy it leaves out and the relit error, against the SH
/// transfer it was fitted to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZonalFit {
    pub bands: u32,
    pub axis: ZonalAxis,
    /// The fraction of the SH transfer's energy (squared coefficients over vertices and
    /// channels) the zonal lobes leave out.
    pub energy_outside: f64,
    /// RMS relit error under the preview light over the RMS of the SH transfer's radiance.
    pub relit_error: f64,
    pub seconds: f64,
}

impl fmt::Display for ZonalFit {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(
            f,
            "zonal: {} bands about the {} axis in {:.2} s; {:.2}% of the transfer's energy \
             outside, relit error {:.2}% under the preview light",
            self.bands,
            self.axis.name(),
            self.seconds,
            100.0 * self.energy_outside,
            100.0 * self.relit_error
        )
    }
}

/// Fits `transfer` (at vertices with `normals`) as `spec` asks, and measures the fit.
pub fn fit_and_measure(
    transfer: &Transfer,
    normals: &[Vec3],
    spec: ZonalSpec,
) -> Result<(ZonalTransfer, ZonalFit)> {
    let mut tally = ZonalTally::new(spec);
    let zonal = tally.fit(transfer, normals)?;
    let fit = tally.measured().expect("one run fitted");
    Ok((zonal, fit))
}

/// A zonal fit a run of vertices at a time (a streamed bake's chunks), and its measure summed
/// over the runs in vertex order: each vertex's fit is its own, so the runs together are the
/// whole transfer's fit, and the measure the whole fit's.
pub struct ZonalTally {
    spec: ZonalSpec,
    /// The preview light at the transfer's bands, once a run is fitted.
    light: Option<ShLight>,
    bands: u32,
    /// Squared SH coefficients, and squared zonal ones: what the lobes keep, since each lobe
    /// turned to its axis has norm `sqrt(sum_l z_l^2)` (`sh::zonal`) and the residual is
    /// orthogonal to it.
    total: f64,
    kept: f64,
    relit: crate::compress::RelativeRms,
    seconds: f64,
}

impl ZonalTally {
    pub fn new(spec: ZonalSpec) -> ZonalTally {
        ZonalTally {
            spec,
            light: None,
            bands: 0,
            total: 0.0,
            kept: 0.0,
            relit: Default::default(),
            seconds: 0.0,
        }
    }

    /// The zonal fit of the next run of vertices (`transfer` at vertices with `normals`),
    /// measured into the tally.
    pub fn fit(&mut self, transfer: &Transfer, normals: &[Vec3]) -> Result<ZonalTransfer> {
        let started = Instant::now();
        let zonal = ZonalTransfer::fit(transfer, normals, self.spec)?;
        self.seconds += started.elapsed().as_secs_f64();
        if self.light.is_none() {
            self.light = Some(light::preview_light(transfer.bands())?);
        }
        let light = self.light.as_ref().expect("built above");
        self.bands = zonal.bands;
        self.total += transfer
            .coeffs()
            .iter()
            .map(|&c| c as f64 * c as f64)
            .sum::<f64>();
        self.kept += zonal
            .coeffs
            .iter()
            .map(|&z| z as f64 * z as f64)
            .sum::<f64>();
        let approximate = zonal.relight(&zonal.axes, light)?;
        let exact = crate::compress::radiance(transfer, light);
        self.relit.add_radiance(&exact, &approximate);
        Ok(zonal)
    }

    /// What the runs fitted so far cost, `None` before the first.
    pub fn measured(&self) -> Option<ZonalFit> {
        self.light.as_ref()?;
        Some(ZonalFit {
            bands: self.bands,
            axis: self.spec.axis,
            energy_outside: outside(self.total, self.kept),
            relit_error: self.relit.value(),
            seconds: self.seconds,
        })
    }
}

/// The fraction of `total` energy that keeping `kept` of it leaves out.
fn outside(total: f64, kept: f64) -> f64 {
    if total == 0.0 {
        0.0
    } else {
        ((total - kept) / total).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unshadowed transfer is circularly symmetric about the normal, so the zonal fit about
    /// the normal with as many bands keeps all of it, and relights as the SH transfer does.
    #[test]
    fn circularly_symmetric_transfer_is_fitted_exactly() {
        let bands = 5;
        let normals: Vec<Vec3> = (0..50)
            .map(|i| {
                let t = i as f32 * 0.37;
                Vec3::new(t.cos(), (0.3 * t).sin(), t.sin()).normalize()
            })
            .collect();
        let coeffs: Vec<f32> = normals
            .iter()
            .flat_map(|n| crate::sh::unshadowed_transfer(bands, n.as_dvec3()))
            .map(|x| x as f32)
            .collect();
        let transfer = Transfer::new(bands, 1, normals.len(), coeffs).unwrap();
        for axis in [ZonalAxis::Normal, ZonalAxis::Fitted] {
            let spec = ZonalSpec { bands, axis };
            let (zonal, fit) = fit_and_measure(&transfer, &normals, spec).unwrap();
            assert!(fit.energy_outside < 1e-6, "{fit}");
            assert!(fit.relit_error < 1e-5, "{fit}");
            for (a, n) in zonal.axes().iter().zip(&normals) {
                assert!(a.dot(*n) > 1.0 - 1e-5, "{a} against {n}");
            }
            let lobes = zonal.lobes(zonal.axes()).unwrap();
            for (a, b) in lobes.coeffs().iter().zip(transfer.coeffs()) {
                assert!((a - b).abs() < 1e-5);
            }
        }
    }

    /// Fitted in two runs, a transfer gives the whole fit's lobes and axes and its measure.
    #[test]
    fn a_fit_in_runs_is_the_whole_fit() {
        let (bands, vertices) = (4, 50);
        let coeffs = (0..vertices * 3 * 16)
            .map(|i| ((i * 7919) % 31) as f32 / 31.0 - 0.3)
            .collect();
        let transfer = Transfer::new(bands, 3, vertices, coeffs).unwrap();
        let normals: Vec<Vec3> = (0..vertices)
            .map(|i| Vec3::new((i as f32).cos(), 0.5, (i as f32).sin()).normalize())
            .collect();
        for axis in [ZonalAxis::Normal, ZonalAxis::Fitted] {
            let spec = ZonalSpec { bands: 3, axis };
            let (whole, measured) = fit_and_measure(&transfer, &normals, spec).unwrap();
            let mut tally = ZonalTally::new(spec);
            assert!(tally.measured().is_none());
            let runs = [0..20, 20..vertices];
            let mut coeffs = Vec::new();
            let mut axes = Vec::new();
            for run in runs {
                let part = crate::bake::Transfer::new(
                    bands,
                    3,
                    run.len(),
                    transfer.coeffs()[run.start * 48..run.end * 48].to_vec(),
                )
                .unwrap();
                let fitted = tally.fit(&part, &normals[run]).unwrap();
                coeffs.extend_from_slice(fitted.coeffs());
                axes.extend_from_slice(fitted.axes());
            }
            assert_eq!(coeffs, whole.coeffs());
            assert_eq!(axes, whole.axes());
            let in_runs = tally.measured().unwrap();
            assert!((in_runs.energy_outside - measured.energy_outside).abs() < 1e-12);
            assert!((in_runs.relit_error - measured.relit_error).abs() < 1e-12);
            assert!(measured.energy_outside > 0.0 && measured.relit_error > 0.0);
        }
    }

    /// About the normal, fewer zonal bands leave more out; the fitted axis never leaves out
    /// more than the normal does (the normal is where its search starts).
    #[test]
    fn fewer_bands_leave_more_out_and_the_fitted_axis_less() {
        let bands = 4;
        let transfer = Transfer::new(
            bands,
            3,
            2,
            (0..2 * 3 * 16)
                .map(|i| ((i * 7919) % 23) as f32 / 23.0 - 0.4)
                .collect(),
        )
        .unwrap();
        let normals = [Vec3::Y, Vec3::new(0.6, 0.0, 0.8)];
        let outside = |bands, axis| {
            let spec = ZonalSpec { bands, axis };
            fit_and_measure(&transfer, &normals, spec)
                .unwrap()
                .1
                .energy_outside
        };
        let mut last = 1.0;
        for zonal_bands in 1..=bands {
            let normal = outside(zonal_bands, ZonalAxis::Normal);
            let fitted = outside(zonal_bands, ZonalAxis::Fitted);
            assert!((0.0..=1.0).contains(&normal));
            assert!(normal < last, "{zonal_bands}: {normal} >= {last}");
            assert!(
                fitted <= normal + 1e-9,
                "{zonal_bands}: {fitted} > {normal}"
            );
            last = normal;
        }
    }

    #[test]
    fn a_broken_shape_is_refused() {
        let shape = (2, 1, ZonalAxis::Normal);
        assert!(ZonalTransfer::new(shape, vec![Vec3::Z], vec![0.0; 2]).is_ok());
        assert!(ZonalTransfer::new(shape, vec![Vec3::Z], vec![0.0; 3]).is_err());
        assert!(ZonalTransfer::new(shape, vec![Vec3::ONE], vec![0.0; 2]).is_err());
        assert!(ZonalTransfer::new(shape, vec![Vec3::Z], vec![f32::NAN, 0.0]).is_err());
        assert!(
            ZonalTransfer::new((2, 2, ZonalAxis::Normal), vec![Vec3::Z], vec![0.0; 4]).is_err()
        );
    }
}
