//! Python plug-ins found at run time (issue 22): importers and exporters written as one `.py`
//! file each, loaded into the embedded interpreter without rebuilding springbake
//! (docs/plugins.md has the API).
//!
//! Discovery ([`plugin_folders`], [`discover`]), in order: `plugins/` beside the scene file,
//! each folder of `$SPRINGBAKE_PLUGIN_PATH`, the user's `$XDG_CONFIG_HOME/springbake/plugins`
//! (`~/.config/springbake/plugins`), then the `springbake.plugins` entry points of the Python
//! packages installed where the interpreter looks (a module each, named by the entry point). A file that fails to load is kept in
//! [`Discovered::failed`] with its error (file and line); the others still register, so bakes
//! that do not use the broken one run. Exceptions inside a plug-in become [`PluginError`]s
//! naming the plug-in's file and line (exit code 2), never a crash; wrong return shapes are
//! caught and named by `plugin_bridge.py`. The host still writes every output atomically: an
//! exporter plug-in writes to a temporary path it is given.

use crate::python::{
    f64_bytes, f64_values, plugin_error, through_temp_file, with_bridge_of, Bridge,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use springbake_core::bake::BakedScene;
use springbake_core::display::{DisplayMesh, ImportedScene, Primitive, SourceDocument, UpAxis};
use springbake_core::nalgebra::{Matrix4, Vector3};
use springbake_core::plugin::{
    ExportSettings, Exporter, ImportSettings, Importer, IoErrorKind, OutputFile, PluginError,
};
use springbake_core::solver::fields::ForceField;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// Environment variable with extra plug-in folders (`:`-separated).
pub const PLUGIN_PATH_ENV: &str = "SPRINGBAKE_PLUGIN_PATH";

static PLUGIN_BRIDGE: Bridge = Bridge {
    source: include_str!("plugin_bridge.py"),
    file_name: c"plugin_bridge.py",
    module_name: c"springbake_plugin_bridge",
    requires: "numpy",
    package: "numpy",
    package_role: "Python's numpy (what plug-ins exchange arrays in)",
    loaded: OnceLock::new(),
};

/// The folders plug-ins are looked for in, in order (module docs); those that do not exist
/// are left out.
pub fn plugin_folders(scene_dir: Option<&Path>) -> Vec<PathBuf> {
    let mut folders: Vec<PathBuf> = scene_dir.map(|d| d.join("plugins")).into_iter().collect();
    if let Some(paths) = std::env::var_os(PLUGIN_PATH_ENV) {
        folders.extend(std::env::split_paths(&paths).filter(|p| !p.as_os_str().is_empty()));
    }
    let config = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")));
    folders.extend(config.map(|c| c.join("springbake").join("plugins")));
    let mut seen = Vec::new();
    folders.retain(|f| {
        f.is_dir() && !seen.contains(f) && {
            seen.push(f.clone());
            true
        }
    });
    folders
}

/// The `*.py` files of the plug-in folders for a scene in `scene_dir` (what `watch` watches
/// to reload an edited plug-in; installed packages' entry points are not reloaded).
pub fn plugin_files(scene_dir: Option<&Path>) -> Vec<PathBuf> {
    plugin_folders(scene_dir)
        .iter()
        .flat_map(|f| python_files(f))
        .collect()
}

/// The `*.py` files of `folder`, sorted by name.
fn python_files(folder: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "py") && p.is_file())
        .collect();
    files.sort();
    files
}

/// One loaded plug-in file.
#[derive(Debug)]
struct Loaded {
    /// The module's globals, where its functions live.
    namespace: Py<PyAny>,
    file: PathBuf,
    up_axis: UpAxis,
    meters_per_unit: f64,
    /// A force field's `SPRINGBAKE_PLUGIN["every"] == "substep"`.
    per_substep: bool,
}

/// What discovery found.
#[derive(Debug, Default)]
pub struct Discovered {
    pub importers: Vec<PythonImporter>,
    pub exporters: Vec<PythonExporter>,
    pub force_fields: Vec<PythonForceField>,
    pub procedures: Vec<PythonProcedure>,
    /// Files that failed to load, with why.
    pub failed: Vec<(PathBuf, String)>,
}

