//! Contact laws as pure functions of pair kinematics and parameters: no particle arrays, no loops,
//! no rayon. `forces` calls them for every pair (`forces/lanes.rs`); tests call them directly.
//!
//! # Conventions
//! * `n_ij` is the unit vector from the centre of i to the centre of j (paper, after eq. 15).
//! * The overlap `δ = r_i + r_j − |x_j − x_i|` is positive in contact; the overlap rate
//!   `δ̇ = (v_i − v_j)·n_ij` is positive while the spheres approach.
//! * A scalar normal force `F` is **positive when repulsive**; the force on i is `−F n_ij` and the
//!   force on j is `+F n_ij`. The paper's "`f_i·n_ij > 0`" (attractive) is `F < 0` here.
//! * SI units everywhere.
//!
//! # Inlining
//! The laws the vector kernels run (`forces/lanes.rs`, `forces/wall_lanes.rs`) are
//! `#[inline(always)]`: a law the compiler leaves out of line is built for the baseline and
//! called lane by lane from the AVX2 and AVX-512 builds (`simd::Kernel`). `contact::normal_force`
//! was, from every kernel with bond laws; a throw-away build with three laws out of line ran the
//! LIGGGHTS bed's step at 0.30 times its speed (docs/performance-log.md, thirty-eighth round). CI's
//! `scripts/check_kernels.py` finds such calls in the release binary.

pub mod bond;
pub mod damping;
pub mod hertz;
pub mod rolling;
pub mod tangential;

pub use bond::BondParams;

/// Per material pair parameters of the normal contact law (resolved once from the scene).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalParams {
    /// Effective Young's modulus E* \[Pa\] (paper eq. 12).
    pub effective_modulus: f64,
    /// Contact damping ratio ξ_con of the Hertz branch (paper eq. 26), `≥ 0`.
    pub damping_ratio: f64,
    /// The bonded branch, if the scene has a `[bond]` section.
    pub bond: Option<BondParams>,
}

/// Parameters of the tangential and rolling laws of one material pair (or material and wall),
/// for scenes with `contact.friction_coefficient` or `contact.rolling_friction_coefficient`.
/// The default is all zero: no tangential force, no rolling resistance.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrictionParams {
    /// Effective shear modulus G* \[Pa\] (M.56).
    pub effective_shear_modulus: f64,
    /// Sliding friction coefficient μ [–] (Coulomb limit, M.59); 0 switches the tangential
    /// force off.
    pub sliding: f64,
    /// Rolling friction coefficient μ_r [–] (M.61); 0 switches rolling resistance off.
    pub rolling: f64,
}

/// Kinematics of one pair at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairKinematics {
    /// Overlap δ \[m\], positive in contact.
    pub overlap: f64,
    /// Overlap rate δ̇ [m/s], positive while approaching.
    pub overlap_rate: f64,
    /// Effective radius r* \[m\] (paper eq. 12).
    pub effective_radius: f64,
    /// Effective mass m* \[kg\] (paper eq. 11).
    pub effective_mass: f64,
}

/// Persistent per-pair state: whether the pair is bonded. Keyed by the two particle ids in
/// `neighbor::NeighborList`, so it survives neighbour-list rebuilds and particle reordering.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BondState {
    /// Hertz branch of paper eq. 25.
    #[default]
    Unbonded,
    /// Bonded (adhesive) branch of paper eq. 25.
    Bonded,
}

/// Which branch of paper eq. 25 produced a force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// No overlap: no force.
    Separated,
    /// Hertz + contact damping (eq. 26).
    Hertz,
    /// Bonded elastic force (eq. 15) + bond damping (eqs. 22-24).
    Bonded,
}

/// Result of the normal law for one pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalForce {
    /// Total normal force \[N\], positive when repulsive.
    pub force: f64,
    /// Its elastic (conservative) part \[N\]: `force − elastic` is what the damper and the sign
    /// rules contributed, and `(force − elastic) δ̇` the power they dissipate (M.34).
    pub elastic: f64,
    /// Bond state after this evaluation.
    pub state: BondState,
    /// Branch that produced `force`.
    pub branch: Branch,
}

