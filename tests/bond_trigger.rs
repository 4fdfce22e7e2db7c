//! The temperature bond criterion in a running simulation: a pair switches to the bonded branch
//! only when the criterion holds (melting points reached: both particles, or either) and
//! δ ≥ δ_crit; a bond formed in the melt stays after the particles cool.

mod common;

use am_sim::contact::BondState;
use am_sim::simulation::Simulation;

const R: f64 = 1e-4;
const EQUILIBRIUM: f64 = 1e-6; // δ_eq; δ_crit = (4/9) δ_eq for α_adh = 1

/// Two resting spheres overlapping by `overlap`, α_adh = 1, criterion "melting" with `rule`,
/// no conduction (so each keeps its own temperature), optional cooling gas.
fn pair(overlap: f64, rule: &str, cooling: &str) -> Simulation {
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 1e-7
duration_s = 1e-2
[materials.steel]
density_kg_m3 = 7950
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
specific_heat_j_kg_k = 500
thermal_conductivity_w_m_k = 18
melting_point_k = 1700
[contact]
model = "hertz"
damping_ratio = 0.3
[bond]
adhesion_exponent = 1.0
equilibrium_overlap_m = {EQUILIBRIUM:e}
damping_ratio = 1.0
criterion = "melting"
melting_rule = "{rule}"
[thermal]
initial_temperature_k = 300
conduction = "none"
{cooling}
[[particles]]
position_m = [0.0, 0.0, 0.0]
radius_m = {R:e}
material = "steel"
[[particles]]
position_m = [{x:e}, 0.0, 0.0]
radius_m = {R:e}
material = "steel"
"#,
        x = 2.0 * R - overlap
    ))
}

/// Sets the two temperatures, takes one step, returns the pair's bond state.
fn after_one_step(sim: &mut Simulation, t0: f64, t1: f64) -> BondState {
    let thermal = sim.thermal.as_mut().unwrap();
    thermal.set_temperature(&sim.particles, 0, t0);
    thermal.set_temperature(&sim.particles, 1, t1);
    sim.step();
    sim.bond_state(0, 1)
}

#[test]
fn cold_pair_beyond_the_critical_overlap_stays_hertz() {
    let mut sim = pair(0.9 * EQUILIBRIUM, "both", "");
    assert_eq!(after_one_step(&mut sim, 300.0, 300.0), BondState::Unbonded);
    // Hertz repels: the pair separates and never bonds.
    for _ in 0..2000 {
        sim.step();
    }
    assert!(common::overlap(&sim) < 0.0 && sim.bonds().is_empty());
}

#[test]
fn hot_pair_below_the_critical_overlap_stays_hertz() {
    let mut sim = pair(0.3 * EQUILIBRIUM, "both", "");
    assert_eq!(
        after_one_step(&mut sim, 1800.0, 1800.0),
        BondState::Unbonded
    );
}

#[test]
fn hot_pair_at_the_critical_overlap_bonds_and_stays_bonded_after_cooling() {
    let cooling =
        "[thermal.convection]\nheat_transfer_coefficient_w_m2_k = 1e5\ngas_temperature_k = 300";
    let mut sim = pair(0.9 * EQUILIBRIUM, "both", cooling);
    assert_eq!(after_one_step(&mut sim, 1800.0, 1800.0), BondState::Bonded);
    // τ = C/(hA) ≈ 3.3 ms: 10 ms of gas cooling brings both far below the melting point.
    while sim.step < sim.model.steps {
        sim.step();
    }
    let t = &sim.thermal.as_ref().unwrap().temperature;
    assert!(t[0] < 500.0 && t[1] < 500.0, "cooled: {t:?}");
    assert_eq!(
        sim.bond_state(0, 1),
        BondState::Bonded,
        "the solidified neck keeps the bond"
    );
    assert!(
        (common::overlap(&sim) / EQUILIBRIUM - 1.0).abs() < 1e-3,
        "held at δ_eq"
    );
}

#[test]
fn one_melted_particle_bonds_with_either_but_not_with_both() {
    let mut both = pair(0.9 * EQUILIBRIUM, "both", "");
    assert_eq!(
        after_one_step(&mut both, 1800.0, 300.0),
        BondState::Unbonded
    );
    let mut either = pair(0.9 * EQUILIBRIUM, "either", "");
    assert_eq!(
        after_one_step(&mut either, 1800.0, 300.0),
        BondState::Bonded
    );
    // The rule is symmetric: which particle melted does not matter.
    let mut swapped = pair(0.9 * EQUILIBRIUM, "either", "");
    assert_eq!(
        after_one_step(&mut swapped, 300.0, 1800.0),
        BondState::Bonded
    );
}

#[test]
fn reaching_the_melting_point_is_latched() {
    let cooling =
        "[thermal.convection]\nheat_transfer_coefficient_w_m2_k = 1e5\ngas_temperature_k = 300";
    let mut sim = pair(0.3 * EQUILIBRIUM, "both", cooling);
    after_one_step(&mut sim, 1800.0, 1800.0);
    for _ in 0..1000 {
        sim.step();
    }
    let thermal = sim.thermal.as_ref().unwrap();
    assert!(
        thermal.temperature[0] < 1700.0,
        "cooled below the melting point"
    );
    assert_eq!(thermal.melted, vec![true, true], "the criterion stays met");
}
