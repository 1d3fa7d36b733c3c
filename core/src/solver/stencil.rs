//! The regular-lattice spring pass (issue 9): the springs of lattice bodies evaluated along
//! stencil directions over each body's grid, instead of one by one through index lists.
//!
//! A lattice body's nodes sit on grid slots (`x + X·(y + Y·z)`, padding where a cell is not
//! active). Its springs fall into a few directions (+x, +x+y, …); for direction `d` with slot
//! offset `o_d`, slot `j`'s spring reaches slot `j + o_d`. One loop per direction over all
//! slots reads the near and far ends from contiguous coordinate arrays, so the compiler
//! vectorises it (and a copy compiled for AVX-512 is chosen at run time where the CPU has it:
//! the same operations per spring, so the same bits). Slots without a spring (padding, the
//! pairs that wrap across a row) have rest length 0 and give no force.
//!
//! Per spring the arithmetic is exactly the index-list pass's (`forces::chunk_forces`), also
//! for the dispersion's speed floors and flags, so per-spring values agree bit for bit. The
//! loop adds each force to its near end's sum and takes it off its far end's; slot chunks are
//! longer than the longest offset, so the even chunks run side by side, then the odd ones,
//! and no slot has two writers. A node's sum therefore adds in another order than the index
//! lists' gather, one fixed by the grid alone: the result does not depend on the thread
//! count.
//!
//! Springs a body cannot place (a body with more than [`MAX_DIRECTIONS`] directions, two
//! springs on one slot pair, a grid much larger than the body) leave that body to the index
//! lists, as do springs outside lattice bodies (joints, cages).

use super::miyazaki1996_velocity_dispersion::DispersionMode;
use super::world::BodyInfo;
use super::{NodeState, SpringSet, PAR_CHUNK};
use nalgebra::Vector3;
use rayon::prelude::*;

const NONE: u32 = u32::MAX;

/// At most this many directions per body (the forward half of the 26-neighbourhood).
pub const MAX_DIRECTIONS: usize = 13;

/// Where a lattice body's nodes sit on its grid (recorded by `World::add_lattice_body`).
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeGrid {
    /// Grid points per axis.
    pub dims: [u32; 3],
    /// Grid coordinates of each of the body's nodes.
    pub coords: Vec<[u32; 3]>,
}

/// One stencil direction of one body: per near slot `j` in `0..slots − offset`.
#[derive(Debug, Clone)]
struct Direction {
    offset: usize,
    /// The parameters of the spring from slot `j` to slot `j + offset` (rest length 0 where
    /// there is none; the plan's `spring_flag` says which spring it is).
    rest: Vec<f64>,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
}

/// One body on its grid.
#[derive(Debug, Clone)]
struct StencilBody {
    /// World node of each slot (`NONE`: padding).
    node_of_slot: Vec<u32>,
    directions: Vec<Direction>,
    /// Per slot, copied every step: position x, y, z, velocity x, y, z, inverse mass.
    state: [Vec<f64>; 7],
    /// Per slot: this step's spring force (near ends added, far ends subtracted).
    sums: [Vec<f64>; 3],
    /// Slots per chunk: more than the largest direction offset, so a chunk's springs reach
    /// at most into the next chunk (see [`StencilBody::forces`]).
    chunk: usize,
    /// Where this body's flags start in the plan's flags: chunk-major, each chunk one block
    /// per direction, `[chunk][direction][slot in chunk]`.
    flag_start: usize,
}

/// The stencil pass of a world: its lattice bodies on their grids, and the springs they take
/// from the index-list pass.
#[derive(Debug, Clone)]
pub(crate) struct StencilPlan {
    bodies: Vec<StencilBody>,
    /// Per world node: (body, slot), `(NONE, NONE)` for nodes of no stencil body.
    site: Vec<(u32, u32)>,
    /// Per spring: its flag's index in `flags`, `NONE` when the index lists evaluate it.
    spring_flag: Vec<u32>,
    /// Per fixed chunk of [`PAR_CHUNK`] springs: whether the stencil takes all of them.
    chunk_covered: Vec<bool>,
    /// Dispersion flags of all bodies (1: no speed floor, test exactly).
    flags: Vec<u8>,
    /// Per fixed slot chunk of each body (bodies one after another): the smallest floor².
    chunk_floor: Vec<f64>,
    /// Per fixed slot chunk of each body: 1 where some spring's flag is 1.
    chunk_flagged: Vec<u8>,
}

