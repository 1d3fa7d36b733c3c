//! Particle effects inside a glTF bake (issue 20 part 1): each emitter a node named after it
//! whose children are its particles, every one an instance of one small octahedron mesh,
//! moved by translation keys (linear) and sized by scale keys (step: the particle's width,
//! zero before its birth and after its death), so any glTF player (Blender, three.js, game
//! engines) plays them without an extension. glTF has no per-node opacity key, so smoke's
//! fading is not in the glTF; the USD stage written beside a glTF bake has all of it.
//!
//! A node per particle is meant for effects of a few thousand particles: each emitter's first
//! [`MAX_PARTICLES_PER_EMITTER`] particles go into the glTF (the USD stage has every one).

use super::builder::DocBuilder;
use serde_json::json;
use springbake_core::bake::BakedParticles;
use springbake_core::particles::{OCTAHEDRON_CORNERS, OCTAHEDRON_FACES};

/// Most particles of one emitter written into a glTF (by emission order).
pub const MAX_PARTICLES_PER_EMITTER: usize = 2000;

/// One animation channel to add: (keys accessor, node, path, interpolation).
pub(super) type Channel = (usize, usize, &'static str, &'static str);

/// Adds the emitters' particle nodes to the document's scene; returns the channels that move
/// them (keyed at `time_accessor`'s times, one key per baked frame).
pub(super) fn add_particles(b: &mut DocBuilder, emitters: &[BakedParticles]) -> Vec<Channel> {
    if emitters.iter().all(|e| e.frames.is_empty()) {
        return Vec::new();
    }
    let mesh = particle_mesh(b);
    let mut channels = Vec::new();
    let mut roots = Vec::new();
    for emitter in emitters {
        let tracks = tracks(emitter);
        let mut children = Vec::new();
        for (id, track) in tracks.iter().enumerate() {
            let node = b.push(
                "nodes",
                json!({"name": format!("{}.{id}", emitter.name), "mesh": mesh}),
            );
            let moves = b.vec3_keys(&track.positions);
            let sizes = b.vec3_keys(&track.scales);
            channels.push((moves, node, "translation", "LINEAR"));
            channels.push((sizes, node, "scale", "STEP"));
            children.push(node);
        }
        let mut group = json!({"name": emitter.name});
        if !children.is_empty() {
            group["children"] = json!(children);
        }
        roots.push(b.push("nodes", group));
    }
    let scene = b.root.get("scene").and_then(|s| s.as_u64()).unwrap_or(0) as usize;
    if b.array_mut("scenes").is_empty() {
        b.push("scenes", json!({"nodes": []}));
    }
    if let Some(nodes) = b
        .array_mut("scenes")
        .get_mut(scene)
        .map(|s| &mut s["nodes"])
    {
        if !nodes.is_array() {
            *nodes = json!([]);
        }
        if let Some(list) = nodes.as_array_mut() {
            list.extend(roots.into_iter().map(|r| json!(r)));
        }
    }
    channels
}

/// The shared particle mesh: a light grey octahedron of radius 1 (scaled per particle).
fn particle_mesh(b: &mut DocBuilder) -> usize {
    let positions = b.vec3(&OCTAHEDRON_CORNERS, true);
    let normals = b.vec3(&OCTAHEDRON_CORNERS, false);
    let indices = b.indices(OCTAHEDRON_FACES.as_flattened());
    let material = b.push(
        "materials",
        json!({"name": "springbake particle",
               "pbrMetallicRoughness": {"baseColorFactor": [0.85, 0.85, 0.85, 1.0],
                                        "metallicFactor": 0.0, "roughnessFactor": 0.8}}),
    );
    b.push(
        "meshes",
        json!({"name": "springbake particle", "primitives": [{
            "attributes": {"POSITION": positions, "NORMAL": normals},
            "indices": indices, "material": material}]}),
    )
}

/// One particle's keys, a key per frame.
struct Track {
    positions: Vec<[f32; 3]>,
    scales: Vec<[f32; 3]>,
}

/// The emitter's first particles (ids below [`MAX_PARTICLES_PER_EMITTER`]) as tracks: where
/// each is (held at its first and last place outside its life) and its radius (zero while
/// it is not alive or fully transparent).
fn tracks(emitter: &BakedParticles) -> Vec<Track> {
    let frames = emitter.frames.len();
    let count = emitter
        .frames
        .iter()
        .flat_map(|f| f.ids.iter())
        .filter(|&&id| (id as usize) < MAX_PARTICLES_PER_EMITTER)
        .map(|&id| id as usize + 1)
        .max()
        .unwrap_or(0);
    let mut tracks: Vec<Track> = (0..count)
        .map(|_| Track {
            positions: vec![[f32::NAN; 3]; frames],
            scales: vec![[0.0; 3]; frames],
        })
        .collect();
    for (f, frame) in emitter.frames.iter().enumerate() {
        for (k, &id) in frame.ids.iter().enumerate() {
            let Some(track) = tracks.get_mut(id as usize) else {
                continue;
            };
            track.positions[f] = frame.positions[k];
            let visible = frame.opacities.get(k).is_none_or(|&o| o > 0.0);
            let radius = if visible { frame.widths[k] * 0.5 } else { 0.0 };
            track.scales[f] = [radius; 3];
        }
    }
    for track in &mut tracks {
        hold_outside_life(&mut track.positions);
    }
    tracks
}

/// Frames without a position take the nearest one before them, or after them before the
/// first (a particle waits, invisible, where it will be born).
fn hold_outside_life(positions: &mut [[f32; 3]]) {
    let known = |p: &[f32; 3]| !p[0].is_nan();
    let first = positions.iter().position(known);
    let Some(first) = first else {
        positions.fill([0.0; 3]);
        return;
    };
    let start = positions[first];
    positions[..first].fill(start);
    let mut last = start;
    for p in &mut positions[first..] {
        if known(p) {
            last = *p;
        } else {
            *p = last;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_particle_waits_where_it_is_born_and_stays_where_it_died() {
        let n = f32::NAN;
        let mut p = [[n; 3], [1.0, 2.0, 3.0], [n; 3], [4.0, 5.0, 6.0], [n; 3]];
        hold_outside_life(&mut p);
        assert_eq!(
            p,
            [
                [1.0, 2.0, 3.0],
                [1.0, 2.0, 3.0],
                [1.0, 2.0, 3.0],
                [4.0, 5.0, 6.0],
                [4.0, 5.0, 6.0]
            ]
        );
    }
}
