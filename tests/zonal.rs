//! Zonal (LDPRT) transfer (`--zonal`): a rigid turn relights like a bake of the turned mesh to
//! within the fit's error; a bent, ribbed tube relit from its zonal transfer about the bent
//! normals follows them, where its rest pose's SH transfer does not; the file read back by the
//! baker, the numpy recipe and the Khronos glTF-Validator; bad options refused. The fit's
//! exactness on circularly symmetric transfer is a unit test (`zonal::tests`).

mod common;

use std::f32::consts::PI;

use common::{assert_clean_failure, prt_gpu, validate_gltf, BadInput};
use glam::{DMat3, Quat, Vec3};
use prt_gpu::bake::{CpuBackend, DirectSource, Mode, NoProgress, Transfer};
use prt_gpu::compress;
use prt_gpu::compress::radiance_error;
use prt_gpu::light::{preview_light, ShLight};
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::sh::rotation::ShRotation;
use prt_gpu::spec::BakeSpec;
use prt_gpu::zonal::{Bend, ZonalAxis, ZonalSpec, ZonalTransfer};
use prt_gpu::{glb, pipeline};

const BANDS: u32 = 4;

fn spec(zonal: Option<ZonalSpec>) -> BakeSpec {
    let mut spec = BakeSpec::default();
    spec.transfer.bands = prt_gpu::spec::Bands::Fixed(BANDS);
    spec.transfer.samples = 256;
    spec.transfer.mode = Mode::Shadowed;
    spec.storage.zonal = zonal;
    spec
}

fn bake(spec: &BakeSpec, scene: Scene) -> pipeline::Baked {
    let source = DirectSource::Compute;
    pipeline::run(spec, scene, None, &CpuBackend, source, &NoProgress)
        .and_then(pipeline::Bake::into_transfer)
        .unwrap()
}

/// `values` of a bake's prepared vertices, in the order of the vertices it was given
/// (`vertex_map`: given vertex -> prepared vertex).
fn in_given_order<T: Copy>(values: &[T], vertex_map: &[u32]) -> Vec<T> {
    vertex_map.iter().map(|&v| values[v as usize]).collect()
}

/// A tube along +Y, `height` long, with ribs: its radius swings by a sixth about `radius`,
/// `ribs` times along it. Open at both ends.
fn ribbed_tube(radius: f32, height: f32, ribs: u32) -> Scene {
    let (rings, segments) = (ribs * 10 + 1, 36u32);
    let mut positions = Vec::new();
    for ring in 0..rings {
        let y = height * ring as f32 / (rings - 1) as f32;
        let r = radius * (1.0 + (2.0 * PI * ribs as f32 * y / height).cos() / 6.0);
        for s in 0..segments {
            let phi = 2.0 * PI * s as f32 / segments as f32;
            positions.push(Vec3::new(r * phi.cos(), y, r * phi.sin()));
        }
    }
    let mut triangles = Vec::new();
    for ring in 0..rings - 1 {
        for s in 0..segments {
            let at = |ring: u32, s: u32| ring * segments + s % segments;
            let (a, b) = (at(ring, s), at(ring, s + 1));
            let (c, d) = (at(ring + 1, s), at(ring + 1, s + 1));
            triangles.push([a, c, b]);
            triangles.push([b, c, d]);
        }
    }
    let albedo = vec![Vec3::splat(0.7); positions.len()];
    Scene {
        positions,
        normals: None,
        albedo,
        triangles,
    }
}

/// Lights that differ in where their light comes from: the preview sky and sun, and it turned
/// about three axes.
fn lights() -> Vec<ShLight> {
    let light = preview_light(BANDS).unwrap();
    vec![
        light.clone(),
        light.rotated(90.0, 0.0, 0.0),
        light.rotated(0.0, 70.0, 0.0),
        light.rotated(30.0, 0.0, 120.0),
    ]
}

