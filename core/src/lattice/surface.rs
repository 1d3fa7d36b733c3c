//! Contact samples on the display surface. Rigid surfaces push on the *mesh*, not on the
//! lattice nodes around it (which stand up to a cell off the surface): the mesh is sampled,
//! each sample embedded in the lattice like a vertex, and a contact force at a sample is spread
//! onto its cell's nodes by the trilinear weights (Terasawa eq 3.43–3.47, physics §1).
//!
//! Small triangles (up to twice the sample spacing) contribute their vertices (each carrying a
//! third of the area of every triangle around it); a longer triangle is covered by a barycentric
//! grid of samples sharing its area, so a coarse mesh (a cube of 12 triangles) still touches a
//! thin manipulator in the middle of a face. The areas sum to the mesh's area.
//!
//! A fine mesh's vertices are thinned to one per [`VERTEX_CLUSTER`] of the spacing (the vertex
//! nearest its cluster's area-weighted centre, carrying the cluster's area): a sculpt of half a
//! million vertices (and glTF's split copies of every vertex along a seam or a flat-shaded
//! edge) would otherwise put every one of them through the contact pass each substep, 20 s of
//! a 48-frame bake, for no contact a cell-sized lattice can resolve.

use nalgebra::Point3;

/// Most grid samples one mesh gets on its long triangles (some 100 MB with their weights and
/// embedding): beyond it the spacing grows for the whole mesh. Without the cap a small file of
/// many repeated large triangles asked for 24 GB (issue 17).
pub const MAX_GRID_SAMPLES: usize = 1 << 20;

/// How flat the surface round a vertex cluster must be for its samples to carry a normal: the
/// length of the area-weighted mean of its faces' normals (1 where they agree; a cube's
/// corner 0.58, its edge 0.71).
const FLAT_CLUSTER: f64 = 0.95;

/// The least cosine between the normals of two triangles sharing an edge for the surface to
/// be flat across it (18°): samples on a sharper edge carry no normal.
const FLAT_EDGE: f64 = 0.95;

/// Side of a vertex cluster, in sample spacings.
pub const VERTEX_CLUSTER: f64 = 0.5;

/// Grid subdivisions of a triangle whose longest edge is `longest` at `spacing` (≤ 2: the
/// triangle's own vertices serve).
fn subdivisions(longest: f64, spacing: f64) -> usize {
    if spacing > 0.0 {
        (longest / spacing).ceil().min(1e9) as usize
    } else {
        1
    }
}

/// Grid samples the long triangles need at `spacing`.
fn grid_samples(positions: &[Point3<f64>], triangles: &[[u32; 3]], spacing: f64) -> usize {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
            match subdivisions(longest, spacing) {
                n if n <= 2 || !longest.is_finite() => 0,
                n => (n + 1).saturating_mul(n + 2) / 2,
            }
        })
        .fold(0usize, usize::saturating_add)
}

/// Sample points and the surface area (m²) each stands for ([`surface_samples_with_normals`]
/// without the normals).
pub fn surface_samples(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    spacing: f64,
) -> (Vec<Point3<f64>>, Vec<f64>) {
    let samples = surface_samples_with_normals(positions, triangles, spacing);
    (samples.points, samples.areas)
}

/// A mesh's contact samples ([`surface_samples_with_normals`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceSamples {
    pub points: Vec<Point3<f64>>,
    /// The surface area each stands for, m².
    pub areas: Vec<f64>,
    /// The surface's unit normal at each, as the triangles are wound, where the surface is
    /// flat round it: an inner grid sample's triangle's, a vertex's the area-weighted mean of
    /// the triangles round its cluster. Zero where it has none: a grid sample on an edge
    /// where the surface folds or ends or at its triangle's corner, a sliver's samples, a
    /// cluster at a corner or a crease.
    pub normals: Vec<nalgebra::Vector3<f64>>,
}

