//! Restitution of bodies too stiff for a substep to resolve their impact (wood, steel).
//!
//! One constraint sweep per substep stops a body inelastically when its elastic wave crosses
//! the whole body faster than a substep: the contact halts the touching nodes and the stiff
//! cells pass that halt to every node within the substep, so the energy an elastic body would
//! store in the impact and give back is never stored. Such a body bounces here as a damped
//! elastic contact would make it: at the first substep a body touches a plane (floor, walls),
//! an impulse on its rigid motion at the contact brings the normal velocity there to
//! `e` times the approach velocity, with `e = exp(−πζ/√(1−ζ²))` from the material's damping
//! ratio ζ (the restitution of a damped oscillator's half period). It applies fully when the
//! wave crosses the body in at most one substep and fades out by three crossings per substep,
//! where the cells resolve the impact and bounce the body by themselves (rubber, jelly, foam).
//! Resting contact (approach slower than gravity's two substeps) gets none.

use super::super::World;
use nalgebra::{Matrix3, Vector3};
use std::ops::Range;

type V3 = Vector3<f64>;

/// Wave crossings per substep at which the restitution starts to fade, and where it is gone.
const FULL_BELOW_CROSSINGS: f64 = 1.0;
const NONE_ABOVE_CROSSINGS: f64 = 3.0;

/// A body's rigid motion: centre of mass, velocity, angular velocity, and the inverse inertia
/// about the centre.
#[derive(Debug, Clone, Copy, Default)]
struct RigidMotion {
    com: V3,
    velocity: V3,
    spin: V3,
    inv_inertia: Matrix3<f64>,
    mass: f64,
}

impl RigidMotion {
    fn of(x: &[V3], v: &[V3], m: &[f64], nodes: Range<usize>) -> RigidMotion {
        let (mut mass, mut com, mut momentum) = (0.0, V3::zeros(), V3::zeros());
        for i in nodes.clone() {
            mass += m[i];
            com += x[i] * m[i];
            momentum += v[i] * m[i];
        }
        if mass <= 0.0 {
            return RigidMotion::default();
        }
        com /= mass;
        let velocity = momentum / mass;
        let (mut angular, mut inertia) = (V3::zeros(), Matrix3::zeros());
        for i in nodes {
            let r = x[i] - com;
            angular += r.cross(&(v[i] - velocity)) * m[i];
            inertia += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * m[i];
        }
        let inv_inertia = inertia.try_inverse().unwrap_or_else(Matrix3::zeros);
        RigidMotion {
            com,
            velocity,
            spin: inv_inertia * angular,
            inv_inertia,
            mass,
        }
    }

    /// Velocity of the body's rigid motion at `p`.
    fn at(&self, p: &V3) -> V3 {
        self.velocity + self.spin.cross(&(p - self.com))
    }
}

/// A body that may need restitution.
#[derive(Debug, Clone)]
struct StiffBody {
    body: usize,
    /// Time its elastic wave takes across the body's largest extent, s.
    crossing: f64,
    /// Restitution of its material.
    e: f64,
    /// Its display-surface contact points (indices into `World::surface`).
    surface: Vec<u32>,
    /// Per plane: touched at the end of the last substep.
    touching: Vec<bool>,
    /// Rigid motion at the start of the current substep.
    before: RigidMotion,
}

/// The stiff bodies' impact state (module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct Restitution {
    bodies: Vec<StiffBody>,
}

