//! The baked file: one self-contained glTF 2.0 binary (`.glb`).
//!
//! Why glTF: engines load it as is (the transfer travels as standard custom vertex attributes),
//! and a reader needs nothing but a JSON parser and a way to view little-endian floats
//! (see [`PYTHON_READER`]).
//!
//! Layout (byte for byte deterministic: no timestamps, JSON keys in name order):
//! - one buffer, the BIN chunk, holding five 4-byte aligned buffer views:
//!   0 positions, 1 normals, 2 albedo (`COLOR_0`), all `VEC3` float; 3 indices (`u32`);
//!   4 the transfer coefficients.
//! - the transfer view is planar, in groups of four coefficients:
//!   `[channel][group][vertex][lane]` float32, coefficient `k = 4 * group + lane`, lanes past
//!   `bands^2` zero. Each `(channel, group)` block is the `VEC4` custom attribute
//!   `_PRT_<R|G|B>_<group>` (`_PRT_<group>` for one channel), so a shader reads one `vec4`
//!   per group and channel.
//! - mesh `extras.prt` holds every [`BakeMetadata`] field, plus `vertices`,
//!   `transfer_buffer_view` and `transfer_layout` ([`TRANSFER_LAYOUT`]).
//! - with a lightmap (`bake --lightmap`): a sixth view, the lightmap coordinates as
//!   `TEXCOORD_0` (`VEC2` float, one pair per vertex; the mesh is split where the atlas'
//!   charts meet, a vertex on a seam once per chart),
//!   and `extras.prt.lightmap` = `{uri, width, height, texcoord: 0, layout}`, `uri` naming the
//!   OpenEXR file beside the .glb that holds the per-texel transfer (`crate::lightmap`).

use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::{self, Read};
use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::bake::{BakeMetadata, BakedMesh, TexelBake, Transfer, TransferShape};
use crate::compress::Cpca;
use crate::error::{Error, Result};
use crate::fs::{check_destination, write_atomically};
use crate::probes::ProbeSet;
use crate::zonal::ZonalTransfer;
use compressed::CpcaExtras;

mod check;
pub mod compressed;
mod decode;
mod encode;
mod json;
pub mod local;
pub mod probes;
pub mod relit;
pub mod scene;
mod stored;
pub mod stream;
pub mod zonal;

// The steps of the file, each in its own module; their items are the whole module's.
use crate::scene::Scene;
pub(crate) use check::groups;
use check::*;
pub(crate) use decode::check_shape;
use decode::*;
use encode::*;
pub(crate) use encode::{glb_container, glb_head};
pub use json::LightmapExtras;
use json::*;
pub use stored::Stored;

/// `extras.prt.transfer_precision` of a half-float transfer view.
const FLOAT16: &str = "float16";

/// How the transfer buffer view is laid out; written into `extras.prt.transfer_layout` and
/// checked on reading, so a future layout change cannot be misread silently.
pub const TRANSFER_LAYOUT: &str = "planar [channel][group][vertex][4] float32 little-endian, \
coefficient k = 4*group + lane, lanes past bands^2 are zero";

/// The layout of a half-float transfer view (`bake --precision f16`), which no accessor
/// describes: glTF has no half-float component type, so the `_PRT_*` attributes are left out
/// and `extras.prt.transfer_precision` is `"float16"`.
pub const TRANSFER_LAYOUT_F16: &str = "planar [channel][group][vertex][4] float16 little-endian, \
coefficient k = 4*group + lane, lanes past bands^2 are zero";

pub use crate::precision::Precision;

/// `transfer` as a half-float file stores it: every coefficient rounded to the nearest f16.
pub fn rounded_to_f16(transfer: &Transfer) -> Transfer {
    let rounded = Precision::F16.round_all(transfer.coeffs());
    let (bands, channels) = (transfer.bands(), transfer.channels());
    Transfer::new(bands, channels, transfer.vertex_count(), rounded)
        .expect("one rounded value for each coefficient")
}

