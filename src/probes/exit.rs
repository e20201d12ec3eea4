//! The light the scene's surfaces send towards a probe: each vertex's exit transfer,
//! `[vertex][channel][k]`, so that the radiance leaving it is `sum_k exit_k l_k`. Only an
//! interreflected bake has it; in a shadowed one the surfaces a probe sees reflect nothing.

use crate::bake::stream::Interreflected;
use crate::bake::{truncate_bands, BakedMesh, Mode, Transfer};
use crate::error::Result;
use crate::scene::Scene;
use crate::sh::coeff_count;

/// The exit transfer of every vertex. One channel where every albedo is grey (the probes'
/// lean form: the light's colour then passes unchanged), three otherwise.
pub struct ExitLight {
    pub(super) values: Vec<f32>,
    pub(super) channels: usize,
}

impl ExitLight {
    /// A whole bake's: its stored transfer (an interreflected bake's is never albedo-free: it
    /// carries the albedo of every bounce). `None` unless the bake is interreflected.
    pub fn of(baked: &BakedMesh) -> Option<ExitLight> {
        if baked.metadata.mode != Mode::Interreflected {
            return None;
        }
        let mut exit = ExitLight::for_scene(&baked.scene);
        exit.push(&baked.transfer);
        Some(exit)
    }

    /// A streamed interreflected bake's over its prepared `scene`, read back a chunk of
    /// `chunk` vertices at a time from its scratch file, at `bands` (fewer than it baked where
    /// `--bands auto` chose fewer).
    pub fn of_streamed(
        interreflected: &mut Interreflected,
        scene: &Scene,
        bands: u32,
        chunk: usize,
    ) -> Result<ExitLight> {
        let mut exit = ExitLight::for_scene(scene);
        let vertices = scene.vertex_count();
        for first in (0..vertices).step_by(chunk.max(1)) {
            let rgb = interreflected.chunk(first..(first + chunk).min(vertices), 3)?;
            exit.push(&truncate_bands(&rgb, bands));
        }
        Ok(exit)
    }

    fn for_scene(scene: &Scene) -> ExitLight {
        ExitLight {
            values: Vec::new(),
            channels: if scene.all_grey() { 1 } else { 3 },
        }
    }

    /// Appends the exit transfer of `transfer`'s vertices: each channel's stored transfer
    /// (the one stored channel of a lean file).
    fn push(&mut self, transfer: &Transfer) {
        let stored_channels = transfer.channels() as usize;
        self.values
            .reserve(transfer.vertex_count() * self.channels * coeff_count(transfer.bands()));
        for v in 0..transfer.vertex_count() {
            for c in 0..self.channels {
                let stored = transfer.vertex_channel(v, c.min(stored_channels - 1));
                self.values.extend_from_slice(stored);
            }
        }
    }
}
