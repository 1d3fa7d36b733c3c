//! Issue 16's trial: Vertex Block Descent (Chen et al. 2024, "Vertex Block Descent",
//! SIGGRAPH 2024) against the product's small-step XPBD sweep, on the same lattice and the
//! same energy, with the same (single) thread. Self-contained (nalgebra and std only: the
//! solver's internals are crate-private), so it measures these reimplementations, not the
//! product's 4-lane path.
//!
//! * Lattice: `nx × ny × nz` cubes of edge `h`, mass `ρh³` split ⅛ to each corner, node slot
//!   `k` of a cell = bit 0 x, bit 1 y, bit 2 z; the nodes at y = 0 pinned.
//! * Energy (`core/src/solver/xpbd/cells.rs`): per cell `Σ_corners V_c μ ‖E_c‖²_F`
//!   (`E = ½(FᵀF − I)`, `V_c = h³/4`, corners `{1,2,4,7}` when `i+j+k` is odd (the product's
//!   parity, rest corner 0 over `h`, for a lattice at the origin), else `{0,3,5,6}`) plus `½ λ V₀ (V/V₀ − 1)²` with
//!   `V` the six Kuhn tets (`core/src/solver/volume.rs`). Isotropic, stiffness scale 1.
//! * XPBD: a scalar port of `CellSet::solve` (volume then the four shear constraints per
//!   cell, compliances `1/(λV₀)/Δt²`, `1/(2μV_c)/Δt²`, multipliers reset every substep, one
//!   sweep over the eight cell colours `(i,j,k) mod 2` per substep), `x̃ = x + Δt v + Δt² g`,
//!   `v = (x − x_prev)/Δt`. No collapse barriers (`det F_c < 0.2` never happens here: the
//!   tables print the smallest corner `det F` seen), no deformation damping, no contacts.
//! * VBD: per substep `y = x + Δt v + Δt² g`, the paper's adaptive initialisation, then
//!   `iterations` Gauss–Seidel passes over the eight node colours `(i,j,k) mod 2` (nodes of a
//!   colour share no cell), each free node moved by one Newton step `H⁻¹ f` of its local
//!   energy with the exact per-vertex Hessian block of the energy above (the volume term's
//!   block is exactly `(λ/V₀) ∇V ∇Vᵀ`: `V` is affine in each node); when that block is not
//!   positive definite (Cholesky fails) the negative `(bᵀEb) I` parts of the StVK blocks are
//!   dropped (SPD), counted in `proj`. Optional Chebyshev acceleration (paper §3.8, `ρ` in
//!   the label; `ρ = 0`: none). `v = (x − x_start)/Δt`. No damping.
//! * Static reference: the lattice's exact equilibrium (Newton, block-Jacobi PCG with
//!   finite-difference Hessian products), what a fully converged solver settles to.
//! * Velocity Verlet with the energy's exact forces: the dynamics' reference.
//!
//! Scenes (all from rest, 24 frames/s, one row per solver and budget; `sweeps` = sweeps per
//! frame: substeps for XPBD, substeps × iterations for VBD; `ns/n-s` = stepping wall time
//! per node per sweep; `min J` = smallest corner `det F` seen; `proj` = VBD SPD fallbacks):
//! * `column`: the product's `solver_checks column`, 0.2 × 1 × 0.2 m, 2×10×2 cells, E = 1 MPa,
//!   ν = 0, ρ = 1000, 96 frames, against `ρgH²/(2E)` and the static reference;
//! * `cube`: the standard scene's lattice, a 1 m cube of 15³ cells in `rubber` (E = 1.5 MPa,
//!   ν = 0.47, ρ = 1100), 48 frames, against the static reference.
//!
//!   Both settle under the same drag `v ← v/(1 + cΔt)`, `c = 10/s`, in both solvers (it does
//!   not move an equilibrium; the product's own damping is deformation damping instead);
//!   `settled` is when the sag came within 1 % of its final value for good. A few rows of
//!   `column` run without drag (the mean of an undamped oscillation).
//! * `dynamics`: the column without gravity or drag, kicked with `v = 0.5 m/s · y/H` along x
//!   (bending, ~1 Hz) or y (axial, ~8 Hz, the mode a bounce rings), and the same column in
//!   rubber kicked axially, 2 s: energy (kinetic + elastic) kept at 1 s and 2 s, the top's
//!   peak displacement in the second second over the first (`peak2/1`), and the RMS
//!   error of the top's displacement (per frame) against velocity Verlet at 400 substeps per
//!   frame (exact forces, energy-conserving: its own row), over the reference's RMS;
//! * `check`: the per-vertex gradient and Hessian blocks against finite differences.
//!
//! `cargo run --release -p springbake-core --example vbd_trial [-- [check] [column] [cube]
//! [dynamics] [BUDGET...]]`: no scene named runs all (about 80 s on one idle core, most of it
//! `cube`); budgets such as `X30 V1x10 V5x6 V1x30r0.95` (X: XPBD substeps per frame; V: VBD
//! substeps x iterations, optional Chebyshev ρ) replace the scenes' own lists.
//!
//! Warm-started XPBD (the fourteenth session's trial of the resting bias): `W30` keeps each
//! constraint's multiplier from the last substep and applies it (`x += Σ w ∇C λ`, gradients
//! at the prediction) before the sweep; `D30` adds the last sweep's move per node instead.
//! `WARM=β` keeps `β λ` (default 1). `TRIAL_DEBUG=1` prints, after each settling row, the
//! force left at the end, how much the multipliers changed over one more frame and the
//! fastest node (a row that has settled its sag but not its nodes is ringing at the substep).

