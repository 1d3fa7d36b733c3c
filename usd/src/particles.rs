//! The bake's particle effects for the USD exporter: per emitter, its frames as flat arrays in
//! the stage's own units and up axis (the bake records Y-up metres), for the bridge's
//! `_author_particles` (one `UsdGeom.Points` per emitter, sampled every frame).

use crate::export::prim_name;
use crate::python::f32_bytes;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use springbake_core::bake::BakedScene;
use springbake_core::display::ImportedScene;
use springbake_core::nalgebra::Point3;
use std::collections::HashSet;

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
        for frame in &emitter.frames {
            let f = PyDict::new(py);
            let positions = frame.positions.iter().flat_map(|p| {
                let q =
                    to_stage.transform_point(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                [q.x as f32, q.y as f32, q.z as f32]
            });
            f.set_item("count", frame.ids.len())?;
            f.set_item("positions", PyBytes::new(py, &f32_bytes(positions)))?;
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
