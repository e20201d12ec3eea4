//! Local lights' files and command line: the baked file read back by our reader, by numpy and
//! by the Khronos validator; relit copies (`render -o relit.glb`) for local and distant light;
//! bad input; CPU against GPU.

mod common;

use std::path::Path;

use glam::Vec3;
use prt_gpu::bake::{Backend, CpuBackend, GpuBackend, Mode, NoProgress};
use prt_gpu::glb;
use prt_gpu::local::depth::{DepthLookup, DirectionGrid};
use prt_gpu::local::lights::LocalLight;
use prt_gpu::local::operator::{relative_rms, sparse_indirect};
use prt_gpu::local::{self, LocalBake, LocalInputs, LocalOptions, OperatorForm, Relighter};
use prt_gpu::scene::prepare::prepare;
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::testing;

/// A small closed room with a box and a ball in it.
fn small_room() -> Scene {
    let shell = builtin::seen_from_inside(builtin::closed_box(
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 1.5, 1.0),
        8,
    ));
    let block = builtin::closed_box(Vec3::new(-0.5, 0.0, -0.25), Vec3::new(0.0, 0.5, 0.25), 3);
    let mut ball = builtin::icosphere(Vec3::new(0.5, 0.3, 0.3), 0.25, 2);
    ball.albedo.fill(Vec3::new(0.2, 0.4, 0.8));
    builtin::merge(&[shell, block, ball])
}

fn small_options() -> LocalOptions {
    let mut options = LocalOptions {
        samples: 64,
        grid_side: 8,
        depth_clusters: 4,
        depth_components: 8,
        example_lights: 24,
        ..LocalOptions::default()
    };
    options.operator.clusters = 6;
    options.operator.components = 4;
    options
}

fn small_bake() -> LocalBake {
    local::bake_local(small_room(), &small_options(), &CpuBackend, &NoProgress)
        .unwrap()
        .0
}

#[test]
fn the_local_file_round_trips_and_numpy_reads_it() {
    let bake = small_bake();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.prt.glb");
    glb::local::write_local_glb(&path, &bake).unwrap();
    let back = glb::local::read_local_glb(&path).unwrap();
    assert_eq!(back, bake);
    if let Some(report) = common::validate_gltf(&path) {
        assert_eq!(report.num_errors, 0, "{report:?}");
    }
    let Some(out) = testing::local_reader_output(&path) else {
        return;
    };
    let v = bake.scene.positions.len();
    let depth: Vec<f32> = (0..bake.grid.len())
        .map(|c| bake.depth.depth(v - 1, c))
        .collect();
    let numpy_depth: Vec<f64> = serde_json::from_value(out["last_depth"].clone()).unwrap();
    assert_eq!(numpy_depth.len(), depth.len());
    for (a, b) in numpy_depth.iter().zip(&depth) {
        assert!(
            (a - *b as f64).abs() < 1e-4 * (1.0 + a.abs()),
            "{a} against {b}"
        );
    }
    let sums: Vec<f64> = serde_json::from_value(out["row_sums"].clone()).unwrap();
    for (p, sum) in sums.iter().enumerate() {
        let ours: f64 = bake.matrix.row(p).1.iter().map(|&w| w as f64).sum();
        assert!((sum - ours).abs() < 1e-5, "row {p}: {sum} against {ours}");
    }
    let indirect = bake.operator.indirect(&vec![1.0; v]);
    let numpy_indirect: Vec<[f64; 3]> = serde_json::from_value(out["indirect"].clone()).unwrap();
    for (p, rgb) in numpy_indirect.iter().enumerate() {
        for c in 0..3 {
            let ours = indirect[p][c] as f64;
            assert!(
                (rgb[c] - ours).abs() < 1e-4 * (1.0 + ours.abs()),
                "receiver {p}: {rgb:?} against {}",
                indirect[p]
            );
        }
    }
}

