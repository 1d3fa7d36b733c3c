//! Alembic export (issue 23 item 1), checked by its real client: Blender's Alembic importer
//! plays the archive, each object has the source's vertices, faces facing outward and UVs, the
//! bodies fall and land, and every vertex is where Blender's import of the same bake in
//! another format puts it (a glTF morph cache; a Z-up USD stage with a hierarchy), to 1e-5 m.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{corpus_dir, last_json_line, run_python_client};
use std::path::Path;
use support::bake_scene;

const FRAMES: usize = 24;

fn bake(dir: &Path, source: &str, output: &str) {
    let scene = format!(
        "[output]\npath = \"{output}\"\nframes = {FRAMES}\n\n[world]\nfloor = 0.0\n\n\
         [[body]]\nsource = \"{source}\"\ncells = 6\n"
    );
    bake_scene(dir, &format!("{output}.toml"), &scene);
}

/// Bakes `source` to `.abc` and to `reference`, and has Blender compare them.
fn compare_in_blender(source: &str, reference: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(corpus_dir().join("blender").join(source), d.join(source)).unwrap();
    bake(d, source, "baked.abc");
    bake(d, source, reference);
    let p = |name: &str| d.join(name).to_string_lossy().into_owned();
    last_json_line(&run_python_client(
        "alembic_blender.py",
        &[&p("baked.abc"), &p(reference), &FRAMES.to_string()],
    ))
}

fn check_objects(report: &serde_json::Value, expected: &[&str]) {
    let objects = report["objects"].as_object().unwrap();
    let mut names: Vec<&str> = objects.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(names, expected, "{report}");
    for (name, o) in objects {
        let worst = o["worst"].as_f64().unwrap_or(f64::INFINITY);
        assert!(
            worst < 1e-5,
            "{name}: {worst} m off the reference: {report}"
        );
        assert_eq!(o["vertices"], o["reference_vertices"], "{name}: {report}");
        assert_eq!(o["outward"].as_f64(), Some(1.0), "{name} faces: {report}");
        assert!(
            !o["uv_layers"].as_array().unwrap().is_empty(),
            "{name} lost its UVs: {report}"
        );
    }
}

#[test]
fn blender_plays_the_alembic_of_a_gltf_bake_as_its_morph_cache() {
    let report = compare_in_blender("icosphere.glb", "morph.glb");
    check_objects(&report, &["Icosphere"]);
    // 0.5 m above the floor at the first sample (Blender frame 0); falls, lands, stays above.
    let lowest: Vec<f64> = report["objects"]["Icosphere"]["lowest"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!((lowest[0] - 0.5).abs() < 1e-3, "{lowest:?}");
    let landed = lowest.iter().copied().fold(f64::INFINITY, f64::min);
    assert!((-0.01..0.02).contains(&landed), "{lowest:?}");
    // Sample i is baked frame i + 1 at i / fps: Blender's range starts at 0.
    assert_eq!(
        report["frame_range"],
        serde_json::json!([0, FRAMES - 1]),
        "{report}"
    );
}

#[test]
fn blender_plays_the_alembic_of_a_z_up_usd_hierarchy_as_the_usd_bake() {
    let report = compare_in_blender("two_objects.usda", "baked.usda");
    let objects = report["objects"].as_object().unwrap();
    assert_eq!(objects.len(), 2, "{report}");
    let mut names: Vec<&str> = objects.keys().map(String::as_str).collect();
    names.sort_unstable();
    check_objects(&report, &names);
}

#[test]
fn the_same_bake_gives_the_same_alembic_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        corpus_dir().join("blender/two_objects.obj"),
        d.join("two_objects.obj"),
    )
    .unwrap();
    std::fs::copy(
        corpus_dir().join("blender/two_objects.mtl"),
        d.join("two_objects.mtl"),
    )
    .unwrap();
    bake(d, "two_objects.obj", "a.abc");
    let first = std::fs::read(d.join("a.abc")).unwrap();
    bake(d, "two_objects.obj", "a.abc");
    assert_eq!(first, std::fs::read(d.join("a.abc")).unwrap());
    assert!(first.starts_with(b"Ogawa"), "not an Ogawa archive");
}
