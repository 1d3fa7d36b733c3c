//! Terasawa's analysis-model features (physics §8–9): Newmark-β against the closed-form
//! oscillator, exact trajectory constraints, the thesis's flag in the wind, and volume
//! preservation of a jelly dropped on the floor.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::solver::{
    nearest_node, nodes_in_box, BodyHandle, DispersionMode, Integrator, Interpolation, Path, Plane,
    Wind, World, WorldSettings,
};
use support::{fitted_box, floor_settings};

fn zero_g(integrator: Integrator) -> WorldSettings {
    WorldSettings {
        gravity: Vector3::zeros(),
        dispersion: DispersionMode::Off,
        integrator,
        ..WorldSettings::default()
    }
}

/// One 1 kg mass on a k = 100 N/m spring (ω = 10 rad/s) to a pinned node, started at rest
/// with amplitude A; run 10 periods at ωΔt = 2π/40. Returns (relative period error, relative
/// amplitude error over the 10th period from the sampled peaks, relative error of the energy
/// amplitude sqrt(u² + (v/ω)²) at the end, newmark iterations, cap hits).
fn oscillator(integrator: Integrator) -> (f64, f64, f64, u32, u32) {
    let (k, m, a0): (f64, f64, f64) = (100.0, 1.0, 0.01);
    let omega = (k / m).sqrt();
    let period = std::f64::consts::TAU / omega;
    let mut w = World::new(zero_g(integrator));
    w.add_body(
        "osc",
        &[Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0)],
        &[0.0, m],
        &[(0, 1, k, 0.0)],
        Vector3::zeros(),
    );
    w.nodes.position[1].x += a0;
    let steps_per_period = 40;
    let dt = period / steps_per_period as f64;
    let (mut iterations, mut caps) = (0, 0);
    let mut prev = a0;
    let mut crossings = Vec::new();
    let mut last_amp = 0.0f64;
    for s in 1..=10 * steps_per_period {
        let st = w.step(dt);
        iterations += st.newmark_iterations;
        caps += st.newmark_cap_hit as u32;
        let u = w.nodes.position[1].x - 1.0;
        assert!(w.nodes.position[1].y == 0.0 && w.nodes.position[1].z == 0.0);
        if prev > 0.0 && u <= 0.0 {
            // Downward zero crossing, linearly interpolated.
            crossings.push((s as f64 - 1.0 + prev / (prev - u)) * dt);
        }
        if s > 9 * steps_per_period {
            last_amp = last_amp.max(u.abs());
        }
        prev = u;
    }
    assert_eq!(crossings.len(), 10, "{crossings:?}");
    let measured = (crossings[9] - crossings[0]) / 9.0;
    let u = w.nodes.position[1].x - 1.0;
    let v = w.nodes.velocity[1].x;
    let energy_amp = (u * u + (v / omega) * (v / omega)).sqrt();
    (
        measured / period - 1.0,
        last_amp / a0 - 1.0,
        energy_amp / a0 - 1.0,
        iterations,
        caps,
    )
}

