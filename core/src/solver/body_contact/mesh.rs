//! A body's display surface in the contact pass ([`BodyMesh`]): its refined triangles
//! embedded in the lattice, their vertices, boxes and planes in the step, and the grid the
//! other bodies' samples query it with.
//!
//! The grid holds each triangle's box grown by a margin, placed where the body was when it was
//! built. It is queried in that placement: a query box is moved back by the body's best-fit
//! motion since (the vertices' mean, and the rotation of the polar decomposition of their
//! spread against the built one's) and grown to hold the turned box, so a body that moves
//! as a whole (falls, slides, rolls) keeps its grid. It is read only where a neighbour list is
//! built, so it is brought up to date only then ([`BodyMesh::ensure_grid`]), and rebuilt only
//! once a vertex, moved back so, lies farther than the margin from where it was built (a body
//! that deforms). In a pile of 60 boxes, rebuilding every mesh's grid each step was a large
//! part of the bake; in a heap of 48 of Blender's parts (a thousand faces each), checking
//! and rebuilding it every step for every mesh in reach was a third of it. The triangles'
//! boxes and planes are computed once a step for the meshes some pair's search reads, meshes
//! side by side ([`super::prepare`]).

use super::*;
use crate::collide::geometry::polar_rotation;
pub(super) use crate::collide::geometry::{closed_outward, weld_positions};
use crate::collide::grid::QueryMarks;
use nalgebra::Matrix3;

/// A body's display surface for body–body contact.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BodyMesh {
    pub body: usize,
    /// Per vertex: its cell's world node indices and trilinear weights.
    pub nodes: Vec<[u32; 8]>,
    pub weights: Vec<[f64; 8]>,
    pub triangles: Vec<[u32; 3]>,
    /// Unique edges of the display mesh as given (before refinement), longer than a node
    /// spacing, `[a, b, c]`: `c` the third corner of a triangle holding the edge, so
    /// `(a, b, c)` gives its outward normal.
    pub edges: Vec<[u32; 3]>,
    /// The display triangles as given (for the local radius of curvature).
    pub display: Vec<[u32; 3]>,
    /// Mean edge length at rest, m (the grid's cell).
    pub mean_edge: f64,
    /// The lattice cell, m.
    pub cell: f64,
    /// Young's modulus read off the springs (eq 3.38, `A_sp = L²`), Pa.
    pub young: f64,
    /// The display surface is closed and wound outwards ([`closed_outward`]): a point
    /// outside its body's node box is outside it (see [`super::detect`]'s `pair_contacts`).
    pub closed: bool,
    /// The step whose vertex positions and velocities `x`, `v` hold.
    stamp: u64,
    pub x: Vec<Vector3<f64>>,
    pub v: Vec<Vector3<f64>>,
    /// Per triangle: its box and plane in the step `face_stamp` says.
    pub faces: Vec<FaceBox>,
    face_stamp: Vec<u64>,
    /// The triangles' boxes grown by `margin` at the vertex positions `built_at`, whose mean
    /// was `built_centre`; `centre` is the mean of the vertices and `turn` the rotation that
    /// best takes the built spread about its mean to theirs, both as of the last
    /// [`BodyMesh::ensure_grid`] ([`BodyMesh::query_grid`] moves a query back by both).
    grid: BoxGrid,
    built_at: Vec<Vector3<f64>>,
    built_centre: Vector3<f64>,
    centre: Vector3<f64>,
    turn: Matrix3<f64>,
    margin: f64,
}

/// A display triangle in the step: what the narrow phase reads before it gathers corners.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct FaceBox {
    pub lo: Vector3<f64>,
    pub hi: Vector3<f64>,
    /// Unit normal (zero for a degenerate triangle).
    pub normal: Vector3<f64>,
    /// `normal · corner`: a point's signed distance from the plane is `normal · x − offset`.
    pub offset: f64,
    /// The fastest corner's speed, m/s (bounds how far the face moved in the step).
    pub speed: f64,
}

/// How far (in mean edge lengths) a vertex may move before the mesh's grid is rebuilt: the
/// grid holds each triangle's box grown by this much.
const GRID_MARGIN_EDGES: f64 = 0.15;

