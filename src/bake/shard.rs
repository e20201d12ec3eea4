//! One shard of a bake: the direct pass of a run of its receivers, for a part file.

use super::*;

/// A part of a bake's receivers: shard `index` of `count`, each a contiguous run of about
/// the same number of receivers in the prepared (Morton) order, so a shard's rays stay
/// coherent. Which receivers a shard holds depends only on the receiver count, and what
/// each receiver gets only on the receiver, so shards merge to the unsharded bake bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    pub fn new(index: u32, count: u32) -> Result<Shard> {
        if count == 0 || index >= count {
            return Err(Error::Options(format!(
                "--shard {index}/{count}: the shard index must lie in 0 to count - 1"
            )));
        }
        Ok(Shard { index, count })
    }

    /// The receivers of `total` this shard bakes.
    pub fn receivers(&self, total: usize) -> std::ops::Range<usize> {
        let edge = |i: u32| (total as u128 * i as u128 / self.count as u128) as usize;
        edge(self.index)..edge(self.index + 1)
    }
}

/// What a shard bakes: the direct pass of its receivers (gather rows included, for
/// interreflection), which of how many receivers they are, and the backend it ran on.
pub struct ShardPass {
    pub receivers: std::ops::Range<usize>,
    pub receivers_total: usize,
    pub direct: DirectPass,
    pub ran_on: String,
}

/// The direct pass of `shard`'s receivers of the bake of `scene` with `options`: everything a
/// shard computes. Bounces, fits and lightmaps need every receiver and run where the shards
/// are merged ([`bake_from`] with [`DirectSource::Given`], a [`GivenDirect`]).
pub fn bake_shard(
    scene: Scene,
    options: &BakeOptions,
    backend: &dyn Backend,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<ShardPass> {
    options.validate()?;
    let planned = plan(scene, options)?;
    let range = shard.receivers(planned.receivers.len());
    let direct = direct_or_adaptive(&planned.inputs, range.clone(), options, backend, progress)?;
    Ok(ShardPass {
        receivers: range,
        receivers_total: planned.receivers.len(),
        direct,
        ran_on: backend.describe(),
    })
}

/// A direct pass computed elsewhere (by the shards of a sharded bake) and given to the rest of
/// the bake, a run of receivers at a time: a whole bake asks for every receiver at once, a
/// streamed one a chunk at a time, so only a chunk's share need be held.
pub trait GivenDirect: Sync {
    /// The receivers the pass covers.
    fn receivers(&self) -> usize;
    /// The direct pass of the receivers `range`, its gather rows' columns indexing every
    /// receiver, and the rays of the shards whose first receiver lies in `range` (so that the
    /// chunks' rays add up to the whole pass's).
    fn direct(&self, range: std::ops::Range<usize>) -> Result<DirectPass>;
    /// What the pass ran on: the file records it.
    fn ran_on(&self) -> String;
}

impl DirectPass {
    /// The pass of the receivers `range` of this one (`coeffs` values each), its rays counted
    /// where `rays` says (see [`GivenDirect::direct`]).
    pub fn slice(&self, range: std::ops::Range<usize>, coeffs: usize, rays: bool) -> DirectPass {
        let matrix = self.matrix.as_ref().map(|m| {
            let (start, end) = (m.row_offsets[range.start], m.row_offsets[range.end]);
            let entries = start as usize..end as usize;
            bounce::GatherMatrix {
                row_offsets: m.row_offsets[range.start..=range.end]
                    .iter()
                    .map(|o| o - start)
                    .collect(),
                columns: m.columns[entries.clone()].to_vec(),
                weights: m.weights[entries].to_vec(),
            }
        });
        let adaptive = self.adaptive.as_ref().map(|a| adaptive::ReceiverErrors {
            samples: a.samples[range.clone()].to_vec(),
            errors: a.errors[range.clone()].to_vec(),
        });
        DirectPass {
            scalar: self.scalar[range.start * coeffs..range.end * coeffs].to_vec(),
            matrix,
            rays_cast: if rays { self.rays_cast } else { 0 },
            adaptive,
        }
    }
}
