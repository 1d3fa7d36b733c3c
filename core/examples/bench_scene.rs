//! Solver benchmark report (docs/benchmarks.md): node-steps per second of `World::step` for
//! 16³/32³/64³ lattices at 1 and 2 threads, time per frame against node count, the standard
//! scene end to end (1 m rubber cube, 15 cells per side, dropped from 1 m, 100 frames at 24 fps)
//! with its correctness checks, and memory per node.
//!
//! `cargo run --release -p springbake-core --example bench_scene [-- --json] [-- --quick]`
//! `--json` prints one JSON line last (for scripts/bench.sh); `--quick` skips 64³ and the
//! frame-time sweep; `--standard` runs only the standard scene; `--trace [THREADS]` runs only the standard scene (1 thread unless given) and prints each frame's diagnostics and wall time;
//! `--step CELLS` times only the step of a CELLS-per-side cube, 1 and 2 threads (for profiling).

use springbake_core::lattice::{
    fit_lattice, surface_samples, FitSettings, Resolution, SpringLayout,
};
use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{Integrator, Plane, World, WorldSettings};
use std::time::Instant;

/// A rubber 1 m cube, `cells` per side, whose bottom is at `bottom` metres, resting above the
/// floor: with the Table 1 spring layout and node contact (`product = false`, the step
/// benchmarks), or set up as `springbake bake` sets up a mesh (`product = true`: the scene
/// default layout with body diagonals, contact on the display surface sampled at half a cell).
fn cube_world(cells: u32, bottom: f64, product: bool) -> World {
    let (p, t) = box_mesh([0.0, bottom, 0.0], [1.0, bottom + 1.0, 1.0]);
    let layout = if product {
        SpringLayout::Both
    } else {
        SpringLayout::FaceDiagonals
    };
    let lattice = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            layout,
            ..FitSettings::default()
        },
    )
    .expect("a box always fits");
    let m = Material::preset("rubber").expect("preset");
    let layer = WorldSettings::default_layer(lattice.cell_size, &m, 0.4);
    // The product's default solver (XPBD) for the product scene, unless SPRINGBAKE_BENCH_PAPER
    // asks for the papers' symplectic Euler; the step benchmarks measure the papers' kernel.
    let integrator = if product && std::env::var_os("SPRINGBAKE_BENCH_PAPER").is_none() {
        Integrator::Xpbd
    } else {
        Integrator::SymplecticEuler
    };
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer,
        integrator,
        ..WorldSettings::default()
    });
    let body = w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    if product {
        let (samples, areas) = surface_samples(&p, &t, 0.5 * lattice.cell_size);
        w.add_contact_surface(body, &lattice, &samples, &areas);
    }
    w
}

/// The step-benchmark state: a Table 1 cube (see [`cube_world`]).
fn world(cells: u32, bottom: f64) -> World {
    cube_world(cells, bottom, false)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
}

/// Node-steps per second of `World::step` for a `cells`-per-side cube touching the floor,
/// best of a few timed batches of at least `min_s` seconds each.
fn node_steps_per_s(cells: u32, threads: usize, min_s: f64) -> f64 {
    pool(threads).install(|| {
        // Bottom slightly inside the layer so the contact branch is exercised.
        let mut w = world(cells, -0.001);
        let dt = w.choose_substeps(1.0 / 24.0).dt;
        let n = w.nodes.len() as f64;
        for _ in 0..3 {
            w.step(dt);
        }
        let mut best = 0.0f64;
        for _ in 0..3 {
            let t0 = Instant::now();
            let mut steps = 0u64;
            while t0.elapsed().as_secs_f64() < min_s {
                w.step(dt);
                steps += 1;
            }
            best = best.max(steps as f64 * n / t0.elapsed().as_secs_f64());
        }
        best
    })
}

/// Wall time of one frame (automatic substeps) for a cube of `cells` resting on the floor.
/// Up to 32³ one whole frame is timed; larger lattices time 40 substeps and multiply by the
/// frame's substep count (the third value says so).
fn frame_time(cells: u32, threads: usize) -> (f64, u32, bool) {
    pool(threads).install(|| {
        let mut w = world(cells, 0.0);
        if cells < 63 {
            let t0 = Instant::now();
            let d = w.advance_frame(1.0 / 24.0, 1, &|| false).expect("finite");
            (t0.elapsed().as_secs_f64(), d.substeps, false)
        } else {
            let choice = w.choose_substeps(1.0 / 24.0);
            let t0 = Instant::now();
            for _ in 0..40 {
                w.step(choice.dt);
            }
            let per_step = t0.elapsed().as_secs_f64() / 40.0;
            (per_step * choice.substeps as f64, choice.substeps, true)
        }
    })
}

