//! Morton (Z-order) codes: an order in which points close in space are mostly close in the
//! sequence. Vertices are sorted by it for coherent rays (`scene::prepare`), and the cosine
//! sample set by it so that runs of 16 samples form small cones (`sampling`).

use glam::{DVec3, Vec3};

/// Vertex indices sorted by 30-bit Morton code of their position in the bounding box, ties
/// broken by index, so equal inputs always give the same order.
pub fn morton_order(positions: &[Vec3]) -> Vec<u32> {
    let (min, max) = positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    // In f64, because max − min can overflow f32.
    let (min, extent) = (min.as_dvec3(), max.as_dvec3() - min.as_dvec3());
    let mut keyed: Vec<(u32, u32)> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| (morton_code(p.as_dvec3(), min, extent), i as u32))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

fn morton_code(p: DVec3, min: DVec3, extent: DVec3) -> u32 {
    let cell = |v: f64, lo: f64, size: f64| -> u32 {
        if size > 0.0 {
            // f64 → u32 casts saturate, and the clamp keeps the maximum inside 10 bits.
            (((v - lo) / size * 1024.0) as u32).min(1023)
        } else {
            0
        }
    };
    spread_bits(cell(p.x, min.x, extent.x))
        | spread_bits(cell(p.y, min.y, extent.y)) << 1
        | spread_bits(cell(p.z, min.z, extent.z)) << 2
}

/// Inserts two zero bits between each of the low 10 bits of `v`.
fn spread_bits(v: u32) -> u32 {
    let mut v = v & 0x3ff;
    v = (v | v << 16) & 0x0300_00ff;
    v = (v | v << 8) & 0x0300_f00f;
    v = (v | v << 4) & 0x030c_30c3;
    (v | v << 2) & 0x0924_9249
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_order_is_a_deterministic_permutation() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut positions: Vec<Vec3> = (0..5000)
            .map(|_| Vec3::new(next(), next(), next()))
            .collect();
        positions.extend_from_within(..100);
        let order = morton_order(&positions);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..positions.len() as u32).collect::<Vec<_>>());
        assert_eq!(order, morton_order(&positions));
        // Duplicated positions share a code; the lower original index comes first.
        for i in 0..100 {
            let first = order.iter().position(|&v| v == i).unwrap();
            let second = order.iter().position(|&v| v == i + 5000).unwrap();
            assert!(first < second);
        }
        let min = positions
            .iter()
            .fold(Vec3::INFINITY, |m, &p| m.min(p))
            .as_dvec3();
        let max = positions
            .iter()
            .fold(Vec3::NEG_INFINITY, |m, &p| m.max(p))
            .as_dvec3();
        let codes: Vec<u32> = order
            .iter()
            .map(|&i| morton_code(positions[i as usize].as_dvec3(), min, max - min))
            .collect();
        assert!(codes.windows(2).all(|w| w[0] <= w[1]));
    }

    #[test]
    fn morton_codes_interleave_axes() {
        assert_eq!(spread_bits(0b11), 0b1001);
        assert_eq!(spread_bits(1023), 0x0924_9249);
        let code = morton_code(DVec3::ONE, DVec3::ZERO, DVec3::ONE);
        assert_eq!(code, (1 << 30) - 1);
        assert_eq!(
            morton_code(DVec3::new(0.0, 0.5, 0.0), DVec3::ZERO, DVec3::ONE),
            2 << 27
        );
    }
}
