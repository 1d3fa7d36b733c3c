//! Polygon triangulation shared by the importers (OBJ n-gons, USD faces): ear clipping in the
//! polygon's best-fit plane (Newell's normal), linear on convex faces, bounded work on hostile
//! ones, always `n − 2` triangles wound like the polygon.

/// Triangulate a polygon given its corner positions: triangles as corner indices, wound like
/// the polygon. Ear clipping in the best-fit plane (Newell's normal); always `n - 2` triangles.
pub fn triangulate(points: &[[f64; 3]]) -> Vec<[usize; 3]> {
    use nalgebra::Vector3;
    let n = points.len();
    if n < 3 {
        return Vec::new();
    }
    if n == 3 {
        return vec![[0, 1, 2]];
    }
    let p: Vec<Vector3<f64>> = points
        .iter()
        .map(|q| Vector3::new(q[0], q[1], q[2]))
        .collect();
    // Newell's normal: robust best-fit plane orientation for non-planar polygons.
    let mut normal = Vector3::<f64>::zeros();
    for i in 0..n {
        let a = p[i];
        let b = p[(i + 1) % n];
        normal.x += (a.y - b.y) * (a.z + b.z);
        normal.y += (a.z - b.z) * (a.x + b.x);
        normal.z += (a.x - b.x) * (a.y + b.y);
    }
    let len = normal.norm();
    if len <= 0.0 || !len.is_finite() {
        return (1..n - 1).map(|i| [0, i, i + 1]).collect();
    }
    let normal = normal / len;
    // Basis (u, w, normal) right-handed: the polygon winds counter-clockwise in (u, w).
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = helper.cross(&normal).normalize();
    let w = normal.cross(&u);
    let q: Vec<[f64; 2]> = p.iter().map(|x| [x.dot(&u), x.dot(&w)]).collect();
    let scale = q
        .iter()
        .flat_map(|a| [a[0].abs(), a[1].abs()])
        .fold(0.0_f64, f64::max)
        .max(1e-300);
    let eps = 1e-12 * scale * scale;

    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    // Ring as a doubly linked list. Only reflex (or flat) corners can lie inside an ear of a
    // simple polygon, and clipping an ear never makes a corner reflex, so the candidates are
    // the corners reflex at the start, pruned as they turn convex: a convex n-gon is O(n).
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let mut alive = vec![true; n];
    let corner = |prev: &[usize], next: &[usize], b: usize| cross(q[prev[b]], q[b], q[next[b]]);
    let mut reflex: Vec<bool> = (0..n).map(|b| corner(&prev, &next, b) <= eps).collect();
    let mut candidates: Vec<usize> = (0..n).filter(|&b| reflex[b]).collect();
    // Bound on containment tests; past it the rest is fanned (hostile huge concave faces).
    let mut budget: u64 = 50_000_000;
    let mut out = Vec::with_capacity(n - 2);
    let mut remaining = n;
    let mut cur = 0;
    let mut stalls = 0;
    while remaining > 3 {
        let (a, c) = (prev[cur], next[cur]);
        let is_ear = !reflex[cur] && {
            let (qa, qb, qc) = (q[a], q[cur], q[c]);
            budget = budget.saturating_sub(candidates.len() as u64);
            !candidates.iter().any(|&j| {
                if !alive[j] || !reflex[j] || j == a || j == cur || j == c {
                    return false;
                }
                let x = q[j];
                if x == qa || x == qb || x == qc {
                    return false;
                }
                cross(qa, qb, x) >= -eps && cross(qb, qc, x) >= -eps && cross(qc, qa, x) >= -eps
            })
        };
        // A full lap without an ear (degenerate or self-intersecting input) or an exhausted
        // budget: clip the current corner anyway so the walk always ends in n - 2 triangles.
        if is_ear || stalls > remaining || budget == 0 {
            out.push([a, cur, c]);
            alive[cur] = false;
            next[a] = c;
            prev[c] = a;
            remaining -= 1;
            for v in [a, c] {
                reflex[v] = corner(&prev, &next, v) <= eps;
                if reflex[v] && !candidates.contains(&v) {
                    candidates.push(v); // only after a forced clip of broken input
                }
            }
            candidates.retain(|&j| alive[j] && reflex[j]);
            cur = a;
            stalls = 0;
        } else {
            cur = next[cur];
            stalls += 1;
        }
    }
    let a = prev[cur];
    out.push([a, cur, next[cur]]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area2(q: &[[f64; 3]], t: &[usize; 3]) -> f64 {
        let a = nalgebra::Vector3::from(q[t[0]]);
        let b = nalgebra::Vector3::from(q[t[1]]);
        let c = nalgebra::Vector3::from(q[t[2]]);
        (b - a).cross(&(c - a)).z
    }

    #[test]
    fn concave_polygon_ear_clipping_preserves_signed_area() {
        // An L shape (area 3), counter-clockwise in XY.
        let pts = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
        ];
        let tris = triangulate(&pts);
        assert_eq!(tris.len(), 4);
        let total: f64 = tris.iter().map(|t| area2(&pts, t) / 2.0).sum();
        assert!((total - 3.0).abs() < 1e-12, "{total}");
        assert!(tris.iter().all(|t| area2(&pts, t) > 0.0), "{tris:?}");
    }

    fn polygon_area(pts: &[[f64; 3]]) -> f64 {
        let n = pts.len();
        (0..n)
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % n]);
                (a[0] * b[1] - b[0] * a[1]) / 2.0
            })
            .sum()
    }

    #[test]
    fn big_convex_and_spiky_polygons_triangulate_with_their_area() {
        // 20 000-gon circle: linear time on convex input.
        let circle: Vec<[f64; 3]> = (0..20_000)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 20_000.0;
                [a.cos(), a.sin(), 0.0]
            })
            .collect();
        // 2 000-corner star: half the corners reflex.
        let star: Vec<[f64; 3]> = (0..2_000)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 2_000.0;
                let r = if k % 2 == 0 { 1.0 } else { 0.7 };
                [r * a.cos(), r * a.sin(), 0.0]
            })
            .collect();
        for pts in [circle, star] {
            let tris = triangulate(&pts);
            assert_eq!(tris.len(), pts.len() - 2);
            let signed: f64 = tris.iter().map(|t| area2(&pts, t) / 2.0).sum();
            let unsigned: f64 = tris.iter().map(|t| area2(&pts, t).abs() / 2.0).sum();
            let want = polygon_area(&pts);
            assert!((signed - want).abs() < 1e-9, "{signed} vs {want}");
            assert!(
                (unsigned - want).abs() < 1e-9,
                "folded triangles: {unsigned} vs {want}"
            );
        }
    }

    #[test]
    fn collinear_polygon_still_gives_n_minus_2_triangles() {
        let pts = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
        ];
        assert_eq!(triangulate(&pts).len(), 2);
    }
}
