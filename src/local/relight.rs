//! The run-time of a local-lights bake: relighting a frame for moving point lights, with the
//! operator's sparse form or its paths, on the CPU or the GPU, and the frame timings.

use super::*;

/// Which form of the operator a frame uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OperatorForm {
    /// Clusters, PCA bases of example direct light, responses per cluster pair.
    Compressed,
    /// The gather matrix bounced B times.
    Sparse,
}

/// How a frame's direct light finds its shadows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Shadows {
    /// One shadow ray per receiver and light through the scene's BVH: exact (within float
    /// rounding of the path tracer's shadows), a few milliseconds a frame on the CPU.
    #[default]
    Rays,
    /// The compressed depth maps, as the paper's run time (no ray tracing): shadow edges are
    /// blurred over a cell of the maps' grid, so the direct term is off near every one.
    DepthMaps,
}

impl Shadows {
    /// What gives the shadows, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Shadows::Rays => "shadow rays",
            Shadows::DepthMaps => "the depth maps",
        }
    }
}

/// The run time: what a frame needs besides the lights, worked out once.
pub struct Relighter<'a> {
    pub bake: &'a LocalBake,
    pub origins: Vec<Vec3>,
    pub frames: Vec<[Vec3; 3]>,
    /// The scene's BVH, for shadow rays (`None` when the depth maps give the shadows).
    bvh: Option<Bvh>,
}

/// One frame's radiance, RGB per receiver.
#[derive(Clone, Debug)]
pub struct Frame {
    pub irradiance: Vec<f32>,
    pub direct: Vec<Vec3>,
    pub indirect: Vec<Vec3>,
}

impl Frame {
    /// Direct plus indirect.
    pub fn total(&self) -> Vec<[f32; 3]> {
        self.direct
            .iter()
            .zip(&self.indirect)
            .map(|(d, i)| (*d + *i).to_array())
            .collect()
    }
}

impl<'a> Relighter<'a> {
    /// The run time with exact shadows ([`Shadows::Rays`]).
    pub fn new(bake: &'a LocalBake) -> Self {
        Self::with_shadows(bake, Shadows::Rays)
    }

    pub fn with_shadows(bake: &'a LocalBake, shadows: Shadows) -> Self {
        let normals = bake.scene.normals.as_deref().unwrap_or_default();
        let extent = crate::scene::extent_of(&bake.scene.positions);
        let origins = bake::ray_origins(&vertex_ray_starts(&bake.scene), normals, extent);
        let frames = normals.iter().map(|&n| tangent_frame(n)).collect();
        let bvh = (shadows == Shadows::Rays)
            .then(|| Bvh::build(&bake.scene.positions, &bake.scene.triangles));
        Relighter {
            bake,
            origins,
            frames,
            bvh,
        }
    }

    pub fn shadows(&self) -> Shadows {
        match self.bvh {
            Some(_) => Shadows::Rays,
            None => Shadows::DepthMaps,
        }
    }

    pub fn receiver_frames(&self) -> ReceiverFrames<'_> {
        ReceiverFrames {
            positions: &self.bake.scene.positions,
            normals: self.bake.scene.normals.as_deref().unwrap_or_default(),
            origins: &self.origins,
            frames: &self.frames,
        }
    }

    /// Irradiance per receiver, visibility by shadow rays or from the compressed depth maps.
    pub fn irradiance(&self, lights: &[LocalLight]) -> Vec<f32> {
        match &self.bvh {
            Some(bvh) => irradiance_by_shadow_rays(&self.receiver_frames(), bvh, lights),
            None => irradiance_from_depth(
                &self.receiver_frames(),
                &self.bake.depth,
                &self.bake.grid,
                lights,
            ),
        }
    }

    /// Direct and indirect radiance for `lights` with the chosen operator.
    pub fn frame(&self, lights: &[LocalLight], form: OperatorForm) -> Frame {
        let irradiance = self.irradiance(lights);
        self.frame_from_irradiance(irradiance, form)
    }

    /// The rest of a frame once the irradiance is known.
    pub fn frame_from_irradiance(&self, irradiance: Vec<f32>, form: OperatorForm) -> Frame {
        let bake = self.bake;
        let direct = direct_radiance(&irradiance, &bake.scene.albedo);
        let indirect = match form {
            OperatorForm::Compressed => bake.operator.indirect(&irradiance),
            OperatorForm::Sparse => sparse_indirect(
                &bake.matrix,
                &bake.scene.albedo,
                bake.options.bounces,
                &direct,
            ),
        };
        Frame {
            irradiance,
            direct,
            indirect,
        }
    }
}

/// The sparse operator's bounces on the GPU (the bake's gather kernel): the gather matrix and
/// the albedo uploaded once, then per frame one kernel pass per bounce.
pub struct GpuSparse<'b> {
    baker: &'b bake::gpu::GpuBaker,
    matrix: bake::gpu::GpuGatherMatrix,
    bounces: u32,
}

impl<'b> GpuSparse<'b> {
    pub fn new(baker: &'b bake::gpu::GpuBaker, bake: &LocalBake) -> Result<Self> {
        Ok(GpuSparse {
            baker,
            matrix: baker.upload_gather_matrix(&bake.matrix, &bake.scene.albedo, 1)?,
            bounces: bake.options.bounces,
        })
    }

