//! The orbit camera shared by the window and the software screenshot renderer: a target point,
//! yaw about the scene's up axis, pitch above the horizontal plane, distance, and a
//! perspective projection to pixels. Plain math with unit tests, no window needed.

use springbake_core::nalgebra::Vector3;

/// Camera-space position of a point: `x` right, `y` up, `depth` along the view direction
/// (positive in front of the eye).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewPoint {
    pub x: f64,
    pub y: f64,
    pub depth: f64,
}

/// A projected point in pixels (origin top-left, y down) with its camera depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenPoint {
    pub x: f64,
    pub y: f64,
    pub depth: f64,
}

/// Points closer than this (metres) are not projected.
pub const NEAR_M: f64 = 1e-3;

/// An orbiting perspective camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    pub target: Vector3<f64>,
    /// Unit up vector of the scene (the simulation frame's up axis).
    pub up: Vector3<f64>,
    /// Rotation about `up`, degrees; 0 looks from the first horizontal axis' positive side.
    pub yaw_deg: f64,
    /// Elevation above the horizontal plane, degrees, kept inside ±89.
    pub pitch_deg: f64,
    /// Eye-to-target distance, metres.
    pub distance: f64,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
}

impl OrbitCamera {
    /// A camera looking at `target` from yaw −60°, pitch 20°: from the front right (+Z, +X for
    /// Y-up scenes; −Y, +X for Z-up ones, Blender's front view).
    pub fn new(target: Vector3<f64>, up: Vector3<f64>, distance: f64) -> OrbitCamera {
        OrbitCamera {
            target,
            up: up.normalize(),
            yaw_deg: -60.0,
            pitch_deg: 20.0,
            distance,
            fov_y_deg: 40.0,
        }
    }

