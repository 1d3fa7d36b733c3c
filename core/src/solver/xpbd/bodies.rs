//! Contact between bodies as inequality constraints of the XPBD step (stage 4a): each
//! contact the body–body pass found at the substep's start
//! ([`crate::solver::body_contact::BodyConstraint`]) keeps its two features from passing each
//! other along its normal, `C = n · Σ s_k x_k ≥ g` (a small gap `g`, [`REST_GAP_LAYERS`]),
//! with no compliance, and Coulomb friction on their relative slip over the substep as the
//! floor has it ([`super::contact`]): static while the slip is within μ times the normal
//! correction, else shortened by that much.
//! The correction of the pair's separation `δ` moves node `k` by `s_k w_k δ / Σ s_j² w_j`
//! (`w` the inverse masses), so the separation changes by exactly `δ` and momentum is
//! conserved. A pair's contacts are met one after the other, in the order the pass found
//! them; pairs that share no node side by side on the team, a colour of pairs at a time
//! ([`ConstraintColours`]): the same bits on any thread count, and, as a colour's pairs touch
//! different nodes, the same bits as meeting every pair in turn in its colour's order. Where a
//! held or rigid body takes part, everything is serial in the pass's order.
//!
//! A contact already closer than the gap at the substep's start (found a substep late, or
//! pressed back in by the floor under a body squeezed between it and another) stops its
//! features' approach and opens them by [`super::MAX_SEPARATION_SPEED`] at most; the rest
//! of its overlap waits for the next substeps. Projected out whole, such an overlap became
//! velocity, `depth / Δt`, every substep it came back: a foam ball dropped on a jelly block
//! gained energy from its first touch (1.4 J to 7 J in 60 ms, nodes at 20 m/s) until cells
//! folded and the bake went to 13 800 J, and a rubber ball pressing the jelly onto the floor
//! likewise; more substeps made it worse.
//!
//! Where no held or rigid body takes part, the constraints are passed over
//! [`CONTACT_PASSES`] times a substep, each contact keeping the push and the friction it has
//! made in all ([`BodyContacts::settle`]). One pass pushes the first of the contacts that share
//! nodes too far: a sample's push moves its cell's nodes, which the samples after it on that
//! cell share. At the pass's end two rubber boxes resting on each other stood some 0.24 mm
//! farther apart than the gap at nearly every contact; the next substep's sweep pulled the
//! cells back as far (0.33 mm a substep at one node, with 0.1 mm of slip along the faces), the
//! contacts pushed them apart again, and the friction, bounded by each contact's small push,
//! let the slip through: a 20 cm rubber box resting centred on a 30 cm one wandered 0.1 m in
//! 2 s at friction 2, and how a stack swayed depended on how its faces were triangulated.
//! Each later pass brings every contact pushed, or near its gap, back to the gap, taking back
//! what it was pushed too far but never more than it pushed, and bounds its friction by μ times
//! its push in all, as sequential impulses do (Catto 2005).
//!
//! The contacts between two held or rigid bodies (every node of theirs moved by a frame) are
//! solved first and apart, together with the floor and colliders under those bodies
//! ([`super::frame_pairs`]); this module's pass takes the rest. In it, a held or rigid body
//! that rests on the floor, a wall or a collider stays put under a push into that support over
//! the outline it rests on ([`super::support`]): only the elastic side moves.
//!
//! Parts that start inside each other's surfaces (a shallow overlap the glue does not take)
//! separate at [`super::MAX_SEPARATION_SPEED`] at most while their nodes carry the start's
//! overlap flag, not at their depth over one substep: such a contact stops its features'
//! approach and opens them at that speed; the rest of its correction is left in `rest`
//! for [`super::shift_bodies`] to move the bodies apart as wholes, without speed.

use super::contact::{friction, tangential};
use super::frame_pairs::{self, FramePairContact, Side, StaticContacts};
use super::frames::{apply_frames, RigidFrame};
use super::support::Support;
use crate::collide::StaticCollider;
use crate::solver::body_contact::colours::ConstraintColours;
use crate::solver::body_contact::{BodyConstraint, CONSTRAINT_FRONT};
use crate::solver::contact::Plane;
use crate::solver::team::{self, Disjoint, Tasks};
use crate::solver::world::SurfacePoints;
use nalgebra::Vector3;
use std::ops::Range;

