//! Internal forces (Miyazaki eq 1): springs `k (1 − L/|r|) r` with dampers on the component of
//! the relative velocity *along* the spring (physics §2 allows it; it leaves rigid rotation
//! undamped), and gravity. Two passes: per-spring forces in parallel, then a per-node gather
//! through a CSR adjacency in fixed order (done inside the world's fused node pass, which also
//! adds gravity and contact and updates the velocity), so there are no racy scatters.

use super::{NodeState, SpringSet, PAR_CHUNK};
use nalgebra::Vector3;
use rayon::prelude::*;

/// For each node, the springs touching it: `links[offsets[i]..offsets[i+1]]`, each
/// `spring * 2 + (1 if the node is the spring's b end)`.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Adjacency {
    pub offsets: Vec<u32>,
    pub links: Vec<u32>,
}

impl Adjacency {
    pub fn new(nodes: usize, springs: &SpringSet) -> Adjacency {
        let mut count = vec![0u32; nodes + 1];
        for s in 0..springs.len() {
            count[springs.a[s] as usize + 1] += 1;
            count[springs.b[s] as usize + 1] += 1;
        }
        for i in 0..nodes {
            count[i + 1] += count[i];
        }
        let offsets = count.clone();
        let mut fill = count;
        let mut links = vec![0u32; springs.len() * 2];
        for s in 0..springs.len() {
            let a = springs.a[s] as usize;
            let b = springs.b[s] as usize;
            links[fill[a] as usize] = (s as u32) * 2;
            fill[a] += 1;
            links[fill[b] as usize] = (s as u32) * 2 + 1;
            fill[b] += 1;
        }
        Adjacency { offsets, links }
    }
}

/// Force on each spring's `a` end (the `b` end gets the opposite). Fixed chunks of
/// [`PAR_CHUNK`] springs, one task each; each slot is written by its spring alone.
pub(crate) fn spring_forces(nodes: &NodeState, springs: &SpringSet, out: &mut [Vector3<f64>]) {
    let (pos, vel) = (&nodes.position[..], &nodes.velocity[..]);
    out.par_chunks_mut(PAR_CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let first = chunk * PAR_CHUNK;
            let range = first..first + out.len();
            let (sa, sb) = (&springs.a[range.clone()], &springs.b[range.clone()]);
            let rest = &springs.rest_length[range.clone()];
            let (k, d) = (&springs.stiffness[range.clone()], &springs.damping[range]);
            for (j, f) in out.iter_mut().enumerate() {
                let (a, b) = (sa[j] as usize, sb[j] as usize);
                let r = pos[a] - pos[b];
                let len = r.norm();
                if len <= f64::MIN_POSITIVE {
                    *f = Vector3::zeros();
                    continue;
                }
                let u = r / len;
                let stretch = len - rest[j];
                let closing = (vel[a] - vel[b]).dot(&u);
                *f = -(k[j] * stretch + d[j] * closing) * u;
            }
        });
}

/// Sum of the spring forces on node `i` (through the CSR adjacency, in fixed order).
#[inline]
pub(crate) fn gathered_spring_force(
    adjacency: &Adjacency,
    spring_force: &[Vector3<f64>],
    i: usize,
) -> Vector3<f64> {
    let (lo, hi) = (
        adjacency.offsets[i] as usize,
        adjacency.offsets[i + 1] as usize,
    );
    let mut acc = Vector3::zeros();
    for &link in &adjacency.links[lo..hi] {
        let sf = spring_force[(link >> 1) as usize];
        if link & 1 == 0 {
            acc += sf;
        } else {
            acc -= sf;
        }
    }
    acc
}

/// Elastic energy ½ k (l − L)² of spring `s`.
pub(crate) fn spring_energy(nodes: &NodeState, springs: &SpringSet, s: usize) -> f64 {
    let r = nodes.position[springs.a[s] as usize] - nodes.position[springs.b[s] as usize];
    let d = r.norm() - springs.rest_length[s];
    0.5 * springs.stiffness[s] * d * d
}
