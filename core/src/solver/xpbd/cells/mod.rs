//! The volumetric cell model of the XPBD solver: every lattice cell (and every cage tet) is an
//! elastic solid with the material's Young's modulus and Poisson ratio, not a set of springs.
//!
//! A lattice cell is integrated at four of its corners: corner `c` and its three edge
//! neighbours (`c^1`, `c^2`, `c^4`) span a corner tetrahedron whose deformation gradient is
//! `F_c = [s_x (x_{c^1} − x_c), s_y (x_{c^2} − x_c), s_z (x_{c^4} − x_c)] / h` (`s = ±1` so a
//! cell at rest gives `F = I`), each standing for a quarter of the cell's volume. The four are
//! every other corner (`{0, 3, 5, 6}` or `{1, 2, 4, 7}`, alternating from cell to cell like
//! the five-tet split, so the discretisation has no preferred diagonal): their twelve edges are
//! the cell's and their tets hold the central tet's six edges too, so the cell has no
//! deformation they do not see. Inverting any corner tetrahedron (what
//! [`crate::lattice::cell_is_inverted`] counts) moves one of these corners' nodes through
//! its tet, which they resist.
//!
//! The energy is Hooke's law made rotation-invariant: a Green-strain (St Venant–Kirchhoff)
//! shear part per corner and a volumetric part per cell,
//! `Ψ = Σ_corners V_c μ ‖E_c‖²_F + ½ λ V_0 (V/V_0 − 1)²`, `E = ½ (FᵀF − I)`, `μ, λ` the Lamé
//! parameters of (E, ν), `V` the cell's volume (its six Kuhn tets, as in
//! [`crate::solver::volume`]). Taking the volume once per cell rather than per corner is
//! selective reduced integration: a nearly incompressible material (jelly, rubber: ν ≈ 0.5)
//! can still shear the lattice instead of locking.
//! At small strain it is linear elasticity with the user's E and ν; it does not change under a
//! rotation of the element, so it exerts no torque and a spinning body keeps its angular
//! momentum. Green strain alone does not see an inverted element (`E` is the same for `F` and
//! a reflection of it); the volumetric term does (`det F < 0` is far from 1), and below
//! [`COLLAPSE_J`] a barrier with the shear stiffness pushes a collapsing corner back open
//! even when ν = 0 leaves λ at zero. As XPBD constraints (Macklin et al. 2016):
//! `C_H = V/V_0 − 1` with compliance `1/(λ V_0)`, `C_D = ‖E‖_F` with compliance
//! `1/(2 μ V_c)`, `V_c` the corner's share of the rest volume; stiffness therefore does not
//! depend on the substep count. A cage's tet is one element with its own rest shape (`C_H =
//! det F − 1` on the tet).
//!
//! Cells are coloured greedily so that no two cells of a colour share a node (a lattice
//! gets the eight colours of `(i, j, k) mod 2`); a colour's cells are solved side by side on
//! local copies of their eight nodes and written back in cell order, so any thread count gives
//! the same bits.

use super::lanes::{
    highest_node, mass_lanes, solve_cubes, Cubes, Gather, MassLanes, Multipliers, Sweep, LANES,
};
use crate::material::Material;
use crate::solver::team::{self, Disjoint, Tasks};
use nalgebra::{Matrix3, Vector3};
use std::ops::Range;

type V3 = Vector3<f64>;

/// Below this volume ratio a corner also meets the collapse barrier `det F − COLLAPSE_J ≥ 0`
/// with the shear compliance.
pub(crate) const COLLAPSE_J: f64 = 0.2;

/// The rest shape of one cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Shape {
    /// An axis-aligned cube of edge `1 / inv_h` at rest (lattice cells): four corner
    /// elements, at the odd corners (`1, 2, 4, 7`) or the even ones (`0, 3, 5, 6`).
    Cube { inv_h: f64, odd: bool },
    /// A tetrahedron stored as a degenerate cell `[a, b, a, c, a, a, a, d]` (cages, and cells
    /// that are not axis-aligned cubes, split in six): one element, `Dm⁻¹` of its rest edges.
    Tet { dm_inv: Matrix3<f64> },
}

/// Lamé parameters `(μ, λ)` of a material, Pa.
pub(crate) fn lame(material: &Material) -> (f64, f64) {
    let (e, nu) = (material.young_pa, material.poisson);
    (
        e / (2.0 * (1.0 + nu)),
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
    )
}

/// What [`CellSet::push`] needs of one cell.
pub(crate) struct CellInput<'a> {
    /// World node ids (joint followers already resolved to their kept node).
    pub nodes: [u32; 8],
    /// Rest positions of `nodes`.
    pub rest: [V3; 8],
    pub material: &'a Material,
    /// Stiffness factor of the cell (regions), 1 by default.
    pub stiffness_scale: f64,
    /// Stiffness factor per axis (anisotropy), `[1, 1, 1]` by default: the shear energy
    /// weights strain component `E_ij` by `sqrt(s_i s_j)` (a stretch along x meets `s_x` times
    /// the stiffness, as the spring lattice's edges along x do), the volume term by the
    /// geometric mean.
    pub axis_scale: [f64; 3],
}

