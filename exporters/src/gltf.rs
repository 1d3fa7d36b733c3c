//! glTF 2.0 export of a bake (`.glb`, or `.gltf` + `.bin`).
//!
//! Owns: writing [`BakedScene`]s as glTF. A scene imported from glTF keeps its source
//! document (nodes, names, hierarchy, materials, textures with images embedded, UVs, other
//! animations); other sources get a fresh document, one node per display mesh. Two caches:
//! - [`CacheKind::Morph`]: one morph target per baked frame on each baked mesh (POSITION and
//!   NORMAL deltas) and one animation whose weights channels play the frames one-hot at
//!   `i / fps`, LINEAR.
//! - [`CacheKind::Pca`]: the mesh's rigid motion as its node's translation and rotation keys,
//!   and the fewest principal components of what is left that keep every vertex within the
//!   bound, as morph targets (16-bit where that keeps the bound) with one weights key per
//!   frame (`compact`, `rigid`, `pca`).
//! - [`CacheKind::Skin`]: the lattice as a skeleton: one joint per lattice node with
//!   translation-only keys, inverse bind matrices undoing the rest translation, 8 influences
//!   per vertex (JOINTS_0/WEIGHTS_0 + JOINTS_1/WEIGHTS_1). The joints hang under a
//!   "lattice root" node that copies the mesh node's local transform and sits beside it under
//!   the same parent, so joint world = mesh world × translate(node) and the skinned vertex
//!   `Σ wⱼ · world · (v − restⱼ + nodeⱼ(t))` is exactly the mesh's world transform applied to
//!   the trilinearly embedded vertex (glTF ignores the skinned node's own transform).
//!
//! Particle effects go in as a node per particle with translation and scale keys
//! ([`particles`]).
//!
//! Output is deterministic: JSON objects are ordered maps and everything is appended in a
//! fixed order.

pub(crate) mod builder;
mod static_mesh;
pub use static_mesh::{static_glb, StaticMesh};
mod compact;
pub mod particles;
mod pca;
mod posed;
mod rigid;

use builder::{image_mime, uri_encode, DocBuilder};
use serde_json::{json, Value};
use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::{vertex_normals, DisplayMesh, ImportedScene, UpAxis};
use springbake_core::plugin::{
    CacheKind, ExportSettings, Exporter, IoErrorKind, OutputFile, PluginError,
};
use springbake_importers::gltf::document::{get_usize, load_document};
use springbake_importers::gltf::pose::{start_values, StartValue};

/// The glTF 2.0 exporter.
#[derive(Debug, Clone, Copy, Default)]
pub struct GltfExporter;

impl Exporter for GltfExporter {
    fn name(&self) -> &str {
        "gltf"
    }

