//! The bake pipeline, shared by the CLI, the watcher and the viewer. Data flows one way:
//!
//! 1. [`load_scene`] reads a scene file ([`springbake_core::scene::SceneFile`]), or
//!    [`default_scene_for_mesh`] makes one for a bare mesh;
//! 2. [`prepare`] imports every body's source through the plug-in [`Registry`], converts it to
//!    the simulation frame (metres, the scene's up axis), fits a lattice and embeds the mesh;
//! 3. [`Prepared::simulate`] steps the world frame by frame and records every vertex;
//! 4. [`export`] hands the baked frames to the exporter for the output's extension, and
//!    [`write_outputs`] writes the files as one atomic set ([`outputs`]: an output that is an
//!    input, or a folder that cannot be written, is refused before step 2).
//!
//! [`bake`] runs all four and returns the report (`--report` JSON).

pub mod budget;
mod colliders;
pub mod device;
pub mod effects;
pub mod events;
mod frame;
pub mod inspect;
mod models;
pub mod outputs;
pub mod placement;
mod report;
mod simulate;
pub use outputs::write_outputs;
pub use springbake_core::files as source;
mod validate;
pub mod watch;
pub mod wedge;

pub use frame::SimFrame;
pub use report::{BodyReport, Report, Seconds};
pub use simulate::{prepare, Prepared, PreparedBody};

use springbake_core::plugin::{
    CacheKind, ExportSettings, ImportSettings, IoErrorKind, OutputFile, PluginError, Registry,
};
use springbake_core::scene::{BodySection, CacheSpec, MaterialSpec, SceneFile, SourceSpec};
use springbake_core::solver::SimulationError;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The host's registry with every built-in plug-in: glTF, OBJ, USD importers; glTF, PC2,
/// MDD, USD exporters.
pub fn default_registry() -> Registry {
    let mut registry = Registry::new();
    registry
        .add_plugin(&springbake_importers::BuiltinImporters)
        .add_plugin(&springbake_exporters::BuiltinExporters)
        .add_plugin(&springbake_usd::UsdPlugin);
    registry
}

/// A plug-in found at run time, for `springbake plugins`.
#[derive(Debug, Clone)]
pub struct FoundPlugin {
    pub kind: &'static str,
    pub name: String,
    pub extensions: Vec<String>,
    pub file: PathBuf,
}

/// Plug-ins found at run time: those that loaded, and the files that failed with why.
#[derive(Debug, Clone, Default)]
pub struct FoundPlugins {
    pub loaded: Vec<FoundPlugin>,
    pub failed: Vec<(PathBuf, String)>,
}

/// [`default_registry`] plus the Python plug-ins discovered for a scene in `scene_dir`
/// (`plugins/` beside it, `$SPRINGBAKE_PLUGIN_PATH`, the user's config folder, the
/// `springbake.plugins` entry points of installed packages), unless
/// `enabled` is false (`--no-plugins`). A built-in format keeps its extensions.
pub fn registry_with_plugins(scene_dir: Option<&Path>, enabled: bool) -> (Registry, FoundPlugins) {
    use springbake_core::plugin::{Exporter, Importer};
    let mut registry = default_registry();
    let mut found = FoundPlugins::default();
    if !enabled {
        return (registry, found);
    }
    let folders = springbake_usd::python_plugins::plugin_folders(scene_dir);
    let discovered = springbake_usd::python_plugins::discover(&folders);
    let mut note = |kind: &'static str, name: &str, extensions: &[&str], file: &Path| {
        found.loaded.push(FoundPlugin {
            kind,
            name: name.to_owned(),
            extensions: extensions.iter().map(|e| e.to_string()).collect(),
            file: file.to_path_buf(),
        });
    };
    for i in discovered.importers {
        note("importer", i.name(), i.extensions(), i.file());
        registry.register_importer(i);
    }
    for e in discovered.exporters {
        note("exporter", e.name(), e.extensions(), e.file());
        registry.register_exporter(e);
    }
    for f in discovered.force_fields {
        let name = springbake_core::solver::fields::ForceField::name(&f).to_owned();
        note("force_field", &name, &[], f.file());
        registry.register_force_field(f);
    }
    for p in discovered.procedures {
        let name = springbake_core::procedures::ProcedurePlugin::name(&p).to_owned();
        note("procedure", &name, &[], p.file());
        registry.register_procedure(p);
    }
    found.failed = discovered.failed;
    (registry, found)
}

