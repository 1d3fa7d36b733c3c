//! The embedded Python side: finds the project's virtual environment, makes the embedded
//! interpreter see its `site-packages`, imports a bridge's package (`pxr` from usd-core,
//! `alembic3d`) and loads its bridge file (`usd_bridge.py`, `alembic_bridge.py`) once.
//! Also turns Python exceptions into [`PluginError`]s and decodes the bridge's byte arrays.
//!
//! Venv search order: `$SPRINGBAKE_VENV` (authoritative when set: nothing else is tried), then
//! `.venv` in the current directory and its ancestors, then `.venv` in the ancestors of the
//! running executable (`target/debug/deps/x` → the workspace root).

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyModule};
use springbake_core::plugin::{IoErrorKind, PluginError};
use std::ffi::CString;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Environment variable naming the virtual environment that has usd-core.
pub const VENV_ENV: &str = "SPRINGBAKE_VENV";

/// One Python file compiled into the binary and the package it needs.
pub struct Bridge {
    /// The bridge's source.
    pub source: &'static str,
    pub file_name: &'static std::ffi::CStr,
    pub module_name: &'static std::ffi::CStr,
    /// The module imported first; when it fails the package is missing.
    pub requires: &'static str,
    /// The PyPI package that provides `requires`.
    pub package: &'static str,
    /// What the package is, for the message when it is missing.
    pub package_role: &'static str,
    pub loaded: OnceLock<Py<PyModule>>,
}

/// usd-core's bridge (`usd_bridge.py`).
pub static USD_BRIDGE: Bridge = Bridge {
    source: include_str!("usd_bridge.py"),
    file_name: c"usd_bridge.py",
    module_name: c"springbake_usd_bridge",
    requires: "pxr.Usd",
    package: "usd-core",
    package_role: "Python's usd-core (module `pxr`)",
    loaded: OnceLock::new(),
};

/// Where the venv search looked and what it found.
#[derive(Debug, Clone, PartialEq)]
pub struct VenvSearch {
    /// The first venv whose `site-packages` exists.
    pub found: Option<PathBuf>,
    /// The `site-packages` folder of `found`.
    pub site_packages: Option<PathBuf>,
    /// Every `.venv` candidate looked at, in order.
    pub tried: Vec<PathBuf>,
}

/// `lib/python<major>.<minor>/site-packages` inside `venv`.
pub fn site_packages_of(venv: &Path, python_version: (u8, u8)) -> PathBuf {
    venv.join("lib")
        .join(format!("python{}.{}", python_version.0, python_version.1))
        .join("site-packages")
}

/// Search for the venv: `explicit` (from `$SPRINGBAKE_VENV`) alone when given; otherwise
/// `.venv` in `cwd` and its ancestors, then in the ancestors of `exe`.
pub fn find_venv(
    explicit: Option<&Path>,
    cwd: Option<&Path>,
    exe: Option<&Path>,
    python_version: (u8, u8),
) -> VenvSearch {
    let mut tried = Vec::new();
    for venv in venv_candidates(explicit, cwd, exe) {
        if tried.contains(&venv) {
            continue;
        }
        tried.push(venv.clone());
        let sp = site_packages_of(&venv, python_version);
        if sp.is_dir() {
            return VenvSearch {
                found: Some(venv),
                site_packages: Some(sp),
                tried,
            };
        }
    }
    VenvSearch {
        found: None,
        site_packages: None,
        tried,
    }
}

/// The venvs [`find_venv`] looks at, in order.
fn venv_candidates(
    explicit: Option<&Path>,
    cwd: Option<&Path>,
    exe: Option<&Path>,
) -> Vec<PathBuf> {
    match explicit {
        Some(dir) => vec![dir.to_path_buf()],
        None => {
            let mut c = Vec::new();
            if let Some(cwd) = cwd {
                c.extend(cwd.ancestors().map(|d| d.join(".venv")));
            }
            if let Some(exe) = exe {
                c.extend(exe.ancestors().skip(1).map(|d| d.join(".venv")));
            }
            c
        }
    }
}

/// Every `lib/python*/site-packages` of the venvs the search would look at, and the folders
/// of `$PYTHONPATH`: where installed packages may be found, known without starting Python.
pub fn package_folders() -> Vec<PathBuf> {
    let explicit = std::env::var_os(VENV_ENV).map(PathBuf::from);
    let cwd = std::env::current_dir().ok();
    let exe = std::env::current_exe().ok();
    let mut folders = Vec::new();
    for venv in venv_candidates(explicit.as_deref(), cwd.as_deref(), exe.as_deref()) {
        let Ok(lib) = std::fs::read_dir(venv.join("lib")) else {
            continue;
        };
        let mut found: Vec<PathBuf> = lib
            .flatten()
            .map(|e| e.path().join("site-packages"))
            .filter(|p| p.is_dir())
            .collect();
        found.sort();
        folders.extend(found);
    }
    if let Some(paths) = std::env::var_os("PYTHONPATH") {
        folders.extend(std::env::split_paths(&paths).filter(|p| p.is_dir()));
    }
    folders
}

