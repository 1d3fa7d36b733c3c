//! The GPU solver's throughput (issue 24): a 1 m rubber cube of N³ nodes dropped from 1 m onto
//! the floor (display-surface contact at half a cell, as the product sets a mesh up), stepped
//! frame by frame on the GPU and, up to `--cpu-max` nodes per side, on the CPU; prints node-
//! substeps per second, seconds per frame and the adapter, one line per size.
//!
//! `--live N` adds the live viewer's case: a 0.5 m jelly cube of N³ nodes on the floor swept
//! broadside (the capsule's axis across the motion) by a 5 cm capsule at 1 m/s, stepped in frames of 1/60 s as the viewer steps them (solve
//! and read back; drawing not counted): median and slowest milliseconds per frame against
//! the 16.7 ms of 60 fps.
//!
//! `--profile` adds, per size, each stage's GPU time per substep (timestamp queries), and the
//! host's share of a frame. `--trace` prints each frame's substeps, inverted cells and time.
//!
//! `cargo run --release -p springbake-gpu --example gpu_bench -- [N ...] [--frames F]
//! [--cpu-max N] [--live N] [--profile] [--trace]` (defaults: 16 32 64, 10 frames, CPU up to 32, no
//! live case, no profile).
#![allow(clippy::unwrap_used)]

#[path = "../tests/support/mod.rs"]
mod support;

use springbake_core::nalgebra::Rotation3;
use springbake_core::solver::device::{DeviceFrame, DeviceSolver};
use springbake_core::solver::World;
use springbake_gpu::GpuSolver;
use std::time::Instant;

/// What [`run`] measured.
struct Run {
    node_steps_per_second: f64,
    seconds_per_frame: f64,
    last_substeps: u32,
    /// The most cells inverted at a frame's end, and the first such frame.
    inverted: Option<(usize, usize)>,
}

/// `frames` frames of `world`, timed; with `trace`, a line per frame (its substeps, inverted
/// cells and milliseconds) under `label`.
fn run(mut world: World, frames: usize, trace: Option<&str>) -> Run {
    let nodes = world.nodes.len() as f64;
    let (mut substeps, mut last_substeps) = (0u64, 0);
    let mut inverted: Option<(usize, usize)> = None;
    let start = Instant::now();
    for f in 1..=frames {
        let frame_start = Instant::now();
        let d = world.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        if let Some(label) = trace {
            println!(
                "  {label} frame {f}: {} substeps, {} inverted, {:.1} ms",
                d.substeps,
                d.inverted_cells,
                frame_start.elapsed().as_secs_f64() * 1e3
            );
        }
        if d.inverted_cells > 0 {
            let (most, first) = inverted.unwrap_or((0, f));
            inverted = Some((most.max(d.inverted_cells), first));
        }
        substeps += u64::from(d.substeps);
        last_substeps = d.substeps;
    }
    let seconds = start.elapsed().as_secs_f64();
    Run {
        node_steps_per_second: nodes * substeps as f64 / seconds,
        seconds_per_frame: seconds / frames as f64,
        last_substeps,
        inverted,
    }
}

/// ", inverted cells: N from frame F" when there were.
fn inverted_note(r: &Run) -> String {
    r.inverted
        .map(|(n, f)| format!(", INVERTED CELLS: up to {n} from frame {f}"))
        .unwrap_or_default()
}

