//! Event procedures on a [`World`] (physics §11; Terasawa §4.1–4.2): what each
//! [`Procedure`] fired by the [`crate::events::EventQueue`] does to a body, and the motion
//! features that keep acting over the following frames. The host calls
//! [`BodyMotion::apply`] for each firing between output frames, [`BodyMotion::before_frame`]
//! before it advances the world by a frame and [`BodyMotion::after_frame`] after.
//!
//! | procedure | what it does |
//! |---|---|
//! | `apply_force` | `F` in N on the whole body (each node gets `F m_i / M`) while `duration_secs` lasts (default: one frame). Applied per output frame as the impulse `F·Δt_overlap`, half before and half after the frame (kick–drift–kick): momentum exact, the force's timing resolved to frames, not substeps |
//! | `apply_impulse` | `J` in N·s: every node's velocity changes by `J / M` |
//! | `set_velocity` | the body's centre-of-mass velocity becomes `v`; its nodes keep their velocities relative to it (the wobble) |
//! | `switch_feature` | ends the body's geometric control (settle, trajectory, roll, bounce rest; not `pin`) and starts a motion feature, below |
//! | `change_material` | a preset: spring constants scaled by `E_new/E_old` (keeps any anisotropy), node masses and the surface points' damper masses by `ρ_new/ρ_old`, dampers re-derived as `2ζ_new sqrt(k μ)`, the deformation-damping rate re-derived |
//! | `pin` / `unpin` | every node held where it is (an exact constant-path constraint) / released, together with `settle` and `follow_trajectory` |
//! | `settle` | stop simulating the body: velocities zeroed, every node held where it is until `unpin` or the next `switch_feature` |
//! | `follow_trajectory` | every node follows the named `[[trajectory]]` path's displacement (key times count from the firing), exactly or loosely by its `strength` |
//! | `volume_scale` | squash and stretch: the body's volume is driven to `s ×` its rest volume (ramped at 2 V₀/s, Terasawa §3.2) |
//! | `anticipate` | the trailing part of the body (nodes weighted 1 at the back to 0 at the front along `velocity`) is drawn back at `pull_back_m / duration_secs` for `duration_secs`, stretching the body against the coming throw; then `set_velocity(velocity)`, and the stretched springs snap it forward |
//! | `start_emitter` / `stop_emitter` | starts the named `[[emitter]]` now (a burst goes off, a stream begins) / stops its stream; the host's particles do it, the body is unchanged |
//! | `plugin` | the named [`ProcedurePlugin`] registered on the host's [`crate::plugin::Registry`]; it may change the nodes and returns built-in procedures (impulse, pin, material, …) applied after it |
//!
//! Motion features (`switch_feature`):
//! - `throw`: dynamics only (gravity, contact); no geometric control.
//! - `bounce`: dynamics with collision response; each time the body leaves a surface the host
//!   reports the rebound speed ([`BodyMotion::rebound`]); the first rebound slower than the
//!   body's `bounce_tolerance` ends the bouncing geometrically: the body is placed with its
//!   lowest surface point on that plane and its normal velocity removed, and from then on,
//!   after every frame, it is kept on the plane that way (tangential motion stays dynamic).
//! - `roll`: geometric rolling without slipping on the plane under the body (the floor): the
//!   body is set down on it, keeps the tangential centre-of-mass speed it had (the previous
//!   feature's), and after every frame is placed exactly at `c(t) = c₀ + v t`, turned about
//!   `n × v̂` by `|v| t / r` (`r`: height of the centre of mass over the plane), node velocities
//!   set to the rolling velocity `v + ω × (x − c)`. Constant speed: no rolling resistance.
//! - `collide`: dynamics with contact response and volume preservation at the body's
//!   `volume_scale` (Terasawa §4.1: struck pins keep their volume); rigid bodies skip the
//!   volume part.
//!
//! Every change to a rigid body's nodes re-seeds its floating frame from them.

use crate::events::{MotionFeature, Procedure};
use crate::material::Material;
use crate::plugin::Registry;
use crate::solver::{BodyHandle, ConstraintError, Path, Plane, TrajectoryConstraint, World};
use nalgebra::{Rotation3, Unit, Vector3};
use std::collections::BTreeMap;

