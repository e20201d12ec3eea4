//! Dilation: invalid texels filled from their valid neighbours ring by ring, so that bilinear
//! (and wider) lookups past a chart's edge, or across a refilled leak, read values of the chart
//! they belong to. Which texels fill, and from which neighbours, depends on the mask alone
//! ([`DilationPlan`]), so a lightmap cleaned up a group of coefficients at a time fills every
//! group alike.

use rayon::prelude::*;

use crate::error::{Error, Result};

/// Fills invalid texels from valid ones, `passes` rings deep. In each pass, every invalid texel
/// with at least one valid 8-neighbour takes the average of those neighbours (read before the
/// pass, so the result does not depend on scan order) and becomes valid.
///
/// `values` is `[texel][channel]`, row-major, `width * height * channels` long; `valid` has one
/// flag per texel. Mismatched lengths are an error.
pub fn dilate(
    width: u32,
    height: u32,
    values: &mut [f32],
    channels: usize,
    valid: &mut [bool],
    passes: u32,
) -> Result<()> {
    dilate_by_owner(width, height, values, channels, valid, &[], passes)
}

/// [`dilate`], each texel filled only from neighbours of its own owner (`owner`, one label per
/// texel, such as [`super::texels::nearest_owner`]'s chart; empty for one owner): a texel in the gutter takes
/// the values of the chart it is nearest, whatever the texels of a nearer-filled neighbour
/// chart hold.
pub fn dilate_by_owner(
    width: u32,
    height: u32,
    values: &mut [f32],
    channels: usize,
    valid: &mut [bool],
    owner: &[u32],
    passes: u32,
) -> Result<()> {
    let (w, h) = (width as usize, height as usize);
    let texels = w.checked_mul(h);
    if texels != Some(valid.len())
        || texels.and_then(|n| n.checked_mul(channels)) != Some(values.len())
        || !(owner.is_empty() || Some(owner.len()) == texels)
    {
        return Err(Error::Options(format!(
            "dilation of a {width} x {height} image of {channels} channels given {} values and {} flags",
            values.len(),
            valid.len()
        )));
    }
    plan_dilation((width, height), valid, owner, passes).apply(values, channels);
    Ok(())
}

/// What [`dilate_by_owner`] fills, pass by pass, from a mask alone: the values it averages
/// never decide which texels fill, so one plan serves every group of channels of an image
/// (a lightmap cleaned up a few coefficients at a time) with the same bits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DilationPlan {
    /// Each pass's filled texels, with the end of their neighbours in `neighbours`.
    passes: Vec<Vec<(usize, usize)>>,
    /// The valid neighbours each filled texel averages, in the order they are summed.
    neighbours: Vec<u32>,
}

/// The plan of [`dilate_by_owner`] on `valid` (`width` x `height` flags, made valid where the
/// passes fill) and `owner`: rows in parallel, a texel's neighbours read as valid before its
/// pass, so the plan does not depend on the threads.
pub fn plan_dilation(
    (width, height): (u32, u32),
    valid: &mut [bool],
    owner: &[u32],
    passes: u32,
) -> DilationPlan {
    let (w, h) = (width as usize, height as usize);
    let mut plan = DilationPlan::default();
    for _ in 0..passes {
        let rows: Vec<Vec<(usize, Vec<u32>)>> = (0..h)
            .into_par_iter()
            .map(|y| fill_row(w, h, y, valid, owner))
            .collect();
        let mut pass = Vec::new();
        for (texel, neighbours) in rows.into_iter().flatten() {
            plan.neighbours.extend(neighbours);
            pass.push((texel, plan.neighbours.len()));
            valid[texel] = true;
        }
        if pass.is_empty() {
            break;
        }
        plan.passes.push(pass);
    }
    plan
}

impl DilationPlan {
    /// Fills `values` (`channels` a texel) as planned: each filled texel the mean of its
    /// neighbours, summed in a fixed order. In place: a pass reads only texels valid before it,
    /// which it never writes.
    pub fn apply(&self, values: &mut [f32], channels: usize) {
        let mut start = 0;
        let mut sum = vec![0.0f32; channels];
        for pass in &self.passes {
            for &(texel, end) in pass {
                let neighbours = &self.neighbours[start..end];
                start = end;
                sum.fill(0.0);
                for &n in neighbours {
                    let n = n as usize;
                    let neighbour = &values[n * channels..(n + 1) * channels];
                    sum.iter_mut().zip(neighbour).for_each(|(a, v)| *a += v);
                }
                let count = neighbours.len() as f32;
                for (value, a) in values[texel * channels..(texel + 1) * channels]
                    .iter_mut()
                    .zip(&sum)
                {
                    *value = a / count;
                }
            }
        }
    }
}

/// The invalid texels of row `y` with a valid 8-neighbour of the same owner, and those
/// neighbours in the order they are summed.
fn fill_row(w: usize, h: usize, y: usize, valid: &[bool], owner: &[u32]) -> Vec<(usize, Vec<u32>)> {
    let mut filled = Vec::new();
    for x in 0..w {
        if valid[y * w + x] {
            continue;
        }
        let neighbours: Vec<u32> = (y.saturating_sub(1)..(y + 2).min(h))
            .flat_map(|ny| (x.saturating_sub(1)..(x + 2).min(w)).map(move |nx| ny * w + nx))
            .filter(|&n| valid[n] && (owner.is_empty() || owner[n] == owner[y * w + x]))
            .map(|n| n as u32)
            .collect();
        if !neighbours.is_empty() {
            filled.push((y * w + x, neighbours));
        }
    }
    filled
}
