//! Hostile files: each reader of the tool fed bytes as a file of its kind, and what must hold
//! of what it gives back. It may refuse the bytes, in one line of plain words, or read them,
//! and then everything it read, and everything written from that, is finite. The suite's
//! mutation test (`tests/hostile_files.rs`) and the cargo-fuzz targets (`fuzz/`) share this
//! one definition. A panic is left to the caller: the test catches it, the fuzzer reports it.

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::bake::{self, BakeOptions, BakedMesh, CpuBackend, Mode, NoProgress};
use crate::error::Result;
use crate::testing::mutate::Mutator;
use crate::{glb, light, scene, shard};

/// A reader of the tool, named as its fuzz target and its corpus folder are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reader {
    /// An OBJ and the material library it names (the library left as written).
    Obj,
    /// A material library, named by a fixed OBJ.
    Mtl,
    Ply,
    /// A `.gltf`, its buffers and images in `data:` URIs, baked in place and written back.
    Gltf,
    /// A `.glb`, baked in place and written back.
    Glb,
    /// Environment maps, projected to SH as `prt-gpu light` does.
    Exr,
    Hdr,
    Png,
    Jpeg,
    /// light.json, as `prt-gpu light` writes it.
    LightJson,
    /// A shard's part file, merged as the only part of its bake (whole, and in two runs).
    Part,
    /// A baked `.glb` (plain or compressed), as `info`, `render` and `view` read it.
    Baked,
}

impl Reader {
    pub const ALL: [Reader; 12] = [
        Reader::Obj,
        Reader::Mtl,
        Reader::Ply,
        Reader::Gltf,
        Reader::Glb,
        Reader::Exr,
        Reader::Hdr,
        Reader::Png,
        Reader::Jpeg,
        Reader::LightJson,
        Reader::Part,
        Reader::Baked,
    ];

    /// The fuzz target's name, and the folder of its corpus under `fuzz/corpus/`.
    pub fn name(self) -> &'static str {
        match self {
            Reader::Obj => "obj",
            Reader::Mtl => "mtl",
            Reader::Ply => "ply",
            Reader::Gltf => "gltf",
            Reader::Glb => "glb",
            Reader::Exr => "exr",
            Reader::Hdr => "hdr",
            Reader::Png => "png",
            Reader::Jpeg => "jpeg",
            Reader::LightJson => "light_json",
            Reader::Part => "part",
            Reader::Baked => "baked",
        }
    }

    pub fn from_name(name: &str) -> Option<Reader> {
        Reader::ALL.into_iter().find(|r| r.name() == name)
    }

    /// The name the bytes are given on disk: the extension is how the tool picks a reader.
    fn file_name(self) -> &'static str {
        match self {
            Reader::Obj | Reader::Mtl => "mesh.obj",
            Reader::Ply => "mesh.ply",
            Reader::Gltf => "scene.gltf",
            Reader::Glb => "scene.glb",
            Reader::Exr => "sky.exr",
            Reader::Hdr => "sky.hdr",
            Reader::Png => "sky.png",
            Reader::Jpeg => "sky.jpg",
            Reader::LightJson => "light.json",
            Reader::Part => "bake.part",
            Reader::Baked => "baked.glb",
        }
    }
}

/// The material library the OBJ seeds name, and the OBJ that names the MTL seeds.
pub const COMPANION_MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl grey\nKd 0.5\n";
pub const COMPANION_OBJ: &str = "mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
    usemtl red\nf 1 2 3\nusemtl grey\nf 1 3 4\n";

/// What a reader did with the bytes, when nothing was wrong with how it did it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    Read,
    /// The one-line error a user would see.
    Refused(String),
}

