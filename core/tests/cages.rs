//! Analysis models besides the lattice (issue 7): primitive, plane, decimated and explicit
//! cages (counts, volumes, real-unit masses and stiffness, the barycentric embedding), a cage
//! body resting on the floor, `kind = "particle"`, shared joint nodes of articulated bodies and
//! per-region mass and stiffness.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::cage::{self, mesh_volume, Cage, Primitive};
use springbake_core::lattice::{surface_samples, Lattice};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Matrix3, Point3, Vector3};
use springbake_core::shapes::{box_mesh, uv_sphere};
use springbake_core::solver::joints::{join_bodies_at, join_nodes};
use springbake_core::solver::regions::{apply_region, Region};
use springbake_core::solver::{
    nodes_in_box, BodyHandle, Integrator, Interpolation, Path, Plane, RigidBody, World,
    WorldSettings,
};
use support::{fitted_box, floor_settings};

fn jelly() -> Material {
    Material::preset("jelly").unwrap()
}

/// Σ k L² over the springs (for the isotropic-network identity Σ k L² = 6 E V).
fn sum_kl2(c: &Cage, springs: &[(u32, u32, f64, f64)]) -> f64 {
    springs
        .iter()
        .map(|&(a, b, k, _)| k * (c.nodes[a as usize] - c.nodes[b as usize]).norm_squared())
        .sum()
}

fn min_weight(c: &Cage, points: &[Point3<f64>]) -> f64 {
    let e = c.embed(points);
    for w in &e.weights {
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
    e.weights
        .iter()
        .flat_map(|w| w[..4].iter().copied())
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn primitive_cages_have_their_springs_volume_mass_and_stiffness() {
    let (p, t) = box_mesh([0.0, 0.0, 0.0], [0.4, 0.2, 0.3]);
    let m = jelly();
    let (hx, hy, hz) = (0.2, 0.1, 0.15);
    // (shape, nodes, springs = surface edges + spokes, tets, volume)
    let phi: f64 = (1.0 + 5f64.sqrt()) / 2.0;
    let expect = [
        (Primitive::Box, 9, 18 + 8, 12, 8.0 * hx * hy * hz),
        // The box corner (1,1,1) needs the unit octahedron scaled 3× (+1 %).
        (
            Primitive::Octahedron,
            7,
            12 + 6,
            8,
            4.0 / 3.0 * 3.03f64.powi(3) * hx * hy * hz,
        ),
        (Primitive::Icosahedron, 13, 30 + 12, 20, f64::NAN),
    ];
    for (shape, nodes, springs, tets, volume) in expect {
        let c = cage::primitive(shape, &p).unwrap();
        assert_eq!(c.nodes.len(), nodes, "{shape:?}");
        assert_eq!(c.springs.len(), springs, "{shape:?}");
        assert_eq!(c.tets.len(), tets, "{shape:?}");
        if volume.is_finite() {
            assert!(
                (c.volume() - volume).abs() < 1e-12,
                "{shape:?}: {}",
                c.volume()
            );
        } else {
            // The icosahedron contains the box: at least its volume, and no more than the
            // scaled regular icosahedron's circumscribed sphere would allow.
            assert!(c.volume() > 8.0 * hx * hy * hz);
            let circum = (1.0 + phi * phi).sqrt() / phi * 3f64.sqrt() * 1.01;
            assert!(c.volume() < 4.0 / 3.0 * std::f64::consts::PI * circum.powi(3) * hx * hy * hz);
        }
        // Every mesh vertex inside (barycentric weights ≥ 0, sum 1).
        assert!(min_weight(&c, &p) > -1e-9, "{shape:?}");
        // Real units: mass = density × mesh volume; isotropic-network stiffness Σ k L² = 6 E V.
        let v_mesh = mesh_volume(&p, &t);
        assert!((v_mesh - 0.024).abs() < 1e-12);
        let bp = c.body_parameters(&m, Some(v_mesh));
        let mass: f64 = bp.masses.iter().sum();
        assert!((mass - m.density_kg_m3 * 0.024).abs() < 1e-9, "{mass}");
        let e = sum_kl2(&c, &bp.springs) / (6.0 * c.volume());
        assert!((e / m.young_pa - 1.0).abs() < 1e-9, "{shape:?}: {e}");
        assert!(bp.springs.iter().all(|s| s.2 > 0.0 && s.3 > 0.0));
    }
}

#[test]
fn the_plane_cage_is_a_slab_of_kuhn_tets() {
    // A 1 m × 0.5 m sheet in the x–z plane (a flag).
    let p: Vec<Point3<f64>> = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.5], [0.0, 0.5]]
        .iter()
        .map(|q| Point3::new(q[0], 1.0, q[1]))
        .collect();
    let c = cage::plane(&p, 4).unwrap();
    // 5 × 3 nodes per sheet, two sheets; 4 × 2 cells of 6 tets.
    assert_eq!(c.nodes.len(), 30);
    assert_eq!(c.tets.len(), 48);
    // Edges: axis edges 24 + 20 + 15, one diagonal per face 16 + 12 + 10, a body diagonal
    // per cell 8 (a conforming split shares face diagonals between neighbours).
    assert_eq!(c.springs.len(), 59 + 38 + 8);
    // Thickness 5 % of the width.
    assert!(
        (c.volume() - 1.0 * 0.5 * 0.05).abs() < 1e-12,
        "{}",
        c.volume()
    );
    assert!(min_weight(&c, &p) > -1e-9);
    let ys: Vec<f64> = c.nodes.iter().map(|n| n.y).collect();
    assert!(ys
        .iter()
        .all(|&y| (y - 0.975).abs() < 1e-12 || (y - 1.025).abs() < 1e-12));
}

