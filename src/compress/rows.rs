//! Where CPCA reads its rows from: the transfer in memory, or a scratch file that a bake in
//! bounded memory holds its transfer in. Every pass over the rows reads them in vertex order, a
//! block at a time, and works in parallel within the block; a block in memory is every row,
//! a file's block what the memory plan leaves room for. Each result depends on one row, or on
//! one cluster's members summed in vertex order, so the block size never changes a bit.

use std::borrow::Cow;
use std::ops::Range;

use crate::bake::Transfer;
use crate::error::Result;

/// Rows of [`Rows::dimension`] floats, one per vertex.
pub trait Rows {
    fn dimension(&self) -> usize;

    /// How many rows.
    fn len(&self) -> usize;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Rows read at once by [`for_each_block`].
    fn block(&self) -> usize;

    /// The rows `range`, at most [`Rows::block`] of them.
    fn read(&mut self, range: Range<usize>) -> Result<Cow<'_, [f32]>>;
}

/// The transfer vectors in memory, one row of `dimension` floats per vertex: one block.
#[derive(Clone, Copy)]
pub struct Points<'a> {
    pub data: &'a [f32],
    pub dimension: usize,
}

impl<'a> Points<'a> {
    /// The transfer's rows, one per vertex (its channels one after the other).
    pub fn of_transfer(transfer: &'a Transfer) -> Points<'a> {
        Points {
            data: transfer.coeffs(),
            dimension: transfer.channels() as usize * transfer.coeffs_per_channel(),
        }
    }

    pub fn len(&self) -> usize {
        self.data.len() / self.dimension
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `i` widened to f64.
    pub(super) fn row(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.data[i * self.dimension..(i + 1) * self.dimension]
            .iter()
            .map(|&x| x as f64)
    }

    pub(super) fn row_f64(&self, i: usize) -> Vec<f64> {
        self.row(i).collect()
    }
}

impl Rows for Points<'_> {
    fn dimension(&self) -> usize {
        self.dimension
    }

    fn len(&self) -> usize {
        Points::len(self)
    }

    fn block(&self) -> usize {
        Points::len(self).max(1)
    }

    fn read(&mut self, range: Range<usize>) -> Result<Cow<'_, [f32]>> {
        let n = self.dimension;
        Ok(Cow::Borrowed(&self.data[range.start * n..range.end * n]))
    }
}

/// Calls `each` with every block of `rows` in order: the index of its first row and its rows.
pub fn for_each_block(
    rows: &mut dyn Rows,
    mut each: impl FnMut(usize, Points) -> Result<()>,
) -> Result<()> {
    let (len, block, dimension) = (rows.len(), rows.block().max(1), rows.dimension());
    let mut first = 0;
    while first < len {
        let end = (first + block).min(len);
        let data = rows.read(first..end)?;
        each(
            first,
            Points {
                data: &data,
                dimension,
            },
        )?;
        first = end;
    }
    Ok(())
}

/// Row `i` of `rows`, widened to f64.
pub fn read_row(rows: &mut dyn Rows, i: usize) -> Result<Vec<f64>> {
    Ok(rows.read(i..i + 1)?.iter().map(|&x| x as f64).collect())
}

/// A transfer's rows read `block` at a time as copies, as a bake's scratch file gives them:
/// what the tests read in blocks through.
#[cfg(test)]
pub(super) struct InBlocks<'a> {
    pub points: Points<'a>,
    pub block: usize,
}

#[cfg(test)]
impl Rows for InBlocks<'_> {
    fn dimension(&self) -> usize {
        self.points.dimension
    }

    fn len(&self) -> usize {
        self.points.len()
    }

    fn block(&self) -> usize {
        self.block
    }

    fn read(&mut self, range: Range<usize>) -> Result<Cow<'_, [f32]>> {
        assert!(
            range.len() <= self.block,
            "{range:?} read in blocks of {}",
            self.block
        );
        let n = self.points.dimension;
        Ok(self.points.data[range.start * n..range.end * n]
            .to_vec()
            .into())
    }
}
