//! Bodies far too stiff for their lattice to bend at the XPBD solver's substeps (wood, steel)
//! are held to their best-fit rigid motion (`solver::xpbd::held`): a wooden cantilever stays
//! straight where the elastic cells let it hang, a wooden plank pinned on one edge swings about
//! it as a rigid pendulum, a spinning steel box keeps its spin, a rubber body of the same
//! shape is left elastic, and any thread count gives the same bits.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{Integrator, World};
use support::{mesh, product_world, spin_kept, Mesh};

const FRAME: f64 = 1.0 / 24.0;

fn world(m: &Mesh, preset: &str, floor: bool) -> World {
    let material = Material::preset(preset).unwrap();
    product_world(m, &material, Integrator::Xpbd, Vector3::zeros(), floor)
}

/// A 1 m × 10 cm × 10 cm beam along x, 20 cells long.
fn beam() -> Mesh {
    mesh(box_mesh([0.0, 0.5, 0.0], [1.0, 0.6, 0.1]), 20)
}

/// Pin the nodes of `w` with `x` below `edge`; step `frames` frames; the mean drop of the
/// nodes at the far end (x = 1), m.
fn tip_sag(w: &mut World, edge: f64, frames: usize) -> f64 {
    let start = w.nodes.position.clone();
    let root: Vec<usize> = (0..start.len()).filter(|&i| start[i].x < edge).collect();
    w.pin(&root).unwrap();
    for f in 1..=frames {
        w.advance_frame(FRAME, f, &|| false).unwrap();
    }
    let tip: Vec<usize> = (0..start.len())
        .filter(|&i| start[i].x > 1.0 - 1e-9)
        .collect();
    let drop: f64 = tip
        .iter()
        .map(|&i| start[i].y - w.nodes.position[i].y)
        .sum();
    drop / tip.len() as f64
}

#[test]
fn a_wooden_cantilever_stays_straight_where_elastic_cells_let_it_hang() {
    // Euler–Bernoulli: w L⁴ / (8 E I) = 0.09 mm for wood.
    let mut held = world(&beam(), "wood", false);
    let sag = tip_sag(&mut held, 1e-9, 24);
    assert!(sag.abs() < 1e-4, "held wood sags {sag} m");
    let mut elastic = world(&beam(), "wood", false);
    elastic.hold_stiff_bodies = false;
    let sag = tip_sag(&mut elastic, 1e-9, 24);
    assert!(
        sag > 0.05,
        "elastic wood sags {sag} m: the case held bodies are for"
    );
    // Rubber shows its bending: it is left elastic.
    let mut rubber = world(&beam(), "rubber", false);
    let sag = tip_sag(&mut rubber, 1e-9, 24);
    assert!(sag > 0.05, "rubber sags {sag} m");
}

#[test]
fn a_wooden_plank_pinned_on_one_edge_swings_as_a_rigid_pendulum() {
    // Pinned along the edge x = 0, y = 0.5 (a line of nodes along z): a hinge.
    let mut w = world(&beam(), "wood", false);
    let rest = w.nodes.position.clone();
    let hinge: Vec<usize> = (0..rest.len())
        .filter(|&i| rest[i].x < 1e-9 && rest[i].y < 0.5 + 1e-9)
        .collect();
    w.pin(&hinge).unwrap();
    let distance = |x: &[Vector3<f64>], a: usize, b: usize| (x[a] - x[b]).norm();
    let (far, near) = (rest.len() - 1, 0);
    let mut lowest = f64::INFINITY;
    for f in 1..=12 {
        w.advance_frame(FRAME, f, &|| false).unwrap();
        let x = &w.nodes.position;
        for i in 0..x.len() {
            for j in [near, far] {
                let stretch = distance(x, i, j) - distance(&rest, i, j);
                assert!(
                    stretch.abs() < 1e-6,
                    "frame {f}: nodes {i}, {j} moved apart by {stretch} m"
                );
            }
        }
        lowest = lowest.min(x.iter().map(|p| p.y).fold(f64::INFINITY, f64::min));
        for &i in &hinge {
            assert_eq!(x[i], rest[i], "a hinge node moved");
        }
    }
    // Half a second of swing: the free end has fallen well below the hinge.
    assert!(lowest < 0.0, "the plank swung down only to {lowest} m");
}

#[test]
fn a_spinning_steel_box_keeps_its_spin_and_shape() {
    let b = mesh(box_mesh([-0.25, -0.25, -0.25], [0.25, 0.25, 0.25]), 8);
    let mut w = world(&b, "steel", false);
    let rest = w.nodes.position.clone();
    let kept = spin_kept(&mut w);
    assert!((kept - 1.0).abs() < 1e-3, "kept {kept} of its spin");
    let x = &w.nodes.position;
    let last = x.len() - 1;
    let stretch = (x[0] - x[last]).norm() - (rest[0] - rest[last]).norm();
    assert!(stretch.abs() < 1e-9, "its diagonal changed by {stretch} m");
}

/// A tilted steel box (held) landing on its corner, stepped in pools of 1, 2 and 8 threads:
/// the same bits.
#[test]
fn a_held_body_gives_the_same_bits_with_one_two_and_eight_threads() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (mut points, triangles) = box_mesh([-0.2, -0.2, -0.2], [0.2, 0.2, 0.2]);
            let tilt = springbake_core::nalgebra::Rotation3::from_euler_angles(0.5, 0.0, 0.4);
            for p in &mut points {
                *p = tilt * *p + Vector3::new(0.0, 0.45, 0.0);
            }
            let mut w = world(&mesh((points, triangles), 12), "steel", true);
            for f in 1..=12 {
                w.advance_frame(FRAME, f, &|| false).unwrap();
            }
            // The box's surface (its contact samples): the lattice round a tilted box stands
            // out of it, and once the box lies on a face its corner nodes are below the floor.
            let surface = &w.surface;
            let lowest = (surface.nodes.iter().zip(&surface.weights))
                .map(|(ids, weights)| {
                    (ids.iter().zip(weights))
                        .map(|(&i, &weight)| w.nodes.position[i as usize].y * weight)
                        .sum::<f64>()
                })
                .fold(f64::INFINITY, f64::min);
            (w.nodes.position.clone(), lowest)
        })
    };
    let (one, lowest) = run(1);
    assert!(
        lowest > -0.01,
        "the box's surface is at {lowest} m, under the floor"
    );
    assert_eq!(one, run(2).0);
    assert_eq!(one, run(8).0);
}
