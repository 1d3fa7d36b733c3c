//! Live-mode stepping rate: a rubber cube (1 m, resting on the floor) fitted with 8³, 16³ and
//! 32³ node lattices, the live capsule pressed into its top and pushed further down every
//! frame against the reaction (as a mouse drag would), nothing drawn to a window. Measures the
//! step time T_c with the capsule in contact, the CPU draw preparation T_r of the window's path
//! (embedding a 7 938-triangle sphere, shading, depth sort, building the egui mesh) and the
//! software screenshot render, then reports what eq 7–8 give at a 30 fps refresh: steps per
//! frame, the stable step, and whether the simulation keeps real time.
//!
//! `cargo run --release -p springbake-viewer --example live_bench [-- --seconds 2]`

use eframe::egui;
use springbake_core::lattice::{fit_lattice, Embedding, FitSettings, Resolution};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{Plane, World, WorldSettings};
use springbake_viewer::camera::OrbitCamera;
use springbake_viewer::live::{plan_steps, Gesture, LiveManipulator, StepTimer};
use springbake_viewer::raster::{self, DrawMesh, BODY_COLOUR};
use std::time::Instant;

/// A UV sphere of radius `r` centred at `c`: `stacks × slices` quads.
fn sphere(c: Vector3<f64>, r: f64, stacks: u32, slices: u32) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..=stacks {
        let phi = std::f64::consts::PI * i as f64 / stacks as f64;
        for j in 0..slices {
            let th = std::f64::consts::TAU * j as f64 / slices as f64;
            p.push(Point3::from(
                c + Vector3::new(phi.sin() * th.cos(), phi.cos(), phi.sin() * th.sin()) * r,
            ));
        }
    }
    let mut t = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            let a = i * slices + j;
            let b = i * slices + (j + 1) % slices;
            t.push([a, b + slices, b]);
            t.push([a, a + slices, b + slices]);
        }
    }
    (p, t)
}

struct Row {
    nodes_per_side: u32,
    nodes: usize,
    springs: usize,
    step_ms: f64,
    draw_ms: f64,
    raster_ms: f64,
    max_dt_ms: f64,
    steps_per_frame: u32,
    realtime_factor: f64,
    reaction_n: f64,
    contact_frames: u32,
    frames: u32,
}

