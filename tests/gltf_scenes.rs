//! glTF scenes in, the same scene out with its transfer baked in: the assimp test models bake
//! or fail clearly, placements bake like the mesh transformed by hand, textures average, the
//! scene survives the round trip and passes the Khronos validator, CPU and GPU agree.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use base64::Engine;
use common::gltf_builder::{ground_and_card_gltf, GltfBuilder};
use common::vec3_accessor;
use glam::{Mat3, Mat4, Quat, Vec3};
use prt_gpu::bake::{
    bake, Backend, BakeOptions, BakeReport, BakedMesh, CpuBackend, Mode, NoProgress,
};
use prt_gpu::glb::scene::{encode_scene_glb, read_scene_glb, write_scene_glb};
use prt_gpu::glb::Stored;
use prt_gpu::precision::Precision;
use prt_gpu::sampling::Sampling;
use prt_gpu::scene::gltf::{self as gltf_scene, GltfScene};
use prt_gpu::scene::{self, builtin, Scene};
use serde_json::{json, Value};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltf")
        .join(name)
}

fn quick() -> BakeOptions {
    BakeOptions {
        samples: 64,
        ..BakeOptions::default()
    }
}

fn bake_gltf(
    path: &Path,
    options: &BakeOptions,
    backend: &dyn Backend,
) -> (GltfScene, BakedMesh, BakeReport) {
    let (gltf, scene) = gltf_scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    let (baked, report) = bake(scene, options, backend, &NoProgress).unwrap();
    (gltf, baked, report)
}

/// The JSON chunk of a .glb.
fn glb_json(bytes: &[u8]) -> Value {
    let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + n]).unwrap()
}

/// The JSON of a glTF file as read, .gltf or .glb.
fn input_json(path: &Path) -> Value {
    let bytes = std::fs::read(path).unwrap();
    if bytes.starts_with(b"glTF") {
        glb_json(&bytes)
    } else {
        serde_json::from_slice(&bytes).unwrap()
    }
}

fn names(doc: &Value, array: &str) -> Vec<Value> {
    doc[array]
        .as_array()
        .map(|items| items.iter().map(|i| i["name"].clone()).collect())
        .unwrap_or_default()
}

fn count(doc: &Value, array: &str) -> usize {
    doc[array].as_array().map_or(0, Vec::len)
}

fn assert_valid(path: &Path) {
    if let Some(report) = common::validate_gltf(path) {
        assert_eq!(
            report.num_errors,
            0,
            "{}: {}",
            path.display(),
            report.listing()
        );
    }
}

#[test]
fn the_assimp_scenes_bake_and_pass_the_validator() {
    let out = tempfile::tempdir().unwrap();
    for name in [
        "BoxTextured/BoxTextured.gltf",
        "BoxTextured.glb",
        "BoxTextured-Embedded.gltf",
        "TextureTransformTest/TextureTransformTest.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_04.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_05.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_06.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_11.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_12.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_13.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_14.gltf",
        "Mesh_PrimitiveMode/Mesh_PrimitiveMode_15.gltf",
        "2CylinderEngine.glb",
    ] {
        let (gltf, baked, report) = bake_gltf(&data(name), &quick(), &CpuBackend);
        let target = out
            .path()
            .join(name.replace('/', "_"))
            .with_extension("glb");
        let written = write_scene_glb(
            &target,
            &gltf,
            Stored::plain(&baked).unwrap(),
            &report.vertex_map,
        )
        .unwrap();
        let primitives: usize = gltf.instances.iter().map(|i| i.primitives.len()).sum();
        assert_eq!(written.primitives_baked, primitives, "{name}");
        assert_valid(&target);
        // What `info` and `render` read: every placement, with its transfer.
        let back = prt_gpu::glb::read_glb(&target).unwrap();
        assert_eq!(back.metadata, baked.metadata, "{name}");
        assert_eq!(
            back.transfer.vertex_count(),
            report.vertex_map.len(),
            "{name}"
        );
        assert!(back.transfer.coeffs().iter().any(|&c| c != 0.0), "{name}");
    }
}

#[test]
fn points_lines_and_compressed_or_broken_files_fail_in_one_line() {
    for (name, expect) in [
        (
            "Mesh_PrimitiveMode/Mesh_PrimitiveMode_00.gltf",
            "no triangles (only points or lines)",
        ),
        (
            "Mesh_PrimitiveMode/Mesh_PrimitiveMode_01.gltf",
            "no triangles (only points or lines)",
        ),
        (
            "Mesh_PrimitiveMode/Mesh_PrimitiveMode_10.gltf",
            "no triangles (only points or lines)",
        ),
        ("draco/2CylinderEngine.gltf", "KHR_draco_mesh_compression"),
        (
            "broken/IndexOutOfRange/IndexOutOfRange.gltf",
            "uses vertex 255 but has only 24 vertices",
        ),
        (
            "broken/IndexOutOfRange/AllIndicesOutOfRange.gltf",
            "but has only 24 vertices",
        ),
        ("broken/MissingBin/BoxTextured.gltf", "cannot read buffer 0"),
        ("broken/BoxWithInfinites.glb", "invalid glTF"),
        ("broken/wrongTypes/badArray.gltf", "invalid type"),
        ("broken/wrongTypes/badExtension.gltf", "invalid type"),
        ("broken/wrongTypes/badNumber.gltf", "invalid type"),
        ("broken/wrongTypes/badObject.gltf", "invalid type"),
        ("broken/wrongTypes/badString.gltf", "invalid type"),
        ("broken/wrongTypes/badUint.gltf", "invalid type"),
        ("broken/RecursiveNodes.gltf", "recursive nodes"),
        ("broken/NoScene.gltf", "scene: Index out of bounds"),
        ("broken/SceneWithoutNodes.gltf", "missing field `nodes`"),
    ] {
        let path = data(name);
        let error = match gltf_scene::load(&path) {
            Ok(_) => panic!("{name} loaded"),
            Err(e) => e.to_string(),
        };
        assert!(!error.contains('\n'), "{name}: {error}");
        assert!(
            error.starts_with(&path.display().to_string()),
            "{name}: {error}"
        );
        assert!(error.contains(expect), "{name}: {error}");
    }
}

#[test]
fn the_cli_refuses_a_broken_scene_without_leaving_a_file() {
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "broken/RecursiveNodes.gltf",
        "draco/2CylinderEngine.gltf",
        "broken/BoxWithInfinites.glb",
    ] {
        let output = dir.path().join("out.glb");
        let run = Command::new(env!("CARGO_BIN_EXE_prt-gpu"))
            .args(["bake", "--device", "cpu", "-o"])
            .arg(&output)
            .arg(data(name))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{name}");
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{name}: {stderr}");
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{name}");
    }
}

