//! Lumped heat transfer against closed forms: convective and radiative cooling of one sphere,
//! linear heating and the latent-heat plateau, two-sphere equilibration with both conduction
//! models, heat conservation in a bed, and a stiff network (H dt / C = 100).

mod common;

use am_sim::simulation::Simulation;
use am_sim::thermal::losses::{STEFAN_BOLTZMANN, sphere_area};

const R: f64 = 1e-4;
const RHO: f64 = 8000.0;
const CP: f64 = 500.0;

fn capacity(radius: f64) -> f64 {
    RHO * 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3) * CP
}

/// One resting sphere with the given `[thermal]` body and material extras.
fn one_sphere(
    dt: f64,
    duration: f64,
    thermal: &str,
    material_extra: &str,
    extra: &str,
) -> Simulation {
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
[materials.steel]
density_kg_m3 = {RHO:e}
youngs_modulus_pa = 2e11
poisson_ratio = 0.3
specific_heat_j_kg_k = {CP:e}
thermal_conductivity_w_m_k = 20
melting_point_k = 1700
{material_extra}
[contact]
model = "hertz"
damping_ratio = 0.0
[thermal]
{thermal}
{extra}
[[particles]]
position_m = [0.0, 0.0, 0.0]
radius_m = {R:e}
material = "steel"
"#
    ))
}

/// A 5 W beam wider than the sphere, held on it for a second: a constant absorbed power.
const STATIONARY_LASER: &str = "[laser]\npower_w = 5.0\nspot_radius_m = 2e-4\n[laser.path]\nkind = \"stationary\"\nposition_m = [0.0, 0.0]\nduration_s = 1.0";

fn temperature(sim: &Simulation, k: usize) -> f64 {
    sim.thermal.as_ref().unwrap().temperature[k]
}

#[test]
fn convective_cooling_follows_the_exponential() {
    let (h, t_gas, t0) = (5e3, 300.0, 1000.0);
    let tau = capacity(R) / (h * sphere_area(R));
    // dt = τ/2e4: explicit Euler's relative error in the excess temperature grows as
    // (t/τ)·(dt/2τ), i.e. 5e-5 at t = 2τ.
    let dt = tau / 2e4;
    let thermal = format!(
        "initial_temperature_k = {t0}\nconduction = \"none\"\n[thermal.convection]\nheat_transfer_coefficient_w_m2_k = {h:e}\ngas_temperature_k = {t_gas}"
    );
    let mut sim = one_sphere(dt, 2.0 * tau, &thermal, "", "");
    let mut worst: f64 = 0.0;
    for _ in 0..sim.model.steps {
        sim.step();
        let exact = t_gas + (t0 - t_gas) * (-sim.time / tau).exp();
        worst = worst.max((temperature(&sim, 0) - exact).abs() / exact);
    }
    eprintln!("convection: worst relative error {worst:.2e}");
    assert!(worst < 1e-4, "{worst}");
}

#[test]
fn radiative_cooling_follows_the_closed_form() {
    // dT/dt = −k T⁴ with T_env = 0: T(t) = (T0⁻³ + 3 k t)^(−1/3), k = ε σ A / C.
    let (emissivity, t0) = (0.8, 2000.0);
    let k = emissivity * STEFAN_BOLTZMANN * sphere_area(R) / capacity(R);
    let time_to_half = (1.0 / (t0 / 2.0_f64).powi(3) - 1.0 / t0.powi(3)) / (3.0 * k);
    let dt = time_to_half / 2e4;
    let thermal = format!(
        "initial_temperature_k = {t0}\nconduction = \"none\"\n[thermal.radiation]\nenvironment_temperature_k = 0.0"
    );
    let mut sim = one_sphere(
        dt,
        time_to_half,
        &thermal,
        &format!("emissivity = {emissivity}"),
        "",
    );
    let mut worst: f64 = 0.0;
    for _ in 0..sim.model.steps {
        sim.step();
        let exact = (1.0 / t0.powi(3) + 3.0 * k * sim.time).powf(-1.0 / 3.0);
        worst = worst.max((temperature(&sim, 0) / exact - 1.0).abs());
    }
    eprintln!(
        "radiation: worst relative error {worst:.2e}, T_end = {}",
        temperature(&sim, 0)
    );
    assert!((temperature(&sim, 0) / (t0 / 2.0) - 1.0).abs() < 1e-4);
    assert!(worst < 1e-4, "{worst}");
}