/// Reads a baked file with Python and numpy alone: `python3 reader.py file.glb`.
///
/// Gives `positions` (V, 3), `indices` (T, 3) and `transfer` (V, channels, bands^2), and prints
/// their shapes and the last vertex's transfer as JSON.
pub const PYTHON_READER: &str = r#"import json, struct, sys, numpy as np
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
bv, acc = gltf["bufferViews"], gltf["accessors"]
view = lambda i, dtype: np.frombuffer(binary, dtype, bv[i]["byteLength"] // np.dtype(dtype).itemsize, bv[i].get("byteOffset", 0))
prim, prt = gltf["meshes"][0]["primitives"][0], gltf["meshes"][0]["extras"]["prt"]
positions = view(acc[prim["attributes"]["POSITION"]]["bufferView"], "<f4").reshape(-1, 3)
indices = view(acc[prim["indices"]]["bufferView"], "<u4").reshape(-1, 3)
V, C, K, f = prt["vertices"], prt["channels"], prt["bands"] ** 2, "<f2" if prt.get("transfer_precision") == "float16" else "<f4"
transfer = view(prt["transfer_buffer_view"], f).astype(np.float32).reshape(C, -1, V, 4).transpose(2, 0, 1, 3).reshape(V, C, -1)[:, :, :K]
print(json.dumps({"positions": positions.shape, "indices": indices.shape, "transfer": transfer.shape, "last_vertex": transfer[-1].tolist()}))
"#;

/// Name of the custom vertex attribute holding coefficients `4 * group .. 4 * group + 3` of
/// `channel`.
pub fn transfer_attribute_name(channels: u32, channel: u32, group: usize) -> String {
    if channels == 1 {
        format!("_PRT_{group}")
    } else {
        let name = ["R", "G", "B"]
            .get(channel as usize)
            .copied()
            .unwrap_or("X");
        format!("_PRT_{name}_{group}")
    }
}

/// Writes `stored` to `path` atomically: a temporary file in the same directory, synced, then
/// renamed over the target, so readers never see a half-written file.
///
/// With a lightmap, its OpenEXR file ([`lightmap_file_name`]) is written beside, first; should
/// the .glb then fail, the lightmap is removed again, so that no half of a bake is left.
pub fn write_glb(path: &Path, stored: Stored) -> Result<()> {
    // Fails before encoding, so a typo in the directory costs no work.
    check_destination(path)?;
    let Some(texels) = &stored.baked().lightmap else {
        return write_atomically(path, &encode_valid(stored, None)?);
    };
    let name = lightmap_file_name(path);
    let bytes = encode_valid(stored, Some(&name))?;
    let exr_path = path.with_file_name(&name);
    check_destination(&exr_path)?;
    write_texels(&exr_path, texels)?;
    write_atomically(path, &bytes).inspect_err(|_| {
        let _ = fs::remove_file(&exr_path);
    })
}

/// The name of the lightmap file written beside `glb`: `scene.prt.glb` -> `scene.prt.lightmap.exr`.
pub fn lightmap_file_name(glb: &Path) -> String {
    let name = glb
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "baked".into());
    let stem = match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name,
    };
    format!("{stem}.lightmap.exr")
}

/// Writes a texel bake's OpenEXR file to `path`: from memory, or read back from the scratch
/// file of a lightmap baked in bounded memory.
fn write_texels(path: &Path, texels: &TexelBake) -> Result<()> {
    match &texels.held {
        Some(held) => crate::lightmap::write_lightmap_rows(path, held),
        None => crate::lightmap::write_lightmap(path, &lightmap_of(texels)),
    }
}

/// The file form of a texel bake.
fn lightmap_of(texels: &TexelBake) -> crate::lightmap::Lightmap<'_> {
    crate::lightmap::Lightmap {
        width: texels.width,
        height: texels.height,
        bands: texels.transfer.bands(),
        channels: texels.transfer.channels(),
        coefficients: std::borrow::Cow::Borrowed(texels.transfer.coeffs()),
    }
}