/// All elastic cells of a world, ordered by colour.
#[derive(Debug, Clone, Default)]
pub(crate) struct CellSet {
    nodes: Vec<[u32; 8]>,
    shape: Vec<Shape>,
    /// Compliance of the volumetric constraint per cell, `1/(λ V_0)` (∞: none).
    hydro_alpha: Vec<f64>,
    /// Compliance of the deviatoric constraint per element, `1/(2 μ V_c)`.
    dev_alpha: Vec<f64>,
    /// Per cell: `sqrt` of the per-axis stiffness factors (`[1, 1, 1]`: isotropic).
    axis_root: Vec<[f64; 3]>,
    /// Cells of each colour; the last one may be `serial` (cells that share nodes).
    colours: Vec<Range<usize>>,
    serial_colour: Option<usize>,
    /// Runs of up to [`LANES`] cells of one colour and one kind (cubes of one corner parity,
    /// or tets) that the lanes solve together, colour after colour.
    groups: Vec<Range<usize>>,
    /// The groups of each colour (ranges of `groups`).
    colour_groups: Vec<Range<usize>>,
    /// Per group of cubes, its lanes' parameters for substeps of `lanes_dt` seconds and its
    /// highest node (`None` for tets): made again when the substep's length changes, not at
    /// every group of every substep.
    lanes: Vec<Option<(Cubes, u32)>>,
    /// The substep length `lanes` are for (NaN: not made).
    lanes_dt: f64,
    /// Per group, its nodes' inverse masses in lanes ([`mass_lanes`]), made from `lanes_w`.
    lane_masses: Vec<MassLanes>,
    /// The inverse masses `lane_masses` were made from: made again when a substep's differ
    /// (a pin let go, a node bound to a path), compared bit for bit.
    lanes_w: Vec<f64>,
    /// Shortest rest edge of any cell, m (0 without cells).
    pub shortest_edge: f64,
    /// Largest `sqrt(E/ρ)` of any cell's material, m/s.
    pub wave_speed: f64,
    /// Smallest `sqrt(E/ρ)` of any cell's material, m/s (0 without cells).
    pub slowest_wave: f64,
    /// The multipliers a [`Pass::First`] kept for a [`Pass::Again`]: per cell of the scalar
    /// path (volume and shear; a tet's in the first two), and per lane group.
    cell_multipliers: Vec<[f64; 5]>,
    lane_multipliers: Vec<Multipliers>,
}

/// Which sweep of a substep [`CellSet::solve`] is: the only one, the first of two, or the
/// second, which takes up the first's multipliers ([`Sweep`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Pass {
    Lone,
    First,
    Again,
}

impl Pass {
    /// This pass over one cell's or group's multipliers.
    fn of<T>(self, lambda: &mut T) -> Sweep<'_, T> {
        match self {
            Pass::Lone => Sweep::Lone,
            Pass::First => Sweep::First(lambda),
            Pass::Again => Sweep::Again(lambda),
        }
    }
}

/// Display-surface points grouped by their cell (see [`CellSet::point_groups`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct PointGroups {
    /// Point indices, group after group.
    pub order: Vec<u32>,
    /// Ranges of `order`: the points of one cell.
    pub groups: Vec<Range<u32>>,
    /// Ranges of `groups`: the groups of one colour (the last may be the points in no cell).
    pub colours: Vec<Range<u32>>,
    /// Per range of `colours`: whether its groups' cells share no node (a colour of the set
    /// other than its serial one), so its groups may run side by side.
    pub parallel: Vec<bool>,
}

/// Colours past this one go to one serial colour.
const MAX_COLOURS: usize = 64;

/// Lane groups a task of a colour pass solves (see [`team`]).
const GROUPS_PER_TASK: usize = 4;

/// Cells a task of a colour's barrier pass looks at.
const BARRIER_CELLS: usize = 128;

impl CellSet {
    /// Add one cell (in any order; [`Self::finish`] colours them). Degenerate cells are left
    /// out.
    pub(crate) fn push(&mut self, cell: CellInput) {
        let (mu, lambda) = lame(cell.material);
        let [sx, sy, sz] = cell.axis_scale;
        let mean = (sx * sy * sz).cbrt();
        let (mu, lambda) = (
            mu * cell.stiffness_scale,
            lambda * cell.stiffness_scale * mean,
        );
        let stiffest = sx.max(sy).max(sz) * cell.stiffness_scale;
        let speed = (cell.material.young_pa * stiffest / cell.material.density_kg_m3).sqrt();
        let root = cell.axis_scale.map(f64::sqrt);
        if crate::cage::is_tet_cell(&cell.nodes) {
            let rest = [0, 1, 3, 7].map(|c| cell.rest[c]);
            if self.push_tet(cell.nodes, rest, mu, lambda, speed) {
                self.axis_root.push(root);
            }
            return;
        }
        let r = &cell.rest;
        let h = (r[1] - r[0]).norm();
        let cube = h > 0.0
            && (0..8).all(|c| {
                let ideal = r[0]
                    + V3::new(
                        (c & 1) as f64 * h,
                        ((c >> 1) & 1) as f64 * h,
                        ((c >> 2) & 1) as f64 * h,
                    );
                (r[c] - ideal).norm() <= 1e-6 * h
            });
        if cube {
            let corner_volume = h * h * h / 4.0;
            // Alternate with the cell's place on its grid (rest corner 0 over the edge).
            let parity = r[0].iter().map(|v| (v / h).round() as i64).sum::<i64>();
            self.nodes.push(cell.nodes);
            self.shape.push(Shape::Cube {
                inv_h: 1.0 / h,
                odd: parity.rem_euclid(2) == 1,
            });
            self.hydro_alpha.push(compliance(lambda * h * h * h));
            self.dev_alpha.push(compliance(2.0 * mu * corner_volume));
            self.axis_root.push(root);
            self.note_scale(h, speed);
        } else {
            // Not an axis-aligned cube: Kuhn's six tets (see `volume::TETS`).
            for t in crate::solver::volume::TETS {
                let nodes = t.map(|c| cell.nodes[c]);
                let rest = t.map(|c| cell.rest[c]);
                if self.push_tet(crate::cage::tet_cell(nodes), rest, mu, lambda, speed) {
                    self.axis_root.push(root);
                }
            }
        }
    }

