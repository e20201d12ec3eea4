//! Per-texel transfer end to end: `bake --lightmap` writes a .glb with lightmap coordinates and
//! an OpenEXR lightmap beside it; both are read back by independent readers (the Khronos glTF
//! validator, the README's Python/OpenEXR recipe) and by our own; every texel a bilinear lookup
//! can reach is baked or filled; `render` draws it; bad requests fail cleanly.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::pixels::Difference;
use common::prt_gpu;
use glam::Vec3;
use prt_gpu::bake::texels::{bake_texels, plan_atlas};
use prt_gpu::bake::{bake, BakeOptions, CpuBackend, Fit, NoProgress};
use prt_gpu::glb::{lightmap_file_name, read_glb, Stored};
use prt_gpu::lightmap::read_lightmap;
use prt_gpu::receivers::uv_set::UvSet;
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::testing::{entries, lightmap_reader_output};

fn succeeded(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A plane with a thin wall standing on it (its foot inside the wall: texels that leak).
fn plane_with_wall() -> Scene {
    let plane = builtin::grid_plane(Vec3::ZERO, Vec3::X * 2.0, Vec3::NEG_Z * 2.0, 4, Vec3::ONE);
    let wall = builtin::closed_box(Vec3::new(-0.9, -0.1, -0.05), Vec3::new(0.9, 0.8, 0.05), 2);
    builtin::merge(&[plane, wall])
}

#[test]
fn a_lightmap_bake_writes_files_other_readers_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "64",
            "--lightmap",
            "512",
            "--device",
            "cpu",
            "-o",
            "scene.prt.glb",
        ],
        dir.path(),
    );
    succeeded(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("lightmap: ") && stderr.contains("covered"),
        "{stderr}"
    );
    assert_eq!(
        entries(dir.path()),
        ["scene.prt.glb", "scene.prt.lightmap.exr"]
    );
    let glb = dir.path().join("scene.prt.glb");
    assert_eq!(lightmap_file_name(&glb), "scene.prt.lightmap.exr");

    if let Some(report) = common::validate_gltf(&glb) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
    }
    let baked = read_glb(&glb).unwrap();
    let texels = baked.lightmap.as_ref().expect("the lightmap is read back");
    assert!(texels.width.max(texels.height) <= 512 && texels.width.max(texels.height) >= 480);
    // Coordinates per triangle corner; the file holds them per vertex, the mesh split only
    // where its charts meet (a vertex on a seam once per chart), so every vertex's corners
    // agree and there are fewer vertices than corners.
    assert_eq!(texels.texcoords.len(), 3 * baked.scene.triangle_count());
    assert!(texels.vertex_texcoords(&baked.scene).is_some());
    assert!(baked.scene.vertex_count() < 3 * baked.scene.triangle_count());
    assert!(texels
        .texcoords
        .iter()
        .flatten()
        .all(|&x| (0.0..=1.0).contains(&x)));

    // The README's recipe (Python, numpy, OpenEXR) reads what our reader reads.
    if let Some(read) = lightmap_reader_output(&glb) {
        let (w, h) = (texels.width as usize, texels.height as usize);
        let k = (baked.metadata.bands * baked.metadata.bands) as usize;
        assert_eq!(
            read["uv"],
            serde_json::json!([baked.scene.vertex_count(), 2])
        );
        assert_eq!(read["texels"], serde_json::json!([h, w, 3, k]));
        let centre = (h / 2) * w + w / 2;
        for c in 0..3 {
            let ours = texels.transfer.vertex_channel(centre, c);
            for (i, &x) in ours.iter().enumerate() {
                let theirs = read["centre"][c][i].as_f64().unwrap();
                // JSON prints the f32 to within a unit of its last decimal digit.
                let close = (theirs - x as f64).abs() <= 1e-6 * (x as f64).abs().max(1e-30);
                assert!(
                    close,
                    "texel {centre}, channel {c}, k = {i}: {theirs} vs {x}"
                );
            }
        }
    }
    let info = prt_gpu(&["info", "scene.prt.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    let expected = format!(
        "lightmap:     {}x{} texels in scene.prt.lightmap.exr (TEXCOORD_0)",
        texels.width, texels.height
    );
    assert!(text.contains(&expected), "{text}");
    // The .exr on its own, through our reader, matches the .glb's description.
    let map = read_lightmap(&dir.path().join("scene.prt.lightmap.exr")).unwrap();
    assert_eq!((map.width, map.height), (texels.width, texels.height));
    dir.close().unwrap();
}

