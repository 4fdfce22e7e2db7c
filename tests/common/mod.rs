//! Helpers shared by the integration tests: scenes are built as TOML text and loaded through the
//! same path as `am-sim scene.toml`, so the tests also exercise the scene layer.
#![allow(dead_code)]

pub mod conducting;

use am_sim::contact::BondParams;
use am_sim::model::Model;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;

/// Overlap and approach speed of particles 0 and 1, and the mass of one sphere of the paper's
/// radius, as the convergence study measures them. (Not every test uses all three.)
#[allow(unused_imports)]
pub use am_sim::study::scenes::{approach_speed, overlap, paper_sphere_mass as sphere_mass};

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
    let bond = bond.map(|b| {
        let params = BondParams {
            adhesion_exponent: b.adhesion_exponent,
            adhesion_stiffness: b.adhesion_stiffness,
            damping_ratio: b.damping_ratio,
        };
        (params, b.criterion)
    });
    simulation(&am_sim::study::scenes::two_spheres_text(
        density,
        distance,
        relative_speed,
        contact_damping,
        bond,
        dt,
        duration,
    ))
}

/// Loads scene text and sets up the simulation.
#[must_use]
pub fn simulation(text: &str) -> Simulation {
    let scene =
        Scene::from_toml(text).unwrap_or_else(|e| panic!("test scene rejected: {e}\n{text}"));
    let (model, particles) = Model::build(&scene);
    Simulation::new(model, particles)
}

/// Sets up the scene `text` and steps it to its end on a pool of `threads` threads.
#[must_use]
pub fn run_on_threads(text: &str, threads: usize) -> Simulation {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let mut sim = simulation(text);
        for _ in 0..sim.model.steps {
            sim.step();
        }
        sim
    })
}

/// The bits of every position and velocity coordinate, in storage order: equal for two runs that
/// are bitwise the same.
#[must_use]
pub fn position_velocity_bits(sim: &Simulation) -> Vec<u64> {
    sim.particles
        .position
        .iter()
        .chain(&sim.particles.velocity)
        .flat_map(|v| v.to_array())
        .map(f64::to_bits)
        .collect()
}

/// The text of a shipped scene, `scenes/<name>`.
#[must_use]
pub fn scene_text(name: &str) -> String {
    std::fs::read_to_string(format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR")))
        .expect("scene file")
}

/// One of the shipped LIGGGHTS scenes (`scenes/liggghts_bed_*.toml`), set up with its import
/// path made absolute.
#[must_use]
pub fn liggghts_scene(name: &str) -> Simulation {
    simulation(&scene_text(name).replace(
        "file = \"data/",
        concat!("file = \"", env!("CARGO_MANIFEST_DIR"), "/scenes/data/"),
    ))
}

/// `scenes/laser_track.toml` shortened to `duration` [s], frames every `every` steps, no CSV.
#[must_use]
pub fn short_track(duration: f64, every: u64) -> String {
    scene_text("laser_track.toml")
        .replace("duration_s = 3.5e-3", &format!("duration_s = {duration:e}"))
        .replace("every_steps = 500", &format!("every_steps = {every}"))
        .replace("series_csv = \"laser_track.csv\"", "")
}

/// The number that follows `label` in `line` (up to the next whitespace), as am-sim prints its
/// summaries; panics, naming both, if there is none.
#[must_use]
pub fn number_after(line: &str, label: &str) -> f64 {
    line.split(label)
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|value| value.parse().ok())
        .unwrap_or_else(|| panic!("no number after {label:?}: {line}"))
}

/// Runs the `am-sim` binary with `args` in `dir` and waits for it.
#[must_use]
pub fn am_sim(dir: &std::path::Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_am-sim"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("am-sim runs")
}

/// Runs the `am-sim` binary like [`am_sim`], fails the test unless the run fails, and returns
/// what it wrote to stderr.
#[must_use]
pub fn am_sim_failing(dir: &std::path::Path, args: &[&str]) -> String {
    let out = am_sim(dir, args);
    let stderr = text(&out.stderr);
    assert!(!out.status.success(), "am-sim {args:?} succeeded: {stderr}");
    stderr
}

/// A process's output as text.
#[must_use]
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Fails the test, naming the first of `expected` that `output` lacks and showing `output`,
/// unless `output` holds every one.
pub fn assert_contains_all(output: &str, expected: &[&str]) {
    for expected in expected {
        assert!(output.contains(expected), "lacks {expected:?}:\n{output}");
    }
}
