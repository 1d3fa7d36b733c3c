//! What the viewer shows: a scene file or a bare mesh prepared through the pipeline and
//! simulated frame by frame ([`Simulation`]), or a baked glTF with morph-target frames played
//! back ([`BakedPlayback`]: frame N applies the weights of the N-th key of the file's `weights`
//! animation to the morph targets). A glTF without morph targets is a mesh to simulate. A
//! lattice-skin glTF is drawn in its rest pose (skinning is not evaluated).

use crate::raster::{
    capsule_mesh, particle_octahedra, rods, wall_meshes, DrawMesh, BODY_COLOUR, CAPSULE_COLOUR,
    COLLIDER_COLOUR, CONTACT_COLOUR, LATTICE_COLOUR,
};
use crate::ViewerError;
use serde_json::Value;
use springbake_core::display::UpAxis;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::plugin::{ImportSettings, Importer, PluginError, Registry};
use springbake_core::solver::Capsule;
use springbake_importers::gltf::accessor::read_floats;
use springbake_importers::gltf::document::{get_usize, load_document, GltfDocument};
use springbake_importers::gltf::GltfImporter;
use springbake_pipeline::effects::Effects;
use springbake_pipeline::{LoadedScene, MeshOverrides, Prepared, Seconds};
use std::path::Path;

/// A prepared world stepped one output frame at a time.
pub struct Simulation {
    pub loaded: LoadedScene,
    pub prepared: Prepared,
    /// Triangles of each body's display mesh (indices into its vertex positions).
    pub triangles: Vec<Vec<[u32; 3]>>,
    /// 1-based output frame the world is at (1 = the initial state).
    pub frame: usize,
    /// The scene's particle effects, stepped with the world (events do not start emitters
    /// here: the viewer does not run the scene's events).
    effects: Effects,
    /// Each body's base-colour texture over its UVs, when its material has one.
    textures: Vec<Option<std::sync::Arc<crate::raster::TexturedSurface>>>,
}

impl Simulation {
    /// Import, fit and build the world for `loaded`.
    pub fn new(registry: &Registry, loaded: LoadedScene) -> Result<Simulation, ViewerError> {
        let mut prepared =
            springbake_pipeline::prepare(registry, &loaded, &mut Seconds::default())?;
        eprintln!("springbake: note: {}", prepared.device.describe());
        for text in springbake_pipeline::budget::interpenetrating_parts_notes(&mut prepared) {
            eprintln!("springbake: note: {text}");
        }
        for text in springbake_pipeline::budget::held_bodies_notes(&mut prepared) {
            eprintln!("springbake: note: {text}");
        }
        let fps = loaded.scene.output.fps;
        for text in springbake_pipeline::budget::under_resolved_notes(&prepared, fps) {
            eprintln!("springbake: note: {text}");
        }
        for text in springbake_pipeline::budget::inside_collider_notes(&prepared) {
            eprintln!("springbake: note: {text}");
        }
        for text in springbake_pipeline::budget::coarse_mesh_notes(&mut prepared, &loaded.scene) {
            eprintln!("springbake: note: {text}");
        }
        let triangles = prepared
            .bodies
            .iter()
            .map(|b| prepared.export_scene.meshes[b.mesh_index].triangles())
            .collect();
        let mut effects = Effects::new(&loaded.scene, &prepared)?;
        effects.start(&prepared);
        let textures = prepared
            .bodies
            .iter()
            .map(|b| {
                let scene = &prepared.export_scene;
                surface_texture(scene, &scene.meshes[b.mesh_index])
            })
            .collect();
        Ok(Simulation {
            loaded,
            prepared,
            triangles,
            frame: 1,
            effects,
            textures,
        })
    }

    pub fn fps(&self) -> f64 {
        self.loaded.scene.output.fps
    }

