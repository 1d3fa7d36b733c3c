//! Contact with the rigid surfaces (floor, walls, capsule manipulators) as inequality
//! constraints of the XPBD step: a point found below a surface after the elastic solve is
//! moved back onto it along the normal, and Coulomb friction acts on its displacement over
//! the substep relative to the surface (static while the tangential slip is within μ times the
//! normal correction, kinetic beyond: the slip is shortened by μ times it; Macklin et al.
//! 2019, "Small Steps"). Contact therefore puts no bound on the step, however stiff.
//!
//! Static colliders (triangle meshes) are constraints of the same kind for the display-surface
//! points ([`resolve_colliders`]), with the entering segment tested so a thin collider is
//! not tunnelled through.
//!
//! A node takes the correction directly; a display-surface point (an embedded point, eight
//! trilinear weights `w_c`) moves its cell's nodes by `w_c m_c⁻¹ δ / W`, `W = Σ w_c² m_c⁻¹`, so
//! the point itself moves by exactly `δ` and momentum is shared as a rigid contact would.

use crate::collide::StaticCollider;
use crate::solver::manipulator::Capsule;
use crate::solver::Plane;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// The rigid surfaces of one substep.
pub(crate) struct Surfaces<'a> {
    pub planes: &'a [Plane],
    pub friction: f64,
    /// Each capsule at the substep's end and at its start (for the motion of its surface).
    pub capsules: &'a [(Capsule, Capsule)],
}

/// What the contact of one point did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct PointContact {
    /// The point's correction, m.
    pub correction: V3,
    /// Part of the correction due to the capsules, m.
    pub from_capsules: V3,
    /// Deepest penetration found, m.
    pub depth: f64,
    /// The capsules' corrections dotted with their surfaces' motion over the substep, m²
    /// (times the point's mass over Δt²: the capsules' work on it).
    pub capsule_work: f64,
}

/// Relative rounding allowed for a point's trilinear sum of its cell's nodes (and for its
/// weights' sum) in [`Surfaces::clear_of_hull`]: far above the few ulps the sums can be off.
pub(crate) const HULL_ROUNDING: f64 = 1e-9;

impl Surfaces<'_> {
    /// Whether every convex combination of `corners` (a point embedded in a cell whose nodes
    /// these are, with weights that are not negative) is clear of every surface: in front of
    /// each plane, and outside each capsule's box on one axis (so [`Self::resolve`] would
    /// leave it alone). A margin of [`HULL_ROUNDING`] times the coordinates' size covers the
    /// rounding of the point's weighted sum.
    pub(crate) fn clear_of_hull(&self, corners: &[V3; 8]) -> bool {
        let size = corners.iter().map(|x| x.amax()).fold(0.0, f64::max);
        self.planes.iter().all(|p| {
            let slack = HULL_ROUNDING * (size + p.offset.abs());
            corners.iter().all(|x| p.normal.dot(x) - p.offset > slack)
        }) && self.capsules.iter().all(|(c, _)| {
            let (a, b) = c.endpoints();
            let lo = a.inf(&b).add_scalar(-c.radius);
            let hi = a.sup(&b).add_scalar(c.radius);
            let slack = HULL_ROUNDING * (size + lo.amax().max(hi.amax()));
            (0..3).any(|k| {
                corners.iter().all(|x| x[k] < lo[k] - slack)
                    || corners.iter().all(|x| x[k] > hi[k] + slack)
            })
        })
    }

    /// Whether every point within `reach` of `x` is clear of every surface.
    pub(crate) fn beyond_reach(&self, x: &V3, reach: f64) -> bool {
        self.planes
            .iter()
            .all(|p| p.normal.dot(x) - p.offset > reach)
            && self.capsules.iter().all(|(c, _)| {
                let (a, b) = c.endpoints();
                let lo = a.inf(&b).add_scalar(-c.radius - reach);
                let hi = a.sup(&b).add_scalar(c.radius + reach);
                (0..3).any(|k| x[k] < lo[k] || x[k] > hi[k])
            })
    }

    /// The correction of a point now at `x` that was at `previous` at the substep's start.
    pub(crate) fn resolve(&self, x: V3, previous: V3) -> PointContact {
        let mut out = PointContact::default();
        let mut p = x;
        for plane in self.planes {
            let depth = plane.offset - plane.normal.dot(&p);
            if depth > 0.0 {
                let moved = p + plane.normal * depth;
                let slip = tangential(moved - previous, &plane.normal);
                let fixed = moved - friction(slip, self.friction * depth);
                out.correction += fixed - p;
                out.depth = out.depth.max(depth);
                p = fixed;
            }
        }
        for (cap, before) in self.capsules {
            let axis_point = cap.closest_point(&p);
            let offset = p - axis_point;
            let dist = offset.norm();
            let depth = cap.radius - dist;
            if depth > 0.0 {
                let n = cap.normal(offset, dist);
                let moved = p + n * depth;
                // Where this surface point was at the substep's start (same axial parameter
                // and offset in the capsule's frame: the capsule's translation and yaw).
                let s = (axis_point - cap.centre).dot(&cap.axis);
                let surface_then = before.centre + before.axis * s + n * cap.radius;
                let surface_now = axis_point + n * cap.radius;
                let slip = tangential(moved - previous - (surface_now - surface_then), &n);
                let fixed = moved - friction(slip, cap.friction * depth);
                out.correction += fixed - p;
                out.from_capsules += fixed - p;
                out.capsule_work += (fixed - p).dot(&(surface_now - surface_then));
                out.depth = out.depth.max(depth);
                p = fixed;
            }
        }
        out
    }
}

