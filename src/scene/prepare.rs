//! Turns a [`Scene`] as loaded into the scene that is baked: validated, free of degenerate
//! triangles and unreferenced vertices, welded, with unit normals, vertices in Morton order.
//!
//! Every step is a pure function of its input, so the prepared scene (and therefore the bake)
//! does not depend on hash-map iteration order or thread count.

use std::collections::HashMap;

use glam::{DVec3, Vec3};

use super::Scene;
use crate::error::{Error, Result};

/// What `prepare` did, for the CLI to report.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PrepareReport {
    pub input_vertices: usize,
    pub input_triangles: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub degenerate_triangles_removed: usize,
    pub unreferenced_vertices_removed: usize,
    /// Vertices merged into an identical one (same position and attributes).
    pub vertices_welded: usize,
    /// Normals were computed here (the input had none, or had unusable ones).
    pub normals_computed: bool,
    /// The input had normals, but some were non-finite or zero, so all were recomputed.
    pub invalid_normals_replaced: bool,
    /// Triangles folded back onto all their neighbours, left out of the computed normals
    /// ([`angle_weighted_normals`]).
    pub folded_triangles: usize,
}

impl PrepareReport {
    /// What `prepare` repaired, in one line for a warning; `None` when it repaired nothing.
    /// Welding and computing missing normals are how every OBJ and PLY is read, not repairs.
    pub fn repairs(&self) -> Option<String> {
        let counted = [
            (
                self.degenerate_triangles_removed,
                "degenerate triangles dropped",
            ),
            (
                self.unreferenced_vertices_removed,
                "unreferenced vertices dropped",
            ),
            (
                self.folded_triangles,
                "folded triangles left out of the vertex normals",
            ),
        ];
        let mut said: Vec<String> = counted
            .iter()
            .filter(|(count, _)| *count > 0)
            .map(|(count, what)| format!("{count} {what}"))
            .collect();
        if self.invalid_normals_replaced {
            said.push("non-finite or zero normals: all normals recomputed".into());
        }
        (!said.is_empty()).then(|| format!("repaired the mesh: {}", said.join(", ")))
    }
}

/// Validates and repairs `scene` for baking.
///
/// Errors (never repaired, because any repair would be a guess): no vertices, no triangles,
/// non-finite positions or albedo, out-of-range indices, attribute arrays whose length differs
/// from the vertex count, and meshes whose triangles are all degenerate.
///
/// Repairs (counted in the report): degenerate triangles are dropped, unreferenced vertices
/// are dropped, identical vertices are welded, missing or unusable normals are computed
/// (angle-weighted), and vertices are reordered along a Morton curve for ray coherence.
/// Triangle order is kept.
pub fn prepare(scene: Scene) -> Result<(Scene, PrepareReport)> {
    prepare_mapped(scene).map(|(scene, report, _)| (scene, report))
}

/// Where each input vertex went: its index in the prepared scene, or [`DROPPED`].
pub type VertexMap = Vec<u32>;

/// An input vertex that is in no prepared triangle (unreferenced, or only in degenerate
/// triangles): it has no prepared vertex.
pub const DROPPED: u32 = u32::MAX;

/// [`prepare`], and for every input vertex the prepared vertex it became (welded vertices share
/// one), so that values computed on the prepared scene can be scattered back to the input's
/// own vertices (bake in place).
pub fn prepare_mapped(scene: Scene) -> Result<(Scene, PrepareReport, VertexMap)> {
    validate(&scene)?;
    let mut report = PrepareReport {
        input_vertices: scene.positions.len(),
        input_triangles: scene.triangles.len(),
        ..PrepareReport::default()
    };

    let scene = remove_degenerate_triangles(scene, &mut report)?;
    let (scene, referenced) = remove_unreferenced_vertices(scene, &mut report);
    let (scene, welded) = match usable_normals(&scene) {
        Some(normals) => weld_with_normals(scene, normals),
        None => {
            report.invalid_normals_replaced = scene.normals.is_some();
            report.normals_computed = true;
            let (scene, welded, folded) = weld_and_compute_normals(scene)?;
            report.folded_triangles = folded;
            (scene, welded)
        }
    };
    report.vertices_welded =
        report.input_vertices - report.unreferenced_vertices_removed - scene.positions.len();
    let (scene, sorted) = sort_vertices_morton(scene);

    report.vertices = scene.positions.len();
    report.triangles = scene.triangles.len();
    let map = compose(&compose(&referenced, &welded), &sorted);
    Ok((scene, report, map))
}

