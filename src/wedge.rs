//! `springbake wedge`: bakes every variant of a scene (see `springbake_pipeline::wedge`) into
//! `OUT/<index>/` (the variant's `scene.toml`, its outputs, `report.json`, `wedge.json` with
//! the hashes), then `OUT/index.json` and a contact sheet. Variants run as child processes of
//! this program (`--jobs N` at a time), or as Ray tasks on a cluster (`--ray ADDRESS`, driven
//! by the embedded `wedge_ray.py`), or are written out as one command line each for a farm
//! manager (`--emit-jobs`). Each of those runs `springbake wedge … --only I`, which bakes one
//! variant in this process: the same code and the same bytes wherever it runs.

use crate::{usage, Failure};
use serde_json::{json, Value};
use springbake_core::plugin::OutputFile;
use springbake_pipeline::wedge::{self, sha256_hex, WedgePlan};
use springbake_pipeline::{bake, registry_with_plugins, write_outputs, BakeHooks};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The Ray driver, written to a temporary file and run with the project's Python.
const RAY_DRIVER: &str = include_str!("wedge_ray.py");
/// Each variant's record of what it was baked from and what it wrote.
const RECORD: &str = "wedge.json";

/// `springbake wedge`'s arguments.
#[derive(clap::Args)]
pub struct WedgeArgs {
    /// The scene file (.toml) to vary.
    pub scene: PathBuf,
    /// PATH=V1,V2,…: a setting path (body[0].material, world.gravity, solver.substeps)
    /// and its values (TOML, or bare words as strings); repeat for more settings.
    #[arg(long, value_name = "PATH=V1,V2")]
    pub vary: Vec<String>,
    /// Output folder (default: `wedges/` beside the scene).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Variants baked at once on this machine (each gets its share of the cores).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub jobs: u32,
    /// Bake only this variant (0-based), here: what each job runs.
    #[arg(long, value_name = "INDEX")]
    pub only: Option<usize>,
    /// Contact sheet PNG (default OUT/contact_sheet.png).
    #[arg(long, value_name = "FILE.png")]
    pub sheet: Option<PathBuf>,
    /// Do not render a contact sheet.
    #[arg(long)]
    pub no_sheet: bool,
    /// Run the variants as tasks on this Ray cluster (e.g. 127.0.0.1:6379); needs Python
    /// with `ray`, and the scene at the same path on every worker.
    #[arg(long, value_name = "ADDRESS")]
    pub ray: Option<String>,
    /// The springbake program on the Ray workers (default: this program's path).
    #[arg(long, value_name = "PATH")]
    pub ray_binary: Option<String>,
    /// Write one command line per variant to this JSON file for a farm manager, and stop.
    #[arg(long, value_name = "FILE.json")]
    pub emit_jobs: Option<PathBuf>,
    /// Bake every variant, even those unchanged since the last run.
    #[arg(long)]
    pub force: bool,
}

fn io_failure(path: &Path, e: impl std::fmt::Display) -> Failure {
    Failure {
        code: 2,
        message: format!("{}: {e}", path.display()),
    }
}

