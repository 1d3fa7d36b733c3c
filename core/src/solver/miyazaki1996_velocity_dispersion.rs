//! The fusion model's velocity dispersion (Miyazaki et al. 1996 §3, physics §7).
//!
//! A spring of length l, natural length L, stiffness k and end mass m keeps its ends in order
//! while `½ m |v2−v1|² + ½ k (l−L)² < ½ k L²` (eq 4), i.e. while the relative speed stays below
//! `θ = sqrt((k/m) · l · (2L − l))` (eq 5, with the square root where it belongs; θ = 0 for
//! l ≥ 2L). A spring over the bound gives the excess `|v2−v1| − θ` to both ends along
//! `v2 − v1` in opposite senses (eq 6): momentum kept, relative speed exactly θ. For unequal end
//! masses m is the harmonic mean `2 m1 m2 / (m1 + m2)` and the excess is shared in inverse
//! proportion to the masses (½ and ½ for equal masses, as printed).
//!
//! The procedure (§3.4) runs after the velocity update and before the position update and
//! repeats until no spring violates the bound, at most `max_iterations` sweeps (hitting the cap
//! is reported). Sweeps go colour by colour over a spring colouring in which no two springs of a
//! colour share a node, so each colour is processed in parallel and the result does not depend
//! on the thread count.
//!
//! Beyond the regime where the printed model works (physics §7b) one explicit step can carry a
//! spring past zero length even under the energy bound, and in 3-D a cell flattens and flips
//! long before any spring reaches zero length. [`DispersionMode::Bounded`] (the production
//! solver) makes two changes: the energy bound is taken against reaching
//! `l_min = MIN_LENGTH_FRACTION · L` instead of 0, `θ = sqrt((k/m)((L − l_min)² − (l − L)²))`
//! (eq 4 with `½k(L − l_min)²` on the right; `l_min = 0` gives eq 5), so a spring at 0.6 of its
//! length (or 1.4 L) moves rigidly ("fusion"); and the per-step bound `θ' = min(θ, ½ l / ΔT)`,
//! so no spring closes by more than half its length in one step. A spring driven beyond that
//! reach (θ = 0) keeps only motion back towards L, at a speed proportional to its excess strain
//! (`fused_release`), so it returns instead of staying fused forever.

use super::forces::Adjacency;
use super::{NodeState, SpringSet, PAR_CHUNK};
use nalgebra::Vector3;
use rayon::prelude::*;

/// In [`DispersionMode::Bounded`], the shortest a spring may be driven by inertia, as a
/// fraction of its natural length (the printed model allows 0).
pub const MIN_LENGTH_FRACTION: f64 = 0.6;

/// How fast a spring strained beyond the bounded model's reach may return, in units of its
/// `ω · excess strain` (see `fused_release`).
pub const RELEASE_RATE: f64 = 0.3;

/// Which velocity-dispersion rule the solver applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DispersionMode {
    /// Springs only (shows the inversion failure of Fig. 3).
    Off,
    /// Eq 5–6 exactly as published.
    AsPrinted,
    /// Eq 5–6 plus the per-step bound θ' = min(θ, ½ l/ΔT) (production default).
    #[default]
    Bounded,
}

/// Springs grouped so that no two springs of one colour share a node.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpringColouring {
    /// Spring indices, colour after colour.
    pub order: Vec<u32>,
    /// `order[offsets[c]..offsets[c+1]]` are the springs of colour c.
    pub offsets: Vec<u32>,
    /// Colour of each spring (for the active set of the later sweeps); empty when there are
    /// more than `u16::MAX` colours.
    pub colour: Vec<u16>,
}