#[test]
fn strips_and_fans_are_the_triangles_they_describe() {
    let load = |n: &str| {
        gltf_scene::load(&data(&format!(
            "Mesh_PrimitiveMode/Mesh_PrimitiveMode_{n}.gltf"
        )))
        .unwrap()
        .1
    };
    for (strip, fan, list) in [("04", "05", "06"), ("11", "12", "13")] {
        let reference = load(list);
        let area_normal = |s: &Scene| {
            s.triangles.iter().fold(Vec3::ZERO, |sum, t| {
                let [a, b, c] = t.map(|i| s.positions[i as usize]);
                sum + (b - a).cross(c - a)
            })
        };
        for other in [load(strip), load(fan)] {
            assert_eq!(other.triangles.len(), reference.triangles.len());
            // Same area, facing the same way: the winding survived the conversion.
            assert!((area_normal(&other) - area_normal(&reference)).length() < 1e-6);
        }
    }
}

/// A sphere shown by two nodes — one translated and turned, one mirrored by a negative scale —
/// over a ground mesh: bake it as glTF, and bake the same geometry transformed by hand as an
/// OBJ. Placement for placement, vertex for vertex, the transfer must be the same.
#[test]
fn two_placements_bake_like_the_mesh_transformed_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = builtin::icosphere(Vec3::ZERO, 0.5, 2);
    let sphere = scene::prepare::prepare(sphere).unwrap().0;
    let ground = builtin::grid_plane(Vec3::ZERO, Vec3::X * 3.0, Vec3::NEG_Z * 3.0, 6, Vec3::ONE);
    let ground = scene::prepare::prepare(ground).unwrap().0;
    let placements = [
        Mat4::from_scale_rotation_translation(
            Vec3::ONE,
            Quat::from_rotation_y(0.7),
            Vec3::new(-0.6, 0.55, 0.1),
        ),
        Mat4::from_scale_rotation_translation(
            Vec3::new(-1.0, 1.0, 1.0),
            Quat::IDENTITY,
            Vec3::new(0.6, 0.5, 0.0),
        ),
        Mat4::IDENTITY,
    ];
    let mut builder = GltfBuilder::default();
    let sphere_primitive = builder.primitive(&sphere, None);
    let ground_primitive = builder.primitive(&ground, None);
    let node = |mesh: usize, m: &Mat4| json!({ "mesh": mesh, "matrix": m.to_cols_array() });
    let doc = json!({
        "scene": 0,
        "scenes": [{ "nodes": [0, 1, 2] }],
        "nodes": [node(0, &placements[0]), node(0, &placements[1]), node(1, &placements[2])],
        "meshes": [{ "name": "sphere", "primitives": [sphere_primitive] }, { "name": "ground", "primitives": [ground_primitive] }],
    });
    let gltf_path = builder.finish(doc, dir.path(), "placed.gltf");

    // The same geometry placed by hand, mirrored winding flipped, in the glTF's vertex order.
    let mut obj = String::new();
    let mut first = 1;
    for (mesh, world) in [
        (&sphere, placements[0]),
        (&sphere, placements[1]),
        (&ground, placements[2]),
    ] {
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().unwrap()) {
            let p = world.transform_point3(*p);
            let n = (normal_matrix * *n).normalize_or_zero();
            obj += &format!(
                "v {:?} {:?} {:?}\nvn {:?} {:?} {:?}\n",
                p.x, p.y, p.z, n.x, n.y, n.z
            );
        }
        let mirrored = Mat3::from_mat4(world).determinant() < 0.0;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| i + first);
            let [b, c] = if mirrored { [c, b] } else { [b, c] };
            obj += &format!("f {a}//{a} {b}//{b} {c}//{c}\n");
        }
        first += mesh.positions.len() as u32;
    }
    let obj_path = dir.path().join("placed.obj");
    std::fs::write(&obj_path, obj).unwrap();

    // A shared direction set: every vertex's estimate is independent of vertex order.
    let options = BakeOptions {
        samples: 256,
        sampling: Sampling::Fibonacci,
        albedo: Some(Vec3::splat(0.5)),
        ..BakeOptions::default()
    };
    let (gltf, baked, report) = bake_gltf(&gltf_path, &options, &CpuBackend);
    assert_eq!(gltf.instances.len(), 3);
    let out = dir.path().join("placed.prt.glb");
    let written = write_scene_glb(
        &out,
        &gltf,
        Stored::plain(&baked).unwrap(),
        &report.vertex_map,
    )
    .unwrap();
    assert_eq!(
        written.mesh_copies, 1,
        "the second sphere gets its own mesh"
    );
    assert_valid(&out);

    let (by_hand, _) = bake(
        scene::load(&obj_path).unwrap(),
        &options,
        &CpuBackend,
        &NoProgress,
    )
    .unwrap();
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let expected: HashMap<[u32; 3], usize> = by_hand
        .scene
        .positions
        .iter()
        .enumerate()
        .map(|(i, &p)| (key(p), i))
        .collect();
    let back = read_scene_glb(&out).unwrap();
    assert_eq!(
        back.scene.positions.len(),
        2 * sphere.positions.len() + ground.positions.len()
    );
    let mut compared = 0;
    for (v, p) in back.scene.positions.iter().enumerate() {
        let twin = expected[&key(*p)];
        for channel in 0..3 {
            let ours = back.transfer.vertex_channel(v, channel);
            let theirs = by_hand.transfer.vertex_channel(twin, channel);
            for (a, b) in ours.iter().zip(theirs) {
                assert!(
                    (a - b).abs() <= 1e-6,
                    "vertex {v} channel {channel}: {a} vs {b}"
                );
            }
        }
        compared += 1;
    }
    assert_eq!(compared, back.scene.positions.len());
    // The two spheres are not the same: each sees the other and the ground from its own place.
    let n = sphere.positions.len();
    let differs = (0..n)
        .any(|v| back.transfer.vertex_channel(v, 0) != back.transfer.vertex_channel(v + n, 0));
    assert!(differs);
}

fn png(width: u32, height: u32, texel: impl Fn(u32, u32) -> u8) -> Vec<u8> {
    let image = image::GrayImage::from_fn(width, height, |x, y| image::Luma([texel(x, y)]));
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
    bytes
}

