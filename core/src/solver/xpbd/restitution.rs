//! Restitution of bodies too stiff for a substep to resolve their impact (wood, steel).
//!
//! One constraint sweep per substep stops a body inelastically when its elastic wave crosses
//! the whole body faster than a substep: the contact halts the touching nodes and the stiff
//! cells pass that halt to every node within the substep, so the energy an elastic body would
//! store in the impact and give back is never stored. Such a body bounces here as a damped
//! elastic contact would make it: at the first substep a body touches a plane (floor, walls) or
//! a static collider, an impulse on its rigid motion at the contact brings the normal velocity there to
//! `e` times the approach velocity, with `e = exp(−πζ/√(1−ζ²))` from the material's damping
//! ratio ζ (the restitution of a damped oscillator's half period). It applies fully when the
//! wave crosses the body in at most one substep and fades out by three crossings per substep,
//! where the cells resolve the impact and bounce the body by themselves (rubber, jelly, foam).
//! Resting contact (approach slower than gravity's two substeps) gets none.

use super::super::deformation_damping::{rigid_motion_in, RigidMotion, RigidScratch};
use super::super::World;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// Wave crossings per substep at which the restitution starts to fade, and where it is gone.
const FULL_BELOW_CROSSINGS: f64 = 1.0;
const NONE_ABOVE_CROSSINGS: f64 = 3.0;

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
    /// Per plane, then per static collider: touched at the end of the last substep.
    touching: Vec<bool>,
    /// Rigid motion at the start of the current substep.
    before: Option<RigidMotion>,
}

/// The stiff bodies' impact state (module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct Restitution {
    bodies: Vec<StiffBody>,
    scratch: RigidScratch,
}

impl Restitution {
    /// Every free body with a material whose wave crossing could fit in a substep: lattice or
    /// cage bodies, not rigid or particle kinds, no pinned node.
    pub(crate) fn build(world: &World) -> Restitution {
        let planes = world.settings.planes.len() + world.body_contact.colliders.len();
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
                    before: None,
                })
            })
            .collect();
        Restitution {
            bodies,
            scratch: RigidScratch::default(),
        }
    }

    /// The share of the restitution a body gets at substep `dt`.
    fn weight(body: &StiffBody, dt: f64) -> f64 {
        let crossings = body.crossing / dt;
        ((NONE_ABOVE_CROSSINGS - crossings) / (NONE_ABOVE_CROSSINGS - FULL_BELOW_CROSSINGS))
            .clamp(0.0, 1.0)
    }

    /// Records the stiff bodies' rigid motion at the substep's start.
    pub(crate) fn before(&mut self, world: &World, dt: f64) {
        for s in &mut self.bodies {
            s.before = (Self::weight(s, dt) > 0.0).then(|| {
                let nodes = world.bodies[s.body].nodes.clone();
                rigid_motion_in(&world.nodes, nodes, &mut self.scratch)
            });
        }
    }

    /// After the velocity update: the impulse of each new impact on a plane or a collider
    /// (module docs). `tolerance` is how close to a plane, m, a point counts as touching it;
    /// `collider_touch` gives, per display-surface point, the collider and face normal the
    /// contact constraints put it back onto in this substep.
    pub(crate) fn after(
        &mut self,
        world: &mut World,
        dt: f64,
        tolerance: f64,
        collider_touch: &[Option<(u32, V3)>],
    ) {
        let resting = 2.0 * world.settings.gravity.norm() * dt;
        let planes = world.settings.planes.len();
        for s in &mut self.bodies {
            let weight = Self::weight(s, dt);
            if weight <= 0.0 {
                // Resolved by the cells (and any contact it is in counts as old).
                s.touching.fill(true);
                continue;
            }
            let nodes = world.bodies[s.body].nodes.clone();
            for slot in 0..s.touching.len() {
                // The contact: the body's nodes and display-surface points on the surface, and
                // its normal.
                let (mut sum, mut count, mut normal) = (V3::zeros(), 0usize, V3::zeros());
                let x = &world.nodes.position;
                let sp = &world.surface;
                let point = |k: u32| -> V3 {
                    let (ids, weights) = (&sp.nodes[k as usize], &sp.weights[k as usize]);
                    (0..8).map(|c| x[ids[c] as usize] * weights[c]).sum()
                };
                if let Some(plane) = world.settings.planes.get(slot) {
                    normal = plane.normal;
                    for i in nodes.clone() {
                        if plane.normal.dot(&x[i]) - plane.offset <= tolerance {
                            sum += x[i];
                            count += 1;
                        }
                    }
                    for &k in &s.surface {
                        let p = point(k);
                        if plane.normal.dot(&p) - plane.offset <= tolerance {
                            sum += p;
                            count += 1;
                        }
                    }
                } else {
                    let collider = (slot - planes) as u32;
                    for &k in &s.surface {
                        if let Some(Some((c, n))) = collider_touch.get(k as usize) {
                            if *c == collider {
                                sum += point(k);
                                normal += n;
                                count += 1;
                            }
                        }
                    }
                }
                let touching = count > 0 && normal.norm() > 0.0;
                let new_impact = touching && !s.touching[slot];
                s.touching[slot] = touching;
                if !new_impact {
                    continue;
                }
                let Some(before) = &s.before else {
                    continue;
                };
                let contact = sum / count as f64;
                let n = normal.normalize();
                let approach = before.velocity_at(&contact).dot(&n);
                if approach > -resting {
                    continue;
                }
                let after = rigid_motion_in(&world.nodes, nodes.clone(), &mut self.scratch);
                let target = -s.e * weight * approach;
                let r = contact - after.centre;
                let now = after.velocity_at(&contact).dot(&n);
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
                    let ri = nodes_mut.position[i] - after.centre;
                    nodes_mut.velocity[i] += dv + dw.cross(&ri);
                }
            }
        }
    }
}
