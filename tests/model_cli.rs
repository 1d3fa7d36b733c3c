//! `springbake model` (issue 20 part 2, Terasawa §5.3): a superquadric creature polygonised
//! at the default resolution is a watertight glTF that Khronos' validator passes, and baking it
//! makes it fall and land like any mesh; a bad shapes file names its line (exit 2).
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::assert_gltf_valid;
use support::{springbake_in, succeeded};

const CREATURE: &str = r#"
[[superquadric]]   # body
center = [0, 0.6, 0]
radii = [0.3, 0.18, 0.16]
exponents = [0.6, 0.9]

[[superquadric]]   # head
center = [0.32, 0.78, 0]
radii = [0.13, 0.12, 0.11]

[[superquadric]]   # legs
center = [0.18, 0.35, 0.1]
radii = [0.05, 0.2, 0.05]
[[superquadric]]
center = [-0.18, 0.35, -0.1]
radii = [0.05, 0.2, 0.05]
[[superquadric]]
center = [0.18, 0.35, -0.1]
radii = [0.05, 0.2, 0.05]
[[superquadric]]
center = [-0.18, 0.35, 0.1]
radii = [0.05, 0.2, 0.05]

[[superquadric]]   # tail
center = [-0.38, 0.72, 0]
radii = [0.18, 0.03, 0.03]
rotation = [0, 0, -35]
"#;

#[test]
fn a_modelled_creature_is_a_valid_watertight_mesh_that_bakes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("creature.toml"), CREATURE).unwrap();
    let said = succeeded(&springbake_in(
        d,
        &["model", "creature.toml", "-o", "creature.glb"],
    ));
    assert!(said.contains("watertight"), "{said}");
    assert_gltf_valid(&d.join("creature.glb"));

    let bake = [
        "bake",
        "creature.glb",
        "-o",
        "baked.glb",
        "--frames",
        "72",
        "--report",
        "report.json",
    ];
    succeeded(&springbake_in(d, &bake));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("report.json")).unwrap()).unwrap();
    let frames = report["frames"].as_array().unwrap();
    let at = |f: usize, key: &str| frames[f][key].as_f64().unwrap();
    assert!(
        at(71, "gravity_energy") < at(0, "gravity_energy"),
        "it fell"
    );
    assert!(
        at(71, "kinetic_energy") < 0.05 * at(0, "gravity_energy"),
        "and landed"
    );
    assert!(frames.iter().all(|f| f["inverted_cells"] == 0));

    std::fs::write(
        d.join("bad.toml"),
        "threshold = 0.5\n[[superquadric]]\nradius = 1\n",
    )
    .unwrap();
    let out = springbake_in(d, &["model", "bad.toml", "-o", "bad.glb"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml") && err.contains("line 3"), "{err}");
}

/// A body's `source` may be the superquadric model itself (issue 20 part 2's scene form):
/// it is polygonised before the fit and bakes like a mesh file (falls, lands, no inverted
/// cells, a validator-clean glTF); a wrong key inside the model names the key and the line.
#[test]
fn an_inline_superquadric_source_bakes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = "[output]\npath = \"blob.glb\"\nframes = 48\n[world]\nfloor = 0.0\n\
        [[body]]\nname = \"blob\"\nmaterial = \"soft_rubber\"\ncells = 8\n\
        source = { threshold = 0.5, superquadric = [\n\
          { center = [0.0, 0.6, 0.0], radii = [0.25, 0.2, 0.2] },\n\
          { center = [0.25, 0.75, 0.0], radii = [0.12, 0.12, 0.12], exponents = [0.3, 0.3] },\n\
        ] }\n";
    let (_, report) = support::bake_scene_reporting(d, "blob.toml", scene);
    assert_gltf_valid(&d.join("blob.glb"));
    let frames = report["frames"].as_array().unwrap();
    let at = |f: usize, key: &str| frames[f][key].as_f64().unwrap();
    assert!(
        at(47, "gravity_energy") < 0.5 * at(0, "gravity_energy"),
        "it fell: {report}"
    );
    assert!(frames.iter().all(|f| f["inverted_cells"] == 0));
    assert_eq!(report["bodies"][0]["name"], "blob", "{report}");

    std::fs::write(
        d.join("bad.toml"),
        scene.replace("radii = [0.25", "radius = [0.25"),
    )
    .unwrap();
    let out = springbake_in(d, &["bake", "bad.toml"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("radius") && err.contains("line"),
        "{err}"
    );
}
