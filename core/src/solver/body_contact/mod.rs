//! Contact between simulated bodies, and of bodies with static colliders (physics §10,
//! Terasawa §3.3.1), evaluated once per step in the force pass.
//!
//! **Detection.** Each body's display surface takes part twice: its contact samples (the
//! world's [`SurfacePoints`], embedded in its lattice) are the *vertices*, its display
//! triangles (registered with [`World::add_collision_surface`], every vertex embedded in the
//! lattice too) the *faces*. Broad phase: the bodies' node boxes (every embedded point lies in
//! the convex hull of its cell's nodes), then, for an overlapping pair, each sample inside the
//! overlap queries the other body's grid of triangles ([`mesh::BodyMesh`]: a [`BoxGrid`] of
//! boxes grown by a margin, rebuilt only once a vertex has left it). Narrow phase:
//! - vertex–face: the segment from the point's previous position (relative to the face,
//!   `x − (v − v_face) Δt`) to its position now; a segment that enters a face from its front
//!   side is a contact with that face even if the point went deep (no tunnelling within a
//!   step); otherwise the nearest face within the layer outside the surface, or a face the
//!   point lies just behind (at most a layer thickness deep);
//! - edge–edge: mesh edges of one body against the other's, closest points inside both edges,
//!   direction the normal of the plane through both edges, turned out of the other body.
//!
//! Static colliders ([`StaticCollider`]) take vertex–face contacts of the bodies' samples.
//!
//! **Response.** Under XPBD with [`ContactModel::ElasticLayer`] (the default), a contact
//! between two bodies is a constraint of the step ([`constraint`]: the pair's features may
//! touch, not pass each other), found within three quarters of a layer of the other
//! surface; a pair
//! whose surfaces are inside each other at the first pass keeps the layer below.
//! [`ContactModel::ElasticLayer`] as forces (the papers' integrators): the layer lies *outside* the
//! partner's surface (a point is pushed once it is closer than the layer thickness `h`), with
//! the floor's stiffness per unit of sample area (`k · share`), a damper for the pair's reduced
//! share of mass, and Coulomb friction (the world's, or the collider's). Touching bodies rest
//! about `h` apart less the layer's compression, so no vertex enters the other surface.
//! [`ContactModel::Hertz`]: the total normal force of a (body, partner) pair is Hertz's
//! `F = n2 α^(3/2)` ([`crate::hertz`], eq 3.34), α the deepest penetration into the layer;
//! `n2` is fixed at the first touch of a contact episode from the mass-spring model: Young's
//! modulus from the springs (eq 3.38, `A_sp = L²`), Poisson 0.3, the local radius from the
//! surface edges near the contact (eq 3.41; a flat surface, or one flatter than the body,
//! reads as half the body's size); a static collider is rigid (δ = 0). `F` is shared among the
//! pair's contacts in proportion to `share · sqrt(depth)` (Hertz's pressure profile), with
//! Coulomb friction and no normal damping (the pulse is elastic, eq 3.29).
//!
//! **Forces** go to nodes by the embedding weights: a sample to its cell's 8 nodes (trilinear),
//! a face point to its triangle's vertices (barycentric) and each vertex to its cell's nodes;
//! the partner gets the opposite force, so momentum is conserved exactly. The pairs' vertex–face
//! searches run side by side once prepared (each only reads the contact state and yields its
//! contacts in its samples' order); everything else is serial, in body, point and triangle
//! order: the same bits on any thread count. Scratch buffers are kept between steps.

use super::contact::{layer_force, ContactLayer};
use super::contact_log::{observe_rigid, ContactLog, ContactPartner, RigidScene};
use super::team::{self, Chunks};
use super::world::{BodyHandle, BodyInfo, SurfacePoints};
use super::{NodeState, World};
use crate::collide::geometry::{
    closest_between_segments, closest_on_triangle, segment_crosses_triangle, triangle_normal,
};
use crate::collide::{BoxGrid, StaticCollider};
use crate::hertz::{self, SurfaceEdge, SurfaceRadius};
use crate::lattice::{Embedding, Lattice};
use nalgebra::{Point3, Vector3};
use std::ops::Range;

/// How bodies push on each other and on static colliders.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ContactModel {
    /// The floor's elastic layer: penalty along the face normal, damper, Coulomb friction.
    #[default]
    ElasticLayer,
    /// Hertz's force law with parameters from the mass-spring model (module docs).
    Hertz,
}

/// The contact pass's reach for pairs held by constraints, in layer thicknesses (after the
/// first pass, which looks a whole layer deep for parts that start inside each other): a
/// resting sample looks at half the faces it does at a whole layer. At half a layer a
/// stack of cubes dropped a centimetre kept jittering at 6 cm/s (rim samples met their
/// partner's faces at a narrower blend, [`detect`]'s `RIM_BLEND`).
const CONSTRAINT_REACH: f64 = 0.75;

/// How near (in layer thicknesses) a sample in front of its partner's face must be for its
/// contact to become a constraint of the substep, beyond the pair's relative travel in it
/// (twice [`BodyContact::sweep`]): the gap the constraint keeps
/// (`xpbd::bodies::REST_GAP_LAYERS`, 0.1) and as much again and half for what the
/// substep's solve may move the surfaces besides. A contact farther out cannot reach the gap
/// in the substep, so its constraint would do nothing: in a pile with 1 cm gaps at 3 cells a
/// body, four in five contacts the search finds are such (the sides of neighbouring cubes).
/// It is neither a constraint nor in the contact log (the surfaces do not touch), and a
/// sample known to be outside that stays farther than this from every face is not searched
/// ([`detect`]'s `pair_contacts`).
pub(crate) const CONSTRAINT_FRONT: f64 = 0.25;

