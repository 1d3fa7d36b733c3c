//! `springbake watch` as a user runs it: real bakes re-run on real file events, a broken
//! scene reported once while the last good output stays, recovery, and a clean Ctrl-C.
#![allow(clippy::unwrap_used)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};

fn scene_text(source: &Path, frames: usize) -> String {
    format!(
        "[output]\npath = \"out.glb\"\nframes = {frames}\n[world]\nfloor = -1.0\n[[body]]\nsource = {:?}\ncells = 4\nmaterial = \"jelly\"\n",
        source.display().to_string()
    )
}

/// The example cube copied into `dir`.
fn example_cube(dir: &Path) -> std::path::PathBuf {
    let source = dir.join("cube.obj");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/cube.obj"),
        &source,
    )
    .unwrap();
    source
}

/// Start the watcher with JSON events; lines arrive on the returned channel.
fn start(scene: &Path) -> (Child, Receiver<serde_json::Value>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_springbake"))
        .args(["watch", scene.to_str().unwrap(), "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line) {
                if tx.send(v).is_err() {
                    break;
                }
            }
        }
    });
    (child, rx)
}

/// Wait (with a deadline) for the next event of one of `kinds`.
fn next_event(rx: &Receiver<serde_json::Value>, kinds: &[&str]) -> serde_json::Value {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let ev = rx
            .recv_timeout(left)
            .unwrap_or_else(|_| panic!("no {kinds:?} event within 60 s"));
        if kinds.contains(&ev["event"].as_str().unwrap_or("")) {
            return ev;
        }
    }
}

/// Morph targets in the baked glb = frames baked (one target per frame).
fn morph_targets(glb: &Path) -> usize {
    let bytes = std::fs::read(glb).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    doc["meshes"][0]["primitives"][0]["targets"]
        .as_array()
        .map_or(0, Vec::len)
}

#[test]
fn watch_rebakes_on_edits_survives_a_broken_scene_and_stops_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let source = example_cube(dir.path());
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, scene_text(&source, 4)).unwrap();
    let out = dir.path().join("out.glb");
    let (mut child, rx) = start(&scene);

    let first = next_event(&rx, &["finished", "failed"]);
    assert_eq!(first["event"], "finished", "{first}");
    assert_eq!(morph_targets(&out), 4);

    // An editor saving through a temp file renamed over the scene: one re-bake, 6 frames.
    let tmp = dir.path().join(".scene.toml.swp");
    std::fs::write(&tmp, scene_text(&source, 6)).unwrap();
    std::fs::rename(&tmp, &scene).unwrap();
    let second = next_event(&rx, &["finished", "failed"]);
    assert_eq!(second["event"], "finished", "{second}");
    assert_eq!(morph_targets(&out), 6);

    // A broken scene: one failure naming the file, the last good output untouched.
    let good = std::fs::read(&out).unwrap();
    std::fs::write(&scene, "[output]\nframes = 3\nbogus = 1\n").unwrap();
    let failed = next_event(&rx, &["finished", "failed"]);
    assert_eq!(failed["event"], "failed", "{failed}");
    assert!(failed.to_string().contains("scene.toml"), "{failed}");
    assert_eq!(std::fs::read(&out).unwrap(), good);

    // Fixed again: recovers by itself. A source edit (the cube made taller) also re-bakes.
    std::fs::write(&scene, scene_text(&source, 5)).unwrap();
    let fixed = next_event(&rx, &["finished", "failed"]);
    assert_eq!(fixed["event"], "finished", "{fixed}");
    assert_eq!(morph_targets(&out), 5);
    let taller = std::fs::read_to_string(&source)
        .unwrap()
        .replace("v -0.25  0.25", "v -0.25  0.75");
    std::fs::write(&source, taller).unwrap();
    let rebaked = next_event(&rx, &["finished", "failed"]);
    assert_eq!(rebaked["event"], "finished", "{rebaked}");
    assert_ne!(std::fs::read(&out).unwrap(), good);

    // Ctrl-C: a clean stop, and no temporary files left behind.
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let deadline = Instant::now() + Duration::from_secs(20);
    let exit = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "watch did not stop on SIGINT");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(exit.success(), "exit status {exit}");
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["cube.obj", "out.glb", "scene.toml"]);
}

/// Issue 22 item 4: an edited plug-in is reloaded. The scene's output format comes from an
/// exporter plug-in in `plugins/` beside it; saving the plug-in with another marker re-bakes
/// and the new output carries the new marker.
#[test]
fn watch_reloads_an_edited_plugin() {
    let dir = tempfile::tempdir().unwrap();
    let source = example_cube(dir.path());
    let plugin = |mark: &str| {
        format!(
            "import json\n\nSPRINGBAKE_PLUGIN = {{'kind': 'exporter', 'name': 'marker', 'extensions': ['mark']}}\n\
             MARK = {mark:?}\n\n\ndef export(baked, path):\n    with open(path, 'w') as f:\n        \
             json.dump({{'mark': MARK, 'meshes': len(baked['meshes'])}}, f)\n"
        )
    };
    std::fs::create_dir(dir.path().join("plugins")).unwrap();
    let plugin_file = dir.path().join("plugins/marker.py");
    std::fs::write(&plugin_file, plugin("first")).unwrap();
    let scene = dir.path().join("scene.toml");
    let text = scene_text(&source, 3).replace("out.glb", "out.mark");
    std::fs::write(&scene, text).unwrap();
    let out = dir.path().join("out.mark");
    let mark =
        || -> serde_json::Value { serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap() };
    let (mut child, rx) = start(&scene);
    let first = next_event(&rx, &["finished", "failed"]);
    assert_eq!(first["event"], "finished", "{first}");
    assert_eq!(mark()["mark"], "first");
    // Saved through a temporary file, as editors do.
    let tmp = dir.path().join("plugins/.marker.py.swp");
    std::fs::write(&tmp, plugin("second")).unwrap();
    std::fs::rename(&tmp, &plugin_file).unwrap();
    let second = next_event(&rx, &["finished", "failed"]);
    assert_eq!(second["event"], "finished", "{second}");
    assert_eq!(mark()["mark"], "second");
    assert_eq!(mark()["meshes"], 1);
    child.kill().unwrap();
    child.wait().unwrap();
}
