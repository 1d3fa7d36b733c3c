//! Point caches baked from a glTF play on Blender's own import of that glTF (issue 19 item 5):
//! Blender turns a glTF's data to Z-up, so `[output] cache_axes = "blender"` (the default)
//! writes `(x, −z, y)`; the Mesh Cache modifier with its default axes then matches Blender's
//! import of the same bake as glTF morph targets. `cache_axes = "source"` keeps the file's Y-up
//! axes, which do not line up in Blender (the check can fail).
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{corpus_dir, last_json_line, run_python_client};
use std::path::Path;
use support::bake_scene;

fn bake(dir: &Path, output: &str, axes: Option<&str>) {
    let axes = axes.map_or(String::new(), |a| format!("cache_axes = \"{a}\"\n"));
    let scene = format!(
        "[output]\npath = \"{output}\"\nframes = 24\n{axes}\n[world]\nfloor = 0.0\n\n\
         [[body]]\nsource = \"two_objects.glb\"\ncells = 6\n"
    );
    bake_scene(dir, &format!("{output}.toml"), &scene);
}

fn worst(dir: &Path, prefix: &str) -> serde_json::Value {
    let p = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let report = last_json_line(&run_python_client(
        "pointcache_gltf_blender.py",
        &[&p("two_objects.glb"), &p("morph.glb"), &p(prefix), "24"],
    ));
    assert_eq!(
        report["objects"],
        serde_json::json!(["Body", "Head"]),
        "{report}"
    );
    report["worst"].clone()
}

#[test]
fn a_pc2_baked_from_a_gltf_lines_up_on_blenders_import_of_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        corpus_dir().join("blender/two_objects.glb"),
        d.join("two_objects.glb"),
    )
    .unwrap();
    bake(d, "morph.glb", None);
    bake(d, "blender.pc2", None);
    bake(d, "source.pc2", Some("source"));
    for (name, err) in worst(d, "blender").as_object().unwrap() {
        let err = err.as_f64().unwrap();
        assert!(
            err < 1e-5,
            "{name}: the PC2 is {err} m off Blender's import of the bake"
        );
    }
    let off = worst(d, "source");
    let largest = off
        .as_object()
        .unwrap()
        .values()
        .map(|e| e.as_f64().unwrap())
        .fold(0.0, f64::max);
    assert!(
        largest > 0.1,
        "source axes should not line up in Blender: {off}"
    );
}