#[test]
fn damaged_local_files_are_one_line_errors() {
    let bake = small_bake();
    let bytes = glb::local::encode_local_glb(&bake).unwrap();
    let path = Path::new("damaged.prt.glb");
    for cut in [10, 100, bytes.len() / 2, bytes.len() - 4] {
        let error = glb::local::decode_local_glb(&bytes[..cut], path).unwrap_err();
        assert!(!error.to_string().contains('\n'), "{error}");
    }
    // A gather column past the vertices.
    let text = String::from_utf8_lossy(&bytes).to_string();
    assert!(text.contains("\"mode\":\"local\""));
    let mut broken = bake.clone();
    broken.matrix.columns[0] = broken.scene.positions.len() as u32 + 5;
    let error = glb::local::decode_local_glb(&glb::local::encode_local_glb(&broken).unwrap(), path)
        .unwrap_err();
    assert!(error.to_string().contains("gather entry"), "{error}");
}

/// COLOR_0 of a .glb, read with Python's struct and json alone.
const COLOR_READER: &str = r#"import json, struct, sys
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
a = gltf["accessors"][gltf["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"]]
v = gltf["bufferViews"][a["bufferView"]]
start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
colors = struct.unpack_from("<%df" % (3 * a["count"]), binary, start)
print(json.dumps({"colors": colors, "relit": gltf["meshes"][0]["extras"]["prt"]["relit"]}))
"#;

/// The radiance a relit copy holds: COLOR_0 times `extras.prt.relit.scale`.
fn relit_colors(path: &Path) -> Option<Vec<f64>> {
    if !testing::python_with(&["json"]) {
        return None;
    }
    let out = testing::python_json(COLOR_READER, path);
    assert!(out["relit"]["color_0"]
        .as_str()
        .unwrap()
        .contains("radiance"));
    let scale = out["relit"]["scale"].as_f64().unwrap();
    assert!(scale >= 1.0);
    let colors: Vec<f64> = serde_json::from_value(out["colors"].clone()).unwrap();
    assert!(colors.iter().all(|c| (0.0..=1.0).contains(c)));
    Some(colors.iter().map(|c| c * scale).collect())
}

fn assert_colors(colors: &[f64], expected: &[[f32; 3]]) {
    assert_eq!(colors.len(), 3 * expected.len());
    for (got, want) in colors.iter().zip(expected.iter().flatten()) {
        let want = want.max(0.0) as f64;
        assert!(
            (got - want).abs() <= 1e-6 * (1.0 + want),
            "{got} against {want}"
        );
    }
}

/// Fails the test with the command's stderr unless it succeeded.
fn succeed(out: std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_relit_local_bake_holds_its_radiance_as_vertex_colours() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.prt.glb");
    glb::local::write_local_glb(&path, &small_bake()).unwrap();
    succeed(common::prt_gpu(
        &[
            "render",
            "room.prt.glb",
            "--point-light=0.3,1.0,-0.4,2",
            "--spot-light=-0.6,1.2,0.5,0,-1,0,40,3",
            "-o",
            "relit.glb",
        ],
        dir.path(),
    ));
    let relit = dir.path().join("relit.glb");
    if let Some(report) = common::validate_gltf(&relit) {
        assert_eq!(report.num_errors, 0, "{report:?}");
    }
    let bake = glb::local::read_local_glb(&path).unwrap();
    let lights = [
        local::lights::parse_point_light("0.3,1.0,-0.4,2").unwrap(),
        local::lights::parse_spot_light("-0.6,1.2,0.5,0,-1,0,40,3").unwrap(),
    ];
    let expected = Relighter::new(&bake)
        .frame(&lights, OperatorForm::Compressed)
        .total();
    assert!(expected.iter().any(|c| c[0] > 0.0));
    if let Some(colors) = relit_colors(&relit) {
        assert_colors(&colors, &expected);
    }
}

