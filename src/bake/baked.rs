//! What a bake gives: the transfer, the baked mesh, what its file records and what the
//! summary line reports.

use super::*;

/// Per-vertex transfer vectors: `channels` (3 for RGB, 1 for lean storage) of `bands^2`
/// coefficients for each of `vertex_count` receivers.
///
/// Layout: `coeffs[(vertex * channels + channel) * bands^2 + k]`, `k = l(l+1) + m`.
/// Exit radiance of vertex v in channel c under lighting coefficients `light[c][k]` is
/// `sum_k light[c][k] * coeffs[(v * channels + c) * bands^2 + k]`.
///
/// The fields are private so that the shape holds wherever a transfer exists: every
/// construction goes through [`Transfer::new`] (checked) or [`Transfer::zeros`], and
/// [`Transfer::coeffs_mut`] can change values, not their number.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    bands: u32,
    channels: u32,
    vertex_count: usize,
    coeffs: Vec<f32>,
}

/// A transfer's bands, channels and receivers, without its coefficients: what a file's layout
/// is decided by before they are baked (a streamed bake).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TransferShape {
    pub bands: u32,
    pub channels: u32,
    pub vertex_count: usize,
}

impl TransferShape {
    pub fn coeffs_per_channel(&self) -> usize {
        (self.bands * self.bands) as usize
    }
}

/// Coefficients that are not `vertex_count × channels × bands²` values, or a shape no transfer has.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ShapeError(String);

impl Transfer {
    /// The transfer of `vertex_count` receivers, `channels` each of `bands^2` coefficients, as
    /// laid out in `coeffs`; refused where the number of values is not that, or the shape is
    /// empty of bands or channels.
    pub fn new(
        bands: u32,
        channels: u32,
        vertex_count: usize,
        coeffs: Vec<f32>,
    ) -> std::result::Result<Transfer, ShapeError> {
        if bands == 0 || channels == 0 {
            return Err(ShapeError(format!(
                "a transfer needs at least one band and one channel, not {bands} bands of {channels} channels"
            )));
        }
        let expected = (bands as usize)
            .checked_mul(bands as usize)
            .and_then(|n| n.checked_mul(channels as usize))
            .and_then(|n| n.checked_mul(vertex_count));
        if expected != Some(coeffs.len()) {
            return Err(ShapeError(format!(
                "{vertex_count} receivers of {channels} channels at {bands} bands need {} \
                 coefficients, not {}",
                expected.map_or_else(|| "more".to_string(), |n| n.to_string()),
                coeffs.len()
            )));
        }
        Ok(Transfer {
            bands,
            channels,
            vertex_count,
            coeffs,
        })
    }

    /// Zero transfer of the given shape (to be filled through [`Transfer::coeffs_mut`]).
    pub fn zeros(bands: u32, channels: u32, vertex_count: usize) -> Transfer {
        let n = (bands * bands * channels) as usize * vertex_count;
        Transfer::new(bands, channels, vertex_count, vec![0.0; n])
            .expect("a zero transfer has its own shape")
    }

    pub fn bands(&self) -> u32 {
        self.bands
    }

    pub fn channels(&self) -> u32 {
        self.channels
    }

    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    pub fn shape(&self) -> TransferShape {
        TransferShape {
            bands: self.bands,
            channels: self.channels,
            vertex_count: self.vertex_count,
        }
    }

    /// Every coefficient, in the layout above.
    pub fn coeffs(&self) -> &[f32] {
        &self.coeffs
    }

    /// Every coefficient, to change in place (the shape stays).
    pub fn coeffs_mut(&mut self) -> &mut [f32] {
        &mut self.coeffs
    }

    /// The coefficients, giving up the shape.
    pub fn into_coeffs(self) -> Vec<f32> {
        self.coeffs
    }

    pub fn coeffs_per_channel(&self) -> usize {
        (self.bands * self.bands) as usize
    }

    /// The bands^2 coefficients of one vertex and channel.
    pub fn vertex_channel(&self, vertex: usize, channel: usize) -> &[f32] {
        let n = self.coeffs_per_channel();
        let start = (vertex * self.channels as usize + channel) * n;
        &self.coeffs[start..start + n]
    }
}

/// A baked mesh: the prepared scene (normals `Some`), its transfer and how it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedMesh {
    pub scene: Scene,
    pub transfer: Transfer,
    pub metadata: BakeMetadata,
    /// Per-texel transfer, when a lightmap was baked (on a generated atlas the scene is then
    /// split where its charts meet, so that each vertex has one pair of lightmap coordinates).
    pub lightmap: Option<TexelBake>,
}