/// Why a bake failed. `is_user_error` tells the CLI to exit with code 2.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("{path}: {message}")]
    Scene { path: PathBuf, message: String },
    #[error("{0}")]
    Plugin(#[from] PluginError),
    #[error("body {body} ({source_path}): {message}")]
    Body {
        body: usize,
        source_path: PathBuf,
        message: String,
    },
    #[error("{0}")]
    Simulation(#[from] SimulationError),
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("{0}")]
    Usage(String),
}

impl PipelineError {
    /// True when the user's input is at fault (exit code 2), false for internal failures.
    pub fn is_user_error(&self) -> bool {
        match self {
            PipelineError::Scene { .. } | PipelineError::Body { .. } | PipelineError::Usage(_) => {
                true
            }
            PipelineError::Plugin(p) => p.kind != IoErrorKind::Io || !p.path.exists(),
            PipelineError::Simulation(SimulationError::NonFinite { .. }) => true,
            PipelineError::Simulation(SimulationError::Field(_)) => true,
            PipelineError::Simulation(SimulationError::Cancelled) => false,
            PipelineError::Simulation(SimulationError::Device(_)) => false,
            PipelineError::Io { .. } => false,
        }
    }

    pub fn is_cancelled(&self) -> bool {
        matches!(self, PipelineError::Simulation(SimulationError::Cancelled))
    }
}

/// A scene file and the folder its relative paths start from.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    pub scene: SceneFile,
    /// The scene file itself, when there is one (not for a bare-mesh bake).
    pub scene_path: Option<PathBuf>,
    /// Folder that `source` and `output.path` are relative to.
    pub base_dir: PathBuf,
}

impl LoadedScene {
    /// Absolute path of a body's source.
    pub fn source_path(&self, body: &BodySection) -> PathBuf {
        match &body.source {
            SourceSpec::File(p) => self.base_dir.join(p),
            SourceSpec::Superquadrics(_) => self.base_dir.join("(inline superquadrics)"),
        }
    }

    /// The folder tree a bake may read from: the scene file's folder, or a bare mesh's own
    /// folder. Sources, colliders and every file they pull in (glTF buffers, USD layers) must
    /// resolve inside it, symlinks followed ([`source::contained`]).
    pub fn read_root(&self) -> PathBuf {
        if self.scene_path.is_some() {
            return self.base_dir.clone();
        }
        self.scene
            .body
            .first()
            .and_then(|b| self.source_path(b).parent().map(Path::to_path_buf))
            .unwrap_or_default()
    }

    /// The bytes of a source named by the scene, read bounded and only inside
    /// [`read_root`](Self::read_root); the message says why not.
    pub fn read_source(&self, path: &Path) -> Result<Vec<u8>, String> {
        source::read_contained(&self.read_root(), path).map_err(|e| {
            if e.contains("outside the folder") && self.scene_path.is_some() {
                format!("{e} (keep sources in the scene file's folder or below it)")
            } else {
                e
            }
        })
    }

    /// Import settings for this scene's sources: dependencies resolve inside the read root.
    pub fn import_settings(&self) -> ImportSettings {
        ImportSettings {
            root: Some(self.read_root()),
            ..ImportSettings::default()
        }
    }

    /// [`Self::import_settings`] for one body's source (its `include_hidden`).
    pub fn import_settings_for(&self, body: &BodySection) -> ImportSettings {
        ImportSettings {
            include_hidden: body.include_hidden,
            ..self.import_settings()
        }
    }

    /// The output file.
    pub fn output_path(&self) -> PathBuf {
        self.base_dir.join(&self.scene.output.path)
    }

    /// Every file the bake reads: the scene file and each body's source (for watch mode).
    pub fn inputs(&self) -> Vec<PathBuf> {
        let mut out: Vec<PathBuf> = self.scene_path.iter().cloned().collect();
        for b in self.scene.body.iter().filter(|b| b.source.file().is_some()) {
            let p = self.source_path(b);
            if !out.contains(&p) {
                out.push(p);
            }
        }
        for c in &self.scene.collider {
            let p = self.base_dir.join(&c.source);
            if !out.contains(&p) {
                out.push(p);
            }
        }
        out
    }
}

