//! What a regular-lattice ("stencil") layout could gain in the spring-force pass (issue 9):
//! the same spring forces on an `N`³-node lattice with cell edges and one diagonal per face
//! (the Table 1 layout the step benchmark uses), computed four ways on one thread:
//!
//! 1. as the solver does (`solver::forces`): node state as arrays of `Vector3`, springs as
//!    index pairs, one force per spring into a buffer, then a per-node gather through a CSR
//!    node → spring list;
//! 2. half stencil, structure of arrays: x/y/z position and velocity arrays (copied from the
//!    `Vector3` state every step, as a fast path inside the solver would have to), each spring
//!    once per row and direction, its force added to both ends;
//! 3. node-centric stencil: every spring evaluated from both ends, the sum kept per node
//!    (no scatter, twice the arithmetic);
//! 4. long rows: one loop per stencil direction over the whole lattice (`i` against
//!    `i + offset`, pairs that wrap across a row masked out), forces into direction buffers,
//!    then two contiguous add passes; also compiled for AVX-512 and chosen at run time.
//!
//! All agree to rounding (printed; the AVX-512 long rows give the baseline long rows' bits,
//! asserted). Findings on the 2-core dev machine are in docs/benchmarks.md: 1–3 land within
//! about ±25 % of each other; long rows are about 1.5× the solver's pass, 2.5× with AVX-512.
//!
//! `cargo run --release -p springbake-core --example force_layouts [-- N]` (default N = 32).

use std::hint::black_box;
use std::time::Instant;

/// Forward stencil of the layout: +x, +y, +z edges and the +x+y, +x+z, +y+z face diagonals.
const FORWARD: [[i64; 3]; 6] = [
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 1, 0],
    [1, 0, 1],
    [0, 1, 1],
];
const K: f64 = 1.0e5;
const D: f64 = 3.0;

/// Spring force on the `a` end for relative position `r = xa − xb` and velocity `dv`.
#[inline(always)]
fn force(r: [f64; 3], dv: [f64; 3], rest: f64) -> [f64; 3] {
    let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    let inv = 1.0 / len;
    let closing = (dv[0] * r[0] + dv[1] * r[1] + dv[2] * r[2]) * inv;
    let s = -(K * (len - rest) + D * closing) * inv;
    [r[0] * s, r[1] * s, r[2] * s]
}

struct Lattice {
    n: usize,
    cell: f64,
    pos: Vec<[f64; 3]>,
    vel: Vec<[f64; 3]>,
}

impl Lattice {
    fn index(&self, p: [i64; 3]) -> Option<usize> {
        let n = self.n as i64;
        p.iter()
            .all(|&c| (0..n).contains(&c))
            .then(|| (p[0] + n * (p[1] + n * p[2])) as usize)
    }
    fn rest(&self, d: [i64; 3]) -> f64 {
        self.cell * ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) as f64).sqrt()
    }
}

/// 1: per-spring forces, then the CSR gather.
fn solver_like(l: &Lattice, reps: usize) -> (f64, Vec<[f64; 3]>) {
    let (mut a, mut b, mut rest) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..l.n.pow(3) {
        let p = [
            (i % l.n) as i64,
            ((i / l.n) % l.n) as i64,
            (i / l.n / l.n) as i64,
        ];
        for d in FORWARD {
            if let Some(j) = l.index([p[0] + d[0], p[1] + d[1], p[2] + d[2]]) {
                a.push(i as u32);
                b.push(j as u32);
                rest.push(l.rest(d));
            }
        }
    }
    let nodes = l.pos.len();
    let mut offsets = vec![0u32; nodes + 1];
    for s in 0..a.len() {
        offsets[a[s] as usize + 1] += 1;
        offsets[b[s] as usize + 1] += 1;
    }
    for i in 0..nodes {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut links = vec![0u32; 2 * a.len()];
    for s in 0..a.len() {
        for (end, node) in [(0, a[s]), (1, b[s])] {
            links[fill[node as usize] as usize] = 2 * s as u32 + end;
            fill[node as usize] += 1;
        }
    }
    let mut spring_force = vec![[0.0; 3]; a.len()];
    let mut out = vec![[0.0; 3]; nodes];
    let t0 = Instant::now();
    for _ in 0..reps {
        for (s, f) in spring_force.iter_mut().enumerate() {
            let (pa, pb) = (l.pos[a[s] as usize], l.pos[b[s] as usize]);
            let (va, vb) = (l.vel[a[s] as usize], l.vel[b[s] as usize]);
            let r = [pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]];
            *f = force(r, [va[0] - vb[0], va[1] - vb[1], va[2] - vb[2]], rest[s]);
        }
        for (i, acc) in out.iter_mut().enumerate() {
            *acc = [0.0; 3];
            for &link in &links[offsets[i] as usize..offsets[i + 1] as usize] {
                let f = spring_force[(link >> 1) as usize];
                let sign = if link & 1 == 0 { 1.0 } else { -1.0 };
                (0..3).for_each(|c| acc[c] += sign * f[c]);
            }
        }
        black_box(&mut out);
    }
    (t0.elapsed().as_secs_f64() / reps as f64, out)
}

