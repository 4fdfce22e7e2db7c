//! A column of 2000 spheres (`scenes/column.toml`) settles under gravity in a walled box: nothing
//! passes through a wall, overlaps stay small, the kinetic energy decays, and the positions are
//! bitwise the same with 1 and 2 threads (the coloured pair passes sum in the list's fixed order).

mod common;

use am_sim::simulation::Simulation;

fn column() -> Simulation {
    let text = common::scene_text("column.toml");
    common::simulation(&text)
}

struct Run {
    sim: Simulation,
    peak_kinetic: f64,
    worst_overlap_ratio: f64,
    worst_wall_penetration: f64,
}

fn run(threads: usize) -> Run {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| {
        let mut sim = column();
        let (mut peak_kinetic, mut worst_overlap_ratio) = (0.0_f64, 0.0_f64);
        let mut worst_wall_penetration = f64::NEG_INFINITY;
        for _ in 0..sim.model.steps {
            sim.step();
            if sim.step % 100 == 0 {
                let d = sim.diagnostics();
                peak_kinetic = peak_kinetic.max(d.kinetic_energy);
                worst_overlap_ratio = worst_overlap_ratio.max(d.max_overlap_ratio);
                // Distance by which a sphere's centre is beyond the inner side of any wall.
                for (x, r) in sim.particles.position.iter().zip(&sim.particles.radius) {
                    for w in &sim.model.walls {
                        worst_wall_penetration =
                            worst_wall_penetration.max(-(*x - w.point).dot(w.normal) / r);
                    }
                }
            }
        }
        Run {
            sim,
            peak_kinetic,
            worst_overlap_ratio,
            worst_wall_penetration,
        }
    })
}

#[test]
fn column_settles_stably_and_identically_on_one_and_two_threads() {
    let one = run(1);
    let two = run(2);

    // Determinism: every coordinate bit for bit.
    assert_eq!(
        common::position_velocity_bits(&one.sim),
        common::position_velocity_bits(&two.sim),
        "1 and 2 threads differ"
    );

    let end = one.sim.diagnostics();
    eprintln!(
        "peak KE {:.3e} J, final KE {:.3e} J, worst overlap {:.3} % r, contacts {}, wall contacts {}",
        one.peak_kinetic,
        end.kinetic_energy,
        100.0 * one.worst_overlap_ratio,
        end.contacts,
        end.wall_contacts
    );
    // No sphere centre ever crossed a wall plane (it would then be pushed out the wrong way).
    assert!(
        one.worst_wall_penetration < 0.0,
        "a centre crossed a wall: {}",
        one.worst_wall_penetration
    );
    // Overlaps: at E = 1e7 Pa and ~1 m/s impacts Hertz gives δ/r ≈ 2 %; 5 % would mean an
    // unresolved contact or a lost one.
    assert!(
        one.worst_overlap_ratio < 0.05,
        "overlap {}",
        one.worst_overlap_ratio
    );
    // Settled: damping (e ≈ 0.42 per impact) has removed more than 99 % of the peak kinetic energy.
    assert!(
        end.kinetic_energy < 1e-2 * one.peak_kinetic,
        "KE {} vs peak {}",
        end.kinetic_energy,
        one.peak_kinetic
    );
    // Everyone is still there and resting on something.
    assert_eq!(one.sim.particles.len(), 2000);
    assert!(
        end.wall_contacts >= 100,
        "the floor carries the bottom layer: {}",
        end.wall_contacts
    );
    assert!(
        end.contacts >= 2000,
        "a packed column has ≳ 2 contacts per sphere: {}",
        end.contacts
    );
}
