//! For the test suites, unit and integration alike: small checks that several suites share.
//! Nothing in the tool itself uses this module. Where a check needs a tool the machine lacks,
//! it skips with a printed reason, except under CI, where that is a failure: no check may
//! skip silently there.

use std::path::Path;
use std::process::Command;

pub mod hostile;
pub mod mutate;
pub mod oracle;
pub mod seeds;

/// The names in `dir`, sorted: what a test left behind (no partial or temporary files).
pub fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| {
            entry
                .expect("a readable entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
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

/// What the numpy reader of probes (`glb::probes::PYTHON_READER`) prints for `path`, as
/// [`numpy_reader_output`] does.
pub fn probes_reader_output(path: &Path) -> Option<serde_json::Value> {
    python_output(crate::glb::probes::PYTHON_READER, path)
}

/// What the numpy reader of zonal transfer (`glb::zonal::PYTHON_READER`) prints for `path`,
/// as [`numpy_reader_output`] does.
pub fn zonal_reader_output(path: &Path) -> Option<serde_json::Value> {
    python_output(crate::glb::zonal::PYTHON_READER, path)
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

/// Headless Chromium (Debian's `chromium`), for the web viewer's and the X3D export's tests:
/// WebGL2 on SwiftShader, Chromium's software GL, so no GPU is needed.
#[derive(Clone)]
pub struct Chromium {
    program: String,
    extra_flags: Vec<String>,
}

/// The flags that give WebGL2 in headless Chromium on a machine without a GPU (Chromium 156):
/// ANGLE on SwiftShader, which newer Chromium only allows when asked for explicitly; no
/// sandbox (the tests may run as root); pixels one to one with CSS pixels.
const CHROMIUM_FLAGS: [&str; 8] = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--hide-scrollbars",
    "--force-device-scale-factor=1",
    // Pages load their neighbours from file:// (X_ITE its scene and components).
    "--allow-file-access-from-files",
];

impl Chromium {
    /// Chromium where it is installed; where it is not, a printed reason and `None`, except
    /// under CI (`CI` set), where `ci/test.sh` installs it: a panic.
    pub fn find_or_skip() -> Option<Chromium> {
        for program in ["chromium", "chromium-browser"] {
            let probe = Command::new(program).arg("--version").output();
            if probe.is_ok_and(|o| o.status.success()) {
                return Some(Chromium {
                    program: program.to_string(),
                    extra_flags: Vec::new(),
                });
            }
        }
        assert!(
            std::env::var_os("CI").is_none(),
            "chromium is missing under CI (ci/test.sh installs it)"
        );
        eprintln!("skipping: chromium is not installed (apt-get install chromium)");
        None
    }

    /// This Chromium, reading pages only after `milliseconds` of virtual time, in which their
    /// timers run at once: for pages that draw after loading (X_ITE). Not for timing pages:
    /// their clock is virtual too.
    pub fn after_virtual_time(&self, milliseconds: u32) -> Chromium {
        let mut chromium = self.clone();
        chromium
            .extra_flags
            .push(format!("--virtual-time-budget={milliseconds}"));
        chromium
    }

    /// A screenshot of `url` in a `width x height` window, as RGB pixels, row-major.
    pub fn screenshot(&self, url: &str, width: u32, height: u32) -> image::RgbImage {
        let scratch = Scratch::new();
        let png = scratch.0.join("screenshot.png");
        self.run(
            &scratch.0,
            &[
                &format!("--window-size={width},{height}"),
                &format!("--screenshot={}", png.display()),
                url,
            ],
        );
        let image = image::open(&png)
            .unwrap_or_else(|e| panic!("chromium's screenshot of {url}: {e}"))
            .into_rgb8();
        assert_eq!(image.dimensions(), (width, height), "screenshot of {url}");
        image
    }

    /// The DOM of `url` once it has loaded (its scripts run), serialised.
    pub fn dump_dom(&self, url: &str) -> String {
        let scratch = Scratch::new();
        let out = self.run(&scratch.0, &["--dump-dom", url]);
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// Runs Chromium with its own profile directory. One Chromium at a time per test binary:
    /// pages timed on virtual time (X_ITE's) still load their scripts in real time, and two
    /// browsers competing for the CPU made a page miss its budget.
    fn run(&self, profile: &Path, args: &[&str]) -> std::process::Output {
        static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let _turn = ONE_AT_A_TIME
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let out = Command::new(&self.program)
            .args(CHROMIUM_FLAGS)
            .args(&self.extra_flags)
            .arg(format!(
                "--user-data-dir={}",
                profile.join("profile").display()
            ))
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("run {}: {e}", self.program));
        assert!(
            out.status.success(),
            "chromium {args:?} failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }
}

/// The text of the element `<pre id="report" ...>` of a dumped DOM (the viewer's reports).
pub fn report_element(dom: &str) -> Option<&str> {
    let start = dom.find("<pre id=\"report\"")?;
    let text_start = start + dom[start..].find('>')? + 1;
    let text_end = text_start + dom[text_start..].find("</pre>")?;
    Some(&dom[text_start..text_end])
}

/// A directory of its own for one run of an outside tool (Chromium, the oracle), removed
/// afterwards (the library cannot use the tests' `tempfile`).
struct Scratch(std::path::PathBuf);

impl Scratch {
    fn new() -> Scratch {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "prt-gpu-scratch-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        Scratch(dir)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
