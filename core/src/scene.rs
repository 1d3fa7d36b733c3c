//! The scene description: the TOML file a user writes (documented in `docs/scene.md`).
//!
//! Parsing is strict: an unknown key is an error with its line and column and the valid keys
//! (serde's `deny_unknown_fields` through the `toml` crate). Paths stay as written; the host
//! resolves them relative to the scene file.

use crate::display::UpAxis;
use crate::material::{Material, MaterialError};
use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};
use std::fmt;
use std::path::PathBuf;

/// A whole scene file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    #[serde(default)]
    pub output: OutputSection,
    #[serde(default)]
    pub world: WorldSection,
    #[serde(default)]
    pub solver: SolverSection,
    #[serde(default)]
    pub body: Vec<BodySection>,
    #[serde(default)]
    pub manipulator: Vec<ManipulatorSection>,
    /// Static colliders: rigid triangle meshes the bodies collide with.
    #[serde(default)]
    pub collider: Vec<ColliderSection>,
    /// Pin and trajectory constraints (Terasawa §3.1).
    #[serde(default)]
    pub constraint: Vec<ConstraintSection>,
    /// Articulated bodies: shared joint nodes (see `crate::solver::joints`).
    #[serde(default)]
    pub joint: Vec<JointSection>,
    /// Events and their procedures (physics §11; see `crate::events`, `crate::procedures`).
    #[serde(default)]
    pub event: Vec<crate::events::EventSpec>,
    /// Named paths for the `follow_trajectory` procedure.
    #[serde(default)]
    pub trajectory: Vec<TrajectorySection>,
    /// Secondary action: child bodies anchored to a parent through three nodes (eq 4.1).
    #[serde(default)]
    pub attach: Vec<AttachSection>,
    /// Force fields from plug-ins acting on bodies (see `crate::solver::fields`).
    #[serde(default)]
    pub force_field: Vec<ForceFieldSection>,
    /// Particle sources (Terasawa §2.3; see `crate::particles`).
    #[serde(default)]
    pub emitter: Vec<crate::particles::EmitterSection>,
    /// Variations of this scene that `springbake wedge` bakes (a bake ignores it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wedge: Option<WedgeSection>,
}

/// `[[force_field]]`: a registered force field (a Python plug-in's) and the bodies it pushes.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ForceFieldSection {
    /// The field's name (its plug-in's `SPRINGBAKE_PLUGIN["name"]`).
    pub field: String,
    /// Body names (`[[body]] name`, or the mesh's name); empty: every body.
    #[serde(default)]
    pub bodies: Vec<String>,
}

/// `[wedge]`: the variations `springbake wedge` bakes, as the cartesian product of their
/// values (the first varies slowest), before any given with `--vary`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, Default)]
#[serde(deny_unknown_fields)]
pub struct WedgeSection {
    #[serde(default)]
    pub vary: Vec<WedgeVariation>,
    /// Frames (1-based) each variant shows in the contact sheet; default first, middle, last.
    #[serde(default)]
    pub sheet_frames: Vec<usize>,
}

/// One varied setting: a path into the scene (`body[0].material`, `world.gravity`) and the
/// values it takes.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WedgeVariation {
    pub path: String,
    pub values: Vec<toml::Value>,
}

/// `[[trajectory]]`: a named path for `follow_trajectory`; key times count from the firing,
/// the body moves by the path's displacement from its first key.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectorySection {
    pub name: String,
    pub keys: Vec<PathKey>,
    #[serde(default)]
    pub interpolation: PathInterpolation,
    #[serde(default = "default_strength")]
    pub strength: f64,
}

/// `[[attach]]`: `child` hangs on `parent` by its three lattice nodes nearest to `anchors`
/// (metres, world frame, after offsets).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AttachSection {
    pub child: String,
    pub parent: String,
    pub anchors: [[f64; 3]; 3],
}

