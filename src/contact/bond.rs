//! The adhesive bond of Quintana-Ruiz & Campello (2020), paper eqs. 13-25: Hertz repulsion plus a
//! power-law adhesion `k_adh δ^α_adh`, its equilibrium and critical overlaps, the critical impact
//! velocity, and the rules that make and break a bond.
//!
//! Signs: forces here are scalar magnitudes along the normal, **positive when repulsive**
//! (the paper's `f·n_ij < 0`). SI units: `k_adh` is in N·m^(−α_adh).
//!
//! # Bond rules (docs/model.md, section "Bond rules")
//! * **Formation** (paper eq. 25): an unbonded pair bonds when the bond criterion holds and
//!   `δ ≥ δ_crit` (and `δ > 0`). The criterion is evaluated outside the force law
//!   (`crate::model::BondCriterion`) and arrives here as a `bool`.
//! * **Persistence**: a formed bond is latched: it stays when the criterion stops holding (a melt
//!   neck that solidified).
//! * **Breakage**: the bond breaks when `δ < δ_crit` (or `δ ≤ 0`). δ_crit is where the bonded
//!   force has zero tangent stiffness (`k* = 0`, paper eq. 24), i.e. where the attraction is at its
//!   largest: a pull beyond it has no stable equilibrium (paper eq. 10, "δ ≥ δ_crit is mandatory for
//!   an ever-stable contact-adhesion interaction"), so the bond strength is
//!   `F_max = k_adh δ_crit^α − (4/3)E*√r* δ_crit^{3/2}`. Below δ_crit the Hertz branch of eq. 25
//!   applies again; the pair may bond anew only if the criterion holds again.

use super::hertz;

/// Parameters of the bonded (adhesive) branch, one set per material pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BondParams {
    /// Adhesion exponent α_adh, `0 ≤ α_adh < 3/2` (paper eq. 9: stability needs α_adh < 3/2).
    pub adhesion_exponent: f64,
    /// Adhesion stiffness k_adh [N·m^(−α_adh)], `≥ 0`.
    pub adhesion_stiffness: f64,
    /// Bond damping ratio ξ_bond (paper eq. 23), `≥ 0`.
    pub damping_ratio: f64,
}

impl BondParams {
    /// Adhesion force magnitude (attractive) `k_adh δ^α_adh` \[N\], the second term of paper eq. 15 (M.12).
    #[inline(always)]
    #[must_use]
    pub fn adhesion_force(&self, overlap: f64) -> f64 {
        if overlap <= 0.0 {
            return 0.0;
        }
        self.adhesion_stiffness * overlap.powf(self.adhesion_exponent)
    }

    /// Elastic force of the bonded branch, paper eq. 15 (M.12), positive when repulsive \[N\]:
    ///
    /// ```text
    /// F_el = (4/3) E* √r* δ^{3/2} − k_adh δ^α_adh
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn elastic_force(
        &self,
        effective_modulus: f64,
        effective_radius: f64,
        overlap: f64,
    ) -> f64 {
        hertz::elastic_force(effective_modulus, effective_radius, overlap)
            - self.adhesion_force(overlap)
    }

    /// Tangent stiffness of the bonded branch, paper eq. 24 (M.13) [N/m]:
    ///
    /// ```text
    /// k* = dF_el/dδ (F_el positive when repulsive; the paper writes −d/dδ of the attraction)
    ///    = 2 E* √r* δ^{1/2} − α_adh k_adh δ^{α_adh − 1}
    /// ```
    ///
    /// Negative for `δ < δ_crit`. The α_adh = 0 case has no second term (it would be `0 · δ^{−1}`).
    #[inline(always)]
    #[must_use]
    pub fn stiffness(&self, effective_modulus: f64, effective_radius: f64, overlap: f64) -> f64 {
        let adhesion = if self.adhesion_exponent == 0.0 || self.adhesion_stiffness == 0.0 {
            0.0
        } else {
            self.adhesion_exponent
                * self.adhesion_stiffness
                * overlap.powf(self.adhesion_exponent - 1.0)
        };
        hertz::stiffness(effective_modulus, effective_radius, overlap) - adhesion
    }

