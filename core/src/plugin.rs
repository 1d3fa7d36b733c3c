//! Plug-in points: importers and exporters register on a [`Registry`] that the host (CLI,
//! watcher, viewer) queries, the way a DCC's plug-in host does. A [`Plugin`] only registers
//! things; the built-in formats arrive as plugins exactly like a third-party crate would.
//! Event procedures are a plug-in point too: a [`ProcedurePlugin`] registered here runs when a
//! scene's event fires `{ plugin = { name, args } }`.

use crate::bake::BakedScene;
use crate::display::ImportedScene;
pub use crate::procedures::ProcedurePlugin;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What kind of failure an import or export is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IoErrorKind {
    /// The file is not this plug-in's format (e.g. wrong magic); the host may try another.
    Incompatible,
    /// The file is this format but broken, hostile or unsupported: the user's input is at fault.
    Invalid,
    /// Reading or writing failed at the operating-system level.
    Io,
    /// A tool the plug-in needs (e.g. Python's `usd-core`) is not available.
    MissingDependency,
}

/// An import or export failure that says where: the file, and inside it a data path or line.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{}{}: {message}", path.display(), location.as_ref().map(|l| format!(": {l}")).unwrap_or_default())]
pub struct PluginError {
    pub kind: IoErrorKind,
    pub path: PathBuf,
    /// Where in the file: `meshes[0].primitives[1].attributes.POSITION`, `line 17`, a prim path.
    pub location: Option<String>,
    pub message: String,
}

impl PluginError {
    pub fn new(kind: IoErrorKind, path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        PluginError {
            kind,
            path: path.into(),
            location: None,
            message: message.into(),
        }
    }

    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::new(IoErrorKind::Invalid, path, message)
    }

    pub fn at(mut self, location: impl Into<String>) -> Self {
        self.location = Some(location.into());
        self
    }
}

/// Import options shared by all importers.
#[derive(Debug, Clone, Default)]
pub struct ImportSettings {
    /// OBJ: merge all `o`/`g` groups into one body instead of one body per object.
    pub merge_objects: bool,
    /// The folder tree files the source pulls in (USD layers, references, payloads) must lie
    /// in, symlinks resolved; `None` means the source's own folder. glTF buffers and images
    /// are always read from the source's own folder or below.
    pub root: Option<PathBuf>,
    /// USD: also simulate invisible meshes and proxy/guide geometry (a renderer draws neither;
    /// by default they are left out, with a note).
    pub include_hidden: bool,
}

/// Reads a file into the display model.
pub trait Importer: Send + Sync {
    /// Short stable name, e.g. `"gltf"`.
    fn name(&self) -> &str;
    /// Lower-case file extensions without the dot, e.g. `["gltf", "glb"]`.
    fn extensions(&self) -> &[&str];
    /// Import `bytes`, read from `path`. Importers may read sibling resources next to `path`
    /// (external buffers) but must refuse any that leave `path`'s folder.
    fn import(
        &self,
        path: &Path,
        bytes: &[u8],
        settings: &ImportSettings,
    ) -> Result<ImportedScene, PluginError>;
}

/// Which kind of cache an exporter should write when a format offers several.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CacheKind {
    /// Morph targets / per-frame points (the default).
    #[default]
    Morph,
    /// The lattice as a skeleton, the mesh skinned to it (glTF only).
    Skin,
    /// The fewest principal components of the per-frame displacements that keep every vertex
    /// within `max_error_um` micrometres of the bake, as morph targets with per-frame weights
    /// (glTF only).
    Pca { max_error_um: u32 },
}

/// The compact cache's default bound: 1 mm.
pub const DEFAULT_PCA_MAX_ERROR_UM: u32 = 1000;

impl From<crate::scene::CacheSpec> for CacheKind {
    /// The cache a scene's `cache` names (`"pca"` at the default bound).
    fn from(spec: crate::scene::CacheSpec) -> CacheKind {
        match spec {
            crate::scene::CacheSpec::Morph => CacheKind::Morph,
            crate::scene::CacheSpec::Skin => CacheKind::Skin,
            crate::scene::CacheSpec::Pca => CacheKind::Pca {
                max_error_um: DEFAULT_PCA_MAX_ERROR_UM,
            },
        }
    }
}

/// Export options.
#[derive(Debug, Clone)]
pub struct ExportSettings {
    pub path: PathBuf,
    pub cache: CacheKind,
    /// Axes of point caches (PC2, MDD).
    pub axes: PointCacheAxes,
}