/// The texels a lookup reads around any point of any triangle: bilinear filtering's 2x2 and
/// bicubic's 4x4 (Bevy and Godot offer bicubic lightmap filtering), all baked or filled by
/// dilation.
#[test]
fn every_texel_a_bilinear_or_bicubic_lookup_reaches_is_baked_or_filled() {
    let (scene, _) = prt_gpu::scene::prepare::prepare(plane_with_wall()).unwrap();
    let options = BakeOptions {
        samples: 64,
        ..BakeOptions::default()
    };
    let (baked, _) = bake(scene.clone(), &options, &CpuBackend, &NoProgress).unwrap();
    let (texels, report) = bake_texels(
        &baked.scene,
        &baked.transfer,
        &options,
        96,
        &CpuBackend,
        &NoProgress,
    )
    .unwrap();
    assert!(
        report.leaking > 0,
        "the wall's foot should leak: {report:?}"
    );
    let (w, h) = (texels.width as i64, texels.height as i64);
    let stride = 3 * 16;
    // Every texel within the 4x4 footprint (which holds the 2x2) of any point of any
    // triangle: the sixteen texels around each corner and around points along its edges.
    let dc = |x: i64, y: i64| texels.transfer.coeffs()[((y * w + x) as usize) * stride];
    let mut checked = 0;
    for corners in texels.texcoords.chunks(3) {
        for i in 0..3 {
            for step in 0..8 {
                let s = step as f32 / 8.0;
                let (a, b) = (corners[i], corners[(i + 1) % 3]);
                let u = (a[0] + (b[0] - a[0]) * s) * w as f32 - 0.5;
                let v = (a[1] + (b[1] - a[1]) * s) * h as f32 - 0.5;
                for (dx, dy) in (-1..=2).flat_map(|dy| (-1..=2).map(move |dx| (dx, dy))) {
                    let x = (u.floor() as i64 + dx).clamp(0, w - 1);
                    let y = (v.floor() as i64 + dy).clamp(0, h - 1);
                    // Open sky above every receiver of this scene: the DC term is positive.
                    assert!(dc(x, y) > 0.0, "texel ({x}, {y}) is empty");
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 4000);
}

#[test]
fn a_lightmap_renders_like_the_vertices_where_transfer_is_smooth() {
    let Some(_) = common::gpu_baker() else {
        return;
    };
    // An open plane: transfer constant over it, so texels and vertices must render alike.
    let dir = tempfile::tempdir().unwrap();
    let plane = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::NEG_Z, 3, Vec3::splat(0.6));
    let options = BakeOptions {
        samples: 64,
        mode: prt_gpu::bake::Mode::Unshadowed,
        ..BakeOptions::default()
    };
    for (name, lightmap) in [("v.glb", None), ("t.glb", Some(32))] {
        let options = BakeOptions {
            lightmap,
            ..options.clone()
        };
        let (baked, _) = bake(plane.clone(), &options, &CpuBackend, &NoProgress).unwrap();
        prt_gpu::glb::write_glb(&dir.path().join(name), Stored::plain(&baked).unwrap()).unwrap();
    }
    let out = prt_gpu(
        &[
            "render", "v.glb", "t.glb", "--width", "64", "--height", "48", "-o", "both.exr",
        ],
        dir.path(),
    );
    succeeded(&out);
    let pixels = prt_gpu::testing::read_exr_rgba(&dir.path().join("both.exr")).1;
    let mut compared = 0;
    for y in 0..48 {
        for x in 0..64 {
            let (a, b) = (pixels[y * 128 + x], pixels[y * 128 + 64 + x]);
            assert_eq!(a[3], b[3], "coverage differs at ({x}, {y})");
            if a[3] == 1.0 {
                for c in 0..3 {
                    // Half-float texels: three significant digits.
                    assert!(
                        (a[c] - b[c]).abs() <= 2e-3 * a[c].abs(),
                        "({x}, {y}): {a:?} {b:?}"
                    );
                }
                compared += 1;
            }
        }
    }
    assert!(compared > 300, "{compared} pixels covered");
}

#[test]
fn bad_lightmap_requests_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    for (args, expect) in [
        (
            vec!["bake", "--lightmap", "0", "-o", "o.glb"],
            "--lightmap 0 is out of range",
        ),
        (
            vec!["bake", "--lightmap", "99999", "-o", "o.glb"],
            "--lightmap 99999 is out of range",
        ),
        (
            vec!["bake", "--lightmap", "16", "--device", "cpu", "-o", "o.glb"],
            "a lightmap of 16 texels a side is too small for the 21 charts of 12544 triangles",
        ),
        (
            vec![
                "bake",
                concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/tests/data/gltf/BoxTextured.glb"
                ),
                "--lightmap",
                "64",
                "-o",
                "o.glb",
            ],
            "no usable UV set (no TEXCOORD_1; TEXCOORD_0 leaves [0, 1]",
        ),
        (
            vec!["bake", "--denoise", "-o", "o.glb"],
            "--denoise filters a lightmap's texels; ask for one with --lightmap SIZE",
        ),
        (
            vec![
                "bake",
                "--lightmap",
                "64",
                "--denoise",
                "--sampling",
                "fibonacci",
                "-o",
                "o.glb",
            ],
            "--sampling fibonacci shares one set among all",
        ),
    ] {
        let out = prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(entries(dir.path()).is_empty(), "{args:?} left files");
    }
    // A lightmapped file whose lightmap is gone: one line naming what is missing.
    let out = prt_gpu(
        &[
            "bake",
            "--samples",
            "16",
            "--lightmap",
            "512",
            "-o",
            "m.glb",
        ],
        dir.path(),
    );
    succeeded(&out);
    std::fs::remove_file(dir.path().join("m.lightmap.exr")).unwrap();
    let out = prt_gpu(&["render", "m.glb", "-o", "m.png"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("m.lightmap.exr"), "{stderr}");
    dir.close().unwrap();
}

/// three.js, installed by ci/test.sh (npm ci in ci/three): its module build and its addons;
/// `None` with a printed reason where it is missing, except under CI: a panic.
fn three_or_skip() -> Option<(PathBuf, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("ci/three/node_modules/three");
    let (module, addons) = (
        root.join("build/three.module.js"),
        root.join("examples/jsm/"),
    );
    if module.is_file() && addons.is_dir() {
        return Some((module, addons));
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "three.js is missing under CI (ci/test.sh installs it)"
    );
    eprintln!("skipping: three.js is not installed (npm ci --prefix ci/three)");
    None
}

/// A relit lightmap for engines (`render --light ... -o relit.glb` on a lightmapped bake): the
/// texels relit, as an RGB OpenEXR image beside the copy, which names it. OpenEXR's own reader
/// reads the texels `render` relights; three.js loads the copy with its glTF loader and the
/// image with its EXR loader, draws it with a stock MeshBasicMaterial and a light map, and
/// the screenshot matches `prt-gpu render` of the bake within the web viewer's tolerance.
#[test]
fn a_relit_lightmap_loads_in_three_js_and_matches_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let teapot = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/teapot.obj");
    let run = |args: &[&str]| succeeded(&prt_gpu(args, d));
    run(&[
        "bake",
        teapot,
        "--samples",
        "128",
        "--lightmap",
        "128",
        "-o",
        "lm.glb",
    ]);
    common::write_light(d, "light.json", 4, &[]);
    run(&[
        "render",
        "lm.glb",
        "--light",
        "light.json",
        "-o",
        "relit.glb",
    ]);
    assert!(d.join("relit.radiance.exr").is_file());
    let baked = read_glb(&d.join("lm.glb")).unwrap();
    let texels = baked.lightmap.as_ref().unwrap();
    let sh = prt_gpu::light::read_json(&d.join("light.json")).unwrap();
    let expected = prt_gpu::render::relight(&texels.transfer, &sh).unwrap();

    // The copy names the image; OpenEXR reads the relit texels back.
    let relit = read_glb(&d.join("relit.glb")).unwrap();
    assert_eq!(relit.scene.positions, baked.scene.positions);
    if let Some(report) = common::validate_gltf(&d.join("relit.glb")) {
        // Not a hint either: the radiance's view is vertex data, and says so.
        let said = report.num_errors + report.num_warnings + report.num_hints;
        assert_eq!(said, 0, "{}", report.listing());
    }
    if prt_gpu::testing::python_with(&["numpy", "OpenEXR"]) {
        let read = prt_gpu::testing::python_json(RELIT_LIGHTMAP_READER, &d.join("relit.glb"));
        let size: [u32; 2] = serde_json::from_value(read["size"].clone()).unwrap();
        assert_eq!(size, [texels.width, texels.height]);
        let rgb: Vec<[f32; 3]> = serde_json::from_value(read["rgb"].clone()).unwrap();
        assert_eq!(rgb, expected, "the image holds the texels render relights");
        assert_eq!(read["alpha"], 1.0);
    }

    // three.js draws it as render does.
    let Some(chromium) = prt_gpu::testing::Chromium::find_or_skip() else {
        return;
    };
    let Some(three) = three_or_skip() else {
        return;
    };
    let difference = three_against_render(&chromium, &three, d, ("lm.glb", "relit.glb"));
    println!("three.js against render, the teapot: {difference:?}");
    assert!(difference.within_tolerance(), "{difference:?}");

    // A glTF scene baked in place on its own TEXCOORD_1, with base colours: its relit
    // lightmap holds the shading they multiply.
    let scene = common::gltf_builder::ground_and_card_gltf(d, Some(1), true, false);
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&scene).unwrap()).unwrap();
    doc["materials"] = serde_json::json!([
        { "pbrMetallicRoughness": { "baseColorFactor": [0.7, 0.6, 0.5, 1.0] } },
        { "pbrMetallicRoughness": { "baseColorFactor": [0.3, 0.5, 0.8, 1.0] } },
    ]);
    for (mesh, material) in [(0, 0), (1, 1)] {
        for primitive in doc["meshes"][mesh]["primitives"].as_array_mut().unwrap() {
            primitive["material"] = serde_json::json!(material);
        }
    }
    std::fs::write(&scene, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = scene.to_str().unwrap();
    run(&[
        "bake",
        scene,
        "--samples",
        "128",
        "--lightmap",
        "64",
        "-o",
        "scene.glb",
    ]);
    run(&[
        "render",
        "scene.glb",
        "--light",
        "light.json",
        "-o",
        "scene_relit.glb",
    ]);
    assert!(d.join("scene_relit.radiance.exr").is_file());
    if let Some(report) = common::validate_gltf(&d.join("scene_relit.glb")) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
    }
    let difference = three_against_render(&chromium, &three, d, ("scene.glb", "scene_relit.glb"));
    println!("three.js against render, a glTF scene: {difference:?}");
    assert!(difference.within_tolerance(), "{difference:?}");
}

