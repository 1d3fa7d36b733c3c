//! Import, fit and simulate: from a [`LoadedScene`] to baked frames.

use crate::frame::SimFrame;
use crate::report::{BodyReport, Seconds};
use crate::{BakeHooks, LoadedScene, PipelineError};
use springbake_core::bake::{
    BakedCapsule, BakedCollider, BakedLattice, BakedMesh, BakedScene, BakedStage,
};
use springbake_core::display::{ImportedScene, SourceDocument};
use springbake_core::lattice::{Embedding, FitSettings, Lattice, Resolution};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Matrix4, Point3, Vector3};
use springbake_core::plugin::Registry;
use springbake_core::scene::{
    BodyKind, CacheSpec, IntegratorSpec, Interpolation as KeyInterpolation, PathInterpolation,
    SceneFile, SourceSpec, DEFAULT_CELLS,
};
use springbake_core::solver::manipulator::{ManipulatorKey, ManipulatorTrack};
use springbake_core::solver::{
    nearest_node, nodes_in_box, BodyHandle, DispersionMode, FrameDiagnostics, Integrator,
    Interpolation, Path, Plane, Wind, World, WorldSettings,
};
use std::time::Instant;

/// A model whose lowest point lies less than this fraction of its height below 0 stands on
/// the ground (a DCC's rounding), for the automatic floor.
const ON_GROUND: f64 = 1e-4;

/// Names that tell the bodies apart, from each mesh's `(name, source key)`: a name only one
/// mesh has is kept; meshes sharing one (usd-wg's chess set: every piece's mesh prim is
/// `Render`) take the shortest tail of their USD prim paths that differs
/// (`White/King/Geom/Render`), or, where the key is not a prim path, Blender's `.001`,
/// `.002` after the first. The exported meshes keep the artist's names.
fn distinct_names(meshes: &[(String, String)]) -> Vec<String> {
    let mut names: Vec<String> = meshes.iter().map(|m| m.0.clone()).collect();
    let mut groups: std::collections::BTreeMap<&str, Vec<usize>> = Default::default();
    for (i, (name, _)) in meshes.iter().enumerate() {
        groups.entry(name.as_str()).or_default().push(i);
    }
    for (name, group) in groups.into_iter().filter(|g| g.1.len() > 1) {
        let paths: Vec<Vec<&str>> = group
            .iter()
            .map(|&i| meshes[i].1.split('/').filter(|c| !c.is_empty()).collect())
            .collect();
        let tail = |path: &Vec<&str>, k: usize| path[path.len().saturating_sub(k)..].join("/");
        let longest = paths.iter().map(Vec::len).max().unwrap_or(0);
        let by_path = group.iter().all(|&i| meshes[i].1.starts_with('/'));
        let distinct_at = (2..=longest).find(|&k| {
            let tails: std::collections::BTreeSet<String> =
                paths.iter().map(|p| tail(p, k)).collect();
            tails.len() == paths.len()
        });
        for (n, (&i, path)) in group.iter().zip(&paths).enumerate() {
            names[i] = match distinct_at {
                Some(k) if by_path => tail(path, k),
                _ if n == 0 => name.to_owned(),
                _ => format!("{name}.{n:03}"),
            };
        }
    }
    names
}

/// One simulated mesh.
#[derive(Debug, Clone)]
pub struct PreparedBody {
    pub name: String,
    /// Index of the `[[body]]` section it came from.
    pub section: usize,
    /// Index into [`Prepared::export_scene`]'s meshes.
    pub mesh_index: usize,
    pub lattice: Lattice,
    pub embedding: Embedding,
    pub handle: BodyHandle,
    pub material: Material,
    /// Maps simulation metres back to the mesh's local frame in source units.
    pub local_from_sim: Matrix4<f64>,
    /// The analysis model (`[body] model`): `lattice`, `box`, …, `explicit`.
    pub model: String,
    /// Set when the model is not exactly what was asked for (a decimated cage replaced by
    /// its convex hull).
    pub model_note: Option<String>,
}

