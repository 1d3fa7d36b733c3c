//! The new solver's targets (issue 16) measured on built-in scenes, for any integrator:
//! rebound per material preset, fidelity against the explicit solver (centre of mass over a
//! drop and two bounces, resting height), spin kept by a free cube, a column's sag under its
//! own weight, the jelly block swept by the capsule (inverted cells, time per frame), the
//! jelly ball dropped at 8 m/s with volume preservation, a 1 cm cube, rubber cubes of 1 cm
//! to 1 m dropped at two frame rates, a rubber ball and cubes bouncing for 4 s (each bounce's
//! height and energy) and tilted cubes tumbling (whether a bounce ever adds energy). Prints
//! one line per check; nothing here is asserted (the tests in `core/tests/xpbd.rs` are).
//!
//! `cargo run --release -p springbake-core --example solver_checks [-- [xpbd|euler|newmark]
//! [--substeps N] [rebound fidelity spin column sweep ball tiny scale bounces tumbles live]]`
//! (no check named: all)

use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::{box_mesh, uv_sphere};
use springbake_core::solver::manipulator::ManipulatorKey;
use springbake_core::solver::{Capsule, Integrator, ManipulatorTrack, World};
use std::time::Instant;

const FPS: f64 = 24.0;

#[path = "../tests/support/mod.rs"]
mod support;
use support::{mesh as body, product_world, spin_kept, Mesh as Body};

/// A world with a floor at y = 0 (unless `floor` is false) holding `b` in `material`, set up as
/// the product sets up a mesh, at `--substeps` when given.
fn world(
    b: &Body,
    material: &Material,
    integrator: Integrator,
    velocity: Vector3<f64>,
    floor: bool,
) -> World {
    let mut w = product_world(b, material, integrator, velocity, floor);
    w.settings.fixed_substeps = SUBSTEPS.with(|s| s.get());
    w
}

fn centre(w: &World) -> Vector3<f64> {
    let n = &w.nodes;
    let m: f64 = n.mass.iter().sum();
    (0..n.len())
        .map(|i| n.position[i] * n.mass[i])
        .sum::<Vector3<f64>>()
        / m
}

fn lowest(w: &World) -> f64 {
    w.nodes
        .position
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min)
}

/// The lowest display-surface contact point's height, m.
fn lowest_surface(w: &World) -> f64 {
    let (s, x) = (&w.surface, &w.nodes.position);
    (0..s.nodes.len())
        .map(|k| {
            (0..8)
                .map(|c| x[s.nodes[k][c] as usize].y * s.weights[k][c])
                .sum::<f64>()
        })
        .fold(f64::INFINITY, f64::min)
}

fn frame(w: &mut World, f: usize) -> springbake_core::solver::FrameDiagnostics {
    w.advance_frame(1.0 / FPS, f, &|| false).expect("finite")
}

