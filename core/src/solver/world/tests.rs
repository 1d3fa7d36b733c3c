//! Tests of the world's step loop: the fast paths against their switched-off copies, bit for
//! bit.

use super::*;
use crate::lattice::{fit_lattice, FitSettings, Resolution};
use crate::shapes::box_mesh;

/// A soft 0.3 m cube thrown at 20 m/s into a wall: fast enough to need the fusion model,
/// with steps whose dispersion takes several sweeps. Also returns its lattice and material.
fn soft_cube_thrown_at_wall() -> (World, Lattice, Material) {
    let (p, t) = box_mesh([0.0, 0.2, 0.0], [0.3, 0.5, 0.3]);
    let lattice = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(5),
            ..FitSettings::default()
        },
    )
    .unwrap();
    let m = Material::preset("soft_rubber").unwrap();
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: -Vector3::x(),
            offset: -0.35,
        }],
        layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
        ..WorldSettings::default()
    });
    w.add_lattice_body("cube", &lattice, &m, Vector3::new(20.0, 0.0, 0.0));
    (w, lattice, m)
}

/// `world`, a copy with one of its fast paths switched off by `switch_off`, and the step
/// for 24 fps.
fn with_twin(mut world: World, switch_off: fn(&mut Prepared)) -> (World, World, f64) {
    let dt = world.choose_substeps(1.0 / 24.0).dt;
    let mut twin = world.clone();
    switch_off(twin.prepare());
    (world, twin, dt)
}

#[test]
fn dispersion_hints_change_nothing_through_an_impact() {
    // The thrown cube stepped with and without the spring hints: the same bits and the
    // same dispersion counts every step.
    let (cube, lattice, m) = soft_cube_thrown_at_wall();
    let (mut hinted, mut plain, dt) = with_twin(cube, |p| p.hints_enabled = false);
    let (mut corrections, mut uniform_steps) = (0, 0);
    for _ in 0..600 {
        let a = hinted.step(dt);
        let b = plain.step(dt);
        assert_eq!(a, b);
        corrections += a.dispersion_corrections;
        let h = hinted.prepared.as_ref().unwrap();
        let spread = h.chunk_spread.iter().cloned().fold(0.0, f64::max);
        let floor = h.chunk_floor.iter().cloned().fold(f64::INFINITY, f64::min);
        uniform_steps += (4.0 * spread <= floor) as u32;
    }
    assert_eq!(hinted.nodes, plain.nodes);
    assert!(corrections > 0, "the impact must need the fusion model");
    assert!(uniform_steps > 0, "the hints must be used at some step");

    // A resting body (uniform motion holds) with one fused spring that violates: spring 0
    // at half its (doubled) natural length, so θ = 0, nearly without stiffness so it
    // loads nothing, and its ends nudged apart. Only its exceptional flag sends it to the
    // exact test.
    let mut hinted = World::new(WorldSettings {
        gravity: Vector3::zeros(),
        ..WorldSettings::default()
    });
    hinted.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    let s = 0;
    hinted.springs.rest_length[s] *= 2.0;
    hinted.springs.stiffness[s] = 1e-6;
    hinted.springs.damping[s] = 0.0;
    let (a, b) = (hinted.springs.a[s] as usize, hinted.springs.b[s] as usize);
    let dir = (hinted.nodes.position[a] - hinted.nodes.position[b]).normalize();
    hinted.nodes.velocity[a] = dir * 0.01;
    let mut plain = hinted.clone();
    plain.prepare().hints_enabled = false;
    let (mut corrections, mut uniform_steps) = (0, 0);
    for _ in 0..50 {
        let x = hinted.step(dt);
        assert_eq!(x, plain.step(dt));
        corrections += x.dispersion_corrections;
        let h = hinted.prepared.as_ref().unwrap();
        let spread = h.chunk_spread.iter().cloned().fold(0.0, f64::max);
        let floor = h.chunk_floor.iter().cloned().fold(f64::INFINITY, f64::min);
        uniform_steps += (4.0 * spread <= floor && x.dispersion_corrections > 0) as u32;
    }
    assert_eq!(hinted.nodes, plain.nodes);
    assert!(
        corrections > 0 && uniform_steps > 0,
        "{corrections} {uniform_steps}"
    );
}

