//! The command line end to end: a bake, `info`, and every kind of bad input failing cleanly.

mod common;

use common::{assert_clean_failure, prt_gpu, BadInput};
use prt_gpu::testing::entries;
use std::path::Path;

#[test]
fn bakes_the_builtin_scene_and_reports_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(&["bake", "--samples", "64", "-o", "scene.glb"], dir.path());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("vertices") && stdout.contains("rays/s"),
        "{stdout}"
    );
    assert_eq!(entries(dir.path()), ["scene.glb"]);

    let info = prt_gpu(&["info", "scene.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success());
    for expected in [
        "bands:        4",
        "samples:      64",
        "mode:         shadowed",
        "Condon-Shortley",
    ] {
        assert!(text.contains(expected), "info lacks {expected:?}:\n{text}");
    }
    dir.close().unwrap();
}

#[test]
fn a_least_squares_bake_says_so_in_its_report_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "bake",
        "--samples",
        "32",
        "--fit",
        "least-squares",
        "--fit-points",
        "4",
        "-o",
        "ls.glb",
    ];
    let out = prt_gpu(&args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("least-squares fit:") && stderr.contains("surface points"),
        "{stderr}"
    );
    let info = prt_gpu(&["info", "ls.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("fit:          least-squares ("), "{text}");
    // A point bake's file keeps its old form: no fit recorded.
    let out = prt_gpu(&["bake", "--samples", "32", "-o", "p.glb"], dir.path());
    assert!(out.status.success());
    let info = prt_gpu(&["info", "p.glb"], dir.path());
    assert!(String::from_utf8_lossy(&info.stdout).contains("fit:          point\n"));
    // A bounce's line gives the iterations of its own fit's solve, and a point bake's none.
    let bounce_line = |fit: &str| {
        let mut args = vec!["bake", "--samples", "32", "--fit", fit, "--fit-points", "4"];
        args.extend(["--mode", "interreflected", "--bounces", "1", "-o", "b.glb"]);
        let out = prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        let line = stderr.lines().find(|l| l.starts_with("bounce 1:"));
        line.unwrap_or_else(|| panic!("no bounce line: {stderr}"))
            .to_string()
    };
    let fitted = bounce_line("least-squares");
    let iterations: u32 = common::number_after(&fitted, "its fit solved in ", ' ')
        .unwrap_or_else(|| panic!("no fit iterations in {fitted:?}"));
    assert!(iterations > 0, "{fitted}");
    assert!(!bounce_line("point").contains("fit"));
    dir.close().unwrap();
}

#[test]
fn bands_auto_chooses_reports_and_writes_the_choice() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "64",
            "--bands",
            "auto",
            "-o",
            "auto.glb",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let chosen: u32 = stderr
        .lines()
        .find_map(|l| l.strip_prefix("bands auto: "))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no choice reported: {stderr}"));
    assert!((1..=8).contains(&chosen));
    let info = prt_gpu(&["info", "auto.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains(&format!("bands:        {chosen} (")),
        "{text}"
    );
    // A threshold that keeps almost everything keeps more bands.
    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "64",
            "--bands",
            "auto",
            "--bands-threshold",
            "0.001",
            "-o",
            "more.glb",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("bands auto: "), "{stderr}");
    let more: u32 = stderr
        .lines()
        .find_map(|l| l.strip_prefix("bands auto: "))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert!(more >= chosen);
    dir.close().unwrap();
}

#[test]
fn a_non_square_sample_count_is_rounded_and_said() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "50",
            "--sampling",
            "stratified",
            "--mode",
            "unshadowed",
            "-o",
            "a.glb",
        ],
        dir.path(),
    );
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("uses 49"), "{stderr}");
    // Sets without a grid take the count as given.
    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "50",
            "--sampling",
            "fibonacci",
            "--mode",
            "unshadowed",
            "-o",
            "b.glb",
        ],
        dir.path(),
    );
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("50 fibonacci samples"));
    dir.close().unwrap();
}

