//! A least-squares bake's surface points and the fit that takes their values to the vertices.
//!
//! The fit's matrix depends on the points alone, so one [`Fitting`] serves the direct light and
//! every bounce. In bounded memory ([`PointChunks`]) the points are baked a run of whole
//! triangles at a time: each run's values are summed into the fit's right-hand side and let go,
//! and, where light bounces, its gather rows wait in a scratch file for each bounce. The fit
//! sums points in one canonical order, triangle by triangle, so runs of whole triangles give
//! the bytes of the whole bake.

use std::ops::Range;
use std::sync::OnceLock;

use glam::Vec3;

use super::adaptive::ReceiverErrors;
use super::spill::Spill;
use super::stream::SpilledRows;
use super::StagePosition;
use super::{check_given_count, direct_run, DirectSource};
use super::{tint_by_albedo, Backend, BakeOptions, Progress};
use super::{Mode, Planned};
use crate::error::Result;
use crate::receivers::fit::{solved_fraction, FitOptions, FitReport, FitSystem, RightHandSide};
use crate::receivers::SurfacePoint;
use crate::scene::Scene;
use crate::sh::coeff_count;

/// The fit of values at a bake's surface points to its vertices.
pub(super) struct Fitting<'a> {
    scene: &'a Scene,
    points: &'a [SurfacePoint],
    system: FitSystem,
    options: FitOptions,
    /// The direct light's right-hand side norms, once it is solved: the scale every bounce's
    /// solve is held to ([`FitSystem::solve_to_scale`]).
    direct_scale: OnceLock<Vec<f64>>,
    /// Where a solve says how far it has come: a solve of the direct light is a stage of its
    /// own, a bounce's a detail of the bounces' stage.
    progress: &'a dyn Progress,
}

/// A solve's progress: percent of the decades its residual must fall.
const SOLVE_STEPS: u64 = 100;

impl<'a> Fitting<'a> {
    pub(super) fn new(
        scene: &'a Scene,
        points: &'a [SurfacePoint],
        progress: &'a dyn Progress,
    ) -> Fitting<'a> {
        let options = FitOptions::default();
        Fitting {
            scene,
            points,
            system: FitSystem::of(scene, points, &options),
            options,
            direct_scale: OnceLock::new(),
            progress,
        }
    }

    /// Percent of the way to the tolerance at `relative_residual`.
    fn percent_solved(&self, relative_residual: f64) -> u64 {
        let fraction = solved_fraction(relative_residual, self.options.tolerance);
        (fraction * SOLVE_STEPS as f64) as u64
    }

    /// Solves `rhs` (held to `scale`) as a stage of its own, `name`, of [`SOLVE_STEPS`].
    fn solve_as_stage(
        &self,
        name: &str,
        rhs: RightHandSide,
        scale: Option<&[f64]>,
    ) -> (Vec<f32>, FitReport) {
        self.progress.stage(name, SOLVE_STEPS);
        let mut position = StagePosition::new(self.progress);
        let solved = self
            .system
            .solve_to_scale(rhs, &self.options, scale, &mut |residual| {
                position.move_to(self.percent_solved(residual))
            });
        position.move_to(SOLVE_STEPS);
        solved
    }

    /// The right-hand side of `values` (`columns` a point) at every point.
    pub(super) fn right_hand_side(&self, values: &[f32], columns: usize) -> Result<RightHandSide> {
        let mut rhs = self.system.right_hand_side(columns);
        self.add(&mut rhs, 0..self.points.len(), values)?;
        Ok(rhs)
    }

    /// Adds `values` at the points `range` to `rhs`.
    fn add(&self, rhs: &mut RightHandSide, range: Range<usize>, values: &[f32]) -> Result<()> {
        let points = &self.points[range];
        self.system.add(rhs, self.scene, points, values)
    }

    /// The vertex values whose interpolation best fits the values summed in `rhs`.
    pub(super) fn solve(&self, rhs: RightHandSide) -> (Vec<f32>, FitReport) {
        self.solve_as_stage("fit", rhs, None)
    }

    /// [`solve`](Self::solve) for the direct light's RGB values, keeping their scale for the
    /// bounces'.
    fn solve_direct(&self, rhs: RightHandSide) -> (Vec<f32>, FitReport) {
        let scale = rhs.column_norms();
        let solved = self.solve(rhs);
        self.direct_scale
            .set(scale)
            .expect("the direct light is solved once");
        solved
    }

    /// [`solve`](Self::solve) for a bounce's RGB values, held to the direct light's scale.
    fn solve_bounce(&self, rhs: RightHandSide) -> (Vec<f32>, FitReport) {
        let scale = self.direct_scale.get().map(Vec::as_slice);
        debug_assert!(scale.is_some(), "bounces follow the direct light");
        let mut shown = None;
        let solved = self
            .system
            .solve_to_scale(rhs, &self.options, scale, &mut |residual| {
                let percent = self.percent_solved(residual);
                if shown.is_none_or(|shown| percent > shown) {
                    self.progress.detail(&format!("(fitting, {percent}%)"));
                    shown = Some(percent);
                }
            });
        self.progress.detail("");
        solved
    }

    /// The vertex values that best fit `values` at every point, the values let go before the
    /// solve (they are every point's transfer, and the solve holds five vectors of every
    /// vertex's beside them otherwise): the direct light's RGB values, or a `bounce`'s.
    pub(super) fn fit(
        &self,
        values: Vec<f32>,
        columns: usize,
        light: Light,
    ) -> Result<(Vec<f32>, FitReport)> {
        let rhs = self.right_hand_side(&values, columns)?;
        drop(values);
        Ok(match light {
            Light::Direct => self.solve_direct(rhs),
            Light::Bounce => self.solve_bounce(rhs),
        })
    }
}

