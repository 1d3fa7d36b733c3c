//! Wavefront MTL material libraries (the `mtllib` files an OBJ names): `newmtl` with `Kd`
//! (base colour), `d` / `Tr` (opacity), `Ns` (shininess), `Ks` (specular, kept for the record),
//! and the texture maps `map_Kd` (base colour), `map_Bump` / `bump` / `norm` (normal map) and
//! `map_d` (opacity), into [`SurfaceMaterial`]s the exporters write back.
//!
//! Read as Blender 5.0.1's OBJ importer reads them: base colour = `Kd` as is, or white when
//! `map_Kd` gives the colour (Blender links the image and leaves `Kd` unused), alpha = `d` (or
//! `1 − Tr`), roughness = `1 − sqrt(Ns / 1000)` clamped to [0, 1], metallic 0. Map options
//! (`-bm 1.0`, `-s …`) are skipped; the file name is the rest of the line, backslashes (files
//! written on Windows) read as `/`, relative to the `.mtl` file. Libraries and textures are
//! read only inside the import's folder rule; a missing or unreadable library or texture is
//! left out with a note (an OBJ whose `.mtl` went missing still imports, as in Blender), a
//! malformed number is an error naming the file and line.

use springbake_core::display::{SurfaceMaterial, TextureImage};
use springbake_core::files;
use springbake_core::plugin::PluginError;
use std::path::{Path, PathBuf};

/// The materials of `libraries` (as written after `mtllib`, relative to the OBJ at `obj`),
/// and notes on what could not be read.
pub fn read_libraries(
    obj: &Path,
    libraries: &[String],
    root: &Path,
) -> Result<(Vec<SurfaceMaterial>, Vec<String>), PluginError> {
    let base = obj.parent().unwrap_or(Path::new(""));
    let mut materials = Vec::new();
    let mut notes = Vec::new();
    for lib in libraries {
        let path = base.join(lib.replace('\\', "/"));
        match files::read_contained(root, &path) {
            Ok(bytes) => {
                let text = String::from_utf8_lossy(&bytes);
                materials.extend(parse(&path, &text, root, &mut notes)?);
            }
            Err(e) => notes.push(format!(
                "{}: material library {}: {e}; its materials are left grey",
                obj.display(),
                path.display()
            )),
        }
    }
    Ok((materials, notes))
}

fn number(path: &Path, line: usize, token: Option<&str>, key: &str) -> Result<f32, PluginError> {
    token
        .and_then(|t| t.parse::<f32>().ok())
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            PluginError::invalid(path, format!("{key}: expected a number"))
                .at(format!("line {line}"))
        })
}

/// The file name of a `map_*` line: the last token not an option or an option's value.
fn map_file(rest: &str) -> Option<String> {
    let mut tokens = rest.split_whitespace().peekable();
    let mut name = Vec::new();
    while let Some(t) = tokens.next() {
        if t.starts_with('-') && name.is_empty() {
            // Options take one to three numbers (`-s u v w`), or a word (`-imfchan r`).
            while tokens
                .peek()
                .is_some_and(|n| n.parse::<f32>().is_ok() || n.len() == 1)
            {
                tokens.next();
            }
            continue;
        }
        name.push(t);
    }
    (!name.is_empty()).then(|| name.join(" ").replace('\\', "/"))
}

fn texture(mtl: &Path, file: &str, root: &Path, notes: &mut Vec<String>) -> Option<TextureImage> {
    let path: PathBuf = mtl.parent().unwrap_or(Path::new("")).join(file);
    match files::read_contained(root, &path) {
        Ok(bytes) => {
            let mime = if bytes.starts_with(b"\x89PNG") {
                "image/png"
            } else if bytes.starts_with(&[0xFF, 0xD8]) {
                "image/jpeg"
            } else {
                notes.push(format!(
                    "texture {}: not a PNG or JPEG image, left out",
                    path.display()
                ));
                return None;
            };
            Some(TextureImage {
                name: file.to_owned(),
                mime: mime.to_owned(),
                bytes,
            })
        }
        Err(e) => {
            notes.push(format!("texture {}: {e}", path.display()));
            None
        }
    }
}

