//! glTF 2.0 import (`.gltf` with external or `data:` buffers, `.glb`).
//!
//! Owns: turning a glTF document into [`ImportedScene`]: one [`DisplayMesh`] per node of the
//! default scene that has a mesh, placed by the node's world matrix, in the pose of the first
//! frame (the first animation at t = 0, morph targets at their weights, skins applied:
//! [`pose`]); triangle lists, strips
//! and fans (triangulated); u8/u16/u32 or missing indices; sparse accessors;
//! KHR_mesh_quantization attributes decoded to `f32`. Refuses POINTS/LINES primitives,
//! Draco/meshopt compression, URIs leaving the file's folder, accessors that overrun their
//! buffers and non-finite positions, always naming the data path.
//!
//! [`document`] (container and buffers) and [`accessor`] (decoding) are public so the glTF
//! exporter can re-read a source document exactly as this importer saw it.

pub mod accessor;
pub mod document;
pub mod pose;

use accessor::{read_indices, read_vec};
use document::{get_usize, load_document, GltfDocument};
use nalgebra::{Matrix4, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;
use springbake_core::display::{
    DisplayMesh, ImportedScene, Primitive, SourceDocument, SurfaceMaterial, TextureImage, UpAxis,
};
use springbake_core::plugin::{ImportSettings, Importer, PluginError};
use std::path::Path;

/// The glTF 2.0 importer.
#[derive(Debug, Clone, Copy, Default)]
pub struct GltfImporter;

impl Importer for GltfImporter {
    fn name(&self) -> &str {
        "gltf"
    }

    fn extensions(&self) -> &[&str] {
        &["gltf", "glb"]
    }

    fn import(
        &self,
        path: &Path,
        bytes: &[u8],
        _settings: &ImportSettings,
    ) -> Result<ImportedScene, PluginError> {
        let mut doc = load_document(path, bytes)?;
        let starts = pose::start_values(&doc)?;
        pose::pose_at_start(&mut doc.json, &starts);
        let (meshes, posed_notes) = display_meshes(&doc)?;
        if meshes.is_empty() {
            return Err(PluginError::invalid(
                path,
                "the scene has no node with a mesh: nothing to simulate",
            ));
        }
        let (materials, mut notes) = surface_materials(&doc);
        notes.extend(posed_notes);
        notes.extend(animated_mesh_notes(&doc, &starts, &meshes));
        Ok(ImportedScene {
            materials,
            notes,
            meshes,
            up_axis: UpAxis::Y,
            meters_per_unit: 1.0,
            source: SourceDocument {
                path: path.to_path_buf(),
                importer: "gltf".to_owned(),
                read_root: None,
            },
        })
    }
}

/// A note per mesh whose node, or a node above it, the first animation moves: the bake starts
/// from the pose at t = 0 and its own motion replaces the animation.
fn animated_mesh_notes(
    doc: &GltfDocument,
    starts: &[pose::StartValue],
    meshes: &[DisplayMesh],
) -> Vec<String> {
    let nodes = doc.array("nodes");
    let mut parent = vec![None; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        for c in children(n) {
            if let Some(slot) = parent.get_mut(c) {
                *slot = Some(i);
            }
        }
    }
    let moved = |node: usize| starts.iter().any(|s| s.node == node && s.path != "weights");
    meshes
        .iter()
        .filter(|m| {
            let node = m
                .source_key
                .strip_prefix("node:")
                .and_then(|n| n.parse().ok());
            // Walk up at most `nodes.len()` steps (scene_nodes refused cycles already).
            std::iter::successors(node, |&n: &usize| parent.get(n).copied().flatten())
                .take(nodes.len())
                .any(moved)
        })
        .map(|m| {
            format!(
                "\"{}\" is animated in the source: the bake starts from its pose at t = 0 and \
                 replaces that animation (a scene file's [[trajectory]] moves a body along a path)",
                m.name
            )
        })
        .collect()
}

/// A node of the default scene with its world matrix.
#[derive(Debug, Clone)]
pub struct PlacedNode {
    pub node: usize,
    pub world_from_local: Matrix4<f64>,
}

/// Every node of the default scene (`scene`, else scene 0, else all root nodes) with its world
/// matrix, sorted by node index.
pub fn scene_nodes(doc: &GltfDocument) -> Result<Vec<PlacedNode>, PluginError> {
    let nodes = doc.array("nodes");
    let roots: Vec<usize> = match doc.array("scenes").len() {
        0 => {
            let mut is_child = vec![false; nodes.len()];
            for n in nodes {
                for c in children(n) {
                    if let Some(slot) = is_child.get_mut(c) {
                        *slot = true;
                    }
                }
            }
            (0..nodes.len()).filter(|&i| !is_child[i]).collect()
        }
        _ => {
            let scene = get_usize(&doc.json, "scene").unwrap_or(0);
            let json = doc.get("scenes", scene, "scene")?;
            json.get("nodes")
                .and_then(Value::as_array)
                .map(|a| {
                    a.iter()
                        .filter_map(|v| v.as_u64().map(|n| n as usize))
                        .collect()
                })
                .unwrap_or_default()
        }
    };
    let mut seen = vec![false; nodes.len()];
    let mut out = Vec::new();
    let mut stack: Vec<(usize, Matrix4<f64>, String)> = roots
        .iter()
        .rev()
        .map(|&r| (r, Matrix4::identity(), "scenes".to_owned()))
        .collect();
    while let Some((index, parent, referrer)) = stack.pop() {
        let node = doc.get("nodes", index, &referrer)?;
        let location = format!("nodes[{index}]");
        if std::mem::replace(&mut seen[index], true) {
            return Err(doc.error(
                &location,
                "node is reached twice (a cycle, or a node with two parents)",
            ));
        }
        let world = parent * local_matrix(doc, node, &location)?;
        for c in children(node).into_iter().rev() {
            stack.push((c, world, format!("{location}.children")));
        }
        out.push(PlacedNode {
            node: index,
            world_from_local: world,
        });
    }
    out.sort_by_key(|p| p.node);
    Ok(out)
}

fn children(node: &Value) -> Vec<usize> {
    node.get("children")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_u64().map(|n| n as usize))
                .collect()
        })
        .unwrap_or_default()
}

