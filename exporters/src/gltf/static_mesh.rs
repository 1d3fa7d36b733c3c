//! One unanimated triangle mesh as a GLB: the rest mesh of vertex animation textures, a
//! polygonised superquadric model (`springbake model`).

use super::builder::DocBuilder;
use serde_json::json;

/// One triangle mesh, Y-up metres.
pub struct StaticMesh<'a> {
    pub name: &'a str,
    pub positions: &'a [[f32; 3]],
    pub normals: &'a [[f32; 3]],
    /// TEXCOORD_0 and TEXCOORD_1, one per vertex, when given.
    pub uv0: Option<&'a [[f32; 2]]>,
    pub uv1: Option<&'a [[f32; 2]]>,
    pub indices: &'a [u32],
}

/// A GLB of one node with `mesh` and a plain material.
pub fn static_glb(mesh: &StaticMesh) -> Vec<u8> {
    let mut doc = DocBuilder::default();
    let position = doc.vec3(mesh.positions, true);
    let normal = doc.vec3(mesh.normals, false);
    let indices = doc.indices(mesh.indices);
    let mut attributes = json!({"POSITION": position, "NORMAL": normal});
    if let Some(uv) = mesh.uv0 {
        attributes["TEXCOORD_0"] = json!(doc.vec2(uv));
    }
    if let Some(uv) = mesh.uv1 {
        attributes["TEXCOORD_1"] = json!(doc.vec2(uv));
    }
    doc.push(
        "materials",
        json!({"name": mesh.name, "pbrMetallicRoughness": {"metallicFactor": 0.0}}),
    );
    doc.push(
        "meshes",
        json!({"name": mesh.name, "primitives": [
            {"attributes": attributes, "indices": indices, "material": 0}
        ]}),
    );
    doc.push("nodes", json!({"name": mesh.name, "mesh": 0}));
    doc.push("scenes", json!({"nodes": [0]}));
    doc.root.insert("scene".into(), json!(0));
    doc.root.insert(
        "asset".into(),
        json!({"version": "2.0", "generator": concat!("springbake ", env!("CARGO_PKG_VERSION"))}),
    );
    doc.into_glb()
}
