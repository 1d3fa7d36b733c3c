//! The default solver: extended position-based dynamics with small steps (Macklin et al.
//! 2016, "XPBD"; 2019, "Small Steps in Physics Simulation"). One constraint sweep per substep,
//! a few tens of substeps per frame whatever the material's stiffness.
//!
//! A substep, in order (each stage its own pass over structure-of-arrays data):
//! 1. **predict**: `v += Δt (g + f/m)` with the external forces (wind, and the contact
//!    layer of [`super::body_contact`] for body pairs that start inside each other and under
//!    `contact = "hertz"` (colliders too), integrated implicitly per node,
//!    `Δv = f Δt / (m + k Δt²)`, so a stiff layer cannot destabilise the step; beyond
//!    [`MAX_SEPARATION_SPEED`] apart its push moves the node without speeding it), `x += Δt v`;
//! 2. **paths**: pinned and trajectory-bound nodes are put on their targets (strength 1: they
//!    do not move in the solve);
//! 3. **elastic solve**: the cells' volumetric constraints ([`cells`]) colour by colour, then
//!    the springs of bodies without cells (cages built of springs only) as distance
//!    constraints with compliance `1/k`; after the internal-torque cancellation, the
//!    attachments of parts that interpenetrate at the start ([`glue`]);
//! 4. **contact**: the body–body contacts the contact pass found at the substep's start,
//!    as constraints with Coulomb friction ([`bodies`]); then nodes and display-surface points
//!    below the floor, the walls or inside a capsule, and display-surface points that entered
//!    a static collider, are projected out with Coulomb friction ([`contact`]); where bodies
//!    touched each other, a second sweep of the cells and a second pass over the body–body
//!    contacts follow ([`sweep_behind_contacts`]);
//! 5. **velocity**: `v = (x − x_prev) / Δt`, then the deformation damping towards each body's
//!    rigid motion ([`super::deformation_damping`]; rigid motion is not damped).
//!
//! Rigid and particle bodies, volume preservation and joints act after the step exactly as
//! with the papers' integrators (see [`super::World`]). Every parallel pass writes disjoint
//! slots and reduces in fixed chunks, and the serial passes run in index order, so the result
//! has the same bits with any thread count.

mod bodies;
mod cells;
mod contact;
mod crowding;
mod frame_contacts;
mod frame_pairs;
mod frames;
mod glue;
mod held;
mod impacts;
mod lane_io;
mod lanes;
mod restitution;
mod rigid_contacts;
mod support;
mod torque;

use self::crowding::Crowding;
use super::body_contact::step_contacts_of;
use super::contact_log::SurfacePass;
use super::deformation_damping::RigidScratch;
use super::diagnostics::StepStats;
use super::integrator::{FrameAccumulator, Integrate};
use super::manipulator::Capsule;
use super::substeps::SubstepChoice;
use super::team::{self, Chunks};
use super::{World, PAR_CHUNK};
pub(crate) use cells::CellSet;
use cells::{CellInput, PointGroups};
pub(crate) use crowding::CROWDED_J;
use glue::Glue;
use impacts::{impact_shares, speed_rate, ImpactHold};
use nalgebra::Vector3;
use restitution::Restitution;
use rigid_contacts::{point_tasks, rigid_contacts, PointSums};
use std::sync::Arc;

type V3 = Vector3<f64>;

/// Fewest substeps per second of simulated time (10 a frame at 24 frames/s). The bounds
/// are rates, not counts per output frame: a bake at 60 frames/s or the viewer's live mode
/// at 30 resolves the physics as finely as a bake at 24, not more.
pub const MIN_SUBSTEP_RATE: f64 = 240.0;
/// Most substeps per second chosen for the material's stiffness (30 a frame at 24 frames/s; a
/// stiffer material is solved less exactly, not more slowly: the sweep is what stays bounded).
pub const MAX_STIFFNESS_SUBSTEP_RATE: f64 = 720.0;
/// Most substeps per second chosen for fast motion towards a surface (60 a frame at 24).
pub const MAX_SPEED_SUBSTEP_RATE: f64 = 1440.0;
/// Substeps per elastic wave crossing of the shortest cell: the sweep's stiffness is within
/// 10 % of the material's at 2 and 5 % at 4 (a column under its own weight).
pub(crate) const SUBSTEPS_PER_WAVE_CROSSING: f64 = 3.0;
/// Most of the shortest cell a node may travel in one substep when a surface is near: an
/// impact stops the touching layer within a substep and the sweep carries that to the next
/// cells, so the layer must not be crushed first (a rubber ball dropped 1 m folds cells at
/// 0.24 of a cell per substep, not at 0.12).
const TRAVEL_PER_SUBSTEP: f64 = 0.1;
/// Most of its thickness a body the restitution moves as a whole may travel in one substep
/// when a surface is near: the first substep of an impact still presses its bottom layer by
/// that travel (a 1 cm rubber cube thrown down at 5 m/s inverts a cell at 0.7 of its size a
/// substep, none at 0.35).
const BODY_TRAVEL_PER_SUBSTEP: f64 = 0.25;
/// Most substeps per second chosen for a body about to hit a floor, wall or collider (500 a
/// frame at 24; see [`impacts`]): [`MAX_SPEED_SUBSTEP_RATE`] does not hold it, for a
/// layer pressed by more than [`TRAVEL_PER_SUBSTEP`] of a cell a substep folds (a 1 m rubber
/// cube dropped 1 m on 64³ nodes held at 60 substeps a frame inverted a cell, 0.19 of a cell
/// a substep; 128³ at 0.39 inverted 11 000; given 108 and 84 in its two impact frames, 64³
/// inverts none). This bounds a bake's time when cells are tiny against an impact.
pub const MAX_IMPACT_SUBSTEP_RATE: f64 = 12_000.0;
/// The same for a capsule's own speed (a thin capsule sweeping a soft body creases it).
const CAPSULE_TRAVEL_PER_SUBSTEP: f64 = 0.05;
/// How close to a plane, in shortest cell edges, a point counts as touching it for the
/// restitution of stiff bodies (contacts leave points on the plane to rounding).
const RESTITUTION_CONTACT_TOLERANCE: f64 = 1e-4;