/// A procedure a plug-in provides: scenes run it as `{ plugin = { name, args } }`.
pub trait ProcedurePlugin: Send + Sync {
    /// The name scenes use.
    fn name(&self) -> &str;
    /// Check the arguments when the scene loads; the message says what is wrong.
    fn check(&self, args: &toml::Table) -> Result<(), String>;
    /// Run on `body` of `world` now (between output frames). Returns built-in procedures
    /// for the host to apply to the body next, in order (an impulse, a pin, a material:
    /// what a plug-in cannot do to the nodes alone); not another plug-in.
    fn run(
        &self,
        world: &mut World,
        body: BodyHandle,
        args: &toml::Table,
    ) -> Result<Vec<Procedure>, String>;
}

/// Why a procedure could not be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcedureError {
    #[error("{0}")]
    Constraint(#[from] ConstraintError),
    #[error("no trajectory is named \"{0}\"")]
    UnknownTrajectory(String),
    #[error("no procedure plug-in is named \"{0}\"")]
    UnknownPlugin(String),
    #[error("{0}")]
    Material(String),
    #[error("roll needs a plane under the body (a floor)")]
    NoPlane,
    #[error("plug-in procedure \"{name}\": {message}")]
    Plugin { name: String, message: String },
}

/// A named path for `follow_trajectory`.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedPath {
    pub path: Path,
    /// 1: exact; below: loosely bound.
    pub strength: f64,
}

/// What procedures need from the host besides the world.
pub struct Context<'a> {
    /// Length of an output frame, s.
    pub frame_dt: f64,
    /// `[[trajectory]]` paths by name, key times relative to the firing.
    pub trajectories: &'a BTreeMap<String, NamedPath>,
    /// The host's plug-ins (for `plugin` procedures).
    pub registry: &'a Registry,
}

/// What the host knows about a body beyond its nodes and springs.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyModel {
    pub handle: BodyHandle,
    pub material: Material,
    /// Lattice cell edge, m.
    pub cell_size: f64,
    /// Longest side of the lattice, m (for the deformation-damping rate).
    pub longest_m: f64,
    /// Volume target of the `collide` feature, × rest volume.
    pub volume_scale: f64,
    /// Rebound speed under which `bounce` settles, m/s.
    pub bounce_tolerance: f64,
}

/// Geometric control of a body by the current motion feature.
#[derive(Debug, Clone, PartialEq)]
enum Control {
    None,
    /// `settle`: all nodes held (the constraint added to the world).
    Held(TrajectoryConstraint),
    Trajectory(TrajectoryConstraint),
    Roll(Roll),
    /// `bounce` after its rebounds fell under the tolerance: kept on this plane.
    Resting(Plane),
}

/// Anticipation in progress.
#[derive(Debug, Clone, PartialEq)]
struct Anticipation {
    release_at: f64,
    velocity: Vector3<f64>,
    /// Pull-back velocity of a node of weight 1 (unit throw direction times speed).
    pull: Vector3<f64>,
    /// Per node of the body, 1 at the back to 0 at the front.
    weights: Vec<f64>,
}

/// One body's motion state: its feature, geometric control and timed procedures.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyMotion {
    pub model: BodyModel,
    /// The last feature switched to (none until a `switch_feature`).
    pub feature: Option<MotionFeature>,
    pin: Option<TrajectoryConstraint>,
    control: Control,
    /// Forces (N) acting until a time (s).
    forces: Vec<(Vector3<f64>, f64)>,
    /// The second half of this frame's force impulse, velocity change (after the frame).
    half_kick: Vector3<f64>,
    anticipation: Option<Anticipation>,
    /// Whether the floating frame was set aside while the body is held (rigid bodies).
    was_rigid: bool,
}

/// Mass, centre of mass and its velocity of a body.
pub fn centre_of_mass(world: &World, body: BodyHandle) -> (f64, Vector3<f64>, Vector3<f64>) {
    let n = &world.nodes;
    let (mut m, mut mx, mut mv) = (0.0, Vector3::zeros(), Vector3::zeros());
    for i in world.bodies[body.0].nodes.clone() {
        m += n.mass[i];
        mx += n.position[i] * n.mass[i];
        mv += n.velocity[i] * n.mass[i];
    }
    if m > 0.0 {
        (m, mx / m, mv / m)
    } else {
        (0.0, Vector3::zeros(), Vector3::zeros())
    }
}

/// Re-seed a rigid body's floating frame from its nodes after they were changed directly.
fn reseed_rigid(world: &mut World, body: BodyHandle) -> Result<(), ProcedureError> {
    if world.rigid.iter().any(|r| r.body == body.0) {
        world.make_rigid(body)?;
    }
    Ok(())
}

