//! The bake pipeline: scene file -> import -> fit -> simulate -> export.
