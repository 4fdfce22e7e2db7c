//! Tangential contact, rolling resistance and rotation (docs/model.md section 27) against closed
//! forms of rigid-body mechanics, and the conservation laws the pair design guarantees.

mod common;

use am_sim::contact::{damping, hertz, tangential};
use am_sim::simulation::Simulation;
use glam::DVec3;

const G: f64 = 9.81;
const RADIUS: f64 = 1e-3;
const DENSITY: f64 = 2000.0;
const YOUNGS: f64 = 1e9;
const POISSON: f64 = 0.3;

fn mass() -> f64 {
    DENSITY * 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3)
}

/// Static overlap of a sphere resting on a wall of its own material (M.4 with F = m g).
fn resting_overlap() -> f64 {
    let e_star = hertz::effective_modulus(YOUNGS, POISSON, YOUNGS, POISSON);
    (mass() * G / (4.0 / 3.0 * e_star * RADIUS.sqrt())).powf(2.0 / 3.0)
}

/// One sphere resting on the floor z = 0 (at its static overlap), launched along x at `speed`
/// without spin.
fn sliding_sphere(speed: f64, friction: f64, rolling: f64, duration: f64) -> Simulation {
    sphere_on_floor(speed, friction, rolling, duration, 0.0)
}

/// As [`sliding_sphere`] on a plane inclined by `angle` [rad] about y: gravity is tilted, so
/// "down the slope" is +x.
fn sphere_on_floor(
    speed: f64,
    friction: f64,
    rolling: f64,
    duration: f64,
    angle: f64,
) -> Simulation {
    let z = RADIUS - resting_overlap() * angle.cos().powf(2.0 / 3.0);
    let (gx, gz) = (G * angle.sin(), -G * angle.cos());
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 1e-6
duration_s = {duration:e}
gravity_m_s2 = [{gx:e}, 0.0, {gz:e}]
[materials.m]
density_kg_m3 = {DENSITY:e}
youngs_modulus_pa = {YOUNGS:e}
poisson_ratio = {POISSON:e}
[contact]
model = "hertz"
restitution = 0.5
friction_coefficient = {friction:e}
rolling_friction_coefficient = {rolling:e}
[[particles]]
position_m = [0.0, 0.0, {z:e}]
velocity_m_s = [{speed:e}, 0.0, 0.0]
radius_m = {RADIUS:e}
material = "m"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "m"
"#
    ))
}

/// Slip speed of particle 0 on the floor: v_x + ω_y r' at the contact point (r' = r − δ/2).
fn slip(sim: &Simulation) -> f64 {
    let p = &sim.particles;
    let omega = sim.rotation.as_ref().unwrap().angular_velocity[0];
    let arm = RADIUS - 0.5 * (RADIUS - p.position[0].z);
    p.velocity[0].x - omega.y * arm
}

/// The forces at t = 0 are those of the state as it stands (docs/model.md section 10): no time has
/// passed, so the unloaded spring of a sphere set down sliding gives no spring force, only the
/// damper's `−γ_t v_t` (M.57, M.59 with dt = 0), and stays unloaded. Fast enough, the damper
/// alone would exceed Coulomb's limit: the force is then μ |F_n| against the slip. (Advancing
/// the spring by v_t dt at t = 0, as am-sim's set-up did before, adds `−k_t v_t dt`, a share
/// k_t dt / γ_t of the slow case's force, which the test checks is far beyond its tolerance.)
#[test]
fn the_forces_at_t0_are_those_of_the_state_as_it_stands() {
    let mu = 0.3;
    let slow = sliding_sphere(1e-5, mu, 0.0, 1e-6);
    assert_eq!(
        slow.held_springs(),
        (0, 0, 0.0),
        "the spring stays unloaded"
    );
    let overlap = RADIUS - slow.particles.position[0].z;
    let shear = slow.model.friction.as_ref().unwrap().wall(0, 0);
    let stiffness = tangential::stiffness(shear.effective_shear_modulus, RADIUS, overlap);
    let gamma = tangential::damping_coefficient(
        slow.model.wall_params(0, 0).damping_ratio,
        mass(),
        stiffness,
    );
    let force = slow.particles.force[0];
    let normal_force = force.z + mass() * G;
    assert!(gamma * 1e-5 < mu * normal_force, "the slow case sticks");
    let dt = slow.model.dt;
    assert!(
        stiffness * dt / gamma > 1e-3,
        "an advanced spring would show"
    );
    // Tolerance: the sum of the weight and the contact's force, rounded.
    assert!(
        (force.x / (-gamma * 1e-5) - 1.0).abs() < 1e-9,
        "{} vs {}",
        force.x,
        -gamma * 1e-5
    );
    let fast = sliding_sphere(0.5, mu, 0.0, 1e-6);
    assert!(
        gamma * 0.5 > 10.0 * mu * normal_force,
        "the damper alone is far beyond"
    );
    let force = fast.particles.force[0];
    let normal_force = force.z + mass() * G;
    assert!(
        (force.x / (-mu * normal_force) - 1.0).abs() < 1e-9,
        "{} vs {}",
        force.x,
        -mu * normal_force
    );
    assert_eq!(fast.held_springs(), (0, 0, 0.0));
}

