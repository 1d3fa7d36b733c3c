//! springbake's built-in importers. Each format is a module with an [`Importer`](springbake_core::plugin::Importer); [`BuiltinImporters`] registers them all.
