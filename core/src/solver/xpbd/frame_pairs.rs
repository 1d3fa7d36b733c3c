//! Stage 4a, contacts between two held or rigid bodies: the body–body constraints whose every
//! node moves with a rigid frame ([`super::frames`]) are solved together, by accumulated
//! positional impulses over all of them, before the other body–body constraints
//! ([`super::bodies`]).
//!
//! One pass of projections, each contact moving its frames in full before the next, left a
//! stack biased by the order: the first contacts of a face tilted the box, the later ones
//! tilted it back, and friction at each contact, worked out from that half-done tilt, kept a
//! sideways push. Six steel boxes stacked 1 cm apart, each shifted 2 cm along x, slid over
//! each other and leaned 30 cm in a second; turned every other one by 0.25 rad, they fell.
//!
//! Here every contact is first reduced to one point on each side (a frame moves its points
//! affinely, so a side's weighted nodes move as their weighted mean does). Then normal passes
//! over all the contacts, in alternating order, accumulate each contact's impulse (never
//! pulling) until no pass moves a contact by more than [`CONVERGED`]; then Coulomb friction
//! at each contact on its slip over the substep, bounded by μ times its normal impulse, the
//! way the colliders' frame contacts have it ([`super::frame_contacts`]).
//!
//! A contact keeps `n · d ≥ min(g, start + opening)`: the gap `g`, or, for a contact closer
//! than the gap when the substep started, that start opened by `opening` at most
//! ([`super::bodies`]' module docs). A separating contact leaves the rest of its overlap to
//! [`super::shift_bodies`] through `rest`, grown as [`super::bodies`] grows it.

use super::bodies::NO_FRAME;
use super::contact::{alternating, friction, tangential};
use super::frames::RigidFrame;
use super::V3;
use crate::solver::contact::Plane;
use crate::solver::world::SurfacePoints;

/// Most normal passes over the contacts.
const NORMAL_PASSES: usize = 12;
/// A normal pass that moves no contact by more than this, m, ends them (serial: the same
/// passes on any thread count).
const CONVERGED: f64 = 1e-7;
/// Sweeps of one push per pair of frames at its contacts' centre, before the passes.
const CENTRE_SWEEPS: usize = 4;
/// How closely a pair's contact normals must agree (their mean's length, 1 when parallel)
/// for its push at their centre ([`super::frame_contacts`] has the same).
const NORMALS_AGREE: f64 = 0.95;
/// Friction passes over the contacts.
const FRICTION_PASSES: usize = 4;

/// One side of a contact: its frame, its nodes' summed signed weight, and their weighted mean
/// where the pass found it; or a fixed point of a plane ([`NO_FRAME`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Side {
    pub frame: u32,
    pub weight: f64,
    pub point: V3,
}

impl Side {
    /// The frame that moves this side, if any.
    fn moving<'a>(&self, frames: &'a [RigidFrame]) -> Option<&'a RigidFrame> {
        frames.get(self.frame as usize)
    }

    /// Where the side's point is with its frame's motion so far.
    fn now(&self, frames: &[RigidFrame]) -> V3 {
        self.moving(frames)
            .map_or(self.point, |f| f.moved(self.point))
    }
}

/// A body–body contact between two frames (module docs).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FramePairContact {
    pub sides: [Side; 2],
    pub normal: V3,
    /// The separation `Σ s_k x_k` at the substep's start.
    pub previous: V3,
    /// The separation along the normal the contact keeps, m.
    pub target: f64,
    /// Its Coulomb friction coefficient.
    pub friction: f64,
    /// Accumulated normal and friction impulses, kg·m.
    impulse: f64,
    friction_impulse: V3,
}

impl FramePairContact {
    pub(crate) fn new(
        sides: [Side; 2],
        (normal, previous): (V3, V3),
        target: f64,
        friction: f64,
    ) -> Self {
        FramePairContact {
            sides,
            normal,
            previous,
            target,
            friction,
            impulse: 0.0,
            friction_impulse: V3::zeros(),
        }
    }