/// Feeds `bytes` to `reader` as a file in `dir` (emptied of the previous case's files first)
/// and checks what came back: `Err` names what was wrong (a refusal of more than one line, or
/// with a Rust debug dump in it; a non-finite value read or written).
pub fn try_reader(
    reader: Reader,
    bytes: &[u8],
    dir: &Path,
) -> std::result::Result<Outcome, String> {
    let path = place(reader, bytes, dir).map_err(|e| format!("cannot write the case: {e}"))?;
    match read(reader, &path) {
        Ok(None) => Ok(Outcome::Read),
        Ok(Some(fault)) => Err(fault),
        Err(error) => {
            let message = error.to_string();
            plain_words(&message)?;
            Ok(Outcome::Refused(message))
        }
    }
}

/// A fuzz target's body: `bytes` (resealed, see [`resealed`]) through `reader` in a scratch
/// directory of this process; a fault is a panic, which the fuzzer records as a crash.
pub fn fuzz_one(reader: Reader, bytes: &[u8]) {
    static SCRATCH: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    let dir = SCRATCH.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("prt-gpu-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a scratch directory for the fuzz target");
        dir
    });
    if let Err(fault) = try_reader(reader, &resealed(reader, bytes), dir) {
        panic!("{}: {fault}", reader.name());
    }
}

fn place(reader: Reader, bytes: &[u8], dir: &Path) -> std::io::Result<PathBuf> {
    for entry in std::fs::read_dir(dir)? {
        std::fs::remove_file(entry?.path())?;
    }
    let path = dir.join(reader.file_name());
    match reader {
        Reader::Mtl => {
            std::fs::write(&path, COMPANION_OBJ)?;
            std::fs::write(dir.join("mesh.mtl"), bytes)?;
        }
        Reader::Obj => {
            std::fs::write(&path, bytes)?;
            std::fs::write(dir.join("mesh.mtl"), COMPANION_MTL)?;
        }
        _ => std::fs::write(&path, bytes)?,
    }
    Ok(path)
}

/// Runs the reader as the tool does; `Ok(Some(fault))` where what it gave is not finite.
fn read(reader: Reader, path: &Path) -> Result<Option<String>> {
    match reader {
        Reader::Obj | Reader::Mtl | Reader::Ply => {
            let (scene, _) = scene::load_with_warnings(path)?;
            let (baked, _) = quick_bake(scene)?;
            let written = glb::encode_glb(glb::Stored::plain(&baked)?)?;
            Ok(non_finite_baked(&baked).or_else(|| non_finite_glb(&written)))
        }
        Reader::Gltf | Reader::Glb => {
            let (gltf, scene) = scene::gltf::load(path)?;
            let (baked, report) = quick_bake(scene)?;
            let stored = glb::Stored::plain(&baked)?;
            let (written, _) =
                glb::scene::encode_scene_glb(&gltf, stored, &report.vertex_map, None)?;
            Ok(non_finite_baked(&baked).or_else(|| non_finite_glb(&written)))
        }
        Reader::Exr | Reader::Hdr | Reader::Png | Reader::Jpeg | Reader::LightJson => {
            let loaded = light::load(path, 3, None, false)?;
            Ok(non_finite(
                "light coefficient",
                loaded.light.coeffs.iter().flatten(),
            ))
        }
        Reader::Part => {
            use crate::bake::GivenDirect;
            let parts = shard::PartSet::read(&[path.to_path_buf()])?;
            // Read as a streamed merge reads it too: in two runs of receivers.
            let half = parts.receivers() / 2;
            parts.direct(0..half)?;
            parts.direct(half..parts.receivers())?;
            let direct = parts.direct(0..parts.receivers())?;
            let weights = direct.matrix.iter().flat_map(|m| &m.weights);
            let error = direct
                .adaptive
                .iter()
                .flat_map(|a| &a.errors)
                .position(|e| !e.is_finite())
                .map(|i| format!("receiver error {i} is not finite"));
            Ok(non_finite("direct transfer", &direct.scalar)
                .or_else(|| non_finite("gather weight", weights))
                .or(error))
        }
        Reader::Baked => {
            let (baked, cpca) = glb::read_glb_compressed(path)?;
            let compressed = cpca.iter().flat_map(|c| c.means.iter().chain(&c.bases));
            Ok(non_finite_baked(&baked).or_else(|| non_finite("CPCA value", compressed)))
        }
    }
}

