//! The bounds on how far particles can have moved, and the work they save. They change which
//! work is done, never the result:
//!
//! * the near lists (`src/neighbor.rs`, "Near lists"): between refreshes the force pass tests
//!   only the pairs that were within the near skin, and refreshes before any particle can have
//!   moved half of it. A run with them is bitwise the same as one that tests every candidate at
//!   every pass (`Simulation::use_near_lists(false)`), on scenes that exercise each way a pair
//!   can need work;
//! * the rebuild test measures the displacements since the build only when a bound on them
//!   (dt |v|max summed over the drifts) comes near half the skin. A run with the bound builds
//!   the list at the same steps, and is bitwise the same, as one that measures after every
//!   drift (`Simulation::use_rebuild_bound(false)`).

mod common;

use am_sim::contact::hertz;
use am_sim::simulation::Simulation;
use common::{E_STAR, R_STAR, RADIUS, approach_speed, sphere_mass, two_spheres_at};

/// Steps `with` and a copy of it changed by `switch_off`, `steps` times, and asserts that the
/// two stay bitwise the same at every step and build their neighbour lists at the same steps.
/// Returns the two runs.
fn same_with_and_without(
    mut with: Simulation,
    steps: u64,
    switch_off: impl FnOnce(&mut Simulation),
) -> (Simulation, Simulation) {
    let mut without = with.clone();
    switch_off(&mut without);
    for step in 0..steps {
        with.step();
        without.step();
        assert_eq!(
            common::position_velocity_bits(&with),
            common::position_velocity_bits(&without),
            "step {step}"
        );
        assert_eq!(
            with.diagnostics().neighbor_builds,
            without.diagnostics().neighbor_builds,
            "step {step}"
        );
    }
    let (d_with, d_without) = (with.diagnostics(), without.diagnostics());
    assert_eq!(d_with.contacts, d_without.contacts);
    assert_eq!(d_with.bonds, d_without.bonds);
    (with, without)
}

/// [`same_with_and_without`] the near lists. Returns the run with them.
fn same_with_and_without_near_lists(with: Simulation, steps: u64) -> Simulation {
    let (with, without) = same_with_and_without(with, steps, |s| s.use_near_lists(false));
    assert_eq!(
        without.diagnostics().near_refreshes,
        steps + 1,
        "off: every pass records"
    );
    with
}

/// [`same_with_and_without`] the rebuild test's bound. Returns the run with it.
fn same_with_and_without_rebuild_bound(with: Simulation, steps: u64) -> Simulation {
    let before = with.diagnostics().displacement_checks;
    let (with, without) = same_with_and_without(with, steps, |s| s.use_rebuild_bound(false));
    assert_eq!(
        without.diagnostics().displacement_checks - before,
        steps,
        "off: every drift measures"
    );
    with
}

/// Two spheres 100 µm apart closing at 2 m/s, run until they have met and separated.
fn fast_pair() -> Simulation {
    let speed = 2.0;
    let m_star = sphere_mass(2000.0) / 2.0;
    let dt = hertz::contact_time(m_star, E_STAR, R_STAR, speed) / 200.0;
    let gap = 1e-4;
    // The gap closes after gap / speed; the contact lasts well under that again.
    let duration = 2.0 * gap / speed;
    two_spheres_at(2000.0, 2.0 * RADIUS + gap, speed, 0.3, None, dt, duration)
}

/// A pair that starts beyond the near skin (gap 100 µm, near skin 25 µm) and closes it at
/// 2 m/s: the refresh must come before the contact, which the run without near lists finds.
#[test]
fn a_fast_pair_from_beyond_the_near_skin_collides_at_the_same_step() {
    let sim = fast_pair();
    let steps = sim.model.steps;
    let sim = same_with_and_without_near_lists(sim, steps);
    // The spheres met and separated: they now move apart.
    assert!(approach_speed(&sim) < 0.0, "{}", approach_speed(&sim));
    // Closing 100 µm at 2 m/s with refreshes before each 12.5 µm of travel: several refreshes,
    // far fewer than steps.
    let refreshes = sim.diagnostics().near_refreshes;
    assert!(
        refreshes > 4 && refreshes < steps / 4,
        "{refreshes} refreshes, {steps} steps"
    );
}

