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
/// are merged ([`bake_from`] with [`DirectSource::Given`]).
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
