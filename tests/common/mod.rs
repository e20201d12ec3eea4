//! Shared by the integration tests: the backends to run every check on.
//!
//! The GPU backend is opened once per test binary on any adapter (lavapipe in CI). Without an
//! adapter the GPU half of a test is skipped with a printed reason, except under CI (or with
//! PRT_GPU_REQUIRE_ADAPTER=1), where that is a failure: GPU tests must never silently skip.
//!
//! [`validate_gltf`] runs the Khronos glTF-Validator on a written file (the same runner the unit
//! tests use); it skips likewise where node or the validator is missing, except under CI.

#![allow(dead_code)]

use std::path::Path;
use std::sync::OnceLock;

use prt_gpu::bake::gpu::{Chunking, GpuBaker};
use prt_gpu::bake::Backend;
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
pub fn backends() -> Vec<Backend<'static>> {
    let mut all = vec![Backend::Cpu];
    if let Some(baker) = gpu_baker() {
        all.push(Backend::Gpu {
            baker,
            chunking: Chunking::default(),
        });
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
