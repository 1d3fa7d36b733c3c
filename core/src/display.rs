//! The display model: triangle meshes as the artist made them, independent of any file format.
//!
//! Importers produce an [`ImportedScene`]; the solver reads world-space positions from it; the
//! exporters write baked frames back into the same meshes. Positions are stored in each mesh's
//! local frame, exactly as in the source file, with `world_from_local` placing them in the
//! source's world (in source units; multiply by `meters_per_unit` for metres).

use nalgebra::{Matrix4, Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Which source axis points up. glTF and OBJ are +Y up; Blender's USD export is +Z up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    #[default]
    Y,
    Z,
}

impl UpAxis {
    /// Unit vector of the up direction in source world coordinates.
    pub fn vector(self) -> Vector3<f64> {
        match self {
            UpAxis::Y => Vector3::y(),
            UpAxis::Z => Vector3::z(),
        }
    }

    /// Index of the up component (1 for Y, 2 for Z).
    pub fn index(self) -> usize {
        match self {
            UpAxis::Y => 1,
            UpAxis::Z => 2,
        }
    }
}

/// One indexed triangle list with its vertex attributes, as one glTF primitive / one OBJ
/// material group / one USD mesh subset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Primitive {
    /// Vertex positions in the mesh's local frame, source units.
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals in the local frame, when the source had them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Per-vertex texture coordinates (first set), when the source had them.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Triangle list: three indices into `positions` per triangle.
    pub indices: Vec<u32>,
    /// Material name, when the source named one.
    pub material: Option<String>,
}

impl Primitive {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A mesh placed in the scene: the unit the solver simulates as one body.
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayMesh {
    /// Human-readable name (node or object name).
    pub name: String,
    /// Handle the exporter of the same format uses to find this mesh in the source document:
    /// glTF `"node:<index>"`, USD the prim path, OBJ `"object:<index>"`.
    pub source_key: String,
    /// Places local positions in the source's world frame (source units).
    pub world_from_local: Matrix4<f64>,
    pub primitives: Vec<Primitive>,
    /// For each vertex (primitive after primitive) the index of the point it came from in the
    /// source's own vertex list: OBJ `v` lines of this object, USD `points`, glTF the vertex
    /// itself. Caches that must follow the source's vertex order (PC2, MDD, USD `points`) write
    /// one point per source point through this map. Empty means identity.
    pub source_point_of_vertex: Vec<u32>,
    /// Number of points in the source's own vertex list (the vertex count when the map is empty).
    pub source_point_count: usize,
}

impl DisplayMesh {
    /// Total vertex count over all primitives.
    pub fn vertex_count(&self) -> usize {
        self.primitives.iter().map(|p| p.positions.len()).sum()
    }

    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(Primitive::triangle_count).sum()
    }

    /// Scatter per-vertex values (primitive after primitive) into the source's point order.
    /// Points no vertex refers to keep `fill`.
    pub fn to_source_points<T: Copy>(&self, per_vertex: &[T], fill: T) -> Vec<T> {
        if self.source_point_of_vertex.is_empty() {
            return per_vertex.to_vec();
        }
        let mut out = vec![fill; self.source_point_count];
        for (v, &p) in self.source_point_of_vertex.iter().enumerate() {
            if let (Some(slot), Some(&value)) = (out.get_mut(p as usize), per_vertex.get(v)) {
                *slot = value;
            }
        }
        out
    }

    /// All vertices, primitive after primitive, in world coordinates (source units).
    pub fn world_positions(&self) -> Vec<Point3<f64>> {
        let m = self.world_from_local;
        self.primitives
            .iter()
            .flat_map(|p| p.positions.iter())
            .map(|q| m.transform_point(&Point3::new(q[0] as f64, q[1] as f64, q[2] as f64)))
            .collect()
    }

    /// All triangles as indices into [`DisplayMesh::world_positions`].
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::with_capacity(self.triangle_count());
        let mut base = 0u32;
        for p in &self.primitives {
            out.extend(
                p.indices
                    .chunks_exact(3)
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
            base += p.positions.len() as u32;
        }
        out
    }
}

