//! Capabilities compose (one spec, one run): every cell of input (OBJ, glTF) × receivers
//! (vertices, least squares, lightmap) × mode (shadowed, interreflected) × storage (rgb, lean) ×
//! precision (f32, f16) × layout (plain, clustered PCA) either bakes — its file passing the
//! Khronos validator and, for lightmaps, OpenEXR's reader, and relighting to the plain bake's
//! radiance within the bound its storage states — or is refused in one line with a reason of
//! format that the README lists. Where a cell bakes, three shards merged write its bytes, and
//! under a memory limit below its need it streams to the same bytes or is refused saying why.

mod common;

use std::path::Path;

use common::gltf_builder::ground_and_card_gltf;
use prt_gpu::bake::stream::MemoryNeed;
use prt_gpu::bake::{BakeOptions, Fit, Mode, Storage};
use prt_gpu::light::preview_light;
use prt_gpu::receivers::spread_point_count;
use prt_gpu::render::relight_baked;
use prt_gpu::testing::lightmap_reader_output;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
const SAMPLES: &str = "16";

#[derive(Clone, Copy, Debug, PartialEq)]
enum Input {
    Obj,
    Gltf,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Receivers {
    Vertices,
    LeastSquares,
    Lightmap,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Cell {
    input: Input,
    receivers: Receivers,
    interreflected: bool,
    lean: bool,
    half: bool,
    compressed: bool,
}

impl Cell {
    fn all() -> Vec<Cell> {
        let mut cells = Vec::new();
        for input in [Input::Obj, Input::Gltf] {
            for receivers in [
                Receivers::Vertices,
                Receivers::LeastSquares,
                Receivers::Lightmap,
            ] {
                for bits in 0..16u32 {
                    cells.push(Cell {
                        input,
                        receivers,
                        interreflected: bits & 1 != 0,
                        lean: bits & 2 != 0,
                        half: bits & 4 != 0,
                        compressed: bits & 8 != 0,
                    });
                }
            }
        }
        cells
    }

    /// The same cell stored plainly: RGB float32 per vertex.
    fn plain(&self) -> Cell {
        Cell {
            lean: false,
            half: false,
            compressed: false,
            ..*self
        }
    }

    fn name(&self) -> String {
        format!(
            "{:?}-{:?}-{}-{}-{}-{}",
            self.input,
            self.receivers,
            ["shadowed", "interreflected"][self.interreflected as usize],
            ["rgb", "lean"][self.lean as usize],
            ["f32", "f16"][self.half as usize],
            ["plain", "cpca"][self.compressed as usize],
        )
    }

    fn args(&self, input: &str) -> Vec<String> {
        let mut args: Vec<String> = ["bake", input, "--samples", SAMPLES, "--device", "cpu"]
            .map(String::from)
            .to_vec();
        let mut add = |more: &[&str]| args.extend(more.iter().map(|s| s.to_string()));
        match self.receivers {
            Receivers::Vertices => {}
            Receivers::LeastSquares => add(&["--fit", "least-squares"]),
            Receivers::Lightmap => add(&["--lightmap", self.lightmap_size()]),
        }
        if self.interreflected {
            add(&["--mode", "interreflected", "--bounces", "2"]);
        }
        if self.lean {
            add(&["--storage", "lean"]);
        }
        if self.half {
            add(&["--precision", "f16"]);
        }
        if self.compressed {
            add(&["--compress", "8x4"]);
        }
        args
    }

    fn lightmap_size(&self) -> &'static str {
        match self.input {
            Input::Obj => "384",
            Input::Gltf => "64",
        }
    }

    /// The reasons (a piece of each one-line refusal) this cell may be refused for: none where
    /// it must bake. Each is a reason of format, listed in the README.
    fn refusals(&self) -> Vec<&'static str> {
        let lightmap = self.receivers == Receivers::Lightmap;
        let mut reasons = Vec::new();
        if lightmap && self.lean {
            reasons.push("--storage lean stores vertex transfer; lightmaps are stored in RGB");
        }
        if self.compressed && lightmap {
            reasons.push("--compress stores per-vertex transfer as clusters");
        }
        if lightmap && self.half {
            reasons.push("--precision f16 stores per-vertex or compressed transfer");
        }
        reasons
    }

