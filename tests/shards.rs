//! Sharded bakes: `bake … --shard I/N` parts merged by `prt-gpu merge` give the very bytes of the
//! unsharded bake, whatever the split; parts that do not belong together are refused.

mod common;

use std::path::{Path, PathBuf};

use common::prt_gpu;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");

/// Bakes `mesh` (the built-in scene for `None`) whole, then in `count` shards merged; returns
/// the two files' bytes.
fn whole_and_merged(
    mesh: Option<&str>,
    extra: &[&str],
    count: u32,
    dir: &Path,
) -> (Vec<u8>, Vec<u8>) {
    let mut args: Vec<String> = vec!["bake".into()];
    args.extend(mesh.map(String::from));
    args.extend(extra.iter().map(|a| a.to_string()));
    let run = |more: &[String]| {
        let all: Vec<&str> = args.iter().chain(more).map(String::as_str).collect();
        let out = prt_gpu(&all, dir);
        assert!(
            out.status.success(),
            "{all:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    run(&["-o".into(), "whole.glb".into()]);
    let mut merge = vec!["merge".to_string()];
    // Shards in reverse, so that the merge has to order them.
    for i in (0..count).rev() {
        let part = format!("shard{i}.part");
        run(&[
            "--shard".into(),
            format!("{i}/{count}"),
            "-o".into(),
            part.clone(),
        ]);
        merge.push(part);
    }
    merge.extend(["-o".into(), "merged.glb".into()]);
    let merge: Vec<&str> = merge.iter().map(String::as_str).collect();
    let out = prt_gpu(&merge, dir);
    assert!(
        out.status.success(),
        "merge: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read = |name: &str| std::fs::read(dir.join(name)).unwrap();
    (read("whole.glb"), read("merged.glb"))
}

#[test]
fn merged_shards_equal_the_whole_bake_byte_for_byte() {
    for mesh in [Some(BUNNY), None] {
        for mode in ["shadowed", "interreflected"] {
            for count in [1, 2, 3, 7] {
                let dir = tempfile::tempdir().unwrap();
                let extra = ["--device", "cpu", "--samples", "128", "--mode", mode];
                let (whole, merged) = whole_and_merged(mesh, &extra, count, dir.path());
                assert!(
                    whole == merged,
                    "{mesh:?} {mode} in {count} shards: the merged file differs"
                );
            }
        }
    }
}

#[test]
fn probes_are_baked_by_the_merge_as_by_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let extra = [
        "--device",
        "cpu",
        "--samples",
        "64",
        "--mode",
        "interreflected",
    ];
    let extra = [&extra[..], &["--probes", "1", "--probe-form", "irradiance"]].concat();
    let (whole, merged) = whole_and_merged(None, &extra, 3, dir.path());
    assert!(whole == merged, "the merged file with probes differs");
    let probes = prt_gpu::glb::probes::decode_probes(&merged, Path::new("merged.glb"))
        .unwrap()
        .expect("the merged file holds probes");
    assert!(!probes.is_empty());
}

/// Fits, auto bands, lean storage and compression run in the merge, as in the whole bake.
#[test]
fn merge_runs_the_rest_of_the_bake_as_the_whole_bake_does() {
    let cases: [&[&str]; 5] = [
        &[
            "--fit",
            "least-squares",
            "--mode",
            "interreflected",
            "--bounces",
            "2",
        ],
        // Interreflected to an error target: the parts carry the gather rows of the batches.
        &["--mode", "interreflected", "--target-error", "0.05"],
        &["--bands", "auto", "--storage", "lean"],
        &["--compress", "8x4", "--seed", "7"],
        // Each receiver's samples and error travel in the parts, so the merged file's mean
        // samples and the summary are the whole bake's.
        &["--target-error", "0.02"],
    ];
    for extra in cases {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec!["--device", "cpu", "--samples", "64"];
        args.extend(extra);
        let (whole, merged) = whole_and_merged(Some(BUNNY), &args, 3, dir.path());
        assert!(whole == merged, "{extra:?}: the merged file differs");
    }
}

/// The parts of a merge in `dir` (`shard0.part`, …), read as the merge reads them.
fn part_set(dir: &Path, count: u32) -> prt_gpu::shard::PartSet {
    let paths: Vec<PathBuf> = (0..count)
        .map(|i| dir.join(format!("shard{i}.part")))
        .collect();
    prt_gpu::shard::PartSet::read(&paths).unwrap()
}

/// A merge under `--memory-limit` holds its lightmap's texels in a scratch file, as the whole
/// bake does under the same limit (its largest part read beside them): the same .glb and
/// lightmap bytes as the merge without one, fitted by points or by least squares.
/// `prt-gpu merge PARTS -o OUTPUT --memory-limit LIMIT` run in `dir`.
fn merge_within(parts: &[&str], output: &str, limit: &str, dir: &Path) -> std::process::Output {
    let mut args = vec!["merge"];
    args.extend(parts);
    args.extend(["-o", output, "--memory-limit", limit]);
    prt_gpu(&args, dir)
}

#[test]
fn a_merge_under_a_memory_limit_holds_its_lightmap() {
    use prt_gpu::bake::stream::MemoryNeed;
    use prt_gpu::bake::{BakeOptions, Fit};
    for (fit, name) in [(Fit::Point, "point"), (Fit::LeastSquares, "least-squares")] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let extra = ["--device", "cpu", "--samples", "64", "--lightmap", "96"];
        let extra = [&extra[..], &["--fit", name]].concat();
        let (_, merged) = whole_and_merged(Some(BUNNY), &extra, 3, d);
        let exr = std::fs::read(d.join("merged.lightmap.exr")).unwrap();
        let options = BakeOptions {
            samples: 64,
            fit,
            ..BakeOptions::default()
        };
        let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
        let mut need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), &options);
        if fit == Fit::LeastSquares {
            let points = prt_gpu::receivers::spread_point_count(&scene, options.point_density);
            need = need.with_fit_points(points as u64, &options);
        }
        let need = need
            .with_lightmap(96, &options)
            .with_merge_part(part_set(d, 3).largest_part_bytes());
        let limit = need.lightmap_held(4).to_string();
        std::fs::create_dir_all(d.join("held")).unwrap();
        let parts = ["shard0.part", "shard1.part", "shard2.part"];
        let out = merge_within(&parts, "held/merged.glb", &limit, d);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        // A group of 4 fits the limit; more may where the vertices' least-squares fit, let go
        // before the lightmap, needs more than the texels do.
        let held = "holding the lightmap's texels in a scratch file, cleaned up ";
        let columns: usize = stderr
            .split_once(held)
            .and_then(|(_, rest)| rest.split(' ').next()?.parse().ok())
            .unwrap_or_else(|| panic!("{name}: not held: {stderr}"));
        assert!((4..48).contains(&columns), "{name}: {stderr}");
        assert!(
            std::fs::read(d.join("held/merged.glb")).unwrap() == merged,
            "{name}"
        );
        assert!(
            std::fs::read(d.join("held/merged.lightmap.exr")).unwrap() == exr,
            "{name}"
        );
    }
}

