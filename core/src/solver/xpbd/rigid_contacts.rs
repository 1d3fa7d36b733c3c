//! Stage 4b of the substep: contact with the rigid surfaces (floor, walls, capsules) and the
//! static colliders. Nodes that take contact are projected in parallel chunks; the
//! display-surface points a colour of cells at a time on the [`team`] (a colour's cells share
//! no node), or one after the other in visiting order when the world has static colliders
//! (a held or rigid body's points in them are then solved together on its rigid frame,
//! [`super::frame_contacts`]). The constraint math is [`super::contact`]'s; this module owns
//! the passes over the points.

use super::bodies::NO_FRAME;
use super::cells::PointGroups;
use super::contact::{resolve_colliders, ColliderContact, PointContact, Surfaces};
use super::frame_contacts;
use super::frames::apply_frames;
use super::{push_capsules, Model, StepOutput, V3};
use crate::solver::manipulator::Capsule;
use crate::solver::team::{self, Chunks, Disjoint};
use crate::solver::{World, PAR_CHUNK};

/// Stage 4b: contact with the floor, walls and capsules (nodes in parallel, display-surface
/// points a colour at a time, or serially in point order with static colliders).
pub(super) fn rigid_contacts(
    world: &mut World,
    model: &mut Model,
    time: f64,
    dt: f64,
) -> StepOutput {
    let mut capsules = std::mem::take(&mut model.capsules);
    capsules.clear();
    push_capsules(world, time, dt, &mut capsules);
    let out = rigid_contacts_with(world, model, &capsules, dt);
    model.capsules = capsules;
    out
}