pub fn run(args: WedgeArgs) -> Result<(), Failure> {
    let variations = args
        .vary
        .iter()
        .map(|e| wedge::parse_vary(e).map_err(usage))
        .collect::<Result<Vec<_>, _>>()?;
    let plan = wedge::plan(&args.scene, &variations)?;
    let out = args
        .output
        .clone()
        .unwrap_or_else(|| args.scene.parent().unwrap_or(Path::new("")).join("wedges"));
    if let Some(index) = args.only {
        if index >= plan.variants.len() {
            return Err(usage(format!(
                "--only {index}: the wedge has {} variants (0 to {})",
                plan.variants.len(),
                plan.variants.len() - 1
            )));
        }
        return bake_variant(&plan, index, &out);
    }
    if let Some(jobs_file) = &args.emit_jobs {
        return emit_jobs(&plan, &args, &out, jobs_file);
    }
    std::fs::create_dir_all(&out).map_err(|e| io_failure(&out, e))?;
    let mut pending = Vec::new();
    for v in &plan.variants {
        if !args.force && unchanged(&plan, v.index, &out)? {
            eprintln!(
                "springbake: variant {} unchanged, skipped: {}",
                v.folder(),
                v.label()
            );
        } else {
            pending.push(v.index);
        }
    }
    eprintln!(
        "springbake: wedge of {} variants ({} to bake) into {}",
        plan.variants.len(),
        pending.len(),
        out.display()
    );
    let started = Instant::now();
    let failures = match &args.ray {
        Some(address) => run_on_ray(&plan, &args, &out, &pending, address)?,
        None => run_locally(&args, &out, &pending, args.jobs.max(1) as usize)?,
    };
    let index = write_index(&plan, &out, started.elapsed().as_secs_f64())?;
    if !args.no_sheet {
        let sheet = args
            .sheet
            .clone()
            .unwrap_or_else(|| out.join("contact_sheet.png"));
        write_sheet(&plan, &out, &sheet)?;
    }
    println!(
        "wedge: {} variants, {} baked, {} failed in {:.1} s: {}",
        plan.variants.len(),
        pending.len() - failures.len(),
        failures.len(),
        started.elapsed().as_secs_f64(),
        index.display()
    );
    match failures.first() {
        Some((index, code, message)) => Err(Failure {
            code: *code,
            message: format!("variant {index:04} failed: {message}"),
        }),
        None => Ok(()),
    }
}

/// Bakes variant `index` here, into `out/<index>/`.
fn bake_variant(plan: &WedgePlan, index: usize, out: &Path) -> Result<(), Failure> {
    let variant = &plan.variants[index];
    let loaded = plan.loaded(index, out);
    let folder = out.join(variant.folder());
    std::fs::create_dir_all(&folder).map_err(|e| io_failure(&folder, e))?;
    let hash = plan.input_hash(index)?;
    let started = Instant::now();
    let (registry, _) = registry_with_plugins(Some(&loaded.read_root()), true);
    let outcome = bake(&registry, &loaded, &mut BakeHooks::default())?;
    let seconds = started.elapsed().as_secs_f64();
    let mut outputs = Vec::new();
    for file in &outcome.outputs {
        let bytes = std::fs::read(file).map_err(|e| io_failure(file, e))?;
        outputs.push(json!({
            "file": file.file_name().map(|n| n.to_string_lossy().into_owned()),
            "sha256": sha256_hex(&bytes),
        }));
    }
    let scene_text = format!(
        "# Variant {} of {} ({}), written by `springbake wedge`.\n\
         # Sources are relative to that scene's folder; re-bake this variant with\n\
         # `springbake wedge {} --only {} …` and the same variations.\n{}",
        variant.folder(),
        plan.scene_path.display(),
        variant.label(),
        plan.scene_path.display(),
        index,
        variant.scene_text
    );
    let values: serde_json::Map<String, Value> = variant
        .values
        .iter()
        .map(|(p, v)| (p.clone(), toml_to_json(v)))
        .collect();
    let record = json!({
        "index": index,
        "values": values,
        "input_sha256": hash,
        "outputs": outputs,
        "bake_seconds": seconds,
    });
    let report = serde_json::to_vec_pretty(&outcome.report).map_err(|e| io_failure(out, e))?;
    let pretty = |v: &Value| serde_json::to_vec_pretty(v).unwrap_or_default();
    let files = [
        ("scene.toml", scene_text.into_bytes()),
        ("report.json", report),
        (RECORD, pretty(&record)),
    ]
    .map(|(name, bytes)| OutputFile {
        path: folder.join(name),
        bytes,
    });
    write_outputs(&files, &loaded.inputs())?;
    println!(
        "variant {} baked in {seconds:.2} s: {}",
        variant.folder(),
        variant.label()
    );
    Ok(())
}

fn toml_to_json(v: &toml::Value) -> Value {
    serde_json::to_value(v).unwrap_or(Value::Null)
}