/// Add `dv` to every node's velocity.
pub fn add_velocity(
    world: &mut World,
    body: BodyHandle,
    dv: Vector3<f64>,
) -> Result<(), ProcedureError> {
    for i in world.bodies[body.0].nodes.clone() {
        world.nodes.velocity[i] += dv;
    }
    reseed_rigid(world, body)
}

/// Move every node of the body by `shift`, its velocities unchanged.
pub fn translate_body(
    world: &mut World,
    body: BodyHandle,
    shift: Vector3<f64>,
) -> Result<(), ProcedureError> {
    for i in world.bodies[body.0].nodes.clone() {
        world.nodes.position[i] += shift;
    }
    reseed_rigid(world, body)
}

/// Lowest height of the body over `plane`: of its display-surface points when it has them,
/// else of its nodes.
pub fn lowest_over(world: &World, body: BodyHandle, plane: &Plane) -> f64 {
    let s = &world.surface;
    let pos = &world.nodes.position;
    let height = |x: Vector3<f64>| plane.normal.dot(&x) - plane.offset;
    let mut lowest = f64::INFINITY;
    for i in (0..s.len()).filter(|&i| s.body[i] as usize == body.0) {
        let x: Vector3<f64> = (0..8)
            .map(|c| pos[s.nodes[i][c] as usize] * s.weights[i][c])
            .sum();
        lowest = lowest.min(height(x));
    }
    if lowest.is_finite() {
        return lowest;
    }
    world.bodies[body.0]
        .nodes
        .clone()
        .map(|i| height(pos[i]))
        .fold(f64::INFINITY, f64::min)
}

/// Put the body down on `plane` (its lowest point on it) and remove the normal component of
/// its centre-of-mass velocity.
pub fn place_on_plane(
    world: &mut World,
    body: BodyHandle,
    plane: &Plane,
) -> Result<(), ProcedureError> {
    let lift = -lowest_over(world, body, plane);
    let (_, _, v) = centre_of_mass(world, body);
    let dv = -plane.normal * plane.normal.dot(&v);
    for i in world.bodies[body.0].nodes.clone() {
        world.nodes.velocity[i] += dv;
    }
    translate_body(world, body, plane.normal * lift)
}

/// The plane under a body: the world plane most nearly facing `up` that the body is above.
pub fn plane_under(world: &World, body: BodyHandle) -> Option<Plane> {
    let (_, c, _) = centre_of_mass(world, body);
    let up = world.settings.up;
    world
        .settings
        .planes
        .iter()
        .filter(|p| p.normal.dot(&up) > 0.9 && p.normal.dot(&c) >= p.offset)
        .max_by(|a, b| a.offset.total_cmp(&b.offset))
        .copied()
}

/// Geometric rolling without slipping (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Roll {
    plane: Plane,
    start_time: f64,
    centre: Vector3<f64>,
    velocity: Vector3<f64>,
    radius: f64,
    offsets: Vec<Vector3<f64>>,
}

impl Roll {
    /// Set the body down on `plane` and start rolling with its tangential velocity.
    pub fn start(
        world: &mut World,
        body: BodyHandle,
        plane: Plane,
    ) -> Result<Roll, ProcedureError> {
        place_on_plane(world, body, &plane)?;
        let (_, c, v) = centre_of_mass(world, body);
        let n = plane.normal;
        let radius = (n.dot(&c) - plane.offset).max(1e-6);
        let roll = Roll {
            plane,
            start_time: world.time,
            centre: c,
            velocity: v - n * n.dot(&v),
            radius,
            offsets: world.bodies[body.0]
                .nodes
                .clone()
                .map(|i| world.nodes.position[i] - c)
                .collect(),
        };
        roll.place(world, body)?;
        Ok(roll)
    }

    /// Angular velocity of the roll.
    pub fn angular_velocity(&self) -> Vector3<f64> {
        self.plane.normal.cross(&self.velocity) / self.radius
    }

    /// Place the body's nodes on the rolling path at the world's time.
    pub fn place(&self, world: &mut World, body: BodyHandle) -> Result<(), ProcedureError> {
        let t = world.time - self.start_time;
        let c = self.centre + self.velocity * t;
        let omega = self.angular_velocity();
        let rotation = match Unit::try_new(omega, 1e-12) {
            Some(axis) => Rotation3::from_axis_angle(&axis, omega.norm() * t),
            None => Rotation3::identity(),
        };
        for (j, i) in world.bodies[body.0].nodes.clone().enumerate() {
            let r = rotation * self.offsets[j];
            world.nodes.position[i] = c + r;
            world.nodes.velocity[i] = self.velocity + omega.cross(&r);
        }
        reseed_rigid(world, body)
    }
}

