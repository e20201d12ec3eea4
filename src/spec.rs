//! What a bake is, in one value: the receivers it computes transfer at, the transfer it
//! computes, how that transfer is stored and the file that holds it. The command line, part
//! files, fingerprints and `merge` all speak it; [`BakeSpec::validate`] holds every rule about
//! which of its choices go together.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bake::adaptive::TargetError;
use crate::bake::{BakeOptions, Fit, Mode, Storage, DEFAULT_SAMPLES, DEFAULT_SAMPLING};
use crate::precision::Precision;
use crate::receivers::PointDensity;
use crate::sampling::Sampling;
use crate::{Error, Result};

/// The layout of [`BakeSpec`] this build writes and reads.
pub const SPEC_VERSION: u32 = 1;

/// The most bands `--bands auto` bakes and chooses among.
pub const AUTO_MAX_BANDS: u32 = 8;

/// Everything that decides a bake's output besides the mesh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BakeSpec {
    pub version: u32,
    pub receivers: ReceiverSpec,
    pub transfer: TransferSpec,
    pub storage: StorageSpec,
    pub container: Container,
}

/// Where transfer is computed: at the vertices or at surface points fitted back to them, and
/// optionally at the texels of a lightmap.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReceiverSpec {
    pub fit: Fit,
    /// Least-squares fit: surface points per vertex, on average.
    pub fit_points: f32,
    /// A lightmap about this many texels on its longer side: on a generated atlas for a mesh,
    /// on the scene's own UV set for a glTF scene (`receivers::uv_set`).
    pub lightmap: Option<u32>,
    /// The glTF scene's `TEXCOORD_n` set the lightmap bakes on, where the user names one.
    /// Left out of the JSON when unset, so specs written before it hash as they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lightmap_uv: Option<u32>,
}

/// What transfer is computed, and from how many samples.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransferSpec {
    pub bands: Bands,
    /// Requested sample directions; the grid strategies use the nearest square.
    pub samples: u32,
    pub sampling: Sampling,
    pub seed: u64,
    pub mode: Mode,
    /// Replaces every material's albedo (linear RGB) when set.
    pub albedo: Option<[f32; 3]>,
    /// Interreflected mode: bounces after the direct pass, and the energy fraction below which
    /// a bounce ends them early.
    pub bounces: u32,
    pub bounce_tolerance: f64,
    /// Samples cast per receiver until this error is reached, instead of `samples` each.
    pub target_error: Option<TargetError>,
}

/// The band count: given, or the fewest (up to [`AUTO_MAX_BANDS`]) that leave less than
/// `threshold` of the transfer's energy above them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Bands {
    Fixed(u32),
    Auto { threshold: f64 },
}

impl Bands {
    /// The bands the transfer is computed with (auto computes the most it chooses among).
    pub fn baked(self) -> u32 {
        match self {
            Bands::Fixed(bands) => bands,
            Bands::Auto { .. } => AUTO_MAX_BANDS,
        }
    }
}

/// How the transfer is stored: its channels, its floats, and per vertex or compressed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StorageSpec {
    pub channels: Storage,
    pub precision: Precision,
    pub layout: Layout,
}

/// Per-vertex transfer as it is, or compressed by clustered PCA.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    PerVertex,
    Cpca(Compression),
}

/// A clustered-PCA shape, or an error target to choose one by.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    Shape { clusters: u32, components: u32 },
    Target { error: f64 },
}

/// The file a bake is written to: a baked mesh (.glb), or the input glTF scene written back
/// with its transfer added.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Container {
    Mesh,
    GltfInPlace,
}

impl Default for BakeSpec {
    /// The command line's defaults.
    fn default() -> Self {
        BakeSpec {
            version: SPEC_VERSION,
            receivers: ReceiverSpec {
                fit: Fit::Point,
                fit_points: PointDensity::default().per_vertex,
                lightmap: None,
                lightmap_uv: None,
            },
            transfer: TransferSpec {
                bands: Bands::Fixed(4),
                samples: DEFAULT_SAMPLES,
                sampling: DEFAULT_SAMPLING,
                seed: 1,
                mode: Mode::Shadowed,
                albedo: None,
                bounces: 3,
                bounce_tolerance: 0.0,
                target_error: None,
            },
            storage: StorageSpec {
                channels: Storage::Rgb,
                precision: Precision::F32,
                layout: Layout::PerVertex,
            },
            container: Container::Mesh,
        }
    }
}

