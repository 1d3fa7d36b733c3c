//! The Alembic exporter (`.abc`, Ogawa): what VFX pipelines (Maya, Houdini, Cinema 4D,
//! Unreal's Geometry Cache, Blender) exchange baked deformation as.
//!
//! Written through `alembic3d`, the PyAlembic bindings on PyPI, in the same embedded Python
//! and virtual environment as usd-core (`alembic_bridge.py`): the reference library writes the
//! archive, so no Ogawa writer is kept here.
//!
//! Layout: one `Xform` per baked mesh (its placement, constant) with one `PolyMesh` child
//! (`<name>Shape`): the source's own points (OBJ `v` lines, USD `points`, glTF vertices; see
//! [`DisplayMesh::to_source_points`]) sampled once per frame, the triangles with face-varying
//! UVs and normals where the source had them, normals re-computed per frame from the deformed
//! surface (hard edges stay where the source split its vertices). Time sampling: uniform,
//! `1/fps` per sample from time 0, so sample `i` is baked frame `i` at `i / fps` seconds.
//!
//! Axes and units: Alembic has neither, and its readers take it as Y-up; Blender and Houdini
//! read one unit as one metre. So the `Xform` holds `axes · metersPerUnit · world_from_local`:
//! a Z-up source is turned Y-up (`(x, y, z) → (x, z, −y)`), and source units become metres.
//! Winding: Alembic's faces are clockwise seen from outside (Blender and Maya reverse each
//! face on import), so every triangle is written reversed, with its face-varying data.