/// The materials of one library's text.
pub fn parse(
    path: &Path,
    text: &str,
    root: &Path,
    notes: &mut Vec<String>,
) -> Result<Vec<SurfaceMaterial>, PluginError> {
    let mut out: Vec<SurfaceMaterial> = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let raw = raw.split('#').next().unwrap_or("").trim();
        let (key, rest) = raw.split_once(char::is_whitespace).unwrap_or((raw, ""));
        let rest = rest.trim();
        if key == "newmtl" {
            out.push(SurfaceMaterial {
                name: rest.to_owned(),
                ..SurfaceMaterial::default()
            });
            continue;
        }
        let Some(m) = out.last_mut() else {
            continue;
        };
        let mut tokens = rest.split_whitespace();
        match key {
            "Kd" if m.base_colour_texture.is_none() => {
                let r = number(path, line, tokens.next(), key)?;
                let g = tokens
                    .next()
                    .map_or(Ok(r), |t| number(path, line, Some(t), key))?;
                let b = tokens
                    .next()
                    .map_or(Ok(r), |t| number(path, line, Some(t), key))?;
                m.base_colour[..3].copy_from_slice(&[r, g, b]);
            }
            "d" => m.base_colour[3] = number(path, line, tokens.next(), key)?.clamp(0.0, 1.0),
            "Tr" => {
                m.base_colour[3] = (1.0 - number(path, line, tokens.next(), key)?).clamp(0.0, 1.0)
            }
            "Ns" => {
                let ns = number(path, line, tokens.next(), key)?.max(0.0);
                m.roughness = (1.0 - (ns / 1000.0).sqrt()).clamp(0.0, 1.0);
            }
            "map_Kd" | "map_Bump" | "map_bump" | "bump" | "norm" | "map_d" => {
                let Some(file) = map_file(rest) else {
                    continue;
                };
                let image = texture(path, &file, root, notes);
                match key {
                    "map_Kd" => {
                        if image.is_some() {
                            m.base_colour[..3].copy_from_slice(&[1.0; 3]);
                        }
                        m.base_colour_texture = image;
                    }
                    "map_d" => m.opacity_texture = image,
                    _ => m.normal_texture = image,
                }
            }
            _ => {}
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_opacity_roughness_and_map_names_read_as_blender_reads_them() {
        let text = "# a comment\nnewmtl Red\nNs 250\nKd 0.8 0.1 0.05\nd 0.5\n\
                    map_Kd -bm 1.0 textures\\red brick.png\nnewmtl Glass\nTr 0.75\nKd 0.2\n";
        let mut notes = Vec::new();
        let m = parse(
            Path::new("/nowhere/x.mtl"),
            text,
            Path::new("/nowhere"),
            &mut notes,
        )
        .unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m[0].name, "Red");
        assert_eq!(m[0].base_colour, [0.8, 0.1, 0.05, 0.5]);
        assert!((m[0].roughness - 0.5).abs() < 1e-6);
        // The texture does not exist: a note naming it, not an error.
        assert!(m[0].base_colour_texture.is_none());
        assert!(notes[0].contains("textures/red brick.png"), "{notes:?}");
        assert_eq!(m[1].base_colour, [0.2, 0.2, 0.2, 0.25]);
        assert_eq!(
            map_file("-s 1 1 1 -o 0 0 0 a\\b.png").as_deref(),
            Some("a/b.png")
        );
        let bad = parse(
            Path::new("x.mtl"),
            "newmtl A\nKd red\n",
            Path::new("."),
            &mut notes,
        );
        assert!(bad.unwrap_err().to_string().contains("line 2"));
    }
}