/// Whether variant `index` in `out` was baked from the same inputs and its outputs are as
/// it wrote them.
fn unchanged(plan: &WedgePlan, index: usize, out: &Path) -> Result<bool, Failure> {
    let folder = out.join(plan.variants[index].folder());
    let Ok(text) = std::fs::read(folder.join(RECORD)) else {
        return Ok(false);
    };
    let Ok(record) = serde_json::from_slice::<Value>(&text) else {
        return Ok(false);
    };
    if record["input_sha256"].as_str() != Some(plan.input_hash(index)?.as_str()) {
        return Ok(false);
    }
    let Some(outputs) = record["outputs"].as_array() else {
        return Ok(false);
    };
    Ok(!outputs.is_empty()
        && outputs.iter().all(|o| {
            let file = folder.join(o["file"].as_str().unwrap_or(""));
            std::fs::read(file).is_ok_and(|b| Some(sha256_hex(&b).as_str()) == o["sha256"].as_str())
        }))
}

/// The command line that bakes variant `index` (what a child process, a Ray task or a farm
/// job runs).
fn variant_command(program: &str, args: &WedgeArgs, out: &Path, index: usize) -> Vec<String> {
    let mut cmd = vec![
        program.to_owned(),
        "wedge".to_owned(),
        args.scene.to_string_lossy().into_owned(),
    ];
    for v in &args.vary {
        cmd.push("--vary".into());
        cmd.push(v.clone());
    }
    cmd.extend([
        "--only".into(),
        index.to_string(),
        "-o".into(),
        out.to_string_lossy().into_owned(),
    ]);
    cmd
}

fn current_program() -> Result<String, Failure> {
    std::env::current_exe()
        .map(|p| p.to_string_lossy().into_owned())
        .map_err(|e| Failure {
            code: 1,
            message: format!("cannot find this program's path: {e}"),
        })
}

fn emit_jobs(plan: &WedgePlan, args: &WedgeArgs, out: &Path, file: &Path) -> Result<(), Failure> {
    let program = current_program()?;
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let absolute = WedgeArgs {
        scene: abs(&args.scene),
        vary: args.vary.clone(),
        ..WedgeArgs::only_paths()
    };
    let jobs: Vec<Value> = plan
        .variants
        .iter()
        .map(|v| {
            json!({
                "index": v.index,
                "label": v.label(),
                "command": variant_command(&program, &absolute, &abs(out), v.index),
            })
        })
        .collect();
    let bytes =
        serde_json::to_vec_pretty(&json!({ "jobs": jobs })).map_err(|e| io_failure(file, e))?;
    springbake_watcher::write_atomically(file, &bytes).map_err(|e| io_failure(file, e))?;
    println!("wedge: {} jobs written to {}", jobs.len(), file.display());
    Ok(())
}

impl WedgeArgs {
    fn only_paths() -> WedgeArgs {
        WedgeArgs {
            scene: PathBuf::new(),
            vary: Vec::new(),
            output: None,
            jobs: 1,
            only: None,
            sheet: None,
            no_sheet: true,
            ray: None,
            ray_binary: None,
            emit_jobs: None,
            force: false,
        }
    }
}

/// (variant, exit code, message) of each variant that failed.
type Failures = Vec<(usize, u8, String)>;

/// Runs `pending` as child processes, `jobs` at a time, each with its share of the cores.
fn run_locally(
    args: &WedgeArgs,
    out: &Path,
    pending: &[usize],
    jobs: usize,
) -> Result<Failures, Failure> {
    let program = current_program()?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = (cores / jobs).max(1).to_string();
    let mut queue = pending.iter().copied();
    let mut running: Vec<(usize, Child, Instant)> = Vec::new();
    let mut failures = Vec::new();
    loop {
        while running.len() < jobs {
            let Some(index) = queue.next() else { break };
            let cmd = variant_command(&program, args, out, index);
            let child = Command::new(&cmd[0])
                .args(&cmd[1..])
                .env("RAYON_NUM_THREADS", &threads)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .map_err(|e| Failure {
                    code: 1,
                    message: format!("cannot start a variant's bake: {e}"),
                })?;
            running.push((index, child, Instant::now()));
        }
        if running.is_empty() {
            return Ok(failures);
        }
        std::thread::sleep(Duration::from_millis(20));
        let mut k = 0;
        while k < running.len() {
            let Ok(Some(status)) = running[k].1.try_wait() else {
                k += 1;
                continue;
            };
            let (index, child, started) = running.swap_remove(k);
            let stderr = child
                .wait_with_output()
                .map(|o| String::from_utf8_lossy(&o.stderr).into_owned())
                .unwrap_or_default();
            report_done(
                index,
                status.success(),
                started.elapsed(),
                &stderr,
                &mut failures,
                status.code(),
            );
        }
    }
}

