//! The [`World`]: every body's nodes and springs, the rigid surfaces and manipulators, and the
//! stepping loop (symplectic Euler, Miyazaki §3.4 order: forces → velocity update → velocity
//! dispersion → position update; or Newmark-β, see [`super::newmark`]), then the constraints of
//! the step: path constraints under symplectic Euler, rigid frames, volume preservation.
//! The symplectic-Euler step itself is in `euler`, its bit-for-bit tests in `tests`; the
//! default XPBD step in [`super::xpbd`].

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

mod euler;

pub(crate) use euler::SymplecticEuler;

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
    /// Per cell: stiffness factor set by regions (empty: 1 everywhere).
    pub cell_stiffness: Vec<f64>,
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
    /// Points of the display surfaces that take the rigid contacts of their bodies.
    pub surface: SurfacePoints,
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
    /// Rest position of every node (where it was added): the XPBD cells' rest shapes.
    pub(crate) rest: Vec<Vector3<f64>>,
    /// The XPBD solver's derived model and buffers, built at its first step.
    pub(crate) xpbd: Option<super::xpbd::Model>,
    /// The most total energy the bodies have had at the start of a frame, plus the
    /// manipulators' work since (see [`FrameDiagnostics::energy_gain`]), J.
    energy_budget: Option<f64>,
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

/// Display-surface contact points (see [`crate::lattice::surface_samples`]), embedded in their
/// body's lattice: a rigid contact at a point pushes its cell's 8 nodes by the trilinear
/// weights (Terasawa eq 3.43–3.47), so the *mesh* rests on the floor and a thin manipulator
/// cannot slip between nodes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfacePoints {
    /// World node indices of each point's cell.
    pub nodes: Vec<[u32; 8]>,
    pub weights: Vec<[f64; 8]>,
    /// The point's area over a cell face (L²): its share of a node's contact stiffness.
    pub share: Vec<f64>,
    /// The body's mass per contact share times the point's share, kg: the mass the point's
    /// contact damper is scaled for, so a body landing on its surface is damped as a whole
    /// (a damper scaled for the point's own tiny mass lets a heavy body bounce almost forever).
    pub body_mass: Vec<f64>,
    /// The body each point belongs to.
    pub body: Vec<u32>,
    /// How far a point can be from its cell's first corner, m (three cell diagonals: cells
    /// stretched by the bounded dispersion stay well inside).
    pub reach: Vec<f64>,
}

impl SurfacePoints {
    /// Rigid contact of point `i` for node positions in `nodes` and node velocities
    /// `velocities`: (force, depth, force from the manipulators). The point feels the layer at
    /// its share of a node's stiffness, damped for its share of the body's mass or its
    /// effective mass `1 / Σ w²/m` through its cell's nodes, whichever is larger.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn contact(
        &self,
        i: usize,
        nodes: &NodeState,
        velocities: &[Vector3<f64>],
        layer: &ContactLayer,
        planes: &[Plane],
        capsules: &[Capsule],
        dt: f64,
    ) -> (Vector3<f64>, f64, Vector3<f64>) {
        let (w, ids) = (&self.weights[i], &self.nodes[i]);
        let mut x = Vector3::zeros();
        for c in 0..8 {
            x += nodes.position[ids[c] as usize] * w[c];
        }
        // No contact: what node_contacts would give (+0 throughout), without its inputs.
        if !touches_any(planes, capsules, &x) {
            return (Vector3::zeros(), 0.0, Vector3::zeros());
        }
        let (mut v, mut compliance) = (Vector3::zeros(), 0.0);
        for c in 0..8 {
            let n = ids[c] as usize;
            v += velocities[n] * w[c];
            compliance += w[c] * w[c] * nodes.inv_mass[n];
        }
        let share = self.share[i];
        let effective = if compliance > 0.0 {
            share / compliance
        } else {
            0.0
        };
        let point_layer = ContactLayer {
            stiffness: layer.stiffness * share,
            ..*layer
        };
        node_contacts(
            &point_layer,
            planes,
            capsules,
            x,
            v,
            effective.max(self.body_mass[i]),
            dt,
        )
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
}

