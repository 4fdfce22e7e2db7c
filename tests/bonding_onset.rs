//! Onset of bonding measured by simulation (paper section 5.2): with no contact damping, the
//! smallest impact speed that makes two spheres stick is the critical velocity of eq. 21. Above it
//! the pair sticks (restitution 0), below it rebounds (restitution 1).

mod common;

use am_sim::contact::{BondParams, BondState, bond};
use common::{Bond, E_STAR, R_STAR, approach_speed, overlap, sphere_mass, two_spheres};

const DT: f64 = 5e-7; // the paper's time step, ≈ 50 steps per contact

fn paper_bond() -> Bond {
    Bond {
        adhesion_exponent: 1.0,
        adhesion_stiffness: bond::adhesion_stiffness_for_equilibrium(E_STAR, R_STAR, 1.0, 5e-5),
        damping_ratio: 1.0, // critically damped, as in section 5.2
        criterion: "always",
    }
}

fn predicted(density: f64) -> f64 {
    let b = paper_bond();
    let params = BondParams {
        adhesion_exponent: 1.0,
        adhesion_stiffness: b.adhesion_stiffness,
        damping_ratio: 1.0,
    };
    params.critical_velocity(E_STAR, R_STAR, sphere_mass(density) / 2.0)
}

/// Outcome of one impact: `Some(restitution)` if the pair separates, `None` if it sticks
/// (bonded at the end of 5 ms).
fn impact(density: f64, speed: f64) -> Option<f64> {
    let mut sim = two_spheres(density, speed, 0.0, Some(paper_bond()), DT, 5e-3);
    let mut touched = false;
    for _ in 0..sim.model.steps {
        sim.step();
        let delta = overlap(&sim);
        touched |= delta > 0.0;
        if touched && delta < 0.0 {
            return Some(-approach_speed(&sim) / speed);
        }
    }
    assert_eq!(
        sim.bond_state(0, 1),
        BondState::Bonded,
        "ρ = {density}, v = {speed}: neither separated nor bonded"
    );
    None
}

#[test]
fn bisection_finds_the_critical_velocity_of_eq_21_within_one_percent() {
    for density in [500.0, 2000.0, 8000.0] {
        let v_crit = predicted(density);
        let (mut low, mut high) = (0.5 * v_crit, 1.5 * v_crit);
        assert!(
            impact(density, low).is_some() && impact(density, high).is_none(),
            "bracket"
        );
        // 14 halvings shrink the bracket to 1/16384 of v_crit, far below the 1 % asked.
        for _ in 0..14 {
            let mid = 0.5 * (low + high);
            if impact(density, mid).is_some() {
                low = mid
            } else {
                high = mid
            }
        }
        let onset = 0.5 * (low + high);
        eprintln!(
            "ρ = {density}: onset {onset:.5} m/s, eq. 21 {v_crit:.5} m/s ({:+.3} %)",
            100.0 * (onset / v_crit - 1.0)
        );
        assert!(
            (onset / v_crit - 1.0).abs() < 1e-2,
            "ρ = {density}: onset {onset}, eq. 21 {v_crit}"
        );
    }
}

#[test]
fn above_the_onset_the_pair_sticks_below_it_rebounds_elastically() {
    for density in [500.0, 2000.0, 8000.0] {
        let v_crit = predicted(density);
        for factor in [1.02, 1.5, 3.0] {
            assert_eq!(
                impact(density, factor * v_crit),
                None,
                "ρ = {density}, v = {factor} v_crit should stick"
            );
        }
        for factor in [0.3, 0.98] {
            let e = impact(density, factor * v_crit).expect("rebound");
            // No damping in the Hertz branch: energy is conserved up to the O(dt²) Verlet error.
            assert!(
                (e - 1.0).abs() < 1e-3,
                "ρ = {density}, v = {factor} v_crit: restitution {e}"
            );
        }
    }
}