    /// A camera that frames the axis-aligned box `lo..hi` (metres) with some margin.
    pub fn framing(lo: Vector3<f64>, hi: Vector3<f64>, up: Vector3<f64>) -> OrbitCamera {
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).norm() * 0.5).max(1e-3);
        let mut cam = OrbitCamera::new(centre, up, 1.0);
        let half = (cam.fov_y_deg.to_radians() * 0.5).tan().atan();
        // The bounding sphere fits the vertical field of view with 20 % to spare.
        cam.distance = 1.2 * radius / half.sin();
        cam
    }

    /// Two horizontal unit axes: `a`, the first world axis not along up (X for Y-up and Z-up
    /// scenes), and `b = up × a`.
    fn horizontal_axes(&self) -> (Vector3<f64>, Vector3<f64>) {
        let trial = if self.up.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::z()
        };
        let a = (trial - self.up * self.up.dot(&trial)).normalize();
        let b = self.up.cross(&a);
        (a, b)
    }

    /// Eye position in world metres.
    pub fn eye(&self) -> Vector3<f64> {
        let (a, b) = self.horizontal_axes();
        let (sy, cy) = self.yaw_deg.to_radians().sin_cos();
        let (sp, cp) = self.pitch_deg.to_radians().sin_cos();
        let dir = (a * cy + b * sy) * cp + self.up * sp;
        self.target + dir * self.distance
    }

    /// Camera basis in world coordinates: (right, true up, forward).
    pub fn basis(&self) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let forward = (self.target - self.eye()).normalize();
        let right = forward.cross(&self.up).normalize();
        let up = right.cross(&forward);
        (right, up, forward)
    }

    /// Focal length in pixels for a viewport `height` pixels tall.
    pub fn focal_px(&self, height: f64) -> f64 {
        0.5 * height / (self.fov_y_deg.to_radians() * 0.5).tan()
    }

    /// World point to camera space.
    pub fn to_view(&self, p: &Vector3<f64>) -> ViewPoint {
        let (r, u, f) = self.basis();
        let d = p - self.eye();
        ViewPoint {
            x: r.dot(&d),
            y: u.dot(&d),
            depth: f.dot(&d),
        }
    }

    /// World point to pixels in a `width × height` viewport; `None` behind the near plane.
    pub fn project(&self, p: &Vector3<f64>, width: f64, height: f64) -> Option<ScreenPoint> {
        let v = self.to_view(p);
        (v.depth > NEAR_M).then(|| {
            let f = self.focal_px(height);
            ScreenPoint {
                x: 0.5 * width + f * v.x / v.depth,
                y: 0.5 * height - f * v.y / v.depth,
                depth: v.depth,
            }
        })
    }

    /// A projector with the basis computed once, for projecting many points.
    pub fn projector(&self, width: f64, height: f64) -> Projector {
        let (right, up, forward) = self.basis();
        Projector {
            eye: self.eye(),
            right,
            up,
            forward,
            focal: self.focal_px(height),
            cx: 0.5 * width,
            cy: 0.5 * height,
        }
    }

    /// Orbit by a mouse drag of `(dx, dy)` pixels: 0.4° per pixel, pitch clamped to ±89°.
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        self.yaw_deg = (self.yaw_deg - 0.4 * dx).rem_euclid(360.0);
        self.pitch_deg = (self.pitch_deg + 0.4 * dy).clamp(-89.0, 89.0);
    }

    /// Zoom by `steps` wheel notches (positive: closer), 10 % per notch.
    pub fn zoom(&mut self, steps: f64) {
        self.distance = (self.distance * 0.9f64.powf(steps)).clamp(1e-3, 1e6);
    }

    /// The world displacement in the horizontal plane for a mouse drag of `(dx, dy)` pixels at
    /// camera depth `depth`: right on screen moves along the camera's right projected onto the
    /// plane, up on screen (negative dy) moves away from the eye, and one pixel covers
    /// `depth / focal` metres so the dragged point keeps pace with the cursor.
    pub fn drag_horizontal(&self, dx: f64, dy: f64, depth: f64, height: f64) -> Vector3<f64> {
        let (right, _, forward) = self.basis();
        let flat = |v: Vector3<f64>| {
            let h = v - self.up * self.up.dot(&v);
            if h.norm() > 1e-9 {
                h.normalize()
            } else {
                Vector3::zeros()
            }
        };
        let mut away = flat(forward);
        if away == Vector3::zeros() {
            // Looking straight down or up: screen-up is the camera's up projected.
            away = flat(self.basis().1);
        }
        let scale = depth.max(NEAR_M) / self.focal_px(height);
        (flat(right) * dx - away * dy) * scale
    }

    /// The world displacement along up for a vertical drag of `dy` pixels at `depth`
    /// (dragging up raises).
    pub fn drag_vertical(&self, dy: f64, depth: f64, height: f64) -> Vector3<f64> {
        self.up * (-dy * depth.max(NEAR_M) / self.focal_px(height))
    }
}