/// Derived data rebuilt when bodies change, and scratch buffers reused every step.
#[derive(Debug, Clone)]
struct Prepared {
    adjacency: Adjacency,
    colouring: SpringColouring,
    spring_force: Vec<Vector3<f64>>,
    /// Per fixed node chunk: deepest penetration and the sum of the manipulators' forces.
    chunk_contact: Vec<(f64, Vector3<f64>)>,
    /// Per fixed node chunk: the largest |v − c|² after the velocity update (c: node 0's
    /// velocity before it), for the dispersion's uniform-motion test.
    chunk_spread: Vec<f64>,
    /// Per spring: 1 where the dispersion must test it exactly (see `SpringHints`).
    exceptional: Vec<u8>,
    /// Per fixed spring chunk: the smallest dispersion speed floor².
    chunk_floor: Vec<f64>,
    /// Pass the spring hints to the dispersion (always, except in the test comparing with
    /// the hint-free path).
    hints_enabled: bool,
    /// Later dispersion sweeps visit only the springs at changed nodes (always, except in the
    /// test comparing with the stamp-only sweeps).
    active_set_enabled: bool,
    dispersion_scratch: DispersionScratch,
    /// Partial sums of the deformation damping's rigid-motion fit.
    rigid_scratch: RigidScratch,
    capsules: Vec<Capsule>,
    /// Per surface point: contact force, depth, force from the manipulators.
    point_contact: Vec<(Vector3<f64>, f64, Vector3<f64>)>,
    /// Per node: the surface points' contact forces spread onto it.
    surface_force: Vec<Vector3<f64>>,
    /// Per body: whether its nodes' box reaches a rigid surface this step.
    body_may_touch: Vec<bool>,
    /// Per block of [`CONTACT_BLOCK`] nodes: whether its nodes' box reaches a rigid surface
    /// this step (computed when some node takes contacts itself).
    block_near: Vec<bool>,
    /// Skip what cannot touch a rigid surface (node blocks, the log's second look at points
    /// the surface pass found free); always, except in the test comparing with the full path.
    rigid_broad_phase: bool,
    static_step: SubstepChoice,
    shortest_spring: f64,
    /// The lattice bodies' springs by stencil (see [`super::stencil`]), and the node → spring
    /// lists of the other springs, which the node pass gathers.
    stencil: Option<StencilPlan>,
    residual_adjacency: Adjacency,
    /// Use the stencil (always, except in the test comparing with the index lists).
    stencil_enabled: bool,
}