type V3 = Vector3<f64>;

/// The gap the constraints keep between two surfaces, in contact layer thicknesses. Not
/// zero: a sample resting exactly on its partner's surface has no direction to it where the
/// nearest point is an edge (a cube's rim under the rim of a cube stacked on it ties between
/// the top face and a side face), and a side face's normal would push the stack apart.
/// A point a little way off an edge has the direction to it, the same from both faces.
pub(crate) const REST_GAP_LAYERS: f64 = 0.1;

/// Fewer constraints than this in a colour are met on the calling thread, not shared with
/// the team: handing out a pass costs some microseconds, about what a few hundred
/// constraints take (a pile's tail colours held a pair or two of 20–100 constraints).
const SHARED_COLOUR: u32 = 256;

/// `frame_of`'s mark of a node that no held or rigid body's frame moves.
pub(crate) const NO_FRAME: u32 = u32::MAX;

/// Passes over the body–body constraints a substep makes where no held or rigid body takes
/// part (module docs).
const CONTACT_PASSES: usize = 4;

/// How far beyond its gap (in the first pass's largest pushes) a contact the first pass did
/// not push is still passed over again: its neighbours' pushes taken back can bring it back
/// within its gap, as far as they pushed. Never beyond the front the contact pass keeps
/// constraints within ([`CONSTRAINT_FRONT`] of the layer, the gap being [`REST_GAP_LAYERS`]
/// of it), so the contacts it leaves out would not have acted in these passes either.
const SETTLE_REACH: f64 = 2.0;

/// What the passes of one substep have done at a constraint, for the passes after the
/// first ([`BodyContacts::settle`]).
#[derive(Debug, Clone, Copy, Default)]
struct Done {
    /// The separation of its features at the substep's start.
    previous: V3,
    /// `Σ s_k² w_k` over its elastic nodes; zero for a constraint the later passes leave out
    /// (one the first pass did not reach, or with nothing to move).
    inverse_mass: f64,
    /// The separation along its normal the first pass found, m.
    gap: f64,
    /// The separation it is brought to ([`BodyContacts::target`]), m.
    target: f64,
    /// Its normal correction in all (never below zero), m.
    normal: f64,
    /// Its friction correction in all (within μ times `normal`), m.
    friction: V3,
}

impl Done {
    fn new(previous: V3, inverse_mass: f64, (gap, target): (f64, f64)) -> Self {
        Done {
            previous,
            inverse_mass,
            gap,
            target,
            ..Done::default()
        }
    }
}

/// `v` shortened to `limit` where it is longer.
fn clamp_length(v: V3, limit: f64) -> V3 {
    let length = v.norm();
    if length > limit && length > 0.0 {
        v * (limit.max(0.0) / length)
    } else {
        v
    }
}

/// What the constraints read.
pub(crate) struct BodyContacts<'a> {
    pub constraints: &'a [BodyConstraint],
    /// Their groups by colour, for the passes without held or rigid bodies.
    pub colours: &'a ConstraintColours,
    pub stencil: &'a [(u32, f64)],
    pub inv_mass: &'a [f64],
    /// Node positions at the substep's start.
    pub previous: &'a [V3],
    pub friction: f64,
    /// How far apart the constraints keep the surfaces, m ([`REST_GAP_LAYERS`] of the layer).
    pub gap: f64,
    /// Per node, while parts that started overlapping are still separating: in contact at
    /// the start (such a contact opens by `opening` at most a substep whatever its start).
    pub separating: Option<&'a [bool]>,
    /// Whether to start the frame pairs' alternating passes in reverse order (every other
    /// substep in a world with held or rigid bodies: see [`super::Model::contact_passes`]).
    pub reverse: bool,
    /// How far a contact closer than the gap at the substep's start, or a separating one,
    /// may open in one substep beyond where it started, m.
    pub opening: f64,
    /// The static geometry that the frames in contact with each other meet in the same
    /// passes ([`frame_pairs::StaticContacts`]).
    pub statics: Option<Statics<'a>>,
}