/// The rest pose's SH transfer with each vertex's turned by `turns`: what the best a transfer
/// that moves rigidly with the surface can do (what the bend changes besides turning it, the
/// ribs squeezed on the inside and the far end in view, it cannot know).
fn turned_transfer(transfer: &Transfer, turns: &[Quat]) -> Transfer {
    let per_vertex = transfer.channels() as usize * transfer.coeffs_per_channel();
    let coeffs = transfer
        .coeffs()
        .chunks_exact(per_vertex)
        .zip(turns)
        .flat_map(|(vertex, turn)| {
            let rotation = ShRotation::new(transfer.bands(), DMat3::from_quat(turn.as_dquat()));
            vertex
                .chunks_exact(transfer.coeffs_per_channel())
                .flat_map(|channel| {
                    let channel: Vec<f64> = channel.iter().map(|&c| c as f64).collect();
                    rotation.apply(&channel).into_iter().map(|c| c as f32)
                })
                .collect::<Vec<f32>>()
        })
        .collect();
    Transfer::new(
        transfer.bands(),
        transfer.channels(),
        transfer.vertex_count(),
        coeffs,
    )
    .unwrap()
}

/// Bending a ribbed tube by a quarter turn: its zonal transfer relit about the bent normals
/// (or the fitted axes turned by the bend) matches a bake of the bent tube far better than the
/// rest pose's SH transfer does, and as well as the rest pose's SH transfer turned vertex by
/// vertex, give or take the fit's own error.
#[test]
fn a_bent_tube_relit_from_zonal_transfer_follows_its_normals() {
    let (radius, height) = (0.3, 3.0);
    let mut mean_zonal_errors = Vec::new();
    for axis in [ZonalAxis::Normal, ZonalAxis::Fitted] {
        // The mean over the lights: bent zonal, rest SH.
        let mut errors = [0.0; 2];
        let zonal_spec = ZonalSpec { bands: BANDS, axis };
        let rest = bake(&spec(Some(zonal_spec)), ribbed_tube(radius, height, 12));
        let (zonal, _) = rest.zonal.as_ref().expect("zonal transfer");
        let rest_scene = &rest.mesh.scene;
        let bend = Bend::of_bounds(rest_scene.bounds(), 90.0);
        let (bent_positions, turns): (Vec<Vec3>, Vec<Quat>) =
            rest_scene.positions.iter().map(|&p| bend.place(p)).unzip();
        let bent_scene = Scene {
            positions: bent_positions,
            normals: None,
            ..rest_scene.clone()
        };
        let bent = bake(&spec(None), bent_scene);
        let map = &bent.report.vertex_map;
        // A runtime turns normals (and fitted axes) with the skinning or the deformation's
        // own turns, as here; the lobes of the normal axis are about the rest normals.
        let axes: Vec<Vec3> = zonal
            .axes()
            .iter()
            .zip(&turns)
            .map(|(a, turn)| *turn * *a)
            .collect();
        for (light, name) in lights().iter().zip(["preview", "yaw", "pitch", "tilted"]) {
            let truth = in_given_order(&compress::radiance(&bent.mesh.transfer, light), map);
            let relit = zonal.relight(&axes, light).unwrap();
            let rest_relit = compress::radiance(&rest.mesh.transfer, light);
            let turned_sh =
                compress::radiance(&turned_transfer(&rest.mesh.transfer, &turns), light);
            let zonal_error = radiance_error(&truth, &relit);
            let static_error = radiance_error(&truth, &rest_relit);
            let rigid_error = radiance_error(&truth, &turned_sh);
            let rest_zonal = zonal.relight(zonal.axes(), light).unwrap();
            let fit_error = radiance_error(&rest_relit, &rest_zonal);
            eprintln!(
                "{} axis, {name} light: bent: zonal {:.2}%, rest SH {:.2}%, rest SH turned \
                 {:.2}%; the fit at rest {:.2}%",
                axis.name(),
                100.0 * zonal_error,
                100.0 * static_error,
                100.0 * rigid_error,
                100.0 * fit_error
            );
            // What turning a transfer rigidly cannot know, plus what the fit leaves out.
            assert!(
                zonal_error <= rigid_error + fit_error + 0.03,
                "{name}: {zonal_error} against {rigid_error} + {fit_error}"
            );
            errors[0] += zonal_error / 4.0;
            errors[1] += static_error / 4.0;
        }
        assert!(errors[0] < 0.5 * errors[1], "{errors:?}");
        mean_zonal_errors.push(errors[0]);
    }
    // The fitted axis keeps more of the transfer, and turned with the surface, it shows.
    assert!(
        mean_zonal_errors[1] < mean_zonal_errors[0],
        "{mean_zonal_errors:?}"
    );
}