/// Sample points, the surface area (m²) each stands for and the surface's normal there.
pub fn surface_samples_with_normals(
    positions: &[Point3<f64>],
    triangles: &[[u32; 3]],
    spacing: f64,
) -> SurfaceSamples {
    // Coarsen the whole mesh's grid until it fits the cap (samples fall as 1/spacing²).
    let mut spacing = spacing;
    for _ in 0..64 {
        let count = grid_samples(positions, triangles, spacing);
        if count <= MAX_GRID_SAMPLES {
            break;
        }
        spacing *= (count as f64 / MAX_GRID_SAMPLES as f64).sqrt().max(1.01);
    }
    let mut vertex_area = vec![0.0; positions.len()];
    // Per vertex, the area-weighted sum of the normals of the triangles round it.
    let mut vertex_normal = vec![nalgebra::Vector3::zeros(); positions.len()];
    let mut out = SurfaceSamples::default();
    let rims = rim_edges(positions, triangles);
    for (t, rim_edge) in triangles.iter().zip(&rims) {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let cross = (b - a).cross(&(c - a));
        let area = 0.5 * cross.norm();
        if area <= 0.0 || !area.is_finite() {
            continue;
        }
        let normal = cross / cross.norm();
        let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
        let n = subdivisions(longest, spacing);
        // Up to twice the spacing the triangle's own vertices are close enough.
        if n <= 2 {
            for &i in t {
                vertex_area[i as usize] += area / 3.0;
                vertex_normal[i as usize] += normal * (area / 3.0);
            }
            continue;
        }
        if let Some(strip) = sliver_samples(&[a, b, c], area, spacing) {
            let share = area / strip.len() as f64;
            // A sliver is all rim: its samples lie within a spacing of its edges.
            for p in strip {
                out.points.push(p);
                out.areas.push(share);
                out.normals.push(nalgebra::Vector3::zeros());
            }
            continue;
        }
        let count = (n + 1) * (n + 2) / 2;
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                out.points.push(Point3::from(
                    a.coords * (1.0 - u - v) + b.coords * u + c.coords * v,
                ));
                out.areas.push(area / count as f64);
                // On an edge where the surface folds or ends (a cube's rim, not a quad's
                // diagonal), or at a corner: no one normal.
                let corner = (i == 0 || j == 0) && (i + j == 0 || i + j == n);
                let rim = corner
                    || (j == 0 && rim_edge[0])
                    || (i + j == n && rim_edge[1])
                    || (i == 0 && rim_edge[2]);
                out.normals.push(if rim {
                    nalgebra::Vector3::zeros()
                } else {
                    normal
                });
            }
        }
    }
    let side = VERTEX_CLUSTER * spacing;
    for (vertex, area, normal) in thin_vertices(positions, (&vertex_area, &vertex_normal), side) {
        out.points.push(positions[vertex]);
        out.areas.push(area);
        // Where the faces round the cluster turn by more than some 18° from their mean (a
        // corner, a crease), it has no one normal.
        let flat = normal.norm() >= FLAT_CLUSTER * area;
        let normal = normal.try_normalize(1e-12).filter(|_| flat);
        out.normals.push(normal.unwrap_or_default());
    }
    out
}

/// Per triangle, whether each of its edges (corners 0–1, 1–2, 2–0) is a rim of the surface:
/// not shared with exactly one other triangle (by position: glTF splits vertices along seams)
/// whose normal is within [`FLAT_EDGE`] of its own.
fn rim_edges(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<[bool; 3]> {
    let welded = crate::collide::geometry::weld_positions(positions.iter().map(|p| p.coords));
    let edge = |t: &[u32; 3], e: usize| {
        let (p, q) = (welded[t[e] as usize], welded[t[(e + 1) % 3] as usize]);
        (p.min(q), p.max(q))
    };
    let normals: Vec<_> = (triangles.iter())
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            (b - a).cross(&(c - a)).try_normalize(0.0)
        })
        .collect();
    let mut sharing: std::collections::HashMap<(u32, u32), Vec<usize>> = Default::default();
    for (k, t) in triangles.iter().enumerate() {
        for e in 0..3 {
            sharing.entry(edge(t, e)).or_default().push(k);
        }
    }
    (triangles.iter().enumerate())
        .map(|(k, t)| {
            [0, 1, 2].map(|e| match sharing[&edge(t, e)][..] {
                [a, b] => {
                    let other = if a == k { b } else { a };
                    let faces = normals[k].zip(normals[other]);
                    !faces.is_some_and(|(m, n)| m.dot(&n) >= FLAT_EDGE)
                }
                _ => true,
            })
        })
        .collect()
}

/// Samples of a sliver (a triangle narrower than a quarter of its longest edge: a bevel, a
/// rim, a COLLADA converter's strip), rows at most `spacing` apart across it, each row's points
/// at most `spacing` apart along it; `None` for other triangles. The barycentric grid of the
/// other triangles spaces its rows by the longest edge, so a 1.2 m strip 2 cm wide got 325
/// samples, 25 on each of its 13 rows, where 26 cover it.
fn sliver_samples(t: &[Point3<f64>; 3], area: f64, spacing: f64) -> Option<Vec<Point3<f64>>> {
    let length = |e: usize| (t[(e + 1) % 3] - t[e]).norm();
    let e = (1..3).fold(0, |best, e| if length(e) > length(best) { e } else { best });
    let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
    let longest = length(e);
    let altitude = 2.0 * area / longest;
    // (A NaN altitude is no sliver either.)
    if altitude * 4.0 >= longest || altitude.is_nan() {
        return None;
    }
    let rows = (altitude / spacing).ceil().clamp(1.0, 1e6) as usize;
    let mut out = Vec::new();
    for j in 0..=rows {
        let s = j as f64 / rows as f64;
        let (p0, p1) = (a + (c - a) * s, b + (c - b) * s);
        let along = ((p1 - p0).norm() / spacing).ceil().clamp(0.0, 1e6) as usize;
        for i in 0..=along {
            let u = if along == 0 {
                0.0
            } else {
                i as f64 / along as f64
            };
            out.push(p0 + (p1 - p0) * u);
        }
    }
    Some(out)
}