impl SpringColouring {
    /// Greedy edge colouring in spring order (deterministic).
    pub fn new(nodes: usize, springs: &SpringSet) -> SpringColouring {
        // used[node] = bitmask of colours touching it, spilling into a Vec for high degrees.
        let mut used: Vec<Vec<u64>> = vec![vec![0]; nodes];
        let mut colour_of = vec![0u32; springs.len()];
        let mut colours = 0u32;
        for (s, colour) in colour_of.iter_mut().enumerate() {
            let (a, b) = (springs.a[s] as usize, springs.b[s] as usize);
            let mut c = 0u32;
            loop {
                let word = (c / 64) as usize;
                let bit = 1u64 << (c % 64);
                let ua = used[a].get(word).copied().unwrap_or(0);
                let ub = used[b].get(word).copied().unwrap_or(0);
                if (ua | ub) & bit == 0 {
                    break;
                }
                c += 1;
            }
            let word = (c / 64) as usize;
            for n in [a, b] {
                if used[n].len() <= word {
                    used[n].resize(word + 1, 0);
                }
                used[n][word] |= 1u64 << (c % 64);
            }
            *colour = c;
            colours = colours.max(c + 1);
        }
        let mut offsets = vec![0u32; colours as usize + 1];
        for &c in &colour_of {
            offsets[c as usize + 1] += 1;
        }
        for c in 0..colours as usize {
            offsets[c + 1] += offsets[c];
        }
        let mut fill = offsets.clone();
        let mut order = vec![0u32; springs.len()];
        for (s, &c) in colour_of.iter().enumerate() {
            order[fill[c as usize] as usize] = s as u32;
            fill[c as usize] += 1;
        }
        // A node of degree d needs at most 2d − 1 colours: far below u16::MAX for any lattice
        // or cage. A model that needed more gets no per-spring colours, and the dispersion
        // falls back to its stamp sweeps.
        let colour = if colours <= u16::MAX as u32 {
            colour_of.iter().map(|&c| c as u16).collect()
        } else {
            Vec::new()
        };
        SpringColouring {
            order,
            offsets,
            colour,
        }
    }

    pub fn colour_count(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
}

/// What one dispersion pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DispersionStats {
    /// Spring corrections applied.
    pub corrections: u64,
    /// Sweeps over all springs (0 when nothing violated the bound).
    pub iterations: u32,
    /// The sweep cap was reached with springs still over the bound.
    pub hit_cap: bool,
}

/// The relative-speed bound of spring `s` (eq 5, and the per-step bound in `Bounded` mode).
#[inline]
pub fn speed_bound(
    mode: DispersionMode,
    k: f64,
    mass_a: f64,
    mass_b: f64,
    length: f64,
    rest_length: f64,
    dt: f64,
) -> f64 {
    let m = 2.0 * mass_a * mass_b / (mass_a + mass_b);
    match mode {
        DispersionMode::Bounded => {
            // Energy bound against reaching MIN_LENGTH_FRACTION·L instead of 0, then the
            // per-step bound.
            let reach = (1.0 - MIN_LENGTH_FRACTION) * rest_length;
            let strain = length - rest_length;
            let room = reach * reach - strain * strain;
            let theta = if room > 0.0 {
                ((k / m) * room).sqrt()
            } else {
                0.0
            };
            theta.min(0.5 * length / dt)
        }
        _ => {
            if length >= 2.0 * rest_length {
                0.0
            } else {
                ((k / m) * length * (2.0 * rest_length - length)).sqrt()
            }
        }
    }
}

/// For a spring strained beyond the bounded model's reach (`|l − L| ≥ (1 − MIN_LENGTH_FRACTION) L`,
/// where θ = 0), the relative velocity it may keep, or `None` when the spring is within reach.
///
/// Eq 4 leaves such a spring no kinetic energy at all: zeroing its relative velocity every
/// step also cancels what its own spring force adds, so the spring can never return and the
/// sweeps hit their cap every step ("stuck fusion"). Here the spring keeps only motion along
/// itself back towards L, at most `RELEASE_RATE · ω · (|l − L| − (L − l_min))` (ω = sqrt(k/m))
/// and the per-step bound: the excess strain decays at most like `exp(−RELEASE_RATE · ω t)`
/// (about half a spring period), any motion that would strain it further or shear it is still
/// removed, and once back within reach the energy bound takes over again. A release speed that
/// does not shrink with the excess (tried: `¼ ω (L − l_min)`) let a rod pressed into jelly fold
/// 6 of 216 cells instead of ≤ 4; with it the standard scene (physics §7, issue 9) took 65 s
/// instead of 207 s, this rule 39 s, both with no inverted cell where the stuck rule left one.
#[allow(clippy::too_many_arguments)]
#[inline]
fn fused_release(
    k: f64,
    mass_a: f64,
    mass_b: f64,
    a_to_b: Vector3<f64>,
    length: f64,
    rest_length: f64,
    rel: Vector3<f64>,
    dt: f64,
) -> Option<Vector3<f64>> {
    let reach = (1.0 - MIN_LENGTH_FRACTION) * rest_length;
    let strain = length - rest_length;
    if strain.abs() < reach || length <= 0.0 {
        return None;
    }
    let m = 2.0 * mass_a * mass_b / (mass_a + mass_b);
    let axis = a_to_b / length;
    // Positive along `back` shortens a stretched spring and lengthens a compressed one.
    let back = if strain > 0.0 { -axis } else { axis };
    let excess = strain.abs() - reach;
    let limit = (RELEASE_RATE * (k / m).sqrt() * excess).min(0.5 * length / dt);
    // Not `clamp`: it panics on a NaN limit, and a NaN must reach the solver's finite check.
    let keep = rel.dot(&back).max(0.0).min(limit);
    Some(back * keep)
}

