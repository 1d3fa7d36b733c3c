//! The `springbake` binary as a user runs it: exit codes, messages, the corpus, atomic output.
#![allow(clippy::unwrap_used)]

mod support;

use support::{corpus, decode_png, springbake, stderr};

#[test]
fn demo_bakes_a_valid_gltf_with_a_manipulator_hit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo.glb");
    let report = dir.path().join("report.json");
    let o = springbake(&[
        "demo",
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    springbake_testkit::assert_gltf_valid(&out);
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let frames = r["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 72);
    assert_eq!(frames[0]["frame"], 1);
    assert_eq!(frames[0]["time"], 0.0);
    assert!(frames.iter().all(|f| f["inverted_cells"] == 0));
    let max_reaction = frames
        .iter()
        .map(|f| {
            f["manipulator_reaction"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap().powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    assert!(
        max_reaction > 1.0,
        "the manipulator must hit the ball: max reaction {max_reaction} N"
    );
    assert!(r["bodies"][0]["nodes"].as_u64().unwrap() > 100);
    for key in ["import", "fit", "simulate", "export"] {
        assert!(r["seconds"][key].as_f64().is_some());
    }
}

#[test]
fn every_corpus_file_imports_or_fails_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    for e in springbake_testkit::corpus_entries(&["gltf", "glb", "obj", "usda", "usdc", "usdz"]) {
        let file = e.path.to_str().unwrap();
        let o = springbake(&["inspect", file]);
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{file}: {err}");
        if e.expect_ok {
            assert!(
                o.status.success(),
                "{file} ({}) should import: {err}",
                e.why
            );
        } else {
            assert_eq!(o.status.code(), Some(2), "{file} ({}): {err}", e.why);
            assert!(
                err.contains("error:") && err.len() > 20,
                "{file}: unclear message: {err}"
            );
            // The bake refuses it too and writes nothing.
            let out = dir.path().join("never.glb");
            let b = springbake(&["bake", file, "-o", out.to_str().unwrap(), "--frames", "2"]);
            assert_eq!(b.status.code(), Some(2), "{file}: {}", stderr(&b));
            assert!(!out.exists(), "{file}: output written for a rejected input");
        }
    }
}

#[test]
fn a_failed_bake_leaves_the_previous_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.glb");
    std::fs::write(&out, b"previous bake").unwrap();
    let o = springbake(&[
        "bake",
        corpus("bad/nan_position.gltf").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&out).unwrap(), b"previous bake");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 1, "no temporary files left behind");
}

#[test]
fn scene_errors_name_the_file_line_and_valid_keys() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, "[output]\nframes = 4\n[world]\nflor = 0.0\n").unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("scene.toml") && err.contains("line 4") && err.contains("floor"),
        "{err}"
    );

    std::fs::write(&scene, "[[body]]\nsource = \"missing.glb\"\n").unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains(&dir.path().join("missing.glb").display().to_string()),
        "names the path tried: {err}"
    );
}

