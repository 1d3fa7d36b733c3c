//! The contact log: what each body touched during the last [`World::advance_frame`], one
//! [`ContactRecord`] per (body, partner) pair — the floor, the walls, a manipulator, another
//! body or a static collider.
//!
//! Contacts are observed in the force pass of every step, from the state the step's forces are
//! evaluated at (so the speed logged at first touch is the approach speed *before* the contact
//! force acted). The impact speed is the body's: its centre-of-mass velocity relative to the
//! partner's (another body's centre of mass, a manipulator's velocity, zero for the floor,
//! walls and colliders) along the mean normal of the touching contacts; a surface point's own
//! velocity would also count the ringing of a soft surface, which re-touches many times. Per step, the forces on each body are summed per partner into a fixed
//! `bodies × slots` table (no allocation once sized); at the end of the step the table updates
//! the frame's running values; at the end of the frame the touched pairs become records, in
//! body order, then partner order (floor, wall, manipulators, bodies, colliders).
//!
//! Floor and walls are the world's planes: a plane whose normal is within 25° of `up` is the
//! floor, any other a wall (several walls are one partner; their forces add).
//!
//! [`World::advance_frame`]: super::World::advance_frame

use super::contact::{node_contacts, ContactLayer, Plane, CONTACT_BLOCK};
use super::manipulator::Capsule;
use super::world::{BodyInfo, SurfacePoints};
use super::NodeState;
use nalgebra::Vector3;
use std::ops::Range;

/// What a body touched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ContactPartner {
    Floor,
    Wall,
    /// Index among the manipulators at that time: the scripted tracks, then the live capsules.
    Manipulator(usize),
    /// Index of the other body in the world.
    Body(usize),
    /// Index of the static collider in the world.
    Collider(usize),
}

/// One (body, partner) pair's contact during a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactRecord {
    /// Index of the body in the world.
    pub body: usize,
    pub partner: ContactPartner,
    /// Largest approach speed at a first touch in the frame (the step the pair began
    /// touching): centre-of-mass velocities along the contact normal (module docs), m/s; 0
    /// when the pair was already touching as the frame began and never separated.
    pub impact_speed: f64,
    /// Largest total force on the body from that partner at any step of the frame, N.
    pub peak_force: f64,
    /// Whether the pair touched at the frame's last step.
    pub touching_at_end: bool,
}

/// One pair's contacts within one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct StepPair {
    force: Vector3<f64>,
    /// Sum of the contacts' unit normals (from the partner into the body).
    normal: Vector3<f64>,
    touching: bool,
}

/// One pair's running values over a frame (and whether it touched at the previous step).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct FramePair {
    touched: bool,
    touching: bool,
    impact: f64,
    peak: f64,
}

/// The per-step table and the frame's records (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContactLog {
    bodies: usize,
    capsules: usize,
    colliders: usize,
    step: Vec<StepPair>,
    frame: Vec<FramePair>,
    records: Vec<ContactRecord>,
    /// Reused buffer for the manipulators of a step that has no contact pass of its own.
    pub(crate) capsules_scratch: Vec<Capsule>,
}

impl ContactLog {
    fn stride(&self) -> usize {
        2 + self.capsules + self.bodies + self.colliders
    }

    /// Size the table for the world's counts (resets the pairs' state when a count changed).
    pub(crate) fn ensure(&mut self, bodies: usize, capsules: usize, colliders: usize) {
        if (bodies, capsules, colliders) != (self.bodies, self.capsules, self.colliders)
            || self.step.is_empty() && bodies > 0
        {
            self.bodies = bodies;
            self.capsules = capsules;
            self.colliders = colliders;
            let n = bodies * self.stride();
            self.step = vec![StepPair::default(); n];
            self.frame = vec![FramePair::default(); n];
        }
    }

    fn slot(&self, partner: ContactPartner) -> usize {
        match partner {
            ContactPartner::Floor => 0,
            ContactPartner::Wall => 1,
            ContactPartner::Manipulator(i) => 2 + i,
            ContactPartner::Body(i) => 2 + self.capsules + i,
            ContactPartner::Collider(i) => 2 + self.capsules + self.bodies + i,
        }
    }

