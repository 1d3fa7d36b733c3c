//! How much of each lattice cell a mesh fills (`lattice::fill`): a box fitted to its cells
//! fills them whole, a sphere's cells hold its volume exactly and balance at its centre, a
//! cone's centre of mass sits a quarter up its axis, and open sheets keep whole cells.
#![allow(clippy::unwrap_used)]

use springbake_core::cage::mesh_volume;
use springbake_core::lattice::fill::{cell_fill, MIN_FILL};
use springbake_core::lattice::{fit_lattice, FitSettings, Lattice, Resolution};
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::{box_mesh, uv_sphere};

fn fit(points: &[Point3<f64>], triangles: &[[u32; 3]], cells: u32) -> Lattice {
    let settings = FitSettings {
        resolution: Resolution::CellsAlongLongest(cells),
        ..FitSettings::default()
    };
    fit_lattice(points, triangles, &settings).unwrap()
}

/// Volume and centroid of the cells weighted by `fill` (whole cells when `None`).
fn weighted(lattice: &Lattice, fill: Option<&[f64]>) -> (f64, Vector3<f64>) {
    let h = lattice.cell_size;
    let (mut volume, mut moment) = (0.0, Vector3::zeros());
    for (c, coords) in lattice.cells.iter().enumerate() {
        let share = fill.map_or(1.0, |f| f[c]);
        let centre = lattice.origin
            + (Vector3::new(coords[0] as f64, coords[1] as f64, coords[2] as f64)
                + Vector3::repeat(0.5))
                * h;
        volume += share * h.powi(3);
        moment += centre * share * h.powi(3);
    }
    (volume, moment / volume)
}

/// A closed cone: base disc of `radius` at z = 0 around the origin, apex at z = `height`.
fn cone(radius: f64, height: f64, segments: u32) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let mut points = vec![Point3::new(0.0, 0.0, height), Point3::origin()];
    for s in 0..segments {
        let a = std::f64::consts::TAU * s as f64 / segments as f64;
        points.push(Point3::new(radius * a.cos(), radius * a.sin(), 0.0));
    }
    let mut triangles = Vec::new();
    for s in 0..segments {
        let (i, j) = (2 + s, 2 + (s + 1) % segments);
        triangles.push([0, i, j]);
        triangles.push([1, j, i]);
    }
    (points, triangles)
}

#[test]
fn a_box_fitted_to_its_cells_fills_every_cell_whole() {
    let (p, t) = box_mesh([0.2, -0.1, 0.3], [1.2, 0.9, 1.3]);
    let lattice = fit(&p, &t, 5);
    let fill = cell_fill(&lattice, &p, &t).unwrap();
    assert_eq!(fill.len(), 125);
    assert!(fill.iter().all(|&f| f == 1.0), "{fill:?}");
}

#[test]
fn a_sphere_s_cells_hold_its_volume_and_balance_at_its_centre() {
    let centre = Vector3::new(0.3, -0.2, 1.0);
    let (p, t) = uv_sphere(centre.into(), 0.5, 16, 32);
    let lattice = fit(&p, &t, 8);
    let fill = cell_fill(&lattice, &p, &t).unwrap();
    let enclosed = mesh_volume(&p, &t);
    let (volume, centroid) = weighted(&lattice, Some(&fill));
    assert!(
        (volume / enclosed - 1.0).abs() < 1e-9,
        "{volume} vs {enclosed}"
    );
    assert!(fill.iter().all(|&f| (MIN_FILL..=1.0).contains(&f)));
    assert!(fill.iter().any(|&f| f < 0.5) && fill.contains(&1.0));
    assert!((centroid - centre).norm() < 0.002, "{centroid} vs {centre}");
    // Whole cells weigh a third more than the sphere.
    let (whole, _) = weighted(&lattice, None);
    assert!(whole > 1.25 * enclosed, "{whole} vs {enclosed}");
}

