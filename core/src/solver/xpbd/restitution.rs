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

use super::super::contact::Plane;
use super::super::deformation_damping::{rigid_motion_in, RigidMotion, RigidScratch};
use super::super::World;
use super::contact::{alternating, friction};
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
    /// That wave's speed, m/s (`crossing × wave_speed` is the body's largest extent).
    wave_speed: f64,
    /// The body's smallest extent at rest, m.
    thickness: f64,
    /// Restitution of its material.
    e: f64,
    /// Its display-surface contact points (indices into `World::surface`).
    surface: Vec<u32>,
    /// Every surface point is a convex combination of its cell's nodes (trilinear weights in
    /// `[0, 1]`): then a point is no nearer a plane than the nearest of the body's nodes, and
    /// the nodes alone tell whether the body touches a plane.
    convex: bool,
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
    /// A resting body's points near a plane, with their heights above it, and their
    /// accumulated impulses (scratch).
    points: Vec<(V3, f64)>,
    impulses: Vec<f64>,
    /// A new impact's contact points and their normals (scratch).
    contacts: Vec<(V3, V3)>,
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
                let surface: Vec<u32> = (0..world.surface.len() as u32)
                    .filter(|&k| world.surface.body[k as usize] as usize == b)
                    .collect();
                let convex = surface.iter().all(|&k| {
                    world.surface.weights[k as usize]
                        .iter()
                        .all(|w| (-1e-6..=1.0 + 1e-6).contains(w))
                });
                Some(StiffBody {
                    body: b,
                    crossing: (hi - lo).max() / speed,
                    wave_speed: speed,
                    thickness: (hi - lo).min(),
                    e,
                    surface,
                    convex,
                    touching: vec![false; planes],
                    before: None,
                })
            })
            .collect();
        Restitution {
            bodies,
            scratch: RigidScratch::default(),
            points: Vec::new(),
            impulses: Vec::new(),
            contacts: Vec::new(),
        }
    }

    /// Whether any body gets some restitution at substeps of `dt` seconds (or shorter ones
    /// never do more).
    pub(crate) fn acts_at(&self, dt: f64) -> bool {
        self.bodies.iter().any(|b| Self::weight(b, dt) > 0.0)
    }

    /// The bodies that get some restitution at substeps of `dt` seconds: body, share (at 1
    /// the wave crosses it within a substep and an impact on a plane or a static collider
    /// moves it as a whole) and its rest thickness (smallest extent), m.
    pub(crate) fn shares_at(&self, dt: f64) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.bodies
            .iter()
            .map(move |b| (b.body, Self::weight(b, dt), b.thickness))
            .filter(|&(_, share, _)| share > 0.0)
    }

    /// The share of the restitution a body gets at substep `dt`.
    fn weight(body: &StiffBody, dt: f64) -> f64 {
        let crossings = body.crossing / dt;
        ((NONE_ABOVE_CROSSINGS - crossings) / (NONE_ABOVE_CROSSINGS - FULL_BELOW_CROSSINGS))
            .clamp(0.0, 1.0)
    }

    /// At the substep's start, for the stiff bodies: records the rigid motion of those that
    /// may make a new contact in it (with a static collider they are not yet touching, or
    /// within `margin` plus twice a node's travel in the substep of a plane they are not yet
    /// touching: a body already on a plane cannot newly hit it within the substep, one farther
    /// away would have to cross more than `margin`, a cell edge, beyond its own motion), and
    /// supports those resting on a plane (`support`).
    pub(crate) fn before(&mut self, world: &mut World, dt: f64, margin: f64, tolerance: f64) {
        let planes = world.settings.planes.len();
        let Restitution {
            bodies,
            scratch,
            points,
            impulses,
            ..
        } = self;
        for s in bodies.iter_mut() {
            s.before = None;
            let weight = Self::weight(s, dt);
            if weight <= 0.0 {
                continue;
            }
            let nodes = world.bodies[s.body].nodes.clone();
            let (x, v) = (&world.nodes.position, &world.nodes.velocity);
            let near_collider = s.touching[planes..].iter().any(|t| !t);
            let near_plane = || {
                world
                    .settings
                    .planes
                    .iter()
                    .enumerate()
                    .any(|(slot, plane)| {
                        !s.touching[slot]
                            && nodes.clone().any(|i| {
                                plane.normal.dot(&x[i]) - plane.offset
                                    <= margin + 2.0 * v[i].norm() * dt
                            })
                    })
            };
            let resting = s.touching[..planes].iter().any(|&t| t);
            if near_collider || near_plane() || resting {
                s.before = Some(rigid_motion_in(&world.nodes, nodes.clone(), scratch));
            }
            if resting {
                support(world, s, weight, dt, tolerance, (points, impulses));
            }
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
                    // The nodes decide touching for a convex embedding; the surface points
                    // only refine where a new impact is.
                    let settled = count > 0 && s.touching[slot];
                    let skip_points = s.convex && (count == 0 || settled);
                    for &k in s.surface.iter().filter(|_| !skip_points) {
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
                let contacts = &mut self.contacts;
                contacts.clear();
                match world.settings.planes.get(slot) {
                    // On a plane, the impact is where the mesh meets it this substep: every
                    // point within a substep's approach of it (the contact pass leaves a flat
                    // face's points a little uneven, and the few within `tolerance` alone
                    // would take the whole impulse off the face's centre and spin a box or a
                    // cone that landed flat).
                    Some(plane) => {
                        let points = &mut self.points;
                        let first = mesh_on_plane(world, s, plane, tolerance, points)
                            .unwrap_or(sum / count as f64);
                        let closing = (-before.velocity_at(&first).dot(&plane.normal)).max(0.0);
                        if mesh_on_plane(world, s, plane, tolerance + closing * dt, points)
                            .is_none()
                        {
                            points.push((first, 0.0));
                        }
                        contacts.extend(points.iter().map(|&(p, _)| (p, plane.normal)));
                    }
                    None => {
                        let collider = (slot - planes) as u32;
                        for &k in &s.surface {
                            if let Some(Some((c, n))) = collider_touch.get(k as usize) {
                                if *c == collider && n.norm() > 0.0 {
                                    contacts.push((point(k), n.normalize()));
                                }
                            }
                        }
                    }
                }
                if contacts.is_empty() {
                    continue;
                }
                let n = normal.normalize();
                let centre = contacts.iter().map(|(p, _)| p).sum::<V3>() / contacts.len() as f64;
                if before.velocity_at(&centre).dot(&n) > -resting {
                    continue;
                }
                let after = rigid_motion_in(&world.nodes, nodes.clone(), &mut self.scratch);
                let friction = match world.settings.planes.get(slot) {
                    Some(_) => world.settings.layer.friction,
                    None => world.body_contact.colliders[slot - planes].friction,
                };
                let impact = Impact {
                    contacts,
                    e: s.e * weight,
                    friction,
                };
                bounce(world, nodes.clone(), before, after, impact);
            }
        }
    }
}