use nalgebra::{Matrix3, Vector3};
use std::time::Instant;

type V3 = Vector3<f64>;
type M3 = Matrix3<f64>;

const FPS: f64 = 24.0;
/// Drag rate of the settling scenes, 1/s (both solvers).
const DRAG: f64 = 10.0;
/// Kuhn's six tets of a cell (`core/src/solver/volume.rs`).
const TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 3, 2, 7],
    [0, 2, 6, 7],
    [0, 6, 4, 7],
    [0, 4, 5, 7],
    [0, 5, 1, 7],
];

struct Lattice {
    dims: [usize; 3],
    h: f64,
    mu: f64,
    lambda: f64,
    rest: Vec<V3>,
    mass: Vec<f64>,
    /// Inverse masses (0: pinned).
    w: Vec<f64>,
    cells: Vec<[u32; 8]>,
    odd: Vec<bool>,
    cell_colours: Vec<Vec<u32>>,
    node_colours: Vec<Vec<u32>>,
    /// Per node: its (cell, slot) pairs.
    incident: Vec<Vec<(u32, u8)>>,
}

fn corners(odd: bool) -> [usize; 4] {
    if odd {
        [1, 2, 4, 7]
    } else {
        [0, 3, 5, 6]
    }
}

/// `s_k / h` of corner `c`'s three edges.
fn signs(c: usize, inv_h: f64) -> [f64; 3] {
    [1, 2, 4].map(|bit| if c & bit == 0 { inv_h } else { -inv_h })
}

fn corner_f(x: &[V3; 8], c: usize, s: &[f64; 3]) -> M3 {
    M3::from_columns(&[
        (x[c ^ 1] - x[c]) * s[0],
        (x[c ^ 2] - x[c]) * s[1],
        (x[c ^ 4] - x[c]) * s[2],
    ])
}

fn green(f: &M3) -> M3 {
    (f.transpose() * f - M3::identity()) * 0.5
}

/// Volume of a cell (six Kuhn tets) and its gradient by node (as in cells.rs).
fn cube_volume(x: &[V3; 8]) -> (f64, [V3; 8]) {
    let (mut volume, mut grad) = (0.0, [V3::zeros(); 8]);
    for [a, b, c, d] in TETS {
        let (e1, e2, e3) = (x[b] - x[a], x[c] - x[a], x[d] - x[a]);
        let (g1, g2, g3) = (e2.cross(&e3), e3.cross(&e1), e1.cross(&e2));
        volume += e1.dot(&g1);
        grad[b] += g1;
        grad[c] += g2;
        grad[d] += g3;
        grad[a] -= g1 + g2 + g3;
    }
    (volume / 6.0, grad.map(|g| g / 6.0))
}

fn dot(a: &[V3], b: &[V3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p.dot(q)).sum()
}

fn max_norm(a: &[V3]) -> f64 {
    a.iter().map(|p| p.amax()).fold(0.0, f64::max)
}

