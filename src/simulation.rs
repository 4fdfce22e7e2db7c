//! The state of a run and one time step.
//!
//! # Step order (docs/model.md, "Step order")
//! 1. Half kick and drift (velocity Verlet, M.30-M.31); forces start over at the weights m g.
//! 2. Rebuild the neighbour list if a particle moved more than half the skin (measured only
//!    when dt |v|max summed over the drifts since the build comes near it); bond states follow
//!    their pairs by id.
//! 3. With `[laser]`: absorbed powers, the beam at mid-step, on the drifted positions.
//! 4. Pair pass: normal forces of every pair, bond formation and breakage (paper eq. 25), and
//!    with `[thermal]` each contact's conductance.
//! 5. Particle pass: the walls, for the particles that can touch one before the next rebuild;
//!    with `[thermal]` also the first substep's heat flows from walls, gas, surroundings and
//!    laser.
//! 6. With `[thermal]`: the temperatures over dt (M.49); melted flags latch. The bond criterion
//!    of the next step's pair pass reads them.
//! 7. Second half kick (M.32), which reports the first non-finite force.

use std::ops::Range;

use crate::contact::tangential::TangentialSpring;
use crate::contact::{BondState, NormalParams, hertz, rolling, tangential};
use crate::forces::{self, ForceSummary};
use crate::integrate;
use crate::laser;
use crate::model::Model;
use crate::neighbor::{HeldPairs, NearPairs, NeighborList};
use crate::pair_history::TangentialHistories;
use crate::particles::{Particles, Rotation};
use crate::team::PARTICLES_PER_ITEM;
use crate::thermal::{self, ThermalState};
use crate::wall_history::WallSprings;

/// A running simulation.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// Run parameters.
    pub model: Model,
    /// Particle state. Positions edited between steps (rather than by [`Simulation::step`]) must
    /// not close any gap by more than half the near skin: the near lists would not see the pair
    /// (`neighbor`'s "Near lists"); a uniform shift of every particle is safe.
    pub particles: Particles,
    neighbors: NeighborList,
    /// Per pair slot of the neighbour list: the bond state, carried over rebuilds by ids; empty
    /// without a bond law (see `slot_bond_state`).
    bond_states: Vec<BondState>,
    /// Temperatures and heat bookkeeping, if the scene has `[thermal]` (otherwise nothing is
    /// allocated and no thermal pass runs).
    pub thermal: Option<ThermalState>,
    laser_snapshot: laser::Snapshot,
    /// What the last force pass saw (the per-step guards read it).
    force_summary: ForceSummary,
    /// The lowest particle whose force was NaN or infinite at the last step's closing kick (or
    /// at the set-up's force pass): the first per-step guard.
    non_finite_force: Option<usize>,
    /// Largest overlap ratio of any step of this run so far.
    peak_overlap_ratio: f64,
    /// Energies this run started from (the balances are measured against them).
    start: StartEnergies,
    /// What has left the domain so far (M.78).
    pub removed: Removed,
    /// Angular velocities, torques and wall contact histories, if the scene has friction or
    /// rolling resistance (otherwise nothing is allocated and no rotation pass runs).
    pub rotation: Option<Rotation>,
    /// With rotation only: the tangential histories of the pairs in contact, carried over
    /// rebuilds like `bond_states`.
    tangential: TangentialHistories,
    /// The slots the force pass tests between refreshes (`neighbor`'s "Near lists").
    near: NearPairs,
    /// How far any particle can have moved since the near lists' refresh \[m\]: the sum over
    /// the drifts since of dt times their largest speed.
    near_travel: f64,
    /// Force passes that recorded the near lists anew.
    near_refreshes: u64,
    /// How far any particle can have moved since the neighbour list's build \[m\]: the largest
    /// displacement as last measured, plus dt times the largest speed of every drift since
    /// (infinite when not known, so that the next step measures it).
    build_travel: f64,
    /// Drifts after which the rebuild test measured every particle's displacement.
    displacement_checks: u64,
    /// Off: the rebuild test measures after every drift (`use_rebuild_bound`).
    rebuild_bound: bool,
    /// Off: every force pass records the near lists anew, testing every candidate (the
    /// reference the near lists are tested against).
    near_lists: bool,
    /// The particles that may touch a wall before the next rebuild (the particle pass visits
    /// only these when the scene has no heat).
    walls: forces::WallCandidates,
    /// Steps taken.
    pub step: u64,
    /// Simulated time \[s\].
    pub time: f64,
}

/// What has left the domain (M.78): how many particles, and the energies they took with them,
/// so that the run's balances still close \[J\].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Removed {
    /// Particles removed.
    pub particles: u64,
    /// Their kinetic (with rotational) and gravitational energy when removed, with the elastic
    /// energy of the contacts they still had (M.78).
    pub mechanical_energy: f64,
    /// The energy they had lost to damping and friction.
    pub dissipated_energy: f64,
    /// Their enthalpy when removed.
    pub enthalpy: f64,
    /// Their enthalpy when removed less their enthalpy at the start of the run in which they
    /// left (the heat balance's share of them).
    pub enthalpy_change: f64,
    /// The laser energy they had absorbed.
    pub laser_energy: f64,
    /// The boundary heat they had received.
    pub boundary_energy: f64,
}

/// Energies at the start of a run (t = 0, or the step a resumed run starts from) \[J\].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct StartEnergies {
    kinetic: f64,
    gravitational: f64,
    elastic: f64,
    dissipated: f64,
    removed: f64,
    thermal: Option<ThermalDiagnostics>,
}

/// Why a run stopped itself (docs/stability.md): the step, the particles and the quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct GuardTrip {
    /// What tripped, with its value and limit.
    pub quantity: String,
    /// The particle ids involved.
    pub ids: Vec<u64>,
    /// Whether the current state is finite and may be written as the last frame.
    pub state_is_finite: bool,
}

/// What a resumed run needs beyond positions and velocities (see [`Simulation::restart_state`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RestartState {
    /// Steps taken.
    pub step: u64,
    /// Forces of the last step \[N\].
    pub force: Vec<glam::DVec3>,
    /// Mechanical energy lost so far, per particle \[J\] (M.35).
    pub dissipated: Vec<f64>,
    /// Bonded pairs as (id_lo, id_hi).
    pub bonded: Vec<(u64, u64)>,
    /// Thermal state, for scenes with `[thermal]`.
    pub thermal: Option<ThermalRestart>,
    /// The laser's last ray cast, for scenes with `[laser]`.
    pub laser: Option<laser::Snapshot>,
    /// Rotation and tangential histories, for scenes with friction or rolling resistance.
    pub rotation: Option<RotationRestart>,
    /// What has left the domain so far (M.78).
    pub removed: Removed,
    /// Positions of the neighbour list's last build \[m\] (empty in files written before they were
    /// saved): a resumed run builds the same list from them.
    pub neighbor_reference: Vec<glam::DVec3>,
}