/// `[output]`
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// Output file; the format comes from the extension.
    #[serde(default = "default_output_path")]
    pub path: PathBuf,
    #[serde(default = "default_fps")]
    pub fps: f64,
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// `"morph"` (default), `"skin"` (lattice-as-skin glTF) or `"pca"` (compact morphs).
    #[serde(default)]
    pub cache: CacheSpec,
    /// `cache = "pca"`: the largest vertex error allowed, metres (default 1 mm).
    #[serde(default)]
    pub max_error: Option<f64>,
    /// Point caches (PC2, MDD): `"blender"` (default: the axes Blender's importer gives the
    /// source) or `"source"` (the file's own axes).
    #[serde(default)]
    pub cache_axes: CacheAxesSpec,
}

/// `[output] cache_axes`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CacheAxesSpec {
    #[default]
    Blender,
    Source,
}

fn default_output_path() -> PathBuf {
    PathBuf::from("baked.glb")
}
fn default_fps() -> f64 {
    24.0
}
fn default_frames() -> usize {
    48
}

impl Default for OutputSection {
    fn default() -> Self {
        OutputSection {
            path: default_output_path(),
            fps: default_fps(),
            frames: default_frames(),
            cache: CacheSpec::default(),
            max_error: None,
            cache_axes: CacheAxesSpec::Blender,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum CacheSpec {
    #[default]
    Morph,
    Skin,
    /// Principal components of the displacements as a few morph targets (`max_error`).
    Pca,
}

impl std::str::FromStr for CacheSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "morph" => Ok(CacheSpec::Morph),
            "skin" => Ok(CacheSpec::Skin),
            "pca" => Ok(CacheSpec::Pca),
            _ => Err(format!("unknown cache \"{s}\": morph, skin or pca")),
        }
    }
}

/// `[world]`
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WorldSection {
    /// m/s², along minus the up axis.
    #[serde(default = "default_gravity")]
    pub gravity: f64,
    /// Floor height along up, in source units; `None` (key omitted): no floor.
    #[serde(default)]
    pub floor: Option<f64>,
    /// Coulomb friction coefficient on the floor and walls.
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Overrides the source's up axis.
    #[serde(default)]
    pub up: Option<UpAxis>,
    /// Optional room walls: an axis-aligned box (source units) whose four side planes are rigid
    /// surfaces with elastic layers.
    #[serde(default)]
    pub walls: Option<RoomSpec>,
    /// Elastic-layer thickness in metres; default: half a lattice cell.
    #[serde(default)]
    pub contact_thickness: Option<f64>,
    /// Elastic-layer stiffness in N/m per node; default: from the body's springs.
    #[serde(default)]
    pub contact_stiffness: Option<f64>,
    /// Wind acting on every node as air drag.
    #[serde(default)]
    pub wind: Option<WindSpec>,
    /// Body–body and body–collider contact: `"layer"` (the elastic layer, default) or
    /// `"hertz"` (Hertz's force law from the mass-spring model, physics §10).
    #[serde(default)]
    pub contact: ContactSpec,
}

/// `[world.wind]`: `F = m · drag_per_s · (w(t) − v)`, `w(t) = velocity + gust·sin(2π gust_hz t)`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WindSpec {
    /// Mean air velocity, m/s.
    pub velocity: [f64; 3],
    #[serde(default)]
    pub gust: [f64; 3],
    #[serde(default)]
    pub gust_hz: f64,
    /// Drag rate, 1/s.
    #[serde(default = "default_drag")]
    pub drag_per_s: f64,
}

fn default_drag() -> f64 {
    1.0
}

fn default_gravity() -> f64 {
    9.81
}
fn default_friction() -> f64 {
    0.4
}

impl Default for WorldSection {
    fn default() -> Self {
        WorldSection {
            gravity: default_gravity(),
            floor: None,
            friction: default_friction(),
            up: None,
            walls: None,
            contact_thickness: None,
            contact_stiffness: None,
            wind: None,
            contact: ContactSpec::default(),
        }
    }
}

/// `[world.walls]`: the room's side walls.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RoomSpec {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

/// `[world] contact`: the response between bodies and against colliders.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ContactSpec {
    #[default]
    Layer,
    Hertz,
}