/// A plane with UVs = position, textured by `image`, loaded: its per-vertex albedo.
fn textured_plane_albedo(image: Vec<u8>, cells: u32) -> (Scene, Vec<[f32; 2]>) {
    let dir = tempfile::tempdir().unwrap();
    let plane = builtin::grid_plane(
        Vec3::new(0.5, 0.0, 0.5),
        Vec3::X * 0.5,
        Vec3::Z * 0.5,
        cells,
        Vec3::ONE,
    );
    let plane = scene::prepare::prepare(plane).unwrap().0;
    let uvs: Vec<[f32; 2]> = plane.positions.iter().map(|p| [p.x, p.z]).collect();
    let mut builder = GltfBuilder::default();
    let primitive = builder.primitive(&plane, Some(&uvs));
    let uri = format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(image)
    );
    let mut primitive = primitive;
    primitive["material"] = json!(0);
    let doc = json!({
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [primitive] }],
        "materials": [{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }],
        "textures": [{ "source": 0, "sampler": 0 }],
        "samplers": [{ "wrapS": 33071, "wrapT": 33071 }],
        "images": [{ "uri": uri }],
    });
    let path = builder.finish(doc, dir.path(), "plane.gltf");
    let (_, loaded) = gltf_scene::load(&path).unwrap();
    (loaded, uvs)
}

#[test]
fn a_texture_half_black_half_white_gives_albedo_zero_and_one() {
    let (plane, uvs) = textured_plane_albedo(png(64, 64, |x, _| if x < 32 { 0 } else { 255 }), 8);
    let mut seen = (0, 0);
    for (albedo, uv) in plane.albedo.iter().zip(&uvs) {
        // Vertices whose surrounding triangles lie in one half (cells are 1/8 wide).
        if uv[0] < 0.5 - 0.125 - 1e-3 {
            assert!(albedo.max_element() < 1e-3, "{uv:?}: {albedo}");
            seen.0 += 1;
        } else if uv[0] > 0.5 + 0.125 + 1e-3 {
            assert!(albedo.min_element() > 1.0 - 1e-3, "{uv:?}: {albedo}");
            seen.1 += 1;
        }
    }
    assert!(seen.0 > 10 && seen.1 > 10, "{seen:?}");
}

#[test]
fn a_checkerboard_finer_than_the_triangles_averages_to_its_mean() {
    // One-texel checks of sRGB 0 and 255, triangles 32 texels across: every vertex is grey
    // (linear 0.5), though a point sample at its UV would be black or white.
    let checks = png(128, 128, |x, y| if (x + y) % 2 == 0 { 0 } else { 255 });
    let (plane, uvs) = textured_plane_albedo(checks.clone(), 4);
    let texture = prt_gpu::scene::texture::Texture::decode(&checks, "checks").unwrap();
    for (albedo, uv) in plane.albedo.iter().zip(&uvs) {
        assert!((albedo.x - 0.5).abs() < 0.02, "{albedo}");
        // The texel the vertex's UV falls in, sampled at its centre, is black or white.
        let texel = uv.map(|c| ((c * 128.0).floor().min(127.0) + 0.5) / 128.0);
        let point = texture.sample(texel)[0];
        assert!(
            !(0.01..=0.99).contains(&point),
            "the texel at {uv:?} is {point}"
        );
    }
}

#[test]
fn the_round_trip_keeps_nodes_meshes_materials_textures_names_and_indices() {
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "BoxTextured/BoxTextured.gltf",
        "2CylinderEngine.glb",
        "TextureTransformTest/TextureTransformTest.gltf",
    ] {
        let input = data(name);
        let (gltf, baked, report) = bake_gltf(&input, &quick(), &CpuBackend);
        let (bytes, written) = encode_scene_glb(
            &gltf,
            Stored::plain(&baked).unwrap(),
            &report.vertex_map,
            None,
        )
        .unwrap();
        let before = input_json(&input);
        let after = glb_json(&bytes);
        for array in [
            "nodes",
            "materials",
            "textures",
            "images",
            "samplers",
            "cameras",
        ] {
            assert_eq!(
                count(&after, array),
                count(&before, array),
                "{name} {array}"
            );
            assert_eq!(
                names(&after, array),
                names(&before, array),
                "{name} {array}"
            );
        }
        let meshes = count(&before, "meshes");
        assert_eq!(
            count(&after, "meshes"),
            meshes + written.mesh_copies,
            "{name}"
        );
        assert_eq!(
            names(&after, "meshes")[..meshes],
            names(&before, "meshes")[..],
            "{name}"
        );
        // Index buffers hold the input's indices, vertex for vertex.
        let (root, buffers) = (&gltf.root, &gltf.buffers);
        let target = dir.path().join("round.glb");
        std::fs::write(&target, &bytes).unwrap();
        assert_valid(&target);
        let (reread, _) = gltf_scene::load(&target).unwrap();
        for (mesh_index, mesh) in root.meshes.iter().enumerate() {
            for (p, primitive) in mesh.primitives.iter().enumerate() {
                let Some(indices) = primitive.indices else {
                    continue;
                };
                let original = gltf_scene::accessor::dense(root, buffers, indices.value())
                    .unwrap()
                    .indices()
                    .unwrap();
                let again = reread.root.meshes[mesh_index].primitives[p]
                    .indices
                    .unwrap();
                let again =
                    gltf_scene::accessor::dense(&reread.root, &reread.buffers, again.value())
                        .unwrap()
                        .indices()
                        .unwrap();
                assert_eq!(original, again, "{name} mesh {mesh_index}");
            }
        }
    }
}

#[test]
fn the_numpy_recipe_reads_a_scene_baked_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let (gltf, baked, report) = bake_gltf(&data("BoxTextured.glb"), &quick(), &CpuBackend);
    let mut float32 = None;
    for precision in [Precision::F32, Precision::F16] {
        let target = dir.path().join(format!("box-{precision:?}.prt.glb"));
        write_scene_glb(
            &target,
            &gltf,
            Stored::new(&baked, None, precision).unwrap(),
            &report.vertex_map,
        )
        .unwrap();
        let Some(printed) = prt_gpu::testing::numpy_reader_output(&target) else {
            return;
        };
        assert_eq!(printed["positions"], json!([24, 3]));
        assert_eq!(printed["indices"], json!([12, 3]));
        assert_eq!(printed["transfer"], json!([24, 3, 16]));
        let back = read_scene_glb(&target).unwrap();
        match &float32 {
            None => float32 = Some(back.transfer.clone()),
            Some(exact) => assert_eq!(back.transfer, prt_gpu::glb::rounded_to_f16(exact)),
        }
        let last: Vec<Vec<f32>> = serde_json::from_value(printed["last_vertex"].clone()).unwrap();
        for (channel, row) in last.iter().enumerate() {
            assert_eq!(
                row[..],
                back.transfer.vertex_channel(23, channel)[..],
                "{precision:?}"
            );
        }
    }
}

