//! Step-size choice (Miyazaki §4, physics §4).
//!
//! - Accuracy bound (eq 9–10): the spring period `T_s = 2π sqrt(m/k)` must span N steps,
//!   `ΔT < T_s / N`, i.e. `k/m < 4π² / (N² ΔT²)`; applied to the stiffest spring (with the
//!   lighter end's mass) and to the contact layer on the lightest node.
//! - Stability: symplectic Euler needs `ω ΔT < 2`; the largest ω² is bounded per node by
//!   Gershgorin, `2 Σ k / m`; we keep a 0.8 safety factor. For lattices this is the binding
//!   limit about as often as the accuracy bound, so both are applied and the binding one named.
//! - Real-time budget (eq 7–8): the largest n with `n T_c + T_r < T_i`, then `ΔT = T_i / n`.

use serde::Serialize;

/// `4π² / (N² ΔT²)`: the largest k/m the accuracy bound allows at step `dt` (eq 10).
pub fn max_k_over_m(dt: f64, n: f64) -> f64 {
    4.0 * std::f64::consts::PI.powi(2) / (n * n * dt * dt)
}

/// Largest step the accuracy bound allows for a given k/m.
pub fn accuracy_step(k_over_m: f64, n: f64) -> f64 {
    2.0 * std::f64::consts::PI / (n * k_over_m.sqrt())
}

/// Eq 7–8: for refresh interval `t_i`, step cost `t_c` and draw cost `t_r` (seconds), the
/// number of steps per refresh and the step length, or `None` when not even one step fits.
pub fn realtime_steps(t_i: f64, t_c: f64, t_r: f64) -> Option<(u32, f64)> {
    if !(t_i > 0.0 && t_c > 0.0 && t_r >= 0.0) || t_c + t_r >= t_i {
        return None;
    }
    let mut n = ((t_i - t_r) / t_c).floor() as u32;
    // Strict inequality: n T_c + T_r < T_i.
    while n > 0 && n as f64 * t_c + t_r >= t_i {
        n -= 1;
    }
    (n > 0).then(|| (n, t_i / n as f64))
}

/// The substep count chosen for a frame and why.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SubstepChoice {
    pub substeps: u32,
    pub dt: f64,
    /// `"accuracy"`, `"stability"`, `"contact"`, `"speed"` or `"fixed"`.
    pub limited_by: &'static str,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table1_max_k_over_m_to_the_papers_rounding() {
        // Miyazaki Table 1 (N = 10): paper value, significant figures it kept.
        let table = [
            (0.003, 43000.0, 2),
            (0.006, 10000.0, 1),
            (0.015, 1700.0, 2),
            (0.03, 430.0, 2),
            (0.048, 170.0, 2),
            (0.08, 60.0, 1),
        ];
        let exact = [43865.0, 10966.0, 1755.0, 439.0, 171.0, 62.0];
        for (i, &(dt, paper, digits)) in table.iter().enumerate() {
            let v = max_k_over_m(dt, 10.0);
            assert!((v - exact[i]).abs() < 1.0, "dt {dt}: {v} vs {}", exact[i]);
            // Truncate to the paper's significant figures.
            let scale = 10f64.powi(v.log10().floor() as i32 + 1 - digits);
            let truncated = (v / scale).floor() * scale;
            assert_eq!(truncated, paper, "dt {dt}: {v} truncates to {truncated}");
        }
    }

    #[test]
    fn accuracy_step_inverts_the_bound() {
        let dt = accuracy_step(max_k_over_m(0.01, 10.0), 10.0);
        assert!((dt - 0.01).abs() < 1e-15);
    }

    #[test]
    fn realtime_choice_eq7_8() {
        // 60 Hz, 1 ms per step, 4 ms per draw: n = 12 (12 + 4 = 16 < 16.67), ΔT = T_i/12.
        let (n, dt) = realtime_steps(1.0 / 60.0, 1e-3, 4e-3).unwrap();
        assert_eq!(n, 12);
        assert!((dt - 1.0 / 720.0).abs() < 1e-15);
        // Exact fit is not allowed (strict inequality): 10 ms frame, 2 ms steps, 2 ms draw → 3.
        assert_eq!(realtime_steps(0.010, 0.002, 0.002).unwrap().0, 3);
        assert!(realtime_steps(0.010, 0.006, 0.005).is_none());
    }
}
