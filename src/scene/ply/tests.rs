//! Tests of `ply`.

use super::*;
use std::io::Write;

/// A value with its PLY type, written the same way in all three encodings.
#[derive(Clone, Copy)]
enum V {
    F64(f64),
    F32(f32),
    U8(u8),
    I16(i16),
    U16(u16),
    I32(i32),
    U32(u32),
}

fn encode(header: &str, rows: &[Vec<V>], format: &str) -> Vec<u8> {
    let mut out = header.replace("FORMAT", format).into_bytes();
    for row in rows {
        for (i, value) in row.iter().enumerate() {
            match format {
                "ascii" => {
                    let text = match *value {
                        V::F64(v) => v.to_string(),
                        V::F32(v) => v.to_string(),
                        V::U8(v) => v.to_string(),
                        V::I16(v) => v.to_string(),
                        V::U16(v) => v.to_string(),
                        V::I32(v) => v.to_string(),
                        V::U32(v) => v.to_string(),
                    };
                    let separator = if i + 1 == row.len() { "\n" } else { " " };
                    out.extend_from_slice(format!("{text}{separator}").as_bytes());
                }
                _ => out.extend(binary(*value, format == "binary_big_endian")),
            }
        }
    }
    out
}

fn binary(value: V, big_endian: bool) -> Vec<u8> {
    macro_rules! bytes {
        ($v:expr) => {
            if big_endian {
                $v.to_be_bytes().to_vec()
            } else {
                $v.to_le_bytes().to_vec()
            }
        };
    }
    match value {
        V::F64(v) => bytes!(v),
        V::F32(v) => bytes!(v),
        V::U8(v) => vec![v],
        V::I16(v) => bytes!(v),
        V::U16(v) => bytes!(v),
        V::I32(v) => bytes!(v),
        V::U32(v) => bytes!(v),
    }
}

const FORMATS: [&str; 3] = ["ascii", "binary_little_endian", "binary_big_endian"];

const HEADER: &str = "ply\nformat FORMAT 1.0\ncomment written by the prt-gpu tests\n\
    element vertex 5\nproperty double x\nproperty float y\nproperty float32 z\n\
    property float confidence\nproperty float nx\nproperty float ny\nproperty float nz\n\
    property uchar red\nproperty uint8 green\nproperty uchar blue\n\
    element edge 2\nproperty int vertex1\nproperty list uchar int path\n\
    element face 2\nproperty uchar flags\nproperty list uchar uint vertex_indices\n\
    property list uchar float texcoord\nend_header\n";

fn rows() -> Vec<Vec<V>> {
    let vertex = |x: f64, y: f32, z: f32, rgb: [u8; 3]| {
        vec![
            V::F64(x),
            V::F32(y),
            V::F32(z),
            V::F32(0.5),
            V::F32(0.0),
            V::F32(0.0),
            V::F32(2.0),
            V::U8(rgb[0]),
            V::U8(rgb[1]),
            V::U8(rgb[2]),
        ]
    };
    vec![
        vertex(0.0, 0.0, 0.0, [255, 0, 128]),
        vertex(1.0, 0.0, 0.0, [10, 20, 30]),
        vertex(1.0, 1.0, 0.0, [255, 255, 255]),
        vertex(0.0, 1.0, 0.1, [0, 0, 0]),
        vertex(0.5, 0.5, -1.0e-7, [1, 2, 3]),
        vec![V::I32(0), V::U8(3), V::I32(1), V::I32(2), V::I32(3)],
        vec![V::I32(4), V::U8(0)],
        vec![
            V::U8(7),
            V::U8(4),
            V::U32(0),
            V::U32(1),
            V::U32(2),
            V::U32(3),
            V::U8(2),
            V::F32(0.25),
            V::F32(0.5),
        ],
        vec![
            V::U8(0),
            V::U8(3),
            V::U32(0),
            V::U32(1),
            V::U32(4),
            V::U8(0),
        ],
    ]
}

fn parse_bytes(bytes: &[u8]) -> Result<Scene> {
    parse(bytes, Path::new("test.ply"))
}

fn error_of(bytes: &[u8]) -> String {
    match parse_bytes(bytes) {
        Err(e @ Error::Mesh { .. }) => e.to_string(),
        other => panic!("expected a mesh error, got {other:?}"),
    }
}

