//! The bake's effects beyond the bodies' own physics: particle effects (`[[emitter]]`, see
//! `springbake_core::particles`), emitted and integrated alongside the bodies, frame by frame,
//! in the world's gravity and against its floor and walls (an emitter that follows a body
//! rides on its centre of mass; recorded in Y-up metres for the exporters), and force fields
//! (`[[force_field]]`, plug-ins bound to bodies, see `springbake_core::solver::fields`).

use crate::simulate::Prepared;
use crate::PipelineError;
use springbake_core::bake::BakedParticles;
use springbake_core::display::UpAxis;
use springbake_core::events::{Firing, Procedure};
use springbake_core::nalgebra::Vector3;
use springbake_core::particle_colliders::TriangleGrid;
use springbake_core::particles::{ParticleEnv, ParticleSystem};
use springbake_core::plugin::Registry;
use springbake_core::scene::SceneFile;
use springbake_core::solver::fields::FieldBinding;
use springbake_core::solver::{BodyHandle, World};

/// Binds each `[[force_field]]` to its bodies (all when it names none); an unknown field or
/// body is refused (exit 2) with what there is.
pub fn bind_force_fields(
    scene: &SceneFile,
    registry: &Registry,
    world: &mut World,
    bodies: &[(Option<String>, String, BodyHandle)],
) -> Result<(), PipelineError> {
    for (i, section) in scene.force_field.iter().enumerate() {
        let field = registry.force_field(&section.field).ok_or_else(|| {
            let known: Vec<&str> = registry.force_fields().iter().map(|f| f.name()).collect();
            PipelineError::Usage(format!(
                "force_field[{i}].field: no force field is named {:?} (found: {}); a Python \
                 plug-in of kind \"force_field\" in plugins/ beside the scene provides one",
                section.field,
                if known.is_empty() {
                    "none".to_owned()
                } else {
                    known.join(", ")
                }
            ))
        })?;
        for (section_name, mesh_name, handle) in bodies {
            let named = section.bodies.is_empty()
                || section
                    .bodies
                    .iter()
                    .any(|b| Some(b) == section_name.as_ref() || b == mesh_name);
            if named {
                world.fields.push(FieldBinding {
                    field: field.clone(),
                    nodes: world.bodies[handle.0].nodes.clone(),
                });
            }
        }
        for b in &section.bodies {
            if !bodies
                .iter()
                .any(|(s, m, _)| Some(b) == s.as_ref() || b == m)
            {
                return Err(PipelineError::Usage(format!(
                    "force_field[{i}].bodies: no body is named {b:?}"
                )));
            }
        }
    }
    Ok(())
}

/// The emitters of one bake and what they recorded so far.
pub struct Effects {
    system: Option<ParticleSystem>,
    /// The static colliders the particles bounce off (simulation frame).
    colliders: Option<TriangleGrid>,
    /// Per emitter: the index of the followed body in [`Prepared::bodies`].
    follow: Vec<Option<usize>>,
    recorded: Vec<BakedParticles>,
}

impl Effects {
    /// The scene's emitters; a `follow` that names no body is refused (exit 2).
    pub fn new(scene: &SceneFile, prepared: &Prepared) -> Result<Effects, PipelineError> {
        let mut follow = Vec::new();
        for (i, e) in scene.emitter.iter().enumerate() {
            follow.push(match &e.follow {
                None => None,
                Some(name) => Some(
                    prepared
                        .bodies
                        .iter()
                        .position(|b| {
                            &b.name == name
                                || scene.body.get(b.section).and_then(|s| s.name.as_ref())
                                    == Some(name)
                        })
                        .ok_or_else(|| {
                            let names: Vec<&str> =
                                prepared.bodies.iter().map(|b| b.name.as_str()).collect();
                            PipelineError::Usage(format!(
                                "emitter[{i}].follow names no body: {name:?} (bodies: {})",
                                names.join(", ")
                            ))
                        })?,
                ),
            });
        }
        let system = (!scene.emitter.is_empty()).then(|| ParticleSystem::new(&scene.emitter));
        let recorded = system
            .as_ref()
            .map(|s| {
                s.names()
                    .into_iter()
                    .zip(s.streaks())
                    .map(|(name, streaks)| BakedParticles {
                        name,
                        streaks,
                        frames: Vec::new(),
                    })
                    .collect()
            })
            .unwrap_or_default();
        let colliders = system.as_ref().and_then(|_| {
            let triangles = prepared
                .world
                .colliders()
                .iter()
                .flat_map(|c| {
                    c.triangles
                        .iter()
                        .map(|t| t.map(|i| c.positions[i as usize]))
                })
                .collect();
            TriangleGrid::new(triangles)
        });
        Ok(Effects {
            system,
            colliders,
            follow,
            recorded,
        })
    }

