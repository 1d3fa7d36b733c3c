//! Parts that interpenetrate at the start: pairs of bodies whose display meshes overlap
//! deeper than the contact layer can push out (a kitbash: a sphere sunk into a box, a rod
//! through it, eyes set into a head, a box modelled inside another).
//!
//! The layer only finds a face within [`BEHIND_LAYERS`] layer thicknesses of a point; a point
//! deeper than that is pushed by whichever face it meets next, and the parts are thrown apart
//! at metres per second (a sphere sunk halfway into a box left it at 10 m/s). The artist
//! modelled one object out of several parts, so such a pair is not a contact: the XPBD solver
//! glues the two where their solids overlap (`xpbd::glue`) and the contact pass ignores the
//! pair. Parts that only touch or overlap within the layer still separate gently
//! (`xpbd::MAX_SEPARATION_SPEED`).
//!
//! A pair is deep when a contact sample of one body lies inside the other's mesh farther than
//! a layer thickness from every one of its triangles. Inside is the nonzero rule of the mesh's
//! winding number along a vertical line, counted both ways: the signed crossings above the
//! point and all the crossings of the line must agree (the line leaves a closed mesh as often
//! as it enters; an open sheet or a hole in the line's way gives no answer, read as outside).
//!
//! A pair is also welded when an edge of one mesh passes through a face of the other at rest
//! and the two are not both closed: a sheet or a double-sided shell has no inside for the
//! deep test, yet a part that pierces it can never be pushed out (trimesh's `chair_model.obj`:
//! a wire loop through a double-sided bowl, each side's samples pushed by the other's two
//! faces, fought each other until the chair shook at 9 m/s). The crossing points are where
//! the glue ties the two.
//!
//! Two closed solids that fit into each other are welded where they touch: a dowel or bolt
//! modelled in a hole of its own radius (a CAD assembly: trimesh's `pins.glb`), a peg through
//! a slot. Their faces coincide, so every sample of the peg lies within the layer of the
//! hole's wall and the contact pushes it in from all round; it cannot part them, only squeeze
//! the peg and widen the hole, which pumped the layer's stored push into the cells (1 g
//! dowels at 3 m/s). A pair fits when at least [`FIT_MIN_POINTS`] samples of the two lie
//! within a layer of the other's faces and those faces' normals nearly cancel (their sum at
//! most [`FIT_RESULTANT`] of their count; a box resting on another has 1). Other closed solids
//! that touch or overlap within the layer still separate.
//!
//! An open mesh whose boundary lies on another's surface at rest was split from it: a block
//! written as its top face and its other five faces (a voxel export: `McUsd.usda`; a DCC
//! splitting a mesh by material). The lid's edge lies inside the sides' layer, which shot it
//! off at 20 m/s. Points along such boundary edges that lie on the other surface (at least
//! [`SEAM_MIN_POINTS`]) weld the pair.

use super::mesh::weld_positions;
use super::{BodyMesh, BEHIND_LAYERS};
use crate::collide::geometry::{closest_on_triangle, segment_crosses_triangle};
use crate::collide::BoxGrid;
use crate::lattice::fill::vertical_crossing;
use crate::solver::World;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// The vertical lines' offsets from the point, in cells of the mesh's grid: irrational and
/// small, so a point on a lattice plane that a box's edge also lies on is not counted on the
/// edge; a second offset is tried when the first line passes through an edge anyway.
const LINE_OFFSETS: [[f64; 2]; 2] = [[1.37e-5, 0.93e-5], [-0.61e-5, 1.71e-5]];

/// Fewest points of an open mesh's boundary on another's surface that make a seam.
const SEAM_MIN_POINTS: usize = 3;

/// How near another surface a point of an open mesh's boundary must be to lie on it, in
/// boundary sample spacings: the two were one mesh, split along that edge.
const SEAM_TOLERANCE: f64 = 1e-6;

/// Fewest samples of a pair within a layer of each other's faces that can make it a fit.
const FIT_MIN_POINTS: usize = 8;

/// Largest length of the sum of the touching faces' unit normals, over their count, for
/// which a pair fits into each other (module docs): a peg in a hole is near 0, a part in a
/// tight recess (its bottom and four walls touching) 0.2, a stack of boxes 1.
const FIT_RESULTANT: f64 = 0.25;