/// three.js' screenshot of the relit copy `relit` (tests/data/three_lightmap_page.html)
/// against `prt-gpu render` of the bake `baked` it was relit from, at 320x240 from a camera
/// turned off render's framing.
fn three_against_render(
    chromium: &prt_gpu::testing::Chromium,
    (three, addons): &(PathBuf, PathBuf),
    d: &Path,
    (baked, relit): (&str, &str),
) -> common::pixels::Difference {
    // The loaders finish after the page's load event; virtual time lets them.
    let chromium = chromium.after_virtual_time(30_000);
    let (width, height) = (320u32, 240u32);
    let read = read_glb(&d.join(baked)).unwrap();
    let texels = read.lightmap.as_ref().unwrap();
    let mut camera = prt_gpu::render::Camera::framing_scene(&read.scene);
    camera.eye = camera.target + glam::Quat::from_rotation_y(0.7) * (camera.eye - camera.target);
    let distance = camera.eye.distance(camera.target);
    let page = include_str!("data/three_lightmap_page.html")
        .replace("{{THREE}}", &format!("file://{}", three.display()))
        .replace("{{ADDONS}}", &format!("file://{}", addons.display()))
        .replace("{{GLB}}", relit)
        .replace("{{WIDTH}}", &width.to_string())
        .replace("{{HEIGHT}}", &height.to_string())
        .replace(
            "{{CAMERA}}",
            &serde_json::json!({
                "eye": camera.eye.to_array(),
                "target": camera.target.to_array(),
                "up": [0.0, 1.0, 0.0],
                "fov": camera.vertical_fov_deg,
                "near": 0.01 * distance,
                "far": 10.0 * distance,
            })
            .to_string(),
        );
    let page_path = d.join(format!("{relit}.html"));
    std::fs::write(&page_path, page).unwrap();
    let url = format!("file://{}", page_path.display());
    let dom = chromium.dump_dom(&url);
    let report = prt_gpu::testing::report_element(&dom).unwrap_or("");
    let report: serde_json::Value = serde_json::from_str(report).unwrap_or_default();
    assert!(
        report["error"].is_null() && report["meshes"].as_u64() > Some(0),
        "{report}"
    );
    assert_eq!(
        report["lightmap"],
        serde_json::json!([texels.width, texels.height])
    );
    let (e, t) = (camera.eye, camera.target);
    let cam = format!(
        "{},{},{},{},{},{},{}",
        e.x, e.y, e.z, t.x, t.y, t.z, camera.vertical_fov_deg
    );
    let (w, h) = (width.to_string(), height.to_string());
    let args = [
        "render",
        baked,
        "--light",
        "light.json",
        "--camera",
        &cam,
        "--width",
        &w,
        "--height",
        &h,
        "-o",
        "render.png",
    ];
    succeeded(&prt_gpu(&args, d));
    let expected = image::open(d.join("render.png")).unwrap().into_rgb8();
    assert!(common::pixels::has_contrast(&expected));
    let shot = chromium.screenshot(&url, width, height);
    Difference::of(&shot, &expected)
}