impl Lattice {
    /// A lattice of `dims` cells of edge `h` in material (E, ν, ρ), the y = 0 nodes pinned.
    fn new(dims: [usize; 3], h: f64, e: f64, nu: f64, rho: f64) -> Lattice {
        let [nx, ny, nz] = dims;
        let id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        let n = (nx + 1) * (ny + 1) * (nz + 1);
        let coords = |p: usize| {
            [
                p % (nx + 1),
                (p / (nx + 1)) % (ny + 1),
                p / ((nx + 1) * (ny + 1)),
            ]
        };
        let rest: Vec<V3> = (0..n)
            .map(|p| coords(p).map(|c| c as f64 * h).into())
            .collect();
        let mut mass = vec![0.0; n];
        let (mut cells, mut odd, mut cell_colours) = (Vec::new(), Vec::new(), vec![vec![]; 8]);
        let mut incident = vec![vec![]; n];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let nodes: [u32; 8] = std::array::from_fn(|c| {
                        id(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)) as u32
                    });
                    for (slot, &p) in nodes.iter().enumerate() {
                        mass[p as usize] += rho * h * h * h / 8.0;
                        incident[p as usize].push((cells.len() as u32, slot as u8));
                    }
                    // The product's greedy colouring of a lattice in grid order.
                    cell_colours[i % 2 + 2 * (j % 2) + 4 * (k % 2)].push(cells.len() as u32);
                    cells.push(nodes);
                    odd.push((i + j + k) % 2 == 1);
                }
            }
        }
        let mut node_colours = vec![vec![]; 8];
        for p in 0..n {
            let [i, j, k] = coords(p);
            node_colours[i % 2 + 2 * (j % 2) + 4 * (k % 2)].push(p as u32);
        }
        let w = (0..n)
            .map(|p| {
                if coords(p)[1] == 0 {
                    0.0
                } else {
                    1.0 / mass[p]
                }
            })
            .collect();
        Lattice {
            dims,
            h,
            mu: e / (2.0 * (1.0 + nu)),
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            rest,
            mass,
            w,
            cells,
            odd,
            cell_colours,
            node_colours,
            incident,
        }
    }

    fn gather(&self, x: &[V3], cell: usize) -> [V3; 8] {
        self.cells[cell].map(|p| x[p as usize])
    }

    /// Elastic energy, J.
    fn energy(&self, x: &[V3]) -> f64 {
        let (v0, vc, inv_h) = (self.h.powi(3), self.h.powi(3) / 4.0, 1.0 / self.h);
        let mut total = 0.0;
        for cell in 0..self.cells.len() {
            let xl = self.gather(x, cell);
            let c_h = cube_volume(&xl).0 / v0 - 1.0;
            total += 0.5 * self.lambda * v0 * c_h * c_h;
            for c in corners(self.odd[cell]) {
                let e = green(&corner_f(&xl, c, &signs(c, inv_h)));
                total += vc * self.mu * e.norm_squared();
            }
        }
        total
    }

    /// Gradient of elastic energy minus gravity's work (0 at pinned nodes) into `out`.
    fn gradient(&self, x: &[V3], gravity: V3, out: &mut [V3]) {
        let (v0, vc, inv_h) = (self.h.powi(3), self.h.powi(3) / 4.0, 1.0 / self.h);
        for (o, m) in out.iter_mut().zip(&self.mass) {
            *o = -gravity * *m;
        }
        for (cell, nodes) in self.cells.iter().enumerate() {
            let xl = self.gather(x, cell);
            if self.lambda > 0.0 {
                let (v, dv) = cube_volume(&xl);
                let s = self.lambda * (v / v0 - 1.0);
                for (p, g) in nodes.iter().zip(&dv) {
                    out[*p as usize] += g * s;
                }
            }
            for c in corners(self.odd[cell]) {
                let s = signs(c, inv_h);
                let f = corner_f(&xl, c, &s);
                let p = f * green(&f) * (2.0 * self.mu * vc);
                for (k, bit) in [1, 2, 4].into_iter().enumerate() {
                    let g = p.column(k) * s[k];
                    out[nodes[c ^ bit] as usize] += g;
                    out[nodes[c] as usize] -= g;
                }
            }
        }
        for (o, w) in out.iter_mut().zip(&self.w) {
            if *w == 0.0 {
                *o = V3::zeros();
            }
        }
    }

    /// Node `i`'s elastic energy gradient, exact Hessian block, and the (≤ 0) sum of the
    /// `(bᵀEb)` coefficients of `I` in it (subtracting it leaves an SPD block).
    fn vertex_terms(&self, x: &[V3], i: usize) -> (V3, M3, f64) {
        let (v0, vc, inv_h) = (self.h.powi(3), self.h.powi(3) / 4.0, 1.0 / self.h);
        let (mut g, mut hess, mut neg) = (V3::zeros(), M3::zeros(), 0.0);
        let k2 = 2.0 * self.mu * vc;
        for &(cell, k) in &self.incident[i] {
            let (cell, k) = (cell as usize, k as usize);
            let xl = self.gather(x, cell);
            if self.lambda > 0.0 {
                let (v, dv) = cube_volume(&xl);
                g += dv[k] * (self.lambda * (v / v0 - 1.0));
                hess += dv[k] * dv[k].transpose() * (self.lambda / v0);
            }
            for c in corners(self.odd[cell]) {
                let s = signs(c, inv_h);
                // F = Σ_a x_a b_aᵀ: b of the apex is −s, of its edge end along axis j, s_j e_j.
                let b = match k ^ c {
                    0 => -V3::new(s[0], s[1], s[2]),
                    1 => V3::new(s[0], 0.0, 0.0),
                    2 => V3::new(0.0, s[1], 0.0),
                    4 => V3::new(0.0, 0.0, s[2]),
                    _ => continue,
                };
                let f = corner_f(&xl, c, &s);
                let e = green(&f);
                g += f * (e * b) * k2;
                let fb = f * b;
                let beb = b.dot(&(e * b));
                hess += (fb * fb.transpose() * 0.5
                    + f * f.transpose() * (0.5 * b.norm_squared())
                    + M3::identity() * beb)
                    * k2;
                neg += k2 * beb.min(0.0);
            }
        }
        (g, hess, neg)
    }

    /// One XPBD sweep (scalar port of `CellSet::solve` without barriers), multipliers
    /// starting from `lambda` (per cell: volume, then the four corners).
    fn xpbd_sweep(&self, x: &mut [V3], dt: f64, lambda: &mut [[f64; 5]]) {
        let (v0, inv_h) = (self.h.powi(3), 1.0 / self.h);
        let hydro = 1.0 / (self.lambda * v0) / (dt * dt);
        let dev = 1.0 / (2.0 * self.mu * v0 / 4.0) / (dt * dt);
        for colour in &self.cell_colours {
            for &cell in colour {
                let nodes = self.cells[cell as usize];
                let mut xl = nodes.map(|p| x[p as usize]);
                let wl = nodes.map(|p| self.w[p as usize]);
                let l = &mut lambda[cell as usize];
                if hydro.is_finite() {
                    solve_cube_volume(&mut xl, &wl, 1.0 / v0, hydro, &mut l[0]);
                }
                for (k, c) in corners(self.odd[cell as usize]).into_iter().enumerate() {
                    solve_corner(&mut xl, &wl, c, inv_h, dev, &mut l[1 + k]);
                }
                for (p, xp) in nodes.iter().zip(xl) {
                    x[*p as usize] = xp;
                }
            }
        }
    }

    /// Warm start: `x += Σ w ∇C(x) λ` over every constraint, gradients at the given `x`.
    fn apply_multipliers(&self, x: &mut [V3], lambda: &[[f64; 5]]) {
        let (v0, inv_h) = (self.h.powi(3), 1.0 / self.h);
        let mut d = vec![V3::zeros(); x.len()];
        for (cell, nodes) in self.cells.iter().enumerate() {
            let xl = nodes.map(|p| x[p as usize]);
            let l = lambda[cell];
            let (_, grad) = cube_volume(&xl);
            for k in 0..8 {
                d[nodes[k] as usize] += grad[k] * (l[0] / v0);
            }
            for (m, c) in corners(self.odd[cell]).into_iter().enumerate() {
                let (_, g) = corner_gradient(&xl, c, inv_h);
                for (slot, gk) in [c, c ^ 1, c ^ 2, c ^ 4].into_iter().zip(g) {
                    d[nodes[slot] as usize] += gk * l[1 + m];
                }
            }
        }
        for (i, di) in d.iter().enumerate() {
            x[i] += di * self.w[i];
        }
    }

    /// Smallest `det F` over all eight corners of every cell (the barrier acts below 0.2).
    fn min_corner_j(&self, x: &[V3]) -> f64 {
        let mut least = f64::INFINITY;
        for cell in 0..self.cells.len() {
            let xl = self.gather(x, cell);
            for c in 0..8 {
                least = least.min(corner_f(&xl, c, &signs(c, 1.0 / self.h)).determinant());
            }
        }
        least
    }

    /// The nodes of the top layer (j = ny).
    fn top_layer(&self) -> Vec<usize> {
        let top = self.dims[1] as f64 * self.h;
        (0..self.rest.len())
            .filter(|&p| (self.rest[p].y - top).abs() < 1e-9 * self.h)
            .collect()
    }

    /// The static equilibrium under `gravity` (Newton; block-Jacobi PCG with central
    /// finite-difference Hessian products). Returns it, the Newton steps and CG iterations
    /// used, and the largest force left on a node over the largest node weight.
    fn static_equilibrium(&self, gravity: V3) -> (Vec<V3>, usize, usize, f64) {
        let n = self.rest.len();
        let mut x = self.rest.clone();
        let zeros = vec![V3::zeros(); n];
        let (mut g, mut gp, mut gm) = (zeros.clone(), zeros.clone(), zeros);
        let (mut cg, mut steps) = (0, 0);
        while steps < 12 {
            steps += 1;
            self.gradient(&x, gravity, &mut g);
            let pre: Vec<M3> = (0..n)
                .map(|i| {
                    if self.w[i] == 0.0 {
                        return M3::zeros();
                    }
                    let (_, hess, neg) = self.vertex_terms(&x, i);
                    let spd = hess.cholesky().unwrap_or_else(|| {
                        (hess - M3::identity() * neg).cholesky().expect("SPD block")
                    });
                    spd.inverse()
                })
                .collect();
            let mut d = vec![V3::zeros(); n];
            let mut r: Vec<V3> = g.iter().map(|v| -v).collect();
            let b_norm = dot(&r, &r).sqrt();
            let mut z: Vec<V3> = r.iter().zip(&pre).map(|(r, m)| m * r).collect();
            let mut p = z.clone();
            let mut rz = dot(&r, &z);
            for _ in 0..20000 {
                cg += 1;
                let eps = 1e-6 * self.h / max_norm(&p);
                let shifted = |sign: f64| -> Vec<V3> {
                    x.iter()
                        .zip(&p)
                        .map(|(x, p)| x + p * (sign * eps))
                        .collect()
                };
                self.gradient(&shifted(1.0), gravity, &mut gp);
                self.gradient(&shifted(-1.0), gravity, &mut gm);
                let ap: Vec<V3> = gp
                    .iter()
                    .zip(&gm)
                    .map(|(a, b)| (a - b) / (2.0 * eps))
                    .collect();
                let alpha = rz / dot(&p, &ap);
                for i in 0..n {
                    d[i] += p[i] * alpha;
                    r[i] -= ap[i] * alpha;
                    z[i] = pre[i] * r[i];
                }
                if dot(&r, &r).sqrt() < 1e-10 * b_norm {
                    break;
                }
                let rz_new = dot(&r, &z);
                for (p, z) in p.iter_mut().zip(&z) {
                    *p = z + *p * (rz_new / rz);
                }
                rz = rz_new;
            }
            for (x, d) in x.iter_mut().zip(&d) {
                *x += d;
            }
            if max_norm(&d) < 1e-13 {
                break;
            }
        }
        self.gradient(&x, gravity, &mut g);
        let weight = self.mass.iter().fold(0.0, |a: f64, &b| a.max(b)) * gravity.norm();
        (x, steps, cg, max_norm(&g) / weight)
    }
}

