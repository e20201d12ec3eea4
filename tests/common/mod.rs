//! Shared by the integration tests: the backends to run every check on.
//!
//! The GPU backend is opened once per test binary on any adapter (lavapipe in CI). Without an
//! adapter the GPU half of a test is skipped with a printed reason, except under CI (or with
//! PRT_GPU_REQUIRE_ADAPTER=1), where that is a failure: GPU tests must never silently skip.
//!
//! [`validate_gltf`] runs the Khronos glTF-Validator on a written file (the same runner the unit
//! tests use); it skips likewise where node or the validator is missing, except under CI.

#![allow(dead_code)]

pub mod counting;
pub mod gltf_builder;
pub mod pixels;
pub mod sky;

use std::path::Path;
use std::sync::OnceLock;

use prt_gpu::bake::gpu::GpuBaker;
use prt_gpu::bake::{Backend, CpuBackend, GpuBackend};
use prt_gpu::device;
use prt_gpu::gltf_validator::{self, ValidatorReport};

static GPU: OnceLock<Option<GpuBaker>> = OnceLock::new();

/// The GPU baker, or `None` (with the reason printed) where there is no adapter outside CI.
pub fn gpu_baker() -> Option<&'static GpuBaker> {
    GPU.get_or_init(|| {
        device::any_adapter_or_skip()
            .map(|context| GpuBaker::new(context).expect("compile the kernels"))
    })
    .as_ref()
}

/// The CPU backend, and the GPU backend where an adapter exists.
pub fn backends() -> Vec<Box<dyn Backend>> {
    let mut all: Vec<Box<dyn Backend>> = vec![Box::new(CpuBackend)];
    if let Some(baker) = gpu_baker() {
        all.push(Box::new(GpuBackend::new(baker)));
    }
    all
}

/// The Khronos glTF-Validator's report on the file at `path`, or `None` (with the reason
/// printed) where node or the validator is not installed outside CI.
pub fn validate_gltf(path: &Path) -> Option<ValidatorReport> {
    gltf_validator::validate_or_skip(path)
}

/// Runs the prt-gpu binary with `args` in `dir`.
pub fn prt_gpu(args: &[&str], dir: &Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_prt-gpu"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run prt-gpu")
}

/// The number printed in `text` right after `marker`, up to `end` (a report line's figure:
/// `number_after(stderr, "coefficient error ", '%')`); `None` where there is none.
pub fn number_after<T: std::str::FromStr>(text: &str, marker: &str, end: char) -> Option<T> {
    let rest = text.split(marker).nth(1)?;
    rest.split(end).next()?.parse().ok()
}

/// The glTF scene with the most parts among the test files: 115 primitives, meshes shown by
/// several nodes.
pub const ENGINE_GLB: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/gltf/2CylinderEngine.glb"
);

/// A sky, ground and sun light of `bands` bands, written to `dir/name` by `prt-gpu light`, with
/// `extra` options.
pub fn write_light(dir: &Path, name: &str, bands: u32, extra: &[&str]) {
    let bands = bands.to_string();
    let mut args = vec![
        "light",
        "--sky",
        "0.6,0.7,0.9",
        "--ground",
        "0.2,0.15,0.1",
        "--sun",
        "0.5,0.8,0.3",
        "--bands",
        &bands,
        "-o",
        name,
    ];
    args.extend_from_slice(extra);
    let out = prt_gpu(&args, dir);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A bad invocation: the file it needs (name, contents), its arguments, and a piece of the
/// one-line error it must print.
pub struct BadInput {
    pub case: &'static str,
    pub file: Option<(&'static str, &'static [u8])>,
    pub args: &'static [&'static str],
    pub expect: &'static str,
}

/// Writes the input's file to a fresh directory, runs prt-gpu there, and checks the failure.
pub fn assert_clean_failure(input: &BadInput) {
    let case = input.case;
    let dir = tempfile::tempdir().unwrap();
    if let Some((name, contents)) = input.file {
        std::fs::write(dir.path().join(name), contents).unwrap();
    }
    let before = prt_gpu::testing::entries(dir.path());
    let out = prt_gpu(input.args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{case}: succeeded: {stderr}");
    assert!(!stderr.contains("panicked"), "{case}: panicked: {stderr}");
    // Informational notes (e.g. which backend bakes) may precede the error.
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| !l.starts_with("note: "))
        .collect();
    assert_eq!(
        lines.len(),
        1,
        "{case}: expected one error line, got {stderr:?}"
    );
    assert!(
        lines[0]
            .to_lowercase()
            .contains(&input.expect.to_lowercase()),
        "{case}: {:?} does not mention {:?}",
        lines[0],
        input.expect
    );
    assert_eq!(
        prt_gpu::testing::entries(dir.path()),
        before,
        "{case}: files were left behind"
    );
    dir.close().unwrap();
}

/// Random points on the triangles `triangles` of a scene, fixed-seeded.
pub fn points_on(
    triangles: std::ops::Range<u32>,
    count: usize,
) -> Vec<prt_gpu::receivers::SurfacePoint> {
    let mut random = prt_gpu::sampling::Pcg32::new(7);
    (0..count)
        .map(|_| {
            let span = triangles.end - triangles.start;
            let triangle =
                triangles.start + ((random.next_f32() * span as f32) as u32).min(span - 1);
            let (a, b) = (random.next_f32(), random.next_f32());
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            prt_gpu::receivers::SurfacePoint {
                triangle,
                barycentrics: [1.0 - a - b, a, b],
            }
        })
        .collect()
}

/// The point of the ground's triangles (the first 128 of `scene`) at `at`, `at` lying on it.
pub fn nearest_point_on_ground(
    scene: &prt_gpu::scene::Scene,
    at: glam::Vec3,
) -> prt_gpu::receivers::SurfacePoint {
    for t in 0..128u32 {
        let [a, b, c] = scene.triangles[t as usize].map(|i| scene.positions[i as usize]);
        let area = (b - a).cross(c - a).y;
        let w = [
            (c - b).cross(at - b).y / area,
            (a - c).cross(at - c).y / area,
            (b - a).cross(at - a).y / area,
        ];
        if w.iter().all(|&w| w >= -1e-6) {
            return prt_gpu::receivers::SurfacePoint {
                triangle: t,
                barycentrics: w,
            };
        }
    }
    panic!("{at} is not on the ground");
}

/// The float `VEC3` values of accessor `index` in a .glb's BIN chunk (tightly packed).
pub fn vec3_accessor(bytes: &[u8], doc: &serde_json::Value, index: u64) -> Vec<[f32; 3]> {
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let bin = &bytes[28 + json_len..];
    let accessor = &doc["accessors"][index as usize];
    assert_eq!(accessor["type"], "VEC3");
    assert_eq!(accessor["componentType"], 5126);
    let view = &doc["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
    assert!(view.get("byteStride").is_none_or(|s| s == 12));
    let start = view["byteOffset"].as_u64().unwrap_or(0) as usize
        + accessor["byteOffset"].as_u64().unwrap_or(0) as usize;
    let count = accessor["count"].as_u64().unwrap() as usize;
    bin[start..start + 12 * count]
        .chunks_exact(12)
        .map(|v| {
            std::array::from_fn(|c| f32::from_le_bytes(v[4 * c..4 * c + 4].try_into().unwrap()))
        })
        .collect()
}
