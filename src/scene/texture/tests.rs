//! Tests of `texture`.

use std::f32::consts::FRAC_PI_2;
use std::io::Cursor;

use super::*;

fn texture(width: u32, height: u32, texel: impl Fn(u32, u32) -> [f32; 4]) -> Texture {
    let texels = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| texel(x, y))
        .collect();
    Texture::new(width, height, texels, "test").unwrap()
}

fn grey(value: f32) -> [f32; 4] {
    [value, value, value, 1.0]
}

/// An n × n grid of vertices over [lo, hi]² in the z = 0 plane with UV = (x, y); each cell
/// (i, j) is split along its diagonal from corner (i, j) to corner (i + 1, j + 1).
fn grid(n: u32, lo: f32, hi: f32) -> (Vec<Vec3>, Vec<[f32; 2]>, Vec<[u32; 3]>) {
    let at = |k: u32| lo + (hi - lo) * k as f32 / (n - 1) as f32;
    let uvs: Vec<[f32; 2]> = (0..n)
        .flat_map(|j| (0..n).map(move |i| [at(i), at(j)]))
        .collect();
    let positions = uvs.iter().map(|&[x, y]| Vec3::new(x, y, 0.0)).collect();
    let index = |i: u32, j: u32| j * n + i;
    let triangles = (0..n - 1)
        .flat_map(|j| (0..n - 1).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let (a, b) = (index(i, j), index(i + 1, j));
            let (c, d) = (index(i + 1, j + 1), index(i, j + 1));
            [[a, b, c], [a, c, d]]
        })
        .collect();
    (positions, uvs, triangles)
}

fn assert_close(actual: [f32; 4], expected: [f32; 4], tolerance: f32, what: &str) {
    for c in 0..4 {
        assert!(
            (actual[c] - expected[c]).abs() <= tolerance,
            "{what}: {actual:?}, expected {expected:?} ± {tolerance}"
        );
    }
}

fn encode(image: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut bytes = Vec::new();
    image
        .write_to(&mut Cursor::new(&mut bytes), format)
        .unwrap();
    bytes
}

#[test]
fn constant_texture_gives_every_vertex_its_colour() {
    let colour = [0.2, 0.45, 0.7, 0.9];
    let texture = texture(7, 5, |_, _| colour);
    // Arbitrary triangles, UVs far outside [0, 1], a zero-area triangle, a lone vertex.
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(3.0, 0.1, 0.5),
        Vec3::new(0.3, 2.0, -1.0),
        Vec3::new(2.0, 2.0, 2.0),
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(9.0, 9.0, 9.0),
    ];
    let uvs = vec![
        [0.1, 0.2],
        [7.5, -3.0],
        [0.3, 0.9],
        [-20.0, 40.0],
        [0.5, 0.5],
        [0.9, 0.1],
    ];
    let triangles = vec![[0, 1, 2], [1, 3, 2], [0, 3, 4], [4, 4, 3]];
    for transform in [
        UvTransform::default(),
        UvTransform {
            offset: [0.3, -2.0],
            rotation: 0.7,
            scale: [5.0, -3.0],
        },
    ] {
        let averages = vertex_averages(&positions, &uvs, &triangles, &texture, &transform);
        assert_eq!(averages.len(), positions.len());
        for (v, average) in averages.into_iter().enumerate() {
            assert_close(average, colour, 1e-6, &format!("vertex {v}"));
        }
    }
}

#[test]
fn half_black_half_white_plane_averages_by_hat_support() {
    // 17 × 17 vertices: the middle column (i = 8) lies on the edge between the halves.
    let (positions, uvs, triangles) = grid(17, 0.0, 1.0);
    let halves = texture(256, 2, |x, _| grey(if x < 128 { 0.0 } else { 1.0 }))
        .with_wrap(Wrap::ClampToEdge, Wrap::ClampToEdge);
    let averages = vertex_averages(
        &positions,
        &uvs,
        &triangles,
        &halves,
        &UvTransform::default(),
    );
    for (v, average) in averages.iter().enumerate() {
        let (i, j) = (v % 17, v / 17);
        let expected = match (i, j) {
            (0..=7, _) => 0.0,
            (9.., _) => 1.0,
            // On the bottom edge two of the vertex's three triangles are on the white
            // side, on the top edge one of three; inside, the hexagon is point-symmetric.
            (8, 0) => 2.0 / 3.0,
            (8, 16) => 1.0 / 3.0,
            (8, _) => 0.5,
        };
        assert_close(
            *average,
            grey(expected),
            1e-3,
            &format!("vertex ({i}, {j})"),
        );
    }
}

