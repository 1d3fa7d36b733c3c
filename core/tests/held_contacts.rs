//! The XPBD solver (issue 16) with held and rigid bodies in contact: a stiff box resting on
//! another, sliding and landing on a collider by Coulomb's law, feeling friction at its
//! bounce, resting on and sliding over a held slab, settling in a groove, and a crooked stack
//! of steel boxes standing on the floor and on a collider, a wooden box staying put under a
//! rubber box. Scenes are set up as the product sets up a mesh (`support::product_world`,
//! `support::add_part`).
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{BodyHandle, FrameDiagnostics, Integrator, World};
use support::{add_part, floored_parts_world, mesh, product_world, Mesh};

const FRAME: f64 = 1.0 / 24.0;

/// An XPBD world holding `m` in `material` at `velocity`, with a floor at y = 0 when `floor`.
fn world(m: &Mesh, material: &Material, velocity: Vector3<f64>, floor: bool) -> World {
    product_world(m, material, Integrator::Xpbd, velocity, floor)
}

fn frame(w: &mut World, f: usize) -> FrameDiagnostics {
    w.advance_frame(FRAME, f, &|| false).unwrap()
}

/// A wooden or steel box set a centimetre above another (both held rigid: far too stiff for
/// their cells), or a rigid one (`kind = "rigid"`) above another, lands on it and rests there.
/// A contact moved only the nodes round its point and the shape matching spread that over the
/// box, a tenth of what the contact asked (a rigid body took it as those nodes' momentum):
/// the upper box sank through the lower one and came to rest inside it.
#[test]
fn a_stiff_or_rigid_box_rests_on_another() {
    for preset in ["wood", "steel", "rigid"] {
        let material = Material::preset(if preset == "rigid" { "rubber" } else { preset });
        let material = material.unwrap();
        let (size, gap, cells) = (0.3, 0.01, 6);
        let mut w = floored_parts_world(&material);
        let mut boxes = Vec::new();
        for i in 0..2 {
            let y0 = gap + i as f64 * (size + gap);
            let m = mesh(box_mesh([0.0, y0, 0.0], [size, y0 + size, size]), cells);
            boxes.push(add_part(&mut w, &format!("box{i}"), &m, &material));
        }
        if preset == "rigid" {
            for &b in &boxes {
                w.make_rigid(b).unwrap();
            }
        } else {
            assert_eq!(w.held_bodies().len(), 2, "{preset}: both held");
        }
        let lowest = |w: &World, h: BodyHandle| {
            (w.body_positions(h).iter()).fold(f64::INFINITY, |lo, p| lo.min(p.y))
        };
        let highest = |w: &World, h: BodyHandle| {
            (w.body_positions(h).iter()).fold(f64::NEG_INFINITY, |hi, p| hi.max(p.y))
        };
        // The lattices overhang the meshes alike, so their nodes' gap is the meshes' gap.
        let apart0 = lowest(&w, boxes[1]) - highest(&w, boxes[0]);
        for f in 1..=36 {
            let d = frame(&mut w, f);
            // 2 cm of fall is 0.63 m/s.
            assert!(
                d.max_speed < 1.0,
                "{preset}, frame {f}: {} m/s",
                d.max_speed
            );
        }
        let apart = lowest(&w, boxes[1]) - highest(&w, boxes[0]);
        let layer = w.settings.layer.thickness_m;
        assert!(
            apart > apart0 - gap - 0.5 * layer && apart < apart0,
            "{preset}: the upper box's nodes end {apart} m above the lower's (at the start \
             {apart0} m; layer {layer} m)"
        );
    }
}

/// A 30 cm wooden (held) or rigid box on a ground plane collider, `height` m above it at
/// `velocity`: the mean of its nodes at the start and after each of `frames` frames.
/// A ground plane collider at y = 0 (one open quad, 6 m wide, friction 0.4).
fn add_ground_plane(w: &mut World) {
    use springbake_core::collide::StaticCollider;
    let points = [
        [-3.0, 0.0, -3.0],
        [3.0, 0.0, -3.0],
        [3.0, 0.0, 3.0],
        [-3.0, 0.0, 3.0],
    ]
    .map(|[x, y, z]| Point3::new(x, y, z));
    let triangles = [[0, 2, 1], [0, 3, 2]];
    w.add_collider(StaticCollider::new("ground", &points, &triangles, 0.4).unwrap());
}

