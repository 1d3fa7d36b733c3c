//! Helpers shared by the CLI's integration tests: run the binary, read its stderr, find the
//! shared corpus, copy the example cube.
#![allow(dead_code)] // each test file uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `springbake` with `args` and waits for it.
pub fn springbake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_springbake"))
        .args(args)
        .output()
        .expect("run springbake")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A file of `../shared/corpus`.
pub fn corpus(rel: &str) -> PathBuf {
    springbake_testkit::corpus_dir().join(rel)
}

/// Copies `examples/cube.obj` to `dir/name`.
pub fn cube(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/cube.obj"),
        &path,
    )
    .expect("copy the example cube");
    path
}

/// A PNG's width, height and RGBA bytes.
#[allow(dead_code)]
pub fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes.to_vec()))
        .read_info()
        .expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("a sized PNG")];
    let info = reader.next_frame(&mut buf).expect("a PNG frame");
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// Runs `springbake` with `args` in `dir` (no plug-ins from the user's config folder or
/// `$SPRINGBAKE_PLUGIN_PATH`) and waits for it.
pub fn springbake_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_springbake"))
        .args(args)
        .current_dir(dir)
        .env_remove("SPRINGBAKE_PLUGIN_PATH")
        .env("XDG_CONFIG_HOME", dir.join("no-config"))
        .output()
        .expect("run springbake")
}

/// Its stdout, after asserting it succeeded (its stderr in the failure).
pub fn succeeded(out: &Output) -> String {
    assert!(out.status.success(), "{}", stderr(out));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Writes `scene` to `dir/file` and bakes it quietly; panics with the CLI's stderr if it
/// fails, else returns that stderr (its notes and warnings).
pub fn bake_scene(dir: &Path, file: &str, scene: &str) -> String {
    std::fs::write(dir.join(file), scene).expect("write the scene");
    let out = springbake_in(dir, &["bake", file, "--progress", "quiet"]);
    succeeded(&out);
    stderr(&out)
}

/// Writes `scene` to `dir/file`, bakes it quietly with a JSON report; panics with the CLI's
/// stderr if it fails, else returns that stderr and the report.
pub fn bake_scene_reporting(dir: &Path, file: &str, scene: &str) -> (String, serde_json::Value) {
    std::fs::write(dir.join(file), scene).expect("write the scene");
    let report = "report.json";
    let out = springbake_in(
        dir,
        &["bake", file, "--progress", "quiet", "--report", report],
    );
    succeeded(&out);
    let bytes = std::fs::read(dir.join(report)).expect("the report");
    let report = serde_json::from_slice(&bytes).expect("the report is JSON");
    (stderr(&out), report)
}

/// Bakes `input` in `dir` to `output` for `frames` frames, quietly; panics with the CLI's
/// stderr if it fails, else returns that stderr (its notes).
pub fn bake_file(dir: &Path, input: &str, output: &str, frames: &str) -> String {
    let args = [
        "bake",
        input,
        "-o",
        output,
        "--frames",
        frames,
        "--progress",
        "quiet",
    ];
    let out = springbake_in(dir, &args);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    err
}

/// An OBJ file's text holding one object `name` of `triangles` over `points`.
#[allow(dead_code)] // not every test file writes meshes
pub fn obj_text(
    name: &str,
    (points, triangles): (Vec<springbake_core::nalgebra::Point3<f64>>, Vec<[u32; 3]>),
) -> String {
    let mut text = format!("o {name}\n");
    for p in &points {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in triangles {
        let [a, b, c] = t.map(|k| k + 1);
        text += &format!("f {a} {b} {c}\n");
    }
    text
}

/// The frames of a PC2 point cache: a 32-byte header (signature, version, point count, start
/// frame, sample rate, sample count), then each sample's points as three little-endian f32.
#[allow(dead_code)]
pub fn pc2_frames(bytes: &[u8]) -> Vec<Vec<[f32; 3]>> {
    let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let float = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let (points, samples) = (int(16), int(28));
    (0..samples)
        .map(|s| {
            (0..points)
                .map(|p| {
                    let at = 32 + 12 * (s * points + p);
                    [float(at), float(at + 4), float(at + 8)]
                })
                .collect()
        })
        .collect()
}

/// A box from `lo` to `hi` as an OBJ object `name` (12 triangles).
pub fn box_obj(name: &str, lo: [f64; 3], hi: [f64; 3]) -> String {
    let (points, triangles) = springbake_core::shapes::box_mesh(lo, hi);
    let mut obj = format!("o {name}\n");
    for p in &points {
        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for [a, b, c] in triangles {
        obj += &format!("f {} {} {}\n", a + 1, b + 1, c + 1);
    }
    obj
}

/// Five boxes side by side as one OBJ (objects `Part0`…`Part4`), each `step` from the last
/// along x, `side` wide, their bottoms at `bottom`, in the file's units.
pub fn row_of_boxes(step: f64, bottom: f64, side: f64) -> String {
    let mut obj = String::new();
    for part in 0..5u32 {
        let x = step * f64::from(part);
        let (points, triangles) =
            springbake_core::shapes::box_mesh([x, bottom, 0.0], [x + side, bottom + side, side]);
        obj += &format!("o Part{part}\n");
        for p in &points {
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        let first = 1 + 8 * part;
        for [a, b, c] in triangles {
            obj += &format!("f {} {} {}\n", a + first, b + first, c + first);
        }
    }
    obj
}
