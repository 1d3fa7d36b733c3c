//! Convex hull of a point set (incremental, O(n²); cages have tens to hundreds of nodes), as
//! outward triangles. Points on a hull face (within a tolerance) are left off the hull.

use nalgebra::Vector3;

/// Outward triangles of the hull of `points`; `None` when the points span no volume.
pub fn convex_hull(points: &[Vector3<f64>]) -> Option<Vec<[u32; 3]>> {
    let n = points.len();
    if n < 4 {
        return None;
    }
    let (lo, hi) = super::bounds(points.iter().copied());
    let scale = (hi - lo).max();
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let eps = 1e-10 * scale;
    // Initial tetrahedron: two far points, the farthest from their line, the farthest from
    // their plane.
    let a = 0;
    let b = (0..n).max_by(|&i, &j| {
        (points[i] - points[a])
            .norm_squared()
            .total_cmp(&(points[j] - points[a]).norm_squared())
    })?;
    let ab = points[b] - points[a];
    if ab.norm() <= eps {
        return None;
    }
    let line = |i: usize| ab.cross(&(points[i] - points[a])).norm();
    let c = (0..n).max_by(|&i, &j| line(i).total_cmp(&line(j)))?;
    if line(c) <= eps * ab.norm() {
        return None;
    }
    let normal = ab.cross(&(points[c] - points[a]));
    let height = |i: usize| normal.dot(&(points[i] - points[a]));
    let d = (0..n).max_by(|&i, &j| height(i).abs().total_cmp(&height(j).abs()))?;
    if height(d).abs() <= eps * normal.norm() {
        return None;
    }
    let [a, b, c, d] = [a, b, c, d].map(|i| i as u32);
    let mut faces: Vec<[u32; 3]> = if height(d as usize) > 0.0 {
        vec![[a, c, b], [a, b, d], [b, c, d], [c, a, d]]
    } else {
        vec![[a, b, c], [a, d, b], [b, d, c], [c, d, a]]
    };
    let above = |f: &[u32; 3], p: &Vector3<f64>| {
        let [x, y, z] = f.map(|i| points[i as usize]);
        let nrm = (y - x).cross(&(z - x));
        let len = nrm.norm();
        len > 0.0 && nrm.dot(&(p - x)) / len > eps
    };
    for (i, p) in points.iter().enumerate() {
        let i = i as u32;
        if [a, b, c, d].contains(&i) {
            continue;
        }
        let visible: Vec<bool> = faces.iter().map(|f| above(f, p)).collect();
        if !visible.contains(&true) {
            continue;
        }
        // Horizon: directed edges of visible faces whose reverse is not on a visible face.
        let mut visible_edges = std::collections::HashSet::new();
        for (f, _) in faces.iter().zip(&visible).filter(|(_, v)| **v) {
            for k in 0..3 {
                visible_edges.insert((f[k], f[(k + 1) % 3]));
            }
        }
        let mut horizon = Vec::new();
        for (f, _) in faces.iter().zip(&visible).filter(|(_, v)| **v) {
            for k in 0..3 {
                let (u, v) = (f[k], f[(k + 1) % 3]);
                if !visible_edges.contains(&(v, u)) {
                    horizon.push((u, v));
                }
            }
        }
        let mut kept: Vec<[u32; 3]> = faces
            .iter()
            .zip(&visible)
            .filter(|(_, v)| !**v)
            .map(|(f, _)| *f)
            .collect();
        kept.extend(horizon.into_iter().map(|(u, v)| [u, v, i]));
        faces = kept;
    }
    Some(faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_of_a_cube_with_inner_points_is_12_outward_triangles() {
        let mut p: Vec<Vector3<f64>> = (0..8)
            .map(|i| Vector3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        p.push(Vector3::new(0.5, 0.5, 0.5));
        p.push(Vector3::new(0.2, 0.7, 0.4));
        let f = convex_hull(&p).unwrap();
        assert_eq!(f.len(), 12);
        let centre = Vector3::new(0.5, 0.5, 0.5);
        let mut volume = 0.0;
        for t in &f {
            assert!(t.iter().all(|&i| i < 8), "inner point on the hull: {t:?}");
            let [x, y, z] = t.map(|i| p[i as usize] - centre);
            let v = x.dot(&y.cross(&z)) / 6.0;
            assert!(v > 0.0, "inward face {t:?}");
            volume += v;
        }
        assert!((volume - 1.0).abs() < 1e-12, "{volume}");
        assert!(convex_hull(&p[..3]).is_none());
        let flat: Vec<Vector3<f64>> = p[..4].to_vec();
        assert!(convex_hull(&flat).is_none(), "four coplanar points");
    }
}
