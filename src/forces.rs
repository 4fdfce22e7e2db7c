//! The two parallel force passes. This is the only place that loops over pairs.
//!
//! 1. **Pair pass** (parallel over pairs): each pair reads positions and velocities, calls the pure
//!    contact law, and writes only its own result slot and its own bond state.
//! 2. **Gather pass** (parallel over particles): each particle sums its incident pair results in
//!    the fixed CSR order of the neighbour list, then adds gravity and wall contacts, and writes
//!    only its own force.
//!
//! No atomics, no locks, no thread-local buffers: each pair is computed once, its history lives in
//! one place, and the sums are bitwise identical for any thread count.

use glam::DVec3;
use rayon::prelude::*;

use crate::contact::{self, BondState, PairKinematics, hertz};
use crate::model::Model;
use crate::neighbor::NeighborList;
use crate::particles::Particles;
use crate::thermal::{self, ThermalModel};

/// What a pair contributes, stored per pair slot between the two passes.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairResult {
    /// Force on the pair's first particle [N]; the second gets the opposite.
    pub force_on_first: DVec3,
    /// Overlap δ [m] (≤ 0 when apart).
    pub overlap: f64,
}

/// Geometry of pair (a, b): unit normal from a to b and the overlap δ = r_a + r_b − |x_b − x_a|.
#[inline]
#[must_use]
pub fn pair_geometry(particles: &Particles, a: usize, b: usize) -> (DVec3, f64) {
    let separation = particles.position[b] - particles.position[a];
    let distance = separation.length();
    // Coincident centres have no direction; any unit vector keeps the force finite and the
    // blown-up overlap is reported by the run's overlap guard.
    let normal = if distance > 0.0 {
        separation / distance
    } else {
        DVec3::X
    };
    (normal, particles.radius[a] + particles.radius[b] - distance)
}

/// What the pair pass needs and fills for scenes with `[thermal]`.
#[derive(Debug)]
pub struct PairHeat<'a> {
    /// Thermal parameters.
    pub model: &'a ThermalModel,
    /// Latched melting flags (the bond criterion reads them).
    pub melted: &'a [bool],
    /// Per pair slot: the contact conductance, written by the pass [W/K].
    pub conductance: &'a mut [f64],
}

/// Pair pass: fills `results` and updates `states` (both indexed like `list.pairs`); with
/// `heat`, also each pair's contact conductance, while the pair's data is at hand.
pub fn pair_pass(
    model: &Model,
    particles: &Particles,
    list: &NeighborList,
    states: &mut [BondState],
    results: &mut [PairResult],
    heat: Option<PairHeat<'_>>,
) {
    let melted = heat.as_ref().map(|h| h.melted);
    let thermal = heat.as_ref().map(|h| h.model);
    let evaluate = |&[a, b]: &[u32; 2],
                    state: &mut BondState,
                    result: &mut PairResult,
                    conductance: Option<&mut f64>| {
        let (a, b) = (a as usize, b as usize);
        let (normal, overlap) = pair_geometry(particles, a, b);
        if let (Some(h), Some(t)) = (conductance, thermal) {
            *h = thermal::pair_conductance(t, particles, a, b, overlap);
        }
        if overlap <= 0.0 {
            *state = BondState::Unbonded;
            *result = PairResult {
                force_on_first: DVec3::ZERO,
                overlap,
            };
            return;
        }
        let kinematics = PairKinematics {
            overlap,
            overlap_rate: (particles.velocity[a] - particles.velocity[b]).dot(normal),
            effective_radius: hertz::effective_radius(particles.radius[a], particles.radius[b]),
            effective_mass: hertz::effective_mass(particles.mass[a], particles.mass[b]),
        };
        let params = model.pair_params(particles.material[a], particles.material[b]);
        let (melted_a, melted_b) = melted.map_or((false, false), |m| (m[a], m[b]));
        let criterion = model.bond_criterion.holds(melted_a, melted_b);
        let outcome = contact::normal_force(params, &kinematics, *state, criterion);
        *state = outcome.state;
        *result = PairResult {
            force_on_first: -outcome.force * normal,
            overlap,
        };
    };
    let parallel = crate::worth_parallel(list.pairs.len());
    match (heat, parallel) {
        (Some(heat), true) => {
            let slots = states
                .par_iter_mut()
                .zip(results.par_iter_mut())
                .zip(heat.conductance.par_iter_mut());
            list.pairs
                .par_iter()
                .zip(slots)
                .for_each(|(p, ((s, r), h))| evaluate(p, s, r, Some(h)));
        }
        (Some(heat), false) => {
            let slots = states
                .iter_mut()
                .zip(results.iter_mut())
                .zip(heat.conductance.iter_mut());
            list.pairs
                .iter()
                .zip(slots)
                .for_each(|(p, ((s, r), h))| evaluate(p, s, r, Some(h)));
        }
        (None, true) => {
            let slots = states.par_iter_mut().zip(results.par_iter_mut());
            list.pairs
                .par_iter()
                .zip(slots)
                .for_each(|(p, (s, r))| evaluate(p, s, r, None));
        }
        (None, false) => {
            let slots = states.iter_mut().zip(results.iter_mut());
            list.pairs
                .iter()
                .zip(slots)
                .for_each(|(p, (s, r))| evaluate(p, s, r, None));
        }
    }
}

/// Overlap of particle `k` with wall `w` [m] (positive in contact) and the wall's normal.
#[inline]
#[must_use]
pub fn wall_overlap(model: &Model, particles: &Particles, k: usize, w: usize) -> f64 {
    let wall = &model.walls[w];
    particles.radius[k] - (particles.position[k] - wall.point).dot(wall.normal)
}

/// Gather pass: `particles.force = m g + Σ pair forces (CSR order) + wall forces`.
pub fn gather(
    model: &Model,
    particles: &mut Particles,
    list: &NeighborList,
    results: &[PairResult],
) {
    let mut forces = std::mem::take(&mut particles.force);
    let state = &*particles;
    let sum = |(k, force): (usize, &mut DVec3)| {
        let mut total = state.mass[k] * model.gravity;
        for incidence in list.incident(k) {
            let f = results[incidence.pair as usize].force_on_first;
            total += if incidence.first { f } else { -f };
        }
        for w in 0..model.walls.len() {
            let overlap = wall_overlap(model, state, k, w);
            if overlap > 0.0 {
                let normal = model.walls[w].normal;
                let params = model.wall_params(w, state.material[k]);
                // A fixed plane is the limit r_j, m_j → ∞: r* = r_k, m* = m_k.
                let kinematics = PairKinematics {
                    overlap,
                    overlap_rate: -state.velocity[k].dot(normal),
                    effective_radius: state.radius[k],
                    effective_mass: state.mass[k],
                };
                total += contact::hertz_force(
                    params.effective_modulus,
                    params.damping_ratio,
                    &kinematics,
                ) * normal;
            }
        }
        *force = total;
    };
    if crate::worth_parallel(forces.len()) {
        forces.par_iter_mut().enumerate().for_each(sum);
    } else {
        forces.iter_mut().enumerate().for_each(sum);
    }
    particles.force = forces;
}