/// How deep behind a face (in layer thicknesses) a point still touches it without a crossing
/// in the step: deeper, the layer has already failed; the search reaches this far.
pub(crate) const BEHIND_LAYERS: f64 = 1.0;

/// An edge–edge contact stands for a whole cell face (the layer's stiffness per node): two
/// crossed edges carry their load at one point, where a face carries it over its samples.
const EDGE_SHARE: f64 = 1.0;

/// Each body's samples carry half the layer's stiffness against another body: where two faces
/// meet, both sides' samples push, and together they feel the floor's layer.
const BODY_LAYER_FRACTION: f64 = 0.5;

/// One side of a contact: where its force acts.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Feature {
    /// A surface sample (index into the world's [`SurfacePoints`]).
    Point(usize),
    /// A point of triangle `tri` of mesh `mesh` with barycentric weights.
    Face {
        mesh: usize,
        tri: usize,
        bary: [f64; 3],
    },
    /// The point `(1 − s) a + s b` of an edge of mesh `mesh`.
    Edge { mesh: usize, a: u32, b: u32, s: f64 },
    /// A static collider (takes no force).
    Static,
}

/// One contact of body `a` with its partner: normal from the partner into `a`'s side.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Contact {
    a: Feature,
    b: Feature,
    normal: Vector3<f64>,
    depth: f64,
    /// Velocity of `a`'s point relative to the partner's.
    relative_velocity: Vector3<f64>,
    /// Sample area over a lattice face (`a`'s cell), for the layer's stiffness per point.
    share: f64,
    /// The features belong the other way round: `a` to the partner, `b` to the body (the
    /// partner's samples against the body's faces).
    flipped: bool,
}

mod broad;
pub(crate) mod colours;
mod constraint;
mod detect;
mod mesh;
mod neighbours;
pub(crate) mod overlap;
mod prepare;
mod register;
mod simplify;
mod still_pairs;
pub(crate) use constraint::BodyConstraint;
use constraint::Stencils;
use detect::*;
use mesh::BodyMesh;

/// A body's node box: its lowest and highest corner, m.
pub(crate) type NodeBox = (Vector3<f64>, Vector3<f64>);

/// The contact pass's state: meshes, colliders, the model, the force it leaves for the node
/// pass, and scratch buffers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BodyContact {
    pub model: ContactModel,
    /// Body pairs that never touch each other: articulated bodies sharing a joint node (see
    /// [`super::joints`]), as (lower, higher) body index.
    pub(crate) ignored_pairs: Vec<(usize, usize)>,
    /// Per body: the assembly it belongs to (the bodies glued to it directly or through
    /// others share one, numbered from 0; `xpbd::glue`); empty when nothing is glued. The
    /// parts of one assembly never touch each other: it is one object, and, as a single
    /// body's cells, its parts do not collide with each other. A contact between two of them
    /// fights the glue that holds both (two parts touching at the start, pushed apart for
    /// ever; a part glued to a sagging sheet and pushed off the sheet's glued neighbour
    /// under it, which made `McUsd.usda`'s ground explode at 55 m/s).
    pub(crate) assemblies: Vec<usize>,
    meshes: Vec<BodyMesh>,
    pub(crate) colliders: Vec<StaticCollider>,
    /// Per node: the contact forces of this step (valid when `active`).
    pub(crate) force: Vec<Vector3<f64>>,
    pub(crate) active: bool,
    /// Static colliders are contact constraints of the integrator (XPBD with the elastic
    /// layer model): this pass still detects and logs their contacts (with the force the layer
    /// would have), but leaves the response to the constraint.
    pub(crate) collider_constraints: bool,
    /// Contacts between bodies are constraints of the integrator (XPBD with the elastic layer
    /// model): this pass detects and logs them and leaves them in `constraints` for the step.
    pub(crate) body_constraints: bool,
    /// This step's body–body contact constraints (see [`constraint`]).
    constraints: Vec<BodyConstraint>,
    /// Their nodes and signed weights.
    stencil: Vec<(u32, f64)>,
    /// The end of each body pair's constraints in `constraints`, in pair order (pairs with
    /// none left out).
    pair_ends: Vec<u32>,
    /// The pairs' constraints in colours, for the step to solve side by side.
    colours: colours::ConstraintColours,
    /// Body pairs `(lower, higher)` that were inside each other's surfaces at the first
    /// pass (an overlap within the layer, not glued): they keep the elastic layer, which
    /// parts them gently ([`crate::solver::xpbd::MAX_SEPARATION_SPEED`]), not the
    /// constraints, which would have to resolve the overlap at once.
    layer_pairs: Vec<(usize, usize)>,
    step: u64,
    /// Per body: node box, surface point range, mass per unit of share, mesh index.
    boxes: Vec<NodeBox>,
    /// Per body: its fastest node's speed in the step, m/s, its nodes' mean velocity, and
    /// the fastest node's speed relative to that mean.
    max_speed: Vec<f64>,
    mean_velocity: Vec<Vector3<f64>>,
    spread_speed: Vec<f64>,
    /// Per body: its farthest node's move since the last pass, m (infinite at the first),
    /// from the node positions then (`last_position`, per node).
    step_motion: Vec<f64>,
    last_position: Vec<Vector3<f64>>,
    points: Vec<Range<usize>>,
    mass_per_share: Vec<f64>,
    mass: Vec<f64>,
    mesh_of: Vec<Option<usize>>,
    /// (bodies, surface points) the per-body tables were built for.
    built_for: (usize, usize),
    /// Each body pair's edge–edge search scratch, kept from step to step.
    edge_scratch: Vec<EdgeScratch>,
    candidates: Vec<u32>,
    bounds: Vec<Bound>,
    contacts: Vec<Contact>,
    /// Per surface point: position and velocity in the step `sample_stamp` of its body holds
    /// (computed once a step for a body in any pair, not once per pair).
    sample_x: Vec<Vector3<f64>>,
    sample_v: Vec<Vector3<f64>>,
    sample_stamp: Vec<u64>,
    /// Scratch of [`prepare`]: per mesh, whether a search reads it in this step; per body,
    /// whether its samples are computed there.
    mesh_needed: Vec<bool>,
    sampled: Vec<bool>,
    /// The samples' candidate faces per pair of bodies (kept across steps).
    neighbours: neighbours::Neighbours,
    /// Rebuild every pair's neighbour lists each step (for tests: the grid search alone).
    pub(crate) lists_off: bool,
    /// Keep every contact of a constrained pair as a constraint, however far in front (for
    /// tests: leaving out the ones beyond [`CONSTRAINT_FRONT`] changes nothing).
    pub(crate) front_off: bool,
    /// Hertz `n2` of each (body, partner) pair in a contact episode, per partner slot.
    hertz_n2: Vec<Option<f64>>,
    normals: Vec<Vector3<f64>>,
    /// The contacts of constrained pairs at rest, kept from pass to pass.
    still: still_pairs::StillPairs,
    /// Buffers of contacts and stencils the pairs' searches of the last pass are done with,
    /// for this pass's (a pile's searches found some ten thousand contacts a pass, and
    /// growing new buffers for them every pass was a few per cent of its bake).
    spare: Vec<(Vec<Contact>, Option<Stencils>)>,
    /// Per body: whether it moves as one rigid frame (held or rigid, set by the XPBD step:
    /// [`Self::set_frame_bodies`]); only pairs of such bodies keep their contacts
    /// ([`still_pairs`]).
    frame_bodies: Vec<bool>,
    /// Search every pair in every pass (for tests: keeping the contacts of pairs at rest
    /// changes where they rest by less than their motion allows).
    pub(crate) still_off: bool,
    /// One sweep of the cells a substep whatever the contacts (for tests: the XPBD step's
    /// second sweep behind body–body contacts, `xpbd::sweep_behind_contacts`, left out).
    pub(crate) one_sweep: bool,
    /// How many pairs kept their contacts in the last pass.
    pub(crate) kept_pairs: usize,
}

