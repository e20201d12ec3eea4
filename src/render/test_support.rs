//! Helpers shared by the tests of several render submodules.

use std::path::Path;

use crate::bake::Transfer;

/// A transfer of `bands` and `channels` whose vertex count follows from `coeffs`.
pub fn transfer(bands: u32, channels: u32, coeffs: Vec<f32>) -> Transfer {
    let per_vertex = (channels * bands * bands) as usize;
    Transfer {
        bands,
        channels,
        vertex_count: coeffs.len() / per_vertex,
        coeffs,
    }
}

/// The names in `dir`, sorted: what a test left behind.
pub fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
