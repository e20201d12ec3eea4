//! Scenes: what a mesh file (or the built-in scene) holds, before and after preparation.
//!
//! Data flow: `load` (obj, ply, built-in) gives a [`Scene`] exactly as the file describes it;
//! `prepare` validates it, computes missing normals, welds duplicate vertices and sorts the
//! vertices spatially, giving the [`Scene`] that is baked and written out.

pub mod builtin;
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
}

/// Albedo given to surfaces whose file says nothing about their colour.
pub const DEFAULT_ALBEDO: Vec3 = Vec3::splat(0.8);

/// Loads a mesh file, choosing the reader by extension (`.obj`, `.ply`, `.ply.gz`).
pub fn load(path: &Path) -> Result<Scene> {
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
        obj::load(path)
    } else if name.ends_with(".ply") || name.ends_with(".ply.gz") {
        ply::load(path)
    } else {
        Err(Error::mesh(
            path,
            "unknown mesh format (expected .obj, .ply or .ply.gz)",
        ))
    }
}