#[test]
fn newmark_and_symplectic_euler_oscillator_period_and_amplitude_after_ten_periods() {
    let wdt = std::f64::consts::TAU / 40.0;
    let (nm_period, nm_amp, nm_energy, nm_iter, nm_caps) = oscillator(Integrator::newmark());
    let (se_period, se_amp, se_energy, se_iter, _) = oscillator(Integrator::SymplecticEuler);
    let (n6_period, n6_amp, n6_energy, _, n6_caps) = oscillator(Integrator::Newmark {
        beta: 1.0 / 6.0,
        tolerance: 1e-10,
        max_iterations: 50,
    });
    println!(
        "ωΔt = {wdt:.4}: Newmark β=1/4 period error {nm_period:+.3e}, sampled peak error \
         {nm_amp:+.3e}, energy amplitude error {nm_energy:+.3e}, {:.1} iterations/step; β=1/6 \
         period {n6_period:+.3e}, peak {n6_amp:+.3e}, energy amplitude {n6_energy:+.3e}; \
         symplectic Euler period {se_period:+.3e}, peak {se_amp:+.3e}, energy amplitude \
         {se_energy:+.3e}",
        nm_iter as f64 / 400.0
    );
    // Average acceleration: period elongation (ωΔt)²/12, no amplitude error.
    let theory_nm = wdt * wdt / 12.0;
    assert!(
        (nm_period - theory_nm).abs() < 0.15 * theory_nm,
        "{nm_period} vs {theory_nm}"
    );
    // (The sampled peak misses the true one by up to 1 − cos(π/40) ≈ 3e-3.)
    assert!(nm_amp.abs() < 3.1e-3, "{nm_amp}");
    assert!(nm_energy.abs() < 1e-8, "{nm_energy}");
    assert_eq!(nm_caps, 0);
    assert!((400 * 2..=400 * 20).contains(&nm_iter), "{nm_iter}");
    // Linear acceleration: the period lengthens half as much, (ωΔt)²/24.
    assert!(n6_period > 0.0 && n6_period < theory_nm, "{n6_period}");
    assert!(n6_amp.abs() < 5e-3, "{n6_amp}");
    assert!(n6_energy.abs() < 5e-3, "{n6_energy}");
    assert_eq!(n6_caps, 0);
    // Symplectic Euler: period shortened by (ωΔt)²/24, position amplitude up by ~(ωΔt)²/8.
    let theory_se = -wdt * wdt / 24.0;
    assert!(
        (se_period - theory_se).abs() < 0.15 * theory_se.abs(),
        "{se_period} vs {theory_se}"
    );
    assert!(se_amp.abs() < wdt * wdt / 4.0, "{se_amp}");
    assert!(se_energy.abs() < wdt, "{se_energy}");
    assert_eq!(se_iter, 0);
}

/// A hanging chain of `n` nodes, 0.1 m apart along -y from the origin.
fn chain(w: &mut World, n: usize) {
    let xs: Vec<Vector3<f64>> = (0..n)
        .map(|i| Vector3::new(0.0, -0.1 * i as f64, 0.0))
        .collect();
    let springs: Vec<(u32, u32, f64, f64)> =
        (0..n as u32 - 1).map(|i| (i, i + 1, 200.0, 0.05)).collect();
    w.add_body("chain", &xs, &vec![0.05; n], &springs, Vector3::zeros());
}

fn swing_path(interpolation: Interpolation) -> Path {
    Path::new(
        vec![
            (0.0, Vector3::zeros()),
            (0.5, Vector3::new(0.3, 0.1, 0.0)),
            (1.0, Vector3::new(0.0, 0.2, 0.3)),
            (1.5, Vector3::new(-0.3, 0.0, 0.0)),
        ],
        interpolation,
    )
    .unwrap()
}

#[test]
fn trajectory_constrained_node_follows_its_path_exactly() {
    for interpolation in [Interpolation::CatmullRom, Interpolation::Linear] {
        for integrator in [Integrator::newmark(), Integrator::SymplecticEuler] {
            let mut w = World::new(WorldSettings {
                dispersion: DispersionMode::Off,
                integrator,
                ..WorldSettings::default()
            });
            chain(&mut w, 6);
            let path = swing_path(interpolation);
            w.add_trajectory(&[0], path.clone(), 1.0).unwrap();
            let dt = 1e-3;
            let mut worst = 0.0f64;
            for _ in 0..2000 {
                w.step(dt);
                worst = worst.max((w.nodes.position[0] - path.at(w.time)).norm());
            }
            println!("{interpolation:?} {integrator:?}: worst path error {worst:.2e} m");
            assert!(worst < 1e-9, "{worst}");
            // The free end was dragged along and hangs under gravity.
            assert!(w.nodes.position[5].y < path.at(w.time).y - 0.3);
        }
    }
    // Loosely bound (strength 0.3): follows, but not exactly.
    let mut w = World::new(WorldSettings {
        integrator: Integrator::newmark(),
        ..WorldSettings::default()
    });
    chain(&mut w, 6);
    let path = swing_path(Interpolation::CatmullRom);
    w.add_trajectory(&[0], path.clone(), 0.3).unwrap();
    let (mut worst, mut last) = (0.0f64, 0.0);
    for _ in 0..2000 {
        w.step(1e-3);
        last = (w.nodes.position[0] - path.at(w.time)).norm();
        worst = worst.max(last);
    }
    println!("strength 0.3: worst path error {worst:.3e} m, at the end {last:.3e} m");
    assert!(worst > 1e-4 && worst < 0.3, "{worst}");
    assert!(last < 0.05, "{last}");
    assert!(w.add_trajectory(&[99], path.clone(), 1.0).is_err());
    assert!(w.add_trajectory(&[0], path, 1.5).is_err());
}

