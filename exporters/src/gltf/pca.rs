//! The compact morph cache (`cache = "pca"`, issue 23 item 3): a mesh's per-frame
//! displacements from its rest pose, `D` (frames × 3·vertices), as the fewest principal
//! components that keep every vertex within a bound: `D ≈ W·T`, `T` the K morph targets and
//! `W` the per-frame weights. The components come from the eigenvectors of the frames' Gram
//! matrix `D·Dᵀ` (frames × frames, small next to the vertices), so the weights `U` are
//! orthonormal columns and any other per-vertex attribute (the normals' change) is fitted to
//! the same weights by least squares as `Uᵀ·X`.

use springbake_core::nalgebra::{DMatrix, SymmetricEigen};

/// Most frames the Gram matrix is built for (4096² doubles are 128 MB).
pub const MAX_FRAMES: usize = 4096;
/// Most components kept; past them the full morph cache is smaller anyway.
pub const MAX_COMPONENTS: usize = 256;

/// A mesh's displacements reduced to K components.
pub struct Components {
    /// Per frame, the K weights (frame-major).
    pub weights: Vec<Vec<f64>>,
    /// Per component, the target: 3 values per vertex.
    pub targets: Vec<Vec<f64>>,
    /// Orthonormal frame vectors of the kept components, to fit other attributes.
    basis: Vec<Vec<f64>>,
    /// Largest vertex distance between the bake and its reconstruction, in the rows' units.
    pub max_error: f64,
}

impl Components {
    /// The targets of another attribute `rows` (frames × 3·vertices) for the same weights,
    /// least squares.
    pub fn fit(&self, rows: &[Vec<f64>]) -> Vec<Vec<f64>> {
        project(&self.basis, rows)
    }
}

/// A cache ready to write: targets whose weights stay in [0, 1] at every frame.
pub struct UnitCache {
    /// Per frame, one weight per target.
    pub weights: Vec<Vec<f64>>,
    pub targets: Vec<Vec<f64>>,
    pub normal_targets: Vec<Vec<f64>>,
    pub names: Vec<String>,
    /// Principal components kept (the offset target not counted).
    pub components: usize,
    pub max_error: f64,
}

/// Maps each component's weights onto [0, 1] (`w = lo + (hi − lo)·w'`), scaling its targets
/// by `hi − lo` and gathering `Σ lo·target` into a first target named `offset`, weight 1 at
/// every frame (left out when it is zero). The motion is the same to rounding.
pub fn unit_weights(c: Components, normal_targets: Vec<Vec<f64>>) -> UnitCache {
    let k = c.targets.len();
    let width = c.targets.first().map_or(0, Vec::len);
    let (mut offset, mut offset_n) = (vec![0.0; width], vec![0.0; width]);
    let (mut targets, mut normals) = (c.targets, normal_targets);
    let mut weights = c.weights;
    for j in 0..k {
        let lo = weights.iter().map(|w| w[j]).fold(f64::INFINITY, f64::min);
        let hi = weights
            .iter()
            .map(|w| w[j])
            .fold(f64::NEG_INFINITY, f64::max);
        let span = if hi > lo { hi - lo } else { 1.0 };
        for (o, &t) in offset.iter_mut().zip(&targets[j]) {
            *o += lo * t;
        }
        for (o, &t) in offset_n.iter_mut().zip(&normals[j]) {
            *o += lo * t;
        }
        targets[j].iter_mut().for_each(|t| *t *= span);
        normals[j].iter_mut().for_each(|t| *t *= span);
        for w in &mut weights {
            w[j] = (w[j] - lo) / span;
        }
    }
    let mut names: Vec<String> = (0..k).map(|i| format!("pc_{i:03}")).collect();
    if k > 0 && offset.iter().any(|&x| x != 0.0) {
        targets.insert(0, offset);
        normals.insert(0, offset_n);
        names.insert(0, "offset".into());
        for w in &mut weights {
            w.insert(0, 1.0);
        }
    }
    UnitCache {
        weights,
        targets,
        normal_targets: normals,
        names,
        components: k,
        max_error: c.max_error,
    }
}

