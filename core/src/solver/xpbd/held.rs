//! Bodies far too stiff for their lattice to bend at the substep's length, held to their
//! best-fit rigid motion (shape matching, Müller et al. 2005): twice a substep, where the other
//! bodies' cells are solved (so that the internal torque's removal, stage 3c, takes out the
//! spin a placement from the linearly predicted positions loses, `ω² Δt²/2` a substep: a steel
//! box turning once a second kept 92.7 % of its spin after 1 s without it) and again after the
//! contacts (so that every substep ends rigid).
//!
//! One constraint sweep per substep resolves a material only up to about the stiffness whose
//! elastic wave crosses a cell in a substep; past it the sweep does not converge and the body
//! bends as if it were far softer than its material. Measured on a 1 m × 0.1 m cantilever of
//! 5 cm cells (ρ = 1000) at 30 substeps a frame: E = 10 MPa sagged 3.2 × Euler–Bernoulli's
//! deflection, E = 100 MPa 30 ×, E = 10 GPa 3000 × (432 mm for 0.15 mm), hanging like rubber;
//! at 300 substeps the 100 MPa beam is within 6 %.
//!
//! A body is held when its material's wave speed `sqrt(E/ρ)` is at least [`HELD_WAVE_SPEED`]
//! (wood, steel, glass, hard plastics: an impact at 10 m/s strains it 1 % at most) and its
//! quasi-static sag under gravity is at most [`HIDDEN_SAG`] of its length, estimated as
//! `g / ω₁²` with ω₁ its first bending frequency as a cantilever, `3.52 r c / L²` (`r` the
//! radius of gyration across its thinnest side, `L` its longest side). A 10 m × 30 cm wooden
//! beam as a cantilever sags 0.6 %: held rigid it is off by that, where its elastic cells would
//! sag metres. A held body's cells are not solved; every free node is placed at
//! `c + R (r_i − c₀)`, `R` the rotation of the polar decomposition of
//! `Σ w (x_i − c)(r_i − c₀)ᵀ`, `c` and `c₀` the weighted centres now and at rest. The weights
//! are the node masses, so linear and angular momentum are kept (the optimal rotation makes
//! `Σ m (x − c) × (g − c)` vanish); a pinned or path-bound node weighs [`PINNED_WEIGHT`] times
//! the body, so a body pinned at one end stays put and one pinned on an axis turns about it.
//! Bodies in joints are left elastic (their shared nodes are another body's too).
//! `World::hold_stiff_bodies` (`[solver] stiff_bodies = "elastic"`) turns this off.
//!
//! Bodies stiffer than the substeps resolve but not held (wave speeds of about 40–1000 m/s:
//! hard rubber, stiff plastics; or rubber on a fine lattice) still bend softer than their
//! material; [`World::under_resolved_bodies`] names them so the CLI can say so.

use super::V3;
use crate::collide::geometry::polar_rotation;
use crate::solver::World;
use nalgebra::Matrix3;
use std::ops::Range;

/// Wave speed `sqrt(E/ρ)` from which a body may be held rigid, m/s.
pub(crate) const HELD_WAVE_SPEED: f64 = 1000.0;
/// Largest quasi-static sag under gravity, as a share of the body's longest side, that a held
/// body may hide.
pub(crate) const HIDDEN_SAG: f64 = 0.01;
/// Weight of a node held in place against the body's mass.
const PINNED_WEIGHT: f64 = 1e6;

/// One held body.
#[derive(Debug, Clone)]
struct HeldBody {
    nodes: Range<usize>,
    mass: f64,
}

/// The held bodies of a world (module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct Held {
    bodies: Vec<HeldBody>,
    /// Largest wave speed `sqrt(E/ρ)` of a held body's material, m/s (0 without): the
    /// substeps keep the count it asks for, as for elastic cells. Their contacts need it: at
    /// 10 substeps a frame instead of its 30 a 2 m steel ball's first impact reached 11 mm
    /// into the floor before the contact pass moved it out (2.7 mm at 30).
    pub(crate) wave_speed: f64,
    /// Per node of a held body: weight, scratch.
    weights: Vec<f64>,
}