/// Position and velocity as six coordinate arrays.
fn to_soa(l: &Lattice, soa: &mut [Vec<f64>; 6]) {
    for (i, (p, v)) in l.pos.iter().zip(&l.vel).enumerate() {
        for c in 0..3 {
            soa[c][i] = p[c];
            soa[3 + c][i] = v[c];
        }
    }
}

/// The six coordinate arrays' slices for the `m` nodes from `start`: sliced up front, so the
/// row loops have no bounds checks left and vectorise.
fn row_of(soa: &[Vec<f64>; 6], start: usize, m: usize) -> [&[f64]; 6] {
    std::array::from_fn(|c| &soa[c][start..start + m])
}

/// The force on node `j` of the `own` row from its spring to node `j` of the `far` row.
#[inline(always)]
fn pair_force(own: &[&[f64]; 6], far: &[&[f64]; 6], j: usize, rest: f64) -> [f64; 3] {
    let r = [
        own[0][j] - far[0][j],
        own[1][j] - far[1][j],
        own[2][j] - far[2][j],
    ];
    let dv = [
        own[3][j] - far[3][j],
        own[4][j] - far[4][j],
        own[5][j] - far[5][j],
    ];
    force(r, dv, rest)
}

/// Forces on the `own` row's nodes from the springs to the `far` row (one stencil direction,
/// natural length `rest`), written into (`ADD = false`) or added to (`ADD = true`) `out`.
#[inline(always)]
fn row_forces<const ADD: bool>(
    own: &[&[f64]; 6],
    far: &[&[f64]; 6],
    rest: f64,
    out: &mut [Vec<f64>; 3],
    m: usize,
) {
    let [ox, oy, oz] = out;
    let (ox, oy, oz) = (&mut ox[..m], &mut oy[..m], &mut oz[..m]);
    for j in 0..m {
        let fs = pair_force(own, far, j, rest);
        if ADD {
            (ox[j], oy[j], oz[j]) = (ox[j] + fs[0], oy[j] + fs[1], oz[j] + fs[2]);
        } else {
            (ox[j], oy[j], oz[j]) = (fs[0], fs[1], fs[2]);
        }
    }
}

/// 2: half stencil over rows, forces added to both ends.
fn half_stencil(l: &Lattice, reps: usize) -> (f64, Vec<[f64; 3]>) {
    let (n, nodes) = (l.n, l.pos.len());
    let mut soa: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; nodes]);
    let mut f: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; nodes]);
    let mut row_force: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let t0 = Instant::now();
    for _ in 0..reps {
        to_soa(l, &mut soa);
        f.iter_mut().for_each(|c| c.fill(0.0));
        for z in 0..n {
            for y in 0..n {
                let row = n * (y + n * z);
                for d in FORWARD {
                    if y as i64 + d[1] >= n as i64 || z as i64 + d[2] >= n as i64 {
                        continue;
                    }
                    let off = (d[0] + n as i64 * (d[1] + n as i64 * d[2])) as usize;
                    let m = n - d[0] as usize;
                    let rest = l.rest(d);
                    let own = row_of(&soa, row, m);
                    let far = row_of(&soa, row + off, m);
                    row_forces::<false>(&own, &far, rest, &mut row_force, m);
                    for c in 0..3 {
                        for j in 0..m {
                            f[c][row + j] += row_force[c][j];
                        }
                        for j in 0..m {
                            f[c][row + off + j] -= row_force[c][j];
                        }
                    }
                }
            }
        }
        black_box(&mut f);
    }
    let out = (0..nodes).map(|i| [f[0][i], f[1][i], f[2][i]]).collect();
    (t0.elapsed().as_secs_f64() / reps as f64, out)
}

