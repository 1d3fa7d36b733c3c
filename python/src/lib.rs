//! springbake as a Python package (issue 22 item 5), built with maturin (`pyproject.toml`,
//! the stable ABI for CPython 3.11 and later):
//!
//! - `springbake.bake(scene, *, output=None, frames=None, fps=None, base_dir=None,
//!   progress=None, plugins=True)`: `scene` is a scene file, a bare mesh (the CLI's default
//!   scene) or a dict in the scene-file schema (relative paths from `base_dir`, else the
//!   working folder). Runs the CLI's pipeline, so the output file has the CLI's bytes, and
//!   returns a dict: `outputs` (paths written), `report` (the `--report` JSON as a dict),
//!   `fps`, `frame_count`, `meters_per_unit` and `meshes`, each `{"name", "positions",
//!   "world_from_local"}`: the positions a float32 numpy array (frames × vertices × 3, the
//!   mesh's local coordinates as exported), placed in the scene by the 4 × 4 matrix
//!   (`world = M @ [x, y, z, 1]`, in the scene's unit).
//!   `progress(done, total)` is called after every frame; an exception it raises (or Ctrl-C)
//!   stops the bake, writes nothing and is raised again.
//! - `springbake.inspect(path, cells=10, plugins=True)`: `springbake inspect --json` as a dict.
//! - `springbake.BakeError`: the user's input is at fault (the CLI's exit code 2); the message
//!   names the file, line or field. Other failures raise `RuntimeError`.

use pyo3::exceptions::{PyException, PyRuntimeError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use springbake_pipeline::{BakeHooks, LoadedScene, MeshOverrides, PipelineError};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

pyo3::create_exception!(
    springbake,
    BakeError,
    PyException,
    "The scene, a source file or a setting is at fault; the message names which."
);

/// A pipeline failure as the Python exception that says whose fault it is.
fn raised(e: PipelineError) -> PyErr {
    if e.is_user_error() {
        BakeError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

/// Bake a scene (file, bare mesh or dict); see the module docs.
#[pyfunction]
#[pyo3(signature = (scene, *, output=None, frames=None, fps=None, base_dir=None, progress=None, plugins=true))]
#[allow(clippy::too_many_arguments)]
fn bake<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    output: Option<PathBuf>,
    frames: Option<usize>,
    fps: Option<f64>,
    base_dir: Option<PathBuf>,
    progress: Option<Bound<'py, PyAny>>,
    plugins: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let overrides = MeshOverrides {
        output,
        frames,
        fps,
        ..MeshOverrides::default()
    };
    let loaded = if scene.is_instance_of::<PyDict>() {
        scene_of_dict(py, scene, base_dir, &overrides)?
    } else {
        let path: PathBuf = scene.extract()?;
        springbake_pipeline::load_input(&path, &overrides).map_err(raised)?
    };
    let (registry, _) =
        springbake_pipeline::registry_with_plugins(Some(&loaded.read_root()), plugins);
    let stop = AtomicBool::new(false);
    let failure: Mutex<Option<PyErr>> = Mutex::new(None);
    let progress = progress.map(Bound::unbind);
    // The bake runs without the interpreter's lock: a plug-in's force field is called from
    // the solver's worker threads, which take the lock (held here, they waited for it for
    // ever). The progress callback takes it back for each frame.
    let outcome = py.detach(|| {
        let mut on_frame = |done: usize, total: usize| {
            let called = Python::attach(|py| {
                let called = match &progress {
                    Some(callback) => callback.bind(py).call1((done, total)).map(drop),
                    None => Ok(()),
                };
                called.and_then(|()| py.check_signals())
            });
            if let Err(e) = called {
                let mut failure = failure.lock().unwrap_or_else(|e| e.into_inner());
                failure.get_or_insert(e);
                stop.store(true, Ordering::Relaxed);
            }
        };
        let cancelled = || stop.load(Ordering::Relaxed);
        let mut hooks = BakeHooks {
            cancelled: Some(&cancelled),
            max_memory: None,
            progress: Some(&mut on_frame),
            note: None,
        };
        springbake_pipeline::bake(&registry, &loaded, &mut hooks)
    });
    let failure = failure.into_inner().unwrap_or_else(|e| e.into_inner());
    if let Some(e) = failure {
        return Err(e);
    }
    let outcome = outcome.map_err(raised)?;
    let json = py.import("json")?;
    let numpy = py.import("numpy")?;
    let result = PyDict::new(py);
    let outputs: Vec<String> = outcome
        .outputs
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    result.set_item("outputs", PyList::new(py, outputs)?)?;
    let report = serde_json::to_string(&outcome.report)
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    result.set_item("report", json.call_method1("loads", (report,))?)?;
    result.set_item("fps", outcome.baked.fps)?;
    result.set_item("meters_per_unit", outcome.meters_per_unit)?;
    result.set_item("frame_count", outcome.baked.frame_count)?;
    let meshes = PyList::empty(py);
    for bm in &outcome.baked.meshes {
        let vertices = bm.frames.first().map_or(0, Vec::len);
        let bytes: Vec<u8> = bm
            .frames
            .iter()
            .flatten()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let flat = numpy.call_method1("frombuffer", (PyBytes::new(py, &bytes), "<f4"))?;
        let positions = flat.call_method1("reshape", ((bm.frames.len(), vertices, 3),))?;
        let mesh = PyDict::new(py);
        if let Some(m) = outcome.export_meshes.get(bm.mesh_index) {
            mesh.set_item("name", &m.name)?;
            let rows: Vec<Vec<f64>> = (0..4)
                .map(|r| (0..4).map(|c| m.world_from_local[(r, c)]).collect())
                .collect();
            mesh.set_item("world_from_local", numpy.call_method1("array", (rows,))?)?;
        }
        mesh.set_item("positions", positions)?;
        meshes.append(mesh)?;
    }
    result.set_item("meshes", meshes)?;
    Ok(result)
}

/// A scene given as a dict in the scene-file schema: written as TOML and read as a scene
/// file in `base_dir` (the working folder when not given) would be.
fn scene_of_dict(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    overrides: &MeshOverrides,
) -> PyResult<LoadedScene> {
    let text: String = py
        .import("json")?
        .call_method1("dumps", (scene,))?
        .extract()?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| BakeError::new_err(format!("scene: {e}")))?;
    let toml = toml::to_string(&value)
        .map_err(|e| BakeError::new_err(format!("scene: not a scene-file table: {e}")))?;
    let base = match base_dir {
        Some(dir) => dir,
        None => std::env::current_dir()?,
    };
    let name = base.join("<scene dict>");
    let mut loaded = springbake_pipeline::scene_from_text(&toml, &name, &base).map_err(raised)?;
    overrides.apply_to(&mut loaded.scene, &base);
    springbake_pipeline::validate_scene(&loaded.scene)
        .map_err(|m| BakeError::new_err(format!("{}: {m}", name.display())))?;
    Ok(loaded)
}

/// What a mesh file holds and the lattice a bake would fit (`springbake inspect --json`).
#[pyfunction]
#[pyo3(signature = (path, cells=10, plugins=true))]
fn inspect<'py>(
    py: Python<'py>,
    path: PathBuf,
    cells: u32,
    plugins: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let (registry, _) = springbake_pipeline::registry_with_plugins(path.parent(), plugins);
    let doc = springbake_pipeline::inspect::describe(&registry, &path, cells).map_err(raised)?;
    py.import("json")?.call_method1("loads", (doc.to_string(),))
}

#[pymodule]
fn springbake(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add_function(wrap_pyfunction!(inspect, m)?)?;
    m.add("BakeError", m.py().get_type::<BakeError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