#[test]
fn rigid_broad_phase_changes_no_bit() {
    use crate::solver::ContactPartner;
    // Node contact (floor, two walls, a capsule pressing down) and display-surface contact
    // (the floor and the capsule: the log takes the surface pass's forces), each stepped
    // with and without the rigid broad phase: the same state and contact records, bit for
    // bit.
    let (p, t) = box_mesh([0.0, 0.005, 0.0], [0.4, 0.405, 0.4]);
    let lattice = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(9),
            ..FitSettings::default()
        },
    )
    .unwrap();
    let m = Material::preset("rubber").unwrap();
    let bits = |w: &World| -> Vec<u64> {
        let n = &w.nodes;
        let all = n.position.iter().chain(&n.velocity);
        all.flat_map(|v| v.iter().map(|c| c.to_bits())).collect()
    };
    let records = |w: &World| -> Vec<_> {
        let r = w.frame_contacts().iter();
        r.map(|r| {
            let speeds = (r.impact_speed.to_bits(), r.peak_force.to_bits());
            (r.body, r.partner, speeds, r.touching_at_end)
        })
        .collect()
    };
    for surface in [false, true] {
        let mut planes = vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }];
        if !surface {
            planes.push(Plane {
                normal: -Vector3::x(),
                offset: -0.41,
            });
            planes.push(Plane {
                normal: Vector3::new(0.1, 0.2, 1.0).normalize(),
                offset: 0.003,
            });
        }
        let mut fast = World::new(WorldSettings {
            planes,
            layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
            ..WorldSettings::default()
        });
        let body = fast.add_lattice_body("cube", &lattice, &m, Vector3::new(0.3, -0.5, 0.0));
        if surface {
            let (samples, areas) = crate::lattice::surface_samples(&p, &t, 0.05);
            fast.add_contact_surface(body, &lattice, &samples, &areas);
        }
        fast.live_capsules.push(Capsule {
            centre: Vector3::new(0.2, 0.44, 0.2),
            axis: Vector3::x(),
            length: 0.2,
            radius: 0.05,
            velocity: Vector3::new(0.0, -0.3, 0.0),
            friction: 0.3,
        });
        let mut full = fast.clone();
        full.prepare().rigid_broad_phase = false;
        let mut partners = Vec::new();
        for frame in 1..=6 {
            for w in [&mut fast, &mut full] {
                w.live_capsules.iter_mut().for_each(|c| c.centre.y -= 0.004);
            }
            let a = fast.advance_frame(1.0 / 120.0, frame, &|| false).unwrap();
            let b = full.advance_frame(1.0 / 120.0, frame, &|| false).unwrap();
            assert_eq!(a.max_penetration.to_bits(), b.max_penetration.to_bits());
            assert_eq!(
                a.manipulator_reaction.map(f64::to_bits),
                b.manipulator_reaction.map(f64::to_bits)
            );
            assert_eq!(records(&fast), records(&full), "surface {surface}");
            assert_eq!(bits(&fast), bits(&full), "surface {surface}");
            partners.extend(fast.frame_contacts().iter().map(|r| r.partner));
        }
        // The scene exercises every partner, and the broad phase skipped blocks.
        assert!(partners.contains(&ContactPartner::Floor), "{partners:?}");
        assert!(
            partners.contains(&ContactPartner::Manipulator(0)),
            "{partners:?}"
        );
        if !surface {
            assert!(partners.contains(&ContactPartner::Wall), "{partners:?}");
            let near = fast.prepare().block_near.clone();
            assert!(near.contains(&false) && near.contains(&true), "{near:?}");
        }
    }
}

