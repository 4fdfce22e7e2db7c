//! One ray cast of the laser (`Laser::absorb`, M.51) over the flagship's beam window, in casts
//! per second. Run: `cargo bench --bench laser_cast`.
//!
//! The window of `scenes/bed.toml` (40 µm spot, 2 µm cells: a raster of 120 × 120 rays) over a
//! pile of about 150 lit spheres of its powder's sizes (7.5-30 µm), two layers deep, about as
//! many as its bed puts under the beam. The flagship casts anew every few steps, whenever the
//! beam or a lit particle has moved half a cell; the fifty-fifth round of docs/performance-log.md
//! made the cast go disk by disk (1.16× on the flagship's scan at 2 threads).

use am_sim::bed::rng::SplitMix64;
use am_sim::laser::Laser;
use am_sim::particles::{ParticleInit, Particles};
use criterion::{Criterion, criterion_group, criterion_main};
use glam::{DVec2, DVec3};
use std::hint::black_box;

/// A random pile over the window and a margin around it (fixed seed).
fn pile() -> Particles {
    let mut random = SplitMix64(55);
    let mut particles = Particles::default();
    // The flagship's 1,770 spheres per mm² over a 0.4 × 0.4 mm square: 283, of which about half
    // reach into the ±120 µm window.
    for _ in 0..283 {
        let init = ParticleInit {
            position: DVec3::new(
                random.uniform(-2.0e-4, 2.0e-4),
                random.uniform(-2.0e-4, 2.0e-4),
                random.uniform(0.0, 6.0e-5),
            ),
            velocity: DVec3::ZERO,
            radius: random.uniform(7.5e-6, 3.0e-5),
            material: 0,
        };
        particles.push(init, 7950.0);
    }
    particles
}

fn cast(c: &mut Criterion) {
    let laser = Laser {
        power: 40.0,
        spot_radius: 4.0e-5,
        raster_cell: 2.0e-6,
        path: Vec::new(),
    };
    let particles = pile();
    let mut power = vec![0.0; particles.len()];
    let lit = laser.absorb(DVec2::ZERO, &particles, |_| 0.6, &mut power);
    println!(
        "laser_cast: {} of {} spheres lit, {:.3} W absorbed",
        lit.len(),
        particles.len(),
        power.iter().sum::<f64>()
    );
    c.bench_function("laser_cast/flagship_window", |b| {
        b.iter(|| {
            let lit = laser.absorb(
                black_box(DVec2::new(1.0e-6, -2.0e-6)),
                &particles,
                |_| 0.6,
                &mut power,
            );
            black_box(lit.len())
        });
    });
}

criterion_group!(benches, cast);
criterion_main!(benches);