/// The map of `first` then `second`.
fn compose(first: &[u32], second: &[u32]) -> VertexMap {
    first
        .iter()
        .map(|&i| {
            if i == DROPPED {
                DROPPED
            } else {
                second[i as usize]
            }
        })
        .collect()
}

/// Per-vertex normals as the sum of adjacent unit face normals, each weighted by the
/// triangle's interior angle at the vertex, normalized.
///
/// Angle weighting makes the result independent of how a flat region is triangulated (a cube
/// corner gets (1,1,1)/√3 whether each face touches it with one triangle or two). Sums are
/// taken in f64. A *folded* triangle — one whose normal opposes that of every triangle it
/// shares an edge with, as the slivers a scanner's reconstruction folds back onto the surface
/// — is left out of its corners' sums: it would tip them into the surface, and a receiver
/// whose hemisphere faces into the surface sees no sky. Where the sum cancels (e.g. two
/// coincident triangles of opposite winding) the vertex takes the normal of its first adjacent
/// non-degenerate triangle. Vertices with no adjacent non-degenerate triangle get `Vec3::ZERO`;
/// triangles with out-of-range indices are ignored.
pub fn angle_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    normals_without_folds(positions, triangles).0
}

/// The scene with hard edges, as auto-smooth by angle makes them: each corner of a face takes
/// the angle-weighted normal of the faces around its position whose normals lie within
/// `crease_degrees` of its own face's, and a vertex becomes one copy per normal its corners
/// take. A room's 90-degree edge stays hard below a threshold of 90 degrees while the facets
/// of a tessellated ball, a few degrees apart, stay smooth; faces that meet back to back (a
/// table top on its leg, a floor under a wall) no longer share a normal. A corner of a
/// zero-area face takes the smooth normal of all faces around it.
pub fn split_creases(scene: &Scene, crease_degrees: f64) -> Scene {
    let positions = &scene.positions;
    let same_position = first_with_same_key(positions.iter().map(|&p| key(p)));
    let faces: Vec<Option<Face>> = scene
        .triangles
        .iter()
        .map(|t| corner_positions(positions, t).and_then(face_normal_and_angles))
        .collect();
    let mut around: Vec<Vec<(u32, usize)>> = vec![Vec::new(); positions.len()];
    for (t, triangle) in scene.triangles.iter().enumerate() {
        if faces[t].is_some() {
            for (corner, &v) in triangle.iter().enumerate() {
                around[same_position[v as usize] as usize].push((t as u32, corner));
            }
        }
    }
    let cos = crease_degrees.to_radians().cos();
    let corner_normal = |t: usize, v: u32| -> Vec3 {
        let own = faces[t].as_ref().map(|f| f.normal);
        let sum: DVec3 = around[same_position[v as usize] as usize]
            .iter()
            .filter_map(|&(g, corner)| {
                let face = faces[g as usize].as_ref()?;
                let within = own.is_none_or(|n| face.normal.dot(n) >= cos);
                within.then(|| face.normal * face.angles[corner])
            })
            .sum();
        sum.try_normalize().unwrap_or(DVec3::Z).as_vec3()
    };
    let mut split = Scene::default();
    let mut normals = Vec::new();
    let mut copies: HashMap<(u32, [u32; 3]), u32> = HashMap::new();
    for (t, triangle) in scene.triangles.iter().enumerate() {
        let corners = triangle.map(|v| {
            let normal = corner_normal(t, v);
            *copies.entry((v, key(normal))).or_insert_with(|| {
                split.positions.push(positions[v as usize]);
                split.albedo.push(scene.albedo[v as usize]);
                normals.push(normal);
                split.positions.len() as u32 - 1
            })
        });
        split.triangles.push(corners);
    }
    split.normals = Some(normals);
    split
}

