//! Body–body and collider contact from the scene: each body's display surface is registered for
//! contact with the others (`World::add_collision_surface`), `[world] contact` picks the
//! response, and every `[[collider]]` is imported through the registry (any format), converted
//! to the simulation frame like a body (units, up axis, `offset`) and added as one static
//! triangle mesh per file.

use crate::frame::SimFrame;
use crate::simulate::PreparedBody;
use crate::{LoadedScene, PipelineError};
use springbake_core::collide::StaticCollider;
use springbake_core::display::ImportedScene;
use springbake_core::nalgebra::{Matrix4, Point3, Vector3};
use springbake_core::plugin::Registry;
use springbake_core::scene::ContactSpec;
use springbake_core::solver::{ContactModel, World};

/// Wire the scene's contact model, the bodies' collision surfaces and the colliders.
pub(crate) fn wire(
    registry: &Registry,
    loaded: &LoadedScene,
    frame: &SimFrame,
    world: &mut World,
    bodies: &[PreparedBody],
    export_scene: &ImportedScene,
) -> Result<(), PipelineError> {
    world.set_contact_model(match loaded.scene.world.contact {
        ContactSpec::Layer => ContactModel::ElasticLayer,
        ContactSpec::Hertz => ContactModel::Hertz,
    });
    // Bodies touch each other only when there is more than one (or a collider).
    if bodies.len() > 1 || !loaded.scene.collider.is_empty() {
        for b in bodies {
            let Some(mesh) = export_scene.meshes.get(b.mesh_index) else {
                continue;
            };
            let rest = b.embedding.points(&b.lattice.rest_positions);
            let triangles = mesh.triangles();
            if b.lattice.cells.is_empty() {
                // A cage model: its own embedding of the display vertices.
                let spacing = b.lattice.cell_size;
                world.add_embedded_collision_surface(
                    b.handle,
                    &b.embedding,
                    &rest,
                    &triangles,
                    spacing,
                );
            } else {
                world.add_collision_surface(b.handle, &b.lattice, &rest, &triangles);
            }
        }
    }
    for (i, section) in loaded.scene.collider.iter().enumerate() {
        let path = loaded.base_dir.join(&section.source);
        let err = |message: String| {
            let message = format!("collider[{i}] ({}): {message}", section.source.display());
            match &loaded.scene_path {
                Some(scene) => PipelineError::Scene {
                    path: scene.clone(),
                    message,
                },
                None => PipelineError::Usage(message),
            }
        };
        let importer = registry.importer_for(&path).ok_or_else(|| {
            err(format!(
                "no importer for this extension; springbake reads {}",
                registry.import_extensions().join(", ")
            ))
        })?;
        let bytes = loaded.read_source(&path).map_err(err)?;
        let source = importer.import(&path, &bytes, &loaded.import_settings())?;
        let sim_from_source = frame.sim_from_source(source.up_axis, source.meters_per_unit);
        let offset = Matrix4::new_translation(&Vector3::from(section.offset));
        let (mut points, mut triangles) = (Vec::new(), Vec::new());
        for mesh in &source.meshes {
            let sim_from_local = offset * sim_from_source * mesh.world_from_local;
            let base = points.len() as u32;
            points.extend(
                mesh.primitives
                    .iter()
                    .flat_map(|p| p.positions.iter())
                    .map(|q| {
                        sim_from_local.transform_point(&Point3::new(
                            q[0] as f64,
                            q[1] as f64,
                            q[2] as f64,
                        ))
                    }),
            );
            triangles.extend(mesh.triangles().iter().map(|t| t.map(|v| v + base)));
        }
        let name = section.name.clone().unwrap_or_else(|| {
            section
                .source
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| format!("collider{i}"))
        });
        let collider = StaticCollider::new(name, &points, &triangles, section.friction)
            .map_err(|e| err(e.to_string()))?;
        world.add_collider(collider);
    }
    Ok(())
}