impl Held {
    /// The bodies of `world` to hold (module docs).
    pub(crate) fn build(world: &World) -> Held {
        if !world.hold_stiff_bodies {
            return Held::default();
        }
        let mut wave_speed = 0.0f64;
        let bodies = (0..world.bodies.len())
            .filter_map(|b| {
                let speed = held_wave_speed(world, b)?;
                wave_speed = wave_speed.max(speed);
                let nodes = world.bodies[b].nodes.clone();
                let mass = world.nodes.mass[nodes.clone()].iter().sum();
                Some(HeldBody { nodes, mass })
            })
            .collect();
        Held {
            bodies,
            wave_speed,
            weights: Vec::new(),
        }
    }

    /// The held bodies' nodes.
    pub(crate) fn node_ranges(&self) -> impl Iterator<Item = Range<usize>> + '_ {
        self.bodies.iter().map(|b| b.nodes.clone())
    }

    /// Whether body `b` is held.
    pub(crate) fn holds(&self, world: &World, b: usize) -> bool {
        let range = &world.bodies[b].nodes;
        self.bodies.iter().any(|h| h.nodes == *range)
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// Place each held body's free nodes at its best-fit rigid motion (module docs);
    /// `inv_mass` the substep's (0: pinned or on a path).
    pub(crate) fn hold(
        &mut self,
        position: &mut [V3],
        rest: &[V3],
        mass: &[f64],
        inv_mass: &[f64],
    ) {
        for body in &self.bodies {
            let range = body.nodes.clone();
            self.weights.clear();
            // A massless node (none in a lattice; kept safe) weighs nothing and follows.
            self.weights.extend(range.clone().map(|i| {
                if inv_mass[i] > 0.0 {
                    mass[i]
                } else if mass[i] > 0.0 {
                    PINNED_WEIGHT * body.mass
                } else {
                    0.0
                }
            }));
            let total: f64 = self.weights.iter().sum();
            if total.is_nan() || total <= 0.0 {
                continue;
            }
            let (mut c, mut c0) = (V3::zeros(), V3::zeros());
            for (w, i) in self.weights.iter().zip(range.clone()) {
                c += position[i] * *w;
                c0 += rest[i] * *w;
            }
            c /= total;
            c0 /= total;
            let mut a = Matrix3::zeros();
            for (w, i) in self.weights.iter().zip(range.clone()) {
                a += (position[i] - c) * ((rest[i] - c0) * *w).transpose();
            }
            // Non-finite positions are left for the frame's check to report.
            let Some(rotation) = polar_rotation(&a) else {
                continue;
            };
            for i in range {
                if inv_mass[i] > 0.0 || mass[i] <= 0.0 {
                    position[i] = c + rotation * (rest[i] - c0);
                }
            }
        }
    }
}

/// Whether body `b` of `world` is one to hold (module docs): its wave speed if so.
fn held_wave_speed(world: &World, b: usize) -> Option<f64> {
    let body = &world.bodies[b];
    let material = body.material.as_ref()?;
    let range = body.nodes.clone();
    let joined =
        (world.joints.iter()).any(|j| range.contains(&j.kept) || range.contains(&j.follower));
    if body.cells.is_empty()
        || range.is_empty()
        || joined
        || world.rigid.iter().any(|r| r.body == b)
    {
        return None;
    }
    let softest = region_scales(body).fold(1.0f64, f64::min)
        * body.axis_stiffness.iter().copied().fold(1.0f64, f64::min);
    let speed = (material.young_pa * softest / material.density_kg_m3).sqrt();
    if speed.is_nan() || speed < HELD_WAVE_SPEED {
        return None;
    }
    let (length, thickness) = extents(world, range);
    let gyration = thickness / 12f64.sqrt();
    let first_bending = 3.52 * gyration * speed / (length * length);
    let sag = world.settings.gravity.norm() / (first_bending * first_bending);
    (length > 0.0 && sag <= HIDDEN_SAG * length).then_some(speed)
}

