//! One time step of a settled-ish column (`scenes/column.toml`, 2000 spheres after 0.05 s of
//! settling) and of a larger 16k bed built from the same scene, on the default thread pool.
//! Run: `cargo bench --bench step`. Reports particle-steps per second as throughput.

use am_sim::model::Model;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn column(scale: usize) -> Simulation {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/column.toml"))
        .expect("scene");
    // Widen the box (and move the far walls) to get `scale` times more columns of spheres.
    let width = 0.022 * (scale as f64).sqrt();
    let text = text
        .replace(
            "max_corner_m = [0.0220, 0.0220, 0.0440]",
            &format!("max_corner_m = [{width}, {width}, 0.0440]"),
        )
        .replace(
            "point_m = [0.0220, 0.0, 0.0]",
            &format!("point_m = [{width}, 0.0, 0.0]"),
        )
        .replace(
            "point_m = [0.0, 0.0220, 0.0]",
            &format!("point_m = [0.0, {width}, 0.0]"),
        );
    let scene = Scene::from_toml(&text).expect("valid");
    let (model, particles) = Model::build(&scene);
    let mut sim = Simulation::new(model, particles);
    for _ in 0..10_000 {
        sim.step(); // 0.05 s: the column has collapsed onto the floor, most spheres in contact
    }
    sim
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(20);
    for (name, scale) in [("column2k", 1), ("column16k", 8)] {
        let mut sim = column(scale);
        group.throughput(Throughput::Elements(sim.particles.len() as u64));
        group.bench_function(name, |b| b.iter(|| sim.step()));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