#[test]
fn a_bake_warns_in_one_line_of_what_it_repaired() {
    let dir = tempfile::tempdir().unwrap();
    // A fan facing +z; a degenerate triangle, the only one to use vertex 7; and a flap beyond
    // edge 2-3 stored with both windings (one of them folded back onto the fan).
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv -1 0 0\nv 0 -1 0\nv 1 1 0\nv 5 5 5\n\
               f 1 2 3\nf 1 3 4\nf 1 4 5\nf 1 5 2\nf 7 7 2\nf 3 2 6\nf 2 3 6\n";
    std::fs::write(dir.path().join("fan.obj"), obj).unwrap();
    let out = prt_gpu(
        &[
            "bake",
            "fan.obj",
            "--samples",
            "16",
            "--device",
            "cpu",
            "-o",
            "fan.glb",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .collect();
    assert_eq!(
        warnings,
        [
            "warning: fan: repaired the mesh: 1 degenerate triangles dropped, \
          1 unreferenced vertices dropped, 1 folded triangles left out of the vertex normals"
        ],
        "{stderr}"
    );
    // A clean mesh bakes without one.
    let out = prt_gpu(&["bake", "--samples", "16", "-o", "scene.glb"], dir.path());
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning:"));
    dir.close().unwrap();
}

/// What a reader repaired (an MTL's Kd out of range) or assumed (a map named for another
/// format) is one `warning:` line; a byte-order mark and trailing comments say nothing.
#[test]
fn readers_warn_in_one_line_of_what_they_repaired() {
    let dir = tempfile::tempdir().unwrap();
    let tetrahedron = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl red # too red\nKd 2 nan -1\n",
    )
    .unwrap();
    let obj = format!("\u{feff}mtllib m.mtl\nusemtl red # the material\n{tetrahedron}");
    std::fs::write(dir.path().join("tet.obj"), obj).unwrap();
    let bake = [
        "bake",
        "tet.obj",
        "--samples",
        "16",
        "--device",
        "cpu",
        "-o",
        "tet.glb",
    ];
    let out = prt_gpu(&bake, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .collect();
    assert_eq!(
        warnings,
        [
            "warning: tet: material \"red\": Kd (2, NaN, -1) is outside [0, 1] or not finite; \
          baked as (1, 0, 0)"
        ],
        "{stderr}"
    );
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 0.5 0.5 0.5\n").unwrap();
    let out = prt_gpu(&bake, dir.path());
    assert!(out.status.success() && !String::from_utf8_lossy(&out.stderr).contains("warning:"));

    image::RgbImage::from_pixel(8, 4, image::Rgb([255, 255, 255]))
        .save_with_format(dir.path().join("sky.exr"), image::ImageFormat::Png)
        .unwrap();
    let out = prt_gpu(&["light", "sky.exr", "-o", "l.json"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(
        stderr.trim_end(),
        "warning: sky.exr: named .exr, but its content is PNG; read as PNG"
    );
    assert!(dir.path().join("l.json").exists());
    dir.close().unwrap();
}

macro_rules! ply_header {
    () => {
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    };
}

#[test]
fn bad_input_fails_with_one_line_and_no_output() {
    let bad_index = concat!(
        ply_header!(),
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"
    );
    let no_faces = concat!(ply_header!(), "end_header\n0 0 0\n1 0 0\n0 1 0\n");
    let cases = [
        BadInput {
            case: "missing",
            file: None,
            args: &["bake", "nope.obj", "-o", "o.glb"],
            expect: "nope.obj",
        },
        BadInput {
            case: "empty",
            file: Some(("e.obj", b"# nothing\n")),
            args: &["bake", "e.obj", "-o", "o.glb"],
            expect: "e.obj",
        },
        BadInput {
            case: "nofaces",
            file: Some(("v.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n")),
            args: &["bake", "v.obj", "-o", "o.glb"],
            expect: "faces",
        },
        BadInput {
            case: "nan",
            file: Some(("n.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")),
            args: &["bake", "n.obj", "-o", "o.glb"],
            expect: "n.obj: invalid mesh: vertex 1",
        },
        BadInput {
            case: "index",
            file: Some(("i.ply", bad_index.as_bytes())),
            args: &["bake", "i.ply", "-o", "o.glb"],
            expect: "i.ply: invalid mesh: triangle 0 refers to vertex 7",
        },
        BadInput {
            case: "plyfaces",
            file: Some(("f.ply", no_faces.as_bytes())),
            args: &["bake", "f.ply", "-o", "o.glb"],
            expect: "faces",
        },
        BadInput {
            case: "bands0",
            file: None,
            args: &["bake", "--bands", "0", "-o", "o.glb"],
            expect: "bands",
        },
        BadInput {
            case: "bands999",
            file: None,
            args: &["bake", "--bands", "999", "-o", "o.glb"],
            expect: "bands",
        },
        BadInput {
            case: "samples0",
            file: None,
            args: &["bake", "--samples", "0", "-o", "o.glb"],
            expect: "samples",
        },
        BadInput {
            case: "samplesbig",
            file: None,
            args: &["bake", "--samples", "4000000000", "-o", "o.glb"],
            expect: "samples",
        },
        BadInput {
            case: "albedo",
            file: None,
            args: &["bake", "--albedo", "2,0,0", "-o", "o.glb"],
            expect: "albedo",
        },
        BadInput {
            case: "outdir",
            file: None,
            args: &["bake", "--samples", "16", "-o", "no/such/dir/o.glb"],
            expect: "no/such/dir",
        },
        BadInput {
            case: "format",
            file: Some(("m.stl", b"solid\n")),
            args: &["bake", "m.stl", "-o", "o.glb"],
            expect: "format",
        },
        BadInput {
            case: "info",
            file: Some(("bad.glb", b"not a glb at all")),
            args: &["info", "bad.glb"],
            expect: "bad.glb",
        },
        BadInput {
            case: "chunk0",
            file: None,
            args: &["bake", "--chunk-vertices", "0", "-o", "o.glb"],
            expect: "chunk-vertices",
        },
        BadInput {
            case: "nolight",
            file: None,
            args: &["light", "-o", "l.json"],
            expect: "environment map",
        },
        BadInput {
            case: "nomap",
            file: None,
            args: &["light", "nope.exr", "-o", "l.json"],
            expect: "nope.exr",
        },
        BadInput {
            case: "badexr",
            file: Some(("cut.exr", b"v/1\x01\x02\x00\x00\x00")),
            args: &["light", "cut.exr", "-o", "l.json"],
            expect: "cut.exr",
        },
        BadInput {
            case: "rendermissing",
            file: None,
            args: &["render", "nope.glb", "-o", "p.png"],
            expect: "nope.glb",
        },
        BadInput {
            case: "adapter",
            file: None,
            args: &[
                "bake",
                "--device",
                "gpu",
                "--adapter",
                "no-such-adapter-xyz",
                "-o",
                "o.glb",
            ],
            expect: "no-such-adapter-xyz",
        },
        BadInput {
            case: "fit-points",
            file: None,
            args: &[
                "bake",
                "--fit",
                "least-squares",
                "--fit-points",
                "0",
                "-o",
                "o.glb",
            ],
            expect: "--fit-points 0",
        },
        BadInput {
            case: "bands-auto-bench",
            file: None,
            args: &["bench", "--bands", "auto"],
            expect: "--bands auto",
        },
        BadInput {
            case: "bands-word",
            file: None,
            args: &["bake", "--bands", "many", "-o", "o.glb"],
            expect: "many",
        },
        BadInput {
            case: "fit",
            file: None,
            args: &["bake", "--fit", "cubic", "-o", "o.glb"],
            expect: "cubic",
        },
        BadInput {
            case: "chart-format",
            file: None,
            args: &["chart", "-o", "chart.txt"],
            expect: "chart.txt: charts must end in .svg or .png",
        },
        BadInput {
            case: "chart-samples",
            file: None,
            args: &["chart", "--samples", "64,0", "-o", "c.svg"],
            expect: "--samples",
        },
        BadInput {
            case: "chart-sampling",
            file: None,
            args: &["chart", "--sampling", "random", "-o", "c.svg"],
            expect: "random",
        },
        BadInput {
            case: "bench-repeats",
            file: None,
            args: &["bench", "--repeats", "0"],
            expect: "--repeats",
        },
        BadInput {
            case: "bench-mesh",
            file: None,
            args: &["bench", "nope.obj"],
            expect: "nope.obj",
        },
    ];
    for input in &cases {
        assert_clean_failure(input);
    }
}

#[test]
fn light_projects_a_real_map_and_refuses_a_wrong_forced_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let studio = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/studio.exr");
    let out = prt_gpu(
        &[
            "light",
            studio,
            "--bands",
            "3",
            "--window",
            "non-negative",
            "-o",
            "l.json",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("l.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["bands"], 3);
    assert_eq!(json["coeffs"].as_array().unwrap().len(), 9);

    // A 2:1 map forced to be an angular probe is refused, and nothing is written.
    let out = prt_gpu(
        &["light", studio, "--mapping", "angular", "-o", "a.json"],
        dir.path(),
    );
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("error:") && !stderr.contains("panicked"),
        "{stderr}"
    );
    assert!(!dir.path().join("a.json").exists());

    // Six white faces (sRGB 255 = linear 1): a constant unit light, DC sqrt(4 pi) alone.
    let names = ["px.png", "nx.png", "py.png", "ny.png", "pz.png", "nz.png"];
    for name in names {
        image::RgbImage::from_pixel(8, 8, image::Rgb([255, 255, 255]))
            .save(dir.path().join(name))
            .unwrap();
    }
    let faces = names.join(",");
    let out = prt_gpu(
        &["light", "--faces", &faces, "--bands", "2", "-o", "c.json"],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("c.json")).unwrap()).unwrap();
    let coeffs = json["coeffs"].as_array().unwrap();
    let dc = coeffs[0][0].as_f64().unwrap();
    assert!(
        (dc - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-5,
        "DC {dc}"
    );
    for (k, c) in coeffs.iter().enumerate().skip(1) {
        assert!(
            c[0].as_f64().unwrap().abs() < 1e-6,
            "coefficient {k} of a constant light"
        );
    }
    let out = prt_gpu(
        &["light", "--faces", "px.png,nx.png", "-o", "d.json"],
        dir.path(),
    );
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("six"));
    dir.close().unwrap();
}

#[test]
fn bake_then_render_side_by_side() {
    if prt_gpu::device::list_adapters().is_empty() {
        assert!(
            !prt_gpu::device::adapter_required(),
            "no GPU adapter under CI"
        );
        eprintln!("skipping: no adapter to render with");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for mode in ["unshadowed", "shadowed"] {
        let out = prt_gpu(
            &[
                "bake",
                "--samples",
                "64",
                "--mode",
                mode,
                "-o",
                &format!("{mode}.glb"),
            ],
            dir.path(),
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let studio = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/studio.exr");
    let out = prt_gpu(
        &[
            "render",
            "unshadowed.glb",
            "shadowed.glb",
            "--light",
            studio,
            "--width",
            "160",
            "--height",
            "120",
            "-o",
            "side.png",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let image = image::open(dir.path().join("side.png")).unwrap().to_rgba8();
    assert_eq!(image.dimensions(), (320, 120));
    // The scene fills the middle of each panel and leaves the corners empty (transparent).
    for panel in 0..2 {
        assert!(
            image.get_pixel(panel * 160 + 80, 75)[3] == 255,
            "panel {panel} centre is empty"
        );
        assert_eq!(
            image.get_pixel(panel * 160 + 1, 1)[3],
            0,
            "panel {panel} corner is covered"
        );
    }
    // With the sky behind it, the corners show the light: opaque, and the light's colour.
    let out = prt_gpu(
        &[
            "render",
            "shadowed.glb",
            "--light",
            studio,
            "--sky",
            "--width",
            "160",
            "--height",
            "120",
            "-o",
            "sky.exr",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sky = prt_gpu::testing::read_exr_rgba(&dir.path().join("sky.exr")).1;
    let light = prt_gpu::light::load(std::path::Path::new(studio), 4, None, false).unwrap();
    let camera = prt_gpu::render::Camera::framing_scene(
        &prt_gpu::glb::read_glb(&dir.path().join("shadowed.glb"))
            .unwrap()
            .scene,
    );
    let expected = prt_gpu::render::sky_radiance(
        &light.light,
        prt_gpu::render::pixel_ray(&camera, 160, 120, 1, 1),
    );
    let corner = sky[160 + 1];
    assert_eq!(corner[3], 1.0);
    for c in 0..3 {
        assert!(
            (corner[c] - expected[c]).abs() <= 1e-4 * expected[c].max(1.0),
            "{corner:?} vs {expected:?}"
        );
    }

    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "16",
            "--preview",
            "p.png",
            "-o",
            "p.glb",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        image::open(dir.path().join("p.png"))
            .unwrap()
            .to_rgba8()
            .dimensions(),
        (640, 480)
    );
    dir.close().unwrap();
}

/// The CSV's data rows (after the header), split into fields.
fn csv_rows(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("sampling,fit,backend,samples,seconds,rays,transfer_rms,radiance_rms,surface_rms,surface_seen_rms,target_error")
    );
    lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn chart_at_default_settings_writes_one_csv_row_per_point() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(&["chart", "--device", "cpu", "-o", "chart.svg"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Printed, not asserted (timings never are): the issue asks for under a minute.
    println!("{}", String::from_utf8_lossy(&out.stdout));
    assert_eq!(entries(dir.path()), ["chart.csv", "chart.svg"]);
    let rows = csv_rows(&dir.path().join("chart.csv"));
    // Five strategies, two fits, three counts, one backend.
    assert_eq!(rows.len(), 5 * 2 * 3);
    for row in &rows {
        assert_eq!(row[2], "cpu");
        let seconds: f64 = row[4].parse().unwrap();
        let errors: Vec<f64> = row[6..10].iter().map(|e| e.parse().unwrap()).collect();
        assert!(seconds > 0.0 && errors.iter().all(|&e| e > 0.0), "{row:?}");
    }
    assert_eq!(rows.iter().filter(|r| r[1] == "least-squares").count(), 15);
    // More samples, less error, for the low-discrepancy set (one line of the chart).
    let fibonacci: Vec<f64> = rows
        .iter()
        .filter(|r| r[0] == "fibonacci" && r[1] == "point")
        .map(|r| r[6].parse().unwrap())
        .collect();
    assert!(fibonacci.windows(2).all(|w| w[1] < w[0]), "{fibonacci:?}");
    let svg = std::fs::read_to_string(dir.path().join("chart.svg")).unwrap();
    assert!(svg.contains("control-variate cpu") && svg.contains("1024"));
    assert!(svg.contains("cosine least-squares cpu") && svg.contains("over the surface"));
    dir.close().unwrap();
}

#[test]
fn chart_runs_each_backend_and_draws_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(
        &[
            "chart",
            "--device",
            "gpu",
            "--samples",
            "16,64",
            "--sampling",
            "stratified,cosine",
            "--reference-samples",
            "1024",
            "--fit",
            "point,least-squares",
            "-o",
            "small.png",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() && stderr.contains("gpu:") && std::env::var_os("CI").is_none() {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return;
    }
    assert!(out.status.success(), "{stderr}");
    let rows = csv_rows(&dir.path().join("small.csv"));
    assert_eq!(rows.len(), 2 * 2 * 2 * 2, "{rows:?}");
    for backend in ["cpu", "gpu"] {
        assert_eq!(rows.iter().filter(|r| r[2] == backend).count(), 8);
    }
    // Both backends bake the same estimates: their errors, at the vertices and over the
    // surface, agree closely point for point.
    for cpu in rows.iter().filter(|r| r[2] == "cpu") {
        let gpu = rows
            .iter()
            .find(|r| r[2] == "gpu" && r[0] == cpu[0] && r[1] == cpu[1] && r[3] == cpu[3])
            .unwrap();
        for column in [6, 8, 9] {
            let (c, g): (f64, f64) = (cpu[column].parse().unwrap(), gpu[column].parse().unwrap());
            assert!((c - g).abs() <= 0.02 * c, "{cpu:?} vs {gpu:?}");
        }
    }
    let png = image::open(dir.path().join("small.png")).unwrap();
    assert!(png.width() > 400 && png.height() > 200);
    dir.close().unwrap();
}

#[test]
fn bench_times_both_backends_and_names_the_adapter() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(
        &["bench", "--samples", "64", "--repeats", "1", "--ray-sets"],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("cpu (") && stdout.contains("M rays/s"),
        "{stdout}"
    );
    // Both ray sets, on every backend, and where a GPU ran, its answers are the CPU's.
    let set_lines: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("shadow (any hit)") || l.starts_with("diffuse (closest hit)"))
        .collect();
    assert_eq!(set_lines.len(), 2, "{stdout}");
    if std::env::var_os("CI").is_some() {
        assert!(
            stdout.contains("gpu (") && stdout.contains("gpu / cpu"),
            "{stdout}"
        );
        for line in set_lines {
            assert!(line.ends_with("rays whose gpu answer differs: 0"), "{line}");
        }
    }
    assert!(entries(dir.path()).is_empty(), "bench writes no files");
    dir.close().unwrap();
}

/// A reader of stdout that stops early (`prt-gpu bake | head -0`) ends the report quietly, not
/// with a panic: the bake's file is still written and the exit is clean.
#[test]
fn a_closed_stdout_ends_the_report_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let teapot = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/teapot.obj");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_prt-gpu"))
        .args([
            "bake",
            teapot,
            "--device",
            "cpu",
            "--samples",
            "64",
            "-o",
            "t.glb",
        ])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The summary line comes at the end; its reader is gone long before.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(dir.path().join("t.glb").exists());
}