    fn partner(&self, slot: usize) -> ContactPartner {
        partner_of(slot, self.capsules, self.bodies)
    }

    /// Start a frame: forget the last frame's values (the touching state carries over).
    pub(crate) fn begin_frame(&mut self) {
        for f in &mut self.frame {
            f.touched = false;
            f.impact = 0.0;
            f.peak = 0.0;
        }
    }

    /// Start a step.
    pub(crate) fn begin_step(&mut self) {
        self.step.fill(StepPair::default());
    }

    /// A contact of `body` with `partner` this step: `force` on the body, `normal` the unit
    /// contact normal from the partner into the body.
    pub(crate) fn add(
        &mut self,
        body: usize,
        partner: ContactPartner,
        force: Vector3<f64>,
        normal: Vector3<f64>,
    ) {
        if body >= self.bodies {
            return;
        }
        let i = body * self.stride() + self.slot(partner);
        if let Some(s) = self.step.get_mut(i) {
            s.force += force;
            s.normal += normal;
            s.touching = true;
        }
    }

    /// End a step: fold its table into the frame's values. `body_velocity(b)`: body `b`'s
    /// centre-of-mass velocity; `capsule_velocity(i)`: manipulator `i`'s (both asked only for
    /// pairs that begin touching).
    pub(crate) fn end_step(
        &mut self,
        body_velocity: &dyn Fn(usize) -> Vector3<f64>,
        capsule_velocity: &dyn Fn(usize) -> Vector3<f64>,
    ) {
        let (stride, capsules, bodies) = (self.stride(), self.capsules, self.bodies);
        for (i, (s, f)) in self.step.iter().zip(self.frame.iter_mut()).enumerate() {
            if s.touching {
                if !f.touching {
                    let partner_velocity = match partner_of(i % stride, capsules, bodies) {
                        ContactPartner::Manipulator(c) => capsule_velocity(c),
                        ContactPartner::Body(b) => body_velocity(b),
                        _ => Vector3::zeros(),
                    };
                    let relative = body_velocity(i / stride) - partner_velocity;
                    let n = s.normal.try_normalize(1e-12).unwrap_or_else(Vector3::zeros);
                    f.impact = f.impact.max(-relative.dot(&n));
                }
                f.touched = true;
                f.peak = f.peak.max(s.force.norm());
            }
            f.touching = s.touching;
        }
    }

    /// End a frame: the touched pairs become the frame's records.
    pub(crate) fn end_frame(&mut self) {
        self.records.clear();
        let stride = self.stride();
        for (i, f) in self.frame.iter().enumerate() {
            if f.touched {
                self.records.push(ContactRecord {
                    body: i / stride,
                    partner: self.partner(i % stride),
                    impact_speed: f.impact,
                    peak_force: f.peak,
                    touching_at_end: f.touching,
                });
            }
        }
    }

    /// The last frame's records.
    pub fn records(&self) -> &[ContactRecord] {
        &self.records
    }
}

/// The partner of table column `slot` with `c` manipulators and `b` bodies.
fn partner_of(slot: usize, c: usize, b: usize) -> ContactPartner {
    match slot {
        0 => ContactPartner::Floor,
        1 => ContactPartner::Wall,
        s if s < 2 + c => ContactPartner::Manipulator(s - 2),
        s if s < 2 + c + b => ContactPartner::Body(s - 2 - c),
        s => ContactPartner::Collider(s - 2 - c - b),
    }
}

/// Whether a plane is the floor (normal within 25° of `up`) rather than a wall.
pub(crate) fn is_floor(plane: &Plane, up: &Vector3<f64>) -> bool {
    plane.normal.dot(up) > 25f64.to_radians().cos()
}

/// The partner a plane is: the floor or a wall.
fn plane_partner(plane: &Plane, up: &Vector3<f64>) -> ContactPartner {
    if is_floor(plane, up) {
        ContactPartner::Floor
    } else {
        ContactPartner::Wall
    }
}

