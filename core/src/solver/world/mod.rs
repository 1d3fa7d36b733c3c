//! The [`World`]: every body's nodes and springs, the rigid surfaces and manipulators, and the
//! stepping loop (symplectic Euler, Miyazaki §3.4 order: forces → velocity update → velocity
//! dispersion → position update; or Newmark-β, see [`super::newmark`]), then the constraints of
//! the step: path constraints under symplectic Euler, rigid frames, volume preservation.
//! This module is the composition: the state ([`World`]), the frame loop
//! ([`World::advance_frame`]: substeps from the integrator, or from an attached device, see
//! [`super::device`]) and the stages every integrator shares after its substep (rigid frames,
//! volume, joints). Around it: `build` (adding bodies, surfaces, pins, paths, volume and rigid
//! kinds), `surface` (display-surface contact points), `measures` (diagnostics, energies,
//! contacts for overlays, memory), `prepared` (what the papers' integrators derive once), and
//! `euler` (the symplectic-Euler step, bit-for-bit tests in `tests`); the default XPBD step is
//! [`super::xpbd`].

use super::body_contact::{step_contacts, BodyContact};
use super::constraints::{ConstraintError, Path, TrajectoryConstraint, Wind};
use super::contact::{
    beyond_reach, bounding_box, box_may_touch, node_contacts, touches_any, ContactLayer, Plane,
    CONTACT_BLOCK,
};
use super::contact_log::{ContactLog, ContactRecord, RigidScene};
use super::deformation_damping::RigidScratch;
use super::diagnostics::{FrameDiagnostics, SimulationError, StepStats};
use super::forces::{gathered_spring_force, spring_energy, spring_forces, Adjacency, FloorOutput};
use super::integrator::{FrameAccumulator, Integrator};
use super::manipulator::{Capsule, ManipulatorTrack};
use super::miyazaki1996_velocity_dispersion::{
    disperse_with, DispersionMode, DispersionScratch, SpringColouring, SpringHints,
};
use super::newmark::NewmarkState;
use super::rigid::RigidBody;
use super::stencil::{FloorInput, LatticeGrid, StencilPlan};
use super::substeps::{accuracy_step, SubstepChoice};
use super::volume::{cells_volume, correct_volume, VolumeConstraint};
use super::{deterministic_sum, parallel_max, NodeState, SpringSet, PAR_CHUNK};
use crate::lattice::Lattice;
use crate::lattice::CORNERS;
use crate::material::Material;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use std::ops::Range;

mod build;
mod euler;
mod measures;
mod prepared;
mod redo;
mod surface;

pub(crate) use euler::SymplecticEuler;
use prepared::Prepared;
pub use surface::SurfacePoints;

/// World-wide settings, SI units, world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldSettings {
    /// Gravitational acceleration vector, m/s².
    pub gravity: Vector3<f64>,
    /// Unit up vector (for gravity energy and the manipulator's yaw).
    pub up: Vector3<f64>,
    /// Rigid surfaces: the floor and the room's walls.
    pub planes: Vec<Plane>,
    pub layer: ContactLayer,
    pub dispersion: DispersionMode,
    pub max_dispersion_iterations: u32,
    /// N of the accuracy bound ΔT < T_s / N.
    pub accuracy_n: f64,
    /// A fixed number of substeps per frame instead of the automatic choice.
    pub fixed_substeps: Option<u32>,
    /// Automatic substeps also keep every node's travel per substep under this fraction of the
    /// shortest spring (physics §7b, "substeps from node speeds").
    pub max_travel_fraction: f64,
    /// Time integration (default: symplectic Euler, today's behaviour bit for bit).
    pub integrator: Integrator,
    /// Air drag towards a gusting wind on every node (default: none).
    pub wind: Option<Wind>,
}

