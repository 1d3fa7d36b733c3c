//! The built-in demo: a rubber ball dropped onto the floor and swept by the manipulator. The
//! mesh is generated (a UV sphere written as OBJ into a temporary folder), so `springbake demo`
//! needs no files.

use springbake_core::scene::{
    BodySection, Interpolation, ManipulatorKey, ManipulatorSection, MaterialSpec, SceneFile,
};
use springbake_core::shapes::uv_sphere;
use springbake_pipeline::LoadedScene;
use std::fmt::Write as _;
use std::path::Path;

/// Write the demo mesh into `dir` and return the demo scene writing to `output`.
pub fn demo_scene(dir: &Path, output: &Path) -> Result<LoadedScene, String> {
    let (points, triangles) = uv_sphere([0.0; 3], 0.3, 16, 32);
    let mut obj = String::from("# springbake demo ball\no Ball\n");
    for p in &points {
        let _ = writeln!(obj, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z);
    }
    for t in &triangles {
        let _ = writeln!(obj, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let source = dir.join("ball.obj");
    std::fs::write(&source, obj).map_err(|e| format!("{}: {e}", source.display()))?;
    let output = std::env::current_dir()
        .map(|d| d.join(output))
        .unwrap_or_else(|_| output.to_path_buf());

    let mut scene = SceneFile::default();
    scene.output.path = output;
    scene.output.fps = 24.0;
    scene.output.frames = 72;
    scene.world.floor = Some(0.0);
    scene.body.push(BodySection {
        cells: Some(8),
        material: MaterialSpec::Preset("rubber".into()),
        offset: [0.0, 0.6, 0.0],
        velocity: [0.3, 0.0, 0.0],
        ..BodySection::new(source)
    });
    scene.manipulator.push(ManipulatorSection {
        radius: 0.05,
        length: 0.8,
        keys: vec![
            ManipulatorKey {
                t: 0.0,
                position: [-1.5, 0.25, 0.0],
                yaw: 90.0,
            },
            ManipulatorKey {
                t: 0.8,
                position: [-1.0, 0.25, 0.0],
                yaw: 90.0,
            },
            ManipulatorKey {
                t: 1.6,
                position: [0.9, 0.25, 0.0],
                yaw: 90.0,
            },
        ],
        interpolation: Interpolation::Smooth,
        friction: 0.3,
    });
    Ok(LoadedScene {
        scene,
        scene_path: None,
        base_dir: dir.to_path_buf(),
    })
}
