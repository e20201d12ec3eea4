//! Relightable probes (`--probes`): analytic cases (nothing around, a closed room, a roof over
//! an open sky), placement inside geometry, CPU against GPU, and the file read back by the
//! baker's reader, the numpy recipe and the Khronos glTF-Validator. Against the path tracer:
//! tests/oracle_probes.rs.

mod common;

use std::f64::consts::PI;

use common::{assert_clean_failure, backends, validate_gltf, BadInput};
use glam::Vec3;
use prt_gpu::bake::{Backend, CpuBackend, DirectSource, Mode, NoProgress};
use prt_gpu::probes::{ProbeForm, ProbePlacement, ProbeSet, ProbeSpec, ProbeStatus};
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::sh::coeff_count;
use prt_gpu::spec::BakeSpec;
use prt_gpu::{glb, pipeline};

fn spec(mode: Mode, samples: u32, placement: ProbePlacement) -> BakeSpec {
    let mut spec = BakeSpec::default();
    spec.transfer.mode = mode;
    spec.transfer.samples = samples;
    spec.probes = Some(ProbeSpec {
        placement,
        form: ProbeForm::Radiance,
    });
    spec
}

fn bake(spec: &BakeSpec, scene: Scene, backend: &dyn Backend) -> pipeline::Bake {
    pipeline::run(
        spec,
        scene,
        None,
        backend,
        DirectSource::Compute,
        &NoProgress,
    )
    .unwrap()
}

fn probes_of(spec: &BakeSpec, scene: Scene, backend: &dyn Backend) -> ProbeSet {
    let baked = bake(spec, scene, backend).into_transfer().unwrap();
    baked.probes.expect("probes baked")
}

fn points(points: &[[f32; 3]]) -> ProbePlacement {
    ProbePlacement::Points(points.to_vec())
}

/// The incident radiance's SH at probe `p` under a constant sky of radiance 1, first channel.
fn under_constant_sky(probes: &ProbeSet, p: usize) -> Vec<f64> {
    let mut light = vec![[0.0f32; 3]; coeff_count(probes.bands)];
    light[0] = [(4.0 * std::f32::consts::PI).sqrt(); 3];
    probes.apply(p, &light).iter().map(|rgb| rgb[0]).collect()
}

/// A unit square in the plane z = 0 (normal +Z).
fn square() -> Scene {
    builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Y, 1, Vec3::splat(0.5))
}

#[test]
fn a_probe_that_sees_nothing_is_exactly_the_identity() {
    // In the square's plane, beside it: no direction of positive measure reaches it.
    for mode in [Mode::Shadowed, Mode::Interreflected] {
        let probes = probes_of(
            &spec(mode, 256, points(&[[5.0, 0.0, 0.0]])),
            square(),
            &CpuBackend,
        );
        assert_eq!(probes.status, [ProbeStatus::Placed]);
        let n = coeff_count(probes.bands);
        for c in 0..probes.channels as usize {
            for i in 0..n {
                for k in 0..n {
                    let expected = if i == k { 1.0 } else { 0.0 };
                    assert_eq!(probes.matrix(0)[(c * n + i) * n + k], expected, "{mode:?}");
                }
            }
        }
    }
}

#[test]
fn a_probe_in_a_closed_room_receives_nothing() {
    // A closed box seen from inside: no light enters, so neither the sky nor bounced light
    // reaches the probe, and every ray is blocked. The estimate is then the identity minus the
    // quadrature of `y_i y_k` over the whole sample set: the negative of that set's
    // quadrature error, which must itself be small.
    let room = || builtin::seen_from_inside(builtin::closed_box(-Vec3::ONE, Vec3::ONE, 2));
    let samples = prt_gpu::sampling::stratified_sphere(1024, 1);
    let n = 16;
    let mut quadrature_error = vec![0.0f64; n * n];
    for d in &samples.directions {
        let y = prt_gpu::sh::basis(4, d.as_dvec3());
        for i in 0..n {
            for k in 0..n {
                quadrature_error[i * n + k] += samples.weight * y[i] * y[k];
            }
        }
    }
    (0..n).for_each(|i| quadrature_error[i * n + i] -= 1.0);
    let largest = quadrature_error.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(
        largest < 0.02,
        "the sample set's quadrature error {largest}"
    );
    for mode in [Mode::Shadowed, Mode::Interreflected] {
        let probes = probes_of(
            &spec(mode, 1024, points(&[[0.1, 0.2, -0.3]])),
            room(),
            &CpuBackend,
        );
        assert_eq!(probes.status, [ProbeStatus::Placed], "{mode:?}");
        for c in 0..probes.channels as usize {
            let m = &probes.matrix(0)[c * n * n..(c + 1) * n * n];
            for (ours, error) in m.iter().zip(&quadrature_error) {
                assert!(
                    (*ours as f64 + error).abs() < 1e-5,
                    "{mode:?}: {ours} against {error}"
                );
            }
        }
    }
}

