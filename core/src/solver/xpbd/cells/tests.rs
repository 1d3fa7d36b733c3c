//! The cells' constraints on single cells and whole lattices: rest, inversion, the closed
//! form volume, energy, colouring and lane groups, and the multipliers a second sweep carries.

use super::*;

/// A cube cell of edge 0.1 m at rest, corner `c` at its bits `(x, y, z)`.
pub(in crate::solver::xpbd) fn unit_cube() -> [V3; 8] {
    std::array::from_fn(|c| {
        V3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64) * 0.1
    })
}

fn one_cell(material: &Material) -> CellSet {
    let mut set = CellSet::default();
    set.push(CellInput {
        nodes: std::array::from_fn(|c| c as u32),
        rest: unit_cube(),
        material,
        stiffness_scale: 1.0,
        axis_scale: [1.0; 3],
    });
    set.finish(8);
    set
}

#[test]
fn a_cell_at_rest_or_rotated_does_not_move() {
    let rubber = Material::preset("rubber").unwrap();
    let mut set = one_cell(&rubber);
    let rot = nalgebra::UnitQuaternion::from_scaled_axis(V3::new(0.3, 0.9, -0.2));
    let mut x: Vec<V3> = unit_cube().iter().map(|p| rot * p + V3::x()).collect();
    let before = x.clone();
    for _ in 0..20 {
        set.solve(&mut x, &[1.0; 8], 1e-3, Pass::Lone);
    }
    // The lanes solve in single precision: within 1e-7 of the 0.1 m edge (a strain that
    // is not rotation-invariant would move it by a tenth of that edge).
    for (a, b) in x.iter().zip(&before) {
        assert!((a - b).norm() < 1e-8, "{a} vs {b}");
    }
}

#[test]
fn an_inverted_cell_is_restored() {
    let jelly = Material::preset("jelly").unwrap();
    let mut set = one_cell(&jelly);
    // Push the top face through the bottom one.
    let mut x: Vec<V3> = unit_cube().to_vec();
    for c in [2, 3, 6, 7] {
        x[c].y = -0.05;
    }
    assert!(crate::solver::volume::cell_volume(&std::array::from_fn(|c| c as u32), &x) < 0.0);
    for _ in 0..200 {
        set.solve(&mut x, &[1.0; 8], 1.0 / 240.0, Pass::Lone);
    }
    let cell: [u32; 8] = std::array::from_fn(|c| c as u32);
    let v = crate::solver::volume::cell_volume(&cell, &x);
    assert!((v - 1e-3).abs() < 1e-5, "volume {v}");
}

/// The closed-form Kuhn volume and gradient against the six tets summed one by one, on
/// cells sheared, squashed, turned and inverted.
#[test]
fn a_cubes_closed_form_volume_is_its_six_tets() {
    let mut rng = fastrand::Rng::with_seed(5);
    for case in 0..200 {
        let spread = if case < 100 { 0.03 } else { 0.2 };
        let x: [V3; 8] = std::array::from_fn(|c| {
            let jitter = V3::new(rng.f64(), rng.f64(), rng.f64()) - V3::repeat(0.5);
            unit_cube()[c] + jitter * spread + V3::new(3.0, -1.0, 2.0)
        });
        let mut volume = 0.0;
        let mut grad = [V3::zeros(); 8];
        for [a, b, c, d] in crate::solver::volume::TETS {
            let (e1, e2, e3) = (x[b] - x[a], x[c] - x[a], x[d] - x[a]);
            let (g1, g2, g3) = (e2.cross(&e3), e3.cross(&e1), e1.cross(&e2));
            volume += e1.dot(&g1) / 6.0;
            grad[b] += g1 / 6.0;
            grad[c] += g2 / 6.0;
            grad[d] += g3 / 6.0;
            grad[a] -= (g1 + g2 + g3) / 6.0;
        }
        let (closed, closed_grad) = cube_volume(&x);
        assert!(
            (closed - volume).abs() < 1e-15,
            "case {case}: {closed} vs {volume}"
        );
        for k in 0..8 {
            let e = (closed_grad[k] - grad[k]).norm();
            assert!(
                e < 1e-14,
                "case {case}, node {k}: {} vs {}",
                closed_grad[k],
                grad[k]
            );
        }
    }
}

