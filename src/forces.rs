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
    /// Mechanical energy the pair lost during this step [J] (M.35): the work of its damper
    /// (and of the sign rules' clipping), plus the drop of stored energy when it bonded (or the
    /// rise when a bond broke). Split half and half between its particles by the gather.
    pub lost: f64,
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
        if overlap <= 0.0 {
            if let Some(h) = conductance {
                *h = 0.0;
            }
            *state = BondState::Unbonded;
            *result = PairResult {
                force_on_first: DVec3::ZERO,
                overlap,
                lost: 0.0,
            };
            return;
        }
        let kinematics = PairKinematics {
            overlap,
            overlap_rate: (particles.velocity[a] - particles.velocity[b]).dot(normal),
            effective_radius: hertz::effective_radius(particles.radius[a], particles.radius[b]),
            effective_mass: hertz::effective_mass(particles.mass[a], particles.mass[b]),
        };
        if let (Some(h), Some(t)) = (conductance, thermal) {
            *h =
                thermal::pair_conductance(t, particles, a, b, overlap, kinematics.effective_radius);
        }
        let params = model.pair_params(particles.material[a], particles.material[b]);
        let (melted_a, melted_b) = melted.map_or((false, false), |m| (m[a], m[b]));
        let criterion = model.bond_criterion.holds(melted_a, melted_b);
        let outcome = contact::normal_force(params, &kinematics, *state, criterion);
        // (M.35): damper work over the step, at the half-step velocity the force used.
        let mut lost = model.dt * (outcome.force - outcome.elastic) * kinematics.overlap_rate;
        if outcome.state != *state {
            if let Some(bond) = &params.bond {
                // The stored energy jumps where eq. 25 switches branch at a given overlap.
                let hertz_energy = hertz::elastic_energy(
                    params.effective_modulus,
                    kinematics.effective_radius,
                    overlap,
                );
                let bond_energy = bond.elastic_energy(
                    params.effective_modulus,
                    kinematics.effective_radius,
                    overlap,
                );
                lost += match outcome.state {
                    BondState::Bonded => hertz_energy - bond_energy,
                    BondState::Unbonded => bond_energy - hertz_energy,
                };
            }
        }
        *state = outcome.state;
        *result = PairResult {
            force_on_first: -outcome.force * normal,
            overlap,
            lost,
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

/// What the gather pass needs and fills for scenes with `[thermal]`: the first substep's heat
/// balance (M.47) is summed over the same incidence lists as the forces.
#[derive(Debug)]
pub struct GatherHeat<'a> {
    /// Thermal parameters.
    pub model: &'a ThermalModel,
    /// Temperatures at the start of the step [K].
    pub temperature: &'a [f64],
    /// Contact conductances of the pair slots [W/K].
    pub conductance: &'a [f64],
    /// Absorbed laser power [W].
    pub laser_power: &'a [f64],
    /// Heat capacities [J/K].
    pub heat_capacity: &'a [f64],
    /// Out: net heat flow [W].
    pub heat_flow: &'a mut [f64],
    /// Out: heat flow from walls, gas and surroundings [W].
    pub boundary_flow: &'a mut [f64],
    /// Out: total conductance G_i [W/K].
    pub total_conductance: &'a mut [f64],
}

/// What the gather pass saw, reduced over particles in a thread-count-independent way (max, and
/// the lowest index on ties): the inputs of the run's per-step guards (docs/stability.md).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GatherSummary {
    /// `max G_i / C_i` [1/s] with `[thermal]`, 0 otherwise (M.49).
    pub max_heat_rate: f64,
    /// Largest overlap of any contact (particle or wall) of a particle divided by that particle's
    /// radius; over all particles this is the largest overlap relative to the smaller radius of
    /// its pair, since each pair is seen from both ends.
    pub max_overlap_ratio: f64,
    /// The particle (index) where `max_overlap_ratio` was seen.
    pub max_overlap_particle: usize,
    /// The lowest particle index whose summed force is NaN or infinite.
    pub non_finite_force: Option<usize>,
}

impl GatherSummary {
    fn of(k: usize, heat_rate: f64, overlap_ratio: f64, force: DVec3) -> Self {
        Self {
            max_heat_rate: heat_rate,
            max_overlap_ratio: overlap_ratio,
            max_overlap_particle: k,
            non_finite_force: (!force.is_finite()).then_some(k),
        }
    }

    /// Combines two partial summaries; associative and commutative, so any reduction tree gives
    /// the same result.
    #[must_use]
    fn merge(self, other: Self) -> Self {
        let overlap = if other.max_overlap_ratio > self.max_overlap_ratio
            || (other.max_overlap_ratio == self.max_overlap_ratio
                && other.max_overlap_particle < self.max_overlap_particle)
        {
            other
        } else {
            self
        };
        Self {
            max_heat_rate: self.max_heat_rate.max(other.max_heat_rate),
            max_overlap_ratio: overlap.max_overlap_ratio,
            max_overlap_particle: overlap.max_overlap_particle,
            non_finite_force: match (self.non_finite_force, other.non_finite_force) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            },
        }
    }
}

