//! The `springbake` command line: bake, demo, inspect, plugins, watch (and view).
//!
//! Exit codes: 0 success, 2 usage or input errors (the user's file or arguments), 1 anything
//! else. Errors are one readable message, never a panic.

mod demo;
mod model;
mod plugins;
mod view;
mod wedge;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use springbake_pipeline::watch::{BakeInput, BakeJob};
use springbake_pipeline::{
    bake, default_registry, BakeHooks, LoadedScene, MeshOverrides, PipelineError,
};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(
    name = "springbake",
    version,
    about = "Soft-body baking: import a mesh, simulate it in real material units, bake the wobble back.",
    long_about = "springbake imports a mesh (glTF, OBJ, USD), fits a cubic lattice around it, \
simulates it in real material units (Young's modulus, Poisson's ratio, density: small-step XPBD \
with volumetric cells, contact with the floor, walls, colliders and a capsule manipulator as \
constraints; the mass-spring models of Miyazaki 1996 and Terasawa 1993 on request) and bakes the \
motion back: glTF morph targets (default), USD time samples, PC2/MDD point caches, a compact \
PCA or lattice-skin glTF.\n\n\
Quick start:\n  springbake demo                      bake the built-in demo to out/demo.glb (+ a GIF)\n  \
springbake bake suzanne.glb          drop a mesh on the floor, write suzanne.baked.glb\n  \
springbake bake scene.toml           bake a scene file (see docs/scene.md)\n  \
springbake wedge scene.toml --vary 'body[0].material=jelly,rubber'   bake variants side by side\n  \
springbake view out/demo.glb         look at a bake (--flipbook out.gif, --screenshot out.png)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake a scene file (.toml) or a bare mesh with the default scene (rubber, ~10 cells,
    /// dropped onto a floor).
    Bake {
        /// A scene file (.toml) or a mesh (.glb, .gltf, .obj, .usda, .usdc, .usdz).
        input: PathBuf,
        /// Output file; the format comes from the extension (.glb, .gltf, .usda, .usdc, .usdz: a package with its textures, .abc, .pc2, .mdd, or .vat: a folder of vertex animation textures).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Number of output frames (frame 1 is the initial state).
        #[arg(long)]
        frames: Option<usize>,
        /// Output frames per second.
        #[arg(long)]
        fps: Option<f64>,
        /// Lattice cells along the longest side (a bare mesh; a scene file sets `cells` per body).
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
        cells: Option<u32>,
        /// Material preset for a bare mesh: jelly, soft_rubber, rubber, foam, wood, steel (a scene
        /// file sets `material` per body).
        #[arg(long)]
        material: Option<String>,
        /// Metres per unit of a bare mesh's numbers, over what the file says (glTF and OBJ:
        /// 1; USD: the stage's metersPerUnit): 0.01 for a model made in centimetres and
        /// written as metres. The baked frames keep the file's units.
        #[arg(long, value_name = "METRES")]
        meters_per_unit: Option<f64>,
        /// Write per-frame diagnostics (energies, inverted cells, penetration, substeps) as JSON,
        /// or, for a .html file, a page with the flipbook, plots over time and the warnings
        /// explained (self-contained: opens offline).
        #[arg(long, value_name = "FILE.json|FILE.html")]
        report: Option<PathBuf>,
        /// Refuse bakes estimated to need more memory than this (e.g. 512M, 4G); default: the
        /// SPRINGBAKE_MAX_MEMORY environment variable, else 90 % of the memory available.
        #[arg(long, value_name = "SIZE", value_parser = springbake_pipeline::budget::parse_size)]
        max_memory: Option<u64>,
        /// How to show progress on stderr: `bar` (a progress bar), `lines` (one
        /// `progress: frame N/M` line per frame, for a host such as the Blender extension to
        /// read), `quiet`, or `auto` (the bar on a terminal, else a line every quarter).
        #[arg(long, value_enum, default_value_t = Progress::Auto)]
        progress: Progress,
        /// Do not load Python plug-ins (from plugins/ beside the scene,
        /// $SPRINGBAKE_PLUGIN_PATH, ~/.config/springbake/plugins).
        #[arg(long)]
        no_plugins: bool,
        /// Where the solver runs, over the scene's `[solver] device`: `auto` (a hardware GPU
        /// for lattices of 32³ nodes and more when the scene uses only what the GPU solver
        /// runs; the log says which), `gpu` (exit 2 naming what is missing when it cannot), or
        /// `cpu`.
        #[arg(long, value_name = "auto|gpu|cpu")]
        device: Option<springbake_core::scene::DeviceSpec>,
        /// How a glTF output stores the motion, over the scene's `[output] cache`: `morph` (a
        /// morph target per frame: plays anywhere, grows with vertices × frames), `skin` (the
        /// lattice's nodes as joints: small at any vertex count) or `pca` (the motion's
        /// principal components as a few morph targets).
        #[arg(long, value_name = "morph|skin|pca")]
        cache: Option<springbake_core::scene::CacheSpec>,
    },
    /// Bake every combination of varied settings ("wedging"), with an index and a contact sheet.
    ///
    /// `--vary 'body[0].material=jelly,rubber' --vary 'body[0].velocity=[0,-2,0],[0,-6,0]'`
    /// (and the scene's `[wedge]` table) give the cartesian product; each variant goes to
    /// OUT/<index>/ (scene.toml, outputs, report.json), with OUT/index.json and a contact
    /// sheet PNG of every variant. Reruns skip variants whose inputs and outputs are unchanged.
    Wedge(wedge::WedgeArgs),
    /// Bake the built-in demo (a soft ball dropped and hit by the manipulator); no files needed.
    Demo {
        /// Output file.
        #[arg(short, long, default_value = "out/demo.glb")]
        output: PathBuf,
        /// Write the diagnostics report as JSON (or an HTML page for a .html file).
        #[arg(long, value_name = "FILE.json|FILE.html")]
        report: Option<PathBuf>,
    },
    /// Polygonise a superquadric metaball model (Terasawa §5.3) into a watertight glTF mesh.
    ///
    /// The shapes file (TOML, Y-up metres): `threshold = 0.5`, `resolution = 0.005` (the
    /// finest detail, m; default a 128th of the model: the mesh follows the surface within a
    /// twentieth of it, with smaller triangles where the surface bends and larger where it is
    /// flat) and `[[superquadric]]` tables with `center`, `radii = [a, b, c]`,
    /// `exponents = [e1, e2]` (1 round, 0.1 a box), `rotation` (degrees about x, y, z) and
    /// `weight`. Primitives blend where their densities overlap; thin parts down to a quarter
    /// of the resolution are kept (the grid is refined where one would fall between samples).
    Model {
        shapes: PathBuf,
        /// Output .glb.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Show a mesh file's meshes, vertex and triangle counts, bounds, and the lattice a fit would make.
    Inspect {
        file: PathBuf,
        /// Lattice cells along the longest side for the fit preview.
        #[arg(long, default_value_t = springbake_core::scene::DEFAULT_CELLS,
              value_parser = clap::value_parser!(u32).range(1..))]
        cells: u32,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// List the built-in importers and exporters and the Python plug-ins found for a scene:
    /// in plugins/ beside it, in each folder of $SPRINGBAKE_PLUGIN_PATH and in
    /// ~/.config/springbake/plugins, each with the file it came from (one that fails to load is
    /// listed with its error). See docs/plugins.md.
    Plugins {
        /// A scene file or folder whose plugins/ to include (default: the current folder).
        scene: Option<PathBuf>,
        /// Skip the Python plug-ins.
        #[arg(long)]
        no_plugins: bool,
    },
    /// Bake, then re-bake whenever the scene file, any source it names or one of its Python
    /// plug-ins changes (plug-ins are loaded again for every bake).
    Watch {
        /// A scene file (.toml) or a mesh.
        input: PathBuf,
        /// Output file for a bare mesh.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// One JSON object per event instead of a line for people.
        #[arg(long)]
        json: bool,
        /// Do not load Python plug-ins.
        #[arg(long)]
        no_plugins: bool,
    },
    /// Open the interactive viewer, or render a screenshot, flipbook or contact sheet offscreen.
    ///
    /// The window: orbit, play/scrub, lattice overlay, live mode with a mouse-driven capsule,
    /// parameter panel, live reload. Offscreen (no GPU or display): --screenshot, --flipbook,
    /// --sheet.
    View(view::ViewCommand),
}

