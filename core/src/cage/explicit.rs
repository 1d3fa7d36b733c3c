//! Explicit analysis models: the scene lists the nodes and springs (see the [`super`] module
//! docs). Input is checked here with the offending field named (`nodes[i]`, `springs[k]`).

use super::hull::convex_hull;
use super::{tet_volume, Cage, CageError};
use nalgebra::Vector3;

/// Build an explicit cage from `nodes` (world metres) and `springs` (node index pairs).
pub fn explicit(nodes: &[Vector3<f64>], springs: &[[usize; 2]]) -> Result<Cage, CageError> {
    if nodes.len() < 4 {
        return Err(CageError::new(
            "nodes",
            format!(
                "an explicit model needs at least 4 nodes, got {}",
                nodes.len()
            ),
        ));
    }
    if nodes.len() > u32::MAX as usize / 2 {
        return Err(CageError::new("nodes", "too many nodes"));
    }
    if let Some(i) = nodes.iter().position(|x| !x.iter().all(|c| c.is_finite())) {
        return Err(CageError::new(
            format!("nodes[{i}]"),
            "coordinates must be finite",
        ));
    }
    if springs.is_empty() {
        return Err(CageError::new(
            "springs",
            "an explicit model needs springs: a list of [i, j] node pairs",
        ));
    }
    let mut seen = std::collections::HashMap::new();
    let mut has_spring = vec![false; nodes.len()];
    for (k, &[a, b]) in springs.iter().enumerate() {
        let field = format!("springs[{k}]");
        if let Some(&n) = [a, b].iter().find(|&&n| n >= nodes.len()) {
            return Err(CageError::new(
                field,
                format!(
                    "node {n} out of range: the model has {} nodes (0 to {})",
                    nodes.len(),
                    nodes.len() - 1
                ),
            ));
        }
        if a == b {
            return Err(CageError::new(field, format!("joins node {a} to itself")));
        }
        if let Some(first) = seen.insert((a.min(b), a.max(b)), k) {
            return Err(CageError::new(
                field,
                format!("repeats springs[{first}] = [{a}, {b}]"),
            ));
        }
        if (nodes[a] - nodes[b]).norm() == 0.0 {
            return Err(CageError::new(
                field,
                format!("nodes {a} and {b} are at the same place (zero rest length)"),
            ));
        }
        has_spring[a] = true;
        has_spring[b] = true;
    }
    if let Some(i) = has_spring.iter().position(|h| !h) {
        return Err(CageError::new(
            format!("nodes[{i}]"),
            "has no spring (it would move on its own)",
        ));
    }
    let hull = convex_hull(nodes).ok_or_else(|| {
        CageError::new(
            "nodes",
            "the nodes span no volume (all on one plane or line); use model = \"plane\" for sheets",
        )
    })?;
    let on_hull: std::collections::BTreeSet<u32> = hull.iter().flatten().copied().collect();
    let hull_centre = on_hull
        .iter()
        .map(|&i| nodes[i as usize])
        .sum::<Vector3<f64>>()
        / on_hull.len() as f64;
    let scale = on_hull
        .iter()
        .map(|&i| (nodes[i as usize] - hull_centre).norm())
        .fold(0.0, f64::max);
    let strictly_inside = |p: &Vector3<f64>| {
        hull.iter().all(|f| {
            let [x, y, z] = f.map(|i| nodes[i as usize]);
            let n = (y - x).cross(&(z - x));
            n.dot(&(p - x)) < -1e-9 * scale * n.norm()
        })
    };
    let apex = (0..nodes.len())
        .filter(|&i| !on_hull.contains(&(i as u32)) && strictly_inside(&nodes[i]))
        .min_by(|&i, &j| {
            (nodes[i] - hull_centre)
                .norm_squared()
                .total_cmp(&(nodes[j] - hull_centre).norm_squared())
        })
        .map(|i| i as u32)
        .or_else(|| on_hull.iter().next().copied())
        .unwrap_or(0);
    let tets: Vec<[u32; 4]> = hull
        .iter()
        .filter(|f| !f.contains(&apex))
        .map(|f| [f[0], f[2], f[1], apex]) // outward face: positive with the apex behind
        .filter(|t| tet_volume(t, nodes) > 1e-12 * scale.powi(3))
        .collect();
    Ok(Cage {
        model: "explicit",
        nodes: nodes.to_vec(),
        springs: springs.iter().map(|s| s.map(|n| n as u32)).collect(),
        tets,
        note: None,
        uniform_springs: true,
    })
}