#[test]
fn a_sliding_sphere_rolls_without_slipping_after_2v0_over_7_mu_g_at_five_sevenths_v0() {
    let (v0, mu) = (0.5, 0.3);
    let t_roll = 2.0 * v0 / (7.0 * mu * G);
    let mut sim = sliding_sphere(v0, mu, 0.0, 1.3 * t_roll);
    let mut rolling_since = None;
    let mut speed_at_half = 0.0;
    for _ in 0..sim.model.steps {
        sim.step();
        if speed_at_half == 0.0 && sim.time >= 0.5 * t_roll {
            speed_at_half = sim.particles.velocity[0].x;
        }
        if rolling_since.is_none() && slip(&sim) < 1e-3 * v0 {
            rolling_since = Some(sim.time);
        }
    }
    // Kinetic friction μ m g decelerates the centre while sliding.
    let expected_half = v0 - mu * G * 0.5 * t_roll;
    assert!(
        (speed_at_half / expected_half - 1.0).abs() < 1e-3,
        "{speed_at_half} vs {expected_half}"
    );
    // The slip speed falls linearly at (7/2) μ g, so it is below 1e-3 v0 from 0.999 t_roll on.
    // Tolerance: the tangential spring needs a few of its periods (2π √(m/k_t) ≈ 0.3 ms, 0.2 % of
    // t_roll) to load and to unload, which shifts the crossing by about that much.
    let t = rolling_since.expect("the sphere never rolled");
    let v = sim.particles.velocity[0].x;
    eprintln!(
        "v(t_roll/2) = {speed_at_half} ({expected_half}), rolls from {t} s (t_roll {t_roll}), v = {v}"
    );
    assert!(
        (t / (0.999 * t_roll) - 1.0).abs() < 2e-3,
        "rolls from {t} s, expected {t_roll} s"
    );
    // Then the centre keeps v0 / (1 + m r'²/I) = (5/7) v0: r'/r = 1 − δ/2r = 1 − 1.2e-5 moves it
    // by 2e-5 relative, the spring's unloading transient by less.
    assert!(
        (v / (5.0 / 7.0 * v0) - 1.0).abs() < 5e-5,
        "{v} vs {}",
        5.0 / 7.0 * v0
    );
    assert!(
        slip(&sim).abs() < 1e-4 * v0,
        "still slipping: {}",
        slip(&sim)
    );
}

#[test]
fn rolling_resistance_decelerates_a_rolling_sphere_at_five_sevenths_mu_r_g() {
    // Rolling at v with the resisting torque M = μ_r r |F_n|, F_n = m g: the wall's friction f
    // keeps v = ω r, so m v̇ = f and I ω̇ = −f r − M give v̇ = −M r / (I + m r²) = −(5/7) μ_r g.
    let (v0, mu, mu_r) = (0.5, 0.5, 0.05);
    let t_roll = 2.0 * v0 / (7.0 * mu * G);
    let mut sim = sliding_sphere(v0, mu, mu_r, 2.0 * t_roll + 0.05);
    let mut samples = Vec::new();
    for _ in 0..sim.model.steps {
        sim.step();
        if sim.time > 2.0 * t_roll && sim.step % 1000 == 0 {
            samples.push((sim.time, sim.particles.velocity[0].x));
        }
    }
    // Least-squares slope of v(t) over the rolling phase.
    let n = samples.len() as f64;
    let (st, sv) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, v)| (a + t, b + v));
    let (mt, mv) = (st / n, sv / n);
    let (num, den) = samples.iter().fold((0.0, 0.0), |(a, b), (t, v)| {
        (a + (t - mt) * (v - mv), b + (t - mt) * (t - mt))
    });
    let slope = num / den;
    let expected = -5.0 / 7.0 * mu_r * G;
    eprintln!("deceleration {slope} m/s², expected {expected}");
    // 0.1 %: the lever arm r − δ/2 and r* = r differ by δ/r ≈ 1e-5, the normal force is m g to
    // within the decaying normal oscillation.
    assert!(
        (slope / expected - 1.0).abs() < 1e-3,
        "{slope} vs {expected}"
    );
    assert!(slip(&sim).abs() < 1e-4 * v0, "slips: {}", slip(&sim));
}