/// Turning the whole built-in scene: its zonal transfer relit about the turned axes matches a
/// bake of the turned scene to within the fit's error under the light as the unturned scene
/// sees it, plus the two bakes' sampling noise (measured as the SH transfers' own difference).
#[test]
fn a_rigid_turn_relights_like_a_bake_of_the_turned_scene() {
    let pitch_deg = 40.0f32;
    let turn = Quat::from_rotation_x(pitch_deg.to_radians());
    for axis in [ZonalAxis::Normal, ZonalAxis::Fitted] {
        let zonal_spec = ZonalSpec { bands: 3, axis };
        let rest = bake(&spec(Some(zonal_spec)), builtin::default_scene());
        let (zonal, _) = rest.zonal.as_ref().expect("zonal transfer");
        let turned_scene = Scene {
            positions: rest
                .mesh
                .scene
                .positions
                .iter()
                .map(|&p| turn * p)
                .collect(),
            normals: None,
            ..rest.mesh.scene.clone()
        };
        let turned = bake(&spec(None), turned_scene);
        let map = &turned.report.vertex_map;
        let axes: Vec<Vec3> = zonal.axes().iter().map(|&a| turn * a).collect();
        for light in lights() {
            let truth = in_given_order(&compress::radiance(&turned.mesh.transfer, &light), map);
            let relit = zonal.relight(&axes, &light).unwrap();
            // The unturned scene under the light turned back sees what the turned one sees.
            let back = light.rotated(0.0, -pitch_deg as f64, 0.0);
            let rest_truth = compress::radiance(&rest.mesh.transfer, &back);
            let fit_error =
                radiance_error(&rest_truth, &zonal.relight(zonal.axes(), &back).unwrap());
            let noise = radiance_error(&truth, &rest_truth);
            let error = radiance_error(&truth, &relit);
            eprintln!(
                "{} axis: turned {:.2}%, fit {:.2}%, noise {:.2}%",
                axis.name(),
                100.0 * error,
                100.0 * fit_error,
                100.0 * noise
            );
            assert!(
                error <= fit_error + noise + 1e-3,
                "{error} against {fit_error} + {noise}"
            );
            // The turned axes matter: relit about the unturned ones, it is far off.
            let unturned = radiance_error(&truth, &zonal.relight(zonal.axes(), &light).unwrap());
            assert!(unturned > 1.5 * error, "{unturned} against {error}");
        }
    }
}

/// The file holds the zonal transfer as the bake fitted it (refitting the file's own SH
/// transfer gives it again); the numpy recipe relights it as the baker does; the Khronos
/// validator finds nothing wrong with the `_PRT_ZH_*` attributes, RGB and lean.
#[test]
fn the_file_holds_it_for_the_baker_numpy_and_the_validator() {
    let dir = tempfile::tempdir().unwrap();
    for (axis, storage, channels) in [("fitted", "rgb", 3), ("normal", "lean", 1)] {
        let name = format!("zonal-{axis}.glb");
        let args = [
            "bake",
            "--samples",
            "64",
            "--zonal",
            "3",
            "--zonal-axis",
            axis,
            "--storage",
            storage,
            "-o",
            &name,
        ];
        let out = prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(
            stderr.contains(&format!("zonal: 3 bands about the {axis} axis")),
            "{stderr}"
        );
        let info = prt_gpu(&["info", &name], dir.path());
        let info = String::from_utf8_lossy(&info.stdout);
        let said = format!("zonal:        3 bands x {channels} channel(s) about the {axis} axis");
        assert!(info.contains(&said), "{info}");
        let path = dir.path().join(&name);
        let stored = glb::zonal::read_zonal(&path)
            .unwrap()
            .expect("zonal transfer");
        let baked = glb::read_glb(&path).unwrap();
        let normals = baked.scene.normals.as_ref().unwrap();
        let axis_kind = stored.axis();
        let refit = ZonalTransfer::fit(
            &baked.transfer,
            normals,
            ZonalSpec {
                bands: 3,
                axis: axis_kind,
            },
        )
        .unwrap();
        assert_eq!(stored.channels(), channels);
        assert_eq!(stored.bands(), 3);
        assert_same_fit(&stored, &refit, 1e-6);
        assert_validator_finds_nothing(&path);
        if let Some((theirs, ours)) = numpy_relights_as_we_do(&path, &stored) {
            assert_eq!(theirs, ours);
        }
    }
}

