//! The classic animation principles from scene files (issue 8 part 4; Terasawa §4.2): squash
//! and stretch (`volume_scale` procedure), anticipation (`anticipate`), exaggeration
//! (`[[body]] contact_scale`), secondary action (`[[attach]]`, eq 4.1), and the motion
//! features `roll` and `bounce` measured in motion.
#![allow(clippy::unwrap_used)]

use springbake_core::procedures::centre_of_mass;
use springbake_core::solver::{BodyHandle, ContactPartner, World};
use springbake_pipeline::{default_registry, load_scene, prepare, BakeHooks, Prepared, Seconds};
use std::path::Path;

/// An axis-aligned box OBJ named `name` from `lo` to `hi`.
fn write_box(dir: &Path, file: &str, name: &str, lo: [f64; 3], hi: [f64; 3]) {
    let mut obj = format!("o {name}\n");
    for c in 0..8 {
        let x = if c & 1 == 0 { lo[0] } else { hi[0] };
        let y = if c & 2 == 0 { lo[1] } else { hi[1] };
        let z = if c & 4 == 0 { lo[2] } else { hi[2] };
        obj += &format!("v {x} {y} {z}\n");
    }
    obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(dir.join(file), obj).unwrap();
}

fn prepared(dir: &Path, scene: &str) -> (Prepared, springbake_pipeline::LoadedScene) {
    write_box(dir, "cube.obj", "Cube", [-0.1, 0.0, -0.1], [0.1, 0.2, 0.1]);
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let loaded = load_scene(&path).unwrap();
    let p = prepare(&default_registry(), &loaded, &mut Seconds::default()).unwrap();
    (p, loaded)
}

fn simulate(dir: &Path, scene: &str) -> Prepared {
    let (mut p, loaded) = prepared(dir, scene);
    p.simulate(&loaded.scene, &mut BakeHooks::default())
        .unwrap();
    p
}

const CUBE: &str =
    "[[body]]\nname = \"cube\"\nsource = \"cube.obj\"\ncells = 4\nmaterial = \"soft_rubber\"\n";

#[test]
fn squash_and_stretch_drives_the_volume_to_the_scale() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "[output]\npath = \"o.glb\"\nframes = 24\n[world]\ngravity = 0.0\n{CUBE}\
         [[event]]\nname = \"squash\"\nbody = \"cube\"\non = {{ time = 0.0 }}\nprocedure = {{ volume_scale = 0.7 }}\n"
    );
    let (p0, _) = prepared(dir.path(), &scene);
    let v0 = p0.world.body_volume(BodyHandle(0));
    let p = simulate(dir.path(), &scene);
    let v = p.world.body_volume(BodyHandle(0));
    assert!((v / v0 - 0.7).abs() < 0.02, "volume ratio {}", v / v0);
}

#[test]
fn anticipation_pulls_back_then_throws() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "[output]\npath = \"o.glb\"\nframes = 2\n[world]\ngravity = 0.0\n{CUBE}\
         [[event]]\nname = \"windup\"\nbody = \"cube\"\non = {{ time = 0.0 }}\n\
         procedure = {{ anticipate = {{ velocity = [2.0, 0.0, 0.0], pull_back_m = 0.05, duration_secs = 0.25 }} }}\n"
    );
    let (mut p, loaded) = prepared(dir.path(), &scene);
    let h = p.bodies[0].handle;
    let back_face = |w: &World| {
        let r = w.bodies[h.0].nodes.clone();
        w.nodes.position[r]
            .iter()
            .map(|x| x.x)
            .fold(f64::INFINITY, f64::min)
    };
    let (back0, (_, c0, _)) = (back_face(&p.world), centre_of_mass(&p.world, h));
    // Run the wind-up (0.25 s = 6 frames) through the pipeline's own frame loop.
    let mut scene6 = loaded.scene.clone();
    scene6.output.frames = 7;
    p.simulate(&scene6, &mut BakeHooks::default()).unwrap();
    let (_, c1, _) = centre_of_mass(&p.world, h);
    let pulled = back0 - back_face(&p.world);
    assert!(pulled > 0.02, "the trailing face drew back {pulled} m");
    assert!(
        c1.x < c0.x,
        "the body moved back first: {} → {}",
        c0.x,
        c1.x
    );
    // Then released at 2 m/s along +x.
    let mut scene12 = loaded.scene.clone();
    scene12.output.frames = 12;
    let (mut p, _) = prepared(dir.path(), &scene);
    p.simulate(&scene12, &mut BakeHooks::default()).unwrap();
    let (_, c2, v2) = centre_of_mass(&p.world, h);
    assert!(
        (v2.x - 2.0).abs() < 1e-9 && c2.x > c1.x,
        "released at {v2:?}"
    );
}