/// The impulses of an impact at several contact points at once (a face, a rim, an edge, a
/// cap): non-negative impulses on the body's rigid motion `after` (its motion once the contact
/// projection has stopped the points that reached the surface) that bring each point's normal
/// velocity up to `e` times the speed it approached at (`before`). The first guess shares the
/// impulse at the points' centre equally among them (exact for a body landing flat or on a
/// symmetric cap); sequential impulses over the points, accumulated and never pulling, then
/// move it where the points differ. One impulse at the centre alone let the points farther
/// down keep approaching: a 2 cm cone landing 1.5° off flat left spinning at 19 rad/s and
/// tipped over. Sequential impulses alone converge slowly over a small cap of many points: a
/// steel ellipsoid dropped straight left its first bounce turning at 1.9 rad/s.
fn bounce(
    world: &mut World,
    range: std::ops::Range<usize>,
    before: &RigidMotion,
    after: RigidMotion,
    Impact {
        contacts,
        e,
        friction,
    }: Impact,
) {
    /// Passes over the contact points.
    const PASSES: usize = 16;
    if after.mass <= 0.0 {
        return;
    }
    let mut rigid = after;
    let target = |p: &V3, n: &V3| -e * before.velocity_at(p).dot(n).min(0.0);
    // The first guess: the impulse at the points' centre that brings their mean normal
    // velocity there up to their mean target, shared equally among them (exact for a body
    // landing flat or on a symmetric cap, where the passes then have nothing left to do).
    let count = contacts.len() as f64;
    let centre = contacts.iter().map(|(p, _)| p).sum::<V3>() / count;
    let normal = contacts.iter().map(|(_, n)| n).sum::<V3>();
    let share = if normal.norm() > 0.0 {
        let normal = normal.normalize();
        let mean_target = contacts.iter().map(|(p, n)| target(p, n)).sum::<f64>() / count;
        let now = rigid.velocity_at(&centre).dot(&normal);
        ((mean_target - now) / inverse_mass_along(&rigid, centre, normal)).max(0.0) / count
    } else {
        0.0
    };
    for (p, n) in contacts {
        nudge(&mut rigid, *p, n * share);
    }
    let mut impulses = vec![share; contacts.len()];
    let goals = SequentialImpulses {
        passes: PASSES,
        alternate: true,
        weight: 1.0,
        bias: V3::zeros(),
    };
    goals.solve(&mut rigid, &mut impulses, |k| {
        let (p, n) = contacts[k];
        (p, n, target(&p, &n))
    });
    coulomb(&mut rigid, contacts, &impulses, friction);
    let (dv, dw) = (
        rigid.velocity - after.velocity,
        rigid.angular_velocity - after.angular_velocity,
    );
    let nodes = &mut world.nodes;
    for i in range {
        nodes.velocity[i] += dv + dw.cross(&(nodes.position[i] - after.centre));
    }
}

