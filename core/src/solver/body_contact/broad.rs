//! The broad phase of body–body contact: which pairs of bodies may touch in the step, by sort
//! and sweep over their node boxes, so the work grows with the pairs that come near each
//! other, not with all pairs of a scene of many parts.
//!
//! A pair may touch when its boxes lie within the search's reach plus the pair's relative
//! travel in the step on every axis ([`pairs_in_reach`] applies the exact test). Each body's
//! box, grown by half the reach and its fastest node's travel, is a superset of that test
//! (the pair's travel is at most both fastest nodes'): the sweep along x over the grown boxes
//! sorted by their lower x finds every candidate, and the exact test keeps the same pairs as
//! testing every pair, in the same `(a, b)` order (the pairs are sorted). A body whose box or
//! speed is not finite is tested against every other.

use super::{prepare::PairInReach, BodyContact, BEHIND_LAYERS};
use nalgebra::Vector3;

/// The pairs of bodies `a < b`, one of them with faces, whose boxes come within reach, in
/// `(a, b)` order, with the region `[lo, hi]` their searches look in (both boxes grown by
/// the layer `h`: it admits gaps up to `2h`), in a step of `dt` seconds.
pub(super) fn pairs_in_reach(bc: &BodyContact, h: f64, dt: f64) -> Vec<PairInReach> {
    let reach = h.max(BEHIND_LAYERS * h);
    let n_bodies = bc.boxes.len();
    let may_touch = |a: usize, b: usize| -> Option<PairInReach> {
        let (alo, ahi) = bc.boxes[a];
        let (blo, bhi) = bc.boxes[b];
        let lo = alo.sup(&blo).add_scalar(-h);
        let hi = ahi.inf(&bhi).add_scalar(h);
        let gap = (alo.sup(&blo) - ahi.inf(&bhi)).max();
        let sweep = bc.sweep(a, b, dt);
        let apart = gap.is_nan()
            || gap > reach + sweep
            || (0..3).any(|k| lo[k] > hi[k])
            || bc.ignored_pairs.contains(&(a, b));
        let has_faces = bc.mesh_of[a].is_some() || bc.mesh_of[b].is_some();
        (!apart && has_faces).then_some((a, b, lo, hi))
    };
    // Grown boxes of the bodies that can touch anything; the others (a box or speed that
    // is not finite) are tested against every body.
    let mut swept: Vec<(f64, f64, usize)> = Vec::new();
    let mut wild = Vec::new();
    let mut grown = vec![None; n_bodies];
    for (b, slot) in grown.iter_mut().enumerate() {
        let (lo, hi) = bc.boxes[b];
        if (0..3).any(|k| lo[k] > hi[k]) {
            continue; // no nodes: an empty box touches nothing
        }
        let e = 0.5 * reach + bc.max_speed[b] * dt;
        let finite = e.is_finite() && (0..3).all(|k| lo[k].is_finite() && hi[k].is_finite());
        if finite {
            let (lo, hi) = (lo.add_scalar(-e), hi.add_scalar(e));
            *slot = Some((lo, hi));
            swept.push((lo.x, hi.x, b));
        } else {
            wild.push(b);
        }
    }
    swept.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.2.cmp(&q.2)));
    let overlap = |a: &(Vector3<f64>, Vector3<f64>), b: &(Vector3<f64>, Vector3<f64>)| {
        (1..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
    };
    let mut out = Vec::new();
    for (i, &(_, hi_x, a)) in swept.iter().enumerate() {
        for &(lo_x, _, b) in &swept[i + 1..] {
            if lo_x > hi_x {
                break;
            }
            let (Some(ga), Some(gb)) = (&grown[a], &grown[b]) else {
                continue;
            };
            if overlap(ga, gb) {
                out.extend(may_touch(a.min(b), a.max(b)));
            }
        }
    }
    for &w in &wild {
        for b in 0..n_bodies {
            // A pair of two wild bodies is tested once, from its lower one.
            if b != w && !(wild.contains(&b) && b < w) {
                out.extend(may_touch(w.min(b), w.max(b)));
            }
        }
    }
    out.sort_by_key(|&(a, b, _, _)| (a, b));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair tested, as the contact pass did before the sweep.
    fn every_pair(bc: &BodyContact, h: f64, dt: f64) -> Vec<PairInReach> {
        let reach = h.max(BEHIND_LAYERS * h);
        let mut out = Vec::new();
        for a in 0..bc.boxes.len() {
            for b in a + 1..bc.boxes.len() {
                let ((alo, ahi), (blo, bhi)) = (bc.boxes[a], bc.boxes[b]);
                let lo = alo.sup(&blo).add_scalar(-h);
                let hi = ahi.inf(&bhi).add_scalar(h);
                let gap = (alo.sup(&blo) - ahi.inf(&bhi)).max();
                let apart = gap.is_nan()
                    || gap > reach + bc.sweep(a, b, dt)
                    || (0..3).any(|k| lo[k] > hi[k])
                    || bc.ignored_pairs.contains(&(a, b));
                let has_faces = bc.mesh_of[a].is_some() || bc.mesh_of[b].is_some();
                if !apart && has_faces {
                    out.push((a, b, lo, hi));
                }
            }
        }
        out
    }

    #[test]
    fn the_sweep_finds_the_pairs_testing_every_pair_finds() {
        // 300 boxes of 1–20 cm in a 1 m cube, some fast, some without faces, one ignored
        // pair, one box with a NaN corner, one infinitely fast, one empty.
        let mut seed = 11u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
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
