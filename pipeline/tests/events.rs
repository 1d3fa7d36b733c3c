//! Events and procedures wired through scene files (issue 8 part 3): time events really change
//! the motion, loop events fire every frame, related events are withdrawn together, branch
//! events pick the procedure by the impact force the contact log measured, plug-in procedures,
//! and the errors a bad `[[event]]` gives.
#![allow(clippy::unwrap_used)]

use springbake_core::nalgebra::Vector3;
use springbake_core::plugin::{ProcedurePlugin, Registry};
use springbake_core::procedures::centre_of_mass;
use springbake_core::solver::{BodyHandle, ContactPartner, World};
use springbake_pipeline::{default_registry, load_scene, prepare, BakeHooks, Prepared, Seconds};
use std::path::Path;

/// A 0.2 m cube (OBJ, Y-up) from y = 0 to 0.2, centred on x = z = 0.
fn write_cube(dir: &Path) {
    let mut obj = String::from("o Cube\n");
    for c in 0..8 {
        let x = if c & 1 == 0 { -0.1 } else { 0.1 };
        let y = if c & 2 == 0 { 0.0 } else { 0.2 };
        let z = if c & 4 == 0 { -0.1 } else { 0.1 };
        obj += &format!("v {x} {y} {z}\n");
    }
    obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(dir.join("cube.obj"), obj).unwrap();
}

struct Run {
    prepared: Prepared,
    /// Per output frame: the cube's vertex centroid (source frame = world here).
    centroid: Vec<Vector3<f64>>,
    events: Vec<serde_json::Value>,
}

fn load(dir: &Path, scene: &str) -> springbake_pipeline::LoadedScene {
    write_cube(dir);
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    load_scene(&path).unwrap()
}

fn run_with(dir: &Path, scene: &str, registry: &Registry) -> Run {
    let loaded = load(dir, scene);
    let mut prepared = prepare(registry, &loaded, &mut Seconds::default()).unwrap();
    let (baked, _) = prepared
        .simulate(&loaded.scene, &mut BakeHooks::default())
        .unwrap();
    let centroid = baked.meshes[0]
        .frames
        .iter()
        .map(|f| {
            f.iter()
                .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .sum::<Vector3<f64>>()
                / f.len() as f64
        })
        .collect();
    let events = prepared.event_report();
    Run {
        prepared,
        centroid,
        events,
    }
}

fn run(dir: &Path, scene: &str) -> Run {
    run_with(dir, scene, &default_registry())
}

/// `(frame, event, procedure as JSON text)` of each firing.
fn log(events: &[serde_json::Value]) -> Vec<(u64, String, String)> {
    events
        .iter()
        .map(|e| {
            (
                e["frame"].as_u64().unwrap(),
                e["event"].as_str().unwrap().to_owned(),
                e["procedure"].to_string(),
            )
        })
        .collect()
}

fn head(frames: usize, gravity: f64, floor: bool) -> String {
    let floor = if floor { "floor = 0.0\n" } else { "" };
    format!(
        "[output]\npath = \"out.glb\"\nframes = {frames}\n[world]\ngravity = {gravity}\n{floor}\
         [[body]]\nname = \"cube\"\nsource = \"cube.obj\"\ncells = 3\nmaterial = \"rubber\"\n"
    )
}

#[test]
fn a_time_event_set_velocity_changes_the_motion() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{}offset = [0.0, 1.0, 0.0]\n[[event]]\nname = \"go\"\nbody = \"cube\"\n\
         on = {{ time = 0.5 }}\nprocedure = {{ set_velocity = [1.0, 0.0, 0.0] }}\n",
        head(25, 0.0, false)
    );
    let r = run(dir.path(), &scene);
    // Frame 13 is t = 12/24 = 0.5 s.
    assert_eq!(
        log(&r.events),
        vec![(13, "go".into(), "{\"set_velocity\":[1.0,0.0,0.0]}".into())]
    );
    let c = &r.centroid;
    assert!((c[12] - c[0]).norm() < 1e-9, "still before the event");
    // After it the cube travels at 1 m/s along x: 0.5 m in the last 12 frames.
    let moved = c[24] - c[12];
    assert!((moved.x - 0.5).abs() < 1e-6, "moved {moved:?}");
    assert!(
        moved.y.abs() < 1e-9 && moved.z.abs() < 1e-9,
        "moved {moved:?}"
    );
}