/// Read and parse a scene file; errors name the file, line and column.
pub fn load_scene(path: &Path) -> Result<LoadedScene, PipelineError> {
    let text = std::fs::read_to_string(path).map_err(|e| PipelineError::Scene {
        path: path.to_path_buf(),
        message: format!("cannot read the scene file: {e}"),
    })?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    scene_from_text(&text, path, &base_dir)
}

/// What `springbake bake INPUT` bakes: a scene file (`.toml`) with the command line's
/// `output`, `frames` and `fps` over its own (an output relative to the working folder), or
/// a bare mesh in the default scene ([`default_scene_for_mesh`]).
pub fn load_input(input: &Path, overrides: &MeshOverrides) -> Result<LoadedScene, PipelineError> {
    if !input.exists() {
        return Err(PipelineError::Usage(format!(
            "{}: no such file",
            input.display()
        )));
    }
    let is_scene = input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let loaded = if is_scene {
        if let Some((flag, key)) = overrides.mesh_only() {
            return Err(PipelineError::Usage(format!(
                "{}: {flag} is for a bare mesh; in a scene file set `{key}` on each [[body]]",
                input.display()
            )));
        }
        let mut loaded = load_scene(input)?;
        let cwd = std::env::current_dir().unwrap_or_default();
        overrides.apply_to(&mut loaded.scene, &cwd);
        loaded
    } else {
        default_scene_for_mesh(input, overrides)
    };
    validate_scene(&loaded.scene).map_err(PipelineError::Usage)?;
    Ok(loaded)
}

/// A scene from its TOML `text`, named `path` in errors, its relative paths resolved (and
/// its reads contained) in `base_dir`: a scene file's text, or one a host built (the Python
/// package's dict).
pub fn scene_from_text(
    text: &str,
    path: &Path,
    base_dir: &Path,
) -> Result<LoadedScene, PipelineError> {
    let scene = SceneFile::parse(text).map_err(|e| PipelineError::Scene {
        path: path.to_path_buf(),
        message: e.message,
    })?;
    validate_scene(&scene)
        .and_then(|()| validate::floor(&scene))
        .map_err(|message| PipelineError::Scene {
            path: path.to_path_buf(),
            message,
        })?;
    Ok(LoadedScene {
        scene,
        scene_path: Some(path.to_path_buf()),
        base_dir: base_dir.to_path_buf(),
    })
}

/// Values the parser accepts but a bake cannot use.
pub fn validate_scene(scene: &SceneFile) -> Result<(), String> {
    let o = &scene.output;
    if !(o.fps > 0.0 && o.fps.is_finite()) {
        return Err(format!("output.fps must be positive, got {}", o.fps));
    }
    if o.frames == 0 {
        return Err("output.frames must be at least 1".into());
    }
    if scene.body.is_empty() {
        return Err("the scene has no [[body]]: nothing to simulate".into());
    }
    for (i, b) in scene.body.iter().enumerate() {
        if b.cells == Some(0) {
            return Err(format!("body[{i}].cells must be at least 1"));
        }
        if let Some(h) = b.cell_size {
            if !(h > 0.0 && h.is_finite()) {
                return Err(format!("body[{i}].cell_size must be positive, got {h}"));
            }
        }
        if let Some(u) = b.meters_per_unit {
            if !(u.is_finite() && (1e-6..=1e6).contains(&u)) {
                return Err(format!(
                    "body[{i}].meters_per_unit must be between 1e-6 and 1e6 (0.01 for centimetres, 0.001 for millimetres), got {u}"
                ));
            }
        }
        b.material
            .resolve()
            .map_err(|e| format!("body[{i}].material: {e}"))?;
    }
    if !(scene.world.friction >= 0.0 && scene.world.friction.is_finite()) {
        return Err(format!(
            "world.friction must be >= 0, got {}",
            scene.world.friction
        ));
    }
    if scene.solver.integrator == springbake_core::scene::IntegratorSpec::Newmark
        && !(scene.solver.newmark_beta > 0.0 && scene.solver.newmark_beta <= 0.5)
    {
        return Err(format!(
            "solver.newmark_beta must be in (0, 0.5], got {}",
            scene.solver.newmark_beta
        ));
    }
    for (i, c) in scene.constraint.iter().enumerate() {
        let selectors = [c.region.is_some(), c.nearest.is_some(), c.nodes.is_some()];
        if selectors.iter().filter(|&&s| s).count() != 1 {
            return Err(format!(
                "constraint[{i}]: give exactly one of box, nearest or nodes"
            ));
        }
        if !(0.0..=1.0).contains(&c.strength) {
            return Err(format!(
                "constraint[{i}].strength must be in [0, 1], got {}",
                c.strength
            ));
        }
    }
    events::validate(scene)?;
    validate::numbers(scene)?;
    for (i, m) in scene.manipulator.iter().enumerate() {
        if !(m.radius > 0.0 && m.length >= 0.0) {
            return Err(format!(
                "manipulator[{i}]: radius must be > 0 and length >= 0"
            ));
        }
        if m.keys.is_empty() {
            return Err(format!("manipulator[{i}].keys is empty"));
        }
    }
    Ok(())
}