/// What the XPBD step derives from the world once (rebuilt when bodies change) and the
/// buffers it reuses.
#[derive(Debug, Clone, Default)]
pub(crate) struct Model {
    cells: CellSet,
    /// The display-surface points by the cell they lie in, in colour order: the order the
    /// contact pass visits them (what a device solver can run a colour at a time).
    points: PointGroups,
    /// Per point in that order, what the contact pass reads of it (in the order it reads
    /// them: from `World::surface` in point order, a pass missed the cache at every point).
    visits: Arc<[PointVisit]>,
    /// Per group of `points`: whether its points all lie in the convex hull of one cell's
    /// nodes (the same nodes, weights that are not negative and add up to 1), so that a group
    /// whose nodes are all clear of the surfaces ([`contact::Surfaces::clear_of_hull`]) has
    /// no point in contact and is skipped whole.
    group_in_hull: Vec<bool>,
    /// Per group of `points` whose points all weigh the same eight distinct nodes in the
    /// same order (a cell's points), the farthest any of them can be from the first node
    /// (their largest `reach`): the contact pass reads those nodes once for the group, skips
    /// the group whole when its first node is that far from every surface, and writes the
    /// nodes back once. `None` for other groups.
    group_one_cell: Vec<Option<f64>>,
    /// Springs solved as distance constraints (bodies without cells).
    springs: Vec<usize>,
    /// Shortest rest edge of any cell or constraint spring, m.
    shortest_edge: f64,
    previous: Vec<V3>,
    /// Positions after the prediction and the paths, before the elastic solve.
    predicted: Vec<V3>,
    /// Per node: the body contacts' push beyond [`MAX_SEPARATION_SPEED`] this substep, m.
    shift: Vec<V3>,
    /// Per assembly (`BodyContact::assemblies`): the mass-weighted sum of `shift` and the
    /// mass, then the shift itself (scratch of [`shift_nodes_bodies`]).
    assembly_shift: Vec<(V3, f64)>,
    /// Per node: in a body contact at the first substep (parts that start touching or
    /// overlapping), until `separated_by` (a node free for a substep in between, as the parts
    /// part, must not meet its partner's layer again at full push).
    overlapping: Vec<bool>,
    /// Whether a substep has predicted since the model was built.
    predicted_once: bool,
    /// Simulated time by which parts that start within each other's layers have separated
    /// at [`MAX_SEPARATION_SPEED`] (a layer thickness; deeper overlaps are glued), s; `None`
    /// once passed.
    separated_by: Option<f64>,
    inv_mass: Vec<f64>,
    /// `inv_mass` with the nodes the floor, walls, colliders or a capsule moved held (0): the
    /// second sweep's ([`sweep_behind_contacts`]).
    behind_contacts: Vec<f64>,
    /// Per node: moved by a rigid contact this substep.
    moved: Vec<bool>,
    /// Per node: moved by a contact between bodies this substep (an elastic body's node).
    by_bodies: Vec<bool>,
    /// Per node: how far the rigid contacts moved it this substep, m (see
    /// [`Model::elastic_energy`]); `contact_shifted` while any is not zero.
    contact_shift: Vec<V3>,
    contact_shifted: bool,
    /// Per fixed node chunk: deepest penetration, the capsules' force on the nodes and their
    /// work.
    chunk_contact: Vec<(f64, V3, f64)>,
    capsules: Vec<(Capsule, Capsule)>,
    rigid_scratch: RigidScratch,
    torque_scratch: torque::TorqueScratch,
    /// Per display-surface point: the last constraint pass's (force, depth, force from the
    /// capsules), for the contact log.
    point_contact: Vec<(V3, f64, V3)>,
    /// The points `point_contact` holds a contact of.
    in_contact: Vec<u32>,
    /// Per task of the points' pass by colour ([`contact_points_by_colour`]), what it found.
    point_sums: Vec<PointSums>,
    /// The points that pass found touching, each task's from the start of its points' places
    /// in the visiting order (scratch, one slot a point).
    found: Vec<u32>,
    /// The static colliders' grid candidates (scratch).
    collider_scratch: Vec<u32>,
    /// Per display-surface point: the collider and face normal it was put back onto in this
    /// substep (for the restitution of stiff bodies).
    collider_touch: Vec<Option<(u32, V3)>>,
    /// Per display-surface point: the two-sided collider's side it rests on, as the collider,
    /// the normal it was last put back along and where, kept while the point stays within a
    /// layer of that place on that side (a point leaving a face after resting on it is a
    /// rounding either side of it; see `collide::StaticCollider::penetration`).
    collider_side: Vec<Option<(u32, V3, V3)>>,
    /// Whether a constraint pass has filled `point_contact` since the model was built.
    logged_once: bool,
    /// Impacts of bodies too stiff for a substep to resolve (`restitution`).
    restitution: Restitution,
    /// Parts that interpenetrate at the start, glued where they overlap (`glue`).
    glue: Glue,
    /// The substeps' doublings for cells near collapse (`crowding`).
    crowding: Crowding,
    /// The last measure of the cells' most collapsed corner and the positions it was made
    /// at ([`World::position_key`]; [`most_collapsed_now`]).
    collapse_memo: Option<((u64, u64), f64)>,
    /// Bodies too stiff for their lattice to bend, held to their rigid motion (`held`).
    held: held::Held,
    /// Per node, its held or rigid body's frame in a contact pass, body–body or with the
    /// static colliders (scratch, see [`frames::rigid_frames`]; empty without such bodies).
    frame_of: Vec<u32>,
    /// The static colliders' contacts of held and rigid bodies' points in a substep
    /// (scratch, see [`frame_contacts`]).
    frame_contacts: Vec<frame_contacts::FrameContact>,
    /// Body–body contact passes so far. In a world with held or rigid bodies, every other pass
    /// starts the frame pairs' passes ([`frame_pairs`]) in reverse order: such a body takes
    /// each contact's push at once, as one rigid body, and in one fixed order the first
    /// contacts' turn biased the rest every substep (a stack of six steel boxes swayed and
    /// fell; with the order alternating it stands). The other contacts keep one order
    /// ([`bodies`]): alternating it, a stack of six rubber boxes fell sooner, and a rubber
    /// box on a wooden one crept 2 mm a second.
    contact_passes: u64,
    /// Each body's impact and the substeps it keeps through it (`impacts`).
    impacts: ImpactHold,
}

/// A display-surface point as the contact pass reads it (`World::surface`'s records).
#[derive(Debug, Clone)]
struct PointVisit {
    nodes: [u32; 8],
    weights: [f64; 8],
    reach: f64,
}