fn box_on_a_ground_plane(
    preset: &str,
    height: f64,
    velocity: Vector3<f64>,
    frames: usize,
) -> Vec<Vector3<f64>> {
    let material = Material::preset(if preset == "rigid" { "rubber" } else { preset }).unwrap();
    let m = mesh(
        box_mesh([-0.15, height, -0.15], [0.15, height + 0.3, 0.15]),
        6,
    );
    let mut w = world(&m, &material, velocity, false);
    if preset == "rigid" {
        w.make_rigid(BodyHandle(0)).unwrap();
    } else {
        assert_eq!(w.held_bodies().len(), 1, "{preset}: held");
    }
    add_ground_plane(&mut w);
    let n = w.nodes.position.len() as f64;
    let mut centres = vec![w.nodes.position.iter().sum::<Vector3<f64>>() / n];
    for f in 1..=frames {
        frame(&mut w, f);
        centres.push(w.nodes.position.iter().sum::<Vector3<f64>>() / n);
    }
    centres
}

/// A held or rigid body on a static collider slides by Coulomb's law and lands flat as on
/// the floor. Through its nodes, a collider's push moved only the eight round the point, and
/// friction bounded by the depths it sank to held the box far harder than μ = 0.4: here a
/// wooden box sliding at 2 m/s stopped in 0.07 m (0.14 m through the CLI, a rigid one 0.25 m),
/// where v²/(2μg) is 0.51 m; and a rigid box dropped onto the plane sank through it.
#[test]
fn a_stiff_or_rigid_box_slides_and_lands_on_a_collider_as_on_the_floor() {
    let coulomb = 2.0f64.powi(2) / (2.0 * 0.4 * 9.81);
    for preset in ["wood", "rigid"] {
        let slid = box_on_a_ground_plane(preset, 0.0, Vector3::new(2.0, 0.0, 0.0), 24);
        let distance = slid[24].x - slid[0].x;
        assert!(
            (0.9 * coulomb..1.2 * coulomb).contains(&distance),
            "{preset}: slid {distance} m, Coulomb {coulomb} m"
        );
        let dropped = box_on_a_ground_plane(preset, 0.2, Vector3::zeros(), 36);
        let rest = dropped[36];
        assert!(
            rest.x.abs() < 1e-3 && rest.z.abs() < 1e-3,
            "{preset}: landed flat and moved sideways to {rest:?}"
        );
        // The lattice overhangs the box by at most a cell: its centre is 0.15 m up.
        assert!(
            (0.13..0.17).contains(&rest.y),
            "{preset}: rests with its centre {} m above the plane",
            rest.y
        );
    }
}

/// Friction acts on a stiff body's bounce as on its landing: the restitution's impulse is
/// bounded by Coulomb's law like the contact's. Without it a steel box thrown at 2 m/s from
/// 30 cm onto the floor hopped on at 2 m/s for a second and came to rest 3.9 m away (a wooden
/// one 2.1 m), where a box that kept no bounce would stop within 0.9 m; and a wooden box
/// landing from 2 mm on a 30° slope (a ground plane collider under gravity turned 30°) slid
/// 13 % farther in a second than Coulomb's law lets it.
#[test]
fn a_stiff_box_bouncing_on_the_floor_or_a_collider_feels_friction() {
    for preset in ["wood", "steel"] {
        let material = Material::preset(preset).unwrap();
        let m = mesh(box_mesh([-0.15, 0.3, -0.15], [0.15, 0.6, 0.15]), 10);
        let mut w = world(&m, &material, Vector3::new(2.0, 0.0, 0.0), true);
        let n = w.nodes.position.len() as f64;
        let start = w.nodes.position.iter().sum::<Vector3<f64>>() / n;
        for f in 1..=48 {
            frame(&mut w, f);
        }
        let rest = w.nodes.position.iter().sum::<Vector3<f64>>() / n;
        let travelled = rest.x - start.x;
        assert!(
            (0.5..1.5).contains(&travelled),
            "{preset}: thrown at 2 m/s, came to rest {travelled} m away"
        );
    }
    let material = Material::preset("wood").unwrap();
    let m = mesh(box_mesh([-0.15, 0.002, -0.15], [0.15, 0.302, 0.15]), 10);
    let mut w = world(&m, &material, Vector3::zeros(), false);
    let slope = 30f64.to_radians();
    w.settings.gravity = Vector3::new(slope.sin(), -slope.cos(), 0.0) * 9.81;
    add_ground_plane(&mut w);
    let n = w.nodes.position.len() as f64;
    let start = w.nodes.position.iter().sum::<Vector3<f64>>() / n;
    for f in 1..=23 {
        frame(&mut w, f);
    }
    let slid = (w.nodes.position.iter().sum::<Vector3<f64>>() / n).x - start.x;
    // Sliding from rest for 23/24 s at g (sin 30° − 0.4 cos 30°).
    let coulomb = 0.5 * 9.81 * (slope.sin() - 0.4 * slope.cos()) * (23.0f64 / 24.0).powi(2);
    assert!(
        (coulomb..1.1 * coulomb).contains(&slid),
        "slid {slid} m down the slope, Coulomb {coulomb} m"
    );
}

