//! Contact with rigid surfaces through an elastic layer (Miyazaki §2.3, physics §5): the floor,
//! the room's walls and the capsule manipulator. A node inside a surface's layer feels a
//! virtual spring pushing it out, proportional to its penetration, plus a normal damper
//! (so impacts lose energy and bodies come to rest), and Coulomb friction with the normal force
//! as the load. The layer's top is the visible surface (the floor height); a penetration deeper
//! than `thickness_m` means the node went through the layer into the rigid body.

use super::manipulator::Capsule;
use nalgebra::Vector3;

/// Elastic-layer parameters shared by the rigid surfaces of a world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLayer {
    /// Layer thickness h, metres.
    pub thickness_m: f64,
    /// Stiffness of the virtual spring per node, N/m.
    pub stiffness: f64,
    /// Damping ratio of the normal response (0: perfectly elastic bounce).
    pub damping_ratio: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
}

/// A rigid half-space: the solid is where `normal · x < offset`; `normal` is unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub normal: Vector3<f64>,
    pub offset: f64,
}

/// One contact's force on a node, given its penetration depth `depth` along the outward
/// normal `n`, the node's velocity relative to the surface, its mass and the step.
pub(crate) fn layer_force(
    layer: &ContactLayer,
    friction: f64,
    depth: f64,
    n: Vector3<f64>,
    relative_velocity: Vector3<f64>,
    mass: f64,
    dt: f64,
) -> Vector3<f64> {
    let vn = relative_velocity.dot(&n);
    let c = 2.0 * layer.damping_ratio * (layer.stiffness * mass).sqrt();
    let normal = (layer.stiffness * depth - c * vn).max(0.0);
    let vt = relative_velocity - vn * n;
    let speed_t = vt.norm();
    let mut f = normal * n;
    if speed_t > 1e-12 && friction > 0.0 {
        // Kinetic friction, capped so it cannot reverse the sliding within one step.
        let limit = if dt > 0.0 {
            mass * speed_t / dt
        } else {
            f64::INFINITY
        };
        f -= (friction * normal).min(limit) * (vt / speed_t);
    }
    f
}

/// The contact of one node with every rigid surface: total force, deepest penetration and
/// the force from the manipulators alone (for their reaction).
pub(crate) fn node_contacts(
    layer: &ContactLayer,
    planes: &[Plane],
    capsules: &[Capsule],
    x: Vector3<f64>,
    v: Vector3<f64>,
    mass: f64,
    dt: f64,
) -> (Vector3<f64>, f64, Vector3<f64>) {
    let mut total = Vector3::zeros();
    let mut deepest = 0.0f64;
    for p in planes {
        let depth = p.offset - p.normal.dot(&x);
        if depth > 0.0 {
            total += layer_force(layer, layer.friction, depth, p.normal, v, mass, dt);
            deepest = deepest.max(depth);
        }
    }
    let mut from_capsules = Vector3::zeros();
    for cap in capsules {
        let closest = cap.closest_point(&x);
        let d = x - closest;
        let dist = d.norm();
        let depth = cap.radius - dist;
        if depth > 0.0 {
            let n = if dist > 1e-12 {
                d / dist
            } else {
                cap.fallback_normal()
            };
            let f = layer_force(layer, cap.friction, depth, n, v - cap.velocity, mass, dt);
            from_capsules += f;
            deepest = deepest.max(depth);
        }
    }
    (total + from_capsules, deepest, from_capsules)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer() -> ContactLayer {
        ContactLayer {
            thickness_m: 0.01,
            stiffness: 1000.0,
            damping_ratio: 0.0,
            friction: 0.5,
        }
    }

    #[test]
    fn undamped_layer_force_is_stiffness_times_depth() {
        let f = layer_force(
            &layer(),
            0.0,
            0.002,
            Vector3::y(),
            Vector3::zeros(),
            1.0,
            1e-3,
        );
        assert!((f - Vector3::new(0.0, 2.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn friction_opposes_sliding_and_is_bounded_by_mu_n() {
        let v = Vector3::new(3.0, 0.0, 0.0);
        let f = layer_force(&layer(), 0.5, 0.002, Vector3::y(), v, 1.0, 1e-3);
        assert!((f.y - 2.0).abs() < 1e-12);
        assert!((f.x + 1.0).abs() < 1e-12, "μN = 0.5·2 = 1, got {}", f.x);
        // A slow slide: the cap m|v_t|/dt (0.5 N) wins over μN.
        let slow = layer_force(
            &layer(),
            0.5,
            0.002,
            Vector3::y(),
            Vector3::new(5e-4, 0.0, 0.0),
            1.0,
            1e-3,
        );
        assert!((slow.x + 0.5).abs() < 1e-12, "{}", slow.x);
    }

    #[test]
    fn damper_never_pulls_a_node_into_the_surface() {
        let v = Vector3::new(0.0, 10.0, 0.0); // leaving fast
        let l = ContactLayer {
            damping_ratio: 1.0,
            ..layer()
        };
        let f = layer_force(&l, 0.0, 1e-4, Vector3::y(), v, 1.0, 1e-3);
        assert_eq!(f.y, 0.0);
    }
}
