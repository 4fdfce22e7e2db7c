//! The full coupled step (mechanics, conduction, laser, melting, bonding) gives bitwise the same
//! state with 1 and 2 threads: the coloured pair passes sum in an order fixed by the neighbour
//! list, and the laser adds its rows in order.

mod common;

use am_sim::simulation::Simulation;

fn run(threads: usize) -> Simulation {
    let text = common::scene_text("laser_track.toml");
    // 0.2 ms settling, then 0.6 ms of the track: enough for particles to melt and bond.
    let text = text.replace("duration_s = 3.5e-3", "duration_s = 8e-4");
    common::run_on_threads(&text, threads)
}

#[test]
fn laser_track_is_bitwise_identical_on_one_and_two_threads() {
    let (one, two) = (run(1), run(2));
    let bits = |s: &Simulation| -> Vec<u64> {
        let p = &s.particles;
        let t = s.thermal.as_ref().unwrap();
        p.position
            .iter()
            .chain(&p.velocity)
            .flat_map(|v| v.to_array())
            .chain(t.temperature.iter().copied())
            .chain(t.enthalpy.iter().copied())
            .map(f64::to_bits)
            .collect()
    };
    assert_eq!(bits(&one), bits(&two));
    assert_eq!(one.bonds(), two.bonds());
    let d = one.diagnostics();
    let thermal = d.thermal.unwrap();
    eprintln!(
        "melted {}, bonds {}, max T {:.0} K",
        thermal.melted, d.bonds, thermal.max_temperature
    );
    assert!(
        thermal.melted > 10 && d.bonds > 10,
        "the test must exercise melting and bonding"
    );
}

/// `scenes/column.toml` with sliding and rolling friction, for the first 15 ms: 2000 particles
/// (so the passes run in parallel), the bottom layers on the floor and on each other (~330
/// contacts, ~90 wall contacts).
fn run_with_friction(threads: usize) -> Simulation {
    let text = common::scene_text("column.toml")
        .replace("duration_s = 0.1", "duration_s = 0.015")
        .replace(
            "damping_ratio = 0.3 ",
            "friction_coefficient = 0.5\nrolling_friction_coefficient = 0.05\ndamping_ratio = 0.3 ",
        );
    common::run_on_threads(&text, threads)
}

#[test]
fn friction_and_rotation_are_bitwise_identical_on_one_and_two_threads() {
    let (one, two) = (run_with_friction(1), run_with_friction(2));
    let bits = |s: &Simulation| -> Vec<u64> {
        let p = &s.particles;
        let r = s.rotation.as_ref().expect("friction allocates rotation");
        p.position
            .iter()
            .chain(&p.velocity)
            .chain(&r.angular_velocity)
            .chain(&r.torque)
            .flat_map(|v| v.to_array())
            .map(f64::to_bits)
            .collect()
    };
    assert_eq!(bits(&one), bits(&two));
    let d = one.diagnostics();
    assert_eq!(d, two.diagnostics());
    eprintln!("contacts {}, wall contacts {}", d.contacts, d.wall_contacts);
    assert!(
        d.contacts > 200 && d.wall_contacts > 50,
        "the test must exercise particle and wall friction"
    );
}

/// The measurements of a state (contacts, elastic energy, stability limit) walk its contacts
/// in chunks of particles that the thread team shares, and sum the chunks in order: the same
/// bits on any number of threads. The LIGGGHTS bed's 19,200 spheres make 19 chunks.
#[test]
fn diagnostics_of_a_state_are_bitwise_the_same_on_any_number_of_threads() {
    let sim = common::liggghts_scene("liggghts_bed_20k.toml");
    let measured_on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(|| sim.diagnostics())
    };
    let one = measured_on(1);
    assert!(one.contacts > 10_000 && one.elastic_energy > 0.0, "{one:?}");
    for threads in [2, 3] {
        assert_eq!(measured_on(threads), one, "{threads} threads");
    }
}