/// The stored zonal transfer is `refit` to `tolerance`, coefficient by coefficient and axis
/// by axis.
fn assert_same_fit(stored: &ZonalTransfer, refit: &ZonalTransfer, tolerance: f32) {
    for (a, b) in stored.coeffs().iter().zip(refit.coeffs()) {
        assert!(
            (a - b).abs() <= tolerance * (1.0 + a.abs()),
            "{a} against {b}"
        );
    }
    for (a, b) in stored.axes().iter().zip(refit.axes()) {
        assert!(a.distance(*b) < tolerance, "{a} against {b}");
    }
}

fn assert_validator_finds_nothing(path: &std::path::Path) {
    if let Some(report) = validate_gltf(path) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
        assert_eq!(report.num_warnings, 0, "{}", report.listing());
    }
}

/// The numpy recipe's radiance of `path` under `L(w) = 1 + w_y`, checked against `stored`
/// relit under the same light on the rows both have (to 1e-5): how many rows the recipe
/// printed and how many we relit; `None` without numpy.
fn numpy_relights_as_we_do(
    path: &std::path::Path,
    stored: &ZonalTransfer,
) -> Option<(usize, usize)> {
    let printed = prt_gpu::testing::zonal_reader_output(path)?;
    // L(w) = 1 + w_y: l_00 = sqrt(4 pi), and band 1 is y's: l_1,-1 = -sqrt(4 pi / 3).
    let mut light = ShLight::constant(3, [1.0; 3]);
    light.coeffs[1] = [-(4.0 * PI / 3.0).sqrt(); 3];
    let relit = stored.relight(stored.axes(), &light).unwrap();
    let rows = printed["radiance"].as_array().unwrap();
    for (row, ours) in rows.iter().zip(&relit) {
        for (c, value) in row.as_array().unwrap().iter().enumerate() {
            let value = value.as_f64().unwrap() as f32;
            assert!(
                (value - ours[c]).abs() < 1e-5 * (1.0 + ours[c].abs()),
                "{value} against {ours:?}"
            );
        }
    }
    Some((rows.len(), relit.len()))
}

#[test]
fn bad_zonal_options_are_refused_in_one_line() {
    for input in [
        BadInput {
            case: "no band",
            file: None,
            args: &["bake", "--zonal", "0", "-o", "o.glb"],
            expect: "--zonal 0: zonal bands run from 1 to the transfer's bands (4)",
        },
        BadInput {
            case: "more bands than the transfer",
            file: None,
            args: &["bake", "--bands", "3", "--zonal", "4", "-o", "o.glb"],
            expect: "--zonal 4: zonal bands run from 1 to the transfer's bands (3)",
        },
        BadInput {
            case: "axis alone",
            file: None,
            args: &["bake", "--zonal-axis", "fitted", "-o", "o.glb"],
            expect: "ask for it with --zonal BANDS",
        },
        BadInput {
            case: "local lights",
            file: None,
            args: &["bake", "--mode", "local", "--zonal", "2", "-o", "o.glb"],
            expect: "--zonal is for SH transfer",
        },
    ] {
        assert_clean_failure(&input);
    }
}

/// The `_RADIANCE` attribute of a relit copy (`render -o relit.glb`), per vertex.
fn relit_radiance(path: &std::path::Path) -> Vec<[f32; 3]> {
    let bytes = std::fs::read(path).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let index = &doc["meshes"][0]["primitives"][0]["attributes"]["_RADIANCE"];
    common::vec3_accessor(&bytes, &doc, index.as_u64().unwrap())
}