/// Reads a relit copy's lightmap (`extras.prt.relit.lightmap`) with OpenEXR's Python binding:
/// its size, alpha and the RGB of every texel, row by row.
const RELIT_LIGHTMAP_READER: &str = r#"import json, pathlib, struct, sys, numpy as np, OpenEXR
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]
lightmap = json.loads(data[20:20 + n])["meshes"][0]["extras"]["prt"]["relit"]["lightmap"]
exr = OpenEXR.File(str(pathlib.Path(sys.argv[1]).with_name(lightmap["uri"])), separate_channels=True)
channels = exr.parts[0].channels
rgb = np.stack([channels[c].pixels for c in "RGB"], -1).astype(np.float32)
H, W = rgb.shape[:2]
alpha = channels["A"].pixels
print(json.dumps({"size": [W, H], "alpha": float(alpha.min()) if alpha.min() == alpha.max() else None, "rgb": rgb.reshape(-1, 3).tolist()}))
"#;

/// A latitude-longitude sphere of `rings` x `segments` cells (poles as fans).
fn uv_sphere(rings: u32, segments: u32) -> Scene {
    let mut positions = vec![Vec3::Y];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ));
        }
    }
    positions.push(Vec3::NEG_Y);
    let at = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let south = positions.len() as u32 - 1;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(1, s), at(1, s + 1)]);
        triangles.push([south, at(rings - 1, s + 1), at(rings - 1, s)]);
        for r in 1..rings - 1 {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
            triangles.push([a, c, b]);
            triangles.push([b, c, d]);
        }
    }
    Scene {
        albedo: vec![Vec3::splat(0.8); positions.len()],
        positions,
        normals: None,
        triangles,
    }
}

