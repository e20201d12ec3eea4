//! Hostile files, run deterministically: every reader of the tool fed its seed files, the
//! fuzzers' corpus and found crashes (`fuzz/corpus`, `fuzz/regressions`), and a fixed-seed run
//! of mutations of the seeds (`prt_gpu::testing::mutate`). Each case must be read or refused
//! in one line of plain words, never panic, give nothing non-finite, and allocate no more than
//! a bound of its size; this binary counts every allocation to check the last.
//!
//! The counting allocator refuses a single request over [`LARGEST_REQUEST`] outright, after
//! printing the case, so that a reader reserving what a header claims fails here with its name
//! rather than taking the machine's memory.

mod common;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use prt_gpu::images;
use prt_gpu::light::envmap;
use prt_gpu::testing::hostile::{self, Outcome, Reader};
use prt_gpu::testing::mutate::Mutator;
use prt_gpu::testing::seeds::seeds;

use common::counting::{self, Counting};

/// What the case being run is, for the line printed when it asks for too much.
static CASE: Mutex<String> = Mutex::new(String::new());
/// The cases share the counters: one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

const LARGEST_REQUEST: usize = 1 << 30;

/// What a case may allocate at its peak, beyond what was live when it began: a floor for the
/// bake's fixed costs (thread pool, SH tables), and this many bytes per byte of its input.
const FLOOR_BYTES: usize = 32 << 20;
const BYTES_PER_INPUT_BYTE: usize = 64;

/// The bound of a case of `input` bytes. A compressed image may decode to what
/// `images::decodable_bytes` allows, at one byte a pixel or more, and is then held as float
/// RGB twice over (24 bytes a pixel); an OpenEXR file to `envmap::exr_pixels_allowed`.
fn allowed(reader: Reader, input: usize) -> usize {
    match reader {
        Reader::Png | Reader::Jpeg | Reader::Hdr => {
            FLOOR_BYTES + 25 * images::decodable_bytes(input) as usize
        }
        // An OpenEXR file's pixels, as float RGB twice over.
        Reader::Exr => FLOOR_BYTES + 24 * envmap::exr_pixels_allowed(input),
        _ => FLOOR_BYTES + BYTES_PER_INPUT_BYTE * input,
    }
}

/// A request the allocator refuses, printed with the case that made it (small allocations
/// while printing are under the limit and do not come back here).
fn refused(size: usize) {
    let case = CASE.lock().map(|c| c.clone()).unwrap_or_default();
    eprintln!("hostile case {case}: asked for {size} bytes at once");
}

#[global_allocator]
static ALLOCATOR: Counting = Counting {
    largest: LARGEST_REQUEST,
    refused,
};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// What one case did, and what it cost.
struct Ran {
    outcome: std::result::Result<Outcome, String>,
    peak: usize,
}

static IN_CASE: AtomicBool = AtomicBool::new(false);

/// The default panic hook would print every panic a case makes, which the tally reports; it
/// still prints the test's own.
fn quiet_while_in_a_case() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !IN_CASE.load(Ordering::Relaxed) {
            default(info)
        }
    }));
}

/// Runs one case, catching a panic as a fault.
fn run(reader: Reader, bytes: &[u8], dir: &Path, name: &str) -> Ran {
    *CASE.lock().unwrap() = format!("{} {name}", reader.name());
    let base = counting::start();
    IN_CASE.store(true, Ordering::Relaxed);
    let outcome = std::panic::catch_unwind(|| hostile::try_reader(reader, bytes, dir));
    IN_CASE.store(false, Ordering::Relaxed);
    let outcome = outcome.unwrap_or_else(|panic| {
        let message = panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        Err(format!("panicked: {message}"))
    });
    let peak = counting::peak_since(base);
    Ran { outcome, peak }
}

/// The files under `fuzz/<folder>/<reader>/`, named.
fn stored_cases(folder: &str, reader: Reader) -> Vec<(String, Vec<u8>)> {
    let dir = root().join("fuzz").join(folder).join(reader.name());
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut cases: Vec<(String, Vec<u8>)> = entries
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            let name = format!("{folder}/{}", p.file_name().unwrap().to_string_lossy());
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    cases.sort();
    cases
}

/// Per reader: the cases run, how many were read, the largest peak over the allowed bound,
/// the faults (at most a few kept, all counted).
#[derive(Default)]
struct Tally {
    cases: usize,
    read: usize,
    worst_fraction_of_bound: f64,
    faults: Vec<String>,
    fault_count: usize,
    seconds: f64,
}

