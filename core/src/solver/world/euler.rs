//! Miyazaki's symplectic-Euler step of a [`World`] (the papers' integrator; module docs of
//! [`super`]): spring forces, the fused node pass with gravity and contacts, deformation
//! damping, velocity dispersion, position update.

use super::*;
use crate::solver::contact_log::SurfacePass;
use crate::solver::integrator::Integrate;

/// The papers' integrator behind [`Integrate`]: the explicit step, then the trajectory
/// constraints enforced on the stepped state (module docs of `constraints`).
pub(crate) struct SymplecticEuler;

impl Integrate for SymplecticEuler {
    fn choose_substeps(&self, world: &mut World, frame_dt: f64) -> SubstepChoice {
        world.explicit_substeps(frame_dt)
    }

    fn substep(&self, world: &mut World, dt: f64, acc: &mut FrameAccumulator) -> StepStats {
        if world.constraints.is_empty() {
            return world.euler_step(dt, acc);
        }
        let t = world.time;
        let mut before = std::mem::take(&mut world.scratch.constrained_before);
        before.resize_with(world.constraints.len(), Vec::new);
        for (c, b) in world.constraints.iter().zip(before.iter_mut()) {
            b.clear();
            b.extend(c.nodes.iter().map(|&i| world.nodes.position[i]));
        }
        let stats = world.euler_step(dt, acc);
        for (c, old) in world.constraints.iter().zip(before.iter()) {
            let s = c.strength;
            for (j, &i) in c.nodes.iter().enumerate() {
                let target = c.target(j, t + dt);
                let v_target = (target - old[j]) / dt;
                if s >= 1.0 {
                    world.nodes.position[i] = target;
                    world.nodes.velocity[i] = v_target;
                } else {
                    let (x, v) = (world.nodes.position[i], world.nodes.velocity[i]);
                    world.nodes.position[i] = x + (target - x) * s;
                    world.nodes.velocity[i] = v + (v_target - v) * s;
                }
            }
        }
        world.scratch.constrained_before = before;
        stats
    }
}

impl World {
    /// Substeps of the explicit integrators (symplectic Euler, Newmark-β): the accuracy and
    /// stability bound of the stiffest spring and the contact layer ([`World::static_step`]),
    /// and no node travelling more than `max_travel_fraction` of the shortest spring.
    pub(crate) fn explicit_substeps(&mut self, frame_dt: f64) -> SubstepChoice {
        let travel = self.settings.max_travel_fraction;
        let v_max = self.max_speed();
        let p = self.prepare();
        let mut choice = p.static_step;
        let mut n = if choice.dt.is_finite() {
            (frame_dt / choice.dt).ceil().max(1.0)
        } else {
            1.0
        };
        if p.shortest_spring.is_finite() && v_max > 0.0 {
            let by_speed = (v_max * frame_dt / (travel * p.shortest_spring)).ceil();
            if by_speed > n {
                n = by_speed;
                choice.limited_by = "speed";
            }
        }
        choice.substeps = n.min(u32::MAX as f64) as u32;
        choice.dt = frame_dt / n;
        choice
    }