/// Which light a fit's RGB values are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Light {
    Direct,
    Bounce,
}

/// A least-squares bake's direct pass at its points, a run at a time ([module docs](self)):
/// what the fit needs of it, and what the report says.
pub(super) struct PointChunks {
    runs: Vec<Range<usize>>,
    /// The direct light's RGB values at the points, summed; taken by its solve.
    direct: Option<RightHandSide>,
    /// Lean direct transfer: the albedo-free values, summed.
    albedo_free: Option<RightHandSide>,
    /// Where light bounces: each run's gather rows in the scratch file.
    rows: Option<(Spill, Vec<SpilledRows>)>,
    pub(super) rays_cast: u64,
    pub(super) adaptive: Option<ReceiverErrors>,
    pub(super) gather_entries: usize,
}

impl PointChunks {
    /// Bakes the direct pass of `planned`'s points about `chunk` at a time, or reads it so from
    /// `source` where it is given (a merge's parts), (`albedo` each point's, white in a
    /// translucent medium) and sums their values for `fitting`.
    pub(super) fn bake(
        planned: &Planned,
        (fitting, albedo): (&Fitting, &[Vec3]),
        (chunk, source): (usize, &DirectSource),
        options: &BakeOptions,
        backend: &dyn Backend,
        progress: &dyn Progress,
    ) -> Result<PointChunks> {
        let bands = options.bands;
        let coeffs = coeff_count(bands);
        let runs = triangle_runs(&planned.points, chunk);
        let mut direct = fitting.system.right_hand_side(3 * coeffs);
        let mut albedo_free = options
            .albedo_free()
            .then(|| fitting.system.right_hand_side(coeffs));
        let mut rows = match options.mode {
            Mode::Interreflected => Some((Spill::new()?, Vec::with_capacity(runs.len()))),
            _ => None,
        };
        let (mut rays_cast, mut gather_entries) = (0, 0);
        let mut adaptive: Option<ReceiverErrors> = None;
        progress.stage("transfer", planned.points.len() as u64);
        if let Some(given) = source.given() {
            check_given_count(given.receivers(), planned.points.len())?;
        }
        for run in &runs {
            let at = (&planned.inputs, run.clone());
            let pass = direct_run(source.given(), at, options, backend, progress)?;
            let tinted = tint_by_albedo(&pass.scalar, &albedo[run.clone()], bands);
            fitting.add(&mut direct, run.clone(), tinted.coeffs())?;
            if let Some(rhs) = &mut albedo_free {
                fitting.add(rhs, run.clone(), &pass.scalar)?;
            }
            if let (Some((spill, spilled)), Some(matrix)) = (&mut rows, &pass.matrix) {
                spilled.push(SpilledRows::put(spill, matrix)?);
                gather_entries += matrix.columns.len();
            }
            rays_cast += pass.rays_cast;
            if let Some(errors) = pass.adaptive {
                let all = adaptive.get_or_insert_with(ReceiverErrors::default);
                all.samples.extend(errors.samples);
                all.errors.extend(errors.errors);
            }
        }
        Ok(PointChunks {
            runs,
            direct: Some(direct),
            albedo_free,
            rows,
            rays_cast,
            adaptive,
            gather_entries,
        })
    }