/// The velocity change for node `a` of spring `s` (node `b` gets `-(m_a/m_b)` times it), or
/// `None` when the spring is within its bound.
#[inline]
fn correction(
    mode: DispersionMode,
    nodes: &NodeState,
    springs: &SpringSet,
    s: usize,
    dt: f64,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let (a, b) = (springs.a[s] as usize, springs.b[s] as usize);
    let (ma, mb) = (nodes.mass[a], nodes.mass[b]);
    if nodes.inv_mass[a] == 0.0 && nodes.inv_mass[b] == 0.0 {
        return None;
    }
    let rel = nodes.velocity[b] - nodes.velocity[a];
    let speed_sq = rel.norm_squared();
    // Cheap early-out: most springs are far below the bound.
    let length = (nodes.position[a] - nodes.position[b]).norm();
    if mode == DispersionMode::Bounded {
        if let Some(target) = fused_release(
            springs.stiffness[s],
            ma,
            mb,
            nodes.position[b] - nodes.position[a],
            length,
            springs.rest_length[s],
            rel,
            dt,
        ) {
            let delta = target - rel;
            if delta.norm_squared() <= 1e-18 * speed_sq {
                return None;
            }
            // rel changes by delta, shared in inverse proportion to mass.
            let (wa, wb) = (nodes.inv_mass[a], nodes.inv_mass[b]);
            let sum = wa + wb;
            return Some((-delta * (wa / sum), delta * (wb / sum)));
        }
    }
    let bound = speed_bound(
        mode,
        springs.stiffness[s],
        ma,
        mb,
        length,
        springs.rest_length[s],
        dt,
    );
    // A relative tolerance keeps a spring just corrected to θ from being corrected again.
    if speed_sq <= bound * bound * (1.0 + 1e-9) {
        return None;
    }
    let speed = speed_sq.sqrt();
    let dir = rel / speed;
    let excess = speed - bound;
    // Share in inverse proportion to mass; a pinned end takes nothing.
    let (wa, wb) = (nodes.inv_mass[a], nodes.inv_mass[b]);
    let share = excess / (wa + wb);
    Some((dir * (share * wa), -dir * (share * wb)))
}

/// The square of a lower bound on spring `s`'s speed bound, valid whenever its squared length
/// `len_sq` lies between `(0.9 L)²` and `(1.1 L)²`; `None` outside that window or with a
/// pinned end. In the window the bound is at least `sqrt(k/m · 0.15 L²)` and `0.45 L / ΔT`
/// (Bounded) or `sqrt(k/m · 0.99 L²)` (as printed), with `k/m = k (1/m_a + 1/m_b) / 2` for the
/// harmonic mean mass. No square roots.
#[inline]
pub(crate) fn speed_floor_sq(
    mode: DispersionMode,
    springs: &SpringSet,
    inv_mass: &[f64],
    s: usize,
    len_sq: f64,
    inv_dt_sq: f64,
) -> Option<f64> {
    let (wa, wb) = (
        inv_mass[springs.a[s] as usize],
        inv_mass[springs.b[s] as usize],
    );
    let rest = springs.rest_length[s];
    let rest_sq = rest * rest;
    if wa == 0.0 || wb == 0.0 || !(len_sq >= 0.81 * rest_sq && len_sq <= 1.21 * rest_sq) {
        return None;
    }
    let k_over_m = 0.5 * springs.stiffness[s] * (wa + wb);
    Some(match mode {
        DispersionMode::Bounded => (k_over_m * 0.15 * rest_sq).min(0.2025 * rest_sq * inv_dt_sq),
        _ => k_over_m * 0.99 * rest_sq,
    })
}

