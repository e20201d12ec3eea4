//! For the tests: the Khronos glTF-Validator's verdict on a file, through node.
//!
//! Every file the tool writes must pass the reference validator with no errors. It is an npm
//! package (`gltf-validator`, pinned in `ci/gltf-validator/package-lock.json`, installed by
//! `ci/test.sh` with `npm ci --prefix ci/gltf-validator`), run by
//! `ci/gltf-validator/validate.mjs`, which prints a summary of the report as JSON. Nothing in
//! the tool itself uses this module; it lives in the library so that the unit tests (`glb`)
//! and the integration tests (`tests/common`) share one implementation.

use std::io;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Deserialize;

/// The validator's report on one file: the counts of each severity and the first messages.
#[derive(Clone, Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct ValidatorReport {
    /// The version of the validator that ran.
    pub validator_version: String,
    pub num_errors: u64,
    pub num_warnings: u64,
    pub num_infos: u64,
    pub num_hints: u64,
    /// Whether more issues were found than `messages` holds.
    pub truncated: bool,
    pub messages: Vec<ValidatorMessage>,
}

/// One issue the validator found.
#[derive(Clone, Debug, Deserialize)]
pub struct ValidatorMessage {
    /// The issue code, such as `ACCESSOR_TOO_LONG`.
    pub code: String,
    pub message: String,
    /// 0 error, 1 warning, 2 info, 3 hint.
    pub severity: u8,
    /// Where in the JSON, such as `/accessors/0/count` (absent for binary-level issues).
    #[serde(default)]
    pub pointer: Option<String>,
}

impl ValidatorReport {
    /// The messages of one severity (0 error, 1 warning, 2 info, 3 hint).
    pub fn messages_of(&self, severity: u8) -> impl Iterator<Item = &ValidatorMessage> {
        self.messages.iter().filter(move |m| m.severity == severity)
    }

    /// One line per message, `severity code pointer: message`, for assertion failures.
    pub fn listing(&self) -> String {
        let mut out = format!(
            "{} errors, {} warnings, {} infos, {} hints (glTF-Validator {}){}",
            self.num_errors,
            self.num_warnings,
            self.num_infos,
            self.num_hints,
            self.validator_version,
            if self.truncated { ", truncated" } else { "" }
        );
        for m in &self.messages {
            let severity = ["error", "warning", "info", "hint"]
                .get(m.severity as usize)
                .unwrap_or(&"?");
            let pointer = m.pointer.as_deref().unwrap_or("");
            out += &format!("\n  {severity} {} {pointer}: {}", m.code, m.message);
        }
        out
    }
}

/// The directory of the node project that runs the validator.
pub fn validator_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("ci/gltf-validator")
}

/// Runs the Khronos glTF-Validator on the `.glb` or `.gltf` at `path`.
///
/// `None`, with the reason on stderr, where node or the validator is not installed; a panic
/// instead under CI (`CI` set), so the check never skips silently there. A panic, too, where
/// the validator is installed but cannot run on the file (it could not even tell glTF from
/// GLB, say): this is a test helper, and that is a failed check.
pub fn validate_or_skip(path: &Path) -> Option<ValidatorReport> {
    let dir = validator_dir();
    let skip = |reason: String| {
        assert!(
            std::env::var_os("CI").is_none(),
            "{reason} under CI (ci/test.sh installs it)"
        );
        eprintln!("skipping the glTF-Validator check: {reason}");
    };
    if !dir.join("node_modules/gltf-validator").is_dir() {
        skip(format!(
            "the glTF-Validator is not installed (npm ci --prefix {})",
            dir.display()
        ));
        return None;
    }
    let out = match Command::new("node")
        .arg(dir.join("validate.mjs"))
        .arg(path)
        .output()
    {
        Ok(out) => out,
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            skip("node is not installed".into());
            return None;
        }
        Err(e) => panic!("cannot run node: {e}"),
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "the glTF-Validator did not run on {} ({}): {stderr}",
        path.display(),
        out.status
    );
    let report = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "unexpected output from validate.mjs ({e}): {}",
            String::from_utf8_lossy(&out.stdout)
        )
    });
    Some(report)
}
