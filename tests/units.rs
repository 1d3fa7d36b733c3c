//! The source's unit: a model made in centimetres and written as metres (an OBJ has no unit;
//! Blender's USD export of a centimetre scene writes `metersPerUnit = 1`) is named before
//! the bake by its size, and given its unit (`--meters-per-unit`, or `meters_per_unit` on
//! a body) it falls as the thing it is, the cache keeping the file's numbers.
#![allow(clippy::unwrap_used)]

mod support;

use support::{springbake_in, stderr, succeeded};

/// A 20 cm cube written in centimetres, its bottom 60 cm up, as an OBJ.
fn centimetre_cube(dir: &std::path::Path) {
    let (points, triangles) =
        springbake_core::shapes::box_mesh([0.0, 60.0, 0.0], [20.0, 80.0, 20.0]);
    std::fs::write(
        dir.join("cube.obj"),
        support::obj_text("Cube", (points, triangles)),
    )
    .unwrap();
}

/// The lowest point of each frame of a PC2 cache, in the file's numbers.
fn lowest(dir: &std::path::Path, pc2: &str) -> Vec<f32> {
    let bytes = std::fs::read(dir.join(pc2)).unwrap();
    (support::pc2_frames(&bytes).iter())
        .map(|points| points.iter().map(|p| p[1]).fold(f32::MAX, f32::min))
        .collect()
}

#[test]
fn a_centimetre_model_given_its_unit_falls_at_its_real_size() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    centimetre_cube(d);
    let bake = |extra: &[&str], out: &str| {
        let mut args = vec!["bake", "cube.obj", "-o", out, "--frames", "12"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--progress", "quiet"]);
        let o = springbake_in(d, &args);
        succeeded(&o);
        stderr(&o)
    };
    // Read as metres: a 20 m cube 60 m up, named with the time it takes to fall its height.
    let err = bake(&[], "metres.pc2");
    assert!(
        err.contains("body \"Cube\" is 20.0 m across (the source's unit is 1 m)")
            && err.contains("falling its own height takes 2.0 s")
            && err.contains("--meters-per-unit 0.01"),
        "{err}"
    );
    let slow = lowest(d, "metres.pc2");
    // Half a second of a 60 m fall: still more than 58 m up.
    assert!(slow[11] > 58.0, "{slow:?}");

    // Given its unit: no note, and the fall of a 20 cm cube from 60 cm.
    let err = bake(&["--meters-per-unit", "0.01"], "centimetres.pc2");
    assert!(!err.contains("across"), "{err}");
    let real = lowest(d, "centimetres.pc2");
    assert!(
        (real[0] - 60.0).abs() < 1e-3,
        "the cache keeps the file's numbers: {real:?}"
    );
    // Free fall in centimetres (g = 981 cm/s²) until it meets the floor at 0.35 s, between
    // the frames at 1/3 and 3/8 s, and bounces.
    for (k, y) in real.iter().enumerate().take(9) {
        let t = k as f32 / 24.0;
        assert!(
            (y - (60.0 - 490.5 * t * t)).abs() < 0.5,
            "frame {k}: {real:?}"
        );
    }
    assert!(real[9] < 3.0 && real[11] > real[9], "{real:?}");

    // The scene file's key does what the flag does, to the byte.
    std::fs::write(
        d.join("cube.toml"),
        "[output]\npath = \"scene.pc2\"\nframes = 12\n[world]\nfloor = 0.0\n\
         [[body]]\nsource = \"cube.obj\"\nmeters_per_unit = 0.01\n",
    )
    .unwrap();
    let o = springbake_in(d, &["bake", "cube.toml", "--progress", "quiet"]);
    succeeded(&o);
    assert_eq!(
        std::fs::read(d.join("scene.pc2")).unwrap(),
        std::fs::read(d.join("centimetres.pc2")).unwrap()
    );
}

#[test]
fn a_unit_out_of_range_and_bare_mesh_flags_on_a_scene_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    centimetre_cube(d);
    let o = springbake_in(d, &["bake", "cube.obj", "--meters-per-unit", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("meters_per_unit must be between"),
        "{}",
        stderr(&o)
    );
    std::fs::write(
        d.join("cube.toml"),
        "[output]\npath = \"scene.pc2\"\nframes = 2\n[[body]]\nsource = \"cube.obj\"\n",
    )
    .unwrap();
    for (flag, value, key) in [
        ("--cells", "4", "`cells`"),
        ("--material", "jelly", "`material`"),
        ("--meters-per-unit", "0.01", "`meters_per_unit`"),
    ] {
        let o = springbake_in(d, &["bake", "cube.toml", flag, value]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let err = stderr(&o);
        assert!(
            err.contains(&format!("cube.toml: {flag} is for a bare mesh"))
                && err.contains(&format!("set {key} on each [[body]]")),
            "{err}"
        );
        assert!(!d.join("scene.pc2").exists());
    }
}

/// A kit of parts made in centimetres and written as metres (five 20 m boxes) gets one size
/// note naming three and counting the rest, not one per part.
#[test]
fn a_kit_of_large_parts_shares_one_size_note() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("kit.obj"), support::row_of_boxes(30.0, 50.0, 20.0)).unwrap();
    let err = support::bake_file(d, "kit.obj", "kit.pc2", "2");
    assert_eq!(err.matches("m across").count(), 1, "{err}");
    assert!(
        err.contains(
            "5 bodies are over 10 m across (\"Part0\", \"Part1\", \"Part2\" and 2 more; the \
             largest 20.0 m; the source's unit is 1 m)"
        ) && err.contains("--meters-per-unit 0.01"),
        "{err}"
    );
}

/// A model standing on the ground whose lowest point a DCC rounded a hair below 0
/// (usd-wg's Teapot: -7e-9 m) keeps standing there: the automatic floor stays at 0 instead
/// of going 5 % of the model's height under it and dropping the model onto it.
#[test]
fn a_model_rounded_a_hair_below_the_ground_stays_on_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (points, triangles) = springbake_core::shapes::box_mesh([0.0, -1e-8, 0.0], [0.2, 0.2, 0.2]);
    std::fs::write(
        d.join("cube.obj"),
        support::obj_text("Cube", (points, triangles)),
    )
    .unwrap();
    support::bake_file(d, "cube.obj", "cube.pc2", "24");
    let low = lowest(d, "cube.pc2");
    // Resting on a floor at 0 (within the contact's give), not 1 cm under it.
    assert!(low.iter().all(|&y| y > -2e-3), "{low:?}");
}