#[test]
fn cpu_and_gpu_bake_a_scene_alike() {
    let options = quick();
    let mut results = Vec::new();
    for backend in common::backends() {
        let (_, baked, _) = bake_gltf(
            &data("TextureTransformTest/TextureTransformTest.gltf"),
            &options,
            backend.as_ref(),
        );
        results.push(baked.transfer.into_coeffs());
    }
    if let [cpu, gpu] = &results[..] {
        let worst = cpu
            .iter()
            .zip(gpu)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "CPU and GPU differ by {worst}");
    }
}

#[test]
fn interreflected_scenes_bake_in_place_too() {
    let options = BakeOptions {
        mode: Mode::Interreflected,
        bounces: 2,
        ..quick()
    };
    let dir = tempfile::tempdir().unwrap();
    let (gltf, baked, report) =
        bake_gltf(&data("BoxTextured/BoxTextured.gltf"), &options, &CpuBackend);
    let target = dir.path().join("box.glb");
    write_scene_glb(
        &target,
        &gltf,
        Stored::plain(&baked).unwrap(),
        &report.vertex_map,
    )
    .unwrap();
    assert_valid(&target);
    assert_eq!(prt_gpu::glb::read_metadata(&target).unwrap().0.bounces, 2);
}

/// Little-endian bytes of `values` through `to_bytes`.
fn le<T: Copy, const N: usize>(values: &[T], to_bytes: impl Fn(T) -> [u8; N]) -> Vec<u8> {
    values.iter().flat_map(|&v| to_bytes(v)).collect()
}

/// KHR_mesh_quantization positions and normals interleaved in one view, and a sparse COLOR_0
/// with no view at all: read as the specification says, written back as floats.
#[test]
fn quantized_interleaved_and_sparse_accessors_are_read_as_specified() {
    let dir = tempfile::tempdir().unwrap();
    // A unit quad in z = 0: positions as normalized i16 (32767 = 1.0), normals as normalized
    // i8, interleaved: [x y z pad | nx ny nz pad] = 12 bytes a vertex.
    let corners: [[i16; 3]; 4] = [[0, 0, 0], [32767, 0, 0], [32767, 32767, 0], [0, 32767, 0]];
    let mut interleaved = Vec::new();
    for c in corners {
        interleaved.extend(le(&c, i16::to_le_bytes));
        interleaved.extend([0, 0]);
        interleaved.extend([0u8, 0, 127, 0]);
    }
    let indices = le(&[0u16, 1, 2, 0, 2, 3], u16::to_le_bytes);
    let sparse_indices = le(&[2u8], |v| [v]);
    let sparse_values = le(&[0.25f32, 0.5, 0.75], f32::to_le_bytes);
    let mut bin = interleaved.clone();
    let indices_at = bin.len();
    bin.extend(&indices);
    let sparse_at = bin.len();
    bin.extend(&sparse_indices);
    bin.resize(bin.len().next_multiple_of(4), 0);
    let values_at = bin.len();
    bin.extend(&sparse_values);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let doc = json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0, "scale": [2.0, 2.0, 2.0] }],
        "meshes": [{ "primitives": [{
            "attributes": { "POSITION": 0, "NORMAL": 1, "COLOR_0": 3 },
            "indices": 2,
        }] }],
        "buffers": [{ "byteLength": bin.len(), "uri": uri }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": interleaved.len(), "byteStride": 12, "target": 34962 },
            { "buffer": 0, "byteOffset": indices_at, "byteLength": indices.len(), "target": 34963 },
            { "buffer": 0, "byteOffset": sparse_at, "byteLength": sparse_indices.len() },
            { "buffer": 0, "byteOffset": values_at, "byteLength": sparse_values.len() },
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5122, "normalized": true, "count": 4, "type": "VEC3",
              "min": [0, 0, 0], "max": [32767, 32767, 0] },
            { "bufferView": 0, "byteOffset": 8, "componentType": 5120, "normalized": true, "count": 4, "type": "VEC3" },
            { "bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR" },
            { "componentType": 5126, "count": 4, "type": "VEC3",
              "sparse": { "count": 1, "indices": { "bufferView": 2, "componentType": 5121 },
                          "values": { "bufferView": 3 } } },
        ],
    });
    let path = dir.path().join("quantized.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let (gltf, loaded) = gltf_scene::load(&path).unwrap();
    let expected = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 2.0, 0.0],
        [0.0, 2.0, 0.0],
    ];
    assert_eq!(
        loaded
            .positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
        expected
    );
    assert_eq!(loaded.normals.as_ref().unwrap(), &vec![Vec3::Z; 4]);
    // COLOR_0 is zero but where the sparse value replaces vertex 2.
    let albedo: Vec<[f32; 3]> = loaded.albedo.iter().map(|a| a.to_array()).collect();
    assert_eq!(albedo, [[0.0; 3], [0.0; 3], [0.25, 0.5, 0.75], [0.0; 3]]);

    let (baked, report) = bake(loaded, &quick(), &CpuBackend, &NoProgress).unwrap();
    let target = dir.path().join("quantized.prt.glb");
    write_scene_glb(
        &target,
        &gltf,
        Stored::plain(&baked).unwrap(),
        &report.vertex_map,
    )
    .unwrap();
    assert_valid(&target);
    let written = glb_json(&std::fs::read(&target).unwrap());
    let accessors = &written["accessors"];
    assert_eq!(
        accessors[0]["componentType"],
        json!(5126),
        "POSITION becomes float"
    );
    assert_eq!(accessors[0]["max"], json!([1.0, 1.0, 0.0]));
    assert_eq!(
        accessors[2]["componentType"],
        json!(5125),
        "indices become u32"
    );
    assert!(
        accessors[3].get("sparse").is_none(),
        "sparse accessors are written dense"
    );
    let (_, reread) = gltf_scene::load(&target).unwrap();
    assert_eq!(
        reread
            .positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
        expected
    );
}

#[test]
fn skinned_and_morphing_meshes_bake_in_their_rest_pose_with_a_note() {
    let out = tempfile::tempdir().unwrap();
    for (name, expect) in [
        (
            "simple_skin.gltf",
            "1 skinned node(s) (0) baked in their rest pose",
        ),
        (
            "AnimatedMorphCube/AnimatedMorphCube.gltf",
            "1 morphing mesh(es) (0) baked in their rest pose",
        ),
    ] {
        let (gltf, baked, report) = bake_gltf(&data(name), &quick(), &CpuBackend);
        assert!(
            gltf.notes.iter().any(|n| n == expect),
            "{name}: {:?}",
            gltf.notes
        );
        let target = out.path().join("out.glb");
        write_scene_glb(
            &target,
            &gltf,
            Stored::plain(&baked).unwrap(),
            &report.vertex_map,
        )
        .unwrap();
        assert_valid(&target);
        // Skins, joints, morph targets and animations travel with the scene.
        let (before, after) = (
            input_json(&data(name)),
            glb_json(&std::fs::read(&target).unwrap()),
        );
        for array in ["skins", "animations"] {
            assert_eq!(
                count(&after, array),
                count(&before, array),
                "{name} {array}"
            );
        }
        assert_eq!(
            after["meshes"][0]["primitives"][0]["targets"]
                .as_array()
                .map(Vec::len),
            before["meshes"][0]["primitives"][0]["targets"]
                .as_array()
                .map(Vec::len),
            "{name}"
        );
    }
}