/// One display-surface point's contact in a step: force, deepest penetration, force from the
/// manipulators.
pub(crate) type PointContact = (Vector3<f64>, f64, Vector3<f64>);

/// What a step's surface contact pass found for the display-surface points.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SurfacePass<'a> {
    /// Per point, its [`PointContact`] (a point that did not touch has depth 0).
    pub contacts: &'a [PointContact],
    /// The points that touched, in the order the pass visited them, where the pass listed
    /// them: then only these are read, not every point's depth.
    pub touching: Option<&'a [u32]>,
}

/// What the rigid-surface contacts need from the world, borrowed for one observation.
pub(crate) struct RigidScene<'a> {
    pub layer: &'a ContactLayer,
    pub planes: &'a [Plane],
    pub capsules: &'a [Capsule],
    pub up: Vector3<f64>,
    pub dt: f64,
    /// Observe every point at `x + lead · v`: 0 for symplectic Euler (its contacts take the
    /// step's starting positions), `dt` for Newmark-β (its contacts take predicted positions,
    /// so they act a step before the starting position reaches a surface).
    pub lead: f64,
    /// The step's surface contact pass, if it ran at the observed state. Only the points it
    /// found touching are looked at again.
    pub points: Option<SurfacePass<'a>>,
    /// Per block of [`CONTACT_BLOCK`] nodes, whether its nodes' box reaches a plane or capsule
    /// at the observed state (see [`super::contact::box_may_touch`]); without, each body's box is tested.
    pub node_blocks: Option<&'a [bool]>,
}

impl RigidScene<'_> {
    /// Log the contacts of a point at `x` moving at `v` (damper mass `mass`, layer `layer`)
    /// with each plane and capsule separately, evaluated by the solver's own contact law.
    fn log_point(
        &self,
        log: &mut ContactLog,
        body: usize,
        layer: &ContactLayer,
        x: Vector3<f64>,
        v: Vector3<f64>,
        mass: f64,
    ) {
        let x = x + v * self.lead;
        for (j, plane) in self.planes.iter().enumerate() {
            if plane.offset - plane.normal.dot(&x) <= 0.0 {
                continue;
            }
            let one = std::slice::from_ref(plane);
            let (f, _, _) = node_contacts(layer, one, &[], x, v, mass, self.dt);
            log.add(
                body,
                plane_partner(&self.planes[j], &self.up),
                f,
                plane.normal,
            );
        }
        for (j, cap) in self.capsules.iter().enumerate() {
            let d = x - cap.closest_point(&x);
            let dist = d.norm();
            if dist >= cap.radius {
                continue;
            }
            let n = cap.normal(d, dist);
            let one = std::slice::from_ref(cap);
            let (f, _, _) = node_contacts(layer, &[], one, x, v, mass, self.dt);
            log.add(body, ContactPartner::Manipulator(j), f, n);
        }
    }
}

/// Position, velocity and damper mass of surface point `i`, as
/// [`SurfacePoints::contact`] computes them: the weighted sums over its cell's nodes, and the
/// larger of its share of the body's mass and its effective mass `share / Σ w²/m`.
pub(crate) fn point_kinematics(
    surface: &SurfacePoints,
    i: usize,
    nodes: &NodeState,
    velocities: &[Vector3<f64>],
) -> (Vector3<f64>, Vector3<f64>, f64) {
    let (w, ids) = (&surface.weights[i], &surface.nodes[i]);
    let (mut x, mut v, mut compliance) = (Vector3::zeros(), Vector3::zeros(), 0.0);
    for c in 0..8 {
        let n = ids[c] as usize;
        x += nodes.position[n] * w[c];
        v += velocities[n] * w[c];
        compliance += w[c] * w[c] * nodes.inv_mass[n];
    }
    let effective = if compliance > 0.0 {
        surface.share[i] / compliance
    } else {
        0.0
    };
    (x, v, effective.max(surface.body_mass[i]))
}