/// `render --zonal` relights from the zonal transfer: the relit copy's radiance is the zonal
/// transfer's under the preview light (not the SH transfer's), and an image renders; a file
/// without zonal transfer is refused in one line.
#[test]
fn render_relights_from_the_zonal_transfer() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["bake", "--samples", "64", "--zonal", "2", "-o", "z.glb"];
    assert!(prt_gpu(&args, dir.path()).status.success());
    for args in [
        &["render", "z.glb", "--zonal", "-o", "relit.glb"][..],
        &[
            "render", "z.glb", "--zonal", "--width", "64", "--height", "48", "-o", "z.png",
        ],
    ] {
        let out = prt_gpu(args, dir.path());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let path = dir.path().join("z.glb");
    let zonal = glb::zonal::read_zonal(&path).unwrap().unwrap();
    let light = preview_light(4).unwrap();
    let expected = zonal.relight(zonal.axes(), &light).unwrap();
    let sh = compress::radiance(&glb::read_glb(&path).unwrap().transfer, &light);
    let relit = relit_radiance(&dir.path().join("relit.glb"));
    assert!(radiance_error(&expected, &relit) < 1e-6);
    assert!(
        radiance_error(&sh, &relit) > 0.01,
        "the SH transfer's, not the zonal's"
    );
    assert!(dir.path().join("z.png").exists());
    let plain = ["bake", "--samples", "16", "-o", "plain.glb"];
    assert!(prt_gpu(&plain, dir.path()).status.success());
    let out = prt_gpu(
        &["render", "plain.glb", "--zonal", "-o", "p.png"],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("holds no zonal transfer (bake it with --zonal BANDS)"),
        "{stderr}"
    );
    assert!(!dir.path().join("p.png").exists());
}

/// A glTF scene baked in place holds zonal transfer on every baked primitive, each
/// placement's own (`_PRT_ZH_*`, `extras.prt.zonal`): read back whole (split at its corners
/// where it has a lightmap), it is the fit of the scene's SH transfer as read back; the numpy
/// recipe reads the first primitive's as we do; the file passes the validator; `info` and
/// `render --zonal` read it.
#[test]
fn a_gltf_scene_baked_in_place_holds_it_on_every_primitive() {
    let dir = tempfile::tempdir().unwrap();
    // The card shown twice (each placement its own transfer); once where it is lightmapped
    // (one UV set cannot hold two placements' texels).
    let twice = common::gltf_builder::ground_and_card_gltf(dir.path(), Some(1), true, true);
    let once_dir = dir.path().join("once");
    std::fs::create_dir(&once_dir).unwrap();
    let once = common::gltf_builder::ground_and_card_gltf(&once_dir, Some(1), true, false);
    for (axis, lightmap) in [("fitted", "0"), ("normal", "0"), ("fitted", "64")] {
        let scene = if lightmap == "0" { &twice } else { &once };
        let scene = scene.to_str().unwrap().to_string();
        let name = format!("scene-{axis}-{lightmap}.glb");
        let mut args = vec![
            "bake",
            &scene,
            "--samples",
            "64",
            "--zonal",
            "3",
            "--zonal-axis",
            axis,
            "-o",
            &name,
        ];
        if lightmap != "0" {
            args.extend(["--lightmap", lightmap]);
        }
        let out = prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        let info = prt_gpu(&["info", &name], dir.path());
        let info = String::from_utf8_lossy(&info.stdout);
        let said = format!("zonal:        3 bands x 3 channel(s) about the {axis} axis");
        assert!(info.contains(&said), "{info}");
        let path = dir.path().join(&name);
        let stored = glb::zonal::read_zonal(&path)
            .unwrap()
            .expect("zonal transfer");
        let baked = glb::scene::read_scene_glb(&path).unwrap();
        assert_eq!(stored.vertex_count(), baked.scene.vertex_count());
        let normals = baked.scene.normals.as_ref().unwrap();
        let shape = ZonalSpec {
            bands: 3,
            axis: stored.axis(),
        };
        let refit = ZonalTransfer::fit(&baked.transfer, normals, shape).unwrap();
        assert_same_fit(&stored, &refit, 1e-5);
        assert_validator_finds_nothing(&path);
        let rendered = prt_gpu(
            &["render", &name, "--zonal", "--bend", "30", "-o", "bent.png"],
            dir.path(),
        );
        assert!(
            rendered.status.success(),
            "{}",
            String::from_utf8_lossy(&rendered.stderr)
        );
        // Read split at its corners, a lightmapped scene's vertices are not the primitives'.
        if lightmap != "0" {
            continue;
        }
        // The recipe reads the first primitive: fewer rows than the whole scene.
        if let Some((theirs, ours)) = numpy_relights_as_we_do(&path, &stored) {
            assert!(theirs > 0 && theirs < ours, "{theirs} of {ours}");
        }
    }
}
