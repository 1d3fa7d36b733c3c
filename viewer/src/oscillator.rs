//! The parameter panel's spring plot: one lattice spring as an analytic damped oscillator for
//! the current material and cell size. Spring `k = E·L` (Miyazaki eq 11); an interior node
//! carries `m = d·L³` (eq 12: eight corners share each of its eight cells); the spring's two
//! ends oscillate against each other with the reduced mass `μ = m/2`, which is also the mass
//! the solver's damper `D = 2ζ sqrt(k μ)` is defined with, so the relative stretch follows
//! `x(t) = e^{−ζωt} cos(ω_d t)` with `ω = sqrt(k/μ)` and `ω_d = ω sqrt(1 − ζ²)` (ζ < 1;
//! critically or over-damped springs decay without oscillating).

use springbake_core::material::Material;

/// A damped spring's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringOscillator {
    /// Spring constant, N/m.
    pub k: f64,
    /// Mass of the oscillating coordinate (the reduced mass of the ends), kg.
    pub mass_kg: f64,
    /// Damping ratio ζ.
    pub zeta: f64,
}

impl SpringOscillator {
    /// The spring of a lattice of cell edge `cell_size_m` in `material`.
    pub fn for_lattice(material: &Material, cell_size_m: f64) -> SpringOscillator {
        let k = material.spring_constant(cell_size_m);
        let node_mass = material.cell_mass(cell_size_m);
        SpringOscillator {
            k,
            mass_kg: 0.5 * node_mass,
            zeta: material.damping_ratio,
        }
    }

    /// Undamped angular frequency ω, rad/s.
    pub fn omega(&self) -> f64 {
        (self.k / self.mass_kg).sqrt()
    }

    /// Damped angular frequency ω_d (0 when ζ ≥ 1).
    pub fn omega_damped(&self) -> f64 {
        self.omega() * (1.0 - self.zeta * self.zeta).max(0.0).sqrt()
    }

    /// Undamped period, s.
    pub fn period(&self) -> f64 {
        std::f64::consts::TAU / self.omega()
    }

    /// Normalised displacement at time `t` after releasing the spring stretched by 1.
    pub fn displacement(&self, t: f64) -> f64 {
        let w = self.omega();
        let z = self.zeta;
        if z < 1.0 {
            (-z * w * t).exp() * (self.omega_damped() * t).cos()
        } else {
            // Critical (and, as an envelope, over-) damping: (1 + ωt) e^{−ωt}.
            (1.0 + w * t) * (-w * t).exp()
        }
    }

    /// `n` samples `(t, x)` over `periods` undamped periods.
    pub fn samples(&self, periods: f64, n: usize) -> Vec<(f64, f64)> {
        let end = periods * self.period();
        (0..n.max(2))
            .map(|i| {
                let t = end * i as f64 / (n.max(2) - 1) as f64;
                (t, self.displacement(t))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rubber_spring_frequency_from_material_and_cell() {
        let rubber = Material::preset("rubber").unwrap();
        let s = SpringOscillator::for_lattice(&rubber, 0.01);
        // k = 1.5e6 × 0.01 = 15000 N/m; m = 1100 × 1e-6 = 1.1e-3 kg; μ = 5.5e-4 kg.
        assert!((s.k - 15000.0).abs() < 1e-9);
        assert!((s.mass_kg - 5.5e-4).abs() < 1e-15);
        assert!((s.omega() - (15000.0f64 / 5.5e-4).sqrt()).abs() < 1e-6);
        // Halving the cell doubles ω (ω² = 2E / (d L²)).
        let fine = SpringOscillator::for_lattice(&rubber, 0.005);
        assert!((fine.omega() / s.omega() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn decays_by_the_damping_ratio_each_period() {
        let s = SpringOscillator {
            k: 100.0,
            mass_kg: 1.0,
            zeta: 0.1,
        };
        assert_eq!(s.displacement(0.0), 1.0);
        let td = std::f64::consts::TAU / s.omega_damped();
        // After one damped period the cosine is back to 1: x = e^{-ζ ω T_d}.
        let expected = (-0.1 * 10.0 * td).exp();
        assert!((s.displacement(td) - expected).abs() < 1e-12);
        // A quarter damped period is a zero crossing.
        assert!(s.displacement(td / 4.0).abs() < 1e-12);
        let samples = s.samples(3.0, 301);
        assert_eq!(samples.len(), 301);
        assert!((samples[300].0 - 3.0 * s.period()).abs() < 1e-12);
    }

    #[test]
    fn critical_damping_never_crosses_zero() {
        let s = SpringOscillator {
            k: 100.0,
            mass_kg: 1.0,
            zeta: 1.0,
        };
        assert!(s
            .samples(5.0, 200)
            .iter()
            .all(|&(_, x)| x > 0.0 && x <= 1.0));
        assert_eq!(s.omega_damped(), 0.0);
    }
}
