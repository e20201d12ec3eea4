//! Scenes: what a mesh file (or the built-in scene) holds, before and after preparation.
//!
//! Data flow: `load` (obj, ply, built-in) gives a [`Scene`] exactly as the file describes it;
//! `prepare` validates it, computes missing normals, welds duplicate vertices and sorts the
//! vertices spatially, giving the [`Scene`] that is baked and written out.

pub mod batch;
pub mod builtin;
pub mod gltf;
pub mod joined;
pub mod obj;
pub mod ply;
pub mod prepare;
pub mod texture;

use std::path::Path;

use glam::Vec3;

use crate::error::{Error, Result};

/// A triangle mesh with per-vertex attributes.
///
/// `normals` is `None` when the source had none; after `prepare` it is always `Some`, unit length.
/// `albedo` is the diffuse reflectance per vertex, linear RGB in [0, 1].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub albedo: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl Scene {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The corners of the positions' bounding box ([`bounds_of`]).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        bounds_of(&self.positions)
    }

    /// The bounding box's largest side ([`extent_of`]).
    pub fn extent(&self) -> f32 {
        extent_of(&self.positions)
    }

    /// Whether every albedo is grey (its channels equal): the light's colour then passes
    /// through the transfer unchanged, and one channel of it is enough.
    pub fn all_grey(&self) -> bool {
        self.albedo.iter().all(|a| a.x == a.y && a.y == a.z)
    }
}

/// The corners of the bounding box of `points` (inverted, infinite, when there are none).
pub fn bounds_of(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    )
}

/// The largest side of the bounding box of `points` (what `ray::offset_ray_origin` scales its
/// floor by; a BVH's root box is the triangles' box, the same); 0 without points.
pub fn extent_of(points: &[Vec3]) -> f32 {
    let (lo, hi) = bounds_of(points);
    (hi - lo).max_element().max(0.0)
}

/// Albedo given to surfaces whose file says nothing about their colour.
pub const DEFAULT_ALBEDO: Vec3 = Vec3::splat(0.8);

/// Whether `path` names a glTF scene (`.gltf` or `.glb`), which can be baked in place.
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// The UTF-8 byte-order mark some editors write at the start of a text file.
const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// `bytes` without a leading UTF-8 byte-order mark: it says only that the text is UTF-8, so
/// every text reader (OBJ, MTL, PLY header, glTF JSON) skips it silently.
pub(crate) fn skip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes)
}

/// Loads a mesh file, choosing the reader by extension (`.gltf`, `.glb`, `.obj`, `.ply`,
/// `.ply.gz`). A glTF scene comes flattened to world space; `gltf::load` keeps the document.
pub fn load(path: &Path) -> Result<Scene> {
    load_with_warnings(path).map(|(scene, _)| scene)
}

/// [`load`], also giving what the reader repaired in the file's values, one line each, for the
/// caller to show (an OBJ material's diffuse colour outside [0, 1], say). What `prepare`
/// repairs in the geometry it reports itself; a glTF scene's notes come with `gltf::load`.
pub fn load_with_warnings(path: &Path) -> Result<(Scene, Vec<String>)> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if !path.exists() {
        return Err(Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        ));
    }
    if name.ends_with(".obj") {
        obj::load_with_warnings(path)
    } else if name.ends_with(".ply") || name.ends_with(".ply.gz") {
        ply::load_with_warnings(path)
    } else if is_gltf(path) {
        gltf::load(path).map(|(_, scene)| (scene, Vec::new()))
    } else {
        Err(Error::mesh(
            path,
            "unknown mesh format (expected .gltf, .glb, .obj, .ply or .ply.gz)",
        ))
    }
}
