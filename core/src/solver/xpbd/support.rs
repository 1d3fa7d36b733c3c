//! Where a held or rigid body rests on static geometry (the floor, walls, colliders), for its
//! contacts with elastic bodies ([`super::bodies`]): a push that presses the body into what
//! it rests on, at a point over the outline it rests on, cannot move it, so such a contact
//! moves only the elastic side (shock propagation, as in stacks of rigid bodies).
//!
//! Pushed down off-centre by a rubber box on it each substep, a wooden box on the floor was
//! turned back by the floor's later stage, and the rubber box, held to it by friction, rode
//! that turn: the two walked 1.3 mm a second. A push outside the outline (a body balanced on
//! an edge, a part overhanging what holds it) or along the support moves the body as before.

use super::V3;

/// How squarely a push must press a body into its support (the cosine between the push and
/// the support's inward normal) for the support to hold the body.
const PRESSED_INTO_SUPPORT: f64 = 0.9;

/// How far outside the outline, as a fraction of its size, a push still counts as over it: a
/// box set on a box of the same size presses on the outline's very edge, and its contacts'
/// points there lay up to 0.8 % of the size beyond it (2.5 mm for 30 cm wooden boxes).
const EDGE_TOLERANCE: f64 = 0.015;

/// The outline a body rests on: the mean normal of its static contacts, and their points'
/// convex hull in the plane across that normal.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Support {
    normal: V3,
    axes: [V3; 2],
    /// The hull's corners in `axes`, counter-clockwise about `normal`; at least three.
    hull: Vec<[f64; 2]>,
    /// The hull's largest extent along an axis, m.
    size: f64,
}

impl Support {
    /// The support of a body whose static contacts are `contacts` (each its point and its
    /// unit normal, pointing from the static side to the body); `None` when they do not span
    /// an area (no contact, or points along a line: a body balanced on an edge can tip).
    pub(crate) fn new(contacts: &[(V3, V3)]) -> Option<Support> {
        let normal = contacts
            .iter()
            .map(|c| c.1)
            .sum::<V3>()
            .try_normalize(0.0)?;
        let u = normal
            .cross(&if normal.x.abs() < 0.9 {
                V3::x()
            } else {
                V3::y()
            })
            .normalize();
        let axes = [u, normal.cross(&u)];
        let flat: Vec<[f64; 2]> = (contacts.iter())
            .map(|(p, _)| [axes[0].dot(p), axes[1].dot(p)])
            .collect();
        let hull = convex_hull(flat);
        let extent = |k: usize| {
            let (lo, hi) = (hull.iter()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[k]), hi.max(p[k]))
            });
            hi - lo
        };
        let size = extent(0).max(extent(1));
        (hull.len() >= 3 && size > 0.0).then_some(Support {
            normal,
            axes,
            hull,
            size,
        })
    }

    /// Whether a push along `push` at `at` leaves the body where it is: it presses the body
    /// into its support, at a point over the outline.
    pub(crate) fn holds(&self, at: V3, push: V3) -> bool {
        let length = push.norm();
        if length <= 0.0 || push.dot(&self.normal) > -PRESSED_INTO_SUPPORT * length {
            return false;
        }
        let p = [self.axes[0].dot(&at), self.axes[1].dot(&at)];
        let slack = EDGE_TOLERANCE * self.size;
        let n = self.hull.len();
        (0..n).all(|k| {
            let (a, b) = (self.hull[k], self.hull[(k + 1) % n]);
            cross(a, b, p) >= -slack * (b[0] - a[0]).hypot(b[1] - a[1])
        })
    }
}

/// `(b − a) × (p − a)`: positive when `p` lies left of the line from `a` to `b`.
fn cross(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// The convex hull of `points`, counter-clockwise, without collinear corners (Andrew's
/// monotone chain); fewer than three corners when the points lie along a line.
fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * points.len());
    let turns_left =
        |hull: &[[f64; 2]], p| cross(hull[hull.len() - 2], hull[hull.len() - 1], p) > 0.0;
    for &p in &points {
        while hull.len() >= 2 && !turns_left(&hull, p) {
            hull.pop();
        }
        hull.push(p);
    }
    let lower = hull.len() + 1;
    for &p in points.iter().rev().skip(1) {
        while hull.len() >= lower && !turns_left(&hull, p) {
            hull.pop();
        }
        hull.push(p);
    }
    hull.pop(); // the first corner again
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The four corners of a 30 cm box's bottom face on the floor (normal +y).
    fn box_on_the_floor() -> Vec<(V3, V3)> {
        [(-0.15, -0.15), (0.15, -0.15), (0.15, 0.15), (-0.15, 0.15)]
            .iter()
            .map(|&(x, z)| (V3::new(x, 0.0, z), V3::y()))
            .collect()
    }

    #[test]
    fn a_box_on_the_floor_is_held_against_pushes_down_over_its_base_only() {
        let support = Support::new(&box_on_the_floor()).unwrap();
        let down = -V3::y();
        assert!(support.holds(V3::new(0.04, 0.3, 0.0), down));
        assert!(support.holds(V3::new(0.15, 0.3, 0.15), down), "its edge");
        assert!(
            !support.holds(V3::new(0.2, 0.3, 0.0), down),
            "beyond its base"
        );
        assert!(!support.holds(V3::new(0.0, 0.3, 0.0), V3::y()), "pulled up");
        assert!(
            !support.holds(V3::new(0.0, 0.3, 0.0), V3::new(1.0, -1.0, 0.0)),
            "at 45°"
        );
    }

    #[test]
    fn a_body_on_an_edge_or_on_nothing_has_no_support() {
        let edge: Vec<(V3, V3)> = box_on_the_floor().into_iter().take(2).collect();
        assert_eq!(Support::new(&edge), None);
        assert_eq!(Support::new(&[]), None);
    }
}