    fn push_tet(
        &mut self,
        nodes: [u32; 8],
        rest: [V3; 4],
        mu: f64,
        lambda: f64,
        speed: f64,
    ) -> bool {
        let dm = Matrix3::from_columns(&[rest[1] - rest[0], rest[2] - rest[0], rest[3] - rest[0]]);
        let volume = dm.determinant() / 6.0;
        let Some(dm_inv) = dm.try_inverse().filter(|_| volume > 0.0) else {
            return false;
        };
        let shortest = (1..4)
            .map(|k| (rest[k] - rest[0]).norm())
            .fold(f64::INFINITY, f64::min);
        self.nodes.push(nodes);
        self.shape.push(Shape::Tet { dm_inv });
        self.hydro_alpha.push(compliance(lambda * volume));
        self.dev_alpha.push(compliance(2.0 * mu * volume));
        self.note_scale(shortest, speed);
        true
    }

    fn note_scale(&mut self, edge: f64, speed: f64) {
        // 0 until the first cell (the derived default).
        self.shortest_edge = if self.shortest_edge > 0.0 {
            self.shortest_edge.min(edge)
        } else {
            edge
        };
        self.wave_speed = self.wave_speed.max(speed);
        self.slowest_wave = if self.slowest_wave > 0.0 {
            self.slowest_wave.min(speed)
        } else {
            speed
        };
    }

    pub(crate) fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Colour the cells (greedy, in the order pushed) and order them by colour.
    pub(crate) fn finish(&mut self, node_count: usize) {
        let mut used = vec![0u64; node_count];
        let colour: Vec<usize> = self
            .nodes
            .iter()
            .map(|cell| {
                let taken = cell.iter().fold(0u64, |m, &n| m | used[n as usize]);
                let c = taken.trailing_ones() as usize;
                if c < MAX_COLOURS {
                    for &n in cell {
                        used[n as usize] |= 1 << c;
                    }
                }
                c.min(MAX_COLOURS)
            })
            .collect();
        // Within a colour, cube cells of one corner parity side by side (then the others,
        // then tets): up to eight consecutive cubes of one parity are one lane group.
        let kind = |shape: &Shape| match shape {
            Shape::Cube { odd: false, .. } => 0,
            Shape::Cube { odd: true, .. } => 1,
            Shape::Tet { .. } => 2,
        };
        let mut order: Vec<usize> = (0..self.nodes.len()).collect();
        order.sort_by_key(|&i| (colour[i], kind(&self.shape[i])));
        let nodes = order.iter().map(|&i| self.nodes[i]).collect();
        let shape = order.iter().map(|&i| self.shape[i]).collect();
        let hydro = order.iter().map(|&i| self.hydro_alpha[i]).collect();
        let dev = order.iter().map(|&i| self.dev_alpha[i]).collect();
        let axis = order.iter().map(|&i| self.axis_root[i]).collect();
        (self.nodes, self.shape, self.axis_root) = (nodes, shape, axis);
        (self.hydro_alpha, self.dev_alpha) = (hydro, dev);
        self.colours.clear();
        self.serial_colour = None;
        let mut start = 0;
        while start < order.len() {
            let c = colour[order[start]];
            let end = start + order[start..].partition_point(|&i| colour[i] == c);
            if c == MAX_COLOURS {
                self.serial_colour = Some(self.colours.len());
            }
            self.colours.push(start..end);
            start = end;
        }
        self.groups.clear();
        self.colour_groups.clear();
        for colour in &self.colours {
            let first_group = self.groups.len();
            let mut start = colour.start;
            while start < colour.end {
                let of_kind = kind(&self.shape[start]);
                let run = &self.shape[start..colour.end];
                let end = start + run.partition_point(|s| kind(s) == of_kind);
                let mut group = start;
                while group < end {
                    self.groups.push(group..(group + LANES).min(end));
                    group = (group + LANES).min(end);
                }
                start = end;
            }
            self.colour_groups.push(first_group..self.groups.len());
        }
        self.lanes.clear();
        self.lanes_dt = f64::NAN;
        self.lane_masses.clear();
        self.lanes_w.clear();
    }

    /// Make the groups' inverse masses in lanes ([`Self::lane_masses`]) from `w`, unless
    /// they are already made from the same bits.
    fn refresh_lane_masses(&mut self, w: &[f64]) {
        let differ = |a: &f64, b: &f64| a.to_bits() ^ b.to_bits();
        let same = self.lanes_w.len() == w.len()
            && self.lane_masses.len() == self.groups.len()
            // An OR of the differences, not a search that stops at the first: it vectorises.
            && self.lanes_w.iter().zip(w).fold(0, |any, (a, b)| any | differ(a, b)) == 0;
        if same {
            return;
        }
        self.lanes_w.clear();
        self.lanes_w.extend_from_slice(w);
        let nodes = &self.nodes;
        let masses = self.groups.iter().map(|g| mass_lanes(&nodes[g.clone()], w));
        self.lane_masses = masses.collect();
    }

    /// Make the groups' lane parameters ([`Self::lanes`]) for substeps of `dt` seconds.
    fn make_lanes(&mut self, dt: f64) {
        let inv_dt2 = 1.0 / (dt * dt);
        let lanes = self.groups.iter().map(|group| {
            let odd = match self.shape[group.start] {
                Shape::Cube { odd, .. } => odd,
                Shape::Tet { .. } => return None,
            };
            // A short group's other lanes repeat its last cell (see [`Gather`]).
            let cell = |k: usize| group.start + k.min(group.len() - 1);
            let inv_h = std::array::from_fn(|k| match self.shape[cell(k)] {
                Shape::Cube { inv_h, .. } => inv_h as f32,
                Shape::Tet { .. } => 0.0,
            });
            let cubes = Cubes {
                inv_h,
                hydro: std::array::from_fn(|k| (self.hydro_alpha[cell(k)] * inv_dt2) as f32),
                dev: std::array::from_fn(|k| (self.dev_alpha[cell(k)] * inv_dt2) as f32),
                axis_root: std::array::from_fn(|i| {
                    std::array::from_fn(|k| self.axis_root[cell(k)][i] as f32)
                }),
                odd,
            };
            Some((cubes, highest_node(&self.nodes[group.clone()])))
        });
        self.lanes = lanes.collect();
        self.lanes_dt = dt;
    }

