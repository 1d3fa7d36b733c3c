//! Set-up shared by core's integration tests: a closed mesh fitted with a lattice at the
//! default fit settings (`fit`, `fitted_box`), and world settings with a floor at y = 0 under
//! the default contact layer (`floor_settings`). Each test file includes it with
//! `mod support;`; it holds set-up only, no assertions.

use springbake_core::lattice::{fit_lattice, FitSettings, Lattice, Resolution};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{Plane, WorldSettings};

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
    .unwrap()
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