#[test]
fn active_set_sweeps_match_full_sweeps_bit_for_bit() {
    // The later dispersion sweeps visit only the springs at changed nodes; through the
    // thrown cube's impact the result must be exactly that of sweeps reading every
    // spring's stamps.
    let (cube, _, _) = soft_cube_thrown_at_wall();
    let (mut active, mut stamps, dt) = with_twin(cube, |p| p.active_set_enabled = false);
    let mut multi_sweep_steps = 0;
    for _ in 0..600 {
        let a = active.step(dt);
        assert_eq!(a, stamps.step(dt));
        multi_sweep_steps += (a.dispersion_iterations >= 2) as u32;
    }
    assert_eq!(active.nodes, stamps.nodes);
    assert!(
        multi_sweep_steps > 0,
        "the impact must need later sweeps for the comparison to mean anything"
    );
}

#[test]
fn the_stencil_pass_follows_the_index_lists() {
    // The thrown cube with its springs by stencil and by index lists: each step's
    // dispersion hints are the same bits (per-spring arithmetic is the same), and the
    // motion through the impact agrees to rounding (node sums add in another order).
    let (cube, _, _) = soft_cube_thrown_at_wall();
    let (mut stencil, mut lists, dt) = with_twin(cube, |p| p.stencil_enabled = false);
    assert!(
        stencil.prepare().stencil.is_some(),
        "a lattice body uses the stencil"
    );
    let hints = |w: &World| {
        let p = w.prepared.as_ref().unwrap();
        let floor = p.chunk_floor.iter().fold(f64::INFINITY, |m, &f| m.min(f));
        // The stencil copies its flags out only when the dispersion reads them.
        let mut exceptional = p.exceptional.clone();
        if let Some(plan) = p.stencil.as_ref().filter(|_| p.stencil_enabled) {
            plan.write_flags(&mut exceptional);
        }
        (exceptional, floor)
    };
    let mut corrections = 0;
    for step in 0..600 {
        let a = stencil.step(dt);
        lists.step(dt);
        if step == 0 {
            assert_eq!(hints(&stencil), hints(&lists));
        }
        corrections += a.dispersion_corrections;
    }
    assert!(corrections > 0, "the impact must need the fusion model");
    let worst = (0..stencil.nodes.len())
        .map(|i| (stencil.nodes.position[i] - lists.nodes.position[i]).norm())
        .fold(0.0f64, f64::max);
    // Measured 0.6 µm: the impact's thresholded dispersion amplifies last-bit
    // differences. A spring missing or wrong in the stencil moves nodes by millimetres.
    assert!(
        worst < 1e-5,
        "positions differ by {worst} m after the impact"
    );
}

#[test]
fn neighbour_lists_find_the_contacts_a_grid_search_finds() {
    // Three rubber boxes: one resting on the floor, one dropped onto it off-centre, one
    // thrown sideways into both at 6 m/s (fast enough to cross a layer in a few substeps);
    // and apart from them two boxes a centimetre apart thrown down together (their lists
    // outlive the fall: they move together). Stepped with the body contact's neighbour lists
    // and with every list rebuilt each step (the grid search alone), the nodes agree to
    // rounding (a tie between two faces at the same distance may go the other way).
    let m = Material::preset("rubber").unwrap();
    let down = Vector3::new(0.0, -2.0, 0.0);
    let boxes = [
        ([0.0, 0.0, 0.0], [0.4, 0.3, 0.4], Vector3::zeros()),
        ([0.1, 0.32, 0.1], [0.3, 0.52, 0.3], Vector3::zeros()),
        (
            [-0.5, 0.05, 0.05],
            [-0.25, 0.25, 0.3],
            Vector3::new(4.0, 0.5, 0.0),
        ),
        ([1.0, 0.3, 0.0], [1.2, 0.5, 0.2], down),
        ([1.21, 0.3, 0.0], [1.41, 0.5, 0.2], down),
    ];
    let mut lists = xpbd_over_floor(0.1, &m);
    for (k, (lo, hi, v)) in boxes.into_iter().enumerate() {
        add_box_body(&mut lists, &format!("box{k}"), (lo, hi), 4, &m, v);
    }
    let mut grid = lists.clone();
    grid.body_contact.lists_off = true;
    let dt = lists.choose_substeps(1.0 / 24.0).dt;
    let mut touched = 0;
    for _ in 0..1200 {
        lists.step(dt);
        grid.step(dt);
        let constrained = !lists.body_contact.constraints().0.is_empty();
        touched += usize::from(lists.body_contact.active || constrained);
        let apart = lists.nodes.position.iter().zip(&grid.nodes.position);
        let worst = apart.map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "{worst} m apart");
    }
    // The boxes met, for most of the run.
    assert!(touched > 200, "{touched} steps in contact");
}

