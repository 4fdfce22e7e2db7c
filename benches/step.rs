//! One time step of a settled-ish column (`scenes/column.toml`, 2000 spheres after 0.05 s of
//! settling) and of a larger 19k bed built from the same scene, without and with heat conduction
//! (the cost of the thermal coupling), and the LIGGGHTS benchmark bed (`scenes/liggghts_bed_20k.toml`,
//! 19,200 frictional spheres after 500 steps), on the default thread pool (set
//! `RAYON_NUM_THREADS=1` for one thread); and the neighbour list's build on that bed.
//! Run: `cargo bench --bench step`. Reports particle-steps per second as throughput.

use am_sim::model::Model;
use am_sim::neighbor::NeighborList;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

mod common;

fn column(scale: usize, thermal: bool) -> Simulation {
    #[allow(clippy::cast_precision_loss)]
    let text = common::wide_column(scale as f64, thermal);
    let scene = Scene::from_toml(&text).expect("valid");
    let (model, particles) = Model::build(&scene);
    let mut sim = Simulation::new(model, particles);
    for _ in 0..10_000 {
        sim.step(); // 0.05 s: the column has collapsed onto the floor, most spheres in contact
    }
    sim
}

/// The LIGGGHTS benchmark bed after its 500 warm-up steps.
fn liggghts_bed() -> Simulation {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/liggghts_bed_20k.toml");
    let scene = Scene::load(&path).expect("valid scene");
    let (model, particles) = Model::try_build(&scene).expect("buildable");
    let mut sim = Simulation::new(model, particles);
    for _ in 0..500 {
        sim.step();
    }
    sim
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(20);
    for (name, scale, thermal) in [
        ("column2k", 1, false),
        ("column19k", 10, false),
        ("column19k_conduction", 10, true),
    ] {
        let mut sim = column(scale, thermal);
        if thermal {
            // A temperature gradient, so that heat actually flows.
            let state = sim.thermal.as_mut().expect("thermal");
            for (k, x) in sim.particles.position.iter().enumerate() {
                state.set_temperature(&sim.particles, k, 300.0 + 2e4 * x.z);
            }
        }
        group.throughput(Throughput::Elements(sim.particles.len() as u64));
        group.bench_function(name, |b| b.iter(|| sim.step()));
    }
    let mut bed = liggghts_bed();
    group.throughput(Throughput::Elements(bed.particles.len() as u64));
    group.bench_function("liggghts_bed20k", |b| b.iter(|| bed.step()));
    group.finish();
    // The neighbour list's build on the same bed, per particle, its particles stored in the
    // list's order first (`spatial_order`), as every rebuild stores them before it builds.
    let mut builds = c.benchmark_group("neighbor_build");
    builds.sample_size(20);
    let mut list = NeighborList::new(bed.model.skin, bed.model.periodic);
    let mut stored = bed.particles.clone();
    let order = list.spatial_order(&stored.position, &stored.radius, &vec![true; stored.len()]);
    stored.select(&order);
    builds.throughput(Throughput::Elements(stored.len() as u64));
    builds.bench_function("liggghts_bed20k", |b| {
        b.iter(|| list.build(&stored.position, &stored.radius))
    });
    builds.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
