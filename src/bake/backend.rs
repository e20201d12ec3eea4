//! Where the transfer is computed: the CPU or the GPU, and the operations every stage asks of
//! either — the direct pass (with the gather matrix where light bounces), and gathers through
//! that matrix. Only this file tells the two apart; the stages call its operations.

use glam::Vec3;

use super::bounce::{self, GatherMatrix};
use super::{gpu, DirectInputs, DirectPass, Mode, Progress};
use crate::device::GpuContext;
use crate::error::Result;
use crate::sh::coeff_count;

/// Where the transfer is computed.
pub enum Backend<'a> {
    Cpu,
    Gpu {
        baker: &'a gpu::GpuBaker,
        chunking: gpu::Chunking,
    },
}

impl<'a> Backend<'a> {
    /// "cpu", or "gpu: adapter (backend, type)".
    pub fn describe(&self) -> String {
        match self {
            Backend::Cpu => "cpu".to_string(),
            Backend::Gpu { baker, .. } => format!("gpu: {}", baker.context.adapter.label()),
        }
    }

    /// The device of a GPU backend, for stages that can use it.
    pub fn gpu_context(&self) -> Option<&'a GpuContext> {
        match self {
            Backend::Gpu { baker, .. } => Some(&baker.context),
            Backend::Cpu => None,
        }
    }

    /// The direct pass over the receivers of `inputs`: albedo-free transfer, and in
    /// interreflected mode the gather matrix of the rays' closest hits.
    pub fn direct_pass(
        &self,
        inputs: &DirectInputs,
        mode: Mode,
        progress: &dyn Progress,
    ) -> Result<DirectPass> {
        progress.stage("transfer", inputs.origins.len() as u64);
        let (scalar, matrix, rays_cast) = match (self, mode) {
            (Backend::Cpu, Mode::Interreflected) => {
                let (scalar, matrix, rays) =
                    bounce::direct_transfer_and_gather_matrix_cpu(inputs, progress);
                (scalar, Some(matrix), rays)
            }
            (Backend::Cpu, mode) => {
                let (scalar, rays) = super::cpu::direct_transfer(inputs, mode, progress);
                (scalar, None, rays)
            }
            (Backend::Gpu { baker, chunking }, Mode::Interreflected) => {
                let (scalar, matrix, run) =
                    gpu::direct_transfer_and_gather_matrix(baker, inputs, *chunking, progress)?;
                (scalar, Some(matrix), run.rays_cast)
            }
            (Backend::Gpu { baker, chunking }, mode) => {
                let (scalar, run) = gpu::direct_transfer(baker, inputs, mode, *chunking, progress)?;
                (scalar, None, run.rays_cast)
            }
        };
        Ok(DirectPass {
            scalar,
            matrix,
            rays_cast,
            adaptive: None,
        })
    }

    /// `matrix` (rows: receivers of `albedo`) made ready to gather `bands`-band RGB transfer
    /// on this backend: uploaded once to the GPU, however many bounces then read it.
    pub fn gatherer<'m>(
        &self,
        matrix: &'m GatherMatrix,
        albedo: &'m [Vec3],
        bands: u32,
    ) -> Result<Gatherer<'m>>
    where
        'a: 'm,
    {
        Ok(match self {
            Backend::Cpu => Gatherer::Cpu {
                matrix,
                albedo,
                coeffs: coeff_count(bands),
            },
            Backend::Gpu { baker, .. } => Gatherer::Gpu {
                baker,
                uploaded: baker.upload_gather_matrix(matrix, albedo, bands)?,
            },
        })
    }
}

/// A gather matrix where its backend reads it ([`Backend::gatherer`]).
pub enum Gatherer<'m> {
    Cpu {
        matrix: &'m GatherMatrix,
        albedo: &'m [Vec3],
        coeffs: usize,
    },
    Gpu {
        baker: &'m gpu::GpuBaker,
        uploaded: gpu::GpuGatherMatrix,
    },
}

impl Gatherer<'_> {
    /// One gather: `next[p][c][k] = albedo[p][c] sum_j weight_pj values[j][c][k]`.
    pub fn gather(&self, values: &[f32]) -> Result<Vec<f32>> {
        match self {
            Gatherer::Cpu {
                matrix,
                albedo,
                coeffs,
            } => Ok(bounce::apply_cpu(matrix, values, albedo, *coeffs)),
            Gatherer::Gpu { baker, uploaded } => baker.bounce(uploaded, values),
        }
    }
}