fn run(nodes_per_side: u32, preset: &str, seconds: f64) -> Result<Row, String> {
    let cells = nodes_per_side - 1;
    let (box_p, box_t) = box_mesh([-0.5, 0.0, -0.5], [0.5, 1.0, 0.5]);
    let lattice = fit_lattice(
        &box_p,
        &box_t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            ..FitSettings::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let material = Material::preset(preset).map_err(|e| e.to_string())?;
    let layer = WorldSettings::default_layer(lattice.cell_size, &material, 0.4);
    let mut world = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer,
        ..WorldSettings::default()
    });
    let handle = world.add_lattice_body("cube", &lattice, &material, Vector3::zeros());
    let (sp, st) = sphere(Vector3::new(0.0, 0.5, 0.0), 0.45, 63, 63);
    let embedding = Embedding::new(&lattice, &sp);
    let mut manipulator = LiveManipulator::above(
        Vector3::new(-0.5, 0.0, -0.5),
        Vector3::new(0.5, 1.0, 0.5),
        Vector3::y(),
        material.young_pa,
    );
    // Start touching the top (the capsule's surface 2 mm into the cube).
    manipulator.centre.y = 1.0 + manipulator.radius - 0.002;
    world.live_capsules = vec![manipulator.capsule()];
    let camera = OrbitCamera::framing(
        Vector3::new(-0.5, 0.0, -0.5),
        Vector3::new(0.5, 1.0, 0.5),
        Vector3::y(),
    );

    let t_i = 1.0 / 30.0;
    let mut timer = StepTimer::default();
    let mut reaction = Vector3::zeros();
    let (mut frames, mut contact_frames) = (0u32, 0u32);
    let (mut step_total, mut steps_total, mut draw_total) = (0.0, 0u64, 0.0);
    let mut last_plan = None;
    let mut max_dt = f64::INFINITY;
    let start = Instant::now();
    while start.elapsed().as_secs_f64() < seconds {
        world.settings.fixed_substeps = None;
        max_dt = world.choose_substeps(t_i).dt;
        let plan = plan_steps(t_i, &timer, max_dt, 20_000);
        // The user drags down 5 mm per frame; resistance takes its share.
        manipulator.update(
            &[Gesture::Move(Vector3::new(0.0, -0.005, 0.0))],
            reaction,
            t_i,
        );
        world.live_capsules = vec![manipulator.capsule()];
        world.settings.fixed_substeps = Some(plan.steps);
        let t0 = Instant::now();
        let d = world
            .advance_frame(plan.steps as f64 * plan.dt, frames as usize + 2, &|| false)
            .map_err(|e| e.to_string())?;
        let step_s = t0.elapsed().as_secs_f64();
        reaction = d.reaction();
        if reaction.norm() > 0.0 {
            contact_frames += 1;
        }
        timer.record_steps(plan.steps, step_s);
        // The window's CPU draw path.
        let t1 = Instant::now();
        let nodes = world.body_points(handle);
        let verts = embedding.points(&nodes);
        let mesh = DrawMesh {
            texture: None,
            positions: verts.iter().map(|p| p.coords).collect(),
            triangles: st.clone(),
            colour: BODY_COLOUR,
        };
        let mut tris = raster::shade(&[mesh], &camera, 1200.0, 800.0);
        tris.sort_by(|x, y| {
            let dx: f64 = x.points.iter().map(|p| p.depth).sum();
            let dy: f64 = y.points.iter().map(|p| p.depth).sum();
            dy.total_cmp(&dx)
        });
        let mut em = egui::Mesh::default();
        for t in &tris {
            let base = em.vertices.len() as u32;
            for p in &t.points {
                em.colored_vertex(
                    egui::pos2(p.x as f32, p.y as f32),
                    egui::Color32::from_rgb(t.colour[0], t.colour[1], t.colour[2]),
                );
            }
            em.add_triangle(base, base + 1, base + 2);
        }
        std::hint::black_box(&em);
        let draw_s = t1.elapsed().as_secs_f64();
        timer.record_draw(draw_s);
        step_total += step_s;
        steps_total += plan.steps as u64;
        draw_total += draw_s;
        frames += 1;
        last_plan = Some(plan);
    }
    // The screenshot path once, 800 × 600.
    let nodes = world.body_points(handle);
    let verts = embedding.points(&nodes);
    let mesh = DrawMesh {
        texture: None,
        positions: verts.iter().map(|p| p.coords).collect(),
        triangles: st,
        colour: BODY_COLOUR,
    };
    let t2 = Instant::now();
    std::hint::black_box(raster::render(&[mesh], &camera, 800, 600));
    let raster_ms = t2.elapsed().as_secs_f64() * 1e3;
    let plan = last_plan.ok_or("no frame ran")?;
    Ok(Row {
        nodes_per_side,
        nodes: world.nodes.len(),
        springs: world.springs.len(),
        step_ms: step_total / steps_total.max(1) as f64 * 1e3,
        draw_ms: draw_total / frames.max(1) as f64 * 1e3,
        raster_ms,
        max_dt_ms: max_dt * 1e3,
        steps_per_frame: plan.steps,
        realtime_factor: plan.realtime_factor,
        reaction_n: reaction.norm(),
        contact_frames,
        frames,
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let seconds = flag("--seconds")
        .and_then(|s| s.parse().ok())
        .unwrap_or(3.0);
    let materials: Vec<String> = flag("--materials")
        .map(|m| m.split(',').map(str::to_owned).collect())
        .unwrap_or_else(|| vec!["rubber".into(), "soft_rubber".into(), "jelly".into()]);
    println!(
        "live mode at a 30 fps refresh (T_i = 33.3 ms): 1 m cube on the floor, live capsule pressed into its top \
         and dragged down 5 mm a frame against the reaction; {} threads, {seconds} s per row",
        rayon_threads()
    );
    println!("T_c: one solver step; T_r: CPU draw prep of the window (7938-triangle embedded sphere); stable: the world's step bound;");
    println!("cost/sim: T_c / stable (real time needs < 1); sim/real: simulated seconds per wall second at 30 fps; raster: 800x600 screenshot");
    println!(
        "{:<12} {:>6} {:>7} {:>8} {:>8} {:>7} {:>9} {:>8} {:>9} {:>8} {:>8} {:>11} {:>9}",
        "material",
        "nodes",
        "total",
        "springs",
        "T_c ms",
        "T_r ms",
        "stable ms",
        "cost/sim",
        "steps/fr",
        "steps/s",
        "sim/real",
        "reaction N",
        "raster ms"
    );
    for material in &materials {
        for n in [8, 16, 32] {
            match run(n, material, seconds) {
                Ok(r) => {
                    let steps_per_s = (1.0 - 30.0 * r.draw_ms * 1e-3) / (r.step_ms * 1e-3);
                    println!(
                        "{:<12} {:>5}³ {:>7} {:>8} {:>8.3} {:>7.2} {:>9.3} {:>8.2} {:>9} {:>8.0} {:>8.3} {:>11.1} {:>9.1}",
                        material,
                        r.nodes_per_side,
                        r.nodes,
                        r.springs,
                        r.step_ms,
                        r.draw_ms,
                        r.max_dt_ms,
                        r.step_ms / r.max_dt_ms,
                        r.steps_per_frame,
                        steps_per_s,
                        r.realtime_factor,
                        r.reaction_n,
                        r.raster_ms
                    );
                    if r.contact_frames < r.frames / 2 {
                        println!(
                            "  (the capsule touched the body in only {}/{} frames)",
                            r.contact_frames, r.frames
                        );
                    }
                }
                Err(e) => {
                    eprintln!("{material} {n}³: {e}");
                    std::process::exit(1);
                }
            }
        }
    }
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
