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
//!
//! What a run measures of itself (diagnostics, balances, the stability limit and the guards) is
//! in `simulation/diagnostics.rs`; what a restart saves and gives back, in
//! `simulation/restart.rs`.

use std::ops::Range;

use crate::bed::contact_history::ImportedRotation;
use crate::contact::tangential::TangentialSpring;
use crate::contact::{BondState, hertz, rolling};
use crate::forces::{self, Evaluation, ForceSummary};
use crate::integrate;
use crate::laser;
use crate::model::Model;
use crate::neighbor::{self, HeldPairs, NearPairs, NeighborList};
use crate::pair_history::TangentialHistories;
use crate::particles::{Particles, Rotation};
use crate::thermal::{self, ThermalState};

mod diagnostics;
mod restart;
#[cfg(test)]
mod tests;

pub use diagnostics::{Diagnostics, GuardTrip, StabilityLimit, ThermalDiagnostics};
pub use restart::{RestartState, RotationRestart, ThermalRestart};

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
    /// The largest `G_i / C_i` [1/s] (M.49) at the last step's first substep, where it was
    /// taken: by the run's start, or by a step whose bound asked for more than one substep
    /// (`thermal::advance`). `None` where the bound sufficed: the diagnostics then measure it.
    max_heat_rate: Option<f64>,
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
    /// Drifts since the near lists' refresh, and the touching pairs the refreshing pass met:
    /// with `near_travel`, what the next refresh chooses its near skin from
    /// (`neighbor::NearSkinTuner`).
    near_steps: u64,
    near_touching: usize,
    near_tuner: neighbor::NearSkinTuner,
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
    /// The heat their vapour had carried off (M.80) \[J\].
    pub evaporated: f64,
    /// The mass it weighs \[kg\] (M.80).
    pub evaporated_mass: f64,
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

/// Whether a bound on how far particles moved, `travel` \[m\] (dt |v|max summed over the drifts
/// since the bound began), shows them all within `limit` \[m\]: the near lists' refresh test and
/// the rebuild test's bound. The bound sums the very steps the drifts took; the rounding of the
/// positions, about 1e-19 m a step, is far below the margin of 1e-6 relative.
fn travel_within(travel: f64, limit: f64) -> bool {
    travel < (1.0 - 1e-6) * limit
}

impl Simulation {
    /// A simulation of `particles` under `model` at step 0, with these optional states and
    /// every other part empty: the neighbour list not built yet, no forces taken, nothing
    /// removed. [`Simulation::new`] and [`Simulation::resume`] go on from here.
    fn assemble(
        model: Model,
        particles: Particles,
        thermal: Option<ThermalState>,
        rotation: Option<Rotation>,
    ) -> Self {
        let neighbors = NeighborList::new(model.skin, model.periodic);
        Self {
            model,
            particles,
            neighbors,
            bond_states: Vec::new(),
            thermal,
            laser_snapshot: laser::Snapshot::default(),
            force_summary: ForceSummary::default(),
            max_heat_rate: None,
            non_finite_force: None,
            peak_overlap_ratio: 0.0,
            start: StartEnergies::default(),
            rotation,
            tangential: TangentialHistories::default(),
            near: NearPairs::default(),
            near_travel: 0.0,
            near_steps: 0,
            near_touching: 0,
            near_tuner: neighbor::NearSkinTuner::default(),
            near_refreshes: 0,
            build_travel: f64::INFINITY,
            displacement_checks: 0,
            rebuild_bound: true,
            near_lists: true,
            walls: forces::WallCandidates::default(),
            removed: Removed::default(),
            step: 0,
            time: 0.0,
        }
    }

