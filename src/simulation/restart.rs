//! Restarts: everything beyond positions and velocities that the next step depends on
//! ([`RestartState`], written to and read from the HDF5 file's `/restart` group by `output`),
//! taken from a run ([`Simulation::restart_state`]) and given back to a new one
//! ([`Simulation::resume`]), so that a resumed run continues bit for bit.

use super::{Removed, Simulation};
use crate::contact::BondState;
use crate::contact::tangential::TangentialSpring;
use crate::laser;
use crate::model::Model;
use crate::neighbor::HeldPairs;
use crate::particles::{Particles, Rotation};
use crate::thermal::{self, LaserHeat, ThermalState};
use crate::wall_history::WallSprings;

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
    /// With a `[laser]`: the power of the last cast \[W\] and the energy absorbed so far \[J\],
    /// per particle.
    pub laser: Option<LaserHeat>,
    /// With heat exchanged with walls, gas or surroundings: the heat so far, per particle \[J\].
    pub boundary_energy: Option<Vec<f64>>,
    /// Heat carried off by evaporation so far, per particle \[J\]: with a material that
    /// evaporates (M.80).
    pub evaporated: Option<Vec<f64>>,
    /// Most substeps in one step so far.
    pub max_substeps: u32,
}

impl Simulation {
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
                laser: t.laser.clone(),
                boundary_energy: t.boundary.as_ref().map(|b| b.energy.clone()),
                evaporated: t.evaporation.as_ref().map(|e| e.evaporated.clone()),
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
        // Each saved per-particle array must hold one entry a particle.
        let fits = |len: usize, what: &str| {
            if len == n {
                Ok(())
            } else {
                Err(format!("restart data has {len} {what} for {n} particles"))
            }
        };
        fits(state.force.len(), "forces")?;
        let thermal = match (&model.thermal, state.thermal) {
            (Some(thermal_model), Some(saved)) => {
                let mut t = ThermalState::new(thermal_model, &particles, model.laser.is_some());
                fits(saved.enthalpy.len(), "temperatures")?;
                fits(saved.melted.len(), "melt flags")?;
                for k in 0..n {
                    let constants = t.heat_constants(&particles, k);
                    t.enthalpy[k] = saved.enthalpy[k];
                    t.temperature[k] = thermal::temperature_from_enthalpy(
                        saved.enthalpy[k],
                        constants.heat_capacity,
                        constants.melting_point,
                        constants.latent_heat,
                    );
                }
                t.melted = saved.melted;
                // A file without the arrays of a source the scene has (saved by a scene without
                // it) starts them at zero, and a source the scene no longer has drops its arrays:
                // the resumed run's heat balance starts anew anyway. (A laser whose power was not
                // saved has no snapshot either, and casts anew at the first step.)
                if let (Some(laser), Some(saved)) = (&mut t.laser, saved.laser) {
                    fits(saved.power.len(), "laser powers")?;
                    fits(saved.energy.len(), "laser energies")?;
                    *laser = saved;
                }
                if let (Some(boundary), Some(energy)) = (&mut t.boundary, saved.boundary_energy) {
                    fits(energy.len(), "boundary heats")?;
                    boundary.energy = energy;
                }
                if let (Some(evaporation), Some(evaporated)) =
                    (&mut t.evaporation, saved.evaporated)
                {
                    fits(evaporated.len(), "evaporated heats")?;
                    evaporation.evaporated = evaporated;
                }
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
        let mut sim = Self::assemble(model, particles, thermal, rotation);
        sim.laser_snapshot = state.laser.unwrap_or_default();
        sim.removed = state.removed;
        sim.step = state.step;
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
}