/// Everything ready to simulate.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub world: World,
    pub bodies: Vec<PreparedBody>,
    /// The scene the exporter writes into (the source document, or a merge of several).
    pub export_scene: ImportedScene,
    pub frame: SimFrame,
    /// Floor height along up, metres, if any.
    pub floor: Option<f64>,
    /// The scene's events, motion features and attachments (none without `[[event]]` or
    /// `[[attach]]`).
    pub events: Option<crate::events::EventDriver>,
    /// Where the solver runs (see [`crate::device`]).
    pub device: crate::device::Placement,
    /// Bodies moved out of the floor or a wall they started through (see [`crate::placement`]).
    pub lifted: Vec<crate::placement::Lift>,
}

fn import_all(
    registry: &Registry,
    loaded: &LoadedScene,
) -> Result<Vec<ImportedScene>, PipelineError> {
    let mut scenes = Vec::new();
    for (i, body) in loaded.scene.body.iter().enumerate() {
        let path = loaded.source_path(body);
        if let SourceSpec::Superquadrics(shapes) = &body.source {
            let name = body.name.as_deref().unwrap_or("superquadrics");
            let scene =
                crate::models::superquadric_scene(shapes, name, &path).map_err(|message| {
                    PipelineError::Body {
                        body: i,
                        source_path: path.clone(),
                        message,
                    }
                })?;
            scenes.push(scene);
            continue;
        }
        let importer = registry
            .importer_for(&path)
            .ok_or_else(|| PipelineError::Body {
                body: i,
                source_path: path.clone(),
                message: format!(
                    "no importer for this extension; springbake reads {}",
                    registry.import_extensions().join(", ")
                ),
            })?;
        let bytes = loaded
            .read_source(&path)
            .map_err(|message| PipelineError::Body {
                body: i,
                source_path: path.clone(),
                message,
            })?;
        let mut scene = importer.import(&path, &bytes, &loaded.import_settings_for(body))?;
        if let Some(unit) = body.meters_per_unit {
            scene.meters_per_unit = unit;
        }
        scenes.push(scene);
    }
    Ok(scenes)
}

