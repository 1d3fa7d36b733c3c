//! Accessor decoding: buffer views, strides, sparse substitution, normalized and integer
//! components (KHR_mesh_quantization) to `f32`, and index lists. Every count, offset and
//! stride is checked against its buffer view and buffer *before* anything is allocated.

use super::document::{get_usize, GltfDocument};
use serde_json::Value;
use springbake_core::plugin::PluginError;

/// Component types of the spec.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ComponentType {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl ComponentType {
    fn from_code(code: u64) -> Option<Self> {
        Some(match code {
            5120 => Self::I8,
            5121 => Self::U8,
            5122 => Self::I16,
            5123 => Self::U16,
            5125 => Self::U32,
            5126 => Self::F32,
            _ => return None,
        })
    }

    pub fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::U32 | Self::F32 => 4,
        }
    }

    /// Read one component at `at` (bounds were checked by the caller).
    fn read(self, b: &[u8], at: usize, normalized: bool) -> f32 {
        match self {
            Self::I8 => {
                let v = b[at] as i8 as f32;
                if normalized {
                    (v / 127.0).max(-1.0)
                } else {
                    v
                }
            }
            Self::U8 => {
                let v = b[at] as f32;
                if normalized {
                    v / 255.0
                } else {
                    v
                }
            }
            Self::I16 => {
                let v = i16::from_le_bytes([b[at], b[at + 1]]) as f32;
                if normalized {
                    (v / 32767.0).max(-1.0)
                } else {
                    v
                }
            }
            Self::U16 => {
                let v = u16::from_le_bytes([b[at], b[at + 1]]) as f32;
                if normalized {
                    v / 65535.0
                } else {
                    v
                }
            }
            Self::U32 => u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as f32,
            Self::F32 => f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]),
        }
    }

    fn read_u32(self, b: &[u8], at: usize) -> u32 {
        match self {
            Self::I8 | Self::U8 => b[at] as u32,
            Self::I16 | Self::U16 => u16::from_le_bytes([b[at], b[at + 1]]) as u32,
            Self::U32 | Self::F32 => u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]),
        }
    }
}

/// Number of components of an accessor `type`.
fn components(kind: &str) -> Option<usize> {
    Some(match kind {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// Accessors without a buffer view (all zeros, possibly sparse) are capped at this many
/// elements: nothing bounds their count otherwise.
const MAX_UNBACKED_ELEMENTS: usize = 1 << 24;

/// The parsed header of an accessor.
struct Header<'a> {
    location: String,
    json: &'a Value,
    component: ComponentType,
    normalized: bool,
    comps: usize,
    count: usize,
}

fn header<'a>(
    doc: &'a GltfDocument,
    index: usize,
    referrer: &str,
) -> Result<Header<'a>, PluginError> {
    let json = doc.get("accessors", index, referrer)?;
    let location = format!("accessors[{index}]");
    let component = json
        .get("componentType")
        .and_then(Value::as_u64)
        .and_then(ComponentType::from_code)
        .ok_or_else(|| {
            doc.error(
                &location,
                "componentType is missing or not a glTF component type",
            )
        })?;
    let comps = json
        .get("type")
        .and_then(Value::as_str)
        .and_then(components)
        .ok_or_else(|| doc.error(&location, "type is missing or unknown"))?;
    let count = get_usize(json, "count")
        .filter(|&c| c >= 1)
        .ok_or_else(|| doc.error(&location, "count is missing or not a positive integer"))?;
    let normalized = json
        .get("normalized")
        .and_then(Value::as_bool)
        .unwrap_or(false);
    Ok(Header {
        location,
        json,
        component,
        normalized,
        comps,
        count,
    })
}