/// A merge at the vertices under a limit below its whole need streams: its parts are read one
/// at a time and the file is written in chunks, byte for byte the whole bake's (shadowed,
/// interreflected to an error target, lean with the bands chosen, compressed). A least-squares
/// fit's merge reads its points from the parts in runs, byte for byte the whole bake's, and
/// below its smallest run refuses the limit in one line and writes nothing.
#[test]
fn a_merge_under_a_memory_limit_streams_its_parts() {
    let cases: [&[&str]; 4] = [
        &[],
        &[
            "--mode",
            "interreflected",
            "--target-error",
            "0.05",
            "--max-samples",
            "1024",
        ],
        &["--bands", "auto", "--storage", "lean"],
        &["--compress", "8x4"],
    ];
    let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
    for extra in cases {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut args = vec!["--device", "cpu", "--samples", "64"];
        args.extend(extra);
        let (whole, _) = whole_and_merged(Some(BUNNY), &args, 3, d);
        let parts = part_set(d, 3);
        let need = prt_gpu::pipeline::memory_need(&parts.header().spec, (&scene, None))
            .with_merge_part(parts.largest_part_bytes());
        let limit = need.streamed(600);
        assert!(
            limit < need.whole(),
            "{extra:?}: the limit must be below the whole need"
        );
        let parts = ["shard1.part", "shard0.part", "shard2.part"];
        let out = merge_within(&parts, "streamed.glb", &limit.to_string(), d);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{extra:?}: {stderr}");
        assert!(
            stderr.contains("streaming the merge in chunks of"),
            "{extra:?}: {stderr}"
        );
        assert!(
            std::fs::read(d.join("streamed.glb")).unwrap() == whole,
            "{extra:?}: the streamed merge differs from the whole bake"
        );
    }

    // A least-squares fit's merge reads its points' direct pass from the parts in runs, as a
    // bake bakes them (interreflected: each run's gather rows wait in a scratch file).
    let fitted = tempfile::tempdir().unwrap();
    let p = fitted.path();
    let extra = [
        "--device",
        "cpu",
        "--samples",
        "16",
        "--fit",
        "least-squares",
        "--mode",
        "interreflected",
    ];
    let (whole, _) = whole_and_merged(Some(BUNNY), &extra, 2, p);
    let parts = part_set(p, 2);
    let need = prt_gpu::pipeline::memory_need(&parts.header().spec, (&scene, None))
        .with_merge_part(parts.largest_part_bytes());
    let limit = need.points_chunked(2000);
    assert!(
        limit < need.whole(),
        "the limit must be below the whole need"
    );
    let names = ["shard0.part", "shard1.part"];
    let out = merge_within(&names, "runs.glb", &limit.to_string(), p);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("reading the least-squares fit's"),
        "{stderr}"
    );
    assert!(
        std::fs::read(p.join("runs.glb")).unwrap() == whole,
        "the merge in runs differs from the whole bake"
    );
    // Below the smallest run beside the solve over every vertex: refused in one line.
    let out = merge_within(&names, "small.glb", "1M", p);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("and the larger of its solve over every vertex"),
        "{stderr}"
    );
    assert!(!p.join("small.glb").exists());
}

