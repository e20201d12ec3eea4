//! Where the transfer is computed: the operations every stage asks of a backend — visibility
//! (the direct pass), closest hits (the gather matrix where light bounces, the distances of
//! local lights' depth maps) and gathers through that matrix. The CPU and the GPU implement
//! them; the stages call them and never ask which backend they have.

use glam::Vec3;
use rayon::prelude::*;

use super::bounce::{self, GatherMatrix, GatherRows, Hit};
use super::{cpu, gpu, DirectInputs, DirectPass, Mode, Progress};
use crate::device::GpuContext;
use crate::error::Result;
use crate::ray::blend_at;
use crate::receivers::denoise::{self, DenoiseGuide};
use crate::scene::Scene;
use crate::sh::coeff_count;

/// Where the transfer is computed: [`CpuBackend`] or [`GpuBackend`].
pub trait Backend: Sync {
    /// "cpu", or "gpu: adapter (backend, type)".
    fn describe(&self) -> String;

    /// The device of a GPU backend, for stages that can use it (clustered PCA).
    fn gpu_context(&self) -> Option<&GpuContext>;

    /// Albedo-free transfer of the receivers of `inputs` in `mode` (not interreflected), and
    /// the rays cast.
    fn direct_transfer(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<(Vec<f32>, u64)>;

    /// The projected sums of the receivers of `inputs` in `mode` (not interreflected),
    /// `[receiver][k]`, before they are finished into transfer (`cpu::finish_transfer`), and
    /// the rays cast: what an error-targeted bake adds up batch by batch.
    fn projected_sums(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<(Vec<f64>, u64)>;

    /// Albedo-free shadowed transfer of the receivers of `inputs`, the gather matrix of their
    /// rays' closest hits, and the rays cast.
    fn direct_transfer_and_gather_matrix(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<(Vec<f32>, GatherMatrix, u64)>;

    /// The projected sums of the receivers of `inputs` in shadowed mode, as
    /// [`Backend::projected_sums`] gives them, the gather rows of the same rays' closest hits
    /// ([`bounce::gather_row`]), and the rays cast: what an interreflected bake to an error
    /// target adds up batch by batch. Each ray is traced once for both: its closest hit, and
    /// it is open where it hits nothing.
    fn projected_sums_and_gather_rows(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<(Vec<f64>, GatherRows, u64)>;

    /// `matrix` (rows: receivers of `albedo`) made ready to gather `bands`-band RGB transfer:
    /// uploaded once to a GPU, however many bounces then read it.
    fn gatherer<'m>(
        &'m self,
        matrix: &'m GatherMatrix,
        albedo: &'m [Vec3],
        bands: u32,
    ) -> Result<Box<dyn Gatherer + 'm>>;

    /// The distance from each receiver's ray origin to the closest surface of `scene` along
    /// each sample direction of `inputs` above its horizon, `[receiver][sample]`, at most
    /// `cap`, and `cap` where the ray leaves the scene.
    fn closest_hit_distances(
        &self,
        inputs: &DirectInputs,
        scene: &Scene,
        cap: f32,
        progress: &dyn Progress,
    ) -> Result<Vec<f32>>;

    /// The closest hit of every ray of `inputs` above its receiver's horizon that hits
    /// something, `(sample, hit)` per receiver, samples ascending: what probes see.
    fn closest_hits(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<Vec<Vec<(u32, Hit)>>>;

    /// The lightmap `image` (`stride` floats a texel) filtered under `guide`
    /// ([`crate::receivers::denoise`]).
    fn denoise(&self, guide: &DenoiseGuide, image: &[f32], stride: usize) -> Result<Vec<f32>>;

    /// The direct pass over the receivers of `inputs`: albedo-free transfer, and in
    /// interreflected mode the gather matrix of the rays' closest hits.
    fn direct_pass(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<DirectPass> {
        progress.stage("transfer", inputs.origins.len() as u64);
        let (scalar, matrix, rays_cast) = match mode {
            Mode::Interreflected => {
                let (scalar, matrix, rays) =
                    self.direct_transfer_and_gather_matrix(inputs, progress)?;
                (scalar, Some(matrix), rays)
            }
            mode => {
                let (scalar, rays) = self.direct_transfer(inputs, mode, progress)?;
                (scalar, None, rays)
            }
        };
        Ok(DirectPass {
            scalar,
            matrix,
            rays_cast,
            adaptive: None,
        })
    }
}

/// One gather through a matrix a backend holds ([`Backend::gatherer`]):
/// `next[p][c][k] = albedo[p][c] sum_j weight_pj values[j][c][k]`.
pub trait Gatherer {
    fn gather(&self, values: &[f32]) -> Result<Vec<f32>>;
}

/// The CPU reference: the BVH traversed by rayon tasks, sums in f64.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuBackend;

impl Backend for CpuBackend {
    fn describe(&self) -> String {
        "cpu".to_string()
    }

    fn gpu_context(&self) -> Option<&GpuContext> {
        None
    }

    fn denoise(&self, guide: &DenoiseGuide, image: &[f32], stride: usize) -> Result<Vec<f32>> {
        Ok(denoise::denoise(guide, image, stride))
    }

    fn direct_transfer(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<(Vec<f32>, u64)> {
        Ok(super::cpu::direct_transfer(inputs, mode, progress))
    }

    fn projected_sums(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<(Vec<f64>, u64)> {
        Ok(super::cpu::projected_sums(inputs, mode, progress))
    }

    fn direct_transfer_and_gather_matrix(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<(Vec<f32>, GatherMatrix, u64)> {
        Ok(bounce::direct_transfer_and_gather_matrix_cpu(
            inputs, progress,
        ))
    }

    fn projected_sums_and_gather_rows(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<(Vec<f64>, GatherRows, u64)> {
        Ok(bounce::projected_sums_and_gather_rows_cpu(inputs, progress))
    }

    fn gatherer<'m>(
        &'m self,
        matrix: &'m GatherMatrix,
        albedo: &'m [Vec3],
        bands: u32,
    ) -> Result<Box<dyn Gatherer + 'm>> {
        Ok(Box::new(CpuGather {
            matrix,
            albedo,
            coeffs: coeff_count(bands),
        }))
    }

    /// The ray's own hit distance.
    fn closest_hit_distances(
        &self,
        inputs: &DirectInputs,
        _scene: &Scene,
        cap: f32,
        _progress: &dyn Progress,
    ) -> Result<Vec<f32>> {
        let samples = inputs.samples.len();
        let mut distances = vec![cap; inputs.origins.len() * samples];
        distances
            .par_chunks_mut(samples.max(1))
            .enumerate()
            .for_each(|(vertex, row)| {
                let above = cpu::samples_above_horizon(inputs, vertex);
                cpu::visit_closest_hits(inputs, vertex, &above, |s, _, hit| {
                    row[s as usize] = hit.t.min(cap);
                });
            });
        Ok(distances)
    }

    fn closest_hits(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<Vec<Vec<(u32, Hit)>>> {
        Ok((0..inputs.origins.len())
            .into_par_iter()
            .map(|receiver| {
                let above = cpu::samples_above_horizon(inputs, receiver);
                let hits = cpu::closest_hits_of(inputs, receiver, &above);
                progress.advance(1);
                hits
            })
            .collect())
    }
}

struct CpuGather<'m> {
    matrix: &'m GatherMatrix,
    albedo: &'m [Vec3],
    coeffs: usize,
}

impl Gatherer for CpuGather<'_> {
    fn gather(&self, values: &[f32]) -> Result<Vec<f32>> {
        Ok(bounce::apply_cpu(
            self.matrix,
            values,
            self.albedo,
            self.coeffs,
        ))
    }
}

/// The WGSL kernels on a wgpu device, in dispatches of `chunking`'s size.
#[derive(Clone, Copy)]
pub struct GpuBackend<'a> {
    pub baker: &'a gpu::GpuBaker,
    pub chunking: gpu::Chunking,
}

impl<'a> GpuBackend<'a> {
    /// `baker` in dispatches of the default size.
    pub fn new(baker: &'a gpu::GpuBaker) -> GpuBackend<'a> {
        GpuBackend {
            baker,
            chunking: gpu::Chunking::default(),
        }
    }
}

impl Backend for GpuBackend<'_> {
    fn describe(&self) -> String {
        format!("gpu: {}", self.baker.context.adapter.label())
    }

    fn gpu_context(&self) -> Option<&GpuContext> {
        Some(&self.baker.context)
    }

    fn denoise(&self, guide: &DenoiseGuide, image: &[f32], stride: usize) -> Result<Vec<f32>> {
        gpu::denoise::denoise(self.baker, guide, image, stride)
    }

    fn direct_transfer(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<(Vec<f32>, u64)> {
        let (scalar, run) =
            gpu::direct_transfer(self.baker, inputs, mode, self.chunking, progress)?;
        Ok((scalar, run.rays_cast))
    }

    fn projected_sums(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<(Vec<f64>, u64)> {
        let (sums, run) = gpu::projected_sums(self.baker, inputs, mode, self.chunking, progress)?;
        Ok((sums.iter().map(|&s| s as f64).collect(), run.rays_cast))
    }

    fn direct_transfer_and_gather_matrix(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<(Vec<f32>, GatherMatrix, u64)> {
        let (scalar, matrix, run) =
            gpu::direct_transfer_and_gather_matrix(self.baker, inputs, self.chunking, progress)?;
        Ok((scalar, matrix, run.rays_cast))
    }

    fn projected_sums_and_gather_rows(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<(Vec<f64>, GatherRows, u64)> {
        let (sums, rows, run) =
            gpu::projected_sums_and_gather_rows(self.baker, inputs, self.chunking, progress)?;
        Ok((
            sums.iter().map(|&s| s as f64).collect(),
            rows,
            run.rays_cast,
        ))
    }

    fn gatherer<'m>(
        &'m self,
        matrix: &'m GatherMatrix,
        albedo: &'m [Vec3],
        bands: u32,
    ) -> Result<Box<dyn Gatherer + 'm>> {
        Ok(Box::new(GpuGather {
            baker: self.baker,
            uploaded: self.baker.upload_gather_matrix(matrix, albedo, bands)?,
        }))
    }

    /// The distance to the hit point, interpolated from the hit triangle's corners by the
    /// kernel's barycentrics (the kernel does not return the ray's own distance).
    fn closest_hit_distances(
        &self,
        inputs: &DirectInputs,
        scene: &Scene,
        cap: f32,
        progress: &dyn Progress,
    ) -> Result<Vec<f32>> {
        let hits = gpu::closest_hits(self.baker, inputs, self.chunking, progress)?;
        let samples = inputs.samples.len();
        let mut distances = vec![cap; inputs.origins.len() * samples];
        distances
            .par_chunks_mut(samples.max(1))
            .zip(hits.par_iter().zip(inputs.origins))
            .for_each(|(row, (own, &origin))| {
                for &(sample, hit) in own {
                    let corners = scene.triangles[hit.triangle as usize];
                    let point = blend_at(&scene.positions, corners, hit.u, hit.v);
                    row[sample as usize] = (point - origin).length().min(cap);
                }
            });
        Ok(distances)
    }

    fn closest_hits(
        &self,
        inputs: &DirectInputs,
        progress: &dyn Progress,
    ) -> Result<Vec<Vec<(u32, Hit)>>> {
        gpu::closest_hits(self.baker, inputs, self.chunking, progress)
    }
}

struct GpuGather<'m> {
    baker: &'m gpu::GpuBaker,
    uploaded: gpu::GpuGatherMatrix,
}

impl Gatherer for GpuGather<'_> {
    fn gather(&self, values: &[f32]) -> Result<Vec<f32>> {
        self.baker.bounce(&self.uploaded, values)
    }
}

/// The backend of `baker` in `chunking`'s dispatches, or the CPU's without one.
pub fn backend_for(
    baker: Option<&gpu::GpuBaker>,
    chunking: gpu::Chunking,
) -> Box<dyn Backend + '_> {
    match baker {
        Some(baker) => Box::new(GpuBackend { baker, chunking }),
        None => Box::new(CpuBackend),
    }
}
