//! A uniform grid over axis-aligned boxes (the broad phase): built over a region by counting
//! sort (two passes, buffers reused, so rebuilding it every step allocates nothing once warm),
//! queried with a box. Building costs O(boxes + cells), a query O(cells it spans + items found);
//! the cell count is capped at a few per box, so memory and time grow linearly with the number
//! of boxes in the region. Everything is serial and in index order: deterministic.

use nalgebra::Vector3;

/// Most cells per box inserted (the grid coarsens beyond it).
const CELLS_PER_BOX: usize = 4;
/// Most cells along one axis.
const MAX_AXIS: usize = 512;

#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoxGrid {
    origin: Vector3<f64>,
    inv_cell: f64,
    dims: [usize; 3],
    /// Per cell, where its items start in `items` (one more entry than cells).
    starts: Vec<u32>,
    items: Vec<u32>,
    /// Per inserted box: item id and its clipped cell range.
    entries: Vec<(u32, [usize; 3], [usize; 3])>,
    /// Per item id: the query that last reported it (deduplication).
    stamp: Vec<u32>,
    /// Scratch: the boxes overlapping the region, and the fill cursor per cell.
    raw: Vec<(u32, Vector3<f64>, Vector3<f64>)>,
    fill: Vec<u32>,
    epoch: u32,
    /// The most ids any build was told of (`stamp` grows to it at a query).
    id_count: usize,
}

/// Which ids a query has reported already ([`BoxGrid::query_marked`]): a stamp per id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QueryMarks {
    stamp: Vec<u32>,
    epoch: u32,
}