/// Each heat source keeps its per-particle arrays only where the scene has it, so that a scene
/// pays for none it does not ask for: a sphere at 500 K that only holds its heat has neither the
/// laser's nor the boundary's; cooled by its gas, the boundary's only; under a laser without
/// exchange, the laser's only; with both, both. Each source's total is counted where it acts
/// (the laser's positive, the cooling gas's negative) and is 0 where it is absent, and the heat
/// balance closes in every case: the sphere has no contact, so its enthalpy changes only by what
/// the sources brought (100 steps, each adding round-off of an ulp of E, far below 1e-10).
#[test]
fn each_heat_source_keeps_its_arrays_only_where_the_scene_has_it() {
    let convection =
        "[thermal.convection]\nheat_transfer_coefficient_w_m2_k = 50\ngas_temperature_k = 300";
    for (laser, exchange) in [(false, false), (false, true), (true, false), (true, true)] {
        let thermal = format!(
            "initial_temperature_k = 500\nconduction = \"none\"\n{}",
            if exchange { convection } else { "" }
        );
        let extra = if laser { STATIONARY_LASER } else { "" };
        let mut sim = one_sphere(1e-5, 1e-3, &thermal, "absorptivity = 0.5", extra);
        let start = sim.diagnostics().thermal.expect("thermal diagnostics");
        for _ in 0..100 {
            sim.step();
        }
        let case = format!("laser {laser}, exchange {exchange}");
        let t = sim.thermal.as_ref().expect("[thermal]");
        assert_eq!(
            t.laser.as_ref().map(|l| (l.power.len(), l.energy.len())),
            laser.then_some((1, 1)),
            "{case}"
        );
        let boundary = t.boundary.as_ref().map(|b| b.energy.len());
        assert_eq!(boundary, exchange.then_some(1), "{case}");
        let d = sim.diagnostics().thermal.expect("thermal diagnostics");
        assert_eq!(
            d.laser_energy > 0.0,
            laser,
            "{case}: {:e} J",
            d.laser_energy
        );
        assert_eq!(d.laser_energy == 0.0, !laser, "{case}");
        assert_eq!(d.boundary_energy < 0.0, exchange, "{case}");
        assert_eq!(d.boundary_energy == 0.0, !exchange, "{case}");
        let stored = d.enthalpy - start.enthalpy;
        assert_eq!(stored == 0.0, !laser && !exchange, "{case}: {stored:e} J");
        assert!(
            d.heat_residual.abs() < 1e-10,
            "{case}: {:e}",
            d.heat_residual
        );
    }
}