#[test]
fn fine_checkerboard_averages_to_its_mean_where_point_samples_alias() {
    let checks = texture(256, 256, |x, y| grey(((x + y) % 2) as f32));
    // 4 × 4 vertices on texel centres 85 texels apart: point samples are pure black or
    // white (texel (85i, 85j) is white when i + j is odd).
    let (positions, uvs, triangles) = grid(4, 0.5 / 256.0, 255.5 / 256.0);
    let averages = vertex_averages(
        &positions,
        &uvs,
        &triangles,
        &checks,
        &UvTransform::default(),
    );
    let mut point_samples = Vec::new();
    for (v, average) in averages.iter().enumerate() {
        let point = checks.sample(uvs[v])[0];
        assert!(
            point == 0.0 || point == 1.0,
            "vertex {v}: point sample {point}"
        );
        point_samples.push(point);
        assert_close(*average, grey(0.5), 0.01, &format!("vertex {v}"));
    }
    assert!(point_samples.contains(&0.0) && point_samples.contains(&1.0));
}

#[test]
fn triangles_past_the_sample_cap_average_on_a_mip_level() {
    // A quad whose UVs tile a 1-texel checkerboard 8 × 8 times: each triangle's diagonal
    // spans 2,896 texels and would want 5,793 subdivisions, so it is sampled five levels
    // down (8 × 8 texels, each the mean of 32 × 32 checks). Capped on the base level
    // instead, the samples would fall 11 texels apart and alias.
    let checks = texture(256, 256, |x, y| grey(((x + y) % 2) as f32));
    let (positions, uvs, triangles) = grid(2, 0.0, 1.0);
    let tiled = UvTransform {
        scale: [8.0, 8.0],
        ..UvTransform::default()
    };
    let dims = level_dims(256, 256);
    let corners = triangles[0].map(|i| tiled.apply_f64(uvs[i as usize]));
    let (level, subdivisions) = sampling_plan(&corners, &dims);
    assert_eq!((level, subdivisions), (5, 182));
    let averages = vertex_averages(&positions, &uvs, &triangles, &checks, &tiled);
    for (v, average) in averages.into_iter().enumerate() {
        assert_close(average, grey(0.5), 1e-3, &format!("vertex {v}"));
    }
}

#[test]
fn a_lone_triangle_weights_by_the_hat_function() {
    // On a linear texture f = Σ f_k λ_k the hat-weighted mean has a closed form:
    // ∫ λ_a λ_a dA = A/6 and ∫ λ_a λ_b dA = A/12, over ∫ λ_a dA = A/3, so vertex a gets
    // f_a/2 + f_b/4 + f_c/4 (a plain area average would give the mean of the three).
    let ramp =
        texture(64, 1, |x, _| grey(x as f32)).with_wrap(Wrap::ClampToEdge, Wrap::ClampToEdge);
    let positions = vec![
        Vec3::ZERO,
        Vec3::new(2.0, 0.5, 0.0),
        Vec3::new(0.3, 1.0, 1.0),
    ];
    let uvs: [[f32; 2]; 3] = [[0.1, 0.2], [0.8, 0.5], [0.4, 0.9]];
    // Texel centres are at (x + ½)/64, so the bilinear ramp is f(u) = 64u − ½.
    let f = uvs.map(|[u, _]| 64.0 * u - 0.5);
    let averages = vertex_averages(
        &positions,
        &uvs,
        &[[0, 1, 2]],
        &ramp,
        &UvTransform::default(),
    );
    for k in 0..3 {
        let expected = f[k] / 2.0 + f[(k + 1) % 3] / 4.0 + f[(k + 2) % 3] / 4.0;
        assert_close(
            averages[k],
            [expected, expected, expected, 1.0],
            0.01,
            &format!("corner {k}"),
        );
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    // 4,802 triangles: more than one block of TRIANGLES_PER_BLOCK.
    let (positions, uvs, triangles) = grid(50, -0.3, 1.7);
    let noise = texture(97, 61, |x, y| {
        grey(((x * 7919 + y * 104_729) % 101) as f32 / 100.0)
    });
    let transform = UvTransform {
        rotation: 0.3,
        ..UvTransform::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| vertex_averages(&positions, &uvs, &triangles, &noise, &transform))
    };
    let one = run(1);
    assert_eq!(one, run(3));
    assert_eq!(one, run(1));
}

