//! The static colliders particles bounce off (issue 20: "bouncing off the floor, walls and
//! colliders"): their triangles in a uniform grid, and the first triangle a particle's step
//! crosses (`collide::geometry::segment_crosses_triangle` on the segment from where it was to
//! where it would be).

use crate::collide::geometry::segment_crosses_triangle;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// Most grid cells (the grid coarsens to stay under it).
const MAX_CELLS: usize = 1 << 20;

/// Triangles bucketed by the grid cells their bounding boxes overlap.
pub struct TriangleGrid {
    triangles: Vec<[V3; 3]>,
    origin: V3,
    cell: f64,
    dims: [usize; 3],
    /// Per cell, `start[c]..start[c + 1]` indexes `entries` (triangle indices).
    start: Vec<u32>,
    entries: Vec<u32>,
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
        for t in &triangles {
            for p in t {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
            edge += (t[1] - t[0]).norm() + (t[2] - t[1]).norm() + (t[0] - t[2]).norm();
        }
        let size = hi - lo;
        let mut cell = (edge / (3 * triangles.len()) as f64)
            .max(size.max() * 1e-3)
            .max(1e-6);
        let dims = loop {
            let d = size.map(|s| (s / cell).floor() as usize + 1);
            if d.x * d.y * d.z <= MAX_CELLS {
                break [d.x, d.y, d.z];
            }
            cell *= 2.0;
        };
        let mut grid = TriangleGrid {
            triangles,
            origin: lo,
            cell,
            dims,
            start: Vec::new(),
            entries: Vec::new(),
        };
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        for (i, t) in grid.triangles.iter().enumerate() {
            let (a, b) = (t[0].inf(&t[1]).inf(&t[2]), t[0].sup(&t[1]).sup(&t[2]));
            grid.for_cells(&a, &b, |c| buckets[c].push(i as u32));
        }
        grid.start.push(0);
        for b in buckets {
            grid.entries.extend(b);
            grid.start.push(grid.entries.len() as u32);
        }
        Some(grid)
    }

    /// Calls `f` with every cell index the box `lo..hi` overlaps (clamped to the grid).
    fn for_cells(&self, lo: &V3, hi: &V3, mut f: impl FnMut(usize)) {
        let index = |p: &V3, k: usize| -> usize {
            (((p[k] - self.origin[k]) / self.cell).floor().max(0.0) as usize).min(self.dims[k] - 1)
        };
        let (i0, i1) = ((0..3).map(|k| index(lo, k)), (0..3).map(|k| index(hi, k)));
        let (a, b): (Vec<usize>, Vec<usize>) = (i0.collect(), i1.collect());
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    f(x + self.dims[0] * (y + self.dims[1] * z));
                }
            }
        }
    }

    /// The first triangle the step `from → to` crosses, or `None`. A box wholly outside the
    /// grid's bounds is not searched.
    pub fn crossing(&self, from: &V3, to: &V3) -> Option<Crossing> {
        let (lo, hi) = (from.inf(to), from.sup(to));
        let far = self.origin
            + V3::new(
                self.dims[0] as f64,
                self.dims[1] as f64,
                self.dims[2] as f64,
            ) * self.cell;
        if (0..3).any(|k| hi[k] < self.origin[k] || lo[k] > far[k]) {
            return None;
        }
        let step = to - from;
        let mut best: Option<(f64, usize)> = None;
        self.for_cells(&lo, &hi, |cell| {
            let bucket = self.start[cell] as usize..self.start[cell + 1] as usize;
            for &t in &self.entries[bucket] {
                let [a, b, c] = &self.triangles[t as usize];
                if let Some((s, _)) = segment_crosses_triangle(from, to, a, b, c) {
                    if best.is_none_or(|(b, i)| s < b || (s == b && (t as usize) < i)) {
                        best = Some((s, t as usize));
                    }
                }
            }
        });
        let (s, t) = best?;
        let tri = &self.triangles[t];
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
