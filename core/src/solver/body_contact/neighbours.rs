//! Neighbour lists for the vertex–face search (Verlet lists with a skin, as molecular
//! dynamics keeps them): for an ordered pair of bodies near each other, each contact sample
//! of the first keeps the triangles of the second that lay within the search's reach plus a
//! skin when the list was built. Until the bodies have moved farther than the skin allows, a
//! sample looks only at its list instead of querying the other body's grid: in a resting pile
//! a sample's list holds a handful of faces where a grid query returned some fifty.
//!
//! **Exactness.** A face the search can pick in a step lies within `max(reach, sweep)` of the
//! sample (the nearest face within the layer, or one the sample crossed in the step, with the
//! pair's relative motion at most `sweep`). Every embedded point (a convex combination of its
//! cell's nodes) moves beyond its body's shift no farther than the body's farthest node, so a
//! face within that distance now lay within `max(reach, sweep) + moved` when the list was
//! built, `moved` the bound on a sample's motion relative to a face since (see Drift). A list
//! is used while `moved + sweep ≤ skin`; it holds every face whose distance bound was within
//! `reach + skin`. The search then sees every face it could pick.
//!
//! **Ranked.** Each sample's faces are kept nearest first by their distance bound when the
//! list was built, with that bound: the search stops at the first face that was farther than
//! the contact it has found plus `moved` (or than the step's travel, for a crossing), so a
//! resting sample looks at the faces under it only.
//!
//! **Skin.** A quarter of the reach to start with; a pair whose list dies within
//! `SHORT_LIFE` steps while it is calm (resting jitter re-anchoring its bodies) builds the next
//! one with twice the skin, up to four times, and one that lives past `LONG_LIFE` steps
//! with half. A body re-anchors only past its share of the widest skin its lists took.
//!
//! **Drift.** Each body keeps an anchor (its node positions at some step) and measures, once a
//! step, how far its nodes' mean has moved from the anchor's (its shift) and its largest node
//! displacement beyond that shift (its drift); once the drift passes a quarter of the skin the
//! body re-anchors, which invalidates its lists. A list remembers both bodies' drift and the
//! difference of their shifts when it was built: a sample has moved relative to a face since
//! by at most both drifts then and now plus how far that difference has changed, so bodies
//! that fall or slide together keep their lists. The sweep is relative too (see
//! `BodyContact::sweep`).

use super::*;
use crate::collide::grid::QueryMarks;
use std::collections::HashMap;

/// The skin, in search reaches (a layer thickness): a longer list against fewer rebuilds.
const SKIN_REACHES: f64 = 0.25;

/// A body re-anchors once a node has moved this fraction of the skin from its anchor.
const ANCHOR_DRIFT: f64 = 0.25;

/// How many steps a list must be expected to live (at the bodies' speeds) to be built with a
/// skin.
const LIST_STEPS: f64 = 4.0;

/// A list that lived fewer steps than this (built with a skin) is rebuilt with twice the
/// skin, up to [`MAX_SKIN_SCALE`] times the base; one that lived more than [`LONG_LIFE`]
/// with half. Resting bodies jitter by a fraction of a millimetre whatever their cells: at 10
/// cells a body the base skin is 1.9 mm and they re-anchored every few steps, at 3 cells it
/// is 6 mm and a wider one only made longer lists.
const SHORT_LIFE: u64 = 16;
const LONG_LIFE: u64 = 64;
const MAX_SKIN_SCALE: f64 = 4.0;

/// How many steps a list not looked at is kept.
const STALE_STEPS: u64 = 64;

/// The lists of all pairs, and each body's drift.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Neighbours {
    drift: Vec<Drift>,
    /// Per body: the widest skin a list of it was built with (its anchor holds for that).
    anchor_skin: Vec<f64>,
    lists: HashMap<(u32, u32), FaceList>,
}

/// A body's anchor: node positions and their mean, a count of re-anchorings, and in step
/// `stamp` how far the nodes' mean has moved from the anchor's (`shift`) and the largest
/// displacement of a node beyond that shift (`now`).
#[derive(Debug, Clone, Default, PartialEq)]
struct Drift {
    anchor: Vec<Vector3<f64>>,
    anchor_mean: Vector3<f64>,
    epoch: u64,
    now: f64,
    shift: Vector3<f64>,
    stamp: u64,
}

/// A body's drift in a step: its anchor's epoch, the largest node displacement beyond the
/// shift, and the shift of the nodes' mean since the anchor.
type DriftNow = (u64, f64, Vector3<f64>);

/// The mean of `positions`.
fn mean(positions: &[Vector3<f64>]) -> Vector3<f64> {
    positions.iter().sum::<Vector3<f64>>() / positions.len().max(1) as f64
}

