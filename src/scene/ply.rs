//! Stanford PLY reader: ascii, binary little- and big-endian (version 1.0), optionally gzipped.
//!
//! Reads `vertex` (x, y, z; nx, ny, nz and red, green, blue when all three of a group are
//! present) and `face` (the `vertex_indices` or `vertex_index` list, fan-triangulated).
//! Everything else is skipped by its declared layout. Indices are not checked against the
//! vertex count here: `prepare` does that for every format alike.

use std::borrow::Cow;
use std::io::Read;
use std::path::Path;

use glam::Vec3;

use super::{Scene, DEFAULT_ALBEDO};
use crate::color::srgb_to_linear;
use crate::error::{Error, Result};

/// Internal result: a one-line message that `parse` attaches to the file name.
type Parsed<T> = std::result::Result<T, String>;

/// Reads a PLY or gzipped PLY file.
pub fn load(path: &Path) -> Result<Scene> {
    load_with_warnings(path).map(|(scene, _)| scene)
}

/// [`load`], also giving a line for what the file holds that its header does not declare
/// (data after the last element), which is not read.
pub fn load_with_warnings(path: &Path) -> Result<(Scene, Vec<String>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_with_warnings(&bytes, path)
}

/// Parses PLY data held in memory (gzip detected by its magic bytes); `path` only names the
/// source in error messages.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Scene> {
    parse_with_warnings(bytes, path).map(|(scene, _)| scene)
}

/// [`parse`] and its warnings, as [`load_with_warnings`] gives them.
pub fn parse_with_warnings(bytes: &[u8], path: &Path) -> Result<(Scene, Vec<String>)> {
    let (scene, trailing) = read_ply(bytes).map_err(|message| Error::mesh(path, message))?;
    let warnings = (trailing > 0)
        .then(|| {
            format!("{trailing} byte(s) after the last element its header declares were not read")
        })
        .into_iter()
        .collect();
    Ok((scene, warnings))
}

/// The scene, and how many bytes of data follow every element the header declares.
fn read_ply(bytes: &[u8]) -> Parsed<(Scene, usize)> {
    let bytes = gunzip_if_compressed(bytes)?;
    let (header, body) = parse_header(&bytes)?;
    let layout = Layout::new(&header)?;
    match header.encoding {
        Encoding::Ascii => read_body(&header, &layout, &mut Ascii { data: body, pos: 0 }),
        Encoding::LittleEndian | Encoding::BigEndian => {
            let big_endian = header.encoding == Encoding::BigEndian;
            let mut source = Binary {
                data: body,
                pos: 0,
                big_endian,
            };
            read_body(&header, &layout, &mut source)
        }
    }
}

fn gunzip_if_compressed(bytes: &[u8]) -> Parsed<Cow<'_, [u8]>> {
    if !bytes.starts_with(&[0x1f, 0x8b]) {
        return Ok(Cow::Borrowed(bytes));
    }
    let mut out = Vec::new();
    // MultiGz: some tools write a gzip file as several concatenated members.
    flate2::read::MultiGzDecoder::new(bytes)
        .read_to_end(&mut out)
        .map_err(|e| format!("invalid gzip data: {e}"))?;
    Ok(Cow::Owned(out))
}

// ---------------------------------------------------------------------------------------------
// Header

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The stored value meaning full intensity when this type holds a colour channel;
    /// `None` for float types, whose colours are already linear in [0, 1].
    fn colour_full_scale(self) -> Option<f64> {
        match self {
            Scalar::I8 => Some(i8::MAX.into()),
            Scalar::U8 => Some(u8::MAX.into()),
            Scalar::I16 => Some(i16::MAX.into()),
            Scalar::U16 => Some(u16::MAX.into()),
            Scalar::I32 => Some(i32::MAX.into()),
            Scalar::U32 => Some(u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => None,
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    /// Fewest bytes one item can occupy, to bound allocations by the data actually present
    /// rather than by a count in the header.
    fn min_item_bytes(&self, encoding: Encoding) -> usize {
        let bytes: usize = self
            .properties
            .iter()
            .map(|p| match (encoding, p.kind) {
                (Encoding::Ascii, _) => 1,
                (_, Kind::Scalar(ty)) => ty.size(),
                (_, Kind::List { count, .. }) => count.size(),
            })
            .sum();
        bytes.max(1)
    }

    /// Bytes per item when every property is a scalar (binary items of fixed size).
    fn fixed_item_bytes(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(ty) => Some(ty.size()),
                Kind::List { .. } => None,
            })
            .sum()
    }
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
}

