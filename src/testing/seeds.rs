//! The files each hostile-file reader starts from: small, valid, and covering the parts of
//! their format the reader handles (materials, normals and colours, binary and text
//! encodings, sparse and quantised accessors, morph targets, compressed transfer). Written by
//! the tool's own writers where it has one, so that they follow the format as it reads it.
//! `examples/fuzz_seeds.rs` writes them as the fuzzers' first corpus; the suite mutates them.

use std::path::{Path, PathBuf};

use super::hostile::{Reader, COMPANION_MTL};
use crate::bake::adaptive::ReceiverErrors;
use crate::bake::bounce::GatherMatrix;
use crate::bake::{self, BakeOptions, CpuBackend, DirectPass, Mode, NoProgress, ShardPass};
use crate::error::{Error, Result};
use crate::precision::Precision;
use crate::scene::Scene;
use crate::spec::BakeSpec;
use crate::{compress, glb, light, shard};

/// Named seed files of `reader`; `data` is the suite's `tests/data` (glTF samples are read
/// from it), `scratch` a directory for writers that write files.
pub fn seeds(reader: Reader, data: &Path, scratch: &Path) -> Result<Vec<(String, Vec<u8>)>> {
    let text = |name: &str, body: &str| (name.to_string(), body.as_bytes().to_vec());
    Ok(match reader {
        Reader::Obj => vec![text("cube.obj", CUBE_OBJ)],
        Reader::Mtl => vec![text("two.mtl", COMPANION_MTL), text("full.mtl", FULL_MTL)],
        Reader::Ply => vec![
            text("ascii.ply", ASCII_PLY),
            ("little.ply".into(), binary_ply(false)),
            ("big.ply".into(), binary_ply(true)),
        ],
        Reader::Gltf => vec![
            read(data, "gltf/BoxTextured-Embedded.gltf")?,
            read(data, "gltf/simple_skin.gltf")?,
        ],
        Reader::Glb => vec![
            read(data, "gltf/BoxTextured.glb")?,
            ("morph-cube.glb".into(), morph_cube_glb(data)?),
        ],
        Reader::Exr => vec![("sky.exr".into(), exr_sky(scratch)?)],
        Reader::Hdr => vec![("sky.hdr".into(), image_sky(image::ImageFormat::Hdr)?)],
        Reader::Png => vec![("sky.png".into(), image_sky(image::ImageFormat::Png)?)],
        Reader::Jpeg => vec![("sky.jpg".into(), image_sky(image::ImageFormat::Jpeg)?)],
        Reader::LightJson => {
            let path = scratch.join("light.json");
            let light = light::ShLight::constant(2, [0.5, 0.25, 1.0]);
            light::file::write_json(&path, &light)?;
            vec![(
                "light.json".into(),
                std::fs::read(&path).map_err(io(&path))?,
            )]
        }
        Reader::Part => vec![
            ("gather.part".into(), part(scratch, true, false)?),
            ("adaptive.part".into(), part(scratch, false, true)?),
        ],
        Reader::Baked => baked(data, scratch)?,
    })
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(path, e)
}

fn read(data: &Path, name: &str) -> Result<(String, Vec<u8>)> {
    let path = data.join(name);
    let bytes = std::fs::read(&path).map_err(io(&path))?;
    let file = name.rsplit('/').next().unwrap_or(name);
    Ok((file.to_string(), bytes))
}

/// A cube in two groups and two materials, with texture coordinates and normals, a quad, a
/// negative (relative) index, a comment after a statement and a continued line.
const CUBE_OBJ: &str = "# cube\nmtllib mesh.mtl\no cube\n\
v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\n\
g front\nusemtl red\nf 1/1/1 4/4/1 3/3/1 2/2/1\nf 5/1/2 6/2/2 7/3/2 # back\n\
f -4/1/2 -2/3/2 \\\n -1/4/2\ng rest\nusemtl grey\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

