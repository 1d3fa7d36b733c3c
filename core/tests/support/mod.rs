//! Set-up shared by core's integration tests: a closed mesh fitted with a lattice at the
//! default fit settings (`fit`, `fitted_box`), world settings with a floor at y = 0 under
//! the default contact layer (`floor_settings`), and a body set up as the product sets up a
//! mesh (`mesh`, `product_world`, `add_part`; also used by `examples/solver_checks.rs`). Each test file includes it with
//! `mod support;`; it holds set-up only, no assertions.

use springbake_core::lattice::fill::cell_fill;
use springbake_core::lattice::{
    fit_lattice, surface_samples_with_normals, FitSettings, Lattice, Resolution, SpringLayout,
};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{BodyHandle, Integrator, Plane, World, WorldSettings};

/// The lattice of the closed mesh (`points`, `triangles`) with `cells` cells along its
/// longest side, the other fit settings at their defaults.
pub fn fit(points: &[Point3<f64>], triangles: &[[u32; 3]], cells: u32) -> Lattice {
    fit_lattice(
        points,
        triangles,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            ..FitSettings::default()
        },
    )
    .expect("the test mesh fits")
}

/// The axis-aligned box from `lo` to `hi` (`box_mesh`) and its lattice of `cells` cells along
/// the longest side (`fit`).
#[allow(dead_code)] // not every test file fits a box
pub fn fitted_box(
    lo: [f64; 3],
    hi: [f64; 3],
    cells: u32,
) -> (Vec<Point3<f64>>, Vec<[u32; 3]>, Lattice) {
    let (p, t) = box_mesh(lo, hi);
    let lattice = fit(&p, &t, cells);
    (p, t, lattice)
}

/// The default world settings (gravity −9.81 m/s² along y) with one floor plane at y = 0,
/// whose layer is `WorldSettings::default_layer` for `lattice`'s cell size in `material` with
/// `friction`.
#[allow(dead_code)] // not every test file has such a floor
pub fn floor_settings(lattice: &Lattice, material: &Material, friction: f64) -> WorldSettings {
    WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: WorldSettings::default_layer(lattice.cell_size, material, friction),
        ..WorldSettings::default()
    }
}

/// A closed mesh and its lattice as `springbake bake` fits one (the scene default spring
/// layout, `cells` along the longest side).
#[allow(dead_code)] // not every test file builds product worlds
pub struct Mesh {
    pub points: Vec<Point3<f64>>,
    pub triangles: Vec<[u32; 3]>,
    pub lattice: Lattice,
}

/// [`Mesh`] of `(points, triangles)` (e.g. from `box_mesh` or `uv_sphere`).
#[allow(dead_code)]
pub fn mesh((points, triangles): (Vec<Point3<f64>>, Vec<[u32; 3]>), cells: u32) -> Mesh {
    let lattice = fit_lattice(
        &points,
        &triangles,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            layout: SpringLayout::Both,
            ..FitSettings::default()
        },
    )
    .expect("the test mesh fits");
    Mesh {
        points,
        triangles,
        lattice,
    }
}

/// A world holding `m` in `material` at `velocity` as the product sets up a mesh (contact on
/// the display surface sampled at half a cell, the default layer with friction 0.4, cells
/// weighing what the mesh fills of them under XPBD), stepped
/// by `integrator`, with a floor at y = 0 when `floor`.
#[allow(dead_code)]
pub fn product_world(
    m: &Mesh,
    material: &Material,
    integrator: Integrator,
    velocity: Vector3<f64>,
    floor: bool,
) -> World {
    let mut w = World::new(WorldSettings {
        planes: if floor {
            vec![Plane {
                normal: Vector3::y(),
                offset: 0.0,
            }]
        } else {
            Vec::new()
        },
        layer: WorldSettings::default_layer(m.lattice.cell_size, material, 0.4),
        integrator,
        ..WorldSettings::default()
    });
    let h = w.add_lattice_body("body", &m.lattice, material, velocity);
    if integrator == Integrator::Xpbd {
        if let Some(fill) = cell_fill(&m.lattice, &m.points, &m.triangles) {
            w.set_cell_fill(h, &fill);
        }
    }
    let s = surface_samples_with_normals(&m.points, &m.triangles, 0.5 * m.lattice.cell_size);
    w.add_contact_surface_with_normals(h, &m.lattice, &s.points, &s.areas, &s.normals);
    w
}

