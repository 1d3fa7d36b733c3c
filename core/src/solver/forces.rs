//! Internal forces (Miyazaki eq 1): springs `k (1 − L/|r|) r` with dampers on the component of
//! the relative velocity *along* the spring (physics §2 allows it; it leaves rigid rotation
//! undamped), and gravity. Two passes: per-spring forces in parallel, then a per-node gather
//! through a CSR adjacency in fixed order (done inside the world's fused node pass, which also
//! adds gravity and contact and updates the velocity), so there are no racy scatters.

use super::miyazaki1996_velocity_dispersion::{speed_floor_sq, DispersionMode};
use super::stencil::StencilPlan;
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
        Adjacency::filtered(nodes, springs, |_| true)
    }

    /// The lists of the springs `keep` accepts only.
    pub fn filtered(nodes: usize, springs: &SpringSet, keep: impl Fn(usize) -> bool) -> Adjacency {
        let kept: Vec<usize> = (0..springs.len()).filter(|&s| keep(s)).collect();
        let mut count = vec![0u32; nodes + 1];
        for &s in &kept {
            count[springs.a[s] as usize + 1] += 1;
            count[springs.b[s] as usize + 1] += 1;
        }
        for i in 0..nodes {
            count[i + 1] += count[i];
        }
        let offsets = count.clone();
        let mut fill = count;
        let mut links = vec![0u32; kept.len() * 2];
        for &s in &kept {
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

/// What the spring pass leaves for the velocity dispersion (see [`SpringHints`]).
///
/// [`SpringHints`]: super::miyazaki1996_velocity_dispersion::SpringHints
pub(crate) struct FloorOutput<'a> {
    pub mode: DispersionMode,
    pub inv_dt_sq: f64,
    /// Per spring: 1 where the spring has no speed floor.
    pub exceptional: &'a mut [u8],
    /// Per chunk of [`PAR_CHUNK`] springs: the smallest speed floor² of the others.
    pub chunk_floor: &'a mut [f64],
}

/// Forces of the springs `first..first + out.len()`; with `floor`, also each spring's
/// dispersion flag (from the same squared length) and the chunk's smallest floor².
#[inline]
fn chunk_forces(
    nodes: &NodeState,
    springs: &SpringSet,
    first: usize,
    out: &mut [Vector3<f64>],
    mut floor: Option<(DispersionMode, f64, &mut [u8])>,
    skip: Option<&StencilPlan>,
) -> f64 {
    if let Some(plan) = skip {
        if plan.covers_chunk(first / PAR_CHUNK) {
            return f64::INFINITY;
        }
    }
    let (pos, vel) = (&nodes.position[..], &nodes.velocity[..]);
    let range = first..first + out.len();
    let (sa, sb) = (&springs.a[range.clone()], &springs.b[range.clone()]);
    let rest = &springs.rest_length[range.clone()];
    let (k, d) = (&springs.stiffness[range.clone()], &springs.damping[range]);
    let mut min_floor = f64::INFINITY;
    for (j, f) in out.iter_mut().enumerate() {
        if skip.is_some_and(|plan| plan.covers(first + j)) {
            continue;
        }
        let (a, b) = (sa[j] as usize, sb[j] as usize);
        let r = pos[a] - pos[b];
        let len_sq = r.norm_squared();
        if let Some((mode, inv_dt_sq, flags)) = floor.as_mut() {
            match speed_floor_sq(
                *mode,
                springs,
                &nodes.inv_mass,
                first + j,
                len_sq,
                *inv_dt_sq,
            ) {
                Some(fl) => {
                    flags[j] = 0;
                    min_floor = min_floor.min(fl);
                }
                None => flags[j] = 1,
            }
        }
        let len = len_sq.sqrt();
        if len <= f64::MIN_POSITIVE {
            *f = Vector3::zeros();
            continue;
        }
        // One division per spring (`r / len` would divide each component).
        let inv_len = 1.0 / len;
        let stretch = len - rest[j];
        let closing = (vel[a] - vel[b]).dot(&r) * inv_len;
        *f = r * (-(k[j] * stretch + d[j] * closing) * inv_len);
    }
    min_floor
}

/// Force on each spring's `a` end (the `b` end gets the opposite). Fixed chunks of
/// [`PAR_CHUNK`] springs, one task each; each slot is written by its spring alone. With
/// `floors`, also each spring's dispersion speed floor from the same squared length. The
/// springs `skip` takes (the stencil's) are left as they are.
pub(crate) fn spring_forces(
    nodes: &NodeState,
    springs: &SpringSet,
    out: &mut [Vector3<f64>],
    floors: Option<FloorOutput>,
    skip: Option<&StencilPlan>,
) {
    match floors {
        Some(FloorOutput {
            mode,
            inv_dt_sq,
            exceptional,
            chunk_floor,
        }) => out
            .par_chunks_mut(PAR_CHUNK)
            .zip(exceptional.par_chunks_mut(PAR_CHUNK))
            .zip(chunk_floor.par_iter_mut())
            .enumerate()
            .for_each(|(chunk, ((out, flags), min_floor))| {
                *min_floor = chunk_forces(
                    nodes,
                    springs,
                    chunk * PAR_CHUNK,
                    out,
                    Some((mode, inv_dt_sq, flags)),
                    skip,
                );
            }),
        None => out
            .par_chunks_mut(PAR_CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                chunk_forces(nodes, springs, chunk * PAR_CHUNK, out, None, skip);
            }),
    }
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