fn numbers<const N: usize>(
    doc: &GltfDocument,
    node: &Value,
    key: &str,
    location: &str,
) -> Result<Option<[f64; N]>, PluginError> {
    let Some(v) = node.get(key) else {
        return Ok(None);
    };
    let bad = || {
        doc.error(
            format!("{location}.{key}"),
            format!("must be {N} finite numbers"),
        )
    };
    let a = v.as_array().filter(|a| a.len() == N).ok_or_else(bad)?;
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64().filter(|x| x.is_finite()).ok_or_else(bad)?;
    }
    Ok(Some(out))
}

/// A node's local matrix from `matrix` or translation/rotation/scale.
pub fn local_matrix(
    doc: &GltfDocument,
    node: &Value,
    location: &str,
) -> Result<Matrix4<f64>, PluginError> {
    if let Some(m) = numbers::<16>(doc, node, "matrix", location)? {
        return Ok(Matrix4::from_column_slice(&m));
    }
    let t = numbers::<3>(doc, node, "translation", location)?.unwrap_or([0.0; 3]);
    let r = numbers::<4>(doc, node, "rotation", location)?.unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let s = numbers::<3>(doc, node, "scale", location)?.unwrap_or([1.0; 3]);
    let q = Quaternion::new(r[3], r[0], r[1], r[2]);
    if q.norm() < 1e-12 {
        return Err(doc.error(
            format!("{location}.rotation"),
            "rotation quaternion is zero",
        ));
    }
    let rotation = UnitQuaternion::from_quaternion(q).to_homogeneous();
    let translation = Translation3::new(t[0], t[1], t[2]).to_homogeneous();
    let scale = Matrix4::new_nonuniform_scaling(&Vector3::new(s[0], s[1], s[2]));
    Ok(translation * rotation * scale)
}

