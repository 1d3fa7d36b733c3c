//! Worlds for the GPU solver's tests and its benchmark (`examples/gpu_bench.rs`).
#![allow(dead_code, clippy::unwrap_used)]

use springbake_core::lattice::{
    fit_lattice, surface_samples, FitSettings, Resolution, SpringLayout,
};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Rotation3, Vector3};
use springbake_core::shapes::box_mesh;
use springbake_core::solver::manipulator::ManipulatorKey;
use springbake_core::solver::{Integrator, ManipulatorTrack, Plane, World, WorldSettings};

/// A world holding a box of edge `size` (turned by `tilt`, its lowest point `height` above a
/// floor at y = 0) as the product sets up a mesh: `cells` along its side, display-surface
/// contact sampled at half a cell, friction 0.4.
pub fn box_world(size: f64, tilt: Rotation3<f64>, height: f64, cells: u32, preset: &str) -> World {
    let material = Material::preset(preset).unwrap();
    box_world_of(size, tilt, height, cells, &material)
}

/// [`box_world`] in any material.
pub fn box_world_of(
    size: f64,
    tilt: Rotation3<f64>,
    height: f64,
    cells: u32,
    material: &Material,
) -> World {
    let half = 0.5 * size;
    let (mut points, triangles) = box_mesh([-half; 3], [half; 3]);
    for p in &mut points {
        *p = tilt * *p;
    }
    let low = points.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    for p in &mut points {
        p.y += height - low;
    }
    let lattice = fit_lattice(
        &points,
        &triangles,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            layout: SpringLayout::Both,
            ..FitSettings::default()
        },
    )
    .unwrap();
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: WorldSettings::default_layer(lattice.cell_size, material, 0.4),
        integrator: Integrator::Xpbd,
        ..WorldSettings::default()
    });
    let h = w.add_lattice_body("box", &lattice, material, Vector3::zeros());
    let (samples, areas) = surface_samples(&points, &triangles, 0.5 * lattice.cell_size);
    w.add_contact_surface(h, &lattice, &samples, &areas);
    w
}

/// A capsule manipulator (friction 0.3) of `radius` and `length`, yawed `yaw_deg` (0: its axis
/// along x), moved at height `y` along x from `from` to `to` in the first `seconds`.
pub fn sweep_along_x(
    w: &mut World,
    (radius, length, yaw_deg): (f64, f64, f64),
    y: f64,
    (from, to): (f64, f64),
    seconds: f64,
) {
    let key = |t: f64, x: f64| ManipulatorKey {
        t,
        position: Vector3::new(x, y, 0.0),
        yaw_deg,
    };
    w.manipulators.push(ManipulatorTrack {
        radius,
        length,
        friction: 0.3,
        smooth: false,
        keys: vec![key(0.0, from), key(seconds, to)],
        up: Vector3::y(),
    });
}
