//! The analysis model of each body (`[body] model`, see `springbake_core::cage`): fit the
//! lattice or build the cage, add it to the world with its per-region scales, display-surface
//! contact and embedding, `kind = "particle"`, and the scene's `[[joint]]`s.

use crate::PipelineError;
use springbake_core::cage::{self, Cage, Primitive};
use springbake_core::lattice::fill::cell_fill;
use springbake_core::lattice::{
    fit_lattice, surface_samples_with_normals, Embedding, FitSettings, Lattice,
};
use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::scene::{BodyKind, BodySection, ModelKind, SceneFile, SpringsSpec};
use springbake_core::solver::joints::{join_bodies_at, JointError};
use springbake_core::solver::regions::{apply_region, Region};
use springbake_core::solver::{BodyHandle, Integrator, RigidBody, World};

/// Default node target of `model = "decimated"`.
pub const DEFAULT_CAGE_VERTICES: u32 = 32;

/// A body's analysis model before it joins the world.
#[derive(Debug, Clone)]
pub enum Analysis {
    Lattice(Lattice),
    Cage(Cage),
}

impl Analysis {
    /// Cell size, or the cage's mean spring length, metres.
    pub fn spacing(&self) -> f64 {
        match self {
            Analysis::Lattice(l) => l.cell_size,
            Analysis::Cage(c) => c.spacing(),
        }
    }
}

/// Fit the lattice or build the cage of one mesh (`points` in simulation metres).
pub fn fit(
    points: &[Point3<f64>],
    triangles: &[[u32; 3]],
    section: &BodySection,
    lattice_settings: &FitSettings,
) -> Result<Analysis, String> {
    let cage_err = |e: cage::CageError| e.to_string();
    if section.model != ModelKind::Explicit {
        for (field, given) in [
            ("nodes", section.nodes.is_some()),
            ("springs", matches!(section.springs, SpringsSpec::Pairs(_))),
        ] {
            if given {
                return Err(format!("{field}: only for model = \"explicit\""));
            }
        }
    }
    if section.cell_size.is_some() && section.model != ModelKind::Lattice {
        return Err("cell_size: only for model = \"lattice\" (a cage is sized to the mesh)".into());
    }
    if section.cells.is_some() && !matches!(section.model, ModelKind::Lattice | ModelKind::Plane) {
        return Err(
            "cells: only for model = \"lattice\" or \"plane\" (other cages have a fixed shape; \
             use cage_vertices with model = \"decimated\")"
                .into(),
        );
    }
    if section.cage_vertices.is_some() && section.model != ModelKind::Decimated {
        return Err("cage_vertices: only for model = \"decimated\"".into());
    }
    Ok(match section.model {
        ModelKind::Lattice => Analysis::Lattice(
            fit_lattice(points, triangles, lattice_settings).map_err(|e| e.to_string())?,
        ),
        ModelKind::Box => {
            Analysis::Cage(cage::primitive(Primitive::Box, points).map_err(cage_err)?)
        }
        ModelKind::Octahedron => {
            Analysis::Cage(cage::primitive(Primitive::Octahedron, points).map_err(cage_err)?)
        }
        ModelKind::Icosahedron => {
            Analysis::Cage(cage::primitive(Primitive::Icosahedron, points).map_err(cage_err)?)
        }
        ModelKind::Plane => {
            let cells = section
                .cells
                .unwrap_or(springbake_core::scene::DEFAULT_CELLS);
            // At most 2 (cells + 1)² nodes (the second side is never the longer one); refused
            // by the fit's memory guard before anything is allocated.
            let nodes = 2 * (u64::from(cells) + 1).pow(2);
            let bytes = nodes.saturating_mul(springbake_core::lattice::BYTES_PER_NODE);
            if bytes > lattice_settings.memory_limit_bytes {
                return Err(format!(
                    "cells = {cells}: a plane of up to {nodes} nodes needs about {} MiB, over the {} MiB limit; use fewer cells",
                    bytes >> 20,
                    lattice_settings.memory_limit_bytes >> 20
                ));
            }
            Analysis::Cage(cage::plane(points, cells).map_err(cage_err)?)
        }
        ModelKind::Decimated => Analysis::Cage(
            cage::decimated(
                points,
                triangles,
                section.cage_vertices.unwrap_or(DEFAULT_CAGE_VERTICES),
            )
            .map_err(cage_err)?,
        ),
        ModelKind::Explicit => {
            let nodes: Vec<Vector3<f64>> = section
                .nodes
                .as_ref()
                .ok_or("nodes: model = \"explicit\" needs nodes = [[x, y, z], ...] (metres)")?
                .iter()
                .map(|p| Vector3::from(*p))
                .collect();
            let SpringsSpec::Pairs(springs) = &section.springs else {
                return Err(
                    "springs: model = \"explicit\" needs springs = [[i, j], ...] (node pairs)"
                        .into(),
                );
            };
            Analysis::Cage(cage::explicit(&nodes, springs).map_err(cage_err)?)
        }
    })
}

/// A body added to the world, with what the host keeps of it.
#[derive(Debug, Clone)]
pub struct AddedBody {
    pub handle: BodyHandle,
    /// The display mesh in the model.
    pub embedding: Embedding,
    /// The lattice, or a cell-less view of the cage, for reports, the viewer and the skin
    /// cache.
    pub lattice: Lattice,
    /// `lattice`, `box`, …, `explicit`.
    pub model: String,
    /// [`Cage::note`].
    pub note: Option<String>,
}

