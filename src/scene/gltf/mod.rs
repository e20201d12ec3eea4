//! glTF 2.0 scenes (`.gltf` with external or `data:` resources, `.glb`): every triangle
//! primitive the scene shows, each instance placed by its node's world transform, becomes part
//! of one [`Scene`] to bake; the document, its buffers and images are kept so the scene can be
//! written back as it came, with the transfer added (bake in place, `glb::scene`).
//!
//! What is read: the `scene` property (else scene 0, else every root node); node matrices or
//! TRS; triangle lists, strips and fans (points and lines are skipped with a note); accessors of
//! every component type, normalized or not, interleaved or sparse (`accessor`); the albedo
//! `baseColorFactor × baseColorTexture × COLOR_0`, the texture averaged around each vertex
//! (`albedo`); the materials' scattering volumes, for subsurface transfer (`volume`). Skinned and morphing meshes are baked in their rest pose, with a note.

pub mod accessor;
mod albedo;
mod resource;
pub mod volume;

use std::path::Path;

use glam::{Mat3, Mat4, Quat, Vec3};
use gltf_json::mesh::{Mode, Semantic};
use gltf_json::validation::{Checked, Validate};
use gltf_json::Root;

use super::Scene;
use crate::error::{one_line, Error, Result};
use accessor::dense;

/// Extensions a file may require that the bake honours (or that change nothing it reads).
const READABLE_EXTENSIONS: &[&str] = &[
    "KHR_mesh_quantization",
    "KHR_texture_transform",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_volume_scatter",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_lights_punctual",
];

/// A glTF scene as read, kept whole so it can be written back with its transfer.
#[derive(Clone, Debug)]
pub struct GltfScene {
    pub root: Root,
    /// Each buffer's bytes.
    pub buffers: Vec<Vec<u8>>,
    /// Each image as encoded in the file.
    pub images: Vec<EncodedImage>,
    /// Every placement of a mesh that the scene shows, in traversal order.
    pub instances: Vec<Instance>,
    /// What was skipped or assumed, one line each, for the user.
    pub notes: Vec<String>,
}

impl GltfScene {
    /// The bytes of its buffers and images, which a scene baked in place writes back.
    pub fn byte_size(&self) -> usize {
        let buffers: usize = self.buffers.iter().map(Vec::len).sum();
        let images: usize = self.images.iter().map(|image| image.bytes.len()).sum();
        buffers + images
    }
}

/// An image's encoded bytes (PNG, JPEG, ...) and MIME type.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedImage {
    pub bytes: Vec<u8>,
    pub mime_type: String,
}

/// One node's mesh, placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    pub node: usize,
    pub mesh: usize,
    pub world: Mat4,
    /// The primitives baked, with where their vertices lie in the baked [`Scene`].
    pub primitives: Vec<PrimitiveSpan>,
}

/// A primitive's vertices in the baked [`Scene`]: `first .. first + count`, in the
/// primitive's own vertex order (so the transfer scatters back by index).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveSpan {
    pub primitive: usize,
    pub first: usize,
    pub count: usize,
}

/// Reads `path` (`.gltf` or `.glb`).
pub fn load(path: &Path) -> Result<(GltfScene, Scene)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let fail = |message: String| Error::mesh(path, message);
    let gltf = read_document(&bytes).map_err(fail)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let root = gltf.document.into_json();
    let buffers = resource::buffers(&root, base, gltf.blob).map_err(fail)?;
    let images = encoded_images(&root, &buffers, base).map_err(fail)?;
    let mut gltf_scene = GltfScene {
        root,
        buffers,
        images,
        instances: Vec::new(),
        notes: Vec::new(),
    };
    let scene = assemble(&mut gltf_scene).map_err(fail)?;
    Ok((gltf_scene, scene))
}

/// The document, validated: references in range, no extension required that the bake
/// cannot honour (compressed geometry names itself), no recursive node tree.
fn read_document(bytes: &[u8]) -> std::result::Result<gltf::Gltf, String> {
    let gltf = gltf::Gltf::from_slice_without_validation(super::skip_bom(bytes))
        .map_err(|e| format!("not a readable glTF file: {}", one_line(&e.to_string())))?;
    let root = gltf.document.as_json();
    for required in &root.extensions_required {
        if !READABLE_EXTENSIONS.contains(&required.as_str()) {
            return Err(format!(
                "requires the glTF extension {required}, which prt-gpu cannot read \
                 (decompress or convert the file first)"
            ));
        }
    }
    validate(root)?;
    check_node_tree(root)?;
    Ok(gltf)
}

