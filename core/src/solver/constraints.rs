//! Pin and trajectory constraints (physics §9, Terasawa §3.1, eq 3.1) and the wind force field.
//!
//! A [`TrajectoryConstraint`] makes a set of nodes follow a keyframed [`Path`] (linear or
//! Catmull-Rom), each node keeping the offset it had from the path when the constraint was
//! added; a pin is a constant path. `strength` in [0, 1] binds the nodes exactly (1) or
//! loosely (a fraction of the control).
//!
//! - Under Newmark-β (see [`super::newmark`]) the control is Terasawa's eq 3.1: the node's
//!   acceleration at t + Δt is the one that lands it on the path,
//!   `a = (x(t+Δt) − x(t) − Δt ẋ(t) − (½ − β) Δt² ẍ(t)) / (β Δt²)` (the control force is `m a`
//!   minus the node's other forces). With strength `s` the node's acceleration is
//!   `(1 − s) F/m + s a`, so `s = 1` is exact to rounding and `s = 0` leaves the node free.
//! - Under symplectic Euler the path is enforced after the step by blending the position
//!   towards the target and the velocity towards `(x_target − x(t)) / Δt` by `s` (with
//!   `s = 1`, position and velocity are set directly).

use nalgebra::Vector3;

/// How a [`Path`] interpolates between its keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    #[default]
    Linear,
    /// Uniform Catmull-Rom spline through the keys (end keys repeated as tangent helpers).
    CatmullRom,
}

/// Why a constraint or path was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConstraintError {
    #[error("path needs at least one key")]
    EmptyPath,
    #[error("path key {index}: time {time} and position must be finite, times increasing")]
    BadKey { index: usize, time: f64 },
    #[error("constraint strength must be in [0, 1], got {0}")]
    BadStrength(f64),
    #[error("node {node} is out of range (the world has {count} nodes)")]
    NodeOutOfRange { node: usize, count: usize },
    #[error("constraint needs at least one node")]
    NoNodes,
    #[error("body {0} is out of range")]
    BodyOutOfRange(usize),
    #[error("body \"{0}\" has no lattice cells, so no volume to preserve")]
    NoCells(String),
    #[error("body \"{0}\" cannot be rigid: it needs three non-collinear nodes, all with mass")]
    NotRigid(String),
    #[error("stiffness scale must be finite and positive, got {0}")]
    BadStiffnessScale(f64),
    #[error("volume scale must be finite and positive, got {0}")]
    BadVolumeScale(f64),
    #[error("body \"{body}\" has a non-positive rest volume {volume} m³")]
    BadRestVolume { body: String, volume: f64 },
}

/// A keyframed path: `(time s, position m)` keys, strictly increasing in time. Before the first
/// key and after the last the path holds still.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    keys: Vec<(f64, Vector3<f64>)>,
    pub interpolation: Interpolation,
}

impl Path {
    pub fn new(
        keys: Vec<(f64, Vector3<f64>)>,
        interpolation: Interpolation,
    ) -> Result<Path, ConstraintError> {
        if keys.is_empty() {
            return Err(ConstraintError::EmptyPath);
        }
        for (i, &(t, p)) in keys.iter().enumerate() {
            let finite = t.is_finite() && p.iter().all(|c| c.is_finite());
            if !finite || (i > 0 && t <= keys[i - 1].0) {
                return Err(ConstraintError::BadKey { index: i, time: t });
            }
        }
        Ok(Path {
            keys,
            interpolation,
        })
    }

    /// A path that stays at `p` (a pin).
    pub fn constant(p: Vector3<f64>) -> Path {
        Path {
            keys: vec![(0.0, p)],
            interpolation: Interpolation::Linear,
        }
    }

    pub fn keys(&self) -> &[(f64, Vector3<f64>)] {
        &self.keys
    }

    /// Position on the path at time `t`.
    pub fn at(&self, t: f64) -> Vector3<f64> {
        let k = &self.keys;
        let n = k.len();
        if n == 1 || t <= k[0].0 {
            return k[0].1;
        }
        if t >= k[n - 1].0 {
            return k[n - 1].1;
        }
        // Segment i: k[i].0 <= t < k[i + 1].0.
        let i = k.partition_point(|key| key.0 <= t) - 1;
        let u = (t - k[i].0) / (k[i + 1].0 - k[i].0);
        let (p1, p2) = (k[i].1, k[i + 1].1);
        match self.interpolation {
            Interpolation::Linear => p1 + (p2 - p1) * u,
            Interpolation::CatmullRom => {
                let p0 = if i > 0 { k[i - 1].1 } else { p1 };
                let p3 = if i + 2 < n { k[i + 2].1 } else { p2 };
                let (u2, u3) = (u * u, u * u * u);
                (p1 * 2.0
                    + (p2 - p0) * u
                    + (p0 * 2.0 - p1 * 5.0 + p2 * 4.0 - p3) * u2
                    + (-p0 + p1 * 3.0 - p2 * 3.0 + p3) * u3)
                    * 0.5
            }
        }
    }
}

