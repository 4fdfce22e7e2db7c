//! The near lists (`src/neighbor.rs`, "Near lists"): between refreshes the force pass tests only
//! the pairs that were within the near skin, and refreshes before any particle can have moved
//! half of it. They change which candidates are tested, never the result: a run with them is
//! bitwise the same as one that tests every candidate at every pass
//! (`Simulation::use_near_lists(false)`), on scenes that exercise each way a pair can need work.

mod common;

use am_sim::contact::hertz;
use am_sim::simulation::Simulation;
use common::{E_STAR, R_STAR, RADIUS, approach_speed, sphere_mass, two_spheres_at};

/// Steps `with` (near lists on) and a copy of it with them off, `steps` times, and asserts that
/// the two stay bitwise the same at every step. Returns the run with near lists.
fn same_with_and_without(mut with: Simulation, steps: u64) -> Simulation {
    let mut without = with.clone();
    without.use_near_lists(false);
    for step in 0..steps {
        with.step();
        without.step();
        assert_eq!(
            common::position_velocity_bits(&with),
            common::position_velocity_bits(&without),
            "step {step}"
        );
    }
    let (d_with, d_without) = (with.diagnostics(), without.diagnostics());
    assert_eq!(d_with.contacts, d_without.contacts);
    assert_eq!(d_with.bonds, d_without.bonds);
    assert_eq!(
        d_without.near_refreshes,
        steps + 1,
        "off: every pass records"
    );
    with
}

/// A pair that starts beyond the near skin (gap 100 µm, near skin 25 µm) and closes it at
/// 2 m/s: the refresh must come before the contact, which the run without near lists finds.
#[test]
fn a_fast_pair_from_beyond_the_near_skin_collides_at_the_same_step() {
    let speed = 2.0;
    let m_star = sphere_mass(2000.0) / 2.0;
    let dt = hertz::contact_time(m_star, E_STAR, R_STAR, speed) / 200.0;
    let gap = 1e-4;
    // The gap closes after gap / speed; the contact lasts well under that again.
    let duration = 2.0 * gap / speed;
    let sim = two_spheres_at(2000.0, 2.0 * RADIUS + gap, speed, 0.3, None, dt, duration);
    let steps = sim.model.steps;
    let sim = same_with_and_without(sim, steps);
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

/// A pile falling onto a plate under friction and rolling resistance: springs that hold and
/// are released, contacts that open and close at up to about 1 m/s.
#[test]
fn a_falling_frictional_pile_is_the_same_with_and_without_near_lists() {
    let text =
        common::scene_text("friction_pile.toml").replace("duration_s = 0.4", "duration_s = 0.02");
    let sim = common::simulation(&text);
    let steps = sim.model.steps;
    same_with_and_without(sim, steps);
}

/// The laser track: pairs melt and bond (bond states that must be kept while apart-tested),
/// with heat conduction through the contacts.
#[test]
fn bonds_and_heat_are_the_same_with_and_without_near_lists() {
    let sim = common::simulation(&common::short_track(4e-4, 1000));
    let steps = sim.model.steps;
    let sim = same_with_and_without(sim, steps);
    assert!(sim.diagnostics().bonds > 0, "the laser bonded some pairs");
}

/// The LIGGGHTS bed: periodic in x and y, so near pairs across the faces need the minimum image.
/// A settled bed refreshes rarely: the lists are in use.
#[test]
fn a_periodic_bed_is_the_same_with_and_without_near_lists_and_rarely_refreshes() {
    let sim = common::liggghts_scene("liggghts_bed_20k.toml");
    let steps = 600;
    let sim = same_with_and_without(sim, steps);
    // Largest speed about 0.02 m/s, dt = 1e-7 s, near skin 1.1 µm: a refresh every ~250 steps.
    let refreshes = sim.diagnostics().near_refreshes;
    assert!(refreshes <= 10, "{refreshes} refreshes in {steps} steps");
}
