//! Subsurface scattering (`bake --subsurface`; Jensen, Marschner, Levoy & Hanrahan 2001,
//! "A Practical Model for Subsurface Light Transport"; Direct3D's `ComputeSS`): light that
//! enters a translucent surface leaves it elsewhere. The dipole diffusion approximation gives
//! the exitance at distance `r` from where a unit flux entered, `R_d(r)`; the exit radiance at
//! `x` is `(1/pi) integral R_d(|x - x_i|) E(x_i) dA(x_i)` over the surface, `E` the irradiance.
//! Irradiance is linear in the light, so the transfer is the same integral of the shadowed
//! irradiance transfer `t_E(x_i) = integral V max(0, n.w) y dw`, which replaces the diffuse
//! reflection (the material's colour is the medium's, from its absorption and scattering).
//!
//! The integral runs over surface points: the vertices and, on triangles larger than a
//! quarter of the diffusion length, a lattice of points within them (their irradiance
//! transfer interpolated from the triangle's corners). Each point stands for the area around
//! it; its weight is that area times `R_d` averaged over the ring of the point's radius about
//! its distance, from the closed form of `R_d`'s integral, so a receiver's own vertex gets the
//! exitance of its own disc however small the diffusion length. Points farther than the
//! `reach` where the infinite plane's remaining exitance falls below [`TAIL`] of the total are
//! left out; a receiver's weights never sum past the plane's total diffuse reflectance, so no
//! surface gives back more than it receives.
//!
//! The integral is a sparse matrix from vertices to vertices per channel, applied through the
//! backend's gatherer (so the CPU and the GPU run the same operation) to the direct light and,
//! interreflected, to each bounce's light as it arrives: as in Direct3D's sequence, the
//! bounces gather the scattered light, and what they bring scatters in turn.

use std::collections::HashMap;
use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::backend::Backend;
use super::bounce::GatherMatrix;
use crate::error::{Error, Result};
use crate::scene::joined::Joined;
use crate::scene::Scene;

/// The fraction of the total diffuse reflectance the cut-off at the reach may leave out.
pub const TAIL: f64 = 1e-2;

/// The most matrix entries (per channel) a subsurface bake builds.
pub const MAX_ENTRIES: usize = 1 << 25;

/// The most lattice steps along a triangle's edge: past it, the diffusion length is so much
/// shorter than the triangle that each point's own disc holds all it gives its neighbours.
pub const MAX_STEPS: usize = 8;

/// The most lattice points the triangles get besides the vertices.
pub const MAX_POINTS: usize = 1 << 22;

/// A homogeneous translucent medium: its index of refraction relative to the outside, and its
/// absorption and reduced scattering coefficients per colour channel, per millimetre;
/// `mm_per_unit` says how many millimetres a scene unit is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubsurfaceMaterial {
    pub ior: f32,
    pub absorption: [f32; 3],
    pub reduced_scattering: [f32; 3],
    pub mm_per_unit: f32,
}

/// Measured media (Jensen et al. 2001, figure 5: `sigma_s'` and `sigma_a` in mm^-1, R G B),
/// with the index of refraction the paper uses for them (1.3; 1.5 for marble).
pub const PRESETS: [(&str, SubsurfaceMaterial); 7] = [
    (
        "apple",
        preset(1.3, [0.0030, 0.0034, 0.046], [2.29, 2.39, 1.97]),
    ),
    (
        "ketchup",
        preset(1.3, [0.061, 0.97, 1.45], [0.18, 0.07, 0.03]),
    ),
    (
        "marble",
        preset(1.5, [0.0021, 0.0041, 0.0071], [2.19, 2.62, 3.00]),
    ),
    (
        "skim-milk",
        preset(1.3, [0.0014, 0.0025, 0.0142], [0.70, 1.22, 1.90]),
    ),
    (
        "skin1",
        preset(1.3, [0.032, 0.17, 0.48], [0.74, 0.88, 1.01]),
    ),
    (
        "skin2",
        preset(1.3, [0.013, 0.070, 0.145], [1.09, 1.59, 1.79]),
    ),
    (
        "whole-milk",
        preset(1.3, [0.0011, 0.0024, 0.014], [2.55, 3.21, 3.77]),
    ),
];