/// Import every source, convert to the simulation frame, fit lattices and build the world.
pub fn prepare(
    registry: &Registry,
    loaded: &LoadedScene,
    seconds: &mut Seconds,
) -> Result<Prepared, PipelineError> {
    let scene = &loaded.scene;
    let t_import = Instant::now();
    let imported = import_all(registry, loaded)?;
    seconds.import = t_import.elapsed().as_secs_f64();
    let t_fit = Instant::now();
    let frame = SimFrame {
        up: scene.world.up.unwrap_or(imported[0].up_axis),
    };
    let up = frame.up_vector();

    // The export scene: the one source document, or a merge (exporters then build a fresh one).
    let single_source = imported
        .windows(2)
        .all(|w| w[0].source.path == w[1].source.path)
        && imported.len() == 1;
    let mut export_scene = if single_source {
        imported[0].clone()
    } else {
        ImportedScene {
            materials: Vec::new(),
            notes: Vec::new(),
            meshes: Vec::new(),
            up_axis: frame.up,
            meters_per_unit: 1.0,
            source: SourceDocument {
                path: loaded.output_path(),
                importer: "merged".into(),
                read_root: None,
            },
        }
    };

    struct Pending {
        name: String,
        key: String,
        mesh_index: usize,
        points: Vec<Point3<f64>>,
        triangles: Vec<[u32; 3]>,
        body: usize,
        local_from_sim: Matrix4<f64>,
    }
    let mut pending = Vec::new();
    if !single_source {
        // Materials by name, the first source's description of a name winning.
        for source in &imported {
            export_scene.notes.extend(source.notes.iter().cloned());
            for m in &source.materials {
                if !export_scene.materials.iter().any(|k| k.name == m.name) {
                    export_scene.materials.push(m.clone());
                }
            }
        }
    }
    for (b, (section, source)) in scene.body.iter().zip(&imported).enumerate() {
        let sim_from_source = frame.sim_from_source(source.up_axis, source.meters_per_unit);
        let offset = Vector3::from(section.offset);
        for mesh in &source.meshes {
            let mesh_index = if single_source {
                pending.len()
            } else {
                // Meshes of a merged scene are stored in simulation metres (their offset, as
                // in a single source, is motion the frames carry).
                let mut m = mesh.clone();
                m.world_from_local = sim_from_source * mesh.world_from_local;
                export_scene.meshes.push(m);
                export_scene.meshes.len() - 1
            };
            let sim_from_local =
                Matrix4::new_translation(&offset) * sim_from_source * mesh.world_from_local;
            // Offsets are motion: the baked frames carry them in the mesh's own frame, so a
            // point cache laid on the artist's object moves it to where it was simulated.
            let local_from_sim = (sim_from_source * mesh.world_from_local)
                .try_inverse()
                .ok_or_else(|| PipelineError::Body {
                    body: b,
                    source_path: source.source.path.clone(),
                    message: format!(
                        "mesh \"{}\" has a singular transform (a zero scale?)",
                        mesh.name
                    ),
                })?;
            let points: Vec<Point3<f64>> = mesh
                .primitives
                .iter()
                .flat_map(|p| p.positions.iter())
                .map(|q| {
                    sim_from_local.transform_point(&Point3::new(
                        q[0] as f64,
                        q[1] as f64,
                        q[2] as f64,
                    ))
                })
                .collect();
            pending.push(Pending {
                name: mesh.name.clone(),
                key: mesh.source_key.clone(),
                mesh_index,
                points,
                triangles: mesh.triangles(),
                body: b,
                local_from_sim,
            });
        }
    }

    let names: Vec<(String, String)> = pending
        .iter()
        .map(|p| (p.name.clone(), p.key.clone()))
        .collect();
    for (p, name) in pending.iter_mut().zip(distinct_names(&names)) {
        p.name = name;
    }

    // Floor: explicit, none, or automatic (NaN): 0 when everything is above it, else just
    // under the lowest point (5 % of the tallest mesh), so the mesh drops, lands and settles.
    // A lowest point a rounding below 0 (usd-wg's Teapot: -7e-9 m) is on the ground: the
    // floor stays at 0 rather than dropping the model 5 % of its height.
    let floor = match scene.world.floor {
        Some(h) if h.is_nan() => {
            let (mut lowest, mut tallest) = (f64::INFINITY, 0.0f64);
            for p in &pending {
                let heights = p.points.iter().map(|q| q.coords.dot(&up));
                let (lo, hi) = heights.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| {
                    (lo.min(h), hi.max(h))
                });
                lowest = lowest.min(lo);
                tallest = tallest.max(hi - lo);
            }
            Some(if lowest >= -ON_GROUND * tallest {
                0.0
            } else {
                lowest - 0.05 * tallest
            })
        }
        other => other,
    };

    let mut bodies = Vec::new();
    let mut fitted = Vec::new();
    for p in &pending {
        let section = &scene.body[p.body];
        let resolution = match (section.cell_size, section.cells) {
            (Some(h), _) => Resolution::CellSize(h),
            (None, n) => Resolution::CellsAlongLongest(n.unwrap_or(DEFAULT_CELLS)),
        };
        let settings = FitSettings {
            resolution,
            layout: section.springs.layout(),
            up_index: frame.up.index(),
            ..FitSettings::default()
        };
        // The lattice or cage (`[body] model`, see `models`).
        let lattice =
            crate::models::fit(&p.points, &p.triangles, section, &settings).map_err(|e| {
                PipelineError::Body {
                    body: p.body,
                    source_path: loaded.source_path(section),
                    message: format!("mesh \"{}\": {e}", p.name),
                }
            })?;
        let material = section
            .material
            .resolve()
            .map_err(|e| PipelineError::Body {
                body: p.body,
                source_path: loaded.source_path(section),
                message: e.to_string(),
            })?;
        fitted.push((lattice, material));
    }
    seconds.fit = t_fit.elapsed().as_secs_f64();

    // One elastic layer for the world: from the finest lattice and the stiffest material.
    let (finest, stiffest) = fitted
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(c, k), (l, m)| {
            (c.min(l.spacing()), k.max(m.spring_constant(l.spacing())))
        });
    let reference = fitted
        .iter()
        .map(|(_, m)| m)
        .max_by(|a, b| a.young_pa.total_cmp(&b.young_pa))
        .cloned()
        .unwrap_or_else(|| Material::preset("rubber").expect("rubber is a preset"));
    let mut layer = WorldSettings::default_layer(finest, &reference, scene.world.friction);
    layer.stiffness = layer.stiffness.max(10.0 * stiffest);
    if let Some(t) = scene.world.contact_thickness {
        layer.thickness_m = t;
    }
    if let Some(k) = scene.world.contact_stiffness {
        layer.stiffness = k;
    }

    let mut planes = Vec::new();
    if let Some(h) = floor {
        planes.push(Plane {
            normal: up,
            offset: h,
        });
    }
    if let Some(room) = &scene.world.walls {
        for axis in 0..3 {
            if axis == frame.up.index() {
                continue;
            }
            let mut n = Vector3::zeros();
            n[axis] = 1.0;
            planes.push(Plane {
                normal: n,
                offset: room.min[axis],
            });
            planes.push(Plane {
                normal: -n,
                offset: -room.max[axis],
            });
        }
    }
    let settings = WorldSettings {
        gravity: -up * scene.world.gravity,
        up,
        planes,
        layer,
        dispersion: if scene.solver.dispersion {
            DispersionMode::Bounded
        } else {
            DispersionMode::Off
        },
        max_dispersion_iterations: scene.solver.max_dispersion_iterations,
        accuracy_n: scene.solver.accuracy_n,
        fixed_substeps: match scene.solver.substeps {
            springbake_core::scene::SubstepSpec::Auto => None,
            springbake_core::scene::SubstepSpec::Fixed(n) => Some(n),
        },
        integrator: match scene.solver.integrator {
            IntegratorSpec::Xpbd => Integrator::Xpbd,
            IntegratorSpec::SymplecticEuler => Integrator::SymplecticEuler,
            IntegratorSpec::Newmark => Integrator::Newmark {
                beta: scene.solver.newmark_beta,
                tolerance: 1e-10,
                max_iterations: 50,
            },
        },
        wind: scene.world.wind.as_ref().map(|w| Wind {
            velocity: Vector3::from(w.velocity),
            gust: Vector3::from(w.gust),
            gust_hz: w.gust_hz,
            drag_per_s: w.drag_per_s,
        }),
        ..WorldSettings::default()
    };
    let mut world = World::new(settings);
    world.hold_stiff_bodies =
        scene.solver.stiff_bodies == springbake_core::scene::StiffBodies::Rigid;
    for m in &scene.manipulator {
        let mut keys: Vec<ManipulatorKey> = m
            .keys
            .iter()
            .map(|k| ManipulatorKey {
                t: k.t,
                position: Vector3::from(k.position),
                yaw_deg: k.yaw,
            })
            .collect();
        keys.sort_by(|a, b| a.t.total_cmp(&b.t));
        world.manipulators.push(ManipulatorTrack {
            radius: m.radius,
            length: m.length,
            friction: m.friction,
            smooth: m.interpolation == KeyInterpolation::Smooth,
            keys,
            up,
        });
    }
    let mut body_names: Vec<(Option<String>, String, BodyHandle)> = Vec::new();
    for (p, (lattice, material)) in pending.into_iter().zip(fitted) {
        let section = &scene.body[p.body];
        // Model, regions, contact surface, embedding, particle kind (see `models`).
        let crate::models::AddedBody {
            handle,
            embedding,
            lattice,
            model,
            note,
        } = crate::models::add_body(
            &mut world,
            lattice,
            &material,
            &p.name,
            section,
            &p.points,
            &p.triangles,
        )
        .map_err(|message| PipelineError::Body {
            body: p.body,
            source_path: loaded.source_path(section),
            message: format!("mesh \"{}\": {message}", p.name),
        })?;
        let source_path = loaded.source_path(section);
        let body_error = |e: springbake_core::solver::ConstraintError| PipelineError::Body {
            body: p.body,
            source_path: source_path.clone(),
            message: format!("mesh \"{}\": {e}", p.name),
        };
        if section.stiffness_scale != [1.0; 3] {
            world
                .scale_stiffness_per_axis(handle, Vector3::from(section.stiffness_scale))
                .map_err(body_error)?;
        }
        if section.kind == BodyKind::Rigid {
            world.make_rigid(handle).map_err(body_error)?;
        }
        if section.preserve_volume {
            world
                .preserve_volume(handle, section.volume_scale)
                .map_err(body_error)?;
        }
        body_names.push((section.name.clone(), p.name.clone(), handle));
        bodies.push(PreparedBody {
            name: p.name,
            section: p.body,
            mesh_index: p.mesh_index,
            lattice,
            embedding,
            handle,
            material,
            local_from_sim: p.local_from_sim,
            model,
            model_note: note,
        });
    }
    // Out of the floor and walls before anything reads where the bodies are (see `placement`).
    let lifted = crate::placement::lift_out_of_planes(&mut world, &bodies);
    // Contact between the bodies and with the `[[collider]]`s (see `colliders`).
    crate::colliders::wire(registry, loaded, &frame, &mut world, &bodies, &export_scene)?;
    add_constraints(scene, &mut world, &body_names)?;
    crate::models::add_joints(scene, &mut world, &body_names)?;
    crate::effects::bind_force_fields(scene, registry, &mut world, &body_names)?;
    let events = crate::events::EventDriver::wire(scene, registry, &mut world, &bodies).map_err(
        |message| match &loaded.scene_path {
            Some(path) => PipelineError::Scene {
                path: path.clone(),
                message,
            },
            None => PipelineError::Usage(message),
        },
    )?;
    let device = crate::device::place(scene, &mut world, events.is_some())?;
    Ok(Prepared {
        world,
        bodies,
        export_scene,
        frame,
        floor,
        events,
        device,
        lifted,
    })
}