/// Rotational part of [`RestartState`].
#[derive(Debug, Clone, PartialEq)]
pub struct RotationRestart {
    /// Angular velocities [rad/s].
    pub angular_velocity: Vec<glam::DVec3>,
    /// Torques of the last step [N·m].
    pub torque: Vec<glam::DVec3>,
    /// Wall histories \[m\], `[k * max(walls, 1) + w]`.
    pub wall_history: Vec<glam::DVec3>,
    /// Wall spring energies \[J\], indexed like `wall_history`.
    pub wall_spring_energy: Vec<f64>,
    /// Pairs with a tangential history, as (id_lo, id_hi).
    pub pair_ids: Vec<(u64, u64)>,
    /// Their histories \[m\] (first → second particle of the key, world frame).
    pub pair_history: Vec<glam::DVec3>,
    /// Their spring energies \[J\].
    pub pair_spring_energy: Vec<f64>,
}

/// Thermal part of [`RestartState`].
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalRestart {
    /// Enthalpy \[J\].
    pub enthalpy: Vec<f64>,
    /// Latched melting flags.
    pub melted: Vec<bool>,
    /// Laser power of the last cast \[W\].
    pub laser_power: Vec<f64>,
    /// Laser energy absorbed so far, per particle \[J\].
    pub laser_energy: Vec<f64>,
    /// Boundary heat so far, per particle \[J\].
    pub boundary_energy: Vec<f64>,
    /// Most substeps in one step so far.
    pub max_substeps: u32,
}

/// Quantities measured on the current state (all summed sequentially: reproducible).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Diagnostics {
    /// Steps taken.
    pub step: u64,
    /// Simulated time \[s\].
    pub time: f64,
    /// `Σ ½ m v²` \[J\].
    pub kinetic_energy: f64,
    /// `−Σ m g·x` \[J\].
    pub gravitational_energy: f64,
    /// Elastic energy stored in contacts and bonds (M.6, M.15) \[J\].
    pub elastic_energy: f64,
    /// Mechanical energy lost so far by damping and bond formation \[J\] (M.35).
    pub dissipated_energy: f64,
    /// Particle–particle pairs with δ > 0.
    pub contacts: usize,
    /// Particle–wall contacts.
    pub wall_contacts: usize,
    /// Bonded pairs.
    pub bonds: usize,
    /// Largest particle–particle or particle–wall overlap \[m\].
    pub max_overlap: f64,
    /// Largest overlap relative to the smaller radius of its pair.
    pub max_overlap_ratio: f64,
    /// Largest overlap ratio met at any step of this run so far (every step is checked).
    pub peak_overlap_ratio: f64,
    /// dt over the stability limit (M.70) of the stiffest contact now; > 1 is unstable.
    pub stability_ratio: f64,
    /// Mechanical energy balance (M.35) since the start of this run, relative to the energy
    /// scale of the run (see [`Simulation::diagnostics`]); positive when energy was created.
    pub energy_residual: f64,
    /// Neighbour-list builds so far.
    pub neighbor_builds: u64,
    /// Force passes so far that recorded the near lists anew (`neighbor`'s "Near lists"); the
    /// others tested only the near pairs.
    pub near_refreshes: u64,
    /// Steps so far whose rebuild test measured every particle's displacement since the build;
    /// at the others a bound showed that none can have moved half the skin.
    pub displacement_checks: u64,
    /// Particles removed so far because they left the domain (M.78); their energies stay in the
    /// totals (dissipated, thermal) and in the balances.
    pub removed_particles: u64,
    /// Thermal quantities, for scenes with `[thermal]`.
    pub thermal: Option<ThermalDiagnostics>,
}

/// Whether a bound on how far particles moved, `travel` \[m\] (dt |v|max summed over the drifts
/// since the bound began), shows them all within `limit` \[m\]: the near lists' refresh test and
/// the rebuild test's bound. The bound sums the very steps the drifts took; the rounding of the
/// positions, about 1e-19 m a step, is far below the margin of 1e-6 relative.
fn travel_within(travel: f64, limit: f64) -> bool {
    travel < (1.0 - 1e-6) * limit
}

/// One touching contact of the current state (see `Simulation::for_each_contact`).
struct Contact<'a> {
    /// The particle (index), or the pair's first particle.
    first: usize,
    /// The pair's second particle, for a particle pair.
    second: Option<usize>,
    /// The wall, for a wall contact.
    wall: Option<usize>,
    /// δ > 0 \[m\].
    overlap: f64,
    /// The smaller radius of the two (the particle's, against a wall) \[m\].
    smaller_radius: f64,
    /// r* \[m\].
    effective_radius: f64,
    /// m* \[kg\].
    effective_mass: f64,
    /// Normal-law parameters of the pair or of the particle against the wall.
    params: &'a NormalParams,
    /// Whether the pair is bonded (never for a wall).
    bonded: bool,
}

impl Contact<'_> {
    /// Elastic energy of the normal law \[J\]: Hertz, or on the bonded branch the bond law's
    /// (paper eq. 25).
    fn elastic_energy(&self) -> f64 {
        let (e_star, r_star) = (self.params.effective_modulus, self.effective_radius);
        match (self.bonded, &self.params.bond) {
            (true, Some(bond)) => bond.elastic_energy(e_star, r_star, self.overlap),
            _ => hertz::elastic_energy(e_star, r_star, self.overlap),
        }
    }
}

/// The contact that limits the time step most (M.70).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityLimit {
    /// Largest stable dt for that contact \[s\].
    pub dt_max: f64,
    /// Its particle ids (the second is `None` for a wall).
    pub ids: (u64, Option<u64>),
    /// Its overlap \[m\].
    pub overlap: f64,
}

/// Thermal quantities of the current state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ThermalDiagnostics {
    /// `Σ E_i` \[J\] (M.48).
    pub enthalpy: f64,
    /// Laser energy absorbed since the start \[J\].
    pub laser_energy: f64,
    /// Heat received from walls, gas and surroundings since the start \[J\].
    pub boundary_energy: f64,
    /// Highest particle temperature \[K\].
    pub max_temperature: f64,
    /// Particles that have reached their melting point.
    pub melted: usize,
    /// Thermal substeps of the last step.
    pub substeps: u32,
    /// dt over the smallest thermal time constant `C_i/G_i` of the last step (M.49); the
    /// substeps keep each substep's share below the scene's `substep_fraction`.
    pub time_step_ratio: f64,
    /// Heat balance since the start of this run: (stored − supplied) / scale (M.48).
    pub heat_residual: f64,
    /// `Σ (E_i − E_i(start))` over the particles, with those removed at their removal \[J\]:
    /// the heat stored since the start of the run (less what it was at the start, for the
    /// removals before it).
    pub stored: f64,
    /// `½ Σ |E_i − E_i(start)|` \[J\]: the heat that changed hands since the start of the run.
    pub exchanged: f64,
}

impl Diagnostics {
    /// Kinetic + gravitational + elastic energy \[J\].
    #[must_use]
    pub fn mechanical_energy(&self) -> f64 {
        self.kinetic_energy + self.gravitational_energy + self.elastic_energy
    }
}

