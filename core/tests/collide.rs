//! Body–body and body–collider contact (physics §10): soft cubes thrown at each other bounce
//! apart without entering each other, momentum is conserved, a cube rests on a static box,
//! and the Hertz model's pulse matches the closed form.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::collide::StaticCollider;
use springbake_core::hertz::{
    lattice_spring_area_m2, young_from_springs, ContactGeometry, HertzBody, HertzImpact, SpringEdge,
};
use springbake_core::lattice::{surface_samples, Embedding, Lattice};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::{box_mesh, uv_sphere};
use springbake_core::solver::{
    BodyHandle, ContactModel, ContactPartner, Integrator, World, WorldSettings,
};
use std::time::Instant;
use support::{fit, fitted_box};

/// A body of the world with its display mesh.
struct Body {
    handle: BodyHandle,
    triangles: Vec<[u32; 3]>,
    embedding: Embedding,
    samples: Embedding,
}

impl Body {
    fn vertices(&self, w: &World) -> Vec<Vector3<f64>> {
        self.embedding
            .points(&w.body_points(self.handle))
            .iter()
            .map(|p| p.coords)
            .collect()
    }
    fn samples(&self, w: &World) -> Vec<Vector3<f64>> {
        self.samples
            .points(&w.body_points(self.handle))
            .iter()
            .map(|p| p.coords)
            .collect()
    }
    /// Its display mesh's lowest height, m.
    fn lowest(&self, w: &World) -> f64 {
        self.vertices(w)
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min)
    }
    fn velocity(&self, w: &World) -> Vector3<f64> {
        let r = w.bodies[self.handle.0].nodes.clone();
        let m: f64 = w.nodes.mass[r.clone()].iter().sum();
        r.map(|i| w.nodes.velocity[i] * w.nodes.mass[i])
            .sum::<Vector3<f64>>()
            / m
    }
}

fn add_body(
    w: &mut World,
    name: &str,
    points: &[Point3<f64>],
    triangles: &[[u32; 3]],
    cells: u32,
    material: &Material,
    velocity: Vector3<f64>,
) -> (Body, Lattice) {
    let lattice = fit(points, triangles, cells);
    let handle = w.add_lattice_body(name, &lattice, material, velocity);
    let (s, a) = surface_samples(points, triangles, 0.5 * lattice.cell_size);
    w.add_contact_surface(handle, &lattice, &s, &a);
    w.add_collision_surface(handle, &lattice, points, triangles);
    let body = Body {
        handle,
        triangles: triangles.to_vec(),
        embedding: Embedding::new(&lattice, points),
        samples: Embedding::new(&lattice, &s),
    };
    (body, lattice)
}

/// Generalised winding number of `q` for a closed triangle mesh (1 inside, 0 outside).
fn winding(q: &Vector3<f64>, positions: &[Vector3<f64>], triangles: &[[u32; 3]]) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let a = positions[t[0] as usize] - q;
        let b = positions[t[1] as usize] - q;
        let c = positions[t[2] as usize] - q;
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let det = a.dot(&b.cross(&c));
        let den = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * det.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Points of `a` (its lattice nodes, display vertices and contact samples) inside `b`'s
/// deformed display surface.
fn inside_count(w: &World, a: &Body, b: &Body) -> usize {
    let surface = b.vertices(w);
    let mut points: Vec<Vector3<f64>> = w.body_positions(a.handle).to_vec();
    points.extend(a.vertices(w));
    points.extend(a.samples(w));
    points
        .iter()
        .filter(|q| winding(q, &surface, &b.triangles) > 0.5)
        .count()
}

fn no_gravity(lattice: &Lattice, m: &Material) -> WorldSettings {
    WorldSettings {
        gravity: Vector3::zeros(),
        layer: WorldSettings::default_layer(lattice.cell_size, m, 0.4),
        ..WorldSettings::default()
    }
}

