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
//! affinely, so a side's weighted nodes move as their weighted mean does). The floor, walls
//! and static colliders under these frames join as contacts with a fixed side
//! ([`StaticContacts`]). Then, in alternating orders: pushes at each pair's centre
//! (`push_at_centres`), which carry a stack's weight down to the floor; normal passes over
//! all the contacts that accumulate each contact's impulse (never pulling) until no pass
//! moves a contact by more than [`CONVERGED`], then over the static contacts alone the same
//! way; and Coulomb friction at each contact on its
//! slip over the substep, bounded by μ times its normal impulse, the way the colliders'
//! frame contacts have it ([`super::frame_contacts`]). Serial, in the contacts' order: the
//! same bits on any thread count.
//!
//! A contact keeps `n · d ≥ min(g, start + opening)`: the gap `g`, or, for a contact closer
//! than the gap when the substep started, that start opened by `opening` at most
//! ([`super::bodies`]' module docs). A separating contact leaves the rest of its overlap to
//! [`super::shift_bodies`] through `rest`, grown as [`super::bodies`] grows it.

use super::bodies::NO_FRAME;
use super::contact::{alternating, friction_impulse, tangential};
use super::frames::RigidFrame;
use super::V3;
use crate::solver::contact::Plane;
use crate::solver::world::SurfacePoints;

/// Most normal passes over the contacts.
const NORMAL_PASSES: usize = 12;
/// A normal pass that moves no contact by more than this, m, ends them (serial: the same
/// passes on any thread count).
const CONVERGED: f64 = 1e-7;
/// Most sweeps of one push per pair of frames at its contacts' centre, before the passes.
const CENTRE_SWEEPS: usize = 32;
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
    push_at_centres(frames, contacts, first);
    // Each contact's inverse mass along its normal where the passes start (the frames turn
    // by a few microradians in a substep).
    let along_normal: Vec<f64> = (contacts.iter())
        .map(|c| c.inverse_mass(frames, c.normal))
        .collect();
    let all: Vec<usize> = (0..contacts.len()).collect();
    normal_passes(frames, contacts, &along_normal, (&all, first));
    // The static contacts alone, until they converge: what the passes over all contacts
    // leave them short, the collider stage after this one ([`super::frame_contacts`]) took
    // up, a few µm, on the bottom box alone and with its friction, which turned it under the
    // boxes above: a crooked stack of six on a collider slab slid 1 mm in 1.5 s.
    let fixed: Vec<usize> = (contacts.iter().enumerate())
        .filter(|(_, c)| c.sides[1].frame == NO_FRAME)
        .map(|(k, _)| k)
        .collect();
    normal_passes(frames, contacts, &along_normal, (&fixed, first));
    for pass in first..first + FRICTION_PASSES {
        for k in alternating(contacts.len(), pass) {
            let c = &mut contacts[k];
            if c.impulse <= 0.0 {
                continue;
            }
            let slip = tangential(c.separation(frames) - c.previous, &c.normal);
            let limit = c.friction * c.impulse;
            let along = |u| c.inverse_mass(frames, u);
            let Some(total) = friction_impulse(slip, c.friction_impulse, limit, along) else {
                continue;
            };
            c.push(frames, total - c.friction_impulse);
            c.friction_impulse = total;
        }
    }
}