/// 4: long-row structure of arrays: per stencil direction one loop over the whole lattice
/// (`i` and `i + offset` contiguous, springs that wrap across a row masked out by a per-node
/// 0/1 factor), forces into three direction buffers, then two contiguous add passes. No short
/// rows, no bounds checks in the arithmetic loop: the form a compiler vectorises best.
fn long_rows(l: &Lattice, reps: usize, wide: bool) -> (f64, Vec<[f64; 3]>) {
    let (n, nodes) = (l.n, l.pos.len());
    let mut soa: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; nodes]);
    let mut f: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; nodes]);
    let mut t: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; nodes]);
    let dirs: Vec<(usize, f64, Vec<f64>)> = FORWARD
        .iter()
        .map(|d| {
            let off = (d[0] + n as i64 * (d[1] + n as i64 * d[2])) as usize;
            let mask = (0..nodes - off)
                .map(|i| {
                    let p = [(i % n) as i64, ((i / n) % n) as i64, (i / n / n) as i64];
                    let q = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                    f64::from(u8::from(l.index(q).is_some()))
                })
                .collect();
            (off, l.rest(*d), mask)
        })
        .collect();
    let t0 = Instant::now();
    for _ in 0..reps {
        to_soa(l, &mut soa);
        f.iter_mut().for_each(|c| c.fill(0.0));
        for (off, rest, mask) in &dirs {
            let m = nodes - off;
            let row = Row {
                own: row_of(&soa, 0, m),
                far: row_of(&soa, *off, m),
                mask: &mask[..m],
                rest: *rest,
            };
            if wide {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `wide` is only set where `stencil::avx512_available` found the CPU features
                // the function is compiled for.
                #[allow(unsafe_code)]
                unsafe {
                    long_row_avx512(&row, &mut t)
                };
            } else {
                long_row(&row, &mut t);
            }
            for c in 0..3 {
                let (fc, tc) = (&mut f[c], &t[c][..m]);
                for (a, b) in fc[..m].iter_mut().zip(tc) {
                    *a += b;
                }
                for (a, b) in fc[*off..].iter_mut().zip(tc) {
                    *a -= b;
                }
            }
        }
        black_box(&mut f);
    }
    let out = (0..nodes).map(|i| [f[0][i], f[1][i], f[2][i]]).collect();
    (t0.elapsed().as_secs_f64() / reps as f64, out)
}

