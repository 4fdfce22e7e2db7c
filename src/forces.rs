//! The force pass: the only place that loops over pairs for forces.
//!
//! 1. **Pair pass**, a coloured traversal of the neighbour list
//!    ([`NeighborList::for_each_owner`]): each pair is evaluated once by its owner, which calls
//!    the pure contact laws and adds the result to both particles (Newton's third law), together
//!    with the torques, the energy the pair lost and, with `[thermal]`, the heat it conducts. The
//!    pair's own history (bond state, tangential spring) lives in its slot.
//! 2. **Particle pass** (parallel over particles): gravity, wall contacts, boundary heat and the
//!    per-step checks, each particle writing only its own entries.
//!
//! The colouring keeps concurrent writes disjoint, so there are no atomics, locks or per-thread
//! copies, and every sum is formed in an order fixed by the list: the result is bitwise the same
//! for any thread count.

use glam::DVec3;
use rayon::prelude::*;

use crate::contact::tangential::TangentialSpring;
use crate::contact::{self, BondState, FrictionParams, PairKinematics, hertz, rolling, tangential};
use crate::model::Model;
use crate::neighbor::NeighborList;
use crate::pair_history::{HistoryTargets, TangentialHistories};
use crate::particles::{Particles, Rotation};
use crate::periodic::Periodic;
use crate::scatter::{self, PerParticle, PerSlot, Scatter, Window};
use crate::thermal::{self, ThermalModel};
use crate::wall_history::{Chunk, PARTICLES_PER_CHUNK};

/// `x_b − x_a` \[m\], as its minimum image across periodic axes (M.77).
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
        separation * (1.0 / distance)
    } else {
        DVec3::X
    }
}

/// What the force pass needs and fills for scenes with `[thermal]`: the first thermal substep's
/// heat balance (M.47), computed with the forces.
#[derive(Debug)]
pub struct PassHeat<'a> {
    /// Thermal parameters.
    pub model: &'a ThermalModel,
    /// Latched melting flags (the bond criterion reads them).
    pub melted: &'a [bool],
    /// Temperatures at the start of the step \[K\].
    pub temperature: &'a [f64],
    /// Absorbed laser power \[W\], with a `[laser]` (without one it is zero).
    pub laser_power: Option<&'a [f64]>,
    /// Heat capacities [J/K].
    pub heat_capacity: &'a [f64],
    /// Out: net heat flow \[W\].
    pub heat_flow: &'a mut [f64],
    /// Out: heat flow from walls, gas and surroundings \[W\].
    pub boundary_flow: &'a mut [f64],
    /// Out: total conductance G_i [W/K].
    pub total_conductance: &'a mut [f64],
}

/// What the force pass needs and fills for scenes with friction or rolling resistance.
#[derive(Debug)]
pub struct PassRotation<'a> {
    /// Angular velocities, torques and wall histories.
    pub rotation: &'a mut Rotation,
    /// The tangential histories of the pairs in contact.
    pub histories: &'a mut TangentialHistories,
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
    /// Total and elastic normal force \[N\], positive when repulsive.
    normal_force: f64,
    elastic_normal_force: f64,
    /// A bonded neck sticks: no Coulomb limit (docs/model.md section 27.5).
    bonded: bool,
}

/// What one contact's tangential and rolling laws give over one step.
#[derive(Debug, Clone, Copy)]
struct TangentialStep {
    /// Tangential force on the first body \[N\].
    force: DVec3,
    /// Rolling torque on the first body [N·m] (the second gets the opposite).
    rolling_torque: DVec3,
    /// The spring after the step.
    spring: TangentialSpring,
    /// Energy lost over the step \[J\] (M.63).
    lost: f64,
}

/// Tangential spring (M.57–M.59) and rolling resistance (M.61) of one contact over one step,
/// and the energy they took (M.63): `−F_t·v_t dt − ΔU_t + (−M_r·ω_rel) dt`.
#[inline(always)]
fn tangential_step(
    params: &FrictionParams,
    damping_ratio: f64,
    dt: f64,
    kinematics: &PairKinematics,
    contact: &TangentialContact,
    held: TangentialSpring,
) -> TangentialStep {
    let n = contact.normal;
    let v = contact.contact_velocity;
    let tangential_velocity = v - v.dot(n) * n;
    let (mut force, mut spring) = (DVec3::ZERO, TangentialSpring::default());
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
            tangential::rotate_history(held.history, n),
            tangential_velocity,
            dt,
            stiffness,
            damping,
            limit,
        );
        force = out.force;
        spring = TangentialSpring {
            history: out.history,
            spring_energy: tangential::spring_energy(stiffness, out.history),
        };
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
        - (spring.spring_energy - held.spring_energy)
        - dt * rolling_torque.dot(contact.relative_angular_velocity);
    TangentialStep {
        force,
        rolling_torque,
        spring,
        lost,
    }
}

