//! The embedding of the display mesh in the lattice (physics §1, Terasawa eq 2.1–2.3): per
//! vertex the containing active cell and its 8 trilinear weights, computed once at rest. The
//! same weights move vertices with the nodes (`x' = Σ w_c x_c`, exact for any affine motion of
//! the cell) and spread a force at a surface point onto the nodes (Terasawa eq 3.43–3.47).

use super::{Lattice, CORNERS};
use nalgebra::{Point3, Vector3};

/// Cell and weights of every embedded point.
#[derive(Debug, Clone, PartialEq)]
pub struct Embedding {
    /// The 8 nodes of the containing cell, per point.
    pub nodes: Vec<[u32; 8]>,
    /// Trilinear weights per point (sum to 1).
    pub weights: Vec<[f64; 8]>,
}

impl Embedding {
    /// Embed `points` (world metres, rest pose) in `lattice`. A point is assigned to the active
    /// cell that contains it; on a shared face or edge any containing active cell gives the same
    /// position. A point outside every active cell (possible only for degenerate input) uses
    /// the nearest active cell and extrapolates, which is still exact for affine motion.
    pub fn new(lattice: &Lattice, points: &[Point3<f64>]) -> Embedding {
        let mut nodes = Vec::with_capacity(points.len());
        let mut weights = Vec::with_capacity(points.len());
        for p in points {
            let cell = containing_cell(lattice, p);
            let corner0 = lattice.rest_positions[lattice.cell_nodes[cell][0] as usize];
            let t: Vector3<f64> = (p - corner0) / lattice.cell_size;
            let mut w = [0.0; 8];
            for (c, off) in CORNERS.iter().enumerate() {
                let f = |a: usize| if off[a] == 1 { t[a] } else { 1.0 - t[a] };
                w[c] = f(0) * f(1) * f(2);
            }
            nodes.push(lattice.cell_nodes[cell]);
            weights.push(w);
        }
        Embedding { nodes, weights }
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Embedded point `i` for the given node positions.
    pub fn point(&self, i: usize, node_positions: &[Point3<f64>]) -> Point3<f64> {
        let mut acc = Vector3::zeros();
        for c in 0..8 {
            acc += node_positions[self.nodes[i][c] as usize].coords * self.weights[i][c];
        }
        Point3::from(acc)
    }

    /// All embedded points for the given node positions.
    pub fn points(&self, node_positions: &[Point3<f64>]) -> Vec<Point3<f64>> {
        (0..self.len())
            .map(|i| self.point(i, node_positions))
            .collect()
    }

    /// Spread a force acting at embedded point `i` onto the nodes (adds into `node_forces`).
    pub fn spread_force(&self, i: usize, force: Vector3<f64>, node_forces: &mut [Vector3<f64>]) {
        for c in 0..8 {
            node_forces[self.nodes[i][c] as usize] += force * self.weights[i][c];
        }
    }
}

fn containing_cell(lattice: &Lattice, p: &Point3<f64>) -> usize {
    let t = (p.coords - lattice.origin) / lattice.cell_size;
    // A point far outside the grid (a vertex no triangle uses lies outside the fitted bounds)
    // is clamped next to it first, so the neighbour offsets below cannot overflow.
    let base: [i64; 3] =
        std::array::from_fn(|a| t[a].floor().clamp(-2.0, f64::from(lattice.dims[a]) + 2.0) as i64);
    // The cell the point falls in, then neighbours it touches (points on shared faces, edges and
    // the grid's far boundary), then the nearest active cell.
    let mut best: Option<(f64, usize)> = None;
    for dz in [0i64, -1, 1] {
        for dy in [0i64, -1, 1] {
            for dx in [0i64, -1, 1] {
                let c = [base[0] + dx, base[1] + dy, base[2] + dz];
                if let Some(cell) = lattice.active_cell_at(c) {
                    let d = outside_distance(&t, c);
                    if d <= 1e-9 {
                        return cell;
                    }
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, cell));
                    }
                }
            }
        }
    }
    if let Some((_, cell)) = best {
        return cell;
    }
    // Far from any active cell: the nearest cell centre overall.
    let mut nearest = 0;
    let mut nearest_d = f64::INFINITY;
    for (i, c) in lattice.cells.iter().enumerate() {
        let centre = Vector3::new(c[0] as f64 + 0.5, c[1] as f64 + 0.5, c[2] as f64 + 0.5);
        let d = (centre - t).norm_squared();
        if d < nearest_d {
            nearest_d = d;
            nearest = i;
        }
    }
    nearest
}

/// How far (in cells) grid-space point `t` lies outside cell `c`.
fn outside_distance(t: &Vector3<f64>, c: [i64; 3]) -> f64 {
    (0..3)
        .map(|a| {
            let lo = c[a] as f64;
            (lo - t[a]).max(t[a] - (lo + 1.0)).max(0.0)
        })
        .fold(0.0, f64::max)
}
