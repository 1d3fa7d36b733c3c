//! A bake's budget (issue 17, item 2), checked after the models are built and before the first
//! step: the memory the run will need against `--max-memory` (or what the machine has free),
//! and the substeps per frame against a cap, each refused with what drives it and what to
//! change (exit code 2) instead of an abort by the allocator or a run without end.
//!
//! The figures are measured, not guessed (peak resident memory of `springbake bake` on a cube
//! at 40 and 60 cells and on an icosphere at 100 and 800 frames, this machine, 2026-12-01):
//! per node, the world, its prepared solver and the fit, by integrator; per vertex and output
//! frame, the recorded frame plus the exporter's buffers, by output format.

use crate::simulate::Prepared;
use crate::PipelineError;
use springbake_core::scene::{IntegratorSpec, SceneFile};
use std::path::Path;

/// Bytes per simulated node at peak, measured and rounded up by about a fifth: XPBD 1.1 KB,
/// symplectic Euler 1.6 KB, Newmark 2.2 KB (68 921 nodes).
fn bytes_per_node(integrator: IntegratorSpec) -> u64 {
    match integrator {
        IntegratorSpec::Xpbd => 1400,
        IntegratorSpec::SymplecticEuler => 2000,
        IntegratorSpec::Newmark => 2700,
    }
}

/// Bytes per display vertex and output frame at peak, by output format (measured: glTF 76,
/// point caches 35, USD 112, plus usd-core's own 100 MB; a glTF of principal components 115:
/// the fit keeps the displacements and their residual beside the frames).
fn bytes_per_vertex_frame(scene: &SceneFile, output: &Path) -> (u64, u64) {
    use springbake_core::scene::CacheSpec;
    match extension(output).as_str() {
        "pc2" | "mdd" => (40, 0),
        "usda" | "usdc" | "usd" | "usdz" => (128, 160 << 20),
        _ if scene.output.cache == CacheSpec::Pca => (128, 0),
        _ => (88, 0),
    }
}

/// The output's extension, lower case (`""` without one).
fn extension(output: &Path) -> String {
    output
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Memory every run needs besides the bake (the binary, its libraries, the imported scene).
const BASE_BYTES: u64 = 64 << 20;

/// Most substeps per output frame the automatic choice may ask for; beyond it a bake takes
/// hours for what a user sees as a few seconds of motion.
pub const MAX_AUTO_SUBSTEPS_PER_FRAME: u32 = 20_000;

/// The memory limit of this run: `requested` (`--max-memory`), else `SPRINGBAKE_MAX_MEMORY`,
/// else nine tenths of the memory the machine has available now (Linux `MemAvailable`), else
/// 16 GiB.
pub fn memory_limit(requested: Option<u64>) -> u64 {
    requested
        .or_else(|| {
            std::env::var("SPRINGBAKE_MAX_MEMORY")
                .ok()
                .and_then(|v| parse_size(&v).ok())
        })
        .or_else(|| available_memory().map(|b| b / 10 * 9))
        .unwrap_or(16 << 30)
}

/// `MemAvailable` from `/proc/meminfo`, bytes.
fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// A size such as `512M`, `4G`, `1.5GiB` or a plain number of bytes.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("\"{text}\" is not a size (e.g. 512M, 4G)"))?;
    let scale: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" | "kib" => 1024.0,
        "m" | "mb" | "mib" => 1024.0 * 1024.0,
        "g" | "gb" | "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tb" | "tib" => 1024.0_f64.powi(4),
        other => {
            return Err(format!(
                "\"{text}\": unknown unit \"{other}\" (use K, M, G or T)"
            ))
        }
    };
    let bytes = value * scale;
    if !(1.0..1.0e18).contains(&bytes) {
        return Err(format!("\"{text}\" is not a usable size"));
    }
    Ok(bytes as u64)
}

