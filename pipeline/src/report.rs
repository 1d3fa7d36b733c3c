//! The `--report` JSON: bodies, per-frame diagnostics, events and stage timings.

use serde::Serialize;
use springbake_core::solver::FrameDiagnostics;

#[derive(Debug, Clone, Default, Serialize)]
pub struct Report {
    pub bodies: Vec<BodyReport>,
    /// One entry per output frame; values summed (energies) or maxed (penetration) over bodies.
    pub frames: Vec<FrameDiagnostics>,
    /// Event firings `{ frame, body, event, procedure }` in firing order (frame, then event
    /// declaration order, then procedure order); empty without `[[event]]`.
    pub events: Vec<serde_json::Value>,
    pub seconds: Seconds,
    /// Where the solver ran: "cpu", or the GPU adapter's name (see `[solver] device`).
    pub device: String,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct BodyReport {
    pub name: String,
    pub nodes: usize,
    pub springs: usize,
    pub cells: usize,
    pub islands: usize,
    /// Cell edge, metres.
    pub cell_size: f64,
    pub material: String,
    pub mass_kg: f64,
    /// The analysis model (`[body] model`).
    pub model: String,
    /// Set when the model is not exactly what was asked for (see `springbake_core::cage`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_note: Option<String>,
}

/// Wall-clock seconds per stage.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Seconds {
    pub import: f64,
    pub fit: f64,
    pub simulate: f64,
    pub export: f64,
}
