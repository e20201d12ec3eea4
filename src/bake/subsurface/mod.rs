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

mod medium;

pub use medium::*;

use std::collections::HashMap;
use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::backend::{Backend, Gatherer};
use super::bounce::GatherMatrix;
use crate::error::{Error, Result};
use crate::scene::gltf::volume::SceneVolumes;
use crate::scene::joined::Joined;
use crate::scene::prepare::DROPPED;
use crate::scene::Scene;

/// The most matrix entries (per channel) a subsurface bake builds.
pub const MAX_ENTRIES: usize = 1 << 25;

/// The most lattice steps along a triangle's edge: past it, the diffusion length is so much
/// shorter than the triangle that each point's own disc holds all it gives its neighbours.
pub const MAX_STEPS: usize = 8;

/// The most lattice points the triangles get besides the vertices.
pub const MAX_POINTS: usize = 1 << 22;

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

/// Each vertex's piece of `scene`: vertices in one medium (`of_vertex`) joined by a triangle,
/// or at the same position, are one piece (the vertices a mesh splits along a crease stay one
/// object; two objects that only touch, or come close, are two, and so are two media that
/// share an edge).
fn pieces(scene: &Scene, of_vertex: &[u32]) -> Vec<u32> {
    let mut sets = Joined::new(scene.vertex_count());
    for t in &scene.triangles {
        for other in [t[1], t[2]] {
            if of_vertex[t[0] as usize] == of_vertex[other as usize] {
                sets.join(t[0], other);
            }
        }
    }
    let mut first_at: HashMap<([u32; 3], u32), u32> = HashMap::new();
    for (v, p) in scene.positions.iter().enumerate() {
        let key = (p.to_array().map(f32::to_bits), of_vertex[v]);
        let first = *first_at.entry(key).or_insert(v as u32);
        sets.join(first, v as u32);
    }
    (0..scene.vertex_count() as u32)
        .map(|v| sets.root(v))
        .collect()
}