/// Whether every point of `visits` is a convex combination of the same eight nodes.
fn in_one_hull(visits: &[PointVisit]) -> bool {
    let Some(first) = visits.first() else {
        return false;
    };
    visits.iter().all(|v| {
        let sum: f64 = v.weights.iter().sum();
        v.nodes == first.nodes
            && v.weights.iter().all(|&w| w >= 0.0)
            && (sum - 1.0).abs() <= contact::HULL_ROUNDING
    })
}

/// What one step reports to the world's frame totals.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct StepOutput {
    pub max_depth: f64,
    /// Force of the capsules on the bodies, N (the manipulators feel its opposite).
    pub capsule_force: V3,
    /// Whether any contact moved a node (see `Model::moved`).
    pub touched: bool,
    /// Work of the capsules on the bodies in this step, J.
    pub capsule_work: f64,
    /// Work of separating parts that start in contact (`shift_bodies`) in this step, J.
    pub separation_work: f64,
}

impl Model {
    /// Per display-surface point: the last constraint pass's (force, depth, force from the
    /// capsules); empty before the first pass.
    pub(crate) fn point_contact(&self) -> &[(V3, f64, V3)] {
        if self.logged_once {
            &self.point_contact
        } else {
            &[]
        }
    }

    /// Per node: whether a rigid contact moved it in the last substep.
    pub(crate) fn moved(&self) -> &[bool] {
        &self.moved
    }

    /// The model of `world`'s bodies as they are now; parts that interpenetrate are glued
    /// (and stop colliding with each other) here, once.
    pub(crate) fn build(world: &mut World) -> Model {
        let kept = kept_nodes(world);
        let glue = Glue::build(world, &kept);
        let model = Model {
            glue,
            ..Model::build_solids(world, &kept)
        };
        // The bodies that move as one frame: their pairs keep their contacts while at rest.
        let frames = (0..world.bodies.len())
            .map(|b| model.held.holds(world, b) || world.rigid.iter().any(|r| r.body == b))
            .collect();
        world.body_contact.set_frame_bodies(frames);
        model
    }

    fn build_solids(world: &World, kept: &[u32]) -> Model {
        let n = world.nodes.len();
        let mut cells = CellSet::default();
        let mut springs = Vec::new();
        let held = held::Held::build(world);
        // The display-surface points are grouped by cell over every cell, the held bodies'
        // too (so a cell's points are skipped whole while clear of every surface), and only
        // the other cells are solved.
        let mut every_cell = (!held.is_empty()).then(CellSet::default);
        for (b, body) in world.bodies.iter().enumerate() {
            if world.rigid.iter().any(|r| r.body == b) {
                continue;
            }
            match &body.material {
                Some(material) if !body.cells.is_empty() => {
                    let holds = held.holds(world, b);
                    for (c, cell) in body.cells.iter().enumerate() {
                        let input = || CellInput {
                            nodes: cell.map(|i| kept[i as usize]),
                            rest: cell.map(|i| world.rest[i as usize]),
                            material,
                            stiffness_scale: body.cell_stiffness.get(c).copied().unwrap_or(1.0),
                            axis_scale: body.axis_stiffness,
                        };
                        if let Some(every) = every_cell.as_mut() {
                            every.push(input());
                        }
                        if !holds {
                            cells.push(input());
                        }
                    }
                }
                _ => springs.extend(body.springs.clone()),
            }
        }
        cells.finish(n);
        let grouping = every_cell.map(|mut every| {
            every.finish(n);
            every
        });
        let grouping = grouping.as_ref().unwrap_or(&cells);
        let resolve = |ids: &[u32; 8]| ids.map(|i| kept[i as usize]);
        let points = grouping.point_groups(world.surface.nodes.iter().map(resolve));
        let shortest_cell = grouping.shortest_edge;
        let point_tasks = point_tasks(&points);
        let visits = points
            .order
            .iter()
            .map(|&i| PointVisit {
                nodes: world.surface.nodes[i as usize],
                weights: world.surface.weights[i as usize],
                reach: world.surface.reach[i as usize],
            })
            .collect::<Arc<[_]>>();
        let group_in_hull = points
            .groups
            .iter()
            .map(|g| in_one_hull(&visits[g.start as usize..g.end as usize]))
            .collect();
        let group_one_cell = points
            .groups
            .iter()
            .map(|g| {
                let group = &visits[g.start as usize..g.end as usize];
                let distinct = |ids: &[u32; 8]| (1..8).all(|k| !ids[..k].contains(&ids[k]));
                let one =
                    distinct(&group[0].nodes) && group.iter().all(|v| v.nodes == group[0].nodes);
                let reach = group.iter().map(|v| v.reach).fold(0.0, f64::max);
                one.then_some(reach)
            })
            .collect();
        let s = &world.springs;
        let shortest_spring = springs
            .iter()
            .map(|&i| s.rest_length[i])
            .fold(f64::INFINITY, f64::min);
        let shortest_edge = if grouping.len() > 0 {
            shortest_cell.min(shortest_spring)
        } else {
            shortest_spring
        };
        Model {
            cells,
            points,
            visits,
            group_in_hull,
            group_one_cell,
            springs,
            shortest_edge,
            previous: vec![V3::zeros(); n],
            predicted: vec![V3::zeros(); n],
            shift: vec![V3::zeros(); n],
            assembly_shift: Vec::new(),
            overlapping: vec![true; n],
            predicted_once: false,
            separated_by: Some(
                world.time
                    + super::body_contact::BEHIND_LAYERS * world.settings.layer.thickness_m
                        / MAX_SEPARATION_SPEED,
            ),
            inv_mass: vec![0.0; n],
            behind_contacts: Vec::new(),
            moved: vec![false; n],
            by_bodies: vec![false; n],
            contact_shift: vec![V3::zeros(); n],
            contact_shifted: false,
            chunk_contact: vec![(0.0, V3::zeros(), 0.0); n.div_ceil(PAR_CHUNK)],
            capsules: Vec::new(),
            rigid_scratch: RigidScratch::default(),
            torque_scratch: torque::TorqueScratch::default(),
            point_contact: vec![(V3::zeros(), 0.0, V3::zeros()); world.surface.len()],
            in_contact: Vec::new(),
            point_sums: vec![PointSums::default(); point_tasks],
            found: vec![0; world.surface.len()],
            collider_scratch: Vec::new(),
            collider_touch: vec![None; world.surface.len()],
            collider_side: vec![None; world.surface.len()],
            logged_once: false,
            restitution: Restitution::build(world),
            glue: Glue::default(),
            crowding: Crowding::default(),
            collapse_memo: None,
            held,
            frame_of: Vec::new(),
            frame_contacts: Vec::new(),
            contact_passes: 0,
            impacts: ImpactHold::default(),
        }
    }