/// On the GPU backend (lavapipe in CI) too: the bounces of GPU parts run on a GPU in the merge.
#[test]
fn gpu_shards_merge_to_the_whole_gpu_bake() {
    if common::gpu_baker().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let extra = [
        "--device",
        "gpu",
        "--samples",
        "64",
        "--mode",
        "interreflected",
    ];
    let (whole, merged) = whole_and_merged(Some(BUNNY), &extra, 2, dir.path());
    assert!(whole == merged, "GPU parts: the merged file differs");
}

fn shard(dir: &Path, mesh: &str, extra: &[&str], index: u32, count: u32) -> PathBuf {
    let name = format!("{}-{index}-of-{count}-{}.part", stem(mesh), extra.join("_"));
    let spec = format!("{index}/{count}");
    let mut args = vec!["bake", mesh, "--device", "cpu", "--samples", "32"];
    args.extend(extra);
    args.extend(["--shard", &spec, "-o", &name]);
    let out = prt_gpu(&args, dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir.join(name)
}

fn stem(mesh: &str) -> String {
    Path::new(mesh)
        .file_stem()
        .unwrap()
        .to_string_lossy()
        .into()
}

/// `merge` of `parts`: its exit failed, with one line of error naming the problem.
fn refused(dir: &Path, parts: &[&Path], expected: &str) {
    let mut args = vec!["merge".to_string()];
    args.extend(parts.iter().map(|p| p.display().to_string()));
    args.extend(["-o".into(), "out.glb".into()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = prt_gpu(&args, dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} was merged");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains(expected), "{args:?}: {stderr}");
    assert!(
        !dir.join("out.glb").exists(),
        "a refused merge wrote a file"
    );
}

#[test]
fn merge_refuses_parts_that_do_not_make_one_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = [0, 1, 2].map(|i| shard(d, BUNNY, &[], i, 3));
    refused(d, &[&a[0], &a[2]], "shard 1/3 is missing");
    refused(d, &[&a[0], &a[1], &a[1], &a[2]], "shard 1/3 is given twice");
    let other_seed = shard(d, BUNNY, &["--seed", "2"], 1, 3);
    refused(d, &[&a[0], &other_seed, &a[2]], "parts of different bakes");
    let other_mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/teapot.obj");
    let other = shard(d, other_mesh, &[], 1, 3);
    refused(d, &[&a[0], &other, &a[2]], "parts of different bakes");
    let other_split = shard(d, BUNNY, &[], 1, 2);
    refused(d, &[&a[0], &other_split, &a[2]], "parts of different bakes");

    // A file that is not a part, and a part cut short.
    let not_a_part = d.join("bunny.obj.part");
    std::fs::copy(BUNNY, &not_a_part).unwrap();
    refused(d, &[&a[0], &not_a_part, &a[2]], "not a part");
    let bytes = std::fs::read(&a[1]).unwrap();
    let cut = d.join("cut.part");
    std::fs::write(&cut, &bytes[..bytes.len() - 8]).unwrap();
    refused(d, &[&a[0], &cut, &a[2]], "not a part");
    // A part one bit of whose data flipped on the way: its length still adds up.
    let mut flipped = bytes.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x40;
    let damaged = d.join("damaged.part");
    std::fs::write(&damaged, &flipped).unwrap();
    refused(d, &[&a[0], &damaged, &a[2]], "does not match its checksum");

    // The mesh changed after the shards were baked.
    let mesh = d.join("moving.obj");
    std::fs::copy(BUNNY, &mesh).unwrap();
    let mesh = mesh.display().to_string();
    let parts = [0, 1].map(|i| shard(d, &mesh, &[], i, 2));
    let text = std::fs::read_to_string(&mesh).unwrap();
    let moved: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, line)| match line.strip_prefix("v ") {
            // The first vertex moves a little along x.
            Some(xyz) if i == text.lines().position(|l| l.starts_with("v ")).unwrap() => {
                let x: Vec<f32> = xyz.split_whitespace().map(|v| v.parse().unwrap()).collect();
                format!("v {} {} {}", x[0] + 1e-3, x[1], x[2])
            }
            _ => line.to_string(),
        })
        .collect();
    std::fs::write(&mesh, moved.join("\n")).unwrap();
    refused(
        d,
        &[&parts[0], &parts[1]],
        "is not the mesh the parts were baked from",
    );
}