use crate::export::{checked_meshes, prim_name};
use crate::python::{
    f32_bytes, i32_bytes, plugin_error, through_temp_file, with_bridge_of, Bridge,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::{vertex_normals, DisplayMesh, ImportedScene};
use springbake_core::plugin::{ExportSettings, Exporter, IoErrorKind, OutputFile, PluginError};
use std::collections::HashSet;
use std::path::Path;
use std::sync::OnceLock;

/// alembic3d's bridge (`alembic_bridge.py`).
static ALEMBIC_BRIDGE: Bridge = Bridge {
    source: include_str!("alembic_bridge.py"),
    file_name: c"alembic_bridge.py",
    module_name: c"springbake_alembic_bridge",
    requires: "alembic3d",
    package: "alembic3d",
    package_role: "Python's alembic3d (PyAlembic bindings)",
    loaded: OnceLock::new(),
};

/// One mesh as the bridge writes it: flat little-endian arrays.
struct ArchiveMesh {
    point_count: usize,
    /// f32 × 3 × points per frame.
    points: Vec<u8>,
    /// i32 per corner, each triangle reversed.
    indices: Vec<u8>,
    counts: Vec<u8>,
    /// f32 × 2 per corner, when every primitive has UVs.
    uvs: Option<Vec<u8>>,
    /// f32 × 3 per corner per frame, when the source had normals.
    normals: Option<Vec<u8>>,
    corner_count: usize,
}

fn archive_mesh(baked: &BakedMesh, mesh: &DisplayMesh) -> ArchiveMesh {
    // Reversed winding: Alembic's front faces are clockwise.
    let corners: Vec<u32> = mesh
        .triangles()
        .into_iter()
        .flat_map(|[a, b, c]| [a, c, b])
        .collect();
    let point_of = |v: u32| -> i32 {
        mesh.source_point_of_vertex
            .get(v as usize)
            .map_or(v as i32, |&p| p as i32)
    };
    let point_count = if mesh.source_point_of_vertex.is_empty() {
        mesh.vertex_count()
    } else {
        mesh.source_point_count
    };
    let mut points = Vec::with_capacity(baked.frames.len() * point_count * 12);
    for frame in &baked.frames {
        let pts = mesh.to_source_points(frame, [0.0f32; 3]);
        points.extend(f32_bytes(pts.iter().flatten().copied()));
    }
    let uvs = mesh.primitives.iter().all(|p| p.uvs.is_some()).then(|| {
        let per_vertex: Vec<[f32; 2]> = mesh
            .primitives
            .iter()
            .flat_map(|p| p.uvs.iter().flatten().copied())
            .collect();
        f32_bytes(
            corners
                .iter()
                .flat_map(|&v| per_vertex.get(v as usize).copied().unwrap_or_default()),
        )
    });
    let had_normals = mesh.primitives.iter().any(|p| p.normals.is_some());
    let normals = had_normals.then(|| {
        let triangles: Vec<u32> = mesh.triangles().into_iter().flatten().collect();
        let mut bytes = Vec::with_capacity(baked.frames.len() * corners.len() * 12);
        for frame in &baked.frames {
            let n = vertex_normals(frame, &triangles);
            bytes.extend(f32_bytes(corners.iter().flat_map(|&v| {
                n.get(v as usize).copied().unwrap_or([0.0, 0.0, 1.0])
            })));
        }
        bytes
    });
    ArchiveMesh {
        point_count,
        points,
        indices: i32_bytes(corners.iter().map(|&v| point_of(v))),
        counts: i32_bytes(corners.chunks_exact(3).map(|_| 3)),
        uvs,
        normals,
        corner_count: corners.len(),
    }
}

/// Writes baked frames as an Alembic archive.
#[derive(Debug, Default, Clone, Copy)]
pub struct AlembicExporter;

impl AlembicExporter {
    fn write(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        out: &Path,
        temp: &Path,
    ) -> Result<(), PluginError> {
        let to_alembic = scene.y_up_metres_from_world();
        let mut taken = HashSet::new();
        let mut meshes = Vec::new();
        for (bm, mesh) in checked_meshes(scene, baked, out)? {
            let world = to_alembic * mesh.world_from_local;
            meshes.push((
                prim_name(&mesh.name, &mut taken),
                world,
                archive_mesh(bm, mesh),
            ));
        }
        with_bridge_of(&ALEMBIC_BRIDGE, out, |py, bridge| {
            let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Io, out);
            let list = PyList::empty(py);
            for (name, world, m) in &meshes {
                let d = PyDict::new(py);
                let bytes = |b: &[u8]| PyBytes::new(py, b);
                // nalgebra is column-major: its columns are Imath's rows (row vectors).
                let world: Vec<u8> = world
                    .as_slice()
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect();
                d.set_item("name", name).map_err(to_err)?;
                d.set_item("world", bytes(&world)).map_err(to_err)?;
                d.set_item("point_count", m.point_count).map_err(to_err)?;
                d.set_item("corner_count", m.corner_count).map_err(to_err)?;
                d.set_item("points", bytes(&m.points)).map_err(to_err)?;
                d.set_item("indices", bytes(&m.indices)).map_err(to_err)?;
                d.set_item("counts", bytes(&m.counts)).map_err(to_err)?;
                d.set_item("uvs", m.uvs.as_deref().map(bytes))
                    .map_err(to_err)?;
                d.set_item("normals", m.normals.as_deref().map(bytes))
                    .map_err(to_err)?;
                list.append(d).map_err(to_err)?;
            }
            let spec = PyDict::new(py);
            spec.set_item("meshes", list).map_err(to_err)?;
            spec.set_item("fps", baked.fps).map_err(to_err)?;
            spec.set_item("frame_count", baked.frame_count)
                .map_err(to_err)?;
            bridge
                .call_method1("write_archive", (temp.to_string_lossy().into_owned(), spec))
                .map_err(to_err)?;
            Ok(())
        })
    }
}

impl Exporter for AlembicExporter {
    fn name(&self) -> &str {
        "alembic"
    }

    fn extensions(&self) -> &[&str] {
        &["abc"]
    }

    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        let out = settings.path.as_path();
        let bytes = through_temp_file(out, "baked.abc", "alembic3d", |temp| {
            self.write(scene, baked, out, temp)
        })?;
        Ok(vec![OutputFile {
            path: out.to_path_buf(),
            bytes,
        }])
    }
}