/// Which file a scene came from, so an exporter of the same format can keep the source document.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceDocument {
    pub path: PathBuf,
    /// Name of the importer that read it (`"gltf"`, `"obj"`, `"usd"`).
    pub importer: String,
    /// The folder tree the source's dependencies had to lie in at import
    /// ([`crate::plugin::ImportSettings::root`]); an exporter that re-reads the source (USD)
    /// keeps to it. `None`: the source's own folder.
    pub read_root: Option<PathBuf>,
}

/// Everything an importer hands over.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedScene {
    pub meshes: Vec<DisplayMesh>,
    pub up_axis: UpAxis,
    /// Size of one source unit in metres (glTF: 1; USD: the stage's metersPerUnit).
    pub meters_per_unit: f64,
    pub source: SourceDocument,
    /// How the materials the primitives name look, for sources whose own document an exporter
    /// does not re-read (OBJ's `.mtl`); glTF and USD exporters keep the source's materials.
    pub materials: Vec<SurfaceMaterial>,
    /// What the importer left out and the user should hear about (a missing `.mtl`).
    pub notes: Vec<String>,
}

impl ImportedScene {
    /// The source's world (source units, its up axis) to Y-up metres, the frame of glTF,
    /// Alembic and the vertex animation textures: a Z-up world turns `(x, y, z) → (x, z, −y)`.
    pub fn y_up_metres_from_world(&self) -> Matrix4<f64> {
        let axes = match self.up_axis {
            UpAxis::Y => Matrix4::identity(),
            UpAxis::Z => Matrix4::new(
                1.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 1.0, 0.0, //
                0.0, -1.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ),
        };
        axes * Matrix4::new_scaling(self.meters_per_unit)
    }
}

/// A material's look, as a metallic-roughness surface (what glTF and USD preview surfaces
/// hold).
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMaterial {
    pub name: String,
    /// Linear RGB and alpha.
    pub base_colour: [f32; 4],
    pub roughness: f32,
    pub base_colour_texture: Option<TextureImage>,
    pub normal_texture: Option<TextureImage>,
    pub opacity_texture: Option<TextureImage>,
}

impl Default for SurfaceMaterial {
    fn default() -> Self {
        SurfaceMaterial {
            name: String::new(),
            base_colour: [0.8, 0.8, 0.8, 1.0],
            roughness: 0.5,
            base_colour_texture: None,
            normal_texture: None,
            opacity_texture: None,
        }
    }
}

/// An image file a material uses, as read (PNG or JPEG).
#[derive(Debug, Clone, PartialEq)]
pub struct TextureImage {
    /// The file name as the source wrote it.
    pub name: String,
    /// `image/png` or `image/jpeg`.
    pub mime: String,
    pub bytes: Vec<u8>,
}

/// Smooth per-vertex normals of a triangle list (area weighted), for meshes without normals
/// and for the NORMAL deltas of baked frames.
pub fn vertex_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[f32; 3]> {
    let mut acc = vec![Vector3::<f64>::zeros(); positions.len()];
    let p = |i: u32| {
        let q = positions[i as usize];
        Vector3::new(q[0] as f64, q[1] as f64, q[2] as f64)
    };
    for t in indices.chunks_exact(3) {
        let n = (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0])));
        for &i in t {
            acc[i as usize] += n;
        }
    }
    acc.into_iter()
        .map(|n| {
            let len = n.norm();
            if len > 0.0 {
                [(n.x / len) as f32, (n.y / len) as f32, (n.z / len) as f32]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(up_axis: UpAxis, meters_per_unit: f64) -> ImportedScene {
        ImportedScene {
            meshes: Vec::new(),
            up_axis,
            meters_per_unit,
            source: SourceDocument {
                path: PathBuf::from("s.usda"),
                importer: "usd".into(),
                read_root: None,
            },
            materials: Vec::new(),
            notes: Vec::new(),
        }
    }

    #[test]
    fn z_up_centimetres_become_y_up_metres() {
        let m = scene(UpAxis::Z, 0.01).y_up_metres_from_world();
        let p = m.transform_point(&Point3::new(100.0, 200.0, 300.0));
        assert!((p - Point3::new(1.0, 3.0, -2.0)).norm() < 1e-12, "{p}");
        assert_eq!(
            scene(UpAxis::Y, 1.0).y_up_metres_from_world(),
            Matrix4::identity()
        );
    }
}
