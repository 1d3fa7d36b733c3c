//! Issue 17 through the CLI: nothing a bake reads or writes can destroy the user's files or
//! reach outside the scene's folder, and every such refusal is exit code 2, made before the
//! simulation, with the paths in the message.
#![allow(clippy::unwrap_used)]

mod support;

use std::process::Output;
use support::{cube, springbake, stderr};

fn refused(o: &Output, needle: &str) {
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    assert!(stderr(o).contains(needle), "{}", stderr(o));
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let obj = cube(dir.path(), "cube.obj");
    let src = dir.path().join("m.glb");
    let o = springbake(&[
        "bake",
        obj.to_str().unwrap(),
        "-o",
        src.to_str().unwrap(),
        "--frames",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let before = std::fs::read(&src).unwrap();
    let src_s = src.to_str().unwrap();
    // The same file, spelled three ways.
    let dotted = dir.path().join("sub/../m.glb");
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    for out in [src_s, dotted.to_str().unwrap()] {
        let o = springbake(&["bake", src_s, "-o", out, "--frames", "3"]);
        refused(&o, "would overwrite the input");
    }
    #[cfg(unix)]
    {
        let link = dir.path().join("link.glb");
        std::os::unix::fs::symlink(&src, &link).unwrap();
        let o = springbake(&["bake", src_s, "-o", link.to_str().unwrap(), "--frames", "3"]);
        refused(&o, "would overwrite the input");
    }
    assert_eq!(std::fs::read(&src).unwrap(), before);
    // A scene's output may not be the scene file itself either.
    let scene = dir.path().join("scene.toml");
    let text = "[output]\npath = \"scene.toml\"\nframes = 3\n[[body]]\nsource = \"cube.obj\"\n";
    std::fs::write(&scene, text).unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), text);
}

#[test]
fn a_report_that_is_the_output_an_input_or_a_folder_is_refused_before_baking() {
    let dir = tempfile::tempdir().unwrap();
    let src = cube(dir.path(), "cube.obj");
    let out = dir.path().join("out.glb");
    let (src_s, out_s) = (src.to_str().unwrap(), out.to_str().unwrap());
    let bake = |report: &str| {
        springbake(&[
            "bake", src_s, "-o", out_s, "--frames", "3", "--report", report,
        ])
    };
    refused(&bake(out_s), "would replace the bake's output");
    refused(&bake(src_s), "would overwrite the input");
    refused(&bake(dir.path().to_str().unwrap()), "it is a folder");
    assert!(!out.exists(), "nothing baked before the refusal");
}

#[test]
fn an_output_folder_that_cannot_exist_is_found_before_the_simulation() {
    let dir = tempfile::tempdir().unwrap();
    let src = cube(dir.path(), "cube.obj");
    std::fs::write(dir.path().join("a-file"), "x").unwrap();
    let out = dir.path().join("a-file/out.glb");
    // 10 000 frames would take minutes: the refusal must come first.
    let started = std::time::Instant::now();
    let o = springbake(&[
        "bake",
        src.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--frames",
        "10000",
    ]);
    refused(&o, "is not a folder");
    assert!(started.elapsed().as_secs() < 60);
}