impl BodyContact {
    /// Which bodies move as one rigid frame (per body; the XPBD step's model says, each time
    /// it is built for the bodies as they are). The contacts kept so far are forgotten: the
    /// bodies may have changed.
    pub(crate) fn set_frame_bodies(&mut self, frames: Vec<bool>) {
        self.frame_bodies = frames;
        self.still = still_pairs::StillPairs::default();
    }

    /// Whether a body can touch another body or a static collider (a lone body's mesh
    /// touches nothing here).
    pub(crate) fn touches_others(&self) -> bool {
        !self.colliders.is_empty() || self.deformable_pairs()
    }

    /// How far a point of body `a` can move relative to a point of body `b` in a step of
    /// `dt`, m: their fastest nodes' speeds, or their mean velocities' difference and each
    /// one's fastest node relative to its mean (two bodies falling together barely move
    /// relative to each other), whichever is less.
    fn sweep(&self, a: usize, b: usize, dt: f64) -> f64 {
        let apart = (self.mean_velocity[a] - self.mean_velocity[b]).norm();
        let relative = self.spread_speed[a] + self.spread_speed[b] + apart;
        relative.min(self.max_speed[a] + self.max_speed[b]) * dt
    }

    /// Whether the contacts of bodies `a < b` are constraints of the step, not the layer's
    /// forces (`layer_pairs` as the first pass found them).
    fn constrains(&self, a: usize, b: usize) -> bool {
        self.body_constraints
            && self.model == ContactModel::ElasticLayer
            && !self.layer_pairs.contains(&(a, b))
    }

    /// The static colliders, and per body its node box at the last contact pass (empty
    /// before it): which side of an open collider a body lies on.
    pub(crate) fn colliders_and_boxes(&mut self) -> (&mut [StaticCollider], &[NodeBox]) {
        (&mut self.colliders, &self.boxes)
    }

    /// Whether bodies `a` and `b` are parts of one glued assembly (see `assemblies`).
    pub(crate) fn same_assembly(&self, a: usize, b: usize) -> bool {
        matches!((self.assemblies.get(a), self.assemblies.get(b)), (Some(x), Some(y)) if x == y)
    }

    /// Whether bodies `a < b` never touch: an ignored pair, or two parts of one assembly.
    pub(crate) fn never_touch(&self, a: usize, b: usize) -> bool {
        self.same_assembly(a, b) || self.ignored_pairs.contains(&(a, b))
    }

