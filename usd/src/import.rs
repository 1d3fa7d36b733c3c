//! The USD importer: asks the bridge for the stage's meshes ([`read_stage`]) and turns them
//! into an [`ImportedScene`] (up axis, metersPerUnit, one [`DisplayMesh`] per `UsdGeomMesh`).

use crate::mesh::{build_display_mesh, Interpolation, RawMesh, RawPrimvar};
use crate::python::{floats_of, ints_of, plugin_error, with_bridge};
use pyo3::prelude::*;
use springbake_core::display::{
    ImportedScene, SourceDocument, SurfaceMaterial, TextureImage, UpAxis,
};
use springbake_core::plugin::{ImportSettings, Importer, IoErrorKind, PluginError};
use std::path::{Path, PathBuf};

/// What the bridge reports about a stage.
#[derive(Debug, Clone, PartialEq)]
pub struct RawStage {
    pub up_axis: UpAxis,
    pub meters_per_unit: f64,
    pub meshes: Vec<RawMesh>,
    /// Meshes left out and why (invisible, proxy/guide, a point-instancer prototype).
    pub hidden: Vec<String>,
    /// Layers the stage names in a format usd-core cannot read (MaterialX `.mtlx`), as
    /// written: the stage composes without them.
    pub unread: Vec<String>,
    /// usd-core's composition warnings on opening the stage (a reference it could not open),
    /// cleaned of their C++ locations.
    pub warnings: Vec<String>,
    /// The bound materials' UsdPreviewSurface looks.
    pub materials: Vec<SurfaceMaterial>,
}

