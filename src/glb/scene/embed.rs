//! The scene's own data, re-embedded in the one BIN chunk: every accessor densely packed in a
//! view of its own (sparse accessors substituted, geometry as float, indices as u32, non-finite
//! values repaired), and every image as a view of its encoded bytes.

use gltf_json::accessor::{ComponentType, GenericComponentType};
use gltf_json::buffer::Target;
use gltf_json::mesh::Semantic;
use gltf_json::validation::Checked;
use gltf_json::{Index, Root};
use serde_json::json;

use super::Bin;
use crate::scene::gltf::accessor::{component_size, dense, Dense};
use crate::scene::gltf::{self, GltfScene};

/// How each accessor is used by the meshes, which decides how it is written.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
struct Use {
    vertex_attribute: bool,
    /// POSITION or NORMAL of a primitive: written as float.
    geometry: bool,
    indices: bool,
    /// The NORMAL of this primitive (mesh, primitive): repaired from its geometry.
    normal_of: Option<(usize, usize)>,
}

fn accessor_uses(root: &Root) -> Vec<Use> {
    let mut uses = vec![Use::default(); root.accessors.len()];
    let mut mark = |index: usize, f: &dyn Fn(&mut Use)| {
        if let Some(u) = uses.get_mut(index) {
            f(u)
        }
    };
    let primitives = root.meshes.iter().enumerate().flat_map(|(m, mesh)| {
        mesh.primitives
            .iter()
            .enumerate()
            .map(move |(p, primitive)| ((m, p), primitive))
    });
    for (place, primitive) in primitives {
        for (semantic, accessor) in &primitive.attributes {
            let geometry = matches!(
                semantic,
                Checked::Valid(Semantic::Positions | Semantic::Normals)
            );
            let normal = matches!(semantic, Checked::Valid(Semantic::Normals));
            mark(accessor.value(), &|u| {
                u.vertex_attribute = true;
                u.geometry |= geometry;
                if normal {
                    u.normal_of.get_or_insert(place);
                }
            });
        }
        for target in primitive.targets.iter().flatten() {
            for accessor in [&target.positions, &target.normals, &target.tangents]
                .into_iter()
                .flatten()
            {
                mark(accessor.value(), &|u| u.vertex_attribute = true);
            }
        }
        if let Some(indices) = primitive.indices {
            mark(indices.value(), &|u| u.indices = true);
        }
    }
    uses
}

/// Rewrites every accessor into a view of its own in `bin`; says which had NaN or infinite
/// values, written repaired.
pub(super) fn embed_accessors(
    root: &mut Root,
    buffers: &[Vec<u8>],
    bin: &mut Bin,
) -> std::result::Result<Vec<String>, String> {
    let uses = accessor_uses(root);
    let mut repaired = Vec::new();
    for (index, usage) in uses.iter().enumerate() {
        let data = dense(root, buffers, index)?;
        let (mut data, mut recompute_bounds) = if usage.geometry && !usage.indices {
            (
                as_float(&data),
                data.component != ComponentType::F32 || data.normalized,
            )
        } else if usage.indices && !usage.vertex_attribute {
            (as_u32(&data)?, false)
        } else {
            (data, false)
        };
        if let Some(said) = repair_non_finite(root, buffers, index, usage, &mut data) {
            repaired.push(said);
            recompute_bounds |= root.accessors[index].min.is_some();
        }
        let accessor = &mut root.accessors[index];
        let element = data.components * component_size(data.component);
        let (bytes, stride) = if usage.vertex_attribute && !element.is_multiple_of(4) {
            (
                pad_elements(&data.bytes, element),
                Some(element.next_multiple_of(4)),
            )
        } else {
            (data.bytes.clone(), None)
        };
        let target = if usage.vertex_attribute {
            Some(Target::ArrayBuffer)
        } else if usage.indices {
            Some(Target::ElementArrayBuffer)
        } else {
            None
        };
        let view = bin.push(&bytes, stride, target);
        accessor.buffer_view = Some(Index::new(view));
        accessor.byte_offset = None;
        accessor.sparse = None;
        accessor.component_type = Checked::Valid(GenericComponentType(data.component));
        accessor.normalized = data.normalized;
        if recompute_bounds {
            let (min, max) = bounds(&data);
            accessor.min = Some(json!(min));
            accessor.max = Some(json!(max));
        } else if usage.indices && !usage.vertex_attribute {
            accessor.min = None;
            accessor.max = None;
        }
    }
    Ok(repaired)
}

