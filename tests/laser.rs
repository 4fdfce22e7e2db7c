//! The laser: energy absorbed by a flat layer against an independent integral of the Gaussian
//! over every disk, shadowing, the timing of a moving beam, and the bound `absorbed ≤ α P`.

mod common;

use am_sim::simulation::Simulation;

const R: f64 = 1.5e-5;
const ALPHA: f64 = 0.6;
const POWER: f64 = 20.0;

/// Spheres at the given centres (no gravity, no contacts: they stay put), thermal on, and a laser.
fn scene(centres: &[[f64; 3]], spot: f64, path: &str, dt: f64, duration: f64) -> Simulation {
    let particles: String = centres
        .iter()
        .map(|c| format!("[[particles]]\nposition_m = [{:e}, {:e}, {:e}]\nradius_m = {R:e}\nmaterial = \"steel\"\n", c[0], c[1], c[2]))
        .collect();
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
[materials.steel]
density_kg_m3 = 7950
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
specific_heat_j_kg_k = 500
thermal_conductivity_w_m_k = 18
melting_point_k = 1e6
absorptivity = {ALPHA}
[contact]
model = "hertz"
damping_ratio = 0.0
[thermal]
initial_temperature_k = 300
conduction = "none"
[laser]
power_w = {POWER}
spot_radius_m = {spot:e}
[laser.path]
{path}
{particles}
"#
    ))
}

/// The power each particle absorbed in the last step \[W\].
fn laser_power(sim: &Simulation) -> &[f64] {
    let thermal = sim.thermal.as_ref().expect("[thermal]");
    &thermal.laser.as_ref().expect("[laser]").power
}

/// Fraction of a Gaussian beam (1/e² radius w, axis at the origin) falling on a disk of radius r
/// centred at `(x, y)`: a fine polar midpoint rule, independent of am-sim's ray casting.
fn disk_fraction(x: f64, y: f64, r: f64, w: f64) -> f64 {
    let (nr, nt) = (200, 400);
    let mut sum = 0.0;
    for i in 0..nr {
        let rho = (f64::from(i) + 0.5) / f64::from(nr) * r;
        for j in 0..nt {
            let theta = (f64::from(j) + 0.5) / f64::from(nt) * std::f64::consts::TAU;
            let (px, py) = (x + rho * theta.cos(), y + rho * theta.sin());
            sum += rho * (-2.0 * (px * px + py * py) / (w * w)).exp();
        }
    }
    let cell = (r / f64::from(nr)) * (std::f64::consts::TAU / f64::from(nt));
    2.0 / (std::f64::consts::PI * w * w) * sum * cell
}

fn flat_layer(n: i32, spacing: f64) -> Vec<[f64; 3]> {
    let mut centres = Vec::new();
    for i in -n..=n {
        for j in -n..=n {
            centres.push([f64::from(i) * spacing, f64::from(j) * spacing, R]);
        }
    }
    centres
}

#[test]
fn a_flat_layer_absorbs_alpha_p_t_times_the_intercepted_fraction() {
    for (spot, offset) in [(6e-5, 0.0), (3e-5, 0.4 * R), (1.5e-4, 0.0)] {
        let centres = flat_layer(7, 2.2 * R);
        let path = format!(
            "kind = \"stationary\"\nposition_m = [{offset:e}, {offset:e}]\nduration_s = 1.0"
        );
        let (dt, steps) = (1e-6, 200);
        let mut sim = scene(&centres, spot, &path, dt, f64::from(steps) * dt);
        let intercepted: f64 = centres
            .iter()
            .map(|c| disk_fraction(c[0] - offset, c[1] - offset, R, spot))
            .sum();
        for _ in 0..steps {
            sim.step();
            let absorbed: f64 = laser_power(&sim).iter().sum();
            assert!(
                absorbed <= ALPHA * POWER * (1.0 + 1e-12),
                "absorbed {absorbed} W > α P"
            );
        }
        let energy = sim.thermal.as_ref().unwrap().total_laser_energy();
        let expected = ALPHA * POWER * sim.time * intercepted;
        eprintln!(
            "w = {spot:e}: intercepted {intercepted:.5}, absorbed/expected − 1 = {:+.2e}",
            energy / expected - 1.0
        );
        assert!(
            (energy / expected - 1.0).abs() < 1e-2,
            "w = {spot}: {energy} vs {expected}"
        );
    }
}