#[test]
fn a_probe_under_a_roof_sees_the_sky_below_and_the_light_the_roof_reflects() {
    // A roof 1 above the probe, 1,000 wide, facing down, under a constant sky of radiance 1:
    // the sky below reaches the probe; above, the roof's underside sends what it reflects of
    // the lower sky, radiance rho (its irradiance pi times rho / pi). So the incident radiance
    // is 1 below and rho above: SH coefficients sqrt(4 pi)(1 + rho)/2 and, for y_10 =
    // sqrt(3 / 4 pi) z, (rho - 1) pi sqrt(3 / 4 pi). Shadowed, the roof reflects nothing.
    let rho = 0.5;
    let roof = builtin::grid_plane(
        Vec3::Z,
        1000.0 * Vec3::X,
        -1000.0 * Vec3::Y,
        1,
        Vec3::splat(rho as f32),
    );
    for (mode, reflected) in [(Mode::Shadowed, 0.0), (Mode::Interreflected, rho)] {
        let mut spec = spec(mode, 1024, points(&[[0.0, 0.0, 0.0]]));
        spec.transfer.bounces = 1;
        let probes = probes_of(&spec, roof.clone(), &CpuBackend);
        let incident = under_constant_sky(&probes, 0);
        let dc = (4.0 * PI).sqrt() * (1.0 + reflected) / 2.0;
        let z = (reflected - 1.0) * PI * (3.0 / (4.0 * PI)).sqrt();
        assert!(
            (incident[0] - dc).abs() < 0.01 * dc,
            "{mode:?}: {incident:?}"
        );
        assert!(
            (incident[2] - z).abs() < 0.01 * z.abs(),
            "{mode:?}: {incident:?}"
        );
        for k in [1, 3] {
            assert!(incident[k].abs() < 0.01, "{mode:?}: {incident:?}");
        }
    }
}

#[test]
fn probes_inside_geometry_are_moved_out_within_half_a_cell_or_marked_invalid() {
    // A closed box of side 1 under a grid of 0.4: every probe but the centre's lies 0.1 from
    // a wall and is moved through it; the centre lies 0.5 from every wall, beyond half a cell.
    let cube = builtin::closed_box(-0.5 * Vec3::ONE, 0.5 * Vec3::ONE, 2);
    let probes = probes_of(
        &spec(Mode::Shadowed, 256, ProbePlacement::Grid { spacing: 0.4 }),
        cube,
        &CpuBackend,
    );
    let grid = probes.grid.expect("a grid");
    assert_eq!(grid.dims, [3, 3, 3]);
    let placed = grid.points();
    let mut counts = [0; 3];
    for (p, (&status, &at)) in probes.status.iter().zip(&probes.positions).enumerate() {
        counts[status.code() as usize] += 1;
        match status {
            ProbeStatus::Invalid => {
                assert!(placed[p].length() < 1e-6, "the centre alone is invalid");
                assert!(probes.matrix(p).iter().all(|&m| m == 0.0));
            }
            ProbeStatus::Moved => {
                assert!(
                    at.abs().max_element() > 0.5,
                    "probe {p} at {at} is still inside"
                );
                assert!(
                    at.distance(placed[p]) <= 0.2,
                    "probe {p} moved beyond half a cell"
                );
            }
            ProbeStatus::Placed => panic!("probe {p} at {at} lies inside the box"),
        }
    }
    assert_eq!(counts, [0, 26, 1]);
}