    /// Step forward to output frame `frame` (no-op when already there or past it).
    pub fn advance_to(&mut self, frame: usize) -> Result<(), ViewerError> {
        let dt = 1.0 / self.fps();
        while self.frame < frame {
            self.frame += 1;
            self.prepared
                .world
                .advance_frame(dt, self.frame, &|| false)?;
            let start = (self.frame - 2) as f64 * dt;
            self.effects.advance(&self.prepared, start, dt);
        }
        Ok(())
    }

    /// The particles alive now, one small octahedron each as wide as the particle, in one
    /// mesh (none without emitters).
    pub fn particle_mesh(&self) -> Option<DrawMesh> {
        let time = (self.frame - 1) as f64 / self.fps();
        let particles = self.effects.visible_now(time);
        (!particles.is_empty()).then(|| particle_octahedra(&particles))
    }

    /// The bodies' display meshes now, in simulation metres, in their material's base colour
    /// and texture (springbake's body colour where the source gives none).
    pub fn body_meshes(&self) -> Vec<DrawMesh> {
        let scene = &self.prepared.export_scene;
        (0..self.prepared.bodies.len())
            .map(|b| {
                let mesh = &scene.meshes[self.prepared.bodies[b].mesh_index];
                DrawMesh {
                    texture: self.textures[b].clone(),
                    positions: self
                        .prepared
                        .vertex_positions(b)
                        .iter()
                        .map(|p| p.coords)
                        .collect(),
                    triangles: self.triangles[b].clone(),
                    colour: material_colour(scene, mesh).unwrap_or(BODY_COLOUR),
                }
            })
            .collect()
    }

    /// Scripted manipulators at the world's time, then the live capsules.
    pub fn capsules(&self) -> Vec<Capsule> {
        let w = &self.prepared.world;
        w.manipulators
            .iter()
            .map(|m| m.capsule_at(w.time))
            .chain(w.live_capsules.iter().copied())
            .collect()
    }

    /// Bodies and capsules.
    pub fn meshes(&self) -> Vec<DrawMesh> {
        let mut out = self.body_meshes();
        out.extend(
            self.capsules()
                .iter()
                .map(|c| capsule_mesh(c, 24, 6, CAPSULE_COLOUR)),
        );
        out.extend(self.prepared.world.colliders().iter().map(|c| DrawMesh {
            texture: None,
            positions: c.positions.clone(),
            triangles: c.triangles.clone(),
            colour: COLLIDER_COLOUR,
        }));
        out.extend(self.particle_mesh());
        let settings = &self.prepared.world.settings;
        if let Some([lo, hi]) = springbake_core::bake::room_of(&settings.planes, &settings.up) {
            let up = self.prepared.frame.up.index();
            out.push(wall_meshes(lo, hi, up, self.prepared.floor.unwrap_or(0.0)));
        }
        out
    }

    pub fn up(&self) -> Vector3<f64> {
        self.prepared.frame.up_vector()
    }
}

/// One mesh of a baked glTF: rest positions and morph deltas in its local frame.
#[derive(Debug, Clone)]
pub struct BakedMeshData {
    pub world_from_local: springbake_core::nalgebra::Matrix4<f64>,
    /// Per frame, the node's world matrix when the file animates it (the compact cache's
    /// rigid keys); empty for a node that stays put.
    pub frame_worlds: Vec<springbake_core::nalgebra::Matrix4<f64>>,
    pub rest: Vec<[f32; 3]>,
    /// Per morph target, one delta per vertex (empty when the mesh is not morphed).
    pub deltas: Vec<Vec<[f32; 3]>>,
    /// Weights per frame (one per target), from the node's `weights` animation channel.
    pub frame_weights: Vec<Vec<f32>>,
    pub triangles: Vec<[u32; 3]>,
    /// Its glTF node.
    pub node: Option<usize>,
    /// The base colour of its first primitive's material (sRGB), else the viewer's body colour.
    pub colour: [u8; 3],
    /// That material's base-colour image (a PNG) over the mesh's UVs, when it has both.
    pub texture: Option<std::sync::Arc<crate::raster::TexturedSurface>>,
}

