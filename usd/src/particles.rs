//! The bake's particle effects for the USD exporter: per emitter, its frames as flat arrays in
//! the stage's own units and up axis (the bake records Y-up metres), for the bridge's
//! `_author_particles` (one `UsdGeom.Points` per emitter, sampled every frame, and for an
//! emitter drawn with streaks a `UsdGeom.BasisCurves` of one segment per particle).

use crate::export::prim_name;
use crate::python::f32_bytes;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use springbake_core::bake::BakedScene;
use springbake_core::display::ImportedScene;
use springbake_core::nalgebra::Point3;
use std::collections::{HashMap, HashSet};

/// How much of a frame's travel a streak spans behind its particle (a 180° shutter).
pub const STREAK_SHUTTER: f32 = 0.5;

/// Per particle, the tail of its streak: back along its travel since the previous frame by
/// [`STREAK_SHUTTER`] of it (the particle itself, a point, in the frame it is born).
fn streak_tails(
    ids: &[u64],
    positions: &[[f32; 3]],
    previous: &HashMap<u64, [f32; 3]>,
) -> Vec<[f32; 3]> {
    ids.iter()
        .zip(positions)
        .map(|(id, p)| match previous.get(id) {
            Some(q) => std::array::from_fn(|k| p[k] - (p[k] - q[k]) * STREAK_SHUTTER),
            None => *p,
        })
        .collect()
}

/// The `particles` list of the bridge's spec (empty without emitters).
pub fn particles_spec<'py>(
    py: Python<'py>,
    scene: &ImportedScene,
    baked: &BakedScene,
) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    let to_y_up = scene.y_up_metres_from_world();
    let to_stage = to_y_up.try_inverse().unwrap_or(to_y_up);
    let unit = 1.0 / scene.meters_per_unit.max(f64::MIN_POSITIVE);
    let mut taken = HashSet::new();
    for emitter in &baked.particles {
        let d = PyDict::new(py);
        d.set_item("prim", prim_name(&emitter.name, &mut taken))?;
        d.set_item("colour", [0.85f32, 0.85, 0.85])?;
        let frames = PyList::empty(py);
        d.set_item("streaks", emitter.streaks)?;
        let mut previous: HashMap<u64, [f32; 3]> = HashMap::new();
        for frame in &emitter.frames {
            let f = PyDict::new(py);
            let positions: Vec<[f32; 3]> = frame
                .positions
                .iter()
                .map(|p| {
                    let q = to_stage.transform_point(&Point3::new(
                        p[0] as f64,
                        p[1] as f64,
                        p[2] as f64,
                    ));
                    [q.x as f32, q.y as f32, q.z as f32]
                })
                .collect();
            if emitter.streaks {
                // Each segment tail then head, each end as wide as the particle.
                let tails = streak_tails(&frame.ids, &positions, &previous);
                let ends = tails
                    .iter()
                    .zip(&positions)
                    .flat_map(|(t, h)| t.iter().chain(h));
                f.set_item("streak_points", PyBytes::new(py, &f32_bytes(ends.copied())))?;
                let widths = frame.widths.iter().flat_map(|w| {
                    let w = (*w as f64 * unit) as f32;
                    [w, w]
                });
                f.set_item("streak_widths", PyBytes::new(py, &f32_bytes(widths)))?;
                previous = frame
                    .ids
                    .iter()
                    .copied()
                    .zip(positions.iter().copied())
                    .collect();
            }
            f.set_item("count", frame.ids.len())?;
            f.set_item(
                "positions",
                PyBytes::new(py, &f32_bytes(positions.into_iter().flatten())),
            )?;
            let widths = frame.widths.iter().map(|w| (*w as f64 * unit) as f32);
            f.set_item("widths", PyBytes::new(py, &f32_bytes(widths)))?;
            let ids: Vec<u8> = frame
                .ids
                .iter()
                .flat_map(|i| (*i as i64).to_le_bytes())
                .collect();
            f.set_item("ids", PyBytes::new(py, &ids))?;
            f.set_item(
                "opacities",
                PyBytes::new(py, &f32_bytes(frame.opacities.iter().copied())),
            )?;
            frames.append(f)?;
        }
        d.set_item("frames", frames)?;
        list.append(d)?;
    }
    Ok(list)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_streak_trails_half_a_frame_of_travel_and_a_newborn_is_a_point() {
        let previous = HashMap::from([(7, [0.0, 2.0, 0.0])]);
        let tails = streak_tails(&[7, 8], &[[1.0, 1.0, 0.0], [5.0, 5.0, 5.0]], &previous);
        assert_eq!(tails, vec![[0.5, 1.5, 0.0], [5.0, 5.0, 5.0]]);
    }
}
