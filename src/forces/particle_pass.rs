//! The particle pass: what each particle adds on its own after the pair pass (gravity is set by
//! the drift): its wall contacts (normal, and with rotation tangential and rolling), with
//! `[thermal]` its boundary heat and laser power, and the wall overlaps for the run's guard.
//! Parallel over particles, each writing only its own entries.

use glam::DVec3;

use super::{ForceSummary, PassHeat, TangentialContact, tangential_step, wall_overlap};
use crate::contact::{self, PairKinematics, rolling};
use crate::model::Model;
use crate::particles::{Particles, Rotation};
use crate::scatter::{self, PerParticle, Scatter, Window};
use crate::thermal::{self, HeatSums, ThermalModel};
use crate::wall_history::{Chunk, PARTICLES_PER_CHUNK};

/// The particle pass: the wall contacts (normal, and with rotation tangential and rolling),
/// boundary heat and laser power, and the wall overlaps for the guard, over every particle or
/// the `listed` ones (ascending; they must include every particle that touches a wall or holds a
/// wall spring). Each particle writes only its own entries. Compiled for one combination of
/// optional physics: rotation with the wall springs (`ROTATION`) and conduction (`HEAT`); what
/// it leaves out is ignored even if given.
#[allow(clippy::too_many_lines)]
pub(super) fn run<const ROTATION: bool, const HEAT: bool>(
    model: &Model,
    particles: &mut Particles,
    rotation: Option<&mut Rotation>,
    heat: Option<PassHeat<'_>>,
    listed: Option<&[u32]>,
    parallel: bool,
) -> ForceSummary {
    let mut forces = std::mem::take(&mut particles.force);
    let mut dissipated = std::mem::take(&mut particles.dissipated);
    let state = &*particles;
    let count = state.len();
    let (omega, torque, mut wall_springs) = match rotation {
        Some(r) => {
            let Rotation {
                angular_velocity,
                torque,
                wall_springs,
                ..
            } = r;
            (
                Some(angular_velocity.as_slice()),
                Some(Scatter::<_, PerParticle>::new(torque)),
                Some(wall_springs),
            )
        }
        None => (None, None, None),
    };
    // Each chunk of particles reads and writes its own wall springs (`wall_history`).
    let mut chunks: Vec<Option<&mut Chunk>> = match wall_springs.as_deref_mut() {
        Some(springs) => springs.begin_pass(count).iter_mut().map(Some).collect(),
        None => (0..count.div_ceil(PARTICLES_PER_CHUNK))
            .map(|_| None)
            .collect(),
    };
    let force_out: Scatter<'_, DVec3, PerParticle> = Scatter::new(&mut forces);
    let lost_out: Scatter<'_, f64, PerParticle> = Scatter::new(&mut dissipated);
    let heat = heat.map(|h| ParticleHeat {
        model: h.model,
        // Decided once per pass: a scene without exchange (or laser) has none to add, and its
        // boundary flows stay zero.
        exchange: h.model.has_boundary_exchange(),
        temperature: h.temperature,
        laser_power: h.laser_power,
        heat_capacity: h.heat_capacity,
        sums: Scatter::new(h.sums),
        boundary_flow: Scatter::new(h.boundary_flow),
    });
    let visit = |summary: &mut ForceSummary,
                 springs: &mut Option<&mut Chunk>,
                 window: &Window<'_>| {
        // Known at compile time to be `None` where the instantiation leaves the physics out.
        let mut springs = springs.as_deref_mut().filter(|_| ROTATION);
        let (omega, torque) = (
            omega.filter(|_| ROTATION),
            torque.as_ref().filter(|_| ROTATION),
        );
        let heat = heat.as_ref().filter(|_| HEAT);
        let particle = window.owner();
        let k = particle.index();
        // Most candidates touch no wall and hold no wall spring: without heat, they get
        // nothing. (The full path below would add zeros to their force, lost energy and torque,
        // which changes no bit of a finite sum, and observe a zero overlap.)
        if !HEAT
            && !(0..model.walls.len()).any(|w| wall_overlap(model, state, k, w) > 0.0)
            && !springs
                .as_deref_mut()
                .is_some_and(|chunk| chunk.holds_any(k))
        {
            return;
        }
        let mut max_overlap: f64 = 0.0;
        let mut force = DVec3::ZERO;
        let mut torque_k = DVec3::ZERO;
        let mut lost = 0.0;
        for w in 0..model.walls.len() {
            let overlap = wall_overlap(model, state, k, w);
            if overlap <= 0.0 {
                // The spring vanishes with the contact: what it held is lost.
                if let Some(chunk) = springs.as_deref_mut() {
                    lost += chunk.take(k, w).spring_energy;
                }
                continue;
            }
            max_overlap = max_overlap.max(overlap);
            let into_domain = model.walls[w].normal;
            let params = model.wall_params(w, state.material[k]);
            // A fixed plane is the limit r_j, m_j → ∞: r* = r_k, m* = m_k.
            let kinematics = PairKinematics {
                overlap,
                overlap_rate: -state.velocity[k].dot(into_domain),
                effective_radius: state.radius[k],
                effective_mass: state.mass[k],
            };
            let (normal_force, elastic) =
                contact::hertz_parts(params.effective_modulus, params.damping_ratio, &kinematics);
            force += normal_force * into_domain;
            // (M.35): the wall's damper work over the step.
            lost += model.dt * (normal_force - elastic) * kinematics.overlap_rate;
            if let (Some(chunk), Some(omega), Some(tables)) =
                (springs.as_deref_mut(), omega, model.friction.as_ref())
            {
                // The particle is the first body, the wall the second: the normal points into
                // the wall.
                let normal = -into_domain;
                let arm = state.radius[k] - 0.5 * overlap;
                let contact = TangentialContact {
                    normal,
                    contact_velocity: state.velocity[k] + (arm * omega[k]).cross(normal),
                    relative_angular_velocity: omega[k],
                    inverse_inertia_sum: 1.0
                        / rolling::sphere_inertia(state.mass[k], state.radius[k]),
                    normal_force,
                    elastic_normal_force: elastic,
                    bonded: false,
                };
                let step = tangential_step::<true>(
                    tables.wall(w, state.material[k]),
                    params.damping_ratio,
                    model.dt,
                    &kinematics,
                    &contact,
                    chunk.take(k, w),
                );
                force += step.force;
                torque_k += arm * normal.cross(step.force) + step.rolling_torque;
                lost += step.lost;
                chunk.keep(k, w, step.spring);
            }
        }
        force_out.update(particle, |f| f + force);
        lost_out.update(particle, |l| l + lost);
        if let Some(t) = torque {
            t.update(particle, |t| t + torque_k);
        }
        let heat_rate = heat.map_or(0.0, |h| {
            let mut added = None;
            if h.exchange {
                let (outside, outside_conductance) =
                    thermal::boundary_heat(h.model, &model.walls, state, k, h.temperature[k]);
                h.boundary_flow.update(particle, |_| outside);
                h.sums.update(particle, |s| HeatSums {
                    conductance: s.conductance + outside_conductance,
                    ..s
                });
                added = Some(outside);
            }
            if let Some(laser_power) = h.laser_power {
                added = Some(added.unwrap_or(0.0) + laser_power[k]);
            }
            if let Some(added) = added {
                h.sums.update(particle, |s| HeatSums {
                    flow: s.flow + added,
                    ..s
                });
            }
            h.sums.read(particle).conductance / h.heat_capacity[k]
        });
        summary.max_heat_rate = summary.max_heat_rate.max(heat_rate);
        summary.observe_overlap(max_overlap / state.radius[k], k);
    };
    let summary = scatter::for_each_particle(
        count,
        PARTICLES_PER_CHUNK,
        listed,
        &mut chunks,
        parallel,
        ForceSummary::default(),
        visit,
        ForceSummary::merge,
    );
    drop(chunks);
    if let Some(springs) = wall_springs {
        springs.end_pass();
    }
    particles.force = forces;
    particles.dissipated = dissipated;
    summary
}
/// The thermal part of the particle pass.
struct ParticleHeat<'a> {
    model: &'a ThermalModel,
    /// `model.has_boundary_exchange()`.
    exchange: bool,
    temperature: &'a [f64],
    laser_power: Option<&'a [f64]>,
    heat_capacity: &'a [f64],
    /// Net heat flow \[W\] and total conductance [W/K].
    sums: Scatter<'a, HeatSums, PerParticle>,
    boundary_flow: Scatter<'a, f64, PerParticle>,
}