impl Prepared {
    fn bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.adjacency.offsets)
            + b(&self.adjacency.links)
            + b(&self.colouring.order)
            + b(&self.colouring.offsets)
            + b(&self.spring_force)
            + b(&self.chunk_contact)
            + b(&self.chunk_spread)
            + b(&self.exceptional)
            + b(&self.chunk_floor)
            + b(&self.dispersion_scratch.corrections)
            + b(&self.dispersion_scratch.changed)
            + b(&self.colouring.colour)
            + b(&self.dispersion_scratch.log)
            + b(&self.dispersion_scratch.candidates)
            + b(&self.capsules)
            + b(&self.block_near)
            + b(&self.point_contact)
            + b(&self.surface_force)
            + b(&self.body_may_touch)
            + self.stencil.as_ref().map_or(0, StencilPlan::bytes)
            + b(&self.residual_adjacency.offsets)
            + b(&self.residual_adjacency.links)
    }
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
            surface: SurfacePoints::default(),
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
            rest: Vec::new(),
            xpbd: None,
            energy_budget: None,
            prepared: None,
            device: Default::default(),
            scratch: StepScratch::default(),
        }
    }

    /// Where rigid surfaces (floor, walls, capsules, colliders) pushed the bodies at the last
    /// substep: the display-surface points and the lattice nodes they moved (what a viewer's
    /// contact overlay marks). Empty before the first step and under the papers' integrators.
    pub fn touching_points(&self) -> Vec<Vector3<f64>> {
        let Some(model) = &self.xpbd else {
            return Vec::new();
        };
        let contact = model.point_contact();
        let points = (0..contact.len().min(self.surface.len()))
            .filter(|&i| contact[i].1 > 0.0)
            .map(|i| {
                let (w, ids) = (&self.surface.weights[i], &self.surface.nodes[i]);
                (0..8).fold(Vector3::zeros(), |x, c| {
                    x + self.nodes.position[ids[c] as usize] * w[c]
                })
            });
        let nodes = model
            .moved()
            .iter()
            .zip(&self.nodes.position)
            .filter(|(moved, _)| **moved)
            .map(|(_, x)| *x);
        points.chain(nodes).collect()
    }

    /// What each body touched during the last [`World::advance_frame`]: one record per
    /// (body, partner) pair, in body order, then partner order (see [`super::contact_log`]).
    pub fn frame_contacts(&self) -> &[ContactRecord] {
        self.contact_log.records()
    }

    /// Add a fitted lattice as a body: masses from density (each cell's mass shared equally by
    /// its 8 corners, so the total is density × lattice volume), springs `k = E·L` with
    /// dampers `D = 2ζ sqrt(k μ)` (μ the reduced mass of the ends), all nodes moving at
    /// `velocity`.
    pub fn add_lattice_body(
        &mut self,
        name: impl Into<String>,
        lattice: &Lattice,
        material: &Material,
        velocity: Vector3<f64>,
    ) -> BodyHandle {
        let base = self.nodes.len();
        let cell_mass = material.cell_mass(lattice.cell_size);
        let mut mass = vec![0.0; lattice.node_count()];
        for corners in &lattice.cell_nodes {
            for &n in corners {
                mass[n as usize] += cell_mass / 8.0;
            }
        }
        let k = material.spring_constant(lattice.cell_size);
        let zeta = material.damping_ratio;
        let springs: Vec<(u32, u32, f64, f64)> = lattice
            .springs
            .iter()
            .map(|s| {
                let (ma, mb) = (mass[s.a as usize], mass[s.b as usize]);
                let mu = ma * mb / (ma + mb);
                (s.a, s.b, k, 2.0 * zeta * (k * mu).sqrt())
            })
            .collect();
        let positions: Vec<Vector3<f64>> =
            lattice.rest_positions.iter().map(|p| p.coords).collect();
        let handle = self.add_body(name, &positions, &mass, &springs, velocity);
        let longest = lattice.dims.iter().copied().max().unwrap_or(1) as f64 * lattice.cell_size;
        self.bodies[handle.0].deformation_damping = super::deformation_damping::damping_rate(
            material.damping_ratio,
            material.young_pa,
            material.density_kg_m3,
            longest,
        );
        self.bodies[handle.0].material = Some(material.clone());
        self.bodies[handle.0].cells = lattice
            .cell_nodes
            .iter()
            .map(|c| c.map(|n| n + base as u32))
            .collect();
        let mut coords = vec![[0u32; 3]; lattice.node_count()];
        for (cell, nodes) in lattice.cells.iter().zip(&lattice.cell_nodes) {
            for (corner, &n) in CORNERS.iter().zip(nodes) {
                coords[n as usize] = std::array::from_fn(|k| cell[k] + corner[k]);
            }
        }
        self.bodies[handle.0].grid = Some(LatticeGrid {
            dims: lattice.dims.map(|d| d + 1),
            coords,
        });
        handle
    }

    /// Add any mass-spring model: node positions (metres) and masses (kg), springs as
    /// `(a, b, k, D)` with rest lengths taken from the given positions.
    pub fn add_body(
        &mut self,
        name: impl Into<String>,
        positions: &[Vector3<f64>],
        masses: &[f64],
        springs: &[(u32, u32, f64, f64)],
        velocity: Vector3<f64>,
    ) -> BodyHandle {
        let base = self.nodes.len() as u32;
        let first_spring = self.springs.len();
        for (p, &m) in positions.iter().zip(masses) {
            self.nodes.position.push(*p);
            self.nodes.velocity.push(velocity);
            self.nodes.mass.push(m);
            self.nodes
                .inv_mass
                .push(if m > 0.0 { 1.0 / m } else { 0.0 });
            self.node_contact.push(true);
            self.rest.push(*p);
        }
        for &(a, b, k, d) in springs {
            let rest = (positions[a as usize] - positions[b as usize]).norm();
            self.springs.push(a + base, b + base, rest, k, d);
        }
        self.bodies.push(BodyInfo {
            name: name.into(),
            nodes: base as usize..self.nodes.len(),
            springs: first_spring..self.springs.len(),
            cells: Vec::new(),
            deformation_damping: 0.0,
            grid: None,
            material: None,
            cell_stiffness: Vec::new(),
            axis_stiffness: [1.0; 3],
        });
        self.invalidate_prepared();
        BodyHandle(self.bodies.len() - 1)
    }

    /// Give a lattice body a contact surface: `points` (world metres, rest pose, e.g. from
    /// [`crate::lattice::surface_samples`]) with the area each stands for. From then on the
    /// floor, walls and manipulators touch these points instead of the body's nodes.
    pub fn add_contact_surface(
        &mut self,
        body: BodyHandle,
        lattice: &Lattice,
        points: &[Point3<f64>],
        areas_m2: &[f64],
    ) {
        let info = &self.bodies[body.0];
        let base = info.nodes.start as u32;
        let embedding = crate::lattice::Embedding::new(lattice, points);
        let face = lattice.cell_size * lattice.cell_size;
        let shares: Vec<f64> = (0..points.len())
            .map(|i| areas_m2.get(i).copied().unwrap_or(0.0) / face)
            .collect();
        let total_share: f64 = shares.iter().sum();
        let body_mass: f64 = self.nodes.mass[info.nodes.clone()].iter().sum();
        for (i, nodes) in embedding.nodes.iter().enumerate() {
            self.surface.nodes.push(nodes.map(|n| n + base));
            self.surface.weights.push(embedding.weights[i]);
            self.surface.share.push(shares[i]);
            self.surface.body.push(body.0 as u32);
            self.surface
                .reach
                .push(3.0 * 3f64.sqrt() * lattice.cell_size);
            self.surface.body_mass.push(if total_share > 0.0 {
                body_mass * shares[i] / total_share
            } else {
                0.0
            });
        }
        for n in info.nodes.clone() {
            self.node_contact[n] = false;
        }
        self.invalidate_prepared();
    }

    /// Where node `i` was when its body was added (its rest position).
    pub fn rest_position(&self, i: usize) -> Vector3<f64> {
        self.rest[i]
    }

    /// Node positions of one body.
    pub fn body_positions(&self, body: BodyHandle) -> &[Vector3<f64>] {
        &self.nodes.position[self.bodies[body.0].nodes.clone()]
    }

    /// Node positions of one body as points.
    pub fn body_points(&self, body: BodyHandle) -> Vec<Point3<f64>> {
        self.body_positions(body)
            .iter()
            .map(|&p| Point3::from(p))
            .collect()
    }

    /// Drop the derived step data (adjacency, colouring, step bounds) after changing nodes or
    /// springs from outside this module (joints, regions, cage contact surfaces).
    pub fn invalidate_prepared(&mut self) {
        self.prepared = None;
        self.xpbd = None;
    }

    fn prepare(&mut self) -> &mut Prepared {
        if self.prepared.is_none() {
            let n = self.nodes.len();
            let adjacency = Adjacency::new(n, &self.springs);
            let colouring = SpringColouring::new(n, &self.springs);
            let stencil = StencilPlan::build(&self.nodes, &self.springs, &self.bodies);
            let residual_adjacency = match &stencil {
                Some(plan) => Adjacency::filtered(n, &self.springs, |s| !plan.covers(s)),
                None => Adjacency::default(),
            };
            let static_step = self.static_step();
            let shortest_spring = self
                .springs
                .rest_length
                .iter()
                .cloned()
                .fold(f64::INFINITY, f64::min);
            self.prepared = Some(Prepared {
                adjacency,
                colouring,
                // Not needed when the stencil takes every spring.
                spring_force: match &stencil {
                    Some(plan) if plan.covers_all() => Vec::new(),
                    _ => vec![Vector3::zeros(); self.springs.len()],
                },
                chunk_contact: vec![(0.0, Vector3::zeros()); n.div_ceil(PAR_CHUNK)],
                chunk_spread: vec![0.0; n.div_ceil(PAR_CHUNK)],
                exceptional: vec![0; self.springs.len()],
                chunk_floor: vec![0.0; self.springs.len().div_ceil(PAR_CHUNK)],
                hints_enabled: true,
                active_set_enabled: true,
                dispersion_scratch: DispersionScratch::default(),
                rigid_scratch: RigidScratch::default(),
                capsules: Vec::with_capacity(self.manipulators.len() + self.live_capsules.len()),
                point_contact: vec![(Vector3::zeros(), 0.0, Vector3::zeros()); self.surface.len()],
                body_may_touch: Vec::with_capacity(self.bodies.len()),
                block_near: vec![false; n.div_ceil(CONTACT_BLOCK)],
                rigid_broad_phase: true,
                surface_force: vec![Vector3::zeros(); if self.surface.is_empty() { 0 } else { n }],
                static_step,
                shortest_spring,
                stencil,
                residual_adjacency,
                stencil_enabled: true,
            });
        }
        self.prepared.as_mut().expect("prepared above")
    }

    /// Largest step allowed by the accuracy bound (stiffest spring, lighter end; the contact
    /// layer on the lightest node) and by symplectic-Euler stability.
    fn static_step(&self) -> SubstepChoice {
        let n_acc = self.settings.accuracy_n;
        let s = &self.springs;
        let nodes = &self.nodes;
        let mut k_over_m: f64 = 0.0;
        let mut max_zeta: f64 = 0.0;
        let mut node_k = vec![0.0; nodes.len()];
        for i in 0..s.len() {
            let (a, b) = (s.a[i] as usize, s.b[i] as usize);
            let m = nodes.mass[a].min(nodes.mass[b]);
            if m > 0.0 {
                k_over_m = k_over_m.max(s.stiffness[i] / m);
            }
            let mu = nodes.mass[a] * nodes.mass[b] / (nodes.mass[a] + nodes.mass[b]);
            if mu > 0.0 && s.stiffness[i] > 0.0 {
                max_zeta = max_zeta.max(s.damping[i] / (2.0 * (s.stiffness[i] * mu).sqrt()));
            }
            node_k[a] += s.stiffness[i];
            node_k[b] += s.stiffness[i];
        }
        let has_contact = !self.settings.planes.is_empty()
            || !self.manipulators.is_empty()
            || !self.live_capsules.is_empty()
            || self.body_contact.any();
        let layer_k = if has_contact {
            self.settings.layer.stiffness
        } else {
            0.0
        };
        let min_mass = nodes
            .mass
            .iter()
            .cloned()
            .filter(|&m| m > 0.0)
            .fold(f64::INFINITY, f64::min);
        let mut omega_sq: f64 = 0.0;
        for (&m, &k) in nodes.mass.iter().zip(&node_k) {
            if m > 0.0 {
                omega_sq = omega_sq.max((2.0 * k + layer_k) / m);
            }
        }
        let mut best = SubstepChoice {
            substeps: 1,
            dt: f64::INFINITY,
            limited_by: "accuracy",
        };
        let mut consider = |dt: f64, why: &'static str| {
            if dt < best.dt {
                best.dt = dt;
                best.limited_by = why;
            }
        };
        if k_over_m > 0.0 {
            consider(accuracy_step(k_over_m, n_acc), "accuracy");
        }
        if layer_k > 0.0 && min_mass.is_finite() {
            consider(accuracy_step(layer_k / min_mass, n_acc), "contact");
        }
        if omega_sq > 0.0 {
            let zeta = max_zeta.max(self.settings.layer.damping_ratio);
            consider(
                0.8 * 2.0 * ((1.0 + zeta * zeta).sqrt() - zeta) / omega_sq.sqrt(),
                "stability",
            );
        }
        best
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

    fn max_speed(&self) -> f64 {
        let v = &self.nodes.velocity;
        parallel_max(v.len(), |i| v[i].norm())
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
    pub fn advance_frame(
        &mut self,
        frame_dt: f64,
        frame: usize,
        cancelled: &dyn Fn() -> bool,
    ) -> Result<FrameDiagnostics, SimulationError> {
        let choice = self.choose_substeps(frame_dt);
        let mut acc = FrameAccumulator::default();
        let (kinetic, elastic, gravity) = self.energies();
        super::fields::refresh(self, false);
        self.contact_log.begin_frame();
        if self.on_device() {
            self.advance_on_device(choice.substeps, choice.dt, &mut acc)?;
        } else {
            on_worker(self.parallel_size(), || {
                for _ in 0..choice.substeps {
                    self.step_accumulate(choice.dt, &mut acc);
                }
            });
        }
        self.contact_log.end_frame();
        if cancelled() {
            return Err(SimulationError::Cancelled);
        }
        if let Some(message) = self.field_error.take() {
            return Err(SimulationError::Field(message));
        }
        self.check_finite(frame)?;
        let mut diag = self.diagnostics(frame);
        diag.substeps = choice.substeps;
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
        let total = kinetic + elastic + gravity;
        let budget = self.energy_budget.map_or(total, |b| b.max(total)) + acc.manipulator_work;
        self.energy_budget = Some(budget);
        let mass: f64 = self.nodes.mass.iter().sum();
        let slack = 0.5 * mass * super::xpbd::MAX_SEPARATION_SPEED.powi(2)
            + mass * self.settings.gravity.norm() * 1e-3
            + 0.05 * (kinetic + elastic);
        diag.energy_gain =
            balanced.then(|| (diag.kinetic_energy + diag.gravity_energy - budget - slack).max(0.0));
        Ok(diag)
    }

    /// State diagnostics at the current time (energies, inverted cells, speed).
    pub fn diagnostics(&self, frame: usize) -> FrameDiagnostics {
        let (kinetic_energy, elastic_energy, gravity_energy) = self.energies();
        FrameDiagnostics {
            frame,
            time: self.time,
            kinetic_energy,
            elastic_energy,
            gravity_energy,
            inverted_cells: self.inverted_cells(),
            max_speed: self.max_speed(),
            ..FrameDiagnostics::default()
        }
    }

    /// Kinetic, elastic (the XPBD cells' or the springs') and gravity energy now, J.
    fn energies(&self) -> (f64, f64, f64) {
        let n = &self.nodes;
        let s = &self.springs;
        let g = self.settings.gravity;
        (
            deterministic_sum(n.len(), |i| 0.5 * n.mass[i] * n.velocity[i].norm_squared()),
            match (&self.settings.integrator, &self.xpbd) {
                (Integrator::Xpbd, Some(model)) => model.elastic_energy(self),
                _ => deterministic_sum(s.len(), |i| spring_energy(n, s, i)),
            },
            deterministic_sum(n.len(), |i| -n.mass[i] * g.dot(&n.position[i])),
        )
    }

    /// Cells of all bodies with a non-positive corner tetrahedron (the test of
    /// [`crate::lattice::cell_is_inverted`], on the node positions in place).
    pub fn inverted_cells(&self) -> usize {
        let pos = &self.nodes.position[..];
        self.bodies
            .iter()
            .map(|b| {
                b.cells
                    .par_iter()
                    .with_min_len(PAR_CHUNK)
                    .filter(|c| cell_inverted_at(c, pos))
                    .count()
            })
            .sum()
    }

    fn check_finite(&self, frame: usize) -> Result<(), SimulationError> {
        let bad = |v: &Vector3<f64>| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite());
        for (what, values) in [
            ("position", &self.nodes.position),
            ("velocity", &self.nodes.velocity),
        ] {
            if let Some(i) = values.iter().position(bad) {
                let body = self.bodies.iter().find(|b| b.nodes.contains(&i));
                return Err(SimulationError::NonFinite {
                    frame,
                    body: body.map(|b| b.name.clone()).unwrap_or_default(),
                    node: i - body.map(|b| b.nodes.start).unwrap_or(0),
                    what,
                });
            }
        }
        Ok(())
    }

    /// Total energy (kinetic + elastic + gravity) now.
    pub fn total_energy(&self) -> f64 {
        let d = self.diagnostics(0);
        d.kinetic_energy + d.elastic_energy + d.gravity_energy
    }

    /// Bytes held by the world's arrays (node state, springs, cells, display-surface contact
    /// points, and the prepared adjacency, colouring and scratch buffers once the first step
    /// has run), counted from the vectors' capacities. Heap bookkeeping, the lattice the world
    /// was built from and the small per-body and per-constraint data are not included.
    pub fn solver_bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let n = &self.nodes;
        let s = &self.springs;
        let mut total = b(&n.position) + b(&n.velocity) + b(&n.mass) + b(&n.inv_mass);
        total += b(&s.a) + b(&s.b) + b(&s.rest_length) + b(&s.stiffness) + b(&s.damping);
        total += self.bodies.iter().map(|body| b(&body.cells)).sum::<usize>();
        let sp = &self.surface;
        total += b(&sp.nodes)
            + b(&sp.weights)
            + b(&sp.share)
            + b(&sp.body_mass)
            + b(&sp.body)
            + b(&sp.reach)
            + b(&self.node_contact);
        if let Some(p) = &self.prepared {
            total += p.bytes();
        }
        total
    }

    /// Bind `nodes` (world indices) to `path` with `strength` in [0, 1] (1: exact); each node
    /// keeps its current offset from the path's position now. Returns the constraint's index.
    pub fn add_trajectory(
        &mut self,
        nodes: &[usize],
        path: Path,
        strength: f64,
    ) -> Result<usize, ConstraintError> {
        if !(0.0..=1.0).contains(&strength) {
            return Err(ConstraintError::BadStrength(strength));
        }
        if nodes.is_empty() {
            return Err(ConstraintError::NoNodes);
        }
        let count = self.nodes.len();
        if let Some(&node) = nodes.iter().find(|&&i| i >= count) {
            return Err(ConstraintError::NodeOutOfRange { node, count });
        }
        let here = path.at(self.time);
        let offsets = nodes
            .iter()
            .map(|&i| self.nodes.position[i] - here)
            .collect();
        self.constraints.push(TrajectoryConstraint {
            nodes: nodes.to_vec(),
            offsets,
            path,
            strength,
        });
        Ok(self.constraints.len() - 1)
    }

    /// Pin `nodes` where they are now (a constant path, exact).
    pub fn pin(&mut self, nodes: &[usize]) -> Result<usize, ConstraintError> {
        let at = nodes
            .first()
            .and_then(|&i| self.nodes.position.get(i))
            .copied()
            .unwrap_or_else(Vector3::zeros);
        self.add_trajectory(nodes, Path::constant(at), 1.0)
    }

    /// Hold `body`'s volume at `scale` × its volume now (lattice bodies; 3 Newton iterations
    /// per step; the target moves from the present volume to the scaled one at 2 V0/s).
    pub fn preserve_volume(&mut self, body: BodyHandle, scale: f64) -> Result<(), ConstraintError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(ConstraintError::BadVolumeScale(scale));
        }
        let info = self
            .bodies
            .get(body.0)
            .ok_or(ConstraintError::BodyOutOfRange(body.0))?;
        if info.cells.is_empty() {
            return Err(ConstraintError::NoCells(info.name.clone()));
        }
        let volume = cells_volume(&info.cells, &self.nodes.position);
        if volume.is_nan() || volume <= 0.0 {
            return Err(ConstraintError::BadRestVolume {
                body: info.name.clone(),
                volume,
            });
        }
        self.volume.retain(|v| v.body != body.0);
        self.volume.push(VolumeConstraint {
            body: body.0,
            rest_volume: volume,
            scale,
            iterations: 3,
            max_rate: 2.0,
            target: volume,
        });
        Ok(())
    }

    /// Step `body` as a rigid body from now on, with the momentum and angular momentum its
    /// nodes have now (see [`super::rigid`]).
    pub fn make_rigid(&mut self, body: BodyHandle) -> Result<(), ConstraintError> {
        let info = self
            .bodies
            .get(body.0)
            .ok_or(ConstraintError::BodyOutOfRange(body.0))?;
        let rigid = RigidBody::from_nodes(body.0, &self.nodes, info.nodes.clone())
            .ok_or_else(|| ConstraintError::NotRigid(info.name.clone()))?;
        self.rigid.retain(|r| r.body != body.0);
        self.rigid.push(rigid);
        self.xpbd = None;
        Ok(())
    }

    /// Anisotropic material: scale the stiffness of `body`'s springs by axis. A spring with
    /// unit rest direction `u` gets `k · (s_x u_x² + s_y u_y² + s_z u_z²)` (an edge along x
    /// exactly `s_x k`, a diagonal the blend) and its damper `D · sqrt` of the same factor, so
    /// the damping ratio is kept. Directions are taken from the current positions, so call it
    /// before stepping. Scales must be finite and positive.
    pub fn scale_stiffness_per_axis(
        &mut self,
        body: BodyHandle,
        scale: Vector3<f64>,
    ) -> Result<(), ConstraintError> {
        if let Some(&bad) = scale.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(ConstraintError::BadStiffnessScale(bad));
        }
        let info = self
            .bodies
            .get(body.0)
            .ok_or(ConstraintError::BodyOutOfRange(body.0))?;
        let s = &mut self.springs;
        for i in info.springs.clone() {
            let r = self.nodes.position[s.a[i] as usize] - self.nodes.position[s.b[i] as usize];
            let len_sq = r.norm_squared();
            if len_sq <= 0.0 {
                continue;
            }
            let factor = (scale.x * r.x * r.x + scale.y * r.y * r.y + scale.z * r.z * r.z) / len_sq;
            s.stiffness[i] *= factor;
            s.damping[i] *= factor.sqrt();
        }
        let body_info = &mut self.bodies[body.0];
        for k in 0..3 {
            body_info.axis_stiffness[k] *= scale[k];
        }
        self.invalidate_prepared();
        Ok(())
    }

    /// Enclosed volume of a lattice body now (sum of its cells' signed volumes), m³.
    pub fn body_volume(&self, body: BodyHandle) -> f64 {
        self.bodies
            .get(body.0)
            .map(|b| cells_volume(&b.cells, &self.nodes.position))
            .unwrap_or(0.0)
    }

    /// The node count [`on_worker`] weighs against [`SERIAL_BELOW_NODES`]: an XPBD world counts
    /// for an eighth of its nodes (see [`XPBD_SERIAL_FACTOR`]).
    fn parallel_size(&self) -> usize {
        match self.settings.integrator {
            Integrator::Xpbd => self.nodes.len() / XPBD_SERIAL_FACTOR,
            _ => self.nodes.len(),
        }
    }

    /// Total linear momentum.
    pub fn momentum(&self) -> Vector3<f64> {
        let n = &self.nodes;
        (0..n.len()).map(|i| n.velocity[i] * n.mass[i]).sum()
    }
}

