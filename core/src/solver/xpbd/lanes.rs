//! The cube cells' constraints four cells at a time: the same constraints as
//! [`super::cells`]'s scalar path (cell volume, shear at the four corners, collapse barriers at
//! all eight), on structure-of-arrays lanes that the compiler vectorises. Four cells of one
//! colour share no node, so solving them side by side is what solving them one after the other
//! would do; each lane's arithmetic is fixed, so the bits do not depend on the thread count.
//! A condition the scalar path branches on (a barrier only below `COLLAPSE_J`, a shear
//! constraint only away from rest) is a lane mask here: a masked lane's step is zero. Every
//! operation is the scalar path's, in its order, so a lane gives the scalar path's bits
//! (tested).

use super::cells::COLLAPSE_J;
use crate::solver::team::Disjoint;
use nalgebra::Vector3;

/// Cells per group.
pub(crate) const LANES: usize = 4;

type L = [f64; LANES];
type V3 = Vector3<f64>;

/// A condition per lane: 1 where it holds, 0 where not (as `f64`, so that setting and testing
/// it stay in vector registers: as `[bool; LANES]` each lane went through a byte in memory).
type Mask = L;

/// The lanes where `holds`.
#[inline(always)]
fn mask(holds: impl Fn(usize) -> bool) -> Mask {
    map(|l| if holds(l) { 1.0 } else { 0.0 })
}

/// A vector per lane.
#[derive(Clone, Copy)]
struct V {
    x: L,
    y: L,
    z: L,
}

