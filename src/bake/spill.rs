//! Scratch storage for a bake in bounded memory: arrays the bake must keep but need not hold —
//! an interreflected bake's gather rows and its transfer between bounces — in an unnamed
//! temporary file (in `TMPDIR`), which the system removes when the bake ends, however it ends.
//! What goes in comes back bit for bit, so a bake that spills writes the bytes of one that
//! does not.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::PathBuf;

use bytemuck::Pod;

use crate::error::{Error, Result};

/// An unnamed temporary file of plain values, written and read at byte offsets.
pub struct Spill {
    file: File,
    len: u64,
}

impl Spill {
    pub fn new() -> Result<Spill> {
        let file = tempfile::tempfile().map_err(|e| Error::io(temp_dir(), e))?;
        Ok(Spill { file, len: 0 })
    }

    /// Appends `values`; returns the offset they start at.
    pub fn append<T: Pod>(&mut self, values: &[T]) -> Result<u64> {
        let at = self.len;
        self.write_at(at, values)?;
        Ok(at)
    }

    /// Keeps the first `bytes` for [`Spill::write_at`]: appends go after them.
    pub fn reserve(&mut self, bytes: u64) {
        self.len = self.len.max(bytes);
    }

    /// Writes `values` at byte offset `at`, growing the file when they reach past its end.
    pub fn write_at<T: Pod>(&mut self, at: u64, values: &[T]) -> Result<()> {
        let bytes: &[u8] = bytemuck::cast_slice(values);
        self.file
            .seek(SeekFrom::Start(at))
            .and_then(|_| self.file.write_all(bytes))
            .map_err(|e| Error::io(temp_dir(), e))?;
        self.len = self.len.max(at + bytes.len() as u64);
        Ok(())
    }

    /// Fills `values` from byte offset `at`.
    pub fn read_at<T: Pod>(&mut self, at: u64, values: &mut [T]) -> Result<()> {
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(values);
        self.file
            .seek(SeekFrom::Start(at))
            .and_then(|_| self.file.read_exact(bytes))
            .map_err(|e| Error::io(temp_dir(), e))
    }

    /// `count` values read from byte offset `at`.
    pub fn read_vec<T: Pod>(&mut self, at: u64, count: usize) -> Result<Vec<T>> {
        let mut values = vec![T::zeroed(); count];
        self.read_at(at, &mut values)?;
        Ok(values)
    }
}

/// Where the scratch file lies, for the message of an error writing it (a full disk).
fn temp_dir() -> PathBuf {
    std::env::temp_dir().join("(prt-gpu scratch file)")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_come_back_as_they_went_in_wherever_they_were_written() {
        let mut spill = Spill::new().unwrap();
        let first = spill.append(&[1.5f32, -0.0, f32::MIN_POSITIVE]).unwrap();
        let second = spill.append(&[7u32, 8, 9, 10]).unwrap();
        assert_eq!((first, second), (0, 12));
        spill.write_at(4, &[2.5f32]).unwrap();
        let floats: Vec<f32> = spill.read_vec(first, 3).unwrap();
        assert_eq!(floats[0].to_bits(), 1.5f32.to_bits());
        assert_eq!(floats[1], 2.5);
        assert_eq!(floats[2], f32::MIN_POSITIVE);
        let words: Vec<u32> = spill.read_vec(second, 4).unwrap();
        assert_eq!(words, [7, 8, 9, 10]);
        assert!(
            spill.read_vec::<u32>(second, 5).is_err(),
            "read past the end"
        );
    }
}