/// The message for a missing usd-core: what was searched and how to install it.
pub fn missing_usd_core_message(search: &VenvSearch, import_error: &str) -> String {
    missing_package_message(&USD_BRIDGE, search, import_error)
}

/// The message for a bridge's missing package: what was searched and how to install it.
pub fn missing_package_message(bridge: &Bridge, search: &VenvSearch, import_error: &str) -> String {
    let looked = if search.tried.is_empty() {
        "no .venv candidates".to_owned()
    } else {
        search
            .tried
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let venv = match &search.found {
        Some(v) => format!("using the virtual environment {}", v.display()),
        None => format!("no virtual environment with site-packages found (looked at {looked})"),
    };
    format!(
        "{} cannot be imported ({import_error}); {venv}. \
         Install it with `scripts/setup-test-env.sh`, or `.venv/bin/pip install {}` in a \
         `.venv` at the workspace root, or point ${VENV_ENV} at a virtual environment that has it",
        bridge.package_role, bridge.package
    )
}

fn search_now(py: Python<'_>) -> VenvSearch {
    let v = py.version_info();
    let explicit = std::env::var_os(VENV_ENV).map(PathBuf::from);
    let cwd = std::env::current_dir().ok();
    let exe = std::env::current_exe().ok();
    find_venv(
        explicit.as_deref(),
        cwd.as_deref(),
        exe.as_deref(),
        (v.major, v.minor),
    )
}

fn load_bridge<'py>(
    py: Python<'py>,
    bridge: &Bridge,
    file: &Path,
) -> Result<Bound<'py, PyModule>, PluginError> {
    if let Some(m) = bridge.loaded.get() {
        return Ok(m.bind(py).clone());
    }
    let search = search_now(py);
    let missing = |e: String| {
        PluginError::new(
            IoErrorKind::MissingDependency,
            file,
            missing_package_message(bridge, &search, &e),
        )
    };
    if let Some(sp) = &search.site_packages {
        let added: PyResult<()> = (|| {
            let sys_path = py.import("sys")?.getattr("path")?;
            let sp = sp.to_string_lossy().into_owned();
            if !sys_path.contains(&sp)? {
                sys_path.call_method1("insert", (0, sp))?;
            }
            Ok(())
        })();
        added.map_err(|e| missing(e.to_string()))?;
    }
    py.import(bridge.requires)
        .map_err(|e| missing(e.to_string()))?;
    let code = CString::new(bridge.source).map_err(|e| {
        PluginError::new(
            IoErrorKind::MissingDependency,
            file,
            format!("bridge source: {e}"),
        )
    })?;
    let module =
        PyModule::from_code(py, &code, bridge.file_name, bridge.module_name).map_err(|e| {
            PluginError::new(
                IoErrorKind::MissingDependency,
                file,
                format!(
                    "loading {} into the embedded Python failed: {e}",
                    bridge.file_name.to_string_lossy()
                ),
            )
        })?;
    let _ = bridge.loaded.set(module.clone().unbind());
    Ok(module)
}

/// Run `f` with usd-core's bridge module, the embedded interpreter attached.
pub fn with_bridge<T>(
    file: &Path,
    f: impl for<'py> FnOnce(Python<'py>, &Bound<'py, PyModule>) -> Result<T, PluginError>,
) -> Result<T, PluginError> {
    with_bridge_of(&USD_BRIDGE, file, f)
}

/// Run `f` with `bridge`'s module (loaded on first use), the embedded interpreter attached.
pub fn with_bridge_of<T>(
    bridge: &Bridge,
    file: &Path,
    f: impl for<'py> FnOnce(Python<'py>, &Bound<'py, PyModule>) -> Result<T, PluginError>,
) -> Result<T, PluginError> {
    Python::attach(|py| {
        let module = load_bridge(py, bridge, file)?;
        f(py, &module)
    })
}

/// A Python exception as a [`PluginError`]: the bridge's `BridgeError` carries its message and
/// location (a prim or attribute path); anything else keeps its type name and text.
pub fn plugin_error(py: Python<'_>, err: PyErr, kind: IoErrorKind, file: &Path) -> PluginError {
    let value = err.value(py);
    let attr = |name: &str| -> Option<String> {
        value
            .getattr_opt(name)
            .ok()
            .flatten()
            .filter(|v| !v.is_none())
            .and_then(|v| v.extract::<String>().ok())
    };
    match attr("message") {
        Some(message) => {
            let e = PluginError::new(kind, file, message);
            match attr("location") {
                Some(location) => e.at(location),
                None => e,
            }
        }
        None => {
            let type_name = err
                .get_type(py)
                .name()
                .map(|n| n.to_string())
                .unwrap_or_else(|_| "exception".into());
            PluginError::new(
                kind,
                file,
                format!("the embedded Python raised {type_name}: {value}"),
            )
        }
    }
}