#[test]
fn two_soft_cubes_thrown_at_each_other_bounce_apart_without_interpenetrating() {
    let started = Instant::now();
    let m = Material::preset("soft_rubber").unwrap();
    let (pa, ta, lattice) = fitted_box([-0.3, 0.0, -0.1], [-0.1, 0.2, 0.1], 4);
    // The second cube is a little higher and turned by a non-axis offset: faces meet off
    // centre, so edges and corners of one reach the other's faces.
    let (pb, tb) = box_mesh([0.1, 0.07, -0.04], [0.3, 0.27, 0.16]);
    let mut w = World::new(no_gravity(&lattice, &m));
    let speed = 3.0;
    let (a, _) = add_body(&mut w, "a", &pa, &ta, 4, &m, Vector3::new(speed, 0.0, 0.0));
    let (b, _) = add_body(&mut w, "b", &pb, &tb, 4, &m, Vector3::new(-speed, 0.0, 0.0));
    let mut touched = false;
    let mut impact = 0.0f64;
    for f in 2..=16 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert_eq!(inside_count(&w, &a, &b), 0, "frame {f}: a inside b");
        assert_eq!(inside_count(&w, &b, &a), 0, "frame {f}: b inside a");
        for r in w.frame_contacts() {
            match (r.body, r.partner) {
                (0, ContactPartner::Body(1)) | (1, ContactPartner::Body(0)) => {
                    touched = true;
                    impact = impact.max(r.impact_speed);
                }
                other => panic!("unexpected contact {other:?}"),
            }
        }
    }
    assert!(touched, "the cubes met");
    assert!(
        (impact - 2.0 * speed).abs() < 0.05 * 2.0 * speed,
        "impact {impact} m/s vs closing speed {}",
        2.0 * speed
    );
    let (va, vb) = (a.velocity(&w), b.velocity(&w));
    assert!(va.x < -0.5 && vb.x > 0.5, "they move apart: {va:?} {vb:?}");
    assert!(w.frame_contacts().is_empty(), "apart at the end");
    eprintln!("two cubes: {:.2} s", started.elapsed().as_secs_f64());
}

#[test]
fn momentum_is_conserved_in_a_gravity_free_collision() {
    // Unequal bodies, glancing: a light cube hits a heavier, larger one off centre.
    let light = Material::preset("soft_rubber").unwrap();
    let heavy = Material::new("dense", 6.0e5, 0.45, 3000.0, 0.1).unwrap();
    let (pa, ta, lattice) = fitted_box([-0.35, 0.05, -0.05], [-0.2, 0.2, 0.1], 3);
    let (pb, tb) = box_mesh([0.0, 0.0, 0.0], [0.25, 0.25, 0.25]);
    let mut w = World::new(no_gravity(&lattice, &light));
    let (a, _) = add_body(
        &mut w,
        "a",
        &pa,
        &ta,
        3,
        &light,
        Vector3::new(4.0, 0.5, 0.3),
    );
    let (b, _) = add_body(
        &mut w,
        "b",
        &pb,
        &tb,
        4,
        &heavy,
        Vector3::new(-0.5, 0.0, 0.0),
    );
    let before = w.momentum();
    let va0 = a.velocity(&w);
    let mut touched = false;
    for f in 2..=12 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        touched |= !w.frame_contacts().is_empty();
    }
    assert!(touched, "the bodies met");
    let after = w.momentum();
    let scale = before.norm();
    assert!(
        (after - before).norm() < 1e-9 * scale,
        "momentum {before:?} → {after:?}"
    );
    // And the collision changed the light body's motion (this test is not vacuous).
    assert!((a.velocity(&w) - va0).norm() > 1.0, "{:?}", a.velocity(&w));
    let _ = b;
}

