//! Throughput of the pure normal law (`contact::normal_force`) on a fixed batch of pair
//! kinematics: Hertz-only pairs, and bonded pairs. Run: `cargo bench --bench pair_kernel`.

use am_sim::contact::{BondParams, BondState, NormalParams, PairKinematics, normal_force};
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

fn bench(c: &mut Criterion) {
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

criterion_group!(benches, bench);
criterion_main!(benches);
