//! The static colliders particles bounce off (issue 20: "bouncing off the floor, walls and
//! colliders"): their triangles' boxes in the broad phase's grid ([`BoxGrid`]), and the first
//! triangle a particle's step crosses (`collide::geometry::segment_crosses_triangle` on the
//! segment from where it was to where it would be).

use crate::collide::geometry::segment_crosses_triangle;
use crate::collide::BoxGrid;
use nalgebra::Vector3;
use std::cell::RefCell;

type V3 = Vector3<f64>;

/// The colliders' triangles and a grid over their boxes.
pub struct TriangleGrid {
    triangles: Vec<[V3; 3]>,
    /// The grid and a query's scratch list (a query marks what it reported: `&mut`).
    query: RefCell<(BoxGrid, Vec<u32>)>,
}

/// Where a step crosses a triangle: the point, and the triangle's unit normal facing the
/// side the step came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    pub point: V3,
    pub normal: V3,
}

impl TriangleGrid {
    /// The grid of `triangles` (none: `None`), cells about the mean triangle size.
    pub fn new(triangles: Vec<[V3; 3]>) -> Option<TriangleGrid> {
        let first = triangles.first()?;
        let (mut lo, mut hi) = (first[0], first[0]);
        let mut edge = 0.0;
        let boxes: Vec<(u32, V3, V3)> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let (a, b) = (t[0].inf(&t[1]).inf(&t[2]), t[0].sup(&t[1]).sup(&t[2]));
                lo = lo.inf(&a);
                hi = hi.sup(&b);
                edge += (t[1] - t[0]).norm() + (t[2] - t[1]).norm() + (t[0] - t[2]).norm();
                (i as u32, a, b)
            })
            .collect();
        let cell = edge / (3 * triangles.len()) as f64;
        let mut grid = BoxGrid::default();
        grid.build(lo, hi, cell, triangles.len(), boxes.into_iter());
        Some(TriangleGrid {
            triangles,
            query: RefCell::new((grid, Vec::new())),
        })
    }

    /// The first triangle the step `from → to` crosses, or `None`.
    pub fn crossing(&self, from: &V3, to: &V3) -> Option<Crossing> {
        let mut query = self.query.borrow_mut();
        let (grid, found) = &mut *query;
        grid.query(&from.inf(to), &from.sup(to), found);
        let mut best: Option<(f64, usize)> = None;
        for &t in found.iter() {
            let [a, b, c] = &self.triangles[t as usize];
            if let Some((s, _)) = segment_crosses_triangle(from, to, a, b, c) {
                if best.is_none_or(|(b, i)| s < b || (s == b && (t as usize) < i)) {
                    best = Some((s, t as usize));
                }
            }
        }
        let (s, t) = best?;
        let tri = &self.triangles[t];
        let step = to - from;
        let n = (tri[1] - tri[0])
            .cross(&(tri[2] - tri[0]))
            .try_normalize(1e-30)?;
        let normal = if n.dot(&step) > 0.0 { -n } else { n };
        Some(Crossing {
            point: from + step * s,
            normal,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_step_through_a_tilted_square_is_found_from_either_side() {
        let (a, b, c, d) = (
            V3::new(-1.0, 0.0, -1.0),
            V3::new(1.0, 0.2, -1.0),
            V3::new(1.0, 0.2, 1.0),
            V3::new(-1.0, 0.0, 1.0),
        );
        let grid = TriangleGrid::new(vec![[a, b, c], [a, c, d]]).unwrap();
        let down = grid
            .crossing(&V3::new(0.0, 0.5, 0.0), &V3::new(0.0, -0.5, 0.0))
            .unwrap();
        assert!((down.point.y - 0.1).abs() < 1e-12);
        assert!(
            down.normal.y > 0.9,
            "faces where it came from: {:?}",
            down.normal
        );
        let up = grid
            .crossing(&V3::new(0.3, -0.5, 0.2), &V3::new(0.3, 0.5, 0.2))
            .unwrap();
        assert!(up.normal.y < -0.9);
        assert!(grid
            .crossing(&V3::new(0.0, 0.5, 0.0), &V3::new(0.0, 0.2, 0.0))
            .is_none());
        assert!(grid
            .crossing(&V3::new(5.0, 0.5, 0.0), &V3::new(5.0, -0.5, 0.0))
            .is_none());
        assert!(TriangleGrid::new(Vec::new()).is_none());
    }
}