#[test]
fn pinned_node_stays_put_under_both_integrators() {
    for integrator in [Integrator::newmark(), Integrator::SymplecticEuler] {
        let mut w = World::new(WorldSettings {
            integrator,
            ..WorldSettings::default()
        });
        chain(&mut w, 4);
        let top = nearest_node(&w.nodes.position, Vector3::new(0.0, 0.05, 0.0)).unwrap();
        assert_eq!(top, 0);
        w.pin(&[top]).unwrap();
        for _ in 0..500 {
            w.step(1e-3);
        }
        assert!(w.nodes.position[0].norm() < 1e-12, "{integrator:?}");
        // Hanging: the chain stretched under its weight.
        assert!(w.nodes.position[3].y < -0.3, "{}", w.nodes.position[3].y);
    }
}

#[test]
fn flag_on_a_spline_pole_in_gusting_wind_runs_ten_seconds_within_twice_rest_length() {
    // Terasawa's flag: a 0.7 × 0.45 m cloth of 15 × 10 nodes (structural, shear and bend
    // springs), its two pole-side corners driven along a Catmull-Rom path, in gusting wind.
    let (nx, ny, h) = (15usize, 10usize, 0.05);
    let id = |i: usize, j: usize| (j * nx + i) as u32;
    let xs: Vec<Vector3<f64>> = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| Vector3::new(i as f64 * h, 1.5 + j as f64 * h, 0.0)))
        .collect();
    let m = 0.3 * h * h;
    let (k, d) = (40.0, 2.0 * 0.2 * (40.0f64 * m / 2.0).sqrt());
    let mut springs = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let mut link = |di: usize, dj: usize, kk: f64| {
                if i + di < nx && j + dj < ny {
                    springs.push((id(i, j), id(i + di, j + dj), kk, d));
                }
            };
            link(1, 0, k);
            link(0, 1, k);
            link(1, 1, k);
            link(2, 0, 0.2 * k);
            link(0, 2, 0.2 * k);
            if i > 0 && j + 1 < ny {
                springs.push((id(i, j), id(i - 1, j + 1), k, d));
            }
        }
    }
    let mut w = World::new(WorldSettings {
        dispersion: DispersionMode::Off,
        integrator: Integrator::newmark(),
        wind: Some(Wind {
            velocity: Vector3::new(4.0, 0.0, 0.0),
            gust: Vector3::new(1.0, 0.0, 2.5),
            gust_hz: 0.7,
            drag_per_s: 3.0,
        }),
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        ..WorldSettings::default()
    });
    w.add_body("flag", &xs, &vec![m; xs.len()], &springs, Vector3::zeros());
    let pole = nodes_in_box(
        &w.nodes.position,
        Vector3::new(-0.01, 0.0, -0.01),
        Vector3::new(0.01, 10.0, 0.01),
    );
    assert_eq!(pole.len(), ny);
    let corners = [pole[0], pole[ny - 1]];
    let path = Path::new(
        (0..=10)
            .map(|s| {
                let t = s as f64;
                (
                    t,
                    Vector3::new(0.0, 0.1 * (t * 1.3).sin(), 0.3 * (t * 0.9).sin()),
                )
            })
            .collect(),
        Interpolation::CatmullRom,
    )
    .unwrap();
    w.add_trajectory(&corners, path.clone(), 1.0).unwrap();
    let rest = w.springs.rest_length.clone();
    let fps = 24.0;
    let (mut worst_ratio, mut worst_path, mut substeps) = (0.0f64, 0.0f64, 0u64);
    let mut sum_x = 0.0;
    for frame in 1..=240 {
        let diag = w.advance_frame(1.0 / fps, frame, &|| false).unwrap();
        substeps += diag.substeps as u64;
        for (s, rest_len) in rest.iter().enumerate() {
            let (a, b) = (w.springs.a[s] as usize, w.springs.b[s] as usize);
            let len = (w.nodes.position[a] - w.nodes.position[b]).norm();
            worst_ratio = worst_ratio.max(len / rest_len);
        }
        for (j, &c) in corners.iter().enumerate() {
            let want =
                path.at(w.time) + Vector3::new(0.0, 1.5 + j as f64 * (ny - 1) as f64 * h, 0.0);
            worst_path = worst_path.max((w.nodes.position[c] - want).norm());
        }
        if frame > 120 {
            let far = id(nx - 1, ny / 2) as usize;
            sum_x += w.nodes.position[far].x - w.nodes.position[corners[0]].x;
        }
    }
    let mean_reach = sum_x / 120.0;
    println!(
        "flag: {substeps} substeps, longest spring {worst_ratio:.3}× rest, pole path error \
         {worst_path:.2e} m, free edge {mean_reach:.3} m downwind of the pole"
    );
    assert!(worst_ratio < 2.0, "{worst_ratio}");
    assert!(worst_path < 1e-9, "{worst_path}");
    // The wind holds the flag out: its free edge mostly downwind, about its width away.
    assert!(mean_reach > 0.35 && mean_reach < 1.4, "{mean_reach}");
    assert!(w.nodes.position.iter().all(|x| x.y > 0.0));
}