/// Reads and fully validates a baked file.
/// Reads and fully validates a baked file, and the lightmap it refers to.
pub fn read_glb(path: &Path) -> Result<BakedMesh> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        return scene::read_scene_glb(path);
    }
    let (mut baked, lightmap, _) = decode_parts(&bytes, path)?;
    if let Some((extras, per_vertex)) = lightmap {
        let texcoords = TexelBake::corner_texcoords(&baked.scene, &per_vertex);
        baked.lightmap = Some(read_texels(path, &baked, extras, texcoords)?);
    }
    Ok(baked)
}

/// Reads a baked file and, where it holds its transfer compressed, the compressed form (the
/// mesh's `transfer` is then its reconstruction).
pub fn read_glb_compressed(path: &Path) -> Result<(BakedMesh, Option<Cpca>)> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        return Ok((scene::read_scene_glb(path)?, None));
    }
    let (mut baked, lightmap, cpca) = decode_parts(&bytes, path)?;
    if let Some((extras, per_vertex)) = lightmap {
        let texcoords = TexelBake::corner_texcoords(&baked.scene, &per_vertex);
        baked.lightmap = Some(read_texels(path, &baked, extras, texcoords)?);
    }
    Ok((baked, cpca))
}

/// Everything a baked file holds, read in one pass: the baked mesh (its lightmap read too),
/// its compressed form, its probes and its zonal transfer.
pub struct ReadBack {
    /// The mesh and its transfer (for a compressed file, the reconstruction).
    pub baked: BakedMesh,
    pub cpca: Option<Cpca>,
    pub probes: Option<ProbeSet>,
    pub zonal: Option<ZonalTransfer>,
}

/// Reads a baked file once for what [`read_glb_compressed`], [`probes::read_probes`] and
/// [`zonal::read_zonal`] each read, as they read it.
pub fn read_back(path: &Path) -> Result<ReadBack> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    let probes = probes::decode_probes(&bytes, path)?;
    if is_scene_file(&bytes) {
        let (baked, zonal) = scene::read_scene_with_zonal(path)?;
        return Ok(ReadBack {
            baked,
            cpca: None,
            probes,
            zonal,
        });
    }
    let (mut baked, lightmap, cpca) = decode_parts(&bytes, path)?;
    let normals = || Ok(baked.scene.normals.clone().unwrap_or_default());
    let zonal = zonal::decode_mesh_zonal(&bytes, path, normals)?;
    if let Some((extras, per_vertex)) = lightmap {
        let texcoords = TexelBake::corner_texcoords(&baked.scene, &per_vertex);
        baked.lightmap = Some(read_texels(path, &baked, extras, texcoords)?);
    }
    Ok(ReadBack {
        baked,
        cpca,
        probes,
        zonal,
    })
}

/// The lightmap `extras` names, beside `glb`, checked against the mesh it belongs to, with
/// its coordinates per triangle corner (`texcoords`).
fn read_texels(
    glb: &Path,
    baked: &BakedMesh,
    extras: LightmapExtras,
    texcoords: Vec<[f32; 2]>,
) -> Result<TexelBake> {
    let uri_is_plain = !extras.uri.is_empty()
        && !extras.uri.contains(['/', '\\', ':'])
        && extras.uri != ".."
        && extras.uri != ".";
    if !uri_is_plain {
        return Err(Error::baked(
            glb,
            format!(
                "extras.prt.lightmap.uri \"{}\" is not a file name beside it",
                extras.uri
            ),
        ));
    }
    let exr_path = glb.with_file_name(&extras.uri);
    let map = crate::lightmap::read_lightmap(&exr_path)?;
    let expected = (
        extras.width,
        extras.height,
        baked.transfer.bands(),
        baked.transfer.channels(),
    );
    if (map.width, map.height, map.bands, map.channels) != expected {
        return Err(Error::baked(
            &exr_path,
            format!(
                "is {}x{} texels of {} bands and {} channels, but {} expects {}x{} of {} and {}",
                map.width,
                map.height,
                map.bands,
                map.channels,
                glb.display(),
                expected.0,
                expected.1,
                expected.2,
                expected.3
            ),
        ));
    }
    Ok(TexelBake {
        width: map.width,
        height: map.height,
        texcoords,
        set: extras.texcoord,
        transfer: Transfer::new(
            map.bands,
            map.channels,
            (map.width * map.height) as usize,
            map.coefficients.into_owned(),
        )
        .map_err(|e| Error::baked(&exr_path, e.to_string()))?,
        held: None,
    })
}

