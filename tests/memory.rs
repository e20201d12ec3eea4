//! Bakes in bounded memory (`bake --memory-limit`): a limit far below the whole bake's need
//! streams the transfer to the file in chunks, and the file's bytes are the whole bake's; a
//! limit no chunk fits, or a bake that cannot stream, is refused before it starts.

mod common;

use std::path::Path;

use common::prt_gpu;
use prt_gpu::bake::adaptive::TargetError;
use prt_gpu::bake::stream::MemoryNeed;
use prt_gpu::bake::{BakeOptions, Fit};

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
const TEAPOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/teapot.obj");

/// The first line of `stderr` that starts with `prefix`.
fn line_starting(stderr: &str, prefix: &str) -> Option<String> {
    stderr
        .lines()
        .find(|line| line.starts_with(prefix))
        .map(str::to_string)
}

/// The need of the bunny's bake with `options`, as the CLI estimates it.
fn bunny_need(options: &BakeOptions) -> MemoryNeed {
    let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
    MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), options)
}

/// `need` with the clustering `extra`'s `--compress` asks for (if it does), of rows of `bands`
/// bands in RGB for `vertices` vertices, as the CLI estimates it.
fn with_compression(need: MemoryNeed, extra: &[&str], bands: u32, vertices: usize) -> MemoryNeed {
    let Some(at) = extra.iter().position(|&a| a == "--compress") else {
        return need;
    };
    let dimension = 3 * (bands * bands) as usize;
    let (clusters, components) = match extra[at + 1].split_once('x') {
        Some((k, m)) => (k.parse().unwrap(), m.parse().unwrap()),
        None => prt_gpu::compress::largest_search_shape(dimension, vertices),
    };
    let group = prt_gpu::compress::covariance_group(dimension);
    let reconstructed = prt_gpu::compress::RECONSTRUCTED_ROWS as u64;
    need.with_compression(
        (clusters as u64, components as u64),
        dimension as u64,
        (group as u64, reconstructed),
    )
}

