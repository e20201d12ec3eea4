//! Part files of a sharded bake, and their merge into the direct pass of the whole bake.
//!
//! A shard (`prt-gpu bake … --shard I/N`) bakes the direct pass of a contiguous run of the
//! receivers ([`crate::bake::Shard`]) and writes it as a part; `prt-gpu merge` checks that the
//! parts belong together and that each shard is there exactly once, and joins them into the
//! direct pass an unsharded bake would have computed, bit for bit: whole, or a run of
//! receivers at a time for a streamed merge ([`PartSet`], a part read at a time). Bounces, fits
//! and lightmaps need every receiver and run in the merge.
//!
//! Layout (little-endian): the 8 bytes `prtpart1`; a u32 `L`; `L` bytes of JSON
//! ([`PartHeader`], padded with spaces to a multiple of 4); then `f32 scalar[receivers ×
//! coeffs]` (albedo-free direct transfer, `[receiver][k]`), and for interreflection the part's
//! gather rows: `u32 row_offsets[receivers + 1]` (from 0), `u32 columns[entries]`,
//! `f32 weights[entries]`; for an error-targeted bake (`"adaptive": true`) each receiver's
//! samples and estimated error, `u32 samples[receivers]`, `f64 errors[receivers]`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bake::adaptive::ReceiverErrors;
use crate::bake::bounce::GatherMatrix;
use crate::bake::{DirectPass, ShardPass};
use crate::error::{Error, Result};
use crate::fs::write_atomically;
use crate::scene::Scene;
use crate::spec::BakeSpec;

const MAGIC: &[u8; 8] = b"prtpart1";

/// The extension a part file's name ends in (without the dot): `bake --shard` writes no other.
pub const PART_EXTENSION: &str = "part";

/// Reads a part file with Python and numpy alone: `python3 reader.py file.part`. Prints the
/// header, and the shapes and sums of the direct transfer `(receivers, coeffs)` and (for
/// interreflection) the gather rows, as JSON.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"prtpart1"
n = struct.unpack_from("<I", data, 8)[0]
header, body = json.loads(data[12:12 + n]), data[12 + n:]
R, K = header["receivers"], header["coeffs"]
scalar = np.frombuffer(body, "<f4", R * K).reshape(R, K)
out = {"header": header, "scalar_shape": scalar.shape, "scalar_sum": float(scalar.astype(np.float64).sum())}
E = header.get("gather_entries")
if E is not None:
    at = 4 * R * K
    offsets = np.frombuffer(body, "<u4", R + 1, at)
    columns = np.frombuffer(body, "<u4", E, at + 4 * (R + 1))
    weights = np.frombuffer(body, "<f4", E, at + 4 * (R + 1 + E))
    assert offsets[0] == 0 and offsets[-1] == E and len(body) == at + 4 * (R + 1 + 2 * E)
    out["weights_sum"] = float(weights.astype(np.float64).sum())
    out["max_column"] = int(columns.max())
if header.get("adaptive"):  # --target-error: samples and estimated error per receiver
    samples = np.frombuffer(body, "<u4", R, 4 * R * K)
    errors = np.frombuffer(body, "<f8", R, 4 * R * (K + 1))
    assert len(body) == 4 * R * (K + 1) + 8 * R
    out["samples_sum"], out["error_max"] = int(samples.sum()), float(errors.max())
print(json.dumps(out))
"#;

/// What a part says about itself and the bake it belongs to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartHeader {
    /// Of the mesh as loaded and the options that shape the output: parts merge only with
    /// parts of the same fingerprint.
    pub fingerprint: String,
    pub shard_index: u32,
    pub shard_count: u32,
    /// The receivers of the whole bake, and this part's run of them.
    pub receivers_total: u64,
    pub first_receiver: u64,
    pub receivers: u64,
    pub coeffs: u32,
    /// Gather entries (interreflection), absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gather_entries: Option<u64>,
    /// Whether each receiver's samples and error follow (`--target-error`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub adaptive: bool,
    pub rays_cast: u64,
    /// The backend the shard ran on (`cpu`, or `gpu: adapter`).
    pub backend: String,
    /// What the bake is: the merge bakes the rest of it as this says.
    pub spec: BakeSpec,
    /// The mesh baked (none for the built-in scene), as given: relative paths are from
    /// `directory`, where the shard ran.
    pub mesh: Option<PathBuf>,
    /// The bake command (arguments after the program's name) and the directory it ran in,
    /// shown when parts of one bake were baked by different commands.
    pub command: Vec<String>,
    pub directory: PathBuf,
    pub tool_version: String,
    /// FNV-1a (64 bits, hex) of the data after the header, set by [`write_part`]: a part whose
    /// bytes changed on the way (a bad disk, a truncated copy that kept its length) is refused
    /// rather than merged.
    pub payload_fnv1a: String,
}

