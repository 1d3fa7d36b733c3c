//! The GPU solver's throughput (issue 24): a 1 m rubber cube of N³ nodes dropped from 1 m onto
//! the floor (display-surface contact at half a cell, as the product sets a mesh up), stepped
//! frame by frame on the GPU and, up to `--cpu-max` nodes per side, on the CPU; prints node-
//! substeps per second, seconds per frame and the adapter, one line per size.
//!
//! `cargo run --release -p springbake-gpu --example gpu_bench -- [N ...] [--frames F]
//! [--cpu-max N]` (defaults: 16 32 64, 10 frames, CPU up to 32).
#![allow(clippy::unwrap_used)]

#[path = "../tests/support/mod.rs"]
mod support;

use springbake_core::nalgebra::Rotation3;
use springbake_core::solver::World;
use springbake_gpu::GpuSolver;
use std::time::Instant;

/// Node-substeps per second and seconds per frame of `frames` frames of `world`.
fn run(mut world: World, frames: usize) -> (f64, f64, u32) {
    let nodes = world.nodes.len() as f64;
    let mut substeps = 0u64;
    let mut last = 0;
    let start = Instant::now();
    for f in 1..=frames {
        let d = world.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        substeps += u64::from(d.substeps);
        last = d.substeps;
    }
    let seconds = start.elapsed().as_secs_f64();
    (
        nodes * substeps as f64 / seconds,
        seconds / frames as f64,
        last,
    )
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut sizes = Vec::new();
    let (mut frames, mut cpu_max) = (10usize, 32u32);
    let mut k = 0;
    while k < args.len() {
        match args[k].as_str() {
            "--frames" => {
                frames = args[k + 1].parse().unwrap();
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
    if sizes.is_empty() {
        sizes = vec![16, 32, 64];
    }
    let adapter = springbake_gpu::probe().map(|a| a.name);
    println!("adapter: {adapter:?}; {frames} frames per size");
    for n in sizes {
        let make = || support::box_world(1.0, Rotation3::identity(), 1.0, n - 1, "rubber");
        let mut gpu = make();
        let built = Instant::now();
        let model = gpu.device_model().unwrap();
        let solver = GpuSolver::new(&model).unwrap();
        gpu.attach_device(Box::new(solver));
        let setup = built.elapsed().as_secs_f64();
        let (rate, per_frame, substeps) = run(gpu, frames);
        print!(
            "{n}³ = {} nodes, {substeps} substeps/frame: GPU {:.2} M node-steps/s, {:.1} ms/frame \
             (setup {setup:.2} s)",
            n * n * n,
            rate * 1e-6,
            per_frame * 1e3
        );
        if n <= cpu_max {
            let (rate, per_frame, _) = run(make(), frames);
            print!(
                "; CPU {:.2} M node-steps/s, {:.1} ms/frame",
                rate * 1e-6,
                per_frame * 1e3
            );
        }
        println!();
    }
}