/// The body a scene names (its `name`, or its mesh's name when it has none), or a message
/// listing the bodies there are.
pub(crate) fn find_body(
    bodies: &[(Option<String>, String, BodyHandle)],
    name: &str,
) -> Result<BodyHandle, String> {
    bodies
        .iter()
        .find(|(section, mesh, _)| section.as_deref() == Some(name) || mesh == name)
        .map(|b| b.2)
        .ok_or_else(|| {
            let names: Vec<&str> = bodies
                .iter()
                .map(|b| b.0.as_deref().unwrap_or(b.1.as_str()))
                .collect();
            format!("no body named \"{name}\"; bodies: {}", names.join(", "))
        })
}

/// Bind the scene's `[[constraint]]`s: nodes chosen by box, nearest point or index follow
/// their keyframes (or stay pinned), exactly or loosely (Terasawa eq 3.1).
fn add_constraints(
    scene: &SceneFile,
    world: &mut World,
    bodies: &[(Option<String>, String, BodyHandle)],
) -> Result<(), PipelineError> {
    for (i, c) in scene.constraint.iter().enumerate() {
        let err = |message: String| PipelineError::Usage(format!("constraint[{i}]: {message}"));
        let handle = find_body(bodies, &c.body).map_err(&err)?;
        let range = world.bodies[handle.0].nodes.clone();
        let positions = &world.nodes.position[range.clone()];
        let local: Vec<usize> = if let Some(r) = &c.region {
            nodes_in_box(positions, Vector3::from(r.min), Vector3::from(r.max))
        } else if let Some(p) = c.nearest {
            nearest_node(positions, Vector3::from(p))
                .into_iter()
                .collect()
        } else {
            let nodes = c.nodes.clone().unwrap_or_default();
            if let Some(bad) = nodes.iter().find(|&&n| n >= positions.len()) {
                return Err(err(format!(
                    "node {bad} out of range: the body has {} nodes",
                    positions.len()
                )));
            }
            nodes
        };
        if local.is_empty() {
            return Err(err("selects no lattice nodes".into()));
        }
        let nodes: Vec<usize> = local.iter().map(|n| n + range.start).collect();
        let path = if c.keys.is_empty() {
            let centre = nodes
                .iter()
                .map(|&n| world.nodes.position[n])
                .sum::<Vector3<f64>>()
                / nodes.len() as f64;
            Path::constant(centre)
        } else {
            let keys = c
                .keys
                .iter()
                .map(|k| (k.t, Vector3::from(k.position)))
                .collect();
            let interpolation = match c.interpolation {
                PathInterpolation::Linear => Interpolation::Linear,
                PathInterpolation::CatmullRom => Interpolation::CatmullRom,
            };
            Path::new(keys, interpolation).map_err(|e| err(e.to_string()))?
        };
        world
            .add_trajectory(&nodes, path, c.strength)
            .map_err(|e| err(e.to_string()))?;
    }
    Ok(())
}

