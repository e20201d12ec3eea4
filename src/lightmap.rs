//! The baked lightmap: per-texel SH transfer as one multi-channel, half-float OpenEXR file.
//!
//! Layout of the file (one part, scan lines, ZIP compression, lossless for the halves):
//! - one pixel per atlas texel: texel `(x, y)` is pixel `(x, y)`, the first scan line is the
//!   atlas' row `y = 0`;
//! - one layer per SH coefficient `k = l(l+1)+m` (`0 <= k < bands^2`, the convention of
//!   [`crate::sh`]): channels `sh{k:02}.R`, `sh{k:02}.G`, `sh{k:02}.B` for coloured transfer,
//!   `sh{k:02}.Y` for one channel (so `sh00.R` ... `sh08.B` for 3 bands in colour; from
//!   `k = 100` on, three digits);
//! - every channel half float (`f16`): transfer coefficients are small (at most a few times
//!   the albedo), so half keeps about three significant digits; values beyond half's range are
//!   refused rather than written as infinities;
//! - attributes: `prtBands` (int), `prtConvention` (the SH convention, [`crate::sh::CONVENTION`])
//!   and `prtLayout` (this layout in a line), for readers that want to check.
//!
//! The file is encoded a block of scan lines at a time (from memory, or from any [`TexelRows`]
//! such as a lightmap held in a scratch file) into a temporary file beside the target, which is
//! put in place only once written ([`crate::fs::AtomicFile`]), so no partial file ever exists
//! and neither the half floats nor the compressed bytes are held whole.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::{Cursor, Write};
use std::ops::Range;
use std::path::Path;
use std::sync::Mutex;

use exr::block::{BlockIndex, UncompressedBlock};
use exr::image::write::channels::{ChannelsWriter, WritableChannels};
use exr::math::RoundingMode;
use exr::meta::attribute::{ChannelDescription, ChannelList, LevelMode, SampleType};
use exr::meta::header::Header;
use exr::prelude::{
    f16, AttributeValue, Encoding, Image, Layer, LayerAttributes, Text, Vec2, WritableImage,
};

use crate::error::{one_line, Error, Result};
use crate::sh;

/// Per-texel transfer: `coefficients[((y * width + x) * channels + c) * bands^2 + k]`; a
/// lightmap being written borrows its coefficients from the bake (a 2048² map of 4 bands in
/// colour is 805 MB of them).
#[derive(Clone, Debug, PartialEq)]
pub struct Lightmap<'a> {
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    /// 1 (grey transfer, channel `Y`) or 3 (`R`, `G`, `B`).
    pub channels: u32,
    /// `[texel row-major][channel][k]`.
    pub coefficients: Cow<'a, [f32]>,
}