/// `[[collider]]`: a static triangle mesh (any importer's format) bodies collide with.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ColliderSection {
    /// Mesh file, relative to the scene file; every mesh in it is part of the collider.
    pub source: PathBuf,
    /// A name for reports (default: the file name).
    #[serde(default)]
    pub name: Option<String>,
    /// Moves the mesh, metres, world frame.
    #[serde(default)]
    pub offset: [f64; 3],
    /// Coulomb friction on its surface.
    #[serde(default = "default_friction")]
    pub friction: f64,
}

/// `[solver]`
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSection {
    #[serde(default)]
    pub substeps: SubstepSpec,
    /// The velocity-dispersion (fusion) model of Miyazaki et al. 1996 §3.
    #[serde(default = "default_true")]
    pub dispersion: bool,
    /// N in ΔT < T_s / N (physics §4).
    #[serde(default = "default_accuracy_n")]
    pub accuracy_n: f64,
    /// Cap on dispersion sweeps per step; hitting it is reported.
    #[serde(default = "default_dispersion_iterations")]
    pub max_dispersion_iterations: u32,
    /// `"xpbd"` (default: small-step XPBD with volumetric cells, see `solver::xpbd`),
    /// `"symplectic_euler"` (Miyazaki's mass-spring lattice with velocity dispersion) or
    /// `"newmark"` (Terasawa's iterative Newmark-β; the dispersion and deformation damping act
    /// after its corrector).
    #[serde(default)]
    pub integrator: IntegratorSpec,
    /// β of Newmark-β: 0.25 (average acceleration) or 1/6 (linear acceleration).
    #[serde(default = "default_beta")]
    pub newmark_beta: f64,
    /// Where the XPBD solver runs: `"auto"` (default: a GPU for bodies of at least
    /// `solver::device`'s size when a hardware adapter is there and the scene uses only what it
    /// runs, else the CPU; the log says which), `"gpu"` (an error when there is none) or
    /// `"cpu"`.
    #[serde(default)]
    pub device: DeviceSpec,
    /// Bodies far too stiff for their lattice to bend at the XPBD solver's substeps (wood,
    /// steel, glass: a wave speed of 1000 m/s and more, and no sag under gravity an artist
    /// could see): `"rigid"` (default: held to their best-fit rigid motion, see
    /// `solver::xpbd::held`) or `"elastic"` (solved as cells like any body: they then bend as
    /// if their material were far softer).
    #[serde(default)]
    pub stiff_bodies: StiffBodies,
}

/// `[solver] stiff_bodies` (see [`SolverSection::stiff_bodies`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum StiffBodies {
    #[default]
    Rigid,
    Elastic,
}

/// `[solver] device` (see [`SolverSection::device`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum DeviceSpec {
    #[default]
    Auto,
    Gpu,
    Cpu,
}

impl DeviceSpec {
    /// The name the scene file and `--device` use.
    pub fn name(self) -> &'static str {
        match self {
            DeviceSpec::Auto => "auto",
            DeviceSpec::Gpu => "gpu",
            DeviceSpec::Cpu => "cpu",
        }
    }
}

impl std::str::FromStr for DeviceSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [DeviceSpec::Auto, DeviceSpec::Gpu, DeviceSpec::Cpu]
            .into_iter()
            .find(|d| d.name() == s)
            .ok_or_else(|| format!("unknown device \"{s}\": auto, gpu or cpu"))
    }
}

fn default_beta() -> f64 {
    0.25
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorSpec {
    #[default]
    Xpbd,
    SymplecticEuler,
    Newmark,
}

fn default_true() -> bool {
    true
}
fn default_accuracy_n() -> f64 {
    10.0
}
fn default_dispersion_iterations() -> u32 {
    32
}

impl Default for SolverSection {
    fn default() -> Self {
        SolverSection {
            substeps: SubstepSpec::Auto,
            dispersion: true,
            accuracy_n: default_accuracy_n(),
            max_dispersion_iterations: default_dispersion_iterations(),
            integrator: IntegratorSpec::default(),
            newmark_beta: default_beta(),
            device: DeviceSpec::default(),
            stiff_bodies: StiffBodies::default(),
        }
    }
}

/// `substeps = "auto"` or a positive integer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub enum SubstepSpec {
    #[default]
    Auto,
    Fixed(u32),
}