    /// The cells and display-surface points as a device takes them (see
    /// [`crate::solver::device`]), or what of this model a device does not run.
    #[allow(clippy::type_complexity)]
    pub(crate) fn device_parts(
        &self,
    ) -> Result<
        (
            Vec<crate::solver::device::DeviceCell>,
            Vec<std::ops::Range<u32>>,
            PointGroups,
        ),
        String,
    > {
        if !self.springs.is_empty() {
            return Err("bodies made of springs only (cages without cells)".into());
        }
        if !self.glue.is_empty() {
            return Err("parts glued where they interpenetrate at the start".into());
        }
        if !self.cells.all_coloured_cubes() {
            return Err("cells that are not lattice cubes (cages, sheared lattices)".into());
        }
        let (cells, colours) = self.cells.device_cells();
        Ok((cells, colours, self.points.clone()))
    }

    /// Whether the restitution of stiff bodies can act at the substeps the material's
    /// stiffness asks for (the longest [`choose_substeps`] picks).
    pub(crate) fn restitution_may_act(&self) -> bool {
        let (h, speed) = (
            self.shortest_edge,
            self.cells.wave_speed.max(self.held.wave_speed),
        );
        let by_wave = if h > 0.0 && speed > 0.0 {
            SUBSTEPS_PER_WAVE_CROSSING * speed / h
        } else {
            0.0
        };
        let rate = by_wave.clamp(MIN_SUBSTEP_RATE, MAX_STIFFNESS_SUBSTEP_RATE);
        self.restitution.acts_at(1.0 / rate) || !self.held.is_empty()
    }

    /// Elastic energy of the cells and constraint springs now, J, as the last substep's
    /// elastic solve left them: without its rigid contacts' projection, which the next
    /// substep's solve relaxes. Read after the projection, a rubber ball's cells held 3.4
    /// times all the energy the ball had at its impact, and that reading also raised the
    /// energy balance's budget for the rest of the bake. What is left (1.3–1.7 times for that
    /// ball, 2 J for a 5 mm steel sphere) is one sweep's residual, which stiff cells read
    /// as energy.
    pub(crate) fn elastic_energy(&self, world: &World) -> f64 {
        let relaxed: Vec<V3>;
        let x = if self.contact_shifted && self.contact_shift.len() == world.nodes.len() {
            relaxed = (world.nodes.position.iter().zip(&self.contact_shift))
                .map(|(x, d)| x - d)
                .collect();
            &relaxed
        } else {
            &world.nodes.position
        };
        let s = &world.springs;
        let springs: f64 = self
            .springs
            .iter()
            .map(|&i| {
                let stretch = (x[s.a[i] as usize] - x[s.b[i] as usize]).norm() - s.rest_length[i];
                0.5 * s.stiffness[i] * stretch * stretch
            })
            .sum();
        self.cells.energy(x) + springs
    }
}

impl World {
    /// The bodies that interpenetrate at the start, by name, and whether they are glued where
    /// they overlap (flexible bodies) or only kept from colliding (a rigid or particle body
    /// among them); `glue` (the XPBD solver only: the papers' integrators leave such parts to
    /// the contact layer). Builds the solver's model if no step has yet.
    pub fn interpenetrating_parts(&mut self) -> Vec<(String, String, bool)> {
        if self.settings.integrator != super::Integrator::Xpbd {
            return Vec::new();
        }
        if self.xpbd.is_none() {
            self.xpbd = Some(Model::build(self));
        }
        let pairs = self.xpbd.as_ref().map_or(&[][..], |m| m.glue.pairs());
        pairs
            .iter()
            .map(|&((a, b), glued)| {
                let name = |i: usize| self.bodies[i].name.clone();
                (name(a), name(b), glued)
            })
            .collect()
    }
}

impl World {
    /// The bodies the XPBD solver holds to their rigid motion because their material is far
    /// too stiff for their lattice to bend (`held`), by name. Builds the solver's model if no
    /// step has yet; empty under the papers' integrators.
    pub fn held_bodies(&mut self) -> Vec<String> {
        if self.settings.integrator != super::Integrator::Xpbd {
            return Vec::new();
        }
        if self.xpbd.is_none() {
            self.xpbd = Some(Model::build(self));
        }
        let held = self.xpbd.as_ref().map(|m| &m.held);
        (0..self.bodies.len())
            .filter(|&b| held.is_some_and(|h| h.holds(self, b)))
            .map(|b| self.bodies[b].name.clone())
            .collect()
    }
}

/// Per node, the node that stands for it in the solve (a joint's follower: its kept node).
fn kept_nodes(world: &World) -> Vec<u32> {
    let mut kept: Vec<u32> = (0..world.nodes.len() as u32).collect();
    for shared in &world.joints {
        kept[shared.follower] = super::joints::resolve(world, shared.kept) as u32;
    }
    kept
}

