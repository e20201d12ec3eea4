//! Sample directions on the sphere and the random numbers behind them.
//!
//! The generator is 32-bit only (PCG with a 32-bit state and the RXS-M-XS output), so WGSL,
//! which has no 64-bit integers, can reproduce it bit for bit with wrapping `u32` arithmetic.
//! Floats are formed from the top 24 bits, which every f32 represents exactly.

use glam::{DVec3, Vec3};

/// PCG-RXS-M-XS-32: a 32-bit linear congruential state with a permuted output.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u32,
}

const PCG_MULTIPLIER: u32 = 747_796_405;
const PCG_INCREMENT: u32 = 2_891_336_453;

/// The output permutation of one state (also a good 32-bit integer hash).
pub fn pcg_hash(input: u32) -> u32 {
    let state = input
        .wrapping_mul(PCG_MULTIPLIER)
        .wrapping_add(PCG_INCREMENT);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

impl Pcg32 {
    /// A stream determined by a 64-bit seed (both halves matter).
    pub fn new(seed: u64) -> Self {
        let low = seed as u32;
        let high = (seed >> 32) as u32;
        Pcg32 {
            state: pcg_hash(low ^ pcg_hash(high)),
        }
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULTIPLIER).wrapping_add(PCG_INCREMENT);
        let word = ((old >> ((old >> 28) + 4)) ^ old).wrapping_mul(277_803_737);
        (word >> 22) ^ word
    }

    /// Uniform in [0, 1), a multiple of 2^-24.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// The largest sample count the baker accepts (1024 x 1024 strata).
pub const MAX_SAMPLES: u32 = 1 << 20;

/// The square number nearest to `requested` (at least 1): stratified sampling needs a
/// sqrt(N) x sqrt(N) grid.
pub fn nearest_square(requested: u32) -> u32 {
    let side = (requested as f64).sqrt().round().max(1.0) as u32;
    side * side
}

/// Directions on the unit sphere with one shared quadrature weight (uniform density).
#[derive(Clone, Debug, PartialEq)]
pub struct SampleSet {
    pub directions: Vec<Vec3>,
    /// Solid angle per sample: 4 pi / N.
    pub weight: f64,
}

impl SampleSet {
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }
}

/// Maps a point of the unit square to the sphere with uniform density:
/// `t = 2 acos(sqrt(1 - u))`, `p = 2 pi v`, so `cos t = 1 - 2u` is uniform.
pub fn square_to_sphere(u: f64, v: f64) -> DVec3 {
    let cos_theta = 1.0 - 2.0 * u;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * v;
    DVec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Jittered stratified sampling of the sphere: one random point in each cell of a
/// `side x side` grid on the unit square, mapped by [`square_to_sphere`]. Sample
/// `i = a * side + b` lies in cell (a, b). `count` must be a square.
pub fn stratified_sphere(count: u32, seed: u64) -> SampleSet {
    let side = (count as f64).sqrt().round() as u32;
    assert_eq!(side * side, count, "stratified_sphere needs a square count");
    let mut rng = Pcg32::new(seed);
    let mut directions = Vec::with_capacity(count as usize);
    for a in 0..side {
        for b in 0..side {
            let u = (a as f64 + rng.next_f32() as f64) / side as f64;
            let v = (b as f64 + rng.next_f32() as f64) / side as f64;
            directions.push(square_to_sphere(u, v).normalize().as_vec3());
        }
    }
    SampleSet {
        directions,
        weight: 4.0 * std::f64::consts::PI / count as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generator_is_deterministic_and_seed_dependent() {
        let a: Vec<u32> = (0..8)
            .scan(Pcg32::new(7), |r, _| Some(r.next_u32()))
            .collect();
        let b: Vec<u32> = (0..8)
            .scan(Pcg32::new(7), |r, _| Some(r.next_u32()))
            .collect();
        let c: Vec<u32> = (0..8)
            .scan(Pcg32::new(7 | (1 << 40)), |r, _| Some(r.next_u32()))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c, "the high half of the seed must matter");
    }

    #[test]
    fn floats_are_uniform_in_the_unit_interval() {
        let mut rng = Pcg32::new(1);
        let n = 100_000;
        let mut histogram = [0u32; 10];
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            histogram[(x * 10.0) as usize] += 1;
        }
        // Each bin holds 10,000 +- 95 (1 sigma); 5 sigma bounds.
        for count in histogram {
            assert!((count as i64 - 10_000).abs() < 475, "{histogram:?}");
        }
    }

    #[test]
    fn nearest_square_rounds_to_the_closest_grid() {
        assert_eq!(nearest_square(1024), 1024);
        assert_eq!(nearest_square(1000), 1024);
        assert_eq!(nearest_square(2), 1);
        assert_eq!(nearest_square(0), 1);
        assert_eq!(nearest_square(3), 4);
        assert_eq!(nearest_square(300), 289);
    }

    #[test]
    fn stratified_directions_are_unit_one_per_stratum() {
        let set = stratified_sphere(64 * 64, 3);
        assert_eq!(set.len(), 4096);
        let side = 64;
        for (i, d) in set.directions.iter().enumerate() {
            assert!((d.length() - 1.0).abs() < 1e-6);
            // Invert the map and check the point lies in its own cell.
            let u = (1.0 - d.z as f64) / 2.0;
            let mut v = (d.y as f64).atan2(d.x as f64) / (2.0 * std::f64::consts::PI);
            if v < 0.0 {
                v += 1.0;
            }
            let (a, b) = (i / side, i % side);
            let cell_u = u * side as f64;
            let cell_v = v * side as f64;
            assert!(cell_u > a as f64 - 1e-3 && cell_u < (a + 1) as f64 + 1e-3);
            // The azimuth wraps at v = 1.
            assert!(
                (cell_v > b as f64 - 1e-3 && cell_v < (b + 1) as f64 + 1e-3)
                    || (b == side - 1 && cell_v < 1e-3),
                "sample {i}: v cell {cell_v} not in {b}"
            );
        }
    }

    #[test]
    fn stratified_mean_direction_is_near_zero() {
        let set = stratified_sphere(32 * 32, 11);
        let mean: Vec3 = set.directions.iter().sum::<Vec3>() / set.len() as f32;
        // Stratification makes this far smaller than the 1/sqrt(N) of plain Monte Carlo.
        assert!(mean.length() < 0.01, "{mean}");
        assert!((set.weight * set.len() as f64 - 4.0 * std::f64::consts::PI).abs() < 1e-12);
    }
}