/// The first 20 ms of `scenes/friction_pile.toml`: a pile falling onto a plate under friction
/// and rolling resistance.
fn falling_pile() -> Simulation {
    let text =
        common::scene_text("friction_pile.toml").replace("duration_s = 0.4", "duration_s = 0.02");
    common::simulation(&text)
}

/// The falling pile: springs that hold and are released, contacts that open and close at up
/// to about 1 m/s.
#[test]
fn a_falling_frictional_pile_is_the_same_with_and_without_near_lists() {
    let sim = falling_pile();
    let steps = sim.model.steps;
    same_with_and_without_near_lists(sim, steps);
}

/// The laser track: pairs melt and bond (bond states that must be kept while apart-tested),
/// with heat conduction through the contacts.
#[test]
fn bonds_and_heat_are_the_same_with_and_without_near_lists() {
    let sim = common::simulation(&common::short_track(4e-4, 1000));
    let steps = sim.model.steps;
    let sim = same_with_and_without_near_lists(sim, steps);
    assert!(sim.diagnostics().bonds > 0, "the laser bonded some pairs");
}

/// The LIGGGHTS bed: periodic in x and y, so near pairs across the faces need the minimum image.
/// A settled bed refreshes rarely: the lists are in use.
#[test]
fn a_periodic_bed_is_the_same_with_and_without_near_lists_and_rarely_refreshes() {
    let sim = common::liggghts_scene("liggghts_bed_20k.toml");
    let steps = 600;
    let sim = same_with_and_without_near_lists(sim, steps);
    // Largest speed about 0.02 m/s, dt = 1e-7 s: the first period (near skin 1.1 µm) lasts
    // ~250 steps, then the tuner halves the skin and settles near 0.13 µm, a refresh every
    // ~26 steps (`neighbor::NearSkinTuner`): 10 refreshes in 600 steps. Every pass refreshing
    // would be 600; a tuner running away to its smallest skin, every ~4 steps.
    let refreshes = sim.diagnostics().near_refreshes;
    assert!(refreshes <= 20, "{refreshes} refreshes in {steps} steps");
}

/// The falling pile, fast enough to rebuild its list about a dozen times in 4000 steps: the
/// builds come at the same steps when the displacements are measured only near the bound, and
/// they are measured at far fewer steps than there are.
#[test]
fn a_falling_pile_rebuilds_at_the_same_steps_with_and_without_the_rebuild_bound() {
    let sim = falling_pile();
    let steps = sim.model.steps;
    let builds_before = sim.diagnostics().neighbor_builds;
    let sim = same_with_and_without_rebuild_bound(sim, steps);
    let d = sim.diagnostics();
    let builds = d.neighbor_builds - builds_before;
    // Every build follows a measurement; the pile rebuilt, so it measured.
    assert!(builds > 0, "the pile moved its half skin");
    assert!(d.displacement_checks >= builds, "{d:?}");
    // About one build per 300 steps, each after one or two measurements.
    assert!(
        d.displacement_checks < steps / 20,
        "{} checks in {steps} steps",
        d.displacement_checks
    );
}

/// The fast pair: a rebuild must come before the pair closes its skin, which the run that
/// measures at every drift finds.
#[test]
fn a_fast_pair_rebuilds_at_the_same_steps_with_and_without_the_rebuild_bound() {
    let sim = fast_pair();
    let steps = sim.model.steps;
    let sim = same_with_and_without_rebuild_bound(sim, steps);
    assert!(approach_speed(&sim) < 0.0, "{}", approach_speed(&sim));
}

/// The settled LIGGGHTS bed: the fastest sphere moves about 2 nm a step, so the bound needs
/// some two thousand steps to reach half the 9 µm skin, and 600 steps measure at most once.
#[test]
fn a_settled_bed_rarely_measures_its_displacements() {
    let sim = common::liggghts_scene("liggghts_bed_20k.toml");
    let steps = 600;
    let before = sim.diagnostics().displacement_checks;
    let sim = same_with_and_without_rebuild_bound(sim, steps);
    let checks = sim.diagnostics().displacement_checks - before;
    assert!(checks <= 1, "{checks} checks in {steps} steps");
}