/// A 0.3 m jelly cube of 6 cells a side, bottom 0.25 m up, thrown at the floor at 6 m/s; runs
/// 1.5 s at 60 fps and returns the volume over V0 at every frame and the largest relative
/// volume drift of one substep before its correction.
fn jelly_drop(preserve: Option<f64>, speed: f64) -> (Vec<f64>, f64) {
    let (_, _, lattice) = fitted_box([0.0, 0.25, 0.0], [0.3, 0.55, 0.3], 6);
    let m = Material::preset("jelly").unwrap();
    let mut w = World::new(floor_settings(&lattice, &m, 0.4));
    let body = w.add_lattice_body("jelly", &lattice, &m, Vector3::new(0.0, -speed, 0.0));
    let v0 = w.body_volume(body);
    assert!((v0 - 0.027).abs() < 0.01 * 0.027, "{v0}");
    if let Some(scale) = preserve {
        w.preserve_volume(body, scale).unwrap();
    }
    let mut ratios = Vec::new();
    let (mut lowest_node, mut drift) = (f64::INFINITY, 0.0f64);
    for _ in 1..=90 {
        let choice = w.choose_substeps(1.0 / 60.0);
        for _ in 0..choice.substeps {
            drift = drift.max(w.step(choice.dt).volume_error);
        }
        assert!(w
            .nodes
            .position
            .iter()
            .all(|x| x.iter().all(|c| c.is_finite())));
        ratios.push(w.body_volume(body) / v0);
        lowest_node = w
            .nodes
            .position
            .iter()
            .map(|x| x.y)
            .fold(lowest_node, f64::min);
    }
    // It did hit the floor, and rests on it.
    assert!(lowest_node < 0.01, "{lowest_node}");
    let centroid_y = w.nodes.position.iter().map(|x| x.y).sum::<f64>() / w.nodes.len() as f64;
    assert!(centroid_y > 0.02 && centroid_y < 0.5, "{centroid_y}");
    (ratios, drift)
}

#[test]
fn jelly_dropped_hard_keeps_its_volume_with_preservation() {
    let range = |r: &[f64]| {
        r.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
    };
    let (off, off_step) = jelly_drop(None, 3.0);
    let (on, on_step) = jelly_drop(Some(1.0), 3.0);
    let (sq, sq_step) = jelly_drop(Some(0.8), 3.0);
    let ((off_lo, off_hi), (on_lo, on_hi)) = (range(&off), range(&on));
    // Scale 0.8: the target ramps at 2 V0/s, so from 0.1 s (frame 6) on it is 0.8 V0.
    assert!(sq[..6].windows(2).all(|w| w[1] < w[0]), "{:?}", &sq[..7]);
    let (sq_lo, sq_hi) = range(&sq[6..]);
    println!(
        "jelly volume / V0 over the drop: off {off_lo:.4}..{off_hi:.4} (loss up to {:.1} %), \
         preserved {on_lo:.6}..{on_hi:.6} (largest drift within one substep before the \
         correction {on_step:.2e}), scale 0.8 {sq_lo:.4}..{sq_hi:.4} (drift {sq_step:.2e})",
        (1.0 - off_lo) * 100.0
    );
    // The impact (and the lattice's missing Poisson effect) squashes the unpreserved jelly.
    assert!(off_lo < 0.9 && off_lo > 0.0, "{off_lo}");
    assert_eq!(off_step, 0.0);
    assert!(on_lo > 0.98 && on_hi < 1.02, "{on_lo} {on_hi}");
    assert!(sq_lo > 0.8 * 0.98 && sq_hi < 0.8 * 1.02, "{sq_lo} {sq_hi}");
    // One substep's unconstrained motion stays well inside the tolerance before correction.
    assert!(on_step > 0.0 && on_step < 0.02, "{on_step}");
    assert!(sq_step < 0.02, "{sq_step}");
}

