//! springbake's built-in importers. Each format is a module with an [`Importer`](springbake_core::plugin::Importer); [`BuiltinImporters`] registers them all.

use springbake_core::plugin::{Plugin, Registry};

pub mod gltf;
pub mod mtl;
pub mod obj;

/// Registers every built-in importer on a host's [`Registry`].
#[derive(Debug, Clone, Copy, Default)]
pub struct BuiltinImporters;

impl Plugin for BuiltinImporters {
    fn build(&self, registry: &mut Registry) {
        registry.register_importer(gltf::GltfImporter);
        registry.register_importer(obj::ObjImporter);
    }
}