/// A part file: its header and its direct pass.
pub struct Part {
    pub header: PartHeader,
    pub direct: DirectPass,
}

impl Part {
    /// The part of `pass`, shard `index` of `count` of the bake of `mesh` that `spec` says,
    /// baked by `command` in `directory`.
    pub fn new(
        pass: ShardPass,
        (index, count): (u32, u32),
        (spec, mesh): (BakeSpec, Option<PathBuf>),
        fingerprint: String,
        (command, directory): (Vec<String>, PathBuf),
    ) -> Part {
        let receivers = pass.receivers.len();
        let coeffs = pass.direct.scalar.len().checked_div(receivers).unwrap_or(0) as u32;
        let header = PartHeader {
            fingerprint,
            shard_index: index,
            shard_count: count,
            receivers_total: pass.receivers_total as u64,
            first_receiver: pass.receivers.start as u64,
            receivers: receivers as u64,
            coeffs,
            gather_entries: pass.direct.matrix.as_ref().map(|m| m.columns.len() as u64),
            adaptive: pass.direct.adaptive.is_some(),
            rays_cast: pass.direct.rays_cast,
            backend: pass.ran_on,
            spec,
            mesh,
            command,
            directory,
            tool_version: env!("CARGO_PKG_VERSION").to_string(),
            payload_fnv1a: String::new(),
        };
        Part {
            header,
            direct: pass.direct,
        }
    }
}

/// Writes `part` to `path`, whole or not at all (a shard killed mid-write leaves no part).
pub fn write_part(path: &Path, part: &Part) -> Result<()> {
    let payload = part_payload(&part.direct);
    let header = PartHeader {
        payload_fnv1a: payload_hash(&payload),
        ..part.header.clone()
    };
    let mut json = serde_json::to_vec(&header).map_err(|e| Error::io(path, e.into()))?;
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bytes = Vec::with_capacity(12 + json.len() + payload.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&(json.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&json);
    bytes.extend_from_slice(&payload);
    write_atomically(path, &bytes)
}

/// The data of a part after its header: the direct transfer, the gather rows, the adaptive
/// receivers' samples and errors, as the header's sizes say.
fn part_payload(direct: &DirectPass) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(4 * direct.scalar.len());
    bytes.extend_from_slice(bytemuck::cast_slice(&direct.scalar));
    if let Some(matrix) = &direct.matrix {
        bytes.extend_from_slice(bytemuck::cast_slice(&matrix.row_offsets));
        bytes.extend_from_slice(bytemuck::cast_slice(&matrix.columns));
        bytes.extend_from_slice(bytemuck::cast_slice(&matrix.weights));
    }
    if let Some(receivers) = &direct.adaptive {
        receivers
            .samples
            .iter()
            .for_each(|s| bytes.extend_from_slice(&s.to_le_bytes()));
        receivers
            .errors
            .iter()
            .for_each(|e| bytes.extend_from_slice(&e.to_le_bytes()));
    }
    bytes
}

/// A part's bytes with the checksum in its header made to match its data again, for the
/// hostile-file tests (a changed part is otherwise refused on its checksum before anything
/// else is read); `None` where the header does not parse.
pub fn resealed(bytes: &[u8]) -> Option<Vec<u8>> {
    let json_len = u32::from_le_bytes(bytes.get(8..12)?.try_into().ok()?) as usize;
    let json = bytes.get(12..12usize.checked_add(json_len)?)?;
    let header: PartHeader = serde_json::from_slice(json).ok()?;
    let body = &bytes[12 + json_len..];
    let header = PartHeader {
        payload_fnv1a: payload_hash(body),
        ..header
    };
    let mut json = serde_json::to_vec(&header).ok()?;
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut out = bytes[..8].to_vec();
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(body);
    Some(out)
}

fn payload_hash(payload: &[u8]) -> String {
    let mut hash = Fnv1a::default();
    hash.write(payload);
    format!("{:016x}", hash.0)
}

/// The counts a part's header declares, in words, and the bytes of data they add up to.
struct PartSizes {
    receivers: usize,
    values: usize,
    offsets: usize,
    entries: usize,
    bytes: u64,
}