/// A cheap, conservative test that spring `s` is within its bound: `true` only when the
/// exact test in [`correction`] would find no violation (see [`speed_floor_sq`]). Springs it
/// cannot clear go to the exact test.
#[inline]
fn surely_within_bound(
    mode: DispersionMode,
    nodes: &NodeState,
    springs: &SpringSet,
    s: usize,
    dt: f64,
) -> bool {
    let (a, b) = (springs.a[s] as usize, springs.b[s] as usize);
    let len_sq = (nodes.position[a] - nodes.position[b]).norm_squared();
    match speed_floor_sq(mode, springs, &nodes.inv_mass, s, len_sq, 1.0 / (dt * dt)) {
        Some(floor_sq) => (nodes.velocity[b] - nodes.velocity[a]).norm_squared() <= floor_sq,
        None => false,
    }
}

/// What the solver's passes already know this step, so dispersion can skip most springs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SpringHints<'a> {
    /// Per spring, 1 where [`speed_floor_sq`] gave no floor (outside the length window or a
    /// pinned end): only these can be over their bound when `uniform` holds.
    pub exceptional: &'a [u8],
    /// Every node's velocity lies within R of one common vector and `4 R²` is at most every
    /// other spring's floor: then `|v_b − v_a| ≤ 2R` keeps all of them within their bound.
    pub uniform: bool,
    /// Whether some spring is flagged in `exceptional` (read only when `uniform` holds:
    /// uniform motion and no flag leave no spring to test).
    pub flagged: bool,
}

/// Whether spring `s` can be skipped without the exact test.
#[inline]
fn skippable(
    mode: DispersionMode,
    nodes: &NodeState,
    springs: &SpringSet,
    s: usize,
    dt: f64,
    hints: Option<SpringHints>,
) -> bool {
    match hints {
        Some(h) if h.uniform => h.exceptional[s] == 0,
        _ => surely_within_bound(mode, nodes, springs, s, dt),
    }
}

/// Whether any spring is over its bound: one parallel pass in fixed chunks (the answer does
/// not depend on the thread count), the cheap test first.
fn any_violation(
    mode: DispersionMode,
    nodes: &NodeState,
    springs: &SpringSet,
    dt: f64,
    hints: Option<SpringHints>,
) -> bool {
    if hints.is_some_and(|h| h.uniform && !h.flagged) {
        return false;
    }
    let n = springs.len();
    (0..n.div_ceil(PAR_CHUNK)).into_par_iter().any(|c| {
        (c * PAR_CHUNK..((c + 1) * PAR_CHUNK).min(n)).any(|s| {
            !skippable(mode, nodes, springs, s, dt, hints)
                && correction(mode, nodes, springs, s, dt).is_some()
        })
    })
}

/// Buffers the dispersion reuses from step to step (nothing is allocated once they have grown).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct DispersionScratch {
    /// One colour's corrections between the parallel evaluation and the serial application
    /// (`u32::MAX` in the spring slot: no correction).
    pub corrections: Vec<(u32, Vector3<f64>, Vector3<f64>)>,
    /// Per node, the colour pass that last changed its velocity.
    pub changed: Vec<u64>,
    /// The last pass number handed out.
    pub pass: u64,
    /// This call's velocity changes in order: (colour pass, node), for the active set.
    pub log: Vec<(u64, u32)>,
    /// One colour's candidate springs in a later sweep.
    pub candidates: Vec<u32>,
}

