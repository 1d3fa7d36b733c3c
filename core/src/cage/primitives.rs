//! Primitive cages sized to a mesh (see the [`super`] module docs): box, octahedron and
//! icosahedron (fan from a centre node), and the `plane` slab of Kuhn tets.

use super::{bounds, tet_edges, tet_volume, Cage, CageError};
use nalgebra::{Point3, Vector3};

/// A closed convex primitive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    Box,
    Octahedron,
    Icosahedron,
}

impl Primitive {
    fn name(self) -> &'static str {
        match self {
            Primitive::Box => "box",
            Primitive::Octahedron => "octahedron",
            Primitive::Icosahedron => "icosahedron",
        }
    }

    /// Unit-shape vertices and outward triangles.
    fn unit(self) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
        match self {
            Primitive::Box => {
                let (p, t) = crate::shapes::box_mesh([-1.0; 3], [1.0; 3]);
                (p.into_iter().map(|q| q.coords).collect(), t)
            }
            Primitive::Octahedron => {
                let v: Vec<Vector3<f64>> = (0..6)
                    .map(|i| {
                        let mut e = Vector3::zeros();
                        e[i / 2] = if i % 2 == 0 { 1.0 } else { -1.0 };
                        e
                    })
                    .collect();
                let mut f = Vec::new();
                for x in [0u32, 1] {
                    for y in [2u32, 3] {
                        for z in [4u32, 5] {
                            f.push(outward(&v, [x, y, z]));
                        }
                    }
                }
                (v, f)
            }
            Primitive::Icosahedron => {
                let phi = (1.0 + 5f64.sqrt()) / 2.0;
                let mut v = Vec::new();
                for a in [-1.0, 1.0] {
                    for b in [-phi, phi] {
                        v.push(Vector3::new(0.0, a, b));
                        v.push(Vector3::new(a, b, 0.0));
                        v.push(Vector3::new(b, 0.0, a));
                    }
                }
                let v: Vec<Vector3<f64>> = v.into_iter().map(|x| x / phi).collect();
                // Faces: the triples of mutually adjacent vertices (edge length 2/φ).
                let edge = 2.0 / phi;
                let adjacent = |i: usize, j: usize| ((v[i] - v[j]).norm() - edge).abs() < 1e-9;
                let mut f = Vec::new();
                for i in 0..12 {
                    for j in i + 1..12 {
                        for k in j + 1..12 {
                            if adjacent(i, j) && adjacent(j, k) && adjacent(i, k) {
                                f.push(outward(&v, [i as u32, j as u32, k as u32]));
                            }
                        }
                    }
                }
                (v, f)
            }
        }
    }
}

/// Orient triangle `t` of a shape centred on the origin outwards.
fn outward(v: &[Vector3<f64>], t: [u32; 3]) -> [u32; 3] {
    let [a, b, c] = t.map(|i| v[i as usize]);
    if (b - a).cross(&(c - a)).dot(&(a + b + c)) >= 0.0 {
        t
    } else {
        [t[0], t[2], t[1]]
    }
}

/// Half extents of `points`' bounding box, thin axes floored at 5 % of the largest, and its
/// centre. Errors on no points or non-finite coordinates.
fn extents(points: &[Point3<f64>]) -> Result<(Vector3<f64>, Vector3<f64>), CageError> {
    if points.is_empty() {
        return Err(CageError::new("model", "the mesh has no vertices"));
    }
    let (lo, hi) = bounds(points.iter().map(|p| p.coords));
    if !(lo.iter().chain(hi.iter()).all(|x| x.is_finite())) {
        return Err(CageError::new("model", "the mesh has non-finite vertices"));
    }
    let half = (hi - lo) / 2.0;
    let largest = half.max();
    if largest <= 0.0 {
        return Err(CageError::new(
            "model",
            "the mesh has no extent (all vertices coincide)",
        ));
    }
    Ok((half.map(|h| h.max(0.05 * largest)), (lo + hi) / 2.0))
}

/// A primitive cage around `points`: the unit shape scaled by the half extents about the box
/// centre, plus a centre node, inflated to contain every point.
pub fn primitive(shape: Primitive, points: &[Point3<f64>]) -> Result<Cage, CageError> {
    let (half, centre) = extents(points)?;
    let (unit, faces) = shape.unit();
    let nodes: Vec<Vector3<f64>> = unit
        .iter()
        .map(|u| centre + u.component_mul(&half))
        .collect();
    let mut cage = Cage::fan(shape.name(), nodes, &faces, centre);
    let c = (cage.nodes.len() - 1) as u32;
    cage.inflate_to_contain(c, points);
    Ok(cage)
}

/// The `plane` slab around `points`: `cells` cells along the widest axis (at least 1), the
/// second axis in proportion, one cell through the thinnest axis.
pub fn plane(points: &[Point3<f64>], cells: u32) -> Result<Cage, CageError> {
    let (half, centre) = extents(points)?;
    // Axes by extent, widest first (ties: lower axis first).
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| half[b].total_cmp(&half[a]).then(a.cmp(&b)));
    let nu = cells.max(1) as usize;
    let nv = ((nu as f64 * half[axes[1]] / half[axes[0]]).round() as usize).max(1);
    let counts = [nu, nv, 1];
    let lo = centre - half;
    let mut nodes = Vec::with_capacity((nu + 1) * (nv + 1) * 2);
    let index = |i: usize, j: usize, k: usize| (i + (nu + 1) * (j + (nv + 1) * k)) as u32;
    for k in 0..=1 {
        for j in 0..=nv {
            for i in 0..=nu {
                let mut x = lo;
                for (axis, (n, c)) in axes.iter().zip([i, j, k].iter().zip(counts)) {
                    x[*axis] += 2.0 * half[*axis] * (*n as f64) / c as f64;
                }
                nodes.push(x);
            }
        }
    }
    // Kuhn's 6 tets around the 0–7 diagonal of every cell (corner bits: 1 = u, 2 = v, 4 = n),
    // the split volume preservation uses.
    use crate::solver::volume::TETS as KUHN;
    let mut tets = Vec::with_capacity(6 * nu * nv);
    for j in 0..nv {
        for i in 0..nu {
            let corner = |c: usize| index(i + (c & 1), j + ((c >> 1) & 1), (c >> 2) & 1);
            for k in KUHN {
                let mut t = k.map(corner);
                if tet_volume(&t, &nodes) < 0.0 {
                    t.swap(1, 2);
                }
                tets.push(t);
            }
        }
    }
    let springs = tet_edges(&tets);
    Ok(Cage {
        model: "plane",
        nodes,
        springs,
        tets,
        note: None,
        uniform_springs: false,
    })
}