impl Tally {
    fn add(&mut self, reader: Reader, name: &str, bytes: &[u8], ran: Ran) {
        self.cases += 1;
        let bound = allowed(reader, bytes.len());
        self.worst_fraction_of_bound = self
            .worst_fraction_of_bound
            .max(ran.peak as f64 / bound as f64);
        let fault = match ran.outcome {
            Ok(Outcome::Read) => {
                self.read += 1;
                None
            }
            Ok(Outcome::Refused(_)) => None,
            Err(fault) => Some(fault),
        };
        let fault = fault.or_else(|| {
            (ran.peak > bound).then(|| {
                format!(
                    "peak allocation {} bytes for {} input bytes (bound {bound})",
                    ran.peak,
                    bytes.len()
                )
            })
        });
        if let Some(fault) = fault {
            self.fault_count += 1;
            if self.faults.len() < 5 {
                self.faults
                    .push(format!("{} {name}: {fault}", reader.name()));
            }
        }
    }
}

/// Mutations of each reader's seeds in the fixed-seed run.
const MUTATIONS_PER_READER: usize = 2000;

#[test]
fn every_reader_survives_its_seeds_corpus_regressions_and_mutations() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    quiet_while_in_a_case();
    let scratch = tempfile::tempdir().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    let mut lines = Vec::new();
    for (index, reader) in Reader::ALL.into_iter().enumerate() {
        let started = Instant::now();
        let mut tally = Tally::default();
        let seeds = seeds(reader, &root().join("tests/data"), scratch.path())
            .unwrap_or_else(|e| panic!("{}: seeds: {e}", reader.name()));
        for (name, bytes) in &seeds {
            let ran = run(reader, bytes, dir.path(), name);
            assert!(
                matches!(ran.outcome, Ok(Outcome::Read)),
                "{} seed {name} is not read: {:?}",
                reader.name(),
                ran.outcome
            );
            tally.add(reader, name, bytes, ran);
        }
        for folder in ["corpus", "regressions"] {
            for (name, bytes) in stored_cases(folder, reader) {
                let ran = run(
                    reader,
                    &hostile::resealed(reader, &bytes),
                    dir.path(),
                    &name,
                );
                tally.add(reader, &name, &bytes, ran);
            }
        }
        let mut mutator = Mutator::new(0x5EED_0000 + index as u64);
        for case in 0..MUTATIONS_PER_READER {
            let (seed_name, seed) = &seeds[case % seeds.len()];
            let (bytes, how) = hostile::mutated(reader, seed, &mut mutator);
            let name = format!("mutation {case} of {seed_name} ({how})");
            let ran = run(reader, &bytes, dir.path(), &name);
            tally.add(reader, &name, &bytes, ran);
        }
        tally.seconds = started.elapsed().as_secs_f64();
        lines.push(format!(
            "{:<10} {:>5} cases {:>5} read {:>7.2} s  peak {:>5.1}% of bound  {} faults",
            reader.name(),
            tally.cases,
            tally.read,
            tally.seconds,
            100.0 * tally.worst_fraction_of_bound,
            tally.fault_count
        ));
        failures.extend(tally.faults);
    }
    println!("{}", lines.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every reader has a fuzz target of its name, so that a reader added to the list is fuzzed.
#[test]
fn every_reader_has_a_fuzz_target() {
    let targets = std::fs::read_to_string(root().join("fuzz/Cargo.toml")).unwrap();
    for reader in Reader::ALL {
        let declared = format!("name = \"{}\"", reader.name());
        assert!(
            targets.contains(&declared),
            "fuzz/Cargo.toml: no {declared}"
        );
        let target = root().join(format!("fuzz/fuzz_targets/{}.rs", reader.name()));
        assert!(target.is_file(), "{} is missing", target.display());
    }
}

/// A minimal glTF triangle whose POSITION accessor declares `count` vertices, with or without
/// a buffer view (an accessor without one reads as zeros).
fn gltf_declaring(count: u64, backed: bool) -> Vec<u8> {
    use base64::Engine as _;
    let positions: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&positions)
    );
    // Without a view, a sparse substitution is what makes it valid glTF: one value, at index
    // 0 (the view's first four bytes, 0.0f32, read as a u32).
    let view = if backed {
        r#""bufferView": 0,"#
    } else {
        r#""sparse": {"count": 1, "indices": {"bufferView": 0, "componentType": 5125},
        "values": {"bufferView": 0}},"#
    };
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
        "nodes": [{{"mesh": 0}}], "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
        "buffers": [{{"byteLength": 36, "uri": "{uri}"}}],
        "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
        "accessors": [{{{view} "componentType": 5126, "count": {count}, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 0]}}]}}"#
    )
    .into_bytes()
}