/// The cheapest bake of a scene (unshadowed, two bands, a few samples, on the CPU): enough to
/// carry what was read through `prepare` and into a written file.
pub(crate) fn quick_bake(scene: scene::Scene) -> Result<(BakedMesh, bake::BakeReport)> {
    let options = BakeOptions {
        bands: 2,
        samples: 16,
        mode: Mode::Unshadowed,
        ..BakeOptions::default()
    };
    bake::bake(scene, &options, &CpuBackend, &NoProgress)
}

fn non_finite<'a>(what: &str, values: impl IntoIterator<Item = &'a f32>) -> Option<String> {
    let (i, v) = values
        .into_iter()
        .enumerate()
        .find(|(_, v)| !v.is_finite())?;
    Some(format!("{what} {i} is {v}"))
}

fn vectors(values: &[Vec3]) -> impl Iterator<Item = &f32> {
    values.iter().flat_map(|v| v.as_ref())
}

fn non_finite_baked(baked: &BakedMesh) -> Option<String> {
    let scene = &baked.scene;
    non_finite("position", vectors(&scene.positions))
        .or_else(|| non_finite("normal", vectors(scene.normals.as_deref().unwrap_or(&[]))))
        .or_else(|| non_finite("albedo", vectors(&scene.albedo)))
        .or_else(|| non_finite("transfer", baked.transfer.coeffs()))
}

/// The first non-finite float in any float accessor of a `.glb` the tool wrote.
fn non_finite_glb(bytes: &[u8]) -> Option<String> {
    let document = match gltf::Gltf::from_slice(bytes) {
        Ok(document) => document,
        Err(e) => return Some(format!("the written .glb does not read back: {e}")),
    };
    let buffers = vec![document.blob.clone().unwrap_or_default()];
    let root = document.document.into_json();
    (0..root.accessors.len()).find_map(|index| {
        let data = match scene::gltf::accessor::dense(&root, &buffers, index) {
            Ok(data) => data,
            Err(e) => return Some(format!("written accessor {index} does not read back: {e}")),
        };
        let float = data.component == gltf_json::accessor::ComponentType::F32;
        let floats = if float { data.floats() } else { Vec::new() };
        non_finite(&format!("written accessor {index}, value"), &floats)
    })
}

/// `seed` changed by `mutator` as a reader's format invites: a `.glb`'s JSON or BIN chunk
/// alone (the container rebuilt around it), a part's header or data (its checksum made to
/// match again, or not), a PNG with its chunks' CRCs made to match; or the bytes as a whole.
/// Returns the bytes and the mutations' names.
pub fn mutated(reader: Reader, seed: &[u8], mutator: &mut Mutator) -> (Vec<u8>, String) {
    let whole = mutator.below(3) == 0;
    match reader {
        Reader::Glb | Reader::Baked if !whole => match glb_chunks(seed) {
            Some((json, bin)) => {
                let in_json = mutator.below(2) == 0;
                let (changed, how) = mutator.mutate(if in_json { json } else { bin });
                let (json, bin) = if in_json {
                    (changed, bin.to_vec())
                } else {
                    (json.to_vec(), changed)
                };
                let chunk = if in_json { "json" } else { "bin" };
                let rebuilt = glb::glb_container(json, bin).unwrap_or_default();
                (rebuilt, format!("{chunk}:{how}"))
            }
            None => mutator.mutate(seed),
        },
        Reader::Part if !whole => {
            let (changed, how) = mutator.mutate(seed);
            match shard::resealed(&changed) {
                Some(resealed) => (resealed, format!("{how}+reseal")),
                None => (changed, how),
            }
        }
        Reader::Png => {
            let (changed, how) = mutator.mutate(seed);
            (png_with_crcs(&changed), format!("{how}+crc"))
        }
        _ => mutator.mutate(seed),
    }
}