/// Drop a ball of radius 0.1 m from 1 m (its bottom) and report the highest its bottom gets
/// after the first bounce.
fn rebound(material: &Material, integrator: Integrator) {
    let mut w = world(
        &support::rebound_ball(),
        material,
        integrator,
        Vector3::zeros(),
        true,
    );
    let t0 = Instant::now();
    let r = support::rebound(&mut w, 72);
    println!(
        "rebound {:>12}: ball r 0.1 m from 1 m bounces to {:.3} m (volume within {:.1} %, {} substeps, inverted max {}, {:.1} ms/frame)",
        material.name,
        r.peak,
        r.volume_change * 100.0,
        r.substeps,
        r.inverted,
        t0.elapsed().as_secs_f64() * 1e3 / 72.0
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let integrator = if args.iter().any(|a| a == "euler") {
        Integrator::SymplecticEuler
    } else if args.iter().any(|a| a == "newmark") {
        Integrator::newmark()
    } else {
        Integrator::Xpbd
    };
    let substeps = args
        .iter()
        .position(|a| a == "--substeps")
        .and_then(|i| args.get(i + 1))
        .and_then(|n| n.parse().ok());
    SUBSTEPS.with(|s| s.set(substeps));
    let wanted = |name: &str| {
        let named: Vec<&String> = args
            .iter()
            .filter(|a| {
                [
                    "rebound",
                    "fidelity",
                    "spin",
                    "column",
                    "cantilever",
                    "sweep",
                    "ball",
                    "tiny",
                    "scale",
                    "bounces",
                    "tumbles",
                ]
                .contains(&a.as_str())
            })
            .collect();
        named.is_empty() || named.iter().any(|a| *a == name)
    };
    println!(
        "integrator {integrator:?}, substeps {}, load {}",
        substeps.map_or("auto".to_string(), |n: u32| n.to_string()),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    if wanted("rebound") {
        for name in ["jelly", "soft_rubber", "rubber", "foam", "wood", "steel"] {
            rebound(&Material::preset(name).expect("preset"), integrator);
        }
    }
    if wanted("fidelity") {
        fidelity(integrator);
    }
    if wanted("spin") {
        spin(integrator);
    }
    if wanted("column") {
        column(integrator);
    }
    if wanted("cantilever") {
        cantilever(integrator);
    }
    if wanted("sweep") {
        jelly_sweep(integrator, 2.0);
        jelly_sweep(integrator, 1.0);
    }
    if wanted("ball") {
        jelly_ball(integrator, true);
        jelly_ball(integrator, false);
    }
    if wanted("tiny") {
        tiny_cube(integrator);
    }
    if wanted("scale") {
        for edge in [0.01, 0.1, 1.0] {
            scaled_drop(integrator, edge, edge);
        }
        scaled_drop(integrator, 0.1, 1.0);
        scaled_drop(integrator, 0.2, 1.0);
    }
    if wanted("bounces") {
        bounces(integrator, "ball r 0.1 m", &support::rebound_ball(), 0.1);
        for (edge, cells) in [(0.1, 10), (0.2, 10), (1.0, 10)] {
            let (p, t) = box_mesh([0.0, 1.0, 0.0], [edge, 1.0 + edge, edge]);
            bounces(
                integrator,
                &format!("{edge} m cube"),
                &body((p, t), cells),
                0.5 * edge,
            );
        }
    }
    if wanted("tumbles") {
        tumbles(integrator);
    }
    if wanted("live") {
        live(integrator);
    }
}

/// The kinetic and gravity energy above rest of a body as each of its flights starts (every
/// display-surface point 5 mm above the floor), J: no bounce can add to it.
#[derive(Default)]
struct Flights {
    energies: Vec<f64>,
    flying: bool,
}

impl Flights {
    /// After a frame: `rest` is the height of the body's centre at rest on the floor, m.
    fn record(&mut self, w: &World, d: &springbake_core::solver::FrameDiagnostics, rest: f64) {
        let airborne = lowest_surface(w) > 0.005;
        if airborne && !self.flying {
            let mass: f64 = w.nodes.mass.iter().sum();
            let g = w.settings.gravity.norm();
            (self.energies).push(d.kinetic_energy + d.gravity_energy - mass * g * rest);
        }
        self.flying = airborne;
    }

    /// The largest rise of a flight's energy over the one before, a share of it.
    fn largest_rise(&self) -> f64 {
        (self.energies.windows(2))
            .map(|p| (p[1] - p[0]) / p[0])
            .fold(0.0, f64::max)
    }

    fn list(&self) -> String {
        let each: Vec<String> = self.energies.iter().map(|e| format!("{e:.2}")).collect();
        each.join(", ")
    }
}

/// A rubber body dropped from 1 m (its bottom; `rest` is its centre's height at rest on the
/// floor), 4 s at 24 frames a second: the peak of each bounce (the centre's height above
/// `rest`) and its share of the one before. A damped elastic body keeps one share from bounce
/// to bounce, whatever the height; a solver that loses more at slow impacts shows the shares
/// falling.
fn bounces(integrator: Integrator, name: &str, b: &Body, rest: f64) {
    let rubber = Material::preset("rubber").expect("preset");
    let mut w = world(b, &rubber, integrator, Vector3::zeros(), true);
    let t0 = Instant::now();
    let start = centre(&w).y - rest;
    let (mut peaks, mut last, mut rising) = (vec![start], centre(&w).y, false);
    let mut substeps = Vec::new();
    let mut flights = Flights::default();
    for f in 1..=96 {
        let d = frame(&mut w, f);
        substeps.push(d.substeps);
        flights.record(&w, &d, rest);
        let y = centre(&w).y;
        if y > last + 1e-5 {
            rising = true;
        } else if rising && y < last {
            rising = false;
            // Wobbles on the floor are not bounces.
            if last - rest > 0.005 {
                peaks.push(last - rest);
            }
        }
        last = y;
    }
    let shares: Vec<String> = peaks
        .windows(2)
        .map(|p| format!("{:.0} %", 100.0 * p[1] / p[0]))
        .collect();
    let heights: Vec<String> = peaks.iter().map(|p| format!("{p:.3}")).collect();
    println!(
        "bounces {name}: peaks {} m, each of the one before {}; energy above rest in each flight {} J; substeps a frame {}–{}, {:.2} s",
        heights.join(", "),
        shares.join(", "),
        flights.list(),
        substeps.iter().min().unwrap_or(&0),
        substeps.iter().max().unwrap_or(&0),
        t0.elapsed().as_secs_f64()
    );
}

/// Cubes dropped 1 m tilted, so they land on an edge or a corner and tumble (rubber and soft
/// rubber, 10 and 20 cm, 10 cells, three tilts), 3 s at 24 frames a second: the energy above
/// rest (kinetic + gravity) in each flight, and the largest rise from one flight to the next,
/// which no bounce can give.
fn tumbles(integrator: Integrator) {
    let mut worst = 0.0_f64;
    let t0 = Instant::now();
    for material in ["rubber", "soft_rubber"] {
        for edge in [0.1, 0.2] {
            for (ax, az) in [(0.3, 0.2), (0.6, 0.1), (0.15, 0.7)] {
                let (p, t) = box_mesh([-0.5 * edge; 3], [0.5 * edge; 3]);
                let turn = springbake_core::nalgebra::Rotation3::from_euler_angles(ax, 0.0, az);
                let lift = Vector3::new(0.0, 1.0 + edge, 0.0);
                let p = p.into_iter().map(|q| turn * q + lift).collect();
                let b = body((p, t), 10);
                let m = Material::preset(material).expect("preset");
                let mut w = world(&b, &m, integrator, Vector3::zeros(), true);
                let mut flights = Flights::default();
                for f in 1..=72 {
                    let d = frame(&mut w, f);
                    flights.record(&w, &d, 0.5 * edge);
                }
                let rise = flights.largest_rise();
                worst = worst.max(rise);
                println!(
                    "tumbles {material} {edge} m tilted ({ax}, {az}): energy above rest in each flight {} J, largest rise {:.0} %",
                    flights.list(),
                    100.0 * rise
                );
            }
        }
    }
    println!(
        "tumbles: largest rise of any flight's energy over the one before {:.0} %, {:.1} s",
        100.0 * worst,
        t0.elapsed().as_secs_f64()
    );
}

/// The viewer's live mode on a 1 m rubber cube (15 cells, 16³ nodes) resting on the floor, a
/// live capsule pressed 1 mm further into its top every frame: wall time of one 1/30 s frame
/// (the viewer steps `advance_frame` over the frame's time), against the 33 ms real time
/// allows.
fn live(integrator: Integrator) {
    let (p, t) = box_mesh([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let b = body((p, t), 15);
    let rubber = Material::preset("rubber").expect("preset");
    let mut w = world(&b, &rubber, integrator, Vector3::zeros(), true);
    for f in 1..=6 {
        w.advance_frame(1.0 / 30.0, f, &|| false).expect("finite");
    }
    let mut capsule = Capsule {
        centre: Vector3::new(0.5, 1.04, 0.5),
        axis: Vector3::x(),
        length: 0.6,
        radius: 0.05,
        velocity: Vector3::new(0.0, -0.03, 0.0),
        friction: 0.3,
    };
    let t0 = Instant::now();
    let frames = 60;
    for f in 0..frames {
        capsule.centre.y -= 0.001;
        w.live_capsules = vec![capsule];
        w.advance_frame(1.0 / 30.0, 7 + f, &|| false)
            .expect("finite");
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3 / frames as f64;
    println!(
        "live: 16³ rubber cube pressed by the live capsule: {ms:.1} ms per 1/30 s frame ({:.0} frames/s of real time possible)",
        1e3 / ms
    );
}

thread_local! {
    /// `--substeps N`: a fixed substep count for every world.
    static SUBSTEPS: std::cell::Cell<Option<u32>> = const { std::cell::Cell::new(None) };
}

/// Rubber cube (0.5 m, 8 cells) dropped from 0.5 m: centre of mass over 48 frames, printed
/// every 4 frames, and the resting height after 4 s.
fn fidelity(integrator: Integrator) {
    let (p, t) = box_mesh([0.0, 0.5, 0.0], [0.5, 1.0, 0.5]);
    let b = body((p, t), 8);
    let rubber = Material::preset("rubber").expect("preset");
    let mut w = world(&b, &rubber, integrator, Vector3::zeros(), true);
    let mut line = String::new();
    for f in 1..=48 {
        frame(&mut w, f);
        if f % 2 == 0 {
            line += &format!(" {:.3}", centre(&w).y);
        }
    }
    println!(
        "fidelity: rubber cube centre y every 2 frames:{line}; lowest node {:.4} m",
        lowest(&w)
    );
}

/// A free rubber cube spinning at 1 rev/s about y (no gravity, no floor): spin kept after 1 s.
fn spin(integrator: Integrator) {
    let (p, t) = box_mesh([-0.25, -0.25, -0.25], [0.25, 0.25, 0.25]);
    let b = body((p, t), 8);
    let rubber = Material::preset("rubber").expect("preset");
    let mut w = world(&b, &rubber, integrator, Vector3::zeros(), false);
    println!(
        "spin: free rubber cube keeps {:.1} % of 1 rev/s after 1 s",
        100.0 * spin_kept(&mut w)
    );
}

/// A cantilever (1 × 0.1 × 0.1 m, 20 cells long) clamped at x = 0, sagging under its own
/// weight for 4 s: tip sag against Euler–Bernoulli's `w L⁴ / (8 E I)`, which does not depend
/// on ν (a model that locks as ν → 0.5 sags less). E = 100 MPa (ρ = 1000) at ν = 0.3, 0.47 and
/// 0.4995 (run with `--substeps 300` to see it converge: at the automatic 30 the sweep leaves
/// it far softer); E = 10 MPa at 10, 20 and 40 cells along, automatic and 300 substeps (at the
/// automatic count a finer lattice bends more: the sweep resolves less of the stiffness); wood
/// held rigid and solved elastic.
fn cantilever(integrator: Integrator) {
    let beam_of =
        |length: f64, cells: u32| body(box_mesh([0.0, 0.5, 0.0], [length, 0.6, 0.1]), cells);
    let beam = |cells: u32| beam_of(1.0, cells);
    let b = beam(20);
    let sag_of = |b: &Body, m: &Material, hold: bool, substeps: Option<u32>| {
        let mut w = world(b, m, integrator, Vector3::zeros(), false);
        w.hold_stiff_bodies = hold;
        if substeps.is_some() {
            w.settings.fixed_substeps = substeps;
        }
        let start = w.nodes.position.clone();
        let root: Vec<usize> = (0..start.len()).filter(|&i| start[i].x < 1e-9).collect();
        w.pin(&root).expect("pins");
        let end = start.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
        let tip: Vec<usize> = (0..start.len())
            .filter(|&i| start[i].x > end - 1e-9)
            .collect();
        for f in 1..=96 {
            frame(&mut w, f);
        }
        let sum: f64 = tip
            .iter()
            .map(|&i| start[i].y - w.nodes.position[i].y)
            .sum();
        sum / tip.len() as f64
    };
    let sag = |m: &Material, hold: bool| sag_of(&b, m, hold, None);
    let theory_of = |m: &Material, length: f64| {
        let load = m.density_kg_m3 * 9.81 * 0.01;
        load * length.powi(4) / (8.0 * m.young_pa * 0.1 * 0.1f64.powi(3) / 12.0)
    };
    let theory = |m: &Material| theory_of(m, 1.0);
    let mut line = String::new();
    for nu in [0.3, 0.47, 0.4995] {
        let m = Material::new("beam", 1.0e8, nu, 1000.0, 0.5).expect("material");
        line += &format!(" nu {nu} {:.2} mm;", sag(&m, true) * 1e3);
    }
    let m = Material::new("beam", 1.0e8, 0.3, 1000.0, 0.5).expect("material");
    println!(
        "cantilever E 100 MPa tip sag:{line} Euler-Bernoulli {:.2} mm",
        theory(&m) * 1e3
    );
    // A beam of `length` at each cell count: tip sag at the automatic substeps and at 300.
    let by_cells = |m: &Material, length: f64, counts: [u32; 3]| {
        let mut line = String::new();
        for cells in counts {
            let b = beam_of(length, cells);
            let auto = sag_of(&b, m, true, None);
            let many = sag_of(&b, m, true, Some(300));
            line += &format!(
                " {cells} cells {:.0} mm (300 substeps {:.0});",
                auto * 1e3,
                many * 1e3
            );
        }
        line
    };
    let stiff = Material::new("E 10 MPa", 1.0e7, 0.3, 1000.0, 0.5).expect("material");
    println!(
        "cantilever E 10 MPa by cells:{} Euler-Bernoulli {:.0} mm",
        by_cells(&stiff, 1.0, [10, 20, 40]),
        theory(&stiff) * 1e3
    );
    // Rubber's E, ν and ρ (damping 0.5, so it settles in the 4 s), a 0.5 m beam: small strain.
    let rubber = Material::new("rubber", 1.5e6, 0.47, 1100.0, 0.5).expect("material");
    println!(
        "cantilever rubber 0.5 m by cells:{} Euler-Bernoulli {:.0} mm",
        by_cells(&rubber, 0.5, [5, 10, 20]),
        theory_of(&rubber, 0.5) * 1e3
    );
    let wood = Material::preset("wood").expect("preset");
    println!(
        "cantilever wood tip sag: held rigid {:.3} mm, elastic {:.1} mm; Euler-Bernoulli {:.3} mm",
        sag(&wood, true) * 1e3,
        sag(&wood, false) * 1e3,
        theory(&wood) * 1e3
    );
}

/// A soft column (0.2 × 1 × 0.2 m, E = 1 MPa, ρ = 1000) standing on the floor, its base
/// nodes pinned: top sag after settling against ρ g h² / (2E).
fn column(integrator: Integrator) {
    let (p, t) = box_mesh([0.0, 0.0, 0.0], [0.2, 1.0, 0.2]);
    let b = body((p, t), 10);
    let m = Material::new("column", 1.0e6, 0.0, 1000.0, 0.5).expect("material");
    let mut w = world(&b, &m, integrator, Vector3::zeros(), true);
    let base: Vec<usize> = (0..w.nodes.len())
        .filter(|&i| w.nodes.position[i].y < 1e-9)
        .collect();
    w.pin(&base).expect("pins");
    let top0 = w.nodes.position.iter().map(|p| p.y).fold(0.0, f64::max);
    for f in 1..=96 {
        frame(&mut w, f);
    }
    let top = w.nodes.position.iter().map(|p| p.y).fold(0.0, f64::max);
    let expected = 1000.0 * 9.81 * 1.0 / (2.0 * 1.0e6);
    println!(
        "column: top sags {:.3} mm, rho g h^2/(2E) = {:.3} mm",
        (top0 - top) * 1e3,
        expected * 1e3
    );
}

/// A 30 cm jelly block (8 cells) on the floor swept broadside by a 4 cm capsule at `speed`.
fn jelly_sweep(integrator: Integrator, speed: f64) {
    let (p, t) = box_mesh([-0.15, 0.0, -0.15], [0.15, 0.3, 0.15]);
    let b = body((p, t), 8);
    let jelly = Material::preset("jelly").expect("preset");
    let mut w = world(&b, &jelly, integrator, Vector3::zeros(), true);
    w.manipulators.push(ManipulatorTrack {
        radius: 0.04,
        length: 0.6,
        friction: 0.3,
        smooth: false,
        keys: vec![
            ManipulatorKey {
                t: 0.0,
                position: Vector3::new(-0.6, 0.15, 0.0),
                yaw_deg: 90.0,
            },
            ManipulatorKey {
                t: 1.2 / speed,
                position: Vector3::new(0.6, 0.15, 0.0),
                yaw_deg: 90.0,
            },
        ],
        up: Vector3::y(),
    });
    let (mut worst, mut last, mut frames) = (0, 0, 0);
    let t0 = Instant::now();
    for f in 1..=48 {
        let d = frame(&mut w, f);
        worst = worst.max(d.inverted_cells);
        last = d.inverted_cells;
        frames += 1;
    }
    println!(
        "jelly sweep at {speed} m/s: inverted cells max {worst}, at the end {last}; {:.1} ms/frame",
        t0.elapsed().as_secs_f64() * 1e3 / frames as f64
    );
}

/// A jelly ball (r 0.5 m, 8 cells) thrown down at 8 m/s with volume preservation: the
/// largest deviation of the lattice volume from rest over 48 frames.
fn jelly_ball(integrator: Integrator, preserve: bool) {
    let (p, t) = uv_sphere([0.0, 0.52, 0.0], 0.5, 16, 32);
    let b = body((p, t), 8);
    let jelly = Material::preset("jelly").expect("preset");
    let mut w = world(&b, &jelly, integrator, Vector3::new(0.0, -8.0, 0.0), true);
    let h = springbake_core::solver::BodyHandle(0);
    if preserve {
        w.preserve_volume(h, 1.0).expect("volume");
    }
    let v0 = w.body_volume(h);
    let (mut worst, mut inverted) = (0.0f64, 0);
    let t0 = Instant::now();
    for f in 1..=48 {
        let d = frame(&mut w, f);
        worst = worst.max((w.body_volume(h) / v0 - 1.0).abs());
        if std::env::var("VOLTRACE").is_ok() {
            println!(
                "f {f} vol {:.4} substeps {}",
                w.body_volume(h) / v0,
                d.substeps
            );
        }
        inverted = inverted.max(d.inverted_cells);
    }
    println!(
        "jelly ball at 8 m/s, preserve_volume {preserve}: lattice volume within {:.2} % of rest, inverted max {inverted}; {:.1} ms/frame",
        worst * 100.0,
        t0.elapsed().as_secs_f64() * 1e3 / 48.0
    );
}

/// A 1 cm rubber cube dropped 1 cm: 72 frames' wall time and substeps.
fn tiny_cube(integrator: Integrator) {
    let (p, t) = box_mesh([0.0, 0.01, 0.0], [0.01, 0.02, 0.01]);
    let b = body((p, t), 10);
    let rubber = Material::preset("rubber").expect("preset");
    let mut w = world(&b, &rubber, integrator, Vector3::zeros(), true);
    let t0 = Instant::now();
    let mut substeps = 0;
    for f in 1..=72 {
        substeps = substeps.max(frame(&mut w, f).substeps);
    }
    println!(
        "1 cm rubber cube: 72 frames in {:.2} s, {substeps} substeps per frame at most, lowest node {:.5} m",
        t0.elapsed().as_secs_f64(),
        lowest(&w)
    );
}

/// A rubber cube of `edge` metres (10 cells) dropped from `drop` above the floor, baked at
/// 24 and at 240 frames a second for 2 s: its least height against its rest height (the
/// impact's squash, as the frames sample it) and the highest its centre of mass gets after
/// the first bounce, over its rest height, as a share of the drop.
fn scaled_drop(integrator: Integrator, edge: f64, drop: f64) {
    for fps in [24.0, 240.0] {
        let (p, t) = box_mesh([0.0, drop, 0.0], [edge, drop + edge, edge]);
        let b = body((p, t), 10);
        let rubber = Material::preset("rubber").expect("preset");
        let mut w = world(&b, &rubber, integrator, Vector3::zeros(), true);
        let height = |w: &World| {
            let ys = w.nodes.position.iter().map(|p| p.y);
            ys.clone().fold(f64::MIN, f64::max) - ys.fold(f64::MAX, f64::min)
        };
        let t0 = Instant::now();
        let (mut least, mut substeps) = (f64::INFINITY, 0.0_f64);
        let (mut rising, mut bounced, mut peak) = (false, false, 0.0_f64);
        let mut last = centre(&w).y;
        for f in 1..=(2.0 * fps) as usize {
            let d = w.advance_frame(1.0 / fps, f, &|| false).expect("finite");
            substeps = substeps.max(f64::from(d.substeps) * fps / FPS);
            least = least.min(height(&w));
            let y = centre(&w).y;
            if !bounced && y > last && last < 0.75 * edge {
                rising = true;
            }
            if rising && y < last {
                bounced = true;
                rising = false;
            }
            if rising {
                peak = peak.max(y - 0.5 * edge);
            }
            last = y;
        }
        println!(
            "scale: {edge} m rubber cube dropped {drop} m at {fps} frames/s: least height {:.1} % of rest, rebound {:.1} % of the drop, {substeps:.0} substeps a 1/24 s frame at most, {:.2} s",
            100.0 * least / edge,
            100.0 * peak / drop,
            t0.elapsed().as_secs_f64()
        );
    }
}
