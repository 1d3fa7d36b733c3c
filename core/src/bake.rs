//! Baked animation: what the simulation hands to exporters.

/// The baked frames of one simulated mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct BakedMesh {
    /// Index into [`crate::display::ImportedScene::meshes`].
    pub mesh_index: usize,
    /// One entry per output frame: every vertex (primitive after primitive, in source order) in
    /// the mesh's *local* frame and source units, ready to be written where the source had it.
    pub frames: Vec<Vec<[f32; 3]>>,
    /// Lattice nodes per frame in the same local frame, and the embedding (8 node indices and
    /// trilinear weights per vertex), for caches that skin the mesh to the lattice.
    pub lattice: Option<BakedLattice>,
}

/// The analysis lattice of one mesh over the bake, for the lattice-as-skin cache.
#[derive(Debug, Clone, PartialEq)]
pub struct BakedLattice {
    /// Rest positions of the nodes, local frame, source units.
    pub rest: Vec<[f32; 3]>,
    /// Node positions per frame, local frame, source units.
    pub frames: Vec<Vec<[f32; 3]>>,
    /// Per vertex: the 8 corner nodes of its cell and their trilinear weights.
    pub vertex_nodes: Vec<[u32; 8]>,
    pub vertex_weights: Vec<[f32; 8]>,
}

/// The whole bake.
#[derive(Debug, Clone, PartialEq)]
pub struct BakedScene {
    pub fps: f64,
    pub frame_count: usize,
    pub meshes: Vec<BakedMesh>,
}

impl BakedScene {
    /// Time of frame `i` (0-based) in seconds.
    pub fn frame_time(&self, i: usize) -> f64 {
        i as f64 / self.fps
    }
}