impl BodyMotion {
    pub fn new(model: BodyModel) -> BodyMotion {
        BodyMotion {
            model,
            feature: None,
            pin: None,
            control: Control::None,
            forces: Vec::new(),
            half_kick: Vector3::zeros(),
            anticipation: None,
            was_rigid: false,
        }
    }

    fn handle(&self) -> BodyHandle {
        self.model.handle
    }

    /// Whether the body is rolling geometrically now.
    pub fn is_rolling(&self) -> bool {
        matches!(self.control, Control::Roll(_))
    }

    /// Whether the body is held by `pin` or `settle`.
    pub fn is_held(&self) -> bool {
        self.pin.is_some() || matches!(self.control, Control::Held(_))
    }

    /// Whether a bounce has settled onto a plane.
    pub fn is_resting(&self) -> bool {
        matches!(self.control, Control::Resting(_))
    }

    /// Hold every node of the body where it is (rigid bodies leave their floating frame while
    /// held: path constraints do not act on rigid nodes).
    fn hold(
        &mut self,
        world: &mut World,
        path: Option<(Path, f64)>,
    ) -> Result<TrajectoryConstraint, ProcedureError> {
        let h = self.handle();
        if world.rigid.iter().any(|r| r.body == h.0) {
            world.rigid.retain(|r| r.body != h.0);
            self.was_rigid = true;
        }
        let nodes: Vec<usize> = world.bodies[h.0].nodes.clone().collect();
        let index = match path {
            None => {
                for &i in &nodes {
                    world.nodes.velocity[i] = Vector3::zeros();
                }
                world.pin(&nodes)?
            }
            Some((path, strength)) => world.add_trajectory(&nodes, path, strength)?,
        };
        Ok(world.constraints[index].clone())
    }

    /// Remove a constraint this body added; restore its floating frame when nothing holds it.
    fn release(
        &mut self,
        world: &mut World,
        c: &TrajectoryConstraint,
    ) -> Result<(), ProcedureError> {
        if let Some(k) = world.constraints.iter().position(|x| x == c) {
            world.constraints.remove(k);
        }
        let still_held =
            self.pin.is_some() || matches!(self.control, Control::Held(_) | Control::Trajectory(_));
        if self.was_rigid && !still_held {
            self.was_rigid = false;
            world.make_rigid(self.handle())?;
        }
        Ok(())
    }

    /// End the current geometric control (not `pin`).
    fn end_control(&mut self, world: &mut World) -> Result<(), ProcedureError> {
        match std::mem::replace(&mut self.control, Control::None) {
            Control::Held(c) | Control::Trajectory(c) => self.release(world, &c),
            Control::None | Control::Roll(_) | Control::Resting(_) => Ok(()),
        }
    }

