//! `springbake wedge` through the CLI: the product of the variations, one folder per
//! variant, the index, the contact sheet, skipping unchanged variants, `--only` and
//! `--emit-jobs` giving the same bytes, clear errors for bad `--vary` expressions, and a local
//! Ray cluster (head and two workers, started and stopped here) baking the same bytes as a
//! local run even when a worker is killed mid-run.
#![allow(clippy::unwrap_used)]

use serde_json::Value;
use springbake_testkit::{venv_python, workspace_root};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn springbake(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_springbake"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A scene folder: the example cube, dropped, with a `[wedge]` table varying the material.
fn scene_folder(cells: u32, frames: u32) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        workspace_root().join("examples/cube.obj"),
        dir.path().join("cube.obj"),
    )
    .unwrap();
    let scene = format!(
        "[output]\npath = \"baked.glb\"\nframes = {frames}\n\n[world]\nfloor = 0.0\n\n\
         [[body]]\nsource = \"cube.obj\"\ncells = {cells}\noffset = [0.0, 0.5, 0.0]\n\n\
         [wedge]\nvary = [{{ path = \"body[0].material\", values = [\"jelly\", \"rubber\"] }}]\n"
    );
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    dir
}

const VELOCITIES: &str = "body[0].velocity=[0,-2,0],[0,-6,0]";