#[test]
fn isolated_vertices_and_zero_area_triangles_take_a_point_sample() {
    let ramp = texture(8, 1, |x, _| grey(x as f32 / 7.0));
    let positions = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(2.0, 0.0, 0.0), // collinear: the only triangle has no area
        Vec3::new(5.0, 5.0, 5.0), // in no triangle
    ];
    let uvs = vec![[0.1, 0.5], [0.4, 0.5], [0.8, 0.5], [0.55, 0.5]];
    let transform = UvTransform {
        offset: [0.05, 0.0],
        ..UvTransform::default()
    };
    // The second triangle names a vertex that does not exist: skipped, no panic.
    let triangles = vec![[0, 1, 2], [0, 1, 9]];
    let averages = vertex_averages(&positions, &uvs, &triangles, &ramp, &transform);
    for (v, average) in averages.into_iter().enumerate() {
        let point = ramp.sample(transform.apply(uvs[v]));
        assert_close(average, point, 1e-6, &format!("vertex {v}"));
    }
    assert!(vertex_averages(&[], &[], &[], &ramp, &transform).is_empty());
}

#[test]
fn decodes_srgb_png_to_linear_keeping_alpha() {
    // Top row (128, 64, 255, 128), bottom row black: UV (0, 0) is the image's top-left.
    let source = image::RgbaImage::from_fn(2, 2, |_, y| {
        image::Rgba(if y == 0 {
            [128, 64, 255, 128]
        } else {
            [0, 0, 0, 255]
        })
    });
    let png = encode(source.into(), image::ImageFormat::Png);
    let texture = Texture::decode(&png, "albedo.png").unwrap();
    assert_eq!((texture.width(), texture.height()), (2, 2));
    assert_eq!(texture.wrap(), (Wrap::Repeat, Wrap::Repeat));
    let linear = |code: f64| srgb_to_linear(code / 255.0) as f32;
    let expected = [linear(128.0), linear(64.0), 1.0, 128.0 / 255.0];
    assert_eq!(texture.sample([0.25, 0.25]), expected);
    assert_eq!(texture.sample([0.75, 0.75]), [0.0, 0.0, 0.0, 1.0]);
    assert!((expected[0] - 0.2158605).abs() < 1e-6, "{}", expected[0]);
}

#[test]
fn decodes_sixteen_bit_grey_and_jpeg() {
    let source = image::ImageBuffer::<image::Rgba<u16>, _>::from_pixel(
        1,
        1,
        image::Rgba([32768, 0, 65535, 16384]),
    );
    let png = encode(source.into(), image::ImageFormat::Png);
    let texel = Texture::decode(&png, "deep.png")
        .unwrap()
        .sample([0.5, 0.5]);
    let linear = srgb_to_linear(32768.0 / 65535.0) as f32;
    assert_eq!(texel, [linear, 0.0, 1.0, 16384.0 / 65535.0]);

    let grey = image::GrayImage::from_pixel(3, 2, image::Luma([128]));
    let png = encode(grey.clone().into(), image::ImageFormat::Png);
    let texel = Texture::decode(&png, "grey.png")
        .unwrap()
        .sample([0.5, 0.5]);
    let linear = srgb_to_linear(128.0 / 255.0) as f32;
    assert_eq!(texel, [linear, linear, linear, 1.0]);

    // JPEG is lossy, but a flat grey survives to within a code value or so.
    let jpeg = encode(grey.into(), image::ImageFormat::Jpeg);
    let texel = Texture::decode(&jpeg, "grey.jpg")
        .unwrap()
        .sample([0.5, 0.5]);
    assert_close(texel, [linear, linear, linear, 1.0], 0.01, "jpeg");
}