    /// Run one firing's procedure on this body now.
    pub fn apply(
        &mut self,
        world: &mut World,
        procedure: &Procedure,
        ctx: &Context,
    ) -> Result<(), ProcedureError> {
        let h = self.handle();
        match procedure {
            Procedure::ApplyForce {
                force_n,
                duration_secs,
            } => {
                let until = world.time + duration_secs.unwrap_or(ctx.frame_dt);
                self.forces.push((Vector3::from(*force_n), until));
                Ok(())
            }
            Procedure::ApplyImpulse(j) => {
                let (m, _, _) = centre_of_mass(world, h);
                if m > 0.0 {
                    add_velocity(world, h, Vector3::from(*j) / m)?;
                }
                Ok(())
            }
            Procedure::SetVelocity(v) => {
                let (_, _, now) = centre_of_mass(world, h);
                add_velocity(world, h, Vector3::from(*v) - now)
            }
            Procedure::SwitchFeature(f) => self.switch(world, *f),
            Procedure::ChangeMaterial(name) => {
                let to =
                    Material::preset(name).map_err(|e| ProcedureError::Material(e.to_string()))?;
                change_material(world, &mut self.model, to)
            }
            Procedure::Pin => {
                if self.pin.is_none() {
                    let c = self.hold(world, None)?;
                    self.pin = Some(c);
                }
                Ok(())
            }
            Procedure::Unpin => {
                self.end_control(world)?;
                if let Some(c) = self.pin.take() {
                    self.release(world, &c)?;
                }
                Ok(())
            }
            Procedure::Settle => {
                self.end_control(world)?;
                let c = self.hold(world, None)?;
                self.control = Control::Held(c);
                Ok(())
            }
            Procedure::FollowTrajectory(name) => {
                let named = ctx
                    .trajectories
                    .get(name)
                    .ok_or_else(|| ProcedureError::UnknownTrajectory(name.clone()))?;
                let shifted: Vec<(f64, Vector3<f64>)> = named
                    .path
                    .keys()
                    .iter()
                    .map(|&(t, x)| (t + world.time, x))
                    .collect();
                let path = Path::new(shifted, named.path.interpolation)?;
                self.end_control(world)?;
                let c = self.hold(world, Some((path, named.strength)))?;
                self.control = Control::Trajectory(c);
                Ok(())
            }
            Procedure::VolumeScale(s) => set_volume_scale(world, h, *s),
            Procedure::Anticipate {
                velocity,
                pull_back_m,
                duration_secs,
            } => {
                let v = Vector3::from(*velocity);
                let u = v.normalize();
                let (_, c, _) = centre_of_mass(world, h);
                let along: Vec<f64> = world.bodies[h.0]
                    .nodes
                    .clone()
                    .map(|i| (world.nodes.position[i] - c).dot(&u))
                    .collect();
                let (lo, hi) = along
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &s| {
                        (a.min(s), b.max(s))
                    });
                let span = (hi - lo).max(1e-12);
                self.anticipation = Some(Anticipation {
                    release_at: world.time + duration_secs,
                    velocity: v,
                    pull: -u * (pull_back_m / duration_secs),
                    weights: along.iter().map(|s| (hi - s) / span).collect(),
                });
                Ok(())
            }
            // The host's particles act on these (`pipeline::effects`); the body is not changed.
            Procedure::StartEmitter(_) | Procedure::StopEmitter(_) => Ok(()),
            Procedure::Plugin { name, args } => {
                let plugin = ctx
                    .registry
                    .procedure(name)
                    .ok_or_else(|| ProcedureError::UnknownPlugin(name.clone()))?;
                let then =
                    plugin
                        .run(world, h, args)
                        .map_err(|message| ProcedureError::Plugin {
                            name: name.clone(),
                            message,
                        })?;
                reseed_rigid(world, h)?;
                for next in &then {
                    if let Procedure::Plugin { name: other, .. } = next {
                        return Err(ProcedureError::Plugin {
                            name: name.clone(),
                            message: format!(
                                "returned the plug-in procedure \"{other}\"; a plug-in may \
                                 return built-in procedures only"
                            ),
                        });
                    }
                    self.apply(world, next, ctx)?;
                }
                Ok(())
            }
        }
    }

    /// Start motion feature `f` (module docs).
    fn switch(&mut self, world: &mut World, f: MotionFeature) -> Result<(), ProcedureError> {
        let h = self.handle();
        self.end_control(world)?;
        self.feature = Some(f);
        match f {
            MotionFeature::Throw | MotionFeature::Bounce => Ok(()),
            MotionFeature::Roll => {
                let plane = plane_under(world, h).ok_or(ProcedureError::NoPlane)?;
                self.control = Control::Roll(Roll::start(world, h, plane)?);
                Ok(())
            }
            MotionFeature::Collide => {
                let rigid = world.rigid.iter().any(|r| r.body == h.0);
                let has_cells = !world.bodies[h.0].cells.is_empty();
                if !rigid && has_cells && !world.volume.iter().any(|v| v.body == h.0) {
                    world.preserve_volume(h, self.model.volume_scale)?;
                }
                Ok(())
            }
        }
    }

    /// The host saw the body leave a surface at `speed` m/s (along the surface normal);
    /// `plane`: that surface when it is one of the world's planes.
    pub fn rebound(
        &mut self,
        world: &mut World,
        speed: f64,
        plane: Option<Plane>,
    ) -> Result<(), ProcedureError> {
        let bouncing = self.feature == Some(MotionFeature::Bounce) && self.control == Control::None;
        if let (true, Some(plane)) = (bouncing && speed.abs() < self.model.bounce_tolerance, plane)
        {
            place_on_plane(world, self.handle(), &plane)?;
            self.control = Control::Resting(plane);
        }
        Ok(())
    }

    /// Before the world advances a frame from its time: timed forces and anticipation.
    pub fn before_frame(&mut self, world: &mut World, frame_dt: f64) -> Result<(), ProcedureError> {
        let h = self.handle();
        let t = world.time;
        let (m, _, _) = centre_of_mass(world, h);
        let mut dv = Vector3::zeros();
        for &(f, until) in &self.forces {
            let overlap = (until.min(t + frame_dt) - t).max(0.0);
            if m > 0.0 {
                dv += f * (overlap / m);
            }
        }
        self.forces.retain(|&(_, until)| until > t + frame_dt);
        // Half the frame's impulse now, half after the frame (kick–drift–kick): a force that
        // balances gravity holds a body still, with no drift.
        self.half_kick = dv * 0.5;
        if dv != Vector3::zeros() {
            add_velocity(world, h, self.half_kick)?;
        }
        if let Some(a) = &self.anticipation {
            if t + 1e-9 >= a.release_at {
                let v = a.velocity;
                self.anticipation = None;
                let (_, _, now) = centre_of_mass(world, h);
                add_velocity(world, h, v - now)?;
            } else {
                let u = a.pull.normalize();
                for (j, i) in world.bodies[h.0].nodes.clone().enumerate() {
                    let v = &mut world.nodes.velocity[i];
                    let target = a.pull * a.weights[j];
                    // Replace the component along the throw with the pull-back.
                    *v += u * (target.dot(&u) - v.dot(&u)) * a.weights[j];
                }
                reseed_rigid(world, h)?;
            }
        }
        Ok(())
    }

    /// After the world advanced a frame: geometric controls that place the body.
    pub fn after_frame(&mut self, world: &mut World) -> Result<(), ProcedureError> {
        let h = self.handle();
        let kick = std::mem::replace(&mut self.half_kick, Vector3::zeros());
        if kick != Vector3::zeros() {
            add_velocity(world, h, kick)?;
        }
        match &self.control {
            Control::Roll(r) => r.place(world, h),
            Control::Resting(plane) => place_on_plane(world, h, plane),
            Control::None | Control::Held(_) | Control::Trajectory(_) => Ok(()),
        }
    }
}

