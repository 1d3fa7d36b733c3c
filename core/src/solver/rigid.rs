//! Rigid bodies (physics §8, Terasawa's floating frame without the deformation terms): a body
//! made rigid keeps its shape exactly. Each step, the integrator runs as usual; the change of
//! every node's momentum it made (gravity, contacts, wind; the springs' forces are internal
//! and cancel) is summed into the body's linear momentum and, about the centre of mass at the
//! step's start, its angular momentum. The frame then moves (centre by its velocity, the
//! orientation quaternion by the angular velocity `ω = R I⁻¹ Rᵀ L`) and the nodes are placed
//! at `x_i = c + R r_i` with `v_i = v_c + ω × R r_i`, so distances between nodes are exact to
//! rounding. Gyroscopic motion comes from keeping L (not ω) as the state.
//!
//! A **particle** ([`RigidBody::particle`], `[body] kind = "particle"`) is the same frame with
//! the rotation locked: only the impulse is taken (the angular impulse is dropped), the nodes
//! keep their rest offsets from the centre, and gravity is integrated exactly —
//! `c += (v_{n+1} − ½ g Δt) Δt`, which is `x0 + v0 t − ½ g t²` to rounding in free fall under
//! either integrator — while the other forces (contacts, wind) keep the symplectic update.

use super::NodeState;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use std::ops::Range;

/// Total mass, centre of mass and centre-of-mass velocity of the nodes `range`; `None` when
/// they are empty, have no mass or include a pinned node.
fn mass_centre_velocity(
    nodes: &NodeState,
    range: Range<usize>,
) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
    let mass: f64 = nodes.mass[range.clone()].iter().sum();
    if range.is_empty() || mass <= 0.0 || nodes.inv_mass[range.clone()].contains(&0.0) {
        return None;
    }
    let weighted = |x: &[Vector3<f64>]| {
        range
            .clone()
            .map(|i| x[i] * nodes.mass[i])
            .sum::<Vector3<f64>>()
            / mass
    };
    Some((mass, weighted(&nodes.position), weighted(&nodes.velocity)))
}

/// The floating frame of one rigid body.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidBody {
    /// Index of the body in the world.
    pub body: usize,
    /// Node offsets from the centre of mass in the body frame.
    pub local: Vec<Vector3<f64>>,
    pub mass: f64,
    pub inverse_inertia: Matrix3<f64>,
    pub centre: Vector3<f64>,
    pub velocity: Vector3<f64>,
    pub orientation: UnitQuaternion<f64>,
    /// Angular momentum about the centre of mass, world frame.
    pub angular_momentum: Vector3<f64>,
    /// A particle: translation only (module docs).
    pub translation_only: bool,
    /// Gravity integrated exactly for a particle (zero for a rigid body).
    pub exact_gravity: Vector3<f64>,
}

impl RigidBody {
    /// The frame of the nodes `range` as they are now (their velocities give the momenta);
    /// `None` when the nodes have no mass or no rotational inertia in some direction (fewer
    /// than three non-collinear massive nodes).
    pub fn from_nodes(body: usize, nodes: &NodeState, range: Range<usize>) -> Option<RigidBody> {
        let (mass, centre, velocity) = mass_centre_velocity(nodes, range.clone())?;
        let mut inertia = Matrix3::zeros();
        let mut angular_momentum = Vector3::zeros();
        let local: Vec<Vector3<f64>> = range
            .clone()
            .map(|i| {
                let r = nodes.position[i] - centre;
                let m = nodes.mass[i];
                inertia += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * m;
                angular_momentum += r.cross(&(nodes.velocity[i] - velocity)) * m;
                r
            })
            .collect();
        let inverse_inertia = inertia.try_inverse()?;
        Some(RigidBody {
            body,
            local,
            mass,
            inverse_inertia,
            centre,
            velocity,
            orientation: UnitQuaternion::identity(),
            angular_momentum,
            translation_only: false,
            exact_gravity: Vector3::zeros(),
        })
    }

    /// The nodes `range` as one point mass moving with their mean momentum, no rotation;
    /// `None` when they have no mass or a pinned node.
    pub fn particle(
        body: usize,
        nodes: &NodeState,
        range: Range<usize>,
        gravity: Vector3<f64>,
    ) -> Option<RigidBody> {
        let (mass, centre, velocity) = mass_centre_velocity(nodes, range.clone())?;
        Some(RigidBody {
            body,
            local: range.map(|i| nodes.position[i] - centre).collect(),
            mass,
            inverse_inertia: Matrix3::zeros(),
            centre,
            velocity,
            orientation: UnitQuaternion::identity(),
            angular_momentum: Vector3::zeros(),
            translation_only: true,
            exact_gravity: gravity,
        })
    }

    /// Angular velocity, world frame.
    pub fn angular_velocity(&self) -> Vector3<f64> {
        let r = self.orientation.to_rotation_matrix();
        r * (self.inverse_inertia * (r.inverse() * self.angular_momentum))
    }

    /// Take the momentum the step gave the nodes `range` (`before`: their positions and
    /// velocities at the step's start), move the frame by `dt` and place the nodes on it.
    pub(crate) fn advance(
        &mut self,
        nodes: &mut NodeState,
        range: Range<usize>,
        before: &[(Vector3<f64>, Vector3<f64>)],
        dt: f64,
    ) {
        let (mut impulse, mut angular) = (Vector3::zeros(), Vector3::zeros());
        for (j, i) in range.clone().enumerate() {
            let (x0, v0) = before[j];
            let j_i = (nodes.velocity[i] - v0) * nodes.mass[i];
            impulse += j_i;
            angular += (x0 - self.centre).cross(&j_i);
        }
        self.velocity += impulse / self.mass;
        if self.translation_only {
            self.centre += (self.velocity - 0.5 * self.exact_gravity * dt) * dt;
            for (j, i) in range.enumerate() {
                nodes.position[i] = self.centre + self.local[j];
                nodes.velocity[i] = self.velocity;
            }
            return;
        }
        self.angular_momentum += angular;
        self.centre += self.velocity * dt;
        let omega = self.angular_velocity();
        self.orientation = UnitQuaternion::from_scaled_axis(omega * dt) * self.orientation;
        let omega = self.angular_velocity();
        let r = self.orientation.to_rotation_matrix();
        for (j, i) in range.enumerate() {
            let arm = r * self.local[j];
            nodes.position[i] = self.centre + arm;
            nodes.velocity[i] = self.velocity + omega.cross(&arm);
        }
    }
}