impl Restitution {
    /// Every free body with a material whose wave crossing could fit in a substep: lattice or
    /// cage bodies, not rigid or particle kinds, no pinned node.
    pub(crate) fn build(world: &World) -> Restitution {
        let planes = world.settings.planes.len();
        let bodies = world
            .bodies
            .iter()
            .enumerate()
            .filter(|(b, body)| {
                !world.rigid.iter().any(|r| r.body == *b)
                    && !body.nodes.is_empty()
                    && body.nodes.clone().all(|i| world.nodes.inv_mass[i] > 0.0)
            })
            .filter_map(|(b, body)| {
                let material = body.material.as_ref()?;
                let zeta = material.damping_ratio.min(0.999);
                let e = (-std::f64::consts::PI * zeta / (1.0 - zeta * zeta).sqrt()).exp();
                let (mut lo, mut hi) = (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY));
                for i in body.nodes.clone() {
                    lo = lo.inf(&world.rest[i]);
                    hi = hi.sup(&world.rest[i]);
                }
                let speed = (material.young_pa / material.density_kg_m3).sqrt();
                let surface = (0..world.surface.len() as u32)
                    .filter(|&k| world.surface.body[k as usize] as usize == b)
                    .collect();
                Some(StiffBody {
                    body: b,
                    crossing: (hi - lo).max() / speed,
                    e,
                    surface,
                    touching: vec![false; planes],
                    before: RigidMotion::default(),
                })
            })
            .collect();
        Restitution { bodies }
    }

    /// The share of the restitution a body gets at substep `dt`.
    fn weight(body: &StiffBody, dt: f64) -> f64 {
        let crossings = body.crossing / dt;
        ((NONE_ABOVE_CROSSINGS - crossings) / (NONE_ABOVE_CROSSINGS - FULL_BELOW_CROSSINGS))
            .clamp(0.0, 1.0)
    }

    /// Records the stiff bodies' rigid motion at the substep's start.
    pub(crate) fn before(&mut self, world: &World, dt: f64) {
        let n = &world.nodes;
        for s in &mut self.bodies {
            if Self::weight(s, dt) > 0.0 {
                let nodes = world.bodies[s.body].nodes.clone();
                s.before = RigidMotion::of(&n.position, &n.velocity, &n.mass, nodes);
            }
        }
    }

    /// After the velocity update: the impulse of each new impact on a plane (module docs).
    /// `tolerance` is how close to a plane, m, a point counts as touching it.
    pub(crate) fn after(&mut self, world: &mut World, dt: f64, tolerance: f64) {
        let resting = 2.0 * world.settings.gravity.norm() * dt;
        for s in &mut self.bodies {
            let weight = Self::weight(s, dt);
            if weight <= 0.0 {
                // Resolved by the cells (and any contact it is in counts as old).
                s.touching.fill(true);
                continue;
            }
            let nodes = world.bodies[s.body].nodes.clone();
            for (p, plane) in world.settings.planes.iter().enumerate() {
                // The contact: the body's nodes and display-surface points on the plane.
                let (mut sum, mut count) = (V3::zeros(), 0usize);
                let x = &world.nodes.position;
                for i in nodes.clone() {
                    if plane.normal.dot(&x[i]) - plane.offset <= tolerance {
                        sum += x[i];
                        count += 1;
                    }
                }
                let sp = &world.surface;
                for &k in &s.surface {
                    let (ids, weights) = (&sp.nodes[k as usize], &sp.weights[k as usize]);
                    let point: V3 = (0..8).map(|c| x[ids[c] as usize] * weights[c]).sum();
                    if plane.normal.dot(&point) - plane.offset <= tolerance {
                        sum += point;
                        count += 1;
                    }
                }
                let touching = count > 0;
                let new_impact = touching && !s.touching[p];
                s.touching[p] = touching;
                if !new_impact {
                    continue;
                }
                let contact = sum / count as f64;
                let n = plane.normal;
                let approach = s.before.at(&contact).dot(&n);
                if approach > -resting {
                    continue;
                }
                let nodes_now = &world.nodes;
                let after = RigidMotion::of(
                    &nodes_now.position,
                    &nodes_now.velocity,
                    &nodes_now.mass,
                    nodes.clone(),
                );
                let target = -s.e * weight * approach;
                let r = contact - after.com;
                let now = after.at(&contact).dot(&n);
                if now >= target || after.mass <= 0.0 {
                    continue;
                }
                let arm = r.cross(&n);
                let k = 1.0 / after.mass + arm.dot(&(after.inv_inertia * arm));
                let j = (target - now) / k;
                let dv = n * (j / after.mass);
                let dw = after.inv_inertia * arm * j;
                let nodes_mut = &mut world.nodes;
                for i in nodes.clone() {
                    let ri = nodes_mut.position[i] - after.com;
                    nodes_mut.velocity[i] += dv + dw.cross(&ri);
                }
            }
        }
    }
}