#[test]
fn the_embedding_is_exact_for_affine_motion() {
    let (p, _) = uv_sphere([0.1, 0.5, -0.2], 0.3, 8, 16);
    for c in [
        cage::primitive(Primitive::Icosahedron, &p).unwrap(),
        cage::primitive(Primitive::Octahedron, &p).unwrap(),
    ] {
        assert!(min_weight(&c, &p) > -1e-9, "{}: a vertex outside", c.model);
        let e = c.embed(&p);
        let a = Matrix3::new(1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 1.2);
        let b = Vector3::new(0.3, -1.0, 2.0);
        let moved: Vec<Point3<f64>> = c.nodes.iter().map(|x| Point3::from(a * x + b)).collect();
        for (i, q) in p.iter().enumerate() {
            let want = a * q.coords + b;
            assert!((e.point(i, &moved).coords - want).norm() < 1e-12);
        }
    }
}

#[test]
fn a_decimated_cage_hits_its_target_and_contains_the_mesh() {
    let (p, t) = uv_sphere([0.0, 1.0, 0.0], 0.5, 16, 32);
    let c = cage::decimated(&p, &t, 40).unwrap();
    let surface_nodes = c.nodes.len() - 1;
    assert!(
        (20..=40).contains(&surface_nodes),
        "{surface_nodes} nodes for a target of 40"
    );
    assert!(c.note.is_none(), "a sphere is star-shaped: {:?}", c.note);
    assert!(min_weight(&c, &p) > -1e-9);
    let v = mesh_volume(&p, &t);
    assert!(
        c.volume() > v && c.volume() < 1.6 * v,
        "{} vs {v}",
        c.volume()
    );
    // An open surface (no top) is not closed: the hull of the clusters is used, and noted.
    let (bp, bt) = box_mesh([0.0; 3], [1.0, 0.5, 0.5]);
    let open: Vec<[u32; 3]> = bt[..6].iter().chain(&bt[8..]).copied().collect();
    let c = cage::decimated(&bp, &open, 8).unwrap();
    assert!(c.note.is_some());
    assert!(min_weight(&c, &bp) > -1e-9);
    assert!(cage::decimated(&p, &t, 3).unwrap_err().field == "cage_vertices");
}