#[test]
fn a_cube_dropped_on_a_static_box_rests_on_it() {
    let m = Material::preset("soft_rubber").unwrap();
    let (pc, tc) = box_mesh([-0.5, -0.3, -0.5], [0.5, 0.0, 0.5]);
    let (p, t, lattice) = fitted_box([-0.1, 0.3, -0.1], [0.1, 0.5, 0.1], 4);
    let mut w = World::new(WorldSettings {
        gravity: Vector3::new(0.0, -9.81, 0.0),
        layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
        ..WorldSettings::default()
    });
    let h = w.settings.layer.thickness_m;
    w.add_collider(StaticCollider::new("table", &pc, &tc, 0.5).unwrap());
    let (cube, _) = add_body(&mut w, "cube", &p, &t, 4, &m, Vector3::zeros());
    let mut impact = 0.0f64;
    for f in 2..=48 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        for r in w.frame_contacts() {
            assert_eq!((r.body, r.partner), (0, ContactPartner::Collider(0)));
            impact = impact.max(r.impact_speed);
        }
        let lowest = cube.lowest(&w);
        assert!(
            lowest > -1e-3,
            "frame {f}: the cube went into the table ({lowest} m)"
        );
    }
    // The layer begins h above the table.
    let expected = (2.0 * 9.81 * (0.3 - h)).sqrt();
    assert!(
        (impact - expected).abs() < 0.03 * expected,
        "impact {impact} m/s vs {expected} m/s"
    );
    let lowest = cube.lowest(&w);
    assert!(
        (0.0..h).contains(&lowest),
        "resting on the table, within its layer: bottom at {lowest} m, layer {h} m"
    );
    assert!(cube.velocity(&w).norm() < 0.02, "{:?}", cube.velocity(&w));
    let last = w.frame_contacts();
    assert_eq!(last.len(), 1);
    assert!(last[0].touching_at_end);
    let weight = w.nodes.mass.iter().sum::<f64>() * 9.81;
    assert!(
        (last[0].peak_force / weight - 1.0).abs() < 0.2,
        "the table carries the weight: {} N vs {weight} N",
        last[0].peak_force
    );
}

/// Throw a 0.1 m sphere (rubber; rigid or flexible) straight down at `v0` onto a static box in
/// Hertz mode, gravity off; return (measured peak force, contact duration, the closed form).
fn hertz_drop(rigid: bool, v0: f64) -> (f64, f64, HertzImpact) {
    let m = Material::preset("rubber").unwrap();
    let r = 0.1;
    let (pc, tc) = box_mesh([-0.5, -0.3, -0.5], [0.5, 0.0, 0.5]);
    let (p, t) = uv_sphere([0.0, r + 0.03, 0.0], r, 12, 24);
    let lattice = fit(&p, &t, 6);
    let mut w = World::new(no_gravity(&lattice, &m));
    w.set_contact_model(ContactModel::Hertz);
    w.add_collider(StaticCollider::new("table", &pc, &tc, 0.0).unwrap());
    let (ball, _) = add_body(&mut w, "ball", &p, &t, 6, &m, Vector3::new(0.0, -v0, 0.0));
    if rigid {
        w.make_rigid(ball.handle).unwrap();
    }
    // The closed form for the same body: mass from the nodes, E from the springs (eq 3.38),
    // the sphere's radius, a rigid table (E a million times the ball's).
    let mass: f64 = w.nodes.mass.iter().sum();
    let springs: Vec<SpringEdge> = (0..w.springs.len())
        .map(|s| SpringEdge {
            length_m: w.springs.rest_length[s],
            k_n_per_m: w.springs.stiffness[s],
        })
        .collect();
    let young = young_from_springs(&springs, lattice_spring_area_m2(lattice.cell_size)).unwrap();
    let expected = HertzImpact::compute(
        &HertzBody::with_default_poisson(mass, young),
        &HertzBody::with_default_poisson(f64::INFINITY, 1e6 * young),
        &ContactGeometry::SphereOnPlane { r_m: r },
        v0,
    )
    .unwrap();
    let frame_dt = expected.t_max / 100.0;
    let (mut peak, mut frames, mut impact) = (0.0f64, 0, 0.0f64);
    for f in 2..=400 {
        w.advance_frame(frame_dt, f, &|| false).unwrap();
        if let Some(c) = w.frame_contacts().first() {
            assert_eq!(c.partner, ContactPartner::Collider(0));
            peak = peak.max(c.peak_force);
            impact = impact.max(c.impact_speed);
            frames += 1;
        }
    }
    assert!((impact - v0).abs() < 0.01 * v0, "impact {impact} m/s");
    assert!(
        ball.velocity(&w).y > 0.0,
        "it bounced: {:?}",
        ball.velocity(&w)
    );
    (peak, frames as f64 * frame_dt, expected)
}