/// Gather pass: `particles.force = m g + Σ pair forces (CSR order) + wall forces`; with `heat`,
/// also each particle's heat flows. Returns what the per-step guards need.
pub fn gather(
    model: &Model,
    particles: &mut Particles,
    list: &NeighborList,
    results: &[PairResult],
    heat: Option<GatherHeat<'_>>,
) -> GatherSummary {
    let mut forces = std::mem::take(&mut particles.force);
    let mut dissipated = std::mem::take(&mut particles.dissipated);
    let state = &*particles;
    let dt = model.dt;
    let inputs = heat.as_ref().map(|h| {
        (
            h.model,
            h.temperature,
            h.conductance,
            h.laser_power,
            h.heat_capacity,
        )
    });
    let sum = |k: usize,
               force: &mut DVec3,
               lost: &mut f64,
               out: Option<(&mut f64, &mut f64, &mut f64)>|
     -> GatherSummary {
        let mut total = state.mass[k] * model.gravity;
        let mut lost_now = 0.0;
        let mut max_overlap: f64 = 0.0;
        let (mut exchange, mut conductance_sum) = (0.0, 0.0);
        let t = inputs.map_or(0.0, |(_, temperature, ..)| temperature[k]);
        for incidence in list.incident(k) {
            let result = &results[incidence.pair as usize];
            total += if incidence.first {
                result.force_on_first
            } else {
                -result.force_on_first
            };
            lost_now += 0.5 * result.lost;
            max_overlap = max_overlap.max(result.overlap);
            // Only touching pairs conduct: testing the overlap (already loaded with the force)
            // saves a random read of the conductance array for the other candidates.
            if let Some((_, temperature, conductance, ..)) = inputs.filter(|_| result.overlap > 0.0)
            {
                let h = conductance[incidence.pair as usize];
                if h > 0.0 {
                    exchange += h * (temperature[incidence.other as usize] - t);
                    conductance_sum += h;
                }
            }
        }
        for w in 0..model.walls.len() {
            let overlap = wall_overlap(model, state, k, w);
            if overlap > 0.0 {
                max_overlap = max_overlap.max(overlap);
                let normal = model.walls[w].normal;
                let params = model.wall_params(w, state.material[k]);
                // A fixed plane is the limit r_j, m_j → ∞: r* = r_k, m* = m_k.
                let kinematics = PairKinematics {
                    overlap,
                    overlap_rate: -state.velocity[k].dot(normal),
                    effective_radius: state.radius[k],
                    effective_mass: state.mass[k],
                };
                let (wall_force, elastic) = contact::hertz_parts(
                    params.effective_modulus,
                    params.damping_ratio,
                    &kinematics,
                );
                total += wall_force * normal;
                // (M.35): the wall's damper work over the step.
                lost_now += dt * (wall_force - elastic) * kinematics.overlap_rate;
            }
        }
        *force = total;
        *lost += lost_now;
        let heat_rate = match (out, inputs) {
            (Some((q, boundary, g)), Some((thermal_model, _, _, laser_power, heat_capacity))) => {
                let (outside, outside_conductance) =
                    thermal::boundary_heat(thermal_model, &model.walls, state, k, t);
                *boundary = outside;
                *q = exchange + outside + laser_power[k];
                *g = conductance_sum + outside_conductance;
                *g / heat_capacity[k]
            }
            _ => 0.0,
        };
        GatherSummary::of(k, heat_rate, max_overlap / state.radius[k], total)
    };
    let parallel = crate::worth_parallel(forces.len());
    let summary = match (heat, parallel) {
        (Some(h), true) => {
            let out = h
                .heat_flow
                .par_iter_mut()
                .zip(h.boundary_flow.par_iter_mut())
                .zip(h.total_conductance.par_iter_mut());
            forces
                .par_iter_mut()
                .zip(dissipated.par_iter_mut())
                .zip(out)
                .enumerate()
                .map(|(k, ((f, d), ((q, b), g)))| sum(k, f, d, Some((q, b, g))))
                .reduce(GatherSummary::default, GatherSummary::merge)
        }
        (Some(h), false) => {
            let out = h
                .heat_flow
                .iter_mut()
                .zip(h.boundary_flow.iter_mut())
                .zip(h.total_conductance.iter_mut());
            forces
                .iter_mut()
                .zip(dissipated.iter_mut())
                .zip(out)
                .enumerate()
                .map(|(k, ((f, d), ((q, b), g)))| sum(k, f, d, Some((q, b, g))))
                .fold(GatherSummary::default(), GatherSummary::merge)
        }
        (None, true) => forces
            .par_iter_mut()
            .zip(dissipated.par_iter_mut())
            .enumerate()
            .map(|(k, (f, d))| sum(k, f, d, None))
            .reduce(GatherSummary::default, GatherSummary::merge),
        (None, false) => forces
            .iter_mut()
            .zip(dissipated.iter_mut())
            .enumerate()
            .map(|(k, (f, d))| sum(k, f, d, None))
            .fold(GatherSummary::default(), GatherSummary::merge),
    };
    particles.force = forces;
    particles.dissipated = dissipated;
    summary
}
