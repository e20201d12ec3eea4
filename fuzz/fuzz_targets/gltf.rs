//! The gltf reader under libFuzzer (see `prt_gpu::testing::hostile`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use prt_gpu::testing::hostile::{fuzz_one, Reader};

fuzz_target!(|data: &[u8]| fuzz_one(Reader::Gltf, data));
