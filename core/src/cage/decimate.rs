//! A cage from the mesh by vertex clustering (Rossignac–Borrel): the vertices are binned on a
//! cubic grid whose cell is chosen (bisection, deterministic) so that about `target` bins are
//! occupied; each bin becomes one node at the mean of its vertices; triangles are remapped and
//! the degenerate and duplicate ones dropped. With a centre node at the nodes' mean the fan
//! must be positively oriented everywhere and the surface closed (every edge used once each
//! way) — then the surface is star-shaped about the centre and the fan tetrahedralises it.
//! Otherwise the convex hull of the clustered nodes is used (noted on the cage). Either way the
//! cage is inflated about its centre to contain every mesh vertex.

use super::hull::convex_hull;
use super::{bounds, tet_volume, Cage, CageError};
use nalgebra::{Point3, Vector3};
use std::collections::{BTreeMap, HashSet};

/// Cluster index per vertex and the cluster count for grid cell `h`.
fn cluster(points: &[Point3<f64>], lo: Vector3<f64>, h: f64) -> (Vec<u32>, usize) {
    let mut ids = BTreeMap::new();
    let of: Vec<u32> = points
        .iter()
        .map(|p| {
            let c = (p.coords - lo) / h;
            let key = (c.x.floor() as i64, c.y.floor() as i64, c.z.floor() as i64);
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        })
        .collect();
    (of, ids.len())
}

/// A decimated cage of about `target` surface nodes (at least 4).
pub fn decimated(
    points: &[Point3<f64>],
    triangles: &[[u32; 3]],
    target: u32,
) -> Result<Cage, CageError> {
    if target < 4 {
        return Err(CageError::new(
            "cage_vertices",
            format!("must be at least 4, got {target}"),
        ));
    }
    if points.len() < 4 {
        return Err(CageError::new(
            "model",
            "the mesh has fewer than 4 vertices to decimate",
        ));
    }
    let (lo, hi) = bounds(points.iter().map(|p| p.coords));
    let size = (hi - lo).max();
    if !(size > 0.0 && size.is_finite()) {
        return Err(CageError::new("model", "the mesh has no finite extent"));
    }
    // Bisect the grid cell: the largest count not above the target.
    let (mut small, mut large) = (size * 1e-4, size * 1.01);
    let mut best = cluster(points, lo, large);
    for _ in 0..40 {
        let mid = 0.5 * (small + large);
        let c = cluster(points, lo, mid);
        if c.1 as u32 > target {
            small = mid;
        } else {
            large = mid;
            best = c;
        }
    }
    let (of, count) = best;
    let mut sums = vec![(Vector3::zeros(), 0usize); count];
    for (p, &c) in points.iter().zip(&of) {
        sums[c as usize].0 += p.coords;
        sums[c as usize].1 += 1;
    }
    let nodes: Vec<Vector3<f64>> = sums.iter().map(|(s, n)| s / *n as f64).collect();
    let mut seen = HashSet::new();
    let mut surface = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|i| of[i as usize]);
        if a == b || b == c || a == c {
            continue;
        }
        let mut key = [a, b, c];
        key.sort_unstable();
        if seen.insert(key) {
            surface.push([a, b, c]);
        }
    }
    let centre = nodes.iter().sum::<Vector3<f64>>() / nodes.len() as f64;
    let star = closed(&surface) && {
        let mut with_centre = nodes.clone();
        with_centre.push(centre);
        let c = nodes.len() as u32;
        surface
            .iter()
            .all(|f| tet_volume(&[f[0], f[2], f[1], c], &with_centre) > 0.0)
    };
    let (surface, note) = if star {
        (surface, None)
    } else {
        let hull = convex_hull(&nodes).ok_or_else(|| {
            CageError::new(
                "cage_vertices",
                format!("the {count} clustered vertices span no volume; raise cage_vertices"),
            )
        })?;
        (
            hull,
            Some(format!(
                "the decimated surface ({count} nodes) is not closed and star-shaped about its \
                 centre; the cage is the convex hull of the clustered nodes"
            )),
        )
    };
    // Keep only the nodes the surface uses (a hull drops interior clusters), in order.
    let mut used = vec![u32::MAX; nodes.len()];
    let mut kept = Vec::new();
    for f in &surface {
        for &n in f {
            if used[n as usize] == u32::MAX {
                used[n as usize] = kept.len() as u32;
                kept.push(n);
            }
        }
    }
    kept.sort_unstable();
    for (new, &old) in kept.iter().enumerate() {
        used[old as usize] = new as u32;
    }
    let compact: Vec<Vector3<f64>> = kept.iter().map(|&n| nodes[n as usize]).collect();
    let faces: Vec<[u32; 3]> = surface
        .iter()
        .map(|f| f.map(|n| used[n as usize]))
        .collect();
    let mut cage = Cage::fan("decimated", compact, &faces, centre);
    cage.note = note;
    let c = (cage.nodes.len() - 1) as u32;
    cage.inflate_to_contain(c, points);
    Ok(cage)
}

/// Every directed edge has exactly one reverse.
fn closed(faces: &[[u32; 3]]) -> bool {
    let mut edges = std::collections::HashMap::new();
    for f in faces {
        for k in 0..3 {
            *edges.entry((f[k], f[(k + 1) % 3])).or_insert(0u32) += 1;
        }
    }
    !faces.is_empty()
        && edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
}