/// Splits the data into the parsed header and the body that follows `end_header`.
fn parse_header(bytes: &[u8]) -> Parsed<(Header, &[u8])> {
    let (first, mut rest) = split_line(super::skip_bom(bytes)).ok_or("not a PLY file")?;
    if first.trim_ascii() != b"ply" {
        return Err("not a PLY file (it does not start with 'ply')".into());
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let (line, next) = split_line(rest).ok_or("PLY header is truncated (no end_header)")?;
        rest = next;
        let line = std::str::from_utf8(line).map_err(|_| "PLY header is not ASCII text")?;
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => encoding = Some(parse_format(words)?),
            Some("element") => elements.push(parse_element(words, line)?),
            Some("property") => elements
                .last_mut()
                .ok_or("PLY header has a property before any element")?
                .properties
                .push(parse_property(words, line)?),
            Some("end_header") => break,
            Some(_) => return Err(format!("unexpected PLY header line {:?}", line.trim())),
        }
    }
    let encoding = encoding.ok_or("PLY header has no format line")?;
    Ok((Header { encoding, elements }, rest))
}

/// The line before the next '\n' (without it) and the bytes after it.
fn split_line(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    let end = bytes.iter().position(|&b| b == b'\n')?;
    Some((&bytes[..end], &bytes[end + 1..]))
}

fn parse_format<'a>(mut words: impl Iterator<Item = &'a str>) -> Parsed<Encoding> {
    let encoding = match words.next() {
        Some("ascii") => Encoding::Ascii,
        Some("binary_little_endian") => Encoding::LittleEndian,
        Some("binary_big_endian") => Encoding::BigEndian,
        other => {
            return Err(format!(
                "unsupported PLY format {:?}",
                other.unwrap_or_default()
            ))
        }
    };
    match words.next() {
        Some("1.0") | Some("1") => Ok(encoding),
        other => Err(format!(
            "unsupported PLY version {:?} (only 1.0 is supported)",
            other.unwrap_or_default()
        )),
    }
}

fn parse_element<'a>(mut words: impl Iterator<Item = &'a str>, line: &str) -> Parsed<Element> {
    let invalid = || format!("invalid PLY element line {:?}", line.trim());
    let name = words.next().ok_or_else(invalid)?;
    let count = words
        .next()
        .and_then(|c| c.parse().ok())
        .ok_or_else(invalid)?;
    Ok(Element {
        name: name.to_owned(),
        count,
        properties: Vec::new(),
    })
}

fn parse_property<'a>(mut words: impl Iterator<Item = &'a str>, line: &str) -> Parsed<Property> {
    let invalid = || format!("invalid PLY property line {:?}", line.trim());
    let scalar = |word: Option<&str>| -> Parsed<Scalar> {
        let word = word.ok_or_else(invalid)?;
        Scalar::from_name(word).ok_or_else(|| format!("unknown PLY property type {word:?}"))
    };
    let first = words.next();
    let kind = if first == Some("list") {
        let count = scalar(words.next())?;
        let item = scalar(words.next())?;
        Kind::List { count, item }
    } else {
        Kind::Scalar(scalar(first)?)
    };
    let name = words.next().ok_or_else(invalid)?;
    Ok(Property {
        name: name.to_owned(),
        kind,
    })
}

// ---------------------------------------------------------------------------------------------
// What to read from the vertex and face elements

/// Slots of the per-vertex row: position, normal, colour.
const X: usize = 0;
const NX: usize = 3;
const RED: usize = 6;
const SLOTS: usize = 9;

struct Layout {
    /// For each vertex property, the row slot it fills, if it is read.
    vertex_slots: Vec<Option<usize>>,
    has_normals: bool,
    /// Types of red, green, blue, when all three are present.
    colour_types: Option<[Scalar; 3]>,
    /// Index of the face property holding vertex indices.
    face_indices: usize,
}

