//! The lightmap file read back by the reference OpenEXR library (its Python binding, pip's
//! `OpenEXR`), independently of the `exr` crate that writes it: every channel's name, type,
//! size and values. Skips with a printed reason where python3 with OpenEXR is missing, except
//! under CI (`CI` set), where `ci/test.sh` installs it and a missing binding is a failure.

use std::path::Path;

use prt_gpu::lightmap::{channel_name, channel_suffixes, write_lightmap, Lightmap};

/// Prints, as JSON, the file's header attributes of ours and every channel: its pixel type,
/// shape (height, width) and values in row-major order.
const OPENEXR_DUMP: &str = r#"
import json, sys
import OpenEXR
f = OpenEXR.File(sys.argv[1], separate_channels=True)
part = f.parts[0]
channels = {}
for name, channel in part.channels.items():
    pixels = channel.pixels
    channels[name] = {
        "dtype": str(pixels.dtype),
        "shape": list(pixels.shape),
        "values": [float(v) for v in pixels.reshape(-1)],
    }
header = {k: v for k, v in part.header.items() if k.startswith("prt")}
print(json.dumps({"channels": channels, "header": header, "parts": len(f.parts)}))
"#;

fn python_with_openexr() -> bool {
    prt_gpu::testing::python_with(&["OpenEXR", "numpy"])
}

fn openexr_dump(path: &Path) -> serde_json::Value {
    prt_gpu::testing::python_json(OPENEXR_DUMP, path)
}

/// Values of many magnitudes and both signs, none exactly representable in half.
fn lightmap(width: u32, height: u32, bands: u32, channels: u32) -> Lightmap<'static> {
    let count = (width * height * channels * bands * bands) as usize;
    Lightmap {
        width,
        height,
        bands,
        channels,
        coefficients: (0..count)
            .map(|i| {
                let i = i as f32;
                (i * 0.731).sin() * 10f32.powf((i * 0.37).cos() * 2.0 - 1.0)
            })
            .collect(),
    }
}

/// Whether `read` is `written` rounded to half: within half an ulp of an 11-bit significand,
/// or of the smallest subnormal step near zero.
fn is_half_of(read: f64, written: f32) -> bool {
    let tolerance = (written.abs() as f64 * 2f64.powi(-11)).max(2f64.powi(-25));
    (read - written as f64).abs() <= tolerance
}

#[test]
fn openexr_reads_every_channel_as_written() {
    if !python_with_openexr() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (width, height, bands, channels) in [(9, 4, 3, 3), (5, 6, 4, 1), (3, 2, 11, 3)] {
        let map = lightmap(width, height, bands, channels);
        let path = dir.path().join(format!("lightmap_{bands}_{channels}.exr"));
        write_lightmap(&path, &map).unwrap();
        let dump = openexr_dump(&path);
        assert_eq!(dump["parts"], 1);
        assert_eq!(dump["header"]["prtBands"], bands);
        let read = dump["channels"].as_object().unwrap();
        let count = (bands * bands) as usize;
        let suffixes = channel_suffixes(channels);
        assert_eq!(read.len(), count * suffixes.len(), "channel count");
        for k in 0..count {
            for (c, suffix) in suffixes.iter().enumerate() {
                let name = channel_name(k, suffix);
                let channel = &read[&name];
                assert_eq!(channel["dtype"], "float16", "{name}");
                assert_eq!(
                    channel["shape"],
                    serde_json::json!([height, width]),
                    "{name}"
                );
                let values = channel["values"].as_array().unwrap();
                for (texel, value) in values.iter().enumerate() {
                    let written = map.coefficients[(texel * suffixes.len() + c) * count + k];
                    let value = value.as_f64().unwrap();
                    assert!(
                        is_half_of(value, written),
                        "{name} texel {texel}: wrote {written}, OpenEXR read {value}"
                    );
                }
            }
        }
    }
}