#[test]
fn masked_materials_are_named_in_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let quad = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z, 1, Vec3::ONE);
    let mut builder = GltfBuilder::default();
    let mut primitive = builder.primitive(&quad, None);
    primitive["material"] = json!(0);
    let doc = json!({
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [primitive] }],
        "materials": [{ "name": "leaves", "alphaMode": "MASK" }],
    });
    let path = builder.finish(doc, dir.path(), "masked.gltf");
    let (gltf, _) = gltf_scene::load(&path).unwrap();
    assert!(
        gltf.notes
            .iter()
            .any(|n| n.contains("\"leaves\"") && n.contains("opaque")),
        "{:?}",
        gltf.notes
    );
}

/// Damaged bytes — every truncation of a .glb, and single corrupted bytes throughout its JSON —
/// are errors or readable scenes, never a panic.
#[test]
fn damaged_glb_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let original = std::fs::read(data("BoxTextured.glb")).unwrap();
    let json_end = 20 + u32::from_le_bytes(original[12..16].try_into().unwrap()) as usize;
    let mut variants: Vec<Vec<u8>> = (0..original.len())
        .step_by(7)
        .map(|n| original[..n].to_vec())
        .collect();
    for at in (12..json_end).step_by(3) {
        for byte in [b'0', b'[', b'"', b'-', 0xff] {
            let mut damaged = original.clone();
            damaged[at] = byte;
            variants.push(damaged);
        }
    }
    let path = dir.path().join("damaged.glb");
    let mut errors = 0;
    for bytes in &variants {
        std::fs::write(&path, bytes).unwrap();
        let outcome = std::panic::catch_unwind(|| gltf_scene::load(&path).map(|_| ()));
        match outcome {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                assert!(!e.to_string().contains('\n'), "{e}");
                errors += 1;
            }
            Err(_) => panic!("loading {} damaged bytes panicked", bytes.len()),
        }
    }
    assert!(
        errors > variants.len() / 2,
        "{errors} of {}",
        variants.len()
    );
}

/// A scene where one primitive has normals and another has none: the first keeps its own, the
/// second gets the smooth normals `prepare` computes, over its own triangles.
#[test]
fn primitives_without_normals_get_the_computed_ones_beside_those_with() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = scene::prepare::prepare(builtin::icosphere(Vec3::ZERO, 0.5, 1))
        .unwrap()
        .0;
    let ground = builtin::grid_plane(Vec3::NEG_Y, Vec3::X * 2.0, Vec3::NEG_Z * 2.0, 2, Vec3::ONE);
    let mut builder = GltfBuilder::default();
    let with_normals = builder.primitive(&ground, None);
    let mut without_normals = builder.primitive(&sphere, None);
    without_normals["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("NORMAL");
    let doc = json!({
        "scenes": [{ "nodes": [0, 1] }],
        "nodes": [{ "mesh": 0 }, { "mesh": 1 }],
        "meshes": [{ "primitives": [with_normals] }, { "primitives": [without_normals] }],
    });
    let path = builder.finish(doc, dir.path(), "mixed.gltf");
    let (_, loaded) = gltf_scene::load(&path).unwrap();
    let normals = loaded.normals.unwrap();
    let split = ground.positions.len();
    assert_eq!(&normals[..split], ground.normals.as_deref().unwrap());
    let computed = scene::prepare::smooth_normals(&sphere.positions, &sphere.triangles);
    assert_eq!(&normals[split..], &computed[..]);
    // Outward: the computed normals agree with the sphere's own.
    for (n, own) in computed.iter().zip(sphere.normals.as_deref().unwrap()) {
        assert!(n.dot(*own) > 0.9, "{n} vs {own}");
    }
}

/// A textured plane written as `scene.gltf` in `dir`: its buffer and image as data: URIs, UVs
/// as given (the plane's 9 vertices).
fn textured_plane_gltf(dir: &Path, uvs: Option<Vec<[f32; 2]>>) -> PathBuf {
    let plane = builtin::grid_plane(Vec3::ZERO, Vec3::X * 0.5, Vec3::Z * 0.5, 2, Vec3::ONE);
    let plane = scene::prepare::prepare(plane).unwrap().0;
    let uvs = uvs.unwrap_or_else(|| plane.positions.iter().map(|p| [p.x, p.z]).collect());
    let mut builder = GltfBuilder::default();
    let mut primitive = builder.primitive(&plane, Some(&uvs));
    primitive["material"] = json!(0);
    let image = format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(png(4, 4, |x, _| 60 * x as u8))
    );
    let doc = json!({
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [primitive] }],
        "materials": [{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }],
        "textures": [{ "source": 0 }],
        "images": [{ "uri": image }],
    });
    builder.finish(doc, dir, "scene.gltf")
}

/// `path`'s JSON with `change` made to it, written back.
fn edit_json(path: &Path, change: impl FnOnce(&mut Value)) {
    let mut doc: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    change(&mut doc);
    std::fs::write(path, serde_json::to_vec(&doc).unwrap()).unwrap();
}

/// The error loading `path` gives, checked to be one line naming the file.
fn load_error(path: &Path) -> String {
    let error = match gltf_scene::load(path) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => e.to_string(),
    };
    assert!(!error.contains('\n'), "{error}");
    assert!(error.starts_with(&path.display().to_string()), "{error}");
    error
}

#[test]
fn a_gltf_with_a_byte_order_mark_reads_like_one_without() {
    let dir = tempfile::tempdir().unwrap();
    let path = textured_plane_gltf(dir.path(), None);
    let (_, plain) = gltf_scene::load(&path).unwrap();
    let bom = dir.path().join("bom.gltf");
    std::fs::write(
        &bom,
        [b"\xEF\xBB\xBF".as_slice(), &std::fs::read(&path).unwrap()].concat(),
    )
    .unwrap();
    assert_eq!(gltf_scene::load(&bom).unwrap().1, plain);
}