/// `Σ_f basis[k][f] · rows[f]` for every k.
fn project(basis: &[Vec<f64>], rows: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let width = rows.first().map_or(0, Vec::len);
    basis
        .iter()
        .map(|u| {
            let mut t = vec![0.0; width];
            for (row, &uf) in rows.iter().zip(u) {
                for (ti, &x) in t.iter_mut().zip(row) {
                    *ti += uf * x;
                }
            }
            t
        })
        .collect()
}

/// Eigen-order candidates past the components already kept that each step weighs.
const WINDOW: usize = 16;

/// The fewest components of `rows` (frames × 3·vertices) whose reconstruction leaves no
/// vertex farther than `bound` from its row, or all that carry any variance (at most
/// [`MAX_COMPONENTS`]) when none do.
///
/// The components are the Gram matrix's eigenvectors; each step keeps the one, among the
/// next [`WINDOW`] by variance, that most lowers the largest vertex error (weighed where the
/// error is near its largest; the kept set's true error is measured over every vertex). Variance order
/// alone minimises the mean error and can spend several components before the one that
/// moves the worst vertex (a rubber Suzanne: 20 components against 17 for 1 mm).
pub fn principal_components(rows: &[Vec<f64>], bound: f64) -> Result<Components, String> {
    let frames = rows.len();
    if frames > MAX_FRAMES {
        return Err(format!(
            "cache = \"pca\" handles at most {MAX_FRAMES} frames, the bake has {frames}; use \
             cache = \"morph\" or \"skin\""
        ));
    }
    let gram = DMatrix::from_fn(frames, frames, |a, b| {
        rows[a]
            .iter()
            .zip(&rows[b])
            .map(|(x, y)| x * y)
            .sum::<f64>()
    });
    let eigen = SymmetricEigen::new(gram);
    let mut order: Vec<usize> = (0..frames).collect();
    // Largest variance first; ties by index so the order is deterministic.
    order.sort_by(|&a, &b| {
        eigen.eigenvalues[b]
            .total_cmp(&eigen.eigenvalues[a])
            .then(a.cmp(&b))
    });
    let largest = order
        .first()
        .map_or(0.0, |&i| eigen.eigenvalues[i])
        .max(0.0);
    // Components with no variance left (to rounding) add nothing.
    order.retain(|&i| eigen.eigenvalues[i] > largest * 1e-24);
    // Per candidate: its frame vector and target once computed; `kept` once chosen.
    let mut candidates: Vec<Option<(Vec<f64>, Vec<f64>)>> = vec![None; order.len()];
    let mut kept = vec![false; order.len()];
    let mut residual: Vec<Vec<f64>> = rows.to_vec();
    let mut components = Components {
        weights: vec![Vec::new(); frames],
        targets: Vec::new(),
        basis: Vec::new(),
        max_error: max_vertex_error(&residual),
    };
    while components.max_error > bound && components.targets.len() < MAX_COMPONENTS {
        let hot = worst_vertices(&residual, components.max_error);
        let window = (components.targets.len() + WINDOW).min(order.len());
        let mut best: Option<(usize, f64)> = None;
        for (c, &i) in order[..window].iter().enumerate() {
            if kept[c] {
                continue;
            }
            let slot = &mut candidates[c];
            if slot.is_none() {
                let u: Vec<f64> = eigen.eigenvectors.column(i).iter().copied().collect();
                let target = project(std::slice::from_ref(&u), rows).remove(0);
                *slot = Some((u, target));
            }
            let Some((u, target)) = slot.as_ref() else {
                continue;
            };
            let error = error_without(&residual, &hot, u, target);
            if best.is_none_or(|(_, e)| error < e) {
                best = Some((c, error));
            }
        }
        let Some((mut c, error)) = best else {
            break; // every component kept
        };
        // No single component lowers the worst errors (they need several together): take the
        // next by variance.
        // (The first one not kept is inside the window, so it was weighed above.)
        if error >= components.max_error * STALL {
            c = kept.iter().position(|k| !k).unwrap_or(c);
        }
        let Some((u, target)) = candidates[c].take() else {
            break;
        };
        kept[c] = true;
        for (f, row) in residual.iter_mut().enumerate() {
            for (r, &t) in row.iter_mut().zip(&target) {
                *r -= u[f] * t;
            }
            components.weights[f].push(u[f]);
        }
        components.targets.push(target);
        components.basis.push(u);
        components.max_error = max_vertex_error(&residual);
    }
    Ok(components)
}