/// Transfer per texel of a lightmap atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct TexelBake {
    pub width: u32,
    pub height: u32,
    /// Lightmap coordinates of every triangle corner of the scene (corner i of triangle t at
    /// `3t + i`), in [0, 1] as glTF's `TEXCOORD_n`: texel (x, y) (row y from the top) has its
    /// centre at `((x + 0.5) / width, (y + 0.5) / height)`. A mesh with a generated atlas is
    /// split where its charts meet, so the corners of one vertex agree and a file holds them
    /// per vertex ([`TexelBake::vertex_texcoords`]).
    pub texcoords: Vec<[f32; 2]>,
    /// The `TEXCOORD_n` set the coordinates are: 0 for a generated atlas, the scene's own
    /// lightmap set otherwise.
    pub set: u32,
    /// The texels' transfer, row-major: `vertex_count` is `width * height`; none (its
    /// `vertex_count` 0, its bands and channels the map's) where `held` holds it.
    pub transfer: Transfer,
    /// The texels' transfer waiting in a scratch file, for a lightmap baked in bounded memory
    /// (`texels::bake_atlas_held`): what is written is read from there.
    pub held: Option<super::texels::HeldLightmap>,
}

impl TexelBake {
    /// The coordinates per vertex of `scene`, as a file's `TEXCOORD_n` holds them: each
    /// vertex's from its corners; `None` where two corners of one vertex disagree (a mesh not
    /// split where its charts meet). A vertex no triangle uses gets `[0, 0]`.
    pub fn vertex_texcoords(&self, scene: &Scene) -> Option<Vec<[f32; 2]>> {
        let mut per_vertex: Vec<Option<[f32; 2]>> = vec![None; scene.vertex_count()];
        let corners = scene.triangles.iter().flatten();
        for (&v, &uv) in corners.zip(&self.texcoords) {
            let slot = per_vertex.get_mut(v as usize)?;
            match slot {
                Some(seen) if seen.map(f32::to_bits) != uv.map(f32::to_bits) => return None,
                _ => *slot = Some(uv),
            }
        }
        Some(
            per_vertex
                .into_iter()
                .map(Option::unwrap_or_default)
                .collect(),
        )
    }

    /// Per triangle corner, the coordinates `per_vertex` gives its vertex: what a file's
    /// `TEXCOORD_n` reads as.
    pub fn corner_texcoords(scene: &Scene, per_vertex: &[[f32; 2]]) -> Vec<[f32; 2]> {
        let corners = scene.triangles.iter().flatten();
        corners.map(|&v| per_vertex[v as usize]).collect()
    }
}

/// Everything a baked file records about how it was made (glTF mesh extras `prt`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeMetadata {
    pub tool: String,
    pub tool_version: String,
    pub bands: u32,
    pub channels: u32,
    pub mode: Mode,
    /// Sample directions actually used (a square number for the grid strategies).
    pub samples: u32,
    /// The `--sampling` strategy's name.
    pub sampling: String,
    pub seed: u64,
    pub backend: String,
    /// One line describing the SH basis; see `sh::CONVENTION`.
    pub sh_convention: String,
    /// One line describing the radiometric meaning of the coefficients.
    pub radiometry: String,
    /// Interreflection bounces added to the direct transfer (0 for the other modes).
    #[serde(default)]
    pub bounces: u32,
    /// How vertex values were obtained from the baked receivers (absent: `point`).
    #[serde(default, skip_serializing_if = "Fit::is_point")]
    pub fit: Fit,
    /// Least-squares fit: the surface points baked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit_points: Option<u32>,
    /// An error-targeted bake's target (`samples` is then the mean over receivers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_error: Option<f64>,
    /// The transfer leaves the albedo out: radiance is `albedo * sum_k l_k t_k`, the albedo
    /// being the vertex colour (`COLOR_0`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub albedo_free: bool,
    /// The translucent medium whose subsurface scattering replaces the diffuse reflection
    /// (`bake --subsurface`), and how far under the surface the bake followed its light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subsurface: Option<SubsurfaceMetadata>,
}

/// `extras.prt.subsurface`: the medium of the whole scene (`--subsurface`), or those of the
/// scene's own glTF materials, and the farthest reach a profile was cut at (scene units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SubsurfaceMetadata {
    #[serde(flatten)]
    pub material: Option<super::subsurface::SubsurfaceMaterial>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<super::subsurface::MaterialMedium>,
    pub reach: f64,
}

impl SubsurfaceMetadata {
    /// What a bake with `options` records, where its subsurface pass ran.
    pub fn of(
        options: &super::BakeOptions,
        pass: Option<super::subsurface::SubsurfaceReport>,
    ) -> Option<SubsurfaceMetadata> {
        let pass = pass?;
        let materials = match (&options.subsurface, &options.scene_media) {
            (None, Some(media)) => media.media.clone(),
            _ => Vec::new(),
        };
        Some(SubsurfaceMetadata {
            material: options.subsurface,
            materials,
            reach: pass.reach,
        })
    }