/// Log one step's rigid-surface contacts (floor, walls, manipulators): the display-surface
/// points (see [`observe_surface`]) and the nodes of bodies without a display surface.
#[allow(clippy::too_many_arguments)]
pub(crate) fn observe_rigid(
    log: &mut ContactLog,
    scene: &RigidScene,
    surface: &SurfacePoints,
    nodes: &NodeState,
    velocities: &[Vector3<f64>],
    node_contact: &[bool],
    bodies: &[BodyInfo],
) {
    if scene.planes.is_empty() && scene.capsules.is_empty() {
        return;
    }
    observe_surface(log, scene, surface, nodes, velocities);
    observe_nodes(log, scene, nodes, velocities, node_contact, bodies);
}

/// Log the rigid-surface contacts of the display-surface points. With the contact pass's
/// results (`scene.points`), only the points it found touching are looked at again (those it
/// listed, or every point's depth read), and with a single plane, no capsule and no lead
/// their force is the pass's own: the pass evaluated the same contact law on the same point,
/// layer and mass with that one plane (the same floating-point operations), so the log takes
/// it as it is. Otherwise every point is evaluated surface by surface.
pub(crate) fn observe_surface(
    log: &mut ContactLog,
    scene: &RigidScene,
    surface: &SurfacePoints,
    nodes: &NodeState,
    velocities: &[Vector3<f64>],
) {
    let only_plane = match (scene.planes, scene.capsules.is_empty(), scene.lead == 0.0) {
        ([plane], true, true) => Some((plane, plane_partner(plane, &scene.up))),
        _ => None,
    };
    let mut observe = |i: usize| {
        if let Some(pass) = scene.points {
            let (force, depth, _) = pass.contacts.get(i).copied().unwrap_or_default();
            if depth <= 0.0 {
                return;
            }
            if let Some((plane, partner)) = only_plane {
                log.add(surface.body[i] as usize, partner, force, plane.normal);
                return;
            }
        }
        let (x, v, mass) = point_kinematics(surface, i, nodes, velocities);
        let layer = ContactLayer {
            stiffness: scene.layer.stiffness * surface.share[i],
            ..*scene.layer
        };
        scene.log_point(log, surface.body[i] as usize, &layer, x, v, mass);
    };
    match scene.points.and_then(|pass| pass.touching) {
        Some(touching) => touching
            .iter()
            .filter(|&&i| (i as usize) < surface.len())
            .for_each(|&i| observe(i as usize)),
        None => (0..surface.len()).for_each(observe),
    }
}

/// Log the rigid-surface contacts of the nodes that take contacts themselves (bodies without
/// a display surface), body by body in node order. Nodes whose block (`scene.node_blocks`) or,
/// without blocks, whose body's box reaches no plane or capsule are skipped: they have none.
pub(crate) fn observe_nodes(
    log: &mut ContactLog,
    scene: &RigidScene,
    nodes: &NodeState,
    velocities: &[Vector3<f64>],
    node_contact: &[bool],
    bodies: &[BodyInfo],
) {
    let log_range = |log: &mut ContactLog, b: usize, range: Range<usize>| {
        for i in range {
            if node_contact[i] {
                let (x, v, m) = (nodes.position[i], velocities[i], nodes.mass[i]);
                scene.log_point(log, b, scene.layer, x, v, m);
            }
        }
    };
    for (b, info) in bodies.iter().enumerate() {
        let range = info.nodes.clone();
        if range.is_empty() || !node_contact.get(range.start).copied().unwrap_or(false) {
            continue;
        }
        match scene.node_blocks {
            Some(near) => {
                for block in range.start / CONTACT_BLOCK..range.end.div_ceil(CONTACT_BLOCK) {
                    if near.get(block).copied().unwrap_or(true) {
                        let from = range.start.max(block * CONTACT_BLOCK);
                        let to = range.end.min((block + 1) * CONTACT_BLOCK);
                        log_range(log, b, from..to);
                    }
                }
            }
            None => {
                if body_box_near(scene, &nodes.position[range.clone()]) {
                    log_range(log, b, range);
                }
            }
        }
    }
}

