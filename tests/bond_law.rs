//! The bond trigger and every branch and sign rule of paper eq. 25 (and the rules after eq. 26),
//! on the pure force function: no particles, no loop. Forces are positive when repulsive.

use am_sim::contact::{
    BondParams, BondState, Branch, NormalParams, PairKinematics, bond, hertz, normal_force,
};

const E_STAR: f64 = 0.5e9;
const R_STAR: f64 = 0.5e-3;
const M_STAR: f64 = 4.188_790_2e-6;

fn params(alpha: f64, k_adh: f64, xi_bond: f64, xi_con: f64) -> NormalParams {
    NormalParams {
        effective_modulus: E_STAR,
        damping_ratio: xi_con,
        bond: Some(BondParams {
            adhesion_exponent: alpha,
            adhesion_stiffness: k_adh,
            damping_ratio: xi_bond,
        }),
    }
}

/// The paper's example 5.1 bond: α = 1, δ_eq = 50 µm.
fn paper(xi_bond: f64, xi_con: f64) -> NormalParams {
    params(
        1.0,
        bond::adhesion_stiffness_for_equilibrium(E_STAR, R_STAR, 1.0, 5e-5),
        xi_bond,
        xi_con,
    )
}

fn kin(overlap: f64, overlap_rate: f64) -> PairKinematics {
    PairKinematics {
        overlap,
        overlap_rate,
        effective_radius: R_STAR,
        effective_mass: M_STAR,
    }
}

fn crit(p: &NormalParams) -> f64 {
    p.bond.unwrap().critical_overlap(E_STAR, R_STAR)
}

fn eq(p: &NormalParams) -> f64 {
    p.bond.unwrap().equilibrium_overlap(E_STAR, R_STAR)
}

#[test]
fn cold_pair_beyond_critical_overlap_stays_hertz() {
    let p = paper(0.5, 0.0);
    let out = normal_force(&p, &kin(2.0 * crit(&p), 0.0), BondState::Unbonded, false);
    assert_eq!(
        (out.state, out.branch),
        (BondState::Unbonded, Branch::Hertz)
    );
    assert_eq!(
        out.force,
        hertz::elastic_force(E_STAR, R_STAR, 2.0 * crit(&p))
    );
}

#[test]
fn pair_meeting_the_criterion_below_critical_overlap_stays_hertz() {
    let p = paper(0.5, 0.0);
    let out = normal_force(&p, &kin(0.9 * crit(&p), 0.0), BondState::Unbonded, true);
    assert_eq!(
        (out.state, out.branch),
        (BondState::Unbonded, Branch::Hertz)
    );
    assert!(out.force > 0.0);
}

#[test]
fn pair_meeting_the_criterion_at_critical_overlap_bonds() {
    let p = paper(0.5, 0.0);
    for overlap in [crit(&p), 1.0001 * crit(&p), 0.9 * eq(&p), 2.0 * eq(&p)] {
        let out = normal_force(&p, &kin(overlap, 0.0), BondState::Unbonded, true);
        assert_eq!(
            (out.state, out.branch),
            (BondState::Bonded, Branch::Bonded),
            "δ = {overlap}"
        );
        let b = p.bond.unwrap();
        assert!(
            (out.force - b.elastic_force(E_STAR, R_STAR, overlap)).abs()
                <= 1e-12 * b.adhesion_force(overlap)
        );
    }
}

#[test]
fn without_a_bond_section_the_criterion_changes_nothing() {
    let p = NormalParams {
        bond: None,
        ..paper(0.5, 0.2)
    };
    let k = kin(3e-5, 0.1);
    let met = normal_force(&p, &k, BondState::Unbonded, true);
    assert_eq!(met, normal_force(&p, &k, BondState::Unbonded, false));
    assert_eq!(met.branch, Branch::Hertz);
}

