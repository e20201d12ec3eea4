//! Bounding volume hierarchy: a binned-SAH build into flat arrays, and the CPU traversal over
//! them. [`gpu`] turns the same tree into the GPU kernels' layout (collapsed four-wide, quantized
//! child boxes).
//!
//! Layout:
//! - `nodes[0]` is the root. An interior node's children are `nodes[left_or_first]` and
//!   `nodes[left_or_first + 1]`; each child carries its own box, so a traversal step tests both
//!   children of the node it stands on. A leaf (`triangle_count > 0`) owns
//!   `triangles[left_or_first .. left_or_first + triangle_count]`.
//! - Triangles are stored in leaf order with their vertex positions inline, so a leaf test
//!   touches one contiguous run of memory and needs no index indirection.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

pub mod gpu;

use crate::ray::{intersect_box, intersect_triangle, past, reach, replaces, Ray, TriangleHit};

/// One BVH node, 32 bytes. The GPU reads the tree as [`gpu::GpuNode`]s instead.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub min: [f32; 3],
    /// Interior: index of the first child. Leaf: index of the first triangle.
    pub left_or_first: u32,
    pub max: [f32; 3],
    /// 0 for an interior node.
    pub triangle_count: u32,
}
const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

impl BvhNode {
    pub fn is_leaf(&self) -> bool {
        self.triangle_count > 0
    }

    pub fn min(&self) -> Vec3 {
        Vec3::from_array(self.min)
    }

    pub fn max(&self) -> Vec3 {
        Vec3::from_array(self.max)
    }
}

/// One triangle in leaf order, 48 bytes; the GPU reads these bytes as three `vec4<u32>`
/// (wgsl/bvh.wgsl): `(v0, source_index)`, `(v1, last_in_leaf)`, `(v2, 0)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhTriangle {
    pub v0: [f32; 3],
    /// Index of this triangle in the scene's triangle list.
    pub source_index: u32,
    pub v1: [f32; 3],
    /// [`gpu::LAST_IN_LEAF`] on the last triangle of a leaf in [`gpu::GpuBvh::triangles`];
    /// 0 in the CPU tree, whose nodes count their triangles.
    pub last_in_leaf: u32,
    pub v2: [f32; 3],
    /// Always 0: the kernels OR products with it, a zero the shader compiler cannot see, so
    /// that no driver fuses them into the sums they feed (wgsl/bvh.wgsl `rounded`).
    pub pad2: u32,
}
const _: () = assert!(std::mem::size_of::<BvhTriangle>() == 48);

impl BvhTriangle {
    pub fn vertices(&self) -> [Vec3; 3] {
        [
            Vec3::from_array(self.v0),
            Vec3::from_array(self.v1),
            Vec3::from_array(self.v2),
        ]
    }
}

/// Deepest traversal stack any tree from [`Bvh::build`] needs (the build stops splitting before).
pub const STACK_SIZE: usize = 64;
/// SAH bins per axis.
const BINS: usize = 16;
/// Leaves never hold more triangles than this unless the triangles cannot be separated.
const MAX_LEAF_TRIANGLES: u32 = 4;
/// Cost of one traversal step (two child boxes) in units of one triangle test, for the SAH.
/// At 0 nearly every node of two triangles split, leaving one-triangle leaves and twice the
/// interior nodes to walk through; higher values keep small clusters of triangles whose boxes
/// overlap in one leaf (never more than `MAX_LEAF_TRIANGLES`). 1 made the CPU packet
/// traversal 15% faster than 0 on the dragon; 3, once ties between triangles no longer
/// depended on the tree, about 2–5% faster again (docs/performance.md).
const TRAVERSAL_COST: f32 = 3.0;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub triangles: Vec<BvhTriangle>,
}