#[test]
fn explicit_models_check_their_input_and_name_the_field() {
    let nodes: Vec<Vector3<f64>> = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.2, 0.2, 0.2],
    ]
    .iter()
    .map(|p| Vector3::from(*p))
    .collect();
    let good = vec![
        [0, 1],
        [0, 2],
        [0, 3],
        [1, 2],
        [1, 3],
        [2, 3],
        [4, 0],
        [4, 1],
        [4, 2],
        [4, 3],
    ];
    let c = cage::explicit(&nodes, &good).unwrap();
    // The interior node is the fan's apex: 4 tets filling the hull (volume 1/6).
    assert_eq!(c.tets.len(), 4);
    assert!((c.volume() - 1.0 / 6.0).abs() < 1e-12);
    let bp = c.body_parameters(&jelly(), None);
    let k0 = bp.springs[0].2;
    assert!(bp.springs.iter().all(|s| (s.2 - k0).abs() < 1e-9 * k0));
    let e = sum_kl2(&c, &bp.springs) / (6.0 * c.volume());
    assert!((e / jelly().young_pa - 1.0).abs() < 1e-9);

    let field = |n: &[Vector3<f64>], s: &[[usize; 2]]| cage::explicit(n, s).unwrap_err().field;
    let mut bad = good.clone();
    bad[3] = [1, 7];
    assert_eq!(field(&nodes, &bad), "springs[3]");
    bad[3] = [2, 2];
    assert_eq!(field(&nodes, &bad), "springs[3]");
    bad[3] = [1, 0];
    assert_eq!(field(&nodes, &bad), "springs[3]", "repeats springs[0]");
    assert_eq!(
        field(&nodes, &good[..6]),
        "nodes[4]",
        "node 4 has no spring"
    );
    assert_eq!(field(&nodes[..3], &good[..3]), "nodes");
    let flat: Vec<Vector3<f64>> = nodes.iter().map(|n| Vector3::new(n.x, n.y, 0.0)).collect();
    let flat_springs = [[0, 1], [1, 2], [2, 0], [4, 0], [4, 1], [4, 2], [3, 4]];
    let mut flat = flat;
    flat[3] = Vector3::new(0.5, 0.5, 0.0);
    assert_eq!(field(&flat, &flat_springs), "nodes", "coplanar nodes");
}

/// A world with a floor at y = 0 and the cage body of `mesh` in `material`, touching with
/// its display surface.
fn cage_on_floor(c: &Cage, p: &[Point3<f64>], t: &[[u32; 3]], m: &Material) -> World {
    let h = c.spacing();
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: WorldSettings::default_layer(h, m, 0.4),
        ..WorldSettings::default()
    });
    let handle = c.add_to_world(&mut w, "cage", m, Some(mesh_volume(p, t)), Vector3::zeros());
    let (s, a) = surface_samples(p, t, 0.5 * h);
    c.add_contact_surface(&mut w, handle, &s, &a);
    w
}

#[test]
fn an_icosahedron_cage_lands_and_rests_on_its_mesh() {
    // A 0.3 m ball of soft rubber dropped from 5 cm: its mesh (not the cage, which stands off
    // it) comes to rest on the floor, the cage's nodes never cross the floor, and the body
    // keeps its shape to within its small sag.
    let (p, t) = uv_sphere([0.0, 0.2, 0.0], 0.15, 8, 16);
    let m = Material::preset("soft_rubber").unwrap();
    let c = cage::primitive(Primitive::Icosahedron, &p).unwrap();
    let mut w = cage_on_floor(&c, &p, &t, &m);
    let e = c.embed(&p);
    let frame = 1.0 / 24.0;
    // It hops and rocks on its mesh for about 3 s (the contact layer's damping is the only
    // loss besides the springs' dampers), then rests.
    let mut late_speed: f64 = 0.0;
    for f in 0..96 {
        let d = w.advance_frame(frame, f + 2, &|| false).unwrap();
        assert!(d.max_speed.is_finite());
        if f >= 88 {
            late_speed = late_speed.max(d.max_speed);
        }
    }
    let nodes: Vec<Point3<f64>> = w.body_points(BodyHandle(0));
    let lowest = (0..p.len())
        .map(|i| e.point(i, &nodes).y)
        .fold(f64::INFINITY, f64::min);
    let layer = w.settings.layer.thickness_m;
    assert!(
        lowest > -layer && lowest < 0.01,
        "mesh bottom at {lowest} (layer {layer})"
    );
    assert!(late_speed < 0.06, "still moving at {late_speed} m/s");
    // Shape: every spring within 5 % of its rest length.
    let s = &w.springs;
    for k in 0..s.len() {
        let l = (w.nodes.position[s.a[k] as usize] - w.nodes.position[s.b[k] as usize]).norm();
        assert!((l / s.rest_length[k] - 1.0).abs() < 0.05, "spring {k}: {l}");
    }
}

