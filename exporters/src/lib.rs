//! springbake's built-in exporters. Each format is a module with an [`Exporter`](springbake_core::plugin::Exporter); [`BuiltinExporters`] registers them all.

use springbake_core::plugin::{Plugin, Registry};

pub mod gltf;
pub mod pointcache;
pub mod vat;

/// Registers every built-in exporter on a host's [`Registry`].
#[derive(Debug, Clone, Copy, Default)]
pub struct BuiltinExporters;

impl Plugin for BuiltinExporters {
    fn build(&self, registry: &mut Registry) {
        registry
            .register_exporter(gltf::GltfExporter)
            .register_exporter(pointcache::Pc2Exporter)
            .register_exporter(pointcache::MddExporter)
            .register_exporter(vat::VatExporter);
    }
}
