//! Subsurface scattering (`--subsurface`): a white slab that does not absorb returns no more
//! than it receives; a thin slab lit from behind glows on its front where a thick one does
//! not; as the diffusion length goes to zero the result is plain shadowed transfer with the
//! medium's total diffuse reflectance as albedo; CPU and GPU agree; bad options are refused.
//! The dipole's own closed forms are unit tests (`bake::subsurface::tests`).

mod common;

use std::path::{Path, PathBuf};

use common::gltf_builder::GltfBuilder;
use common::{assert_clean_failure, backends, BadInput};
use glam::Vec3;
use prt_gpu::bake::subsurface::{Dipole, SubsurfaceMaterial};
use prt_gpu::bake::{Backend, CpuBackend, DirectSource, Mode, NoProgress};
use prt_gpu::compress;
use prt_gpu::compress::radiance_error;
use prt_gpu::light::{analytic, ShLight};
use prt_gpu::pipeline;
use prt_gpu::scene::{builtin, Scene};
use prt_gpu::spec::BakeSpec;
use serde_json::json;

const BANDS: u32 = 3;

fn spec(mode: Mode, subsurface: Option<SubsurfaceMaterial>) -> BakeSpec {
    let mut spec = BakeSpec::default();
    spec.transfer.bands = prt_gpu::spec::Bands::Fixed(BANDS);
    spec.transfer.samples = 256;
    spec.transfer.mode = mode;
    spec.transfer.subsurface = subsurface;
    spec
}

fn bake(spec: &BakeSpec, scene: Scene, backend: &dyn Backend) -> pipeline::Baked {
    let source = DirectSource::Compute;
    pipeline::run(spec, scene, None, backend, source, &NoProgress)
        .and_then(pipeline::Bake::into_transfer)
        .unwrap()
}

/// A medium in a scene measured in millimetres.
fn medium(absorption: [f32; 3], reduced_scattering: [f32; 3]) -> SubsurfaceMaterial {
    SubsurfaceMaterial {
        ior: 1.3,
        absorption,
        reduced_scattering,
        mm_per_unit: 1.0,
    }
}

/// A slab `width` wide (x and z) and `thickness` thick (y), its top at y = 0.
fn slab(width: f32, thickness: f32, cells: u32) -> Scene {
    let half = 0.5 * width;
    builtin::closed_box(
        Vec3::new(-half, -thickness, -half),
        Vec3::new(half, 0.0, half),
        cells,
    )
}

/// The vertices of `scene` on its top face (y = 0), away from its rim by `margin`.
fn top_vertices(scene: &Scene, margin: f32) -> Vec<usize> {
    let (low, high) = scene.bounds();
    (0..scene.vertex_count())
        .filter(|&v| {
            let p = scene.positions[v];
            p.y == 0.0
                && p.x > low.x + margin
                && p.x < high.x - margin
                && p.z > low.z + margin
                && p.z < high.z - margin
        })
        .collect()
}

/// A white medium that does not absorb, under a constant sky of radiance 1: every vertex
/// sends back at most radiance 1 (its weights sum to at most the total diffuse reflectance,
/// 1), and the middle of the top, where the slab looks most like a half-space, close to it.
#[test]
fn a_white_slab_that_does_not_absorb_returns_no_more_than_it_receives() {
    let material = medium([0.0; 3], [1.0; 3]);
    let baked = bake(
        &spec(Mode::Unshadowed, Some(material)),
        slab(40.0, 10.0, 16),
        &CpuBackend,
    );
    let sky = ShLight::constant(BANDS, [1.0; 3]);
    let radiance = compress::radiance(&baked.mesh.transfer, &sky);
    let most = radiance.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
    assert!(most <= 1.0 + 1e-4, "{most}");
    let middle = top_vertices(&baked.mesh.scene, 15.0);
    assert!(!middle.is_empty());
    for &v in &middle {
        // The half-space returns 1 - 1e-3; this slab's top is 40 mm wide, and what would come
        // from farther away (about (z_r + z_v) / 2R of it) is missing.
        assert!(radiance[v][0] > 0.8, "{:?}", radiance[v]);
    }
}