/// `line` without the seconds it states (" in 0.05 s"): a clustering's time is its own.
fn without_seconds(line: String) -> String {
    match line.split_once(" in ") {
        Some((before, after)) => format!("{before}{}", &after[after.find(" s").unwrap_or(0)..]),
        None => line,
    }
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
    const TARGET: [&str; 4] = ["--target-error", "0.05", "--max-samples", "1024"];
    let cases: [&[&str]; 23] = [
        &["--device", "cpu"],
        // Clustered PCA: the chunks wait in a scratch file, and every pass of the clustering
        // reads them back a chunk at a time.
        &["--device", "cpu", "--compress", "8x4"],
        &[
            "--device",
            "cpu",
            "--compress",
            "auto:0.05",
            "--bands",
            "auto",
            "--storage",
            "lean",
            "--precision",
            "f16",
            "--zonal",
            "2",
        ],
        &[
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--compress",
            "16x6",
        ],
        &["--device", "gpu", "--compress", "8x4", "--zonal", "3"],
        // An error target: the chunks wait until the mean samples the file records are known.
        &[
            "--device", "cpu", TARGET[0], TARGET[1], TARGET[2], TARGET[3],
        ],
        &[
            "--device", "gpu", TARGET[0], TARGET[1], TARGET[2], TARGET[3],
        ],
        // Interreflected to an error target: each chunk's gather rows come from its batches.
        &[
            "--device",
            "cpu",
            INTERREFLECTED[0],
            INTERREFLECTED[1],
            TARGET[0],
            TARGET[1],
            TARGET[2],
            TARGET[3],
        ],
        // --bands auto: the chunks wait at the most bands until the bands are chosen.
        &["--device", "cpu", "--bands", "auto"],
        &[
            "--device",
            "cpu",
            "--bands",
            "auto",
            "--mode",
            "interreflected",
            "--storage",
            "lean",
            "--precision",
            "f16",
        ],
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
        // Half floats: each chunk rounded as the whole file is, and its cost summed in order.
        &["--device", "cpu", "--precision", "f16"],
        &[
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--storage",
            "lean",
            "--precision",
            "f16",
        ],
        // Zonal transfer: each chunk fitted and written to its place in the reserved views.
        &["--device", "cpu", "--zonal", "3", "--zonal-axis", "fitted"],
        &["--device", "cpu", "--zonal", "2", "--bands", "auto"],
        &[
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--storage",
            "lean",
            "--precision",
            "f16",
            "--zonal",
            "4",
        ],
        &["--device", "gpu", "--zonal", "2", "--zonal-axis", "fitted"],
    ];
    for extra in cases {
        if extra.contains(&"gpu") && common::gpu_baker().is_none() {
            continue;
        }
        let interreflected = extra.windows(2).any(|w| w == INTERREFLECTED);
        let options = BakeOptions {
            bands: if extra.contains(&"6") {
                6
            } else if extra.contains(&"auto") {
                prt_gpu::spec::AUTO_MAX_BANDS
            } else {
                4
            },
            samples: 64,
            mode: match interreflected {
                true => prt_gpu::bake::Mode::Interreflected,
                false => prt_gpu::bake::Mode::Shadowed,
            },
            target_error: extra.contains(&TARGET[0]).then_some(TargetError {
                relative: 0.05,
                max_samples: 1024,
            }),
            ..BakeOptions::default()
        };
        let zonal = extra.iter().position(|&a| a == "--zonal");
        let need = match zonal {
            Some(at) => bunny_need(&options).with_zonal(extra[at + 1].parse().unwrap()),
            None => bunny_need(&options),
        };
        let need = with_compression(need, extra, options.bands, need.receivers as usize);
        // Chunks of 300 receivers: seven of them for the bunny's 1,839 vertices (compressed,
        // more where the clustering after the last chunk needs more room than one chunk).
        let limit = need.streamed(300);
        let chunk = need.chunk_within(limit).unwrap();
        assert!(chunk == 300 || extra.contains(&"--compress"), "{chunk}");
        assert!(
            limit < need.whole(),
            "the limit must be below the whole bake's need"
        );
        let mut whole = extra.to_vec();
        whole.extend(["-o", "whole.glb", "--memory-limit", "1T"]);
        let whole = bake(d, &whole);
        assert!(whole.status.success());
        let limit = limit.to_string();
        let mut streamed = extra.to_vec();
        streamed.extend(["-o", "streamed.glb", "--memory-limit", &limit]);
        let out = bake(d, &streamed);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{extra:?}: {stderr}");
        assert!(
            stderr.contains(&format!("chunks of {chunk} receivers")),
            "{extra:?}: {stderr}"
        );
        let same = std::fs::read(d.join("whole.glb")).unwrap()
            == std::fs::read(d.join("streamed.glb")).unwrap();
        assert!(
            same,
            "{extra:?}: the streamed file differs from the whole bake's"
        );
        // The lines the whole bake states — what half floats cost, the bands chosen, an
        // error target's samples and errors — and whether the case asks for each; the
        // streamed bake states the same.
        let whole_stderr = String::from_utf8_lossy(&whole.stderr);
        for (prefix, asked) in [
            // Compressed, what half floats cost is in the compression's line.
            (
                "precision f16:",
                extra.contains(&"f16") && !extra.contains(&"--compress"),
            ),
            ("bands auto:", extra.contains(&"auto")),
            ("target error:", extra.contains(&TARGET[0])),
            ("zonal:", zonal.is_some()),
            ("compressed:", extra.contains(&"--compress")),
        ] {
            // The zonal fit's seconds are its own; what it costs is the whole fit's.
            let without_time = |line: String| match line.split_once(" in ") {
                Some((before, after)) if prefix == "zonal:" => {
                    format!("{before}{}", &after[after.find(';').unwrap_or(0)..])
                }
                _ if prefix == "compressed:" => without_seconds(line),
                _ => line,
            };
            let stated = line_starting(&whole_stderr, prefix).map(without_time);
            assert_eq!(stated.is_some(), asked, "{extra:?} {prefix} {whole_stderr}");
            let streamed_line = line_starting(&stderr, prefix).map(without_time);
            assert_eq!(streamed_line, stated, "{extra:?}");
        }
    }
}