    /// The media, for a line of text: the whole scene's, or each glTF material's.
    pub fn describe(&self) -> String {
        let medium = |m: &super::subsurface::SubsurfaceMaterial| {
            format!(
                "ior {}, absorption {:?} and reduced scattering {:?} per mm, {} mm a unit",
                m.ior, m.absorption, m.reduced_scattering, m.mm_per_unit
            )
        };
        match &self.material {
            Some(m) => medium(m),
            None => self
                .materials
                .iter()
                .map(|m| format!("material {}: {}", m.material, medium(&m.medium)))
                .collect::<Vec<_>>()
                .join("; "),
        }
    }
}

/// The meaning of the coefficients, for file metadata.
pub const RADIOMETRY: &str = "exit radiance L_o = sum_k l_k t_k per channel, \
l_k = integral L_in(w) y_k(w) dw, t_k = (albedo/pi) integral V(w) max(0, n.w) y_k(w) dw";

/// What the baked file records about a bake with `options`.
pub(super) fn metadata_for(
    options: &BakeOptions,
    samples: usize,
    bounces: usize,
    fit_points: Option<u32>,
) -> BakeMetadata {
    BakeMetadata {
        tool: env!("CARGO_PKG_NAME").to_string(),
        tool_version: env!("CARGO_PKG_VERSION").to_string(),
        bands: options.bands,
        channels: 3,
        mode: options.mode,
        samples: samples as u32,
        sampling: options.sampling.name().to_string(),
        seed: options.seed,
        backend: String::new(),
        sh_convention: CONVENTION.to_string(),
        radiometry: RADIOMETRY.to_string(),
        bounces: bounces as u32,
        fit: options.fit,
        fit_points,
        target_error: options.target_error.map(|t| t.relative),
        albedo_free: false,
        subsurface: None,
    }
}

/// What a bake did, for the summary line.
#[derive(Clone, Debug)]
pub struct BakeReport {
    pub prepare: PrepareReport,
    /// For every vertex of the scene as given, its vertex in the baked (prepared) mesh.
    pub vertex_map: VertexMap,
    /// Points the transfer was computed at (the vertices, or the fit's surface points).
    pub receivers: usize,
    pub samples_used: u32,
    pub rays_cast: u64,
    pub bvh_nodes: usize,
    pub seconds_prepare: f64,
    /// The direct pass (and, interreflected, the hits and the gather matrix).
    pub seconds_transfer: f64,
    /// The least-squares fit of the direct pass (zero for point values).
    pub seconds_fit: f64,
    /// The fit's solve, when the vertex values were fitted.
    pub fit: Option<FitReport>,
    /// The lightmap's bake, when one was asked for.
    pub texels: Option<texels::TexelReport>,
    /// The error-targeted direct pass, when a target was given.
    pub adaptive: Option<adaptive::AdaptiveReport>,
    /// One entry per bounce performed (each including its fit).
    pub bounces: Vec<BounceStat>,
    /// Non-zero entries of the gather matrix (interreflected mode).
    pub gather_entries: usize,
    pub backend: String,
    /// What the subsurface pass did, where the options ask for one.
    pub subsurface: Option<super::subsurface::SubsurfaceReport>,
}

/// What one bounce added and what it cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BounceStat {
    /// DC energy the bounce added over the DC energy of all transfer before it.
    pub relative_energy: f64,
    pub seconds: f64,
    /// The iterations of its least-squares fit's solve, where the bake has one.
    pub fit_iterations: Option<u32>,
}

#[cfg(test)]
mod transfer_tests {
    use super::*;

    #[test]
    fn a_transfer_holds_exactly_its_shapes_coefficients() {
        let two_vertices = Transfer::new(2, 3, 2, vec![0.5; 24]).unwrap();
        assert_eq!(two_vertices.vertex_channel(1, 2), &[0.5; 4]);
        let shape = two_vertices.shape();
        assert_eq!((shape.bands, shape.channels, shape.vertex_count), (2, 3, 2));
        let short = Transfer::new(2, 3, 2, vec![0.5; 23])
            .unwrap_err()
            .to_string();
        assert_eq!(
            short,
            "2 receivers of 3 channels at 2 bands need 24 coefficients, not 23"
        );
        assert!(Transfer::new(0, 3, 0, Vec::new()).is_err());
        assert!(Transfer::new(2, 0, 0, Vec::new()).is_err());
        let overflowing = Transfer::new(u32::MAX, 3, usize::MAX, Vec::new()).unwrap_err();
        assert!(overflowing.to_string().contains("need more coefficients"));
        assert_eq!(Transfer::zeros(3, 1, 4).coeffs(), &[0.0; 36]);
        assert_eq!(
            Transfer::new(1, 1, 0, Vec::new()).unwrap().vertex_count(),
            0
        );
    }
}
