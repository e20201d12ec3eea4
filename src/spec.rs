//! What a bake is, in one value: the receivers it computes transfer at, the transfer it
//! computes, how that transfer is stored and the file that holds it. The command line, part
//! files, fingerprints and `merge` all speak it; [`BakeSpec::validate`] holds every rule about
//! which of its choices go together.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bake::adaptive::TargetError;
pub use crate::bake::subsurface::SubsurfaceMaterial;
use crate::bake::{BakeOptions, Fit, Mode, Storage, DEFAULT_SAMPLES, DEFAULT_SAMPLING};
use crate::precision::Precision;
use crate::receivers::PointDensity;
use crate::sampling::Sampling;
use crate::{Error, Result};

/// The layout of [`BakeSpec`] this build writes and reads.
pub const SPEC_VERSION: u32 = 1;

/// The most bands `--bands auto` bakes and chooses among.
pub const AUTO_MAX_BANDS: u32 = 8;

/// The most cells per side of a local-lights depth map (65,536 directions per receiver).
pub const MAX_GRID_SIDE: u32 = 256;

/// Everything that decides a bake's output besides the mesh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BakeSpec {
    pub version: u32,
    pub receivers: ReceiverSpec,
    pub transfer: TransferSpec,
    pub storage: StorageSpec,
    pub container: Container,
    /// What a local-lights bake (`transfer.mode` local) computes: depth maps and a
    /// direct-to-indirect operator instead of SH transfer. Left out of the JSON otherwise, so
    /// specs written before it hash as they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub local: Option<LocalOptions>,
    /// Relightable probes in the space around the scene (`--probes`), baked after its
    /// transfer. Left out of the JSON when unset, so specs written before it hash as they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probes: Option<ProbeSpec>,
}

/// Where probes go and what each stores (`probes::bake_probes`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    pub placement: ProbePlacement,
    pub form: ProbeForm,
}

/// Where the probes are: a grid over the scene's bounds, or the user's points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProbePlacement {
    /// Points `spacing` apart along each axis, centred on the scene's bounding box and
    /// covering it.
    Grid {
        spacing: f32,
    },
    Points(Vec<[f32; 3]>),
}

/// What a probe stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ProbeForm {
    /// The incident radiance's SH from the light's: bands^2 x bands^2 per channel.
    Radiance,
    /// Only what irradiance needs: the first three bands' rows, cosine-convolved
    /// (9 x bands^2 per channel).
    Irradiance,
}

impl ProbeForm {
    pub fn name(self) -> &'static str {
        match self {
            ProbeForm::Radiance => "radiance",
            ProbeForm::Irradiance => "irradiance",
        }
    }
}

/// The most probes one bake places.
pub const MAX_PROBES: usize = 1 << 22;

impl ProbeSpec {
    /// Refuses a grid without a positive finite spacing, points that are not finite, and no
    /// probe at all.
    pub fn validate(&self) -> Result<()> {
        match &self.placement {
            ProbePlacement::Grid { spacing } if !(spacing.is_finite() && *spacing > 0.0) => {
                Err(Error::Options(format!(
                    "--probes {spacing}: the grid spacing must be a positive length"
                )))
            }
            ProbePlacement::Points(points) if points.is_empty() => Err(Error::Options(
                "--probe-points: the file lists no point".into(),
            )),
            ProbePlacement::Points(points) if points.len() > MAX_PROBES => {
                Err(Error::Options(format!(
                    "--probe-points: {} points, more than {MAX_PROBES}",
                    points.len()
                )))
            }
            ProbePlacement::Points(points) if points.iter().flatten().any(|x| !x.is_finite()) => {
                Err(Error::Options(
                    "--probe-points: a point has a coordinate that is not finite".into(),
                ))
            }
            _ => Ok(()),
        }
    }
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
    /// Denoise the lightmap's texels (`receivers::denoise`). Left out of the JSON when off.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub denoise: bool,
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
    /// A translucent medium whose subsurface scattering replaces the diffuse reflection
    /// (`bake::subsurface`). Left out of the JSON when unset, so specs written before it hash
    /// as they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subsurface: Option<SubsurfaceMaterial>,
    /// Without `subsurface`: whether a glTF scene's materials with a scattering volume scatter
    /// in their media (`--subsurface none`: no, every material is opaque). Left out of the
    /// JSON when true, so specs written before it hash as they did.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub materials_scatter: bool,
}

fn yes() -> bool {
    true
}

fn is_true(value: &bool) -> bool {
    *value
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
    /// Zonal-harmonic transfer stored beside the SH transfer (`--zonal`), for meshes that
    /// deform. Left out of the JSON when unset, so specs written before it hash as they did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zonal: Option<ZonalSpec>,
}

