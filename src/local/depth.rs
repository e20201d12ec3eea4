//! Hemispherical depth maps (the meshless PCA paper's visibility for lights anywhere in the
//! scene): per receiver, the distance to the nearest surface along a fixed grid of directions
//! over its hemisphere. A light at distance r in direction w is visible where the depth
//! towards w is larger than r. Between the stored directions the four nearest are looked up
//! and their tests weighted bilinearly (a percentage-closer filter: 0 or 1 away from shadow
//! edges, a fraction across them).
//!
//! The directions are the cell centres of a `side x side` grid over the hemi-octahedral
//! square in the receiver's tangent frame (`sampling::tangent_frame`): a direction `d`
//! (`d.z >= 0`) maps to `p = (d.x, d.y) / (|d.x| + |d.y| + d.z)` in the diamond
//! `|p.x| + |p.y| <= 1`, turned 45 degrees onto the square `u = p.x + p.y`, `v = p.x - p.y`
//! in `[-1, 1]^2`. Cells are about equal in solid angle (within a factor of two), every cell
//! centre lies strictly above the horizon, and a direction's four nearest cells are found
//! with no search.

use glam::{Vec2, Vec3};

use crate::bvh::Bvh;
use crate::compress::Cpca;
use crate::sampling::tangent_frame;

/// The grid of stored directions over a receiver's hemisphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DirectionGrid {
    /// Cells per side: `side^2` directions.
    pub side: u32,
}

pub use crate::spec::MAX_GRID_SIDE;

impl DirectionGrid {
    pub fn len(&self) -> usize {
        (self.side * self.side) as usize
    }

    pub fn is_empty(&self) -> bool {
        self.side == 0
    }

    /// The tangent-frame direction of cell `cell` (row-major over `(u, v)`): its centre.
    pub fn direction(&self, cell: usize) -> Vec3 {
        let side = self.side as usize;
        let centre = |i: usize| 2.0 * (i as f32 + 0.5) / side as f32 - 1.0;
        from_hemi_octahedral(Vec2::new(centre(cell % side), centre(cell / side)))
    }

    /// Every cell's tangent-frame direction, in cell order.
    pub fn directions(&self) -> Vec<Vec3> {
        (0..self.len()).map(|cell| self.direction(cell)).collect()
    }

    /// The four cells whose centres surround the tangent-frame direction `d` (`d.z > 0`),
    /// with bilinear weights that sum to 1 (clamped at the square's border).
    pub fn neighbours(&self, d: Vec3) -> [(usize, f32); 4] {
        let side = self.side as usize;
        let square = hemi_octahedral(d);
        // Continuous cell coordinates: cell i's centre sits at i.
        let at = (square + Vec2::ONE) * 0.5 * self.side as f32 - Vec2::splat(0.5);
        let last = (side - 1) as f32;
        let at = at.clamp(Vec2::ZERO, Vec2::splat(last));
        let (i0, j0) = (at.x.floor() as usize, at.y.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(side - 1), (j0 + 1).min(side - 1));
        let (fx, fy) = (at.x - i0 as f32, at.y - j0 as f32);
        [
            (j0 * side + i0, (1.0 - fx) * (1.0 - fy)),
            (j0 * side + i1, fx * (1.0 - fy)),
            (j1 * side + i0, (1.0 - fx) * fy),
            (j1 * side + i1, fx * fy),
        ]
    }
}

/// A direction of the upper hemisphere (`d.z >= 0`, any length) on the square `[-1, 1]^2`.
pub fn hemi_octahedral(d: Vec3) -> Vec2 {
    let p = Vec2::new(d.x, d.y) / (d.x.abs() + d.y.abs() + d.z.max(0.0));
    Vec2::new(p.x + p.y, p.x - p.y)
}

/// The unit direction of a point of the square `[-1, 1]^2`; inverse of [`hemi_octahedral`].
pub fn from_hemi_octahedral(square: Vec2) -> Vec3 {
    let p = Vec2::new(square.x + square.y, square.x - square.y) * 0.5;
    Vec3::new(p.x, p.y, 1.0 - p.x.abs() - p.y.abs()).normalize()
}

