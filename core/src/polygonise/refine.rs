//! Grading a polygonised surface by its curvature: edges are split where the surface bulges
//! away from them, so a mesh is fine only where the surface bends (§5.3's "finer where the
//! curvature is high") and the grid's cell size everywhere else.
//!
//! A triangle is refined when the midpoint of one of its edges, moved onto the surface
//! (Newton steps along the field's gradient), moves more than the tolerance and that edge is
//! longer than the shortest edge allowed. Refining follows Rivara's longest-edge propagation
//! path: the neighbour across the longest edge is followed while its own longest edge is
//! longer, and the edge where the path ends (the longest of both its triangles) is split, until
//! the triangle's own longest edge is. Splitting only such edges keeps every angle above half
//! the smallest the mesh started with, however far it is refined. Splitting an edge splits both
//! triangles on it in two, in their own winding, so the mesh stays watertight and consistently
//! oriented after every split. Triangles are taken first in first out from a queue seeded in
//! index order: the same surface always refines the same way.

use super::V3;
use crate::superquadric::Model;
use rustc_hash::FxHashMap;
use std::collections::VecDeque;

/// Longest path of longest edges followed from a triangle to the edge to split.
const MAX_PATH: usize = 32;
/// A Newton step shorter than this fraction of the gradient's difference step ends the
/// projection (the point is on the surface to well under the tolerance).
const CONVERGED_PER_STEP: f64 = 0.01;
/// Most Newton steps that move a point onto the surface.
const PROJECTION_STEPS: usize = 3;

/// What grading asks of the mesh.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grading {
    /// Largest distance between an edge's midpoint and the surface left unsplit, m.
    pub tolerance: f64,
    /// Edges shorter than this are never split, m.
    pub shortest_edge: f64,
    /// The step of the field's finite-difference gradient, m.
    pub gradient_step: f64,
    /// Most triangles the mesh may grow to.
    pub max_triangles: usize,
}

/// `p` moved onto the surface along the field's gradient; `p` itself where the gradient
/// vanishes or the steps would carry it further than `reach` (another sheet of the surface).
pub(super) fn project(model: &Model, p: V3, step: f64, reach: f64) -> V3 {
    let t = model.threshold();
    let mut q = p;
    for _ in 0..PROJECTION_STEPS {
        let g = model.gradient(&q, step);
        let gg = g.norm_squared();
        if !(gg > 0.0 && gg.is_finite()) {
            return p;
        }
        let next = q - g * ((model.field(&q) - t) / gg);
        if (next - p).norm() > reach || !next.iter().all(|x| x.is_finite()) {
            return p;
        }
        let moved = (next - q).norm();
        q = next;
        if moved < step * CONVERGED_PER_STEP {
            break;
        }
    }
    q
}

/// Triangles on each edge, by sorted vertex pair.
struct Edges(FxHashMap<(u32, u32), [u32; 2]>);

fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl Edges {
    fn of(triangles: &[[u32; 3]]) -> Edges {
        let mut edges = Edges(FxHashMap::default());
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                edges.attach(tri[k], tri[(k + 1) % 3], t as u32);
            }
        }
        edges
    }

    /// Triangle `t` is on edge `(a, b)` (the edge's first triangle, or its second).
    fn attach(&mut self, a: u32, b: u32, t: u32) {
        let slot = self.0.entry(key(a, b)).or_insert([u32::MAX; 2]);
        slot[usize::from(slot[0] != u32::MAX)] = t;
    }

    /// Edge `(a, b)` is on `new` where it was on `old`.
    fn replace(&mut self, a: u32, b: u32, old: u32, new: u32) {
        if let Some(slot) = self.0.get_mut(&key(a, b)) {
            for t in slot.iter_mut().filter(|t| **t == old) {
                *t = new;
            }
        }
    }
}

/// The mesh being graded.
struct Mesh<'a> {
    positions: &'a mut Vec<[f64; 3]>,
    triangles: &'a mut Vec<[u32; 3]>,
    edges: Edges,
}

