//! glTF files built in the tests: a `.gltf` with its buffer a base64 `data:` URI.

use std::path::{Path, PathBuf};

use base64::Engine;
use glam::Vec3;
use prt_gpu::scene::{self, builtin, Scene};
use serde_json::{json, Value};

/// A .gltf whose buffer is a base64 `data:` URI, built in the tests.
#[derive(Default)]
pub struct GltfBuilder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl GltfBuilder {
    pub fn floats(&mut self, values: &[f32], kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let components = match kind {
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 4,
        };
        let mut accessor = json!({
            "bufferView": self.view(&bytes, 34962),
            "componentType": 5126,
            "count": values.len() / components,
            "type": kind,
        });
        if bounds {
            let column = |c: usize, pick: fn(f32, f32) -> f32| {
                values
                    .iter()
                    .skip(c)
                    .step_by(components)
                    .copied()
                    .reduce(pick)
                    .unwrap()
            };
            accessor["min"] = json!((0..components)
                .map(|c| column(c, f32::min))
                .collect::<Vec<_>>());
            accessor["max"] = json!((0..components)
                .map(|c| column(c, f32::max))
                .collect::<Vec<_>>());
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    pub fn indices(&mut self, triangles: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = triangles
            .iter()
            .flatten()
            .flat_map(|i| (*i as u16).to_le_bytes())
            .collect();
        let view = self.view(&bytes, 34963);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": triangles.len() * 3, "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }

    pub fn view(&mut self, bytes: &[u8], target: u32) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target
        }));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// A primitive of `mesh` (positions, normals, optional UVs) as glTF attributes.
    pub fn primitive(&mut self, mesh: &Scene, uvs: Option<&[[f32; 2]]>) -> Value {
        let sets: Vec<(u32, &[[f32; 2]])> = uvs.map(|uvs| (0, uvs)).into_iter().collect();
        self.primitive_with_sets(mesh, &sets)
    }

    /// A primitive of `mesh` with the UV sets `sets` (`TEXCOORD_n`, coordinates).
    pub fn primitive_with_sets(&mut self, mesh: &Scene, sets: &[(u32, &[[f32; 2]])]) -> Value {
        let positions: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
        let normals: Vec<f32> = mesh
            .normals
            .as_ref()
            .unwrap()
            .iter()
            .flat_map(|n| n.to_array())
            .collect();
        let mut attributes = json!({
            "POSITION": self.floats(&positions, "VEC3", true),
            "NORMAL": self.floats(&normals, "VEC3", false),
        });
        for &(set, uvs) in sets {
            let flat: Vec<f32> = uvs.iter().flatten().copied().collect();
            attributes[format!("TEXCOORD_{set}")] = json!(self.floats(&flat, "VEC2", false));
        }
        json!({ "attributes": attributes, "indices": self.indices(&mesh.triangles) })
    }

    pub fn finish(self, mut doc: Value, dir: &Path, name: &str) -> PathBuf {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        doc["asset"] = json!({ "version": "2.0" });
        doc["buffers"] = json!([{ "byteLength": self.bin.len(), "uri": uri }]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        let path = dir.join(name);
        std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        path
    }
}

/// A ground and a card (two-sided) floating over it, lightmapped on the scene's own UV sets:
/// `TEXCOORD_<lightmap_set>` lays each out in a region of its own (a planar projection, the
/// ground on the left half, the card on the right); with `texture_set`, `TEXCOORD_0` puts both
/// on the whole square, as a texture set does (overlapping). The card is shown twice with
/// `card_twice`.
pub fn ground_and_card_gltf(
    dir: &Path,
    lightmap_set: Option<u32>,
    texture_set: bool,
    card_twice: bool,
) -> PathBuf {
    let prepared = |mesh: Scene| scene::prepare::prepare(mesh).unwrap().0;
    let ground = prepared(builtin::grid_plane(
        Vec3::ZERO,
        Vec3::X * 3.0,
        Vec3::NEG_Z * 3.0,
        8,
        Vec3::ONE,
    ));
    let card = prepared(builtin::grid_plane(
        Vec3::new(0.3, 0.5, 0.0),
        Vec3::X,
        Vec3::NEG_Z,
        2,
        Vec3::ONE,
    ));
    // The card's underside, facing the ground: what the ground's texels under it see is a
    // front face, so they are not taken for texels inside geometry.
    let underside = prepared(builtin::grid_plane(
        Vec3::new(0.3, 0.45, 0.0),
        Vec3::X,
        Vec3::Z,
        2,
        Vec3::ONE,
    ));
    // The mesh's extent in x and z onto the rectangle [u0, u1] x [v0, v1].
    let project = |mesh: &Scene, [u0, v0, u1, v1]: [f32; 4]| -> Vec<[f32; 2]> {
        let lo = mesh.positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
        let hi = mesh
            .positions
            .iter()
            .fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
        mesh.positions
            .iter()
            .map(|p| {
                let s = (*p - lo) / (hi - lo).max(Vec3::splat(1e-9));
                [u0 + (u1 - u0) * s.x, v0 + (v1 - v0) * s.z]
            })
            .collect()
    };
    let mut builder = GltfBuilder::default();
    let mut primitive = |mesh: &Scene, region: [f32; 4]| {
        let own = project(mesh, region);
        let whole = project(mesh, [0.0, 0.0, 1.0, 1.0]);
        let mut sets: Vec<(u32, &[[f32; 2]])> = Vec::new();
        if texture_set {
            sets.push((0, &whole));
        }
        if let Some(set) = lightmap_set {
            sets.push((set, &own));
        }
        builder.primitive_with_sets(mesh, &sets)
    };
    let ground_primitive = primitive(&ground, [0.02, 0.02, 0.48, 0.98]);
    let card_primitive = primitive(&card, [0.52, 0.02, 0.98, 0.48]);
    let underside_primitive = primitive(&underside, [0.52, 0.52, 0.98, 0.98]);
    let mut nodes = vec![json!({ "mesh": 0 }), json!({ "mesh": 1 })];
    if card_twice {
        nodes.push(json!({ "mesh": 1, "translation": [0.0, 0.3, 0.0] }));
    }
    let doc = json!({
        "scene": 0,
        "scenes": [{ "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": [
            { "name": "ground", "primitives": [ground_primitive] },
            { "name": "card", "primitives": [card_primitive, underside_primitive] },
        ],
    });
    builder.finish(doc, dir, "lit.gltf")
}
