//! Every file the tool writes passes the Khronos glTF-Validator with no errors: the built-in
//! scene and an OBJ, shadowed and interreflected, baked by the `prt-gpu` binary. And the check
//! can fail: a copy with a wrong accessor count is reported.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::validate_gltf;
use prt_gpu::gltf_validator::ValidatorReport;

/// Bakes `mesh` (the built-in scene when `None`) in `mode` with 64 samples into `dir`.
fn bake(dir: &Path, mesh: Option<&str>, mode: &str) -> PathBuf {
    let target = dir.join(format!("{}-{mode}.glb", mesh.map_or("builtin", |_| "mesh")));
    let mut command = Command::new(env!("CARGO_BIN_EXE_prt-gpu"));
    command.arg("bake");
    if let Some(mesh) = mesh {
        command.arg(Path::new(env!("CARGO_MANIFEST_DIR")).join(mesh));
    }
    let out = command
        .args(["--samples", "64", "--mode", mode, "--device", "cpu", "-o"])
        .arg(&target)
        .output()
        .expect("run prt-gpu");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    target
}

/// The validator's report on a baked file, which must have no errors; `None` where the
/// validator is not installed (outside CI).
fn assert_valid(mesh: Option<&str>, mode: &str) -> Option<ValidatorReport> {
    let dir = tempfile::tempdir().unwrap();
    let file = bake(dir.path(), mesh, mode);
    let report = validate_gltf(&file)?;
    assert_eq!(report.num_errors, 0, "{}", report.listing());
    // Warnings are not failures, but they are worth seeing.
    if report.num_warnings > 0 {
        eprintln!("{}: {}", file.display(), report.listing());
    }
    Some(report)
}

#[test]
fn builtin_scene_shadowed_is_valid_gltf() {
    assert_valid(None, "shadowed");
}

#[test]
fn builtin_scene_interreflected_is_valid_gltf() {
    assert_valid(None, "interreflected");
}

#[test]
fn obj_shadowed_is_valid_gltf() {
    assert_valid(Some("tests/data/bunny.obj"), "shadowed");
}

#[test]
fn obj_interreflected_is_valid_gltf() {
    assert_valid(Some("tests/data/bunny.obj"), "interreflected");
}

/// `bytes` (a .glb) with its JSON chunk replaced by `doc`, the BIN chunk kept.
fn with_json(bytes: &[u8], doc: &serde_json::Value) -> Vec<u8> {
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let bin = &bytes[20 + word(12) as usize..];
    let mut json = serde_json::to_vec(doc).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = 20 + json.len() + bin.len();
    let mut out = Vec::with_capacity(total);
    for word in [word(0), word(4), total as u32, json.len() as u32, word(16)] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json);
    out.extend_from_slice(bin);
    out
}

#[test]
fn a_wrong_accessor_count_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let good = bake(dir.path(), Some("tests/data/bunny.obj"), "shadowed");
    let bytes = std::fs::read(&good).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let mut doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    // One more NORMAL than there are positions: past the end of its buffer view, too.
    let normal = doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]
        .as_u64()
        .unwrap() as usize;
    let count = &mut doc["accessors"][normal]["count"];
    *count = (count.as_u64().unwrap() + 1).into();
    let broken = dir.path().join("broken.glb");
    std::fs::write(&broken, with_json(&bytes, &doc)).unwrap();

    // Our own reader refuses it too.
    assert!(prt_gpu::glb::read_glb(&broken).is_err());
    let Some(report) = validate_gltf(&broken) else {
        return;
    };
    assert!(report.num_errors > 0, "{}", report.listing());
    let codes: Vec<&str> = report.messages_of(0).map(|m| m.code.as_str()).collect();
    assert!(
        codes.contains(&"MESH_PRIMITIVE_UNEQUAL_ACCESSOR_COUNT"),
        "{}",
        report.listing()
    );
    // The unbroken file still passes: the errors are the edit's.
    assert_eq!(validate_gltf(&good).unwrap().num_errors, 0);
}
