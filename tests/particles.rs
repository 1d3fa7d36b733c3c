//! Particle effects (issue 20 part 1, Terasawa §2.3) through the CLI and their real clients:
//! usd-core reads each emitter's `Points` (counts rising for streams and falling as bursts
//! die, smoke's widths growing and opacity fading, ids with every point) and a fountain's
//! streaks (a segment per particle along its motion), Blender imports
//! them as point clouds whose point counts change over time and stay above the floor; a glTF
//! output holds the particles as nodes with keys (validator, Blender) and all of them in a USD
//! stage beside it; the same scene gives the same bytes;
//! a `follow` that names no body is refused with exit code 2.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{corpus_dir, last_json_line, run_python_client};
use std::path::Path;
use support::{springbake_in, succeeded};

const SCENE: &str = r#"
[output]
path = "OUTPUT"
frames = 48

[world]
floor = 0.0

[[body]]
name = "ball"
source = "icosphere.glb"
cells = 6

[[emitter]]
name = "boom"
kind = "explosion"
position = [0, 1.5, 0]
count = 2000
speed = [2, 5]
lifetime = [0.5, 1.5]
seed = 3

[[emitter]]
name = "jet"
kind = "fountain"
position = [1, 0, 0]
rate = 400
speed = [3, 4]
spread = 10

[[emitter]]
name = "puff"
kind = "smoke"
position = [-1, 0.5, 0]
count = 300
speed = [0.2, 0.5]
size = [0.02, 0.3]
opacity = [0.8, 0.0]
lifetime = [1.5, 1.8]

[[emitter]]
name = "ring"
kind = "splash"
follow = "FOLLOW"
radius = 0.5
rate = 300
speed = [1, 2]
spread = 60
"#;

fn bake(dir: &Path, output: &str, follow: &str) -> std::process::Output {
    let file = format!("{output}.toml");
    let text = SCENE.replace("OUTPUT", output).replace("FOLLOW", follow);
    std::fs::write(dir.join(&file), text).unwrap();
    springbake_in(dir, &["bake", &file, "--progress", "quiet"])
}

fn baked(dir: &Path, output: &str) {
    succeeded(&bake(dir, output, "ball"));
}

/// A temporary folder holding the corpus icosphere.
fn with_icosphere() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        corpus_dir().join("blender/icosphere.glb"),
        dir.path().join("icosphere.glb"),
    )
    .unwrap();
    dir
}

fn column(report: &serde_json::Value, prim: &str, k: usize) -> Vec<f64> {
    report[prim]
        .as_array()
        .unwrap_or_else(|| panic!("no {prim}: {report}"))
        .iter()
        .map(|row| row[k].as_f64().unwrap())
        .collect()
}