impl<'de> Deserialize<'de> for SubstepSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = SubstepSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("\"auto\" or a positive integer")
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<SubstepSpec, E> {
                if s == "auto" {
                    Ok(SubstepSpec::Auto)
                } else {
                    Err(E::invalid_value(de::Unexpected::Str(s), &self))
                }
            }
            fn visit_i64<E: de::Error>(self, n: i64) -> Result<SubstepSpec, E> {
                if n >= 1 && n <= u32::MAX as i64 {
                    Ok(SubstepSpec::Fixed(n as u32))
                } else {
                    Err(E::invalid_value(de::Unexpected::Signed(n), &self))
                }
            }
        }
        d.deserialize_any(V)
    }
}

/// A body's `source`: a mesh file, or a superquadric metaball model written inline
/// (`source = { superquadric = [ { center = …, radii = … }, … ], threshold = 0.5 }`, the
/// schema of `springbake model`'s shapes file; Terasawa §5.3), polygonised before the fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum SourceSpec {
    File(PathBuf),
    Superquadrics(crate::superquadric::ShapesFile),
}

impl SourceSpec {
    /// The file, when the source is one.
    pub fn file(&self) -> Option<&PathBuf> {
        match self {
            SourceSpec::File(p) => Some(p),
            SourceSpec::Superquadrics(_) => None,
        }
    }
}

impl<'de> Deserialize<'de> for SourceSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct SourceVisitor;
        impl<'de> Visitor<'de> for SourceVisitor {
            type Value = SourceSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a mesh file path, or a table of superquadrics")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<SourceSpec, E> {
                Ok(SourceSpec::File(PathBuf::from(v)))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<SourceSpec, A::Error> {
                // The shapes file's own errors (unknown keys, wrong types) come through.
                let shapes = crate::superquadric::ShapesFile::deserialize(
                    de::value::MapAccessDeserializer::new(map),
                )?;
                Ok(SourceSpec::Superquadrics(shapes))
            }
        }
        d.deserialize_any(SourceVisitor)
    }
}

