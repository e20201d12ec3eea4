//! One error type for the whole library. Every message is a single line that names the
//! offending input, so the CLI can print it as is.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A mesh file that could not be parsed or that describes no usable geometry.
    #[error("{path}: {message}")]
    Mesh { path: PathBuf, message: String },
    /// Geometry that is structurally wrong whatever file it came from (NaN, bad indices, empty).
    #[error("invalid mesh: {0}")]
    Geometry(String),
    /// Options outside the range the baker supports.
    #[error("invalid option: {0}")]
    Options(String),
    /// An output that would destroy an input or another output of the same command (`-o` naming
    /// the mesh being baked); the message names the path and the option to change.
    #[error("{0}")]
    Output(String),
    /// No usable adapter, or the GPU failed (validation, device loss, limits).
    /// Parts of a sharded bake that do not make one bake.
    #[error("merge: {0}")]
    Merge(String),

    /// Meshes of a batch that failed (each reported as it failed).
    #[error("batch: {0}")]
    Batch(String),

    #[error("gpu: {0}")]
    Gpu(String),
    /// An environment map or light file that cannot be read, or lighting that cannot be projected.
    #[error("{path}: {message}")]
    Light { path: PathBuf, message: String },
    /// A baked file that is not one of ours, or is damaged.
    #[error("{path}: {message}")]
    Baked { path: PathBuf, message: String },
    /// A chart that cannot be drawn: nothing to plot on log axes, or the drawing failed.
    #[error("{path}: {message}")]
    Chart { path: PathBuf, message: String },
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    pub fn mesh(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Mesh {
            path: path.into(),
            message: printable(&message.into()),
        }
    }

    pub fn light(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Light {
            path: path.into(),
            message: printable(&message.into()),
        }
    }

    pub fn baked(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Baked {
            path: path.into(),
            message: printable(&message.into()),
        }
    }

    pub fn chart(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Chart {
            path: path.into(),
            message: message.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, Error>;

/// `message` on one line, every run of white space (line breaks included) made one space:
/// errors of other libraries (wgpu, exr) span lines, ours never do.
pub fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The most characters of a reader's message shown: one that quotes a file's bytes (a header
/// line, a token) shows the start and the end of it.
const MESSAGE_CHARS: usize = 240;

/// `message` as a terminal shows it: control characters (a NUL, an escape, a line break a
/// file put in a quoted token) escaped, and at most `MESSAGE_CHARS` characters, the middle
/// of a longer one left out.
pub fn printable(message: &str) -> String {
    let escaped: String = message
        .chars()
        .flat_map(|c| {
            let escape = c
                .is_control()
                .then(|| c.escape_default().collect::<String>());
            escape
                .unwrap_or_else(|| c.to_string())
                .chars()
                .collect::<Vec<_>>()
        })
        .collect();
    let count = escaped.chars().count();
    if count <= MESSAGE_CHARS {
        return escaped;
    }
    let head: String = escaped.chars().take(MESSAGE_CHARS * 2 / 3).collect();
    let tail: String = escaped.chars().skip(count - MESSAGE_CHARS / 3).collect();
    format!("{head}…{tail}")
}

/// An image decoder's error in plain words on one line: the `png` crate writes chunk types as
/// Rust debug dumps (`ChunkType { type: IHDR, critical: true, … }`), which become the chunk's
/// name.
pub fn image_error(error: &image::ImageError) -> String {
    let message = match error {
        image::ImageError::Limits(_) => {
            return "the image is larger than this program reads".into()
        }
        other => other.to_string(),
    };
    let mut plain = String::with_capacity(message.len());
    let mut rest = message.as_str();
    while let Some(at) = rest.find("ChunkType {") {
        plain.push_str(&rest[..at]);
        let dump = &rest[at..];
        let end = dump.find('}').map_or(dump.len(), |e| e + 1);
        let name = dump
            .split("type: ")
            .nth(1)
            .and_then(|t| t.split([',', ' ', '}']).next())
            .unwrap_or("a");
        rest = &dump[end..];
        plain.push_str(name);
        if !rest.starts_with(" chunk") {
            plain.push_str(" chunk");
        }
    }
    plain.push_str(rest);
    one_line(&plain)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A message of a thousand characters with a NUL in it (a PLY header line quoted as a
    /// fuzzer wrote it, unescaped): its start and end, the NUL escaped.
    #[test]
    fn messages_are_printable_and_short() {
        let line = format!(
            "unsupported PLY version '0.0{}\0r' (only 1.0 is supported)",
            "S".repeat(1000)
        );
        let shown = Error::mesh("m.ply", line).to_string();
        assert!(
            shown.starts_with("m.ply: unsupported PLY version '0.0SSS"),
            "{shown}"
        );
        assert!(
            shown.ends_with("SS\\u{0}r' (only 1.0 is supported)"),
            "{shown}"
        );
        assert!(shown.chars().count() < 260, "{}", shown.len());
        assert!(!shown.chars().any(char::is_control));
    }

    /// A PNG whose header chunk is damaged: the error names the chunk, with no debug dump.
    #[test]
    fn image_errors_are_plain_words_on_one_line() {
        let mut png = Vec::new();
        image::RgbImage::new(2, 2)
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        // The IHDR chunk's width, after the signature (8), length (4) and type (4).
        png[16] ^= 0x7f;
        let error = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap_err();
        let said = image_error(&error);
        assert!(!said.contains('{') && !said.contains('\n'), "{said}");
        assert!(said.contains("IHDR"), "{error} -> {said}");
        assert!(!said.contains("chunk chunk"), "{said}");
    }
}