/// [`rigid_contacts`] against the substep's `capsules`.
fn rigid_contacts_with(
    world: &mut World,
    model: &mut Model,
    capsules: &[(Capsule, Capsule)],
    dt: f64,
) -> StepOutput {
    let surfaces = Surfaces {
        planes: &world.settings.planes,
        friction: world.settings.layer.friction,
        capsules,
    };
    let mut out = StepOutput::default();
    let bc = &mut world.body_contact;
    let colliders = bc.collider_constraints && !bc.colliders.is_empty();
    if surfaces.planes.is_empty() && surfaces.capsules.is_empty() && !colliders {
        return out;
    }
    model.contact_shifted = true;
    let inv_dt2 = 1.0 / (dt * dt);
    let (w, prev) = (&model.inv_mass[..], &model.previous[..]);
    let (mass, takes) = (&world.nodes.mass[..], &world.node_contact[..]);
    let chunks = (
        Chunks::new(&mut world.nodes.position, PAR_CHUNK),
        Chunks::new(&mut model.moved, PAR_CHUNK),
        Chunks::new(&mut model.contact_shift, PAR_CHUNK),
        Chunks::new(&mut model.chunk_contact, 1),
    );
    team::for_each(chunks, |chunk, (xs, moved, shifts, sums)| {
        let mut deepest = 0.0f64;
        let mut force = V3::zeros();
        let mut work = 0.0;
        for (j, ((x, moved), shift)) in xs.iter_mut().zip(moved).zip(shifts).enumerate() {
            let i = chunk * PAR_CHUNK + j;
            if !takes[i] || w[i] <= 0.0 {
                continue;
            }
            let c = surfaces.resolve(*x, prev[i]);
            if c.depth > 0.0 {
                *x += c.correction;
                *shift += c.correction;
                *moved = true;
                deepest = deepest.max(c.depth);
                force += c.from_capsules * (mass[i] * inv_dt2);
                work += c.capsule_work * (mass[i] * inv_dt2);
            }
        }
        sums[0] = (deepest, force, work);
    });
    for &(deepest, force, work) in &model.chunk_contact {
        out.touched |= deepest > 0.0;
        out.max_depth = out.max_depth.max(deepest);
        out.capsule_force += force;
        out.capsule_work += work;
    }
    // Held and rigid bodies take the colliders' pushes as rigid bodies (see `frames`).
    let mut frames = if colliders {
        let frame_of = &mut model.frame_of;
        super::contact_frames(world, &model.held, &model.inv_mass, frame_of)
    } else {
        Vec::new()
    };
    model.frame_contacts.clear();
    let x = &mut world.nodes.position;
    let (statics, boxes) = world.body_contact.colliders_and_boxes();
    let surface_body = &world.surface.body;
    let behind = world.settings.layer.thickness_m;
    model.logged_once = true;
    for &i in &model.in_contact {
        model.point_contact[i as usize] = (V3::zeros(), 0.0, V3::zeros());
    }
    model.in_contact.clear();
    if !colliders {
        let sums = contact_points_by_colour(x, model, &surfaces, inv_dt2);
        out.touched |= sums.touched;
        out.max_depth = out.max_depth.max(sums.deepest);
        out.capsule_force += sums.force;
        out.capsule_work += sums.work;
        return out;
    }
    for (&i, visit) in model.points.order.iter().zip(model.visits.iter()) {
        let i = i as usize;
        if colliders {
            model.collider_touch[i] = None;
        }
        let (ids, weights) = (&visit.nodes, &visit.weights);
        let near_surfaces = !surfaces.beyond_reach(&x[ids[0] as usize], visit.reach);
        if !near_surfaces && !colliders {
            continue;
        }
        let ids = ids.map(|n| n as usize);
        // A point's eight nodes are one body's: a held or rigid one's frame, if any (it moves
        // only after the pass).
        let frame = frame_of_point(&model.frame_of, ids[0]);
        let nodes = (ids.map(|n| x[n]), ids.map(|n| prev[n]), ids.map(|n| w[n]));
        let (p, p_prev, denominator) = interpolate(weights, &nodes.0, &nodes.1, &nodes.2);
        if denominator <= 0.0 {
            continue;
        }
        let c = if near_surfaces {
            surfaces.resolve(p, p_prev)
        } else {
            PointContact::default()
        };
        let held = if colliders {
            let after = p + c.correction;
            let side = &mut model.collider_side[i];
            // The side it rested on holds while it stays within a layer of that place.
            *side = side.filter(|&(_, n, q)| (p_prev - q).dot(&n).abs() < behind);
            let resting = side.map(|(k, n, _)| (k, n));
            let body = (boxes.get(surface_body[i] as usize))
                .map(|(lo, hi)| (lo + hi) / 2.0)
                .filter(|c| c.iter().all(|v| v.is_finite()));
            let scratch = &mut model.collider_scratch;
            let sides = (resting, body);
            let held = resolve_colliders(statics, (p_prev, after), behind, sides, scratch);
            if let Some((k, n)) = held.deepest {
                *side = Some((k, n, after + held.correction));
            }
            held
        } else {
            ColliderContact::default()
        };
        if c.depth <= 0.0 && held.depth <= 0.0 {
            continue;
        }
        if colliders {
            model.collider_touch[i] = held.deepest;
        }
        out.touched = true;
        out.max_depth = out.max_depth.max(c.depth).max(held.depth);
        if c.depth > 0.0 {
            out.capsule_force += c.from_capsules * (inv_dt2 / denominator);
            out.capsule_work += c.capsule_work * (inv_dt2 / denominator);
            // The log reads the rigid surfaces' part (colliders log through the contact pass).
            model.point_contact[i] = (
                c.correction * (inv_dt2 / denominator),
                c.depth,
                c.from_capsules * (inv_dt2 / denominator),
            );
            model.in_contact.push(i as u32);
        }
        let mut correction = c.correction + held.correction;
        if let (Some(f), Some((k, normal))) = (frame, held.deepest) {
            // The collider's push moves the whole body, solved with the body's other points
            // after the pass; a two-sided collider's face met from its far side is left to the
            // near one (`frame_contacts`).
            correction = c.correction;
            let far_side =
                statics[k as usize].two_sided && (p - frames[f].centre).dot(&normal) > 0.0;
            if !far_side {
                let at = p + c.correction;
                model.frame_contacts.push(frame_contacts::FrameContact::new(
                    (at, f as u32),
                    (normal, at + normal * held.correction.dot(&normal)),
                    p_prev,
                    statics[k as usize].friction,
                ));
            }
        }
        for (&n, weight) in ids.iter().zip(weights) {
            let step = correction * (weight * w[n] / denominator);
            x[n] += step;
            model.contact_shift[n] += step;
            model.moved[n] = true;
        }
    }
    frame_contacts::solve(&mut frames, &mut model.frame_contacts);
    apply_frames(&frames, x, &mut model.contact_shift, &mut model.moved);
    out
}