/// A 0.3 m rubber cube with a contact surface (its mesh, not its lattice, touches the floor),
/// dropped from 0.1 m under Newmark-β; returns the lowest mesh-point height at the end and the
/// state's bits after 1 s.
fn newmark_surface_drop() -> (f64, Vec<u64>) {
    use springbake_core::lattice::surface_samples;
    use springbake_core::nalgebra::Point3;
    let (p, t, lattice) = fitted_box([0.0, 0.1, 0.0], [0.3, 0.4, 0.3], 4);
    let m = Material::preset("rubber").unwrap();
    let mut w = World::new(WorldSettings {
        integrator: Integrator::newmark(),
        wind: Some(Wind {
            velocity: Vector3::new(1.0, 0.0, 0.0),
            gust: Vector3::new(0.0, 0.0, 0.5),
            gust_hz: 2.0,
            drag_per_s: 0.1,
        }),
        ..floor_settings(&lattice, &m, 0.4)
    });
    let body = w.add_lattice_body("cube", &lattice, &m, Vector3::zeros());
    let (points, areas) = surface_samples(&p, &t, lattice.cell_size / 2.0);
    w.add_contact_surface(body, &lattice, &points, &areas);
    w.preserve_volume(body, 1.0).unwrap();
    let top = nodes_in_box(
        &w.nodes.position,
        Vector3::new(-1.0, 0.39, -1.0),
        Vector3::new(1.0, 1.0, 1.0),
    );
    assert!(!top.is_empty());
    w.add_trajectory(&top[..1], Path::constant(w.nodes.position[top[0]]), 0.2)
        .unwrap();
    let (mut caps, mut steps) = (0u32, 0u32);
    for _ in 0..60 {
        let choice = w.choose_substeps(1.0 / 60.0);
        for _ in 0..choice.substeps {
            caps += w.step(choice.dt).newmark_cap_hit as u32;
            steps += 1;
        }
    }
    // (Before the contacts took the explicit predictor velocity, friction made ~15 % of the
    // steps hit the cap.)
    assert_eq!(caps, 0, "{caps} cap hits in {steps} steps");
    let lowest = points
        .iter()
        .map(|q: &Point3<f64>| q.y)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > 0.09);
    let bits = w
        .nodes
        .position
        .iter()
        .chain(&w.nodes.velocity)
        .flat_map(|v| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
        .collect();
    let lowest_node = w
        .nodes
        .position
        .iter()
        .map(|x| x.y)
        .fold(f64::INFINITY, f64::min);
    (lowest_node, bits)
}

#[test]
fn newmark_body_rests_on_its_contact_surface_with_the_same_bits_on_any_thread_count() {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(newmark_surface_drop)
    };
    let (lowest, one) = run(1);
    let (_, all) = run(4);
    println!("Newmark cube on its contact surface: lowest lattice node at {lowest:.4} m");
    // The mesh's bottom is the lattice's bottom here (a box fits its lattice exactly), so the
    // lattice rests on the floor, inside the contact layer, not through it.
    assert!(lowest > -0.02 && lowest < 0.02, "{lowest}");
    assert!(one == all, "thread count changed the result");
}

fn largest_distance_change(w: &World, rest: &[Vector3<f64>]) -> f64 {
    let x = &w.nodes.position;
    let mut worst = 0.0f64;
    for i in 0..x.len() {
        for j in (i + 1)..x.len() {
            let d = (x[i] - x[j]).norm() - (rest[i] - rest[j]).norm();
            worst = worst.max(d.abs());
        }
    }
    worst
}