/// A cube cell's energy, written out per corner, against the general element path (F as
/// edges times the element's map, the Green strain as `(FᵀF − I)/2`): deformed cells,
/// both parities, anisotropic.
#[test]
fn a_cubes_energy_is_the_element_paths() {
    let jelly = Material::preset("jelly").unwrap();
    let mut rng = fastrand::Rng::with_seed(11);
    for (odd, axis) in [(false, [1.0; 3]), (true, [1.0, 2.0, 0.5])] {
        let mut set = one_cell(&jelly);
        set.shape[0] = Shape::Cube { inv_h: 10.0, odd };
        set.axis_root[0] = axis;
        let x: Vec<V3> = (unit_cube().iter())
            .map(|p| p + V3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5) * 0.04)
            .collect();
        let local: [V3; 8] = std::array::from_fn(|k| x[k]);
        let (kh, kd) = (inverse(set.hydro_alpha[0]), inverse(set.dev_alpha[0]));
        let c_h = cube_volume(&local).0 * 1000.0 - 1.0;
        let mut reference = 0.5 * kh * c_h * c_h;
        for_each_element(set.shape[0], |element| {
            let e = green_strain(&element.gradient(&local));
            let weighted = Matrix3::from_fn(|i, k| e[(i, k)] * axis[i] * axis[k]);
            reference += 0.5 * kd * e.dot(&weighted);
        });
        let energy = set.cell_energy(0, &x);
        assert!(
            (energy - reference).abs() <= 1e-12 * reference,
            "{energy} vs {reference}"
        );
    }
}

/// The cells `keep` picks of an `n`×`n`×`n` lattice of unit cubes, finished.
fn lattice_set(n: usize, keep: impl Fn(usize, usize, usize) -> bool) -> CellSet {
    let rubber = Material::preset("rubber").unwrap();
    let mut set = CellSet::default();
    let side = n + 1;
    let id = |i: usize, j: usize, k: usize| (i + side * (j + side * k)) as u32;
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                if !keep(i, j, k) {
                    continue;
                }
                let corner = |c: usize| (i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                set.push(CellInput {
                    nodes: std::array::from_fn(|c| {
                        let (a, b, d) = corner(c);
                        id(a, b, d)
                    }),
                    rest: std::array::from_fn(|c| {
                        let (a, b, d) = corner(c);
                        V3::new(a as f64, b as f64, d as f64)
                    }),
                    material: &rubber,
                    stiffness_scale: 1.0,
                    axis_scale: [1.0; 3],
                });
            }
        }
    }
    set.finish(side * side * side);
    set
}

/// The lanes' inverse masses follow the ones a substep passes: a node pinned between two
/// sweeps stays where it is, and the sweep is the one a fresh set makes.
#[test]
fn the_lanes_take_the_masses_of_each_sweep() {
    let n = 4;
    let side = n + 1;
    let squashed = |x: &mut Vec<V3>| {
        for (i, p) in x.iter_mut().enumerate() {
            let k = i / (side * side);
            *p = V3::new(
                (i % side) as f64,
                ((i / side) % side) as f64,
                k as f64 * 0.8,
            );
        }
    };
    let mut x = Vec::new();
    x.resize(side * side * side, V3::zeros());
    squashed(&mut x);
    let mut w = vec![1.0; x.len()];
    let mut kept = lattice_set(n, |_, _, _| true);
    kept.solve(&mut x.clone(), &w, 1e-3, Pass::Lone);
    let pinned = 2 + side * (2 + side * 2);
    w[pinned] = 0.0;
    let mut y = x.clone();
    kept.solve(&mut x, &w, 1e-3, Pass::Lone);
    lattice_set(n, |_, _, _| true).solve(&mut y, &w, 1e-3, Pass::Lone);
    assert_eq!(x, y);
    assert_eq!(x[pinned], V3::new(2.0, 2.0, 1.6));
    assert_ne!(x[pinned + 1], V3::new(3.0, 2.0, 1.6));
}

#[test]
fn lattice_cells_take_eight_colours() {
    let set = lattice_set(3, |_, _, _| true);
    assert_eq!(set.colours.len(), 8);
    assert_eq!(set.serial_colour, None);
}