    /// The pair's separation `Σ s_k x_k` with the frames' motion so far.
    pub(crate) fn separation(&self, frames: &[RigidFrame]) -> V3 {
        self.sides.iter().map(|s| s.now(frames) * s.weight).sum()
    }

    /// The separation's inverse mass along unit `u`.
    fn inverse_mass(&self, frames: &[RigidFrame], u: V3) -> f64 {
        self.sides
            .iter()
            .filter_map(|s| {
                let frame = s.moving(frames)?;
                Some(s.weight * s.weight * frame.inverse_mass_at(frame.moved(s.point), u))
            })
            .sum()
    }

    /// Change the separation by the positional impulse `impulse` (each side takes it times
    /// its weight).
    fn push(&self, frames: &mut [RigidFrame], impulse: V3) {
        for s in &self.sides {
            if let Some(frame) = frames.get_mut(s.frame as usize) {
                let at = frame.moved(s.point);
                frame.push(at, impulse * s.weight);
            }
        }
    }
}

/// Solve `contacts` on `frames`, starting the alternating order backwards when `reverse`
/// (module docs). The frames' motion is applied to their nodes afterwards.
pub(crate) fn solve(frames: &mut [RigidFrame], contacts: &mut [FramePairContact], reverse: bool) {
    let first = usize::from(reverse);
    let pairs = Pairs::of(contacts);
    for sweep in first..first + CENTRE_SWEEPS {
        push_at_centres(frames, contacts, &pairs, sweep);
    }
    // Each contact's inverse mass along its normal where the passes start (the frames turn
    // by a few microradians in a substep).
    let along_normal: Vec<f64> = (contacts.iter())
        .map(|c| c.inverse_mass(frames, c.normal))
        .collect();
    for pass in first..first + NORMAL_PASSES {
        let mut largest = 0.0f64;
        for k in alternating(contacts.len(), pass) {
            let (c, along) = (&mut contacts[k], along_normal[k]);
            if along <= 0.0 {
                continue;
            }
            let gap = c.normal.dot(&c.separation(frames));
            let total = (c.impulse + (c.target - gap) / along).max(0.0);
            if total != c.impulse {
                c.push(frames, c.normal * (total - c.impulse));
                largest = largest.max((total - c.impulse).abs() * along);
                c.impulse = total;
            }
        }
        if largest <= CONVERGED {
            break;
        }
    }
    for pass in first..first + FRICTION_PASSES {
        for k in alternating(contacts.len(), pass) {
            let c = &mut contacts[k];
            if c.impulse <= 0.0 {
                continue;
            }
            let slip = tangential(c.separation(frames) - c.previous, &c.normal);
            let length = slip.norm();
            if length <= 0.0 {
                continue;
            }
            let along = c.inverse_mass(frames, slip / length);
            if along <= 0.0 {
                continue;
            }
            let total = friction(c.friction_impulse - slip / along, c.friction * c.impulse);
            c.push(frames, total - c.friction_impulse);
            c.friction_impulse = total;
        }
    }
}

/// The contacts of one pair of frames (or of a frame and the planes), as a range of
/// [`Pairs::order`].
struct Pair {
    frames: [u32; 2],
    contacts: std::ops::Range<usize>,
}

/// The contacts grouped by pair, each group in the contacts' order, the groups in order of
/// their first contact.
struct Pairs {
    pairs: Vec<Pair>,
    order: Vec<usize>,
}

impl Pairs {
    fn of(contacts: &[FramePairContact]) -> Pairs {
        let mut index = rustc_hash::FxHashMap::default();
        let mut members: Vec<Vec<usize>> = Vec::new();
        let mut keys = Vec::new();
        for (k, c) in contacts.iter().enumerate() {
            let key = [c.sides[0].frame, c.sides[1].frame];
            let slot = *index.entry(key).or_insert_with(|| {
                keys.push(key);
                members.push(Vec::new());
                members.len() - 1
            });
            members[slot].push(k);
        }
        let mut order = Vec::with_capacity(contacts.len());
        let mut pairs = Vec::with_capacity(keys.len());
        for (frames, list) in keys.into_iter().zip(members) {
            let start = order.len();
            order.extend(list);
            pairs.push(Pair {
                frames,
                contacts: start..order.len(),
            });
        }
        Pairs { pairs, order }
    }
}

