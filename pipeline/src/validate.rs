//! Physical ranges of a scene's numbers (issue 17, item 1 in part): every value the solver
//! takes from the scene file must be finite and in a range a bake can use, or the scene is
//! refused before any work with the key and the allowed range in the message (exit 2).
//! Without it, NaN gravity ran to a non-finite error frames later, 1e30 m/s² ran without end,
//! and walls with min > max trapped the bodies in an empty room.

use springbake_core::scene::{SceneFile, SubstepSpec};

/// Most output frames a bake may ask for (a day at 24 frames/s is 2 073 600).
pub const MAX_FRAMES: usize = 10_000_000;
/// Most substeps per output frame a scene may ask for (`[solver] substeps`).
pub const MAX_FIXED_SUBSTEPS: u32 = 100_000;
/// Largest gravity, m/s² (a hundred times Jupiter's).
const MAX_GRAVITY: f64 = 1000.0;
/// Farthest a body may be moved, m (beyond it single-precision meshes lose their shape).
const MAX_DISTANCE: f64 = 1.0e6;
/// Largest initial speed of a body, m/s.
const MAX_SPEED: f64 = 1.0e4;
/// Young's modulus range, Pa (softer than any gel; stiffer than diamond).
const YOUNG: (f64, f64) = (1.0, 1.0e13);
/// Density range, kg/m³ (aerogel to osmium, with margin).
const DENSITY: (f64, f64) = (0.1, 1.0e5);

fn finite3(key: &str, v: &[f64; 3]) -> Result<(), String> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(format!("{key} must be finite, got {v:?}"))
    }
}

fn within(key: &str, value: f64, lo: f64, hi: f64, unit: &str) -> Result<(), String> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(format!(
            "{key} must be between {lo} and {hi} {unit}, got {value}"
        ))
    }
}

fn positive(key: &str, value: f64, unit: &str) -> Result<(), String> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(format!(
            "{key} must be a finite number > 0 {unit}, got {value}"
        ))
    }
}

/// The scene's numbers in their physical ranges (module docs); `world.floor` is checked by
/// [`floor`] (a bare mesh's bake leaves it NaN for "automatic").
pub fn numbers(scene: &SceneFile) -> Result<(), String> {
    for (i, e) in scene.emitter.iter().enumerate() {
        e.check(&format!("emitter[{i}]"))?;
    }
    if scene.output.frames > MAX_FRAMES {
        return Err(format!(
            "output.frames must be at most {MAX_FRAMES}, got {}",
            scene.output.frames
        ));
    }
    within("output.fps", scene.output.fps, 1e-3, 1e4, "frames/s")?;
    cache(&scene.output)?;
    let w = &scene.world;
    within("world.gravity", w.gravity, 0.0, MAX_GRAVITY, "m/s²")?;
    if let Some(room) = &w.walls {
        finite3("world.walls.min", &room.min)?;
        finite3("world.walls.max", &room.max)?;
        if let Some(axis) = (0..3).find(|&a| room.min[a] >= room.max[a]) {
            return Err(format!(
                "world.walls: min must be below max on every axis, axis {} has min {} and max {}",
                ["x", "y", "z"][axis],
                room.min[axis],
                room.max[axis]
            ));
        }
    }
    if let Some(t) = w.contact_thickness {
        positive("world.contact_thickness", t, "m")?;
    }
    if let Some(k) = w.contact_stiffness {
        positive("world.contact_stiffness", k, "N/m")?;
    }
    if let Some(wind) = &w.wind {
        finite3("world.wind.velocity", &wind.velocity)?;
        finite3("world.wind.gust", &wind.gust)?;
        within("world.wind.gust_hz", wind.gust_hz, 0.0, 1.0e3, "Hz")?;
        within("world.wind.drag_per_s", wind.drag_per_s, 0.0, 1.0e4, "1/s")?;
    }
    let s = &scene.solver;
    positive("solver.accuracy_n", s.accuracy_n, "")?;
    if let SubstepSpec::Fixed(n) = s.substeps {
        if n > MAX_FIXED_SUBSTEPS {
            return Err(format!(
                "solver.substeps must be at most {MAX_FIXED_SUBSTEPS} per frame, got {n}"
            ));
        }
    }
    for (i, b) in scene.body.iter().enumerate() {
        finite3(&format!("body[{i}].offset"), &b.offset)?;
        for (axis, &x) in b.offset.iter().enumerate() {
            within(
                &format!("body[{i}].offset[{axis}]"),
                x,
                -MAX_DISTANCE,
                MAX_DISTANCE,
                "m",
            )?;
        }
        finite3(&format!("body[{i}].velocity"), &b.velocity)?;
        let speed = b.velocity.iter().map(|v| v * v).sum::<f64>().sqrt();
        within(
            &format!("body[{i}].velocity (speed)"),
            speed,
            0.0,
            MAX_SPEED,
            "m/s",
        )?;
        if let Ok(m) = b.material.resolve() {
            let key = format!("body[{i}].material");
            within(&format!("{key}.young"), m.young_pa, YOUNG.0, YOUNG.1, "Pa")?;
            within(
                &format!("{key}.density"),
                m.density_kg_m3,
                DENSITY.0,
                DENSITY.1,
                "kg/m³",
            )?;
        }
    }
    for (i, m) in scene.manipulator.iter().enumerate() {
        positive(&format!("manipulator[{i}].radius"), m.radius, "m")?;
        within(
            &format!("manipulator[{i}].length"),
            m.length,
            0.0,
            1.0e4,
            "m",
        )?;
        within(
            &format!("manipulator[{i}].friction"),
            m.friction,
            0.0,
            100.0,
            "",
        )?;
        for (k, key) in m.keys.iter().enumerate() {
            let name = format!("manipulator[{i}].keys[{k}]");
            if !(key.t.is_finite() && key.yaw.is_finite()) {
                return Err(format!(
                    "{name}: t and yaw must be finite, got t = {}, yaw = {}",
                    key.t, key.yaw
                ));
            }
            finite3(&format!("{name}.position"), &key.position)?;
        }
    }
    Ok(())
}