impl Default for WorldSettings {
    fn default() -> Self {
        WorldSettings {
            gravity: Vector3::new(0.0, -9.81, 0.0),
            up: Vector3::y(),
            planes: Vec::new(),
            layer: ContactLayer {
                thickness_m: 0.01,
                stiffness: 1.0e4,
                damping_ratio: 0.3,
                friction: 0.4,
            },
            dispersion: DispersionMode::Bounded,
            max_dispersion_iterations: 32,
            accuracy_n: 10.0,
            fixed_substeps: None,
            max_travel_fraction: 0.2,
            integrator: Integrator::SymplecticEuler,
            wind: None,
        }
    }
}

impl WorldSettings {
    /// The default elastic layer for a lattice of cell size `cell_m` in `material`: half a cell
    /// thick, ten times an edge spring's stiffness (a resting body sinks a tiny fraction of
    /// the layer), damping ratio 0.3.
    pub fn default_layer(cell_m: f64, material: &Material, friction: f64) -> ContactLayer {
        ContactLayer {
            thickness_m: 0.5 * cell_m,
            stiffness: 10.0 * material.spring_constant(cell_m),
            damping_ratio: 0.3,
            friction,
        }
    }
}

/// Index of a body in its world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BodyHandle(pub usize);

/// A body's share of the world's arrays.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyInfo {
    pub name: String,
    pub nodes: Range<usize>,
    pub springs: Range<usize>,
    /// Lattice cells (8 world node indices each), for the inverted-cell count.
    pub cells: Vec<[u32; 8]>,
    /// Damping rate of the deformation relative to the rigid motion, 1/s (0: none); see
    /// [`super::deformation_damping`].
    pub deformation_damping: f64,
    /// Where a lattice body's nodes sit on its grid (`None` for other models): lets the
    /// step evaluate its springs by stencil (see [`super::stencil`]).
    pub grid: Option<LatticeGrid>,
    /// The body's material (lattice and cage bodies): the XPBD solver's cells take their
    /// Young's modulus and Poisson ratio from it ([`super::xpbd`]).
    pub material: Option<Material>,
    /// Per cell: stiffness factor set by regions and by how much of the cell the mesh fills
    /// (empty: 1 everywhere).
    pub cell_stiffness: Vec<f64>,
    /// Per cell: how much of it the mesh fills ([`World::set_cell_fill`]; empty: whole
    /// cells). Its mass and stiffness both take the factor, so its wave speed does not.
    pub cell_fill: Vec<f64>,
    /// Stiffness factor per axis (anisotropy, [`World::scale_stiffness_per_axis`]): the XPBD
    /// cells weight their strain components by it.
    pub axis_stiffness: [f64; 3],
}