/// A baked glTF's frames.
#[derive(Debug, Clone)]
pub struct BakedPlayback {
    pub meshes: Vec<BakedMeshData>,
    pub frame_count: usize,
    /// Frames per second from the animation's key times (24 when it has a single key).
    pub fps: f64,
    /// The floor height (Y-up metres) from the file's `extras.springbake_stage`, when it had
    /// one.
    pub floor: Option<f64>,
    /// The manipulators the bake recorded there.
    pub capsules: Vec<StageCapsule>,
    /// The static colliders recorded there, and the room's walls drawn low.
    pub colliders: Vec<DrawMesh>,
}

/// A manipulator recorded in a baked glTF: per frame the axis centre and direction.
#[derive(Debug, Clone, PartialEq)]
pub struct StageCapsule {
    pub radius: f64,
    pub length: f64,
    pub frames: Vec<[f64; 6]>,
}

impl StageCapsule {
    /// The capsule at 1-based `frame` (clamped).
    pub fn at(&self, frame: usize) -> Option<Capsule> {
        let f = self
            .frames
            .get(frame.clamp(1, self.frames.len().max(1)) - 1)?;
        Some(Capsule {
            centre: Vector3::new(f[0], f[1], f[2]),
            axis: Vector3::new(f[3], f[4], f[5]),
            length: self.length,
            radius: self.radius,
            velocity: Vector3::zeros(),
            friction: 0.0,
        })
    }
}

/// The base-colour image of `mesh`'s first primitive's material (PNG or JPEG) over the mesh's UVs
/// (every primitive's, in order), when both are there.
fn surface_texture(
    scene: &springbake_core::display::ImportedScene,
    mesh: &springbake_core::display::DisplayMesh,
) -> Option<std::sync::Arc<crate::raster::TexturedSurface>> {
    let name = mesh.primitives.first()?.material.as_ref()?;
    let image = scene
        .materials
        .iter()
        .find(|m| &m.name == name)?
        .base_colour_texture
        .as_ref()?;
    let texture = crate::raster::Texture::decode(&image.bytes)?;
    let uvs = mesh
        .primitives
        .iter()
        .map(|p| p.uvs.clone())
        .collect::<Option<Vec<_>>>()?
        .concat();
    Some(std::sync::Arc::new(crate::raster::TexturedSurface {
        texture,
        uvs,
    }))
}

/// The sRGB base colour of glTF mesh `mesh`'s first primitive's material (`baseColorFactor`
/// is linear).
fn base_colour(doc: &GltfDocument, mesh: usize) -> Option<[u8; 3]> {
    let material = doc.array("meshes").get(mesh)?["primitives"][0]["material"].as_u64()?;
    let factor = doc.array("materials").get(material as usize)?["pbrMetallicRoughness"]
        ["baseColorFactor"]
        .as_array()?
        .iter()
        .take(3)
        .map(|c| c.as_f64())
        .collect::<Option<Vec<f64>>>()?;
    (factor.len() == 3).then(|| srgb([factor[0], factor[1], factor[2]]))
}

/// The sRGB base colour of `mesh`'s first primitive's material, as the importer read it
/// (white under a texture: the image carries the colour).
fn material_colour(
    scene: &springbake_core::display::ImportedScene,
    mesh: &springbake_core::display::DisplayMesh,
) -> Option<[u8; 3]> {
    let name = mesh.primitives.first()?.material.as_ref()?;
    let material = scene.materials.iter().find(|m| &m.name == name)?;
    let c = material.base_colour.map(f64::from);
    Some(srgb([c[0], c[1], c[2]]))
}

/// Linear RGB in [0, 1] as 8-bit sRGB.
fn srgb(linear: [f64; 3]) -> [u8; 3] {
    linear.map(|c| {
        let c = c.clamp(0.0, 1.0);
        let s = if c <= 0.003_130_8 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    })
}