#[test]
fn scene_sources_outside_the_scene_folder_are_refused() {
    let outer = tempfile::tempdir().unwrap();
    let folder = outer.path().join("scene");
    std::fs::create_dir(&folder).unwrap();
    let outside = cube(outer.path(), "outside.obj");
    let scene = folder.join("scene.toml");
    let mut sources = vec!["../outside.obj".to_owned(), outside.display().to_string()];
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&outside, folder.join("link.obj")).unwrap();
        sources.push("link.obj".into());
    }
    for source in sources {
        std::fs::write(
            &scene,
            format!("[output]\npath = \"out.glb\"\nframes = 3\n[[body]]\nsource = {source:?}\n"),
        )
        .unwrap();
        let o = springbake(&["bake", scene.to_str().unwrap()]);
        refused(&o, "outside the folder");
        assert!(!folder.join("out.glb").exists());
    }
    // Inside the folder tree (here through a subfolder) bakes.
    std::fs::create_dir(folder.join("assets")).unwrap();
    cube(&folder.join("assets"), "cube.obj");
    std::fs::write(
        &scene,
        "[output]\npath = \"out.glb\"\nframes = 3\n[[body]]\nsource = \"assets/cube.obj\"\n",
    )
    .unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_gltf_and_its_bin_are_replaced_together() {
    let dir = tempfile::tempdir().unwrap();
    let src = cube(dir.path(), "cube.obj");
    let out = dir.path().join("out.gltf");
    let bake = |frames: &str| {
        springbake(&[
            "bake",
            src.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--frames",
            frames,
        ])
    };
    assert!(bake("3").status.success());
    let bin = dir.path().join("out.bin");
    let (json1, bin1) = (std::fs::read(&out).unwrap(), std::fs::read(&bin).unwrap());
    // The .bin cannot be replaced (a folder is in its way): the old pair stays whole.
    std::fs::remove_file(&bin).unwrap();
    std::fs::create_dir(&bin).unwrap();
    std::fs::write(bin.join("keep"), "x").unwrap();
    let o = bake("4");
    assert_ne!(o.status.code(), Some(0));
    assert_eq!(
        std::fs::read(&out).unwrap(),
        json1,
        "the .gltf is renamed last"
    );
    std::fs::remove_dir_all(&bin).unwrap();
    std::fs::write(&bin, &bin1).unwrap();
    assert!(bake("4").status.success());
    springbake_testkit::assert_gltf_valid(&out);
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(names.is_empty(), "temporary files left: {names:?}");
}

/// Item 2: memory and substeps are budgeted before the first step, with what drives them.
#[test]
fn bakes_over_budget_are_refused_before_the_simulation_with_the_cause() {
    let dir = tempfile::tempdir().unwrap();
    let src = cube(dir.path(), "cube.obj");
    let src_s = src.to_str().unwrap();
    let out = dir.path().join("out.glb");
    let o = springbake(&[
        "bake",
        src_s,
        "--cells",
        "40",
        "--max-memory",
        "50M",
        "-o",
        out.to_str().unwrap(),
    ]);
    refused(&o, "over the limit of 50 MiB");
    assert!(stderr(&o).contains("68921 nodes"), "{}", stderr(&o));
    let o = springbake(&["bake", src_s, "--max-memory", "lots"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // A 2 cm steel cone under the papers' explicit integrator needs ~10⁶ substeps a frame.
    std::fs::copy(
        springbake_testkit::corpus_dir().join("blender/cone_2cm.glb"),
        dir.path().join("cone.glb"),
    )
    .unwrap();
    let scene = dir.path().join("steel.toml");
    std::fs::write(
        &scene,
        "[output]\npath = \"o.glb\"\nframes = 2\n[solver]\nintegrator = \"symplectic_euler\"\n[[body]]\nsource = \"cone.glb\"\nmaterial = \"steel\"\n",
    )
    .unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    refused(&o, "substeps per frame, over the cap");
    assert!(
        stderr(&o).contains("stiff material or small cells"),
        "{}",
        stderr(&o)
    );
    // The default solver bakes the same cone.
    std::fs::write(
        &scene,
        "[output]\npath = \"o.glb\"\nframes = 2\n[[body]]\nsource = \"cone.glb\"\nmaterial = \"steel\"\n",
    )
    .unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // ... and says it is small before it starts (a unit slip shows before the bake).
    assert!(
        stderr(&o).contains("\"Cone\" is 2.0 cm across (the source's unit is 1 m)"),
        "{}",
        stderr(&o)
    );
    // A plane cage with absurd cells is refused before it is built.
    std::fs::write(
        &scene,
        "[output]\npath = \"o.glb\"\nframes = 2\n[[body]]\nsource = \"cube.obj\"\nmodel = \"plane\"\ncells = 4000000\n",
    )
    .unwrap();
    refused(
        &springbake(&["bake", scene.to_str().unwrap()]),
        "use fewer cells",
    );
}