    /// Whether two bodies with surfaces can touch each other.
    pub(crate) fn deformable_pairs(&self) -> bool {
        self.meshes.len() > 1
    }

    /// Whether any pair can touch (a body's surface, or a collider).
    pub fn any(&self) -> bool {
        !self.colliders.is_empty() || !self.meshes.is_empty()
    }

    /// Body `b`'s surface points' positions and velocities in this step, into `sample_x`,
    /// `sample_v` (once a step).
    fn update_samples(&mut self, surface: &SurfacePoints, nodes: &NodeState, b: usize) {
        if self.sample_stamp[b] == self.step {
            return;
        }
        self.sample_stamp[b] = self.step;
        for i in self.points[b].clone() {
            (self.sample_x[i], self.sample_v[i]) = sample(surface, nodes, i);
        }
    }

    fn partner_slots(&self) -> usize {
        self.boxes.len() + self.colliders.len()
    }

    fn tables(&mut self, nodes: &NodeState, surface: &SurfacePoints, bodies: &[BodyInfo]) {
        if self.built_for == (bodies.len(), surface.len())
            && self.mass.len() == bodies.len()
            && self.hertz_n2.len() == bodies.len() * self.partner_slots()
        {
            return;
        }
        self.built_for = (bodies.len(), surface.len());
        // Kept contacts name bodies and nodes by index: they may have changed.
        self.still = still_pairs::StillPairs::default();
        self.points = vec![0..0; bodies.len()];
        let mut i = 0;
        while i < surface.len() {
            let b = surface.body[i] as usize;
            let start = i;
            while i < surface.len() && surface.body[i] as usize == b {
                i += 1;
            }
            if let Some(r) = self.points.get_mut(b) {
                *r = start..i;
            }
        }
        self.mass = bodies
            .iter()
            .map(|b| nodes.mass[b.nodes.clone()].iter().sum())
            .collect();
        self.mass_per_share = self
            .points
            .iter()
            .map(|r| {
                let share: f64 = surface.share[r.clone()].iter().sum();
                let mass: f64 = surface.body_mass[r.clone()].iter().sum();
                if share > 0.0 {
                    mass / share
                } else {
                    0.0
                }
            })
            .collect();
        self.mesh_of = vec![None; bodies.len()];
        for (m, mesh) in self.meshes.iter().enumerate() {
            if let Some(slot) = self.mesh_of.get_mut(mesh.body) {
                *slot = Some(m);
            }
        }
        self.boxes = vec![(Vector3::zeros(), Vector3::zeros()); bodies.len()];
        self.max_speed = vec![0.0; bodies.len()];
        self.mean_velocity = vec![Vector3::zeros(); bodies.len()];
        self.spread_speed = vec![0.0; bodies.len()];
        self.step_motion = vec![f64::INFINITY; bodies.len()];
        self.last_position.clear();
        self.sample_x = vec![Vector3::zeros(); surface.len()];
        self.sample_v = vec![Vector3::zeros(); surface.len()];
        self.sample_stamp = vec![0; bodies.len()];
        self.neighbours = Default::default();
        self.hertz_n2 = vec![None; bodies.len() * (bodies.len() + self.colliders.len())];
    }
}

/// What one contact pass needs from the world.
pub(crate) struct PassInput<'a> {
    pub nodes: &'a NodeState,
    pub surface: &'a SurfacePoints,
    pub bodies: &'a [BodyInfo],
    pub layer: &'a ContactLayer,
    pub dt: f64,
}

/// One step's contacts for the log and the node pass: sizes and begins the log's step, logs
/// the rigid-surface contacts (see [`super::contact_log`]), runs [`contact_pass`], ends the
/// log's step (what the step's own passes already found comes in `scene`).
pub(crate) fn step_contacts(
    bc: &mut BodyContact,
    log: &mut ContactLog,
    scene: &RigidScene,
    surface: &SurfacePoints,
    nodes: &NodeState,
    node_contact: &[bool],
    bodies: &[BodyInfo],
) {
    log.ensure(bodies.len(), scene.capsules.len(), bc.colliders.len());
    log.begin_step();
    observe_rigid(
        log,
        scene,
        surface,
        nodes,
        &nodes.velocity,
        node_contact,
        bodies,
    );
    let input = PassInput {
        nodes,
        surface,
        bodies,
        layer: scene.layer,
        dt: scene.dt,
    };
    contact_pass(bc, log, &input);
    let body_velocity = |b: usize| {
        let range = bodies[b].nodes.clone();
        let (mut p, mut m) = (Vector3::zeros(), 0.0);
        for i in range {
            p += nodes.velocity[i] * nodes.mass[i];
            m += nodes.mass[i];
        }
        if m > 0.0 {
            p / m
        } else {
            Vector3::zeros()
        }
    };
    let capsule_velocity = |c: usize| {
        scene
            .capsules
            .get(c)
            .map_or_else(Vector3::zeros, |cap| cap.velocity)
    };
    log.end_step(&body_velocity, &capsule_velocity);
}

