//! How much of each lattice cell the mesh fills: the share of the cell's volume inside the
//! mesh, so a body's mass and stiffness are the mesh's, not its cells' (a sphere at 8 cells
//! across is 57 % heavier as whole cubes, and its centre of mass and inertia are a cube's).
//!
//! Each cell is sampled on an `S × S × S` grid of points (`S = 4`, doubled while the samples
//! and the enclosed volume disagree, within a budget: a rod or plate thinner than the sample
//! spacing is found at a finer one). Inside is the nonzero rule of the
//! mesh's winding number along a ray in +z: one line of samples per `(x, y)` sample position
//! of a grid column, the crossings of its triangles sorted once, each sample's winding the
//! sum of the signs (`n_z`) of the crossings above it. Overlapping closed parts are their
//! union. The sample lines sit off the cells' regular positions by an irrational fraction, so
//! a mesh whose edges or vertices lie on the lattice's planes (a box fitted to its cells) is
//! not crossed on an edge.
//!
//! The samples' volume is then matched to the enclosed volume by scaling the partly filled
//! cells' shares (on a coarse lattice the samples alone are a few per cent off).
//!
//! The rule only means something for a closed mesh: [`cell_fill`] gives `None` when the
//! sampled volume and the mesh's enclosed volume (divergence theorem) still disagree at the
//! finest sampling the budget allows, so an open sheet keeps whole cells.

use super::Lattice;
use nalgebra::{Point3, Vector3};

/// Samples per cell edge at first; doubled while the samples and the enclosed volume
/// disagree (a part thinner than the sample spacing: a rod or a plate a cell thick).
const FIRST_SAMPLES: usize = 4;
/// Most samples in all (cells × samples per cell) a refinement may take.
const SAMPLE_BUDGET: usize = 1 << 24;
/// Least share a cell keeps: a cell the mesh barely enters still holds its nodes together.
/// Where the mesh fills less than that of its cells on average (a thin rod in one row of
/// cells) the floor is that average, so the body still weighs its mesh. (A quarter, tried,
/// saved jelly 5–15 % of its substeps, but moved the bowling example's pins enough that all
/// three were knocked; not kept.)
pub const MIN_FILL: f64 = 0.1;
/// Largest disagreement between the sampled and the enclosed volume, relative, for a mesh to
/// count as closed.
const CLOSED_TOLERANCE: f64 = 0.05;

