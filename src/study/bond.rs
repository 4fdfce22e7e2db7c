//! The bond of the paper's example 5.1 (final overlap against δ_eq, eq. 23; settling time; peak
//! overlap) and the onset of bonding (the smallest sticking speed against eq. 21), against the
//! time step.

use std::time::Instant;

use super::scenes::{
    PAPER_E_STAR, PAPER_R_STAR, approach_speed, overlap, paper_sphere_mass, two_spheres,
};
use super::{Family, Reference, Series, best_of, steps, timed_steps};
use crate::contact::{BondParams, BondState, bond, hertz};

/// Density of section 5 [kg/m³].
const DENSITY: f64 = 2000.0;
/// Impact speed of example 5.1 [m/s].
const SPEED: f64 = 2.6;
/// δ_eq of example 5.1 \[m\].
const EQUILIBRIUM: f64 = 5e-5;
/// Duration of example 5.1 \[s\].
const DURATION: f64 = 5e-3;
/// The paper's time step \[s\].
const PAPER_DT: f64 = 5e-7;
/// Half-width of the band around δ_eq that defines "settled" (relative).
const BAND: f64 = 5e-3;

/// The bond of section 5 (α = 1, k_adh from δ_eq = 50 µm) with damping ratio ξ_bond.
fn paper_bond(damping_ratio: f64) -> BondParams {
    BondParams {
        adhesion_exponent: 1.0,
        adhesion_stiffness: bond::adhesion_stiffness_for_equilibrium(
            PAPER_E_STAR,
            PAPER_R_STAR,
            1.0,
            EQUILIBRIUM,
        ),
        damping_ratio,
    }
}

struct Settling {
    final_overlap: f64,
    /// The last time |δ/δ_eq − 1| leaves the band, interpolated between steps.
    settling_time: f64,
    peak_overlap: f64,
    wall_time: f64,
}

fn settle(damping_ratio: f64, dt: f64) -> Settling {
    let mut sim = two_spheres(
        DENSITY,
        SPEED,
        0.0,
        Some(paper_bond(damping_ratio)),
        dt,
        DURATION,
    );
    let (mut settling_time, mut peak_overlap) = (0.0, 0.0_f64);
    let mut previous = (overlap(&sim) / EQUILIBRIUM - 1.0).abs();
    let wall_time = timed_steps(&mut sim, |sim| {
        let delta = overlap(sim);
        peak_overlap = peak_overlap.max(delta);
        let deviation = (delta / EQUILIBRIUM - 1.0).abs();
        if previous > BAND && deviation <= BAND {
            settling_time = sim.time - dt + dt * (previous - BAND) / (previous - deviation);
        }
        previous = deviation;
        false
    });
    assert_eq!(sim.bond_state(0, 1), BondState::Bonded, "example 5.1 bonds");
    Settling {
        final_overlap: overlap(&sim),
        settling_time,
        peak_overlap,
        wall_time,
    }
}

pub(super) fn family(quick: bool) -> Family {
    let counts: &[u32] = if quick {
        &[1, 2, 4, 8]
    } else {
        &[1, 2, 4, 8, 16, 32, 64, 128]
    };
    // dt = 4 × 5e-7 s / n: from 4 times the paper's step down.
    let dts = steps(4.0 * PAPER_DT, counts);
    let m_star = paper_sphere_mass(DENSITY) / 2.0;
    let t_c = hertz::contact_time(m_star, PAPER_E_STAR, PAPER_R_STAR, SPEED);
    let scale = ("t_c", t_c);
    let dampings: &[f64] = if quick { &[0.3] } else { &[0.3, 1.0] };
    let mut series = Vec::new();
    for &xi in dampings {
        let variant = format!("ξ_bond = {xi}");
        // Settling time and peak overlap have no closed form: reference run 8 times finer than
        // the finest of the sweep.
        let fine = dts[dts.len() - 1] / 8.0;
        let reference = settle(xi, fine);
        let mut final_overlap = Series::new(
            "final δ",
            &variant,
            "m",
            scale,
            EQUILIBRIUM,
            Reference::ClosedForm("δ_eq, paper eq. 23"),
        )
        .expecting("none: δ_eq is a fixed point of the step");
        let mut settling = Series::new(
            "settling time",
            &variant,
            "s",
            scale,
            reference.settling_time,
            Reference::FineStep(fine),
        )
        .expecting("1 (the bond forms on the step grid)");
        let mut peak = Series::new(
            "peak δ",
            &variant,
            "m",
            scale,
            reference.peak_overlap,
            Reference::FineStep(fine),
        )
        .expecting("1 (the bond forms on the step grid)");
        for &dt in &dts {
            let (r, wall) = best_of(quick, || settle(xi, dt), |r| r.wall_time);
            final_overlap.push(dt, r.final_overlap, wall);
            settling.push(dt, r.settling_time, wall);
            peak.push(dt, r.peak_overlap, wall);
        }
        series.extend([final_overlap, settling, peak]);
    }
    Family {
        key: "bond",
        title: "The bond of example 5.1",
        description: format!(
            "The paper's example 5.1: the spheres of section 5 (ρ = {DENSITY} kg/m³) meet at \
             {SPEED} m/s without contact damping; the bond (α_adh = 1, k_adh from δ_eq = 50 µm, \
             criterion \"always\") forms when δ reaches δ_crit = (4/9) δ_eq and pulls the pair \
             onto δ_eq. The run lasts {DURATION} s; dt = 4 × 5e-7 s / n for n = {counts:?} (the \
             paper's step is n = 4; t_c = {t_c:.3e} s is the Hertz contact time at {SPEED} m/s). \
             Measured: the overlap at the end (against δ_eq, eq. 23), the settling time (the \
             last time |δ/δ_eq − 1| falls below {BAND}, interpolated between steps) and the \
             largest overlap (no closed form for these two: the reference is a run at dt = \
             5e-7 s × 4/{}).",
            counts[counts.len() - 1] * 8
        ),
        reading: "The final overlap sits on δ_eq to round-off at every time step: δ_eq is where \
                  the bonded force vanishes, which makes it a fixed point of the discrete map \
                  too, and the oscillation has died out long before 5 ms. The bond forms at the \
                  first step at which δ ≥ δ_crit, not at the instant δ crosses δ_crit: the force \
                  law switches up to one step late, an O(dt) error in the state from which the \
                  bonded oscillation starts. The peak overlap and the settling time inherit it \
                  and are first order although the integrator is second order. The delay is the \
                  fraction of a step by which the crossing precedes the next step, which changes \
                  erratically with dt: the local orders scatter (from −1 to 3), and the \
                  least-squares slope over the sweep (1.0–1.1) is the order to read. The \
                  settling time adds the sensitivity of a threshold crossing: when the last \
                  excursion out of the band barely leaves it, a small change of amplitude moves \
                  the crossing a lot.",
        series,
    }
}