/// A new impact on one plane or collider: its contact points with their normals, the
/// restitution it gets and its friction coefficient.
struct Impact<'a> {
    contacts: &'a [(V3, V3)],
    e: f64,
    friction: f64,
}

/// Coulomb friction with a bounce's normal impulses (`normal[k]` at `contacts[k]`): at each
/// point, an impulse against its slip on the surface that stops the slip, bounded by
/// `mu` (the friction coefficient) times the point's normal impulse; sequential impulses, accumulated per point,
/// a few passes in alternating order. The contact projection stops the approach with its
/// friction, but the bounce's impulse is the larger part of the impact's (it also stops what
/// the projection left approaching), and it had none: a steel box thrown at 2 m/s onto the
/// floor from 30 cm hopped on at 2 m/s for a second and came to rest 3.9 m away (1.2 m now),
/// and a wooden box landing from 2 mm on a 30° ramp slid 13 % farther in the next second
/// than Coulomb's law lets it (7 % now; 3 % with no bounce at all).
fn coulomb(rigid: &mut RigidMotion, contacts: &[(V3, V3)], normal: &[f64], mu: f64) {
    /// Passes over the contact points.
    const PASSES: usize = 4;
    let mut totals = vec![V3::zeros(); contacts.len()];
    for pass in 0..PASSES {
        for k in alternating(contacts.len(), pass) {
            let (p, n) = contacts[k];
            let v = rigid.velocity_at(&p);
            let slip = v - n * v.dot(&n);
            let speed = slip.norm();
            if speed <= 0.0 {
                continue;
            }
            let t = slip / speed;
            let stop = totals[k] - t * (speed / inverse_mass_along(rigid, p, t));
            let total = friction(stop, mu * normal[k]);
            nudge(rigid, p, total - totals[k]);
            totals[k] = total;
        }
    }
}

/// Sequential impulses on a rigid motion along contact normals (Catto's accumulated impulses):
/// each pass moves every point's normal velocity, plus `bias` along the normal, `weight` of
/// the way to its goal, the point's impulse accumulated and never pulling.
struct SequentialImpulses {
    passes: usize,
    /// Forwards and backwards over the points in turn, so no point is always first.
    alternate: bool,
    weight: f64,
    /// Velocity added to the rigid motion's at each point before it is compared with the goal
    /// (gravity's for the coming substep), m/s.
    bias: V3,
}

impl SequentialImpulses {
    /// `point(k)` is point `k`'s (position, normal, goal normal velocity); `totals[k]` its
    /// accumulated impulse, starting from what it holds.
    fn solve(
        &self,
        rigid: &mut RigidMotion,
        totals: &mut [f64],
        point: impl Fn(usize) -> (V3, V3, f64),
    ) {
        for pass in 0..self.passes {
            // One order throughout (pass 0's) unless alternating.
            for k in alternating(totals.len(), if self.alternate { pass } else { 0 }) {
                let (p, n, goal) = point(k);
                let now = (rigid.velocity_at(&p) + self.bias).dot(&n);
                let push = self.weight * (goal - now) / inverse_mass_along(rigid, p, n);
                let j = (totals[k] + push).max(0.0);
                nudge(rigid, p, n * (j - totals[k]));
                totals[k] = j;
            }
        }
    }
}

/// How much the rigid velocity at `at` along `dir` changes per unit impulse there.
fn inverse_mass_along(rigid: &RigidMotion, at: V3, dir: V3) -> f64 {
    let arm = (at - rigid.centre).cross(&dir);
    1.0 / rigid.mass + arm.dot(&(rigid.inv_inertia * arm))
}