/// `extras.springbake_stage` of a baked glTF (written by springbake's exporter): the floor and
/// the capsules; absent or malformed parts are left out.
fn read_stage(doc: &GltfDocument) -> (Option<f64>, Vec<StageCapsule>, Vec<DrawMesh>) {
    let stage = &doc.json["extras"]["springbake_stage"];
    let floor = stage["floor"].as_f64().filter(|h| h.is_finite());
    let capsules = stage["capsules"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|c| {
            let radius = c["radius"].as_f64().filter(|r| r.is_finite() && *r > 0.0)?;
            let length = c["length"]
                .as_f64()
                .filter(|l| l.is_finite() && *l >= 0.0)?;
            let frames = c["frames"]
                .as_array()?
                .iter()
                .map(|f| {
                    let v: Vec<f64> = f.as_array()?.iter().filter_map(Value::as_f64).collect();
                    (v.len() == 6 && v.iter().all(|x| x.is_finite()))
                        .then(|| [v[0], v[1], v[2], v[3], v[4], v[5]])
                })
                .collect::<Option<Vec<_>>>()?;
            (!frames.is_empty()).then_some(StageCapsule {
                radius,
                length,
                frames,
            })
        })
        .collect();
    let colliders: Vec<DrawMesh> = stage["colliders"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|c| {
            let flat: Vec<f64> = c["positions"]
                .as_array()?
                .iter()
                .filter_map(Value::as_f64)
                .collect();
            let index: Vec<u32> = c["triangles"]
                .as_array()?
                .iter()
                .filter_map(|i| i.as_u64().and_then(|i| u32::try_from(i).ok()))
                .collect();
            let positions: Vec<Vector3<f64>> = flat
                .chunks_exact(3)
                .map(|p| Vector3::new(p[0], p[1], p[2]))
                .collect();
            let count = positions.len() as u32;
            let triangles: Vec<[u32; 3]> = index
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .filter(|t| t.iter().all(|&i| i < count))
                .collect();
            (!triangles.is_empty() && positions.iter().all(|p| p.iter().all(|x| x.is_finite())))
                .then_some(DrawMesh {
                    texture: None,
                    positions,
                    triangles,
                    colour: COLLIDER_COLOUR,
                })
        })
        .collect();
    let mut colliders = colliders;
    let corner = |v: &Value| -> Option<[f64; 3]> {
        let a: Vec<f64> = v.as_array()?.iter().filter_map(Value::as_f64).collect();
        (a.len() == 3 && a.iter().all(|x| x.is_finite())).then(|| [a[0], a[1], a[2]])
    };
    if let (Some(lo), Some(hi)) = (corner(&stage["walls"][0]), corner(&stage["walls"][1])) {
        colliders.push(wall_meshes(lo, hi, 1, floor.unwrap_or(0.0)));
    }
    (floor, capsules, colliders)
}

impl BakedPlayback {
    /// Vertex positions (world frame of the file, Y-up metres) at 1-based `frame`, clamped to
    /// the frames there are.
    pub fn meshes_at(&self, frame: usize) -> Vec<DrawMesh> {
        self.meshes
            .iter()
            .map(|m| {
                let world = match m.frame_worlds.len() {
                    0 => &m.world_from_local,
                    n => &m.frame_worlds[frame.clamp(1, n) - 1],
                };
                let weights = if m.frame_weights.is_empty() {
                    None
                } else {
                    m.frame_weights
                        .get(frame.clamp(1, m.frame_weights.len()) - 1)
                };
                let positions = m
                    .rest
                    .iter()
                    .enumerate()
                    .map(|(v, r)| {
                        let mut p = Vector3::new(r[0] as f64, r[1] as f64, r[2] as f64);
                        if let Some(w) = weights {
                            for (t, &wt) in w.iter().enumerate() {
                                if wt != 0.0 {
                                    if let Some(d) = m.deltas.get(t).and_then(|d| d.get(v)) {
                                        p += Vector3::new(d[0] as f64, d[1] as f64, d[2] as f64)
                                            * wt as f64;
                                    }
                                }
                            }
                        }
                        world.transform_point(&Point3::from(p)).coords
                    })
                    .collect();
                DrawMesh {
                    texture: m.texture.clone(),
                    positions,
                    triangles: m.triangles.clone(),
                    colour: m.colour,
                }
            })
            .collect()
    }
}