/// [`step_contacts`] for the integrators without a surface contact pass of their own to share:
/// the manipulators at the world's time go into a reused buffer; rigid surfaces are observed
/// `lead` seconds ahead (Newmark's contacts take predicted positions: `dt`; XPBD's: 0), and
/// only the display points `points` found touching, when given (XPBD's last constraint pass).
pub(crate) fn step_contacts_of(
    world: &mut World,
    dt: f64,
    lead: f64,
    points: Option<super::contact_log::SurfacePass>,
) {
    let mut caps = std::mem::take(&mut world.contact_log.capsules_scratch);
    caps.clear();
    caps.extend(world.manipulators.iter().map(|m| m.capsule_at(world.time)));
    caps.extend(world.live_capsules.iter().copied());
    let scene = RigidScene {
        layer: &world.settings.layer,
        planes: &world.settings.planes,
        capsules: &caps,
        up: world.settings.up,
        dt,
        lead,
        points,
        node_blocks: None,
    };
    step_contacts(
        &mut world.body_contact,
        &mut world.contact_log,
        &scene,
        &world.surface,
        &world.nodes,
        &world.node_contact,
        &world.bodies,
    );
    world.contact_log.capsules_scratch = caps;
}

/// The step's body–body and body–collider contacts: forces into `bc.force` (`bc.active` says
/// whether there are any), contacts into the log (already sized and begun for the step).
pub(crate) fn contact_pass(bc: &mut BodyContact, log: &mut ContactLog, input: &PassInput) {
    if bc.active {
        bc.force.iter_mut().for_each(|f| *f = Vector3::zeros());
        bc.active = false;
    }
    bc.constraints.clear();
    bc.stencil.clear();
    bc.pair_ends.clear();
    bc.colours.clear();
    if !bc.any() {
        return;
    }
    let PassInput {
        nodes,
        surface,
        bodies,
        layer,
        dt,
    } = *input;
    bc.tables(nodes, surface, bodies);
    bc.step += 1;
    bc.neighbours.forget_stale(bc.step);
    if bc.force.len() != nodes.len() {
        bc.force = vec![Vector3::zeros(); nodes.len()];
    }
    let h = layer.thickness_m;
    for (b, info) in bodies.iter().enumerate() {
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        );
        let (mut speed2, mut spread2): (f64, f64) = (0.0, 0.0);
        let mut mean_v = Vector3::zeros();
        if bc.mesh_of[b].is_some() || !bc.points[b].is_empty() {
            let v = &nodes.velocity[info.nodes.clone()];
            for (x, v) in nodes.position[info.nodes.clone()].iter().zip(v) {
                lo = lo.inf(x);
                hi = hi.sup(x);
                speed2 = speed2.max(v.norm_squared());
            }
            mean_v = v.iter().sum::<Vector3<f64>>() / v.len().max(1) as f64;
            for v in v {
                spread2 = spread2.max((v - mean_v).norm_squared());
            }
        }
        bc.boxes[b] = (lo, hi);
        // Only the searches between bodies read it (a lone body's pass keeps no copy).
        bc.step_motion[b] = if bc.deformable_pairs() {
            let range = info.nodes.clone();
            farthest_move(&nodes.position[range.clone()], bc.last_position.get(range))
        } else {
            f64::INFINITY
        };
        bc.max_speed[b] = speed2.sqrt();
        bc.mean_velocity[b] = mean_v;
        bc.spread_speed[b] = spread2.sqrt();
    }
    bc.last_position.clear();
    if bc.deformable_pairs() {
        bc.last_position.extend_from_slice(&nodes.position);
    }
    let n_bodies = bodies.len();
    let mut searches = begin_searches(bc, input);
    let mut edge_scratch = std::mem::take(&mut bc.edge_scratch);
    edge_scratch.resize_with(searches.len(), Default::default);
    let samples = (input.surface, &input.nodes.position[..]);
    search_pairs(bc, samples, &mut searches, &mut edge_scratch);
    bc.edge_scratch = edge_scratch;
    // Hertz's episodes end for the pairs out of reach (the others' end in `respond`).
    if bc.model == ContactModel::Hertz {
        end_hertz_episodes(bc, &searches);
    }
    let pairs_this_pass = searches.len();
    for pair in searches {
        let (a, b) = (pair.a, pair.b);
        bc.contacts.clear();
        bc.contacts.extend_from_slice(&pair.found);
        for search in pair.searches.into_iter().flatten() {
            detect::end_pair(bc, search);
        }
        let stencils = pair.stencils.as_ref();
        respond(
            bc,
            log,
            input,
            (a, ContactPartner::Body(b)),
            stencils,
            *layer,
            dt,
        );
        if bc.pair_ends.last().copied().unwrap_or(0) < bc.constraints.len() as u32 {
            bc.pair_ends.push(bc.constraints.len() as u32);
        }
        if bc.constrains(a, b) {
            let contacts = (pair.found, pair.stencils);
            let (mut found, mut stencils) = bc.still.keep((a, b), bc.step, contacts, !pair.kept);
            // A kept pair's are empty (it took its buffers back): not worth keeping.
            if found.capacity() > 0 || stencils.is_some() {
                found.clear();
                if let Some(stencils) = stencils.as_mut() {
                    stencils.clear();
                }
                bc.spare.push((found, stencils));
            }
        }
    }
    // No more than a pass's pairs can take.
    bc.spare.truncate(pairs_this_pass);
    let constraints = (&bc.constraints[..], &bc.stencil[..]);
    (bc.colours).build(constraints, &bc.pair_ends, nodes.position.len());
    bc.still.forget_older(bc.step);
    for a in 0..n_bodies {
        for c in 0..bc.colliders.len() {
            let (alo, ahi) = bc.boxes[a];
            let col = &bc.colliders[c];
            let lo = alo.sup(&col.lo).add_scalar(-h);
            let hi = ahi.inf(&col.hi).add_scalar(h);
            bc.contacts.clear();
            if !(0..3).any(|k| lo[k] > hi[k]) {
                detect_collider(bc, input, a, c, lo, hi);
            }
            let friction = bc.colliders[c].friction;
            let collider_layer = ContactLayer { friction, ..*layer };
            let partner = (a, ContactPartner::Collider(c));
            respond(bc, log, input, partner, None, collider_layer, dt);
        }
    }
}

