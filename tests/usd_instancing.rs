//! USD sources as a renderer draws them (issue 19 item 3): native instances (instanceable
//! internal references) are simulated, one body per instance, and written back with their
//! own points (the instance stops sharing its prototype); a point instancer's instances are
//! realised, one body per visible instance, written back as meshes of their own beside the
//! instancer (which is made invisible), while its prototype is not simulated where it sits;
//! an invisible mesh is left out with a note unless the body asks
//! for it (`include_hidden = true`). usd-core reads the baked stages. Before this, the two
//! crates were skipped silently (the traversal did not enter instances) and the prototype was
//! simulated as a body; the stage did not even open (an internal reference was taken for a
//! file).

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

mod support;

use support::{bake_file, springbake_in, stderr};

fn motion(stage: &std::path::Path) -> serde_json::Value {
    let out =
        springbake_testkit::run_python_client("usd_mesh_motion.py", &[stage.to_str().unwrap()]);
    springbake_testkit::last_json_line(&out)["meshes"].clone()
}

#[test]
fn instances_are_simulated_prototypes_and_hidden_meshes_are_not() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let source = d.join("stage.usda");
    springbake_testkit::run_python_client("make_instanced_usd.py", &[source.to_str().unwrap()]);
    let err = bake_file(d, "stage.usda", "baked.usda", "24");
    assert!(
        err.contains("1 prim(s) not simulated")
            && err.contains("/World/GhostXf/Ghost (invisible)")
            && err.contains("include_hidden"),
        "{err}"
    );
    let m = motion(&d.join("baked.usda"));
    for crate_path in ["/World/Crate0/Box", "/World/Crate1/Box"] {
        let c = &m[crate_path];
        assert_eq!(c["samples"], 24, "{crate_path}: {m}");
        let (first, last) = (
            c["lowest_first"].as_f64().unwrap(),
            c["lowest_last"].as_f64().unwrap(),
        );
        assert!(first > 0.7 && last < first - 0.3, "{crate_path} falls: {c}");
    }
    assert_eq!(m["/World/Scatter/Prototypes/Pebble"]["samples"], 0, "{m}");

    // The point instances start where usd-core draws them (position, orientation, scale,
    // the prototype root's own transform, the instancer's) and fall; the masked one is not
    // made; the instancer no longer draws.
    let out = springbake_testkit::run_python_client(
        "usd_point_instances.py",
        &[
            source.to_str().unwrap(),
            "/World/Scatter",
            "/World/Scatter/Prototypes/Pebble",
            d.join("baked.usda").to_str().unwrap(),
        ],
    );
    let pi = springbake_testkit::last_json_line(&out);
    assert_eq!(pi["instancer_visible"], false, "{pi}");
    assert_eq!(pi["masked_copies"], serde_json::json!([]), "{pi}");
    for i in 0..3 {
        let path = format!("/World/Scatter_instances/Pebble_{i}");
        let copy = &pi["copies"][&path];
        assert!(copy["error"].as_f64().unwrap() < 1e-5, "{path}: {pi}");
        assert_eq!(copy["visible"], true, "{path}: {pi}");
        assert_eq!(copy["samples"], 24, "{path}: {pi}");
        let fell = &m[&path];
        assert!(
            fell["lowest_last"].as_f64().unwrap() < fell["lowest_first"].as_f64().unwrap() - 0.3,
            "{path} falls: {fell}"
        );
    }
    // By hand: the second pebble's centre, (0, 0, 0.1) in its prototype, scaled 0.5, turned
    // about z, at (0, 4, 1), the instancer moved 0.5 m along x.
    let centre = &pi["copies"]["/World/Scatter_instances/Pebble_1"]["centre"];
    for (k, want) in [0.5, 4.0, 1.05].iter().enumerate() {
        assert!(
            (centre[k].as_f64().unwrap() - want).abs() < 1e-5,
            "{centre}"
        );
    }
    assert_eq!(m["/World/GhostXf/Ghost"]["samples"], 0, "{m}");

    // Asked for: the invisible box is simulated too.
    std::fs::write(
        d.join("scene.toml"),
        "[output]\npath = \"all.usda\"\nframes = 12\n[world]\nfloor = 0.0\n\
         [[body]]\nsource = \"stage.usda\"\ninclude_hidden = true\n",
    )
    .unwrap();
    let out = springbake_in(d, &["bake", "scene.toml", "--progress", "quiet"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("not simulated"), "{}", stderr(&out));
    let m = motion(&d.join("all.usda"));
    assert_eq!(m["/World/GhostXf/Ghost"]["samples"], 12, "{m}");
    assert_eq!(m["/World/Crate1/Box"]["samples"], 12, "{m}");
}
