//! Damping of a body's deformation relative to its rigid motion.
//!
//! Dampers on springs (Miyazaki eq 1) damp each mode in proportion to its frequency, so the
//! slow modes an artist sees — the whole body squashing on impact, the wobble afterwards — keep
//! almost all their energy and a dropped ball bounces nearly forever. Here every node is also
//! pulled towards the body's rigid motion, `F_i = −c m_i (v_i − v_cm − ω × (x_i − x_cm))`, with
//! `c = 2 ζ ω₁` for the material's damping ratio ζ and the lattice's lowest deformation
//! frequency `ω₁ ≈ π sqrt(E/ρ) / ℓ` (ℓ the longest side). Linear and angular momentum are kept
//! exactly: rigid motion is not damped.

use super::team::{self, Chunks};
use super::{NodeState, PAR_CHUNK};
use nalgebra::{Matrix3, Vector3};
use std::ops::Range;

/// The rigid motion of a body at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidMotion {
    pub centre: Vector3<f64>,
    pub velocity: Vector3<f64>,
    pub angular_velocity: Vector3<f64>,
    /// Total mass, kg.
    pub mass: f64,
    /// Inverse inertia about the centre (zero where the inertia is singular).
    pub inv_inertia: Matrix3<f64>,
}

impl RigidMotion {
    /// Velocity of the rigid motion at `x`.
    pub fn velocity_at(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.velocity + self.angular_velocity.cross(&(x - self.centre))
    }
}

/// Best-fit rigid motion of the nodes in `range` (centre of mass, its velocity, and the angular
/// velocity `I⁻¹ L` about it). Partial sums over fixed chunks, added in chunk order: the same
/// bits with any thread count.
pub fn rigid_motion(nodes: &NodeState, range: Range<usize>) -> RigidMotion {
    rigid_motion_in(nodes, range, &mut RigidScratch::default())
}

/// Per-chunk partial sums of [`rigid_motion_in`], kept between calls so the solver's step
/// allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct RigidScratch {
    first: Vec<(f64, Vector3<f64>, Vector3<f64>)>,
    second: Vec<(SecondMoment, Vector3<f64>)>,
}

/// A sum of point masses' second moments `Σ m r rᵀ`, kept as its six distinct entries: the
/// inertia about the same point is `tr(S) 1 − S` ([`Self::inertia`]). Summed as full 3 × 3
/// matrices `m (|r|² 1 − r rᵀ)`, a node took 50 floating-point operations instead of 9.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SecondMoment {
    /// `xx, yy, zz, xy, xz, yz`.
    sums: [f64; 6],
}

impl SecondMoment {
    /// Add a mass `m` at `r`.
    #[inline(always)]
    pub(crate) fn add(&mut self, r: &Vector3<f64>, m: f64) {
        let mr = r * m;
        let s = &mut self.sums;
        s[0] += mr.x * r.x;
        s[1] += mr.y * r.y;
        s[2] += mr.z * r.z;
        s[3] += mr.x * r.y;
        s[4] += mr.x * r.z;
        s[5] += mr.y * r.z;
    }

    /// The sum of two sums.
    pub(crate) fn plus(self, o: SecondMoment) -> SecondMoment {
        SecondMoment {
            sums: std::array::from_fn(|i| self.sums[i] + o.sums[i]),
        }
    }

    /// The inertia tensor about the point the moments are taken about.
    pub(crate) fn inertia(&self) -> Matrix3<f64> {
        let [xx, yy, zz, xy, xz, yz] = self.sums;
        Matrix3::new(yy + zz, -xy, -xz, -xy, xx + zz, -yz, -xz, -yz, xx + yy)
    }
}

