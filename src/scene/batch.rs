//! The meshes of a batch bake (`prt-gpu bake a.obj meshes/ 'scans/*.ply' --out-dir baked/`):
//! files as given, the mesh files of directories, the matches of glob patterns; and where each
//! one's baked file goes.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The file-name endings `load` reads, lower case.
const MESH_ENDINGS: [&str; 5] = [".obj", ".ply", ".ply.gz", ".gltf", ".glb"];

/// Whether `path`'s name ends like a mesh file `load` reads.
pub fn is_mesh_file(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    MESH_ENDINGS.iter().any(|ending| name.ends_with(ending))
}

/// The meshes `given` names, in order: a file as it is (a missing one fails when it is baked,
/// not here, so that the rest of a batch still bakes), a directory's mesh files (not its
/// subdirectories'), a glob pattern's mesh files; the last two sorted by name. A directory or
/// pattern without mesh files is an error, as is a bad pattern.
pub fn mesh_files(given: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut meshes = Vec::new();
    for path in given {
        let text = path.to_string_lossy();
        if path.is_dir() {
            meshes.extend(non_empty(directory_meshes(path)?, path, "directory")?);
        } else if !path.exists() && text.contains(['*', '?', '[']) {
            meshes.extend(non_empty(glob_meshes(&text)?, path, "pattern")?);
        } else {
            meshes.push(path.clone());
        }
    }
    Ok(meshes)
}

fn directory_meshes(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut meshes: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && is_mesh_file(p))
        .collect();
    meshes.sort();
    Ok(meshes)
}

fn glob_meshes(pattern: &str) -> Result<Vec<PathBuf>> {
    let matches = glob::glob(pattern)
        .map_err(|e| Error::Options(format!("bad glob pattern {pattern}: {e}")))?;
    let mut meshes: Vec<PathBuf> = matches
        .filter_map(|m| m.ok())
        .filter(|p| p.is_file() && is_mesh_file(p))
        .collect();
    meshes.sort();
    Ok(meshes)
}

fn non_empty(meshes: Vec<PathBuf>, given: &Path, what: &str) -> Result<Vec<PathBuf>> {
    if meshes.is_empty() {
        return Err(Error::Options(format!(
            "{what} {} holds no mesh files ({})",
            given.display(),
            MESH_ENDINGS.join(", ")
        )));
    }
    Ok(meshes)
}

/// A mesh's name without its directory and endings: `scans/dragon.ply.gz` is `dragon`.
pub fn mesh_name(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name.to_string(),
    }
}

/// Where each mesh's bake goes: `out_dir/<name>.prt.glb`. Two meshes of one name (`a/x.obj`,
/// `b/x.ply`) would overwrite each other: an error naming both.
pub fn output_paths(meshes: &[PathBuf], out_dir: &Path) -> Result<Vec<PathBuf>> {
    let mut seen: HashMap<PathBuf, &Path> = HashMap::new();
    let mut outputs = Vec::with_capacity(meshes.len());
    for mesh in meshes {
        let output = out_dir.join(format!("{}.prt.glb", mesh_name(mesh)));
        if let Some(other) = seen.insert(output.clone(), mesh) {
            return Err(Error::Options(format!(
                "{} and {} would both be baked to {}",
                other.display(),
                mesh.display(),
                output.display()
            )));
        }
        outputs.push(output);
    }
    Ok(outputs)
}

/// Each mesh's share of a batch's work, for the bar over the whole batch: its size on disk, a
/// gzip file counted at four times its size (PLY shrinks about that much), at least 1 (a file
/// that cannot be read is reported when its turn comes).
pub fn work_weights(meshes: &[PathBuf]) -> Vec<u64> {
    meshes
        .iter()
        .map(|mesh| {
            let bytes = std::fs::metadata(mesh).map_or(0, |m| m.len());
            let gzip = mesh
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
            (if gzip { 4 * bytes } else { bytes }).max(1)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_follows_the_bytes_to_bake() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, len: usize| {
            let path = dir.path().join(name);
            std::fs::write(&path, vec![b'x'; len]).unwrap();
            path
        };
        let meshes = [
            write("a.obj", 1000),
            write("b.ply.gz", 100),
            write("empty.obj", 0),
            dir.path().join("gone.obj"),
        ];
        assert_eq!(work_weights(&meshes), [1000, 400, 1, 1]);
    }

    #[test]
    fn directories_and_patterns_give_their_mesh_files_sorted() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "b.obj",
            "a.PLY",
            "c.ply.gz",
            "d.glb",
            "notes.txt",
            "e.obj.bak",
        ] {
            std::fs::write(dir.path().join(name), "").unwrap();
        }
        std::fs::create_dir(dir.path().join("sub.obj")).unwrap();
        let names = |paths: Vec<PathBuf>| -> Vec<String> {
            paths
                .iter()
                .map(|p| p.file_name().unwrap().to_string_lossy().into())
                .collect()
        };
        let all = mesh_files(&[dir.path().to_path_buf()]).unwrap();
        assert_eq!(names(all), ["a.PLY", "b.obj", "c.ply.gz", "d.glb"]);
        let pattern = dir.path().join("*.ply*");
        assert_eq!(names(mesh_files(&[pattern]).unwrap()), ["c.ply.gz"]);
        // Files as given, in the order given, missing ones included.
        let given = [dir.path().join("missing.obj"), dir.path().join("b.obj")];
        assert_eq!(mesh_files(&given).unwrap(), given);
    }

    #[test]
    fn empty_directories_and_patterns_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("notes.txt"), "").unwrap();
        let error = mesh_files(&[dir.path().to_path_buf()])
            .unwrap_err()
            .to_string();
        assert!(error.contains("holds no mesh files"), "{error}");
        let error = mesh_files(&[dir.path().join("*.obj")])
            .unwrap_err()
            .to_string();
        assert!(error.contains("pattern"), "{error}");
    }

    #[test]
    fn outputs_are_named_after_the_meshes_and_never_shared() {
        let out = Path::new("baked");
        let meshes = [PathBuf::from("a/dragon.ply.gz"), PathBuf::from("bunny.obj")];
        let outputs = output_paths(&meshes, out).unwrap();
        assert_eq!(
            outputs,
            [out.join("dragon.prt.glb"), out.join("bunny.prt.glb")]
        );
        let clash = [PathBuf::from("a/x.obj"), PathBuf::from("b/x.ply")];
        let error = output_paths(&clash, out).unwrap_err().to_string();
        assert!(
            error.contains("a/x.obj") && error.contains("b/x.ply"),
            "{error}"
        );
    }
}
