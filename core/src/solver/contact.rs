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

/// Nodes per block of the rigid broad phase (see [`box_may_touch`]).
pub(crate) const CONTACT_BLOCK: usize = 64;

/// The axis-aligned box `(lo, hi)` of the positions `xs`; NaN coordinates are left out (a
/// NaN position touches nothing), and no positions give an empty box (`lo > hi`).
pub(crate) fn bounding_box(xs: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for x in xs {
        for k in 0..3 {
            lo[k] = lo[k].min(x[k]);
            hi[k] = hi[k].max(x[k]);
        }
    }
    (Vector3::from(lo), Vector3::from(hi))
}

/// Whether a point in the box `lo..=hi` may touch a plane or a capsule: `false` only when
/// [`node_contacts`] finds no contact for any point in the box, bit for bit. A plane: the
/// box corner lowest along its normal (the dot product is monotone in each coordinate, also
/// rounded, so no point in the box lies lower) is not below the offset. A capsule: the box is
/// apart from the axis segment's box grown by the radius and a rounding margin. NaN anywhere
/// counts as touching; an empty box touches nothing.
pub(crate) fn box_may_touch(
    lo: Vector3<f64>,
    hi: Vector3<f64>,
    planes: &[Plane],
    capsules: &[Capsule],
) -> bool {
    if !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) {
        return false;
    }
    let pick = |n: f64, k: usize| if n >= 0.0 { lo[k] } else { hi[k] };
    let near_plane = planes.iter().any(|p| {
        let n = p.normal;
        let lowest = Vector3::new(pick(n.x, 0), pick(n.y, 1), pick(n.z, 2));
        let d = n.dot(&lowest);
        d < p.offset || d.is_nan() || p.offset.is_nan()
    });
    near_plane
        || capsules.iter().any(|c| {
            let (a, e) = c.endpoints();
            let reach = c.radius + 1e-9 * (1.0 + c.radius + a.amax() + e.amax());
            let apart =
                (0..3).any(|k| a[k].min(e[k]) - reach > hi[k] || a[k].max(e[k]) + reach < lo[k]);
            !apart
        })
}

/// How deep `x` is below plane `p` (positive: in contact).
#[inline]
fn plane_depth(p: &Plane, x: &Vector3<f64>) -> f64 {
    p.offset - p.normal.dot(x)
}

/// The offset of `x` from the nearest point of capsule `cap`'s axis, and its length.
#[inline]
fn capsule_offset(cap: &Capsule, x: &Vector3<f64>) -> (Vector3<f64>, f64) {
    let d = x - cap.closest_point(x);
    let dist = d.norm();
    (d, dist)
}

/// Whether [`node_contacts`] finds any contact at `x` (the same depths, bit for bit).
#[inline]
pub(crate) fn touches_any(planes: &[Plane], capsules: &[Capsule], x: &Vector3<f64>) -> bool {
    planes.iter().any(|p| plane_depth(p, x) > 0.0)
        || capsules
            .iter()
            .any(|cap| cap.radius - capsule_offset(cap, x).1 > 0.0)
}

/// Whether every point within `reach` of `x` is clear of all surfaces (no [`touches_any`]):
/// the distance to a plane or a capsule changes by at most the distance moved.
#[inline]
pub(crate) fn beyond_reach(
    planes: &[Plane],
    capsules: &[Capsule],
    x: &Vector3<f64>,
    reach: f64,
) -> bool {
    planes.iter().all(|p| -plane_depth(p, x) > reach)
        && capsules
            .iter()
            .all(|cap| capsule_offset(cap, x).1 - cap.radius > reach)
}

/// The contact of one node with every rigid surface: total force, deepest penetration and
/// the force from the manipulators alone (for their reaction).
#[inline]
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
        let depth = plane_depth(p, &x);
        if depth > 0.0 {
            total += layer_force(layer, layer.friction, depth, p.normal, v, mass, dt);
            deepest = deepest.max(depth);
        }
    }
    let mut from_capsules = Vector3::zeros();
    for cap in capsules {
        let (d, dist) = capsule_offset(cap, &x);
        let depth = cap.radius - dist;
        if depth > 0.0 {
            let n = cap.normal(d, dist);
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

    /// The broad phase may only skip a box in which no point has a contact: points on a
    /// lattice (corners, faces, interior) of many boxes around tilted planes and a slanted
    /// capsule, at and just beside the surfaces; and it does skip boxes clearly apart.
    #[test]
    fn box_test_never_skips_a_touching_point() {
        let planes = [
            Plane {
                normal: Vector3::y(),
                offset: 0.0,
            },
            Plane {
                normal: Vector3::new(0.3, -0.2, 0.9).normalize(),
                offset: 0.1,
            },
        ];
        let capsules = [Capsule {
            centre: Vector3::new(0.2, 0.5, -0.1),
            axis: Vector3::new(1.0, 0.4, -0.3).normalize(),
            length: 0.6,
            radius: 0.15,
            velocity: Vector3::zeros(),
            friction: 0.0,
        }];
        let (mut touching_boxes, mut skipped) = (0, 0);
        for bi in 0..12 {
            for bj in 0..12 {
                for bk in 0..12 {
                    // Boxes of width 0.1 over [-0.6, 0.6]³, offset by 1/3 of a width so that
                    // faces fall near the surfaces at odd values.
                    let lo = Vector3::new(bi as f64, bj as f64, bk as f64) * 0.1
                        - Vector3::repeat(0.6 - 0.1 / 3.0);
                    let hi = lo + Vector3::new(0.1, 0.07, 0.13);
                    let xs: Vec<Vector3<f64>> = (0..125)
                        .map(|s| {
                            let t = Vector3::new(
                                (s % 5) as f64 / 4.0,
                                (s / 5 % 5) as f64 / 4.0,
                                (s / 25) as f64 / 4.0,
                            );
                            lo + (hi - lo).component_mul(&t)
                        })
                        .collect();
                    let (blo, bhi) = bounding_box(&xs);
                    let near = box_may_touch(blo, bhi, &planes, &capsules);
                    let l = layer();
                    let touches = xs.iter().any(|&x| {
                        let (_, depth, _) =
                            node_contacts(&l, &planes, &capsules, x, Vector3::zeros(), 1.0, 1e-3);
                        depth > 0.0
                    });
                    assert!(near || !touches, "box {blo:?}..{bhi:?} skipped but touches");
                    touching_boxes += touches as usize;
                    skipped += !near as usize;
                }
            }
        }
        assert!(touching_boxes > 100, "{touching_boxes}");
        assert!(skipped > 200, "the test must skip boxes apart: {skipped}");
        // An empty box (no positions) touches nothing; NaN counts as touching.
        let (lo, hi) = bounding_box(&[]);
        assert!(!box_may_touch(lo, hi, &planes, &capsules));
        let nan_plane = Plane {
            normal: Vector3::y(),
            offset: f64::NAN,
        };
        let (lo, hi) = (Vector3::repeat(1.0), Vector3::repeat(2.0));
        assert!(box_may_touch(lo, hi, &[nan_plane], &[]));
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