    fn extensions(&self) -> &[&str] {
        &["glb", "gltf"]
    }

    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        let out = &settings.path;
        let ext = out
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if !matches!(ext.as_deref(), Some("glb") | Some("gltf")) {
            return Err(PluginError::invalid(
                out,
                "the glTF exporter writes .glb or .gltf files",
            ));
        }
        check_bake(scene, baked, settings)?;
        let (mut b, node_of_mesh, starts) = if scene.source.importer == "gltf" {
            source_document(scene)?
        } else {
            let all = (0..scene.meshes.len()).collect();
            (fresh_document(scene), all, Vec::new())
        };
        let err = |m: String| PluginError::invalid(out, m);
        let mut targets = Vec::new();
        let mut skins = Vec::new();
        for bm in &baked.meshes {
            let node = node_of_mesh[bm.mesh_index];
            let display = &scene.meshes[bm.mesh_index];
            let posing = posed::Posing::of(&mut b, node);
            let mesh = prepare_node(&mut b, node, display).map_err(err)?;
            posed::write_posed_geometry(&mut b, mesh, display, posing);
            skins.extend(posing.skin);
            targets.push((node, mesh, bm));
        }
        let baked_nodes: Vec<usize> = targets.iter().map(|t| t.0).collect();
        drop_weight_channels(&mut b, &baked_nodes);
        posed::drop_posing(&mut b, &baked_nodes, &skins, &starts);
        let times: Vec<f32> = (0..baked.frame_count)
            .map(|i| baked.frame_time(i) as f32)
            .collect();
        let time_accessor = b.scalars(&times, true);
        let mut anim = Animation::default();
        for &(node, mesh, bm) in &targets {
            let display = &scene.meshes[bm.mesh_index];
            match settings.cache {
                CacheKind::Morph => {
                    add_morph(&mut b, node, mesh, display, bm, time_accessor, &mut anim)
                        .map_err(err)?
                }
                CacheKind::Skin => {
                    add_skin(&mut b, node, mesh, display, bm, time_accessor, &mut anim)
                        .map_err(err)?
                }
                CacheKind::Pca { max_error_um } => {
                    let cache = compact::CompactCache {
                        max_error_m: f64::from(max_error_um) * 1e-6,
                        metres_per_unit: scene.meters_per_unit,
                    };
                    cache
                        .add(&mut b, node, mesh, display, bm, time_accessor, &mut anim)
                        .map_err(err)?
                }
            }
        }
        for (keys, node, path, interpolation) in particles::add_particles(&mut b, &baked.particles)
        {
            anim.add_with(time_accessor, keys, node, path, interpolation);
        }
        if !anim.channels.is_empty() {
            b.push(
                "animations",
                json!({"name": "springbake", "channels": anim.channels, "samplers": anim.samplers}),
            );
        }
        if let Some(stage) = &baked.stage {
            add_stage(&mut b, stage);
        }
        if ext.as_deref() == Some("glb") {
            return Ok(vec![OutputFile {
                path: out.clone(),
                bytes: b.into_glb(),
            }]);
        }
        let bin_path = out.with_extension("bin");
        let bin_name = bin_path
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| PluginError::invalid(out, "output file name is not UTF-8"))?;
        let (json, bin) = b.into_gltf(&uri_encode(bin_name));
        Ok(vec![
            OutputFile {
                path: out.clone(),
                bytes: json,
            },
            OutputFile {
                path: bin_path,
                bytes: bin,
            },
        ])
    }
}

/// The bake's surroundings as the document's `extras.springbake_stage` (Y-up metres, glTF's
/// world frame): `floor` (height or null), `walls` (the room box's `[min, max]` or null), `capsules` (`radius`, `length`, and per frame
/// `[cx, cy, cz, ax, ay, az]`: the axis segment's centre and direction) and `colliders`
/// (`name`, flat `positions` and `triangles`, up to 20 000 triangles in all), for players that
/// draw what the bodies moved against. Other extras of the source are kept.
fn add_stage(b: &mut DocBuilder, stage: &springbake_core::bake::BakedStage) {
    let capsules: Vec<Value> = stage
        .capsules
        .iter()
        .map(|c| {
            let frames: Vec<Value> = c
                .frames
                .iter()
                .map(|(p, a)| json!([p[0], p[1], p[2], a[0], a[1], a[2]]))
                .collect();
            json!({"radius": c.radius, "length": c.length, "frames": frames})
        })
        .collect();
    let extras = b.root.entry("extras").or_insert_with(|| json!({}));
    if !extras.is_object() {
        *extras = json!({});
    }
    // Colliders as flat arrays, up to a size a player can take from JSON.
    let mut budget = MAX_STAGE_TRIANGLES;
    let colliders: Vec<Value> = stage
        .colliders
        .iter()
        .filter(|c| {
            let fits = c.triangles.len() <= budget;
            budget = budget.saturating_sub(c.triangles.len());
            fits
        })
        .map(|c| {
            let positions: Vec<f64> = c.positions.iter().flatten().copied().collect();
            let triangles: Vec<u32> = c.triangles.iter().flatten().copied().collect();
            json!({"name": c.name, "positions": positions, "triangles": triangles})
        })
        .collect();
    extras["springbake_stage"] = json!({"floor": stage.floor, "capsules": capsules,
        "colliders": colliders, "walls": stage.walls});
}

/// Most collider triangles recorded in a glTF's stage (the rest are left out).
const MAX_STAGE_TRIANGLES: usize = 20_000;

/// Channels and samplers of the one animation we add.
#[derive(Default)]
struct Animation {
    channels: Vec<Value>,
    samplers: Vec<Value>,
}

impl Animation {
    fn add(&mut self, input: usize, output: usize, node: usize, path: &str) {
        self.add_with(input, output, node, path, "LINEAR");
    }

