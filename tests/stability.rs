//! The time-step stability limit of the integrator (M.70, docs/stability.md) against the
//! integrator itself: a contact oscillating about its equilibrium stays bounded just below the
//! predicted limit and grows just above it, for undamped, damped and overdamped contacts, on the
//! bonded branch (stiffness eq. 24) and on a Hertz wall contact. `check` then refuses a scene whose
//! dt is beyond the limit.

mod common;

use am_sim::check;
use am_sim::contact::{BondState, bond, hertz};
use am_sim::integrate::stability_limit;
use common::{Bond, E_STAR, R_STAR, overlap, sphere_mass, two_spheres_at};

const DENSITY: f64 = 2000.0;
const EQUILIBRIUM: f64 = 5e-5;
/// Initial offset from equilibrium, relative: small enough that the stiffness varies by ~1e-4
/// over the oscillation, so the linear analysis of M.70 applies.
const OFFSET: f64 = 1e-4;
/// Just inside / just outside the limit: ±5 % moves the amplification factor well off 1 (by
/// 0.1-0.9 per step depending on ξ, docs/stability.md), so 3000 steps separate the two cleanly.
const MARGIN: f64 = 0.05;
const STEPS: usize = 3000;
/// What "blows up" means here: the offset grew by more than two orders of magnitude. Undamped
/// cases reach NaN or break the bond; overdamped ones (ξ = 5) saturate in a limit cycle a few
/// hundred to a few thousand times the offset, because the stiffness and the damper grow with δ
/// (measured: 370× for the resting sphere, 2100× for the bond), still far above the bounded 3.2×.
const GROWN: f64 = 100.0;

fn bond_params(damping_ratio: f64) -> Bond {
    Bond {
        adhesion_exponent: 1.0,
        adhesion_stiffness: bond::adhesion_stiffness_for_equilibrium(
            E_STAR,
            R_STAR,
            1.0,
            EQUILIBRIUM,
        ),
        damping_ratio,
        criterion: "always",
    }
}

/// Largest |δ − δ_eq| / (initial offset) over the run of a bonded pair started at rest at
/// δ_eq (1 + OFFSET) with time step `dt`. Stops early once the bond has broken or the offset grew
/// by 1e6 (the outcome is then clear).
fn bonded_growth(damping_ratio: f64, dt: f64) -> f64 {
    let start = EQUILIBRIUM * (1.0 + OFFSET);
    let mut sim = two_spheres_at(
        DENSITY,
        2.0 * common::RADIUS - start,
        0.0,
        0.0,
        Some(bond_params(damping_ratio)),
        dt,
        dt * STEPS as f64,
    );
    assert_eq!(sim.bond_state(0, 1), BondState::Bonded, "bond at t = 0");
    let mut growth: f64 = 0.0;
    for _ in 0..STEPS {
        sim.step();
        let deviation = (overlap(&sim) - EQUILIBRIUM).abs() / (EQUILIBRIUM * OFFSET);
        growth = growth.max(deviation);
        if !deviation.is_finite() || growth > 1e6 || sim.bond_state(0, 1) != BondState::Bonded {
            return f64::INFINITY;
        }
    }
    growth
}

#[test]
fn the_limit_has_the_closed_form_of_m70() {
    let (k, m): (f64, f64) = (4.0e5, 1.0e-6);
    let omega = (k / m).sqrt();
    // ξ = 0: the textbook ω dt ≤ 2.
    assert!((stability_limit(k, m, 0.0) * omega - 2.0).abs() < 1e-14);
    // (ω dt)² + 4ξ ω dt = 4 at the limit, for any ξ.
    for xi in [0.1, 0.3, 1.0, 5.0] {
        let s = stability_limit(k, m, xi) * omega;
        assert!((s * s + 4.0 * xi * s - 4.0).abs() < 1e-12, "ξ = {xi}");
    }
    assert!(stability_limit(-1.0, m, 0.3).is_infinite());
}