#[test]
fn cpu_and_gpu_probes_agree() {
    let backends = backends();
    let mut spec = spec(
        Mode::Interreflected,
        256,
        ProbePlacement::Grid { spacing: 0.75 },
    );
    spec.transfer.bounces = 1;
    let cpu = probes_of(&spec, builtin::default_scene(), backends[0].as_ref());
    assert!(cpu.status.contains(&ProbeStatus::Placed));
    for backend in &backends[1..] {
        let gpu = probes_of(&spec, builtin::default_scene(), backend.as_ref());
        assert_eq!(gpu.status, cpu.status, "{}", backend.describe());
        assert_eq!(gpu.positions, cpu.positions, "{}", backend.describe());
        // The hits are the same ray for ray (one tie rule); the bounced light differs by the
        // float rounding of the surfaces' transfer.
        let worst = gpu
            .matrices
            .iter()
            .zip(&cpu.matrices)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-4, "{}: {worst}", backend.describe());
    }
}

#[test]
fn the_file_holds_the_probes_for_every_reader() {
    let dir = tempfile::tempdir().unwrap();
    for (form, name) in [
        (ProbeForm::Radiance, "r.glb"),
        (ProbeForm::Irradiance, "i.glb"),
    ] {
        let mut spec = spec(
            Mode::Interreflected,
            256,
            ProbePlacement::Grid { spacing: 1.0 },
        );
        spec.probes.as_mut().unwrap().form = form;
        let done = bake(&spec, builtin::default_scene(), &CpuBackend);
        let path = dir.path().join(name);
        pipeline::write(&spec, &done, None, &path).unwrap();
        let baked = done.transfer().unwrap();
        let probes = baked.probes.as_ref().unwrap();
        assert_eq!(
            probes.channels, 3,
            "the built-in scene's albedo is not grey"
        );
        let rows = match form {
            ProbeForm::Radiance => 16,
            ProbeForm::Irradiance => 9,
        };
        assert_eq!(probes.rows, rows);
        let read = glb::probes::read_probes(&path)
            .unwrap()
            .expect("probes in the file");
        assert_eq!(&read, probes);
        // The mesh and its transfer read as before.
        assert_eq!(glb::read_glb(&path).unwrap().transfer, baked.mesh.transfer);
        if let Some(report) = validate_gltf(&path) {
            assert_eq!(report.num_errors, 0, "{}", report.listing());
            assert_eq!(report.num_warnings, 0, "{}", report.listing());
        }
        let Some(printed) = prt_gpu::testing::probes_reader_output(&path) else {
            continue;
        };
        let status: Vec<u64> = serde_json::from_value(printed["status"].clone()).unwrap();
        let codes: Vec<u64> = probes.status.iter().map(|s| s.code() as u64).collect();
        assert_eq!(status, codes);
        let positions: Vec<[f32; 3]> =
            serde_json::from_value(printed["positions"].clone()).unwrap();
        let ours: Vec<[f32; 3]> = probes.positions.iter().map(|p| p.to_array()).collect();
        assert_eq!(positions, ours);
        let incident: Vec<Vec<Vec<f64>>> =
            serde_json::from_value(printed["incident"].clone()).unwrap();
        let white = {
            let mut light = vec![[0.0f32; 3]; 16];
            light[0] = [(4.0 * std::f32::consts::PI).sqrt(); 3];
            light
        };
        for (p, numpy) in incident.iter().enumerate() {
            let ours = probes.apply(p, &white);
            for (c, rows) in numpy.iter().enumerate() {
                for (i, &value) in rows.iter().enumerate() {
                    assert!(
                        (value - ours[i][c]).abs() < 1e-5,
                        "probe {p} channel {c} row {i}"
                    );
                }
            }
        }
    }
}