/// The bytes a fuzz target reads: with a part's checksum and a PNG's CRCs made to match, so
/// that the fuzzer gets past them to the parsing behind.
pub fn resealed(reader: Reader, bytes: &[u8]) -> Vec<u8> {
    match reader {
        Reader::Part => shard::resealed(bytes).unwrap_or_else(|| bytes.to_vec()),
        Reader::Png => png_with_crcs(bytes),
        _ => bytes.to_vec(),
    }
}

/// The JSON and BIN chunk data of a well-formed `.glb`.
fn glb_chunks(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    let word = |at: usize| -> Option<usize> {
        let b = bytes.get(at..at + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    let json_len = word(12)?;
    let json = bytes.get(20..20 + json_len)?;
    let bin_len = word(20 + json_len)?;
    let bin = bytes.get(28 + json_len..28 + json_len + bin_len)?;
    Some((json, bin))
}

/// A PNG with each whole chunk's CRC recomputed (the rest left as it is).
fn png_with_crcs(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let mut at = 8;
    while let Some(b) = out.get(at..at + 4) {
        let length = u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize;
        let Some(end) = (at + 8).checked_add(length).filter(|&e| e + 4 <= out.len()) else {
            break;
        };
        let crc = crc32(&out[at + 4..end]);
        out[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
    out
}

/// CRC-32 (ISO 3309, as PNG uses), bit by bit: the files are small.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// A user's error line: one line of printable characters, short enough to read (a path and
/// [`crate::error::printable`]'s length), no Rust debug dump (`Name { field: … }`, `Some(…)`)
/// outside the quotes that show a file's own bytes.
pub fn plain_words(message: &str) -> std::result::Result<(), String> {
    if message.contains('\n') {
        return Err(format!("error of more than one line: {message:?}"));
    }
    if message.chars().any(char::is_control) {
        return Err(format!("error with control characters: {message:?}"));
    }
    if message.chars().count() > 400 {
        return Err(format!(
            "error of {} characters: {message:?}",
            message.chars().count()
        ));
    }
    let unquoted = without_quotes(message);
    let message = unquoted.as_str();
    let dump = message.split(" { ").skip(1).any(|after| {
        let field: String = after.chars().take_while(|c| *c != ':').collect();
        !field.is_empty() && field.chars().all(|c| c.is_ascii_lowercase() || c == '_')
    });
    if dump || message.contains("Some(") || message.contains("Ok(") {
        return Err(format!("error with a debug dump: {message:?}"));
    }
    Ok(())
}

/// `message` without the file's own text it quotes, which the readers write as Rust string
/// literals (`{:?}`: double quotes, a quote or backslash inside escaped).
fn without_quotes(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut chars = message.chars();
    while let Some(c) = chars.next() {
        if c != '"' {
            out.push(c);
            continue;
        }
        while let Some(inside) = chars.next() {
            match inside {
                '\\' => {
                    chars.next();
                }
                '"' => break,
                _ => {}
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_debug_dump_is_not_plain_words() {
        assert!(plain_words("bad chunk ChunkType { type: IHDR, critical: true }").is_err());
        assert!(plain_words("first line\nsecond").is_err());
        assert!(plain_words("expected Some(3)").is_err());
        assert!(plain_words("mesh.obj: line 3: a face needs three vertices { 1 2 }").is_ok());
        assert!(plain_words("light.json: bands must be between 1 and 9, not 0").is_ok());
        let quoted = format!(
            "m.ply: unsupported PLY version {:?} (only 1.0)",
            "0\"Some({ r:"
        );
        assert!(plain_words(&quoted).is_ok(), "{quoted}");
        assert!(plain_words("it's a Some(3) that isn't quoted").is_err());
        assert!(plain_words("a NUL \0 in it").is_err());
    }

    #[test]
    fn crc32_of_iend_is_the_one_every_png_ends_with() {
        assert_eq!(crc32(b"IEND"), 0xAE42_6082);
    }

    #[test]
    fn every_reader_has_a_name_that_names_it_back() {
        for reader in Reader::ALL {
            assert_eq!(Reader::from_name(reader.name()), Some(reader));
        }
    }
}
