//! Newmark-β integration (physics §8, Terasawa eq 2.27–2.28), an alternative to the default
//! symplectic Euler step.
//!
//! With γ = ½ and the acceleration `a_n` of the previous step:
//! `x_{n+1} = x_n + Δt v_n + Δt² ((½ − β) a_n + β a_{n+1})`,
//! `v_{n+1} = v_n + Δt (a_n + a_{n+1}) / 2`.
//! `a_{n+1}` is found by the iterative predictor-corrector: start from `a_n`, predict the state,
//! evaluate the forces there (gravity, springs with their dampers, wind, the contacts of nodes
//! with the planes and manipulators), correct `a_{n+1} = F/m`, until the largest change of any
//! node's acceleration is at most `tolerance × max(|a|∞, 1 m/s²)` or `max_iterations` is reached
//! (reported in [`super::StepStats`]). β = ¼ is the average-acceleration (energy-conserving)
//! rule, β = ⅙ the linear-acceleration rule.
//!
//! Trajectory constraints replace the acceleration of their nodes by eq 3.1 (see
//! [`super::constraints`]), so a node with strength 1 lands on its path exactly.
//!
//! Contacts take the predicted positions but the explicit predictor velocity `v_n + Δt a_n`
//! (fixed during the iterations) for their dampers and friction: the friction cap ("cannot
//! reverse the sliding within one step", `m |v_t| / Δt`) fed by the iterated velocity makes the
//! fixed-point iteration oscillate instead of converging. Contacts of display-surface points
//! (bodies given a contact surface) are evaluated like the node contacts, spread onto their
//! cells' nodes by the trilinear weights, without the symplectic step's broad phase.
//!
//! After the corrector the velocity-dispersion fusion model and the deformation damping
//! towards the rigid motion act as in the symplectic step ([`super::newmark_post`]).

use super::constraints::TrajectoryConstraint;
use super::contact::{bounding_box, box_may_touch, node_contacts, CONTACT_BLOCK};
use super::diagnostics::StepStats;
use super::forces::{gathered_spring_force, spring_forces, Adjacency};
pub use super::integrator::Integrator;
use super::integrator::{FrameAccumulator, Integrate};
use super::manipulator::Capsule;
use super::substeps::SubstepChoice;
use super::{NodeState, World};
use nalgebra::Vector3;

/// Newmark state and scratch, kept between steps.
#[derive(Debug, Clone, Default)]
pub(crate) struct NewmarkState {
    /// a_n, one per node (recomputed from the forces when the node count changes).
    acceleration: Vec<Vector3<f64>>,
    next: Vec<Vector3<f64>>,
    trial: NodeState,
    spring_force: Vec<Vector3<f64>>,
    adjacency: Adjacency,
    /// (nodes, springs) the adjacency was built for.
    built_for: (usize, usize),
    capsules: Vec<Capsule>,
    /// Per node: the surface points' contact forces spread onto it.
    surface_force: Vec<Vector3<f64>>,
    /// Per node: the explicit predictor velocity v_n + Δt a_n, for the contacts.
    contact_velocity: Vec<Vector3<f64>>,
    /// The current guess of a_{n+1}.
    guess: Vec<Vector3<f64>>,
    /// Dispersion colouring and scratch.
    post: super::newmark_post::PostState,
}

/// What one Newmark step did.
pub(crate) struct NewmarkOutcome {
    pub iterations: u32,
    pub cap_hit: bool,
    pub max_depth: f64,
    /// The velocity dispersion after the corrector.
    pub dispersion: super::miyazaki1996_velocity_dispersion::DispersionStats,
}