/// Local, deformable PRT (`zonal::ZonalTransfer`): per receiver and channel, `bands` zonal
/// coefficients about one axis, which a runtime turns with the surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZonalSpec {
    pub bands: u32,
    pub axis: ZonalAxis,
}

/// The axis each receiver's zonal lobe is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ZonalAxis {
    /// The shading normal: nothing more is stored, and a runtime needs only its normals.
    Normal,
    /// The axis that keeps most of the transfer's energy (Sloan, Luna & Snyder's optimal
    /// "shading normal"): stored per vertex, and turned by a runtime as it turns normals.
    Fitted,
}

impl ZonalAxis {
    pub fn name(self) -> &'static str {
        match self {
            ZonalAxis::Normal => "normal",
            ZonalAxis::Fitted => "fitted",
        }
    }
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
                denoise: false,
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
                subsurface: None,
                materials_scatter: true,
            },
            storage: StorageSpec {
                channels: Storage::Rgb,
                precision: Precision::F32,
                layout: Layout::PerVertex,
                zonal: None,
            },
            container: Container::Mesh,
            local: None,
            probes: None,
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
            denoise: self.receivers.denoise,
            turns: false,
            subsurface: self.transfer.subsurface,
            scene_media: None,
            point_chunk: None,
            texel_groups: None,
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
        if self.transfer.mode == Mode::Local || self.local.is_some() {
            return self.check_local();
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
        self.check_storage_fits_container()?;
        self.check_zonal()?;
        self.check_subsurface()?;
        self.check_probes()
    }

    /// Subsurface scattering: a valid medium, stored RGB (its colour is the medium's, per
    /// channel).
    fn check_subsurface(&self) -> Result<()> {
        let Some(material) = &self.transfer.subsurface else {
            return Ok(());
        };
        material.validate()?;
        let refuse = |why: &str| Err(Error::Options(format!("--subsurface {why}")));
        if self.storage.channels == Storage::Lean {
            return refuse(
                "with --storage lean: subsurface transfer is RGB (each channel scatters as far \
                 as the medium lets it)",
            );
        }
        Ok(())
    }

    /// Zonal transfer: at least one band and no more than the transfer has.
    fn check_zonal(&self) -> Result<()> {
        let Some(zonal) = self.storage.zonal else {
            return Ok(());
        };
        let baked = self.transfer.bands.baked();
        if !(1..=baked).contains(&zonal.bands) {
            return Err(Error::Options(format!(
                "--zonal {}: zonal bands run from 1 to the transfer's bands ({baked})",
                zonal.bands
            )));
        }
        Ok(())
    }

    /// Probes: valid, and only where there is occlusion for them to see (unshadowed transfer
    /// has none: every probe would be the identity).
    fn check_probes(&self) -> Result<()> {
        let Some(probes) = &self.probes else {
            return Ok(());
        };
        probes.validate()?;
        if self.transfer.mode == Mode::Unshadowed {
            return Err(Error::Options(
                "--probes with --mode unshadowed: nothing is occluded, so every probe would be \
                 the identity (bake shadowed or interreflected)"
                    .into(),
            ));
        }
        Ok(())
    }

    /// A local-lights bake: its section, valid, and nothing of what SH transfer is stored as
    /// or computed at, which it has none of.
    fn check_local(&self) -> Result<()> {
        let Some(local) = &self.local else {
            return Err(Error::Options(
                "the spec's mode is local and it has no local section".into(),
            ));
        };
        if self.transfer.mode != Mode::Local {
            return Err(Error::Options(format!(
                "the spec has a local-lights section and its mode is {}, not local",
                self.transfer.mode.name()
            )));
        }
        let sh_only = BakeSpec::default();
        let asked = [
            (self.storage.layout != Layout::PerVertex, "--compress"),
            (self.receivers.lightmap.is_some(), "--lightmap"),
            (self.receivers.fit != Fit::Point, "--fit"),
            (self.transfer.target_error.is_some(), "--target-error"),
            (self.storage.channels != Storage::Rgb, "--storage"),
            (self.transfer.bands != sh_only.transfer.bands, "--bands"),
            (self.storage.precision != Precision::F32, "--precision"),
            (
                self.container != Container::Mesh,
                "a glTF scene baked in place",
            ),
            (self.probes.is_some(), "--probes"),
            (self.storage.zonal.is_some(), "--zonal"),
            (self.transfer.subsurface.is_some(), "--subsurface"),
        ];
        if let Some((_, what)) = asked.iter().find(|(given, _)| *given) {
            return Err(Error::Options(format!(
                "{what} is for SH transfer; --mode local bakes depth maps and a \
                 direct-to-indirect operator (see --depth-grid, --depth-compress, \
                 --operator-compress)"
            )));
        }
        local.validate()
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

/// The compressed operator's shape.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatorShape {
    /// Clusters of receivers (senders and receivers alike).
    pub clusters: u32,
    /// Basis vectors of example irradiance per cluster.
    pub components: u32,
    /// In each receiver cluster, the least terms are dropped while their expected energy
    /// together stays within `sparsity^2` of the cluster's total (0 keeps every term).
    pub sparsity: f32,
    /// Seed of the clustering.
    pub seed: u64,
}