/// `[[body]]`
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BodySection {
    /// Mesh file, relative to the scene file, or an inline superquadric model.
    pub source: SourceSpec,
    /// Lattice cells along the longest side of the mesh's bounding box.
    #[serde(default)]
    pub cells: Option<u32>,
    /// Alternatively, the cell edge in metres.
    #[serde(default)]
    pub cell_size: Option<f64>,
    /// Metres per unit of the source's numbers, over what the file says (glTF and OBJ: 1;
    /// USD: the stage's `metersPerUnit`): 0.01 for a model made in centimetres and written
    /// as metres. The baked frames keep the source's units.
    #[serde(default)]
    pub meters_per_unit: Option<f64>,
    #[serde(default)]
    pub material: MaterialSpec,
    /// Moves the mesh before simulating (source units, world frame).
    #[serde(default)]
    pub offset: [f64; 3],
    /// Initial velocity, m/s, world frame.
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Spring arrangement (physics §2). Scenes default to `both` (edges, face and body
    /// diagonals): the single-face-diagonal lattice of Miyazaki's Table 1 is weak in shear and
    /// folds cells even on an ordinary drop.
    #[serde(default = "default_springs")]
    pub springs: SpringsSpec,
    /// A name for constraints to refer to (default: the mesh names).
    #[serde(default)]
    pub name: Option<String>,
    /// `"flexible"` (default), `"rigid"` (keeps its shape exactly: a floating frame) or
    /// `"particle"` (one point mass: translation only).
    #[serde(default)]
    pub kind: BodyKind,
    /// Keep the lattice's volume (Terasawa §3.2) at `volume_scale` × its rest volume.
    #[serde(default)]
    pub preserve_volume: bool,
    #[serde(default = "default_volume_scale")]
    pub volume_scale: f64,
    /// Stiffness scale along x, y, z (anisotropy), e.g. `[1, 4, 1]` for a stiff column.
    #[serde(default = "default_stiffness_scale")]
    pub stiffness_scale: [f64; 3],
    /// The analysis model: `lattice` (default), `box`, `octahedron`, `icosahedron`, `plane`,
    /// `decimated`, `explicit` (see `crate::cage`).
    #[serde(default)]
    pub model: ModelKind,
    /// Target node count of `model = "decimated"` (default 32).
    #[serde(default)]
    pub cage_vertices: Option<u32>,
    /// Nodes of `model = "explicit"`, metres, world frame (after offsets).
    #[serde(default, deserialize_with = "de_nodes")]
    pub nodes: Option<Vec<[f64; 3]>>,
    /// Per-region mass and stiffness scales.
    #[serde(default)]
    pub region: Vec<RegionSection>,
    /// Exaggeration: multiplies the stiffness of this body's elastic contact layer.
    #[serde(default = "default_contact_scale")]
    pub contact_scale: f64,
    /// The `bounce` feature settles once a rebound is slower than this, m/s.
    #[serde(default = "default_bounce_tolerance")]
    pub bounce_tolerance: f64,
    /// USD sources: also simulate invisible meshes and proxy/guide geometry.
    #[serde(default)]
    pub include_hidden: bool,
}

fn default_contact_scale() -> f64 {
    1.0
}
fn default_bounce_tolerance() -> f64 {
    0.3
}

impl BodySection {
    /// A body with every default: rubber, 10 cells, no offset or velocity, springs `both`.
    pub fn new(source: impl Into<PathBuf>) -> BodySection {
        BodySection {
            source: SourceSpec::File(source.into()),
            cells: None,
            cell_size: None,
            meters_per_unit: None,
            material: MaterialSpec::default(),
            offset: [0.0; 3],
            velocity: [0.0; 3],
            springs: default_springs(),
            name: None,
            kind: BodyKind::default(),
            preserve_volume: false,
            volume_scale: default_volume_scale(),
            stiffness_scale: default_stiffness_scale(),
            model: ModelKind::default(),
            cage_vertices: None,
            nodes: None,
            region: Vec::new(),
            contact_scale: default_contact_scale(),
            bounce_tolerance: default_bounce_tolerance(),
            include_hidden: false,
        }
    }
}

fn default_volume_scale() -> f64 {
    1.0
}
fn default_stiffness_scale() -> [f64; 3] {
    [1.0; 3]
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum BodyKind {
    #[default]
    Flexible,
    Rigid,
    /// One point mass: translation only (see `crate::solver::rigid`).
    Particle,
}

/// `[[constraint]]`: lattice nodes of a body follow keyframes (a pin without keys).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ConstraintSection {
    /// The body: a `[[body]] name` or a mesh name.
    pub body: String,
    /// Which nodes: those in a box (metres, world frame)…
    #[serde(default, rename = "box")]
    pub region: Option<RoomSpec>,
    /// …or the node nearest to a point…
    #[serde(default)]
    pub nearest: Option<[f64; 3]>,
    /// …or node indices of the body's lattice.
    #[serde(default)]
    pub nodes: Option<Vec<usize>>,
    /// Where the group goes: `[{ t = s, position = [x, y, z] }]`, the nodes keeping their
    /// offsets from the first key. No keys: a pin where the nodes are.
    #[serde(default)]
    pub keys: Vec<PathKey>,
    #[serde(default)]
    pub interpolation: PathInterpolation,
    /// 1: exact; below 1 a loosely bound trajectory.
    #[serde(default = "default_strength")]
    pub strength: f64,
}

fn default_strength() -> f64 {
    1.0
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PathKey {
    pub t: f64,
    pub position: [f64; 3],
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum PathInterpolation {
    #[default]
    Linear,
    CatmullRom,
}

fn default_springs() -> SpringsSpec {
    SpringsSpec::Layout(crate::lattice::SpringLayout::Both)
}

pub const DEFAULT_CELLS: u32 = 10;

/// `[body] model`: the analysis model the mesh is embedded in (see `crate::cage`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ModelKind {
    /// The auto-fitted cubic lattice (trilinear embedding).
    #[default]
    Lattice,
    Box,
    Octahedron,
    Icosahedron,
    /// A one-cell slab across the mesh's two widest axes (`cells` along the widest).
    Plane,
    /// The mesh's vertices clustered to about `cage_vertices` nodes.
    Decimated,
    /// `nodes` and `springs` listed in the scene.
    Explicit,
}

/// `[body] springs`: a lattice layout name, or for `model = "explicit"` the node pairs
/// `[[i, j], ...]`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum SpringsSpec {
    Layout(crate::lattice::SpringLayout),
    Pairs(Vec<[usize; 2]>),
}

impl SpringsSpec {
    /// The lattice layout (`both` when explicit pairs were given).
    pub fn layout(&self) -> crate::lattice::SpringLayout {
        match self {
            SpringsSpec::Layout(l) => *l,
            SpringsSpec::Pairs(_) => crate::lattice::SpringLayout::Both,
        }
    }
}

impl<'de> Deserialize<'de> for SpringsSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = SpringsSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "springs: \"face_diagonals\", \"body_diagonals\", \"both\", or a list of \
                     [i, j] node pairs",
                )
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<SpringsSpec, E> {
                crate::lattice::SpringLayout::deserialize(de::value::StrDeserializer::<E>::new(s))
                    .map(SpringsSpec::Layout)
                    .map_err(|_| {
                        E::custom(format!(
                            "springs: unknown layout \"{s}\"; expected \"face_diagonals\", \
                             \"body_diagonals\", \"both\", or a list of [i, j] node pairs"
                        ))
                    })
            }
            fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<SpringsSpec, A::Error> {
                let mut pairs = Vec::new();
                while let Some(v) = seq.next_element::<toml::Value>()? {
                    let k = pairs.len();
                    let bad = || {
                        de::Error::custom(format!(
                            "springs[{k}]: expected a pair of node indices [i, j] (non-negative \
                             integers), got {v}"
                        ))
                    };
                    let arr = v.as_array().ok_or_else(bad)?;
                    if arr.len() != 2 {
                        return Err(bad());
                    }
                    let idx = |x: &toml::Value| {
                        x.as_integer()
                            .filter(|i| *i >= 0)
                            .map(|i| i as usize)
                            .ok_or_else(bad)
                    };
                    pairs.push([idx(&arr[0])?, idx(&arr[1])?]);
                }
                Ok(SpringsSpec::Pairs(pairs))
            }
        }
        d.deserialize_any(V)
    }
}