fn lattice_bar(lo: [f64; 3], hi: [f64; 3], cells: u32) -> Lattice {
    fitted_box(lo, hi, cells).2
}

fn centre_of_mass(w: &World, body: BodyHandle) -> Vector3<f64> {
    let r = w.bodies[body.0].nodes.clone();
    let m: f64 = w.nodes.mass[r.clone()].iter().sum();
    r.map(|i| w.nodes.position[i] * w.nodes.mass[i])
        .sum::<Vector3<f64>>()
        / m
}

#[test]
fn a_particle_falls_exactly_and_keeps_its_shape() {
    let lattice = lattice_bar([0.0, 1.0, 0.0], [0.2, 1.2, 0.2], 3);
    for integrator in [Integrator::SymplecticEuler, Integrator::newmark()] {
        let mut w = World::new(WorldSettings {
            integrator,
            ..floor_settings(&lattice, &jelly(), 0.8)
        });
        let v0 = Vector3::new(1.5, 2.0, 0.0);
        let h = w.add_lattice_body("p", &lattice, &jelly(), v0);
        let range = w.bodies[h.0].nodes.clone();
        let g = w.settings.gravity;
        w.rigid
            .push(RigidBody::particle(h.0, &w.nodes, range.clone(), g).unwrap());
        let x0 = centre_of_mass(&w, h);
        let rest: Vec<Vector3<f64>> = range.clone().map(|i| w.nodes.position[i] - x0).collect();
        // Free flight until just before the lowest node reaches the layer: x0 + v0 t + ½ g t².
        let dt = 1e-3;
        let mut t = 0.0;
        while t < 0.55 {
            w.step(dt);
            t += dt;
            let want = x0 + v0 * t + 0.5 * g * t * t;
            let got = centre_of_mass(&w, h);
            assert!(
                (got - want).norm() < 1e-9,
                "{integrator:?} t={t}: {got} vs {want}"
            );
        }
        // Then it lands, slides with friction and bounces, and never rotates or deforms:
        // every node keeps its rest offset from the centre exactly.
        let (mut lowest, mut rebound) = (f64::INFINITY, 0.0f64);
        for _ in 0..1000 {
            w.step(dt);
            let c = centre_of_mass(&w, h);
            lowest = lowest.min(c.y);
            rebound = rebound.max(w.nodes.velocity[range.start].y);
            for (j, i) in range.clone().enumerate() {
                assert!((w.nodes.position[i] - c - rest[j]).norm() < 1e-12);
                assert_eq!(w.nodes.velocity[i], w.nodes.velocity[range.start]);
            }
        }
        assert!(
            lowest > 0.0 && lowest < 0.12,
            "{integrator:?}: lowest centre {lowest}"
        );
        assert!(
            rebound > 0.5,
            "{integrator:?}: it bounces ({rebound} m/s up)"
        );
        let vx = w.nodes.velocity[range.start].x;
        assert!(
            vx < 1.4,
            "{integrator:?}: friction slowed the slide to {vx}"
        );
    }
}