/// Forget Hertz's `n2` of the body pairs `a < b` that are not among `searched` (out of
/// reach in this step: no contacts).
fn end_hertz_episodes(bc: &mut BodyContact, searched: &[PairSearches]) {
    let (n_bodies, slots) = (bc.boxes.len(), bc.partner_slots());
    let mut next = searched.iter().peekable();
    for a in 0..n_bodies {
        for b in a + 1..n_bodies {
            if next.next_if(|p| (p.a, p.b) == (a, b)).is_none() {
                if let Some(n2) = bc.hertz_n2.get_mut(a * slots + b) {
                    *n2 = None;
                }
            }
        }
    }
}

/// The farthest any of `positions` lies from where it was (`last`), m; infinite when not
/// known (no last positions, or a NaN).
fn farthest_move(positions: &[Vector3<f64>], last: Option<&[Vector3<f64>]>) -> f64 {
    let Some(last) = last else {
        return f64::INFINITY;
    };
    let mut farthest: f64 = 0.0;
    for (x, l) in positions.iter().zip(last) {
        let d = (x - l).norm_squared();
        if d.is_nan() {
            return f64::INFINITY;
        }
        farthest = farthest.max(d);
    }
    farthest.sqrt()
}

/// The vertex–face searches of one pair of bodies `a < b` that may touch: `a`'s samples
/// against `b`'s faces and the other way round, within `[lo, hi]`, at layer thickness `h`
/// (thinner for pairs whose contacts are constraints, see [`CONSTRAINT_REACH`]).
struct PairSearches {
    a: usize,
    b: usize,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
    h: f64,
    /// For a constrained pair: how far in front of a face a contact may be and still act in
    /// the substep ([`CONSTRAINT_FRONT`]).
    front: Option<f64>,
    searches: [Option<detect::PairSearch>; 2],
    /// Whether `found` and `stencils` are a search's of an earlier pass, kept
    /// ([`still_pairs`]): then there is nothing to search.
    kept: bool,
    found: Vec<Contact>,
    /// The stencils of `found`'s contacts that act (deeper than 0), made beside the search
    /// when the pair's contacts are constraints (from the second step: the first decides
    /// which pairs are).
    stencils: Option<Stencils>,
}

/// Broad phase: the pairs of bodies whose boxes come within reach of each other (a contact
/// needs a point of one within the reach of the other's surface, or crossing it in the step:
/// boxes farther apart than that, with both moving at their fastest node, cannot touch), in
/// pair order, each with its searches prepared, or with the contacts it keeps: a pair of
/// rigid frames at rest ([`still_pairs`]; only the searched pairs' surfaces are prepared).
fn begin_searches(bc: &mut BodyContact, input: &PassInput) -> Vec<PairSearches> {
    let h = input.layer.thickness_m;
    let mut pairs = broad::pairs_in_reach(bc, h, input.dt);
    // Pairs at rest keep their contacts; the rest are searched.
    let mut out = still_pairs::take_kept(bc, &mut pairs, h);
    bc.kept_pairs = out.len();
    prepare::surfaces_in_reach(bc, input, &pairs);
    for (a, b, lo, hi) in pairs {
        // Constraints need contacts only a little ahead of the gap they keep: a thinner
        // reach looks at a quarter of the faces around a resting sample. The first pass
        // looks a whole layer deep for parts inside each other.
        let thin = bc.step > 1 && bc.constrains(a, b);
        let layer = ContactLayer {
            thickness_m: if thin { h * CONSTRAINT_REACH } else { h },
            ..*input.layer
        };
        let pass = PassInput {
            layer: &layer,
            ..*input
        };
        let front = (bc.constrains(a, b) && !bc.front_off)
            .then(|| CONSTRAINT_FRONT * h + 2.0 * bc.sweep(a, b, input.dt));
        let searches = [
            detect::begin_pair(bc, &pass, (a, b), false, (lo, hi), front),
            detect::begin_pair(bc, &pass, (b, a), true, (lo, hi), front),
        ];
        let (found, stencils) = bc.spare.pop().unwrap_or_default();
        out.push(PairSearches {
            a,
            b,
            lo,
            hi,
            h: layer.thickness_m,
            front,
            searches,
            kept: false,
            found,
            stencils,
        });
    }
    out.sort_by_key(|p| (p.a, p.b));
    grids_for_lists(bc, &out);
    out
}

/// The grids of the meshes a list is to be built from in this step, up to date (meshes side
/// by side: each task writes only its own).
fn grids_for_lists(bc: &mut BodyContact, pairs: &[PairSearches]) {
    let mut needed = std::mem::take(&mut bc.mesh_needed);
    needed.clear();
    needed.resize(bc.meshes.len(), false);
    for search in pairs.iter().flat_map(|p| p.searches.iter().flatten()) {
        if let Some(m) = detect::grid_needed(search) {
            needed[m] = true;
        }
    }
    team::for_each(Chunks::new(&mut bc.meshes, 1), |m, mesh| {
        if needed[m] {
            mesh[0].ensure_grid();
        }
    });
    bc.mesh_needed = needed;
}