/// Command-line overrides for a bare-mesh bake.
#[derive(Debug, Clone, Default)]
pub struct MeshOverrides {
    pub output: Option<PathBuf>,
    pub frames: Option<usize>,
    pub fps: Option<f64>,
    pub cells: Option<u32>,
    pub material: Option<String>,
    /// `--meters-per-unit`: the source's unit, over what the file says.
    pub meters_per_unit: Option<f64>,
    /// `--device`: where the solver runs, over the scene's `[solver] device`.
    pub device: Option<springbake_core::scene::DeviceSpec>,
    /// `--cache`: how a glTF output stores the motion, over the scene's `[output] cache`.
    pub cache: Option<springbake_core::scene::CacheSpec>,
}

impl MeshOverrides {
    /// The first flag given that only a bare mesh takes (a scene file sets it per body), and
    /// the body key that does the same.
    pub fn mesh_only(&self) -> Option<(&'static str, &'static str)> {
        [
            (self.cells.is_some(), "--cells", "cells"),
            (self.material.is_some(), "--material", "material"),
            (
                self.meters_per_unit.is_some(),
                "--meters-per-unit",
                "meters_per_unit",
            ),
        ]
        .into_iter()
        .find_map(|(given, flag, key)| given.then_some((flag, key)))
    }

    /// The command line's `output` (relative to `folder`), `frames`, `fps`, `cache` and
    /// `device` over a scene's own `[output]` and `[solver]`.
    pub fn apply_to(&self, scene: &mut SceneFile, folder: &Path) {
        let output = &mut scene.output;
        if let Some(o) = &self.output {
            output.path = folder.join(o);
        }
        if let Some(n) = self.frames {
            output.frames = n;
        }
        if let Some(f) = self.fps {
            output.fps = f;
        }
        if let Some(d) = self.device {
            scene.solver.device = d;
        }
        if let Some(c) = self.cache {
            output.cache = c;
        }
    }
}

/// Frames of a bare-mesh bake: 3 s at 24 fps, long enough to fall, land, wobble and settle.
pub const DEFAULT_MESH_FRAMES: usize = 72;

/// The default scene for a bare mesh: rubber, about 10 cells, a floor (placed by
/// [`Prepared`] at height 0 when the mesh is above it, else below its lowest point), the
/// output next to the mesh as `<stem>.baked.glb`.
pub fn default_scene_for_mesh(mesh: &Path, o: &MeshOverrides) -> LoadedScene {
    let mut scene = SceneFile::default();
    let stem = mesh.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh");
    scene.output.path = mesh.with_file_name(format!("{stem}.baked.glb"));
    scene.output.frames = DEFAULT_MESH_FRAMES;
    // The command line's settings over these defaults (an `-o` path as given).
    o.apply_to(&mut scene, Path::new(""));
    scene.world.floor = Some(f64::NAN); // "automatic": resolved against the mesh in `prepare`
    scene.body.push(BodySection {
        cells: Some(o.cells.unwrap_or(springbake_core::scene::DEFAULT_CELLS)),
        material: o
            .material
            .clone()
            .map(MaterialSpec::Preset)
            .unwrap_or_default(),
        meters_per_unit: o.meters_per_unit,
        ..BodySection::new(mesh)
    });
    LoadedScene {
        scene,
        scene_path: None,
        base_dir: PathBuf::new(),
    }
}

