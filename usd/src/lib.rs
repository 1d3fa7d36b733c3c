//! USD import and export through Python's `usd-core`, and Alembic export through `alembic3d`
//! (PyAlembic), both embedded with pyo3.
//!
//! [`UsdPlugin`] registers [`UsdImporter`] (`.usda`, `.usdc`, `.usdz`, `.usd`),
//! [`UsdExporter`] (`.usda`, `.usdc`, `.usd`) and [`AlembicExporter`] (`.abc`).
//! [`python_plugins`] hosts the user's Python importer and exporter plug-ins in the same
//! interpreter. The Python side is one file, `usd_bridge.py`,
//! compiled into the binary; [`python`] finds the virtual environment with usd-core and loads
//! it; [`mesh`] holds the Rust-side geometry (triangulation, primvar expansion, normals).
//! Bulk data crosses into and out of Python as flat byte arrays.

pub mod alembic;
pub mod export;
pub mod import;
pub mod mesh;
pub mod particles;
pub mod python;
pub mod python_plugins;

pub use alembic::AlembicExporter;
pub use export::UsdExporter;
pub use import::{read_stage, UsdImporter};

use springbake_core::plugin::{Plugin, Registry};

/// Registers the USD importer and exporter.
#[derive(Debug, Default, Clone, Copy)]
pub struct UsdPlugin;

impl Plugin for UsdPlugin {
    fn build(&self, registry: &mut Registry) {
        registry.register_importer(UsdImporter);
        registry.register_exporter(UsdExporter);
        registry.register_exporter(AlembicExporter);
    }
}
