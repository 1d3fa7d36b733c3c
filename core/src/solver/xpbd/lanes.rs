//! The cube cells' constraints eight cells at a time: the same constraints as
//! [`super::cells`]'s scalar path (cell volume, shear at the four corners, collapse barriers at
//! all eight), on structure-of-arrays lanes of single precision that the compiler vectorises.
//! Eight cells of one colour share no node, so solving them side by side is what solving them
//! one after the other would do; each lane's arithmetic is fixed, so the bits do not depend
//! on the thread count or on which lane a cell takes. A condition the scalar path branches on
//! (a barrier only below `COLLAPSE_J`, a shear constraint only away from rest) is a lane mask
//! here: a masked lane's step is zero. Every operation is the scalar path's, in its order, in
//! `f32` in the cell's own frame, so a lane agrees with the scalar path to single precision
//! (tested).

use super::cells::COLLAPSE_J;
use super::lane_io;
use crate::solver::team::Disjoint;
use nalgebra::Vector3;
use std::mem::MaybeUninit;

/// Cells per group: eight single-precision lanes fill a 256-bit AVX register.
pub(crate) const LANES: usize = 8;

/// The lanes' number type. Each cell is solved in its own frame (its nodes relative to its
/// first one), so single precision resolves a cell's strain to about 1e-7 whatever the
/// body's size or distance from the origin, and the positions themselves stay `f64`: a node
/// moves by the `f32` difference the solve made. Eight lanes of `f32` took the standard
/// scene's kernel from 1.53 s to 1.06 s on one thread against four of `f64`.
type S = f32;
type L = [S; LANES];
type V3 = Vector3<f64>;

/// Below this a shear or volume constraint's value is single precision's rounding, not a
/// strain: the lanes leave it alone, so that a body at rest stays still (solved from its
/// rounding, two cubes at rest drifted to 1e-4 m/s in half a second) and a rigid motion
/// moves no node against another. The rounding of a cell at rest, turned any way, is 2e-7 to
/// 4e-7 at most (a test turns 3 200 of them); two millionths of strain are two micrometres
/// on a metre.
const NOISE_FLOOR: S = 2e-6;

/// A condition per lane: 1 where it holds, 0 where not (as `f64`, so that setting and testing
/// it stay in vector registers: as `[bool; LANES]` each lane went through a byte in memory).
type Mask = L;

/// The lanes where `holds`.
#[inline(always)]
fn mask(holds: impl Fn(usize) -> bool) -> Mask {
    map(|l| if holds(l) { 1.0 } else { 0.0 })
}

/// Whether no lane holds: the masks' bits OR-ed together, which vectorises (a lane-by-lane
/// `all` with its early exit stayed eight compares and branches).
#[inline(always)]
fn none(on: &Mask) -> bool {
    on.iter().fold(0u32, |any, m| any | m.to_bits()) == 0
}

/// A vector per lane (`repr(C)`: three `L` in a row, as [`lane_io`] lays them out).
#[derive(Clone, Copy)]
#[repr(C)]
struct V {
    x: L,
    y: L,
    z: L,
}

#[inline(always)]
fn map(f: impl Fn(usize) -> S) -> L {
    std::array::from_fn(f)
}

/// Three lane vectors (a corner's edges or gradients), `$e` written out for `$k` = 0, 1, 2: as
/// `std::array::from_fn` calls, or closures, the compiler kept them out of line (9 % of the
/// standard scene's samples).
macro_rules! three {
    (|$k:ident| $e:expr) => {
        [
            {
                let $k = 0;
                $e
            },
            {
                let $k = 1;
                $e
            },
            {
                let $k = 2;
                $e
            },
        ]
    };
}

