//! Relighting: per-vertex exit radiance from a baked transfer and an SH light.

use rayon::prelude::*;

use glam::Vec3;

use crate::bake::{BakedMesh, Transfer};
use crate::error::{Error, Result};
use crate::light::ShLight;

/// Per-vertex exit radiance `L_o[c] = sum_k light[k][c] * transfer[v][c][k]`, linear RGB.
///
/// Bands: only the coefficients both sides have are summed. A light with more bands than the
/// transfer is truncated (the transfer has no response to the higher bands); a light with
/// fewer bands is treated as zero-padded, which is exact for a band-limited light.
/// A one-channel transfer applies to all three light channels.
pub fn relight(transfer: &Transfer, light: &ShLight) -> Result<Vec<[f32; 3]>> {
    check_transfer(transfer)?;
    check_light(light)?;
    let per_channel = transfer.coeffs_per_channel();
    let channels = transfer.channels() as usize;
    let light = &light.coeffs[..per_channel.min(light.coeffs.len())];
    Ok(transfer
        .coeffs()
        .par_chunks_exact(per_channel * channels)
        // Vertices are tiny work items; batching keeps rayon's bookkeeping below the work.
        .with_min_len(1024)
        .map(|vertex| vertex_radiance(vertex, per_channel, light))
        .collect())
}

/// Per-vertex exit radiance of a baked mesh: [`relight`], times the vertex albedo where the
/// file stores its transfer albedo-free (`--storage lean`).
pub fn relight_baked(baked: &BakedMesh, light: &ShLight) -> Result<Vec<[f32; 3]>> {
    let radiance = relight(&baked.transfer, light)?;
    Ok(apply_albedo(baked, radiance))
}

/// `radiance` of `baked`'s vertices times their albedo where its transfer leaves it out.
pub fn apply_albedo(baked: &BakedMesh, mut radiance: Vec<[f32; 3]>) -> Vec<[f32; 3]> {
    if baked.metadata.albedo_free {
        tint_by(&mut radiance, &baked.scene.albedo);
    }
    radiance
}

/// Each vertex's radiance times its albedo, channel by channel.
pub fn tint_by(radiance: &mut [[f32; 3]], albedo: &[Vec3]) {
    for (r, a) in radiance.iter_mut().zip(albedo) {
        *r = [r[0] * a.x, r[1] * a.y, r[2] * a.z];
    }
}

/// One vertex: `vertex` holds its `channels * per_channel` coefficients, channel-major.
fn vertex_radiance(vertex: &[f32], per_channel: usize, light: &[[f32; 3]]) -> [f32; 3] {
    let channels = vertex.len() / per_channel;
    std::array::from_fn(|c| {
        let start = c.min(channels - 1) * per_channel;
        vertex[start..start + light.len()]
            .iter()
            .zip(light)
            .map(|(t, l)| t * l[c])
            .sum()
    })
}

/// Refuses channels other than RGB and lean (the shape itself holds by construction).
fn check_transfer(transfer: &Transfer) -> Result<()> {
    if !matches!(transfer.channels(), 1 | 3) {
        return Err(Error::Options(format!(
            "relight: transfer with {} channels (1 or 3)",
            transfer.channels()
        )));
    }
    Ok(())
}