#[test]
fn rigid_box_tumbles_about_its_intermediate_axis_keeping_its_shape() {
    // A 0.4 × 0.2 × 0.1 m box spun mostly about its intermediate (y) axis in zero gravity:
    // the rotation is unstable and flips (Dzhanibekov), with L and the shape kept.
    let (_, _, lattice) = fitted_box([0.0, 0.0, 0.0], [0.4, 0.2, 0.1], 4);
    let m = Material::preset("rubber").unwrap();
    let mut w = World::new(zero_g(Integrator::SymplecticEuler));
    let body = w.add_lattice_body("box", &lattice, &m, Vector3::zeros());
    let mass: f64 = w.nodes.mass.iter().sum();
    let centre = |w: &World| {
        w.nodes
            .position
            .iter()
            .zip(&w.nodes.mass)
            .map(|(x, m)| x * *m)
            .sum::<Vector3<f64>>()
            / mass
    };
    let c0 = centre(&w);
    let omega0 = Vector3::new(0.3, 5.0, 0.2);
    for i in 0..w.nodes.len() {
        w.nodes.velocity[i] =
            Vector3::new(0.1, 0.0, 0.0) + omega0.cross(&(w.nodes.position[i] - c0));
    }
    w.make_rigid(body).unwrap();
    let rest = w.nodes.position.clone();
    let momentum = |w: &World| {
        let c = centre(w);
        (0..w.nodes.len())
            .map(|i| (w.nodes.position[i] - c).cross(&w.nodes.velocity[i]) * w.nodes.mass[i])
            .sum::<Vector3<f64>>()
    };
    let l0 = momentum(&w);
    let e0 = w.total_energy();
    let (mut worst_shape, mut worst_l, mut worst_e) = (0.0f64, 0.0f64, 0.0f64);
    let (mut min_wy, mut max_wy) = (f64::INFINITY, f64::NEG_INFINITY);
    for frame in 1..=240 {
        w.advance_frame(1.0 / 60.0, frame, &|| false).unwrap();
        worst_shape = worst_shape.max(largest_distance_change(&w, &rest));
        worst_l = worst_l.max((momentum(&w) - l0).norm() / l0.norm());
        worst_e = worst_e.max((w.total_energy() / e0 - 1.0).abs());
        let r = &w.rigid[0];
        let body_omega = r.orientation.inverse() * r.angular_velocity();
        min_wy = min_wy.min(body_omega.y);
        max_wy = max_wy.max(body_omega.y);
    }
    let drift = centre(&w) - c0 - Vector3::new(0.1, 0.0, 0.0) * w.time;
    println!(
        "rigid tumble: distance change {worst_shape:.2e} m, |ΔL|/|L| {worst_l:.2e}, energy \
         drift {worst_e:.2e}, body ω_y {min_wy:.3}..{max_wy:.3} rad/s, centre drift {:.2e} m",
        drift.norm()
    );
    assert!(worst_shape < 1e-9, "{worst_shape}");
    assert!(worst_l < 1e-9, "{worst_l}");
    assert!(worst_e < 0.02, "{worst_e}");
    assert!(drift.norm() < 1e-9, "{drift}");
    // The flip: the spin about y reverses.
    assert!(max_wy > 4.0 && min_wy < -4.0, "{min_wy} {max_wy}");
}

