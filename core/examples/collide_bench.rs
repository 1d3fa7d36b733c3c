//! Body–body contact cost against display triangle count: two soft spheres pressed together
//! (8-cell lattices, so the lattice work stays the same) with UV meshes from 224 to ~16 000
//! triangles each; the time per step with body contact on, and with the same world without
//! collision surfaces (body contact off), the difference being the contact pass.
//!
//! `cargo run --release -p springbake-core --example collide_bench`

use springbake_core::lattice::{fit_lattice, surface_samples, FitSettings, Resolution};
use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::uv_sphere;
use springbake_core::solver::{World, WorldSettings};
use std::time::Instant;

fn world(rings: u32, segments: u32, contact: bool) -> (World, usize) {
    let m = Material::preset("soft_rubber").expect("preset");
    let r = 0.2;
    let mut w: Option<World> = None;
    let mut triangles = 0;
    for (x, v) in [(-r, 0.5), (r + 0.005, -0.5)] {
        let (p, t) = uv_sphere([x, 0.0, 0.0], r, rings, segments);
        triangles = t.len();
        let lattice = fit_lattice(
            &p,
            &t,
            &FitSettings {
                resolution: Resolution::CellsAlongLongest(8),
                ..FitSettings::default()
            },
        )
        .expect("a sphere fits");
        let world = w.get_or_insert_with(|| {
            World::new(WorldSettings {
                gravity: Vector3::zeros(),
                layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
                ..WorldSettings::default()
            })
        });
        let h = world.add_lattice_body("ball", &lattice, &m, Vector3::new(v, 0.0, 0.0));
        let (s, a) = surface_samples(&p, &t, 0.5 * lattice.cell_size);
        world.add_contact_surface(h, &lattice, &s, &a);
        if contact {
            world.add_collision_surface(h, &lattice, &p, &t);
        }
    }
    (w.expect("two bodies"), triangles)
}

fn time_steps(w: &mut World, steps: usize) -> f64 {
    let dt = w.choose_substeps(1.0 / 24.0).dt;
    // Let the balls meet first.
    for _ in 0..100 {
        w.step(dt);
    }
    let t = Instant::now();
    for _ in 0..steps {
        w.step(dt);
    }
    t.elapsed().as_secs_f64() / steps as f64
}

fn main() {
    println!("triangles/body  step with contact  step without  contact pass  ball 0 v_x after");
    for (rings, segments) in [(8, 16), (16, 32), (32, 64), (64, 128)] {
        let (mut on, triangles) = world(rings, segments, true);
        let (mut off, _) = world(rings, segments, false);
        let steps = 300;
        let t_on = time_steps(&mut on, steps);
        let t_off = time_steps(&mut off, steps);
        // Ball 0 started at +0.5 m/s: pushed back by ball 1 when the contact works.
        let range = on.bodies[0].nodes.clone();
        let vx = range.clone().map(|i| on.nodes.velocity[i].x).sum::<f64>() / range.len() as f64;
        println!(
            "{triangles:>14}  {:>14.1} µs  {:>9.1} µs  {:>9.1} µs  {vx:>+10.3} m/s",
            t_on * 1e6,
            t_off * 1e6,
            (t_on - t_off) * 1e6,
        );
    }
}