/// The force pass (steps 4-5 of the step order): every particle's force, with rotation its
/// torque, with `[thermal]` its first-substep heat flows and total conductances; bond states
/// (`states`, per slot, given when the scene has a bond law) and tangential histories advance by
/// one step. Returns what the per-step guards need. `cleared`: the forces and torques are
/// already zero (the step's opening pass, `integrate::kick_drift`, leaves them so), and the
/// pass adds into them without zeroing them first.
pub fn compute(
    model: &Model,
    particles: &mut Particles,
    list: &NeighborList,
    states: Option<&mut [BondState]>,
    rotation: Option<PassRotation<'_>>,
    mut heat: Option<PassHeat<'_>>,
    cleared: bool,
) -> ForceSummary {
    let parallel = crate::worth_parallel(particles.len());
    let mut forces = std::mem::take(&mut particles.force);
    let mut dissipated = std::mem::take(&mut particles.dissipated);
    if !cleared {
        fill(&mut forces, DVec3::ZERO, parallel);
    }
    let (mut rotation, mut histories) = match rotation {
        Some(PassRotation {
            rotation,
            histories,
        }) => (Some(rotation), Some(histories)),
        None => (None, None),
    };
    if let Some(r) = rotation.as_mut().filter(|_| !cleared) {
        fill(&mut r.torque, DVec3::ZERO, parallel);
    }
    if let Some(h) = &mut heat {
        fill(h.heat_flow, 0.0, parallel);
        fill(h.total_conductance, 0.0, parallel);
    }
    let pairs = {
        let state = &*particles;
        let (omega, torque) = match rotation.as_mut() {
            Some(r) => (
                Some(r.angular_velocity.as_slice()),
                Some(Scatter::new(&mut r.torque)),
            ),
            None => (None, None),
        };
        let heat = heat.as_mut().map(|h| HeatTargets {
            model: h.model,
            melted: h.melted,
            temperature: h.temperature,
            heat_flow: Scatter::new(h.heat_flow),
            total_conductance: Scatter::new(h.total_conductance),
        });
        let targets = PairTargets {
            force: Scatter::new(&mut forces),
            lost: Scatter::new(&mut dissipated),
            states: states.map(Scatter::new),
            torque,
            tangential: histories.as_mut().map(|h| h.start_pass()),
            heat,
        };
        // One compiled pass per combination of the scene's optional pair physics: what a scene
        // does not have is not in its pass (no test per candidate, fewer live registers).
        let pass = match (
            targets.states.is_some(),
            targets.tangential.is_some(),
            targets.heat.is_some(),
        ) {
            (false, false, false) => pair_pass::<false, false, false>,
            (false, false, true) => pair_pass::<false, false, true>,
            (false, true, false) => pair_pass::<false, true, false>,
            (false, true, true) => pair_pass::<false, true, true>,
            (true, false, false) => pair_pass::<true, false, false>,
            (true, false, true) => pair_pass::<true, false, true>,
            (true, true, false) => pair_pass::<true, true, false>,
            (true, true, true) => pair_pass::<true, true, true>,
        };
        let summary = pass(model, state, list, omega, &targets, parallel);
        if let Some(h) = histories {
            h.finish_pass();
        }
        summary
    };
    particles.force = forces;
    particles.dissipated = dissipated;
    // As for the pair pass: one compiled particle pass per combination of optional physics.
    let own = match (rotation.is_some(), heat.is_some()) {
        (false, false) => particle_pass::<false, false>(model, particles, rotation, heat, parallel),
        (false, true) => particle_pass::<false, true>(model, particles, rotation, heat, parallel),
        (true, false) => particle_pass::<true, false>(model, particles, rotation, heat, parallel),
        (true, true) => particle_pass::<true, true>(model, particles, rotation, heat, parallel),
    };
    pairs.merge(own)
}