/// `nodes = [[x, y, z], ...]` with errors naming the entry.
fn de_nodes<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<[f64; 3]>>, D::Error> {
    let values = Vec::<toml::Value>::deserialize(d)?;
    let mut nodes = Vec::with_capacity(values.len());
    for (i, v) in values.iter().enumerate() {
        let bad = || {
            de::Error::custom(format!(
                "nodes[{i}]: expected three coordinates [x, y, z] in metres, got {v}"
            ))
        };
        let arr = v.as_array().filter(|a| a.len() == 3).ok_or_else(bad)?;
        let mut p = [0.0; 3];
        for (c, x) in p.iter_mut().zip(arr) {
            *c = x
                .as_float()
                .or_else(|| x.as_integer().map(|n| n as f64))
                .ok_or_else(bad)?;
        }
        nodes.push(p);
    }
    Ok(Some(nodes))
}

/// `[[body.region]]`: a box (metres, world frame, after offsets) with its own mass and
/// stiffness scales (locality, e.g. a heavy bottom).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSection {
    pub min: [f64; 3],
    pub max: [f64; 3],
    #[serde(default = "default_one")]
    pub mass_scale: f64,
    #[serde(default = "default_one")]
    pub stiffness_scale: f64,
}

fn default_one() -> f64 {
    1.0
}

/// `[[joint]]`: two flexible bodies share the node of each nearest `at` (metres, world frame).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct JointSection {
    /// The two bodies: `[[body]] name`s or mesh names.
    pub bodies: Vec<String>,
    pub at: [f64; 3],
}

/// A material preset name or an inline table of values.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum MaterialSpec {
    Preset(String),
    Custom(CustomMaterial),
}

