//! Lighting in the SH basis: what a baked transfer is dotted with.

use serde::{Deserialize, Serialize};

/// RGB lighting coefficients `l_k = integral L_in(w) y_k(w) dw` in the basis of `sh`
/// (`coeffs[k] = [r, g, b]`, `k = l(l+1) + m`, `bands^2` entries).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShLight {
    pub bands: u32,
    pub coeffs: Vec<[f32; 3]>,
}

impl ShLight {
    /// Constant radiance `rgb` from every direction: only the DC term, `rgb * sqrt(4 pi)`.
    pub fn constant(bands: u32, rgb: [f32; 3]) -> Self {
        let mut coeffs = vec![[0.0; 3]; crate::sh::coeff_count(bands)];
        let dc = (4.0 * std::f32::consts::PI).sqrt();
        coeffs[0] = rgb.map(|c| c * dc);
        ShLight { bands, coeffs }
    }
}
