//! The bytes a glTF file's buffers and images name: the GLB's BIN chunk, a base64 `data:` URI,
//! or a file beside the glTF.
//!
//! glTF URIs are data URIs or relative paths, `../` included (glTF 2.0, §3.1 "URIs"); a client
//! may support more, and this one does not: an absolute path or another scheme (`file:`,
//! `http:`) is refused, naming the URI, so a scene cannot have the bake read files anywhere it
//! likes. A file must be a regular file (not a device, a pipe or a directory) and is read no
//! further than needed: a buffer up to its `byteLength`, an image up to the file's size.

use std::io::Read;
use std::path::{Path, PathBuf};

use gltf_json::Root;

type Result<T> = std::result::Result<T, String>;

/// Each buffer's bytes, at least its `byteLength` (padded to a multiple of four, as the
/// `gltf` crate's importer gave them). `blob` is the GLB's BIN chunk, for the buffer without a
/// URI.
pub(super) fn buffers(root: &Root, base: &Path, mut blob: Option<Vec<u8>>) -> Result<Vec<Vec<u8>>> {
    root.buffers
        .iter()
        .enumerate()
        .map(|(index, buffer)| {
            let length = buffer.byte_length.0;
            let fail = |message: String| format!("cannot read buffer {index}: {message}");
            let mut data = match &buffer.uri {
                None => blob
                    .take()
                    .ok_or_else(|| fail("it has no uri and there is no BIN chunk for it".into()))?,
                Some(uri) => read(uri, base, Some(length)).map_err(fail)?,
            };
            if (data.len() as u64) < length {
                return Err(fail(format!(
                    "it holds {} bytes, fewer than its byteLength {length}",
                    data.len()
                )));
            }
            while data.len() % 4 != 0 {
                data.push(0);
            }
            Ok(data)
        })
        .collect()
}

/// The bytes `uri` names (a `data:` URI, or a file relative to `base`): a file no longer than
/// `limit` bytes when given, and then refused if shorter.
pub(super) fn read(uri: &str, base: &Path, limit: Option<u64>) -> Result<Vec<u8>> {
    if let Some(data) = uri.strip_prefix("data:") {
        return decode_data_uri(data);
    }
    read_file(&resolve(uri, base)?, limit)
}

fn decode_data_uri(data: &str) -> Result<Vec<u8>> {
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    use base64::Engine;
    // Padding optional, as the `gltf` crate's importer read it.
    const BASE64: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
    );
    let (_, payload) = data
        .split_once(";base64,")
        .ok_or_else(|| "a data: URI that is not base64".to_string())?;
    BASE64
        .decode(payload)
        .map_err(|e| format!("a data: URI that does not decode: {e}"))
}

/// The file a relative `uri` names, percent-decoded and joined to `base`.
fn resolve(uri: &str, base: &Path) -> Result<PathBuf> {
    if scheme(uri).is_some() {
        return Err(format!(
            "its uri {uri:?} is neither a data: URI nor a relative path, the only resources \
             prt-gpu reads"
        ));
    }
    let relative = percent_decode(uri);
    let path = Path::new(&relative);
    if path.has_root() || path.is_absolute() {
        return Err(format!(
            "its uri {uri:?} is an absolute path; glTF resources are data: URIs or paths \
             relative to the glTF file"
        ));
    }
    Ok(base.join(path))
}

/// The scheme of an absolute URI (RFC 3986 §3.1: a letter, then letters, digits, `+`, `-`,
/// `.`, then `:` before any `/`, `?` or `#`); `None` for a relative reference.
fn scheme(uri: &str) -> Option<&str> {
    let end = uri.find([':', '/', '?', '#'])?;
    let scheme = &uri[..end];
    let valid = uri[end..].starts_with(':')
        && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        && scheme
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c));
    valid.then_some(scheme)
}