#[test]
fn two_linked_bars_share_a_joint_node_and_the_pulled_one_drags_the_other() {
    // Two 0.4 m bars end to end along x, joined at x = 0.4; no gravity. The free end of the
    // upper bar (x = 0) is pulled 0.3 m along −x in 1 s and held.
    let m = Material::preset("soft_rubber").unwrap();
    let mut w = World::new(WorldSettings {
        gravity: Vector3::zeros(),
        ..WorldSettings::default()
    });
    let upper = w.add_lattice_body(
        "upper",
        &lattice_bar([0.0, 0.0, 0.0], [0.4, 0.1, 0.1], 4),
        &m,
        Vector3::zeros(),
    );
    let lower = w.add_lattice_body(
        "lower",
        &lattice_bar([0.4, 0.0, 0.0], [0.8, 0.1, 0.1], 4),
        &m,
        Vector3::zeros(),
    );
    let (mass0, p0) = (w.nodes.mass.iter().sum::<f64>(), w.momentum());
    let shared = join_bodies_at(&mut w, upper, lower, Vector3::new(0.4, 0.05, 0.05)).unwrap();
    assert!(w.bodies[upper.0].nodes.contains(&shared.kept));
    assert!(w.bodies[lower.0].nodes.contains(&shared.follower));
    assert_eq!(
        w.nodes.mass.iter().sum::<f64>(),
        mass0,
        "mass moved, not made"
    );
    assert!((w.momentum() - p0).norm() < 1e-15);
    let f = shared.follower as u32;
    assert!(!w.springs.a.contains(&f) && !w.springs.b.contains(&f));
    // The lower bar's springs now reach into the upper bar's node range.
    let range = w.bodies[lower.0].springs.clone();
    assert!(range
        .clone()
        .any(|k| w.springs.a[k] as usize == shared.kept || w.springs.b[k] as usize == shared.kept));
    assert_eq!(
        join_nodes(&mut w, shared.kept, shared.follower).unwrap_err(),
        springbake_core::solver::joints::JointError::AlreadyShared
    );

    let upper_range = w.bodies[upper.0].nodes.clone();
    let end: Vec<usize> = nodes_in_box(
        &w.nodes.position[upper_range.clone()],
        Vector3::new(-0.01, -0.01, -0.01),
        Vector3::new(0.01, 0.11, 0.11),
    )
    .into_iter()
    .map(|n| n + upper_range.start)
    .collect();
    assert_eq!(end.len(), 4);
    let path = Path::new(
        vec![(0.0, Vector3::zeros()), (1.0, Vector3::new(-0.3, 0.0, 0.0))],
        Interpolation::Linear,
    )
    .unwrap();
    w.add_trajectory(&end, path, 1.0).unwrap();
    let c0 = centre_of_mass(&w, lower);
    for f in 0..36 {
        let d = w.advance_frame(1.0 / 24.0, f + 2, &|| false).unwrap();
        assert!(d.max_speed.is_finite());
        assert_eq!(
            w.nodes.position[shared.kept], w.nodes.position[shared.follower],
            "the joint came apart"
        );
        assert_eq!(d.inverted_cells, 0);
    }
    let moved = centre_of_mass(&w, lower) - c0;
    assert!(
        moved.x < -0.2,
        "the lower bar's centre moved {moved} for a 0.3 m pull"
    );
    assert!(moved.x > -0.4);
}

