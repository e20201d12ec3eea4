//! Files written whole or not at all: every output of the crate (baked files, images, charts,
//! light files, CSV) goes through [`write_atomically`], so none is ever left half-written; and
//! the checks every command makes of its outputs before it starts: [`check_outputs`] (no output
//! is one of the inputs or another output) and [`check_extension`] (the name says the format).

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `bytes` to `path` through a temporary file in the same directory that is synced and
/// renamed over the target; on failure the temporary file is removed. Every output format of
/// the crate goes through here, so none can leave a half-written file.
///
/// A target that exists and is neither a regular file nor a directory — a character device
/// such as `/dev/null`, a FIFO — is written directly instead: renaming over it would replace
/// the device with a regular file. Errors name `path`, never the temporary file.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = check_destination(path)?;
    if is_special_file(path) {
        return write_directly(path, bytes);
    }
    let tmp = temporary_beside(path, dir)?;
    let result = write_then_rename(&tmp, path, bytes);
    if result.is_err() {
        // Best effort: the error being reported matters more than a failure to clean up.
        let _ = fs::remove_file(&tmp);
    } else {
        sync_dir(dir);
    }
    result
}

/// Whether `path` exists and is neither a regular file nor a directory (after symbolic
/// links): a character or block device, a FIFO, a socket. Such a target is written to as it
/// is, not replaced.
pub fn is_special_file(path: &Path) -> bool {
    fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// The temporary name `path` is written under before the rename: in `dir`, beside it.
fn temporary_beside(path: &Path, dir: &Path) -> Result<PathBuf> {
    let Some(file_name) = path.file_name() else {
        return Err(Error::io(
            path,
            io::Error::new(io::ErrorKind::InvalidInput, "output path names no file"),
        ));
    };
    let mut tmp_name = file_name.to_os_string();
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    Ok(dir.join(tmp_name))
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

/// The temporary file's errors are the target's: the user named the target, and the temporary
/// is gone by the time the error is read.
fn write_then_rename(tmp: &Path, path: &Path, bytes: &[u8]) -> Result<()> {
    let mut file = File::create(tmp).map_err(|e| Error::io(path, e))?;
    file.write_all(bytes).map_err(|e| Error::io(path, e))?;
    file.flush().map_err(|e| Error::io(path, e))?;
    // Without the sync a crash right after the rename could leave a renamed but empty file.
    file.sync_all().map_err(|e| Error::io(path, e))?;
    drop(file);
    fs::rename(tmp, path).map_err(|e| Error::io(path, e))
}

/// `bytes` written straight into an existing device or FIFO (no temporary, no rename, no
/// sync: a device is not a file to make durable).
fn write_directly(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut file = OpenOptions::new()
        .write(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    file.write_all(bytes)
        .and_then(|()| file.flush())
        .map_err(|e| Error::io(path, e))
}

/// A file written piece by piece (at any offset) and then put in place whole: a temporary file
/// beside the target that [`AtomicFile::commit`] syncs and renames, and that is removed when
/// the writer is dropped uncommitted (an error or a panic halfway). For outputs too large to
/// hold in memory; the rest go through [`write_atomically`]. A device or FIFO target (see
/// [`write_atomically`]) gets a temporary file in the system's temporary directory instead,
/// copied into the target on commit. Errors name the target, never the temporary file.
pub struct AtomicFile {
    file: Option<File>,
    tmp: PathBuf,
    path: PathBuf,
    /// The target is a device or FIFO: copied into, not renamed over.
    special: bool,
}

impl AtomicFile {
    pub fn create(path: &Path) -> Result<AtomicFile> {
        let dir = check_destination(path)?;
        let special = is_special_file(path);
        let tmp = match special {
            // Not beside a device: that would put a file in /dev.
            true => std::env::temp_dir().join(format!(
                "prt-gpu-{}-{}",
                std::process::id(),
                path.file_name().unwrap_or_default().to_string_lossy()
            )),
            false => temporary_beside(path, dir)?,
        };
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)
            .map_err(|e| Error::io(path, e))?;
        Ok(AtomicFile {
            file: Some(file),
            tmp,
            path: path.to_path_buf(),
            special,
        })
    }

    /// Writes `bytes` at byte `offset` of the file.
    pub fn write_at(&mut self, offset: u64, bytes: &[u8]) -> Result<()> {
        use std::io::{Seek, SeekFrom};
        let file = self.file.as_mut().expect("open until committed");
        file.seek(SeekFrom::Start(offset))
            .and_then(|_| file.write_all(bytes))
            .map_err(|e| Error::io(&self.path, e))
    }

    /// The file itself, for a writer that streams into it (and seeks within it).
    pub fn file_mut(&mut self) -> &mut File {
        self.file.as_mut().expect("open until committed")
    }

    /// The file's first `len` bytes (all of it, where it is shorter), as written so far.
    pub fn read_prefix(&mut self, len: u64) -> Result<Vec<u8>> {
        use std::io::{Read, Seek, SeekFrom};
        let file = self.file.as_mut().expect("open until committed");
        let mut bytes = Vec::new();
        file.seek(SeekFrom::Start(0))
            .and_then(|_| Read::by_ref(file).take(len).read_to_end(&mut bytes))
            .map_err(|e| Error::io(&self.path, e))?;
        Ok(bytes)
    }

    /// Makes the file `len` bytes long (zeros where nothing was written yet).
    pub fn set_len(&mut self, len: u64) -> Result<()> {
        let file = self.file.as_mut().expect("open until committed");
        file.set_len(len).map_err(|e| Error::io(&self.path, e))
    }

    /// Syncs the file and renames it over the target (a device or FIFO target: copies it in).
    pub fn commit(mut self) -> Result<()> {
        let file = self.file.take().expect("open until committed");
        if self.special {
            let copied = copy_into(file, &self.path);
            let _ = fs::remove_file(&self.tmp);
            return copied;
        }
        let renamed = file
            .sync_all()
            .map_err(|e| Error::io(&self.path, e))
            .and_then(|()| {
                drop(file);
                fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))
            });
        if renamed.is_err() {
            let _ = fs::remove_file(&self.tmp);
            return renamed;
        }
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

/// The whole of `file` copied into the device or FIFO at `path`.
fn copy_into(mut file: File, path: &Path) -> Result<()> {
    use std::io::{Seek, SeekFrom};
    let mut target = OpenOptions::new()
        .write(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    file.seek(SeekFrom::Start(0))
        .and_then(|_| io::copy(&mut file, &mut target))
        .and_then(|_| target.flush())
        .map_err(|e| Error::io(path, e))
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

/// An output a command is about to write, and the option that names it (`-o`, `--preview`,
/// `--out-dir`), for the message that refuses it.
#[derive(Clone, Copy, Debug)]
pub struct Output<'a> {
    pub option: &'a str,
    pub path: &'a Path,
}

/// Refuses, before any work, outputs that would destroy what the command reads or writes:
/// an output that is the same file as one of `inputs` (`bake a.obj -o ./a.obj`, a hard link),
/// or two outputs that are the same file (a preview written over the lightmap). Outputs that
/// exist and are devices or FIFOs (`-o /dev/null`) are written into, not replaced, and are
/// not compared.
pub fn check_outputs(outputs: &[Output], inputs: &[&Path]) -> Result<()> {
    let checked: Vec<&Output> = outputs
        .iter()
        .filter(|o| !is_special_file(o.path))
        .collect();
    for (k, output) in checked.iter().enumerate() {
        if inputs.iter().any(|input| same_file(output.path, input)) {
            return Err(Error::Output(format!(
                "output {} is also an input; choose another {}",
                output.path.display(),
                output.option
            )));
        }
        if let Some(earlier) = checked[..k]
            .iter()
            .find(|earlier| same_file(earlier.path, output.path))
        {
            return Err(Error::Output(format!(
                "output {} ({}) is also output {} ({}); choose another {}",
                output.path.display(),
                output.option,
                earlier.path.display(),
                earlier.option,
                output.option
            )));
        }
    }
    Ok(())
}

/// One output checked before any work, as [`check_outputs`] (not one of `inputs`),
/// [`check_extension`] (named for what the command writes) and [`check_destination`] (in a
/// directory that exists) check it.
pub fn check_output(
    output: Output,
    inputs: &[&Path],
    extensions: &[&str],
    what: &str,
) -> Result<()> {
    check_outputs(&[output], inputs)?;
    check_extension(output, extensions, what)?;
    check_destination(output.path).map(|_| ())
}

/// Whether `a` and `b` name the same file: the same device and inode where both exist (on
/// unix; elsewhere the same canonical path), else the same path once the directories are
/// resolved (`./a.obj` and `a.obj`, links to directories).
pub fn same_file(a: &Path, b: &Path) -> bool {
    if let (Ok(ma), Ok(mb)) = (fs::metadata(a), fs::metadata(b)) {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
        #[cfg(not(unix))]
        {
            let _ = (ma, mb);
        }
    }
    match (resolved(a), resolved(b)) {
        (Some(a), Some(b)) => a == b,
        _ => false,
    }
}

/// `path` made absolute with links resolved: the whole path where it exists, else its
/// directory (resolved) and its name.
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(canonical) = path.canonicalize() {
        return Some(canonical);
    }
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    Some(dir.canonicalize().ok()?.join(path.file_name()?))
}

/// Refuses, before any work, an output whose name does not end in one of `extensions` (any
/// case; without the dot), the formats the command writes there: `what` says what it writes
/// ("bake writes binary glTF"). An existing device or FIFO (`-o /dev/null`) takes the bytes as
/// they are and needs no extension.
pub fn check_extension(output: Output, extensions: &[&str], what: &str) -> Result<()> {
    match is_special_file(output.path) {
        true => Ok(()),
        false => check_named_format(output, extensions, what),
    }
}

/// [`check_extension`] for outputs whose format the name chooses (an image's `.png` or
/// `.exr`): a name without one of `extensions` is refused even for a device.
pub fn check_named_format(output: Output, extensions: &[&str], what: &str) -> Result<()> {
    if has_extension(output.path, extensions) {
        return Ok(());
    }
    let names: Vec<String> = extensions.iter().map(|e| format!(".{e}")).collect();
    Err(Error::Options(format!(
        "{} {}: {what}, so the name must end in {}",
        output.option,
        output.path.display(),
        names.join(" or ")
    )))
}

/// Whether `path`'s extension is one of `extensions` (any case; without the dot).
pub fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    extensions
        .iter()
        .any(|known| extension.eq_ignore_ascii_case(known))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_by_any_name() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        fs::create_dir(d.join("sub")).unwrap();
        fs::write(d.join("a.obj"), "v 0 0 0\n").unwrap();
        fs::hard_link(d.join("a.obj"), d.join("sub/b.obj")).unwrap();
        fs::write(d.join("c.obj"), "v 0 0 0\n").unwrap();
        let a = d.join("a.obj");
        assert!(same_file(&a, &d.join("sub/../a.obj")));
        assert!(same_file(&a, &d.join("./a.obj")));
        assert!(same_file(&a, &d.join("sub/b.obj")), "a hard link");
        assert!(
            !same_file(&a, &d.join("c.obj")),
            "equal bytes, another file"
        );
        // Not there yet: the same place by its resolved directory, not by its bytes.
        assert!(same_file(&d.join("new.glb"), &d.join("sub/../new.glb")));
        assert!(!same_file(&d.join("new.glb"), &a));
        assert!(!same_file(
            &d.join("no/such/x.glb"),
            &d.join("no/such/x.glb/..")
        ));
    }

    #[test]
    fn outputs_are_refused_over_inputs_and_each_other() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = dir.path().join("m.obj");
        fs::write(&mesh, "v 0 0 0\n").unwrap();
        let output = |option, path| Output { option, path };
        let same = dir.path().join("./m.obj");
        let error = check_outputs(&[output("-o", &same)], &[&mesh]).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "output {} is also an input; choose another -o",
                same.display()
            )
        );
        let (glb, png) = (dir.path().join("o.glb"), dir.path().join("o.png"));
        check_outputs(&[output("-o", &glb), output("--preview", &png)], &[&mesh]).unwrap();
        let error = check_outputs(&[output("-o", &png), output("--preview", &png)], &[&mesh])
            .unwrap_err()
            .to_string();
        assert!(error.contains("choose another --preview"), "{error}");
    }

    #[test]
    fn extensions_are_those_the_command_writes() {
        let output = |path: &'static str| Output {
            option: "-o",
            path: Path::new(path),
        };
        check_extension(output("a.glb"), &["glb"], "binary glTF").unwrap();
        check_extension(output("dir.x/A.GLB"), &["glb"], "binary glTF").unwrap();
        check_extension(output("v.htm"), &["html", "htm"], "a page").unwrap();
        for wrong in ["a.gltf", "a.glb.png", "a", "glb"] {
            let error = check_extension(output(wrong), &["glb"], "binary glTF")
                .unwrap_err()
                .to_string();
            assert_eq!(
                error,
                format!("invalid option: -o {wrong}: binary glTF, so the name must end in .glb")
            );
        }
    }

    #[test]
    fn write_errors_name_the_target_and_leave_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        // 254 bytes fit the usual limit of 255; with the temporary's suffix they do not.
        let target = dir.path().join(format!("{}.glb", "o".repeat(250)));
        let error = write_atomically(&target, b"bytes").unwrap_err();
        assert!(
            matches!(error, Error::Io { ref path, .. } if path == &target),
            "{error}"
        );
        let error = AtomicFile::create(&target).err().expect("refused");
        assert!(
            matches!(error, Error::Io { ref path, .. } if path == &target),
            "{error}"
        );
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
