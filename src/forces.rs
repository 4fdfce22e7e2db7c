//! The parallel force passes. This is the only place that loops over pairs.
//!
//! 1. **Pair pass** (parallel over pairs): each pair reads positions and velocities, calls the pure
//!    contact law, and writes only its own result slot and its own bond state.
//! 2. **Gather pass** (parallel over particles): each particle sums its incident pair results in
//!    the fixed CSR order of the neighbour list, then adds gravity and wall contacts, and writes
//!    only its own force.
//! 3. **Torque pass** (parallel over particles, only with friction or rolling resistance): each
//!    particle sums the torques of its incident pair slots in the same CSR order and adds its
//!    walls' tangential forces and torques, writing only its own slots ([`torque_gather`]).
//!
//! No atomics, no locks, no thread-local buffers: each pair is computed once, its history lives in
//! one place, and the sums are bitwise identical for any thread count.

use glam::DVec3;
use rayon::prelude::*;

use crate::contact::{self, BondState, FrictionParams, PairKinematics, hertz, rolling, tangential};
use crate::model::Model;
use crate::neighbor::NeighborList;
use crate::particles::{Particles, Rotation, WallTangential};
use crate::periodic::Periodic;
use crate::thermal::{self, ThermalModel};

/// What a pair contributes, stored per pair slot between the two passes.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairResult {
    /// Force on the pair's first particle [N]; the second gets the opposite.
    pub force_on_first: DVec3,
    /// Overlap δ [m]; negative when apart (then −(d² − R²)/(2R), R = r_a + r_b: only the sign is
    /// meaningful, which spares the square root for the many candidate pairs that do not touch).
    pub overlap: f64,
    /// Mechanical energy the pair lost during this step [J] (M.35): the work of its damper
    /// (and of the sign rules' clipping), plus the drop of stored energy when it bonded (or the
    /// rise when a bond broke). Split half and half between its particles by the gather.
    pub lost: f64,
}

/// `x_b − x_a` [m], as its minimum image across periodic axes (M.77).
#[inline]
#[must_use]
pub fn pair_separation(
    periodic: Option<&Periodic>,
    particles: &Particles,
    a: usize,
    b: usize,
) -> DVec3 {
    let separation = particles.position[b] - particles.position[a];
    periodic.map_or(separation, |p| p.minimum_image(separation))
}

/// Geometry of pair (a, b): unit normal from a to b and the overlap δ = r_a + r_b − |x_b − x_a|,
/// with x_b − x_a taken as its minimum image across periodic axes (M.77).
#[inline]
#[must_use]
pub fn pair_geometry(
    periodic: Option<&Periodic>,
    particles: &Particles,
    a: usize,
    b: usize,
) -> (DVec3, f64) {
    let separation = pair_separation(periodic, particles, a, b);
    let distance = separation.length();
    (
        unit_normal(separation, distance),
        particles.radius[a] + particles.radius[b] - distance,
    )
}

/// `separation / distance`, the unit normal from a to b. Coincident centres have no direction;
/// any unit vector keeps the force finite, and the blown-up overlap is reported by the run's
/// overlap guard.
#[inline]
fn unit_normal(separation: DVec3, distance: f64) -> DVec3 {
    if distance > 0.0 {
        separation / distance
    } else {
        DVec3::X
    }
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

/// Per pair slot, for scenes with friction or rolling resistance: the tangential history
/// (carried over neighbour-list rebuilds by id key) and the torques of this step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairTangential {
    /// Tangential displacement ξ [m] of the first particle relative to the second, world frame,
    /// turned into the current tangent plane at each use (M.58).
    pub history: DVec3,
    /// Spring energy `½ k_t |ξ|²` at the last evaluation [J] (M.63).
    pub spring_energy: f64,
    /// Torque on the first particle [N·m] (M.60, M.61).
    pub torque_on_first: DVec3,
    /// Torque on the second particle [N·m].
    pub torque_on_second: DVec3,
}

/// What the pair pass needs and fills for scenes with friction or rolling resistance.
#[derive(Debug)]
pub struct PairFriction<'a> {
    /// Angular velocities [rad/s] (at the half step, like the velocities).
    pub angular_velocity: &'a [DVec3],
    /// Per pair slot: history in, history and torques out.
    pub slots: &'a mut [PairTangential],
}