/// The (frame, vertex) pairs whose error is within [`HOT`] of the largest, the [`MAX_HOT`]
/// largest of them: where the next component's effect on the largest error is weighed.
fn worst_vertices(residual: &[Vec<f64>], largest: f64) -> Vec<(usize, usize)> {
    let floor = (HOT * largest).powi(2);
    let mut hot: Vec<(f64, usize, usize)> = Vec::new();
    for (f, row) in residual.iter().enumerate() {
        for (v, r) in row.chunks_exact(3).enumerate() {
            let e = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            if e >= floor {
                hot.push((e, f, v));
            }
        }
    }
    if hot.len() > MAX_HOT {
        hot.select_nth_unstable_by(MAX_HOT, |a, b| {
            b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2))
        });
        hot.truncate(MAX_HOT);
    }
    hot.into_iter().map(|(_, f, v)| (f, v)).collect()
}

/// A step whose best component leaves the largest error above this fraction of it stalls.
const STALL: f64 = 0.99;

/// Errors this close to the largest are weighed when choosing the next component.
const HOT: f64 = 0.7;
/// Most (frame, vertex) pairs weighed.
const MAX_HOT: usize = 8_192;

/// Largest vertex error among `hot` left when `u ⊗ target` is taken from `residual` too.
fn error_without(residual: &[Vec<f64>], hot: &[(usize, usize)], u: &[f64], target: &[f64]) -> f64 {
    let mut worst: f64 = 0.0;
    for &(f, v) in hot {
        let (r, t) = (&residual[f][3 * v..3 * v + 3], &target[3 * v..3 * v + 3]);
        let d = [r[0] - u[f] * t[0], r[1] - u[f] * t[1], r[2] - u[f] * t[2]];
        worst = worst.max(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    worst.sqrt()
}

/// Largest length of a vertex's 3 values in any row.
fn max_vertex_error(rows: &[Vec<f64>]) -> f64 {
    rows.iter()
        .flat_map(|row| row.chunks_exact(3))
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_motion_of_two_modes_needs_two_components_and_reconstructs() {
        // 30 frames of 50 vertices: a sway (x) and a squash (y), each with its own time course.
        let rows: Vec<Vec<f64>> = (0..30)
            .map(|f| {
                let t = f as f64 / 30.0;
                (0..50)
                    .flat_map(|v| {
                        let h = v as f64 / 50.0;
                        [
                            0.1 * h * (6.0 * t).sin(),
                            -0.05 * h * h * (3.0 * t).cos(),
                            0.0,
                        ]
                    })
                    .collect()
            })
            .collect();
        let c = principal_components(&rows, 1e-9).unwrap();
        assert_eq!(c.targets.len(), 2);
        assert!(c.max_error < 1e-9, "{}", c.max_error);
        for (f, row) in rows.iter().enumerate() {
            for (i, &x) in row.iter().enumerate() {
                let back: f64 = (0..2).map(|k| c.weights[f][k] * c.targets[k][i]).sum();
                assert!((back - x).abs() < 1e-9);
            }
        }
        // Weights in [0, 1] play the same motion.
        let unit = unit_weights(
            principal_components(&rows, 1e-9).unwrap(),
            vec![vec![0.0; 150]; 2],
        );
        assert_eq!(unit.names[0], "offset");
        for (f, row) in rows.iter().enumerate() {
            assert!(unit.weights[f].iter().all(|w| (0.0..=1.0).contains(w)));
            for (i, &x) in row.iter().enumerate() {
                let back: f64 = (0..unit.targets.len())
                    .map(|k| unit.weights[f][k] * unit.targets[k][i])
                    .sum();
                assert!((back - x).abs() < 1e-9);
            }
        }
        // A loose bound keeps only the larger mode.
        let one = principal_components(&rows, 0.06).unwrap();
        assert_eq!(one.targets.len(), 1);
        assert!(one.max_error <= 0.06);
        // A still mesh needs none.
        let still = principal_components(&vec![vec![0.0; 9]; 4], 1e-6).unwrap();
        assert!(still.targets.is_empty());
    }
}
