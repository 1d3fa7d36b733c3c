//! Collision geometry, format-free (physics §10): exact point/segment/triangle queries
//! ([`geometry`]), the uniform-grid broad phase ([`grid`]) and static colliders
//! ([`StaticCollider`]: a rigid triangle mesh in the simulation frame with a grid over its
//! triangles, built once). The solver's body–body and body–collider contact pass
//! (`solver::body_contact`) uses them.

pub mod geometry;
pub mod grid;

pub use grid::BoxGrid;

use nalgebra::{Point3, Vector3};

/// A rigid triangle mesh bodies collide with (a lane, a table, a ramp), in simulation metres.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticCollider {
    pub name: String,
    pub positions: Vec<Vector3<f64>>,
    pub triangles: Vec<[u32; 3]>,
    /// Unit face normals (counter-clockwise front: the side bodies are pushed to).
    pub normals: Vec<Vector3<f64>>,
    /// The mesh bounds no solid (`geometry::closed_outward` is false: a ground plane, a sheet,
    /// a double-sided or inside-out mesh): each face has two fronts, and a point meets the
    /// one on its side (see [`StaticCollider::penetration`]).
    pub two_sided: bool,
    /// Coulomb friction coefficient on its surface.
    pub friction: f64,
    /// Bounding box of the mesh.
    pub lo: Vector3<f64>,
    pub hi: Vector3<f64>,
    pub(crate) grid: BoxGrid,
}

/// A collider mesh that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ColliderError {
    #[error("collider \"{0}\" has no triangles")]
    Empty(String),
    #[error("collider \"{name}\": vertex {vertex} is not finite")]
    NonFinite { name: String, vertex: usize },
    #[error("collider \"{name}\": triangle {triangle} uses vertex {index}, but there are {count}")]
    BadIndex {
        name: String,
        triangle: usize,
        index: u32,
        count: usize,
    },
    #[error("collider \"{name}\": friction must be finite and >= 0, got {value}")]
    BadFriction { name: String, value: f64 },
}

/// How near a face's plane a point counts as on it, in contact layers: what the contact of
/// a body lying on the face leaves (its points are set there through their cells, within a
/// rounding or a fraction of a micrometre either side).
const ON_FACE: f64 = 1e-3;