/// A sparse lattice, whose colours hold cubes of both corner parities: each colour's
/// lane groups cover its cells once, in order, each group one parity and at most
/// [`LANES`] cells, and a parity's run splits into as few groups as it can.
#[test]
fn lane_groups_keep_to_one_parity() {
    let set = lattice_set(7, |i, j, k| (i * 7 + j * 3 + k * 5) % 4 != 0);
    let parity = |j: usize| match set.shape[j] {
        Shape::Cube { odd, .. } => odd,
        Shape::Tet { .. } => panic!("a lattice has cubes only"),
    };
    let mut mixed_colours = 0;
    for (colour, range) in set.colours.iter().enumerate() {
        let groups = &set.groups[set.colour_groups[colour].clone()];
        let mut next = range.start;
        for g in groups {
            assert_eq!(g.start, next, "colour {colour}");
            assert!(!g.is_empty() && g.len() <= LANES);
            assert!(g.clone().all(|j| parity(j) == parity(g.start)));
            next = g.end;
        }
        assert_eq!(next, range.end, "colour {colour}");
        let odd = range.clone().filter(|&j| parity(j)).count();
        let even = range.len() - odd;
        mixed_colours += usize::from(odd > 0 && even > 0);
        assert_eq!(groups.len(), odd.div_ceil(LANES) + even.div_ceil(LANES));
    }
    assert!(mixed_colours > 0, "no colour holds both parities");
}

/// The sag of the top of a 3 × 3 × 3 lattice of 1 cm rubber cells standing on its held base
/// under gravity, stepped to rest at 720 substeps a second (its wave crosses a cell five times
/// a substep) with `sweeps` after the first in each substep; `carry`: those sweeps take up
/// the first's multipliers ([`Pass::Again`]), else each starts afresh ([`Pass::Lone`]).
fn lattice_sag(sweeps: usize, carry: bool) -> f64 {
    let n = 3;
    let side = n + 1;
    let mut set = lattice_set(n, |_, _, _| true);
    let h = 0.01;
    let mut x: Vec<V3> = (0..side * side * side)
        .map(|i| {
            V3::new(
                (i % side) as f64,
                ((i / side) % side) as f64,
                (i / side / side) as f64,
            ) * h
        })
        .collect();
    // Rubber's density; the base layer (y = 0) held.
    let m = 1100.0 * h * h * h;
    let w: Vec<f64> = x
        .iter()
        .map(|p| if p.y == 0.0 { 0.0 } else { 1.0 / m })
        .collect();
    let rest = x.clone();
    // `lattice_set` made its cells of unit edge: scale them to `h`.
    for cell in &mut set.shape {
        if let Shape::Cube { inv_h, .. } = cell {
            *inv_h = 1.0 / h;
        }
    }
    for a in &mut set.hydro_alpha {
        *a /= h * h * h;
    }
    for a in &mut set.dev_alpha {
        *a /= h * h * h;
    }
    let dt = 1.0 / 720.0;
    let mut v = vec![V3::zeros(); x.len()];
    for _ in 0..4000 {
        let before = x.clone();
        for i in 0..x.len() {
            if w[i] > 0.0 {
                v[i].y -= 9.81 * dt;
                x[i] += v[i] * dt;
            }
        }
        let first = if sweeps > 0 && carry {
            Pass::First
        } else {
            Pass::Lone
        };
        set.solve(&mut x, &w, dt, first);
        for _ in 0..sweeps {
            set.solve(&mut x, &w, dt, if carry { Pass::Again } else { Pass::Lone });
        }
        for i in 0..x.len() {
            v[i] = (x[i] - before[i]) / dt * 0.99;
        }
    }
    let top = (0..x.len()).filter(|&i| rest[i].y == n as f64 * h);
    let sags: Vec<f64> = top.map(|i| rest[i].y - x[i].y).collect();
    sags.iter().sum::<f64>() / sags.len() as f64
}

/// Sweeps after the first that take up its multipliers converge the substep's solve: one
/// more takes the column's sag more than halfway from one sweep's (20 times elasticity's
/// here) to where many put it, and many rest it where still more do. Sweeps that start
/// their multipliers afresh stiffen the material instead: eight of them leave a fifth of
/// eight carried ones' sag (measured: one sweep 6.4e-5 m, two 2.9e-5, nine 6.8e-6, nine
/// afresh 1.4e-6; elasticity, ρgH²/2E, 3.2e-6).
#[test]
fn sweeps_that_take_up_the_multipliers_converge_and_do_not_stiffen() {
    let one = lattice_sag(0, true);
    let two = lattice_sag(1, true);
    let nine = lattice_sag(8, true);
    let seventeen = lattice_sag(16, true);
    let afresh = lattice_sag(8, false);
    assert!(
        two - nine < 0.5 * (one - nine),
        "sags {one:e}, {two:e}, {nine:e}"
    );
    assert!(
        (nine / seventeen - 1.0).abs() < 0.2,
        "sags {nine:e}, {seventeen:e}"
    );
    assert!(afresh < 0.5 * nine, "afresh {afresh:e}, carried {nine:e}");
}
