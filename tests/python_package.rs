//! springbake as a Python package (issue 22 item 5): the package built from this checkout
//! with maturin into `.venv` (scripts/build-python-package.sh, run first: incremental), used
//! by a user's script (tests/clients/python_package.py) — the same bytes as the CLI from a
//! scene file and from a dict, the frames as numpy arrays, progress, a callback stopping the
//! bake with nothing written, a `BakeError` naming the field, and `inspect`.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

mod support;

use std::process::Command;
use support::{corpus, springbake_in, succeeded};

#[test]
fn the_python_package_bakes_what_the_cli_bakes() {
    let root = springbake_testkit::workspace_root();
    let build = Command::new(root.join("scripts/build-python-package.sh"))
        .output()
        .unwrap();
    assert!(
        build.status.success(),
        "build-python-package.sh:\n{}{}",
        String::from_utf8_lossy(&build.stdout),
        String::from_utf8_lossy(&build.stderr)
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        corpus("blender/icosphere.glb"),
        dir.path().join("icosphere.glb"),
    )
    .unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        "[output]\npath = \"cli.glb\"\nframes = 30\n[world]\nfloor = 0.0\n\
         [[body]]\nsource = \"icosphere.glb\"\nmaterial = \"rubber\"\n",
    )
    .unwrap();
    succeeded(&springbake_in(
        dir.path(),
        &["bake", "scene.toml", "--progress", "quiet"],
    ));
    // A scene with a plug-in's force field called every substep (from the solver's worker
    // threads, which take the interpreter's lock: a bake that held it hung for ever).
    let field = dir.path().join("field");
    std::fs::create_dir_all(field.join("plugins")).unwrap();
    std::fs::copy(
        root.join("examples/plugins/vortex_field.py"),
        field.join("plugins/vortex_field.py"),
    )
    .unwrap();
    std::fs::copy(corpus("blender/icosphere.glb"), field.join("icosphere.glb")).unwrap();
    std::fs::write(
        field.join("scene.toml"),
        "[output]\npath = \"cli.glb\"\nframes = 12\n[world]\nfloor = 0.0\n\
         [[body]]\nsource = \"icosphere.glb\"\nmaterial = \"rubber\"\n\
         [[force_field]]\nfield = \"vortex\"\n",
    )
    .unwrap();
    succeeded(&springbake_in(
        &field,
        &["bake", "scene.toml", "--progress", "quiet"],
    ));
    let out =
        springbake_testkit::run_python_client("python_package.py", &[dir.path().to_str().unwrap()]);
    let r = springbake_testkit::last_json_line(&out);
    eprintln!("REPORT {r}");
    assert!(
        r["module"].as_str().unwrap().contains(".venv"),
        "the package imported is not the one in .venv: {r}"
    );
    let cli = std::fs::read(dir.path().join("cli.glb")).unwrap();
    for name in ["from_file.glb", "from_dict.glb"] {
        let bytes = std::fs::read(dir.path().join(name)).unwrap();
        assert!(bytes == cli, "{name} differs from the CLI's bake");
    }
    let f = &r["file"];
    assert_eq!(f["outputs"][0], "from_file.glb");
    assert_eq!(f["frame_count"], 30);
    assert_eq!(f["shape"], serde_json::json!([30, 960, 3]));
    assert_eq!(f["dtype"], "float32");
    assert_eq!(f["name"], "Icosphere");
    assert_eq!(f["progress_calls"], 30);
    assert_eq!(f["last_progress"], serde_json::json!([30, 30]));
    assert_eq!(f["report_frames"], 30);
    assert_eq!(r["dict_outputs"][0], "from_dict.glb");
    assert_eq!(r["dict_positions_equal"], true);
    // The icosphere (centre 1 m up, radius 0.5 m) falls and lands on the floor.
    assert!(
        (r["lowest_first"].as_f64().unwrap() - 0.5).abs() < 1e-3,
        "{r}"
    );
    assert!(r["lowest_ever"].as_f64().unwrap().abs() < 0.01, "{r}");
    assert!(
        r["stopped"].as_str().unwrap().contains("stop at three"),
        "{r}"
    );
    assert_eq!(r["stopped_written"], false);
    let e = r["bake_error"].as_str().unwrap();
    assert!(e.contains("pth") && e.contains("path"), "{e}");
    assert_eq!(r["inspect"]["format"], "gltf");
    assert_eq!(r["inspect"]["vertices"], 960);
    assert_eq!(r["field_frames"], 12);
    let (cli, python) = (field.join("cli.glb"), field.join("python.glb"));
    assert!(
        std::fs::read(cli).unwrap() == std::fs::read(python).unwrap(),
        "the force-field scene baked from Python differs from the CLI's bake"
    );
}
