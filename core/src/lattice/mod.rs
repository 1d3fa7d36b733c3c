//! The analysis lattice: auto-fit of a cubic mass-spring lattice around a display mesh
//! ([`fit`]) and the trilinear embedding of the mesh in it ([`embed`]).

use serde::{Deserialize, Serialize};

/// Which springs each cell carries (Miyazaki Fig. 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SpringLayout {
    /// Cell edges + one diagonal per square face: the fewest springs (Table 1).
    #[default]
    FaceDiagonals,
    /// Cell edges + the four body diagonals.
    BodyDiagonals,
    /// Cell edges + face diagonals + body diagonals.
    Both,
}

pub mod embed;
pub mod fill;
pub mod fit;
pub mod surface;

pub use embed::Embedding;
pub use fit::{fit_lattice, FitError, FitSettings, Resolution, BYTES_PER_NODE, CORNERS};
pub use surface::{surface_samples, surface_samples_with_normals, SurfaceSamples, VERTEX_CLUSTER};

use nalgebra::{Point3, Vector3};

/// A spring between two nodes (indices into the lattice's nodes) with its natural length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    pub a: u32,
    pub b: u32,
    pub rest_length: f64,
}

/// A fitted cubic lattice in world metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Lattice {
    /// World position of grid point (0, 0, 0).
    pub origin: Vector3<f64>,
    /// Cell edge, metres.
    pub cell_size: f64,
    /// Grid size in cells.
    pub dims: [u32; 3],
    /// Grid coordinates of the active cells, in grid order.
    pub cells: Vec<[u32; 3]>,
    /// The 8 nodes of each active cell, corner order of [`CORNERS`].
    pub cell_nodes: Vec<[u32; 8]>,
    /// Rest position of each node.
    pub rest_positions: Vec<Point3<f64>>,
    pub springs: Vec<Spring>,
    /// Island (connected component) of each node.
    pub island_of_node: Vec<u32>,
    pub island_count: usize,
    /// Active cell index per grid cell (`u32::MAX` where inactive), for embedding look-ups.
    cell_lookup: Vec<u32>,
}

impl Lattice {
    pub(crate) fn from_parts(
        origin: Vector3<f64>,
        cell_size: f64,
        dims: [u32; 3],
        cells: Vec<[u32; 3]>,
        cell_nodes: Vec<[u32; 8]>,
        rest_positions: Vec<Point3<f64>>,
        springs: Vec<Spring>,
    ) -> Lattice {
        let (island_of_node, island_count) = islands(rest_positions.len(), &springs);
        let grid = fit::Grid {
            origin,
            cell: cell_size,
            dims,
        };
        let mut cell_lookup = vec![u32::MAX; grid.cell_count()];
        for (i, c) in cells.iter().enumerate() {
            cell_lookup[grid.cell_index(*c)] = i as u32;
        }
        Lattice {
            origin,
            cell_size,
            dims,
            cells,
            cell_nodes,
            rest_positions,
            springs,
            island_of_node,
            island_count,
            cell_lookup,
        }
    }

    pub fn node_count(&self) -> usize {
        self.rest_positions.len()
    }

    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Total volume of the active cells, m³.
    pub fn volume(&self) -> f64 {
        self.cells.len() as f64 * self.cell_size.powi(3)
    }

    /// The active cell at grid coordinates `c`, if any.
    pub fn active_cell_at(&self, c: [i64; 3]) -> Option<usize> {
        if (0..3).any(|a| c[a] < 0 || c[a] >= self.dims[a] as i64) {
            return None;
        }
        let idx = c[0] as usize
            + self.dims[0] as usize * (c[1] as usize + self.dims[1] as usize * c[2] as usize);
        let cell = self.cell_lookup[idx];
        (cell != u32::MAX).then_some(cell as usize)
    }

    /// Number of cells with a non-positive signed volume in any of their 8 corner tetrahedra,
    /// for the given node positions.
    pub fn inverted_cells(&self, positions: &[Point3<f64>]) -> usize {
        self.cell_nodes
            .iter()
            .filter(|nodes| cell_is_inverted(nodes, positions))
            .count()
    }
}

/// A cell is inverted when any corner tetrahedron (the corner and its three axis neighbours,
/// taken right-handed) has non-positive signed volume.
pub fn cell_is_inverted(nodes: &[u32; 8], positions: &[Point3<f64>]) -> bool {
    let p = |c: usize| positions[nodes[c] as usize];
    (0..8).any(|c| {
        let nx = c ^ 1;
        let ny = c ^ 2;
        let nz = c ^ 4;
        let ex = p(nx) - p(c);
        let ey = p(ny) - p(c);
        let ez = p(nz) - p(c);
        // Mirrored corners flip the handedness of (ex, ey, ez); compensate with the parity.
        let parity = ((c & 1) + ((c >> 1) & 1) + ((c >> 2) & 1)) % 2;
        let vol = ex.dot(&ey.cross(&ez));
        let signed = if parity == 0 { vol } else { -vol };
        signed <= 0.0
    })
}

fn islands(nodes: usize, springs: &[Spring]) -> (Vec<u32>, usize) {
    connected_components(nodes, springs.iter().map(|s| (s.a, s.b)))
}

/// The connected components of a graph of `nodes` nodes and `edges`: each node's component,
/// numbered from 0 in the order of their lowest node, and how many there are (union–find).
pub(crate) fn connected_components(
    nodes: usize,
    edges: impl IntoIterator<Item = (u32, u32)>,
) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..nodes as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for (a, b) in edges {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    let mut label = vec![u32::MAX; nodes];
    let mut component = vec![0; nodes];
    let mut count = 0u32;
    for n in 0..nodes as u32 {
        let r = find(&mut parent, n);
        if label[r as usize] == u32::MAX {
            label[r as usize] = count;
            count += 1;
        }
        component[n as usize] = label[r as usize];
    }
    (component, count as usize)
}