/// The display-surface points, the planes (floor, walls; with the contacts' `friction`), the
/// static colliders, and per point the collider face it rests on (`Model::collider_side`).
#[derive(Clone, Copy)]
pub(crate) struct Statics<'a> {
    pub surface: &'a SurfacePoints,
    pub planes: &'a [Plane],
    pub colliders: &'a [StaticCollider],
    pub resting: &'a [Option<(u32, V3, V3)>],
}

/// What the constraints did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Touch {
    pub touched: bool,
    /// Deepest a contact had passed its partner's surface before its correction, m.
    pub depth: f64,
    /// Whether a contact left part of its correction in `rest`.
    pub rested: bool,
}

/// The node arrays the constraints read and write: positions, the marks of the nodes they
/// move, their corrections, and what separating contacts leave to `rest`. A colour's tasks
/// share them, each touching only its own constraints' stencils' nodes, which no other task
/// of the colour touches ([`ConstraintColours`]).
struct Nodes<'a> {
    x: Disjoint<'a, V3>,
    moved: Disjoint<'a, bool>,
    by_bodies: Disjoint<'a, bool>,
    shift: Disjoint<'a, V3>,
    rest: Disjoint<'a, V3>,
}

impl<'a> Nodes<'a> {
    /// The arrays, one entry per node each (panics if their lengths differ).
    fn new(
        x: &'a mut [V3],
        (moved, by_bodies, shift, rest): (
            &'a mut [bool],
            &'a mut [bool],
            &'a mut [V3],
            &'a mut [V3],
        ),
    ) -> Self {
        let n = x.len();
        assert!(
            [moved.len(), by_bodies.len(), shift.len(), rest.len()] == [n; 4],
            "node arrays of different lengths"
        );
        Nodes {
            x: Disjoint::new(x),
            moved: Disjoint::new(moved),
            by_bodies: Disjoint::new(by_bodies),
            shift: Disjoint::new(shift),
            rest: Disjoint::new(rest),
        }
    }
}

// Every method's contract: no other task of the pass touches the nodes it is given. Each
// checks its node against the one length all five arrays share (`Nodes::new`) once.
#[allow(unsafe_code)]
impl Nodes<'_> {
    /// Node `k`'s position.
    ///
    /// # Safety
    /// No other task of the pass touches node `k`.
    unsafe fn x(&self, k: usize) -> V3 {
        // SAFETY: the caller's.
        unsafe { self.x.get(k) }
    }

    /// `Σ s_k x_k` over `stencil`.
    ///
    /// # Safety
    /// No other task of the pass touches the stencil's nodes.
    unsafe fn separation(&self, stencil: &[(u32, f64)]) -> V3 {
        // SAFETY: the caller's.
        stencil
            .iter()
            .map(|&(k, s)| unsafe { self.x(k as usize) } * s)
            .sum()
    }

    /// Move node `k` by `step` and mark it moved by the body contacts.
    ///
    /// # Safety
    /// No other task of the pass touches node `k`.
    unsafe fn shift_node(&self, k: usize, step: V3) {
        assert!(k < self.x.len(), "node {k} out of {}", self.x.len());
        // SAFETY: `k` is within every array (one length, `new`); the rest is the caller's.
        unsafe {
            self.x.set_unchecked(k, self.x.get_unchecked(k) + step);
            self.shift
                .set_unchecked(k, self.shift.get_unchecked(k) + step);
            self.moved.set_unchecked(k, true);
            self.by_bodies.set_unchecked(k, true);
        }
    }

    /// Leave `by` of node `k`'s move to `rest`.
    ///
    /// # Safety
    /// No other task of the pass touches node `k`.
    unsafe fn leave_to_rest(&self, k: usize, by: V3) {
        // SAFETY: the caller's.
        unsafe { self.rest.set(k, self.rest.get(k) + by) }
    }
}

/// The held and rigid bodies' part in the first pass: their frames (moved as rigid bodies,
/// applied to their nodes at the end), per node its frame (`frame_of`), per frame what it
/// rests on, and per frame the move its separating contacts leave to `rest`. All empty
/// without such bodies.
struct FrameSides<'f> {
    frames: &'f mut [RigidFrame],
    frame_of: &'f [u32],
    supports: &'f [Option<Support>],
    frame_rest: &'f mut [V3],
}

