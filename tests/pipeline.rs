//! One spec, one run: a library caller with a `BakeSpec` gets what `prt-gpu bake` writes for
//! the same options, byte for byte, on both backends — compressed, lean, half-float and
//! auto-band stages included, which the command line alone had.

mod common;

use std::path::Path;

use common::{backends, prt_gpu};
use prt_gpu::bake::{Backend, CpuBackend, DirectSource, Mode, NoProgress, Storage};
use prt_gpu::local::build::OperatorShape;
use prt_gpu::local::LocalOptions;
use prt_gpu::precision::Precision;
use prt_gpu::spec::{BakeSpec, Bands, Compression, Layout};
use prt_gpu::{pipeline, scene};

const TEAPOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/teapot.obj");

/// What `pipeline::run` says in refusing `spec` for `scene`.
fn refusal_of_run(spec: &BakeSpec, scene: scene::Scene) -> String {
    pipeline::run(
        spec,
        scene,
        None,
        &CpuBackend,
        DirectSource::Compute,
        &NoProgress,
    )
    .err()
    .expect("refused")
    .to_string()
}

/// The spec of `bake TEAPOT --samples 64` with `edit` applied, and the flags that say it.
fn cases() -> Vec<(BakeSpec, Vec<&'static str>)> {
    let spec = |edit: fn(&mut BakeSpec)| {
        let mut spec = BakeSpec::default();
        spec.transfer.samples = 64;
        edit(&mut spec);
        spec
    };
    vec![
        (
            spec(|s| {
                s.storage.channels = Storage::Lean;
                s.storage.precision = Precision::F16;
                s.storage.layout = Layout::Cpca(Compression::Shape {
                    clusters: 8,
                    components: 4,
                });
            }),
            vec![
                "--storage",
                "lean",
                "--precision",
                "f16",
                "--compress",
                "8x4",
            ],
        ),
        (
            spec(|s| {
                s.transfer.bands = Bands::Auto { threshold: 0.02 };
                s.storage.precision = Precision::F16;
            }),
            vec![
                "--bands",
                "auto",
                "--bands-threshold",
                "0.02",
                "--precision",
                "f16",
            ],
        ),
    ]
}

fn run_library(spec: &BakeSpec, backend: &dyn Backend, path: &Path) -> pipeline::Baked {
    let scene = scene::load(Path::new(TEAPOT)).unwrap();
    let bake = pipeline::run(
        spec,
        scene,
        None,
        backend,
        DirectSource::Compute,
        &NoProgress,
    )
    .unwrap();
    assert!(pipeline::write(spec, &bake, None, path).unwrap().is_none());
    bake.into_transfer().unwrap()
}

#[test]
fn a_spec_run_through_the_library_writes_the_command_lines_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (k, (spec, flags)) in cases().into_iter().enumerate() {
        spec.validate().unwrap();
        for (b, backend) in backends().iter().enumerate() {
            let device = match backend.gpu_context() {
                None => "cpu",
                Some(_) => "gpu",
            };
            let cli = format!("cli{k}-{device}.glb");
            let mut args = vec![
                "bake",
                TEAPOT,
                "--samples",
                "64",
                "--device",
                device,
                "-o",
                &cli,
            ];
            args.extend(&flags);
            let out = prt_gpu(&args, d);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let cli = std::fs::read(d.join(&cli)).unwrap();
            let path = d.join(format!("library{k}-{b}.glb"));
            let baked = run_library(&spec, backend.as_ref(), &path);
            assert_eq!(
                std::fs::read(&path).unwrap(),
                cli,
                "{flags:?} on {}",
                backend.describe()
            );
            // What each stage reports is what the file holds.
            if let Bands::Auto { .. } = spec.transfer.bands {
                let chosen = baked.bands_chosen.expect("bands chosen");
                assert_eq!(chosen.bands, baked.mesh.transfer.bands());
                assert!(chosen.beyond < 0.02);
            }
            match (&baked.cpca, &baked.compressed, &baked.half_float) {
                (Some(cpca), Some(compressed), None) => {
                    assert_eq!(compressed.bytes, cpca.byte_size(Precision::F16));
                    assert!(compressed.bytes < compressed.bytes_uncompressed);
                }
                (None, None, Some(cost)) => {
                    assert_eq!(cost.bytes * 2, cost.bytes_f32);
                    assert!(cost.relit_error > 0.0 && cost.relit_error < 1e-3);
                }
                _ => panic!("{flags:?}: compressed and half-float reports disagree with the spec"),
            }
        }
    }
}

#[test]
fn a_spec_the_file_formats_cannot_hold_is_refused_before_any_ray() {
    let mut spec = BakeSpec::default();
    spec.receivers.lightmap = Some(256);
    spec.storage.layout = Layout::Cpca(Compression::Target { error: 0.05 });
    let scene = scene::builtin::default_scene();
    let error = refusal_of_run(&spec, scene);
    assert!(error.contains("--compress"), "{error}");
}

/// Local lights are a mode of the spec and of the one run: a spec whose mode is local, run
/// through the library (`pipeline::run`, then `pipeline::write`), writes what `bake --mode
/// local` writes for the same options, byte for byte; asked for SH transfer, its bake says it
/// has none.
#[test]
fn a_local_lights_spec_run_through_the_library_writes_the_command_lines_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = prt_gpu(
        &[
            "bake",
            "--mode",
            "local",
            "--samples",
            "64",
            "--depth-grid",
            "8",
            "--depth-compress",
            "8x8",
            "--operator-compress",
            "8x4",
            "--example-lights",
            "32",
            "--device",
            "cpu",
            "-o",
            "cli.glb",
        ],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let defaults = LocalOptions::default();
    let mut spec = BakeSpec {
        local: Some(LocalOptions {
            samples: 64,
            grid_side: 8,
            depth_clusters: 8,
            depth_components: 8,
            operator: OperatorShape {
                clusters: 8,
                components: 4,
                ..defaults.operator
            },
            example_lights: 32,
            ..defaults
        }),
        ..BakeSpec::default()
    };
    spec.transfer.mode = Mode::Local;
    let scene = scene::builtin::interior_scene();
    let source = DirectSource::Compute;
    let bake = pipeline::run(&spec, scene, None, &CpuBackend, source, &NoProgress).unwrap();
    let library = d.join("library.glb");
    assert!(pipeline::write(&spec, &bake, None, &library)
        .unwrap()
        .is_none());
    assert!(
        std::fs::read(&library).unwrap() == std::fs::read(d.join("cli.glb")).unwrap(),
        "the library's local-lights file differs from the command line's"
    );
    let error = bake.into_transfer().err().expect("no SH transfer");
    assert!(error.to_string().contains("mode is local"), "{error}");
}