fn primvar(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Option<RawPrimvar>> {
    if obj.is_none() {
        return Ok(None);
    }
    let token: String = obj.get_item("interpolation")?.extract()?;
    let interpolation = Interpolation::parse(&token).ok_or_else(|| {
        pyo3::exceptions::PyValueError::new_err(format!("{what}: unknown interpolation {token:?}"))
    })?;
    Ok(Some(RawPrimvar {
        interpolation,
        values: floats_of(&obj.get_item("values")?)?,
    }))
}

/// `[(material name, face indices), …]` from the bridge's `subsets`.
fn subsets_of(obj: &Bound<'_, PyAny>) -> PyResult<Vec<(String, Vec<i32>)>> {
    let mut out = Vec::new();
    for item in obj.try_iter()? {
        let item = item?;
        let name: String = item.get_item(0)?.extract()?;
        out.push((name, ints_of(&item.get_item(1)?)?));
    }
    Ok(out)
}

fn raw_mesh(m: &Bound<'_, PyAny>) -> PyResult<RawMesh> {
    let flat = floats_of(&m.get_item("points")?)?;
    let world = crate::python::bytes_of(&m.get_item("world")?)?;
    let mut world_gf = [0.0; 16];
    for (slot, c) in world_gf.iter_mut().zip(world.chunks_exact(8)) {
        *slot = f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
    }
    let orientation: String = m.get_item("orientation")?.extract()?;
    Ok(RawMesh {
        path: m.get_item("path")?.extract()?,
        name: m.get_item("name")?.extract()?,
        points: flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        counts: ints_of(&m.get_item("counts")?)?,
        indices: ints_of(&m.get_item("indices")?)?,
        normals: primvar(&m.get_item("normals")?, "normals")?,
        normals_source: m.get_item("normals_source")?.extract()?,
        st: primvar(&m.get_item("st")?, "primvars:st")?,
        left_handed: orientation == "leftHanded",
        material: m.get_item("material")?.extract()?,
        subsets: subsets_of(&m.get_item("subsets")?)?,
        world_gf,
    })
}

/// Open `path` with usd-core and read every mesh's raw arrays, native instances expanded
/// (`usd_bridge.read_stage`); invisible and proxy/guide meshes too when `include_hidden`.
/// Every layer the stage pulls in (subLayers, references, payloads, transitively) must
/// resolve inside `root`, symlinks followed; the bridge checks each one before opening it.
pub fn read_stage(path: &Path, root: &Path, include_hidden: bool) -> Result<RawStage, PluginError> {
    with_bridge(path, |py, bridge| {
        let to_err = |e: PyErr| plugin_error(py, e, IoErrorKind::Invalid, path);
        let root = if root.as_os_str().is_empty() {
            Path::new(".")
        } else {
            root
        };
        let result = bridge
            .call_method1(
                "read_stage",
                (
                    path.to_string_lossy().into_owned(),
                    root.to_string_lossy().into_owned(),
                    include_hidden,
                ),
            )
            .map_err(to_err)?;
        let up: String = result
            .get_item("up_axis")
            .and_then(|v| v.extract())
            .map_err(to_err)?;
        let up_axis = match up.as_str() {
            "Z" => UpAxis::Z,
            "Y" => UpAxis::Y,
            other => {
                return Err(PluginError::invalid(
                    path,
                    format!("upAxis {other:?} is neither \"Y\" nor \"Z\""),
                )
                .at("upAxis"))
            }
        };
        let meters_per_unit: f64 = result
            .get_item("meters_per_unit")
            .and_then(|v| v.extract())
            .map_err(to_err)?;
        if !(meters_per_unit.is_finite() && meters_per_unit > 0.0) {
            return Err(PluginError::invalid(
                path,
                format!("metersPerUnit {meters_per_unit} is not a positive number"),
            )
            .at("metersPerUnit"));
        }
        let mut meshes = Vec::new();
        for m in result
            .get_item("meshes")
            .and_then(|v| v.try_iter())
            .map_err(to_err)?
        {
            let m = m.map_err(to_err)?;
            let location: Option<String> = m.get_item("path").and_then(|p| p.extract()).ok();
            meshes.push(raw_mesh(&m).map_err(|e| {
                let err = to_err(e);
                match &location {
                    Some(l) if err.location.is_none() => err.at(l.clone()),
                    _ => err,
                }
            })?);
        }
        let mut materials = Vec::new();
        if let Ok(list) = result.get_item("materials").and_then(|v| v.try_iter()) {
            for m in list.flatten() {
                let look = (|| -> PyResult<SurfaceMaterial> {
                    let c: [f32; 4] = m.get_item("base_colour")?.extract()?;
                    let texture = m.get_item("texture")?;
                    let base_colour_texture = if texture.is_none() {
                        None
                    } else {
                        let name: String = texture.get_item("name")?.extract()?;
                        let bytes: Vec<u8> = texture.get_item("bytes")?.extract()?;
                        let mime = if bytes.starts_with(&[0x89, b'P', b'N', b'G']) {
                            "image/png"
                        } else {
                            "image/jpeg"
                        };
                        Some(TextureImage {
                            name,
                            mime: mime.to_owned(),
                            bytes,
                        })
                    };
                    Ok(SurfaceMaterial {
                        name: m.get_item("name")?.extract()?,
                        base_colour: c,
                        roughness: m.get_item("roughness")?.extract()?,
                        base_colour_texture,
                        ..SurfaceMaterial::default()
                    })
                })();
                match look {
                    Ok(look) if look.base_colour.iter().all(|c| c.is_finite()) => {
                        materials.push(look)
                    }
                    _ => {}
                }
            }
        }
        let hidden: Vec<String> = result
            .get_item("hidden")
            .and_then(|v| v.extract())
            .map_err(to_err)?;
        let unread: Vec<String> = result
            .get_item("unread")
            .and_then(|v| v.extract())
            .map_err(to_err)?;
        let warnings: Vec<String> = result
            .get_item("warnings")
            .and_then(|v| v.extract())
            .map_err(to_err)?;
        Ok(RawStage {
            up_axis,
            meters_per_unit,
            meshes,
            hidden,
            unread,
            warnings,
            materials,
        })
    })
}

/// Reads `.usda`, `.usdc`, `.usdz` and `.usd` with usd-core.
#[derive(Debug, Default, Clone, Copy)]
pub struct UsdImporter;

impl UsdImporter {
    /// usd-core opens files by path; when `path` is not a readable file (bytes handed over
    /// from memory), the bytes go to a temporary file with the same extension first.
    fn import_from(
        &self,
        path: &Path,
        bytes: &[u8],
        settings: &ImportSettings,
    ) -> Result<ImportedScene, PluginError> {
        if path.is_file() {
            let own_folder = path.parent().unwrap_or(Path::new(""));
            let root = settings.root.as_deref().unwrap_or(own_folder);
            return self.import_path(path, path, root, settings.include_hidden);
        }
        if bytes.is_empty() {
            return Err(PluginError::new(
                IoErrorKind::Io,
                path,
                "file cannot be read and no bytes were given",
            ));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("usd")
            .to_ascii_lowercase();
        let dir = tempfile::tempdir()
            .map_err(|e| PluginError::new(IoErrorKind::Io, path, format!("temp folder: {e}")))?;
        let temp = dir.path().join(format!("input.{ext}"));
        std::fs::write(&temp, bytes)
            .map_err(|e| PluginError::new(IoErrorKind::Io, path, format!("temp file: {e}")))?;
        // Bytes from memory have no folder: they may pull in nothing.
        self.import_path(&temp, path, dir.path(), settings.include_hidden)
    }

    fn import_path(
        &self,
        open: &Path,
        report: &Path,
        root: &Path,
        include_hidden: bool,
    ) -> Result<ImportedScene, PluginError> {
        let retarget = |mut e: PluginError| {
            e.path = report.to_path_buf();
            e
        };
        let stage = read_stage(open, root, include_hidden).map_err(retarget)?;
        if stage.meshes.is_empty() {
            return Err(PluginError::invalid(
                report,
                "the stage has no UsdGeomMesh prims to simulate",
            ));
        }
        let meshes = stage
            .meshes
            .iter()
            .map(|m| build_display_mesh(m, report))
            .collect::<Result<Vec<_>, _>>()?;
        let mut notes = Vec::new();
        if !stage.hidden.is_empty() {
            let shown: Vec<&str> = stage.hidden.iter().take(5).map(String::as_str).collect();
            notes.push(format!(
                "{}: {} prim(s) not simulated: {}{} \
                 (include_hidden = true on the body simulates invisible and proxy/guide meshes)",
                report.display(),
                stage.hidden.len(),
                shown.join(", "),
                if stage.hidden.len() > 5 { ", …" } else { "" }
            ));
        }
        if !stage.unread.is_empty() {
            let shown: Vec<&str> = stage.unread.iter().take(3).map(String::as_str).collect();
            notes.push(format!(
                "{}: {} layer(s) in a format usd-core cannot read were left out ({}{}): the \
                 stage is composed without them, so materials they define (MaterialX) are \
                 not read; the geometry is",
                report.display(),
                stage.unread.len(),
                shown.join(", "),
                if stage.unread.len() > 3 { ", …" } else { "" }
            ));
        }
        // The unread layers' own warnings are said by the note above.
        let other: Vec<&String> = stage
            .warnings
            .iter()
            .filter(|w| {
                let named = |u: &String| {
                    let file = Path::new(u).file_name().unwrap_or_default();
                    w.contains(&*file.to_string_lossy())
                };
                !stage.unread.iter().any(named)
            })
            .collect();
        if let Some(first) = other.first() {
            notes.push(format!(
                "{}: usd-core composed the stage with {} warning(s), the first: {first}",
                report.display(),
                other.len()
            ));
        }
        Ok(ImportedScene {
            materials: stage.materials,
            notes,
            meshes,
            up_axis: stage.up_axis,
            meters_per_unit: stage.meters_per_unit,
            source: SourceDocument {
                path: PathBuf::from(report),
                importer: "usd".into(),
                read_root: Some(root.to_path_buf()),
            },
        })
    }
}

impl Importer for UsdImporter {
    fn name(&self) -> &str {
        "usd"
    }

    fn extensions(&self) -> &[&str] {
        &["usda", "usdc", "usdz", "usd"]
    }

    fn import(
        &self,
        path: &Path,
        bytes: &[u8],
        settings: &ImportSettings,
    ) -> Result<ImportedScene, PluginError> {
        self.import_from(path, bytes, settings)
    }
}