/// What static colliders did to one display-surface point in a substep.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct ColliderContact {
    /// The point's correction, m.
    pub correction: V3,
    /// Deepest penetration, m (0: none).
    pub depth: f64,
    /// The collider and its face normal of the deepest penetration.
    pub deepest: Option<(u32, V3)>,
}

/// The correction of a display-surface point now at `x` (at `previous` at the substep's
/// start) that static colliders make: each collider it entered (or lies at most `behind`
/// behind) moves it back onto the face along the face normal, with the collider's Coulomb
/// friction on its slip, as the floor does. `resting`: the collider and normal a substep
/// before put the point back along (its [`ColliderContact::deepest`]) while it stays near,
/// and `body`, the centre of the point's body: which side of a two-sided collider the point
/// is on.
pub(crate) fn resolve_colliders(
    colliders: &mut [StaticCollider],
    (previous, x): (V3, V3),
    behind: f64,
    (resting, body): (Option<(u32, V3)>, Option<V3>),
    scratch: &mut Vec<u32>,
) -> ColliderContact {
    let mut out = ColliderContact::default();
    let mut p = x;
    for (c, collider) in colliders.iter_mut().enumerate() {
        let rests = resting.filter(|&(k, _)| k as usize == c).map(|(_, n)| n);
        let side = (rests, body);
        if let Some((n, depth)) = collider.penetration(&previous, &p, behind, side, scratch) {
            let moved = p + n * depth;
            let slip = tangential(moved - previous, &n);
            p = moved - friction(slip, collider.friction * depth);
            if depth > out.depth {
                out.depth = depth;
                out.deepest = Some((c as u32, n));
            }
        }
    }
    out.correction = p - x;
    out
}

pub(super) fn tangential(d: V3, n: &V3) -> V3 {
    d - n * d.dot(n)
}

/// The part of `slip` friction removes: all of it while it is within `limit` (static), else
/// `limit` of its length (kinetic).
pub(super) fn friction(slip: V3, limit: f64) -> V3 {
    let length = slip.norm();
    if length <= limit {
        slip
    } else {
        slip * (limit / length)
    }
}

/// Coulomb friction as an accumulated positional impulse (kg·m): the contact's new total
/// impulse against `slip` (its tangential motion over the substep), given its total so far
/// `accumulated`, its inverse mass along a unit direction (`inverse_mass`) and the bound
/// `limit` (μ times its normal impulse). `None` without slip or where nothing moves.
pub(super) fn friction_impulse(
    slip: V3,
    accumulated: V3,
    limit: f64,
    inverse_mass: impl FnOnce(V3) -> f64,
) -> Option<V3> {
    let length = slip.norm();
    if length <= 0.0 {
        return None;
    }
    let along = inverse_mass(slip / length);
    (along > 0.0).then(|| friction(accumulated - slip / along, limit))
}

