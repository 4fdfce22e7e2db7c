//! Per-particle exchange with the surroundings: convection to a gas and radiation to an enclosure.
//! Per particle, never per contact. Positive values heat the particle \[W\].

/// Stefan–Boltzmann constant σ [W/(m²·K⁴)] (CODATA 2018, exact in the SI since 2019).
pub const STEFAN_BOLTZMANN: f64 = 5.670_374_419e-8;

/// Surface area of a sphere `A = 4 π r²` \[m²\]; the lumped models use the whole surface.
#[must_use]
#[inline]
pub fn sphere_area(radius: f64) -> f64 {
    4.0 * std::f64::consts::PI * radius * radius
}

/// Newton convection (M.44): `Q = h A (T_gas − T)` \[W\].
#[must_use]
#[inline]
pub fn convection(coefficient: f64, area: f64, temperature: f64, gas_temperature: f64) -> f64 {
    coefficient * area * (gas_temperature - temperature)
}

/// Grey-body radiation to surroundings at `T_env` (M.45): `Q = ε σ A (T_env⁴ − T⁴)` \[W\].
#[must_use]
#[inline]
pub fn radiation(emissivity: f64, area: f64, temperature: f64, environment: f64) -> f64 {
    emissivity * STEFAN_BOLTZMANN * area * (environment.powi(4) - temperature.powi(4))
}

/// Largest `|dQ/dT|` of radiation up to temperature `T` (M.46): `4 ε σ A max(T, T_env)³` [W/K];
/// the stiffness the time integrator must resolve.
#[must_use]
#[inline]
pub fn radiation_conductance(
    emissivity: f64,
    area: f64,
    temperature: f64,
    environment: f64,
) -> f64 {
    4.0 * emissivity * STEFAN_BOLTZMANN * area * temperature.max(environment).powi(3)
}
