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
        if self.stamp.len() < id_count {
            self.stamp.resize(id_count, 0);
        }
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
        out.clear();
        if self.starts.len() < 2 || self.items.is_empty() {
            return;
        }
        let region_hi = self.origin + self.dims_vec() / self.inv_cell;
        if (0..3).any(|a| hi[a] < self.origin[a] || lo[a] > region_hi[a]) {
            return;
        }
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.fill(0);
            self.epoch = 1;
        }
        let (c0, c1) = (self.cell_of(lo), self.cell_of(hi));
        for k in c0[2]..=c1[2] {
            for j in c0[1]..=c1[1] {
                for i in c0[0]..=c1[0] {
                    let c = self.index([i, j, k]);
                    for &id in &self.items[self.starts[c] as usize..self.starts[c + 1] as usize] {
                        let s = &mut self.stamp[id as usize];
                        if *s != self.epoch {
                            *s = self.epoch;
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