#[test]
fn a_loop_event_fires_every_frame_and_its_force_holds_the_body_up() {
    let dir = tempfile::tempdir().unwrap();
    // The body's mass, from a prepare without events.
    let loaded = load(dir.path(), &head(2, 9.81, false));
    let p = prepare(&default_registry(), &loaded, &mut Seconds::default()).unwrap();
    let (mass, _, _) = centre_of_mass(&p.world, p.bodies[0].handle);
    let weight = mass * 9.81;
    // The force comes as frame-resolved kicks (half before, half after each frame) while the
    // solver integrates gravity per substep (symplectic: the body sinks g T² / (2n) a frame
    // at n substeps of a frame T); 400 substeps keep that under the 1 mm asserted.
    let scene = format!(
        "{}offset = [0.0, 1.0, 0.0]\n[[event]]\nname = \"hold\"\nbody = \"cube\"\n\
         on = {{ frame = 1 }}\nloop = true\nprocedure = {{ apply_force = {{ force_n = [0.0, {weight}, 0.0] }} }}\n\
         [solver]\nsubsteps = 400\n",
        head(24, 9.81, false)
    );
    let r = run(dir.path(), &scene);
    let frames: Vec<u64> = log(&r.events).iter().map(|e| e.0).collect();
    assert_eq!(
        frames,
        (1..=24).collect::<Vec<u64>>(),
        "one firing per frame"
    );
    // Balanced by the force every frame, the cube stays where it was (free fall: 2.6 m).
    let drift = (r.centroid[23] - r.centroid[0]).norm();
    assert!(drift < 1e-3, "drift {drift} m");
    // Without the event it falls.
    let free = run(
        dir.path(),
        &format!("{}offset = [0.0, 1.0, 0.0]\n", head(24, 9.81, false)),
    );
    assert!(free.centroid[0].y - free.centroid[23].y > 2.0);
}

#[test]
fn related_events_are_withdrawn_together_through_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    let ev = |name: &str, on: &str, extra: &str, v: &str| {
        format!(
            "[[event]]\nname = \"{name}\"\nbody = \"cube\"\non = {{ {on} }}\n{extra}\
             procedure = {{ set_velocity = {v} }}\n"
        )
    };
    let scene = format!(
        "{}{}{}{}",
        head(20, 0.0, false),
        ev("a", "frame = 5", "group = \"g\"\n", "[1.0, 0.0, 0.0]"),
        ev("b", "frame = 10", "group = \"g\"\n", "[0.0, 0.0, 1.0]"),
        ev("c", "frame = 12", "after = \"b\"\n", "[0.0, 1.0, 0.0]"),
    );
    let r = run(dir.path(), &scene);
    let fired: Vec<(u64, String)> = log(&r.events).into_iter().map(|e| (e.0, e.1)).collect();
    assert_eq!(fired, vec![(5, "a".to_owned())]);
    let (_, _, v) = centre_of_mass(&r.prepared.world, r.prepared.bodies[0].handle);
    assert!((v - Vector3::x()).norm() < 1e-9, "only a's velocity: {v:?}");
}

/// Peak floor force of the first impact of the cube dropped from `height` (contact log).
fn first_impact_force(dir: &Path, height: f64) -> f64 {
    let loaded = load(
        dir,
        &format!("{}offset = [0.0, {height}, 0.0]\n", head(2, 9.81, true)),
    );
    let mut p = prepare(&default_registry(), &loaded, &mut Seconds::default()).unwrap();
    let world: &mut World = &mut p.world;
    for f in 2..200 {
        world.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        if let Some(r) = world
            .frame_contacts()
            .iter()
            .find(|r| r.partner == ContactPartner::Floor)
        {
            return r.peak_force;
        }
    }
    panic!("no impact");
}

