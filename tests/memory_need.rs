//! The memory a bake says it needs before it starts (`pipeline::memory_need`: what
//! `--memory-limit` is held against, and what the warning over the machine's memory says)
//! bounds what the bake allocates, and not loosely. Each bake here is loaded, run and written
//! in this process under a counting allocator, one at a time (this file holds one test, so no
//! other test allocates beside it).

mod common;

use std::path::Path;

use common::counting::{self, Counting};
use prt_gpu::bake::{CpuBackend, DirectSource, Fit, Mode, NoProgress};
use prt_gpu::local::LocalOptions;
use prt_gpu::spec::{BakeSpec, Compression, Layout as StoredLayout};
use prt_gpu::{pipeline, scene};

#[global_allocator]
static ALLOCATOR: Counting = Counting {
    largest: usize::MAX,
    refused: |_| {},
};

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
const DRAGON: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/dragon_vrip_res3.ply.gz"
);

/// How a case bakes: whole, a least-squares fit's points in runs of this many, streamed in
/// chunks of this many vertices, or its lightmap held and cleaned up this many coefficients at
/// a time.
#[derive(Clone, Copy)]
enum Run {
    Whole,
    PointsInRuns(usize),
    Streamed(usize),
    /// The lightmap held (and, where given, the least-squares fit's points at the vertices
    /// baked in runs of this many).
    TexelsHeld(u64, Option<usize>),
    /// A local-lights spec: depth maps and an operator, held whole.
    Local,
    /// A merge of this many shards (their parts written before the measurement starts),
    /// streamed in chunks of this many vertices.
    MergeStreamed(u32, usize),
}

/// The parts of the bake of `mesh` as `spec` asks in `shards` shards, written to `dir`.
fn write_parts(spec: &BakeSpec, mesh: &str, shards: u32, dir: &Path) -> Vec<std::path::PathBuf> {
    let options = spec.options();
    (0..shards)
        .map(|index| {
            let scene = scene::load(Path::new(mesh)).unwrap();
            let fingerprint = prt_gpu::shard::fingerprint(&scene, &spec.fingerprint_text());
            let shard = prt_gpu::bake::Shard::new(index, shards).unwrap();
            let pass = prt_gpu::bake::bake_shard(scene, &options, &CpuBackend, shard, &NoProgress)
                .unwrap();
            let what = (spec.clone(), Some(Path::new(mesh).to_path_buf()));
            let part = prt_gpu::shard::Part::new(
                pass,
                (index, shards),
                what,
                fingerprint,
                (Vec::new(), dir.to_path_buf()),
            );
            let path = dir.join(format!("part{index}.part"));
            prt_gpu::shard::write_part(&path, &part).unwrap();
            path
        })
        .collect()
}

/// The bytes allocated at the peak of loading `mesh`, baking it as `spec` asks (as `run` says)
/// and writing it, beyond what was live before; and the estimate the bake plans by.
fn measured((spec, run): &(BakeSpec, Run), mesh: &str, dir: &Path) -> (u64, u64) {
    let parts = match *run {
        Run::MergeStreamed(shards, _) => write_parts(spec, mesh, shards, dir),
        _ => Vec::new(),
    };
    let before = counting::start();
    let scene = scene::load(Path::new(mesh)).unwrap();
    let planned = pipeline::plan(spec, scene, None).unwrap();
    let need = pipeline::memory_need(spec, (planned.scene(), None));
    let path = dir.join("baked.glb");
    let need = match *run {
        Run::Whole => {
            let baked = planned
                .run(&CpuBackend, DirectSource::Compute, &NoProgress)
                .unwrap();
            pipeline::write(spec, &baked, None, &path).unwrap();
            need.whole()
        }
        Run::PointsInRuns(chunk) => {
            let baked = planned
                .with_point_chunk(chunk)
                .run(&CpuBackend, DirectSource::Compute, &NoProgress)
                .unwrap();
            pipeline::write(spec, &baked, None, &path).unwrap();
            need.points_chunked(chunk)
        }
        Run::TexelsHeld(columns, fit_run) => {
            let lightmap = need.lightmap.expect("a lightmap's need");
            let groups = prt_gpu::bake::texels::TexelGroups {
                chunk: lightmap.chunk(columns),
                columns: columns as usize,
            };
            let (planned, need) = match fit_run {
                Some(run) => (planned.with_point_chunk(run), need.with_fit_run(run as u64)),
                None => (planned, need),
            };
            let baked = planned
                .with_texel_groups(groups)
                .run(&CpuBackend, DirectSource::Compute, &NoProgress)
                .unwrap();
            pipeline::write(spec, &baked, None, &path).unwrap();
            need.lightmap_held(columns)
        }
        Run::Local => {
            let options = spec.local.as_ref().expect("a local-lights spec");
            let need = pipeline::local_memory_need(options, planned.scene());
            let baked = planned
                .run(&CpuBackend, DirectSource::Compute, &NoProgress)
                .unwrap();
            pipeline::write(spec, &baked, None, &path).unwrap();
            need
        }
        Run::MergeStreamed(_, chunk) => {
            let parts = prt_gpu::shard::PartSet::read(&parts).unwrap();
            let need = need.with_merge_part(parts.largest_part_bytes());
            let sink = (path.as_path(), None);
            let source = DirectSource::Given(Box::new(parts));
            planned
                .run_streamed((&CpuBackend, source), chunk, sink, false, &NoProgress)
                .unwrap();
            need.streamed(chunk)
        }
        Run::Streamed(chunk) => {
            let sink = (path.as_path(), None);
            planned
                .run_streamed(
                    (&CpuBackend, DirectSource::Compute),
                    chunk,
                    sink,
                    false,
                    &NoProgress,
                )
                .unwrap();
            need.streamed(chunk)
        }
    };
    let peak = counting::peak_since(before);
    (peak as u64, need)
}

