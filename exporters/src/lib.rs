//! springbake's built-in exporters. Each format is a module with an [`Exporter`](springbake_core::plugin::Exporter); [`BuiltinExporters`] registers them all.
