//! Lattice fit and embedding: Table 1 counts, interior fill, flat and open meshes, islands,
//! memory limit, and the embedding's exactness.
#![allow(clippy::unwrap_used)]

use springbake_core::lattice::{
    fit_lattice, Embedding, FitError, FitSettings, Resolution, SpringLayout,
};
use springbake_core::nalgebra::{Matrix3, Point3, Vector3};
use springbake_core::shapes::{box_mesh, uv_sphere};

fn settings(cells: u32, layout: SpringLayout) -> FitSettings {
    FitSettings {
        resolution: Resolution::CellsAlongLongest(cells),
        layout,
        ..FitSettings::default()
    }
}

#[test]
fn table1_node_and_spring_counts_for_full_blocks() {
    // Miyazaki Table 1: nodes (I+1)^3, springs 3I(I+1)^2 + 3I^2(I+1).
    let expected = [
        (2, 27, 90),
        (3, 64, 252),
        (4, 125, 540),
        (5, 216, 990),
        (6, 343, 1638),
        (7, 512, 2520),
    ];
    let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
    for (i, nodes, springs) in expected {
        let l = fit_lattice(&p, &t, &settings(i, SpringLayout::FaceDiagonals)).unwrap();
        assert_eq!(l.cell_count(), (i * i * i) as usize, "I = {i}");
        assert_eq!(l.node_count(), nodes, "I = {i}");
        assert_eq!(l.springs.len(), springs, "I = {i}");
        assert_eq!(l.island_count, 1);
    }
}

#[test]
fn other_spring_layouts_add_body_diagonals() {
    let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
    let i = 3usize;
    let edges = 3 * i * (i + 1) * (i + 1);
    let faces = 3 * i * i * (i + 1);
    let body = 4 * i * i * i;
    let b = fit_lattice(&p, &t, &settings(3, SpringLayout::BodyDiagonals)).unwrap();
    assert_eq!(b.springs.len(), edges + body);
    let both = fit_lattice(&p, &t, &settings(3, SpringLayout::Both)).unwrap();
    assert_eq!(both.springs.len(), edges + faces + body);
}

#[test]
fn closed_sphere_interior_is_filled() {
    let (p, t) = uv_sphere([0.0; 3], 1.0, 24, 48);
    let l = fit_lattice(&p, &t, &settings(12, SpringLayout::FaceDiagonals)).unwrap();
    // Every cell whose centre lies inside the sphere must be active: the lattice volume covers
    // the sphere (4.19 m³) and stays below the 8 m³ bounding cube.
    let vol = l.volume();
    assert!(vol > 4.19 && vol < 8.0, "lattice volume {vol}");
    for cx in 0..12 {
        for cy in 0..12 {
            for cz in 0..12 {
                let c = l.origin
                    + (Vector3::new(cx as f64, cy as f64, cz as f64) + Vector3::repeat(0.5))
                        * l.cell_size;
                if c.norm() < 0.85 {
                    assert!(
                        l.active_cell_at([cx, cy, cz]).is_some(),
                        "interior cell {cx},{cy},{cz} missing"
                    );
                }
            }
        }
    }
    // Corners of the bounding cube lie outside the sphere: not active.
    assert!(l.active_cell_at([0, 0, 0]).is_none());
    assert!(l.active_cell_at([11, 11, 11]).is_none());
}