/// Display vertices of every simulated body (what each output frame records).
fn display_vertices(prepared: &Prepared) -> u64 {
    prepared
        .bodies
        .iter()
        .filter_map(|b| prepared.export_scene.meshes.get(b.mesh_index))
        .map(|m| m.vertex_count() as u64)
        .sum()
}

/// The bake's estimated peak memory, bytes, and a sentence naming what it is made of.
pub fn estimate_memory(prepared: &Prepared, scene: &SceneFile, output: &Path) -> (u64, String) {
    let nodes = prepared.world.nodes.len() as u64;
    let vertices = display_vertices(prepared);
    let frames = scene.output.frames as u64;
    let (per_vertex_frame, exporter_base) = bytes_per_vertex_frame(scene, output);
    let world = nodes.saturating_mul(bytes_per_node(scene.solver.integrator));
    let baked = vertices
        .saturating_mul(frames)
        .saturating_mul(per_vertex_frame);
    let total = BASE_BYTES
        .saturating_add(exporter_base)
        .saturating_add(world)
        .saturating_add(baked);
    let what = format!(
        "{nodes} nodes ({} MiB) and {frames} frames of {vertices} vertices ({} MiB)",
        world >> 20,
        baked >> 20
    );
    (total, what)
}

/// Outputs larger than this get a note before the bake starts.
pub const LARGE_OUTPUT_BYTES: u64 = 100 << 20;

/// Bytes on disk per display vertex and output frame, by format (measured: a glTF morph
/// target holds a position and a normal delta, 24 bytes, 25.3 with the accessors on a 960
/// vertex icosphere over 120 frames; a point cache 12; USD crate files about 24, text 60).
/// `None` where the size does not grow that way (the skin and compact caches).
fn disk_bytes_per_vertex_frame(scene: &SceneFile, output: &Path) -> Option<f64> {
    use springbake_core::scene::CacheSpec;
    match extension(output).as_str() {
        "pc2" | "mdd" => Some(12.0),
        "usda" => Some(60.0),
        "usdc" | "usd" | "usdz" => Some(24.0),
        _ if scene.output.cache == CacheSpec::Morph => Some(25.3),
        _ => None,
    }
}

/// A note for bakes whose output will be over [`LARGE_OUTPUT_BYTES`]: its expected size,
/// what makes it, and what makes it smaller.
pub fn large_output_note(prepared: &Prepared, scene: &SceneFile, output: &Path) -> Option<String> {
    let per = disk_bytes_per_vertex_frame(scene, output)?;
    let vertices = display_vertices(prepared);
    let frames = scene.output.frames as u64;
    let bytes = (vertices * frames) as f64 * per;
    if bytes < LARGE_OUTPUT_BYTES as f64 {
        return None;
    }
    let gltf = matches!(
        output.extension().and_then(|e| e.to_str()),
        Some("glb" | "gltf")
    );
    let smaller = if gltf {
        "--cache pca (the motion's principal components) or --cache skin (the lattice as joints) ([output] cache in a scene file), or fewer frames"
    } else {
        "a glTF output (.glb) with --cache pca or --cache skin, or fewer frames"
    };
    Some(format!(
        "{}: the output will be about {:.0} MB ({vertices} vertices × {frames} frames); {smaller} make it smaller",
        output.display(),
        bytes / 1e6
    ))
}

/// Bodies smaller than this (largest lattice side, metres) get a note: usually a unit slip
/// (a centimetre USD stage, a millimetre CAD export), not a 3 cm prop.
pub const SMALL_BODY_M: f64 = 0.05;
/// Bodies larger than this get a note too: usually the other slip (a model made in
/// centimetres or millimetres written as metres: Blender's USD export of a centimetre scene
/// writes its numbers with `metersPerUnit = 1`), not a 10 m soft body.
pub const LARGE_BODY_M: f64 = 10.0;