impl FrameSides<'_> {
    fn frame(&self, k: usize) -> u32 {
        self.frame_of.get(k).copied().unwrap_or(NO_FRAME)
    }
}

/// `a` and `b` together: touched if either is, the deeper depth.
fn both(a: Touch, b: Touch) -> Touch {
    Touch {
        touched: a.touched || b.touched,
        depth: a.depth.max(b.depth),
        rested: a.rested || b.rested,
    }
}

impl BodyContacts<'_> {
    /// Solve every constraint once on `x`, marking the nodes it moves in `moved` and in
    /// `by_bodies` (the elastic ones) and adding their corrections to `shift`, and what
    /// separating contacts leave to `rest`. The held
    /// and rigid bodies' `frames` (indexed per node by `frame_of`, empty without such bodies)
    /// move as rigid bodies ([`RigidFrame`]), applied to their nodes at the end.
    pub(crate) fn solve(
        &self,
        x: &mut [V3],
        (moved, by_bodies, shift, rest): (&mut [bool], &mut [bool], &mut [V3], &mut [V3]),
        (frames, frame_of): (&mut [RigidFrame], &[u32]),
    ) -> Touch {
        if frames.is_empty() {
            return self.solve_in_colours(&Nodes::new(x, (moved, by_bodies, shift, rest)));
        }
        let mut out = Touch::default();
        // Per frame, the move its separating contacts leave to `rest` (see `keep_apart`).
        let mut frame_rest = vec![V3::zeros(); frames.len()];
        let mut mixed = vec![false; frames.len()];
        let mut pairs = self.frame_pairs(
            x,
            (frames, frame_of),
            (&mut out, &mut frame_rest, &mut mixed),
        );
        let supports = self.add_statics(x, frame_of, &mixed, &mut pairs);
        frame_pairs::solve(frames, &mut pairs, self.reverse);
        // The rest in one order: alternated every other substep, an elastic box resting on a
        // held one crept 2 mm a second (the two orders' friction did not cancel), and a stack
        // of six rubber boxes fell sooner.
        {
            let nodes = Nodes::new(x, (&mut *moved, &mut *by_bodies, &mut *shift, &mut *rest));
            let mut sides = FrameSides {
                frames,
                frame_of,
                supports: &supports,
                frame_rest: &mut frame_rest,
            };
            for c in self.constraints {
                // SAFETY: one task, this thread's.
                #[allow(unsafe_code)]
                unsafe {
                    self.first(c, &nodes, &mut sides, None, &mut out)
                };
            }
        }
        apply_frames(frames, x, shift, moved);
        for (f, by) in frames.iter().zip(&frame_rest) {
            if *by != V3::zeros() {
                f.nodes.clone().for_each(|k| rest[k] += by);
            }
        }
        out
    }

    /// [`Self::solve`] in a world without held or rigid bodies: [`CONTACT_PASSES`] passes,
    /// those after the first taking back what it pushed too far ([`Self::settle`]), each pass
    /// a colour of pairs at a time, the colour's pairs side by side on the team.
    fn solve_in_colours(&self, nodes: &Nodes) -> Touch {
        let mut done = vec![Done::default(); self.constraints.len()];
        let mut touches = vec![Touch::default(); self.colours.groups.len()];
        {
            let (done, touches) = (Disjoint::new(&mut done), Disjoint::new(&mut touches));
            self.in_colours(|g, group| {
                let mut out = Touch::default();
                let mut sides = FrameSides {
                    frames: &mut [],
                    frame_of: &[],
                    supports: &[],
                    frame_rest: &mut [],
                };
                for i in group {
                    // SAFETY: a group's constraints and their nodes are its task's alone.
                    #[allow(unsafe_code)]
                    unsafe {
                        let mut d = Done::default();
                        let c = &self.constraints[i];
                        self.first(c, nodes, &mut sides, Some(&mut d), &mut out);
                        done.set(i, d);
                    }
                }
                // SAFETY: group `g` is this task's alone.
                #[allow(unsafe_code)]
                unsafe {
                    touches.set(g, out)
                };
            });
        }
        let pushed = done.iter().map(|d| d.normal).fold(0.0, f64::max);
        let front = self.gap * (CONSTRAINT_FRONT - REST_GAP_LAYERS) / REST_GAP_LAYERS;
        let reach = (SETTLE_REACH * pushed).min(front);
        let (done, touches) = (Disjoint::new(&mut done), Disjoint::new(&mut touches));
        for _ in 1..CONTACT_PASSES {
            self.in_colours(|g, group| {
                // SAFETY: as in the first pass.
                #[allow(unsafe_code)]
                unsafe {
                    let mut out = touches.get(g);
                    for i in group {
                        let mut d = done.get(i);
                        self.settle(&self.constraints[i], &mut d, reach, nodes, &mut out);
                        done.set(i, d);
                    }
                    touches.set(g, out);
                }
            });
        }
        // SAFETY: the passes are over.
        #[allow(unsafe_code)]
        (0..touches.len()).fold(Touch::default(), |t, g| both(t, unsafe { touches.get(g) }))
    }

    /// Run `task(g, its constraints)` for every group `g` of the constraints' colours
    /// ([`ConstraintColours`]), a colour at a time, the colour's groups side by side on the
    /// team (those of a serial colour, or of one with fewer than [`SHARED_COLOUR`]
    /// constraints in all, in order on this thread: the same bits either way).
    fn in_colours(&self, task: impl Fn(usize, Range<usize>) + Sync) {
        let colours = self.colours;
        let mut first = 0;
        for (colour, groups) in colours.colours().enumerate() {
            let small = groups.iter().map(|g| g.end - g.start).sum::<u32>() < SHARED_COLOUR;
            let serial = small || colours.serial_last && colour + 1 == colours.ends.len();
            let run = |g: usize| {
                let group = &groups[g];
                task(first + g, group.start as usize..group.end as usize);
            };
            if serial {
                (0..groups.len()).for_each(run);
            } else {
                team::for_each(Tasks(groups.len()), |g, ()| run(g));
            }
            first += groups.len();
        }
    }

    /// The first pass at constraint `c`: its features brought to the gap (or opened by
    /// `opening` at most, module docs), with friction, the held or rigid sides moved as
    /// frames. What it did goes to `done`, for the later passes, where there are any.
    ///
    /// # Safety
    /// No other task of the pass touches the nodes of `c`'s stencil.
    #[allow(unsafe_code)]
    unsafe fn first(
        &self,
        c: &BodyConstraint,
        nodes: &Nodes,
        fs: &mut FrameSides,
        mut done: Option<&mut Done>,
        out: &mut Touch,
    ) {
        let stencil = &self.stencil[c.stencil.start as usize..c.stencil.end as usize];
        if between_frames(stencil, &|k| fs.frame(k)) {
            return; // solved with the other frame pairs
        }
        let (mut d, mut d_prev, mut inverse_mass) = (V3::zeros(), V3::zeros(), 0.0);
        // Up to two sides moved as frames: (frame, summed weight, weighted point).
        let mut sides = [(NO_FRAME, 0.0, V3::zeros()); 2];
        for &(node, s) in stencil {
            let k = node as usize;
            d_prev += self.previous[k] * s;
            // SAFETY: the caller's.
            let xk = unsafe { nodes.x(k) };
            let f = fs.frame(k);
            if f == NO_FRAME {
                d += xk * s;
                inverse_mass += s * s * self.inv_mass[k];
                continue;
            }
            let xk = fs.frames[f as usize].moved(xk);
            d += xk * s;
            let slot = usize::from(sides[0].0 != NO_FRAME && sides[0].0 != f);
            sides[slot].0 = f;
            sides[slot].1 += s;
            sides[slot].2 += xk * s;
        }
        let mut points = [V3::zeros(); 2];
        for (side, point) in sides.iter_mut().zip(&mut points) {
            let (f, sum, weighted) = *side;
            if f != NO_FRAME && sum != 0.0 {
                *point = weighted / sum;
                let support = fs.supports.get(f as usize).and_then(Option::as_ref);
                if support.is_some_and(|s| s.holds(*point, c.normal * sum)) {
                    side.1 = 0.0; // it does not move (see `supports`)
                    continue;
                }
                let w = fs.frames[f as usize].inverse_mass_at(*point, c.normal);
                inverse_mass += sum * sum * w;
            }
        }
        if inverse_mass <= 0.0 {
            return;
        }
        let gap = c.normal.dot(&d);
        // Opened by `opening` at most beyond where the substep started (module docs).
        let start = c.normal.dot(&d_prev);
        if let Some(done) = done.as_deref_mut().filter(|_| !gap.is_nan()) {
            *done = Done::new(d_prev, inverse_mass, (gap, self.target(start)));
        }
        if gap >= self.gap || gap.is_nan() {
            return;
        }
        let mut push = self.gap - gap;
        let allowed = (start + self.opening - gap).clamp(0.0, push);
        let separating = self
            .separating
            .is_some_and(|overlapping| stencil.iter().any(|&(k, _)| overlapping[k as usize]));
        if separating {
            let left = c.normal * ((push - allowed) / inverse_mass);
            for &(node, s) in stencil {
                let k = node as usize;
                if fs.frame(k) == NO_FRAME {
                    // SAFETY: the caller's.
                    unsafe { nodes.leave_to_rest(k, left * (s * self.inv_mass[k])) };
                }
            }
            for (side, point) in sides.iter().zip(&points) {
                let (f, sum, _) = *side;
                if f != NO_FRAME && sum != 0.0 {
                    let w = fs.frames[f as usize].inverse_mass_at(*point, c.normal);
                    keep_apart(&mut fs.frame_rest[f as usize], left * (sum * w));
                }
            }
            out.rested |= allowed < push;
            push = allowed;
        } else if start < self.gap {
            push = allowed;
        }
        out.touched = true;
        out.depth = out.depth.max(-gap);
        if push <= 0.0 {
            return;
        }
        let slip = tangential(d + c.normal * push - d_prev, &c.normal);
        let removed = friction(slip, self.friction * push);
        let correction = c.normal * push - removed;
        if let Some(done) = done {
            done.normal = push;
            done.friction = -removed;
        }
        // SAFETY: the caller's.
        unsafe { self.apply((stencil, fs.frame_of), correction, inverse_mass, nodes) };
        for (side, point) in sides.iter().zip(&points) {
            if side.0 != NO_FRAME && side.1 != 0.0 {
                fs.frames[side.0 as usize].push(*point, correction * (side.1 / inverse_mass));
            }
        }
    }

    /// One more pass at constraint `c`, where the first pass (`done`) pushed it or found it
    /// within `reach` beyond its gap: brought to its target gap again, taking back what it
    /// was pushed too far, never more than it pushed in all, its friction kept within μ times
    /// its push in all (module docs).
    ///
    /// # Safety
    /// No other task of the pass touches the nodes of `c`'s stencil.
    #[allow(unsafe_code)]
    unsafe fn settle(
        &self,
        c: &BodyConstraint,
        done: &mut Done,
        reach: f64,
        nodes: &Nodes,
        out: &mut Touch,
    ) {
        if done.inverse_mass <= 0.0 || !(done.normal > 0.0 || done.gap < self.gap + reach) {
            return;
        }
        let stencil = &self.stencil[c.stencil.start as usize..c.stencil.end as usize];
        // SAFETY: the caller's.
        let d = unsafe { nodes.separation(stencil) };
        let gap = c.normal.dot(&d);
        let push = (done.target - gap).max(-done.normal);
        if push == 0.0 && done.normal == 0.0 {
            return;
        }
        if gap < self.gap {
            out.touched = true;
            out.depth = out.depth.max(-gap);
        }
        let normal = done.normal + push;
        let slip = tangential(d + c.normal * push - done.previous, &c.normal);
        let friction = clamp_length(done.friction - slip, self.friction * normal);
        let correction = c.normal * push + friction - done.friction;
        (done.normal, done.friction) = (normal, friction);
        // SAFETY: the caller's.
        unsafe { self.apply((stencil, &[]), correction, done.inverse_mass, nodes) };
    }

    /// The separation a contact whose features were `start` apart along its normal at the
    /// substep's start is brought to: the gap, or `opening` beyond `start` where that is
    /// nearer (module docs).
    fn target(&self, start: f64) -> f64 {
        self.gap.min(start + self.opening)
    }

    /// Move the elastic nodes of a constraint's `stencil` (those no frame moves, by
    /// `frame_of`) by `correction` of its separation, each by its weight over the
    /// constraint's `inverse_mass`, and mark them.
    ///
    /// # Safety
    /// No other task of the pass touches the stencil's nodes.
    #[allow(unsafe_code)]
    unsafe fn apply(
        &self,
        (stencil, frame_of): (&[(u32, f64)], &[u32]),
        correction: V3,
        inverse_mass: f64,
        nodes: &Nodes,
    ) {
        for &(node, s) in stencil {
            let k = node as usize;
            if frame_of.get(k).is_some_and(|&f| f != NO_FRAME) {
                continue;
            }
            // SAFETY: the caller's.
            unsafe { nodes.shift_node(k, correction * (s * self.inv_mass[k] / inverse_mass)) };
        }
    }
}

