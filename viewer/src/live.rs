//! Live mode's logic, kept out of the window so it can be tested: the mouse-driven capsule
//! ([`LiveManipulator`]: drag moves it in the horizontal plane, wheel or shift-drag changes its
//! height, right-drag turns it about up) with the resistance of physics §6 (the advance into
//! the body shrinks in proportion to the reaction force), and the real-time step plan of
//! Miyazaki eq 7–8 ([`StepTimer`], [`plan_steps`]) from measured step and draw times.

use springbake_core::nalgebra::Vector3;
use springbake_core::solver::manipulator::axis_from_yaw;
use springbake_core::solver::{realtime_steps, Capsule};

/// A user's mouse gesture on the capsule, already converted to world units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gesture {
    /// Move by this world displacement (horizontal drag or height change).
    Move(Vector3<f64>),
    /// Turn about up by this many degrees.
    Yaw(f64),
}

/// Reduce a desired displacement by the reaction (physics §6): the part of `desired` that
/// pushes against the reaction force `reaction` (N, the force the body exerts on the capsule)
/// is scaled by `max(0, 1 − |reaction| / stop_force_n)`; moving sideways or away is free. At
/// `stop_force_n` the capsule no longer advances into the body.
pub fn resisted_displacement(
    desired: Vector3<f64>,
    reaction: Vector3<f64>,
    stop_force_n: f64,
) -> Vector3<f64> {
    let f = reaction.norm();
    if !(f > 0.0 && f.is_finite() && stop_force_n > 0.0) {
        return desired;
    }
    let back = reaction / f; // points out of the body, towards where the capsule is pushed
    let into = -desired.dot(&back); // > 0 when moving against the reaction
    if into <= 0.0 {
        return desired;
    }
    let keep = (1.0 - f / stop_force_n).max(0.0);
    desired + back * (into * (1.0 - keep))
}

/// The mouse-driven capsule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveManipulator {
    pub centre: Vector3<f64>,
    pub yaw_deg: f64,
    pub radius: f64,
    pub length: f64,
    pub friction: f64,
    pub up: Vector3<f64>,
    /// Reaction at which the capsule stops advancing into the body, N.
    pub stop_force_n: f64,
    /// Velocity from the last update, m/s (for contact friction).
    pub velocity: Vector3<f64>,
}

impl LiveManipulator {
    /// A capsule sized to a body with bounds `lo..hi`, parked just above it: radius 8 % and
    /// axis 60 % of the largest extent. It stops advancing at the force that compresses the
    /// body's material (Young's modulus `young_pa`) under the capsule's projected area
    /// (2 r × length) by 20 %, so a stiff material resists sooner than jelly.
    pub fn above(
        lo: Vector3<f64>,
        hi: Vector3<f64>,
        up: Vector3<f64>,
        young_pa: f64,
    ) -> LiveManipulator {
        let size = (hi - lo).amax().max(1e-3);
        let centre_xy = (lo + hi) * 0.5;
        let top = up.dot(&hi);
        let radius = 0.08 * size;
        let centre = centre_xy - up * up.dot(&centre_xy) + up * (top + 2.0 * radius);
        LiveManipulator {
            centre,
            yaw_deg: 0.0,
            radius,
            length: 0.6 * size,
            friction: 0.4,
            up,
            stop_force_n: (0.2 * young_pa * 2.0 * radius * 0.6 * size).max(1e-3),
            velocity: Vector3::zeros(),
        }
    }

    /// The solver's capsule for this pose.
    pub fn capsule(&self) -> Capsule {
        Capsule {
            centre: self.centre,
            axis: axis_from_yaw(self.up, self.yaw_deg),
            length: self.length,
            radius: self.radius,
            velocity: self.velocity,
            friction: self.friction,
        }
    }

    /// Apply one frame's gestures (summed) against the last reaction; `frame_dt` seconds per
    /// frame gives the capsule's velocity. Returns the displacement actually applied.
    pub fn update(
        &mut self,
        gestures: &[Gesture],
        reaction: Vector3<f64>,
        frame_dt: f64,
    ) -> Vector3<f64> {
        let mut desired = Vector3::zeros();
        for g in gestures {
            match *g {
                Gesture::Move(d) => desired += d,
                Gesture::Yaw(deg) => self.yaw_deg = (self.yaw_deg + deg).rem_euclid(360.0),
            }
        }
        let moved = resisted_displacement(desired, reaction, self.stop_force_n);
        self.centre += moved;
        self.velocity = if frame_dt > 0.0 {
            moved / frame_dt
        } else {
            Vector3::zeros()
        };
        moved
    }
}