impl BakeSpec {
    /// What the bake stage computes for this spec.
    pub fn options(&self) -> BakeOptions {
        let transfer = &self.transfer;
        BakeOptions {
            bands: transfer.bands.baked(),
            samples: transfer.samples,
            sampling: transfer.sampling,
            seed: transfer.seed,
            mode: transfer.mode,
            albedo: transfer.albedo.map(Vec3::from_array),
            bounces: transfer.bounces,
            bounce_tolerance: transfer.bounce_tolerance,
            fit: self.receivers.fit,
            point_density: PointDensity {
                per_vertex: self.receivers.fit_points,
                ..PointDensity::default()
            },
            lightmap: self.receivers.lightmap,
            target_error: transfer.target_error,
            storage: self.storage.channels,
        }
    }

    /// The compression asked for, if any.
    pub fn compression(&self) -> Option<Compression> {
        match self.storage.layout {
            Layout::PerVertex => None,
            Layout::Cpca(compression) => Some(compression),
        }
    }

    /// The spec as the text a part file's fingerprint hashes: its canonical JSON.
    pub fn fingerprint_text(&self) -> String {
        serde_json::to_string(self).unwrap_or_else(|_| format!("{self:?}"))
    }

    /// Every rule about the spec's values and which of them go together, in one place: an
    /// option out of range, or a combination the file formats cannot hold, is one line here.
    pub fn validate(&self) -> Result<()> {
        if self.version != SPEC_VERSION {
            return Err(Error::Options(format!(
                "bake spec version {} is not this prt-gpu's ({SPEC_VERSION})",
                self.version
            )));
        }
        if let Bands::Auto { threshold } = self.transfer.bands {
            check_bands_threshold(threshold)?;
        }
        self.options().validate()?;
        if let Some(Compression::Target { error }) = self.compression() {
            if !(error > 0.0 && error < 1.0) {
                return Err(Error::Options(format!(
                    "--compress auto:{error}: the error target must lie in (0, 1)"
                )));
            }
        }
        self.check_storage_fits_container()
    }

    /// Refuses storage a container cannot hold: lean glTF scenes whose albedo the materials do
    /// not say; compressed lightmaps, and half-float ones (they are half floats already); a UV
    /// set named for a mesh, which gets a generated atlas.
    fn check_storage_fits_container(&self) -> Result<()> {
        let refuse = |message: &str| Err(Error::Options(message.to_string()));
        let gltf = self.container == Container::GltfInPlace;
        let lightmap = self.receivers.lightmap.is_some();
        if self.compression().is_some() && lightmap {
            return refuse(
                "--compress stores per-vertex transfer as clusters; a lightmap's texels are \
                 stored whole (OpenEXR)",
            );
        }
        if self.storage.precision == Precision::F16 && lightmap {
            return refuse(
                "--precision f16 stores per-vertex or compressed transfer; a lightmap is half \
                 floats already (OpenEXR HALF)",
            );
        }
        if gltf && self.storage.channels == Storage::Lean && self.transfer.albedo.is_some() {
            return refuse(
                "--albedo with --storage lean: a glTF scene's lean transfer leaves the albedo to \
                 its materials, which --albedo does not change (bake RGB transfer instead)",
            );
        }
        if let Some(set) = self.receivers.lightmap_uv {
            if !lightmap {
                return Err(Error::Options(format!(
                    "--lightmap-uv {set} names the UV set of a lightmap; ask for one with \
                     --lightmap SIZE"
                )));
            }
            if !gltf {
                return Err(Error::Options(format!(
                    "--lightmap-uv {set} names a glTF scene's UV set; an OBJ, a PLY and the \
                     built-in scene get a generated atlas"
                )));
            }
        }
        Ok(())
    }
}