    /// Sets up the neighbour list and the forces at t = 0.
    #[must_use]
    pub fn new(model: Model, particles: Particles) -> Self {
        let thermal = model
            .thermal
            .as_ref()
            .map(|t| ThermalState::new(t, &particles, model.laser.is_some()));
        let rotation = model
            .friction
            .as_ref()
            .map(|_| Rotation::new(particles.len(), model.walls.len()));
        let mut sim = Self::assemble(model, particles, thermal, rotation);
        sim.rebuild_neighbors();
        let mut imported = std::mem::take(&mut sim.model.imported_rotation);
        // Sorted by key: each listed pair finds its spring by a binary search.
        imported.pair_springs.sort_unstable_by_key(|s| s.0);
        sim.set_imported_rotation(&imported);
        drop(imported);
        if sim.model.deposition.is_none() {
            // With a deposition the run starts from the settled bed (`restart_clock`).
            sim.apply_initial_regions();
        }
        sim.force_summary = sim.compute_forces(Evaluation::SetUp, None);
        sim.non_finite_force = sim.particles.force.iter().position(|f| !f.is_finite());
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
        if let (Some(model), Some(state)) = (&self.model.thermal, &self.thermal) {
            self.max_heat_rate = Some(thermal::max_stiffness(
                model,
                &self.model.walls,
                self.model.periodic.as_ref(),
                &self.particles,
                &self.neighbors,
                state,
            ));
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
                state.set_temperature(&self.particles, k, temperature);
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
                if let Some(laser) = &t.laser {
                    removed.laser_energy += laser.energy[k];
                }
                if let Some(boundary) = &t.boundary {
                    removed.boundary_energy += boundary.energy[k];
                }
                if let Some(evaporation) = &t.evaporation {
                    let heat = evaporation.evaporated[k];
                    removed.evaporated += heat;
                    removed.evaporated_mass += self.model.evaporated_mass(p.material[k], heat);
                }
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

    /// Calls `visit(slot, owner, partner, unit normal owner → partner, overlap [m])` for every
    /// touching pair, in slot order.
    fn for_each_touching_pair(&self, visit: impl FnMut(usize, usize, usize, glam::DVec3, f64)) {
        self.for_each_touching_pair_of(0..self.particles.len(), visit);
    }

    /// [`Simulation::for_each_touching_pair`] for the owners `owners`: every candidate slot of
    /// theirs, in plain loops (written with the list's pair iterator, the walk took nearly as
    /// many instructions as two steps at each output on the 19.2k LIGGGHTS bed), with the
    /// minimum image taken only for the owners that need it, as in the pair pass
    /// ([`NeighborList::needs_minimum_image`]). The touching pairs' normals and overlaps are
    /// [`forces::pair_geometry`]'s bit for bit; those apart take no square root
    /// ([`forces::touching_geometry`]).
    fn for_each_touching_pair_of(
        &self,
        owners: Range<usize>,
        mut visit: impl FnMut(usize, usize, usize, glam::DVec3, f64),
    ) {
        let p = &self.particles;
        let (list, periodic) = (&self.neighbors, self.model.periodic.as_ref());
        let (position, radius) = (&p.position[..p.len()], &p.radius[..p.len()]);
        let partners = list.partners();
        for a in owners {
            let image = periodic.filter(|_| list.needs_minimum_image(a));
            let (x_a, r_a) = (position[a], radius[a]);
            for slot in list.slots(a) {
                let b = partners[slot] as usize;
                let separation = forces::pair_separation(image, x_a, position[b]);
                if let Some((normal, overlap)) =
                    forces::touching_geometry(separation, r_a + radius[b])
                {
                    visit(slot, a, b, normal, overlap);
                }
            }
        }
    }

    /// Bonded pairs as (index a, index b, overlap \[m\], normal force \[N\], positive when
    /// repulsive), the force from the bonded law at the current positions and velocities.
    #[must_use]
    pub fn bonded_pairs(&self) -> Vec<(usize, usize, f64, f64)> {
        let p = &self.particles;
        let mut bonded = Vec::new();
        self.for_each_touching_pair(|slot, a, b, normal, overlap| {
            if self.slot_bond_state(slot) != BondState::Bonded {
                return;
            }
            let kinematics = crate::contact::PairKinematics {
                overlap,
                overlap_rate: (p.velocity[a] - p.velocity[b]).dot(normal),
                effective_radius: hertz::effective_radius(p.radius[a], p.radius[b]),
                effective_mass: hertz::effective_mass(p.mass[a], p.mass[b]),
            };
            let params = self.model.pair_params(p.material[a], p.material[b]);
            let force =
                crate::contact::normal_force(params, &kinematics, BondState::Bonded, true).force;
            bonded.push((a, b, overlap, force));
        });
        bonded
    }

    /// Number of contacts (particles and walls) of every particle.
    #[must_use]
    pub fn contact_counts(&self) -> Vec<u64> {
        let mut counts = vec![0u64; self.particles.len()];
        self.for_each_touching_pair(|_, a, b, _, _| {
            counts[a] += 1;
            counts[b] += 1;
        });
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

    /// The force pass (steps 4-5), of either kind ([`Evaluation`]: the set-up's, or a step's
    /// after the opening pass). With `[thermal]` it also computes the contact conductances and
    /// the first substep's heat flows, and adds each particle's total conductance G_i into
    /// `totals` where given.
    fn compute_forces(
        &mut self,
        evaluation: Evaluation,
        totals: Option<&mut [f64]>,
    ) -> ForceSummary {
        let heat = match (&self.model.thermal, &mut self.thermal) {
            (Some(model), Some(state)) => {
                let ThermalState {
                    temperature,
                    melted,
                    laser,
                    materials,
                    heat_flow,
                    boundary,
                    ..
                } = state;
                Some(forces::PassHeat {
                    model,
                    melted,
                    temperature,
                    laser_power: laser.as_ref().map(|l| l.power.as_slice()),
                    materials,
                    sums: heat_flow,
                    totals,
                    boundary_flow: boundary.as_mut().map(|b| b.flow.as_mut_slice()),
                })
            }
            _ => None,
        };
        // A pair missing from the near lists had a gap of at least the near skin at their
        // refresh, and each of its particles closed it by at most `near_travel` since: they
        // hold every pair that can touch while 2 × near_travel stays below the near skin.
        let near_skin = self.near.skin(&self.neighbors);
        let refresh_near = !self.near_lists
            || !self.near.belong_to(&self.neighbors)
            || !travel_within(2.0 * self.near_travel, near_skin);
        if refresh_near {
            // The near skin that would have made the last period cheapest is the next one's
            // (the lists in hand were recorded with `near_skin`, and hold `self.near.len()`).
            if self.near_lists && self.near_steps > 0 && !self.near.is_empty() {
                let last = neighbor::NearPeriod {
                    skin: near_skin,
                    steps: self.near_steps,
                    travel: self.near_travel,
                    entries: self.near.len(),
                    touching: self.near_touching,
                };
                let next =
                    self.near_tuner
                        .next(last, self.neighbors.pair_count(), self.neighbors.skin());
                self.near.set_skin(next);
            }
            self.near_travel = 0.0;
            self.near_steps = 0;
            self.near_refreshes += 1;
        }
        let summary = forces::compute(
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
            evaluation,
        );
        if refresh_near {
            self.near_touching = summary.pair_contacts;
        }
        summary
    }

    /// The tangential springs stretched now (ξ ≠ 0): `(pairs, particle–wall contacts, their
    /// energy [J])` (M.63); zeros without rotation. (Every contact holds a spring, of zero
    /// length until it has acted over a step: at the start of a run at rest, say.)
    #[must_use]
    pub fn held_springs(&self) -> (usize, usize, f64) {
        self.rotation.as_ref().map_or((0, 0, 0.0), |rotation| {
            (
                self.tangential.stretched(),
                rotation
                    .wall_springs
                    .entries()
                    .filter(|(.., spring)| spring.history != glam::DVec3::ZERO)
                    .count(),
                self.tangential.spring_energy() + rotation.wall_springs.spring_energy(),
            )
        })
    }

    /// Gives the particles the spins and their contacts the tangential springs an import brought
    /// ([`crate::bed::contact_history::ImportedRotation`]), by id, before the set-up evaluation
    /// takes the forces from them ([`Evaluation::SetUp`]). That evaluation runs each spring
    /// through the law and stores it with its energy `½ k_t |ξ|²` at the imported overlap (M.57,
    /// M.63), from which the run's energy balance starts (the set-up's own lost energy is
    /// discarded), so the springs are given here without one. Scene validation admits springs
    /// only with friction, and only for pairs and walls within the skin, which the list and the
    /// wall candidates hold.
    fn set_imported_rotation(&mut self, imported: &ImportedRotation) {
        let Some(rotation) = &mut self.rotation else {
            return;
        };
        if imported.is_empty() {
            return;
        }
        let p = &self.particles;
        // Ids are 0..n until particles leave; a list, not a map, at this peak of memory.
        let mut index_of = vec![u32::MAX; p.len()];
        for (k, &id) in p.id.iter().enumerate() {
            index_of[usize::try_from(id).expect("ids index the particles")] =
                u32::try_from(k).expect("fewer than 2^32 particles");
        }
        let index = |id: u64| index_of[usize::try_from(id).expect("an id of the bed")] as usize;
        for &(id, omega) in &imported.angular_velocity {
            rotation.angular_velocity[index(id)] = omega;
        }
        // Energy 0 until the set-up evaluation (above).
        let spring = |history| TangentialSpring {
            history,
            spring_energy: 0.0,
        };
        let springs = &imported.pair_springs;
        let mut set = 0;
        for (slot, a, b) in self.neighbors.pairs() {
            let (ia, ib) = (p.id[a], p.id[b]);
            let Ok(found) = springs.binary_search_by_key(&(ia.min(ib), ia.max(ib)), |s| s.0) else {
                continue;
            };
            // Stored as the lower id's displacement; the list's owner is `a`.
            let history = springs[found].1;
            let history = if ia < ib { history } else { -history };
            self.tangential
                .set(&self.neighbors, slot, a, spring(history));
            set += 1;
        }
        debug_assert_eq!(set, springs.len(), "validated: every pair is listed");
        let walls = imported
            .wall_springs
            .iter()
            .map(|&(id, w, history)| (index(id), w, spring(history)));
        rotation.wall_springs = crate::wall_history::WallSprings::from_entries(p.len(), walls);
    }

    /// Laser absorption with the beam at mid-step, on the drifted positions (before the force
    /// passes, which fold the absorbed power into the first substep's heat balance).
    fn absorb_laser(&mut self) {
        let heat = self.thermal.as_mut().and_then(|t| t.laser.as_mut());
        let (Some(model), Some(heat), Some(laser)) = (&self.model.thermal, heat, &self.model.laser)
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
                    laser.absorb(at, p, absorptivity, &mut heat.power)
                }
                None => {
                    heat.power.fill(0.0);
                    Vec::new()
                }
            };
            self.laser_snapshot.record(beam, &lit, p);
        }
    }

