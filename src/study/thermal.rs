//! The thermal closed forms against the time step and the substep fraction θ of (M.49):
//! convective cooling of one sphere, two spheres equilibrating through their contact, and the
//! latent-heat plateau of a sphere under a constant laser.

use super::scenes::{STEEL_DENSITY, steel_capacity, thermal};
use super::{Family, Reference, Series, best_of, steps, timed_steps};
use crate::contact::bond;
use crate::thermal::losses::sphere_area;

/// Radius of the single sphere, and of the larger of the pair \[m\].
const RADIUS: f64 = 1e-4;
/// Radius of the smaller sphere of the pair \[m\].
const SMALL_RADIUS: f64 = 0.7e-4;
/// Convection coefficient h [W/(m²·K)].
const CONVECTION: f64 = 5e3;
/// Gas temperature \[K\].
const GAS: f64 = 300.0;
/// Initial temperature of the hot sphere \[K\].
const HOT: f64 = 1000.0;
/// Conductivity k of the pair [W/(m·K)].
const CONDUCTIVITY: f64 = 20.0;
/// Young's modulus of the pair \[Pa\]: 1 kPa makes the bond oscillation period (≈ 0.1 s) longer
/// than any step used, so the pair rests at δ_eq and its conductance stays fixed.
const SOFT_YOUNGS: f64 = 1e3;
/// Melting point \[K\] and latent heat [J/kg] of the plateau case.
const MELTING: f64 = 1700.0;
const LATENT: f64 = 2.7e5;

/// One sphere of radius [`RADIUS`] at rest at the origin.
fn one_particle() -> String {
    format!(
        "[[particles]]\nposition_m = [0.0, 0.0, 0.0]\nradius_m = {RADIUS:e}\nmaterial = \"steel\""
    )
}

fn material(melting: f64) -> String {
    format!("thermal_conductivity_w_m_k = {CONDUCTIVITY:e}\nmelting_point_k = {melting:e}")
}

/// Excess temperature `T − T_gas` at the end of a cooling run of `2τ`, and the wall time.
fn cooling(dt: f64, theta: f64, tau: f64) -> (f64, f64, f64) {
    let body = format!(
        "initial_temperature_k = {HOT:e}\nconduction = \"none\"\n[thermal.convection]\nheat_transfer_coefficient_w_m2_k = {CONVECTION:e}\ngas_temperature_k = {GAS:e}"
    );
    let mut sim = thermal(
        dt,
        2.0 * tau,
        theta,
        2e11,
        &body,
        &material(MELTING),
        "",
        &one_particle(),
    );
    let wall_time = timed_steps(&mut sim, |_| false);
    let state = sim.thermal.as_ref().expect("thermal scene");
    (state.temperature[0] - GAS, sim.time, wall_time)
}

/// The pair, held bonded at its equilibrium overlap δ_eq = r*/100 (zero force), hot sphere at
/// [`HOT`], the other at [`GAS`]. Returns the time constant measured from the temperature gap
/// at the end of a run of `2τ`, and the wall time.
fn equilibration(dt: f64, theta: f64, tau: f64, overlap: f64) -> (f64, f64) {
    let r_star = RADIUS * SMALL_RADIUS / (RADIUS + SMALL_RADIUS);
    let e_star = SOFT_YOUNGS / (2.0 * (1.0 - 0.09));
    let k_adh = bond::adhesion_stiffness_for_equilibrium(e_star, r_star, 1.0, overlap);
    let bond = format!(
        "[bond]\nadhesion_exponent = 1.0\nadhesion_stiffness = {k_adh:e}\ndamping_ratio = 1.0\ncriterion = \"always\""
    );
    let particles = format!(
        "{}\n[[particles]]\nposition_m = [{x:e}, 0.0, 0.0]\nradius_m = {SMALL_RADIUS:e}\nmaterial = \"steel\"",
        one_particle(),
        x = RADIUS + SMALL_RADIUS - overlap
    );
    let body = format!("initial_temperature_k = {GAS:e}\nconduction = \"batchelor_obrien\"");
    // Melting point far above: no latent heat or melting in this case.
    let mut sim = thermal(
        dt,
        2.0 * tau,
        theta,
        SOFT_YOUNGS,
        &body,
        &material(1e5),
        &bond,
        &particles,
    );
    sim.thermal
        .as_mut()
        .expect("thermal scene")
        .set_temperature(&sim.particles, 0, HOT);
    let wall_time = timed_steps(&mut sim, |_| false);
    let t = &sim.thermal.as_ref().expect("thermal scene").temperature;
    // gap(t) = gap(0) e^{−t/τ}
    let measured = -sim.time / ((t[0] - t[1]) / (HOT - GAS)).ln();
    (measured, wall_time)
}