/// A glTF scene baked in place streams too: its chunks come in the baked (Morton) order of
/// vertices and fill the primitives' views in the scene's order at the end. 2CylinderEngine has
/// 115 primitives, meshes shown by several nodes (copied per placement) and vertices in no
/// baked triangle (dropped), so every path of the scatter runs.
#[test]
fn a_gltf_scene_streamed_in_chunks_writes_the_whole_bakes_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (gltf, scene) = prt_gpu::scene::gltf::load(Path::new(common::ENGINE_GLB)).unwrap();
    // Few rays: the bytes of a streamed bake are the whole bake's at any count, and three of
    // the cases cast theirs on lavapipe, ten times slower than the CPU.
    const SAMPLES: u32 = 8;
    let cases: [&[&str]; 9] = [
        &["--device", "cpu"],
        &["--device", "cpu", "--storage", "lean", "--precision", "f16"],
        // Clustered PCA: every placement's clusters and weights written at the end, from the
        // clustering of the transfer held in a scratch file.
        &[
            "--device",
            "cpu",
            "--compress",
            "16x4",
            "--precision",
            "f16",
        ],
        &["--device", "cpu", "--compress", "8x2", "--zonal", "2"],
        // Zonal transfer: each chunk's fit waits in a scratch file of its own and fills every
        // placement's zonal views at the end (dropped vertices get no lobe, as whole).
        &["--device", "cpu", "--zonal", "3", "--zonal-axis", "fitted"],
        &["--device", "gpu", "--zonal", "2"],
        &[
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--bounces",
            "2",
        ],
        &["--device", "gpu"],
        &[
            "--device",
            "gpu",
            "--mode",
            "interreflected",
            "--bounces",
            "1",
            "--precision",
            "f16",
        ],
    ];
    for extra in cases {
        if extra.contains(&"gpu") && common::gpu_baker().is_none() {
            continue;
        }
        let options = BakeOptions {
            samples: SAMPLES,
            mode: match extra.contains(&"interreflected") {
                true => prt_gpu::bake::Mode::Interreflected,
                false => prt_gpu::bake::Mode::Shadowed,
            },
            ..BakeOptions::default()
        };
        let mut need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), &options)
            .with_document(gltf.byte_size());
        if let Some(at) = extra.iter().position(|&a| a == "--zonal") {
            need = need.with_zonal(extra[at + 1].parse().unwrap());
        }
        let need = with_compression(need, extra, 4, scene.vertex_count());
        let limit = need.streamed(4096);
        let chunk = need.chunk_within(limit).unwrap();
        assert!(limit < need.whole());
        let run = |output: &str, limit: &str| {
            let samples = SAMPLES.to_string();
            let mut args = vec![
                "bake",
                common::ENGINE_GLB,
                "--samples",
                &samples,
                "-o",
                output,
            ];
            args.extend(["--memory-limit", limit]);
            args.extend(extra);
            let out = prt_gpu(&args, d);
            let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
            assert!(out.status.success(), "{extra:?}: {stderr}");
            stderr
        };
        let whole = run("whole.glb", "1T");
        let streamed = run("streamed.glb", &limit.to_string());
        assert!(
            streamed.contains(&format!("chunks of {chunk} receivers")),
            "{extra:?}: {streamed}"
        );
        // The same report of what was written in place (primitives, copies).
        let in_place = |stderr: &str| {
            let line = stderr.lines().find(|l| l.starts_with("baked in place:"));
            let line = line.unwrap_or_else(|| panic!("{extra:?}: {stderr}"));
            line.split(',').next().unwrap().to_string() + line.split(';').nth(1).unwrap_or("")
        };
        assert_eq!(in_place(&whole), in_place(&streamed), "{extra:?}");
        let compressed = |stderr: &str| line_starting(stderr, "compressed:").map(without_seconds);
        assert_eq!(compressed(&whole), compressed(&streamed), "{extra:?}");
        assert_eq!(
            compressed(&whole).is_some(),
            extra.contains(&"--compress"),
            "{whole}"
        );
        assert!(in_place(&whole).contains("115 primitive(s)"), "{whole}");
        let same = std::fs::read(d.join("whole.glb")).unwrap()
            == std::fs::read(d.join("streamed.glb")).unwrap();
        assert!(
            same,
            "{extra:?}: the streamed scene differs from the whole bake's"
        );
        if let Some(report) = common::validate_gltf(&d.join("streamed.glb")) {
            assert_eq!(report.num_errors, 0, "{extra:?}: {report:?}");
        }
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
    // Each bake that is not split says what it does with every receiver at once.
    let cases: [(&[&str], &str); 6] = [
        (&["--memory-limit", &below_any_chunk], "needs at least"),
        (
            &["--memory-limit", &below_any_chunk, "--fit", "least-squares"],
            "and the larger of its solve over every vertex",
        ),
        (
            &["--memory-limit", &below_any_chunk, "--compress", "8x4"],
            "the clustering's model, clusters and weights",
        ),
        (
            &["--memory-limit", &below_whole, "--lightmap", "256"],
            "with its lightmap held in a scratch file",
        ),
        (
            &["--memory-limit", &below_whole, "--subsurface", "marble"],
            "over the whole surface, so it does not stream in chunks",
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
    // A least-squares fit's shards split its points, each holding all of them.
    let cases = [
        ("shadowed", Fit::Point),
        ("interreflected", Fit::Point),
        ("interreflected", Fit::LeastSquares),
    ];
    for (mode, fit) in cases {
        let options = BakeOptions {
            samples: 64,
            mode: if mode == "shadowed" {
                prt_gpu::bake::Mode::Shadowed
            } else {
                prt_gpu::bake::Mode::Interreflected
            },
            fit,
            ..BakeOptions::default()
        };
        let mut need = bunny_need(&options);
        if fit == Fit::LeastSquares {
            let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
            let points = prt_gpu::receivers::spread_point_count(&scene, options.point_density);
            need = need.with_fit_points(points as u64, &options);
        }
        let limit = need.shard(4);
        let fewest = need.shards_within(limit).unwrap();
        assert!((2..=4).contains(&fewest), "{mode}: {fewest}");
        let limit_text = limit.to_string();
        let fit_name = match fit {
            Fit::Point => "point",
            Fit::LeastSquares => "least-squares",
        };
        let base = [
            "--device",
            "cpu",
            "--mode",
            mode,
            "--fit",
            fit_name,
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

/// A streamed bake's preview draws the radiance summed chunk by chunk: the whole bake's
/// preview, pixel for pixel within a step of 8-bit rounding.
#[test]
fn a_streamed_bake_draws_the_whole_bakes_preview() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let options = BakeOptions {
        samples: 64,
        storage: prt_gpu::bake::Storage::Lean,
        ..BakeOptions::default()
    };
    let limit = bunny_need(&options).streamed(300).to_string();
    let lean = ["--device", "cpu", "--storage", "lean"];
    let mut previews = Vec::new();
    for (name, memory) in [("whole", "1T"), ("streamed", limit.as_str())] {
        let (glb, png) = (format!("{name}.glb"), format!("{name}.png"));
        let mut args = lean.to_vec();
        args.extend(["-o", &glb, "--preview", &png, "--memory-limit", memory]);
        let out = bake(d, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        assert_eq!(
            stderr.contains("chunks of 300 receivers"),
            name == "streamed"
        );
        previews.push(image::open(d.join(&png)).unwrap().to_rgb8());
    }
    let (whole, streamed) = (&previews[0], &previews[1]);
    assert_eq!(whole.dimensions(), streamed.dimensions());
    let worst = whole
        .as_raw()
        .iter()
        .zip(streamed.as_raw())
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    assert!(worst <= 1, "the previews differ by {worst} of 255");
    // The bunny is drawn: the preview is not one colour.
    let first = whole.as_raw()[..3].to_vec();
    assert!(whole.as_raw().chunks(3).any(|p| p != first));
}

/// A lightmap held in a scratch file (its texels baked a chunk at a time, cleaned up a group of
/// coefficients at a time, encoded a block of rows at a time) writes the whole bake's .glb and
/// OpenEXR bytes, and draws the whole bake's preview; on the CPU and the GPU, shadowed,
/// interreflected and denoised, cut to the bands `--bands auto` chooses, and fitted by least
/// squares (its points in a scratch file too), interreflected and denoised on the GPU.
#[test]
fn a_lightmap_held_in_a_scratch_file_writes_the_whole_bakes_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: [&[&str]; 5] = [
        &["--device", "cpu"],
        &["--device", "cpu", "--mode", "interreflected", "--denoise"],
        &["--device", "gpu", "--denoise", "--bands", "5"],
        &["--device", "cpu", "--bands", "auto"],
        &[
            "--device",
            "gpu",
            "--mode",
            "interreflected",
            "--denoise",
            "--fit",
            "least-squares",
        ],
    ];
    for extra in cases {
        let options = BakeOptions {
            samples: 64,
            bands: match extra.iter().position(|&a| a == "--bands") {
                Some(at) if extra[at + 1] == "auto" => prt_gpu::spec::AUTO_MAX_BANDS,
                Some(at) => extra[at + 1].parse().unwrap(),
                None => 4,
            },
            mode: match extra.contains(&"interreflected") {
                true => prt_gpu::bake::Mode::Interreflected,
                false => prt_gpu::bake::Mode::Shadowed,
            },
            denoise: extra.contains(&"--denoise"),
            fit: match extra.contains(&"least-squares") {
                true => Fit::LeastSquares,
                false => Fit::Point,
            },
            ..BakeOptions::default()
        };
        let mut need = bunny_need(&options);
        if options.fit == Fit::LeastSquares {
            let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
            let points = prt_gpu::receivers::spread_point_count(&scene, options.point_density);
            need = need.with_fit_points(points as u64, &options);
        }
        let need = need.with_lightmap(96, &options);
        // Room for the seam solve's four coefficients at a time, not for the whole map.
        let limit = need.lightmap_held(4);
        assert!(limit < need.whole(), "{extra:?}");
        let mut outputs = Vec::new();
        for (name, memory) in [("whole", "1T".to_string()), ("held", limit.to_string())] {
            let sub = d.join(name);
            std::fs::create_dir_all(&sub).unwrap();
            let mut args = extra.to_vec();
            args.extend(["--lightmap", "96", "-o", "out.glb", "--preview", "out.png"]);
            args.extend(["--memory-limit", &memory]);
            let out = bake(&sub, &args);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(out.status.success(), "{extra:?} {name}: {stderr}");
            assert_eq!(
                stderr.contains("holding the lightmap's texels in a scratch file, cleaned up 4"),
                name == "held",
                "{extra:?} {name}: {stderr}"
            );
            let read = |file: &str| std::fs::read(sub.join(file)).unwrap();
            outputs.push([read("out.glb"), read("out.lightmap.exr"), read("out.png")]);
        }
        let names = ["the .glb", "the lightmap", "the preview"];
        for ((whole, held), what) in outputs[0].iter().zip(&outputs[1]).zip(names) {
            assert!(
                whole == held,
                "{extra:?}: {what} differs from the whole bake's"
            );
        }
    }
}

/// Beside a held lightmap, a least-squares fit at the vertices whose points, all at once, would
/// not fit the limit bakes them in runs, as it does without a lightmap: the whole bake's .glb
/// and OpenEXR bytes (the bunny, interreflected, whose points' gather rows are most of the fit).
#[test]
fn a_held_lightmap_beside_a_fit_in_runs_writes_the_whole_bakes_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let options = BakeOptions {
        samples: 64,
        mode: prt_gpu::bake::Mode::Interreflected,
        fit: Fit::LeastSquares,
        ..BakeOptions::default()
    };
    let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
    let points = prt_gpu::receivers::spread_point_count(&scene, options.point_density);
    let need = bunny_need(&options)
        .with_fit_points(points as u64, &options)
        .with_lightmap(96, &options);
    let limit = need.with_fit_run(1024).lightmap_held(4);
    assert!(limit < need.lightmap_held(1), "the fit fits whole");
    let mut outputs = Vec::new();
    for (name, memory) in [("whole", "1T".to_string()), ("held", limit.to_string())] {
        let sub = d.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        let args = [
            "--device",
            "cpu",
            "--mode",
            "interreflected",
            "--fit",
            "least-squares",
            "--lightmap",
            "96",
            "--memory-limit",
            &memory,
            "-o",
            "out.glb",
        ];
        let out = bake(&sub, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        assert_eq!(
            stderr.contains("and baking the vertices' least-squares points in runs of"),
            name == "held",
            "{name}: {stderr}"
        );
        let read = |file: &str| std::fs::read(sub.join(file)).unwrap();
        outputs.push([read("out.glb"), read("out.lightmap.exr")]);
    }
    assert!(outputs[0][0] == outputs[1][0], "the .glb differs");
    assert!(outputs[0][1] == outputs[1][1], "the lightmap differs");
}

/// A least-squares fit's points baked a few hundred at a time (each run's values summed into
/// the fit and let go, its gather rows in a scratch file) give the whole bake's transfer bit
/// for bit, and the same report: rays, gather entries, bounces, the fit's solve.
///
/// On the teapot: the bits of runs are the whole bake's on any mesh, and its 992 triangles
/// cast a quarter of the bunny's rays (the error target's case casts at least 512 a point,
/// twice, on lavapipe too).
#[test]
fn a_fit_whose_points_bake_in_runs_gives_the_whole_fits_bits() {
    use prt_gpu::bake::{DirectSource, Fit, Mode, NoProgress, Storage};
    use prt_gpu::pipeline;
    use prt_gpu::spec::BakeSpec;

    let scene = prt_gpu::scene::load(Path::new(TEAPOT)).unwrap();
    let spec = |change: &dyn Fn(&mut BakeSpec)| {
        let mut spec = BakeSpec::default();
        spec.receivers.fit = Fit::LeastSquares;
        spec.transfer.samples = 36;
        change(&mut spec);
        spec
    };
    let cases = [
        ("shadowed", spec(&|_| {})),
        ("lean", spec(&|s| s.storage.channels = Storage::Lean)),
        (
            "target error",
            spec(&|s| {
                s.transfer.target_error = Some(TargetError {
                    relative: 0.1,
                    max_samples: 512,
                })
            }),
        ),
        (
            "interreflected",
            spec(&|s| {
                s.transfer.mode = Mode::Interreflected;
                s.transfer.bounces = 2;
            }),
        ),
    ];
    for backend in common::backends() {
        for (name, spec) in &cases {
            let run = |chunk: Option<usize>| {
                let planned = pipeline::plan(spec, scene.clone(), None).unwrap();
                let planned = match chunk {
                    Some(chunk) => planned.with_point_chunk(chunk),
                    None => planned,
                };
                let source = DirectSource::Compute;
                let bake = planned.run(backend.as_ref(), source, &NoProgress);
                bake.and_then(pipeline::Bake::into_transfer).unwrap()
            };
            let whole = run(None);
            let name = format!("{name} on {}", backend.describe());
            // Runs of one triangle's points each on the CPU; a device's calls cost more.
            let chunks: &[usize] = match backend.gpu_context() {
                None => &[1, 300],
                Some(_) => &[300],
            };
            for &chunk in chunks {
                let runs = run(Some(chunk));
                let bits = |baked: &pipeline::Baked| -> Vec<u32> {
                    let coeffs = baked.mesh.transfer.coeffs();
                    coeffs.iter().map(|c| c.to_bits()).collect()
                };
                assert!(bits(&runs) == bits(&whole), "{name}, runs of {chunk}");
                let (a, b) = (&runs.report, &whole.report);
                assert_eq!(a.rays_cast, b.rays_cast, "{name}");
                assert_eq!(a.gather_entries, b.gather_entries, "{name}");
                assert_eq!(a.fit, b.fit, "{name}");
                assert_eq!(a.adaptive, b.adaptive, "{name}");
                let energies = |r: &prt_gpu::bake::BakeReport| -> Vec<f64> {
                    r.bounces.iter().map(|b| b.relative_energy).collect()
                };
                assert_eq!(energies(a), energies(b), "{name}");
                assert_eq!(runs.mesh.metadata, whole.mesh.metadata, "{name}");
            }
            if spec.transfer.mode == Mode::Interreflected {
                assert!(whole.report.gather_entries > 0, "{name}");
                assert_eq!(whole.report.bounces.len(), 2, "{name}");
            }
        }
    }
}