/// Two spheres in free space, the second hit off-centre by the first (impact parameter `b`).
fn off_centre_collision(friction: f64, rolling: f64, skin: f64, dt: f64) -> Simulation {
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = 2e-4
skin_m = {skin:e}
[materials.m]
density_kg_m3 = {DENSITY:e}
youngs_modulus_pa = {YOUNGS:e}
poisson_ratio = {POISSON:e}
[materials.n]
density_kg_m3 = 5000.0
youngs_modulus_pa = 3e9
poisson_ratio = 0.2
[contact]
model = "hertz"
restitution = 0.7
friction_coefficient = {friction:e}
rolling_friction_coefficient = {rolling:e}
[[particles]]
position_m = [-1.05e-3, 0.3e-3, 0.1e-3]
velocity_m_s = [2.0, 0.1, -0.3]
radius_m = 1e-3
material = "m"
[[particles]]
position_m = [1.3e-3, -0.5e-3, 0.2e-3]
velocity_m_s = [-1.0, 0.5, 0.0]
radius_m = 1.2e-3
material = "n"
"#
    ))
}

fn momenta(sim: &Simulation) -> (DVec3, DVec3) {
    let p = &sim.particles;
    let omega = &sim.rotation.as_ref().unwrap().angular_velocity;
    let mut linear = DVec3::ZERO;
    let mut angular = DVec3::ZERO;
    for (k, w) in omega.iter().enumerate() {
        linear += p.mass[k] * p.velocity[k];
        angular += p.position[k].cross(p.mass[k] * p.velocity[k])
            + 0.4 * p.mass[k] * p.radius[k] * p.radius[k] * *w;
    }
    (linear, angular)
}

#[test]
fn an_off_centre_collision_conserves_linear_and_angular_momentum_to_round_off() {
    let mut sim = off_centre_collision(0.5, 0.1, 1e-4, 2e-8);
    let (p0, l0) = momenta(&sim);
    let mut max_torque: f64 = 0.0;
    for _ in 0..sim.model.steps {
        sim.step();
        let torque = sim.rotation.as_ref().unwrap().torque[0].length();
        max_torque = max_torque.max(torque);
    }
    let (p1, l1) = momenta(&sim);
    let spin = sim.rotation.as_ref().unwrap().angular_velocity[0].length();
    assert!(
        max_torque > 0.0 && spin > 10.0,
        "no spin was imparted: {spin} rad/s"
    );
    // Verlet kicks conserve Σ x × m v + I ω exactly when Σ x × F + τ = 0 at each evaluation (the
    // lever arms r_i − δ/2 + r_j − δ/2 add up to the centre distance), drifts add v × m v = 0:
    // what remains is round-off of ~1e4 steps.
    let p_scale = p0.length().max(1e-30);
    assert!((p1 - p0).length() < 1e-12 * p_scale, "{p0} → {p1}");
    let l_scale = sim.particles.mass[0] * 2.0 * 1e-3 + l0.length();
    assert!((l1 - l0).length() < 1e-12 * l_scale, "{l0} → {l1}");
    // Friction took energy; the books still close (M.63).
    let d = sim.diagnostics();
    assert!(d.dissipated_energy > 0.0);
}

#[test]
fn the_energy_balance_closes_with_friction_and_rolling_resistance() {
    let residual = |dt: f64| {
        let mut sim = off_centre_collision(0.3, 0.2, 1e-4, dt);
        let d0 = sim.diagnostics();
        let e0 = d0.mechanical_energy();
        for _ in 0..sim.model.steps {
            sim.step();
        }
        let d = sim.diagnostics();
        assert!(
            d.dissipated_energy > 0.1 * e0,
            "too little was lost to test the books"
        );
        (d.mechanical_energy() + d.dissipated_energy - e0).abs() / e0
    };
    let coarse = residual(4e-8);
    let fine = residual(2e-8);
    eprintln!("energy residuals {coarse:e}, {fine:e}");
    // The damper and friction work use the half-step velocity: first order in dt, as the normal
    // law (docs/model.md section 13a).
    assert!(coarse < 1e-2, "{coarse}");
    assert!(fine < 0.6 * coarse, "{coarse} → {fine}");
}