const fn preset(
    ior: f32,
    absorption: [f32; 3],
    reduced_scattering: [f32; 3],
) -> SubsurfaceMaterial {
    SubsurfaceMaterial {
        ior,
        absorption,
        reduced_scattering,
        mm_per_unit: 1000.0,
    }
}

impl SubsurfaceMaterial {
    /// The preset named `name`.
    pub fn preset(name: &str) -> Option<SubsurfaceMaterial> {
        PRESETS.iter().find(|(n, _)| *n == name).map(|(_, m)| *m)
    }

    /// Refuses a medium the dipole does not describe: an index of refraction outside
    /// [1, 3], negative or non-finite coefficients, a channel with neither absorption nor
    /// scattering, a scale that is not a positive length.
    pub fn validate(&self) -> Result<()> {
        let refuse = |why: String| Err(Error::Options(format!("--subsurface: {why}")));
        if !(1.0..=3.0).contains(&self.ior) {
            return refuse(format!("index of refraction {} (1 to 3)", self.ior));
        }
        let coefficients = self.absorption.iter().chain(&self.reduced_scattering);
        if !coefficients.into_iter().all(|c| c.is_finite() && *c >= 0.0) {
            return refuse("absorption and scattering must be finite and not negative".into());
        }
        if (0..3).any(|c| self.absorption[c] + self.reduced_scattering[c] <= 0.0) {
            return refuse("every channel needs absorption or scattering (or both)".into());
        }
        if !(self.mm_per_unit.is_finite() && self.mm_per_unit > 0.0) {
            return refuse(format!(
                "{} mm per scene unit: the scale must be a positive length",
                self.mm_per_unit
            ));
        }
        Ok(())
    }

    /// The dipole of channel `c`, its lengths in scene units.
    pub fn dipole(&self, c: usize) -> Dipole {
        let per_unit = self.mm_per_unit as f64;
        Dipole::new(
            self.ior as f64,
            self.absorption[c] as f64 * per_unit,
            self.reduced_scattering[c] as f64 * per_unit,
        )
    }
}

/// The dipole diffusion profile of one channel (Jensen et al. 2001, eq. 4 and 5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dipole {
    /// The reduced albedo `sigma_s' / sigma_t'`.
    pub albedo: f64,
    /// The effective transport coefficient `sqrt(3 sigma_a sigma_t')`.
    pub sigma_tr: f64,
    /// Depths of the real and the virtual source.
    pub z_real: f64,
    pub z_virtual: f64,
}

impl Dipole {
    pub fn new(ior: f64, absorption: f64, reduced_scattering: f64) -> Dipole {
        let sigma_t = absorption + reduced_scattering;
        // Diffuse Fresnel reflectance (Egan and Hilgeman's fit) and the boundary term A.
        let fdr = -1.440 / (ior * ior) + 0.710 / ior + 0.668 + 0.0636 * ior;
        let boundary = (1.0 + fdr) / (1.0 - fdr);
        let z_real = 1.0 / sigma_t;
        Dipole {
            albedo: reduced_scattering / sigma_t,
            sigma_tr: (3.0 * absorption * sigma_t).sqrt(),
            z_real,
            z_virtual: z_real * (1.0 + 4.0 * boundary / 3.0),
        }
    }

    /// `R_d(r)`: exitance at distance `r` per unit incident flux.
    pub fn profile(&self, r: f64) -> f64 {
        let term = |z: f64| {
            let d = (r * r + z * z).sqrt();
            z * (1.0 + self.sigma_tr * d) * (-self.sigma_tr * d).exp() / (d * d * d)
        };
        self.albedo / (4.0 * PI) * (term(self.z_real) + term(self.z_virtual))
    }

    /// `integral_0^r R_d(s) 2 pi s ds`, in closed form: with `d = sqrt(s^2 + z^2)`,
    /// `z (1 + sigma d) e^(-sigma d) / d^3 s ds = -z d(e^(-sigma d) / d)`.
    pub fn within(&self, r: f64) -> f64 {
        let term = |z: f64| {
            let d = (r * r + z * z).sqrt();
            (-self.sigma_tr * z).exp() - z * (-self.sigma_tr * d).exp() / d
        };
        self.albedo / 2.0 * (term(self.z_real) + term(self.z_virtual))
    }

    /// The total diffuse reflectance, `within(infinity)`: at most 1, and 1 for a medium that
    /// does not absorb.
    pub fn total(&self) -> f64 {
        let term = |z: f64| (-self.sigma_tr * z).exp();
        self.albedo / 2.0 * (term(self.z_real) + term(self.z_virtual))
    }

