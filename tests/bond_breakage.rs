//! What happens when a bonded pair is pulled below δ_crit (docs/model.md, "Bond rules"): the bond
//! breaks there, the Hertz branch takes over, and the pair separates. Without damping the energy
//! needed to break it is the depth of the bond potential between δ_eq and δ_crit, so the
//! separation speed that breaks the bond follows from energy conservation.

mod common;

use am_sim::contact::{BondParams, BondState, bond};
use common::{Bond, E_STAR, R_STAR, RADIUS, overlap, sphere_mass, two_spheres_at};

const DENSITY: f64 = 2000.0;

fn undamped_bond() -> Bond {
    Bond {
        adhesion_exponent: 1.0,
        adhesion_stiffness: bond::adhesion_stiffness_for_equilibrium(E_STAR, R_STAR, 1.0, 5e-5),
        damping_ratio: 0.0,
        criterion: "always",
    }
}

/// Relative separation speed that just carries a pair at rest at δ_eq up to δ_crit:
/// ½ m* v² = U(δ_crit) − U(δ_eq) with U of (M.15).
fn escape_speed() -> f64 {
    let b = undamped_bond();
    let p = BondParams {
        adhesion_exponent: 1.0,
        adhesion_stiffness: b.adhesion_stiffness,
        damping_ratio: 0.0,
    };
    let (eq, crit) = (
        p.equilibrium_overlap(E_STAR, R_STAR),
        p.critical_overlap(E_STAR, R_STAR),
    );
    let depth = p.elastic_energy(E_STAR, R_STAR, crit) - p.elastic_energy(E_STAR, R_STAR, eq);
    (2.0 * depth / (sphere_mass(DENSITY) / 2.0)).sqrt()
}

/// Starts bonded at δ_eq and separating at `speed`; returns (bonded at the end, final overlap,
/// smallest overlap seen).
fn pull(speed: f64) -> (bool, f64, f64) {
    let mut sim = two_spheres_at(
        DENSITY,
        2.0 * RADIUS - 5e-5,
        -speed,
        0.0,
        Some(undamped_bond()),
        1e-7,
        2e-3,
    );
    assert_eq!(
        sim.bond_state(0, 1),
        BondState::Bonded,
        "δ_eq ≥ δ_crit: bonded from the first force evaluation"
    );
    let mut smallest = f64::INFINITY;
    for _ in 0..sim.model.steps {
        sim.step();
        smallest = smallest.min(overlap(&sim));
    }
    (
        sim.bond_state(0, 1) == BondState::Bonded,
        overlap(&sim),
        smallest,
    )
}

#[test]
fn a_pull_below_the_bond_depth_oscillates_and_stays_bonded() {
    let crit = 4.0 / 9.0 * 5e-5;
    let (bonded, _, smallest) = pull(0.95 * escape_speed());
    assert!(bonded);
    // Energy conservation keeps the turning point above δ_crit: (0.95² of the depth).
    assert!(
        smallest > crit,
        "smallest overlap {smallest} vs δ_crit {crit}"
    );
}

#[test]
fn a_pull_beyond_the_bond_depth_breaks_it_and_the_spheres_separate() {
    let (bonded, final_overlap, _) = pull(1.05 * escape_speed());
    assert!(!bonded, "bond should break below δ_crit");
    assert!(
        final_overlap < -1e-4,
        "the spheres fly apart after the break: overlap {final_overlap}"
    );
}

#[test]
fn the_breaking_speed_is_the_escape_speed_of_the_bond_potential() {
    // Bisection on the pull speed; 12 halvings of a ±20 % bracket resolve 0.01 %.
    let v = escape_speed();
    let (mut low, mut high) = (0.8 * v, 1.2 * v);
    for _ in 0..12 {
        let mid = 0.5 * (low + high);
        if pull(mid).0 { low = mid } else { high = mid }
    }
    let measured = 0.5 * (low + high);
    // Verlet's energy error at 1e-7 s (≈ 560 steps per bond period) is far below 0.5 %.
    assert!(
        (measured / v - 1.0).abs() < 5e-3,
        "measured {measured}, energy balance {v}"
    );
}

/// A scene without a bond law stores no bond state, so a restart that holds bonds cannot be
/// resumed with it: the run refuses, naming the bonds, instead of dropping them silently.
#[test]
fn a_restart_with_bonds_is_refused_by_a_scene_without_a_bond_law() {
    use am_sim::model::Model;
    use am_sim::scene::Scene;
    use am_sim::simulation::Simulation;
    let distance = 2.0 * RADIUS - 5e-5;
    let bonded = two_spheres_at(
        DENSITY,
        distance,
        0.0,
        0.0,
        Some(undamped_bond()),
        1e-7,
        1e-6,
    );
    assert_eq!(
        bonded.bonds(),
        vec![(0, 1)],
        "bonded at δ_eq from the start"
    );
    let text =
        am_sim::study::scenes::two_spheres_text(DENSITY, distance, 0.0, 0.0, None, 1e-7, 1e-6);
    let (model, particles) = Model::try_build(&Scene::from_toml(&text).unwrap()).unwrap();
    let Err(error) = Simulation::resume(model, particles, bonded.restart_state()) else {
        panic!("a restart with a bond was resumed without a bond law");
    };
    assert!(
        error.contains("1 bonds") && error.contains("[bond]"),
        "{error}"
    );
}