/// Sets every element to `value`.
fn fill<T: Copy + Send + Sync>(values: &mut [T], value: T, parallel: bool) {
    if parallel {
        values.par_iter_mut().for_each(|v| *v = value);
    } else {
        values.fill(value);
    }
}

/// What the pair pass writes, shared by the concurrent slabs of a colour phase.
struct PairTargets<'a> {
    force: Scatter<'a, DVec3, PerParticle>,
    lost: Scatter<'a, f64, PerParticle>,
    /// Per slot, with a bond law in the scene.
    states: Option<Scatter<'a, BondState, PerSlot>>,
    torque: Option<Scatter<'a, DVec3, PerParticle>>,
    tangential: Option<HistoryTargets<'a>>,
    heat: Option<HeatTargets<'a>>,
}

/// The thermal part of [`PairTargets`], with the inputs the conductances need.
struct HeatTargets<'a> {
    model: &'a ThermalModel,
    melted: &'a [bool],
    temperature: &'a [f64],
    heat_flow: Scatter<'a, f64, PerParticle>,
    total_conductance: Scatter<'a, f64, PerParticle>,
}

/// The pair pass over every owner, compiled for one combination of optional physics: bond
/// states (`BONDS`), tangential springs and torques (`FRICTION`), conduction (`HEAT`). A target
/// the combination leaves out is ignored even if present.
fn pair_pass<const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    particles: &Particles,
    list: &NeighborList,
    omega: Option<&[DVec3]>,
    targets: &PairTargets<'_>,
    parallel: bool,
) -> ForceSummary {
    list.for_each_owner(
        parallel,
        ForceSummary::default(),
        |summary, window| {
            owner_pairs::<BONDS, FRICTION, HEAT>(model, particles, omega, targets, summary, window);
        },
        ForceSummary::merge,
    )
}