/// A body's display mesh at rest, for inside and distance queries.
pub(crate) struct Solid {
    triangles: Vec<[V3; 3]>,
    grid: BoxGrid,
    lo: V3,
    hi: V3,
    cell: f64,
    found: Vec<u32>,
}

impl Solid {
    fn new(triangles: Vec<[V3; 3]>, cell: f64) -> Solid {
        let (mut lo, mut hi) = (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY));
        for t in &triangles {
            for p in t {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
        }
        let mut grid = BoxGrid::default();
        let boxes = triangles
            .iter()
            .enumerate()
            .map(|(i, [a, b, c])| (i as u32, a.inf(b).inf(c), a.sup(b).sup(c)));
        grid.build(lo, hi, cell, triangles.len(), boxes);
        Solid {
            triangles,
            grid,
            lo,
            hi,
            cell,
            found: Vec::new(),
        }
    }

    /// Whether `p` lies inside the mesh (module docs).
    pub(crate) fn contains(&mut self, p: &V3) -> bool {
        if (0..3).any(|k| p[k] < self.lo[k] || p[k] > self.hi[k]) {
            return false;
        }
        for [dx, dy] in LINE_OFFSETS {
            let (x, y) = (p.x + dx * self.cell, p.y + dy * self.cell);
            let (bottom, top) = (
                V3::new(x, y, self.lo.z - self.cell),
                V3::new(x, y, self.hi.z + self.cell),
            );
            self.grid.query(&bottom, &top, &mut self.found);
            let (mut above, mut all) = (0i32, 0i32);
            for &t in &self.found {
                if let Some((z, sign)) = vertical_crossing(self.triangles[t as usize], x, y) {
                    all += sign;
                    if z > p.z {
                        above += sign;
                    }
                }
            }
            if all == 0 {
                return above != 0;
            }
        }
        false
    }

    /// Where segment `p0 → p1` passes through the mesh's triangles, strictly inside both
    /// (a corner resting on a face, an edge on an edge, coplanar faces do not count), pushed
    /// to `out`.
    fn crossings(&mut self, p0: &V3, p1: &V3, out: &mut Vec<V3>) {
        const INSIDE: f64 = 1e-6;
        self.grid.query(&p0.inf(p1), &p0.sup(p1), &mut self.found);
        for &t in &self.found {
            let [a, b, c] = &self.triangles[t as usize];
            if let Some((s, w)) = segment_crosses_triangle(p0, p1, a, b, c) {
                if s > INSIDE && s < 1.0 - INSIDE && w.iter().all(|&w| w > INSIDE) {
                    out.push(p0 + (p1 - p0) * s);
                }
            }
        }
    }

    /// The unit normal of the triangle nearest `p`, if one comes within `r` (outward for a
    /// mesh wound outwards).
    fn nearest_normal(&mut self, p: &V3, r: f64) -> Option<V3> {
        self.grid
            .query(&p.add_scalar(-r), &p.add_scalar(r), &mut self.found);
        let mut nearest: Option<(f64, V3)> = None;
        for &t in &self.found {
            let [a, b, c] = &self.triangles[t as usize];
            let (w, _) = closest_on_triangle(p, a, b, c);
            let d = (p - (a * w[0] + b * w[1] + c * w[2])).norm();
            if d < r && nearest.is_none_or(|(e, _)| d < e) {
                nearest = Some((d, (b - a).cross(&(c - a))));
            }
        }
        nearest.and_then(|(_, n)| n.try_normalize(0.0))
    }

    /// Whether some triangle of the mesh comes within `r` of `p`.
    fn near_surface(&mut self, p: &V3, r: f64) -> bool {
        self.grid
            .query(&p.add_scalar(-r), &p.add_scalar(r), &mut self.found);
        self.found.iter().any(|&t| {
            let [a, b, c] = &self.triangles[t as usize];
            let (w, _) = closest_on_triangle(p, a, b, c);
            (p - (a * w[0] + b * w[1] + c * w[2])).norm() < r
        })
    }
}