impl Layout {
    fn new(header: &Header) -> Parsed<Layout> {
        let vertex = find_element(header, "vertex").ok_or("PLY has no vertex element")?;
        let face = find_element(header, "face")
            .filter(|f| f.count > 0)
            .ok_or("PLY has no faces")?;
        let mut vertex_slots = vec![None; vertex.properties.len()];
        for (axis, name) in ["x", "y", "z"].into_iter().enumerate() {
            let (index, _) = find_scalar(vertex, &[name])?
                .ok_or_else(|| format!("PLY vertex element has no '{name}' property"))?;
            vertex_slots[index] = Some(X + axis);
        }
        let normals = find_group(vertex, [&["nx"], &["ny"], &["nz"]])?;
        let colours = find_group(
            vertex,
            [
                &["red", "diffuse_red"],
                &["green", "diffuse_green"],
                &["blue", "diffuse_blue"],
            ],
        )?;
        for (first_slot, group) in [(NX, &normals), (RED, &colours)] {
            for (offset, (index, _)) in group.iter().flatten().enumerate() {
                vertex_slots[*index] = Some(first_slot + offset);
            }
        }
        let face_indices = face
            .properties
            .iter()
            .position(|p| {
                matches!(p.kind, Kind::List { .. })
                    && (p.name == "vertex_indices" || p.name == "vertex_index")
            })
            .ok_or("PLY face element has no vertex_indices list")?;
        Ok(Layout {
            vertex_slots,
            has_normals: normals.is_some(),
            colour_types: colours.map(|group| group.map(|(_, ty)| ty)),
            face_indices,
        })
    }
}

fn find_element<'h>(header: &'h Header, name: &str) -> Option<&'h Element> {
    header.elements.iter().find(|e| e.name == name)
}

/// Index and type of the first scalar property with one of `names`.
fn find_scalar(element: &Element, names: &[&str]) -> Parsed<Option<(usize, Scalar)>> {
    let Some((index, property)) = element
        .properties
        .iter()
        .enumerate()
        .find(|(_, p)| names.contains(&p.name.as_str()))
    else {
        return Ok(None);
    };
    match property.kind {
        Kind::Scalar(ty) => Ok(Some((index, ty))),
        Kind::List { .. } => Err(format!(
            "PLY {} property '{}' is a list, expected a number",
            element.name, property.name
        )),
    }
}

/// Three properties that only mean something together (a normal, a colour): all or none.
fn find_group(element: &Element, names: [&[&str]; 3]) -> Parsed<Option<[(usize, Scalar); 3]>> {
    let [a, b, c] = names;
    Ok(
        match (
            find_scalar(element, a)?,
            find_scalar(element, b)?,
            find_scalar(element, c)?,
        ) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        },
    )
}

// ---------------------------------------------------------------------------------------------
// Body

/// A stream of PLY values in one encoding.
trait Source {
    /// The next value of type `ty`; every PLY type widens exactly to f64.
    fn value(&mut self, ty: Scalar) -> Parsed<f64>;
    /// Skips `n` values of type `ty`.
    fn skip(&mut self, ty: Scalar, n: usize) -> Parsed<()>;
    /// Skips `values` values taking `bytes` bytes in binary (whichever the encoding needs).
    fn skip_fixed(&mut self, bytes: usize, values: usize) -> Parsed<()>;
    /// Bytes not yet read.
    fn remaining(&self) -> usize;
    /// Bytes not yet read that hold data (in ascii, white space is not data).
    fn unread(&self) -> usize;
}

const TRUNCATED: &str = "truncated data";

struct Ascii<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Ascii<'a> {
    fn token(&mut self) -> Parsed<&'a str> {
        let data = self.data;
        let start = self.pos
            + data[self.pos..]
                .iter()
                .position(|b| !b.is_ascii_whitespace())
                .ok_or(TRUNCATED)?;
        let end = start
            + data[start..]
                .iter()
                .position(u8::is_ascii_whitespace)
                .unwrap_or(data.len() - start);
        self.pos = end;
        std::str::from_utf8(&data[start..end]).map_err(|_| "non-ASCII bytes in PLY data".into())
    }
}

impl Source for Ascii<'_> {
    fn value(&mut self, ty: Scalar) -> Parsed<f64> {
        let token = self.token()?;
        // Parsing f32 as f32 (not via f64) gives the same rounding as a binary file would.
        let value = match ty {
            Scalar::F32 => token.parse::<f32>().ok().map(f64::from),
            Scalar::F64 => token.parse::<f64>().ok(),
            _ => token.parse::<i64>().ok().map(|v| v as f64),
        };
        value.ok_or_else(|| format!("invalid number {token:?}"))
    }

    fn skip(&mut self, _ty: Scalar, n: usize) -> Parsed<()> {
        self.skip_fixed(0, n)
    }

    fn skip_fixed(&mut self, _bytes: usize, values: usize) -> Parsed<()> {
        for _ in 0..values {
            self.token()?;
        }
        Ok(())
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    fn unread(&self) -> usize {
        self.data[self.pos..].trim_ascii().len()
    }
}