fn to_local(m: &Matrix4<f64>, p: &Point3<f64>) -> [f32; 3] {
    let q = m.transform_point(p);
    [q.x as f32, q.y as f32, q.z as f32]
}

impl Prepared {
    /// The report's per-body lines.
    pub fn body_reports(&self) -> Vec<BodyReport> {
        self.bodies
            .iter()
            .map(|b| BodyReport {
                name: b.name.clone(),
                nodes: b.lattice.node_count(),
                springs: b.lattice.springs.len(),
                // Lattice cells, or a cage's tets.
                cells: self.world.bodies[b.handle.0].cells.len(),
                islands: b.lattice.island_count,
                cell_size: b.lattice.cell_size,
                material: b.material.name.clone(),
                model: b.model.clone(),
                model_note: b.model_note.clone(),
                mass_kg: self.world.nodes.mass[self.world.bodies[b.handle.0].nodes.clone()]
                    .iter()
                    .sum(),
            })
            .collect()
    }

    /// Display-vertex positions of every body now, in simulation metres.
    pub fn vertex_positions(&self, body: usize) -> Vec<Point3<f64>> {
        let b = &self.bodies[body];
        b.embedding.points(&self.world.body_points(b.handle))
    }

    fn record(&self, meshes: &mut [BakedMesh], with_lattice: bool) {
        for (b, baked) in self.bodies.iter().zip(meshes.iter_mut()) {
            let nodes = self.world.body_points(b.handle);
            let verts = b.embedding.points(&nodes);
            baked.frames.push(
                verts
                    .iter()
                    .map(|p| to_local(&b.local_from_sim, p))
                    .collect(),
            );
            if with_lattice {
                if let Some(l) = baked.lattice.as_mut() {
                    l.frames.push(
                        nodes
                            .iter()
                            .map(|p| to_local(&b.local_from_sim, p))
                            .collect(),
                    );
                }
            }
        }
    }

