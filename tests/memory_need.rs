//! The memory a bake says it needs before it starts (`pipeline::memory_need`: what
//! `--memory-limit` is held against, and what the warning over the machine's memory says)
//! bounds what the bake allocates, and not loosely. Each bake here is loaded, run and written
//! in this process under a counting allocator, one at a time (this file holds one test, so no
//! other test allocates beside it).

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use prt_gpu::bake::{CpuBackend, DirectSource, Fit, Mode, NoProgress};
use prt_gpu::spec::{BakeSpec, Compression, Layout as StoredLayout};
use prt_gpu::{pipeline, scene};

/// Bytes allocated and not yet freed, and the most there were since the last reset.
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grown(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

// SAFETY: every call is passed on to the system allocator unchanged; only counts are kept.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            grown(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc_zeroed(layout);
        if !p.is_null() {
            grown(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        System.dealloc(p, layout);
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    // The system's own, so that a block grown in place counts once, as it is held.
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = System.realloc(p, layout, size);
        if !q.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            grown(size);
        }
        q
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const DRAGON: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/dragon_vrip_res3.ply.gz"
);

/// The bytes allocated at the peak of loading `mesh`, baking it as `spec` asks (a fit's points
/// `point_chunk` at a time where given) and writing it, beyond what was live before; and the
/// estimate the bake plans by.
fn measured((spec, point_chunk): &(BakeSpec, Option<usize>), mesh: &str, dir: &Path) -> (u64, u64) {
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let scene = scene::load(Path::new(mesh)).unwrap();
    let planned = pipeline::plan(spec, scene, None).unwrap();
    let need = pipeline::memory_need(spec, (planned.scene(), None));
    let (planned, need) = match *point_chunk {
        Some(chunk) => (planned.with_point_chunk(chunk), need.points_chunked(chunk)),
        None => (planned, need.whole()),
    };
    let baked = planned
        .run(&CpuBackend, DirectSource::Compute, &NoProgress)
        .unwrap();
    pipeline::write(spec, &baked, None, &dir.join("baked.glb")).unwrap();
    drop(baked);
    let peak = PEAK.load(Ordering::Relaxed) - before;
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
    let whole = |spec: BakeSpec| (spec, None);
    let cases: Vec<(&str, (BakeSpec, Option<usize>))> = vec![
        ("vertices, shadowed", whole(spec(&|_| {}))),
        ("vertices, interreflected", whole(spec(&interreflected))),
        (
            "compressed",
            whole(spec(&|s| {
                s.storage.layout = StoredLayout::Cpca(Compression::Shape {
                    clusters: 16,
                    components: 4,
                })
            })),
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
                Some(20_000),
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
    ];
    let mut failures = Vec::new();
    for (what, case) in &cases {
        let (peak, need) = measured(case, DRAGON, dir.path());
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