/// gltf-json's validation, less its refusal of extensions we read ourselves. Its hooks index
/// arrays before their indices are checked, so a damaged file may panic inside it: that is
/// caught and reported as the damage it is.
fn validate(root: &Root) -> std::result::Result<(), String> {
    let mut errors = Vec::new();
    let outcome = catch_silently(|| {
        root.validate(root, gltf_json::Path::new, &mut |path, error| {
            let path = path().to_string();
            let accepted = matches!(error, gltf_json::validation::Error::Unsupported)
                && path.starts_with("extensionsRequired");
            if !accepted {
                errors.push(format!("{path}: {error}"));
            }
        })
    });
    if outcome.is_none() {
        return Err("invalid glTF: an index or reference is out of range".into());
    }
    match errors.first() {
        Some(first) if errors.len() == 1 => Err(format!("invalid glTF: {first}")),
        Some(first) => Err(format!(
            "invalid glTF: {first} (and {} more problems)",
            errors.len() - 1
        )),
        None => Ok(()),
    }
}

/// Runs `work`, turning a panic into `None` without printing it.
fn catch_silently<T>(work: impl FnOnce() -> T) -> Option<T> {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).ok();
    std::panic::set_hook(previous);
    outcome
}

/// Every node has at most one parent and no node is its own ancestor.
fn check_node_tree(root: &Root) -> std::result::Result<(), String> {
    let mut parent = vec![None; root.nodes.len()];
    for (index, node) in root.nodes.iter().enumerate() {
        for child in node.children.iter().flatten() {
            let child = child.value();
            if child == index {
                return Err(format!("node {index} is its own child (recursive nodes)"));
            }
            if let Some(other) = parent
                .get_mut(child)
                .and_then(|p: &mut Option<usize>| p.replace(index))
            {
                return Err(format!(
                    "node {child} has two parents, {other} and {index} (recursive or shared nodes)"
                ));
            }
        }
    }
    for start in 0..root.nodes.len() {
        let mut node = start;
        for _ in 0..root.nodes.len() {
            match parent[node] {
                Some(up) if up == start => {
                    return Err(format!(
                        "node {start} is its own ancestor (recursive nodes)"
                    ))
                }
                Some(up) => node = up,
                None => break,
            }
        }
    }
    Ok(())
}

/// Each image's encoded bytes: from a buffer view, a `data:` URI or a file beside the glTF.
fn encoded_images(
    root: &Root,
    buffers: &[Vec<u8>],
    base: &Path,
) -> std::result::Result<Vec<EncodedImage>, String> {
    root.images
        .iter()
        .enumerate()
        .map(|(index, image)| {
            let declared = image.mime_type.as_ref().map(|m| m.0.clone());
            let bytes = match (&image.buffer_view, &image.uri) {
                (Some(view), _) => accessor::view_bytes(root, buffers, view.value())?.to_vec(),
                (None, Some(uri)) => resource::read(uri, base, None)
                    .map_err(|e| format!("cannot read image {index}: {e}"))?,
                (None, None) => return Err(format!("image {index} has no data")),
            };
            let mime_type = declared
                .or_else(|| sniff_mime_type(&bytes).map(str::to_string))
                .ok_or_else(|| format!("image {index} is neither PNG nor JPEG"))?;
            Ok(EncodedImage { bytes, mime_type })
        })
        .collect()
}

fn sniff_mime_type(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG") {
        Some("image/png")
    } else if bytes.starts_with(&[0xff, 0xd8]) {
        Some("image/jpeg")
    } else {
        None
    }
}

/// The nodes the scene shows, with their world transforms, parents before children.
fn shown_nodes(root: &Root) -> Vec<(usize, Mat4)> {
    let roots: Vec<usize> = match root
        .scene
        .map(|s| s.value())
        .or((!root.scenes.is_empty()).then_some(0))
    {
        Some(scene) => root.scenes[scene].nodes.iter().map(|n| n.value()).collect(),
        None => {
            let mut is_child = vec![false; root.nodes.len()];
            for child in root.nodes.iter().flat_map(|n| n.children.iter().flatten()) {
                is_child[child.value()] = true;
            }
            (0..root.nodes.len()).filter(|&n| !is_child[n]).collect()
        }
    };
    let mut shown = Vec::new();
    let mut stack: Vec<(usize, Mat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY))
        .collect();
    while let Some((index, parent)) = stack.pop() {
        let node = &root.nodes[index];
        let world = parent * local_transform(node);
        shown.push((index, world));
        for child in node.children.iter().flatten().rev() {
            stack.push((child.value(), world));
        }
    }
    shown
}