/// One display mesh per mesh node of the default scene, in the pose of the first frame
/// ([`pose`]: skins and morph targets applied); notes for what that pose replaces.
fn display_meshes(doc: &GltfDocument) -> Result<(Vec<DisplayMesh>, Vec<String>), PluginError> {
    let mut cache: Vec<Option<Vec<Primitive>>> = vec![None; doc.array("meshes").len()];
    let mut out = Vec::new();
    let mut notes = Vec::new();
    let placed_nodes = scene_nodes(doc)?;
    let mut world_of = vec![None; doc.array("nodes").len()];
    for p in &placed_nodes {
        world_of[p.node] = Some(p.world_from_local);
    }
    for placed in &placed_nodes {
        let node = &doc.array("nodes")[placed.node];
        let Some(mesh_index) = get_usize(node, "mesh") else {
            continue;
        };
        let location = format!("nodes[{}].mesh", placed.node);
        let mesh = doc.get("meshes", mesh_index, &location)?;
        let mut primitives = match cache.get(mesh_index).cloned().flatten() {
            Some(p) => p,
            None => {
                let p = mesh_primitives(doc, mesh_index, mesh)?;
                cache[mesh_index] = Some(p.clone());
                p
            }
        };
        let name = node
            .get("name")
            .or_else(|| mesh.get("name"))
            .and_then(Value::as_str)
            .map(str::to_owned)
            .unwrap_or_else(|| format!("node_{}", placed.node));
        let skin = skin_matrices(doc, node, placed, &world_of)?;
        let has_targets = mesh["primitives"]
            .as_array()
            .is_some_and(|p| p.iter().any(|p| p.get("targets").is_some()));
        if skin.is_some() || has_targets {
            let weights = morph_weights(node, mesh);
            if has_targets {
                notes.push(format!(
                    "\"{name}\": its morph targets are applied at their first-frame weights; \
                     the bake's output replaces them"
                ));
            }
            if skin.is_some() {
                notes.push(format!(
                    "\"{name}\" is skinned: it starts from its pose at the first frame; the \
                     output keeps that pose and drops the skin and the joints' animation"
                ));
            }
            let deformers = pose::Deformers {
                weights: &weights,
                skin,
            };
            let prims = mesh["primitives"].as_array().cloned().unwrap_or_default();
            primitives = primitives
                .into_iter()
                .zip(&prims)
                .enumerate()
                .map(|(p, (base, json))| {
                    let loc = format!("meshes[{mesh_index}].primitives[{p}]");
                    pose::posed_primitive(doc, json, &loc, base, &deformers)
                })
                .collect::<Result<_, _>>()?;
        }
        let vertex_count = primitives.iter().map(|p| p.positions.len()).sum();
        out.push(DisplayMesh {
            name,
            source_key: format!("node:{}", placed.node),
            world_from_local: placed.world_from_local,
            primitives,
            source_point_of_vertex: Vec::new(),
            source_point_count: vertex_count,
        });
    }
    Ok((out, notes))
}

/// The node's morph weights: its own, else its mesh's, else none.
fn morph_weights(node: &Value, mesh: &Value) -> Vec<f64> {
    node.get("weights")
        .or_else(|| mesh.get("weights"))
        .and_then(Value::as_array)
        .map(|a| a.iter().map(|w| w.as_f64().unwrap_or(0.0)).collect())
        .unwrap_or_default()
}

