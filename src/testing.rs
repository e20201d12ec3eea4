//! For the test suites, unit and integration alike: small checks that several suites share.
//! Nothing in the tool itself uses this module. Where a check needs a tool the machine lacks,
//! it skips with a printed reason, except under CI, where that is a failure: no check may
//! skip silently there.

use std::path::Path;
use std::process::Command;

/// The names in `dir`, sorted: what a test left behind (no partial or temporary files).
pub fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// What the README's numpy reader (`glb::PYTHON_READER`) prints for the baked file `path`, as
/// JSON; `None`, with the reason printed, where python3 with numpy is missing (a panic under CI,
/// where `ci/test.sh` installs numpy). A reader that fails is a panic with its stderr.
pub fn numpy_reader_output(path: &Path) -> Option<serde_json::Value> {
    python_output(crate::glb::PYTHON_READER, path)
}

/// What the README's numpy reader of compressed files (`glb::compressed::PYTHON_READER`)
/// prints for `path`, as [`numpy_reader_output`] does.
pub fn compressed_reader_output(path: &Path) -> Option<serde_json::Value> {
    python_output(crate::glb::compressed::PYTHON_READER, path)
}

/// What the numpy reader of local-lights files (`glb::local::PYTHON_READER`) prints for
/// `path`, as [`numpy_reader_output`] does.
pub fn local_reader_output(path: &Path) -> Option<serde_json::Value> {
    python_output(crate::glb::local::PYTHON_READER, path)
}

fn python_output(script: &str, path: &Path) -> Option<serde_json::Value> {
    python_with_numpy().then(|| python_json(script, path))
}

fn python_with_numpy() -> bool {
    python_with(&["numpy"])
}

/// Whether python3 can import every one of `modules`; where it cannot, a printed reason and
/// `false`, except under CI (`CI` set), where `ci/test.sh` installs them: a panic.
pub fn python_with(modules: &[&str]) -> bool {
    let probe = Command::new("python3")
        .args(["-c", &format!("import {}", modules.join(", "))])
        .output();
    if probe.is_ok_and(|o| o.status.success()) {
        return true;
    }
    let missing = modules.join(" and ");
    assert!(
        std::env::var_os("CI").is_none(),
        "python3 with {missing} is missing under CI"
    );
    eprintln!("skipping: python3 with {missing} is not available");
    false
}

/// What `script` (Python) prints, as JSON, when run with `argument`; a panic with its stderr
/// when it fails.
pub fn python_json(script: &str, argument: &Path) -> serde_json::Value {
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(argument)
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("the script prints JSON")
}

/// The RGBA pixels of an OpenEXR image, row-major, and its width.
pub fn read_exr_rgba(path: &Path) -> (usize, Vec<[f32; 4]>) {
    exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| (size.0, vec![[0.0f32; 4]; size.0 * size.1]),
        |out: &mut (usize, Vec<[f32; 4]>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
            out.1[pos.1 * out.0 + pos.0] = [r, g, b, a];
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    .layer_data
    .channel_data
    .pixels
}

/// What the README's lightmap reader (`lightmap::PYTHON_READER`) prints for the baked file
/// `path` (a .glb with its lightmap beside it), as JSON; `None`, with the reason printed, where
/// python3 with numpy and OpenEXR is missing (a panic under CI, where `ci/test.sh` installs
/// them). A reader that fails is a panic with its stderr.
pub fn lightmap_reader_output(path: &Path) -> Option<serde_json::Value> {
    python_with(&["numpy", "OpenEXR"]).then(|| python_json(crate::lightmap::PYTHON_READER, path))
}