/// All simulated bodies and what they touch.
#[derive(Debug, Clone)]
pub struct World {
    pub settings: WorldSettings,
    pub nodes: NodeState,
    pub springs: SpringSet,
    pub bodies: Vec<BodyInfo>,
    pub manipulators: Vec<ManipulatorTrack>,
    /// Capsules driven directly (the viewer's live mode), in addition to the tracks.
    pub live_capsules: Vec<Capsule>,
    /// Simulated time, seconds.
    pub time: f64,
    /// Points of the display surfaces that take the rigid contacts of their bodies (shared
    /// with the copy a frame may be taken again from: `Arc::make_mut` to change them).
    pub surface: std::sync::Arc<SurfacePoints>,
    /// Per node: whether the node itself takes rigid contacts (false for the nodes of a body
    /// with a contact surface: its mesh touches the floor, not its lattice).
    pub node_contact: Vec<bool>,
    /// Pin and trajectory constraints (see [`super::constraints`]), applied in order.
    pub constraints: Vec<TrajectoryConstraint>,
    /// Bodies whose volume is preserved (see [`super::volume`]).
    pub volume: Vec<VolumeConstraint>,
    /// Bodies stepped as rigid bodies (see [`super::rigid`]); path constraints and volume
    /// preservation do not act on their nodes.
    pub rigid: Vec<RigidBody>,
    /// Shared joint nodes of articulated bodies (see [`super::joints`]), synced after each
    /// step.
    pub joints: Vec<super::joints::SharedNode>,
    /// Force fields bound to bodies (see [`super::fields`]).
    pub fields: Vec<super::fields::FieldBinding>,
    /// Their forces per node, N (empty without fields).
    pub(crate) field_force: Vec<Vector3<f64>>,
    /// The first failure of a field this frame.
    pub(crate) field_error: Option<String>,
    /// Newmark-β state (the previous step's accelerations), once a Newmark step ran.
    pub(crate) newmark: Option<NewmarkState>,
    /// What each body touched during the last frame (see [`super::contact_log`]).
    pub(crate) contact_log: ContactLog,
    /// Body–body and body–collider contact (see [`super::body_contact`]).
    pub(crate) body_contact: BodyContact,
    /// Whether the XPBD solver holds bodies far too stiff for their lattice to bend at its
    /// substeps (wood, steel) to their best-fit rigid motion (default; see
    /// `super::xpbd::held`). Off, they are solved as elastic cells like any other body,
    /// and bend as if their material were far softer.
    pub hold_stiff_bodies: bool,
    /// Rest position of every node (where it was added): the XPBD cells' rest shapes.
    pub(crate) rest: Vec<Vector3<f64>>,
    /// The XPBD solver's derived model and buffers, built at its first step.
    pub(crate) xpbd: Option<super::xpbd::Model>,
    /// The total energy the bodies had at the start of the first frame, plus the work done
    /// on them since and what changed between frames (see [`FrameDiagnostics::energy_gain`]),
    /// and their total energy at the end of the last frame, J.
    energy_budget: Option<(f64, f64)>,
    /// The elastic energy last measured, keyed by the time and the positions' fingerprint
    /// (see [`World::frame_energies`]).
    elastic_memo: Option<((u64, u64), f64)>,
    prepared: Option<Prepared>,
    /// A device that steps the frames instead of the CPU (see [`super::device`]).
    pub(crate) device: super::device::DeviceSlot,
    /// Buffers of the step's constraint, rigid-body and volume passes, reused.
    scratch: StepScratch,
}

/// Buffers [`World::step`] reuses for the passes around the integrator, so a step allocates
/// nothing once they have grown.
#[derive(Debug, Clone, Default)]
struct StepScratch {
    /// Per rigid body: its nodes' positions and velocities at the step's start.
    rigid_before: Vec<Vec<(Vector3<f64>, Vector3<f64>)>>,
    /// Per path constraint: its nodes' positions at the step's start.
    constrained_before: Vec<Vec<Vector3<f64>>>,
    /// Volume gradient per node of the body being corrected.
    volume_grad: Vec<Vector3<f64>>,
}

impl World {
    pub fn new(settings: WorldSettings) -> World {
        World {
            settings,
            nodes: NodeState::default(),
            springs: SpringSet::default(),
            bodies: Vec::new(),
            manipulators: Vec::new(),
            live_capsules: Vec::new(),
            time: 0.0,
            surface: Default::default(),
            node_contact: Vec::new(),
            constraints: Vec::new(),
            volume: Vec::new(),
            rigid: Vec::new(),
            joints: Vec::new(),
            fields: Vec::new(),
            field_force: Vec::new(),
            field_error: None,
            newmark: None,
            contact_log: ContactLog::default(),
            body_contact: BodyContact::default(),
            hold_stiff_bodies: true,
            rest: Vec::new(),
            xpbd: None,
            energy_budget: None,
            elastic_memo: None,
            prepared: None,
            device: Default::default(),
            scratch: StepScratch::default(),
        }
    }

    /// Drop the derived step data (adjacency, colouring, step bounds) after changing nodes or
    /// springs from outside this module (joints, regions, cage contact surfaces).
    pub fn invalidate_prepared(&mut self) {
        self.prepared = None;
        self.xpbd = None;
    }

    /// Substeps for an output frame of `frame_dt` seconds: the scene's fixed count, else the
    /// integrator's choice ([`super::integrator::Integrate::choose_substeps`]).
    pub fn choose_substeps(&mut self, frame_dt: f64) -> SubstepChoice {
        if let Some(n) = self.settings.fixed_substeps {
            return SubstepChoice {
                substeps: n.max(1),
                dt: frame_dt / n.max(1) as f64,
                limited_by: "fixed",
            };
        }
        let integrator = self.settings.integrator;
        integrator.choose_substeps(self, frame_dt)
    }