impl BodyContacts<'_> {
    /// The static contacts (floor, walls, colliders, within the gap: [`StaticContacts`]) of
    /// the frames in `pairs` and of those in contact with an elastic body (`mixed`), found in
    /// one scan of the surface points. The first join `pairs`; the second make, per frame
    /// (empty when none is mixed), what such a body rests on: a contact that presses it into
    /// that support moves only the elastic side ([`Support::holds`]).
    fn add_statics(
        &self,
        x: &[V3],
        frame_of: &[u32],
        mixed: &[bool],
        pairs: &mut Vec<FramePairContact>,
    ) -> Vec<Option<Support>> {
        let Some(statics) = self.statics else {
            return Vec::new();
        };
        let mut in_pairs = vec![false; mixed.len()];
        for s in pairs.iter().flat_map(|c| &c.sides) {
            if let Some(t) = in_pairs.get_mut(s.frame as usize) {
                *t = true;
            }
        }
        let any_mixed = mixed.contains(&true);
        if !any_mixed && !in_pairs.contains(&true) {
            return Vec::new();
        }
        let touching: Vec<bool> = (in_pairs.iter().zip(mixed))
            .map(|(p, m)| *p || *m)
            .collect();
        let contacts = StaticContacts {
            surface: statics.surface,
            x,
            previous: self.previous,
            frame_of,
            touching: &touching,
            margin: self.gap,
        };
        let mut found = Vec::new();
        contacts.planes(statics.planes, self.friction, &mut found);
        let colliders = statics.colliders;
        let friction = |c: u32| colliders.get(c as usize).map_or(0.0, |c| c.friction);
        contacts.faces(statics.resting, friction, &mut found);
        let mut supported = vec![Vec::new(); mixed.len()];
        for c in found {
            let f = c.sides[0].frame as usize;
            if mixed.get(f) == Some(&true) {
                supported[f].push((c.sides[0].point, c.normal));
            }
            if in_pairs.get(f) == Some(&true) {
                pairs.push(c);
            }
        }
        if !any_mixed {
            return Vec::new();
        }
        supported.iter().map(|c| Support::new(c)).collect()
    }

    /// The constraints between two frames, every node of theirs moved by one
    /// ([`frame_pairs`]), at `x` before any frame has moved, with the gaps they keep. Marks
    /// `out` touched by those closer than the gap, and leaves what separating ones cannot
    /// open this substep in `frame_rest`; marks `mixed` the frames in a constraint with an
    /// elastic body.
    fn frame_pairs(
        &self,
        x: &[V3],
        (frames, frame_of): (&[RigidFrame], &[u32]),
        (out, frame_rest, mixed): (&mut Touch, &mut [V3], &mut [bool]),
    ) -> Vec<FramePairContact> {
        let frame = |k: usize| frame_of.get(k).copied().unwrap_or(NO_FRAME);
        let mut pairs = Vec::new();
        if frames.is_empty() {
            return pairs;
        }
        for c in self.constraints {
            let stencil = &self.stencil[c.stencil.start as usize..c.stencil.end as usize];
            if !between_frames(stencil, &frame) {
                // With an elastic body: its frames are `mixed`.
                if stencil.iter().any(|&(k, _)| frame(k as usize) == NO_FRAME) {
                    for &(k, _) in stencil {
                        if let Some(m) = mixed.get_mut(frame(k as usize) as usize) {
                            *m = true;
                        }
                    }
                }
                continue;
            }
            let mut sides = [Side {
                frame: NO_FRAME,
                weight: 0.0,
                point: V3::zeros(),
            }; 2];
            let (mut d, mut d_prev) = (V3::zeros(), V3::zeros());
            for &(node, s) in stencil {
                let k = node as usize;
                let f = frame(k);
                let slot = usize::from(sides[0].frame != NO_FRAME && sides[0].frame != f);
                sides[slot].frame = f;
                sides[slot].weight += s;
                sides[slot].point += x[k] * s;
                d += x[k] * s;
                d_prev += self.previous[k] * s;
            }
            if sides[1].frame == NO_FRAME || sides.iter().any(|s| s.weight == 0.0) {
                continue;
            }
            for side in &mut sides {
                side.point /= side.weight;
            }
            let gap = c.normal.dot(&d);
            if gap.is_nan() {
                continue;
            }
            let target = self.target(c.normal.dot(&d_prev));
            let contact = FramePairContact::new(sides, (c.normal, d_prev), target, self.friction);
            if gap < self.gap {
                out.touched = true;
                out.depth = out.depth.max(-gap);
                let separating = self.separating.is_some_and(|overlapping| {
                    stencil.iter().any(|&(k, _)| overlapping[k as usize])
                });
                if separating {
                    self.leave_to_rest(&contact, gap, frames, (out, frame_rest));
                }
            }
            pairs.push(contact);
        }
        pairs
    }

    /// What separating frame-pair `contact`, at separation `gap` along its normal, cannot
    /// open this substep, left to each side's frame in `frame_rest` ([`keep_apart`]).
    fn leave_to_rest(
        &self,
        contact: &FramePairContact,
        gap: f64,
        frames: &[RigidFrame],
        (out, frame_rest): (&mut Touch, &mut [V3]),
    ) {
        let n = contact.normal;
        let inverse_mass: f64 = (contact.sides.iter())
            .map(|s| s.weight * s.weight * frames[s.frame as usize].inverse_mass_at(s.point, n))
            .sum();
        // Where this substep leaves it: its target, or where it is if that is farther.
        let opened = contact.target.max(gap);
        if inverse_mass <= 0.0 || opened >= self.gap {
            return;
        }
        out.rested = true;
        let apart = n * ((self.gap - opened) / inverse_mass);
        for s in &contact.sides {
            let w = frames[s.frame as usize].inverse_mass_at(s.point, n);
            keep_apart(&mut frame_rest[s.frame as usize], apart * (s.weight * w));
        }
    }
}

/// Whether every node of `stencil` moves with a frame, and its nodes are two frames'.
fn between_frames(stencil: &[(u32, f64)], frame: &impl Fn(usize) -> u32) -> bool {
    let Some(&(first, _)) = stencil.first() else {
        return false;
    };
    let first = frame(first as usize);
    let mut two = false;
    for &(k, _) in stencil {
        let f = frame(k as usize);
        if f == NO_FRAME {
            return false;
        }
        two |= f != first;
    }
    first != NO_FRAME && two
}

/// Grow a held or rigid body's move `by` (what its separating contacts leave to `rest`) so
/// that it moves at least `apart` along `apart`: the contacts are met one after the other
/// without the body moving in between, and each asks the whole body to move, so their moves
/// are not summed. Added up, a wooden box set 1 mm above a wooden slab (both held) was moved
/// 19 cm up at the first substep by its few hundred points on the slab, and fell back.
fn keep_apart(by: &mut V3, apart: V3) {
    let length = apart.norm();
    if length > 0.0 {
        let along = apart / length;
        *by += along * (length - by.dot(&along)).max(0.0);
    }
}