/// The bodies that interpenetrate at the start and each body's solid (for the glue).
pub(crate) struct StartOverlaps {
    /// Body pairs `(lower, higher)` whose meshes overlap deeper than the layer, or cross
    /// where one is not closed.
    pub pairs: Vec<(usize, usize)>,
    /// Per pair: the points where the meshes cross at rest, or where they touch for a pair
    /// that fits into each other.
    pub welds: Vec<Vec<V3>>,
    /// Per pair: whether it is welded where it touches (a fit: two closed solids touching
    /// all round; a seam: an open mesh's boundary on the other's surface), not where the two
    /// overlap or cross.
    pub touch_welded: Vec<bool>,
    /// Per body: its mesh at rest, for the bodies of `pairs`.
    pub solids: Vec<Option<Solid>>,
}

/// The body pairs of `world` whose display meshes overlap deeper than the contact layer at
/// rest, cross where one is not closed, fit into each other or meet along a seam (module
/// docs), among the bodies with a collision mesh.
pub(crate) fn start_overlaps(world: &World) -> StartOverlaps {
    let bc = &world.body_contact;
    let depth = BEHIND_LAYERS * world.settings.layer.thickness_m;
    let mut solids: Vec<Option<Solid>> = (0..world.bodies.len()).map(|_| None).collect();
    let (mut pairs, mut welds, mut touch_welded) = (Vec::new(), Vec::new(), Vec::new());
    if bc.meshes.len() < 2 || depth.is_nan() || depth <= 0.0 {
        return StartOverlaps {
            pairs,
            welds,
            touch_welded,
            solids,
        };
    }
    let meshes: Vec<&BodyMesh> = bc.meshes.iter().collect();
    let rest = |ids: &[u32; 8], w: &[f64; 8]| -> V3 {
        (0..8).map(|c| world.rest[ids[c] as usize] * w[c]).sum()
    };
    let vertices: Vec<Vec<V3>> = meshes
        .iter()
        .map(|m| {
            m.nodes
                .iter()
                .zip(&m.weights)
                .map(|(n, w)| rest(n, w))
                .collect()
        })
        .collect();
    let bounds = |v: &[V3]| {
        v.iter().fold(
            (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        )
    };
    let boxes: Vec<(V3, V3)> = vertices.iter().map(|v| bounds(v)).collect();
    let samples = rest_samples(world);
    let mut boundaries: Vec<Option<Vec<(V3, V3)>>> = vec![None; meshes.len()];
    let solid_of = |m: usize| {
        let v = &vertices[m];
        let corners = meshes[m].display.iter().map(|t| t.map(|k| v[k as usize]));
        Solid::new(corners.collect(), meshes[m].cell)
    };
    for i in 0..meshes.len() {
        for j in i + 1..meshes.len() {
            let (a, b) = (
                meshes[i].body.min(meshes[j].body),
                meshes[i].body.max(meshes[j].body),
            );
            let ((alo, ahi), (blo, bhi)) = (boxes[i], boxes[j]);
            let (lo, hi) = (alo.sup(&blo), ahi.inf(&bhi));
            if (0..3).any(|k| lo[k] > hi[k]) || bc.ignored_pairs.contains(&(a, b)) {
                continue;
            }
            let mut deep = false;
            for (from, to) in [(i, j), (j, i)] {
                if deep {
                    break;
                }
                let solid = solids[meshes[to].body].get_or_insert_with(|| solid_of(to));
                deep = samples[meshes[from].body].iter().any(|p| {
                    (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k])
                        && solid.contains(p)
                        && !solid.near_surface(p, depth)
                });
            }
            let mut crossings = Vec::new();
            if deep || !(meshes[i].closed && meshes[j].closed) {
                for (from, to) in [(i, j), (j, i)] {
                    let solid = solids[meshes[to].body].get_or_insert_with(|| solid_of(to));
                    let v = &vertices[from];
                    for t in &meshes[from].display {
                        for e in 0..3 {
                            let (p0, p1) = (&v[t[e] as usize], &v[t[(e + 1) % 3] as usize]);
                            let outside =
                                |k: usize| p0[k].max(p1[k]) < lo[k] || p0[k].min(p1[k]) > hi[k];
                            if !(0..3).any(outside) {
                                solid.crossings(p0, p1, &mut crossings);
                            }
                        }
                    }
                }
            }
            let mut seam = Vec::new();
            if !deep && crossings.is_empty() && !(meshes[i].closed && meshes[j].closed) {
                for (from, to) in [(i, j), (j, i)] {
                    if meshes[from].closed {
                        continue;
                    }
                    let solid = solids[meshes[to].body].get_or_insert_with(|| solid_of(to));
                    let edges = boundaries[from].get_or_insert_with(|| {
                        boundary_edges(&vertices[from], &meshes[from].display)
                    });
                    let spacing = 0.5 * meshes[from].cell;
                    let tolerance = SEAM_TOLERANCE * spacing;
                    on_surface(solid, edges, (spacing, tolerance), &mut seam);
                }
            }
            let is_seam = seam.len() >= SEAM_MIN_POINTS;
            let mut touching = Vec::new();
            if !deep && crossings.is_empty() && meshes[i].closed && meshes[j].closed {
                let region = (lo.add_scalar(-depth), hi.add_scalar(depth));
                for (from, to, sense) in [(i, j, 1.0), (j, i, -1.0)] {
                    let solid = solids[meshes[to].body].get_or_insert_with(|| solid_of(to));
                    let points = &samples[meshes[from].body];
                    touches(solid, points, region, (depth, sense), &mut touching);
                }
            }
            let fit = fits_into(&touching);
            if deep || !crossings.is_empty() || fit || is_seam {
                pairs.push((a, b));
                touch_welded.push(fit || is_seam);
                if fit {
                    crossings.extend(touching.iter().map(|&(p, _)| p));
                } else if is_seam {
                    crossings.append(&mut seam);
                }
                welds.push(crossings);
                // Both sides' solids: the glue attaches each side's nodes inside the other.
                for m in [i, j] {
                    solids[meshes[m].body].get_or_insert_with(|| solid_of(m));
                }
            }
        }
    }
    // Keep the solids of the bodies in a pair only.
    for (b, solid) in solids.iter_mut().enumerate() {
        if !pairs.iter().any(|&(x, y)| x == b || y == b) {
            *solid = None;
        }
    }
    StartOverlaps {
        pairs,
        welds,
        touch_welded,
        solids,
    }
}

