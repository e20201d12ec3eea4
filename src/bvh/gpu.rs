//! The BVH in the layout the GPU kernels read (wgsl/bvh.wgsl): the CPU's binary tree collapsed
//! four-wide, each node holding its children's boxes quantized to a 16-bit grid, and the
//! triangles with leaf ends marked. Built from the CPU tree ([`super::Bvh`]), so both backends
//! test the same triangles.

use bytemuck::{Pod, Zeroable};

use super::{Bvh, BvhNode, BvhTriangle, STACK_SIZE};
use crate::ray::NO_HIT;

/// Marks a child reference in a [`GpuNode`] as a leaf (the rest is its first triangle).
pub const LEAF_FLAG: u32 = 1 << 31;
/// The reference of a [`GpuNode`]'s unused child slots (never tested: the kernel skips it).
pub const EMPTY_CHILD: u32 = u32::MAX;
/// `BvhTriangle::last_in_leaf` of the last triangle of a leaf in [`GpuBvh::triangles`].
pub const LAST_IN_LEAF: u32 = 1;
/// Children of a [`GpuNode`].
pub const WIDTH: usize = 4;
/// The kernel's traversal stack: a step pushes at most three children and descends two levels
/// of the binary tree, whose depth stays below [`STACK_SIZE`]; plus one slot, since the kernel
/// writes each child it might push before it knows whether it will keep it.
pub const WIDE_STACK_SIZE: usize = (WIDTH - 1) * STACK_SIZE.div_ceil(2) + 1;

/// One child of a [`GpuNode`], 16 bytes (one `vec4<u32>` in wgsl/bvh.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuChild {
    /// (min.x, min.y), (min.z, max.x), (max.y, max.z) as pairs of u16, low half first.
    pub bounds: [u32; 3],
    /// An interior child's index in [`GpuBvh::nodes`], `LEAF_FLAG | first triangle`, or
    /// [`EMPTY_CHILD`].
    pub reference: u32,
}

/// A node of the four-wide tree, 64 bytes (WGSL layout in wgsl/bvh.wgsl): a binary node's
/// grandchildren (a child that is a leaf stands for itself; slots left over hold the children
/// of the largest member), in the binary tree's order, then empty slots.
///
/// A traversal step on llvmpipe pays per storage-buffer load (a loop over the SIMD lanes with
/// a bounds check per lane and component): a node of four quantized boxes is four 16-byte
/// loads, and a ray takes about half the binary tree's interior steps.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNode {
    pub children: [GpuChild; WIDTH],
}
const _: () = assert!(std::mem::size_of::<GpuNode>() == 64);

/// The BVH in the visibility kernel's layout. Boxes are quantized to 16 bits per coordinate
/// on a grid whose step is a power of two and whose points `grid_origin + q * grid_step` are
/// all exact f32 values, rounded outwards: every box holds its exact box, so the kernel tests
/// every triangle the CPU tests (and perhaps a few more, which cannot change an answer). Of
/// triangles at one distance both keep the first in the scene (`ray::replaces`), so the
/// order a traversal meets them in cannot change a closest hit either.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuBvh {
    pub nodes: Vec<GpuNode>,
    /// `bvh.triangles` with [`LAST_IN_LEAF`] in `last_in_leaf` of each leaf's last triangle.
    pub triangles: Vec<BvhTriangle>,
    pub grid_origin: [f32; 3],
    pub grid_step: f32,
}

const GRID_MAX: f64 = 65535.0;

const EMPTY: GpuChild = GpuChild {
    bounds: [0; 3],
    reference: EMPTY_CHILD,
};

/// A node with every slot empty, to be filled from the first.
const EMPTY_NODE: GpuNode = GpuNode {
    children: [EMPTY; WIDTH],
};