/// Loads every `*.py` file of `folders` (sorted by name within a folder), then the
/// `springbake.plugins` entry points of the installed Python packages (sorted by name).
pub fn discover(folders: &[PathBuf]) -> Discovered {
    let mut found = Discovered::default();
    for folder in folders {
        for file in python_files(folder) {
            let loaded = load(&file, |bridge| {
                let path = file.to_string_lossy().into_owned();
                let (namespace, kind, name, extensions) =
                    bridge.call_method1("load_plugin", (path,))?.extract()?;
                Ok((namespace, kind, name, extensions, file.clone()))
            });
            found.add(loaded, file);
        }
    }
    for (name, value) in installed_entry_points() {
        let label = PathBuf::from(format!("entry point {name} = {value}"));
        let loaded = load(&label, |bridge| {
            bridge
                .call_method1("load_entry_point", (&name, &value))?
                .extract()
        });
        found.add(loaded, label);
    }
    found
}

/// The `springbake.plugins` entry points of the installed packages, `(name, value)`; none
/// when the plug-in bridge cannot load (no numpy: the folders' plug-ins report that). Python
/// is started for it only when a package's metadata names the group ([`declares_plugins`]).
fn installed_entry_points() -> Vec<(String, String)> {
    let folders = crate::python::package_folders();
    if !folders.iter().any(|f| declares_plugins(f)) {
        return Vec::new();
    }
    let folders: Vec<String> = folders
        .iter()
        .map(|f| f.to_string_lossy().into_owned())
        .collect();
    let label = Path::new("springbake.plugins entry points");
    with_bridge_of(&PLUGIN_BRIDGE, label, |py, bridge| {
        bridge
            .call_method1("entry_points", (folders,))
            .and_then(|r| r.extract())
            .map_err(|e| plugin_error(py, e, IoErrorKind::Invalid, label))
    })
    .unwrap_or_default()
}

/// Whether a package in `folder` declares `springbake.plugins` entry points (its
/// `*.dist-info/entry_points.txt` or `*.egg-info/entry_points.txt` has the section).
fn declares_plugins(folder: &Path) -> bool {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return false;
    };
    entries.flatten().any(|e| {
        let name = e.file_name();
        let name = name.to_string_lossy();
        (name.ends_with(".dist-info") || name.ends_with(".egg-info"))
            && std::fs::read_to_string(e.path().join("entry_points.txt"))
                .is_ok_and(|t| t.lines().any(|l| l.trim() == "[springbake.plugins]"))
    })
}

impl Discovered {
    /// Registers a loaded plug-in under its kind, or records why `origin` did not load.
    fn add(&mut self, loaded: Result<Manifest, PluginError>, origin: PathBuf) {
        let (loaded, kind, name, extensions) = match loaded {
            Ok(m) => m,
            Err(e) => {
                let why = match e.location {
                    Some(at) => format!("{at}: {}", e.message),
                    None => e.message,
                };
                self.failed.push((origin, why));
                return;
            }
        };
        let extensions = extensions.into_iter().map(|e| &*String::leak(e)).collect();
        let loaded = Arc::new(loaded);
        match kind.as_str() {
            "importer" => self.importers.push(PythonImporter {
                name,
                extensions,
                loaded,
            }),
            "force_field" => self.force_fields.push(PythonForceField { name, loaded }),
            "procedure" => self.procedures.push(PythonProcedure { name, loaded }),
            _ => self.exporters.push(PythonExporter {
                name,
                extensions,
                loaded,
            }),
        }
    }
}

type Manifest = (Loaded, String, String, Vec<String>);

/// What the bridge's loaders return: the plug-in's namespace, kind, name, extensions and
/// the file it came from.
type Found<'py> = (Bound<'py, PyAny>, String, String, Vec<String>, PathBuf);