/// Replaces what a reader cannot use in accessor `index`: a primitive's normals that are NaN,
/// infinite or zero by the smooth normals of its triangles (`prepare` baked with computed
/// ones too), any other NaN or infinite float by zero (a morph target's zero moves nothing).
/// Says what it did; `None` where nothing needed it.
fn repair_non_finite(
    root: &Root,
    buffers: &[Vec<u8>],
    index: usize,
    usage: &Use,
    data: &mut Dense,
) -> Option<String> {
    if data.component != ComponentType::F32 {
        return None;
    }
    let mut values = data.floats();
    let name = root.accessors[index].name.as_deref().unwrap_or("");
    let unusable = |e: &[f32]| !e.iter().all(|v| v.is_finite()) || e.iter().all(|&v| v == 0.0);
    if let Some((mesh, primitive)) = usage.normal_of.filter(|_| data.components == 3) {
        let bad = values.chunks_exact(3).filter(|e| unusable(e)).count();
        let computed = (bad > 0)
            .then(|| primitive_normals(root, buffers, mesh, primitive))
            .flatten()
            .filter(|normals| normals.len() == data.count);
        if let Some(normals) = computed {
            for (element, normal) in values.chunks_exact_mut(3).zip(normals) {
                if unusable(element) {
                    element.copy_from_slice(&normal.to_array());
                }
            }
            data.bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            return Some(format!(
                "accessor {index} {name:?} had {bad} normal(s) NaN, infinite or zero, written \
                 as the normals computed from its triangles"
            ));
        }
    }
    let bad = values.iter().filter(|v| !v.is_finite()).count();
    if bad == 0 {
        return None;
    }
    values
        .iter_mut()
        .filter(|v| !v.is_finite())
        .for_each(|v| *v = 0.0);
    data.bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    Some(format!(
        "accessor {index} {name:?} had {bad} NaN or infinite value(s), written as zeros"
    ))
}

/// The smooth normals of a primitive's own triangles, in its own space; `None` where its
/// geometry does not give them.
fn primitive_normals(
    root: &Root,
    buffers: &[Vec<u8>],
    mesh: usize,
    primitive: usize,
) -> Option<Vec<glam::Vec3>> {
    let primitive = root.meshes.get(mesh)?.primitives.get(primitive)?;
    let positions = primitive
        .attributes
        .get(&Checked::Valid(Semantic::Positions))?;
    let positions: Vec<glam::Vec3> = dense(root, buffers, positions.value())
        .ok()?
        .vectors::<3>("POSITION")
        .ok()?
        .into_iter()
        .map(glam::Vec3::from_array)
        .collect();
    if !positions.iter().all(|p| p.is_finite()) {
        return None;
    }
    let triangles = gltf::triangle_list(root, buffers, primitive, "primitive").ok()??;
    let normals = crate::scene::prepare::smooth_normals(&positions, &triangles);
    // A vertex in no triangle has no normal to compute: any unit vector is as good as another.
    Some(
        normals
            .into_iter()
            .map(|n| {
                if n.is_finite() && n != glam::Vec3::ZERO {
                    n
                } else {
                    glam::Vec3::Z
                }
            })
            .collect(),
    )
}

fn as_float(data: &Dense) -> Dense {
    Dense {
        count: data.count,
        components: data.components,
        component: ComponentType::F32,
        normalized: false,
        bytes: data.floats().iter().flat_map(|f| f.to_le_bytes()).collect(),
    }
}

fn as_u32(data: &Dense) -> std::result::Result<Dense, String> {
    Ok(Dense {
        count: data.count,
        components: 1,
        component: ComponentType::U32,
        normalized: false,
        bytes: data
            .indices()?
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
    })
}

fn pad_elements(bytes: &[u8], element: usize) -> Vec<u8> {
    let padded = element.next_multiple_of(4);
    let mut out = Vec::with_capacity(bytes.len() / element.max(1) * padded);
    for item in bytes.chunks_exact(element) {
        out.extend_from_slice(item);
        out.resize(out.len() + padded - element, 0);
    }
    out
}

/// Per-component minimum and maximum of float data.
fn bounds(data: &Dense) -> (Vec<f32>, Vec<f32>) {
    let floats = data.floats();
    let mut min = vec![f32::INFINITY; data.components];
    let mut max = vec![f32::NEG_INFINITY; data.components];
    for element in floats.chunks_exact(data.components) {
        for (c, &v) in element.iter().enumerate() {
            min[c] = min[c].min(v);
            max[c] = max[c].max(v);
        }
    }
    (min, max)
}

/// Every image as a view of its encoded bytes.
pub(super) fn embed_images(root: &mut Root, gltf: &GltfScene, bin: &mut Bin) {
    for (image, encoded) in root.images.iter_mut().zip(&gltf.images) {
        let view = bin.push(&encoded.bytes, None, None);
        image.buffer_view = Some(Index::new(view));
        image.uri = None;
        image.mime_type = Some(gltf_json::image::MimeType(encoded.mime_type.clone()));
    }
}