/// Up to [`NORMAL_PASSES`] passes over the contacts `which` (in alternating order, the first
/// backwards when `first` is odd), each accumulating a contact's normal impulse to bring it to
/// its target (never pulling), until a pass moves none by more than [`CONVERGED`].
/// `along_normal`: each contact's inverse mass along its normal.
fn normal_passes(
    frames: &mut [RigidFrame],
    contacts: &mut [FramePairContact],
    along_normal: &[f64],
    (which, first): (&[usize], usize),
) {
    for pass in first..first + NORMAL_PASSES {
        let mut largest = 0.0f64;
        for k in alternating(which.len(), pass).map(|j| which[j]) {
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
}

/// The contacts of one pair of frames (or of a frame and static geometry) that are closer
/// than their targets when the passes start, summed so that a push at their centre is one
/// step however many they are: the frames move their points affinely, so the contacts'
/// summed shortfall follows from the frames' motion alone (each side's weights sum to ±1).
struct Pair {
    /// The frames (the second may be [`NO_FRAME`]).
    frames: [u32; 2],
    /// The short contacts (indices into the contacts).
    members: Vec<usize>,
    /// Their summed normals `m`, oriented from the second side to the first.
    normal: V3,
    /// Their summed shortfalls when the passes start, m.
    short: f64,
    /// The first side's points' mean (where the pushes act), and per side `Σ (p − c) × m`
    /// about its frame's centre.
    centre: V3,
    turn: [V3; 2],
    /// The pushes so far, kg·m.
    impulse: f64,
}

impl Pair {
    /// The summed shortfall with the frames' motion so far.
    fn short_now(&self, frames: &[RigidFrame]) -> f64 {
        let mut moved = 0.0;
        for (side, (&f, sign)) in self.frames.iter().zip([1.0, -1.0]).enumerate() {
            if let Some(frame) = frames.get(f as usize) {
                let by = self.normal.dot(&frame.translation) + frame.rotation.dot(&self.turn[side]);
                moved += sign * by;
            }
        }
        self.short - moved
    }
}

/// The short contacts of `contacts` grouped by pair, the groups in order of their first
/// contact, with their sums (the frames have not moved yet).
fn short_pairs(frames: &[RigidFrame], contacts: &[FramePairContact]) -> Vec<Pair> {
    let mut index = rustc_hash::FxHashMap::default();
    let mut pairs: Vec<Pair> = Vec::new();
    for (k, c) in contacts.iter().enumerate() {
        let short = c.target - c.normal.dot(&c.separation(frames));
        if short <= 0.0 {
            continue;
        }
        let key = [c.sides[0].frame, c.sides[1].frame];
        let slot = *index.entry(key).or_insert_with(|| {
            pairs.push(Pair {
                frames: key,
                members: Vec::new(),
                normal: V3::zeros(),
                short: 0.0,
                centre: V3::zeros(),
                turn: [V3::zeros(); 2],
                impulse: 0.0,
            });
            pairs.len() - 1
        });
        let pair = &mut pairs[slot];
        let m = c.normal * c.sides[0].weight.signum();
        pair.members.push(k);
        pair.normal += m;
        pair.short += short;
        pair.centre += c.sides[0].point;
        for (side, s) in c.sides.iter().enumerate() {
            if let Some(frame) = frames.get(s.frame as usize) {
                pair.turn[side] += (s.point - frame.centre).cross(&m);
            }
        }
    }
    for pair in &mut pairs {
        pair.centre /= pair.members.len() as f64;
    }
    pairs
}

/// Pushes at the pairs' centres (module docs): sweeps over the pairs, in alternating order,
/// each pushing its frames apart at the mean of its short contacts' points, along their mean
/// normal, by what brings their mean shortfall to zero (never pulling in all), until a sweep
/// moves no pair by more than [`CONVERGED`]; then each pair's impulse is shared among its
/// contacts as their first impulses. A box resting flat on another is lifted level, as a
/// whole, and a stack's weight reaches its bottom box and the floor in these sweeps:
/// contact by contact, the first ones tilted a box and the rest tilted it back, a little
/// differently each substep.
fn push_at_centres(frames: &mut [RigidFrame], contacts: &mut [FramePairContact], first: usize) {
    let mut pairs = short_pairs(frames, contacts);
    for sweep in first..first + CENTRE_SWEEPS {
        let mut largest = 0.0f64;
        for p in alternating(pairs.len(), sweep) {
            let pair = &mut pairs[p];
            let count = pair.members.len() as f64;
            if pair.normal.norm() < NORMALS_AGREE * count {
                continue;
            }
            let normal = pair.normal.normalize();
            let centre = match frames.get(pair.frames[0] as usize) {
                Some(frame) => frame.moved(pair.centre),
                None => continue,
            };
            let along: f64 = (pair.frames.iter())
                .filter_map(|&f| frames.get(f as usize))
                .map(|f| f.inverse_mass_at(centre, normal))
                .sum();
            if along <= 0.0 {
                continue;
            }
            let total = (pair.impulse + pair.short_now(frames) / count / along).max(0.0);
            let push = total - pair.impulse;
            pair.impulse = total;
            largest = largest.max(push.abs() * along);
            for (&f, sign) in pair.frames.iter().zip([1.0, -1.0]) {
                if let Some(frame) = frames.get_mut(f as usize) {
                    frame.push(centre, normal * (push * sign));
                }
            }
        }
        if largest <= CONVERGED {
            break;
        }
    }
    for pair in &pairs {
        let share = pair.impulse / pair.members.len() as f64;
        for &k in &pair.members {
            contacts[k].impulse += share;
        }
    }
}

/// A surface point's frame, where it is now and where it was at the substep's start.
type FramePoint = (u32, V3, V3);

/// The display-surface points of the frames in contact with other frames, where they meet
/// static geometry, as contacts of the same passes: the floor or a collider holds up a
/// stack's bottom box together with the boxes on it. Solved after them, it turned the box
/// back each substep that the boxes above had pressed it down at their off-centre weight,
/// and the boxes, held to it by friction, rode that turn: a stack of steel boxes each
/// shifted 2 cm walked sideways 3 mm a second. On a collider, the bottom box was pushed back
/// up into the box above, which then sank into it, and the stack fell.
pub(crate) struct StaticContacts<'a> {
    pub surface: &'a SurfacePoints,
    /// Node positions now and at the substep's start.
    pub x: &'a [V3],
    pub previous: &'a [V3],
    /// Per node its frame, and per frame whether it is in contact with another.
    pub frame_of: &'a [u32],
    pub touching: &'a [bool],
    /// Points farther from the plane or face than this are left out, m.
    pub margin: f64,
}

impl StaticContacts<'_> {
    /// Surface point `i`'s frame, if it is one in `touching`, and where the point is now and
    /// was at the substep's start.
    fn point(&self, i: usize) -> Option<FramePoint> {
        let nodes = self.surface.nodes.get(i)?;
        let frame = self.frame_of.get(nodes[0] as usize).copied()?;
        if !self.touching.get(frame as usize).copied().unwrap_or(false) {
            return None;
        }
        let (mut p, mut p_prev) = (V3::zeros(), V3::zeros());
        for (&k, &w) in nodes.iter().zip(&self.surface.weights[i]) {
            p += self.x[k as usize] * w;
            p_prev += self.previous[k as usize] * w;
        }
        Some((frame, p, p_prev))
    }

    /// The contact of point `p` of `frame` (at `p_prev` at the substep's start) with the plane
    /// through `on_plane` of unit `normal`, with friction `mu`, if within the margin.
    fn push(
        &self,
        (frame, p, p_prev): FramePoint,
        (normal, on_plane): (V3, V3),
        mu: f64,
        out: &mut Vec<FramePairContact>,
    ) {
        let gap = normal.dot(&(p - on_plane));
        if gap >= self.margin || gap.is_nan() {
            return;
        }
        let at = p - normal * gap;
        let sides = [
            Side {
                frame,
                weight: 1.0,
                point: p,
            },
            Side {
                frame: NO_FRAME,
                weight: -1.0,
                point: at,
            },
        ];
        out.push(FramePairContact::new(sides, (normal, p_prev - at), 0.0, mu));
    }

    /// The points' contacts with `planes` (floor, walls), whose friction is `mu`.
    pub(crate) fn planes(&self, planes: &[Plane], mu: f64, out: &mut Vec<FramePairContact>) {
        let mut near = Vec::new();
        for plane in planes {
            near.clear();
            let on_plane = plane.normal * plane.offset;
            for i in 0..self.surface.nodes.len() {
                if let Some(point) = self.point(i) {
                    if plane.normal.dot(&(point.1 - on_plane)) < self.margin {
                        near.push(point);
                    }
                }
            }
            // The surface points are in body order: one run per frame.
            for run in near.chunk_by(|a, b| a.0 == b.0) {
                for k in outline(run.iter().map(|p| p.1), plane.normal) {
                    self.push(run[k], (plane.normal, on_plane), mu, out);
                }
            }
        }
    }

    /// The points resting on a static collider's face (`resting`: per surface point, the
    /// collider, the face's unit normal and a point of it, see `Model::collider_side`),
    /// against the face's plane with the collider's friction (`friction`, per collider).
    /// As on the planes, only the corners of each frame's outline on each of a collider's
    /// face planes are kept ([`outline`]): every resting point held a stack's bottom box on
    /// a collider slab, and the passes, which rarely converge over hundreds of contacts, left
    /// the boxes above sliding 4 mm in 2 s.
    pub(crate) fn faces(
        &self,
        resting: &[Option<(u32, V3, V3)>],
        friction: impl Fn(u32) -> f64,
        out: &mut Vec<FramePairContact>,
    ) {
        let mut index = rustc_hash::FxHashMap::default();
        let mut groups: Vec<Vec<(usize, FramePoint)>> = Vec::new();
        for (i, side) in resting.iter().enumerate() {
            let Some((collider, normal, on_face)) = *side else {
                continue;
            };
            if let Some(point) = self.point(i) {
                let key = (point.0, collider, plane_key(normal, on_face));
                let slot = *index.entry(key).or_insert_with(|| {
                    groups.push(Vec::new());
                    groups.len() - 1
                });
                groups[slot].push((i, point));
            }
        }
        for group in &groups {
            let Some(&(first, _)) = group.first() else {
                continue;
            };
            let Some((_, normal, _)) = resting[first] else {
                continue;
            };
            for k in outline(group.iter().map(|p| p.1 .1), normal) {
                let (i, point) = group[k];
                if let Some((collider, normal, on_face)) = resting[i] {
                    self.push(point, (normal, on_face), friction(collider), out);
                }
            }
        }
    }
}