/// The cache `[output]` asks for, with the compact cache's bound (`max_error`, metres).
pub fn cache_kind(output: &springbake_core::scene::OutputSection) -> CacheKind {
    match (output.cache, output.max_error) {
        (CacheSpec::Pca, Some(m)) => CacheKind::Pca {
            max_error_um: (m * 1e6).round().clamp(1.0, u32::MAX as f64) as u32,
        },
        (spec, _) => spec.into(),
    }
}

/// Run the exporter for the output's extension (point caches in Blender's axes).
pub fn export(
    registry: &Registry,
    prepared: &Prepared,
    baked: &springbake_core::bake::BakedScene,
    output: &Path,
    cache: impl Into<CacheKind>,
) -> Result<Vec<OutputFile>, PipelineError> {
    let settings = ExportSettings {
        path: output.to_path_buf(),
        cache: cache.into(),
        axes: Default::default(),
    };
    export_with(registry, prepared, baked, &settings)
}

/// The export settings `[output]` asks for, writing to `output`.
pub fn export_settings(
    section: &springbake_core::scene::OutputSection,
    output: &Path,
) -> ExportSettings {
    use springbake_core::plugin::PointCacheAxes;
    use springbake_core::scene::CacheAxesSpec;
    ExportSettings {
        path: output.to_path_buf(),
        cache: cache_kind(section),
        axes: match section.cache_axes {
            CacheAxesSpec::Blender => PointCacheAxes::Blender,
            CacheAxesSpec::Source => PointCacheAxes::Source,
        },
    }
}

/// Run the exporter for `settings.path`'s extension.
pub fn export_with(
    registry: &Registry,
    prepared: &Prepared,
    baked: &springbake_core::bake::BakedScene,
    settings: &ExportSettings,
) -> Result<Vec<OutputFile>, PipelineError> {
    let output = &settings.path;
    let exporter = registry.exporter_for(output).ok_or_else(|| {
        PipelineError::Usage(format!(
            "{}: no exporter for this extension; springbake writes {}",
            output.display(),
            registry.export_extensions().join(", ")
        ))
    })?;
    let mut files = exporter.export(&prepared.export_scene, baked, settings)?;
    if !baked.particles.is_empty() && exporter.name() != "usd" {
        files.extend(particles_beside(registry, prepared, baked, settings)?);
    }
    Ok(files)
}

/// Particle effects of a bake whose output format has no point clouds: a USD stage beside
/// it, `<output stem>.particles.usda`, with one `Points` per emitter (Blender, Houdini and
/// usdview read them as point clouds).
fn particles_beside(
    registry: &Registry,
    prepared: &Prepared,
    baked: &springbake_core::bake::BakedScene,
    settings: &ExportSettings,
) -> Result<Vec<OutputFile>, PipelineError> {
    let output = &settings.path;
    let stem = output
        .file_stem()
        .map_or_else(|| "baked".to_owned(), |s| s.to_string_lossy().into_owned());
    let path = output.with_file_name(format!("{stem}.particles.usda"));
    let usd = registry.exporter_for(&path).ok_or_else(|| {
        PipelineError::Usage(format!(
            "{}: the particles need the USD exporter, which this build lacks",
            path.display()
        ))
    })?;
    let source = &prepared.export_scene;
    let stage = springbake_core::display::ImportedScene {
        meshes: Vec::new(),
        up_axis: source.up_axis,
        meters_per_unit: source.meters_per_unit,
        source: springbake_core::display::SourceDocument {
            path: path.clone(),
            importer: "springbake".into(),
            read_root: None,
        },
        materials: Vec::new(),
        notes: Vec::new(),
    };
    let particles = springbake_core::bake::BakedScene {
        fps: baked.fps,
        frame_count: baked.frame_count,
        meshes: Vec::new(),
        stage: None,
        particles: baked.particles.clone(),
    };
    let settings = ExportSettings {
        path,
        ..settings.clone()
    };
    Ok(usd.export(&stage, &particles, &settings)?)
}