#[test]
fn a_relit_distant_bake_holds_its_radiance_as_vertex_colours() {
    let dir = tempfile::tempdir().unwrap();
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
    let bunny = bunny.to_str().unwrap();
    succeed(common::prt_gpu(
        &[
            "bake",
            bunny,
            "--samples",
            "64",
            "--device",
            "cpu",
            "-o",
            "bunny.prt.glb",
        ],
        dir.path(),
    ));
    let out = common::prt_gpu(&["render", "bunny.prt.glb", "-o", "relit.glb"], dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let relit = dir.path().join("relit.glb");
    if let Some(report) = common::validate_gltf(&relit) {
        assert_eq!(report.num_errors, 0, "{report:?}");
    }
    let baked = glb::read_glb(&dir.path().join("bunny.prt.glb")).unwrap();
    let light = prt_gpu::light::preview_light(baked.metadata.bands).unwrap();
    let expected = prt_gpu::render::relight_baked(&baked, &light).unwrap();
    if let Some(colors) = relit_colors(&relit) {
        assert_colors(&colors, &expected);
    }
    // The copy is the baked file in every other respect: the transfer reads back the same.
    let copy = glb::read_glb(&relit).unwrap();
    assert_eq!(copy.transfer, baked.transfer);
}

#[test]
fn bad_local_input_is_one_line_and_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.prt.glb");
    glb::local::write_local_glb(&path, &small_bake()).unwrap();
    let cases: &[&[&str]] = &[
        &["render", "room.prt.glb", "room.prt.glb", "-o", "a.png"],
        &[
            "render",
            "room.prt.glb",
            "--light",
            "light.json",
            "--point-light=0,1,0",
            "-o",
            "a.png",
        ],
        &["render", "room.prt.glb", "-o", "a.png"],
        &["render", "room.prt.glb", "--point-light=1,2", "-o", "a.png"],
        &[
            "render",
            "room.prt.glb",
            "--point-light=0,1,0,-3",
            "-o",
            "a.png",
        ],
        &[
            "render",
            "room.prt.glb",
            "--spot-light=0,1,0,0,0,0,30",
            "-o",
            "a.png",
        ],
        &[
            "render",
            "room.prt.glb",
            "--point-light=0,1,0",
            "--frames",
            "3",
            "-o",
            "a.glb",
        ],
        &[
            "render",
            "room.prt.glb",
            "--point-light=0,1,0",
            "--frames",
            "100000",
            "-o",
            "a.png",
        ],
        &[
            "bake",
            "--mode",
            "local",
            "--compress",
            "8x2",
            "-o",
            "b.glb",
        ],
        &[
            "bake",
            "--mode",
            "local",
            "--depth-grid",
            "1",
            "-o",
            "b.glb",
        ],
        &[
            "bake",
            "--mode",
            "local",
            "--operator-compress",
            "8x0",
            "-o",
            "b.glb",
        ],
    ];
    for args in cases {
        let out = common::prt_gpu(args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("error:"), "{args:?}: {stderr}");
    }
    assert_eq!(
        testing::entries(dir.path()),
        vec!["room.prt.glb".to_string()]
    );
    let info = common::prt_gpu(&["info", "room.prt.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success() && text.contains("mode:         local"),
        "{text}"
    );
    assert!(
        text.contains("operator:     6 clusters x 4 components"),
        "{text}"
    );
}

#[test]
fn frames_write_a_sequence_and_report_their_time() {
    let dir = tempfile::tempdir().unwrap();
    glb::local::write_local_glb(&dir.path().join("room.prt.glb"), &small_bake()).unwrap();
    let out = common::prt_gpu(
        &[
            "render",
            "room.prt.glb",
            "--point-light=0.5,1,0,2",
            "--frames",
            "3",
            "--device",
            "gpu",
            "--width",
            "64",
            "--height",
            "48",
            "--camera=-0.9,1.3,-0.9,0.5,0.3,0.5",
            "-o",
            "seq.png",
        ],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        // Rendering needs an adapter; without one outside CI the command says so.
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            std::env::var_os("CI").is_none() && stderr.contains("adapter"),
            "{stderr}"
        );
        return;
    }
    // The images need an adapter, so the relighting runs on it too: both operators timed there.
    assert!(
        stdout.contains("relighting per frame")
            && stdout.contains("+ compressed operator ")
            && stdout.contains("+ compressed operator on the GPU (")
            && stdout.contains("+ sparse operator on the GPU ("),
        "{stdout}"
    );
    let names = testing::entries(dir.path());
    let mut means = Vec::new();
    for f in ["seq_000.png", "seq_001.png", "seq_002.png"] {
        assert!(names.contains(&f.to_string()), "{names:?}");
        let image = image::open(dir.path().join(f)).unwrap().to_rgba8();
        assert_eq!(image.dimensions(), (64, 48));
        let sum: u64 = image
            .pixels()
            .map(|p| p[0] as u64 + p[1] as u64 + p[2] as u64)
            .sum();
        assert!(sum > 0, "{f} is black");
        means.push(sum);
    }
    // The light moves, so the frames differ.
    assert!(means[0] != means[1] || means[1] != means[2], "{means:?}");
}