#[test]
fn rigid_cube_dropped_on_the_floor_lands_and_keeps_its_shape() {
    let (_, _, lattice) = fitted_box([0.0, 0.0, 0.0], [0.2, 0.2, 0.2], 3);
    let m = Material::preset("rubber").unwrap();
    for integrator in [Integrator::SymplecticEuler, Integrator::newmark()] {
        let mut w = World::new(WorldSettings {
            planes: vec![Plane {
                normal: Vector3::y(),
                offset: -0.3,
            }],
            layer: WorldSettings::default_layer(lattice.cell_size, &m, 0.4),
            integrator,
            ..WorldSettings::default()
        });
        let body = w.add_lattice_body("cube", &lattice, &m, Vector3::new(0.5, 0.0, 0.0));
        // Tilted spin so it lands on an edge.
        let c0 = Vector3::new(0.1, 0.1, 0.1);
        for i in 0..w.nodes.len() {
            let arm = w.nodes.position[i] - c0;
            w.nodes.velocity[i] += Vector3::new(2.0, 0.0, 3.0).cross(&arm);
        }
        w.make_rigid(body).unwrap();
        let rest = w.nodes.position.clone();
        let mut worst_shape = 0.0f64;
        let mut lowest = f64::INFINITY;
        for frame in 1..=120 {
            w.advance_frame(1.0 / 60.0, frame, &|| false).unwrap();
            worst_shape = worst_shape.max(largest_distance_change(&w, &rest));
            lowest = w.nodes.position.iter().map(|x| x.y).fold(lowest, f64::min);
        }
        let c = w.rigid[0].centre;
        println!(
            "{integrator:?}: rigid drop: distance change {worst_shape:.2e} m, deepest point \
             {:.4} m into the floor, centre at rest {:.4} m above it, speed {:.3} m/s",
            -0.3 - lowest,
            c.y + 0.3,
            w.rigid[0].velocity.norm()
        );
        assert!(worst_shape < 1e-9, "{worst_shape}");
        assert!(lowest > -0.3 - 0.5 * lattice.cell_size, "{lowest}");
        // Came to rest on a face, the centre half a side above the floor.
        assert!((c.y + 0.3 - 0.1).abs() < 0.01, "{}", c.y);
        assert!(w.rigid[0].velocity.norm() < 0.05);
    }
}

/// Height of a 0.1 × 0.4 × 0.1 m soft-rubber column resting on the floor after 3 s, with its
/// stiffness scaled by `scale` per axis; also checks an x edge and a y edge got their factor.
fn column_height(scale: Vector3<f64>) -> f64 {
    let (_, _, lattice) = fitted_box([0.0, 0.0, 0.0], [0.1, 0.4, 0.1], 8);
    let m = Material::preset("soft_rubber").unwrap();
    let mut w = World::new(floor_settings(&lattice, &m, 0.4));
    let body = w.add_lattice_body("column", &lattice, &m, Vector3::zeros());
    let k0 = w.springs.stiffness.clone();
    w.scale_stiffness_per_axis(body, scale).unwrap();
    let mut seen = [false; 3];
    for (s, k_before) in k0.iter().enumerate() {
        let r =
            w.nodes.position[w.springs.a[s] as usize] - w.nodes.position[w.springs.b[s] as usize];
        for (axis, hit) in seen.iter_mut().enumerate() {
            if (r[axis].abs() - r.norm()).abs() < 1e-12 {
                let want = k_before * scale[axis];
                assert!((w.springs.stiffness[s] - want).abs() <= 1e-12 * want);
                *hit = true;
            }
        }
    }
    assert_eq!(seen, [true; 3]);
    for frame in 1..=180 {
        w.advance_frame(1.0 / 60.0, frame, &|| false).unwrap();
    }
    let ys = w.nodes.position.iter().map(|x| x.y);
    ys.clone().fold(f64::NEG_INFINITY, f64::max) - ys.fold(f64::INFINITY, f64::min)
}

#[test]
fn per_axis_stiffness_scale_stiffens_the_column_along_that_axis() {
    assert!(World::new(WorldSettings::default())
        .scale_stiffness_per_axis(BodyHandle(0), Vector3::new(1.0, 0.0, 1.0))
        .is_err());
    let plain = 0.4 - column_height(Vector3::new(1.0, 1.0, 1.0));
    let stiff_y = 0.4 - column_height(Vector3::new(1.0, 4.0, 1.0));
    let stiff_x = 0.4 - column_height(Vector3::new(4.0, 1.0, 1.0));
    println!(
        "column sag under its weight: isotropic {plain:.3e} m, y ×4 {stiff_y:.3e} m, x ×4 \
         {stiff_x:.3e} m"
    );
    assert!(plain > 1e-4, "{plain}");
    // Edges along y carry the load with the diagonals (which get 2.5× or 2×): between.
    let ratio = plain / stiff_y;
    assert!(ratio > 2.0 && ratio < 4.5, "{ratio}");
    // Stiffening across the load changes the sag much less.
    assert!(
        stiff_x > stiff_y * 1.5 && stiff_x <= plain * 1.01,
        "{stiff_x}"
    );
}
