//! Tests of the step that read the simulation's own state (its force summary, the heat sums).

use super::*;
use crate::thermal::{HeatRate, StepInfo};

#[path = "../../tests/common/conducting.rs"]
mod conducting;

/// The conducting column's packed cube (`tests/common/conducting.rs`, which tests/thermal.rs
/// runs too), from 300 K at the floor to 1300 K at the top. Every third sphere's radius is
/// scaled by `scale` (its mass by `scale³`, its heat capacity with it), so that a scale other
/// than 1 makes a bed of two sizes. Returned after three steps, so that its contacts conduct and
/// the step's own heat sums and force summary are there to read.
fn packed_bed(scale: f64) -> Simulation {
    let text = conducting::packed_cube("1e-4");
    let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
    let (model, mut particles) = Model::build(&scene);
    for k in (0..particles.len()).step_by(3) {
        particles.radius[k] *= scale;
        particles.mass[k] *= scale.powi(3);
    }
    let mut sim = Simulation::new(model, particles);
    assert_eq!(sim.particles.len(), 1000);
    for k in 0..sim.particles.len() {
        let z = sim.particles.position[k].z;
        let thermal = sim.thermal.as_mut().expect("[thermal]");
        thermal.set_temperature(&sim.particles, k, 300.0 + 5e4 * z);
    }
    for _ in 0..3 {
        sim.step();
    }
    sim
}

/// Without laser or boundary exchange the force pass takes no `G_i / C_i`: the pair pass's
/// largest G_i, over the smallest heat capacity, bounds the largest. The largest G_i any of the
/// pair pass's additions left is the largest of the finished sums to the bit (each G_i only
/// grows as contacts add to it), and for spheres of one size and material the bound is the
/// largest rate itself, to the bit (`fl(G/C)` grows with G for one C); with two sizes it is
/// above it.
#[test]
fn the_pair_pass_bounds_the_largest_heat_rate_by_the_largest_conductance() {
    for scale in [1.0, 1.05] {
        let sim = packed_bed(scale);
        let summary = sim.force_summary;
        let state = sim.thermal.as_ref().expect("[thermal]");
        // The bound sufficed (dt G/C is about 1e-4 here), so no step took the rate itself.
        assert_eq!(summary.max_heat_rate, None);
        assert_eq!(state.substeps, 1);
        let largest = state
            .heat_sums
            .iter()
            .map(|s| s.conductance)
            .fold(0.0, f64::max);
        assert!(largest > 0.0);
        assert_eq!(summary.max_conductance.to_bits(), largest.to_bits());
        // Each particle's own C_i = m_i c: the state's smallest, `min_i(m_i) c` for one
        // material, is their smallest to the bit.
        let smallest = (0..sim.particles.len())
            .map(|k| state.heat_constants(&sim.particles, k).heat_capacity)
            .fold(f64::INFINITY, f64::min);
        assert_eq!(state.min_heat_capacity.to_bits(), smallest.to_bits());
        let HeatRate::AtMost(bound) = HeatRate::at_most(largest, smallest) else {
            unreachable!("`at_most` makes a bound")
        };
        let exact = thermal::max_heat_rate_of(state, &sim.particles);
        assert!(exact > 0.0);
        if scale == 1.0 {
            assert_eq!(bound.to_bits(), exact.to_bits(), "one size");
        } else {
            // The large spheres hold the largest G_i, the small ones the smallest C_i: the bound
            // exceeds the rate by about the capacities' ratio, far beyond rounding.
            assert!(bound > 1.01 * exact, "{bound:e} against {exact:e}");
        }
    }
}

