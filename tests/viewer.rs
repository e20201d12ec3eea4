//! The web viewer (`prt-gpu view`) in headless Chromium: its screenshots against `prt-gpu
//! render` of the same bake, camera, light and exposure; the light turned in the page against
//! `prt-gpu light --rotate`; inputs it must refuse. Chromium draws with SwiftShader (software
//! GL) and render with wgpu, so pixels differ along silhouettes and by rounding; the
//! tolerances below are stated with each check.

mod common;

use std::path::{Path, PathBuf};

use common::prt_gpu;
use image::RgbImage;
use prt_gpu::testing::{entries, report_element, Chromium};

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

/// A pixel counts as different when a channel differs by more than this (of 255): well above
/// rounding and the software rasterisers' interpolation, well below what shading changes do.
const PIXEL_THRESHOLD: u8 = 12;
/// At most this fraction of pixels may differ: silhouette pixels, where the two rasterisers'
/// coverage rules and depth precision disagree.
const MAX_DIFFERENT_FRACTION: f64 = 0.005;
/// Mean absolute difference over all pixels and channels, in 8-bit steps (seen: about 0.013,
/// with 0.01% of pixels beyond the threshold, on the teapot at 320x240).
const MAX_MEAN_DIFFERENCE: f64 = 0.25;

fn run_ok(args: &[&str], dir: &Path) -> String {
    let out = prt_gpu(args, dir);
    assert!(
        out.status.success(),
        "prt-gpu {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn teapot() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/teapot.obj")
}

/// Bakes the teapot (shadowed, `bands` bands, CPU) into `dir`, with `extra` options.
fn bake_teapot(dir: &Path, name: &str, bands: u32, extra: &[&str]) -> PathBuf {
    let teapot = teapot();
    let bands = bands.to_string();
    let mut args = vec![
        "bake",
        teapot.to_str().unwrap(),
        "--bands",
        &bands,
        "--samples",
        "256",
        "--mode",
        "shadowed",
        "--device",
        "cpu",
        "-o",
        name,
    ];
    args.extend_from_slice(extra);
    run_ok(&args, dir);
    dir.join(name)
}

/// A sky, ground and sun light of `bands` bands, written to `dir/name`, with `extra` options.
fn write_light(dir: &Path, name: &str, bands: u32, extra: &[&str]) {
    let bands = bands.to_string();
    let mut args = vec![
        "light",
        "--sky",
        "0.6,0.7,0.9",
        "--ground",
        "0.2,0.15,0.1",
        "--sun",
        "0.5,0.8,0.3",
        "--bands",
        &bands,
        "-o",
        name,
    ];
    args.extend_from_slice(extra);
    run_ok(&args, dir);
}

fn page_url(page: &Path, query: &str) -> String {
    format!("file://{}?ui=0&{query}", page.display())
}

/// `prt-gpu render` of `baked` at the test size with `extra` options, as RGB.
fn render(dir: &Path, baked: &Path, extra: &[&str]) -> RgbImage {
    let (width, height) = (WIDTH.to_string(), HEIGHT.to_string());
    let mut args = vec![
        "render",
        baked.to_str().unwrap(),
        "--width",
        &width,
        "--height",
        &height,
        "-o",
        "render.png",
    ];
    args.extend_from_slice(extra);
    run_ok(&args, dir);
    image::open(dir.join("render.png")).unwrap().into_rgb8()
}

#[derive(Debug)]
struct Difference {
    mean: f64,
    different_fraction: f64,
}

impl Difference {
    fn of(a: &RgbImage, b: &RgbImage) -> Difference {
        assert_eq!(a.dimensions(), b.dimensions());
        let mut sum = 0u64;
        let mut different = 0usize;
        for (p, q) in a.pixels().zip(b.pixels()) {
            let channel = |c: usize| p.0[c].abs_diff(q.0[c]);
            sum += (0..3).map(|c| channel(c) as u64).sum::<u64>();
            different += usize::from((0..3).any(|c| channel(c) > PIXEL_THRESHOLD));
        }
        let pixels = a.pixels().len();
        Difference {
            mean: sum as f64 / (3 * pixels) as f64,
            different_fraction: different as f64 / pixels as f64,
        }
    }