/// A resumed run keeps the saved arrays of the sources its scene has and no others: a laser's
/// saved powers of the wrong length are refused, the message naming them; the laser's and
/// boundary's arrays saved for a scene that has neither (as earlier versions saved them for any
/// scene with heat) are dropped; a source with nothing saved starts at zero.
#[test]
fn a_resumed_run_keeps_the_arrays_of_the_sources_its_scene_has() {
    let heated = |laser: &str| {
        let thermal = "initial_temperature_k = 500\nconduction = \"none\"";
        let mut sim = one_sphere(1e-5, 1e-3, thermal, "absorptivity = 0.5", laser);
        for _ in 0..10 {
            sim.step();
        }
        sim
    };
    let (lit, plain) = (heated(STATIONARY_LASER), heated(""));
    let saved_laser = lit.restart_state();
    let laser = saved_laser.thermal.as_ref().and_then(|t| t.laser.clone());
    assert!(laser.as_ref().is_some_and(|l| l.energy[0] > 0.0));
    let resume = |sim: &Simulation, state| {
        Simulation::resume(sim.model.clone(), sim.particles.clone(), state)
    };
    // The laser's arrays, one particle short.
    let mut short = saved_laser.clone();
    let saved = short
        .thermal
        .as_mut()
        .and_then(|t| t.laser.as_mut())
        .unwrap();
    saved.power.clear();
    let error = resume(&lit, short).expect_err("refused");
    assert!(error.contains("0 laser powers for 1 particles"), "{error}");
    // Laser and boundary arrays saved for the scene without either: dropped.
    let mut old = plain.restart_state();
    let thermal = old.thermal.as_mut().unwrap();
    (thermal.laser, thermal.boundary_energy) = (laser.clone(), Some(vec![-1.0]));
    let resumed = resume(&plain, old).expect("resumed");
    let t = resumed.thermal.as_ref().unwrap();
    assert!(t.laser.is_none() && t.boundary.is_none());
    // The laser's scene resumed from the scene without it: its laser energy starts at zero,
    // and from its own restart data it carries on with the saved one.
    let resumed = resume(&lit, plain.restart_state()).expect("resumed");
    assert_eq!(resumed.thermal.unwrap().total_laser_energy(), 0.0);
    let resumed = resume(&lit, saved_laser).expect("resumed");
    assert_eq!(resumed.thermal.unwrap().laser, laser);
}

#[test]
fn constant_power_heats_linearly_and_the_latent_heat_holds_a_plateau() {
    let latent = 2.7e5;
    let laser = STATIONARY_LASER;
    let dt = 2e-6;
    let mut sim = one_sphere(
        dt,
        0.5,
        "initial_temperature_k = 300\nconduction = \"none\"",
        &format!("latent_heat_j_kg = {latent:e}\nabsorptivity = 0.5"),
        laser,
    );
    let c = capacity(R);
    let mass_latent = c / CP * latent;
    sim.step();
    let power = sim.thermal.as_ref().unwrap().laser.as_ref().unwrap().power[0];
    assert!(power > 0.0 && power <= 0.5 * 5.0, "absorbed {power} W");
    let (mut plateau_start, mut plateau_end) = (None, None);
    let mut linear_error: f64 = 0.0;
    while sim.step < sim.model.steps {
        sim.step();
        let t = temperature(&sim, 0);
        if t < 1700.0 {
            // Solid: T = T0 + P t / C (exact for a constant source, up to round-off).
            linear_error = linear_error.max((t - (300.0 + power * sim.time / c)).abs() / t);
        }
        if t >= 1700.0 && plateau_start.is_none() {
            plateau_start = Some(sim.time);
        }
        if t > 1700.0 && plateau_end.is_none() {
            plateau_end = Some(sim.time);
            break;
        }
    }
    let duration = plateau_end.expect("melted through") - plateau_start.expect("reached T_m");
    let expected = mass_latent / power;
    eprintln!(
        "plateau {duration:.6e} s, m L / P = {expected:.6e} s; linear heating error {linear_error:.1e}"
    );
    assert!(linear_error < 1e-9);
    // The plateau is resolved to ±dt at each end: 2 dt ≪ 1 % of it.
    assert!(
        (duration / expected - 1.0).abs() < 1e-2,
        "{duration} vs {expected}"
    );
}

/// Two spheres of radii `ra`, `rb` held bonded at their equilibrium overlap (zero force), with
/// temperatures `ta`, `tb`. Returns the simulation.
const YOUNGS_PAIR: f64 = 1e3;