/// Whether `bytes` are a glTF scene baked in place ([`scene`]) rather than a single mesh.
pub fn is_scene_file(bytes: &[u8]) -> bool {
    let Some(head) = bytes.get(..20) else {
        return false;
    };
    let Ok(json_len) = check_head(head, bytes.len() as u64, Path::new("")) else {
        return false;
    };
    serde_json::from_slice::<serde_json::Value>(&bytes[20..20 + json_len])
        .is_ok_and(|doc| doc["extras"]["prt"]["baked_in_place"] == serde_json::json!(true))
}

/// Reads only the header and JSON of a baked file: metadata, vertex count, triangle count.
///
/// The layout is validated against the BIN chunk's length, but its contents are not read, so
/// this stays fast on large bakes.
pub fn read_metadata(path: &Path) -> Result<(BakeMetadata, usize, usize)> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        let baked = scene::read_scene_glb(path)?;
        let (vertices, triangles) = (baked.scene.positions.len(), baked.scene.triangles.len());
        return Ok((baked.metadata, vertices, triangles));
    }
    let mut file = File::open(path).map_err(|e| Error::io(path, e))?;
    let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut read = |buf: &mut [u8], what: &str| -> Result<()> {
        file.read_exact(buf).map_err(|e| match e.kind() {
            io::ErrorKind::UnexpectedEof => Error::baked(path, format!("file ends inside {what}")),
            _ => Error::io(path, e),
        })
    };
    let mut head = [0u8; 20];
    read(&mut head, "the glTF binary header")?;
    let json_len = check_head(&head, file_len, path)?;
    let mut json = vec![0u8; json_len];
    read(&mut json, "the JSON chunk")?;
    let mut bin_head = [0u8; 8];
    read(&mut bin_head, "the BIN chunk header")?;
    let bin_len = check_bin_head(&bin_head, 20 + json_len as u64, file_len, path)?;
    let doc = parse_document(&json, path)?;
    let plan = plan(&doc, bin_len, path)?;
    Ok((plan.metadata, plan.vertices, plan.triangles))
}

/// What a single-mesh baked file refers to beside its transfer: its lightmap
/// (`extras.prt.lightmap`) and how its transfer is compressed (`extras.prt.cpca`), each if
/// any; the JSON only is parsed.
pub fn read_references(path: &Path) -> Result<References> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    if is_scene_file(&bytes) {
        return scene::stored_references(&bytes).map_err(|m| Error::baked(path, m));
    }
    let prt = mesh_prt_extras(&bytes, path)?;
    Ok(References {
        precision: match prt.transfer_precision.as_deref() {
            Some(FLOAT16) => Precision::F16,
            _ => Precision::F32,
        },
        lightmap: prt.lightmap,
        cpca: prt.cpca,
    })
}

/// What a baked file's `extras.prt` says about where and how its transfer is stored.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct References {
    pub lightmap: Option<LightmapExtras>,
    pub cpca: Option<CpcaExtras>,
    pub precision: Precision,
}

/// `extras.prt` of the single-mesh baked file `bytes` (read from `path`).
fn mesh_prt_extras(bytes: &[u8], path: &Path) -> Result<PrtExtrasIn> {
    let head = bytes
        .get(..20)
        .ok_or_else(|| Error::baked(path, "too short to be a glTF binary (.glb) file"))?;
    let json_len = check_head(head, bytes.len() as u64, path)?;
    let doc = parse_document(&bytes[20..20 + json_len], path)?;
    if doc.meshes.is_empty() {
        return Err(Error::baked(path, "the file contains no mesh"));
    }
    prt_extras(&doc).map_err(|m| Error::baked(path, m))
}