/// A failure and its exit code.
struct Failure {
    code: u8,
    message: String,
}

impl From<PipelineError> for Failure {
    fn from(e: PipelineError) -> Self {
        Failure {
            code: if e.is_user_error() { 2 } else { 1 },
            message: e.to_string(),
        }
    }
}

fn usage(message: impl Into<String>) -> Failure {
    Failure {
        code: 2,
        message: message.into(),
    }
}

fn main() {
    // A bug must still end in a readable line, not a backtrace.
    std::panic::set_hook(Box::new(|info| {
        eprintln!("springbake: internal error: {info}");
    }));
    let cli = Cli::parse();
    // A panic (a bug) has been reported by the hook; it ends with exit code 1 like any failure
    // that is not the user's.
    let code = match std::panic::catch_unwind(|| run(cli.command)) {
        Ok(Ok(())) => 0,
        Ok(Err(f)) => {
            eprintln!("springbake: error: {}", f.message);
            f.code
        }
        Err(_) => 1,
    };
    exit_now(code)
}

/// End the process without running C++ static destructors. usd-core's libraries (loaded into
/// the embedded Python) tear down their thread pools in static destructors, which can race
/// with worker threads at exit and abort ("pure virtual method called") after a perfectly
/// good run. Every output was already written and renamed into place by then, and every Rust
/// value was dropped when `run` returned; only the standard streams need flushing.
fn exit_now(code: u8) -> ! {
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    #[allow(unsafe_code)]
    // SAFETY: `_exit` takes no pointers and never returns; nothing Rust owns needs dropping.
    unsafe {
        libc::_exit(i32::from(code))
    }
}

