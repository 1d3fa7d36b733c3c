//! Vertex animation textures played by a real player (issue 23 item 2): three.js in headless
//! Chromium applies the textures in a vertex shader (`tests/clients/vat_player/`), and every
//! frame's image (silhouette and normal colours, from a fixed orthographic camera) matches
//! three.js's own playback of the glTF morph cache of the same bake. The pca cache (item 3)
//! is played and compared the same way. A Y-up glTF and a Z-up USD hierarchy of two parts.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{corpus_dir, last_json_line, run_node_client};
use std::path::Path;
use support::bake_scene;

const FRAMES: usize = 24;

fn bake(dir: &Path, source: &str, output: &str, cache: &str) {
    let scene = format!(
        "[output]\npath = \"{output}\"\nframes = {FRAMES}\n{cache}\n\n[world]\nfloor = 0.0\n\n\
         [[body]]\nsource = \"{source}\"\ncells = 6\n"
    );
    bake_scene(dir, &format!("{output}.toml"), &scene);
}

fn play(source: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(corpus_dir().join("blender").join(source), d.join(source)).unwrap();
    bake(d, source, "baked.vat", "");
    bake(d, source, "morph.glb", "");
    bake(d, source, "pca.glb", "cache = \"pca\"");
    let frames: Vec<String> = [0, 4, 8, 12, 16, 20, FRAMES - 1]
        .iter()
        .map(|f| f.to_string())
        .collect();
    let mut args = vec![d.to_str().unwrap(), "baked.vat", "morph.glb", "pca.glb"];
    args.extend(frames.iter().map(String::as_str));
    let report = last_json_line(&run_node_client("vat_player.js", &args));
    assert!(d.join("vat_player.png").is_file());
    assert_eq!(report["errors"], serde_json::json!([]), "{report}");
    report
}

fn check(report: &serde_json::Value) {
    let mut moved = false;
    for row in report["results"].as_array().unwrap() {
        let at = |player: &str, what: &str| row[player][what].as_f64().unwrap();
        assert!(at("vat_float", "pixels") > 5_000.0, "nothing drawn: {row}");
        assert!(at("vat_float", "iou") > 0.999, "float VAT: {row}");
        assert!(
            at("vat_float", "colour") < 0.005,
            "float VAT normals: {row}"
        );
        // 8-bit offsets step by their range over 255: 1.1 cm for the USD scene's 2.7 m fall,
        // a few pixels at this camera, so edges may move a pixel or two (the float VAT above
        // shows the decoding itself is exact).
        assert!(at("vat_8bit", "iou") > 0.985, "8-bit VAT: {row}");
        assert!(at("vat_8bit", "colour") < 0.02, "8-bit VAT normals: {row}");
        assert!(at("pca", "iou") > 0.995, "pca cache: {row}");
        // The comparison sees motion: later frames do not look like the first.
        moved |= at("vat_float_vs_first", "iou") < 0.9;
    }
    assert!(moved, "the bake never moved: {report}");
}

#[test]
fn three_js_plays_the_vat_of_a_gltf_bake_as_its_morph_cache() {
    check(&play("icosphere.glb"));
}

#[test]
fn three_js_plays_the_vat_of_a_z_up_usd_hierarchy_as_its_morph_cache() {
    check(&play("two_objects.usda"));
}