    /// Step 6 of the step order: temperatures over dt, the first substep's flows given. Keeps
    /// the first substep's `max G_i / C_i` where it was taken (`max_heat_rate`).
    fn advance_temperatures(&mut self, first_flows: Option<thermal::HeatRate>) {
        self.max_heat_rate = None;
        if let (Some(model), Some(state)) = (&self.model.thermal, &mut self.thermal) {
            let taken = thermal::advance(
                model,
                &self.model.walls,
                &self.particles,
                &self.neighbors,
                state,
                thermal::StepInfo {
                    dt: self.model.dt,
                    first_flows,
                    periodic: self.model.periodic.as_ref(),
                },
            );
            self.max_heat_rate = taken;
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
        self.advance(1, || true);
    }

    /// Advances up to `count` time steps in the documented order, as many calls of
    /// [`Simulation::step`] would, with bitwise the same results. It stops early after a step
    /// whose per-step guard trips ([`Simulation::guard_trip`]) or after which `keep_going()`
    /// is false, and returns the number of steps taken.
    ///
    /// Within the call a step's closing half kick (M.32) is left to the next step's opening
    /// pass, which gives it first with the same forces ([`integrate::Opening`]): one sweep of
    /// the velocities, forces, spins and torques fewer per step (4.5 % of the 19.2k LIGGGHTS
    /// bed's step). The state between the steps of one call is therefore never seen; every
    /// call returns with its last step complete. Before a step's kick is left to the next pass
    /// its forces are tested for NaN and infinities (the test the closing kick makes; the
    /// particle pass makes it on each chunk's finished forces,
    /// [`ForceSummary::first_non_finite_force`]): a non-finite force ends the call with that
    /// step's closing kick given alone, as `step` gives it, so that the guard names the same
    /// step and particle.
    pub fn advance(&mut self, count: u64, keep_going: impl Fn() -> bool) -> u64 {
        let dt = self.model.dt;
        let mut opening = integrate::Opening::AfterStep;
        for done in 1..=count {
            self.open_step(opening);
            self.forces_and_temperatures(done == count);
            // Found anew at every step, by its closing kick or by the test below.
            self.non_finite_force = None;
            self.step += 1;
            #[allow(clippy::cast_precision_loss)]
            let time = self.step as f64 * dt; // no accumulated round-off over millions of steps
            self.time = time;
            let last = done == count || self.guard_trip().is_some() || !keep_going();
            if last || self.force_summary.first_non_finite_force.is_some() {
                self.non_finite_force =
                    integrate::kick(&mut self.particles, self.rotation.as_mut(), dt);
                return done;
            }
            opening = integrate::Opening::AfterClosingKick;
        }
        0 // count was 0: every other call returns from the loop
    }

    /// Steps 1-3 (see the module documentation): the half kick and the drift (after the last
    /// step's closing kick, if `opening` says it was left to this pass), the rebuild, the laser.
    fn open_step(&mut self, opening: integrate::Opening) {
        let dt = self.model.dt;
        // The force pass's heat sums are zeroed with the forces (its `cleared`).
        let sums = self.thermal.as_mut().map(|t| t.heat_flow.as_mut_slice());
        let drift = integrate::kick_drift(
            &mut self.particles,
            self.rotation.as_mut(),
            sums,
            (dt, self.model.gravity),
            opening,
        );
        self.near_travel += dt * drift.max_speed;
        self.near_steps += 1;
        self.build_travel += dt * drift.max_speed;
        if self.neighbors.is_stale(self.particles.len()) || self.moved_too_far() {
            self.rebuild_neighbors();
        }
        self.absorb_laser();
    }

    /// Steps 4-6: the forces and the temperatures. With `take_rate` (the last step of an
    /// [`Simulation::advance`] call, whose state an output may read), the largest `G_i / C_i`
    /// of the first substep too, for the diagnostics.
    fn forces_and_temperatures(&mut self, take_rate: bool) {
        // At that step the force pass sums each G_i, into an array of its own (8 B a particle,
        // for that step alone): the other steps only bound the rate, which sets the substeps,
        // and a pass of its own to measure it would cost about as much as a step's heat.
        let mut totals = (take_rate && self.model.thermal.is_some() && self.thermal.is_some())
            .then(|| vec![0.0; self.particles.len()]);
        // The opening pass left the forces at the weights and the torques and heat sums at zero
        // (a rebuild permutes and drops particles with their forces).
        let summary = self.compute_forces(Evaluation::Step, totals.as_deref_mut());
        self.peak_overlap_ratio = self.peak_overlap_ratio.max(summary.max_overlap_ratio);
        self.force_summary = summary;
        let first_flows = self.model.thermal.as_ref().map(|model| {
            thermal::HeatRate::at_most(
                summary.heat_rate_bound,
                self.neighbors.max_degree(),
                model.smallest_specific_heat(),
            )
        });
        self.advance_temperatures(first_flows);
        if let (Some(totals), Some(state)) = (totals, &self.thermal) {
            // The same bits as a rate the step took itself up to the order of each sum; this
            // one is in the force pass's order, whichever the step took.
            let rate = thermal::max_heat_rate(&totals, state, &self.particles);
            self.max_heat_rate = Some(rate);
        }
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
}
