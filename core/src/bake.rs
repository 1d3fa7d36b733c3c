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
    /// What the bodies moved against (floor, manipulators), for players that show it.
    pub stage: Option<BakedStage>,
    /// The particle effects, per emitter (empty without `[[emitter]]`s).
    pub particles: Vec<BakedParticles>,
}

/// One emitter's particles over the bake, in Y-up metres (glTF's world frame, like the
/// stage); exporters turn them into their own frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BakedParticles {
    pub name: String,
    /// Drawn as streaks along their motion too (a fountain's water).
    pub streaks: bool,
    /// One per output frame.
    pub frames: Vec<crate::particles::ParticleFrame>,
}

/// The rigid surroundings of a bake, in Y-up metres (glTF's world frame): what a viewer draws
/// around the baked meshes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BakedStage {
    /// Floor height (along +Y), metres.
    pub floor: Option<f64>,
    pub capsules: Vec<BakedCapsule>,
    /// Static colliders: triangle meshes.
    pub colliders: Vec<BakedCollider>,
    /// The room's side walls (`[world.walls]`): the box's lowest and highest corner, Y-up
    /// metres; its vertical extent is not used.
    pub walls: Option<[[f64; 3]; 2]>,
}

/// The room box of a world's side-wall planes (every plane but the floor, whose normal is
/// `up`): per horizontal axis the `+axis` plane's offset is the low side, the `−axis` plane's
/// the high side; `None` without walls. Frame of the planes.
pub fn room_of(
    planes: &[crate::solver::Plane],
    up: &nalgebra::Vector3<f64>,
) -> Option<[[f64; 3]; 2]> {
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    let mut any = false;
    for p in planes {
        if (p.normal - up).norm() < 1e-9 {
            continue;
        }
        let axis = p.normal.iamax();
        if p.normal[axis] > 0.0 {
            lo[axis] = p.offset;
        } else {
            hi[axis] = -p.offset;
        }
        any = true;
    }
    any.then_some([lo, hi])
}

/// A static collider's surface.
#[derive(Debug, Clone, PartialEq)]
pub struct BakedCollider {
    pub name: String,
    pub positions: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// A capsule manipulator over the bake.
#[derive(Debug, Clone, PartialEq)]
pub struct BakedCapsule {
    pub radius: f64,
    /// Length of the axis segment between the cap centres, metres.
    pub length: f64,
    /// Per output frame: the axis segment's centre and unit direction.
    pub frames: Vec<([f64; 3], [f64; 3])>,
}

impl BakedScene {
    /// Time of frame `i` (0-based) in seconds.
    pub fn frame_time(&self, i: usize) -> f64 {
        i as f64 / self.fps
    }
}