/// [`OrbitCamera::project`] with the basis precomputed.
#[derive(Debug, Clone, Copy)]
pub struct Projector {
    pub eye: Vector3<f64>,
    pub right: Vector3<f64>,
    pub up: Vector3<f64>,
    pub forward: Vector3<f64>,
    pub focal: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Projector {
    pub fn project(&self, p: &Vector3<f64>) -> Option<ScreenPoint> {
        let d = p - self.eye;
        let depth = self.forward.dot(&d);
        (depth > NEAR_M).then(|| ScreenPoint {
            x: self.cx + self.focal * self.right.dot(&d) / depth,
            y: self.cy - self.focal * self.up.dot(&d) / depth,
            depth,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn target_projects_to_the_viewport_centre_at_its_distance() {
        for up in [Vector3::y(), Vector3::z()] {
            let cam = OrbitCamera::new(Vector3::new(1.0, 2.0, 3.0), up, 5.0);
            let s = cam.project(&cam.target, 800.0, 600.0).unwrap();
            assert!(close(s.x, 400.0) && close(s.y, 300.0), "{s:?}");
            assert!(close(s.depth, 5.0));
        }
    }

    #[test]
    fn up_is_up_on_screen_and_right_is_right() {
        let mut cam = OrbitCamera::new(Vector3::zeros(), Vector3::y(), 4.0);
        cam.pitch_deg = 0.0;
        cam.yaw_deg = 0.0; // eye on +X looking towards -X; right is then -Z... check by projection
        let above = cam
            .project(&Vector3::new(0.0, 1.0, 0.0), 100.0, 100.0)
            .unwrap();
        assert!(
            above.y < 50.0,
            "a point above the target is higher on screen: {above:?}"
        );
        let (right, _, _) = cam.basis();
        let r = cam.project(&right, 100.0, 100.0).unwrap();
        assert!(r.x > 50.0 && close(r.y, 50.0));
        // Eye on +X: the eye sits at (4, 0, 0).
        assert!((cam.eye() - Vector3::new(4.0, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn one_unit_at_depth_d_spans_focal_over_d_pixels() {
        let mut cam = OrbitCamera::new(Vector3::zeros(), Vector3::z(), 10.0);
        cam.fov_y_deg = 90.0; // focal = height / 2
        let (right, _, _) = cam.basis();
        let s = cam.project(&right, 200.0, 200.0).unwrap();
        assert!(close(s.x - 100.0, 100.0 / 10.0), "{s:?}");
    }

    #[test]
    fn points_behind_the_eye_are_not_projected() {
        let cam = OrbitCamera::new(Vector3::zeros(), Vector3::y(), 2.0);
        let behind = cam.eye() + (cam.eye() - cam.target);
        assert!(cam.project(&behind, 10.0, 10.0).is_none());
    }

    #[test]
    fn orbit_clamps_pitch_and_wraps_yaw() {
        let mut cam = OrbitCamera::new(Vector3::zeros(), Vector3::y(), 2.0);
        cam.orbit(0.0, 1000.0);
        assert_eq!(cam.pitch_deg, 89.0);
        cam.orbit(1000.0, 0.0);
        assert!((0.0..360.0).contains(&cam.yaw_deg));
        let eye_dist = (cam.eye() - cam.target).norm();
        assert!(close(eye_dist, 2.0));
        cam.zoom(1.0);
        assert!(close(cam.distance, 1.8));
    }

    #[test]
    fn framing_keeps_the_box_corners_on_screen() {
        let lo = Vector3::new(-0.5, 0.0, -0.2);
        let hi = Vector3::new(0.7, 1.3, 0.4);
        let cam = OrbitCamera::framing(lo, hi, Vector3::y());
        for i in 0..8 {
            let c = Vector3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let s = cam.project(&c, 400.0, 400.0).unwrap();
            assert!(
                (0.0..400.0).contains(&s.x) && (0.0..400.0).contains(&s.y),
                "corner {c:?} at {s:?}"
            );
        }
    }

    #[test]
    fn horizontal_drag_stays_in_the_plane_and_follows_the_cursor() {
        for up in [Vector3::y(), Vector3::z()] {
            let cam = OrbitCamera::new(Vector3::zeros(), up, 3.0);
            let d = cam.drag_horizontal(10.0, 0.0, 3.0, 500.0);
            assert!(d.dot(&up).abs() < 1e-12, "no vertical component: {d:?}");
            // A point on the target moved by d lands 10 px to the right.
            let s0 = cam.project(&cam.target, 500.0, 500.0).unwrap();
            let s1 = cam.project(&(cam.target + d), 500.0, 500.0).unwrap();
            assert!((s1.x - s0.x - 10.0).abs() < 0.1, "{s0:?} -> {s1:?}");
            // Dragging up on screen moves away from the eye (deeper).
            let away = cam.drag_horizontal(0.0, -10.0, 3.0, 500.0);
            assert!(away.dot(&up).abs() < 1e-12);
            assert!(cam.to_view(&away).depth > cam.to_view(&Vector3::zeros()).depth);
            // Dragging up with the vertical mode raises.
            assert!(cam.drag_vertical(-10.0, 3.0, 500.0).dot(&up) > 0.0);
        }
    }
}