impl BoxGrid {
    /// Rebuild over `[lo, hi]` with cells of about `cell` metres (coarser if the region would
    /// need more than a few cells per box), inserting the boxes `(id, lo, hi)` that overlap
    /// the region; ids must be below `id_count`.
    pub fn build(
        &mut self,
        lo: Vector3<f64>,
        hi: Vector3<f64>,
        cell: f64,
        id_count: usize,
        boxes: impl Iterator<Item = (u32, Vector3<f64>, Vector3<f64>)>,
    ) {
        self.entries.clear();
        self.items.clear();
        let extent = (hi - lo).map(|e| e.max(0.0));
        let mut cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            extent.max().max(1e-9)
        };
        // Collect the overlapping boxes first (their count bounds the cell count).
        let mut kept = std::mem::take(&mut self.entries);
        let mut raw = std::mem::take(&mut self.raw);
        raw.clear();
        for (id, blo, bhi) in boxes {
            if (0..3).all(|a| blo[a] <= hi[a] && bhi[a] >= lo[a]) {
                raw.push((id, blo, bhi));
            }
        }
        let budget = (CELLS_PER_BOX * raw.len()).max(8) as f64;
        loop {
            let cells: f64 = (0..3)
                .map(|a| ((extent[a] / cell).floor() + 1.0).min(MAX_AXIS as f64))
                .product();
            if cells <= budget {
                break;
            }
            cell *= 1.5;
        }
        self.origin = lo;
        self.inv_cell = 1.0 / cell;
        for a in 0..3 {
            self.dims[a] = ((extent[a] / cell).floor() as usize + 1).min(MAX_AXIS);
        }
        let n_cells = self.dims[0] * self.dims[1] * self.dims[2];
        self.starts.clear();
        self.starts.resize(n_cells + 1, 0);
        kept.clear();
        for &(id, blo, bhi) in &raw {
            let (c0, c1) = (self.cell_of(&blo), self.cell_of(&bhi));
            kept.push((id, c0, c1));
            for k in c0[2]..=c1[2] {
                for j in c0[1]..=c1[1] {
                    for i in c0[0]..=c1[0] {
                        let c = self.index([i, j, k]);
                        self.starts[c + 1] += 1;
                    }
                }
            }
        }
        for c in 0..n_cells {
            self.starts[c + 1] += self.starts[c];
        }
        self.items.resize(self.starts[n_cells] as usize, 0);
        let mut fill = std::mem::take(&mut self.fill);
        fill.clear();
        fill.extend_from_slice(&self.starts);
        for &(id, c0, c1) in &kept {
            for k in c0[2]..=c1[2] {
                for j in c0[1]..=c1[1] {
                    for i in c0[0]..=c1[0] {
                        let c = self.index([i, j, k]);
                        self.items[fill[c] as usize] = id;
                        fill[c] += 1;
                    }
                }
            }
        }
        self.fill = fill;
        self.raw = raw;
        self.entries = kept;
        self.id_count = self.id_count.max(id_count);
    }

    fn cell_of(&self, p: &Vector3<f64>) -> [usize; 3] {
        let mut c = [0usize; 3];
        for a in 0..3 {
            // `as` truncates (the floor of a non-negative value) and saturates: a negative or
            // NaN offset reads as cell 0 (and no libm `floor` call on the hot path).
            let t = (p[a] - self.origin[a]) * self.inv_cell;
            c[a] = (t as usize).min(self.dims[a] - 1);
        }
        c
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// The ids of the boxes in the cells `[lo, hi]` overlaps, each once, into `out` (cleared
    /// first), in cell order.
    pub fn query(&mut self, lo: &Vector3<f64>, hi: &Vector3<f64>, out: &mut Vec<u32>) {
        let mut marks = QueryMarks {
            stamp: std::mem::take(&mut self.stamp),
            epoch: self.epoch,
        };
        self.query_marked(lo, hi, out, &mut marks);
        (self.stamp, self.epoch) = (marks.stamp, marks.epoch);
    }

    /// [`Self::query`] on a shared grid, deduplicating with the caller's `marks` (so several
    /// threads can query one grid, each with its own marks): the same ids in the same order.
    pub fn query_marked(
        &self,
        lo: &Vector3<f64>,
        hi: &Vector3<f64>,
        out: &mut Vec<u32>,
        marks: &mut QueryMarks,
    ) {
        out.clear();
        if self.starts.len() < 2 || self.items.is_empty() {
            return;
        }
        let region_hi = self.origin + self.dims_vec() / self.inv_cell;
        if (0..3).any(|a| hi[a] < self.origin[a] || lo[a] > region_hi[a]) {
            return;
        }
        if marks.stamp.len() < self.id_count {
            marks.stamp.resize(self.id_count, 0);
        }
        marks.epoch = marks.epoch.wrapping_add(1);
        if marks.epoch == 0 {
            marks.stamp.fill(0);
            marks.epoch = 1;
        }
        let (c0, c1) = (self.cell_of(lo), self.cell_of(hi));
        for k in c0[2]..=c1[2] {
            for j in c0[1]..=c1[1] {
                for i in c0[0]..=c1[0] {
                    let c = self.index([i, j, k]);
                    for &id in &self.items[self.starts[c] as usize..self.starts[c + 1] as usize] {
                        let s = &mut marks.stamp[id as usize];
                        if *s != marks.epoch {
                            *s = marks.epoch;
                            out.push(id);
                        }
                    }
                }
            }
        }
    }

    fn dims_vec(&self) -> Vector3<f64> {
        Vector3::new(
            self.dims[0] as f64,
            self.dims[1] as f64,
            self.dims[2] as f64,
        )
    }

    /// Boxes inserted at the last build.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_exactly_the_overlapping_boxes_once() {
        // A row of unit boxes along x; a query box over 2.5..4.5 finds boxes 2, 3, 4.
        let boxes: Vec<(u32, Vector3<f64>, Vector3<f64>)> = (0..10)
            .map(|i| {
                let lo = Vector3::new(i as f64, 0.0, 0.0);
                (i, lo, lo + Vector3::repeat(1.0))
            })
            .collect();
        let mut g = BoxGrid::default();
        g.build(
            Vector3::zeros(),
            Vector3::new(10.0, 1.0, 1.0),
            0.5,
            10,
            boxes.iter().copied(),
        );
        assert_eq!(g.len(), 10);
        let mut out = Vec::new();
        g.query(
            &Vector3::new(2.5, 0.2, 0.2),
            &Vector3::new(4.5, 0.4, 0.4),
            &mut out,
        );
        out.sort();
        // Cells are at least 0.5 m; neighbours sharing a cell may be reported (a superset).
        assert!(
            out.contains(&2) && out.contains(&3) && out.contains(&4),
            "{out:?}"
        );
        assert!(out.len() <= 6, "{out:?}");
        let mut unique = out.clone();
        unique.dedup();
        assert_eq!(unique, out);
        g.query(
            &Vector3::new(20.0, 0.0, 0.0),
            &Vector3::new(21.0, 1.0, 1.0),
            &mut out,
        );
        assert!(out.is_empty());
    }

    #[test]
    fn a_query_with_its_own_marks_finds_the_same_ids_in_the_same_order() {
        // Boxes of 0.3 m scattered over a 2 m cube (spanning several cells each); queries of
        // all sizes, with the grid's marks and with two callers' own, interleaved.
        let mut rng = fastrand::Rng::with_seed(7);
        let mut next = move || rng.f64();
        let boxes: Vec<(u32, Vector3<f64>, Vector3<f64>)> = (0..300)
            .map(|i| {
                let lo = Vector3::new(next(), next(), next()) * 2.0;
                (i, lo, lo + Vector3::repeat(0.3))
            })
            .collect();
        let mut g = BoxGrid::default();
        g.build(
            Vector3::zeros(),
            Vector3::repeat(2.3),
            0.2,
            300,
            boxes.into_iter(),
        );
        let (mut first, mut second) = (QueryMarks::default(), QueryMarks::default());
        let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
        let mut found = 0;
        for _ in 0..200 {
            let lo = Vector3::new(next(), next(), next()) * 2.0;
            let hi = lo + Vector3::repeat(next() * 0.8);
            g.query(&lo, &hi, &mut a);
            g.query_marked(&lo, &hi, &mut b, &mut first);
            g.query_marked(&lo, &hi, &mut c, &mut second);
            assert_eq!(a, b);
            assert_eq!(a, c);
            found += a.len();
        }
        // The queries found boxes (hundreds of ids in all), not only empty lists.
        assert!(found > 1000, "{found}");
    }

    #[test]
    fn region_clips_the_boxes_and_cells_stay_bounded() {
        let boxes = (0..1000u32).map(|i| {
            let lo = Vector3::new(i as f64 * 0.01, 0.0, 0.0);
            (i, lo, lo + Vector3::repeat(0.01))
        });
        let mut g = BoxGrid::default();
        g.build(
            Vector3::zeros(),
            Vector3::new(1.0, 0.01, 0.01),
            1e-6,
            1000,
            boxes,
        );
        assert_eq!(g.len(), 101, "boxes 0..=100 touch [0, 1]");
        assert!(g.starts.len() <= CELLS_PER_BOX * 101 + 2);
    }
}
