//! Events in a bake (physics §11, Terasawa §4): the scene's `[[event]]`, `[[trajectory]]` and
//! `[[attach]]` tables and `[[body]] contact_scale` wired to the world.
//!
//! After each output frame the [`EventDriver`] turns the solver's contact log
//! ([`World::frame_contacts`]) into an [`Observation`]: a *collision* for every (body, partner)
//! pair that began touching during the frame (it was not touching at the end of the previous
//! one), with the log's first-touch approach speed and peak force; a *rebound* for every body
//! whose contact with a static surface (the floor, a wall, a collider) ended during the frame,
//! with its centre-of-mass speed away from it (along the plane normal for the floor and walls;
//! the centre-of-mass speed for a collider, whose normal the log does not give). Parting from
//! another body or a manipulator is not a rebound.
//! Partners are named by the other body's event name, `"floor"`, `"wall"`, `"manipulator"` or
//! the collider's name. The event queue answers with firings, applied in their order by
//! [`springbake_core::procedures`]; every firing is logged for the report's `events` array.
//!
//! A body's event name is its `[[body]] name` when given, else its mesh name; an event on a
//! name several bodies share acts on each of them.

use crate::simulate::PreparedBody;
use crate::PipelineError;
use springbake_core::events::{EventQueue, Firing, Observation, Procedure, Trigger};
use springbake_core::lattice::Embedding;
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::plugin::Registry;
use springbake_core::procedures::{
    centre_of_mass, plane_under, BodyModel, BodyMotion, Context, NamedPath,
};
use springbake_core::scene::{PathInterpolation, SceneFile};
use springbake_core::secondary::Attachment;
use springbake_core::solver::{nearest_node, ContactPartner, Interpolation, Path, Plane, World};
use std::collections::{BTreeMap, BTreeSet};

/// The scene's events, motion features and attachments during one bake.
#[derive(Clone)]
pub struct EventDriver {
    queue: EventQueue,
    /// Event name of each prepared body.
    names: Vec<String>,
    /// Prepared body of each world body.
    of_world: Vec<Option<usize>>,
    motions: Vec<BodyMotion>,
    trajectories: BTreeMap<String, NamedPath>,
    attachments: Vec<Attachment>,
    registry: Registry,
    collider_names: Vec<String>,
    /// (world body, partner) pairs touching at the end of the last frame.
    touching: BTreeSet<(usize, ContactPartner)>,
    log: Vec<Firing>,
}

impl std::fmt::Debug for EventDriver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EventDriver")
            .field("names", &self.names)
            .field("pending", &self.queue.pending())
            .field("fired", &self.log.len())
            .finish_non_exhaustive()
    }
}