fn bonded_pair(
    ra: f64,
    rb: f64,
    conductivity: f64,
    conduction: &str,
    dt: f64,
    duration: f64,
) -> Simulation {
    // α = 1, k_adh chosen for δ_eq = 1 % of r*: at δ_eq the bonded force is zero, so the pair
    // rests there and the overlap (hence H) stays fixed. A tiny Young's modulus (1 kPa) makes the
    // bond oscillation period (≈ 0.1 s) far longer than any dt used here, so round-off in the
    // zero force cannot grow.
    let r_star = ra * rb / (ra + rb);
    let e_star = YOUNGS_PAIR / (2.0 * (1.0 - 0.09));
    let overlap = 0.01 * r_star;
    let k_adh =
        am_sim::contact::bond::adhesion_stiffness_for_equilibrium(e_star, r_star, 1.0, overlap);
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
[materials.steel]
density_kg_m3 = {RHO:e}
youngs_modulus_pa = {YOUNGS_PAIR:e}
poisson_ratio = 0.3
specific_heat_j_kg_k = {CP:e}
thermal_conductivity_w_m_k = {conductivity:e}
melting_point_k = 1e5
[contact]
model = "hertz"
damping_ratio = 0.0
[bond]
adhesion_exponent = 1.0
adhesion_stiffness = {k_adh:e}
damping_ratio = 1.0
criterion = "always"
[thermal]
initial_temperature_k = 300
conduction = "{conduction}"
[[particles]]
position_m = [0.0, 0.0, 0.0]
radius_m = {ra:e}
material = "steel"
[[particles]]
position_m = [{x:e}, 0.0, 0.0]
radius_m = {rb:e}
material = "steel"
"#,
        x = ra + rb - overlap
    ))
}

#[test]
fn two_spheres_equilibrate_with_the_reduced_capacity_time_constant() {
    let (ra, rb, k): (f64, f64, f64) = (1e-4, 0.7e-4, 20.0);
    let r_star = ra * rb / (ra + rb);
    let overlap = 0.01 * r_star;
    let a = (r_star * overlap).sqrt();
    let (ca, cb) = (capacity(ra), capacity(rb));
    let reduced = ca * cb / (ca + cb);
    for (model, h) in [
        ("batchelor_obrien", 2.0 * k * a),
        (
            "thermal_pipe",
            k * std::f64::consts::PI * a * a / (ra + rb - overlap),
        ),
        (
            // LIGGGHTS' heat/gran/conduction: 2 k √A over the intersection circle, whose
            // radius follows from Pythagoras in either sphere.
            "overlap_area",
            {
                let d = ra + rb - overlap;
                let x = (d * d + ra * ra - rb * rb) / (2.0 * d);
                2.0 * k * (std::f64::consts::PI * (ra * ra - x * x)).sqrt()
            },
        ),
    ] {
        let tau = reduced / h;
        let dt = tau / 1e4; // Euler's relative error in τ ≈ dt/(2τ) = 5e-5
        let mut sim = bonded_pair(ra, rb, k, model, dt, tau);
        let thermal = sim.thermal.as_mut().unwrap();
        thermal.set_temperature(&sim.particles, 0, 1000.0);
        let e0 = thermal.total_enthalpy();
        for _ in 0..sim.model.steps {
            sim.step();
        }
        let gap = temperature(&sim, 0) - temperature(&sim, 1);
        let measured = -sim.time / (gap / 700.0).ln();
        eprintln!("{model}: τ = {measured:.6e} s, expected {tau:.6e} s");
        assert!(
            (measured / tau - 1.0).abs() < 1e-3,
            "{model}: {measured} vs {tau}"
        );
        let e1 = sim.thermal.as_ref().unwrap().total_enthalpy();
        assert!((e1 / e0 - 1.0).abs() < 1e-13, "{model}: heat not conserved");
    }
}

#[test]
fn stiff_network_stays_bounded_and_reaches_the_mixed_temperature() {
    // H dt / C = 100 (issue 4) and 1e4 (issue 6's extreme case).
    for stiffness in [100.0, 1e4] {
        stiff_pair(stiffness);
    }
}