fn run(command: Command) -> Result<(), Failure> {
    match command {
        Command::Bake {
            input,
            output,
            frames,
            fps,
            cells,
            material,
            meters_per_unit,
            report,
            max_memory,
            progress,
            no_plugins,
            device,
            cache,
        } => {
            let overrides = MeshOverrides {
                output,
                frames,
                fps,
                cells,
                material,
                meters_per_unit,
                device,
                cache,
            };
            let loaded = load_input(&input, &overrides)?;
            let (registry, found) =
                springbake_pipeline::registry_with_plugins(Some(&loaded.read_root()), !no_plugins);
            for (file, why) in &found.failed {
                eprintln!(
                    "springbake: note: plug-in {} not loaded: {why}",
                    file.display()
                );
            }
            run_bake(&loaded, &registry, report.as_deref(), max_memory, progress)
        }
        Command::Demo { output, report } => {
            let dir = tempfile::tempdir().map_err(|e| Failure {
                code: 1,
                message: format!("cannot create a temporary folder: {e}"),
            })?;
            let loaded = demo::demo_scene(dir.path(), &output).map_err(|e| Failure {
                code: 1,
                message: e,
            })?;
            run_bake(
                &loaded,
                &default_registry(),
                report.as_deref(),
                None,
                Progress::Auto,
            )?;
            // A look at it without opening anything: a flipbook beside the bake.
            let gif = output.with_extension("gif");
            let started = std::time::Instant::now();
            springbake_viewer::flipbook::write_flipbook(
                &springbake_viewer::flipbook::FlipbookArgs {
                    input: output.clone(),
                    output: gif.clone(),
                    frames: None,
                    width: 480,
                    height: 360,
                    camera: None,
                },
            )
            .map_err(|e| Failure {
                code: 1,
                message: format!("the demo's flipbook: {e}"),
            })?;
            println!(
                "flipbook in {:.1} s: {} (open it in a browser or an image viewer)",
                started.elapsed().as_secs_f64(),
                gif.display()
            );
            Ok(())
        }
        Command::Wedge(args) => wedge::run(args),
        Command::Model { shapes, output } => model::run(&shapes, &output),
        Command::Inspect { file, cells, json } => inspect(&file, cells, json),
        Command::Plugins { scene, no_plugins } => {
            plugins::list(scene.as_deref(), !no_plugins);
            Ok(())
        }
        Command::Watch {
            input,
            output,
            json,
            no_plugins,
        } => watch(input, output, json, !no_plugins),
        Command::View(args) => view::run(args),
    }
}

