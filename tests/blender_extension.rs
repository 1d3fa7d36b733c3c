//! The Blender extension, as a user and a farm script use it: built into its zip by
//! `scripts/build-blender-extension.sh`, installed from that zip into Blender 5.0.1 (`bpy`),
//! then `bpy.ops.springbake.bake()` / `free_bake()` on Suzanne over a plane collider, three
//! balls in a centimetre scene, and a block pushed by an animated object as the manipulator
//! (`tests/clients/blender_extension.py` does the Blender side and prints what it saw).
#![allow(clippy::unwrap_used)]

use serde_json::Value;
use springbake_testkit::{last_json_line, venv_python, workspace_root};
use std::process::Command;

fn lows(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn the_extension_bakes_selected_objects_onto_the_originals_and_frees_them() {
    let root = workspace_root();
    let dir = tempfile::tempdir().unwrap();
    let zip = dir.path().join("springbake.zip");
    let built = Command::new(root.join("scripts/build-blender-extension.sh"))
        .arg(&zip)
        .output()
        .unwrap();
    assert!(built.status.success(), "{built:?}");
    let (resources, work) = (dir.path().join("blender"), dir.path().join("work"));
    std::fs::create_dir_all(&resources).unwrap();
    std::fs::create_dir_all(&work).unwrap();
    let run = Command::new(venv_python())
        .arg(root.join("tests/clients/blender_extension.py"))
        .arg(&zip)
        .arg(env!("CARGO_BIN_EXE_springbake"))
        .arg(&work)
        // Installs into this folder, not the user's own Blender configuration.
        .env("BLENDER_USER_RESOURCES", &resources)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "client failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let r = last_json_line(&stdout);
    assert_eq!(r["installed"], true, "{r}");

    // Suzanne: the bake is a Mesh Cache modifier first in the stack, on the original.
    assert_eq!(r["bake_error"], Value::Null, "{r}");
    assert_eq!(
        r["modifiers"][0],
        serde_json::json!(["springbake", "MESH_CACHE"])
    );
    assert_eq!(r["modifiers"][1][1], "SUBSURF", "later modifiers stay: {r}");
    for kept in [
        "vertex_count_kept",
        "material_kept",
        "uv_layers_kept",
        "plane_has_no_modifier",
    ] {
        assert_eq!(r[kept], true, "{kept}: {r}");
    }
    // Frame 1 is the rest shape; it falls onto the plane (not through it) and comes to lie
    // on it.
    assert!(r["frame1_vs_rest_max_m"].as_f64().unwrap() < 1e-5, "{r}");
    let plane = r["plane_z"].as_f64().unwrap();
    let suzanne = lows(&r["suzanne_lowest_z"]);
    let lowest = suzanne.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        lowest > plane - 0.01 && lowest < plane + 0.02,
        "Suzanne's lowest point over the bake {lowest} (plane at {plane}): {suzanne:?}"
    );
    let resting = suzanne[suzanne.len() - 12..]
        .iter()
        .cloned()
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        resting < plane + 0.05,
        "Suzanne still above the plane over the last half second: {suzanne:?}"
    );
    // Another material, another motion; Free bake gives the rest shape back.
    assert_eq!(r["rebake_error"], Value::Null, "{r}");
    assert!(r["material_change_moves_m"].as_f64().unwrap() > 0.01, "{r}");
    assert_eq!(r["free"], serde_json::json!(["FINISHED"]));
    assert!(
        r["after_free_vs_rest_max_m"].as_f64().unwrap() < 1e-6,
        "{r}"
    );
    assert_eq!(r["modifiers_after_free"], serde_json::json!(["SUBSURF"]));
    // A missing binary is a report naming the cause and where to set it, not a traceback;
    // the previous bake stays.
    let missing = r["missing_binary_error"].as_str().unwrap();
    assert!(
        missing.contains("springbake binary") && missing.contains("Preferences"),
        "{missing}"
    );
    assert!(!missing.contains("Traceback"), "{missing}");
    assert_eq!(r["modifier_kept_after_failure"], true);

    // Three bodies and a collider in a centimetre scene: every original gets its cache, and
    // they fall 50 cm in about 0.32 s (frame 8.7 at 24 fps), not in slow motion.
    assert_eq!(r["multi_error"], Value::Null, "{r}");
    for m in r["multi_modifiers"].as_array().unwrap() {
        assert_eq!(m, &serde_json::json!(["MESH_CACHE"]), "{r}");
    }
    for (name, lows_cm) in r["multi_lowest_z"].as_object().unwrap() {
        let lows_cm = lows(lows_cm);
        let landed = lows_cm.iter().position(|&z| z < 5.0).unwrap();
        assert!(
            (8..=9).contains(&landed),
            "{name} reached the ground at frame index {landed}: {lows_cm:?}"
        );
        assert!(
            lows_cm.iter().all(|&z| z > -1.0),
            "{name} went through: {lows_cm:?}"
        );
    }

    // Cancelling stops the process at once.
    let cancel = &r["cancel"];
    assert_eq!(cancel["total"], 5000, "{cancel}");
    assert!(cancel["seconds"].as_f64().unwrap() < 5.0, "{cancel}");
    assert_ne!(cancel["returncode"], 0, "{cancel}");

    // The panels name existing settings and operators, the custom material's constants too.
    let items: Vec<&str> = r["panel_items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for needed in [
        "material",
        "young",
        "cells",
        "kind",
        "floor",
        "manipulator",
        "springbake.bake",
        "springbake.free_bake",
    ] {
        assert!(items.contains(&needed), "{needed} not drawn: {items:?}");
    }

    // The animated object drove the capsule through the block.
    assert_eq!(r["manipulator_error"], Value::Null, "{r}");
    assert_eq!(r["pusher_modifiers"], 0);
    assert!(r["block_pushed_m"].as_f64().unwrap() > 0.3, "{r}");
}