/// [`angle_weighted_normals`] and the number of folded triangles left out of them.
pub fn normals_without_folds(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<Vec3>, usize) {
    // Faces are recomputed in each pass rather than kept: a few products each, where keeping
    // them would cost 56 bytes a triangle on meshes of millions.
    let face = |triangle: &[u32; 3]| {
        corner_positions(positions, triangle).and_then(face_normal_and_angles)
    };
    let mut sums = vec![NormalSum::default(); positions.len()];
    for triangle in triangles {
        if let Some(face) = face(triangle) {
            for (&index, &angle) in triangle.iter().zip(&face.angles) {
                sums[index as usize].add(face.normal, angle);
            }
        }
    }
    let folded = folded_faces(triangles, face, &sums);
    // Only the corners of folded faces change: sum them again without those faces, unless a
    // corner has no other face.
    let mut refolded: HashMap<u32, NormalSum> = HashMap::new();
    for &f in &folded {
        for &index in &triangles[f] {
            refolded.entry(index).or_default();
        }
    }
    if !refolded.is_empty() {
        for (f, triangle) in triangles.iter().enumerate() {
            if folded.binary_search(&f).is_ok() {
                continue;
            }
            let Some(face) = face(triangle) else { continue };
            for (index, &angle) in triangle.iter().zip(&face.angles) {
                if let Some(sum) = refolded.get_mut(index) {
                    sum.add(face.normal, angle);
                }
            }
        }
        for (index, sum) in refolded {
            if sum.first.is_some() {
                sums[index as usize] = sum;
            }
        }
    }
    (sums.iter().map(NormalSum::resolve).collect(), folded.len())
}

/// A triangle's unit normal and its interior angle at each corner.
struct Face {
    normal: DVec3,
    angles: [f64; 3],
}

/// The angle-weighted sum of a vertex's face normals.
#[derive(Clone, Copy, Debug, Default)]
struct NormalSum {
    sum: DVec3,
    weight: f64,
    first: Option<DVec3>,
}

impl NormalSum {
    fn add(&mut self, normal: DVec3, angle: f64) {
        self.sum += normal * angle;
        self.weight += angle;
        self.first.get_or_insert(normal);
    }

    fn resolve(&self) -> Vec3 {
        match self.first {
            None => Vec3::ZERO,
            Some(_) if self.sum.length() > CANCELLED_SUM * self.weight => {
                self.sum.normalize().as_vec3()
            }
            Some(fallback) => fallback.as_vec3(),
        }
    }
}

/// Cancellation threshold: a sum shorter than this fraction of its total weight carries no
/// direction beyond rounding noise.
const CANCELLED_SUM: f64 = 1e-9;

/// The faces (ascending) whose normal opposes the normal of every face sharing one of its
/// edges. Only faces that oppose the summed normal at one of their corners can be folded, so
/// only those are examined, and adjacency is gathered only around them: a clean mesh costs one
/// pass and no memory.
fn folded_faces(
    triangles: &[[u32; 3]],
    face: impl Fn(&[u32; 3]) -> Option<Face>,
    sums: &[NormalSum],
) -> Vec<usize> {
    let normal = |f: usize| face(&triangles[f]).map(|face| face.normal);
    let opposes_a_corner = |triangle: &[u32; 3], normal: DVec3| {
        triangle
            .iter()
            .any(|&v| sums[v as usize].sum.dot(normal) < 0.0)
    };
    let candidates: Vec<usize> = (0..triangles.len())
        .filter(|&f| normal(f).is_some_and(|n| opposes_a_corner(&triangles[f], n)))
        .collect();
    if candidates.is_empty() {
        return Vec::new();
    }
    let mut around: HashMap<u32, Vec<usize>> = HashMap::new();
    for &f in &candidates {
        for &v in &triangles[f] {
            around.entry(v).or_default();
        }
    }
    for (f, triangle) in triangles.iter().enumerate() {
        if triangle.iter().any(|v| around.contains_key(v)) && normal(f).is_some() {
            for v in triangle {
                if let Some(incident) = around.get_mut(v) {
                    incident.push(f);
                }
            }
        }
    }
    candidates
        .into_iter()
        .filter(|&f| {
            let own = normal(f).unwrap_or(DVec3::ZERO);
            let triangle = triangles[f];
            let mut neighbours = (0..3)
                .flat_map(|e| {
                    let (a, b) = (triangle[e], triangle[(e + 1) % 3]);
                    around[&a]
                        .iter()
                        .filter(move |&&g| g != f && triangles[g].contains(&b))
                })
                .peekable();
            neighbours.peek().is_some()
                && neighbours.all(|&g| normal(g).is_some_and(|n| n.dot(own) < 0.0))
        })
        .collect()
}