fn local_transform(node: &gltf_json::Node) -> Mat4 {
    if let Some(matrix) = node.matrix {
        return Mat4::from_cols_array(&matrix);
    }
    let translation = node.translation.map_or(Vec3::ZERO, Vec3::from_array);
    let rotation = node
        .rotation
        .map_or(Quat::IDENTITY, |q| Quat::from_array(q.0).normalize());
    let scale = node.scale.map_or(Vec3::ONE, Vec3::from_array);
    Mat4::from_scale_rotation_translation(scale, rotation, translation)
}

/// The baked [`Scene`]: every shown instance's triangle primitives in world space. Fills the
/// instances and notes of `gltf`.
fn assemble(gltf: &mut GltfScene) -> std::result::Result<Scene, String> {
    let mut scene = Scene::default();
    let mut normals = Vec::new();
    // Primitives without normals, as (first vertex, first triangle) spans of `scene`.
    let mut without_normals = Vec::new();
    let mut notes = Notes::default();
    let mut textures = albedo::Textures::default();
    for (node_index, world) in shown_nodes(&gltf.root) {
        let node = &gltf.root.nodes[node_index];
        let Some(mesh_index) = node.mesh.map(|m| m.value()) else {
            continue;
        };
        if node.skin.is_some() {
            notes.skinned.push(node_index);
        }
        let mut instance = Instance {
            node: node_index,
            mesh: mesh_index,
            world,
            primitives: Vec::new(),
        };
        for (primitive_index, primitive) in
            gltf.root.meshes[mesh_index].primitives.iter().enumerate()
        {
            let what = format!("mesh {mesh_index} primitive {primitive_index}");
            let Some(triangles) = triangle_list(&gltf.root, &gltf.buffers, primitive, &what)?
            else {
                notes.not_triangles.push(what);
                continue;
            };
            if primitive.targets.as_ref().is_some_and(|t| !t.is_empty()) {
                notes.morphing.push(mesh_index);
            }
            let part = primitive_geometry(gltf, primitive, &triangles, world, &what)?;
            let part = albedo::apply(gltf, primitive, part, &mut textures, &what, &mut notes)?;
            let first = scene.positions.len();
            instance.primitives.push(PrimitiveSpan {
                primitive: primitive_index,
                first,
                count: part.positions.len(),
            });
            if part.normals.is_none() {
                without_normals.push((
                    first..first + part.positions.len(),
                    scene.triangles.len()..scene.triangles.len() + part.triangles.len(),
                ));
            }
            append(&mut scene, &mut normals, part, first);
        }
        if !instance.primitives.is_empty() {
            gltf.instances.push(instance);
        }
    }
    if scene.triangles.is_empty() {
        return Err(match notes.not_triangles.first() {
            Some(_) => "the scene shows no triangles (only points or lines)".into(),
            None => "the scene shows no meshes".into(),
        });
    }
    // Where no primitive has normals, `prepare` computes them all, as for OBJ and PLY; where
    // some do, the others get the normals `prepare` would give them, primitive by primitive.
    if without_normals.len() < gltf.instances.iter().map(|i| i.primitives.len()).sum() {
        for (vertices, triangles) in without_normals {
            let local: Vec<[u32; 3]> = scene.triangles[triangles]
                .iter()
                .map(|t| t.map(|i| i - vertices.start as u32))
                .collect();
            let computed =
                super::prepare::smooth_normals(&scene.positions[vertices.clone()], &local);
            normals[vertices].copy_from_slice(&computed);
        }
        scene.normals = Some(normals);
    }
    gltf.notes = notes.lines(gltf);
    Ok(scene)
}

/// The scene's `TEXCOORD_<set>` coordinates, one pair per vertex of the [`Scene`] `load`
/// made (placement after placement, primitive after primitive): `Ok(None)` where a baked
/// primitive lacks the set; an error where one holds NaN or infinite coordinates.
pub fn texcoords(gltf: &GltfScene, set: u32) -> std::result::Result<Option<Vec<[f32; 2]>>, String> {
    let mut uvs = Vec::new();
    for instance in &gltf.instances {
        let mesh = &gltf.root.meshes[instance.mesh];
        for span in &instance.primitives {
            let primitive = &mesh.primitives[span.primitive];
            let what = format!("mesh {} primitive {}", instance.mesh, span.primitive);
            let Some(accessor) = primitive
                .attributes
                .get(&Checked::Valid(Semantic::TexCoords(set)))
            else {
                return Ok(None);
            };
            let own = dense(&gltf.root, &gltf.buffers, accessor.value())?
                .vectors::<2>(&format!("{what} TEXCOORD_{set}"))?;
            if own.len() != span.count {
                return Err(format!(
                    "{what}: TEXCOORD_{set} holds {} coordinates for {} vertices",
                    own.len(),
                    span.count
                ));
            }
            if let Some(vertex) = own.iter().position(|uv| !uv.iter().all(|c| c.is_finite())) {
                return Err(format!(
                    "{what}: TEXCOORD_{set} is NaN or infinite at vertex {vertex}"
                ));
            }
            uvs.extend(own);
        }
    }
    Ok(Some(uvs))
}

