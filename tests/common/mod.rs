//! Helpers shared by the integration tests: scenes are built as TOML text and loaded through the
//! same path as `am-sim scene.toml`, so the tests also exercise the scene layer.
#![allow(dead_code)]

use am_sim::model::Model;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;

/// Material and contact data of the paper's section 5 (r = 1 mm, E = 1 GPa, ν = 0).
pub const RADIUS: f64 = 1e-3;
pub const YOUNGS: f64 = 1e9;
/// Effective modulus E* = E/2 for ν = 0 (paper eq. 12).
pub const E_STAR: f64 = 0.5e9;
/// r* = r/2 for equal spheres (paper eq. 12).
pub const R_STAR: f64 = 0.5e-3;

/// Bond section of a two-sphere scene.
#[derive(Debug, Clone, Copy)]
pub struct Bond {
    pub adhesion_exponent: f64,
    /// k_adh [N·m^-α].
    pub adhesion_stiffness: f64,
    pub damping_ratio: f64,
    pub criterion: &'static str,
}

/// Two equal spheres of the paper's section 5, just touching at the origin, approaching each
/// other along x at `relative_speed` [m/s] (each moves at half of it).
#[must_use]
pub fn two_spheres(
    density: f64,
    relative_speed: f64,
    contact_damping: f64,
    bond: Option<Bond>,
    dt: f64,
    duration: f64,
) -> Simulation {
    two_spheres_at(
        density,
        2.0 * RADIUS,
        relative_speed,
        contact_damping,
        bond,
        dt,
        duration,
    )
}

/// As [`two_spheres`] with the centre distance given [m] (less than 2r: initially overlapping).
#[must_use]
pub fn two_spheres_at(
    density: f64,
    distance: f64,
    relative_speed: f64,
    contact_damping: f64,
    bond: Option<Bond>,
    dt: f64,
    duration: f64,
) -> Simulation {
    let bond_section = bond.map_or_else(String::new, |b| {
        format!(
            "[bond]\nadhesion_exponent = {:e}\nadhesion_stiffness = {:e}\ndamping_ratio = {:e}\ncriterion = \"{}\"\n",
            b.adhesion_exponent, b.adhesion_stiffness, b.damping_ratio, b.criterion
        )
    });
    let half_d = distance / 2.0;
    let half_v = relative_speed / 2.0;
    let text = format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
skin_m = 2e-4
[materials.paper]
density_kg_m3 = {density:e}
youngs_modulus_pa = {YOUNGS:e}
poisson_ratio = 0.0
[contact]
model = "hertz"
damping_ratio = {contact_damping:e}
{bond_section}
[[particles]]
position_m = [{x0:e}, 0.0, 0.0]
velocity_m_s = [{half_v:e}, 0.0, 0.0]
radius_m = {RADIUS:e}
material = "paper"
[[particles]]
position_m = [{half_d:e}, 0.0, 0.0]
velocity_m_s = [{v1:e}, 0.0, 0.0]
radius_m = {RADIUS:e}
material = "paper"
"#,
        x0 = -half_d,
        v1 = -half_v
    );
    simulation(&text)
}

/// Loads scene text and sets up the simulation.
#[must_use]
pub fn simulation(text: &str) -> Simulation {
    let scene =
        Scene::from_toml(text).unwrap_or_else(|e| panic!("test scene rejected: {e}\n{text}"));
    let (model, particles) = Model::build(&scene);
    Simulation::new(model, particles)
}

/// Overlap of the first two particles [m].
#[must_use]
pub fn overlap(sim: &Simulation) -> f64 {
    let p = &sim.particles;
    p.radius[0] + p.radius[1] - p.position[0].distance(p.position[1])
}

/// Approach speed of the first two particles along their line of centres [m/s] (> 0 approaching).
#[must_use]
pub fn approach_speed(sim: &Simulation) -> f64 {
    let p = &sim.particles;
    let n = (p.position[1] - p.position[0]).normalize();
    (p.velocity[0] - p.velocity[1]).dot(n)
}

/// Mass of one sphere of the paper's radius [kg].
#[must_use]
pub fn sphere_mass(density: f64) -> f64 {
    density * 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3)
}

/// The text of a shipped scene, `scenes/<name>`.
#[must_use]
pub fn scene_text(name: &str) -> String {
    std::fs::read_to_string(format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR")))
        .expect("scene file")
}

/// `scenes/laser_track.toml` shortened to `duration` [s], frames every `every` steps, no CSV.
#[must_use]
pub fn short_track(duration: f64, every: u64) -> String {
    scene_text("laser_track.toml")
        .replace("duration_s = 3.5e-3", &format!("duration_s = {duration:e}"))
        .replace("every_steps = 500", &format!("every_steps = {every}"))
        .replace("series_csv = \"laser_track.csv\"", "")
}
