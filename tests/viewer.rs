//! The web viewer (`prt-gpu view`) in headless Chromium: its screenshots against `prt-gpu
//! render` of the same bake, camera, light and exposure; the light turned in the page against
//! `prt-gpu light --rotate`; inputs it must refuse. Chromium draws with SwiftShader (software
//! GL) and render with wgpu, so pixels differ along silhouettes and by rounding; the
//! tolerances below are stated with each check.

mod common;

use std::path::{Path, PathBuf};

use common::pixels::{has_contrast, Difference, MAX_MEAN_DIFFERENCE, PIXEL_THRESHOLD};
use common::{prt_gpu, write_light};
use image::RgbImage;
use prt_gpu::testing::{entries, report_element, Chromium};

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

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

/// The page at `url`, its screenshot checked to match `expected` (`render`'s image) within
/// the tolerance of `common::pixels`.
fn shot_matching(chromium: &Chromium, url: &str, expected: &RgbImage) -> RgbImage {
    let shot = chromium.screenshot(url, WIDTH, HEIGHT);
    let difference = Difference::of(&shot, expected);
    println!("{url}: {difference:?}");
    assert!(difference.within_tolerance(), "{url}: {difference:?}");
    shot
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
    // Compressed (CPCA): the page shows the reconstruction; render relights the clusters.
    let compressed = bake_teapot(dir.path(), "compressed.glb", 4, &["--compress", "8x4"]);
    write_light(dir.path(), "light.json", 4, &[]);
    run_ok(
        &[
            "view",
            "rgb.glb",
            "lean.glb",
            "compressed.glb",
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
    let cases: [(&Path, &str, Vec<&str>); 5] = [
        (&rgb, "file=0", vec!["--sky"]),
        (&lean, "file=1", vec!["--sky"]),
        (&compressed, "file=2", vec!["--sky"]),
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
        shot_matching(&chromium, &page_url(&page, query), &expected);
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

/// Zonal transfer and a bent mesh: the page with the teapot bent by 60 degrees and relit from
/// its zonal transfer about the turned axes matches `render --zonal --bend 60` of the same bake
/// and camera; bent and drawn from its SH transfer as baked (static PRT), it matches `render
/// --bend 60`, and unbent from its zonal transfer, `render --zonal`. The bent zonal and the
/// bent SH images differ far beyond the tolerance: the comparison sees the axes turn.
#[test]
fn page_bends_and_relights_zonal_transfer_as_render_does() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_teapot(
        dir.path(),
        "zonal.glb",
        4,
        &["--zonal", "4", "--zonal-axis", "fitted"],
    );
    write_light(dir.path(), "light.json", 4, &[]);
    run_ok(
        &[
            "view",
            "zonal.glb",
            "--light",
            "light.json",
            "-o",
            "viewer.html",
        ],
        dir.path(),
    );
    let page = dir.path().join("viewer.html");
    let camera = another_camera(&baked);
    let camera_query = format!("cam={camera}&sky=0");
    let base = ["--light", "light.json", "--camera", &camera];
    let mut shots = Vec::new();
    for (query, extra) in [
        ("zonal=1&bend=60", &["--zonal", "--bend", "60"][..]),
        ("bend=60", &["--bend", "60"][..]),
        ("zonal=1", &["--zonal"][..]),
    ] {
        let options: Vec<&str> = base.iter().chain(extra).copied().collect();
        let expected = render(dir.path(), &baked, &options);
        assert!(has_contrast(&expected), "{query}: the render shows nothing");
        let url = page_url(&page, &format!("{camera_query}&{query}"));
        let shot = shot_matching(&chromium, &url, &expected);
        shots.push(shot);
    }
    let difference = Difference::of(&shots[0], &shots[1]);
    assert!(
        difference.mean > 10.0 * MAX_MEAN_DIFFERENCE,
        "{difference:?}"
    );
}

/// A lightmapped file: the page relights the four texels around each pixel's lightmap
/// coordinates and blends them bilinearly, as render looks its relit texels up.
#[test]
fn lightmapped_page_matches_render() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_teapot(dir.path(), "lightmapped.glb", 4, &["--lightmap", "128"]);
    write_light(dir.path(), "light.json", 4, &[]);
    run_ok(
        &[
            "view",
            "lightmapped.glb",
            "--light",
            "light.json",
            "-o",
            "viewer.html",
        ],
        dir.path(),
    );
    let page = dir.path().join("viewer.html");
    let camera = another_camera(&baked);
    for (query, options) in [
        (String::new(), vec!["--sky"]),
        (
            format!("cam={camera}&exposure=1&sky=0"),
            vec!["--camera", &camera, "--exposure", "1"],
        ),
    ] {
        let mut options = options;
        options.extend(["--light", "light.json"]);
        let expected = render(dir.path(), &baked, &options);
        assert!(has_contrast(&expected));
        shot_matching(&chromium, &page_url(&page, &query), &expected);
    }
    // X3D carries per-vertex transfer only.
    assert_refused(
        &["export", "x3d", "lightmapped.glb", "-o", "scene.x3d"],
        dir.path(),
        "lightmap",
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
    shot_matching(&chromium, &page_url(&page, "rot=70,-35,20"), &expected);
    // Unturned, the page is far from the turned render: the rotation is what agrees.
    let unturned = chromium.screenshot(&page_url(&page, ""), WIDTH, HEIGHT);
    assert!(!Difference::of(&unturned, &expected).within_tolerance());
}

fn studio_map() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/studio.exr")
}

/// What the page should show behind the model: the library's lat-long copy of the map, looked
/// up bilinearly along each pixel's view ray turned back by `yaw_pitch_roll`, tone-mapped
/// (Reinhard, no exposure) and sRGB-encoded to 8 bits.
fn expected_sky(camera: &prt_gpu::render::Camera, yaw_pitch_roll: [f64; 3]) -> RgbImage {
    use prt_gpu::light::{envmap, sky, Mapping};
    use prt_gpu::render::{pixel_ray, tone_map, ToneMap};
    let map = envmap::load(&studio_map()).unwrap();
    let copy = sky::latlong_copy(&map, Mapping::Latlong, prt_gpu::view::SKY_MAP_MAX_WIDTH).unwrap();
    let [yaw, pitch, roll] = yaw_pitch_roll.map(f64::to_radians);
    let turn = glam::DMat3::from_rotation_y(yaw)
        * glam::DMat3::from_rotation_x(pitch)
        * glam::DMat3::from_rotation_z(roll);
    RgbImage::from_fn(WIDTH, HEIGHT, |x, y| {
        let ray = pixel_ray(camera, WIDTH, HEIGHT, x, y);
        let radiance = sky::sample_latlong(&copy, turn.transpose() * ray);
        let encode = |v: f32| prt_gpu::color::srgb_encode(tone_map(v, ToneMap::Reinhard, 0.0));
        image::Rgb(radiance.map(|v| (encode(v).clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
    })
}

/// Pixels the model covers, and their neighbours: lit in a shot with no sky and a bright
/// exposure (nothing of the model stays black at +6 stops).
fn model_mask(shot_without_sky: &RgbImage) -> Vec<bool> {
    let (w, h) = shot_without_sky.dimensions();
    let lit = |x: u32, y: u32| shot_without_sky.get_pixel(x, y).0.iter().any(|&c| c > 0);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            (x.saturating_sub(1)..(x + 2).min(w))
                .any(|i| (y.saturating_sub(1)..(y + 2).min(h)).any(|j| lit(i, j)))
        })
        .collect()
}

/// Sky pixels (outside `mask`) of `shot` against `expected`: their count, the mean absolute
/// difference in 8-bit steps, and the fraction with a channel off by more than the threshold.
fn sky_difference(shot: &RgbImage, expected: &RgbImage, mask: &[bool]) -> (usize, f64, f64) {
    let mut sum = 0u64;
    let (mut count, mut different) = (0usize, 0usize);
    for ((p, q), &covered) in shot.pixels().zip(expected.pixels()).zip(mask) {
        if covered {
            continue;
        }
        let channel = |c: usize| p.0[c].abs_diff(q.0[c]);
        sum += (0..3).map(|c| channel(c) as u64).sum::<u64>();
        different += usize::from((0..3).any(|c| channel(c) > PIXEL_THRESHOLD));
        count += 1;
    }
    (
        count,
        sum as f64 / (3 * count.max(1)) as f64,
        different as f64 / count.max(1) as f64,
    )
}

/// The environment map as the sky: the page's background pixels against the library's map
/// reading and lat-long mapping along the same rays, unturned and turned with the light.
/// Tolerance: a mean difference of at most 0.1 of an 8-bit step over the sky pixels and at
/// most 0.1% of them off by more than PIXEL_THRESHOLD (half floats, SwiftShader's filtering
/// weights, f32 rays against f64 ones; seen: mean 0.006 unturned, 0.008 turned, none beyond).
#[test]
fn page_draws_the_environment_map_as_the_sky() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let baked = bake_teapot(dir.path(), "teapot.glb", 3, &[]);
    let studio = studio_map();
    let studio = studio.to_str().unwrap();
    run_ok(
        &["view", "teapot.glb", "--light", studio, "-o", "viewer.html"],
        dir.path(),
    );
    run_ok(
        &["light", studio, "--bands", "3", "-o", "light.json"],
        dir.path(),
    );
    run_ok(
        &[
            "view",
            "teapot.glb",
            "--light",
            "light.json",
            "-o",
            "sh.html",
        ],
        dir.path(),
    );
    let page = dir.path().join("viewer.html");
    // The embedded map is bounded: 512 x 256 half-float texels, about 1 MB of base64.
    let size = |name: &str| std::fs::metadata(dir.path().join(name)).unwrap().len();
    println!(
        "viewer.html {} bytes, with light.json {} bytes",
        size("viewer.html"),
        size("sh.html")
    );
    assert!(size("viewer.html") < size("sh.html") + 1_100_000);
    // A wide view: the teapot in the middle, the studio around it.
    let scene = prt_gpu::glb::read_glb(&baked).unwrap().scene;
    let mut camera = prt_gpu::render::Camera::framing_scene(&scene);
    camera.vertical_fov_deg = 100.0;
    let (e, t) = (camera.eye, camera.target);
    let cam = format!("{},{},{},{},{},{},100", e.x, e.y, e.z, t.x, t.y, t.z);
    let shot = |query: &str| {
        chromium.screenshot(
            &page_url(&page, &format!("cam={cam}&{query}")),
            WIDTH,
            HEIGHT,
        )
    };
    let mask = model_mask(&shot("sky=0&exposure=6"));
    let covered = mask.iter().filter(|&&m| m).count();
    assert!(
        covered > 100 && covered < mask.len() / 2,
        "{covered} pixels of model"
    );
    for rotation in [[0.0, 0.0, 0.0], [70.0, -35.0, 20.0]] {
        let query = format!("rot={},{},{}", rotation[0], rotation[1], rotation[2]);
        let expected = expected_sky(&camera, rotation);
        let (count, mean, fraction) = sky_difference(&shot(&query), &expected, &mask);
        println!("map sky {query}: {count} pixels, mean {mean:.3}, beyond threshold {fraction:.4}");
        assert!(
            mean <= 1.0 && fraction <= 0.01,
            "{query}: mean {mean}, fraction {fraction}"
        );
        // The comparison can tell: the SH sky, or the map unturned, is far off.
        let (_, sh_mean, _) = sky_difference(&shot(&format!("{query}&sky=sh")), &expected, &mask);
        assert!(sh_mean > 5.0, "{query}: the SH sky is within {sh_mean}");
    }
    let turned = expected_sky(&camera, [70.0, -35.0, 20.0]);
    let (_, unturned_mean, _) = sky_difference(&shot(""), &turned, &mask);
    assert!(unturned_mean > 5.0, "unturned within {unturned_mean}");
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

/// X_ITE's script, installed by ci/test.sh (npm ci in ci/x3d); `None` with a printed reason
/// where it is missing, except under CI: a panic.
fn x_ite_or_skip() -> Option<PathBuf> {
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("ci/x3d/node_modules/x_ite/dist/x_ite.min.js");
    if script.is_file() {
        return Some(script);
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "X_ITE is missing under CI (ci/test.sh installs it)"
    );
    eprintln!("skipping: X_ITE is not installed (npm ci --prefix ci/x3d)");
    None
}

/// The X3D test page (tests/data/x_ite_page.html) with X_ITE and the scene `x3d` filled in.
fn write_x_ite_page(dir: &Path, x_ite: &Path, x3d: &str) -> PathBuf {
    // X_ITE sizes its canvas from the element's own size: 100vw/100vh left it unsized when the
    // screenshot was taken, so the window size is written in.
    assert!(
        !x3d.contains("</script"),
        "the scene would end the page's script element"
    );
    let template = include_str!("data/x_ite_page.html");
    let page = template
        .replace("{{X_ITE}}", &format!("file://{}", x_ite.display()))
        .replace("{{WIDTH}}", &WIDTH.to_string())
        .replace("{{HEIGHT}}", &HEIGHT.to_string())
        .replace("{{SCENE}}", x3d);
    let path = dir.join("x_ite_page.html");
    std::fs::write(&path, page).unwrap();
    path
}

/// A screenshot of the X3D page once X_ITE has drawn: virtual time runs out before a busy
/// machine has loaded X_ITE now and then, leaving a black window, so that is tried again.
fn x_ite_screenshot(chromium: &Chromium, page: &Path) -> RgbImage {
    let url = format!("file://{}", page.display());
    for _ in 0..4 {
        let shot = chromium.screenshot(&url, WIDTH, HEIGHT);
        if shot.pixels().any(|p| p.0 != [0, 0, 0]) {
            return shot;
        }
        eprintln!("X_ITE had not drawn when the screenshot was taken; again");
    }
    panic!("X_ITE drew nothing in four tries");
}

/// What X_ITE reported on loading `x3d`.
fn x_ite_report(chromium: &Chromium, dir: &Path, x_ite: &Path, x3d: &str) -> serde_json::Value {
    let page = write_x_ite_page(dir, x_ite, x3d);
    for _ in 0..4 {
        let dom = chromium.dump_dom(&format!("file://{}", page.display()));
        match report_element(&dom).filter(|text| !text.is_empty()) {
            Some(text) => return serde_json::from_str(text).unwrap(),
            // As with the screenshots: X_ITE not loaded yet when virtual time ran out.
            None => eprintln!("X_ITE had not reported when the page was read; again"),
        }
    }
    panic!("the X3D page reported nothing in four tries");
}

#[test]
fn x3d_export_loads_in_x_ite_and_matches_render() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let Some(x_ite) = x_ite_or_skip() else { return };
    // X_ITE parses and draws after the page's load event; virtual time lets it finish.
    let chromium = chromium.after_virtual_time(120_000);
    let dir = tempfile::tempdir().unwrap();
    let rgb = bake_teapot(dir.path(), "rgb.glb", 4, &[]);
    let lean = bake_teapot(
        dir.path(),
        "lean.glb",
        4,
        &["--storage", "lean", "--albedo", "0.9,0.6,0.3"],
    );
    write_light(dir.path(), "light.json", 4, &[]);
    let camera = another_camera(&rgb);
    let cases: [(&Path, Vec<&str>); 2] = [
        (&rgb, vec![]),
        (
            &lean,
            vec![
                "--camera",
                &camera,
                "--exposure",
                "1.5",
                "--tone-map",
                "aces",
            ],
        ),
    ];
    for (baked, options) in cases {
        let name = baked.to_str().unwrap();
        let mut args = vec![
            "export",
            "x3d",
            name,
            "--light",
            "light.json",
            "-o",
            "scene.x3d",
        ];
        args.extend(&options);
        run_ok(&args, dir.path());
        let x3d = std::fs::read_to_string(dir.path().join("scene.x3d")).unwrap();
        let report = x_ite_report(&chromium, dir.path(), &x_ite, &x3d);
        assert_eq!(report["loaded"], true, "{name}: {report}");
        assert_eq!(report["shaderValid"], true, "{name}: {report}");
        assert_eq!(
            report["messages"],
            serde_json::json!([]),
            "{name}: {report}"
        );

        let mut render_options = options.clone();
        render_options.extend(["--light", "light.json"]);
        let expected = render(dir.path(), baked, &render_options);
        assert!(has_contrast(&expected));
        let page = dir.path().join("x_ite_page.html");
        let shot = x_ite_screenshot(&chromium, &page);
        let difference = Difference::of(&shot, &expected);
        println!("x3d {name}: {difference:?}");
        assert!(difference.within_tolerance(), "{name}: {difference:?}");
    }
}

/// X_ITE's loader is the validity check, so it must catch what is wrong: a misspelt node,
/// malformed XML, a shader that does not compile. (It passes over unknown or malformed field
/// values silently: `numComponents='four'` loads without a word, so fields are not checked.)
#[test]
fn x_ite_reports_broken_x3d() {
    let Some(chromium) = Chromium::find_or_skip() else {
        return;
    };
    let Some(x_ite) = x_ite_or_skip() else { return };
    let chromium = chromium.after_virtual_time(120_000);
    let dir = tempfile::tempdir().unwrap();
    bake_teapot(dir.path(), "teapot.glb", 2, &[]);
    run_ok(
        &["export", "x3d", "teapot.glb", "-o", "scene.x3d"],
        dir.path(),
    );
    let x3d = std::fs::read_to_string(dir.path().join("scene.x3d")).unwrap();
    let report = x_ite_report(&chromium, dir.path(), &x_ite, &x3d);
    assert_eq!(report["shaderValid"], true, "{report}");
    assert_eq!(report["messages"], serde_json::json!([]), "{report}");
    let breakages = [
        ("<Coordinate ", "<Coordinates "),
        ("</Shape>", "</Shap>"),
        ("sum += light[k] * t;", "sum += light[k] * t"),
    ];
    for (from, to) in breakages {
        assert!(x3d.contains(from), "{from}");
        let report = x_ite_report(&chromium, dir.path(), &x_ite, &x3d.replace(from, to));
        let flagged = report["messages"].as_array().is_some_and(|m| !m.is_empty())
            || report["shaderValid"] != true
            || report["loaded"] != true;
        assert!(flagged, "{to:?} went unnoticed: {report}");
    }
}

#[test]
fn export_x3d_refuses_what_it_cannot_write_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    bake_teapot(dir.path(), "teapot.glb", 4, &[]);
    bake_teapot(dir.path(), "wide.glb", 5, &[]);
    write_light(dir.path(), "two_bands.json", 2, &[]);
    let plain = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gltf/BoxTextured.glb");
    std::fs::copy(plain, dir.path().join("plain.glb")).unwrap();
    let export = |file: &str, extra: &[&str], why: &str| {
        let mut args = vec!["export", "x3d", file, "-o", "scene.x3d"];
        args.extend(extra);
        assert_refused(&args, dir.path(), why);
    };
    export("plain.glb", &[], "not a prt-gpu file");
    export(
        "teapot.glb",
        &["--light", "two_bands.json"],
        "the light has 2 bands",
    );
    // 5 bands x 3 channels = 75 floats: 19 attributes, more than WebGL leaves.
    export("wide.glb", &[], "vertex attributes");
}

/// Probes: the page's test sphere, lit by the probes at its centre, against `render
/// --probe-sphere` at the same place (a grid of radiance probes, interpolated; a few given
/// points in the irradiance form, the nearest valid one), with the tolerances of the files'
/// own comparisons; and the irradiance SH the page computes at the centre against the
/// library's (`ProbeSet::interpolate`, `ProbeSet::irradiance`) for random normals.
#[test]
fn page_lights_a_sphere_with_the_probes_as_render_does() {
    let Some(chromium) = chromium_and_adapter() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bake = ["bake", "--samples", "64", "--device", "cpu"];
    run_ok(
        &[&bake[..], &["--probes", "0.5", "-o", "grid.glb"]].concat(),
        d,
    );
    std::fs::write(
        d.join("points.txt"),
        "1.2 0.5 1.2\n-1 0.8 0.9\n0.3 1.6 -0.4\n",
    )
    .unwrap();
    let points = [
        "--probe-points",
        "points.txt",
        "--probe-form",
        "irradiance",
        "--mode",
        "interreflected",
        "-o",
        "points.glb",
    ];
    run_ok(&[&bake[..], &points].concat(), d);
    write_light(d, "light.json", 4, &[]);
    run_ok(
        &[
            "view",
            "grid.glb",
            "points.glb",
            "--light",
            "light.json",
            "-o",
            "viewer.html",
        ],
        d,
    );
    let page = d.join("viewer.html");
    let grid = d.join("grid.glb");
    let camera = another_camera(&grid);
    let turned_query = format!("file=0&sky=0&cam={camera}");
    let cases: [(&str, &str, &str, Vec<&str>); 3] = [
        ("grid.glb", "file=0", "1.2,0.5,1.2,0.4", vec!["--sky"]),
        (
            "grid.glb",
            &turned_query,
            "1.2,0.5,1.2,0.4",
            vec!["--camera", &camera],
        ),
        (
            "points.glb",
            "file=1&exposure=1",
            "-0.9,0.7,0.9,0.5",
            vec!["--sky", "--exposure", "1"],
        ),
    ];
    for (file, query, sphere, options) in cases {
        let mut options = options;
        options.extend(["--light", "light.json", "--probe-sphere", sphere]);
        let expected = render(d, &d.join(file), &options);
        assert!(has_contrast(&expected), "{query}: the render shows nothing");
        let shot = |sphere: &str| {
            let url = page_url(&page, &format!("{query}&sphere={sphere}"));
            chromium.screenshot(&url, WIDTH, HEIGHT)
        };
        let difference = Difference::of(&shot(sphere), &expected);
        println!("{query}, sphere {sphere}: {difference:?}");
        assert!(difference.within_tolerance(), "{query}: {difference:?}");
        // The sphere is seen: without it the page is outside the tolerance.
        let without = Difference::of(&shot("0"), &expected);
        assert!(!without.within_tolerance(), "{query}: {without:?}");
    }

    let light = prt_gpu::light::read_json(&d.join("light.json")).unwrap();
    let probes = prt_gpu::glb::probes::read_probes(&grid).unwrap().unwrap();
    for (query, centre) in [
        (
            "sphere=0.37,0.61,-0.23",
            Some(glam::Vec3::new(0.37, 0.61, -0.23)),
        ),
        // The default place: a valid probe.
        ("", None),
    ] {
        let dom = chromium.dump_dom(&page_url(&page, &format!("report=sphere&{query}")));
        let report: serde_json::Value =
            serde_json::from_str(report_element(&dom).expect("the page reports its sphere"))
                .unwrap();
        let at: Vec<f32> = report["sphere"]["centre"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap() as f32)
            .collect();
        let at = glam::Vec3::from_slice(&at);
        match centre {
            Some(centre) => assert_eq!(at, centre),
            None => assert!(probes
                .positions
                .iter()
                .zip(&probes.status)
                .any(|(&p, s)| { p == at && *s != prt_gpu::probes::ProbeStatus::Invalid })),
        }
        let irradiance: Vec<[f64; 3]> =
            serde_json::from_value(report["irradiance"].clone()).unwrap();
        assert_eq!(irradiance.len(), probes.rows);
        let matrix = probes.interpolate(at).unwrap();
        for normal in prt_gpu::sampling::fibonacci_sphere(50, 7).directions {
            let normal = normal.as_dvec3();
            let expected = probes.irradiance(&matrix, &light.coeffs, normal);
            let basis = prt_gpu::sh::basis(probes.bands, normal);
            for rgb in 0..3 {
                let page: f64 = irradiance.iter().zip(&basis).map(|(e, y)| e[rgb] * y).sum();
                let tolerance = 1e-5 * expected[rgb].abs().max(1.0);
                assert!(
                    (page - expected[rgb]).abs() < tolerance,
                    "{query}: {page} vs {expected:?}"
                );
            }
        }
    }
}