/// Plateau of a sphere heated by a constant laser: `(duration measured on the step grid, m L / P
/// with the absorbed power P of this run, wall time)`.
fn plateau(dt: f64) -> (f64, f64, f64) {
    let laser = "[laser]\npower_w = 5.0\nspot_radius_m = 2e-4\n[laser.path]\nkind = \"stationary\"\nposition_m = [0.0, 0.0]\nduration_s = 1.0";
    let mut sim = thermal(
        dt,
        1.0,
        0.5,
        2e11,
        "initial_temperature_k = 300\nconduction = \"none\"",
        &format!(
            "{}\nlatent_heat_j_kg = {LATENT:e}\nabsorptivity = 0.5",
            material(MELTING)
        ),
        laser,
        &one_particle(),
    );
    let (mut start, mut end) = (None, None);
    let wall_time = timed_steps(&mut sim, |sim| {
        let t = sim.thermal.as_ref().expect("thermal scene").temperature[0];
        if t >= MELTING && start.is_none() {
            start = Some(sim.time);
        }
        if t > MELTING {
            end = Some(sim.time);
        }
        end.is_some()
    });
    let state = sim.thermal.as_ref().expect("thermal scene");
    let latent_heat = state.heat_constants(&sim.particles, 0).latent_heat;
    let expected = latent_heat / state.laser.as_ref().expect("[laser]").power[0];
    let measured = end.expect("melted through within 1 s") - start.expect("reached T_m");
    (measured, expected, wall_time)
}

