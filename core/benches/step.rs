//! Criterion benchmark of one `World::step`: a 1 m rubber cube resting on the floor, lattices
//! of 15, 31 and 63 cells per side (16³, 32³, 64³ nodes), with 1 and 2 rayon threads. The
//! throughput is reported in elements = nodes, so criterion prints node-steps per second.
//!
//! `cargo bench -p springbake-core --bench step` (add `-- 32` to run only the 32³ cases).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use springbake_core::lattice::{fit_lattice, FitSettings, Resolution};
use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{Plane, World, WorldSettings};
use std::time::Duration;

/// A rubber cube of `cells` per side whose bottom sits 1 mm inside the floor's layer, so the
/// contact path runs every step.
fn resting_cube(cells: u32) -> World {
    let (p, t) = box_mesh([0.0, -0.001, 0.0], [1.0, 0.999, 1.0]);
    let lattice = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            ..FitSettings::default()
        },
    )
    .expect("a box always fits");
    let m = Material::preset("rubber").expect("preset");
    let layer = WorldSettings::default_layer(lattice.cell_size, &m, 0.4);
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer,
        ..WorldSettings::default()
    });
    w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    w
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("world_step");
    for cells in [15u32, 31, 63] {
        let nodes = (cells as u64 + 1).pow(3);
        group.throughput(Throughput::Elements(nodes));
        if cells >= 63 {
            group.sample_size(10);
            group.measurement_time(Duration::from_secs(8));
        } else {
            group.sample_size(30);
            group.measurement_time(Duration::from_secs(4));
        }
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let mut world = pool.install(|| resting_cube(cells));
            let dt = world.choose_substeps(1.0 / 24.0).dt;
            let id = BenchmarkId::new(format!("{}^3_nodes", cells + 1), format!("{threads}t"));
            group.bench_function(id, |b| {
                pool.install(|| b.iter(|| world.step(dt)));
            });
        }
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
