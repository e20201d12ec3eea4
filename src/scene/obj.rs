//! Wavefront OBJ reader (through tobj). All objects and groups become one [`Scene`].
//!
//! Albedo comes from the diffuse colour (Kd) of each object's material. A missing or
//! unreadable MTL file, or an object without a material, gives [`DEFAULT_ALBEDO`]: an OBJ is
//! routinely copied without its MTL, and refusing to bake it would help no one.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use glam::Vec3;

use super::{Scene, DEFAULT_ALBEDO};
use crate::error::{Error, Result};

/// Reads an OBJ file and the MTL files it names (relative to the OBJ's directory).
///
/// Polygons are fan-triangulated; points and lines are ignored (they bound no surface).
/// Normals are kept only if every object has one per vertex; otherwise `prepare` computes
/// them for the whole mesh, so that no object is shaded differently from its neighbours.
pub fn load(path: &Path) -> Result<Scene> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let directory = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let options = tobj::LoadOptions {
        triangulate: true,
        // One index per vertex, as the baker needs; tobj splits vertices whose position,
        // normal and texture coordinate indices differ, and prepare welds them again.
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, materials) = tobj::load_obj_buf(&mut BufReader::new(file), &options, |mtl_path| {
        tobj::load_mtl(directory.join(mtl_path))
    })
    .map_err(|e| Error::mesh(path, format!("cannot read OBJ: {e}")))?;
    let scene = merge_models(&models, &materials.unwrap_or_default());
    if scene.triangles.is_empty() {
        return Err(Error::mesh(path, "no faces"));
    }
    Ok(scene)
}

fn merge_models(models: &[tobj::Model], materials: &[tobj::Material]) -> Scene {
    let every_model_has_normals = models
        .iter()
        .all(|m| m.mesh.normals.len() == m.mesh.positions.len());
    let mut scene = Scene {
        normals: every_model_has_normals.then(Vec::new),
        ..Scene::default()
    };
    for model in models {
        let mesh = &model.mesh;
        // Saturating keeps an impossible overflow visible as out-of-range indices.
        let offset = u32::try_from(scene.positions.len()).unwrap_or(u32::MAX);
        scene.positions.extend(vec3s(&mesh.positions));
        scene
            .albedo
            .resize(scene.positions.len(), model_albedo(mesh, materials));
        if let Some(normals) = scene.normals.as_mut() {
            normals.extend(vec3s(&mesh.normals));
        }
        scene.triangles.extend(
            mesh.indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]].map(|i| i.saturating_add(offset))),
        );
    }
    scene
}

/// Kd of the model's material, clamped to [0, 1] because albedo above 1 would create
/// energy in the bounce passes. A NaN is left for `prepare` to reject.
fn model_albedo(mesh: &tobj::Mesh, materials: &[tobj::Material]) -> Vec3 {
    mesh.material_id
        .and_then(|id| materials.get(id))
        .and_then(|material| material.diffuse)
        .map(|kd| Vec3::from_array(kd).clamp(Vec3::ZERO, Vec3::ONE))
        .unwrap_or(DEFAULT_ALBEDO)
}

fn vec3s(flat: &[f32]) -> impl Iterator<Item = Vec3> + '_ {
    flat.chunks_exact(3).map(Vec3::from_slice)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// Writes `text` to `name` in `dir`; returns the path.
    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// `usemtl` holds across `o` lines, so the object without a material comes first.
    const THREE_OBJECTS: &str = "mtllib colours.mtl\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\n\
        o plain\nf 1 5 6\n\
        o red_quad\nusemtl red\nf 1 2 3 4\n\
        o bright\nusemtl bright\nf 5 6 7\n";

    const MTL: &str = "newmtl red\nKd 0.9 0.1 0.05\n\nnewmtl bright\nKd 2.0 0.5 -1\n";

    #[test]
    fn bunny_counts() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
        let scene = load(&path).unwrap();
        assert_eq!(scene.vertex_count(), 1839);
        assert_eq!(scene.triangle_count(), 3674);
        assert_eq!(scene.albedo, vec![DEFAULT_ALBEDO; 1839]);
        assert!(scene.normals.is_none());
    }

    #[test]
    fn objects_are_merged_with_their_material_albedo() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "colours.mtl", MTL);
        let scene = load(&write(dir.path(), "scene.obj", THREE_OBJECTS)).unwrap();
        // The quad is triangulated; each object has its own vertices.
        assert_eq!(scene.triangle_count(), 4);
        assert_eq!(scene.vertex_count(), 4 + 3 + 3);
        assert_eq!(scene.triangles[0], [0, 1, 2]);
        assert_eq!(scene.triangles[1..3], [[3, 4, 5], [3, 5, 6]]);
        assert_eq!(scene.triangles[3], [7, 8, 9]);
        assert_eq!(scene.albedo[..3], [DEFAULT_ALBEDO; 3]);
        assert_eq!(scene.albedo[3..7], [Vec3::new(0.9, 0.1, 0.05); 4]);
        assert_eq!(scene.albedo[7..], [Vec3::new(1.0, 0.5, 0.0); 3]);
        for t in &scene.triangles {
            let [a, b, c] = t.map(|i| scene.positions[i as usize]);
            assert!((b - a).cross(c - a).length() > 0.0);
        }
    }

    #[test]
    fn missing_mtl_gives_default_albedo() {
        let dir = tempfile::tempdir().unwrap();
        let scene = load(&write(dir.path(), "scene.obj", THREE_OBJECTS)).unwrap();
        assert_eq!(scene.albedo, vec![DEFAULT_ALBEDO; scene.vertex_count()]);
    }

    #[test]
    fn normals_are_kept_only_when_every_object_has_them() {
        let dir = tempfile::tempdir().unwrap();
        let with =
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\no a\nf 1//1 2//1 3//1\no b\nf 3//1 2//1 1//1\n";
        let scene = load(&write(dir.path(), "with.obj", with)).unwrap();
        assert_eq!(scene.normals, Some(vec![Vec3::Z; 6]));
        let mixed = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\no a\nf 1//1 2//1 3//1\no b\nf 3 2 1\n";
        let scene = load(&write(dir.path(), "mixed.obj", mixed)).unwrap();
        assert_eq!(scene.normals, None);
        assert_eq!(scene.vertex_count(), 6);
    }

    #[test]
    fn no_faces_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(
            dir.path(),
            "lines.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\np 3\n",
        );
        let error = load(&path).unwrap_err();
        assert!(matches!(error, Error::Mesh { .. }));
        assert!(error.to_string().ends_with(": no faces"), "{error}");
    }

    #[test]
    fn parse_errors_are_one_line_mesh_errors() {
        let dir = tempfile::tempdir().unwrap();
        for text in ["v 0 0 0\nv 1 0 0\nf 1 2 3\n", "v 0 0 zero\nf 1 1 1\n"] {
            let error = load(&write(dir.path(), "bad.obj", text)).unwrap_err();
            assert!(matches!(error, Error::Mesh { .. }), "{error:?}");
            assert!(!error.to_string().contains('\n'));
        }
        let missing = load(&dir.path().join("absent.obj")).unwrap_err();
        assert!(matches!(missing, Error::Io { .. }));
    }
}
