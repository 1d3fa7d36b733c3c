//! The manipulator (Miyazaki §2.1, physics §6): a rigid capsule, a cylinder with hemispherical
//! caps, moved by translation and by rotation (yaw) about the up axis. Its side hits, its tip
//! pokes. A [`ManipulatorTrack`] plays scripted keyframes; the viewer drives a [`Capsule`]
//! directly.

use nalgebra::Vector3;

/// The capsule at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// Centre of the axis segment, world metres.
    pub centre: Vector3<f64>,
    /// Unit direction of the axis.
    pub axis: Vector3<f64>,
    /// Length of the axis segment between the cap centres, metres.
    pub length: f64,
    pub radius: f64,
    /// Linear velocity, m/s (for friction).
    pub velocity: Vector3<f64>,
    pub friction: f64,
}

impl Capsule {
    pub fn endpoints(&self) -> (Vector3<f64>, Vector3<f64>) {
        let h = self.axis * (self.length * 0.5);
        (self.centre - h, self.centre + h)
    }

    /// The point of the axis segment nearest to `x`.
    pub fn closest_point(&self, x: &Vector3<f64>) -> Vector3<f64> {
        let t = (x - self.centre)
            .dot(&self.axis)
            .clamp(-self.length * 0.5, self.length * 0.5);
        self.centre + self.axis * t
    }

    /// The outward normal at a point `offset` (length `dist`) from the nearest point of the
    /// axis: the offset's direction, or [`Self::fallback_normal`] on the axis itself.
    pub fn normal(&self, offset: Vector3<f64>, dist: f64) -> Vector3<f64> {
        if dist > 1e-12 {
            offset / dist
        } else {
            self.fallback_normal()
        }
    }

    /// A normal for a point exactly on the axis: any direction perpendicular to it.
    pub fn fallback_normal(&self) -> Vector3<f64> {
        let trial = if self.axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        self.axis.cross(&trial).normalize()
    }
}

/// Axis direction for a yaw (degrees) about `up`: yaw 0 points along the first horizontal
/// axis (+X for both Y-up and Z-up), positive yaw turns right-handed about `up`.
pub fn axis_from_yaw(up: Vector3<f64>, yaw_deg: f64) -> Vector3<f64> {
    let x = Vector3::x();
    let h2 = up.cross(&x);
    let (s, c) = yaw_deg.to_radians().sin_cos();
    (x * c + h2 * s).normalize()
}

/// One keyframe: time (s), centre (world metres), yaw (degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManipulatorKey {
    pub t: f64,
    pub position: Vector3<f64>,
    pub yaw_deg: f64,
}

/// A scripted manipulator: capsule shape plus keyframes, linear or smooth (Catmull-Rom in
/// position, smoothstep-eased in yaw) interpolation, held constant outside the keys.
#[derive(Debug, Clone, PartialEq)]
pub struct ManipulatorTrack {
    pub radius: f64,
    pub length: f64,
    pub friction: f64,
    pub smooth: bool,
    /// Sorted by time.
    pub keys: Vec<ManipulatorKey>,
    pub up: Vector3<f64>,
}

impl ManipulatorTrack {
    fn pose(&self, t: f64) -> (Vector3<f64>, f64) {
        let k = &self.keys;
        match k.len() {
            0 => return (Vector3::zeros(), 0.0),
            1 => return (k[0].position, k[0].yaw_deg),
            _ => {}
        }
        if t <= k[0].t {
            return (k[0].position, k[0].yaw_deg);
        }
        let last = k.len() - 1;
        if t >= k[last].t {
            return (k[last].position, k[last].yaw_deg);
        }
        let i = k.partition_point(|key| key.t <= t) - 1;
        let (a, b) = (&k[i], &k[i + 1]);
        let span = (b.t - a.t).max(1e-12);
        let u = (t - a.t) / span;
        if !self.smooth {
            return (
                a.position + (b.position - a.position) * u,
                a.yaw_deg + (b.yaw_deg - a.yaw_deg) * u,
            );
        }
        let p0 = if i > 0 { k[i - 1].position } else { a.position };
        let p3 = if i + 1 < last {
            k[i + 2].position
        } else {
            b.position
        };
        let (p1, p2) = (a.position, b.position);
        let u2 = u * u;
        let u3 = u2 * u;
        let pos = 0.5
            * ((2.0 * p1)
                + (p2 - p0) * u
                + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * u2
                + (3.0 * p1 - p0 - 3.0 * p2 + p3) * u3);
        let eased = u * u * (3.0 - 2.0 * u);
        (pos, a.yaw_deg + (b.yaw_deg - a.yaw_deg) * eased)
    }

    /// The capsule at time `t`, its velocity by central difference.
    pub fn capsule_at(&self, t: f64) -> Capsule {
        let (centre, yaw) = self.pose(t);
        let h = 1e-4;
        let velocity = (self.pose(t + h).0 - self.pose(t - h).0) / (2.0 * h);
        Capsule {
            centre,
            axis: axis_from_yaw(self.up, yaw),
            length: self.length,
            radius: self.radius,
            velocity,
            friction: self.friction,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_turns_about_up() {
        let y = axis_from_yaw(Vector3::y(), 90.0);
        assert!((y - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        let z = axis_from_yaw(Vector3::z(), 90.0);
        assert!((z - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn linear_and_smooth_tracks_hit_their_keys() {
        let keys = vec![
            ManipulatorKey {
                t: 0.0,
                position: Vector3::new(-1.0, 0.5, 0.0),
                yaw_deg: 0.0,
            },
            ManipulatorKey {
                t: 0.5,
                position: Vector3::new(0.3, 0.5, 0.0),
                yaw_deg: 30.0,
            },
            ManipulatorKey {
                t: 1.0,
                position: Vector3::new(0.3, 1.0, 0.0),
                yaw_deg: 30.0,
            },
        ];
        for smooth in [false, true] {
            let track = ManipulatorTrack {
                radius: 0.05,
                length: 0.8,
                friction: 0.3,
                smooth,
                keys: keys.clone(),
                up: Vector3::y(),
            };
            let c = track.capsule_at(0.5);
            assert!((c.centre - keys[1].position).norm() < 1e-12);
            let mid = track.capsule_at(0.25);
            assert!((mid.centre.x + 0.35).abs() < 0.1);
            assert!(
                mid.velocity.x > 2.0,
                "moving +x at about 2.6 m/s: {}",
                mid.velocity.x
            );
        }
        let lin = ManipulatorTrack {
            radius: 0.05,
            length: 0.8,
            friction: 0.3,
            smooth: false,
            keys,
            up: Vector3::y(),
        };
        assert!((lin.capsule_at(0.25).centre.x + 0.35).abs() < 1e-12);
        assert!((lin.capsule_at(0.25).velocity.x - 2.6).abs() < 1e-6);
    }

    #[test]
    fn closest_point_clamps_to_the_segment() {
        let c = Capsule {
            centre: Vector3::zeros(),
            axis: Vector3::x(),
            length: 2.0,
            radius: 0.1,
            velocity: Vector3::zeros(),
            friction: 0.0,
        };
        assert_eq!(
            c.closest_point(&Vector3::new(5.0, 1.0, 0.0)),
            Vector3::new(1.0, 0.0, 0.0)
        );
        assert_eq!(
            c.closest_point(&Vector3::new(0.3, 1.0, 0.0)),
            Vector3::new(0.3, 0.0, 0.0)
        );
    }
}
