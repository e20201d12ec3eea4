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
mod tests;
