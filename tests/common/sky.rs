//! The band-limited sky of the oracle tests (tests/oracle_distant.rs, tests/oracle_probes.rs).

use glam::{DVec3, Vec3};
use prt_gpu::testing::oracle::OracleLight;

/// The sky: 9 RGB coefficients, index `l(l+1) + m`. With `y_1,-1 = -0.4886 y`, a negative
/// `c_1` makes it brighter from above (+Y, up); every other coefficient is non-zero and differs
/// between the channels, so that each of the 9 transfer coefficients of each channel counts.
/// Positive everywhere (checked in [`sky`]): about 1.7 at the zenith, 0.2 at the nadir, its
/// least 0.13, 0.026 and 0.11 (red, green, blue).
pub const SKY: [[f32; 3]; 9] = [
    [3.0, 2.7, 2.4],
    [-1.6, -1.5, -1.2],
    [0.3, -0.2, 0.1],
    [-0.25, 0.15, 0.3],
    [0.2, -0.1, 0.15],
    [-0.3, -0.2, 0.25],
    [0.25, 0.3, -0.2],
    [0.1, -0.25, 0.2],
    [-0.35, -0.3, -0.25],
];

/// The sky's coefficients, and the oracle's light, after checking that the sky is positive
/// (over 10,000 Fibonacci directions, with the baker's basis): a proper density for the path
/// tracer's importance sampling of the map.
pub fn sky() -> (Vec<Vec3>, OracleLight) {
    let coefficients: Vec<Vec3> = SKY.iter().map(|&c| Vec3::from(c)).collect();
    let n = 10_000;
    let least = (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let r = (1.0 - z * z).sqrt();
            let y = prt_gpu::sh::basis(3, DVec3::new(r * phi.cos(), r * phi.sin(), z));
            coefficients
                .iter()
                .zip(&y)
                .map(|(c, &y)| c.as_dvec3() * y)
                .sum::<DVec3>()
                .min_element()
        })
        .fold(f64::INFINITY, f64::min);
    assert!(least > 0.0, "the sky dips to {least}");
    let light = OracleLight::Sky {
        bands: 3,
        coefficients: coefficients.clone(),
    };
    (coefficients, light)
}