    fn add_with(&mut self, input: usize, output: usize, node: usize, path: &str, how: &str) {
        let sampler = self.samplers.len();
        self.samplers
            .push(json!({"input": input, "output": output, "interpolation": how}));
        self.channels
            .push(json!({"sampler": sampler, "target": {"node": node, "path": path}}));
    }
}

/// Refuse bakes that do not fit the scene: counts, finiteness, lattice consistency.
fn check_bake(
    scene: &ImportedScene,
    baked: &BakedScene,
    settings: &ExportSettings,
) -> Result<(), PluginError> {
    let out = &settings.path;
    let bad = |at: String, m: String| PluginError::invalid(out, m).at(at);
    if !(baked.fps.is_finite() && baked.fps > 0.0) {
        return Err(bad(
            "fps".into(),
            format!("fps must be positive, got {}", baked.fps),
        ));
    }
    if baked.frame_count == 0 {
        return Err(bad("frame_count".into(), "the bake has no frames".into()));
    }
    let mut seen = vec![false; scene.meshes.len()];
    for (k, bm) in baked.meshes.iter().enumerate() {
        let at = format!("baked.meshes[{k}]");
        let Some(display) = scene.meshes.get(bm.mesh_index) else {
            return Err(bad(
                at,
                format!("mesh_index {} is not a mesh of the scene", bm.mesh_index),
            ));
        };
        if std::mem::replace(&mut seen[bm.mesh_index], true) {
            return Err(bad(at, format!("mesh {} is baked twice", bm.mesh_index)));
        }
        if bm.frames.len() != baked.frame_count {
            return Err(bad(
                at,
                format!(
                    "{} frames, the bake says {}",
                    bm.frames.len(),
                    baked.frame_count
                ),
            ));
        }
        let n = display.vertex_count();
        for (f, frame) in bm.frames.iter().enumerate() {
            if frame.len() != n {
                return Err(bad(
                    format!("{at}.frames[{f}]"),
                    format!(
                        "{} vertices, mesh \"{}\" has {n}",
                        frame.len(),
                        display.name
                    ),
                ));
            }
            if let Some(v) = frame.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
                return Err(bad(
                    format!("{at}.frames[{f}][{v}]"),
                    "non-finite position".into(),
                ));
            }
        }
        if settings.cache == CacheKind::Skin {
            check_lattice(bm, n, baked.frame_count).map_err(|m| bad(format!("{at}.lattice"), m))?;
        }
    }
    Ok(())
}

fn check_lattice(bm: &BakedMesh, vertices: usize, frames: usize) -> Result<(), String> {
    let l = bm
        .lattice
        .as_ref()
        .ok_or("the skin cache needs the lattice, and this baked mesh has none")?;
    if l.rest.len() < 8 || l.rest.len() > u16::MAX as usize + 1 {
        return Err(format!(
            "{} lattice nodes: a skin needs 8 to 65536",
            l.rest.len()
        ));
    }
    if l.vertex_nodes.len() != vertices || l.vertex_weights.len() != vertices {
        return Err(format!(
            "embedding covers {} / {} vertices, the mesh has {vertices}",
            l.vertex_nodes.len(),
            l.vertex_weights.len()
        ));
    }
    if l.frames.len() != frames || l.frames.iter().any(|f| f.len() != l.rest.len()) {
        return Err("lattice frames do not match the bake's frames and nodes".into());
    }
    let finite = |p: &[f32; 3]| p.iter().all(|c| c.is_finite());
    if !l.rest.iter().all(finite) || !l.frames.iter().flatten().all(finite) {
        return Err("non-finite lattice node position".into());
    }
    if let Some(v) = l
        .vertex_nodes
        .iter()
        .position(|ns| ns.iter().any(|&j| j as usize >= l.rest.len()))
    {
        return Err(format!("vertex {v} refers to a node beyond the lattice"));
    }
    Ok(())
}