/// Reads a baked file's lightmap with Python, numpy and OpenEXR (pip's `OpenEXR` 3.x):
/// `python3 reader.py file.glb`. Gives `uv` (V, 2), each vertex's lightmap coordinates (of the
/// first primitive, for a glTF scene baked in place; float coordinates), and
/// `texels` (height, width, channels, bands^2), the transfer of every texel (row 0 at the top,
/// as `uv`'s v = 0); prints their shapes and the centre texel's transfer as JSON.
pub const PYTHON_READER: &str = r#"import json, pathlib, struct, sys, numpy as np, OpenEXR
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]  # JSON chunk length; BIN chunk data starts at 28 + n
gltf, binary = json.loads(data[20:20 + n]), data[28 + n:]
prim, prt = gltf["meshes"][0]["primitives"][0], gltf["meshes"][0]["extras"]["prt"]
lightmap = prt.get("lightmap") or gltf["extras"]["prt"]["lightmap"]  # a mesh's, or a scene's
accessor = gltf["accessors"][prim["attributes"]["TEXCOORD_%d" % lightmap["texcoord"]]]
view = gltf["bufferViews"][accessor["bufferView"]]
uv = np.frombuffer(binary, "<f4", view["byteLength"] // 4, view.get("byteOffset", 0)).reshape(-1, 2)
exr = OpenEXR.File(str(pathlib.Path(sys.argv[1]).with_name(lightmap["uri"])), separate_channels=True)
channels = exr.parts[0].channels
colours, K = ("RGB" if prt["channels"] == 3 else "Y"), prt["bands"] ** 2
texels = np.stack([np.stack([channels["sh%02d.%s" % (k, c)].pixels for k in range(K)], -1) for c in colours], -2).astype(np.float32)
H, W = texels.shape[:2]
print(json.dumps({"uv": uv.shape, "texels": texels.shape, "centre": texels[H // 2, W // 2].tolist()}))
"#;

/// The attribute that holds the band count.
pub const BANDS_ATTRIBUTE: &str = "prtBands";
const CONVENTION_ATTRIBUTE: &str = "prtConvention";
const LAYOUT_ATTRIBUTE: &str = "prtLayout";
/// The channel layout in a line (the file's `prtLayout`, and `extras.prt.lightmap.layout` of the .glb).
pub const LAYOUT: &str = "channel shKK.C = SH coefficient k = l(l+1)+m of colour C (R, G, B, or Y \
for one channel); pixel (x, y) = atlas texel (x, y)";

/// The largest value a half float holds.
const HALF_MAX: f32 = 65504.0;

/// The channel names of a lightmap with `channels` channels, in the order of its values.
pub fn channel_suffixes(channels: u32) -> &'static [&'static str] {
    if channels == 1 {
        &["Y"]
    } else {
        &["R", "G", "B"]
    }
}

/// The name of coefficient `k`'s channel `suffix`, such as `sh04.G`.
pub fn channel_name(k: usize, suffix: &str) -> String {
    format!("sh{k:02}.{suffix}")
}

impl Lightmap<'_> {
    fn coefficient_count(&self) -> usize {
        sh::coeff_count(self.bands)
    }

    /// `Ok` for a lightmap that can be written: a shape a file holds ([`LightmapShape::check`]),
    /// as many values as it says, each finite and within half-float range.
    pub fn check(&self) -> Result<()> {
        self.shape().check()?;
        let expected = (self.width as u64)
            * (self.height as u64)
            * (self.channels as u64)
            * (self.coefficient_count() as u64);
        if self.coefficients.len() as u64 != expected {
            return Err(Error::Options(format!(
                "a {} x {} lightmap of {} channels and {} bands needs {expected} values, not {}",
                self.width,
                self.height,
                self.channels,
                self.bands,
                self.coefficients.len()
            )));
        }
        match self
            .coefficients
            .iter()
            .position(|v| !v.is_finite() || v.abs() > HALF_MAX)
        {
            Some(i) => Err(Error::Options(format!(
                "lightmap value {} (texel {}) is not a finite half float",
                self.coefficients[i],
                i / (self.channels as usize * self.coefficient_count())
            ))),
            None => Ok(()),
        }
    }
}

/// Writes `lightmap` to `path` as OpenEXR (the layout in the module documentation), whole or
/// not at all.
pub fn write_lightmap(path: &Path, lightmap: &Lightmap) -> Result<()> {
    lightmap.check()?;
    write_lightmap_rows(path, lightmap)
}

/// Writes the lightmap whose rows `rows` gives to `path`, a block of scan lines at a time, so
/// that neither its half floats nor its compressed bytes are ever held whole; the file appears
/// only once written. A value that is not a finite half float fails the write.
pub fn write_lightmap_rows(path: &Path, rows: &dyn TexelRows) -> Result<()> {
    let shape = rows.shape();
    shape.check()?;
    let mut file = crate::fs::AtomicFile::create(path)?;
    let failed = |message: String| Error::baked(path, format!("OpenEXR: {message}"));
    let writer = TexelChannels::new(rows);
    {
        let mut buffered = std::io::BufWriter::new(file.file_mut());
        image_of(shape, &writer)
            .write()
            .to_buffered(&mut buffered)
            .map_err(|e| failed(one_line(&e.to_string())))?;
        buffered.flush().map_err(|e| Error::io(path, e))?;
    }
    writer.finish()?;
    let header = file.read_prefix(HEADER_READ)?;
    let mut sorted = header.clone();
    crate::images::sort_exr_header_attributes(&mut sorted).map_err(failed)?;
    if sorted != header {
        file.write_at(0, &sorted)?;
    }
    file.commit()
}

/// Bytes read back to sort the header in place: an OpenEXR header of this tool's lightmaps
/// (at most 16 bands in colour, 768 channels of about 25 bytes) is far shorter.
const HEADER_READ: u64 = 1 << 20;

/// The OpenEXR bytes of a lightmap; a lightmap that fails [`Lightmap::check`] is an error.
pub fn encode_lightmap(lightmap: &Lightmap) -> std::result::Result<Vec<u8>, String> {
    lightmap.check().map_err(|e| e.to_string())?;
    let writer = TexelChannels::new(lightmap);
    let mut bytes = Cursor::new(Vec::new());
    image_of(lightmap.shape(), &writer)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| one_line(&e.to_string()))?;
    writer.finish().map_err(|e| e.to_string())?;
    let mut bytes = bytes.into_inner();
    crate::images::sort_exr_header_attributes(&mut bytes)?;
    Ok(bytes)
}

/// What a lightmap is without its values: its size, bands and colour channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightmapShape {
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    /// 1 (grey transfer, channel `Y`) or 3 (`R`, `G`, `B`).
    pub channels: u32,
}

impl LightmapShape {
    /// Values a texel holds: every coefficient of every channel.
    pub fn stride(&self) -> usize {
        self.channels as usize * sh::coeff_count(self.bands)
    }

    /// `Ok` for a shape a file can hold: a known band count, 1 or 3 channels, a texel.
    pub fn check(&self) -> Result<()> {
        sh::check_bands(self.bands)?;
        if self.channels != 1 && self.channels != 3 {
            return Err(Error::Options(format!(
                "a lightmap has 1 or 3 channels, not {}",
                self.channels
            )));
        }
        if self.width == 0 || self.height == 0 {
            return Err(Error::Options(format!(
                "a lightmap of {} x {} texels is empty",
                self.width, self.height
            )));
        }
        Ok(())
    }
}

/// A lightmap's texels as its encoder asks for them: whole rows, a block of scan lines at a
/// time, from any thread.
pub trait TexelRows: Sync {
    fn shape(&self) -> LightmapShape;
    /// The values of the texels of image rows `rows`, `[texel row-major][channel][k]` as in
    /// [`Lightmap::coefficients`].
    fn read_rows(&self, rows: Range<usize>) -> Result<Cow<'_, [f32]>>;
}

impl TexelRows for Lightmap<'_> {
    fn shape(&self) -> LightmapShape {
        LightmapShape {
            width: self.width,
            height: self.height,
            bands: self.bands,
            channels: self.channels,
        }
    }

    fn read_rows(&self, rows: Range<usize>) -> Result<Cow<'_, [f32]>> {
        let row = self.width as usize * self.shape().stride();
        Ok(Cow::Borrowed(
            &self.coefficients[rows.start * row..rows.end * row],
        ))
    }
}

