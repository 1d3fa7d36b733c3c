//! A body's contact surface simplified to its samples' spacing: normal-aware vertex clustering
//! (Rossignac and Borrel 1993) of the display triangles, so the faces a sample searches are
//! bounded by the lattice, not by the display mesh.
//!
//! A fine display mesh (a chair's 3 mm wire frame of 2 000 faces a tube, a sculpt) puts
//! hundreds of faces within a contact layer of every sample: on trimesh's `chair_model.obj`
//! each of 14 000 samples a step looked at some 700 faces. The samples themselves are already
//! thinned to a quarter cell ([`crate::lattice::surface_samples`]); the faces now are too.
//!
//! Vertices are clustered on a grid of cubes of side `side`; within a cube, a vertex joins the
//! first cluster (in vertex order) whose first vertex's normal is within [`MAX_TURN_COS`] of
//! its own, so the two sides of a thin plate or a tube never merge. Each cluster is
//! represented by its member nearest the members' mean: an original vertex, on the surface,
//! already embedded. A triangle takes its corners' representatives; one that collapses to an
//! edge or a point, turns over, or repeats a kept triangle is dropped. A mesh coarser than the
//! cubes (every vertex alone in its cluster) comes back unchanged.

use nalgebra::{Point3, Vector3};
use std::collections::{HashMap, HashSet};

/// The cosine of the largest angle between a vertex normal and its cluster's first normal
/// (60°): a tube's circle keeps three to six sides, a plate both of its faces.
const MAX_TURN_COS: f64 = 0.5;

/// `triangles` over `positions` with their corners moved to their clusters' representatives
/// (indices into `positions`), at clusters of side `side`, m. A side that is not positive and
/// finite leaves the triangles as given.
pub(super) fn cluster_triangles(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    side: f64,
) -> Vec<[u32; 3]> {
    if !(side > 0.0 && side.is_finite()) {
        return triangles.to_vec();
    }
    let normals = vertex_normals(positions, triangles);
    let representative = representatives(positions, &normals, triangles, side);
    let mut kept = HashSet::new();
    let mut out = Vec::with_capacity(triangles.len());
    for t in triangles.iter().filter(|t| indexes(positions, t)) {
        let moved = t.map(|i| representative[i as usize]);
        if moved != *t {
            let [a, b, c] = moved;
            if a == b || b == c || c == a {
                continue;
            }
            let before = face_normal(positions, t);
            if face_normal(positions, &moved).dot(&before) <= 0.0 {
                continue;
            }
        }
        // One key for a triangle however its corners are rotated (the winding kept).
        let first = (0..3).min_by_key(|&e| moved[e]).unwrap_or(0);
        let key = [moved[first], moved[(first + 1) % 3], moved[(first + 2) % 3]];
        if kept.insert(key) || moved == *t {
            out.push(moved);
        }
    }
    out
}

/// Whether every corner of `t` indexes `positions`.
fn indexes(positions: &[Point3<f64>], t: &[u32; 3]) -> bool {
    t.iter().all(|&i| (i as usize) < positions.len())
}

/// The (unnormalised) normal of triangle `t`.
fn face_normal(positions: &[Point3<f64>], t: &[u32; 3]) -> Vector3<f64> {
    let [a, b, c] = t.map(|i| positions[i as usize]);
    (b - a).cross(&(c - a))
}