#[test]
fn bad_shard_specs_are_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    for spec in ["3/3", "1/0", "1/2/3", "a/b", "2"] {
        let out = prt_gpu(&["bake", BUNNY, "--shard", spec], dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "--shard {spec} was accepted");
        assert_eq!(stderr.trim().lines().count(), 1, "--shard {spec}: {stderr}");
        assert!(stderr.contains("--shard"), "--shard {spec}: {stderr}");
    }
    assert!(
        prt_gpu::testing::entries(dir.path()).is_empty(),
        "a refused shard wrote a file"
    );
}

/// The Kubernetes manifest (k8s/sharded-bake.yaml) is valid YAML and splits as the Slurm script
/// does: an Indexed Job of N completions whose pods bake `--shard $JOB_COMPLETION_INDEX/N`, and a
/// merge of N parts.
#[test]
fn kubernetes_manifest_is_an_indexed_job_of_n_shards_and_a_merge() {
    if !prt_gpu::testing::python_with(&["yaml"]) {
        return;
    }
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("k8s/sharded-bake.yaml");
    let script =
        "import json, sys, yaml\nprint(json.dumps(list(yaml.safe_load_all(open(sys.argv[1])))))";
    let docs = prt_gpu::testing::python_json(script, &manifest);
    let docs = docs.as_array().expect("a list of documents");
    assert_eq!(docs.len(), 2);
    let (shards, merge) = (&docs[0], &docs[1]);
    for doc in docs {
        assert_eq!(doc["apiVersion"], "batch/v1");
        assert_eq!(doc["kind"], "Job");
    }
    assert_eq!(shards["spec"]["completionMode"], "Indexed");
    let n = shards["spec"]["completions"].as_u64().expect("completions");
    let command = |job: &serde_json::Value| {
        let container = &job["spec"]["template"]["spec"]["containers"][0];
        container["args"][0].as_str().expect("args").to_string()
    };
    let bake = command(shards);
    assert!(bake.starts_with("prt-gpu bake "), "{bake}");
    assert!(
        bake.contains(&format!("--shard \"${{JOB_COMPLETION_INDEX}}/{n}\"")),
        "{bake}"
    );
    assert!(
        bake.contains(&format!("part-${{JOB_COMPLETION_INDEX}}-of-{n}.part")),
        "{bake}"
    );
    let merging = command(merge);
    assert!(merging.starts_with("prt-gpu merge "), "{merging}");
    assert!(
        merging.contains(&format!("part-*-of-{n}.part")),
        "{merging}"
    );
}