/// Loads one plug-in through `call` (a file's or an entry point's loader); `origin` names
/// it in errors.
fn load(
    origin: &Path,
    call: impl for<'py> FnOnce(&Bound<'py, PyModule>) -> PyResult<Found<'py>>,
) -> Result<Manifest, PluginError> {
    with_bridge_of(&PLUGIN_BRIDGE, origin, |py, bridge| {
        let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Invalid, origin);
        let (namespace, kind, name, extensions, file) = call(bridge).map_err(to_err)?;
        let info = namespace.get_item("SPRINGBAKE_PLUGIN").map_err(to_err)?;
        let up_axis = match info
            .get_item("up_axis")
            .ok()
            .and_then(|v| v.extract::<String>().ok())
            .as_deref()
        {
            Some("Z") | Some("z") => UpAxis::Z,
            _ => UpAxis::Y,
        };
        let meters_per_unit = info
            .get_item("meters_per_unit")
            .ok()
            .and_then(|v| v.extract::<f64>().ok())
            .filter(|m| m.is_finite() && *m > 0.0)
            .unwrap_or(1.0);
        let per_substep = info
            .get_item("every")
            .ok()
            .and_then(|v| v.extract::<String>().ok())
            .is_some_and(|e| e == "substep");
        Ok((
            Loaded {
                namespace: namespace.unbind(),
                file,
                up_axis,
                meters_per_unit,
                per_substep,
            },
            kind,
            name,
            extensions,
        ))
    })
}

/// A body's node positions, velocities and masses as the bridge's f64 byte arrays.
fn node_bytes(
    positions: &[Vector3<f64>],
    velocities: &[Vector3<f64>],
    masses: &[f64],
) -> [Vec<u8>; 3] {
    let flat = |v: &[Vector3<f64>]| f64_bytes(v.iter().flat_map(|p| [p.x, p.y, p.z]));
    [
        flat(positions),
        flat(velocities),
        f64_bytes(masses.iter().copied()),
    ]
}

/// An importer plug-in.
#[derive(Debug)]
pub struct PythonImporter {
    name: String,
    extensions: Vec<&'static str>,
    loaded: Arc<Loaded>,
}

impl PythonImporter {
    /// The plug-in's file.
    pub fn file(&self) -> &Path {
        &self.loaded.file
    }
}

impl Importer for PythonImporter {
    fn name(&self) -> &str {
        &self.name
    }

    fn extensions(&self) -> &[&str] {
        &self.extensions
    }

    fn import(
        &self,
        path: &Path,
        _bytes: &[u8],
        _settings: &ImportSettings,
    ) -> Result<ImportedScene, PluginError> {
        let plugin = &self.loaded;
        let meshes = with_bridge_of(&PLUGIN_BRIDGE, &plugin.file, |py, bridge| {
            let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Invalid, &plugin.file);
            let list = bridge
                .call_method1(
                    "call_import",
                    (
                        plugin.namespace.bind(py),
                        plugin.file.to_string_lossy().into_owned(),
                        path.to_string_lossy().into_owned(),
                    ),
                )
                .map_err(to_err)?;
            let list = list.cast::<PyList>().map_err(|e| to_err(e.into()))?;
            let mut meshes = Vec::new();
            for (k, item) in list.iter().enumerate() {
                let get = |key: &str| -> Option<Vec<u8>> {
                    item.get_item(key)
                        .ok()
                        .and_then(|v| v.cast::<PyBytes>().ok().map(|b| b.as_bytes().to_vec()))
                };
                let name: String = item
                    .get_item("name")
                    .and_then(|v| v.extract())
                    .map_err(to_err)?;
                let positions = f64_values(&get("positions").unwrap_or_default());
                let faces: Vec<u32> = get("faces")
                    .unwrap_or_default()
                    .chunks_exact(4)
                    .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u32)
                    .collect();
                let to_f32 = |v: Vec<f64>, w: usize| -> Vec<Vec<f32>> {
                    v.chunks_exact(w)
                        .map(|c| c.iter().map(|x| *x as f32).collect())
                        .collect()
                };
                let primitive = Primitive {
                    positions: to_f32(positions, 3)
                        .into_iter()
                        .map(|p| [p[0], p[1], p[2]])
                        .collect(),
                    normals: get("normals").map(|b| {
                        to_f32(f64_values(&b), 3)
                            .into_iter()
                            .map(|n| [n[0], n[1], n[2]])
                            .collect()
                    }),
                    uvs: get("uvs").map(|b| {
                        to_f32(f64_values(&b), 2)
                            .into_iter()
                            .map(|t| [t[0], t[1]])
                            .collect()
                    }),
                    indices: faces,
                    material: None,
                };
                let world_from_local = get("matrix")
                    .map(|b| Matrix4::from_row_slice(&f64_values(&b)))
                    .unwrap_or_else(Matrix4::identity);
                let count = primitive.positions.len();
                meshes.push(DisplayMesh {
                    name,
                    source_key: format!("plugin:{k}"),
                    world_from_local,
                    primitives: vec![primitive],
                    source_point_of_vertex: Vec::new(),
                    source_point_count: count,
                });
            }
            Ok(meshes)
        })?;
        Ok(ImportedScene {
            meshes,
            up_axis: plugin.up_axis,
            meters_per_unit: plugin.meters_per_unit,
            source: SourceDocument {
                path: path.to_path_buf(),
                importer: self.name.clone(),
                read_root: None,
            },
            materials: Vec::new(),
            notes: Vec::new(),
        })
    }
}