    /// The display-surface points (their cells' node ids, joint followers already resolved)
    /// grouped by the cell they lie in, in the cells' colour order: what the contact pass
    /// visits in order, and what a device runs a colour of at a time (groups of one colour
    /// share no node). Points in no cell of this set come last, as one group.
    pub(crate) fn point_groups(&self, point_nodes: impl Iterator<Item = [u32; 8]>) -> PointGroups {
        let cell_of: rustc_hash::FxHashMap<[u32; 8], u32> = self
            .nodes
            .iter()
            .enumerate()
            .map(|(c, nodes)| (*nodes, c as u32))
            .collect();
        let mut keyed: Vec<(u32, u32)> = point_nodes
            .enumerate()
            .map(|(i, nodes)| (cell_of.get(&nodes).copied().unwrap_or(u32::MAX), i as u32))
            .collect();
        keyed.sort_unstable();
        let mut groups = PointGroups {
            order: keyed.iter().map(|&(_, i)| i).collect(),
            ..PointGroups::default()
        };
        let mut colour_of_group = Vec::new();
        let mut start = 0;
        while start < keyed.len() {
            let cell = keyed[start].0;
            let end = start + keyed[start..].partition_point(|k| k.0 == cell);
            groups.groups.push(start as u32..end as u32);
            let colour = self
                .colours
                .iter()
                .position(|r| r.contains(&(cell as usize)));
            colour_of_group.push(colour.unwrap_or(self.colours.len()));
            start = end;
        }
        let mut first = 0;
        while first < colour_of_group.len() {
            let c = colour_of_group[first];
            let end = first + colour_of_group[first..].partition_point(|&k| k == c);
            groups.colours.push(first as u32..end as u32);
            (groups.parallel).push(c < self.colours.len() && Some(c) != self.serial_colour);
            first = end;
        }
        groups
    }

    /// Whether some cells share nodes within their colour (more than [`MAX_COLOURS`] were
    /// needed) or are not lattice cubes: what a device solver does not run.
    pub(crate) fn all_coloured_cubes(&self) -> bool {
        self.serial_colour.is_none() && self.shape.iter().all(|s| matches!(s, Shape::Cube { .. }))
    }

    /// The cells as a device takes them (see [`crate::solver::device`]): colour ranges and,
    /// per cell, its nodes, `1/h`, compliances (the volume's `None` where λ is 0), axis
    /// roots and corner parity. Only for [`Self::all_coloured_cubes`].
    pub(crate) fn device_cells(&self) -> (Vec<crate::solver::device::DeviceCell>, Vec<Range<u32>>) {
        let cells = (0..self.nodes.len())
            .map(|j| {
                let (inv_h, odd) = match self.shape[j] {
                    Shape::Cube { inv_h, odd } => (inv_h, odd),
                    Shape::Tet { .. } => (0.0, false),
                };
                crate::solver::device::DeviceCell {
                    nodes: self.nodes[j],
                    inv_h,
                    odd,
                    volume_compliance: self.hydro_alpha[j]
                        .is_finite()
                        .then_some(self.hydro_alpha[j]),
                    shear_compliance: self.dev_alpha[j],
                    axis_root: self.axis_root[j],
                }
            })
            .collect();
        let colours = self
            .colours
            .iter()
            .map(|r| r.start as u32..r.end as u32)
            .collect();
        (cells, colours)
    }