/// For a skinned node: per joint, `joint world × inverse bind matrix`, and the node's world
/// matrix (the posed vertices are written in its local frame, as the output keeps the node
/// without its skin).
#[allow(clippy::type_complexity)]
fn skin_matrices(
    doc: &GltfDocument,
    node: &Value,
    placed: &PlacedNode,
    world_of: &[Option<Matrix4<f64>>],
) -> Result<Option<(Vec<Matrix4<f64>>, Matrix4<f64>)>, PluginError> {
    let Some(skin_index) = get_usize(node, "skin") else {
        return Ok(None);
    };
    let location = format!("nodes[{}].skin", placed.node);
    let skin = doc.get("skins", skin_index, &location)?;
    let Some(joint_list) = skin["joints"].as_array() else {
        // glTF 2.0 requires `joints`; glTF 1.0 named them (`jointNames`), as some old
        // converters still wrote into files marked 2.0.
        let why = if skin.get("jointNames").is_some() {
            "is missing (this skin has glTF 1.0's `jointNames`; re-export the file as glTF 2.0)"
        } else {
            "is missing (glTF 2.0 requires it)"
        };
        return Err(doc.error(format!("skins[{skin_index}].joints"), why));
    };
    let joints: Vec<usize> = joint_list
        .iter()
        .filter_map(|j| j.as_u64().map(|j| j as usize))
        .collect();
    let inverse_binds = match get_usize(skin, "inverseBindMatrices") {
        Some(i) => accessor::read_floats(doc, i, &format!("skins[{skin_index}]"))?.0,
        None => Vec::new(),
    };
    let mut matrices = Vec::with_capacity(joints.len());
    for (k, &j) in joints.iter().enumerate() {
        let world = world_of.get(j).copied().flatten().ok_or_else(|| {
            doc.error(
                format!("skins[{skin_index}].joints[{k}]"),
                format!("joint node {j} is not in the scene"),
            )
        })?;
        let ibm = inverse_binds
            .get(16 * k..16 * k + 16)
            .map(|m| Matrix4::from_iterator(m.iter().map(|&x| f64::from(x))))
            .unwrap_or_else(Matrix4::identity);
        matrices.push(world * ibm);
    }
    Ok(Some((matrices, placed.world_from_local)))
}

fn mesh_primitives(
    doc: &GltfDocument,
    mesh_index: usize,
    mesh: &Value,
) -> Result<Vec<Primitive>, PluginError> {
    let prims = mesh
        .get("primitives")
        .and_then(Value::as_array)
        .filter(|a| !a.is_empty())
        .ok_or_else(|| doc.error(format!("meshes[{mesh_index}]"), "mesh has no primitives"))?;
    prims
        .iter()
        .enumerate()
        .map(|(p, prim)| primitive(doc, &format!("meshes[{mesh_index}].primitives[{p}]"), prim))
        .collect()
}