/// Apply the dispersion procedure to `nodes.velocity` (positions are the current ones).
/// `scratch` is reused between calls; see [`disperse_with`] for what the solver does.
pub fn disperse(
    mode: DispersionMode,
    nodes: &mut NodeState,
    springs: &SpringSet,
    colouring: &SpringColouring,
    dt: f64,
    max_iterations: u32,
    scratch: &mut Vec<(u32, Vector3<f64>, Vector3<f64>)>,
) -> DispersionStats {
    let mut buffers = DispersionScratch {
        corrections: std::mem::take(scratch),
        ..DispersionScratch::default()
    };
    let stats = disperse_with(
        mode,
        nodes,
        springs,
        colouring,
        dt,
        max_iterations,
        &mut buffers,
        None,
        None,
    );
    *scratch = buffers.corrections;
    stats
}

/// The dispersion procedure with reusable buffers.
///
/// One parallel check pass first: when no spring is over its bound (the common case) the
/// sweeps are skipped, which gives exactly what a sweep finding nothing would. The first sweep
/// evaluates every spring; later sweeps evaluate a spring only when one of its ends changed
/// velocity since the spring was last evaluated (positions do not move during the procedure,
/// so an unchanged spring would be found within its bound again): the same corrections in the
/// same order as full sweeps. Without `adjacency` a later sweep finds those springs by reading
/// two stamps per spring; with it (the solver's node → spring lists) only the springs of the
/// nodes changed since are visited, the "active set": an impact whose sweeps correct a
/// handful of springs each no longer pays a pass over every spring per sweep. `hints` (from
/// the solver's spring and node passes) let the check and the first sweep skip springs that
/// cannot be over their bound.
#[allow(clippy::too_many_arguments)]
pub(crate) fn disperse_with(
    mode: DispersionMode,
    nodes: &mut NodeState,
    springs: &SpringSet,
    colouring: &SpringColouring,
    dt: f64,
    max_iterations: u32,
    scratch: &mut DispersionScratch,
    hints: Option<SpringHints>,
    adjacency: Option<&Adjacency>,
) -> DispersionStats {
    let mut stats = DispersionStats::default();
    if mode == DispersionMode::Off || !any_violation(mode, nodes, springs, dt, hints) {
        return stats;
    }
    if scratch.changed.len() != nodes.len() {
        scratch.changed.clear();
        scratch.changed.resize(nodes.len(), 0);
    }
    scratch.log.clear();
    let colours = colouring.colour_count() as u64;
    // The active set needs every spring's colour (without them: the stamp sweeps).
    let adjacency = adjacency.filter(|_| colouring.colour.len() == springs.len());
    // Pass numbers of this call: base + 1 + sweep·colours + colour, all above every stamp.
    let base = scratch.pass;
    // Start of the log entries at or after the pass being looked back to (monotone).
    let mut window = 0usize;
    loop {
        let sweep = stats.iterations as u64;
        let mut violated = 0u64;
        for c in 0..colouring.colour_count() {
            let group =
                &colouring.order[colouring.offsets[c] as usize..colouring.offsets[c + 1] as usize];
            let pass = base + 1 + sweep * colours + c as u64;
            // The pass that last evaluated this colour (none before the first sweep).
            let last_eval = (sweep > 0).then(|| pass - colours);
            let evaluate: &[u32] = match (last_eval, adjacency) {
                (Some(last), Some(adj)) => {
                    // Active set: the springs of this colour at nodes changed since `last`.
                    while window < scratch.log.len() && scratch.log[window].0 < last {
                        window += 1;
                    }
                    scratch.candidates.clear();
                    for &(_, n) in &scratch.log[window..] {
                        let n = n as usize;
                        let links =
                            &adj.links[adj.offsets[n] as usize..adj.offsets[n + 1] as usize];
                        for &link in links {
                            let s = link >> 1;
                            if colouring.colour[s as usize] as usize == c {
                                scratch.candidates.push(s);
                            }
                        }
                    }
                    scratch.candidates.sort_unstable();
                    scratch.candidates.dedup();
                    &scratch.candidates
                }
                _ => group,
            };
            let corrections = &mut scratch.corrections;
            if corrections.len() < evaluate.len() {
                corrections.resize(evaluate.len(), (NONE, Vector3::zeros(), Vector3::zeros()));
            }
            let state: &NodeState = nodes;
            let changed = &scratch.changed[..];
            let slot_of = |(slot, &s): (&mut (u32, Vector3<f64>, Vector3<f64>), &u32)| {
                let su = s as usize;
                let stale = match last_eval {
                    // First sweep: what the hints cannot clear, and every spring an earlier
                    // colour of this sweep changed (the hints predate that).
                    None => {
                        changed[springs.a[su] as usize].max(changed[springs.b[su] as usize]) > base
                            || !skippable(mode, state, springs, su, dt, hints)
                    }
                    Some(last) => {
                        changed[springs.a[su] as usize].max(changed[springs.b[su] as usize]) >= last
                    }
                };
                slot.0 = NONE;
                if stale {
                    if let Some((da, db)) = correction(mode, state, springs, su, dt) {
                        *slot = (s, da, db);
                    }
                }
            };
            if evaluate.len() > 2 * PAR_CHUNK {
                corrections[..evaluate.len()]
                    .par_iter_mut()
                    .zip(evaluate.par_iter())
                    .with_min_len(PAR_CHUNK)
                    .for_each(slot_of);
            } else {
                corrections[..evaluate.len()]
                    .iter_mut()
                    .zip(evaluate.iter())
                    .for_each(slot_of);
            }
            // No two springs of one colour share a node: applying in any order is the same.
            for &(s, da, db) in corrections[..evaluate.len()].iter() {
                if s != NONE {
                    let (a, b) = (springs.a[s as usize], springs.b[s as usize]);
                    nodes.velocity[a as usize] += da;
                    nodes.velocity[b as usize] += db;
                    scratch.changed[a as usize] = pass;
                    scratch.changed[b as usize] = pass;
                    if adjacency.is_some() {
                        scratch.log.push((pass, a));
                        scratch.log.push((pass, b));
                    }
                    violated += 1;
                }
            }
            scratch.pass = pass;
        }
        if violated == 0 {
            break;
        }
        stats.corrections += violated;
        stats.iterations += 1;
        if stats.iterations >= max_iterations {
            // One more check tells whether springs are still over the bound.
            // (Velocities changed since the hints were taken: no hints.)
            stats.hit_cap = any_violation(mode, nodes, springs, dt, None);
            break;
        }
    }
    stats
}