/// Accelerations F/m at the state `trial` and time `t` into `out` (constrained nodes not yet
/// applied); returns the deepest contact penetration.
fn accelerations(world: &World, st: &mut NewmarkState, t: f64, dt: f64) -> f64 {
    let settings = &world.settings;
    st.capsules.clear();
    st.capsules
        .extend(world.manipulators.iter().map(|m| m.capsule_at(t)));
    st.capsules.extend(world.live_capsules.iter().copied());
    spring_forces(&st.trial, &world.springs, &mut st.spring_force, None, None);
    let has_contact = !settings.planes.is_empty() || !st.capsules.is_empty();
    let air = settings.wind.map(|w| (w, w.air_velocity(t)));
    let mut deepest = 0.0f64;
    let trial = &st.trial;
    let surface = &world.surface;
    let surface_contact = has_contact && !surface.is_empty();
    if surface_contact {
        st.surface_force.clear();
        st.surface_force.resize(trial.len(), Vector3::zeros());
        let layer = settings.layer;
        for i in 0..surface.len() {
            let (w, ids) = (&surface.weights[i], &surface.nodes[i]);
            let (f, d, _) = surface.contact(
                i,
                trial,
                &st.contact_velocity,
                &layer,
                &settings.planes,
                &st.capsules,
                dt,
            );
            deepest = deepest.max(d);
            if f != Vector3::zeros() {
                for c in 0..8 {
                    st.surface_force[ids[c] as usize] += f * w[c];
                }
            }
        }
    }
    // Whether the current block of nodes reaches a rigid surface (see `box_may_touch`), for
    // the nodes that take contacts themselves.
    let node_blocks = has_contact && world.node_contact.contains(&true);
    let mut near = false;
    for (i, a) in st.next.iter_mut().enumerate() {
        let (x, v, m) = (trial.position[i], trial.velocity[i], trial.mass[i]);
        if node_blocks && i % CONTACT_BLOCK == 0 {
            let block = &trial.position[i..(i + CONTACT_BLOCK).min(trial.len())];
            let (lo, hi) = bounding_box(block);
            near = box_may_touch(lo, hi, &settings.planes, &st.capsules);
        }
        let mut f =
            settings.gravity * m + gathered_spring_force(&st.adjacency, &st.spring_force, i);
        if let Some((w, air)) = air {
            f += w.force(air, v, m);
        }
        if surface_contact {
            f += st.surface_force[i];
        }
        if world.body_contact.active {
            // Body–body and collider contacts, from the step's starting state.
            f += world.body_contact.force[i];
        }
        if let Some(field) = world.field_force.get(i) {
            f += field;
        }
        if has_contact && world.node_contact[i] && !near {
            // Out of reach node_contacts gives +0; adding it keeps the bits (−0 turns +0).
            f += Vector3::zeros();
        } else if has_contact && world.node_contact[i] {
            let (cf, d, _) = node_contacts(
                &settings.layer,
                &settings.planes,
                &st.capsules,
                x,
                st.contact_velocity[i],
                m,
                dt,
            );
            f += cf;
            deepest = deepest.max(d);
        }
        *a = f * trial.inv_mass[i];
    }
    deepest
}

/// Eq 3.1: the acceleration that lands a node at `target` after `dt`.
#[inline]
fn landing_acceleration(
    target: Vector3<f64>,
    x: Vector3<f64>,
    v: Vector3<f64>,
    a: Vector3<f64>,
    beta: f64,
    dt: f64,
) -> Vector3<f64> {
    (target - x - v * dt - a * ((0.5 - beta) * dt * dt)) / (beta * dt * dt)
}

fn apply_constraints(
    constraints: &[TrajectoryConstraint],
    nodes: &NodeState,
    a_n: &[Vector3<f64>],
    next: &mut [Vector3<f64>],
    t_next: f64,
    beta: f64,
    dt: f64,
) {
    for c in constraints {
        for (j, &i) in c.nodes.iter().enumerate() {
            let want = landing_acceleration(
                c.target(j, t_next),
                nodes.position[i],
                nodes.velocity[i],
                a_n[i],
                beta,
                dt,
            );
            next[i] = if c.strength >= 1.0 {
                want
            } else {
                next[i] * (1.0 - c.strength) + want * c.strength
            };
        }
    }
}