/// A glTF scene baked in place: the probes in the root's `extras.prt`, read back by our reader
/// and the numpy recipe, equal to those of the same scene baked as a mesh; the file still
/// passes the validator; `info`, `render --probe-sphere` and `view` find them.
#[test]
fn a_gltf_scene_baked_in_place_carries_its_probes() {
    use prt_gpu::scene::gltf as gltf_scene;
    use prt_gpu::spec::Container;
    let dir = tempfile::tempdir().unwrap();
    let input = common::ENGINE_GLB;
    let (gltf, scene) = gltf_scene::load(std::path::Path::new(input)).unwrap();
    let mut spec = spec(Mode::Shadowed, 32, ProbePlacement::Grid { spacing: 60.0 });
    spec.container = Container::GltfInPlace;
    let run = |spec: &BakeSpec, gltf| {
        let (source, progress) = (DirectSource::Compute, &NoProgress);
        pipeline::run(spec, scene.clone(), gltf, &CpuBackend, source, progress).unwrap()
    };
    let bake = run(&spec, Some(&gltf));
    let path = dir.path().join("engine.glb");
    pipeline::write(&spec, &bake, Some(&gltf), &path).unwrap();
    let baked = bake.into_transfer().unwrap();
    let probes = baked.probes.as_ref().unwrap();
    assert!(probes.len() > 100, "{}", probes.describe());
    assert!(probes.status.contains(&ProbeStatus::Moved));
    let read = glb::probes::read_probes(&path)
        .unwrap()
        .expect("probes in the scene");
    assert_eq!(&read, probes);
    assert!(glb::is_scene_file(&std::fs::read(&path).unwrap()));
    spec.container = Container::Mesh;
    let mesh_bake = run(&spec, None).into_transfer().unwrap();
    assert_eq!(mesh_bake.probes.as_ref(), Some(probes));
    if let Some(report) = validate_gltf(&path) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
        assert_eq!(report.num_warnings, 0, "{}", report.listing());
    }
    if let Some(printed) = prt_gpu::testing::probes_reader_output(&path) {
        let status: Vec<u8> = serde_json::from_value(printed["status"].clone()).unwrap();
        let codes: Vec<u8> = probes.status.iter().map(|s| s.code()).collect();
        assert_eq!(status, codes);
    }
    let d = dir.path();
    let out = common::prt_gpu(&["info", "engine.glb"], d);
    assert!(String::from_utf8_lossy(&out.stdout).contains(&probes.describe()));
    let valid = probes
        .status
        .iter()
        .position(|&s| s == ProbeStatus::Placed)
        .unwrap();
    let at = probes.positions[valid];
    let sphere = format!("{},{},{},20", at.x, at.y, at.z);
    for args in [
        &[
            "render",
            "engine.glb",
            "--probe-sphere",
            &sphere,
            "-o",
            "e.png",
        ][..],
        &["view", "engine.glb", "-o", "e.html"],
    ] {
        let out = common::prt_gpu(args, d);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {stderr}");
    }
}

/// A streamed bake (`--memory-limit` below the whole bake's need) carries the probes: baked
/// once the transfer is known (an interreflected bake's exit light read back from its scratch
/// file, at the bands `--bands auto` keeps), written where the whole bake writes them. The
/// file is the whole bake's byte for byte: the built-in scene as a mesh, shadowed and
/// interreflected, with bands auto, lean half floats and irradiance probes, on the GPU; and a
/// glTF scene in place.
#[test]
fn streamed_bakes_carry_the_probes_of_the_whole_bake() {
    use prt_gpu::bake::stream::MemoryNeed;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: [(Option<&str>, &[&str]); 6] = [
        (None, &["--mode", "shadowed"]),
        (None, &["--mode", "interreflected"]),
        (None, &["--mode", "interreflected", "--bands", "auto"]),
        (
            None,
            &[
                "--mode",
                "interreflected",
                "--storage",
                "lean",
                "--precision",
                "f16",
                "--probe-form",
                "irradiance",
            ],
        ),
        (None, &["--mode", "interreflected", "--device", "gpu"]),
        (
            Some(common::ENGINE_GLB),
            &["--mode", "interreflected", "--bounces", "1"],
        ),
    ];
    for (input, extra) in cases {
        if extra.contains(&"gpu") && common::gpu_baker().is_none() {
            continue;
        }
        let (scene, document, spacing) = match input {
            Some(path) => {
                let (gltf, scene) = prt_gpu::scene::gltf::load(std::path::Path::new(path)).unwrap();
                (scene, gltf.byte_size(), "60")
            }
            None => (builtin::default_scene(), 0, "0.5"),
        };
        let interreflected = extra.contains(&"interreflected");
        let mut probe_spec = spec(
            Mode::Shadowed,
            64,
            ProbePlacement::Grid {
                spacing: spacing.parse().unwrap(),
            },
        );
        let options = probe_spec.options();
        let bands = match extra.contains(&"auto") {
            true => prt_gpu::spec::AUTO_MAX_BANDS,
            false => 4,
        };
        if extra.contains(&"irradiance") {
            probe_spec.probes.as_mut().unwrap().form = ProbeForm::Irradiance;
        }
        let probes = prt_gpu::probes::memory_need(
            probe_spec.probes.as_ref().unwrap(),
            &scene,
            (bands, 64),
            interreflected,
        );
        let options = prt_gpu::bake::BakeOptions {
            bands,
            mode: if interreflected {
                Mode::Interreflected
            } else {
                Mode::Shadowed
            },
            ..options
        };
        let need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), &options)
            .with_document(document)
            .with_probes(probes);
        let limit = need.streamed(2048).to_string();
        let run = |output: &str, limit: &str| {
            let mut args = vec!["bake", "--samples", "64", "--probes", spacing, "-o", output];
            args.extend(input);
            args.extend(["--memory-limit", limit]);
            args.extend(extra);
            let out = common::prt_gpu(&args, d);
            let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
            assert!(out.status.success(), "{extra:?}: {stderr}");
            stderr
        };
        let whole = run("whole.glb", "1T");
        let streamed = run("streamed.glb", &limit);
        assert!(
            streamed.contains("chunks of 2048 receivers"),
            "{extra:?}: {streamed}"
        );
        let probes_line = |stderr: &str| {
            let line = stderr.lines().find(|l| l.starts_with("probes:"));
            line.unwrap_or_else(|| panic!("{extra:?}: {stderr}"))
                .split(';')
                .next()
                .unwrap()
                .to_string()
        };
        assert_eq!(probes_line(&whole), probes_line(&streamed), "{extra:?}");
        let same = std::fs::read(d.join("whole.glb")).unwrap()
            == std::fs::read(d.join("streamed.glb")).unwrap();
        assert!(
            same,
            "{extra:?}: the streamed file differs from the whole bake's"
        );
        let read = glb::probes::read_probes(&d.join("streamed.glb"))
            .unwrap()
            .unwrap();
        assert_eq!(
            read.channels,
            if interreflected { 3 } else { 1 },
            "{extra:?}"
        );
    }
}