#[inline(always)]
fn map(f: impl Fn(usize) -> f64) -> L {
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

#[inline(always)]
fn map_v3(f: impl Fn(usize) -> V3) -> [V3; LANES] {
    std::array::from_fn(f)
}

impl V {
    const ZERO: V = V {
        x: [0.0; LANES],
        y: [0.0; LANES],
        z: [0.0; LANES],
    };
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

/// `-value / denominator` where the lane is `active` (see [`Mask`]) and the denominator
/// positive and finite; 0 elsewhere. Every lane divides and a mask picks (a branch per lane kept the
/// divisions scalar: 8 % of the kernel's instructions).
#[inline(always)]
fn multiplier(value: &L, denominator: &L, active: &Mask) -> L {
    map(|l| {
        let d = denominator[l];
        let q = -value[l] / d;
        if (active[l] != 0.0) & (d > 0.0) & (d < f64::INFINITY) {
            q
        } else {
            0.0
        }
    })
}

/// The parameters of a group of cube cells (one per lane) of the same corner parity.
pub(crate) struct Cubes {
    pub inv_h: L,
    /// Compliances over Δt²: volume, shear.
    pub hydro: L,
    pub dev: L,
    /// `sqrt` of the per-axis stiffness factors, per lane.
    pub axis_root: [[f64; 3]; LANES],
    /// The shear corners are `1, 2, 4, 7` (else `0, 3, 5, 6`).
    pub odd: bool,
}

/// A group's nodes: the four cells' node ids (`nodes`, one cell a lane) into the positions
/// `x` (read and written in place) and inverse masses `w`.
pub(crate) struct Gather<'a, 'x> {
    pub nodes: &'a [[u32; 8]],
    pub x: &'a Disjoint<'x, V3>,
    pub w: &'a [f64],
}

/// Solve the four cells `from` names, reading their nodes' positions from `from.x` and
/// writing the new ones back there, with 256-bit AVX arithmetic where the CPU has it: the
/// same IEEE operations in the same order (AVX without FMA fuses nothing), so the same bits
/// on every CPU. The nodes are read straight into the lanes and written straight back (a copy
/// of each cell's eight nodes first, then the lanes from it, cost the standard scene a tenth
/// of its time in copies; a buffer of solved cells written back in a pass of its own, 5 %).
///
/// # Safety
/// No other task of the pass touches the four cells' nodes (a colour's cells share none).
// Kept out of line: inlined into the colour loop it zeroed its lane buffers with a memset
// every call and the standard scene ran 11 % slower.
#[inline(never)]
#[allow(unsafe_code)]
pub(crate) unsafe fn solve_cubes(from: &Gather, p: &Cubes) {
    #[cfg(target_arch = "x86_64")]
    if avx_available() {
        // SAFETY: `avx_available` found the CPU feature the function is compiled for; the
        // nodes are the caller's alone.
        return unsafe { solve_cubes_avx(from, p) };
    }
    // SAFETY: the caller's.
    unsafe { solve_cubes_here(from, p) }
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
unsafe fn solve_cubes_avx(from: &Gather, p: &Cubes) {
    // SAFETY: the caller's.
    unsafe { solve_cubes_here(from, p) }
}

#[inline(always)]
#[allow(unsafe_code)]
unsafe fn solve_cubes_here(from: &Gather, p: &Cubes) {
    let nodes: &[[u32; 8]; LANES] = from.nodes.try_into().expect("a group is four cells");
    let mut x = [V::ZERO; 8];
    for (k, xk) in x.iter_mut().enumerate() {
        // SAFETY: the caller's (these nodes are this task's alone).
        let at: [V3; LANES] = map_v3(|l| unsafe { from.x.get(nodes[l][k] as usize) });
        *xk = V {
            x: map(|l| at[l].x),
            y: map(|l| at[l].y),
            z: map(|l| at[l].z),
        };
    }
    let mut wk = [[0.0; LANES]; 8];
    for (k, wk) in wk.iter_mut().enumerate() {
        for (l, w) in wk.iter_mut().enumerate() {
            *w = from.w[nodes[l][k] as usize];
        }
    }
    volume(&mut x, &wk, p);
    let corners = if p.odd { [1, 2, 4, 7] } else { [0, 3, 5, 6] };
    for c in corners {
        shear(&mut x, &wk, c, p);
    }
    for c in 0..8 {
        barrier(&mut x, &wk, c, p);
    }
    for (l, cell) in nodes.iter().enumerate() {
        for (k, xk) in x.iter().enumerate() {
            // SAFETY: as above.
            unsafe {
                from.x
                    .set(cell[k] as usize, V3::new(xk.x[l], xk.y[l], xk.z[l]))
            };
        }
    }
}

/// `V/V_0 − 1` over the six Kuhn tets.
#[inline(always)]
fn volume(x: &mut [V; 8], w: &[L; 8], p: &Cubes) {
    let mut grad = [V::ZERO; 8];
    let mut six_v = [0.0; LANES];
    for [a, b, c, d] in crate::solver::volume::TETS {
        let (e1, e2, e3) = (x[b].sub(&x[a]), x[c].sub(&x[a]), x[d].sub(&x[a]));
        let (g1, g2, g3) = (e2.cross(&e3), e3.cross(&e1), e1.cross(&e2));
        let v = e1.dot(&g1);
        six_v = map(|l| six_v[l] + v[l]);
        grad[b] = grad[b].add(&g1);
        grad[c] = grad[c].add(&g2);
        grad[d] = grad[d].add(&g3);
        grad[a] = grad[a].sub(&g1.add(&g2).add(&g3));
    }
    let sixth = [1.0 / 6.0; LANES];
    for g in &mut grad {
        *g = g.scale(&sixth);
    }
    let inv_v = map(|l| p.inv_h[l] * p.inv_h[l] * p.inv_h[l]);
    let value = map(|l| six_v[l] * sixth[l] * inv_v[l] - 1.0);
    let mut denominator = p.hydro;
    for k in 0..8 {
        let n = grad[k].dot(&grad[k]);
        denominator = map(|l| denominator[l] + w[k][l] * n[l] * inv_v[l] * inv_v[l]);
    }
    let active = mask(|l| p.hydro[l].is_finite());
    let dl = multiplier(&value, &denominator, &active);
    let dl = map(|l| dl[l] * inv_v[l]);
    for k in 0..8 {
        step(&mut x[k], &grad[k], &w[k], &dl);
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
fn project(x: &mut [V; 8], w: &[L; 8], c: usize, g: [V; 3], value: &L, alpha: &L, on: &Mask) {
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
    step(&mut x[c], &apex, &w[c], &dl);
    for k in 0..3 {
        step(&mut x[nb[k]], &g[k], &w[nb[k]], &dl);
    }
}

/// The shear constraint `sqrt(Σ W_ij E_ij²)` of corner `c`.
#[inline(always)]
fn shear(x: &mut [V; 8], w: &[L; 8], c: usize, p: &Cubes) {
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
            we[i][j] = map(|l| e[i][j][l] * p.axis_root[l][i] * p.axis_root[l][j]);
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
    let on = mask(|l| value[l] > 1e-14);
    let inv = map(|l| {
        if value[l] > 1e-14 {
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
    project(x, w, c, g, &value, &p.dev, &on);
}

/// The collapse barrier `det F_c ≥ COLLAPSE_J` of corner `c` (hard).
#[inline(always)]
fn barrier(x: &mut [V; 8], w: &[L; 8], c: usize, p: &Cubes) {
    let nb = [c ^ 1, c ^ 2, c ^ 4];
    let s = signs(c, &p.inv_h);
    let f: [V; 3] = three!(|k| x[nb[k]].sub(&x[c]).scale(&s[k]));
    let first = f[1].cross(&f[2]);
    let j = f[0].dot(&first);
    let on = mask(|l| j[l] < COLLAPSE_J);
    if on.iter().all(|&m| m == 0.0) {
        return;
    }
    let cof = [first, f[2].cross(&f[0]), f[0].cross(&f[1])];
    let g: [V; 3] = three!(|k| cof[k].scale(&s[k]));
    let value = map(|l| j[l] - COLLAPSE_J);
    project(x, w, c, g, &value, &[0.0; LANES], &on);
}