/// The pairs of the window's owner: every contact law, added to both particles.
#[allow(clippy::too_many_lines)]
#[inline]
fn owner_pairs<const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    particles: &Particles,
    omega: Option<&[DVec3]>,
    targets: &PairTargets<'_>,
    summary: &mut ForceSummary,
    window: &Window<'_>,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    let histories = targets.tangential.as_ref().filter(|_| FRICTION);
    let torque = targets.torque.as_ref().filter(|_| FRICTION);
    let omega = omega.filter(|_| FRICTION);
    let friction_tables = model.friction.as_ref().filter(|_| FRICTION);
    let heat = targets.heat.as_ref().filter(|_| HEAT);
    let owner = window.owner();
    let a = owner.index();
    let periodic = model
        .periodic
        .as_ref()
        .filter(|_| window.needs_minimum_image());
    let (v_a, r_a, m_a) = (
        particles.velocity[a],
        particles.radius[a],
        particles.mass[a],
    );
    let material_a = particles.material[a];
    let (mut force_a, mut lost_a, mut torque_a) = (DVec3::ZERO, 0.0, DVec3::ZERO);
    let (mut heat_a, mut conductance_a) = (0.0, 0.0);
    for (p, partner) in window.pairs() {
        let b = partner.index();
        let separation = pair_separation(periodic, particles, a, b);
        let r_b = particles.radius[b];
        let reach = r_a + r_b;
        let distance_squared = separation.length_squared();
        if distance_squared >= reach * reach {
            // Most candidate pairs are apart: no square root, no division, and no write unless
            // the slot still holds something from an earlier contact.
            if let Some(states) = states {
                if states.read(p) != BondState::Unbonded {
                    states.update(p, |s| *s = BondState::Unbonded);
                }
            }
            if let Some(histories) = histories {
                // The spring vanishes with the contact (k_t → 0 as δ → 0): what it held is
                // lost, half to each particle.
                let held = histories.release(window, p);
                if held.spring_energy != 0.0 {
                    lost_a += 0.5 * held.spring_energy;
                    targets
                        .lost
                        .update(partner, |l| *l += 0.5 * held.spring_energy);
                }
            }
            continue;
        }
        debug_assert!(
            model
                .periodic
                .is_none_or(|p| p.minimum_image(separation) == separation),
            "a touching pair of owner {a} across a periodic face, which the list did not flag"
        );
        let distance = distance_squared.sqrt();
        let normal = unit_normal(separation, distance);
        let overlap = reach - distance;
        let m_b = particles.mass[b];
        let v_b = particles.velocity[b];
        let kinematics = PairKinematics {
            overlap,
            overlap_rate: (v_a - v_b).dot(normal),
            effective_radius: hertz::effective_radius(r_a, r_b),
            effective_mass: hertz::effective_mass(m_a, m_b),
        };
        summary.observe_overlap(overlap / r_a.min(r_b), if r_a <= r_b { a } else { b });
        let material_b = particles.material[b];
        let params = model.pair_params(material_a, material_b);
        let melted = heat.map_or((false, false), |h| (h.melted[a], h.melted[b]));
        let criterion = model.bond_criterion.holds(melted.0, melted.1);
        let state = states.map_or(BondState::Unbonded, |states| states.read(p));
        let outcome = contact::normal_force(params, &kinematics, state, criterion);
        // (M.35): damper work over the step, at the half-step velocity the force used.
        let mut lost = model.dt * (outcome.force - outcome.elastic) * kinematics.overlap_rate;
        if outcome.state != state {
            if let Some(bond) = &params.bond {
                // The stored energy jumps where eq. 25 switches branch at a given overlap.
                let e_star = params.effective_modulus;
                let r_star = kinematics.effective_radius;
                let hertz_energy = hertz::elastic_energy(e_star, r_star, overlap);
                let bond_energy = bond.elastic_energy(e_star, r_star, overlap);
                lost += match outcome.state {
                    BondState::Bonded => hertz_energy - bond_energy,
                    BondState::Unbonded => bond_energy - hertz_energy,
                };
            }
            if let Some(states) = states {
                states.update(p, |s| *s = outcome.state);
            }
        }
        let mut force_on_a = -outcome.force * normal;
        if let (Some(histories), Some(omega), Some(tables)) = (histories, omega, friction_tables) {
            // Lever arms to the middle of the overlap (M.60).
            let arm_a = r_a - 0.5 * overlap;
            let arm_b = r_b - 0.5 * overlap;
            let friction = tables.pair(material_a, material_b);
            let contact = TangentialContact {
                normal,
                contact_velocity: v_a - v_b + (arm_a * omega[a] + arm_b * omega[b]).cross(normal),
                relative_angular_velocity: omega[a] - omega[b],
                // Only the rolling law needs it: two divisions spared without μ_r.
                inverse_inertia_sum: if friction.rolling > 0.0 {
                    1.0 / rolling::sphere_inertia(m_a, r_a)
                        + 1.0 / rolling::sphere_inertia(m_b, r_b)
                } else {
                    0.0
                },
                normal_force: outcome.force,
                elastic_normal_force: outcome.elastic,
                bonded: outcome.state == BondState::Bonded,
            };
            let step = tangential_step(
                friction,
                params.damping_ratio,
                model.dt,
                &kinematics,
                &contact,
                histories.read(window, p),
            );
            histories.write(window, p, step.spring);
            force_on_a += step.force;
            lost += step.lost;
            let lever = normal.cross(step.force);
            torque_a += arm_a * lever + step.rolling_torque;
            if let Some(torque) = torque {
                torque.update(partner, |t| *t += arm_b * lever - step.rolling_torque);
            }
        }
        force_a += force_on_a;
        lost_a += 0.5 * lost;
        {
            targets.force.update(partner, |f| *f -= force_on_a);
            targets.lost.update(partner, |l| *l += 0.5 * lost);
        }
        if let Some(h) = heat {
            let conductance = thermal::pair_conductance(
                h.model,
                particles,
                a,
                b,
                overlap,
                kinematics.effective_radius,
            );
            let flow = conductance * (h.temperature[b] - h.temperature[a]);
            heat_a += flow;
            conductance_a += conductance;
            {
                h.heat_flow.update(partner, |q| *q -= flow);
                h.total_conductance.update(partner, |g| *g += conductance);
            }
        }
    }
    {
        targets.force.update(owner, |f| *f += force_a);
        targets.lost.update(owner, |l| *l += lost_a);
        if let Some(torque) = torque {
            torque.update(owner, |t| *t += torque_a);
        }
        if let Some(h) = heat {
            h.heat_flow.update(owner, |q| *q += heat_a);
            h.total_conductance.update(owner, |g| *g += conductance_a);
        }
    }
}