    /// Frame 1 (t = 0): what is due at the start, recorded.
    pub fn start(&mut self, prepared: &Prepared) {
        self.step(prepared, 0.0, 0.0);
    }

    /// The frame from `time` to `time + dt`, recorded at its end.
    pub fn advance(&mut self, prepared: &Prepared, time: f64, dt: f64) {
        self.step(prepared, time, dt);
    }

    fn step(&mut self, prepared: &Prepared, time: f64, dt: f64) {
        let Some(system) = self.system.as_mut() else {
            return;
        };
        let world = &prepared.world;
        let centres: Vec<Option<Vector3<f64>>> = self
            .follow
            .iter()
            .map(|b| {
                b.map(|b| {
                    let nodes = world.bodies[prepared.bodies[b].handle.0].nodes.clone();
                    let (mut moment, mut mass) = (Vector3::zeros(), 0.0);
                    for i in nodes {
                        moment += world.nodes.position[i] * world.nodes.mass[i];
                        mass += world.nodes.mass[i];
                    }
                    if mass > 0.0 {
                        moment / mass
                    } else {
                        Vector3::zeros()
                    }
                })
            })
            .collect();
        let env = ParticleEnv {
            gravity: world.settings.gravity,
            up: prepared.frame.up_vector(),
            planes: &world.settings.planes,
            follow: &centres,
            colliders: self.colliders.as_ref(),
        };
        if dt > 0.0 {
            system.advance(time, dt, &env);
        } else {
            system.emit(time, 0.0, &env);
        }
        let z_up = prepared.frame.up == UpAxis::Z;
        let frames = system.snapshot(time + dt, |v| {
            if z_up {
                [v.x as f32, v.z as f32, -v.y as f32]
            } else {
                [v.x as f32, v.y as f32, v.z as f32]
            }
        });
        for (record, frame) in self.recorded.iter_mut().zip(frames) {
            record.frames.push(frame);
        }
    }

    /// Events' `start_emitter` / `stop_emitter` firings, at `time` (their frame's time).
    pub fn trigger(&mut self, firings: &[Firing], time: f64) {
        let Some(system) = self.system.as_mut() else {
            return;
        };
        for f in firings {
            // The names were checked against the emitters when the scene was validated.
            match &f.procedure {
                Procedure::StartEmitter(name) => {
                    system.start_emitter(name, time);
                }
                Procedure::StopEmitter(name) => {
                    system.stop_emitter(name, time);
                }
                _ => {}
            }
        }
    }

    /// The particles alive at `time` that can be seen (opacity above zero), in the world's
    /// frame: position and width, m (what a viewer draws while it steps the world).
    pub fn visible_now(&self, time: f64) -> Vec<(Vector3<f64>, f64)> {
        let Some(system) = self.system.as_ref() else {
            return Vec::new();
        };
        let frames = system.snapshot(time, |v| [v.x as f32, v.y as f32, v.z as f32]);
        frames
            .iter()
            .flat_map(|f| {
                f.positions
                    .iter()
                    .zip(&f.widths)
                    .zip(&f.opacities)
                    .filter(|(_, &o)| o > 0.0)
                    .map(|((p, &w), _)| {
                        (
                            Vector3::new(p[0].into(), p[1].into(), p[2].into()),
                            w.into(),
                        )
                    })
            })
            .collect()
    }

    /// Every emitter's frames.
    pub fn finish(self) -> Vec<BakedParticles> {
        self.recorded
    }
}
