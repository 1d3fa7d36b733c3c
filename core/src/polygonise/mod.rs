//! Polygonising an implicit surface (a [`Model`]'s `field = threshold`) into a watertight,
//! consistently oriented triangle mesh, graded by curvature, that keeps every piece of surface
//! down to a quarter of the resolution (Terasawa §5.3's point: no thin part is dropped).
//!
//! 1. An octree over the model's bounds keeps only the cells whose field interval
//!    ([`Model::interval`]) holds the threshold, down to a base grid of the resolution or
//!    [`BASE_CELLS_ACROSS`] cells across the model, whichever is coarser: the surface's cells,
//!    without visiting the empty space.
//! 2. A base cell whose interval holds the threshold while its eight corners all lie on one
//!    side hides a piece of surface thinner than a cell (a thin plate, a sharp tip): then the
//!    whole grid is halved and the search runs again, down to a quarter of the resolution and
//!    while the finer grid stays within [`REFINE_CELLS`] (its surface cells grow fourfold);
//!    past that [`Surface::hidden_cells`] says how many cells may hide thin parts.
//! 3. Marching tetrahedra on those cells (each cube in the six Kuhn tetrahedra along its main
//!    diagonal, which neighbouring cubes split the same way): vertices on grid edges shared by
//!    key, so every edge of the mesh has exactly two triangles; each triangle faces away from
//!    its tetrahedron's inside corners. The vertices are then moved onto the surface.
//! 4. [`refine`]: edges are split where the surface bulges away from them by more than a
//!    [`TOLERANCE_PER_RESOLUTION`] of the resolution, down to edges of a quarter of it, so
//!    the mesh is fine where the surface bends and coarse where it is flat. Vertex normals
//!    are the field's gradient.

mod refine;

use crate::superquadric::Model;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::collections::HashMap;

type V3 = Vector3<f64>;

/// The base grid's cells across the model's largest extent, at most (a finer resolution is
/// reached by grading, not by a finer grid).
pub const BASE_CELLS_ACROSS: f64 = 128.0;
/// How far below the resolution the grid may be halved to catch surface hidden inside a
/// cell: a quarter of it.
pub const MAX_EXTRA_LEVELS: u32 = 2;
/// Most surface cells a polygonisation may keep (about 100 bytes each).
pub const MAX_CELLS: usize = 20_000_000;
/// The largest distance between the mesh's edges and the surface, as a fraction of the
/// resolution.
pub const TOLERANCE_PER_RESOLUTION: f64 = 0.05;
/// Most triangles grading may make.
pub const MAX_TRIANGLES: usize = 20_000_000;
/// Most surface cells a refinement for hidden surface may lead to.
pub const REFINE_CELLS: usize = 2_000_000;

/// A polygonised surface.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface {
    pub positions: Vec<[f64; 3]>,
    pub normals: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// The finest cell edge used, m.
    pub cell: f64,
    /// Cells that may still hide surface thinner than a cell (refinement stopped at its
    /// budget); 0 when none.
    pub hidden_cells: usize,
    /// Edges left coarser than the tolerance asks because grading reached
    /// [`MAX_TRIANGLES`]; 0 when none.
    pub ungraded_edges: usize,
}

struct Grid<'a> {
    model: &'a Model,
    origin: V3,
    h: f64,
    /// Points per side (cells + 1).
    side: u64,
    values: HashMap<u64, f64>,
}