/// Running averages of the measured step and draw times (exponential, weight 0.2 per sample).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepTimer {
    /// Seconds per solver step.
    pub step_s: Option<f64>,
    /// Seconds per draw.
    pub draw_s: Option<f64>,
}

fn blend(old: Option<f64>, new: f64) -> Option<f64> {
    if !(new.is_finite() && new >= 0.0) {
        return old;
    }
    Some(match old {
        Some(o) => 0.8 * o + 0.2 * new,
        None => new,
    })
}

impl StepTimer {
    /// Record `steps` solver steps that took `seconds` in all.
    pub fn record_steps(&mut self, steps: u32, seconds: f64) {
        if steps > 0 {
            self.step_s = blend(self.step_s, seconds / steps as f64);
        }
    }

    pub fn record_draw(&mut self, seconds: f64) {
        self.draw_s = blend(self.draw_s, seconds);
    }
}

/// How to advance the world in one displayed frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepPlan {
    pub steps: u32,
    /// Step length, s.
    pub dt: f64,
    /// Simulated seconds per wall-clock second (1 when real time holds).
    pub realtime_factor: f64,
    /// True when eq 7–8 fit: `steps · T_c + T_r < T_i` with a stable step.
    pub realtime: bool,
}

/// Steps per displayed frame (Miyazaki eq 7–8): with refresh interval `t_i`, the largest `n`
/// with `n T_c + T_r < T_i` and `ΔT = T_i / n`. A step may not exceed `max_dt` (the world's
/// accuracy/stability bound): when the budget cannot afford `T_i / max_dt` steps, the plan takes
/// the affordable number of `max_dt` steps and the simulation runs slower than real time.
/// Before anything was measured it takes one step per `max_dt`. At most `max_steps` steps.
pub fn plan_steps(t_i: f64, timer: &StepTimer, max_dt: f64, max_steps: u32) -> StepPlan {
    let max_dt = if max_dt > 0.0 && max_dt.is_finite() {
        max_dt
    } else {
        t_i
    };
    let needed = ((t_i / max_dt).ceil().max(1.0)).min(max_steps as f64) as u32;
    let fits = match (timer.step_s, timer.draw_s) {
        (Some(c), r) => realtime_steps(t_i, c, r.unwrap_or(0.0)),
        (None, _) => Some((needed, t_i / needed as f64)),
    };
    match fits {
        Some((n, dt)) if dt <= max_dt * (1.0 + 1e-9) => {
            let n = n.min(max_steps).max(needed);
            StepPlan {
                steps: n,
                dt: t_i / n as f64,
                realtime_factor: 1.0,
                realtime: true,
            }
        }
        Some((n, _)) => {
            let n = n.min(max_steps).max(1);
            StepPlan {
                steps: n,
                dt: max_dt,
                realtime_factor: n as f64 * max_dt / t_i,
                realtime: false,
            }
        }
        None => StepPlan {
            steps: 1,
            dt: max_dt.min(t_i),
            realtime_factor: max_dt.min(t_i) / t_i,
            realtime: false,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_reaction_means_no_resistance() {
        let d = Vector3::new(0.01, -0.02, 0.0);
        assert_eq!(resisted_displacement(d, Vector3::zeros(), 10.0), d);
    }

    #[test]
    fn pushing_in_is_reduced_in_proportion_to_the_reaction() {
        // The body pushes the capsule up with 5 N; the user drags 1 cm down into it.
        let reaction = Vector3::new(0.0, 5.0, 0.0);
        let down = Vector3::new(0.0, -0.01, 0.0);
        let got = resisted_displacement(down, reaction, 20.0);
        assert!(
            (got.y + 0.0075).abs() < 1e-15,
            "75 % of the advance survives: {got:?}"
        );
        let harder = resisted_displacement(down, reaction * 2.0, 20.0);
        assert!((harder.y + 0.005).abs() < 1e-15, "50 %: {harder:?}");
        // At and beyond the stop force it no longer advances.
        assert!(resisted_displacement(down, reaction * 4.0, 20.0).norm() < 1e-15);
        assert!(resisted_displacement(down, reaction * 10.0, 20.0).norm() < 1e-15);
    }

    #[test]
    fn sideways_and_retreat_are_free() {
        let reaction = Vector3::new(0.0, 15.0, 0.0);
        let diagonal = Vector3::new(0.02, -0.01, 0.0);
        let got = resisted_displacement(diagonal, reaction, 20.0);
        assert!((got.x - 0.02).abs() < 1e-15, "sideways part kept: {got:?}");
        assert!(
            (got.y + 0.0025).abs() < 1e-15,
            "downward part at 25 %: {got:?}"
        );
        let up = Vector3::new(0.0, 0.01, 0.0);
        assert_eq!(resisted_displacement(up, reaction, 20.0), up);
    }

    #[test]
    fn gestures_move_turn_and_set_velocity() {
        let mut m = LiveManipulator::above(
            Vector3::new(-0.5, 0.0, -0.5),
            Vector3::new(0.5, 1.0, 0.5),
            Vector3::y(),
            1.0e4,
        );
        assert!(
            (m.centre - Vector3::new(0.0, 1.16, 0.0)).norm() < 1e-12,
            "{:?}",
            m.centre
        );
        assert!((m.stop_force_n - 192.0).abs() < 1e-9, "{}", m.stop_force_n);
        let moved = m.update(
            &[
                Gesture::Move(Vector3::new(0.1, 0.0, 0.0)),
                Gesture::Yaw(90.0),
            ],
            Vector3::zeros(),
            0.05,
        );
        assert_eq!(moved, Vector3::new(0.1, 0.0, 0.0));
        assert!((m.velocity.x - 2.0).abs() < 1e-12);
        let c = m.capsule();
        assert!(
            (c.axis - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12,
            "yaw 90 about +Y: {:?}",
            c.axis
        );
        // Pressing down against 96 N (half the stop force) advances half as far.
        let moved = m.update(
            &[Gesture::Move(Vector3::new(0.0, -0.02, 0.0))],
            Vector3::new(0.0, 96.0, 0.0),
            0.05,
        );
        assert!((moved.y + 0.01).abs() < 1e-12, "{moved:?}");
    }

    #[test]
    fn plan_uses_the_budget_at_real_time() {
        // 30 fps, 1 ms per step, 5 ms per draw: n = 28 (28 + 5 < 33.3), dt = T_i / 28.
        let timer = StepTimer {
            step_s: Some(1e-3),
            draw_s: Some(5e-3),
        };
        let p = plan_steps(1.0 / 30.0, &timer, 1e-3 * 2.0, 10_000);
        assert_eq!(p.steps, 28);
        assert!((p.dt - 1.0 / 30.0 / 28.0).abs() < 1e-15);
        assert!(p.realtime && p.realtime_factor == 1.0);
    }

    #[test]
    fn plan_slows_down_when_the_stable_step_is_too_short() {
        // Only 28 steps fit but stability needs dt <= 0.5 ms (67 steps): slow motion, 28 × 0.5 ms.
        let timer = StepTimer {
            step_s: Some(1e-3),
            draw_s: Some(5e-3),
        };
        let p = plan_steps(1.0 / 30.0, &timer, 5e-4, 10_000);
        assert_eq!(p.steps, 28);
        assert_eq!(p.dt, 5e-4);
        assert!(!p.realtime);
        assert!((p.realtime_factor - 28.0 * 5e-4 * 30.0).abs() < 1e-12);
        // Not even one step fits: one stable step per frame.
        let slow = StepTimer {
            step_s: Some(0.03),
            draw_s: Some(0.01),
        };
        let p = plan_steps(1.0 / 30.0, &slow, 5e-4, 10_000);
        assert_eq!((p.steps, p.dt), (1, 5e-4));
        // Unmeasured: as many steps as stability needs.
        let p = plan_steps(0.04, &StepTimer::default(), 0.01, 10_000);
        assert_eq!(p.steps, 4);
        assert!(p.realtime);
    }

    #[test]
    fn timer_averages_and_ignores_nonsense() {
        let mut t = StepTimer::default();
        t.record_steps(10, 0.01);
        assert_eq!(t.step_s, Some(0.001));
        t.record_steps(10, 0.02);
        assert!((t.step_s.unwrap() - 0.0012).abs() < 1e-15);
        t.record_steps(0, 1.0);
        t.record_draw(f64::NAN);
        assert!((t.step_s.unwrap() - 0.0012).abs() < 1e-15);
        assert_eq!(t.draw_s, None);
    }
}