#[test]
fn a_bond_is_stable_just_below_the_limit_and_blows_up_just_above() {
    let m_star = hertz::effective_mass(sphere_mass(DENSITY), sphere_mass(DENSITY));
    for xi in [0.0, 0.3, 5.0] {
        let b = bond_params(xi);
        let params = am_sim::contact::BondParams {
            adhesion_exponent: b.adhesion_exponent,
            adhesion_stiffness: b.adhesion_stiffness,
            damping_ratio: xi,
        };
        let stiffness = params.stiffness(E_STAR, R_STAR, EQUILIBRIUM);
        let limit = stability_limit(stiffness, m_star, xi);
        let below = bonded_growth(xi, (1.0 - MARGIN) * limit);
        let above = bonded_growth(xi, (1.0 + MARGIN) * limit);
        // Below: bounded. The undamped scheme near its limit swings up to 1/√(1 − (ωdt/2)²) ≈ 3.2
        // times the start (its invariant ellipse is elongated), so 10 is the bound; damped cases
        // decay.
        assert!(
            below < 10.0,
            "ξ = {xi}: {below} times the offset at 0.95 × limit"
        );
        assert!(
            above > GROWN,
            "ξ = {xi}: only {above} times the offset at 1.05 × limit"
        );
    }
}

/// A sphere resting on the plate under gravity, started OFFSET above its static overlap
/// (r = 1 mm, E = 1 GPa, ν = 0 against a wall: E* = E/2 with the wall of the same material).
fn resting_growth(damping_ratio: f64, dt: f64) -> f64 {
    let (g, r) = (9.81, common::RADIUS);
    let mass = sphere_mass(DENSITY);
    // m g = (4/3) E* √r δ^{3/2}  (M.5)
    let static_overlap = (mass * g / (4.0 / 3.0 * E_STAR * r.sqrt())).powf(2.0 / 3.0);
    let start = static_overlap * (1.0 + OFFSET);
    let text = format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
gravity_m_s2 = [0.0, 0.0, -{g:e}]
skin_m = 1e-4
[materials.paper]
density_kg_m3 = {DENSITY:e}
youngs_modulus_pa = 1e9
poisson_ratio = 0.0
[contact]
model = "hertz"
damping_ratio = {damping_ratio:e}
[[particles]]
position_m = [0.0, 0.0, {z:e}]
radius_m = {r:e}
material = "paper"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "paper"
"#,
        duration = dt * STEPS as f64,
        z = r - start,
    );
    let mut sim = common::simulation(&text);
    let mut growth: f64 = 0.0;
    for _ in 0..STEPS {
        sim.step();
        let overlap = r - sim.particles.position[0].z;
        let deviation = (overlap - static_overlap).abs() / (static_overlap * OFFSET);
        growth = growth.max(deviation);
        if !deviation.is_finite() || growth > 1e6 {
            return f64::INFINITY;
        }
    }
    growth
}

#[test]
fn a_resting_hertz_contact_is_stable_just_below_the_limit_and_not_above() {
    let (g, r) = (9.81, common::RADIUS);
    let mass = sphere_mass(DENSITY);
    let static_overlap = (mass * g / (4.0 / 3.0 * E_STAR * r.sqrt())).powf(2.0 / 3.0);
    for xi in [0.0, 0.5, 5.0] {
        let limit = stability_limit(hertz::stiffness(E_STAR, r, static_overlap), mass, xi);
        let below = resting_growth(xi, (1.0 - MARGIN) * limit);
        let above = resting_growth(xi, (1.0 + MARGIN) * limit);
        assert!(
            below < 10.0,
            "ξ = {xi}: {below} times the offset at 0.95 × limit"
        );
        assert!(
            above > GROWN,
            "ξ = {xi}: only {above} times the offset at 1.05 × limit"
        );
    }
}

#[test]
fn check_reports_the_limit_and_refuses_a_dt_beyond_it() {
    // Example 5.1 at 2.6 m/s: the stiffest expected contact is the Hertz impact's largest overlap.
    let m_star = hertz::effective_mass(sphere_mass(DENSITY), sphere_mass(DENSITY));
    let impact_overlap = hertz::max_overlap(m_star, E_STAR, R_STAR, 2.6);
    let limit = stability_limit(
        hertz::stiffness(E_STAR, R_STAR, impact_overlap),
        m_star,
        0.0,
    );
    for (dt, refused) in [(0.9 * limit, false), (1.1 * limit, true)] {
        let sim = common::two_spheres(DENSITY, 2.6, 0.0, Some(bond_params(0.3)), dt, 1e-3);
        let report = check::report(&sim);
        assert!((report.stability_limit.0 / limit - 1.0).abs() < 1e-12);
        assert!(report.recommended_dt <= 0.5 * limit);
        let reason = report.instability();
        assert_eq!(reason.is_some(), refused, "dt = {dt:e}: {reason:?}");
        if let Some(reason) = reason {
            assert!(reason.contains("simulation.dt_s") && reason.contains("--force"));
        }
    }
}
