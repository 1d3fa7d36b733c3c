//! Exact small geometric queries for collision detection: the closest point of a triangle,
//! a segment crossing a triangle, the closest points of two segments, whether a mesh bounds a
//! solid; and the rotation of a polar decomposition (a point set's best-fit turn).

use nalgebra::{Matrix3, Point3, Vector3};

/// Closest point of triangle `(a, b, c)` to `p`, as barycentric weights `[wa, wb, wc]`
/// (Ericson, *Real-Time Collision Detection* §5.1.5), and whether it lies inside the face
/// (not on an edge or a corner).
pub fn closest_on_triangle(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> ([f64; 3], bool) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ([1.0, 0.0, 0.0], false);
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return ([0.0, 1.0, 0.0], false);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return ([1.0 - v, v, 0.0], false);
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return ([0.0, 0.0, 1.0], false);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return ([1.0 - w, 0.0, w], false);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return ([0.0, 1.0 - w, w], false);
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE {
        // Degenerate (zero-area) triangle: its first corner.
        return ([1.0, 0.0, 0.0], false);
    }
    let v = vb / denom;
    let w = vc / denom;
    ([1.0 - v - w, v, w], true)
}

/// Where segment `p0 → p1` crosses triangle `(a, b, c)`: the segment parameter `t ∈ [0, 1]`
/// and the barycentric weights of the crossing point (Möller–Trumbore), or `None`.
pub fn segment_crosses_triangle(
    p0: &Vector3<f64>,
    p1: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Option<(f64, [f64; 3])> {
    let d = p1 - p0;
    let e1 = b - a;
    let e2 = c - a;
    let h = d.cross(&e2);
    let det = e1.dot(&h);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = p0 - a;
    let u = s.dot(&h) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(&q) * inv;
    (0.0..=1.0).contains(&t).then_some((t, [1.0 - u - v, u, v]))
}

/// Closest points of segments `p0 → p1` and `q0 → q1`: parameters `(s, t)` in [0, 1]
/// (Ericson §5.1.9).
pub fn closest_between_segments(
    p0: &Vector3<f64>,
    p1: &Vector3<f64>,
    q0: &Vector3<f64>,
    q1: &Vector3<f64>,
) -> (f64, f64) {
    let d1 = p1 - p0;
    let d2 = q1 - q0;
    let r = p0 - q0;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let tiny = 1e-300;
    if a <= tiny && e <= tiny {
        return (0.0, 0.0);
    }
    if a <= tiny {
        return (0.0, (f / e).clamp(0.0, 1.0));
    }
    let c = d1.dot(&r);
    if e <= tiny {
        return ((-c / a).clamp(0.0, 1.0), 0.0);
    }
    let b = d1.dot(&d2);
    let denom = a * e - b * b;
    let mut s = if denom > tiny {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    (s, t)
}

/// Unit normal of triangle `(a, b, c)` (counter-clockwise front), zero if degenerate.
pub fn triangle_normal(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Vector3<f64> {
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    if len > 0.0 {
        n / len
    } else {
        Vector3::zeros()
    }
}

/// Most sweeps the singular value decomposition takes (a 3 × 3 converges in a few; the bound
/// keeps non-finite input from looping).
const SVD_SWEEPS: usize = 64;

/// The rotation of the polar decomposition of `a` (a proper rotation: a reflection's sign is
/// moved to the smallest singular value); `None` when `a` is not finite or does not converge.
pub fn polar_rotation(a: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = a.try_svd(true, true, f64::EPSILON, SVD_SWEEPS)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut u = u;
    if (u * v_t).determinant() < 0.0 {
        // nalgebra sorts singular values in decreasing order: flip the last.
        let flipped = -u.column(2);
        u.set_column(2, &flipped);
    }
    Some(u * v_t)
}

/// Whether `triangles` over `positions` bound a solid with their fronts outside: with
/// corners at the same position taken as one vertex (a DCC's export splits them at seams
/// and hard edges), every edge is walked once each way by two triangles, none is
/// degenerate, and the enclosed (signed) volume is positive. An open sheet, a mesh with a
/// hole, a non-manifold edge or one wound inside out is not.
pub fn closed_outward(positions: &[Point3<f64>], triangles: &[[u32; 3]]) -> bool {
    use std::collections::HashMap;
    if triangles.is_empty() {
        return false;
    }
    let welded = weld_positions(positions.iter().map(|p| p.coords));
    let mut walks: HashMap<(u32, u32), u32> = HashMap::new();
    let mut volume = 0.0;
    for t in triangles {
        let Some(v) = t
            .iter()
            .map(|&i| welded.get(i as usize).copied())
            .collect::<Option<Vec<u32>>>()
        else {
            return false;
        };
        if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
            return false;
        }
        for e in 0..3 {
            *walks.entry((v[e], v[(e + 1) % 3])).or_insert(0) += 1;
        }
        let [a, b, c] = t.map(|i| positions[i as usize].coords);
        volume += a.dot(&b.cross(&c)) / 6.0;
    }
    let paired = walks
        .iter()
        .all(|(&(u, v), &n)| n == 1 && walks.get(&(v, u)) == Some(&1));
    paired && volume > 0.0
}

/// Per position, an index shared by all positions equal to it (corners a DCC's export split
/// at seams and hard edges taken as one vertex), numbered in order of first appearance.
pub fn weld_positions(positions: impl Iterator<Item = Vector3<f64>>) -> Vec<u32> {
    use std::collections::HashMap;
    // `+ 0.0` turns −0 into 0, so both weld.
    let key = |p: Vector3<f64>| [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits);
    let mut ids: HashMap<[u64; 3], u32> = HashMap::new();
    positions
        .map(|p| {
            let next = ids.len() as u32;
            *ids.entry(key(p)).or_insert(next)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn the_polar_rotation_is_proper_and_refuses_what_is_not_finite() {
        let turn = Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        let stretched = turn * Matrix3::from_diagonal(&Vector3::new(2.0, 0.5, 1.2));
        let r = polar_rotation(&stretched).unwrap();
        assert!((r - turn).norm() < 1e-12, "{r}");
        // A reflection through its thinnest axis: the nearest proper rotation is the turn.
        let mirrored = turn * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.1));
        let r = polar_rotation(&mirrored).unwrap();
        assert!((r - turn).norm() < 1e-12, "{r}");
        let mut broken = stretched;
        broken[(1, 2)] = f64::NAN;
        assert!(polar_rotation(&broken).is_none());
    }

    fn tri() -> [Vector3<f64>; 3] {
        [Vector3::zeros(), Vector3::x(), Vector3::y()]
    }

    #[test]
    fn closest_point_regions() {
        let [a, b, c] = tri();
        let (w, inside) = closest_on_triangle(&Vector3::new(0.2, 0.2, 1.0), &a, &b, &c);
        assert!(inside);
        assert!((w[1] - 0.2).abs() < 1e-12 && (w[2] - 0.2).abs() < 1e-12);
        let (w, inside) = closest_on_triangle(&Vector3::new(2.0, -1.0, 0.0), &a, &b, &c);
        assert!(!inside);
        assert_eq!(w, [0.0, 1.0, 0.0]);
        // Beyond the hypotenuse: on the edge b–c at its midpoint.
        let (w, _) = closest_on_triangle(&Vector3::new(1.0, 1.0, 0.0), &a, &b, &c);
        assert!((w[1] - 0.5).abs() < 1e-12 && (w[2] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn segment_crossing_and_miss() {
        let [a, b, c] = tri();
        let hit = segment_crosses_triangle(
            &Vector3::new(0.25, 0.25, 1.0),
            &Vector3::new(0.25, 0.25, -3.0),
            &a,
            &b,
            &c,
        );
        let (t, w) = hit.unwrap();
        assert!((t - 0.25).abs() < 1e-12);
        assert!((w[1] - 0.25).abs() < 1e-12);
        let short = segment_crosses_triangle(
            &Vector3::new(0.25, 0.25, 1.0),
            &Vector3::new(0.25, 0.25, 0.5),
            &a,
            &b,
            &c,
        );
        assert!(short.is_none());
        let outside = segment_crosses_triangle(
            &Vector3::new(0.8, 0.8, 1.0),
            &Vector3::new(0.8, 0.8, -1.0),
            &a,
            &b,
            &c,
        );
        assert!(outside.is_none());
    }

    #[test]
    fn crossed_segments_meet_at_their_middles() {
        let (s, t) = closest_between_segments(
            &Vector3::new(-1.0, 0.0, 0.0),
            &Vector3::new(1.0, 0.0, 0.0),
            &Vector3::new(0.0, -1.0, 0.5),
            &Vector3::new(0.0, 1.0, 0.5),
        );
        assert!((s - 0.5).abs() < 1e-12 && (t - 0.5).abs() < 1e-12);
        // Parallel, overlapping: any pair at distance 1 (here the start of p).
        let (s, t) = closest_between_segments(
            &Vector3::new(0.0, 0.0, 0.0),
            &Vector3::new(1.0, 0.0, 0.0),
            &Vector3::new(0.0, 1.0, 0.0),
            &Vector3::new(1.0, 1.0, 0.0),
        );
        let p = Vector3::new(s, 0.0, 0.0);
        let q = Vector3::new(t, 1.0, 0.0);
        assert!(((p - q).norm() - 1.0).abs() < 1e-12);
    }
}