impl Simulation {
    /// Sets up the neighbour list and the forces at t = 0.
    #[must_use]
    pub fn new(model: Model, particles: Particles) -> Self {
        let neighbors = NeighborList::new(model.skin, model.periodic);
        let thermal = model
            .thermal
            .as_ref()
            .map(|t| ThermalState::new(t, &particles));
        let rotation = model
            .friction
            .as_ref()
            .map(|_| Rotation::new(particles.len(), model.walls.len()));
        let mut sim = Self {
            model,
            particles,
            neighbors,
            bond_states: Vec::new(),
            thermal,
            laser_snapshot: laser::Snapshot::default(),
            force_summary: ForceSummary::default(),
            non_finite_force: None,
            peak_overlap_ratio: 0.0,
            start: StartEnergies::default(),
            rotation,
            tangential: TangentialHistories::default(),
            near: NearPairs::default(),
            near_travel: 0.0,
            near_refreshes: 0,
            build_travel: f64::INFINITY,
            displacement_checks: 0,
            rebuild_bound: true,
            near_lists: true,
            walls: forces::WallCandidates::default(),
            removed: Removed::default(),
            step: 0,
            time: 0.0,
        };
        sim.rebuild_neighbors();
        if sim.model.deposition.is_none() {
            // With a deposition the run starts from the settled bed (`restart_clock`).
            sim.apply_initial_regions();
        }
        sim.force_summary = sim.compute_forces(false);
        sim.non_finite_force = sim.particles.force.iter().position(|f| !f.is_finite());
        sim.clear_tangential_history();
        // The t = 0 evaluation did no work over time; the energy the run starts with already
        // counts any bond it formed.
        sim.particles.dissipated.fill(0.0);
        sim.mark_start();
        sim
    }

    /// Makes the current state the start of the run: step 0 at t = 0, nothing dissipated yet, and
    /// the balances and peaks measured from here (after a deposition, say).
    pub fn restart_clock(&mut self) {
        self.step = 0;
        self.time = 0.0;
        self.particles.dissipated.fill(0.0);
        self.apply_initial_regions();
        // The t = 0 diagnostics report the thermal stiffness of the state the run starts from:
        // the initial regions have just changed temperatures, and a deposition may have left
        // the heat model out (`bed::deposition`), so that no force pass has measured it.
        if let (Some(model), Some(state)) = (&self.model.thermal, &mut self.thermal) {
            // Measured in the run's own scratch arrays, not a copy of the whole thermal state
            // (about 100 B per particle at once): every step refills the heat flows before it
            // reads them, and only a step of several substeps keeps per-slot conductances,
            // computing them anew.
            self.force_summary.max_heat_rate = thermal::max_stiffness(
                model,
                &self.model.walls,
                self.model.periodic.as_ref(),
                &self.particles,
                &self.neighbors,
                state,
            );
            state.conductance = Vec::new();
        }
        self.mark_start();
    }

    /// Gives the particles in the scene's initial regions (`[[thermal.initial_region]]`) their
    /// temperatures, at the start of the run; the others keep theirs. The next force pass
    /// computes the heat flows from them.
    fn apply_initial_regions(&mut self) {
        let (Some(model), Some(state)) = (&self.model.thermal, &mut self.thermal) else {
            return;
        };
        for (k, x) in self.particles.position.iter().enumerate() {
            if let Some(temperature) = model.region_temperature(*x) {
                state.set_temperature(k, temperature);
            }
        }
    }

    /// Removes the particles whose centre has left `[domain]` (M.78), counting them and the
    /// energies they carry, so the balances still close. Runs at neighbour-list builds, which a
    /// particle moving away triggers once it has moved half the skin.
    /// The particles to keep at a rebuild: those inside the domain (M.78). The ones outside are
    /// counted, with the energies they take away, so that the run's balances still close.
    fn account_escaped(&mut self) -> Vec<bool> {
        let p = &self.particles;
        let Some(domain) = self.model.domain else {
            return vec![true; p.len()];
        };
        let keep: Vec<bool> = p.position.iter().map(|x| domain.contains(*x)).collect();
        for k in (0..p.len()).filter(|&k| !keep[k]) {
            let rotational = self.rotation.as_ref().map_or(0.0, |r| {
                0.5 * rolling::sphere_inertia(p.mass[k], p.radius[k])
                    * r.angular_velocity[k].length_squared()
            });
            let removed = &mut self.removed;
            removed.particles += 1;
            removed.mechanical_energy += 0.5 * p.mass[k] * p.velocity[k].length_squared()
                + rotational
                - p.mass[k] * self.model.gravity.dot(p.position[k]);
            removed.dissipated_energy += p.dissipated[k];
            if let Some(t) = &self.thermal {
                removed.enthalpy += t.enthalpy[k];
                removed.enthalpy_change += t.enthalpy[k] - t.start_enthalpy[k];
                removed.laser_energy += t.laser_energy[k];
                removed.boundary_energy += t.boundary_energy[k];
            }
        }
        if keep.iter().all(|k| *k) {
            return keep;
        }
        // The contacts of a removed particle end with it: their elastic energy (normal law and
        // tangential springs) leaves the mechanical energy too, and is booked with it.
        let mut elastic = 0.0;
        self.for_each_contact(|c| {
            if !keep[c.first] || c.second.is_some_and(|b| !keep[b]) {
                elastic += c.elastic_energy();
            }
        });
        self.removed.mechanical_energy += elastic;
        if let Some(rotation) = &self.rotation {
            let list = &self.neighbors;
            let springs: f64 = rotation
                .wall_springs
                .entries()
                .filter(|&(k, ..)| !keep[k])
                .map(|(.., s)| s.spring_energy)
                .chain(
                    list.pairs()
                        .filter(|&(_, a, b)| !keep[a] || !keep[b])
                        .map(|(slot, a, _)| self.tangential.get(list, slot, a).spring_energy),
                )
                .sum();
            self.removed.mechanical_energy += springs;
        }
        keep
    }

    /// Takes the current state as the reference of the run's energy balances.
    fn mark_start(&mut self) {
        if let Some(t) = &mut self.thermal {
            t.mark_start();
        }
        let d = self.diagnostics();
        self.peak_overlap_ratio = d.max_overlap_ratio;
        self.start = StartEnergies {
            kinetic: d.kinetic_energy,
            gravitational: d.gravitational_energy,
            elastic: d.elastic_energy,
            dissipated: d.dissipated_energy,
            removed: self.removed.mechanical_energy,
            thermal: d.thermal,
        };
    }

    /// Everything beyond positions and velocities that the next step depends on, so that a run
    /// resumed from it continues bit for bit (see [`Simulation::resume`]).
    #[must_use]
    pub fn restart_state(&self) -> RestartState {
        RestartState {
            step: self.step,
            force: self.particles.force.clone(),
            dissipated: self.particles.dissipated.clone(),
            bonded: self.bonds(),
            thermal: self.thermal.as_ref().map(|t| ThermalRestart {
                enthalpy: t.enthalpy.clone(),
                melted: t.melted.clone(),
                laser_power: t.laser_power.clone(),
                laser_energy: t.laser_energy.clone(),
                boundary_energy: t.boundary_energy.clone(),
                max_substeps: t.max_substeps,
            }),
            laser: self
                .model
                .laser
                .as_ref()
                .map(|_| self.laser_snapshot.clone()),
            rotation: self.rotation.as_ref().map(|r| self.rotation_restart(r)),
            removed: self.removed,
            neighbor_reference: self.neighbors.reference_positions().to_vec(),
        }
    }

