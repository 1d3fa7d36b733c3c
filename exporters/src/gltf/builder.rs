//! Building a glTF document in memory: the JSON root, one binary buffer, buffer views and
//! accessors (with the `min`/`max` the spec requires), and the GLB / .gltf+.bin containers.
//!
//! Everything is appended in call order, so the same calls give the same bytes.

use serde_json::{json, Map, Value};

/// `ARRAY_BUFFER` / `ELEMENT_ARRAY_BUFFER` buffer view targets.
pub const ARRAY_BUFFER: u32 = 34962;
pub const ELEMENT_ARRAY_BUFFER: u32 = 34963;

const FLOAT: u32 = 5126;
const SHORT: u32 = 5122;
const BYTE: u32 = 5120;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// A glTF root object plus the bytes of its single buffer.
#[derive(Debug, Clone, Default)]
pub struct DocBuilder {
    pub root: Map<String, Value>,
    pub bin: Vec<u8>,
}

fn num(x: f32) -> Value {
    json!(x as f64)
}

impl DocBuilder {
    /// Append `value` to the root array `key` and return its index.
    pub fn push(&mut self, key: &str, value: Value) -> usize {
        let a = self.array_mut(key);
        a.push(value);
        a.len() - 1
    }

    /// The root array `key` (created empty when absent or not an array).
    pub fn array_mut(&mut self, key: &str) -> &mut Vec<Value> {
        let slot = self.root.entry(key.to_owned()).or_insert(Value::Null);
        if !slot.is_array() {
            *slot = Value::Array(Vec::new());
        }
        match slot {
            Value::Array(a) => a,
            _ => unreachable!("the slot was made an array just above"),
        }
    }