/// Move a cell's nodes `slots` to reduce constraint `value` of gradient `grad` (by slot)
/// with compliance `alpha` over Δt² (XPBD, multiplier reset every substep).
fn project<const N: usize>(
    x: &mut [V3; 8],
    w: &[f64; 8],
    slots: [usize; N],
    grad: [V3; N],
    value: f64,
    alpha: f64,
    lambda: &mut f64,
) {
    let mut denominator = alpha;
    for (&k, g) in slots.iter().zip(&grad) {
        denominator += w[k] * g.norm_squared();
    }
    if denominator > 0.0 && denominator.is_finite() {
        let dl = (-value - alpha * *lambda) / denominator;
        *lambda += dl;
        for (&k, g) in slots.iter().zip(&grad) {
            x[k] += g * (dl * w[k]);
        }
    }
}

/// The cell's volumetric constraint `V/V₀ − 1` (cells.rs `solve_cube_volume`).
fn solve_cube_volume(x: &mut [V3; 8], w: &[f64; 8], inv_volume: f64, alpha: f64, lambda: &mut f64) {
    let (volume, grad) = cube_volume(x);
    let slots = std::array::from_fn(|k| k);
    let grad = grad.map(|g| g * inv_volume);
    project(x, w, slots, grad, volume * inv_volume - 1.0, alpha, lambda);
}

