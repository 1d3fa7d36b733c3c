//! Physics checks of the solver against closed forms and the papers (physics §2–7).
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::lattice::{fit_lattice, FitSettings, Lattice, Resolution, SpringLayout};
use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{ContactLayer, DispersionMode, Plane, World, WorldSettings};
use support::{fitted_box, floor_settings};

fn cube_lattice(lo: [f64; 3], size: f64, cells: u32) -> Lattice {
    fitted_box(lo, [lo[0] + size, lo[1] + size, lo[2] + size], cells).2
}

fn no_contact(gravity: f64) -> WorldSettings {
    WorldSettings {
        gravity: Vector3::new(0.0, -gravity, 0.0),
        ..WorldSettings::default()
    }
}

fn floor(height: f64) -> Plane {
    Plane {
        normal: Vector3::y(),
        offset: height,
    }
}

#[test]
fn free_fall_matches_half_g_t_squared_within_the_integrators_error() {
    let mut w = World::new(no_contact(9.81));
    let lattice = cube_lattice([0.0, 10.0, 0.0], 0.2, 2);
    let m = Material::preset("rubber").unwrap();
    let body = w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    let mut substeps = 0;
    for f in 1..=24 {
        let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert!(
            substeps == 0 || substeps == d.substeps,
            "constant substeps in free fall"
        );
        substeps = d.substeps;
    }
    let dt = 1.0 / 24.0 / substeps as f64;
    let t = 1.0;
    let y0 = lattice.rest_positions[0].y;
    let y = w.body_positions(body)[0].y;
    let fallen = y0 - y;
    // Symplectic Euler: x_n = x_0 − g ΔT² n(n+1)/2, so the error against ½gt² is ½ g ΔT t.
    let exact = 0.5 * 9.81 * t * t;
    let integrator_error = 0.5 * 9.81 * dt * t;
    assert!(
        (fallen - exact - integrator_error).abs() < 1e-9,
        "fell {fallen}, ½gt² = {exact}, ΔT = {dt}"
    );
    assert!((fallen - exact).abs() <= integrator_error * 1.0001);
    // All nodes fell together: the lattice did not deform.
    for (p, r) in w.body_positions(body).iter().zip(&lattice.rest_positions) {
        assert!(((r.coords - p) - Vector3::new(0.0, fallen, 0.0)).norm() < 1e-9);
    }
}

#[test]
fn momentum_is_conserved_without_gravity_and_contact() {
    let mut w = World::new(no_contact(0.0));
    let lattice = cube_lattice([0.0; 3], 0.5, 4);
    let m = Material::preset("soft_rubber").unwrap();
    w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    // Uneven initial velocities (a spin plus a shear plus a drift) that load springs and dampers.
    for (i, v) in w.nodes.velocity.iter_mut().enumerate() {
        let p = lattice.rest_positions[i].coords;
        *v = Vector3::new(0.3, -0.2, 0.1)
            + Vector3::new(-p.y, p.x, 0.0) * 4.0
            + Vector3::new(p.z * p.z, 0.0, -p.x) * 3.0;
    }
    let p0 = w.momentum();
    for f in 1..=24 {
        w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
    }
    let p1 = w.momentum();
    assert!((p1 - p0).norm() < 1e-9 * (1.0 + p0.norm()), "{p0} → {p1}");
}

#[test]
fn undamped_energy_drift_is_bounded_over_ten_seconds() {
    // Springs alone: the dispersion is an inelastic correction by design.
    let mut w = World::new(WorldSettings {
        dispersion: DispersionMode::Off,
        ..no_contact(0.0)
    });
    let lattice = cube_lattice([0.0; 3], 0.3, 3);
    let m = Material::new("undamped", 2.0e4, 0.3, 1000.0, 0.0).unwrap();
    w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    // Four times the automatic substeps: symplectic Euler's energy error oscillates with
    // amplitude ∝ ωΔT and does not grow.
    let auto = w.choose_substeps(1.0 / 24.0).substeps;
    w.settings.fixed_substeps = Some(4 * auto);
    // Start stretched 10 % so it oscillates strongly.
    for p in w.nodes.position.iter_mut() {
        *p *= 1.1;
    }
    let e0 = w.total_energy();
    let elastic0 = w.diagnostics(0).elastic_energy;
    let (mut first_second, mut last_second) = (0.0f64, 0.0f64);
    for f in 1..=240 {
        let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert_eq!(d.dispersion_corrections, 0);
        let dev = (w.total_energy() - e0).abs();
        if f <= 24 {
            first_second = first_second.max(dev);
        }
        if f > 216 {
            last_second = last_second.max(dev);
        }
    }
    assert!(
        first_second < 0.05 * elastic0,
        "energy error {first_second} J of {elastic0} J"
    );
    // Bounded: no secular growth from the first second to the tenth.
    assert!(
        last_second <= 1.2 * first_second + 1e-3 * elastic0,
        "drift grew from {first_second} J to {last_second} J"
    );
}