#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: Vec3,
    max: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    fn grow(&mut self, other: &Aabb) {
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    fn grow_point(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    fn half_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

struct BuildTask {
    node: usize,
    first: usize,
    count: usize,
    depth: usize,
}

impl Bvh {
    /// Builds the tree over `triangles` (indices into `positions`) with the surface area
    /// heuristic evaluated on `BINS` centroid bins per axis.
    pub fn build(positions: &[Vec3], triangles: &[[u32; 3]]) -> Bvh {
        if triangles.is_empty() {
            return Bvh::default();
        }
        let bounds: Vec<Aabb> = triangles
            .iter()
            .map(|t| {
                let mut b = Aabb::EMPTY;
                for &i in t {
                    b.grow_point(positions[i as usize]);
                }
                b
            })
            .collect();
        let centroids: Vec<Vec3> = bounds.iter().map(|b| (b.min + b.max) * 0.5).collect();
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();

        let mut nodes = vec![BvhNode::default()];
        let mut tasks = vec![BuildTask {
            node: 0,
            first: 0,
            count: triangles.len(),
            depth: 0,
        }];
        while let Some(task) = tasks.pop() {
            let range = task.first..task.first + task.count;
            let mut node_bounds = Aabb::EMPTY;
            let mut centroid_bounds = Aabb::EMPTY;
            for &t in &order[range.clone()] {
                node_bounds.grow(&bounds[t as usize]);
                centroid_bounds.grow_point(centroids[t as usize]);
            }
            let node = &mut nodes[task.node];
            node.min = node_bounds.min.to_array();
            node.max = node_bounds.max.to_array();

            let split = if task.depth + 1 >= STACK_SIZE {
                None
            } else {
                choose_split(&order[range.clone()], &bounds, &centroids, &centroid_bounds).filter(
                    |s| {
                        task.count > MAX_LEAF_TRIANGLES as usize
                            || s.cost + node_bounds.half_area() * TRAVERSAL_COST
                                < node_bounds.half_area() * task.count as f32
                    },
                )
            };
            let left_count = match split {
                Some(s) => partition(&mut order[range.clone()], |t| {
                    bin_of(centroids[t as usize], &centroid_bounds, s.axis) < s.bin
                }),
                // Unsplittable by centroid but too big: halve by order so leaves stay small.
                None if task.count > MAX_LEAF_TRIANGLES as usize && task.depth + 1 < STACK_SIZE => {
                    task.count / 2
                }
                None => 0,
            };
            if left_count == 0 || left_count == task.count {
                node.left_or_first = task.first as u32;
                node.triangle_count = task.count as u32;
                continue;
            }
            let left = nodes.len();
            nodes[task.node].left_or_first = left as u32;
            nodes.push(BvhNode::default());
            nodes.push(BvhNode::default());
            tasks.push(BuildTask {
                node: left,
                first: task.first,
                count: left_count,
                depth: task.depth + 1,
            });
            tasks.push(BuildTask {
                node: left + 1,
                first: task.first + left_count,
                count: task.count - left_count,
                depth: task.depth + 1,
            });
        }

        let triangles = order
            .iter()
            .map(|&t| {
                let [a, b, c] = triangles[t as usize];
                BvhTriangle {
                    v0: positions[a as usize].to_array(),
                    source_index: t,
                    v1: positions[b as usize].to_array(),
                    last_in_leaf: 0,
                    v2: positions[c as usize].to_array(),
                    pad2: 0,
                }
            })
            .collect();
        Bvh { nodes, triangles }
    }

    /// Extent of the whole scene: the largest side of the root box.
    pub fn extent(&self) -> f32 {
        self.nodes
            .first()
            .map(|root| (root.max() - root.min()).max_element())
            .unwrap_or(0.0)
    }

    /// The nodes whose boxes hold `point`, from the root down ([`PointPath`]). Where both
    /// children hold it, the path takes the one whose centre is nearer, as fan walks do.
    pub fn path_to(&self, point: Vec3) -> PointPath {
        let p = point.to_array();
        let mut path = PointPath {
            point,
            ..PointPath::NONE
        };
        match self.nodes.first() {
            Some(root) if holds(root, p) => {}
            _ => return path,
        }
        let mut node = 0;
        loop {
            let n = &self.nodes[node as usize];
            if n.is_leaf() {
                break;
            }
            let (left, right) = (n.left_or_first, n.left_or_first + 1);
            let (l, r) = (&self.nodes[left as usize], &self.nodes[right as usize]);
            let centre_distance = |n: &BvhNode| (n.min() + n.max() - 2.0 * point).length_squared();
            let (next, sibling) = match (holds(l, p), holds(r, p)) {
                (true, true) if centre_distance(r) < centre_distance(l) => (right, left),
                (true, _) => (left, right),
                (false, true) => (right, left),
                (false, false) => break,
            };
            path.siblings[path.sibling_count] = sibling;
            path.sibling_count += 1;
            node = next;
        }
        path.deepest = Some(node);
        path
    }

    /// Any-hit query: does anything block the ray on `(0, t_max)`?
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let mut hit = false;
        self.traverse(ray, t_max, |_, _| {
            hit = true;
            (true, 0.0, 0.0)
        });
        hit
    }

    /// Closest-hit query: the nearest triangle (scene index) on `(0, t_max)` and where it is hit;
    /// of triangles at the same distance, the first in the scene ([`crate::ray::replaces`]).
    pub fn closest_hit(&self, ray: &Ray, t_max: f32) -> Option<(u32, TriangleHit)> {
        let mut best: Option<(u32, TriangleHit)> = None;
        self.traverse(ray, t_max, |triangle, hit| {
            let closest = match best {
                Some((i, b)) if !replaces(hit.t, triangle, b.t, i) => b.t,
                _ => {
                    best = Some((triangle, hit));
                    hit.t
                }
            };
            (false, past(closest), reach(closest))
        });
        best
    }

    /// Stack traversal shared by both queries. `on_hit(scene index, hit)`
    /// returns (stop, new t_max of the triangle tests, new t_max of the box tests).
    fn traverse(
        &self,
        ray: &Ray,
        mut t_max: f32,
        mut on_hit: impl FnMut(u32, TriangleHit) -> (bool, f32, f32),
    ) {
        let mut box_t_max = t_max;
        let Some(root) = self.nodes.first() else {
            return;
        };
        if intersect_box(ray, root.min(), root.max(), 0.0, t_max).is_none() {
            return;
        }
        let mut stack = [0u32; STACK_SIZE];
        let mut stack_len = 0;
        let mut node = root;
        loop {
            if node.is_leaf() {
                let first = node.left_or_first as usize;
                for tri in &self.triangles[first..][..node.triangle_count as usize] {
                    let [v0, v1, v2] = tri.vertices();
                    if let Some(hit) = intersect_triangle(ray, v0, v1, v2, 0.0, t_max) {
                        let stop;
                        (stop, t_max, box_t_max) = on_hit(tri.source_index, hit);
                        if stop {
                            return;
                        }
                    }
                }
            } else {
                let left = &self.nodes[node.left_or_first as usize];
                let right = &self.nodes[node.left_or_first as usize + 1];
                let t_left = intersect_box(ray, left.min(), left.max(), 0.0, box_t_max);
                let t_right = intersect_box(ray, right.min(), right.max(), 0.0, box_t_max);
                match (t_left, t_right) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b {
                            (left, node.left_or_first + 1)
                        } else {
                            (right, node.left_or_first)
                        };
                        stack[stack_len] = far;
                        stack_len += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if stack_len == 0 {
                return;
            }
            stack_len -= 1;
            node = &self.nodes[stack[stack_len] as usize];
        }
    }
}

/// The nodes whose boxes hold one point, from the root down: where every ray from that point
/// enters the tree. A ray that starts inside a box meets it (`ray::intersect_box` gives it
/// entry 0 and a non-negative exit, whatever its direction), so a walk of rays from the point
/// can start at the deepest of these nodes with the other children along the way waiting on its
/// stack, instead of testing its way down from the root one dependent step at a time.
#[derive(Clone, Debug)]
pub struct PointPath {
    point: Vec3,
    /// The deepest node holding the point; `None` where the root does not hold it.
    deepest: Option<u32>,
    /// The other child at each step down, the shallowest first.
    siblings: [u32; STACK_SIZE],
    sibling_count: usize,
}

impl PointPath {
    /// No path: a walk starts at the root and tests it.
    pub const NONE: PointPath = PointPath {
        point: Vec3::ZERO,
        deepest: None,
        siblings: [0; STACK_SIZE],
        sibling_count: 0,
    };

    pub fn deepest(&self) -> Option<u32> {
        self.deepest
    }

    /// Whether a walk from `point` may start down this path: it leads to `point`, or it is
    /// no path at all.
    pub fn leads_to(&self, point: Vec3) -> bool {
        self.deepest.is_none() || self.point == point
    }

    /// The other child at each step down to [`PointPath::deepest`], the shallowest first.
    pub fn siblings(&self) -> &[u32] {
        &self.siblings[..self.sibling_count]
    }
}

/// Whether `point` lies in the node's box, boundary included. Where it does, `bound - point` is
/// `<= 0` on the low side and `>= 0` on the high side exactly, which is what makes every ray
/// from the point meet the box.
fn holds(node: &BvhNode, point: [f32; 3]) -> bool {
    (0..3).all(|axis| node.min[axis] <= point[axis] && point[axis] <= node.max[axis])
}

#[derive(Clone, Copy, Debug)]
struct Split {
    axis: usize,
    /// Triangles in bins `< bin` go left.
    bin: usize,
    cost: f32,
}

fn bin_of(centroid: Vec3, centroid_bounds: &Aabb, axis: usize) -> usize {
    let lo = centroid_bounds.min[axis];
    let extent = centroid_bounds.max[axis] - lo;
    let b = ((centroid[axis] - lo) / extent * BINS as f32) as usize;
    b.min(BINS - 1)
}

/// The cheapest bin boundary over all axes by the SAH, `None` if the centroids coincide.
fn choose_split(
    triangles: &[u32],
    bounds: &[Aabb],
    centroids: &[Vec3],
    centroid_bounds: &Aabb,
) -> Option<Split> {
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        if centroid_bounds.max[axis] <= centroid_bounds.min[axis] {
            continue;
        }
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0u32; BINS];
        for &t in triangles {
            let b = bin_of(centroids[t as usize], centroid_bounds, axis);
            bin_bounds[b].grow(&bounds[t as usize]);
            bin_counts[b] += 1;
        }
        // Sweep from the right to get the cost of every right side, then from the left.
        let mut right_cost = [0.0f32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut count = 0;
        for b in (1..BINS).rev() {
            acc.grow(&bin_bounds[b]);
            count += bin_counts[b];
            right_cost[b] = if count > 0 {
                acc.half_area() * count as f32
            } else {
                0.0
            };
        }
        let mut acc = Aabb::EMPTY;
        let mut count = 0;
        for b in 1..BINS {
            acc.grow(&bin_bounds[b - 1]);
            count += bin_counts[b - 1];
            if count == 0 || count as usize == triangles.len() {
                continue;
            }
            let cost = acc.half_area() * count as f32 + right_cost[b];
            if best.is_none_or(|s| cost < s.cost) {
                best = Some(Split { axis, bin: b, cost });
            }
        }
    }
    best
}

/// Moves the items for which `goes_left` holds to the front; returns how many there are.
fn partition(items: &mut [u32], goes_left: impl Fn(u32) -> bool) -> usize {
    let mut left = 0;
    for i in 0..items.len() {
        if goes_left(items[i]) {
            items.swap(i, left);
            left += 1;
        }
    }
    left
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    fn random_soup(count: usize, seed: u64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut rng = Pcg32::new(seed);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for i in 0..count as u32 {
            let c = Vec3::new(r(), r(), r()) * 10.0;
            for _ in 0..3 {
                positions.push(c + Vec3::new(r(), r(), r()) * 0.5);
            }
            triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        (positions, triangles)
    }

    fn brute_closest(positions: &[Vec3], triangles: &[[u32; 3]], ray: &Ray) -> Option<(u32, f32)> {
        let mut best: Option<(u32, f32)> = None;
        for (i, t) in triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| positions[v as usize]);
            if let Some(hit) = intersect_triangle(ray, a, b, c, 0.0, f32::INFINITY) {
                if best.is_none_or(|(_, t)| hit.t < t) {
                    best = Some((i as u32, hit.t));
                }
            }
        }
        best
    }

    /// The path to a point: each node on it holds the point, each sibling is the other child
    /// of the node above, and the walk stops at a leaf or where no child holds the point.
    #[test]
    fn a_point_path_holds_the_point_down_to_where_no_child_does() {
        let (positions, triangles) = random_soup(3000, 2);
        let bvh = Bvh::build(&positions, &triangles);
        let mut rng = Pcg32::new(5);
        let mut lengths = Vec::new();
        for i in 0..500 {
            // Half the points on triangles' corners (inside several boxes), half anywhere.
            let point = match i % 2 {
                0 => positions[rng.next_u32() as usize % positions.len()],
                _ => Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 24.0 - 12.0,
            };
            let path = bvh.path_to(point);
            let p = point.to_array();
            let Some(deepest) = path.deepest() else {
                assert!(!holds(&bvh.nodes[0], p), "the root holds {point}");
                continue;
            };
            assert!(path.leads_to(point) && !path.leads_to(point + Vec3::X));
            // Climb back up from the deepest node through the siblings.
            let mut node = deepest;
            for &sibling in path.siblings().iter().rev() {
                assert!(holds(&bvh.nodes[node as usize], p));
                let pair = node.min(sibling);
                assert_eq!(
                    node.max(sibling),
                    pair + 1,
                    "siblings are a node's two children"
                );
                let parent = bvh
                    .nodes
                    .iter()
                    .position(|n| !n.is_leaf() && n.left_or_first == pair);
                node = parent.expect("a parent") as u32;
            }
            assert_eq!(node, 0, "the path starts at the root");
            let bottom = &bvh.nodes[deepest as usize];
            if !bottom.is_leaf() {
                let first = bottom.left_or_first as usize;
                assert!(!holds(&bvh.nodes[first], p) && !holds(&bvh.nodes[first + 1], p));
            }
            lengths.push(path.siblings().len());
        }
        assert!(
            lengths.iter().filter(|&&n| n > 5).count() > 100,
            "{lengths:?}"
        );
    }

    #[test]
    fn every_triangle_sits_in_exactly_one_leaf_inside_its_boxes() {
        let (positions, triangles) = random_soup(3000, 1);
        let bvh = Bvh::build(&positions, &triangles);
        let mut seen = vec![0u32; triangles.len()];
        // Walk the tree, checking that children lie inside parents and leaves cover triangles.
        let mut stack = vec![(0usize, 0usize)];
        let mut max_depth = 0;
        while let Some((n, depth)) = stack.pop() {
            max_depth = max_depth.max(depth);
            let node = bvh.nodes[n];
            if node.is_leaf() {
                assert!(node.triangle_count <= MAX_LEAF_TRIANGLES);
                let first = node.left_or_first as usize;
                for tri in &bvh.triangles[first..first + node.triangle_count as usize] {
                    seen[tri.source_index as usize] += 1;
                    for v in tri.vertices() {
                        assert!(v.cmpge(node.min()).all() && v.cmple(node.max()).all());
                    }
                }
            } else {
                for child in [node.left_or_first as usize, node.left_or_first as usize + 1] {
                    let c = bvh.nodes[child];
                    assert!(c.min().cmpge(node.min()).all() && c.max().cmple(node.max()).all());
                    stack.push((child, depth + 1));
                }
            }
        }
        assert!(
            seen.iter().all(|&c| c == 1),
            "a triangle is missing or repeated"
        );
        assert!(max_depth < STACK_SIZE);
    }

    #[test]
    fn queries_agree_with_brute_force() {
        let (positions, triangles) = random_soup(2000, 2);
        let bvh = Bvh::build(&positions, &triangles);
        let mut rng = Pcg32::new(3);
        let mut hits = 0;
        for _ in 0..5000 {
            let mut r = || rng.next_f32() * 2.0 - 1.0;
            let origin = Vec3::new(r(), r(), r()) * 12.0;
            let dir = Vec3::new(r(), r(), r()).normalize_or(Vec3::X);
            let ray = Ray::new(origin, dir);
            let expected = brute_closest(&positions, &triangles, &ray);
            let got = bvh.closest_hit(&ray, f32::INFINITY);
            assert_eq!(got.map(|(t, h)| (t, h.t)), expected);
            assert_eq!(bvh.occluded(&ray, f32::INFINITY), expected.is_some());
            hits += expected.is_some() as u32;
        }
        assert!(hits > 500, "too few hits ({hits}) to test anything");
    }

    #[test]
    fn coincident_centroids_still_give_small_leaves() {
        // 100 identical triangles: no SAH split exists, the build must still terminate.
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let triangles = vec![[0, 1, 2]; 100];
        let bvh = Bvh::build(&positions, &triangles);
        assert_eq!(bvh.triangles.len(), 100);
        assert!(bvh
            .nodes
            .iter()
            .all(|n| n.triangle_count <= MAX_LEAF_TRIANGLES));
        let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z);
        assert!(bvh.occluded(&ray, f32::INFINITY));
        // All 100 at one distance: the closest is the first in the scene.
        let (triangle, _) = bvh.closest_hit(&ray, f32::INFINITY).unwrap();
        assert_eq!(triangle, 0);
    }

    #[test]
    fn ties_go_to_the_first_triangle_of_the_scene_whatever_the_leaf_order() {
        // A strip of 16 unit squares along x in the plane z = 0, listed from +x to -x, so that
        // the build, which puts lower centroids left, stores them the other way round. A ray
        // down onto the edge two squares share meets a triangle of each at t = 1 exactly: the
        // direction's z is -1, so every sheared z is 1 and t is det / det, and the edge's two
        // corners shear to x = 0, so the edge function is 0 in both triangles. (The direction
        // leans in x because a zero component is taken as a tiny one by the box test, which
        // then passes by the boxes whose face the ray runs in.)
        let squares = 16u32;
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for square in (0..squares).rev() {
            let x = square as f32;
            let first = positions.len() as u32;
            positions.extend(
                [(x, 0.0), (x + 1.0, 0.0), (x + 1.0, 1.0), (x, 1.0)]
                    .map(|(x, y)| Vec3::new(x, y, 0.0)),
            );
            // The first holds the square's right edge, the second its left edge.
            triangles.push([first, first + 1, first + 2]);
            triangles.push([first, first + 2, first + 3]);
        }
        let bvh = Bvh::build(&positions, &triangles);
        let leaf_order: Vec<u32> = bvh.triangles.iter().map(|t| t.source_index).collect();
        assert!(
            leaf_order.windows(2).any(|w| w[0] > w[1]),
            "the test needs a leaf order other than the scene's: {leaf_order:?}"
        );
        for edge in 1..squares {
            let ray = Ray::new(
                Vec3::new(edge as f32 - 0.5, 0.3, 1.0),
                Vec3::new(0.5, 0.0, -1.0),
            );
            let (triangle, hit) = bvh.closest_hit(&ray, f32::INFINITY).unwrap();
            assert_eq!(hit.t, 1.0);
            // The left edge of square `edge` (listed earlier) and the right edge of the square
            // before it.
            let left_edge_of_square = 2 * (squares - 1 - edge) + 1;
            assert_eq!(triangle, left_edge_of_square, "edge {edge}");
        }
    }

    #[test]
    fn empty_tree_blocks_nothing() {
        let bvh = Bvh::build(&[], &[]);
        assert!(!bvh.occluded(&Ray::new(Vec3::ZERO, Vec3::X), f32::INFINITY));
    }
}