    fn rotation_restart(&self, rotation: &Rotation) -> RotationRestart {
        // The restart format keeps a slot per particle and wall, `[k * max(walls, 1) + w]`.
        let stride = rotation.walls.max(1);
        let mut dense_wall_springs =
            vec![TangentialSpring::default(); rotation.angular_velocity.len() * stride];
        for (k, w, spring) in rotation.wall_springs.entries() {
            dense_wall_springs[k * stride + w] = spring;
        }
        // Saved by id key, oriented from the lower id to the higher (slots are oriented owner →
        // partner, and the owner depends on the storage order).
        let held: Vec<((u64, u64), TangentialSpring)> = self
            .pair_keys()
            .filter_map(|(p, owner, key, owner_is_lower)| {
                let t = self.tangential.get(&self.neighbors, p, owner);
                (t != TangentialSpring::default())
                    .then_some((key, if owner_is_lower { t } else { t.turned() }))
            })
            .collect();
        RotationRestart {
            angular_velocity: rotation.angular_velocity.clone(),
            torque: rotation.torque.clone(),
            wall_history: dense_wall_springs.iter().map(|c| c.history).collect(),
            wall_spring_energy: dense_wall_springs.iter().map(|c| c.spring_energy).collect(),
            pair_ids: held.iter().map(|(key, _)| *key).collect(),
            pair_history: held.iter().map(|(_, t)| t.history).collect(),
            pair_spring_energy: held.iter().map(|(_, t)| t.spring_energy).collect(),
        }
    }

    /// Rotation state from restart data (`None` without friction in the scene).
    fn resumed_rotation(
        model: &Model,
        n: usize,
        saved: Option<&RotationRestart>,
    ) -> Result<Option<Rotation>, String> {
        match (&model.friction, saved) {
            (None, None) => Ok(None),
            (Some(_), None) => Err(
                "the scene has friction or rolling resistance but the restart data has no angular velocities"
                    .into(),
            ),
            (None, Some(_)) => Err(
                "the restart data has angular velocities but the scene has no friction or rolling resistance"
                    .into(),
            ),
            (Some(_), Some(saved)) => {
                let mut rotation = Rotation::new(n, model.walls.len());
                let stride = model.walls.len().max(1);
                if saved.angular_velocity.len() != n
                    || saved.torque.len() != n
                    || saved.wall_history.len() != n * stride
                    || saved.wall_spring_energy.len() != n * stride
                {
                    return Err(format!(
                        "restart data has {} angular velocities and {} wall histories for {n} particles and {} walls",
                        saved.angular_velocity.len(),
                        saved.wall_history.len(),
                        model.walls.len()
                    ));
                }
                rotation.angular_velocity.clone_from(&saved.angular_velocity);
                rotation.torque.clone_from(&saved.torque);
                let springs = saved
                    .wall_history
                    .iter()
                    .zip(&saved.wall_spring_energy)
                    .enumerate()
                    .map(|(slot, (history, energy))| {
                        let spring = TangentialSpring {
                            history: *history,
                            spring_energy: *energy,
                        };
                        (slot / stride, slot % stride, spring)
                    });
                rotation.wall_springs = WallSprings::from_entries(n, springs);
                Ok(Some(rotation))
            }
        }
    }

    /// Continues a run: `particles` carry the saved positions and velocities (same ids, same
    /// order as the scene builds them), `state` the rest. Forces are not recomputed (they were
    /// computed with the half-step velocities of velocity Verlet; recomputing them with v(t)
    /// would change the next step) and no bond is formed or broken here.
    ///
    /// # Errors
    /// A message if the saved state does not fit the scene (array lengths).
    pub fn resume(model: Model, particles: Particles, state: RestartState) -> Result<Self, String> {
        let n = particles.len();
        if state.force.len() != n {
            return Err(format!(
                "restart data has {} forces for {n} particles",
                state.force.len()
            ));
        }
        let thermal = match (&model.thermal, state.thermal) {
            (Some(thermal_model), Some(saved)) => {
                let mut t = ThermalState::new(thermal_model, &particles);
                if saved.enthalpy.len() != n || saved.melted.len() != n {
                    return Err(format!(
                        "restart data has {} temperatures for {n} particles",
                        saved.enthalpy.len()
                    ));
                }
                for k in 0..n {
                    t.enthalpy[k] = saved.enthalpy[k];
                    t.temperature[k] = thermal::temperature_from_enthalpy(
                        saved.enthalpy[k],
                        t.heat_capacity[k],
                        t.melting_point[k],
                        t.latent_heat[k],
                    );
                }
                t.melted = saved.melted;
                t.laser_power = saved.laser_power;
                t.laser_energy = saved.laser_energy;
                t.boundary_energy = saved.boundary_energy;
                t.max_substeps = saved.max_substeps;
                Some(t)
            }
            (None, None) => None,
            (Some(_), None) => {
                return Err(
                    "the scene has [thermal] but the restart data has no temperatures".into(),
                );
            }
            (None, Some(_)) => {
                return Err(
                    "the restart data has temperatures but the scene has no [thermal]".into(),
                );
            }
        };
        let rotation = Self::resumed_rotation(&model, n, state.rotation.as_ref())?;
        let mut sim = Self {
            neighbors: NeighborList::new(model.skin, model.periodic),
            model,
            particles,
            bond_states: Vec::new(),
            thermal,
            laser_snapshot: state.laser.unwrap_or_default(),
            force_summary: ForceSummary::default(),
            non_finite_force: None,
            peak_overlap_ratio: 0.0,
            start: StartEnergies::default(),
            rotation,
            tangential: TangentialHistories::default(),
            near: NearPairs::default(),
            near_travel: 0.0,
            near_refreshes: 0,
            build_travel: f64::INFINITY,
            displacement_checks: 0,
            rebuild_bound: true,
            near_lists: true,
            walls: forces::WallCandidates::default(),
            removed: state.removed,
            step: state.step,
            time: 0.0,
        };
        #[allow(clippy::cast_precision_loss)]
        let time = sim.step as f64 * sim.model.dt;
        sim.time = time;
        sim.particles.force = state.force;
        if state.dissipated.len() == n {
            sim.particles.dissipated = state.dissipated;
        }
        // The list of the original run at this step: built from the positions of its last build,
        // on the particles in the order they were saved, so that the resumed run sums every force
        // in the same order (and rebuilds at the same step) as the original.
        let reference = if state.neighbor_reference.len() == n {
            state.neighbor_reference
        } else {
            sim.particles.position.clone()
        };
        sim.neighbors.build(&reference, &sim.particles.radius);
        // Nothing held: the pair data come from the restart data below.
        sim.carry_pairs(&[], &HeldPairs::default(), &HeldPairs::default());
        if !state.bonded.is_empty() && !sim.model.has_bonds() {
            return Err(format!(
                "the restart data has {} bonds but the scene has no bond law ([bond])",
                state.bonded.len()
            ));
        }
        let bonded: std::collections::HashSet<(u64, u64)> = state.bonded.into_iter().collect();
        let held: std::collections::HashMap<(u64, u64), TangentialSpring> = state
            .rotation
            .as_ref()
            .map(|saved| {
                saved
                    .pair_ids
                    .iter()
                    .zip(saved.pair_history.iter().zip(&saved.pair_spring_energy))
                    .map(|(key, (history, spring_energy))| {
                        let t = TangentialSpring {
                            history: *history,
                            spring_energy: *spring_energy,
                        };
                        (*key, t)
                    })
                    .collect()
            })
            .unwrap_or_default();
        let keys: Vec<_> = sim.pair_keys().collect();
        for (p, owner, key, owner_is_lower) in keys {
            if bonded.contains(&key) {
                // (Only with a bond law: a restart with bonds is refused without one, above.)
                sim.bond_states[p] = BondState::Bonded;
            }
            if let Some(t) = held.get(&key) {
                let t = if owner_is_lower { *t } else { t.turned() };
                sim.tangential.set(&sim.neighbors, p, owner, t);
            }
        }
        sim.mark_start();
        Ok(sim)
    }