    /// Run the bake: frame 1 is the initial state at t = 0, each later frame one 1/fps step on.
    pub fn simulate(
        &mut self,
        scene: &SceneFile,
        hooks: &mut BakeHooks,
    ) -> Result<(BakedScene, Vec<FrameDiagnostics>), PipelineError> {
        let fps = scene.output.fps;
        let total = scene.output.frames;
        let with_lattice = scene.output.cache == CacheSpec::Skin;
        let mut meshes: Vec<BakedMesh> = self
            .bodies
            .iter()
            .map(|b| BakedMesh {
                mesh_index: b.mesh_index,
                frames: Vec::with_capacity(total),
                lattice: with_lattice.then(|| BakedLattice {
                    rest: b
                        .lattice
                        .rest_positions
                        .iter()
                        .map(|p| to_local(&b.local_from_sim, p))
                        .collect(),
                    frames: Vec::with_capacity(total),
                    vertex_nodes: b.embedding.nodes.clone(),
                    vertex_weights: b
                        .embedding
                        .weights
                        .iter()
                        .map(|w| w.map(|x| x as f32))
                        .collect(),
                }),
            })
            .collect();
        let mut diagnostics = Vec::with_capacity(total);
        let mut effects = crate::effects::Effects::new(scene, self)?;
        if let Some(events) = self.events.as_mut() {
            // Events of frame 1 (t = 0) act before it is recorded, like every later frame's.
            events.after_frame(&mut self.world, 1, fps)?;
        }
        let mut seen = 0;
        if let Some(events) = self.events.as_ref() {
            effects.trigger(events.log(), 0.0);
            seen = events.log().len();
        }
        effects.start(self);
        let mut first = self.world.diagnostics(1);
        first.max_penetration = self.current_penetration();
        diagnostics.push(first);
        self.record(&mut meshes, with_lattice);
        if let Some(p) = hooks.progress.as_mut() {
            p(1, total);
        }
        let never = || false;
        let cancelled: &(dyn Fn() -> bool + Sync) = hooks.cancelled.unwrap_or(&never);
        for f in 2..=total {
            if cancelled() {
                return Err(springbake_core::solver::SimulationError::Cancelled.into());
            }
            if let Some(events) = self.events.as_mut() {
                events.before_frame(&mut self.world, fps)?;
            }
            let d = self.world.advance_frame(1.0 / fps, f, cancelled)?;
            if let Some(events) = self.events.as_mut() {
                events.after_frame(&mut self.world, f, fps)?;
            }
            diagnostics.push(d);
            self.record(&mut meshes, with_lattice);
            // Emitters an event of this frame started or stopped act from its time on (a
            // burst goes off at the frame's end and is in its snapshot).
            if let Some(events) = self.events.as_ref() {
                effects.trigger(&events.log()[seen..], (f - 1) as f64 / fps);
                seen = events.log().len();
            }
            effects.advance(self, (f - 2) as f64 / fps, 1.0 / fps);
            if let Some(p) = hooks.progress.as_mut() {
                p(f, total);
            }
        }
        let stage = Some(self.stage(fps, total));
        Ok((
            BakedScene {
                stage,
                fps,
                frame_count: total,
                meshes,
                particles: effects.finish(),
            },
            diagnostics,
        ))
    }

