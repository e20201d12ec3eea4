//! How many bands a bake keeps (`--bands auto`): the energy above each band, and transfer cut
//! to fewer bands.

use super::*;

/// The fraction of a transfer's energy (sum of squared coefficients over vertices and channels)
/// in each band `l`.
pub fn band_energy_fractions(transfer: &Transfer) -> Vec<f64> {
    let mut energy = BandEnergy::new(transfer.bands());
    energy.add(transfer);
    energy.fractions()
}

/// The fewest bands whose transfer leaves less than `threshold` of the energy in the bands
/// above them, and the fraction it leaves.
pub fn choose_bands(transfer: &Transfer, threshold: f64) -> (u32, f64) {
    let mut energy = BandEnergy::new(transfer.bands());
    energy.add(transfer);
    energy.choose(threshold)
}

/// The energy of each band summed over runs of vertices in order: the whole transfer at once,
/// or the chunks of a streamed bake, give the same bits.
pub struct BandEnergy {
    energy: Vec<f64>,
}

impl BandEnergy {
    pub fn new(bands: u32) -> BandEnergy {
        BandEnergy {
            energy: vec![0.0; bands as usize],
        }
    }

    pub fn add(&mut self, transfer: &Transfer) {
        assert_eq!(transfer.bands() as usize, self.energy.len());
        let n = transfer.coeffs_per_channel();
        for row in transfer.coeffs().chunks_exact(n) {
            for (k, &t) in row.iter().enumerate() {
                self.energy[(k as f64).sqrt() as usize] += (t as f64) * (t as f64);
            }
        }
    }

    /// The fraction of the energy in each band.
    pub fn fractions(&self) -> Vec<f64> {
        let total: f64 = self.energy.iter().sum();
        self.energy
            .iter()
            .map(|e| e / total.max(f64::MIN_POSITIVE))
            .collect()
    }

    /// [`choose_bands`] of what was added.
    pub fn choose(&self, threshold: f64) -> (u32, f64) {
        let fractions = self.fractions();
        let bands = self.energy.len() as u32;
        (1..=bands)
            .map(|kept| (kept, fractions[kept as usize..].iter().sum::<f64>()))
            .find(|&(_, beyond)| beyond < threshold)
            .unwrap_or((bands, 0.0))
    }
}

/// `transfer` with only its first `bands` bands: the lower bands of SH transfer do not depend on
/// the higher ones, so this is the transfer a bake of `bands` bands computes.
pub fn truncate_bands(transfer: &Transfer, bands: u32) -> Transfer {
    let (n, kept) = (transfer.coeffs_per_channel(), coeff_count(bands));
    Transfer::new(
        bands,
        transfer.channels(),
        transfer.vertex_count(),
        transfer
            .coeffs()
            .chunks_exact(n)
            .flat_map(|row| row[..kept].iter().copied())
            .collect(),
    )
    .expect("the kept coefficients of every row")
}

/// A baked mesh cut to `bands` bands (its lightmap too), its metadata saying so.
pub fn truncate_baked(baked: &mut BakedMesh, bands: u32) {
    baked.transfer = truncate_bands(&baked.transfer, bands);
    if let Some(texels) = &mut baked.lightmap {
        texels.transfer = truncate_bands(&texels.transfer, bands);
        texels.held = texels.held.as_ref().map(|held| held.truncated(bands));
    }
    baked.metadata.bands = bands;
}

#[cfg(test)]
mod band_tests {
    use super::*;

    #[test]
    fn bands_are_chosen_by_the_energy_above_them() {
        // One vertex, one channel, 3 bands: energies 1 (l = 0), 0.09 (l = 1), 0.01 (l = 2).
        let transfer = Transfer::new(3, 1, 1, vec![1.0, 0.3, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0])
            .expect("one vertex of 3 bands");
        let fractions = band_energy_fractions(&transfer);
        assert!((fractions[2] - 0.01 / 1.1).abs() < 1e-9, "{fractions:?}");
        assert_eq!(choose_bands(&transfer, 0.05).0, 2);
        assert_eq!(choose_bands(&transfer, 0.2).0, 1);
        assert_eq!(choose_bands(&transfer, 0.001).0, 3);
        let cut = truncate_bands(&transfer, 2);
        assert_eq!(cut.coeffs(), vec![1.0, 0.3, 0.0, 0.0]);
    }

    #[test]
    fn a_bake_cut_to_fewer_bands_is_the_bake_of_fewer_bands() {
        let scene = crate::scene::builtin::icosphere(Vec3::ZERO, 1.0, 2);
        let plane = crate::scene::builtin::grid_plane(
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::X * 3.0,
            Vec3::NEG_Z * 3.0,
            6,
            Vec3::ONE,
        );
        let scene = crate::scene::builtin::merge(&[scene, plane]);
        let bake_with = |bands| {
            let options = BakeOptions {
                bands,
                samples: 256,
                ..BakeOptions::default()
            };
            bake(scene.clone(), &options, &CpuBackend, &NoProgress)
                .unwrap()
                .0
        };
        let (eight, four) = (bake_with(8), bake_with(4));
        let cut = truncate_bands(&eight.transfer, 4);
        for (a, b) in cut.coeffs().iter().zip(four.transfer.coeffs()) {
            // The same sums; only the rotation's rounding differs with the band count.
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1e-2), "{a} vs {b}");
        }
    }
}