#[test]
fn cpu_and_gpu_agree() {
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let gpu = GpuBackend {
        baker,
        chunking: Default::default(),
    };
    let (scene, _) = prepare(small_room()).unwrap();
    let options = small_options();
    let mut inputs = LocalInputs::new(&scene, &options);
    let grid = DirectionGrid { side: 12 };
    let cpu_maps = local::depth_maps(&scene, &mut inputs, grid, &CpuBackend).unwrap();
    let gpu_maps = local::depth_maps(&scene, &mut inputs, grid, &gpu).unwrap();
    let cells = cpu_maps.depths.len();
    let differing = cpu_maps
        .depths
        .iter()
        .zip(&gpu_maps.depths)
        .filter(|(a, b)| (*a - *b).abs() > 1e-4 * (1.0 + a.abs()))
        .count();
    println!("{differing} of {cells} depths differ");
    // Rays that graze an edge may hit the other triangle on the other device: a handful.
    assert!(
        differing as f64 <= 1e-3 * cells as f64,
        "{differing} of {cells}"
    );
    // The gather matrix and the bounces on either device.
    let cpu_pass = CpuBackend
        .direct_pass(&inputs.bake.view(), Mode::Interreflected, &NoProgress)
        .unwrap();
    let bake = local::bake_prepared(scene.clone(), &options, &CpuBackend, &NoProgress)
        .unwrap()
        .0;
    assert_eq!(Some(&bake.matrix), cpu_pass.matrix.as_ref());
    let relighter = Relighter::new(&bake);
    let light = [LocalLight::point(Vec3::new(0.4, 1.1, -0.3), 2.0)];
    let frame = relighter.frame(&light, OperatorForm::Sparse);
    let on_gpu = local::GpuSparse::new(baker, &bake)
        .unwrap()
        .indirect(&frame.direct)
        .unwrap();
    let error = relative_rms(&frame.indirect, &on_gpu);
    assert!(error < 1e-5, "{error}");
    let reference = sparse_indirect(&bake.matrix, &scene.albedo, options.bounces, &frame.direct);
    assert_eq!(reference, frame.indirect);
    // The compressed operator: one pass per kernel, and 7 terms a pass (the passes that add).
    let expected = bake.operator.indirect(&frame.irradiance);
    assert!(expected.iter().any(|v| v.max_element() > 0.0));
    // And its responses in runs no larger than the largest cluster's (a small binding limit).
    let offsets = &bake.operator.response_offsets;
    let largest_cluster = 4 * offsets.windows(2).map(|w| w[1] - w[0]).max().unwrap();
    for (terms, binding) in [
        (local::gpu::TERMS_PER_PASS, u64::MAX),
        (7, u64::MAX),
        (7, largest_cluster),
    ] {
        let mut on_gpu =
            local::gpu::GpuCompressed::with_binding_limit(baker, &bake.operator, binding).unwrap();
        on_gpu.terms_per_pass = terms;
        let runs = on_gpu.response_runs();
        assert_eq!(runs > 1, binding == largest_cluster, "{runs} runs");
        let indirect = on_gpu.indirect(&frame.irradiance).unwrap();
        let error = relative_rms(&expected, &indirect);
        println!(
            "compressed operator, {terms} terms a pass, {runs} runs: GPU against CPU {error:e}"
        );
        assert!(error < 1e-5, "{terms} terms a pass, {runs} runs: {error}");
    }
    // A binding smaller than one cluster's responses is a one-line error.
    let error = local::gpu::GpuCompressed::with_binding_limit(baker, &bake.operator, 4)
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("exceed one storage binding") && !error.contains('\n'),
        "{error}"
    );
}