impl V {
    #[inline(always)]
    fn sub(&self, o: &V) -> V {
        V {
            x: map(|l| self.x[l] - o.x[l]),
            y: map(|l| self.y[l] - o.y[l]),
            z: map(|l| self.z[l] - o.z[l]),
        }
    }
    #[inline(always)]
    fn add(&self, o: &V) -> V {
        V {
            x: map(|l| self.x[l] + o.x[l]),
            y: map(|l| self.y[l] + o.y[l]),
            z: map(|l| self.z[l] + o.z[l]),
        }
    }
    #[inline(always)]
    fn scale(&self, s: &L) -> V {
        V {
            x: map(|l| self.x[l] * s[l]),
            y: map(|l| self.y[l] * s[l]),
            z: map(|l| self.z[l] * s[l]),
        }
    }
    #[inline(always)]
    fn neg(&self) -> V {
        V {
            x: map(|l| -self.x[l]),
            y: map(|l| -self.y[l]),
            z: map(|l| -self.z[l]),
        }
    }
    #[inline(always)]
    fn dot(&self, o: &V) -> L {
        map(|l| self.x[l] * o.x[l] + self.y[l] * o.y[l] + self.z[l] * o.z[l])
    }
    #[inline(always)]
    fn cross(&self, o: &V) -> V {
        V {
            x: map(|l| self.y[l] * o.z[l] - self.z[l] * o.y[l]),
            y: map(|l| self.z[l] * o.x[l] - self.x[l] * o.z[l]),
            z: map(|l| self.x[l] * o.y[l] - self.y[l] * o.x[l]),
        }
    }
}

/// `x += g * (w * dl)` lane by lane.
#[inline(always)]
fn step(x: &mut V, g: &V, w: &L, dl: &L) {
    let k = map(|l| w[l] * dl[l]);
    *x = x.add(&g.scale(&k));
}

/// `-value / denominator` where the lane is `active` (see [`Mask`]), the denominator positive
/// and the quotient finite; 0 elsewhere. Every lane divides and a mask picks (a branch per lane
/// kept the divisions scalar: 8 % of the kernel's instructions). The quotient's finiteness is
/// tested as `q − q == 0` (NaN for infinities and NaN): written as `d < ∞`, the compiler
/// turned the test into integer bit tests one lane at a time (a tenth of the kernel).
#[inline(always)]
fn multiplier(value: &L, denominator: &L, active: &Mask) -> L {
    map(|l| {
        let d = denominator[l];
        let q = -value[l] / d;
        // `q − q` is 0 for a finite `q` and NaN otherwise (meant: not a slip for `0`).
        #[allow(clippy::eq_op)]
        let finite = q - q == 0.0;
        if (active[l] != 0.0) & (d > 0.0) & finite {
            q
        } else {
            0.0
        }
    })
}