    /// `(T + ... + T^B) direct`, as [`operator::sparse_indirect`] on the CPU.
    pub fn indirect(&self, direct: &[Vec3]) -> Result<Vec<Vec3>> {
        let mut previous: Vec<f32> = direct.iter().flat_map(|d| d.to_array()).collect();
        let mut total = vec![Vec3::ZERO; direct.len()];
        for _ in 0..self.bounces {
            previous = self.baker.bounce(&self.matrix, &previous)?;
            for (t, c) in total.iter_mut().zip(previous.chunks_exact(3)) {
                *t += Vec3::new(c[0], c[1], c[2]);
            }
        }
        Ok(total)
    }
}

/// Both operators on the GPU, uploaded once for a sequence of frames.
pub struct GpuPaths<'b> {
    pub sparse: GpuSparse<'b>,
    /// Or why it could not be uploaded (one receiver cluster's responses larger than a
    /// storage binding): the frames are then timed without it.
    pub compressed: std::result::Result<gpu::GpuCompressed<'b>, String>,
}

impl<'b> GpuPaths<'b> {
    pub fn new(baker: &'b bake::gpu::GpuBaker, bake: &LocalBake) -> Result<Self> {
        Ok(GpuPaths {
            sparse: GpuSparse::new(baker, bake)?,
            compressed: gpu::GpuCompressed::new(baker, &bake.operator).map_err(|e| e.to_string()),
        })
    }
}

/// Per-frame relighting times, seconds, one entry per frame.
#[derive(Clone, Debug, Default)]
pub struct FrameTimes {
    /// Irradiance, by shadow rays or from the depth maps (shared by every operator).
    pub irradiance: Vec<f64>,
    /// Irradiance, direct radiance and the compressed operator.
    pub compressed: Vec<f64>,
    /// Irradiance, direct radiance and the sparse bounces on the CPU.
    pub sparse: Vec<f64>,
    /// Irradiance and direct radiance on the CPU, the sparse bounces on the GPU.
    pub gpu_sparse: Vec<f64>,
    /// Irradiance and direct radiance on the CPU, the compressed operator on the GPU
    /// (upload of the irradiance and read-back of the result included).
    pub gpu_compressed: Vec<f64>,
}

pub(super) fn mean_and_max_ms(times: &[f64]) -> (f64, f64) {
    let mean = times.iter().sum::<f64>() / times.len().max(1) as f64;
    let max = times.iter().cloned().fold(0.0, f64::max);
    (1e3 * mean, 1e3 * max)
}

impl FrameTimes {
    /// One line: mean and worst milliseconds per frame of each path.
    pub fn report(&self, receivers: usize, shadows: Shadows, gpu: Option<String>) -> String {
        let part = |name: &str, times: &[f64]| {
            let (mean, max) = mean_and_max_ms(times);
            format!("{name} {mean:.2} ms (max {max:.2})")
        };
        let mut parts = vec![
            part(
                &format!("irradiance by {}", shadows.describe()),
                &self.irradiance,
            ),
            part("+ compressed operator", &self.compressed),
            part("+ sparse operator", &self.sparse),
        ];
        if let Some(adapter) = gpu {
            if self.gpu_compressed.is_empty() {
                parts.push("+ compressed operator on the GPU: not run".into());
            } else {
                parts.push(part(
                    &format!("+ compressed operator on the GPU ({adapter})"),
                    &self.gpu_compressed,
                ));
            }
            parts.push(part(
                &format!("+ sparse operator on the GPU ({adapter})"),
                &self.gpu_sparse,
            ));
        }
        format!(
            "relighting per frame, {receivers} receivers, mean of {} frame(s): {}",
            self.irradiance.len(),
            parts.join("; ")
        )
    }
}

/// One frame timed on every path (the compressed and sparse operators on the CPU, and on the
/// GPU when given); returns the frame of the `form` asked for.
pub fn time_frame(
    relighter: &Relighter,
    lights: &[LocalLight],
    form: OperatorForm,
    gpu: Option<&GpuPaths>,
    times: &mut FrameTimes,
) -> Result<Frame> {
    let started = Instant::now();
    let irradiance = relighter.irradiance(lights);
    let seconds_irradiance = started.elapsed().as_secs_f64();
    times.irradiance.push(seconds_irradiance);
    let mut chosen = None;
    for (path, record) in [
        (OperatorForm::Compressed, &mut times.compressed),
        (OperatorForm::Sparse, &mut times.sparse),
    ] {
        let started = Instant::now();
        let frame = relighter.frame_from_irradiance(irradiance.clone(), path);
        record.push(seconds_irradiance + started.elapsed().as_secs_f64());
        if path == form {
            chosen = Some(frame);
        }
    }
    if let Some(gpu) = gpu {
        if let Ok(compressed) = &gpu.compressed {
            let started = Instant::now();
            direct_radiance(&irradiance, &relighter.bake.scene.albedo);
            compressed.indirect(&irradiance)?;
            times
                .gpu_compressed
                .push(seconds_irradiance + started.elapsed().as_secs_f64());
        }
        let started = Instant::now();
        let direct = direct_radiance(&irradiance, &relighter.bake.scene.albedo);
        gpu.sparse.indirect(&direct)?;
        times
            .gpu_sparse
            .push(seconds_irradiance + started.elapsed().as_secs_f64());
    }
    Ok(chosen.expect("both forms are timed"))
}

/// Frame `index`'s image: `path` itself for a single frame, else `STEM_012.EXT`.
pub fn frame_path(path: &std::path::Path, index: u32, frames: u32) -> std::path::PathBuf {
    if frames <= 1 {
        return path.to_path_buf();
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}_{index:03}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{index:03}"),
    };
    path.with_file_name(name)
}
