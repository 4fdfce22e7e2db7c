//! What heat conduction adds to the step time (issue 4's bound: at most 25 %). The same 19k
//! sphere column, settled, is stepped with and without `[thermal]`, alternating blocks of steps
//! so that both see the same machine load; medians of the per-block times are compared.
//! Run: `cargo bench --bench thermal_cost`.

use std::time::Instant;

use am_sim::model::Model;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;

mod common;

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
    if let Some(state) = sim.thermal.as_mut() {
        // A vertical gradient, so that heat flows through every contact.
        for (k, z) in sim
            .particles
            .position
            .iter()
            .map(|x| x.z)
            .enumerate()
            .collect::<Vec<_>>()
        {
            state.set_temperature(k, 300.0 + 2e4 * z);
        }
    }
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

fn main() {
    let (mut plain, mut heated) = (column(false), column(true));
    let d = plain.diagnostics();
    println!(
        "column: {} spheres, {} contacts, {} threads",
        plain.particles.len(),
        d.contacts + d.wall_contacts,
        rayon::current_num_threads()
    );
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        a.push(block(&mut plain, 100));
        b.push(block(&mut heated, 100));
    }
    let (ta, tb) = (median(a), median(b));
    println!("step without heat: median {:.3} ms", 1e3 * ta);
    println!("step with conduction: median {:.3} ms", 1e3 * tb);
    println!(
        "thermal coupling adds {:+.1} % to the step time",
        100.0 * (tb / ta - 1.0)
    );
}