/// A note per body smaller than [`SMALL_BODY_M`] or larger than [`LARGE_BODY_M`]: its size in
/// metres and the unit the source was read in, so a unit slip is seen before the bake rather
/// than after (a large one as the slow fall it gives). Past [`MAX_NAMED_BODIES`] of a kind
/// (a kit of parts written in the wrong unit), one note names the first and counts the rest.
pub fn body_size_notes(prepared: &Prepared) -> Vec<String> {
    let unit = prepared.export_scene.meters_per_unit;
    let gravity = prepared.world.settings.gravity.norm();
    let sized: Vec<(String, f64)> = prepared
        .bodies
        .iter()
        .map(|b| {
            let size = b
                .lattice
                .dims
                .iter()
                .map(|&d| f64::from(d) * b.lattice.cell_size)
                .fold(0.0, f64::max);
            (format!("\"{}\"", b.name), size)
        })
        .collect();
    let small: Vec<&(String, f64)> = sized
        .iter()
        .filter(|(_, size)| *size > 0.0 && *size < SMALL_BODY_M)
        .collect();
    let large: Vec<&(String, f64)> = sized.iter().filter(|(_, s)| *s > LARGE_BODY_M).collect();
    let small_advice = "if the model should be bigger, scale it in the source or give its \
                        unit (`meters_per_unit` on the body, `--meters-per-unit` for a bare mesh)";
    let large_advice = format!("{}, or scale it in the source", smaller_unit_advice(unit));
    let fall = |size: f64, who: &str| {
        if gravity > 0.0 {
            format!(
                ", and {who} its own height takes {:.1} s",
                (2.0 * size / gravity).sqrt()
            )
        } else {
            String::new()
        }
    };
    let mut notes = Vec::new();
    if small.len() <= MAX_NAMED_BODIES {
        notes.extend(small.iter().map(|(name, size)| {
            format!(
                "body {name} is {} across (the source's unit is {unit} m): it is simulated at \
                 that real size; {small_advice}",
                small_length(*size)
            )
        }));
    } else {
        let named: Vec<String> = small.iter().map(|b| b.0.clone()).collect();
        let least = small.iter().map(|b| b.1).fold(f64::MAX, f64::min);
        notes.push(format!(
            "{} bodies are under {:.0} cm across ({}; the smallest {}; the source's unit is \
             {unit} m): they are simulated at that real size; {small_advice}",
            small.len(),
            SMALL_BODY_M * 100.0,
            first_and_count(&named),
            small_length(least)
        ));
    }
    if large.len() <= MAX_NAMED_BODIES {
        notes.extend(large.iter().map(|(name, size)| {
            format!(
                "body {name} is {size:.1} m across (the source's unit is {unit} m): it is \
                 simulated at that real size{}; {large_advice}",
                fall(*size, "falling")
            )
        }));
    } else {
        let named: Vec<String> = large.iter().map(|b| b.0.clone()).collect();
        let most = large.iter().map(|b| b.1).fold(0.0, f64::max);
        notes.push(format!(
            "{} bodies are over {LARGE_BODY_M:.0} m across ({}; the largest {most:.1} m; the \
             source's unit is {unit} m): they are simulated at that real size{}; {large_advice}",
            large.len(),
            first_and_count(&named),
            fall(most, "the largest falling")
        ));
    }
    notes
}

/// A small body's size, metres, in centimetres, or in millimetres under one (a 0.4 mm part
/// read "0.0 cm").
fn small_length(metres: f64) -> String {
    if metres < 0.01 {
        format!("{:.2} mm", metres * 1000.0)
    } else {
        format!("{:.1} cm", metres * 100.0)
    }
}