    /// The smallest distance beyond which the plane's exitance is at most `tail` of the total
    /// (bisection on [`Self::within`], to a part in a thousand).
    pub fn reach(&self, tail: f64) -> f64 {
        let total = self.total();
        let enough = |r: f64| total - self.within(r) <= tail * total;
        let mut high = self.z_virtual.max(1e-30);
        while !enough(high) {
            high *= 2.0;
        }
        let mut low = 0.0;
        while high - low > 1e-3 * high {
            let mid = 0.5 * (low + high);
            if enough(mid) {
                high = mid;
            } else {
                low = mid;
            }
        }
        high
    }

    /// `R_d` averaged over the ring from `r - radius` to `r + radius` (the disc of `radius`
    /// where `r <= radius`): what a point at distance `r` standing for a disc of that radius
    /// receives per unit area.
    pub fn ring_mean(&self, r: f64, radius: f64) -> f64 {
        let (inner, outer) = ((r - radius).max(0.0), r + radius);
        let area = PI * (outer * outer - inner * inner);
        if area <= 0.0 {
            return self.profile(r);
        }
        (self.within(outer) - self.within(inner)) / area
    }
}

/// A surface point the integral runs over: where it is, the area it stands for, and how its
/// irradiance transfer comes from the vertices (up to three, by barycentric weight).
#[derive(Clone, Copy, Debug)]
struct SurfaceSample {
    position: DVec3,
    area: f64,
    corners: [u32; 3],
    weights: [f64; 3],
    /// The piece of the surface it lies on ([`pieces`]): light that enters one piece leaves
    /// by that piece alone.
    piece: u32,
}

/// Each vertex's piece of `scene`: vertices joined by a triangle, or at the same position,
/// are one piece (the vertices a mesh splits along a crease stay one object; two objects that
/// only touch, or come close, are two).
fn pieces(scene: &Scene) -> Vec<u32> {
    let mut sets = Joined::new(scene.vertex_count());
    for t in &scene.triangles {
        sets.join(t[0], t[1]);
        sets.join(t[0], t[2]);
    }
    let mut first_at: HashMap<[u32; 3], u32> = HashMap::new();
    for (v, p) in scene.positions.iter().enumerate() {
        let first = *first_at
            .entry(p.to_array().map(f32::to_bits))
            .or_insert(v as u32);
        sets.join(first, v as u32);
    }
    (0..scene.vertex_count() as u32)
        .map(|v| sets.root(v))
        .collect()
}

/// The points of `scene` about `spacing` apart: every vertex, and on each triangle with an edge
/// longer than `spacing`, a lattice of up to [`MAX_STEPS`] steps per edge. Each lattice point
/// stands for a third of the area of the lattice's sub-triangles it is a corner of; the
/// corners' shares go to the vertices.
fn surface_samples(scene: &Scene, spacing: f64) -> Result<Vec<SurfaceSample>> {
    let position = |v: u32| scene.positions[v as usize].as_dvec3();
    let piece = pieces(scene);
    let mut vertex_area = vec![0.0f64; scene.vertex_count()];
    let mut lattice = Vec::new();
    for &corners in &scene.triangles {
        let [a, b, c] = corners.map(position);
        let area = 0.5 * (b - a).cross(c - a).length();
        let longest = [(b - a), (c - b), (a - c)]
            .map(|e| e.length())
            .into_iter()
            .fold(0.0, f64::max);
        let steps = ((longest / spacing).ceil() as usize).clamp(1, MAX_STEPS);
        let share = area / (3 * steps * steps) as f64;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let touching = lattice_touching(i, j, steps);
                let weights = [
                    (steps - i - j) as f64 / steps as f64,
                    i as f64 / steps as f64,
                    j as f64 / steps as f64,
                ];
                match weights.iter().position(|&w| w == 1.0) {
                    Some(corner) => vertex_area[corners[corner] as usize] += touching * share,
                    None => lattice.push(SurfaceSample {
                        position: weights[0] * a + weights[1] * b + weights[2] * c,
                        area: touching * share,
                        corners,
                        weights,
                        piece: piece[corners[0] as usize],
                    }),
                }
            }
        }
        if lattice.len() > MAX_POINTS {
            return Err(Error::Options(format!(
                "--subsurface: the surface needs more than {MAX_POINTS} points at a spacing of \
                 {spacing:.3e} scene units (a quarter of the diffusion length; a smaller \
                 --sss-mm-per-unit makes the object smaller and the spacing wider)"
            )));
        }
    }
    let vertices = (0..scene.vertex_count()).map(|v| SurfaceSample {
        position: position(v as u32),
        area: vertex_area[v],
        corners: [v as u32; 3],
        weights: [1.0, 0.0, 0.0],
        piece: piece[v],
    });
    Ok(vertices.chain(lattice).collect())
}

