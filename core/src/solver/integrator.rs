//! The integrators behind one trait ([`Integrate`]): each chooses the substeps of an output
//! frame and advances a [`World`] by one substep, adding what the frame's diagnostics need to
//! a [`FrameAccumulator`]. `World` owns the state (nodes, springs, cells, contacts) and the
//! steps shared by every integrator (rigid bodies, volume preservation, joints); which
//! integrator steps it is the [`Integrator`] of its settings:
//!
//! - [`Integrator::SymplecticEuler`]: Miyazaki's explicit step with the fusion model
//!   (`world/euler.rs`), trajectory constraints enforced after it;
//! - [`Integrator::Newmark`]: Terasawa's iterative Newmark-β (`newmark.rs`);
//! - [`Integrator::Xpbd`]: small-step XPBD with volumetric cells (`xpbd/`).

use super::diagnostics::StepStats;
use super::substeps::SubstepChoice;
use super::World;
use nalgebra::Vector3;

/// Time integration scheme of a [`World`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Integrator {
    /// Miyazaki's symplectic Euler with velocity dispersion (the default).
    #[default]
    SymplecticEuler,
    /// Terasawa's iterative Newmark-β (module docs).
    Newmark {
        /// ¼ (average acceleration) or ⅙ (linear acceleration); any value in (0, ½].
        beta: f64,
        /// Relative tolerance on the change of the acceleration between iterations.
        tolerance: f64,
        max_iterations: u32,
    },
    /// Extended position-based dynamics with small steps and volumetric cells (the scene
    /// file's default; see [`super::xpbd`]).
    Xpbd,
}

impl Integrator {
    /// Refuse parameters the step cannot use: β outside (0, ½], a tolerance that is not
    /// positive and finite, or no iterations.
    pub fn check(&self) -> Result<(), String> {
        match *self {
            Integrator::SymplecticEuler | Integrator::Xpbd => Ok(()),
            Integrator::Newmark {
                beta,
                tolerance,
                max_iterations,
            } => {
                if !(beta > 0.0 && beta <= 0.5) {
                    Err(format!("Newmark beta must be in (0, 0.5], got {beta}"))
                } else if !(tolerance.is_finite() && tolerance > 0.0) {
                    Err(format!(
                        "Newmark tolerance must be finite and positive, got {tolerance}"
                    ))
                } else if max_iterations == 0 {
                    Err("Newmark max_iterations must be at least 1".to_string())
                } else {
                    Ok(())
                }
            }
        }
    }

    /// Newmark-β with β = ¼, tolerance 1e-10, at most 50 iterations.
    pub fn newmark() -> Integrator {
        Integrator::Newmark {
            beta: 0.25,
            tolerance: 1e-10,
            max_iterations: 50,
        }
    }
}

/// What an integrator does for a [`World`]; implemented by one zero-sized (or parameter)
/// type per integrator, dispatched statically by [`Integrator`] (no allocation per substep).
pub(crate) trait Integrate {
    /// Substeps for an output frame of `frame_dt` seconds, and what bounds them.
    fn choose_substeps(&self, world: &mut World, frame_dt: f64) -> SubstepChoice;
    /// One substep of `dt` seconds; advances `world.time`.
    fn substep(&self, world: &mut World, dt: f64, acc: &mut FrameAccumulator) -> StepStats;
}

impl Integrator {
    /// Calls `f` with this integrator's [`Integrate`] implementation.
    fn with<R>(self, f: impl FnOnce(&dyn Integrate) -> R) -> R {
        match self {
            Integrator::SymplecticEuler => f(&super::world::SymplecticEuler),
            Integrator::Newmark {
                beta,
                tolerance,
                max_iterations,
            } => f(&super::newmark::NewmarkBeta {
                beta,
                tolerance,
                max_iterations,
            }),
            Integrator::Xpbd => f(&super::xpbd::SmallStepXpbd),
        }
    }

    /// [`Integrate::choose_substeps`] of this integrator.
    pub(crate) fn choose_substeps(self, world: &mut World, frame_dt: f64) -> SubstepChoice {
        self.with(|i| i.choose_substeps(world, frame_dt))
    }

    /// [`Integrate::substep`] of this integrator.
    pub(crate) fn substep(
        self,
        world: &mut World,
        dt: f64,
        acc: &mut FrameAccumulator,
    ) -> StepStats {
        self.with(|i| i.substep(world, dt, acc))
    }
}

/// Totals over one output frame's substeps, filled by the integrators and read into the
/// frame's diagnostics.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct FrameAccumulator {
    pub corrections: u64,
    pub iterations: u32,
    pub cap_hits: u32,
    pub max_depth: f64,
    pub reaction_sum: Vector3<f64>,
    pub steps: u32,
    pub newmark_iterations: u32,
    pub newmark_max_iterations: u32,
    pub newmark_cap_hits: u32,
    /// Work of the manipulators on the bodies, J (XPBD steps).
    pub manipulator_work: f64,
    /// Work of separating parts that start in contact, J (XPBD steps).
    pub separation_work: f64,
}