/// The gradient of corner `c`'s shear constraint by slots `c, c^1, c^2, c^4` (zero at rest).
fn corner_gradient(x: &[V3; 8], c: usize, inv_h: f64) -> (f64, [V3; 4]) {
    let s = signs(c, inv_h);
    let f = corner_f(x, c, &s);
    let e = green(&f);
    let value = e.norm();
    if value > 1e-14 {
        let p = f * e / value;
        let g = [0, 1, 2].map(|k| p.column(k) * s[k]);
        (value, [-(g[0] + g[1] + g[2]), g[0], g[1], g[2]])
    } else {
        (value, [V3::zeros(); 4])
    }
}

/// The shear constraint `‖E_c‖_F` of corner `c` (cells.rs `solve_corner`, isotropic).
fn solve_corner(x: &mut [V3; 8], w: &[f64; 8], c: usize, inv_h: f64, dev: f64, lambda: &mut f64) {
    let (value, grad) = corner_gradient(x, c, inv_h);
    if value > 1e-14 {
        project(x, w, [c, c ^ 1, c ^ 2, c ^ 4], grad, value, dev, lambda);
    }
}

#[derive(Clone, Copy)]
enum Solver {
    Xpbd(usize),
    /// XPBD with the multipliers warm-started from the last substep: `W` applies them with
    /// gradients at the prediction, `D` adds the last sweep's displacement per node.
    XpbdWarm(usize, bool),
    /// Substeps per frame, iterations per substep, Chebyshev ρ (0: none).
    Vbd(usize, usize, f64),
    /// Velocity Verlet with the energy's exact forces (the dynamics' reference).
    Verlet(usize),
}

/// Solvers from a list such as `"X30 V1x10 V1x30r0.95"` (X: XPBD substeps; V: VBD
/// substeps x iterations, optional Chebyshev ρ).
fn solvers(spec: &str) -> Vec<Solver> {
    let num = |t: &str| t.parse().expect("a budget");
    spec.split_whitespace()
        .map(|t| match t.split_at(1) {
            ("X", n) => Solver::Xpbd(num(n)),
            ("W", n) => Solver::XpbdWarm(num(n), true),
            ("D", n) => Solver::XpbdWarm(num(n), false),
            (_, t) => {
                let (t, rho) = t.split_once('r').unwrap_or((t, "0"));
                let (s, it) = t.split_once('x').expect("VBD budget SxI");
                Solver::Vbd(num(s), num(it), rho.parse().expect("rho"))
            }
        })
        .collect()
}

impl Solver {
    fn label(&self) -> String {
        match *self {
            Solver::Xpbd(s) => format!("XPBD {s:>3} sub"),
            Solver::XpbdWarm(s, true) => format!("XPBD {s:>3} warm"),
            Solver::XpbdWarm(s, false) => format!("XPBD {s:>3} disp"),
            Solver::Vbd(s, it, rho) if rho > 0.0 => format!("VBD {s:>2}x{it:<2} r{rho}"),
            Solver::Vbd(s, it, _) => format!("VBD {s:>2}x{it:<2}"),
            Solver::Verlet(s) => format!("Verlet {s} sub"),
        }
    }

    fn sweeps_per_frame(&self) -> usize {
        match *self {
            Solver::Xpbd(s) | Solver::Verlet(s) | Solver::XpbdWarm(s, _) => s,
            Solver::Vbd(s, it, _) => s * it,
        }
    }
}

struct Sim<'a> {
    lat: &'a Lattice,
    x: Vec<V3>,
    v: Vec<V3>,
    v_old: Vec<V3>,
    start: Vec<V3>,
    y: Vec<V3>,
    older: Vec<V3>,
    last: Vec<V3>,
    /// Verlet: the energy's gradient at `x` (empty until first needed).
    grad: Vec<V3>,
    /// XPBD: per cell, the multipliers (volume, four corners); warm: the last sweep's move.
    lambda: Vec<[f64; 5]>,
    moved: Vec<V3>,
    gravity: V3,
    drag: f64,
    /// VBD blocks that needed the SPD fallback; wall time spent stepping, s.
    projected: u64,
    seconds: f64,
}