    /// The bond state of pair slot `slot` (always unbonded without a bond law, where no state is
    /// stored).
    fn slot_bond_state(&self, slot: usize) -> BondState {
        self.bond_states.get(slot).copied().unwrap_or_default()
    }

    /// Every pair slot as `(slot, owner, (id_lo, id_hi), whether the owner has the lower id)`.
    fn pair_keys(&self) -> impl Iterator<Item = (usize, usize, (u64, u64), bool)> + '_ {
        let ids = &self.particles.id;
        self.neighbors.pairs().map(|(p, a, b)| {
            let (ia, ib) = (ids[a], ids[b]);
            (p, a, (ia.min(ib), ia.max(ib)), ia < ib)
        })
    }

    /// Every touching pair as `(slot, owner, partner, unit normal owner → partner, overlap [m])`,
    /// in slot order.
    fn touching_pairs(&self) -> impl Iterator<Item = (usize, usize, usize, glam::DVec3, f64)> + '_ {
        self.touching_pairs_of(0..self.particles.len())
    }

    /// The touching pairs of the owners `owners`, as [`Simulation::touching_pairs`] gives them.
    fn touching_pairs_of(
        &self,
        owners: Range<usize>,
    ) -> impl Iterator<Item = (usize, usize, usize, glam::DVec3, f64)> + '_ {
        let periodic = self.model.periodic.as_ref();
        self.neighbors
            .pairs_of(owners)
            .filter_map(move |(p, a, b)| {
                let (normal, overlap) = forces::pair_geometry(periodic, &self.particles, a, b);
                (overlap > 0.0).then_some((p, a, b, normal, overlap))
            })
    }

    /// Bonded pairs as (index a, index b, overlap \[m\], normal force \[N\], positive when
    /// repulsive), the force from the bonded law at the current positions and velocities.
    #[must_use]
    pub fn bonded_pairs(&self) -> Vec<(usize, usize, f64, f64)> {
        let p = &self.particles;
        self.touching_pairs()
            .filter(|(slot, ..)| self.slot_bond_state(*slot) == BondState::Bonded)
            .map(|(_, a, b, normal, overlap)| {
                let kinematics = crate::contact::PairKinematics {
                    overlap,
                    overlap_rate: (p.velocity[a] - p.velocity[b]).dot(normal),
                    effective_radius: hertz::effective_radius(p.radius[a], p.radius[b]),
                    effective_mass: hertz::effective_mass(p.mass[a], p.mass[b]),
                };
                let params = self.model.pair_params(p.material[a], p.material[b]);
                let force =
                    crate::contact::normal_force(params, &kinematics, BondState::Bonded, true)
                        .force;
                (a, b, overlap, force)
            })
            .collect()
    }

    /// Number of contacts (particles and walls) of every particle.
    #[must_use]
    pub fn contact_counts(&self) -> Vec<u64> {
        let mut counts = vec![0u64; self.particles.len()];
        for (_, a, b, _, _) in self.touching_pairs() {
            counts[a] += 1;
            counts[b] += 1;
        }
        for (k, count) in counts.iter_mut().enumerate() {
            for w in 0..self.model.walls.len() {
                if forces::wall_overlap(&self.model, &self.particles, k, w) > 0.0 {
                    *count += 1;
                }
            }
        }
        counts
    }

    /// The rebuild test ([`NeighborList::moved_too_far`]), measured only when `build_travel`,
    /// a bound on the largest displacement since the build, comes near half the skin
    /// ([`travel_within`]): a settled bed then measures it a few times between builds instead
    /// of at every drift. The test decides as if measured at every step, so the builds come at
    /// the same steps.
    fn moved_too_far(&mut self) -> bool {
        if self.rebuild_bound && travel_within(self.build_travel, 0.5 * self.neighbors.skin()) {
            return false;
        }
        self.displacement_checks += 1;
        let measured = self
            .neighbors
            .largest_displacement_squared(&self.particles.position);
        self.build_travel = measured.sqrt();
        self.neighbors.moved_too_far(measured)
    }

    /// Step 2: removes the particles that left the domain, wraps positions into the periodic
    /// box, stores the particles in the neighbour list's spatial order, rebuilds the list and
    /// carries every pair's bond state and tangential history over by the particles' ids.
    fn rebuild_neighbors(&mut self) {
        let keep = self.account_escaped();
        if let Some(periodic) = &self.model.periodic {
            // (M.77): back into the box; the neighbour search and the output see wrapped
            // positions, and the reference positions of the next rebuild check are these.
            for x in &mut self.particles.position {
                *x = periodic.wrap(*x);
            }
        }
        // The near lists name the old slots: no use after the rebuild, freed before its peak.
        self.near = NearPairs::default();
        crate::memory::return_free_pages();
        let (states, tangential, list) = (&self.bond_states, &self.tangential, &self.neighbors);
        let bonds = list.held_pairs(|p, _| {
            states
                .get(p)
                .copied()
                .filter(|state| *state != BondState::Unbonded)
        });
        let springs = list.held_pairs(|p, owner| {
            let spring = tangential.get(list, p, owner);
            (spring != TangentialSpring::default()).then_some(spring)
        });
        // The old per-slot arrays go before the new ones are built (peak memory).
        self.bond_states = Vec::new();
        self.tangential = TangentialHistories::default();
        if let Some(t) = &mut self.thermal {
            t.conductance = Vec::new();
        }
        crate::memory::return_free_pages();
        let order =
            self.neighbors
                .spatial_order(&self.particles.position, &self.particles.radius, &keep);
        self.reorder(&order);
        let p = &self.particles;
        self.neighbors.build(&p.position, &p.radius);
        self.build_travel = 0.0;
        self.carry_pairs(&order, &bonds, &springs);
    }

    /// Stores the particles in `order` (`new[i] = old[order[i]]`), dropping those not named.
    fn reorder(&mut self, order: &[u32]) {
        self.particles.select(order);
        if let Some(t) = &mut self.thermal {
            t.select(order);
        }
        if let Some(r) = &mut self.rotation {
            r.select(order);
        }
        self.laser_snapshot.renumber(order);
    }

    /// The pair data of the rebuilt list, from the bonds and springs held before the rebuild
    /// (keyed by the particles' indices then: `origin[k]` is particle `k`'s).
    fn carry_pairs(
        &mut self,
        origin: &[u32],
        bonds: &HeldPairs<BondState>,
        springs: &HeldPairs<TangentialSpring>,
    ) {
        if self.model.has_bonds() {
            self.bond_states = self.neighbors.carry(origin, bonds, |state, _| *state);
        }
        if self.rotation.is_some() {
            self.tangential =
                TangentialHistories::carry(&self.neighbors, origin, springs, |t, turned| {
                    if turned { t.turned() } else { *t }
                });
        }
    }

    /// The force pass (steps 4-5). With `[thermal]` it also computes the contact conductances
    /// and the first substep's heat flows. `cleared`: the forces are already at the weights and
    /// the torques (and with heat, the heat flows and total conductances) at zero, as the step's
    /// opening pass leaves them (the pass then skips setting them: one parallel region and one
    /// sweep fewer per step, three with heat).
    fn compute_forces(&mut self, cleared: bool) -> ForceSummary {
        let heat = match (&self.model.thermal, &mut self.thermal) {
            (Some(model), Some(state)) => {
                let ThermalState {
                    temperature,
                    melted,
                    laser_power,
                    heat_capacity,
                    heat_flow,
                    boundary_flow,
                    total_conductance,
                    ..
                } = state;
                Some(forces::PassHeat {
                    model,
                    melted,
                    temperature,
                    laser_power: self.model.laser.is_some().then_some(laser_power.as_slice()),
                    heat_capacity,
                    heat_flow,
                    boundary_flow,
                    total_conductance,
                })
            }
            _ => None,
        };
        // A pair missing from the near lists had a gap of at least the near skin at their
        // refresh, and each of its particles closed it by at most `near_travel` since: they
        // hold every pair that can touch while 2 × near_travel stays below the near skin.
        let refresh_near = !self.near_lists
            || !self.near.belong_to(&self.neighbors)
            || !travel_within(2.0 * self.near_travel, self.neighbors.near_skin());
        if refresh_near {
            self.near_travel = 0.0;
            self.near_refreshes += 1;
        }
        forces::compute(
            &self.model,
            &mut self.particles,
            &self.neighbors,
            (&mut self.near, refresh_near),
            &mut self.walls,
            self.model
                .has_bonds()
                .then_some(self.bond_states.as_mut_slice()),
            self.rotation.as_mut().map(|rotation| forces::PassRotation {
                rotation,
                histories: &mut self.tangential,
            }),
            heat,
            cleared,
        )
    }

    /// The set-up evaluation at t = 0 computed the tangential forces with a history advanced by
    /// v_t dt; a run starts with no tangential displacement, so the history is cleared (the
    /// energy it held was not counted either: `dissipated` is reset too).
    fn clear_tangential_history(&mut self) {
        if let Some(rotation) = &mut self.rotation {
            self.tangential.clear();
            rotation.wall_springs.clear();
        }
    }

    /// Laser absorption with the beam at mid-step, on the drifted positions (before the force
    /// passes, which fold the absorbed power into the first substep's heat balance).
    fn absorb_laser(&mut self) {
        let (Some(model), Some(state), Some(laser)) =
            (&self.model.thermal, &mut self.thermal, &self.model.laser)
        else {
            return;
        };
        let beam = laser.beam_at(self.time + 0.5 * self.model.dt);
        let p = &self.particles;
        if !self.laser_snapshot.still_valid(beam, p, laser.raster_cell) {
            let lit = match beam {
                Some(at) => {
                    let absorptivity =
                        |k: usize| model.materials[usize::from(p.material[k])].absorptivity;
                    laser.absorb(at, p, absorptivity, &mut state.laser_power)
                }
                None => {
                    state.laser_power.fill(0.0);
                    Vec::new()
                }
            };
            self.laser_snapshot.record(beam, &lit, p);
        }
    }

    /// Step 6 of the step order: temperatures over dt, the first substep's flows given.
    fn advance_temperatures(&mut self, first_flows: Option<f64>) {
        if let (Some(model), Some(state)) = (&self.model.thermal, &mut self.thermal) {
            thermal::advance(
                model,
                &self.model.walls,
                &self.particles,
                &self.neighbors,
                state,
                thermal::StepInfo {
                    dt: self.model.dt,
                    first_flows,
                    laser_on: self.model.laser.is_some(),
                    periodic: self.model.periodic.as_ref(),
                },
            );
        }
    }

    /// Whether the force passes test only the near pairs between refreshes (the default), or
    /// every candidate at every pass. The results are the same; the switch exists so that tests
    /// can show it.
    pub fn use_near_lists(&mut self, on: bool) {
        self.near_lists = on;
    }

    /// Whether the rebuild test measures the displacements only when the bound on them comes
    /// near half the skin (the default), or after every drift. The builds come at the same
    /// steps either way; the switch exists so that tests can show it.
    pub fn use_rebuild_bound(&mut self, on: bool) {
        self.rebuild_bound = on;
    }

    /// Advances one time step in the documented order.
    pub fn step(&mut self) {
        let dt = self.model.dt;
        // The force pass's heat sums are zeroed with the forces (its `cleared`).
        let sums = self.thermal.as_mut().map(|t| {
            (
                t.heat_flow.as_mut_slice(),
                t.total_conductance.as_mut_slice(),
            )
        });
        let drift = integrate::kick_drift(
            &mut self.particles,
            self.rotation.as_mut(),
            sums,
            (dt, self.model.gravity),
        );
        self.near_travel += dt * drift.max_speed;
        self.build_travel += dt * drift.max_speed;
        if self.neighbors.is_stale(self.particles.len()) || self.moved_too_far() {
            self.rebuild_neighbors();
        }
        self.absorb_laser();
        // The opening pass left the forces at the weights and the torques and heat sums at zero
        // (a rebuild permutes and drops particles with their forces).
        let summary = self.compute_forces(true);
        self.peak_overlap_ratio = self.peak_overlap_ratio.max(summary.max_overlap_ratio);
        self.force_summary = summary;
        let first_flows = self.thermal.is_some().then_some(summary.max_heat_rate);
        self.advance_temperatures(first_flows);
        self.non_finite_force = integrate::kick(&mut self.particles, self.rotation.as_mut(), dt);
        self.step += 1;
        #[allow(clippy::cast_precision_loss)]
        let time = self.step as f64 * dt; // no accumulated round-off over millions of steps
        self.time = time;
    }

    /// Bond state of the pair of particle ids `(a, b)` (in either order); `Unbonded` if the pair
    /// is not in the neighbour list.
    #[must_use]
    pub fn bond_state(&self, a: u64, b: u64) -> BondState {
        let key = (a.min(b), a.max(b));
        self.pair_keys()
            .find(|(_, _, k, _)| *k == key)
            .map_or(BondState::Unbonded, |(p, ..)| self.slot_bond_state(p))
    }

    /// Bonded pairs as `(id_lo, id_hi)`, sorted.
    #[must_use]
    pub fn bonds(&self) -> Vec<(u64, u64)> {
        let mut bonds: Vec<(u64, u64)> = self
            .pair_keys()
            .filter(|(p, ..)| self.slot_bond_state(*p) == BondState::Bonded)
            .map(|(_, _, key, _)| key)
            .collect();
        bonds.sort_unstable();
        bonds
    }

    /// Measures the current state.
    #[must_use]
    pub fn diagnostics(&self) -> Diagnostics {
        let p = &self.particles;
        let mut d = Diagnostics {
            step: self.step,
            time: self.time,
            kinetic_energy: p.kinetic_energy(),
            dissipated_energy: p.dissipated_energy() + self.removed.dissipated_energy,
            removed_particles: self.removed.particles,
            gravitational_energy: p.gravitational_energy(self.model.gravity),
            neighbor_builds: self.neighbors.builds,
            near_refreshes: self.near_refreshes,
            displacement_checks: self.displacement_checks,
            ..Diagnostics::default()
        };
        let mut tightest = f64::INFINITY;
        let partials = self.fold_contacts(
            || (Diagnostics::default(), f64::INFINITY),
            |(d, tightest), contact| {
                if contact.second.is_some() {
                    d.contacts += 1;
                } else {
                    d.wall_contacts += 1;
                }
                d.max_overlap = d.max_overlap.max(contact.overlap);
                d.max_overlap_ratio = d
                    .max_overlap_ratio
                    .max(contact.overlap / contact.smaller_radius);
                if contact.bonded && contact.params.bond.is_some() {
                    d.bonds += 1;
                }
                d.elastic_energy += contact.elastic_energy();
                *tightest = tightest.min(self.stability_limit_of(&contact));
            },
        );
        for (chunk, chunk_tightest) in partials {
            d.contacts += chunk.contacts;
            d.wall_contacts += chunk.wall_contacts;
            d.max_overlap = d.max_overlap.max(chunk.max_overlap);
            d.max_overlap_ratio = d.max_overlap_ratio.max(chunk.max_overlap_ratio);
            d.bonds += chunk.bonds;
            d.elastic_energy += chunk.elastic_energy;
            tightest = tightest.min(chunk_tightest);
        }
        if let Some(rotation) = &self.rotation {
            // (M.63): rotation is kinetic energy, the tangential springs store elastic energy.
            d.kinetic_energy += rotation.kinetic_energy(p);
            d.elastic_energy += self.tangential.spring_energy() + rotation.wall_spring_energy();
        }
        d.thermal = self.thermal.as_ref().map(|t| {
            let (stored, exchanged) = t.enthalpy_change();
            ThermalDiagnostics {
                enthalpy: t.total_enthalpy() + self.removed.enthalpy,
                laser_energy: t.total_laser_energy() + self.removed.laser_energy,
                boundary_energy: t.total_boundary_energy() + self.removed.boundary_energy,
                max_temperature: t
                    .temperature
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max),
                melted: t.melted.iter().filter(|m| **m).count(),
                substeps: t.substeps,
                time_step_ratio: self.model.dt * self.force_summary.max_heat_rate,
                heat_residual: 0.0,
                stored: stored + self.removed.enthalpy_change,
                exchanged,
            }
        });
        d.peak_overlap_ratio = self.peak_overlap_ratio.max(d.max_overlap_ratio);
        d.stability_ratio = self.model.dt / tightest;
        self.close_balances(&mut d);
        d
    }

    /// The balances of this run, against its start (M.35, M.48). The mechanical residual is
    /// `(E(t) + W_lost − E(0)) / scale`, with the scale the energy the run had or exchanged:
    /// kinetic and elastic energy at the start, the change of gravitational energy and the energy
    /// lost (not the gravitational energy itself, which depends on where z = 0 is; and not the
    /// current energies, so that a blow-up shows as a large residual instead of saturating at 1).
    fn close_balances(&self, d: &mut Diagnostics) {
        let start = &self.start;
        let created = d.mechanical_energy() + d.dissipated_energy + self.removed.mechanical_energy
            - (start.kinetic
                + start.gravitational
                + start.elastic
                + start.dissipated
                + start.removed);
        let scale = [
            start.kinetic,
            start.elastic,
            d.gravitational_energy - start.gravitational,
            d.dissipated_energy - start.dissipated,
            // Round-off of the sums, for a run where nothing moves.
            f64::EPSILON * (d.gravitational_energy.abs() + d.mechanical_energy().abs()),
        ]
        .iter()
        .fold(f64::MIN_POSITIVE, |m, x| m.max(x.abs()));
        d.energy_residual = created / scale;
        if let (Some(t), Some(t0)) = (&mut d.thermal, &start.thermal) {
            let stored = t.stored - t0.stored;
            let supplied =
                (t.laser_energy - t0.laser_energy) + (t.boundary_energy - t0.boundary_energy);
            // The heat supplied, stored or moved between particles: conduction alone supplies
            // and stores nothing, and its balance is measured against what it moved.
            let scale = t
                .laser_energy
                .abs()
                .max(t.boundary_energy.abs())
                .max(stored.abs())
                .max(t.exchanged)
                .max(t0.enthalpy.abs() * f64::EPSILON);
            t.heat_residual = (stored - supplied) / scale;
        }
    }

    /// The per-step guards (docs/stability.md), from what the last force pass saw: a NaN or
    /// infinite force, or an overlap beyond `guards.max_overlap_ratio`. Costs nothing extra:
    /// the gather pass reduces both while summing forces.
    #[must_use]
    pub fn guard_trip(&self) -> Option<GuardTrip> {
        let summary = &self.force_summary;
        if let Some(k) = self.non_finite_force {
            return Some(GuardTrip {
                quantity: "a non-finite (NaN or infinite) force".into(),
                ids: vec![self.particles.id[k]],
                state_is_finite: false,
            });
        }
        let limit = self.model.guards.max_overlap_ratio;
        if summary.max_overlap_ratio > limit {
            let k = summary.max_overlap_particle;
            return Some(GuardTrip {
                quantity: format!(
                    "an overlap of {:.3} × the radius (guards.max_overlap_ratio = {limit})",
                    summary.max_overlap_ratio
                ),
                ids: self.deepest_contact_of(k),
                state_is_finite: integrate::first_non_finite(&self.particles).is_none(),
            });
        }
        None
    }

    /// The energy guard on measured diagnostics: energy created beyond
    /// `guards.max_energy_residual` of the run's energy scale.
    #[must_use]
    pub fn energy_guard_trip(&self, d: &Diagnostics) -> Option<GuardTrip> {
        let limit = self.model.guards.max_energy_residual;
        (d.energy_residual > limit).then(|| {
            let p = &self.particles;
            let fastest = (0..p.len()).max_by(|&a, &b| {
                p.velocity[a]
                    .length_squared()
                    .total_cmp(&p.velocity[b].length_squared())
            });
            GuardTrip {
                quantity: format!(
                    "an energy blow-up (the fastest particle): the mechanical energy balance gained {:.3} × the run's energy scale (guards.max_energy_residual = {limit})",
                    d.energy_residual
                ),
                ids: fastest.map(|k| vec![p.id[k]]).unwrap_or_default(),
                state_is_finite: integrate::first_non_finite(p).is_none(),
            }
        })
    }

    /// Particle `k` and the partner of its deepest contact (ids; one id for a wall).
    fn deepest_contact_of(&self, k: usize) -> Vec<u64> {
        let p = &self.particles;
        let mut deepest = (f64::NEG_INFINITY, None);
        for (_, a, b, _, overlap) in self.touching_pairs() {
            if (a == k || b == k) && overlap > deepest.0 {
                deepest = (overlap, Some(p.id[a + b - k]));
            }
        }
        for w in 0..self.model.walls.len() {
            let overlap = forces::wall_overlap(&self.model, p, k, w);
            if overlap > deepest.0 {
                deepest = (overlap, None);
            }
        }
        std::iter::once(p.id[k]).chain(deepest.1).collect()
    }

    /// The tightest time-step stability limit (M.70) over the contacts of the current state:
    /// each touching pair or wall contact with its tangent stiffness at its overlap (Hertz M.5,
    /// or eq. 24 when bonded) and its damping ratio. `None` without contacts.
    #[must_use]
    pub fn stability_limit_now(&self) -> Option<StabilityLimit> {
        let mut tightest: Option<StabilityLimit> = None;
        self.for_each_contact(|contact| {
            let limit = self.stability_limit_of(&contact);
            if tightest.is_none_or(|t| limit < t.dt_max) {
                let p = &self.particles;
                tightest = Some(StabilityLimit {
                    dt_max: limit,
                    ids: (p.id[contact.first], contact.second.map(|b| p.id[b])),
                    overlap: contact.overlap,
                });
            }
        });
        tightest
    }

    /// The stability limit (M.70) of one contact: its tangent stiffness at its overlap (Hertz
    /// M.5, or eq. 24 when bonded) with its damping ratio, lowered by the sticking tangential
    /// spring (M.64) when the scene has friction.
    fn stability_limit_of(&self, contact: &Contact<'_>) -> f64 {
        let p = &self.particles;
        let (a, params) = (contact.first, contact.params);
        let (stiffness, damping_ratio) = match (contact.bonded, &params.bond) {
            (true, Some(bond)) => (
                bond.stiffness(
                    params.effective_modulus,
                    contact.effective_radius,
                    contact.overlap,
                ),
                bond.damping_ratio,
            ),
            _ => (
                hertz::stiffness(
                    params.effective_modulus,
                    contact.effective_radius,
                    contact.overlap,
                ),
                params.damping_ratio,
            ),
        };
        let sticking = self.model.friction.as_ref().map_or(1.0, |f| {
            let friction = match (contact.second, contact.wall) {
                (Some(b), _) => f.pair(p.material[a], p.material[b]),
                (None, Some(w)) => f.wall(w, p.material[a]),
                (None, None) => unreachable!("a contact has a second particle or a wall"),
            };
            tangential::sticking_time_factor(
                friction.effective_shear_modulus,
                params.effective_modulus,
            )
            .min(1.0)
        });
        sticking * integrate::stability_limit(stiffness, contact.effective_mass, damping_ratio)
    }

    /// Visits every touching contact of the current state, particles' chunk by chunk
    /// ([`PARTICLES_PER_ITEM`] consecutive particles): the chunk's pairs with δ > 0 in the
    /// neighbour list's order (the pairs it owns), then its particles' wall contacts (a wall is
    /// the limit r, m → ∞: r* = r, m* = m). The measurements of the state (diagnostics,
    /// stability limit) all walk the contacts in this order, serially or
    /// ([`Simulation::fold_contacts`]) chunk by chunk on the team.
    fn for_each_contact(&self, mut visit: impl FnMut(Contact<'_>)) {
        for first in (0..self.particles.len()).step_by(PARTICLES_PER_ITEM) {
            self.contacts_of_chunk(first, &mut visit);
        }
    }

    /// The partials `visit` folds from `identity()` over each chunk's contacts (in the order of
    /// [`Simulation::for_each_contact`]), in chunk order: the chunks run on the thread team when
    /// the state is large, and the caller merges the partials in this order, so the thread
    /// count does not change a sum.
    fn fold_contacts<R: Send>(
        &self,
        identity: impl Fn() -> R + Sync,
        visit: impl Fn(&mut R, Contact<'_>) + Sync,
    ) -> Vec<R> {
        let count = self.particles.len();
        let chunks: Vec<usize> = (0..count).step_by(PARTICLES_PER_ITEM).collect();
        let mut partials = crate::team::fold_items(
            crate::worth_parallel(count),
            chunks,
            Vec::new,
            |mut partials, c, first| {
                let mut partial = identity();
                self.contacts_of_chunk(first, |contact| visit(&mut partial, contact));
                partials.push((c, partial));
                partials
            },
            |mut a, b| {
                a.extend(b);
                a
            },
        );
        // The team's members may take each other's chunks: the order is restored here.
        partials.sort_unstable_by_key(|(c, _)| *c);
        partials.into_iter().map(|(_, partial)| partial).collect()
    }

    /// The contacts of the chunk of particles from `first` (see [`Simulation::for_each_contact`]).
    fn contacts_of_chunk(&self, first: usize, mut visit: impl FnMut(Contact<'_>)) {
        let p = &self.particles;
        let chunk = first..(first + PARTICLES_PER_ITEM).min(p.len());
        for (slot, a, b, _, overlap) in self.touching_pairs_of(chunk.clone()) {
            visit(Contact {
                first: a,
                second: Some(b),
                wall: None,
                overlap,
                smaller_radius: p.radius[a].min(p.radius[b]),
                effective_radius: hertz::effective_radius(p.radius[a], p.radius[b]),
                effective_mass: hertz::effective_mass(p.mass[a], p.mass[b]),
                params: self.model.pair_params(p.material[a], p.material[b]),
                bonded: self.slot_bond_state(slot) == BondState::Bonded,
            });
        }
        for k in chunk {
            for w in 0..self.model.walls.len() {
                let overlap = forces::wall_overlap(&self.model, p, k, w);
                if overlap > 0.0 {
                    visit(Contact {
                        first: k,
                        second: None,
                        wall: Some(w),
                        overlap,
                        smaller_radius: p.radius[k],
                        effective_radius: p.radius[k],
                        effective_mass: p.mass[k],
                        params: self.model.wall_params(w, p.material[k]),
                        bonded: false,
                    });
                }
            }
        }
    }

    /// Smallest thermal time constant `min C_i/G_i` \[s\] at the current state (M.49), for scenes
    /// with `[thermal]`; infinite when nothing exchanges heat.
    #[must_use]
    pub fn smallest_thermal_time_constant(&self) -> Option<f64> {
        let model = self.model.thermal.as_ref()?;
        // Evaluated on a copy: measuring must not touch the run's scratch arrays.
        let mut state = self.thermal.clone()?;
        Some(
            1.0 / thermal::max_stiffness(
                model,
                &self.model.walls,
                self.model.periodic.as_ref(),
                &self.particles,
                &self.neighbors,
                &mut state,
            ),
        )
    }

    /// The first non-finite particle value as `(particle id, field)`.
    #[must_use]
    pub fn first_non_finite(&self) -> Option<(u64, &'static str)> {
        let thermal = self.thermal.as_ref().and_then(|t| {
            t.temperature
                .iter()
                .position(|x| !x.is_finite())
                .map(|k| (k, "temperature"))
        });
        let rotation = self.rotation.as_ref().and_then(|r| {
            r.angular_velocity
                .iter()
                .position(|w| !w.is_finite())
                .map(|k| (k, "angular_velocity"))
        });
        integrate::first_non_finite(&self.particles)
            .or(thermal)
            .or(rotation)
            .map(|(k, field)| (self.particles.id[k], field))
    }
}
