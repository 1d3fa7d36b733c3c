//! Hertz contact between two bodies: Terasawa's sinusoidal impact pulse (physics §10;
//! Terasawa 1993, §3.3.2 eq 3.29–3.42 and appendix B eq 7.10–7.28).
//!
//! This module owns the closed-form impact model and the helpers that read its inputs off a
//! mass-spring body. It is pure arithmetic: collision detection and distributing the force onto
//! lattice nodes (eq 3.43–3.47) belong to the solver, which is not wired to this module yet.
//!
//! Model, SI units throughout:
//!
//! - `n1 = (M1 + M2) / (M1 M2)` (eq 3.33; a body of infinite mass, e.g. the floor, contributes
//!   `1/M = 0`);
//! - `δi = (1 − σi²) / (π Ei)` (eq 3.35);
//! - `n2 = (4/3) q_k(A/B) / ((δ1 + δ2) sqrt(A + B))` (eq 3.34), `A`, `B` the coefficients of the
//!   gap `z1 + z2 = A x² + B y²` near the contact point (table 3.2, [`ContactGeometry`]);
//! - `α_m = ((5/4) v0² / (n1 n2))^(2/5)` (eq 7.24; the body text's eq 3.32 prints 1/3, a
//!   transcription error: the worked ratios of §3.3.4 need 2/5);
//! - `F_max = 1.140 v0² / (n1 α_m)` (eq 3.30), `T_max = π α_m / (1.068 v0)` (eq 3.31);
//! - `F(t) = F_max sin(π t / T_max)` for `0 ≤ t ≤ T_max`, zero otherwise (eq 3.29).
//!
//! `q_k` comes from table 3.3 (Goldsmith 1960), interpolated log–log between the nine
//! tabulated ratios; [`q_k_elliptic`] evaluates the same quantity exactly from complete
//! elliptic integrals (Hertz's elliptical contact, Johnson *Contact Mechanics* §4.2), which
//! agrees with the table to within 2 % and is used by the tests to check the transcription.
//!
//! Body parameters from a mass-spring model (eq 3.36–3.41): total mass is the sum of node
//! masses; Young's modulus is `E = (1/N_e) Σ l_i k_i / A_sp` over the springs
//! ([`young_from_springs`]), where `A_sp` is the cross-section one spring stands for. For this
//! project's cubic lattice of cell edge `L` the natural choice is `A_sp = L²`
//! ([`lattice_spring_area_m2`]): it makes eq 3.38 the inverse of the lattice's own `k = E L`
//! (physics §3, [`crate::material::Material::spring_constant`]) on the axis edges. The Poisson
//! ratio is fixed at 0.3 ([`MASS_SPRING_POISSON`]), as in the thesis, and the local radius of
//! curvature is `R = (1/N) Σ l_i / |n_i1 − n_i2|` over the edges of the contact face
//! ([`local_radius`], eq 3.41).

use nalgebra::Vector3;
use std::f64::consts::PI;

/// Poisson ratio the thesis fixes for bodies built from springs (§3.3.2: E dominates δ).
pub const MASS_SPRING_POISSON: f64 = 0.3;

/// Table 3.3 (Goldsmith 1960): `(A/B, q_k)`, A ≤ B, ratio decreasing. The first row is the
/// paper's rounded `1/π` and is kept as printed.
#[allow(clippy::approx_constant)]
pub const Q_K_TABLE: [(f64, f64); 9] = [
    (1.00, 0.3180),
    (0.7041, 0.3215),
    (0.4903, 0.3322),
    (0.3333, 0.3505),
    (0.2174, 0.3819),
    (0.1325, 0.4300),
    (0.0718, 0.5132),
    (0.0311, 0.6662),
    (0.00765, 1.1450),
];

/// Smallest `A/B` the table covers.
pub const Q_K_MIN_RATIO: f64 = 0.00765;

/// Bad input to the Hertz model. `field` names the argument, e.g. `body1.young_pa`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HertzError {
    #[error("hertz: {field} must be {rule}, got {value}")]
    OutOfRange {
        field: String,
        rule: &'static str,
        value: f64,
    },
    #[error("hertz: both bodies have infinite mass; n1 = 0 and the impact is undefined")]
    BothImmovable,
    #[error(
        "hertz: A/B = {ratio} is outside table 3.3 (A/B ≥ {min}); such an elongated contact is \
         not covered (use q_k_elliptic if you need it)"
    )]
    RatioOutOfTable { ratio: f64, min: f64 },
    #[error("hertz: {what}: no input ({field} is empty)")]
    Empty {
        what: &'static str,
        field: &'static str,
    },
}

