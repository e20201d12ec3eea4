//! What the commands write, checked before they start and written so that nothing else is lost:
//! an output that is one of the inputs (or another output) is refused and the input left as it
//! was; a device such as /dev/null is written into, not replaced; an output whose name says
//! another format than the command writes is refused; a failed preview or frame sequence leaves
//! nothing behind; and a write error names the output, not the temporary file under it.

mod common;

use std::path::Path;

use common::prt_gpu;
use prt_gpu::bake::stream::MemoryNeed;
use prt_gpu::bake::BakeOptions;
use prt_gpu::render::ToneMap;
use prt_gpu::testing::entries;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");

const TET: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// A quick CPU bake of the tetrahedron.
const BAKE: [&str; 5] = ["--samples", "16", "--device", "cpu", "--seed"];

fn bake_args<'a>(mesh: &'a str, rest: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["bake", mesh];
    args.extend(BAKE);
    args.push("1");
    args.extend(rest);
    args
}

fn succeed(out: &std::process::Output, what: &str) {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The run failed with exactly one `error:` line, which it returns.
fn one_error(out: &std::process::Output, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{what} succeeded: {stderr}");
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{what}: {stderr}");
    errors[0].to_string()
}

/// A directory with the tetrahedron (`tet.obj`), its bake (`tet.glb`), the two parts of a
/// sharded bake of it (`p0.part`, `p1.part`), a light (`l.json`) and an image (`map.png`).
fn inputs() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tet.obj"), TET).unwrap();
    succeed(
        &prt_gpu(&bake_args("tet.obj", &["-o", "tet.glb"]), d),
        "bake",
    );
    for i in 0..2 {
        let (shard, part) = (format!("{i}/2"), format!("p{i}.part"));
        let out = prt_gpu(&bake_args("tet.obj", &["--shard", &shard, "-o", &part]), d);
        succeed(&out, "shard");
    }
    let light = prt_gpu(&["light", "--sky", "1,1,1", "-o", "l.json"], d);
    succeed(&light, "light");
    write_png(&d.join("map.png"));
    dir
}

/// A 2x1 PNG, written as the tool writes its images.
fn write_png(path: &Path) {
    let pixels = [[1.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0]];
    prt_gpu::render::write_image(path, &pixels, 2, 1, ToneMap::None, 0.0).unwrap();
}

/// A `--memory-limit` that makes the bunny's bake at 16 samples stream in chunks.
fn streaming_limit() -> String {
    let scene = prt_gpu::scene::load(Path::new(BUNNY)).unwrap();
    let options = BakeOptions {
        samples: 16,
        ..BakeOptions::default()
    };
    let need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), &options);
    let limit = need.streamed(300);
    assert!(limit < need.whole());
    limit.to_string()
}

