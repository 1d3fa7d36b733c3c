//! The glTF container: GLB header and chunks, the JSON document, and buffer/image loading from
//! the GLB `BIN` chunk, `data:` URIs or files beside the source (never outside its folder).
//!
//! The exporter re-reads the source document through [`load_document`] so that it keeps
//! exactly what the importer saw.

use base64::Engine as _;
use serde_json::Value;
use springbake_core::plugin::{IoErrorKind, PluginError};
use std::path::{Component, Path, PathBuf};

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Extensions whose geometry we cannot decode; files using them are refused by name.
pub const UNSUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
];

/// A parsed glTF document with every buffer loaded.
#[derive(Debug, Clone)]
pub struct GltfDocument {
    /// The file it came from (for error messages and to resolve relative URIs).
    pub path: PathBuf,
    pub json: Value,
    /// `buffers[i]`'s bytes, at least `byteLength` long.
    pub buffers: Vec<Vec<u8>>,
}

impl GltfDocument {
    /// Invalid-input error about this document.
    pub fn error(&self, location: impl Into<String>, message: impl Into<String>) -> PluginError {
        PluginError::invalid(&self.path, message).at(location)
    }

    /// The array `key` of the document (empty when absent).
    pub fn array(&self, key: &str) -> &[Value] {
        self.json
            .get(key)
            .and_then(Value::as_array)
            .map(Vec::as_slice)
            .unwrap_or(&[])
    }

    /// Element `index` of the array `key`, or an error naming the dangling reference.
    pub fn get(&self, key: &str, index: usize, referrer: &str) -> Result<&Value, PluginError> {
        self.array(key).get(index).ok_or_else(|| {
            self.error(
                referrer,
                format!(
                    "refers to {key}[{index}], but the file has {} {key}",
                    self.array(key).len()
                ),
            )
        })
    }

    /// Load the bytes behind an image or buffer `uri` (a `data:` URI or a relative file path).
    pub fn load_uri(&self, uri: &str, location: &str) -> Result<Vec<u8>, PluginError> {
        load_uri(&self.path, uri, location)
    }
}

/// Read an unsigned integer property.
pub fn get_usize(v: &Value, key: &str) -> Option<usize> {
    v.get(key)
        .and_then(Value::as_u64)
        .and_then(|n| usize::try_from(n).ok())
}

/// Parse `bytes` (GLB or JSON glTF) read from `path` and load all its buffers.
pub fn load_document(path: &Path, bytes: &[u8]) -> Result<GltfDocument, PluginError> {
    let (json, bin) = split_container(path, bytes)?;
    let json: Value = serde_json::from_slice(json).map_err(|e| {
        PluginError::invalid(
            path,
            format!(
                "invalid JSON at line {}, column {}: {e}",
                e.line(),
                e.column()
            ),
        )
    })?;
    if !json.is_object() {
        return Err(PluginError::invalid(path, "the glTF JSON is not an object"));
    }
    let version = json
        .get("asset")
        .and_then(|a| a.get("version"))
        .and_then(Value::as_str)
        .ok_or_else(|| PluginError::invalid(path, "asset.version is missing").at("asset"))?;
    if !version.starts_with("2.") {
        return Err(PluginError::invalid(
            path,
            format!("glTF version {version} is not supported (only 2.x)"),
        )
        .at("asset.version"));
    }
    let mut doc = GltfDocument {
        path: path.to_path_buf(),
        json,
        buffers: Vec::new(),
    };
    check_extensions(&doc)?;
    let mut buffers = Vec::new();
    for (i, buffer) in doc.array("buffers").iter().enumerate() {
        let location = format!("buffers[{i}]");
        let byte_length = get_usize(buffer, "byteLength")
            .ok_or_else(|| doc.error(&location, "byteLength is missing or not an integer"))?;
        let data = match buffer.get("uri").and_then(Value::as_str) {
            Some(uri) => load_uri(path, uri, &format!("{location}.uri"))?,
            None if i == 0 => bin.map(<[u8]>::to_vec).ok_or_else(|| {
                doc.error(
                    &location,
                    "buffer has no uri and the file has no GLB BIN chunk",
                )
            })?,
            None => return Err(doc.error(&location, "buffer has no uri")),
        };
        if data.len() < byte_length {
            return Err(doc.error(
                &location,
                format!(
                    "byteLength is {byte_length} but only {} bytes are there",
                    data.len()
                ),
            ));
        }
        // Views are checked against the declared length, not against whatever follows it (a
        // GLB chunk's padding, or a longer file): data past byteLength is not the buffer's.
        let mut data = data;
        data.truncate(byte_length);
        buffers.push(data);
    }
    doc.buffers = buffers;
    Ok(doc)
}