/// Encodes `stored` as a `.glb` in memory. A lightmap is referred to as
/// [`DEFAULT_LIGHTMAP_URI`] (it is [`write_glb`] that names and writes it).
pub fn encode_glb(stored: Stored) -> Result<Vec<u8>> {
    encode_valid(stored, None)
}

/// The lightmap reference of a file encoded without a name for it.
pub const DEFAULT_LIGHTMAP_URI: &str = "lightmap.exr";

/// Decodes and validates a `.glb`; `path` only names the file in error messages. A lightmap the
/// file refers to is not loaded (see [`read_glb`]).
pub fn decode_glb(bytes: &[u8], path: &Path) -> Result<BakedMesh> {
    decode_parts(bytes, path).map(|(baked, _, _)| baked)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::Mode;
    use crate::testing::entries;

    /// Three vertices, one triangle; bands 3 (9 coefficients, not a multiple of 4), RGB, every
    /// coefficient distinct and not exactly representable in decimal.
    fn sample(channels: u32) -> BakedMesh {
        let bands = 3;
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, -0.25, 0.1),
            Vec3::new(-0.3, 2.0, 0.7),
        ];
        let v = positions.len();
        let n = (bands * bands) as usize;
        let coeffs = (0..v * channels as usize * n)
            .map(|i| 0.1 * i as f32 - 1.7 / (i as f32 + 3.0))
            .collect();
        BakedMesh {
            scene: Scene {
                positions,
                normals: Some(vec![Vec3::Z, Vec3::Y, Vec3::new(0.6, 0.0, 0.8)]),
                albedo: vec![Vec3::splat(0.8), Vec3::new(0.1, 0.2, 0.3), Vec3::ONE],
                triangles: vec![[0, 1, 2]],
            },
            transfer: Transfer::new(bands, channels, v, coeffs)
                .expect("a test mesh of its own shape"),
            metadata: BakeMetadata {
                tool: "prt-gpu".into(),
                tool_version: env!("CARGO_PKG_VERSION").into(),
                bands,
                channels,
                mode: Mode::Shadowed,
                samples: 1024,
                sampling: "stratified 32x32".into(),
                seed: 0xDEAD_BEEF_CAFE_F00D,
                backend: "cpu".into(),
                sh_convention: crate::sh::CONVENTION.into(),
                radiometry: "L_o = sum_k l_k t_k".into(),
                bounces: 0,
                fit: crate::bake::Fit::Point,
                fit_points: None,
                target_error: None,
                albedo_free: false,
                subsurface: None,
            },
            lightmap: None,
        }
    }

    fn json_of(bytes: &[u8]) -> serde_json::Value {
        let len = u32_at(bytes, 12) as usize;
        serde_json::from_slice(&bytes[20..20 + len]).unwrap()
    }

    #[test]
    fn round_trip_is_exact() {
        for channels in [1, 3] {
            let baked = sample(channels);
            let bytes = Stored::plain(&baked).and_then(encode_glb).unwrap();
            let decoded = decode_glb(&bytes, Path::new("mem.glb")).unwrap();
            assert_eq!(decoded, baked);
        }
    }

    #[test]
    fn lightmap_coordinates_are_written_per_vertex_where_the_corners_agree() {
        // Two triangles sharing an edge: four vertices, six corners.
        let mut baked = sample(1);
        baked.scene.positions.push(Vec3::new(1.0, 1.0, 0.0));
        baked.scene.albedo.push(Vec3::ONE);
        baked.scene.normals.as_mut().unwrap().push(Vec3::Z);
        baked.scene.triangles.push([1, 3, 2]);
        let n = baked.transfer.coeffs_per_channel();
        let coeffs = [baked.transfer.coeffs(), &vec![0.5; n]].concat();
        baked.transfer = Transfer::new(3, 1, 4, coeffs).unwrap();
        let per_vertex = [[0.1, 0.2], [0.7, 0.2], [0.1, 0.8], [0.7, 0.8]];
        let texcoords = TexelBake::corner_texcoords(&baked.scene, &per_vertex);
        assert_eq!(texcoords.len(), 6);
        baked.lightmap = Some(TexelBake {
            width: 2,
            height: 2,
            texcoords,
            set: 0,
            transfer: Transfer::zeros(3, 1, 4),
            held: None,
        });
        let bytes = Stored::plain(&baked).and_then(|s| encode_valid(s, Some("a.exr")));
        let doc = json_of(&bytes.unwrap());
        let attributes = &doc["meshes"][0]["primitives"][0]["attributes"];
        let accessor = &doc["accessors"][attributes["TEXCOORD_0"].as_u64().unwrap() as usize];
        assert_eq!(accessor["count"], 4);
        // A vertex whose corners lie on two charts cannot be written per vertex.
        baked.lightmap.as_mut().unwrap().texcoords[3] = [0.9, 0.9];
        let refused = Stored::plain(&baked)
            .and_then(|s| encode_valid(s, Some("a.exr")))
            .unwrap_err();
        assert!(
            refused.to_string().contains("split where its charts meet"),
            "{refused}"
        );
    }

    #[test]
    fn encoding_is_deterministic() {
        let baked = sample(3);
        assert_eq!(
            Stored::plain(&baked).and_then(encode_glb).unwrap(),
            Stored::plain(&baked.clone()).and_then(encode_glb).unwrap()
        );
    }

    #[test]
    fn layout_follows_the_spec() {
        let baked = sample(3);
        let bytes = Stored::plain(&baked).and_then(encode_glb).unwrap();
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(u32_at(&bytes, 8) as usize, bytes.len());
        let json_len = u32_at(&bytes, 12) as usize;
        assert_eq!(json_len % 4, 0);
        assert_eq!(u32_at(&bytes, 16), CHUNK_JSON);
        assert_eq!(u32_at(&bytes, 20 + json_len + 4), CHUNK_BIN);
        assert_eq!(u32_at(&bytes, 20 + json_len) % 4, 0);

        let doc = json_of(&bytes);
        assert_eq!(doc["asset"]["version"], "2.0");
        let attributes = &doc["meshes"][0]["primitives"][0]["attributes"];
        // bands^2 = 9 needs three groups of four per channel.
        for name in ["R", "G", "B"] {
            for group in 0..3 {
                assert!(attributes.get(format!("_PRT_{name}_{group}")).is_some());
            }
            assert!(attributes.get(format!("_PRT_{name}_3")).is_none());
        }
        let pos = &doc["accessors"][attributes["POSITION"].as_u64().unwrap() as usize];
        assert_eq!(pos["min"], serde_json::json!([-0.3, -0.25, 0.0]));
        assert_eq!(pos["max"], serde_json::json!([1.0, 2.0, 0.7]));
        let prt = &doc["meshes"][0]["extras"]["prt"];
        assert_eq!(prt["vertices"], 3);
        assert_eq!(prt["seed"], 0xDEAD_BEEF_CAFE_F00Du64);
        assert_eq!(prt["mode"], "shadowed");
        assert_eq!(prt["transfer_layout"], TRANSFER_LAYOUT);

        // Lane 1 of group 2 in channel 0 is coefficient 9: padding, so zero.
        let view = &doc["bufferViews"][prt["transfer_buffer_view"].as_u64().unwrap() as usize];
        let bin = 28 + json_len + view["byteOffset"].as_u64().unwrap() as usize;
        let at = |c: usize, g: usize, vtx: usize, lane: usize| {
            f32_at(&bytes, bin + ((c * 3 + g) * 3 + vtx) * 16 + 4 * lane)
        };
        assert_eq!(at(0, 2, 1, 1), 0.0);
        assert_eq!(at(0, 2, 1, 0), baked.transfer.vertex_channel(1, 0)[8]);
        assert_eq!(at(2, 1, 2, 3), baked.transfer.vertex_channel(2, 2)[7]);
    }

    #[test]
    fn invalid_meshes_are_refused() {
        let mut no_normals = sample(3);
        no_normals.scene.normals = None;
        let mut count = sample(3);
        let shape = (count.transfer.bands(), count.transfer.channels());
        count.transfer = Transfer::zeros(shape.0, shape.1, 4);
        let mut index = sample(3);
        index.scene.triangles[0][2] = 3;
        let mut nan = sample(3);
        nan.transfer.coeffs_mut()[5] = f32::NAN;
        let mut meta = sample(3);
        meta.metadata.bands = 4;
        for baked in [no_normals, count, index, nan, meta] {
            let err = Stored::plain(&baked)
                .and_then(encode_glb)
                .unwrap_err()
                .to_string();
            assert!(!err.contains('\n'), "{err}");
        }
    }

    #[test]
    fn damaged_files_are_errors_not_panics() {
        let bytes = Stored::plain(&sample(3)).and_then(encode_glb).unwrap();
        let path = Path::new("damaged.glb");
        for len in 0..bytes.len() {
            assert!(
                decode_glb(&bytes[..len], path).is_err(),
                "truncated to {len}"
            );
        }
        let json_len = u32_at(&bytes, 12) as usize;
        let mut rejected = 0;
        for bit in 0..bytes.len() * 8 {
            let mut flipped = bytes.clone();
            flipped[bit / 8] ^= 1 << (bit % 8);
            let result = decode_glb(&flipped, path);
            // Headers carry no redundancy to spare: any flip there must be caught.
            let byte = bit / 8;
            if byte < 20 || (20 + json_len..28 + json_len).contains(&byte) {
                assert!(result.is_err(), "flip of bit {bit} accepted");
            }
            if let Err(e) = result {
                assert!(!e.to_string().contains('\n'));
                rejected += 1;
            }
        }
        assert!(rejected > 0);
        let mut extended = bytes.clone();
        extended.extend_from_slice(&[0; 4]);
        assert!(decode_glb(&extended, path).is_err());
    }

    #[test]
    fn foreign_gltf_is_refused() {
        let bytes = Stored::plain(&sample(3)).and_then(encode_glb).unwrap();
        let mut doc = json_of(&bytes);
        doc["meshes"][0].as_object_mut().unwrap().remove("extras");
        let mut json = serde_json::to_vec(&doc).unwrap();
        json.resize(json.len().next_multiple_of(4), b' ');
        let json_len = u32_at(&bytes, 12) as usize;
        let bin = &bytes[20 + json_len..];
        let mut out = Vec::new();
        let total = (20 + json.len() + bin.len()) as u32;
        for word in [GLB_MAGIC, GLB_VERSION, total, json.len() as u32, CHUNK_JSON] {
            out.extend_from_slice(&word.to_le_bytes());
        }
        out.extend_from_slice(&json);
        out.extend_from_slice(bin);
        let err = decode_glb(&out, Path::new("x.glb"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("extras.prt"), "{err}");
    }

    #[test]
    fn write_into_missing_directory_fails_cleanly() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("nope").join("out.glb");
        let err = Stored::plain(&sample(3))
            .and_then(|stored| write_glb(&target, stored))
            .unwrap_err()
            .to_string();
        assert!(err.contains("does not exist"), "{err}");
        assert!(!target.exists());
        assert!(entries(tmp.path()).is_empty());
    }

    #[test]
    fn write_then_read_round_trip() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("mesh.glb");
        let baked = sample(3);
        Stored::plain(&baked)
            .and_then(|stored| write_glb(&target, stored))
            .unwrap();
        // Overwriting an existing file goes through the same rename.
        Stored::plain(&baked)
            .and_then(|stored| write_glb(&target, stored))
            .unwrap();
        assert_eq!(entries(tmp.path()), ["mesh.glb"]);
        assert_eq!(read_glb(&target).unwrap(), baked);
        assert_eq!(
            fs::read(&target).unwrap(),
            Stored::plain(&baked).and_then(encode_glb).unwrap()
        );
        let (metadata, vertices, triangles) = read_metadata(&target).unwrap();
        assert_eq!((metadata, vertices, triangles), (baked.metadata, 3, 1));
    }

    #[test]
    fn failed_write_leaves_no_temporary_file() {
        let tmp = tempfile::tempdir().unwrap();
        // Renaming a file over a directory fails after the temporary file is complete.
        let target = tmp.path().join("taken.glb");
        fs::create_dir(&target).unwrap();
        let err = Stored::plain(&sample(3))
            .and_then(|stored| write_glb(&target, stored))
            .unwrap_err();
        assert!(
            matches!(err, Error::Io { ref path, .. } if path == &target),
            "{err}"
        );
        assert_eq!(entries(tmp.path()), ["taken.glb"]);
        assert!(target.is_dir());

        // Invalid input fails before anything is created.
        let mut bad = sample(3);
        bad.transfer.coeffs_mut()[0] = f32::INFINITY;
        assert!(Stored::plain(&bad).is_err());
        assert_eq!(entries(tmp.path()), ["taken.glb"]);
    }

    #[test]
    fn the_khronos_validator_finds_no_errors() {
        let tmp = tempfile::tempdir().unwrap();
        // One channel and three: the attribute names differ; bands 3 pads the last group.
        for channels in [1, 3] {
            let target = tmp.path().join(format!("mesh-{channels}.glb"));
            Stored::plain(&sample(channels))
                .and_then(|stored| write_glb(&target, stored))
                .unwrap();
            let Some(report) = crate::gltf_validator::validate_or_skip(&target) else {
                return;
            };
            assert_eq!(report.num_errors, 0, "{}", report.listing());
            assert_eq!(report.num_warnings, 0, "{}", report.listing());
        }
    }

    #[test]
    fn read_metadata_rejects_truncated_files() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("cut.glb");
        let bytes = Stored::plain(&sample(1)).and_then(encode_glb).unwrap();
        for len in [0, 10, 30, bytes.len() - 4] {
            fs::write(&target, &bytes[..len]).unwrap();
            assert!(read_metadata(&target).is_err(), "truncated to {len}");
        }
    }

    #[test]
    fn readme_quotes_the_python_readers_verbatim() {
        let readme = include_str!("../../README.md");
        for (reader, name) in [
            (PYTHON_READER, "glb::PYTHON_READER"),
            (compressed::PYTHON_READER, "glb::compressed::PYTHON_READER"),
            (local::PYTHON_READER, "glb::local::PYTHON_READER"),
            (probes::PYTHON_READER, "glb::probes::PYTHON_READER"),
            (zonal::PYTHON_READER, "glb::zonal::PYTHON_READER"),
        ] {
            assert!(
                readme.contains(reader),
                "README.md's snippet differs from {name}"
            );
        }
    }

    #[test]
    fn python_reader_reads_the_file() {
        let line_count = PYTHON_READER.lines().count();
        assert!(line_count <= 12, "{line_count} lines");
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("mesh.glb");
        let baked = sample(3);
        Stored::plain(&baked)
            .and_then(|stored| write_glb(&target, stored))
            .unwrap();
        let Some(printed) = crate::testing::numpy_reader_output(&target) else {
            return;
        };
        assert_eq!(printed["positions"], serde_json::json!([3, 3]));
        assert_eq!(printed["indices"], serde_json::json!([1, 3]));
        assert_eq!(printed["transfer"], serde_json::json!([3, 3, 9]));
        for channel in 0..3 {
            let row: Vec<f32> = printed["last_vertex"][channel]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap() as f32)
                .collect();
            assert_eq!(row, baked.transfer.vertex_channel(2, channel));
        }
    }
}