/// Lit only from below: the middle of the top of a 1 mm slab glows, that of a 20 mm one does
/// not (its light would have to travel 20 mm through the medium, or 14 mm from the lit sides),
/// and without subsurface scattering neither top receives more than the band-limited light's
/// ringing.
#[test]
fn a_thin_slab_lit_from_behind_glows_where_a_thick_one_does_not() {
    let material = medium([0.05; 3], [1.0; 3]);
    let below = analytic::hemisphere(BANDS, [0.0; 3], [1.0; 3]).unwrap();
    let top_mean = |thickness: f32, subsurface: Option<SubsurfaceMaterial>| {
        let baked = bake(
            &spec(Mode::Shadowed, subsurface),
            slab(40.0, thickness, 20),
            &CpuBackend,
        );
        let radiance = compress::radiance(&baked.mesh.transfer, &below);
        let top = top_vertices(&baked.mesh.scene, 14.0);
        top.iter().map(|&v| radiance[v][1] as f64).sum::<f64>() / top.len() as f64
    };
    let thin = top_mean(1.0, Some(material));
    let thick = top_mean(20.0, Some(material));
    let plain = top_mean(1.0, None);
    eprintln!("top under light from below: thin {thin:.4}, thick {thick:.2e}, plain {plain:.2e}");
    assert!(thin > 0.05, "{thin}");
    assert!(thick.abs() < 0.01 * thin, "{thick} against {thin}");
    assert!(plain.abs() < 0.01 * thin, "{plain}");
}

/// A medium whose light travels a ten-thousandth of a millimetre, on the bunny (a metre tall
/// at 1000 mm a unit... here 1 mm a unit, 0.15 mm tall): each vertex gives back what it
/// receives, scaled by the total diffuse reflectance, channel by channel: plain shadowed
/// transfer with that albedo.
#[test]
fn as_the_diffusion_length_vanishes_it_is_shadowed_transfer_with_the_mediums_albedo() {
    let material = medium([1e3, 3e3, 1e4], [1e4; 3]);
    let albedo: [f32; 3] = std::array::from_fn(|c| material.dipole(c).total() as f32);
    let bunny = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.obj");
    let scene = || prt_gpu::scene::load(&bunny).unwrap();
    let scattered = bake(&spec(Mode::Shadowed, Some(material)), scene(), &CpuBackend);
    let mut plain_spec = spec(Mode::Shadowed, None);
    plain_spec.transfer.albedo = Some(albedo);
    let plain = bake(&plain_spec, scene(), &CpuBackend);
    let light = prt_gpu::light::preview_light(BANDS).unwrap();
    let error = radiance_error(
        &compress::radiance(&plain.mesh.transfer, &light),
        &compress::radiance(&scattered.mesh.transfer, &light),
    );
    eprintln!("albedo {albedo:?}: {error:.2e}");
    assert!(error < 1e-4, "{error}");
    assert!(
        albedo[0] > albedo[2] + 0.1,
        "{albedo:?}: the channels differ"
    );
}

/// Interreflected, the bounces gather the light the medium sends back and it scatters again
/// where it arrives: a convex slab sees none of itself and gains nothing; two slabs 1 mm apart
/// light each other's facing sides, each bounce adding less than the one before.
#[test]
fn bounces_gather_the_scattered_light() {
    let material = medium([0.05; 3], [1.0; 3]);
    let sky = ShLight::constant(BANDS, [1.0; 3]);
    let radiance = |mode: Mode, scene: Scene| {
        let baked = bake(&spec(mode, Some(material)), scene, &CpuBackend);
        let relit = compress::radiance(&baked.mesh.transfer, &sky);
        (baked, relit)
    };
    let (_, shadowed) = radiance(Mode::Shadowed, slab(10.0, 2.0, 8));
    let (_, bounced) = radiance(Mode::Interreflected, slab(10.0, 2.0, 8));
    assert!(radiance_error(&shadowed, &bounced) < 1e-6);
    let facing = || {
        builtin::merge(&[
            slab(10.0, 2.0, 8),
            builtin::closed_box(Vec3::new(-5.0, 1.0, -5.0), Vec3::new(5.0, 3.0, 5.0), 8),
        ])
    };
    let (_, shadowed) = radiance(Mode::Shadowed, facing());
    let (baked, bounced) = radiance(Mode::Interreflected, facing());
    let gap = top_vertices(&baked.mesh.scene, 2.0);
    let mean = |relit: &[[f32; 3]]| gap.iter().map(|&v| relit[v][0] as f64).sum::<f64>();
    let gained = mean(&bounced) / mean(&shadowed);
    let energies: Vec<f64> = baked
        .report
        .bounces
        .iter()
        .map(|b| b.relative_energy)
        .collect();
    eprintln!("facing slabs: the gap's side gains {gained:.3}x; bounces {energies:?}");
    assert!(gained > 1.05, "{gained}");
    assert!(
        energies.windows(2).all(|w| w[1] < w[0]) && energies[0] < 1.0,
        "{energies:?}"
    );
}

