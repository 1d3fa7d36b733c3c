//! Secondary action (Terasawa §4.2.4, eq 4.1; physics §11): a child part simulated as its own
//! body, anchored to its parent through three of its nodes.
//!
//! The three anchor nodes `x₁ x₂ x₃` of the child correspond to three points `x'₁ x'₂ x'₃`
//! embedded in the parent's lattice (trilinear weights, fixed at rest, where the anchors were).
//! Eq 4.1 asks for the 3×3 transform `E` with `[x'₁ x'₂ x'₃] = E [x₁ x₂ x₃]`; with positions
//! taken relative to the first anchor, the two edges and a normal scaled to a length give the
//! frames `F = [x₂−x₁, x₃−x₁, n]`, `F' = [x'₂−x'₁, x'₃−x'₁, n']` and `E = F' F⁻¹`. Every child
//! node is then mapped `x ← x'₁ + E (x − x₁)`, `v ← v̄' + E (v − v̄)` (`v̄`, `v̄'`: the mean
//! anchor velocities), which carries the child with the parent's motion and deformation.
//!
//! Between those exact placements (once per output frame, [`Attachment::after_frame`]) the
//! child is simulated freely except its three anchor nodes, which follow a path from the
//! parent points' position towards where their velocity takes them over the frame
//! ([`Attachment::before_frame`]): the rest of the child lags, swings and wobbles behind
//! the parent — the secondary action.

use crate::solver::{
    BodyHandle, ConstraintError, Interpolation, Path, TrajectoryConstraint, World,
};
use nalgebra::{Matrix3, Vector3};

/// A child body anchored to a parent through three nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Attachment {
    pub child: BodyHandle,
    pub parent: BodyHandle,
    /// World indices of the child's three anchor nodes.
    pub anchors: [usize; 3],
    /// Per anchor: world node indices of the parent cell holding the matching point.
    pub parent_nodes: [[usize; 8]; 3],
    /// Per anchor: trilinear weights of that point in the cell.
    pub parent_weights: [[f64; 8]; 3],
    /// The anchors' path constraint over the current frame.
    constraint: Option<TrajectoryConstraint>,
}

/// Why an attachment cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AttachError {
    #[error("the three anchor nodes must be different and not on one line")]
    Degenerate,
    #[error("{0}")]
    Constraint(#[from] ConstraintError),
}

/// `[b − a, c − a, n]` with `n` the normal scaled to the square root of the area (a length).
fn frame(a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>) -> Matrix3<f64> {
    let (e1, e2) = (b - a, c - a);
    let n = e1.cross(&e2);
    let n = n / n.norm().sqrt().max(1e-300);
    Matrix3::from_columns(&[e1, e2, n])
}

impl Attachment {
    /// Anchor `anchors` (world node indices of `child`) to the parent points given by their
    /// cells and weights (e.g. the anchors' rest positions embedded in the parent's lattice).
    pub fn new(
        world: &World,
        child: BodyHandle,
        parent: BodyHandle,
        anchors: [usize; 3],
        parent_nodes: [[usize; 8]; 3],
        parent_weights: [[f64; 8]; 3],
    ) -> Result<Attachment, AttachError> {
        let x = anchors.map(|i| world.nodes.position[i]);
        let f = frame(x[0], x[1], x[2]);
        let distinct =
            anchors[0] != anchors[1] && anchors[1] != anchors[2] && anchors[0] != anchors[2];
        if !distinct || f.determinant().abs() < 1e-18 {
            return Err(AttachError::Degenerate);
        }
        Ok(Attachment {
            child,
            parent,
            anchors,
            parent_nodes,
            parent_weights,
            constraint: None,
        })
    }

    /// The parent points' positions and velocities now.
    pub fn parent_points(&self, world: &World) -> ([Vector3<f64>; 3], [Vector3<f64>; 3]) {
        let n = &world.nodes;
        let at = |k: usize, of: &[Vector3<f64>]| -> Vector3<f64> {
            (0..8)
                .map(|c| of[self.parent_nodes[k][c]] * self.parent_weights[k][c])
                .sum()
        };
        (
            [0, 1, 2].map(|k| at(k, &n.position)),
            [0, 1, 2].map(|k| at(k, &n.velocity)),
        )
    }

