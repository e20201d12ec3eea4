//! The BVH in the layout the GPU kernels read (wgsl/bvh.wgsl): interior nodes with both
//! children's boxes quantized to a 16-bit grid, and the triangles with leaf ends marked.
//! Built from the CPU tree ([`super::Bvh`]), so both backends test the same triangles.

use bytemuck::{Pod, Zeroable};

use super::{Bvh, BvhTriangle};
use crate::ray::NO_HIT;

/// Marks a child reference in a [`GpuNode`] as a leaf (the rest is its first triangle).
pub const LEAF_FLAG: u32 = 1 << 31;
/// `BvhTriangle::last_in_leaf` of the last triangle of a leaf in [`GpuBvh::triangles`].
pub const LAST_IN_LEAF: u32 = 1;

/// One interior node of the CPU tree as the visibility kernel reads it, 32 bytes (WGSL layout
/// in wgsl/bvh.wgsl): both children's boxes on the grid of [`GpuBvh`], and their references
/// (an interior child's index in [`GpuBvh::nodes`], or `LEAF_FLAG | first triangle`).
///
/// A traversal step on llvmpipe pays per storage-buffer load (a loop over the SIMD lanes with
/// a bounds check per lane and component): this layout gives a step two 16-byte loads where
/// `BvhNode`s take six loads (the node, then both children's corners).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNode {
    /// (min.x, min.y), (min.z, max.x), (max.y, max.z) as pairs of u16, low half first.
    pub left_box: [u32; 3],
    pub left: u32,
    pub right_box: [u32; 3],
    pub right: u32,
}
const _: () = assert!(std::mem::size_of::<GpuNode>() == 32);

/// The BVH in the visibility kernel's layout. Boxes are quantized to 16 bits per coordinate
/// on a grid whose step is a power of two and whose points `grid_origin + q * grid_step` are
/// all exact f32 values, rounded outwards: every box holds its exact box, so the kernel tests
/// the triangles the CPU tests (and perhaps a few more, which cannot change an answer).
/// Nodes come in the CPU tree's order and the near child is chosen the same way, so a
/// closest-hit query finds the same triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuBvh {
    pub nodes: Vec<GpuNode>,
    /// `bvh.triangles` with [`LAST_IN_LEAF`] in `last_in_leaf` of each leaf's last triangle.
    pub triangles: Vec<BvhTriangle>,
    pub grid_origin: [f32; 3],
    pub grid_step: f32,
}

const GRID_MAX: f64 = 65535.0;