/// [`PartSizes`] of a header; `None` where they overflow.
fn part_sizes(header: &PartHeader) -> Option<PartSizes> {
    let receivers = header.receivers;
    let values = receivers.checked_mul(u64::from(header.coeffs))?;
    let (offsets, entries) = match header.gather_entries {
        Some(entries) => (receivers.checked_add(1)?, entries),
        None => (0, 0),
    };
    let words = values
        .checked_add(offsets)?
        .checked_add(entries.checked_mul(2)?)?;
    let adaptive = if header.adaptive {
        receivers.checked_mul(12)?
    } else {
        0
    };
    let bytes = words.checked_mul(4)?.checked_add(adaptive)?;
    let size = |n: u64| usize::try_from(n).ok();
    Some(PartSizes {
        receivers: size(receivers)?,
        values: size(values)?,
        offsets: size(offsets)?,
        entries: size(entries)?,
        bytes,
    })
}

/// A part's header from the first bytes of its file (`start`: the signature, the header's
/// length and at least that much JSON), checked against the file's `file_len` bytes: its
/// sizes, and where its data begins.
fn header_of(path: &Path, start: &[u8], file_len: u64) -> Result<(PartHeader, PartSizes, usize)> {
    let broken = |why: &str| Error::io(path, std::io::Error::other(format!("not a part: {why}")));
    if start.len() < 12 || &start[..8] != MAGIC {
        return Err(broken(
            "no prtpart1 signature (not written by prt-gpu bake --shard)",
        ));
    }
    let json_len = u32::from_le_bytes(start[8..12].try_into().expect("4 bytes")) as usize;
    let json = start
        .get(12..12 + json_len)
        .ok_or_else(|| broken("truncated header"))?;
    let header: PartHeader = serde_json::from_slice(json).map_err(|e| {
        // serde names an unknown field as the file spells it: escape what it echoes.
        broken(&crate::error::printable(&format!("header: {e}")))
    })?;
    let body_len = file_len - (12 + json_len) as u64;
    // Sizes from the header, checked against the data before anything is read or reserved.
    match part_sizes(&header).filter(|s| s.bytes == body_len) {
        Some(sizes) => Ok((header, sizes, 12 + json_len)),
        None => Err(broken(&format!(
            "{body_len} bytes of data where its header says {}",
            part_sizes(&header)
                .map_or("more than can be addressed".into(), |s| s.bytes.to_string())
        ))),
    }
}

/// A part file's header, read without its data: its signature, its JSON and the data's size
/// checked, not its checksum ([`read_part`] checks that as it reads the data).
pub fn read_part_header(path: &Path) -> Result<PartHeader> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut start = vec![0u8; 12.min(file_len as usize)];
    file.read_exact(&mut start)
        .map_err(|e| Error::io(path, e))?;
    if let Some(len) = start.get(8..12) {
        let json_len = u32::from_le_bytes(len.try_into().expect("4 bytes")) as u64;
        // No more than the file holds, however long the header says it is.
        let more = json_len.min(file_len - 12) as usize;
        start.resize(12 + more, 0);
        file.read_exact(&mut start[12..])
            .map_err(|e| Error::io(path, e))?;
    }
    header_of(path, &start, file_len).map(|(header, _, _)| header)
}

/// Reads a part file written by [`write_part`], checking that its sizes add up.
pub fn read_part(path: &Path) -> Result<Part> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let (header, sizes, header_len) = header_of(path, &bytes, bytes.len() as u64)?;
    let PartSizes {
        receivers,
        values,
        offsets,
        entries,
        ..
    } = sizes;
    let broken = |why: &str| Error::io(path, std::io::Error::other(format!("not a part: {why}")));
    let body = &bytes[header_len..];
    let words_before_adaptive = values + offsets + 2 * entries;
    if payload_hash(body) != header.payload_fnv1a {
        return Err(broken(
            "its data does not match its checksum (damaged or changed since it was written)",
        ));
    }
    let words = |from: usize, count: usize| -> Vec<u32> {
        body[4 * from..4 * (from + count)]
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes(w.try_into().expect("4 bytes")))
            .collect()
    };
    let floats = |from: usize, count: usize| words(from, count).into_iter().map(f32::from_bits);
    let scalar = floats(0, values).collect();
    let matrix = header.gather_entries.map(|_| GatherMatrix {
        row_offsets: words(values, offsets),
        columns: words(values + offsets, entries),
        weights: floats(values + offsets + entries, entries).collect(),
    });
    if let Some(m) = &matrix {
        check_gather_rows(m, entries, header.receivers_total).map_err(|why| broken(&why))?;
    }
    let adaptive = header.adaptive.then(|| {
        let errors_at = 4 * (words_before_adaptive + receivers);
        ReceiverErrors {
            samples: words(words_before_adaptive, receivers),
            errors: body[errors_at..errors_at + 8 * receivers]
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect(),
        }
    });
    // A checksum says the bytes are as written, not that a writer wrote numbers: the merge
    // would carry a NaN into every receiver that gathers from this one.
    let weights = matrix.iter().flat_map(|m| &m.weights);
    let error = adaptive
        .iter()
        .flat_map(|a| &a.errors)
        .position(|e| !e.is_finite())
        .map(|i| format!("receiver error {i}"));
    if let Some(what) = first_non_finite(&scalar, "direct transfer value")
        .or_else(|| first_non_finite(weights, "gather weight"))
        .or(error)
    {
        return Err(broken(&format!("{what} is not a finite number")));
    }
    let direct = DirectPass {
        scalar,
        matrix,
        rays_cast: header.rays_cast,
        adaptive,
    };
    Ok(Part { header, direct })
}