fn stiff_pair(stiffness: f64) {
    // dt chosen so that H dt / C* = 100 at a conductivity of 2e4 W/(m·K), then the conductivity
    // raised so that H dt / C* = `stiffness`, C* = C_a C_b/(C_a + C_b) (raising dt instead would
    // make the mechanics unstable): an explicit step would overshoot by that factor; sub-cycling
    // must keep every temperature within [300, 1300] K and land on the capacity-weighted mean.
    let (ra, rb): (f64, f64) = (1e-4, 0.7e-4);
    let k = 2e4 * stiffness / 100.0;
    let r_star = ra * rb / (ra + rb);
    let a = (r_star * 0.01 * r_star).sqrt();
    let h = 2.0 * k * a;
    let (ca, cb) = (capacity(ra), capacity(rb));
    let reduced = ca * cb / (ca + cb);
    let dt = stiffness * reduced / h;
    let mut sim = bonded_pair(ra, rb, k, "batchelor_obrien", dt, 50.0 * dt);
    let thermal = sim.thermal.as_mut().unwrap();
    thermal.set_temperature(&sim.particles, 0, 1300.0);
    let mixed = (ca * 1300.0 + cb * 300.0) / (ca + cb);
    for _ in 0..sim.model.steps {
        sim.step();
        for k in 0..2 {
            let t = temperature(&sim, k);
            assert!(
                (300.0..=1300.0).contains(&t),
                "overshoot: T{k} = {t} at step {}",
                sim.step
            );
        }
    }
    let state = sim.thermal.as_ref().unwrap();
    eprintln!(
        "stiff: {} substeps per step, T = {:?}",
        state.max_substeps, state.temperature
    );
    assert!(
        f64::from(state.max_substeps) >= stiffness,
        "sub-cycling must resolve H dt / C = {stiffness}"
    );
    for k in 0..2 {
        assert!(
            (temperature(&sim, k) / mixed - 1.0).abs() < 1e-9,
            "T{k} = {} vs {mixed}",
            temperature(&sim, k)
        );
    }
}

#[test]
fn an_isolated_bed_conserves_its_heat() {
    // 1000 spheres settled in an adiabatic box with a vertical temperature gradient: conduction
    // only moves heat around. 1e5 steps; each step adds round-off of ~1e-16 of the total.
    let text = common::conducting::conducting_column("[0.0220, 0.0220, 0.0220]", "0.5");
    let mut sim = common::simulation(&text);
    assert_eq!(sim.particles.len(), 1000);
    for k in 0..1000 {
        let z = sim.particles.position[k].z;
        let thermal = sim.thermal.as_mut().unwrap();
        thermal.set_temperature(&sim.particles, k, 300.0 + 5e4 * z);
    }
    // The heat balance starts from the gradient.
    sim.restart_clock();
    let e0 = sim.thermal.as_ref().unwrap().total_enthalpy();
    let spread0 = spread(&sim);
    for _ in 0..100_000 {
        sim.step();
    }
    let e1 = sim.thermal.as_ref().unwrap().total_enthalpy();
    let d = sim.diagnostics();
    let t = d.thermal.expect("thermal diagnostics");
    eprintln!(
        "bed: heat drift {:.2e}, contacts {}, temperature spread {spread0:.1} → {:.1} K, \
         {:.3e} J moved, heat residual {:.2e}",
        e1 / e0 - 1.0,
        d.contacts,
        spread(&sim),
        t.exchanged,
        t.heat_residual
    );
    assert!((e1 / e0 - 1.0).abs() < 1e-10);
    assert!(spread(&sim) < 0.9 * spread0, "heat did flow");
    // The run's own indicator: nothing supplied, nothing stored, measured against the heat that
    // moved (some 1e5 round-offs of ε E_i per particle, far below 1e-10 of it). Taken as the
    // difference of two bed totals (as the run computed it before), it read about 1 here.
    assert!(t.heat_residual.abs() < 1e-10, "{}", t.heat_residual);
}