/// Per cell of `body`, its stiffness factor without the share of the cell its mesh fills
/// (which scales the cell's mass too, leaving its wave speed as it is): the regions' factors.
fn region_scales(body: &crate::solver::BodyInfo) -> impl Iterator<Item = f64> + '_ {
    let fill = |c: usize| body.cell_fill.get(c).copied().filter(|&f| f > 0.0);
    (body.cell_stiffness.iter().enumerate()).map(move |(c, &s)| fill(c).map_or(s, |f| s / f))
}

/// The longest and the thinnest side of the rest box of the nodes `range`, m.
fn extents(world: &World, range: Range<usize>) -> (f64, f64) {
    let (mut lo, mut hi) = (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY));
    for i in range {
        lo = lo.inf(&world.rest[i]);
        hi = hi.sup(&world.rest[i]);
    }
    ((hi - lo).max(), (hi - lo).min())
}

/// How many times the stiffness cap's substeps a body's material must ask for before
/// [`World::under_resolved_bodies`] names it. Measured on an E = 10 MPa cantilever: asking 4 ×
/// the cap it bent 2.5 × as far as at 300 substeps, 8 × 4.9 ×, 17 × 5.6 ×; an E = 100 MPa one
/// asking 26 × bent 30 ×.
pub const UNDER_RESOLVED_FACTOR: f64 = 4.0;
/// Longest over thinnest side from which a body counts as slender, where that softening shows
/// (the beams above are 10; a compact body's squash is mostly compression, which the sweep
/// resolves within about 10 % at a substep a wave crossing: the column check).
pub const SLENDER: f64 = 4.0;

impl World {
    /// The XPBD bodies whose material is stiffer than the automatic substeps resolve at their
    /// cell size, with the substeps a frame of `frame_dt` seconds would need (three per
    /// elastic wave crossing of a cell): at least [`UNDER_RESOLVED_FACTOR`] times the
    /// stiffness cap, for a body at least [`SLENDER`]. Such a body bends far softer than its
    /// material. Held bodies, rigid and particle kinds, and worlds at fixed substeps are not
    /// named.
    pub fn under_resolved_bodies(&self, frame_dt: f64) -> Vec<(String, u32)> {
        use super::{MAX_STIFFNESS_SUBSTEP_RATE, SUBSTEPS_PER_WAVE_CROSSING};
        if self.settings.integrator != crate::solver::Integrator::Xpbd
            || self.settings.fixed_substeps.is_some()
        {
            return Vec::new();
        }
        let cap = (MAX_STIFFNESS_SUBSTEP_RATE * frame_dt).ceil();
        (0..self.bodies.len())
            .filter_map(|b| {
                let body = &self.bodies[b];
                let material = body.material.as_ref()?;
                let rigid = self.rigid.iter().any(|r| r.body == b);
                let held = self.hold_stiff_bodies && held_wave_speed(self, b).is_some();
                let (length, thickness) = extents(self, body.nodes.clone());
                if rigid || held || length.is_nan() || length < SLENDER * thickness {
                    return None;
                }
                let cell = (body.cells.iter())
                    .map(|c| (self.rest[c[1] as usize] - self.rest[c[0] as usize]).norm())
                    .filter(|&h| h > 0.0)
                    .fold(f64::INFINITY, f64::min);
                let stiffest = region_scales(body).fold(1.0f64, f64::max)
                    * body.axis_stiffness.iter().copied().fold(1.0f64, f64::max);
                let speed = (material.young_pa * stiffest / material.density_kg_m3).sqrt();
                let asked = (SUBSTEPS_PER_WAVE_CROSSING * frame_dt * speed / cell).ceil();
                (asked.is_finite() && asked >= UNDER_RESOLVED_FACTOR * cap)
                    .then(|| (body.name.clone(), asked.min(u32::MAX as f64) as u32))
            })
            .collect()
    }
}