/// A stiff body resting on a plane is rigid at the substep's scale, so the plane holds it up
/// as a whole: before gravity moves it, impulses on its rigid motion at its points on the
/// plane cancel the approach gravity would give each of them, and Coulomb friction (the
/// floor's coefficient, bounded by each point's impulse) the sliding there, both times the
/// body's restitution weight. Sequential impulses over the points, accumulated and kept
/// pushing (never pulling), a few passes: a box on its face rests on all four corners rather
/// than rocking about one. Left to the contact projection, gravity would press the bottom
/// cells by `g Δt²` every substep, more than the one sweep carries up the body, and a small
/// body (a 1 cm cube, its wave crossing it many times a substep) folds under its own weight.
fn support(
    world: &mut World,
    s: &StiffBody,
    weight: f64,
    dt: f64,
    tolerance: f64,
    (points, impulses): (&mut Vec<(V3, f64)>, &mut Vec<f64>),
) {
    /// Passes over a resting body's contact points.
    const PASSES: usize = 4;
    let Some(start) = s.before else {
        return;
    };
    let mut rigid = start;
    let (g, friction) = (world.settings.gravity, world.settings.layer.friction);
    // Points this substep's rigid motion and gravity could bring onto the plane.
    let extent = s.crossing * s.wave_speed;
    let reach = tolerance
        + (start.velocity.norm() + start.angular_velocity.norm() * extent + g.norm() * dt) * dt;
    for slot in 0..world.settings.planes.len() {
        let plane = world.settings.planes[slot];
        if !s.touching[slot] || mesh_on_plane(world, s, &plane, reach, points).is_none() {
            continue;
        }
        let n = plane.normal;
        impulses.clear();
        impulses.resize(points.len(), 0.0);
        let goals = SequentialImpulses {
            passes: PASSES,
            alternate: false,
            weight,
            bias: g * dt,
        };
        // Speculative: a point above the plane may close the gap, no more.
        goals.solve(&mut rigid, impulses, |k| {
            let (p, height) = points[k];
            (p, n, -height.max(0.0) / dt)
        });
        for ((p, _), total) in points.iter().zip(impulses.iter()) {
            let v = rigid.velocity_at(p) + g * dt;
            let slide = v - n * v.dot(&n);
            let speed = slide.norm();
            if speed > 0.0 && *total > 0.0 {
                let t = -slide / speed;
                let stop = weight * speed / inverse_mass_along(&rigid, *p, t);
                nudge(&mut rigid, *p, t * stop.min(friction * total));
            }
        }
    }
    let (dv, dw) = (
        rigid.velocity - start.velocity,
        rigid.angular_velocity - start.angular_velocity,
    );
    let nodes = &mut world.nodes;
    for i in world.bodies[s.body].nodes.clone() {
        nodes.velocity[i] += dv + dw.cross(&(nodes.position[i] - start.centre));
    }
}

/// `impulse` at `at` on the rigid motion alone.
fn nudge(rigid: &mut RigidMotion, at: V3, impulse: V3) {
    rigid.velocity += impulse / rigid.mass;
    rigid.angular_velocity += rigid.inv_inertia * (at - rigid.centre).cross(&impulse);
}

/// Where a body's mesh is on `plane`: its surface points and the nodes that take contact
/// within `tolerance` of it, into `out`, and their centre (a lattice's nodes outside the mesh
/// may lie on the plane, or below it, and would hold a tilted box up on its lattice's face,
/// or put the impact of a flat face off its centre).
fn mesh_on_plane(
    world: &World,
    s: &StiffBody,
    plane: &Plane,
    tolerance: f64,
    out: &mut Vec<(V3, f64)>,
) -> Option<V3> {
    let (x, sp, takes) = (&world.nodes.position, &world.surface, &world.node_contact);
    out.clear();
    let height = |p: V3| (p, plane.normal.dot(&p) - plane.offset);
    let on = |&(_, h): &(V3, f64)| h <= tolerance;
    let nodes = world.bodies[s.body].nodes.clone();
    out.extend(nodes.filter(|&i| takes[i]).map(|i| height(x[i])).filter(on));
    // A point of these barely deforming bodies lies within one and a half cell diagonals of its
    // cell's first node (`reach`, three, allows for stretched cells): that node tells which are far.
    let near = |k: &&u32| {
        let first = x[sp.nodes[**k as usize][0] as usize];
        plane.normal.dot(&first) - plane.offset <= tolerance + 0.5 * sp.reach[**k as usize]
    };
    out.extend(
        s.surface
            .iter()
            .filter(near)
            .map(|&k| {
                let (ids, weights) = (&sp.nodes[k as usize], &sp.weights[k as usize]);
                height((0..8).map(|c| x[ids[c] as usize] * weights[c]).sum::<V3>())
            })
            .filter(on),
    );
    (!out.is_empty()).then(|| out.iter().map(|(p, _)| p).sum::<V3>() / out.len() as f64)
}