#[test]
fn flat_mesh_gets_one_cell_thick_lattice() {
    let p = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(2.0, 0.0, 0.0),
        Point3::new(2.0, 0.0, 1.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    let t = vec![[0, 2, 1], [0, 3, 2]];
    let l = fit_lattice(&p, &t, &settings(8, SpringLayout::FaceDiagonals)).unwrap();
    assert_eq!(l.dims, [8, 1, 4]);
    assert_eq!(l.cell_count(), 32);
    assert_eq!(l.island_count, 1);
}

#[test]
fn a_mesh_with_flipped_normals_is_as_solid_as_the_same_mesh_the_right_way_round() {
    // Every face wound the other way (Blender's "Flip Normals", a mirrored object exported
    // without reordering): the winding number inside is −1, and the box is still solid. It
    // used to get only its 296 surface cells of 512: a hollow shell.
    let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
    let flipped: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let right = fit_lattice(&p, &t, &settings(8, SpringLayout::FaceDiagonals)).unwrap();
    let wrong = fit_lattice(&p, &flipped, &settings(8, SpringLayout::FaceDiagonals)).unwrap();
    assert_eq!(right.cell_count(), 512);
    assert_eq!(wrong.cell_count(), 512);
    assert_eq!(wrong.cells, right.cells);
}

#[test]
fn a_mesh_thinner_than_a_cell_along_up_is_centred_in_its_cells() {
    // A 2 m plank 4 cm thick at 8 cells: one layer of 25 cm cells. Aligned to its bottom it
    // would sit in the lowest 4 cm of its cells, their centre of mass 10.5 cm above its own.
    let (p, t) = box_mesh([0.0, 0.3, 0.0], [2.0, 0.34, 0.2]);
    let l = fit_lattice(&p, &t, &settings(8, SpringLayout::FaceDiagonals)).unwrap();
    assert_eq!(l.dims, [8, 1, 1]);
    let middle = l.origin.y + 0.5 * l.cell_size;
    assert!((middle - 0.32).abs() < 1e-12, "{}", l.origin);
    // Thicker than a cell: aligned to the bottom as before.
    let (p, t) = box_mesh([0.0, 0.3, 0.0], [2.0, 0.7, 0.2]);
    let l = fit_lattice(&p, &t, &settings(8, SpringLayout::FaceDiagonals)).unwrap();
    assert_eq!(l.dims, [8, 2, 1]);
    assert!((l.origin.y - 0.3).abs() < 1e-12, "{}", l.origin);
}

#[test]
fn open_box_without_lid_is_hollow_but_robust() {
    // A box with its top removed: the generalised winding number inside is about ½ at most and
    // falls off; the fit must not crash, must cover the surface, and all surface cells are there.
    let (p, mut t) = box_mesh([0.0; 3], [1.0; 3]);
    t.retain(|tri| !tri.iter().all(|&i| i & 2 != 0)); // drop the y = hi face
    let l = fit_lattice(&p, &t, &settings(6, SpringLayout::FaceDiagonals)).unwrap();
    for x in 0..6 {
        for z in 0..6 {
            assert!(l.active_cell_at([x, 0, z]).is_some(), "floor cell missing");
        }
    }
    assert_eq!(l.island_count, 1);
}

#[test]
fn disconnected_parts_stay_separate_islands() {
    let (mut p, mut t) = box_mesh([0.0; 3], [1.0; 3]);
    let (p2, t2) = box_mesh([3.0, 0.0, 0.0], [4.0, 1.0, 1.0]);
    let base = p.len() as u32;
    p.extend(p2);
    t.extend(t2.into_iter().map(|tri| tri.map(|i| i + base)));
    let l = fit_lattice(&p, &t, &settings(8, SpringLayout::FaceDiagonals)).unwrap();
    assert_eq!(l.cell_count(), 2 * 8, "{:?} {:?}", l.dims, l.cells);
    assert_eq!(l.island_count, 2);
}

#[test]
fn bad_input_is_a_typed_error() {
    let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
    assert_eq!(
        fit_lattice(&p, &[], &FitSettings::default()),
        Err(FitError::EmptyMesh)
    );
    let mut nan = p.clone();
    nan[3].y = f64::NAN;
    assert!(matches!(
        fit_lattice(&nan, &t, &FitSettings::default()),
        Err(FitError::NonFinite { vertex: 3, .. })
    ));
    let bad = vec![[0, 1, 99]];
    assert!(matches!(
        fit_lattice(&p, &bad, &FitSettings::default()),
        Err(FitError::BadIndex { index: 99, .. })
    ));
    assert!(matches!(
        fit_lattice(&p, &t, &settings(0, SpringLayout::FaceDiagonals)),
        Err(FitError::BadResolution(_))
    ));
    let huge = FitSettings {
        memory_limit_bytes: 1 << 30,
        ..settings(2000, SpringLayout::FaceDiagonals)
    };
    match fit_lattice(&p, &t, &huge) {
        Err(FitError::TooLarge {
            nx: 2000,
            estimate_mib,
            limit_mib: 1024,
            ..
        }) => {
            assert!(estimate_mib > 1024);
            let msg = fit_lattice(&p, &t, &huge).unwrap_err().to_string();
            assert!(msg.contains("MiB"), "{msg}");
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
}

/// Meshes whose triangles are points or lines (one vertex, coincident or collinear vertices)
/// get a typed error, not a lattice without cells (whose embedding panicked).
#[test]
fn meshes_without_area_are_refused() {
    let point = vec![Point3::origin(); 3];
    let line: Vec<Point3<f64>> = (0..3).map(|i| Point3::new(i as f64, 0.0, 0.0)).collect();
    for (name, positions) in [("point", point), ("line", line)] {
        assert!(
            matches!(
                fit_lattice(&positions, &[[0, 1, 2]], &FitSettings::default()),
                Err(FitError::Degenerate { .. })
            ),
            "{name}"
        );
    }
}

#[test]
fn cell_size_resolution_in_metres() {
    let (p, t) = box_mesh([0.0; 3], [1.0, 0.5, 0.25]);
    let l = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellSize(0.125),
            ..FitSettings::default()
        },
    )
    .unwrap();
    assert_eq!(l.dims, [8, 4, 2]);
    assert_eq!(l.cell_count(), 64);
}

#[test]
fn embedding_reproduces_rest_and_follows_affine_motion_exactly() {
    let (p, t) = uv_sphere([0.3, 1.0, -0.2], 0.7, 12, 24);
    let l = fit_lattice(&p, &t, &settings(7, SpringLayout::FaceDiagonals)).unwrap();
    let e = Embedding::new(&l, &p);
    for (i, w) in e.weights.iter().enumerate() {
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(
            w.iter().all(|&x| x >= -1e-9),
            "vertex {i} outside its cell: {w:?}"
        );
    }
    let rest = e.points(&l.rest_positions);
    for (a, b) in rest.iter().zip(&p) {
        assert!((a - b).norm() < 1e-12);
    }
    // An arbitrary affine map: rotation-shear-scale plus translation.
    let m = Matrix3::new(1.2, 0.3, -0.1, 0.05, 0.8, 0.4, -0.2, 0.1, 1.5);
    let shift = Vector3::new(3.0, -1.0, 0.5);
    let moved: Vec<Point3<f64>> = l
        .rest_positions
        .iter()
        .map(|q| Point3::from(m * q.coords + shift))
        .collect();
    let got = e.points(&moved);
    for (g, orig) in got.iter().zip(&p) {
        let want = m * orig.coords + shift;
        assert!((g.coords - want).norm() < 1e-12, "{g} vs {want}");
    }
}

#[test]
fn spread_force_conserves_force_and_torque_about_the_point() {
    let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
    let l = fit_lattice(&p, &t, &settings(4, SpringLayout::FaceDiagonals)).unwrap();
    let at = [Point3::new(0.3, 0.7, 0.55)];
    let e = Embedding::new(&l, &at);
    let f = Vector3::new(1.0, -2.0, 0.5);
    let mut nodes = vec![Vector3::zeros(); l.node_count()];
    e.spread_force(0, f, &mut nodes);
    let total: Vector3<f64> = nodes.iter().sum();
    assert!((total - f).norm() < 1e-12);
    // Moment about the application point vanishes (trilinear weights reproduce the point).
    let torque: Vector3<f64> = nodes
        .iter()
        .zip(&l.rest_positions)
        .map(|(fi, x)| (x - at[0]).cross(fi))
        .sum();
    assert!(torque.norm() < 1e-12, "{torque}");
}

/// An extent a float32 rounding over a whole number of cells gets that number: the corpus's
/// Blender cylinder (0.6 × 1.2 × 0.6 m) at 10 cells is 5 × 10 × 5 from its OBJ (Y-up) and its
/// USD (Z-up) alike, as their float32 coordinates round differently (it was 6 × 10 × 6 from
/// the OBJ, 320 cells and a third more mass than from the USD's 250).
#[test]
fn an_extent_a_rounding_over_whole_cells_gets_whole_cells() {
    for (half, tall) in [
        (0.300_000_011_920_929, 1.199_999_976_158_142),
        (0.300_000_011_920_929, 1.200_000_047_683_716),
    ] {
        let (p, t) = box_mesh([-half, 0.2, -half], [half, 0.2 + tall, half]);
        let lattice = fit_lattice(&p, &t, &settings(10, SpringLayout::Both)).unwrap();
        assert_eq!(lattice.dims, [5, 10, 5], "height {tall}");
        assert_eq!(lattice.cells.len(), 250);
    }
}