/// The frame (index into the pass's frames) of the body whose nodes `first` is one of, if it
/// is held or rigid.
fn frame_of_point(frame_of: &[u32], first: usize) -> Option<usize> {
    (frame_of.get(first).copied())
        .filter(|&f| f != NO_FRAME)
        .map(|f| f as usize)
}

/// What a task of the points' pass found: whether a point touched, the deepest, and the
/// capsules' force and work on its points.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct PointSums {
    touched: bool,
    deepest: f64,
    force: V3,
    work: f64,
    /// Where the task's points start in the visiting order, and how many of them touched
    /// (listed in `Model::found` from there).
    first: u32,
    count: u32,
}

/// Cells' worth of points a task of the points' pass takes.
const POINT_GROUPS_PER_TASK: usize = 16;

/// How many groups of `groups` a task of a colour takes: all of them where the points' cells
/// may share nodes (not `parallel`: the cells' serial colour, and the points in no cell,
/// last).
fn point_groups_per_task(parallel: bool, groups: usize) -> usize {
    if parallel {
        POINT_GROUPS_PER_TASK
    } else {
        groups.max(1)
    }
}

/// Tasks of the points' pass by colour over all colours.
pub(super) fn point_tasks(points: &PointGroups) -> usize {
    (points.colours.iter().zip(&points.parallel))
        .map(|(groups, &parallel)| {
            let n = groups.len();
            n.div_ceil(point_groups_per_task(parallel, n))
        })
        .sum()
}

/// A point weighing its eight nodes by `weights`: where it is (from the nodes' `x`), where
/// it was at the substep's start (from `prev`), and `Σ weight² · w` of the nodes' inverse
/// masses, which spreads a correction of the point over the nodes.
#[inline(always)]
fn interpolate(weights: &[f64; 8], x: &[V3; 8], prev: &[V3; 8], w: &[f64; 8]) -> (V3, V3, f64) {
    let (mut p, mut p_prev, mut denominator) = (V3::zeros(), V3::zeros(), 0.0);
    for c in 0..8 {
        p += x[c] * weights[c];
        p_prev += prev[c] * weights[c];
        denominator += weights[c] * weights[c] * w[c];
    }
    (p, p_prev, denominator)
}

/// One point's contact with the rigid surfaces from its eight nodes (as [`interpolate`]
/// takes them). `None` where the point does not touch (or cannot move); else the contact and
/// the point's `Σ weight² · w`.
#[inline(always)]
fn point_contact(
    surfaces: &Surfaces,
    weights: &[f64; 8],
    x: &[V3; 8],
    prev: &[V3; 8],
    w: &[f64; 8],
) -> Option<(PointContact, f64)> {
    let (p, p_prev, denominator) = interpolate(weights, x, prev, w);
    if denominator <= 0.0 {
        return None;
    }
    let c = surfaces.resolve(p, p_prev);
    (c.depth > 0.0).then_some((c, denominator))
}