/// The particle pass: gravity, the wall contacts (normal, and with rotation tangential and
/// rolling), boundary heat and laser power, and the per-step checks. Each particle writes only
/// its own entries. Compiled for one combination of optional physics: rotation with the wall
/// springs (`ROTATION`) and conduction (`HEAT`); what it leaves out is ignored even if given.
#[allow(clippy::too_many_lines)]
fn particle_pass<const ROTATION: bool, const HEAT: bool>(
    model: &Model,
    particles: &mut Particles,
    rotation: Option<&mut Rotation>,
    heat: Option<PassHeat<'_>>,
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
        heat_flow: Scatter::new(h.heat_flow),
        boundary_flow: Scatter::new(h.boundary_flow),
        total_conductance: Scatter::new(h.total_conductance),
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
        let mut max_overlap: f64 = 0.0;
        let mut force = state.mass[k] * model.gravity;
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
                let step = tangential_step(
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
        let mut total = DVec3::ZERO;
        force_out.update(particle, |f| {
            *f += force;
            total = *f;
        });
        lost_out.update(particle, |l| *l += lost);
        if let Some(t) = torque {
            t.update(particle, |t| *t += torque_k);
        }
        let heat_rate = heat.map_or(0.0, |h| {
            let mut added = None;
            if h.exchange {
                let (outside, outside_conductance) =
                    thermal::boundary_heat(h.model, &model.walls, state, k, h.temperature[k]);
                h.boundary_flow.update(particle, |b| *b = outside);
                h.total_conductance
                    .update(particle, |g| *g += outside_conductance);
                added = Some(outside);
            }
            if let Some(laser_power) = h.laser_power {
                added = Some(added.unwrap_or(0.0) + laser_power[k]);
            }
            if let Some(added) = added {
                h.heat_flow.update(particle, |q| *q += added);
            }
            h.total_conductance.read(particle) / h.heat_capacity[k]
        });
        summary.max_heat_rate = summary.max_heat_rate.max(heat_rate);
        // The chunk's particles come in ascending order: the first is the lowest.
        if !total.is_finite() && summary.non_finite_force.is_none() {
            summary.non_finite_force = Some(k);
        }
        summary.observe_overlap(max_overlap / state.radius[k], k);
    };
    let summary = scatter::for_each_particle(
        count,
        PARTICLES_PER_CHUNK,
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
    heat_flow: Scatter<'a, f64, PerParticle>,
    boundary_flow: Scatter<'a, f64, PerParticle>,
    total_conductance: Scatter<'a, f64, PerParticle>,
}

/// Overlap of particle `k` with wall `w` \[m\] (positive in contact) and the wall's normal.
#[inline]
#[must_use]
pub fn wall_overlap(model: &Model, particles: &Particles, k: usize, w: usize) -> f64 {
    let wall = &model.walls[w];
    particles.radius[k] - (particles.position[k] - wall.point).dot(wall.normal)
}

/// What the force pass saw, reduced in a thread-count-independent way (max, and the lowest
/// index on ties): the inputs of the run's per-step guards (docs/stability.md).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceSummary {
    /// `max G_i / C_i` [1/s] with `[thermal]`, 0 otherwise (M.49).
    pub max_heat_rate: f64,
    /// Largest overlap of any contact relative to the smaller radius of its pair (the
    /// particle's radius, against a wall).
    pub max_overlap_ratio: f64,
    /// The particle (index) with that smaller radius.
    pub max_overlap_particle: usize,
    /// The lowest particle index whose total force is NaN or infinite.
    pub non_finite_force: Option<usize>,
}

impl ForceSummary {
    /// Takes in one contact's overlap ratio, seen at particle `k`.
    #[inline]
    fn observe_overlap(&mut self, ratio: f64, k: usize) {
        if ratio > self.max_overlap_ratio
            || (ratio == self.max_overlap_ratio && k < self.max_overlap_particle)
        {
            self.max_overlap_ratio = ratio;
            self.max_overlap_particle = k;
        }
    }

    /// Combines two partial summaries; associative and commutative, so any reduction tree gives
    /// the same result.
    #[must_use]
    fn merge(mut self, other: Self) -> Self {
        self.observe_overlap(other.max_overlap_ratio, other.max_overlap_particle);
        self.max_heat_rate = self.max_heat_rate.max(other.max_heat_rate);
        self.non_finite_force = match (self.non_finite_force, other.non_finite_force) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self
    }
}
