//! The step's surfaces of the bodies that may touch, brought up to date side by side before
//! the pairs' searches are prepared (vertex–face and edge–edge): each mesh's vertices, grid
//! and every face's box and plane
//! ([`BodyMesh::update`], [`BodyMesh::refresh_all`]), and each body's contact samples. Serial,
//! this upkeep was a fifth of a pile's bake (60 cubes 1 cm apart). Each task writes only its
//! own mesh or its own run of samples and computes what the serial pass did, so the bits are
//! the same on any thread count. The searches and their lists' builds then only read.

use super::detect::sample;
use super::{BodyContact, PassInput};
use crate::solver::team::{self, Chunks};
use nalgebra::Vector3;

/// A pair of bodies `a < b` that may touch, and the region `[lo, hi]` its searches look in.
pub(super) type PairInReach = (usize, usize, Vector3<f64>, Vector3<f64>);

/// Samples per task of the samples' pass.
const SAMPLE_CHUNK: usize = 512;

/// Bring the meshes and samples that the searches of `pairs` read up to this step: a pair's
/// search runs each body's samples against the other's mesh.
pub(super) fn surfaces_in_reach(bc: &mut BodyContact, input: &PassInput, pairs: &[PairInReach]) {
    let mut mesh_needed = std::mem::take(&mut bc.mesh_needed);
    mesh_needed.clear();
    mesh_needed.resize(bc.meshes.len(), false);
    let mut sampled = std::mem::take(&mut bc.sampled);
    sampled.clear();
    sampled.resize(bc.points.len(), false);
    for &(a, b, _, _) in pairs {
        // The edge–edge search reads both meshes.
        if let (Some(ma), Some(mb)) = (bc.mesh_of[a], bc.mesh_of[b]) {
            (mesh_needed[ma], mesh_needed[mb]) = (true, true);
        }
        for (from, to) in [(a, b), (b, a)] {
            if let (Some(m), false) = (bc.mesh_of[to], bc.points[from].is_empty()) {
                mesh_needed[m] = true;
                // Samples already computed in this step are kept as they are.
                sampled[from] = bc.sample_stamp[from] != bc.step;
            }
        }
    }
    let (nodes, step) = (input.nodes, bc.step);
    team::for_each(Chunks::new(&mut bc.meshes, 1), |m, mesh| {
        if mesh_needed[m] {
            mesh[0].update(nodes, step);
            mesh[0].refresh_all();
        }
    });
    for (b, &fresh) in sampled.iter().enumerate() {
        if fresh {
            bc.sample_stamp[b] = step;
        }
    }
    let surface = input.surface;
    let parts = (
        Chunks::new(&mut bc.sample_x, SAMPLE_CHUNK),
        Chunks::new(&mut bc.sample_v, SAMPLE_CHUNK),
    );
    team::for_each(parts, |chunk, (xs, vs)| {
        let start = chunk * SAMPLE_CHUNK;
        for (k, (x, v)) in xs.iter_mut().zip(vs).enumerate() {
            let i = start + k;
            if sampled.get(surface.body[i] as usize) == Some(&true) {
                (*x, *v) = sample(surface, nodes, i);
            }
        }
    });
    bc.mesh_needed = mesh_needed;
    bc.sampled = sampled;
}