/// Substeps for an output frame of `frame_dt` seconds (at least [`MIN_SUBSTEP_RATE`] a
/// second): enough for [`SUBSTEPS_PER_WAVE_CROSSING`] per crossing of the shortest cell by an
/// elastic wave (`sqrt(E/ρ)`), at most [`MAX_STIFFNESS_SUBSTEP_RATE`]; with any surface to
/// touch, also enough that no node travels more than [`TRAVEL_PER_SUBSTEP`] of the shortest
/// cell (a capsule [`CAPSULE_TRAVEL_PER_SUBSTEP`]) in one, at most
/// [`MAX_SPEED_SUBSTEP_RATE`]; of a body the restitution moves as a whole at an impact, the
/// share it moves is bounded by the body's thickness instead ([`speed_rate`]). A body about to
/// hit a floor, wall or collider keeps the travel bound for its approach, through the impact's release, up to
/// [`MAX_IMPACT_SUBSTEP_RATE`] ([`impacts`]). Each count is rounded up to a whole substep.
pub(crate) fn choose_substeps(world: &mut World, frame_dt: f64) -> SubstepChoice {
    if world.xpbd.is_none() {
        world.xpbd = Some(Model::build(world));
    }
    let (h, speed) = world.xpbd.as_ref().map_or((f64::INFINITY, 0.0), |m| {
        (m.shortest_edge, m.cells.wave_speed.max(m.held.wave_speed))
    });
    // Rates into counts for this frame (a hair under, so 240/s × 1/24 s is 10, not 11).
    let count = |rate: f64| (rate * frame_dt * (1.0 - 1e-12)).ceil().max(1.0);
    let mut n = count(MIN_SUBSTEP_RATE);
    let mut limited_by = "minimum";
    let sized = h.is_finite() && h > 0.0;
    if sized && speed > 0.0 {
        let by_wave = (SUBSTEPS_PER_WAVE_CROSSING * frame_dt * speed / h).ceil();
        if by_wave > n {
            n = by_wave.min(count(MAX_STIFFNESS_SUBSTEP_RATE).max(n));
            limited_by = if by_wave > n {
                "stiffness cap"
            } else {
                "stiffness"
            };
        }
    }
    let time = world.time;
    let capsule_speed = world
        .manipulators
        .iter()
        .map(|m| m.capsule_at(time).velocity.norm())
        .chain(world.live_capsules.iter().map(|c| c.velocity.norm()))
        .fold(0.0, f64::max);
    let surfaces = !world.settings.planes.is_empty() || world.body_contact.any();
    if sized && (surfaces || capsule_speed > 0.0 || !world.manipulators.is_empty()) {
        let shares = impact_shares(world, frame_dt / n);
        let v = &world.nodes.velocity;
        let rate = super::parallel_max(v.len(), |i| speed_rate(i, v[i].norm(), h, &shares));
        let by_speed = (rate * frame_dt)
            .max(capsule_speed * frame_dt / (CAPSULE_TRAVEL_PER_SUBSTEP * h))
            .ceil();
        if by_speed > n {
            n = by_speed.min(count(MAX_SPEED_SUBSTEP_RATE).max(n));
            limited_by = if by_speed > n { "speed cap" } else { "speed" };
        }
        let mut impacts = world
            .xpbd
            .as_mut()
            .map(|m| std::mem::take(&mut m.impacts))
            .unwrap_or_default();
        let impact = impacts.rate(world, frame_dt, h, &shares);
        if let Some(model) = world.xpbd.as_mut() {
            model.impacts = impacts;
        }
        let by_impact = (impact * frame_dt).ceil();
        if by_impact > n {
            n = by_impact.min(count(MAX_IMPACT_SUBSTEP_RATE));
            limited_by = if by_impact > n { "speed cap" } else { "speed" };
        }
    }
    if sized {
        let cap = count(MAX_IMPACT_SUBSTEP_RATE);
        if let Some(crowded) = crowded_substeps(world, n, cap) {
            n = crowded;
            limited_by = "collapse";
        }
    }
    SubstepChoice {
        substeps: n as u32,
        dt: frame_dt / n,
        limited_by,
    }
}

/// `choice` at twice the substeps, for a frame taken again after it folded a cell (the
/// world's `redo`), at most the impact cap; `None` when it is there already.
pub(crate) fn doubled_substeps(choice: SubstepChoice, frame_dt: f64) -> Option<SubstepChoice> {
    let cap = (MAX_IMPACT_SUBSTEP_RATE * frame_dt * (1.0 - 1e-12))
        .ceil()
        .max(1.0) as u32;
    let substeps = choice.substeps.saturating_mul(2).min(cap);
    (substeps > choice.substeps).then(|| SubstepChoice {
        substeps,
        dt: frame_dt / f64::from(substeps),
        limited_by: "collapse",
    })
}

/// The slowest elastic wave of any cell, `sqrt(E/ρ)` in m/s; `None` without cells (or
/// before the model is built).
pub(crate) fn slowest_wave(world: &World) -> Option<f64> {
    let speed = world.xpbd.as_ref()?.cells.slowest_wave;
    (speed > 0.0).then_some(speed)
}

/// The world's cells, taken out of its model (`None` before the model is built), to be put
/// back with [`put_cells`] (the world's `redo` copies a world without them).
pub(crate) fn take_cells(world: &mut World) -> Option<CellSet> {
    world.xpbd.as_mut().map(|m| std::mem::take(&mut m.cells))
}

/// Put back the cells [`take_cells`] took.
pub(crate) fn put_cells(world: &mut World, cells: CellSet) {
    if let Some(model) = world.xpbd.as_mut() {
        model.cells = cells;
    }
}

/// The smallest corner volume ratio of any of `world`'s cells at its positions now (`None`
/// before the model is built). The measure is kept with the positions it was made at, so a
/// frame's end and the next frame's start share one, and so do a frame's start and the copy
/// a frame is taken again from ([`most_collapsed_in_copy`]).
pub(crate) fn most_collapsed_now(world: &mut World) -> Option<f64> {
    let key = world.position_key();
    let model = world.xpbd.as_mut()?;
    match model.collapse_memo {
        Some((at, ratio)) if at == key => Some(ratio),
        _ => {
            let ratio = model.cells.most_collapsed(&world.nodes.position);
            model.collapse_memo = Some((key, ratio));
            Some(ratio)
        }
    }
}

/// [`most_collapsed_now`] of `copy`, a copy of `world` that holds no cells: the measure the
/// copy kept for its positions, else one made on `world`'s cells.
pub(crate) fn most_collapsed_in_copy(world: &World, copy: &World) -> Option<f64> {
    let kept = copy.xpbd.as_ref().and_then(|m| m.collapse_memo);
    match kept {
        Some((at, ratio)) if at == copy.position_key() => Some(ratio),
        _ => Some(
            world
                .xpbd
                .as_ref()?
                .cells
                .most_collapsed(&copy.nodes.position),
        ),
    }
}

/// Keep a frame's doubling for the frames after it ([`crowding::Crowding::raise`]): the frame
/// starting now is taken again at twice the substeps because it folded a cell or crowded one
/// (the world's `redo`).
pub(crate) fn hold_doubling(world: &mut World) {
    let time = world.time;
    if let Some(model) = world.xpbd.as_mut() {
        model.crowding.raise(time);
    }
}

