//! Translucent media: what `--subsurface` names or a glTF material describes, and the dipole
//! diffusion profile of each colour channel (Jensen, Marschner, Levoy & Hanrahan 2001, eq. 4
//! and 5), in closed form: the profile, its integral over a disc, the total diffuse
//! reflectance, the reach that leaves out a given tail.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::scene::gltf::volume::MaterialVolume;

/// The fraction of the total diffuse reflectance the cut-off at the reach may leave out.
pub const TAIL: f64 = 1e-2;

/// A homogeneous translucent medium: its index of refraction relative to the outside, and its
/// absorption and reduced scattering coefficients per colour channel, per millimetre;
/// `mm_per_unit` says how many millimetres a scene unit is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubsurfaceMaterial {
    pub ior: f32,
    pub absorption: [f32; 3],
    pub reduced_scattering: [f32; 3],
    pub mm_per_unit: f32,
}

/// Measured media (Jensen et al. 2001, figure 5: `sigma_s'` and `sigma_a` in mm^-1, R G B),
/// with the index of refraction the paper uses for them (1.3; 1.5 for marble). Spectralon
/// absorbs nothing the paper could measure: its light all comes back, after a short walk.
pub const PRESETS: [(&str, SubsurfaceMaterial); 12] = [
    (
        "apple",
        preset(1.3, [0.0030, 0.0034, 0.046], [2.29, 2.39, 1.97]),
    ),
    (
        "chicken1",
        preset(1.3, [0.015, 0.077, 0.19], [0.15, 0.21, 0.38]),
    ),
    (
        "chicken2",
        preset(1.3, [0.018, 0.088, 0.20], [0.19, 0.25, 0.32]),
    ),
    (
        "cream",
        preset(1.3, [0.0002, 0.0028, 0.0163], [7.38, 5.47, 3.15]),
    ),
    (
        "ketchup",
        preset(1.3, [0.061, 0.97, 1.45], [0.18, 0.07, 0.03]),
    ),
    (
        "marble",
        preset(1.5, [0.0021, 0.0041, 0.0071], [2.19, 2.62, 3.00]),
    ),
    (
        "potato",
        preset(1.3, [0.0024, 0.0090, 0.12], [0.68, 0.70, 0.55]),
    ),
    (
        "skim-milk",
        preset(1.3, [0.0014, 0.0025, 0.0142], [0.70, 1.22, 1.90]),
    ),
    (
        "skin1",
        preset(1.3, [0.032, 0.17, 0.48], [0.74, 0.88, 1.01]),
    ),
    (
        "skin2",
        preset(1.3, [0.013, 0.070, 0.145], [1.09, 1.59, 1.79]),
    ),
    (
        "spectralon",
        preset(1.3, [0.0, 0.0, 0.0], [11.6, 20.4, 14.9]),
    ),
    (
        "whole-milk",
        preset(1.3, [0.0011, 0.0024, 0.014], [2.55, 3.21, 3.77]),
    ),
];

const fn preset(
    ior: f32,
    absorption: [f32; 3],
    reduced_scattering: [f32; 3],
) -> SubsurfaceMaterial {
    SubsurfaceMaterial {
        ior,
        absorption,
        reduced_scattering,
        mm_per_unit: MM_PER_METRE,
    }
}

impl SubsurfaceMaterial {
    /// The preset named `name`.
    pub fn preset(name: &str) -> Option<SubsurfaceMaterial> {
        PRESETS.iter().find(|(n, _)| *n == name).map(|(_, m)| *m)
    }

    /// Refuses a medium the dipole does not describe: an index of refraction outside
    /// [1, 3], negative or non-finite coefficients, a channel with neither absorption nor
    /// scattering, a scale that is not a positive length.
    pub fn validate(&self) -> Result<()> {
        match self.problem() {
            Some(why) => Err(Error::Options(format!("--subsurface: {why}"))),
            None => Ok(()),
        }
    }

    /// What [`Self::validate`] refuses, if anything.
    fn problem(&self) -> Option<String> {
        if !(1.0..=3.0).contains(&self.ior) {
            return Some(format!("index of refraction {} (1 to 3)", self.ior));
        }
        let coefficients = self.absorption.iter().chain(&self.reduced_scattering);
        if !coefficients.into_iter().all(|c| c.is_finite() && *c >= 0.0) {
            return Some("absorption and scattering must be finite and not negative".into());
        }
        if (0..3).any(|c| self.absorption[c] + self.reduced_scattering[c] <= 0.0) {
            return Some("every channel needs absorption or scattering (or both)".into());
        }
        if !(self.mm_per_unit.is_finite() && self.mm_per_unit > 0.0) {
            return Some(format!(
                "{} mm per scene unit: the scale must be a positive length",
                self.mm_per_unit
            ));
        }
        None
    }