fn bytes(p: PathBuf) -> Vec<u8> {
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn a_wedge_bakes_every_variant_with_an_index_and_a_contact_sheet() {
    let dir = scene_folder(4, 24);
    let d = dir.path();
    let run = springbake(
        d,
        &["wedge", "scene.toml", "--vary", VELOCITIES, "--jobs", "2"],
    );
    assert!(run.status.success(), "{}", text(&run));
    let index: Value = serde_json::from_slice(&bytes(d.join("wedges/index.json"))).unwrap();
    let variants = index["variants"].as_array().unwrap();
    assert_eq!(variants.len(), 4);
    // The first variation varies slowest.
    let values: Vec<(String, String)> = variants
        .iter()
        .map(|v| {
            (
                v["values"]["body[0].material"].as_str().unwrap().to_owned(),
                v["values"]["body[0].velocity"].to_string(),
            )
        })
        .collect();
    assert_eq!(values[0], ("jelly".into(), "[0,-2,0]".into()));
    assert_eq!(values[1], ("jelly".into(), "[0,-6,0]".into()));
    assert_eq!(values[3], ("rubber".into(), "[0,-6,0]".into()));
    for v in variants {
        let folder = d.join("wedges").join(v["folder"].as_str().unwrap());
        assert_eq!(v["baked"], true, "{v}");
        for file in ["scene.toml", "baked.glb", "report.json", "wedge.json"] {
            assert!(folder.join(file).is_file(), "{} {file}", folder.display());
        }
    }
    // Different settings, different motion.
    let glbs: Vec<Vec<u8>> = (0..4)
        .map(|i| bytes(d.join(format!("wedges/{i:04}/baked.glb"))))
        .collect();
    assert!(glbs.windows(2).all(|w| w[0] != w[1]));
    springbake_testkit::assert_gltf_valid(&d.join("wedges/0003/baked.glb"));

    // The contact sheet: a row of 3 frames per variant, every cell drawn.
    let sheet = bytes(d.join("wedges/contact_sheet.png"));
    let decoder = png::Decoder::new(std::io::Cursor::new(sheet));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (3 * 240, 4 * (180 + 22)));
    let background = [24u8, 26, 30];
    for row in 0..4u32 {
        for col in 0..3u32 {
            let (x0, y0) = (col * 240, row * 202 + 22 + 30);
            let drawn = (y0..y0 + 140)
                .flat_map(|y| (x0..x0 + 240).map(move |x| (x, y)))
                .filter(|&(x, y)| {
                    let i = ((y * info.width + x) * 4) as usize;
                    buf[i..i + 3] != background
                })
                .count();
            assert!(drawn > 500, "cell ({row}, {col}) is blank: {drawn} pixels");
        }
    }

    // A rerun skips every variant; a changed source re-bakes them all.
    let again = springbake(d, &["wedge", "scene.toml", "--vary", VELOCITIES]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(text(&again).contains("(0 to bake)"), "{}", text(&again));
    let cube = std::fs::read_to_string(d.join("cube.obj")).unwrap();
    std::fs::write(d.join("cube.obj"), cube.replace("v ", "v  ")).unwrap();
    let changed = springbake(d, &["wedge", "scene.toml", "--vary", VELOCITIES]);
    assert!(text(&changed).contains("(4 to bake)"), "{}", text(&changed));
    // Only the whitespace changed: the same motion.
    assert_eq!(bytes(d.join("wedges/0003/baked.glb")), glbs[3]);

    // `--only` bakes one variant anywhere, to the same bytes.
    let only = springbake(
        d,
        &[
            "wedge",
            "scene.toml",
            "--vary",
            VELOCITIES,
            "--only",
            "2",
            "-o",
            "single",
        ],
    );
    assert!(only.status.success(), "{}", text(&only));
    assert_eq!(bytes(d.join("single/0002/baked.glb")), glbs[2]);
    assert!(!d.join("single/0001").exists());
}

#[test]
fn emitted_jobs_are_command_lines_that_bake_the_same_bytes() {
    let dir = scene_folder(4, 12);
    let d = dir.path();
    let emit = springbake(
        d,
        &[
            "wedge",
            "scene.toml",
            "--vary",
            VELOCITIES,
            "--emit-jobs",
            "jobs.json",
        ],
    );
    assert!(emit.status.success(), "{}", text(&emit));
    assert!(!d.join("wedges").exists(), "--emit-jobs bakes nothing");
    let jobs: Value = serde_json::from_slice(&bytes(d.join("jobs.json"))).unwrap();
    let jobs = jobs["jobs"].as_array().unwrap();
    assert_eq!(jobs.len(), 4);
    let command: Vec<String> = jobs[1]["command"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap().to_owned())
        .collect();
    // A farm runs it from anywhere: the paths are absolute.
    let run = Command::new(&command[0])
        .args(&command[1..])
        .current_dir(std::env::temp_dir())
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", text(&run));
    let local = springbake(
        d,
        &["wedge", "scene.toml", "--vary", VELOCITIES, "-o", "local"],
    );
    assert!(local.status.success(), "{}", text(&local));
    assert_eq!(
        bytes(d.join("wedges/0001/baked.glb")),
        bytes(d.join("local/0001/baked.glb"))
    );
}

#[test]
fn bad_variations_are_refused_naming_the_expression() {
    let dir = scene_folder(4, 12);
    let d = dir.path();
    for (vary, expected) in [
        ("body[0].material", "expected PATH=VALUE1,VALUE2"),
        ("body[0.material=jelly", "an index is written [0]"),
        ("body..material=jelly", "is not a setting path"),
        ("body[0].velocity=[0,-2,0", "unclosed bracket"),
        ("body[0].material=jelly,,rubber", "an empty value"),
        (
            "body[3].material=jelly",
            "index 3 does not exist (there are 1)",
        ),
        ("body[0].material=unobtainium", "variant 0"),
        ("world.gravity=-5", "gravity"),
    ] {
        let run = springbake(d, &["wedge", "scene.toml", "--vary", vary, "--no-sheet"]);
        let out = text(&run);
        assert_eq!(run.status.code(), Some(2), "{vary}: {out}");
        assert!(out.contains(expected), "{vary}: {out}");
        assert!(!out.contains("panicked"), "{out}");
    }
    let no_such = springbake(
        d,
        &["wedge", "scene.toml", "--vary", VELOCITIES, "--only", "9"],
    );
    assert_eq!(no_such.status.code(), Some(2));
    assert!(text(&no_such).contains("the wedge has 4 variants"));
}

/// A Ray cluster on 127.0.0.1 for one test: stopped (with every Ray process on the machine
/// started under its temp folder) when dropped.
struct RayCluster {
    ray: PathBuf,
    address: String,
}

impl RayCluster {
    fn start(port: u16) -> RayCluster {
        let ray = venv_python().parent().unwrap().join("ray");
        let address = format!("127.0.0.1:{port}");
        let start = |args: &[&str]| {
            let o = Command::new(&ray)
                .args(args)
                .env("RAY_USAGE_STATS_ENABLED", "0")
                .output()
                .unwrap();
            assert!(o.status.success(), "ray {args:?}: {}", text(&o));
        };
        let port = port.to_string();
        let cluster = RayCluster {
            ray: ray.clone(),
            address: address.clone(),
        };
        start(&[
            "start",
            "--head",
            "--port",
            &port,
            "--node-ip-address",
            "127.0.0.1",
            "--num-cpus",
            "1",
            "--include-dashboard",
            "false",
            "--disable-usage-stats",
        ]);
        for _ in 0..2 {
            start(&[
                "start",
                "--address",
                &address,
                "--node-ip-address",
                "127.0.0.1",
                "--num-cpus",
                "1",
            ]);
        }
        cluster
    }
}

impl Drop for RayCluster {
    fn drop(&mut self) {
        let _ = Command::new(&self.ray).args(["stop", "--force"]).output();
    }
}

/// A variant bake a Ray worker runs (`springbake wedge … --only`): its pid, its worker's,
/// and the worker's temporary folder it writes into (`src/wedge_ray.py`).
struct RunningBake {
    pid: u32,
    worker: u32,
    folder: Option<PathBuf>,
}

/// The variant bakes Ray workers are running now.
fn running_bakes() -> Vec<RunningBake> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
        let args: Vec<&[u8]> = cmdline.split(|&b| b == 0).collect();
        let in_wedge_folder = |a: &&&[u8]| a.windows(16).any(|w| w == b"springbake-wedge");
        let Some(arg) = args.iter().find(in_wedge_folder) else {
            continue;
        };
        if !args.iter().any(|a| *a == b"--only") {
            continue;
        }
        // The argument is a path inside the worker's `springbake-wedge-…` folder.
        let arg = PathBuf::from(String::from_utf8_lossy(arg).into_owned());
        let folder = arg.ancestors().find(|p| {
            let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
            name.is_some_and(|n| n.starts_with("springbake-wedge-"))
        });
        let stat = std::fs::read_to_string(entry.path().join("stat")).unwrap_or_default();
        let parent = stat
            .rsplit(')')
            .next()
            .and_then(|rest| rest.split_whitespace().nth(1))
            .and_then(|p| p.parse().ok())
            .unwrap_or(0);
        out.push(RunningBake {
            pid,
            worker: parent,
            folder: folder.map(Path::to_path_buf),
        });
    }
    out
}