/// Worlds with fewer nodes step on one thread when the caller has not chosen a pool: their
/// parallel passes are too short to pay for handing work to a second thread (measured: the
/// 613-node demo bakes in 2.8 s on one thread, 3.3–3.7 s on two).
const SERIAL_BELOW_NODES: usize = PAR_CHUNK;

/// The XPBD step does about an eighth of the papers' step's work per node between its
/// parallel passes (a colour's cells, four at a time): it stays on one thread below eight
/// times as many nodes (measured: the 4096-node standard scene, 3.3 s on one thread, 3.6 s
/// on two).
const XPBD_SERIAL_FACTOR: usize = 8;

/// Run `f` (the steps of a world of `nodes` nodes) on a thread-pool worker. Called from any
/// other thread, each parallel pass of a step would hand its work to the pool and wait for it
/// (a wake-up and a context switch per pass); on a worker the passes run in place. A caller
/// already on a worker keeps its pool (and its thread count); otherwise small worlds go to a
/// one-thread pool and the others to the global pool. Results do not depend on the choice.
fn on_worker<R: Send>(nodes: usize, f: impl FnOnce() -> R + Send) -> R {
    static SERIAL: std::sync::OnceLock<Option<rayon::ThreadPool>> = std::sync::OnceLock::new();
    if rayon::current_thread_index().is_some() {
        return f();
    }
    if nodes < SERIAL_BELOW_NODES {
        let serial = SERIAL.get_or_init(|| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .thread_name(|_| "springbake-serial".into())
                .build()
                .ok()
        });
        if let Some(pool) = serial {
            return pool.install(f);
        }
    }
    rayon::scope(|_| f())
}

/// [`crate::lattice::cell_is_inverted`] on `Vector3` positions (the same arithmetic, without building a
/// `Vec<Point3>` of every node each frame).
fn cell_inverted_at(nodes: &[u32; 8], positions: &[Vector3<f64>]) -> bool {
    let p = |c: usize| positions[nodes[c] as usize];
    if crate::cage::is_tet_cell(nodes) {
        // A cage's tet stored as a degenerate cell (see `crate::cage::tet_cell`).
        let a = p(0);
        return (p(1) - a).dot(&(p(3) - a).cross(&(p(7) - a))) <= 0.0;
    }
    (0..8).any(|c| {
        let ex = p(c ^ 1) - p(c);
        let ey = p(c ^ 2) - p(c);
        let ez = p(c ^ 4) - p(c);
        // Mirrored corners flip the handedness of (ex, ey, ez); compensate with the parity.
        let parity = ((c & 1) + ((c >> 1) & 1) + ((c >> 2) & 1)) % 2;
        let vol = ex.dot(&ey.cross(&ez));
        let signed = if parity == 0 { vol } else { -vol };
        signed <= 0.0
    })
}

#[cfg(test)]
mod tests;