/// The one-layer image the encoder writes: the lightmap's channels under its attributes.
fn image_of<'w, 'r>(
    shape: LightmapShape,
    channels: &'w TexelChannels<'r>,
) -> Image<Layer<&'w TexelChannels<'r>>> {
    let size = (shape.width as usize, shape.height as usize);
    Image::from_layer(Layer::new(
        size,
        lightmap_attributes(shape.bands),
        Encoding::SMALL_LOSSLESS,
        channels,
    ))
}

/// The encoder's view of [`TexelRows`]: one half-float channel per coefficient and colour, in
/// name order as OpenEXR stores them, each block's rows read once for all its channels. A
/// failed read or a value out of half's range is kept (the encoder's blocks cannot fail) and
/// reported by [`TexelChannels::finish`].
struct TexelChannels<'r> {
    rows: &'r dyn TexelRows,
    /// `(name, k, c)` of each channel in the file's order.
    names: Vec<(Text, usize, usize)>,
    failure: Mutex<Option<Error>>,
}

impl<'r> TexelChannels<'r> {
    fn new(rows: &'r dyn TexelRows) -> Self {
        let shape = rows.shape();
        let suffixes = channel_suffixes(shape.channels);
        let mut names: Vec<(Text, usize, usize)> = (0..sh::coeff_count(shape.bands))
            .flat_map(|k| {
                suffixes
                    .iter()
                    .enumerate()
                    .map(move |(c, suffix)| (Text::from(channel_name(k, suffix).as_str()), k, c))
            })
            .collect();
        names.sort_unstable_by(|a, b| a.0.cmp(&b.0));
        TexelChannels {
            rows,
            names,
            failure: Mutex::new(None),
        }
    }