fn corner_positions(positions: &[Vec3], triangle: &[u32; 3]) -> Option<[DVec3; 3]> {
    let corner = |i: u32| positions.get(i as usize).map(|p| p.as_dvec3());
    Some([
        corner(triangle[0])?,
        corner(triangle[1])?,
        corner(triangle[2])?,
    ])
}

/// Unit normal and the interior angle at each corner; `None` for zero area.
fn face_normal_and_angles([a, b, c]: [DVec3; 3]) -> Option<Face> {
    let cross = (b - a).cross(c - a);
    let double_area = cross.length();
    if !(double_area > 0.0 && double_area.is_finite()) {
        return None;
    }
    // atan2(|u×v|, u·v) stays accurate for angles near 0 and π, where acos of a dot does not;
    // |u×v| is twice the area whichever corner it is taken at.
    let angle = |apex: DVec3, p: DVec3, q: DVec3| double_area.atan2((p - apex).dot(q - apex));
    Some(Face {
        normal: cross / double_area,
        angles: [angle(a, b, c), angle(b, c, a), angle(c, a, b)],
    })
}

fn validate(scene: &Scene) -> Result<()> {
    let n = scene.positions.len();
    if n == 0 {
        return Err(Error::Geometry("mesh has no vertices".into()));
    }
    if scene.triangles.is_empty() {
        return Err(Error::Geometry("mesh has no triangles".into()));
    }
    if scene.albedo.len() != n {
        return Err(Error::Geometry(format!(
            "albedo has {} entries for {n} vertices",
            scene.albedo.len()
        )));
    }
    if let Some(normals) = &scene.normals {
        if normals.len() != n {
            return Err(Error::Geometry(format!(
                "normals have {} entries for {n} vertices",
                normals.len()
            )));
        }
    }
    if let Some(i) = scene.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::Geometry(format!(
            "vertex {i} has a non-finite position {}",
            show(scene.positions[i])
        )));
    }
    if let Some(i) = scene.albedo.iter().position(|a| !a.is_finite()) {
        return Err(Error::Geometry(format!(
            "vertex {i} has a non-finite albedo {}",
            show(scene.albedo[i])
        )));
    }
    check_indices(&scene.triangles, n)
}

fn check_indices(triangles: &[[u32; 3]], vertex_count: usize) -> Result<()> {
    for (t, triangle) in triangles.iter().enumerate() {
        if let Some(&bad) = triangle.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(Error::Geometry(format!(
                "triangle {t} refers to vertex {bad}, but there are only {vertex_count} vertices"
            )));
        }
    }
    Ok(())
}

fn show(v: Vec3) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}

fn remove_degenerate_triangles(mut scene: Scene, report: &mut PrepareReport) -> Result<Scene> {
    let before = scene.triangles.len();
    let positions = &scene.positions;
    scene.triangles.retain(|t| !is_degenerate(t, positions));
    report.degenerate_triangles_removed = before - scene.triangles.len();
    if scene.triangles.is_empty() {
        return Err(Error::Geometry(format!(
            "all {before} triangles are degenerate"
        )));
    }
    Ok(scene)
}

/// Per triangle of `scene`, whether `prepare` keeps it: it drops the degenerate ones and keeps
/// the rest in order, so that values given per input triangle can follow it. A triangle with
/// an index out of range counts as dropped (`prepare` refuses such a scene).
pub fn kept_triangles(scene: &Scene) -> Vec<bool> {
    let n = scene.positions.len() as u32;
    scene
        .triangles
        .iter()
        .map(|t| t.iter().all(|&i| i < n) && !is_degenerate(t, &scene.positions))
        .collect()
}