    /// One Gauss–Seidel sweep over every cell's constraints (colour by colour), moving the
    /// positions `x` with inverse masses `w` (0: the node does not move), for a substep of
    /// `dt` seconds. A [`Pass::First`] keeps each constraint's multiplier for a
    /// [`Pass::Again`] in the same substep, which takes them up ([`Sweep`]); that one's `w`
    /// may hold more nodes still than the first's (its lanes' masses are made from it, not
    /// kept).
    pub(crate) fn solve(&mut self, x: &mut [V3], w: &[f64], dt: f64, pass: Pass) {
        let inv_dt2 = 1.0 / (dt * dt);
        if self.lanes_dt != dt || self.lanes.len() != self.groups.len() {
            self.make_lanes(dt);
        }
        if pass != Pass::Again {
            self.refresh_lane_masses(w);
        }
        self.cell_multipliers.resize(self.nodes.len(), [0.0; 5]);
        self.lane_multipliers
            .resize(self.groups.len(), [[0.0; LANES]; 5]);
        let cell_multipliers = Disjoint::new(&mut self.cell_multipliers);
        let lane_multipliers = Disjoint::new(&mut self.lane_multipliers);
        for (colour, range) in self.colours.iter().enumerate() {
            let nodes = &self.nodes[range.clone()];
            let shape = &self.shape[range.clone()];
            let hydro = &self.hydro_alpha[range.clone()];
            let dev = &self.dev_alpha[range.clone()];
            let axis = &self.axis_root[range.clone()];
            let xs = Disjoint::new(&mut *x);
            // SAFETY (every `get`, `set` and `solve_cubes` of this colour): a node belongs
            // to one cell of the colour, so no two tasks read or write the same one, and a
            // cell or a group to one task; the serial colour's cells, which may share nodes,
            // run one after the other here.
            #[allow(unsafe_code)]
            let solve_one = |j: usize| {
                let mut local = nodes[j].map(|n| unsafe { xs.get(n as usize) });
                let wl = nodes[j].map(|n| w[n as usize]);
                let alphas = (hydro[j] * inv_dt2, dev[j] * inv_dt2);
                let cell = range.start + j;
                if pass == Pass::Lone {
                    solve_cell(&mut local, &wl, shape[j], alphas, &axis[j], Sweep::Lone);
                } else {
                    let mut lambda = unsafe { cell_multipliers.get(cell) };
                    solve_cell(
                        &mut local,
                        &wl,
                        shape[j],
                        alphas,
                        &axis[j],
                        pass.of(&mut lambda),
                    );
                    unsafe { cell_multipliers.set(cell, lambda) };
                }
                for (k, &n) in nodes[j].iter().enumerate() {
                    unsafe { xs.set(n as usize, local[k]) };
                }
            };
            if Some(colour) == self.serial_colour {
                (0..nodes.len()).for_each(solve_one);
                continue;
            }
            let first_group = self.colour_groups[colour].start;
            #[allow(unsafe_code)]
            let solve_group = |g: usize| {
                let group = &self.groups[g];
                let (first, end) = (group.start - range.start, group.end - range.start);
                let Some((cubes, highest)) = &self.lanes[g] else {
                    return (first..end).for_each(solve_one);
                };
                let held;
                let masses = if pass == Pass::Again {
                    held = mass_lanes(&nodes[first..end], w);
                    &held
                } else {
                    &self.lane_masses[g]
                };
                let from = Gather {
                    nodes: &nodes[first..end],
                    highest: *highest,
                    x: &xs,
                    masses,
                };
                if pass == Pass::Lone {
                    return unsafe { solve_cubes(&from, cubes, Sweep::Lone) };
                }
                let mut lambda = unsafe { lane_multipliers.get(g) };
                unsafe { solve_cubes(&from, cubes, pass.of(&mut lambda)) };
                unsafe { lane_multipliers.set(g, lambda) };
            };
            // A group takes about a microsecond and a half: hand out GROUPS_PER_TASK of them
            // at a time (a 16³ lattice's colour, 53 groups, is 14 tasks).
            let groups = self.colour_groups[colour].len();
            team::for_each(Tasks(groups.div_ceil(GROUPS_PER_TASK)), |task, ()| {
                let first = first_group + task * GROUPS_PER_TASK;
                (first..(first + GROUPS_PER_TASK).min(first_group + groups)).for_each(solve_group);
            });
        }
    }

    /// Only the collapse barriers of the cells with a node the contacts moved (`moved`), after
    /// the contacts: they move a display-surface point's nodes by their weights and can
    /// flatten the cell the point is in. A colour at a time, its cells side by side on the team.
    pub(crate) fn solve_barriers(&self, x: &mut [V3], w: &[f64], moved: &[bool]) {
        let xs = Disjoint::new(x);
        for (colour, range) in self.colours.iter().enumerate() {
            let per_task = if Some(colour) == self.serial_colour {
                range.len().max(1)
            } else {
                BARRIER_CELLS
            };
            let cells = range.clone();
            team::for_each(Tasks(range.len().div_ceil(per_task)), |task, ()| {
                let start = cells.start + task * per_task;
                for j in start..(start + per_task).min(cells.end) {
                    let cell = &self.nodes[j];
                    if !cell.iter().any(|&n| moved[n as usize]) {
                        continue;
                    }
                    // SAFETY (`get`, `set`): a task's cells share no node with another task's
                    // (one colour's cells share none; the serial colour is one task).
                    #[allow(unsafe_code)]
                    let mut local = cell.map(|n| unsafe { xs.get(n as usize) });
                    let wl = cell.map(|n| w[n as usize]);
                    let unused = [1.0; 3];
                    solve_cell(
                        &mut local,
                        &wl,
                        self.shape[j],
                        (f64::INFINITY, f64::INFINITY),
                        &unused,
                        Sweep::Lone,
                    );
                    for (k, &n) in cell.iter().enumerate() {
                        #[allow(unsafe_code)]
                        unsafe {
                            xs.set(n as usize, local[k])
                        };
                    }
                }
            });
        }
    }

    /// The smallest corner volume ratio `det F` of any cell at positions `x`: 1 at rest,
    /// [`COLLAPSE_J`] where the barrier starts, 0 or less for an inverted corner. Every corner
    /// of a cube cell counts (what [`crate::lattice::cell_is_inverted`] tests), and the one
    /// element of a tet. A minimum, so the same on any thread count; `∞` with no cells.
    pub(crate) fn most_collapsed(&self, x: &[V3]) -> f64 {
        let least = |j: usize| {
            let local = gather(&self.nodes[j], x);
            match self.shape[j] {
                Shape::Cube { inv_h, .. } => {
                    let mut least = f64::INFINITY;
                    for c in 0..8 {
                        let f = corner_columns(&local, c, inv_h);
                        least = least.min(f[0].dot(&f[1].cross(&f[2])));
                    }
                    least
                }
                shape @ Shape::Tet { .. } => {
                    let mut ratio = f64::INFINITY;
                    for_each_element(shape, |e| ratio = volume_ratio(&e.gradient(&local)).0);
                    ratio
                }
            }
        };
        super::super::fold_chunks(
            self.nodes.len(),
            f64::INFINITY,
            |r| r.map(least).fold(f64::INFINITY, f64::min),
            f64::min,
        )
    }

    /// Elastic energy of every cell at positions `x`, J (for the report's energy balance),
    /// summed over fixed chunks of cells on the pool: the same bits on any thread count. Two
    /// a frame; on a GPU's 128³ lattice, serially, they cost the frame 0.75 s of the CPU.
    pub(crate) fn energy(&self, x: &[V3]) -> f64 {
        super::super::deterministic_sum(self.nodes.len(), |j| self.cell_energy(j, x))
    }