#[test]
fn usd_core_and_blender_read_the_emitters_point_clouds() {
    let dir = with_icosphere();
    let d = dir.path();
    baked(d, "fx.usda");
    let stage = d.join("fx.usda").to_string_lossy().into_owned();
    let frames = ["0", "12", "24", "47"];
    let mut args = vec![stage.as_str()];
    args.extend(frames);
    let usd = last_json_line(&run_python_client("particles_usd.py", &args));

    let boom = column(&usd, "/root/particles/boom", 0);
    assert_eq!(boom[0], 2000.0, "the burst at the start: {usd}");
    assert!(boom[2] < boom[1] && boom[3] == 0.0, "bursts die: {boom:?}");
    let jet = column(&usd, "/root/particles/jet", 0);
    assert!((jet[2] - 400.0).abs() <= 2.0, "400/s for 1 s: {jet:?}");
    assert!(
        jet.windows(2).all(|w| w[0] < w[1]),
        "a stream grows: {jet:?}"
    );
    let (width, opacity) = (
        column(&usd, "/root/particles/puff", 1),
        column(&usd, "/root/particles/puff", 2),
    );
    assert!(
        width[0] < width[1] && width[1] < width[2],
        "smoke grows: {width:?}"
    );
    assert!(
        opacity[0] > opacity[1] && opacity[1] > opacity[2],
        "and fades: {opacity:?}"
    );
    assert_eq!(
        column(&usd, "/root/particles/ring", 0),
        column(&usd, "/root/particles/ring", 3),
        "an id per point"
    );

    // The fountain's water is drawn as streaks too (§2.3.2): a segment per particle,
    // half a frame of its travel long, along it; only the fountain has them by default.
    let streaks = last_json_line(&run_python_client(
        "particles_streaks.py",
        &[stage.as_str(), "/root/particles/jet", "24"],
    ));
    assert_eq!(streaks["segments"], streaks["points"], "{streaks}");
    assert!(streaks["segments"].as_u64().unwrap() > 300, "{streaks}");
    assert!(streaks["cosine"].as_f64().unwrap() > 0.999, "{streaks}");
    assert!(
        (streaks["length_ratio"].as_f64().unwrap() - 0.5).abs() < 0.01,
        "{streaks}"
    );
    assert_eq!(
        streaks["streak_prims"],
        serde_json::json!(["/root/particles/jet_streaks"])
    );

    let blender = last_json_line(&run_python_client("particles_blender.py", &args));
    for name in ["boom", "jet", "puff", "ring"] {
        let counts: Vec<f64> = blender["counts"][name]
            .as_array()
            .unwrap_or_else(|| panic!("Blender has no point cloud {name}: {blender}"))
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect();
        assert_eq!(counts, column(&usd, &format!("/root/particles/{name}"), 0));
        for low in blender["lowest"][name].as_array().unwrap() {
            if let Some(z) = low.as_f64() {
                assert!(z > -1e-4, "{name} went through the floor: {blender}");
            }
        }
    }
}