/// The axes a point cache's points are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PointCacheAxes {
    /// The local axes Blender's importer gives the source's objects, so the cache plays with
    /// the Mesh Cache modifier's default axes on Blender's import of the source: a glTF's
    /// Y-up `(x, y, z)` becomes Blender's `(x, −z, y)`; OBJ and USD points stay as they are
    /// (Blender keeps their data and turns the object).
    #[default]
    Blender,
    /// The source file's own axes, unchanged (Maya, Houdini and other Y-up importers of glTF).
    Source,
}

/// One file an exporter produced. The host writes all of them atomically (temp file + rename).
#[derive(Debug, Clone, PartialEq)]
pub struct OutputFile {
    pub path: PathBuf,
    pub bytes: Vec<u8>,
}

/// Writes a bake. Returns the files instead of writing them so hosts control atomicity and
/// tests stay off the filesystem.
pub trait Exporter: Send + Sync {
    fn name(&self) -> &str;
    fn extensions(&self) -> &[&str];
    fn export(
        &self,
        scene: &ImportedScene,
        baked: &BakedScene,
        settings: &ExportSettings,
    ) -> Result<Vec<OutputFile>, PluginError>;
}

/// Something that registers importers and exporters on a host.
pub trait Plugin {
    fn build(&self, registry: &mut Registry);
}

/// The host's table of plug-ins.
#[derive(Default, Clone)]
pub struct Registry {
    importers: Vec<Arc<dyn Importer>>,
    exporters: Vec<Arc<dyn Exporter>>,
    procedures: Vec<Arc<dyn ProcedurePlugin>>,
    force_fields: Vec<Arc<dyn crate::solver::fields::ForceField>>,
}

fn extension_of(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

impl Registry {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn add_plugin(&mut self, plugin: &dyn Plugin) -> &mut Self {
        plugin.build(self);
        self
    }

    pub fn register_importer(&mut self, importer: impl Importer + 'static) -> &mut Self {
        self.importers.push(Arc::new(importer));
        self
    }

    pub fn register_exporter(&mut self, exporter: impl Exporter + 'static) -> &mut Self {
        self.exporters.push(Arc::new(exporter));
        self
    }

    /// Register an event procedure; a later one with the same name replaces it.
    pub fn register_procedure(&mut self, procedure: impl ProcedurePlugin + 'static) -> &mut Self {
        self.procedures.retain(|p| p.name() != procedure.name());
        self.procedures.push(Arc::new(procedure));
        self
    }

    /// Register a force field; a later one with the same name replaces it.
    pub fn register_force_field(
        &mut self,
        field: impl crate::solver::fields::ForceField + 'static,
    ) -> &mut Self {
        self.force_fields.retain(|f| f.name() != field.name());
        self.force_fields.push(Arc::new(field));
        self
    }

    /// The force field registered under `name`.
    pub fn force_field(&self, name: &str) -> Option<&Arc<dyn crate::solver::fields::ForceField>> {
        self.force_fields.iter().find(|f| f.name() == name)
    }

    pub fn force_fields(&self) -> &[Arc<dyn crate::solver::fields::ForceField>] {
        &self.force_fields
    }

    /// The event procedure registered under `name`.
    pub fn procedure(&self, name: &str) -> Option<&Arc<dyn ProcedurePlugin>> {
        self.procedures.iter().find(|p| p.name() == name)
    }

    /// Names of the registered event procedures, for error messages.
    pub fn procedure_names(&self) -> Vec<String> {
        self.procedures
            .iter()
            .map(|p| p.name().to_owned())
            .collect()
    }

    pub fn importers(&self) -> &[Arc<dyn Importer>] {
        &self.importers
    }

    pub fn exporters(&self) -> &[Arc<dyn Exporter>] {
        &self.exporters
    }

    /// The importer registered for `path`'s extension.
    pub fn importer_for(&self, path: &Path) -> Option<&Arc<dyn Importer>> {
        let ext = extension_of(path)?;
        self.importers
            .iter()
            .find(|i| i.extensions().contains(&ext.as_str()))
    }

    /// The exporter registered for `path`'s extension.
    pub fn exporter_for(&self, path: &Path) -> Option<&Arc<dyn Exporter>> {
        let ext = extension_of(path)?;
        self.exporters
            .iter()
            .find(|e| e.extensions().contains(&ext.as_str()))
    }

    /// Every extension some importer reads, for error messages.
    pub fn import_extensions(&self) -> Vec<String> {
        self.importers
            .iter()
            .flat_map(|i| i.extensions().iter().map(|e| e.to_string()))
            .collect()
    }

    pub fn export_extensions(&self) -> Vec<String> {
        self.exporters
            .iter()
            .flat_map(|e| e.extensions().iter().map(|x| x.to_string()))
            .collect()
    }
}
