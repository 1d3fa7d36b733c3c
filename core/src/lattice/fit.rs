//! Lattice auto-fit: the cubic cells that the surface passes through or that lie inside it.
//!
//! 1. Grid: cell edge from the resolution; the grid covers the mesh's bounding box, centred on
//!    the horizontal axes and aligned to the box's bottom along up (so a body resting on its
//!    lattice's bottom nodes shows its lowest vertex on the floor), except that a mesh thinner
//!    than a cell along up is centred in its cells there too: the cells of a rod or plank
//!    lying in one layer of them balance where it does, not up to half a cell above it (a rod
//!    at the bottom of its cells rolled to and fro like a top-heavy thing).
//! 2. Surface cells: exact triangle–box overlap (separating-axis test, Akenine-Möller) of every
//!    triangle against the cells of its bounding box, boxes grown by a hair so touching counts.
//! 3. Interior: the non-surface cells split into face-connected regions; each region is inside
//!    when the generalised winding number (Jacobson et al. 2013) at its sample cells averages
//!    above ½ in magnitude (a mesh with flipped normals winds −1 inside). That is robust for
//!    open, non-manifold and self-intersecting meshes, and costs one winding-number
//!    evaluation per region sample instead of one per cell.
//! 4. Nodes are the corners of active cells (shared between neighbours); springs per
//!    [`SpringLayout`]; islands are the connected components of the spring graph.

use super::{Lattice, Spring, SpringLayout};
use nalgebra::{Point3, Vector3};
use std::collections::VecDeque;

/// How fine the lattice is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Resolution {
    /// Cells along the longest side of the bounding box.
    CellsAlongLongest(u32),
    /// Cell edge in metres.
    CellSize(f64),
}

/// Everything [`fit_lattice`] needs besides the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitSettings {
    pub resolution: Resolution,
    pub layout: SpringLayout,
    /// Index of the up axis (0, 1 or 2): the grid's bottom is aligned with the mesh's lowest
    /// point (a mesh thinner than a cell along it is centred in its cells instead).
    pub up_index: usize,
    /// Refuse lattices whose estimated memory exceeds this many bytes.
    pub memory_limit_bytes: u64,
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            resolution: Resolution::CellsAlongLongest(10),
            layout: SpringLayout::FaceDiagonals,
            up_index: 1,
            memory_limit_bytes: 8 << 30,
        }
    }
}

/// Why a lattice could not be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("the mesh has no triangles")]
    EmptyMesh,
    #[error("vertex {vertex} has a non-finite coordinate {value:?}")]
    NonFinite { vertex: usize, value: [f64; 3] },
    #[error("triangle {triangle} refers to vertex {index}, but the mesh has {count} vertices")]
    BadIndex {
        triangle: usize,
        index: u32,
        count: usize,
    },
    #[error("resolution must be positive and finite, got {0}")]
    BadResolution(f64),
    #[error(
        "the mesh covers no area: its triangles are points or lines (extent {extent:?} m), so \
         no lattice cell holds it"
    )]
    Degenerate { extent: [f64; 3] },
    #[error(
        "a {nx}×{ny}×{nz}-cell grid needs about {estimate_mib} MiB, over the {limit_mib} MiB limit; use fewer cells"
    )]
    TooLarge {
        nx: u64,
        ny: u64,
        nz: u64,
        estimate_mib: u64,
        limit_mib: u64,
    },
}

/// Bytes per grid point and per node the fit and the solver need (grid maps, node state,
/// springs, cells, adjacency, the solver's prepared arrays); used for the up-front memory
/// estimate. Measured as peak resident memory over nodes (1.1–2.2 KB by integrator, 68 921
/// nodes, 2026-12-01; it was 400, 3.7× under what runs used).
const BYTES_PER_GRID_POINT: u64 = 8;
pub const BYTES_PER_NODE: u64 = 1500;