    /// The floor and the manipulators' capsule at every output frame, in Y-up metres.
    fn stage(&self, fps: f64, frames: usize) -> BakedStage {
        let z_up = self.frame.up == springbake_core::display::UpAxis::Z;
        let y_up = |v: Vector3<f64>| {
            if z_up {
                [v.x, v.z, -v.y]
            } else {
                [v.x, v.y, v.z]
            }
        };
        let capsules = self
            .world
            .manipulators
            .iter()
            .map(|track| BakedCapsule {
                radius: track.radius,
                length: track.length,
                frames: (0..frames)
                    .map(|f| {
                        let c = track.capsule_at(f as f64 / fps);
                        (y_up(c.centre), y_up(c.axis))
                    })
                    .collect(),
            })
            .collect();
        let colliders = self
            .world
            .colliders()
            .iter()
            .map(|c| BakedCollider {
                name: c.name.clone(),
                positions: c.positions.iter().map(|p| y_up(*p)).collect(),
                triangles: c.triangles.clone(),
            })
            .collect();
        let walls =
            springbake_core::bake::room_of(&self.world.settings.planes, &self.world.settings.up)
                .map(|[lo, hi]| {
                    let (a, b) = (y_up(Vector3::from(lo)), y_up(Vector3::from(hi)));
                    [
                        std::array::from_fn(|k| a[k].min(b[k])),
                        std::array::from_fn(|k| a[k].max(b[k])),
                    ]
                });
        BakedStage {
            floor: self.floor,
            capsules,
            colliders,
            walls,
        }
    }

    fn current_penetration(&self) -> f64 {
        let planes = &self.world.settings.planes;
        self.world
            .nodes
            .position
            .iter()
            .flat_map(|x| planes.iter().map(move |p| p.offset - p.normal.dot(x)))
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::distinct_names;

    fn named(meshes: &[(&str, &str)]) -> Vec<String> {
        let meshes: Vec<(String, String)> = meshes
            .iter()
            .map(|(n, k)| (n.to_string(), k.to_string()))
            .collect();
        distinct_names(&meshes)
    }

    #[test]
    fn shared_names_take_the_tail_of_their_prim_paths_or_a_number() {
        let usd = named(&[
            ("Render", "/Set/White/King/Geom/Render"),
            ("Render", "/Set/Black/King/Geom/Render"),
            ("Render", "/Set/White/Queen/Geom/Render"),
            ("Board", "/Set/Board/Geom/Board"),
        ]);
        assert_eq!(
            usd,
            [
                "White/King/Geom/Render",
                "Black/King/Geom/Render",
                "White/Queen/Geom/Render",
                "Board"
            ]
        );
        let gltf = named(&[("Cube", "node:0"), ("Ball", "node:1"), ("Cube", "node:2")]);
        assert_eq!(gltf, ["Cube", "Ball", "Cube.001"]);
    }
}
