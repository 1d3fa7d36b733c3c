//! The broad phase of body–body contact: which pairs of bodies may touch in the step, by sort
//! and sweep over their node boxes, so the work grows with the pairs that come near each
//! other, not with all pairs of a scene of many parts.
//!
//! A pair may touch when its boxes lie within the search's reach plus the pair's relative
//! travel in the step on every axis ([`pair_in_reach`] is the exact test). Each body's
//! box, grown by half the reach and its fastest node's travel, is a superset of that test
//! (the pair's travel is at most both fastest nodes'): the sweep along x over the grown boxes
//! sorted by their lower x finds every candidate, and the exact test keeps the same pairs as
//! testing every pair, in the same `(a, b)` order (the pairs are sorted). A body whose box or
//! speed is not finite is tested against every other.

use super::{prepare::PairInReach, BodyContact, BEHIND_LAYERS};
use nalgebra::Vector3;

/// The pairs of bodies `a < b`, one of them with faces, whose boxes come within reach, in
/// `(a, b)` order, with the region their searches look in ([`pair_in_reach`]), in a step of
/// `dt` seconds at layer `h`.
pub(super) fn pairs_in_reach(bc: &BodyContact, h: f64, dt: f64) -> Vec<PairInReach> {
    let reach = h.max(BEHIND_LAYERS * h);
    // Grown boxes of the bodies that can touch anything, by lower x; the others (a box or
    // speed that is not finite) are tested against every body.
    let mut swept: Vec<(Vector3<f64>, Vector3<f64>, usize)> = Vec::new();
    let mut wild = Vec::new();
    for (b, &(lo, hi)) in bc.boxes.iter().enumerate() {
        if (0..3).any(|k| lo[k] > hi[k]) {
            continue; // no nodes: an empty box touches nothing
        }
        let e = 0.5 * reach + bc.max_speed[b] * dt;
        let finite = e.is_finite() && (0..3).all(|k| lo[k].is_finite() && hi[k].is_finite());
        if finite {
            swept.push((lo.add_scalar(-e), hi.add_scalar(e), b));
        } else {
            wild.push(b);
        }
    }
    swept.sort_by(|p, q| p.0.x.total_cmp(&q.0.x).then(p.2.cmp(&q.2)));
    let mut out = Vec::new();
    for (i, (alo, ahi, a)) in swept.iter().enumerate() {
        for (blo, bhi, b) in &swept[i + 1..] {
            if blo.x > ahi.x {
                break;
            }
            if (1..3).all(|k| alo[k] <= bhi[k] && blo[k] <= ahi[k]) {
                out.extend(pair_in_reach(bc, (*a.min(b), *a.max(b)), h, dt));
            }
        }
    }
    for &w in &wild {
        for b in 0..bc.boxes.len() {
            // A pair of two wild bodies is tested once, from its lower one.
            if b != w && !(wild.contains(&b) && b < w) {
                out.extend(pair_in_reach(bc, (w.min(b), w.max(b)), h, dt));
            }
        }
    }
    out.sort_by_key(|&(a, b, _, _)| (a, b));
    out
}

/// Bodies `a < b` when they may touch in the step (the exact test): their boxes lie within
/// the reach plus the pair's travel on every axis, within `2h` of each other, the pair is
/// not one that never touches (`BodyContact::never_touch`) and one of them has faces; with
/// the region `[lo, hi]` (both boxes grown by `h`) the searches look in.
fn pair_in_reach(bc: &BodyContact, (a, b): (usize, usize), h: f64, dt: f64) -> Option<PairInReach> {
    let reach = h.max(BEHIND_LAYERS * h);
    let ((alo, ahi), (blo, bhi)) = (bc.boxes[a], bc.boxes[b]);
    let lo = alo.sup(&blo).add_scalar(-h);
    let hi = ahi.inf(&bhi).add_scalar(h);
    let gap = (alo.sup(&blo) - ahi.inf(&bhi)).max();
    let apart = gap.is_nan()
        || gap > reach + bc.sweep(a, b, dt)
        || (0..3).any(|k| lo[k] > hi[k])
        || bc.never_touch(a, b);
    let has_faces = bc.mesh_of[a].is_some() || bc.mesh_of[b].is_some();
    (!apart && has_faces).then_some((a, b, lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair tested, as the contact pass did before the sweep.
    fn every_pair(bc: &BodyContact, h: f64, dt: f64) -> Vec<PairInReach> {
        let n = bc.boxes.len();
        (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
            .filter_map(|pair| pair_in_reach(bc, pair, h, dt))
            .collect()
    }

    #[test]
    fn the_sweep_finds_the_pairs_testing_every_pair_finds() {
        // 300 boxes of 1–20 cm in a 1 m cube, some fast, some without faces, one ignored
        // pair, one box with a NaN corner, one infinitely fast, one empty.
        let mut rng = fastrand::Rng::with_seed(11);
        let mut next = move || rng.f64();
        let n = 300;
        let mut bc = BodyContact::default();
        for b in 0..n {
            let lo = Vector3::new(next(), next(), next());
            let size = Vector3::new(next(), next(), next()) * 0.19 + Vector3::repeat(0.01);
            bc.boxes.push((lo, lo + size));
            let fast = next() < 0.1;
            bc.max_speed
                .push(if fast { 20.0 * next() } else { 0.5 * next() });
            bc.mean_velocity
                .push(Vector3::new(next(), next(), next()) - Vector3::repeat(0.5));
            bc.spread_speed.push(0.1 * next());
            bc.mesh_of.push((next() < 0.9).then_some(b));
        }
        bc.boxes[7].0.y = f64::NAN;
        bc.max_speed[8] = f64::INFINITY;
        bc.boxes[9] = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        );
        bc.ignored_pairs.push((3, 4));
        for (h, dt) in [(0.01, 1.0 / 720.0), (0.03, 1.0 / 240.0), (0.002, 1e-4)] {
            let swept = pairs_in_reach(&bc, h, dt);
            let every = every_pair(&bc, h, dt);
            assert_eq!(swept, every, "h {h}, dt {dt}");
            // Not a vacuous agreement: many pairs, far fewer than all.
            assert!(
                every.len() > 100 && every.len() < n * (n - 1) / 4,
                "{}",
                every.len()
            );
            assert!(
                every.iter().any(|p| p.0 == 8 || p.1 == 8),
                "the fast box meets others"
            );
        }
    }
}