/// A latitude-longitude sphere of `rings` x `segments` cells whose vertices are written once
/// per texture coordinate, as a glTF file holds them (the meridian at u = 0 twice, each pole
/// once per segment), with its normals, and the coordinates (u along the segments, v down
/// the rings, a texel's margin inside [0, 1]).
fn uv_mapped_sphere(rings: u32, segments: u32) -> (Scene, Vec<[f32; 2]>) {
    let (mut positions, mut uvs) = (Vec::new(), Vec::new());
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        // The poles exactly on the axis, so that their copies lie at one point.
        let (radius, height) = match r {
            0 => (0.0, 1.0),
            r if r == rings => (0.0, -1.0),
            _ => (theta.sin(), theta.cos()),
        };
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * (s % segments) as f32 / segments as f32;
            positions.push(Vec3::new(radius * phi.cos(), height, -radius * phi.sin()));
            let margin = 1.0 / 128.0;
            let along = |i: u32, n: u32| margin + (1.0 - 2.0 * margin) * i as f32 / n as f32;
            uvs.push([along(s, segments), along(r, rings)]);
        }
    }
    let at = |r: u32, s: u32| r * (segments + 1) + s;
    let mut triangles = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
            if r > 0 {
                triangles.push([a, c, b]);
            }
            if r + 1 < rings {
                triangles.push([b, c, d]);
            }
        }
    }
    let scene = Scene {
        albedo: vec![Vec3::splat(0.8); positions.len()],
        normals: Some(positions.clone()),
        positions,
        triangles,
    };
    (scene, uvs)
}

