//! Hertz contact of two elastic spheres (or a sphere and a plane): effective properties, the
//! repulsive elastic force and its closed-form impact results.
//!
//! Conventions (shared by all of `contact`): the overlap `δ = r_i + r_j − |x_j − x_i|` is positive
//! in contact; a scalar normal force is **positive when repulsive**. SI units throughout.
//! Equation numbers `(M.x)` refer to `docs/model.md`, `paper eq. N` to Quintana-Ruiz & Campello (2020).

/// Effective radius of two spheres, paper eq. 12 (M.1): `r* = r_i r_j / (r_i + r_j)` \[m\].
///
/// For a sphere against a plane use `r* = r_i` directly (the limit `r_j → ∞`).
#[inline(always)]
#[must_use]
pub fn effective_radius(radius_i: f64, radius_j: f64) -> f64 {
    radius_i * radius_j / (radius_i + radius_j)
}

/// Effective (reduced) mass, paper eq. 11 (M.2): `m* = m_i m_j / (m_i + m_j)` \[kg\].
///
/// For a sphere against a fixed plane use `m* = m_i` (the limit `m_j → ∞`).
#[inline(always)]
#[must_use]
pub fn effective_mass(mass_i: f64, mass_j: f64) -> f64 {
    mass_i * mass_j / (mass_i + mass_j)
}

/// Effective Young's modulus, paper eq. 12 (M.3):
///
/// ```text
/// E* = E_i E_j / (E_j (1 − ν_i²) + E_i (1 − ν_j²))      [Pa]
/// ```
#[must_use]
pub fn effective_modulus(youngs_i: f64, poisson_i: f64, youngs_j: f64, poisson_j: f64) -> f64 {
    youngs_i * youngs_j
        / (youngs_j * (1.0 - poisson_i * poisson_i) + youngs_i * (1.0 - poisson_j * poisson_j))
}

/// Hertz elastic force magnitude (repulsive), paper eqs. 12 and 15 (M.4):
///
/// ```text
/// F_hertz = (4/3) E* √r* δ^{3/2}      [N],   0 for δ ≤ 0
/// ```
#[inline(always)]
#[must_use]
pub fn elastic_force(effective_modulus: f64, effective_radius: f64, overlap: f64) -> f64 {
    if overlap <= 0.0 {
        return 0.0;
    }
    4.0 / 3.0 * effective_modulus * (effective_radius * overlap).sqrt() * overlap
}

/// Tangent stiffness of the Hertz force, the first term of paper eq. 24 (M.5):
///
/// ```text
/// k_hertz(δ) = dF_hertz/dδ = 2 E* √(r* δ)      [N/m],   0 for δ ≤ 0
/// ```
#[inline(always)]
#[must_use]
pub fn stiffness(effective_modulus: f64, effective_radius: f64, overlap: f64) -> f64 {
    if overlap <= 0.0 {
        return 0.0;
    }
    2.0 * effective_modulus * (effective_radius * overlap).sqrt()
}

/// Elastic energy stored in a Hertz contact (M.6): `U = (8/15) E* √r* δ^{5/2}` \[J\], the integral
/// of [`elastic_force`] over δ.
#[inline(always)]
#[must_use]
pub fn elastic_energy(effective_modulus: f64, effective_radius: f64, overlap: f64) -> f64 {
    if overlap <= 0.0 {
        return 0.0;
    }
    8.0 / 15.0 * effective_modulus * effective_radius.sqrt() * overlap * overlap * overlap.sqrt()
}

/// Largest overlap of an undamped Hertz impact at approach speed `v`, paper eq. 20 (M.7):
///
/// ```text
/// δ_max = (15 m* v² / (16 E* √r*))^{2/5}      [m]
/// ```
#[must_use]
pub fn max_overlap(
    effective_mass: f64,
    effective_modulus: f64,
    effective_radius: f64,
    speed: f64,
) -> f64 {
    (15.0 * effective_mass * speed * speed / (16.0 * effective_modulus * effective_radius.sqrt()))
        .powf(0.4)
}

/// Duration of an undamped Hertz impact at approach speed `v` (M.8):
///
/// ```text
/// t_c = 2.8682657 (m*² / (E*² r* v))^{1/5}      [s]
/// ```
///
/// The constant is `2 (15/16)^{2/5} ∫₀¹ dx/√(1 − x^{5/2})` (Johnson 1985, §11.4), with the integral
/// `B(2/5, 1/2) / (5/2)` = 1.4716376; it is given to full precision, since the convergence study
/// (`am-sim study`) resolves contact times to 1e-7, where a 7-digit constant would show.
#[must_use]
pub fn contact_time(
    effective_mass: f64,
    effective_modulus: f64,
    effective_radius: f64,
    speed: f64,
) -> f64 {
    2.868_265_699_195_33
        * (effective_mass * effective_mass
            / (effective_modulus * effective_modulus * effective_radius * speed))
            .powf(0.2)
}

/// Rayleigh-wave time of a sphere (M.9), the usual DEM time-step scale:
///
/// ```text
/// t_R = π r √(ρ/G) / (0.1631 ν + 0.8766),   G = E / (2 (1 + ν))      [s]
/// ```
#[must_use]
pub fn rayleigh_time(radius: f64, density: f64, youngs: f64, poisson: f64) -> f64 {
    let shear_modulus = youngs / (2.0 * (1.0 + poisson));
    std::f64::consts::PI * radius * (density / shear_modulus).sqrt() / (0.1631 * poisson + 0.8766)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effective_modulus_of_equal_materials_with_zero_poisson_is_half() {
        assert_eq!(effective_modulus(1e9, 0.0, 1e9, 0.0), 5e8);
        // ν = 0.3 on both sides: E/(2(1-ν²))
        let e = effective_modulus(2e8, 0.3, 2e8, 0.3);
        assert!((e - 2e8 / (2.0 * 0.91)).abs() < 1e-6 * e);
    }

    #[test]
    fn stiffness_and_energy_are_derivative_and_integral_of_the_force() {
        let (e, r, d) = (5e8, 5e-4, 3e-5);
        let h = d * 1e-5; // central difference: error O(h²) ≈ 1e-10 relative
        let fd_stiff = (elastic_force(e, r, d + h) - elastic_force(e, r, d - h)) / (2.0 * h);
        assert!((fd_stiff / stiffness(e, r, d) - 1.0).abs() < 1e-8);
        let fd_force = (elastic_energy(e, r, d + h) - elastic_energy(e, r, d - h)) / (2.0 * h);
        assert!((fd_force / elastic_force(e, r, d) - 1.0).abs() < 1e-8);
    }

    #[test]
    fn no_force_without_overlap() {
        assert_eq!(elastic_force(1e9, 1e-3, 0.0), 0.0);
        assert_eq!(elastic_force(1e9, 1e-3, -1e-6), 0.0);
        assert_eq!(stiffness(1e9, 1e-3, -1e-6), 0.0);
    }

    #[test]
    fn max_overlap_balances_kinetic_and_elastic_energy() {
        let (m, e, r, v) = (4.2e-6, 5e8, 5e-4, 2.6);
        let d = max_overlap(m, e, r, v);
        let ratio = elastic_energy(e, r, d) / (0.5 * m * v * v);
        assert!((ratio - 1.0).abs() < 1e-12, "{ratio}");
    }
}