/// Every file under `dir` (one level) and its bytes.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    entries(dir)
        .into_iter()
        .map(|name| {
            let bytes = std::fs::read(dir.join(&name)).unwrap_or_default();
            (name, bytes)
        })
        .collect()
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let dir = inputs();
    let d = dir.path();
    std::fs::create_dir(d.join("sub")).unwrap();
    std::fs::hard_link(d.join("tet.obj"), d.join("sub/link.obj")).unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (bake_args("tet.obj", &["-o", "tet.obj"]), "tet.obj"),
        (
            bake_args("./tet.obj", &["-o", "sub/../tet.obj"]),
            "sub/../tet.obj",
        ),
        (
            bake_args("tet.obj", &["-o", "sub/link.obj"]),
            "sub/link.obj",
        ),
        (bake_args("tet.glb", &["-o", "tet.glb"]), "tet.glb"),
        (
            bake_args("tet.obj", &["--shard", "0/2", "-o", "tet.obj"]),
            "tet.obj",
        ),
        (
            bake_args("tet.obj", &["--mode", "local", "-o", "./tet.obj"]),
            "./tet.obj",
        ),
        (
            vec!["render", "tet.glb", "--light", "l.json", "-o", "tet.glb"],
            "tet.glb",
        ),
        (
            vec!["render", "tet.glb", "--light", "map.png", "-o", "map.png"],
            "map.png",
        ),
        (vec!["view", "tet.glb", "-o", "tet.glb"], "tet.glb"),
        (
            vec!["view", "tet.glb", "--light", "l.json", "-o", "l.json"],
            "l.json",
        ),
        (vec!["export", "x3d", "tet.glb", "-o", "tet.glb"], "tet.glb"),
        (vec!["light", "map.png", "-o", "map.png"], "map.png"),
        (
            vec!["light", "--faces", "map.png,map.png", "-o", "./map.png"],
            "./map.png",
        ),
        (
            vec!["merge", "p0.part", "p1.part", "-o", "p0.part"],
            "p0.part",
        ),
        (
            vec![
                "merge",
                "p0.part",
                "p1.part",
                "-o",
                "m.glb",
                "--preview",
                "p1.part",
            ],
            "p1.part",
        ),
        (vec!["chart", "tet.obj", "-o", "tet.obj"], "tet.obj"),
        // A lightmapped bake relit to a .glb writes its relit lightmap beside: x.radiance.exr.
        (
            vec![
                "render",
                "lm.glb",
                "--light",
                "x.radiance.exr",
                "-o",
                "x.glb",
            ],
            "x.radiance.exr",
        ),
    ];
    let lightmapped = bake_args("tet.obj", &["--lightmap", "32", "-o", "lm.glb"]);
    succeed(&prt_gpu(&lightmapped, d), "a lightmapped bake");
    std::fs::copy(d.join("map.png"), d.join("x.radiance.exr")).unwrap();
    let before = snapshot(d);
    for (args, output) in &cases {
        let what = args.join(" ");
        let error = one_error(&prt_gpu(args, d), &what);
        assert!(
            error.contains(&format!("output {output} is also an input; choose another")),
            "{what}: {error}"
        );
        assert_eq!(snapshot(d), before, "{what} changed the inputs");
    }
    let link = std::fs::read(d.join("sub/link.obj")).unwrap();
    assert_eq!(link, TET.as_bytes());

    // A batch whose --out-dir would put a bake over one of its meshes (bunny.obj bakes to
    // bunny.prt.glb, itself a mesh of the batch) is refused before anything is baked.
    let batch = d.join("batch");
    std::fs::create_dir(&batch).unwrap();
    std::fs::write(batch.join("bunny.obj"), TET).unwrap();
    std::fs::copy(d.join("tet.glb"), batch.join("bunny.prt.glb")).unwrap();
    let before = snapshot(&batch);
    let mut args = vec!["bake", "batch", "--out-dir", "batch"];
    args.extend(BAKE);
    args.push("1");
    let error = one_error(&prt_gpu(&args, d), "batch");
    assert!(
        error.contains("output batch/bunny.prt.glb is also an input; choose another --out-dir"),
        "{error}"
    );
    assert_eq!(snapshot(&batch), before);
}

#[test]
fn two_outputs_that_are_one_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tet.obj"), TET).unwrap();
    let args = bake_args(
        "tet.obj",
        &[
            "--lightmap",
            "32",
            "-o",
            "o.glb",
            "--preview",
            "o.lightmap.exr",
        ],
    );
    let error = one_error(&prt_gpu(&args, d), "preview over the lightmap");
    assert!(
        error.contains("o.lightmap.exr") && error.contains("choose another --preview"),
        "{error}"
    );
    assert_eq!(entries(d), ["tet.obj"]);
}

/// Whether `path` is a character device.
#[cfg(unix)]
fn is_char_device(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_char_device())
}

/// A null device of the test's own in `dir` (`mknod`, so root only, on a file system that allows
/// devices), written to once to be sure it works; `None` where it cannot be made.
#[cfg(unix)]
fn private_null(dir: &Path) -> Option<std::path::PathBuf> {
    let null = dir.join("null");
    let made = std::process::Command::new("mknod")
        .arg(&null)
        .args(["c", "1", "3"])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let works = made && is_char_device(&null) && std::fs::write(&null, b"probe").is_ok();
    if made && !works {
        let _ = std::fs::remove_file(&null);
    }
    works.then_some(null)
}