/// What [`StencilPlan::forces`] found for the velocity dispersion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StencilFloors {
    /// The smallest speed floor² of the springs flagged 0.
    pub least: f64,
    /// Whether any spring is flagged 1 (only then do the flags need copying out).
    pub flagged: bool,
}

/// What the spring pass computes for the velocity dispersion: the floor mode and 1/ΔT².
#[derive(Debug, Clone, Copy)]
pub(crate) struct FloorInput {
    pub mode: DispersionMode,
    pub inv_dt_sq: f64,
}

impl StencilPlan {
    /// The plan for the world's lattice bodies, or `None` when no body can use it.
    pub fn build(
        nodes: &NodeState,
        springs: &SpringSet,
        bodies: &[BodyInfo],
    ) -> Option<StencilPlan> {
        let mut plan = StencilPlan {
            bodies: Vec::new(),
            site: vec![(NONE, NONE); nodes.len()],
            spring_flag: vec![NONE; springs.len()],
            chunk_covered: Vec::new(),
            flags: Vec::new(),
            chunk_floor: Vec::new(),
            chunk_flagged: Vec::new(),
        };
        for body in bodies {
            let Some(grid) = &body.grid else { continue };
            let Some(stencil) = place_body(body, grid, springs, &mut plan) else {
                continue;
            };
            let b = plan.bodies.len() as u32;
            for (slot, &node) in stencil.node_of_slot.iter().enumerate() {
                if node != NONE {
                    plan.site[node as usize] = (b, slot as u32);
                }
            }
            plan.chunk_floor
                .extend(std::iter::repeat_n(f64::INFINITY, stencil.chunk_count()));
            plan.chunk_flagged
                .extend(std::iter::repeat_n(0, stencil.chunk_count()));
            plan.bodies.push(stencil);
        }
        if plan.bodies.is_empty() {
            return None;
        }
        plan.chunk_covered = plan
            .spring_flag
            .chunks(PAR_CHUNK)
            .map(|c| c.iter().all(|&f| f != NONE))
            .collect();
        Some(plan)
    }

    /// Whether the stencil evaluates spring `s` (the index-list pass skips it).
    #[inline]
    pub fn covers(&self, s: usize) -> bool {
        self.spring_flag[s] != NONE
    }

    /// Whether the stencil evaluates every spring of the world (the index-list pass has
    /// nothing to do).
    pub fn covers_all(&self) -> bool {
        self.chunk_covered.iter().all(|&c| c)
    }

    /// Whether the stencil evaluates every spring of fixed chunk `chunk`.
    #[inline]
    pub fn covers_chunk(&self, chunk: usize) -> bool {
        self.chunk_covered[chunk]
    }

    /// This step's spring forces of every stencil body; with `floor`, also each spring's
    /// dispersion flag (kept here: [`StencilPlan::write_flags`] copies them out).
    pub fn forces(&mut self, nodes: &NodeState, floor: Option<FloorInput>) -> StencilFloors {
        self.forces_with(nodes, floor, avx512_available())
    }

    /// [`StencilPlan::forces`] with the AVX-512 kernel (`wide`, only where available) or the
    /// baseline one.
    fn forces_with(
        &mut self,
        nodes: &NodeState,
        floor: Option<FloorInput>,
        wide: bool,
    ) -> StencilFloors {
        let mut floors = &mut self.chunk_floor[..];
        let mut flagged = &mut self.chunk_flagged[..];
        let mut flags = &mut self.flags[..];
        for body in &mut self.bodies {
            let (body_floors, rest) = floors.split_at_mut(body.chunk_count());
            floors = rest;
            let (body_flagged, rest) = flagged.split_at_mut(body.chunk_count());
            flagged = rest;
            let (body_flags, rest) = flags.split_at_mut(body.blocks());
            flags = rest;
            body.copy_state(nodes);
            body.forces(body_flags, (body_floors, body_flagged), floor, wide);
        }
        StencilFloors {
            least: self
                .chunk_floor
                .iter()
                .fold(f64::INFINITY, |m, &f| m.min(f)),
            flagged: self.chunk_flagged.contains(&1),
        }
    }