/// What the bake's summary names: each file, except that the files of a folder output
/// (`out.vat/…`) are named once, as the folder with their count.
fn output_lines(outputs: &[PathBuf]) -> Vec<String> {
    let folder_of = |p: &Path| {
        p.ancestors()
            .find(|a| springbake_pipeline::outputs::is_folder_output(a))
            .map(Path::to_path_buf)
    };
    let mut lines: Vec<(Option<PathBuf>, String, usize)> = Vec::new();
    for out in outputs {
        match folder_of(out) {
            Some(folder) => match lines
                .iter_mut()
                .find(|(f, _, _)| f.as_ref() == Some(&folder))
            {
                Some(line) => line.2 += 1,
                None => lines.push((Some(folder.clone()), folder.display().to_string(), 1)),
            },
            None => lines.push((None, out.display().to_string(), 1)),
        }
    }
    lines
        .into_iter()
        .map(|(folder, name, count)| match folder {
            Some(_) => format!("{name}/ ({count} files)"),
            None => name,
        })
        .collect()
}

/// `outputs` on one line: all of them up to three, else the first two, an ellipsis, the last
/// and the count (a point cache per body of a 48-part kit is 48 files).
fn listed(outputs: &[String]) -> String {
    match outputs {
        [] => "nothing written".into(),
        [first, .., last] if outputs.len() > 3 => {
            format!(
                "{first}, {}, …, {last} ({} files)",
                outputs[1],
                outputs.len()
            )
        }
        _ => outputs.join(", "),
    }
}

fn is_html(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("html") || e.eq_ignore_ascii_case("htm"))
}

/// The HTML report of a finished bake, with a flipbook of its glTF output (400 × 300).
fn html_report(loaded: &LoadedScene, outcome: &springbake_pipeline::BakeOutcome) -> String {
    use springbake_viewer::report_page::{report_page, PageInput};
    let glb = outcome.outputs.iter().find(|p| {
        p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"))
    });
    let gif = glb.and_then(|file| {
        let dir = tempfile::tempdir().ok()?;
        let out = dir.path().join("flipbook.gif");
        springbake_viewer::flipbook::write_flipbook(&springbake_viewer::flipbook::FlipbookArgs {
            input: file.clone(),
            output: out.clone(),
            frames: None,
            width: 400,
            height: 300,
            camera: None,
        })
        .ok()?;
        std::fs::read(out).ok()
    });
    let title = loaded
        .scene_path
        .as_deref()
        .or_else(|| outcome.outputs.first().map(PathBuf::as_path))
        .and_then(|p| p.file_name())
        .map_or_else(|| "bake".to_owned(), |n| n.to_string_lossy().into_owned());
    report_page(
        &outcome.report,
        &PageInput {
            title: &title,
            outputs: &outcome.outputs,
            flipbook_gif: gif.as_deref(),
        },
    )
}

fn is_scene(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

fn load_input(input: &Path, overrides: &MeshOverrides) -> Result<LoadedScene, Failure> {
    Ok(springbake_pipeline::load_input(input, overrides)?)
}

/// Refuses a `--report` path that would replace the bake's output or an input, or that cannot
/// be written, before any simulation.
fn check_report_path(loaded: &LoadedScene, report: &Path) -> Result<(), Failure> {
    use springbake_pipeline::outputs;
    let output = loaded.output_path();
    if outputs::same_file(report, &output) {
        return Err(usage(format!(
            "{}: the report would replace the bake's output; give --report another file",
            report.display()
        )));
    }
    outputs::refuse_overwriting_inputs(loaded, report)?;
    outputs::check_writable(report, "report")?;
    Ok(())
}

/// How `bake` reports its progress on stderr.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Progress {
    /// A bar on a terminal, else a line every quarter of the frames.
    Auto,
    /// A progress bar (drawn only on a terminal).
    Bar,
    /// One `progress: frame N/M` line per frame.
    Lines,
    /// Nothing.
    Quiet,
}