/// `-o /dev/null` discards the output and leaves /dev/null a device: a target that is not a
/// regular file is written into, never renamed over (which, run as root, would replace
/// /dev/null with a regular file). The real /dev/null is never put at risk here: every command
/// writes to a null device of the test's own where it can make one (root, `mknod`), and to a
/// FIFO of its own otherwise, drained as it is written; either must still be what it was.
#[cfg(unix)]
#[test]
fn a_device_or_fifo_takes_the_output_and_stays_what_it_was() {
    use std::os::unix::fs::FileTypeExt;
    let dir = inputs();
    let d = dir.path();
    let targets = tempfile::tempdir().unwrap();
    let (target, is_fifo) = match private_null(targets.path()) {
        Some(null) => (null, false),
        None => (private_fifo(targets.path()), true),
    };
    let before = entries(d);
    let limit = streaming_limit();
    let null = target.display().to_string();
    let cases: Vec<Vec<&str>> = vec![
        bake_args("tet.obj", &["-o", &null]),
        // Streamed to the file a chunk at a time.
        bake_args(BUNNY, &["--memory-limit", &limit, "-o", &null]),
        bake_args("tet.obj", &["--shard", "1/2", "-o", &null]),
        bake_args("tet.obj", &["--mode", "local", "-o", &null]),
        vec!["light", "--sky", "1,1,1", "-o", &null],
        vec!["view", "tet.glb", "-o", &null],
        vec!["export", "x3d", "tet.glb", "-o", &null],
        vec!["merge", "p0.part", "p1.part", "-o", &null],
    ];
    for args in cases {
        let drain = is_fifo.then(|| {
            let fifo = target.clone();
            std::thread::spawn(move || std::fs::read(fifo).map(|bytes| bytes.len()))
        });
        let out = prt_gpu(&args, d);
        succeed(&out, &args.join(" "));
        if let Some(drain) = drain {
            let received = drain.join().unwrap().unwrap();
            assert!(received > 0, "{}: nothing reached the FIFO", args.join(" "));
        }
        let kind = std::fs::metadata(&target).unwrap().file_type();
        assert!(
            kind.is_char_device() || kind.is_fifo(),
            "{} replaced {}",
            args.join(" "),
            target.display()
        );
    }
    assert_eq!(entries(d), before, "a temporary file was left");
    assert_eq!(
        entries(targets.path()),
        [target.file_name().unwrap().to_string_lossy().into_owned()],
        "a temporary file was left beside the target"
    );
}

/// A FIFO of the test's own in `dir` (`mkfifo`, which needs no privilege).
#[cfg(unix)]
fn private_fifo(dir: &Path) -> std::path::PathBuf {
    let fifo = dir.join("fifo");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    assert!(made, "mkfifo {} failed", fifo.display());
    fifo
}

#[test]
fn outputs_named_for_another_format_are_refused_before_any_work() {
    let dir = inputs();
    let d = dir.path();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (bake_args("tet.obj", &["-o", "out.gltf"]), "-o out.gltf"),
        (bake_args("tet.obj", &["-o", "out.png"]), "-o out.png"),
        (bake_args("tet.obj", &["-o", "out.obj"]), "-o out.obj"),
        (bake_args("tet.obj", &["-o", "out"]), "-o out"),
        (
            bake_args("tet.obj", &["--lightmap", "128", "-o", "out.lightmap.exr"]),
            "-o out.lightmap.exr",
        ),
        (
            bake_args("tet.obj", &["--mode", "local", "-o", "out.png"]),
            "-o out.png",
        ),
        (
            bake_args("tet.obj", &["--shard", "0/2", "-o", "p.glb"]),
            "-o p.glb",
        ),
        (
            bake_args("tet.obj", &["-o", "o.glb", "--preview", "p.txt"]),
            "--preview p.txt",
        ),
        (
            vec!["light", "--sky", "1,1,1", "-o", "out.exr"],
            "-o out.exr",
        ),
        (vec!["export", "x3d", "tet.glb", "-o", "s.png"], "-o s.png"),
        (vec!["view", "tet.glb", "-o", "v.txt"], "-o v.txt"),
        (vec!["render", "tet.glb", "-o", "r.txt"], "-o r.txt"),
        (
            vec!["merge", "p0.part", "p1.part", "-o", "m.part"],
            "-o m.part",
        ),
        (
            vec![
                "merge",
                "p0.part",
                "p1.part",
                "-o",
                "m.glb",
                "--preview",
                "p.txt",
            ],
            "--preview p.txt",
        ),
    ];
    let before = snapshot(d);
    for (args, named) in &cases {
        let what = args.join(" ");
        let error = one_error(&prt_gpu(args, d), &what);
        assert!(
            error.contains(named) && error.contains("must end in ."),
            "{what}: {error}"
        );
        assert_eq!(snapshot(d), before, "{what} left a file");
    }
    // The same outputs named as documented are written (upper-case extensions too).
    let fine: Vec<Vec<&str>> = vec![
        bake_args("tet.obj", &["-o", "OUT.GLB"]),
        bake_args("tet.obj", &["--shard", "0/2", "-o", "s.part"]),
        vec!["light", "--sky", "1,1,1", "-o", "sky.json"],
        vec!["export", "x3d", "tet.glb", "-o", "s.x3d"],
        vec!["view", "tet.glb", "-o", "v.html"],
        vec!["view", "tet.glb", "-o", "v.htm"],
        vec!["merge", "p0.part", "p1.part", "-o", "m.glb"],
    ];
    for args in &fine {
        succeed(&prt_gpu(args, d), &args.join(" "));
    }
}