/// The subsurface matrices applied on every backend give the same transfer (the GPU's gather
/// sums in f32), of the direct light and of its bounces.
#[test]
fn cpu_and_gpu_agree() {
    let material = medium([0.05, 0.1, 0.2], [1.0, 0.8, 0.6]);
    let spec = spec(Mode::Interreflected, Some(material));
    let light = prt_gpu::light::preview_light(BANDS).unwrap();
    let relit: Vec<Vec<[f32; 3]>> = backends()
        .iter()
        .map(|backend| {
            let scene = builtin::merge(&[
                slab(10.0, 2.0, 8),
                builtin::closed_box(Vec3::new(-5.0, 1.0, -5.0), Vec3::new(5.0, 3.0, 5.0), 8),
            ]);
            compress::radiance(&bake(&spec, scene, backend.as_ref()).mesh.transfer, &light)
        })
        .collect();
    for other in &relit[1..] {
        let error = radiance_error(&relit[0], other);
        assert!(error < 1e-5, "{error}");
    }
}

/// The medium's colour comes from its coefficients: skin, lit from everywhere, is redder than
/// it is blue (red light travels farther and is absorbed less). Every preset is a medium that
/// sends back some of its light and no more than all of it.
#[test]
fn a_preset_has_its_mediums_colour() {
    let skin = SubsurfaceMaterial::preset("skin1").expect("a preset");
    let totals: Vec<f64> = (0..3).map(|c| skin.dipole(c).total()).collect();
    assert!(totals[0] > totals[1] && totals[1] > totals[2], "{totals:?}");
    let dipole: Dipole = skin.dipole(0);
    assert!(dipole.sigma_tr > 0.0);
    for (name, medium) in prt_gpu::bake::subsurface::PRESETS {
        medium.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        for c in 0..3 {
            let total = medium.dipole(c).total();
            assert!(total > 0.0 && total <= 1.0, "{name}: {total}");
        }
    }
}

#[test]
fn bad_subsurface_options_are_refused_in_one_line() {
    for input in [
        BadInput {
            case: "unknown medium",
            file: None,
            args: &["bake", "--subsurface", "jelly", "-o", "o.glb"],
            expect: "--subsurface jelly: not a medium this tool knows",
        },
        BadInput {
            case: "custom without coefficients",
            file: None,
            args: &["bake", "--subsurface", "custom", "-o", "o.glb"],
            expect: "needs --sss-absorption and --sss-scattering",
        },
        BadInput {
            case: "coefficients alone",
            file: None,
            args: &["bake", "--sss-ior", "1.4", "-o", "o.glb"],
            expect: "ask for subsurface scattering with --subsurface",
        },
        BadInput {
            case: "none with a medium",
            file: None,
            args: &[
                "bake",
                "--subsurface",
                "none",
                "--sss-absorption",
                "1,1,1",
                "-o",
                "o.glb",
            ],
            expect: "--subsurface none bakes every material opaque",
        },
        BadInput {
            case: "lean",
            file: None,
            args: &[
                "bake",
                "--subsurface",
                "marble",
                "--storage",
                "lean",
                "-o",
                "o.glb",
            ],
            expect: "--subsurface with --storage lean",
        },
        BadInput {
            case: "negative absorption",
            file: None,
            args: &[
                "bake",
                "--subsurface",
                "custom",
                "--sss-absorption=-1",
                "--sss-scattering",
                "1",
                "-o",
                "o.glb",
            ],
            expect: "absorption and scattering must be finite and not negative",
        },
        BadInput {
            case: "index of refraction",
            file: None,
            args: &[
                "bake",
                "--subsurface",
                "skin1",
                "--sss-ior",
                "0.5",
                "-o",
                "o.glb",
            ],
            expect: "index of refraction 0.5",
        },
        BadInput {
            case: "light through the whole scene",
            file: None,
            args: &[
                "bake",
                concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/tests/data/dragon_vrip_res3.ply.gz"
                ),
                "--samples",
                "16",
                "--subsurface",
                "custom",
                "--sss-absorption",
                "0",
                "--sss-scattering",
                "0.001",
                "--sss-mm-per-unit",
                "1",
                "-o",
                "o.glb",
            ],
            expect: "matrix entries: the light travels",
        },
        BadInput {
            case: "scale",
            file: None,
            args: &[
                "bake",
                "--subsurface",
                "skin1",
                "--sss-mm-per-unit",
                "0",
                "-o",
                "o.glb",
            ],
            expect: "the scale must be a positive length",
        },
    ] {
        assert_clean_failure(&input);
    }
}