fn check(field: &str, ok: bool, rule: &'static str, value: f64) -> Result<(), HertzError> {
    if ok && !value.is_nan() {
        Ok(())
    } else {
        Err(HertzError::OutOfRange {
            field: field.to_owned(),
            rule,
            value,
        })
    }
}

fn positive_finite(field: &str, value: f64) -> Result<(), HertzError> {
    check(
        field,
        value > 0.0 && value.is_finite(),
        "finite and > 0",
        value,
    )
}

/// One side of the contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HertzBody {
    /// Total mass, kg (eq 3.36). `f64::INFINITY` for an immovable body such as the floor.
    pub mass_kg: f64,
    /// Young's modulus, Pa.
    pub young_pa: f64,
    /// Poisson ratio σ, in [0, 0.5].
    pub poisson: f64,
}

impl HertzBody {
    /// A body with the thesis's fixed Poisson ratio 0.3.
    pub fn with_default_poisson(mass_kg: f64, young_pa: f64) -> HertzBody {
        HertzBody {
            mass_kg,
            young_pa,
            poisson: MASS_SPRING_POISSON,
        }
    }

    fn validate(&self, name: &str) -> Result<(), HertzError> {
        check(
            &format!("{name}.mass_kg"),
            self.mass_kg > 0.0,
            "> 0 (f64::INFINITY for an immovable body)",
            self.mass_kg,
        )?;
        positive_finite(&format!("{name}.young_pa"), self.young_pa)?;
        check(
            &format!("{name}.poisson"),
            (0.0..=0.5).contains(&self.poisson),
            "in [0, 0.5]",
            self.poisson,
        )
    }

    /// `δ = (1 − σ²) / (π E)` (eq 3.35), m²/N.
    pub fn delta(&self) -> f64 {
        (1.0 - self.poisson * self.poisson) / (PI * self.young_pa)
    }
}

/// Shape of the two surfaces at the contact point (table 3.2). Radii in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactGeometry {
    /// Sphere of radius `r1_m` on sphere of radius `r2_m` (eq 3.40): `A = B = 1/(2R1) + 1/(2R2)`.
    Spheres { r1_m: f64, r2_m: f64 },
    /// Sphere of radius `r_m` on a plane: `A = B = 1/(2R)`.
    SphereOnPlane { r_m: f64 },
    /// Two cylinders crossed at right angles: `A = 1/(2R1)`, `B = 1/(2R2)`.
    CrossedCylinders { r1_m: f64, r2_m: f64 },
    /// Sphere of radius `sphere_r_m` on a cylinder of radius `cylinder_r_m`:
    /// `A = 1/(2R1)`, `B = (1/R1 + 1/R2)/2`.
    SphereOnCylinder { sphere_r_m: f64, cylinder_r_m: f64 },
    /// The gap coefficients directly, 1/m (eq 7.10: `z1 + z2 = A x² + B y²`).
    Quadratic { a_per_m: f64, b_per_m: f64 },
}

impl ContactGeometry {
    /// Both surfaces from their local radii ([`local_radius`]): sphere–sphere or sphere–plane.
    /// Two flat surfaces have no Hertz point contact: an error.
    pub fn from_radii(r1: SurfaceRadius, r2: SurfaceRadius) -> Result<Self, HertzError> {
        match (r1, r2) {
            (SurfaceRadius::Curved(r1_m), SurfaceRadius::Curved(r2_m)) => {
                Ok(ContactGeometry::Spheres { r1_m, r2_m })
            }
            (SurfaceRadius::Curved(r_m), SurfaceRadius::Flat)
            | (SurfaceRadius::Flat, SurfaceRadius::Curved(r_m)) => {
                Ok(ContactGeometry::SphereOnPlane { r_m })
            }
            (SurfaceRadius::Flat, SurfaceRadius::Flat) => Err(HertzError::OutOfRange {
                field: "geometry (both surfaces flat)".to_owned(),
                rule: "at least one curved surface",
                value: f64::INFINITY,
            }),
        }
    }