/// One direction of [`long_rows`]: the near ends (`own`), the far ends `offset` slots on, which
/// pairs are springs (`mask`, 1 or 0) and their rest length.
struct Row<'a> {
    own: [&'a [f64]; 6],
    far: [&'a [f64]; 6],
    mask: &'a [f64],
    rest: f64,
}

/// The masked spring forces of one [`Row`] into `t`.
#[inline(always)]
fn long_row(row: &Row, t: &mut [Vec<f64>; 3]) {
    let m = row.mask.len();
    let [tx, ty, tz] = t;
    let (tx, ty, tz, mask) = (&mut tx[..m], &mut ty[..m], &mut tz[..m], row.mask);
    for j in 0..m {
        let fs = pair_force(&row.own, &row.far, j, row.rest);
        (tx[j], ty[j], tz[j]) = (fs[0] * mask[j], fs[1] * mask[j], fs[2] * mask[j]);
    }
}

/// [`long_row`] compiled for AVX-512 (8 lanes of f64). The same IEEE operations in the same
/// order per spring (Rust never fuses a multiply and an add on its own), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx2")]
fn long_row_avx512(row: &Row, t: &mut [Vec<f64>; 3]) {
    long_row(row, t)
}

/// 3: every spring from both ends, summed per node (interior nodes only, timed per node).
fn node_centric(l: &Lattice, reps: usize) -> (f64, Vec<[f64; 3]>) {
    let (n, nodes) = (l.n, l.pos.len());
    let mut soa: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; nodes]);
    let mut out = vec![[f64::NAN; 3]; nodes];
    let both: Vec<[i64; 3]> = FORWARD.iter().flat_map(|d| [*d, d.map(|c| -c)]).collect();
    let t0 = Instant::now();
    for _ in 0..reps {
        to_soa(l, &mut soa);
        for z in 1..n - 1 {
            for y in 1..n - 1 {
                // One row of interior nodes at a time: the row and each neighbour row are
                // contiguous, so the loop over x vectorises.
                let (row, m) = (1 + n * (y + n * z), n - 2);
                let own = row_of(&soa, row, m);
                let mut acc = [vec![0.0; m], vec![0.0; m], vec![0.0; m]];
                for d in &both {
                    let far_row =
                        (row as i64 + d[0] + n as i64 * (d[1] + n as i64 * d[2])) as usize;
                    let far = row_of(&soa, far_row, m);
                    row_forces::<true>(&own, &far, l.rest(*d), &mut acc, m);
                }
                for j in 0..m {
                    out[row + j] = [acc[0][j], acc[1][j], acc[2][j]];
                }
            }
        }
        black_box(&mut out);
    }
    let interior = ((n - 2) as f64 / n as f64).powi(3);
    (t0.elapsed().as_secs_f64() / reps as f64 / interior, out)
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(32)
        .max(3);
    // A jittered lattice with random velocities (seeded: the same lattice every run).
    let mut rng = fastrand::Rng::with_seed(1);
    let mut rnd = move || rng.f64() - 0.5;
    let cell = 1.0 / (n - 1) as f64;
    let nodes = n.pow(3);
    let pos = (0..nodes)
        .map(|i| {
            let p = [i % n, (i / n) % n, i / n / n];
            p.map(|c| (c as f64 + 0.01 * rnd()) * cell)
        })
        .collect();
    let vel = (0..nodes).map(|_| [rnd(), rnd(), rnd()]).collect();
    let l = Lattice { n, cell, pos, vel };
    let reps = (2.0e7 / nodes as f64).ceil() as usize;
    let (t1, f1) = solver_like(&l, reps);
    let (t2, f2) = half_stencil(&l, reps);
    let (t3, f3) = node_centric(&l, reps);
    let (t4, f4) = long_rows(&l, reps, false);
    let wide =
        springbake_core::solver::stencil::avx512_available().then(|| long_rows(&l, reps, true));
    let diff = |f: &[[f64; 3]]| {
        f1.iter()
            .zip(f)
            .filter(|(_, b)| !b[0].is_nan())
            .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
            .fold(0.0f64, f64::max)
    };
    println!("{n}³ nodes, one thread, force pass only (M node-steps/s):");
    let mut rows = vec![
        ("solver layout (per spring + CSR gather)", t1, 0.0),
        ("half stencil, structure of arrays", t2, diff(&f2)),
        ("node-centric stencil (interior)", t3, diff(&f3)),
        ("long rows, structure of arrays, masked", t4, diff(&f4)),
    ];
    if let Some((t5, f5)) = &wide {
        // Same bits as the baseline long rows: the lanes do the same operations.
        assert_eq!(
            f5, &f4,
            "the AVX-512 long rows differ from the baseline ones"
        );
        rows.push(("long rows, AVX-512 (detected at run time)", *t5, diff(f5)));
    } else {
        println!("  (no AVX-512 on this CPU: the long rows' AVX-512 variant is not run)");
    }
    for (name, t, d) in rows {
        println!(
            "  {name:<42} {:>7.3} ms/step {:>6.1} M  (largest difference from 1: {d:.1e} N)",
            t * 1e3,
            nodes as f64 / t / 1e6
        );
    }
}