    /// Energy stored in the bonded spring relative to δ = 0 \[J\] (M.15):
    /// `U = (8/15) E* √r* δ^{5/2} − k_adh δ^{α+1}/(α+1)`.
    #[inline(always)]
    #[must_use]
    pub fn elastic_energy(
        &self,
        effective_modulus: f64,
        effective_radius: f64,
        overlap: f64,
    ) -> f64 {
        if overlap <= 0.0 {
            return 0.0;
        }
        let a = self.adhesion_exponent + 1.0;
        hertz::elastic_energy(effective_modulus, effective_radius, overlap)
            - self.adhesion_stiffness * overlap.powf(a) / a
    }

    /// Equilibrium overlap, paper eq. 13 (M.16) \[m\]: where the bonded elastic force vanishes,
    ///
    /// ```text
    /// δ_eq = (k_adh / ((4/3) E* √r*))^{1/(3/2 − α_adh)}
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn equilibrium_overlap(&self, effective_modulus: f64, effective_radius: f64) -> f64 {
        (self.adhesion_stiffness / (4.0 / 3.0 * effective_modulus * effective_radius.sqrt()))
            .powf(1.0 / (1.5 - self.adhesion_exponent))
    }

    /// Critical overlap, paper eq. 14 (M.17) \[m\]: where `k* = 0`, the least overlap of a stable bond,
    ///
    /// ```text
    /// δ_crit = (α_adh k_adh / (2 E* √r*))^{1/(3/2 − α_adh)}
    /// ```
    ///
    /// For α_adh = 1, `δ_crit = (2/3)² δ_eq = (4/9) δ_eq`; for α_adh = 0 or k_adh = 0 it is 0.
    #[inline(always)]
    #[must_use]
    pub fn critical_overlap(&self, effective_modulus: f64, effective_radius: f64) -> f64 {
        (self.adhesion_exponent * self.adhesion_stiffness
            / (2.0 * effective_modulus * effective_radius.sqrt()))
        .powf(1.0 / (1.5 - self.adhesion_exponent))
    }

    /// Equilibrium strain ε_eq = δ_eq / r*, paper eq. 19 (M.18), from the normalised stiffnesses
    /// of eq. 18: `k̄_con = (4/3) E* r*²`, `k̄_adh = k_adh r*^α`, `ε_eq = (k̄_adh/k̄_con)^{1/(3/2−α)}`.
    #[must_use]
    pub fn equilibrium_strain(&self, effective_modulus: f64, effective_radius: f64) -> f64 {
        let (k_con, k_adh) = self.normalised_stiffnesses(effective_modulus, effective_radius);
        (k_adh / k_con).powf(1.0 / (1.5 - self.adhesion_exponent))
    }

    /// Critical strain ε_crit = δ_crit / r*, paper eq. 19 (M.18):
    /// `ε_crit = ((2/3) α_adh k̄_adh/k̄_con)^{1/(3/2−α)}`.
    #[must_use]
    pub fn critical_strain(&self, effective_modulus: f64, effective_radius: f64) -> f64 {
        let (k_con, k_adh) = self.normalised_stiffnesses(effective_modulus, effective_radius);
        (2.0 / 3.0 * self.adhesion_exponent * k_adh / k_con)
            .powf(1.0 / (1.5 - self.adhesion_exponent))
    }

    /// `(k̄_con, k̄_adh)` of paper eq. 18 \[N\].
    fn normalised_stiffnesses(&self, effective_modulus: f64, effective_radius: f64) -> (f64, f64) {
        (
            4.0 / 3.0 * effective_modulus * effective_radius * effective_radius,
            self.adhesion_stiffness * effective_radius.powf(self.adhesion_exponent),
        )
    }