#[test]
fn hertz_contact_matches_the_closed_form_pulse() {
    // A rigid ball: the only compliance is the Hertz law at the contact, so the pulse should be
    // the law's own: duration 2.94 α_m / v0 as in eq 3.31; peak n2 α_m^1.5 = 1.25 v0²/(n1 α_m),
    // which is 9.6 % above eq 3.30's sine fit (1.140). Tolerances 5 %: the frames sample the
    // pulse at T_max/100, the contact starts at the layer's top, and the local radius read off
    // the mesh (eq 3.41) is capped at the ball's radius.
    let (peak, duration, hz) = hertz_drop(true, 1.0);
    let law_peak = hz.f_max * 1.25 / 1.140;
    eprintln!(
        "rigid: peak {peak:.1} N vs F_max {:.1} N; duration {duration:.5} s vs T_max {:.5} s",
        hz.f_max, hz.t_max
    );
    assert!(
        (peak / law_peak - 1.0).abs() < 0.05,
        "peak {peak} N vs n2 α_m^1.5 = {law_peak} N"
    );
    assert!(
        (duration / hz.t_max - 1.0).abs() < 0.05,
        "duration {duration} s vs T_max {} s",
        hz.t_max
    );
    // A flexible ball adds its lattice's own compliance in series with the contact: a longer,
    // softer pulse, within a factor of two of the closed form.
    let (peak, duration, hz) = hertz_drop(false, 1.0);
    eprintln!(
        "flexible: peak {peak:.1} N vs F_max {:.1} N; duration {duration:.5} s vs T_max {:.5} s",
        hz.f_max, hz.t_max
    );
    assert!(
        peak > 0.5 * hz.f_max && peak < 1.3 * hz.f_max,
        "peak {peak} N vs F_max {} N",
        hz.f_max
    );
    assert!(
        duration > 0.9 * hz.t_max && duration < 2.0 * hz.t_max,
        "duration {duration} s vs T_max {} s",
        hz.t_max
    );
}

#[test]
fn body_contact_gives_the_same_bits_on_1_and_2_threads() {
    let run = |threads: usize| {
        in_pool(threads, || {
            let m = Material::preset("soft_rubber").unwrap();
            let (pa, ta, lattice) = fitted_box([-0.3, 0.0, -0.1], [-0.1, 0.2, 0.1], 4);
            let (pb, tb) = box_mesh([0.1, 0.07, -0.04], [0.3, 0.27, 0.16]);
            let (pc, tc) = box_mesh([-1.0, -0.3, -1.0], [1.0, -0.01, 1.0]);
            let mut w = World::new(WorldSettings {
                gravity: Vector3::new(0.0, -9.81, 0.0),
                layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
                ..WorldSettings::default()
            });
            w.add_collider(StaticCollider::new("table", &pc, &tc, 0.4).unwrap());
            add_body(&mut w, "a", &pa, &ta, 4, &m, Vector3::new(3.0, 0.0, 0.0));
            add_body(&mut w, "b", &pb, &tb, 4, &m, Vector3::new(-3.0, 0.0, 0.0));
            frames_with_contacts(&mut w, 8)
        })
    };
    let (one, log1) = run(1);
    let (two, log2) = run(2);
    assert!(log1
        .iter()
        .any(|r| matches!(r.partner, ContactPartner::Body(_))));
    assert!(log1
        .iter()
        .any(|r| matches!(r.partner, ContactPartner::Collider(_))));
    assert_eq!(one, two);
    assert_eq!(log1, log2);
}