    /// Elastic energy of cell `j` at positions `x`, J.
    fn cell_energy(&self, j: usize, x: &[V3]) -> f64 {
        let local = gather(&self.nodes[j], x);
        let (kh, kd) = (inverse(self.hydro_alpha[j]), inverse(self.dev_alpha[j]));
        match self.shape[j] {
            Shape::Cube { inv_h, odd } => {
                // Written out for the cube's corners (F = the corner's scaled edges), as the
                // solve is: through `Element`'s general 3×3 products a 128³ lattice's energy
                // took 0.24 s a frame on two cores.
                let c_h = cube_volume(&local).0 * inv_h * inv_h * inv_h - 1.0;
                let r = self.axis_root[j];
                let mut shear = 0.0;
                for c in corners(odd) {
                    shear += weighted_strain_squared(&corner_columns(&local, c, inv_h), &r);
                }
                0.5 * kh * c_h * c_h + 0.5 * kd * shear
            }
            shape @ Shape::Tet { .. } => {
                let mut total = 0.0;
                for_each_element(shape, |element| {
                    let f = element.gradient(&local);
                    let c_h = f.determinant() - 1.0;
                    total += 0.5 * kh * c_h * c_h;
                    total += 0.5 * kd * green_strain(&f).norm_squared();
                });
                total
            }
        }
    }
}

/// The eight nodes of a cell, read from the positions (written out: a closure over the
/// array stayed an out-of-line call).
#[inline(always)]
fn gather(nodes: &[u32; 8], x: &[V3]) -> [V3; 8] {
    let p = |k: usize| x[nodes[k] as usize];
    [p(0), p(1), p(2), p(3), p(4), p(5), p(6), p(7)]
}

/// `Σ_ik r_i r_k E_ik²` for the Green strain `E = (FᵀF − I)/2` of the corner whose `F` has
/// columns `f` (the anisotropic shear's squared measure; `r` = 1 is `‖E‖²`).
#[inline(always)]
fn weighted_strain_squared(f: &[V3; 3], r: &[f64; 3]) -> f64 {
    let mut sum = 0.0;
    for i in 0..3 {
        for k in 0..3 {
            let identity = if i == k { 1.0 } else { 0.0 };
            let e = 0.5 * (f[i].dot(&f[k]) - identity);
            sum += e * e * r[i] * r[k];
        }
    }
    sum
}

fn compliance(stiffness: f64) -> f64 {
    if stiffness > 0.0 {
        1.0 / stiffness
    } else {
        f64::INFINITY
    }
}

fn inverse(alpha: f64) -> f64 {
    if alpha.is_finite() {
        1.0 / alpha
    } else {
        0.0
    }
}

/// One element of a cell: its four local node slots and the map from its edge vectors to `F`.
#[derive(Clone, Copy)]
struct Element {
    /// Local slots: the apex and its three edge ends.
    slots: [usize; 4],
    /// `∂F/∂(edge k)` as a matrix: `F = E · m` with `E = [x_k − x_apex]`.
    m: Matrix3<f64>,
}

impl Element {
    fn gradient(&self, x: &[V3; 8]) -> Matrix3<f64> {
        let [a, b, c, d] = self.slots;
        Matrix3::from_columns(&[x[b] - x[a], x[c] - x[a], x[d] - x[a]]) * self.m
    }

    /// Move the element's nodes to reduce constraint `value` with gradient `∂C/∂F` = `p`
    /// (XPBD with the multiplier reset every substep: one Newton step of the constraint).
    fn project(
        &self,
        x: &mut [V3; 8],
        w: &[f64; 8],
        (value, p): (f64, &Matrix3<f64>),
        alpha: f64,
        slot: Slot,
    ) {
        let h = p * self.m.transpose();
        let g = [
            -(h.column(0) + h.column(1) + h.column(2)),
            h.column(0).into_owned(),
            h.column(1).into_owned(),
            h.column(2).into_owned(),
        ];
        let mut denominator = alpha;
        for (&s, g) in self.slots.iter().zip(&g) {
            denominator += w[s] * g.norm_squared();
        }
        if !(denominator > 0.0 && denominator.is_finite()) {
            return;
        }
        let dl = -residual(value, alpha, &slot) / denominator;
        keep(slot, dl);
        for (&s, g) in self.slots.iter().zip(&g) {
            x[s] += g * (w[s] * dl);
        }
    }
}

/// The corners a cube cell is integrated at (module docs).
fn corners(odd: bool) -> [usize; 4] {
    if odd {
        [1, 2, 4, 7]
    } else {
        [0, 3, 5, 6]
    }
}

/// Call `f` with each element of a cell of `shape`.
fn for_each_element(shape: Shape, mut f: impl FnMut(Element)) {
    match shape {
        Shape::Cube { inv_h, odd } => {
            for c in corners(odd) {
                let sign = |bit: usize| if c & bit == 0 { inv_h } else { -inv_h };
                f(Element {
                    slots: [c, c ^ 1, c ^ 2, c ^ 4],
                    m: Matrix3::from_diagonal(&V3::new(sign(1), sign(2), sign(4))),
                });
            }
        }
        Shape::Tet { dm_inv } => f(Element {
            slots: [0, 1, 3, 7],
            m: dm_inv,
        }),
    }
}

