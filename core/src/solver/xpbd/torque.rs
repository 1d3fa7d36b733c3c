//! Stage 3c of the substep: internal forces exert no torque. Each projection of a
//! rotation-invariant constraint keeps angular momentum about the positions it was evaluated
//! at, but the sweep evaluates them at the moving intermediate positions, which leaks spin at
//! a rate of about `ω² Δt` (6 % per second for a body turning once a second at 720
//! substeps/s). Per body, the angular impulse of the elastic corrections about the substep's
//! start, `ΔL = Σ m (x_n − c) × (x − x̃)`, is removed by a rotation `δθ = I⁻¹ ΔL` of the
//! corrections (bodies with pinned or path-bound nodes are left alone: their constraint
//! forces are external). Their net impulse `ΔP = Σ m (x − x̃)`, zero but for rounding (the
//! cells' lanes solve in single precision: a cube thrown at 2 m/s gained 1e-6 m/s in six
//! frames), is removed the same way, by shifting the corrections by `ΔP / M`, except for a
//! body joined to another (a joint's shared node carries the other body's pull as a
//! correction: removed, a bar would no longer drag the bar linked to it).
//!
//! The sums run over fixed chunks of a body's nodes on the [`team`] and add up in chunk
//! order, so any thread count gives the same bits.

use super::{Model, V3};
use crate::solver::deformation_damping::SecondMoment;
use crate::solver::team::{self, Chunks};
use crate::solver::{World, PAR_CHUNK};
use std::ops::Range;

/// Per-chunk partial sums, kept between substeps so the step allocates nothing.
#[derive(Debug, Clone, Default)]
pub(super) struct TorqueScratch {
    /// Mass, mass-weighted start positions, and whether the chunk holds a node held in place.
    first: Vec<(f64, V3, bool)>,
    /// Angular impulse of the corrections and second moments, about the body's centre, and
    /// the corrections' impulse.
    second: Vec<(V3, SecondMoment, V3)>,
}

/// Remove each body's net angular impulse of the elastic corrections (see the module).
pub(super) fn cancel_internal_torque(world: &mut World, model: &mut Model) {
    let Model {
        torque_scratch: scratch,
        inv_mass,
        previous,
        predicted,
        ..
    } = model;
    let start = Start {
        inv_mass,
        previous,
        predicted,
    };
    for body in &world.bodies {
        let range = body.nodes.clone();
        if range.is_empty() {
            continue;
        }
        let Some((centre, turn, shift)) = body_turn(world, &start, range.clone(), scratch) else {
            continue;
        };
        let joined =
            (world.joints.iter()).any(|j| range.contains(&j.kept) || range.contains(&j.follower));
        let shift = if joined { V3::zeros() } else { shift };
        let (mass, previous) = (&world.nodes.mass[range.clone()], &previous[range.clone()]);
        team::for_each(
            Chunks::new(&mut world.nodes.position[range], PAR_CHUNK),
            |c, xs: &mut [V3]| {
                let from = c * PAR_CHUNK;
                for (j, x) in xs.iter_mut().enumerate() {
                    if mass[from + j] > 0.0 {
                        *x -= turn.cross(&(previous[from + j] - centre)) + shift;
                    }
                }
            },
        );
    }
}

/// What [`body_turn`] reads of the model: the substep's inverse masses, the positions at
/// its start, and the positions predicted before the elastic solve.
struct Start<'a> {
    inv_mass: &'a [f64],
    previous: &'a [V3],
    predicted: &'a [V3],
}

/// The body's centre of mass at the substep's start, the rotation `I⁻¹ ΔL` that cancels its
/// corrections' angular impulse and the shift `ΔP / M` that cancels their impulse; `None`
/// for a body with a node held in place, without mass, or whose inertia has no inverse.
fn body_turn(
    world: &World,
    model: &Start,
    range: Range<usize>,
    scratch: &mut TorqueScratch,
) -> Option<(V3, V3, V3)> {
    let nodes = &world.nodes;
    let (mass, moment, held) = team::chunked_sum(
        range.clone(),
        PAR_CHUNK,
        (0.0, V3::zeros(), false),
        &mut scratch.first,
        |(mass, moment, held), i| {
            *held |= model.inv_mass[i] <= 0.0 && nodes.mass[i] > 0.0;
            *mass += nodes.mass[i];
            *moment += model.previous[i] * nodes.mass[i];
        },
        |a, b| (a.0 + b.0, a.1 + b.1, a.2 | b.2),
    );
    if held || mass <= 0.0 {
        return None;
    }
    let centre = moment / mass;
    let (torque, moments, impulse) = team::chunked_sum(
        range,
        PAR_CHUNK,
        (V3::zeros(), SecondMoment::default(), V3::zeros()),
        &mut scratch.second,
        |(torque, moments, impulse), i| {
            let r = model.previous[i] - centre;
            let m = nodes.mass[i];
            let correction = nodes.position[i] - model.predicted[i];
            *torque += r.cross(&correction) * m;
            moments.add(&r, m);
            *impulse += correction * m;
        },
        |a, b| (a.0 + b.0, a.1.plus(b.1), a.2 + b.2),
    );
    let turn = moments.inertia().try_inverse()? * torque;
    Some((centre, turn, impulse / mass))
}