    /// Copy this step's flags of the stencil's springs into the per-spring `exceptional`.
    pub fn write_flags(&self, exceptional: &mut [u8]) {
        exceptional
            .par_chunks_mut(PAR_CHUNK)
            .zip(self.spring_flag.par_chunks(PAR_CHUNK))
            .for_each(|(out, site)| {
                for (e, &f) in out.iter_mut().zip(site) {
                    if f != NONE {
                        *e = self.flags[f as usize];
                    }
                }
            });
    }

    /// This step's force of the stencil springs on world node `i` (`None`: not a stencil
    /// node).
    #[inline]
    pub fn node_force(&self, i: usize) -> Option<Vector3<f64>> {
        let (b, slot) = self.site[i];
        if b == NONE {
            return None;
        }
        let [x, y, z] = &self.bodies[b as usize].sums;
        let j = slot as usize;
        Some(Vector3::new(x[j], y[j], z[j]))
    }

    pub fn bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let bodies: usize = self
            .bodies
            .iter()
            .map(|body| {
                let dirs: usize = body
                    .directions
                    .iter()
                    .map(|d| b(&d.rest) + b(&d.stiffness) + b(&d.damping))
                    .sum();
                dirs + b(&body.node_of_slot)
                    + body.state.iter().map(b).sum::<usize>()
                    + body.sums.iter().map(b).sum::<usize>()
            })
            .sum();
        bodies
            + b(&self.site)
            + b(&self.spring_flag)
            + b(&self.chunk_covered)
            + b(&self.flags)
            + b(&self.chunk_floor)
            + b(&self.chunk_flagged)
    }
}

/// `body` on its grid, its springs taken into the plan; `None` (nothing taken) when a spring
/// does not fit a stencil.
fn place_body(
    body: &BodyInfo,
    grid: &LatticeGrid,
    springs: &SpringSet,
    plan: &mut StencilPlan,
) -> Option<StencilBody> {
    let [gx, gy, gz] = grid.dims.map(|d| d as usize);
    let slots = gx * gy * gz;
    let count = body.nodes.len();
    if grid.coords.len() != count || slots > 4 * count.max(1) {
        return None;
    }
    let slot_of = |c: [u32; 3]| c[0] as usize + gx * (c[1] as usize + gy * c[2] as usize);
    let mut node_of_slot = vec![NONE; slots];
    for (k, &c) in grid.coords.iter().enumerate() {
        let slot = node_of_slot.get_mut(slot_of(c))?;
        if *slot != NONE {
            return None;
        }
        *slot = (body.nodes.start + k) as u32;
    }
    // Each spring as (direction, near slot, slot offset): the near end is the lower slot.
    let mut deltas: Vec<[i64; 3]> = Vec::new();
    let mut placed = Vec::with_capacity(body.springs.len());
    for s in body.springs.clone() {
        let (a, b) = (springs.a[s] as usize, springs.b[s] as usize);
        if !body.nodes.contains(&a) || !body.nodes.contains(&b) {
            return None;
        }
        let (ca, cb) = (
            grid.coords[a - body.nodes.start],
            grid.coords[b - body.nodes.start],
        );
        let (near, far) = if slot_of(ca) < slot_of(cb) {
            (ca, cb)
        } else {
            (cb, ca)
        };
        let delta: [i64; 3] = std::array::from_fn(|k| far[k] as i64 - near[k] as i64);
        let d = match deltas.iter().position(|&x| x == delta) {
            Some(d) => d,
            None if deltas.len() < MAX_DIRECTIONS => {
                deltas.push(delta);
                deltas.len() - 1
            }
            None => return None,
        };
        placed.push((s, d, slot_of(near), slot_of(far) - slot_of(near)));
    }
    let mut directions: Vec<Direction> = Vec::with_capacity(deltas.len());
    for d in 0..deltas.len() {
        let offset = placed.iter().find(|p| p.1 == d).map(|p| p.3)?;
        let len = slots - offset;
        directions.push(Direction {
            offset,
            rest: vec![0.0; len],
            stiffness: vec![0.0; len],
            damping: vec![0.0; len],
        });
    }
    for &(s, d, near, offset) in &placed {
        let dir = &mut directions[d];
        // A spring of no length (or NaN) could not be told from an empty slot.
        let has_length = springs.rest_length[s] > 0.0;
        if offset != dir.offset || dir.rest[near] != 0.0 || !has_length {
            return None;
        }
        dir.rest[near] = springs.rest_length[s];
        dir.stiffness[near] = springs.stiffness[s];
        dir.damping[near] = springs.damping[s];
    }
    // Accepted: take the springs.
    let longest = directions.iter().map(|d| d.offset).max().unwrap_or(0);
    let stencil = StencilBody {
        node_of_slot,
        directions,
        state: std::array::from_fn(|_| vec![0.0; slots]),
        sums: std::array::from_fn(|_| vec![0.0; slots]),
        chunk: (longest + 1).next_multiple_of(256).max(512),
        flag_start: plan.flags.len(),
    };
    plan.flags
        .extend(std::iter::repeat_n(0u8, stencil.blocks()));
    for &(s, d, near, _) in &placed {
        let at = stencil.flag_start + stencil.block_index(d, near);
        plan.spring_flag[s] = at as u32;
    }
    Some(stencil)
}

