//! The cells' lanes' reads and writes ([`super::lanes`]): a group's cells' nodes from the
//! `f64` positions into `f32` lanes, each cell in its own frame (relative to its first node);
//! and the solve's moves back onto the positions.
//!
//! A lane is one cell and a node's three coordinates go to three lanes, so a read is a
//! transpose. One value at a time it was a quarter of the kernel's instructions (callgrind,
//! the standard scene: 23 a node and corner). On x86-64 a node is two loads, a subtraction
//! and a conversion in SSE2 registers, and four nodes are transposed into four lanes with
//! shuffles; elsewhere one value at a time. Both make the same IEEE operations (`f64`
//! subtraction, rounding to `f32`; exact widening, `f64` addition), so the same bits.

use super::lanes::LANES;
use crate::solver::team::Disjoint;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// Where a group's lanes are: `f32` number `(k·3 + a)·LANES + l` is axis `a` of corner `k`
/// of lane `l` (the layout of `[[[f32; LANES]; 3]; 8]`).
#[inline(always)]
fn slot(k: usize, axis: usize, lane: usize) -> usize {
    (k * 3 + axis) * LANES + lane
}

// `read(x, nodes, corners)` writes the nodes of the group `nodes` (a cell a lane) relative to
// each cell's first node into `corners` (laid out as [`slot`] says).
// `write(x, nodes, cells, after, before)` moves the nodes of the group's first `cells` lanes
// by `after − before` (the lanes past `cells` repeat the last cell and are not written).
//
// Safety of both: every node of `nodes` is below `x.len()`, no other task of the pass touches
// these nodes, and `corners`, `after` and `before` hold `24·LANES` values.
#[cfg(not(target_arch = "x86_64"))]
pub(super) use scalar::{read, write};
#[cfg(target_arch = "x86_64")]
pub(super) use sse::{read, write};

/// One value at a time (what [`sse`] does four lanes at a time).
#[cfg_attr(all(target_arch = "x86_64", not(test)), allow(dead_code))]
pub(super) mod scalar {
    use super::*;

    /// `read` (see the module's `use` of it).
    #[allow(unsafe_code)]
    #[inline(always)]
    pub(in crate::solver::xpbd) unsafe fn read(
        x: &Disjoint<V3>,
        nodes: &[[u32; 8]; LANES],
        corners: *mut f32,
    ) {
        // SAFETY (every access below): the caller's.
        unsafe {
            for (l, cell) in nodes.iter().enumerate() {
                let origin = x.get_unchecked(cell[0] as usize);
                for (k, &n) in cell.iter().enumerate() {
                    let d = x.get_unchecked(n as usize) - origin;
                    for axis in 0..3 {
                        *corners.add(slot(k, axis, l)) = d[axis] as f32;
                    }
                }
            }
        }
    }

    /// `write` (see the module's `use` of it).
    #[allow(unsafe_code)]
    #[inline(always)]
    pub(in crate::solver::xpbd) unsafe fn write(
        x: &Disjoint<V3>,
        nodes: &[[u32; 8]; LANES],
        cells: usize,
        after: *const f32,
        before: *const f32,
    ) {
        // SAFETY (every access below): the caller's.
        unsafe {
            for (l, cell) in nodes.iter().enumerate().take(cells) {
                for (k, &n) in cell.iter().enumerate() {
                    let d = |axis| {
                        (*after.add(slot(k, axis, l)) - *before.add(slot(k, axis, l))) as f64
                    };
                    let moved = V3::new(d(0), d(1), d(2));
                    x.set_unchecked(n as usize, x.get_unchecked(n as usize) + moved);
                }
            }
        }
    }
}

/// Four lanes at a time in SSE2 registers (every x86-64 CPU has them; in the AVX build of the
/// kernel the same instructions are VEX-encoded).
#[cfg(target_arch = "x86_64")]
pub(super) mod sse {
    use super::*;
    use std::arch::x86_64::*;

    /// The node at `p` relative to the one at `o` as `(x, y, z, 0)` in `f32`.
    #[allow(unsafe_code)]
    #[inline(always)]
    unsafe fn relative(p: *const f64, o: *const f64) -> __m128 {
        // SAFETY: `p` and `o` point at three `f64` each (the caller's).
        unsafe {
            let xy = _mm_sub_pd(_mm_loadu_pd(p), _mm_loadu_pd(o));
            let z = _mm_sub_sd(_mm_load_sd(p.add(2)), _mm_load_sd(o.add(2)));
            _mm_movelh_ps(_mm_cvtpd_ps(xy), _mm_cvtpd_ps(z))
        }
    }