/// The vertex–face contacts of each pair's searches (`a`'s samples first), then its
/// edge–edge contacts, into its `found`, pairs side by side on the world's team (`scratch`:
/// one per pair): each search builds its own list if due and only reads the contact state,
/// and yields its contacts in its samples' (or edges') order, so the result is the same on
/// any thread count. A constrained pair drops the contacts that cannot act in the step and
/// makes the stencils of those that may.
fn search_pairs(
    bc: &BodyContact,
    (surface, positions): (&SurfacePoints, &[Vector3<f64>]),
    pairs: &mut [PairSearches],
    scratch: &mut [EdgeScratch],
) {
    let parts = (Chunks::new(pairs, 1), Chunks::new(scratch, 1));
    team::for_each(parts, |_, (pair, scratch)| {
        let pair = &mut pair[0];
        if pair.kept {
            return;
        }
        pair.found.clear();
        for search in pair.searches.iter_mut().flatten() {
            detect::search_pair(bc, (surface, positions), search, &mut pair.found);
        }
        let (ab, region) = ((pair.a, pair.b), (pair.lo, pair.hi));
        detect_edges(bc, ab, region, pair.h, &mut scratch[0], &mut pair.found);
        if let Some(front) = pair.front {
            // Contacts found deeper than this can reach the constraint's gap.
            let least = pair.h - front;
            pair.found.retain(|c| c.depth > least);
        }
        let mut stencils = pair.stencils.take().unwrap_or_default();
        stencils.clear();
        pair.stencils = (bc.step > 1 && bc.constrains(pair.a, pair.b)).then(|| {
            for c in pair.found.iter().filter(|c| c.depth > 0.0) {
                stencils.push(bc, surface, c.a, c.b);
            }
            stencils
        });
    });
}

/// Add force `f` acting at `feature` to the nodes.
fn apply(
    force: &mut [Vector3<f64>],
    meshes: &[BodyMesh],
    surface: &SurfacePoints,
    feature: Feature,
    f: Vector3<f64>,
) {
    let mut vertex = |mesh: &BodyMesh, v: u32, scale: f64| {
        let (ids, w) = (&mesh.nodes[v as usize], &mesh.weights[v as usize]);
        for c in 0..8 {
            force[ids[c] as usize] += f * (w[c] * scale);
        }
    };
    match feature {
        Feature::Point(i) => {
            let (ids, w) = (&surface.nodes[i], &surface.weights[i]);
            for c in 0..8 {
                force[ids[c] as usize] += f * w[c];
            }
        }
        Feature::Face { mesh, tri, bary } => {
            let m = &meshes[mesh];
            for (&v, &w) in m.triangles[tri].iter().zip(&bary) {
                vertex(m, v, w);
            }
        }
        Feature::Edge { mesh, a, b, s } => {
            let m = &meshes[mesh];
            vertex(m, a, 1.0 - s);
            vertex(m, b, s);
        }
        Feature::Static => {}
    }
}

/// Forces of the contacts gathered for body `a` and `partner` (a body or a collider), logged
/// both ways.
fn respond(
    bc: &mut BodyContact,
    log: &mut ContactLog,
    input: &PassInput,
    (a, partner): (usize, ContactPartner),
    stencils: Option<&Stencils>,
    layer: ContactLayer,
    dt: f64,
) {
    let n_bodies = bc.boxes.len();
    let (b, c) = match partner {
        ContactPartner::Body(b) => (Some(b), 0),
        ContactPartner::Collider(c) => (None, c),
        _ => return,
    };
    let pair = a * bc.partner_slots() + b.unwrap_or(n_bodies + c);
    if bc.contacts.is_empty() {
        if let Some(s) = bc.hertz_n2.get_mut(pair) {
            *s = None;
        }
        return;
    }
    if let Some(b) = b {
        let inside = bc.contacts.iter().any(|c| c.depth > layer.thickness_m);
        if bc.step == 1 && inside && !bc.layer_pairs.contains(&(a, b)) {
            bc.layer_pairs.push((a, b));
        }
    }
    let constrain = b.is_some_and(|b| bc.constrains(a, b));
    let push = match b {
        Some(_) => !constrain,
        None => !bc.collider_constraints,
    };
    bc.active |= push;
    // Damper mass per unit of share: the pair's reduced mass (a collider is immovable).
    let mps_a = bc.mass_per_share[a];
    let mps = match b {
        Some(b) => {
            let mps_b = bc.mass_per_share[b];
            if mps_a + mps_b > 0.0 {
                mps_a * mps_b / (mps_a + mps_b)
            } else {
                0.0
            }
        }
        None => mps_a,
    };
    let stiffness_fraction = if b.is_some() {
        BODY_LAYER_FRACTION
    } else {
        1.0
    };
    let hertz = if bc.model == ContactModel::Hertz {
        let n2 = match bc.hertz_n2[pair] {
            Some(n2) => n2,
            None => {
                let n2 = hertz_n2(bc, input, a, b, c);
                bc.hertz_n2[pair] = Some(n2);
                n2
            }
        };
        let alpha = bc.contacts.iter().map(|c| c.depth).fold(0.0, f64::max);
        let total = n2 * alpha.powf(1.5);
        let weight: f64 = bc
            .contacts
            .iter()
            .map(|c| c.share * c.depth.max(0.0).sqrt())
            .sum();
        (weight > 0.0).then_some(total / weight)
    } else {
        None
    };
    let mut acting = 0;
    for k in 0..bc.contacts.len() {
        let c = bc.contacts[k];
        if c.depth <= 0.0 {
            continue;
        }
        acting += 1;
        let mass = mps * c.share;
        let point_layer = match hertz {
            Some(per_weight) => ContactLayer {
                stiffness: per_weight * c.share * c.depth.sqrt() / c.depth,
                damping_ratio: 0.0,
                ..layer
            },
            None => ContactLayer {
                stiffness: layer.stiffness * c.share * stiffness_fraction,
                ..layer
            },
        };
        let f = layer_force(
            &point_layer,
            layer.friction,
            c.depth,
            c.normal,
            c.relative_velocity,
            mass,
            dt,
        );
        if push {
            apply(&mut bc.force, &bc.meshes, input.surface, c.a, f);
            apply(&mut bc.force, &bc.meshes, input.surface, c.b, -f);
        }
        if constrain {
            match stencils {
                Some(made) => bc.constrain_with(made.get(acting - 1), c.normal),
                None => bc.constrain(input.surface, c.a, c.b, c.normal),
            }
        }
        // f acts on feature a: on the body unless the features are flipped.
        let (f_body, n_body) = if c.flipped {
            (-f, -c.normal)
        } else {
            (f, c.normal)
        };
        log.add(a, partner, f_body, n_body);
        if let Some(b) = b {
            log.add(b, ContactPartner::Body(a), -f_body, -n_body);
        }
    }
}