fn is_degenerate(&[i, j, k]: &[u32; 3], positions: &[Vec3]) -> bool {
    i == j
        || j == k
        || k == i
        || cross_is_exactly_zero(
            positions[i as usize],
            positions[j as usize],
            positions[k as usize],
        )
}

/// Decides exactly (no rounding) whether the three points are collinear.
///
/// (b−a)×(c−a) = a×b + b×c + c×a. Each component of the right side is a sum of six
/// products of two f32 values; such a product is exact in f64 (48-bit mantissa, exponent
/// well in range), and the sum is evaluated exactly as a floating-point expansion. A plain
/// f64 cross product could round a truly collinear triangle to a tiny non-zero normal
/// pointing anywhere, which would then be weighted by an interior angle of π.
fn cross_is_exactly_zero(a: Vec3, b: Vec3, c: Vec3) -> bool {
    let [a, b, c] = [a, b, c].map(|p| p.to_array().map(f64::from));
    (0..3).all(|k| {
        // Component k of p×q is p[i]q[j] − p[j]q[i], with (i, j) the next two axes.
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let terms = [(a, b), (b, c), (c, a)]
            .into_iter()
            .flat_map(|(p, q)| [p[i] * q[j], -(p[j] * q[i])]);
        exact_sum_is_zero(terms)
    })
}

/// Shewchuk's grow-expansion: after each step the components sum exactly to the terms added
/// so far and do not overlap, so the sum is zero exactly when every component is zero.
fn exact_sum_is_zero(terms: impl IntoIterator<Item = f64>) -> bool {
    let mut expansion: Vec<f64> = Vec::new();
    for term in terms {
        let mut carry = term;
        let mut next = Vec::with_capacity(expansion.len() + 1);
        for &component in &expansion {
            let (sum, error) = two_sum(carry, component);
            if error != 0.0 {
                next.push(error);
            }
            carry = sum;
        }
        next.push(carry);
        expansion = next;
    }
    expansion.iter().all(|&c| c == 0.0)
}

/// Knuth's error-free addition: `sum + error == a + b` exactly.
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let sum = a + b;
    let b_virtual = sum - a;
    let a_virtual = sum - b_virtual;
    (sum, (a - a_virtual) + (b - b_virtual))
}

/// Keeps only referenced vertices, in their original relative order.
fn remove_unreferenced_vertices(scene: Scene, report: &mut PrepareReport) -> (Scene, VertexMap) {
    let mut referenced = vec![false; scene.positions.len()];
    for &i in scene.triangles.iter().flatten() {
        referenced[i as usize] = true;
    }
    let kept: Vec<u32> = (0..scene.positions.len() as u32)
        .filter(|&i| referenced[i as usize])
        .collect();
    report.unreferenced_vertices_removed = scene.positions.len() - kept.len();
    select_vertices(&scene, &kept, |old| old)
}

/// Builds the scene made of the vertices `kept` (old indices, in new order); a triangle
/// index `i` becomes the new index of `representative(i)`, which must be in `kept` for every
/// referenced `i`. Also returns, for every old vertex, the new index of its representative
/// ([`DROPPED`] where that is not kept).
fn select_vertices(
    scene: &Scene,
    kept: &[u32],
    representative: impl Fn(u32) -> u32,
) -> (Scene, VertexMap) {
    let mut new_index = vec![u32::MAX; scene.positions.len()];
    for (new, &old) in kept.iter().enumerate() {
        new_index[old as usize] = new as u32;
    }
    let pick = |values: &[Vec3]| kept.iter().map(|&i| values[i as usize]).collect::<Vec<_>>();
    let selected = Scene {
        positions: pick(&scene.positions),
        normals: scene.normals.as_deref().map(pick),
        albedo: pick(&scene.albedo),
        triangles: scene
            .triangles
            .iter()
            .map(|t| t.map(|i| new_index[representative(i) as usize]))
            .collect(),
    };
    let map = (0..scene.positions.len() as u32)
        .map(|old| new_index[representative(old) as usize])
        .collect();
    (selected, map)
}

