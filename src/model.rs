//! `springbake model shapes.toml -o shape.glb`: polygonises a superquadric metaball model
//! (Terasawa §5.3; `springbake_core::superquadric`, `springbake_core::polygonise`) into a
//! watertight glTF mesh a DCC opens and a scene can bake.

use crate::Failure;
use springbake_core::superquadric::{shapes_surface, ShapesFile};
use std::path::Path;
use std::time::Instant;

pub fn run(shapes: &Path, output: &Path) -> Result<(), Failure> {
    let usage = |message: String| Failure { code: 2, message };
    let text = std::fs::read_to_string(shapes)
        .map_err(|e| usage(format!("{}: cannot read: {e}", shapes.display())))?;
    let file: ShapesFile = toml::from_str(&text).map_err(|e| {
        let at = e
            .span()
            .map(|s| {
                let line = text[..s.start].matches('\n').count() + 1;
                format!("line {line}: ")
            })
            .unwrap_or_default();
        usage(format!("{}: {at}{}", shapes.display(), e.message()))
    })?;
    let start = Instant::now();
    let (surface, note) =
        shapes_surface(&file).map_err(|e| usage(format!("{}: {e}", shapes.display())))?;
    let seconds = start.elapsed().as_secs_f64();
    if let Some(note) = note {
        eprintln!("springbake: note: {note}");
    }
    let f32s =
        |v: &[[f64; 3]]| -> Vec<[f32; 3]> { v.iter().map(|p| p.map(|c| c as f32)).collect() };
    let indices: Vec<u32> = surface.triangles.iter().flatten().copied().collect();
    let name = output
        .file_stem()
        .map_or_else(|| "model".to_owned(), |s| s.to_string_lossy().into_owned());
    let bytes = springbake_exporters::gltf::static_glb(&springbake_exporters::gltf::StaticMesh {
        name: &name,
        positions: &f32s(&surface.positions),
        normals: &f32s(&surface.normals),
        uv0: None,
        uv1: None,
        indices: &indices,
    });
    springbake_pipeline::write_outputs(
        &[springbake_core::plugin::OutputFile {
            path: output.to_path_buf(),
            bytes,
        }],
        &[shapes.to_path_buf()],
    )?;
    println!(
        "modelled {} triangles ({} vertices, cells {:.4} m, volume {:.6} m³, {}) in {seconds:.2} s: {}",
        surface.triangles.len(),
        surface.positions.len(),
        surface.cell,
        surface.volume(),
        if surface.is_watertight() { "watertight" } else { "open" },
        output.display()
    );
    Ok(())
}