/// Refuse files that need a geometry-compression extension we cannot decode.
fn check_extensions(doc: &GltfDocument) -> Result<(), PluginError> {
    for key in ["extensionsRequired", "extensionsUsed"] {
        for (i, ext) in doc.array(key).iter().enumerate() {
            if let Some(name) = ext.as_str().filter(|n| UNSUPPORTED_EXTENSIONS.contains(n)) {
                return Err(doc.error(
                    format!("{key}[{i}]"),
                    format!(
                        "{name} compressed geometry is not supported: re-export the file \
                         without {name} (e.g. untick compression in Blender's glTF exporter)"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Split a GLB into its JSON and BIN chunks, or take the bytes as JSON text.
fn split_container<'a>(
    path: &Path,
    bytes: &'a [u8],
) -> Result<(&'a [u8], Option<&'a [u8]>), PluginError> {
    if bytes.is_empty() {
        return Err(PluginError::invalid(path, "the file is empty"));
    }
    if !bytes.starts_with(GLB_MAGIC) {
        let first = bytes
            .iter()
            .copied()
            .find(|b| !b.is_ascii_whitespace() && *b != 0xEF && *b != 0xBB && *b != 0xBF);
        if first == Some(b'{') {
            return Ok((bytes, None));
        }
        return Err(PluginError::new(
            IoErrorKind::Incompatible,
            path,
            format!(
                "not a glTF file: starts with {:02x?} instead of the GLB magic \"glTF\" or a JSON object",
                &bytes[..bytes.len().min(4)]
            ),
        ));
    }
    let u32_at = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let header = |m: &str| PluginError::invalid(path, m.to_owned()).at("GLB header");
    let version = u32_at(4).ok_or_else(|| header("GLB header cut short"))?;
    if version != 2 {
        return Err(header(&format!(
            "GLB container version {version} is not supported (only 2)"
        )));
    }
    let total = u32_at(8).ok_or_else(|| header("GLB header cut short"))? as usize;
    if total > bytes.len() {
        return Err(header(&format!(
            "file is cut short: the GLB header says {total} bytes, the file has {}",
            bytes.len()
        )));
    }
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while at < total {
        let location = format!("GLB chunk {index}");
        let len = u32_at(at)
            .ok_or_else(|| PluginError::invalid(path, "chunk header cut short").at(&location))?
            as usize;
        let kind = u32_at(at + 4)
            .ok_or_else(|| PluginError::invalid(path, "chunk header cut short").at(&location))?;
        let start = at + 8;
        let end = start
            .checked_add(len)
            .filter(|&e| e <= total)
            .ok_or_else(|| {
                PluginError::invalid(
                    path,
                    format!("chunk of {len} bytes runs past the end of the file ({total} bytes)"),
                )
                .at(&location)
            })?;
        let data = &bytes[start..end];
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(data),
            (0, _) => {
                return Err(
                    PluginError::invalid(path, "the first GLB chunk is not JSON").at(&location),
                )
            }
            (_, CHUNK_BIN) if bin.is_none() => bin = Some(data),
            _ => {} // unknown chunks are skipped, as the spec asks
        }
        at = next_chunk(end, |at| u32_at(at + 4));
        index += 1;
    }
    let json = json.ok_or_else(|| header("GLB has no JSON chunk"))?;
    Ok((json, bin))
}

/// Where the chunk after one ending at `end` starts. A chunk's length includes its padding
/// to 4 bytes, so in a valid file that is `end`; some writers (trimesh up to 3.x) give the
/// JSON's unpadded length and pad after it. Blender's importer reads the next header at
/// `end` too, so a chunk type found there is taken; otherwise the next multiple of 4.
fn next_chunk(end: usize, kind_at: impl Fn(usize) -> Option<u32>) -> usize {
    let is_chunk = |at: usize| matches!(kind_at(at), Some(CHUNK_BIN | CHUNK_JSON));
    if end.is_multiple_of(4) || is_chunk(end) {
        end
    } else {
        end.next_multiple_of(4)
    }
}

/// Load a `data:` URI or a file named by a relative URI next to `base`.
pub fn load_uri(base: &Path, uri: &str, location: &str) -> Result<Vec<u8>, PluginError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest
            .split_once(',')
            .ok_or_else(|| PluginError::invalid(base, "malformed data URI: no ','").at(location))?;
        if !header.ends_with(";base64") {
            return Err(PluginError::invalid(base, "data URI is not base64-encoded").at(location));
        }
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| {
                PluginError::invalid(base, format!("bad base64 in data URI: {e}")).at(location)
            });
    }
    let file =
        resolve_relative_uri(base, uri).map_err(|m| PluginError::invalid(base, m).at(location))?;
    // Symlinks are resolved before the folder check (a link inside the folder may point out),
    // and the read is bounded like a source's.
    let folder = base.parent().unwrap_or(Path::new(""));
    springbake_core::files::read_contained(folder, &file).map_err(|e| {
        PluginError::invalid(
            base,
            format!("cannot read {} (from uri \"{uri}\"): {e}", file.display()),
        )
        .at(location)
    })
}

/// The file a relative URI names beside `base`; refuses anything that would leave `base`'s
/// folder (`..`, absolute paths, drive letters, other schemes).
pub fn resolve_relative_uri(base: &Path, uri: &str) -> Result<PathBuf, String> {
    let decoded = percent_decode(uri)?;
    let refuse = |why: &str| {
        Err(format!(
            "uri \"{uri}\" {why}: only files inside the glTF file's folder are read"
        ))
    };
    if decoded.contains(':') {
        return refuse("has a scheme or drive letter");
    }
    if decoded.starts_with('/') || decoded.starts_with('\\') {
        return refuse("is an absolute path");
    }
    let relative = PathBuf::from(decoded.replace('\\', "/"));
    for c in relative.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            _ => return refuse("leaves the folder"),
        }
    }
    let dir = base.parent().unwrap_or(Path::new(""));
    Ok(dir.join(relative))
}