/// Drive `body`'s volume to `scale ×` its rest volume (an existing volume constraint keeps its
/// rest volume; else the volume now is the rest volume).
pub fn set_volume_scale(
    world: &mut World,
    body: BodyHandle,
    scale: f64,
) -> Result<(), ProcedureError> {
    if let Some(v) = world.volume.iter_mut().find(|v| v.body == body.0) {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(ConstraintError::BadVolumeScale(scale).into());
        }
        v.scale = scale;
        return Ok(());
    }
    world.preserve_volume(body, scale)?;
    Ok(())
}

/// Swap a body's material (see the module docs).
pub fn change_material(
    world: &mut World,
    model: &mut BodyModel,
    to: Material,
) -> Result<(), ProcedureError> {
    let h = model.handle;
    let from = &model.material;
    let k_ratio = to.young_pa / from.young_pa;
    let rho_ratio = to.density_kg_m3 / from.density_kg_m3;
    // Scales every spring constant (and marks the world's derived step data stale).
    world.scale_stiffness_per_axis(h, Vector3::repeat(k_ratio))?;
    let info = world.bodies[h.0].clone();
    for i in info.nodes.clone() {
        world.nodes.mass[i] *= rho_ratio;
        if world.nodes.inv_mass[i] > 0.0 {
            world.nodes.inv_mass[i] = 1.0 / world.nodes.mass[i];
        }
    }
    let s = &mut world.springs;
    for i in info.springs.clone() {
        let (ma, mb) = (
            world.nodes.mass[s.a[i] as usize],
            world.nodes.mass[s.b[i] as usize],
        );
        let mu = ma * mb / (ma + mb);
        s.damping[i] = 2.0 * to.damping_ratio * (s.stiffness[i] * mu).sqrt();
    }
    let surface = std::sync::Arc::make_mut(&mut world.surface);
    for i in 0..surface.len() {
        if surface.body[i] as usize == h.0 {
            surface.body_mass[i] *= rho_ratio;
        }
    }
    world.bodies[h.0].deformation_damping = crate::solver::deformation_damping::damping_rate(
        to.damping_ratio,
        to.young_pa,
        to.density_kg_m3,
        model.longest_m,
    );
    if let Some(body) = world.bodies.get_mut(h.0) {
        // The XPBD cells take E from the material itself: undo the uniform factor the
        // spring pass above recorded (any anisotropy stays).
        body.axis_stiffness = body.axis_stiffness.map(|s| s / k_ratio);
        body.material = Some(to.clone());
    }
    world.invalidate_prepared();
    model.material = to;
    reseed_rigid(world, h)
}