#[test]
fn a_ray_cluster_bakes_the_same_bytes_and_retries_a_killed_worker() {
    let dir = scene_folder(10, 48);
    let d = dir.path();
    let cluster = RayCluster::start(26_000 + (std::process::id() % 2000) as u16);
    let started = Instant::now();
    let wedge = Command::new(env!("CARGO_BIN_EXE_springbake"))
        .current_dir(d)
        .args([
            "wedge",
            "scene.toml",
            "--vary",
            VELOCITIES,
            "--ray",
            &cluster.address,
            "-o",
            "ray",
            "--no-sheet",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Kill the Ray worker running the first variant bake that shows up.
    let mut killed = None;
    while killed.is_none() && started.elapsed() < Duration::from_secs(60) {
        if let Some(bake) = running_bakes().into_iter().next() {
            Command::new("kill")
                .args(["-9", &bake.worker.to_string()])
                .status()
                .unwrap();
            killed = Some(bake);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = wedge.wait_with_output().unwrap();
    let ray_seconds = started.elapsed().as_secs_f64();
    assert!(out.status.success(), "{}", text(&out));
    let killed = killed.unwrap_or_else(|| panic!("no variant bake seen running: {}", text(&out)));
    // The killed worker never removed its temporary folder: remove it here.
    if let Some(folder) = &killed.folder {
        let _ = std::fs::remove_dir_all(folder);
    }
    let bake = killed.pid;
    // The killed worker's bake died with it, so its variant's files below come from Ray's
    // retry on another worker.
    assert!(
        !Path::new(&format!("/proc/{bake}")).exists(),
        "bake {bake} outlived its worker"
    );
    let local = springbake(
        d,
        &[
            "wedge",
            "scene.toml",
            "--vary",
            VELOCITIES,
            "-o",
            "local",
            "--no-sheet",
        ],
    );
    assert!(local.status.success(), "{}", text(&local));
    for i in 0..4 {
        assert_eq!(
            bytes(d.join(format!("ray/{i:04}/baked.glb"))),
            bytes(d.join(format!("local/{i:04}/baked.glb"))),
            "variant {i}"
        );
    }
    eprintln!(
        "ray wedge of 4 variants with a killed worker: {ray_seconds:.1} s; killed bake {bake} \
         of worker {}",
        killed.worker
    );
}