    /// The options whose memory need decides whether the cell streams.
    fn options(&self) -> BakeOptions {
        BakeOptions {
            samples: SAMPLES.parse().unwrap(),
            mode: match self.interreflected {
                true => Mode::Interreflected,
                false => Mode::Shadowed,
            },
            bounces: 2,
            fit: match self.receivers {
                Receivers::LeastSquares => Fit::LeastSquares,
                _ => Fit::Point,
            },
            lightmap: (self.receivers == Receivers::Lightmap)
                .then(|| self.lightmap_size().parse().unwrap()),
            storage: match self.lean {
                true => Storage::Lean,
                false => Storage::Rgb,
            },
            ..BakeOptions::default()
        }
    }

    /// Whether the cell streams under a memory limit below its whole need (compressed, its
    /// chunks wait in a scratch file that the clustering reads a chunk at a time).
    fn streams(&self) -> bool {
        self.receivers == Receivers::Vertices
    }

    /// Whether the cell, under a memory limit below its whole need, bakes its least-squares
    /// fit's points a run at a time.
    fn points_in_runs(&self) -> bool {
        self.receivers == Receivers::LeastSquares
    }

    /// Whether the cell, under a memory limit below its whole need, holds its lightmap's
    /// texels in a scratch file and cleans them up a group of coefficients at a time.
    fn texels_held(&self) -> bool {
        self.receivers == Receivers::Lightmap
    }
}

fn run(dir: &Path, args: &[String]) -> std::process::Output {
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    common::prt_gpu(&args, dir)
}