/// A world vector in the tangent frame `(t, b, n)`.
pub fn to_tangent(frame: &[Vec3; 3], v: Vec3) -> Vec3 {
    Vec3::new(frame[0].dot(v), frame[1].dot(v), frame[2].dot(v))
}

/// A tangent-frame vector in the world.
pub fn to_world(frame: &[Vec3; 3], v: Vec3) -> Vec3 {
    frame[0] * v.x + frame[1] * v.y + frame[2] * v.z
}

/// Depth maps of every receiver, `[receiver][cell]`.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMaps {
    pub grid: DirectionGrid,
    /// The depth stored where a ray leaves the scene: twice the scene's extent, beyond any
    /// light inside it (so the PCA sees a finite value).
    pub open_depth: f32,
    pub depths: Vec<f32>,
}

impl DepthMaps {
    pub fn receivers(&self) -> usize {
        self.depths.len() / self.grid.len().max(1)
    }
}

/// The depth stored for rays that leave a scene of this BVH.
pub fn open_depth(bvh: &Bvh) -> f32 {
    2.0 * bvh.extent().max(f32::MIN_POSITIVE)
}

/// The world directions of one receiver's cells.
pub fn world_directions(grid: &DirectionGrid, normal: Vec3) -> Vec<Vec3> {
    let frame = tangent_frame(normal);
    grid.directions()
        .into_iter()
        .map(|d| to_world(&frame, d))
        .collect()
}

/// Where a depth map is read: the exact maps, or their compressed form.
pub trait DepthLookup: Sync {
    fn depth(&self, receiver: usize, cell: usize) -> f32;
}

impl DepthLookup for DepthMaps {
    fn depth(&self, receiver: usize, cell: usize) -> f32 {
        self.depths[receiver * self.grid.len() + cell]
    }
}

/// Compressed maps: per cluster of receivers a mean map and a PCA basis
/// (the paper's `S^_c = (S_c - M) B_c^T`); a lookup reconstructs one cell.
impl DepthLookup for Cpca {
    fn depth(&self, receiver: usize, cell: usize) -> f32 {
        self.entry(receiver, cell)
    }
}

/// The fraction of the four cells around the direction from `origin` to `light` whose depth
/// lies beyond the light; 0 below the receiver's horizon.
pub fn visibility(
    lookup: &dyn DepthLookup,
    grid: &DirectionGrid,
    receiver: usize,
    frame: &[Vec3; 3],
    origin: Vec3,
    light: Vec3,
) -> f32 {
    let to_light = light - origin;
    let distance = to_light.length();
    let local = to_tangent(frame, to_light);
    if local.z <= 0.0 || distance == 0.0 {
        return 0.0;
    }
    grid.neighbours(local)
        .iter()
        .filter(|(_, weight)| *weight > 0.0)
        .map(|&(cell, weight)| {
            if lookup.depth(receiver, cell) > distance {
                weight
            } else {
                0.0
            }
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    #[test]
    fn the_map_and_its_inverse_agree_and_cells_stay_above_the_horizon() {
        let mut rng = Pcg32::new(3);
        for _ in 0..1000 {
            let square = Vec2::new(rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0);
            let back = hemi_octahedral(from_hemi_octahedral(square));
            assert!(
                (back - square).abs().max_element() < 1e-5,
                "{square} -> {back}"
            );
        }
        let grid = DirectionGrid { side: 8 };
        for d in grid.directions() {
            assert!(d.z > 0.0 && (d.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn a_cell_centre_looks_up_only_itself_and_weights_sum_to_one() {
        let grid = DirectionGrid { side: 6 };
        for cell in 0..grid.len() {
            let around = grid.neighbours(grid.direction(cell));
            let own: f32 = around.iter().filter(|n| n.0 == cell).map(|n| n.1).sum();
            assert!((own - 1.0).abs() < 1e-4, "cell {cell}: {around:?}");
        }
        let mut rng = Pcg32::new(5);
        for _ in 0..200 {
            let d = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32());
            let sum: f32 = grid.neighbours(d).iter().map(|n| n.1).sum();
            assert!((sum - 1.0).abs() < 1e-5);
        }
    }
}