impl Mesh<'_> {
    fn length(&self, (a, b): (u32, u32)) -> f64 {
        (V3::from(self.positions[a as usize]) - V3::from(self.positions[b as usize])).norm()
    }

    /// The triangle's longest edge (ties broken by key, so a path's edges strictly grow).
    fn longest(&self, t: u32) -> ((u32, u32), f64) {
        let tri = self.triangles[t as usize];
        (0..3)
            .map(|k| {
                let e = key(tri[k], tri[(k + 1) % 3]);
                (e, self.length(e))
            })
            .fold(((0, 0), -1.0), |best, (e, l)| {
                if l > best.1 || (l == best.1 && e > best.0) {
                    (e, l)
                } else {
                    best
                }
            })
    }

    /// The triangle across edge `e` from `t`, if any.
    fn across(&self, e: (u32, u32), t: u32) -> Option<u32> {
        let [t0, t1] = *self.edges.0.get(&e)?;
        let other = if t0 == t { t1 } else { t0 };
        (other != u32::MAX).then_some(other)
    }

    /// Splits edge `(a, b)` at `at`: both its triangles in two. Returns the four triangles.
    fn split(&mut self, (a, b): (u32, u32), at: V3) -> Vec<u32> {
        let Some(sides) = self.edges.0.remove(&(a, b)) else {
            return Vec::new();
        };
        let m = self.positions.len() as u32;
        self.positions.push([at.x, at.y, at.z]);
        let mut touched = Vec::with_capacity(4);
        for t in sides.into_iter().filter(|&t| t != u32::MAX) {
            let tri = self.triangles[t as usize];
            // The triangle's corners from the split edge on, in its own winding: (x, y, z).
            let start = (0..3)
                .find(|&k| key(tri[k], tri[(k + 1) % 3]) == (a, b))
                .unwrap_or(0);
            let (x, y, z) = (tri[start], tri[(start + 1) % 3], tri[(start + 2) % 3]);
            let new = self.triangles.len() as u32;
            self.triangles[t as usize] = [x, m, z];
            self.triangles.push([m, y, z]);
            self.edges.replace(y, z, t, new);
            self.edges.attach(x, m, t);
            self.edges.attach(m, y, new);
            self.edges.0.insert(key(m, z), [t, new]);
            touched.extend([t, new]);
        }
        touched
    }
}

/// Splits the surface's edges as [`Grading`] asks, appending vertices (their normals are
/// the caller's). Returns how many triangles still asked for a split when the triangle
/// budget ran out (0 when none).
pub(super) fn refine(
    model: &Model,
    positions: &mut Vec<[f64; 3]>,
    triangles: &mut Vec<[u32; 3]>,
    grading: Grading,
) -> usize {
    let edges = Edges::of(triangles);
    let mut mesh = Mesh {
        positions,
        triangles,
        edges,
    };
    let mut queue: VecDeque<u32> = (0..mesh.triangles.len() as u32).collect();
    // Edges whose midpoint is on the surface within the tolerance (never split for it).
    let mut flat: rustc_hash::FxHashSet<(u32, u32)> = Default::default();
    let mut unsplit = 0;
    // The edge's midpoint and that point on the surface, or None where the surface point
    // would not split the edge (it lands near an end).
    let on_surface = |mesh: &Mesh, (a, b): (u32, u32), length: f64| {
        let (pa, pb) = (
            V3::from(mesh.positions[a as usize]),
            V3::from(mesh.positions[b as usize]),
        );
        let middle = (pa + pb) * 0.5;
        // Within a quarter of the edge of its midpoint, so both halves are shorter than 0.56
        // of it (refining always ends) and the point cannot jump to another sheet.
        let target = project(model, middle, grading.gradient_step, length * 0.25);
        let splits = (target - pa).norm() > length * 0.25 && (target - pb).norm() > length * 0.25;
        (middle, splits.then_some(target))
    };
    while let Some(t) = queue.pop_front() {
        // Refined when any edge long enough to split bulges away from the surface.
        let tri = mesh.triangles[t as usize];
        let bulging = (0..3).any(|k| {
            let e = key(tri[k], tri[(k + 1) % 3]);
            let length = mesh.length(e);
            if length < grading.shortest_edge || flat.contains(&e) {
                return false;
            }
            let (middle, target) = on_surface(&mesh, e, length);
            let bulges = target.is_some_and(|p| (p - middle).norm() > grading.tolerance);
            if !bulges {
                flat.insert(e);
            }
            bulges
        });
        if !bulging {
            continue;
        }
        if mesh.triangles.len() + 2 > grading.max_triangles {
            unsplit += 1;
            continue;
        }
        let (edge, _) = mesh.longest(t);
        // Follow the longest edges to where two triangles share theirs, and split there.
        // (A path through a fan of degenerate triangles, vertices the grid put on one point,
        // is not followed far: the triangle is left as it is.)
        let (mut at, mut at_edge) = (t, edge);
        let mut steps = 0;
        while let Some(next) = mesh.across(at_edge, at) {
            let (next_edge, _) = mesh.longest(next);
            if next_edge == at_edge || steps == MAX_PATH {
                break;
            }
            (at, at_edge, steps) = (next, next_edge, steps + 1);
        }
        if steps == MAX_PATH {
            continue;
        }
        let (middle, target) = on_surface(&mesh, at_edge, mesh.length(at_edge));
        let point = target.unwrap_or(middle);
        queue.extend(mesh.split(at_edge, point));
        if at_edge != edge {
            queue.push_back(t); // not refined yet: the path to its edge is shorter now
        }
    }
    unsplit
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::superquadric::Superquadric;

    #[test]
    fn projection_lands_on_a_sphere() {
        let m = Model::new(
            &[Superquadric {
                center: [0.0; 3],
                radii: [0.5; 3],
                exponents: [1.0, 1.0],
                rotation: [0.0; 3],
                weight: 1.0,
            }],
            0.5,
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let p = project(&m, V3::new(0.3, 0.2, 0.1), 1e-4, 1.0);
        assert!((p.norm() - 0.5).abs() < 1e-6, "{}", p.norm());
    }
}