/// A part's gather rows in order from 0 to its `entries`, every column one of the bake's
/// `receivers_total` receivers (columns index every receiver, not only the part's).
fn check_gather_rows(
    m: &GatherMatrix,
    entries: usize,
    receivers_total: u64,
) -> std::result::Result<(), String> {
    let ascending = m.row_offsets.windows(2).all(|w| w[0] <= w[1]);
    if m.row_offsets.first() != Some(&0)
        || !ascending
        || m.row_offsets.last() != Some(&(entries as u32))
    {
        return Err("gather rows out of order".into());
    }
    match m.columns.iter().find(|&&c| u64::from(c) >= receivers_total) {
        Some(column) => Err(format!(
            "gather column {column} is past the bake's {receivers_total} receivers"
        )),
        None => Ok(()),
    }
}

/// What to tell the user when parts of one bake (their fingerprints agree) were baked by
/// commands that differ in more than the shard and the part's own output, or in different
/// directories: the merge finishes the bake as the first part's command says, and the others'
/// differences (a `--memory-limit`, a mesh path spelled otherwise) are not applied.
fn command_differences(parts: &[(PathBuf, PartHeader)]) -> Option<String> {
    let (first_path, first) = parts.first()?;
    let first_command = bake_command(&first.command);
    parts[1..].iter().find_map(|(path, header)| {
        let command = bake_command(&header.command);
        let differs = command != first_command || header.directory != first.directory;
        differs.then(|| {
            format!(
                "{} was baked by `{}` in {} and {} by `{}` in {}; the merge finishes the bake as \
                 the first says",
                first_path.display(),
                first_command.join(" "),
                first.directory.display(),
                path.display(),
                command.join(" "),
                header.directory.display(),
            )
        })
    })
}

/// A part's command without what differs between the parts of one bake by design: the
/// shard (`--shard I/N`) and the part's file (`-o`, `--output`).
fn bake_command(command: &[String]) -> Vec<&str> {
    let mut kept = Vec::new();
    let mut words = command.iter().map(String::as_str);
    while let Some(word) = words.next() {
        match word {
            "--shard" | "-o" | "--output" => {
                words.next();
            }
            _ if word.starts_with("--shard=") || word.starts_with("--output=") => {}
            _ => kept.push(word),
        }
    }
    kept
}

/// "`what` `i`" for the first value that is NaN or infinite.
fn first_non_finite<'a>(values: impl IntoIterator<Item = &'a f32>, what: &str) -> Option<String> {
    let i = values.into_iter().position(|v| !v.is_finite())?;
    Some(format!("{what} {i}"))
}