    /// The medium a glTF material's scattering volume describes (`KHR_materials_volume` with
    /// `KHR_materials_volume_scatter`): the extinction `sigma_t = -ln(c) / d` of the
    /// attenuation colour `c` at distance `d` (world units: metres); the single-scatter
    /// albedo from the multi-scatter one by the fit the extension gives
    /// ([`single_scatter_albedo`]), `sigma_s = rho_ss sigma_t` and `sigma_a = sigma_t -
    /// sigma_s`; the reduced scattering `sigma_s (1 - g)` of the phase function's anisotropy
    /// `g` (the similarity relation the dipole rests on). Why it describes no medium, if not.
    pub fn of_volume(volume: &MaterialVolume) -> std::result::Result<SubsurfaceMaterial, String> {
        let distance = volume.attenuation_distance as f64;
        if !(distance.is_finite() && distance > 0.0) {
            return Err(format!(
                "attenuationDistance {distance}: scattering needs a positive, finite one"
            ));
        }
        let anisotropy = volume.scatter_anisotropy as f64;
        if !(-1.0 < anisotropy && anisotropy < 1.0) {
            return Err(format!("scatterAnisotropy {anisotropy} (between -1 and 1)"));
        }
        let color = volume.attenuation_color;
        if !color.iter().all(|c| *c > 0.0 && *c <= 1.0) {
            return Err(format!(
                "attenuationColor {color:?} (each above 0, at most 1)"
            ));
        }
        let multi = volume.multiscatter_color;
        if !multi.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(format!("multiscatterColor {multi:?} (each 0 to 1)"));
        }
        let mut material = SubsurfaceMaterial {
            ior: volume.ior,
            absorption: [0.0; 3],
            reduced_scattering: [0.0; 3],
            mm_per_unit: MM_PER_METRE,
        };
        for c in 0..3 {
            let extinction = -(color[c] as f64).ln() / distance / MM_PER_METRE as f64;
            let scattering = single_scatter_albedo(multi[c] as f64) * extinction;
            material.absorption[c] = (extinction - scattering) as f32;
            material.reduced_scattering[c] = (scattering * (1.0 - anisotropy)) as f32;
        }
        match material.problem() {
            Some(why) => Err(why),
            None => Ok(material),
        }
    }

    /// The dipole of channel `c`, its lengths in scene units.
    pub fn dipole(&self, c: usize) -> Dipole {
        let per_unit = self.mm_per_unit as f64;
        Dipole::new(
            self.ior as f64,
            self.absorption[c] as f64 * per_unit,
            self.reduced_scattering[c] as f64 * per_unit,
        )
    }
}

/// Millimetres in a metre: glTF's unit.
const MM_PER_METRE: f32 = 1000.0;

/// The single-scatter albedo of a medium whose multi-scatter albedo (the colour it shows after
/// many bounces) is `multi`: Kulla & Conty's fit (2017), as `KHR_materials_volume_scatter`
/// defines it, held to [0, 1].
pub fn single_scatter_albedo(multi: f64) -> f64 {
    let root = (9.59217 + 41.6808 * multi + 17.7126 * multi * multi).sqrt();
    let term = 4.09712 + 4.20863 * multi - root;
    (1.0 - term * term).clamp(0.0, 1.0)
}

/// The dipole diffusion profile of one channel (Jensen et al. 2001, eq. 4 and 5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dipole {
    /// The reduced albedo `sigma_s' / sigma_t'`.
    pub albedo: f64,
    /// The effective transport coefficient `sqrt(3 sigma_a sigma_t')`.
    pub sigma_tr: f64,
    /// Depths of the real and the virtual source.
    pub z_real: f64,
    pub z_virtual: f64,
}

