//! Superquadric metaball models (Terasawa 1993 §5.3; Barr 1981; Nishimura's metaballs): each
//! primitive's inside-outside function
//! `F(p) = (|x/a|^(2/e₂) + |y/b|^(2/e₂))^(e₂/e₁) + |z/c|^(2/e₁)` (1 on its surface, in its own
//! frame) becomes a density `w (1 − F/R²)³` for `F < R²`, and the model's surface is where the
//! summed density equals the threshold `T`. `R² = 1 / (1 − T^(1/3))` puts a lone primitive
//! of weight 1 exactly on its own superquadric; nearby primitives blend smoothly, far ones
//! stay apart. [`Model::interval`] bounds the density over a box (interval arithmetic), which
//! is how [`crate::polygonise`] finds every piece of surface, however thin.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

type V3 = Vector3<f64>;

/// One primitive, as a shapes file gives it.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Superquadric {
    pub center: [f64; 3],
    /// Half extents along the primitive's own x, y, z, m.
    pub radii: [f64; 3],
    /// `[e₁, e₂]`: 1 is round, → 0 square, 2 a diamond (north–south, then around).
    #[serde(default = "round")]
    pub exponents: [f64; 2],
    /// Rotation about x, then y, then z, degrees.
    #[serde(default)]
    pub rotation: [f64; 3],
    #[serde(default = "one")]
    pub weight: f64,
}

fn round() -> [f64; 2] {
    [1.0, 1.0]
}

fn one() -> f64 {
    1.0
}

/// A shapes file (`springbake model shapes.toml`): the primitives (Y-up metres), the
/// threshold and the finest cell edge.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ShapesFile {
    #[serde(default = "half")]
    pub threshold: f64,
    /// Largest cell edge of the polygonisation, m (default: a 128th of the model's size).
    #[serde(default)]
    pub resolution: Option<f64>,
    #[serde(rename = "superquadric", alias = "superquadrics", default)]
    pub superquadrics: Vec<Superquadric>,
}

fn half() -> f64 {
    0.5
}

/// Fraction of the model's size the default resolution is.
pub const DEFAULT_CELLS_ACROSS: f64 = 128.0;

/// A shapes file's surface: its model polygonised at its resolution (default: a 128th of
/// the model's size), and a note when cells may hide parts thinner than a cell. An error when
/// the model is invalid or has no surface at its threshold.
pub fn shapes_surface(
    file: &ShapesFile,
) -> Result<(crate::polygonise::Surface, Option<String>), String> {
    let model = Model::new(&file.superquadrics, file.threshold)?;
    let (lo, hi) = model.bounds();
    let resolution = file
        .resolution
        .unwrap_or_else(|| (hi - lo).max() / DEFAULT_CELLS_ACROSS);
    let surface = crate::polygonise::polygonise(&model, resolution)?;
    if surface.triangles.is_empty() {
        return Err(format!(
            "the model has no surface at threshold {}",
            file.threshold
        ));
    }
    let mut notes = Vec::new();
    if surface.hidden_cells > 0 {
        notes.push(format!(
            "{} cells of {:.4} m may hide parts thinner than a cell (the refinement stopped at \
             its budget); set a finer resolution to keep them",
            surface.hidden_cells, surface.cell
        ));
    }
    if surface.ungraded_edges > 0 {
        notes.push(format!(
            "{} edges stay further than {:.5} m from the surface: the mesh reached {} \
             triangles; set a coarser resolution",
            surface.ungraded_edges,
            resolution * crate::polygonise::TOLERANCE_PER_RESOLUTION,
            crate::polygonise::MAX_TRIANGLES
        ));
    }
    Ok((surface, (!notes.is_empty()).then(|| notes.join("; "))))
}

/// A model: primitives blended at a threshold.
#[derive(Debug, Clone)]
pub struct Model {
    prims: Vec<Prim>,
    threshold: f64,
    /// `R²` of the density's support (module docs).
    reach: f64,
}

#[derive(Debug, Clone)]
struct Prim {
    centre: V3,
    /// World to the primitive's frame, scaled by its radii (so its surface has F = 1).
    to_local: Matrix3<f64>,
    e1: f64,
    e2: f64,
    weight: f64,
    /// Beyond this in any local coordinate the density is zero (`F ≥ |l_k|^(2/e1)` for each
    /// coordinate, so `|l_k| ≥ reach^(e1/2)` puts `F` past the reach).
    cut: f64,
}

impl Model {
    /// The model of `prims` at `threshold` (in (0, 1)), or what is wrong with them.
    pub fn new(prims: &[Superquadric], threshold: f64) -> Result<Model, String> {
        if !(threshold > 0.0 && threshold < 1.0) {
            return Err(format!("threshold must lie in (0, 1), got {threshold}"));
        }
        if prims.is_empty() {
            return Err("no superquadrics".into());
        }
        let reach = 1.0 / (1.0 - threshold.cbrt());
        let mut out = Vec::new();
        for (i, q) in prims.iter().enumerate() {
            let bad = |what: &str| Err(format!("superquadric[{i}].{what}"));
            if q.radii.iter().any(|r| !(r.is_finite() && *r > 0.0)) {
                return bad("radii must be positive");
            }
            if q.exponents
                .iter()
                .any(|e| !(e.is_finite() && (0.05..=4.0).contains(e)))
            {
                return bad("exponents must lie in [0.05, 4]");
            }
            if !(q.weight.is_finite() && q.weight > 0.0) {
                return bad("weight must be positive");
            }
            if q.center.iter().chain(&q.rotation).any(|x| !x.is_finite()) {
                return bad("center and rotation must be finite");
            }
            let [rx, ry, rz] = q.rotation.map(f64::to_radians);
            let rotation = Rotation3::from_euler_angles(rx, ry, rz);
            let scale = Matrix3::from_diagonal(&V3::from(q.radii).map(|r| 1.0 / r));
            out.push(Prim {
                centre: V3::from(q.center),
                to_local: scale * rotation.inverse().matrix(),
                e1: q.exponents[0],
                e2: q.exponents[1],
                weight: q.weight,
                cut: reach.powf(q.exponents[0] / 2.0),
            });
        }
        Ok(Model {
            prims: out,
            threshold,
            reach,
        })
    }

    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    fn inside_outside(p: &Prim, local: [f64; 3]) -> f64 {
        let [x, y, z] = local.map(f64::abs);
        // `|v|^(2/e)`, exact and cheap for the round e = 1.
        let power = |v: f64, e: f64| if e == 1.0 { v * v } else { v.powf(2.0 / e) };
        let around = power(x, p.e2) + power(y, p.e2);
        let around = if p.e1 == p.e2 {
            around
        } else {
            around.powf(p.e2 / p.e1)
        };
        around + power(z, p.e1)
    }