/// A part read by the documented numpy recipe (prt_gpu::shard::PYTHON_READER) holds what the
/// library reads from it.
#[test]
fn parts_read_by_numpy_alone_match_the_library() {
    if !prt_gpu::testing::python_with(&["numpy"]) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for mode in ["shadowed", "interreflected", "adaptive"] {
        let extra: &[&str] = match mode {
            "adaptive" => &["--target-error", "0.02"],
            _ => &["--mode", mode],
        };
        let path = shard(d, BUNNY, extra, 1, 3);
        let part = prt_gpu::shard::read_part(&path).unwrap();
        let python = prt_gpu::testing::python_json(prt_gpu::shard::PYTHON_READER, &path);
        let header = serde_json::to_value(&part.header).unwrap();
        assert_eq!(python["header"], header);
        let (receivers, coeffs) = (part.header.receivers as u64, part.header.coeffs as u64);
        assert_eq!(
            python["scalar_shape"],
            serde_json::json!([receivers, coeffs])
        );
        let sum: f64 = part.direct.scalar.iter().map(|&x| x as f64).sum();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(1.0);
        assert!(close(python["scalar_sum"].as_f64().unwrap(), sum), "{mode}");
        if let Some(matrix) = &part.direct.matrix {
            let weights: f64 = matrix.weights.iter().map(|&x| x as f64).sum();
            assert!(close(python["weights_sum"].as_f64().unwrap(), weights));
            let max_column = *matrix.columns.iter().max().unwrap() as u64;
            assert_eq!(python["max_column"].as_u64().unwrap(), max_column);
        } else {
            assert!(python.get("weights_sum").is_none(), "{mode}");
        }
        match &part.direct.adaptive {
            Some(receivers) => {
                let samples: u64 = receivers.samples.iter().map(|&s| s as u64).sum();
                assert_eq!(python["samples_sum"].as_u64().unwrap(), samples);
                let worst = receivers.errors.iter().copied().fold(0.0, f64::max);
                assert_eq!(python["error_max"].as_f64().unwrap(), worst);
                assert_eq!(receivers.len() as u64, part.header.receivers);
            }
            None => assert!(python.get("samples_sum").is_none(), "{mode}"),
        }
    }
}