/// Every statement the MTL reader looks at, and some it skips.
const FULL_MTL: &str = "# all\nnewmtl red\nKa 0 0 0\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\n\
Ns 10\nd 1\nillum 2\nnewmtl grey\nKd 0.5\nmap_Kd missing.png\n";

const ASCII_PLY: &str = "ply\nformat ascii 1.0\ncomment tetrahedron\n\
element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
property uchar red\nproperty uchar green\nproperty uchar blue\n\
element face 4\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n0 0 1 128 128 128\n\
3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

/// A tetrahedron with normals (double positions, float normals), a face list counted by an
/// int, and an element after the faces that the reader skips.
fn binary_ply(big_endian: bool) -> Vec<u8> {
    let encoding = if big_endian { "big" } else { "little" };
    let header = format!(
        "ply\nformat binary_{encoding}_endian 1.0\nelement vertex 4\n\
         property double x\nproperty double y\nproperty double z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         element face 4\nproperty list int uint vertex_indices\n\
         element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    );
    let mut bytes = header.into_bytes();
    let mut put = |word: &[u8]| {
        if big_endian {
            bytes.extend(word.iter().rev());
        } else {
            bytes.extend_from_slice(word);
        }
    };
    let corners = [
        [0.0f64, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    for corner in corners {
        corner.iter().for_each(|c| put(&c.to_le_bytes()));
        let n = glam::DVec3::from_array(corner).normalize_or(glam::DVec3::NEG_ONE.normalize());
        n.to_array()
            .iter()
            .for_each(|c| put(&(*c as f32).to_le_bytes()));
    }
    for face in [[0u32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
        put(&3i32.to_le_bytes());
        face.iter().for_each(|i| put(&i.to_le_bytes()));
    }
    put(&0i32.to_le_bytes());
    put(&1i32.to_le_bytes());
    bytes
}

/// AnimatedMorphCube (morph targets, an animation) as one `.glb`: its JSON without the
/// buffer's `uri`, its `.bin` as the BIN chunk.
fn morph_cube_glb(data: &Path) -> Result<Vec<u8>> {
    let (_, json) = read(data, "gltf/AnimatedMorphCube/AnimatedMorphCube.gltf")?;
    let (_, bin) = read(data, "gltf/AnimatedMorphCube/AnimatedMorphCube.bin")?;
    let mut root: serde_json::Value =
        serde_json::from_slice(&json).map_err(|e| Error::Geometry(e.to_string()))?;
    if let Some(buffer) = root["buffers"][0].as_object_mut() {
        buffer.remove("uri");
    }
    let json = serde_json::to_vec(&root).map_err(|e| Error::Geometry(e.to_string()))?;
    glb::glb_container(json, bin)
}

/// A sky brighter overhead, 16x8 (latlong), in each channel a little differently.
fn sky(x: usize, y: usize) -> [f32; 3] {
    let up = 1.0 - y as f32 / 8.0;
    [0.2 + up, 0.3 + 0.5 * up, 0.5 + 0.01 * x as f32]
}

fn exr_sky(scratch: &Path) -> Result<Vec<u8>> {
    let path = scratch.join("sky.exr");
    exr::prelude::write_rgb_file(&path, 16, 8, |x, y| {
        let [r, g, b] = sky(x, y);
        (r, g, b)
    })
    .map_err(|e| Error::light(&path, e.to_string()))?;
    std::fs::read(&path).map_err(io(&path))
}

fn image_sky(format: image::ImageFormat) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let cursor = &mut std::io::Cursor::new(&mut bytes);
    let failed = |e: image::ImageError| Error::Geometry(format!("cannot encode a seed: {e}"));
    if format == image::ImageFormat::Hdr {
        let image =
            image::Rgb32FImage::from_fn(16, 8, |x, y| image::Rgb(sky(x as usize, y as usize)));
        image.write_to(cursor, format).map_err(failed)?;
    } else {
        let image = image::RgbImage::from_fn(16, 8, |x, y| {
            image::Rgb(sky(x as usize, y as usize).map(|c| (c.min(1.0) * 255.0) as u8))
        });
        image.write_to(cursor, format).map_err(failed)?;
    }
    Ok(bytes)
}

/// The one part of a bake of 3 receivers, with gather rows or with each
/// receiver's samples and error.
fn part(scratch: &Path, gather: bool, adaptive: bool) -> Result<Vec<u8>> {
    let receivers = 3;
    let coeffs = 4;
    let direct = DirectPass {
        scalar: (0..receivers * coeffs).map(|i| i as f32 / 10.0).collect(),
        matrix: gather.then(|| GatherMatrix {
            row_offsets: vec![0, 2, 2, 3],
            columns: vec![0, 2, 1],
            weights: vec![0.25, 0.5, 0.125],
        }),
        rays_cast: 96,
        adaptive: adaptive.then(|| ReceiverErrors {
            samples: vec![16, 32, 64],
            errors: vec![0.1, 0.05, 0.025],
        }),
    };
    let pass = ShardPass {
        receivers: 0..receivers,
        receivers_total: receivers,
        direct,
        ran_on: "cpu".into(),
    };
    let command = ["bake", "--shard", "0/1", "mesh.obj"]
        .map(String::from)
        .to_vec();
    let what = (BakeSpec::default(), Some(PathBuf::from("mesh.obj")));
    let fingerprint = "0123456789abcdef".to_string();
    let part = shard::Part::new(pass, (0, 1), what, fingerprint, (command, ".".into()));
    let path = scratch.join("seed.part");
    shard::write_part(&path, &part)?;
    std::fs::read(&path).map_err(io(&path))
}

/// A tetrahedron baked shadowed at three bands, written plain and compressed, and a glTF
/// scene baked in place.
fn baked(data: &Path, scratch: &Path) -> Result<Vec<(String, Vec<u8>)>> {
    let scene = Scene {
        positions: [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]
        .map(glam::Vec3::from_array)
        .to_vec(),
        normals: None,
        albedo: vec![glam::Vec3::splat(0.5); 4],
        triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    };
    let options = BakeOptions {
        bands: 3,
        samples: 64,
        mode: Mode::Shadowed,
        ..BakeOptions::default()
    };
    let (baked, _) = bake::bake(scene, &options, &CpuBackend, &NoProgress)?;
    let cpca_options = compress::CpcaOptions {
        clusters: 2,
        components: 2,
        ..compress::CpcaOptions::default()
    };
    let cpca = compress::compress(&baked.transfer, &cpca_options)?;
    let path = scratch.join("compressed.glb");
    glb::write_glb(
        &path,
        glb::Stored::new(&baked, Some(&cpca), Precision::F16)?,
    )?;
    Ok(vec![
        (
            "tetrahedron.glb".into(),
            glb::encode_glb(glb::Stored::plain(&baked)?)?,
        ),
        (
            "compressed.glb".into(),
            std::fs::read(&path).map_err(io(&path))?,
        ),
        ("in-place.glb".into(), baked_in_place(data, Precision::F32)?),
        (
            "in-place-f16.glb".into(),
            baked_in_place(data, Precision::F16)?,
        ),
    ])
}

/// BoxTextured baked in place (unshadowed, two bands): a scene file as `render` reads one.
fn baked_in_place(data: &Path, precision: Precision) -> Result<Vec<u8>> {
    let (gltf, scene) = crate::scene::gltf::load(&data.join("gltf/BoxTextured.glb"))?;
    let (baked, report) = super::hostile::quick_bake(scene)?;
    let (bytes, _) = glb::scene::encode_scene_glb(
        &gltf,
        glb::Stored::new(&baked, None, precision)?,
        &report.vertex_map,
        None,
    )?;
    Ok(bytes)
}