impl StencilBody {
    fn slots(&self) -> usize {
        self.node_of_slot.len()
    }

    fn chunk_count(&self) -> usize {
        self.slots().div_ceil(self.chunk)
    }

    /// Length of the chunk-major flag array: a block of `chunk` per (chunk, direction).
    fn blocks(&self) -> usize {
        self.chunk_count() * self.directions.len() * self.chunk
    }

    /// Index of direction `d`'s near slot `k` in the chunk-major flag array.
    #[inline]
    fn block_index(&self, d: usize, k: usize) -> usize {
        let (c, w) = (k / self.chunk, k % self.chunk);
        (c * self.directions.len() + d) * self.chunk + w
    }

    /// Position, velocity and inverse mass into the slot arrays (padding stays 0), and the
    /// force sums to zero.
    fn copy_state(&mut self, nodes: &NodeState) {
        let [px, py, pz, vx, vy, vz, w] = &mut self.state;
        let [sx, sy, sz] = &mut self.sums;
        let map = &self.node_of_slot;
        px.par_chunks_mut(PAR_CHUNK)
            .zip(py.par_chunks_mut(PAR_CHUNK))
            .zip(pz.par_chunks_mut(PAR_CHUNK))
            .zip(vx.par_chunks_mut(PAR_CHUNK))
            .zip(vy.par_chunks_mut(PAR_CHUNK))
            .zip(vz.par_chunks_mut(PAR_CHUNK))
            .zip(w.par_chunks_mut(PAR_CHUNK))
            .zip(sx.par_chunks_mut(PAR_CHUNK))
            .zip(sy.par_chunks_mut(PAR_CHUNK))
            .zip(sz.par_chunks_mut(PAR_CHUNK))
            .enumerate()
            .for_each(
                |(c, (((((((((px, py), pz), vx), vy), vz), w), sx), sy), sz))| {
                    sx.fill(0.0);
                    sy.fill(0.0);
                    sz.fill(0.0);
                    let first = c * PAR_CHUNK;
                    for k in 0..px.len() {
                        let node = map[first + k];
                        if node == NONE {
                            continue;
                        }
                        let (x, v) = (nodes.position[node as usize], nodes.velocity[node as usize]);
                        (px[k], py[k], pz[k]) = (x.x, x.y, x.z);
                        (vx[k], vy[k], vz[k]) = (v.x, v.y, v.z);
                        w[k] = nodes.inv_mass[node as usize];
                    }
                },
            );
    }