/// Checks that `parts` are one bake's, each shard once, their runs of receivers tiling the
/// whole; returns the first's header and the parts sorted by shard.
fn check_set(
    mut parts: Vec<(PathBuf, PartHeader)>,
) -> Result<(PartHeader, Vec<(PathBuf, PartHeader)>)> {
    let refuse = |message: String| Err(Error::Merge(message));
    let Some((first_path, first)) = parts.first() else {
        return refuse("merge needs at least one part".into());
    };
    let (first_path, first) = (first_path.clone(), first.clone());
    for (path, h) in &parts {
        if h.fingerprint != first.fingerprint || h.shard_count != first.shard_count {
            return refuse(format!(
                "{} and {} are parts of different bakes (mesh, options, seed or shard count differ)",
                first_path.display(),
                path.display()
            ));
        }
        if h.backend != first.backend {
            return refuse(format!(
                "{} was baked on {} and {} on {}: parts of one bake must share a backend",
                first_path.display(),
                first.backend,
                path.display(),
                h.backend
            ));
        }
    }
    parts.sort_by_key(|(_, h)| h.shard_index);
    for pair in parts.windows(2) {
        if pair[0].1.shard_index == pair[1].1.shard_index {
            return refuse(format!(
                "shard {}/{} is given twice: {} and {}",
                pair[0].1.shard_index,
                first.shard_count,
                pair[0].0.display(),
                pair[1].0.display()
            ));
        }
    }
    let present: Vec<u32> = parts.iter().map(|(_, h)| h.shard_index).collect();
    if let Some(missing) = (0..first.shard_count).find(|i| !present.contains(i)) {
        return refuse(format!(
            "shard {missing}/{} is missing ({} of {} parts given)",
            first.shard_count,
            parts.len(),
            first.shard_count
        ));
    }
    let mut next_receiver = 0;
    for (path, h) in &parts {
        if h.first_receiver != next_receiver || h.receivers_total != first.receivers_total {
            return refuse(format!(
                "{} holds receivers {}.. where {next_receiver}.. were expected",
                path.display(),
                h.first_receiver
            ));
        }
        next_receiver += h.receivers;
    }
    if next_receiver != first.receivers_total {
        return refuse(format!(
            "the parts hold {next_receiver} of {} receivers",
            first.receivers_total
        ));
    }
    Ok((first, parts))
}

/// Direct passes of consecutive runs of receivers, joined in order.
struct Joined(DirectPass);

impl Joined {
    /// Nothing yet, of a bake whose parts look like `header`'s, with room for `receivers`
    /// receivers of `values` values and `entries` gather entries in all: joined without
    /// growing (a grown vector briefly takes its old and its new room).
    fn with_room(
        header: &PartHeader,
        (receivers, values, entries): (usize, usize, usize),
    ) -> Joined {
        let mut row_offsets = Vec::with_capacity(receivers + 1);
        row_offsets.push(0);
        Joined(DirectPass {
            scalar: Vec::with_capacity(values),
            matrix: header.gather_entries.map(|_| GatherMatrix {
                row_offsets,
                columns: Vec::with_capacity(entries),
                weights: Vec::with_capacity(entries),
            }),
            rays_cast: 0,
            adaptive: header.adaptive.then(|| ReceiverErrors {
                samples: Vec::with_capacity(receivers),
                errors: Vec::with_capacity(receivers),
            }),
        })
    }

    fn append(&mut self, next: DirectPass) {
        let all = &mut self.0;
        all.rays_cast += next.rays_cast;
        all.scalar.extend(next.scalar);
        if let (Some(all), Some(rows)) = (&mut all.matrix, next.matrix) {
            let base = all.columns.len() as u32;
            all.row_offsets
                .extend(rows.row_offsets[1..].iter().map(|o| o + base));
            all.columns.extend(rows.columns);
            all.weights.extend(rows.weights);
        }
        if let (Some(all), Some(receivers)) = (&mut all.adaptive, next.adaptive) {
            all.extend(receivers);
        }
    }
}

/// The parts of a sharded bake, checked, held as their headers: each part's data is read
/// whole (its checksum is of the whole) when its receivers are needed, so a merge holds one
/// part at a time beside what it joins or streams.
pub struct PartSet {
    first: PartHeader,
    /// The parts' files and headers, by shard.
    parts: Vec<(PathBuf, PartHeader)>,
    /// And in the order given.
    given: Vec<(PathBuf, PartHeader)>,
    /// The part read last and its direct pass, for the chunks that follow in it.
    last: std::sync::Mutex<Option<(usize, DirectPass)>>,
}

impl PartSet {
    /// Reads each part's header (its data's size checked, its checksum when the data is read)
    /// and checks the set: refuses, naming the files, parts of different bakes, a shard given
    /// twice, a shard missing, and parts whose runs of receivers do not tile the whole.
    pub fn read(paths: &[PathBuf]) -> Result<PartSet> {
        let headers = paths
            .iter()
            .map(|path| Ok((path.clone(), read_part_header(path)?)))
            .collect::<Result<Vec<_>>>()?;
        let (first, parts) = check_set(headers.clone())?;
        Ok(PartSet {
            first,
            parts,
            given: headers,
            last: std::sync::Mutex::new(None),
        })
    }

