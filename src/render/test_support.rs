//! Helpers shared by the tests of several render submodules.

use crate::bake::Transfer;

/// A transfer of `bands` and `channels` whose vertex count follows from `coeffs`.
pub fn transfer(bands: u32, channels: u32, coeffs: Vec<f32>) -> Transfer {
    let per_vertex = (channels * bands * bands) as usize;
    Transfer::new(bands, channels, coeffs.len() / per_vertex, coeffs)
        .expect("whole vertices of coefficients")
}
