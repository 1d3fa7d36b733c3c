//! Stage 4b, held and rigid bodies on static colliders: the points of such a body that the
//! points' pass found in a collider ([`super::rigid_contacts`]) are solved together, on the
//! body's rigid frame ([`super::frames`]), after that pass.
//!
//! Through its nodes, a collider's push moved only the eight round the point and the shape
//! matching spread it over the body: the body sank a little further every substep until the
//! points' depths held it up, and friction, bounded by those depths, held it far harder than
//! Coulomb's law (a wooden box sliding at 2 m/s on a ground plane collider with μ = 0.4
//! stopped in 0.14 m, not 0.51; on a 30° ramp it crept at 0.08 m/s where it should slide at
//! 1.5 m/s²; a `kind = "rigid"` box sank through it). Pushed one point at a time on the
//! frame, the first points of a face landing flat turned the body for the rest, and a
//! wooden box dropped flat bounced off tilted and slid away.
//!
//! So, per body: first one push at the centre of its contact points, along their mean
//! normal, that brings their mean depth to zero (exact for a face landing flat); then
//! sequential impulses over the points, accumulated per point and kept pushing (never
//! pulling), in alternating order, each bringing its point back to its face's plane; then
//! Coulomb friction at each point on its slip over the substep, bounded by μ times its
//! normal impulse, the same way. Impulses here are positional (kg·m): a push `J` along `n`
//! at `p` moves the point by `J` times the body's inverse mass there along `n`.
//!
//! The points' pass leaves out a two-sided collider's face whose normal points away from the
//! body's centre: it was met from its far side (a box's corner pushed past the bottom of a
//! V-shaped groove meets the other wall from behind), and its push, taken by the whole body,
//! threw a wooden box a metre along the groove; the face on the near side holds the point.

use super::contact::{alternating, friction_impulse, tangential};
use super::frames::RigidFrame;
use super::V3;

/// Normal passes over a body's contact points (after the first push at their centre).
const NORMAL_PASSES: usize = 16;
/// A normal pass that moves no point by more than this, m, ends them (the same passes on
/// any thread count: the solve is serial).
const CONVERGED: f64 = 1e-7;
/// Friction passes over the contact points.
const FRICTION_PASSES: usize = 4;
/// How closely a body's contact normals must agree (their mean's length, 1 when parallel) for
/// the first push at their centre: in a corner or a groove one push along their mean would
/// move the body the wrong way, and the passes alone solve it.
const NORMALS_AGREE: f64 = 0.95;

/// A held or rigid body's display-surface point that a static collider holds this substep.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FrameContact {
    /// The point, where the pass left it before the frames moved, and its body's frame.
    point: V3,
    frame: u32,
    /// The collider face's normal, and a point of the face's plane.
    normal: V3,
    on_face: V3,
    /// Where the point was at the substep's start.
    previous: V3,
    /// The collider's friction coefficient.
    friction: f64,
    /// Accumulated normal and friction impulses, kg·m.
    impulse: f64,
    friction_impulse: V3,
}

impl FrameContact {
    pub(crate) fn new(
        (point, frame): (V3, u32),
        (normal, on_face): (V3, V3),
        previous: V3,
        friction: f64,
    ) -> FrameContact {
        FrameContact {
            point,
            frame,
            normal,
            on_face,
            previous,
            friction,
            impulse: 0.0,
            friction_impulse: V3::zeros(),
        }
    }
}

/// Solve `contacts` on `frames` (module docs); the frames' motion is applied to their nodes
/// afterwards.
pub(crate) fn solve(frames: &mut [RigidFrame], contacts: &mut [FrameContact]) {
    if contacts.is_empty() {
        return;
    }
    push_at_centres(frames, contacts);
    for pass in 0..NORMAL_PASSES {
        // The most a pass moved a point: passes stop once none moves more than CONVERGED.
        let mut largest = 0.0f64;
        for k in alternating(contacts.len(), pass) {
            let c = &mut contacts[k];
            let frame = &mut frames[c.frame as usize];
            let p = frame.moved(c.point);
            let along = frame.inverse_mass_at(p, c.normal);
            if along <= 0.0 {
                continue;
            }
            let depth = (c.on_face - p).dot(&c.normal);
            let total = (c.impulse + depth / along).max(0.0);
            frame.push(p, c.normal * (total - c.impulse));
            largest = largest.max((total - c.impulse).abs() * along);
            c.impulse = total;
        }
        if largest <= CONVERGED {
            break;
        }
    }
    for pass in 0..FRICTION_PASSES {
        for k in alternating(contacts.len(), pass) {
            let c = &mut contacts[k];
            let frame = &mut frames[c.frame as usize];
            let p = frame.moved(c.point);
            let slip = tangential(p - c.previous, &c.normal);
            let limit = c.friction * c.impulse;
            let along = |u| frame.inverse_mass_at(p, u);
            let Some(total) = friction_impulse(slip, c.friction_impulse, limit, along) else {
                continue;
            };
            frame.push(p, total - c.friction_impulse);
            c.friction_impulse = total;
        }
    }
}

/// Per frame, one push at the centre of its contact points along their mean normal that
/// brings their mean depth to zero, shared among the points as their first impulses.
fn push_at_centres(frames: &mut [RigidFrame], contacts: &mut [FrameContact]) {
    // Per frame: the points' sum, the normals' sum, the depths' sum and the count.
    let mut sums = vec![(V3::zeros(), V3::zeros(), 0.0, 0usize); frames.len()];
    for c in contacts.iter() {
        let frame = &frames[c.frame as usize];
        let p = frame.moved(c.point);
        let s = &mut sums[c.frame as usize];
        s.0 += p;
        s.1 += c.normal;
        s.2 += (c.on_face - p).dot(&c.normal);
        s.3 += 1;
    }
    let mut shares = vec![0.0; frames.len()];
    for (f, &(points, normals, depths, count)) in sums.iter().enumerate() {
        if count == 0 || depths <= 0.0 || normals.norm() < NORMALS_AGREE * count as f64 {
            continue;
        }
        let (centre, normal) = (points / count as f64, normals.normalize());
        let along = frames[f].inverse_mass_at(centre, normal);
        if along <= 0.0 {
            continue;
        }
        let push = depths / count as f64 / along;
        frames[f].push(centre, normal * push);
        shares[f] = push / count as f64;
    }
    for c in contacts.iter_mut() {
        c.impulse = shares[c.frame as usize];
    }
}