#[test]
fn hertz_branch_adds_eq_26_damping_and_never_attracts() {
    let p = paper(0.5, 0.3);
    let overlap = 1e-5; // below δ_crit: Hertz branch even with the criterion
    let elastic = hertz::elastic_force(E_STAR, R_STAR, overlap);
    let d_con = 2.0 * 0.3 * (2.0 * E_STAR * M_STAR * R_STAR.sqrt()).sqrt() * overlap.powf(0.25);
    let approaching = normal_force(&p, &kin(overlap, 0.2), BondState::Unbonded, true);
    assert!((approaching.force / (elastic + d_con * 0.2) - 1.0).abs() < 1e-12);
    // Sign rule 1: separating fast, the damper would pull; the total is clipped to zero.
    let fast_rate = -10.0 * elastic / d_con;
    assert_eq!(
        normal_force(&p, &kin(overlap, fast_rate), BondState::Unbonded, true).force,
        0.0
    );
    // Separating slowly: the damper lowers the repulsion but the total stays repulsive.
    let slow = normal_force(
        &p,
        &kin(overlap, 0.1 * fast_rate),
        BondState::Unbonded,
        true,
    )
    .force;
    assert!(slow > 0.0 && slow < elastic);
}

#[test]
fn bonded_branch_sign_rules_keep_the_force_restoring() {
    let p = paper(1.0, 0.0);
    let b = p.bond.unwrap();
    let (crit, eq) = (crit(&p), eq(&p));
    // Undamped statics: repulsive above δ_eq, attractive between δ_crit and δ_eq, zero at δ_eq.
    assert!(normal_force(&p, &kin(1.5 * eq, 0.0), BondState::Bonded, false).force > 0.0);
    assert!(normal_force(&p, &kin(0.5 * (crit + eq), 0.0), BondState::Bonded, false).force < 0.0);
    assert!(b.elastic_force(E_STAR, R_STAR, eq).abs() < 1e-9 * b.adhesion_force(eq));
    // Sign rule 2: δ > δ_eq, pulled apart fast: the damper would make it attractive → zero.
    let above = normal_force(&p, &kin(1.2 * eq, -50.0), BondState::Bonded, false);
    assert_eq!((above.force, above.state), (0.0, BondState::Bonded));
    // Sign rule 3: δ_crit < δ < δ_eq, pushed together fast: the damper would make it repulsive → zero.
    let below = normal_force(&p, &kin(0.8 * eq, 50.0), BondState::Bonded, false);
    assert_eq!((below.force, below.state), (0.0, BondState::Bonded));
    // Slow motion keeps the sign of the elastic force, with the eq. 23 damper added.
    let overlap = 1.2 * eq;
    let k_star = b.stiffness(E_STAR, R_STAR, overlap);
    let d_star = 2.0 * 1.0 * (M_STAR * k_star).sqrt();
    let rate = -0.001;
    let slow = normal_force(&p, &kin(overlap, rate), BondState::Bonded, false).force;
    assert!(
        (slow - (b.elastic_force(E_STAR, R_STAR, overlap) + d_star * rate)).abs()
            < 1e-12 * slow.abs().max(1e-9)
    );
    assert!(slow > 0.0);
}

#[test]
fn bond_is_latched_while_the_overlap_stays_above_critical() {
    let p = paper(0.5, 0.0);
    // Criterion no longer met (the neck cooled): the pair stays bonded.
    let out = normal_force(&p, &kin(1.01 * crit(&p), 0.0), BondState::Bonded, false);
    assert_eq!((out.state, out.branch), (BondState::Bonded, Branch::Bonded));
    assert!(out.force < 0.0, "bonded below δ_eq attracts");
}

#[test]
fn bond_breaks_below_the_critical_overlap_and_the_hertz_branch_returns() {
    let p = paper(0.5, 0.0);
    for criterion in [true, false] {
        let out = normal_force(
            &p,
            &kin(0.99 * crit(&p), -0.01),
            BondState::Bonded,
            criterion,
        );
        assert_eq!(
            (out.state, out.branch),
            (BondState::Unbonded, Branch::Hertz)
        );
        assert!(out.force >= 0.0, "no attraction after the break");
    }
    let apart = normal_force(&p, &kin(-1e-7, -0.01), BondState::Bonded, true);
    assert_eq!(
        (apart.state, apart.branch, apart.force),
        (BondState::Unbonded, Branch::Separated, 0.0)
    );
}