/// The points of `scene` about `spacing` apart (per medium; infinite where opaque): every
/// vertex, and on each triangle with an edge longer than its medium's spacing, a lattice of up
/// to [`MAX_STEPS`] steps per edge. Each lattice point stands for a third of the area of the
/// lattice's sub-triangles it is a corner of; the corners' shares go to the vertices.
fn surface_samples(
    scene: &Scene,
    (of_vertex, spacing): (&[u32], &dyn Fn(u32) -> f64),
) -> Result<Vec<SurfaceSample>> {
    let position = |v: u32| scene.positions[v as usize].as_dvec3();
    let piece = pieces(scene, of_vertex);
    let mut vertex_area = vec![0.0f64; scene.vertex_count()];
    let mut lattice = Vec::new();
    for &corners in &scene.triangles {
        let spacing = spacing(of_vertex[corners[0] as usize]);
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

/// A vertex in no medium: an opaque diffuse surface, its own albedo.
pub const OPAQUE: u32 = u32::MAX;

/// One medium's profiles, how far they reach, and the spacing of the points its surface
/// needs (a quarter of its shortest diffusion length).
struct MediumProfiles {
    dipoles: [Dipole; 3],
    reach: f64,
    spacing: f64,
}

impl MediumProfiles {
    fn new(material: &SubsurfaceMaterial) -> Result<MediumProfiles> {
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
        Ok(MediumProfiles {
            dipoles,
            reach,
            spacing: 0.25 * diffusion_length,
        })
    }
}

/// The surface a subsurface integral runs over: its media's profiles, its points (with each
/// vertex's piece), a grid over them, and the farthest reach.
struct Surface {
    profiles: Vec<MediumProfiles>,
    samples: Vec<SurfaceSample>,
    grid: PointGrid,
    reach: f64,
}

/// Where a row is made for: a point, its piece, its medium, and the radius of the disc about
/// it whose light is its own (integrated exactly, the rest from the surface's points).
#[derive(Clone, Copy, Debug)]
struct RowReceiver {
    position: DVec3,
    piece: u32,
    medium: u32,
    own_radius: f64,
}

/// A receiver's row (per column: a vertex, and its weight per channel) and the weight of its
/// own disc's light, per channel.
type Row = (Vec<(u32, [f32; 3])>, [f32; 3]);

impl Surface {
    /// The surface of `scene`, its vertices in `media` (`of_vertex` indexes them, or is
    /// [`OPAQUE`]).
    fn new(scene: &Scene, (media, of_vertex): (&[SubsurfaceMaterial], &[u32])) -> Result<Surface> {
        let profiles = media
            .iter()
            .map(MediumProfiles::new)
            .collect::<Result<Vec<_>>>()?;
        let reach = profiles.iter().map(|p| p.reach).fold(0.0, f64::max);
        let spacing = |medium: u32| match profiles.get(medium as usize) {
            Some(profiles) => profiles.spacing,
            None => f64::INFINITY,
        };
        let samples = surface_samples(scene, (of_vertex, &spacing))?;
        let grid = PointGrid::new(&samples, reach);
        Ok(Surface {
            profiles,
            samples,
            grid,
            reach,
        })
    }

    /// The piece vertex `v` lies on.
    fn piece(&self, v: u32) -> u32 {
        self.samples[v as usize].piece
    }

    /// The rows of `receivers`; `opaque(i)` the own weight (its albedo) of receiver `i` in no
    /// medium. Stops, with the advice, as the rows pass [`MAX_ENTRIES`].
    fn rows(
        &self,
        receivers: impl IndexedParallelIterator<Item = RowReceiver>,
        opaque: impl Fn(usize) -> Row + Sync,
    ) -> Result<Vec<Row>> {
        // Counted as the rows are made, so a matrix too big to hold stops being built.
        let entries = std::sync::atomic::AtomicUsize::new(0);
        let rows: Vec<Row> = receivers
            .enumerate()
            .map(|(i, receiver)| {
                if entries.load(std::sync::atomic::Ordering::Relaxed) > MAX_ENTRIES {
                    return (Vec::new(), [0.0; 3]);
                }
                let Some(medium) = self.profiles.get(receiver.medium as usize) else {
                    return opaque(i);
                };
                let row = self.row(receiver, medium);
                entries.fetch_add(row.0.len(), std::sync::atomic::Ordering::Relaxed);
                row
            })
            .collect();
        if entries.into_inner() > MAX_ENTRIES {
            return Err(Error::Options(format!(
                "--subsurface: more than {MAX_ENTRIES} matrix entries: the light travels \
                 {:.3e} scene units under the surface, through most of the mesh (a larger \
                 --sss-mm-per-unit makes the object bigger and the way shorter)",
                self.reach
            )));
        }
        Ok(rows)
    }

    /// One receiver's row: every sample of its piece within its medium's reach, the profile's
    /// mass over the sample's ring outside the receiver's own disc spread over the sample's
    /// corners, and the disc's own mass; the sum per channel held to the plane's total.
    fn row(&self, receiver: RowReceiver, medium: &MediumProfiles) -> Row {
        let RowReceiver {
            position,
            piece,
            own_radius,
            ..
        } = receiver;
        let (dipoles, reach) = (&medium.dipoles, medium.reach);
        let mut entries: Vec<(u32, [f64; 3])> = Vec::new();
        let own: [f64; 3] = std::array::from_fn(|c| dipoles[c].within(own_radius));
        let mut sums = own;
        self.grid.within(position, reach, |s| {
            let sample = &self.samples[s];
            let r = sample.position.distance(position);
            if r > reach || sample.area <= 0.0 || sample.piece != piece {
                return;
            }
            let radius = (sample.area / PI).sqrt();
            let weight: [f64; 3] = std::array::from_fn(|c| {
                sample.area * dipoles[c].ring_mean_outside(r, radius, own_radius)
            });
            for c in 0..3 {
                sums[c] += weight[c];
            }
            for (&corner, &share) in sample.corners.iter().zip(&sample.weights) {
                if share > 0.0 {
                    entries.push((corner, weight.map(|w| share * w)));
                }
            }
        });
        let scale: [f64; 3] = std::array::from_fn(|c| {
            let total = dipoles[c].total();
            if sums[c] > total {
                total / sums[c]
            } else {
                1.0
            }
        });
        entries.sort_unstable_by_key(|&(j, _)| j);
        let mut row: Vec<(u32, [f32; 3])> = Vec::new();
        for (j, weight) in entries {
            let scaled: [f32; 3] = std::array::from_fn(|c| (weight[c] * scale[c]) as f32);
            match row.last_mut() {
                Some((last, sum)) if *last == j => (0..3).for_each(|c| sum[c] += scaled[c]),
                _ => row.push((j, scaled)),
            }
        }
        (row, std::array::from_fn(|c| (own[c] * scale[c]) as f32))
    }
}

/// The subsurface matrices of `scene`, its vertices in `media` (`of_vertex` indexes them, or
/// is [`OPAQUE`]), one per channel: row `p`, column `j`, the weight of what vertex `j` would
/// send back as a white diffuse surface in what vertex `p` sends back through its medium
/// ([`Scattering::apply`]); an opaque vertex's row is its own albedo. Also the farthest reach
/// it cut at.
pub fn subsurface_matrices(
    scene: &Scene,
    (media, of_vertex): (&[SubsurfaceMaterial], &[u32]),
) -> Result<([GatherMatrix; 3], f64)> {
    let surface = Surface::new(scene, (media, of_vertex))?;
    // A vertex's own point stands for its own area: no disc besides.
    let receivers = scene
        .positions
        .par_iter()
        .enumerate()
        .map(|(v, p)| RowReceiver {
            position: p.as_dvec3(),
            piece: surface.piece(v as u32),
            medium: of_vertex[v],
            own_radius: 0.0,
        });
    let opaque = |v: usize| (vec![(v as u32, scene.albedo[v].to_array())], [0.0; 3]);
    let rows = surface.rows(receivers, opaque)?;
    Ok((per_channel(&rows), surface.reach))
}

/// The rows' matrices, channel by channel.
fn per_channel(rows: &[Row]) -> [GatherMatrix; 3] {
    std::array::from_fn(|c| {
        GatherMatrix::from_rows(
            rows.iter()
                .map(|(row, _)| row.iter().map(|&(j, w)| (j, w[c])).collect())
                .collect(),
        )
    })
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

/// A glTF material's medium, as the file's metadata records it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialMedium {
    /// The index of the glTF material it is the volume of.
    pub material: usize,
    #[serde(flatten)]
    pub medium: SubsurfaceMaterial,
}

/// The media of a scene's own materials (a glTF scene's scattering volumes), and per vertex
/// of the scene as loaded, its index among them or [`OPAQUE`].
#[derive(Clone, Debug, PartialEq)]
pub struct SceneMedia {
    pub media: Vec<MaterialMedium>,
    pub of_vertex: Vec<u32>,
}

impl SceneMedia {
    /// The media `volumes` describe (`None` where none does), and a line for each volume
    /// that describes none, saying why.
    pub fn of_volumes(volumes: &SceneVolumes) -> (Option<SceneMedia>, Vec<String>) {
        let mut media = Vec::new();
        let mut notes = Vec::new();
        let renumbered: Vec<u32> = volumes
            .volumes
            .iter()
            .map(|volume| match SubsurfaceMaterial::of_volume(volume) {
                Ok(medium) => {
                    media.push(MaterialMedium {
                        material: volume.material,
                        medium,
                    });
                    media.len() as u32 - 1
                }
                Err(why) => {
                    notes.push(format!("material {} is baked opaque: {why}", volume.label));
                    OPAQUE
                }
            })
            .collect();
        let of_vertex = volumes
            .of_vertex
            .iter()
            .map(|&v| renumbered.get(v as usize).copied().unwrap_or(OPAQUE))
            .collect();
        let found = (!media.is_empty()).then_some(SceneMedia { media, of_vertex });
        (found, notes)
    }

    /// The medium of each of the `vertices` of the prepared scene, `map` giving the prepared
    /// vertex each loaded one became ([`DROPPED`] where none): a prepared vertex welded from
    /// vertices in two media takes the first's.
    pub fn on_prepared(&self, map: &[u32], vertices: usize) -> Vec<u32> {
        let mut of_prepared = vec![OPAQUE; vertices];
        for (&prepared, &medium) in map.iter().zip(&self.of_vertex) {
            if prepared != DROPPED && of_prepared[prepared as usize] == OPAQUE {
                of_prepared[prepared as usize] = medium;
            }
        }
        of_prepared
    }

    /// The media, in the order `of_vertex` indexes them.
    pub fn materials(&self) -> Vec<SubsurfaceMaterial> {
        self.media.iter().map(|m| m.medium).collect()
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
    /// The scattering of `scene`'s vertices in `media` (`of_vertex` indexes them, or is
    /// [`OPAQUE`]).
    pub fn new(scene: &Scene, media: (&[SubsurfaceMaterial], &[u32])) -> Result<Scatter> {
        let started = std::time::Instant::now();
        let (matrices, reach) = subsurface_matrices(scene, media)?;
        let only = channel_selectors(scene.vertex_count());
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

    /// The scattering on `backend` for transfer of `bands`, each channel's matrix made ready
    /// once (on the GPU: uploaded once) for the direct light and every bounce.
    pub fn on<'s>(&'s self, bands: u32, backend: &'s dyn Backend) -> Result<Scattering<'s>> {
        Scattering::new(&self.matrices, &self.only, bands, backend)
    }
}

/// Subsurface matrices ready on a backend: [`Scattering::apply`] runs them.
pub struct Scattering<'s> {
    /// Each channel's gatherer, `None` for a channel whose matrix is empty.
    gatherers: Vec<Option<Box<dyn Gatherer + 's>>>,
    rows: usize,
    stride: usize,
}

impl<'s> Scattering<'s> {
    fn new(
        matrices: &'s [GatherMatrix; 3],
        only: &'s [Vec<Vec3>; 3],
        bands: u32,
        backend: &'s dyn Backend,
    ) -> Result<Scattering<'s>> {
        let gatherers = matrices
            .iter()
            .zip(only)
            .map(|(matrix, only)| match matrix.columns.is_empty() {
                true => Ok(None),
                false => backend.gatherer(matrix, only, bands).map(Some),
            })
            .collect::<Result<_>>()?;
        Ok(Scattering {
            gatherers,
            rows: matrices[0].rows(),
            stride: 3 * crate::sh::coeff_count(bands),
        })
    }

    /// The light a surface sends back from the albedo-free transfer `values` (RGB,
    /// `[vertex][3][coeffs]`, what a white diffuse surface would send back), scattered under
    /// it: channel by channel `W_c values_c`, summed. For a white diffuse surface, `values`
    /// is `1/pi` times the irradiance transfer, and `W_c` holds the profile's exitance, so
    /// this is `(1/pi) integral R_d E dA` per unit light.
    pub fn apply(&self, values: &[f32]) -> Result<Vec<f32>> {
        let mut sum = vec![0.0f32; self.rows * self.stride];
        for gatherer in self.gatherers.iter().flatten() {
            let gathered = gatherer.gather(values)?;
            sum.iter_mut().zip(gathered).for_each(|(s, g)| *s += g);
        }
        Ok(sum)
    }
}

/// Channel `c`'s selector for `rows` rows: `e_c` at every row (the gather's per-row albedo).
fn channel_selectors(rows: usize) -> [Vec<Vec3>; 3] {
    std::array::from_fn(|c| {
        let mut unit = Vec3::ZERO;
        unit[c] = 1.0;
        vec![unit; rows]
    })
}

/// A point of the surface where subsurface light is wanted (a lightmap's texel): where it is,
/// a vertex of its triangle (whose piece and medium it shares), the radius of the disc it
/// stands for, and its albedo, should its material be opaque.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScatterPoint {
    pub position: Vec3,
    pub vertex: u32,
    pub own_radius: f64,
    pub albedo: Vec3,
}

/// Subsurface transfer at points of a scene's surface besides its vertices: its media, and
/// the light that arrives at its vertices as a white diffuse surface would send it back (RGB,
/// `[vertex][3][coeffs]`: what [`Scattering::apply`] scattered, summed over the direct light and
/// the bounces).
pub struct PointScatter<'a> {
    pub media: &'a [SubsurfaceMaterial],
    pub of_vertex: &'a [u32],
    pub incoming: &'a [f32],
}