#[test]
fn a_bakes_estimated_need_bounds_what_it_allocates() {
    let dir = tempfile::tempdir().unwrap();
    let spec = |edit: &dyn Fn(&mut BakeSpec)| {
        let mut spec = BakeSpec::default();
        spec.transfer.samples = 16;
        edit(&mut spec);
        spec
    };
    let interreflected = |s: &mut BakeSpec| s.transfer.mode = Mode::Interreflected;
    let least_squares_interreflected = |s: &mut BakeSpec| {
        s.receivers.fit = Fit::LeastSquares;
        interreflected(s);
    };
    let whole = |spec: BakeSpec| (spec, Run::Whole);
    let compressed = |s: &mut BakeSpec| {
        s.storage.layout = StoredLayout::Cpca(Compression::Shape {
            clusters: 16,
            components: 4,
        })
    };
    let cases: Vec<(&str, (BakeSpec, Run))> = vec![
        ("vertices, shadowed", whole(spec(&|_| {}))),
        ("vertices, interreflected", whole(spec(&interreflected))),
        ("compressed", whole(spec(&compressed))),
        (
            "vertices, shadowed, streamed in chunks of 2,000",
            (spec(&|_| {}), Run::Streamed(2000)),
        ),
        (
            "compressed, streamed in chunks of 2,000",
            (spec(&compressed), Run::Streamed(2000)),
        ),
        (
            "interreflected, 3 parts merged in chunks of 2,000",
            (spec(&interreflected), Run::MergeStreamed(3, 2000)),
        ),
        (
            "least squares, shadowed",
            whole(spec(&|s| s.receivers.fit = Fit::LeastSquares)),
        ),
        (
            "least squares, interreflected",
            whole(spec(&least_squares_interreflected)),
        ),
        (
            "least squares, interreflected, 64 samples, points in runs",
            (
                spec(&|s| {
                    least_squares_interreflected(s);
                    s.transfer.samples = 64;
                }),
                Run::PointsInRuns(20_000),
            ),
        ),
        (
            "lightmap 512, shadowed",
            whole(spec(&|s| s.receivers.lightmap = Some(512))),
        ),
        (
            "lightmap 512, interreflected",
            whole(spec(&|s| {
                s.receivers.lightmap = Some(512);
                interreflected(s);
            })),
        ),
        (
            "lightmap 512, least squares",
            whole(spec(&|s| {
                s.receivers.lightmap = Some(512);
                s.receivers.fit = Fit::LeastSquares;
            })),
        ),
        (
            "lightmap 512, held, 4 coefficients at a time",
            (
                spec(&|s| s.receivers.lightmap = Some(512)),
                Run::TexelsHeld(4, None),
            ),
        ),
        (
            "lightmap 512, least squares, held, 4 at a time",
            (
                spec(&|s| {
                    s.receivers.lightmap = Some(512);
                    s.receivers.fit = Fit::LeastSquares;
                }),
                Run::TexelsHeld(4, None),
            ),
        ),
        (
            "held lightmap 512, least squares in runs, interreflected",
            (
                spec(&|s| {
                    s.receivers.lightmap = Some(512);
                    least_squares_interreflected(s);
                }),
                Run::TexelsHeld(4, Some(20_000)),
            ),
        ),
        (
            "lightmap 512, interreflected, denoised, held, 12 at a time",
            (
                spec(&|s| {
                    s.receivers.lightmap = Some(512);
                    s.receivers.denoise = true;
                    interreflected(s);
                }),
                Run::TexelsHeld(12, None),
            ),
        ),
    ];
    // Local lights: the bunny at the defaults, the dragon with a smaller operator and maps
    // (at the defaults its depth maps' compression alone takes half a minute).
    let local = |edit: &dyn Fn(&mut LocalOptions)| {
        let mut options = LocalOptions::default();
        edit(&mut options);
        let mut spec = BakeSpec {
            local: Some(options),
            ..BakeSpec::default()
        };
        spec.transfer.mode = Mode::Local;
        (spec, Run::Local)
    };
    let local_cases = [
        ("local lights, bunny, defaults", local(&|_| {}), BUNNY),
        (
            "local lights, 64 samples, 64 lights, maps 8x8 in 16x8",
            local(&|o| {
                o.samples = 64;
                o.example_lights = 64;
                o.grid_side = 8;
                o.depth_clusters = 16;
                o.depth_components = 8;
                o.operator.clusters = 32;
                o.operator.components = 8;
            }),
            DRAGON,
        ),
    ];
    let cases = cases
        .into_iter()
        .map(|(what, case)| (what, case, DRAGON))
        .chain(local_cases);
    let mut failures = Vec::new();
    for (what, case, mesh) in cases {
        let (peak, need) = measured(&case, mesh, dir.path());
        let ratio = need as f64 / peak as f64;
        eprintln!(
            "{what:<58} peak {:>8.1} MiB  estimate {:>8.1} MiB  estimate/peak {ratio:.2}",
            peak as f64 / 1048576.0,
            need as f64 / 1048576.0
        );
        if !(1.0..=2.5).contains(&ratio) {
            failures.push(format!("{what}: estimate/peak {ratio:.2}"));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}