/// One contact as the tangential and rolling laws see it (a pair, or a particle and a wall).
#[derive(Debug, Clone, Copy)]
struct TangentialContact {
    /// Unit normal from the first body to the second.
    normal: DVec3,
    /// `v_first − v_second` at the contact point (M.60) [m/s].
    contact_velocity: DVec3,
    /// `ω_first − ω_second` [rad/s].
    relative_angular_velocity: DVec3,
    /// `1/I_first + 1/I_second` [1/(kg·m²)].
    inverse_inertia_sum: f64,
    /// Total and elastic normal force [N], positive when repulsive.
    normal_force: f64,
    elastic_normal_force: f64,
    /// A bonded neck sticks: no Coulomb limit (docs/model.md section 27.5).
    bonded: bool,
}

/// What one contact's tangential and rolling laws give over one step.
#[derive(Debug, Clone, Copy)]
struct TangentialStep {
    /// Tangential force on the first body [N].
    force: DVec3,
    /// Rolling torque on the first body [N·m] (the second gets the opposite).
    rolling_torque: DVec3,
    history: DVec3,
    spring_energy: f64,
    /// Energy lost over the step [J] (M.63).
    lost: f64,
}

/// Tangential spring (M.57–M.59) and rolling resistance (M.61) of one contact over one step,
/// and the energy they took (M.63): `−F_t·v_t dt − ΔU_t + (−M_r·ω_rel) dt`.
fn tangential_step(
    params: &FrictionParams,
    damping_ratio: f64,
    dt: f64,
    kinematics: &PairKinematics,
    contact: &TangentialContact,
    history: DVec3,
    spring_energy: f64,
) -> TangentialStep {
    let n = contact.normal;
    let v = contact.contact_velocity;
    let tangential_velocity = v - v.dot(n) * n;
    let (mut force, mut new_history, mut new_energy) = (DVec3::ZERO, DVec3::ZERO, 0.0);
    if params.sliding > 0.0 || contact.bonded {
        let stiffness = tangential::stiffness(
            params.effective_shear_modulus,
            kinematics.effective_radius,
            kinematics.overlap,
        );
        let damping =
            tangential::damping_coefficient(damping_ratio, kinematics.effective_mass, stiffness);
        // LIGGGHTS caps with the total normal force (M.59, section 27.3).
        let limit = (!contact.bonded).then(|| params.sliding * contact.normal_force.abs());
        let out = tangential::tangential_force(
            tangential::rotate_history(history, n),
            tangential_velocity,
            dt,
            stiffness,
            damping,
            limit,
        );
        force = out.force;
        new_history = out.history;
        new_energy = tangential::spring_energy(stiffness, new_history);
    }
    let rolling_torque = rolling::rolling_torque(
        params.rolling,
        kinematics.effective_radius,
        contact.elastic_normal_force,
        contact.relative_angular_velocity,
        contact.inverse_inertia_sum,
        dt,
    );
    let lost = -dt * force.dot(tangential_velocity)
        - (new_energy - spring_energy)
        - dt * rolling_torque.dot(contact.relative_angular_velocity);
    TangentialStep {
        force,
        rolling_torque,
        history: new_history,
        spring_energy: new_energy,
        lost,
    }
}