/// The seams' disagreement and the texels' noise, each as an RMS over the seams' lookup points
/// relative to the RMS radiance there: `(stitched, unstitched, noise)`, radiance under a fixed
/// SH light; the texels made as `fit` says.
fn seam_figures(
    input: &Scene,
    atlas_of: impl Fn(&Scene) -> prt_gpu::receivers::atlas::Atlas,
    samples: u32,
    fit: Fit,
) -> (f64, f64, f64, usize) {
    use prt_gpu::bake::texels::{bake_atlas_with_seams, Seams};
    use prt_gpu::receivers::seams::seams;
    use prt_gpu::receivers::texels::bilinear_taps;
    let options = |seed| BakeOptions {
        samples,
        seed,
        fit,
        ..BakeOptions::default()
    };
    let (baked, _) = bake(input.clone(), &options(1), &CpuBackend, &NoProgress).unwrap();
    let scene = baked.scene.clone();
    let atlas = atlas_of(&scene);
    let found = seams(&scene, &atlas);
    assert!(found.len() > 20, "{} seam edges", found.len());
    let light: Vec<f32> = (0..16)
        .map(|k| [1.0, 0.7, 0.9, -0.4][k % 4] / (1 + k / 4) as f32)
        .collect();
    let radiance_at = |seed: u64, stitched: bool| -> Vec<(f64, f64)> {
        let stitching = if stitched {
            Seams::Stitched
        } else {
            Seams::AsBaked
        };
        let at = (&scene, &baked.transfer, &atlas);
        let (texels, _) =
            bake_atlas_with_seams(at, &options(seed), &CpuBackend, &NoProgress, stitching).unwrap();
        let coeffs = texels.transfer.coeffs();
        let stride = (texels.transfer.channels() * texels.transfer.bands().pow(2)) as usize;
        let k = texels.transfer.bands().pow(2) as usize;
        let radiance = |p: glam::DVec2| -> f64 {
            bilinear_taps(atlas.width, atlas.height, p.as_vec2())
                .iter()
                .map(|&(t, w)| {
                    let channel = &coeffs[t * stride..t * stride + k];
                    w as f64
                        * channel
                            .iter()
                            .zip(&light)
                            .map(|(c, l)| (c * l) as f64)
                            .sum::<f64>()
                })
                .sum()
        };
        found
            .iter()
            .flat_map(|seam| seam.points())
            .map(|(a, b)| (radiance(a), radiance(b)))
            .collect()
    };
    let rms = |values: &mut dyn Iterator<Item = f64>| {
        let (sum, n) = values.fold((0.0, 0), |(s, n), v| (s + v * v, n + 1));
        (sum / n as f64).sqrt()
    };
    let stitched = radiance_at(1, true);
    let scale = rms(&mut stitched.iter().map(|p| p.0));
    let across = |pairs: &[(f64, f64)]| rms(&mut pairs.iter().map(|(a, b)| a - b)) / scale;
    let unstitched = radiance_at(1, false);
    let again = radiance_at(2, false);
    // One lookup's noise: the difference of two seeds over the square root of two.
    let noise = rms(&mut unstitched.iter().zip(&again).map(|(a, b)| a.0 - b.0))
        / std::f64::consts::SQRT_2
        / scale;
    (
        across(&stitched),
        across(&unstitched),
        noise,
        stitched.len(),
    )
}