    fn finish(&self) -> Result<()> {
        match self.failure.lock().map(|mut failure| failure.take()) {
            Ok(None) => Ok(()),
            Ok(Some(error)) => Err(error),
            Err(_) => Err(Error::Options("a lightmap block's encoder panicked".into())),
        }
    }

    fn fail(&self, error: Error) {
        if let Ok(mut failure) = self.failure.lock() {
            failure.get_or_insert(error);
        }
    }

    /// The rows of `block`, checked: every value a finite half float.
    fn block_rows(&self, block: &BlockIndex) -> Result<Cow<'_, [f32]>> {
        let first = block.pixel_position.y();
        let values = self
            .rows
            .read_rows(first..first + block.pixel_size.height())?;
        let stride = self.rows.shape().stride();
        let texel_of = |i: usize| first * self.rows.shape().width as usize + i / stride;
        match values
            .iter()
            .position(|v| !v.is_finite() || v.abs() > HALF_MAX)
        {
            Some(i) => Err(Error::Options(format!(
                "lightmap value {} (texel {}) is not a finite half float",
                values[i],
                texel_of(i)
            ))),
            None => Ok(values),
        }
    }
}

impl<'w> WritableChannels<'w> for &'w TexelChannels<'_> {
    fn infer_channel_list(&self) -> ChannelList {
        ChannelList::new(
            self.names
                .iter()
                .map(|(name, _, _)| ChannelDescription {
                    name: name.clone(),
                    sample_type: SampleType::F16,
                    quantize_linearly: ChannelDescription::guess_quantization_linearity(name),
                    sampling: Vec2(1, 1),
                })
                .collect(),
        )
    }

    fn infer_level_modes(&self) -> (LevelMode, RoundingMode) {
        (LevelMode::Singular, RoundingMode::Down)
    }

    type Writer = Self;

    fn create_writer(&'w self, _header: &Header) -> Self {
        self
    }
}

impl ChannelsWriter for &TexelChannels<'_> {
    fn extract_uncompressed_block(&self, header: &Header, block: BlockIndex) -> Vec<u8> {
        let values = self.block_rows(&block).unwrap_or_else(|error| {
            self.fail(error);
            Cow::Owned(Vec::new())
        });
        let shape = self.rows.shape();
        let (width, stride) = (shape.width as usize, shape.stride());
        let count = sh::coeff_count(shape.bands);
        let first = block.pixel_position.y();
        UncompressedBlock::collect_block_data_from_lines(&header.channels, block, |line| {
            let (_, k, c) = self.names[line.location.channel];
            let start = (line.location.position.y() - first) * width + line.location.position.x();
            let samples: Vec<f16> = (start..start + line.location.sample_count)
                .map(|texel| {
                    values
                        .get(texel * stride + c * count + k)
                        .map_or(f16::ZERO, |&v| f16::from_f32(v))
                })
                .collect();
            // The line's bytes are sized for exactly its samples, so this cannot fail.
            let _ = line.write_samples_from_slice(&samples);
        })
    }
}