#[test]
fn cube_dropped_on_the_floor_comes_to_rest() {
    let lattice = cube_lattice([0.0, 0.5, 0.0], 0.5, 6);
    let m = Material::preset("rubber").unwrap();
    let mut w = World::new(floor_settings(&lattice, &m, 0.5));
    let layer = w.settings.layer;
    w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    let mut last = None;
    for f in 1..=72 {
        let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert!(
            d.max_penetration < layer.thickness_m,
            "frame {f}: penetration {} ≥ layer {}",
            d.max_penetration,
            layer.thickness_m
        );
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        last = Some(d);
    }
    let d = last.unwrap();
    assert!(
        d.max_speed < 0.05,
        "still moving at {} m/s after 3 s",
        d.max_speed
    );
    let lowest = w
        .nodes
        .position
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    assert!(
        lowest < 0.0 && lowest > -layer.thickness_m,
        "resting on the layer: lowest node at {lowest}"
    );
}

/// The world of physics §7b's check: gravity, a floor whose elastic layer is 1.5·10⁴ N/m,
/// undamped, frictionless.
fn section_7b_world(mode: DispersionMode) -> World {
    let layer = ContactLayer {
        thickness_m: 0.05,
        stiffness: 1.5e4,
        damping_ratio: 0.0,
        friction: 0.0,
    };
    World::new(WorldSettings {
        planes: vec![floor(0.0)],
        layer,
        dispersion: mode,
        max_dispersion_iterations: 100,
        ..no_contact(9.81)
    })
}

/// A vertical chain of 4 springs (physics §7b): L = 0.1 m, k = 2000 N/m, m = 0.05 kg, floor
/// layer 1.5·10⁴ N/m, ΔT = 1 ms, no damping, dropped onto the floor at `v0`. Returns whether
/// the nodes kept their order along up throughout.
fn chain_keeps_order(mode: DispersionMode, v0: f64) -> bool {
    let mut w = section_7b_world(mode);
    let positions: Vec<Vector3<f64>> = (0..5)
        .map(|i| Vector3::new(0.0, 0.001 + 0.1 * i as f64, 0.0))
        .collect();
    let springs: Vec<(u32, u32, f64, f64)> = (0..4).map(|i| (i, i + 1, 2000.0, 0.0)).collect();
    w.add_body(
        "chain",
        &positions,
        &[0.05; 5],
        &springs,
        Vector3::new(0.0, -v0, 0.0),
    );
    for _ in 0..300 {
        w.step(1e-3);
        let y: Vec<f64> = w.nodes.position.iter().map(|p| p.y).collect();
        if y.windows(2).any(|p| p[1] <= p[0]) {
            return false;
        }
    }
    true
}

#[test]
fn fusion_model_keeps_the_chains_order_where_springs_alone_flip() {
    // Elastic only: kept at 12 m/s, flips at 15.
    assert!(chain_keeps_order(DispersionMode::Off, 12.0));
    assert!(!chain_keeps_order(DispersionMode::Off, 15.0));
    // The model as printed fixes 15 m/s (Fig. 5) but not 18 (physics §7b).
    assert!(chain_keeps_order(DispersionMode::AsPrinted, 15.0));
    assert!(!chain_keeps_order(DispersionMode::AsPrinted, 18.0));
    // The production solver (per-step bound) keeps order up to 60 m/s.
    for v0 in [12.0, 15.0, 18.0, 30.0, 60.0] {
        assert!(
            chain_keeps_order(DispersionMode::Bounded, v0),
            "bounded flips at {v0} m/s"
        );
    }
}