/// Spin `w` (no gravity) at 1 rev/s about y through the origin, step it 1 s in 24 frames and
/// return the share of its angular velocity (about its centre of mass) it kept.
#[allow(dead_code)]
pub fn spin_kept(w: &mut World) -> f64 {
    w.settings.gravity = Vector3::zeros();
    let omega = 2.0 * std::f64::consts::PI;
    for i in 0..w.nodes.len() {
        w.nodes.velocity[i] = Vector3::y().cross(&w.nodes.position[i]) * omega;
    }
    let spin = |w: &World| {
        let all = 0..w.nodes.len();
        springbake_core::solver::deformation_damping::rigid_motion(&w.nodes, all)
            .angular_velocity
            .y
    };
    let before = spin(w);
    for f in 1..=24 {
        w.advance_frame(1.0 / 24.0, f, &|| false)
            .expect("a spinning cube stays finite");
    }
    spin(w) / before
}

/// The rebound check's ball: r 0.1 m, its bottom 1 m above the floor, 8 cells.
#[allow(dead_code)]
pub fn rebound_ball() -> Mesh {
    mesh(
        springbake_core::shapes::uv_sphere([0.0, 1.1, 0.0], 0.1, 12, 24),
        8,
    )
}

/// What the dropped ball did: the highest its bottom got after the first bounce, the most
/// cells inverted and substeps in any frame, and the furthest its lattice volume got from
/// rest (a fraction).
#[allow(dead_code)]
pub struct Rebound {
    pub peak: f64,
    pub inverted: usize,
    pub substeps: u32,
    pub volume_change: f64,
}

/// Steps `w` (holding [`rebound_ball`] over a floor) `frames` frames at 24 fps. A bounce counts
/// from the first frame the ball is near the floor or rising (a frame may miss the instant it
/// touches).
#[allow(dead_code)]
pub fn rebound(w: &mut World, frames: usize) -> Rebound {
    let lowest = |w: &World| {
        w.nodes
            .position
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min)
    };
    let offset = lowest(w) - 1.0;
    let ball = springbake_core::solver::BodyHandle(0);
    let rest_volume = w.body_volume(ball);
    let mut out = Rebound {
        peak: 0.0,
        inverted: 0,
        substeps: 0,
        volume_change: 0.0,
    };
    let mut touched = false;
    for f in 1..=frames {
        let d = w
            .advance_frame(1.0 / 24.0, f, &|| false)
            .expect("a dropped ball stays finite");
        out.inverted = out.inverted.max(d.inverted_cells);
        out.substeps = out.substeps.max(d.substeps);
        out.volume_change = out
            .volume_change
            .max((w.body_volume(ball) / rest_volume - 1.0).abs());
        let bottom = lowest(w) - offset;
        let rising = w.nodes.velocity.iter().map(|v| v.y).sum::<f64>() > 0.0;
        touched |= bottom < 0.02 || rising;
        if touched {
            out.peak = out.peak.max(bottom);
        }
    }
    out
}

/// Add `m` to `w` as a body at rest named `name` whose mesh touches the other bodies (contact
/// samples at half a cell, its display surface for body–body contact).
#[allow(dead_code)]
pub fn add_part(w: &mut World, name: &str, m: &Mesh, material: &Material) -> BodyHandle {
    let h = w.add_lattice_body(name, &m.lattice, material, Vector3::zeros());
    let s = surface_samples_with_normals(&m.points, &m.triangles, 0.5 * m.lattice.cell_size);
    w.add_contact_surface_with_normals(h, &m.lattice, &s.points, &s.areas, &s.normals);
    w.add_collision_surface(h, &m.lattice, &m.points, &m.triangles);
    h
}

#[allow(dead_code)]
/// An XPBD world whose contact layer is that of 0.5 m parts at 6 cells in `material`, with a floor at
/// y = 0.
pub fn floored_parts_world(material: &Material) -> World {
    World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: WorldSettings::default_layer(0.5 / 6.0, material, 0.4),
        integrator: Integrator::Xpbd,
        ..WorldSettings::default()
    })
}
