//! What a bake replaces in a source glTF whose first frame the importer posed (issue 19
//! item 4; `springbake_importers::gltf::pose`): a skinned node keeps its node but not its
//! skin, its mesh gets the posed positions and normals in place of the bind pose and loses
//! its joint attributes; a mesh with morph targets gets its first-frame shape as its base.
//! The animation that posed the bodies (the channels driving the baked nodes, their
//! ancestors and the removed skins' joints) is dropped, its first-frame values kept as the
//! nodes' static transforms, so the output's rest is what was simulated; skins no node uses
//! are removed.

use super::builder::DocBuilder;
use serde_json::{json, Value};
use springbake_core::display::DisplayMesh;
use springbake_importers::gltf::document::get_usize;
use springbake_importers::gltf::pose::{pose_at_start, StartValue};

/// How the importer posed a node: its skin (read before the node is prepared) and whether
/// its mesh has morph targets.
#[derive(Debug, Clone, Copy, Default)]
pub struct Posing {
    pub skin: Option<usize>,
    pub targets: bool,
}

impl Posing {
    /// `node`'s posing in the source document (call before the node is prepared).
    pub fn of(b: &mut DocBuilder, node: usize) -> Posing {
        let json = b
            .array_mut("nodes")
            .get(node)
            .cloned()
            .unwrap_or(Value::Null);
        let targets = get_usize(&json, "mesh")
            .and_then(|m| b.array_mut("meshes").get(m).cloned())
            .and_then(|m| m["primitives"].as_array().cloned())
            .is_some_and(|p| p.iter().any(|p| p.get("targets").is_some()));
        Posing {
            skin: get_usize(&json, "skin"),
            targets,
        }
    }

    fn posed(&self) -> bool {
        self.skin.is_some() || self.targets
    }
}

/// The posed geometry as `mesh`'s base: POSITION (and NORMAL where the primitive has
/// normals) from `display`, the joint attributes dropped with the skin.
pub fn write_posed_geometry(
    b: &mut DocBuilder,
    mesh: usize,
    display: &DisplayMesh,
    posing: Posing,
) {
    if !posing.posed() {
        return;
    }
    for (p, dp) in display.primitives.iter().enumerate() {
        let position = b.vec3(&dp.positions, true);
        let normal = match (&dp.normals, has_attribute(b, mesh, p, "NORMAL")) {
            (Some(n), true) => Some(b.vec3(n, false)),
            _ => None,
        };
        let Some(attributes) =
            b.array_mut("meshes")[mesh]["primitives"][p]["attributes"].as_object_mut()
        else {
            continue;
        };
        attributes.insert("POSITION".into(), json!(position));
        if let Some(n) = normal {
            attributes.insert("NORMAL".into(), json!(n));
        }
        if posing.skin.is_some() {
            attributes.retain(|k, _| !k.starts_with("JOINTS_") && !k.starts_with("WEIGHTS_"));
        }
    }
}

fn has_attribute(b: &mut DocBuilder, mesh: usize, p: usize, name: &str) -> bool {
    b.array_mut("meshes")[mesh]["primitives"][p]["attributes"]
        .get(name)
        .is_some()
}

/// Drops the animation that posed the baked nodes (module docs) and the skins no node uses.
/// `skins`: the skins the baked nodes had.
pub fn drop_posing(
    b: &mut DocBuilder,
    baked_nodes: &[usize],
    skins: &[usize],
    starts: &[StartValue],
) {
    let nodes = b.array_mut("nodes").to_vec();
    let mut parent = vec![None; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        for c in n["children"].as_array().into_iter().flatten() {
            if let Some(slot) = c.as_u64().and_then(|c| parent.get_mut(c as usize)) {
                *slot = Some(i);
            }
        }
    }
    let mut posed = vec![false; nodes.len()];
    for &n in baked_nodes {
        let mut at = Some(n);
        while let Some(i) = at.filter(|&i| i < posed.len()) {
            posed[i] = true;
            at = parent[i];
        }
    }
    let skin_list = b
        .root
        .get("skins")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    for &s in skins {
        for j in skin_list
            .get(s)
            .and_then(|s| s["joints"].as_array())
            .into_iter()
            .flatten()
        {
            if let Some(slot) = j.as_u64().and_then(|j| posed.get_mut(j as usize)) {
                *slot = true;
            }
        }
    }
    let is_posed = |n: usize| posed.get(n).copied().unwrap_or(false);
    let kept: Vec<StartValue> = starts
        .iter()
        .filter(|s| s.path != "weights" && is_posed(s.node))
        .cloned()
        .collect();
    let mut root = Value::Object(std::mem::take(&mut b.root));
    pose_at_start(&mut root, &kept);
    if let Value::Object(map) = root {
        b.root = map;
    }
    drop_channels(b, |node, path| path != "weights" && is_posed(node));
    drop_unused_skins(b);
}

/// Removes the channels `drop(node, path)` selects from every animation, and animations left
/// with none (their samplers stay, unused).
fn drop_channels(b: &mut DocBuilder, drop: impl Fn(usize, &str) -> bool) {
    let Some(animations) = b.root.get_mut("animations").and_then(Value::as_array_mut) else {
        return;
    };
    for a in animations.iter_mut() {
        if let Some(channels) = a.get_mut("channels").and_then(Value::as_array_mut) {
            channels.retain(|c| {
                let t = &c["target"];
                match (get_usize(t, "node"), t["path"].as_str()) {
                    (Some(node), Some(path)) => !drop(node, path),
                    _ => true,
                }
            });
        }
    }
    animations.retain(|a| a["channels"].as_array().is_some_and(|c| !c.is_empty()));
    if animations.is_empty() {
        b.root.remove("animations");
    }
}

/// Removes the skins no node refers to, renumbering the nodes' `skin`.
fn drop_unused_skins(b: &mut DocBuilder) {
    let count = match b.root.get("skins") {
        Some(Value::Array(skins)) if !skins.is_empty() => skins.len(),
        _ => return,
    };
    let mut used = vec![false; count];
    for n in b.array_mut("nodes").iter() {
        if let Some(slot) = get_usize(n, "skin").and_then(|s| used.get_mut(s)) {
            *slot = true;
        }
    }
    let mut new_index = vec![0; count];
    let mut next = 0;
    for (i, &u) in used.iter().enumerate() {
        new_index[i] = next;
        next += usize::from(u);
    }
    for n in b.array_mut("nodes").iter_mut() {
        if let Some(s) = get_usize(n, "skin") {
            n["skin"] = json!(new_index.get(s).copied().unwrap_or(s));
        }
    }
    let mut i = 0;
    b.array_mut("skins").retain(|_| {
        i += 1;
        used[i - 1]
    });
    if next == 0 {
        b.root.remove("skins");
    }
}
