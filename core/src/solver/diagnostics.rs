//! Per-frame diagnostics (serialisable) and the solver's error type.

use nalgebra::Vector3;
use serde::Serialize;

/// What one step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepStats {
    pub dispersion_corrections: u64,
    pub dispersion_iterations: u32,
    pub dispersion_cap_hit: bool,
    /// Newmark-β predictor-corrector iterations (0 under symplectic Euler).
    pub newmark_iterations: u32,
    /// The Newmark iterations stopped at the cap without reaching the tolerance.
    pub newmark_cap_hit: bool,
    /// Largest relative volume error of the volume-preserved bodies before their correction.
    pub volume_error: f64,
}

/// Diagnostics of one output frame.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FrameDiagnostics {
    /// 1-based frame number.
    pub frame: usize,
    /// Simulated time at the frame, seconds (frame 1 is t = 0).
    pub time: f64,
    pub kinetic_energy: f64,
    pub elastic_energy: f64,
    /// m g h relative to height 0 along up, joules.
    pub gravity_energy: f64,
    pub substeps: u32,
    pub dispersion_corrections: u64,
    pub dispersion_iterations: u32,
    /// Steps in this frame whose dispersion sweeps hit the iteration cap.
    pub dispersion_cap_hits: u32,
    /// Newmark-β predictor-corrector iterations summed over the frame's steps (0 under
    /// symplectic Euler).
    pub newmark_iterations: u32,
    /// Most iterations one step of the frame needed.
    pub newmark_max_iterations: u32,
    /// Steps whose iterations stopped at the cap without reaching the tolerance.
    pub newmark_cap_hits: u32,
    /// How many times the frame was taken again from its start at twice the substeps because
    /// it folded a cell (the XPBD solver at automatic substeps; `substeps` is the last take's).
    pub redone: u32,
    pub inverted_cells: usize,
    /// Deepest penetration into any contact layer, metres.
    pub max_penetration: f64,
    /// Fastest node, m/s.
    pub max_speed: f64,
    /// Force on the manipulators (minus the sum of their contact forces on the body), N.
    pub manipulator_reaction: [f64; 3],
    /// Work the manipulators did on the bodies during the frame, J (XPBD).
    pub manipulator_work: f64,
    /// The energy balance: how far the kinetic and gravity energy at the frame's end exceed
    /// the total energy (kinetic + elastic + gravity) the bodies had at the start of the
    /// first frame plus the work done on them since (the manipulators', the parting of parts
    /// that start in contact), beyond a slack (5 % of the kinetic and elastic energy, the
    /// bodies' mass lifted 1 mm, and moving at the contacts' separation speed), J; 0 when
    /// they do not. Elastic energy counts in the budget only: at an impact the cells' energy
    /// of a state the sweep has not converged overstates what the motion can give back.
    /// Changes between frames (events) enter the budget. The budget is not the most total
    /// energy any frame started with: a contact pumping energy into the cells and the motion
    /// together (trimesh's chair, 15 J to 300 J in a second) raised that budget with it and
    /// was never flagged. `None` where the balance is not kept: a wind field (its work is not
    /// summed) or manipulators under the papers' integrators.
    pub energy_gain: Option<f64>,
}

impl FrameDiagnostics {
    pub fn reaction(&self) -> Vector3<f64> {
        Vector3::from(self.manipulator_reaction)
    }
}

/// A simulation that cannot go on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulationError {
    #[error("simulation diverged at frame {frame}: node {node} of body \"{body}\" has a non-finite {what}")]
    NonFinite {
        frame: usize,
        body: String,
        node: usize,
        what: &'static str,
    },
    #[error("cancelled")]
    Cancelled,
    /// A force field failed (a plug-in's exception, a wrong number of forces).
    #[error("{0}")]
    Field(String),
    /// The device solver failed (see [`crate::solver::device`]).
    #[error("the GPU solver failed: {0}")]
    Device(String),
}