    /// `(A, B)` in 1/m, validated (radii finite and > 0).
    pub fn coefficients(&self) -> Result<(f64, f64), HertzError> {
        match *self {
            ContactGeometry::Spheres { r1_m, r2_m } => {
                positive_finite("geometry.r1_m", r1_m)?;
                positive_finite("geometry.r2_m", r2_m)?;
                let a = 0.5 / r1_m + 0.5 / r2_m;
                Ok((a, a))
            }
            ContactGeometry::SphereOnPlane { r_m } => {
                positive_finite("geometry.r_m", r_m)?;
                Ok((0.5 / r_m, 0.5 / r_m))
            }
            ContactGeometry::CrossedCylinders { r1_m, r2_m } => {
                positive_finite("geometry.r1_m", r1_m)?;
                positive_finite("geometry.r2_m", r2_m)?;
                Ok((0.5 / r1_m, 0.5 / r2_m))
            }
            ContactGeometry::SphereOnCylinder {
                sphere_r_m,
                cylinder_r_m,
            } => {
                positive_finite("geometry.sphere_r_m", sphere_r_m)?;
                positive_finite("geometry.cylinder_r_m", cylinder_r_m)?;
                Ok((
                    0.5 / sphere_r_m,
                    0.5 * (1.0 / sphere_r_m + 1.0 / cylinder_r_m),
                ))
            }
            ContactGeometry::Quadratic { a_per_m, b_per_m } => {
                positive_finite("geometry.a_per_m", a_per_m)?;
                positive_finite("geometry.b_per_m", b_per_m)?;
                Ok((a_per_m, b_per_m))
            }
        }
    }
}

/// `q_k(A/B)` from table 3.3, `ln q_k` linear in `ln(A/B)` between rows (within 0.7 % of the
/// exact elliptic solution at the geometric midpoints; interpolating `q_k` itself is off by
/// 3.8 % in the last interval). The ratio may be given either
/// way round (`A/B` or `B/A`: swapping the x and y axes is the same contact); it is folded to
/// `min/max` ≤ 1. Below [`Q_K_MIN_RATIO`] it is an error.
pub fn q_k(ratio: f64) -> Result<f64, HertzError> {
    positive_finite("A/B", ratio)?;
    let r = if ratio > 1.0 { 1.0 / ratio } else { ratio };
    if r == 1.0 {
        return Ok(Q_K_TABLE[0].1);
    }
    // Folding `B/A` back to `A/B` may round a table row down by an ulp: allow for it.
    if r < Q_K_MIN_RATIO * (1.0 - 1e-12) {
        return Err(HertzError::RatioOutOfTable {
            ratio: r,
            min: Q_K_MIN_RATIO,
        });
    }
    let r = r.max(Q_K_MIN_RATIO);
    for w in Q_K_TABLE.windows(2) {
        let (r_hi, q_hi) = w[0];
        let (r_lo, q_lo) = w[1];
        if r <= r_hi && r >= r_lo {
            let s = (r.ln() - r_lo.ln()) / (r_hi.ln() - r_lo.ln());
            return Ok((q_lo.ln() + s * (q_hi.ln() - q_lo.ln())).exp());
        }
    }
    // Unreachable for r in [Q_K_MIN_RATIO, 1]; report rather than panic.
    Err(HertzError::RatioOutOfTable {
        ratio: r,
        min: Q_K_MIN_RATIO,
    })
}

/// Complete elliptic integrals `(K(m), E(m))` of parameter `m = e²`, `0 ≤ m < 1`, by the
/// arithmetic-geometric mean.
fn elliptic_k_e(m: f64) -> (f64, f64) {
    let mut a = 1.0_f64;
    let mut b = (1.0 - m).sqrt();
    let mut c = m.sqrt();
    let mut c2_sum = 0.5 * m; // Σ 2^(n−1) c_n², c_0² = m
    let mut pow = 0.5;
    for _ in 0..64 {
        let an = 0.5 * (a + b);
        // c_(n+1) = (a_n − b_n)/2 = c_n² / (4 a_(n+1)), without the cancellation.
        c = c * c / (4.0 * an);
        b = (a * b).sqrt();
        a = an;
        pow *= 2.0;
        c2_sum += pow * c * c;
        if c < 1e-17 * a {
            break;
        }
    }
    let k = PI / (2.0 * a);
    (k, k * (1.0 - c2_sum))
}