#[test]
fn friction_runs_with_different_skins_agree_to_round_off() {
    // The skin changes how often the list is rebuilt and the particles re-sorted, so the forces are
    // summed in other orders: the runs differ by round-off, which a dense frictional column
    // amplifies. A tangential history lost or turned the wrong way at a rebuild would instead
    // change contact forces at once by O(1) of μ F_n; the bounds below sit far under that.
    let run = |skin: &str| {
        let text = common::scene_text("column.toml")
            .replace("duration_s = 0.1", "duration_s = 0.015")
            .replace("skin_m = 2e-4", skin)
            .replace(
                "damping_ratio = 0.3 ",
                "friction_coefficient = 0.5\nrolling_friction_coefficient = 0.05\ndamping_ratio = 0.3 ",
            );
        let mut sim = common::simulation(&text);
        for _ in 0..sim.model.steps {
            sim.step();
        }
        sim
    };
    let (small, large) = (run("skin_m = 2e-5"), run("skin_m = 4e-4"));
    let builds = |s: &Simulation| s.diagnostics().neighbor_builds;
    eprintln!("builds: {} vs {}", builds(&small), builds(&large));
    assert!(builds(&small) > 5 * builds(&large));
    let (a, b) = (&small.particles, &large.particles);
    let (mut dx, mut dv, mut dw): (f64, f64, f64) = (0.0, 0.0, 0.0);
    let (mut speed, mut spin): (f64, f64) = (0.0, 0.0);
    for k in 0..a.len() {
        let j = b.index_of(a.id[k]).expect("same particles");
        dx = dx.max((a.position[k] - b.position[j]).length() / a.radius[k]);
        dv = dv.max((a.velocity[k] - b.velocity[j]).length());
        let (wa, wb) = (
            small.rotation.as_ref().unwrap().angular_velocity[k],
            large.rotation.as_ref().unwrap().angular_velocity[j],
        );
        dw = dw.max((wa - wb).length());
        speed = speed.max(a.velocity[k].length());
        spin = spin.max(wa.length());
    }
    eprintln!(
        "largest differences: position {dx:.2e} radii, velocity {dv:.2e} of {speed:.2e} m/s, spin {dw:.2e} of {spin:.2e} rad/s"
    );
    assert!(dx < 1e-6, "positions differ by {dx} radii");
    assert!(dv < 1e-4 * speed, "velocities differ by {dv} m/s");
    assert!(dw < 1e-4 * spin, "spins differ by {dw} rad/s");
}

/// `Simulation::advance` leaves each step's closing half kick to the next step's opening pass
/// within a call. Runs in calls of irregular sizes (1 to 64 steps, so that calls end at every
/// phase of the neighbour-list builds and near-list refreshes) must be bitwise the same as
/// step-by-step runs, at every call's end, for the full coupled step (laser, melting, bonding,
/// evaporation), for the same with thermal substeps that change from step to step, and for
/// friction with rotation.
#[test]
fn advance_in_calls_is_bitwise_the_same_as_step_by_step() {
    let laser_track =
        common::scene_text("laser_track.toml").replace("duration_s = 3.5e-3", "duration_s = 6e-4");
    // The track's steps have dt max(G/C) up to 2.4e-4: with θ = 1.5e-4 the hotter steps take
    // two substeps and the others one, so that steps of either kind follow each other within
    // a call (the thermal state the opening pass zeroes must be that of the step before).
    let substepping = laser_track.replace("[thermal]\n", "[thermal]\nsubstep_fraction = 1.5e-4\n");
    assert_ne!(substepping, laser_track);
    let column = common::scene_text("column.toml")
        .replace("duration_s = 0.1", "duration_s = 0.005")
        .replace(
            "damping_ratio = 0.3 ",
            "friction_coefficient = 0.5\nrolling_friction_coefficient = 0.05\ndamping_ratio = 0.3 ",
        );
    for text in [laser_track, substepping, column] {
        // Two simulations made from the text (a clone would record its near lists once more).
        let mut by_step = common::simulation(&text);
        let mut in_calls = common::simulation(&text);
        let bits = |s: &Simulation| -> Vec<u64> {
            let mut bits = common::position_velocity_bits(s);
            if let Some(r) = &s.rotation {
                bits.extend(
                    r.angular_velocity
                        .iter()
                        .flat_map(|w| w.to_array())
                        .map(f64::to_bits),
                );
            }
            if let Some(t) = &s.thermal {
                let evaporated = t.evaporation.iter().flat_map(|e| &e.evaporated);
                let laser = t.laser.iter().flat_map(|l| &l.energy);
                let boundary = t.boundary.iter().flat_map(|b| &b.energy);
                for column in [&t.enthalpy, &t.temperature] {
                    bits.extend(column.iter().map(|e| e.to_bits()));
                }
                bits.extend(laser.chain(boundary).chain(evaporated).map(|e| e.to_bits()));
                bits.extend(t.melted.iter().map(|&m| u64::from(m)));
            }
            bits
        };
        // The substep counts of the step-by-step run's steps.
        let mut substeps = std::collections::BTreeSet::new();
        let sizes = [1, 7, 64, 2, 13, 31, 3, 50];
        let mut calls = 0;
        while in_calls.step < in_calls.model.steps {
            let size = sizes[calls % sizes.len()].min(in_calls.model.steps - in_calls.step);
            assert_eq!(in_calls.advance(size, || true), size, "no guard trips here");
            for _ in 0..size {
                by_step.step();
                substeps.extend(by_step.thermal.as_ref().map(|t| t.substeps));
            }
            assert_eq!(in_calls.step, by_step.step);
            assert_eq!(
                bits(&in_calls),
                bits(&by_step),
                "after step {}",
                by_step.step
            );
            calls += 1;
        }
        assert_eq!(in_calls.diagnostics(), by_step.diagnostics());
        assert_eq!(in_calls.bonds(), by_step.bonds());
        if let Some(t) = &in_calls.thermal {
            eprintln!("substeps per step: {substeps:?}");
            assert!(t.melted.iter().any(|&m| m), "the track melts particles");
            let evaporated = t.evaporation.as_ref().expect("the track's steel boils");
            assert!(
                evaporated.evaporated.iter().any(|&e| e > 0.0),
                "and evaporates some"
            );
            if text.contains("substep_fraction") {
                assert!(substeps.contains(&1) && substeps.len() > 1, "{substeps:?}");
            }
        }
    }
}