/// `world.floor` of a scene file: finite when given.
pub fn floor(scene: &SceneFile) -> Result<(), String> {
    match scene.world.floor {
        Some(h) if !h.is_finite() => Err(format!("world.floor must be finite, got {h}")),
        _ => Ok(()),
    }
}

/// `output.cache`, `output.cache_axes` and `output.max_error` against the output's format.
fn cache(o: &springbake_core::scene::OutputSection) -> Result<(), String> {
    use springbake_core::scene::CacheSpec;
    let gltf = o
        .path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    let name = match o.cache {
        CacheSpec::Morph => None,
        CacheSpec::Skin => Some("skin"),
        CacheSpec::Pca => Some("pca"),
    };
    if let (Some(name), false) = (name, gltf) {
        return Err(format!(
            "output.cache = \"{name}\" is for glTF outputs (.glb, .gltf), not {}",
            o.path.display()
        ));
    }
    let point_cache = o
        .path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("pc2") || e.eq_ignore_ascii_case("mdd"));
    if o.cache_axes != springbake_core::scene::CacheAxesSpec::Blender && !point_cache {
        return Err("output.cache_axes: only for point caches (.pc2, .mdd outputs)".into());
    }
    if let Some(m) = o.max_error {
        if o.cache != CacheSpec::Pca {
            return Err("output.max_error: only with cache = \"pca\"".into());
        }
        within("output.max_error", m, 1e-6, 1.0, "m")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(extra: &str) -> SceneFile {
        let text = format!("[output]\npath = \"o.glb\"\n{extra}\n[[body]]\nsource = \"m.obj\"\n");
        SceneFile::parse(&text).unwrap()
    }

    #[test]
    fn nonsense_numbers_are_refused_with_their_key() {
        for (extra, key) in [
            ("[world]\ngravity = nan", "world.gravity"),
            ("[world]\ngravity = 1e30", "world.gravity"),
            (
                "[world]\ncontact_thickness = 0.0",
                "world.contact_thickness",
            ),
            (
                "[world.walls]\nmin = [1.0, 0.0, 0.0]\nmax = [0.0, 1.0, 1.0]",
                "world.walls",
            ),
            (
                "[world.wind]\nvelocity = [nan, 0.0, 0.0]",
                "world.wind.velocity",
            ),
            ("[solver]\naccuracy_n = 0.0", "solver.accuracy_n"),
            ("[solver]\nsubsteps = 1000000000", "solver.substeps"),
        ] {
            let err = numbers(&scene(extra)).unwrap_err();
            assert!(err.starts_with(key), "{extra}: {err}");
        }
        let mut s = scene("");
        s.output.frames = usize::MAX;
        assert!(numbers(&s).unwrap_err().starts_with("output.frames"));
        s.output.frames = 72;
        s.body[0].velocity = [1e20, 0.0, 0.0];
        assert!(numbers(&s).unwrap_err().contains("body[0].velocity"));
        s.body[0].velocity = [0.0; 3];
        assert_eq!(numbers(&s), Ok(()));
        s.world.floor = Some(f64::NAN);
        assert!(floor(&s).unwrap_err().starts_with("world.floor"));
    }
}