fn lightmap_attributes(bands: u32) -> LayerAttributes {
    let mut attributes = LayerAttributes::default();
    let mut text = |name: &str, value: &str| {
        // Both are ASCII constants, which exr's Latin-1 text always takes.
        if let (Some(name), Some(value)) = (Text::new_or_none(name), Text::new_or_none(value)) {
            attributes.other.insert(name, AttributeValue::Text(value));
        }
    };
    text(CONVENTION_ATTRIBUTE, sh::CONVENTION);
    text(LAYOUT_ATTRIBUTE, LAYOUT);
    if let Some(name) = Text::new_or_none(BANDS_ATTRIBUTE) {
        attributes
            .other
            .insert(name, AttributeValue::I32(bands as i32));
    }
    attributes
}

/// Reads a lightmap written by [`write_lightmap`] (or any OpenEXR file with the same channels:
/// `shKK.R/G/B` or `shKK.Y` for every `k < bands^2`, nothing else). Anything else is a one-line
/// error naming the file.
pub fn read_lightmap(path: &Path) -> Result<Lightmap<'static>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode_lightmap(&bytes).map_err(|message| Error::baked(path, message))
}

/// A lightmap from OpenEXR bytes; the error is a one-line message.
pub fn decode_lightmap(bytes: &[u8]) -> std::result::Result<Lightmap<'static>, String> {
    use exr::prelude::{read, ReadChannels, ReadLayers};
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| format!("OpenEXR: {}", one_line(&e.to_string())))?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let mut named = BTreeMap::new();
    for channel in &layer.channel_data.list {
        named.insert(channel.name.to_string(), &channel.sample_data);
    }
    let (bands, channels) = lightmap_shape(named.keys().map(String::as_str))?;
    if let Some(AttributeValue::I32(said)) =
        Text::new_or_none(BANDS_ATTRIBUTE).and_then(|name| layer.attributes.other.get(&name))
    {
        if *said != bands as i32 {
            return Err(format!(
                "{BANDS_ATTRIBUTE} says {said} bands but the channels hold {bands}"
            ));
        }
    }
    let count = sh::coeff_count(bands);
    let suffixes = channel_suffixes(channels);
    let stride = suffixes.len() * count;
    let mut coefficients = vec![0.0f32; width * height * stride];
    for k in 0..count {
        for (c, suffix) in suffixes.iter().enumerate() {
            let samples = named[&channel_name(k, suffix)];
            for (texel, value) in samples.values_as_f32().enumerate() {
                coefficients[texel * stride + c * count + k] = value;
            }
        }
    }
    Ok(Lightmap {
        width: width as u32,
        height: height as u32,
        bands,
        channels,
        coefficients: Cow::Owned(coefficients),
    })
}