/// Nodes bound to a path: node `nodes[j]` follows `path(t) + offsets[j]`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryConstraint {
    pub nodes: Vec<usize>,
    pub offsets: Vec<Vector3<f64>>,
    pub path: Path,
    /// 1: exact; 0: free; between: loosely bound (module docs).
    pub strength: f64,
}

impl TrajectoryConstraint {
    /// Target of the constraint's `j`-th node at time `t`.
    pub fn target(&self, j: usize, t: f64) -> Vector3<f64> {
        self.path.at(t) + self.offsets[j]
    }
}

/// A uniform wind with a sinusoidal gust, acting on every node as air drag:
/// `F = m · drag_per_s · (w(t) − v)`, `w(t) = velocity + gust · sin(2π gust_hz t)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wind {
    /// Mean air velocity, m/s.
    pub velocity: Vector3<f64>,
    /// Gust amplitude, m/s.
    pub gust: Vector3<f64>,
    pub gust_hz: f64,
    /// Drag rate, 1/s (drag force per unit mass per unit relative speed).
    pub drag_per_s: f64,
}

impl Wind {
    pub fn air_velocity(&self, t: f64) -> Vector3<f64> {
        self.velocity + self.gust * (std::f64::consts::TAU * self.gust_hz * t).sin()
    }

    /// Force on a node of mass `m` moving at `v`, given the air velocity `air`.
    #[inline]
    pub fn force(&self, air: Vector3<f64>, v: Vector3<f64>, m: f64) -> Vector3<f64> {
        (air - v) * (m * self.drag_per_s)
    }
}

/// Indices of the nodes inside the axis-aligned box `[lo, hi]` (bounds included).
pub fn nodes_in_box(positions: &[Vector3<f64>], lo: Vector3<f64>, hi: Vector3<f64>) -> Vec<usize> {
    positions
        .iter()
        .enumerate()
        .filter(|(_, x)| (0..3).all(|k| x[k] >= lo[k] && x[k] <= hi[k]))
        .map(|(i, _)| i)
        .collect()
}

/// Index of the node nearest to `point` (the lowest index on ties), `None` without nodes.
pub fn nearest_node(positions: &[Vector3<f64>], point: Vector3<f64>) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (i, x) in positions.iter().enumerate() {
        let d = (x - point).norm_squared();
        if best.is_none_or(|(_, b)| d < b) {
            best = Some((i, d));
        }
    }
    best.map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_interpolate_through_their_keys() {
        let keys = vec![
            (0.0, Vector3::new(0.0, 0.0, 0.0)),
            (1.0, Vector3::new(1.0, 2.0, 0.0)),
            (2.0, Vector3::new(3.0, 2.0, 1.0)),
        ];
        for interp in [Interpolation::Linear, Interpolation::CatmullRom] {
            let p = Path::new(keys.clone(), interp).unwrap();
            for (t, x) in &keys {
                assert!((p.at(*t) - x).norm() < 1e-15, "{interp:?} at {t}");
            }
            assert_eq!(p.at(-1.0), keys[0].1);
            assert_eq!(p.at(5.0), keys[2].1);
        }
        let lin = Path::new(keys.clone(), Interpolation::Linear).unwrap();
        assert!((lin.at(1.5) - Vector3::new(2.0, 2.0, 0.5)).norm() < 1e-15);
        // Catmull-Rom at the middle of the first segment (p0 = p1 repeated):
        // 0.5·(2p1 + (p2 − p0)/2 + (2p0 − 5p1 + 4p2 − p3)/4 + (−p0 + 3p1 − 3p2 + p3)/8).
        let cr = Path::new(keys.clone(), Interpolation::CatmullRom).unwrap();
        let (p0, p1, p2, p3) = (keys[0].1, keys[0].1, keys[1].1, keys[2].1);
        let want = (p1 * 2.0
            + (p2 - p0) * 0.5
            + (p0 * 2.0 - p1 * 5.0 + p2 * 4.0 - p3) * 0.25
            + (-p0 + p1 * 3.0 - p2 * 3.0 + p3) * 0.125)
            * 0.5;
        assert!((cr.at(0.5) - want).norm() < 1e-15);
        assert!(Path::new(vec![], Interpolation::Linear).is_err());
        assert_eq!(
            Path::new(
                vec![(1.0, Vector3::zeros()), (1.0, Vector3::x())],
                Interpolation::Linear
            ),
            Err(ConstraintError::BadKey {
                index: 1,
                time: 1.0
            })
        );
    }

    #[test]
    fn node_selection_by_box_and_nearest_point() {
        let xs: Vec<Vector3<f64>> = (0..10).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect();
        assert_eq!(
            nodes_in_box(
                &xs,
                Vector3::new(2.0, -1.0, -1.0),
                Vector3::new(4.5, 1.0, 1.0)
            ),
            vec![2, 3, 4]
        );
        assert_eq!(nearest_node(&xs, Vector3::new(6.6, 3.0, 0.0)), Some(7));
        assert_eq!(nearest_node(&[], Vector3::zeros()), None);
    }
}