/// `--bands-threshold`: a fraction of the transfer's energy, strictly between 0 and 1.
pub fn check_bands_threshold(threshold: f64) -> Result<()> {
    if !(threshold > 0.0 && threshold < 1.0) {
        return Err(Error::Options(format!(
            "--bands-threshold {threshold} must lie in (0, 1)"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_spec_asks_for_the_default_bake() {
        assert_eq!(BakeSpec::default().options(), BakeOptions::default());
        BakeSpec::default()
            .validate()
            .expect("the defaults are a bake");
    }

    #[test]
    fn a_spec_survives_its_json_and_its_json_names_every_part() {
        let mut spec = BakeSpec::default();
        spec.transfer.bands = Bands::Auto { threshold: 0.02 };
        spec.transfer.albedo = Some([0.5, 0.25, 0.125]);
        spec.transfer.target_error = Some(TargetError {
            relative: 0.01,
            max_samples: 512,
        });
        spec.storage.layout = Layout::Cpca(Compression::Shape {
            clusters: 64,
            components: 8,
        });
        spec.storage.precision = Precision::F16;
        let json = spec.fingerprint_text();
        let back: BakeSpec = serde_json::from_str(&json).expect("reads back");
        assert_eq!(back, spec);
        for name in [
            "\"version\":1",
            "\"auto\":{\"threshold\":0.02}",
            "\"cpca\":{\"shape\":{\"clusters\":64,\"components\":8}}",
            "\"precision\":\"f16\"",
            "\"container\":\"mesh\"",
        ] {
            assert!(json.contains(name), "{name} missing from {json}");
        }
        let unknown = json.replacen("\"version\"", "\"colour\":1,\"version\"", 1);
        assert!(serde_json::from_str::<BakeSpec>(&unknown).is_err());
    }

    #[test]
    fn every_combination_rule_refuses_in_one_line() {
        let gltf = |edit: fn(&mut BakeSpec)| {
            let mut spec = BakeSpec {
                container: Container::GltfInPlace,
                ..BakeSpec::default()
            };
            edit(&mut spec);
            spec
        };
        let refused = [
            gltf(|s| {
                s.storage.channels = Storage::Lean;
                s.transfer.albedo = Some([0.5; 3]);
            }),
            gltf(|s| s.receivers.lightmap_uv = Some(1)),
            {
                let mut spec = BakeSpec::default();
                spec.receivers.lightmap = Some(256);
                spec.receivers.lightmap_uv = Some(1);
                spec
            },
            gltf(|s| {
                s.receivers.lightmap = Some(64);
                s.storage.layout = Layout::Cpca(Compression::Shape {
                    clusters: 8,
                    components: 4,
                })
            }),
            BakeSpec {
                version: SPEC_VERSION + 1,
                ..BakeSpec::default()
            },
            {
                let mut spec = BakeSpec::default();
                spec.transfer.bands = Bands::Auto { threshold: 1.0 };
                spec
            },
            {
                let mut spec = BakeSpec::default();
                spec.storage.layout = Layout::Cpca(Compression::Target { error: 0.0 });
                spec
            },
            {
                let mut spec = BakeSpec::default();
                spec.receivers.lightmap = Some(256);
                spec.storage.precision = Precision::F16;
                spec
            },
        ];
        for spec in refused {
            let error = spec.validate().expect_err("refused").to_string();
            assert!(!error.contains('\n'), "{error}");
        }
        BakeSpec {
            container: Container::GltfInPlace,
            ..BakeSpec::default()
        }
        .validate()
        .expect("a glTF scene bakes per vertex in RGB float32");
        let mut lightmapped = BakeSpec {
            container: Container::GltfInPlace,
            ..BakeSpec::default()
        };
        lightmapped.receivers.lightmap = Some(256);
        lightmapped.receivers.lightmap_uv = Some(1);
        lightmapped
            .validate()
            .expect("a glTF scene bakes a lightmap on its own UV set");
    }
}