/// Re-read the source glTF, gather its buffers into one and embed its images.
/// Returns the builder and, per display mesh, its node index.
/// The source's document to write the bake into, the node of each display mesh, and the
/// first animation's values at t = 0 (the pose the importer gave the bodies).
#[allow(clippy::type_complexity)]
fn source_document(
    scene: &ImportedScene,
) -> Result<(DocBuilder, Vec<usize>, Vec<StartValue>), PluginError> {
    let path = &scene.source.path;
    let bytes = std::fs::read(path).map_err(|e| {
        PluginError::new(
            IoErrorKind::Io,
            path,
            format!("cannot re-read the source glTF to keep its document: {e}"),
        )
    })?;
    let doc = load_document(path, &bytes)?;
    let starts = start_values(&doc)?;
    let mut node_of_mesh = Vec::with_capacity(scene.meshes.len());
    for m in &scene.meshes {
        let node = m
            .source_key
            .strip_prefix("node:")
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|&n| n < doc.array("nodes").len())
            .ok_or_else(|| {
                PluginError::invalid(
                    path,
                    format!(
                        "mesh \"{}\" has source_key \"{}\", which names no node of the source",
                        m.name, m.source_key
                    ),
                )
            })?;
        node_of_mesh.push(node);
    }
    let mut b = DocBuilder {
        root: doc.json.as_object().cloned().unwrap_or_default(),
        bin: Vec::new(),
    };
    let mut base = Vec::with_capacity(doc.buffers.len());
    for (i, data) in doc.buffers.iter().enumerate() {
        b.align();
        base.push(b.bin.len());
        let len = get_usize(&doc.array("buffers")[i], "byteLength").unwrap_or(data.len());
        b.bin.extend_from_slice(&data[..len.min(data.len())]);
    }
    for (i, view) in b.array_mut("bufferViews").iter_mut().enumerate() {
        let buffer = get_usize(view, "buffer").unwrap_or(usize::MAX);
        let start = *base.get(buffer).ok_or_else(|| {
            PluginError::invalid(path, "bufferView refers to a missing buffer")
                .at(format!("bufferViews[{i}]"))
        })?;
        view["buffer"] = json!(0);
        view["byteOffset"] = json!(start + get_usize(view, "byteOffset").unwrap_or(0));
    }
    let images = doc.array("images").to_vec();
    for (i, image) in images.iter().enumerate() {
        let Some(uri) = image.get("uri").and_then(Value::as_str) else {
            continue;
        };
        let at = format!("images[{i}].uri");
        let data = doc.load_uri(uri, &at)?;
        let mime = image
            .get("mimeType")
            .and_then(Value::as_str)
            .map(str::to_owned)
            .or_else(|| image_mime(uri, &data).map(str::to_owned))
            .ok_or_else(|| {
                doc.error(
                    &at,
                    "cannot tell the image's type (PNG, JPEG, WebP or KTX2)",
                )
            })?;
        let view = b.view(&data, None);
        let slot = &mut b.array_mut("images")[i];
        if let Some(o) = slot.as_object_mut() {
            o.remove("uri");
            o.insert("bufferView".into(), json!(view));
            o.insert("mimeType".into(), json!(mime));
        }
    }
    let asset = b.root.entry("asset").or_insert_with(|| json!({}));
    let generator = asset
        .get("generator")
        .and_then(Value::as_str)
        .map(|g| format!("springbake (source: {g})"))
        .unwrap_or_else(|| "springbake".to_owned());
    asset["generator"] = json!(generator);
    Ok((b, node_of_mesh, starts))
}