/// The display-surface points' rigid contacts (no static colliders in the world), a colour
/// at a time: the points of one cell move only that cell's nodes, and a colour's cells share
/// none, so a colour's cells' points run side by side (on the [`team`]) and give what the
/// visiting order gives one after the other. A cell's group of points reads the cell's
/// nodes once, moves them point after point in a copy (the same arithmetic, in the same
/// order, as on the shared arrays) and writes them back once: point by point, the standard
/// scene's resting cube spent a fifth of its time here. Each task sums its points' force and
/// work, and the tasks' sums add up in order: the same bits on any thread count.
fn contact_points_by_colour(
    x: &mut [V3],
    model: &mut Model,
    surfaces: &Surfaces,
    inv_dt2: f64,
) -> PointSums {
    let Model {
        points,
        visits,
        group_in_hull,
        group_one_cell,
        inv_mass: w,
        previous: prev,
        contact_shift,
        moved,
        point_contact: logs,
        point_sums,
        in_contact,
        found,
        ..
    } = model;
    let (xs, shifts) = (Disjoint::new(x), Disjoint::new(contact_shift));
    let (moved, logged) = (Disjoint::new(moved), Disjoint::new(logs));
    let listed = Disjoint::new(found);
    // What a touching point adds to its task's sums and logs (`o`: its place in the visiting
    // order; `c`, `denominator`: from `point_contact`).
    let note = |o: usize, c: &PointContact, denominator: f64, sums: &mut PointSums| {
        sums.touched = true;
        sums.deepest = sums.deepest.max(c.depth);
        sums.force += c.from_capsules * (inv_dt2 / denominator);
        sums.work += c.capsule_work * (inv_dt2 / denominator);
        let i = points.order[o] as usize;
        let log = (
            c.correction * (inv_dt2 / denominator),
            c.depth,
            c.from_capsules * (inv_dt2 / denominator),
        );
        // SAFETY: a point logs only itself, and a task lists its points from its first
        // place in the visiting order on.
        #[allow(unsafe_code)]
        unsafe {
            listed.set((sums.first + sums.count) as usize, i as u32);
            logged.set(i, log);
        }
        sums.count += 1;
    };
    // SAFETY (every `get` and `set` below): a point moves only its cell's nodes, and the
    // tasks of a pass take cells that share no node (see above).
    #[allow(unsafe_code)]
    let at = |n: u32| unsafe { xs.get(n as usize) };
    // A point on its own, on the shared arrays (a group whose points weigh different nodes).
    let visit = |o: usize, sums: &mut PointSums| {
        let v = &visits[o];
        if surfaces.beyond_reach(&at(v.nodes[0]), v.reach) {
            return;
        }
        let ids = v.nodes.map(|n| n as usize);
        let (x, p, wn) = (
            ids.map(|n| at(n as u32)),
            ids.map(|n| prev[n]),
            ids.map(|n| w[n]),
        );
        let Some((c, denominator)) = point_contact(surfaces, &v.weights, &x, &p, &wn) else {
            return;
        };
        note(o, &c, denominator, sums);
        #[allow(unsafe_code)]
        unsafe {
            for (&n, weight) in ids.iter().zip(v.weights) {
                let step = c.correction * (weight * w[n] / denominator);
                xs.set(n, xs.get(n) + step);
                shifts.set(n, shifts.get(n) + step);
                moved.set(n, true);
            }
        }
    };
    // A cell's points: its eight nodes read once (the group's first point's), moved in a
    // copy, written back once if a point touched.
    let visit_cell = |points: std::ops::Range<u32>, corners: [V3; 8], sums: &mut PointSums| {
        let ids = visits[points.start as usize].nodes.map(|n| n as usize);
        let mut x = corners;
        let (before, wn) = (ids.map(|n| prev[n]), ids.map(|n| w[n]));
        let mut shift: Option<[V3; 8]> = None;
        for o in points.map(|o| o as usize) {
            let v = &visits[o];
            if surfaces.beyond_reach(&x[0], v.reach) {
                continue;
            }
            let Some((c, denominator)) = point_contact(surfaces, &v.weights, &x, &before, &wn)
            else {
                continue;
            };
            note(o, &c, denominator, sums);
            #[allow(unsafe_code)]
            let shift = shift.get_or_insert_with(|| ids.map(|n| unsafe { shifts.get(n) }));
            for k in 0..8 {
                let step = c.correction * (v.weights[k] * wn[k] / denominator);
                x[k] += step;
                shift[k] += step;
            }
        }
        if let Some(shift) = shift {
            #[allow(unsafe_code)]
            unsafe {
                for k in 0..8 {
                    xs.set(ids[k], x[k]);
                    shifts.set(ids[k], shift[k]);
                    moved.set(ids[k], true);
                }
            }
        }
    };
    let mut slot = 0;
    for (colour, range) in points.colours.iter().enumerate() {
        let first_group = range.start as usize;
        let groups = &points.groups[first_group..range.end as usize];
        let per_task = point_groups_per_task(points.parallel[colour], groups.len());
        let tasks = groups.len().div_ceil(per_task);
        team::for_each(
            Chunks::new(&mut point_sums[slot..slot + tasks], 1),
            |t, sums| {
                let end = ((t + 1) * per_task).min(groups.len());
                let mut task = PointSums {
                    first: groups.get(t * per_task).map_or(0, |g| g.start),
                    ..PointSums::default()
                };
                let mine = t * per_task..end;
                for (g, group) in mine.clone().zip(&groups[mine]) {
                    let g = first_group + g;
                    let Some(reach) = group_one_cell[g] else {
                        for o in group.start..group.end {
                            visit(o as usize, &mut task);
                        }
                        continue;
                    };
                    // Every point of the group would find itself beyond reach (it tests the
                    // same node, at a reach no larger): skipped with one test.
                    let ids = &visits[group.start as usize].nodes;
                    if surfaces.beyond_reach(&at(ids[0]), reach) {
                        continue;
                    }
                    let corners = ids.map(at);
                    // A cell's group whose nodes are all clear of the surfaces has no point
                    // that touches.
                    if !(group_in_hull[g] && surfaces.clear_of_hull(&corners)) {
                        visit_cell(group.clone(), corners, &mut task);
                    }
                }
                sums[0] = task;
            },
        );
        slot += tasks;
    }
    let mut total = PointSums::default();
    for s in &point_sums[..slot] {
        total.touched |= s.touched;
        total.deepest = total.deepest.max(s.deepest);
        total.force += s.force;
        total.work += s.work;
        // The points in contact, for the next pass to clear.
        let first = s.first as usize;
        in_contact.extend_from_slice(&found[first..first + s.count as usize]);
    }
    total
}

