//! Bakes in bounded memory (`bake --memory-limit`): a limit far below the whole bake's need
//! streams the transfer to the file in chunks, and the file's bytes are the whole bake's; a
//! limit no chunk fits, or a bake that cannot stream, is refused before it starts.

mod common;

use std::path::Path;

use common::prt_gpu;
use prt_gpu::bake::stream::MemoryNeed;
use prt_gpu::bake::BakeOptions;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");

/// The need of the bunny's bake with `options`, as the CLI estimates it.
fn bunny_need(options: &BakeOptions) -> MemoryNeed {
    let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
    MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), options)
}

fn bake(dir: &Path, args: &[&str]) -> std::process::Output {
    let mut all = vec!["bake", BUNNY, "--samples", "64"];
    all.extend(args);
    prt_gpu(&all, dir)
}

#[test]
fn a_bake_streamed_in_chunks_writes_the_whole_bakes_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    const INTERREFLECTED: [&str; 2] = ["--mode", "interreflected"];
    let cases: [&[&str]; 8] = [
        &["--device", "cpu"],
        &["--device", "cpu", "--storage", "lean", "--bands", "6"],
        &[
            "--device",
            "cpu",
            "--mode",
            "unshadowed",
            "--sampling",
            "stratified",
        ],
        &["--device", "gpu"],
        // Interreflection: the direct pass streams, the bounces read a chunk of gather rows at
        // a time; the bunny's grey albedo makes the lean file one channel.
        &["--device", "cpu", "--mode", "interreflected"],
        &[
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--storage",
            "lean",
            "--bounces",
            "2",
        ],
        &[
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--bounce-tolerance",
            "0.05",
        ],
        &["--device", "gpu", "--mode", "interreflected"],
    ];
    for extra in cases {
        if extra.contains(&"gpu") && common::gpu_baker().is_none() {
            continue;
        }
        let interreflected = extra.windows(2).any(|w| w == INTERREFLECTED);
        let options = BakeOptions {
            bands: if extra.contains(&"6") { 6 } else { 4 },
            samples: 64,
            mode: match interreflected {
                true => prt_gpu::bake::Mode::Interreflected,
                false => prt_gpu::bake::Mode::Shadowed,
            },
            ..BakeOptions::default()
        };
        let need = bunny_need(&options);
        // Chunks of 300 receivers: seven of them for the bunny's 1,839 vertices.
        let limit = need.streamed(300);
        assert!(
            limit < need.whole(),
            "the limit must be below the whole bake's need"
        );
        let mut whole = extra.to_vec();
        whole.extend(["-o", "whole.glb", "--memory-limit", "1T"]);
        assert!(bake(d, &whole).status.success());
        let limit = limit.to_string();
        let mut streamed = extra.to_vec();
        streamed.extend(["-o", "streamed.glb", "--memory-limit", &limit]);
        let out = bake(d, &streamed);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{extra:?}: {stderr}");
        assert!(
            stderr.contains("chunks of 300 receivers"),
            "{extra:?}: {stderr}"
        );
        let same = std::fs::read(d.join("whole.glb")).unwrap()
            == std::fs::read(d.join("streamed.glb")).unwrap();
        assert!(
            same,
            "{extra:?}: the streamed file differs from the whole bake's"
        );
    }
}

#[test]
fn limits_that_cannot_be_met_are_refused_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let need = bunny_need(&BakeOptions {
        samples: 64,
        ..BakeOptions::default()
    });
    let below_any_chunk = (need.fixed / 2).to_string();
    let below_whole = (need.whole() / 2).to_string();
    let cases: [(&[&str], &str); 4] = [
        (&["--memory-limit", &below_any_chunk], "needs at least"),
        (
            &["--memory-limit", &below_whole, "--fit", "least-squares"],
            "stream in chunks",
        ),
        (
            &["--memory-limit", &below_whole, "--compress", "8x4"],
            "stream in chunks",
        ),
        (&["--memory-limit", "lots"], "expected a size"),
    ];
    for (args, expected) in cases {
        let mut all = vec!["--device", "cpu", "-o", "out.glb"];
        all.extend(args);
        let out = bake(d, &all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} baked");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert!(
            prt_gpu::testing::entries(d).is_empty(),
            "{args:?} left a file"
        );
    }
}

/// A shard is not streamed: over an explicit limit it is refused before the bake, naming the
/// fewest shards that each fit, and that many shards then bake within the same limit.
#[test]
fn a_shard_over_the_limit_is_refused_naming_a_count_that_fits() {
    let dir = tempfile::tempdir().unwrap();
    for mode in ["shadowed", "interreflected"] {
        let options = BakeOptions {
            samples: 64,
            mode: if mode == "shadowed" {
                prt_gpu::bake::Mode::Shadowed
            } else {
                prt_gpu::bake::Mode::Interreflected
            },
            ..BakeOptions::default()
        };
        let need = bunny_need(&options);
        let limit = need.shard(4);
        let fewest = need.shards_within(limit).unwrap();
        assert!((2..=4).contains(&fewest), "{mode}: {fewest}");
        let limit_text = limit.to_string();
        let base = [
            "--device",
            "cpu",
            "--mode",
            mode,
            "--memory-limit",
            &limit_text,
        ];

        let mut one = base.to_vec();
        one.extend(["--shard", "0/1", "-o", "one.part"]);
        let out = bake(dir.path(), &one);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{mode}: one shard baked");
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains(&format!("{fewest} or more shards would each fit")),
            "{mode}: {stderr}"
        );
        assert!(prt_gpu::testing::entries(dir.path()).is_empty());

        let shard = format!("0/{fewest}");
        let mut split = base.to_vec();
        split.extend(["--shard", &shard, "-o", "split.part"]);
        let out = bake(dir.path(), &split);
        assert!(
            out.status.success(),
            "{mode}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        std::fs::remove_file(dir.path().join("split.part")).unwrap();
    }
}
