//! The order the XPBD step passes over the body–body constraints in: the pairs' groups of
//! constraints in colours, no two groups of a colour sharing a node, so a colour's groups can
//! be solved side by side (`xpbd::bodies`) with the same bits on any thread count.
//!
//! A group is one body pair's constraints, in the order its search found them; it is solved
//! serially. Groups are coloured greedily in pair order: each takes the lowest colour none of
//! its stencils' nodes has taken yet, so a pair shares its colour only with pairs it shares no
//! node with (two bodies joined at a node, or a body and its cage, are not assumed apart). A
//! world with one touching pair keeps the serial order exactly; in a pile of 60 cubes, about
//! 400 pairs in contact fell into some twenty colours.
//!
//! At most [`COLOURS`] colours: groups that find none free go to one more, last colour, which
//! is solved as one task, in pair order.

use super::constraint::BodyConstraint;
use std::ops::Range;

/// Colours a node can hold (one bit each of a `u64`).
pub(crate) const COLOURS: usize = 64;

/// The groups of constraints in colour order (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct ConstraintColours {
    /// Each group's constraints (a range of the step's constraints), colour after colour,
    /// in pair order within a colour.
    pub groups: Vec<Range<u32>>,
    /// Per colour, the end of its groups in `groups`.
    pub ends: Vec<u32>,
    /// Whether the last colour holds the groups that found no colour free (solved serially).
    pub serial_last: bool,
    /// Per node, the colours its groups took (all zero between builds).
    taken: Vec<u64>,
    /// Per group in pair order, its colour (scratch).
    colour_of: Vec<u8>,
}

impl ConstraintColours {
    /// Colour the groups ending at `pair_ends` (in pair order) of `constraints`, whose
    /// stencils' nodes are below `nodes`.
    pub(crate) fn build(
        &mut self,
        (constraints, stencil): (&[BodyConstraint], &[(u32, f64)]),
        pair_ends: &[u32],
        nodes: usize,
    ) {
        debug_assert_eq!(
            pair_ends.last().map_or(0, |&e| e as usize),
            constraints.len()
        );
        self.clear();
        self.colour_of.clear();
        if self.taken.len() < nodes {
            self.taken.resize(nodes, 0);
        }
        let group_nodes = |g: &Range<u32>| {
            let (first, last) = (
                &constraints[g.start as usize],
                &constraints[g.end as usize - 1],
            );
            stencil[first.stencil.start as usize..last.stencil.end as usize].iter()
        };
        let mut start = 0;
        let mut used = 0;
        for &end in pair_ends {
            let group = start..end;
            start = end;
            let taken = group_nodes(&group).fold(0, |t, &(k, _)| t | self.taken[k as usize]);
            let colour = (!taken).trailing_zeros() as usize;
            if colour < COLOURS {
                group_nodes(&group).for_each(|&(k, _)| self.taken[k as usize] |= 1 << colour);
            }
            used = used.max(colour + 1);
            self.colour_of.push(colour as u8);
        }
        // Every group in pair order again: clear the marks, then list them by colour.
        let mut start = 0;
        for &end in pair_ends {
            group_nodes(&(start..end)).for_each(|&(k, _)| self.taken[k as usize] = 0);
            start = end;
        }
        self.serial_last = used > COLOURS;
        for colour in 0..used.min(COLOURS + 1) {
            let mut start = 0;
            for (&end, &c) in pair_ends.iter().zip(&self.colour_of) {
                if c as usize == colour {
                    self.groups.push(start..end);
                }
                start = end;
            }
            self.ends.push(self.groups.len() as u32);
        }
    }

    /// No groups (the marks are clear already).
    pub(crate) fn clear(&mut self) {
        self.groups.clear();
        self.ends.clear();
        self.serial_last = false;
    }

    /// Each colour's groups, in order.
    pub(crate) fn colours(&self) -> impl Iterator<Item = &[Range<u32>]> {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts
            .zip(&self.ends)
            .map(|(start, &end)| &self.groups[start as usize..end as usize])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// Constraints of one node pair each, grouped as `groups` (nodes per group).
    fn world(groups: &[&[(u32, u32)]]) -> (Vec<BodyConstraint>, Vec<(u32, f64)>, Vec<u32>) {
        let (mut constraints, mut stencil, mut ends) = (Vec::new(), Vec::new(), Vec::new());
        for group in groups {
            for &(a, b) in *group {
                let start = stencil.len() as u32;
                stencil.extend([(a, 1.0), (b, -1.0)]);
                constraints.push(BodyConstraint {
                    normal: Vector3::z(),
                    stencil: start..stencil.len() as u32,
                });
            }
            ends.push(constraints.len() as u32);
        }
        (constraints, stencil, ends)
    }

    #[test]
    fn groups_sharing_a_node_take_different_colours_and_keep_pair_order() {
        // Bodies as node ranges: A 0..2, B 2..4, C 4..6, D 6..8.
        let (c, s, ends) = world(&[
            &[(0, 2), (1, 3)], // A–B
            &[(2, 4)],         // B–C
            &[(4, 6), (5, 7)], // C–D
            &[(0, 6)],         // A–D
        ]);
        let mut colours = ConstraintColours::default();
        colours.build((&c, &s), &ends, 8);
        let listed: Vec<Vec<Range<u32>>> = colours.colours().map(<[_]>::to_vec).collect();
        assert_eq!(listed, vec![vec![0..2, 3..5], vec![2..3, 5..6]]);
        assert!(!colours.serial_last);
        assert!(colours.taken.iter().all(|&t| t == 0), "marks cleared");
        // Built again on one group: one colour, the marks from before gone.
        colours.build((&c[..2], &s[..4]), &ends[..1], 8);
        assert_eq!(colours.groups, vec![0..2]);
        assert_eq!(colours.ends, vec![1]);
    }

    #[test]
    fn groups_beyond_the_colours_share_one_serial_colour_last() {
        // 70 groups all on node 0: 64 colours of one group, then the six left in one.
        let groups: Vec<Vec<(u32, u32)>> = (1..=70).map(|k| vec![(0, k)]).collect();
        let refs: Vec<&[(u32, u32)]> = groups.iter().map(Vec::as_slice).collect();
        let (c, s, ends) = world(&refs);
        let mut colours = ConstraintColours::default();
        colours.build((&c, &s), &ends, 71);
        assert!(colours.serial_last);
        assert_eq!(colours.ends.len(), COLOURS + 1);
        let last = colours.colours().last().unwrap();
        assert_eq!(last, &[64..65, 65..66, 66..67, 67..68, 68..69, 69..70]);
    }
}