#[test]
fn corrupt_images_are_one_line_errors() {
    let good = encode(
        image::RgbImage::from_pixel(16, 16, image::Rgb([1, 2, 3])).into(),
        image::ImageFormat::Png,
    );
    let hdr = encode(
        image::Rgb32FImage::from_pixel(2, 2, image::Rgb([1.0, 2.0, 3.0])).into(),
        image::ImageFormat::Hdr,
    );
    let mut garbled = good.clone();
    garbled[20..40].fill(0xAB);
    let cases: [(&[u8], &str); 6] = [
        (&[], "the image is empty"),
        (b"hello, world", "not a PNG or JPEG image"),
        (&hdr, "not a PNG or JPEG image"),
        (&good[..good.len() / 2], "PNG: "),
        (&garbled, "PNG: "),
        (
            &[0xFF, 0xD8, 0xFF, 0xE0, 0, 0x10, b'J', b'F', 1, 2, 3],
            "JPEG: ",
        ),
    ];
    for (bytes, expected) in cases {
        let error = Texture::decode(bytes, "images[3]").unwrap_err().to_string();
        assert!(!error.contains('\n'), "{error}");
        assert!(error.starts_with("images[3]: "), "{error}");
        assert!(error.contains(expected), "{error} (expected {expected:?})");
    }
    let error = Texture::new(0, 4, Vec::new(), "images[0]").unwrap_err();
    assert_eq!(
        error.to_string(),
        "images[0]: the image has no texels (0×4)"
    );
    assert!(Texture::new(2, 2, vec![[0.0; 4]; 3], "images[0]").is_err());
}

#[test]
fn wrap_modes_pick_the_right_texels() {
    let gradient = texture(4, 1, |x, _| grey(x as f32));
    let at = |wrap: Wrap, u: f32| gradient.clone().with_wrap(wrap, wrap).sample([u, 0.5])[0];
    // u = 1.25 is texel coordinate 5 (between the centres of texels 4 and 5, half-way).
    // Repeat: texels 0 and 1. Clamp: texel 3 twice. Mirrored: texels 3 and 2.
    assert_eq!(at(Wrap::Repeat, 1.25), 0.5);
    assert_eq!(at(Wrap::ClampToEdge, 1.25), 3.0);
    assert_eq!(at(Wrap::MirroredRepeat, 1.25), 2.5);
    // At the centre of texel 5 (u = 1.375) and of texel −1 (u = −0.125).
    assert_eq!(at(Wrap::Repeat, 1.375), 1.0);
    assert_eq!(at(Wrap::ClampToEdge, 1.375), 3.0);
    assert_eq!(at(Wrap::MirroredRepeat, 1.375), 2.0);
    assert_eq!(at(Wrap::Repeat, -0.125), 3.0);
    assert_eq!(at(Wrap::ClampToEdge, -0.125), 0.0);
    assert_eq!(at(Wrap::MirroredRepeat, -0.125), 0.0);
    // Inside the image the modes agree; far outside nothing panics.
    for wrap in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
        assert_eq!(at(wrap, 0.5), 1.5);
        for u in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -1e30] {
            let _ = at(wrap, u);
        }
    }
    assert_eq!(Wrap::from_gl(10497), Some(Wrap::Repeat));
    assert_eq!(Wrap::from_gl(33071), Some(Wrap::ClampToEdge));
    assert_eq!(Wrap::from_gl(33648), Some(Wrap::MirroredRepeat));
    assert_eq!(Wrap::from_gl(9729), None);
}