/// Per vertex: the area-weighted mean of its triangles' normals, unit (zero where they cancel
/// or the vertex is in no triangle).
fn vertex_normals(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<Vector3<f64>> {
    let mut normals = vec![Vector3::zeros(); positions.len()];
    for t in triangles.iter().filter(|t| indexes(positions, t)) {
        let n = face_normal(positions, t);
        if n.iter().all(|c| c.is_finite()) {
            for &i in t {
                normals[i as usize] += n;
            }
        }
    }
    for n in &mut normals {
        *n = n.try_normalize(0.0).unwrap_or_else(Vector3::zeros);
    }
    normals
}

/// Per vertex: its cluster's representative (itself for a vertex in no triangle, or one whose
/// position is not finite).
fn representatives(
    positions: &[Point3<f64>],
    normals: &[Vector3<f64>],
    triangles: &[[u32; 3]],
    side: f64,
) -> Vec<u32> {
    let mut used = vec![false; positions.len()];
    for t in triangles {
        for &i in t {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    // Per cube: its clusters; per cluster: its first normal, member count and position sum.
    let mut cubes: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    let mut clusters: Vec<(Vector3<f64>, f64, Vector3<f64>)> = Vec::new();
    let mut member = vec![usize::MAX; positions.len()];
    for (i, p) in positions.iter().enumerate() {
        if !used[i] || !p.coords.iter().all(|c| c.is_finite()) {
            continue;
        }
        let key = p
            .coords
            .map(|c| (c / side).floor().clamp(-1e15, 1e15) as i64);
        let in_cube = cubes.entry([key.x, key.y, key.z]).or_default();
        let normal = normals[i];
        let joined = in_cube
            .iter()
            .copied()
            .find(|&c| clusters[c].0.dot(&normal) >= MAX_TURN_COS);
        let c = joined.unwrap_or_else(|| {
            clusters.push((normal, 0.0, Vector3::zeros()));
            in_cube.push(clusters.len() - 1);
            clusters.len() - 1
        });
        clusters[c].1 += 1.0;
        clusters[c].2 += p.coords;
        member[i] = c;
    }
    let mut nearest = vec![(f64::INFINITY, u32::MAX); clusters.len()];
    for (i, &c) in member.iter().enumerate() {
        if c != usize::MAX {
            let mean = clusters[c].2 / clusters[c].1;
            let d = (positions[i].coords - mean).norm_squared();
            if d < nearest[c].0 || nearest[c].1 == u32::MAX {
                nearest[c] = (d, i as u32);
            }
        }
    }
    member
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            if c == usize::MAX {
                i as u32
            } else {
                nearest[c].1
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{box_mesh, uv_sphere};

    /// A `n` × `n` grid of squares of side `1/n` in the plane z = `z`, facing +z (or −z when
    /// `down`), its vertices numbered from `base`.
    fn sheet(n: u32, z: f64, down: bool, base: u32) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(Point3::new(
                    f64::from(i) / f64::from(n),
                    f64::from(j) / f64::from(n),
                    z,
                ));
            }
        }
        let mut t = Vec::new();
        let at = |i: u32, j: u32| base + j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                if down {
                    t.extend([[a, c, b], [a, d, c]]);
                } else {
                    t.extend([[a, b, c], [a, c, d]]);
                }
            }
        }
        (p, t)
    }

    #[test]
    fn a_mesh_coarser_than_the_clusters_is_unchanged() {
        let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
        assert_eq!(cluster_triangles(&p, &t, 0.25), t);
        let (p, t) = uv_sphere([0.0; 3], 0.5, 8, 6);
        assert_eq!(cluster_triangles(&p, &t, 0.01), t);
    }

    #[test]
    fn a_fine_sheet_keeps_its_extent_facing_and_area_with_far_fewer_faces() {
        let (p, t) = sheet(100, 0.0, false, 0);
        let coarse = cluster_triangles(&p, &t, 0.1);
        assert!(coarse.len() < t.len() / 20, "{} faces", coarse.len());
        let area: f64 = coarse.iter().map(|f| face_normal(&p, f).norm() / 2.0).sum();
        assert!(area > 0.75 && area <= 1.0 + 1e-9, "area {area}");
        for f in &coarse {
            assert!(face_normal(&p, f).z > 0.0, "a face turned over");
        }
    }

    #[test]
    fn the_two_sides_of_a_thin_plate_stay_apart() {
        // A 1 mm plate: two sheets facing away from each other, on 10 cm clusters.
        let (mut p, mut t) = sheet(50, 0.0, true, 0);
        let (p2, t2) = sheet(50, 0.001, false, p.len() as u32);
        p.extend(p2);
        t.extend(t2);
        let coarse = cluster_triangles(&p, &t, 0.1);
        let up = coarse.iter().filter(|f| face_normal(&p, f).z > 0.0).count();
        let down = coarse.iter().filter(|f| face_normal(&p, f).z < 0.0).count();
        assert!(up > 0 && down > 0, "{up} up, {down} down");
        for f in &coarse {
            let z = f.map(|i| p[i as usize].z);
            let top = face_normal(&p, f).z > 0.0;
            assert!(
                z.iter().all(|&z| (z == 0.001) == top),
                "a face joins the two sides"
            );
        }
    }
}