    /// The header of the first part given: the merge bakes the rest as its command says.
    pub fn header(&self) -> &PartHeader {
        &self.first
    }

    /// The bytes the largest part takes while it is read: its file and its direct pass.
    pub fn largest_part_bytes(&self) -> u64 {
        let bytes = |h: &PartHeader| part_sizes(h).map_or(0, |sizes| sizes.bytes);
        2 * self.parts.iter().map(|(_, h)| bytes(h)).max().unwrap_or(0)
    }

    /// What to tell the user when these parts were baked by commands that differ in more than
    /// the shard and the part's own output, or in different directories (the first given
    /// leads: the merge finishes the bake as its command says).
    pub fn command_differences(&self) -> Option<String> {
        command_differences(&self.given)
    }

    /// The direct pass of part `k`, sliced to its receivers `local` (counted in the part): all
    /// of it, given up by the cache or read and not kept; or a slice, the part kept for the
    /// chunks that follow in it.
    fn piece(&self, k: usize, local: std::ops::Range<usize>) -> Result<DirectPass> {
        let mut last = self.last.lock().expect("no reader panics holding the part");
        let cached = last.as_ref().is_some_and(|(read, _)| *read == k);
        let header = &self.parts[k].1;
        if !cached {
            // Let go of the part before, before the next is read.
            *last = None;
        }
        if local == (0..header.receivers as usize) {
            return match cached {
                true => Ok(last.take().expect("cached").1),
                false => self.read_checked(k),
            };
        }
        if !cached {
            *last = Some((k, self.read_checked(k)?));
        }
        let (_, direct) = last.as_ref().expect("read above");
        // The part's rays go with its first receiver's chunk.
        let rays = local.start == 0;
        Ok(direct.slice(local, header.coeffs as usize, rays))
    }

    /// Part `k`'s direct pass, read again and checked to be the part checked before.
    fn read_checked(&self, k: usize) -> Result<DirectPass> {
        let (path, header) = &self.parts[k];
        let part = read_part(path)?;
        if part.header != *header {
            return Err(Error::Merge(format!(
                "{} changed since the merge checked it",
                path.display()
            )));
        }
        Ok(part.direct)
    }
}

impl crate::bake::GivenDirect for PartSet {
    fn receivers(&self) -> usize {
        self.first.receivers_total as usize
    }

    fn direct(&self, range: std::ops::Range<usize>) -> Result<DirectPass> {
        // Each overlapping part's run of `range`, counted in the part.
        let runs: Vec<(usize, std::ops::Range<usize>)> = (self.parts.iter().enumerate())
            .filter_map(|(k, (_, h))| {
                let start = h.first_receiver as usize;
                let end = start + h.receivers as usize;
                let (from, to) = (range.start.max(start), range.end.min(end));
                (from < to).then(|| (k, from - start..to - start))
            })
            .collect();
        let values = runs
            .iter()
            .map(|(k, run)| run.len() * self.parts[*k].1.coeffs as usize)
            .sum();
        // A whole part's entries; a run's share of a part is not known before it is read.
        let entries = runs
            .iter()
            .filter(|(k, run)| run.len() as u64 == self.parts[*k].1.receivers)
            .map(|(k, _)| self.parts[*k].1.gather_entries.unwrap_or(0) as usize)
            .sum();
        let mut joined = Joined::with_room(&self.first, (range.len(), values, entries));
        for (k, run) in runs {
            joined.append(self.piece(k, run)?);
        }
        Ok(joined.0)
    }

    fn ran_on(&self) -> String {
        self.first.backend.clone()
    }
}

/// A fingerprint of `scene` as loaded and of `options` (any text that determines the output
/// besides the mesh): FNV-1a, 64 bits, as hex. Not a defence against tampering; a check that
/// parts come from the same inputs.
pub fn fingerprint(scene: &Scene, options: &str) -> String {
    let mut hash = Fnv1a::default();
    hash.write(bytemuck::cast_slice(&scene.positions));
    if let Some(normals) = &scene.normals {
        hash.write(bytemuck::cast_slice(normals));
    }
    hash.write(bytemuck::cast_slice(&scene.albedo));
    hash.write(bytemuck::cast_slice(&scene.triangles));
    hash.write(options.as_bytes());
    hash.write(env!("CARGO_PKG_VERSION").as_bytes());
    format!("{:016x}", hash.0)
}

struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
        // Separates fields, so that moving bytes from one field to the next changes the hash.
        self.0 = (self.0 ^ 0xff).wrapping_mul(0x0100_0000_01b3);
    }
}