/// The file says what medium its transfer was baked in (`extras.prt`, read back and shown by
/// `info`), and passes the Khronos validator.
#[test]
fn the_file_records_its_medium() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "bake",
        "--samples",
        "16",
        "--subsurface",
        "skin1",
        "-o",
        "skin.glb",
    ];
    let out = common::prt_gpu(&args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("subsurface: ior 1.3"), "{stderr}");
    let path = dir.path().join("skin.glb");
    let stored = prt_gpu::glb::read_glb(&path).unwrap().metadata.subsurface;
    let stored = stored.expect("the medium in the metadata");
    assert_eq!(stored.material, SubsurfaceMaterial::preset("skin1"));
    assert!(stored.reach > 0.0);
    let info = common::prt_gpu(&["info", "skin.glb"], dir.path());
    let info = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.contains("subsurface:   ior 1.3, absorption [0.032, 0.17, 0.48]"),
        "{info}"
    );
    if let Some(report) = common::validate_gltf(&path) {
        assert_eq!(report.num_errors, 0, "{}", report.listing());
    }
}

/// A slab 40 mm wide and 10 mm thick (the scene in metres, as glTF's is) in the material
/// "wax", and a box beside it in "glass"; with `extensions`, wax has a scattering volume
/// (`KHR_materials_volume` + `_volume_scatter` + `_ior`) and glass a volume that only absorbs.
fn wax_and_glass_gltf(dir: &Path, extensions: bool) -> PathBuf {
    let prepared = |mesh: Scene| prt_gpu::scene::prepare::prepare(mesh).unwrap().0;
    let wax = prepared(slab(0.04, 0.01, 10));
    let glass = prepared(builtin::closed_box(
        Vec3::new(0.03, -0.01, -0.01),
        Vec3::new(0.05, 0.01, 0.01),
        4,
    ));
    let mut builder = GltfBuilder::default();
    let mut primitives = [
        builder.primitive(&wax, None),
        builder.primitive(&glass, None),
    ];
    for (material, primitive) in primitives.iter_mut().enumerate() {
        primitive["material"] = json!(material);
    }
    let mut doc = json!({
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": primitives }],
        "materials": [{ "name": "wax" }, { "name": "glass" }],
    });
    if extensions {
        doc["materials"][0]["extensions"] = json!({
            "KHR_materials_volume": {
                "thicknessFactor": 0.01,
                "attenuationColor": WAX_ATTENUATION_COLOR,
                "attenuationDistance": WAX_ATTENUATION_DISTANCE,
            },
            "KHR_materials_volume_scatter": {
                "multiscatterColor": WAX_MULTISCATTER_COLOR,
                "scatterAnisotropy": WAX_ANISOTROPY,
            },
            "KHR_materials_ior": { "ior": 1.4 },
            "KHR_materials_diffuse_transmission": { "diffuseTransmissionFactor": 1.0 },
        });
        doc["materials"][1]["extensions"] = json!({
            "KHR_materials_volume": { "thicknessFactor": 0.02, "attenuationColor": [0.9, 0.5, 0.5], "attenuationDistance": 0.1 },
            "KHR_materials_transmission": { "transmissionFactor": 1.0 },
        });
        doc["extensionsUsed"] = json!([
            "KHR_materials_volume",
            "KHR_materials_volume_scatter",
            "KHR_materials_ior",
            "KHR_materials_diffuse_transmission",
            "KHR_materials_transmission"
        ]);
    }
    let name = if extensions { "wax.gltf" } else { "plain.gltf" };
    builder.finish(doc, dir, name)
}

const WAX_ATTENUATION_COLOR: [f32; 3] = [0.5, 0.6, 0.7];
const WAX_ATTENUATION_DISTANCE: f32 = 0.002;
const WAX_MULTISCATTER_COLOR: [f32; 3] = [0.8, 0.6, 0.4];
const WAX_ANISOTROPY: f32 = 0.2;