impl PointScatter<'_> {
    /// The transfer at `points`, from what arrives at each point's own disc (`own`, laid out
    /// as `incoming`: the point's own rays see detail finer than the vertices) and, through
    /// the profile beyond that disc, at the surface's points; an opaque point's is its own
    /// times its albedo.
    pub fn at_points(
        &self,
        scene: &Scene,
        points: &[ScatterPoint],
        (own, bands): (&[f32], u32),
        backend: &dyn Backend,
    ) -> Result<Vec<f32>> {
        let surface = Surface::new(scene, (self.media, self.of_vertex))?;
        let receivers = points.par_iter().map(|point| RowReceiver {
            position: point.position.as_dvec3(),
            piece: surface.piece(point.vertex),
            medium: self.of_vertex[point.vertex as usize],
            own_radius: point.own_radius,
        });
        let opaque = |i: usize| (Vec::new(), points[i].albedo.to_array());
        let rows = surface.rows(receivers, opaque)?;
        let only = channel_selectors(points.len());
        let matrices = per_channel(&rows);
        let scattering = Scattering::new(&matrices, &only, bands, backend)?;
        let mut transfer = scattering.apply(self.incoming)?;
        let coeffs = crate::sh::coeff_count(bands);
        let per_point = transfer
            .chunks_exact_mut(3 * coeffs)
            .zip(own.chunks_exact(3 * coeffs));
        for ((out, own), (_, weight)) in per_point.zip(&rows) {
            let channels = out.chunks_exact_mut(coeffs).zip(own.chunks_exact(coeffs));
            for ((out, own), &weight) in channels.zip(weight) {
                out.iter_mut().zip(own).for_each(|(o, &t)| *o += weight * t);
            }
        }
        Ok(transfer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let one_medium = vec![0; scene.vertex_count()];
            let samples = surface_samples(&scene, (&one_medium, &|_| spacing)).unwrap();
            let total: f64 = samples.iter().map(|s| s.area).sum();
            assert!(
                (total - area).abs() < 1e-6 * area,
                "{spacing}: {total} against {area}"
            );
            assert!(samples.iter().all(|s| s.area > 0.0));
        }
    }
}