/// Hooks a host passes to a bake: cancellation (polled every frame), progress, and the
/// memory limit of the run ([`budget::memory_limit`]).
#[derive(Default)]
pub struct BakeHooks<'a> {
    pub cancelled: Option<&'a (dyn Fn() -> bool + Sync)>,
    /// `--max-memory`, bytes; `None` for the environment's or the machine's limit.
    pub max_memory: Option<u64>,
    /// Called after each frame with (frames done, frames total).
    pub progress: Option<&'a mut dyn FnMut(usize, usize)>,
    /// Called before the first step with notes for the user (a large output's expected size).
    pub note: Option<&'a mut dyn FnMut(&str)>,
}

/// The outcome of a bake: the report, the files written and the baked frames.
#[derive(Debug, Clone)]
pub struct BakeOutcome {
    pub report: Report,
    pub outputs: Vec<PathBuf>,
    /// Every baked mesh's vertices per frame (the exported scene's local coordinates).
    pub baked: springbake_core::bake::BakedScene,
    /// Each mesh of the exported scene (`baked.meshes[i].mesh_index` indexes them).
    pub export_meshes: Vec<ExportMesh>,
    /// The exported scene's unit (metres per unit of its coordinates).
    pub meters_per_unit: f64,
}

/// A mesh of the exported scene: its name and where its local coordinates (the baked
/// frames') sit in the scene.
#[derive(Debug, Clone)]
pub struct ExportMesh {
    pub name: String,
    pub world_from_local: springbake_core::nalgebra::Matrix4<f64>,
}

/// Import, fit, simulate, export and write. Nothing is written unless every stage succeeded.
pub fn bake(
    registry: &Registry,
    loaded: &LoadedScene,
    hooks: &mut BakeHooks,
) -> Result<BakeOutcome, PipelineError> {
    let output = loaded.output_path();
    // Fail on an unknown output format before spending time simulating.
    if registry.exporter_for(&output).is_none() {
        return Err(PipelineError::Usage(format!(
            "{}: no exporter for this extension; springbake writes {}",
            output.display(),
            registry.export_extensions().join(", ")
        )));
    }
    outputs::refuse_overwriting_inputs(loaded, &output)?;
    outputs::check_writable(&output, "output")?;
    let mut seconds = Seconds::default();
    let mut prepared = prepare(registry, loaded, &mut seconds)?;
    if let Some(note) = hooks.note.as_mut() {
        for text in &prepared.export_scene.notes {
            note(text);
        }
        if let Some(text) = budget::large_output_note(&prepared, &loaded.scene, &output) {
            note(&text);
        }
        note(&prepared.device.describe());
        for text in budget::through_plane_notes(&prepared) {
            note(&text);
        }
        for text in budget::body_size_notes(&prepared) {
            note(&text);
        }
        for text in budget::interpenetrating_parts_notes(&mut prepared) {
            note(&text);
        }
        for text in budget::held_bodies_notes(&mut prepared) {
            note(&text);
        }
        for text in budget::under_resolved_notes(&prepared, loaded.scene.output.fps) {
            note(&text);
        }
        for text in budget::coarse_mesh_notes(&mut prepared, &loaded.scene) {
            note(&text);
        }
        for text in budget::inside_collider_notes(&prepared) {
            note(&text);
        }
        if let Some(text) = budget::no_ground_note(&prepared, &loaded.scene) {
            note(&text);
        }
    }
    budget::check_memory(
        &prepared,
        &loaded.scene,
        &output,
        budget::memory_limit(hooks.max_memory),
    )?;
    budget::check_substeps(&mut prepared, &loaded.scene)?;
    let t1 = Instant::now();
    let (baked, frames) = prepared.simulate(&loaded.scene, hooks)?;
    seconds.simulate = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let settings = export_settings(&loaded.scene.output, &output);
    let files = export_with(registry, &prepared, &baked, &settings)?;
    write_outputs(&files, &loaded.inputs())?;
    seconds.export = t2.elapsed().as_secs_f64();
    Ok(BakeOutcome {
        report: Report {
            bodies: prepared.body_reports(),
            frames,
            events: prepared.event_report(),
            seconds,
            device: prepared.device.name.clone(),
        },
        outputs: files.into_iter().map(|f| f.path).collect(),
        export_meshes: prepared
            .export_scene
            .meshes
            .iter()
            .map(|m| ExportMesh {
                name: m.name.clone(),
                world_from_local: m.world_from_local,
            })
            .collect(),
        meters_per_unit: prepared.export_scene.meters_per_unit,
        baked,
    })
}