/// A triangle of 3 springs in the vertical plane, base down, dropped at `v0` (Fig. 6).
/// Returns whether its orientation (signed area) never flipped.
fn triangle_keeps_orientation(mode: DispersionMode, v0: f64) -> bool {
    let mut w = section_7b_world(mode);
    let h = 0.1 * 3f64.sqrt() / 2.0;
    let positions = vec![
        Vector3::new(-0.05, 0.001, 0.0),
        Vector3::new(0.05, 0.001, 0.0),
        Vector3::new(0.0, 0.001 + h, 0.0),
    ];
    let springs = vec![
        (0, 1, 2000.0, 0.0),
        (1, 2, 2000.0, 0.0),
        (2, 0, 2000.0, 0.0),
    ];
    w.add_body(
        "triangle",
        &positions,
        &[0.05; 3],
        &springs,
        Vector3::new(0.0, -v0, 0.0),
    );
    let area = |w: &World| {
        let p = &w.nodes.position;
        (p[1] - p[0]).cross(&(p[2] - p[0])).z
    };
    let sign0 = area(&w).signum();
    for _ in 0..300 {
        w.step(1e-3);
        if area(&w) * sign0 <= 0.0 {
            return false;
        }
    }
    true
}

#[test]
fn fusion_model_keeps_the_triangles_orientation() {
    // Springs alone: the apex falls through the base at 10 m/s.
    assert!(triangle_keeps_orientation(DispersionMode::Off, 8.0));
    assert!(!triangle_keeps_orientation(DispersionMode::Off, 10.0));
    // The model as printed does not help here: the triangle flattens while its slanted springs
    // are still over half their length, where eq 5's bound is far above the impact speed
    // (physics §7b: shapes flip without any spring reaching zero length).
    assert!(!triangle_keeps_orientation(DispersionMode::AsPrinted, 10.0));
    // The production solver, whose bound fuses springs at 0.6 L, keeps it up to 60 m/s.
    for v0 in [10.0, 15.0, 30.0, 60.0] {
        assert!(
            triangle_keeps_orientation(DispersionMode::Bounded, v0),
            "bounded flips at {v0} m/s"
        );
    }
}

#[test]
fn lattice_thrown_into_a_wall_at_20_m_s_never_inverts() {
    // Edges + face diagonals + body diagonals: the single-face-diagonal lattice of Table 1 is
    // weak in shear and inverts cells from about 10 m/s into a wall (rubber, 10 cm cells:
    // Mach 0.27 against rubber's 37 m/s wave speed), whatever the dispersion does.
    let (p, t) = box_mesh([0.0; 3], [1.0; 3]);
    let lattice = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(10),
            layout: SpringLayout::Both,
            ..FitSettings::default()
        },
    )
    .unwrap();
    assert_eq!(lattice.cell_count(), 1000);
    let m = Material::preset("rubber").unwrap();
    let layer = WorldSettings::default_layer(lattice.cell_size, &m, 0.4);
    let wall = Plane {
        normal: -Vector3::x(),
        offset: -1.5,
    };
    let mut w = World::new(WorldSettings {
        planes: vec![wall],
        layer,
        ..no_contact(0.0)
    });
    w.add_lattice_body("cube", &lattice, &m, Vector3::new(20.0, 0.0, 0.0));
    let mut hit = false;
    let mut corrections = 0;
    for f in 1..=12 {
        let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        assert_eq!(d.inverted_cells, 0, "frame {f}: {d:?}");
        hit |= d.max_penetration > 0.0;
        corrections += d.dispersion_corrections;
    }
    assert!(hit, "the cube must reach the wall");
    assert!(corrections > 0, "the impact must need the fusion model");
    let vx = w.momentum().x;
    assert!(vx < 0.0, "it bounced back: momentum x {vx}");
}

fn run_with_threads(threads: usize) -> Vec<[u64; 3]> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let lattice = cube_lattice([0.0, 0.3, 0.0], 1.0, 15);
        assert!(lattice.node_count() >= 4096);
        let m = Material::preset("rubber").unwrap();
        let mut w = World::new(floor_settings(&lattice, &m, 0.4));
        w.add_lattice_body("cube", &lattice, &m, Vector3::new(0.5, -6.0, 0.2));
        let mut energies = Vec::new();
        for f in 1..=4 {
            let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
            energies.push([
                d.kinetic_energy.to_bits(),
                d.elastic_energy.to_bits(),
                d.dispersion_corrections,
            ]);
        }
        energies.extend(
            w.nodes
                .position
                .iter()
                .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]),
        );
        energies
    })
}