#[test]
fn critical_overlap_is_where_the_bond_is_strongest() {
    let p = paper(0.0, 0.0);
    let b = p.bond.unwrap();
    let crit = crit(&p);
    // k* = 0 at δ_crit, negative below, positive above (paper eq. 24).
    assert!(
        b.stiffness(E_STAR, R_STAR, crit).abs() < 1e-9 * hertz::stiffness(E_STAR, R_STAR, crit)
    );
    assert!(b.stiffness(E_STAR, R_STAR, 0.9 * crit) < 0.0);
    assert!(b.stiffness(E_STAR, R_STAR, 1.1 * crit) > 0.0);
    // ... so the attraction −F_el has its maximum there: the bond strength.
    let strength = b.strength(E_STAR, R_STAR);
    for f in [0.5, 0.9, 0.99, 1.01, 1.1, 2.0] {
        assert!(
            -b.elastic_force(E_STAR, R_STAR, f * crit) < strength,
            "factor {f}"
        );
    }
}

#[test]
fn stiffness_and_energy_are_consistent_with_the_force() {
    for alpha in [0.0, 0.5, 1.0, 1.3] {
        let b = BondParams {
            adhesion_exponent: alpha,
            adhesion_stiffness: 1e5,
            damping_ratio: 0.0,
        };
        let d = 3e-5;
        let h = 1e-10; // central differences, error O(h²/d²) ≈ 1e-11
        let dfdd = (b.elastic_force(E_STAR, R_STAR, d + h)
            - b.elastic_force(E_STAR, R_STAR, d - h))
            / (2.0 * h);
        assert!(
            (dfdd / b.stiffness(E_STAR, R_STAR, d) - 1.0).abs() < 1e-5,
            "α = {alpha}: k*"
        );
        let dude = (b.elastic_energy(E_STAR, R_STAR, d + h)
            - b.elastic_energy(E_STAR, R_STAR, d - h))
            / (2.0 * h);
        assert!(
            (dude / b.elastic_force(E_STAR, R_STAR, d) - 1.0).abs() < 1e-4,
            "α = {alpha}: U"
        );
    }
}

#[test]
fn strains_of_eq_19_match_the_overlaps_of_eqs_13_and_14() {
    for alpha in [0.0, 0.7, 1.0, 1.4] {
        let b = BondParams {
            adhesion_exponent: alpha,
            adhesion_stiffness: 2e4,
            damping_ratio: 0.0,
        };
        let (eq, crit) = (
            b.equilibrium_overlap(E_STAR, R_STAR),
            b.critical_overlap(E_STAR, R_STAR),
        );
        assert!(
            (b.equilibrium_strain(E_STAR, R_STAR) * R_STAR / eq - 1.0).abs() < 1e-10,
            "α = {alpha}"
        );
        if crit > 0.0 {
            assert!(
                (b.critical_strain(E_STAR, R_STAR) * R_STAR / crit - 1.0).abs() < 1e-10,
                "α = {alpha}"
            );
        }
    }
}

#[test]
fn alpha_zero_is_a_constant_adhesion_that_bonds_on_contact() {
    let k_adh = bond::adhesion_stiffness_for_equilibrium(E_STAR, R_STAR, 0.0, 5e-5);
    let p = params(0.0, k_adh, 0.5, 0.0);
    let b = p.bond.unwrap();
    assert_eq!(b.critical_overlap(E_STAR, R_STAR), 0.0);
    assert_eq!(b.critical_velocity(E_STAR, R_STAR, M_STAR), 0.0);
    assert!((b.equilibrium_overlap(E_STAR, R_STAR) / 5e-5 - 1.0).abs() < 1e-12);
    assert_eq!(b.adhesion_force(1e-9), k_adh);
    // The stiffness has no adhesion term (0 · δ^{-1} must not become NaN).
    assert_eq!(
        b.stiffness(E_STAR, R_STAR, 1e-9),
        hertz::stiffness(E_STAR, R_STAR, 1e-9)
    );
    let touch = normal_force(&p, &kin(1e-12, 1.0), BondState::Unbonded, true);
    assert_eq!(touch.state, BondState::Bonded);
    assert!(touch.force.is_finite());
}