    /// Miyazaki's symplectic-Euler step (module docs).
    pub(super) fn euler_step(&mut self, dt: f64, acc: &mut FrameAccumulator) -> StepStats {
        let gravity = self.settings.gravity;
        let layer = self.settings.layer;
        let dispersion = self.settings.dispersion;
        let max_iter = self.settings.max_dispersion_iterations;
        let time = self.time;
        self.prepare();
        let World {
            nodes,
            springs,
            settings,
            prepared,
            manipulators,
            live_capsules,
            surface,
            node_contact,
            bodies,
            contact_log,
            body_contact,
            field_force,
            ..
        } = self;
        let fields = (!field_force.is_empty()).then_some(&field_force[..]);
        let p = prepared.as_mut().expect("prepared");
        // Capsules of the scripted tracks at this time plus the live ones (reused buffer).
        p.capsules.clear();
        p.capsules
            .extend(manipulators.iter().map(|m| m.capsule_at(time)));
        p.capsules.extend(live_capsules.iter().copied());
        let has_contact = !settings.planes.is_empty() || !p.capsules.is_empty();
        let wind = settings.wind.map(|w| (w, w.air_velocity(time)));

        let hinted = dispersion != DispersionMode::Off && p.hints_enabled;
        let stencil = p.stencil.as_mut().filter(|_| p.stencil_enabled);
        if stencil.as_ref().is_none_or(|plan| !plan.covers_all()) {
            // (Grows only when a test has switched the stencil off.)
            p.spring_force.resize(springs.len(), Vector3::zeros());
            spring_forces(
                nodes,
                springs,
                &mut p.spring_force,
                hinted.then_some(FloorOutput {
                    mode: dispersion,
                    inv_dt_sq: 1.0 / (dt * dt),
                    exceptional: &mut p.exceptional,
                    chunk_floor: &mut p.chunk_floor,
                }),
                stencil.as_deref(),
            );
        } else if hinted {
            p.chunk_floor.fill(f64::INFINITY);
        }
        // The lattice bodies' springs (skipped above), with the same per-spring hints.
        let stencil = stencil.map(|plan| {
            let floor = hinted.then_some(FloorInput {
                mode: dispersion,
                inv_dt_sq: 1.0 / (dt * dt),
            });
            let found = plan.forces(nodes, floor);
            if hinted {
                if let Some(first) = p.chunk_floor.first_mut() {
                    *first = first.min(found.least);
                }
            }
            (&*plan, found.flagged)
        });
        let (stencil, stencil_flagged) = stencil.map_or((None, false), |(plan, f)| (Some(plan), f));
        let reference = nodes
            .velocity
            .first()
            .copied()
            .unwrap_or_else(Vector3::zeros);

        // Rigid broad phase for the nodes that take contacts themselves: per block of nodes,
        // whether its box reaches a plane or capsule (exact: a block that does not has no
        // contact, see `box_may_touch`). The log and the node pass below skip the others.
        let node_blocks = has_contact && node_contact.contains(&true);
        if node_blocks && !p.rigid_broad_phase {
            p.block_near.fill(true);
        } else if node_blocks {
            let (planes, caps, pos) = (&settings.planes[..], &p.capsules[..], &nodes.position[..]);
            p.block_near
                .par_chunks_mut(PAR_CHUNK / CONTACT_BLOCK)
                .enumerate()
                .for_each(|(chunk, near)| {
                    let first = chunk * PAR_CHUNK;
                    for (j, near) in near.iter_mut().enumerate() {
                        let start = first + j * CONTACT_BLOCK;
                        let block = &pos[start..(start + CONTACT_BLOCK).min(pos.len())];
                        let (lo, hi) = bounding_box(block);
                        *near = box_may_touch(lo, hi, planes, caps);
                    }
                });
        }

        // Contacts of the display surfaces, spread onto their nodes (serial scatter in point
        // order: deterministic).
        let surface_contact = has_contact && !surface.is_empty();
        if surface_contact {
            let planes = &settings.planes[..];
            let caps = &p.capsules[..];
            let state: &NodeState = nodes;
            // Broad phase: a body whose nodes' box touches no rigid surface has no contact
            // (its surface lies inside the cells, inside that box).
            p.body_may_touch.clear();
            p.body_may_touch.extend(bodies.iter().map(|b| {
                let (mut lo, mut hi) = (
                    Vector3::repeat(f64::INFINITY),
                    Vector3::repeat(f64::NEG_INFINITY),
                );
                for x in &state.position[b.nodes.clone()] {
                    lo = lo.inf(x);
                    hi = hi.sup(x);
                }
                let plane_near = planes.iter().any(|pl| {
                    let lowest = (0..8).map(|c| {
                        let corner = Vector3::new(
                            if c & 1 == 0 { lo.x } else { hi.x },
                            if c & 2 == 0 { lo.y } else { hi.y },
                            if c & 4 == 0 { lo.z } else { hi.z },
                        );
                        pl.normal.dot(&corner)
                    });
                    lowest.fold(f64::INFINITY, f64::min) < pl.offset
                });
                let capsule_near = caps.iter().any(|c| {
                    let (a, b) = c.endpoints();
                    let (clo, chi) = (
                        a.inf(&b).add_scalar(-c.radius),
                        a.sup(&b).add_scalar(c.radius),
                    );
                    (0..3).all(|k| clo[k] <= hi[k] && chi[k] >= lo[k])
                });
                plane_near || capsule_near
            }));
            let (may_touch, broad_phase) = (&p.body_may_touch, p.rigid_broad_phase);
            let point = |(i, out): (usize, &mut (Vector3<f64>, f64, Vector3<f64>))| {
                if !may_touch[surface.body[i] as usize] {
                    *out = (Vector3::zeros(), 0.0, Vector3::zeros());
                    return;
                }
                // Narrow phase: a point whose cell corner is farther than its reach from every
                // plane and capsule cannot touch one.
                let corner = &state.position[surface.nodes[i][0] as usize];
                if broad_phase && beyond_reach(planes, caps, corner, surface.reach[i]) {
                    *out = (Vector3::zeros(), 0.0, Vector3::zeros());
                    return;
                }
                *out = surface.contact(i, state, &state.velocity, &layer, planes, caps, dt);
            };
            // Small point sets stay on this thread: waking the pool costs more than the work.
            if p.point_contact.len() > 2 * PAR_CHUNK {
                p.point_contact
                    .par_iter_mut()
                    .with_min_len(PAR_CHUNK)
                    .enumerate()
                    .for_each(point);
            } else {
                p.point_contact.iter_mut().enumerate().for_each(point);
            }
            p.surface_force
                .iter_mut()
                .for_each(|f| *f = Vector3::zeros());
            let mut from_caps = Vector3::zeros();
            for (i, &(f, depth, fc)) in p.point_contact.iter().enumerate() {
                acc.max_depth = acc.max_depth.max(depth);
                from_caps += fc;
                if f != Vector3::zeros() {
                    for c in 0..8 {
                        p.surface_force[surface.nodes[i][c] as usize] += f * surface.weights[i][c];
                    }
                }
            }
            if !p.capsules.is_empty() {
                acc.reaction_sum -= from_caps;
            }
        }
        // Body–body and body–collider contacts, and the contact log: this step's contacts per
        // (body, partner), at the state the forces are evaluated at (only the points the pass
        // above found touching are looked at again).
        {
            let scene = RigidScene {
                layer: &layer,
                planes: &settings.planes,
                capsules: &p.capsules,
                up: settings.up,
                dt,
                lead: 0.0,
                points: (surface_contact && p.rigid_broad_phase).then_some(SurfacePass {
                    contacts: &p.point_contact,
                    touching: None,
                }),
                node_blocks: (node_blocks && p.rigid_broad_phase).then_some(&p.block_near[..]),
            };
            step_contacts(
                body_contact,
                contact_log,
                &scene,
                surface,
                nodes,
                node_contact,
                bodies,
            );
        }

        // Fused node pass: gravity + gathered springs + contact, then v += F/m·ΔT (eq 2).
        {
            let node_contact = &node_contact[..];
            let surface_force = &p.surface_force[..];
            let body_force = body_contact.active.then_some(&body_contact.force[..]);
            let planes = &settings.planes[..];
            let caps = &p.capsules[..];
            // With the stencil, the index lists hold only the springs it does not take.
            let adjacency = if stencil.is_some() {
                &p.residual_adjacency
            } else {
                &p.adjacency
            };
            let spring_force = &p.spring_force[..];
            let block_near = &p.block_near[..];
            let (pos, mass, inv_mass) = (&nodes.position[..], &nodes.mass[..], &nodes.inv_mass[..]);
            nodes
                .velocity
                .par_chunks_mut(PAR_CHUNK)
                .zip(p.chunk_contact.par_iter_mut())
                .zip(p.chunk_spread.par_iter_mut())
                .enumerate()
                .for_each(|(chunk, ((vel, out), spread))| {
                    let first = chunk * PAR_CHUNK;
                    let mut widest = 0.0f64;
                    let mut deepest = 0.0f64;
                    let mut from_caps = Vector3::zeros();
                    for (j, v) in vel.iter_mut().enumerate() {
                        let i = first + j;
                        let mut springs_f = gathered_spring_force(adjacency, spring_force, i);
                        if let Some(sf) = stencil.and_then(|plan| plan.node_force(i)) {
                            springs_f = sf + springs_f;
                        }
                        let mut f = gravity * mass[i] + springs_f;
                        if surface_contact {
                            f += surface_force[i];
                        }
                        if let Some(bf) = body_force {
                            f += bf[i];
                        }
                        if let Some((w, air)) = wind {
                            f += w.force(air, *v, mass[i]);
                        }
                        if let Some(fields) = fields {
                            f += fields[i];
                        }
                        if has_contact && node_contact[i] {
                            if block_near[i / CONTACT_BLOCK] {
                                let (cf, d, fc) =
                                    node_contacts(&layer, planes, caps, pos[i], *v, mass[i], dt);
                                f += cf;
                                deepest = deepest.max(d);
                                from_caps += fc;
                            } else {
                                // Out of reach node_contacts gives +0 (no depth, no capsule
                                // force); adding it keeps the bits (a −0 of f turns +0).
                                f += Vector3::zeros();
                            }
                        }
                        *v += f * (inv_mass[i] * dt);
                        // NaN-safe: a NaN spread makes the uniform test fail.
                        let w = (*v - reference).norm_squared();
                        widest = if w > widest || w.is_nan() { w } else { widest };
                    }
                    *out = (deepest, from_caps);
                    *spread = widest;
                });
        }
        if has_contact {
            // Fixed chunk order: the same sums with any thread count.
            let mut sum = Vector3::zeros();
            for &(deepest, from_caps) in &p.chunk_contact {
                acc.max_depth = acc.max_depth.max(deepest);
                sum += from_caps;
            }
            if !p.capsules.is_empty() {
                acc.reaction_sum -= sum;
            }
        }

        // Deformation damping: pull every node towards its body's rigid motion.
        crate::solver::deformation_damping::damp(nodes, bodies, dt, &mut p.rigid_scratch);

        // Velocity dispersion (§3.4 step 2–3).
        let hints = hinted.then(|| {
            let spread =
                p.chunk_spread
                    .iter()
                    .fold(0.0f64, |m, &w| if w > m || w.is_nan() { w } else { m });
            let floor = p.chunk_floor.iter().fold(f64::INFINITY, |m, &f| m.min(f));
            let uniform = 4.0 * spread <= floor;
            // The flags are read only when motion is uniform: the stencil's are copied out
            // then, and only when one is set if it takes every spring.
            let flagged = uniform
                && match stencil {
                    Some(plan) if plan.covers_all() => {
                        if stencil_flagged {
                            plan.write_flags(&mut p.exceptional);
                        }
                        stencil_flagged
                    }
                    Some(plan) => {
                        plan.write_flags(&mut p.exceptional);
                        p.exceptional.contains(&1)
                    }
                    None => p.exceptional.contains(&1),
                };
            SpringHints {
                exceptional: &p.exceptional,
                uniform,
                flagged,
            }
        });
        let d = disperse_with(
            dispersion,
            nodes,
            springs,
            &p.colouring,
            dt,
            max_iter,
            &mut p.dispersion_scratch,
            hints,
            p.active_set_enabled.then_some(&p.adjacency),
        );

        // Position update with the new velocity (eq 3, symplectic).
        let velocity = &nodes.velocity[..];
        nodes
            .position
            .par_chunks_mut(PAR_CHUNK)
            .enumerate()
            .for_each(|(chunk, xs)| {
                let v = &velocity[chunk * PAR_CHUNK..chunk * PAR_CHUNK + xs.len()];
                for (x, v) in xs.iter_mut().zip(v) {
                    *x += v * dt;
                }
            });

        self.time += dt;
        acc.corrections += d.corrections;
        acc.iterations += d.iterations;
        acc.cap_hits += d.hit_cap as u32;
        acc.steps += 1;
        StepStats {
            dispersion_corrections: d.corrections,
            dispersion_iterations: d.iterations,
            dispersion_cap_hit: d.hit_cap,
            ..StepStats::default()
        }
    }
}