#[test]
fn identical_bits_with_one_thread_and_with_all_threads() {
    let one = run_with_threads(1);
    let all = run_with_threads(rayon::current_num_threads().max(2));
    assert!(one == all, "results differ between 1 and several threads");
}

#[test]
fn scripted_manipulator_sweep_pushes_a_jelly_cube_away() {
    use springbake_core::solver::manipulator::{ManipulatorKey, ManipulatorTrack};
    // The scene default layout (edges, face and body diagonals).
    let (p, t) = box_mesh([-0.25, 0.0, -0.25], [0.25, 0.5, 0.25]);
    let lattice = fit_lattice(
        &p,
        &t,
        &FitSettings {
            resolution: Resolution::CellsAlongLongest(6),
            layout: SpringLayout::Both,
            ..FitSettings::default()
        },
    )
    .unwrap();
    let m = Material::preset("jelly").unwrap();
    let mut w = World::new(floor_settings(&lattice, &m, 0.4));
    w.add_lattice_body("jelly", &lattice, &m, Vector3::zeros());
    // A vertical rod sweeping +x through the cube's centre line at 1 m/s.
    // Contact acts on lattice nodes, so the rod is at least a cell thick (a thinner rod slips
    // between nodes and folds cells: see the core issue note).
    w.manipulators.push(ManipulatorTrack {
        radius: 0.1,
        length: 0.8,
        friction: 0.3,
        smooth: false,
        keys: vec![
            ManipulatorKey {
                t: 0.0,
                position: Vector3::new(-0.6, 0.25, 0.0),
                yaw_deg: 90.0,
            },
            ManipulatorKey {
                t: 1.0,
                position: Vector3::new(0.4, 0.25, 0.0),
                yaw_deg: 90.0,
            },
        ],
        up: Vector3::y(),
    });
    let centre_x =
        |w: &World| w.nodes.position.iter().map(|p| p.x).sum::<f64>() / w.nodes.len() as f64;
    let x0 = centre_x(&w);
    let mut touched = false;
    for f in 1..=24 {
        let d = w.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        // Known weakness (core issue note): the rod pressing deep into jelly folds a cell or
        // two next to it; more than 2 % of the cells would be a regression.
        assert!(
            d.inverted_cells * 50 <= lattice.cell_count(),
            "frame {f}: {} inverted",
            d.inverted_cells
        );
        if d.reaction().norm() > 0.0 {
            touched = true;
            assert!(
                d.reaction().x < 0.0,
                "the cube pushes back against the sweep: {:?}",
                d.manipulator_reaction
            );
        }
    }
    assert!(touched, "the manipulator must touch the cube");
    let moved = centre_x(&w) - x0;
    assert!(
        moved > 0.05,
        "the cube moved away from the manipulator by only {moved} m"
    );
}

#[test]
fn a_non_finite_value_stops_the_run_naming_frame_body_and_node() {
    use springbake_core::solver::SimulationError;
    let mut w = World::new(no_contact(9.81));
    let lattice = cube_lattice([0.0; 3], 0.3, 3);
    let m = Material::preset("rubber").unwrap();
    w.add_lattice_body("first", &lattice, &m, Vector3::zeros());
    w.add_lattice_body("second", &lattice, &m, Vector3::zeros());
    w.advance_frame(1.0 / 24.0, 2, &|| false).unwrap();
    let n = lattice.node_count();
    w.nodes.velocity[n + 5].y = f64::NAN;
    match w.advance_frame(1.0 / 24.0, 3, &|| false) {
        Err(SimulationError::NonFinite {
            frame, body, node, ..
        }) => {
            assert_eq!((frame, body.as_str()), (3, "second"));
            // The NaN spreads through its springs within the frame; the reported node is one
            // of the second body's nodes.
            assert!(node < n, "body-local index {node}");
        }
        other => panic!("expected a non-finite error, got {other:?}"),
    }
    let err = SimulationError::NonFinite {
        frame: 3,
        body: "second".into(),
        node: 5,
        what: "position",
    };
    assert!(
        err.to_string().contains("frame 3") && err.to_string().contains("node 5"),
        "{err}"
    );
}