/// Add one body: the model's nodes and springs, its `[[body.region]]` scales, the display
/// surface as its contact surface, `kind = "particle"`.
pub fn add_body(
    world: &mut World,
    analysis: Analysis,
    material: &Material,
    name: &str,
    section: &BodySection,
    points: &[Point3<f64>],
    triangles: &[[u32; 3]],
) -> Result<AddedBody, String> {
    let velocity = Vector3::from(section.velocity);
    let handle = match &analysis {
        Analysis::Lattice(l) => {
            let handle = world.add_lattice_body(name, l, material, velocity);
            // The XPBD cells weigh and resist as much of them as the mesh fills; the papers'
            // integrators keep their whole cells.
            if world.settings.integrator == Integrator::Xpbd {
                if let Some(fill) = cell_fill(l, points, triangles) {
                    world.set_cell_fill(handle, &fill);
                }
            }
            handle
        }
        Analysis::Cage(c) => {
            // Mass from the mesh's enclosed volume when it is closed (module docs of `cage`).
            let volume = cage::mesh_volume(points, triangles);
            let closed = volume > 1e-3 * c.volume();
            c.add_to_world(world, name, material, closed.then_some(volume), velocity)
        }
    };
    for (i, r) in section.region.iter().enumerate() {
        let region = Region {
            min: Vector3::from(r.min),
            max: Vector3::from(r.max),
            mass_scale: r.mass_scale,
            stiffness_scale: r.stiffness_scale,
        };
        apply_region(world, handle, &region).map_err(|e| format!("region[{i}]: {e}"))?;
    }
    // The mesh, not its model, touches the floor, walls and manipulators.
    let samples = surface_samples_with_normals(points, triangles, 0.5 * analysis.spacing());
    let (normals, areas) = (&samples.normals, &samples.areas);
    let samples_at = &samples.points;
    let (embedding, lattice, model, note) = match analysis {
        Analysis::Lattice(l) => {
            world.add_contact_surface_with_normals(handle, &l, samples_at, areas, normals);
            (Embedding::new(&l, points), l, "lattice", None)
        }
        Analysis::Cage(c) => {
            c.add_contact_surface(world, handle, samples_at, areas);
            (c.embed(points), c.lattice_view(), c.model, c.note)
        }
    };
    if section.kind == BodyKind::Particle {
        let range = world.bodies[handle.0].nodes.clone();
        let particle = RigidBody::particle(handle.0, &world.nodes, range, world.settings.gravity)
            .ok_or("kind = \"particle\": the body has no mass")?;
        world.rigid.push(particle);
    }
    Ok(AddedBody {
        handle,
        embedding,
        lattice,
        model: model.to_string(),
        note,
    })
}

/// Bind the scene's `[[joint]]`s (after every body is in the world).
pub fn add_joints(
    scene: &SceneFile,
    world: &mut World,
    bodies: &[(Option<String>, String, BodyHandle)],
) -> Result<(), PipelineError> {
    for (i, j) in scene.joint.iter().enumerate() {
        let err = |message: String| PipelineError::Usage(format!("joint[{i}]: {message}"));
        if j.bodies.len() != 2 {
            return Err(err(format!(
                "bodies: expected two body names, got {}",
                j.bodies.len()
            )));
        }
        let find = |name: &str| {
            crate::simulate::find_body(bodies, name).map_err(|e| err(format!("bodies: {e}")))
        };
        let (a, b) = (find(&j.bodies[0])?, find(&j.bodies[1])?);
        if !j.at.iter().all(|x| x.is_finite()) {
            return Err(err("at: coordinates must be finite".into()));
        }
        join_bodies_at(world, a, b, Vector3::from(j.at)).map_err(|e| match e {
            // Name the body as the scene does.
            JointError::TooFar {
                which,
                distance_m,
                reach_m,
                ..
            } => err(format!(
                "at: body \"{}\"'s nearest node is {distance_m:.3} m away, farther than its \
                 longest spring there ({reach_m:.3} m): put `at` where the two bodies meet",
                j.bodies[which]
            )),
            e => err(e.to_string()),
        })?;
    }
    Ok(())
}

/// A `source = { superquadric = [...] }` body's mesh: the model polygonised
/// (`springbake_core::superquadric::shapes_surface`) as a one-mesh scene in Y-up metres, its
/// note (cells that may hide thin parts) kept. `path` names it in errors and outputs.
pub fn superquadric_scene(
    shapes: &springbake_core::superquadric::ShapesFile,
    name: &str,
    path: &std::path::Path,
) -> Result<springbake_core::display::ImportedScene, String> {
    use springbake_core::display::{DisplayMesh, ImportedScene, Primitive, SourceDocument, UpAxis};
    let (surface, note) = springbake_core::superquadric::shapes_surface(shapes)?;
    let f32s =
        |v: &[[f64; 3]]| -> Vec<[f32; 3]> { v.iter().map(|p| p.map(|c| c as f32)).collect() };
    let positions = f32s(&surface.positions);
    let count = positions.len();
    Ok(ImportedScene {
        materials: Vec::new(),
        notes: note.map(|n| format!("{name}: {n}")).into_iter().collect(),
        meshes: vec![DisplayMesh {
            name: name.to_owned(),
            source_key: "superquadrics".to_owned(),
            world_from_local: springbake_core::nalgebra::Matrix4::identity(),
            primitives: vec![Primitive {
                positions,
                normals: Some(f32s(&surface.normals)),
                uvs: None,
                indices: surface.triangles.iter().flatten().copied().collect(),
                material: None,
            }],
            source_point_of_vertex: Vec::new(),
            source_point_count: count,
        }],
        up_axis: UpAxis::Y,
        meters_per_unit: 1.0,
        source: SourceDocument {
            path: path.to_path_buf(),
            importer: "superquadrics".to_owned(),
            read_root: None,
        },
    })
}