pub(super) fn family(quick: bool) -> Family {
    let capacity = steel_capacity(RADIUS);
    let tau_convection = capacity / (CONVECTION * sphere_area(RADIUS));
    let r_star = RADIUS * SMALL_RADIUS / (RADIUS + SMALL_RADIUS);
    let overlap = 0.01 * r_star;
    // H = 2 k a, a = √(r* δ) (M.41, with k* = k for one material); τ = C_a C_b / ((C_a + C_b) H).
    let conductance = 2.0 * CONDUCTIVITY * (r_star * overlap).sqrt();
    let (ca, cb) = (capacity, steel_capacity(SMALL_RADIUS));
    let tau_pair = ca * cb / ((ca + cb) * conductance);
    let counts: &[u32] = if quick {
        &[4, 8, 16, 32]
    } else {
        &[1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096]
    };
    let thetas: &[f64] = if quick { &[1.0, 0.1] } else { &[1.0, 0.5, 0.1] };
    let mut series = Vec::new();
    for &theta in thetas {
        let variant = format!("θ = {theta}");
        let mut cooling_series = Series::new(
            "convection: T − T_gas",
            &variant,
            "K",
            ("τ", tau_convection),
            (HOT - GAS) * (-2.0_f64).exp(),
            Reference::ClosedForm("(T₀ − T_gas) e^{−t/τ}, τ = C/(hA)"),
        )
        .expecting("1 (explicit Euler), a θ floor at large dt");
        for dt in steps(tau_convection, counts) {
            let ((excess, time, _), wall) =
                best_of(quick, || cooling(dt, theta, tau_convection), |r| r.2);
            let exact = (HOT - GAS) * (-time / tau_convection).exp();
            // Every run ends at t = 2τ up to the rounding of the step count: the value is
            // scaled to t = 2τ exactly, so that one reference serves the whole table.
            let at_two_tau = excess / exact * cooling_series.reference;
            cooling_series.push(dt, at_two_tau, wall);
        }
        let mut pair = Series::new(
            "two spheres: τ",
            &variant,
            "s",
            ("τ", tau_pair),
            tau_pair,
            Reference::ClosedForm("C_a C_b / ((C_a + C_b) H), H = 2 k a"),
        )
        .expecting("1 (explicit Euler), a θ floor at large dt");
        for dt in steps(tau_pair, counts) {
            let ((measured, _), wall) = best_of(
                quick,
                || equilibration(dt, theta, tau_pair, overlap),
                |r| r.1,
            );
            pair.push(dt, measured, wall);
        }
        series.extend([cooling_series, pair]);
    }
    let plateau_counts: &[u32] = if quick {
        &[16, 32, 64, 128]
    } else {
        &[8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192]
    };
    // The absorbed power depends only on the geometry: any run gives the reference.
    let (_, expected, _) = plateau(1e-4);
    let mut plateau_series = Series::new(
        "latent plateau",
        "",
        "s",
        ("mL/P", expected),
        expected,
        Reference::ClosedForm("m L / P"),
    )
    .expecting("1 (read on the step grid)");
    // dt = (m L / P)/(n √2): a step commensurate with the plateau would put both of its ends at
    // the same phase of the step grid, and the grid error would cancel by construction.
    for dt in steps(expected / std::f64::consts::SQRT_2, plateau_counts) {
        let ((measured, reference, _), wall) = best_of(quick, || plateau(dt), |r| r.2);
        assert!(
            (reference / expected - 1.0).abs() < 1e-12,
            "the absorbed power does not depend on dt"
        );
        plateau_series.push(dt, measured, wall);
    }
    series.push(plateau_series);
    Family {
        key: "thermal",
        title: "Thermal closed forms",
        description: format!(
            "Three cases of the lumped heat balance (M.47–M.49), steel-like spheres (ρ = \
             {STEEL_DENSITY} kg/m³, c = 500 J/(kg·K)): (1) one sphere of r = {RADIUS:e} m at \
             {HOT} K cooling by convection (h = {CONVECTION} W/(m²·K), T_gas = {GAS} K), the \
             excess temperature at t = 2τ against (T₀ − T_gas) e^{{−2}}, τ = C/(hA) = \
             {tau_convection:.4e} s; (2) spheres of r = {RADIUS:e} and {SMALL_RADIUS:e} m held \
             bonded at δ = r*/100 (zero force), the first at {HOT} K, the second at {GAS} K, \
             exchanging heat through H = 2 k a (M.41, k = {CONDUCTIVITY} W/(m·K)), the time \
             constant measured from the temperature gap at t = 2τ against τ = C_a C_b/((C_a + \
             C_b) H) = {tau_pair:.4e} s; (3) one sphere heated by a stationary laser (absorbed \
             power P, no losses) through its melting point ({MELTING} K, L = {LATENT:e} J/kg), the \
             plateau read on the step grid (from the first step at T_m to the first above it) \
             against m L / P = {expected:.4e} s. For (1) and (2) dt = τ/n, n = {counts:?}, with \
             the substep fraction θ of M.49 swept over {thetas:?} (a step is split into \
             ⌈dt max(G/C) / θ⌉ substeps); for (3) dt = (m L/P)/(n √2), n = {plateau_counts:?} (incommensurate with the plateau, so that its two ends fall at different phases of the step grid; no conductance, so always one substep)."
        ),
        reading: "The heat balance is integrated by explicit Euler on the enthalpy, first order: \
                  while one substep per step suffices (dt ≤ θ C/G), the errors of (1) and (2) \
                  halve with dt (relative error ≈ dt/τ at t = 2τ), and θ changes nothing, to \
                  the last bit. At larger steps the sub-cycling takes over: the substep is \
                  capped at θ C/G whatever dt is, so the error stops growing at a floor set by θ \
                  (0.5–1 for θ = 1, 0.26–0.35 for θ = 0.5, 0.06–0.09 for θ = 0.1 here); θ = 1 is \
                  the edge of the maximum principle, where one Euler substep of C/G empties the \
                  excess temperature at once (two spheres at dt = τ: error 1). A smaller θ buys \
                  a bounded error at large dt with more substeps per step. The plateau is exact \
                  in the enthalpy (a constant source integrates without error); its measured \
                  length is off by less than one step at each end because it is read on the step \
                  grid: first order in its bound, with a scatter that follows where the melting \
                  point falls between steps. Its wall time is mostly the one ray cast of the \
                  stationary beam, whatever dt.",
        series,
    }
}