/// Rendering needs an adapter: without one (outside CI) the render half of a test is skipped.
fn can_render() -> bool {
    prt_gpu::device::any_adapter_or_skip().is_some()
}

#[test]
fn a_failed_preview_leaves_no_bake() {
    let dir = inputs();
    let d = dir.path();
    let before = entries(d);
    // A preview that cannot be written (its name is taken by a directory): the bake, its
    // lightmap and the preview all fail together.
    std::fs::create_dir(d.join("p.png")).unwrap();
    let cases = [
        bake_args(
            "tet.obj",
            &["--lightmap", "32", "-o", "o.glb", "--preview", "p.png"],
        ),
        vec![
            "merge",
            "p0.part",
            "p1.part",
            "-o",
            "o.glb",
            "--preview",
            "p.png",
        ],
    ];
    for args in &cases {
        let what = args.join(" ");
        let error = one_error(&prt_gpu(args, d), &what);
        if can_render() {
            assert!(error.contains("p.png"), "{what}: {error}");
        }
        let mut expected = before.clone();
        expected.push("p.png".into());
        expected.sort();
        assert_eq!(entries(d), expected, "{what} left a file");
        assert!(d.join("p.png").is_dir());
    }
}

#[test]
fn a_failed_frame_leaves_no_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tet.obj"), TET).unwrap();
    let bake = prt_gpu(
        &bake_args("tet.obj", &["--mode", "local", "-o", "room.glb"]),
        d,
    );
    succeed(&bake, "local bake");
    // Frame 1's name is taken by a directory: frame 0 is written, then frame 1 fails.
    std::fs::create_dir(d.join("r_001.png")).unwrap();
    let render = [
        "render",
        "room.glb",
        "--point-light=0,1,0",
        "--frames",
        "3",
        "--device",
        "cpu",
        "--width",
        "32",
        "--height",
        "24",
        "-o",
        "r.png",
    ];
    let error = one_error(&prt_gpu(&render, d), "frames");
    if can_render() {
        assert!(error.contains("r_001.png"), "{error}");
    }
    assert_eq!(entries(d), ["r_001.png", "room.glb", "tet.obj"]);
}

#[test]
fn a_write_error_names_the_output_not_its_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tet.obj"), TET).unwrap();
    // A name that fits the file system's limit of 255 bytes but leaves no room for the
    // temporary's suffix: creating the temporary fails, for root too.
    let long = format!("{}.glb", "o".repeat(250));
    let limit = streaming_limit();
    let cases = [
        bake_args("tet.obj", &["-o", &long]),
        bake_args(BUNNY, &["--memory-limit", &limit, "-o", &long]),
    ];
    for args in &cases {
        let error = one_error(&prt_gpu(args, d), "long name");
        assert!(
            error.starts_with(&format!("error: {long}: ")) && !error.contains(".tmp-"),
            "{error}"
        );
        assert_eq!(entries(d), ["tet.obj"]);
    }

    // Unwritable directory, where the user is not root (root writes anyway).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = d.join("ro");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::write(ro.join("probe"), b"").is_ok() {
            eprintln!("skipped the read-only directory: this user writes into it anyway");
            return;
        }
        let out = prt_gpu(&bake_args("tet.obj", &["-o", "ro/out.glb"]), d);
        let error = one_error(&out, "read-only directory");
        assert!(
            error.starts_with("error: ro/out.glb: ") && !error.contains(".tmp-"),
            "{error}"
        );
    }
}