/// Which sweep of a substep a solve is, and the multipliers it carries between sweeps.
/// XPBD's multiplier `λ` of each constraint starts at zero every substep; a sweep after the
/// first takes up where the last left it, `Δλ = −(C + α̃ λ) / (Σ w |∇C|² + α̃)`, so that a
/// second sweep converges the substep's solve further instead of stiffening the material (a
/// second sweep that starts again from `λ = 0` makes a lone node's sag `r/(1+r)` of its
/// material's, `r = α̃/(w + α̃)`).
pub(crate) enum Sweep<'a, T> {
    /// The substep's only sweep: nothing is kept.
    Lone,
    /// The first of two: each constraint's `Δλ` is written to its slot.
    First(&'a mut T),
    /// A later sweep: each constraint reads its slot and adds its `Δλ`.
    Again(&'a mut T),
}

impl<'a, T> Sweep<'a, T> {
    /// The slots, and whether this is a later sweep (`None`: a lone one).
    pub(crate) fn slots(self) -> Option<(&'a mut T, bool)> {
        match self {
            Sweep::Lone => None,
            Sweep::First(t) => Some((t, false)),
            Sweep::Again(t) => Some((t, true)),
        }
    }
}

/// The multipliers of a group's constraints: the volume, then the shear at each of the four
/// corners, a lane each.
pub(crate) type Multipliers = [L; 5];

/// `C + α̃ λ` for a sweep after the first; `C` otherwise.
#[inline(always)]
fn residual(value: &L, alpha: &L, slot: &Option<(&mut L, bool)>) -> L {
    match slot {
        Some((lambda, true)) => map(|l| value[l] + alpha[l] * lambda[l]),
        _ => *value,
    }
}

/// Keep a constraint's step `dl` in its slot: written by the first sweep, added to by a
/// later one.
#[inline(always)]
fn keep(slot: Option<(&mut L, bool)>, dl: &L) {
    match slot {
        Some((lambda, true)) => *lambda = map(|l| lambda[l] + dl[l]),
        Some((lambda, false)) => *lambda = *dl,
        None => {}
    }
}

/// The parameters of a group of cube cells (one per lane) of the same corner parity.
#[derive(Debug, Clone)]
pub(crate) struct Cubes {
    pub inv_h: L,
    /// Compliances over Δt²: volume, shear.
    pub hydro: L,
    pub dev: L,
    /// `sqrt` of the stiffness factors, per axis, a lane each.
    pub axis_root: [L; 3],
    /// The shear corners are `1, 2, 4, 7` (else `0, 3, 5, 6`).
    pub odd: bool,
}

/// A group's inverse masses in lanes: corner `k` of lane `l` at `[k][l]` ([`mass_lanes`]).
pub(crate) type MassLanes = [L; 8];

/// A group's nodes: the node ids of one to [`LANES`] cells (`nodes`, one cell a lane) into
/// the positions `x` (read and written in place), and their inverse masses in lanes.
pub(crate) struct Gather<'a, 'x> {
    pub nodes: &'a [[u32; 8]],
    /// The highest node id in `nodes` ([`highest_node`]): the bounds are checked against it
    /// once (the largest of 64 ids, taken each time, was 3 % of the kernel).
    pub highest: u32,
    pub x: &'a Disjoint<'x, V3>,
    /// [`mass_lanes`] of `nodes`: kept by the caller while the masses stay (read with the
    /// positions at every group, they were 7 % of the kernel's instructions).
    pub masses: &'a MassLanes,
}

/// The inverse masses `w` of a group's nodes in lanes, a short group's last cell repeated.
pub(crate) fn mass_lanes(nodes: &[[u32; 8]], w: &[f64]) -> MassLanes {
    let cell = |l: usize| &nodes[l.min(nodes.len().saturating_sub(1))];
    std::array::from_fn(|k| map(|l| w[cell(l)[k] as usize] as S))
}

/// The highest node id of a group's cells.
pub(crate) fn highest_node(nodes: &[[u32; 8]]) -> u32 {
    nodes.iter().flatten().copied().max().unwrap_or(0)
}

/// Solve the cells `from` names, reading their nodes' positions from `from.x` and moving
/// them there, with 256-bit AVX arithmetic where the CPU has it: the same IEEE operations in
/// the same order (AVX without FMA fuses nothing), so the same bits on every CPU. A group of
/// fewer than [`LANES`] cells fills its other lanes with its last cell, whose results are
/// not written. The nodes are read straight into the lanes and moved straight back (a copy
/// of each cell's eight nodes first, then the lanes from it, cost the standard scene a tenth
/// of its time in copies; a buffer of solved cells written back in a pass of its own, 5 %).
///
/// # Safety
/// No other task of the pass touches the cells' nodes (a colour's cells share none), and
/// `from.highest` is [`highest_node`] of `from.nodes`.
// Kept out of line: inlined into the colour loop it zeroed its lane buffers with a memset
// every call and the standard scene ran 11 % slower.
#[inline(never)]
#[allow(unsafe_code)]
pub(crate) unsafe fn solve_cubes(from: &Gather, p: &Cubes, sweep: Sweep<Multipliers>) {
    #[cfg(target_arch = "x86_64")]
    if avx_available() {
        // SAFETY: `avx_available` found the CPU feature the function is compiled for; the
        // nodes are the caller's alone.
        return unsafe { solve_cubes_avx(from, p, sweep) };
    }
    // SAFETY: the caller's.
    unsafe { solve_cubes_here(from, p, sweep) }
}

/// Whether this CPU has AVX (checked once).
#[cfg(target_arch = "x86_64")]
fn avx_available() -> bool {
    static AVX: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX.get_or_init(|| is_x86_feature_detected!("avx"))
}

/// [`solve_cubes_here`] compiled for AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[allow(unsafe_code)]
unsafe fn solve_cubes_avx(from: &Gather, p: &Cubes, sweep: Sweep<Multipliers>) {
    // SAFETY: the caller's.
    unsafe { solve_cubes_here(from, p, sweep) }
}

#[inline(always)]
#[allow(unsafe_code)]
unsafe fn solve_cubes_here(from: &Gather, p: &Cubes, sweep: Sweep<Multipliers>) {
    let cells = from.nodes.len();
    assert!(
        (1..=LANES).contains(&cells),
        "a group is 1 to {LANES} cells"
    );
    let nodes: [[u32; 8]; LANES] = std::array::from_fn(|l| from.nodes[l.min(cells - 1)]);
    // Bounds checked once for the group, not at each of its 128 reads and 64 writes.
    debug_assert_eq!(from.highest, highest_node(from.nodes));
    let highest = from.highest as usize;
    assert!(highest < from.x.len(), "node {highest} out of bounds");
    // SAFETY (`read`, `write`): in bounds (checked above), and the nodes are this task's
    // alone (the caller's contract).
    let mut x = MaybeUninit::<[V; 8]>::uninit();
    let mut x = unsafe {
        lane_io::read(from.x, &nodes, x.as_mut_ptr().cast());
        // Every lane was written (`V` is three `L` in a row: `repr(C)`).
        x.assume_init()
    };
    let wk = from.masses;
    let start = x;
    let [mut volume_slot, mut shear_slots @ ..] = match sweep.slots() {
        Some((lambda, again)) => {
            let [v, a, b, c, d] = lambda.each_mut();
            [v, a, b, c, d].map(|slot| Some((slot, again)))
        }
        None => [None, None, None, None, None],
    };
    volume(&mut x, wk, p, volume_slot.take());
    let corners = if p.odd { [1, 2, 4, 7] } else { [0, 3, 5, 6] };
    for (c, slot) in corners.into_iter().zip(&mut shear_slots) {
        shear(&mut x, wk, c, p, slot.take());
    }
    for c in 0..8 {
        barrier(&mut x, wk, c, p);
    }
    // Each node moves by what the solve moved it: a node it left alone keeps its bits.
    // SAFETY: as above.
    unsafe {
        let (after, before) = (x.as_ptr().cast(), start.as_ptr().cast());
        lane_io::write(from.x, &nodes, cells, after, before);
    }
}

/// `V/V_0 − 1` over the six Kuhn tets, in the closed form of [`super::cells::cube_volume`].
#[inline(always)]
fn volume(x: &mut [V; 8], w: &[L; 8], p: &Cubes, slot: Option<(&mut L, bool)>) {
    let grad = six_volume_gradient(x);
    let six_v = grad.diagonal.dot(&grad.loop_area);
    // The gradients below are 6 V's: a sixth of them is V's.
    let q = map(|l| p.inv_h[l] * p.inv_h[l] * p.inv_h[l] * (1.0 / 6.0));
    let value = map(|l| six_v[l] * q[l] - 1.0);
    let value = residual(&value, &p.hydro, &slot);
    let ends = grad.loop_area.dot(&grad.loop_area);
    let mut denominator = map(|l| p.hydro[l] + (w[0][l] + w[7][l]) * ends[l] * q[l] * q[l]);
    for (k, g) in grad.side.iter().enumerate() {
        let n = g.dot(g);
        let wk = &w[SIDE_NODES[k]];
        denominator = map(|l| denominator[l] + wk[l] * n[l] * q[l] * q[l]);
    }
    let active = mask(|l| p.hydro[l].is_finite() & (value[l].abs() > NOISE_FLOOR));
    let dl = multiplier(&value, &denominator, &active);
    keep(slot, &dl);
    let dl = map(|l| dl[l] * q[l]);
    step(&mut x[0], &grad.loop_area.neg(), &w[0], &dl);
    step(&mut x[7], &grad.loop_area, &w[7], &dl);
    for (k, g) in grad.side.iter().enumerate() {
        let n = SIDE_NODES[k];
        step(&mut x[n], g, &w[n], &dl);
    }
}

/// The six nodes off the 0–7 diagonal, in the order of [`SixVolume::side`].
const SIDE_NODES: [usize; 6] = [1, 2, 4, 3, 5, 6];

/// Six times a cube cell's Kuhn volume `6V = d · S` and its gradient (see
/// [`super::cells::cube_volume`]): `d = x₇ − x₀`, `S` the hexagon's loop area; the gradient
/// is `−S` at node 0, `S` at node 7 and `side` at [`SIDE_NODES`].
struct SixVolume {
    diagonal: V,
    loop_area: V,
    side: [V; 6],
}

#[inline(always)]
fn six_volume_gradient(x: &[V; 8]) -> SixVolume {
    let u = |k: usize| x[k].sub(&x[0]);
    let d = x[7].sub(&x[0]);
    let (u1, u2, u3, u4, u5, u6) = (u(1), u(2), u(3), u(4), u(5), u(6));
    let (a1, a2, a3) = (u3.sub(&u5), u6.sub(&u3), u5.sub(&u6));
    let (b1, b2, b3) = (u1.sub(&u2), u4.sub(&u1), u2.sub(&u4));
    let loop_area = u1.cross(&a1).add(&u2.cross(&a2)).add(&u4.cross(&a3));
    SixVolume {
        side: [
            a1.cross(&d),
            a2.cross(&d),
            a3.cross(&d),
            d.cross(&b1),
            d.cross(&b2),
            d.cross(&b3),
        ],
        diagonal: d,
        loop_area,
    }
}

/// `s_k / h` of corner `c`'s three edges, per lane.
#[inline(always)]
fn signs(c: usize, inv_h: &L) -> [L; 3] {
    [1, 2, 4].map(|bit| map(|l| if c & bit == 0 { inv_h[l] } else { -inv_h[l] }))
}

/// Project corner `c`'s constraint of value `value` whose gradient by column k of F is
/// `g[k]` (already times `s_k`).
#[inline(always)]
fn project(
    x: &mut [V; 8],
    w: &[L; 8],
    (c, g): (usize, [V; 3]),
    (value, alpha): (&L, &L),
    on: &Mask,
    slot: Option<(&mut L, bool)>,
) {
    let value = &residual(value, alpha, &slot);
    let nb = [c ^ 1, c ^ 2, c ^ 4];
    let apex = g[0].add(&g[1]).add(&g[2]).neg();
    let mut denominator = map(|l| alpha[l]);
    let a = apex.dot(&apex);
    denominator = map(|l| denominator[l] + w[c][l] * a[l]);
    for k in 0..3 {
        let n = g[k].dot(&g[k]);
        denominator = map(|l| denominator[l] + w[nb[k]][l] * n[l]);
    }
    let dl = multiplier(value, &denominator, on);
    keep(slot, &dl);
    step(&mut x[c], &apex, &w[c], &dl);
    for k in 0..3 {
        step(&mut x[nb[k]], &g[k], &w[nb[k]], &dl);
    }
}

/// The shear constraint `sqrt(Σ W_ij E_ij²)` of corner `c`.
#[inline(always)]
fn shear(x: &mut [V; 8], w: &[L; 8], c: usize, p: &Cubes, slot: Option<(&mut L, bool)>) {
    let nb = [c ^ 1, c ^ 2, c ^ 4];
    let s = signs(c, &p.inv_h);
    let f: [V; 3] = three!(|k| x[nb[k]].sub(&x[c]).scale(&s[k]));
    // Green strain, weighted by the axes' stiffness.
    let mut e = [[[0.0; LANES]; 3]; 3];
    let mut we = [[[0.0; LANES]; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            // `f_j · f_i` is `f_i · f_j` to the bit (each product commutes), so once a pair.
            let d = f[i].dot(&f[j]);
            e[i][j] = map(|l| 0.5 * (d[l] - if i == j { 1.0 } else { 0.0 }));
            e[j][i] = e[i][j];
        }
    }
    for i in 0..3 {
        for j in 0..3 {
            we[i][j] = map(|l| e[i][j][l] * p.axis_root[i][l] * p.axis_root[j][l]);
        }
    }
    // Column by column, as the scalar path's matrix dot product adds.
    let mut sum = [0.0; LANES];
    for j in 0..3 {
        for i in 0..3 {
            sum = map(|l| sum[l] + e[i][j][l] * we[i][j][l]);
        }
    }
    let value = map(|l| sum[l].sqrt());
    let on = mask(|l| value[l] > NOISE_FLOOR);
    let inv = map(|l| {
        if value[l] > NOISE_FLOOR {
            1.0 / value[l]
        } else {
            0.0
        }
    });
    let g: [V; 3] = three!(|k| {
        f[0].scale(&we[0][k])
            .add(&f[1].scale(&we[1][k]))
            .add(&f[2].scale(&we[2][k]))
            .scale(&inv)
            .scale(&s[k])
    });
    project(x, w, (c, g), (&value, &p.dev), &on, slot);
}

/// The collapse barrier `det F_c ≥ COLLAPSE_J` of corner `c` (hard).
#[inline(always)]
fn barrier(x: &mut [V; 8], w: &[L; 8], c: usize, p: &Cubes) {
    let nb = [c ^ 1, c ^ 2, c ^ 4];
    let s = signs(c, &p.inv_h);
    let f: [V; 3] = three!(|k| x[nb[k]].sub(&x[c]).scale(&s[k]));
    let first = f[1].cross(&f[2]);
    let j = f[0].dot(&first);
    let on = mask(|l| j[l] < COLLAPSE_J as S);
    if none(&on) {
        return;
    }
    let cof = [first, f[2].cross(&f[0]), f[0].cross(&f[1])];
    let g: [V; 3] = three!(|k| cof[k].scale(&s[k]));
    let value = map(|l| j[l] - COLLAPSE_J as S);
    project(x, w, (c, g), (&value, &[0.0; LANES]), &on, None);
}

/// The lanes against [`super::cells`]'s scalar path, at rest, and in short groups.
#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Material;
    use crate::solver::xpbd::cells::tests::unit_cube;
    use crate::solver::xpbd::cells::{lame, solve_cell, Shape};

    /// Cells to solve side by side, with their inverse masses, axis factors and compliances
    /// over Δt² (volume, shear).
    struct LaneCells {
        cells: Vec<[V3; 8]>,
        w: Vec<[f64; 8]>,
        axis: [[f64; 3]; LANES],
        alphas: (f64, f64),
    }

    /// Eight deformed cube cells of edge `h` (one collapsing at a corner, one anisotropic),
    /// shifted by `at`.
    fn lane_cells(h: f64, at: V3) -> LaneCells {
        let jelly = Material::preset("jelly").unwrap();
        let mut rng = fastrand::Rng::with_seed(7);
        let mut cells = Vec::new();
        for l in 0..LANES {
            let mut jitter = |_| V3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5) * 0.04;
            let mut cell: [V3; 8] = unit_cube().map(|p| at + (p + jitter(())) * (h / 0.1));
            if l == 2 {
                cell[7] = cell[0] + V3::new(0.01, 0.01, 0.01) * (h / 0.1);
            }
            cells.push(cell);
        }
        let w = (0..LANES).map(|l| [50.0 - 5.0 * l as f64; 8]).collect();
        let mut axis = [[1.0; 3]; LANES];
        axis[3] = [1.0, 2.0, 0.5];
        let (mu, lambda) = lame(&jelly);
        let dt2 = 1.0 / (240.0f64 * 240.0);
        let hydro = 1.0 / (lambda * h * h * h) / dt2;
        let dev = 1.0 / (2.0 * mu * h * h * h / 4.0) / dt2;
        LaneCells {
            cells,
            w,
            axis,
            alphas: (hydro, dev),
        }
    }

    /// `cells` (each its own eight nodes) solved as one lane group; their nodes after.
    fn run_lanes(cells: &[[V3; 8]], w: &[[f64; 8]], cubes: &Cubes) -> Vec<[V3; 8]> {
        // SAFETY: one thread, cells with their own nodes.
        #[allow(unsafe_code)]
        run_lanes_with(cells, w, |from| unsafe {
            solve_cubes(from, cubes, Sweep::Lone)
        })
    }

    /// `cells` (each its own eight nodes) gathered as one lane group for `solve`; their
    /// nodes after.
    fn run_lanes_with(
        cells: &[[V3; 8]],
        w: &[[f64; 8]],
        solve: impl FnOnce(&Gather),
    ) -> Vec<[V3; 8]> {
        let nodes: Vec<[u32; 8]> = (0..cells.len())
            .map(|l| std::array::from_fn(|k| (8 * l + k) as u32))
            .collect();
        let mut x: Vec<V3> = cells.iter().flatten().copied().collect();
        let wn: Vec<f64> = w.iter().flatten().copied().collect();
        let from = Gather {
            nodes: &nodes,
            highest: highest_node(&nodes),
            x: &Disjoint::new(&mut x),
            masses: &mass_lanes(&nodes, &wn),
        };
        solve(&from);
        x.chunks(8).map(|c| std::array::from_fn(|k| c[k])).collect()
    }

    /// The lane parameters of [`lane_cells`]' cells `which` (odd corners).
    fn lane_group(h: f64, cells: &LaneCells, which: &std::ops::Range<usize>) -> Cubes {
        let (hydro, dev) = cells.alphas;
        let axis = |l: usize| cells.axis[which.start + l.min(which.len() - 1)];
        Cubes {
            inv_h: [(1.0 / h) as f32; LANES],
            hydro: [hydro as f32; LANES],
            dev: [dev as f32; LANES],
            axis_root: std::array::from_fn(|i| std::array::from_fn(|l| axis(l)[i] as f32)),
            odd: true,
        }
    }

    /// The cells `which` of [`lane_cells`] solved as one lane group; every cell's nodes after.
    fn solve_lanes(h: f64, at: V3, which: std::ops::Range<usize>) -> Vec<[V3; 8]> {
        let group = lane_cells(h, at);
        let cubes = lane_group(h, &group, &which);
        let mut cells = group.cells;
        let solved = run_lanes(&cells[which.clone()], &group.w[which.clone()], &cubes);
        cells[which].copy_from_slice(&solved);
        cells
    }

    /// Cube cells at rest, turned any way and placed anywhere within a kilometre, from a
    /// millimetre to ten metres across, both parities, anisotropic: the lanes leave every
    /// node where it is, to the bit (their rounding stays under the noise floor).
    #[test]
    fn the_lanes_leave_cells_at_rest_alone() {
        let jelly = Material::preset("jelly").unwrap();
        let (mu, lambda) = lame(&jelly);
        let mut rng = fastrand::Rng::with_seed(11);
        let mut random =
            |scale: f64| V3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5) * scale;
        for trial in 0..400 {
            let h = 10f64.powf(random(8.0).x - 2.0);
            let cells: Vec<[V3; 8]> = (0..LANES)
                .map(|_| {
                    let turn = nalgebra::UnitQuaternion::from_scaled_axis(random(8.0));
                    let at = random(2000.0);
                    unit_cube().map(|p| at + turn * (p * (h / 0.1)))
                })
                .collect();
            let w = vec![[1.0 / (1000.0 * h * h * h); 8]; LANES];
            let dt2 = 1.0 / (720.0f64 * 720.0);
            let cubes = Cubes {
                inv_h: [(1.0 / h) as f32; LANES],
                hydro: [(1.0 / (lambda * h * h * h) / dt2) as f32; LANES],
                dev: [(1.0 / (2.0 * mu * h * h * h / 4.0) / dt2) as f32; LANES],
                axis_root: [[1.0; LANES], [1.5; LANES], [0.7; LANES]],
                odd: trial % 2 == 1,
            };
            assert_eq!(run_lanes(&cells, &w, &cubes), cells, "trial {trial}, h {h}");
        }
    }

    /// Eight deformed cube cells through the lane path (single precision, each in its own
    /// frame) and one by one through the scalar path (double): the same moves to a millionth
    /// of a cell, for a 10 cm cell at the origin and a 1 mm cell a kilometre away. Lanes
    /// holding world coordinates in `f32` would miss the far cell by half its size.
    #[test]
    fn the_lane_path_agrees_with_the_scalar_path() {
        for (h, at) in [(0.1, V3::zeros()), (1e-3, V3::new(1000.0, -700.0, 300.0))] {
            let LaneCells {
                cells,
                w,
                axis,
                alphas,
            } = lane_cells(h, at);
            let lanes = solve_lanes(h, at, 0..LANES);
            let shape = Shape::Cube {
                inv_h: 1.0 / h,
                odd: true,
            };
            let mut largest_move = 0.0f64;
            for (l, cell) in cells.iter().enumerate() {
                let mut scalar = *cell;
                solve_cell(&mut scalar, &w[l], shape, alphas, &axis[l], Sweep::Lone);
                for k in 0..8 {
                    largest_move = largest_move.max((scalar[k] - cell[k]).norm());
                    let miss = (lanes[l][k] - scalar[k]).norm();
                    assert!(miss < 1e-6 * h, "h {h}: cell {l} node {k} misses by {miss}");
                }
            }
            assert!(
                largest_move > 1e-2 * h,
                "the cells hardly moved: {largest_move}"
            );
        }
    }

    /// Two sweeps, the second taking up the first's multipliers, through the lanes and
    /// through the scalar path: the same moves to a millionth of a cell; and the second
    /// sweep's moves are not those of a sweep that starts afresh.
    #[test]
    fn the_lanes_carry_the_multipliers_as_the_scalar_path_does() {
        let h = 0.1;
        let group = lane_cells(h, V3::zeros());
        let cubes = lane_group(h, &group, &(0..LANES));
        let LaneCells {
            cells,
            w,
            axis,
            alphas,
        } = group;
        let lanes = |carry: bool| {
            // SAFETY: one thread, cells with their own nodes.
            #[allow(unsafe_code)]
            run_lanes_with(&cells, &w, |from| unsafe {
                let mut lambda = [[0.0; LANES]; 5];
                solve_cubes(from, &cubes, Sweep::First(&mut lambda));
                let again = if carry {
                    Sweep::Again(&mut lambda)
                } else {
                    Sweep::Lone
                };
                solve_cubes(from, &cubes, again);
            })
        };
        let (carried, afresh) = (lanes(true), lanes(false));
        let shape = Shape::Cube {
            inv_h: 1.0 / h,
            odd: true,
        };
        let mut apart = 0.0f64;
        for (l, cell) in cells.iter().enumerate() {
            let mut scalar = *cell;
            let mut lambda = [0.0; 5];
            for again in [false, true] {
                let sweep = if again {
                    Sweep::Again(&mut lambda)
                } else {
                    Sweep::First(&mut lambda)
                };
                solve_cell(&mut scalar, &w[l], shape, alphas, &axis[l], sweep);
            }
            for k in 0..8 {
                let miss = (carried[l][k] - scalar[k]).norm();
                assert!(miss < 1e-6 * h, "cell {l} node {k} misses by {miss}");
                apart = apart.max((carried[l][k] - afresh[l][k]).norm());
            }
        }
        assert!(apart > 1e-3 * h, "carried and afresh {apart} apart");
    }

    /// A group of three cells moves its cells' nodes as those cells' lanes of a full group
    /// do, to the bit, and leaves every other node alone.
    #[test]
    fn a_short_group_solves_its_cells_as_a_full_one() {
        let (h, at) = (0.1, V3::new(0.3, 0.2, 0.1));
        let cells = lane_cells(h, at).cells;
        let full = solve_lanes(h, at, 0..LANES);
        let short = solve_lanes(h, at, 2..5);
        for l in 0..LANES {
            let expected = if (2..5).contains(&l) {
                full[l]
            } else {
                cells[l]
            };
            assert_eq!(short[l], expected, "cell {l}");
        }
    }
}
