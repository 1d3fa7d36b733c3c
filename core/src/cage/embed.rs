//! Barycentric embedding of points in a cage's tets (see the [`super`] module docs): the
//! containing tet, or the least-outside one (largest smallest barycentric coordinate) with
//! extrapolated weights; 4 weights padded to the lattice embedding's 8.

use crate::lattice::Embedding;
use nalgebra::{Matrix3, Point3, Vector3};

/// Per tet, the inverse of its edge matrix `[b − a, c − a, d − a]` (`None`: degenerate).
pub(crate) fn inverses(nodes: &[Vector3<f64>], tets: &[[u32; 4]]) -> Vec<Option<Matrix3<f64>>> {
    tets.iter()
        .map(|t| {
            let a = nodes[t[0] as usize];
            Matrix3::from_columns(&[
                nodes[t[1] as usize] - a,
                nodes[t[2] as usize] - a,
                nodes[t[3] as usize] - a,
            ])
            .try_inverse()
        })
        .collect()
}

/// Barycentric coordinates of `p` in tet `t` (sum to 1).
pub(crate) fn barycentric(
    nodes: &[Vector3<f64>],
    t: &[u32; 4],
    inverse: &Matrix3<f64>,
    p: &Vector3<f64>,
) -> [f64; 4] {
    let l = inverse * (p - nodes[t[0] as usize]);
    [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
}

/// Embed `points` in `tets` over `nodes` (rest positions). With no usable tet every point is
/// bound to node 0 with weight 1 (it then moves rigidly with that node).
pub fn embed(nodes: &[Vector3<f64>], tets: &[[u32; 4]], points: &[Point3<f64>]) -> Embedding {
    let inv = inverses(nodes, tets);
    let mut out = Embedding {
        nodes: Vec::with_capacity(points.len()),
        weights: Vec::with_capacity(points.len()),
    };
    for p in points {
        let mut best: Option<(f64, usize, [f64; 4])> = None;
        for (i, (t, m)) in tets.iter().zip(&inv).enumerate() {
            let Some(m) = m else { continue };
            let l = barycentric(nodes, t, m, &p.coords);
            let worst = l.iter().copied().fold(f64::INFINITY, f64::min);
            if best.is_none_or(|(w, _, _)| worst > w) {
                best = Some((worst, i, l));
            }
            if worst >= 0.0 {
                break; // inside: the first containing tet (deterministic order)
            }
        }
        match best {
            Some((_, i, l)) => {
                let t = tets[i];
                out.nodes
                    .push([t[0], t[1], t[2], t[3], t[0], t[0], t[0], t[0]]);
                out.weights
                    .push([l[0], l[1], l[2], l[3], 0.0, 0.0, 0.0, 0.0]);
            }
            None => {
                out.nodes.push([0; 8]);
                out.weights.push([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
            }
        }
    }
    out
}