/// The samples among `points` inside `region` that lie within `r` of `solid`'s faces, each
/// with the nearest face's unit normal times `sense` (so that both sides of a pair count
/// their normals the same way round), pushed to `out`.
fn touches(
    solid: &mut Solid,
    points: &[V3],
    (lo, hi): (V3, V3),
    (r, sense): (f64, f64),
    out: &mut Vec<(V3, V3)>,
) {
    for p in points {
        if (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]) {
            continue;
        }
        if let Some(n) = solid.nearest_normal(p, r) {
            out.push((*p, n * sense));
        }
    }
}

/// The boundary edges of the mesh `triangles` over `vertices` (edges walked by one triangle
/// only, corners at the same position taken as one vertex), as corner pairs.
fn boundary_edges(vertices: &[V3], triangles: &[[u32; 3]]) -> Vec<(V3, V3)> {
    use std::collections::BTreeMap;
    let welded = weld_positions(vertices.iter().copied());
    let mut walks: BTreeMap<(u32, u32), (u32, usize, usize)> = BTreeMap::new();
    for t in triangles {
        for e in 0..3 {
            let (p, q) = (t[e] as usize, t[(e + 1) % 3] as usize);
            let (u, v) = (welded[p], welded[q]);
            let edge = if u < v { (u, v) } else { (v, u) };
            walks.entry(edge).or_insert((0, p, q)).0 += 1;
        }
    }
    (walks.into_values())
        .filter(|&(n, _, _)| n == 1)
        .map(|(_, p, q)| (vertices[p], vertices[q]))
        .collect()
}

/// Points along `edges`, at most `spacing` apart and including their ends, that lie within
/// `tolerance` of `solid`'s faces, pushed to `out`.
fn on_surface(
    solid: &mut Solid,
    edges: &[(V3, V3)],
    (spacing, tolerance): (f64, f64),
    out: &mut Vec<V3>,
) {
    for (p0, p1) in edges {
        let pieces = ((p1 - p0).norm() / spacing).ceil().clamp(1.0, 1e4) as usize;
        for k in 0..=pieces {
            let p = p0 + (p1 - p0) * (k as f64 / pieces as f64);
            if solid.near_surface(&p, tolerance) {
                out.push(p);
            }
        }
    }
}