impl Default for MaterialSpec {
    fn default() -> Self {
        MaterialSpec::Preset("rubber".into())
    }
}

impl MaterialSpec {
    pub fn resolve(&self) -> Result<Material, MaterialError> {
        match self {
            MaterialSpec::Preset(name) => Material::preset(name),
            MaterialSpec::Custom(c) => Material::new(
                "custom",
                c.young,
                c.poisson.unwrap_or(0.45),
                c.density,
                c.damping.unwrap_or(0.05),
            ),
        }
    }
}

/// `material = { young = 2e5, density = 1000, poisson = 0.45, damping = 0.05 }`
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CustomMaterial {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Density, kg/m³.
    pub density: f64,
    #[serde(default)]
    pub poisson: Option<f64>,
    /// Damping ratio (1 = critical).
    #[serde(default)]
    pub damping: Option<f64>,
}

impl<'de> Deserialize<'de> for MaterialSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = MaterialSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a preset name or a table { young, density, poisson, damping }")
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<MaterialSpec, E> {
                Ok(MaterialSpec::Preset(s.to_owned()))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<MaterialSpec, A::Error> {
                CustomMaterial::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(MaterialSpec::Custom)
            }
        }
        d.deserialize_any(V)
    }
}

/// `[[manipulator]]`: a scripted rigid capsule (physics §6).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ManipulatorSection {
    /// Capsule radius, metres.
    pub radius: f64,
    /// Length of the capsule's axis segment, metres.
    pub length: f64,
    pub keys: Vec<ManipulatorKey>,
    #[serde(default)]
    pub interpolation: Interpolation,
    /// Coulomb friction on the capsule's surface.
    #[serde(default = "default_friction")]
    pub friction: f64,
}

/// A manipulator keyframe: time, position of the capsule's centre, yaw about up (degrees).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ManipulatorKey {
    pub t: f64,
    pub position: [f64; 3],
    #[serde(default)]
    pub yaw: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    #[default]
    Linear,
    Smooth,
}

/// A scene file that failed to parse, with line and column.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{message}")]
pub struct SceneParseError {
    pub message: String,
    /// 1-based line and column of the offending key or value.
    pub line: Option<usize>,
    pub column: Option<usize>,
}

/// 1-based line and column of a TOML error in `text`, when the error has a span.
pub(crate) fn toml_error_position(
    text: &str,
    e: &toml::de::Error,
) -> (Option<usize>, Option<usize>) {
    match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map(|i| i + 1).unwrap_or(0) + 1;
            (Some(line), Some(column))
        }
        None => (None, None),
    }
}

impl SceneFile {
    /// Parse TOML text. Errors carry 1-based line and column.
    pub fn parse(text: &str) -> Result<SceneFile, SceneParseError> {
        toml::from_str::<SceneFile>(text).map_err(|e| {
            let (line, column) = toml_error_position(text, &e);
            let mut message = e.message().to_owned();
            if looks_like_a_shapes_file(text) {
                message.push_str(
                    " (this is a shapes file of [[superquadric]]s: build its mesh with \
                     `springbake model FILE -o shape.glb`, then bake that)",
                );
            }
            SceneParseError {
                message: match (line, column) {
                    (Some(l), Some(c)) => format!("line {l}, column {c}: {message}"),
                    _ => message,
                },
                line,
                column,
            }
        })
    }
}