/// A regular file's bytes, at most `limit` of them (and then no fewer).
fn read_file(path: &Path, limit: Option<u64>) -> Result<Vec<u8>> {
    let shown = path.display();
    let not_regular = |meta: &std::fs::Metadata| {
        format!(
            "{shown} is {}",
            if meta.is_dir() {
                "a directory"
            } else {
                "not a regular file"
            }
        )
    };
    // Checked before opening too: opening a named pipe would wait for a writer.
    let meta = std::fs::metadata(path).map_err(|e| format!("{shown}: {e}"))?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    let file = std::fs::File::open(path).map_err(|e| format!("{shown}: {e}"))?;
    let meta = file.metadata().map_err(|e| format!("{shown}: {e}"))?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    let size = meta.len();
    let wanted = match limit {
        Some(limit) if size < limit => {
            return Err(format!(
                "{shown} has {size} bytes, fewer than the buffer's byteLength {limit}"
            ))
        }
        Some(limit) => limit,
        None => size,
    };
    let mut bytes = Vec::with_capacity(usize::try_from(wanted).unwrap_or(0));
    file.take(wanted)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("{shown}: {e}"))?;
    if (bytes.len() as u64) < wanted {
        return Err(format!("{shown} became shorter while it was read"));
    }
    Ok(bytes)
}

/// `%XX` escapes decoded (a URI's path is percent-encoded); anything else kept as written.
fn percent_decode(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], hex) {
            (b'%', Some(byte)) => {
                out.push(byte);
                i += 3;
            }
            (byte, _) => {
                out.push(byte);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_are_percent_decoded() {
        assert_eq!(percent_decode("my%20box%2Fa.bin"), "my box/a.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("%zz"), "%zz");
    }

    #[test]
    fn schemes_are_told_from_relative_paths() {
        assert_eq!(scheme("file:///etc/passwd"), Some("file"));
        assert_eq!(scheme("http://example.com/x.bin"), Some("http"));
        assert_eq!(scheme("C:/textures/a.png"), Some("C"));
        assert_eq!(scheme("a.bin"), None);
        assert_eq!(scheme("../dir/x.png"), None);
        assert_eq!(scheme("dir/a:b.png"), None);
        assert_eq!(scheme("1a:b.png"), None);
    }

    #[test]
    fn relative_paths_resolve_beside_the_file_and_absolute_ones_are_refused() {
        let base = Path::new("scenes/box");
        assert_eq!(
            resolve("../textures/a%20b.png", base).unwrap(),
            Path::new("scenes/box/../textures/a b.png")
        );
        for uri in ["/etc/passwd", "%2Fetc%2Fpasswd", "/dev/zero"] {
            let error = resolve(uri, base).unwrap_err();
            assert!(error.contains("absolute path"), "{error}");
            assert!(error.contains(&format!("{uri:?}")), "{error}");
        }
        let error = resolve("file:///etc/passwd", base).unwrap_err();
        assert!(
            error.contains("neither a data: URI nor a relative path"),
            "{error}"
        );
    }

    #[test]
    fn a_buffer_reads_its_byte_length_and_no_more() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("b.bin"), [7u8; 10]).unwrap();
        assert_eq!(read("b.bin", dir.path(), Some(6)).unwrap(), [7u8; 6]);
        assert_eq!(read("b.bin", dir.path(), None).unwrap(), [7u8; 10]);
        let error = read("b.bin", dir.path(), Some(11)).unwrap_err();
        assert!(error.contains("has 10 bytes, fewer than"), "{error}");
        let error = read(".", dir.path(), Some(4)).unwrap_err();
        assert!(error.ends_with("is a directory"), "{error}");
        let error = read("absent.bin", dir.path(), Some(4)).unwrap_err();
        assert!(error.contains("absent.bin"), "{error}");
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_not_read() {
        // /dev/zero through a relative path: refused before a byte is read.
        let dir = tempfile::tempdir().unwrap();
        std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.bin")).unwrap();
        for limit in [Some(96), None] {
            let error = read("zero.bin", dir.path(), limit).unwrap_err();
            assert!(error.ends_with("is not a regular file"), "{error}");
        }
    }

    #[test]
    fn data_uris_decode_with_or_without_padding() {
        let base = Path::new(".");
        assert_eq!(
            read("data:application/octet-stream;base64,AAE=", base, None).unwrap(),
            [0, 1]
        );
        assert_eq!(
            read("data:application/octet-stream;base64,AAE", base, None).unwrap(),
            [0, 1]
        );
        assert!(read("data:text/plain,hello", base, None)
            .unwrap_err()
            .contains("not base64"));
        assert!(read("data:;base64,@@@@", base, None)
            .unwrap_err()
            .contains("does not decode"));
    }
}
