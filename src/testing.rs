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

fn python_output(script: &str, path: &Path) -> Option<serde_json::Value> {
    if !python_with_numpy() {
        return None;
    }
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(path)
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).expect("the reader prints JSON"))
}

fn python_with_numpy() -> bool {
    let numpy = Command::new("python3")
        .args(["-c", "import numpy"])
        .output();
    if numpy.is_ok_and(|o| o.status.success()) {
        return true;
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "python3 with numpy is missing under CI"
    );
    eprintln!("skipping: python3 with numpy is not available");
    false
}

/// What the README's lightmap reader (`lightmap::PYTHON_READER`) prints for the baked file
/// `path` (a .glb with its lightmap beside it), as JSON; `None`, with the reason printed, where
/// python3 with numpy and OpenEXR is missing (a panic under CI, where `ci/test.sh` installs
/// them). A reader that fails is a panic with its stderr.
pub fn lightmap_reader_output(path: &Path) -> Option<serde_json::Value> {
    let probe = Command::new("python3")
        .args(["-c", "import numpy, OpenEXR"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("CI").is_none(),
            "python3 with numpy and OpenEXR is missing under CI"
        );
        eprintln!("skipping: python3 with numpy and OpenEXR is not available");
        return None;
    }
    let out = Command::new("python3")
        .arg("-c")
        .arg(crate::lightmap::PYTHON_READER)
        .arg(path)
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).expect("the reader prints JSON"))
}