fn primitive(doc: &GltfDocument, location: &str, prim: &Value) -> Result<Primitive, PluginError> {
    if let Some(ext) = prim.get("extensions").and_then(Value::as_object) {
        for name in document::UNSUPPORTED_EXTENSIONS {
            if ext.contains_key(*name) {
                return Err(doc.error(
                    format!("{location}.extensions.{name}"),
                    format!("{name} compressed geometry is not supported"),
                ));
            }
        }
    }
    let mode = prim.get("mode").and_then(Value::as_u64).unwrap_or(4);
    let mode_name = match mode {
        0 => "POINTS",
        1 => "LINES",
        2 => "LINE_LOOP",
        3 => "LINE_STRIP",
        4..=6 => "",
        _ => "an unknown mode",
    };
    if !mode_name.is_empty() {
        return Err(doc.error(
            format!("{location}.mode"),
            format!(
                "primitive mode {mode} ({mode_name}) has no surface to simulate: only TRIANGLES, \
                 TRIANGLE_STRIP and TRIANGLE_FAN are supported"
            ),
        ));
    }
    let attributes = prim
        .get("attributes")
        .ok_or_else(|| doc.error(location, "primitive has no attributes"))?;
    let attr = |name: &str| get_usize(attributes, name);
    let pos_loc = format!("{location}.attributes.POSITION");
    let pos_index = attr("POSITION")
        .ok_or_else(|| doc.error(&pos_loc, "primitive has no POSITION attribute"))?;
    check_position_type(doc, pos_index)?;
    let positions = read_vec::<3>(doc, pos_index, &pos_loc)?;
    if let Some(bad) = positions
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(doc.error(
            format!("accessors[{pos_index}]"),
            format!(
                "POSITION of {location} has a NaN or infinite coordinate at element {bad}: {:?}",
                positions[bad]
            ),
        ));
    }
    let n = positions.len();
    let optional = |name: &str| attr(name).map(|i| (i, format!("{location}.attributes.{name}")));
    let normals = match optional("NORMAL") {
        Some((i, loc)) => Some(same_count(doc, read_vec::<3>(doc, i, &loc)?, n, &loc)?),
        None => None,
    };
    let uvs = match optional("TEXCOORD_0") {
        Some((i, loc)) => Some(same_count(doc, read_vec::<2>(doc, i, &loc)?, n, &loc)?),
        None => None,
    };
    let idx_loc = format!("{location}.indices");
    let raw = match get_usize(prim, "indices") {
        Some(i) => read_indices(doc, i, &idx_loc)?,
        None => (0..n as u32).collect(),
    };
    if let Some(bad) = raw.iter().find(|&&i| i as usize >= n) {
        return Err(doc.error(
            &idx_loc,
            format!("index {bad} is beyond the {n} vertices of the primitive"),
        ));
    }
    let indices = triangulate(mode, &raw).map_err(|m| doc.error(&idx_loc, m))?;
    let material = match get_usize(prim, "material") {
        Some(m) => Some(
            doc.get("materials", m, &format!("{location}.material"))?
                .get("name")
                .and_then(Value::as_str)
                .map(str::to_owned)
                .unwrap_or_else(|| format!("material_{m}")),
        ),
        None => None,
    };
    Ok(Primitive {
        positions,
        normals,
        uvs,
        indices,
        material,
    })
}

fn same_count<T>(
    doc: &GltfDocument,
    v: Vec<T>,
    n: usize,
    location: &str,
) -> Result<Vec<T>, PluginError> {
    if v.len() != n {
        return Err(doc.error(
            location,
            format!("has {} elements but POSITION has {n}", v.len()),
        ));
    }
    Ok(v)
}

/// Turn a TRIANGLES (4), TRIANGLE_STRIP (5) or TRIANGLE_FAN (6) index sequence into a
/// triangle list, following the winding rules of the glTF spec (§3.7.2.1). Degenerate strip
/// and fan triangles (restarts) are dropped.
pub fn triangulate(mode: u64, idx: &[u32]) -> Result<Vec<u32>, String> {
    match mode {
        4 => {
            if !idx.len().is_multiple_of(3) {
                return Err(format!(
                    "TRIANGLES needs a multiple of 3 indices, got {}",
                    idx.len()
                ));
            }
            Ok(idx.to_vec())
        }
        5 | 6 => {
            let mut out = Vec::with_capacity(idx.len().saturating_sub(2) * 3);
            for i in 0..idx.len().saturating_sub(2) {
                let t = if mode == 5 {
                    if i % 2 == 0 {
                        [idx[i], idx[i + 1], idx[i + 2]]
                    } else {
                        [idx[i + 1], idx[i], idx[i + 2]]
                    }
                } else {
                    [idx[i + 1], idx[i + 2], idx[0]]
                };
                if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                    out.extend(t);
                }
            }
            Ok(out)
        }
        _ => Err(format!("mode {mode} is not a triangle mode")),
    }
}

/// POSITION is FLOAT in core glTF; integer positions are only valid under
/// `KHR_mesh_quantization` (which the accessor reader decodes, normalized or not).
fn check_position_type(doc: &GltfDocument, index: usize) -> Result<(), PluginError> {
    const FLOAT: u64 = 5126;
    let component = doc
        .get("accessors", index, "POSITION")?
        .get("componentType")
        .and_then(serde_json::Value::as_u64);
    let quantized = doc
        .array("extensionsUsed")
        .iter()
        .any(|e| e.as_str() == Some("KHR_mesh_quantization"));
    if component == Some(FLOAT) || quantized {
        return Ok(());
    }
    Err(doc.error(
        format!("accessors[{index}].componentType"),
        format!(
            "POSITION must be FLOAT (5126), got {}; integer positions need the \
             KHR_mesh_quantization extension",
            component.map_or("nothing".to_owned(), |c| c.to_string())
        ),
    ))
}