/// Whether the touching samples of a pair of closed solids, with their faces' normals (see
/// [`touches`]), make it a fit (module docs).
fn fits_into(touching: &[(V3, V3)]) -> bool {
    let sum: V3 = touching.iter().map(|(_, n)| n).sum();
    touching.len() >= FIT_MIN_POINTS && sum.norm() <= FIT_RESULTANT * touching.len() as f64
}

/// Per body: its contact samples at rest.
fn rest_samples(world: &World) -> Vec<Vec<V3>> {
    let surface = &world.surface;
    let mut samples: Vec<Vec<V3>> = vec![Vec::new(); world.bodies.len()];
    for i in 0..surface.len() {
        if let Some(list) = samples.get_mut(surface.body[i] as usize) {
            let (ids, w) = (&surface.nodes[i], &surface.weights[i]);
            list.push((0..8).map(|c| world.rest[ids[c] as usize] * w[c]).sum());
        }
    }
    samples
}

/// The (body, static collider) pairs of `world` where a contact sample of the body lies
/// inside the collider's closed mesh at rest, farther than the contact layer from its faces:
/// the collider only puts back points that entered its faces or lie within the layer, so
/// such a body stays inside it or is pushed out through a face.
pub(crate) fn inside_colliders(world: &World) -> Vec<(usize, usize)> {
    let depth = BEHIND_LAYERS * world.settings.layer.thickness_m;
    let mut found = Vec::new();
    if world.body_contact.colliders.is_empty() || depth.is_nan() || depth <= 0.0 {
        return found;
    }
    let samples = rest_samples(world);
    for (c, collider) in world.body_contact.colliders.iter().enumerate() {
        let corners = (0..collider.triangles.len()).map(|t| collider.corners(t));
        let mut solid = Solid::new(corners.collect(), 2.0 * depth);
        for (b, points) in samples.iter().enumerate() {
            let inside = points.iter().any(|p| {
                (0..3).all(|k| p[k] >= collider.lo[k] && p[k] <= collider.hi[k])
                    && solid.contains(p)
                    && !solid.near_surface(p, depth)
            });
            if inside {
                found.push((b, c));
            }
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::box_mesh;

    fn solid(triangles: &[[u32; 3]], flip: bool) -> Solid {
        let (points, _) = box_mesh([0.0; 3], [1.0; 3]);
        let corners = triangles
            .iter()
            .map(|t| {
                let c = t.map(|i| points[i as usize].coords);
                if flip {
                    [c[0], c[2], c[1]]
                } else {
                    c
                }
            })
            .collect();
        Solid::new(corners, 0.25)
    }

    /// Inside a closed box (also on the diagonal its faces are split along, and with its
    /// faces wound inwards), not outside it, and no answer through an open box.
    #[test]
    fn a_point_is_inside_a_closed_mesh_only() {
        let (_, triangles) = box_mesh([0.0; 3], [1.0; 3]);
        for flip in [false, true] {
            let mut s = solid(&triangles, flip);
            for p in [[0.5, 0.5, 0.5], [0.25, 0.75, 0.9], [0.0, 0.0, 0.5]] {
                assert!(s.contains(&V3::from(p)), "{p:?} (flipped: {flip})");
            }
            for p in [[1.5, 0.5, 0.5], [0.5, 0.5, 1.01], [-0.01, 0.5, 0.5]] {
                assert!(!s.contains(&V3::from(p)), "{p:?} (flipped: {flip})");
            }
        }
        // Without its two faces at z = 1 the box is open along the vertical line.
        let top = |t: &&[u32; 3]| t.iter().all(|&i| i & 4 != 0);
        let open: Vec<[u32; 3]> = triangles.iter().filter(|t| !top(t)).copied().collect();
        assert_eq!(open.len(), triangles.len() - 2);
        assert!(!solid(&open, false).contains(&V3::new(0.5, 0.5, 0.5)));
    }

    #[test]
    fn near_surface_reaches_the_nearest_face() {
        let (_, triangles) = box_mesh([0.0; 3], [1.0; 3]);
        let mut s = solid(&triangles, false);
        assert!(s.near_surface(&V3::new(0.5, 0.5, 0.95), 0.06));
        assert!(!s.near_surface(&V3::new(0.5, 0.5, 0.9), 0.06));
    }
}
