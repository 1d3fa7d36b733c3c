//! Force fields from plug-ins (issue 22): a vectorised force on the nodes of the bodies a
//! field is bound to, `force(positions, velocities, masses, time) → forces` in newtons and
//! simulation metres, evaluated once per output frame (held over its substeps) or before
//! every substep, as the field declares. The forces only accumulate into
//! [`World::field_force`]; each integrator adds them where it adds gravity and wind.

use super::World;
use nalgebra::Vector3;
use std::ops::Range;
use std::sync::Arc;

type V3 = Vector3<f64>;

/// A force field (a plug-in's, or one built in Rust).
pub trait ForceField: Send + Sync {
    fn name(&self) -> &str;
    /// Whether it is evaluated before every substep (else once per output frame).
    fn per_substep(&self) -> bool;
    /// One force per node, N, or why not.
    fn force(
        &self,
        positions: &[V3],
        velocities: &[V3],
        masses: &[f64],
        time: f64,
    ) -> Result<Vec<V3>, String>;
}

/// A field acting on a range of the world's nodes (one body).
#[derive(Clone)]
pub struct FieldBinding {
    pub field: Arc<dyn ForceField>,
    pub nodes: Range<usize>,
}

impl std::fmt::Debug for FieldBinding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FieldBinding")
            .field("field", &self.field.name())
            .field("nodes", &self.nodes)
            .finish()
    }
}

/// Re-evaluates the bound fields of one timing (`per_substep`) into [`World::field_force`];
/// the first failure is kept in `World::field_error` and the field's force is dropped.
pub(crate) fn refresh(world: &mut World, per_substep: bool) {
    if world.fields.is_empty() {
        return;
    }
    let n = world.nodes.position.len();
    if world.field_force.len() != n {
        world.field_force = vec![V3::zeros(); n];
    }
    for binding in &world.fields {
        if binding.field.per_substep() != per_substep {
            continue;
        }
        let range = binding.nodes.clone();
        let nodes = &world.nodes;
        let result = binding.field.force(
            &nodes.position[range.clone()],
            &nodes.velocity[range.clone()],
            &nodes.mass[range.clone()],
            world.time,
        );
        match result {
            Ok(forces) if forces.len() == range.len() => {
                world.field_force[range].copy_from_slice(&forces);
            }
            Ok(forces) => {
                world.field_error.get_or_insert(format!(
                    "force field \"{}\" returned {} forces for {} nodes",
                    binding.field.name(),
                    forces.len(),
                    range.len()
                ));
            }
            Err(message) => {
                world.field_error.get_or_insert(format!(
                    "force field \"{}\": {message}",
                    binding.field.name()
                ));
            }
        }
    }
}