fn report_done(
    index: usize,
    ok: bool,
    took: Duration,
    stderr: &str,
    failures: &mut Failures,
    code: Option<i32>,
) {
    if ok {
        eprintln!(
            "springbake: variant {index:04} done in {:.1} s",
            took.as_secs_f64()
        );
        return;
    }
    let message = stderr
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("no message")
        .trim_start_matches("springbake: error: ")
        .to_owned();
    eprintln!("springbake: variant {index:04} failed: {message}");
    let code = match code {
        Some(2) => 2,
        _ => 1,
    };
    failures.push((index, code, message));
}

/// Runs `pending` as Ray tasks through the embedded driver; writes each returned variant
/// folder into `out`.
fn run_on_ray(
    plan: &WedgePlan,
    args: &WedgeArgs,
    out: &Path,
    pending: &[usize],
    address: &str,
) -> Result<Failures, Failure> {
    let python = python_for_ray();
    let dir = tempfile::tempdir().map_err(|e| io_failure(Path::new("temporary folder"), e))?;
    let driver = dir.path().join("springbake_ray_driver.py");
    std::fs::write(&driver, RAY_DRIVER).map_err(|e| io_failure(&driver, e))?;
    let program = match &args.ray_binary {
        Some(b) => b.clone(),
        None => current_program()?,
    };
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let absolute = WedgeArgs {
        scene: abs(&args.scene),
        vary: args.vary.clone(),
        ..WedgeArgs::only_paths()
    };
    let tasks: Vec<Value> = pending
        .iter()
        .map(|&i| {
            json!({
                "index": i,
                "folder": plan.variants[i].folder(),
                // The worker bakes into a folder of its own; OUT is replaced there.
                "command": variant_command(&program, &absolute, Path::new("{OUT}"), i),
            })
        })
        .collect();
    let request = json!({ "address": address, "tasks": tasks, "retries": 3 });
    let request_file = dir.path().join("request.json");
    std::fs::write(&request_file, request.to_string()).map_err(|e| io_failure(&request_file, e))?;
    let output = Command::new(&python)
        .arg(&driver)
        .arg(&request_file)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| Failure {
            code: 2,
            message: format!(
                "--ray needs Python with the `ray` package ({}): {e}",
                python.display()
            ),
        })?;
    if !output.status.success() {
        return Err(Failure {
            code: 2,
            message: format!(
                "the Ray driver failed (address {address}); is a cluster running there and \
                 `ray` installed for {}?",
                python.display()
            ),
        });
    }
    let mut failures = Vec::new();
    for line in String::from_utf8_lossy(&output.stdout).lines() {
        let Ok(result) = serde_json::from_str::<Value>(line) else {
            continue;
        };
        let index = result["index"].as_u64().unwrap_or(0) as usize;
        let took = Duration::from_secs_f64(result["seconds"].as_f64().unwrap_or(0.0));
        let ok = result["ok"].as_bool() == Some(true);
        if ok {
            write_returned_folder(plan, out, index, &result["files"])?;
        }
        let stderr = result["error"].as_str().unwrap_or("");
        let code = result["code"].as_i64().map(|c| c as i32);
        report_done(index, ok, took, stderr, &mut failures, code);
    }
    Ok(failures)
}