#[test]
fn the_tangential_history_survives_neighbor_rebuilds_bit_for_bit() {
    // A small skin rebuilds the list many times during the contact, a large one never after the
    // start. Pairs that do not touch add exact zeros, and touching pairs keep their key order, so
    // the trajectories are bitwise equal only if the history follows its pair through rebuilds.
    let run = |skin: f64| {
        let mut sim = off_centre_collision(0.5, 0.1, skin, 2e-8);
        for _ in 0..sim.model.steps {
            sim.step();
        }
        sim
    };
    let (small, large) = (run(2e-6), run(1e-3));
    assert!(small.diagnostics().neighbor_builds > 20);
    assert_eq!(large.diagnostics().neighbor_builds, 1);
    let bits = |s: &Simulation| -> Vec<u64> {
        s.particles
            .position
            .iter()
            .chain(&s.particles.velocity)
            .chain(&s.rotation.as_ref().unwrap().angular_velocity)
            .flat_map(|v| v.to_array())
            .map(f64::to_bits)
            .collect()
    };
    assert_eq!(bits(&small), bits(&large));
}

#[test]
fn without_friction_keys_nothing_rotates_and_nothing_is_allocated() {
    let sim = common::two_spheres(2000.0, 1.0, 0.1, None, 1e-7, 1e-5);
    assert!(sim.rotation.is_none());
    assert!(sim.model.friction.is_none());
}

/// Restitution of a head-on Hertz impact with the damping of M.10, by RK4 on the dimensionless
/// equation x'' = −x^{3/2} − 2ξ √(3/2) x^{1/4} x' (δ = L x, t = T τ with
/// T² = 3 m* / (4 E* √r* √L)), the force clipped at 0 (sign rule 1). e depends on ξ alone.
fn restitution_by_rk4(xi: f64) -> f64 {
    let c = 2.0 * xi * 1.5_f64.sqrt();
    let accel = |x: f64, v: f64| {
        let x = x.max(0.0);
        (-(x * x.sqrt()) - c * x.sqrt().sqrt() * v).min(0.0)
    };
    let (mut x, mut v, h) = (0.0, 1.0, 2e-5);
    while x >= 0.0 {
        let (k1x, k1v) = (v, accel(x, v));
        let (k2x, k2v) = (
            v + 0.5 * h * k1v,
            accel(x + 0.5 * h * k1x, v + 0.5 * h * k1v),
        );
        let (k3x, k3v) = (
            v + 0.5 * h * k2v,
            accel(x + 0.5 * h * k2x, v + 0.5 * h * k2v),
        );
        let (k4x, k4v) = (v + h * k3v, accel(x + h * k3x, v + h * k3v));
        x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }
    -v
}

#[test]
fn restitution_0_5_follows_liggghts_and_gives_the_hertz_restitution_of_its_damping_ratio() {
    let xi = damping::damping_ratio_from_restitution(0.5);
    // LIGGGHTS: ξ = √(5/6) (−β), β = ln e / √(ln² e + π²).
    let beta = 0.5_f64.ln() / (0.5_f64.ln().powi(2) + std::f64::consts::PI.powi(2)).sqrt();
    assert!((xi - (5.0_f64 / 6.0).sqrt() * -beta).abs() < 1e-15);
    let expected = restitution_by_rk4(xi);
    let measured: Vec<f64> = [200.0, 400.0]
        .iter()
        .map(|steps_per_contact| {
            let m_star = common::sphere_mass(2000.0) / 2.0;
            let dt = hertz::contact_time(m_star, common::E_STAR, common::R_STAR, 1.0)
                / steps_per_contact;
            let text = common_two_spheres_text(dt);
            let mut sim = common::simulation(&text);
            for _ in 0..sim.model.steps {
                sim.step();
            }
            -common::approach_speed(&sim)
        })
        .collect();
    eprintln!("e = 0.5 → ξ = {xi}: RK4 e = {expected}, am-sim {measured:?}");
    // Not 0.5: the linear-spring relation does not hold for Hertz (docs/model.md section 4).
    assert!(expected > 0.53 && expected < 0.57);
    // The damper sees the half-step velocity: an O(dt) error, 1.2e-4 at 200 steps per contact.
    for e in &measured {
        assert!((e / expected - 1.0).abs() < 5e-4, "{e} vs {expected}");
    }
    assert!((measured[0] - measured[1]).abs() < 5e-4);
}