    /// Critical impact velocity, paper eq. 21 (M.19) [m/s]: the approach speed whose undamped Hertz
    /// impact (eq. 20) just reaches δ_crit,
    ///
    /// ```text
    /// v_crit = [ (16 E* √r* / (15 m*))^{2/5} (α_adh k_adh / (2 E* √r*))^{1/(3/2 − α_adh)} ]^{5/4}
    ///        = δ_crit^{5/4} √(16 E* √r* / (15 m*))
    /// ```
    ///
    /// Necessary, not sufficient, for bonding (contact damping lowers δ_max below eq. 20).
    #[must_use]
    pub fn critical_velocity(
        &self,
        effective_modulus: f64,
        effective_radius: f64,
        effective_mass: f64,
    ) -> f64 {
        let hertz_term = (16.0 * effective_modulus * effective_radius.sqrt()
            / (15.0 * effective_mass))
            .powf(0.4);
        (hertz_term * self.critical_overlap(effective_modulus, effective_radius)).powf(1.25)
    }

    /// Largest attractive force the bond carries \[N\] (its strength): `−F_el(δ_crit)`, reached at δ_crit
    /// where `k* = 0`. Zero when there is no adhesion.
    #[must_use]
    pub fn strength(&self, effective_modulus: f64, effective_radius: f64) -> f64 {
        let crit = self.critical_overlap(effective_modulus, effective_radius);
        // Written out rather than through `elastic_force`, which is 0 at δ = 0: for α_adh = 0,
        // δ_crit = 0 and the strength is the limit δ → 0⁺, i.e. k_adh (powf(0, 0) = 1).
        let attraction = self.adhesion_stiffness * crit.powf(self.adhesion_exponent);
        (attraction - hertz::elastic_force(effective_modulus, effective_radius, crit)).max(0.0)
    }

    /// Angular frequency of small oscillations of a bond about δ_eq: `ω = √(k*(δ_eq)/m*)` [rad/s].
    #[must_use]
    pub fn oscillation_frequency(
        &self,
        effective_modulus: f64,
        effective_radius: f64,
        effective_mass: f64,
    ) -> f64 {
        let eq = self.equilibrium_overlap(effective_modulus, effective_radius);
        (self
            .stiffness(effective_modulus, effective_radius, eq)
            .max(0.0)
            / effective_mass)
            .sqrt()
    }
}

/// Adhesion stiffness that puts the equilibrium at `δ_eq`, paper eq. 13 solved for k_adh (M.20),
/// as the paper does in section 5.1 [N·m^(−α_adh)]:
///
/// ```text
/// k_adh = (4/3) E* √r* δ_eq^{3/2 − α_adh}
/// ```
///
/// Example 5.1 (E* = 0.5 GPa, r* = 0.5 mm, δ_eq = 50 µm, α_adh = 1) gives 1.0541e5.
#[must_use]
pub fn adhesion_stiffness_for_equilibrium(
    effective_modulus: f64,
    effective_radius: f64,
    adhesion_exponent: f64,
    equilibrium_overlap: f64,
) -> f64 {
    4.0 / 3.0
        * effective_modulus
        * effective_radius.sqrt()
        * equilibrium_overlap.powf(1.5 - adhesion_exponent)
}

/// Formation rule, paper eq. 25 (M.21): an unbonded pair bonds when the bond criterion holds and
/// the overlap reached the critical overlap.
#[inline(always)]
#[must_use]
pub fn forms(criterion_met: bool, overlap: f64, critical_overlap: f64) -> bool {
    criterion_met && holds(overlap, critical_overlap)
}

/// Persistence rule (M.22): a bonded pair stays bonded while `δ ≥ δ_crit` and `δ > 0`; below, it
/// breaks (see the module documentation for why δ_crit is the breaking point).
#[inline(always)]
#[must_use]
pub fn holds(overlap: f64, critical_overlap: f64) -> bool {
    overlap > 0.0 && overlap >= critical_overlap
}