/// One sweep over the pairs of frames (in alternating order by `sweep`): per pair, one push
/// at the centre of its contacts closer than their targets, along their mean normal, that
/// brings their mean shortfall to zero, shared among those contacts as impulse (each keeps
/// pushing, never pulling). A box resting flat on another is then lifted level, as a whole:
/// contact by contact, the first ones tilted it and the rest tilted it back, a little
/// differently each substep.
fn push_at_centres(
    frames: &mut [RigidFrame],
    contacts: &mut [FramePairContact],
    pairs: &Pairs,
    sweep: usize,
) {
    for p in alternating(pairs.pairs.len(), sweep) {
        let pair = &pairs.pairs[p];
        let members = &pairs.order[pair.contacts.clone()];
        // The short contacts' summed points, normals (oriented from the second frame to the
        // first) and shortfalls.
        let (mut points, mut normals, mut shortfalls, mut count) =
            (V3::zeros(), V3::zeros(), 0.0, 0);
        for &k in members {
            let c = &contacts[k];
            let short = c.target - c.normal.dot(&c.separation(frames));
            if short > 0.0 {
                points += c.sides[0].now(frames);
                normals += c.normal * c.sides[0].weight.signum();
                shortfalls += short;
                count += 1;
            }
        }
        if count == 0 || normals.norm() < NORMALS_AGREE * count as f64 {
            continue;
        }
        let (centre, normal) = (points / count as f64, normals.normalize());
        let along: f64 = (pair.frames.iter())
            .filter_map(|&f| frames.get(f as usize))
            .map(|f| f.inverse_mass_at(centre, normal))
            .sum();
        if along <= 0.0 {
            continue;
        }
        let push = shortfalls / count as f64 / along;
        let share = push / count as f64;
        for &k in members {
            let c = &mut contacts[k];
            if c.target > c.normal.dot(&c.separation(frames)) {
                c.impulse += share;
            }
        }
        for (&f, sign) in pair.frames.iter().zip([1.0, -1.0]) {
            if let Some(frame) = frames.get_mut(f as usize) {
                frame.push(centre, normal * (push * sign));
            }
        }
    }
}

/// The points of the display surface of each frame in `touching` that lie within `margin` of
/// a plane (floor, walls), as contacts with the plane that keep them on it, with its
/// friction `mu`: the plane holds up a stack's bottom box in the same passes as the boxes on
/// it. Solved after them, it turned the box back each substep that the boxes above had
/// pressed it down at their off-centre weight, and the boxes, held to it by friction, rode
/// that turn: a stack of steel boxes each shifted 2 cm walked sideways 3 mm a second.
pub(crate) fn plane_contacts(
    (surface, planes, mu): (&SurfacePoints, &[Plane], f64),
    (x, previous): (&[V3], &[V3]),
    (frame_of, touching): (&[u32], &[bool]),
    margin: f64,
    out: &mut Vec<FramePairContact>,
) {
    if planes.is_empty() {
        return;
    }
    for (nodes, weights) in surface.nodes.iter().zip(&surface.weights) {
        let frame = frame_of.get(nodes[0] as usize).copied().unwrap_or(NO_FRAME);
        if !touching.get(frame as usize).copied().unwrap_or(false) {
            continue;
        }
        let (mut p, mut p_prev) = (V3::zeros(), V3::zeros());
        for (&k, &w) in nodes.iter().zip(weights) {
            p += x[k as usize] * w;
            p_prev += previous[k as usize] * w;
        }
        for plane in planes {
            let gap = plane.normal.dot(&p) - plane.offset;
            if gap >= margin || gap.is_nan() {
                continue;
            }
            let on_plane = p - plane.normal * gap;
            let sides = [
                Side {
                    frame,
                    weight: 1.0,
                    point: p,
                },
                Side {
                    frame: NO_FRAME,
                    weight: -1.0,
                    point: on_plane,
                },
            ];
            let contact = FramePairContact::new(sides, (plane.normal, p_prev - on_plane), 0.0, mu);
            out.push(contact);
        }
    }
}