    /// Append raw bytes (4-byte aligned) as a new buffer view; returns its index.
    pub fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.align();
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        let mut v = json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.push("bufferViews", v)
    }

    /// Pad the buffer to a multiple of 4 bytes.
    pub fn align(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    fn float_accessor(
        &mut self,
        flat: &[f32],
        comps: usize,
        kind: &str,
        target: Option<u32>,
        min_max: bool,
    ) -> usize {
        let bytes: Vec<u8> = flat.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        let count = flat.len() / comps;
        let mut a =
            json!({"bufferView": view, "componentType": FLOAT, "count": count, "type": kind});
        if min_max {
            let mut lo = vec![f32::INFINITY; comps];
            let mut hi = vec![f32::NEG_INFINITY; comps];
            for e in flat.chunks_exact(comps) {
                for c in 0..comps {
                    lo[c] = lo[c].min(e[c]);
                    hi[c] = hi[c].max(e[c]);
                }
            }
            a["min"] = Value::Array(lo.into_iter().map(num).collect());
            a["max"] = Value::Array(hi.into_iter().map(num).collect());
        }
        self.push("accessors", a)
    }

    /// A VEC3 float vertex attribute; `min_max` for POSITION (base or morph target).
    pub fn vec3(&mut self, data: &[[f32; 3]], min_max: bool) -> usize {
        let flat: Vec<f32> = data.iter().flatten().copied().collect();
        self.float_accessor(&flat, 3, "VEC3", Some(ARRAY_BUFFER), min_max)
    }

    /// A VEC2 float vertex attribute.
    pub fn vec2(&mut self, data: &[[f32; 2]]) -> usize {
        let flat: Vec<f32> = data.iter().flatten().copied().collect();
        self.float_accessor(&flat, 2, "VEC2", Some(ARRAY_BUFFER), false)
    }

    /// A VEC4 float vertex attribute (skin weights).
    pub fn vec4(&mut self, data: &[[f32; 4]]) -> usize {
        let flat: Vec<f32> = data.iter().flatten().copied().collect();
        self.float_accessor(&flat, 4, "VEC4", Some(ARRAY_BUFFER), false)
    }

    /// Scalar floats with min/max (animation inputs) or without (outputs).
    pub fn scalars(&mut self, data: &[f32], min_max: bool) -> usize {
        self.float_accessor(data, 1, "SCALAR", None, min_max)
    }

    /// VEC3 floats outside vertex data (translation keys).
    pub fn vec3_keys(&mut self, data: &[[f32; 3]]) -> usize {
        let flat: Vec<f32> = data.iter().flatten().copied().collect();
        self.float_accessor(&flat, 3, "VEC3", None, false)
    }

    /// VEC4 floats outside vertex data (rotation keys, `[x, y, z, w]`).
    pub fn vec4_keys(&mut self, data: &[[f32; 4]]) -> usize {
        let flat: Vec<f32> = data.iter().flatten().copied().collect();
        self.float_accessor(&flat, 4, "VEC4", None, false)
    }

    /// A VEC3 vertex attribute as normalized signed 16-bit integers (`KHR_mesh_quantization`,
    /// which this requires of the document): each value `round(x · 32767)`, an element padded
    /// to 8 bytes (vertex data is 4-byte aligned); `min_max` in those integers. `None` when a
    /// value is outside [−1, 1] or not finite.
    pub fn vec3_snorm16(&mut self, data: &[[f32; 3]], min_max: bool) -> Option<usize> {
        if !data.iter().flatten().all(|x| x.abs() <= 1.0) {
            return None;
        }
        let ints: Vec<[i16; 3]> = data.iter().map(|v| v.map(snorm16)).collect();
        let bytes: Vec<u8> = ints
            .iter()
            .flat_map(|v| [v[0], v[1], v[2], 0])
            .flat_map(i16::to_le_bytes)
            .collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        self.array_mut("bufferViews")[view]["byteStride"] = json!(8);
        let mut a = json!({"bufferView": view, "componentType": SHORT, "normalized": true,
                           "count": data.len(), "type": "VEC3"});
        if min_max {
            let lo: Vec<Value> = (0..3)
                .map(|c| json!(ints.iter().map(|v| v[c]).min().unwrap_or(0)))
                .collect();
            let hi: Vec<Value> = (0..3)
                .map(|c| json!(ints.iter().map(|v| v[c]).max().unwrap_or(0)))
                .collect();
            a["min"] = Value::Array(lo);
            a["max"] = Value::Array(hi);
        }
        self.require_extension("KHR_mesh_quantization");
        Some(self.push("accessors", a))
    }

    /// A VEC3 vertex attribute (a normal or a normal's change) as normalized signed bytes
    /// (`KHR_mesh_quantization`): `round(x · 127)`, an element padded to 4 bytes. `None` when
    /// a value is outside [−1, 1] or not finite.
    pub fn vec3_snorm8(&mut self, data: &[[f32; 3]]) -> Option<usize> {
        if !data.iter().flatten().all(|x| x.abs() <= 1.0) {
            return None;
        }
        let bytes: Vec<u8> = data
            .iter()
            .flat_map(|v| [snorm8(v[0]), snorm8(v[1]), snorm8(v[2]), 0])
            .map(|i| i as u8)
            .collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        self.array_mut("bufferViews")[view]["byteStride"] = json!(4);
        self.require_extension("KHR_mesh_quantization");
        Some(self.push(
            "accessors",
            json!({"bufferView": view, "componentType": BYTE, "normalized": true,
                   "count": data.len(), "type": "VEC3"}),
        ))
    }

    /// Name `extension` in `extensionsUsed` and `extensionsRequired` (once).
    pub fn require_extension(&mut self, extension: &str) {
        for key in ["extensionsUsed", "extensionsRequired"] {
            let list = self.array_mut(key);
            if !list.iter().any(|e| e == extension) {
                list.push(json!(extension));
            }
        }
    }

    /// MAT4 floats (inverse bind matrices), each column-major.
    pub fn mat4(&mut self, data: &[[f32; 16]]) -> usize {
        let flat: Vec<f32> = data.iter().flatten().copied().collect();
        self.float_accessor(&flat, 16, "MAT4", None, false)
    }

    /// A triangle index list, as u16 when every index fits, else u32.
    pub fn indices(&mut self, idx: &[u32]) -> usize {
        let max = idx.iter().copied().max().unwrap_or(0);
        let (bytes, ct): (Vec<u8>, u32) = if max < u16::MAX as u32 {
            (
                idx.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(),
                UNSIGNED_SHORT,
            )
        } else {
            (
                idx.iter().flat_map(|&i| i.to_le_bytes()).collect(),
                UNSIGNED_INT,
            )
        };
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": ct, "count": idx.len(), "type": "SCALAR"}),
        )
    }

    /// JOINTS_n: four joint indices per vertex, u8 when `joint_count <= 256`, else u16.
    pub fn joints(&mut self, data: &[[u16; 4]], joint_count: usize) -> usize {
        let (bytes, ct): (Vec<u8>, u32) = if joint_count <= 256 {
            (
                data.iter().flatten().map(|&j| j as u8).collect(),
                UNSIGNED_BYTE,
            )
        } else {
            (
                data.iter()
                    .flatten()
                    .flat_map(|j| j.to_le_bytes())
                    .collect(),
                UNSIGNED_SHORT,
            )
        };
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": ct, "count": data.len(), "type": "VEC4"}),
        )
    }

    /// Set `buffers` to the single buffer, with `uri` for .gltf+.bin output.
    fn finish_json(&mut self, uri: Option<&str>) -> Value {
        self.align();
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(u) = uri {
            buffer["uri"] = json!(u);
        }
        self.root
            .insert("buffers".to_owned(), Value::Array(vec![buffer]));
        Value::Object(self.root.clone())
    }

    /// The whole document as one GLB.
    pub fn into_glb(mut self) -> Vec<u8> {
        let json = self.finish_json(None);
        let mut text = serde_json::to_vec(&json).unwrap_or_default();
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let total = 12 + 8 + text.len() + 8 + self.bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
        out.extend_from_slice(&text);
        out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(&self.bin);
        out
    }

    /// The document as pretty JSON referring to `bin_uri`, and the buffer's bytes.
    pub fn into_gltf(mut self, bin_uri: &str) -> (Vec<u8>, Vec<u8>) {
        let json = self.finish_json(Some(bin_uri));
        let mut text = serde_json::to_vec_pretty(&json).unwrap_or_default();
        text.push(b'\n');
        (text, self.bin)
    }
}