/// What to give a body too large at the source's `unit` (m): the unit a centimetre or
/// millimetre model written in a larger unit needs. A USD stage in centimetres
/// (`metersPerUnit = 0.01`) is not told to use 0.01 again.
fn smaller_unit_advice(unit: f64) -> String {
    let give = |u: &str, rest: &str| {
        format!(
            "give its unit (`meters_per_unit = {u}` on the body, `--meters-per-unit {u}` for a \
             bare mesh{rest})"
        )
    };
    if unit > 0.0101 {
        format!(
            "if the model was made in centimetres, {}",
            give("0.01", "; 0.001 for millimetres")
        )
    } else if unit > 0.00101 {
        format!(
            "if the model was made in millimetres, {}",
            give("0.001", "")
        )
    } else {
        "if the model was made in a smaller unit, give that unit (`meters_per_unit` on the \
         body, `--meters-per-unit` for a bare mesh)"
            .to_owned()
    }
}

/// Parts that interpenetrate at the start deeper than the contact layer reaches, or fit into
/// each other, stop colliding with each other, and flexible ones are glued where they overlap
/// or touch (the XPBD solver's glue): name them, so a user who meant them to collide knows to
/// move them apart.
pub fn interpenetrating_parts_notes(prepared: &mut Prepared) -> Vec<String> {
    let pairs = prepared.world.interpenetrating_parts();
    let mut notes = Vec::new();
    for glued in [true, false] {
        let what = if glued {
            "they are glued where they overlap or touch (a peg in its hole, a mesh split \
             along a seam) and do not collide with each other"
        } else {
            "they do not collide with each other; a rigid or particle body is not glued"
        };
        let named: Vec<String> = (pairs.iter())
            .filter(|p| p.2 == glued)
            .map(|(a, b, _)| format!("\"{a}\" and \"{b}\""))
            .collect();
        let fix = "move them apart to make them collide";
        if named.len() <= MAX_NAMED_BODIES {
            notes.extend(
                named.iter().map(|pair| {
                    format!("bodies {pair} interpenetrate at the start: {what} ({fix})")
                }),
            );
        } else {
            // A kit modelled touching: one note, not a screenful.
            notes.push(format!(
                "{} pairs of bodies interpenetrate at the start ({}): {what} ({fix})",
                named.len(),
                first_and_count(&named),
            ));
        }
    }
    notes
}

/// Bodies the XPBD solver holds rigid because their material is far too stiff for their
/// lattice to bend (wood, steel): name them, and how to have them solved elastic instead.
pub fn held_bodies_notes(prepared: &mut Prepared) -> Vec<String> {
    prepared
        .world
        .held_bodies()
        .into_iter()
        .map(|body| {
            format!(
                "body \"{body}\" is held rigid: its material is too stiff for a deformation \
                 to show at its size, and far too stiff for its cells to bend right at the \
                 solver's substeps (`[solver] stiff_bodies = \"elastic\"` solves it as cells, \
                 far softer than its material)"
            )
        })
        .collect()
}

/// Bodies whose material is stiffer than the automatic substeps resolve at their cell size
/// (`World::under_resolved_bodies`): name them, what they would need and what to do.
pub fn under_resolved_notes(prepared: &Prepared, fps: f64) -> Vec<String> {
    let cap = (springbake_core::solver::xpbd::MAX_STIFFNESS_SUBSTEP_RATE / fps).ceil();
    prepared
        .world
        .under_resolved_bodies(1.0 / fps)
        .into_iter()
        .map(|(body, asked)| {
            format!(
                "body \"{body}\" is stiffer than the solver resolves at its cell size: its \
                 material asks for {asked} substeps a frame (three per elastic wave crossing \
                 of a cell) and the automatic count stops at {cap}, so it bends and wobbles \
                 softer than its material (a stiff beam asking 4 times the cap bent 2.5 times \
                 as far, 26 times: 30 times). For a truer bend set `[solver] substeps = \
                 {asked}` (slower) or use fewer cells"
            )
        })
        .collect()
}

/// Cells a display face's edge may span before the face hides the lattice's bending.
pub const COARSE_FACE_CELLS: f64 = 2.0;