/// A new document: one node per display mesh (node index = mesh index), materials by name,
/// under a root node converting Z-up / non-metre sources to glTF's Y-up metres.
fn fresh_document(scene: &ImportedScene) -> DocBuilder {
    let mut b = DocBuilder::default();
    b.root.insert(
        "asset".into(),
        json!({"version": "2.0", "generator": "springbake"}),
    );
    let mut materials: Vec<String> = Vec::new();
    for m in &scene.meshes {
        for p in &m.primitives {
            if let Some(name) = &p.material {
                if !materials.contains(name) {
                    materials.push(name.clone());
                }
            }
        }
    }
    for name in &materials {
        let look = scene.materials.iter().find(|m| &m.name == name);
        let material = material_json(&mut b, name, look);
        b.push("materials", material);
    }
    for (i, m) in scene.meshes.iter().enumerate() {
        let mut prims = Vec::new();
        for p in &m.primitives {
            let pos = b.vec3(&p.positions, true);
            let normals = p
                .normals
                .clone()
                .unwrap_or_else(|| vertex_normals(&p.positions, &p.indices));
            let nrm = b.vec3(&normals, false);
            let mut attributes = json!({"POSITION": pos, "NORMAL": nrm});
            if let Some(uv) = &p.uvs {
                attributes["TEXCOORD_0"] = json!(b.vec2(uv));
            }
            let mut prim = json!({"attributes": attributes, "indices": b.indices(&p.indices)});
            if let Some(name) = &p.material {
                prim["material"] = json!(materials.iter().position(|n| n == name));
            }
            prims.push(prim);
        }
        b.push("meshes", json!({"name": m.name, "primitives": prims}));
        let mut node = json!({"name": m.name, "mesh": i});
        if m.world_from_local != nalgebra::Matrix4::identity() {
            node["matrix"] = json!(m.world_from_local.as_slice().to_vec());
        }
        b.push("nodes", node);
    }
    let mut roots: Vec<usize> = (0..scene.meshes.len()).collect();
    if scene.up_axis == UpAxis::Z || scene.meters_per_unit != 1.0 {
        let mut root = json!({"name": "springbake_root", "children": roots});
        if scene.up_axis == UpAxis::Z {
            let h = std::f64::consts::FRAC_1_SQRT_2;
            root["rotation"] = json!([-h, 0.0, 0.0, h]); // Z-up → Y-up: (x, y, z) ↦ (x, z, −y)
        }
        if scene.meters_per_unit != 1.0 {
            let s = scene.meters_per_unit;
            root["scale"] = json!([s, s, s]);
        }
        roots = vec![b.push("nodes", root)];
    }
    b.push("scenes", json!({"nodes": roots}));
    b.root.insert("scene".into(), json!(0));
    b
}

/// A glTF material from a source's material description (OBJ's `.mtl`): base colour and
/// alpha, roughness (metallic 0), and the base colour, normal and opacity images embedded in
/// the binary. Without a description, the grey Blender gives a material it knows only by name.
fn material_json(
    b: &mut DocBuilder,
    name: &str,
    look: Option<&springbake_core::display::SurfaceMaterial>,
) -> Value {
    let default = springbake_core::display::SurfaceMaterial::default();
    let look = look.unwrap_or(&default);
    let c = look.base_colour;
    let mut pbr = json!({
        "baseColorFactor": [c[0], c[1], c[2], c[3]],
        "metallicFactor": 0.0,
        "roughnessFactor": look.roughness,
    });
    let mut texture = |image: &springbake_core::display::TextureImage| {
        let view = b.view(&image.bytes, None);
        let img = b.push(
            "images",
            json!({"name": image.name, "bufferView": view, "mimeType": image.mime}),
        );
        b.push("textures", json!({"source": img}))
    };
    if let Some(image) = &look.base_colour_texture {
        pbr["baseColorTexture"] = json!({"index": texture(image)});
    }
    let mut material = json!({"name": name, "pbrMetallicRoughness": pbr});
    if let Some(image) = &look.normal_texture {
        material["normalTexture"] = json!({"index": texture(image)});
    }
    if c[3] < 1.0 || look.opacity_texture.is_some() {
        material["alphaMode"] = json!("BLEND");
    }
    material
}

fn node_mut(b: &mut DocBuilder, node: usize) -> Result<&mut Value, String> {
    b.array_mut("nodes")
        .get_mut(node)
        .ok_or_else(|| format!("nodes[{node}] does not exist"))
}

