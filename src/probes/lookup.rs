//! What a run-time does with probes: the matrix at any point, trilinearly interpolated from the
//! grid's eight probes around it, and irradiance for a normal from an incident radiance's SH.

use glam::{DVec3, Vec3};

use super::{ProbeForm, ProbeSet, ProbeStatus};

impl ProbeSet {
    /// The matrix at `point` (`[channel][row][k]`), trilinear in the grid's probes around it,
    /// leaving out invalid probes and weighting the rest by what remains; points beyond the
    /// outer probes take the nearest face's values. `None` without a grid, or where all eight
    /// probes are invalid.
    pub fn interpolate(&self, point: Vec3) -> Option<Vec<f32>> {
        let grid = self.grid?;
        let dims = grid.dims.map(|d| d as usize);
        let local = (point - grid.origin) / grid.spacing;
        let mut lower = [0usize; 3];
        let mut fraction = [0.0f32; 3];
        for axis in 0..3 {
            let last = dims[axis].saturating_sub(1) as f32;
            let x = local[axis].clamp(0.0, last);
            let base = x.floor().min((last - 1.0).max(0.0));
            lower[axis] = base as usize;
            fraction[axis] = x - base;
        }
        let mut out = vec![0.0f32; self.per_probe()];
        let mut total = 0.0f32;
        for corner in 0..8 {
            let mut index = [0usize; 3];
            let mut weight = 1.0f32;
            for axis in 0..3 {
                let upper = corner >> axis & 1 == 1;
                index[axis] = (lower[axis] + upper as usize).min(dims[axis] - 1);
                weight *= if upper {
                    fraction[axis]
                } else {
                    1.0 - fraction[axis]
                };
            }
            let p = index[0] + dims[0] * (index[1] + dims[1] * index[2]);
            if weight == 0.0 || self.status[p] == ProbeStatus::Invalid {
                continue;
            }
            total += weight;
            for (o, &m) in out.iter_mut().zip(self.matrix(p)) {
                *o += weight * m;
            }
        }
        (total > 0.0).then(|| out.into_iter().map(|m| m / total).collect())
    }

    /// The incident radiance's SH at probe `p` under `light` (`[k]` RGB), `[row]` RGB: for the
    /// irradiance form, the irradiance's SH.
    pub fn apply(&self, p: usize, light: &[[f32; 3]]) -> Vec<[f64; 3]> {
        let matrix = self.matrix(p);
        (0..self.rows)
            .map(|i| std::array::from_fn(|rgb| self.row_times_light(matrix, i, rgb, light)))
            .collect()
    }

    /// Irradiance (RGB) at a surface of unit normal `normal` lit through `matrix` (one
    /// probe's or [`ProbeSet::interpolate`]'s) by `light` (`[k]` RGB): the incident
    /// radiance's SH convolved with the clamped cosine, band by band.
    pub fn irradiance(&self, matrix: &[f32], light: &[[f32; 3]], normal: DVec3) -> [f64; 3] {
        let y = crate::sh::basis(self.bands, normal);
        std::array::from_fn(|rgb| {
            y.iter()
                .take(self.rows)
                .enumerate()
                .map(|(i, y_i)| {
                    self.row_factor(i) * self.row_times_light(matrix, i, rgb, light) * y_i
                })
                .sum()
        })
    }

    /// What row `i` of a matrix is multiplied by to give the irradiance's SH: band `l`'s
    /// clamped-cosine factor `A_l` for the radiance form, 1 for the irradiance form (its rows
    /// are convolved already).
    pub fn row_factor(&self, i: usize) -> f64 {
        match self.form {
            ProbeForm::Radiance => super::cosine_convolution((i as f64).sqrt().floor() as u32),
            ProbeForm::Irradiance => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::probes::ProbeGrid;
    use crate::sh::coeff_count;

    /// A 2 x 2 x 2 grid of one-band probes whose single entry is the probe's index.
    fn cube_of_probes() -> ProbeSet {
        let grid = ProbeGrid {
            origin: Vec3::ZERO,
            spacing: 2.0,
            dims: [2, 2, 2],
        };
        ProbeSet {
            bands: 1,
            channels: 1,
            form: ProbeForm::Radiance,
            rows: 1,
            grid: Some(grid),
            positions: grid.points(),
            status: vec![ProbeStatus::Placed; 8],
            matrices: (0..8).map(|p| p as f32).collect(),
            samples: 16,
        }
    }

    #[test]
    fn interpolation_is_exact_at_the_probes_and_trilinear_between() {
        let probes = cube_of_probes();
        for (p, &at) in probes.positions.iter().enumerate() {
            assert_eq!(probes.interpolate(at).unwrap(), [p as f32]);
        }
        // Probe index x + 2y + 4z: trilinear weights reproduce that linear function.
        let at = Vec3::new(0.5, 1.0, 1.5);
        let expected = 0.25 + 2.0 * 0.5 + 4.0 * 0.75;
        assert!((probes.interpolate(at).unwrap()[0] - expected).abs() < 1e-6);
        // Beyond the outer probes: the nearest face's values.
        let beyond = probes.interpolate(Vec3::new(-5.0, 1.0, 9.0)).unwrap()[0];
        assert!((beyond - (0.0 + 2.0 * 0.5 + 4.0)).abs() < 1e-6);
    }

    #[test]
    fn invalid_probes_are_left_out_of_the_interpolation() {
        let mut probes = cube_of_probes();
        probes.status[7] = ProbeStatus::Invalid;
        probes.matrices[7] = 1000.0;
        // The centre weighs all eight equally: the mean of the seven valid ones.
        let centre = probes.interpolate(Vec3::ONE).unwrap()[0];
        assert!((centre - 3.0).abs() < 1e-6, "{centre}");
        probes.status = vec![ProbeStatus::Invalid; 8];
        assert!(probes.interpolate(Vec3::ONE).is_none());
    }

    #[test]
    fn relighting_every_probe_applies_each_matrix() {
        let probes = cube_of_probes();
        let relit = probes.relight(&[[2.0, 3.0, 0.5]]);
        for (p, value) in relit.iter().enumerate() {
            let m = p as f32;
            assert_eq!(*value, [2.0 * m, 3.0 * m, 0.5 * m]);
            assert_eq!(
                probes.apply(p, &[[2.0, 3.0, 0.5]])[0],
                value.map(|v| v as f64)
            );
        }
    }

    #[test]
    fn irradiance_of_a_constant_sky_through_the_identity_is_pi_times_its_radiance() {
        let probes = ProbeSet::open_sky(3);
        let n = coeff_count(3);
        let identity = probes.matrix(0).to_vec();
        let mut light = vec![[0.0f32; 3]; n];
        light[0] = [2.0 * (4.0 * std::f32::consts::PI).sqrt(), 0.0, 1.0];
        for normal in [DVec3::Z, DVec3::new(0.6, -0.8, 0.0)] {
            let e = probes.irradiance(&identity, &light, normal);
            let pi = std::f64::consts::PI;
            assert!((e[0] - 2.0 * pi).abs() < 1e-5, "{e:?}");
            assert_eq!(e[1], 0.0);
        }
    }
}