fn check_light(light: &ShLight) -> Result<()> {
    let expected = crate::sh::coeff_count(light.bands);
    if light.bands == 0 || light.coeffs.len() != expected {
        return Err(Error::Options(format!(
            "relight: light with {} bands holds {} coefficients (need bands >= 1 and bands^2)",
            light.bands,
            light.coeffs.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::{bake, BakeOptions, CpuBackend, Mode, NoProgress};
    use crate::render::test_support::transfer;
    use crate::scene::builtin::icosphere;
    use glam::Vec3;

    #[test]
    fn relight_is_the_dot_product_per_channel() {
        // Two vertices, 2 bands (4 coefficients), RGB.
        let coeffs: Vec<f32> = (0..2 * 3 * 4).map(|i| i as f32 * 0.5 - 3.0).collect();
        let light = ShLight {
            bands: 2,
            coeffs: vec![
                [1.0, 2.0, -1.0],
                [0.5, 0.0, 3.0],
                [-2.0, 1.0, 0.25],
                [4.0, -0.5, 1.5],
            ],
        };
        let got = relight(&transfer(2, 3, coeffs.clone()), &light).unwrap();
        for (v, rgb) in got.iter().enumerate() {
            for (c, value) in rgb.iter().enumerate() {
                let t = &coeffs[(v * 3 + c) * 4..][..4];
                let expected = t[0] * light.coeffs[0][c]
                    + t[1] * light.coeffs[1][c]
                    + t[2] * light.coeffs[2][c]
                    + t[3] * light.coeffs[3][c];
                assert!(
                    (value - expected).abs() < 1e-5,
                    "v{v} c{c}: {value} vs {expected}"
                );
            }
        }
        // Vertex 0, red: t = [-3, -2.5, -2, -1.5], l = [1, 0.5, -2, 4] by hand.
        assert!((got[0][0] - (-3.0 - 1.25 + 4.0 - 6.0)).abs() < 1e-6);
    }

    #[test]
    fn relight_one_channel_transfer_lights_all_channels() {
        let light = ShLight {
            bands: 1,
            coeffs: vec![[1.0, 2.0, 3.0]],
        };
        let got = relight(&transfer(1, 1, vec![0.5, 2.0]), &light).unwrap();
        assert_eq!(got, vec![[0.5, 1.0, 1.5], [2.0, 4.0, 6.0]]);
    }

    #[test]
    fn relight_sums_over_the_bands_both_sides_have() {
        let t = transfer(2, 1, vec![1.0, 10.0, 100.0, 1000.0]);
        // A 1-band light: the missing bands count as zero.
        let dc_only = ShLight {
            bands: 1,
            coeffs: vec![[2.0; 3]],
        };
        assert_eq!(relight(&t, &dc_only).unwrap(), vec![[2.0; 3]]);
        // A 3-band light: band 2 meets no transfer and is ignored.
        let mut wide = ShLight {
            bands: 3,
            coeffs: vec![[1.0; 3]; 9],
        };
        wide.coeffs[4..].iter_mut().for_each(|l| *l = [1e6; 3]);
        assert_eq!(relight(&t, &wide).unwrap(), vec![[1111.0; 3]]);
    }

    #[test]
    fn relight_rejects_inconsistent_inputs() {
        let light = ShLight::constant(2, [1.0; 3]);
        assert!(relight(&transfer(2, 2, vec![0.0; 16]), &light).is_err());
        let bad_light = ShLight {
            bands: 2,
            coeffs: vec![[1.0; 3]; 3],
        };
        assert!(relight(&transfer(2, 3, vec![0.0; 24]), &bad_light).is_err());
        let empty = transfer(2, 3, Vec::new());
        assert_eq!(relight(&empty, &light).unwrap(), Vec::<[f32; 3]>::new());
    }

    #[test]
    fn white_unshadowed_sphere_under_unit_light_relights_to_one() {
        let options = BakeOptions {
            bands: 4,
            samples: 1024,
            mode: Mode::Unshadowed,
            albedo: Some(Vec3::ONE),
            ..BakeOptions::default()
        };
        let (baked, _) = bake(
            icosphere(Vec3::ZERO, 1.0, 2),
            &options,
            &CpuBackend,
            &NoProgress,
        )
        .unwrap();
        let radiance = relight(&baked.transfer, &ShLight::constant(4, [1.0; 3])).unwrap();
        assert_eq!(radiance.len(), baked.scene.vertex_count());
        let worst = radiance
            .iter()
            .flatten()
            .map(|v| (v - 1.0).abs())
            .fold(0.0f32, f32::max);
        // 1024 stratified samples integrate the clamped cosine to well under 1%.
        assert!(worst < 1e-2, "furthest from the white furnace: {worst}");
    }
}