/// Pair pass: fills `results` and updates `states` (both indexed like `list.pairs`); with
/// `heat`, also each pair's contact conductance, while the pair's data is at hand; with
/// `friction`, the tangential force (added to the result) and the pair's torques.
pub fn pair_pass(
    model: &Model,
    particles: &Particles,
    list: &NeighborList,
    states: &mut [BondState],
    results: &mut [PairResult],
    heat: Option<PairHeat<'_>>,
    friction: Option<PairFriction<'_>>,
) {
    let melted = heat.as_ref().map(|h| h.melted);
    let thermal = heat.as_ref().map(|h| h.model);
    let angular_velocity = friction.as_ref().map(|f| f.angular_velocity);
    let evaluate = |&[a, b]: &[u32; 2],
                    state: &mut BondState,
                    result: &mut PairResult,
                    conductance: Option<&mut f64>,
                    slot: Option<&mut PairTangential>| {
        let (a, b) = (a as usize, b as usize);
        let separation = pair_separation(model.periodic.as_ref(), particles, a, b);
        let reach = particles.radius[a] + particles.radius[b];
        let distance_squared = separation.length_squared();
        if distance_squared >= reach * reach {
            // Most candidate pairs are apart: no square root, no division for them. The stored
            // overlap is −(d² − R²)/(2R), negative like the gap R − d and within (R − d)²/(2R)
            // of it; only its sign is ever read for an apart pair.
            if let Some(h) = conductance {
                *h = 0.0;
            }
            // The spring vanishes with the contact (k_t → 0 as δ → 0): what it held is lost, and
            // the torques go to zero. Written only when not already clear, to spare the memory
            // traffic of the many pairs that stay apart.
            let released = slot
                .filter(|t| **t != PairTangential::default())
                .map_or(0.0, |t| std::mem::take(t).spring_energy);
            *state = BondState::Unbonded;
            *result = PairResult {
                force_on_first: DVec3::ZERO,
                overlap: (reach * reach - distance_squared) / (2.0 * reach),
                lost: released,
            };
            return;
        }
        let distance = distance_squared.sqrt();
        let normal = unit_normal(separation, distance);
        let overlap = reach - distance;
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
        let mut force_on_first = -outcome.force * normal;
        if let (Some(slot), Some(omega), Some(tables)) =
            (slot, angular_velocity, model.friction.as_ref())
        {
            // Lever arms to the middle of the overlap (M.60).
            let arm_a = particles.radius[a] - 0.5 * overlap;
            let arm_b = particles.radius[b] - 0.5 * overlap;
            let v = particles.velocity[a] - particles.velocity[b];
            let contact = TangentialContact {
                normal,
                contact_velocity: v + (arm_a * omega[a] + arm_b * omega[b]).cross(normal),
                relative_angular_velocity: omega[a] - omega[b],
                inverse_inertia_sum: 1.0
                    / rolling::sphere_inertia(particles.mass[a], particles.radius[a])
                    + 1.0 / rolling::sphere_inertia(particles.mass[b], particles.radius[b]),
                normal_force: outcome.force,
                elastic_normal_force: outcome.elastic,
                bonded: outcome.state == BondState::Bonded,
            };
            let step = tangential_step(
                tables.pair(particles.material[a], particles.material[b]),
                params.damping_ratio,
                model.dt,
                &kinematics,
                &contact,
                slot.history,
                slot.spring_energy,
            );
            force_on_first += step.force;
            lost += step.lost;
            let lever = normal.cross(step.force);
            *slot = PairTangential {
                history: step.history,
                spring_energy: step.spring_energy,
                torque_on_first: arm_a * lever + step.rolling_torque,
                torque_on_second: arm_b * lever - step.rolling_torque,
            };
        }
        *result = PairResult {
            force_on_first,
            overlap,
            lost,
        };
    };
    let parallel = crate::worth_parallel(list.pairs.len());
    if let Some(friction) = friction {
        pair_pass_with_friction(
            list,
            states,
            results,
            heat,
            friction.slots,
            parallel,
            evaluate,
        );
        return;
    }
    match (heat, parallel) {
        (Some(heat), true) => {
            let slots = states
                .par_iter_mut()
                .zip(results.par_iter_mut())
                .zip(heat.conductance.par_iter_mut());
            list.pairs
                .par_iter()
                .zip(slots)
                .for_each(|(p, ((s, r), h))| evaluate(p, s, r, Some(h), None));
        }
        (Some(heat), false) => {
            let slots = states
                .iter_mut()
                .zip(results.iter_mut())
                .zip(heat.conductance.iter_mut());
            list.pairs
                .iter()
                .zip(slots)
                .for_each(|(p, ((s, r), h))| evaluate(p, s, r, Some(h), None));
        }
        (None, true) => {
            let slots = states.par_iter_mut().zip(results.par_iter_mut());
            list.pairs
                .par_iter()
                .zip(slots)
                .for_each(|(p, (s, r))| evaluate(p, s, r, None, None));
        }
        (None, false) => {
            let slots = states.iter_mut().zip(results.iter_mut());
            list.pairs
                .iter()
                .zip(slots)
                .for_each(|(p, (s, r))| evaluate(p, s, r, None, None));
        }
    }
}

/// The pair pass's loop for scenes with friction: the tangential slots zipped in, and the
/// conductances when there are any (an `Either` of slots or `None`s keeps it to two arms).
fn pair_pass_with_friction<F>(
    list: &NeighborList,
    states: &mut [BondState],
    results: &mut [PairResult],
    heat: Option<PairHeat<'_>>,
    slots: &mut [PairTangential],
    parallel: bool,
    evaluate: F,
) where
    F: Fn(
            &[u32; 2],
            &mut BondState,
            &mut PairResult,
            Option<&mut f64>,
            Option<&mut PairTangential>,
        ) + Sync,
{
    use rayon::iter::Either;
    let n = list.pairs.len();
    if parallel {
        let conductance = match heat {
            Some(h) => Either::Left(h.conductance.par_iter_mut().map(Some)),
            None => Either::Right((0..n).into_par_iter().map(|_| None)),
        };
        let outputs = states
            .par_iter_mut()
            .zip(results.par_iter_mut())
            .zip(conductance.zip(slots.par_iter_mut()));
        list.pairs
            .par_iter()
            .zip(outputs)
            .for_each(|(p, ((s, r), (h, t)))| evaluate(p, s, r, h, Some(t)));
    } else {
        let conductance = match heat {
            Some(h) => Either::Left(h.conductance.iter_mut().map(Some)),
            None => Either::Right((0..n).map(|_| None)),
        };
        let outputs = states
            .iter_mut()
            .zip(results.iter_mut())
            .zip(conductance.zip(slots.iter_mut()));
        list.pairs
            .iter()
            .zip(outputs)
            .for_each(|(p, ((s, r), (h, t)))| evaluate(p, s, r, h, Some(t)));
    }
}