/// A wooden or steel box (held rigid) set 1 mm above a slab of its material (held too) stays
/// where it is, and slid over the slab at 2 m/s it stops in Coulomb's distance without
/// rearing up. The slab's points that start within its contact layer are parted as a whole
/// body's move; each of them asked the whole box to move, and their moves were summed: the
/// box was moved 19 cm up at the first substep and fell back. The slab's points just ahead of
/// the sliding box's front edge met that edge with the direction to it, nearly level: the box
/// reared up on its back edge and stopped in 0.3 m. They take the slab's own normal now.
#[test]
fn a_held_box_rests_on_and_slides_over_a_held_slab() {
    for preset in ["wood", "steel"] {
        let material = Material::preset(preset).unwrap();
        let m = mesh(box_mesh([-0.15, 0.101, -0.15], [0.15, 0.401, 0.15]), 10);
        let slab = mesh(box_mesh([-1.5, 0.0, -0.5], [1.5, 0.1, 0.5]), 30);
        for speed in [0.0, 2.0] {
            let mut w = world(&m, &material, Vector3::new(speed, 0.0, 0.0), true);
            add_part(&mut w, "slab", &slab, &material);
            let count = m.lattice.rest_positions.len();
            let centre = |w: &World| w.nodes.position[..count].iter().sum::<Vector3<f64>>();
            let start = centre(&w) / count as f64;
            let mut highest = start.y;
            for f in 1..=24 {
                frame(&mut w, f);
                highest = highest.max(centre(&w).y / count as f64);
            }
            let moved = centre(&w) / count as f64 - start;
            let coulomb = speed * speed / (2.0 * 0.4 * 9.81);
            assert!(
                highest - start.y < 0.005,
                "{preset} at {speed} m/s: rose {} m",
                highest - start.y
            );
            assert!(
                (moved.x - coulomb).abs() < 0.05 * coulomb + 0.003 && moved.z.abs() < 0.003,
                "{preset} at {speed} m/s: moved {moved:?}, Coulomb {coulomb} m"
            );
        }
    }
}

/// A wooden box dropped into a V-shaped groove (one open mesh of two 45° walls) lands in it
/// and settles without gaining energy. A corner pushed past the groove's bottom met the far
/// wall from behind, and that face's push, taken by the whole rigid body, threw the box a
/// metre along the groove (12 J gained in a frame).
#[test]
fn a_wooden_box_dropped_into_a_groove_settles_in_it() {
    use springbake_core::collide::StaticCollider;
    let material = Material::preset("wood").unwrap();
    let m = mesh(box_mesh([-0.1, 0.4, -0.1], [0.1, 0.6, 0.1]), 10);
    let mut w = world(&m, &material, Vector3::zeros(), false);
    let points = [
        [-0.7, 0.7, -1.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 1.0],
        [-0.7, 0.7, 1.0],
        [0.7, 0.7, -1.0],
        [0.7, 0.7, 1.0],
    ]
    .map(|[x, y, z]| Point3::new(x, y, z));
    let triangles = [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]];
    w.add_collider(StaticCollider::new("groove", &points, &triangles, 0.4).unwrap());
    let n = w.nodes.position.len() as f64;
    for f in 1..=36 {
        let d = frame(&mut w, f);
        assert!(
            d.energy_gain.unwrap_or(0.0) <= 0.0,
            "frame {f}: {:?} J gained",
            d.energy_gain
        );
    }
    let centre = w.nodes.position.iter().sum::<Vector3<f64>>() / n;
    // At rest on both walls (flat on one, or turned 45° flat on both) its centre is 0.1 to
    // 0.15 m up, over the groove's bottom; on its two bottom edges, one on each wall, 0.2 m
    // (the walls' normals there meet at its centre, so friction holds it, as it does since
    // its bounces feel friction).
    assert!(
        centre.x.abs() < 0.02 && centre.z.abs() < 0.1 && (0.09..0.21).contains(&centre.y),
        "the box ends at {centre:?}"
    );
    let fastest = (w.nodes.velocity.iter()).fold(0.0f64, |m, v| m.max(v.norm()));
    assert!(fastest < 0.01, "the box still moves at {fastest} m/s");
}