impl BodyMesh {
    /// A mesh of `triangles` over vertices embedded by `nodes` and `weights`, in the step
    /// before the first.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        body: usize,
        nodes: Vec<[u32; 8]>,
        weights: Vec<[f64; 8]>,
        triangles: Vec<[u32; 3]>,
        edges: Vec<[u32; 3]>,
        display: Vec<[u32; 3]>,
        (mean_edge, cell, young): (f64, f64, f64),
    ) -> Self {
        let n = nodes.len();
        BodyMesh {
            body,
            nodes,
            weights,
            faces: vec![FaceBox::default(); triangles.len()],
            face_stamp: vec![0; triangles.len()],
            triangles,
            edges,
            display,
            mean_edge,
            cell,
            young,
            closed: false,
            stamp: 0,
            x: vec![Vector3::zeros(); n],
            v: vec![Vector3::zeros(); n],
            grid: BoxGrid::default(),
            built_at: Vec::new(),
            built_centre: Vector3::zeros(),
            centre: Vector3::zeros(),
            turn: Matrix3::identity(),
            margin: GRID_MARGIN_EDGES * mean_edge,
        }
    }

    /// The vertices' positions and velocities in step `stamp` (once a step); the grid is
    /// left to [`BodyMesh::ensure_grid`].
    pub fn update(&mut self, nodes: &NodeState, stamp: u64) {
        if self.stamp == stamp {
            return;
        }
        self.stamp = stamp;
        for (k, (ids, w)) in self.nodes.iter().zip(&self.weights).enumerate() {
            let (mut x, mut v) = (Vector3::zeros(), Vector3::zeros());
            for c in 0..8 {
                x += nodes.position[ids[c] as usize] * w[c];
                v += nodes.velocity[ids[c] as usize] * w[c];
            }
            self.x[k] = x;
            self.v[k] = v;
        }
    }

    /// The grid rebuilt if a vertex has left its margin since it was built (at the
    /// vertices of this step's [`BodyMesh::update`]), before a neighbour list is built from it.
    pub fn ensure_grid(&mut self) {
        let sum = self.x.iter().fold(Vector3::zeros(), |s, x| s + x);
        self.centre = sum / self.x.len().max(1) as f64;
        let kept = self.built_at.len() == self.x.len() && {
            let (c, c0) = (self.centre, self.built_centre);
            let spread = (self.x.iter().zip(&self.built_at)).fold(Matrix3::zeros(), |a, (x, b)| {
                a + (x - c) * (b - c0).transpose()
            });
            // Not finite (a vertex gone to NaN) or not converged: rebuilt.
            polar_rotation(&spread).is_some_and(|turn| {
                self.turn = turn;
                let back = turn.transpose();
                let m2 = self.margin * self.margin;
                (self.x.iter().zip(&self.built_at))
                    .all(|(x, b)| (back * (x - c) + c0 - b).norm_squared() <= m2)
            })
        };
        if !kept {
            self.build_grid();
        }
    }

    /// Whether the vertices are those of step `stamp` ([`BodyMesh::update`]).
    pub fn is_current(&self, stamp: u64) -> bool {
        self.stamp == stamp
    }

    /// The grid over the triangles' boxes at the vertices' positions now, grown by the margin.
    fn build_grid(&mut self) {
        self.built_at.clone_from(&self.x);
        self.built_centre = self.centre;
        self.turn = Matrix3::identity();
        let (x, m) = (&self.x, self.margin);
        let grown = |t: &[u32; 3]| {
            let [p, q, r] = t.map(|i| x[i as usize]);
            (
                p.inf(&q).inf(&r).add_scalar(-m),
                p.sup(&q).sup(&r).add_scalar(m),
            )
        };
        // The region: every vertex's position grown by the margin (holds every box).
        let (lo, hi) = x.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        );
        let (lo, hi) = (lo.add_scalar(-m), hi.add_scalar(m));
        let boxes = self.triangles.iter().enumerate().map(|(k, t)| {
            let (tlo, thi) = grown(t);
            (k as u32, tlo, thi)
        });
        self.grid
            .build(lo, hi, self.mean_edge, self.triangles.len(), boxes);
    }

    /// The ids of the triangles whose grown boxes may meet `[lo, hi]` (this step's
    /// positions), each once, into `out` ([`BoxGrid::query_marked`]): the box moved back by
    /// the body's motion since the grid was built, and grown to the box that holds it turned.
    pub fn query_grid(
        &self,
        (lo, hi): (&Vector3<f64>, &Vector3<f64>),
        out: &mut Vec<u32>,
        marks: &mut QueryMarks,
    ) {
        let back = self.turn.transpose();
        let (mid, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        let at = back * (mid - self.centre) + self.built_centre;
        let reach = back.abs() * half;
        self.grid
            .query_marked(&(at - reach), &(at + reach), out, marks);
    }

    /// Every triangle's box, plane and speed in this step.
    pub fn refresh_all(&mut self) {
        for t in 0..self.triangles.len() {
            self.refresh_face(t);
        }
    }

    #[inline]
    fn refresh_face(&mut self, t: usize) {
        if self.face_stamp[t] == self.stamp {
            return;
        }
        self.face_stamp[t] = self.stamp;
        let tri = self.triangles[t];
        let [p, q, r] = tri.map(|i| self.x[i as usize]);
        let normal = triangle_normal(&p, &q, &r);
        let speed = tri
            .iter()
            .map(|&i| self.v[i as usize].norm_squared())
            .fold(0.0, f64::max)
            .sqrt();
        self.faces[t] = FaceBox {
            lo: p.inf(&q).inf(&r),
            hi: p.sup(&q).sup(&r),
            normal,
            offset: normal.dot(&p),
            speed,
        };
    }

    pub fn corners(&self, t: usize) -> [Vector3<f64>; 3] {
        self.triangles[t].map(|i| self.x[i as usize])
    }
}