    /// One step of `dt` seconds, on the CPU (an attached device is let go: its state would
    /// be behind).
    pub fn step(&mut self, dt: f64) -> StepStats {
        self.device = Default::default();
        let mut acc = FrameAccumulator::default();
        on_worker(self.parallel_size(), || self.step_accumulate(dt, &mut acc))
    }

    /// One substep: the integrator's ([`super::integrator`]), then the stages every integrator
    /// shares: rigid bodies' frames, volume preservation, joints. Nothing is allocated once the
    /// prepared buffers exist; every parallel loop runs over fixed chunks, so the result does
    /// not depend on the thread count.
    fn step_accumulate(&mut self, dt: f64, acc: &mut FrameAccumulator) -> StepStats {
        let rigid_before = &mut self.scratch.rigid_before;
        rigid_before.resize_with(self.rigid.len(), Vec::new);
        for (r, before) in self.rigid.iter().zip(rigid_before.iter_mut()) {
            before.clear();
            before.extend(
                self.bodies[r.body]
                    .nodes
                    .clone()
                    .map(|i| (self.nodes.position[i], self.nodes.velocity[i])),
            );
        }
        super::fields::refresh(self, true);
        let integrator = self.settings.integrator;
        let mut stats = integrator.substep(self, dt, acc);
        let mut scratch = std::mem::take(&mut self.scratch);
        for (r, before) in self.rigid.iter_mut().zip(&scratch.rigid_before) {
            let range = self.bodies[r.body].nodes.clone();
            r.advance(&mut self.nodes, range, before, dt);
        }
        // Volume preservation after the unconstrained step (Terasawa §3.2).
        for vc in &mut self.volume {
            let Some(body) = self.bodies.get(vc.body) else {
                continue;
            };
            if self.rigid.iter().any(|r| r.body == vc.body) {
                continue;
            }
            let previous = vc.target;
            let goal = vc.scale * vc.rest_volume;
            let most = vc.max_rate * vc.rest_volume * dt;
            vc.target += (goal - vc.target).clamp(-most, most);
            let now = cells_volume(&body.cells, &self.nodes.position);
            // Velocity only for the share of the correction that undoes this step's drift.
            let total = vc.target - now;
            let fraction = if total != 0.0 {
                ((previous - now) / total).clamp(0.0, 1.0)
            } else {
                1.0
            };
            correct_volume(
                &mut self.nodes,
                &body.cells,
                body.nodes.clone(),
                vc.target,
                vc.iterations,
                dt,
                fraction,
                &mut scratch.volume_grad,
            );
            let drift = 1.0 - now / previous;
            stats.volume_error = stats.volume_error.max(drift.abs());
        }
        super::joints::sync(&self.joints, &mut self.nodes);
        self.scratch = scratch;
        stats
    }