struct Binary<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl<'a> Binary<'a> {
    fn take(&mut self, n: usize) -> Parsed<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&end| end <= self.data.len())
            .ok_or(TRUNCATED)?;
        let bytes = &self.data[self.pos..end];
        self.pos = end;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self) -> Parsed<[u8; N]> {
        let mut out = [0; N];
        out.copy_from_slice(self.take(N)?);
        Ok(out)
    }
}

macro_rules! decode {
    ($source:expr, $ty:ty) => {{
        let bytes = $source.array()?;
        f64::from(if $source.big_endian {
            <$ty>::from_be_bytes(bytes)
        } else {
            <$ty>::from_le_bytes(bytes)
        })
    }};
}

impl Source for Binary<'_> {
    fn value(&mut self, ty: Scalar) -> Parsed<f64> {
        Ok(match ty {
            Scalar::I8 => decode!(self, i8),
            Scalar::U8 => decode!(self, u8),
            Scalar::I16 => decode!(self, i16),
            Scalar::U16 => decode!(self, u16),
            Scalar::I32 => decode!(self, i32),
            Scalar::U32 => decode!(self, u32),
            Scalar::F32 => decode!(self, f32),
            Scalar::F64 => decode!(self, f64),
        })
    }

    fn skip(&mut self, ty: Scalar, n: usize) -> Parsed<()> {
        let bytes = ty.size().checked_mul(n).ok_or(TRUNCATED)?;
        self.skip_fixed(bytes, n)
    }

    fn skip_fixed(&mut self, bytes: usize, _values: usize) -> Parsed<()> {
        self.take(bytes).map(|_| ())
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    fn unread(&self) -> usize {
        self.remaining()
    }
}

#[derive(Default)]
struct Vertices {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    colours: Vec<[f64; 3]>,
}

fn read_body(header: &Header, layout: &Layout, source: &mut impl Source) -> Parsed<(Scene, usize)> {
    let mut vertices = None;
    let mut triangles = None;
    let mut read = 0;
    for element in &header.elements {
        if vertices.is_some() && triangles.is_some() {
            break;
        }
        read += 1;
        let budget = source.remaining() / element.min_item_bytes(header.encoding);
        let capacity = element.count.min(budget);
        match element.name.as_str() {
            "vertex" if vertices.is_none() => {
                vertices = Some(read_vertices(element, layout, source, capacity)?);
            }
            "face" if triangles.is_none() => {
                triangles = Some(read_faces(element, layout, source, capacity)?);
            }
            _ => skip_element(element, source)?,
        }
    }
    // Layout::new has checked that both elements exist, so both have been read.
    let (vertices, triangles) = vertices.zip(triangles).ok_or(TRUNCATED)?;
    // Elements after the two we need cannot change the mesh: damage confined to them is no
    // reason to refuse it, and data past them is only worth a warning.
    let rest_skipped = header.elements[read..]
        .iter()
        .all(|element| skip_element(element, source).is_ok());
    let trailing = if rest_skipped { source.unread() } else { 0 };
    Ok((build_scene(vertices, triangles, layout), trailing))
}

fn build_scene(vertices: Vertices, triangles: Vec<[u32; 3]>, layout: &Layout) -> Scene {
    let albedo = match layout.colour_types {
        Some(types) => vertices
            .colours
            .iter()
            .map(|c| colour_to_albedo(*c, types))
            .collect(),
        None => vec![DEFAULT_ALBEDO; vertices.positions.len()],
    };
    Scene {
        normals: layout.has_normals.then_some(vertices.normals),
        albedo,
        positions: vertices.positions,
        triangles,
    }
}

/// Integer colours are sRGB-encoded fractions of the type's maximum; float colours are
/// taken as linear. Out-of-range values are clamped (a NaN stays NaN for `prepare` to reject).
fn colour_to_albedo(colour: [f64; 3], types: [Scalar; 3]) -> Vec3 {
    let channel = |value: f64, ty: Scalar| {
        let linear = match ty.colour_full_scale() {
            Some(full) => srgb_to_linear((value / full).clamp(0.0, 1.0)),
            None => value,
        };
        linear.clamp(0.0, 1.0) as f32
    };
    Vec3::new(
        channel(colour[0], types[0]),
        channel(colour[1], types[1]),
        channel(colour[2], types[2]),
    )
}

