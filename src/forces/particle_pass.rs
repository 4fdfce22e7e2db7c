//! The particle pass: what each particle adds on its own after the pair pass (gravity is set by
//! the drift): its wall contacts (normal, and with rotation tangential and rolling), with
//! `[thermal]` its boundary heat and laser power, and the wall overlaps for the run's guard.
//! Parallel over chunks of particles, each particle writing only its own entries. A chunk's wall
//! contacts fill lanes of 16, whose laws run vectorised ([`super::wall_lanes`]), and a round's
//! write-back replays each particle's walls in order ([`WallRound`]). Its boundary heat fills
//! lanes of its own ([`crate::thermal::BoundaryLanes`], [`HeatRound`]).

use glam::DVec3;

use super::lanes::LANES;
use super::wall_lanes::{self, WallInput, WallLanes};
use super::{ForceSummary, PassHeat, wall_overlap};
use crate::model::Model;
use crate::particles::{Particles, Rotation};
use crate::scatter::{self, Member, ParticleChunk, PerParticle, Scatter};
use crate::simd::InstructionSet;
use crate::thermal::{BoundaryLanes, HeatSums, ThermalModel};
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
    interval: f64,
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
    let outputs = Outputs {
        force: force_out,
        lost: lost_out,
        torque: torque.filter(|_| ROTATION),
    };
    let set = InstructionSet::detect();
    // Known at compile time to be `None` where the instantiation leaves rotation out.
    let friction = model.friction.as_ref().filter(|_| ROTATION);
    assert!(
        !ROTATION || friction.is_some(),
        "a scene with rotation has friction tables (`Model::build`)"
    );
    let visit = |summary: &mut ForceSummary,
                 springs: &mut Option<&mut Chunk>,
                 chunk: &ParticleChunk<'_>| {
        let mut springs = springs.as_deref_mut().filter(|_| ROTATION);
        let heat = heat.as_ref().filter(|_| HEAT);
        let mut round = WallRound::new();
        let mut heat_round = heat.map(|h| HeatRound::new(h, &model.walls));
        for window in chunk.windows() {
            let particle = window.owner();
            let k = particle.index();
            // Most particles touch no wall and hold no wall spring: their walls give nothing.
            // (The wall path below would add zeros to their force, lost energy and torque, which
            // changes no bit of a finite sum, and observe a zero overlap.)
            if (0..model.walls.len()).any(|w| wall_overlap(model, state, k, w) > 0.0)
                || springs
                    .as_deref_mut()
                    .is_some_and(|chunk| chunk.holds_any(k))
            {
                let mut max_overlap: f64 = 0.0;
                for w in 0..model.walls.len() {
                    let overlap = wall_overlap(model, state, k, w);
                    if overlap <= 0.0 {
                        // The spring vanishes with the contact: what it held is lost.
                        if let Some(chunk) = springs.as_deref_mut() {
                            round.release(chunk.take(k, w).spring_energy);
                        }
                        continue;
                    }
                    max_overlap = max_overlap.max(overlap);
                    let params = model.wall_params(w, state.material[k]);
                    let (angular_velocity, friction, held) =
                        match (friction, springs.as_deref_mut()) {
                            (Some(tables), Some(chunk)) => (
                                omega.map_or(DVec3::ZERO, |omega| omega[k]),
                                *tables.wall(w, state.material[k]),
                                chunk.take(k, w),
                            ),
                            _ => Default::default(),
                        };
                    let input = WallInput {
                        overlap,
                        into_domain: model.walls[w].normal,
                        radius: state.radius[k],
                        mass: state.mass[k],
                        velocity: state.velocity[k],
                        effective_modulus: params.effective_modulus,
                        damping_ratio: params.damping_ratio,
                        angular_velocity,
                        friction,
                        held,
                    };
                    if round.contact::<ROTATION>(particle, w, &input) {
                        round.write_back::<ROTATION>(
                            model,
                            (set, interval),
                            &outputs,
                            springs.as_deref_mut(),
                        );
                    }
                }
                round.end_particle(particle);
                if round.filled == 0 {
                    // Nothing waits on the kernel (the particle's last contact filled the lanes,
                    // or its springs all let go): its events are written now, so that they do
                    // not pile up over the chunk.
                    round.write_back::<ROTATION>(
                        model,
                        (set, interval),
                        &outputs,
                        springs.as_deref_mut(),
                    );
                }
                summary.observe_overlap(max_overlap / state.radius[k], k);
            }
            if let Some((h, heat_round)) = heat.zip(heat_round.as_mut()) {
                heat_round.add(h, state, set, particle, summary);
            }
        }
        round.write_back::<ROTATION>(model, (set, interval), &outputs, springs);
        if let Some((h, heat_round)) = heat.zip(heat_round.as_mut()) {
            heat_round.finish(h, set, summary);
        }
    };
    let summary = scatter::for_each_chunk(
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

/// The heat of a chunk's particles on its way through the boundary kernel: with exchange, the
/// particles in its lanes; each is finished (its boundary flow, laser power and largest
/// `G_i / C_i`) once its lane has run. Without exchange each is finished at once.
struct HeatRound<'c> {
    /// `None` without exchange.
    lanes: Option<BoundaryLanes>,
    particles: Vec<Member<'c>>,
}