/// Fit a lattice around a triangle mesh given in world metres.
pub fn fit_lattice(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    settings: &FitSettings,
) -> Result<Lattice, FitError> {
    if triangles.is_empty() || positions.is_empty() {
        return Err(FitError::EmptyMesh);
    }
    for (vertex, p) in positions.iter().enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(FitError::NonFinite {
                vertex,
                value: [p.x, p.y, p.z],
            });
        }
    }
    for (triangle, t) in triangles.iter().enumerate() {
        if let Some(&index) = t.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(FitError::BadIndex {
                triangle,
                index,
                count: positions.len(),
            });
        }
    }
    let (lo, hi) = bounds(positions, triangles);
    let extent = hi - lo;
    // Triangles that are all points or segments have nothing a lattice could hold; cells
    // marked along a line of collinear vertices would simulate a mesh that is not there.
    let has_area = triangles.iter().any(|t| {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = (b - a).cross(&(c - a));
        n.norm() > 1e-12 * (b - a).norm_squared().max((c - a).norm_squared())
    });
    if !has_area {
        return Err(FitError::Degenerate {
            extent: [extent.x, extent.y, extent.z],
        });
    }
    let longest = extent.max();
    let cell = match settings.resolution {
        Resolution::CellsAlongLongest(n) => {
            if n == 0 {
                return Err(FitError::BadResolution(0.0));
            }
            if longest > 0.0 {
                longest / n as f64
            } else {
                1.0
            }
        }
        Resolution::CellSize(h) => {
            if !(h > 0.0 && h.is_finite()) {
                return Err(FitError::BadResolution(h));
            }
            h
        }
    };
    let mut dims = [0u64; 3];
    let mut origin = Vector3::zeros();
    for a in 0..3 {
        // A relative tolerance as large as a float32 coordinate's rounding keeps an extent of
        // n cells at n cells: the 0.6 m width of Blender's 1.2 m cylinder at 10 cells came
        // out 5.0000003 cells from its OBJ and 4.9999999 from its USD, and got 6 and 5.
        let n = ((extent[a] / cell) * (1.0 - 1e-6)).ceil().max(1.0);
        if !n.is_finite() || n > 1e7 {
            return Err(too_large([n as u64, 1, 1], settings));
        }
        dims[a] = n as u64;
        let span = n * cell;
        origin[a] = if a == settings.up_index && n > 1.0 {
            lo[a]
        } else {
            lo[a] - (span - extent[a]) / 2.0
        };
    }
    let grid_points = (dims[0] + 1) * (dims[1] + 1) * (dims[2] + 1);
    let estimate = grid_points * (BYTES_PER_GRID_POINT + BYTES_PER_NODE);
    if estimate > settings.memory_limit_bytes {
        return Err(too_large(dims, settings));
    }
    let dims = [dims[0] as u32, dims[1] as u32, dims[2] as u32];
    let grid = Grid { origin, cell, dims };

    let mut active = mark_surface_cells(&grid, positions, triangles);
    fill_interior(&grid, positions, triangles, &mut active);
    let lattice = build_lattice(&grid, &active, settings.layout);
    if lattice.cells.is_empty() {
        return Err(FitError::Degenerate {
            extent: [extent.x, extent.y, extent.z],
        });
    }
    Ok(lattice)
}

fn too_large(dims: [u64; 3], settings: &FitSettings) -> FitError {
    let points = (dims[0] + 1)
        .saturating_mul(dims[1] + 1)
        .saturating_mul(dims[2] + 1);
    FitError::TooLarge {
        nx: dims[0],
        ny: dims[1],
        nz: dims[2],
        estimate_mib: points.saturating_mul(BYTES_PER_GRID_POINT + BYTES_PER_NODE) >> 20,
        limit_mib: settings.memory_limit_bytes >> 20,
    }
}

fn bounds(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> (Vector3<f64>, Vector3<f64>) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for t in triangles {
        for &i in t {
            let p = positions[i as usize].coords;
            lo = lo.inf(&p);
            hi = hi.sup(&p);
        }
    }
    (lo, hi)
}

/// The regular grid the lattice lives on.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grid {
    pub origin: Vector3<f64>,
    pub cell: f64,
    pub dims: [u32; 3],
}

impl Grid {
    pub fn cell_count(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }
    pub fn cell_index(&self, c: [u32; 3]) -> usize {
        (c[0] as usize)
            + self.dims[0] as usize * (c[1] as usize + self.dims[1] as usize * c[2] as usize)
    }
    pub fn cell_coords(&self, i: usize) -> [u32; 3] {
        let nx = self.dims[0] as usize;
        let ny = self.dims[1] as usize;
        [
            (i % nx) as u32,
            ((i / nx) % ny) as u32,
            (i / (nx * ny)) as u32,
        ]
    }
    pub fn point_index(&self, p: [u32; 3]) -> usize {
        let nx = self.dims[0] as usize + 1;
        let ny = self.dims[1] as usize + 1;
        p[0] as usize + nx * (p[1] as usize + ny * p[2] as usize)
    }
    pub fn point_position(&self, p: [u32; 3]) -> Point3<f64> {
        Point3::from(self.origin + Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) * self.cell)
    }
    fn cell_range(&self, lo: f64, hi: f64, axis: usize) -> (u32, u32) {
        let to = |x: f64| ((x - self.origin[axis]) / self.cell).floor();
        let max = self.dims[axis] as f64 - 1.0;
        (to(lo).clamp(0.0, max) as u32, to(hi).clamp(0.0, max) as u32)
    }
}