/// The substeps a frame takes instead of `n` while a cell is near collapse (the [`crowding`]
/// module), at most `cap`; `None` when that is not more than `n`.
fn crowded_substeps(world: &mut World, n: f64, cap: f64) -> Option<f64> {
    let measured = world.device_census_now().map(|c| c.most_collapsed);
    let ratio = match measured {
        Some(ratio) => ratio,
        None => most_collapsed_now(world)?,
    };
    let time = world.time;
    let model = world.xpbd.as_mut()?;
    let max_level = (cap / n).log2().ceil().max(0.0) as u32;
    let level = model.crowding.update(time, ratio, max_level);
    let crowded = (n * f64::from(1u32 << level)).min(cap);
    (crowded > n).then_some(crowded)
}

/// Small-step XPBD behind [`Integrate`] (module docs).
pub(crate) struct SmallStepXpbd;

impl Integrate for SmallStepXpbd {
    fn choose_substeps(&self, world: &mut World, frame_dt: f64) -> SubstepChoice {
        choose_substeps(world, frame_dt)
    }

    fn substep(&self, world: &mut World, dt: f64, acc: &mut FrameAccumulator) -> StepStats {
        let out = step(world, dt);
        acc.manipulator_work += out.capsule_work;
        acc.separation_work += out.separation_work;
        acc.max_depth = acc.max_depth.max(out.max_depth);
        acc.steps += 1;
        if !world.manipulators.is_empty() || !world.live_capsules.is_empty() {
            acc.reaction_sum -= out.capsule_force;
        }
        StepStats::default()
    }
}

/// One XPBD substep of `dt` seconds (module docs). Advances the world's time.
pub(crate) fn step(world: &mut World, dt: f64) -> StepOutput {
    if world.xpbd.is_none() {
        world.xpbd = Some(Model::build(world));
    }
    let mut model = world.xpbd.take().unwrap_or_default();
    // The contact log and the body–body layer forces, at the substep's start; static
    // colliders are constraints of `rigid_contacts` (Hertz's force law stays a force).
    let layer_model = world.body_contact.model == super::body_contact::ContactModel::ElasticLayer;
    world.body_contact.collider_constraints = layer_model;
    world.body_contact.body_constraints = layer_model;
    log_contacts(world, &model, dt);
    let time = world.time;
    let first = !model.predicted_once;
    let touch = RESTITUTION_CONTACT_TOLERANCE * model.shortest_edge;
    model
        .restitution
        .before(world, dt, model.shortest_edge, touch);
    push_by_fields(world, dt);
    predict(world, &mut model, dt);
    let separation_work = shift_bodies(world, &mut model);
    bind_paths(world, &mut model, time + dt);
    model.predicted.copy_from_slice(&world.nodes.position);
    let bc = &world.body_contact;
    let second_sweep = model.cells.len() > 0 && !bc.one_sweep && !bc.constraints().0.is_empty();
    let pass = if second_sweep {
        cells::Pass::First
    } else {
        cells::Pass::Lone
    };
    let x = &mut world.nodes.position;
    model.cells.solve(x, &model.inv_mass, dt, pass);
    solve_springs(world, &model, dt);
    let x = &mut world.nodes.position;
    (model.held).hold(x, &world.rest, &world.nodes.mass, &model.inv_mass);
    torque::cancel_internal_torque(world, &mut model);
    model.glue.solve(&mut world.nodes.position, &model.inv_mass);
    model.begin_contacts();
    let bodies = body_contacts(world, &mut model, first, dt);
    let separation_work = separation_work
        + if bodies.rested {
            shift_nodes_bodies(world, &mut model)
        } else {
            0.0
        };
    let mut out = rigid_contacts(world, &mut model, time, dt);
    let mut separation_work = separation_work;
    if second_sweep && bodies.touched {
        sweep_behind_contacts(world, &mut model, dt);
        let again = body_contacts(world, &mut model, false, dt);
        if again.rested {
            separation_work += shift_nodes_bodies(world, &mut model);
        }
    }
    out.touched |= bodies.touched;
    out.max_depth = out.max_depth.max(bodies.depth);
    let x = &mut world.nodes.position;
    (model.held).hold(x, &world.rest, &world.nodes.mass, &model.inv_mass);
    if out.touched {
        let (w, moved) = (&model.inv_mass, &model.moved);
        model
            .cells
            .solve_barriers(&mut world.nodes.position, w, moved);
    }
    update_velocities(world, &model, dt);
    model
        .restitution
        .after(world, dt, touch, &model.collider_touch);
    damp_deformation(world, &mut model, dt);
    world.time += dt;
    world.xpbd = Some(model);
    StepOutput {
        separation_work,
        ..out
    }
}

/// Stage 4c, in a substep where bodies touched each other: a second sweep of the cells, each
/// constraint taking up its multiplier from the first ([`cells::Pass::Again`]), with the
/// nodes that the floor, the walls, colliders or a capsule moved this substep held where they
/// were put (inverse mass 0); the caller then passes over the body–body contacts again.
/// With one sweep before the contacts, the correction a contact makes waits in the touching
/// layer for the next substep's sweep to pass it on, and a body carried by another rests on
/// a layer softer than its material: two 30 cm rubber boxes, the upper 4 cm off-centre,
/// rocked 13.6 mm peak to peak and came to rest tilted 12 mrad with the lower box squeezed
/// 3.3 mm; with the second sweep, 8.3 mm, 6.9 mrad and 2.0 mm (elasticity: about 4 mrad and
/// 1.1 mm; see docs/benchmarks.md). The nodes the body–body contacts moved are not held:
/// held on both sides, a stack of rubber cubes dropped a centimetre onto each other kept
/// hopping (0.3 J of their motion's energy after 2.5 s).
fn sweep_behind_contacts(world: &mut World, model: &mut Model, dt: f64) {
    let held = &mut model.behind_contacts;
    held.clear();
    let moved = model.moved.iter().zip(&model.by_bodies);
    let moved = moved.map(|(&m, &b)| m && !b);
    held.extend((model.inv_mass.iter().zip(moved)).map(|(&w, m)| if m { 0.0 } else { w }));
    let x = &mut world.nodes.position;
    model
        .cells
        .solve(x, &model.behind_contacts, dt, cells::Pass::Again);
}

/// Stage 0: the substep's contact log and the body–body / collider layer forces (at the
/// substep's start). The rigid surfaces' contacts of the display-surface points come from the
/// previous substep's constraint pass (`Model::point_contact`: only the points it found
/// touching are looked at, and with a lone floor its constraint force is logged as it is).
fn log_contacts(world: &mut World, model: &Model, dt: f64) {
    let fresh = model.point_contact.len() == world.surface.len() && model.logged_once;
    let points = fresh.then_some(SurfacePass {
        contacts: &model.point_contact,
        touching: Some(&model.in_contact),
    });
    step_contacts_of(world, dt, 0.0, points);
}