/// The run's largest `G_i / C_i` (M.49), which sets the thermal substeps and which the
/// diagnostics report as `dt / τ`, is the largest over every particle, each G_i summed here
/// afresh from every pair of spheres that overlap (not from the neighbour list) and the gas.
/// A packed cube of 1000 spheres in the column's box, each pressed a little into its six
/// neighbours: the inner ones hold the most contacts, and none of them is near a wall. The
/// force pass only bounds the rate (`thermal::HeatRate::at_most`), which asks for one substep
/// here, and the diagnostics measure it. They agree to rounding (1e-12 relative: the two sum a
/// particle's conductances in other orders). The same with convection, whose `h A_i` adds to
/// every G_i.
#[test]
fn the_largest_heat_rate_of_a_step_is_that_of_every_particle() {
    let packed = common::conducting::packed_cube("1e-4");
    let h = 1e4;
    let convected = packed.replace(
        "[output]",
        &format!(
            "[thermal.convection]\nheat_transfer_coefficient_w_m2_k = {h}\n\
             gas_temperature_k = 300\n[output]"
        ),
    );
    assert_ne!(convected, packed);
    for (text, gas) in [(packed, 0.0), (convected, h)] {
        let mut sim = common::simulation(&text);
        assert_eq!(sim.particles.len(), 1000);
        for _ in 0..5 {
            sim.step();
        }
        let d = sim.diagnostics();
        assert!(d.contacts > 2500, "{} contacts", d.contacts);
        let thermal = d.thermal.expect("[thermal]");
        assert_eq!(thermal.substeps, 1);
        let model = sim.model.thermal.as_ref().expect("[thermal]");
        let p = &sim.particles;
        let n = p.len();
        let mut total: Vec<f64> = (0..n).map(|k| gas * sphere_area(p.radius[k])).collect();
        for a in 0..n {
            for b in a + 1..n {
                let overlap = p.radius[a] + p.radius[b] - p.position[a].distance(p.position[b]);
                if overlap > 0.0 {
                    let effective = p.radius[a] * p.radius[b] / (p.radius[a] + p.radius[b]);
                    let contact = am_sim::thermal::conduction::contact_radius(effective, overlap);
                    let radii = [p.radius[a], p.radius[b]];
                    let materials = [p.material[a], p.material[b]];
                    let conductance = am_sim::thermal::pair_conductance(
                        model, materials, radii, overlap, contact,
                    );
                    total[a] += conductance;
                    total[b] += conductance;
                }
            }
        }
        let c = model.materials[0].specific_heat;
        let largest = (0..n)
            .map(|k| total[k] / (p.mass[k] * c))
            .fold(0.0, f64::max);
        let reported = thermal.time_step_ratio / sim.model.dt;
        assert!(largest > 0.0);
        assert!(
            (reported / largest - 1.0).abs() < 1e-12,
            "{reported:e} against {largest:e}"
        );
        let tau = sim.smallest_thermal_time_constant().expect("[thermal]");
        assert!((tau * largest - 1.0).abs() < 1e-12);
    }
}

