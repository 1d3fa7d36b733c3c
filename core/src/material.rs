//! Materials in real units (physics §3): Young's modulus, Poisson ratio, density and a damping
//! ratio, with the presets artists reach for. The solver turns them into spring constants
//! (`k = E·L`, Miyazaki eq 11), node masses (`m = d·L³` shared among a cell's corners, eq 12)
//! and dampers (`D = 2ζ·sqrt(k·μ)`, ζ the damping ratio, μ the reduced mass of the spring's ends).

use serde::{Deserialize, Serialize};

/// A bulk material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Material {
    pub name: String,
    /// Young's modulus, Pa.
    pub young_pa: f64,
    /// Poisson ratio (used by Hertz contact; a mass-spring lattice cannot set it independently).
    pub poisson: f64,
    /// Density, kg/m³.
    pub density_kg_m3: f64,
    /// Damping ratio of each spring (1 = critical damping).
    pub damping_ratio: f64,
}

/// A material value out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MaterialError {
    #[error("unknown material preset \"{name}\"; presets: {}", PRESETS.iter().map(|p| p.0).collect::<Vec<_>>().join(", "))]
    UnknownPreset { name: String },
    #[error("material {field} must be {rule}, got {value}")]
    OutOfRange {
        field: &'static str,
        rule: &'static str,
        value: f64,
    },
}

/// name, E (Pa), Poisson ratio, density (kg/m³), damping ratio.
/// Rubber and steel from Terasawa Table 3.1 (rubber at the soft end of 1.5–5.0 MPa). The
/// damping ratio also sets how stiff bodies bounce (`solver::xpbd`'s restitution,
/// e = exp(−πζ/√(1−ζ²))): wood's 0.15 gives e ≈ 0.62, a hardwood ball on a hard floor (0.5–0.7);
/// steel's 0.07 gives e ≈ 0.80 (a steel ball on stone or concrete, 0.7–0.9). Jelly's ν is
/// 0.499 (a gel is mostly water: nearly incompressible): at 0.49 its bulk modulus was only
/// 167 kPa, and a 1 m jelly ball thrown down at 8 m/s lost 22 % of its volume at the impact
/// (a jelly snowman's 0.4 m head landing at 6.7 m/s: 26 %, measured in Blender); at 0.499,
/// 1.2 % and 2.4 %.
pub const PRESETS: &[(&str, f64, f64, f64, f64)] = &[
    ("jelly", 1.0e4, 0.499, 1050.0, 0.02),
    ("soft_rubber", 3.0e5, 0.49, 1100.0, 0.04),
    ("rubber", 1.5e6, 0.47, 1100.0, 0.1),
    ("foam", 5.0e4, 0.30, 60.0, 0.20),
    ("wood", 1.0e10, 0.35, 600.0, 0.15),
    ("steel", 2.01e11, 0.29, 7850.0, 0.07),
];

impl Material {
    /// A validated material: E, density > 0, 0 ≤ ν < 0.5, damping ratio ≥ 0, all finite.
    pub fn new(
        name: impl Into<String>,
        young_pa: f64,
        poisson: f64,
        density_kg_m3: f64,
        damping_ratio: f64,
    ) -> Result<Material, MaterialError> {
        let check = |field: &'static str, ok: bool, rule: &'static str, value: f64| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(MaterialError::OutOfRange { field, rule, value })
            }
        };
        check("young", young_pa > 0.0, "> 0 Pa", young_pa)?;
        check("density", density_kg_m3 > 0.0, "> 0 kg/m³", density_kg_m3)?;
        check(
            "poisson",
            (0.0..0.5).contains(&poisson),
            "in [0, 0.5)",
            poisson,
        )?;
        check("damping", damping_ratio >= 0.0, ">= 0", damping_ratio)?;
        Ok(Material {
            name: name.into(),
            young_pa,
            poisson,
            density_kg_m3,
            damping_ratio,
        })
    }

    /// A preset by name (case-insensitive; `soft-rubber` and `soft_rubber` both work).
    pub fn preset(name: &str) -> Result<Material, MaterialError> {
        let key = name.to_ascii_lowercase().replace(['-', ' '], "_");
        PRESETS
            .iter()
            .find(|p| p.0 == key)
            .map(|&(n, e, nu, d, z)| Material {
                name: n.to_owned(),
                young_pa: e,
                poisson: nu,
                density_kg_m3: d,
                damping_ratio: z,
            })
            .ok_or_else(|| MaterialError::UnknownPreset {
                name: name.to_owned(),
            })
    }

    /// Spring constant of a lattice spring for cell edge `cell_size_m` (Miyazaki eq 11).
    pub fn spring_constant(&self, cell_size_m: f64) -> f64 {
        self.young_pa * cell_size_m
    }

    /// Mass of one full cell (Miyazaki eq 12); each corner node gets an eighth of it.
    pub fn cell_mass(&self, cell_size_m: f64) -> f64 {
        self.density_kg_m3 * cell_size_m.powi(3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_named() {
        for p in PRESETS {
            let m = Material::preset(p.0).unwrap();
            Material::new(
                &m.name,
                m.young_pa,
                m.poisson,
                m.density_kg_m3,
                m.damping_ratio,
            )
            .unwrap();
        }
        assert_eq!(Material::preset("Soft-Rubber").unwrap().name, "soft_rubber");
        assert!(matches!(
            Material::preset("unobtanium"),
            Err(MaterialError::UnknownPreset { .. })
        ));
    }

    #[test]
    fn rejects_zero_negative_and_nan() {
        assert!(Material::new("x", 0.0, 0.3, 1000.0, 0.1).is_err());
        assert!(Material::new("x", 1e5, 0.3, -1.0, 0.1).is_err());
        assert!(Material::new("x", 1e5, 0.5, 1000.0, 0.1).is_err());
        assert!(Material::new("x", f64::NAN, 0.3, 1000.0, 0.1).is_err());
        assert!(Material::new("x", 1e5, 0.3, 1000.0, -0.1).is_err());
    }

    #[test]
    fn rubber_in_paper_units() {
        // Miyazaki: rubber 10^6 dyn/cm² = 10^5 Pa, d = 1 g/cm³; eq 13 with max k/m = 430 s⁻²
        // needs L > sqrt(E / (d·430)) ≈ 0.48 m ("50 cm").
        let l_min = (1.0e5_f64 / (1000.0 * 430.0)).sqrt();
        assert!((l_min - 0.482).abs() < 0.001, "{l_min}");
        let m = Material::new("paper_rubber", 1.0e5, 0.47, 1000.0, 0.0).unwrap();
        assert!((m.spring_constant(0.5) / (m.cell_mass(0.5)) - 400.0).abs() < 1e-9);
    }
}