/// No correction in a slot of [`DispersionScratch::corrections`].
const NONE: u32 = u32::MAX;

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(v1: f64, v2: f64, m1: f64, m2: f64) -> (NodeState, SpringSet) {
        let nodes = NodeState {
            position: vec![Vector3::zeros(), Vector3::new(0.1, 0.0, 0.0)],
            velocity: vec![Vector3::new(v1, 0.0, 0.0), Vector3::new(v2, 0.0, 0.0)],
            mass: vec![m1, m2],
            inv_mass: vec![1.0 / m1, 1.0 / m2],
        };
        let mut springs = SpringSet::default();
        springs.push(0, 1, 0.1, 2000.0, 0.0);
        (nodes, springs)
    }

    #[test]
    fn eq5_bound_in_si_units() {
        // l = L: θ = sqrt(k/m)·L; k = 2000, m = 0.05 → sqrt(40000)·0.1 = 20 m/s.
        let theta = speed_bound(
            DispersionMode::AsPrinted,
            2000.0,
            0.05,
            0.05,
            0.1,
            0.1,
            1e-3,
        );
        assert!((theta - 20.0).abs() < 1e-12);
        assert_eq!(
            speed_bound(
                DispersionMode::AsPrinted,
                2000.0,
                0.05,
                0.05,
                0.2,
                0.1,
                1e-3
            ),
            0.0
        );
        // Bounded at rest length: sqrt(k/m)·(L − 0.6 L) = 200·0.04 = 8 m/s; per-step bound:
        // ½ l/ΔT = 0.5·0.1/0.01 = 5 m/s wins at ΔT = 10 ms.
        let fused = speed_bound(DispersionMode::Bounded, 2000.0, 0.05, 0.05, 0.1, 0.1, 1e-4);
        assert!((fused - 8.0).abs() < 1e-12);
        assert_eq!(
            speed_bound(DispersionMode::Bounded, 2000.0, 0.05, 0.05, 0.06, 0.1, 1e-4),
            0.0
        );
        let bounded = speed_bound(DispersionMode::Bounded, 2000.0, 0.05, 0.05, 0.1, 0.1, 0.01);
        assert!((bounded - 5.0).abs() < 1e-12);
    }

    #[test]
    fn eq6_keeps_momentum_and_leaves_exactly_theta() {
        for (m1, m2) in [(0.05, 0.05), (0.05, 0.2)] {
            let (mut nodes, springs) = pair(30.0, -10.0, m1, m2);
            let p0 = nodes.velocity[0] * m1 + nodes.velocity[1] * m2;
            let col = SpringColouring::new(2, &springs);
            let stats = disperse(
                DispersionMode::AsPrinted,
                &mut nodes,
                &springs,
                &col,
                1e-3,
                8,
                &mut Vec::new(),
            );
            assert_eq!(stats.corrections, 1);
            assert_eq!(stats.iterations, 1);
            let p1 = nodes.velocity[0] * m1 + nodes.velocity[1] * m2;
            assert!((p1 - p0).norm() < 1e-12);
            let rel = (nodes.velocity[1] - nodes.velocity[0]).norm();
            let theta = speed_bound(DispersionMode::AsPrinted, 2000.0, m1, m2, 0.1, 0.1, 1e-3);
            assert!((rel - theta).abs() < 1e-9, "{rel} vs {theta}");
        }
    }

    /// A pair 0.15 m apart on a 0.1 m spring: stretched 1.5 L, beyond the 0.4 L reach.
    fn overstretched(v1: Vector3<f64>, v2: Vector3<f64>) -> (NodeState, SpringSet) {
        let (mut nodes, springs) = pair(0.0, 0.0, 0.05, 0.02);
        nodes.position[1].x = 0.15;
        nodes.velocity = vec![v1, v2];
        (nodes, springs)
    }

    fn momentum(n: &NodeState) -> Vector3<f64> {
        n.velocity[0] * n.mass[0] + n.velocity[1] * n.mass[1]
    }

    #[test]
    fn fused_spring_moving_further_out_or_sideways_keeps_nothing() {
        let (mut nodes, springs) =
            overstretched(Vector3::new(-0.5, 0.3, 0.0), Vector3::new(0.4, -0.2, 0.1));
        let p0 = momentum(&nodes);
        let col = SpringColouring::new(2, &springs);
        let stats = disperse(
            DispersionMode::Bounded,
            &mut nodes,
            &springs,
            &col,
            1e-3,
            8,
            &mut Vec::new(),
        );
        assert!(stats.corrections > 0 && !stats.hit_cap, "{stats:?}");
        assert!((nodes.velocity[1] - nodes.velocity[0]).norm() < 1e-12);
        assert!((momentum(&nodes) - p0).norm() < 1e-15);
    }

    #[test]
    fn fused_spring_returns_at_a_speed_proportional_to_its_excess_strain() {
        // Closing at 3 m/s with some shear: only the closing part survives, capped at
        // RELEASE_RATE · ω · (0.5 L − 0.4 L).
        let (mut nodes, springs) =
            overstretched(Vector3::new(1.0, 0.2, 0.0), Vector3::new(-2.0, 0.0, 0.3));
        let p0 = momentum(&nodes);
        let col = SpringColouring::new(2, &springs);
        disperse(
            DispersionMode::Bounded,
            &mut nodes,
            &springs,
            &col,
            1e-3,
            8,
            &mut Vec::new(),
        );
        let m = 2.0 * 0.05 * 0.02 / 0.07;
        let expected = RELEASE_RATE * (2000.0_f64 / m).sqrt() * 0.01;
        let rel = nodes.velocity[1] - nodes.velocity[0];
        assert!((rel.x + expected).abs() < 1e-12, "{rel:?} vs {expected}");
        assert!(rel.y.abs() < 1e-12 && rel.z.abs() < 1e-12, "{rel:?}");
        assert!((momentum(&nodes) - p0).norm() < 1e-15);
    }

    #[test]
    fn a_spring_released_beyond_reach_comes_back_instead_of_staying_fused() {
        // Symplectic Euler with the spring force and the bounded dispersion, from rest at
        // 1.6 L: the stuck rule (θ = 0 beyond reach) kept it at 1.6 L forever.
        let (mut nodes, springs) = overstretched(Vector3::zeros(), Vector3::zeros());
        nodes.position[1].x = 0.16;
        let col = SpringColouring::new(2, &springs);
        let dt = 1e-4;
        let mut shortest_after = f64::INFINITY;
        for step in 0..2000 {
            let d = nodes.position[1] - nodes.position[0];
            let f = d / d.norm() * (2000.0 * (d.norm() - 0.1));
            nodes.velocity[0] += f * (dt / nodes.mass[0]);
            nodes.velocity[1] -= f * (dt / nodes.mass[1]);
            disperse(
                DispersionMode::Bounded,
                &mut nodes,
                &springs,
                &col,
                dt,
                32,
                &mut Vec::new(),
            );
            for i in 0..2 {
                let v = nodes.velocity[i];
                nodes.position[i] += v * dt;
            }
            let l = (nodes.position[1] - nodes.position[0]).norm();
            if step > 1000 {
                shortest_after = shortest_after.min(l);
            }
        }
        let l = (nodes.position[1] - nodes.position[0]).norm();
        // Back within reach (1.4 L) and never beyond the other side's reach (0.6 L).
        assert!(l < 0.14 + 1e-6, "still at {l}");
        assert!(shortest_after > 0.06 - 1e-9, "overshot to {shortest_after}");
    }

    #[test]
    fn within_bound_nothing_changes() {
        let (mut nodes, springs) = pair(1.0, -1.0, 0.05, 0.05);
        let before = nodes.clone();
        let col = SpringColouring::new(2, &springs);
        let stats = disperse(
            DispersionMode::AsPrinted,
            &mut nodes,
            &springs,
            &col,
            1e-3,
            8,
            &mut Vec::new(),
        );
        assert_eq!(stats, DispersionStats::default());
        assert_eq!(nodes, before);
    }

    #[test]
    fn cheap_prefilter_never_clears_a_violating_spring() {
        // A deterministic sweep over lengths, relative speeds, mass ratios and steps around
        // the prefilter's thresholds: whenever it clears a spring, the exact test agrees.
        let (mut cleared, mut violating) = (0, 0);
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for i in 0..20_000 {
            let mode = if i % 2 == 0 {
                DispersionMode::Bounded
            } else {
                DispersionMode::AsPrinted
            };
            let (m1, m2) = (0.01 + rnd(), 0.01 + rnd());
            let len = 0.1 * (0.85 + 0.3 * rnd());
            let dt = [1e-4, 1e-3, 1e-2][i % 3];
            let mut nodes = NodeState {
                position: vec![Vector3::zeros(), Vector3::new(len, 0.0, 0.0)],
                velocity: vec![Vector3::zeros(); 2],
                mass: vec![m1, m2],
                inv_mass: vec![1.0 / m1, 1.0 / m2],
            };
            let mut springs = SpringSet::default();
            springs.push(0, 1, 0.1, 2000.0, 0.0);
            let theta = speed_bound(mode, 2000.0, m1, m2, len, 0.1, dt);
            let speed = theta * (0.5 + rnd());
            let dir = Vector3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            nodes.velocity[1] = dir * speed;
            let exact = correction(mode, &nodes, &springs, 0, dt);
            if surely_within_bound(mode, &nodes, &springs, 0, dt) {
                cleared += 1;
                assert!(exact.is_none(), "case {i}: cleared a violating spring");
            }
            violating += exact.is_some() as u32;
        }
        assert!(
            cleared > 2_000,
            "the prefilter clears too little: {cleared}"
        );
        assert!(
            violating > 2_000,
            "the sweep must include violations: {violating}"
        );
    }

    #[test]
    fn colouring_never_puts_two_springs_of_a_node_in_one_colour() {
        let mut springs = SpringSet::default();
        // A small complete graph: 6 nodes, 15 springs.
        for a in 0..6u32 {
            for b in a + 1..6 {
                springs.push(a, b, 1.0, 1.0, 0.0);
            }
        }
        let col = SpringColouring::new(6, &springs);
        for c in 0..col.colour_count() {
            let mut seen = [false; 6];
            for &s in &col.order[col.offsets[c] as usize..col.offsets[c + 1] as usize] {
                for n in [springs.a[s as usize], springs.b[s as usize]] {
                    assert!(!seen[n as usize]);
                    seen[n as usize] = true;
                }
            }
        }
        assert_eq!(col.order.len(), 15);
    }
}