#[test]
fn probes_go_with_every_receiver_storage_and_layout_of_a_baked_mesh() {
    use prt_gpu::bake::Fit;
    use prt_gpu::precision::Precision;
    use prt_gpu::spec::{Compression, Layout};
    let dir = tempfile::tempdir().unwrap();
    let base = spec(
        Mode::Interreflected,
        64,
        ProbePlacement::Grid { spacing: 1.5 },
    );
    let reference = probes_of(&base, builtin::default_scene(), &CpuBackend);
    type Edit = fn(&mut BakeSpec);
    let cases: Vec<(&str, Edit)> = vec![
        ("least squares", |s| s.receivers.fit = Fit::LeastSquares),
        ("lightmap", |s| s.receivers.lightmap = Some(512)),
        ("f16", |s| s.storage.precision = Precision::F16),
        ("compressed", |s| {
            s.storage.layout = Layout::Cpca(Compression::Shape {
                clusters: 4,
                components: 4,
            })
        }),
    ];
    for (name, edit) in cases {
        let mut spec = base.clone();
        edit(&mut spec);
        let done = bake(&spec, builtin::default_scene(), &CpuBackend);
        let baked = done.transfer().unwrap();
        let path = dir.path().join(format!("{name}.glb"));
        pipeline::write(&spec, &done, None, &path).unwrap();
        let read = glb::probes::read_probes(&path)
            .unwrap()
            .expect("probes in the file");
        assert_eq!(Some(&read), baked.probes.as_ref(), "{name}");
        // The same places and what became of them; the matrices see the transfer this
        // bake's receivers gave the surfaces.
        assert_eq!(read.positions, reference.positions, "{name}");
        assert_eq!(read.status, reference.status, "{name}");
        if let Some(report) = validate_gltf(&path) {
            assert_eq!(report.num_errors, 0, "{name}: {}", report.listing());
        }
    }
}

#[test]
fn bad_probe_options_are_refused_in_one_line() {
    for input in [
        BadInput {
            case: "zero spacing",
            file: None,
            args: &["bake", "--probes", "0", "-o", "o.glb"],
            expect: "--probes 0: the grid spacing must be a positive length",
        },
        BadInput {
            case: "too many probes",
            file: None,
            args: &["bake", "--probes", "0.001", "-o", "o.glb"],
            expect: "choose a larger spacing",
        },
        BadInput {
            case: "missing points file",
            file: None,
            args: &["bake", "--probe-points", "nope.txt", "-o", "o.glb"],
            expect: "nope.txt",
        },
        BadInput {
            case: "bad points line",
            file: Some(("p.txt", b"# probes\n0 1 2\n0 1\n")),
            args: &["bake", "--probe-points", "p.txt", "-o", "o.glb"],
            expect: "p.txt: line 3: a probe point is three finite numbers",
        },
        BadInput {
            case: "form alone",
            file: None,
            args: &["bake", "--probe-form", "irradiance", "-o", "o.glb"],
            expect: "ask for them with --probes",
        },
        BadInput {
            case: "unshadowed",
            file: None,
            args: &[
                "bake",
                "--probes",
                "1",
                "--mode",
                "unshadowed",
                "-o",
                "o.glb",
            ],
            expect: "every probe would be the identity",
        },
    ] {
        assert_clean_failure(&input);
    }
}