/// How many of the `steps^2` sub-triangles of a triangle's lattice have point `(i, j)`
/// (`i + j <= steps`) as a corner: the upward ones `U(a, b)` = (a,b), (a+1,b), (a,b+1) for
/// `a + b < steps`, the downward ones `D(a, b)` = (a+1,b), (a,b+1), (a+1,b+1) for
/// `a + b < steps - 1`. Six inside, three on an edge, one at a corner.
fn lattice_touching(i: usize, j: usize, steps: usize) -> f64 {
    let inside = i + j < steps;
    let count = inside as usize // U(i, j)
        + (i >= 1) as usize // U(i - 1, j)
        + (j >= 1) as usize // U(i, j - 1)
        + (i >= 1 && inside) as usize // D(i - 1, j)
        + (j >= 1 && inside) as usize // D(i, j - 1)
        + (i >= 1 && j >= 1) as usize; // D(i - 1, j - 1)
    count as f64
}

/// The subsurface matrices of `scene` for `material`, one per channel: row `p`, column `j`,
/// the weight of what vertex `j` would send back as a white diffuse surface in what vertex
/// `p` sends back through the medium ([`Scatter::apply`]). Also the reach it cut at.
pub fn subsurface_matrices(
    scene: &Scene,
    material: &SubsurfaceMaterial,
) -> Result<([GatherMatrix; 3], f64)> {
    material.validate()?;
    let dipoles: [Dipole; 3] = std::array::from_fn(|c| material.dipole(c));
    let reach = dipoles.iter().map(|d| d.reach(TAIL)).fold(0.0, f64::max);
    let diffusion_length = dipoles
        .iter()
        .map(|d| {
            if d.sigma_tr > 0.0 {
                1.0 / d.sigma_tr
            } else {
                d.z_virtual
            }
        })
        .fold(f64::INFINITY, f64::min)
        .min(reach);
    let samples = surface_samples(scene, 0.25 * diffusion_length)?;
    let grid = PointGrid::new(&samples, reach);
    // Counted as the rows are made, so a matrix too big to hold stops being built.
    let entries = std::sync::atomic::AtomicUsize::new(0);
    let rows: Vec<Vec<(u32, [f32; 3])>> = scene
        .positions
        .par_iter()
        .zip(&samples[..scene.vertex_count()])
        .map(|(receiver, own)| {
            if entries.load(std::sync::atomic::Ordering::Relaxed) > MAX_ENTRIES {
                return Vec::new();
            }
            let receiver = (receiver.as_dvec3(), own.piece);
            let row = subsurface_row(receiver, &samples, &grid, (&dipoles, reach));
            entries.fetch_add(row.len(), std::sync::atomic::Ordering::Relaxed);
            row
        })
        .collect();
    if entries.into_inner() > MAX_ENTRIES {
        return Err(Error::Options(format!(
            "--subsurface: more than {MAX_ENTRIES} matrix entries: the light travels \
             {reach:.3e} scene units under the surface, through most of the mesh (a larger \
             --sss-mm-per-unit makes the object bigger and the way shorter)"
        )));
    }
    let matrices = std::array::from_fn(|c| {
        GatherMatrix::from_rows(
            rows.iter()
                .map(|row| row.iter().map(|&(j, w)| (j, w[c])).collect())
                .collect(),
        )
    });
    Ok((matrices, reach))
}