    /// Every direction's spring forces into the slot sums (near end +, far end −), and the
    /// flags. A chunk's springs reach at most into the next chunk, so the even chunks run in
    /// parallel first, each owning itself and its successor, then the odd chunks: no slot is
    /// written by two tasks at once, and each slot's sum adds in an order fixed by the grid
    /// alone (whatever the thread count).
    fn forces(
        &mut self,
        flags: &mut [u8],
        (chunk_floor, chunk_flagged): (&mut [f64], &mut [u8]),
        floor: Option<FloorInput>,
        wide: bool,
    ) {
        let (dirs, state, chunk) = (&self.directions, &self.state, self.chunk);
        let n_dirs = dirs.len();
        let [sx, sy, sz] = &mut self.sums;
        for phase in 0..2 {
            // Pairs of chunks from chunk `phase` on: each task owns a pair and works on the
            // first chunk of it (its flags and floor come first in its pieces too).
            let start = (phase * chunk).min(sx.len());
            let flag_start = (phase * n_dirs * chunk).min(flags.len());
            let floor_start = phase.min(chunk_floor.len());
            sx[start..]
                .par_chunks_mut(2 * chunk)
                .zip(sy[start..].par_chunks_mut(2 * chunk))
                .zip(sz[start..].par_chunks_mut(2 * chunk))
                .zip(flags[flag_start..].par_chunks_mut(2 * n_dirs * chunk))
                .zip(chunk_floor[floor_start..].par_chunks_mut(2))
                .zip(chunk_flagged[floor_start..].par_chunks_mut(2))
                .enumerate()
                .for_each(|(k, (((((sx, sy), sz), flags), floors), flagged))| {
                    let lo = (2 * k + phase) * chunk;
                    let (min_floor, any_flag) = (&mut floors[0], &mut flagged[0]);
                    *min_floor = f64::INFINITY;
                    *any_flag = 0;
                    for (dir, flag) in dirs.iter().zip(flags.chunks_mut(chunk)) {
                        let m = dir.rest.len().saturating_sub(lo).min(chunk);
                        if m == 0 {
                            continue;
                        }
                        let far = lo + dir.offset;
                        let args = KernelArgs {
                            near: std::array::from_fn(|k| &state[k][lo..lo + m]),
                            far: std::array::from_fn(|k| &state[k][far..far + m]),
                            rest: &dir.rest[lo..lo + m],
                            stiffness: &dir.stiffness[lo..lo + m],
                            damping: &dir.damping[lo..lo + m],
                        };
                        let out = KernelOut {
                            flag: &mut flag[..m],
                            sums: [&mut sx[..], &mut sy[..], &mut sz[..]],
                            offset: dir.offset,
                            record: None,
                        };
                        let (least, flagged) = run_kernel(&args, out, floor, wide);
                        *min_floor = min_floor.min(least);
                        *any_flag |= flagged;
                    }
                });
        }
    }
}

