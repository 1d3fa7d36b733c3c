//! Watch mode: re-bake when the scene or any source changes.
