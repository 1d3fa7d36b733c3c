//! Contacts of pairs at rest, kept from one pass to the next: a pair of held or rigid bodies
//! (each moved as one frame by the XPBD step) whose contacts are constraints
//! (`BodyContact::constrains`), searched or kept in the pass before, whose nodes have
//! together moved less than [`STILL_LAYERS`] of a layer since its last search, takes that
//! search's contacts and stencils again instead of searching.
//!
//! Elastic pairs are always searched: a resting rubber stack's nodes rarely stay within the
//! limit for long, and a tower of four rubber cubes, which never quite stops rocking, ended
//! in another phase of its rocking (cubes 2 mm deeper into each other at the last frame).
//!
//! A stack of six steel boxes spent about two thirds of its time finding the same contacts
//! every substep ([`super::detect`]'s search of each sample's nearest face). The constraints
//! read the nodes where they are when they act, so a kept contact differs from a fresh one
//! only in where on its face its stencil sits (by at most that motion) and in the depth and
//! speed the contact log records for it. Once the motion adds up past the limit the pair is
//! searched again; its lists, not looked at in the passes between, forget which samples they
//! had found far away ([`super::neighbours::take`]), so none is missed.

use super::constraint::Stencils;
use super::prepare::PairInReach;
use super::{BodyContact, Contact, PairSearches, CONSTRAINT_REACH};

/// How far, in contact layer thicknesses, the nodes of a pair may move in all (both bodies'
/// farthest node, added over the passes) before its kept contacts are searched again. Well
/// inside what the search's front leaves beyond the gap (`CONSTRAINT_FRONT` less
/// `REST_GAP_LAYERS`, 0.15 of a layer): no sample can reach the gap unseen. Resting steel
/// boxes' farthest nodes move about a micrometre a substep: at 1e-4 of a layer (1.5 µm for
/// 3 cm cells) few pairs were kept and the stack took as long as before, at 1e-3 10 % less
/// time, at 0.01 40 % less, at 0.05 no less than at 0.01.
pub(super) const STILL_LAYERS: f64 = 0.01;

/// The pairs of `pairs` (in reach in this pass, layer thickness `h`) that keep their
/// contacts, taken out of `pairs`: pairs of rigid frames ([`BodyContact::frame_bodies`])
/// whose contacts are constraints, from the third pass on (the first two decide which pairs
/// are constrained and make their stencils).
pub(super) fn take_kept(
    bc: &mut BodyContact,
    pairs: &mut Vec<PairInReach>,
    h: f64,
) -> Vec<PairSearches> {
    let mut out = Vec::with_capacity(pairs.len());
    pairs.retain(|&(a, b, lo, hi)| {
        let frames = |b: usize| bc.frame_bodies.get(b) == Some(&true);
        if bc.step <= 2 || bc.still_off || !bc.constrains(a, b) || !frames(a) || !frames(b) {
            return true;
        }
        let moved = bc.step_motion[a] + bc.step_motion[b];
        let Some((found, stencils)) = bc.still.take((a, b), bc.step, moved, STILL_LAYERS * h)
        else {
            return true;
        };
        out.push(PairSearches {
            a,
            b,
            lo,
            hi,
            h: h * CONSTRAINT_REACH,
            front: None,
            searches: [None, None],
            kept: true,
            found,
            stencils,
        });
        false
    });
    out
}

/// The contacts of one pair's last search, and how far its bodies have moved since.
#[derive(Debug, Clone, Default, PartialEq)]
struct Kept {
    pair: (usize, usize),
    /// The pass that last searched or reused it.
    step: u64,
    /// Both bodies' farthest node moves added up since the search, m.
    moved: f64,
    found: Vec<Contact>,
    stencils: Option<Stencils>,
}

/// The kept contacts of the constrained pairs, by pair.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct StillPairs {
    kept: Vec<Kept>,
}

impl StillPairs {
    /// The contacts pair `pair` keeps in pass `step`, whose bodies moved `moved` m (their
    /// farthest nodes added) since the pass before, if it was searched or kept in that pass
    /// and has moved at most `limit` since its search; `None`: search it.
    pub(super) fn take(
        &mut self,
        pair: (usize, usize),
        step: u64,
        moved: f64,
        limit: f64,
    ) -> Option<(Vec<Contact>, Option<Stencils>)> {
        let at = self.kept.binary_search_by_key(&pair, |k| k.pair).ok()?;
        let kept = &mut self.kept[at];
        let total = kept.moved + moved;
        if kept.step + 1 != step || total.is_nan() || total > limit {
            return None;
        }
        kept.moved = total;
        kept.step = step;
        Some((std::mem::take(&mut kept.found), kept.stencils.take()))
    }

    /// Keep the contacts of `pair` in pass `step`: those its search `found` (from then on,
    /// its motion counts from 0), or those [`Self::take`] gave it back (`searched` false).
    /// Gives back the ones it kept before (their buffers, for the next searches to reuse).
    pub(super) fn keep(
        &mut self,
        pair: (usize, usize),
        step: u64,
        (found, stencils): (Vec<Contact>, Option<Stencils>),
        searched: bool,
    ) -> (Vec<Contact>, Option<Stencils>) {
        let at = match self.kept.binary_search_by_key(&pair, |k| k.pair) {
            Ok(at) => at,
            Err(at) => {
                let new = Kept {
                    pair,
                    ..Kept::default()
                };
                self.kept.insert(at, new);
                at
            }
        };
        let kept = &mut self.kept[at];
        kept.step = step;
        if searched {
            kept.moved = 0.0;
        }
        let before = (std::mem::take(&mut kept.found), kept.stencils.take());
        (kept.found, kept.stencils) = (found, stencils);
        before
    }

    /// Forget the pairs that pass `step` neither searched nor reused.
    pub(super) fn forget_older(&mut self, step: u64) {
        self.kept.retain(|k| k.step == step);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pair_keeps_its_contacts_while_it_stays_within_the_limit() {
        let mut still = StillPairs::default();
        let stencils = Some(Stencils::default());
        assert!(
            still.take((0, 1), 1, 0.0, 1.0).is_none(),
            "nothing kept yet"
        );
        still.keep((0, 1), 1, (Vec::new(), stencils.clone()), true);
        still.keep((2, 3), 1, (Vec::new(), None), true);
        let back = still.take((0, 1), 2, 0.4, 1.0).expect("kept");
        still.keep((0, 1), 2, back, false);
        let back = still.take((0, 1), 3, 0.4, 1.0).expect("kept");
        assert_eq!(back.1, stencils, "given back as it was kept");
        still.keep((0, 1), 3, back, false);
        // 1.2 in all since the search: searched again.
        assert!(still.take((0, 1), 4, 0.4, 1.0).is_none());
        // (2, 3) was neither searched nor kept in pass 2: not kept in pass 3.
        assert!(still.take((2, 3), 3, 0.0, 1.0).is_none());
        // A pass that neither searched nor kept a pair forgets it.
        still.keep((0, 1), 4, (Vec::new(), stencils), true);
        still.forget_older(4);
        assert!(still.take((2, 3), 5, 0.0, 1.0).is_none());
        assert!(still.take((0, 1), 5, 0.0, 1.0).is_some());
        // A body whose motion is not known (its first pass) is searched.
        assert!(still.take((0, 1), 6, f64::INFINITY, 1.0).is_none());
    }
}