#[cfg(test)]
mod tests {
    use crate::lattice::{fit_lattice, surface_samples, FitSettings, Resolution};
    use crate::material::Material;
    use crate::shapes::box_mesh;
    use crate::solver::manipulator::Capsule;
    use crate::solver::{Integrator, Plane, World, WorldSettings};
    use nalgebra::Vector3;

    /// A jelly box sliding onto the floor under a capsule: its display-surface points touch
    /// both, with friction.
    fn sliding_box() -> World {
        let jelly = Material::preset("jelly").unwrap();
        let (p, t) = box_mesh([0.0, 0.004, 0.0], [0.3, 0.2, 0.25]);
        let settings = FitSettings {
            resolution: Resolution::CellsAlongLongest(5),
            ..FitSettings::default()
        };
        let lattice = fit_lattice(&p, &t, &settings).unwrap();
        let mut world = World::new(WorldSettings {
            planes: vec![Plane {
                normal: Vector3::y(),
                offset: 0.0,
            }],
            layer: WorldSettings::default_layer(lattice.cell_size, &jelly, 0.4),
            integrator: Integrator::Xpbd,
            ..WorldSettings::default()
        });
        let velocity = Vector3::new(0.8, -0.6, 0.1);
        let body = world.add_lattice_body("box", &lattice, &jelly, velocity);
        let (samples, areas) = surface_samples(&p, &t, 0.5 * lattice.cell_size);
        world.add_contact_surface(body, &lattice, &samples, &areas);
        world.live_capsules.push(Capsule {
            centre: Vector3::new(0.15, 0.24, 0.12),
            axis: Vector3::z(),
            length: 0.2,
            radius: 0.05,
            velocity: Vector3::new(0.0, -0.4, 0.0),
            friction: 0.3,
        });
        world
    }

    /// A cell's points moving one copy of its nodes (read once, written back once) give the
    /// bits of the same points one at a time on the shared arrays.
    #[test]
    fn a_cells_points_move_its_nodes_as_one_point_at_a_time_would() {
        let mut by_cell = sliding_box();
        by_cell.step(1e-4);
        let mut by_point = by_cell.clone();
        let model = by_point.xpbd.as_mut().unwrap();
        assert!(model.group_one_cell.iter().flatten().count() > 10);
        model.group_one_cell.fill(None);
        let mut touched = 0;
        for _ in 0..200 {
            let dt = 1.0 / 2400.0;
            by_cell.step(dt);
            by_point.step(dt);
            assert_eq!(by_cell.nodes.position, by_point.nodes.position);
            let (a, b) = (by_cell.xpbd.as_ref(), by_point.xpbd.as_ref());
            let (a, b) = (a.unwrap(), b.unwrap());
            assert_eq!(a.point_contact, b.point_contact);
            assert_eq!(a.in_contact, b.in_contact);
            touched += a.in_contact.len();
        }
        assert!(touched > 500, "{touched} point contacts");
    }
}