/// Flexible lattice bodies (not held rigid) whose display mesh is too coarse for its lattice:
/// at least half its surface lies in triangles with an edge over [`COARSE_FACE_CELLS`]
/// cells. Each vertex follows the lattice where it sits, so such a face stays flat and its
/// edges straight whatever the cells between its corners do: an 8-vertex box shows neither
/// a dent nor a bend, and a ball dropped on it seems to sink into a flat face. Say so, with
/// what to do, before the bake.
pub fn coarse_mesh_notes(prepared: &mut Prepared, scene: &SceneFile) -> Vec<String> {
    use springbake_core::scene::{BodyKind, ModelKind};
    let held = prepared.world.held_bodies();
    // Per coarse body: its name, the share of its surface in coarse faces, and the most
    // cells a face's edge spans.
    let coarse: Vec<(String, f64, f64)> = (0..prepared.bodies.len())
        .filter_map(|b| {
            let body = &prepared.bodies[b];
            let section = scene.body.get(body.section)?;
            let flexible = section.kind == BodyKind::Flexible
                && section.model == ModelKind::Lattice
                && !held.contains(&body.name);
            if !flexible {
                return None;
            }
            let mesh = prepared.export_scene.meshes.get(body.mesh_index)?;
            let (points, h) = (prepared.vertex_positions(b), body.lattice.cell_size);
            let (mut area, mut coarse, mut longest) = (0.0, 0.0, 0.0_f64);
            for t in mesh.triangles() {
                let corner = |k: usize| points.get(t[k] as usize).copied();
                let (Some(a), Some(b), Some(c)) = (corner(0), corner(1), corner(2)) else {
                    continue;
                };
                let cells = (b - a).norm().max((c - b).norm()).max((a - c).norm()) / h;
                let size = 0.5 * (b - a).cross(&(c - a)).norm();
                area += size;
                longest = longest.max(cells);
                if cells > COARSE_FACE_CELLS {
                    coarse += size;
                }
            }
            (area > 0.0 && coarse >= 0.5 * area)
                .then(|| (body.name.clone(), 100.0 * coarse / area, longest))
        })
        .collect();
    let why = "and a face stays flat whatever the cells between its corners do, so dents, \
               bulges and bends inside it will not show; subdivide the mesh before export to \
               see them (in Blender a Subdivision Surface modifier, Simple, applied), or use \
               fewer cells to bake the same look faster";
    if coarse.len() <= MAX_NAMED_BODIES {
        return coarse
            .iter()
            .map(|(name, share, longest)| {
                format!(
                    "body \"{name}\" has a coarse mesh for its lattice: {share:.0} % of its \
                     surface is in faces whose edges span more than {COARSE_FACE_CELLS:.0} cells \
                     (up to {longest:.1}), {why}"
                )
            })
            .collect();
    }
    // Many parts (a kit, a pile): one note, not a screenful of the same one.
    let least = coarse.iter().map(|c| c.1).fold(f64::MAX, f64::min);
    let most = coarse.iter().map(|c| c.1).fold(0.0, f64::max);
    let longest = coarse.iter().map(|c| c.2).fold(0.0, f64::max);
    let named: Vec<String> = coarse.iter().map(|c| format!("\"{}\"", c.0)).collect();
    let share = if format!("{least:.0}") == format!("{most:.0}") {
        format!("{most:.0} %")
    } else {
        format!("{least:.0}–{most:.0} %")
    };
    vec![format!(
        "{} bodies have a coarse mesh for their lattice ({}): {share} of each one's surface is \
         in faces whose edges span more than {COARSE_FACE_CELLS:.0} cells (up to \
         {longest:.1}), {why}",
        coarse.len(),
        first_and_count(&named),
    )]
}

/// Bodies a note names one by one; past this many it names these and counts the rest.
const MAX_NAMED_BODIES: usize = 3;