/// Wax's medium as `KHR_materials_volume_scatter` defines it, written out here from the
/// extension's text: `sigma_t = -ln(c) / d`, Kulla & Conty's single-scatter albedo, the
/// reduced scattering `sigma_s (1 - g)`, per millimetre.
fn wax_medium() -> SubsurfaceMaterial {
    let per_mm: [(f32, f32); 3] = std::array::from_fn(|c| {
        let extinction = -(WAX_ATTENUATION_COLOR[c] as f64).ln() / WAX_ATTENUATION_DISTANCE as f64;
        let m = WAX_MULTISCATTER_COLOR[c] as f64;
        let term = 4.09712 + 4.20863 * m - (9.59217 + 41.6808 * m + 17.7126 * m * m).sqrt();
        let single = 1.0 - term * term;
        let scattering = single * extinction / 1000.0;
        let absorption = extinction / 1000.0 - scattering;
        (
            absorption as f32,
            (scattering * (1.0 - WAX_ANISOTROPY as f64)) as f32,
        )
    });
    SubsurfaceMaterial {
        ior: 1.4,
        absorption: per_mm.map(|(a, _)| a),
        reduced_scattering: per_mm.map(|(_, s)| s),
        mm_per_unit: 1000.0,
    }
}

fn bake_in_place(spec: &BakeSpec, path: &Path, backend: &dyn Backend) -> pipeline::Baked {
    let (gltf, scene) = prt_gpu::scene::gltf::load(path).unwrap();
    let source = DirectSource::Compute;
    pipeline::run(spec, scene, Some(&gltf), backend, source, &NoProgress)
        .and_then(pipeline::Bake::into_transfer)
        .unwrap()
}

/// Radiance under the preview light at each loaded vertex of `range` (the bake's vertex map
/// takes them to the prepared ones).
fn loaded_radiance(baked: &pipeline::Baked, range: std::ops::Range<usize>) -> Vec<[f32; 3]> {
    let light = prt_gpu::light::preview_light(BANDS).unwrap();
    let radiance = compress::radiance(&baked.mesh.transfer, &light);
    range
        .map(|v| radiance[baked.report.vertex_map[v] as usize])
        .collect()
}

/// A glTF material with a scattering volume bakes with subsurface transfer, in the medium the
/// extension's definitions give (checked against the formulas written out in this test): its
/// slab's transfer is that of the whole scene baked with `--subsurface` in that medium, and
/// the box beside it, whose volume only absorbs, is the plain bake's. The file records the
/// medium by material, the bake says what it did, and CPU and GPU agree with bounces.
#[test]
fn a_gltf_materials_scattering_volume_is_baked_in_its_medium() {
    let dir = tempfile::tempdir().unwrap();
    let wax = wax_and_glass_gltf(dir.path(), true);
    let plain = wax_and_glass_gltf(dir.path(), false);
    let mut in_place = spec(Mode::Shadowed, None);
    in_place.container = prt_gpu::spec::Container::GltfInPlace;
    let from_materials = bake_in_place(&in_place, &wax, &CpuBackend);
    let without = bake_in_place(&in_place, &plain, &CpuBackend);
    let mut everywhere = in_place.clone();
    everywhere.transfer.subsurface = Some(wax_medium());
    let in_wax = bake_in_place(&everywhere, &plain, &CpuBackend);

    let stored = from_materials.mesh.metadata.subsurface.as_ref().unwrap();
    assert_eq!(stored.material, None);
    assert_eq!(stored.materials.len(), 1, "{stored:?}");
    assert_eq!(stored.materials[0].material, 0);
    let (got, want) = (stored.materials[0].medium, wax_medium());
    for c in 0..3 {
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * b.abs().max(1e-3);
        assert!(
            close(got.absorption[c], want.absorption[c]),
            "{got:?} {want:?}"
        );
        assert!(
            close(got.reduced_scattering[c], want.reduced_scattering[c]),
            "{got:?}"
        );
    }
    let notes = from_materials.notes.join("\n");
    assert!(
        notes.contains("\"glass\"") && notes.contains("only absorbs"),
        "{notes}"
    );
    assert!(
        notes.contains("\"wax\"") && notes.contains("subsurface"),
        "{notes}"
    );

    let wax_vertices = 0..prepared_count(&slab(0.04, 0.01, 10));
    let glass_vertices = wax_vertices.end..from_materials.report.vertex_map.len();
    let slab_error = radiance_error(
        &loaded_radiance(&in_wax, wax_vertices.clone()),
        &loaded_radiance(&from_materials, wax_vertices.clone()),
    );
    let box_error = radiance_error(
        &loaded_radiance(&without, glass_vertices.clone()),
        &loaded_radiance(&from_materials, glass_vertices.clone()),
    );
    let plain_slab_change = radiance_error(
        &loaded_radiance(&without, wax_vertices.clone()),
        &loaded_radiance(&from_materials, wax_vertices),
    );
    eprintln!(
        "slab against --subsurface in its medium {slab_error:.2e}, box against the plain bake \
         {box_error:.2e}, slab against the plain bake {plain_slab_change:.3}"
    );
    assert!(slab_error < 1e-5, "{slab_error}");
    assert!(box_error < 1e-5, "{box_error}");
    assert!(plain_slab_change > 0.05, "{plain_slab_change}");

    let interreflected = {
        let mut spec = in_place.clone();
        spec.transfer.mode = Mode::Interreflected;
        spec
    };
    let relit: Vec<Vec<[f32; 3]>> = backends()
        .iter()
        .map(|backend| {
            let baked = bake_in_place(&interreflected, &wax, backend.as_ref());
            loaded_radiance(&baked, 0..baked.report.vertex_map.len())
        })
        .collect();
    for other in &relit[1..] {
        let error = radiance_error(&relit[0], other);
        assert!(error < 1e-5, "{error}");
    }
}