impl GpuBvh {
    pub fn new(bvh: &Bvh) -> Self {
        let Some(root) = bvh.nodes.first() else {
            // No triangles: one node whose children are a leaf holding a degenerate triangle
            // (zero determinant: never hit).
            return GpuBvh {
                nodes: vec![GpuNode {
                    left: LEAF_FLAG,
                    right: LEAF_FLAG,
                    ..GpuNode::default()
                }],
                triangles: vec![BvhTriangle {
                    source_index: NO_HIT,
                    last_in_leaf: LAST_IN_LEAF,
                    ..BvhTriangle::default()
                }],
                grid_origin: [0.0; 3],
                grid_step: 1.0,
            };
        };
        let (lo, hi) = (root.min.map(f64::from), root.max.map(f64::from));
        let magnitude = (0..3).fold(0.0f64, |m, a| m.max(lo[a].abs()).max(hi[a].abs()));
        let extent = (0..3).fold(0.0f64, |m, a| m.max(hi[a] - lo[a]));
        // The smallest power of two that spans the scene in GRID_MAX steps (plus one for the
        // origin's rounding down) and keeps origin + q * step exact in f32 (24-bit mantissa).
        let mut step = f64::from(f32::MIN_POSITIVE);
        while extent > (GRID_MAX - 1.0) * step || magnitude + extent >= step * (1u64 << 23) as f64 {
            step *= 2.0;
        }
        let origin = lo.map(|v| (v / step).floor() * step);
        let grid = |v: f32, axis: usize, up: bool| -> u32 {
            let q = (f64::from(v) - origin[axis]) / step;
            (if up { q.ceil() } else { q.floor() }).clamp(0.0, GRID_MAX) as u32
        };
        let quantize = |index: u32| -> [u32; 3] {
            let n = &bvh.nodes[index as usize];
            let q = [
                grid(n.min[0], 0, false),
                grid(n.min[1], 1, false),
                grid(n.min[2], 2, false),
                grid(n.max[0], 0, true),
                grid(n.max[1], 1, true),
                grid(n.max[2], 2, true),
            ];
            [q[0] | q[1] << 16, q[2] | q[3] << 16, q[4] | q[5] << 16]
        };

        let mut triangles = bvh.triangles.clone();
        let mut gpu_index = vec![u32::MAX; bvh.nodes.len()];
        let mut interior = Vec::new();
        if root.is_leaf() {
            // A one-leaf tree: a node whose two children are that leaf.
            interior.push((0, 0));
        } else {
            // Interior nodes in the CPU tree's order.
            for (i, n) in bvh.nodes.iter().enumerate() {
                if !n.is_leaf() {
                    gpu_index[i] = interior.len() as u32;
                    interior.push((n.left_or_first, n.left_or_first + 1));
                }
            }
        }
        let reference = |child: u32, triangles: &mut Vec<BvhTriangle>| -> u32 {
            let n = &bvh.nodes[child as usize];
            if n.is_leaf() {
                triangles[(n.left_or_first + n.triangle_count - 1) as usize].last_in_leaf =
                    LAST_IN_LEAF;
                LEAF_FLAG | n.left_or_first
            } else {
                gpu_index[child as usize]
            }
        };
        let nodes = interior
            .iter()
            .map(|&(left, right)| GpuNode {
                left_box: quantize(left),
                left: reference(left, &mut triangles),
                right_box: quantize(right),
                right: reference(right, &mut triangles),
            })
            .collect();
        GpuBvh {
            nodes,
            triangles,
            grid_origin: origin.map(|v| v as f32),
            grid_step: step as f32,
        }
    }

    /// A box of `nodes` back in world space, as the kernel computes it.
    pub fn decode(&self, q: [u32; 3]) -> ([f32; 3], [f32; 3]) {
        let g = |v: u32, a: usize| self.grid_origin[a] + (v as f32) * self.grid_step;
        (
            [g(q[0] & 0xffff, 0), g(q[0] >> 16, 1), g(q[1] & 0xffff, 2)],
            [g(q[1] >> 16, 0), g(q[2] & 0xffff, 1), g(q[2] >> 16, 2)],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::{intersect_box, intersect_triangle, past, reach, replaces, Ray, RAY_T_MAX};
    use crate::sampling::Pcg32;
    use crate::scene::builtin;
    use glam::Vec3;

    fn default_bvh() -> Bvh {
        let scene = builtin::default_scene();
        Bvh::build(&scene.positions, &scene.triangles)
    }

    /// The kernel's traversal (wgsl/bvh.wgsl `trace`), step for step, on the CPU.
    fn gpu_closest_hit(g: &GpuBvh, ray: &Ray, any_hit: bool) -> Option<(u32, f32)> {
        let mut t_max = RAY_T_MAX;
        let mut box_t_max = RAY_T_MAX;
        let mut best = None;
        let mut best_index = NO_HIT;
        let mut stack = Vec::new();
        let mut node = 0u32;
        loop {
            let mut descend = false;
            if node & LEAF_FLAG != 0 {
                let mut i = (node & !LEAF_FLAG) as usize;
                loop {
                    let t = &g.triangles[i];
                    let [v0, v1, v2] = t.vertices();
                    if let Some(hit) = intersect_triangle(ray, v0, v1, v2, 0.0, t_max) {
                        let best_t = best.map_or(RAY_T_MAX, |b: (u32, f32)| b.1);
                        if any_hit || replaces(hit.t, i as u32, best_t, best_index) {
                            best = Some((t.source_index, hit.t));
                            best_index = i as u32;
                            if any_hit {
                                return best;
                            }
                            t_max = past(hit.t);
                            box_t_max = reach(hit.t);
                        }
                    }
                    if t.last_in_leaf != 0 {
                        break;
                    }
                    i += 1;
                }
            } else {
                let n = &g.nodes[node as usize];
                let test = |q| {
                    let (lo, hi) = g.decode(q);
                    intersect_box(ray, Vec3::from(lo), Vec3::from(hi), 0.0, box_t_max)
                };
                match (test(n.left_box), test(n.right_box)) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b {
                            (n.left, n.right)
                        } else {
                            (n.right, n.left)
                        };
                        stack.push(far);
                        node = near;
                        descend = true;
                    }
                    (Some(_), None) => (node, descend) = (n.left, true),
                    (None, Some(_)) => (node, descend) = (n.right, true),
                    (None, None) => {}
                }
            }
            if !descend {
                match stack.pop() {
                    Some(next) => node = next,
                    None => return best,
                }
            }
        }
    }