/// The radiance across every seam edge, looked up on both sides at the same surface points,
/// agrees within the texels' own noise once stitched, and not as baked: across the charts of
/// generated atlases (a UV sphere, the dragon) and across the cut of a scene's own UV set (a
/// sphere written as a glTF file holds it, baked on its coordinates per triangle corner).
#[test]
fn seams_agree_within_the_texels_own_noise() {
    let dragon = prt_gpu::scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/dragon_vrip_res3.ply.gz"
    )))
    .unwrap();
    let generated = |size| move |scene: &Scene| plan_atlas(scene, size).unwrap();
    let (mapped_sphere, uvs) = uv_mapped_sphere(24, 48);
    // Coordinates per triangle corner, as a glTF bake in place keeps them whatever prepare
    // welds (the copies along the cut are identical but for their coordinates).
    let own_set = {
        let set = UvSet::from_vertices(1, &uvs, &mapped_sphere.triangles);
        let kept = prt_gpu::scene::prepare::kept_triangles(&mapped_sphere);
        move |_: &Scene| set.kept(&kept).atlas(128)
    };
    type AtlasOf = Box<dyn Fn(&Scene) -> prt_gpu::receivers::atlas::Atlas>;
    let cases: [(&str, Scene, u32, AtlasOf); 3] = [
        (
            "UV sphere",
            uv_sphere(24, 48),
            128,
            Box::new(generated(128)),
        ),
        ("dragon", dragon, 512, Box::new(generated(512))),
        // Its own UV set, cut along a meridian (the vertices there written twice, as a
        // glTF file holds them) and at the poles.
        (
            "UV sphere on its own UV set",
            mapped_sphere,
            128,
            Box::new(own_set),
        ),
    ];
    for (name, scene, size, atlas_of) in cases {
        // Least-squares texels (`--fit least-squares`), fitted on both sides to points of the
        // same surface, must agree too, their seams pulled together more gently.
        if name != "dragon" {
            let fitted = seam_figures(&scene, &atlas_of, 64, Fit::LeastSquares);
            let (stitched, unstitched, noise, _) = fitted;
            println!(
                "{name} at {size}, least squares: across the seams {:.3}% stitched, {:.3}% \
                 fitted without them; texels' noise {:.3}%",
                100.0 * stitched,
                100.0 * unstitched,
                100.0 * noise
            );
            assert!(
                stitched <= noise,
                "{name}, least squares: {stitched} against the noise {noise}"
            );
        }
        let (stitched, unstitched, noise, points) = seam_figures(&scene, &atlas_of, 64, Fit::Point);
        println!(
            "{name} at {size}: across the seams {:.3}% stitched, {:.3}% as baked; texels' noise \
             {:.3}% ({points} points)",
            100.0 * stitched,
            100.0 * unstitched,
            100.0 * noise
        );
        assert!(
            stitched <= noise,
            "{name}: {stitched} against the noise {noise}"
        );
        assert!(
            unstitched > 2.0 * stitched,
            "{name}: {unstitched} unstitched"
        );
    }
}

/// `--denoise` at equal rays (64 cosine samples, the same vertex bake and atlas), against a
/// high-sample bake of the held-out surface points the chart uses (`prt-gpu chart --denoise`):
/// the denoised lightmap's relit error is lower on the built-in scene (128 texels) and on the
/// teapot (256). At 64 samples the texels' own noise dominates; docs/performance.md charts the
/// counts where the filter's blur costs more than it saves.
#[test]
fn denoising_lowers_the_error_at_equal_rays() {
    use prt_gpu::bake::Backend;
    use prt_gpu::sampling::Sampling;
    use prt_gpu::sweep::{self, SweepOptions};
    let teapot =
        prt_gpu::scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/teapot.obj"))
            .unwrap();
    let light = prt_gpu::light::preview_light(4).unwrap();
    for (name, scene, size) in [
        ("built-in", builtin::default_scene(), 128),
        ("teapot", teapot, 256),
    ] {
        let options = SweepOptions {
            strategies: vec![Sampling::Cosine],
            counts: vec![64],
            reference_samples: 4096,
            fits: vec![Fit::Point],
            surface_points: 4000,
            lightmap_sizes: vec![size],
            denoise: true,
            ..SweepOptions::default()
        };
        let backends: Vec<(String, Box<dyn Backend>)> =
            vec![("cpu".to_string(), Box::new(CpuBackend))];
        let result = sweep::run(&scene, &options, &backends, &light, &NoProgress).unwrap();
        let error = |denoised: bool| {
            let point = result
                .points
                .iter()
                .find(|p| p.lightmap == Some(size) && p.denoised == denoised)
                .unwrap();
            (point.surface_rms, point.rays)
        };
        let ((plain, plain_rays), (denoised, denoised_rays)) = (error(false), error(true));
        eprintln!("{name}: surface error {plain:.4} as baked, {denoised:.4} denoised");
        assert_eq!(plain_rays, denoised_rays, "{name}: not at equal rays");
        assert!(
            denoised < 0.9 * plain,
            "{name}: {plain} as baked, {denoised} denoised"
        );
    }
}