/// What only relights a local-lights bake is refused, in one line, for a distant-light one.
/// Depth maps compressed into more bytes than they take whole (a small mesh, many clusters) are
/// pointed out with the clusters that would take no more, and that suggestion holds.
#[test]
fn depth_maps_compressed_larger_than_whole_are_pointed_out() {
    let dir = tempfile::tempdir().unwrap();
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
    let bake = |depth_compress: &str| {
        let args = [
            "bake",
            bunny,
            "--mode",
            "local",
            "--device",
            "cpu",
            "--samples",
            "16",
            "--bounces",
            "1",
            "--depth-grid",
            "8",
            "--depth-compress",
            depth_compress,
            "--operator-compress",
            "8x4",
            "--example-lights",
            "16",
            "-o",
            "bunny.glb",
        ];
        let out = common::prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        stderr
    };
    // 1,839 receivers of 64 directions: 0.47 MB of maps, and 128 clusters' bases of 24
    // components alone take 0.82 MB.
    let stderr = bake("128x24");
    assert!(
        stderr.contains("note: the compressed depth maps take")
            && stderr.contains("1839 receivers are few for 128 clusters of 24 components")
            && stderr.contains("(--depth-compress 44x24 or fewer clusters take less)"),
        "{stderr}"
    );
    let stderr = bake("44x24");
    assert!(!stderr.contains("compressed depth maps take"), "{stderr}");
}

/// A local-lights bake runs whole: under a memory limit above its need it writes the bytes it
/// writes without one (`tests/memory_need.rs` checks the need against what it allocates).
#[test]
fn a_local_bake_within_its_memory_limit_bakes_as_without_one() {
    let dir = tempfile::tempdir().unwrap();
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");
    let bake = |output: &str, limit: &[&str]| {
        let mut args = vec![
            "bake",
            bunny,
            "--mode",
            "local",
            "--device",
            "cpu",
            "--samples",
            "16",
            "--depth-grid",
            "8",
            "--depth-compress",
            "16x8",
            "--operator-compress",
            "8x4",
            "--example-lights",
            "16",
            "-o",
            output,
        ];
        args.extend(limit);
        let out = common::prt_gpu(&args, dir.path());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        std::fs::read(dir.path().join(output)).unwrap()
    };
    let limited = bake("limited.glb", &["--memory-limit", "1G"]);
    assert!(limited == bake("whole.glb", &[]), "the files differ");
}

/// What a local-lights bake cannot run as is refused in one line before anything is read or
/// written, saying why.
#[test]
fn a_local_bake_refuses_what_it_cannot_run_as() {
    for input in [
        common::BadInput {
            case: "a memory limit below its need",
            file: None,
            args: &[
                "bake",
                "--mode",
                "local",
                "--memory-limit",
                "200M",
                "-o",
                "o.glb",
            ],
            expect: "--memory-limit 200.0 MiB: this local-lights bake needs about",
        },
        common::BadInput {
            case: "a preview",
            file: None,
            args: &[
                "bake",
                "--mode",
                "local",
                "--preview",
                "p.png",
                "-o",
                "o.glb",
            ],
            expect: "--preview is for SH transfer",
        },
        common::BadInput {
            case: "a shard",
            file: None,
            args: &["bake", "--mode", "local", "--shard", "0/2", "-o", "o.part"],
            expect: "--shard is for SH transfer",
        },
        common::BadInput {
            case: "a lightmap",
            file: None,
            args: &["bake", "--mode", "local", "--lightmap", "64", "-o", "o.glb"],
            expect: "--lightmap is for SH transfer",
        },
        common::BadInput {
            case: "a least-squares fit",
            file: None,
            args: &[
                "bake",
                "--mode",
                "local",
                "--fit",
                "least-squares",
                "-o",
                "o.glb",
            ],
            expect: "--fit is for SH transfer",
        },
    ] {
        common::assert_clean_failure(&input);
    }
}