#[test]
fn contacts_left_out_in_front_would_not_have_acted() {
    // A 3 × 2 pile of rubber boxes 1 cm apart side by side, its upper layer 1 cm above the
    // lower, dropped onto the floor from 5 cm: the sides' samples find their neighbours'
    // faces within the constraints' reach all the way down. Stepped with the contacts beyond
    // `CONSTRAINT_FRONT` left out and with every one kept as a constraint: the same bits.
    let m = Material::preset("rubber").unwrap();
    let mut kept = xpbd_over_floor(0.2 / 3.0, &m);
    for (i, layer) in [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1)] {
        let x = i as f64 * 0.21;
        let y = 0.05 + layer as f64 * 0.21;
        let corners = ([x, y, 0.0], [x + 0.2, y + 0.2, 0.2]);
        add_box_body(
            &mut kept,
            &format!("box{i}_{layer}"),
            corners,
            3,
            &m,
            Vector3::zeros(),
        );
    }
    let mut all = kept.clone();
    all.body_contact.front_off = true;
    let dt = kept.choose_substeps(1.0 / 24.0).dt;
    let (mut fewer, mut touched) = (0, 0);
    for _ in 0..720 {
        kept.step(dt);
        all.step(dt);
        let (left, every) = (
            kept.body_contact.constraints().0.len(),
            all.body_contact.constraints().0.len(),
        );
        fewer += usize::from(left < every);
        touched += usize::from(kept.body_contact.touches_others() && left > 0);
        assert_eq!(kept.nodes.position, all.nodes.position);
    }
    // Most steps left contacts out, and the boxes met.
    assert!(fewer > 600, "{fewer} steps with fewer constraints");
    assert!(touched > 100, "{touched} steps with constraints");
}

#[test]
fn resting_rigid_pairs_keep_their_contacts_and_rest_where_they_would() {
    // Three wooden boxes (held rigid) stacked 1 cm apart, each shifted 2 cm, dropped onto the
    // floor. Stepped with the contacts of pairs at rest kept from pass to pass and with every
    // pair searched each pass: most passes keep the pairs' contacts once the stack has
    // landed, and the boxes end within 2 µm of where the other run puts them (0.14 µm).
    let m = Material::preset("wood").unwrap();
    let mut kept = xpbd_over_floor(0.03, &m);
    for i in 0..3 {
        let (x, y) = (0.02 * i as f64, 0.005 + 0.31 * i as f64);
        let corners = ([x, y, 0.0], [x + 0.3, y + 0.3, 0.3]);
        add_box_body(
            &mut kept,
            &format!("box{i}"),
            corners,
            10,
            &m,
            Vector3::zeros(),
        );
    }
    let mut searched = kept.clone();
    searched.body_contact.still_off = true;
    let dt = kept.choose_substeps(1.0 / 24.0).dt;
    let steps = (1.5 / dt) as usize;
    let mut keeping = 0;
    for step in 0..steps {
        kept.step(dt);
        searched.step(dt);
        assert_eq!(searched.body_contact.kept_pairs, 0);
        if step > steps / 2 {
            keeping += usize::from(kept.body_contact.kept_pairs == 2);
        }
    }
    assert!(
        keeping > steps / 4,
        "{keeping} of the last {} passes kept both pairs",
        steps / 2
    );
    let apart = kept.nodes.position.iter().zip(&searched.nodes.position);
    let worst = apart.map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(worst < 2e-6, "{worst} m apart");
}