struct Standard {
    wall_s: f64,
    substeps: u64,
    inverted_max: usize,
    penetration_max: f64,
    layer: f64,
    nodes: usize,
    /// The bound that sets the step (`SubstepChoice::limited_by`).
    limited_by: &'static str,
}

/// The standard scene: 15 cells per side (16³ nodes), bottom at 1 m, 100 frames at 24 fps,
/// set up as the product sets up a mesh (see [`cube_world`]).
fn standard(threads: usize, trace: bool) -> Standard {
    pool(threads).install(|| {
        let mut w = cube_world(15, 1.0, true);
        let layer = w.settings.layer.thickness_m;
        // What sets the substep count (the frames' counts can only rise above it, by speed).
        let limited_by = w.choose_substeps(1.0 / 24.0).limited_by;
        let t0 = Instant::now();
        let mut inverted_max = 0;
        let mut penetration_max = 0.0f64;
        let mut substeps = 0u64;
        for f in 1..=100 {
            let frame_start = Instant::now();
            let d = w.advance_frame(1.0 / 24.0, f, &|| false).expect("finite");
            let frame_ms = frame_start.elapsed().as_secs_f64() * 1e3;
            inverted_max = inverted_max.max(d.inverted_cells);
            penetration_max = penetration_max.max(d.max_penetration);
            substeps += d.substeps as u64;
            if trace {
                println!(
                    "    frame {f:>3}: {frame_ms:>6.1} ms, {} substeps, dispersion {} corrections / {} sweeps / {} cap hits, \
                     inverted {}, penetration {:.4} m, max speed {:.3} m/s",
                    d.substeps,
                    d.dispersion_corrections,
                    d.dispersion_iterations,
                    d.dispersion_cap_hits,
                    d.inverted_cells,
                    d.max_penetration,
                    d.max_speed
                );
            }
        }
        Standard {
            wall_s: t0.elapsed().as_secs_f64(),
            substeps,
            inverted_max,
            penetration_max,
            layer,
            nodes: w.nodes.len(),
            limited_by,
        }
    })
}

/// User + system CPU seconds of this process, all threads (`/proc/self/stat`, 100 Hz ticks):
/// `--step` prints how many cores were busy, which tells a shared machine's noise apart.
fn process_cpu_s() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name: utime and stime are the 12th and 13th.
    let after = s.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = after
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|x| x.parse().ok())
        .collect();
    f.iter().sum::<f64>() / 100.0
}