    /// The direct light's RGB vertex values, fitted (once).
    pub(super) fn direct_at_vertices(&mut self, fitting: &Fitting) -> (Vec<f32>, FitReport) {
        let rhs = self.direct.take().expect("the direct light is fitted once");
        fitting.solve_direct(rhs)
    }

    /// Lean direct transfer's albedo-free vertex values, fitted (once).
    pub(super) fn albedo_free_at_vertices(&mut self, fitting: &Fitting) -> Vec<f32> {
        let rhs = self
            .albedo_free
            .take()
            .expect("summed for lean direct transfer");
        fitting.solve(rhs).0
    }

    /// Whether the points gather bounced light.
    pub(super) fn gathers(&self) -> bool {
        self.rows.is_some()
    }

    /// The next bounce's vertex values: the `previous` bounce's RGB vertex values gathered at
    /// the points a run of rows at a time (`albedo` each point's), fitted.
    pub(super) fn bounce(
        &mut self,
        (fitting, albedo): (&Fitting, &[Vec3]),
        previous: &[f32],
        bands: u32,
        backend: &dyn Backend,
    ) -> Result<(Vec<f32>, FitReport)> {
        let (spill, spilled) = self.rows.as_mut().expect("only bounced light is gathered");
        let mut rhs = fitting.system.right_hand_side(3 * coeff_count(bands));
        for (run, rows) in self.runs.iter().zip(spilled.iter()) {
            let matrix = rows.read(spill)?;
            let gathered = backend
                .gatherer(&matrix, &albedo[run.clone()], bands)?
                .gather(previous)?;
            fitting.add(&mut rhs, run.clone(), &gathered)?;
        }
        Ok(fitting.solve_bounce(rhs))
    }
}

/// The points `0..points.len()` in runs of about `chunk`, each ending where a triangle's
/// points end (the points are in the order of their triangles, as spread).
fn triangle_runs(points: &[SurfacePoint], chunk: usize) -> Vec<Range<usize>> {
    let mut runs = Vec::new();
    let mut start = 0;
    while start < points.len() {
        let mut end = (start + chunk.max(1)).min(points.len());
        while end < points.len() && points[end].triangle == points[end - 1].triangle {
            end += 1;
        }
        runs.push(start..end);
        start = end;
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on(triangles: &[u32]) -> Vec<SurfacePoint> {
        triangles
            .iter()
            .map(|&triangle| SurfacePoint {
                triangle,
                barycentrics: [1.0 / 3.0; 3],
            })
            .collect()
    }

    #[test]
    fn runs_cover_every_point_once_and_never_split_a_triangle() {
        let points = on(&[0, 0, 0, 1, 2, 2, 2, 2, 3, 4, 4]);
        for chunk in [0, 1, 2, 3, 5, 100] {
            let runs = triangle_runs(&points, chunk);
            let mut next = 0;
            for run in &runs {
                assert_eq!(run.start, next, "chunk {chunk}: {runs:?}");
                assert!(!run.is_empty());
                next = run.end;
                if run.end < points.len() {
                    let (last, first_after) = (&points[run.end - 1], &points[run.end]);
                    assert_ne!(last.triangle, first_after.triangle, "chunk {chunk}");
                }
                assert!(run.len() >= chunk.clamp(1, points.len() - run.start));
            }
            assert_eq!(next, points.len());
        }
        assert!(triangle_runs(&[], 4).is_empty());
    }
}
