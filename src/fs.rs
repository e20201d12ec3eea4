//! Files written whole or not at all: every output of the crate (baked files, images, charts,
//! light files, CSV) goes through [`write_atomically`], so none is ever left half-written.

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::Path;

use crate::error::{Error, Result};

/// Writes `bytes` to `path` through a temporary file in the same directory that is synced and
/// renamed over the target; on failure the temporary file is removed. Every output format of
/// the crate goes through here, so none can leave a half-written file.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = check_destination(path)?;
    let Some(file_name) = path.file_name() else {
        return Err(Error::io(
            path,
            io::Error::new(io::ErrorKind::InvalidInput, "output path names no file"),
        ));
    };
    let mut tmp_name = file_name.to_os_string();
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = dir.join(tmp_name);
    let result = write_then_rename(&tmp, path, bytes);
    if result.is_err() {
        // Best effort: the error being reported matters more than a failure to clean up.
        let _ = fs::remove_file(&tmp);
    } else {
        sync_dir(dir);
    }
    result
}

/// Checks that `path` can be written to: its directory exists. Returns that directory.
///
/// Called by every writer, and by the CLI before a long bake so a typo fails in a second.
pub fn check_destination(path: &Path) -> Result<&Path> {
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    if dir.is_dir() {
        return Ok(dir);
    }
    let problem = if dir.exists() {
        "is not a directory"
    } else {
        "does not exist"
    };
    Err(Error::io(
        path,
        io::Error::new(
            io::ErrorKind::NotFound,
            format!("output directory {} {problem}", dir.display()),
        ),
    ))
}

fn write_then_rename(tmp: &Path, path: &Path, bytes: &[u8]) -> Result<()> {
    let mut file = File::create(tmp).map_err(|e| Error::io(tmp, e))?;
    file.write_all(bytes).map_err(|e| Error::io(tmp, e))?;
    file.flush().map_err(|e| Error::io(tmp, e))?;
    // Without the sync a crash right after the rename could leave a renamed but empty file.
    file.sync_all().map_err(|e| Error::io(tmp, e))?;
    drop(file);
    fs::rename(tmp, path).map_err(|e| Error::io(path, e))
}

/// A file written piece by piece (at any offset) and then put in place whole: a temporary file
/// beside the target that [`AtomicFile::commit`] syncs and renames, and that is removed when
/// the writer is dropped uncommitted (an error or a panic halfway). For outputs too large to
/// hold in memory; the rest go through [`write_atomically`].
pub struct AtomicFile {
    file: Option<File>,
    tmp: std::path::PathBuf,
    path: std::path::PathBuf,
}

impl AtomicFile {
    pub fn create(path: &Path) -> Result<AtomicFile> {
        let dir = check_destination(path)?;
        let mut tmp_name = path.file_name().unwrap_or_default().to_os_string();
        tmp_name.push(format!(".tmp-{}", std::process::id()));
        let tmp = dir.join(tmp_name);
        let file = File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        Ok(AtomicFile {
            file: Some(file),
            tmp,
            path: path.to_path_buf(),
        })
    }

    /// Writes `bytes` at byte `offset` of the file.
    pub fn write_at(&mut self, offset: u64, bytes: &[u8]) -> Result<()> {
        use std::io::{Seek, SeekFrom};
        let file = self.file.as_mut().expect("open until committed");
        file.seek(SeekFrom::Start(offset))
            .and_then(|_| file.write_all(bytes))
            .map_err(|e| Error::io(&self.tmp, e))
    }

    /// Makes the file `len` bytes long (zeros where nothing was written yet).
    pub fn set_len(&mut self, len: u64) -> Result<()> {
        let file = self.file.as_mut().expect("open until committed");
        file.set_len(len).map_err(|e| Error::io(&self.tmp, e))
    }

    /// Syncs the file and renames it over the target.
    pub fn commit(mut self) -> Result<()> {
        let file = self.file.take().expect("open until committed");
        file.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
        drop(file);
        fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))?;
        if let Some(dir) = self.path.parent() {
            sync_dir(if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            });
        }
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            // Best effort: the error that stopped the writer matters more.
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

/// Makes the rename itself durable where the platform allows syncing a directory.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// The format `path` asks for by its extension (any case), from `(extension, format)` pairs;
/// `what` names the kind of file in the error ("images must end in .png or .exr").
pub fn format_by_extension<F: Copy>(path: &Path, formats: &[(&str, F)], what: &str) -> Result<F> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if let Some(&(_, format)) = formats
        .iter()
        .find(|(known, _)| extension.eq_ignore_ascii_case(known))
    {
        return Ok(format);
    }
    let names: Vec<String> = formats.iter().map(|(e, _)| format!(".{e}")).collect();
    Err(Error::Options(format!(
        "{}: {what} must end in {}",
        path.display(),
        names.join(" or ")
    )))
}