    /// `read` (see the module's `use` of it).
    #[allow(unsafe_code)]
    #[inline(always)]
    pub(in crate::solver::xpbd) unsafe fn read(
        x: &Disjoint<V3>,
        nodes: &[[u32; 8]; LANES],
        corners: *mut f32,
    ) {
        // A `Vector3<f64>` is three contiguous `f64` (nalgebra's array storage).
        let base = x.as_ptr() as *const f64;
        let node = |l: usize, k: usize| nodes[l][k] as usize;
        // SAFETY (every pointer below): the nodes are in bounds, the lanes have room (the
        // caller's).
        unsafe {
            for first in (0..LANES).step_by(4) {
                let o0 = base.add(3 * node(first, 0));
                let o1 = base.add(3 * node(first + 1, 0));
                let o2 = base.add(3 * node(first + 2, 0));
                let o3 = base.add(3 * node(first + 3, 0));
                for k in 0..8 {
                    let r0 = relative(base.add(3 * node(first, k)), o0);
                    let r1 = relative(base.add(3 * node(first + 1, k)), o1);
                    let r2 = relative(base.add(3 * node(first + 2, k)), o2);
                    let r3 = relative(base.add(3 * node(first + 3, k)), o3);
                    let (t0, t1) = (_mm_unpacklo_ps(r0, r1), _mm_unpacklo_ps(r2, r3));
                    let (t2, t3) = (_mm_unpackhi_ps(r0, r1), _mm_unpackhi_ps(r2, r3));
                    _mm_storeu_ps(corners.add(slot(k, 0, first)), _mm_movelh_ps(t0, t1));
                    _mm_storeu_ps(corners.add(slot(k, 1, first)), _mm_movehl_ps(t1, t0));
                    _mm_storeu_ps(corners.add(slot(k, 2, first)), _mm_movelh_ps(t2, t3));
                }
            }
        }
    }

    /// `write` (see the module's `use` of it).
    #[allow(unsafe_code)]
    #[inline(always)]
    pub(in crate::solver::xpbd) unsafe fn write(
        x: &Disjoint<V3>,
        nodes: &[[u32; 8]; LANES],
        cells: usize,
        after: *const f32,
        before: *const f32,
    ) {
        let base = x.as_ptr() as *mut f64;
        // SAFETY (every pointer below): the nodes are in bounds, the lanes hold their values
        // (the caller's).
        unsafe {
            let moved = |k: usize, axis: usize, first: usize| {
                let i = slot(k, axis, first);
                _mm_sub_ps(_mm_loadu_ps(after.add(i)), _mm_loadu_ps(before.add(i)))
            };
            let add = |n: u32, xy: __m128d, z: __m128d| {
                let p = base.add(3 * n as usize);
                _mm_storeu_pd(p, _mm_add_pd(_mm_loadu_pd(p), xy));
                _mm_store_sd(p.add(2), _mm_add_sd(_mm_load_sd(p.add(2)), z));
            };
            for first in (0..cells).step_by(4) {
                let here = (cells - first).min(4);
                // `k` names a corner in the lanes and in four cells' node lists.
                #[allow(clippy::needless_range_loop)]
                for k in 0..8 {
                    let (mx, my, mz) = (moved(k, 0, first), moved(k, 1, first), moved(k, 2, first));
                    let (t0, t1) = (_mm_unpacklo_ps(mx, my), _mm_unpackhi_ps(mx, my));
                    let (zl, zh) = (_mm_cvtps_pd(mz), _mm_cvtps_pd(_mm_movehl_ps(mz, mz)));
                    add(nodes[first][k], _mm_cvtps_pd(t0), zl);
                    if here > 1 {
                        let xy = _mm_cvtps_pd(_mm_movehl_ps(t0, t0));
                        add(nodes[first + 1][k], xy, _mm_unpackhi_pd(zl, zl));
                    }
                    if here > 2 {
                        add(nodes[first + 2][k], _mm_cvtps_pd(t1), zh);
                    }
                    if here > 3 {
                        let xy = _mm_cvtps_pd(_mm_movehl_ps(t1, t1));
                        add(nodes[first + 3][k], xy, _mm_unpackhi_pd(zh, zh));
                    }
                }
            }
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    /// Lanes as the kernel holds them.
    type Lanes = [[[f32; LANES]; 3]; 8];

    /// The SSE2 transposes read and write the bits one value at a time does, for full and
    /// short groups, near the origin and far from it.
    #[test]
    fn the_shuffled_lanes_are_the_values_one_at_a_time() {
        let mut rng = fastrand::Rng::with_seed(11);
        let n = 300;
        let mut xs: Vec<V3> = (0..n)
            .map(|_| V3::new(rng.f64(), rng.f64(), rng.f64()) * 2000.0 - V3::repeat(1000.0))
            .collect();
        for cells in 1..=LANES {
            let mut nodes = [[0u32; 8]; LANES];
            let mut ids: Vec<u32> = (0..n as u32).collect();
            rng.shuffle(&mut ids);
            for (l, cell) in nodes.iter_mut().enumerate() {
                let from = 8 * l.min(cells - 1);
                cell.copy_from_slice(&ids[from..from + 8]);
            }
            let (mut a, mut b) = ([[[0.0; LANES]; 3]; 8], [[[0.0; LANES]; 3]; 8]);
            let mut ys = xs.clone();
            #[allow(unsafe_code)]
            unsafe {
                let x = Disjoint::new(&mut xs);
                sse::read(&x, &nodes, a.as_mut_ptr().cast());
                scalar::read(&x, &nodes, b.as_mut_ptr().cast());
            }
            assert_eq!(a, b);
            let before: Lanes = a;
            let after: Lanes = a.map(|c| c.map(|axis| axis.map(|v| v + rng.f32() * 1e-3 - 5e-4)));
            #[allow(unsafe_code)]
            unsafe {
                let x = Disjoint::new(&mut xs);
                sse::write(
                    &x,
                    &nodes,
                    cells,
                    after.as_ptr().cast(),
                    before.as_ptr().cast(),
                );
                let y = Disjoint::new(&mut ys);
                scalar::write(
                    &y,
                    &nodes,
                    cells,
                    after.as_ptr().cast(),
                    before.as_ptr().cast(),
                );
            }
            assert_eq!(xs, ys, "{cells} cells");
        }
    }
}