/// Standard deviation of the temperatures [K].
fn spread(sim: &Simulation) -> f64 {
    let t = &sim.thermal.as_ref().unwrap().temperature;
    #[allow(clippy::cast_precision_loss)]
    let n = t.len() as f64;
    let mean = t.iter().sum::<f64>() / n;
    (t.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The column with conduction and two overlapping initial regions: the upper half of the
/// column at 1000 K, and within it the part with x ≤ 11 mm at 500 K (the later region wins).
fn column_with_regions(extra: &str) -> String {
    common::scene_text("column.toml")
        .replace(
            "poisson_ratio = 0.3",
            "poisson_ratio = 0.3\nspecific_heat_j_kg_k = 800\nthermal_conductivity_w_m_k = 400\nmelting_point_k = 1900",
        )
        .replace(
            "[output]",
            &format!(
                "{extra}\n[thermal]\ninitial_temperature_k = 300\nconduction = \"batchelor_obrien\"\n\
                 [[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 0.022]\nmax_corner_m = [inf, inf, inf]\ntemperature_k = 1000\n\
                 [[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 0.022]\nmax_corner_m = [0.011, inf, inf]\ntemperature_k = 500\n\
                 [output]"
            ),
        )
}

/// The rule the regions state, written out independently of the model.
fn region_temperature(x: glam::DVec3) -> f64 {
    match (x.z >= 0.022, x.x <= 0.011) {
        (true, true) => 500.0,
        (true, false) => 1000.0,
        (false, _) => 300.0,
    }
}

/// Each particle has the temperature of the last region holding its centre, or the scene's
/// initial temperature, with the enthalpy that goes with it; the run's heat balance starts
/// from that state (its residual stays at round-off while conduction moves heat).
#[test]
fn initial_regions_set_the_start_temperatures_the_later_region_winning() {
    let mut sim = common::simulation(&column_with_regions(""));
    let mut counts = [0usize; 3];
    for k in 0..sim.particles.len() {
        let x = sim.particles.position[k];
        let expected = region_temperature(x);
        assert_eq!(temperature(&sim, k), expected, "particle {k} at {x}");
        counts[[300.0, 500.0, 1000.0]
            .iter()
            .position(|t| *t == expected)
            .unwrap()] += 1;
    }
    assert!(
        counts.iter().all(|c| *c > 50),
        "every case is met: {counts:?}"
    );
    let thermal = sim.thermal.as_ref().unwrap();
    let stored: f64 = (0..sim.particles.len())
        .map(|k| thermal.heat_constants(&sim.particles, k).heat_capacity * thermal.temperature[k])
        .sum();
    // Below the melting point E = C T; the sums differ by their order only.
    assert!((thermal.total_enthalpy() / stored - 1.0).abs() < 1e-12);
    for _ in 0..2000 {
        sim.step();
    }
    let d = sim.diagnostics();
    let residual = d.thermal.expect("thermal diagnostics").heat_residual;
    assert!(residual.abs() < 1e-12, "{residual}");
}

/// With a `[deposition]`, the regions apply to the settled bed: not when the simulation is set
/// up, but when the run's clock starts (`restart_clock`, which the deposition ends with), at
/// the positions of that moment.
#[test]
fn with_a_deposition_the_regions_apply_when_the_run_starts() {
    let mut sim = common::simulation(&column_with_regions(
        "[deposition]\nmax_duration_s = 0.1\nkinetic_energy_ratio = 1e-4",
    ));
    let n = sim.particles.len();
    assert!((0..n).all(|k| temperature(&sim, k) == 300.0));
    // Where the deposition would have left the particles: lower by 11 mm.
    for x in &mut sim.particles.position {
        x.z -= 0.011;
    }
    sim.restart_clock();
    let mut heated = 0;
    for k in 0..n {
        let x = sim.particles.position[k];
        assert_eq!(
            temperature(&sim, k),
            region_temperature(x),
            "particle {k} at {x}"
        );
        heated += usize::from(x.z >= 0.022);
    }
    assert!(heated > 50 && heated < n / 2, "{heated} of {n}");
}

#[test]
fn a_sphere_heated_past_its_boiling_point_stays_there_and_its_vapour_carries_off_the_rest() {
    // The sphere of the plateau test with a boiling point (M.80): solid heating, the melting
    // plateau, liquid heating, then T = T_b for good while the excess leaves with the vapour.
    let (latent, boiling, vaporization) = (2.7e5, 2500.0, 6.0e6);
    let laser = STATIONARY_LASER;
    let dt = 2e-6;
    let material = format!(
        "latent_heat_j_kg = {latent:e}\nabsorptivity = 0.5\nboiling_point_k = {boiling:e}\nlatent_heat_vaporization_j_kg = {vaporization:e}"
    );
    let mut sim = one_sphere(
        dt,
        0.1,
        "initial_temperature_k = 300\nconduction = \"none\"",
        &material,
        laser,
    );
    let c = capacity(R);
    let mass = c / CP;
    let start = sim.diagnostics();
    sim.step();
    let power = sim.thermal.as_ref().unwrap().laser.as_ref().unwrap().power[0];
    assert!(power > 0.0 && power <= 0.5 * 5.0, "absorbed {power} W");
    // Closed form: the sphere reaches T_b once P t = C (T_b − T_0) + m L.
    let boiling_at = (c * (boiling - 300.0) + mass * latent) / power;
    assert!(
        boiling_at < 0.5 * 0.1,
        "boils at {boiling_at} s, within the run"
    );
    let mut hottest: f64 = 0.0;
    let mut first_at_boiling = None;
    while sim.step < sim.model.steps {
        sim.step();
        let t = temperature(&sim, 0);
        hottest = hottest.max(t);
        if t >= boiling * (1.0 - 1e-12) && first_at_boiling.is_none() {
            first_at_boiling = Some(sim.time);
        }
    }
    let first_at_boiling = first_at_boiling.expect("reached the boiling point");
    // T(E_b) = (C T_b + m L − m L) / C: T_b to a few ulps, never above it.
    assert!(
        hottest <= boiling * (1.0 + 4.0 * f64::EPSILON),
        "hottest {hottest} K"
    );
    assert!((temperature(&sim, 0) / boiling - 1.0).abs() < 4.0 * f64::EPSILON);
    // The step grid resolves the onset to one step.
    assert!(
        (first_at_boiling - boiling_at).abs() <= dt * (1.0 + 1e-9),
        "boiled at {first_at_boiling} s, closed form {boiling_at} s"
    );
    // Everything absorbed after the onset left with the vapour: P (t − t_b), to the one step
    // in which the onset falls (at most P dt) and round-off.
    let end = sim.diagnostics();
    let thermal = end.thermal.expect("thermal");
    let evaporation = thermal.evaporation.expect("the material evaporates");
    let expected_heat = power * (sim.time - boiling_at);
    eprintln!(
        "boiled at {first_at_boiling:.6e} s (closed form {boiling_at:.6e} s); carried off {:.6e} J (P (t − t_b) = {expected_heat:.6e} J), {:.4e} kg; heat residual {:.1e}",
        evaporation.heat, evaporation.mass, thermal.heat_residual
    );
    assert!(
        (evaporation.heat - expected_heat).abs() <= power * dt * (1.0 + 1e-6),
        "{} J vs {expected_heat} J",
        evaporation.heat
    );
    // Mass: heat over L_v; one particle, so its share is the whole mass fraction.
    assert!((evaporation.mass / (evaporation.heat / vaporization) - 1.0).abs() < 1e-12);
    assert!((evaporation.max_fraction / (evaporation.mass / mass) - 1.0).abs() < 1e-12);
    assert_eq!(evaporation.particles, 1);
    // The balance books the vapour's heat: laser in, enthalpy stored, vapour out.
    assert!(
        thermal.heat_residual.abs() < 1e-12,
        "{}",
        thermal.heat_residual
    );
    let stored = thermal.stored - start.thermal.unwrap().stored;
    assert!(
        (stored + evaporation.heat - thermal.laser_energy).abs() < 1e-12 * thermal.laser_energy
    );

    // Without a boiling point the same heating runs past T_b: the bound is the model's doing.
    let mut unbounded = one_sphere(
        dt,
        0.1,
        "initial_temperature_k = 300\nconduction = \"none\"",
        &format!("latent_heat_j_kg = {latent:e}\nabsorptivity = 0.5"),
        laser,
    );
    while unbounded.step < unbounded.model.steps {
        unbounded.step();
    }
    assert!(unbounded.thermal.as_ref().unwrap().evaporation.is_none());
    assert!(temperature(&unbounded, 0) > 1.5 * boiling);
}