/// The vertices with an area, one per cube of side `side` (the one nearest the cube's
/// area-weighted centre, with the cube's whole area and the sum of its vertices' normal sums:
/// a flat-shaded corner's split copies all count), in order of first vertex.
fn thin_vertices(
    positions: &[Point3<f64>],
    (vertex_area, vertex_normal): (&[f64], &[nalgebra::Vector3<f64>]),
    side: f64,
) -> Vec<(usize, f64, nalgebra::Vector3<f64>)> {
    let key = |p: &Point3<f64>| {
        if side > 0.0 && side.is_finite() {
            p.coords
                .map(|c| (c / side).floor().clamp(-1e15, 1e15) as i64)
        } else {
            nalgebra::Vector3::zeros()
        }
    };
    // Per cluster, in order of its first vertex: area, area-weighted sum of positions, first
    // vertex (kept where no distance compares, e.g. an overflowing sum).
    let mut cluster_of = std::collections::HashMap::new();
    let mut clusters: Vec<(f64, nalgebra::Vector3<f64>, usize)> = Vec::new();
    let mut normals: Vec<nalgebra::Vector3<f64>> = Vec::new();
    let mut member = vec![usize::MAX; positions.len()];
    for (i, &area) in vertex_area.iter().enumerate() {
        if area > 0.0 && positions[i].coords.iter().all(|c| c.is_finite()) {
            let c = *cluster_of.entry(key(&positions[i])).or_insert_with(|| {
                clusters.push((0.0, nalgebra::Vector3::zeros(), i));
                normals.push(nalgebra::Vector3::zeros());
                clusters.len() - 1
            });
            clusters[c].0 += area;
            clusters[c].1 += positions[i].coords * area;
            normals[c] += vertex_normal[i];
            member[i] = c;
        }
    }
    let mut nearest: Vec<(f64, usize)> = clusters.iter().map(|c| (f64::INFINITY, c.2)).collect();
    for (i, &c) in member.iter().enumerate() {
        if c != usize::MAX {
            let centre = clusters[c].1 / clusters[c].0;
            let d = (positions[i].coords - centre).norm_squared();
            if d < nearest[c].0 {
                nearest[c] = (d, i);
            }
        }
    }
    (nearest.iter().zip(&clusters).zip(normals))
        .map(|((&(_, vertex), &(area, _, _)), normal)| (vertex, area, normal))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{box_mesh, uv_sphere};

    #[test]
    fn areas_sum_to_the_mesh_area_and_big_faces_are_covered() {
        let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
        let (s, a) = surface_samples(&p, &t, 0.1);
        assert!((a.iter().sum::<f64>() - 6.0).abs() < 1e-9);
        // Every 0.1 m patch of the top face has a sample within the spacing.
        for x in 0..10 {
            for z in 0..10 {
                let q = Point3::new(0.05 + 0.1 * x as f64, 1.0, 0.05 + 0.1 * z as f64);
                assert!(
                    s.iter().any(|p| (p - q).norm() <= 0.1),
                    "no sample near {q}"
                );
            }
        }
        let (sp, st) = uv_sphere([0.0; 3], 1.0, 16, 32);
        let (points, areas) = surface_samples(&sp, &st, 1.0);
        assert!(
            points.iter().all(|q| sp.contains(q)),
            "fine meshes are sampled at their vertices"
        );
        let total: f64 = areas.iter().sum();
        assert!(
            total > 12.0 && total < 4.0 * std::f64::consts::PI,
            "{total}"
        );
    }

    /// Each sample carries the surface's outward normal where it is flat: a face's on a cube's
    /// faces (its diagonal too), none on its edges and corners, the radial one on a fine
    /// sphere (at its vertices).
    #[test]
    fn samples_carry_the_surface_normal() {
        let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
        let s = surface_samples_with_normals(&p, &t, 0.1);
        assert_eq!(s.normals.len(), s.points.len());
        let centre = Point3::new(0.5, 0.5, 0.5);
        let (mut inner, mut rims) = (0, 0);
        for (q, n) in s.points.iter().zip(&s.normals) {
            let inside = (q.coords.iter()).filter(|c| **c > 1e-9 && **c < 1.0 - 1e-9);
            if inside.count() < 2 {
                // On the cube's edges and corners: none.
                assert_eq!(*n, nalgebra::Vector3::zeros(), "at {q}");
                rims += 1;
            } else {
                // In a face, on the diagonal its two triangles meet on too: the face's
                // outward normal, one axis.
                assert!((n.amax() - 1.0).abs() < 1e-9, "{n} at {q}");
                assert!((q - centre).dot(n) > 0.0, "{n} at {q} points in");
                inner += 1;
            }
        }
        assert!(
            inner > 2 * rims,
            "{inner} samples inside faces, {rims} on edges"
        );
        let (sp, st) = uv_sphere([0.0; 3], 1.0, 32, 64);
        let s = surface_samples_with_normals(&sp, &st, 0.5);
        let known = s.normals.iter().filter(|n| n.norm() > 0.0).count();
        assert!(
            known * 10 > s.normals.len() * 9,
            "{known} of {}",
            s.normals.len()
        );
        for (q, n) in s
            .points
            .iter()
            .zip(&s.normals)
            .filter(|(_, n)| n.norm() > 0.0)
        {
            assert!(q.coords.normalize().dot(n) > 0.99, "{n} at {q}");
        }
    }

    #[test]
    fn a_fine_mesh_keeps_one_vertex_per_cluster_and_its_whole_area() {
        // 64 × 128 quads on a unit sphere: 8 k vertices, some 3 cm apart at the equator.
        let (sp, st) = uv_sphere([0.0; 3], 1.0, 64, 128);
        let spacing = 0.25;
        let (points, areas) = surface_samples(&sp, &st, spacing);
        let mesh_area: f64 = st
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| sp[i as usize]);
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .sum();
        assert!((areas.iter().sum::<f64>() - mesh_area).abs() < 1e-9 * mesh_area);
        // About one point per (spacing / 2)² of surface, not one per vertex.
        let side = VERTEX_CLUSTER * spacing;
        assert!(
            points.len() < 2 * (mesh_area / (side * side)) as usize,
            "{}",
            points.len()
        );
        assert!(
            points.len() * 4 < sp.len(),
            "{} of {}",
            points.len(),
            sp.len()
        );
        // Every vertex still has a sample within a cluster's diagonal.
        for v in &sp {
            let near = points.iter().any(|p| (p - v).norm() <= 3f64.sqrt() * side);
            assert!(near, "no sample near {v}");
        }
    }

    #[test]
    fn coincident_vertices_become_one_sample() {
        // A box whose faces have their own vertices (flat shading as glTF writes it).
        let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
        let mut split = Vec::new();
        let mut tris = Vec::new();
        for tri in &t {
            let base = split.len() as u32;
            split.extend(tri.map(|i| p[i as usize]));
            tris.push([base, base + 1, base + 2]);
        }
        let (points, areas) = surface_samples(&split, &tris, 1.0);
        assert_eq!(points.len(), 8, "one sample per corner");
        assert!((areas.iter().sum::<f64>() - 6.0).abs() < 1e-9);
    }

    #[test]
    fn a_sliver_is_sampled_along_its_length_not_across_it() {
        // A strip 1.2 m long and 2 cm wide, as two triangles.
        let p = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.2, 0.0, 0.0),
            Point3::new(1.2, 0.0, 0.02),
            Point3::new(0.0, 0.0, 0.02),
        ];
        let t = [[0u32, 1, 2], [0, 2, 3]];
        let (points, areas) = surface_samples(&p, &t, 0.05);
        assert!((areas.iter().sum::<f64>() - 0.024).abs() < 1e-12);
        assert!(points.len() <= 60, "{} samples", points.len());
        // Still no point of the strip farther than the spacing from a sample.
        for k in 0..=120 {
            for side in [0.0, 0.02] {
                let q = Point3::new(0.01 * k as f64, 0.0, side);
                let near = points.iter().any(|s| (s - q).norm() <= 0.05);
                assert!(near, "no sample near {q}");
            }
        }
    }

    #[test]
    fn many_repeated_large_triangles_stay_within_the_sample_cap() {
        let p = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let t = vec![[0u32, 1, 2]; 100_000];
        let (points, areas) = surface_samples(&p, &t, 0.01);
        assert!(
            points.len() <= MAX_GRID_SAMPLES + p.len(),
            "{}",
            points.len()
        );
        assert!((areas.iter().sum::<f64>() - 0.5 * 100_000.0).abs() < 1e-6 * 50_000.0);
    }
}