/// What `write` puts at a temporary path named `file_name` (a Python library writes files, not
/// buffers), read back as the bytes of the output `out`; `who` names the writer in errors.
pub fn through_temp_file(
    out: &Path,
    file_name: &str,
    who: &str,
    write: impl FnOnce(&Path) -> Result<(), PluginError>,
) -> Result<Vec<u8>, PluginError> {
    let dir = tempfile::tempdir()
        .map_err(|e| PluginError::new(IoErrorKind::Io, out, format!("temp folder: {e}")))?;
    let temp = dir.path().join(file_name);
    write(&temp)?;
    std::fs::read(&temp).map_err(|e| {
        PluginError::new(
            IoErrorKind::Io,
            out,
            format!("reading back {who}'s output {}: {e}", temp.display()),
        )
    })
}

/// Bytes of a `bytes` object.
pub fn bytes_of(obj: &Bound<'_, PyAny>) -> PyResult<Vec<u8>> {
    Ok(obj.cast::<PyBytes>()?.as_bytes().to_vec())
}

/// The bridge's `(format, bytes)` float array ("f" = f32, "d" = f64, little-endian) as f64.
pub fn floats_of(obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let (format, data): (String, Bound<'_, PyBytes>) = obj.extract()?;
    let data = data.as_bytes();
    match format.as_str() {
        "f" => Ok(data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
            .collect()),
        "d" => Ok(f64_values(data)),
        other => Err(pyo3::exceptions::PyValueError::new_err(format!(
            "unexpected array format {other:?}"
        ))),
    }
}

/// The bridge's `("i", bytes)` int32 array.
pub fn ints_of(obj: &Bound<'_, PyAny>) -> PyResult<Vec<i32>> {
    let (_format, data): (String, Bound<'_, PyBytes>) = obj.extract()?;
    Ok(data
        .as_bytes()
        .chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Little-endian f64s from bytes (a trailing partial value is ignored).
pub fn f64_values(data: &[u8]) -> Vec<f64> {
    data.chunks_exact(8)
        .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
        .collect()
}

/// f64 values as little-endian bytes, for the bridge.
pub fn f64_bytes(values: impl IntoIterator<Item = f64>) -> Vec<u8> {
    values.into_iter().flat_map(f64::to_le_bytes).collect()
}

/// f32 values as little-endian bytes, for the bridge.
pub fn f32_bytes(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// i32 values as little-endian bytes, for the bridge.
pub fn i32_bytes(values: impl IntoIterator<Item = i32>) -> Vec<u8> {
    values.into_iter().flat_map(i32::to_le_bytes).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn make_venv(root: &Path) -> PathBuf {
        let venv = root.join(".venv");
        std::fs::create_dir_all(site_packages_of(&venv, (3, 11))).unwrap();
        venv
    }

    #[test]
    fn explicit_venv_is_authoritative() {
        let dir = tempfile::tempdir().unwrap();
        let venv = make_venv(dir.path());
        let empty = dir.path().join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        // An explicit folder without site-packages: not found, even though cwd has a venv.
        let s = find_venv(Some(&empty), Some(dir.path()), None, (3, 11));
        assert_eq!(s.found, None);
        assert_eq!(s.tried, vec![empty.clone()]);
        let s = find_venv(Some(&venv), None, None, (3, 11));
        assert_eq!(s.found.as_deref(), Some(venv.as_path()));
        assert_eq!(s.site_packages, Some(site_packages_of(&venv, (3, 11))));
    }

    #[test]
    fn cwd_ancestors_then_executable_ancestors() {
        let dir = tempfile::tempdir().unwrap();
        let ws = dir.path().join("ws");
        let venv = make_venv(&ws);
        let deep = ws.join("usd/src");
        std::fs::create_dir_all(&deep).unwrap();
        let s = find_venv(None, Some(&deep), None, (3, 11));
        assert_eq!(s.found.as_deref(), Some(venv.as_path()));
        assert_eq!(s.tried[0], deep.join(".venv"));

        let elsewhere = dir.path().join("elsewhere");
        std::fs::create_dir_all(&elsewhere).unwrap();
        let exe = ws.join("target/debug/deps/usd_tests-123");
        let s = find_venv(None, Some(&elsewhere), Some(&exe), (3, 11));
        assert_eq!(s.found.as_deref(), Some(venv.as_path()));
        assert!(s.tried.contains(&ws.join("target/debug/deps/.venv")));
        // Wrong Python version: the venv's site-packages does not match.
        let s = find_venv(None, Some(&deep), None, (3, 12));
        assert_eq!(s.found, None);
    }

    #[test]
    fn missing_message_names_the_install_commands() {
        let search = VenvSearch {
            found: None,
            site_packages: None,
            tried: vec![PathBuf::from("/x/.venv")],
        };
        let m = missing_usd_core_message(&search, "No module named 'pxr'");
        assert!(m.contains("scripts/setup-test-env.sh"), "{m}");
        assert!(m.contains("pip install usd-core"), "{m}");
        assert!(m.contains("/x/.venv"), "{m}");
        assert!(m.contains("No module named 'pxr'"), "{m}");
        assert!(m.contains(VENV_ENV), "{m}");
    }
}