/// Checks that need only the scene file: the event queue's own rules, material presets,
/// trajectory names and keys, body options.
pub fn validate(scene: &SceneFile) -> Result<(), String> {
    for (i, b) in scene.body.iter().enumerate() {
        if !(b.contact_scale.is_finite() && b.contact_scale > 0.0 && b.contact_scale <= 10.0) {
            return Err(format!(
                "body[{i}].contact_scale must be in (0, 10], got {}",
                b.contact_scale
            ));
        }
        if !(b.bounce_tolerance.is_finite() && b.bounce_tolerance >= 0.0) {
            return Err(format!(
                "body[{i}].bounce_tolerance must be >= 0 m/s, got {}",
                b.bounce_tolerance
            ));
        }
    }
    let mut names = BTreeSet::new();
    for (i, t) in scene.trajectory.iter().enumerate() {
        if t.name.trim().is_empty() || !names.insert(t.name.as_str()) {
            return Err(format!(
                "trajectory[{i}].name must be non-empty and unique, got \"{}\"",
                t.name
            ));
        }
        named_path(t).map_err(|e| format!("trajectory[{i}] \"{}\": {e}", t.name))?;
    }
    EventQueue::new(scene.event.clone()).map_err(|e| e.to_string())?;
    let emitters = springbake_core::particles::ParticleSystem::new(&scene.emitter).names();
    for (i, e) in scene.event.iter().enumerate() {
        for (loc, p) in procedures_of(e) {
            let at = format!("event[{i}] \"{}\".{loc}", e.name);
            match p {
                Procedure::ChangeMaterial(m) => {
                    Material::preset(m).map_err(|err| format!("{at}.change_material: {err}"))?;
                }
                Procedure::StartEmitter(n) | Procedure::StopEmitter(n) if !emitters.contains(n) => {
                    return Err(format!(
                        "{at}: no [[emitter]] is named \"{n}\"; emitters: {}",
                        emitters.join(", ")
                    ));
                }
                Procedure::FollowTrajectory(t) if !names.contains(t.as_str()) => {
                    return Err(format!(
                        "{at}.follow_trajectory: no [[trajectory]] is named \"{t}\"; trajectories: {}",
                        names.iter().copied().collect::<Vec<_>>().join(", ")
                    ));
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// Every procedure of an event with its data path (`procedure[0]`, `branch.case[1].procedure[0]`).
fn procedures_of(e: &springbake_core::events::EventSpec) -> Vec<(String, &Procedure)> {
    let mut out: Vec<(String, &Procedure)> = e
        .procedure
        .iter()
        .enumerate()
        .map(|(k, p)| (format!("procedure[{k}]"), p))
        .collect();
    if let Some(b) = &e.branch {
        for (c, case) in b.cases.iter().enumerate() {
            for (k, p) in case.procedure.iter().enumerate() {
                out.push((format!("branch.case[{c}].procedure[{k}]"), p));
            }
        }
    }
    out
}

fn named_path(t: &springbake_core::scene::TrajectorySection) -> Result<NamedPath, String> {
    if !(0.0..=1.0).contains(&t.strength) {
        return Err(format!("strength must be in [0, 1], got {}", t.strength));
    }
    let keys = t
        .keys
        .iter()
        .map(|k| (k.t, Vector3::from(k.position)))
        .collect();
    let interpolation = match t.interpolation {
        PathInterpolation::Linear => Interpolation::Linear,
        PathInterpolation::CatmullRom => Interpolation::CatmullRom,
    };
    Ok(NamedPath {
        path: Path::new(keys, interpolation).map_err(|e| e.to_string())?,
        strength: t.strength,
    })
}

/// Scale the elastic-layer stiffness of each body's display-surface points by its
/// `contact_scale` (exaggeration).
fn apply_contact_scale(scene: &SceneFile, world: &mut World, bodies: &[PreparedBody]) {
    for b in bodies {
        let s = scene.body[b.section].contact_scale;
        if s == 1.0 {
            continue;
        }
        let surface = std::sync::Arc::make_mut(&mut world.surface);
        for i in 0..surface.len() {
            if surface.body[i] as usize == b.handle.0 {
                surface.share[i] *= s;
            }
        }
    }
}

/// Event name of each prepared body.
fn body_names(scene: &SceneFile, bodies: &[PreparedBody]) -> Vec<String> {
    bodies
        .iter()
        .map(|b| {
            scene.body[b.section]
                .name
                .clone()
                .unwrap_or_else(|| b.name.clone())
        })
        .collect()
}

impl EventDriver {
    /// Wire the scene's events and attachments to a prepared world (and apply every body's
    /// `contact_scale`). `None` when the scene has neither events nor attachments. Errors
    /// name the event or attachment and the field.
    pub(crate) fn wire(
        scene: &SceneFile,
        registry: &Registry,
        world: &mut World,
        bodies: &[PreparedBody],
    ) -> Result<Option<EventDriver>, String> {
        apply_contact_scale(scene, world, bodies);
        if scene.event.is_empty() && scene.attach.is_empty() {
            return Ok(None);
        }
        validate(scene)?;
        let names = body_names(scene, bodies);
        let listed = || {
            let unique: BTreeSet<&str> = names.iter().map(String::as_str).collect();
            unique.into_iter().collect::<Vec<_>>().join(", ")
        };
        let collider_names: Vec<String> =
            world.colliders().iter().map(|c| c.name.clone()).collect();
        for (i, e) in scene.event.iter().enumerate() {
            let at = format!("event[{i}] \"{}\"", e.name);
            if !names.contains(&e.body) {
                return Err(format!(
                    "{at}.body: no body named \"{}\"; bodies: {}",
                    e.body,
                    listed()
                ));
            }
            if let Trigger::Collision(Some(w)) = &e.on {
                let surfaces = ["floor", "wall", "manipulator"];
                if !names.contains(w)
                    && !surfaces.contains(&w.as_str())
                    && !collider_names.contains(w)
                {
                    return Err(format!(
                        "{at}.on.collision: nothing is named \"{w}\"; bodies: {}; surfaces: floor, wall, manipulator{}",
                        listed(),
                        collider_names.iter().map(|c| format!(", {c}")).collect::<String>()
                    ));
                }
            }
            for (loc, p) in procedures_of(e) {
                if let Procedure::Plugin { name, args } = p {
                    let plugin = registry.procedure(name).ok_or_else(|| {
                        format!(
                            "{at}.{loc}: unknown procedure plug-in \"{name}\"; registered: {}",
                            registry.procedure_names().join(", ")
                        )
                    })?;
                    plugin
                        .check(args)
                        .map_err(|m| format!("{at}.{loc}: plug-in \"{name}\": {m}"))?;
                }
            }
        }
        let trajectories = scene
            .trajectory
            .iter()
            .map(|t| Ok((t.name.clone(), named_path(t)?)))
            .collect::<Result<BTreeMap<_, _>, String>>()?;
        let motions = bodies
            .iter()
            .map(|b| {
                let section = &scene.body[b.section];
                let dims = b.lattice.dims.iter().copied().max().unwrap_or(1) as f64;
                BodyMotion::new(BodyModel {
                    handle: b.handle,
                    material: b.material.clone(),
                    cell_size: b.lattice.cell_size,
                    longest_m: dims * b.lattice.cell_size,
                    volume_scale: section.volume_scale,
                    bounce_tolerance: section.bounce_tolerance,
                })
            })
            .collect();
        let mut of_world = vec![None; world.bodies.len()];
        for (i, b) in bodies.iter().enumerate() {
            of_world[b.handle.0] = Some(i);
        }
        let mut attachments = Vec::new();
        for (i, a) in scene.attach.iter().enumerate() {
            let find = |name: &str, field: &str| {
                let found: Vec<usize> = (0..names.len()).filter(|&k| names[k] == name).collect();
                match found.as_slice() {
                    [one] => Ok(*one),
                    [] => Err(format!(
                        "attach[{i}].{field}: no body named \"{name}\"; bodies: {}",
                        listed()
                    )),
                    _ => Err(format!(
                        "attach[{i}].{field}: several bodies are named \"{name}\"; give each [[body]] its own name"
                    )),
                }
            };
            let (child, parent) = (find(&a.child, "child")?, find(&a.parent, "parent")?);
            if child == parent {
                return Err(format!("attach[{i}]: a body cannot be attached to itself"));
            }
            let (c, p) = (&bodies[child], &bodies[parent]);
            let range = world.bodies[c.handle.0].nodes.clone();
            let positions = &world.nodes.position[range.clone()];
            let anchors = a
                .anchors
                .map(|x| nearest_node(positions, Vector3::from(x)).map_or(0, |n| n + range.start));
            let rest: Vec<Point3<f64>> = anchors
                .iter()
                .map(|&n| Point3::from(world.nodes.position[n]))
                .collect();
            let embedding = Embedding::new(&p.lattice, &rest);
            let base = world.bodies[p.handle.0].nodes.start;
            let nodes = [0, 1, 2].map(|k| embedding.nodes[k].map(|n| n as usize + base));
            let weights = [0, 1, 2].map(|k| embedding.weights[k]);
            let attachment = Attachment::new(world, c.handle, p.handle, anchors, nodes, weights)
                .map_err(|e| format!("attach[{i}].anchors: {e}"))?;
            attachments.push(attachment);
        }
        Ok(Some(EventDriver {
            queue: EventQueue::new(scene.event.clone()).map_err(|e| e.to_string())?,
            names,
            of_world,
            motions,
            trajectories,
            attachments,
            registry: registry.clone(),
            collider_names,
            touching: BTreeSet::new(),
            log: Vec::new(),
        }))
    }

    /// The firings so far, in order: the report's `events`.
    pub fn log(&self) -> &[Firing] {
        &self.log
    }

    /// Motion state of each prepared body.
    pub fn motions(&self) -> &[BodyMotion] {
        &self.motions
    }

    fn partner_name(&self, partner: ContactPartner) -> String {
        match partner {
            ContactPartner::Floor => "floor".into(),
            ContactPartner::Wall => "wall".into(),
            ContactPartner::Manipulator(_) => "manipulator".into(),
            ContactPartner::Body(j) => match self.of_world.get(j).copied().flatten() {
                Some(b) => self.names[b].clone(),
                None => format!("body {j}"),
            },
            ContactPartner::Collider(j) => self
                .collider_names
                .get(j)
                .cloned()
                .unwrap_or_else(|| format!("collider {j}")),
        }
    }

    /// Speed of world body `body` away from static surface `partner` now, and the partner's
    /// plane if it is one.
    fn rebound(world: &World, body: usize, partner: ContactPartner) -> (f64, Option<Plane>) {
        let h = springbake_core::solver::BodyHandle(body);
        let (_, c, v) = centre_of_mass(world, h);
        let up = world.settings.up;
        let along = |n: Vector3<f64>| v.dot(&n);
        match partner {
            ContactPartner::Floor => {
                let plane = plane_under(world, h);
                (along(plane.map_or(up, |p| p.normal)), plane)
            }
            ContactPartner::Wall => {
                let nearest = world
                    .settings
                    .planes
                    .iter()
                    .filter(|p| p.normal.dot(&up) <= 0.9)
                    .min_by(|a, b| {
                        let d = |p: &&Plane| p.normal.dot(&c) - p.offset;
                        d(a).total_cmp(&d(b))
                    })
                    .copied();
                (nearest.map_or(v.norm(), |p| along(p.normal)), nearest)
            }
            // Colliders (and, unused, bodies and manipulators): the centre-of-mass speed.
            _ => (v.norm(), None),
        }
    }

    /// Build the observation of the frame just advanced (module docs); returns it with the
    /// rebounds as (prepared body, speed, plane).
    fn observe(
        &mut self,
        world: &World,
        frame: u64,
        fps: f64,
    ) -> (Observation, Vec<(usize, f64, Option<Plane>)>) {
        let mut obs = Observation {
            frame,
            // The frame's nominal time (the world's clock sums substeps, a hair off).
            time_secs: frame.saturating_sub(1) as f64 / fps,
            ..Observation::default()
        };
        let mut rebounds = Vec::new();
        let mut touching = BTreeSet::new();
        for r in world.frame_contacts() {
            let Some(b) = self.of_world.get(r.body).copied().flatten() else {
                continue;
            };
            let key = (r.body, r.partner);
            if r.touching_at_end {
                touching.insert(key);
            }
            let with = self.partner_name(r.partner);
            if !self.touching.contains(&key) {
                obs = obs.with_collision(&self.names[b], with, r.impact_speed, r.peak_force);
            }
            // A rebound is leaving a static surface (the bounce feature's, Terasawa §4.1):
            // parting from another body or a manipulator is not one.
            let static_surface = matches!(
                r.partner,
                ContactPartner::Floor | ContactPartner::Wall | ContactPartner::Collider(_)
            );
            if !r.touching_at_end && static_surface {
                let (speed, plane) = Self::rebound(world, r.body, r.partner);
                obs = obs.with_rebound(&self.names[b], speed);
                rebounds.push((b, speed, plane));
            }
        }
        self.touching = touching;
        (obs, rebounds)
    }

    /// Before the world advances a frame.
    pub(crate) fn before_frame(
        &mut self,
        world: &mut World,
        fps: f64,
    ) -> Result<(), PipelineError> {
        let dt = 1.0 / fps;
        for (m, name) in self.motions.iter_mut().zip(&self.names) {
            m.before_frame(world, dt)
                .map_err(|e| PipelineError::Usage(format!("body \"{name}\": {e}")))?;
        }
        for a in &mut self.attachments {
            a.before_frame(world, dt)
                .map_err(|e| PipelineError::Usage(format!("attach: {e}")))?;
        }
        Ok(())
    }

    /// After the world reached output frame `frame` (1-based; frame 1 is t = 0, before any
    /// step): observe, fire, apply, then place the geometrically controlled bodies.
    pub(crate) fn after_frame(
        &mut self,
        world: &mut World,
        frame: usize,
        fps: f64,
    ) -> Result<(), PipelineError> {
        let (obs, rebounds) = self.observe(world, frame as u64, fps);
        for (b, speed, plane) in rebounds {
            self.motions[b]
                .rebound(world, speed, plane)
                .map_err(|e| PipelineError::Usage(format!("body \"{}\": {e}", self.names[b])))?;
        }
        let firings = self.queue.observe(&obs);
        let ctx = Context {
            frame_dt: 1.0 / fps,
            trajectories: &self.trajectories,
            registry: &self.registry,
        };
        for f in &firings {
            for (b, name) in self.names.iter().enumerate() {
                if *name != f.body {
                    continue;
                }
                self.motions[b]
                    .apply(world, &f.procedure, &ctx)
                    .map_err(|e| {
                        PipelineError::Usage(format!(
                            "frame {}: event \"{}\" on body \"{}\": {e}",
                            f.frame, f.event, f.body
                        ))
                    })?;
            }
        }
        self.log.extend(firings);
        for (m, name) in self.motions.iter_mut().zip(&self.names) {
            m.after_frame(world)
                .map_err(|e| PipelineError::Usage(format!("body \"{name}\": {e}")))?;
        }
        for a in &mut self.attachments {
            a.after_frame(world);
        }
        Ok(())
    }
}

impl crate::simulate::Prepared {
    /// The report's `events`: one `{ frame, body, event, procedure }` per firing, in order.
    pub fn event_report(&self) -> Vec<serde_json::Value> {
        self.events
            .as_ref()
            .map(|e| {
                e.log()
                    .iter()
                    .map(|f| serde_json::to_value(f).unwrap_or(serde_json::Value::Null))
                    .collect()
            })
            .unwrap_or_default()
    }
}