/// The bytes of buffer view `view` and its stride, after checking it fits its buffer.
fn view_bytes<'a>(
    doc: &'a GltfDocument,
    view: usize,
    referrer: &str,
) -> Result<(&'a [u8], Option<usize>), PluginError> {
    let json = doc.get("bufferViews", view, referrer)?;
    let location = format!("bufferViews[{view}]");
    if json.get("extensions").is_some_and(|e| {
        e.get("EXT_meshopt_compression").is_some() || e.get("KHR_meshopt_compression").is_some()
    }) {
        return Err(doc.error(
            &location,
            "meshopt-compressed buffer views are not supported",
        ));
    }
    let buffer =
        get_usize(json, "buffer").ok_or_else(|| doc.error(&location, "buffer is missing"))?;
    let data = doc.buffers.get(buffer).ok_or_else(|| {
        doc.error(
            &location,
            format!("refers to buffers[{buffer}], which does not exist"),
        )
    })?;
    let offset = get_usize(json, "byteOffset").unwrap_or(0);
    let length = get_usize(json, "byteLength")
        .ok_or_else(|| doc.error(&location, "byteLength is missing"))?;
    let end = offset
        .checked_add(length)
        .filter(|&e| e <= data.len())
        .ok_or_else(|| {
            doc.error(
                &location,
                format!(
                    "byteOffset {offset} + byteLength {length} runs past buffers[{buffer}] ({} bytes)",
                    data.len()
                ),
            )
        })?;
    let stride = get_usize(json, "byteStride").filter(|&s| s > 0);
    Ok((&data[offset..end], stride))
}

/// Check that `count` elements of `elem` bytes at `offset` with `stride` fit in `len` bytes.
fn check_fits(
    doc: &GltfDocument,
    location: &str,
    len: usize,
    offset: usize,
    stride: usize,
    elem: usize,
    count: usize,
) -> Result<(), PluginError> {
    let needed = (count as u64 - 1)
        .checked_mul(stride as u64)
        .and_then(|n| n.checked_add(offset as u64))
        .and_then(|n| n.checked_add(elem as u64));
    match needed {
        Some(n) if n <= len as u64 => Ok(()),
        _ => Err(doc.error(
            location,
            format!(
                "{count} elements of {elem} bytes (stride {stride}, byteOffset {offset}) do not fit \
                 in the {len} bytes of its buffer view"
            ),
        )),
    }
}

/// Decode accessor `index` to `count × comps` floats (normalized integers mapped to [0,1] or
/// [-1,1], other integers converted), sparse substitution applied.
pub fn read_floats(
    doc: &GltfDocument,
    index: usize,
    referrer: &str,
) -> Result<(Vec<f32>, usize), PluginError> {
    let h = header(doc, index, referrer)?;
    let elem = h.comps * h.component.size();
    let mut out;
    if let Some(view) = get_usize(h.json, "bufferView") {
        let (bytes, stride) = view_bytes(doc, view, &h.location)?;
        let stride = stride.unwrap_or(elem);
        if stride < elem {
            return Err(doc.error(
                &h.location,
                format!("byteStride {stride} is smaller than one element ({elem} bytes)"),
            ));
        }
        let offset = get_usize(h.json, "byteOffset").unwrap_or(0);
        check_fits(doc, &h.location, bytes.len(), offset, stride, elem, h.count)?;
        out = Vec::with_capacity(h.count * h.comps);
        for i in 0..h.count {
            let base = offset + i * stride;
            for c in 0..h.comps {
                out.push(
                    h.component
                        .read(bytes, base + c * h.component.size(), h.normalized),
                );
            }
        }
    } else {
        if h.count > MAX_UNBACKED_ELEMENTS {
            return Err(doc.error(
                &h.location,
                format!(
                    "count {} without a bufferView is beyond the supported {MAX_UNBACKED_ELEMENTS}",
                    h.count
                ),
            ));
        }
        out = vec![0.0; h.count * h.comps];
    }
    if let Some(sparse) = h.json.get("sparse") {
        apply_sparse(doc, &h, sparse, &mut out)?;
    }
    Ok((out, h.comps))
}