    fn within_tolerance(&self) -> bool {
        self.mean <= MAX_MEAN_DIFFERENCE && self.different_fraction <= MAX_DIFFERENT_FRACTION
    }
}

/// Whether the render is not empty: some pixels lit, some not (so agreeing means something).
fn has_contrast(image: &RgbImage) -> bool {
    let luma: Vec<u8> = image.pixels().map(|p| p.0[1]).collect();
    let (lo, hi) = (luma.iter().min().unwrap(), luma.iter().max().unwrap());
    hi - lo > 100
}

/// A camera other than the framing one: turned 100 degrees about the vertical, a little
/// closer, a narrower field of view; in the form of `--camera` and the page's `cam=`.
fn another_camera(baked: &Path) -> String {
    let scene = prt_gpu::glb::read_glb(baked).unwrap().scene;
    let framed = prt_gpu::render::Camera::framing_scene(&scene);
    let turn = glam::Quat::from_rotation_y(100f32.to_radians());
    let eye = framed.target + turn * (framed.eye - framed.target) * 0.8;
    let t = framed.target;
    format!("{},{},{},{},{},{},35", eye.x, eye.y, eye.z, t.x, t.y, t.z)
}

fn chromium_and_adapter() -> Option<Chromium> {
    let chromium = Chromium::find_or_skip()?;
    prt_gpu::device::any_adapter_or_skip()?;
    Some(chromium)
}

#[test]
fn page_matches_render_for_each_file_camera_exposure_and_tone_map() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let rgb = bake_teapot(dir.path(), "rgb.glb", 4, &[]);
    let lean = bake_teapot(
        dir.path(),
        "lean.glb",
        4,
        &["--storage", "lean", "--albedo", "0.9,0.6,0.3"],
    );
    write_light(dir.path(), "light.json", 4, &[]);
    run_ok(
        &[
            "view",
            "rgb.glb",
            "lean.glb",
            "--light",
            "light.json",
            "-o",
            "viewer.html",
        ],
        dir.path(),
    );
    let page = dir.path().join("viewer.html");
    let camera = another_camera(&rgb);
    let camera_query = format!("file=1&cam={camera}&exposure=1.5&tone=aces");
    let cases: [(&Path, &str, Vec<&str>); 4] = [
        (&rgb, "file=0", vec!["--sky"]),
        (&lean, "file=1", vec!["--sky"]),
        (
            &lean,
            &camera_query,
            vec![
                "--sky",
                "--camera",
                &camera,
                "--exposure",
                "1.5",
                "--tone-map",
                "aces",
            ],
        ),
        (
            &rgb,
            "file=0&sky=0&exposure=-0.5",
            vec!["--exposure", "-0.5"],
        ),
    ];
    for (baked, query, options) in cases {
        let mut options = options;
        options.extend(["--light", "light.json"]);
        let expected = render(dir.path(), baked, &options);
        assert!(has_contrast(&expected), "{query}: the render shows nothing");
        let shot = chromium.screenshot(&page_url(&page, query), WIDTH, HEIGHT);
        let difference = Difference::of(&shot, &expected);
        println!("{query}: {difference:?}");
        assert!(difference.within_tolerance(), "{query}: {difference:?}");
    }
    // The comparison can tell: a stop of exposure more is far outside the tolerance.
    let expected = render(dir.path(), &rgb, &["--sky", "--light", "light.json"]);
    let brighter = chromium.screenshot(&page_url(&page, "file=0&exposure=1"), WIDTH, HEIGHT);
    let difference = Difference::of(&brighter, &expected);
    assert!(
        difference.mean > 10.0 * MAX_MEAN_DIFFERENCE,
        "{difference:?}"
    );
}

#[test]
fn light_turned_in_the_page_matches_light_rotate() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_teapot(dir.path(), "teapot.glb", 4, &[]);
    write_light(dir.path(), "light.json", 4, &[]);
    write_light(dir.path(), "turned.json", 4, &["--rotate", "70,-35,20"]);
    run_ok(
        &[
            "view",
            "teapot.glb",
            "--light",
            "light.json",
            "-o",
            "viewer.html",
        ],
        dir.path(),
    );
    let page = dir.path().join("viewer.html");
    let expected = render(dir.path(), &baked, &["--sky", "--light", "turned.json"]);
    let shot = chromium.screenshot(&page_url(&page, "rot=70,-35,20"), WIDTH, HEIGHT);
    let difference = Difference::of(&shot, &expected);
    println!("rotated: {difference:?}");
    assert!(difference.within_tolerance(), "{difference:?}");
    // Unturned, the page is far from the turned render: the rotation is what agrees.
    let unturned = chromium.screenshot(&page_url(&page, ""), WIDTH, HEIGHT);
    assert!(!Difference::of(&unturned, &expected).within_tolerance());
}

