//! Subsurface scattering (`--subsurface`): a white slab that does not absorb returns no more
//! than it receives; a thin slab lit from behind glows on its front where a thick one does
//! not; as the diffusion length goes to zero the result is plain shadowed transfer with the
//! medium's total diffuse reflectance as albedo; CPU and GPU agree; bad options are refused.
//! The dipole's own closed forms are unit tests (`bake::subsurface::tests`).

mod common;

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
    pipeline::run(spec, scene, None, backend, source, &NoProgress).unwrap()
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
/// it is blue (red light travels farther and is absorbed less).
#[test]
fn a_preset_has_its_mediums_colour() {
    let skin = SubsurfaceMaterial::preset("skin1").expect("a preset");
    let totals: Vec<f64> = (0..3).map(|c| skin.dipole(c).total()).collect();
    assert!(totals[0] > totals[1] && totals[1] > totals[2], "{totals:?}");
    let dipole: Dipole = skin.dipole(0);
    assert!(dipole.sigma_tr > 0.0);
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
            case: "lightmap",
            file: None,
            args: &[
                "bake",
                "--subsurface",
                "marble",
                "--lightmap",
                "64",
                "-o",
                "o.glb",
            ],
            expect: "--subsurface with --lightmap",
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
    assert_eq!(Some(stored.material), SubsurfaceMaterial::preset("skin1"));
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