/// Decode `%XX` escapes of a URI into a UTF-8 string.
fn percent_decode(uri: &str) -> Result<String, String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("uri \"{uri}\" has a bad %-escape"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("uri \"{uri}\" is not UTF-8 after decoding"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_leaving_the_folder_are_refused() {
        let base = Path::new("/a/b/scene.gltf");
        assert!(resolve_relative_uri(base, "../x.bin").is_err());
        assert!(resolve_relative_uri(base, "sub/../../x.bin").is_err());
        assert!(resolve_relative_uri(base, "%2E%2E/x.bin").is_err());
        assert!(resolve_relative_uri(base, "/etc/passwd").is_err());
        assert!(resolve_relative_uri(base, "C:/x.bin").is_err());
        assert!(resolve_relative_uri(base, "file:///etc/passwd").is_err());
        assert_eq!(
            resolve_relative_uri(base, "sub/my%20file.bin").unwrap(),
            PathBuf::from("/a/b/sub/my file.bin")
        );
    }

    #[test]
    fn glb_chunk_running_past_the_end_is_an_error() {
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(24u32.to_le_bytes());
        glb.extend(1000u32.to_le_bytes());
        glb.extend(CHUNK_JSON.to_le_bytes());
        glb.extend(b"{}  ");
        let err = load_document(Path::new("x.glb"), &glb).unwrap_err();
        assert!(err.message.contains("runs past"), "{err}");
    }
}
