//! Skinned and animated glTF sources (issue 19 item 4): Blender writes a tube bound to a bent,
//! animated two-bone armature with a shape key at 0.4; springbake bakes it from the pose the
//! source renders at its first frame, and writes a file without the skin, its joint attributes
//! or the joints' animation (validator clean: no skinned-mesh warnings). Blender's import of
//! the bake sits, at the first frame, where Blender's import of the source renders (skin and
//! shape key applied) and then falls onto the floor. Before this, the bake started from the
//! straight bind pose.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

mod support;

use support::bake_file;

#[test]
fn a_skinned_gltf_bakes_from_its_first_frame_pose_and_loses_its_skin_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("skinned.glb");
    springbake_testkit::run_python_client("make_skinned_gltf.py", &[source.to_str().unwrap()]);
    let err = bake_file(dir.path(), "skinned.glb", "baked.glb", "24");
    assert!(
        err.contains("skinned") && err.contains("morph targets"),
        "{err}"
    );
    let baked = dir.path().join("baked.glb");
    let report = springbake_testkit::gltf_validate(&baked);
    let issues = &report["issues"];
    assert_eq!(issues["numErrors"], 0, "{issues}");
    assert_eq!(issues["numWarnings"], 0, "{issues}");
    let r = springbake_testkit::last_json_line(&springbake_testkit::run_python_client(
        "skinned_roundtrip.py",
        &[source.to_str().unwrap(), baked.to_str().unwrap()],
    ));
    eprintln!("REPORT {r}");
    assert_eq!(r["baked_vertices"], r["source_vertices"], "{r}");
    assert_eq!(r["baked_meshes"], 1, "{r}");
    assert_eq!(r["baked_armatures"], 0, "{r}");
    assert_eq!(r["baked_armature_modifiers"], 0, "{r}");
    // The bent pose: the tube's top is 1.41 m up, not the bind pose's 1.5 m.
    assert!(r["source_highest"].as_f64().unwrap() < 1.45, "{r}");
    let d = r["max_distance_first_frame"].as_f64().unwrap();
    assert!(d < 1e-4, "first frame {d} m from the source's pose: {r}");
    assert!(
        r["baked_lowest_ever"].as_f64().unwrap().abs() < 0.01,
        "lands: {r}"
    );
}