/// What a local-lights bake is asked for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalOptions {
    /// Cosine-distributed gather rays per receiver (the gather matrix's samples).
    pub samples: u32,
    pub seed: u64,
    /// Bounces of the direct-to-indirect operator (indirect light after 1 to B bounces; 0:
    /// direct light alone).
    pub bounces: u32,
    /// Depth-map directions per side: `side^2` per receiver.
    pub grid_side: u32,
    /// Clusters and PCA components of the compressed depth maps.
    pub depth_clusters: u32,
    pub depth_components: u32,
    /// The compressed operator's shape.
    pub operator: OperatorShape,
    /// Example lights for the operator's PCA bases.
    pub example_lights: u32,
}

impl Default for LocalOptions {
    fn default() -> Self {
        LocalOptions {
            samples: 256,
            seed: 1,
            bounces: 3,
            grid_side: 16,
            depth_clusters: 128,
            depth_components: 24,
            operator: OperatorShape {
                clusters: 64,
                components: 16,
                sparsity: 0.03,
                seed: 1,
            },
            example_lights: 256,
        }
    }
}

impl LocalOptions {
    pub fn validate(&self) -> Result<()> {
        let refuse = |message: String| Err(Error::Options(message));
        if !(1..=crate::sampling::MAX_SAMPLES).contains(&self.samples) {
            return refuse(format!("--samples {} is out of range", self.samples));
        }
        if self.bounces > crate::bake::MAX_BOUNCES {
            return refuse(format!(
                "--bounces {} is out of range for local lights (0 to {})",
                self.bounces,
                crate::bake::MAX_BOUNCES
            ));
        }
        if !(2..=MAX_GRID_SIDE).contains(&self.grid_side) {
            return refuse(format!(
                "--depth-grid {} is out of range (2 to {})",
                self.grid_side, MAX_GRID_SIDE
            ));
        }
        let directions = self.grid_side * self.grid_side;
        if self.depth_clusters == 0 || self.depth_components > directions {
            return refuse(format!(
                "--depth-compress {}x{}: need at least one cluster and at most {directions} \
                 components (the directions per map)",
                self.depth_clusters, self.depth_components
            ));
        }
        let op = &self.operator;
        if op.clusters == 0 || op.components == 0 || op.components > self.example_lights {
            return refuse(format!(
                "--operator-compress {}x{}: need at least one cluster and 1 to --example-lights \
                 ({}) components",
                op.clusters, op.components, self.example_lights
            ));
        }
        if !(0.0..1.0).contains(&op.sparsity) {
            return refuse(format!("--sparsity {} must lie in [0, 1)", op.sparsity));
        }
        Ok(())
    }
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

    /// A local-lights spec: its section round-trips through JSON, and a spec without one
    /// writes no `local` key (so the fingerprints of specs written before it hold).
    #[test]
    fn local_lights_are_a_mode_of_the_spec() {
        assert!(!BakeSpec::default().fingerprint_text().contains("local"));
        let local = BakeSpec {
            transfer: TransferSpec {
                mode: Mode::Local,
                ..BakeSpec::default().transfer
            },
            local: Some(LocalOptions {
                grid_side: 8,
                ..LocalOptions::default()
            }),
            ..BakeSpec::default()
        };
        local.validate().expect("the default local bake");
        let json = local.fingerprint_text();
        assert!(json.contains("\"local\":{\"samples\":256"), "{json}");
        let back: BakeSpec = serde_json::from_str(&json).expect("reads back");
        assert_eq!(back, local);

        let edits: [fn(&mut BakeSpec); 6] = [
            |s| s.local = None,
            |s| s.transfer.mode = Mode::Shadowed,
            |s| s.storage.precision = Precision::F16,
            |s| s.receivers.lightmap = Some(64),
            |s| s.container = Container::GltfInPlace,
            |s| s.local.as_mut().unwrap().grid_side = 1,
        ];
        for edit in edits {
            let mut spec = local.clone();
            edit(&mut spec);
            let error = spec.validate().expect_err("refused").to_string();
            assert!(!error.contains('\n'), "{error}");
        }
    }
}
