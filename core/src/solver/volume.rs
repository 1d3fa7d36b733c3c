//! Volume preservation of lattice bodies (physics §9, Terasawa §3.2).
//!
//! After the unconstrained step, the body's nodes are moved along the gradient of its volume
//! so that the volume returns to `scale × V0` (Lagrange multiplier, a few Newton iterations,
//! displacement weighted by 1/m so momentum is kept: the volume gradient sums to zero), and
//! the displacement divided by Δt is added to the velocities (the matching velocity
//! correction).
//!
//! Deviation from Terasawa: the volume is the sum of the signed volumes of the body's lattice
//! cells, each split into six tetrahedra around its 0–7 diagonal, not the volume of the
//! nodes' convex hull. It is exact for the lattice's own (possibly concave) shape, cheap
//! (linear in the cells), has a closed-form gradient, and does not jump when a node enters or
//! leaves the hull. Terasawa's c2/c3 terms (staying near the unconstrained displacement and
//! its direction) are what the minimum-norm, mass-weighted Lagrange step does by construction.

use super::NodeState;
use nalgebra::Vector3;

/// The six tetrahedra of a cell (Kuhn's split; corner bit 1 = +x, 2 = +y, 4 = +z), all
/// positively oriented for an unrotated cell, sharing the 0–7 diagonal.
pub(crate) const TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 3, 2, 7],
    [0, 2, 6, 7],
    [0, 6, 4, 7],
    [0, 4, 5, 7],
    [0, 5, 1, 7],
];

/// A body whose volume is held at `scale × rest_volume`. The target moves towards a changed
/// scale at `max_rate` (fraction of V0 per second), so squash and stretch is animated, not a
/// jump.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeConstraint {
    /// Index of the body in the world.
    pub body: usize,
    /// V0, m³, measured when the constraint was added.
    pub rest_volume: f64,
    /// Target volume over V0 (1: preserve; other values squash or inflate the body).
    pub scale: f64,
    /// Newton iterations per step.
    pub iterations: u32,
    /// How fast the target follows a changed `scale`, fraction of V0 per second.
    pub max_rate: f64,
    /// The target volume of the last step, m³.
    pub target: f64,
}

/// Signed volume of one cell, m³.
pub fn cell_volume(cell: &[u32; 8], positions: &[Vector3<f64>]) -> f64 {
    let p = |c: usize| positions[cell[c] as usize];
    TETS.iter()
        .map(|t| {
            let a = p(t[0]);
            (p(t[1]) - a).dot(&(p(t[2]) - a).cross(&(p(t[3]) - a)))
        })
        .sum::<f64>()
        / 6.0
}

/// Enclosed volume of a set of cells (sum of their signed volumes), m³.
pub fn cells_volume(cells: &[[u32; 8]], positions: &[Vector3<f64>]) -> f64 {
    cells.iter().map(|c| cell_volume(c, positions)).sum()
}

/// Move the nodes of `cells` (world indices in `nodes`, within `range`) so their volume
/// becomes `target`. Adds `velocity_fraction` ×
/// displacement / `dt` to the velocities (1 when the correction only undoes this step's drift;
/// less when part of it moves the target, which must not throw the nodes). Returns the
/// volume before the correction. `grad` is scratch space (reused, so the step allocates
/// nothing).
#[allow(clippy::too_many_arguments)]
pub(crate) fn correct_volume(
    nodes: &mut NodeState,
    cells: &[[u32; 8]],
    range: std::ops::Range<usize>,
    target: f64,
    iterations: u32,
    dt: f64,
    velocity_fraction: f64,
    grad: &mut Vec<Vector3<f64>>,
) -> f64 {
    grad.clear();
    grad.resize(range.len(), Vector3::zeros());
    let before = cells_volume(cells, &nodes.position);
    let base = range.start;
    for _ in 0..iterations {
        grad.iter_mut().for_each(|g| *g = Vector3::zeros());
        let mut volume = 0.0;
        {
            let pos = &nodes.position;
            for cell in cells {
                for t in &TETS {
                    let [a, b, c, d] = t.map(|k| cell[k] as usize);
                    let (eb, ec, ed) = (pos[b] - pos[a], pos[c] - pos[a], pos[d] - pos[a]);
                    let (gb, gc, gd) = (ec.cross(&ed), ed.cross(&eb), eb.cross(&ec));
                    volume += eb.dot(&gb);
                    grad[b - base] += gb;
                    grad[c - base] += gc;
                    grad[d - base] += gd;
                    grad[a - base] -= gb + gc + gd;
                }
            }
        }
        // Gradient of V (the sixths folded in here).
        volume /= 6.0;
        let residual = target - volume;
        let mut denom = 0.0;
        for (j, g) in grad.iter_mut().enumerate() {
            *g /= 6.0;
            denom += nodes.inv_mass[base + j] * g.norm_squared();
        }
        if denom <= 0.0 || !denom.is_finite() || residual == 0.0 {
            break;
        }
        let lambda = residual / denom;
        for (j, g) in grad.iter().enumerate() {
            let i = base + j;
            let dx = g * (lambda * nodes.inv_mass[i]);
            nodes.position[i] += dx;
            nodes.velocity[i] += dx * (velocity_fraction / dt);
        }
    }
    before
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_cell(scale: Vector3<f64>) -> (Vec<Vector3<f64>>, [u32; 8]) {
        let xs = (0..8)
            .map(|c| {
                Vector3::new(
                    (c & 1) as f64 * scale.x,
                    ((c >> 1) & 1) as f64 * scale.y,
                    ((c >> 2) & 1) as f64 * scale.z,
                )
            })
            .collect();
        (xs, [0, 1, 2, 3, 4, 5, 6, 7])
    }

    #[test]
    fn cell_volume_is_the_box_volume_and_the_correction_reaches_the_target() {
        let (mut xs, cell) = unit_cell(Vector3::new(2.0, 3.0, 0.5));
        assert!((cell_volume(&cell, &xs) - 3.0).abs() < 1e-14);
        // A sheared cell keeps its volume.
        for (c, x) in xs.iter_mut().enumerate() {
            if c & 2 != 0 {
                x.x += 0.7;
            }
        }
        assert!((cell_volume(&cell, &xs) - 3.0).abs() < 1e-14);
        let mut nodes = NodeState {
            position: xs.clone(),
            velocity: vec![Vector3::zeros(); 8],
            mass: vec![1.0; 8],
            inv_mass: vec![1.0; 8],
        };
        let before = correct_volume(
            &mut nodes,
            &[cell],
            0..8,
            2.4,
            3,
            0.01,
            1.0,
            &mut Vec::new(),
        );
        assert!((before - 3.0).abs() < 1e-14);
        let after = cells_volume(&[cell], &nodes.position);
        assert!((after - 2.4).abs() < 1e-9, "{after}");
        // Momentum kept: the displacements (and velocity changes) sum to zero.
        let p: Vector3<f64> = nodes.velocity.iter().sum();
        assert!(p.norm() < 1e-9, "{p}");
        assert!(nodes.velocity.iter().any(|v| v.norm() > 1.0));
    }
}