/// [`rigid_motion`] with reusable buffers.
pub fn rigid_motion_in(
    nodes: &NodeState,
    range: Range<usize>,
    scratch: &mut RigidScratch,
) -> RigidMotion {
    let (m, mx, mv) = team::chunked_sum(
        range.clone(),
        PAR_CHUNK,
        (0.0, Vector3::zeros(), Vector3::zeros()),
        &mut scratch.first,
        |(m, mx, mv), i| {
            *m += nodes.mass[i];
            *mx += nodes.position[i] * nodes.mass[i];
            *mv += nodes.velocity[i] * nodes.mass[i];
        },
        |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2),
    );
    if m <= 0.0 {
        return RigidMotion {
            centre: Vector3::zeros(),
            velocity: Vector3::zeros(),
            angular_velocity: Vector3::zeros(),
            mass: 0.0,
            inv_inertia: Matrix3::zeros(),
        };
    }
    let (centre, velocity) = (mx / m, mv / m);
    let (moments, momentum) = team::chunked_sum(
        range,
        PAR_CHUNK,
        (SecondMoment::default(), Vector3::zeros()),
        &mut scratch.second,
        |(moments, momentum), i| {
            let d = nodes.position[i] - centre;
            let mi = nodes.mass[i];
            moments.add(&d, mi);
            *momentum += d.cross(&(nodes.velocity[i] - velocity)) * mi;
        },
        |a, b| (a.0.plus(b.0), a.1 + b.1),
    );
    let inv_inertia = moments
        .inertia()
        .try_inverse()
        .unwrap_or_else(Matrix3::zeros);
    RigidMotion {
        centre,
        velocity,
        angular_velocity: inv_inertia * momentum,
        mass: m,
        inv_inertia,
    }
}

/// Pull every node of each body with a damping rate towards the body's rigid motion over
/// `dt`: `v += (v_rigid(x) − v) · min(c Δt, 1)` (the fit serial in node order, so
/// deterministic; momentum and angular momentum are kept exactly). Shared by every
/// integrator.
pub(crate) fn damp(
    nodes: &mut NodeState,
    bodies: &[super::BodyInfo],
    dt: f64,
    scratch: &mut RigidScratch,
) {
    for body in bodies.iter().filter(|b| b.deformation_damping > 0.0) {
        let rigid = rigid_motion_in(nodes, body.nodes.clone(), scratch);
        let pull = (body.deformation_damping * dt).min(1.0);
        let (pos, vel) = (&nodes.position, &mut nodes.velocity);
        let (vel, pos) = (&mut vel[body.nodes.clone()], &pos[body.nodes.clone()]);
        team::for_each(
            Chunks::new(vel, PAR_CHUNK),
            |c, vel: &mut [Vector3<f64>]| {
                for (v, x) in vel.iter_mut().zip(&pos[c * PAR_CHUNK..]) {
                    *v += (rigid.velocity_at(x) - *v) * pull;
                }
            },
        );
    }
}

/// The damping rate `c = 2 ζ ω₁` (1/s) for a lattice of longest side `longest_m`.
pub fn damping_rate(damping_ratio: f64, young_pa: f64, density: f64, longest_m: f64) -> f64 {
    if longest_m <= 0.0 {
        return 0.0;
    }
    2.0 * damping_ratio * std::f64::consts::PI * (young_pa / density).sqrt() / longest_m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_rigid_spin_and_drift_exactly() {
        let positions: Vec<Vector3<f64>> = (0..8)
            .map(|c| Vector3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64))
            .collect();
        let omega = Vector3::new(0.3, -1.0, 2.0);
        let v0 = Vector3::new(1.0, 2.0, -0.5);
        let centre = Vector3::repeat(0.5);
        let nodes = NodeState {
            velocity: positions
                .iter()
                .map(|x| v0 + omega.cross(&(x - centre)))
                .collect(),
            position: positions,
            mass: vec![2.0; 8],
            inv_mass: vec![0.5; 8],
        };
        let r = rigid_motion(&nodes, 0..8);
        // 2 kg at each corner of a unit cube: Σ m (y² + z²) = 16 · 0.5 about each axis
        // through the centre, no products of inertia.
        let inertia = r.inv_inertia.try_inverse().unwrap();
        assert!(
            (inertia - Matrix3::identity() * 8.0).norm() < 1e-12,
            "{inertia}"
        );
        assert!((r.centre - centre).norm() < 1e-12);
        assert!((r.velocity - v0).norm() < 1e-12);
        assert!((r.angular_velocity - omega).norm() < 1e-12);
    }
}