/// One ordered pair's lists: per sample, its faces of the other body.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct FaceList {
    /// Both bodies' anchors when built, their drift then (summed), and the first's shift
    /// less the second's then.
    epochs: (u64, u64),
    drift_at_build: f64,
    offset_at_build: Vector3<f64>,
    /// The skin it was built with, m (none while the bodies move fast), and the multiple of
    /// the base skin the pair's next list takes (0: not yet chosen, 1).
    skin: f64,
    scale: f64,
    /// The step it was last looked at, and the step it was built in (its faces' boxes and
    /// planes are that step's).
    used: u64,
    pub built: u64,
    /// Per sample with faces: its index and the end of its faces in `faces`.
    pub samples: Vec<(u32, u32)>,
    /// Each sample's faces, nearest first by `lower`: the face's distance bound from the
    /// sample when the list was built.
    pub faces: Vec<u32>,
    pub lower: Vec<f64>,
    /// How far the sample and the faces may have moved since the list was built, in the
    /// step it was last taken for, m (0 when built in that step).
    pub slack: f64,
    /// Per sample: how far outside the partner it is at least, m, as its last search found
    /// it less how far things moved since (see [`super::detect::pair_contacts`]); 0 when not
    /// known, cleared when the list is built or missed a step.
    pub outside_by: Vec<f64>,
    /// Set by [`take`] when the list is to be built in this step ([`build`]).
    pending: Option<Pending>,
    /// Scratch of [`build`]: the grid query's marks and candidates, the ranked faces.
    marks: QueryMarks,
    candidates: Vec<u32>,
    ranked: Vec<(f64, u32)>,
}

/// What [`build`] needs of a list [`take`] decided to rebuild: the pair's region grown by
/// the skin (samples outside it get no faces) and the range of faces kept, m.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    wide: (Vector3<f64>, Vector3<f64>),
    range: f64,
}

impl Neighbours {
    /// Body `b`'s drift in step `step`, re-anchoring it when a node has moved past its share
    /// of `skin` beyond the body's shift (its nodes: `positions`). A body that only moves as
    /// a whole (a pile falling together) keeps its anchor.
    fn drift(&mut self, b: usize, positions: &[Vector3<f64>], step: u64, skin: f64) -> DriftNow {
        if self.drift.len() <= b {
            self.drift.resize_with(b + 1, Drift::default);
        }
        let skin = skin.max(self.anchor_skin.get(b).copied().unwrap_or(0.0));
        let d = &mut self.drift[b];
        if d.stamp != step {
            d.stamp = step;
            (d.now, d.shift) = if d.anchor.len() == positions.len() {
                let shift = mean(positions) - d.anchor_mean;
                let far = positions
                    .iter()
                    .zip(&d.anchor)
                    .map(|(x, a)| (x - a - shift).norm_squared())
                    .fold(0.0, f64::max);
                (far.sqrt(), shift)
            } else {
                (f64::INFINITY, Vector3::zeros())
            };
            if d.now.is_nan() || d.now > ANCHOR_DRIFT * skin || !d.shift.norm().is_finite() {
                d.anchor.clear();
                d.anchor.extend_from_slice(positions);
                d.anchor_mean = mean(positions);
                d.epoch += 1;
                d.now = 0.0;
                d.shift = Vector3::zeros();
            }
        }
        (d.epoch, d.now, d.shift)
    }

    /// Forget the lists not looked at for a while (pairs that moved apart).
    pub fn forget_stale(&mut self, step: u64) {
        if step.is_multiple_of(STALE_STEPS) {
            self.lists.retain(|_, l| l.used + STALE_STEPS > step);
        }
    }
}

