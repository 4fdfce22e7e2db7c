//! `[deposition]`: ~200 spheres inserted at random fall onto a plate between four side walls and
//! settle: the kinetic-energy criterion is met, every sphere rests above the plate, overlaps stay
//! small, and the solid fraction of the bed's interior is that of a random packing of spheres.

use am_sim::bed::deposition::{self, kinetic_energy_ratio};
use am_sim::bed::rng::SplitMix64;
use am_sim::model::Model;
use am_sim::particles::Particles;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;
use glam::DVec3;

/// Side of the square box [m]: 6 mean diameters, so that 200 spheres make a bed ~5 deep.
const SIDE: f64 = 1.8e-4;

fn scene() -> String {
    format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 1e-7
duration_s = 1e-6
gravity_m_s2 = [0.0, 0.0, -9.81]
[materials.steel]
density_kg_m3 = 7950
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
[contact]
model = "hertz"
damping_ratio = 0.5
[[insert]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [{SIDE}, {SIDE}, 2.8e-4]
count = 200
seed = 2024
material = "steel"
[insert.size]
distribution = "lognormal"
d10_m = 25e-6
d50_m = 30e-6
d90_m = 36e-6
[deposition]
max_duration_s = 0.1
damping_time_s = 3e-3
kinetic_energy_ratio = 1e-4
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "steel"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
material = "steel"
[[walls]]
point_m = [{SIDE}, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
material = "steel"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "steel"
[[walls]]
point_m = [0.0, {SIDE}, 0.0]
normal = [0.0, -1.0, 0.0]
material = "steel"
"#
    )
}

/// Solid fraction of `p` in the box `[lo, hi]`, by Monte Carlo over `samples` points.
fn solid_fraction(p: &Particles, lo: DVec3, hi: DVec3, samples: usize) -> f64 {
    let mut rng = SplitMix64(1);
    let mut inside = 0usize;
    for _ in 0..samples {
        let x = DVec3::new(
            rng.uniform(lo.x, hi.x),
            rng.uniform(lo.y, hi.y),
            rng.uniform(lo.z, hi.z),
        );
        if p.position
            .iter()
            .zip(&p.radius)
            .any(|(c, r)| c.distance_squared(x) < r * r)
        {
            inside += 1;
        }
    }
    #[allow(clippy::cast_precision_loss)]
    let fraction = inside as f64 / samples as f64;
    fraction
}

#[test]
fn two_hundred_spheres_settle_into_a_random_packing_on_the_plate() {
    let scene = Scene::from_toml(&scene()).expect("scene");
    let (model, particles) = Model::try_build(&scene).expect("build");
    let settings = model.deposition.expect("[deposition]");
    let mut sim = Simulation::new(model, particles);
    let mut checks = Vec::new();
    let report = deposition::settle(&mut sim, &settings, |r| checks.push(r.clone()));
    assert!(report.settled, "{report:?}");
    // The criterion was checked every 1000 steps and first met at the last check.
    assert!(checks.iter().all(|r| r.steps % 1000 == 0));
    assert!(
        checks[..checks.len() - 1]
            .iter()
            .all(|r| r.kinetic_energy_ratio > 1e-4
                || r.steps
                    < deposition::free_fall_steps(&sim.particles, sim.model.gravity, sim.model.dt))
    );
    let gravity = sim.model.gravity.length();
    assert!(kinetic_energy_ratio(&sim.particles, gravity) <= 1e-4);
    // The run's clock starts on the settled bed.
    assert_eq!((sim.step, sim.time), (0, 0.0));

    let p = &sim.particles;
    let d = sim.diagnostics();
    // Static Hertz overlap under the weight of a ~3-sphere column: δ/r ≈ (3 m g / (E* √r))^(2/3)
    // / r ≈ 1e-4 at E = 2e8 Pa; 1 % of r is a hundred times that, and far below a numerical
    // blow-up or a particle tunnelling through the plate.
    for k in 0..p.len() {
        let gap = p.position[k].z - p.radius[k];
        assert!(
            gap > -0.01 * p.radius[k],
            "particle {k} sank into the plate: {gap:e}"
        );
    }
    assert!(d.max_overlap_ratio < 0.01, "{}", d.max_overlap_ratio);
    // The deposition reports its own error indicators. Its energy balance (M.35) is first order
    // in dt through the damper work at the half-step velocity: 0.5-2 % for example 5.1 at a
    // like resolution (tests/energy_balance.rs), 1.5 % here. The background damping (M.76)
    // takes about half of the energy scale here: left out of the books, the residual would be
    // about −0.5. Its peak overlap is at least the settled bed's, and held to the same 1 %.
    assert!(
        report.energy_residual.abs() < 0.05,
        "energy residual {}",
        report.energy_residual
    );
    assert!(
        (d.max_overlap_ratio..0.01).contains(&report.peak_overlap_ratio),
        "peak overlap {} against {} at the end",
        report.peak_overlap_ratio,
        d.max_overlap_ratio
    );
    // Solid fraction of the interior: one diameter from the side walls and the plate, two below
    // the top, where the packing is not loosened by a flat boundary. Frictionless spheres pack
    // randomly to ≈ 0.64 (random close packing, O'Hern et al. 2003; Scott & Kilgour 1969), a
    // narrow polydispersity adds ~0.01; any random packing exceeds random loose packing ≈ 0.55
    // (Onoda & Liniger 1990) and stays below 0.68, far from crystalline 0.74. The Monte-Carlo
    // error of 1e5 points, sqrt(φ(1−φ)/n) ≈ 0.0015, is negligible against that window.
    let top = p
        .position
        .iter()
        .zip(&p.radius)
        .map(|(x, r)| x.z + r)
        .fold(0.0, f64::max);
    let d50 = 30e-6;
    let lo = DVec3::new(d50, d50, d50);
    let hi = DVec3::new(SIDE - d50, SIDE - d50, top - 2.0 * d50);
    assert!(hi.z - lo.z > d50, "bed too thin to measure: top {top:e}");
    let phi = solid_fraction(p, lo, hi, 100_000);
    eprintln!(
        "settled after {} steps ({:.3e} s); max overlap {:.2e} r; interior solid fraction {phi:.4}; energy residual {:.3e}, peak overlap {:.3e}",
        report.steps,
        report.time,
        d.max_overlap_ratio,
        report.energy_residual,
        report.peak_overlap_ratio
    );
    assert!((0.55..0.68).contains(&phi), "solid fraction {phi}");
}

/// The scene above with `[thermal]`: powder at 300 K, gas and surroundings at 300 K, the plate
/// held at `plate_k`.
fn thermal_scene(plate_k: f64) -> String {
    scene()
        .replace(
            "poisson_ratio = 0.3\n",
            "poisson_ratio = 0.3\nspecific_heat_j_kg_k = 500\nthermal_conductivity_w_m_k = 18\n\
             melting_point_k = 1700\nlatent_heat_j_kg = 2.7e5\nemissivity = 0.4\n\
             absorptivity = 0.6\n",
        )
        .replacen(
            "normal = [0.0, 0.0, 1.0]\nmaterial = \"steel\"\n",
            &format!("normal = [0.0, 0.0, 1.0]\nmaterial = \"steel\"\ntemperature_k = {plate_k}\n"),
            1,
        )
        + "[thermal]\ninitial_temperature_k = 300\nconduction = \"batchelor_obrien\"\n\
           [thermal.radiation]\nenvironment_temperature_k = 300\n\
           [thermal.convection]\nheat_transfer_coefficient_w_m2_k = 10\ngas_temperature_k = 300\n"
}

fn settled(text: &str) -> Simulation {
    let scene = Scene::from_toml(text).expect("scene");
    let (model, particles) = Model::try_build(&scene).expect("build");
    let settings = model.deposition.expect("[deposition]");
    let mut sim = Simulation::new(model, particles);
    let report = deposition::settle(&mut sim, &settings, |_| {});
    assert!(report.settled, "{report:?}");
    sim
}

/// A bed at the temperature of the plate, the gas and the surroundings exchanges no heat, so the
/// deposition leaves the heat model out: it settles exactly as without `[thermal]`, takes no
/// thermal step, leaves every temperature at 300 K bitwise, and hands the heat model back for
/// the run. With the plate at 400 K heat flows, and the deposition runs the heat model.
#[test]
fn a_deposition_runs_the_heat_model_only_where_heat_can_flow() {
    let mechanical = settled(&scene());
    let inert = settled(&thermal_scene(300.0));
    assert!(
        inert.model.thermal.is_some(),
        "the heat model is handed back"
    );
    assert_eq!(inert.particles.position, mechanical.particles.position);
    let state = inert.thermal.as_ref().expect("thermal state");
    assert!(state.temperature.iter().all(|&t| t == 300.0));
    assert_eq!(state.max_substeps, 0, "no thermal step");
    // The run's first diagnostics still report the thermal stiffness of the settled bed (dt
    // over its smallest time constant C_i/G_i, M.49), which no force pass measured.
    let tau = inert.smallest_thermal_time_constant().expect("[thermal]");
    let ratio = inert
        .diagnostics()
        .thermal
        .expect("[thermal]")
        .time_step_ratio;
    assert!(tau.is_finite() && tau > 0.0);
    assert!(
        (ratio / (inert.model.dt / tau) - 1.0).abs() < 1e-12,
        "{ratio:e} against dt/tau {:e}",
        inert.model.dt / tau
    );

    let heated = settled(&thermal_scene(400.0));
    assert!(heated.model.thermal.is_some());
    let state = heated.thermal.as_ref().expect("thermal state");
    let warmest = state.temperature.iter().copied().fold(0.0, f64::max);
    // The spheres on the plate draw heat from it through their contacts over the ~10 ms of the
    // deposition; even a microkelvin shows the heat model ran.
    assert!(warmest > 300.0 + 1e-6, "warmest sphere {warmest} K");
    assert!(state.max_substeps >= 1);
}