impl<'c> HeatRound<'c> {
    fn new(heat: &ParticleHeat<'_>, walls: &[crate::model::Wall]) -> Self {
        Self {
            lanes: heat.exchange.then(|| BoundaryLanes::new(heat.model, walls)),
            particles: Vec::with_capacity(LANES),
        }
    }

    /// `particle`'s walls are done: its heat is added now, or when its lane has run.
    #[inline(always)]
    fn add(
        &mut self,
        heat: &ParticleHeat<'_>,
        state: &Particles,
        set: InstructionSet,
        particle: Member<'c>,
        summary: &mut ForceSummary,
    ) {
        let k = particle.index();
        match &mut self.lanes {
            Some(lanes) => {
                lanes.set(
                    self.particles.len(),
                    heat.model,
                    state,
                    k,
                    heat.temperature[k],
                );
                self.particles.push(particle);
                if self.particles.len() == LANES {
                    self.finish(heat, set, summary);
                }
            }
            None => finish_particle(heat, particle, None, summary),
        }
    }

    /// Runs the boundary kernel over the filled lanes and finishes their particles.
    fn finish(&mut self, heat: &ParticleHeat<'_>, set: InstructionSet, summary: &mut ForceSummary) {
        let Some(lanes) = self.lanes.as_mut().filter(|_| !self.particles.is_empty()) else {
            return;
        };
        lanes.run(set, heat.model);
        for (i, particle) in self.particles.drain(..).enumerate() {
            finish_particle(heat, particle, Some(lanes.output(i)), summary);
        }
    }
}

/// Adds `particle`'s exchange with its boundaries (`outside`: flow \[W\] and conductance
/// [W/K]) and its laser power to its heat sums, and takes in its `G_i / C_i`.
#[inline(always)]
fn finish_particle(
    heat: &ParticleHeat<'_>,
    particle: Member<'_>,
    outside: Option<(f64, f64)>,
    summary: &mut ForceSummary,
) {
    let k = particle.index();
    let mut sums = heat.sums.read(particle);
    if let Some((_, outside_conductance)) = outside {
        sums.conductance += outside_conductance;
    }
    let added = match (outside, heat.laser_power) {
        (Some((outside, _)), Some(laser_power)) => Some(outside + laser_power[k]),
        (Some((outside, _)), None) => Some(outside),
        // (As ever: `0.0 +` turns a power of −0 into +0.)
        (None, Some(laser_power)) => Some(0.0 + laser_power[k]),
        (None, None) => None,
    };
    if let Some(added) = added {
        sums.flow += added;
    }
    heat.sums.update(particle, |_| sums);
    if let Some((outside, _)) = outside {
        heat.boundary_flow.update(particle, |_| outside);
    }
    let heat_rate = sums.conductance / heat.heat_capacity[k];
    summary.max_heat_rate = summary.max_heat_rate.max(heat_rate);
}

