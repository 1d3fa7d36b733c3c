//! Scene-level contact: `[[collider]]` meshes from any importer, body–body contact between
//! `[[body]]`s, and clear errors for unusable colliders.
#![allow(clippy::unwrap_used)]

use springbake_core::solver::ContactPartner;
use springbake_pipeline::{default_registry, load_scene, prepare, Prepared, Seconds};
use std::path::Path;

/// An axis-aligned box OBJ from `lo` to `hi` (outward quads).
fn write_box(dir: &Path, file: &str, lo: [f64; 3], hi: [f64; 3]) {
    let mut obj = String::from("o Box\n");
    for c in 0..8 {
        let x = if c & 1 == 0 { lo[0] } else { hi[0] };
        let y = if c & 2 == 0 { lo[1] } else { hi[1] };
        let z = if c & 4 == 0 { lo[2] } else { hi[2] };
        obj += &format!("v {x} {y} {z}\n");
    }
    obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::write(dir.join(file), obj).unwrap();
}

fn prepared(dir: &Path, scene: &str) -> Result<Prepared, String> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let loaded = load_scene(&path).map_err(|e| e.to_string())?;
    prepare(&default_registry(), &loaded, &mut Seconds::default()).map_err(|e| e.to_string())
}

#[test]
fn a_cube_dropped_on_an_obj_collider_rests_on_it() {
    let dir = tempfile::tempdir().unwrap();
    write_box(dir.path(), "cube.obj", [-0.1, 0.0, -0.1], [0.1, 0.2, 0.1]);
    write_box(dir.path(), "table.obj", [-0.5, -0.3, -0.5], [0.5, 0.0, 0.5]);
    // No floor: only the table (top at y = 0.1 after its offset) holds the cube.
    let scene = "[world]\nfriction = 0.5\n\
                 [[body]]\nsource = \"cube.obj\"\ncells = 4\nmaterial = \"soft_rubber\"\n\
                 offset = [0.0, 0.4, 0.0]\n\
                 [[collider]]\nsource = \"table.obj\"\nname = \"table\"\noffset = [0.0, 0.1, 0.0]\n";
    let mut p = prepared(dir.path(), scene).unwrap();
    assert_eq!(p.world.colliders().len(), 1);
    assert_eq!(p.world.colliders()[0].name, "table");
    let h = p.world.settings.layer.thickness_m;
    let mut touched_at = None;
    for f in 2..=48 {
        p.world.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        let lowest = p
            .vertex_positions(0)
            .iter()
            .map(|v| v.y)
            .fold(f64::INFINITY, f64::min);
        assert!(
            lowest > 0.099,
            "frame {f}: the cube went into the table ({lowest} m)"
        );
        if touched_at.is_none() && !p.world.frame_contacts().is_empty() {
            touched_at = Some(f);
        }
    }
    // A 0.3 m fall (less the layer) takes about 0.24 s: frame 6 or 7.
    assert!(
        matches!(touched_at, Some(6..=8)),
        "first touch {touched_at:?}"
    );
    let lowest = p
        .vertex_positions(0)
        .iter()
        .map(|v| v.y)
        .fold(f64::INFINITY, f64::min);
    // XPBD holds the surface on the collider's face as a constraint (within rounding); the
    // contact is still logged through the layer's detection.
    assert!(
        lowest > 0.1 - 1e-9 && lowest < 0.1 + h,
        "resting on the table top (0.1 m), at most its layer ({h} m) above: {lowest} m"
    );
    let log = p.world.frame_contacts();
    assert_eq!(log.len(), 1, "{log:?}");
    assert_eq!(log[0].partner, ContactPartner::Collider(0));
    assert!(log[0].touching_at_end);
}

#[test]
fn two_bodies_of_a_scene_collide_and_part() {
    let dir = tempfile::tempdir().unwrap();
    write_box(dir.path(), "a.obj", [-0.3, 0.0, -0.1], [-0.1, 0.2, 0.1]);
    write_box(dir.path(), "b.obj", [0.1, 0.05, -0.1], [0.3, 0.25, 0.1]);
    let scene = "[world]\ngravity = 0.0\n\
                 [[body]]\nsource = \"a.obj\"\ncells = 4\nmaterial = \"soft_rubber\"\nvelocity = [2.0, 0.0, 0.0]\n\
                 [[body]]\nsource = \"b.obj\"\ncells = 4\nmaterial = \"soft_rubber\"\nvelocity = [-2.0, 0.0, 0.0]\n";
    let mut p = prepared(dir.path(), scene).unwrap();
    let mut impact = 0.0f64;
    for f in 2..=16 {
        p.world.advance_frame(1.0 / 24.0, f, &|| false).unwrap();
        for r in p.world.frame_contacts() {
            assert!(
                matches!(
                    (r.body, r.partner),
                    (0, ContactPartner::Body(1)) | (1, ContactPartner::Body(0))
                ),
                "{r:?}"
            );
            impact = impact.max(r.impact_speed);
        }
        // Where the faces meet (heights both boxes span: a's top corners, b's bottom ones),
        // a's display vertices stay left of b's and vice versa: the boxes stay axis-aligned
        // enough for a plane test between their faces. (Below b, a's face may flare past
        // b's: nothing is there.)
        let spans =
            |v: &&springbake_core::nalgebra::Point3<f64>, lo: f64, hi: f64| (lo..hi).contains(&v.y);
        let a_right = p
            .vertex_positions(0)
            .iter()
            .filter(|v| spans(v, 0.1, 0.3))
            .map(|v| v.x)
            .fold(f64::MIN, f64::max);
        let b_left = p
            .vertex_positions(1)
            .iter()
            .filter(|v| spans(v, -0.05, 0.15))
            .map(|v| v.x)
            .fold(f64::MAX, f64::min);
        assert!(
            a_right < b_left,
            "frame {f}: a reaches {a_right}, b starts at {b_left}"
        );
    }
    assert!(
        (impact - 4.0).abs() < 0.2,
        "closing speed 4 m/s, logged {impact}"
    );
    let v = |b: usize| {
        let r = p.world.bodies[b].nodes.clone();
        r.clone().map(|i| p.world.nodes.velocity[i].x).sum::<f64>() / r.len() as f64
    };
    assert!(v(0) < 0.0 && v(1) > 0.0, "they part: {} {}", v(0), v(1));
}

#[test]
fn unusable_colliders_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    write_box(dir.path(), "cube.obj", [-0.1, 0.0, -0.1], [0.1, 0.2, 0.1]);
    let body = "[[body]]\nsource = \"cube.obj\"\ncells = 3\n";
    let e = prepared(
        dir.path(),
        &format!("{body}[[collider]]\nsource = \"lane.xyz\"\n"),
    )
    .err()
    .unwrap();
    assert!(
        e.contains("collider[0]") && e.contains("lane.xyz") && e.contains("no importer"),
        "{e}"
    );
    let e = prepared(
        dir.path(),
        &format!("{body}[[collider]]\nsource = \"missing.obj\"\n"),
    )
    .err()
    .unwrap();
    assert!(
        e.contains("collider[0]") && e.contains("missing.obj"),
        "{e}"
    );
    let e = prepared(
        dir.path(),
        &format!("{body}[[collider]]\nsource = \"cube.obj\"\nfriction = -1.0\n"),
    )
    .err()
    .unwrap();
    assert!(e.contains("collider[0]") && e.contains("friction"), "{e}");
}
