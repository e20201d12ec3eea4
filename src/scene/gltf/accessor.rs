//! glTF accessors read as the specification allows them: every component type, normalized or
//! not (KHR_mesh_quantization), interleaved views (`byteStride`), sparse substitution, and no
//! view at all (zeros). Every offset comes from the file, so every range is checked against
//! the buffer before it is read: a damaged file is an error, never a panic.

use gltf_json::accessor::{ComponentType, Type};
use gltf_json::validation::Checked;
use gltf_json::Root;

/// An accessor's elements, densely packed: `count` elements of `components` components.
#[derive(Clone, Debug, PartialEq)]
pub struct Dense {
    pub count: usize,
    pub components: usize,
    pub component: ComponentType,
    pub normalized: bool,
    /// `count * components * component size` little-endian bytes.
    pub bytes: Vec<u8>,
}

pub fn component_size(component: ComponentType) -> usize {
    match component {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn component_count(kind: Type) -> usize {
    match kind {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// Accessor `index` of `root`, read from `buffers` (one byte vector per buffer).
pub fn dense(root: &Root, buffers: &[Vec<u8>], index: usize) -> Result<Dense, String> {
    let accessor = root
        .accessors
        .get(index)
        .ok_or_else(|| format!("accessor {index} does not exist"))?;
    let (Checked::Valid(component), Checked::Valid(kind)) =
        (&accessor.component_type, &accessor.type_)
    else {
        return Err(format!("accessor {index} has an invalid type"));
    };
    let component = component.0;
    let components = component_count(*kind);
    let size = component_size(component);
    if size < 4 && matches!(kind, Type::Mat2 | Type::Mat3) {
        // Columns of these are padded to 4 bytes; no vertex attribute uses them.
        return Err(format!(
            "accessor {index}: {kind:?} of {size}-byte components is not supported"
        ));
    }
    let element = components * size;
    let count = accessor.count.0 as usize;
    let total = count
        .checked_mul(element)
        .ok_or_else(|| format!("accessor {index}: {count} elements overflow"))?;
    let mut bytes = match accessor.buffer_view {
        Some(view) => {
            let offset = accessor.byte_offset.map_or(0, |o| o.0 as usize);
            strided(root, buffers, view.value(), offset, count, element)
                .map_err(|e| format!("accessor {index}: {e}"))?
        }
        None => {
            // Zeros (for sparse values to land on) justified by nothing read: no more than the
            // file's buffers hold, so a count near 2^32 is an error and not an abort.
            let held: usize = buffers.iter().map(Vec::len).sum();
            if total > held.max(UNBACKED_FLOOR) {
                return Err(format!(
                    "accessor {index}: {count} elements with no buffer view would take {total} \
                     bytes, more than the file's buffers hold ({held})"
                ));
            }
            vec![0; total]
        }
    };
    if let Some(sparse) = &accessor.sparse {
        substitute(root, buffers, sparse, &mut bytes, element)
            .map_err(|e| format!("accessor {index}: sparse: {e}"))?;
    }
    Ok(Dense {
        count,
        components,
        component,
        normalized: accessor.normalized,
        bytes,
    })
}

/// The most bytes of zeros an accessor without a buffer view may take when the file's buffers
/// hold less.
const UNBACKED_FLOOR: usize = 1 << 20;

/// `count` elements of `element` bytes starting `offset` bytes into view `view`, at the
/// view's stride (or packed), copied out densely.
fn strided(
    root: &Root,
    buffers: &[Vec<u8>],
    view: usize,
    offset: usize,
    count: usize,
    element: usize,
) -> Result<Vec<u8>, String> {
    let data = view_bytes(root, buffers, view)?;
    let stride = root.buffer_views[view].byte_stride.map_or(element, |s| s.0);
    if stride < element {
        return Err(format!(
            "stride {stride} is less than an element ({element} bytes)"
        ));
    }
    // The last element must lie inside the view before anything is reserved: a count read
    // from the file is not a size to allocate.
    if let Some(last) = count.checked_sub(1) {
        let end = last
            .checked_mul(stride)
            .and_then(|s| s.checked_add(offset))
            .and_then(|s| s.checked_add(element));
        if end.is_none_or(|end| end > data.len()) {
            return Err(format!(
                "{count} elements of {element} bytes run past the end of buffer view {view} \
                 ({} bytes)",
                data.len()
            ));
        }
    }
    let mut bytes = Vec::with_capacity(count * element);
    for i in 0..count {
        let start = i
            .checked_mul(stride)
            .and_then(|s| s.checked_add(offset))
            .ok_or("offset overflows")?;
        let item = data
            .get(start..start + element)
            .ok_or_else(|| format!("element {i} lies past the end of buffer view {view}"))?;
        bytes.extend_from_slice(item);
    }
    Ok(bytes)
}

/// The bytes of buffer view `view`, checked to lie inside its buffer.
pub fn view_bytes<'b>(
    root: &Root,
    buffers: &'b [Vec<u8>],
    view: usize,
) -> Result<&'b [u8], String> {
    let v = root
        .buffer_views
        .get(view)
        .ok_or_else(|| format!("buffer view {view} does not exist"))?;
    let buffer = buffers
        .get(v.buffer.value())
        .ok_or_else(|| format!("buffer view {view} refers to a missing buffer"))?;
    let start = v.byte_offset.map_or(0, |o| o.0 as usize);
    let end = start.checked_add(v.byte_length.0 as usize);
    end.and_then(|end| buffer.get(start..end))
        .ok_or_else(|| format!("buffer view {view} runs past the end of its buffer"))
}

/// Writes the sparse values over the elements the sparse indices name.
fn substitute(
    root: &Root,
    buffers: &[Vec<u8>],
    sparse: &gltf_json::accessor::sparse::Sparse,
    bytes: &mut [u8],
    element: usize,
) -> Result<(), String> {
    let count = sparse.count.0 as usize;
    let Checked::Valid(index_type) = sparse.indices.component_type else {
        return Err("invalid index type".into());
    };
    let index_size = component_size(index_type.0);
    let indices = view_bytes(root, buffers, sparse.indices.buffer_view.value())?;
    let values = view_bytes(root, buffers, sparse.values.buffer_view.value())?;
    let index_at = sparse.indices.byte_offset.0 as usize;
    let value_at = sparse.values.byte_offset.0 as usize;
    let elements = bytes.len() / element.max(1);
    for i in 0..count {
        let raw = indices
            .get(index_at + i * index_size..index_at + (i + 1) * index_size)
            .ok_or("indices run past their buffer view")?;
        let target = unsigned(raw) as usize;
        if target >= elements {
            return Err(format!("index {target} is past the {elements} elements"));
        }
        let value = values
            .get(value_at + i * element..value_at + (i + 1) * element)
            .ok_or("values run past their buffer view")?;
        bytes[target * element..(target + 1) * element].copy_from_slice(value);
    }
    Ok(())
}

/// A little-endian unsigned integer of 1, 2 or 4 bytes.
fn unsigned(raw: &[u8]) -> u32 {
    raw.iter()
        .rev()
        .fold(0u32, |value, &byte| (value << 8) | u32::from(byte))
}

impl Dense {
    /// Every component as f32: floats as they are, normalized integers mapped to [0, 1] or
    /// [-1, 1] as the specification says, other integers as their value.
    pub fn floats(&self) -> Vec<f32> {
        let size = component_size(self.component);
        self.bytes
            .chunks_exact(size)
            .map(|raw| {
                let value = match self.component {
                    ComponentType::F32 => f32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]),
                    ComponentType::I8 => raw[0] as i8 as f32,
                    ComponentType::I16 => i16::from_le_bytes([raw[0], raw[1]]) as f32,
                    ComponentType::U8 | ComponentType::U16 | ComponentType::U32 => {
                        unsigned(raw) as f32
                    }
                };
                if self.normalized {
                    normalize(value, self.component)
                } else {
                    value
                }
            })
            .collect()
    }

    /// The elements as vectors of `N` components; an error unless the accessor has `N`.
    pub fn vectors<const N: usize>(&self, what: &str) -> Result<Vec<[f32; N]>, String> {
        if self.components != N {
            return Err(format!(
                "{what} has {} components per element, expected {N}",
                self.components
            ));
        }
        Ok(self
            .floats()
            .chunks_exact(N)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect())
    }

    /// The elements as vertex indices: unsigned integer scalars only.
    pub fn indices(&self) -> Result<Vec<u32>, String> {
        let unsigned_type = matches!(
            self.component,
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32
        );
        if self.components != 1 || !unsigned_type || self.normalized {
            return Err("indices must be unsigned integer scalars".into());
        }
        let size = component_size(self.component);
        Ok(self.bytes.chunks_exact(size).map(unsigned).collect())
    }
}