/// The first [`MAX_NAMED_BODIES`] of `named`, then how many more: `a, b, c and 45 more`.
fn first_and_count(named: &[String]) -> String {
    let shown = &named[..named.len().min(MAX_NAMED_BODIES)];
    format!(
        "{} and {} more",
        shown.join(", "),
        named.len() - shown.len()
    )
}

/// A body that starts inside a static collider, deeper than the contact layer, is not held
/// in by it: the collider's faces push only outwards, so the body is thrown out through the
/// first face it reaches (a cube dropped inside a closed box collider gained 7.8 kJ at its
/// floor). Say so before the bake.
pub fn inside_collider_notes(prepared: &Prepared) -> Vec<String> {
    prepared
        .world
        .bodies_inside_colliders()
        .into_iter()
        .map(|(body, collider)| {
            format!(
                "body \"{body}\" starts inside collider \"{collider}\": a collider holds bodies \
                 off its outside only, so this one will be thrown out through the first face \
                 it reaches (move the body out of the collider; a container needs its walls \
                 as separate thin colliders)"
            )
        })
        .collect()
}

/// Bodies that started through the floor or a wall were lifted out of it
/// ([`crate::placement`]): say which and how far, so the artist knows frame 1 is not where
/// they put them. A body still through a plane after that (wider than the room) is thrown out
/// of it at the first substeps: say so, with the depth and what to change.
pub fn through_plane_notes(prepared: &Prepared) -> Vec<String> {
    let mut notes: Vec<String> = prepared
        .lifted
        .iter()
        .map(|lift| {
            let named: Vec<String> = (lift.bodies.iter())
                .map(|&b| format!("\"{}\"", prepared.bodies[b].name))
                .collect();
            let who = match named.len() {
                1 => format!("body {}", named[0]),
                n if n <= MAX_NAMED_BODIES => format!("bodies {} (touching)", named.join(", ")),
                n => format!("{n} touching bodies ({})", first_and_count(&named)),
            };
            let (plane, verb) = if lift.floor {
                ("the floor", "lifted onto it")
            } else {
                ("a wall", "moved out of it")
            };
            format!(
                "{who} started {:.3} m through {plane}: {verb} before frame 1 (pushed out \
                 during the bake, the model would be thrown; to place it yourself, set \
                 `offset` in [[body]] or move the plane)",
                lift.distance
            )
        })
        .collect();
    let planes = &prepared.world.settings.planes;
    notes.extend((0..prepared.bodies.len()).filter_map(|b| {
        let body = &prepared.bodies[b];
        let points = prepared.vertex_positions(b);
        let deepest = points
            .iter()
            .flat_map(|p| {
                planes
                    .iter()
                    .map(move |pl| pl.offset - pl.normal.dot(&p.coords))
            })
            .fold(0.0, f64::max);
        (deepest > 0.5 * body.lattice.cell_size).then(|| {
            format!(
                "body \"{}\" starts {:.3} m through the floor or a wall, and cannot be moved \
                 clear of them all (it, or the bodies it touches, is wider than the room): it \
                 will be thrown out of it; make the room larger or the body smaller",
                body.name, deepest
            )
        })
    }));
    notes
}

/// A scene with gravity and nothing to land on (no `floor`, walls, collider or pin) drops its
/// bodies for the whole bake: a minimal scene file that leaves out `floor` sees its model
/// fall out of the frame. Say so with how far they fall, and what to add.
pub fn no_ground_note(prepared: &Prepared, scene: &SceneFile) -> Option<String> {
    let world = &prepared.world;
    let held_up = !world.settings.planes.is_empty()
        || !scene.collider.is_empty()
        || !scene.constraint.is_empty()
        || !scene.attach.is_empty()
        || !scene.manipulator.is_empty();
    let g = world.settings.gravity.norm();
    if held_up || g == 0.0 || prepared.bodies.is_empty() {
        return None;
    }
    // Frame 1 is the start: the bake spans one frame fewer.
    let seconds = scene.output.frames.saturating_sub(1) as f64 / scene.output.fps;
    let fall = 0.5 * g * seconds * seconds;
    let size = (prepared.bodies.iter())
        .map(|body| {
            let longest = body.lattice.dims.iter().copied().max().unwrap_or(0);
            body.lattice.cell_size * f64::from(longest)
        })
        .fold(0.0, f64::max);
    (fall > size).then(|| {
        format!(
            "no floor, wall, collider or pin: under gravity the bodies fall freely, {fall:.1} m \
             over the bake's {seconds:.1} s (add `floor = HEIGHT` under [world], or set \
             `gravity = 0` for a float)"
        )
    })
}