/// `keep_going` ends a call after the step on which it turns false (the run loop's ^C).
#[test]
fn advance_stops_when_told() {
    let text = common::scene_text("column.toml").replace("duration_s = 0.1", "duration_s = 0.001");
    let mut sim = common::simulation(&text);
    let calls = std::cell::Cell::new(0);
    let done = sim.advance(100, || {
        calls.set(calls.get() + 1);
        calls.get() < 5
    });
    assert_eq!(done, 5);
    assert_eq!(sim.step, 5);
}

/// A force that turns NaN or infinite ends a call of `advance` after that very step, with its
/// closing kick given, and the guard names the same particle as step-by-step runs do. One
/// sphere of the column is thrown at the floor at 1e307 m/s: its first drift takes it about
/// 5e301 m into the floor, whose Hertz force overflows. The overlap guard is switched off
/// (`max_overlap_ratio` infinite), so that only the test of the forces can stop the call.
#[test]
fn advance_stops_after_the_step_whose_force_is_not_finite() {
    let text = common::scene_text("column.toml").replace("duration_s = 0.1", "duration_s = 0.001");
    let thrown = |sim: &mut Simulation| {
        sim.model.guards.max_overlap_ratio = f64::INFINITY;
        // The step ends with a finite state; the sphere is chosen in the middle of the arrays.
        let k = sim.particles.len() / 2 + 7;
        sim.particles.velocity[k] = glam::DVec3::new(0.0, 0.0, -1e307);
        sim.particles.id[k]
    };
    let (mut in_calls, mut by_step) = (common::simulation(&text), common::simulation(&text));
    for _ in 0..3 {
        assert_eq!(in_calls.advance(3, || true), 3);
        by_step.step();
        by_step.step();
        by_step.step();
    }
    let id = thrown(&mut in_calls);
    assert_eq!(thrown(&mut by_step), id);
    assert_eq!(
        in_calls.advance(50, || true),
        1,
        "the call ends after the step"
    );
    by_step.step();
    assert_eq!((in_calls.step, by_step.step), (10, 10));
    for sim in [&in_calls, &by_step] {
        let trip = sim.guard_trip().expect("the guard trips");
        assert!(trip.quantity.contains("non-finite"), "{}", trip.quantity);
        assert_eq!(trip.ids, [id]);
    }
    assert_eq!(
        common::position_velocity_bits(&in_calls),
        common::position_velocity_bits(&by_step)
    );
}