/// The scene's normals, normalized, if every one is finite and non-zero.
fn usable_normals(scene: &Scene) -> Option<Vec<Vec3>> {
    scene
        .normals
        .as_ref()?
        .iter()
        .map(|n| n.try_normalize())
        .collect()
}

/// Bit pattern used as a weld key; -0.0 and +0.0 are the same point, so they share a key.
fn key(v: Vec3) -> [u32; 3] {
    (v + Vec3::ZERO).to_array().map(f32::to_bits)
}

/// For each vertex, the index of the first vertex with the same key (itself if it is first).
fn first_with_same_key<K: std::hash::Hash + Eq>(keys: impl Iterator<Item = K>) -> Vec<u32> {
    let mut first: HashMap<K, u32> = HashMap::new();
    keys.enumerate()
        .map(|(i, k)| *first.entry(k).or_insert(i as u32))
        .collect()
}

/// Merges vertices whose (position, albedo) or (position, normal, albedo) are identical.
fn weld(scene: &Scene, representative: &[u32]) -> (Scene, VertexMap) {
    let kept: Vec<u32> = (0..representative.len() as u32)
        .filter(|&i| representative[i as usize] == i)
        .collect();
    select_vertices(scene, &kept, |old| representative[old as usize])
}

fn weld_with_normals(mut scene: Scene, normals: Vec<Vec3>) -> (Scene, VertexMap) {
    let representative = first_with_same_key((0..scene.positions.len()).map(|i| {
        (
            key(scene.positions[i]),
            key(normals[i]),
            key(scene.albedo[i]),
        )
    }));
    scene.normals = Some(normals);
    weld(&scene, &representative)
}

/// The normals `prepare` computes for a mesh without them: angle-weighted over the mesh
/// welded by position alone, so a seam of UVs or colours is not also a shading seam.
/// `Vec3::ZERO` for vertices in no non-degenerate triangle.
pub fn smooth_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    smooth_normals_without_folds(positions, triangles).0
}

/// [`smooth_normals`] and the number of folded triangles left out of them.
fn smooth_normals_without_folds(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<Vec3>, usize) {
    let same_position = first_with_same_key(positions.iter().map(|&p| key(p)));
    let position_triangles: Vec<[u32; 3]> = triangles
        .iter()
        .map(|t| t.map(|i| same_position[i as usize]))
        .collect();
    // Non-representative vertices are referenced by no triangle here, so their normal is
    // read from their representative.
    let (by_position, folded) = normals_without_folds(positions, &position_triangles);
    let normals = same_position
        .iter()
        .map(|&rep| by_position[rep as usize])
        .collect();
    (normals, folded)
}

/// Computes normals over the mesh welded by position alone, then welds by (position, albedo).
///
/// Computing on the position-welded mesh means a colour seam (same position, different
/// albedo) does not also become a shading seam.
fn weld_and_compute_normals(mut scene: Scene) -> Result<(Scene, VertexMap, usize)> {
    let (normals, folded) = smooth_normals_without_folds(&scene.positions, &scene.triangles);
    // Every triangle left is exactly non-degenerate, but its f64 cross product could still
    // round to zero for extreme coordinates; that vertex has no usable normal.
    if let Some(v) = normals.iter().position(|&n| n == Vec3::ZERO) {
        return Err(Error::Geometry(format!(
            "cannot compute a normal for vertex at {}: its triangles are too small",
            show(scene.positions[v])
        )));
    }
    scene.normals = Some(normals);
    let representative = first_with_same_key(
        scene
            .positions
            .iter()
            .zip(&scene.albedo)
            .map(|(&p, &a)| (key(p), key(a))),
    );
    let (scene, welded) = weld(&scene, &representative);
    Ok((scene, welded, folded))
}

fn sort_vertices_morton(scene: Scene) -> (Scene, VertexMap) {
    let order = crate::morton::morton_order(&scene.positions);
    select_vertices(&scene, &order, |old| old)
}

#[cfg(test)]
mod tests;