/// One Newmark-β step of `dt` (does not advance `world.time`).
pub(crate) fn step(
    world: &mut World,
    dt: f64,
    beta: f64,
    tolerance: f64,
    max_iterations: u32,
) -> NewmarkOutcome {
    let mut st = world.newmark.take().unwrap_or_default();
    let n = world.nodes.len();
    let t = world.time;
    if st.built_for != (n, world.springs.len()) {
        st.adjacency = Adjacency::new(n, &world.springs);
        st.spring_force = vec![Vector3::zeros(); world.springs.len()];
        st.built_for = (n, world.springs.len());
    }
    st.trial.clone_from(&world.nodes);
    st.next.resize(n, Vector3::zeros());
    if st.acceleration.len() != n {
        st.contact_velocity.clone_from(&world.nodes.velocity);
        accelerations(world, &mut st, t, dt);
        st.acceleration.clone_from(&st.next);
    }
    st.contact_velocity.clear();
    st.contact_velocity.extend(
        world
            .nodes
            .velocity
            .iter()
            .zip(&st.acceleration)
            .map(|(v, a)| v + a * dt),
    );
    st.next.clone_from(&st.acceleration);
    let (h, h2) = (dt, dt * dt);
    let mut iterations = 0;
    let mut converged = false;
    let mut max_depth = 0.0;
    let mut guess = std::mem::take(&mut st.guess);
    guess.clone_from(&st.next);
    while iterations < max_iterations.max(1) {
        iterations += 1;
        // Predict at the current guess of a_{n+1}.
        for (i, g) in guess.iter().enumerate() {
            let (x, v, a) = (
                world.nodes.position[i],
                world.nodes.velocity[i],
                st.acceleration[i],
            );
            st.trial.position[i] = x + v * h + (a * (0.5 - beta) + g * beta) * h2;
            st.trial.velocity[i] = v + (a + g) * (0.5 * h);
        }
        max_depth = accelerations(world, &mut st, t + dt, dt);
        apply_constraints(
            &world.constraints,
            &world.nodes,
            &st.acceleration,
            &mut st.next,
            t + dt,
            beta,
            dt,
        );
        let (mut change, mut size) = (0.0f64, 1.0f64);
        for (a, g) in st.next.iter().zip(&guess) {
            let d = (a - g).amax();
            // NaN-safe: a NaN change never counts as converged.
            change = if d > change || d.is_nan() { d } else { change };
            size = size.max(a.amax());
        }
        std::mem::swap(&mut guess, &mut st.next);
        if change <= tolerance * size {
            converged = true;
            break;
        }
    }
    // Correct with the final a_{n+1}.
    for (i, g) in guess.iter().enumerate() {
        let (x, v, a) = (
            world.nodes.position[i],
            world.nodes.velocity[i],
            st.acceleration[i],
        );
        world.nodes.position[i] = x + v * h + (a * (0.5 - beta) + g * beta) * h2;
        world.nodes.velocity[i] = v + (a + g) * (0.5 * h);
    }
    std::mem::swap(&mut st.acceleration, &mut guess);
    st.guess = guess;
    let dispersion = super::newmark_post::after_corrector(world, &mut st.post, dt);
    world.newmark = Some(st);
    NewmarkOutcome {
        iterations,
        cap_hit: !converged,
        max_depth,
        dispersion,
    }
}

/// Terasawa's Newmark-β behind [`Integrate`]: body–body contact forces at the substep's
/// start, then the iterative step ([`step`]); substeps as the explicit integrator's.
pub(crate) struct NewmarkBeta {
    pub beta: f64,
    pub tolerance: f64,
    pub max_iterations: u32,
}

impl Integrate for NewmarkBeta {
    fn choose_substeps(&self, world: &mut World, frame_dt: f64) -> SubstepChoice {
        world.explicit_substeps(frame_dt)
    }

    fn substep(&self, world: &mut World, dt: f64, acc: &mut FrameAccumulator) -> StepStats {
        super::body_contact::step_contacts_of(world, dt, dt, None);
        let out = step(world, dt, self.beta, self.tolerance, self.max_iterations);
        world.time += dt;
        acc.max_depth = acc.max_depth.max(out.max_depth);
        acc.steps += 1;
        acc.newmark_iterations += out.iterations;
        acc.newmark_max_iterations = acc.newmark_max_iterations.max(out.iterations);
        acc.newmark_cap_hits += out.cap_hit as u32;
        acc.corrections += out.dispersion.corrections;
        acc.iterations += out.dispersion.iterations;
        acc.cap_hits += out.dispersion.hit_cap as u32;
        StepStats {
            newmark_iterations: out.iterations,
            newmark_cap_hit: out.cap_hit,
            dispersion_corrections: out.dispersion.corrections,
            dispersion_iterations: out.dispersion.iterations,
            dispersion_cap_hit: out.dispersion.hit_cap,
            ..StepStats::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrator_parameters_are_checked() {
        assert!(Integrator::SymplecticEuler.check().is_ok());
        assert!(Integrator::newmark().check().is_ok());
        let with = |beta: f64, tolerance: f64, max_iterations: u32| Integrator::Newmark {
            beta,
            tolerance,
            max_iterations,
        };
        assert!(with(1.0 / 6.0, 1e-8, 10).check().is_ok());
        assert!(with(0.0, 1e-8, 10).check().unwrap_err().contains("beta"));
        assert!(with(0.6, 1e-8, 10).check().is_err());
        assert!(with(f64::NAN, 1e-8, 10).check().is_err());
        assert!(with(0.25, 0.0, 10)
            .check()
            .unwrap_err()
            .contains("tolerance"));
        assert!(with(0.25, 1e-8, 0)
            .check()
            .unwrap_err()
            .contains("max_iterations"));
    }
}