#[test]
fn local_only_options_are_refused_for_a_distant_bake() {
    let dir = tempfile::tempdir().unwrap();
    let bake = ["bake", "--samples", "16", "--device", "cpu", "-o", "d.glb"];
    succeed(common::prt_gpu(&bake, dir.path()));
    for extra in [
        &["--device", "cpu"][..],
        &["--point-light=0,1,0"],
        &["--frames", "3"],
        &["--orbit=0,0,0"],
    ] {
        let mut args = vec!["render", "d.glb", "-o", "d.png"];
        args.extend(extra);
        let out = common::prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} rendered");
        assert_eq!(stderr.trim().lines().count(), 1, "{extra:?}: {stderr}");
        assert!(stderr.contains("local-lights bake"), "{extra:?}: {stderr}");
    }
    assert_eq!(testing::entries(dir.path()), vec!["d.glb".to_string()]);
}

/// `--bounces 0` is direct light alone: both operators give no indirect light, and the direct
/// term is the shadow rays' (the default) or the depth maps' as asked, each within [0, open].
#[test]
fn zero_bounces_is_direct_light_alone_shadowed_either_way() {
    let options = LocalOptions {
        bounces: 0,
        ..small_options()
    };
    let bake = local::bake_local(small_room(), &options, &CpuBackend, &NoProgress)
        .unwrap()
        .0;
    let lights = [LocalLight::point(Vec3::new(0.3, 1.1, -0.4), 2.0)];
    let rays = Relighter::new(&bake);
    let maps = Relighter::with_shadows(&bake, local::Shadows::DepthMaps);
    assert_eq!(rays.shadows(), local::Shadows::Rays);
    let normals = bake.scene.normals.as_deref().unwrap();
    for (relighter, form) in [
        (&rays, OperatorForm::Sparse),
        (&rays, OperatorForm::Compressed),
        (&maps, OperatorForm::Compressed),
    ] {
        let frame = relighter.frame(&lights, form);
        assert!(frame.indirect.iter().all(|v| *v == Vec3::ZERO));
        for (p, &e) in frame.irradiance.iter().enumerate() {
            let open = lights[0].unshadowed_irradiance(bake.scene.positions[p], normals[p]);
            assert!((0.0..=open * 1.000_01).contains(&e), "{p}: {e} of {open}");
        }
    }
    // The block shadows part of the floor: shadow rays give exact zeros there, and agree with
    // the depth maps on most receivers.
    let exact = rays.irradiance(&lights);
    let from_maps = maps.irradiance(&lights);
    let shadowed = (0..exact.len())
        .filter(|&p| {
            exact[p] == 0.0
                && lights[0].unshadowed_irradiance(bake.scene.positions[p], normals[p]) > 0.0
        })
        .count();
    assert!(shadowed > 0);
    let agree = exact
        .iter()
        .zip(&from_maps)
        .filter(|(a, b)| (**a - **b).abs() <= 0.25 * a.max(**b))
        .count();
    assert!(
        agree as f64 > 0.9 * exact.len() as f64,
        "{agree} of {}",
        exact.len()
    );
}

/// `--shadows` belongs to local-lights bakes: a distant-light render refuses it in one line.
#[test]
fn shadows_is_refused_for_a_distant_render() {
    common::assert_clean_failure(&common::BadInput {
        case: "--shadows with a distant bake",
        file: Some(("a.prt.glb", b"not read")),
        args: &["render", "a.prt.glb", "--shadows", "rays", "-o", "x.png"],
        expect: "--shadows",
    });
}