fn run_bake(
    loaded: &LoadedScene,
    registry: &springbake_core::plugin::Registry,
    report: Option<&Path>,
    max_memory: Option<u64>,
    mode: Progress,
) -> Result<(), Failure> {
    if let Some(path) = report {
        check_report_path(loaded, path)?;
    }
    let total = loaded.scene.output.frames;
    let terminal = std::io::stderr().is_terminal();
    let show_bar = matches!(mode, Progress::Bar) || (mode == Progress::Auto && terminal);
    let bar = show_bar.then(|| {
        let bar = ProgressBar::new(total as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} baking [{bar:30}] frame {pos}/{len} {elapsed} eta {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar
    });
    let mut last_percent = 0;
    let mut progress = |done: usize, total: usize| {
        if let Some(bar) = &bar {
            bar.set_position(done as u64);
        } else if mode == Progress::Lines {
            eprintln!("progress: frame {done}/{total}");
        } else if mode == Progress::Auto {
            let percent = done * 100 / total.max(1);
            if percent >= last_percent + 25 || done == total {
                eprintln!("springbake: frame {done}/{total}");
                last_percent = percent;
            }
        }
    };
    let mut note = |text: &str| {
        if let Some(bar) = &bar {
            bar.suspend(|| eprintln!("springbake: note: {text}"));
        } else {
            eprintln!("springbake: note: {text}");
        }
    };
    let mut hooks = BakeHooks {
        cancelled: None,
        max_memory,
        progress: Some(&mut progress),
        note: Some(&mut note),
    };
    let outcome = bake(registry, loaded, &mut hooks);
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let outcome = outcome?;
    if let Some(path) = report {
        let bytes = if is_html(path) {
            html_report(loaded, &outcome).into_bytes()
        } else {
            serde_json::to_vec_pretty(&outcome.report).map_err(|e| Failure {
                code: 1,
                message: e.to_string(),
            })?
        };
        springbake_pipeline::write_outputs(
            &[springbake_core::plugin::OutputFile {
                path: path.to_path_buf(),
                bytes,
            }],
            &loaded.inputs(),
        )?;
    }
    let r = &outcome.report;
    let nodes: usize = r.bodies.iter().map(|b| b.nodes).sum();
    let inverted = r.frames.iter().map(|f| f.inverted_cells).max().unwrap_or(0);
    println!(
        "baked {} frames of {} bodies ({nodes} nodes) in {:.2} s (simulate {:.2} s): {}",
        r.frames.len(),
        r.bodies.len(),
        r.seconds.import + r.seconds.fit + r.seconds.simulate + r.seconds.export,
        r.seconds.simulate,
        listed(&output_lines(&outcome.outputs)),
    );
    if let Some(note) = redone_note(&r.frames) {
        eprintln!("springbake: note: {note}");
    }
    if inverted > 0 {
        eprintln!(
            "springbake: warning: {}",
            inverted_warning(loaded, &r.frames)
        );
    }
    let gains: Vec<_> = r
        .frames
        .iter()
        .filter_map(|f| f.energy_gain.filter(|g| *g > 0.0).map(|g| (f.frame, g)))
        .collect();
    if let Some(&(frame, gain)) = gains.first() {
        let worst = gains.iter().map(|g| g.1).fold(0.0, f64::max);
        let largest = if gains.len() > 1 {
            format!("; the largest rise {worst:.3} J")
        } else {
            String::new()
        };
        eprintln!(
            "springbake: warning: the total energy rose beyond the work done on the bodies in {} frame(s), first at frame {frame} (by {gain:.3} J{largest}): the motion may not be physical (see energy_gain in --report); try more substeps or cells",
            gains.len()
        );
    }
    Ok(())
}

fn inspect(file: &Path, cells: u32, json: bool) -> Result<(), Failure> {
    let (registry, _) = springbake_pipeline::registry_with_plugins(file.parent(), true);
    let doc = springbake_pipeline::inspect::describe(&registry, file, cells)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&doc).unwrap_or_default());
    } else {
        println!(
            "{} ({}, {}-up, {} m per unit)",
            file.display(),
            doc["format"].as_str().unwrap_or(""),
            doc["up_axis"].as_str().unwrap_or(""),
            doc["meters_per_unit"]
        );
        for m in doc["meshes"].as_array().into_iter().flatten() {
            println!(
                "  {}: {} vertices, {} triangles, bounds {} .. {} m",
                m["name"].as_str().unwrap_or(""),
                m["vertices"],
                m["triangles"],
                m["bounds_m"]["min"],
                m["bounds_m"]["max"]
            );
            let l = &m["lattice"];
            println!(
                "    lattice at {cells} cells: {} cells, {} nodes, {} springs, {} island(s), cell {:.4} m",
                l["cells"], l["nodes"], l["springs"], l["islands"], l["cell_size_m"].as_f64().unwrap_or(0.0)
            );
        }
    }
    Ok(())
}