#[test]
fn a_shard_with_no_receivers_says_so_and_still_merges() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = d.join("tri.obj");
    std::fs::write(&mesh, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let mesh = mesh.display().to_string();
    let parts: Vec<_> = (0..4).map(|i| shard(d, &mesh, &[], i, 4)).collect();
    let out = prt_gpu(&["bake", &mesh, "--shard", "0/4", "-o", "again.part"], d);
    assert!(
        String::from_utf8_lossy(&out.stderr)
            .contains("note: shard 0/4 holds none of the 3 receivers"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut args = vec!["merge".to_string()];
    args.extend(parts.iter().map(|p| p.display().to_string()));
    args.extend(["-o".into(), "merged.glb".into()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    assert!(prt_gpu(&args, d).status.success());
}

/// A part whose gather rows name a receiver past the bake's, with a checksum that matches
/// (written so, not damaged on the way): refused in one line, not a panic in the bounce (a
/// mutated part once made `merge` index past the transfer).
#[test]
fn merge_refuses_a_gather_column_past_the_receivers() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = [0, 1].map(|i| shard(d, BUNNY, &["--mode", "interreflected"], i, 2));
    let mut part = prt_gpu::shard::read_part(&a[1]).unwrap();
    let total = part.header.receivers_total as u32;
    let matrix = part
        .direct
        .matrix
        .as_mut()
        .expect("interreflected parts hold gather rows");
    *matrix.columns.last_mut().unwrap() = total + 5;
    let bad = d.join("bad-column.part");
    prt_gpu::shard::write_part(&bad, &part).unwrap();
    refused(d, &[&a[0], &bad], "gather column");
}

/// Parts of one bake baked by commands that differ beyond the shard and the part's file (here
/// a memory limit, which shapes no output and is not in the fingerprint): merged, with a warning that
/// names both commands and says whose the merge follows.
#[test]
fn merge_warns_when_the_parts_commands_differ() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = shard(d, BUNNY, &[], 0, 2);
    let second = shard(d, BUNNY, &["--memory-limit", "8G"], 1, 2);
    let (first, second) = (first.display().to_string(), second.display().to_string());
    let out = prt_gpu(&["merge", &first, &second, "-o", "merged.glb"], d);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let warning = stderr
        .lines()
        .find(|l| l.starts_with("warning:"))
        .unwrap_or_else(|| panic!("no warning: {stderr}"));
    assert!(warning.contains("--memory-limit 8G"), "{warning}");
    assert!(
        warning.ends_with("the merge finishes the bake as the first says"),
        "{warning}"
    );
    let same = [0, 1].map(|i| {
        shard(d, BUNNY, &["--seed", "3"], i, 2)
            .display()
            .to_string()
    });
    let out = prt_gpu(&["merge", &same[0], &same[1], "-o", "again.glb"], d);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning:"));
}

/// A part says what its bake is as a spec, and the merge bakes the rest by that spec: a part
/// whose recorded command was changed (resealed, so its checksum holds) still merges to the
/// bytes of the whole bake.
#[test]
fn a_part_holds_its_bake_spec_and_the_merge_bakes_by_it_not_by_the_command() {
    use prt_gpu::precision::Precision;
    use prt_gpu::shard::{read_part, write_part};
    use prt_gpu::spec::{Bands, Compression, Layout};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let flags = [
        "--bands",
        "auto",
        "--compress",
        "8x4",
        "--precision",
        "f16",
        "--seed",
        "5",
    ];
    let parts = [0, 1].map(|i| shard(d, BUNNY, &flags, i, 2));
    for path in &parts {
        let mut part = read_part(path).unwrap();
        let spec = &part.header.spec;
        assert_eq!(spec.transfer.bands, Bands::Auto { threshold: 0.05 });
        assert_eq!(spec.transfer.seed, 5);
        assert_eq!(spec.transfer.samples, 32);
        assert_eq!(spec.storage.precision, Precision::F16);
        assert_eq!(
            spec.storage.layout,
            Layout::Cpca(Compression::Shape {
                clusters: 8,
                components: 4
            })
        );
        assert_eq!(part.header.mesh.as_deref(), Some(Path::new(BUNNY)));
        part.header.command = ["bake", "--bands", "2", "elsewhere.obj"]
            .map(String::from)
            .to_vec();
        write_part(path, &part).unwrap();
    }
    let parts = parts.map(|p| p.display().to_string());
    let out = prt_gpu(&["merge", &parts[0], &parts[1], "-o", "merged.glb"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut whole = vec![
        "bake",
        BUNNY,
        "--device",
        "cpu",
        "--samples",
        "32",
        "-o",
        "whole.glb",
    ];
    whole.extend(flags);
    let out = prt_gpu(&whole, d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read = |name: &str| std::fs::read(d.join(name)).unwrap();
    assert_eq!(read("merged.glb"), read("whole.glb"));
}