/// A normalized integer's value (glTF 2.0, "Animation" and KHR_mesh_quantization: signed
/// values are max(c / MAX, -1)).
fn normalize(value: f32, component: ComponentType) -> f32 {
    match component {
        ComponentType::I8 => (value / 127.0).max(-1.0),
        ComponentType::U8 => value / 255.0,
        ComponentType::I16 => (value / 32767.0).max(-1.0),
        ComponentType::U16 => value / 65535.0,
        ComponentType::U32 => value / u32::MAX as f32,
        ComponentType::F32 => value,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root(accessors: serde_json::Value, views: serde_json::Value) -> Root {
        serde_json::from_value(serde_json::json!({
            "asset": { "version": "2.0" },
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{ "byteLength": 64 }],
        }))
        .unwrap()
    }

    #[test]
    fn normalized_integers_map_as_the_specification_says() {
        let bytes = vec![vec![0, 127, 129, 255, 0, 128, 255, 255]];
        let views = serde_json::json!([{ "buffer": 0, "byteLength": 8 }]);
        let accessors = serde_json::json!([
            { "bufferView": 0, "componentType": 5120, "normalized": true, "count": 4, "type": "SCALAR" },
            { "bufferView": 0, "componentType": 5121, "normalized": true, "count": 4, "type": "SCALAR" },
            { "bufferView": 0, "componentType": 5123, "normalized": true, "count": 4, "type": "SCALAR" },
            { "bufferView": 0, "componentType": 5123, "count": 4, "type": "SCALAR" },
        ]);
        let root = root(accessors, views);
        let floats = |i| dense(&root, &bytes, i).unwrap().floats();
        // i8: 0, 127, -127, -1 -> 0, 1, -1, -1/127 (and -128 would clamp to -1).
        assert_eq!(floats(0), [0.0, 1.0, -1.0, -1.0 / 127.0]);
        assert_eq!(floats(1), [0.0, 127.0 / 255.0, 129.0 / 255.0, 1.0]);
        assert_eq!(
            floats(2),
            [32512.0 / 65535.0, 65409.0 / 65535.0, 32768.0 / 65535.0, 1.0]
        );
        assert_eq!(floats(3), [32512.0, 65409.0, 32768.0, 65535.0]);
        assert_eq!(
            dense(&root, &bytes, 3).unwrap().indices().unwrap(),
            [32512, 65409, 32768, 65535]
        );
        assert!(dense(&root, &bytes, 0).unwrap().indices().is_err());
    }

    #[test]
    fn strided_elements_are_gathered_and_overruns_refused() {
        // Two f32 VEC2 elements 12 bytes apart, after a 4-byte offset.
        let values: Vec<u8> = [9.0f32, 1.0, 2.0, 9.0, 3.0, 4.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let bytes = vec![[vec![0; 4], values].concat()];
        let views = serde_json::json!([{ "buffer": 0, "byteOffset": 4, "byteLength": 24, "byteStride": 12 }]);
        let accessors = serde_json::json!([
            { "bufferView": 0, "byteOffset": 4, "componentType": 5126, "count": 2, "type": "VEC2" },
            { "bufferView": 0, "byteOffset": 4, "componentType": 5126, "count": 3, "type": "VEC2" },
            { "bufferView": 7, "componentType": 5126, "count": 1, "type": "VEC2" },
        ]);
        let root = root(accessors, views);
        assert_eq!(
            dense(&root, &bytes, 0).unwrap().vectors::<2>("uv").unwrap(),
            [[1.0, 2.0], [3.0, 4.0]]
        );
        let overrun = dense(&root, &bytes, 1).unwrap_err();
        assert!(overrun.contains("past the end"), "{overrun}");
        assert!(dense(&root, &bytes, 2)
            .unwrap_err()
            .contains("does not exist"));
        assert!(dense(&root, &bytes, 9).is_err());
        assert!(dense(&root, &bytes, 0).unwrap().vectors::<3>("uv").is_err());
    }

    /// A count near 2^32 is refused before anything is reserved (it once aborted the process
    /// with a 48 GB allocation): with a buffer view too short for it, and with none at all.
    #[test]
    fn a_huge_count_is_an_error_not_an_allocation() {
        let bytes = vec![vec![0u8; 64]];
        let views = serde_json::json!([{ "buffer": 0, "byteLength": 64 }]);
        let accessors = serde_json::json!([
            { "bufferView": 0, "componentType": 5126, "count": 4294967295u32, "type": "VEC3" },
            { "componentType": 5126, "count": 4294967295u32, "type": "VEC3" },
        ]);
        let root = root(accessors, views);
        let short = dense(&root, &bytes, 0).unwrap_err();
        assert!(short.contains("past the end of buffer view 0"), "{short}");
        let unbacked = dense(&root, &bytes, 1).unwrap_err();
        assert!(unbacked.contains("no buffer view"), "{unbacked}");
    }
}