/// Four rubber boxes 1 cm apart in a square on the floor, pushed into each other, big enough
/// (1372 nodes) for the world to take two threads: the contact pass's parallel parts (the
/// meshes' and samples' upkeep, the lists' builds, the searches, the constraints' pairs solved
/// side by side a colour at a time) give the same bits as one.
#[test]
fn a_pile_gives_the_same_bits_on_1_and_2_threads() {
    let run = |threads: usize| {
        in_pool(threads, || {
            let m = Material::preset("rubber").unwrap();
            let mut w = World::new(WorldSettings {
                gravity: Vector3::new(0.0, -9.81, 0.0),
                layer: WorldSettings::default_layer(0.2 / 6.0, &m, 0.4),
                planes: vec![springbake_core::solver::Plane {
                    normal: Vector3::y(),
                    offset: 0.0,
                }],
                integrator: springbake_core::solver::Integrator::Xpbd,
                ..WorldSettings::default()
            });
            for (i, (x, z)) in [(0.0, 0.0), (0.21, 0.0), (0.0, 0.21), (0.21, 0.21)]
                .into_iter()
                .enumerate()
            {
                let (p, t) = box_mesh([x, 0.001, z], [x + 0.2, 0.201, z + 0.2]);
                let towards = |c: f64| if c > 0.1 { -0.5 } else { 0.5 };
                let push = Vector3::new(towards(x), 0.0, towards(z));
                add_body(&mut w, &format!("box{i}"), &p, &t, 6, &m, push);
            }
            frames_with_contacts(&mut w, 4)
        })
    };
    let (one, log1) = run(1);
    let (two, log2) = run(2);
    assert!(log1
        .iter()
        .any(|r| matches!(r.partner, ContactPartner::Body(_))));
    assert_eq!(one, two);
    assert_eq!(log1, log2);
}

/// `f` run in a pool of `threads` threads (a world takes at most that many).
fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// Frames 2 to `last` of `w` at 24 fps: the nodes at the end, and every frame's contacts.
fn frames_with_contacts(
    w: &mut World,
    last: usize,
) -> (
    springbake_core::solver::NodeState,
    Vec<springbake_core::solver::ContactRecord>,
) {
    let mut log = Vec::new();
    for f in 2..=last {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        log.extend(w.frame_contacts().iter().copied());
    }
    (w.nodes.clone(), log)
}

/// A cube of side 0.2 centred at `centre`, turned 45° about `axis` (0: x, 1: y, 2: z).
fn turned_cube(centre: [f64; 3], axis: usize) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let (p, t) = box_mesh([-0.1; 3], [0.1; 3]);
    let (s, c) = std::f64::consts::FRAC_PI_4.sin_cos();
    let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
    let p = p
        .iter()
        .map(|q| {
            let mut r = *q;
            r[i] = c * q[i] - s * q[j];
            r[j] = s * q[i] + c * q[j];
            Point3::new(r.x + centre[0], r.y + centre[1], r.z + centre[2])
        })
        .collect();
    (p, t)
}

