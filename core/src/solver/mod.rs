//! The mass-spring solver (Miyazaki et al. 1996): node state in structure-of-arrays, springs
//! with dampers, gravity, elastic-layer contact with friction, the velocity-dispersion fusion
//! model, and symplectic-Euler stepping with substeps chosen from the accuracy bound; Terasawa's
//! analysis-model options: Newmark-β integration, pin/trajectory constraints, a wind field and
//! volume preservation.
//!
//! All bodies of a scene live in one [`World`]: their nodes are concatenated (a body is a range
//! of nodes), so one step is one pass over all nodes and springs. Every parallel loop writes
//! disjoint slots and every reduction runs in fixed-size chunks, so results are identical bit
//! for bit whatever the thread count.

pub mod body_contact;
pub mod constraints;
mod contact;
pub mod contact_log;
pub mod deformation_damping;
pub mod device;
pub mod diagnostics;
pub mod fields;
mod forces;
mod integrator;
pub mod joints;
pub mod manipulator;
pub mod miyazaki1996_velocity_dispersion;
pub mod newmark;
mod newmark_post;
pub mod regions;
pub mod rigid;
pub mod stencil;
pub mod substeps;
mod team;
pub mod volume;
mod world;
pub mod xpbd;

pub use body_contact::ContactModel;
pub use constraints::{
    nearest_node, nodes_in_box, ConstraintError, Interpolation, Path, TrajectoryConstraint, Wind,
};
pub use contact::{ContactLayer, Plane};
pub use contact_log::{ContactLog, ContactPartner, ContactRecord};
pub use diagnostics::{FrameDiagnostics, SimulationError, StepStats};
pub use manipulator::{Capsule, ManipulatorTrack};
pub use miyazaki1996_velocity_dispersion::DispersionMode;
pub use newmark::Integrator;
pub use rigid::RigidBody;
pub use stencil::LatticeGrid;
pub use substeps::{max_k_over_m, realtime_steps, SubstepChoice};
pub use volume::VolumeConstraint;
pub use world::{BodyHandle, BodyInfo, World, WorldSettings};

use nalgebra::Vector3;

/// Node state, one entry per node of every body.
#[derive(Debug, Default, PartialEq)]
pub struct NodeState {
    pub position: Vec<Vector3<f64>>,
    pub velocity: Vec<Vector3<f64>>,
    pub mass: Vec<f64>,
    /// 0 for pinned nodes.
    pub inv_mass: Vec<f64>,
}

impl Clone for NodeState {
    fn clone(&self) -> Self {
        NodeState {
            position: self.position.clone(),
            velocity: self.velocity.clone(),
            mass: self.mass.clone(),
            inv_mass: self.inv_mass.clone(),
        }
    }

    /// Field by field into the existing buffers (the derived `clone_from` would allocate
    /// new ones): the Newmark step copies the state every step.
    fn clone_from(&mut self, source: &Self) {
        self.position.clone_from(&source.position);
        self.velocity.clone_from(&source.velocity);
        self.mass.clone_from(&source.mass);
        self.inv_mass.clone_from(&source.inv_mass);
    }
}

impl NodeState {
    pub fn len(&self) -> usize {
        self.position.len()
    }
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
}

/// Springs in structure-of-arrays form. Spring `s` joins nodes `a[s]` and `b[s]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpringSet {
    pub a: Vec<u32>,
    pub b: Vec<u32>,
    pub rest_length: Vec<f64>,
    /// Spring constant, N/m.
    pub stiffness: Vec<f64>,
    /// Damper constant along the spring, N·s/m.
    pub damping: Vec<f64>,
}

impl SpringSet {
    pub fn len(&self) -> usize {
        self.a.len()
    }
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }
    pub fn push(&mut self, a: u32, b: u32, rest_length: f64, stiffness: f64, damping: f64) {
        self.a.push(a);
        self.b.push(b);
        self.rest_length.push(rest_length);
        self.stiffness.push(stiffness);
        self.damping.push(damping);
    }
}

/// Chunk length for parallel loops: small systems stay on one thread.
pub(crate) const PAR_CHUNK: usize = 2048;

/// Sum `f(i)` over `0..n` in fixed chunks, so the result does not depend on the thread count
/// (see [`fold_chunks`]).
pub(crate) fn deterministic_sum(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    // −0.0 like `Iterator::sum` of floats: the same bits as summing the collected chunk sums.
    fold_chunks(n, -0.0, |r| r.map(&f).sum(), |total, p| total + p)
}

/// `chunk` over fixed [`PAR_CHUNK`]-long ranges of `0..n`, their results folded into `init`
/// in chunk order: the same on any thread count. The chunks run on the calling thread's
/// [`team`] when it has one (a frame's measures, between its substeps' passes: on rayon's pool
/// each of a frame's dozen measures woke a sleeping worker while the team's helper still held
/// the other core), else on rayon's pool. They are computed in batches held on the stack, so
/// nothing is allocated.
pub(crate) fn fold_chunks<T: Copy + Default + Send>(
    n: usize,
    init: T,
    chunk: impl Fn(std::ops::Range<usize>) -> T + Sync,
    fold: impl Fn(T, T) -> T,
) -> T {
    use rayon::prelude::*;
    const BATCH: usize = 64;
    let chunks = n.div_ceil(PAR_CHUNK);
    let on_team = team::active();
    let mut total = init;
    for first in (0..chunks).step_by(BATCH) {
        let mut partial = [T::default(); BATCH];
        let batch = &mut partial[..BATCH.min(chunks - first)];
        let run = |j: usize, out: &mut T| {
            let c = first + j;
            *out = chunk(c * PAR_CHUNK..((c + 1) * PAR_CHUNK).min(n));
        };
        if on_team {
            team::for_each(team::Chunks::new(batch, 1), |j, out: &mut [T]| {
                run(j, &mut out[0])
            });
        } else {
            batch
                .par_iter_mut()
                .enumerate()
                .for_each(|(j, out)| run(j, out));
        }
        total = batch.iter().fold(total, |t, &p| fold(t, p));
    }
    total
}

/// Maximum of `f(i)` over `0..n` and 0 ([`fold_chunks`]: on the team when there is one).
pub(crate) fn parallel_max(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    fold_chunks(n, 0.0, |r| r.map(&f).fold(0.0, f64::max), f64::max)
}