/// Most halvings of one display triangle by [`refine`] (at most 2¹² pieces: a triangle 64
/// spacings long).
const MAX_BISECTIONS: u32 = 12;

/// `triangles` with every triangle whose longest edge is over `spacing` halved across that
/// edge until none is (longest-edge bisection; corners keep their vertex, new vertices are
/// appended), so the reaction on a face lands on the lattice cells under the contact, not on
/// the corners of a coarse mesh's big triangles. A thin sliver (a bevel, a rim) is cut along
/// its length only: a barycentric grid cut it into `n²` slivers (a 1.2 m strip of a
/// COLLADA-converted box into 576), whose boxes each query then had to test (a box nested in
/// another took 10 s a frame). Triangles with an out-of-range index are dropped.
pub(super) fn refine(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    spacing: f64,
) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let mut points = positions.to_vec();
    let mut out = Vec::with_capacity(triangles.len());
    let mut stack: Vec<([u32; 3], u32)> = Vec::new();
    for t in triangles {
        if t.iter().any(|&i| i as usize >= positions.len()) {
            continue;
        }
        stack.push((*t, 0));
        while let Some((tri, depth)) = stack.pop() {
            let p = tri.map(|i| points[i as usize]);
            let length = |e: usize| (p[(e + 1) % 3] - p[e]).norm();
            let e = (1..3).fold(0, |best, e| if length(e) > length(best) { e } else { best });
            // `!(… > spacing)` also stops at a NaN length or spacing.
            if depth >= MAX_BISECTIONS || !(spacing > 0.0 && length(e) > spacing) {
                out.push(tri);
                continue;
            }
            let (a, b, c) = (tri[e], tri[(e + 1) % 3], tri[(e + 2) % 3]);
            points.push(Point3::from(
                (points[a as usize].coords + points[b as usize].coords) * 0.5,
            ));
            let m = (points.len() - 1) as u32;
            // The same winding as (a, b, c); the half at `a` comes out first.
            stack.push(([m, b, c], depth + 1));
            stack.push(([a, m, c], depth + 1));
        }
    }
    (points, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::box_mesh;

    #[test]
    fn closed_outward_takes_solids_only() {
        let (p, t) = box_mesh([0.0, 0.0, 0.0], [0.2, 0.3, 0.4]);
        assert!(closed_outward(&p, &t), "a box");
        // Split at every corner the way a DCC exports hard edges: each triangle its own
        // three vertices, welded back by position.
        let split: Vec<Point3<f64>> = t
            .iter()
            .flat_map(|tri| tri.map(|i| p[i as usize]))
            .collect();
        let split_t: Vec<[u32; 3]> = (0..t.len() as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        assert!(
            closed_outward(&split, &split_t),
            "a box split at its corners"
        );
        let inside_out: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
        assert!(!closed_outward(&p, &inside_out), "wound inwards");
        assert!(!closed_outward(&p, &t[1..]), "a face missing a triangle");
        let mut doubled = t.clone();
        doubled.extend_from_slice(&t[..2]);
        assert!(
            !closed_outward(&p, &doubled),
            "a face twice (non-manifold edges)"
        );
        let sheet = [[0, 1, 3], [0, 3, 2]];
        assert!(!closed_outward(&p, &sheet), "an open sheet");
        assert!(!closed_outward(&p, &[]), "nothing");
        let mut nan = p.clone();
        nan[0].x = f64::NAN;
        assert!(!closed_outward(&nan, &t), "a NaN corner");
    }
}
