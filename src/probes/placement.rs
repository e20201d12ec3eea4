//! Where probes go: a grid over the scene's bounds, and what is done with a probe that lands
//! inside geometry.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::{ProbeHits, Sight};
use crate::bake::Backend;
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::spec::MAX_PROBES;

/// How far a probe of the user's points may be moved, as a fraction of the scene's extent
/// (a grid's probes move at most half a cell).
pub const POINT_REACH: f32 = 0.02;

/// A probe is inside geometry when more than this fraction of its rays reach the backs of
/// surfaces: from outside a closed surface no ray does, from inside every one does, and an
/// open scan's holes let a few through.
pub const BACK_FACE_LIMIT: f64 = 0.25;

/// How far past the surface it crosses a moved probe lands, as a fraction of its reach: off
/// the surface, so its own rays leave from free space.
const PAST_SURFACE: f32 = 0.05;

/// What became of a probe; the file stores the code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ProbeStatus {
    /// Baked where it was placed.
    Placed = 0,
    /// Inside geometry where placed; baked where it was moved to, within half a cell.
    Moved = 1,
    /// Inside geometry with no free point within reach: its matrix is zero, and a run-time
    /// leaves it out of the interpolation.
    Invalid = 2,
}

impl ProbeStatus {
    pub fn code(self) -> u8 {
        self as u8
    }

    pub fn from_code(code: u8) -> Option<ProbeStatus> {
        [
            ProbeStatus::Placed,
            ProbeStatus::Moved,
            ProbeStatus::Invalid,
        ]
        .into_iter()
        .find(|s| s.code() == code)
    }
}

/// A regular grid of probes: `dims` points along x, y, z, `spacing` apart from `origin`, x
/// varying fastest (probe `x + dims.x (y + dims.y z)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeGrid {
    pub origin: Vec3,
    pub spacing: f32,
    pub dims: [u32; 3],
}

impl ProbeGrid {
    /// The grid of `spacing` whose cells cover `scene`'s bounding box, centred on it, a probe
    /// at each cell's centre: none lies on the box's faces, where a floor or a wall would be.
    pub fn over(scene: &Scene, spacing: f32) -> Result<ProbeGrid> {
        let (lo, hi) = scene.bounds();
        let size = (hi - lo).max(Vec3::ZERO);
        let count = (size / spacing)
            .ceil()
            .max(Vec3::ONE)
            .to_array()
            .map(|c| c as f64);
        let total = count.iter().product::<f64>();
        if total > MAX_PROBES as f64 {
            return Err(Error::Options(format!(
                "--probes {spacing}: a grid of {} x {} x {} probes over the scene's bounds, more \
                 than {MAX_PROBES} (choose a larger spacing)",
                count[0], count[1], count[2]
            )));
        }
        let dims = count.map(|c| c as u32);
        let cells = Vec3::from(count.map(|c| c as f32));
        let centre = 0.5 * (lo + hi);
        Ok(ProbeGrid {
            origin: centre - 0.5 * spacing * (cells - Vec3::ONE),
            spacing,
            dims,
        })
    }

    pub fn points(&self) -> Vec<Vec3> {
        grid_points(self.origin, self.spacing, self.dims)
    }
}

/// The points of a grid, x varying fastest.
pub fn grid_points(origin: Vec3, spacing: f32, [nx, ny, nz]: [u32; 3]) -> Vec<Vec3> {
    let mut points = Vec::with_capacity((nx * ny * nz) as usize);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                points.push(origin + spacing * Vec3::new(x as f32, y as f32, z as f32));
            }
        }
    }
    points
}

/// A probe placed: where it is baked, what became of it, and the hits it is baked from.
pub(super) struct Placed {
    pub position: Vec3,
    pub status: ProbeStatus,
    pub hits: ProbeHits,
}

/// The probes at `points` with their hits `seen`: those inside geometry moved past the
/// nearest back face they see when it lies within `reach`, and cast again from there; marked
/// invalid where that fails.
pub(super) fn place(
    points: &[Vec3],
    seen: Vec<ProbeHits>,
    reach: f32,
    sight: &Sight,
    backend: &dyn Backend,
) -> Result<Vec<Placed>> {
    let samples = sight.samples.len();
    let mut moves = Vec::new();
    // Each probe takes its hits over (they are a batch's largest allocation); an invalid one
    // keeps none.
    let mut placed: Vec<Placed> = points
        .iter()
        .zip(seen)
        .enumerate()
        .map(|(index, (&position, hits))| {
            if !inside(sight, &hits, samples) {
                let status = ProbeStatus::Placed;
                return Placed {
                    position,
                    status,
                    hits,
                };
            }
            if let Some(to) = way_out(sight, position, &hits, reach) {
                moves.push((index, to));
            }
            Placed {
                position,
                status: ProbeStatus::Invalid,
                hits: Vec::new(),
            }
        })
        .collect();
    if moves.is_empty() {
        return Ok(placed);
    }
    let targets: Vec<Vec3> = moves.iter().map(|&(_, to)| to).collect();
    let again = sight.cast(&targets, backend)?;
    for ((index, to), hits) in moves.into_iter().zip(again) {
        if !inside(sight, &hits, samples) {
            placed[index] = Placed {
                position: to,
                status: ProbeStatus::Moved,
                hits,
            };
        }
    }
    Ok(placed)
}

/// Whether more than [`BACK_FACE_LIMIT`] of a probe's `samples` rays reach back faces.
fn inside(sight: &Sight, hits: &ProbeHits, samples: usize) -> bool {
    let back = hits
        .iter()
        .filter(|&&(sample, hit)| sight.hit_point_and_side(sample, hit).1)
        .count();
    back as f64 > BACK_FACE_LIMIT * samples as f64
}

/// Just past the nearest back face the probe at `from` sees, along the ray that reaches it,
/// when that lies within `reach`.
fn way_out(sight: &Sight, from: Vec3, hits: &ProbeHits, reach: f32) -> Option<Vec3> {
    let nearest = hits
        .iter()
        .filter_map(|&(sample, hit)| {
            let (point, back) = sight.hit_point_and_side(sample, hit);
            back.then(|| (point.distance(from), sample))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))?;
    let (distance, sample) = nearest;
    let past = PAST_SURFACE * reach;
    (distance + past <= reach).then(|| from + sight.direction(sample) * (distance + past))
}