/// Check the baked node's mesh matches the display mesh, give the node its own copy of a
/// shared mesh, and clear old morph targets / weights. Returns the node's mesh index.
fn prepare_node(b: &mut DocBuilder, node: usize, display: &DisplayMesh) -> Result<usize, String> {
    let mesh = get_usize(node_mut(b, node)?, "mesh")
        .ok_or_else(|| format!("nodes[{node}] has no mesh"))?;
    let json = b
        .array_mut("meshes")
        .get(mesh)
        .cloned()
        .ok_or_else(|| format!("nodes[{node}].mesh refers to a missing mesh"))?;
    let prims = json
        .get("primitives")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    if prims.len() != display.primitives.len() {
        return Err(format!(
            "meshes[{mesh}] has {} primitives, the imported mesh \"{}\" {}: was the source changed?",
            prims.len(),
            display.name,
            display.primitives.len()
        ));
    }
    for (p, (prim, dp)) in prims.iter().zip(&display.primitives).enumerate() {
        let count = prim
            .get("attributes")
            .and_then(|a| get_usize(a, "POSITION"))
            .and_then(|a| b.array_mut("accessors").get(a).cloned())
            .and_then(|a| get_usize(&a, "count"));
        if count != Some(dp.positions.len()) {
            return Err(format!(
                "meshes[{mesh}].primitives[{p}] has {count:?} vertices, the imported mesh {}: \
                 was the source changed?",
                dp.positions.len()
            ));
        }
    }
    let users = b
        .array_mut("nodes")
        .iter()
        .filter(|n| get_usize(n, "mesh") == Some(mesh))
        .count();
    let mesh = if users > 1 {
        let copy = b.push("meshes", json);
        node_mut(b, node)?["mesh"] = json!(copy);
        copy
    } else {
        mesh
    };
    if let Some(o) = b
        .array_mut("meshes")
        .get_mut(mesh)
        .and_then(Value::as_object_mut)
    {
        o.remove("weights");
        if let Some(extras) = o.get_mut("extras").and_then(Value::as_object_mut) {
            extras.remove("targetNames");
        }
        if let Some(prims) = o.get_mut("primitives").and_then(Value::as_array_mut) {
            for prim in prims.iter_mut().filter_map(Value::as_object_mut) {
                prim.remove("targets");
            }
        }
    }
    if let Some(o) = node_mut(b, node)?.as_object_mut() {
        o.remove("weights");
        o.remove("skin");
    }
    Ok(mesh)
}

/// Remove existing animation channels that drive the weights of nodes we bake (their old
/// targets are gone); animations left without channels are dropped.
fn drop_weight_channels(b: &mut DocBuilder, nodes: &[usize]) {
    let Some(anims) = b.root.get_mut("animations").and_then(Value::as_array_mut) else {
        return;
    };
    for a in anims.iter_mut() {
        if let Some(ch) = a.get_mut("channels").and_then(Value::as_array_mut) {
            ch.retain(|c| {
                let t = &c["target"];
                !(t["path"] == "weights"
                    && get_usize(t, "node").is_some_and(|n| nodes.contains(&n)))
            });
        }
    }
    anims.retain(|a| a["channels"].as_array().is_some_and(|c| !c.is_empty()));
    if anims.is_empty() {
        b.root.remove("animations");
    }
}

/// Whether primitive `p` of mesh `mesh` has its own normals.
fn has_normal(b: &mut DocBuilder, mesh: usize, p: usize) -> bool {
    b.array_mut("meshes")[mesh]["primitives"][p]["attributes"]
        .get("NORMAL")
        .is_some()
}