/// An exporter plug-in.
#[derive(Debug)]
pub struct PythonExporter {
    name: String,
    extensions: Vec<&'static str>,
    loaded: Arc<Loaded>,
}

impl PythonExporter {
    /// The plug-in's file.
    pub fn file(&self) -> &Path {
        &self.loaded.file
    }
}

impl Exporter for PythonExporter {
    fn name(&self) -> &str {
        &self.name
    }

    fn extensions(&self) -> &[&str] {
        &self.extensions
    }

    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError> {
        let out = settings.path.as_path();
        let name = out
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let bytes = through_temp_file(out, &name, &self.name, |temp| {
            self.run_export(scene, baked, temp)
        })?;
        Ok(vec![OutputFile {
            path: out.to_path_buf(),
            bytes,
        }])
    }
}

impl PythonExporter {
    /// Calls the plug-in's `export` with the bake and `temp` to write.
    fn run_export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        temp: &Path,
    ) -> Result<(), PluginError> {
        let plugin = &self.loaded;
        with_bridge_of(&PLUGIN_BRIDGE, &plugin.file, |py, bridge| {
            let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Invalid, &plugin.file);
            let spec = PyDict::new(py);
            let meshes = PyList::empty(py);
            for bm in &baked.meshes {
                let Some(mesh) = scene.meshes.get(bm.mesh_index) else {
                    continue;
                };
                let d = PyDict::new(py);
                let frames: Vec<u8> = bm
                    .frames
                    .iter()
                    .flatten()
                    .flatten()
                    .flat_map(|c| c.to_le_bytes())
                    .collect();
                let triangles: Vec<u8> = mesh
                    .triangles()
                    .iter()
                    .flatten()
                    .flat_map(|&i| (i as i32).to_le_bytes())
                    .collect();
                let matrix: Vec<u8> = mesh
                    .world_from_local
                    .transpose()
                    .as_slice()
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect();
                d.set_item("name", &mesh.name).map_err(to_err)?;
                d.set_item("frames", PyBytes::new(py, &frames))
                    .map_err(to_err)?;
                d.set_item("triangles", PyBytes::new(py, &triangles))
                    .map_err(to_err)?;
                d.set_item("matrix", PyBytes::new(py, &matrix))
                    .map_err(to_err)?;
                meshes.append(d).map_err(to_err)?;
            }
            spec.set_item("meshes", meshes).map_err(to_err)?;
            spec.set_item("fps", baked.fps).map_err(to_err)?;
            spec.set_item("frame_count", baked.frame_count)
                .map_err(to_err)?;
            let up = if scene.up_axis == UpAxis::Z { "Z" } else { "Y" };
            spec.set_item("up_axis", up).map_err(to_err)?;
            spec.set_item("meters_per_unit", scene.meters_per_unit)
                .map_err(to_err)?;
            bridge
                .call_method1(
                    "call_export",
                    (
                        plugin.namespace.bind(py),
                        plugin.file.to_string_lossy().into_owned(),
                        spec,
                        temp.to_string_lossy().into_owned(),
                    ),
                )
                .map_err(to_err)?;
            Ok(())
        })
    }
}

/// A force-field plug-in (`force(positions, velocities, time[, masses]) -> forces`).
#[derive(Debug)]
pub struct PythonForceField {
    name: String,
    loaded: Arc<Loaded>,
}

impl PythonForceField {
    /// The plug-in's file.
    pub fn file(&self) -> &Path {
        &self.loaded.file
    }
}

impl ForceField for PythonForceField {
    fn name(&self) -> &str {
        &self.name
    }

    fn per_substep(&self) -> bool {
        self.loaded.per_substep
    }