fn write_returned_folder(
    plan: &WedgePlan,
    out: &Path,
    index: usize,
    files: &Value,
) -> Result<(), Failure> {
    use base64::Engine;
    let folder = out.join(plan.variants[index].folder());
    let mut set = Vec::new();
    for (name, data) in files.as_object().into_iter().flatten() {
        if name.contains('/') || name.contains('\\') || name.starts_with('.') {
            continue;
        }
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(data.as_str().unwrap_or(""))
            .map_err(|e| io_failure(&folder.join(name), e))?;
        set.push(OutputFile {
            path: folder.join(name),
            bytes,
        });
    }
    std::fs::create_dir_all(&folder).map_err(|e| io_failure(&folder, e))?;
    write_outputs(&set, std::slice::from_ref(&plan.scene_path))?;
    Ok(())
}

/// The Python that runs the Ray driver: the project's venv (as for usd-core), else `python3`.
fn python_for_ray() -> PathBuf {
    let explicit = std::env::var_os(springbake_usd::python::VENV_ENV).map(PathBuf::from);
    let cwd = std::env::current_dir().ok();
    let exe = std::env::current_exe().ok();
    let search = springbake_usd::python::find_venv(
        explicit.as_deref(),
        cwd.as_deref(),
        exe.as_deref(),
        (3, 11),
    );
    search
        .found
        .map(|v| v.join("bin/python"))
        .unwrap_or_else(|| PathBuf::from("python3"))
}

/// `out/index.json`: every variant's values, folder, outputs and status.
fn write_index(plan: &WedgePlan, out: &Path, seconds: f64) -> Result<PathBuf, Failure> {
    let variants: Vec<Value> = plan
        .variants
        .iter()
        .map(|v| {
            let folder = out.join(v.folder());
            let record = std::fs::read(folder.join(RECORD))
                .ok()
                .and_then(|b| serde_json::from_slice::<Value>(&b).ok());
            let values: serde_json::Map<String, Value> = v
                .values
                .iter()
                .map(|(p, x)| (p.clone(), toml_to_json(x)))
                .collect();
            json!({
                "index": v.index,
                "folder": v.folder(),
                "values": values,
                "baked": record.is_some(),
                "outputs": record.as_ref().map(|r| r["outputs"].clone()),
                "bake_seconds": record.as_ref().map(|r| r["bake_seconds"].clone()),
            })
        })
        .collect();
    let variations: Vec<Value> = plan
        .variations
        .iter()
        .map(|v| json!({ "path": v.path, "values": v.values.iter().map(toml_to_json).collect::<Vec<_>>() }))
        .collect();
    let index = json!({
        "scene": plan.scene_path,
        "variations": variations,
        "variants": variants,
        "wall_seconds": seconds,
    });
    let path = out.join("index.json");
    let bytes = serde_json::to_vec_pretty(&index).map_err(|e| io_failure(&path, e))?;
    springbake_watcher::write_atomically(&path, &bytes).map_err(|e| io_failure(&path, e))?;
    Ok(path)
}

/// The contact sheet of every baked glTF variant (a row each) at the plan's sheet frames.
fn write_sheet(plan: &WedgePlan, out: &Path, sheet: &Path) -> Result<(), Failure> {
    use springbake_viewer::sheet::{contact_sheet, SheetRow};
    let rows: Vec<SheetRow> = plan
        .variants
        .iter()
        .filter_map(|v| {
            let name = v.scene.output.path.file_name()?;
            let file = out.join(v.folder()).join(name);
            let gltf = matches!(
                file.extension().and_then(|e| e.to_str()),
                Some("glb" | "gltf")
            );
            (gltf && file.is_file()).then(|| SheetRow {
                file,
                label: format!("{} {}", v.folder(), v.short_label()),
            })
        })
        .collect();
    if rows.is_empty() {
        eprintln!("springbake: no glTF outputs to show: no contact sheet (bake to .glb for one)");
        return Ok(());
    }
    let image = contact_sheet(&rows, &plan.sheet_frames(), (240, 180)).map_err(|e| Failure {
        code: if e.is_user_error() { 2 } else { 1 },
        message: format!("contact sheet: {e}"),
    })?;
    let bytes = image.to_png().map_err(|e| io_failure(sheet, e))?;
    springbake_watcher::write_atomically(sheet, &bytes).map_err(|e| io_failure(sheet, e))?;
    eprintln!(
        "springbake: contact sheet of {} variants: {}",
        rows.len(),
        sheet.display()
    );
    Ok(())
}