/// The relit error a compressed bake states: "relit error X% under the preview light".
fn stated_relit_error(stderr: &str) -> f64 {
    let at = stderr
        .find("relit error ")
        .expect("a compressed bake states its error")
        + 12;
    let percent: String = stderr[at..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    percent.parse::<f64>().unwrap() / 100.0
}

/// What one cell did, for the summary.
struct Outcome {
    cell: Cell,
    baked: bool,
}

fn check_cell(dir: &Path, input: &str, cell: Cell) -> Outcome {
    let name = cell.name();
    let output = format!("{name}.glb");
    let mut args = cell.args(input);
    args.extend(["-o".into(), output.clone()]);
    let out = run(dir, &args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let reasons = cell.refusals();
    if !reasons.is_empty() {
        assert!(!out.status.success(), "{name} baked, though {reasons:?}");
        assert_eq!(stderr.trim().lines().count(), 1, "{name}: {stderr}");
        assert!(
            reasons.iter().any(|r| stderr.contains(r)),
            "{name}: refused for another reason: {stderr}"
        );
        assert!(!stderr.contains(" yet"), "{name}: {stderr}");
        assert!(!dir.join(&output).exists(), "{name} left a file");
        return Outcome { cell, baked: false };
    }
    assert!(out.status.success(), "{name}: {stderr}");
    let glb = dir.join(&output);
    if let Some(report) = common::validate_gltf(&glb) {
        assert_eq!(report.num_errors, 0, "{name}: {}", report.listing());
    }
    let baked = prt_gpu::glb::read_glb(&glb).unwrap_or_else(|e| panic!("{name}: {e}"));
    if cell.receivers == Receivers::Lightmap {
        let texels = baked.lightmap.as_ref().expect("a lightmap");
        if let Some(read) = lightmap_reader_output(&glb) {
            let (w, h) = (texels.width, texels.height);
            assert_eq!(read["texels"][0], h, "{name}: {read}");
            assert_eq!(read["texels"][1], w, "{name}: {read}");
        }
    }
    // Against the plain bake of the same cell (baked before it: its bits are all zero).
    if cell != cell.plain() {
        let plain = prt_gpu::glb::read_glb(&dir.join(format!("{}.glb", cell.plain().name())))
            .expect("the plain bake");
        let light = preview_light(4).unwrap();
        let reference = relight_baked(&plain, &light).unwrap();
        let stored = relight_baked(&baked, &light).unwrap();
        let error = prt_gpu::compress::radiance_error(&reference, &stored);
        let bound = match (cell.compressed, cell.half) {
            // The rounding of a clustered PCA's stored form is within its stated error.
            (true, _) => 1.5 * stated_relit_error(&stderr) + 2e-3,
            (false, true) => 2e-3,
            // Lean storage is the same radiance, to float rounding.
            (false, false) => 1e-5,
        };
        assert!(
            error <= bound,
            "{name}: relit error {error:.2e} against the plain bake, over {bound:.2e}"
        );
    }
    Outcome { cell, baked: true }
}

/// Three shards merged write the whole bake's bytes (and its lightmap's); under a memory limit
/// below its need, a cell streams to the same bytes or is refused saying why.
fn check_sinks(dir: &Path, input: &str, scene: &prt_gpu::scene::Scene, cell: Cell) {
    let name = cell.name();
    let whole = std::fs::read(dir.join(format!("{name}.glb"))).unwrap();
    let mut parts = Vec::new();
    for i in 0..3 {
        let part = format!("{name}.{i}.part");
        let mut args = cell.args(input);
        args.extend([
            "--shard".into(),
            format!("{i}/3"),
            "-o".into(),
            part.clone(),
        ]);
        let out = run(dir, &args);
        assert!(
            out.status.success(),
            "{name} shard {i}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        parts.push(part);
    }
    // Beside a file of the same name in a directory of its own: a lightmapped file names its
    // lightmap after itself.
    std::fs::create_dir_all(dir.join("merged")).unwrap();
    std::fs::create_dir_all(dir.join("streamed")).unwrap();
    let merged = format!("merged/{name}.glb");
    let mut args: Vec<String> = vec!["merge".into()];
    args.extend(parts.iter().cloned());
    args.extend(["-o".into(), merged.clone()]);
    let out = run(dir, &args);
    assert!(
        out.status.success(),
        "{name} merge: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        std::fs::read(dir.join(&merged)).unwrap() == whole,
        "{name}: merged bytes differ"
    );
    if cell.receivers == Receivers::Lightmap {
        let exr = |glb: &str| {
            let glb = dir.join(glb);
            std::fs::read(glb.with_file_name(prt_gpu::glb::lightmap_file_name(&glb))).unwrap()
        };
        assert!(
            exr(&merged) == exr(&format!("{name}.glb")),
            "{name}: merged lightmap differs"
        );
    }

    // A glTF scene's buffers and images count too: the file written carries them.
    let document = match cell.input {
        Input::Gltf => prt_gpu::scene::gltf::load(Path::new(input))
            .unwrap()
            .0
            .byte_size(),
        Input::Obj => 0,
    };
    let options = cell.options();
    let mut need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), &options)
        .with_document(document);
    if options.fit == Fit::LeastSquares {
        let points = spread_point_count(scene, options.point_density);
        need = need.with_fit_points(points as u64, &options);
    }
    if let Some(size) = options.lightmap {
        need = need.with_lightmap(size, &options);
    }
    if cell.compressed {
        // --compress 8x4 of RGB rows of 4 bands.
        let group = prt_gpu::compress::covariance_group(48) as u64;
        let reconstructed = prt_gpu::compress::RECONSTRUCTED_ROWS as u64;
        need = need.with_compression((8, 4), 48, (group, reconstructed));
    }
    // Chunks of 300 receivers where the cell streams (the glTF scene, of fewer vertices,
    // streams in one chunk of all of them; tests/memory.rs streams a larger one in many), runs
    // of 300 points where the fit's points bake in runs; half its need where it cannot.
    let chunk = 300.min(scene.vertex_count());
    let limit = match (cell.streams(), cell.points_in_runs(), cell.texels_held()) {
        (true, _, _) => need.streamed(chunk),
        (_, true, _) => need.points_chunked(300),
        // Room for one group of the seam solve's four coefficients.
        (_, _, true) => need.lightmap_held(4),
        _ => need.whole() / 2,
    };
    if cell.streams() && cell.input == Input::Gltf && limit >= need.whole() {
        // An interreflected bake streamed holds every vertex's last bounce beside its chunk,
        // and a compressed one reads its chunk back to cluster it, so the glTF scene's hundred
        // vertices need more streamed than whole: nothing to stream. tests/memory.rs streams
        // 2CylinderEngine interreflected and compressed instead.
        assert!(cell.interreflected || cell.compressed, "{name}");
        return;
    }
    assert!(
        limit < need.whole(),
        "{name}: the limit must be below the whole need"
    );
    let streamed = format!("streamed/{name}.glb");
    let mut args = cell.args(input);
    args.extend([
        "--memory-limit".into(),
        limit.to_string(),
        "-o".into(),
        streamed.clone(),
    ]);
    let out = run(dir, &args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if cell.streams() || cell.points_in_runs() || cell.texels_held() {
        assert!(out.status.success(), "{name} streamed: {stderr}");
        let said = match (cell.streams(), cell.points_in_runs()) {
            // Compressed, the chunks may be larger: the clustering after the last one needs
            // the room of more than one.
            (true, _) => format!("chunks of {} receivers", need.chunk_within(limit).unwrap()),
            (_, true) => "points in runs of about".into(),
            _ => "cleaned up 4 coefficients at a time".into(),
        };
        assert!(stderr.contains(&said), "{name}: {stderr}");
        assert!(
            std::fs::read(dir.join(&streamed)).unwrap() == whole,
            "{name}: streamed bytes differ"
        );
        if cell.texels_held() {
            let exr = |glb: &Path| {
                std::fs::read(glb.with_file_name(prt_gpu::glb::lightmap_file_name(glb))).unwrap()
            };
            assert!(
                exr(&dir.join(&streamed)) == exr(&dir.join(format!("{name}.glb"))),
                "{name}: the held lightmap differs from the whole bake's"
            );
        }
    } else {
        assert!(
            !out.status.success(),
            "{name} did not stream yet succeeded: {stderr}"
        );
        assert_eq!(stderr.trim().lines().count(), 1, "{name}: {stderr}");
        assert!(stderr.contains("stream in chunks"), "{name}: {stderr}");
    }
}

#[test]
fn every_combination_bakes_within_its_bound_or_is_refused_with_its_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gltf = ground_and_card_gltf(d, Some(1), true, false);
    let gltf = gltf.to_str().unwrap().to_string();
    let inputs = [
        (
            Input::Obj,
            BUNNY.to_string(),
            prt_gpu::scene::load(Path::new(BUNNY)).unwrap(),
        ),
        (
            Input::Gltf,
            gltf.clone(),
            prt_gpu::scene::load(Path::new(&gltf)).unwrap(),
        ),
    ];
    // Plain cells first (bits zero): the others compare with them. Two workers, one per core.
    let cells = Cell::all();
    let (plain, stored): (Vec<Cell>, Vec<Cell>) = cells.iter().partition(|c| **c == c.plain());
    let input_of = |cell: &Cell| inputs.iter().find(|(i, _, _)| *i == cell.input).unwrap();
    let mut outcomes = Vec::new();
    for batch in [plain, stored] {
        let results: Vec<Outcome> = std::thread::scope(|scope| {
            let halves: Vec<_> = batch
                .chunks(batch.len().div_ceil(2))
                .map(|chunk| {
                    scope.spawn(|| {
                        chunk
                            .iter()
                            .map(|cell| check_cell(d, &input_of(cell).1, *cell))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            halves.into_iter().flat_map(|h| h.join().unwrap()).collect()
        });
        outcomes.extend(results);
    }
    let baked: Vec<Cell> = outcomes
        .iter()
        .filter(|o| o.baked)
        .map(|o| o.cell)
        .collect();
    eprintln!(
        "{} cells: {} baked, {} refused with their reasons",
        outcomes.len(),
        baked.len(),
        outcomes.len() - baked.len()
    );
    // Sinks for the cells stored plainly and for those stored lean, half and compressed.
    let sinks: Vec<Cell> = baked
        .iter()
        .copied()
        .filter(|c| *c == c.plain() || (c.lean && c.half))
        .collect();
    std::thread::scope(|scope| {
        for chunk in sinks.chunks(sinks.len().div_ceil(2)) {
            scope.spawn(move || {
                for cell in chunk {
                    let (_, input, scene) = input_of(cell);
                    check_sinks(d, input, scene, *cell);
                }
            });
        }
    });
}