fn prepared_count(mesh: &Scene) -> usize {
    prt_gpu::scene::prepare::prepare(mesh.clone())
        .unwrap()
        .0
        .vertex_count()
}

/// The command line bakes the materials' media in place, says so, and the file it writes
/// passes the Khronos validator and shows its media in `info`; stored in one channel, or with
/// `--subsurface none`, the translucent material is baked opaque, with a note.
#[test]
fn the_command_line_bakes_a_scenes_translucent_materials() {
    let dir = tempfile::tempdir().unwrap();
    wax_and_glass_gltf(dir.path(), true);
    let bake_saying = |extra: &[&str], output: &str, said: &[&str]| {
        let mut args = vec!["bake", "wax.gltf", "--samples", "16", "-o", output];
        args.extend(extra);
        let out = common::prt_gpu(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        for line in said {
            assert!(stderr.contains(line), "{line}: {stderr}");
        }
    };
    let said = [
        "\"wax\") scatter light under the surface",
        "subsurface: material 0: ior 1.4",
    ];
    bake_saying(&[], "wax.glb", &said);
    let info = common::prt_gpu(&["info", "wax.glb"], dir.path());
    let info = String::from_utf8_lossy(&info.stdout);
    assert!(info.contains("subsurface:   material 0: ior 1.4"), "{info}");
    if let Some(report) = common::validate_gltf(&dir.path().join("wax.glb")) {
        let problems = report.num_errors + report.num_warnings;
        assert_eq!(problems, 0, "{}", report.listing());
    }
    let lean = ["\"wax\") baked opaque: --storage lean keeps one channel"];
    bake_saying(&["--storage", "lean"], "lean.glb", &lean);
    let none = ["\"wax\") baked opaque: --subsurface none"];
    bake_saying(&["--subsurface", "none"], "opaque.glb", &none);
    let opaque = prt_gpu::glb::read_metadata(&dir.path().join("opaque.glb")).unwrap();
    assert_eq!(opaque.0.subsurface, None);
}

/// Radiance under `light` of a bake's lightmap, texel by texel.
fn texel_radiance(baked: &pipeline::Baked, light: &ShLight) -> Vec<[f32; 3]> {
    let lightmap = baked.mesh.lightmap.as_ref().expect("a lightmap");
    compress::radiance(&lightmap.transfer, light)
}

/// Lightmap texels in a medium whose light goes nowhere (a diffusion length of 10^-4 units,
/// texels about 10^-1 wide) each send back their own irradiance times the medium's total
/// diffuse reflectance: the plain lightmap with that albedo, its shadows as sharp.
#[test]
fn a_lightmap_in_a_medium_whose_light_goes_nowhere_is_the_plain_one_with_its_albedo() {
    let material = medium([1e3, 3e3, 1e4], [1e4; 3]);
    let albedo: [f32; 3] = std::array::from_fn(|c| material.dipole(c).total() as f32);
    let mut scattered_spec = spec(Mode::Shadowed, Some(material));
    scattered_spec.receivers.lightmap = Some(64);
    let scattered = bake(&scattered_spec, builtin::default_scene(), &CpuBackend);
    let mut plain_spec = spec(Mode::Shadowed, None);
    plain_spec.receivers.lightmap = Some(64);
    plain_spec.transfer.albedo = Some(albedo);
    let plain = bake(&plain_spec, builtin::default_scene(), &CpuBackend);
    let light = prt_gpu::light::preview_light(BANDS).unwrap();
    let error = radiance_error(
        &texel_radiance(&plain, &light),
        &texel_radiance(&scattered, &light),
    );
    eprintln!("texels against the plain lightmap with the medium's albedo: {error:.2e}");
    assert!(error < 1e-5, "{error}");
}

/// A 1 mm slab lit only from below glows on its top in its lightmap as at its vertices: the
/// lightmap looked up at the top's vertices gives what they give, within 5% on average, and
/// no texel sends back more than a white sky would.
#[test]
fn a_lightmap_in_a_medium_glows_like_the_vertices() {
    let material = medium([0.05; 3], [1.0; 3]);
    let mut thin = spec(Mode::Shadowed, Some(material));
    thin.receivers.lightmap = Some(96);
    let baked = bake(&thin, slab(40.0, 1.0, 20), &CpuBackend);
    let below = analytic::hemisphere(BANDS, [0.0; 3], [1.0; 3]).unwrap();
    let texels = texel_radiance(&baked, &below);
    let lightmap = baked.mesh.lightmap.as_ref().unwrap();
    let flat: Vec<f32> = texels.iter().flatten().copied().collect();
    let vertices = compress::radiance(&baked.mesh.transfer, &below);
    let top = top_vertices(&baked.mesh.scene, 14.0);
    let per_vertex = lightmap.vertex_texcoords(&baked.mesh.scene).unwrap();
    let (mut from_texels, mut from_vertices) = (0.0f64, 0.0f64);
    for &v in &top {
        let uv = per_vertex[v];
        let looked_up =
            prt_gpu::bake::texels::sample_bilinear(&flat, 3, lightmap.width, lightmap.height, uv);
        from_texels += looked_up[1] as f64;
        from_vertices += vertices[v][1] as f64;
    }
    let (from_texels, from_vertices) = (
        from_texels / top.len() as f64,
        from_vertices / top.len() as f64,
    );
    eprintln!("top under light from below: texels {from_texels:.4}, vertices {from_vertices:.4}");
    assert!(from_vertices > 0.05, "{from_vertices}");
    assert!(
        (from_texels - from_vertices).abs() < 0.05 * from_vertices,
        "{from_texels} against {from_vertices}"
    );
    let sky = ShLight::constant(BANDS, [1.0; 3]);
    let most = texel_radiance(&baked, &sky)
        .iter()
        .flatten()
        .fold(0.0f32, |a, &b| a.max(b));
    assert!(most <= 1.0 + 1e-3, "{most}");
}

/// The texels' scattering runs through the backend's gather too: CPU and GPU give the same
/// lightmap, interreflected, in a scene half translucent.
#[test]
fn cpu_and_gpu_agree_on_a_lightmap_in_a_medium() {
    let material = medium([0.05, 0.1, 0.2], [1.0, 0.8, 0.6]);
    let mut spec = spec(Mode::Interreflected, Some(material));
    spec.receivers.lightmap = Some(48);
    let light = prt_gpu::light::preview_light(BANDS).unwrap();
    let relit: Vec<Vec<[f32; 3]>> = backends()
        .iter()
        .map(|backend| {
            let scene = builtin::merge(&[
                slab(10.0, 2.0, 6),
                builtin::closed_box(Vec3::new(-5.0, 1.0, -5.0), Vec3::new(5.0, 3.0, 5.0), 6),
            ]);
            texel_radiance(&bake(&spec, scene, backend.as_ref()), &light)
        })
        .collect();
    for other in &relit[1..] {
        let error = radiance_error(&relit[0], other);
        assert!(error < 1e-5, "{error}");
    }
}

/// In a scene whose own materials put one part in a medium, the opaque part's texels are the
/// plain lightmap's: looked up at its vertices, the same to float rounding.
#[test]
fn opaque_parts_of_a_translucent_scene_keep_their_plain_texels() {
    use prt_gpu::bake::subsurface::{MaterialMedium, SceneMedia, OPAQUE};
    use prt_gpu::bake::BakeOptions;
    let translucent = slab(10.0, 2.0, 6);
    let opaque = builtin::closed_box(Vec3::new(6.0, -2.0, -2.0), Vec3::new(10.0, 2.0, 2.0), 6);
    let scene = builtin::merge(&[translucent.clone(), opaque]);
    let of_vertex = (0..scene.vertex_count())
        .map(|v| {
            if v < translucent.vertex_count() {
                0
            } else {
                OPAQUE
            }
        })
        .collect();
    let medium = MaterialMedium {
        material: 0,
        medium: medium([0.05, 0.1, 0.2], [1.0, 0.8, 0.6]),
    };
    let plain = BakeOptions {
        samples: 64,
        bands: BANDS,
        lightmap: Some(64),
        ..BakeOptions::default()
    };
    let in_media = BakeOptions {
        scene_media: Some(SceneMedia {
            media: vec![medium],
            of_vertex,
        }),
        ..plain.clone()
    };
    let light = prt_gpu::light::preview_light(BANDS).unwrap();
    let at_box_vertices = |options: &BakeOptions| {
        let (baked, _) =
            prt_gpu::bake::bake(scene.clone(), options, &CpuBackend, &NoProgress).unwrap();
        let lightmap = baked.lightmap.as_ref().unwrap();
        let texels: Vec<f32> = compress::radiance(&lightmap.transfer, &light)
            .into_iter()
            .flatten()
            .collect();
        let (width, height) = (lightmap.width, lightmap.height);
        let per_vertex = lightmap.vertex_texcoords(&baked.scene).unwrap();
        (0..baked.scene.vertex_count())
            .filter(|&v| baked.scene.positions[v].x >= 6.0)
            .map(|v| {
                let looked_up = prt_gpu::bake::texels::sample_bilinear(
                    &texels,
                    3,
                    width,
                    height,
                    per_vertex[v],
                );
                [looked_up[0], looked_up[1], looked_up[2]]
            })
            .collect::<Vec<[f32; 3]>>()
    };
    let (expected, got) = (at_box_vertices(&plain), at_box_vertices(&in_media));
    assert!(expected.len() > 50, "{}", expected.len());
    let error = radiance_error(&expected, &got);
    assert!(error < 1e-5, "{error}");
}

/// Volumes that describe no medium — values of the wrong type, out of range, missing — are
/// read, not refused: the material is baked opaque, with a note naming it and why, and the
/// bake is the plain one. `--subsurface MEDIUM` on a scene with its own media says it leaves
/// them out.
#[test]
fn volumes_that_describe_no_medium_are_baked_opaque_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let path = wax_and_glass_gltf(dir.path(), true);
    let original: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let mut in_place = spec(Mode::Shadowed, None);
    in_place.container = prt_gpu::spec::Container::GltfInPlace;
    let cases: [(&str, serde_json::Value, &str); 5] = [
        ("attenuationDistance", json!(-1.0), "attenuationDistance -1"),
        (
            "attenuationDistance",
            json!("far"),
            "attenuationDistance inf",
        ),
        (
            "attenuationColor",
            json!([0.5, "red", 0.5]),
            "attenuationColor",
        ),
        (
            "attenuationColor",
            json!([0.0, 0.5, 0.5]),
            "attenuationColor",
        ),
        ("attenuationColor", json!([0.5, 0.5]), "attenuationColor"),
    ];
    for (field, value, says) in cases {
        let mut doc = original.clone();
        doc["materials"][0]["extensions"]["KHR_materials_volume"][field] = value.clone();
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let baked = bake_in_place(&in_place, &path, &CpuBackend);
        let notes = baked.notes.join("\n");
        assert!(
            notes.contains("material 0 (\"wax\") is baked opaque") && notes.contains(says),
            "{field} = {value}: {notes}"
        );
        assert_eq!(baked.mesh.metadata.subsurface, None, "{field} = {value}");
    }
    std::fs::write(&path, serde_json::to_vec(&original).unwrap()).unwrap();
    let mut everywhere = in_place.clone();
    everywhere.transfer.subsurface = SubsurfaceMaterial::preset("marble");
    let notes = bake_in_place(&everywhere, &path, &CpuBackend)
        .notes
        .join("\n");
    assert!(
        notes.contains("\"wax\"): their own media left out, --subsurface puts the whole scene"),
        "{notes}"
    );
}
