//! Newmark-β with the velocity dispersion and the deformation damping after its corrector,
//! and its iteration counts in the frame diagnostics (issue 7).
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::lattice::Lattice;
use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::solver::{
    ContactLayer, DispersionMode, Integrator, Interpolation, Path, Plane, World, WorldSettings,
};

/// Physics §7b's chain (4 springs, L = 0.1 m, k = 2000 N/m, m = 0.05 kg, floor layer
/// 1.5·10⁴ N/m, ΔT = 1 ms, undamped) dropped at `v0` under Newmark-β; whether the nodes kept
/// their order along up, and the dispersion corrections made.
fn chain_keeps_order(mode: DispersionMode, v0: f64) -> (bool, u64) {
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: ContactLayer {
            thickness_m: 0.05,
            stiffness: 1.5e4,
            damping_ratio: 0.0,
            friction: 0.0,
        },
        dispersion: mode,
        max_dispersion_iterations: 100,
        integrator: Integrator::newmark(),
        ..WorldSettings::default()
    });
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
    let mut corrections = 0;
    for _ in 0..300 {
        corrections += w.step(1e-3).dispersion_corrections;
        let y: Vec<f64> = w.nodes.position.iter().map(|p| p.y).collect();
        if y.windows(2).any(|p| p[1] <= p[0]) {
            return (false, corrections);
        }
    }
    (true, corrections)
}

#[test]
fn the_fusion_model_keeps_the_chains_order_under_newmark() {
    // Springs alone keep the order at 5 m/s and flip at 15; with the bounded dispersion the
    // chain keeps it up to 60 m/s.
    assert!(chain_keeps_order(DispersionMode::Off, 5.0).0);
    assert!(!chain_keeps_order(DispersionMode::Off, 15.0).0);
    for v0 in [5.0, 15.0, 30.0, 60.0] {
        let (kept, corrections) = chain_keeps_order(DispersionMode::Bounded, v0);
        assert!(kept, "bounded flips at {v0} m/s");
        if v0 >= 15.0 {
            assert!(corrections > 0, "{v0} m/s needs the fusion model");
        }
    }
}

fn cube() -> Lattice {
    support::fitted_box([0.0, 0.0, 0.0], [0.3, 0.3, 0.3], 3).2
}

#[test]
fn deformation_damping_acts_under_newmark_and_keeps_momentum() {
    // A spinning, drifting soft cube squashed along y, no gravity: with the deformation
    // damping its elastic energy decays much faster than with the springs' dampers alone,
    // momentum is kept and angular momentum as well as the integrator keeps it.
    let m = Material::preset("soft_rubber").unwrap();
    let run = |damped: bool| {
        let mut w = World::new(WorldSettings {
            gravity: Vector3::zeros(),
            integrator: Integrator::newmark(),
            ..WorldSettings::default()
        });
        w.add_lattice_body("c", &cube(), &m, Vector3::new(0.3, 0.0, 0.1));
        if !damped {
            w.bodies[0].deformation_damping = 0.0;
        }
        for i in 0..w.nodes.len() {
            let x = w.nodes.position[i];
            w.nodes.position[i].y = 0.15 + (x.y - 0.15) * 0.9;
            w.nodes.velocity[i] += Vector3::new(0.0, 2.0, 0.0).cross(&(x - Vector3::repeat(0.15)));
        }
        let angular = |w: &World| {
            let c = w
                .nodes
                .position
                .iter()
                .zip(&w.nodes.mass)
                .map(|(x, m)| x * *m)
                .sum::<Vector3<f64>>()
                / w.nodes.mass.iter().sum::<f64>();
            (0..w.nodes.len())
                .map(|i| (w.nodes.position[i] - c).cross(&w.nodes.velocity[i]) * w.nodes.mass[i])
                .sum::<Vector3<f64>>()
        };
        let (p0, l0) = (w.momentum(), angular(&w));
        let e0 = w.diagnostics(0).elastic_energy;
        for f in 0..12 {
            let d = w.advance_frame(1.0 / 24.0, f + 2, &|| false).unwrap();
            assert!(d.newmark_iterations >= d.substeps && d.newmark_max_iterations >= 1);
            assert_eq!(d.newmark_cap_hits, 0);
        }
        assert!((w.momentum() - p0).norm() < 1e-9 * p0.norm());
        // Newmark-β's trapezoidal rule itself lets L drift a few 1e-4 here (spring dampers and
        // all); the damping's pull towards the rigid motion must not add to that.
        let drift = (angular(&w) - l0).norm() / l0.norm();
        assert!(drift < 1e-3, "angular momentum drifted {drift}");
        w.diagnostics(0).elastic_energy / e0
    };
    let (with, without) = (run(true), run(false));
    println!(
        "elastic energy after 0.5 s: {with:.2e} of the squash with damping, {without:.2e} without"
    );
    assert!(with < 0.2 * without, "{with} vs {without}");
}

#[test]
fn paths_stay_exact_with_the_dispersion_on_and_caps_are_reported() {
    let m = Material::preset("jelly").unwrap();
    let mut w = World::new(WorldSettings {
        integrator: Integrator::newmark(),
        dispersion: DispersionMode::Bounded,
        ..WorldSettings::default()
    });
    w.add_lattice_body("c", &cube(), &m, Vector3::zeros());
    let path = Path::new(
        vec![(0.0, Vector3::zeros()), (0.5, Vector3::new(0.0, 0.4, 0.0))],
        Interpolation::CatmullRom,
    )
    .unwrap();
    w.add_trajectory(&[0], path.clone(), 1.0).unwrap();
    let start = w.nodes.position[0];
    for f in 0..12 {
        w.advance_frame(1.0 / 24.0, f + 2, &|| false).unwrap();
        let want = start + path.at(w.time);
        assert!((w.nodes.position[0] - want).norm() < 1e-9);
    }
    // One iteration with an unreachable tolerance: every step hits the cap, and says so.
    w.settings.integrator = Integrator::Newmark {
        beta: 0.25,
        tolerance: 1e-300,
        max_iterations: 1,
    };
    let d = w.advance_frame(1.0 / 24.0, 14, &|| false).unwrap();
    assert_eq!(d.newmark_cap_hits, d.substeps);
    assert_eq!(
        (d.newmark_iterations, d.newmark_max_iterations),
        (d.substeps, 1)
    );
}