fn mark_surface_cells(grid: &Grid, positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<bool> {
    let mut active = vec![false; grid.cell_count()];
    // Boxes shrunk by a hair, so a surface lying exactly on a grid plane does not mark the
    // cells on both sides of it. Such a triangle marks nothing at first; it is then nudged a
    // hair to its back (inner) side, or to its front where the back is outside the grid (a
    // flat mesh on the grid's boundary), and marks the cells there.
    let shrunk = Vector3::repeat(grid.cell * 0.5 * (1.0 - 1e-7));
    for t in triangles {
        let v = [
            positions[t[0] as usize].coords,
            positions[t[1] as usize].coords,
            positions[t[2] as usize].coords,
        ];
        if mark_triangle(grid, &v, &shrunk, &mut active) {
            continue;
        }
        let n = (v[1] - v[0]).cross(&(v[2] - v[0]));
        let nudge = if n.norm() > 0.0 {
            n.normalize() * (grid.cell * 1e-4)
        } else {
            Vector3::zeros()
        };
        for offset in [-nudge, nudge] {
            let moved = [v[0] + offset, v[1] + offset, v[2] + offset];
            if mark_triangle(grid, &moved, &shrunk, &mut active) {
                break;
            }
        }
    }
    active
}

/// Mark the cells whose box (half extent `half`) overlaps the triangle; true if any overlapped.
fn mark_triangle(
    grid: &Grid,
    v: &[Vector3<f64>; 3],
    half: &Vector3<f64>,
    active: &mut [bool],
) -> bool {
    let lo = v[0].inf(&v[1]).inf(&v[2]);
    let hi = v[0].sup(&v[1]).sup(&v[2]);
    let eps = grid.cell * 1e-6;
    let rx = grid.cell_range(lo.x - eps, hi.x + eps, 0);
    let ry = grid.cell_range(lo.y - eps, hi.y + eps, 1);
    let rz = grid.cell_range(lo.z - eps, hi.z + eps, 2);
    let mut any = false;
    for k in rz.0..=rz.1 {
        for j in ry.0..=ry.1 {
            for i in rx.0..=rx.1 {
                let idx = grid.cell_index([i, j, k]);
                let centre =
                    grid.point_position([i, j, k]).coords + Vector3::repeat(grid.cell * 0.5);
                if triangle_box_overlap(&centre, half, v) {
                    active[idx] = true;
                    any = true;
                }
            }
        }
    }
    any
}

/// Separating-axis triangle–box test (Akenine-Möller 2001).
fn triangle_box_overlap(
    centre: &Vector3<f64>,
    half: &Vector3<f64>,
    tri: &[Vector3<f64>; 3],
) -> bool {
    let v = [tri[0] - centre, tri[1] - centre, tri[2] - centre];
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let separated_on = |axis: Vector3<f64>| {
        let p = [axis.dot(&v[0]), axis.dot(&v[1]), axis.dot(&v[2])];
        let r = half.x * axis.x.abs() + half.y * axis.y.abs() + half.z * axis.z.abs();
        p.iter().cloned().fold(f64::INFINITY, f64::min) > r
            || p.iter().cloned().fold(f64::NEG_INFINITY, f64::max) < -r
    };
    for edge in &e {
        for a in 0..3 {
            let mut unit = Vector3::zeros();
            unit[a] = 1.0;
            let axis = unit.cross(edge);
            if axis.norm_squared() > 0.0 && separated_on(axis) {
                return false;
            }
        }
    }
    for a in 0..3 {
        let mut unit = Vector3::zeros();
        unit[a] = 1.0;
        if separated_on(unit) {
            return false;
        }
    }
    let normal = e[0].cross(&e[1]);
    !(normal.norm_squared() > 0.0 && separated_on(normal))
}

/// Generalised winding number of point `q` (Van Oosterom–Strackee solid angles / 4π).
pub(crate) fn winding_number(
    q: &Vector3<f64>,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let a = positions[t[0] as usize].coords - q;
        let b = positions[t[1] as usize].coords - q;
        let c = positions[t[2] as usize].coords - q;
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let det = a.dot(&b.cross(&c));
        let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * det.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

fn fill_interior(
    grid: &Grid,
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    active: &mut [bool],
) {
    let n = grid.cell_count();
    let mut region = vec![u32::MAX; n];
    let mut queue = VecDeque::new();
    let mut next_region = 0u32;
    for start in 0..n {
        if active[start] || region[start] != u32::MAX {
            continue;
        }
        let mut members = Vec::new();
        region[start] = next_region;
        queue.push_back(start);
        while let Some(c) = queue.pop_front() {
            members.push(c);
            let [i, j, k] = grid.cell_coords(c);
            let neighbours = [
                (i > 0).then(|| [i - 1, j, k]),
                (i + 1 < grid.dims[0]).then(|| [i + 1, j, k]),
                (j > 0).then(|| [i, j - 1, k]),
                (j + 1 < grid.dims[1]).then(|| [i, j + 1, k]),
                (k > 0).then(|| [i, j, k - 1]),
                (k + 1 < grid.dims[2]).then(|| [i, j, k + 1]),
            ];
            for nb in neighbours.into_iter().flatten() {
                let idx = grid.cell_index(nb);
                if !active[idx] && region[idx] == u32::MAX {
                    region[idx] = next_region;
                    queue.push_back(idx);
                }
            }
        }
        // Sample a few cells spread over the region; average their winding numbers.
        let samples = [0, members.len() / 2, members.len() - 1];
        let mut w = 0.0;
        for &s in &samples {
            let c = grid.cell_coords(members[s]);
            let centre = grid.point_position(c).coords + Vector3::repeat(grid.cell * 0.5);
            w += winding_number(&centre, positions, triangles);
        }
        // The magnitude: a mesh whose faces all wind the other way (flipped normals, a
        // mirrored object exported without reordering) reads −1 inside, and is as solid.
        if (w / samples.len() as f64).abs() > 0.5 {
            for &m in &members {
                active[m] = true;
            }
        }
        next_region += 1;
    }
}

/// Local corner offsets; corner `c` is `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`.
pub const CORNERS: [[u32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [1, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [0, 1, 1],
    [1, 1, 1],
];

fn build_lattice(grid: &Grid, active: &[bool], layout: SpringLayout) -> Lattice {
    let npts =
        (grid.dims[0] as usize + 1) * (grid.dims[1] as usize + 1) * (grid.dims[2] as usize + 1);
    let mut node_of_point = vec![u32::MAX; npts];
    let mut node_grid = Vec::new();
    let mut cells = Vec::new();
    let mut cell_nodes = Vec::new();
    // Nodes numbered in grid order of first use by active cells (cells in grid order): deterministic.
    for (ci, _) in active.iter().enumerate().filter(|(_, &on)| on) {
        let c = grid.cell_coords(ci);
        let mut corners = [0u32; 8];
        for (slot, off) in CORNERS.iter().enumerate() {
            let p = [c[0] + off[0], c[1] + off[1], c[2] + off[2]];
            let pi = grid.point_index(p);
            if node_of_point[pi] == u32::MAX {
                node_of_point[pi] = node_grid.len() as u32;
                node_grid.push(p);
            }
            corners[slot] = node_of_point[pi];
        }
        cells.push(c);
        cell_nodes.push(corners);
    }
    // Springs: pairs of local corners per cell; shared edges/faces deduplicated afterwards.
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7), // x
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7), // y
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7), // z
    ];
    // One diagonal per face, the one from the face's low-low corner to its high-high corner, so a
    // face shared by two cells gets the same diagonal from both.
    const FACE_DIAGONALS: [(usize, usize); 6] = [
        (0, 3),
        (4, 7), // z = 0 / 1 faces (xy)
        (0, 5),
        (2, 7), // y = 0 / 1 faces (xz)
        (0, 6),
        (1, 7), // x = 0 / 1 faces (yz)
    ];
    const BODY_DIAGONALS: [(usize, usize); 4] = [(0, 7), (1, 6), (2, 5), (3, 4)];
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for corners in &cell_nodes {
        let mut push = |list: &[(usize, usize)]| {
            for &(a, b) in list {
                let (x, y) = (corners[a], corners[b]);
                pairs.push((x.min(y), x.max(y)));
            }
        };
        push(&EDGES);
        if matches!(layout, SpringLayout::FaceDiagonals | SpringLayout::Both) {
            push(&FACE_DIAGONALS);
        }
        if matches!(layout, SpringLayout::BodyDiagonals | SpringLayout::Both) {
            push(&BODY_DIAGONALS);
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let rest_positions: Vec<Point3<f64>> =
        node_grid.iter().map(|&p| grid.point_position(p)).collect();
    let springs = pairs
        .into_iter()
        .map(|(a, b)| Spring {
            a,
            b,
            rest_length: (rest_positions[a as usize] - rest_positions[b as usize]).norm(),
        })
        .collect();
    Lattice::from_parts(
        grid.origin,
        grid.cell,
        grid.dims,
        cells,
        cell_nodes,
        rest_positions,
        springs,
    )
}
