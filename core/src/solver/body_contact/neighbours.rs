//! Neighbour lists for the vertex–face search (Verlet lists with a skin, as molecular
//! dynamics keeps them): for an ordered pair of bodies near each other, each contact sample
//! of the first keeps the triangles of the second that lay within the search's reach plus a
//! skin when the list was built. Until the bodies have moved farther than the skin allows, a
//! sample looks only at its list instead of querying the other body's grid: in a resting pile
//! a sample's list holds a handful of faces where a grid query returned some fifty.
//!
//! **Exactness.** A face the search can pick in a step lies within `max(reach, sweep)` of the
//! sample (the nearest face within the layer, or one the sample crossed in the step, with the
//! pair's relative motion at most `sweep`). Every embedded point moves no farther than its
//! body's farthest node, so a face within that distance now lay within
//! `max(reach, sweep) + drift` when the list was built, `drift` both bodies' largest node
//! displacement since. A list is used while `drift + sweep ≤ skin`; it holds every face whose
//! distance bound was within `reach + skin`. The search then sees every face it could pick.
//!
//! **Ranked.** Each sample's faces are kept nearest first by their distance bound when the
//! list was built, with that bound: the search stops at the first face that was farther than
//! the contact it has found plus both bodies' drift since (or than the step's travel, for a
//! crossing), so a resting sample looks at the faces under it only.
//!
//! **Drift.** Each body keeps an anchor (its node positions at some step) and measures its
//! largest node displacement from it once a step; once that passes a quarter of the skin the
//! body re-anchors, which invalidates its lists. A list remembers both bodies' drift when it
//! was built (the displacement since is at most that plus the drift now).

use super::*;
use std::collections::HashMap;

/// The skin, in search reaches (a layer thickness): a longer list against fewer rebuilds.
const SKIN_REACHES: f64 = 0.25;

/// A body re-anchors once a node has moved this fraction of the skin from its anchor.
const ANCHOR_DRIFT: f64 = 0.25;

/// How many steps a list must be expected to live (at the bodies' speeds) to be built with a
/// skin.
const LIST_STEPS: f64 = 4.0;

/// How many steps a list not looked at is kept.
const STALE_STEPS: u64 = 64;

/// The lists of all pairs, and each body's drift.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Neighbours {
    drift: Vec<Drift>,
    lists: HashMap<(u32, u32), FaceList>,
}

/// A body's anchor: node positions, a count of re-anchorings, and the largest displacement
/// from the anchor in step `stamp`.
#[derive(Debug, Clone, Default, PartialEq)]
struct Drift {
    anchor: Vec<Vector3<f64>>,
    epoch: u64,
    now: f64,
    stamp: u64,
}

/// One ordered pair's lists: per sample, its faces of the other body.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct FaceList {
    /// Both bodies' anchors when built, and their drift then (summed).
    epochs: (u64, u64),
    drift_at_build: f64,
    /// The skin it was built with, m (none while the bodies move fast).
    skin: f64,
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
}

impl Neighbours {
    /// Body `b`'s (epoch, drift) in step `step`, re-anchoring it when it has drifted past
    /// its share of `skin` (its nodes: `positions`).
    fn drift(&mut self, b: usize, positions: &[Vector3<f64>], step: u64, skin: f64) -> (u64, f64) {
        if self.drift.len() <= b {
            self.drift.resize_with(b + 1, Drift::default);
        }
        let d = &mut self.drift[b];
        if d.stamp != step {
            d.stamp = step;
            d.now = if d.anchor.len() == positions.len() {
                let far = positions
                    .iter()
                    .zip(&d.anchor)
                    .map(|(x, a)| (x - a).norm_squared())
                    .fold(0.0, f64::max);
                far.sqrt()
            } else {
                f64::INFINITY
            };
            if d.now.is_nan() || d.now > ANCHOR_DRIFT * skin {
                d.anchor.clear();
                d.anchor.extend_from_slice(positions);
                d.epoch += 1;
                d.now = 0.0;
            }
        }
        (d.epoch, d.now)
    }

    /// Forget the lists not looked at for a while (pairs that moved apart).
    pub fn forget_stale(&mut self, step: u64) {
        if step.is_multiple_of(STALE_STEPS) {
            self.lists.retain(|_, l| l.used + STALE_STEPS > step);
        }
    }
}

/// Body `a`'s samples against body `b`'s mesh `mb` in this step: the pair's list, taken out
/// of the table (give it back with [`put_back`]) and rebuilt when the bodies have moved too
/// far for it (module docs). Samples must be up to date (`update_samples`), the mesh too
/// (`BodyMesh::update`). `[lo, hi]` is the pair's region.
pub(super) fn take(
    bc: &mut BodyContact,
    input: &PassInput,
    (a, b, mb): (usize, usize, usize),
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) -> FaceList {
    let (h, dt) = (input.layer.thickness_m, input.dt);
    let reach = h.max(BEHIND_LAYERS * h);
    let skin = if bc.lists_off {
        0.0
    } else {
        SKIN_REACHES * reach
    };
    let step = bc.step;
    let nodes = |body: usize| &input.nodes.position[input.bodies[body].nodes.clone()];
    let (epoch_a, drift_a) = bc.neighbours.drift(a, nodes(a), step, skin);
    let (epoch_b, drift_b) = bc.neighbours.drift(b, nodes(b), step, skin);
    let sweep = (bc.max_speed[a] + bc.max_speed[b]) * dt;
    let mut list = bc
        .neighbours
        .lists
        .remove(&(a as u32, b as u32))
        .unwrap_or_default();
    let fresh = list.epochs == (epoch_a, epoch_b)
        && list.used > 0
        && !bc.lists_off
        && list.drift_at_build + drift_a + drift_b + sweep <= list.skin;
    list.used = step;
    if fresh {
        list.slack = list.drift_at_build + drift_a + drift_b;
        return list;
    }
    list.slack = 0.0;
    list.built = step;
    // A list pays only if it outlives a few steps: while the bodies move fast enough to
    // re-anchor sooner, it is built without a skin (the plain search, for this step only).
    let calm = sweep * LIST_STEPS <= ANCHOR_DRIFT * skin;
    let skin = if calm { skin } else { 0.0 };
    list.epochs = (epoch_a, epoch_b);
    list.drift_at_build = drift_a + drift_b;
    list.skin = skin;
    list.samples.clear();
    list.faces.clear();
    list.lower.clear();
    let mut ranked: Vec<(f64, u32)> = Vec::new();
    let (wide_lo, wide_hi) = (lo.add_scalar(-skin), hi.add_scalar(skin));
    let mesh = &mut bc.meshes[mb];
    let range = reach + skin;
    for i in bc.points[a].clone() {
        let x = bc.sample_x[i];
        if (0..3).any(|k| x[k] < wide_lo[k] || x[k] > wide_hi[k]) {
            continue;
        }
        let (qlo, qhi) = (x.add_scalar(-range), x.add_scalar(range));
        mesh.grid.query(&qlo, &qhi, &mut bc.candidates);
        mesh.refresh(&bc.candidates);
        let faces = MeshFaces(mesh);
        ranked.clear();
        ranked.extend(bc.candidates.iter().filter_map(|&t| {
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
    list
}

/// Return the list of `a`'s samples against `b` to the table.
pub(super) fn put_back(bc: &mut BodyContact, (a, b): (usize, usize), list: FaceList) {
    bc.neighbours.lists.insert((a as u32, b as u32), list);
}