/// The per-particle arrays the wall contacts add into.
struct Outputs<'a> {
    force: Scatter<'a, DVec3, PerParticle>,
    lost: Scatter<'a, f64, PerParticle>,
    torque: Option<Scatter<'a, DVec3, PerParticle>>,
}

/// What happened at one wall of one particle, in the order of the particles and their walls:
/// what [`WallRound::write_back`] replays, so that every particle's sums are formed in that order.
#[derive(Debug, Clone, Copy)]
enum WallEvent<'c> {
    /// A contact, whose laws run in the next lane of the round.
    Contact { particle: Member<'c>, wall: usize },
    /// A wall spring of a contact that ended, holding `energy` \[J\]: lost.
    Released { energy: f64 },
    /// The particle's walls are done: its sums are written.
    End { particle: Member<'c> },
}

/// The wall contacts of a chunk's particles on their way through the wall kernel: the lanes
/// being filled, the events since the last write-back, and the sums of the particle being
/// written back (a particle's contacts may straddle two rounds).
struct WallRound<'c> {
    lanes: WallLanes,
    filled: usize,
    events: Vec<WallEvent<'c>>,
    /// Force \[N\], torque [N·m] and lost energy \[J\] of the particle's walls written back so
    /// far, for its [`WallEvent::End`].
    sums: (DVec3, DVec3, f64),
}

impl<'c> WallRound<'c> {
    /// An empty round.
    fn new() -> Self {
        Self {
            lanes: WallLanes::default(),
            filled: 0,
            events: Vec::with_capacity(2 * LANES),
            sums: (DVec3::ZERO, DVec3::ZERO, 0.0),
        }
    }

    /// A wall spring that held `energy` \[J\] is lost.
    fn release(&mut self, energy: f64) {
        self.events.push(WallEvent::Released { energy });
    }

    /// `particle` touches wall `wall`: its laws go into the next lane. Returns whether the
    /// lanes are full, to be written back before the next contact.
    fn contact<const FRICTION: bool>(
        &mut self,
        particle: Member<'c>,
        wall: usize,
        input: &WallInput,
    ) -> bool {
        self.lanes.set::<FRICTION>(self.filled, input);
        self.filled += 1;
        self.events.push(WallEvent::Contact { particle, wall });
        self.filled == LANES
    }

    /// `particle`'s walls are done.
    fn end_particle(&mut self, particle: Member<'c>) {
        self.events.push(WallEvent::End { particle });
    }

    /// Runs the laws of the filled lanes and writes back every event in order: each particle's
    /// force, lost energy and torque summed over its walls and added once, its springs kept.
    fn write_back<const FRICTION: bool>(
        &mut self,
        model: &Model,
        (set, interval): (InstructionSet, f64),
        outputs: &Outputs<'_>,
        mut springs: Option<&mut Chunk>,
    ) {
        if self.filled > 0 {
            wall_lanes::run::<FRICTION>(set, interval, &mut self.lanes);
        }
        let (mut force, mut torque, mut lost) = self.sums;
        let mut lane = 0;
        for event in self.events.drain(..) {
            match event {
                WallEvent::Released { energy } => lost += energy,
                WallEvent::Contact { particle, wall } => {
                    let out = self.lanes.output::<FRICTION>(lane);
                    lane += 1;
                    force += out.normal_force * model.walls[wall].normal;
                    lost += out.damper_lost;
                    if let Some(chunk) = springs.as_deref_mut().filter(|_| FRICTION) {
                        force += out.tangential_force;
                        torque += out.torque;
                        lost += out.tangential_lost;
                        chunk.keep(particle.index(), wall, out.spring);
                    }
                }
                WallEvent::End { particle } => {
                    outputs.force.update(particle, |f| f + force);
                    outputs.lost.update(particle, |l| l + lost);
                    if let Some(t) = &outputs.torque {
                        t.update(particle, |t| t + torque);
                    }
                    (force, torque, lost) = (DVec3::ZERO, DVec3::ZERO, 0.0);
                }
            }
        }
        debug_assert_eq!(lane, self.filled, "every lane filled is written back");
        self.filled = 0;
        self.sums = (force, torque, lost);
    }
}