/// Least-squares texels (`--fit least-squares`) bake their points on either backend and are
/// fitted on the CPU: the GPU's map is within 1e-4 of the CPU's RMS (7e-7 when written;
/// the point-sampled map of the same bake, 2e-5), and the CLI writes a map our reader and the
/// glTF validator read, its `lightmap:` line naming the points.
#[test]
fn a_least_squares_lightmap_agrees_on_cpu_and_gpu_and_is_written() {
    let teapot =
        prt_gpu::scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/teapot.obj"))
            .unwrap();
    let options = BakeOptions {
        samples: 64,
        fit: Fit::LeastSquares,
        ..BakeOptions::default()
    };
    let (baked, _) = bake(teapot, &options, &CpuBackend, &NoProgress).unwrap();
    let atlas = plan_atlas(&baked.scene, 96).unwrap();
    let at = (&baked.scene, &baked.transfer, &atlas);
    let map = |backend: &dyn prt_gpu::bake::Backend| {
        let (texels, report) = prt_gpu::bake::texels::bake_atlas_with_seams(
            at,
            &options,
            backend,
            &NoProgress,
            prt_gpu::bake::texels::Seams::Stitched,
        )
        .unwrap();
        assert!(
            report.fit_points.is_some_and(|p| p > report.covered),
            "{report:?}"
        );
        texels.transfer.coeffs().to_vec()
    };
    let cpu = map(&CpuBackend);
    if let Some(baker) = common::gpu_baker() {
        let gpu = map(&prt_gpu::bake::GpuBackend::new(baker));
        let rms = |v: &mut dyn Iterator<Item = f64>| {
            let (sum, n) = v.fold((0.0, 0), |(s, n), x| (s + x * x, n + 1));
            (sum / n as f64).sqrt()
        };
        let scale = rms(&mut cpu.iter().map(|&x| x as f64));
        let difference = rms(&mut cpu.iter().zip(&gpu).map(|(a, b)| (a - b) as f64)) / scale;
        println!("least-squares texels, GPU against CPU: {difference:.2e} of their RMS");
        assert!(difference < 1e-4, "{difference}");
    }
    let dir = tempfile::tempdir().unwrap();
    bake_teapot_with_a_least_squares_lightmap(dir.path(), &["--samples", "32", "--lightmap", "96"]);
    let glb = dir.path().join("teapot.glb");
    if let Some(report) = common::validate_gltf(&glb) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
    }
    let read = read_lightmap(&dir.path().join("teapot.lightmap.exr")).unwrap();
    let baked = read_glb(&glb).unwrap();
    let texels = baked.lightmap.expect("the lightmap is read back");
    assert_eq!((read.width, read.height), (texels.width, texels.height));
    assert!(texels.transfer.coeffs().iter().all(|x| x.is_finite()));
}

/// A least-squares lightmap with a sample set that cannot turn (`--sampling stratified`): its
/// points share the set, as its texels do, and the bake succeeds (it failed after baking the
/// texels, asking for cosine sampling as `--denoise` does).
#[test]
fn a_least_squares_lightmap_bakes_with_a_shared_stratified_set() {
    let dir = tempfile::tempdir().unwrap();
    let options = [
        "--samples",
        "16",
        "--sampling",
        "stratified",
        "--lightmap",
        "48",
    ];
    bake_teapot_with_a_least_squares_lightmap(dir.path(), &options);
    let read = read_lightmap(&dir.path().join("teapot.lightmap.exr")).unwrap();
    assert!(read.width >= 48 || read.height >= 48);
}

/// Bakes the teapot with a least-squares lightmap through the CLI in `dir` (`teapot.glb` and
/// `teapot.lightmap.exr`), with `options` besides, and checks that the bake says it fitted
/// the texels.
fn bake_teapot_with_a_least_squares_lightmap(dir: &Path, options: &[&str]) {
    let teapot = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/teapot.obj");
    let mut args = vec!["bake", teapot, "--fit", "least-squares", "--device", "cpu"];
    args.extend(["-o", "teapot.glb"]);
    args.extend(options);
    let out = prt_gpu(&args, dir);
    succeeded(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("(least squares)"), "{stderr}");
}