#[test]
fn alpha_close_to_three_halves_stays_finite_and_consistent() {
    for alpha in [1.45, 1.49, 1.4999] {
        let k_adh = bond::adhesion_stiffness_for_equilibrium(E_STAR, R_STAR, alpha, 5e-5);
        let p = params(alpha, k_adh, 1.0, 0.0);
        let b = p.bond.unwrap();
        let eq = b.equilibrium_overlap(E_STAR, R_STAR);
        // The exponent 1/(3/2 − α) reaches 1e4, amplifying round-off in the base by as much.
        assert!((eq / 5e-5 - 1.0).abs() < 1e-9, "α = {alpha}: δ_eq = {eq}");
        // δ_crit/δ_eq = (2α/3)^{1/(3/2 − α)} → e^{−2/3} as α → 3/2.
        let ratio = b.critical_overlap(E_STAR, R_STAR) / eq;
        let expected = (2.0 * alpha / 3.0).powf(1.0 / (1.5 - alpha));
        assert!(
            (ratio / expected - 1.0).abs() < 1e-9 && ratio > 0.5 && ratio < 0.6,
            "α = {alpha}: {ratio}"
        );
        for overlap in [0.6 * eq, eq, 2.0 * eq] {
            let out = normal_force(&p, &kin(overlap, 0.3), BondState::Bonded, true);
            assert!(out.force.is_finite(), "α = {alpha}, δ = {overlap}");
        }
        assert!(b.critical_velocity(E_STAR, R_STAR, M_STAR).is_finite());
    }
}

#[test]
fn zero_adhesion_stiffness_bonds_without_attraction() {
    let p = params(1.0, 0.0, 0.5, 0.0);
    let b = p.bond.unwrap();
    assert_eq!(b.equilibrium_overlap(E_STAR, R_STAR), 0.0);
    assert_eq!(b.critical_overlap(E_STAR, R_STAR), 0.0);
    assert_eq!(b.strength(E_STAR, R_STAR), 0.0);
    let overlap = 2e-5;
    let out = normal_force(&p, &kin(overlap, 0.0), BondState::Unbonded, true);
    assert_eq!(out.state, BondState::Bonded);
    assert!((out.force / hertz::elastic_force(E_STAR, R_STAR, overlap) - 1.0).abs() < 1e-12);
    // δ > δ_eq = 0 always, so sign rule 2 forbids any attraction.
    assert_eq!(
        normal_force(&p, &kin(overlap, -1e3), BondState::Bonded, true).force,
        0.0
    );
}

#[test]
fn guarded_bond_damping_gives_no_nan_below_critical_overlap() {
    // k* < 0 below δ_crit; a bonded pair evaluated there breaks, but the damper itself must stay finite.
    let b = paper(1.0, 0.0).bond.unwrap();
    let k = b.stiffness(E_STAR, R_STAR, 0.5 * b.critical_overlap(E_STAR, R_STAR));
    assert!(k < 0.0);
    assert_eq!(
        am_sim::contact::damping::bond_coefficient(1.0, M_STAR, k),
        0.0
    );
}

#[test]
fn strength_of_a_constant_adhesion_is_its_stiffness() {
    // α = 0: the attraction k_adh − F_hertz(δ) is largest as δ → 0⁺, where it is k_adh.
    let b = params(0.0, 0.3, 0.0, 0.0).bond.unwrap();
    assert_eq!(b.strength(E_STAR, R_STAR), 0.3);
}