/// Stage 1a: the force fields' push on the velocities (a pass of its own, only with fields,
/// so the prediction's loop stays as it is without them).
fn push_by_fields(world: &mut World, dt: f64) {
    if world.field_force.is_empty() {
        return;
    }
    let nodes = &mut world.nodes;
    for ((v, f), m) in nodes
        .velocity
        .iter_mut()
        .zip(&world.field_force)
        .zip(&nodes.mass)
    {
        if *m > 0.0 {
            *v += f * (dt / m);
        }
    }
}

/// Stage 1: external forces and the predicted positions.
fn predict(world: &mut World, model: &mut Model, dt: f64) {
    let gravity = world.settings.gravity;
    let wind = world.settings.wind.map(|w| (w, w.air_velocity(world.time)));
    let layer_k = world.settings.layer.stiffness;
    let bc = &world.body_contact;
    let body_force = bc.active.then_some(&bc.force[..]);
    if model.separated_by.is_some_and(|t| world.time >= t) {
        model.overlapping.fill(false);
        model.separated_by = None;
    }
    let first = !std::mem::replace(&mut model.predicted_once, true);
    let nodes = &mut world.nodes;
    let mass = &nodes.mass[..];
    model.inv_mass.copy_from_slice(&nodes.inv_mass);
    let chunks = (
        Chunks::new(&mut nodes.position, PAR_CHUNK),
        Chunks::new(&mut nodes.velocity, PAR_CHUNK),
        Chunks::new(&mut model.previous, PAR_CHUNK),
        Chunks::new(&mut model.shift, PAR_CHUNK),
        Chunks::new(&mut model.overlapping, PAR_CHUNK),
    );
    team::for_each(chunks, |chunk, (xs, vs, prev, shift, overlapping)| {
        for j in 0..xs.len() {
            let i = chunk * PAR_CHUNK + j;
            prev[j] = xs[j];
            let m = mass[i];
            if m <= 0.0 {
                continue;
            }
            let mut f = V3::zeros();
            if let Some((w, air)) = wind {
                f += w.force(air, vs[j], m);
            }
            vs[j] += (gravity + f / m) * dt;
            if let Some(bf) = body_force {
                let kick = bf[i] * (dt / (m + layer_k * dt * dt));
                if bf[i] == V3::zeros() {
                    overlapping[j] &= !first;
                } else if overlapping[j] {
                    let moving = contact_kick(kick, vs[j]);
                    vs[j] += moving;
                    shift[j] = (kick - moving) * dt;
                } else {
                    vs[j] += kick;
                }
            } else {
                overlapping[j] &= !first;
            }
            xs[j] += vs[j] * dt;
        }
    });
}

/// Fastest a body–body or collider contact may push apart a node that has been in contact
/// since the start (parts that start a centimetre apart, inside each other's layers, or
/// overlapping), m/s, beyond stopping it; the rest of its push moves the node's body as a
/// whole without giving it velocity (`shift_bodies`). The layer's stored push would otherwise
/// throw such parts apart at `depth / Δt`. A body–body constraint closer than its gap at a
/// substep's start opens at this speed at most too, beyond stopping its approach
/// ([`bodies`]); its overlap came from a substep before, not from this one's motion.
pub const MAX_SEPARATION_SPEED: f64 = 0.1;

/// The velocity change `kick` a body contact gives a node moving at `v`, limited so that the
/// node's speed along it does not exceed [`MAX_SEPARATION_SPEED`] (a node moving into the
/// contact is still stopped).
fn contact_kick(kick: V3, v: V3) -> V3 {
    let size = kick.norm();
    if size.is_nan() || size <= 0.0 {
        return V3::zeros();
    }
    let along = v.dot(&kick) / size;
    let allowed = (MAX_SEPARATION_SPEED - along).max(0.0);
    kick * (size.min(allowed) / size)
}

/// Stage 1b: the part of the body contacts' push beyond [`MAX_SEPARATION_SPEED`] moves each
/// body as a whole (its mass-weighted mean, on positions and the substep's start alike), so it
/// separates bodies that start inside each other's layers without speeding them or stretching
/// them (which would turn into speed), and not into a plane the body is within a cell of.
/// Returns the work of gravity it undid, J (a stack of
/// boxes that starts a centimetre apart is lifted apart: the energy balance counts it as
/// work done on the bodies).
fn shift_bodies(world: &mut World, model: &mut Model) -> f64 {
    if !world.body_contact.active {
        return 0.0;
    }
    shift_nodes_bodies(world, model)
}

/// [`shift_bodies`] of whatever `Model::shift` holds. The parts of a glued assembly
/// (`BodyContact::assemblies`) move together by the assembly's mean: shifted one by one, the
/// glue between them would pull them back with speed.
fn shift_nodes_bodies(world: &mut World, model: &mut Model) -> f64 {
    let gravity = world.settings.gravity;
    let nodes = &mut world.nodes;
    let assemblies = &world.body_contact.assemblies;
    let group = |b: usize| assemblies.get(b).copied().unwrap_or(b);
    let sums = &mut model.assembly_shift;
    sums.clear();
    sums.resize(world.bodies.len(), (V3::zeros(), 0.0));
    for (b, body) in world.bodies.iter().enumerate() {
        let (moment, mass) = &mut sums[group(b)];
        for i in body.nodes.clone() {
            *moment += model.shift[i] * nodes.mass[i];
            *mass += nodes.mass[i];
            model.shift[i] = V3::zeros();
        }
    }
    let mut work = 0.0;
    for (g, (moment, mass)) in sums.iter_mut().enumerate() {
        if *mass <= 0.0 || *moment == V3::zeros() {
            *moment = V3::zeros();
            continue;
        }
        let mut shift = *moment / *mass;
        // Not into a floor or wall the assembly rests on: the plane would put it back and the
        // put-back would be speed (a stack of boxes touching at the start jumped at 1 m/s).
        for plane in &world.settings.planes {
            let into = shift.dot(&plane.normal);
            let near = |i: usize| {
                nodes.position[i].dot(&plane.normal) - plane.offset < model.shortest_edge
            };
            let resting = || {
                (world.bodies.iter().enumerate())
                    .any(|(b, body)| group(b) == g && body.nodes.clone().any(near))
            };
            if into < 0.0 && resting() {
                shift -= plane.normal * into;
            }
        }
        work -= *mass * gravity.dot(&shift);
        *moment = shift;
    }
    for (b, body) in world.bodies.iter().enumerate() {
        let shift = sums[group(b)].0;
        if shift == V3::zeros() {
            continue;
        }
        for i in body.nodes.clone() {
            if model.inv_mass[i] > 0.0 {
                nodes.position[i] += shift;
                model.previous[i] += shift;
            }
        }
    }
    work
}