#[test]
fn crossed_edges_collide_through_the_edge_edge_test_alone() {
    // Two cubes meet ridge on ridge, the ridges crossed at right angles (one along z, one
    // along y), and have no contact samples: only edge–edge contacts can stop them.
    let m = Material::preset("soft_rubber").unwrap();
    let ridge = 0.1 * std::f64::consts::SQRT_2;
    let (pa, ta) = turned_cube([-ridge - 0.05, 0.0, 0.0], 2);
    let (pb, tb) = turned_cube([ridge + 0.05, 0.0, 0.0], 1);
    let (la, lb) = (fit(&pa, &ta, 4), fit(&pb, &tb, 4));
    let mut w = World::new(no_gravity(&la, &m));
    let a = w.add_lattice_body("a", &la, &m, Vector3::new(1.5, 0.0, 0.0));
    let b = w.add_lattice_body("b", &lb, &m, Vector3::new(-1.5, 0.0, 0.0));
    w.add_collision_surface(a, &la, &pa, &ta);
    w.add_collision_surface(b, &lb, &pb, &tb);
    let (ea, eb) = (Embedding::new(&la, &pa), Embedding::new(&lb, &pb));
    let before = w.momentum();
    let mut touched = false;
    for f in 2..=14 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        touched |= w
            .frame_contacts()
            .iter()
            .any(|r| r.partner == ContactPartner::Body(1));
        let xa: Vec<Vector3<f64>> = ea
            .points(&w.body_points(a))
            .iter()
            .map(|p| p.coords)
            .collect();
        let xb: Vec<Vector3<f64>> = eb
            .points(&w.body_points(b))
            .iter()
            .map(|p| p.coords)
            .collect();
        // Points along every edge of each mesh stay outside the other: the ridges do not
        // pass through each other (corners alone would not show it).
        let along = |x: &[Vector3<f64>], t: &[[u32; 3]]| -> Vec<Vector3<f64>> {
            let mut out = Vec::new();
            for tri in t {
                for e in 0..3 {
                    let (p, q) = (x[tri[e] as usize], x[tri[(e + 1) % 3] as usize]);
                    out.extend((0..=20).map(|k| p + (q - p) * (k as f64 / 20.0)));
                }
            }
            out
        };
        for q in along(&xa, &ta) {
            assert!(
                winding(&q, &xb, &tb) < 0.5,
                "frame {f}: an edge of a inside b"
            );
        }
        for q in along(&xb, &tb) {
            assert!(
                winding(&q, &xa, &ta) < 0.5,
                "frame {f}: an edge of b inside a"
            );
        }
    }
    assert!(touched, "the ridges met");
    let va: f64 = w.body_positions(a).len() as f64;
    let vx_a = w.bodies[0]
        .nodes
        .clone()
        .map(|i| w.nodes.velocity[i].x)
        .sum::<f64>()
        / va;
    assert!(vx_a < 0.0, "a bounced back: {vx_a} m/s");
    assert!((w.momentum() - before).norm() < 1e-9 * before.norm().max(1.0));
}

#[test]
fn hertz_between_two_rigid_balls_matches_the_closed_form() {
    // Two equal rubber balls, rigid (only the contact law is compliant), closing at 2 m/s:
    // spheres R1 = R2 = 0.1 m, eq 3.34 with both bodies' δ. Tolerances as for the ball on the
    // table (5 %); the peak is the law's n2 α_m^1.5 = 1.25/1.140 F_max.
    let m = Material::preset("rubber").unwrap();
    let r = 0.1;
    let (pa, ta) = uv_sphere([-r - 0.02, 0.0, 0.0], r, 12, 24);
    let (pb, tb) = uv_sphere([r + 0.02, 0.0, 0.0], r, 12, 24);
    let la = fit(&pa, &ta, 6);
    let mut w = World::new(no_gravity(&la, &m));
    w.set_contact_model(ContactModel::Hertz);
    let (a, _) = add_body(&mut w, "a", &pa, &ta, 6, &m, Vector3::new(1.0, 0.0, 0.0));
    let (b, _) = add_body(&mut w, "b", &pb, &tb, 6, &m, Vector3::new(-1.0, 0.0, 0.0));
    w.make_rigid(a.handle).unwrap();
    w.make_rigid(b.handle).unwrap();
    let range = w.bodies[0].nodes.clone();
    let mass: f64 = w.nodes.mass[range.clone()].iter().sum();
    let springs: Vec<SpringEdge> = w.bodies[0]
        .springs
        .clone()
        .map(|s| SpringEdge {
            length_m: w.springs.rest_length[s],
            k_n_per_m: w.springs.stiffness[s],
        })
        .collect();
    let young = young_from_springs(&springs, lattice_spring_area_m2(la.cell_size)).unwrap();
    let ball = HertzBody::with_default_poisson(mass, young);
    let hz = HertzImpact::compute(
        &ball,
        &ball,
        &ContactGeometry::Spheres { r1_m: r, r2_m: r },
        2.0,
    )
    .unwrap();
    let frame_dt = hz.t_max / 100.0;
    let (mut peak, mut frames, mut impact) = (0.0f64, 0, 0.0f64);
    for f in 2..=400 {
        w.advance_frame(frame_dt, f, &|| false).unwrap();
        let log = w.frame_contacts();
        if let Some(c) = log.first() {
            assert_eq!((c.body, c.partner), (0, ContactPartner::Body(1)));
            assert_eq!(log.len(), 2);
            // The log's forces on the two bodies are equal and opposite.
            assert!((log[1].peak_force - c.peak_force).abs() <= 1e-9 * c.peak_force);
            peak = peak.max(c.peak_force);
            impact = impact.max(c.impact_speed);
            frames += 1;
        }
    }
    let law_peak = hz.f_max * 1.25 / 1.140;
    let duration = frames as f64 * frame_dt;
    eprintln!(
        "two balls: peak {peak:.1} N vs {law_peak:.1} N; {duration:.5} s vs {:.5} s",
        hz.t_max
    );
    assert!((impact - 2.0).abs() < 0.02, "impact {impact} m/s");
    assert!(
        (peak / law_peak - 1.0).abs() < 0.05,
        "peak {peak} N vs {law_peak} N"
    );
    assert!(
        (duration / hz.t_max - 1.0).abs() < 0.05,
        "duration {duration} s vs T_max {} s",
        hz.t_max
    );
    assert!(
        a.velocity(&w).x < -0.9 && b.velocity(&w).x > 0.9,
        "elastic rebound"
    );
}