/// Indices `0..n`, forwards on even passes and backwards on odd ones: sequential impulses
/// over a body's contacts in this order leave no contact always first.
pub(super) fn alternating(n: usize, pass: usize) -> impl Iterator<Item = usize> {
    (0..n).map(move |k| if pass.is_multiple_of(2) { k } else { n - 1 - k })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_below_the_floor_lands_on_it_and_sticks_within_the_friction_cone() {
        let floor = [Plane {
            normal: V3::y(),
            offset: 0.0,
        }];
        let s = Surfaces {
            planes: &floor,
            friction: 0.5,
            capsules: &[],
        };
        // Falling straight in: lands exactly on the floor.
        let c = s.resolve(V3::new(0.0, -0.01, 0.0), V3::new(0.0, 0.02, 0.0));
        assert_eq!(c.correction, V3::new(0.0, 0.01, 0.0));
        // Sliding fast: the slip is shortened by μ × depth.
        let c = s.resolve(V3::new(0.1, -0.01, 0.0), V3::new(0.0, 0.0, 0.0));
        assert!((c.correction.x + 0.005).abs() < 1e-15, "{}", c.correction);
        // Slow: static friction holds it where it was.
        let c = s.resolve(V3::new(0.001, -0.01, 0.0), V3::new(0.0, 0.0, 0.0));
        assert!((c.correction.x + 0.001).abs() < 1e-15);
    }

    #[test]
    fn a_point_inside_a_capsule_is_pushed_out_radially() {
        let cap = Capsule {
            centre: V3::zeros(),
            axis: V3::x(),
            length: 1.0,
            radius: 0.1,
            velocity: V3::zeros(),
            friction: 0.0,
        };
        let s = Surfaces {
            planes: &[],
            friction: 0.0,
            capsules: &[(cap, cap)],
        };
        let c = s.resolve(V3::new(0.2, 0.05, 0.0), V3::new(0.2, 0.05, 0.0));
        assert!((c.correction - V3::new(0.0, 0.05, 0.0)).norm() < 1e-12);
        assert_eq!(c.correction, c.from_capsules);
        assert!(s.beyond_reach(&V3::new(0.0, 0.5, 0.0), 0.1));
        assert!(!s.beyond_reach(&V3::new(0.0, 0.15, 0.0), 0.1));
    }

    /// A cell cleared whole has no embedded point that `resolve` would touch, and a cell
    /// with any such point is never cleared; cells drawn at random near a tilted floor and a
    /// capsule, many straddling them.
    #[test]
    fn a_cell_clear_of_the_surfaces_has_no_point_in_contact() {
        let floor = [Plane {
            normal: V3::new(0.1, 1.0, -0.2).normalize(),
            offset: 0.3,
        }];
        let cap = Capsule {
            centre: V3::new(0.0, 1.0, 0.0),
            axis: V3::new(1.0, 0.5, 0.0).normalize(),
            length: 0.8,
            radius: 0.15,
            velocity: V3::zeros(),
            friction: 0.0,
        };
        let s = Surfaces {
            planes: &floor,
            friction: 0.4,
            capsules: &[(cap, cap)],
        };
        let mut rng = fastrand::Rng::with_seed(7);
        let coord = |rng: &mut fastrand::Rng, span: f64| (rng.f64() - 0.5) * span;
        let (mut cleared, mut kept) = (0, 0);
        for _ in 0..4000 {
            let centre = V3::new(
                coord(&mut rng, 3.0),
                0.6 + coord(&mut rng, 2.0),
                coord(&mut rng, 1.0),
            );
            let corners: [V3; 8] = std::array::from_fn(|_| {
                let r = &mut rng;
                centre + V3::new(coord(r, 0.2), coord(r, 0.2), coord(r, 0.2))
            });
            let touching = (0..64).any(|_| {
                let raw: [f64; 8] = std::array::from_fn(|_| rng.f64());
                let total: f64 = raw.iter().sum();
                let p = (0..8).fold(V3::zeros(), |p, c| p + corners[c] * (raw[c] / total));
                s.resolve(p, p).depth > 0.0 || corners.iter().any(|c| s.resolve(*c, *c).depth > 0.0)
            });
            if s.clear_of_hull(&corners) {
                cleared += 1;
                assert!(
                    !touching,
                    "cleared a cell with a point in contact: {corners:?}"
                );
            } else {
                kept += 1;
            }
        }
        assert!(
            cleared > 1000 && kept > 1000,
            "{cleared} cleared, {kept} kept"
        );
    }
}