/// Torques and the tangential part of the wall contacts, for scenes with friction or rolling
/// resistance (parallel over particles, after [`gather`]): each particle sums its incident pair
/// torques in CSR order, then adds, wall by wall, the wall's tangential force to its force and
/// the wall's torque, and its wall springs' lost energy to its own accumulator (M.63).
pub fn torque_gather(
    model: &Model,
    particles: &mut Particles,
    list: &NeighborList,
    slots: &[PairTangential],
    rotation: &mut Rotation,
) {
    let Some(tables) = model.friction.as_ref() else {
        return;
    };
    let mut forces = std::mem::take(&mut particles.force);
    let mut dissipated = std::mem::take(&mut particles.dissipated);
    let mut torques = std::mem::take(&mut rotation.torque);
    let mut wall_contacts = std::mem::take(&mut rotation.wall_contacts);
    let stride = rotation.wall_stride();
    let (state, omega) = (&*particles, &rotation.angular_velocity);
    let sum = |k: usize,
               ((force, lost), (torque, walls)): (
        (&mut DVec3, &mut f64),
        (&mut DVec3, &mut [WallTangential]),
    )| {
        let mut total = DVec3::ZERO;
        for incidence in list.incident(k) {
            let slot = &slots[incidence.pair as usize];
            total += if incidence.first {
                slot.torque_on_first
            } else {
                slot.torque_on_second
            };
        }
        for (w, wall_slot) in walls.iter_mut().enumerate().take(model.walls.len()) {
            let overlap = wall_overlap(model, state, k, w);
            if overlap <= 0.0 {
                *lost += std::mem::take(wall_slot).spring_energy;
                continue;
            }
            let into_domain = model.walls[w].normal;
            let params = model.wall_params(w, state.material[k]);
            let kinematics = PairKinematics {
                overlap,
                overlap_rate: -state.velocity[k].dot(into_domain),
                effective_radius: state.radius[k],
                effective_mass: state.mass[k],
            };
            let (normal_force, elastic) =
                contact::hertz_parts(params.effective_modulus, params.damping_ratio, &kinematics);
            // The particle is the first body, the wall the second: the normal points into the wall.
            let normal = -into_domain;
            let arm = state.radius[k] - 0.5 * overlap;
            let contact = TangentialContact {
                normal,
                contact_velocity: state.velocity[k] + (arm * omega[k]).cross(normal),
                relative_angular_velocity: omega[k],
                inverse_inertia_sum: 1.0 / rolling::sphere_inertia(state.mass[k], state.radius[k]),
                normal_force,
                elastic_normal_force: elastic,
                bonded: false,
            };
            let step = tangential_step(
                tables.wall(w, state.material[k]),
                params.damping_ratio,
                model.dt,
                &kinematics,
                &contact,
                wall_slot.history,
                wall_slot.spring_energy,
            );
            *force += step.force;
            total += arm * normal.cross(step.force) + step.rolling_torque;
            *lost += step.lost;
            *wall_slot = WallTangential {
                history: step.history,
                spring_energy: step.spring_energy,
            };
        }
        *torque = total;
    };
    if crate::worth_parallel(forces.len()) {
        forces
            .par_iter_mut()
            .zip(dissipated.par_iter_mut())
            .zip(
                torques
                    .par_iter_mut()
                    .zip(wall_contacts.par_chunks_mut(stride)),
            )
            .enumerate()
            .for_each(|(k, slots)| sum(k, slots));
    } else {
        forces
            .iter_mut()
            .zip(dissipated.iter_mut())
            .zip(torques.iter_mut().zip(wall_contacts.chunks_mut(stride)))
            .enumerate()
            .for_each(|(k, slots)| sum(k, slots));
    }
    particles.force = forces;
    particles.dissipated = dissipated;
    rotation.torque = torques;
    rotation.wall_contacts = wall_contacts;
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
