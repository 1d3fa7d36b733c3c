//! springbake's headless engine.
//!
//! Data flows one way: an importer fills a [`display::ImportedScene`]; [`lattice`] fits a cubic
//! mass-spring lattice around each mesh and embeds the mesh in it; [`solver`] steps the lattice
//! (Miyazaki et al. 1996: springs, elastic-layer contact, the velocity-dispersion "fusion"
//! model); the baked frames ([`bake::BakedScene`]) go to an exporter. [`plugin`] holds the
//! plug-in traits the host queries; [`scene`] the scene-file description.

pub mod bake;
pub mod cage;
pub mod collide;
pub mod display;
pub mod files;
pub mod lattice;
pub mod material;
pub mod particle_colliders;
pub mod particles;
pub mod plugin;
pub mod scene;

pub use nalgebra;
/// Re-exported for procedure plug-ins, whose arguments are TOML tables.
pub use toml;
pub mod events;
pub mod hertz;
pub mod polygon;
pub mod polygonise;
pub mod procedures;
pub mod secondary;
pub mod shapes;
pub mod solver;
pub mod superquadric;