/// One receiver's row: every sample of its piece within `reach`, its ring-averaged profile
/// times its area, spread over its corners; the row's sum per channel held to the plane's
/// total.
fn subsurface_row(
    (receiver, piece): (DVec3, u32),
    samples: &[SurfaceSample],
    grid: &PointGrid,
    (dipoles, reach): (&[Dipole; 3], f64),
) -> Vec<(u32, [f32; 3])> {
    let mut row: HashMap<u32, [f64; 3]> = HashMap::new();
    let mut sums = [0.0f64; 3];
    grid.within(receiver, reach, |s| {
        let sample = &samples[s];
        let r = sample.position.distance(receiver);
        if r > reach || sample.area <= 0.0 || sample.piece != piece {
            return;
        }
        let radius = (sample.area / PI).sqrt();
        let weight: [f64; 3] =
            std::array::from_fn(|c| sample.area * dipoles[c].ring_mean(r, radius));
        for c in 0..3 {
            sums[c] += weight[c];
        }
        for (&corner, &share) in sample.corners.iter().zip(&sample.weights) {
            if share > 0.0 {
                let entry = row.entry(corner).or_insert([0.0; 3]);
                for c in 0..3 {
                    entry[c] += share * weight[c];
                }
            }
        }
    });
    let scale: [f32; 3] = std::array::from_fn(|c| {
        let total = dipoles[c].total();
        (if sums[c] > total {
            total / sums[c]
        } else {
            1.0
        }) as f32
    });
    let mut row: Vec<(u32, [f32; 3])> = row
        .into_iter()
        .map(|(j, w)| (j, std::array::from_fn(|c| w[c] as f32 * scale[c])))
        .collect();
    row.sort_unstable_by_key(|&(j, _)| j);
    row
}

/// A uniform grid of cells `cell` wide over the samples, for the samples near a point.
struct PointGrid {
    origin: DVec3,
    cell: f64,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl PointGrid {
    fn new(samples: &[SurfaceSample], cell: f64) -> PointGrid {
        let origin = samples
            .iter()
            .fold(DVec3::splat(f64::INFINITY), |o, s| o.min(s.position));
        let mut grid = PointGrid {
            origin,
            cell: cell.max(1e-30),
            cells: HashMap::new(),
        };
        for (i, s) in samples.iter().enumerate() {
            grid.cells
                .entry(grid.key(s.position))
                .or_default()
                .push(i as u32);
        }
        grid
    }

    fn key(&self, p: DVec3) -> [i64; 3] {
        ((p - self.origin) / self.cell)
            .floor()
            .as_i64vec3()
            .to_array()
    }

    /// Calls `visit` with every sample in the cells within `radius` of `p`.
    fn within(&self, p: DVec3, radius: f64, mut visit: impl FnMut(usize)) {
        let low = self.key(p - DVec3::splat(radius));
        let high = self.key(p + DVec3::splat(radius));
        for x in low[0]..=high[0] {
            for y in low[1]..=high[1] {
                for z in low[2]..=high[2] {
                    if let Some(cell) = self.cells.get(&[x, y, z]) {
                        cell.iter().for_each(|&s| visit(s as usize));
                    }
                }
            }
        }
    }
}

/// What a subsurface pass did: how far it followed the light, the matrix entries per
/// channel, its seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubsurfaceReport {
    pub reach: f64,
    pub entries: usize,
    pub seconds: f64,
}

/// The subsurface matrices of a scene in a medium, built once: what replaces the diffuse
/// reflection of the direct light and of each bounce.
pub struct Scatter {
    matrices: [GatherMatrix; 3],
    /// Channel `c`'s selector: `e_c` at every vertex (the gather's per-row albedo).
    only: [Vec<Vec3>; 3],
    pub report: SubsurfaceReport,
}

impl Scatter {
    pub fn new(scene: &Scene, material: &SubsurfaceMaterial) -> Result<Scatter> {
        let started = std::time::Instant::now();
        let (matrices, reach) = subsurface_matrices(scene, material)?;
        let only = std::array::from_fn(|c| {
            let mut unit = Vec3::ZERO;
            unit[c] = 1.0;
            vec![unit; scene.vertex_count()]
        });
        let report = SubsurfaceReport {
            reach,
            entries: matrices[0].columns.len(),
            seconds: started.elapsed().as_secs_f64(),
        };
        Ok(Scatter {
            matrices,
            only,
            report,
        })
    }