/// `q_k(A/B)` evaluated exactly from Hertz's elliptical contact (not from the table): with the
/// contact ellipse's eccentricity `e` solving `B/A = (E/(1−e²) − K) / (K − E)`,
/// `q_k = ½ sqrt((1 + B/A)(K − E)/e²) / K^(3/2)`, which is `1/π` at `A = B`. Valid for any
/// ratio in (0, ∞) (folded to ≤ 1 like [`q_k`]).
pub fn q_k_elliptic(ratio: f64) -> Result<f64, HertzError> {
    positive_finite("A/B", ratio)?;
    let r = if ratio > 1.0 { 1.0 / ratio } else { ratio };
    if r == 1.0 {
        return Ok(1.0 / PI);
    }
    let b_over_a = 1.0 / r;
    let f = |m: f64| {
        let (k, e) = elliptic_k_e(m);
        (e / (1.0 - m) - k) / (k - e)
    };
    // f increases from 1 (m → 0) to ∞ (m → 1): bisect on m.
    let (mut lo, mut hi) = (1e-12_f64, 1.0 - 1e-16);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < b_over_a {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let m = 0.5 * (lo + hi);
    let (k, e) = elliptic_k_e(m);
    Ok(0.5 * ((1.0 + b_over_a) * (k - e) / m).sqrt() / k.powf(1.5))
}

/// The impact pulse of one collision (eq 3.29–3.35).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HertzImpact {
    /// Peak force, N (eq 3.30).
    pub f_max: f64,
    /// Contact duration, s (eq 3.31).
    pub t_max: f64,
    /// Maximum relative compression, m (eq 7.24).
    pub alpha_m: f64,
    /// `(M1 + M2)/(M1 M2)`, 1/kg (eq 3.33).
    pub n1: f64,
    /// Hertz stiffness, N/m^(3/2) (eq 3.34): `F = n2 α^(3/2)`.
    pub n2: f64,
}

impl HertzImpact {
    /// The pulse for bodies `body1`, `body2` meeting at relative normal speed `v0_m_s`
    /// (eq 3.37) with the given contact geometry. Every input is validated; nothing panics.
    pub fn compute(
        body1: &HertzBody,
        body2: &HertzBody,
        geometry: &ContactGeometry,
        v0_m_s: f64,
    ) -> Result<HertzImpact, HertzError> {
        body1.validate("body1")?;
        body2.validate("body2")?;
        positive_finite("v0_m_s", v0_m_s)?;
        let (a, b) = geometry.coefficients()?;
        let n1 = 1.0 / body1.mass_kg + 1.0 / body2.mass_kg;
        if n1 <= 0.0 {
            return Err(HertzError::BothImmovable);
        }
        let qk = q_k(a / b)?;
        let n2 = (4.0 / 3.0) * qk / ((body1.delta() + body2.delta()) * (a + b).sqrt());
        let alpha_m = (1.25 * v0_m_s * v0_m_s / (n1 * n2)).powf(0.4);
        let f_max = 1.140 * v0_m_s * v0_m_s / (n1 * alpha_m);
        let t_max = PI * alpha_m / (1.068 * v0_m_s);
        let out = HertzImpact {
            f_max,
            t_max,
            alpha_m,
            n1,
            n2,
        };
        for (field, v) in [("f_max", f_max), ("t_max", t_max), ("alpha_m", alpha_m)] {
            // Extreme but valid inputs can still overflow (e.g. E = 1e-300).
            positive_finite(&format!("result {field} (inputs too extreme)"), v)?;
        }
        Ok(out)
    }

    /// `F(t) = F_max sin(π t / T_max)` for `0 ≤ t ≤ T_max`, else 0 (eq 3.29), N.
    pub fn force_at(&self, t_secs: f64) -> f64 {
        if (0.0..=self.t_max).contains(&t_secs) {
            self.f_max * (PI * t_secs / self.t_max).sin()
        } else {
            0.0
        }
    }

    /// `∫ F dt = (2/π) F_max T_max` (eq 7.28), N·s; equals `2.135 v0 / n1` by construction
    /// (`2 · 1.140 / 1.068`).
    pub fn impulse(&self) -> f64 {
        2.0 / PI * self.f_max * self.t_max
    }

    /// Mean force over a time window `[t0, t1]` (e.g. one solver substep), N: the exact
    /// integral of the pulse divided by the window length. Zero for an empty window.
    pub fn mean_force(&self, t0_secs: f64, t1_secs: f64) -> f64 {
        if t1_secs <= t0_secs || t0_secs.is_nan() || t1_secs.is_nan() {
            return 0.0;
        }
        let a = t0_secs.clamp(0.0, self.t_max);
        let b = t1_secs.clamp(0.0, self.t_max);
        let w = PI / self.t_max;
        let integral = self.f_max / w * ((w * a).cos() - (w * b).cos());
        integral / (t1_secs - t0_secs)
    }
}

/// One spring of a mass-spring body: rest length `l_i` and stiffness `k_i`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringEdge {
    pub length_m: f64,
    pub k_n_per_m: f64,
}

/// `A_sp` for a cubic lattice of cell edge `cell_size_m`: `L²`, the face of the cell an axis
/// spring stands for. With it, eq 3.38 inverts the lattice's `k = E L` exactly on axis edges;
/// face diagonals (length `√2 L`, same `k`) read as `√2 E`, so a lattice with diagonals reads
/// stiffer than its material, as in the thesis's own averaging.
pub fn lattice_spring_area_m2(cell_size_m: f64) -> f64 {
    cell_size_m * cell_size_m
}

