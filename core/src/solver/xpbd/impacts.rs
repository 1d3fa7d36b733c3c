//! The substeps an impact asks for: a body about to hit a floor, a wall or a static collider
//! gets enough substeps that its cells stop it within a tenth of a cell a substep, and keeps
//! them until the impact is over, through the release as well as the approach.
//!
//! Why the release: the cells store an impact's energy as they are squashed and give it
//! back as they spring open, and one sweep a substep gives it back only as far as the
//! substep resolves the cells' elastic wave. A 10 cm rubber cube (10 cells) dropped 1 m,
//! sampled at 240 frames a second, was stopped at 10 substeps a 1/240 s frame and sprang
//! open in the next frames at the 6 and 4 the speed bound gave its slower centre: it
//! rebounded 9.6 % of the drop, against 36 % with the impact frame's count kept for the two
//! frames after it and 26–36 % at any fixed count of 50–300 substeps a 1/24 s frame. How
//! high a body bounced depended on the output frame rate (30 % at 24 frames a second).
//!
//! So each body's impact is an episode ([`ImpactHold`]): from the frame it closes on a
//! surface it may reach, for as long as it touches one (a node within a cell of it) and its
//! centre still moves along the normal at [`RELEASE_SHARE`] of the approach speed or more,
//! it keeps the most substeps any frame of the episode asked for. It ends when the body
//! leaves the surface or comes to rest on it.

use super::super::World;
use super::{BODY_TRAVEL_PER_SUBSTEP, TRAVEL_PER_SUBSTEP};
use nalgebra::Vector3;
use std::ops::Range;

type V3 = Vector3<f64>;

/// Share of an impact's approach speed below which a body touching the surface counts as
/// come to rest on it (the impact is over).
const RELEASE_SHARE: f64 = 0.1;

/// Per body, the impact episode it is in: the substep rate kept (per second) and the
/// approach speed (m/s); zeros outside one.
#[derive(Debug, Clone, Default)]
pub(crate) struct ImpactHold {
    episodes: Vec<(f64, f64)>,
    /// The frame start (time bits) of the last decision and the episodes before it: asked
    /// again for the same frame start (the pipeline's budget check, then the frame, or a
    /// frame taken again), the answer is the same.
    last: Option<(u64, Vec<(f64, f64)>)>,
}

/// How one body meets the surfaces at a frame's start.
struct Approach {
    /// Its centre's speed towards a surface it can reach within the frame, m/s (0: none).
    closing: f64,
    /// Whether a node is within a cell of a plane or a static collider.
    touching: bool,
    /// Its centre's speed along the normal of a surface it touches, either way, m/s.
    normal_speed: f64,
}

impl ImpactHold {
    /// Substeps per second the impacts ask for in the frame of `frame_dt` seconds starting
    /// at the world's time: the most of any body's ([`speed_rate`] of its approach speed,
    /// kept through its episode; module docs).
    pub(crate) fn rate(
        &mut self,
        world: &World,
        frame_dt: f64,
        h: f64,
        shares: &[ImpactShare],
    ) -> f64 {
        let time = world.time.to_bits();
        match &self.last {
            Some((t, before)) if *t == time => self.episodes.clone_from(before),
            _ => self.last = Some((time, self.episodes.clone())),
        }
        self.episodes.resize(world.bodies.len(), (0.0, 0.0));
        let mut rate = 0.0f64;
        for (b, body) in world.bodies.iter().enumerate() {
            let Some(a) = approach(world, body.nodes.clone(), frame_dt, h) else {
                self.episodes[b] = (0.0, 0.0);
                continue;
            };
            let asked = if a.closing > 0.0 {
                speed_rate(body.nodes.start, a.closing, h, shares)
            } else {
                0.0
            };
            let (kept, speed) = self.episodes[b];
            let going_on = kept > 0.0 && a.touching && a.normal_speed >= RELEASE_SHARE * speed;
            self.episodes[b] = if going_on {
                (kept.max(asked), speed.max(a.closing))
            } else if a.closing > 0.0 {
                (asked, a.closing)
            } else {
                (0.0, 0.0)
            };
            rate = rate.max(self.episodes[b].0);
        }
        rate
    }
}