/// The band count and channel count that a set of channel names describes, or why it is not
/// a lightmap's.
fn lightmap_shape<'a>(
    names: impl Iterator<Item = &'a str>,
) -> std::result::Result<(u32, u32), String> {
    let mut suffixes_of: BTreeMap<usize, Vec<&str>> = BTreeMap::new();
    for name in names {
        let parsed = name
            .strip_prefix("sh")
            .and_then(|rest| rest.split_once('.'))
            .filter(|(digits, _)| digits.len() >= 2 && digits.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|(digits, suffix)| Some((digits.parse::<usize>().ok()?, suffix)))
            .filter(|&(k, suffix)| {
                channel_name(k, suffix) == name && ["R", "G", "B", "Y"].contains(&suffix)
            });
        let Some((k, suffix)) = parsed else {
            return Err(format!(
                "not a lightmap: channel {name:?} is not shKK.R, .G, .B or .Y"
            ));
        };
        suffixes_of.entry(k).or_default().push(suffix);
    }
    let count = suffixes_of.len();
    let bands = (count as f64).sqrt().round() as u32;
    if count == 0 || sh::coeff_count(bands) != count || bands > sh::MAX_BANDS {
        return Err(format!(
            "not a lightmap: {count} SH coefficients is not a square number of bands up to {}",
            sh::MAX_BANDS
        ));
    }
    let channels = if suffixes_of[&0] == ["Y"] { 1 } else { 3 };
    let mut expected = channel_suffixes(channels).to_vec();
    expected.sort_unstable();
    for (i, (&k, suffixes)) in suffixes_of.iter_mut().enumerate() {
        suffixes.sort_unstable();
        if k != i || *suffixes != expected {
            return Err(format!(
                "not a lightmap: coefficient {i} should have channels {}",
                expected.join(", ")
            ));
        }
    }
    Ok((bands, channels))
}

#[cfg(test)]
mod tests {

    #[test]
    fn readme_quotes_the_python_reader_verbatim() {
        let readme = include_str!("../README.md");
        assert!(
            readme.contains(PYTHON_READER),
            "README.md's lightmap snippet differs from lightmap::PYTHON_READER"
        );
    }

    use super::*;
    use crate::testing::entries;