/// Mesh `mesh`, its `extras` made an object (kept when it already is one).
fn mesh_with_extras(b: &mut DocBuilder, mesh: usize) -> &mut Value {
    let m = &mut b.array_mut("meshes")[mesh];
    if !m.get("extras").is_some_and(Value::is_object) {
        m["extras"] = json!({});
    }
    m
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// One morph target per frame on every primitive, and the one-hot weights channel.
fn add_morph(
    b: &mut DocBuilder,
    node: usize,
    mesh: usize,
    display: &DisplayMesh,
    bm: &BakedMesh,
    times: usize,
    anim: &mut Animation,
) -> Result<(), String> {
    let frames = bm.frames.len();
    let mut offset = 0;
    for (p, dp) in display.primitives.iter().enumerate() {
        let n = dp.positions.len();
        let has_normal = has_normal(b, mesh, p);
        let rest_normals = vertex_normals(&dp.positions, &dp.indices);
        let mut targets = Vec::with_capacity(frames);
        for frame in &bm.frames {
            let local = &frame[offset..offset + n];
            let dpos: Vec<[f32; 3]> = local
                .iter()
                .zip(&dp.positions)
                .map(|(&a, &r)| sub(a, r))
                .collect();
            let mut t = json!({"POSITION": b.vec3(&dpos, true)});
            if has_normal {
                // the change of the smooth normal, added to the file's own normals
                let dn: Vec<[f32; 3]> = vertex_normals(local, &dp.indices)
                    .into_iter()
                    .zip(&rest_normals)
                    .map(|(a, &r)| sub(a, r))
                    .collect();
                t["NORMAL"] = json!(b.vec3(&dn, false));
            }
            targets.push(t);
        }
        b.array_mut("meshes")[mesh]["primitives"][p]["targets"] = Value::Array(targets);
        offset += n;
    }
    let names: Vec<String> = (0..frames).map(|f| format!("frame_{f:04}")).collect();
    let m = mesh_with_extras(b, mesh);
    m["weights"] = json!(vec![0.0; frames]);
    m["extras"]["targetNames"] = json!(names);
    let mut one_hot = vec![0.0f32; frames * frames];
    for f in 0..frames {
        one_hot[f * frames + f] = 1.0;
    }
    let output = b.scalars(&one_hot, false);
    anim.add(times, output, node, "weights");
    Ok(())
}

/// The lattice as a skin: joints, inverse bind matrices, 8 influences, translation keys.
fn add_skin(
    b: &mut DocBuilder,
    node: usize,
    mesh: usize,
    display: &DisplayMesh,
    bm: &BakedMesh,
    times: usize,
    anim: &mut Animation,
) -> Result<(), String> {
    let lattice = bm.lattice.as_ref().ok_or("no lattice")?;
    let joints_n = lattice.rest.len();
    // lattice root: the mesh node's local transform, beside it under the same parent
    let mesh_node = node_mut(b, node)?.clone();
    let mut root = json!({"name": format!("{}_lattice", display.name)});
    for key in ["matrix", "translation", "rotation", "scale"] {
        if let Some(v) = mesh_node.get(key) {
            root[key] = v.clone();
        }
    }
    let first_joint = b.array_mut("nodes").len() + 1;
    root["children"] = json!((first_joint..first_joint + joints_n).collect::<Vec<_>>());
    let root_index = b.push("nodes", root);
    let parent = b.array_mut("nodes").iter().position(|n| {
        n["children"]
            .as_array()
            .is_some_and(|c| c.iter().any(|c| c.as_u64() == Some(node as u64)))
    });
    match parent {
        Some(p) => b.array_mut("nodes")[p]["children"]
            .as_array_mut()
            .ok_or("parent children")?
            .push(json!(root_index)),
        None => {
            for s in b.array_mut("scenes").iter_mut() {
                if let Some(ns) = s.get_mut("nodes").and_then(Value::as_array_mut) {
                    if ns.iter().any(|n| n.as_u64() == Some(node as u64)) {
                        ns.push(json!(root_index));
                    }
                }
            }
        }
    }
    let mut ibm = Vec::with_capacity(joints_n);
    for (j, r) in lattice.rest.iter().enumerate() {
        b.push(
            "nodes",
            json!({"name": format!("{}_lattice_{j}", display.name), "translation": r}),
        );
        let mut m = [0.0f32; 16];
        m[0] = 1.0;
        m[5] = 1.0;
        m[10] = 1.0;
        m[15] = 1.0;
        m[12] = -r[0];
        m[13] = -r[1];
        m[14] = -r[2];
        ibm.push(m);
    }
    let ibm_accessor = b.mat4(&ibm);
    let skin = b.push(
        "skins",
        json!({"name": format!("{}_lattice", display.name), "joints": (first_joint..first_joint + joints_n).collect::<Vec<_>>(),
               "inverseBindMatrices": ibm_accessor, "skeleton": root_index}),
    );
    node_mut(b, node)?["skin"] = json!(skin);
    let mut offset = 0;
    for (p, dp) in display.primitives.iter().enumerate() {
        let n = dp.positions.len();
        let (mut j0, mut j1, mut w0, mut w1) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for v in offset..offset + n {
            let (js, ws) = influences(lattice.vertex_nodes[v], lattice.vertex_weights[v])
                .ok_or_else(|| format!("vertex {v}: lattice weights are not positive"))?;
            j0.push([js[0], js[1], js[2], js[3]]);
            j1.push([js[4], js[5], js[6], js[7]]);
            w0.push([ws[0], ws[1], ws[2], ws[3]]);
            w1.push([ws[4], ws[5], ws[6], ws[7]]);
        }
        let a = [
            b.joints(&j0, joints_n),
            b.vec4(&w0),
            b.joints(&j1, joints_n),
            b.vec4(&w1),
        ];
        let attrs = &mut b.array_mut("meshes")[mesh]["primitives"][p]["attributes"];
        attrs["JOINTS_0"] = json!(a[0]);
        attrs["WEIGHTS_0"] = json!(a[1]);
        attrs["JOINTS_1"] = json!(a[2]);
        attrs["WEIGHTS_1"] = json!(a[3]);
        offset += n;
    }
    for j in 0..joints_n {
        let keys: Vec<[f32; 3]> = lattice.frames.iter().map(|f| f[j]).collect();
        let output = b.vec3_keys(&keys);
        anim.add(times, output, first_joint + j, "translation");
    }
    Ok(())
}

/// Merge duplicate nodes, clamp negative weights, normalize so the f32 weights sum to 1, and
/// give zero-weight slots distinct unused joints. `None` when no weight is positive.
fn influences(nodes: [u32; 8], weights: [f32; 8]) -> Option<([u16; 8], [f32; 8])> {
    let mut merged: Vec<(u32, f64)> = Vec::with_capacity(8);
    for (&j, &w) in nodes.iter().zip(&weights) {
        let w = if w.is_finite() {
            (w as f64).max(0.0)
        } else {
            0.0
        };
        match merged.iter_mut().find(|(k, _)| *k == j) {
            Some(slot) => slot.1 += w,
            None => merged.push((j, w)),
        }
    }
    merged.retain(|&(_, w)| w > 0.0);
    let sum: f64 = merged.iter().map(|m| m.1).sum();
    if merged.is_empty() || sum <= 0.0 {
        return None;
    }
    // largest first, ties by joint index: deterministic
    merged.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut js = [0u16; 8];
    let mut ws = [0f32; 8];
    for (k, &(j, w)) in merged.iter().enumerate() {
        js[k] = j as u16;
        ws[k] = (w / sum) as f32;
    }
    let total: f32 = ws.iter().sum();
    ws[0] += 1.0 - total;
    let mut next = 0u16;
    for slot in js.iter_mut().skip(merged.len()) {
        while merged.iter().any(|&(j, _)| j == next as u32) {
            next += 1;
        }
        *slot = next;
        next += 1;
    }
    Some((js, ws))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn influences_merge_clamp_and_normalize() {
        let (js, ws) = influences(
            [5, 5, 2, 3, 4, 6, 7, 8],
            [0.2, 0.2, -0.1, 0.1, 0.1, 0.1, 0.2, 0.2],
        )
        .unwrap();
        assert_eq!(js[0], 5, "duplicates merged into the largest weight");
        let sum: f32 = ws.iter().sum();
        assert!((sum - 1.0).abs() < 1e-7);
        assert!(ws.iter().all(|&w| w >= 0.0));
        // node 2 had a negative weight: it is dropped and its slot gets an unused joint
        assert_eq!(ws[6..], [0.0, 0.0]);
        assert_eq!(js[6..], [0, 1], "padding uses the lowest unused joints");
        let mut sorted = js.to_vec();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), 8, "no duplicate joints: {js:?}");
        assert!(influences([0; 8], [0.0; 8]).is_none());
    }

    #[test]
    fn uri_encoding_of_the_bin_name() {
        assert_eq!(uri_encode("my bake.bin"), "my%20bake.bin");
        assert_eq!(uri_encode("a_b-c.bin"), "a_b-c.bin");
    }

    #[test]
    fn non_glb_output_is_refused() {
        let scene = ImportedScene {
            materials: Vec::new(),
            notes: Vec::new(),
            meshes: vec![],
            up_axis: UpAxis::Y,
            meters_per_unit: 1.0,
            source: springbake_core::display::SourceDocument {
                path: Path::new("x.obj").into(),
                importer: "obj".into(),
                read_root: None,
            },
        };
        let baked = BakedScene {
            particles: Vec::new(),
            fps: 24.0,
            frame_count: 1,
            meshes: vec![],
            stage: None,
        };
        let settings = ExportSettings {
            path: "out.usd".into(),
            cache: CacheKind::Morph,
            axes: Default::default(),
        };
        assert!(GltfExporter.export(&scene, &baked, &settings).is_err());
    }
}