#[test]
fn three_encodings_give_the_same_scene() {
    let scenes: Vec<Scene> = FORMATS
        .iter()
        .map(|format| parse_bytes(&encode(HEADER, &rows(), format)).unwrap())
        .collect();
    assert_eq!(scenes[0], scenes[1]);
    assert_eq!(scenes[0], scenes[2]);

    let scene = &scenes[0];
    assert_eq!(scene.positions.len(), 5);
    assert_eq!(scene.positions[3], Vec3::new(0.0, 1.0, 0.1));
    assert_eq!(scene.positions[4].z, -1.0e-7);
    assert_eq!(scene.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
    assert_eq!(scene.normals, Some(vec![Vec3::new(0.0, 0.0, 2.0); 5]));
    assert_eq!(scene.albedo[2], Vec3::ONE);
    assert_eq!(scene.albedo[3], Vec3::ZERO);
    // 128/255 in sRGB is about 0.2158 linear: the conversion happened.
    assert_eq!(scene.albedo[0].x, 1.0);
    assert!(
        (scene.albedo[0].z - 0.2158605).abs() < 1e-6,
        "{}",
        scene.albedo[0]
    );
}

#[test]
fn a_byte_order_mark_before_the_header_is_skipped() {
    for format in FORMATS {
        let plain = encode(HEADER, &rows(), format);
        let marked = [b"\xEF\xBB\xBF".as_slice(), &plain].concat();
        assert_eq!(parse_bytes(&marked).unwrap(), parse_bytes(&plain).unwrap());
    }
}

#[test]
fn gzip_round_trip() {
    for format in FORMATS {
        let plain = encode(HEADER, &rows(), format);
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        encoder.write_all(&plain).unwrap();
        let compressed = encoder.finish().unwrap();
        assert_eq!(
            parse_bytes(&compressed).unwrap(),
            parse_bytes(&plain).unwrap()
        );
        let cut = &compressed[..compressed.len() / 2];
        assert!(error_of(cut).contains("gzip"));
    }
}

#[test]
fn every_truncation_of_binary_data_is_an_error() {
    for format in ["binary_little_endian", "binary_big_endian"] {
        let bytes = encode(HEADER, &rows(), format);
        let header_len = HEADER.replace("FORMAT", format).len();
        for len in header_len..bytes.len() {
            let message = error_of(&bytes[..len]);
            assert!(message.contains("truncated data"), "{len}: {message}");
        }
    }
    let header = HEADER.replace("FORMAT", "binary_little_endian");
    let message = error_of(&header.as_bytes()[..header.len() - 5]);
    assert!(message.contains("no end_header"), "{message}");
}

#[test]
fn truncated_ascii_is_an_error() {
    let bytes = encode(HEADER, &rows(), "ascii");
    let message = error_of(&bytes[..bytes.len() - 16]);
    assert!(
        message.contains("truncated data in element 'face'"),
        "{message}"
    );
}

#[test]
fn no_faces_is_an_error() {
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
        property float y\nproperty float z\nelement face 0\n\
        property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    assert!(error_of(header.as_bytes()).ends_with("PLY has no faces"));
    let no_element = header.replace(
        "element face 0\nproperty list uchar int vertex_indices\n",
        "",
    );
    assert!(error_of(no_element.as_bytes()).ends_with("PLY has no faces"));
}

#[test]
fn bad_headers_are_errors() {
    assert!(error_of(b"solid cube\nfacet normal 0 0 1\n").contains("not a PLY"));
    assert!(error_of(b"").contains("not a PLY"));
    let good = encode(HEADER, &rows(), "ascii");
    let text = String::from_utf8(good).unwrap();
    let middle = text.replace("format ascii 1.0", "format binary_middle_endian 1.0");
    assert!(error_of(middle.as_bytes()).contains("unsupported PLY format"));
    let version = text.replace("format ascii 1.0", "format ascii 2.0");
    assert!(error_of(version.as_bytes()).contains("unsupported PLY version"));
    let no_z = text.replace("property float32 z\n", "");
    assert!(error_of(no_z.as_bytes()).contains("no 'z' property"));
    let bad_type = text.replace("property float y", "property quad y");
    assert!(error_of(bad_type.as_bytes()).contains("unknown PLY property type \"quad\""));
    let no_list = text.replace("vertex_indices", "corners");
    assert!(error_of(no_list.as_bytes()).contains("no vertex_indices list"));
}

fn small(faces: &str) -> Vec<u8> {
    format!(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_index\n\
         end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n{faces}\n"
    )
    .into_bytes()
}

/// Data after the last declared element is not read, and a warning says so; white space
/// after an ascii body, and an element after the faces, are no such data.
#[test]
fn data_past_the_declared_elements_is_a_warning() {
    let warnings = |bytes: &[u8]| parse_with_warnings(bytes, Path::new("t.ply")).unwrap().1;
    assert!(warnings(&small("3 0 1 2\n\n  ")).is_empty());
    let said = warnings(&small("3 0 1 2\n3 1 2 3"));
    assert_eq!(
        said,
        ["7 byte(s) after the last element its header declares were not read"]
    );
    let with_edges = String::from_utf8(small("3 0 1 2\n0 1")).unwrap().replace(
        "end_header",
        "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header",
    );
    assert!(warnings(with_edges.as_bytes()).is_empty());
}

#[test]
fn bad_faces_are_errors() {
    let message = error_of(&small("3 0 -1 2"));
    assert!(message.contains("negative vertex index -1"), "{message}");
    let message = error_of(&small("2 0 1"));
    assert!(message.contains("face with 2 vertices"), "{message}");
    assert!(message.contains("item 0 of 1"), "{message}");
    let message = error_of(&small("3 0 1 x"));
    assert!(message.contains("invalid number \"x\""), "{message}");
}

#[test]
fn vertex_index_spelling_and_unchecked_range() {
    // Out-of-range indices pass through: prepare rejects them for every format alike.
    let scene = parse_bytes(&small("5 0 1 2 3 9")).unwrap();
    assert_eq!(scene.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 9]]);
    assert_eq!(scene.normals, None);
    assert_eq!(scene.albedo, vec![DEFAULT_ALBEDO; 4]);
}