fn watch(
    input: PathBuf,
    output: Option<PathBuf>,
    json: bool,
    plugins: bool,
) -> Result<(), Failure> {
    use springbake_watcher::{install_ctrlc, CancelToken, WatchOptions, Watcher};
    if !input.exists() {
        return Err(usage(format!("{}: no such file", input.display())));
    }
    let bake_input = if is_scene(&input) {
        BakeInput::Scene(input)
    } else {
        BakeInput::Mesh(
            input,
            MeshOverrides {
                output,
                ..MeshOverrides::default()
            },
        )
    };
    let stop = CancelToken::new();
    install_ctrlc(stop.clone()).map_err(|e| Failure {
        code: 1,
        message: e.to_string(),
    })?;
    let job = BakeJob {
        input: bake_input,
        plugins,
    };
    Watcher::new(job, WatchOptions::default())
        .run_until(&stop, |event| {
            if json {
                println!("{}", event.to_json_line());
            } else {
                println!("{event}");
            }
        })
        .map_err(|e| Failure {
            code: 1,
            message: e.to_string(),
        })?;
    Ok(())
}

/// The note for a bake whose frames were taken again at more substeps because they folded a
/// cell (`None` when none was): which frames, at how many substeps in the end.
fn redone_note(frames: &[springbake_core::solver::FrameDiagnostics]) -> Option<String> {
    let redone: Vec<_> = frames.iter().filter(|f| f.redone > 0).collect();
    match redone[..] {
        [] => None,
        [f] => Some(format!(
            "frame {} folded a cell and was taken again from its start at {} substeps",
            f.frame, f.substeps
        )),
        _ => {
            let mut listed: Vec<String> = (redone.iter().take(5))
                .map(|f| format!("{} ({} substeps)", f.frame, f.substeps))
                .collect();
            if redone.len() > listed.len() {
                listed.push(format!("… {} frames in all", redone.len()));
            }
            Some(format!(
                "frames {} folded a cell and were taken again from their start at more substeps",
                listed.join(", ")
            ))
        }
    }
}

/// The warning for a bake whose report counts inverted cells: how many at most, in which
/// frames, and what to change for the integrator the scene uses.
fn inverted_warning(
    loaded: &LoadedScene,
    frames: &[springbake_core::solver::FrameDiagnostics],
) -> String {
    let with: Vec<&springbake_core::solver::FrameDiagnostics> =
        frames.iter().filter(|f| f.inverted_cells > 0).collect();
    let most = with.iter().map(|f| f.inverted_cells).max().unwrap_or(0);
    let mut listed: Vec<String> = with.iter().take(5).map(|f| f.frame.to_string()).collect();
    if with.len() > listed.len() {
        listed.push(format!("… {} frames in all", with.len()));
    }
    let busiest = frames.iter().map(|f| f.substeps).max().unwrap_or(0);
    let advice = match loaded.scene.solver.integrator {
        springbake_core::scene::IntegratorSpec::Xpbd
            if loaded.scene.solver.substeps != springbake_core::scene::SubstepSpec::Auto =>
        {
            format!(
                "they took the {busiest} substeps the scene sets; try [solver] substeps = \
                 \"auto\" or {}",
                2 * busiest.max(1)
            )
        }
        springbake_core::scene::IntegratorSpec::Xpbd => {
            // Twice what the folding frames took, and no fewer than any frame took.
            let folding = with.iter().map(|f| f.substeps).max().unwrap_or(0);
            format!(
                "they took up to {folding} substeps; try [solver] substeps = {} (or a softer push \
                 or impact)",
                (2 * folding).max(busiest).max(1)
            )
        }
        _ => "try more cells, a softer impact or springs = \"both\"".to_string(),
    };
    format!(
        "up to {most} lattice cells inverted during the bake (frame {}); {advice}",
        listed.join(", ")
    )
}