/// Both constraints of every element of one cell and its collapse barriers, on its local
/// node copy `x`; `alphas` are the volumetric and shear compliances over Δt² (infinite: that
/// constraint is skipped). The barriers are hard (compliance 0: no stiffness of the
/// material lets a corner pass through itself).
pub(super) fn solve_cell(
    x: &mut [V3; 8],
    w: &[f64; 8],
    shape: Shape,
    alphas: (f64, f64),
    axis_root: &[f64; 3],
    sweep: Sweep<[f64; 5]>,
) {
    let (hydro, dev) = alphas;
    let [mut volume_slot, mut shear_slots @ ..] = match sweep.slots() {
        Some((lambda, again)) => lambda.each_mut().map(|slot| Some((slot, again))),
        None => [None, None, None, None, None],
    };
    match shape {
        Shape::Cube { inv_h, odd } => {
            if hydro.is_finite() {
                let slot = volume_slot.take();
                solve_cube_volume(x, w, inv_h * inv_h * inv_h, hydro, slot);
            }
            if dev.is_finite() {
                for (c, slot) in corners(odd).into_iter().zip(&mut shear_slots) {
                    solve_corner(x, w, (c, inv_h), dev, axis_root, slot.take());
                }
            }
            for c in 0..8 {
                solve_barrier(x, w, c, inv_h);
            }
        }
        Shape::Tet { .. } => {
            for_each_element(shape, |element| {
                let f = element.gradient(x);
                let (value, cofactor) = volume_ratio(&f);
                if hydro.is_finite() {
                    let slot = volume_slot.take();
                    element.project(x, w, (value - 1.0, &cofactor), hydro, slot);
                }
                if value < COLLAPSE_J {
                    let f = element.gradient(x);
                    let (value, cofactor) = volume_ratio(&f);
                    if value < COLLAPSE_J {
                        element.project(x, w, (value - COLLAPSE_J, &cofactor), 0.0, None);
                    }
                }
                let f = element.gradient(x);
                let e = green_strain(&f);
                let value = e.norm();
                if value > 1e-14 {
                    let slot = shear_slots[0].take();
                    element.project(x, w, (value, &(f * e / value)), dev, slot);
                }
            });
            // The apex's duplicate slots follow it (they are written back too).
            for k in [2, 4, 5, 6] {
                x[k] = x[0];
            }
        }
    }
}

/// The constraints of corner `c` of a cube cell: the same arithmetic as the general
/// element with `F`'s columns the corner's scaled edges (no matrix products: this is the
/// solver's inner loop).
#[inline(always)]
fn solve_corner(
    x: &mut [V3; 8],
    w: &[f64; 8],
    (c, inv_h): (usize, f64),
    dev: f64,
    axis_root: &[f64; 3],
    slot: Slot,
) {
    let nb = [c ^ 1, c ^ 2, c ^ 4];
    let s = corner_signs(c, inv_h);
    let columns = |x: &[V3; 8]| {
        [
            (x[nb[0]] - x[c]) * s[0],
            (x[nb[1]] - x[c]) * s[1],
            (x[nb[2]] - x[c]) * s[2],
        ]
    };
    // Move the corner's four nodes against constraint `value` whose gradient with respect to
    // column k of F is p[k].
    let project = |x: &mut [V3; 8], value: f64, p: [V3; 3], alpha: f64, slot: Slot| {
        let g = [p[0] * s[0], p[1] * s[1], p[2] * s[2]];
        let g_apex = -(g[0] + g[1] + g[2]);
        let denominator = alpha
            + w[c] * g_apex.norm_squared()
            + w[nb[0]] * g[0].norm_squared()
            + w[nb[1]] * g[1].norm_squared()
            + w[nb[2]] * g[2].norm_squared();
        if !(denominator > 0.0 && denominator.is_finite()) {
            return;
        }
        let dl = -residual(value, alpha, &slot) / denominator;
        keep(slot, dl);
        x[c] += g_apex * (w[c] * dl);
        for k in 0..3 {
            x[nb[k]] += g[k] * (w[nb[k]] * dl);
        }
    };
    let f = columns(x);
    // Green strain E (symmetric) and ∂‖E‖/∂F = F E / ‖E‖, column by column.
    let e = Matrix3::new(
        0.5 * (f[0].dot(&f[0]) - 1.0),
        0.5 * f[0].dot(&f[1]),
        0.5 * f[0].dot(&f[2]),
        0.5 * f[1].dot(&f[0]),
        0.5 * (f[1].dot(&f[1]) - 1.0),
        0.5 * f[1].dot(&f[2]),
        0.5 * f[2].dot(&f[0]),
        0.5 * f[2].dot(&f[1]),
        0.5 * (f[2].dot(&f[2]) - 1.0),
    );
    // Anisotropy: C = sqrt(Σ W_ij E_ij²), W_ij = r_i r_j, ∂C/∂F = F (W∘E) / C.
    let r = axis_root;
    let weighted = Matrix3::from_fn(|i, j| e[(i, j)] * r[i] * r[j]);
    let value = e.dot(&weighted).sqrt();
    if value > 1e-14 {
        let inv = 1.0 / value;
        let we = weighted;
        let p = [
            (f[0] * we[(0, 0)] + f[1] * we[(1, 0)] + f[2] * we[(2, 0)]) * inv,
            (f[0] * we[(0, 1)] + f[1] * we[(1, 1)] + f[2] * we[(2, 1)]) * inv,
            (f[0] * we[(0, 2)] + f[1] * we[(1, 2)] + f[2] * we[(2, 2)]) * inv,
        ];
        project(x, value, p, dev, slot);
    }
}

/// The collapse barrier `det F_c ≥ COLLAPSE_J` of corner `c` of a cube cell (at all eight
/// corners: the shear energy sits at four, but a fold can flatten any corner's tet).
#[inline(always)]
fn solve_barrier(x: &mut [V3; 8], w: &[f64; 8], c: usize, inv_h: f64) {
    let nb = [c ^ 1, c ^ 2, c ^ 4];
    let s = corner_signs(c, inv_h);
    let f = corner_columns(x, c, inv_h);
    let first = f[1].cross(&f[2]);
    let j = f[0].dot(&first);
    if j >= COLLAPSE_J {
        return;
    }
    let cof = [first, f[2].cross(&f[0]), f[0].cross(&f[1])];
    let g = [cof[0] * s[0], cof[1] * s[1], cof[2] * s[2]];
    let g_apex = -(g[0] + g[1] + g[2]);
    let denominator = w[c] * g_apex.norm_squared()
        + w[nb[0]] * g[0].norm_squared()
        + w[nb[1]] * g[1].norm_squared()
        + w[nb[2]] * g[2].norm_squared();
    if !(denominator > 0.0 && denominator.is_finite()) {
        return;
    }
    let dl = -(j - COLLAPSE_J) / denominator;
    x[c] += g_apex * (w[c] * dl);
    for k in 0..3 {
        x[nb[k]] += g[k] * (w[nb[k]] * dl);
    }
}

