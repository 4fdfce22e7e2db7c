//! Throughput of the contact laws, in contacts per second. Run: `cargo bench --bench pair_kernel`.
//!
//! - `pair_kernel/hertz`, `pair_kernel/bonded`: the pure normal law (`contact::normal_force`) on
//!   a fixed batch of pair kinematics, Hertz-only and bonded pairs.
//! - `contact_kernel/liggghts_bed_{baseline,avx2,avx512}`: the kernel the pair pass runs
//!   (`forces::KernelBench`: normal and tangential laws over batches of 16 contacts, filled and
//!   read back as the pass does), with the material and friction of the LIGGGHTS benchmark bed
//!   (`scenes/liggghts_bed_20k.toml`, r = 15 µm), in each build this processor runs: the x86-64
//!   baseline (SSE2), AVX2, AVX-512. This kernel is 12-17 % of that bed's step (AVX-512, AVX2;
//!   docs/performance.md): a change to the laws shows here long before it shows in the step's
//!   noise.

use am_sim::contact::{BondParams, BondState, NormalParams, PairKinematics, normal_force};
use am_sim::forces::KernelBench;
use am_sim::model::Model;
use am_sim::scene::Scene;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn batch() -> Vec<PairKinematics> {
    (0..4096)
        .map(|k| {
            let f = f64::from(k) / 4096.0;
            PairKinematics {
                overlap: 1e-7 + 2e-6 * f,
                overlap_rate: 0.1 * (f - 0.5),
                effective_radius: 7.5e-6,
                effective_mass: 5.5e-11,
            }
        })
        .collect()
}

fn normal_law(c: &mut Criterion) {
    let pairs = batch();
    let hertz = NormalParams {
        effective_modulus: 1.1e8,
        damping_ratio: 0.2,
        bond: None,
    };
    let bonded = NormalParams {
        bond: Some(BondParams {
            adhesion_exponent: 1.0,
            adhesion_stiffness: 50.0,
            damping_ratio: 0.5,
        }),
        ..hertz
    };
    let mut group = c.benchmark_group("pair_kernel");
    group.throughput(Throughput::Elements(pairs.len() as u64));
    for (name, params, state) in [
        ("hertz", hertz, BondState::Unbonded),
        ("bonded", bonded, BondState::Bonded),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for k in &pairs {
                    sum += normal_force(black_box(&params), black_box(k), state, true).force;
                }
                sum
            });
        });
    }
    group.finish();
}

fn contact_kernel(c: &mut Criterion) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/liggghts_bed_20k.toml");
    let scene = Scene::load(&path).expect("valid scene");
    let (model, _) = Model::try_build(&scene).expect("buildable");
    let mut group = c.benchmark_group("contact_kernel");
    for build in am_sim::forces::kernel_builds() {
        // A build this processor does not run is left out.
        let Some(mut bench) = KernelBench::new(model.clone(), 15e-6, 4096, build) else {
            continue;
        };
        group.throughput(Throughput::Elements(bench.len() as u64));
        group.bench_function(format!("liggghts_bed_{build}"), |b| {
            b.iter(|| black_box(bench.run()));
        });
    }
    group.finish();
}

criterion_group!(benches, normal_law, contact_kernel);
criterion_main!(benches);
