//! Hertz impact of two spheres of the paper's section 5: maximum overlap (paper eq. 20), contact
//! time (Johnson 1985, M.8) and restitution, against the time step.

use super::scenes::{
    PAPER_E_STAR, PAPER_R_STAR, approach_speed, overlap, paper_sphere_mass, two_spheres,
};
use super::{Family, Reference, Series, best_of, steps, timed_steps};
use crate::contact::hertz;

/// Density of the impact case [kg/m³].
const DENSITY: f64 = 2000.0;
/// Impact speed [m/s].
const SPEED: f64 = 1.0;
/// Contact damping ratio ξ_con of the damped impact (eq. 26).
const DAMPING: f64 = 0.3;

/// What one impact measures.
struct Impact {
    max_overlap: f64,
    /// From the zero crossings of δ(t), interpolated linearly between steps.
    contact_time: f64,
    /// Steps with δ > 0, times dt.
    contact_time_on_grid: f64,
    restitution: f64,
    wall_time: f64,
}

/// One head-on impact at [`SPEED`] with contact damping `damping` and time step `dt`.
fn impact(damping: f64, dt: f64, contact_time: f64) -> Impact {
    let mut sim = two_spheres(DENSITY, SPEED, damping, None, dt, 3.0 * contact_time);
    let (mut max_overlap, mut steps_in_contact) = (0.0_f64, 0u32);
    let mut previous = overlap(&sim); // 0: the spheres start touching, at t = 0
    let mut end = None;
    let wall_time = timed_steps(&mut sim, |sim| {
        let delta = overlap(sim);
        if delta > 0.0 {
            steps_in_contact += 1;
            max_overlap = max_overlap.max(delta);
        } else if previous > 0.0 {
            end = Some(sim.time - dt + dt * previous / (previous - delta));
            return true;
        }
        previous = delta;
        false
    });
    Impact {
        max_overlap,
        contact_time: end.expect("the spheres separate within 3 t_c"),
        contact_time_on_grid: f64::from(steps_in_contact) * dt,
        restitution: -approach_speed(&sim) / SPEED,
        wall_time,
    }
}

pub(super) fn family(quick: bool) -> Family {
    let m_star = paper_sphere_mass(DENSITY) / 2.0;
    let t_c = hertz::contact_time(m_star, PAPER_E_STAR, PAPER_R_STAR, SPEED);
    let counts: &[u32] = if quick {
        &[16, 32, 64, 128]
    } else {
        &[8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192]
    };
    let dts = steps(t_c, counts);
    let scale = ("t_c", t_c);
    let mut series = [
        Series::new(
            "δ_max",
            "ξ = 0",
            "m",
            scale,
            hertz::max_overlap(m_star, PAPER_E_STAR, PAPER_R_STAR, SPEED),
            Reference::ClosedForm("paper eq. 20"),
        )
        .expecting("2 (velocity Verlet)"),
        Series::new(
            "t_c, interpolated",
            "ξ = 0",
            "s",
            scale,
            t_c,
            Reference::ClosedForm("Johnson's t_c, M.8"),
        )
        .expecting("2 (velocity Verlet)"),
        Series::new(
            "t_c, on the step grid",
            "ξ = 0",
            "s",
            scale,
            t_c,
            Reference::ClosedForm("Johnson's t_c, M.8"),
        )
        .expecting("1 (a whole number of steps)"),
        Series::new(
            "e",
            "ξ = 0",
            "",
            scale,
            1.0,
            Reference::ClosedForm("e = 1 (no damping)"),
        )
        .expecting("≥ 2 (symplectic: energy error bounded)"),
    ];
    for &dt in &dts {
        let (r, wall) = best_of(quick, || impact(0.0, dt, t_c), |r| r.wall_time);
        series[0].push(dt, r.max_overlap, wall);
        series[1].push(dt, r.contact_time, wall);
        series[2].push(dt, r.contact_time_on_grid, wall);
        series[3].push(dt, r.restitution, wall);
    }
    // Damped restitution has no closed form for eq. 26: the reference is a run 16 times finer
    // than the finest of the sweep.
    let fine = dts[dts.len() - 1] / 16.0;
    let mut damped = Series::new(
        "e",
        &format!("ξ = {DAMPING}"),
        "",
        scale,
        impact(DAMPING, fine, t_c).restitution,
        Reference::FineStep(fine),
    )
    .expecting("1 (the damping sees v(t + dt/2))");
    for &dt in &dts {
        let (r, wall) = best_of(quick, || impact(DAMPING, dt, t_c), |r| r.wall_time);
        damped.push(dt, r.restitution, wall);
    }
    let mut series = series.to_vec();
    series.push(damped);
    Family {
        key: "hertz",
        title: "Hertz impact",
        description: format!(
            "Two spheres of the paper's section 5 (r = 1 mm, E = 1 GPa, ν = 0, ρ = {DENSITY} kg/m³) \
             meet head-on at {SPEED} m/s, touching at t = 0, with no bond. The time step is \
             t_c/n for n = {counts:?}, t_c = {t_c:.4e} s the Hertz contact time. Measured: the \
             largest overlap on the step grid (against paper eq. 20), the contact time from the \
             zero crossings of δ(t) interpolated linearly between steps and, for comparison, as \
             the number of steps in contact times dt (both against Johnson's t_c, M.8), and \
             the restitution coefficient e (the separation speed over the impact speed) without \
             damping (against 1) and with ξ_con = {DAMPING} (eq. 26; no closed form, so the \
             reference is a run at dt = t_c/{}).",
            counts[counts.len() - 1] * 16
        ),
        reading: "Velocity Verlet is second order, and so are the quantities read from the \
                  smooth trajectory: the sampled peak overlap (sampling misses a smooth maximum \
                  by O(dt²) too) and the contact time from linearly interpolated zero crossings, \
                  both at 2.00 down to errors of 1e-8. Counting the steps in contact is first \
                  order: the contact ends inside a step, so the count falls short by a fraction \
                  of a step. With dt = t_c/n and the contact starting at t = 0 the numerical \
                  contact lasts just under n steps, so the count is n − 1 and the error is \
                  exactly dt/t_c, the bound. The undamped restitution converges faster than the \
                  scheme's order (about 3.5): the energy error of a symplectic scheme oscillates \
                  during the contact and returns almost entirely once the pair has separated. \
                  The damped restitution is first order: in velocity Verlet the force at t + dt \
                  sees the half-step velocity v(t + dt/2) (src/integrate.rs), so the damping of \
                  eq. 26 lags by half a step. At coarse steps a second-order term of the \
                  opposite sign dominates; the two cancel near dt = t_c/256, where the error \
                  dips, and below it the first-order lag is what remains.",
        series,
    }
}