fn apply_sparse(
    doc: &GltfDocument,
    h: &Header<'_>,
    sparse: &Value,
    out: &mut [f32],
) -> Result<(), PluginError> {
    let location = format!("{}.sparse", h.location);
    let count = get_usize(sparse, "count")
        .filter(|&c| c >= 1 && c <= h.count)
        .ok_or_else(|| {
            doc.error(
                &location,
                "count is missing or larger than the accessor's count",
            )
        })?;
    let indices = sparse
        .get("indices")
        .ok_or_else(|| doc.error(&location, "indices are missing"))?;
    let values = sparse
        .get("values")
        .ok_or_else(|| doc.error(&location, "values are missing"))?;
    let ilocation = format!("{location}.indices");
    let icomp = indices
        .get("componentType")
        .and_then(Value::as_u64)
        .and_then(ComponentType::from_code)
        .filter(|c| {
            matches!(
                c,
                ComponentType::U8 | ComponentType::U16 | ComponentType::U32
            )
        })
        .ok_or_else(|| {
            doc.error(
                &ilocation,
                "componentType must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
            )
        })?;
    let iview = get_usize(indices, "bufferView")
        .ok_or_else(|| doc.error(&ilocation, "bufferView is missing"))?;
    let (ibytes, _) = view_bytes(doc, iview, &ilocation)?;
    let ioffset = get_usize(indices, "byteOffset").unwrap_or(0);
    check_fits(
        doc,
        &ilocation,
        ibytes.len(),
        ioffset,
        icomp.size(),
        icomp.size(),
        count,
    )?;
    let vlocation = format!("{location}.values");
    let vview = get_usize(values, "bufferView")
        .ok_or_else(|| doc.error(&vlocation, "bufferView is missing"))?;
    let (vbytes, _) = view_bytes(doc, vview, &vlocation)?;
    let voffset = get_usize(values, "byteOffset").unwrap_or(0);
    let elem = h.comps * h.component.size();
    check_fits(doc, &vlocation, vbytes.len(), voffset, elem, elem, count)?;
    for k in 0..count {
        let target = icomp.read_u32(ibytes, ioffset + k * icomp.size()) as usize;
        if target >= h.count {
            return Err(doc.error(
                &ilocation,
                format!(
                    "sparse index {target} is beyond the accessor's count {}",
                    h.count
                ),
            ));
        }
        for c in 0..h.comps {
            out[target * h.comps + c] = h.component.read(
                vbytes,
                voffset + k * elem + c * h.component.size(),
                h.normalized,
            );
        }
    }
    Ok(())
}

/// Decode an accessor that must have `want` components per element into fixed arrays.
pub fn read_vec<const N: usize>(
    doc: &GltfDocument,
    index: usize,
    referrer: &str,
) -> Result<Vec<[f32; N]>, PluginError> {
    let (flat, comps) = read_floats(doc, index, referrer)?;
    if comps != N {
        return Err(doc.error(
            format!("accessors[{index}]"),
            format!("{referrer} needs {N} components per element, the accessor has {comps}"),
        ));
    }
    Ok(flat
        .chunks_exact(N)
        .map(|c| {
            let mut a = [0.0; N];
            a.copy_from_slice(c);
            a
        })
        .collect())
}

/// Decode an index accessor (SCALAR, UNSIGNED_BYTE/SHORT/INT).
pub fn read_indices(
    doc: &GltfDocument,
    index: usize,
    referrer: &str,
) -> Result<Vec<u32>, PluginError> {
    let h = header(doc, index, referrer)?;
    if h.comps != 1
        || !matches!(
            h.component,
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32
        )
        || h.normalized
    {
        return Err(doc.error(
            &h.location,
            "indices must be SCALAR UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
        ));
    }
    if h.json.get("sparse").is_some() {
        // Rare, but legal: decode through the float path (exact for indices below 2^24).
        let (flat, _) = read_floats(doc, index, referrer)?;
        return Ok(flat.into_iter().map(|v| v as u32).collect());
    }
    let view = get_usize(h.json, "bufferView")
        .ok_or_else(|| doc.error(&h.location, "an index accessor needs a bufferView"))?;
    let (bytes, _) = view_bytes(doc, view, &h.location)?;
    let size = h.component.size();
    let offset = get_usize(h.json, "byteOffset").unwrap_or(0);
    check_fits(doc, &h.location, bytes.len(), offset, size, size, h.count)?;
    Ok((0..h.count)
        .map(|i| h.component.read_u32(bytes, offset + i * size))
        .collect())
}
