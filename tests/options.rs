//! Nonsense options fail in one line that names the option, before any work and without output;
//! options that only read wrongly before (a light file given to `light`) work.

mod common;

use common::{assert_clean_failure, prt_gpu, BadInput};

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bunny.obj");

#[test]
fn nonsense_options_fail_in_one_line_naming_the_option() {
    let cases = [
        BadInput {
            case: "negative sun",
            file: None,
            args: &["light", "--sun", "0,1,0", "--sun-irradiance=-3"],
            expect: "--sun-irradiance <SUN_IRRADIANCE>': light cannot be negative",
        },
        BadInput {
            case: "negative sky",
            file: None,
            args: &["light", "--sky=-1,-1,-1"],
            expect: "--sky <SKY>': light cannot be negative",
        },
        BadInput {
            case: "nan sky",
            file: None,
            args: &["light", "--sky", "nan,0,0"],
            expect: "--sky <SKY>': expected three finite numbers R,G,B",
        },
        BadInput {
            case: "zero direction",
            file: None,
            args: &["light", "--sun", "0,0,0"],
            expect: "--sun <SUN>': a direction cannot be 0,0,0",
        },
        BadInput {
            case: "two numbers for a direction",
            file: None,
            args: &["light", "--directional", "1,2"],
            expect: "expected three finite numbers X,Y,Z (a direction)",
        },
        BadInput {
            case: "one angle for a rotation",
            file: None,
            args: &["light", "--sky", "1", "--rotate", "30"],
            expect: "--rotate <ROTATE>': expected three finite numbers YAW,PITCH,ROLL",
        },
        BadInput {
            case: "sun angle in degrees",
            file: None,
            args: &["light", "--sun", "0,1,0", "--sun-angle", "200"],
            expect: "--sun-angle 200 must lie in (0, 180] degrees",
        },
        BadInput {
            case: "nan exposure",
            file: None,
            args: &["render", "x.glb", "--exposure", "nan"],
            expect: "--exposure <EXPOSURE>': expected a finite number",
        },
        BadInput {
            case: "nan albedo",
            file: None,
            args: &["bake", "--albedo", "nan"],
            expect: "--albedo <ALBEDO>'",
        },
        BadInput {
            case: "nan camera",
            file: None,
            args: &["render", "x.glb", "--camera", "nan,0,0,0,0,0,45"],
            expect: "camera: every value must be finite (eye [NaN, 0, 0]",
        },
        BadInput {
            case: "zero reference samples",
            file: None,
            args: &[
                "chart",
                BUNNY,
                "--samples",
                "16",
                "--reference-samples",
                "0",
            ],
            expect: "--reference-samples 0 is out of range",
        },
        BadInput {
            case: "absurd surface points",
            file: None,
            args: &[
                "chart",
                BUNNY,
                "--samples",
                "16",
                "--surface-points",
                "999999999",
            ],
            expect: "--surface-points 999999999 is out of range",
        },
        BadInput {
            case: "absurd repeats",
            file: None,
            args: &["bench", "--repeats", "100000000"],
            expect: "--repeats 100000000 is out of range (1 to 1000)",
        },
        BadInput {
            case: "a gpu that is not there",
            file: None,
            args: &[
                "bench",
                "--samples",
                "16",
                "--device",
                "gpu",
                "--adapter",
                "no such adapter",
            ],
            expect: "no such adapter",
        },
    ];
    for case in &cases {
        assert_clean_failure(case);
    }
}

#[test]
fn light_takes_a_light_file_to_turn_it() {
    let dir = tempfile::tempdir().unwrap();
    let made = prt_gpu(&["light", "--tutorial", "-o", "a.json"], dir.path());
    assert!(made.status.success());
    let turned = prt_gpu(
        &["light", "a.json", "--rotate", "90,0,0", "-o", "b.json"],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&turned.stdout);
    assert!(
        turned.status.success() && stdout.contains("projected a.json onto 4 bands"),
        "{stdout}{}",
        String::from_utf8_lossy(&turned.stderr)
    );
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(dir.path().join(name)).unwrap()).unwrap()
    };
    // A turn keeps the band-0 term and moves the others.
    let (a, b) = (read("a.json"), read("b.json"));
    assert_eq!(a["coeffs"][0], b["coeffs"][0]);
    assert_ne!(a["coeffs"], b["coeffs"]);
}

#[test]
fn a_wgpu_backend_variable_that_names_no_backend_is_said_so() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        &["devices"][..],
        &["bake", "--samples", "16", "-o", "x.glb"],
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_prt-gpu"))
            .args(args)
            .env("WGPU_BACKEND", "banana")
            .current_dir(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert_eq!(
            stderr.trim(),
            "error: gpu: WGPU_BACKEND=\"banana\" names no backend (vulkan, metal, dx12 or gl)",
            "{args:?}"
        );
    }
    assert!(prt_gpu::testing::entries(dir.path()).is_empty());
}

#[test]
fn info_refuses_a_file_that_render_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let baked = prt_gpu(
        &[
            "bake",
            BUNNY,
            "--samples",
            "16",
            "--device",
            "cpu",
            "-o",
            "a.glb",
        ],
        dir.path(),
    );
    assert!(baked.status.success());
    assert!(prt_gpu(&["info", "a.glb"], dir.path()).status.success());
    // Point the first triangle at a vertex that does not exist.
    let path = dir.path().join("a.glb");
    let mut bytes = std::fs::read(&path).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let gltf: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let accessor = &gltf["accessors"][gltf["meshes"][0]["primitives"][0]["indices"]
        .as_u64()
        .unwrap() as usize];
    let view = &gltf["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
    let at = 28 + json_len + view["byteOffset"].as_u64().unwrap_or(0) as usize;
    bytes[at..at + 4].copy_from_slice(&100_000_000u32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    for command in ["info", "render"] {
        let out = prt_gpu(&[command, "a.glb"], dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{command} read a damaged file");
        assert!(
            stderr
                .trim()
                .ends_with("triangle 0 uses vertex 100000000 but there are only 1839 vertices"),
            "{command}: {stderr}"
        );
    }
}