/// Whether `text` is a `springbake model` shapes file (it has `[[superquadric]]` tables and
/// nothing a scene has), so a scene error can say which command reads it.
fn looks_like_a_shapes_file(text: &str) -> bool {
    text.parse::<toml::Table>().is_ok_and(|table| {
        table.contains_key("superquadric")
            && !["mesh", "body", "world", "output"]
                .iter()
                .any(|key| table.contains_key(*key))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shapes_file_given_as_a_scene_names_the_model_command() {
        let text = "threshold = 0.5\nresolution = 0.005\n[[superquadric]]\nradii = [1, 1, 1]\n";
        let error = SceneFile::parse(text).unwrap_err();
        assert!(
            error.message.contains("springbake model"),
            "{}",
            error.message
        );
        let scene = SceneFile::parse("[world]\nresolutio = 1\n").unwrap_err();
        assert!(
            !scene.message.contains("springbake model"),
            "{}",
            scene.message
        );
    }

    #[test]
    fn parses_the_documented_example() {
        let s = SceneFile::parse(
            r#"
[output]
path = "baked.glb"
fps = 24
frames = 48
[world]
gravity = 9.81
floor = 0.0
friction = 0.4
[solver]
substeps = "auto"
dispersion = true
[[body]]
source = "suzanne.glb"
cells = 10
material = "rubber"
offset = [0.0, 1.0, 0.0]
velocity = [0.0, 0.0, 0.0]
[[body]]
source = "b.obj"
material = { young = 2e5, density = 1000, poisson = 0.45, damping = 0.05 }
"#,
        )
        .unwrap();
        assert_eq!(s.output.frames, 48);
        assert_eq!(s.world.floor, Some(0.0));
        assert_eq!(s.solver.substeps, SubstepSpec::Auto);
        assert_eq!(s.body.len(), 2);
        assert_eq!(s.body[0].offset, [0.0, 1.0, 0.0]);
        match &s.body[1].material {
            MaterialSpec::Custom(c) => assert_eq!(c.young, 2e5),
            other => panic!("expected custom material, got {other:?}"),
        }
        assert_eq!(s.body[1].material.resolve().unwrap().young_pa, 2e5);
    }

    #[test]
    fn unknown_key_reports_line_column_and_valid_keys() {
        let err = SceneFile::parse("[world]\ngravity = 9.81\nflor = 0.0\n").unwrap_err();
        assert_eq!(err.line, Some(3));
        assert_eq!(err.column, Some(1));
        assert!(err.message.contains("flor"), "{}", err.message);
        assert!(err.message.contains("floor"), "{}", err.message);
    }

    #[test]
    fn unknown_key_in_inline_material_is_reported() {
        let err = SceneFile::parse(
            "[[body]]\nsource = \"a.glb\"\nmaterial = { young = 1e5, densty = 3 }\n",
        )
        .unwrap_err();
        assert!(err.message.contains("densty"), "{}", err.message);
        assert_eq!(err.line, Some(3));
    }

    #[test]
    fn colliders_and_the_contact_model_parse_and_unknown_keys_are_named() {
        let s = SceneFile::parse(
            "[world]\ncontact = \"hertz\"\n[[collider]]\nsource = \"lane.glb\"\nname = \"lane\"\n\
             offset = [0.0, -0.1, 0.0]\nfriction = 0.2\n[[collider]]\nsource = \"b.obj\"\n",
        )
        .unwrap();
        assert_eq!(s.world.contact, ContactSpec::Hertz);
        assert_eq!(s.collider.len(), 2);
        assert_eq!(s.collider[0].name.as_deref(), Some("lane"));
        assert_eq!(s.collider[0].offset, [0.0, -0.1, 0.0]);
        assert_eq!(s.collider[0].friction, 0.2);
        assert_eq!(s.collider[1].friction, 0.4);
        assert_eq!(SceneFile::default().world.contact, ContactSpec::Layer);
        let err =
            SceneFile::parse("[[collider]]\nsource = \"a.glb\"\nfriction_ = 1\n").unwrap_err();
        assert_eq!(err.line, Some(3));
        assert!(err.message.contains("friction"), "{}", err.message);
        let err = SceneFile::parse("[world]\ncontact = \"soft\"\n").unwrap_err();
        assert!(err.message.contains("hertz"), "{}", err.message);
    }

    #[test]
    fn substeps_accepts_auto_or_positive_integer() {
        let s = SceneFile::parse("[solver]\nsubsteps = 12\n").unwrap();
        assert_eq!(s.solver.substeps, SubstepSpec::Fixed(12));
        assert!(SceneFile::parse("[solver]\nsubsteps = 0\n").is_err());
        assert!(SceneFile::parse("[solver]\nsubsteps = \"many\"\n").is_err());
    }
}