/// Body `a`'s samples against body `b`'s mesh in this step: the pair's list, taken out
/// of the table (give it back with [`put_back`]), marked to be built ([`build`]) when the
/// bodies have moved too far for it (module docs). The samples and the mesh must be fresh
/// in this step ([`super::prepare`]). `[lo, hi]` is the pair's region.
pub(super) fn take(
    bc: &mut BodyContact,
    input: &PassInput,
    (a, b): (usize, usize),
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) -> FaceList {
    let (h, dt) = (input.layer.thickness_m, input.dt);
    let reach = h.max(BEHIND_LAYERS * h);
    let scale = |list: &FaceList| if list.scale > 0.0 { list.scale } else { 1.0 };
    let base = if bc.lists_off {
        0.0
    } else {
        SKIN_REACHES * reach
    };
    let mut list = bc
        .neighbours
        .lists
        .remove(&(a as u32, b as u32))
        .unwrap_or_default();
    let skin = base * scale(&list);
    let step = bc.step;
    let nodes = |body: usize| &input.nodes.position[input.bodies[body].nodes.clone()];
    let (epoch_a, drift_a, shift_a) = bc.neighbours.drift(a, nodes(a), step, skin);
    let (epoch_b, drift_b, shift_b) = bc.neighbours.drift(b, nodes(b), step, skin);
    let sweep = bc.sweep(a, b, dt);
    // How far a sample may have moved relative to a face since the list was built.
    let moved =
        list.drift_at_build + drift_a + drift_b + (shift_a - shift_b - list.offset_at_build).norm();
    let fresh = list.epochs == (epoch_a, epoch_b)
        && list.used > 0
        && !bc.lists_off
        && moved + sweep <= list.skin;
    if list.used + 1 != step {
        // Not looked at in the last step: how far things moved since is not known.
        list.outside_by.fill(0.0);
    }
    list.used = step;
    if fresh {
        list.slack = moved;
        return list;
    }
    // A list pays only if it outlives a few steps: while the bodies move fast enough to
    // re-anchor sooner, it is built without a skin (the plain search, for this step only).
    // A list that died young while the pair was calm is rebuilt wider, one that outlived
    // many steps narrower (module docs).
    let mut scale = scale(&list);
    if list.skin > 0.0 {
        let lived = step - list.built;
        if lived < SHORT_LIFE {
            scale = (scale * 2.0).min(MAX_SKIN_SCALE);
        } else if lived > LONG_LIFE {
            scale = (scale * 0.5).max(1.0);
        }
    }
    list.scale = scale;
    list.slack = 0.0;
    list.built = step;
    let skin = base * scale;
    let calm = sweep * LIST_STEPS <= ANCHOR_DRIFT * skin;
    let skin = if calm { skin } else { 0.0 };
    for body in [a, b] {
        let widest = &mut bc.neighbours.anchor_skin;
        if widest.len() <= body {
            widest.resize(body + 1, 0.0);
        }
        widest[body] = widest[body].max(skin);
    }
    list.epochs = (epoch_a, epoch_b);
    list.drift_at_build = drift_a + drift_b;
    list.offset_at_build = shift_a - shift_b;
    list.skin = skin;
    list.pending = Some(Pending {
        wide: (lo.add_scalar(-skin), hi.add_scalar(skin)),
        range: reach + skin,
    });
    list
}

/// Build `list` if [`take`] left it to be built: body `a`'s samples (`samples` of the
/// step's `sample_x`) against `mesh`, each with the faces whose distance bound lies within
/// the list's range, nearest first. The mesh's faces must be fresh in this step
/// ([`BodyMesh::refresh_all`]); reads nothing else, so the pairs' lists build side by side.
pub(super) fn build(
    list: &mut FaceList,
    mesh: &BodyMesh,
    sample_x: &[Vector3<f64>],
    samples: Range<usize>,
) {
    let Some(Pending {
        wide: (wide_lo, wide_hi),
        range,
    }) = list.pending.take()
    else {
        return;
    };
    list.samples.clear();
    list.faces.clear();
    list.lower.clear();
    list.outside_by.clear();
    let faces = MeshFaces(mesh);
    let (mut candidates, mut ranked) = (
        std::mem::take(&mut list.candidates),
        std::mem::take(&mut list.ranked),
    );
    for i in samples {
        let x = sample_x[i];
        if (0..3).any(|k| x[k] < wide_lo[k] || x[k] > wide_hi[k]) {
            continue;
        }
        let (qlo, qhi) = (x.add_scalar(-range), x.add_scalar(range));
        mesh.query_grid((&qlo, &qhi), &mut candidates, &mut list.marks);
        ranked.clear();
        ranked.extend(candidates.iter().filter_map(|&t| {
            let bound = faces.distance_bound(t as usize, &x);
            (bound <= range).then_some((bound, t))
        }));
        if ranked.is_empty() {
            continue;
        }
        // Nearest first (a stable sort: equal bounds keep the grid's order).
        ranked.sort_by(|p, q| p.0.total_cmp(&q.0));
        list.faces.extend(ranked.iter().map(|&(_, t)| t));
        list.lower.extend(ranked.iter().map(|&(bound, _)| bound));
        list.samples.push((i as u32, list.faces.len() as u32));
    }
    (list.candidates, list.ranked) = (candidates, ranked);
}

impl FaceList {
    /// Whether [`take`] left it to be built in this step: [`build`] will query the mesh's
    /// grid ([`BodyMesh::ensure_grid`]).
    pub fn is_pending(&self) -> bool {
        self.pending.is_some()
    }
}

/// Return the list of `a`'s samples against `b` to the table.
pub(super) fn put_back(bc: &mut BodyContact, (a, b): (usize, usize), list: FaceList) {
    bc.neighbours.lists.insert((a as u32, b as u32), list);
}