    fn force(
        &self,
        positions: &[Vector3<f64>],
        velocities: &[Vector3<f64>],
        masses: &[f64],
        time: f64,
    ) -> Result<Vec<Vector3<f64>>, String> {
        let plugin = &self.loaded;
        let [positions, velocities, masses] = node_bytes(positions, velocities, masses);
        let bytes = with_bridge_of(&PLUGIN_BRIDGE, &plugin.file, |py, bridge| {
            let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Invalid, &plugin.file);
            let out = bridge
                .call_method1(
                    "call_force",
                    (
                        plugin.namespace.bind(py),
                        plugin.file.to_string_lossy().into_owned(),
                        PyBytes::new(py, &positions),
                        PyBytes::new(py, &velocities),
                        PyBytes::new(py, &masses),
                        time,
                    ),
                )
                .map_err(to_err)?;
            out.cast::<PyBytes>()
                .map(|b| b.as_bytes().to_vec())
                .map_err(|e| to_err(e.into()))
        })
        .map_err(|e| e.to_string())?;
        Ok(f64_values(&bytes)
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect())
    }
}

/// An event-procedure plug-in (`run(body, args)` → new node velocities or None; optional
/// `check(args)`), run as `{ plugin = { name, args } }` in an `[[event]]`.
#[derive(Debug)]
pub struct PythonProcedure {
    name: String,
    loaded: Arc<Loaded>,
}

impl PythonProcedure {
    /// The plug-in's file.
    pub fn file(&self) -> &Path {
        &self.loaded.file
    }
}

fn json_of(args: &toml::Table) -> String {
    serde_json::to_string(args).unwrap_or_else(|_| "{}".into())
}

impl springbake_core::procedures::ProcedurePlugin for PythonProcedure {
    fn name(&self) -> &str {
        &self.name
    }

    fn check(&self, args: &toml::Table) -> Result<(), String> {
        let plugin = &self.loaded;
        with_bridge_of(&PLUGIN_BRIDGE, &plugin.file, |py, bridge| {
            bridge
                .call_method1(
                    "call_check",
                    (
                        plugin.namespace.bind(py),
                        plugin.file.to_string_lossy().into_owned(),
                        json_of(args),
                    ),
                )
                .map(|_| ())
                .map_err(|e| plugin_error(py, e, IoErrorKind::Invalid, &plugin.file))
        })
        .map_err(|e| e.to_string())
    }

    fn run(
        &self,
        world: &mut springbake_core::solver::World,
        body: springbake_core::solver::BodyHandle,
        args: &toml::Table,
    ) -> Result<Vec<springbake_core::events::Procedure>, String> {
        let plugin = &self.loaded;
        let range = world.bodies[body.0].nodes.clone();
        let nodes = &world.nodes;
        let [positions, velocities, masses] = node_bytes(
            &nodes.position[range.clone()],
            &nodes.velocity[range.clone()],
            &nodes.mass[range.clone()],
        );
        let time = world.time;
        let out = with_bridge_of(&PLUGIN_BRIDGE, &plugin.file, |py, bridge| {
            let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Invalid, &plugin.file);
            let out = bridge
                .call_method1(
                    "call_procedure",
                    (
                        plugin.namespace.bind(py),
                        plugin.file.to_string_lossy().into_owned(),
                        PyBytes::new(py, &positions),
                        PyBytes::new(py, &velocities),
                        PyBytes::new(py, &masses),
                        time,
                        json_of(args),
                    ),
                )
                .map_err(to_err)?;
            let (velocities, then): (Option<Bound<PyBytes>>, String) =
                out.extract().map_err(to_err)?;
            Ok((velocities.map(|b| b.as_bytes().to_vec()), then))
        })
        .map_err(|e| e.to_string())?;
        let (velocities, then) = out;
        let then: Vec<springbake_core::events::Procedure> =
            serde_json::from_str(&then).map_err(|e| {
                format!(
                    "{}: run() returned a procedure springbake does not know: {e}",
                    plugin.file.display()
                )
            })?;
        if let Some(bytes) = velocities {
            let v = f64_values(&bytes);
            for (slot, c) in world.nodes.velocity[range]
                .iter_mut()
                .zip(v.chunks_exact(3))
            {
                *slot = Vector3::new(c[0], c[1], c[2]);
            }
        }
        Ok(then)
    }
}