/// The normal force of the bond model, paper eq. 25 with the sign rules stated after eq. 26
/// (M.23 in docs/model.md). `criterion_met` is the bond criterion for this pair (always, never,
/// or later temperature-based); the law itself does not care where it comes from.
///
/// * Unbonded (Hertz branch): `F = (4/3)E*√r* δ^{3/2} + d_con δ̇`, and `F = 0` if that would
///   attract (`F < 0`): damping never pulls (sign rule 1).
/// * Bonded: `F = (4/3)E*√r* δ^{3/2} − k_adh δ^α + d* δ̇` with `d* = 2ξ_bond√(m* k*)`; if
///   `δ > δ_eq` and `F < 0`, then `F = 0` (sign rule 2); if `δ < δ_eq` and `F > 0`, then `F = 0`
///   (sign rule 3). The total bond force thus always points back towards δ_eq.
///
/// State changes follow [`bond::forms`] and [`bond::holds`]: formation when the criterion holds
/// and `δ ≥ δ_crit`; a bond stays while `δ ≥ δ_crit` whatever the criterion; it breaks below.
#[inline(always)]
#[must_use]
pub fn normal_force(
    params: &NormalParams,
    kin: &PairKinematics,
    state: BondState,
    criterion_met: bool,
) -> NormalForce {
    let overlap = kin.overlap;
    if overlap <= 0.0 {
        return NormalForce {
            force: 0.0,
            elastic: 0.0,
            state: BondState::Unbonded,
            branch: Branch::Separated,
        };
    }
    let e_star = params.effective_modulus;
    let r_star = kin.effective_radius;
    if let Some(bond) = &params.bond {
        // δ_crit costs a powf: only computed when the pair is bonded or may bond.
        let bonded = match state {
            BondState::Bonded => bond::holds(overlap, bond.critical_overlap(e_star, r_star)),
            BondState::Unbonded => {
                criterion_met && bond::forms(true, overlap, bond.critical_overlap(e_star, r_star))
            }
        };
        if bonded {
            let (force, elastic) = bonded_parts(bond, e_star, kin);
            return NormalForce {
                force,
                elastic,
                state: BondState::Bonded,
                branch: Branch::Bonded,
            };
        }
    }
    let (force, elastic) = hertz_parts(e_star, params.damping_ratio, kin);
    NormalForce {
        force,
        elastic,
        state: BondState::Unbonded,
        branch: Branch::Hertz,
    }
}

/// Hertz branch of paper eq. 25 (M.24): `F = max(0, (4/3)E*√r* δ^{3/2} + d_con δ̇)` \[N\], with d_con
/// from eq. 26 as corrected ([`damping::contact_coefficient`]). Also the particle–wall law.
#[must_use]
pub fn hertz_force(effective_modulus: f64, damping_ratio: f64, kin: &PairKinematics) -> f64 {
    hertz_parts(effective_modulus, damping_ratio, kin).0
}

/// [`hertz_force`] and its elastic part `(total, elastic)` \[N\].
#[inline(always)]
#[must_use]
pub fn hertz_parts(effective_modulus: f64, damping_ratio: f64, kin: &PairKinematics) -> (f64, f64) {
    let elastic = hertz::elastic_force(effective_modulus, kin.effective_radius, kin.overlap);
    let damping = damping::contact_coefficient(
        damping_ratio,
        effective_modulus,
        kin.effective_radius,
        kin.effective_mass,
        kin.overlap,
    );
    // Sign rule 1 (after paper eq. 26): a contact without a bond never attracts.
    ((elastic + damping * kin.overlap_rate).max(0.0), elastic)
}

/// Bonded branch of paper eq. 25 (M.25): eq. 15 plus the damper of eqs. 22-24, clipped by sign
/// rules 2 and 3 so that it never pushes away from δ_eq \[N\].
#[must_use]
pub fn bonded_force(bond: &BondParams, effective_modulus: f64, kin: &PairKinematics) -> f64 {
    bonded_parts(bond, effective_modulus, kin).0
}

/// [`bonded_force`] and its elastic part `(total, elastic)` \[N\].
#[inline(always)]
#[must_use]
pub fn bonded_parts(bond: &BondParams, effective_modulus: f64, kin: &PairKinematics) -> (f64, f64) {
    let (r_star, overlap) = (kin.effective_radius, kin.overlap);
    let elastic = bond.elastic_force(effective_modulus, r_star, overlap);
    let stiffness = bond.stiffness(effective_modulus, r_star, overlap);
    let damping = damping::bond_coefficient(bond.damping_ratio, kin.effective_mass, stiffness);
    let total = elastic + damping * kin.overlap_rate;
    let equilibrium = bond.equilibrium_overlap(effective_modulus, r_star);
    if (overlap > equilibrium && total < 0.0) || (overlap < equilibrium && total > 0.0) {
        (0.0, elastic)
    } else {
        (total, elastic)
    }
}