/// Runs `read_item` for each item of `element`, adding where it failed to any error.
fn for_each_item(element: &Element, mut read_item: impl FnMut(usize) -> Parsed<()>) -> Parsed<()> {
    for i in 0..element.count {
        read_item(i).map_err(|message| {
            format!(
                "{message} in element '{}' (item {i} of {})",
                element.name, element.count
            )
        })?;
    }
    Ok(())
}

fn read_vertices(
    element: &Element,
    layout: &Layout,
    source: &mut impl Source,
    capacity: usize,
) -> Parsed<Vertices> {
    let mut out = Vertices {
        positions: Vec::with_capacity(capacity),
        ..Vertices::default()
    };
    let mut row = [0.0f64; SLOTS];
    for_each_item(element, |_| {
        for (property, slot) in element.properties.iter().zip(&layout.vertex_slots) {
            match (property.kind, slot) {
                (Kind::Scalar(ty), Some(slot)) => row[*slot] = source.value(ty)?,
                (Kind::Scalar(ty), None) => source.skip(ty, 1)?,
                (Kind::List { count, item }, _) => skip_list(source, count, item)?,
            }
        }
        let vec3 = |first: usize| {
            Vec3::new(
                row[first] as f32,
                row[first + 1] as f32,
                row[first + 2] as f32,
            )
        };
        out.positions.push(vec3(X));
        if layout.has_normals {
            out.normals.push(vec3(NX));
        }
        if layout.colour_types.is_some() {
            out.colours.push([row[RED], row[RED + 1], row[RED + 2]]);
        }
        Ok(())
    })?;
    Ok(out)
}

fn read_faces(
    element: &Element,
    layout: &Layout,
    source: &mut impl Source,
    capacity: usize,
) -> Parsed<Vec<[u32; 3]>> {
    let mut triangles = Vec::with_capacity(capacity);
    let mut corners: Vec<u32> = Vec::new();
    for_each_item(element, |_| {
        for (index, property) in element.properties.iter().enumerate() {
            match property.kind {
                Kind::List { count, item } if index == layout.face_indices => {
                    read_polygon(source, count, item, &mut corners)?;
                    // Fan triangulation: exact for the convex polygons scanners and modelling
                    // tools write.
                    triangles.extend(
                        corners
                            .windows(2)
                            .skip(1)
                            .map(|pair| [corners[0], pair[0], pair[1]]),
                    );
                }
                Kind::List { count, item } => skip_list(source, count, item)?,
                Kind::Scalar(ty) => source.skip(ty, 1)?,
            }
        }
        Ok(())
    })?;
    Ok(triangles)
}

fn read_polygon(
    source: &mut impl Source,
    count: Scalar,
    item: Scalar,
    corners: &mut Vec<u32>,
) -> Parsed<()> {
    let n = list_length(source.value(count)?)?;
    if n < 3 {
        return Err(format!("face with {n} vertices (at least 3 needed)"));
    }
    corners.clear();
    for _ in 0..n {
        corners.push(vertex_index(source.value(item)?)?);
    }
    Ok(())
}

fn skip_list(source: &mut impl Source, count: Scalar, item: Scalar) -> Parsed<()> {
    let n = list_length(source.value(count)?)?;
    source.skip(item, n)
}

fn skip_element(element: &Element, source: &mut impl Source) -> Parsed<()> {
    if let Some(item_bytes) = element.fixed_item_bytes() {
        let values = element.properties.len().checked_mul(element.count);
        let bytes = item_bytes.checked_mul(element.count);
        return match values.zip(bytes) {
            Some((values, bytes)) => source.skip_fixed(bytes, values),
            None => Err(TRUNCATED.into()),
        }
        .map_err(|message| format!("{message} in element '{}'", element.name));
    }
    for_each_item(element, |_| {
        for property in &element.properties {
            match property.kind {
                Kind::Scalar(ty) => source.skip(ty, 1)?,
                Kind::List { count, item } => skip_list(source, count, item)?,
            }
        }
        Ok(())
    })
}

fn list_length(value: f64) -> Parsed<usize> {
    if value >= 0.0 && value.fract() == 0.0 {
        // Saturates for absurd lengths, which then fail as truncated data.
        Ok(value as usize)
    } else {
        Err(format!("invalid list length {value}"))
    }
}

fn vertex_index(value: f64) -> Parsed<u32> {
    if value < 0.0 {
        Err(format!("negative vertex index {value}"))
    } else if value.fract() != 0.0 || value > f64::from(u32::MAX) {
        Err(format!("invalid vertex index {value}"))
    } else {
        Ok(value as u32)
    }
}

#[cfg(test)]
mod tests {
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
            let mut encoder =
                flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
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
}