#[test]
fn a_heavy_bottom_lowers_the_centre_of_mass_and_moves_less() {
    let lattice = lattice_bar([0.0, 0.0, 0.0], [0.3, 0.3, 0.3], 3);
    let m = Material::preset("soft_rubber").unwrap();
    let world = |heavy: bool| {
        let mut w = World::new(WorldSettings {
            gravity: Vector3::zeros(),
            ..WorldSettings::default()
        });
        let h = w.add_lattice_body("b", &lattice, &m, Vector3::zeros());
        if heavy {
            let e = apply_region(
                &mut w,
                h,
                &Region {
                    min: Vector3::new(-1.0, -1.0, -1.0),
                    max: Vector3::new(1.0, 0.04, 1.0),
                    mass_scale: 4.0,
                    stiffness_scale: 1.0,
                },
            )
            .unwrap();
            assert_eq!(e.nodes, 16, "the bottom layer of 4 × 4 nodes");
            let s = &w.springs;
            let flat = (0..s.len())
                .filter(|&k| {
                    w.nodes.position[s.a[k] as usize]
                        .y
                        .max(w.nodes.position[s.b[k] as usize].y)
                        < 0.04
                })
                .count();
            assert!(flat >= 24, "bottom edges and diagonals: {flat}");
            assert_eq!(e.springs, flat);
        }
        (w, h)
    };
    let (plain, h) = world(false);
    let (heavy, _) = world(true);
    // The bottom layer (y = 0) at 4× mass: the centre of mass drops from 0.15 m to
    // 0.15 M / (M + 3 M_bottom).
    let mass = |w: &World| w.nodes.mass.iter().sum::<f64>();
    let bottom_mass: f64 = (0..64)
        .filter(|&i| plain.nodes.position[i].y < 0.05)
        .map(|i| plain.nodes.mass[i])
        .sum();
    assert!((mass(&heavy) - mass(&plain) - 3.0 * bottom_mass).abs() < 1e-12);
    let (c_plain, c_heavy) = (centre_of_mass(&plain, h).y, centre_of_mass(&heavy, h).y);
    let want = (c_plain * mass(&plain)) / mass(&heavy);
    assert!((c_plain - 0.15).abs() < 1e-12);
    assert!((c_heavy - want).abs() < 1e-12, "{c_heavy} vs {want}");
    // The damping ratio of every spring is kept.
    let ratio = |w: &World, k: usize| {
        let s = &w.springs;
        let (a, b) = (s.a[k] as usize, s.b[k] as usize);
        let mu = w.nodes.mass[a] * w.nodes.mass[b] / (w.nodes.mass[a] + w.nodes.mass[b]);
        s.damping[k] / (s.stiffness[k] * mu).sqrt()
    };
    for k in 0..plain.springs.len() {
        assert!((ratio(&plain, k) - ratio(&heavy, k)).abs() < 1e-12);
    }
    // Wobble: the same sideways impulse on both bodies (1 m/s for the plain body's node
    // masses, so the plain body just translates); the heavy bottom moves less and the body
    // leans.
    let plain_mass = plain.nodes.mass.clone();
    let kick = |mut w: World| {
        for ((v, m), m0) in w
            .nodes
            .velocity
            .iter_mut()
            .zip(&w.nodes.mass)
            .zip(&plain_mass)
        {
            v.x += m0 / m;
        }
        let p0 = w.momentum();
        w.advance_frame(1.0 / 60.0, 2, &|| false).unwrap();
        assert!((w.momentum() - p0).norm() < 1e-9 * p0.norm());
        let layer = |lo: f64, hi: f64| {
            let ids: Vec<usize> = (0..64)
                .filter(|&i| {
                    let y = lattice.rest_positions[i].y;
                    y > lo && y < hi
                })
                .collect();
            ids.iter()
                .map(|&i| w.nodes.position[i].x - lattice.rest_positions[i].x)
                .sum::<f64>()
                / ids.len() as f64
        };
        (layer(-0.01, 0.01), layer(0.29, 0.31))
    };
    let (bottom_plain, top_plain) = kick(plain);
    let (bottom_heavy, top_heavy) = kick(heavy);
    println!("bottom {bottom_plain} -> {bottom_heavy}, top {top_plain} -> {top_heavy}");
    assert!((bottom_plain - 1.0 / 60.0).abs() < 1e-9 && (top_plain - 1.0 / 60.0).abs() < 1e-9);
    assert!(
        bottom_heavy < 0.7 * bottom_plain,
        "bottom moved {bottom_heavy} vs {bottom_plain}"
    );
    assert!(top_heavy > 1.2 * bottom_heavy, "the body leans");
}

#[test]
fn a_cage_body_keeps_its_volume_and_counts_inverted_tets() {
    // A jelly ball in an icosahedron cage thrown at the floor at 3 m/s, with and without
    // volume preservation; the tets are the body's cells.
    let (p, t) = uv_sphere([0.0, 0.2, 0.0], 0.15, 8, 16);
    let m = jelly();
    let c = cage::primitive(Primitive::Icosahedron, &p).unwrap();
    let run = |preserve: bool| {
        let mut w = cage_on_floor(&c, &p, &t, &m);
        let h = BodyHandle(0);
        assert_eq!(w.bodies[0].cells.len(), 20);
        assert_eq!(w.inverted_cells(), 0);
        let v0 = w.body_volume(h);
        assert!((v0 - c.volume()).abs() < 1e-12 * v0);
        for v in &mut w.nodes.velocity {
            v.y = -3.0;
        }
        if preserve {
            w.preserve_volume(h, 1.0).unwrap();
        }
        let mut worst: f64 = 0.0;
        for f in 0..24 {
            w.advance_frame(1.0 / 24.0, f + 2, &|| false).unwrap();
            worst = worst.max((w.body_volume(h) / v0 - 1.0).abs());
        }
        (worst, w)
    };
    let (kept, _) = run(true);
    let (lost, mut w) = run(false);
    println!("volume error with preservation {kept:.2e}, without {lost:.3}");
    assert!(kept < 0.02, "{kept}");
    assert!(lost > 2.0 * kept, "{lost} vs {kept}");
    // Push the centre node through a face: the tets on the far side count as inverted.
    let centre = c.nodes.len() - 1;
    let far = w.nodes.position[0] + (w.nodes.position[0] - w.nodes.position[centre]) * 0.5;
    w.nodes.position[centre] = far;
    let d = w.diagnostics(0);
    assert!(
        d.inverted_cells >= 1 && d.inverted_cells < 20,
        "{}",
        d.inverted_cells
    );
}