#[test]
fn a_gltf_bake_writes_its_particles_beside_it_and_the_same_scene_the_same_bytes() {
    let dir = with_icosphere();
    let d = dir.path();
    baked(d, "fx.glb");
    let first = std::fs::read(d.join("fx.particles.usda")).unwrap();
    let first_glb = std::fs::read(d.join("fx.glb")).unwrap();
    baked(d, "fx.glb");
    assert_eq!(first, std::fs::read(d.join("fx.particles.usda")).unwrap());
    assert!(first_glb == std::fs::read(d.join("fx.glb")).unwrap());
    assert!(String::from_utf8_lossy(&first).contains("def Points \"boom\""));

    // In the glTF itself: a node per particle under its emitter's node (the first 2000 of
    // the burst), one shared mesh, translation and scale keys; the validator passes it and
    // Blender plays it: the jet's last particle is not there until it is born, the burst's
    // first flies out and is gone once dead.
    springbake_testkit::assert_gltf_valid(&d.join("fx.glb"));
    let out = run_python_client(
        "particles_gltf_blender.py",
        &[
            d.join("fx.glb").to_str().unwrap(),
            "boom,jet,puff",
            "jet.700@1/48,boom.0@1/10/48",
        ],
    );
    let report = last_json_line(&out);
    assert_eq!(report["children"]["boom"], 2000, "{report}");
    assert_eq!(report["children"]["puff"], 300, "{report}");
    let jet = report["children"]["jet"].as_u64().unwrap();
    assert!((700..=800).contains(&jet), "400 a second for 2 s: {report}");
    let row = |name: &str, k: usize| -> Vec<f64> {
        let r = &report["particles"][name][k];
        (0..4).map(|i| r[i].as_f64().unwrap()).collect()
    };
    assert_eq!(row("jet.700", 0)[3], 0.0, "not born at frame 1: {report}");
    assert!(row("jet.700", 1)[3] > 0.0, "alive at frame 48: {report}");
    let (start, flying) = (row("boom.0", 0), row("boom.0", 1));
    assert!(start[3] > 0.0 && flying[3] > 0.0, "{report}");
    // Blender's Z-up: the burst starts 1.5 m up and its particles fly apart.
    assert!((start[2] - 1.5).abs() < 0.2, "{report}");
    let moved: f64 = (0..3)
        .map(|k| (flying[k] - start[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved > 0.5, "moved {moved} m: {report}");
    assert_eq!(
        row("boom.0", 2)[3],
        0.0,
        "dead by 2 s (lifetime ≤ 1.5 s): {report}"
    );

    // springbake's viewer opens the glTF with its thousands of particle nodes and renders a
    // frame (a smoke test: what it draws was looked at by hand, see docs/benchmarks.md).
    let png = d.join("shot.png");
    let args = [
        "view",
        "fx.glb",
        "--screenshot",
        png.to_str().unwrap(),
        "--frame",
        "12",
    ];
    succeeded(&springbake_in(d, &args));
    assert!(png.exists());

    let out = bake(d, "wrong.usda", "nobody");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("emitter[3].follow") && err.contains("nobody"),
        "{err}"
    );
    assert!(!d.join("wrong.usda").exists());
}

/// Emitters started and stopped by events (issue 20: "a body that hits the floor hard enough
/// bursts into an explosion"): a ball falls onto the floor; its landing starts a burst that
/// waits for it (`wait_for_event`, following the ball) and a time event stops a fountain.
/// No dust before the landing frame, the whole burst on it, at the ball; the fountain's count
/// stops growing once stopped and its last particles die.
#[test]
fn events_start_a_burst_on_landing_and_stop_a_stream() {
    let dir = with_icosphere();
    let d = dir.path();
    let scene = r#"
[output]
path = "ev.usda"
frames = 48

[world]
floor = 0.0

[[body]]
name = "ball"
source = "icosphere.glb"
cells = 6

[[emitter]]
name = "dust"
kind = "explosion"
follow = "ball"
wait_for_event = true
count = 400
speed = [0.5, 1.0]
lifetime = [3.0, 3.0]

[[emitter]]
name = "jet"
kind = "fountain"
position = [1, 0, 0]
rate = 240
lifetime = [0.2, 0.2]

[[event]]
name = "land"
body = "ball"
on = { collision = "floor" }
procedure = { start_emitter = "dust" }

[[event]]
name = "tap"
body = "ball"
on = { time = 0.5 }
procedure = { stop_emitter = "jet" }
"#;
    let (_, report) = support::bake_scene_reporting(d, "ev.toml", scene);
    let landing = report["events"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["event"] == "land")
        .unwrap_or_else(|| panic!("the ball never landed: {report}"))["frame"]
        .as_u64()
        .unwrap() as usize;
    // USD time code i is output frame i + 1.
    let frames: Vec<String> = (0..48).map(|i| i.to_string()).collect();
    let mut args = vec![d.join("ev.usda").to_str().unwrap().to_owned()];
    args.extend(frames);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let usd = last_json_line(&run_python_client("particles_usd.py", &args));
    let dust = column(&usd, "/root/particles/dust", 0);
    assert!(
        dust[..landing - 1].iter().all(|&c| c == 0.0),
        "dust before the landing (frame {landing}): {dust:?}"
    );
    assert_eq!(
        dust[landing - 1],
        400.0,
        "the burst on the landing frame: {dust:?}"
    );
    let jet = column(&usd, "/root/particles/jet", 0);
    // stopped at 0.5 s (frame 13); 0.2 s lifetimes: none left from frame 19 on
    assert!(jet[10] > 30.0, "the jet runs first: {jet:?}");
    assert!(jet[20..].iter().all(|&c| c == 0.0), "stopped: {jet:?}");
    // A start_emitter naming no emitter is refused before the bake.
    std::fs::write(
        d.join("bad.toml"),
        scene.replace("start_emitter = \"dust\"", "start_emitter = \"dusty\""),
    )
    .unwrap();
    let bad = springbake_in(d, &["bake", "bad.toml"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        support::stderr(&bad).contains("no [[emitter]] is named \"dusty\""),
        "{}",
        support::stderr(&bad)
    );
}

/// Particles bounce off `[[collider]]`s too (issue 20: "bouncing off the floor, walls and
/// colliders"): a burst 0.7 m above a 2 m square table top (a collider at 0.5 m) lands on it
/// and stays on it; without the table the same burst falls to the floor.
#[test]
fn particles_land_on_a_collider() {
    let dir = with_icosphere();
    let d = dir.path();
    std::fs::write(
        d.join("table.obj"),
        "o Table\nv -1 0.5 -1\nv 1 0.5 -1\nv 1 0.5 1\nv -1 0.5 1\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    let scene = |collider: &str| {
        format!(
            "[output]\npath = \"t.usda\"\nframes = 36\n[world]\nfloor = 0.0\n\
             [[body]]\nsource = \"icosphere.glb\"\noffset = [5.0, 0.0, 0.0]\ncells = 4\n\
             [[emitter]]\nname = \"grit\"\nkind = \"explosion\"\nposition = [0, 1.2, 0]\n\
             radius = 0.2\ncount = 300\nspeed = [0.0, 0.3]\nlifetime = [5, 5]\n{collider}"
        )
    };
    let lowest = |collider: &str| -> Vec<Option<f64>> {
        std::fs::write(d.join("t.toml"), scene(collider)).unwrap();
        succeeded(&springbake_in(
            d,
            &["bake", "t.toml", "--progress", "quiet"],
        ));
        let stage = d.join("t.usda");
        let out = run_python_client(
            "particles_heights.py",
            &[stage.to_str().unwrap(), "0.8", "36"],
        );
        last_json_line(&out)["/root/particles/grit"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64())
            .collect()
    };
    let on_table = lowest("[[collider]]\nsource = \"table.obj\"\n");
    let ys: Vec<f64> = on_table.iter().flatten().copied().collect();
    assert!(
        ys.iter().all(|&y| y > 0.5 - 1e-4),
        "through the table: {on_table:?}"
    );
    assert!(
        ys.last().is_some_and(|&y| y < 0.52),
        "landed on it: {on_table:?}"
    );
    let no_table = lowest("");
    assert!(
        no_table.iter().flatten().any(|&y| y < 0.1),
        "without the table it reaches the floor: {no_table:?}"
    );
}

/// The viewer draws a scene's particles while it steps it (issue 20: "the viewer draws
/// particles"): the same scene with and without its explosion, rendered at frame 12 with the
/// same camera (it frames the bodies), differs by thousands of light pixels.
#[test]
fn the_viewer_draws_a_scenes_particles() {
    let dir = with_icosphere();
    let d = dir.path();
    let scene = "[output]\nframes = 24\n[world]\nfloor = 0.0\n\
                 [[body]]\nname = \"ball\"\nsource = \"icosphere.glb\"\ncells = 6\n";
    let burst = "[[emitter]]\nkind = \"explosion\"\nposition = [0, 1.5, 0]\ncount = 2000\n\
                 speed = [2, 5]\nlifetime = [0.5, 1.5]\nsize = [0.03, 0.03]\n";
    std::fs::write(d.join("plain.toml"), scene).unwrap();
    std::fs::write(d.join("burst.toml"), format!("{scene}{burst}")).unwrap();
    let render = |name: &str| {
        let png = d.join(format!("{name}.png"));
        let toml = format!("{name}.toml");
        let args = [
            "view",
            &toml,
            "--screenshot",
            png.to_str().unwrap(),
            "--frame",
            "12",
        ];
        succeeded(&springbake_in(d, &args));
        support::decode_png(&std::fs::read(&png).unwrap()).2
    };
    let (plain, burst) = (render("plain"), render("burst"));
    assert_eq!(plain.len(), burst.len());
    let particles = plain
        .chunks_exact(4)
        .zip(burst.chunks_exact(4))
        .filter(|(a, b)| {
            let light = b[..3].iter().all(|&c| c > 120);
            let changed = (0..3).any(|k| a[k].abs_diff(b[k]) > 30);
            light && changed
        })
        .count();
    assert!(particles > 2000, "{particles} particle pixels");
}