#[test]
fn a_scene_file_bakes_to_point_caches() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    // Sources live in the scene's folder tree (issue 17): an absolute path inside it is fine.
    let src = dir.path().join("assets/two_objects.obj");
    std::fs::create_dir_all(src.parent().unwrap()).unwrap();
    std::fs::copy(corpus("blender/two_objects.obj"), &src).unwrap();
    std::fs::write(
        &scene,
        format!("[output]\npath = \"out.pc2\"\nframes = 6\n[world]\nfloor = -2.0\n[[body]]\nsource = {:?}\ncells = 6\nmaterial = \"jelly\"\n", src.display().to_string()),
    )
    .unwrap();
    let o = springbake(&["bake", scene.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["out_Body.pc2", "out_Head.pc2"] {
        let bytes = std::fs::read(dir.path().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(&bytes[..12], b"POINTCACHE2\0");
        let samples = i32::from_le_bytes(bytes[28..32].try_into().unwrap());
        assert_eq!(samples, 6);
    }
}

#[test]
fn plugins_lists_every_format() {
    let o = springbake(&["plugins"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    for ext in ["glb", "gltf", "obj", "usda", "usdc", "usdz", "pc2", "mdd"] {
        assert!(text.contains(ext), "{ext} missing from:\n{text}");
    }
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(springbake(&["bake"]).status.code(), Some(2));
    assert_eq!(
        springbake(&["bake", "/no/such/file.glb"]).status.code(),
        Some(2)
    );
    let o = springbake(&[
        "bake",
        corpus("blender/icosphere.glb").to_str().unwrap(),
        "-o",
        "/tmp/x.fbx",
        "--frames",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("glb"),
        "lists the formats it writes: {}",
        stderr(&o)
    );
}

/// A bake whose output will be large says so before it starts, with its size and what makes
/// it smaller (the memory limit then stops this one before any step, keeping the test fast).
#[test]
fn a_large_output_is_announced_with_its_size_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let n = 200;
    let mut obj = String::from("o grid\n");
    for j in 0..=n {
        for i in 0..=n {
            obj += &format!(
                "v {} {} {}\n",
                i as f64 / n as f64,
                0.5,
                j as f64 / n as f64
            );
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i + 1;
            obj += &format!("f {a} {} {} {}\n", a + 1, a + n + 2, a + n + 1);
        }
    }
    let grid = dir.path().join("grid.obj");
    std::fs::write(&grid, obj).unwrap();
    let out = dir.path().join("grid.glb");
    let (grid_arg, out_arg) = (grid.to_str().unwrap(), out.to_str().unwrap());
    let bake_grid = |frames: &str, extra: &[&str]| {
        let mut args = vec!["bake", grid_arg, "--frames", frames, "--cells", "4"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", out_arg]);
        springbake(&args)
    };
    let o = bake_grid("120", &["--max-memory", "50M"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    // 40 401 vertices × 120 frames of morph targets: 117.9 MB when baked.
    assert!(
        err.contains("the output will be about 123 MB (40401 vertices × 120 frames)")
            && err.contains("--cache pca"),
        "{err}"
    );
    // What the message offers works: the lattice as joints, a small file.
    let skin = bake_grid("120", &["--cache", "skin"]);
    assert!(skin.status.success(), "{}", stderr(&skin));
    let size = std::fs::metadata(&out).unwrap().len();
    assert!(size < 10_000_000, "{size} bytes");
    let bad = springbake(&["bake", grid_arg, "--cache", "bones"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        stderr(&bad).contains("morph, skin or pca"),
        "{}",
        stderr(&bad)
    );
    let small = bake_grid("2", &[]);
    assert!(small.status.success(), "{}", stderr(&small));
    assert!(
        !stderr(&small).contains("will be about"),
        "{}",
        stderr(&small)
    );
}

/// `demo` writes a flipbook beside its bake; `view` renders flipbooks and contact sheets of a
/// bake offscreen; a video needs ffmpeg and says so when it is missing.
#[test]
fn the_demo_and_view_write_flipbooks_and_sheets() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("demo.glb");
    let o = springbake(&["demo", "-o", glb.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let gif_path = dir.path().join("demo.gif");
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(&*gif_path.to_string_lossy()),
        "the demo says where its flipbook is"
    );
    let count_frames = |path: &std::path::Path| {
        let bytes = std::fs::read(path).unwrap();
        let mut decoder = gif::DecodeOptions::new().read_info(&bytes[..]).unwrap();
        let mut n = 0;
        while let Some(frame) = decoder.read_next_frame().unwrap() {
            assert_eq!((frame.width, frame.height), (480, 360));
            n += 1;
        }
        n
    };
    assert_eq!(count_frames(&gif_path), 72);

    let part = dir.path().join("part.gif");
    let sheet = dir.path().join("sheet.png");
    let o = springbake(&[
        "view",
        glb.to_str().unwrap(),
        "--flipbook",
        part.to_str().unwrap(),
        "--frames",
        "10..19",
        "--sheet",
        sheet.to_str().unwrap(),
        "--count",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(count_frames(&part), 10);
    let (w, h, _) = decode_png(&std::fs::read(&sheet).unwrap());
    assert_eq!((w, h), (4 * 320, 240 + 22));

    let o = springbake(&[
        "view",
        glb.to_str().unwrap(),
        "--flipbook",
        part.to_str().unwrap(),
        "--frames",
        "70..80",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the file has frames 1..72"),
        "{}",
        stderr(&o)
    );

    let mp4 = dir.path().join("demo.mp4");
    let o = springbake(&[
        "view",
        glb.to_str().unwrap(),
        "--flipbook",
        mp4.to_str().unwrap(),
    ]);
    let has_ffmpeg = std::process::Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok();
    if has_ffmpeg {
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(std::fs::metadata(&mp4).unwrap().len() > 1000);
    } else {
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("needs ffmpeg on PATH"),
            "{}",
            stderr(&o)
        );
        assert!(!mp4.exists());
    }
}

/// The demo at frame 30, as `springbake view --screenshot` draws it (issue 21's check): the
/// camera frames the ball at that frame, so it covers at least 5 % of the picture; the floor
/// grid and the capsule recorded in the glb are drawn. Compared with the stored reference
/// (`tests/reference/demo_frame30.png`): at most 2 % of the pixels may differ by more than 24
/// levels. `SPRINGBAKE_UPDATE_REFERENCE=1` rewrites the reference after a deliberate change.
#[test]
fn the_demo_screenshot_shows_the_ball_large_with_the_floor_and_the_capsule() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("demo.glb");
    assert!(springbake(&["demo", "-o", glb.to_str().unwrap()])
        .status
        .success());
    let png_path = dir.path().join("f30.png");
    let o = springbake(&[
        "view",
        glb.to_str().unwrap(),
        "--screenshot",
        png_path.to_str().unwrap(),
        "--frame",
        "30",
        "--size",
        "320x240",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let decode = |bytes: Vec<u8>| decode_png(&bytes);
    let shot = std::fs::read(&png_path).unwrap();
    let (w, h, rgba) = decode(shot.clone());
    assert_eq!((w, h), (320, 240));
    let pixels: Vec<[i32; 3]> = rgba
        .chunks(4)
        .map(|p| [p[0] as i32, p[1] as i32, p[2] as i32])
        .collect();
    let share = |f: &dyn Fn(&[i32; 3]) -> bool| {
        pixels.iter().filter(|p| f(p)).count() as f64 / pixels.len() as f64
    };
    let ball = share(&|p| p[0] > p[2] + 60);
    let capsule = share(&|p| p[2] > p[0] + 60);
    let grid = share(&|p| (p[0] - p[2]).abs() < 20 && p[0] > 60 && p[0] < 110);
    assert!(
        ball >= 0.05,
        "the ball covers {:.1} % of the picture",
        ball * 100.0
    );
    assert!(capsule > 0.002, "the capsule: {:.2} %", capsule * 100.0);
    assert!(grid > 0.002, "the floor grid: {:.2} %", grid * 100.0);

    // Another view with --camera: another picture; a bad angle is a usage error.
    let top = dir.path().join("top.png");
    let o = springbake(&[
        "view",
        glb.to_str().unwrap(),
        "--screenshot",
        top.to_str().unwrap(),
        "--frame",
        "30",
        "--size",
        "320x240",
        "--camera",
        "0,80",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(std::fs::read(&top).unwrap(), shot);
    let o = springbake(&[
        "view",
        glb.to_str().unwrap(),
        "--screenshot",
        top.to_str().unwrap(),
        "--camera",
        "up",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));

    let reference = springbake_testkit::workspace_root().join("tests/reference/demo_frame30.png");
    if std::env::var_os("SPRINGBAKE_UPDATE_REFERENCE").is_some() {
        std::fs::write(&reference, &shot).unwrap();
    }
    let want = std::fs::read(&reference).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (SPRINGBAKE_UPDATE_REFERENCE=1 writes it)",
            reference.display()
        )
    });
    let (rw, rh, ref_rgba) = decode(want);
    assert_eq!((rw, rh), (w, h));
    let differing = rgba
        .chunks(4)
        .zip(ref_rgba.chunks(4))
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 24))
        .count();
    assert!(
        differing as f64 <= 0.02 * (w * h) as f64,
        "{differing} of {} pixels differ from the reference",
        w * h
    );
}

/// `--report report.html`: one self-contained page (nothing fetched: the flipbook is a data
/// URI), four plots over time with the events marked, the bodies, and the warnings section.
#[test]
fn an_html_report_is_a_self_contained_page_with_the_flipbook_and_plots() {
    use base64::Engine;
    let dir = tempfile::tempdir().unwrap();
    let scene = springbake_testkit::workspace_root().join("examples/bowling/bowling.toml");
    let glb = dir.path().join("bowling.glb");
    let html = dir.path().join("report.html");
    let json = dir.path().join("report.json");
    for report in [&html, &json] {
        let o = springbake(&[
            "bake",
            scene.to_str().unwrap(),
            "-o",
            glb.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let page = std::fs::read_to_string(&html).unwrap();
    let facts: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert!(page.starts_with("<!DOCTYPE html>") && page.trim_end().ends_with("</html>"));
    assert_eq!(
        page.matches("<svg").count(),
        4,
        "energy, penetration, inverted, substeps"
    );
    assert_eq!(page.matches("</svg>").count(), 4);
    // Offline: no address to fetch, no script.
    for banned in ["http://", "https://", "<script", "<link"] {
        assert!(!page.contains(banned), "{banned}");
    }
    // The flipbook: every frame of the bake.
    let data = page
        .split("data:image/gif;base64,")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .expect("an embedded flipbook");
    let gif = base64::engine::general_purpose::STANDARD
        .decode(data)
        .unwrap();
    let mut decoder = gif::DecodeOptions::new().read_info(&gif[..]).unwrap();
    let mut frames = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        frames += 1;
    }
    assert_eq!(frames, facts["frames"].as_array().unwrap().len());
    // Each fired event is marked on each plot; every body is listed.
    let events = facts["events"].as_array().unwrap().len();
    assert!(events > 0);
    assert_eq!(page.matches("class=\"event\"").count(), 4 * events);
    for body in facts["bodies"].as_array().unwrap() {
        assert!(page.contains(&format!("<td>{}</td>", body["name"].as_str().unwrap())));
    }
    assert!(page.contains("<h2>Warnings</h2>"));
}

/// A baked glb records its static colliders; a screenshot of it draws them (a slab under a
/// cube, seen from close by: large triangles are drawn in pieces, not dropped).
#[test]
fn a_baked_glb_shows_its_collider() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        springbake_testkit::workspace_root().join("examples/cube.obj"),
        d.join("cube.obj"),
    )
    .unwrap();
    std::fs::write(
        d.join("slab.obj"),
        "v -3 -0.1 -3\nv 3 -0.1 -3\nv 3 -0.1 3\nv -3 -0.1 3\nv -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\n\
         f 5 8 7 6\nf 1 2 3 4\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1\n",
    )
    .unwrap();
    std::fs::write(
        d.join("scene.toml"),
        "[output]\npath = \"out.glb\"\nframes = 12\n[[body]]\nsource = \"cube.obj\"\ncells = 4\n\
         offset = [0.0, 0.4, 0.0]\n[[collider]]\nsource = \"slab.obj\"\n",
    )
    .unwrap();
    let o = springbake(&["bake", d.join("scene.toml").to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let share = grey_share(&d.join("out.glb"), &d.join("shot.png"), |p| {
        p[0] > 90
            && (p[0] as i32 - p[2] as i32).abs() < 30
            && (p[1] as i32 - p[2] as i32).abs() < 30
    });
    assert!(
        share > 0.1,
        "the collider covers {:.1} % of the picture",
        share * 100.0
    );
}

/// `[world.walls]` show as skirting boards around the room, in a simulated scene's screenshot
/// and in a baked glb's (the walls travel in `extras.springbake_stage`), and not without walls.
#[test]
fn the_rooms_walls_show_in_screenshots() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        springbake_testkit::corpus_dir().join("blender/icosphere.glb"),
        d.join("icosphere.glb"),
    )
    .unwrap();
    let scene = "[output]\npath = \"w.glb\"\nframes = 12\n[world]\nfloor = 0.0\n\
        WALLS[[body]]\nsource = \"icosphere.glb\"\ncells = 4\n";
    let walls = "[world.walls]\nmin = [-0.8, 0.0, -0.8]\nmax = [0.8, 3.0, 0.8]\n";
    let walls_share = |text: &str, view: &str| -> f64 {
        std::fs::write(d.join("w.toml"), scene.replace("WALLS", text)).unwrap();
        let o = springbake(&[
            "bake",
            d.join("w.toml").to_str().unwrap(),
            "--progress",
            "quiet",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        // the walls' lit grey (the HUD's text is brighter, the floor darker)
        grey_share(&d.join(view), &d.join("w.png"), |p| {
            (80..=150).contains(&p[0])
                && (p[0] as i32 - p[2] as i32).abs() < 25
                && (p[1] as i32 - p[2] as i32).abs() < 25
        })
    };
    for view in ["w.toml", "w.glb"] {
        let (with, without) = (walls_share(walls, view), walls_share("", view));
        assert!(
            with > 0.01 && without < 0.002,
            "{view}: walls {with}, none {without}"
        );
    }
}

/// The share of a 320×240 screenshot of `input` at frame 12 (written to `shot`) whose pixels
/// pass `keep`.
fn grey_share(
    input: &std::path::Path,
    shot: &std::path::Path,
    keep: impl Fn(&[u8]) -> bool,
) -> f64 {
    let args = [
        "view",
        input.to_str().unwrap(),
        "--screenshot",
        shot.to_str().unwrap(),
        "--frame",
        "12",
        "--size",
        "320x240",
    ];
    let o = springbake(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let (width, height, buf) = decode_png(&std::fs::read(shot).unwrap());
    buf.chunks(4).filter(|p| keep(p)).count() as f64 / (width * height) as f64
}

/// A mesh that starts half through the floor of a scene (a DCC's cube at the origin, the
/// floor at 0) is lifted onto it before frame 1 and named, with how far; then it rests. Pushed
/// out during the bake, a 30 cm rubber cube centred on the floor flew 7.5 m up. One that
/// rests on the floor, or above it, is not moved or named.
#[test]
fn a_body_that_starts_through_the_floor_is_lifted_onto_it() {
    let dir = tempfile::tempdir().unwrap();
    support::cube(dir.path(), "cube.obj");
    let scene = |offset: f64| {
        format!(
            "[output]\npath = \"out.glb\"\nframes = 24\n[world]\nfloor = 0.0\n\
             [[body]]\nsource = \"cube.obj\"\ncells = 4\noffset = [0.0, {offset}, 0.0]\n"
        )
    };
    let (err, report) = support::bake_scene_reporting(dir.path(), "half.toml", &scene(0.0));
    assert!(
        err.contains("body \"Cube\" started 0.250 m through the floor: lifted onto it"),
        "{err}"
    );
    let frames = report["frames"].as_array().unwrap();
    for f in frames {
        let speed = f["max_speed"].as_f64().unwrap();
        assert!(speed < 0.3, "frame {}: {speed} m/s", f["frame"]);
        assert_eq!(f["energy_gain"].as_f64().unwrap_or(0.0), 0.0, "{f}");
    }
    let err = support::bake_scene(dir.path(), "on.toml", &scene(0.25));
    assert!(!err.contains("through the floor"), "{err}");
    assert!(!err.contains("no floor"), "{err}");
}

/// A scene file that leaves out `floor` has none: its model falls out of the frame. The CLI
/// says so before the bake, with how far, and what to add.
#[test]
fn a_scene_without_a_floor_says_its_bodies_fall_freely() {
    let dir = tempfile::tempdir().unwrap();
    support::cube(dir.path(), "cube.obj");
    let scene = "[output]\npath = \"out.pc2\"\nframes = 24\n\
                 [[body]]\nsource = \"cube.obj\"\ncells = 2\n";
    let err = support::bake_scene(dir.path(), "fall.toml", scene);
    assert!(
        err.contains(
            "no floor, wall, collider or pin: under gravity the bodies fall freely, 4.5 m over \
             the bake's 1.0 s"
        ),
        "{err}"
    );
    let float = format!("{scene}[world]\ngravity = 0.0\n");
    let err = support::bake_scene(dir.path(), "float.toml", &float);
    assert!(!err.contains("no floor"), "{err}");
}

/// A bake that folds cells says so on stderr with the frames, and for the XPBD solver what to
/// set: a jelly cube thrown at the floor at 10 m/s with 4 substeps a frame folds; the
/// automatic substeps it is pointed to do not.
#[test]
fn folded_cells_are_warned_of_with_their_frames_and_the_substeps_to_try() {
    let dir = tempfile::tempdir().unwrap();
    support::cube(dir.path(), "cube.obj");
    let scene = |substeps: &str| {
        format!(
            "[output]\npath = \"out.pc2\"\nframes = 12\n[solver]\nsubsteps = {substeps}\n\
             [world]\nfloor = 0.0\n[[body]]\nsource = \"cube.obj\"\ncells = 4\n\
             material = \"jelly\"\noffset = [0.0, 0.5, 0.0]\nvelocity = [0.0, -10.0, 0.0]\n"
        )
    };
    let err = support::bake_scene(dir.path(), "few.toml", &scene("4"));
    assert!(
        err.contains("lattice cells inverted during the bake (frame 2, 3"),
        "{err}"
    );
    assert!(
        err.contains(
            "they took the 4 substeps the scene sets; try [solver] substeps = \"auto\" or 8"
        ),
        "{err}"
    );
    let err = support::bake_scene(dir.path(), "auto.toml", &scene("\"auto\""));
    assert!(!err.contains("inverted"), "{err}");
}

/// A frame that folds a cell is taken again at more substeps, and the CLI says which: the
/// corpus's 2 m jelly cylinder (Blender's export) collapses under its own weight and folded
/// two cells in frame 54 at its 13 automatic substeps, and the bake warned of them.
#[test]
fn a_frame_that_folds_a_cell_is_taken_again_at_more_substeps() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        corpus("blender/cylinder.obj"),
        dir.path().join("cylinder.obj"),
    )
    .unwrap();
    let scene = "[output]\npath = \"out.pc2\"\nframes = 72\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"cylinder.obj\"\nmaterial = \"jelly\"\n";
    let (err, report) = support::bake_scene_reporting(dir.path(), "jelly.toml", scene);
    assert!(!err.contains("inverted"), "{err}");
    let frames = report["frames"].as_array().unwrap();
    let redone: Vec<&serde_json::Value> = (frames.iter())
        .filter(|f| f["redone"].as_u64() > Some(0))
        .collect();
    assert!(!redone.is_empty(), "no frame was taken again: {err}");
    for f in &redone {
        let (frame, substeps) = (
            f["frame"].as_u64().unwrap(),
            f["substeps"].as_u64().unwrap(),
        );
        // Twice the frame's own choice at least, which may be below the frame before's: at
        // least twice the fewest a frame takes (10 at 24 fps).
        assert!(substeps >= 20, "frame {frame}: {substeps}");
        let note = format!(
            "frame {frame} folded a cell and was taken again from its start at {substeps} substeps"
        );
        assert!(redone.len() > 1 || err.contains(&note), "{err}");
    }
    assert!(frames.iter().all(|f| f["inverted_cells"] == 0), "{err}");
}

/// Two cubes of one OBJ sunk a quarter of a metre into each other are named before the bake
/// as glued (they would otherwise be thrown apart); two a centimetre apart are not.
#[test]
fn parts_that_interpenetrate_are_named_as_glued_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let two_cubes = |second_x: f64| {
        let mut obj = String::new();
        for (i, x0) in [0.0, second_x].into_iter().enumerate() {
            let (points, triangles) =
                springbake_core::shapes::box_mesh([x0, 0.3, 0.0], [x0 + 0.5, 0.8, 0.5]);
            obj += &format!("o part{i}\n");
            for p in &points {
                obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
            }
            for t in triangles {
                let [a, b, c] = t.map(|k| 8 * i + k as usize + 1);
                obj += &format!("f {a} {b} {c}\n");
            }
        }
        obj
    };
    for (second_x, glued) in [(0.25, true), (0.51, false)] {
        std::fs::write(dir.path().join("two.obj"), two_cubes(second_x)).unwrap();
        let args = [
            "bake", "two.obj", "--cells", "4", "--frames", "2", "-o", "two.pc2",
        ];
        let o = support::springbake_in(dir.path(), &args);
        let err = stderr(&o);
        assert!(o.status.success(), "{err}");
        let named = err.contains("bodies \"part0\" and \"part1\" interpenetrate at the start");
        assert_eq!(named, glued, "second cube at x = {second_x}: {err}");
    }
}

#[test]
fn a_body_that_starts_inside_a_collider_is_named_before_the_bake() {
    // A 0.5 m cube inside a closed 2 m box collider (the collider cannot hold it in), and
    // the same cube above the box (no note).
    let dir = tempfile::tempdir().unwrap();
    let obj = |name: &str, lo: [f64; 3], hi: [f64; 3]| {
        support::obj_text(name, springbake_core::shapes::box_mesh(lo, hi))
    };
    std::fs::write(
        dir.path().join("crate.obj"),
        obj("crate", [0.0; 3], [2.0; 3]),
    )
    .unwrap();
    std::fs::write(dir.path().join("cube.obj"), obj("cube", [0.0; 3], [0.5; 3])).unwrap();
    for (y, inside) in [(0.75, true), (2.5, false)] {
        let scene = format!(
            "[output]\npath = \"out.pc2\"\nframes = 2\n[world]\nfloor = -1.0\n\
             [[body]]\nsource = \"cube.obj\"\ncells = 4\noffset = [0.75, {y}, 0.75]\n\
             [[collider]]\nsource = \"crate.obj\"\n"
        );
        std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
        let o = support::springbake_in(dir.path(), &["bake", "scene.toml"]);
        let err = stderr(&o);
        assert!(o.status.success(), "{err}");
        let named = err.contains("body \"cube\" starts inside collider \"crate\"");
        assert_eq!(named, inside, "cube at y = {y}: {err}");
    }
}

/// A wooden plank pinned at one end is held rigid, and the CLI says so before the bake; with
/// `[solver] stiff_bodies = "elastic"` it is solved as cells (no note) and sags far more than
/// wood can; a value that is neither names the key (exit 2). A plank too stiff for the
/// substeps to resolve but not held is named with the substeps it asks for.
#[test]
fn a_pinned_wooden_plank_is_held_rigid_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let plank = springbake_core::shapes::box_mesh([0.0, 1.0, 0.0], [2.0, 1.05, 0.3]);
    std::fs::write(
        dir.path().join("plank.obj"),
        support::obj_text("plank", plank),
    )
    .unwrap();
    let scene = |solver: &str| {
        format!(
            "[output]\npath = \"out.pc2\"\nframes = 12\n{solver}\
             [[body]]\nsource = \"plank.obj\"\nname = \"plank\"\nmaterial = \"wood\"\ncells = 20\n\
             [[constraint]]\nbody = \"plank\"\nbox = {{ min = [-0.01, 0.9, -0.1], max = [0.05, 1.1, 0.4] }}\n"
        )
    };
    // The lowest point of the last frame, from the report-free PC2: y of every point.
    let lowest = |dir: &std::path::Path| {
        let bytes = std::fs::read(dir.join("out.pc2")).unwrap();
        let points = u32::from_le_bytes(bytes[16..20].try_into().unwrap()) as usize;
        let frame = &bytes[bytes.len() - points * 12..];
        (0..points)
            .map(|i| f32::from_le_bytes(frame[i * 12 + 4..i * 12 + 8].try_into().unwrap()))
            .fold(f32::INFINITY, f32::min)
    };
    let err = support::bake_scene(dir.path(), "held.toml", &scene(""));
    assert!(err.contains("body \"plank\" is held rigid"), "{err}");
    assert!(!err.contains("stiffer than the solver resolves"), "{err}");
    let held = lowest(dir.path());
    assert!(
        (held - 1.0).abs() < 1e-3,
        "held plank's lowest point {held} m"
    );
    let elastic = "[solver]\nstiff_bodies = \"elastic\"\n";
    let err = support::bake_scene(dir.path(), "elastic.toml", &scene(elastic));
    assert!(!err.contains("held rigid"), "{err}");
    let sagged = lowest(dir.path());
    assert!(sagged < 0.95, "elastic plank's lowest point {sagged} m");
    // A plank of a made-up E = 10 MPa (wave speed 100 m/s: not held) asks for more substeps
    // than the automatic count gives, and is named with what it would take.
    let plastic = scene("").replace(
        "material = \"wood\"",
        "material = { young = 1e7, density = 1000, poisson = 0.3, damping = 0.5 }",
    );
    let err = support::bake_scene(dir.path(), "plastic.toml", &plastic);
    assert!(!err.contains("held rigid"), "{err}");
    assert!(
        err.contains("body \"plank\" is stiffer than the solver resolves")
            && err.contains("`[solver] substeps = 126`"),
        "{err}"
    );
    // A hard plastic (E 1.5 GPa, 1100 kg/m³: 1170 m/s) is held too, though its 5 cm plank
    // fills half of each 10 cm cell (mass and stiffness both halved: the same wave speed).
    let hard = scene("").replace(
        "material = \"wood\"",
        "material = { young = 1.5e9, density = 1100, poisson = 0.35, damping = 0.1 }",
    );
    let err = support::bake_scene(dir.path(), "hard.toml", &hard);
    assert!(err.contains("body \"plank\" is held rigid"), "{err}");
    let bogus = "[solver]\nstiff_bodies = \"stiff\"\n";
    std::fs::write(dir.path().join("bogus.toml"), scene(bogus)).unwrap();
    let o = support::springbake_in(dir.path(), &["bake", "bogus.toml"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("stiff_bodies") || err.contains("rigid"),
        "{err}"
    );
}

/// A light ball dropped onto a soft block dents it and settles without gaining energy:
/// a body–body contact that overlaps at a substep's start (found a substep late, or pressed
/// back in by the floor under the squeezed jelly) opens slowly instead of at `depth / Δt`.
/// Before, a foam ball on a jelly block gained energy from its first touch, folded cells
/// from frame 12 and ended at thousands of joules.
#[test]
fn a_ball_dropped_on_a_jelly_block_settles_without_gaining_energy() {
    let dir = tempfile::tempdir().unwrap();
    let obj = |name: &str, mesh| {
        std::fs::write(
            dir.path().join(format!("{name}.obj")),
            support::obj_text(name, mesh),
        )
        .unwrap();
    };
    obj(
        "block",
        springbake_core::shapes::box_mesh([-0.15, 0.0, -0.15], [0.15, 0.3, 0.15]),
    );
    // A UV sphere of r 0.1 m as a quad mesh whose rings meet at the poles in degenerate quads
    // (as the bake that first showed this was given).
    let (rings, segments) = (16, 32);
    let mut points = Vec::new();
    for i in 0..=rings {
        let theta = std::f64::consts::PI * f64::from(i) / f64::from(rings);
        for j in 0..segments {
            let phi = 2.0 * std::f64::consts::PI * f64::from(j) / f64::from(segments);
            points.push(springbake_core::nalgebra::Point3::new(
                0.1 * theta.sin() * phi.cos(),
                1.0 + 0.1 * theta.cos(),
                0.1 * theta.sin() * phi.sin(),
            ));
        }
    }
    let mut triangles = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let at = |i: u32, j: u32| i * segments + j % segments;
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    obj("ball", (points, triangles));
    let scene = "[output]\npath = \"out.pc2\"\nframes = 24\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"block.obj\"\nname = \"block\"\nmaterial = \"jelly\"\ncells = 8\n\
                 [[body]]\nsource = \"ball.obj\"\nname = \"ball\"\nmaterial = \"foam\"\ncells = 6\n";
    let err = support::bake_scene(dir.path(), "ball_on_jelly.toml", scene);
    assert!(!err.contains("energy rose"), "{err}");
    assert!(!err.contains("inverted"), "{err}");
}

/// A rubber cube dropped tilted lands on an edge and tumbles: no flight after a bounce may
/// carry more energy than the one before. A frame whose contact crushes a corner cell stores
/// energy the motion did not give it (the contact lifts the cell's light corner node into it
/// every substep, the collapse barrier pushes it back); the next frame, doubled by the
/// crowding rule, resolved the cells better and gave it back as motion. Before such a frame
/// was taken again at twice its substeps, this 10 cm cube left its fourth bounce with 40 %
/// more energy than its third (a visible hop).
#[test]
fn a_tumbling_rubber_cube_never_leaves_a_bounce_with_more_energy() {
    use springbake_core::nalgebra::{Rotation3, Vector3};
    let dir = tempfile::tempdir().unwrap();
    let (points, triangles) = springbake_core::shapes::box_mesh([-0.05; 3], [0.05; 3]);
    let turn = Rotation3::from_euler_angles(0.6, 0.0, 0.1);
    let points = points
        .into_iter()
        .map(|p| turn * p + Vector3::new(0.0, 1.1, 0.0))
        .collect();
    std::fs::write(
        dir.path().join("cube.obj"),
        support::obj_text("cube", (points, triangles)),
    )
    .unwrap();
    let scene = "[output]\npath = \"out.pc2\"\nframes = 96\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"cube.obj\"\nmaterial = \"rubber\"\ncells = 10\n";
    let (_, report) = support::bake_scene_reporting(dir.path(), "tumble.toml", scene);
    // The cube's lowest corner per frame, from the point cache.
    let pc2 = std::fs::read(dir.path().join("out.pc2")).unwrap();
    let lowest: Vec<f32> = support::pc2_frames(&pc2)
        .iter()
        .map(|corners| corners.iter().map(|p| p[1]).fold(f32::MAX, f32::min))
        .collect();
    let frames = report["frames"].as_array().unwrap();
    let at = |f: &serde_json::Value, key: &str| f[key].as_f64().unwrap();
    let floor = frames
        .iter()
        .map(|f| at(f, "gravity_energy"))
        .fold(f64::MAX, f64::min);
    // Kinetic and gravity energy (above the lowest the body got) as each flight starts.
    let (mut flights, mut flying) = (Vec::new(), false);
    for (f, low) in frames.iter().zip(&lowest) {
        let airborne = *low > 0.005;
        if airborne && !flying {
            flights.push(at(f, "kinetic_energy") + at(f, "gravity_energy") - floor);
        }
        flying = airborne;
    }
    assert!(flights.len() >= 3, "{flights:?}");
    for pair in flights.windows(2) {
        assert!(
            pair[1] <= 1.1 * pair[0],
            "a flight gained energy: {flights:?}"
        );
    }
}

/// A display mesh much coarser than its lattice cannot show what the lattice does: an
/// 8-vertex box's faces stay flat whatever its cells do. The CLI says so before the bake and
/// how to fix it; a mesh as fine as its cells (Blender's icosphere) gets no such note.
#[test]
fn a_mesh_coarser_than_its_lattice_is_named_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("box.obj"),
        support::obj_text(
            "box",
            springbake_core::shapes::box_mesh([0.0, 0.5, 0.0], [0.3, 0.8, 0.3]),
        ),
    )
    .unwrap();
    let err = support::bake_file(dir.path(), "box.obj", "box.pc2", "2");
    assert!(
        err.contains("body \"box\" has a coarse mesh for its lattice: 100 % of its surface"),
        "{err}"
    );
    assert!(err.contains("Subdivision Surface"), "{err}");
    let ball = corpus("blender/icosphere.glb");
    std::fs::copy(&ball, dir.path().join("ball.glb")).unwrap();
    let err = support::bake_file(dir.path(), "ball.glb", "ball.pc2", "2");
    assert!(!err.contains("coarse mesh"), "{err}");
}

/// A kit of many coarse parts gets one note naming a few and counting the rest, not one per
/// part, and the bake's line names its first and last point caches and how many there are.
#[test]
fn many_coarse_parts_share_one_note_and_one_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("kit.obj"),
        support::row_of_boxes(0.5, 0.5, 0.3),
    )
    .unwrap();
    let o = support::springbake_in(
        dir.path(),
        &[
            "bake",
            "kit.obj",
            "-o",
            "kit.pc2",
            "--frames",
            "2",
            "--progress",
            "quiet",
        ],
    );
    let said = support::succeeded(&o);
    let err = stderr(&o);
    assert_eq!(err.matches("coarse mesh").count(), 1, "{err}");
    assert!(
        err.contains("5 bodies have a coarse mesh for their lattice (\"Part0\", \"Part1\", \"Part2\" and 2 more)"),
        "{err}"
    );
    assert!(!err.contains("interpenetrate"), "{err}");
    assert_eq!(said.lines().count(), 1, "{said}");
    assert!(
        said.contains("kit_Part0.pc2, kit_Part1.pc2, …, kit_Part4.pc2 (5 files)"),
        "{said}"
    );
}

/// Many pairs of parts modelled inside each other get one note, as many coarse parts do.
#[test]
fn many_interpenetrating_pairs_share_one_note() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("kit.obj"),
        support::row_of_boxes(0.2, 0.5, 0.3),
    )
    .unwrap();
    let err = support::bake_file(dir.path(), "kit.obj", "kit.pc2", "2");
    assert_eq!(err.matches("interpenetrate").count(), 1, "{err}");
    assert!(
        err.contains("4 pairs of bodies interpenetrate at the start (\"Part0\" and \"Part1\", \"Part1\" and \"Part2\", \"Part2\" and \"Part3\" and 1 more): they are glued"),
        "{err}"
    );
}

/// The annotated example (README, docs/scene.md) bakes without a warning or a note that its
/// mesh is too coarse, and shows what it is for: the capsule's dent in the face it hits,
/// which bows by centimetres (an 8-vertex cube's face would stay flat).
#[test]
fn the_annotated_example_bakes_and_shows_the_capsules_dent() {
    use springbake_core::nalgebra::{Matrix3, Vector3};
    let dir = tempfile::tempdir().unwrap();
    let examples = springbake_testkit::workspace_root().join("examples");
    for file in ["drop_and_hit.toml", "soft_cube.obj"] {
        std::fs::copy(examples.join(file), dir.path().join(file)).unwrap();
    }
    let o = support::springbake_in(
        dir.path(),
        &[
            "bake",
            "drop_and_hit.toml",
            "-o",
            "out.pc2",
            "--no-plugins",
            "--progress",
            "quiet",
        ],
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        !err.contains("warning") && !err.contains("coarse mesh"),
        "{err}"
    );
    let frames = support::pc2_frames(&std::fs::read(dir.path().join("out.pc2")).unwrap());
    assert_eq!(frames.len(), 72);
    // The face the capsule hits (−x at rest): how far its points get from their best plane.
    let face: Vec<usize> = (0..frames[0].len())
        .filter(|&v| (frames[0][v][0] + 0.25).abs() < 1e-5)
        .collect();
    assert_eq!(face.len(), 81);
    let bow = |points: &[[f32; 3]]| {
        let p: Vec<Vector3<f64>> = face
            .iter()
            .map(|&v| Vector3::from(points[v].map(f64::from)))
            .collect();
        let c = p.iter().sum::<Vector3<f64>>() / p.len() as f64;
        let spread: Matrix3<f64> = p.iter().map(|q| (q - c) * (q - c).transpose()).sum();
        let eigen = spread.symmetric_eigen();
        let n = eigen
            .eigenvectors
            .column(eigen.eigenvalues.imin())
            .into_owned();
        p.iter().map(|q| (q - c).dot(&n).abs()).fold(0.0, f64::max)
    };
    let most = frames.iter().map(|f| bow(f)).fold(0.0, f64::max);
    assert!(most > 0.01, "the hit face bows {most} m at most");
}

/// A body's `offset` is motion the baked frames carry, whether the scene's bodies come from
/// one file or several: a point cache laid on the artist's object puts it where it was
/// simulated. Bodies from two files used to be written without their offsets (a ball set
/// 45 cm down onto a block played back 45 cm above it in Blender).
#[test]
fn point_caches_of_bodies_from_several_files_carry_their_offsets() {
    let dir = tempfile::tempdir().unwrap();
    let (block, ball) = (
        springbake_core::shapes::box_mesh([-0.25, -0.25, -0.25], [0.25, 0.25, 0.25]),
        springbake_core::shapes::box_mesh([-0.1, 1.0, -0.1], [0.1, 1.2, 0.1]),
    );
    for (name, mesh) in [("block", &block), ("ball", &ball)] {
        std::fs::write(
            dir.path().join(format!("{name}.obj")),
            support::obj_text(name, mesh.clone()),
        )
        .unwrap();
    }
    let scene = "[output]\npath = \"out.pc2\"\nframes = 2\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"block.obj\"\ncells = 4\noffset = [0.0, 0.25, 0.0]\n\
                 [[body]]\nsource = \"ball.obj\"\ncells = 4\noffset = [0.3, -0.45, 0.0]\n";
    support::bake_scene(dir.path(), "stack.toml", scene);
    for (name, (points, _), offset) in [
        ("block", &block, [0.0, 0.25, 0.0]),
        ("ball", &ball, [0.3, -0.45, 0.0]),
    ] {
        let pc2 = std::fs::read(dir.path().join(format!("out_{name}.pc2"))).unwrap();
        let first = &support::pc2_frames(&pc2)[0];
        assert_eq!(first.len(), points.len(), "{name}");
        for (p, q) in points.iter().zip(first) {
            for k in 0..3 {
                let want = p[k] + offset[k];
                assert!(
                    (f64::from(q[k]) - want).abs() < 1e-5,
                    "{name}: {q:?} for {p} + {offset:?}"
                );
            }
        }
    }
}

/// A body's point cache does not depend on what else is in the scene: Blender's icosphere
/// (glTF) alone and beside a body from another file starts from the same points, its offset
/// carried and its axes turned Z-up for Blender's import of the glTF. Beside another file it
/// used to be written in the file's Y-up axes and without its offset.
#[test]
fn a_gltf_bodys_point_cache_is_the_same_beside_a_body_from_another_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(corpus("blender/icosphere.glb"), dir.path().join("ball.glb")).unwrap();
    std::fs::write(
        dir.path().join("box.obj"),
        support::obj_text(
            "box",
            springbake_core::shapes::box_mesh([3.0, 0.0, 0.0], [3.2, 0.2, 0.2]),
        ),
    )
    .unwrap();
    let ball = "[[body]]\nsource = \"ball.glb\"\ncells = 4\noffset = [0.5, 1.0, 0.2]\n";
    let alone = format!("[output]\npath = \"alone.pc2\"\nframes = 2\n{ball}");
    let beside = format!(
        "[output]\npath = \"beside.pc2\"\nframes = 2\n{ball}\
         [[body]]\nsource = \"box.obj\"\ncells = 2\n"
    );
    support::bake_scene(dir.path(), "alone.toml", &alone);
    support::bake_scene(dir.path(), "beside.toml", &beside);
    let first =
        |file: &str| support::pc2_frames(&std::fs::read(dir.path().join(file)).unwrap())[0].clone();
    let (alone, beside) = (first("alone.pc2"), first("beside_Icosphere.pc2"));
    assert_eq!(alone.len(), beside.len());
    for (a, b) in alone.iter().zip(&beside) {
        assert!(
            (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6),
            "{a:?} alone, {b:?} beside"
        );
    }
}

/// A wooden crate (an 8-vertex OBJ box) slid at 2 m/s over a wooden table top (another box,
/// one quad a side) stops in Coulomb's distance, v²/(2μg) = 0.51 m, flat on the table. Both
/// are held rigid: the crate, set 1 mm above the table, was thrown 19 cm up at the first
/// substep; the table's samples ahead of the crate's front edge stopped it like a wall, and
/// where it crossed the diagonal of the table's quad it reared up and turned (0.2 m).
#[test]
fn a_wooden_crate_slides_over_a_wooden_table_by_coulombs_law() {
    let dir = tempfile::tempdir().unwrap();
    let crate_obj = support::box_obj("Crate", [-0.15, 0.101, -0.15], [0.15, 0.401, 0.15]);
    std::fs::write(dir.path().join("crate.obj"), crate_obj).unwrap();
    let table_obj = support::box_obj("Table", [-1.5, 0.0, -0.5], [1.5, 0.1, 0.5]);
    std::fs::write(dir.path().join("table.obj"), table_obj).unwrap();
    let scene = "[output]\npath = \"out.pc2\"\nframes = 24\n\
                 [world]\nfloor = 0.0\nfriction = 0.4\n\
                 [[body]]\nsource = \"crate.obj\"\nmaterial = \"wood\"\ncells = 10\n\
                 velocity = [2.0, 0.0, 0.0]\n\
                 [[body]]\nsource = \"table.obj\"\nmaterial = \"wood\"\ncells = 30\n";
    support::bake_scene(dir.path(), "slide.toml", scene);
    let frames = support::pc2_frames(&std::fs::read(dir.path().join("out_Crate.pc2")).unwrap());
    let centre = |f: &Vec<[f32; 3]>| {
        let n = f.len() as f64;
        [0, 1, 2].map(|k| f.iter().map(|p| f64::from(p[k])).sum::<f64>() / n)
    };
    let (start, end) = (centre(&frames[0]), centre(&frames[frames.len() - 1]));
    let rose = frames
        .iter()
        .map(|f| centre(f)[1] - start[1])
        .fold(0.0, f64::max);
    let coulomb = 2.0f64.powi(2) / (2.0 * 0.4 * 9.81);
    assert!(
        (end[0] - start[0] - coulomb).abs() < 0.03 && (end[2] - start[2]).abs() < 0.01,
        "slid from {start:?} to {end:?}, Coulomb {coulomb} m"
    );
    assert!(rose < 0.005, "rose {rose} m");
}
