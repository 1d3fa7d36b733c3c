//! `[solver] device` through the CLI (issue 24): `--device gpu` bakes on the GPU solver (Mesa's
//! lavapipe on CI) what the CPU bakes, and says where it ran in the log and the report; a scene
//! the GPU solver does not run, or a machine without an adapter, is a clear error (exit 2) for
//! `gpu` and a note and the CPU for `auto`.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{assert_gltf_valid, workspace_root};
use std::path::Path;
use std::process::{Command, Output};

fn bake(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_springbake"));
    command.arg("bake").args(args).args(["--progress", "quiet"]);
    for (k, v) in env {
        command.env(k, v);
    }
    command.output().unwrap()
}

fn report(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn the_gpu_bakes_the_cube_drop_as_the_cpu_does_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let cube = workspace_root().join("examples/cube.obj");
    let mut reports = Vec::new();
    for device in ["gpu", "cpu"] {
        let glb = dir.path().join(format!("{device}.glb"));
        let json = dir.path().join(format!("{device}.json"));
        let out = bake(
            &[
                cube.to_str().unwrap(),
                "--cells",
                "6",
                "--frames",
                "24",
                "--device",
                device,
                "-o",
                glb.to_str().unwrap(),
                "--report",
                json.to_str().unwrap(),
            ],
            &[],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{device}: {err}");
        assert!(err.contains("solver on "), "{err}");
        assert_gltf_valid(&glb);
        reports.push(report(&json));
    }
    let (gpu, cpu) = (&reports[0], &reports[1]);
    assert_ne!(gpu["device"], "cpu", "{}", gpu["device"]);
    assert_eq!(cpu["device"], "cpu");
    let mass = gpu["bodies"][0]["mass_kg"].as_f64().unwrap();
    for (a, b) in gpu["frames"]
        .as_array()
        .unwrap()
        .iter()
        .zip(cpu["frames"].as_array().unwrap())
    {
        assert_eq!(a["inverted_cells"], 0);
        // Gravity energy m g h: the centres of mass within 0.1 mm.
        let (ga, gb) = (
            a["gravity_energy"].as_f64().unwrap(),
            b["gravity_energy"].as_f64().unwrap(),
        );
        assert!(
            (ga - gb).abs() <= mass * 9.81 * 1e-4,
            "frame {}: {ga} against {gb} J",
            a["frame"]
        );
        // The cells' elastic energy, the device's from its census: as the CPU reads it (the
        // elastic solve's, before the contacts; read after them, the cube resting on its
        // display-surface contact showed 3–4 times the CPU's).
        let (ea, eb) = (
            a["elastic_energy"].as_f64().unwrap(),
            b["elastic_energy"].as_f64().unwrap(),
        );
        assert!(
            (ea - eb).abs() <= 0.02 * eb.abs() + 1e-3,
            "frame {}: elastic {ea} against {eb} J",
            a["frame"]
        );
    }
}

#[test]
fn what_the_gpu_cannot_run_is_an_error_for_gpu_and_a_note_for_auto() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        workspace_root().join("examples/cube.obj"),
        dir.path().join("cube.obj"),
    )
    .unwrap();
    let scene = dir.path().join("held.toml");
    std::fs::write(
        &scene,
        "[output]\npath = \"held.glb\"\nframes = 2\n[world]\nfloor = 0.0\n\
         [[body]]\nsource = \"cube.obj\"\ncells = 4\npreserve_volume = true\n",
    )
    .unwrap();
    let glb = dir.path().join("hit.glb");
    let out = bake(
        &[
            scene.to_str().unwrap(),
            "--device",
            "gpu",
            "-o",
            glb.to_str().unwrap(),
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("device = \"gpu\"") && err.contains("volume preservation"),
        "{err}"
    );
    assert!(!glb.exists());

    // No adapter at all (wgpu told to look for Metal only, which Linux has not).
    let cube = workspace_root().join("examples/cube.obj");
    let args = |device: &'static str, cells: &'static str| {
        [
            cube.to_str().unwrap().to_string(),
            "--cells".into(),
            cells.into(),
            "--frames".into(),
            "2".into(),
            "--device".into(),
            device.into(),
            "-o".into(),
            glb.to_str().unwrap().to_string(),
        ]
    };
    let no_adapter = [("WGPU_BACKEND", "metal")];
    let a = args("gpu", "4");
    let out = bake(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &no_adapter,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no GPU adapter found") && err.contains("mesa-vulkan-drivers"),
        "{err}"
    );
    // `auto` on a lattice large enough for a GPU falls back to the CPU and says why.
    let a = args("auto", "32");
    let out = bake(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &no_adapter,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("solver on cpu: no GPU adapter found"), "{err}");
    assert!(glb.exists());
}

/// The viewer steps a scene through the same placement: with `[solver] device = "gpu"` its
/// screenshot of a scene comes from the GPU solver (the log says so), and shows the cube on
/// the floor as the CPU's does.
#[test]
fn the_viewer_steps_a_scene_on_the_gpu() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        workspace_root().join("examples/cube.obj"),
        dir.path().join("cube.obj"),
    )
    .unwrap();
    let mut pictures = Vec::new();
    for device in ["gpu", "cpu"] {
        let scene = dir.path().join(format!("{device}.toml"));
        std::fs::write(
            &scene,
            format!(
                "[output]\npath = \"out.glb\"\nframes = 24\n[world]\nfloor = 0.0\n\
                 [solver]\ndevice = \"{device}\"\n[[body]]\nsource = \"cube.obj\"\ncells = 6\n\
                 offset = [0.0, 0.3, 0.0]\n"
            ),
        )
        .unwrap();
        let png = dir.path().join(format!("{device}.png"));
        let out = Command::new(env!("CARGO_BIN_EXE_springbake"))
            .args(["view", scene.to_str().unwrap(), "--screenshot"])
            .arg(&png)
            .args(["--frame", "20", "--size", "160x120"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        // Any adapter will do for the GPU (lavapipe's on CI), never the CPU.
        let on_cpu = err.contains("solver on cpu");
        assert!(
            err.contains("solver on ") && on_cpu == (device == "cpu"),
            "{err}"
        );
        pictures.push(std::fs::read(&png).unwrap());
    }
    // The same picture: the cube at rest on the floor at frame 20, within a few pixels.
    let (gpu, cpu) = (
        support::decode_png(&pictures[0]),
        support::decode_png(&pictures[1]),
    );
    assert_eq!((gpu.0, gpu.1), (160, 120));
    let differing = gpu
        .2
        .chunks(4)
        .zip(cpu.2.chunks(4))
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 24))
        .count();
    assert!(differing <= 160 * 120 / 100, "{differing} pixels differ");
    // And the cube is in the picture (its orange against the grey floor).
    let orange = gpu
        .2
        .chunks(4)
        .filter(|p| p[0] as i32 > p[2] as i32 + 60)
        .count();
    assert!(orange > 160 * 120 / 50, "{orange} orange pixels");
}