/// The temperature update takes the substep count of the largest `G_i / C_i` whatever the force
/// pass gives it: the rate itself, a bound that asks for one substep (the rate would ask for
/// one too), or a bound that asks for more or is NaN (the update then takes the rate in a pass
/// of its own). The state after each is the same to the bit as after the rate itself, on a bed
/// of two sizes, with time steps that make the rate take half a substep's allowance (one
/// substep) and two and a half (three substeps).
#[test]
fn the_temperature_update_takes_the_substep_count_of_the_largest_rate_from_any_bound() {
    let sim = packed_bed(1.05);
    let model = sim.model.thermal.as_ref().expect("[thermal]");
    let state = sim.thermal.as_ref().expect("[thermal]");
    let exact = thermal::max_heat_rate_of(state, &sim.particles);
    let fraction = model.substep_fraction;
    for (share, substeps) in [(0.5, 1), (2.5, 3)] {
        let dt = share * fraction / exact;
        let advance = |first_flows| {
            let mut after = state.clone();
            let taken = thermal::advance(
                model,
                &sim.model.walls,
                &sim.particles,
                &sim.neighbors,
                &mut after,
                StepInfo {
                    dt,
                    first_flows: Some(first_flows),
                    periodic: sim.model.periodic.as_ref(),
                },
            );
            (after, taken)
        };
        let (reference, taken) = advance(HeatRate::Exact(exact));
        assert_eq!(taken, Some(exact));
        assert_eq!(reference.substeps, substeps);
        assert!(reference.enthalpy != state.enthalpy, "heat flowed");
        for bound in [1.5 * exact, 4.0 * exact, f64::NAN] {
            let (after, taken) = advance(HeatRate::AtMost(bound));
            // Only a bound that asks for one substep spares the pass that takes the rate.
            let sufficed = dt * bound / fraction <= 1.0;
            assert_eq!(sufficed, share == 0.5 && bound == 1.5 * exact);
            assert_eq!(taken, (!sufficed).then_some(exact), "bound {bound:e}");
            assert!(
                after == reference,
                "bound {bound:e}, share {share}: {} substeps against {substeps}",
                after.substeps
            );
        }
    }
}

/// The largest `G_i / C_i` measured once (`thermal::max_stiffness`, as the run's start takes it,
/// and `max_stiffness_aside`, as the diagnostics take it, to the same bits), and a step of one
/// substep without the force pass's flows, compute each contact's conductance as they meet the
/// pair and keep no per-slot array, whose 8 B a pair slot would set a heated bed's peak memory.
/// A step of three substeps stores the conductances for its second and third flow passes; its
/// temperatures and heat sums are the same to the bit as those of three steps of a third of its
/// length, each of one substep, which compute every conductance from the positions.
#[test]
fn flow_passes_without_stored_conductances_match_the_stored_ones_to_the_bit() {
    let sim = packed_bed(1.05);
    let model = sim.model.thermal.as_ref().expect("[thermal]");
    let periodic = sim.model.periodic.as_ref();
    let state = sim.thermal.as_ref().expect("[thermal]");
    assert_eq!(state.conductance.capacity(), 0, "the run kept conductances");
    let mut measured = state.clone();
    let rate = thermal::max_stiffness(
        model,
        &sim.model.walls,
        periodic,
        &sim.particles,
        &sim.neighbors,
        &mut measured,
    );
    assert!(rate > 0.0);
    assert_eq!(measured.conductance.capacity(), 0);
    // Measured aside (as the diagnostics measure it), in heat sums of its own: the same rate.
    let aside = thermal::max_stiffness_aside(
        model,
        &sim.model.walls,
        periodic,
        &sim.particles,
        &sim.neighbors,
        state,
    );
    assert_eq!(aside.to_bits(), rate.to_bits());
    let advance = |state: &mut ThermalState, dt: f64| {
        thermal::advance(
            model,
            &sim.model.walls,
            &sim.particles,
            &sim.neighbors,
            state,
            StepInfo {
                dt,
                first_flows: None,
                periodic,
            },
        )
    };
    // A step whose largest rate takes 2.5 substeps' allowance takes three; a third of it takes
    // one (the rate moves by far less than the 17 % margin over the three thirds: the positions
    // stay, only the radiation's conductance follows the temperatures).
    let dt = 2.5 * model.substep_fraction / rate;
    let mut stored = state.clone();
    assert_eq!(advance(&mut stored, dt), Some(rate));
    assert_eq!(stored.substeps, 3);
    assert!(!stored.conductance.is_empty());
    let mut computed = state.clone();
    for third in 0..3 {
        let taken = advance(&mut computed, dt / 3.0).expect("no bound given");
        if third == 0 {
            assert_eq!(taken.to_bits(), rate.to_bits());
        }
        assert_eq!(computed.substeps, 1);
        assert_eq!(computed.conductance.capacity(), 0, "third {third}");
    }
    assert!(computed.enthalpy != state.enthalpy, "heat flowed");
    assert!(
        computed.enthalpy == stored.enthalpy,
        "the enthalpies differ"
    );
    assert!(computed.temperature == stored.temperature);
    assert!(
        computed.heat_sums == stored.heat_sums,
        "the heat sums differ"
    );
}