/// The page's rotation of every coefficient, for a light of many bands (more than the bake:
/// the page rotates all the light's bands for its sky), against `prt-gpu light --rotate`.
#[test]
fn page_rotates_every_band_as_the_library_does() {
    let Some(chromium) = Chromium::find_or_skip() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    bake_teapot(dir.path(), "teapot.glb", 2, &[]);
    for (bands, rotation) in [(9, "70,-35,20"), (16, "-120,80,-45")] {
        write_light(dir.path(), "light.json", bands, &["--tutorial"]);
        write_light(
            dir.path(),
            "turned.json",
            bands,
            &["--tutorial", "--rotate", rotation],
        );
        run_ok(
            &[
                "view",
                "teapot.glb",
                "--light",
                "light.json",
                "-o",
                "viewer.html",
            ],
            dir.path(),
        );
        let page = dir.path().join("viewer.html");
        let dom = chromium.dump_dom(&page_url(&page, &format!("report=light&rot={rotation}")));
        let report: serde_json::Value =
            serde_json::from_str(report_element(&dom).expect("the page reports its light"))
                .unwrap();
        let turned = prt_gpu::light::read_json(&dir.path().join("turned.json")).unwrap();
        let original = prt_gpu::light::read_json(&dir.path().join("light.json")).unwrap();
        let page_coeffs = report["coeffs"].as_array().unwrap();
        assert_eq!(page_coeffs.len(), turned.coeffs.len());
        let scale = original
            .coeffs
            .iter()
            .flatten()
            .fold(0f32, |m, c| m.max(c.abs()));
        let mut worst = 0f32;
        for (k, (got, want)) in page_coeffs.iter().zip(&turned.coeffs).enumerate() {
            for c in 0..3 {
                let got = got[c].as_f64().unwrap() as f32;
                worst = worst.max((got - want[c]).abs());
                assert!(
                    (got - want[c]).abs() <= 1e-5 * scale,
                    "{bands} bands, k {k}: {got} vs {}",
                    want[c]
                );
            }
        }
        println!("{bands} bands: worst difference {worst:e} (largest coefficient {scale})");
        // Not trivially equal: the rotation moved the coefficients.
        let moved = original
            .coeffs
            .iter()
            .zip(&turned.coeffs)
            .any(|(a, b)| (a[1] - b[1]).abs() > 0.1 * scale);
        assert!(moved);
    }
}

fn assert_refused(args: &[&str], dir: &Path, why: &str) {
    let before = entries(dir);
    let out = prt_gpu(args, dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} was accepted");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    assert!(
        stderr.starts_with("error:") && stderr.contains(why),
        "{args:?}: {stderr}"
    );
    assert_eq!(entries(dir), before, "{args:?} left files behind");
}

#[test]
fn view_refuses_files_it_cannot_show_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    bake_teapot(dir.path(), "teapot.glb", 4, &[]);
    write_light(dir.path(), "two_bands.json", 2, &[]);
    let plain = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gltf/BoxTextured.glb");
    std::fs::copy(plain, dir.path().join("plain.glb")).unwrap();
    assert_refused(
        &["view", "plain.glb", "-o", "viewer.html"],
        dir.path(),
        "not a prt-gpu file",
    );
    assert_refused(
        &[
            "view",
            "teapot.glb",
            "--light",
            "two_bands.json",
            "-o",
            "viewer.html",
        ],
        dir.path(),
        "only 2",
    );
    assert_refused(
        &["view", "missing.glb", "-o", "viewer.html"],
        dir.path(),
        "missing.glb",
    );
    assert_refused(
        &["view", "teapot.glb", "-o", "viewer.txt/"],
        dir.path(),
        "viewer.txt",
    );
}