    /// A lightmap whose every value is distinct and half-exact (multiples of 1/64 below 32).
    fn sample_lightmap(width: u32, height: u32, bands: u32, channels: u32) -> Lightmap<'static> {
        let n = (width * height * channels) as usize * sh::coeff_count(bands);
        Lightmap {
            width,
            height,
            bands,
            channels,
            coefficients: (0..n).map(|i| (i % 2048) as f32 / 64.0 - 16.0).collect(),
        }
    }

    #[test]
    fn lightmaps_round_trip_exactly_when_half_exact() {
        let dir = tempfile::tempdir().unwrap();
        for (bands, channels) in [(1, 1), (3, 3), (4, 1), (11, 3)] {
            let lightmap = sample_lightmap(7, 5, bands, channels);
            let path = dir.path().join(format!("map{bands}_{channels}.exr"));
            write_lightmap(&path, &lightmap).unwrap();
            assert_eq!(read_lightmap(&path).unwrap(), lightmap);
        }
        assert_eq!(
            entries(dir.path()),
            ["map11_3.exr", "map1_1.exr", "map3_3.exr", "map4_1.exr"]
        );
    }

    #[test]
    fn a_lightmap_encodes_to_the_same_bytes_every_time_with_its_attributes_in_name_order() {
        let lightmap = sample_lightmap(9, 4, 3, 3);
        let first = encode_lightmap(&lightmap).unwrap();
        for _ in 0..16 {
            assert_eq!(encode_lightmap(&lightmap).unwrap(), first);
        }
        let mut names = Vec::new();
        let mut at = 8;
        while first[at] != 0 {
            let name_end = at + crate::images::nul_position(&first[at..]).unwrap();
            let kind_end =
                name_end + 1 + crate::images::nul_position(&first[name_end + 1..]).unwrap();
            let size = u32::from_le_bytes(first[kind_end + 1..kind_end + 5].try_into().unwrap());
            names.push(String::from_utf8(first[at..name_end].to_vec()).unwrap());
            at = kind_end + 5 + size as usize;
        }
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(names, sorted);
        for name in [
            BANDS_ATTRIBUTE,
            CONVENTION_ATTRIBUTE,
            LAYOUT_ATTRIBUTE,
            "channels",
        ] {
            assert!(names.iter().any(|n| n == name), "{name} in {names:?}");
        }
        assert_eq!(decode_lightmap(&first).unwrap(), lightmap);
    }

    /// The exr crate's own encoder of in-memory channels (what this module used before it
    /// streamed blocks), its header sorted as ours is.
    fn encoded_by_exr_from_flat_channels(lightmap: &Lightmap) -> Vec<u8> {
        use exr::prelude::{AnyChannel, AnyChannels, FlatSamples, SmallVec};
        let count = lightmap.coefficient_count();
        let suffixes = channel_suffixes(lightmap.channels);
        let stride = suffixes.len() * count;
        let mut channels = Vec::new();
        for k in 0..count {
            for (c, suffix) in suffixes.iter().enumerate() {
                let samples = lightmap
                    .coefficients
                    .chunks_exact(stride)
                    .map(|texel| f16::from_f32(texel[c * count + k]))
                    .collect();
                channels.push(AnyChannel::new(
                    channel_name(k, suffix).as_str(),
                    FlatSamples::F16(samples),
                ));
            }
        }
        let size = (lightmap.width as usize, lightmap.height as usize);
        let layer = Layer::new(
            size,
            lightmap_attributes(lightmap.bands),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        );
        let mut bytes = Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .to_buffered(&mut bytes)
            .unwrap();
        let mut bytes = bytes.into_inner();
        crate::images::sort_exr_header_attributes(&mut bytes).unwrap();
        bytes
    }

    /// Rows computed on request, a block at a time: the values of [`sample_lightmap`].
    struct ComputedRows(LightmapShape, Option<usize>);

    impl TexelRows for ComputedRows {
        fn shape(&self) -> LightmapShape {
            self.0
        }

        fn read_rows(&self, rows: Range<usize>) -> Result<Cow<'_, [f32]>> {
            let row = self.0.width as usize * self.0.stride();
            Ok(Cow::Owned(
                (rows.start * row..rows.end * row)
                    .map(|i| match self.1 {
                        Some(bad) if bad == i => f32::NAN,
                        _ => (i % 2048) as f32 / 64.0 - 16.0,
                    })
                    .collect(),
            ))
        }
    }

    #[test]
    fn a_lightmap_streamed_a_block_at_a_time_is_the_file_exr_encodes_from_whole_channels() {
        let dir = tempfile::tempdir().unwrap();
        // 37 rows: two whole blocks of 16 scan lines and a short one; 100 coefficients in
        // colour give three-digit channel names, which sort before some two-digit ones.
        for (width, height, bands, channels) in [(9, 37, 3, 3), (5, 3, 1, 1), (4, 17, 11, 3)] {
            let lightmap = sample_lightmap(width, height, bands, channels);
            let expected = encoded_by_exr_from_flat_channels(&lightmap);
            assert_eq!(encode_lightmap(&lightmap).unwrap(), expected);
            let path = dir.path().join("map.exr");
            write_lightmap(&path, &lightmap).unwrap();
            assert_eq!(std::fs::read(&path).unwrap(), expected);
            let computed = ComputedRows(lightmap.shape(), None);
            write_lightmap_rows(&path, &computed).unwrap();
            assert_eq!(std::fs::read(&path).unwrap(), expected);
        }
    }

    #[test]
    fn a_bad_value_met_while_streaming_fails_the_write_and_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.exr");
        let shape = sample_lightmap(6, 40, 2, 3).shape();
        // In the last block: the blocks before it are already written when it is met.
        let bad = 38 * 6 * shape.stride() + 5;
        let error = write_lightmap_rows(&path, &ComputedRows(shape, Some(bad))).unwrap_err();
        let message = error.to_string();
        assert!(
            message.contains(&format!("(texel {}) is not a finite half float", 38 * 6)),
            "{message}"
        );
        assert!(!message.contains('\n'), "{message}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }

    #[test]
    fn values_are_rounded_to_half() {
        let mut lightmap = sample_lightmap(3, 2, 2, 3);
        lightmap.coefficients.to_mut()[5] = 0.1;
        let back = decode_lightmap(&encode_lightmap(&lightmap).unwrap()).unwrap();
        assert!((back.coefficients[5] - 0.1).abs() < 0.1 * 2f32.powi(-11));
        assert_eq!(back.coefficients[6], lightmap.coefficients[6]);
    }

    #[test]
    fn channel_names_are_per_coefficient_layers() {
        assert_eq!(channel_name(0, "R"), "sh00.R");
        assert_eq!(channel_name(8, "Y"), "sh08.Y");
        assert_eq!(channel_name(120, "B"), "sh120.B");
        let names = ["sh00.Y", "sh01.Y", "sh02.Y", "sh03.Y"];
        assert_eq!(lightmap_shape(names.into_iter()), Ok((2, 1)));
    }

    #[test]
    fn bad_lightmaps_are_refused_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.exr");
        let mut cases = Vec::new();
        let good = sample_lightmap(2, 2, 2, 3);
        cases.push(Lightmap {
            channels: 2,
            ..good.clone()
        });
        cases.push(Lightmap {
            bands: 0,
            ..good.clone()
        });
        cases.push(Lightmap {
            width: 3,
            ..good.clone()
        });
        cases.push(Lightmap {
            width: 0,
            height: 0,
            coefficients: Cow::Owned(vec![]),
            ..good.clone()
        });
        for value in [f32::NAN, f32::INFINITY, 1e6] {
            let mut bad = good.clone();
            bad.coefficients.to_mut()[3] = value;
            cases.push(bad);
        }
        for bad in cases {
            let message = write_lightmap(&path, &bad).unwrap_err().to_string();
            assert!(!message.contains('\n'), "{message}");
        }
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn wrong_files_are_one_line_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.exr");
        let mut bad_files: Vec<Vec<u8>> = vec![b"not an exr".to_vec(), Vec::new()];
        let good = encode_lightmap(&sample_lightmap(4, 3, 2, 3)).unwrap();
        bad_files.extend((1..good.len()).step_by(37).map(|n| good[..n].to_vec()));
        // An OpenEXR image that is not a lightmap: plain RGB.
        let rgb = plain_rgb_exr();
        bad_files.push(rgb);
        for bytes in bad_files {
            std::fs::write(&path, &bytes).unwrap();
            let error = read_lightmap(&path).unwrap_err().to_string();
            assert!(!error.contains('\n') && error.contains("x.exr"), "{error}");
        }
        assert!(read_lightmap(&dir.path().join("missing.exr")).is_err());
    }

    fn plain_rgb_exr() -> Vec<u8> {
        use exr::prelude::SpecificChannels;
        let channels = SpecificChannels::rgb(|_| (0.5f32, 0.25f32, 1.0f32));
        let mut bytes = Cursor::new(Vec::new());
        Image::from_channels((4, 4), channels)
            .write()
            .to_buffered(&mut bytes)
            .unwrap();
        bytes.into_inner()
    }

    #[test]
    fn inconsistent_channel_sets_are_not_lightmaps() {
        let shape = |names: &[&str]| lightmap_shape(names.iter().copied());
        assert!(shape(&[]).is_err());
        assert!(shape(&["sh00.R", "sh00.G", "sh00.B", "sh01.R", "sh01.G", "sh01.B"]).is_err());
        assert!(shape(&["sh00.R", "sh00.G"]).is_err());
        assert!(shape(&["sh0.Y"]).is_err());
        assert!(shape(&["sh00.Y", "sh01.Y", "sh02.Y", "sh04.Y"]).is_err());
        assert!(shape(&["sh00.Y", "sh01.Y", "sh02.Y", "sh03.R"]).is_err());
        assert!(shape(&["sh00.Y", "depth"]).is_err());
        assert_eq!(shape(&["sh00.B", "sh00.G", "sh00.R"]), Ok((1, 3)));
    }
}