/// Local radius of mesh `m` near `at` (eq 3.41 over the edges of triangles with a corner
/// within `reach`), `None` when flat or nothing is near.
fn mesh_radius(
    normals: &mut Vec<Vector3<f64>>,
    positions: &[Vector3<f64>],
    triangles: &[[u32; 3]],
    at: Vector3<f64>,
    reach: f64,
) -> Option<f64> {
    normals.clear();
    normals.resize(positions.len(), Vector3::zeros());
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = (b - a).cross(&(c - a));
        for &i in t {
            normals[i as usize] += n;
        }
    }
    let mut edges = Vec::new();
    for t in triangles {
        if !t
            .iter()
            .any(|&i| (positions[i as usize] - at).norm() <= reach)
        {
            continue;
        }
        for e in 0..3 {
            let (i, j) = (t[e] as usize, t[(e + 1) % 3] as usize);
            edges.push(SurfaceEdge {
                a: positions[i],
                b: positions[j],
                normal_a: normals[i],
                normal_b: normals[j],
            });
        }
    }
    match hertz::local_radius(&edges) {
        Ok(SurfaceRadius::Curved(r)) => Some(r),
        _ => None,
    }
}

/// Hertz stiffness `n2` (eq 3.34, spheres: `A = B = 1/(2R1) + 1/(2R2)`, `q_k(1)`) of body `a`
/// against body `b` or collider `c`, from the mass-spring model at the deepest contact.
fn hertz_n2(bc: &mut BodyContact, input: &PassInput, a: usize, b: Option<usize>, c: usize) -> f64 {
    let deepest = bc.contacts.iter().fold(
        &bc.contacts[0],
        |m, k| if k.depth > m.depth { k } else { m },
    );
    let at = match deepest.a {
        Feature::Point(i) => sample(input.surface, input.nodes, i).0,
        Feature::Edge { mesh, a, b, s } => {
            let m = &bc.meshes[mesh];
            m.x[a as usize] * (1.0 - s) + m.x[b as usize] * s
        }
        Feature::Face { mesh, tri, bary } => {
            let [p, q, r] = bc.meshes[mesh].corners(tri);
            p * bary[0] + q * bary[1] + r * bary[2]
        }
        Feature::Static => Vector3::zeros(),
    };
    let poisson = hertz::MASS_SPRING_POISSON;
    let body = |bc: &mut BodyContact, body: usize| -> (f64, f64) {
        let (lo, hi) = bc.boxes[body];
        let cap = 0.5 * (hi - lo).max();
        match bc.mesh_of[body] {
            Some(m) => {
                let mesh = &bc.meshes[m];
                let r = mesh_radius(&mut bc.normals, &mesh.x, &mesh.display, at, 1.5 * mesh.cell);
                let delta = (1.0 - poisson * poisson) / (std::f64::consts::PI * mesh.young);
                (r.map_or(cap, |r| r.min(cap)), delta)
            }
            None => (cap, 0.0),
        }
    };
    let (r1, d1) = body(bc, a);
    let (inv_r2, d2) = match b {
        Some(b) => {
            let (r2, d2) = body(bc, b);
            (1.0 / r2, d2)
        }
        None => {
            let reach =
                bc.mesh_of[a].map_or(8.0 * input.layer.thickness_m, |m| 1.5 * bc.meshes[m].cell);
            let col = &bc.colliders[c];
            let r = mesh_radius(&mut bc.normals, &col.positions, &col.triangles, at, reach);
            (r.map_or(0.0, |r| 1.0 / r), 0.0)
        }
    };
    let coefficient = 0.5 / r1 + 0.5 * inv_r2;
    let qk = hertz::q_k(1.0).unwrap_or(hertz::Q_K_TABLE[0].1);
    (4.0 / 3.0) * qk / ((d1 + d2) * (2.0 * coefficient).sqrt())
}