/// Per active cell of `lattice` (its order), the share of its volume inside the closed mesh
/// `positions`/`triangles` (world metres), at least [`MIN_FILL`] (or the mean share, if that
/// is less); `None` when the mesh is not closed (see the module docs).
pub fn cell_fill(
    lattice: &Lattice,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
) -> Option<Vec<f64>> {
    let enclosed = crate::cage::mesh_volume(positions, triangles).abs();
    if !(enclosed > 0.0 && enclosed.is_finite()) || lattice.cells.is_empty() {
        return None;
    }
    let h = lattice.cell_size;
    let columns = triangles_by_column(lattice, positions, triangles);
    let mut samples = FIRST_SAMPLES;
    let mut fill = loop {
        let fill = sampled_fill(lattice, positions, triangles, &columns, samples);
        let sampled = fill.iter().sum::<f64>() * h.powi(3);
        if (sampled - enclosed).abs() <= CLOSED_TOLERANCE * enclosed {
            break fill;
        }
        samples *= 2;
        if lattice.cells.len().saturating_mul(samples.pow(3)) > SAMPLE_BUDGET {
            return None;
        }
    };
    // The samples' share of a cell is only good to a few per cent on a coarse lattice (a
    // 4 × 4 grid of lines per cell across a cylinder's disc); the enclosed volume is exact,
    // so the partly filled cells share the difference.
    let whole = fill.iter().filter(|&&f| f >= 1.0).count() as f64;
    let partial: Vec<f64> = fill.iter().copied().filter(|&f| f < 1.0).collect();
    let target = enclosed / h.powi(3) - whole;
    let floor = MIN_FILL.min(target / partial.len().max(1) as f64);
    // The scale that brings the clamped shares to the target (their sum grows with it).
    let total = |scale: f64| -> f64 { partial.iter().map(|f| (f * scale).clamp(floor, 1.0)).sum() };
    let (mut lo, mut hi) = (0.0, 2.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if total(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    for f in fill.iter_mut().filter(|f| **f < 1.0) {
        *f = (*f * hi).clamp(floor, 1.0);
    }
    Some(fill)
}

/// The triangles by the grid columns (cells in x, y) their xy bounds touch.
fn triangles_by_column(
    lattice: &Lattice,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
) -> Vec<Vec<u32>> {
    let h = lattice.cell_size;
    let [nx, ny, _] = lattice.dims.map(|d| d as usize);
    let mut columns: Vec<Vec<u32>> = vec![Vec::new(); nx * ny];
    let column_of = |v: f64, a: usize, n: usize| {
        (((v - lattice.origin[a]) / h).floor().max(0.0) as usize).min(n - 1)
    };
    for (t, tri) in triangles.iter().enumerate() {
        let p = tri.map(|i| positions[i as usize]);
        let (lo_x, hi_x) = span(p.map(|q| q.x));
        let (lo_y, hi_y) = span(p.map(|q| q.y));
        let (i0, i1) = (column_of(lo_x, 0, nx), column_of(hi_x, 0, nx));
        let (j0, j1) = (column_of(lo_y, 1, ny), column_of(hi_y, 1, ny));
        for j in j0..=j1 {
            for i in i0..=i1 {
                columns[j * nx + i].push(t as u32);
            }
        }
    }
    columns
}

/// Per active cell, the share of its `samples³` sample points inside the mesh.
fn sampled_fill(
    lattice: &Lattice,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    columns: &[Vec<u32>],
    samples: usize,
) -> Vec<f64> {
    let h = lattice.cell_size;
    let nx = lattice.dims[0] as usize;
    // Active cells by column, bottom to top (cells are in grid order: x fastest).
    let mut cells_of: Vec<Vec<usize>> = vec![Vec::new(); columns.len()];
    for (c, coords) in lattice.cells.iter().enumerate() {
        cells_of[coords[1] as usize * nx + coords[0] as usize].push(c);
    }
    let mut inside = vec![0u32; lattice.cells.len()];
    let mut hits: Vec<(f64, i32)> = Vec::new();
    let offset = |m: usize, a: usize| (m as f64 + 0.5 + JITTER[a]) / samples as f64;
    for (column, cells) in cells_of.iter_mut().enumerate() {
        if cells.is_empty() {
            continue;
        }
        cells.sort_by_key(|&c| lattice.cells[c][2]);
        let (i, j) = (column % nx, column / nx);
        for mx in 0..samples {
            for my in 0..samples {
                let x = lattice.origin.x + (i as f64 + offset(mx, 0)) * h;
                let y = lattice.origin.y + (j as f64 + offset(my, 1)) * h;
                hits.clear();
                for &t in &columns[column] {
                    let p = triangles[t as usize].map(|v| positions[v as usize].coords);
                    if let Some(hit) = vertical_crossing(p, x, y) {
                        hits.push(hit);
                    }
                }
                hits.sort_by(|a, b| a.0.total_cmp(&b.0));
                // Winding above a height: the signs of the crossings above it.
                let mut above: i32 = hits.iter().map(|h| h.1).sum();
                let mut next = 0;
                for &c in cells.iter() {
                    let k = lattice.cells[c][2] as f64;
                    for mz in 0..samples {
                        let z = lattice.origin.z + (k + offset(mz, 2)) * h;
                        while next < hits.len() && hits[next].0 <= z {
                            above -= hits[next].1;
                            next += 1;
                        }
                        if above != 0 {
                            inside[c] += 1;
                        }
                    }
                }
            }
        }
    }
    let per_cell = samples.pow(3) as f64;
    inside.iter().map(|&n| n as f64 / per_cell).collect()
}

/// The sample lines' offsets within a sample spacing, per axis (irrational, small).
const JITTER: [f64; 3] = [0.0137_2519, 0.0093_8471, 0.0061_0293];

fn span(v: [f64; 3]) -> (f64, f64) {
    (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]))
}

/// Where the vertical line through `(x, y)` crosses triangle `p`: its height and the sign of
/// the triangle's normal's z (0-area triangles in xy are not crossed).
pub(crate) fn vertical_crossing(p: [Vector3<f64>; 3], x: f64, y: f64) -> Option<(f64, i32)> {
    let edge = |a: Vector3<f64>, b: Vector3<f64>| (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
    let (w0, w1, w2) = (edge(p[1], p[2]), edge(p[2], p[0]), edge(p[0], p[1]));
    let all_pos = w0 > 0.0 && w1 > 0.0 && w2 > 0.0;
    let all_neg = w0 < 0.0 && w1 < 0.0 && w2 < 0.0;
    if !(all_pos || all_neg) {
        return None;
    }
    let sum = w0 + w1 + w2;
    let z = (w0 * p[0].z + w1 * p[1].z + w2 * p[2].z) / sum;
    Some((z, if all_pos { 1 } else { -1 }))
}
