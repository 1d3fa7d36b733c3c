//! The motion features measured in motion (physics §11): `roll` is an exact geometric rolling
//! path with the speed the body had, `bounce` sets the body down on the floor once a rebound
//! is slower than its tolerance, `settle` freezes it, `change_material` re-derives the springs.
#![allow(clippy::unwrap_used)]

use springbake_core::nalgebra::{Rotation3, Unit, Vector3};
use springbake_core::procedures::{centre_of_mass, lowest_over};
use springbake_core::solver::{Plane, World};
use springbake_pipeline::{default_registry, load_scene, prepare, BakeHooks, Prepared, Seconds};
use std::path::Path;

/// Simulate a scene (written into `dir`) whose bodies use the bowling example's ball.obj.
fn simulate(dir: &Path, scene: &str) -> Prepared {
    simulate_heights(dir, scene).0
}

/// The same, with the ball's vertex-centroid height per output frame.
fn simulate_heights(dir: &Path, scene: &str) -> (Prepared, Vec<f64>) {
    let ball = springbake_testkit::workspace_root().join("examples/bowling/ball.obj");
    std::fs::copy(ball, dir.join("ball.obj")).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let loaded = load_scene(&path).unwrap();
    let mut p = prepare(&default_registry(), &loaded, &mut Seconds::default()).unwrap();
    let (baked, _) = p
        .simulate(&loaded.scene, &mut BakeHooks::default())
        .unwrap();
    let heights = baked.meshes[0]
        .frames
        .iter()
        .map(|f| f.iter().map(|q| q[1] as f64).sum::<f64>() / f.len() as f64)
        .collect();
    (p, heights)
}

fn ball_scene(frames: usize, extra: &str) -> String {
    format!(
        "[output]\npath = \"o.glb\"\nframes = {frames}\n[world]\nfloor = 0.0\n\
         [[body]]\nname = \"ball\"\nsource = \"ball.obj\"\ncells = 3\nmaterial = \"rubber\"\n{extra}"
    )
}

fn positions(w: &World) -> Vec<Vector3<f64>> {
    w.nodes.position[w.bodies[0].nodes.clone()].to_vec()
}

#[test]
fn roll_follows_the_geometric_rolling_path_with_the_speed_it_had() {
    let dir = tempfile::tempdir().unwrap();
    let events = "offset = [0.0, 0.2, 0.0]\n[[event]]\nname = \"go\"\nbody = \"ball\"\n\
                  on = { time = 0.0 }\nprocedure = [{ set_velocity = [2.0, -1.0, 0.0] }, { switch_feature = \"roll\" }]\n";
    // Frame 1: the roll starts (the ball set down on the floor, its vertical speed dropped).
    let start = simulate(dir.path(), &ball_scene(1, events));
    let floor = Plane {
        normal: Vector3::y(),
        offset: 0.0,
    };
    assert!(lowest_over(&start.world, start.bodies[0].handle, &floor).abs() < 1e-12);
    let (_, c0, v0) = centre_of_mass(&start.world, start.bodies[0].handle);
    assert!((v0 - Vector3::new(2.0, 0.0, 0.0)).norm() < 1e-12, "{v0:?}");
    let x0 = positions(&start.world);
    // 12 frames later (0.5 s): 1 m along x, turned by 1 m / r about −z, every node exactly.
    let end = simulate(dir.path(), &ball_scene(13, events));
    assert!(end.events.as_ref().unwrap().motions()[0].is_rolling());
    let (_, c1, _) = centre_of_mass(&end.world, end.bodies[0].handle);
    assert!(
        (c1 - c0 - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-9,
        "{c0:?} → {c1:?}"
    );
    let radius = c0.y;
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(-Vector3::z()), 1.0 / radius);
    let worst = x0
        .iter()
        .zip(positions(&end.world))
        .map(|(a, b)| (c1 + turn * (a - c0) - b).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "off the rolling path by {worst} m");
}

#[test]
fn bounce_settles_on_the_floor_once_a_rebound_is_under_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let events = "offset = [0.0, 0.6, 0.0]\nbounce_tolerance = 1.6\n[[event]]\nname = \"b\"\n\
                  body = \"ball\"\non = { time = 0.0 }\nprocedure = { switch_feature = \"bounce\" }\n";
    let (p, y) = simulate_heights(dir.path(), &ball_scene(40, events));
    let motion = &p.events.as_ref().unwrap().motions()[0];
    assert!(
        motion.is_resting(),
        "the bounce never settled: heights {y:?}"
    );
    // It bounced (rebounds faster than the tolerance) before it settled: two or more landings.
    let landings = (1..y.len() - 1)
        .filter(|&i| y[i] < y[i - 1] && y[i] < y[i + 1])
        .count();
    assert!(landings >= 2, "heights {y:?}");
    let floor = Plane {
        normal: Vector3::y(),
        offset: 0.0,
    };
    let h = p.bodies[0].handle;
    assert!(lowest_over(&p.world, h, &floor).abs() < 1e-12);
    let (_, _, v) = centre_of_mass(&p.world, h);
    assert!(v.y.abs() < 1e-12, "still moving vertically: {v:?}");
    let last = &y[y.len() - 4..];
    let spread = last.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - last.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(spread < 0.003, "resting ball moved {spread} m: {y:?}");
}

#[test]
fn settle_freezes_and_change_material_rederives_the_springs() {
    let dir = tempfile::tempdir().unwrap();
    let events = "offset = [0.0, 0.6, 0.0]\n[[event]]\nname = \"stop\"\nbody = \"ball\"\n\
                  on = { frame = 5 }\nprocedure = [\"settle\", { change_material = \"steel\" }]\n";
    let p = simulate(dir.path(), &ball_scene(12, events));
    let h = p.bodies[0].handle;
    let (_, _, v) = centre_of_mass(&p.world, h);
    assert_eq!(v, Vector3::zeros());
    let at5 = simulate(dir.path(), &ball_scene(5, events));
    let moved = positions(&p.world)
        .iter()
        .zip(positions(&at5.world))
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(moved < 1e-12, "frozen since frame 5, moved {moved} m");
    // Steel: E × 2.01e11 / 1.5e6 on every spring, masses × 7850 / 1100.
    let w0 = simulate(dir.path(), &ball_scene(1, "offset = [0.0, 0.6, 0.0]\n")).world;
    let s = p.world.bodies[0].springs.clone();
    let k = p.world.springs.stiffness[s.start] / w0.springs.stiffness[s.start];
    assert!((k / (2.01e11 / 1.5e6) - 1.0).abs() < 1e-12, "{k}");
    let m = p.world.nodes.mass[0] / w0.nodes.mass[0];
    assert!((m / (7850.0 / 1100.0) - 1.0).abs() < 1e-12, "{m}");
}