/// Largest floor force over a drop of the cube with this contact scale (contact log), with
/// the papers' integrator: its floor is the elastic layer whose stiffness the scale sets (the
/// XPBD solver's floor is a hard constraint: see docs/scene.md).
fn peak_floor_force(dir: &Path, contact_scale: f64) -> f64 {
    let scene = format!(
        "[output]\npath = \"o.glb\"\nframes = 2\n[world]\nfloor = 0.0\n{CUBE}\
         offset = [0.0, 0.3, 0.0]\ncontact_scale = {contact_scale}\n\
         [solver]\nintegrator = \"symplectic_euler\"\n"
    );
    let (mut p, _) = prepared(dir, &scene);
    let mut peak: f64 = 0.0;
    for f in 2..16 {
        p.world.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        for r in p.world.frame_contacts() {
            if r.partner == ContactPartner::Floor {
                peak = peak.max(r.peak_force);
            }
        }
    }
    peak
}

#[test]
fn exaggeration_scales_the_contact_force() {
    let dir = tempfile::tempdir().unwrap();
    let plain = peak_floor_force(dir.path(), 1.0);
    let exaggerated = peak_floor_force(dir.path(), 4.0);
    // A 4× stiffer layer stops the body over a shorter distance: a larger peak force.
    assert!(exaggerated > 1.4 * plain, "{exaggerated} N vs {plain} N");
}

#[test]
fn secondary_action_child_hangs_on_its_parent_by_three_nodes() {
    let dir = tempfile::tempdir().unwrap();
    write_box(
        dir.path(),
        "tail.obj",
        "Tail",
        [-0.02, -0.32, -0.02],
        [0.02, -0.02, 0.02],
    );
    let scene = format!(
        "[output]\npath = \"o.glb\"\nframes = 7\n[world]\ngravity = 9.81\n{CUBE}\
         [[body]]\nname = \"tail\"\nsource = \"tail.obj\"\ncell_size = 0.04\nmaterial = \"jelly\"\n\
         [[attach]]\nchild = \"tail\"\nparent = \"cube\"\n\
         anchors = [[-0.02, -0.02, -0.02], [0.02, -0.02, -0.02], [0.0, -0.02, 0.02]]\n\
         [[event]]\nname = \"swing\"\nbody = \"cube\"\non = {{ time = 0.0 }}\n\
         procedure = {{ follow_trajectory = \"sideways\" }}\n\
         [[trajectory]]\nname = \"sideways\"\nkeys = [{{ t = 0.0, position = [0.0, 0.0, 0.0] }}, {{ t = 0.25, position = [0.5, 0.0, 0.0] }}]\n"
    );
    let p = simulate(dir.path(), &scene);
    let (cube, tail) = (p.bodies[0].handle, p.bodies[1].handle);
    // At t = 0.25 s the parent went 0.5 m along x (its trajectory) and the tail came with it…
    let (_, cc, _) = centre_of_mass(&p.world, cube);
    let (_, ct, _) = centre_of_mass(&p.world, tail);
    assert!((cc.x - 0.5).abs() < 1e-6, "parent at {cc:?}");
    assert!(ct.x > 0.3, "the tail followed: {ct:?}");
    // …held up by its anchors (free, it would have fallen 0.31 m in 0.25 s)…
    let top = |w: &World| {
        let r = w.bodies[tail.0].nodes.clone();
        w.nodes.position[r]
            .iter()
            .map(|x| x.y)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let (p0, _) = prepared(dir.path(), &scene);
    let dropped = top(&p0.world) - top(&p.world);
    assert!(
        dropped.abs() < 0.005,
        "the tail's top moved {dropped} m down"
    );
    // …and its free end lags behind: the tail is bent, not carried rigidly (which would give
    // 0). The nearly incompressible jelly (ν = 0.49) of the volumetric cells bends less in a
    // one-cell-thick tail than the papers' spring lattice did (3 mm against 1 cm at 0.25 s;
    // ν = 0 gives 9 mm): see the solver issue's note.
    let lag = lag_of_tip(&p.world, tail);
    assert!(lag > 0.002, "tip lag {lag} m");
}

/// How far the tail's lowest nodes are behind (−x) its top nodes.
fn lag_of_tip(world: &World, tail: BodyHandle) -> f64 {
    let r = world.bodies[tail.0].nodes.clone();
    let xs = &world.nodes.position[r];
    let top = xs.iter().map(|x| x.y).fold(f64::NEG_INFINITY, f64::max);
    let bottom = xs.iter().map(|x| x.y).fold(f64::INFINITY, f64::min);
    let mean_x = |pick: &dyn Fn(f64) -> bool| {
        let sel: Vec<f64> = xs.iter().filter(|x| pick(x.y)).map(|x| x.x).collect();
        sel.iter().sum::<f64>() / sel.len() as f64
    };
    mean_x(&|y| y > top - 0.01) - mean_x(&|y| y < bottom + 0.01)
}