/// Two spheres of the paper's section 5 meeting head-on at 1 m/s, with `restitution = 0.5`.
fn common_two_spheres_text(dt: f64) -> String {
    let r = common::RADIUS;
    format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = 1e-4
skin_m = 2e-4
[materials.paper]
density_kg_m3 = 2000.0
youngs_modulus_pa = 1e9
poisson_ratio = 0.0
[contact]
model = "hertz"
restitution = 0.5
[[particles]]
position_m = [{x0:e}, 0.0, 0.0]
velocity_m_s = [0.5, 0.0, 0.0]
radius_m = {r:e}
material = "paper"
[[particles]]
position_m = [{r:e}, 0.0, 0.0]
velocity_m_s = [-0.5, 0.0, 0.0]
radius_m = {r:e}
material = "paper"
"#,
        x0 = -r
    )
}

#[test]
fn check_reports_the_mindlin_stiffness_ratio_and_the_shorter_tangential_time() {
    let sim = sliding_sphere(0.5, 0.3, 0.0, 1e-3);
    let report = am_sim::check::report(&sim);
    let friction = report.friction.expect("friction scene");
    // Equal materials: k_t/k_n = 4 G*/E* = 2 (1 − ν)/(2 − ν).
    let ratio = 2.0 * (1.0 - POISSON) / (2.0 - POISSON);
    assert!((friction.stiffness_ratio.0 / ratio - 1.0).abs() < 1e-12);
    assert!((friction.stiffness_ratio.1 / ratio - 1.0).abs() < 1e-12);
    // Tangential mass 2 m*/7 (rotation included): time factor √(2/7 / ratio) = 0.589.
    assert!((friction.time_factor - (2.0 / 7.0 / ratio).sqrt()).abs() < 1e-12);
    assert!(friction.time_factor < 1.0);
    assert!(report.to_string().contains("k_t/k_n = 0.8235"));
    let no_friction =
        am_sim::check::report(&common::two_spheres(2000.0, 1.0, 0.1, None, 1e-7, 1e-5));
    assert!(no_friction.friction.is_none());
}

/// Speed along the slope after `duration` of a sphere released at rest on an incline.
fn incline_speed(tan_angle: f64, friction: f64, rolling: f64, duration: f64) -> f64 {
    let mut sim = sphere_on_floor(0.0, friction, rolling, duration, tan_angle.atan());
    for _ in 0..sim.model.steps {
        sim.step();
    }
    sim.particles.velocity[0].x
}

#[test]
fn on_an_incline_a_sphere_rolls_below_tan_theta_3_5_mu_and_slides_above() {
    let t = 0.1;
    let angle = 0.5_f64.atan();
    // Rolling needs the friction f = (2/7) m g sin θ ≤ μ m g cos θ, i.e. tan θ ≤ 3.5 μ:
    // then a = (5/7) g sin θ; above it the sphere slides with a = g (sin θ − μ cos θ).
    let rolling = incline_speed(0.5, 0.3, 0.0, t);
    let expected = 5.0 / 7.0 * G * angle.sin() * t;
    eprintln!("rolls at {rolling} m/s, expected {expected}");
    // 0.1 %: the tangential spring loads within a few of its 0.3 ms periods, while the sphere
    // already moves; the normal overlap settles from the tilted-gravity estimate as quickly.
    assert!(
        (rolling / expected - 1.0).abs() < 1e-3,
        "{rolling} vs {expected}"
    );
    let sliding = incline_speed(0.5, 0.1, 0.0, t);
    let expected = G * (angle.sin() - 0.1 * angle.cos()) * t;
    eprintln!("slides at {sliding} m/s, expected {expected}");
    assert!(
        (sliding / expected - 1.0).abs() < 1e-3,
        "{sliding} vs {expected}"
    );
}