/// A mesh the scene shows at more than one placement, if any: its index and how many nodes
/// show it.
pub fn mesh_placed_twice(gltf: &GltfScene) -> Option<(usize, usize)> {
    let mut shown = std::collections::BTreeMap::new();
    for instance in &gltf.instances {
        *shown.entry(instance.mesh).or_insert(0usize) += 1;
    }
    shown.into_iter().find(|&(_, nodes)| nodes > 1)
}

/// Appends `part` (whose own indices start at 0) to `scene`, its vertices from `first`.
fn append(scene: &mut Scene, normals: &mut Vec<Vec3>, part: Part, first: usize) {
    let offset = first as u32;
    scene
        .triangles
        .extend(part.triangles.iter().map(|t| t.map(|i| i + offset)));
    // Placeholders where the primitive has none: filled by `assemble` if they are needed.
    match part.normals {
        Some(own) => normals.extend(own),
        None => normals.extend(std::iter::repeat_n(Vec3::ZERO, part.positions.len())),
    }
    scene.positions.extend(part.positions);
    scene.albedo.extend(part.albedo);
}

/// One primitive in world space.
struct Part {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    albedo: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

fn primitive_geometry(
    gltf: &GltfScene,
    primitive: &gltf_json::mesh::Primitive,
    triangles: &[[u32; 3]],
    world: Mat4,
    what: &str,
) -> std::result::Result<Part, String> {
    let root = &gltf.root;
    let attribute = |semantic: Semantic| primitive.attributes.get(&Checked::Valid(semantic));
    let positions_accessor =
        attribute(Semantic::Positions).ok_or_else(|| format!("{what} has no POSITION"))?;
    let local: Vec<[f32; 3]> = dense(root, &gltf.buffers, positions_accessor.value())?
        .vectors(&format!("{what} POSITION"))?;
    let positions: Vec<Vec3> = local
        .iter()
        .map(|&p| world.transform_point3(Vec3::from_array(p)))
        .collect();
    let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
    let normals = match attribute(Semantic::Normals) {
        Some(index) => Some(
            dense(root, &gltf.buffers, index.value())?
                .vectors::<3>(&format!("{what} NORMAL"))?
                .iter()
                .map(|&n| (normal_matrix * Vec3::from_array(n)).normalize_or_zero())
                .collect::<Vec<_>>(),
        ),
        None => None,
    };
    // A mirroring transform turns the winding inside out; flipping it keeps faces facing out.
    let mirrored = Mat3::from_mat4(world).determinant() < 0.0;
    let triangles = triangles
        .iter()
        .map(|&[a, b, c]| if mirrored { [a, c, b] } else { [a, b, c] })
        .collect();
    Ok(Part {
        albedo: vec![Vec3::ONE; positions.len()],
        positions,
        normals,
        triangles,
    })
}

/// The primitive's triangles as a list (strips and fans converted), `None` for points and
/// lines; every index checked against the vertex count.
pub(crate) fn triangle_list(
    root: &Root,
    buffers: &[Vec<u8>],
    primitive: &gltf_json::mesh::Primitive,
    what: &str,
) -> std::result::Result<Option<Vec<[u32; 3]>>, String> {
    let mode = match primitive.mode {
        Checked::Valid(mode) => mode,
        Checked::Invalid => return Err(format!("{what} has an invalid mode")),
    };
    if !matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(None);
    }
    let positions = primitive
        .attributes
        .get(&Checked::Valid(Semantic::Positions));
    let vertex_count = positions
        .and_then(|a| root.accessors.get(a.value()))
        .map_or(0, |a| a.count.0 as usize);
    let indices = match (primitive.indices, positions) {
        (Some(index), _) => dense(root, buffers, index.value())?
            .indices()
            .map_err(|e| format!("{what}: {e}"))?,
        // One index per vertex: as many as the positions the buffers hold (read, so that a
        // count the data cannot back is an error before anything is reserved for it).
        (None, Some(positions)) => {
            let held = dense(root, buffers, positions.value())?.count;
            (0..u32::try_from(held).map_err(|_| format!("{what} has over 2^32 vertices"))?)
                .collect()
        }
        (None, None) => Vec::new(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
        return Err(format!(
            "{what} uses vertex {bad} but has only {vertex_count} vertices"
        ));
    }
    Ok(Some(match mode {
        Mode::TriangleStrip => strip_to_list(&indices),
        Mode::TriangleFan => fan_to_list(&indices),
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    }))
}

/// Triangle `i` of a strip is (i, i+1, i+2), every second one reversed so all face alike.
fn strip_to_list(indices: &[u32]) -> Vec<[u32; 3]> {
    indices
        .windows(3)
        .enumerate()
        .map(|(i, w)| {
            if i % 2 == 0 {
                [w[0], w[1], w[2]]
            } else {
                [w[1], w[0], w[2]]
            }
        })
        .collect()
}

/// Triangle `i` of a fan is (0, i+1, i+2).
fn fan_to_list(indices: &[u32]) -> Vec<[u32; 3]> {
    match indices.split_first() {
        Some((&center, rest)) => rest.windows(2).map(|w| [center, w[0], w[1]]).collect(),
        None => Vec::new(),
    }
}

/// What the loader skipped or assumed, gathered while reading and said once.
#[derive(Default)]
struct Notes {
    not_triangles: Vec<String>,
    skinned: Vec<usize>,
    morphing: Vec<usize>,
    /// Materials whose alphaMode is MASK or BLEND.
    see_through: Vec<usize>,
}

impl Notes {
    fn lines(mut self, gltf: &GltfScene) -> Vec<String> {
        let mut lines = Vec::new();
        if !self.not_triangles.is_empty() {
            lines.push(format!(
                "skipped {} point or line primitive(s) ({}): only triangles receive transfer",
                self.not_triangles.len(),
                self.not_triangles.join(", ")
            ));
        }
        for (list, what) in [
            (&mut self.skinned, "skinned node(s)"),
            (&mut self.morphing, "morphing mesh(es)"),
        ] {
            list.sort_unstable();
            list.dedup();
            if !list.is_empty() {
                lines.push(format!(
                    "{} {what} ({}) baked in their rest pose",
                    list.len(),
                    join(list)
                ));
            }
        }
        self.see_through.sort_unstable();
        self.see_through.dedup();
        if !self.see_through.is_empty() {
            let names: Vec<String> = self
                .see_through
                .iter()
                .map(|&m| material_label(&gltf.root, m))
                .collect();
            lines.push(format!(
                "material(s) {} use alphaMode MASK or BLEND; they are baked as opaque",
                names.join(", ")
            ));
        }
        lines
    }
}

fn join(values: &[usize]) -> String {
    values
        .iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn material_label(root: &Root, index: usize) -> String {
    match root.materials.get(index).and_then(|m| m.name.as_deref()) {
        Some(name) => format!("{index} ({name:?})"),
        None => index.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_alternate_their_winding_and_fans_pivot_on_the_first_vertex() {
        assert_eq!(
            strip_to_list(&[0, 1, 2, 3, 4]),
            [[0, 1, 2], [2, 1, 3], [2, 3, 4]]
        );
        assert_eq!(fan_to_list(&[0, 1, 2, 3]), [[0, 1, 2], [0, 2, 3]]);
        assert!(strip_to_list(&[0, 1]).is_empty() && fan_to_list(&[]).is_empty());
    }

    fn nodes(children: &[&[u32]]) -> Root {
        let nodes: Vec<_> = children
            .iter()
            .map(|c| serde_json::json!({ "children": c }))
            .collect();
        serde_json::from_value(serde_json::json!({ "asset": { "version": "2.0" }, "nodes": nodes }))
            .unwrap()
    }

    #[test]
    fn node_trees_with_cycles_or_shared_children_are_refused() {
        assert!(check_node_tree(&nodes(&[&[1], &[2], &[]])).is_ok());
        assert!(check_node_tree(&nodes(&[&[0]]))
            .unwrap_err()
            .contains("its own child"));
        assert!(check_node_tree(&nodes(&[&[1], &[0]])).is_err());
        assert!(check_node_tree(&nodes(&[&[2], &[2], &[]]))
            .unwrap_err()
            .contains("two parents"));
    }

    #[test]
    fn a_panic_inside_is_caught_and_silent() {
        assert_eq!(catch_silently(|| 7), Some(7));
        assert_eq!(catch_silently(|| -> u32 { panic!("inside") }), None);
    }
}
