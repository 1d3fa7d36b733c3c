//! Body–body contacts as constraints of the XPBD step (issue 16, "contact as constraints").
//!
//! The contact pass finds a contact between a feature of one body (a surface sample, a point
//! of a face, a point of an edge) and a feature of its partner, with the normal from the
//! partner into the body's side. Every feature is a fixed linear combination of lattice
//! nodes (a sample: its cell's eight trilinear weights; a face point: its triangle's
//! barycentric weights times each vertex's eight), so the pair's separation along the normal
//! is `C(x) = n · Σ_k s_k x_k` over one signed *stencil* (the body's weights positive, the
//! partner's negative, each node once). The step keeps `C ≥ g`, a small gap
//! (`xpbd::bodies`): the two surfaces may touch but not pass each other. Unlike the elastic layer (a stiff spring that rests the bodies
//! half a cell apart and returns what an impact stored in it), the constraint stores no
//! energy: stacked bodies rest on each other, and a pile dropped together does not throw its
//! parts apart.

use super::{BodyContact, BodyMesh, Feature};
use crate::solver::world::SurfacePoints;
use nalgebra::Vector3;
use std::ops::Range;

/// One contact to keep: `normal · Σ s_k x_k ≥ g` over `stencil` (a range of
/// [`BodyContact::stencil`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BodyConstraint {
    pub normal: Vector3<f64>,
    pub stencil: Range<u32>,
}

/// The stencils of a pair's contacts, made where the pair's search ran (side by side with the
/// other pairs'), for [`BodyContact::constrain_with`] to copy: contact `k`'s entries are
/// `entries[ends[k - 1]..ends[k]]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Stencils {
    pub entries: Vec<(u32, f64)>,
    pub ends: Vec<u32>,
}

impl Stencils {
    /// Append the stencil of contact `a`–`b`.
    pub fn push(&mut self, bc: &BodyContact, surface: &SurfacePoints, a: Feature, b: Feature) {
        append_stencil(&mut self.entries, &bc.meshes, surface, (a, b));
        self.ends.push(self.entries.len() as u32);
    }

    /// Empty, keeping its buffers.
    pub fn clear(&mut self) {
        self.entries.clear();
        self.ends.clear();
    }

    /// Contact `k`'s stencil.
    pub fn get(&self, k: usize) -> &[(u32, f64)] {
        let start = if k == 0 { 0 } else { self.ends[k - 1] };
        &self.entries[start as usize..self.ends[k] as usize]
    }
}

/// Append the stencil of contact `a`–`b` to `stencil`: `a`'s nodes and weights, `b`'s
/// negated, each node once (a face's corners often share cells: the constraint's inverse mass
/// `Σ s_k² w_k` needs the summed weight of a node, not its parts), in node order.
fn append_stencil(
    stencil: &mut Vec<(u32, f64)>,
    meshes: &[BodyMesh],
    surface: &SurfacePoints,
    (a, b): (Feature, Feature),
) {
    let start = stencil.len();
    push_feature(stencil, meshes, surface, a, 1.0);
    let split = stencil.len();
    push_feature(stencil, meshes, surface, b, -1.0);
    merge_nodes(stencil, start, split);
}

/// Sort `stencil[start..]` by node and sum the weights of each node into one entry. Where
/// the two features' parts (split at `split`) are each in node order already (a sample's
/// cell, a face in one cell), the second's nodes all after the first's or all before (two
/// bodies), they are kept or swapped, not sorted.
fn merge_nodes(stencil: &mut Vec<(u32, f64)>, start: usize, split: usize) {
    let part = &mut stencil[start..];
    let (first, second) = part.split_at(split - start);
    let ordered = |p: &[(u32, f64)]| p.windows(2).all(|w| w[0].0 < w[1].0);
    if ordered(first) && ordered(second) {
        match (first.first(), first.last(), second.first(), second.last()) {
            (_, Some(last), Some(next), _) if last.0 < next.0 => return,
            (Some(head), _, _, Some(tail)) if tail.0 < head.0 => {
                part.rotate_left(split - start);
                return;
            }
            (None, ..) | (.., None) => return,
            _ => {}
        }
    }
    part.sort_unstable_by_key(|&(node, _)| node);
    let mut kept = start;
    for i in start..stencil.len() {
        let (node, weight) = stencil[i];
        if kept > start && stencil[kept - 1].0 == node {
            stencil[kept - 1].1 += weight;
        } else {
            stencil[kept] = (node, weight);
            kept += 1;
        }
    }
    stencil.truncate(kept);
}

impl BodyContact {
    /// Keep contact `a`–`b` (normal from `b` into `a`'s side) as a constraint of this step.
    pub(super) fn constrain(
        &mut self,
        surface: &SurfacePoints,
        a: Feature,
        b: Feature,
        normal: Vector3<f64>,
    ) {
        let start = self.stencil.len();
        append_stencil(&mut self.stencil, &self.meshes, surface, (a, b));
        self.constraints.push(BodyConstraint {
            normal,
            stencil: start as u32..self.stencil.len() as u32,
        });
    }

