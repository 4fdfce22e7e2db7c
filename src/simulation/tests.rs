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

/// The largest `G_i / C_i` [1/s] of `sim`'s state, measured as the diagnostics measure it.
fn largest_heat_rate(sim: &Simulation) -> f64 {
    thermal::max_stiffness(
        sim.model.thermal.as_ref().expect("[thermal]"),
        &sim.model.walls,
        sim.model.periodic.as_ref(),
        &sim.particles,
        &sim.neighbors,
        sim.thermal.as_ref().expect("[thermal]"),
    )
}

/// The force pass bounds the largest `G_i / C_i` without summing any G_i
/// (`HeatRate::at_most`), from the largest `H_ij / min(m_i, m_j)` of a contact (P), the most
/// slots of one particle in the neighbour list (D) and the specific heat c. Checked on a bed of
/// one size and one of two, from its parts:
/// - P is the largest of the pairs' own, each conductance computed one pair at a time, to the
///   bit;
/// - D is the most slots of one particle, counted pair by pair;
/// - the bound lies between the largest rate and D times it: the small sphere of the pair that
///   gives P has at least that contact, so the largest rate is at least P / c;
/// - the bound asked for one substep, and the step took the rate itself only for the
///   diagnostics (in its force pass, as the last step of its `advance` call).
#[test]
fn the_force_pass_bounds_the_largest_heat_rate_from_its_contacts() {
    for scale in [1.0, 1.05] {
        let sim = packed_bed(scale);
        let model = sim.model.thermal.as_ref().expect("[thermal]");
        let state = sim.thermal.as_ref().expect("[thermal]");
        // The bound sufficed (dt G/C is about 1e-4 here): one substep.
        assert_eq!(state.substeps, 1);
        let seen = sim.force_summary.heat_rate_bound;
        // No exchange with walls, gas or surroundings.
        assert_eq!(seen.boundary_rate.to_bits(), 0);
        let mut conductances = Vec::new();
        thermal::update_conductances(
            model,
            sim.model.periodic.as_ref(),
            &sim.particles,
            &sim.neighbors,
            &mut conductances,
        );
        let mass = &sim.particles.mass;
        let mut degree = vec![0; sim.particles.len()];
        let mut largest_per_mass: f64 = 0.0;
        for (slot, a, b) in sim.neighbors.pairs() {
            degree[a] += 1;
            degree[b] += 1;
            if conductances[slot] > 0.0 {
                let per_mass = conductances[slot] / mass[a].min(mass[b]);
                largest_per_mass = largest_per_mass.max(per_mass);
            }
        }
        assert!(largest_per_mass > 0.0);
        assert_eq!(
            seen.contact_conductance_per_mass.to_bits(),
            largest_per_mass.to_bits()
        );
        let most = degree.into_iter().max().expect("particles");
        assert_eq!(sim.neighbors.max_degree(), most);
        let c = model.smallest_specific_heat();
        let HeatRate::AtMost(bound) = HeatRate::at_most(seen, most, c) else {
            unreachable!("`at_most` makes a bound")
        };
        let exact = largest_heat_rate(&sim);
        assert!(exact > 0.0);
        // The step, the last of its `advance` call, took the rate in its force pass for the
        // diagnostics: that of the state, up to the order of each G_i's sum.
        let taken = sim
            .max_heat_rate
            .expect("the last step of a call takes the rate");
        assert!(
            (taken / exact - 1.0).abs() < 1e-12,
            "{taken:e} against {exact:e}"
        );
        // P / c ≤ rate ≤ bound ≤ D P / c, up to rounding (1e-12 relative: far above the few
        // ulps of the quotients, far below any real difference).
        assert!(
            largest_per_mass / c <= exact * (1.0 + 1e-12),
            "scale {scale}"
        );
        assert!(exact <= bound, "{exact:e} above the bound {bound:e}");
        #[allow(clippy::cast_precision_loss)]
        let widest = most as f64 * largest_per_mass / c;
        assert!(
            bound <= widest * (1.0 + 1e-12),
            "{bound:e} against {widest:e}"
        );
    }
}

/// With an exchange with a gas (Newton cooling), the particle pass adds each particle's
/// conductance to the gas over its heat capacity to the bound: the bound's part of it is the
/// largest `h A_i / C_i`, which for spheres of one material is that of the smallest, `3 h / (ρ
/// r c)`, and the bound still lies above the largest rate.
#[test]
fn the_bound_takes_the_exchange_with_a_gas() {
    let text = conducting::packed_cube("1e-4").replace(
        "[output]",
        "[thermal.convection]\nheat_transfer_coefficient_w_m2_k = 5e4\ngas_temperature_k = 300\n\
         [output]",
    );
    let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
    let (model, mut particles) = Model::build(&scene);
    for k in (0..particles.len()).step_by(3) {
        particles.radius[k] *= 1.05;
        particles.mass[k] *= 1.05_f64.powi(3);
    }
    let mut sim = Simulation::new(model, particles);
    for _ in 0..3 {
        sim.step();
    }
    let seen = sim.force_summary.heat_rate_bound;
    let model = sim.model.thermal.as_ref().expect("[thermal]");
    let c = model.smallest_specific_heat();
    let state = sim.thermal.as_ref().expect("[thermal]");
    let rate_of = |k: usize| {
        let radius = sim.particles.radius[k];
        let area = 4.0 * std::f64::consts::PI * radius * radius;
        5e4 * area / state.heat_constants(&sim.particles, k).heat_capacity
    };
    let largest = (0..sim.particles.len()).map(rate_of).fold(0.0, f64::max);
    // The particle pass's `h A / C` and this one's differ at most by the rounding of their
    // products (1e-12 relative is far above it).
    assert!(
        (seen.boundary_rate - largest).abs() <= 1e-12 * largest,
        "{:e} against {largest:e}",
        seen.boundary_rate
    );
    let HeatRate::AtMost(bound) = HeatRate::at_most(seen, sim.neighbors.max_degree(), c) else {
        unreachable!("`at_most` makes a bound")
    };
    let exact = largest_heat_rate(&sim);
    assert!(exact <= bound, "{exact:e} above the bound {bound:e}");
    // The gas's part alone is below the rate: the contacts add to it.
    assert!(seen.boundary_rate < exact);
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
    let exact = largest_heat_rate(&sim);
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

/// The largest `G_i / C_i` measured once (`thermal::max_stiffness`, as the run's start and the
/// diagnostics take it), and a step of one substep without the force pass's flows, compute each
/// contact's conductance as they meet the pair and keep no per-slot array, whose 8 B a pair slot
/// would set a heated bed's peak memory.
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
    let rate = thermal::max_stiffness(
        model,
        &sim.model.walls,
        periodic,
        &sim.particles,
        &sim.neighbors,
        state,
    );
    assert!(rate > 0.0);
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
        computed.heat_flow == stored.heat_flow,
        "the heat flows differ"
    );
}