    /// The light a surface sends back from the albedo-free transfer `values` (RGB,
    /// `[vertex][3][coeffs]`, what a white diffuse surface would send back), scattered under
    /// it: channel by channel `W_c values_c`. For a white diffuse surface, `values` is
    /// `1/pi` times the irradiance transfer, and `W_c` holds the profile's exitance, so this
    /// is `(1/pi) integral R_d E dA` per unit light.
    pub fn apply(&self, values: &[f32], bands: u32, backend: &dyn Backend) -> Result<Vec<f32>> {
        let mut sum = vec![0.0f32; values.len()];
        for (matrix, only) in self.matrices.iter().zip(&self.only) {
            let gathered = backend.gatherer(matrix, only, bands)?.gather(values)?;
            sum.iter_mut().zip(gathered).for_each(|(s, g)| *s += g);
        }
        Ok(sum)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn media() -> [Dipole; 3] {
        [
            Dipole::new(1.3, 0.032, 0.74),
            Dipole::new(1.5, 0.0, 2.0),
            Dipole::new(1.0, 1.0, 0.1),
        ]
    }

    /// The closed form of the profile's integral is the integral (against a midpoint rule),
    /// its limit is Jensen's total diffuse reflectance, which is 1 without absorption, and the
    /// reach leaves out what it says.
    #[test]
    fn the_profiles_integral_is_its_closed_form() {
        for dipole in media() {
            let r_max = 20.0 * dipole.z_virtual;
            let steps = 200_000;
            let dr = r_max / steps as f64;
            let numeric: f64 = (0..steps)
                .map(|i| {
                    let r = (i as f64 + 0.5) * dr;
                    dipole.profile(r) * 2.0 * PI * r * dr
                })
                .sum();
            let closed = dipole.within(r_max);
            assert!(
                (numeric - closed).abs() < 1e-6 * closed.max(1e-3),
                "{numeric} against {closed}"
            );
            let one_minus = (3.0 * (1.0 - dipole.albedo)).sqrt();
            let boundary = (dipole.z_virtual / dipole.z_real - 1.0) * 3.0 / 4.0;
            let jensen = dipole.albedo / 2.0
                * (1.0 + (-4.0 / 3.0 * boundary * one_minus).exp())
                * (-one_minus).exp();
            assert!(
                (dipole.total() - jensen).abs() < 1e-12,
                "{} against {jensen}",
                dipole.total()
            );
            assert!(dipole.total() <= 1.0);
            let reach = dipole.reach(TAIL);
            let left = dipole.total() - dipole.within(reach);
            assert!(left <= TAIL * dipole.total() * (1.0 + 1e-9), "{left}");
            assert!(dipole.total() - dipole.within(0.99 * reach) > 0.9 * TAIL * dipole.total());
        }
        assert!(
            (media()[1].total() - 1.0).abs() < 1e-12,
            "no absorption returns everything"
        );
    }

    /// A ring's mean times its area is the profile's integral over it; the disc about a point
    /// holds what is within its radius.
    #[test]
    fn ring_means_integrate_the_profile() {
        let dipole = media()[0];
        for (r, radius) in [(0.0f64, 0.5f64), (0.2, 0.5), (3.0, 0.25)] {
            let (inner, outer) = ((r - radius).max(0.0), r + radius);
            let area = PI * (outer * outer - inner * inner);
            let mass = dipole.ring_mean(r, radius) * area;
            assert!((mass - (dipole.within(outer) - dipole.within(inner))).abs() < 1e-12);
        }
    }

    /// Every lattice has `3 steps^2` corner incidences: the sub-triangles' areas are shared
    /// out whole, and so a triangle's samples (and a mesh's) stand for all of its area.
    #[test]
    fn the_samples_stand_for_the_whole_area() {
        for steps in 1..=MAX_STEPS {
            let mut count = 0.0;
            for i in 0..=steps {
                for j in 0..=steps - i {
                    count += lattice_touching(i, j, steps);
                }
            }
            assert_eq!(count, (3 * steps * steps) as f64, "{steps} steps");
        }
        let scene = crate::scene::builtin::icosphere(Vec3::ZERO, 1.0, 2);
        let area: f64 = crate::receivers::triangle_areas(&scene).iter().sum();
        for spacing in [10.0, 0.3, 0.05] {
            let samples = surface_samples(&scene, spacing).unwrap();
            let total: f64 = samples.iter().map(|s| s.area).sum();
            assert!(
                (total - area).abs() < 1e-6 * area,
                "{spacing}: {total} against {area}"
            );
            assert!(samples.iter().all(|s| s.area > 0.0));
        }
    }
}
