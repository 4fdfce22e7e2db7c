//! What heat conduction adds to the step time (issue 4's bound: at most 25 % on a bed of 20k
//! particles). Two beds, each stepped with and without `[thermal]`, alternating blocks of steps so
//! that both see the same machine load; medians of the per-block times are compared:
//! * the LIGGGHTS benchmark bed (`scenes/liggghts_bed_20k.toml` and its `_heat` variant: 19,200
//!   frictional spheres on a plate, periodic in x and y), a powder bed as am-sim runs them;
//! * a settled frictionless 19k column, the worst case: without friction the mechanical step is
//!   cheap, so the conduction work weighs more.
//!
//! Run: `cargo bench --bench thermal_cost` (`RAYON_NUM_THREADS=1` for one thread).

use std::time::Instant;

use am_sim::model::Model;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;

mod common;

/// A vertical temperature gradient, so that heat flows through every contact.
fn gradient(sim: &mut Simulation, kelvin_per_metre: f64) {
    if let Some(state) = sim.thermal.as_mut() {
        for (k, x) in sim.particles.position.iter().enumerate() {
            state.set_temperature(&sim.particles, k, 300.0 + kelvin_per_metre * x.z);
        }
    }
}

/// The LIGGGHTS benchmark bed after its 500 warm-up steps, with or without conduction.
fn liggghts_bed(thermal: bool) -> Simulation {
    let name = if thermal {
        "scenes/liggghts_bed_20k_heat.toml"
    } else {
        "scenes/liggghts_bed_20k.toml"
    };
    let scene = Scene::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(name))
        .expect("valid scene");
    let (model, particles) = Model::try_build(&scene).expect("buildable");
    let mut sim = Simulation::new(model, particles);
    for _ in 0..500 {
        sim.step();
    }
    // 700 K over the bed's 0.2 mm, like LIGGGHTS' hot top layer.
    gradient(&mut sim, 3.5e6);
    sim
}

fn column(thermal: bool) -> Simulation {
    // √10 × wider than scenes/column.toml: 31 × 31 × 20 = 19,220 spheres.
    let text = common::wide_column(10.0, thermal);
    let scene = Scene::from_toml(&text).expect("valid");
    let (model, particles) = Model::build(&scene);
    let mut sim = Simulation::new(model, particles);
    // 0.08 s: the column has collapsed and is nearly at rest, most spheres in contact.
    for _ in 0..16_000 {
        sim.step();
    }
    gradient(&mut sim, 2e4);
    sim
}

fn block(sim: &mut Simulation, steps: usize) -> f64 {
    let start = Instant::now();
    for _ in 0..steps {
        sim.step();
    }
    start.elapsed().as_secs_f64() / steps as f64
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Alternating blocks of both runs; prints and returns the relative cost of conduction.
fn compare(name: &str, plain: &mut Simulation, heated: &mut Simulation) -> f64 {
    let d = plain.diagnostics();
    println!(
        "{name}: {} spheres, {} contacts, {} threads",
        plain.particles.len(),
        d.contacts + d.wall_contacts,
        rayon::current_num_threads()
    );
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        a.push(block(plain, 100));
        b.push(block(heated, 100));
    }
    let (ta, tb) = (median(a), median(b));
    println!("  step without heat: median {:.3} ms", 1e3 * ta);
    println!("  step with conduction: median {:.3} ms", 1e3 * tb);
    println!(
        "  thermal coupling adds {:+.1} % to the step time",
        100.0 * (tb / ta - 1.0)
    );
    tb / ta - 1.0
}

fn main() {
    let (mut plain, mut heated) = (liggghts_bed(false), liggghts_bed(true));
    compare("LIGGGHTS bed", &mut plain, &mut heated);
    let (mut plain, mut heated) = (column(false), column(true));
    compare("frictionless column", &mut plain, &mut heated);
}