/// Five steel boxes (30 cm, held rigid) stacked a centimetre apart on the floor or on a
/// static collider, each 2 cm further along x than the one below and every other one turned
/// 0.25 rad about the vertical, settle and stand: the stack's weight lies well inside each
/// box's support. Each contact moving the boxes in full before the next, the first ones
/// tilted a box and the rest tilted it back a little differently each substep, and the
/// floor, solved after the boxes, turned the bottom one back under the others: the stack
/// walked sideways and fell within a second. On the collider, the bottom box was pushed
/// back up into the one above, which sank into it.
#[test]
fn a_crooked_stack_of_steel_boxes_stands_on_the_floor_and_on_a_collider() {
    use springbake_core::collide::StaticCollider;
    let steel = Material::preset("steel").unwrap();
    let boxes: Vec<Mesh> = (0..5)
        .map(|i| {
            let (mut points, triangles) = box_mesh([-0.15, 0.0, -0.15], [0.15, 0.3, 0.15]);
            let (turn, y0) = (if i % 2 == 1 { 0.25f64 } else { 0.0 }, 0.31 * i as f64);
            for p in &mut points {
                let (x, z) = (p.x, p.z);
                p.x = turn.cos() * x - turn.sin() * z + 0.02 * i as f64;
                p.z = turn.sin() * x + turn.cos() * z;
                p.y += y0;
            }
            mesh((points, triangles), 6)
        })
        .collect();
    for on_floor in [true, false] {
        let mut w = world(&boxes[0], &steel, Vector3::zeros(), on_floor);
        if !on_floor {
            let (points, triangles) = box_mesh([-1.0, -0.2, -1.0], [1.0, 0.0, 1.0]);
            let table = StaticCollider::new("table", &points, &triangles, 0.4).unwrap();
            w.add_collider(table);
        }
        let handles: Vec<BodyHandle> = std::iter::once(BodyHandle(0))
            .chain(
                boxes[1..]
                    .iter()
                    .enumerate()
                    .map(|(i, m)| add_part(&mut w, &format!("box{}", i + 1), m, &steel)),
            )
            .collect();
        let centre = |w: &World, h: BodyHandle| {
            let xs = w.body_positions(h);
            xs.iter().sum::<Vector3<f64>>() / xs.len() as f64
        };
        let start: Vec<_> = handles.iter().map(|&h| centre(&w, h)).collect();
        let mut settled = start.clone();
        for f in 1..=36 {
            frame(&mut w, f);
            if f == 12 {
                settled = handles.iter().map(|&h| centre(&w, h)).collect();
            }
        }
        for (i, ((&h, s), at_12)) in handles.iter().zip(&start).zip(&settled).enumerate() {
            let moved = centre(&w, h) - s;
            // Each box falls the centimetre gaps below it, and no box slides.
            let fell = 0.01 * i as f64;
            assert!(
                (moved.y + fell).abs() < 0.01 && moved.x.abs().max(moved.z.abs()) < 0.005,
                "on the floor: {on_floor}; box {i} moved {moved:?}"
            );
            // Settled by frame 12, no box creeps afterwards.
            let crept = centre(&w, h) - at_12;
            assert!(
                crept.norm() < 2e-4,
                "on the floor: {on_floor}; box {i} crept {crept:?} after frame 12"
            );
        }
    }
}

/// A rubber box set 4 cm off-centre on a wooden box on the floor: the wooden box stays put.
/// Pressed down off-centre by the rubber box each substep, the wooden box (held rigid) was
/// turned back by the floor's later stage, and the rubber box, held to it by friction, rode
/// that turn: from frame 12 to 48 the wooden box walked 4.8 mm along the overhang and the
/// rubber box 20 mm. The rubber box still creeps a little over the still box here (3 mm;
/// none at the product's contact layer: `springbake bake` of the same boxes).
#[test]
fn a_wooden_box_under_a_rubber_box_stays_put() {
    let (rubber, wood) = (
        Material::preset("rubber").unwrap(),
        Material::preset("wood").unwrap(),
    );
    let mut w = floored_parts_world(&rubber);
    let lower = mesh(box_mesh([-0.15, 0.005, -0.15], [0.15, 0.305, 0.15]), 6);
    let upper = mesh(box_mesh([-0.11, 0.315, -0.15], [0.19, 0.615, 0.15]), 6);
    let handles = [
        add_part(&mut w, "wood", &lower, &wood),
        add_part(&mut w, "rubber", &upper, &rubber),
    ];
    assert_eq!(w.held_bodies().len(), 1, "the wooden box is held");
    let centre = |w: &World, h: BodyHandle| {
        let xs = w.body_positions(h);
        xs.iter().sum::<Vector3<f64>>() / xs.len() as f64
    };
    let mut settled = Vec::new();
    for f in 1..=48 {
        frame(&mut w, f);
        if f == 12 {
            settled = handles.iter().map(|&h| centre(&w, h)).collect();
        }
    }
    for ((&h, at_12), (name, most)) in handles
        .iter()
        .zip(&settled)
        .zip([("wood", 2e-4), ("rubber", 5e-3)])
    {
        let crept = centre(&w, h) - at_12;
        let sideways = crept.x.hypot(crept.z);
        assert!(
            sideways < most,
            "the {name} box crept {crept:?} after frame 12"
        );
    }
}