/// An axis-aligned box: lowest and highest corner, metres.
pub type Bounds = (Vector3<f64>, Vector3<f64>);

/// What a file opens as.
pub enum ViewSource {
    Simulated(Box<Simulation>),
    Baked(BakedPlayback),
}

impl ViewSource {
    /// Open `path`: a `.toml` scene, a baked glTF (one with morph targets and a weights
    /// animation), or any mesh the registry imports (simulated with the default scene).
    pub fn open(registry: &Registry, path: &Path) -> Result<ViewSource, ViewerError> {
        if !path.exists() {
            return Err(ViewerError::Usage(format!(
                "{}: no such file",
                path.display()
            )));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        if ext == "toml" {
            let loaded = springbake_pipeline::load_scene(path)?;
            return Ok(ViewSource::Simulated(Box::new(Simulation::new(
                registry, loaded,
            )?)));
        }
        if ext == "glb" || ext == "gltf" {
            let bytes = std::fs::read(path).map_err(|e| ViewerError::Io {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
            if let Some(baked) = read_baked_gltf(path, &bytes)? {
                return Ok(ViewSource::Baked(baked));
            }
        }
        let loaded = springbake_pipeline::default_scene_for_mesh(path, &MeshOverrides::default());
        springbake_pipeline::validate_scene(&loaded.scene).map_err(ViewerError::Usage)?;
        Ok(ViewSource::Simulated(Box::new(Simulation::new(
            registry, loaded,
        )?)))
    }

    /// The overlays of what is drawn now (lines and markers `width` across): a simulated
    /// scene's lattice springs and contact points; nothing for a baked file.
    pub fn overlay_meshes(&self, overlays: crate::Overlays, width: f64) -> Vec<DrawMesh> {
        let ViewSource::Simulated(sim) = self else {
            return Vec::new();
        };
        let mut out = Vec::new();
        let world = &sim.prepared.world;
        if overlays.lattice {
            let mut springs = Vec::new();
            for b in &sim.prepared.bodies {
                let nodes = world.body_positions(b.handle);
                springs.extend(
                    b.lattice
                        .springs
                        .iter()
                        .map(|s| (nodes[s.a as usize], nodes[s.b as usize])),
                );
            }
            springs.truncate(crate::MAX_OVERLAY_SPRINGS);
            out.push(rods(&springs, width, LATTICE_COLOUR));
        }
        if overlays.contacts {
            let points: Vec<(Vector3<f64>, f64)> = world
                .touching_points()
                .into_iter()
                .map(|p| (p, width * 4.0))
                .collect();
            let mut markers = particle_octahedra(&points);
            markers.colour = CONTACT_COLOUR;
            out.push(markers);
        }
        out
    }

    /// How many of the meshes drawn for a frame are bodies (they come first).
    pub fn body_count(&self) -> usize {
        match self {
            ViewSource::Simulated(s) => s.prepared.bodies.len(),
            ViewSource::Baked(b) => b.meshes.len(),
        }
    }

    /// Up vector of what is drawn.
    pub fn up(&self) -> Vector3<f64> {
        match self {
            ViewSource::Simulated(s) => s.up(),
            ViewSource::Baked(_) => UpAxis::Y.vector(),
        }
    }

    pub fn fps(&self) -> f64 {
        match self {
            ViewSource::Simulated(s) => s.fps(),
            ViewSource::Baked(b) => b.fps,
        }
    }

    /// Number of frames the source plays (the scene's `output.frames` for a simulation).
    pub fn frame_count(&self) -> usize {
        match self {
            ViewSource::Simulated(s) => s.loaded.scene.output.frames,
            ViewSource::Baked(b) => b.frame_count,
        }
    }

    /// The box a camera should frame, from the state before any step: the bodies, their
    /// shadow on the floor (where they fall to), and the scripted manipulators' key positions
    /// (± half their length); for a baked file, the bodies over every frame.
    pub fn view_bounds(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let mut points: Vec<Vector3<f64>> = Vec::new();
        match self {
            ViewSource::Simulated(s) => {
                let up = s.up();
                for m in s.body_meshes() {
                    if let Some((lo, hi)) = m.bounds() {
                        points.push(lo);
                        points.push(hi);
                        if let Some(floor) = s.prepared.floor {
                            points.push(lo - up * up.dot(&lo) + up * floor);
                            points.push(hi - up * up.dot(&hi) + up * floor);
                        }
                    }
                }
                for track in &s.prepared.world.manipulators {
                    for key in &track.keys {
                        let c = track.capsule_at(key.t);
                        let (a, b) = c.endpoints();
                        points.push(a);
                        points.push(b);
                    }
                }
            }
            ViewSource::Baked(b) => {
                let step = (b.frame_count / 200).max(1);
                let up = UpAxis::Y.vector();
                for f in (1..=b.frame_count).step_by(step) {
                    for m in b.meshes_at(f) {
                        if let Some((lo, hi)) = m.bounds() {
                            points.push(lo);
                            points.push(hi);
                            if let Some(floor) = b.floor {
                                points.push(lo - up * up.dot(&lo) + up * floor);
                                points.push(hi - up * up.dot(&hi) + up * floor);
                            }
                        }
                    }
                    for c in b.capsules.iter().filter_map(|c| c.at(f)) {
                        let (a, e) = c.endpoints();
                        points.push(a);
                        points.push(e);
                    }
                }
            }
        }
        crate::raster::bounds_of(points.iter())
    }

    /// The box a camera should frame to show the bodies at 1-based `frame`: the bodies there
    /// and, below them, the floor they stand on or fall to (a simulation steps to `frame`).
    pub fn bounds_at(&mut self, frame: usize) -> Result<Option<Bounds>, ViewerError> {
        let (bodies, up) = match self {
            ViewSource::Simulated(s) => {
                s.advance_to(frame)?;
                (s.body_meshes(), s.up())
            }
            ViewSource::Baked(b) => (b.meshes_at(frame), UpAxis::Y.vector()),
        };
        let floor = self.floor();
        let mut points = Vec::new();
        for m in &bodies {
            if let Some((lo, hi)) = m.bounds() {
                points.push(lo);
                points.push(hi);
                if let Some(h) = floor {
                    points.push(lo - up * up.dot(&lo) + up * h);
                    points.push(hi - up * up.dot(&hi) + up * h);
                }
            }
        }
        Ok(crate::raster::bounds_of(points.iter()))
    }

    /// Floor height along up, when the scene has a floor (a baked file: when springbake
    /// recorded one).
    pub fn floor(&self) -> Option<f64> {
        match self {
            ViewSource::Simulated(s) => s.prepared.floor,
            ViewSource::Baked(b) => b.floor,
        }
    }

    /// Everything to draw at 1-based `frame` (a simulation steps forward to it).
    pub fn meshes_at(&mut self, frame: usize) -> Result<Vec<DrawMesh>, ViewerError> {
        match self {
            ViewSource::Simulated(s) => {
                s.advance_to(frame)?;
                Ok(s.meshes())
            }
            ViewSource::Baked(b) => {
                let mut meshes = b.meshes_at(frame);
                meshes.extend(
                    b.capsules
                        .iter()
                        .filter_map(|c| c.at(frame))
                        .map(|c| capsule_mesh(&c, 24, 6, CAPSULE_COLOUR)),
                );
                meshes.extend(b.colliders.iter().cloned());
                Ok(meshes)
            }
        }
    }
}

/// Per frame (at `f / fps`), the world matrix of each mesh whose node (or an ancestor) the
/// file's animations move: translation, rotation and scale channels sampled and the node
/// tree composed again (`doc`'s nodes are overwritten with each frame's values).
fn animate_nodes(
    doc: &mut GltfDocument,
    meshes: &mut [BakedMeshData],
    frame_count: usize,
    fps: f64,
) -> Result<(), ViewerError> {
    use springbake_importers::gltf::pose::{pose_at_start, values_at};
    const MOVES: [&str; 3] = ["translation", "rotation", "scale"];
    let animations = doc.array("animations").len();
    let mut any = false;
    for a in 0..animations {
        any |= !values_at(doc, a, 0.0, &MOVES)?.is_empty();
    }
    if !any {
        return Ok(());
    }
    for f in 0..frame_count {
        let time = f as f64 / fps.max(1e-9);
        for a in 0..animations {
            let values = values_at(doc, a, time, &MOVES)?;
            pose_at_start(&mut doc.json, &values);
        }
        let worlds = springbake_importers::gltf::scene_nodes(doc)?;
        for m in meshes.iter_mut() {
            if let Some(w) = m.node.and_then(|n| worlds.iter().find(|p| p.node == n)) {
                m.frame_worlds.push(w.world_from_local);
            }
        }
    }
    Ok(())
}

/// A `weights` animation channel: target node, key times, flat weights (targets per key).
type WeightsChannel = (usize, Vec<f32>, Vec<f32>);

fn weights_channels(doc: &GltfDocument) -> Result<Vec<WeightsChannel>, PluginError> {
    let mut out = Vec::new();
    for (a, anim) in doc.array("animations").iter().enumerate() {
        let samplers = anim
            .get("samplers")
            .and_then(Value::as_array)
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        for (c, ch) in anim
            .get("channels")
            .and_then(Value::as_array)
            .map(Vec::as_slice)
            .unwrap_or(&[])
            .iter()
            .enumerate()
        {
            let target = ch.get("target");
            if target.and_then(|t| t.get("path")).and_then(Value::as_str) != Some("weights") {
                continue;
            }
            let (Some(node), Some(sampler)) = (
                target.and_then(|t| get_usize(t, "node")),
                get_usize(ch, "sampler"),
            ) else {
                continue;
            };
            let location = format!("animations[{a}].channels[{c}]");
            let s = samplers.get(sampler).ok_or_else(|| {
                doc.error(
                    &location,
                    format!("refers to sampler {sampler}, which does not exist"),
                )
            })?;
            let (Some(input), Some(output)) = (get_usize(s, "input"), get_usize(s, "output"))
            else {
                return Err(doc.error(
                    format!("animations[{a}].samplers[{sampler}]"),
                    "needs input and output",
                ));
            };
            let (times, _) = read_floats(doc, input, &location)?;
            let (weights, _) = read_floats(doc, output, &location)?;
            out.push((node, times, weights));
        }
    }
    Ok(out)
}

/// A baked glTF's meshes and frames, or `None` when the file has no morph targets (a plain mesh).
pub fn read_baked_gltf(path: &Path, bytes: &[u8]) -> Result<Option<BakedPlayback>, ViewerError> {
    let mut doc = load_document(path, bytes)?;
    let has_targets = doc.array("meshes").iter().any(|m| {
        m.get("primitives")
            .and_then(Value::as_array)
            .is_some_and(|ps| ps.iter().any(|p| p.get("targets").is_some()))
    });
    if !has_targets {
        return Ok(None);
    }
    let scene = GltfImporter.import(path, bytes, &ImportSettings::default())?;
    let channels = weights_channels(&doc)?;
    let mut meshes = Vec::new();
    let mut frame_count = 1;
    let mut fps = 24.0;
    for mesh in &scene.meshes {
        let triangles = mesh.triangles();
        // The importer gives the first frame's pose; the targets play from the base mesh.
        let mut rest: Vec<[f32; 3]> = mesh
            .primitives
            .iter()
            .flat_map(|p| p.positions.iter().copied())
            .collect();
        let node = mesh
            .source_key
            .strip_prefix("node:")
            .and_then(|n| n.parse::<usize>().ok());
        let gltf_mesh = node
            .and_then(|n| doc.array("nodes").get(n))
            .and_then(|n| get_usize(n, "mesh"));
        let mut deltas: Vec<Vec<[f32; 3]>> = Vec::new();
        let mut frame_weights = Vec::new();
        if let Some(mi) = gltf_mesh {
            let prims = doc.array("meshes")[mi]
                .get("primitives")
                .and_then(Value::as_array)
                .cloned()
                .unwrap_or_default();
            // Deltas per target, primitives concatenated in the importer's order; used only when
            // every primitive's vertex count matches what the importer produced.
            let counts_match = prims.len() == mesh.primitives.len()
                && prims.iter().zip(&mesh.primitives).all(|(p, ip)| {
                    p.get("attributes")
                        .and_then(|a| get_usize(a, "POSITION"))
                        .and_then(|acc| doc.array("accessors").get(acc))
                        .and_then(|a| get_usize(a, "count"))
                        == Some(ip.positions.len())
                });
            if counts_match {
                rest.clear();
                for (pi, p) in prims.iter().enumerate() {
                    let location = format!("meshes[{mi}].primitives[{pi}].attributes.POSITION");
                    let accessor = get_usize(&p["attributes"], "POSITION").unwrap_or(usize::MAX);
                    let (flat, _) = read_floats(&doc, accessor, &location)?;
                    rest.extend(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                }
                let targets = prims
                    .first()
                    .and_then(|p| p.get("targets"))
                    .and_then(Value::as_array)
                    .map_or(0, Vec::len);
                for t in 0..targets {
                    let mut delta = Vec::with_capacity(rest.len());
                    for (pi, (p, ip)) in prims.iter().zip(&mesh.primitives).enumerate() {
                        let location =
                            format!("meshes[{mi}].primitives[{pi}].targets[{t}].POSITION");
                        match p
                            .get("targets")
                            .and_then(|ts| ts.get(t))
                            .and_then(|tg| get_usize(tg, "POSITION"))
                        {
                            Some(acc) => {
                                let (flat, comps) = read_floats(&doc, acc, &location)?;
                                if comps != 3 || flat.len() != ip.positions.len() * 3 {
                                    return Err(doc.error(location, "morph target POSITION must be VEC3 with one delta per vertex").into());
                                }
                                delta.extend(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                            }
                            None => {
                                delta.extend(std::iter::repeat_n([0.0f32; 3], ip.positions.len()))
                            }
                        }
                    }
                    deltas.push(delta);
                }
                if let Some((_, times, weights)) =
                    channels.iter().find(|(n, _, _)| Some(*n) == node)
                {
                    if targets > 0 && !times.is_empty() && weights.len() >= times.len() * targets {
                        frame_weights = weights
                            .chunks_exact(targets)
                            .take(times.len())
                            .map(<[f32]>::to_vec)
                            .collect();
                        frame_count = frame_count.max(times.len());
                        if times.len() > 1 {
                            let span = (times[times.len() - 1] - times[0]) as f64;
                            if span > 0.0 {
                                fps = ((times.len() - 1) as f64 / span * 1000.0).round() / 1000.0;
                            }
                        }
                    }
                }
            }
        }
        let colour = gltf_mesh
            .and_then(|mi| base_colour(&doc, mi))
            .unwrap_or(BODY_COLOUR);
        let texture = surface_texture(&scene, mesh);
        meshes.push(BakedMeshData {
            world_from_local: mesh.world_from_local,
            frame_worlds: Vec::new(),
            node,
            rest,
            deltas,
            frame_weights,
            triangles,
            colour,
            texture,
        });
    }
    animate_nodes(&mut doc, &mut meshes, frame_count, fps)?;
    let (floor, capsules, colliders) = read_stage(&doc);
    Ok(Some(BakedPlayback {
        meshes,
        frame_count,
        fps,
        floor,
        capsules,
        colliders,
    }))
}