/// Whether the box of a body's nodes at `xs` reaches a plane (its lowest corner below the
/// offset) or a capsule's box (the test [`observe_nodes`] makes without node blocks).
fn body_box_near(scene: &RigidScene, xs: &[Vector3<f64>]) -> bool {
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for x in xs {
        lo = lo.inf(x);
        hi = hi.sup(x);
    }
    let near_plane = scene.planes.iter().any(|pl| {
        let lowest = (0..8)
            .map(|c| {
                let corner = Vector3::new(
                    if c & 1 == 0 { lo.x } else { hi.x },
                    if c & 2 == 0 { lo.y } else { hi.y },
                    if c & 4 == 0 { lo.z } else { hi.z },
                );
                pl.normal.dot(&corner)
            })
            .fold(f64::INFINITY, f64::min);
        lowest < pl.offset
    });
    let near_capsule = scene.capsules.iter().any(|c| {
        let (a, e) = c.endpoints();
        let (clo, chi) = (
            a.inf(&e).add_scalar(-c.radius),
            a.sup(&e).add_scalar(c.radius),
        );
        (0..3).all(|k| clo[k] <= hi[k] && chi[k] >= lo[k])
    });
    near_plane || near_capsule
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_touch_speed_peak_force_and_order() {
        let mut log = ContactLog::default();
        log.ensure(2, 1, 1);
        // Body 1 falls at 3 m/s (and drifts sideways: only the normal part counts); body 0
        // moves at 0.5 m/s into collider 0; manipulator 0 moves at 2 m/s towards body 1.
        let bodies = |b: usize| {
            if b == 1 {
                Vector3::new(4.0, -3.0, 0.0)
            } else {
                Vector3::new(-0.5, 0.0, 0.0)
            }
        };
        let capsule = |_: usize| Vector3::new(0.0, 0.0, 2.0);
        log.begin_frame();
        // Step 1: body 1 hits the floor; body 0 is touched by collider 0.
        log.begin_step();
        log.add(
            1,
            ContactPartner::Floor,
            Vector3::new(0.0, 5.0, 0.0),
            Vector3::y(),
        );
        log.add(0, ContactPartner::Collider(0), Vector3::x(), Vector3::x());
        log.end_step(&bodies, &capsule);
        // Step 2: body 1 still on the floor (larger force), manipulator 0 on body 1.
        log.begin_step();
        log.add(
            1,
            ContactPartner::Floor,
            Vector3::new(0.0, 8.0, 0.0),
            Vector3::y(),
        );
        log.add(
            1,
            ContactPartner::Floor,
            Vector3::new(0.0, 2.0, 0.0),
            Vector3::y(),
        );
        log.add(
            1,
            ContactPartner::Manipulator(0),
            Vector3::zeros(),
            Vector3::z(),
        );
        log.end_step(&|_| Vector3::new(0.0, -9.0, 0.0), &capsule);
        log.end_frame();
        let r = log.records();
        assert_eq!(r.len(), 3);
        assert_eq!((r[0].body, r[0].partner), (0, ContactPartner::Collider(0)));
        assert_eq!(r[0].impact_speed, 0.5);
        assert!(!r[0].touching_at_end);
        assert_eq!((r[1].body, r[1].partner), (1, ContactPartner::Floor));
        assert_eq!(r[1].impact_speed, 3.0, "speed at first touch, not later");
        assert_eq!(r[1].peak_force, 10.0, "forces of one step add");
        assert!(r[1].touching_at_end);
        // Relative to the manipulator, (0, −9, 0) − (0, 0, 2), along the normal +z (from the
        // capsule into the body): 2 m/s closing.
        assert_eq!(r[2].partner, ContactPartner::Manipulator(0));
        assert_eq!(r[2].impact_speed, 2.0);
        // Next frame: still touching the floor from the start, so no new impact.
        log.begin_frame();
        log.begin_step();
        log.add(
            1,
            ContactPartner::Floor,
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::y(),
        );
        log.end_step(&bodies, &capsule);
        log.end_frame();
        let r = log.records();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].impact_speed, 0.0);
        assert_eq!(r[0].peak_force, 1.0);
    }
}