/// `x` in [−1, 1] as a normalized signed 16-bit integer.
pub fn snorm16(x: f32) -> i16 {
    (x.clamp(-1.0, 1.0) * 32767.0).round() as i16
}

/// `x` in [−1, 1] as a normalized signed byte.
pub fn snorm8(x: f32) -> i8 {
    (x.clamp(-1.0, 1.0) * 127.0).round() as i8
}

/// What a player reads back from [`snorm16`]: `max(i / 32767, −1)`.
pub fn from_snorm16(i: i16) -> f32 {
    (f32::from(i) / 32767.0).max(-1.0)
}

/// Percent-encode a file name for use as a relative URI.
pub fn uri_encode(name: &str) -> String {
    let mut out = String::new();
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// MIME type of an embedded image, from a `data:` URI header, the bytes' magic, or the name.
pub fn image_mime(uri: &str, bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(&[0x89, b'P', b'N', b'G']) {
        return Some("image/png");
    }
    if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return Some("image/jpeg");
    }
    if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        return Some("image/webp");
    }
    if bytes.starts_with(&[0xAB, b'K', b'T', b'X', b' ', b'2', b'0']) {
        return Some("image/ktx2");
    }
    let lower = uri.to_ascii_lowercase();
    for (ext, mime) in [
        ("png", "image/png"),
        ("jpg", "image/jpeg"),
        ("jpeg", "image/jpeg"),
        ("webp", "image/webp"),
        ("ktx2", "image/ktx2"),
    ] {
        if lower.ends_with(&format!(".{ext}")) || lower.starts_with(&format!("data:{mime}")) {
            return Some(mime);
        }
    }
    None
}