/// External buffers and images are read beside the file, `../` included, a buffer no further
/// than its byteLength; absolute paths and other schemes are refused, naming the URI; so is a
/// file too short for its buffer.
#[test]
fn external_resources_are_relative_regular_files_read_within_their_length() {
    let dir = tempfile::tempdir().unwrap();
    let path = textured_plane_gltf(dir.path(), None);
    let (_, expected) = gltf_scene::load(&path).unwrap();
    let doc: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let base64 = |uri: &Value| {
        let uri = uri.as_str().unwrap();
        base64::engine::general_purpose::STANDARD
            .decode(&uri[uri.find(",").unwrap() + 1..])
            .unwrap()
    };
    let mut bin = base64(&doc["buffers"][0]["uri"]);
    // Bytes past the byteLength are never read.
    bin.extend_from_slice(&[0xAB; 13]);
    let resources = dir.path().join("resources");
    std::fs::create_dir(&resources).unwrap();
    std::fs::write(resources.join("plane data.bin"), &bin).unwrap();
    std::fs::write(resources.join("t.png"), base64(&doc["images"][0]["uri"])).unwrap();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    let external = scenes.join("external.gltf");
    std::fs::copy(&path, &external).unwrap();
    edit_json(&external, |doc| {
        doc["buffers"][0]["uri"] = json!("../resources/plane%20data.bin");
        doc["images"][0]["uri"] = json!("../resources/t.png");
    });
    let (gltf, loaded) = gltf_scene::load(&external).unwrap();
    assert_eq!(loaded, expected);
    assert_eq!(gltf.buffers[0].len(), bin.len() - 13);

    let absolute = resources.join("t.png").display().to_string();
    for (field, uri, expect) in [
        ("buffers", absolute.as_str(), "is an absolute path"),
        ("images", absolute.as_str(), "is an absolute path"),
        (
            "buffers",
            "file:///etc/passwd",
            "neither a data: URI nor a relative path",
        ),
        (
            "images",
            "http://example.com/t.png",
            "neither a data: URI nor a relative path",
        ),
        ("buffers", "../resources", "is a directory"),
        ("images", "../resources/absent.png", "absent.png"),
    ] {
        let bad = scenes.join("bad.gltf");
        std::fs::copy(&external, &bad).unwrap();
        edit_json(&bad, |doc| doc[field][0]["uri"] = json!(uri));
        let error = load_error(&bad);
        assert!(error.contains(expect), "{uri}: {error}");
        if expect.starts_with("is an") || expect.starts_with("neither") {
            assert!(error.contains(&format!("{uri:?}")), "{error}");
        }
    }
    let short = scenes.join("short.gltf");
    std::fs::copy(&external, &short).unwrap();
    edit_json(&short, |doc| {
        doc["buffers"][0]["byteLength"] = json!(bin.len() + 1);
    });
    assert!(load_error(&short).contains("fewer than the buffer's byteLength"));
}

/// A buffer or image that names a device (here /dev/zero, through a link beside the file) is
/// refused at once, not read until memory runs out.
#[cfg(unix)]
#[test]
fn a_resource_that_is_a_device_is_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let path = textured_plane_gltf(dir.path(), None);
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.bin")).unwrap();
    for field in ["buffers", "images"] {
        let bad = dir.path().join(format!("{field}.gltf"));
        std::fs::copy(&path, &bad).unwrap();
        edit_json(&bad, |doc| doc[field][0]["uri"] = json!("zero.bin"));
        let error = load_error(&bad);
        assert!(error.contains("zero.bin is not a regular file"), "{error}");
    }
}

#[test]
fn a_nan_texture_coordinate_is_refused_naming_the_attribute() {
    let dir = tempfile::tempdir().unwrap();
    let mut uvs = vec![[0.25, 0.5]; 9];
    uvs[4] = [f32::NAN, 0.5];
    let path = textured_plane_gltf(dir.path(), Some(uvs));
    let error = load_error(&path);
    assert!(
        error.contains("mesh 0 primitive 0 TEXCOORD_0 is NaN or infinite at vertex 4"),
        "{error}"
    );
}

/// A primitive whose NORMAL holds a NaN, an infinity and a zero vector, with a morph target
/// holding a NaN (seen in hostile files, and copied into the output as they were): the bake
/// recomputes the normals, and the file it writes carries them repaired — the primitive's
/// computed normals where the input's were unusable, the rest as given, the target's NaN as
/// zero — with a line for each, and passes the validator.
#[test]
fn non_finite_normals_and_morph_targets_are_written_repaired() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = builtin::icosphere(Vec3::ZERO, 0.5, 1);
    let mut sphere = scene::prepare::prepare(sphere).unwrap().0;
    let given = sphere.normals.clone().unwrap();
    let normals = sphere.normals.as_mut().unwrap();
    normals[3].x = f32::NAN;
    normals[5].z = f32::INFINITY;
    normals[7] = Vec3::ZERO;
    let mut builder = GltfBuilder::default();
    let mut primitive = builder.primitive(&sphere, None);
    let mut moves = vec![0.0f32; 3 * sphere.positions.len()];
    moves[1] = f32::NAN;
    moves[4] = 0.25;
    primitive["targets"] = json!([{ "POSITION": builder.floats(&moves, "VEC3", true) }]);
    let doc = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [primitive], "weights": [0.0] }],
    });
    let path = builder.finish(doc, dir.path(), "nan.gltf");
    let (gltf, baked, report) = bake_gltf(&path, &quick(), &CpuBackend);
    let (bytes, written) = encode_scene_glb(
        &gltf,
        Stored::plain(&baked).unwrap(),
        &report.vertex_map,
        None,
    )
    .unwrap();
    assert_eq!(written.repaired.len(), 2, "{:?}", written.repaired);
    assert!(
        written.repaired[0].contains("3 normal(s) NaN, infinite or zero, written as the normals"),
        "{:?}",
        written.repaired
    );
    assert!(
        written.repaired[1].contains("written as zeros"),
        "{:?}",
        written.repaired
    );
    let out = dir.path().join("out.glb");
    std::fs::write(&out, &bytes).unwrap();
    assert_valid(&out);
    let (read, _) = gltf_scene::load(&out).unwrap();
    let floats = |accessor: usize| {
        prt_gpu::scene::gltf::accessor::dense(&read.root, &read.buffers, accessor)
            .unwrap()
            .floats()
    };
    let json = glb_json(&bytes);
    let normal_accessor = json["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]
        .as_u64()
        .unwrap() as usize;
    let target_accessor = json["meshes"][0]["primitives"][0]["targets"][0]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    let written_normals = floats(normal_accessor);
    for (v, n) in written_normals.chunks_exact(3).enumerate() {
        let n = Vec3::from_slice(n);
        assert!(
            n.is_finite() && (n.length() - 1.0).abs() < 1e-4,
            "vertex {v}: {n}"
        );
        if ![3, 5, 7].contains(&v) {
            assert_eq!(n, given[v], "vertex {v} was finite and is kept");
        } else {
            assert!(
                n.dot(given[v]) > 0.9,
                "vertex {v}: {n} against {}",
                given[v]
            );
        }
    }
    let written_moves = floats(target_accessor);
    assert_eq!((written_moves[1], written_moves[4]), (0.0, 0.25));
}