#[test]
fn a_branch_event_picks_the_procedure_by_impact_force() {
    let dir = tempfile::tempdir().unwrap();
    let (low, high) = (0.05, 1.0);
    let soft = first_impact_force(dir.path(), low);
    let hard = first_impact_force(dir.path(), high);
    assert!(hard > 2.0 * soft, "hard {hard} N vs soft {soft} N");
    let threshold = (soft * hard).sqrt();
    let scene = |height: f64| {
        format!(
            "{}offset = [0.0, {height}, 0.0]\n[[event]]\nname = \"land\"\nbody = \"cube\"\n\
             on = {{ collision = \"floor\" }}\nbranch.by = \"impact_force\"\n\
             branch.case = [{{ below = {threshold}, procedure = \"settle\" }}, \
             {{ procedure = {{ set_velocity = [0.0, 3.0, 0.0] }} }}]\n",
            head(30, 9.81, true)
        )
    };
    // Soft drop: settle — the cube stops where it was at the firing.
    let r = run(dir.path(), &scene(low));
    let fired = log(&r.events);
    assert_eq!(fired.len(), 1, "{fired:?}");
    assert_eq!(fired[0].2, "\"settle\"");
    let at = fired[0].0 as usize - 1;
    let still = (r.centroid[29] - r.centroid[at]).norm();
    assert!(still < 1e-9, "settled body moved {still} m");
    // Hard drop: the other case — the cube leaves the floor at 3 m/s.
    let r = run(dir.path(), &scene(high));
    let fired = log(&r.events);
    assert_eq!(fired.len(), 1, "{fired:?}");
    assert_eq!(fired[0].2, "{\"set_velocity\":[0.0,3.0,0.0]}");
    let at = fired[0].0 as usize - 1;
    let rise = r.centroid[at + 6].y - r.centroid[at].y;
    // 3 m/s up for 0.25 s under gravity: 0.75 − 0.31 = 0.44 m.
    assert!((rise - 0.44).abs() < 0.05, "rose {rise} m");
}

/// A plug-in procedure: lifts the body by `height` metres.
struct Lift;

impl ProcedurePlugin for Lift {
    fn name(&self) -> &str {
        "lift"
    }
    fn check(&self, args: &springbake_core::toml::Table) -> Result<(), String> {
        match args.get("height").and_then(|h| h.as_float()) {
            Some(h) if h.is_finite() => Ok(()),
            _ => Err("needs a finite `height` in metres".into()),
        }
    }
    fn run(
        &self,
        world: &mut World,
        body: BodyHandle,
        args: &springbake_core::toml::Table,
    ) -> Result<Vec<springbake_core::events::Procedure>, String> {
        let h = args["height"].as_float().unwrap();
        for i in world.bodies[body.0].nodes.clone() {
            world.nodes.position[i].y += h;
        }
        Ok(Vec::new())
    }
}

#[test]
fn a_plug_in_procedure_registered_on_the_host_runs_from_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    let mut registry = default_registry();
    registry.register_procedure(Lift);
    let event = "[[event]]\nname = \"up\"\nbody = \"cube\"\non = { frame = 3 }\n\
                 procedure = { plugin = { name = \"lift\", args = { height = 0.25 } } }\n";
    let scene = format!("{}{event}", head(5, 0.0, false));
    let r = run_with(dir.path(), &scene, &registry);
    // Frame 3's events act before frame 3 is recorded.
    assert_eq!(r.centroid[1].y - r.centroid[0].y, 0.0);
    assert!((r.centroid[2].y - r.centroid[1].y - 0.25).abs() < 1e-6);
    assert_eq!(r.events[0]["procedure"]["plugin"]["name"], "lift");
    // Unknown plug-in and bad arguments are scene errors naming the event.
    let loaded = load(dir.path(), &scene.replace("\"lift\"", "\"lfit\""));
    let err = prepare(&registry, &loaded, &mut Seconds::default()).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("event[0] \"up\".procedure[0]")
            && msg.contains("lfit")
            && msg.contains("lift"),
        "{msg}"
    );
    let loaded = load(dir.path(), &scene.replace("height = 0.25", "hieght = 0.25"));
    let msg = prepare(&registry, &loaded, &mut Seconds::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("needs a finite `height`"), "{msg}");
}