#[test]
fn a_rubber_box_off_centre_on_another_rocks_less_with_the_second_sweep() {
    // Two 30 cm rubber boxes, the upper one 4 cm off-centre and 1 cm above, dropped onto the
    // floor; the peak-to-peak of the upper box's centre along x over frames 12 to 48 (the
    // CLI at `cells = 8`: 10.7 mm and 8.0 mm over the two halves with one sweep a substep,
    // 6.5 and 4.8 with the second sweep behind the contacts).
    let m = Material::preset("rubber").unwrap();
    let mut two = xpbd_over_floor(0.3 / 8.0, &m);
    for i in 0..2 {
        let (x, y) = (0.04 * i as f64, 0.005 + 0.31 * i as f64);
        let corners = ([x, y, 0.0], [x + 0.3, y + 0.3, 0.3]);
        add_box_body(
            &mut two,
            &format!("box{i}"),
            corners,
            8,
            &m,
            Vector3::zeros(),
        );
    }
    let mut one = two.clone();
    one.body_contact.one_sweep = true;
    let sway = |w: &mut World| {
        let dt = w.choose_substeps(1.0 / 24.0).dt;
        let steps = (1.0 / 24.0 / dt).round() as usize;
        let upper = w.bodies[1].nodes.clone();
        let mut xs = Vec::new();
        for frame in 0..48 {
            for _ in 0..steps {
                w.step(dt);
            }
            let centre = w.nodes.position[upper.clone()]
                .iter()
                .map(|p| p.x)
                .sum::<f64>();
            if frame >= 12 {
                xs.push(centre / upper.len() as f64);
            }
        }
        let (lo, hi) = xs
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        hi - lo
    };
    let (with, without) = (sway(&mut two), sway(&mut one));
    assert!(
        with < 0.75 * without,
        "{:.1} mm peak to peak, {:.1} mm with one sweep",
        with * 1e3,
        without * 1e3
    );
}

#[test]
fn a_rubber_box_resting_centred_on_another_stays_put_at_high_friction() {
    // A 20 cm rubber box dropped 1 cm onto the middle of a 30 cm one, friction 2 (rubber on
    // rubber). One pass over the body–body constraints a substep pushed the contacts that
    // share nodes apart too far, the sweep pulled them back, and the friction let the slip
    // through: the upper box wandered 3.8 mm in these 2 s (the CLI at `cells = 10`: 99 mm).
    // With the passes that take the pushes back: 0.95 mm.
    let m = Material::preset("rubber").unwrap();
    let mut world = xpbd_over_floor(0.3 / 8.0, &m);
    world.settings.layer.friction = 2.0;
    add_box_body(
        &mut world,
        "lower",
        ([0.0, 0.005, 0.0], [0.3, 0.305, 0.3]),
        8,
        &m,
        Vector3::zeros(),
    );
    add_box_body(
        &mut world,
        "upper",
        ([0.05, 0.315, 0.05], [0.25, 0.515, 0.25]),
        8,
        &m,
        Vector3::zeros(),
    );
    let dt = world.choose_substeps(1.0 / 24.0).dt;
    let steps = (1.0 / 24.0 / dt).round() as usize;
    let centre = |w: &World, b: usize| {
        let nodes = &w.nodes.position[w.bodies[b].nodes.clone()];
        nodes.iter().sum::<Vector3<f64>>() / nodes.len() as f64
    };
    let apart = |w: &World| {
        let d = centre(w, 1) - centre(w, 0);
        Vector3::new(d.x, 0.0, d.z)
    };
    let start = apart(&world);
    let mut wandered = 0.0f64;
    for _ in 0..48 {
        for _ in 0..steps {
            world.step(dt);
        }
        wandered = wandered.max((apart(&world) - start).norm());
    }
    assert!(
        wandered < 0.002,
        "the upper box wandered {:.1} mm",
        wandered * 1e3
    );
}

/// An XPBD world over a floor at height 0, its contact layer the default for cells of `cell`
/// metres of `material` (friction 0.4).
fn xpbd_over_floor(cell: f64, material: &Material) -> World {
    World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: WorldSettings::default_layer(cell, material, 0.4),
        integrator: Integrator::Xpbd,
        ..WorldSettings::default()
    })
}