/// Young's modulus of a mass-spring body, Pa: `E = (1/N_e) Σ l_i k_i / A_sp` (eq 3.38–3.39),
/// `A_sp` the cross-section every spring is assumed to have (m², see
/// [`lattice_spring_area_m2`]).
pub fn young_from_springs(edges: &[SpringEdge], spring_area_m2: f64) -> Result<f64, HertzError> {
    positive_finite("spring_area_m2", spring_area_m2)?;
    if edges.is_empty() {
        return Err(HertzError::Empty {
            what: "young_from_springs",
            field: "edges",
        });
    }
    let mut sum = 0.0;
    for (i, e) in edges.iter().enumerate() {
        positive_finite(&format!("edges[{i}].length_m"), e.length_m)?;
        positive_finite(&format!("edges[{i}].k_n_per_m"), e.k_n_per_m)?;
        sum += e.length_m * e.k_n_per_m / spring_area_m2;
    }
    Ok(sum / edges.len() as f64)
}

/// Total mass of a body, kg: the sum of its node masses (eq 3.36).
pub fn total_mass(node_masses_kg: &[f64]) -> Result<f64, HertzError> {
    if node_masses_kg.is_empty() {
        return Err(HertzError::Empty {
            what: "total_mass",
            field: "node_masses_kg",
        });
    }
    let mut sum = 0.0;
    for (i, &m) in node_masses_kg.iter().enumerate() {
        positive_finite(&format!("node_masses_kg[{i}]"), m)?;
        sum += m;
    }
    Ok(sum)
}

/// An edge of the contact face with the surface normals at its two ends (eq 3.41, fig 3.14).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceEdge {
    pub a: Vector3<f64>,
    pub b: Vector3<f64>,
    /// Normal at `a` (need not be unit length; it is normalised).
    pub normal_a: Vector3<f64>,
    /// Normal at `b`.
    pub normal_b: Vector3<f64>,
}

/// Local radius of curvature of a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceRadius {
    Curved(f64),
    /// Infinite radius: the normals do not turn along some edge.
    Flat,
}

/// `R = (1/N) Σ l_i / |n_i1 − n_i2|` over the edges of the contact face (eq 3.41). Exact for
/// chords of a sphere with its true normals. If the normals are equal along any edge
/// (`|n_i1 − n_i2| < 1e-12`) that edge's radius is infinite and so is the mean: the surface is
/// [`SurfaceRadius::Flat`]. Note this mean of radii is dominated by the flattest edge, as the
/// thesis's formula is.
pub fn local_radius(edges: &[SurfaceEdge]) -> Result<SurfaceRadius, HertzError> {
    if edges.is_empty() {
        return Err(HertzError::Empty {
            what: "local_radius",
            field: "edges",
        });
    }
    let mut sum = 0.0;
    for (i, e) in edges.iter().enumerate() {
        let l = (e.b - e.a).norm();
        positive_finite(&format!("edges[{i}] length"), l)?;
        let na = e.normal_a.norm();
        let nb = e.normal_b.norm();
        positive_finite(&format!("edges[{i}].normal_a length"), na)?;
        positive_finite(&format!("edges[{i}].normal_b length"), nb)?;
        let chord = (e.normal_a / na - e.normal_b / nb).norm();
        if chord < 1e-12 {
            return Ok(SurfaceRadius::Flat);
        }
        sum += l / chord;
    }
    Ok(SurfaceRadius::Curved(sum / edges.len() as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elliptic_integrals_match_known_values() {
        // K(0) = E(0) = π/2; K(0.5) = 1.854074677301372, E(0.5) = 1.350643881047675.
        let (k0, e0) = elliptic_k_e(0.0);
        assert!((k0 - PI / 2.0).abs() < 1e-14 && (e0 - PI / 2.0).abs() < 1e-14);
        let (k, e) = elliptic_k_e(0.5);
        assert!((k - 1.854_074_677_301_372).abs() < 1e-13, "{k}");
        assert!((e - 1.350_643_881_047_675).abs() < 1e-13, "{e}");
    }

    #[test]
    fn q_k_hits_table_rows_and_folds_the_ratio() {
        for (r, q) in Q_K_TABLE {
            assert!((q_k(r).unwrap() - q).abs() < 1e-12);
            assert!((q_k(1.0 / r).unwrap() - q).abs() < 1e-12);
        }
    }
}