#[test]
fn rolling_resistance_holds_a_sphere_below_tan_theta_mu_r() {
    let (mu, mu_r, t) = (0.5, 0.1, 0.1);
    // Held: the friction torque f r = m g sin θ r is balanced by M_r ≤ μ_r r m g cos θ.
    let held = incline_speed(0.08, mu, mu_r, t);
    // The guard stops the relative rotation each step, after the torque of that step has acted
    // for dt: a creep of ω ≈ dt τ/I, v ≈ dt g sin θ / 0.4 = 2e-6 m/s (M.61, section 27.4).
    assert!(held.abs() < 1e-5, "moves at {held} m/s");
    // Above: rolls at a = (5/7) g (sin θ − μ_r cos θ).
    let angle = 0.12_f64.atan();
    let rolls = incline_speed(0.12, mu, mu_r, t);
    let expected = 5.0 / 7.0 * G * (angle.sin() - mu_r * angle.cos()) * t;
    // 0.5 %: measured 0.15 % fast, because the guard lets the sphere start with less than the
    // full torque while ω is still tiny.
    assert!(
        (rolls / expected - 1.0).abs() < 5e-3,
        "{rolls} vs {expected}"
    );
    eprintln!("held at {held} m/s; above: {rolls} vs {expected} m/s");
}

/// Two bonded spheres of example 5.1 at their equilibrium overlap (normal force ≈ 0), sheared by
/// opposite velocities ±`speed`/2 along y, with or without a bond criterion.
fn sheared_pair(criterion: &str, speed: f64) -> Simulation {
    let half_distance = RADIUS - 2.5e-5; // δ = δ_eq = 50 µm
    let half_v = speed / 2.0;
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 1e-7
duration_s = 2e-3
skin_m = 1e-4
[materials.paper]
density_kg_m3 = 2000
youngs_modulus_pa = 1e9
poisson_ratio = 0.0
[contact]
model = "hertz"
restitution = 0.5
friction_coefficient = 0.1
[bond]
adhesion_exponent = 1.0
equilibrium_overlap_m = 5e-5
damping_ratio = 0.3
criterion = "{criterion}"
[[particles]]
position_m = [-{half_distance:e}, 0.0, 0.0]
velocity_m_s = [0.0, {half_v:e}, 0.0]
radius_m = {RADIUS:e}
material = "paper"
[[particles]]
position_m = [{half_distance:e}, 0.0, 0.0]
velocity_m_s = [0.0, -{half_v:e}, 0.0]
radius_m = {RADIUS:e}
material = "paper"
"#
    ))
}

/// Tangential slip speed at the contact of the first two particles (M.60).
fn pair_slip(sim: &Simulation) -> f64 {
    let p = &sim.particles;
    let omega = &sim.rotation.as_ref().unwrap().angular_velocity;
    let separation = p.position[1] - p.position[0];
    let n = separation.normalize();
    let overlap = 2.0 * RADIUS - separation.length();
    let arm = RADIUS - 0.5 * overlap;
    let v = p.velocity[0] - p.velocity[1] + (arm * omega[0] + arm * omega[1]).cross(n);
    (v - v.dot(n) * n).length()
}

#[test]
fn a_bonded_neck_sticks_beyond_the_coulomb_limit() {
    let (speed, mu) = (0.2, 0.1);
    let mut sim = sheared_pair("always", speed);
    let mut normal_impulse = 0.0;
    for _ in 0..sim.model.steps {
        sim.step();
        let (_, _, _, normal_force) = sim.bonded_pairs()[0];
        normal_impulse += normal_force.abs() * sim.model.dt;
    }
    assert_eq!(sim.bonds().len(), 1, "the shear must not break the bond");
    // No Coulomb limit: the spring and its damper bring the slip to rest and the pair spins.
    let spin = sim.rotation.as_ref().unwrap().angular_velocity[0].z;
    let slip = pair_slip(&sim);
    // The tangential impulse that stopped particle 0's shear motion, against what a contact with
    // the same normal force could have transmitted, μ ∫|F_n| dt.
    let tangential_impulse = sim.particles.mass[0] * (0.5 * speed - sim.particles.velocity[0].y);
    eprintln!(
        "bonded: slip {slip} m/s, spin {spin} rad/s, tangential impulse {tangential_impulse:e}, μ ∫|F_n| {:e}",
        mu * normal_impulse
    );
    assert!(slip < 1e-3 * speed, "{slip}");
    assert!(spin.abs() > 10.0);
    // Measured 30×: the normal force of a bond at δ_eq is nearly zero.
    assert!(tangential_impulse > 10.0 * mu * normal_impulse);
}