#[test]
fn texture_transform_matches_the_extension() {
    let close = |a: [f32; 2], b: [f32; 2]| (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6;
    let check = |t: UvTransform, uv: [f32; 2], expected: [f32; 2]| {
        let got = t.apply(uv);
        assert!(
            close(got, expected),
            "{t:?} maps {uv:?} to {got:?}, not {expected:?}"
        );
    };
    let identity = UvTransform::default();
    check(identity, [0.3, -1.7], [0.3, -1.7]);
    let offset = UvTransform {
        offset: [0.5, -0.25],
        ..identity
    };
    check(offset, [0.0, 0.0], [0.5, -0.25]);
    let scale = UvTransform {
        scale: [2.0, 3.0],
        ..identity
    };
    check(scale, [1.0, 1.0], [2.0, 3.0]);
    // u' = cos·u + sin·v, v' = −sin·u + cos·v.
    let quarter = UvTransform {
        rotation: FRAC_PI_2,
        ..identity
    };
    check(quarter, [1.0, 0.0], [0.0, -1.0]);
    check(quarter, [0.0, 1.0], [1.0, 0.0]);
    // Scale first, then rotate, then offset: (1, 0) → (2, 0) → (0, −2) → (0.5, −1.5).
    let all = UvTransform {
        offset: [0.5, 0.5],
        rotation: FRAC_PI_2,
        scale: [2.0, 1.0],
    };
    check(all, [1.0, 0.0], [0.5, -1.5]);
    // The extension's example: the unit square onto the image's lower-left quadrant.
    let example = UvTransform {
        offset: [0.0, 1.0],
        rotation: FRAC_PI_2, // the example's 1.57079632679
        scale: [0.5, 0.5],
    };
    check(example, [0.0, 0.0], [0.0, 1.0]);
    check(example, [1.0, 0.0], [0.0, 0.5]);
    check(example, [0.0, 1.0], [0.5, 1.0]);
    check(example, [1.0, 1.0], [0.5, 0.5]);
}

#[test]
fn sample_count_follows_the_longest_texel_edge() {
    let dims = level_dims(1024, 512);
    assert_eq!(dims.len(), 11);
    assert_eq!(dims[1], (512, 256));
    assert_eq!(*dims.last().unwrap(), (1, 1));
    assert_eq!(level_dims(5, 3), [(5, 3), (3, 2), (2, 1), (1, 1)]);
    let plan = |uv: [[f64; 2]; 3]| sampling_plan(&uv, &dims);
    // Smaller than a texel: the minimum, 16 samples.
    assert_eq!(plan([[0.5, 0.5], [0.5001, 0.5], [0.5, 0.5001]]), (0, 4));
    // 10 texels along u: 20 subdivisions.
    assert_eq!(
        plan([
            [0.0, 0.0],
            [10.0 / 1024.0, 0.0],
            [5.0 / 1024.0, 1.0 / 512.0]
        ]),
        (0, 20)
    );
    // A sliver 100 texels long is sampled along its length, whatever its area.
    assert_eq!(
        plan([[0.0, 0.0], [0.0, 100.0 / 512.0], [1e-6, 50.0 / 512.0]]),
        (0, 200)
    );
    // 128 texels across is the most the base level takes; 129 moves one level down.
    assert_eq!(plan([[0.0, 0.0], [0.125, 0.0], [0.0, 0.0]]), (0, 256));
    assert_eq!(
        plan([[0.0, 0.0], [129.0 / 1024.0, 0.0], [0.0, 0.0]]),
        (1, 129)
    );
    // Tiled a thousand times: the 1 × 1 level, at the cap.
    assert_eq!(plan([[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]]), (10, 256));
    // NaN UVs get a plan like any other, not an endless or empty one.
    assert_eq!(plan([[f64::NAN; 2]; 3]), (0, 4));
    let (_, n) = plan([[f64::NAN, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    assert!((MIN_SUBDIVISIONS..=MAX_SUBDIVISIONS).contains(&n));
}

#[test]
fn subdivision_tiles_the_triangle_evenly() {
    for n in [1, 2, 4, 7, 256] {
        let centroids: Vec<[f64; 2]> = subtriangle_centroids(n).collect();
        assert_eq!(centroids.len(), (n * n) as usize);
        // Every centroid strictly inside, and their mean is the triangle's centroid
        // (the rule integrates the linear hat functions exactly).
        let mut sum = [0.0; 2];
        for &[b1, b2] in &centroids {
            assert!(b1 > 0.0 && b2 > 0.0 && b1 + b2 < 1.0);
            sum = [sum[0] + b1, sum[1] + b2];
        }
        let mean = sum.map(|s| s / f64::from(n * n));
        assert!((mean[0] - 1.0 / 3.0).abs() < 1e-12 && (mean[1] - 1.0 / 3.0).abs() < 1e-12);
    }
}

#[test]
fn mip_levels_keep_the_mean() {
    let odd = texture(5, 3, |x, y| [x as f32, y as f32, (x * y) as f32, 1.0]);
    let mean = |t: &Texture| {
        let n = t.texels.len() as f64;
        std::array::from_fn::<f64, 4, _>(|c| {
            t.texels.iter().map(|p| f64::from(p[c])).sum::<f64>() / n
        })
    };
    let base = mean(&odd);
    let pyramid = Pyramid::new(&odd, 3);
    let dims: Vec<_> = (0..4)
        .map(|l| (pyramid.level(l).width(), pyramid.level(l).height()))
        .collect();
    assert_eq!(dims, level_dims(5, 3));
    for level in 1..4 {
        let m = mean(pyramid.level(level));
        for c in 0..4 {
            assert!(
                (m[c] - base[c]).abs() < 1e-6,
                "level {level}: {m:?} vs {base:?}"
            );
        }
    }
    // A 2 × 2 box average on even sizes.
    let even = texture(4, 2, |x, y| grey((x + 4 * y) as f32));
    let half = even.downsampled();
    assert_eq!(half.texels, vec![grey(2.5), grey(4.5)]);
}