#[test]
fn a_cone_s_centre_of_mass_is_a_quarter_up_its_axis() {
    let (p, t) = cone(0.5, 1.0, 48);
    let lattice = fit(&p, &t, 8);
    let fill = cell_fill(&lattice, &p, &t).unwrap();
    let (volume, centroid) = weighted(&lattice, Some(&fill));
    let enclosed = mesh_volume(&p, &t);
    assert!((volume / enclosed - 1.0).abs() < 1e-9);
    assert!((centroid.z - 0.25).abs() < 0.02, "{centroid}");
    assert!(centroid.xy().norm() < 0.01, "{centroid}");
    // Whole cells put it well above.
    let (_, whole) = weighted(&lattice, None);
    assert!(whole.z > 0.28, "{whole}");
}

#[test]
fn open_meshes_keep_whole_cells() {
    let sheet = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(2.0, 0.0, 0.0),
        Point3::new(2.0, 1.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
    ];
    let quads = vec![[0, 1, 2], [0, 2, 3]];
    assert!(cell_fill(&fit(&sheet, &quads, 8), &sheet, &quads).is_none());
    // A box without its lid.
    let (p, mut t) = box_mesh([0.0; 3], [1.0; 3]);
    t.retain(|tri| !tri.iter().all(|&i| i & 4 != 0));
    assert!(cell_fill(&fit(&p, &t, 6), &p, &t).is_none());
}

/// A closed cylinder along x: `radius`, from x = 0 to `length`, `segments` around.
fn rod(radius: f64, length: f64, segments: u32) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let mut points = vec![Point3::origin(), Point3::new(length, 0.0, 0.0)];
    for s in 0..segments {
        let a = std::f64::consts::TAU * s as f64 / segments as f64;
        let (y, z) = (radius * a.cos(), radius * a.sin());
        points.push(Point3::new(0.0, y, z));
        points.push(Point3::new(length, y, z));
    }
    let mut triangles = Vec::new();
    for s in 0..segments {
        let (a0, a1) = (2 + 2 * s, 3 + 2 * s);
        let (b0, b1) = (2 + 2 * ((s + 1) % segments), 3 + 2 * ((s + 1) % segments));
        triangles.push([0, b0, a0]);
        triangles.push([1, a1, b1]);
        triangles.push([a0, b0, b1]);
        triangles.push([a0, b1, a1]);
    }
    (points, triangles)
}

#[test]
fn a_rod_thinner_than_the_samples_weighs_its_mesh() {
    // 2 m long, 4 cm across, 8 cells along: one row of 25 cm cells, which the first 4 × 4
    // grid of sample lines (6 cm apart) misses entirely. It used to keep whole cells and
    // weigh 50 times its mesh.
    let (p, t) = rod(0.02, 2.0, 24);
    let enclosed = mesh_volume(&p, &t);
    assert!(enclosed > 0.0);
    let lattice = fit(&p, &t, 8);
    let fill = cell_fill(&lattice, &p, &t).unwrap();
    let (volume, centroid) = weighted(&lattice, Some(&fill));
    assert!(
        (volume / enclosed - 1.0).abs() < 1e-9,
        "{volume} vs {enclosed}"
    );
    assert!(fill.iter().all(|&f| f > 0.0 && f < MIN_FILL), "{fill:?}");
    assert!((centroid.x - 1.0).abs() < 0.01, "{centroid}");
}

#[test]
fn a_mesh_with_flipped_normals_fills_as_much_as_the_right_way_round() {
    let (p, t) = uv_sphere([0.0, 0.0, 1.0], 0.5, 16, 32);
    let flipped: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let lattice = fit(&p, &t, 8);
    assert_eq!(fit(&p, &flipped, 8).cells, lattice.cells);
    let right = cell_fill(&lattice, &p, &t).unwrap();
    let wrong = cell_fill(&lattice, &p, &flipped).unwrap();
    assert_eq!(right, wrong);
}