    #[test]
    fn grid_boxes_hold_the_exact_boxes() {
        let bvh = default_bvh();
        let g = GpuBvh::new(&bvh);
        let interior: Vec<_> = bvh.nodes.iter().filter(|n| !n.is_leaf()).collect();
        assert_eq!(interior.len(), g.nodes.len());
        for (n, gn) in interior.iter().zip(&g.nodes) {
            for (child, q) in [
                (n.left_or_first, gn.left_box),
                (n.left_or_first + 1, gn.right_box),
            ] {
                let exact = &bvh.nodes[child as usize];
                let (lo, hi) = g.decode(q);
                for a in 0..3 {
                    assert!(lo[a] <= exact.min[a] && hi[a] >= exact.max[a]);
                    // Rounded outwards by less than two grid steps.
                    assert!(exact.min[a] - lo[a] <= 2.0 * g.grid_step);
                    assert!(hi[a] - exact.max[a] <= 2.0 * g.grid_step);
                }
            }
        }
    }

    #[test]
    fn gpu_layout_traversal_matches_the_cpu_tree() {
        let bvh = default_bvh();
        let g = GpuBvh::new(&bvh);
        let mut rng = Pcg32::new(3);
        let root = &bvh.nodes[0];
        for _ in 0..20_000 {
            let mut r = || rng.next_f32();
            let origin = Vec3::from(root.min)
                + (Vec3::from(root.max) - Vec3::from(root.min)) * Vec3::new(r(), r(), r());
            let direction = (Vec3::new(r(), r(), r()) * 2.0 - 1.0).normalize_or(Vec3::Y);
            let ray = Ray::new(origin, direction);
            assert_eq!(
                gpu_closest_hit(&g, &ray, true).is_some(),
                bvh.occluded(&ray, RAY_T_MAX)
            );
            assert_eq!(
                gpu_closest_hit(&g, &ray, false),
                bvh.closest_hit(&ray, RAY_T_MAX).map(|(i, h)| (i, h.t))
            );
        }
    }

    #[test]
    fn an_empty_or_one_leaf_tree_has_a_gpu_layout() {
        let empty = GpuBvh::new(&Bvh::default());
        assert_eq!(empty.nodes.len(), 1);
        let ray = Ray::new(Vec3::ZERO, Vec3::Y);
        assert_eq!(gpu_closest_hit(&empty, &ray, true), None);
        let one = Bvh::build(
            &[
                Vec3::new(-1.0, 1.0, -1.0),
                Vec3::new(1.0, 1.0, -1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            &[[0, 1, 2]],
        );
        let g = GpuBvh::new(&one);
        assert_eq!(gpu_closest_hit(&g, &ray, false).map(|h| h.0), Some(0));
        // The kernels read the first triangle's pad word as their unseen zero (`rounded`).
        for tree in [&empty, &g, &GpuBvh::new(&default_bvh())] {
            assert!(!tree.triangles.is_empty());
            assert!(tree.triangles.iter().all(|t| t.pad2 == 0));
        }
    }
}