    /// [`BodyContact::constrain`] with the stencil made already ([`Stencils`]).
    pub(super) fn constrain_with(&mut self, stencil: &[(u32, f64)], normal: Vector3<f64>) {
        let start = self.stencil.len();
        self.stencil.extend_from_slice(stencil);
        self.constraints.push(BodyConstraint {
            normal,
            stencil: start as u32..self.stencil.len() as u32,
        });
    }
}

/// Append `feature`'s nodes and weights times `sign` to `stencil` (zero weights left out).
/// A face's or an edge's points embedded in one cell (the same eight nodes: a face smaller
/// than a cell often lies in one) give that cell's eight nodes once, their weights summed,
/// not three times eight entries to sort and merge.
fn push_feature(
    stencil: &mut Vec<(u32, f64)>,
    meshes: &[BodyMesh],
    surface: &SurfacePoints,
    feature: Feature,
    sign: f64,
) {
    let mut push = |ids: &[u32; 8], w: &[f64; 8]| {
        for c in 0..8 {
            if w[c] != 0.0 {
                stencil.push((ids[c], w[c] * sign));
            }
        }
    };
    // The points `v` of a mesh at weights `s`, as one cell's where they share it.
    let mut points = |m: &BodyMesh, v: &[u32], s: &[f64]| {
        let ids = &m.nodes[v[0] as usize];
        if v.iter().all(|&v| m.nodes[v as usize] == *ids) {
            let mut w = [0.0; 8];
            for (&v, &s) in v.iter().zip(s) {
                let wv = &m.weights[v as usize];
                for c in 0..8 {
                    w[c] += wv[c] * s;
                }
            }
            push(ids, &w);
        } else {
            for (&v, &s) in v.iter().zip(s) {
                push(&m.nodes[v as usize], &m.weights[v as usize].map(|w| w * s));
            }
        }
    };
    match feature {
        Feature::Point(i) => push(&surface.nodes[i], &surface.weights[i]),
        Feature::Face { mesh, tri, bary } => {
            let m = &meshes[mesh];
            points(m, &m.triangles[tri], &bary);
        }
        Feature::Edge { mesh, a, b, s } => points(&meshes[mesh], &[a, b], &[1.0 - s, s]),
        Feature::Static => {}
    }
}

impl BodyContact {
    /// This step's body–body contact constraints and their stencils (empty unless
    /// `body_constraints`).
    pub(crate) fn constraints(&self) -> (&[BodyConstraint], &[(u32, f64)]) {
        (&self.constraints, &self.stencil)
    }

    /// The groups of [`Self::constraints`] by colour ([`super::colours`]).
    pub(crate) fn constraint_colours(&self) -> &super::colours::ConstraintColours {
        &self.colours
    }
}

#[cfg(test)]
mod tests {
    use super::merge_nodes;

    /// `merge_nodes` by sorting alone.
    fn sorted(parts: &[(u32, f64)]) -> Vec<(u32, f64)> {
        let mut all = parts.to_vec();
        all.sort_by_key(|&(node, _)| node);
        let mut out: Vec<(u32, f64)> = Vec::new();
        for (node, w) in all {
            match out.last_mut() {
                Some(last) if last.0 == node => last.1 += w,
                _ => out.push((node, w)),
            }
        }
        out
    }

    #[test]
    fn merged_stencils_are_in_node_order_each_node_once() {
        let cell = |base: u32, sign: f64| -> Vec<(u32, f64)> {
            [0, 1, 4, 5, 16, 17, 20, 21]
                .iter()
                .map(|&o| (base + o, sign * (0.1 + o as f64)))
                .collect()
        };
        let spread = vec![(70, -0.5), (66, -0.25), (70, -0.125), (3, -1.0)];
        for (a, b) in [
            (cell(0, 1.0), cell(64, -1.0)),  // in order
            (cell(64, 1.0), cell(0, -1.0)),  // swapped
            (cell(0, 1.0), cell(2, -1.0)),   // interleaved
            (cell(64, 1.0), spread.clone()), // a face across cells
            (Vec::new(), cell(0, -1.0)),     // one side empty
            (cell(0, 1.0), Vec::new()),
        ] {
            let mut stencil = vec![(999, 9.0)];
            stencil.extend(&a);
            let split = stencil.len();
            stencil.extend(&b);
            merge_nodes(&mut stencil, 1, split);
            let parts: Vec<_> = a.iter().chain(&b).copied().collect();
            assert_eq!(stencil[0], (999, 9.0), "before `start` untouched");
            assert_eq!(&stencil[1..], &sorted(&parts)[..], "{a:?} {b:?}");
        }
    }
}