/// The grid of [`GpuBvh`] for a scene whose box is `lo`..`hi`: its origin and step.
fn box_grid(lo: [f64; 3], hi: [f64; 3]) -> ([f64; 3], f64) {
    let magnitude = (0..3).fold(0.0f64, |m, a| m.max(lo[a].abs()).max(hi[a].abs()));
    let extent = (0..3).fold(0.0f64, |m, a| m.max(hi[a] - lo[a]));
    // The smallest power of two that spans the scene in GRID_MAX steps (plus one for the
    // origin's rounding down) and keeps origin + q * step exact in f32 (24-bit mantissa).
    let mut step = f64::from(f32::MIN_POSITIVE);
    while extent > (GRID_MAX - 1.0) * step || magnitude + extent >= step * (1u64 << 23) as f64 {
        step *= 2.0;
    }
    (lo.map(|v| (v / step).floor() * step), step)
}

impl GpuBvh {
    pub fn new(bvh: &Bvh) -> Self {
        let Some(root) = bvh.nodes.first() else {
            // No triangles: one node whose child is a leaf holding a degenerate triangle
            // (zero determinant: never hit).
            let mut node = EMPTY_NODE;
            node.children[0].reference = LEAF_FLAG;
            return GpuBvh {
                nodes: vec![node],
                triangles: vec![BvhTriangle {
                    source_index: NO_HIT,
                    last_in_leaf: LAST_IN_LEAF,
                    ..BvhTriangle::default()
                }],
                grid_origin: [0.0; 3],
                grid_step: 1.0,
            };
        };
        let (origin, step) = box_grid(root.min.map(f64::from), root.max.map(f64::from));
        let mut wide = WideBuilder {
            bvh,
            origin,
            step,
            nodes: Vec::new(),
            triangles: bvh.triangles.clone(),
        };
        if root.is_leaf() {
            // A one-leaf tree: a node whose one child is that leaf.
            let mut node = EMPTY_NODE;
            node.children[0] = wide.child(0);
            wide.nodes.push(node);
        } else {
            wide.collapse(0);
        }
        GpuBvh {
            nodes: wide.nodes,
            triangles: wide.triangles,
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

fn half_area(node: &BvhNode) -> f32 {
    let d = node.max() - node.min();
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Collapses the binary tree into [`GpuNode`]s, depth first (a node before its children).
struct WideBuilder<'a> {
    bvh: &'a Bvh,
    origin: [f64; 3],
    step: f64,
    nodes: Vec<GpuNode>,
    triangles: Vec<BvhTriangle>,
}

impl WideBuilder<'_> {
    /// The wide node of the binary interior node `index`; returns its index in `nodes`.
    fn collapse(&mut self, index: u32) -> u32 {
        let nodes = &self.bvh.nodes;
        let children = |i: u32| {
            let first = nodes[i as usize].left_or_first;
            [first, first + 1]
        };
        let interior = |i: &u32| !nodes[*i as usize].is_leaf();
        // The node's children, each interior one replaced by its own two: a step descends two
        // levels of the binary tree wherever it can, which bounds the stack (WIDE_STACK_SIZE).
        let mut members = Vec::with_capacity(WIDTH);
        for child in children(index) {
            if interior(&child) {
                members.extend(children(child));
            } else {
                members.push(child);
            }
        }
        // Slots left over (a child was a leaf) take the children of the largest interior
        // member, as wide-tree builders collapse by area.
        while members.len() < WIDTH {
            let largest = (0..members.len())
                .filter(|&m| interior(&members[m]))
                .max_by(|&a, &b| {
                    let area = |m: usize| half_area(&nodes[members[m] as usize]);
                    area(a).total_cmp(&area(b))
                });
            let Some(m) = largest else { break };
            members.splice(m..=m, children(members[m]));
        }
        let at = self.nodes.len();
        self.nodes.push(EMPTY_NODE);
        for (slot, member) in members.into_iter().enumerate() {
            let child = self.child(member);
            self.nodes[at].children[slot] = child;
        }
        at as u32
    }

    /// The binary node `index` as a child: its box on the grid and its reference (an interior
    /// node collapsed in turn).
    fn child(&mut self, index: u32) -> GpuChild {
        let node = self.bvh.nodes[index as usize];
        let reference = if node.is_leaf() {
            self.triangles[(node.left_or_first + node.triangle_count - 1) as usize].last_in_leaf =
                LAST_IN_LEAF;
            LEAF_FLAG | node.left_or_first
        } else {
            self.collapse(index)
        };
        let grid = |v: f32, axis: usize, up: bool| -> u32 {
            let q = (f64::from(v) - self.origin[axis]) / self.step;
            (if up { q.ceil() } else { q.floor() }).clamp(0.0, GRID_MAX) as u32
        };
        let q = [
            grid(node.min[0], 0, false),
            grid(node.min[1], 1, false),
            grid(node.min[2], 2, false),
            grid(node.max[0], 0, true),
            grid(node.max[1], 1, true),
            grid(node.max[2], 2, true),
        ];
        GpuChild {
            bounds: [q[0] | q[1] << 16, q[2] | q[3] << 16, q[4] | q[5] << 16],
            reference,
        }
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

    /// The kernel's traversal (wgsl/bvh.wgsl `trace`), step for step, on the CPU (children
    /// met at one entry distance may be taken in another order, which changes no answer).
    fn gpu_closest_hit(g: &GpuBvh, ray: &Ray, any_hit: bool) -> Option<(u32, f32)> {
        let mut t_max = RAY_T_MAX;
        let mut box_t_max = RAY_T_MAX;
        let mut best = None;
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
                        let (best_index, best_t) = best.unwrap_or((NO_HIT, RAY_T_MAX));
                        if any_hit || replaces(hit.t, t.source_index, best_t, best_index) {
                            best = Some((t.source_index, hit.t));
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
                // Children met, nearest first, as the kernel orders them.
                let mut met: Vec<(f32, u32)> = g.nodes[node as usize]
                    .children
                    .iter()
                    .filter(|c| c.reference != EMPTY_CHILD)
                    .filter_map(|c| {
                        let (lo, hi) = g.decode(c.bounds);
                        intersect_box(ray, Vec3::from(lo), Vec3::from(hi), 0.0, box_t_max)
                            .map(|near| (near, c.reference))
                    })
                    .collect();
                met.sort_by(|a, b| a.0.total_cmp(&b.0));
                if let Some((&(_, nearest), rest)) = met.split_first() {
                    stack.extend(rest.iter().rev().map(|&(_, r)| r));
                    assert!(stack.len() < WIDE_STACK_SIZE);
                    node = nearest;
                    descend = true;
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

    /// The bounds of the triangles below `reference`, and how many leaves hold them.
    fn triangles_below(g: &GpuBvh, reference: u32) -> (Vec3, Vec3, usize) {
        if reference & LEAF_FLAG != 0 {
            let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            for t in &g.triangles[(reference & !LEAF_FLAG) as usize..] {
                for v in t.vertices() {
                    (lo, hi) = (lo.min(v), hi.max(v));
                }
                if t.last_in_leaf != 0 {
                    break;
                }
            }
            return (lo, hi, 1);
        }
        let (mut lo, mut hi, mut leaves) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0);
        for child in &g.nodes[reference as usize].children {
            if child.reference != EMPTY_CHILD {
                let (l, h, n) = triangles_below(g, child.reference);
                (lo, hi, leaves) = (lo.min(l), hi.max(h), leaves + n);
            }
        }
        (lo, hi, leaves)
    }

    #[test]
    fn grid_boxes_hold_the_triangles_below_them() {
        let bvh = default_bvh();
        let g = GpuBvh::new(&bvh);
        for node in &g.nodes {
            let used = node.children.iter().filter(|c| c.reference != EMPTY_CHILD);
            // Used slots first, at least two of them.
            let count = used.clone().count();
            assert!(count >= 2);
            assert!(node.children[count..]
                .iter()
                .all(|c| c.reference == EMPTY_CHILD));
            for child in used {
                let (exact_lo, exact_hi, _) = triangles_below(&g, child.reference);
                let (lo, hi) = g.decode(child.bounds);
                for a in 0..3 {
                    assert!(lo[a] <= exact_lo[a] && hi[a] >= exact_hi[a]);
                    // Rounded outwards by less than two grid steps.
                    assert!(exact_lo[a] - lo[a] <= 2.0 * g.grid_step);
                    assert!(hi[a] - exact_hi[a] <= 2.0 * g.grid_step);
                }
            }
        }
        // Every leaf of the binary tree is a child of exactly one wide node.
        let binary_leaves = bvh.nodes.iter().filter(|n| n.is_leaf()).count();
        assert_eq!(triangles_below(&g, 0).2, binary_leaves);
        // Most nodes of the binary tree are inside a wide node: a ray takes about half the
        // interior steps. (Subtrees of two or three leaves make nodes of two or three.)
        let binary_interior = bvh.nodes.len() - binary_leaves;
        assert!(g.nodes.len() * 5 < binary_interior * 3);
    }

    /// The most entries the kernel's stack holds on any path of `g`: each node pushes all its
    /// children but one.
    fn deepest_stack(g: &GpuBvh, node: u32) -> usize {
        let children = g.nodes[node as usize]
            .children
            .iter()
            .filter(|c| c.reference != EMPTY_CHILD);
        let pushed = children.clone().count() - 1;
        let below = children
            .filter(|c| c.reference & LEAF_FLAG == 0)
            .map(|c| deepest_stack(g, c.reference))
            .max()
            .unwrap_or(0);
        pushed + below
    }

    /// A tree nearly as deep as the build makes (leaves at depth [`STACK_SIZE`] - 2, one above
    /// the build's deepest), in the shape that fills a wide stack most: a spine whose every
    /// node has four grandchildren, the next spine node and three leaves. Every box is the unit
    /// cube and every triangle lies in it, off the z axis.
    fn deepest_spine() -> Bvh {
        let unit = |left_or_first, triangle_count| BvhNode {
            min: [0.0; 3],
            max: [1.0; 3],
            left_or_first,
            triangle_count,
        };
        let mut nodes = vec![unit(0, 0)];
        let mut triangles = Vec::new();
        let mut leaf = |nodes: &mut Vec<BvhNode>| {
            nodes.push(unit(triangles.len() as u32, 1));
            triangles.push(BvhTriangle {
                v0: [0.5, 0.5, 0.5],
                v1: [0.9, 0.5, 0.5],
                v2: [0.9, 0.9, 0.5],
                source_index: triangles.len() as u32,
                ..BvhTriangle::default()
            });
        };
        let mut spine = 0;
        // Spine nodes at depths 0, 2, ..., 60; the last one's grandchildren are leaves.
        for depth in (0..STACK_SIZE - 2).step_by(2) {
            let first = nodes.len() as u32;
            nodes[spine].left_or_first = first;
            nodes.extend([unit(first + 2, 0), unit(first + 4, 0)]);
            let next = nodes.len();
            if depth + 2 < STACK_SIZE - 2 {
                nodes.push(unit(0, 0));
            } else {
                leaf(&mut nodes);
            }
            for _ in 0..3 {
                leaf(&mut nodes);
            }
            spine = next;
        }
        Bvh { nodes, triangles }
    }

    #[test]
    fn the_deepest_tree_fits_the_kernels_stack() {
        let spine = deepest_spine();
        let g = GpuBvh::new(&spine);
        let depth = deepest_stack(&g, 0);
        assert!(
            depth + 8 > WIDE_STACK_SIZE && depth < WIDE_STACK_SIZE,
            "{depth}"
        );
        // A ray along the z axis enters every box and meets no triangle: the kernel's walk
        // (its CPU copy checks the stack on every push) visits every node.
        let ray = Ray::new(Vec3::new(0.01, 0.01, -1.0), Vec3::Z);
        assert_eq!(gpu_closest_hit(&g, &ray, false), None);
        assert!(deepest_stack(&GpuBvh::new(&default_bvh()), 0) < WIDE_STACK_SIZE);
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
        assert_eq!(empty.nodes[0].children[0].reference, LEAF_FLAG);
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
