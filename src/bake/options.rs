//! What the user asks of a bake: the mode, the fit, the storage, and the options' checks.

use super::*;

/// Which light transport the transfer vectors capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Clamped cosine only: every direction above the horizon is assumed visible.
    Unshadowed,
    /// Clamped cosine times binary visibility against the whole scene.
    Shadowed,
    /// Shadowed transfer plus light reflected between surfaces (`--bounces`).
    Interreflected,
    /// Point and spot lights inside the scene: depth maps and the direct-to-indirect operator,
    /// not SH transfer (README, "Local lights").
    Local,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Unshadowed => "unshadowed",
            Mode::Shadowed => "shadowed",
            Mode::Interreflected => "interreflected",
            Mode::Local => "local",
        }
    }
}

/// The most bounces a bake accepts.
pub const MAX_BOUNCES: u32 = 64;

/// How a bake turns transfer baked at receivers into the per-vertex values a renderer
/// interpolates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Fit {
    /// Bake at the vertices: exact there, whatever lies between them.
    #[default]
    Point,
    /// Bake at points spread over every triangle and fit the vertex values whose
    /// interpolation matches them best over the surface (Kavan et al. 2011).
    LeastSquares,
}

impl Fit {
    pub fn name(self) -> &'static str {
        match self {
            Fit::Point => "point",
            Fit::LeastSquares => "least-squares",
        }
    }

    pub(super) fn is_point(&self) -> bool {
        *self == Fit::Point
    }
}

/// The strategy a bake uses when none is asked for; chosen from `prt-gpu chart` (README): the
/// least error per sample, and with fan packets on the CPU as many rays per second as the
/// shared-direction sets.
pub const DEFAULT_SAMPLING: Sampling = Sampling::Cosine;

/// The sample count a bake uses when none is asked for (README: with the default strategy it
/// has a third of the error of the tutorial's 1024 stratified samples, at the same count).
pub const DEFAULT_SAMPLES: u32 = 1024;

/// What the user asks of a bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    pub bands: u32,
    /// Requested sample directions; the grid strategies use the nearest square.
    pub samples: u32,
    pub sampling: Sampling,
    pub seed: u64,
    pub mode: Mode,
    /// Replaces every material's albedo when set.
    pub albedo: Option<Vec3>,
    /// Interreflected mode: bounces after the direct pass.
    pub bounces: u32,
    /// Interreflected mode: stop once a bounce adds less than this fraction of the energy.
    pub bounce_tolerance: f64,
    pub fit: Fit,
    /// Least-squares fit: how many surface points to bake.
    pub point_density: PointDensity,
    /// Also bake a lightmap about this many texels on its longer side.
    pub lightmap: Option<u32>,
    /// Cast samples per receiver until this error is reached (instead of `samples` each).
    pub target_error: Option<adaptive::TargetError>,
    pub storage: Storage,
    /// Denoise the lightmap (`receivers::denoise`), its texels cast with their own turns.
    pub denoise: bool,
    /// Each receiver turns a tangent-frame sample set about its normal by its own angle
    /// (`sampling::ReceiverTurns`): set for the texels of a lightmap to be denoised.
    pub turns: bool,
    /// A translucent medium whose subsurface scattering replaces the diffuse reflection, of
    /// the direct light and of every bounce (`subsurface`).
    pub subsurface: Option<super::subsurface::SubsurfaceMaterial>,
    /// Without `subsurface`: the media of the scene's own materials (a glTF scene's
    /// scattering volumes), each on its vertices; the other vertices stay opaque.
    pub scene_media: Option<super::subsurface::SceneMedia>,
    /// Least-squares fit: bake the points about this many at a time, each run's values summed
    /// into the fit and let go, its gather rows in a scratch file (`points::PointChunks`), to
    /// bound memory; the bytes are the whole bake's. How the bake runs, not what it is.
    pub point_chunk: Option<usize>,
    /// Lightmap: bake its texels a chunk at a time into a scratch file and clean them up a
    /// group of coefficients at a time (`texels::bake_atlas_held`), to bound memory; the bytes
    /// are the whole bake's. How the bake runs, not what it is.
    pub texel_groups: Option<super::texels::TexelGroups>,
}