/// The load or prepare error of a scene with these events.
fn scene_error(events: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    write_cube(dir.path());
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, format!("{}{events}", head(5, 9.81, true))).unwrap();
    match load_scene(&path) {
        Err(e) => e.to_string(),
        Ok(loaded) => prepare(&default_registry(), &loaded, &mut Seconds::default())
            .map(|_| ())
            .unwrap_err()
            .to_string(),
    }
}

#[test]
fn bad_events_are_errors_naming_the_event_and_field() {
    let ev = |body: &str, rest: &str| {
        format!("[[event]]\nname = \"e\"\nbody = \"{body}\"\non = {{ frame = 2 }}\n{rest}")
    };
    let msg = scene_error(&ev("cueb", "procedure = \"pin\"\n"));
    assert!(
        msg.contains("event[0] \"e\".body") && msg.contains("cueb") && msg.contains("cube"),
        "{msg}"
    );

    let msg = scene_error(&ev("cube", "procedure = \"settel\"\n"));
    assert!(msg.contains("line 16") && msg.contains("settel"), "{msg}");

    let msg = scene_error(&ev("cube", "procedure = { follow_trajectory = \"arc\" }\n"));
    assert!(
        msg.contains("event[0] \"e\".procedure[0].follow_trajectory") && msg.contains("arc"),
        "{msg}"
    );

    let msg = scene_error(&ev(
        "cube",
        "procedure = { change_material = \"cheese\" }\n",
    ));
    assert!(
        msg.contains("event[0] \"e\".procedure[0].change_material") && msg.contains("cheese"),
        "{msg}"
    );

    let msg = scene_error(&ev("cube", "procedure = \"pin\"\nafter = \"nope\"\n"));
    assert!(
        msg.contains("event[0] \"e\".after") && msg.contains("nope"),
        "{msg}"
    );

    let branch = "[[event]]\nname = \"land\"\nbody = \"cube\"\non = { collision = \"floor\" }\n\
                  branch.by = \"impact_force\"\nbranch.case = [{ below = 50.0, procedure = \"pin\" }, \
                  { below = 10.0, procedure = \"settle\" }]\n";
    let msg = scene_error(branch);
    assert!(
        msg.contains("event[0] \"land\".branch.case[1].below"),
        "{msg}"
    );

    let msg = scene_error(
        &ev("cube", "procedure = \"pin\"\n").replace("frame = 2", "collision = \"lane\""),
    );
    assert!(
        msg.contains("event[0] \"e\".on.collision")
            && msg.contains("lane")
            && msg.contains("floor"),
        "{msg}"
    );
}

#[test]
fn events_fire_and_act_the_same_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{}offset = [0.0, 0.3, 0.0]\n[[event]]\nname = \"land\"\nbody = \"cube\"\n\
         on = {{ collision = \"floor\" }}\nloop = true\nprocedure = {{ apply_impulse = [0.5, 0.0, 0.0] }}\n\
         [[event]]\nname = \"spin\"\nbody = \"cube\"\non = {{ convergence = 5.0 }}\n\
         procedure = {{ switch_feature = \"roll\" }}\n",
        head(30, 9.81, true)
    );
    let runs: Vec<Run> = [1, 2]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap();
            pool.install(|| run(dir.path(), &scene))
        })
        .collect();
    assert!(!runs[0].events.is_empty());
    assert_eq!(runs[0].events, runs[1].events);
    assert_eq!(runs[0].centroid, runs[1].centroid);
    assert_eq!(runs[0].prepared.world.nodes, runs[1].prepared.world.nodes);
}