/// Resolution of [`plane_key`]: the faces of one flat side of a collider (its triangles) give
/// normals and offsets that differ by rounding only.
const PLANE_KEY_RESOLUTION: f64 = 1e-6;

/// A face plane's normal and offset, rounded to [`PLANE_KEY_RESOLUTION`], to group the points
/// resting on one flat side of a collider.
fn plane_key(normal: V3, on_face: V3) -> [i64; 4] {
    let round = |v: f64| (v / PLANE_KEY_RESOLUTION).round() as i64;
    [
        round(normal.x),
        round(normal.y),
        round(normal.z),
        round(normal.dot(&on_face)),
    ]
}

/// Directions in a plane along which [`outline`] takes a body's outermost point.
const OUTLINE_DIRECTIONS: usize = 8;

/// The indices of the points of `points` (of one rigid body) outermost along
/// [`OUTLINE_DIRECTIONS`] directions in the plane of unit normal `n`, each once, in order.
/// A rigid body's distance from a plane is affine over its points, so it is least at a
/// corner of their outline: a box's face resting on the floor is held by its corners as by
/// its hundreds of samples, in a fraction of the passes' time. The first point wins a tie.
fn outline(points: impl Iterator<Item = V3>, n: V3) -> Vec<usize> {
    let u = n
        .cross(&if n.x.abs() < 0.9 { V3::x() } else { V3::y() })
        .normalize();
    let v = n.cross(&u);
    let directions: Vec<V3> = (0..OUTLINE_DIRECTIONS)
        .map(|k| {
            let angle = std::f64::consts::TAU * k as f64 / OUTLINE_DIRECTIONS as f64;
            u * angle.cos() + v * angle.sin()
        })
        .collect();
    let mut best = vec![(f64::NEG_INFINITY, usize::MAX); OUTLINE_DIRECTIONS];
    for (i, p) in points.enumerate() {
        for (d, b) in directions.iter().zip(&mut best) {
            let along = d.dot(&p);
            if along > b.0 {
                *b = (along, i);
            }
        }
    }
    let mut chosen: Vec<usize> = best
        .iter()
        .map(|b| b.1)
        .filter(|&i| i != usize::MAX)
        .collect();
    chosen.sort_unstable();
    chosen.dedup();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_outline_of_a_resting_face_is_its_corners() {
        // A 5 × 5 grid of samples on a face resting on the floor (normal +y).
        let points: Vec<V3> = (0..25)
            .map(|k| V3::new(f64::from(k % 5) * 0.1, 0.0, f64::from(k / 5) * 0.1))
            .collect();
        let chosen = outline(points.iter().copied(), V3::y());
        for corner in [0, 4, 20, 24] {
            assert!(chosen.contains(&corner), "{chosen:?}");
        }
        let on_rim = |p: &V3| {
            [p.x, p.z]
                .iter()
                .any(|&c| c.abs() < 1e-12 || (c - 0.4).abs() < 1e-12)
        };
        assert!(chosen.iter().all(|&k| on_rim(&points[k])), "{chosen:?}");
        assert!(chosen.len() <= OUTLINE_DIRECTIONS);
    }
}