/// Files whose headers declare 2^32 vertices (or pixels, or receivers) over a few bytes of
/// data: each is refused, and reading it costs no more than the bound of its own size.
#[test]
fn declaring_four_billion_vertices_costs_what_the_bytes_hold() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    quiet_while_in_a_case();
    let dir = tempfile::tempdir().unwrap();
    let huge = 1u64 << 32;
    let ply = |format: &str, body: &[u8]| {
        let mut bytes = format!(
            "ply\nformat {format} 1.0\nelement vertex {huge}\nproperty float x\n\
             property float y\nproperty float z\nelement face {huge}\n\
             property list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes();
        bytes.extend_from_slice(body);
        bytes
    };
    let binary_body: Vec<u8> = (0..9).flat_map(|i| (i as f32).to_le_bytes()).collect();
    let mut png = Vec::new();
    image::RgbImage::new(4, 4)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png[16..24].copy_from_slice(&[0, 1, 0, 0, 0, 1, 0, 0]); // 65536 x 65536
    let seed_part = root().join("fuzz/corpus/part/seed-gather.part");
    let mut declaring = prt_gpu::shard::read_part(&seed_part).unwrap();
    declaring.header.receivers = huge;
    let part_path = dir.path().join("declaring.part");
    prt_gpu::shard::write_part(&part_path, &declaring).unwrap();
    let part = std::fs::read(&part_path).unwrap();
    let mut exr = std::fs::read(root().join("fuzz/corpus/exr/seed-sky.exr")).unwrap();
    for window in [&b"dataWindow\0box2i\0"[..], b"displayWindow\0box2i\0"] {
        let at = exr.windows(window.len()).position(|w| w == window).unwrap() + window.len();
        // After the attribute's size: xmin, ymin, xmax, ymax; 16384 x 8192 is 2^27 pixels.
        exr[at + 12..at + 16].copy_from_slice(&16383i32.to_le_bytes());
        exr[at + 16..at + 20].copy_from_slice(&8191i32.to_le_bytes());
    }
    let cases: Vec<(Reader, &str, Vec<u8>)> = vec![
        (
            Reader::Ply,
            "ascii PLY",
            ply("ascii", b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
        ),
        (
            Reader::Ply,
            "binary PLY",
            ply("binary_little_endian", &binary_body),
        ),
        (
            Reader::Gltf,
            "glTF accessor with a view",
            gltf_declaring(huge - 1, true),
        ),
        (
            Reader::Gltf,
            "glTF accessor without one",
            gltf_declaring(huge - 1, false),
        ),
        (Reader::Png, "PNG", hostile::resealed(Reader::Png, &png)),
        (Reader::Exr, "OpenEXR", exr),
        (Reader::Part, "part", part),
    ];
    let mut lines = Vec::new();
    for (reader, what, bytes) in cases {
        let ran = run(reader, &bytes, dir.path(), what);
        let bound = allowed(reader, bytes.len());
        lines.push(format!(
            "{what:<28} {:>6} bytes  peak {:>10} bytes  bound {bound:>10}  {:?}",
            bytes.len(),
            ran.peak,
            ran.outcome
        ));
        assert!(
            matches!(ran.outcome, Ok(Outcome::Refused(_))),
            "{what}: {:?}",
            ran.outcome
        );
        assert!(ran.peak <= bound, "{what}: peak {} over {bound}", ran.peak);
    }
    println!("{}", lines.join("\n"));
}

/// No `.unwrap()` in the tool's code, where a value read from a file could reach it: every
/// one outside the tests (a file's `#[cfg(test)]` module, `tests.rs`, `src/testing/`) fails here, as
/// `clippy::unwrap_used` does under clippy (denied in `lib.rs` and `main.rs`).
#[test]
fn the_tools_code_unwraps_nothing() {
    fn visit(dir: &Path, found: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                if !path.ends_with("testing") {
                    visit(&path, found);
                }
                continue;
            }
            // `tests.rs` is a module declared under #[cfg(test)] by its parent.
            if path.extension().is_none_or(|e| e != "rs") || path.ends_with("tests.rs") {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let code = text.split("#[cfg(test)]").next().unwrap_or_default();
            for (number, line) in code.lines().enumerate() {
                let line = line.split("//").next().unwrap_or_default();
                if line.contains(".unwrap()") {
                    found.push(format!(
                        "{}:{}: {}",
                        path.display(),
                        number + 1,
                        line.trim()
                    ));
                }
            }
        }
    }
    let mut found = Vec::new();
    visit(&root().join("src"), &mut found);
    assert!(
        found.is_empty(),
        "unwrap in the tool's code:\n{}",
        found.join("\n")
    );
}