#[test]
fn a_particle_under_another_gets_no_direct_laser_heat() {
    let path = "kind = \"stationary\"\nposition_m = [0.0, 0.0]\nduration_s = 1.0";
    // B fully under A (same axis, 3r lower).
    let mut sim = scene(
        &[[0.0, 0.0, 4.0 * R], [0.0, 0.0, R]],
        4e-5,
        path,
        1e-6,
        1e-5,
    );
    sim.step();
    // Particles are stored in spatial order: look them up by id (scene order).
    let power_of =
        |sim: &Simulation, id: u64| laser_power(sim)[sim.particles.index_of(id).unwrap()];
    assert!(power_of(&sim, 0) > 0.0);
    assert_eq!(power_of(&sim, 1), 0.0, "the lower sphere is fully shadowed");
    // C half under A: it receives something, but less than when alone.
    let mut half = scene(&[[0.0, 0.0, 4.0 * R], [R, 0.0, R]], 4e-5, path, 1e-6, 1e-5);
    let mut alone = scene(&[[R, 0.0, R]], 4e-5, path, 1e-6, 1e-5);
    half.step();
    alone.step();
    let (shadowed, free) = (power_of(&half, 1), power_of(&alone, 0));
    // Independent reference: the beam power on C's disk outside A's disk (fine midpoint grid).
    let (n, w) = (800, 4e-5);
    let mut lune = 0.0;
    for i in 0..n {
        for j in 0..n {
            let x = (f64::from(i) + 0.5) / f64::from(n) * 2.0 * R; // C's disk spans x ∈ [0, 2R]
            let y = -R + (f64::from(j) + 0.5) / f64::from(n) * 2.0 * R;
            let in_c = (x - R).powi(2) + y * y < R * R;
            let in_a = x * x + y * y < R * R;
            if in_c && !in_a {
                lune += (-2.0 * (x * x + y * y) / (w * w)).exp();
            }
        }
    }
    let expected = ALPHA * POWER * 2.0 / (std::f64::consts::PI * w * w)
        * lune
        * (2.0 * R / f64::from(n)).powi(2);
    eprintln!(
        "half-shadowed {shadowed:.4e} W (lune integral {expected:.4e} W), alone {free:.4e} W"
    );
    assert!(
        shadowed > 0.0 && shadowed < 0.7 * free,
        "{shadowed} vs {free}"
    );
    // The visible share comes from rays 1.5 µm apart (r/10, the default): about 300 rays cross
    // C's disk, and the lune's edge is resolved to ~0.1 %; 1 % leaves room.
    assert!(
        (shadowed / expected - 1.0).abs() < 1e-2,
        "{shadowed} vs {expected}"
    );
}

#[test]
fn a_moving_beam_heats_particles_along_its_path_at_the_right_times() {
    // Eight spheres along x, 100 µm apart; the beam sweeps x from −100 µm at 1 m/s.
    let centres: Vec<[f64; 3]> = (0..8).map(|k| [f64::from(k) * 1e-4, 0.0, R]).collect();
    let (speed, start) = (1.0, -1e-4);
    let path = format!(
        "kind = \"polyline\"\npoints_m = [[{start:e}, 0.0], [9e-4, 0.0]]\nspeed_m_s = {speed}"
    );
    let dt = 1e-7;
    let mut sim = scene(&centres, 3e-5, &path, dt, 1e-3);
    let mut peak = vec![(0.0, 0.0); centres.len()];
    for _ in 0..sim.model.steps {
        let t_mid = sim.time + 0.5 * dt;
        sim.step();
        for (k, p) in laser_power(&sim).iter().enumerate() {
            if *p > peak[k].1 {
                peak[k] = (t_mid, *p);
            }
        }
    }
    let cell = sim.model.laser.as_ref().unwrap().raster_cell;
    for (k, c) in centres.iter().enumerate() {
        let expected = (c[0] - start) / speed;
        // The beam is re-cast when it has moved half a cell: timing within that plus a step.
        let tolerance = 0.5 * cell / speed + 2.0 * dt;
        assert!(
            (peak[k].0 - expected).abs() <= tolerance,
            "particle {k}: peak at {} s, expected {expected} s",
            peak[k].0
        );
        assert!(peak[k].1 > 0.0);
    }
    // All eight received about the same energy (same geometry along the path).
    let t = sim.thermal.as_ref().unwrap();
    let energies: Vec<f64> = (0..8)
        .map(|k| t.enthalpy[k] - t.heat_constants(&sim.particles, k).heat_capacity * 300.0)
        .collect();
    let mean = energies.iter().sum::<f64>() / 8.0;
    assert!(
        energies.iter().all(|e| (e / mean - 1.0).abs() < 1e-2),
        "{energies:?}"
    );
}

#[test]
fn without_a_thermal_section_nothing_thermal_exists() {
    let text = common::scene_text("column.toml");
    let sim = common::simulation(&text);
    assert!(sim.thermal.is_none() && sim.model.thermal.is_none() && sim.model.laser.is_none());
    assert!(sim.diagnostics().thermal.is_none());
}
