//! Hertz impact without bonding: maximum overlap (paper eq. 20), contact time (Johnson 1985),
//! energy conservation without damping, and a restitution coefficient independent of the impact
//! speed with the damping of eq. 26 (as corrected: d = 2ξ√(m* k(δ))).

mod common;

use am_sim::contact::hertz;
use common::{E_STAR, R_STAR, approach_speed, overlap, sphere_mass, two_spheres};

const DENSITY: f64 = 2000.0;

struct Impact {
    max_overlap: f64,
    contact_time: f64,
    restitution: f64,
    energy_error: f64,
}

/// Runs one head-on impact with a time step `dt` [s].
fn impact(speed: f64, damping: f64, dt: f64) -> Impact {
    let m_star = sphere_mass(DENSITY) / 2.0;
    let t_c = hertz::contact_time(m_star, E_STAR, R_STAR, speed);
    let mut sim = two_spheres(DENSITY, speed, damping, None, dt, 3.0 * t_c);
    let energy0 = sim.diagnostics().mechanical_energy();
    let (mut max_overlap, mut steps_in_contact, mut energy_error) = (0.0_f64, 0u32, 0.0_f64);
    let mut previous = overlap(&sim);
    // Contact time from the zero crossings of δ(t), interpolated linearly between steps.
    let mut contact_start = 0.0;
    let mut contact_end = None;
    for _ in 0..sim.model.steps {
        let t0 = sim.time;
        sim.step();
        let delta = overlap(&sim);
        if delta > 0.0 {
            steps_in_contact += 1;
            max_overlap = max_overlap.max(delta);
            energy_error =
                energy_error.max((sim.diagnostics().mechanical_energy() / energy0 - 1.0).abs());
        }
        if previous <= 0.0 && delta > 0.0 && steps_in_contact == 1 {
            contact_start = t0 + dt * (-previous) / (delta - previous);
        }
        if previous > 0.0 && delta <= 0.0 && contact_end.is_none() {
            contact_end = Some(t0 + dt * previous / (previous - delta));
            break;
        }
        previous = delta;
    }
    Impact {
        max_overlap,
        contact_time: contact_end.expect("the spheres separate") - contact_start,
        restitution: -approach_speed(&sim) / speed,
        energy_error,
    }
}

#[test]
fn undamped_impact_matches_hertz_theory() {
    let m_star = sphere_mass(DENSITY) / 2.0;
    for speed in [0.1, 1.0, 5.0] {
        // 200 steps per contact: the sampled peak misses the true one by O((π/200)²/8) ≈ 3e-5.
        let dt = hertz::contact_time(m_star, E_STAR, R_STAR, speed) / 200.0;
        let r = impact(speed, 0.0, dt);
        let expected_overlap = hertz::max_overlap(m_star, E_STAR, R_STAR, speed);
        let expected_time = hertz::contact_time(m_star, E_STAR, R_STAR, speed);
        assert!(
            (r.max_overlap / expected_overlap - 1.0).abs() < 5e-3,
            "v = {speed}: δ_max {} vs eq. 20 {expected_overlap}",
            r.max_overlap
        );
        assert!(
            (r.contact_time / expected_time - 1.0).abs() < 1e-2,
            "v = {speed}: t_c {} vs {expected_time}",
            r.contact_time
        );
        assert!(
            (r.restitution - 1.0).abs() < 1e-3,
            "v = {speed}: restitution {}",
            r.restitution
        );
        // Velocity Verlet is symplectic: the energy error stays bounded at O(dt²) ≈ (π/200)² ~ 2e-4.
        assert!(
            r.energy_error < 1e-3,
            "v = {speed}: energy error {}",
            r.energy_error
        );
        eprintln!(
            "v = {speed}: δ_max {:+.2e}, t_c {:+.2e} relative error, e - 1 = {:+.2e}, energy error {:.2e}",
            r.max_overlap / expected_overlap - 1.0,
            r.contact_time / expected_time - 1.0,
            r.restitution - 1.0,
            r.energy_error
        );
    }
}

#[test]
fn damped_restitution_is_independent_of_impact_speed() {
    // One time step for all speeds, as in a real scene: 100 steps per contact at the fastest
    // impact. (Scaling dt with the contact time would make the runs identical in dimensionless
    // form and the test empty.) The eq. 26 form ξ√(m* k(δ)) makes e a constant of the law itself.
    let m_star = sphere_mass(DENSITY) / 2.0;
    let dt = hertz::contact_time(m_star, E_STAR, R_STAR, 5.0) / 100.0;
    for damping in [0.1, 0.3] {
        let reference = impact(1.0, damping, dt).restitution;
        assert!(
            reference < 0.95 && reference > 0.3,
            "ξ = {damping}: e = {reference}"
        );
        for speed in [0.1, 0.3, 2.0, 5.0] {
            let e = impact(speed, damping, dt).restitution;
            eprintln!("ξ = {damping}, v = {speed}: e = {e:.6} (v = 1: {reference:.6})");
            assert!(
                (e / reference - 1.0).abs() < 1e-2,
                "ξ = {damping}, v = {speed}: e = {e} vs {reference} at 1 m/s"
            );
        }
    }
}

#[test]
fn more_damping_gives_less_restitution() {
    let dt = hertz::contact_time(sphere_mass(DENSITY) / 2.0, E_STAR, R_STAR, 1.0) / 200.0;
    let e: Vec<f64> = [0.0, 0.05, 0.2, 0.5]
        .iter()
        .map(|&xi| impact(1.0, xi, dt).restitution)
        .collect();
    assert!(e.windows(2).all(|w| w[1] < w[0]), "{e:?}");
}