#[test]
fn render_draws_spheres_lit_by_the_probes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str]| {
        let out = common::prt_gpu(args, d);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    run(&["bake", "--samples", "64", "--probes", "0.5", "-o", "p.glb"]);
    run(&[
        "render",
        "p.glb",
        "--width",
        "160",
        "--height",
        "120",
        "-o",
        "plain.png",
    ]);
    let sphere = ["--probe-sphere", "1.2,0.5,1.2,0.4"];
    let with = [
        &["render", "p.glb", "--width", "160", "--height", "120"][..],
        &sphere,
    ]
    .concat();
    run(&[&with[..], &["-o", "sphere.png"]].concat());
    let pixels = |name: &str| image::open(d.join(name)).unwrap().to_rgba8();
    let (plain, sphere) = (pixels("plain.png"), pixels("sphere.png"));
    let changed = plain
        .pixels()
        .zip(sphere.pixels())
        .filter(|(a, b)| a != b)
        .count();
    // A ball 0.8 across in a 4-unit scene framed into 160 x 120: some hundred pixels.
    assert!(changed > 60, "{changed} pixels changed");
    let lit = plain
        .pixels()
        .zip(sphere.pixels())
        .filter(|(a, b)| a != b && b[3] == 255 && b[0] > 20)
        .count();
    assert!(
        lit > changed / 2,
        "{lit} of {changed} changed pixels are lit"
    );

    run(&["bake", "--samples", "16", "-o", "none.glb"]);
    assert_clean_failure(&BadInput {
        case: "no probes in the file",
        file: None,
        args: &["render", "/nonexistent/none.glb", "--probe-sphere", "0,1,0"],
        expect: "none.glb",
    });
    let out = common::prt_gpu(&["render", "none.glb", "--probe-sphere", "0,1,0"], d);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("holds no probes"),
        "{stderr}"
    );
    let out = common::prt_gpu(&["render", "p.glb", "--probe-sphere", "0,1,0,-2"], d);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("positive radius"),
        "{stderr}"
    );
}

#[test]
fn gpu_relighting_agrees_with_the_cpu() {
    let Some(baker) = common::gpu_baker() else {
        return;
    };
    let mut spec = spec(
        Mode::Interreflected,
        64,
        ProbePlacement::Grid { spacing: 0.5 },
    );
    spec.transfer.bounces = 1;
    let baked = probes_of(&spec, builtin::default_scene(), &CpuBackend);
    // More probes than one dispatch holds, one channel, in the irradiance form.
    let mut random = prt_gpu::sampling::Pcg32::new(5);
    let many = ProbeSet {
        bands: 3,
        channels: 1,
        form: ProbeForm::Irradiance,
        rows: 9,
        grid: None,
        positions: vec![Vec3::ZERO; 5000],
        status: vec![ProbeStatus::Placed; 5000],
        matrices: (0..5000 * 9 * 9).map(|_| random.next_f32() - 0.5).collect(),
        samples: 16,
    };
    assert!(many.len() > prt_gpu::probes::gpu::PROBES_PER_DISPATCH as usize);
    let light: Vec<[f32; 3]> = (0..16)
        .map(|k| [1.0 / (1 + k) as f32, 0.5, -0.25 * (k % 3) as f32])
        .collect();
    for probes in [&baked, &many] {
        let gpu = prt_gpu::probes::gpu::GpuProbes::new(&baker.context, probes)
            .unwrap()
            .relight(&light)
            .unwrap();
        let cpu = probes.relight(&light);
        assert_eq!(gpu.len(), cpu.len());
        for (g, c) in gpu.iter().zip(&cpu) {
            for rgb in 0..3 {
                let tolerance = 1e-5 * (1.0 + c[rgb].abs());
                assert!((g[rgb] - c[rgb]).abs() <= tolerance, "{g:?} against {c:?}");
            }
        }
    }
}
