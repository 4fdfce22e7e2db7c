//! Scenes of the study, written as TOML and loaded like a user's scene file, so the study runs
//! exactly what `am-sim scene.toml` would.

use crate::contact::BondParams;
use crate::model::Model;
use crate::scene::Scene;
use crate::simulation::Simulation;

/// Radius of the spheres of the paper's section 5 \[m\].
pub const PAPER_RADIUS: f64 = 1e-3;
/// Young's modulus of section 5 \[Pa\] (ν = 0).
pub const PAPER_YOUNGS: f64 = 1e9;
/// E* = E/2 for ν = 0 (paper eq. 12) \[Pa\].
pub const PAPER_E_STAR: f64 = 0.5 * PAPER_YOUNGS;
/// r* = r/2 for two equal spheres (paper eq. 12) \[m\].
pub const PAPER_R_STAR: f64 = 0.5 * PAPER_RADIUS;

/// Mass of one sphere of the paper's radius at `density` \[kg\].
#[must_use]
pub fn paper_sphere_mass(density: f64) -> f64 {
    density * 4.0 / 3.0 * std::f64::consts::PI * PAPER_RADIUS.powi(3)
}

/// Sets up a scene given as TOML text.
///
/// # Panics
/// If the scene is rejected: the study's scenes are fixed text, so that is a bug here.
#[must_use]
pub fn simulation(text: &str) -> Simulation {
    let scene = Scene::from_toml(text).unwrap_or_else(|e| panic!("study scene rejected: {e}"));
    let (model, particles) = Model::build(&scene);
    Simulation::new(model, particles)
}

/// Two spheres of section 5 (r = 1 mm, E = 1 GPa, ν = 0), just touching at the origin and
/// approaching along x at `relative_speed` [m/s], with contact damping ratio ξ_con and an
/// optional bond (criterion "always").
#[must_use]
pub fn two_spheres(
    density: f64,
    relative_speed: f64,
    contact_damping: f64,
    bond: Option<BondParams>,
    dt: f64,
    duration: f64,
) -> Simulation {
    simulation(&two_spheres_text(
        density,
        2.0 * PAPER_RADIUS,
        relative_speed,
        contact_damping,
        bond.map(|b| (b, "always")),
        dt,
        duration,
    ))
}

/// Scene text of two spheres of section 5 (r = 1 mm, E = 1 GPa, ν = 0) of `density` [kg/m³],
/// centred on the origin `distance` \[m\] apart along x (less than 2r: initially overlapping) and
/// approaching each other at `relative_speed` [m/s] (each moves at half of it), with contact
/// damping ratio ξ_con and an optional bond with its criterion ("always", "never", ...).
/// The integration tests build their two-sphere scenes with it too.
#[must_use]
pub fn two_spheres_text(
    density: f64,
    distance: f64,
    relative_speed: f64,
    contact_damping: f64,
    bond: Option<(BondParams, &str)>,
    dt: f64,
    duration: f64,
) -> String {
    let bond_section = bond.map_or_else(String::new, |(b, criterion)| {
        format!(
            "[bond]\nadhesion_exponent = {:e}\nadhesion_stiffness = {:e}\ndamping_ratio = {:e}\ncriterion = \"{criterion}\"\n",
            b.adhesion_exponent, b.adhesion_stiffness, b.damping_ratio
        )
    });
    let (r, half_d, half_v) = (PAPER_RADIUS, distance / 2.0, relative_speed / 2.0);
    format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
skin_m = 2e-4
[materials.paper]
density_kg_m3 = {density:e}
youngs_modulus_pa = {PAPER_YOUNGS:e}
poisson_ratio = 0.0
[contact]
model = "hertz"
damping_ratio = {contact_damping:e}
{bond_section}
[[particles]]
position_m = [{x0:e}, 0.0, 0.0]
velocity_m_s = [{half_v:e}, 0.0, 0.0]
radius_m = {r:e}
material = "paper"
[[particles]]
position_m = [{half_d:e}, 0.0, 0.0]
velocity_m_s = [{v1:e}, 0.0, 0.0]
radius_m = {r:e}
material = "paper"
"#,
        x0 = -half_d,
        v1 = -half_v
    )
}

/// Overlap of particles 0 and 1 \[m\].
#[must_use]
pub fn overlap(sim: &Simulation) -> f64 {
    let p = &sim.particles;
    p.radius[0] + p.radius[1] - p.position[0].distance(p.position[1])
}

/// Approach speed of particles 0 and 1 along their line of centres [m/s] (> 0 approaching).
#[must_use]
pub fn approach_speed(sim: &Simulation) -> f64 {
    let p = &sim.particles;
    let n = (p.position[1] - p.position[0]).normalize();
    (p.velocity[0] - p.velocity[1]).dot(n)
}

/// Steel-like thermal material of the thermal cases (ρ = 8000 kg/m³, c = 500 J/(kg·K)).
pub const STEEL_DENSITY: f64 = 8000.0;
/// Specific heat of the thermal cases [J/(kg·K)].
pub const STEEL_SPECIFIC_HEAT: f64 = 500.0;

/// Heat capacity `C = ρ (4/3) π r³ c` of a sphere of the thermal cases [J/K].
#[must_use]
pub fn steel_capacity(radius: f64) -> f64 {
    STEEL_DENSITY * 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3) * STEEL_SPECIFIC_HEAT
}

/// A thermal scene. `thermal` is the body of `[thermal]` (without `substep_fraction`, which is
/// `theta`), `material_extra` extra keys of the material, `extra` further tables, `particles`
/// the `[[particles]]` tables; `youngs` the modulus \[Pa\].
#[allow(clippy::too_many_arguments)]
#[must_use]
pub fn thermal(
    dt: f64,
    duration: f64,
    theta: f64,
    youngs: f64,
    thermal: &str,
    material_extra: &str,
    extra: &str,
    particles: &str,
) -> Simulation {
    simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = {dt:e}
duration_s = {duration:e}
[materials.steel]
density_kg_m3 = {STEEL_DENSITY:e}
youngs_modulus_pa = {youngs:e}
poisson_ratio = 0.3
specific_heat_j_kg_k = {STEEL_SPECIFIC_HEAT:e}
{material_extra}
[contact]
model = "hertz"
damping_ratio = 0.0
{extra}
[thermal]
substep_fraction = {theta:e}
{thermal}
{particles}
"#
    ))
}
