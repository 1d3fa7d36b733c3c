//! The contact log (`World::frame_contacts`): bodies dropped on the floor and thrown at a wall
//! log the partner, the approach speed at first touch and the contact force.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::lattice::{surface_samples, Lattice};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::solver::{
    ContactPartner, ContactRecord, Integrator, Plane, World, WorldSettings,
};

fn cube(lo: [f64; 3], size: f64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>, Lattice) {
    support::fitted_box(lo, [lo[0] + size, lo[1] + size, lo[2] + size], 4)
}

fn world(planes: Vec<Plane>, gravity: f64, lattice: &Lattice, m: &Material) -> World {
    World::new(WorldSettings {
        gravity: Vector3::new(0.0, -gravity, 0.0),
        planes,
        layer: WorldSettings::default_layer(lattice.cell_size, m, 0.4),
        ..WorldSettings::default()
    })
}

fn floor() -> Plane {
    Plane {
        normal: Vector3::y(),
        offset: 0.0,
    }
}

/// Drop a 0.2 m soft rubber cube whose bottom starts `h` above the floor; return each frame's log.
fn drop_cube(
    h: f64,
    surface: bool,
    integrator: Integrator,
    frames: usize,
) -> (f64, Vec<Vec<ContactRecord>>) {
    let m = Material::preset("soft_rubber").unwrap();
    let (p, t, lattice) = cube([-0.1, h, -0.1], 0.2);
    let mut w = world(vec![floor()], 9.81, &lattice, &m);
    w.settings.integrator = integrator;
    let body = w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    if surface {
        let (s, a) = surface_samples(&p, &t, 0.5 * lattice.cell_size);
        w.add_contact_surface(body, &lattice, &s, &a);
    }
    let mass: f64 = w.nodes.mass.iter().sum();
    let mut log = Vec::new();
    for f in 2..=frames {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        log.push(w.frame_contacts().to_vec());
    }
    (mass, log)
}

fn check_drop(h: f64, log: &[Vec<ContactRecord>], mass: f64, what: &str) {
    let expected = (2.0 * 9.81 * h).sqrt();
    let first = log.iter().position(|r| !r.is_empty()).unwrap();
    let r = &log[first];
    assert_eq!(r.len(), 1, "{what}: only the floor is touched: {r:?}");
    assert_eq!((r[0].body, r[0].partner), (0, ContactPartner::Floor));
    let err = (r[0].impact_speed - expected).abs() / expected;
    assert!(
        err < 0.03,
        "{what}: impact {} m/s vs sqrt(2gh) = {expected} m/s",
        r[0].impact_speed
    );
    // Landing: the force at the impact is many times the weight.
    let weight = mass * 9.81;
    let peak = log
        .iter()
        .map(|r| r.first().map_or(0.0, |c| c.peak_force))
        .fold(0.0, f64::max);
    assert!(
        peak > 2.0 * weight,
        "{what}: peak {peak} N, weight {weight} N"
    );
    // At rest in the last frame: touching, no new impact, the floor carries the weight.
    let last = log.last().unwrap();
    assert_eq!(last.len(), 1, "{what}: {last:?}");
    assert!(
        last[0].touching_at_end && last[0].impact_speed == 0.0,
        "{what}: {last:?}"
    );
    let ratio = last[0].peak_force / weight;
    assert!(
        (0.95..1.25).contains(&ratio),
        "{what}: resting floor force {} N vs weight {weight} N",
        last[0].peak_force
    );
}

#[test]
fn a_cube_dropped_on_the_floor_logs_the_floor_with_impact_speed_sqrt_2gh() {
    let h = 0.3;
    let (mass, log) = drop_cube(h, true, Integrator::SymplecticEuler, 60);
    check_drop(h, &log, mass, "display surface, symplectic Euler");
    // Nothing is logged before the cube reaches the floor: a free fall of 0.3 m takes 0.247 s.
    let first = log.iter().position(|r| !r.is_empty()).unwrap();
    assert!(
        (4..=6).contains(&first),
        "first contact in logged frame {first}"
    );
    // The nodes of a body without a display surface take the contacts themselves.
    let (mass, log) = drop_cube(h, false, Integrator::SymplecticEuler, 60);
    check_drop(h, &log, mass, "lattice nodes, symplectic Euler");
    let (mass, log) = drop_cube(h, true, Integrator::newmark(), 60);
    check_drop(h, &log, mass, "display surface, Newmark");
}

#[test]
fn a_cube_thrown_at_a_wall_logs_the_wall_not_the_floor() {
    let m = Material::preset("soft_rubber").unwrap();
    let (p, t, lattice) = cube([-0.1, 0.0, -0.1], 0.2);
    let wall = Plane {
        normal: -Vector3::x(),
        offset: -0.3,
    };
    let mut w = world(vec![wall], 0.0, &lattice, &m);
    let body = w.add_lattice_body("cube", &lattice, &m, Vector3::new(2.0, 0.0, 0.0));
    let (s, a) = surface_samples(&p, &t, 0.5 * lattice.cell_size);
    w.add_contact_surface(body, &lattice, &s, &a);
    let mut records = Vec::new();
    for f in 2..=12 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        records.extend(w.frame_contacts().iter().copied());
    }
    assert!(!records.is_empty(), "the cube reaches the wall");
    assert!(records.iter().all(|r| r.partner == ContactPartner::Wall));
    let impact = records.iter().map(|r| r.impact_speed).fold(0.0, f64::max);
    assert!((impact - 2.0).abs() < 0.02, "impact {impact} m/s");
    // It bounced: the last frames log nothing and the cube moves away from the wall.
    assert!(w.frame_contacts().is_empty());
    assert!(w.momentum().x < 0.0);
}