#[test]
fn set_velocity_moves_a_rigid_body_too() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{}kind = \"rigid\"\n[[event]]\nname = \"go\"\nbody = \"cube\"\non = {{ frame = 3 }}\n\
         procedure = {{ set_velocity = [0.0, 0.0, -2.0] }}\n",
        head(9, 0.0, false)
    );
    let r = run(dir.path(), &scene);
    // From frame 3 to 9 (0.25 s) at 2 m/s along −z.
    let moved = r.centroid[8] - r.centroid[2];
    assert!(
        (moved - Vector3::new(0.0, 0.0, -0.5)).norm() < 1e-6,
        "{moved:?}"
    );
}

#[test]
fn pin_holds_the_body_until_unpin_and_a_timed_force_gives_its_impulse() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{}offset = [0.0, 1.0, 0.0]\n\
         [[event]]\nname = \"hold\"\nbody = \"cube\"\non = {{ frame = 3 }}\nprocedure = \"pin\"\n\
         [[event]]\nname = \"drop\"\nbody = \"cube\"\non = {{ frame = 10 }}\nprocedure = \"unpin\"\n",
        head(14, 9.81, false)
    );
    let r = run(dir.path(), &scene);
    let c = &r.centroid;
    assert!(c[0].y - c[2].y > 0.01, "fell before the pin");
    assert!((c[9] - c[2]).norm() < 1e-9, "held from frame 3 to 10");
    assert!(c[9].y - c[13].y > 0.05, "fell again after unpin");

    // 2 N along x for 0.5 s on a free body: momentum 1 N·s.
    let loaded = load(dir.path(), &head(2, 0.0, false));
    let p = prepare(&default_registry(), &loaded, &mut Seconds::default()).unwrap();
    let (mass, _, _) = centre_of_mass(&p.world, p.bodies[0].handle);
    let scene = format!(
        "{}[[event]]\nname = \"push\"\nbody = \"cube\"\non = {{ time = 0.0 }}\n\
         procedure = {{ apply_force = {{ force_n = [2.0, 0.0, 0.0], duration_secs = 0.5 }} }}\n",
        head(24, 0.0, false)
    );
    let r = run(dir.path(), &scene);
    let (_, _, v) = centre_of_mass(&r.prepared.world, r.prepared.bodies[0].handle);
    assert!(
        (v.x * mass - 1.0).abs() < 1e-9,
        "momentum {} N·s",
        v.x * mass
    );
    // Uniform acceleration for 0.5 s, then coasting 0.458 s: x = ½ a t² + a t · 0.458.
    let a = 2.0 / mass;
    let want = 0.5 * a * 0.25 + a * 0.5 * (23.0 / 24.0 - 0.5);
    let got = r.centroid[23].x - r.centroid[0].x;
    assert!((got - want).abs() < 1e-6, "moved {got} m, want {want} m");
}

#[test]
fn a_collision_event_names_a_static_collider() {
    let dir = tempfile::tempdir().unwrap();
    let mut table = String::from("o Table\n");
    for c in 0..8 {
        let x = if c & 1 == 0 { -0.5 } else { 0.5 };
        let y = if c & 2 == 0 { 0.0 } else { 0.3 };
        let z = if c & 4 == 0 { -0.5 } else { 0.5 };
        table += &format!("v {x} {y} {z}\n");
    }
    table += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(dir.path().join("table.obj"), table).unwrap();
    let scene = format!(
        "{}offset = [0.0, 0.5, 0.0]\n[[collider]]\nsource = \"table.obj\"\nname = \"table\"\n\
         [[event]]\nname = \"land\"\nbody = \"cube\"\non = {{ collision = \"table\" }}\nprocedure = \"settle\"\n",
        head(16, 9.81, false)
    );
    let r = run(dir.path(), &scene);
    let fired = log(&r.events);
    assert_eq!(fired.len(), 1, "{fired:?}");
    // Landed on the table (its top at 0.3 m; the contact layer lies outside it), not through
    // it, and frozen there; it fell from 0.5 m.
    let at = fired[0].0 as usize - 1;
    let bottom = r.centroid[at].y - 0.1;
    assert!(bottom > 0.28 && bottom < 0.4, "cube bottom at {bottom} m");
    assert!(at > 3, "fired at frame {}", at + 1);
    assert!((r.centroid[15] - r.centroid[at]).norm() < 1e-9);
}
