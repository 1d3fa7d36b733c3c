//! Wedges: a scene baked once per combination of varied settings (Houdini's "wedging").
//!
//! A variation is a path into the scene file's TOML (`body[0].material`, `world.gravity`,
//! `solver.substeps`) and the values it takes, from the scene's `[wedge]` table and from
//! `--vary 'PATH=V1,V2,…'`. The plan is their cartesian product, the first variation varying
//! slowest; variant `i` is the scene with those values set, checked as any scene is. Each
//! variant keeps the original scene's folder for its sources (the folder rule is unchanged);
//! only its output goes to the wedge's own folder. Planning is deterministic, so a variant is
//! named by its index alone: a farm job or a Ray task re-plans and bakes variant `i` and gets
//! the same bytes as a local run.

use crate::{validate, validate_scene, LoadedScene, PipelineError};
use sha2::{Digest, Sha256};
use springbake_core::scene::{SceneFile, WedgeVariation};
use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// Most variants one wedge may have.
pub const MAX_VARIANTS: usize = 10_000;

/// One baked combination.
#[derive(Debug, Clone, PartialEq)]
pub struct Variant {
    pub index: usize,
    /// `(path, value)` of every variation, in plan order.
    pub values: Vec<(String, Value)>,
    /// The variant's whole scene, as TOML.
    pub scene_text: String,
    pub scene: SceneFile,
}

impl Variant {
    /// The folder name of the variant: its index, four digits or more.
    pub fn folder(&self) -> String {
        format!("{:04}", self.index)
    }

    /// `path=value  …` for logs.
    pub fn label(&self) -> String {
        self.values
            .iter()
            .map(|(p, v)| format!("{p}={}", compact(v)))
            .collect::<Vec<_>>()
            .join("  ")
    }