impl StaticCollider {
    /// A collider from triangles over `positions` (simulation metres). Zero-area triangles are
    /// kept but never touched (their normal is zero).
    pub fn new(
        name: impl Into<String>,
        positions: &[Point3<f64>],
        triangles: &[[u32; 3]],
        friction: f64,
    ) -> Result<StaticCollider, ColliderError> {
        let name = name.into();
        if triangles.is_empty() {
            return Err(ColliderError::Empty(name));
        }
        if !(friction.is_finite() && friction >= 0.0) {
            return Err(ColliderError::BadFriction {
                name,
                value: friction,
            });
        }
        if let Some(vertex) = positions
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return Err(ColliderError::NonFinite { name, vertex });
        }
        for (triangle, t) in triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(ColliderError::BadIndex {
                    name,
                    triangle,
                    index,
                    count: positions.len(),
                });
            }
        }
        let positions: Vec<Vector3<f64>> = positions.iter().map(|p| p.coords).collect();
        let corners = |t: &[u32; 3]| t.map(|i| positions[i as usize]);
        let normals = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = corners(t);
                geometry::triangle_normal(&a, &b, &c)
            })
            .collect();
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        );
        let mut edge_sum = 0.0;
        for t in triangles {
            let [a, b, c] = corners(t);
            for p in [a, b, c] {
                lo = lo.inf(&p);
                hi = hi.sup(&p);
            }
            edge_sum += (b - a).norm() + (c - b).norm() + (a - c).norm();
        }
        let mut grid = BoxGrid::default();
        grid.build(
            lo,
            hi,
            edge_sum / (3.0 * triangles.len() as f64),
            triangles.len(),
            triangles.iter().enumerate().map(|(i, t)| {
                let [a, b, c] = corners(t);
                (i as u32, a.inf(&b).inf(&c), a.sup(&b).sup(&c))
            }),
        );
        let two_sided = !geometry::closed_outward(
            &positions
                .iter()
                .map(|&p| Point3::from(p))
                .collect::<Vec<_>>(),
            triangles,
        );
        Ok(StaticCollider {
            name,
            positions,
            triangles: triangles.to_vec(),
            normals,
            two_sided,
            friction,
            lo,
            hi,
            grid,
        })
    }

    /// Corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [Vector3<f64>; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }

    /// How a point that moved from `previous` to `x` in one step penetrates this surface, as
    /// a contact constraint sees it: `(unit face normal, depth)`. A segment that enters a face
    /// from its front side is a contact with the first face it enters, however deep the point
    /// went (no tunnelling through a thin collider); otherwise a point lying behind the inside
    /// of a face, at most `behind` deep, is a contact with the nearest such face, unless it
    /// lies as near in front of another face (a double-sided sheet). `scratch` holds the
    /// grid's candidates.
    ///
    /// A [`two_sided`](Self::two_sided) collider's faces front the side the point is on
    /// (`side`: the normal this collider last put the point back along, while it stays near,
    /// and the centre of the point's body; see `facing`). A box dropped onto a ground plane
    /// whose faces point down landed on it instead of being pushed through it and thrown at
    /// 170 m/s.
    pub fn penetration(
        &mut self,
        previous: &Vector3<f64>,
        x: &Vector3<f64>,
        behind: f64,
        side: (Option<Vector3<f64>>, Option<Vector3<f64>>),
        scratch: &mut Vec<u32>,
    ) -> Option<(Vector3<f64>, f64)> {
        let lo = x.inf(previous).add_scalar(-behind);
        let hi = x.sup(previous).add_scalar(behind);
        if (0..3).any(|k| hi[k] < self.lo[k] || lo[k] > self.hi[k]) {
            return None;
        }
        self.grid.query(&lo, &hi, scratch);
        let mut crossing: Option<(f64, Vector3<f64>, f64)> = None;
        let mut nearest: Option<(Vector3<f64>, f64)> = None;
        for &t in scratch.iter() {
            let n = self.normals[t as usize];
            if n == Vector3::zeros() {
                continue;
            }
            let [a, b, c] = self.corners(t as usize);
            let n = self.facing(n, a, previous, side, behind);
            let depth = -(x - a).dot(&n);
            if depth <= 0.0 {
                continue;
            }
            if (previous - a).dot(&n) >= 0.0 {
                if let Some((u, _)) = geometry::segment_crosses_triangle(previous, x, &a, &b, &c) {
                    if crossing.is_none_or(|(first, _, _)| u < first) {
                        crossing = Some((u, n, depth));
                    }
                    continue;
                }
            }
            if depth < behind
                && geometry::closest_on_triangle(x, &a, &b, &c).1
                && nearest.is_none_or(|(_, d)| depth < d)
            {
                nearest = Some((n, depth));
            }
        }
        if crossing.is_some() {
            return crossing.map(|(_, n, d)| (n, d));
        }
        // A point as near a face it lies in front of is outside: a double-sided sheet's
        // turned-over face, or a slab thinner than `behind`, would push it through. (A
        // two-sided face fronts the point's side already.)
        nearest.filter(|&(_, depth)| self.two_sided || !self.in_front_within(x, depth, scratch))
    }

    /// Face normal `n` (corner `a`) turned to front the point's side when the collider is
    /// two-sided (see [`Self::penetration`]): the side it rests on, else the side of
    /// `previous`, unless that lies within [`ON_FACE`] layers (`behind`) of the plane (a
    /// point of a body lying on the face, set there through its cell by its neighbours'
    /// contacts, a rounding either side of it): then the side of `body`, the centre of the
    /// point's body; the face's own front when that too lies on the plane.
    fn facing(
        &self,
        n: Vector3<f64>,
        a: Vector3<f64>,
        previous: &Vector3<f64>,
        (resting, body): (Option<Vector3<f64>>, Option<Vector3<f64>>),
        behind: f64,
    ) -> Vector3<f64> {
        if !self.two_sided {
            return n;
        }
        let band = ON_FACE * behind;
        let back = match resting {
            Some(r) => r.dot(&n) < 0.0,
            None => {
                let side = (previous - a).dot(&n);
                if side.abs() > band {
                    side < 0.0
                } else {
                    body.is_some_and(|c| (c - a).dot(&n) < -band)
                }
            }
        };
        if back {
            -n
        } else {
            n
        }
    }

    /// Whether `x` lies in front of the interior of one of the `candidates`, at most `gap`
    /// from it.
    fn in_front_within(&self, x: &Vector3<f64>, gap: f64, candidates: &[u32]) -> bool {
        candidates.iter().any(|&t| {
            let n = self.normals[t as usize];
            let [a, b, c] = self.corners(t as usize);
            let side = (x - a).dot(&n);
            n != Vector3::zeros()
                && side >= 0.0
                && side <= gap * (1.0 + 1e-9)
                && geometry::closest_on_triangle(x, &a, &b, &c).1
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::box_mesh;

    #[test]
    fn a_point_entering_a_face_is_caught_even_through_a_thin_collider() {
        // A 2 × 2 quad at y = 0, facing +y.
        let corners = [
            Point3::new(-1.0, 0.0, -1.0),
            Point3::new(1.0, 0.0, -1.0),
            Point3::new(1.0, 0.0, 1.0),
            Point3::new(-1.0, 0.0, 1.0),
        ];
        let mut quad = StaticCollider::new("quad", &corners, &[[0, 2, 1], [0, 3, 2]], 0.4).unwrap();
        assert!(quad
            .normals
            .iter()
            .all(|n| (n - Vector3::y()).norm() < 1e-12));
        let mut scratch = Vec::new();
        let above = Vector3::new(0.2, 0.3, 0.1);
        // Crossed from the front, 0.5 m deep in one step: depth to the face.
        let (n, d) = quad
            .penetration(
                &above,
                &Vector3::new(0.2, -0.5, 0.1),
                0.05,
                (None, None),
                &mut scratch,
            )
            .unwrap();
        assert_eq!((n, d), (Vector3::y(), 0.5));
        // The quad is open, so two-sided: crossed from below, the face fronts down.
        let below = Vector3::new(0.2, -0.3, 0.1);
        let (n, d) = quad
            .penetration(&below, &above, 0.05, (None, None), &mut scratch)
            .unwrap();
        assert_eq!((n, d), (-Vector3::y(), 0.3));
        // Still above: no contact. Just behind without crossing: on the quad's back, unless
        // it rests on its front, where it is a contact within `behind` only.
        let near = Vector3::new(0.2, -0.01, 0.1);
        assert!(quad
            .penetration(&above, &above, 0.05, (None, None), &mut scratch)
            .is_none());
        assert!(quad
            .penetration(&near, &near, 0.05, (None, None), &mut scratch)
            .is_none());
        let resting = (Some(Vector3::y()), None);
        assert_eq!(
            quad.penetration(&near, &near, 0.05, resting, &mut scratch)
                .unwrap()
                .1,
            0.01
        );
        assert!(quad
            .penetration(&near, &near, 0.005, resting, &mut scratch)
            .is_none());
        // A point on the face's plane, not resting on it, takes its body's side: going down
        // from above it meets the front, going up from below the back.
        let on = Vector3::new(0.2, 0.0, 0.1);
        let (down, up) = (Vector3::new(0.2, -0.01, 0.1), Vector3::new(0.2, 0.01, 0.1));
        let sides = |body: f64| (None, Some(Vector3::new(0.0, body, 0.0)));
        let (n, _) = quad
            .penetration(&on, &down, 0.05, sides(0.2), &mut scratch)
            .unwrap();
        assert_eq!(n, Vector3::y());
        assert!(quad
            .penetration(&on, &up, 0.05, sides(0.2), &mut scratch)
            .is_none());
        let (n, _) = quad
            .penetration(&on, &up, 0.05, sides(-0.2), &mut scratch)
            .unwrap();
        assert_eq!(n, -Vector3::y());
        // Beside the quad: nothing.
        let off = Vector3::new(1.5, -0.01, 0.0);
        assert!(quad
            .penetration(&off, &off, 0.05, (None, None), &mut scratch)
            .is_none());
    }

    #[test]
    fn bad_colliders_are_refused_with_their_name() {
        let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
        let c = StaticCollider::new("lane", &p, &t, 0.3).unwrap();
        assert_eq!(c.triangles.len(), 12);
        assert_eq!((c.lo, c.hi), (Vector3::zeros(), Vector3::repeat(1.0)));
        // Outward normals of the box: the top face's point up.
        assert_eq!(c.normals[6], Vector3::y());
        let e = StaticCollider::new("lane", &p, &[], 0.3).unwrap_err();
        assert!(e.to_string().contains("\"lane\""), "{e}");
        let e = StaticCollider::new("lane", &p, &[[0, 1, 9]], 0.3).unwrap_err();
        assert!(e.to_string().contains("vertex 9"), "{e}");
        let e = StaticCollider::new("lane", &p, &t, -1.0).unwrap_err();
        assert!(e.to_string().contains("friction"), "{e}");
    }
}