impl Dipole {
    pub fn new(ior: f64, absorption: f64, reduced_scattering: f64) -> Dipole {
        let sigma_t = absorption + reduced_scattering;
        // Diffuse Fresnel reflectance (Egan and Hilgeman's fit) and the boundary term A.
        let fdr = -1.440 / (ior * ior) + 0.710 / ior + 0.668 + 0.0636 * ior;
        let boundary = (1.0 + fdr) / (1.0 - fdr);
        let z_real = 1.0 / sigma_t;
        Dipole {
            albedo: reduced_scattering / sigma_t,
            sigma_tr: (3.0 * absorption * sigma_t).sqrt(),
            z_real,
            z_virtual: z_real * (1.0 + 4.0 * boundary / 3.0),
        }
    }

    /// `R_d(r)`: exitance at distance `r` per unit incident flux.
    pub fn profile(&self, r: f64) -> f64 {
        let term = |z: f64| {
            let d = (r * r + z * z).sqrt();
            z * (1.0 + self.sigma_tr * d) * (-self.sigma_tr * d).exp() / (d * d * d)
        };
        self.albedo / (4.0 * PI) * (term(self.z_real) + term(self.z_virtual))
    }

    /// `integral_0^r R_d(s) 2 pi s ds`, in closed form: with `d = sqrt(s^2 + z^2)`,
    /// `z (1 + sigma d) e^(-sigma d) / d^3 s ds = -z d(e^(-sigma d) / d)`.
    pub fn within(&self, r: f64) -> f64 {
        let term = |z: f64| {
            let d = (r * r + z * z).sqrt();
            (-self.sigma_tr * z).exp() - z * (-self.sigma_tr * d).exp() / d
        };
        self.albedo / 2.0 * (term(self.z_real) + term(self.z_virtual))
    }

    /// The total diffuse reflectance, `within(infinity)`: at most 1, and 1 for a medium that
    /// does not absorb.
    pub fn total(&self) -> f64 {
        let term = |z: f64| (-self.sigma_tr * z).exp();
        self.albedo / 2.0 * (term(self.z_real) + term(self.z_virtual))
    }

    /// The smallest distance beyond which the plane's exitance is at most `tail` of the total
    /// (bisection on [`Self::within`], to a part in a thousand).
    pub fn reach(&self, tail: f64) -> f64 {
        let total = self.total();
        let enough = |r: f64| total - self.within(r) <= tail * total;
        let mut high = self.z_virtual.max(1e-30);
        while !enough(high) {
            high *= 2.0;
        }
        let mut low = 0.0;
        while high - low > 1e-3 * high {
            let mid = 0.5 * (low + high);
            if enough(mid) {
                high = mid;
            } else {
                low = mid;
            }
        }
        high
    }