impl Grid<'_> {
    fn point(&self, id: u64) -> V3 {
        let (i, j, k) = (
            id % self.side,
            (id / self.side) % self.side,
            id / (self.side * self.side),
        );
        self.origin + V3::new(i as f64, j as f64, k as f64) * self.h
    }

    /// Whether any grid point within one cell of the cell whose first corner is `first` is
    /// inside.
    fn inside_nearby(&mut self, first: u64) -> bool {
        let side = self.side;
        let (i, j, k) = (first % side, (first / side) % side, first / (side * side));
        let span = |c: u64| c.saturating_sub(1)..=(c + 2).min(side - 1);
        for z in span(k) {
            for y in span(j) {
                for x in span(i) {
                    if self.value(x + side * (y + side * z)) >= 0.0 {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Field minus threshold at grid point `id` (≥ 0 inside).
    fn value(&mut self, id: u64) -> f64 {
        if let Some(v) = self.values.get(&id) {
            return *v;
        }
        let v = self.model.field(&self.point(id)) - self.model.threshold();
        self.values.insert(id, v);
        v
    }
}

/// The surface cells at finest cell `h` over a cube of `n` cells per side from `origin`, and
/// whether any hides surface between its corners.
fn surface_cells(model: &Model, origin: V3, h: f64, n: u64) -> Result<Vec<[u64; 3]>, String> {
    let t = model.threshold();
    let mut out = Vec::new();
    let mut stack = vec![([0u64; 3], n)];
    while let Some((at, size)) = stack.pop() {
        let lo = origin + V3::new(at[0] as f64, at[1] as f64, at[2] as f64) * h;
        let hi = lo + V3::repeat(size as f64 * h);
        let (a, b) = model.interval(&lo, &hi);
        if !(a <= t && t <= b) {
            continue;
        }
        if size == 1 {
            out.push(at);
            if out.len() > MAX_CELLS {
                return Err(format!(
                    "more than {MAX_CELLS} surface cells at {h} m; use a coarser resolution"
                ));
            }
            continue;
        }
        let half = size / 2;
        for c in 0..8u64 {
            let child = [
                at[0] + (c & 1) * half,
                at[1] + ((c >> 1) & 1) * half,
                at[2] + ((c >> 2) & 1) * half,
            ];
            stack.push((child, half));
        }
    }
    out.sort_unstable_by_key(|c| (c[2], c[1], c[0]));
    Ok(out)
}

/// Polygonises `model` with cells of at most `resolution` metres.
pub fn polygonise(model: &Model, resolution: f64) -> Result<Surface, String> {
    if !(resolution.is_finite() && resolution > 0.0) {
        return Err(format!("resolution must be positive, got {resolution}"));
    }
    let (lo, hi) = model.bounds();
    let extent = (hi - lo).max();
    if (extent / resolution).log2() > 20.0 {
        return Err(format!(
            "resolution {resolution} m is too fine for a model {extent} m across"
        ));
    }
    let base = resolution.max(extent / BASE_CELLS_ACROSS);
    let mut levels = (extent / base).log2().ceil().max(1.0) as u32;
    let finest_levels = (extent / resolution).log2().ceil().max(1.0) as u32 + MAX_EXTRA_LEVELS;
    loop {
        let n = 1u64 << levels;
        let h = extent / n as f64;
        let cells = surface_cells(model, lo, h, n)?;
        let mut grid = Grid {
            model,
            origin: lo,
            h,
            side: n + 1,
            values: HashMap::new(),
        };
        let mut corner_ids = Vec::with_capacity(cells.len());
        for c in &cells {
            let ids: [u64; 8] = std::array::from_fn(|k| {
                let k = k as u64;
                let (i, j, l) = (c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + (k >> 2));
                i + grid.side * (j + grid.side * l)
            });
            for id in ids {
                grid.value(id);
            }
            corner_ids.push(ids);
        }
        // A cell whose corners are all outside but which holds an inside point hides a piece
        // of surface (all-inside cells by the surface are expected: the interval is loose).
        // Only a piece no sample around it sees: a surface bulging into a cell between its
        // corners (everywhere on a curved surface) has inside samples one cell away.
        let candidates: Vec<u64> = corner_ids
            .iter()
            .filter(|ids| {
                ids.iter().all(|&id| grid.values[&id] < 0.0)
                    && hidden_inside(model, &grid.point(ids[0]), h, HIDDEN_SEARCH_DEPTH)
            })
            .map(|ids| ids[0])
            .collect();
        let hiding = candidates
            .into_iter()
            .filter(|&first| !grid.inside_nearby(first))
            .count();
        if hiding > 0 && levels < finest_levels && cells.len() * 4 <= REFINE_CELLS {
            levels += 1;
            continue;
        }
        let mut surface = march(&mut grid, &corner_ids);
        surface.hidden_cells = hiding;
        let step = resolution * 0.01;
        surface.positions = surface
            .positions
            .par_iter()
            .map(|p| {
                let q = refine::project(model, V3::from(*p), step, h);
                [q.x, q.y, q.z]
            })
            .collect();
        surface.ungraded_edges = refine::refine(
            model,
            &mut surface.positions,
            &mut surface.triangles,
            refine::Grading {
                tolerance: resolution * TOLERANCE_PER_RESOLUTION,
                shortest_edge: resolution / 4.0,
                gradient_step: step,
                max_triangles: MAX_TRIANGLES,
            },
        );
        surface.normals = surface
            .positions
            .par_iter()
            .map(|p| {
                let g = model.gradient(&V3::from(*p), step);
                let n = if g.norm() > 0.0 {
                    -g.normalize()
                } else {
                    V3::z()
                };
                [n.x, n.y, n.z]
            })
            .collect();
        return Ok(surface);
    }
}

/// Halvings of a cell [`hidden_inside`] searches (a sixteenth of the cell).
const HIDDEN_SEARCH_DEPTH: u32 = 4;

/// Whether the cell at `p` (edge `h`) holds a point inside the surface: its interval, then its
/// centre, then its eight halves, `depth` times.
fn hidden_inside(model: &Model, p: &V3, h: f64, depth: u32) -> bool {
    let t = model.threshold();
    let (a, b) = model.interval(p, &(p + V3::repeat(h)));
    if !(a <= t && t <= b) {
        return false;
    }
    if model.field(&(p + V3::repeat(h * 0.5))) >= t {
        return true;
    }
    depth > 0
        && (0..8).any(|c| {
            let corner = V3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64);
            hidden_inside(model, &(p + corner * (h * 0.5)), h * 0.5, depth - 1)
        })
}

fn march(grid: &mut Grid, cells: &[[u64; 8]]) -> Surface {
    let mut surface = Surface {
        cell: grid.h,
        ..Surface::default()
    };
    let mut on_edge: HashMap<(u64, u64), u32> = HashMap::new();
    for ids in cells {
        // The six Kuhn tetrahedra of the cube (corner = x + 2y + 4z), as the volume term splits
        // a cell.
        for tet in crate::solver::volume::TETS {
            let v = tet.map(|c| ids[c]);
            let s = v.map(|id| grid.values[&id]);
            let inside: Vec<usize> = (0..4).filter(|&k| s[k] >= 0.0).collect();
            let outside: Vec<usize> = (0..4).filter(|&k| s[k] < 0.0).collect();
            let mut vertex = |a: usize, b: usize, surface: &mut Surface| -> u32 {
                let key = (v[a].min(v[b]), v[a].max(v[b]));
                *on_edge.entry(key).or_insert_with(|| {
                    let t = s[a] / (s[a] - s[b]);
                    let p = grid.point(v[a]) + (grid.point(v[b]) - grid.point(v[a])) * t;
                    surface.positions.push([p.x, p.y, p.z]);
                    surface.positions.len() as u32 - 1
                })
            };
            let inner = match inside.first() {
                Some(&k) => grid.point(v[k]),
                None => continue,
            };
            let emit = |tri: [u32; 3], surface: &mut Surface| {
                let [a, b, c] = tri.map(|i| V3::from(surface.positions[i as usize]));
                let normal = (b - a).cross(&(c - a));
                let centre = (a + b + c) / 3.0;
                if normal.dot(&(centre - inner)) < 0.0 {
                    surface.triangles.push([tri[0], tri[2], tri[1]]);
                } else {
                    surface.triangles.push(tri);
                }
            };
            match (inside.len(), outside.len()) {
                (1, 3) | (3, 1) => {
                    let (lone, others) = if inside.len() == 1 {
                        (inside[0], &outside)
                    } else {
                        (outside[0], &inside)
                    };
                    let tri = [
                        vertex(lone, others[0], &mut surface),
                        vertex(lone, others[1], &mut surface),
                        vertex(lone, others[2], &mut surface),
                    ];
                    emit(tri, &mut surface);
                }
                (2, 2) => {
                    let (i0, i1, o0, o1) = (inside[0], inside[1], outside[0], outside[1]);
                    let q = [
                        vertex(i0, o0, &mut surface),
                        vertex(i0, o1, &mut surface),
                        vertex(i1, o1, &mut surface),
                        vertex(i1, o0, &mut surface),
                    ];
                    emit([q[0], q[1], q[2]], &mut surface);
                    emit([q[0], q[2], q[3]], &mut surface);
                }
                _ => {}
            }
        }
    }
    surface
}

impl Surface {
    /// Enclosed volume (divergence theorem), m³.
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| V3::from(self.positions[i as usize]));
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Whether every edge is shared by exactly two triangles, once each way.
    pub fn is_watertight(&self) -> bool {
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        let mut uses: HashMap<(u32, u32), usize> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        edges.values().all(|&d| d == 0) && uses.values().all(|&u| u == 2)
    }

    /// Connected pieces of the mesh (by shared vertices).
    pub fn components(&self) -> usize {
        let n = self.positions.len();
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for t in &self.triangles {
            for k in 1..3 {
                let (a, b) = (
                    root(&mut parent, t[0] as usize),
                    root(&mut parent, t[k] as usize),
                );
                parent[a] = b;
            }
        }
        let used: std::collections::BTreeSet<usize> = self
            .triangles
            .iter()
            .flatten()
            .map(|&i| root(&mut parent, i as usize))
            .collect();
        used.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::superquadric::Superquadric;

    fn prim(center: [f64; 3], radii: [f64; 3], exponents: [f64; 2]) -> Superquadric {
        Superquadric {
            center,
            radii,
            exponents,
            rotation: [0.0; 3],
            weight: 1.0,
        }
    }

    #[test]
    fn an_ellipsoid_has_its_volume_and_is_watertight() {
        let m = Model::new(&[prim([0.0; 3], [0.3, 0.2, 0.1], [1.0, 1.0])], 0.5).unwrap();
        let s = polygonise(&m, 0.005).unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.3 * 0.2 * 0.1;
        assert!(
            (s.volume() / exact - 1.0).abs() < 0.01,
            "{} vs {exact}",
            s.volume()
        );
        assert!(s.is_watertight());
        assert_eq!(s.components(), 1);
    }

    #[test]
    fn triangles_are_small_where_the_surface_bends_and_large_where_it_is_flat() {
        // A lens: flat faces (radius of curvature 1.8 m at the poles), a rim of radius 8 mm.
        let m = Model::new(&[prim([0.0; 3], [0.3, 0.3, 0.05], [1.0, 1.0])], 0.5).unwrap();
        let resolution = 0.002;
        let s = polygonise(&m, resolution).unwrap();
        assert!(s.is_watertight());
        let edge = |zone: &dyn Fn(&V3) -> bool| {
            let mut lengths = Vec::new();
            for t in &s.triangles {
                let p = t.map(|i| V3::from(s.positions[i as usize]));
                if p.iter().all(zone) {
                    lengths.extend((0..3).map(|k| (p[k] - p[(k + 1) % 3]).norm()));
                }
            }
            assert!(!lengths.is_empty());
            lengths.iter().sum::<f64>() / lengths.len() as f64
        };
        let flat = edge(&|p| p.xy().norm() < 0.1);
        let rim = edge(&|p| p.xy().norm() > 0.29);
        assert!(flat > 2.0 * rim, "flat {flat} m against rim {rim} m");
        // Every edge's midpoint lies within the tolerance of the surface, or the edge is one
        // too short to split.
        let tolerance = resolution * TOLERANCE_PER_RESOLUTION;
        for t in &s.triangles {
            for k in 0..3 {
                let (a, b) = (
                    V3::from(s.positions[t[k] as usize]),
                    V3::from(s.positions[t[(k + 1) % 3] as usize]),
                );
                if (a - b).norm() < resolution / 4.0 {
                    continue;
                }
                let middle = (a + b) * 0.5;
                let g = m.gradient(&middle, 1e-5);
                let distance = (m.field(&middle) - m.threshold()).abs() / g.norm();
                assert!(distance < 1.5 * tolerance, "{distance} m off at {middle:?}");
            }
        }
    }

    #[test]
    fn a_small_exponent_makes_a_box() {
        let m = Model::new(&[prim([0.0; 3], [0.2, 0.1, 0.15], [0.1, 0.1])], 0.5).unwrap();
        let s = polygonise(&m, 0.004).unwrap();
        let exact = 0.4 * 0.2 * 0.3;
        assert!(
            (s.volume() / exact - 1.0).abs() < 0.02,
            "{} vs {exact}",
            s.volume()
        );
        assert!(s.is_watertight());
    }

    #[test]
    fn near_spheres_blend_into_one_and_far_ones_stay_two() {
        let pair = |d: f64| {
            let m = Model::new(
                &[
                    prim([0.0; 3], [0.1; 3], [1.0, 1.0]),
                    prim([d, 0.0, 0.0], [0.1; 3], [1.0, 1.0]),
                ],
                0.5,
            )
            .unwrap();
            polygonise(&m, 0.005).unwrap().components()
        };
        assert_eq!(pair(0.22), 1, "touching spheres blend");
        assert_eq!(pair(0.5), 2, "far apart they split");
    }

    #[test]
    fn a_thin_plate_between_two_blobs_is_kept() {
        // Whatever the grid's phase against the 2 mm plate, it is in the mesh: the blobs are
        // joined and there is surface between them.
        for y in [0.0, 0.0027] {
            let m = Model::new(
                &[
                    prim([-0.3, 0.0, 0.0], [0.15; 3], [1.0, 1.0]),
                    prim([0.3, 0.0, 0.0], [0.15; 3], [1.0, 1.0]),
                    prim([0.0, y, 0.0], [0.3, 0.001, 0.1], [0.2, 0.2]),
                ],
                0.5,
            )
            .unwrap();
            let s = polygonise(&m, 0.008).unwrap();
            assert_eq!(s.components(), 1, "blobs joined by the plate at y = {y}");
            assert!(s.is_watertight());
            let middle = s.positions.iter().filter(|p| p[0].abs() < 0.05).count();
            assert!(middle > 20, "{middle} vertices on the plate at y = {y}");
        }
    }
}