/// Each stage's name and microseconds per substep.
type Stages = Vec<(&'static str, f64)>;

/// What [`profile`] measured: each stage's µs per substep, a frame's ms through
/// `advance_frame` and in the solver alone, and the host's substep choice and diagnostics, ms.
struct Profile {
    stages: Stages,
    frame_ms: f64,
    solver_ms: f64,
    host: (f64, f64),
}

/// Substeps per frame in [`profile`].
const PROFILED_SUBSTEPS: u32 = 30;

/// Where a frame's time goes, on worlds from `make` held at [`PROFILED_SUBSTEPS`] a frame:
/// the second frame's milliseconds through `advance_frame` and in the solver alone (upload,
/// substeps, read back; the rest is the world's own frame work: energies, inverted cells),
/// and each stage's microseconds per substep (timestamp queries).
fn profile(make: impl Fn() -> World) -> Result<Profile, String> {
    let fixed = || {
        let mut w = make();
        w.settings.fixed_substeps = Some(PROFILED_SUBSTEPS);
        w
    };
    let (mut world, _) = on_gpu(fixed());
    let mut frame_ms = 0.0;
    for f in 1..=2 {
        let start = Instant::now();
        world
            .advance_frame(1.0 / 24.0, f, &|| false)
            .map_err(|e| e.to_string())?;
        frame_ms = start.elapsed().as_secs_f64() * 1e3;
    }
    // The substep choice measured apart (held at a fixed count the frames above skip it), and
    // the diagnostics as the CPU measures them (a frame on the device takes the census's).
    world.settings.fixed_substeps = None;
    let start = Instant::now();
    world.choose_substeps(1.0 / 24.0);
    let choice_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    world.diagnostics(2);
    let host = (choice_ms, start.elapsed().as_secs_f64() * 1e3);
    let mut world = fixed();
    let model = world.device_model().map_err(|e| e.to_string())?;
    let mut solver = GpuSolver::new(&model).map_err(|e| e.to_string())?;
    let mut solver_ms = 0.0;
    for _ in 0..2 {
        let nodes = &mut world.nodes;
        let start = Instant::now();
        solver.advance(DeviceFrame {
            substeps: PROFILED_SUBSTEPS,
            dt: 1.0 / 24.0 / f64::from(PROFILED_SUBSTEPS),
            position: &mut nodes.position,
            velocity: &mut nodes.velocity,
            capsules: &[],
            capsule_count: 0,
        })?;
        solver_ms = start.elapsed().as_secs_f64() * 1e3;
    }
    let stages = solver.profile(PROFILED_SUBSTEPS)?;
    let stages = stages
        .into_iter()
        .map(|(name, s)| (name, s * 1e6))
        .collect();
    Ok(Profile {
        stages,
        frame_ms,
        solver_ms,
        host,
    })
}

/// The world on the GPU (setup seconds with it).
fn on_gpu(mut world: World) -> (World, f64) {
    let built = Instant::now();
    let model = world.device_model().unwrap();
    world.attach_device(Box::new(GpuSolver::new(&model).unwrap()));
    (world, built.elapsed().as_secs_f64())
}

/// The live viewer's scene (module docs) on N³ nodes.
fn live_world(n: u32) -> World {
    let mut world = support::box_world(0.5, Rotation3::identity(), 0.0, n - 1, "jelly");
    support::sweep_along_x(&mut world, (0.05, 1.0, 90.0), 0.2, (-0.6, 0.6), 1.2);
    world
}

/// The live viewer's case (module docs): median and slowest ms per 1/60 s frame, substeps
/// in the last frame, most inverted cells in a frame.
fn live(n: u32, frames: usize, gpu: bool) -> (f64, f64, u32, usize) {
    let mut world = live_world(n);
    if gpu {
        world = on_gpu(world).0;
    }
    let mut times = Vec::with_capacity(frames);
    let (mut last, mut inverted) = (0, 0);
    for f in 1..=frames {
        let start = Instant::now();
        let d = world.advance_frame(1.0 / 60.0, f, &|| false).unwrap();
        times.push(start.elapsed().as_secs_f64() * 1e3);
        inverted = inverted.max(d.inverted_cells);
        last = d.substeps;
    }
    let slowest = times.iter().copied().fold(0.0, f64::max);
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], slowest, last, inverted)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut sizes = Vec::new();
    let (mut frames, mut cpu_max) = (10usize, 32u32);
    let mut live_sizes = Vec::new();
    let mut profiled = false;
    let mut traced = false;
    let mut k = 0;
    while k < args.len() {
        match args[k].as_str() {
            "--frames" => {
                frames = args[k + 1].parse().unwrap();
                k += 1;
            }
            "--profile" => profiled = true,
            "--trace" => traced = true,
            "--live" => {
                live_sizes.push(args[k + 1].parse::<u32>().unwrap());
                k += 1;
            }
            "--cpu-max" => {
                cpu_max = args[k + 1].parse().unwrap();
                k += 1;
            }
            n => sizes.push(n.parse::<u32>().unwrap()),
        }
        k += 1;
    }
    if sizes.is_empty() && live_sizes.is_empty() {
        sizes = vec![16, 32, 64];
    }
    let adapter = springbake_gpu::probe().map(|a| a.name);
    println!("adapter: {adapter:?}; {frames} frames per size");
    for n in sizes {
        let make = || support::box_world(1.0, Rotation3::identity(), 1.0, n - 1, "rubber");
        let (gpu, setup) = on_gpu(make());
        let r = run(gpu, frames, traced.then_some("GPU"));
        print!(
            "{n}³ = {} nodes, {} substeps/frame: GPU {:.2} M node-steps/s, {:.1} ms/frame \
             (setup {setup:.2} s){}",
            n * n * n,
            r.last_substeps,
            r.node_steps_per_second * 1e-6,
            r.seconds_per_frame * 1e3,
            inverted_note(&r)
        );
        if n <= cpu_max {
            let r = run(make(), frames, traced.then_some("CPU"));
            print!(
                "; CPU {:.2} M node-steps/s, {:.1} ms/frame{}",
                r.node_steps_per_second * 1e-6,
                r.seconds_per_frame * 1e3,
                inverted_note(&r)
            );
        }
        println!();
        if profiled {
            print_profile(make);
        }
    }
    for n in live_sizes {
        let frames = 120;
        let (median, slowest, substeps, inverted) = live(n, frames, true);
        print!(
            "live {n}³ jelly, {frames} frames of 1/60 s, {substeps} substeps/frame: GPU median \
             {median:.1} ms, slowest {slowest:.1} ms, {inverted} cells inverted"
        );
        if n <= cpu_max {
            let (median, slowest, _, inverted) = live(n, frames, false);
            print!("; CPU median {median:.1} ms, slowest {slowest:.1} ms, {inverted} inverted");
        }
        println!(" (60 fps: 16.7 ms)");
        if profiled {
            print_profile(|| live_world(n));
        }
    }
}

/// [`profile`]'s figures, or why there are none.
fn print_profile(make: impl Fn() -> World) {
    match profile(make) {
        Ok(Profile {
            stages,
            frame_ms,
            solver_ms,
            host: (choice_ms, diagnostics_ms),
        }) => {
            println!(
                "  a frame of {PROFILED_SUBSTEPS} substeps: {frame_ms:.1} ms, of which \
                 {solver_ms:.1} ms in the solver (upload, substeps, census, read back) and \
                 {:.1} ms the world's own on the host; a substep choice {choice_ms:.1} ms; \
                 the CPU's diagnostics of that state (no census) {diagnostics_ms:.1} ms",
                frame_ms - solver_ms
            );
            let total: f64 = stages.iter().map(|s| s.1).sum();
            print!("  µs per substep, {total:.1} in all:");
            for (name, us) in stages {
                print!(" {name} {us:.1};");
            }
            println!();
        }
        Err(e) => println!("  no profile: {e}"),
    }
}