/// The kernel's inputs: near and far ends (x, y, z, vx, vy, vz, inverse mass) and the
/// springs' parameters, all of one length.
struct KernelArgs<'a> {
    near: [&'a [f64]; 7],
    far: [&'a [f64]; 7],
    rest: &'a [f64],
    stiffness: &'a [f64],
    damping: &'a [f64],
}

/// The kernel's outputs: the flags, and the slot sums from the near ends on (the far ends
/// are `offset` further); `record` also keeps each spring's force (for the tests).
struct KernelOut<'a> {
    flag: &'a mut [u8],
    sums: [&'a mut [f64]; 3],
    offset: usize,
    record: Option<[&'a mut [f64]; 3]>,
}

/// The kernel for this CPU; returns the smallest floor² of the springs flagged 0 and 1 where
/// some spring is flagged 1.
fn run_kernel(
    args: &KernelArgs,
    out: KernelOut,
    floor: Option<FloorInput>,
    wide: bool,
) -> (f64, u8) {
    let (c1, cap) = match floor {
        Some(FloorInput {
            mode: DispersionMode::Bounded,
            inv_dt_sq,
        }) => (0.15, inv_dt_sq),
        _ => (0.99, f64::INFINITY),
    };
    #[cfg(target_arch = "x86_64")]
    if wide {
        // SAFETY: `wide` comes from `avx512_available`, which found the CPU features the
        // function is compiled for.
        #[allow(unsafe_code)]
        return unsafe {
            match floor {
                Some(_) => kernel_avx512::<true>(args, out, c1, cap),
                None => kernel_avx512::<false>(args, out, c1, cap),
            }
        };
    }
    let _ = wide;
    match floor {
        Some(_) => kernel::<true>(args, out, c1, cap),
        None => kernel::<false>(args, out, c1, cap),
    }
}

/// Whether this CPU runs the AVX-512 kernel: AVX-512F, AVX-512VL and AVX2 (checked once).
pub fn avx512_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static WIDE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *WIDE.get_or_init(|| {
            is_x86_feature_detected!("avx512f")
                && is_x86_feature_detected!("avx512vl")
                && is_x86_feature_detected!("avx2")
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// [`kernel`] compiled for AVX-512: the same IEEE operations per spring (Rust never fuses a
/// multiply and an add by itself), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx2")]
fn kernel_avx512<const FLOOR: bool>(
    args: &KernelArgs,
    out: KernelOut,
    c1: f64,
    cap: f64,
) -> (f64, u8) {
    kernel::<FLOOR>(args, out, c1, cap)
}

/// Spring forces on the near ends (as `forces::chunk_forces` computes them, bit for bit),
/// added to the near ends' sums and taken off the far ends'; with `FLOOR`, each spring's
/// dispersion flag, the smallest speed floor² (as `speed_floor_sq`) and whether any flag is 1.
/// Slots without a spring (rest 0) give zero and flag 0.
///
/// The arithmetic loop writes only to local blocks, copied out after it: the compiler then
/// needs no run-time overlap checks between the two dozen slices, which would keep it from
/// vectorising the loop (measured: passing the outputs as separate `&mut` parameters
/// instead was slower).
#[inline(always)]
fn kernel<const FLOOR: bool>(args: &KernelArgs, out: KernelOut, c1: f64, cap: f64) -> (f64, u8) {
    const BLOCK: usize = 256;
    let m = args.rest.len();
    let (near, far) = (args.near.map(|a| &a[..m]), args.far.map(|a| &a[..m]));
    let (rest, k, d) = (&args.rest[..m], &args.stiffness[..m], &args.damping[..m]);
    let KernelOut {
        flag,
        mut sums,
        offset,
        mut record,
    } = out;
    let mut min_floor = f64::INFINITY;
    let mut any_flag = 0u8;
    // Every block fills `[..n]` of these before reading it.
    let mut f = [[0.0f64; BLOCK]; 3];
    let mut floors = [f64::INFINITY; BLOCK];
    let mut flags = [0u8; BLOCK];
    for start in (0..m).step_by(BLOCK) {
        let n = BLOCK.min(m - start);
        for j in 0..n {
            let g = start + j;
            let present = rest[g] > 0.0;
            let r = [
                near[0][g] - far[0][g],
                near[1][g] - far[1][g],
                near[2][g] - far[2][g],
            ];
            let len_sq = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            if FLOOR {
                let (wa, wb) = (near[6][g], far[6][g]);
                let rest_sq = rest[g] * rest[g];
                // `&` rather than `&&`: no branches in the loop.
                let ok = present
                    & (wa != 0.0)
                    & (wb != 0.0)
                    & (len_sq >= 0.81 * rest_sq)
                    & (len_sq <= 1.21 * rest_sq);
                let k_over_m = 0.5 * k[g] * (wa + wb);
                let fl = (k_over_m * c1 * rest_sq).min(0.2025 * rest_sq * cap);
                flags[j] = u8::from(present & !ok);
                floors[j] = if ok { fl } else { f64::INFINITY };
            }
            let len = len_sq.sqrt();
            let inv_len = 1.0 / len;
            let stretch = len - rest[g];
            let dv = [
                near[3][g] - far[3][g],
                near[4][g] - far[4][g],
                near[5][g] - far[5][g],
            ];
            let closing = (dv[0] * r[0] + dv[1] * r[1] + dv[2] * r[2]) * inv_len;
            let s = -(k[g] * stretch + d[g] * closing) * inv_len;
            // As the index-list pass: no force at (near) zero length; NaN goes through.
            let degenerate = len <= f64::MIN_POSITIVE;
            let live = present & !degenerate;
            for c in 0..3 {
                f[c][j] = if live { r[c] * s } else { 0.0 };
            }
        }
        for (c, sum) in sums.iter_mut().enumerate() {
            if let Some(record) = &mut record {
                record[c][start..start + n].copy_from_slice(&f[c][..n]);
            }
            for (sum, fc) in sum[start..start + n].iter_mut().zip(&f[c][..n]) {
                *sum += fc;
            }
            let far = start + offset;
            for (sum, fc) in sum[far..far + n].iter_mut().zip(&f[c][..n]) {
                *sum -= fc;
            }
        }
        if FLOOR {
            flag[start..start + n].copy_from_slice(&flags[..n]);
            min_floor = floors[..n].iter().fold(min_floor, |m, &f| m.min(f));
            any_flag = flags[..n].iter().fold(any_flag, |a, &f| a | f);
        }
    }
    (min_floor, any_flag)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::{fit_lattice, FitSettings, Resolution, SpringLayout};
    use crate::material::Material;
    use crate::shapes::uv_sphere;
    use crate::solver::forces::{gathered_spring_force, spring_forces, Adjacency, FloorOutput};
    use crate::solver::{World, WorldSettings};

    /// A sphere's lattice (cells outside it missing: the grid has padding) with edges, face
    /// and body diagonals (10 stencil directions), every node jittered off the grid and
    /// moving, some nodes pinned.
    fn jittered_sphere() -> World {
        jittered_sphere_of(9)
    }

    fn jittered_sphere_of(cells: u32) -> World {
        let (p, t) = uv_sphere([0.0, 0.5, 0.0], 0.4, 12, 16);
        let lattice = fit_lattice(
            &p,
            &t,
            &FitSettings {
                resolution: Resolution::CellsAlongLongest(cells),
                layout: SpringLayout::Both,
                ..FitSettings::default()
            },
        )
        .unwrap();
        let m = Material::preset("rubber").unwrap();
        let mut w = World::new(WorldSettings::default());
        w.add_lattice_body("ball", &lattice, &m, Vector3::zeros());
        let mut rng = fastrand::Rng::with_seed(7);
        let mut rnd = move || rng.f64() - 0.5;
        let cell = lattice.cell_size;
        for i in 0..w.nodes.len() {
            // Up to ±25 % of a cell: some springs leave the dispersion's floor band.
            w.nodes.position[i] += Vector3::new(rnd(), rnd(), rnd()) * (0.5 * cell);
            w.nodes.velocity[i] = Vector3::new(rnd(), rnd(), rnd()) * 3.0;
            if i % 17 == 0 {
                w.nodes.inv_mass[i] = 0.0;
            }
        }
        w
    }

    fn bounded_floor() -> FloorInput {
        FloorInput {
            mode: DispersionMode::Bounded,
            inv_dt_sq: 1.0 / (2e-4f64).powi(2),
        }
    }

    #[test]
    fn per_spring_forces_and_hints_are_the_index_lists_bit_for_bit() {
        let w = jittered_sphere();
        let (nodes, springs) = (&w.nodes, &w.springs);
        let floor = bounded_floor();
        let mut plan = StencilPlan::build(nodes, springs, &w.bodies).expect("a lattice body");
        assert_eq!(plan.bodies.len(), 1);
        assert_eq!(plan.bodies[0].directions.len(), 10);
        assert!((0..springs.len()).all(|s| plan.covers(s)));
        assert!(
            plan.bodies[0].slots() > nodes.len(),
            "the sphere's grid has padding"
        );

        // The index-list pass over every spring.
        let mut expected = vec![Vector3::zeros(); springs.len()];
        let mut exceptional = vec![0u8; springs.len()];
        let mut chunk_floor = vec![0.0; springs.len().div_ceil(PAR_CHUNK)];
        spring_forces(
            nodes,
            springs,
            &mut expected,
            Some(FloorOutput {
                mode: floor.mode,
                inv_dt_sq: floor.inv_dt_sq,
                exceptional: &mut exceptional,
                chunk_floor: &mut chunk_floor,
            }),
            None,
        );
        let found = plan.forces_with(nodes, Some(floor), false);
        let csr_least = chunk_floor.iter().fold(f64::INFINITY, |m, &f| m.min(f));
        assert_eq!(found.least, csr_least);
        let mut flags = vec![7u8; springs.len()];
        plan.write_flags(&mut flags);
        assert_eq!(flags, exceptional);
        assert!(exceptional.contains(&0) && exceptional.contains(&1));
        assert!(found.flagged);

        // Each spring's force on its near end (the kernel run once more over each whole
        // direction, keeping every force): the index lists' force on its `a` end, or that
        // force's negation when the near end is `b`.
        let body = &plan.bodies[0];
        let n_dirs = body.directions.len();
        let recorded: Vec<[Vec<f64>; 3]> = body
            .directions
            .iter()
            .map(|dir| {
                let m = dir.rest.len();
                let mut record: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; m]);
                let mut sums: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; body.slots()]);
                let mut flag = vec![0u8; m];
                let args = KernelArgs {
                    near: std::array::from_fn(|k| &body.state[k][..m]),
                    far: std::array::from_fn(|k| &body.state[k][dir.offset..dir.offset + m]),
                    rest: &dir.rest,
                    stiffness: &dir.stiffness,
                    damping: &dir.damping,
                };
                let [rx, ry, rz] = &mut record;
                let [sx, sy, sz] = &mut sums;
                let out = KernelOut {
                    flag: &mut flag,
                    sums: [sx, sy, sz],
                    offset: dir.offset,
                    record: Some([rx, ry, rz]),
                };
                run_kernel(&args, out, Some(floor), false);
                record
            })
            .collect();
        for (s, &on_a) in expected.iter().enumerate() {
            // The spring's (direction, near slot) from its flag's place in the blocks.
            let q = plan.spring_flag[s] as usize - body.flag_start;
            let (block, w) = (q / body.chunk, q % body.chunk);
            let (d, j) = (block % n_dirs, block / n_dirs * body.chunk + w);
            assert!(body.directions[d].rest[j] > 0.0);
            let r = &recorded[d];
            let f = Vector3::new(r[0][j], r[1][j], r[2][j]);
            let want = if body.node_of_slot[j] == springs.a[s] {
                on_a
            } else {
                -on_a
            };
            assert_eq!(f, want, "spring {s}");
        }

        // Per node, the sums agree to rounding (they add in another order).
        let adjacency = Adjacency::new(nodes.len(), springs);
        for i in 0..nodes.len() {
            let want = gathered_spring_force(&adjacency, &expected, i);
            let got = plan.node_force(i).unwrap();
            assert!(
                (got - want).norm() <= 1e-9 * (1.0 + want.norm()),
                "node {i}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn the_avx512_kernel_gives_the_baseline_bits() {
        if !avx512_available() {
            eprintln!("this CPU has no AVX-512: only the baseline kernel runs here");
            return;
        }
        let w = jittered_sphere();
        let floor = Some(bounded_floor());
        let mut plain = StencilPlan::build(&w.nodes, &w.springs, &w.bodies).unwrap();
        let mut wide = plain.clone();
        let a = plain.forces_with(&w.nodes, floor, false);
        let b = wide.forces_with(&w.nodes, floor, true);
        assert_eq!(a, b);
        assert_eq!(plain.flags, wide.flags);
        assert_eq!(plain.bodies[0].sums, wide.bodies[0].sums);
    }

    #[test]
    fn the_sums_are_the_same_bits_on_one_and_two_threads() {
        // 25³ slots in chunks of 768: both phases run several chunks side by side.
        let w = jittered_sphere_of(24);
        let floor = Some(bounded_floor());
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut plan = StencilPlan::build(&w.nodes, &w.springs, &w.bodies).unwrap();
            let least = pool.install(|| plan.forces(&w.nodes, floor));
            assert!(plan.bodies[0].chunk_count() >= 8);
            (least, plan.flags.clone(), plan.bodies[0].sums.clone())
        };
        assert_eq!(run(1), run(2));
    }

    #[test]
    fn a_body_with_two_springs_on_one_pair_stays_on_the_index_lists() {
        let mut w = jittered_sphere();
        assert!(StencilPlan::build(&w.nodes, &w.springs, &w.bodies).is_some());
        // Spring 1 made a second spring between spring 0's ends: one slot, two springs.
        w.springs.a[1] = w.springs.b[0];
        w.springs.b[1] = w.springs.a[0];
        assert!(StencilPlan::build(&w.nodes, &w.springs, &w.bodies).is_none());
    }
}