/// Stage 2: nodes bound to paths go to their targets at `t`; exact ones stop moving in the
/// solve.
fn bind_paths(world: &mut World, model: &mut Model, t: f64) {
    for c in &world.constraints {
        for (j, &i) in c.nodes.iter().enumerate() {
            let target = c.target(j, t);
            let x = &mut world.nodes.position[i];
            if c.strength >= 1.0 {
                *x = target;
                model.inv_mass[i] = 0.0;
            } else {
                *x += (target - *x) * c.strength;
            }
        }
    }
}

/// Stage 3b: springs of bodies without cells, as distance constraints (serial, in order).
fn solve_springs(world: &mut World, model: &Model, dt: f64) {
    let s = &world.springs;
    let x = &mut world.nodes.position;
    let w = &model.inv_mass;
    let inv_dt2 = 1.0 / (dt * dt);
    for &i in &model.springs {
        let (a, b) = (s.a[i] as usize, s.b[i] as usize);
        let d = x[a] - x[b];
        let length = d.norm();
        let wsum = w[a] + w[b];
        if length <= 1e-15 || wsum <= 0.0 || s.stiffness[i] <= 0.0 {
            continue;
        }
        let n = d / length;
        let dl = -(length - s.rest_length[i]) / (wsum + inv_dt2 / s.stiffness[i]);
        x[a] += n * (w[a] * dl);
        x[b] -= n * (w[b] * dl);
    }
}

impl Model {
    /// Clear the marks of the contact stages (the nodes they move, how far).
    fn begin_contacts(&mut self) {
        self.moved.fill(false);
        self.by_bodies.fill(false);
        if self.contact_shifted {
            self.contact_shift.fill(V3::zeros());
            self.contact_shifted = false;
        }
    }
}

/// Stage 4a: contact between bodies ([`bodies`]); at the first substep, the nodes in
/// contact are the ones that separate gently (see [`MAX_SEPARATION_SPEED`]).
fn body_contacts(world: &mut World, model: &mut Model, first: bool, dt: f64) -> bodies::Touch {
    let (constraints, stencil) = world.body_contact.constraints();
    if constraints.is_empty() {
        return bodies::Touch::default();
    }
    if first {
        for &(k, _) in stencil {
            model.overlapping[k as usize] = true;
        }
    }
    let mut contacts = bodies::BodyContacts {
        constraints,
        colours: world.body_contact.constraint_colours(),
        stencil,
        inv_mass: &model.inv_mass,
        previous: &model.previous,
        friction: world.settings.layer.friction,
        gap: bodies::REST_GAP_LAYERS * world.settings.layer.thickness_m,
        separating: model.separated_by.map(|_| &model.overlapping[..]),
        opening: MAX_SEPARATION_SPEED * dt,
        reverse: false,
        statics: Some(bodies::Statics {
            surface: &world.surface,
            planes: &world.settings.planes,
            colliders: &world.body_contact.colliders,
            resting: &model.collider_side,
        }),
    };
    model.contact_shifted = true;
    let mut frames = contact_frames(world, &model.held, &model.inv_mass, &mut model.frame_of);
    let x = &mut world.nodes.position;
    contacts.reverse = !frames.is_empty() && model.contact_passes % 2 == 1;
    model.contact_passes += 1;
    contacts.solve(
        x,
        (
            &mut model.moved,
            &mut model.by_bodies,
            &mut model.contact_shift,
            &mut model.shift,
        ),
        (&mut frames, &model.frame_of),
    )
}

/// The held and rigid bodies' frames for a contact pass at the positions now
/// ([`frames::rigid_frames`]), with `frame_of` per node.
fn contact_frames(
    world: &World,
    held: &held::Held,
    inv_mass: &[f64],
    frame_of: &mut Vec<u32>,
) -> Vec<frames::RigidFrame> {
    let rigid =
        (world.rigid.iter()).map(|r| (world.bodies[r.body].nodes.clone(), !r.translation_only));
    let bodies = held.node_ranges().map(|r| (r, true)).chain(rigid);
    let state = (&world.nodes.position[..], &world.nodes.mass[..], inv_mass);
    frames::rigid_frames(bodies, state, frame_of)
}

/// The capsules of the substep from `time` to `time + dt`, each at the substep's end and at
/// its start (the scripted tracks, then the live capsules moved back by their velocity), added
/// to `out`: what the contact stage pushes against, here and on a device.
pub(crate) fn push_capsules(world: &World, time: f64, dt: f64, out: &mut Vec<(Capsule, Capsule)>) {
    out.extend(
        world
            .manipulators
            .iter()
            .map(|m| (m.capsule_at(time + dt), m.capsule_at(time))),
    );
    out.extend(world.live_capsules.iter().map(|c| {
        let mut before = *c;
        before.centre -= c.velocity * dt;
        (*c, before)
    }));
}

/// Stage 5a: velocities from the positions' change.
fn update_velocities(world: &mut World, model: &Model, dt: f64) {
    let inv_dt = 1.0 / dt;
    let nodes = &mut world.nodes;
    let (mass, prev) = (&nodes.mass[..], &model.previous[..]);
    let x = &nodes.position[..];
    team::for_each(Chunks::new(&mut nodes.velocity, PAR_CHUNK), |chunk, vs| {
        for (j, v) in vs.iter_mut().enumerate() {
            let i = chunk * PAR_CHUNK + j;
            if mass[i] > 0.0 {
                *v = (x[i] - prev[i]) * inv_dt;
            }
        }
    });
}

/// Stage 5b: every node pulled towards its body's rigid motion (momentum kept exactly).
fn damp_deformation(world: &mut World, model: &mut Model, dt: f64) {
    let scratch = &mut model.rigid_scratch;
    super::deformation_damping::damp(&mut world.nodes, &world.bodies, dt, scratch);
}