    /// A shorter label for pictures: each path by its last key (`material=jelly`) unless two
    /// variations share it, values without spaces.
    pub fn short_label(&self) -> String {
        let last = |p: &str| p.rsplit('.').next().unwrap_or(p).to_owned();
        self.values
            .iter()
            .map(|(p, v)| {
                let shared = self
                    .values
                    .iter()
                    .filter(|(q, _)| last(q) == last(p))
                    .count()
                    > 1;
                let name = if shared { p.clone() } else { last(p) };
                format!("{name}={}", compact(v).replace(' ', ""))
            })
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// A TOML value as written in a `--vary` list (strings without quotes).
pub fn compact(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Every variant of a scene.
#[derive(Debug, Clone)]
pub struct WedgePlan {
    pub scene_path: PathBuf,
    pub variations: Vec<WedgeVariation>,
    pub variants: Vec<Variant>,
    /// Frames for the contact sheet (1-based), from `[wedge] sheet_frames`.
    pub sheet_frames: Vec<usize>,
}

fn scene_error(path: &Path, message: impl Into<String>) -> PipelineError {
    PipelineError::Scene {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Parses `PATH=V1,V2,…`: values are TOML (`2.5`, `[0, -2, 0]`, `{ young = 1e5 }`, `"x"`) or
/// bare words taken as strings (`jelly`); commas inside brackets, braces and quotes do not
/// split.
pub fn parse_vary(expression: &str) -> Result<WedgeVariation, String> {
    let bad = |why: String| format!("--vary '{expression}': {why}");
    let (path, list) = expression
        .split_once('=')
        .ok_or_else(|| bad("expected PATH=VALUE1,VALUE2,…".into()))?;
    let path = path.trim();
    parse_path(path).map_err(bad)?;
    let mut values = Vec::new();
    for item in split_top_level(list).map_err(bad)? {
        let item = item.trim();
        if item.is_empty() {
            return Err(bad(
                "an empty value (two commas, or a comma at the end)".into()
            ));
        }
        values.push(parse_value(item).map_err(bad)?);
    }
    Ok(WedgeVariation {
        path: path.to_owned(),
        values,
    })
}

fn parse_value(item: &str) -> Result<Value, String> {
    match format!("v = {item}").parse::<Table>() {
        Ok(mut t) => t
            .remove("v")
            .ok_or_else(|| format!("'{item}' is not a value")),
        Err(_)
            if item
                .chars()
                .all(|c| c.is_alphanumeric() || "_-.".contains(c)) =>
        {
            Ok(Value::String(item.to_owned()))
        }
        Err(e) => Err(format!("'{item}' is not a TOML value: {}", e.message())),
    }
}

fn split_top_level(list: &str) -> Result<Vec<&str>, String> {
    let (mut depth, mut quote, mut start) = (0i32, None, 0);
    let mut out = Vec::new();
    for (i, c) in list.char_indices() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth == 0 => {
                out.push(&list[start..i]);
                start = i + 1;
            }
            _ => {}
        }
        if depth < 0 {
            return Err("a closing bracket without its opening one".into());
        }
    }
    if depth != 0 || quote.is_some() {
        return Err("an unclosed bracket, brace or quote".into());
    }
    out.push(&list[start..]);
    Ok(out)
}

/// One step of a path: a key or an array index.
#[derive(Debug, Clone, PartialEq)]
enum Step {
    Key(String),
    Index(usize),
}

fn parse_path(path: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for part in path.split('.') {
        let (key, rest) = part.split_once('[').unwrap_or((part, ""));
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(format!(
                "'{path}' is not a setting path (e.g. body[0].material, world.gravity)"
            ));
        }
        steps.push(Step::Key(key.to_owned()));
        if !rest.is_empty() {
            let index = rest
                .strip_suffix(']')
                .and_then(|n| n.parse::<usize>().ok())
                .ok_or_else(|| format!("'{part}' in '{path}': an index is written [0], [1], …"))?;
            steps.push(Step::Index(index));
        }
    }
    Ok(steps)
}

/// Sets `path` in `table` to `value`, making missing tables on the way; an index must exist.
fn set_path(table: &mut Table, path: &str, value: Value) -> Result<(), String> {
    let steps = parse_path(path)?;
    let mut root = Value::Table(std::mem::take(table));
    let result = set_in(&mut root, &steps, path, value);
    if let Value::Table(t) = root {
        *table = t;
    }
    result
}

fn set_in(root: &mut Value, steps: &[Step], path: &str, value: Value) -> Result<(), String> {
    let mut here = root;
    for (n, step) in steps.iter().enumerate() {
        let last = n + 1 == steps.len();
        here = match (step, here) {
            (Step::Key(k), Value::Table(t)) => {
                if last {
                    t.insert(k.clone(), value);
                    return Ok(());
                }
                let next_is_index = matches!(steps.get(n + 1), Some(Step::Index(_)));
                t.entry(k.clone()).or_insert_with(|| {
                    if next_is_index {
                        Value::Array(Vec::new())
                    } else {
                        Value::Table(Table::new())
                    }
                })
            }
            (Step::Index(i), Value::Array(a)) => {
                let count = a.len();
                let slot = a.get_mut(*i).ok_or_else(|| {
                    format!("'{path}': index {i} does not exist (there are {count})")
                })?;
                if last {
                    *slot = value;
                    return Ok(());
                }
                slot
            }
            (_, other) => {
                return Err(format!(
                    "'{path}': cannot go into a {} there",
                    other.type_str()
                ))
            }
        };
    }
    Ok(())
}

/// Plans the wedge of the scene at `scene_path` with the `[wedge]` variations and then
/// `extra` (from `--vary`). Every variant is checked as a scene; errors name the variant.
pub fn plan(scene_path: &Path, extra: &[WedgeVariation]) -> Result<WedgePlan, PipelineError> {
    let text = std::fs::read_to_string(scene_path)
        .map_err(|e| scene_error(scene_path, format!("cannot read the scene file: {e}")))?;
    let base = SceneFile::parse(&text).map_err(|e| scene_error(scene_path, e.message))?;
    let mut table: Table = text
        .parse()
        .map_err(|e: toml::de::Error| scene_error(scene_path, e.message().to_owned()))?;
    table.remove("wedge");
    let section = base.wedge.clone().unwrap_or_default();
    let mut variations = section.vary.clone();
    variations.extend(extra.iter().cloned());
    if variations.is_empty() {
        return Err(scene_error(
            scene_path,
            "nothing to vary: give --vary 'PATH=V1,V2' or a [wedge] vary table",
        ));
    }
    let mut count: usize = 1;
    for v in &variations {
        parse_path(&v.path).map_err(|e| scene_error(scene_path, format!("[wedge] vary: {e}")))?;
        if v.values.is_empty() {
            return Err(scene_error(
                scene_path,
                format!("[wedge] vary '{}': no values", v.path),
            ));
        }
        count = count.saturating_mul(v.values.len());
    }
    if count > MAX_VARIANTS {
        return Err(scene_error(
            scene_path,
            format!("{count} variants; at most {MAX_VARIANTS} in one wedge"),
        ));
    }
    let mut variants = Vec::with_capacity(count);
    for index in 0..count {
        let mut rest = index;
        let mut picks = vec![0; variations.len()];
        for (k, v) in variations.iter().enumerate().rev() {
            picks[k] = rest % v.values.len();
            rest /= v.values.len();
        }
        let mut t = table.clone();
        let mut values = Vec::new();
        for (v, &pick) in variations.iter().zip(&picks) {
            let value = v.values[pick].clone();
            set_path(&mut t, &v.path, value.clone())
                .map_err(|e| scene_error(scene_path, format!("variant {index}: {e}")))?;
            values.push((v.path.clone(), value));
        }
        let scene_text = toml::to_string(&t)
            .map_err(|e| scene_error(scene_path, format!("variant {index}: {e}")))?;
        let label = values
            .iter()
            .map(|(p, v)| format!("{p} = {v}"))
            .collect::<Vec<_>>()
            .join(", ");
        let scene = SceneFile::parse(&scene_text).map_err(|e| {
            scene_error(
                scene_path,
                format!("variant {index} ({label}): {}", e.message),
            )
        })?;
        validate_scene(&scene)
            .and_then(|()| validate::floor(&scene))
            .map_err(|e| scene_error(scene_path, format!("variant {index} ({label}): {e}")))?;
        variants.push(Variant {
            index,
            values,
            scene_text,
            scene,
        });
    }
    Ok(WedgePlan {
        scene_path: scene_path.to_path_buf(),
        variations,
        variants,
        sheet_frames: section.sheet_frames,
    })
}

impl WedgePlan {
    /// Variant `index` ready to bake: its sources from the original scene's folder, its
    /// output in `out_dir/<folder>/` under the original output's file name.
    pub fn loaded(&self, index: usize, out_dir: &Path) -> LoadedScene {
        let v = &self.variants[index];
        let mut scene = v.scene.clone();
        let name = scene
            .output
            .path
            .file_name()
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("baked.glb"));
        let out = std::path::absolute(out_dir.join(v.folder()).join(name))
            .unwrap_or_else(|_| out_dir.join(v.folder()));
        scene.output.path = out;
        LoadedScene {
            scene,
            scene_path: Some(self.scene_path.clone()),
            base_dir: self
                .scene_path
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default(),
        }
    }

    /// A hash of everything variant `index`'s bake reads: the program's version, the
    /// variant's scene and the bytes of its sources and colliders. A rerun skips a variant
    /// whose hash and outputs are unchanged.
    pub fn input_hash(&self, index: usize) -> Result<String, PipelineError> {
        let loaded = self.loaded(index, Path::new(""));
        let mut h = Sha256::new();
        h.update(env!("CARGO_PKG_VERSION").as_bytes());
        h.update(self.variants[index].scene_text.as_bytes());
        for input in loaded.inputs().iter().skip(1) {
            let bytes = loaded
                .read_source(input)
                .map_err(|message| PipelineError::Io {
                    path: input.clone(),
                    message,
                })?;
            h.update((bytes.len() as u64).to_le_bytes());
            h.update(&bytes);
        }
        Ok(hex(&h.finalize()))
    }

    /// The contact sheet's frames: `[wedge] sheet_frames`, else first, middle and last.
    pub fn sheet_frames(&self) -> Vec<usize> {
        if !self.sheet_frames.is_empty() {
            return self.sheet_frames.clone();
        }
        let frames = self
            .variants
            .first()
            .map_or(1, |v| v.scene.output.frames.max(1));
        let mut out = vec![1, frames.div_ceil(2), frames];
        out.dedup();
        out
    }
}

/// SHA-256 of `bytes` as hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vary_expressions_split_at_top_level_commas_and_bare_words_are_strings() {
        let v = parse_vary("body[0].velocity=[0,-2,0],[0, -6, 0]").unwrap();
        assert_eq!(v.path, "body[0].velocity");
        assert_eq!(v.values.len(), 2);
        assert_eq!(v.values[1].to_string(), "[0, -6, 0]");
        let v = parse_vary("body[0].material=jelly,soft_rubber,{ young = 1e5, density = 900 }")
            .unwrap();
        assert_eq!(v.values[0], Value::String("jelly".into()));
        assert!(v.values[2].is_table());
        for bad in [
            "body[0].material",
            "body[x].material=a",
            "=a,b",
            "world.gravity=1,,2",
            "world.gravity=[1,2",
            "body[0].material=a b",
        ] {
            assert!(parse_vary(bad).unwrap_err().contains(bad), "{bad}");
        }
    }

    #[test]
    fn set_path_makes_tables_and_refuses_missing_indices() {
        let mut t: Table = "[[body]]\nsource = \"a.obj\"\n".parse().unwrap();
        set_path(&mut t, "solver.substeps", Value::Integer(12)).unwrap();
        set_path(&mut t, "body[0].cells", Value::Integer(4)).unwrap();
        assert_eq!(t["solver"]["substeps"].as_integer(), Some(12));
        assert_eq!(t["body"][0]["cells"].as_integer(), Some(4));
        let e = set_path(&mut t, "body[1].cells", Value::Integer(4)).unwrap_err();
        assert!(e.contains("index 1 does not exist (there are 1)"), "{e}");
        assert!(t.contains_key("body"), "the table survives an error");
    }
}