    /// `R_d` over the ring from `r - radius` to `r + radius` (the disc of `radius` where
    /// `r <= radius`) outside the disc of radius `own` about the receiver (whose light the
    /// receiver takes from its own irradiance), over the whole ring's area: what a point at
    /// distance `r` standing for a disc of that radius sends the receiver per unit area. With
    /// `own` zero, the ring's mean.
    pub fn ring_mean_outside(&self, r: f64, radius: f64, own: f64) -> f64 {
        let (inner, outer) = ((r - radius).max(0.0), r + radius);
        let area = PI * (outer * outer - inner * inner);
        if outer <= own {
            return 0.0;
        }
        if area <= 0.0 {
            return self.profile(r);
        }
        (self.within(outer) - self.within(inner.max(own))) / area
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn media() -> [Dipole; 3] {
        [
            Dipole::new(1.3, 0.032, 0.74),
            Dipole::new(1.5, 0.0, 2.0),
            Dipole::new(1.0, 1.0, 0.1),
        ]
    }

    /// The closed form of the profile's integral is the integral (against a midpoint rule),
    /// its limit is Jensen's total diffuse reflectance, which is 1 without absorption, and the
    /// reach leaves out what it says.
    #[test]
    fn the_profiles_integral_is_its_closed_form() {
        for dipole in media() {
            let r_max = 20.0 * dipole.z_virtual;
            let steps = 200_000;
            let dr = r_max / steps as f64;
            let numeric: f64 = (0..steps)
                .map(|i| {
                    let r = (i as f64 + 0.5) * dr;
                    dipole.profile(r) * 2.0 * PI * r * dr
                })
                .sum();
            let closed = dipole.within(r_max);
            assert!(
                (numeric - closed).abs() < 1e-6 * closed.max(1e-3),
                "{numeric} against {closed}"
            );
            let one_minus = (3.0 * (1.0 - dipole.albedo)).sqrt();
            let boundary = (dipole.z_virtual / dipole.z_real - 1.0) * 3.0 / 4.0;
            let jensen = dipole.albedo / 2.0
                * (1.0 + (-4.0 / 3.0 * boundary * one_minus).exp())
                * (-one_minus).exp();
            assert!(
                (dipole.total() - jensen).abs() < 1e-12,
                "{} against {jensen}",
                dipole.total()
            );
            assert!(dipole.total() <= 1.0);
            let reach = dipole.reach(TAIL);
            let left = dipole.total() - dipole.within(reach);
            assert!(left <= TAIL * dipole.total() * (1.0 + 1e-9), "{left}");
            assert!(dipole.total() - dipole.within(0.99 * reach) > 0.9 * TAIL * dipole.total());
        }
        assert!(
            (media()[1].total() - 1.0).abs() < 1e-12,
            "no absorption returns everything"
        );
    }

    /// A ring's mean times its area is the profile's integral over it (the disc about a point
    /// holds what is within its radius); outside a receiver's own disc, the part beyond it;
    /// within it, nothing.
    #[test]
    fn ring_means_integrate_the_profile() {
        let dipole = media()[0];
        for (r, radius) in [(0.0f64, 0.5f64), (0.2, 0.5), (3.0, 0.25)] {
            let (inner, outer) = ((r - radius).max(0.0), r + radius);
            let area = PI * (outer * outer - inner * inner);
            let mass = dipole.ring_mean_outside(r, radius, 0.0) * area;
            assert!((mass - (dipole.within(outer) - dipole.within(inner))).abs() < 1e-12);
            let own = 0.5 * (inner + outer);
            let beyond = dipole.ring_mean_outside(r, radius, own) * area;
            assert!((beyond - (dipole.within(outer) - dipole.within(own))).abs() < 1e-12);
            assert_eq!(dipole.ring_mean_outside(r, radius, outer), 0.0);
        }
    }

    /// The extension's fit takes a multi-scatter albedo from 0 to 1 to a single-scatter one
    /// from 0 to 1, rising; the dipole's total diffuse reflectance of the medium it gives
    /// (index-matched, as the fit's random walks are) is the colour asked for to within 0.1:
    /// two models of one medium agree.
    #[test]
    fn a_volumes_multiscatter_colour_is_about_the_dipoles_reflectance() {
        assert!(single_scatter_albedo(0.0) < 1e-5);
        assert!(single_scatter_albedo(1.0) > 1.0 - 1e-4);
        let mut last = -1.0;
        for step in 0..=20 {
            let multi = step as f64 / 20.0;
            let single = single_scatter_albedo(multi);
            assert!(single > last, "{multi}: {single} after {last}");
            last = single;
            let reflectance = Dipole::new(1.0, 1.0 - single, single).total();
            assert!((reflectance - multi).abs() < 0.1, "{multi}: {reflectance}");
        }
    }

    /// A volume that describes no medium says why.
    #[test]
    fn a_volume_without_a_medium_is_refused_with_its_reason() {
        let wax = MaterialVolume {
            material: 0,
            label: "0".into(),
            ior: 1.4,
            attenuation_color: [0.5, 0.6, 0.7],
            attenuation_distance: 0.002,
            multiscatter_color: [0.8, 0.6, 0.4],
            scatter_anisotropy: 0.0,
        };
        assert!(SubsurfaceMaterial::of_volume(&wax).is_ok());
        let cases = [
            (
                MaterialVolume {
                    attenuation_distance: f32::INFINITY,
                    ..wax.clone()
                },
                "attenuationDistance",
            ),
            (
                MaterialVolume {
                    attenuation_color: [0.0, 0.5, 0.5],
                    ..wax.clone()
                },
                "attenuationColor",
            ),
            (
                MaterialVolume {
                    multiscatter_color: [f32::NAN; 3],
                    ..wax.clone()
                },
                "multiscatterColor",
            ),
            (
                MaterialVolume {
                    scatter_anisotropy: 1.0,
                    ..wax.clone()
                },
                "scatterAnisotropy",
            ),
            (
                MaterialVolume {
                    ior: 4.0,
                    ..wax.clone()
                },
                "index of refraction",
            ),
        ];
        for (volume, says) in cases {
            let why = SubsurfaceMaterial::of_volume(&volume).unwrap_err();
            assert!(why.contains(says), "{why}");
        }
    }
}