/// Whether the bond forms in one impact of the onset case (before the spheres separate).
fn sticks(speed: f64, dt: f64, contact_time: f64) -> bool {
    let mut sim = two_spheres(
        DENSITY,
        speed,
        0.0,
        Some(paper_bond(1.0)),
        dt,
        3.0 * contact_time,
    );
    let mut touched = false;
    let mut bonded = false;
    timed_steps(&mut sim, |sim| {
        let delta = overlap(sim);
        touched |= delta > 0.0;
        bonded = sim.bond_state(0, 1) == BondState::Bonded;
        bonded || (touched && delta < 0.0)
    });
    debug_assert!(bonded || approach_speed(&sim) < 0.0);
    bonded
}

pub(super) fn onset_family(quick: bool) -> Family {
    let m_star = paper_sphere_mass(DENSITY) / 2.0;
    let bond = paper_bond(1.0);
    let v_crit = bond.critical_velocity(PAPER_E_STAR, PAPER_R_STAR, m_star);
    let t_c = hertz::contact_time(m_star, PAPER_E_STAR, PAPER_R_STAR, v_crit);
    let counts: &[u32] = if quick {
        &[16, 32, 64, 128]
    } else {
        &[8, 16, 32, 64, 128, 256, 512, 1024, 2048]
    };
    // Bisection to 2⁻²⁸ ≈ 4e-9 of v_crit (quick: 2⁻²⁰ ≈ 1e-6), below the errors measured.
    let halvings = if quick { 20 } else { 28 };
    let mut series = Series::new(
        "onset velocity",
        "",
        "m/s",
        ("t_c", t_c),
        v_crit,
        Reference::ClosedForm("v_crit, paper eq. 21"),
    )
    .expecting("2 (velocity Verlet, sampled peak)");
    for dt in steps(t_c, counts) {
        let bisection = || {
            let start = Instant::now();
            let (mut low, mut high) = (0.8 * v_crit, 1.2 * v_crit);
            assert!(
                !sticks(low, dt, t_c) && sticks(high, dt, t_c),
                "the onset lies within ±20 % of eq. 21 at dt = {dt:e}"
            );
            for _ in 0..halvings {
                let mid = 0.5 * (low + high);
                if sticks(mid, dt, t_c) {
                    high = mid;
                } else {
                    low = mid;
                }
            }
            (0.5 * (low + high), start.elapsed().as_secs_f64())
        };
        let ((onset, _), wall) = best_of(quick, bisection, |r| r.1);
        series.push(dt, onset, wall);
    }
    Family {
        key: "onset",
        title: "Onset of bonding",
        description: format!(
            "The smallest impact speed at which the bond of section 5 forms (ρ = {DENSITY} \
             kg/m³, ξ_bond = 1, no contact damping), found by bisection ({halvings} halvings of \
             ±20 % around the prediction) at each time step t_c/n, n = {counts:?}, against the \
             critical velocity of paper eq. 21, v_crit = {v_crit:.5} m/s (t_c = {t_c:.3e} s, the \
             Hertz contact time at v_crit). An impact counts as bonding if the bond forms before \
             the spheres separate. The wall time is that of the whole bisection, including the scene set-up of each of its impacts, which is what it costs at the coarse steps."
        ),
        reading: "The bond forms when the overlap at a step reaches δ_crit, so the measured \
                  onset is the speed whose largest sampled overlap equals δ_crit. The sampled \
                  peak falls short of the true one by at most (1/2)|δ̈|(dt/2)², and the \
                  integrator adds its own O(dt²): the onset converges at second order to eq. 21, \
                  from below: velocity Verlet overshoots the peak overlap (δ_max of the Hertz \
                  impact is too large at every step) by more than the sampling loses, so a \
                  slightly slower impact already reaches δ_crit.",
        series: vec![series],
    }
}
