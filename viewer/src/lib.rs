//! The interactive egui viewer.
