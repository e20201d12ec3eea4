//! prt-gpu: precomputed radiance transfer baking.
//!
//! The data flows one way, one module per step:
//! `scene` (load, prepare) → `bvh` → `sampling` + `sh` → `bake` (cpu or gpu backend, bounces)
//! → `glb` (the baked file; `lightmap` for transfer per texel); `light` + a baked transfer → `render` (relight, preview images);
//! `compress` shrinks a baked transfer by clustered PCA (and relights the compressed form);
//! `sweep` bakes over strategies and sample counts against a reference → `chart`.
//! Imports go the same way (no cycles); docs/architecture.md says what each module owns and
//! may import.

// A value read from a file is checked, never unwrapped: an unwrap outside the tests is an
// error under clippy (tests/hostile_files.rs checks the same without it).
#![cfg_attr(not(test), deny(clippy::unwrap_used))]

pub mod bake;
pub mod bvh;
pub mod chart;
pub mod color;
pub mod compress;
pub mod device;
pub mod error;
pub mod fs;
pub mod glb;
pub mod gltf_validator;
pub mod images;
pub mod light;
pub mod lightmap;
pub mod local;
pub mod morton;
pub mod packet;
pub mod pipeline;
pub mod precision;
pub mod probes;
pub mod ray;
pub mod receivers;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod sh;
pub mod shaders;
pub mod shard;
pub mod spec;
pub mod surface;
pub mod sweep;
pub mod testing;
pub mod view;
pub mod x3d;
pub mod zonal;

pub use error::{Error, Result};