/// The document's materials as [`SurfaceMaterial`]s (for exporters that build a new document:
/// USD): `baseColorFactor`, `roughnessFactor`, the base colour image (from a buffer view, a
/// `data:` URI or a file beside the source), named as the primitives name them. An image that
/// cannot be read is left out with a note.
fn surface_materials(doc: &GltfDocument) -> (Vec<SurfaceMaterial>, Vec<String>) {
    let mut notes = Vec::new();
    let materials = doc
        .array("materials")
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let pbr = &m["pbrMetallicRoughness"];
            let mut look = SurfaceMaterial {
                name: m["name"]
                    .as_str()
                    .map_or_else(|| format!("material_{i}"), str::to_owned),
                ..SurfaceMaterial::default()
            };
            if let Some(c) = pbr["baseColorFactor"].as_array() {
                let c: Vec<f32> = c
                    .iter()
                    .filter_map(|x| x.as_f64())
                    .map(|x| x as f32)
                    .collect();
                if c.len() == 4 && c.iter().all(|x| x.is_finite()) {
                    look.base_colour = [c[0], c[1], c[2], c[3]];
                }
            } else {
                look.base_colour = [1.0; 4];
            }
            if let Some(r) = pbr["roughnessFactor"].as_f64().filter(|r| r.is_finite()) {
                look.roughness = r.clamp(0.0, 1.0) as f32;
            } else {
                look.roughness = 1.0;
            }
            let location = format!("materials[{i}].pbrMetallicRoughness.baseColorTexture");
            if let Some(t) = pbr["baseColorTexture"]["index"].as_u64() {
                match texture_image(doc, t as usize, &location) {
                    Ok(image) => look.base_colour_texture = image,
                    Err(e) => notes.push(format!("{location}: {e}; left out")),
                }
            }
            look
        })
        .collect();
    (materials, notes)
}

/// The image behind texture `t`, when its source is a PNG or JPEG.
fn texture_image(
    doc: &GltfDocument,
    t: usize,
    location: &str,
) -> Result<Option<TextureImage>, PluginError> {
    let Some(source) = doc
        .array("textures")
        .get(t)
        .and_then(|t| get_usize(t, "source"))
    else {
        return Ok(None);
    };
    let image = doc.get("images", source, location)?;
    let bytes = if let Some(view) = get_usize(image, "bufferView") {
        let v = doc.get("bufferViews", view, location)?;
        let buffer = get_usize(v, "buffer").unwrap_or(0);
        let offset = get_usize(v, "byteOffset").unwrap_or(0);
        let length = get_usize(v, "byteLength").unwrap_or(0);
        doc.buffers
            .get(buffer)
            .and_then(|b| b.get(offset..offset.checked_add(length)?))
            .ok_or_else(|| doc.error(location, "the image's bufferView is out of its buffer"))?
            .to_vec()
    } else if let Some(uri) = image["uri"].as_str() {
        doc.load_uri(uri, location)?
    } else {
        return Ok(None);
    };
    let mime = if bytes.starts_with(b"\x89PNG") {
        "image/png"
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        "image/jpeg"
    } else {
        return Ok(None);
    };
    Ok(Some(TextureImage {
        name: image["name"].as_str().map_or_else(
            || format!("image_{source}.{}", &mime[6..]),
            |n| {
                if n.contains('.') {
                    n.to_owned()
                } else {
                    format!("{n}.{}", &mime[6..])
                }
            },
        ),
        mime: mime.to_owned(),
        bytes,
    }))
}
