//! What the Newmark-β step adds after its corrector: Miyazaki's velocity dispersion (fusion
//! model) and the deformation damping, which used to be symplectic-Euler only. Both act on
//! `v_{n+1}` as in the symplectic step (damping first, then the dispersion, with the same
//! settings); each node's velocity change Δv also moves it by ½ Δt Δv, so
//! `x_{n+1} − x_n = Δt (v_n + v_{n+1}) / 2` — the average-acceleration identity of β = ¼ — holds
//! for the changed velocities too (β = ⅙ gets the same trapezoidal share). The fusion test
//! looks one step ahead from `x_{n+1}` (the symplectic step tests from `x_n` before moving).
//! Nodes of path constraints keep the corrector's state, so they stay on their paths exactly.
//! The accelerations kept for the next step are the forces' (an operator split).

use super::deformation_damping::RigidScratch;
use super::forces::Adjacency;
use super::miyazaki1996_velocity_dispersion::{
    disperse_with, DispersionMode, DispersionScratch, DispersionStats, SpringColouring,
};
use super::World;
use nalgebra::Vector3;

/// Colouring, node → spring lists (the dispersion's active set) and scratch kept between
/// steps.
#[derive(Debug, Clone, Default)]
pub(crate) struct PostState {
    colouring: SpringColouring,
    adjacency: Adjacency,
    /// (nodes, springs) the colouring and adjacency were built for.
    built_for: (usize, usize),
    scratch: DispersionScratch,
    rigid: RigidScratch,
    before: Vec<Vector3<f64>>,
    kept: Vec<(usize, Vector3<f64>, Vector3<f64>)>,
}

/// Apply the deformation damping and the velocity dispersion to the corrected state.
pub(crate) fn after_corrector(world: &mut World, post: &mut PostState, dt: f64) -> DispersionStats {
    let damped = world.bodies.iter().any(|b| b.deformation_damping > 0.0);
    let mode = world.settings.dispersion;
    if !damped && mode == DispersionMode::Off {
        return DispersionStats::default();
    }
    let nodes = &mut world.nodes;
    post.before.clone_from(&nodes.velocity);
    post.kept.clear();
    for c in &world.constraints {
        for &i in &c.nodes {
            post.kept.push((i, nodes.position[i], nodes.velocity[i]));
        }
    }
    super::deformation_damping::damp(nodes, &world.bodies, dt, &mut post.rigid);
    let stats = if mode == DispersionMode::Off {
        DispersionStats::default()
    } else {
        let shape = (nodes.len(), world.springs.len());
        if post.built_for != shape {
            post.colouring = SpringColouring::new(nodes.len(), &world.springs);
            post.adjacency = Adjacency::new(nodes.len(), &world.springs);
            post.built_for = shape;
        }
        disperse_with(
            mode,
            nodes,
            &world.springs,
            &post.colouring,
            dt,
            world.settings.max_dispersion_iterations,
            &mut post.scratch,
            None,
            Some(&post.adjacency),
        )
    };
    for (i, v0) in post.before.iter().enumerate() {
        let dv = nodes.velocity[i] - v0;
        nodes.position[i] += dv * (0.5 * dt);
    }
    for &(i, x, v) in &post.kept {
        nodes.position[i] = x;
        nodes.velocity[i] = v;
    }
    stats
}