/// Add a box `(lo, hi)` at `cells` cells along its longest side, moving at `velocity`, with
/// its contact samples and collision surface (it touches the world's other bodies).
fn add_box_body(
    world: &mut World,
    name: &str,
    (lo, hi): ([f64; 3], [f64; 3]),
    cells: u32,
    material: &Material,
    velocity: Vector3<f64>,
) {
    let (p, t) = box_mesh(lo, hi);
    let settings = FitSettings {
        resolution: Resolution::CellsAlongLongest(cells),
        ..FitSettings::default()
    };
    let lattice = fit_lattice(&p, &t, &settings).unwrap();
    let body = world.add_lattice_body(name, &lattice, material, velocity);
    let (samples, areas) = crate::lattice::surface_samples(&p, &t, 0.5 * lattice.cell_size);
    world.add_contact_surface(body, &lattice, &samples, &areas);
    world.add_collision_surface(body, &lattice, &p, &t);
}

/// A world gets a thread per 2048 of its parallel size, at least one, at most what the pool
/// has: the standard scene's 4096 XPBD nodes eight threads, a 1331-node cube two, a 613-node
/// demo one, a 64³ lattice every thread of a 16-core machine.
#[test]
fn worlds_get_threads_by_their_size() {
    assert_eq!(threads_for(613 * XPBD_PARALLEL_WEIGHT, 16), 1);
    assert_eq!(threads_for(1331 * XPBD_PARALLEL_WEIGHT, 2), 2);
    assert_eq!(threads_for(4096 * XPBD_PARALLEL_WEIGHT, 16), 8);
    assert_eq!(threads_for(4096 * XPBD_PARALLEL_WEIGHT, 2), 2);
    assert_eq!(threads_for(65 * 65 * 65 * XPBD_PARALLEL_WEIGHT, 16), 16);
    assert_eq!(threads_for(10, 0), 1);
}

/// A pool sized for a world is built once and kept: the second ask gets the same pool.
#[test]
fn sized_pools_are_built_once() {
    let a = sized_pool(1).expect("one thread");
    let b = sized_pool(1).expect("one thread");
    assert!(std::ptr::eq(a, b));
    assert_eq!(a.current_num_threads(), 1);
}

/// A frame taken again from the copy [`World::redo_point`] keeps gives the bits of the same
/// frame run from a whole copy of the world, after the world had gone on in between: what the
/// copy leaves out (springs, rest positions, cells) is what no frame changes. Two jelly boxes,
/// the upper thrown down onto the lower one, frame after frame through the impact.
#[test]
fn a_frame_taken_again_from_its_copy_is_the_frame_run_afresh() {
    let jelly = Material::preset("jelly").unwrap();
    let mut world = xpbd_over_floor(0.05, &jelly);
    let (low, high) = (
        ([-0.2, 0.01, -0.2], [0.2, 0.31, 0.2]),
        ([-0.1, 0.36, -0.1], [0.1, 0.56, 0.1]),
    );
    add_box_body(&mut world, "low", low, 6, &jelly, Vector3::zeros());
    let down = Vector3::new(0.0, -4.0, 0.0);
    add_box_body(&mut world, "high", high, 4, &jelly, down);
    let frame = 1.0 / 24.0;
    let mut touched = false;
    for f in 1..=4 {
        let n = world.choose_substeps(frame).substeps;
        let mut afresh = world.clone();
        let start = world.redo_point().expect("a fast frame keeps a copy");
        for _ in 0..5 {
            world.step(frame / f64::from(n));
        }
        world.redo_from(&start);
        for w in [&mut world, &mut afresh] {
            w.settings.fixed_substeps = Some(2 * n);
        }
        let again = world.advance_frame(frame, f, &|| false).unwrap();
        let fresh = afresh.advance_frame(frame, f, &|| false).unwrap();
        assert_eq!(format!("{again:?}"), format!("{fresh:?}"), "frame {f}");
        assert_eq!(world.nodes.position, afresh.nodes.position, "frame {f}");
        assert_eq!(world.nodes.velocity, afresh.nodes.velocity, "frame {f}");
        world.settings.fixed_substeps = None;
        let partner = super::super::contact_log::ContactPartner::Body(1);
        touched |=
            (world.contact_log.records().iter()).any(|r| r.body == 0 && r.partner == partner);
    }
    assert!(touched, "the boxes never met");
}