#[test]
fn other_scalar_types_and_partial_groups() {
    let header = "ply\nformat FORMAT 1.0\nelement vertex 3\nproperty short x\n\
        property int16 y\nproperty int z\nproperty float nx\nproperty float ny\n\
        property float red\nproperty float green\nproperty float blue\n\
        element face 1\nproperty list ushort short vertex_indices\nend_header\n";
    let vertex = |x: i16, y: i16, z: i32, red: f32| {
        let mut row = vec![V::I16(x), V::I16(y), V::I32(z), V::F32(0.0), V::F32(1.0)];
        row.extend([V::F32(red), V::F32(0.25), V::F32(-3.0)]);
        row
    };
    let rows = vec![
        vertex(0, 0, 0, 0.5),
        vertex(-2, 0, 7, 1.5),
        vertex(0, 3, 0, f32::NAN),
        vec![V::U16(3), V::I16(0), V::I16(1), V::I16(2)],
    ];
    let scenes: Vec<Scene> = FORMATS
        .iter()
        .map(|f| parse_bytes(&encode(header, &rows, f)).unwrap())
        .collect();
    // A NaN colour makes Scene equality fail by design, so compare field by field.
    for scene in &scenes {
        assert_eq!(
            scene.positions,
            vec![
                Vec3::ZERO,
                Vec3::new(-2.0, 0.0, 7.0),
                Vec3::new(0.0, 3.0, 0.0)
            ]
        );
        assert_eq!(scene.triangles, vec![[0, 1, 2]]);
        // Only nx and ny: not a normal.
        assert_eq!(scene.normals, None);
        // Float colours are linear and clamped; a NaN is kept for prepare to reject.
        assert_eq!(scene.albedo[0], Vec3::new(0.5, 0.25, 0.0));
        assert_eq!(scene.albedo[1], Vec3::new(1.0, 0.25, 0.0));
        assert!(scene.albedo[2].x.is_nan());
    }
}

#[test]
fn mutated_inputs_never_panic() {
    // Every byte replaced by values that make counts huge, negative or non-numeric: each
    // parse must end in a scene or an error, within the data's size.
    for format in FORMATS {
        let bytes = encode(HEADER, &rows(), format);
        for position in 0..bytes.len() {
            for value in [0x00, 0x7f, 0x80, 0xff, b'9', b'-', b' '] {
                let mut mutated = bytes.clone();
                mutated[position] = value;
                if let Ok(scene) = parse_bytes(&mutated) {
                    assert!(scene.albedo.len() == scene.positions.len());
                }
            }
        }
    }
}

#[test]
fn dragon_counts() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/dragon_vrip_res3.ply.gz");
    let scene = load(&path).unwrap();
    assert_eq!(scene.vertex_count(), 22_998);
    assert_eq!(scene.triangle_count(), 47_794);
    assert!(scene.normals.is_none());
}

#[test]
fn missing_file_is_an_io_error() {
    let result = load(Path::new("/nonexistent/prt-gpu-test.ply"));
    assert!(matches!(result, Err(Error::Io { .. })));
}