    /// Bind the anchors to the parent points' linear motion over the coming frame.
    pub fn before_frame(&mut self, world: &mut World, frame_dt: f64) -> Result<(), AttachError> {
        self.release(world);
        let (x, v) = self.parent_points(world);
        let centre = (x[0] + x[1] + x[2]) / 3.0;
        let velocity = (v[0] + v[1] + v[2]) / 3.0;
        let t = world.time;
        let path = Path::new(
            vec![(t, centre), (t + frame_dt, centre + velocity * frame_dt)],
            Interpolation::Linear,
        )?;
        let index = world.add_trajectory(&self.anchors, path, 1.0)?;
        self.constraint = Some(world.constraints[index].clone());
        Ok(())
    }

    /// Map the whole child by eq 4.1 onto the parent points (module docs).
    pub fn after_frame(&mut self, world: &mut World) {
        let (xp, vp) = self.parent_points(world);
        let n = &mut world.nodes;
        let x = self.anchors.map(|i| n.position[i]);
        let v_child = self.anchors.map(|i| n.velocity[i]);
        let Some(inverse) = frame(x[0], x[1], x[2]).try_inverse() else {
            return;
        };
        let e = frame(xp[0], xp[1], xp[2]) * inverse;
        let mean = |a: [Vector3<f64>; 3]| (a[0] + a[1] + a[2]) / 3.0;
        let (vbar, vbar_p) = (mean(v_child), mean(vp));
        for i in world.bodies[self.child.0].nodes.clone() {
            n.position[i] = xp[0] + e * (n.position[i] - x[0]);
            n.velocity[i] = vbar_p + e * (n.velocity[i] - vbar);
        }
    }

    /// Remove the anchors' path constraint (also done by the next `before_frame`).
    pub fn release(&mut self, world: &mut World) {
        if let Some(c) = self.constraint.take() {
            if let Some(k) = world.constraints.iter().position(|x| *x == c) {
                world.constraints.remove(k);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::WorldSettings;
    use nalgebra::Rotation3;

    /// Eq 4.1 carries the child with the parent: for a rotation, uniform scale and translation
    /// of the parent the whole child moves by the same map; for any affine motion the three
    /// anchors land exactly on the parent points.
    #[test]
    fn the_child_follows_the_motion_of_its_parent() {
        let mut world = World::new(WorldSettings::default());
        let cube: Vec<Vector3<f64>> = (0..8)
            .map(|c| Vector3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64))
            .collect();
        let parent = world.add_body("parent", &cube, &[1.0; 8], &[], Vector3::zeros());
        let child_points: Vec<Vector3<f64>> = [
            [0.2, 1.2, 0.3],
            [0.8, 1.2, 0.3],
            [0.5, 1.2, 0.8],
            [0.5, 1.9, 0.5],
        ]
        .iter()
        .map(|p| Vector3::from(*p))
        .collect();
        let child = world.add_body("child", &child_points, &[1.0; 4], &[], Vector3::zeros());
        // The parent points at the child's first three nodes: trilinear weights in the unit cube
        // (extrapolated above it, still exact for affine motion).
        let weights = |p: Vector3<f64>| {
            let mut w = [0.0; 8];
            for (c, wc) in w.iter_mut().enumerate() {
                let f = |a: usize, t: f64| if (c >> a) & 1 == 1 { t } else { 1.0 - t };
                *wc = f(0, p.x) * f(1, p.y) * f(2, p.z);
            }
            w
        };
        let nodes = [0, 1, 2].map(|_| [0, 1, 2, 3, 4, 5, 6, 7]);
        let w = [0, 1, 2].map(|k| weights(child_points[k]));
        let mut a = Attachment::new(&world, child, parent, [8, 9, 10], nodes, w).unwrap();
        let rotation = *Rotation3::from_euler_angles(0.3, -0.5, 0.9).matrix();
        let shift = Vector3::new(0.4, -1.0, 2.0);
        let rest = world.nodes.position.clone();
        for (linear, all_exact) in [
            (rotation * 1.2, true),
            (
                rotation * Matrix3::from_diagonal(&Vector3::new(1.3, 0.8, 1.1)),
                false,
            ),
        ] {
            world.nodes.position = rest.clone();
            for (x, c) in world.nodes.position.iter_mut().zip(&cube) {
                *x = linear * c + shift;
            }
            a.after_frame(&mut world);
            for (j, p) in child_points.iter().enumerate() {
                let err = (world.nodes.position[8 + j] - (linear * p + shift)).norm();
                if j < 3 || all_exact {
                    assert!(err < 1e-12, "node {j} off by {err}");
                }
            }
        }
    }
}