#[test]
fn a_gltf_scene_bakes_a_lightmap_on_its_own_texcoord_1() {
    use prt_gpu::bake::bake_at;
    use prt_gpu::receivers::Receivers;
    let dir = tempfile::tempdir().unwrap();
    let input = ground_and_card_gltf(dir.path(), Some(1), true, false);
    let out = common::prt_gpu(
        &[
            "bake",
            "lit.gltf",
            "--lightmap",
            "64",
            "--samples",
            "2048",
            "--device",
            "cpu",
            "-o",
            "lit.prt.glb",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("lightmap: 64x64 texels"), "{stderr}");
    let glb = dir.path().join("lit.prt.glb");
    assert!(dir.path().join("lit.prt.lightmap.exr").is_file());
    assert_valid(&glb);
    let doc = glb_json(&std::fs::read(&glb).unwrap());
    let lightmap = &doc["extras"]["prt"]["lightmap"];
    assert_eq!(lightmap["texcoord"], 1, "{lightmap}");
    assert_eq!(lightmap["uri"], "lit.prt.lightmap.exr", "{lightmap}");
    assert_eq!(
        (lightmap["width"].clone(), lightmap["height"].clone()),
        (json!(64), json!(64))
    );

    // The scene keeps its vertices and both UV sets.
    let (input_gltf, input_scene) = gltf_scene::load(&input).unwrap();
    let (output_gltf, output_scene) = gltf_scene::load(&glb).unwrap();
    assert_eq!(output_scene.positions, input_scene.positions);
    for set in [0, 1] {
        let read = |gltf: &GltfScene| gltf_scene::texcoords(gltf, set).unwrap().unwrap();
        assert_eq!(read(&output_gltf), read(&input_gltf), "TEXCOORD_{set}");
    }
    // OpenEXR's reader, through the README's recipe, reads the lightmap the .glb names.
    if let Some(read) = prt_gpu::testing::lightmap_reader_output(&glb) {
        assert_eq!(read["texels"], json!([64, 64, 3, 16]), "{read}");
        assert_eq!(read["uv"], json!([9 * 9, 2]), "{read}");
    }
    let info = common::prt_gpu(&["info", "lit.prt.glb"], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains("lightmap:     64x64 texels in lit.prt.lightmap.exr (TEXCOORD_1)"),
        "{text}"
    );

    // A texel looked up through TEXCOORD_1 gives what a point bake at that surface point does.
    let baked = prt_gpu::glb::read_glb(&glb).unwrap();
    let texels = baked.lightmap.as_ref().expect("the lightmap is read back");
    assert_eq!(texels.set, 1);
    let ground_triangles = 0..(8 * 8 * 2);
    let points = common::points_on(ground_triangles, 400);
    let light = prt_gpu::light::preview_light(4).unwrap();
    let looked_up = prt_gpu::render::relight(
        &prt_gpu::surface::texel_transfer_at(texels, &points),
        &light,
    )
    .unwrap();
    // The prepared scene keeps the loaded triangles in order (none is degenerate).
    let prepared = scene::prepare::prepare(input_scene).unwrap().0;
    let options = BakeOptions {
        samples: 2048,
        ..BakeOptions::default()
    };
    let point_bake = |points: &[prt_gpu::receivers::SurfacePoint]| {
        let receivers = Receivers::at_points(&prepared, points);
        let (transfer, _) = bake_at(
            &prepared,
            &receivers,
            &options,
            &CpuBackend,
            None,
            &NoProgress,
        )
        .unwrap();
        prt_gpu::render::relight(&transfer, &light).unwrap()
    };
    let error = prt_gpu::compress::radiance_error(&point_bake(&points), &looked_up);
    // The control: the same lookups against points mirrored across the card's shadow.
    let mirrored: Vec<_> = points
        .iter()
        .map(|p| {
            let position: Vec3 = (0..3)
                .map(|i| {
                    p.barycentrics[i]
                        * prepared.positions[prepared.triangles[p.triangle as usize][i] as usize]
                })
                .sum();
            common::nearest_point_on_ground(&prepared, Vec3::new(-position.x, 0.0, position.z))
        })
        .collect();
    let control = prt_gpu::compress::radiance_error(&point_bake(&mirrored), &looked_up);
    eprintln!(
        "lookup against a point bake: {:.2}%, mirrored {:.2}%",
        100.0 * error,
        100.0 * control
    );
    assert!(
        error < 0.015,
        "lookup against a point bake: {:.2}%",
        100.0 * error
    );
    assert!(control > 4.0 * error, "control {control} against {error}");
}

#[test]
fn a_gltf_scene_without_a_usable_lightmap_set_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let bake = |args: &[&str]| {
        let mut all = vec!["bake", "lit.gltf", "--samples", "16", "--device", "cpu"];
        all.extend_from_slice(args);
        let out = common::prt_gpu(&all, dir.path());
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(!dir.path().join("lit.prt.glb").exists(), "{stderr}");
        assert!(
            !dir.path().join("lit.prt.lightmap.exr").exists(),
            "{stderr}"
        );
        stderr
    };
    ground_and_card_gltf(dir.path(), None, true, false);
    let error = bake(&["--lightmap", "64"]);
    assert!(
        error.contains("no usable UV set (no TEXCOORD_1; TEXCOORD_0 overlaps itself"),
        "{error}"
    );
    let error = bake(&["--lightmap", "64", "--lightmap-uv", "2"]);
    assert!(
        error.contains("a baked primitive has no TEXCOORD_2"),
        "{error}"
    );
    let error = bake(&["--lightmap-uv", "0"]);
    assert!(error.contains("--lightmap SIZE"), "{error}");
    ground_and_card_gltf(dir.path(), Some(1), false, true);
    let error = bake(&["--lightmap", "64"]);
    assert!(error.contains("mesh 1 is shown by 2 nodes"), "{error}");
    let obj = common::prt_gpu(
        &[
            "bake",
            "--lightmap",
            "64",
            "--lightmap-uv",
            "1",
            "--samples",
            "16",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&obj.stderr);
    assert!(
        !obj.status.success() && stderr.contains("generated atlas"),
        "{stderr}"
    );
}

#[test]
fn a_gltf_scene_whose_texcoord_0_does_not_overlap_bakes_its_lightmap_there() {
    let dir = tempfile::tempdir().unwrap();
    ground_and_card_gltf(dir.path(), Some(0), false, false);
    let out = common::prt_gpu(
        &[
            "bake",
            "lit.gltf",
            "--lightmap",
            "64",
            "--samples",
            "16",
            "--device",
            "cpu",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("note: the scene has no TEXCOORD_1"),
        "{stderr}"
    );
    let glb = dir.path().join("lit.prt.glb");
    assert_valid(&glb);
    let doc = glb_json(&std::fs::read(&glb).unwrap());
    assert_eq!(doc["extras"]["prt"]["lightmap"]["texcoord"], 0);
    let baked = prt_gpu::glb::read_glb(&glb).unwrap();
    assert_eq!(baked.lightmap.map(|l| l.set), Some(0));
}

#[test]
fn a_gltf_lightmap_on_its_own_uv_set_bakes_alike_on_the_cpu_and_the_gpu() {
    use prt_gpu::bake::DirectSource;
    use prt_gpu::pipeline;
    use prt_gpu::spec::{BakeSpec, Container};
    let dir = tempfile::tempdir().unwrap();
    let input = ground_and_card_gltf(dir.path(), Some(1), false, false);
    let (gltf, scene) = gltf_scene::load(&input).unwrap();
    let mut spec = BakeSpec {
        container: Container::GltfInPlace,
        ..BakeSpec::default()
    };
    spec.receivers.lightmap = Some(32);
    spec.transfer.samples = 64;
    spec.transfer.mode = Mode::Interreflected;
    let light = prt_gpu::light::preview_light(4).unwrap();
    let relit: Vec<Vec<[f32; 3]>> = common::backends()
        .iter()
        .map(|backend| {
            let run = pipeline::run;
            let source = DirectSource::Compute;
            let baked = run(
                &spec,
                scene.clone(),
                Some(&gltf),
                backend.as_ref(),
                source,
                &NoProgress,
            );
            let baked = baked
                .and_then(prt_gpu::pipeline::Bake::into_transfer)
                .unwrap();
            let texels = baked.mesh.lightmap.expect("a lightmap");
            assert_eq!((texels.width, texels.height, texels.set), (32, 32, 1));
            prt_gpu::render::relight(&texels.transfer, &light).unwrap()
        })
        .collect();
    for gpu in &relit[1..] {
        let error = prt_gpu::compress::radiance_error(&relit[0], gpu);
        assert!(error < 1e-4, "CPU and GPU lightmaps differ by {error:.2e}");
    }
}

/// `render SCENE -o relit.glb` on a glTF scene baked in place: every baked primitive carries
/// the relit radiance as `_RADIANCE` (exactly the relighting of the baked file), `COLOR_0` its
/// shading — radiance over the vertex albedo, over the stated scale — for the material's colour
/// to multiply, and its material is unlit; the copy passes the Khronos validator and is the
/// same baked scene in every other respect. RGB (albedo in the transfer) and lean (albedo left
/// to the material) files, one primitive with a texture and several sharing materials.
#[test]
fn a_relit_scene_shows_its_radiance_through_unlit_materials() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scenes = [
        ("BoxTextured.glb", "rgb"),
        ("BoxTextured.glb", "lean"),
        ("TextureTransformTest/TextureTransformTest.gltf", "rgb"),
    ];
    for (input, storage) in scenes {
        let source = data(input);
        let out = common::prt_gpu(
            &[
                "bake",
                source.to_str().unwrap(),
                "--samples",
                "64",
                "--device",
                "cpu",
                "--storage",
                storage,
                "-o",
                "scene.prt.glb",
            ],
            d,
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let out = common::prt_gpu(&["render", "scene.prt.glb", "-o", "relit.glb"], d);
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(said.contains("_RADIANCE = exit radiance"), "{said}");
        let relit = d.join("relit.glb");
        assert_valid(&relit);

        let (gltf, baked) =
            prt_gpu::glb::scene::read_scene_vertices(&d.join("scene.prt.glb")).unwrap();
        assert_eq!(baked.metadata.albedo_free, storage == "lean", "{input}");
        let light = prt_gpu::light::preview_light(baked.metadata.bands).unwrap();
        let expected = prt_gpu::render::relight_baked(&baked, &light).unwrap();
        let bytes = std::fs::read(&relit).unwrap();
        let doc = glb_json(&bytes);
        let scale = doc["extras"]["prt"]["relit"]["scale"].as_f64().unwrap() as f32;
        assert!(scale >= 1.0, "{scale}");
        assert!(doc["extensionsUsed"]
            .as_array()
            .unwrap()
            .contains(&json!("KHR_materials_unlit")));
        let mut primitives = 0;
        for instance in &gltf.instances {
            for span in &instance.primitives {
                let primitive = &doc["meshes"][instance.mesh]["primitives"][span.primitive];
                let attribute = |name: &str| {
                    let index = primitive["attributes"][name].as_u64().unwrap();
                    vec3_accessor(&bytes, &doc, index)
                };
                let radiance = attribute("_RADIANCE");
                let colors = attribute("COLOR_0");
                let wanted = &expected[span.first..span.first + span.count];
                assert_eq!(radiance, wanted, "{input} {storage}: _RADIANCE");
                let albedo = &baked.scene.albedo[span.first..span.first + span.count];
                for ((color, r), a) in colors.iter().zip(wanted).zip(albedo) {
                    for c in 0..3 {
                        assert!((0.0..=1.0).contains(&color[c]), "{color:?}");
                        // The material's colour (the albedo) times the shading is the radiance.
                        let shown = a[c] * color[c] * scale;
                        let bound = 1e-5 * (1.0 + r[c].abs());
                        assert!(
                            (shown - r[c].max(0.0)).abs() <= bound || a[c] == 0.0,
                            "{input} {storage}: albedo {a:?} x colour {color:?} x {scale} is \
                             not {r:?}"
                        );
                    }
                }
                let material = primitive["material"].as_u64().unwrap() as usize;
                assert!(
                    doc["materials"][material]["extensions"]["KHR_materials_unlit"].is_object(),
                    "{input}: material {material} is not unlit"
                );
                primitives += 1;
            }
        }
        assert!(primitives > 0);
        // The copy is the baked scene in every other respect: it reads back to the same transfer.
        let copy = read_scene_glb(&relit).unwrap();
        assert_eq!(
            copy.transfer,
            read_scene_glb(&d.join("scene.prt.glb")).unwrap().transfer
        );
    }
}