impl<'a> Sim<'a> {
    fn new(lat: &'a Lattice, v: Vec<V3>, gravity: V3, drag: f64) -> Sim<'a> {
        let zeros = vec![V3::zeros(); lat.rest.len()];
        Sim {
            lat,
            x: lat.rest.clone(),
            v_old: v.clone(),
            v,
            start: zeros.clone(),
            y: zeros.clone(),
            older: zeros.clone(),
            last: zeros,
            grad: Vec::new(),
            lambda: vec![[0.0; 5]; lat.cells.len()],
            moved: vec![V3::zeros(); lat.rest.len()],
            gravity,
            drag,
            projected: 0,
            seconds: 0.0,
        }
    }

    fn frame(&mut self, solver: Solver) {
        let t0 = Instant::now();
        let (Solver::Xpbd(substeps)
        | Solver::XpbdWarm(substeps, _)
        | Solver::Vbd(substeps, ..)
        | Solver::Verlet(substeps)) = solver;
        let dt = 1.0 / FPS / substeps as f64;
        for _ in 0..substeps {
            match solver {
                Solver::Xpbd(_) => self.xpbd_substep(dt),
                Solver::XpbdWarm(_, exact) => self.xpbd_warm_substep(dt, exact),
                Solver::Vbd(_, iters, rho) => self.vbd_substep(dt, iters, rho),
                Solver::Verlet(_) => self.verlet_substep(dt),
            }
        }
        self.seconds += t0.elapsed().as_secs_f64();
    }

    fn finish_velocities(&mut self, dt: f64) {
        let keep = 1.0 / (1.0 + self.drag * dt);
        for i in 0..self.x.len() {
            if self.lat.w[i] > 0.0 {
                self.v[i] = (self.x[i] - self.start[i]) / dt * keep;
            }
        }
    }

    fn xpbd_substep(&mut self, dt: f64) {
        self.start.copy_from_slice(&self.x);
        for i in 0..self.x.len() {
            if self.lat.w[i] > 0.0 {
                self.v[i] += self.gravity * dt;
                self.x[i] += self.v[i] * dt;
            }
        }
        self.lambda.fill([0.0; 5]);
        self.lat.xpbd_sweep(&mut self.x, dt, &mut self.lambda);
        self.finish_velocities(dt);
    }

    fn xpbd_warm_substep(&mut self, dt: f64, exact: bool) {
        self.start.copy_from_slice(&self.x);
        for i in 0..self.x.len() {
            if self.lat.w[i] > 0.0 {
                self.v[i] += self.gravity * dt;
                self.x[i] += self.v[i] * dt;
            }
        }
        self.y.copy_from_slice(&self.x);
        let beta: f64 = std::env::var("WARM")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(1.0);
        for l in self.lambda.iter_mut() {
            *l = l.map(|v| v * beta);
        }
        if exact {
            self.lat.apply_multipliers(&mut self.x, &self.lambda);
        } else {
            for (x, d) in self.x.iter_mut().zip(&self.moved) {
                *x += d;
            }
        }
        self.lat.xpbd_sweep(&mut self.x, dt, &mut self.lambda);
        for i in 0..self.x.len() {
            self.moved[i] = self.x[i] - self.y[i];
        }
        self.finish_velocities(dt);
    }

    fn verlet_substep(&mut self, dt: f64) {
        let lat = self.lat;
        if self.grad.is_empty() {
            self.grad = vec![V3::zeros(); self.x.len()];
            lat.gradient(&self.x, self.gravity, &mut self.grad);
        }
        for i in 0..self.x.len() {
            self.v[i] -= self.grad[i] * (0.5 * dt / lat.mass[i]);
            self.x[i] += self.v[i] * dt;
        }
        lat.gradient(&self.x, self.gravity, &mut self.grad);
        for i in 0..self.x.len() {
            self.v[i] -= self.grad[i] * (0.5 * dt / lat.mass[i]);
        }
    }

    fn vbd_substep(&mut self, dt: f64, iters: usize, rho: f64) {
        let lat = self.lat;
        let g = self.gravity;
        self.start.copy_from_slice(&self.x);
        for i in 0..self.x.len() {
            if lat.w[i] == 0.0 {
                self.y[i] = self.x[i];
                continue;
            }
            self.y[i] = self.x[i] + self.v[i] * dt + g * (dt * dt);
            // Adaptive initialisation (§3.7): the part of last step's acceleration along g.
            let along = if g.norm() > 0.0 {
                let a = (self.v[i] - self.v_old[i]).dot(&g.normalize()) / dt;
                (a / g.norm()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            self.x[i] += self.v[i] * dt + g * (along * dt * dt);
        }
        self.older.copy_from_slice(&self.x);
        self.last.copy_from_slice(&self.x);
        let mut omega = 1.0;
        for n in 1..=iters {
            for colour in &lat.node_colours {
                for &i in colour {
                    let i = i as usize;
                    if lat.w[i] == 0.0 {
                        continue;
                    }
                    let (grad, hess, neg) = lat.vertex_terms(&self.x, i);
                    let inertia = lat.mass[i] / (dt * dt);
                    let f = -(self.x[i] - self.y[i]) * inertia - grad;
                    let hess = hess + M3::identity() * inertia;
                    // Exact block if SPD, else without its negative (bᵀEb) I parts.
                    let spd = hess.cholesky().or_else(|| {
                        self.projected += 1;
                        (hess - M3::identity() * neg).cholesky()
                    });
                    if let Some(ch) = spd {
                        self.x[i] += ch.solve(&f);
                    }
                }
            }
            if rho > 0.0 {
                // Chebyshev (§3.8): ω₁ = 1, ω₂ = 2/(2 − ρ²), ωₙ = 4/(4 − ρ² ωₙ₋₁).
                omega = match n {
                    1 => 1.0,
                    2 => 2.0 / (2.0 - rho * rho),
                    _ => 4.0 / (4.0 - rho * rho * omega),
                };
                for i in 0..self.x.len() {
                    if n >= 2 && lat.w[i] > 0.0 {
                        self.x[i] = (self.x[i] - self.older[i]) * omega + self.older[i];
                    }
                    self.older[i] = self.last[i];
                    self.last[i] = self.x[i];
                }
            }
        }
        self.v_old.copy_from_slice(&self.v);
        self.finish_velocities(dt);
    }

    fn kinetic(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.lat.mass)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum()
    }
}

/// One table row's timing columns: ms per frame and ns per node-sweep.
fn timing(sim: &Sim, solver: Solver, frames: usize) -> String {
    let sweeps = (sim.lat.rest.len() * solver.sweeps_per_frame() * frames) as f64;
    format!(
        "{:>8.2} {:>7.1}",
        sim.seconds * 1e3 / frames as f64,
        sim.seconds * 1e9 / sweeps
    )
}

/// Run a settling scene per solver: the sag of `top` averaged over the last `average` of
/// `frames` frames against the static reference, and when it came within 1 % of that mean
/// for good (`settled`).
fn settle(
    lat: &Lattice,
    solvers: &[Solver],
    frames: usize,
    average: usize,
    top: &dyn Fn(&[V3]) -> f64,
    reference: f64,
    drag: f64,
) {
    let height = top(&lat.rest);
    println!(
        "{:<16} {:>6} {:>9} {:>8} {:>7} {:>8} {:>7} {:>6} {:>4}",
        "solver", "sweeps", "sag mm", "vs ref", "settled", "ms/frame", "ns/n-s", "min J", "proj"
    );
    for &solver in solvers {
        let n = lat.rest.len();
        let mut sim = Sim::new(lat, vec![V3::zeros(); n], V3::new(0.0, -9.81, 0.0), drag);
        let (mut sags, mut least) = (Vec::new(), f64::INFINITY);
        for _ in 0..frames {
            sim.frame(solver);
            sags.push(height - top(&sim.x));
            least = least.min(lat.min_corner_j(&sim.x));
        }
        let sag = sags[frames - average..].iter().sum::<f64>() / average as f64;
        if std::env::var("TRIAL_DEBUG").is_ok() {
            let mut g = vec![V3::zeros(); n];
            lat.gradient(&sim.x, V3::new(0.0, -9.81, 0.0), &mut g);
            let weight = lat.mass.iter().cloned().fold(0.0, f64::max) * 9.81;
            let before = sim.lambda.clone();
            sim.frame(solver);
            let drift = sim
                .lambda
                .iter()
                .zip(&before)
                .map(|(a, b)| (0..5).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            let size = before
                .iter()
                .map(|a| (0..5).map(|k| a[k].abs()).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            println!("  force left {:.3e} of a node weight; lambda change over a frame {drift:.3e} of {size:.3e}; speed {:.3e}", max_norm(&g) / weight, sim.v.iter().map(|v| v.norm()).fold(0.0, f64::max));
        }
        let settled = sags
            .iter()
            .rposition(|s| (s - sag).abs() > 0.01 * sag.abs());
        println!(
            "{:<16} {:>6} {:>9.4} {:>+7.2}% {:>6.2}s {} {:>6.3} {:>4}",
            solver.label() + if drag == 0.0 { " nodrag" } else { "" },
            solver.sweeps_per_frame(),
            sag * 1e3,
            (sag / reference - 1.0) * 100.0,
            settled.map_or(0, |f| f + 1) as f64 / FPS,
            timing(&sim, solver, frames),
            least,
            sim.projected
        );
    }
}

fn print_reference(lat: &Lattice, top: &dyn Fn(&[V3]) -> f64) -> f64 {
    let t0 = Instant::now();
    let (x, steps, cg, left) = lat.static_equilibrium(V3::new(0.0, -9.81, 0.0));
    let sag = top(&lat.rest) - top(&x);
    println!(
        "static reference (Newton {steps} steps, {cg} PCG iterations, {:.1} s, force left {left:.0e} of a node's weight): sag {:.4} mm",
        t0.elapsed().as_secs_f64(),
        sag * 1e3
    );
    sag
}

fn column_lattice() -> Lattice {
    Lattice::new([2, 10, 2], 0.1, 1.0e6, 0.0, 1000.0)
}

fn column(custom: &str) {
    let lat = column_lattice();
    println!("\n== column 0.2 x 1 x 0.2 m, 2x10x2 cells ({} nodes), E 1 MPa, nu 0, rho 1000; 96 frames, drag {DRAG}/s; sag = highest node (as solver_checks), mean of last 24 frames", lat.rest.len());
    println!("rho g H^2/(2E) = 4.9050 mm; the product's XPBD (30 substeps, its damping): 5.33 mm");
    let top = |x: &[V3]| x.iter().map(|p| p.y).fold(f64::MIN, f64::max);
    let reference = print_reference(&lat, &top);
    let list = "X5 X10 X20 X30 X60 X120 V1x10 V1x30 V1x60 V1x200 V2x15 V5x6 V10x3 V30x1 V30x2 V60x1 V1x30r0.95 V5x6r0.95";
    if !custom.is_empty() {
        return settle(&lat, &solvers(custom), 96, 24, &top, reference, DRAG);
    }
    settle(&lat, &solvers(list), 96, 24, &top, reference, DRAG);
    let undamped = solvers("X30 X60 V30x1 V5x6");
    settle(&lat, &undamped, 96, 24, &top, reference, 0.0);
}

fn cube(custom: &str) {
    let n = 15;
    let lat = Lattice::new([n, n, n], 1.0 / n as f64, 1.5e6, 0.47, 1100.0);
    println!("\n== rubber cube 1 m, 15^3 cells ({} nodes), E 1.5 MPa, nu 0.47, rho 1100; 48 frames, drag {DRAG}/s; sag = mean of the top layer, mean of last 12 frames", lat.rest.len());
    let layer = lat.top_layer();
    let top = move |x: &[V3]| layer.iter().map(|&p| x[p].y).sum::<f64>() / layer.len() as f64;
    let reference = print_reference(&lat, &top);
    let list = "X10 X30 X60 X120 V1x10 V1x30 V5x6 V30x1 V1x30r0.95";
    let list = if custom.is_empty() { list } else { custom };
    settle(&lat, &solvers(list), 48, 12, &top, reference, DRAG);
}

/// A column lattice (`lattice`) without gravity or drag, kicked with `v = v0 (y/H)` along
/// `axis`: energy (kinetic + elastic) kept at 1 s and 2 s, the top's peak displacement in
/// the second second over the first, and the RMS error of the top layer's mean displacement
/// (sampled per frame) against velocity Verlet at 400 substeps per frame (the first row),
/// over the reference's RMS.
fn kick(lat: &Lattice, axis: usize, solvers: &[Solver]) {
    let layer = lat.top_layer();
    let frames = 48;
    // Pinned nodes lie at y = 0: no kick.
    let v0: Vec<V3> = lat.rest.iter().map(|p| V3::ith(axis, 0.5 * p.y)).collect();
    let run = |solver: Solver| {
        let mut sim = Sim::new(lat, v0.clone(), V3::zeros(), 0.0);
        let e0 = sim.kinetic();
        let (mut track, mut energy, mut least) = (Vec::new(), Vec::new(), f64::INFINITY);
        for _ in 0..frames {
            sim.frame(solver);
            let d = layer.iter().map(|&p| sim.x[p][axis] - lat.rest[p][axis]);
            track.push(d.sum::<f64>() / layer.len() as f64);
            energy.push((sim.kinetic() + lat.energy(&sim.x)) / e0);
            least = least.min(lat.min_corner_j(&sim.x));
        }
        let time = format!("{} {least:>6.3}", timing(&sim, solver, frames));
        (track, energy, time)
    };
    let rms = |a: &[f64]| (a.iter().map(|d| d * d).sum::<f64>() / a.len() as f64).sqrt();
    println!(
        "{:<16} {:>6} {:>7} {:>7} {:>7} {:>8} {:>8} {:>7} {:>6}",
        "solver", "sweeps", "E(1s)", "E(2s)", "peak2/1", "traj err", "ms/frame", "ns/n-s", "min J"
    );
    let verlet = Solver::Verlet(400);
    let first = run(verlet);
    let reference = first.0.clone();
    let rows = solvers.iter().map(|&solver| (solver, run(solver)));
    for (solver, (track, energy, time)) in std::iter::once((verlet, first)).chain(rows) {
        let peak = |r: std::ops::Range<usize>| track[r].iter().fold(0.0f64, |m, d| m.max(d.abs()));
        let error: Vec<f64> = track.iter().zip(&reference).map(|(a, b)| a - b).collect();
        println!(
            "{:<16} {:>6} {:>7.4} {:>7.4} {:>7.3} {:>7.1}% {time}",
            solver.label(),
            solver.sweeps_per_frame(),
            energy[23],
            energy[47],
            peak(24..48) / peak(0..24),
            100.0 * rms(&error) / rms(&reference)
        );
    }
}

fn dynamics(custom: &str) {
    let all = "X5 X10 X20 X30 X60 X120 X480 V1x10 V1x30 V1x60 V2x15 V5x6 V5x30 V10x3 V10x10 V30x1 V30x2 V60x1 V120x1";
    let list = solvers(if custom.is_empty() { all } else { custom });
    let column = column_lattice();
    println!("\n== dynamics: the column, no gravity, no drag, 48 frames; kick v = 0.5 m/s (y/H) along x (bending, ~1 Hz)");
    kick(&column, 0, &list);
    println!("\n== dynamics: the same, kick along y (axial, ~8 Hz: the mode of a bounce)");
    kick(&column, 1, &list);
    let rubber = Lattice::new([2, 10, 2], 0.1, 1.5e6, 0.47, 1100.0);
    println!("\n== dynamics: the same column in rubber (E 1.5 MPa, nu 0.47, rho 1100), axial kick");
    kick(&rubber, 1, &list);
}

/// The per-vertex gradient and Hessian blocks against central differences of the energy,
/// on a randomly deformed 2×2×2 lattice with ν = 0.3 (both energy terms).
fn check() {
    let lat = Lattice::new([2, 2, 2], 0.1, 1.0e6, 0.3, 1000.0);
    let mut seed = 12345u64;
    let mut rand = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let x: Vec<V3> = lat
        .rest
        .iter()
        .map(|p| V3::new(p.x * 0.9, p.y * 1.1, p.z) + V3::new(rand(), rand(), rand()) * 0.03)
        .collect();
    let (mut g_err, mut h_err, mut g_scale, mut h_scale) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let eps = 1e-6;
    for i in 0..x.len() {
        let (g, hess, _) = lat.vertex_terms(&x, i);
        for a in 0..3 {
            let mut xp = x.clone();
            xp[i][a] += eps;
            let mut xm = x.clone();
            xm[i][a] -= eps;
            let fd = (lat.energy(&xp) - lat.energy(&xm)) / (2.0 * eps);
            g_err = g_err.max((fd - g[a]).abs());
            g_scale = g_scale.max(g[a].abs());
            let (gp, _, _) = lat.vertex_terms(&xp, i);
            let (gm, _, _) = lat.vertex_terms(&xm, i);
            let column = (gp - gm) / (2.0 * eps);
            h_err = h_err.max((column - hess.column(a)).amax());
            h_scale = h_scale.max(hess.column(a).amax());
        }
    }
    println!(
        "check: per-vertex gradient vs finite differences of the energy: max error {:.2e} of {:.2e}; Hessian block vs differences of the gradient: {:.2e} of {:.2e}",
        g_err, g_scale, h_err, h_scale
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenes = ["check", "column", "cube", "dynamics"];
    let named = args.iter().any(|a| scenes.contains(&a.as_str()));
    let wanted = |name: &str| !named || args.iter().any(|a| a == name);
    // Other words: budgets replacing the scenes' lists (e.g. `-- cube X30 V5x6`).
    let custom = args
        .iter()
        .filter(|a| !scenes.contains(&a.as_str()))
        .cloned()
        .collect::<Vec<_>>()
        .join(" ");
    println!(
        "vbd_trial, one thread, load average {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    if wanted("check") {
        check();
    }
    if wanted("column") {
        column(&custom);
    }
    if wanted("cube") {
        cube(&custom);
    }
    if wanted("dynamics") {
        dynamics(&custom);
    }
}