/// How the transfer is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Storage {
    /// Red, green and blue transfer, albedo included.
    #[default]
    Rgb,
    /// One channel where one suffices: shadowed and unshadowed transfer albedo-free (the albedo,
    /// in `COLOR_0`, is applied at relighting); interreflected transfer when every albedo is
    /// grey (its channels are then equal); RGB otherwise.
    Lean,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            bands: 4,
            samples: DEFAULT_SAMPLES,
            sampling: DEFAULT_SAMPLING,
            seed: 1,
            mode: Mode::Shadowed,
            albedo: None,
            bounces: 3,
            bounce_tolerance: 0.0,
            fit: Fit::Point,
            point_density: PointDensity::default(),
            lightmap: None,
            target_error: None,
            storage: Storage::Rgb,
            denoise: false,
            turns: false,
            subsurface: None,
            scene_media: None,
            point_chunk: None,
            texel_groups: None,
        }
    }
}

impl BakeOptions {
    /// Whether the transfer is stored albedo-free: lean direct (shadowed or unshadowed)
    /// transfer, whose albedo is applied at relighting.
    pub fn albedo_free(&self) -> bool {
        self.storage == Storage::Lean && self.mode != Mode::Interreflected
    }

    /// These options with receivers' turns on or off.
    pub fn with_turns(self, turns: bool) -> Self {
        BakeOptions { turns, ..self }
    }

    /// These options with each receiver turning its samples where the sampling can turn them
    /// (cosine, about each receiver's normal): what a least-squares fit's points cast, so that
    /// the fit averages their errors out; a stratified or uniform set stays shared.
    pub fn with_turns_where_possible(self) -> Self {
        let turns = self.turns || self.sampling == Sampling::Cosine;
        self.with_turns(turns)
    }

    pub fn validate(&self) -> Result<()> {
        if self.mode == Mode::Local {
            return Err(Error::Options(
                "--mode local bakes depth maps and a direct-to-indirect operator, not SH \
                 transfer: pipeline::run bakes its spec's local section"
                    .into(),
            ));
        }
        if let Some(material) = &self.subsurface {
            material.validate()?;
        }
        if self.bands == 0 || self.bands > MAX_BANDS {
            return Err(Error::Options(format!(
                "--bands {} is out of range (1 to {MAX_BANDS})",
                self.bands
            )));
        }
        if self.samples == 0 || self.samples > MAX_SAMPLES {
            return Err(Error::Options(format!(
                "--samples {} is out of range (1 to {MAX_SAMPLES})",
                self.samples
            )));
        }
        if self.bounces > MAX_BOUNCES {
            return Err(Error::Options(format!(
                "--bounces {} is out of range (0 to {MAX_BOUNCES})",
                self.bounces
            )));
        }
        if !(0.0..1.0).contains(&self.bounce_tolerance) {
            return Err(Error::Options(format!(
                "--bounce-tolerance {} must lie in [0, 1)",
                self.bounce_tolerance
            )));
        }
        if let Some(size) = self.lightmap {
            let max = crate::receivers::atlas::MAX_ATLAS_SIZE;
            if !(1..=max).contains(&size) {
                return Err(Error::Options(format!(
                    "--lightmap {size} is out of range (1 to {max} texels)"
                )));
            }
        }
        if let Some(target) = &self.target_error {
            target.validate()?;
        }
        if self.denoise && self.lightmap.is_none() {
            return Err(Error::Options(
                "--denoise filters a lightmap's texels; ask for one with --lightmap SIZE".into(),
            ));
        }
        if (self.denoise || self.turns) && self.sampling != Sampling::Cosine {
            return Err(Error::Options(format!(
                "--denoise needs texels that cast their own directions, which cosine \
                 sampling gives by turning its set about each texel's normal; --sampling {} \
                 shares one set among all",
                self.sampling.name()
            )));
        }
        if self.storage == Storage::Lean && self.lightmap.is_some() {
            return Err(Error::Options(
                "--storage lean stores vertex transfer; lightmaps are stored in RGB".into(),
            ));
        }
        let density = self.point_density;
        if !(density.per_vertex.is_finite()
            && density.per_vertex > 0.0
            && density.per_vertex <= 1e4)
            || density.min_per_triangle == 0
        {
            return Err(Error::Options(format!(
                "--fit-points {} must be a number of points per vertex in (0, 10000]",
                density.per_vertex
            )));
        }
        if let Some(a) = self.albedo {
            if !a.is_finite() || a.min_element() < 0.0 || a.max_element() > 1.0 {
                return Err(Error::Options(format!(
                    "--albedo {},{},{} must lie in [0, 1]",
                    a.x, a.y, a.z
                )));
            }
        }
        Ok(())
    }

    /// The sample count actually used (the nearest square for the grid strategies).
    pub fn samples_used(&self) -> u32 {
        self.sampling.samples_used(self.samples)
    }
}