/// Peak resident memory of this process (VmHWM), bytes.
fn vm_hwm() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let json = args.iter().any(|a| a == "--json");
    let quick = args.iter().any(|a| a == "--quick");
    let trace = args.iter().any(|a| a == "--trace");
    let only_standard = args.iter().any(|a| a == "--standard");
    if trace {
        let threads = args
            .iter()
            .position(|a| a == "--trace")
            .and_then(|i| args.get(i + 1))
            .and_then(|t| t.parse().ok())
            .unwrap_or(1);
        let s = standard(threads, true);
        println!("{threads} thread(s): {:.2} s wall", s.wall_s);
        return;
    }
    if let Some(cells) = args
        .iter()
        .position(|a| a == "--step")
        .and_then(|i| args.get(i + 1))
    {
        let cells: u32 = cells.parse().expect("--step takes a cell count per side");
        println!("load average before: {}", load_average());
        for threads in [1, 2] {
            let cpu0 = process_cpu_s();
            let t0 = Instant::now();
            let r = node_steps_per_s(cells, threads, 2.0);
            let busy = (process_cpu_s() - cpu0) / t0.elapsed().as_secs_f64();
            println!(
                "  {:>2}³ nodes, {threads} thread(s): {:>7.2} M node-steps/s ({busy:.2} cores busy)",
                cells + 1,
                r / 1e6
            );
        }
        return;
    }
    let sizes: &[u32] = if quick { &[15, 31] } else { &[15, 31, 63] };
    println!("load average before: {}", load_average());

    // Memory first, in a fresh process state: VmHWM before and after building a 64³ world
    // and stepping it, divided by its nodes (includes the lattice fit's transient data).
    if only_standard {
        return standard_report(json);
    }
    let hwm0 = vm_hwm().unwrap_or(0);
    let (mem_nodes, arrays_bytes) = {
        let mut w = world(63, -0.001);
        w.step(1e-5);
        (w.nodes.len(), w.solver_bytes())
    };
    let hwm1 = vm_hwm().unwrap_or(0);
    let hwm_per_node = (hwm1.saturating_sub(hwm0)) as f64 / mem_nodes as f64;
    let arrays_per_node = arrays_bytes as f64 / mem_nodes as f64;
    println!(
        "memory, 64³ ({mem_nodes} nodes): solver arrays {arrays_per_node:.0} B/node (World::solver_bytes); \
         peak RSS growth {hwm_per_node:.0} B/node (VmHWM, includes the lattice fit)"
    );

    println!("\nWorld::step throughput (cube touching the floor, automatic dt):");
    let mut rows = Vec::new();
    for &c in sizes {
        for threads in [1, 2] {
            let r = node_steps_per_s(c, threads, if c >= 63 { 1.0 } else { 0.5 });
            println!(
                "  {:>2}³ nodes, {threads} thread(s): {:>7.2} M node-steps/s",
                c + 1,
                r / 1e6
            );
            rows.push(format!(
                "{{\"nodes_per_side\":{},\"threads\":{threads},\"node_steps_per_s\":{r:.0}}}",
                c + 1
            ));
        }
    }

    if !quick {
        println!("\nTime per frame (1/24 s, automatic substeps, resting on the floor):");
        for c in [7u32, 15, 31, 63] {
            for threads in [1, 2] {
                let (t, n, extrapolated) = frame_time(c, threads);
                println!(
                    "  {:>2}³ = {:>6} nodes, {threads} thread(s): {:>8.1} ms/frame ({n} substeps{})",
                    c + 1,
                    (c + 1).pow(3),
                    t * 1e3,
                    if extrapolated { ", from 40 timed" } else { "" }
                );
            }
        }
    }

    let (std_rows, ok) = standard_rows();
    println!("load average after: {}", load_average());
    if json {
        println!(
            "{{\"throughput\":[{}],\"standard\":[{}],\"bytes_per_node_arrays\":{arrays_per_node:.1},\"bytes_per_node_hwm\":{hwm_per_node:.1},\"ok\":{ok}}}",
            rows.join(","),
            std_rows.join(",")
        );
    }
    if !ok {
        std::process::exit(1);
    }
}

/// Runs the standard scene at 1 and 2 threads, printing a line each; returns the JSON rows and
/// whether the checks passed.
fn standard_rows() -> (Vec<String>, bool) {
    println!(
        "\nStandard scene (1 m rubber cube, 16³ nodes, dropped from 1 m, 100 frames @ 24 fps):"
    );
    let mut std_rows = Vec::new();
    let mut ok = true;
    for threads in [1, 2] {
        let s = standard(threads, false);
        let pass = s.inverted_max == 0 && s.penetration_max < s.layer;
        ok &= pass;
        println!(
            "  {threads} thread(s): {:.2} s wall, {} substeps (step set by {}), {} nodes, \
             {:.1} M node-steps/s, inverted cells max {}, max penetration {:.4} m (layer {:.4} m) {}",
            s.wall_s,
            s.substeps,
            s.limited_by,
            s.nodes,
            (s.substeps * s.nodes as u64) as f64 / s.wall_s / 1e6,
            s.inverted_max,
            s.penetration_max,
            s.layer,
            if pass { "OK" } else { "FAILED" }
        );
        std_rows.push(format!(
            "{{\"threads\":{threads},\"wall_s\":{:.4},\"substeps\":{},\"nodes\":{},\"limited_by\":\"{}\",\"inverted_max\":{},\"penetration_max\":{:.6},\"layer\":{:.6}}}",
            s.wall_s, s.substeps, s.nodes, s.limited_by, s.inverted_max, s.penetration_max, s.layer
        ));
    }
    (std_rows, ok)
}

/// `--standard`: only the standard scene (what scripts/bench.sh compares with Blender).
fn standard_report(json: bool) {
    let (rows, ok) = standard_rows();
    println!("load average after: {}", load_average());
    if json {
        println!("{{\"standard\":[{}],\"ok\":{ok}}}", rows.join(","));
    }
    if !ok {
        std::process::exit(1);
    }
}
