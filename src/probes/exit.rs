//! The light the scene's surfaces send towards a probe: each vertex's exit transfer,
//! `[vertex][channel][k]`, so that the radiance leaving it is `sum_k exit_k l_k`. Only an
//! interreflected bake has it; in a shadowed one the surfaces a probe sees reflect nothing.

use glam::Vec3;

use crate::bake::stream::Interreflected;
use crate::bake::{truncate_bands, BakedMesh, Mode, Transfer};
use crate::error::Result;
use crate::sh::coeff_count;

/// The exit transfer of every vertex. One channel where every albedo is grey (the probes'
/// lean form: the light's colour then passes unchanged), three otherwise.
pub struct ExitLight {
    pub(super) values: Vec<f32>,
    pub(super) channels: usize,
}

impl ExitLight {
    /// A whole bake's: its stored transfer, tinted by the albedo where it is albedo-free.
    /// `None` unless the bake is interreflected.
    pub fn of(baked: &BakedMesh) -> Option<ExitLight> {
        if baked.metadata.mode != Mode::Interreflected {
            return None;
        }
        let mut exit = ExitLight::for_albedo(&baked.scene.albedo);
        let tint = baked.metadata.albedo_free;
        exit.push(&baked.transfer, &baked.scene.albedo, tint);
        Some(exit)
    }

    /// A streamed interreflected bake's, read back a chunk of `chunk` vertices at a time from
    /// its scratch file, at `bands` (fewer than it baked where `--bands auto` chose fewer).
    pub fn of_streamed(
        interreflected: &mut Interreflected,
        albedo: &[Vec3],
        bands: u32,
        chunk: usize,
    ) -> Result<ExitLight> {
        let mut exit = ExitLight::for_albedo(albedo);
        for first in (0..albedo.len()).step_by(chunk.max(1)) {
            let range = first..(first + chunk).min(albedo.len());
            let rgb = interreflected.chunk(range.clone(), 3)?;
            exit.push(&truncate_bands(&rgb, bands), &albedo[range], false);
        }
        Ok(exit)
    }

    fn for_albedo(albedo: &[Vec3]) -> ExitLight {
        let grey = albedo.iter().all(|a| a.x == a.y && a.y == a.z);
        ExitLight {
            values: Vec::new(),
            channels: if grey { 1 } else { 3 },
        }
    }

    /// Appends the exit transfer of `transfer`'s vertices (`albedo` theirs): each channel's
    /// stored transfer (the one stored channel of a lean file), times the albedo where `tint`.
    fn push(&mut self, transfer: &Transfer, albedo: &[Vec3], tint: bool) {
        let stored_channels = transfer.channels() as usize;
        let n = coeff_count(transfer.bands());
        self.values
            .reserve(transfer.vertex_count() * self.channels * n);
        for (v, vertex_albedo) in albedo.iter().enumerate().take(transfer.vertex_count()) {
            for (c, &tint_c) in vertex_albedo
                .to_array()
                .iter()
                .enumerate()
                .take(self.channels)
            {
                let stored = transfer.vertex_channel(v, c.min(stored_channels - 1));
                let scale = if tint { tint_c } else { 1.0 };
                self.values.extend(stored.iter().map(|t| t * scale));
            }
        }
    }
}