    /// Advance one output frame of `frame_dt` seconds; `frame` is the 1-based number of the
    /// frame reached. Stops with an error naming the frame and node at the first non-finite
    /// value, and with [`SimulationError::Cancelled`] when `cancelled()` turns true.
    /// The frame runs on one worker ([`on_worker`]): its substeps' passes and its measures
    /// (the substep choice, the energies, the checks) share the world's team. The fields
    /// evaluated once a frame are evaluated first, on the caller's thread: a plug-in's field
    /// takes the Python interpreter's lock, which a caller running from Python holds.
    pub fn advance_frame(
        &mut self,
        frame_dt: f64,
        frame: usize,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<FrameDiagnostics, SimulationError> {
        super::fields::refresh(self, false);
        on_worker(self.parallel_size(), || {
            self.advance_frame_here(frame_dt, frame, cancelled)
        })
    }

    /// [`Self::advance_frame`] on the worker it runs on.
    fn advance_frame_here(
        &mut self,
        frame_dt: f64,
        frame: usize,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<FrameDiagnostics, SimulationError> {
        let mut choice = self.choose_substeps(frame_dt);
        let (kinetic, elastic, gravity) = self.frame_energies();
        // A frame that folds or crowds a cell is taken again from here at twice the substeps
        // (`redo`).
        let start = self.redo_point();
        let mut redos = 0;
        let (acc, census, inverted) = loop {
            let mut acc = FrameAccumulator::default();
            self.contact_log.begin_frame();
            let census = if self.on_device() {
                self.advance_on_device(choice.substeps, choice.dt, &mut acc)?
            } else {
                for _ in 0..choice.substeps {
                    self.step_accumulate(choice.dt, &mut acc);
                }
                None
            };
            self.contact_log.end_frame();
            if cancelled() {
                return Err(SimulationError::Cancelled);
            }
            if let Some(message) = self.field_error.take() {
                return Err(SimulationError::Field(message));
            }
            self.check_finite(frame)?;
            let mut inverted = census.map(|c| c.inverted_cells);
            if let Some(start) = start.as_deref().filter(|_| redos < redo::MAX_REDOS) {
                let now = *inverted.get_or_insert_with(|| self.inverted_cells());
                let doubled = super::xpbd::doubled_substeps(choice, frame_dt);
                if let Some(doubled) = doubled.filter(|_| self.spoiled_since(start, now)) {
                    self.redo_from(start);
                    super::xpbd::hold_doubling(self);
                    (choice, redos) = (doubled, redos + 1);
                    continue;
                }
            }
            break (acc, census, inverted);
        };
        let key = self.position_key();
        self.file_device_census(key, census);
        if let Some(c) = census {
            self.elastic_memo = Some((key, c.elastic_energy));
        }
        let energies = self.frame_energies_at(key);
        let mut diag = self.diagnostics_from(frame, energies, inverted);
        diag.substeps = choice.substeps;
        diag.redone = redos;
        diag.dispersion_corrections = acc.corrections;
        diag.dispersion_iterations = acc.iterations;
        diag.dispersion_cap_hits = acc.cap_hits;
        diag.newmark_iterations = acc.newmark_iterations;
        diag.newmark_max_iterations = acc.newmark_max_iterations;
        diag.newmark_cap_hits = acc.newmark_cap_hits;
        diag.max_penetration = acc.max_depth;
        if acc.steps > 0 {
            diag.manipulator_reaction = (acc.reaction_sum / acc.steps as f64).into();
        }
        diag.manipulator_work = acc.manipulator_work;
        let manipulated = !self.manipulators.is_empty() || !self.live_capsules.is_empty();
        let balanced = self.settings.wind.is_none()
            && self.fields.is_empty()
            && (self.settings.integrator == Integrator::Xpbd || !manipulated);
        // What changed between frames (an event, a caller moving nodes) enters the budget;
        // what changes in a frame may only be the work done on the bodies.
        let start = kinetic + elastic + gravity;
        let budget = self
            .energy_budget
            .map_or(start, |(budget, end)| budget + start - end)
            + acc.manipulator_work
            + acc.separation_work;
        let end = diag.kinetic_energy + diag.elastic_energy + diag.gravity_energy;
        self.energy_budget = Some((budget, end));
        let mass: f64 = self.nodes.mass.iter().sum();
        let slack = 0.5 * mass * super::xpbd::MAX_SEPARATION_SPEED.powi(2)
            + mass * self.settings.gravity.norm() * 1e-3
            + 0.05 * (kinetic + elastic);
        diag.energy_gain =
            balanced.then(|| (diag.kinetic_energy + diag.gravity_energy - budget - slack).max(0.0));
        Ok(diag)
    }

    /// The node count [`on_worker`] weighs against [`SERIAL_BELOW_NODES`]: an XPBD world counts
    /// for four times its nodes (see [`XPBD_PARALLEL_WEIGHT`]), and bodies that can touch each
    /// other add their contact samples ([`CONTACT_SAMPLE_WEIGHT`]).
    fn parallel_size(&self) -> usize {
        let nodes = match self.settings.integrator {
            Integrator::Xpbd => self.nodes.len() * XPBD_PARALLEL_WEIGHT,
            _ => self.nodes.len(),
        };
        let touching = self.body_contact.deformable_pairs();
        nodes
            + if touching {
                self.surface.len() * CONTACT_SAMPLE_WEIGHT
            } else {
                0
            }
    }
}

/// Worlds with fewer nodes step on one thread when the caller has not chosen a pool, and larger
/// ones get a thread per this many: shorter parallel passes do not pay for handing work to
/// another thread (measured: the 613-node demo bakes in 2.8 s on one thread, 3.3–3.7 s on two).
const SERIAL_BELOW_NODES: usize = PAR_CHUNK;

/// The XPBD step's passes run on a spinning team ([`super::team`]), a pass costing the second
/// thread about a microsecond, so they pay for it at fewer nodes than the papers' step: an
/// XPBD world takes two threads from 1024 nodes. Measured through the CLI (0.5 m rubber cube
/// dropped 1 m, 100 frames, 2 cores, idle): 1331 nodes 0.84 s on one thread, 0.70–0.73 s on
/// two; 729 nodes 0.45 s on one, 0.48 s on two (its node passes are one chunk, so only the
/// cells' colours share out); the 4096-node standard scene 2.32–2.36 s on one, 2.04–2.05 s
/// on two (2.75 s on two with the passes on rayon's pool).
const XPBD_PARALLEL_WEIGHT: usize = 4;

/// In a world whose bodies can touch each other, each contact sample counts for this many
/// nodes: its share of the contact pass (the meshes' upkeep, the lists, the search) runs on
/// the team too. Measured through the CLI (eight 20 cm cubes in two layers 1 cm apart,
/// `cells = 3`, 512 nodes, 24 frames, 2 cores): 1.02–1.06 s on one thread, 0.73–0.74 s on
/// two.
const CONTACT_SAMPLE_WEIGHT: usize = 2;

/// Run `f` (the steps of a world of `nodes` nodes) on a thread-pool worker. Called from any
/// other thread, each parallel pass of a step would hand its work to the pool and wait for it
/// (a wake-up and a context switch per pass); on a worker the passes run in place. A caller
/// already on a worker keeps its pool (and its thread count). Otherwise the world gets one
/// thread per [`SERIAL_BELOW_NODES`] of its size ([`threads_for`]), up to the global pool's
/// count: a small world on a many-core machine would otherwise split each short colour pass
/// sixteen ways and wait on every thread (measured on a 16-core host: the 4096-node standard
/// scene took 3.9 s and 15 s of CPU on the global pool, against 1.5 s on two threads here).
/// Results do not depend on the choice.
fn on_worker<R: Send>(nodes: usize, f: impl FnOnce() -> R + Send) -> R {
    let threads = threads_for(nodes, rayon::current_num_threads());
    if rayon::current_thread_index().is_some() {
        return super::team::with_team(threads, f);
    }
    if threads < rayon::current_num_threads() {
        if let Some(pool) = sized_pool(threads) {
            return pool.install(|| super::team::with_team(threads, f));
        }
    }
    rayon::scope(|_| super::team::with_team(threads, f))
}

/// Threads for a world of parallel size `nodes` given `available` ones: one per
/// [`SERIAL_BELOW_NODES`], at least one, at most `available`.
fn threads_for(nodes: usize, available: usize) -> usize {
    (nodes / SERIAL_BELOW_NODES).clamp(1, available.max(1))
}

/// The process's pool of `threads` threads, built on first use and kept (one per count asked
/// for, at most the global pool's count of them); `None` if the system refuses a thread.
fn sized_pool(threads: usize) -> Option<&'static rayon::ThreadPool> {
    use std::collections::BTreeMap;
    use std::sync::{Mutex, OnceLock};
    static POOLS: OnceLock<Mutex<BTreeMap<usize, Option<&'static rayon::ThreadPool>>>> =
        OnceLock::new();
    let pools = POOLS.get_or_init(|| Mutex::new(BTreeMap::new()));
    let mut pools = pools
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    *pools.entry(threads).or_insert_with(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(move |i| format!("springbake-{threads}x-{i}"))
            .build()
            .ok()
            .map(|pool| &*Box::leak(Box::new(pool)))
    })
}

#[cfg(test)]
mod tests;