/// Refuses a bake whose estimated memory is over `limit` bytes.
pub fn check_memory(
    prepared: &Prepared,
    scene: &SceneFile,
    output: &Path,
    limit: u64,
) -> Result<(), PipelineError> {
    let (need, what) = estimate_memory(prepared, scene, output);
    if need <= limit {
        return Ok(());
    }
    Err(PipelineError::Usage(format!(
        "this bake needs about {} MiB ({what}), over the limit of {} MiB (--max-memory, \
         SPRINGBAKE_MAX_MEMORY, or nine tenths of the memory available): use fewer cells, \
         fewer frames, a point cache (.pc2) or raise the limit",
        need >> 20,
        limit >> 20
    )))
}

/// Refuses a bake whose automatic substep count for the first frame is over
/// [`MAX_AUTO_SUBSTEPS_PER_FRAME`], saying what drives it. A fixed `solver.substeps` is the
/// user's explicit choice and is not capped here (its own range is checked at load).
pub fn check_substeps(prepared: &mut Prepared, scene: &SceneFile) -> Result<(), PipelineError> {
    let choice = prepared.world.choose_substeps(1.0 / scene.output.fps);
    if choice.limited_by == "fixed" || choice.substeps <= MAX_AUTO_SUBSTEPS_PER_FRAME {
        return Ok(());
    }
    let why = match choice.limited_by {
        "stability" | "accuracy" => {
            "the stiffest spring against the lightest node: a stiff material or small cells"
        }
        "contact" => "the contact layer's stiffness against the lightest node: small cells",
        "speed" => "the fastest node against the shortest spring: a fast body or small cells",
        other => other,
    };
    Err(PipelineError::Usage(format!(
        "this bake needs {} substeps per frame, over the cap of {MAX_AUTO_SUBSTEPS_PER_FRAME}; \
         they are driven by {why} (integrator \"{}\"). Use integrator = \"xpbd\" (the default), \
         a softer material, fewer cells, or set solver.substeps yourself",
        choice.substeps,
        match scene.solver.integrator {
            IntegratorSpec::Xpbd => "xpbd",
            IntegratorSpec::SymplecticEuler => "symplectic_euler",
            IntegratorSpec::Newmark => "newmark",
        }
    )))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A stage already in centimetres is not told to use centimetres again.
    #[test]
    fn a_large_body_is_told_a_unit_smaller_than_its_own() {
        assert!(smaller_unit_advice(1.0).contains("`--meters-per-unit 0.01`"));
        let cm = smaller_unit_advice(0.01);
        assert!(
            cm.contains("`meters_per_unit = 0.001`") && !cm.contains("0.01`"),
            "{cm}"
        );
        assert!(!smaller_unit_advice(0.001).contains("0.001"));
        assert_eq!(small_length(0.022), "2.2 cm");
        assert_eq!(small_length(0.0004), "0.40 mm");
    }

    #[test]
    fn sizes_parse_with_units() {
        assert_eq!(parse_size("512").unwrap(), 512);
        assert_eq!(parse_size("4K").unwrap(), 4096);
        assert_eq!(parse_size("1.5G").unwrap(), 3 << 29);
        assert_eq!(parse_size(" 2 GiB ").unwrap(), 2 << 30);
        for bad in ["", "G", "-1G", "1Q", "0", "nan", "1e30"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