/// How the body of nodes `nodes` meets the planes and static colliders (`None`: massless).
fn approach(world: &World, nodes: Range<usize>, frame_dt: f64, h: f64) -> Option<Approach> {
    let (x, v, mass) = (
        &world.nodes.position,
        &world.nodes.velocity,
        &world.nodes.mass,
    );
    let (m, momentum) = nodes.clone().fold((0.0, V3::zeros()), |(m, p), i| {
        (m + mass[i], p + v[i] * mass[i])
    });
    if nodes.is_empty() || m <= 0.0 {
        return None;
    }
    let centre_v = momentum / m;
    let reaches = |towards: f64, gap: f64| towards > 0.0 && gap <= towards * frame_dt + h;
    let mut a = Approach {
        closing: 0.0,
        touching: false,
        normal_speed: 0.0,
    };
    let mut meet = |towards: f64, gap: f64| {
        if reaches(towards, gap) {
            a.closing = a.closing.max(towards);
        }
        if gap <= h {
            a.touching = true;
            a.normal_speed = a.normal_speed.max(towards.abs());
        }
    };
    // Each plane (usually the floor).
    for p in &world.settings.planes {
        let gap = nodes
            .clone()
            .fold(f64::INFINITY, |g, i| g.min(p.normal.dot(&x[i]) - p.offset));
        meet(-p.normal.dot(&centre_v), gap);
    }
    let colliders = &world.body_contact.colliders;
    if !colliders.is_empty() {
        let (lo, hi) = nodes.fold(
            (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY)),
            |(lo, hi), i| (lo.inf(&x[i]), hi.sup(&x[i])),
        );
        for c in colliders {
            let (towards, gap) = box_approach((lo, hi), (c.lo, c.hi), centre_v);
            meet(towards, gap);
        }
    }
    Some(a)
}

/// How fast a body with bounding box `a` moving at `v` closes on the fixed box `b`, and the
/// gap between the boxes: along the axis that parts them most (of overlapping boxes, the axis
/// they overlap least along), towards `b`.
fn box_approach(a: (V3, V3), b: (V3, V3), v: V3) -> (f64, f64) {
    let mut best = (f64::NEG_INFINITY, 0.0, 0usize);
    for k in 0..3 {
        // Positive: apart by that much along k; negative: overlapping by that much.
        let (above, below) = (a.0[k] - b.1[k], b.0[k] - a.1[k]);
        let (apart, side) = if above >= below {
            (above, 1.0)
        } else {
            (below, -1.0)
        };
        if apart > best.0 {
            best = (apart, side, k);
        }
    }
    let (apart, side, k) = best;
    (-side * v[k], apart.max(0.0))
}

/// A body the restitution takes a share of the impacts of (`xpbd::restitution`): its node
/// range, that share at the substep, and its thickness, m.
pub(crate) struct ImpactShare {
    nodes: Range<usize>,
    share: f64,
    thickness: f64,
}

/// The bodies the restitution takes a share of the impacts of at substeps of `dt`, when
/// planes and static colliders are all a body can touch (no deformable partner, no capsule).
pub(crate) fn impact_shares(world: &World, dt: f64) -> Vec<ImpactShare> {
    let only_static = !world.body_contact.deformable_pairs()
        && world.manipulators.is_empty()
        && world.live_capsules.is_empty();
    match world.xpbd.as_ref() {
        Some(model) if only_static => model
            .restitution
            .shares_at(dt)
            .map(|(b, share, thickness)| ImpactShare {
                nodes: world.bodies[b].nodes.clone(),
                share,
                thickness,
            })
            .collect(),
        _ => Vec::new(),
    }
}

/// Substeps per second that node `i`'s speed `v` asks for near a surface: its cells must
/// stop `(1 − share) v` of an impact within a tenth of the shortest cell `h` a substep, and
/// the restitution moves the body as a whole by the other `share v`, within
/// [`BODY_TRAVEL_PER_SUBSTEP`] of its thickness a substep (a body the restitution moves
/// wholly, a 1 cm cube or a steel ball, needs no more substeps as it shrinks).
pub(crate) fn speed_rate(i: usize, v: f64, h: f64, shares: &[ImpactShare]) -> f64 {
    let cells = v / (TRAVEL_PER_SUBSTEP * h);
    match shares.iter().find(|s| s.nodes.contains(&i)) {
        Some(s) if s.thickness > 0.0 => {
            (1.0 - s.share) * cells + s.share * v / (BODY_TRAVEL_PER_SUBSTEP * s.thickness)
        }
        _ => cells,
    }
}