/// A soft cube dropped 0.3 m onto a ground quad (a static collider) whose faces point up
/// (`up`) or down: the lowest point of the cube at the end, its fastest node over the bake,
/// and how high its lowest point rose after it landed. Each frame's energy balance holds.
fn drop_on_quad(up: bool) -> (f64, f64, f64) {
    let m = Material::preset("soft_rubber").unwrap();
    let corners =
        [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]].map(|[x, z]| Point3::new(x, 0.0, z));
    // Seen from above (+y), 0 → 3 → 2 turns anticlockwise: facing up.
    let triangles = if up {
        [[0, 3, 2], [0, 2, 1]]
    } else {
        [[0, 2, 3], [0, 1, 2]]
    };
    let (p, t, lattice) = fitted_box([-0.1, 0.3, -0.1], [0.1, 0.5, 0.1], 4);
    let mut w = World::new(WorldSettings {
        gravity: Vector3::new(0.0, -9.81, 0.0),
        layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
        integrator: Integrator::Xpbd,
        ..WorldSettings::default()
    });
    let ground = StaticCollider::new("ground", &corners, &triangles, 0.5).unwrap();
    assert_eq!(ground.normals[0].y, if up { 1.0 } else { -1.0 });
    w.add_collider(ground);
    let (cube, _) = add_body(&mut w, "cube", &p, &t, 4, &m, Vector3::zeros());
    let (mut fastest, mut landed, mut bounce) = (0.0f64, false, 0.0f64);
    for f in 2..=36 {
        let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert_eq!(d.energy_gain, Some(0.0), "frame {f}");
        fastest = fastest.max(d.max_speed);
        let lowest = cube.lowest(&w);
        landed |= lowest < 5e-3;
        if landed {
            bounce = bounce.max(lowest);
        }
    }
    (cube.lowest(&w), fastest, bounce)
}

/// A ground plane is an open mesh: which way its faces point is how it was exported. A cube
/// dropped onto one whose faces point down lands and rests on it as on one facing up (it was
/// pushed through it and thrown at 170 m/s).
#[test]
fn a_cube_lands_on_a_ground_quad_whichever_way_its_faces_point() {
    let (rest_up, fastest_up, bounce_up) = drop_on_quad(true);
    let (rest_down, fastest_down, bounce_down) = drop_on_quad(false);
    // 0.3 m of fall is 2.4 m/s.
    for (fastest, rest) in [(fastest_up, rest_up), (fastest_down, rest_down)] {
        assert!(fastest < 3.0, "fastest node {fastest} m/s");
        assert!((-1e-3..5e-3).contains(&rest), "resting at {rest} m");
    }
    assert!(
        (rest_up - rest_down).abs() < 1e-3,
        "{rest_up} m and {rest_down} m"
    );
    // It bounces off either alike (the rebound was held down onto a face pointing down).
    assert!(bounce_up > 0.02, "bounced {bounce_up} m");
    assert!(
        (bounce_up - bounce_down).abs() < 0.1 * bounce_up,
        "bounced {bounce_up} m and {bounce_down} m"
    );
}
