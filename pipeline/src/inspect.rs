//! `springbake inspect` (and the Python package's `inspect`): what a mesh file holds, as
//! springbake reads it, and the lattice a bake would fit at a given resolution.

use crate::PipelineError;
use serde_json::{json, Value};
use springbake_core::lattice::{fit_lattice, FitSettings, Resolution};
use springbake_core::plugin::Registry;
use std::path::Path;

/// The file's format, up axis and unit, and per mesh: vertex, triangle and primitive counts,
/// materials, bounds in metres and the lattice fitted at `cells` along its longest side.
pub fn describe(registry: &Registry, file: &Path, cells: u32) -> Result<Value, PipelineError> {
    let importer = registry.importer_for(file).ok_or_else(|| {
        PipelineError::Usage(format!(
            "{}: no importer for this extension; springbake reads {}",
            file.display(),
            registry.import_extensions().join(", ")
        ))
    })?;
    let bytes = crate::source::read_source(file)
        .map_err(|e| PipelineError::Usage(format!("{}: {e}", file.display())))?;
    let scene = importer.import(file, &bytes, &Default::default())?;
    let mut meshes = Vec::new();
    for m in &scene.meshes {
        let points: Vec<_> = m
            .world_positions()
            .iter()
            .map(|p| p * scene.meters_per_unit)
            .collect();
        let (lo, hi) = points.iter().fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    [lo[0].min(p.x), lo[1].min(p.y), lo[2].min(p.z)],
                    [hi[0].max(p.x), hi[1].max(p.y), hi[2].max(p.z)],
                )
            },
        );
        let settings = FitSettings {
            resolution: Resolution::CellsAlongLongest(cells),
            up_index: scene.up_axis.index(),
            ..FitSettings::default()
        };
        let lattice = fit_lattice(&points, &m.triangles(), &settings).map_err(|e| {
            PipelineError::Usage(format!("{}: mesh \"{}\": {e}", file.display(), m.name))
        })?;
        meshes.push(json!({
            "name": m.name,
            "vertices": m.vertex_count(),
            "triangles": m.triangle_count(),
            "primitives": m.primitives.len(),
            "materials": m.primitives.iter().filter_map(|p| p.material.clone()).collect::<Vec<_>>(),
            "bounds_m": { "min": lo, "max": hi },
            "lattice": { "cells": lattice.cell_count(), "nodes": lattice.node_count(), "springs": lattice.springs.len(),
                          "islands": lattice.island_count, "cell_size_m": lattice.cell_size, "dims": lattice.dims },
        }));
    }
    Ok(json!({
        "file": file.display().to_string(),
        "format": importer.name(),
        "up_axis": format!("{:?}", scene.up_axis),
        "meters_per_unit": scene.meters_per_unit,
        "meshes": meshes,
    }))
}