/// The columns of corner `c`'s `F`: its three edges (to `c^1`, `c^2`, `c^4`) times `s_k / h`,
/// so a cell at rest gives the identity and `det F` is the corner's volume ratio.
#[inline(always)]
fn corner_columns(x: &[V3; 8], c: usize, inv_h: f64) -> [V3; 3] {
    let s = corner_signs(c, inv_h);
    let apex = x[c];
    [
        (x[c ^ 1] - apex) * s[0],
        (x[c ^ 2] - apex) * s[1],
        (x[c ^ 4] - apex) * s[2],
    ]
}

/// `s_k / h` of corner `c`'s three edges (`+1/h` where the edge runs along +axis).
#[inline(always)]
fn corner_signs(c: usize, inv_h: f64) -> [f64; 3] {
    let sign = |bit: usize| if c & bit == 0 { inv_h } else { -inv_h };
    [sign(1), sign(2), sign(4)]
}

/// The volume of a cube cell (its six Kuhn tets, [`crate::solver::volume::TETS`]) and its
/// gradient by node, in closed form. The tets share the diagonal `d = x₇ − x₀`, and with
/// `u_k = x_k − x₀` their six volumes sum to `6V = d · S`, where
/// `S = u₁×u₃ + u₃×u₂ + u₂×u₆ + u₆×u₄ + u₄×u₅ + u₅×u₁` is twice the vector area of the loop
/// of the other six nodes, `= u₁×(u₃−u₅) + u₂×(u₆−u₃) + u₄×(u₅−u₆)`. Its gradient is `S` at
/// node 7, `−S` at node 0 (the others' sum to zero), `(u₃−u₅)×d` at node 1, `(u₆−u₃)×d` at 2,
/// `(u₅−u₆)×d` at 4, `d×(u₁−u₂)` at 3, `d×(u₄−u₁)` at 5 and `d×(u₂−u₄)` at 6: 9 cross
/// products where the tets one by one took 18 (the standard scene 11 % faster).
#[inline(always)]
pub(super) fn cube_volume(x: &[V3; 8]) -> (f64, [V3; 8]) {
    let u = |k: usize| x[k] - x[0];
    let d = x[7] - x[0];
    let (u1, u2, u3, u4, u5, u6) = (u(1), u(2), u(3), u(4), u(5), u(6));
    let (a1, a2, a3) = (u3 - u5, u6 - u3, u5 - u6);
    let (b1, b2, b3) = (u1 - u2, u4 - u1, u2 - u4);
    let loop_area = u1.cross(&a1) + u2.cross(&a2) + u4.cross(&a3);
    let grad = [
        -loop_area,
        a1.cross(&d),
        a2.cross(&d),
        d.cross(&b1),
        a3.cross(&d),
        d.cross(&b2),
        d.cross(&b3),
        loop_area,
    ];
    let sixth = 1.0 / 6.0;
    (d.dot(&loop_area) * sixth, grad.map(|g| g * sixth))
}

/// The cell's volumetric constraint `V/V_0 − 1` (`inv_volume` = 1/V_0, `alpha` its compliance
/// over Δt²), over all eight nodes.
#[inline(always)]
fn solve_cube_volume(x: &mut [V3; 8], w: &[f64; 8], inv_volume: f64, alpha: f64, slot: Slot) {
    let (volume, grad) = cube_volume(x);
    let value = volume * inv_volume - 1.0;
    let mut denominator = alpha;
    for k in 0..8 {
        denominator += w[k] * grad[k].norm_squared() * inv_volume * inv_volume;
    }
    if !(denominator > 0.0 && denominator.is_finite()) {
        return;
    }
    let dl = -residual(value, alpha, &slot) / denominator;
    keep(slot, dl);
    let dl = dl * inv_volume;
    for k in 0..8 {
        x[k] += grad[k] * (w[k] * dl);
    }
}

/// A constraint's carried multiplier and whether this is a sweep after the first
/// ([`Sweep::slots`]; `None`: a lone sweep).
type Slot<'a> = Option<(&'a mut f64, bool)>;

/// `C + α̃ λ` for a sweep after the first; `C` otherwise.
#[inline(always)]
fn residual(value: f64, alpha: f64, slot: &Slot) -> f64 {
    match slot {
        Some((lambda, true)) => value + alpha * **lambda,
        _ => value,
    }
}

/// Keep a constraint's step `dl` in its slot: written by the first sweep, added to by a
/// later one.
#[inline(always)]
fn keep(slot: Slot, dl: f64) {
    match slot {
        Some((lambda, true)) => *lambda += dl,
        Some((lambda, false)) => *lambda = dl,
        None => {}
    }
}

/// `det F` and its gradient `∂ det F / ∂F` (the cofactor matrix).
fn volume_ratio(f: &Matrix3<f64>) -> (f64, Matrix3<f64>) {
    let (f0, f1, f2) = (f.column(0), f.column(1), f.column(2));
    let cofactor = Matrix3::from_columns(&[f1.cross(&f2), f2.cross(&f0), f0.cross(&f1)]);
    (f0.dot(&f1.cross(&f2)), cofactor)
}

/// Green's strain `½ (FᵀF − I)`.
fn green_strain(f: &Matrix3<f64>) -> Matrix3<f64> {
    (f.transpose() * f - Matrix3::identity()) * 0.5
}

#[cfg(test)]
pub(super) mod tests;