    fn density(&self, f: f64, weight: f64) -> f64 {
        if f >= self.reach {
            0.0
        } else {
            let t = 1.0 - f / self.reach;
            weight * t * t * t
        }
    }

    /// The summed density at `p`.
    pub fn field(&self, p: &V3) -> f64 {
        self.prims
            .iter()
            .map(|q| {
                let l = q.to_local * (p - q.centre);
                if l.amax() >= q.cut {
                    return 0.0; // out of the primitive's reach: skips the powers
                }
                self.density(Self::inside_outside(q, [l.x, l.y, l.z]), q.weight)
            })
            .sum()
    }

    /// The field's gradient at `p` (central differences at `h`).
    pub fn gradient(&self, p: &V3, h: f64) -> V3 {
        let d = |axis: usize| {
            let mut e = V3::zeros();
            e[axis] = h;
            (self.field(&(p + e)) - self.field(&(p - e))) / (2.0 * h)
        };
        V3::new(d(0), d(1), d(2))
    }

    /// Bounds of the density over the axis-aligned box `[lo, hi]`.
    pub fn interval(&self, lo: &V3, hi: &V3) -> (f64, f64) {
        let centre = (lo + hi) * 0.5;
        let half = (hi - lo) * 0.5;
        let (mut low, mut high) = (0.0, 0.0);
        for q in &self.prims {
            let c = q.to_local * (centre - q.centre);
            let extent = q.to_local.abs() * half;
            // |local| ranges per axis over the box's image.
            let range = |k: usize| {
                let (a, b) = (c[k] - extent[k], c[k] + extent[k]);
                if a <= 0.0 && b >= 0.0 {
                    (0.0, a.abs().max(b.abs()))
                } else {
                    (a.abs().min(b.abs()), a.abs().max(b.abs()))
                }
            };
            let (x, y, z) = (range(0), range(1), range(2));
            let f_lo = Self::inside_outside(q, [x.0, y.0, z.0]);
            let f_hi = Self::inside_outside(q, [x.1, y.1, z.1]);
            low += self.density(f_hi, q.weight);
            high += self.density(f_lo, q.weight);
        }
        (low, high)
    }

    /// A box that holds every primitive's support, m.
    pub fn bounds(&self) -> (V3, V3) {
        let mut lo = V3::repeat(f64::INFINITY);
        let mut hi = V3::repeat(f64::NEG_INFINITY);
        for q in &self.prims {
            // The support F < R² lies within the radii times R^(max exponent) on every axis.
            let world_from_local = q.to_local.try_inverse().unwrap_or_else(Matrix3::identity);
            let grow = self.reach.powf(q.e1.max(q.e2).max(1.0) / 2.0);
            let extent = world_from_local.abs() * V3::repeat(grow);
            lo = lo.inf(&(q.centre - extent));
            hi = hi.sup(&(q.centre + extent));
        }
        (lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(center: [f64; 3], r: f64) -> Superquadric {
        Superquadric {
            center,
            radii: [r; 3],
            exponents: [1.0, 1.0],
            rotation: [0.0; 3],
            weight: 1.0,
        }
    }

    #[test]
    fn a_lone_primitive_sits_on_its_own_surface() {
        let m = Model::new(&[sphere([0.0; 3], 0.5)], 0.5).unwrap();
        assert!((m.field(&V3::new(0.5, 0.0, 0.0)) - 0.5).abs() < 1e-12);
        assert!(m.field(&V3::zeros()) > 0.5 && m.field(&V3::new(0.6, 0.0, 0.0)) < 0.5);
    }

    #[test]
    fn intervals_hold_every_sample_of_the_box() {
        let mut q = sphere([0.1, 0.2, 0.0], 0.3);
        q.exponents = [0.3, 1.7];
        q.rotation = [30.0, 10.0, 70.0];
        let m = Model::new(&[q, sphere([0.4, 0.0, 0.1], 0.2)], 0.4).unwrap();
        let (lo, hi) = (V3::new(0.0, 0.0, -0.1), V3::new(0.25, 0.3, 0.2));
        let (a, b) = m.interval(&lo, &hi);
        for i in 0..=6 {
            for j in 0..=6 {
                for k in 0..=6 {
                    let t = V3::new(i as f64, j as f64, k as f64) / 6.0;
                    let p = lo + (hi - lo).component_mul(&t);
                    let f = m.field(&p);
                    assert!(f >= a - 1e-12 && f <= b + 1e-12, "{f} not in [{a}, {b}]");
                }
            }
        }
    }
}
