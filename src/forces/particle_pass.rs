//! The particle pass: what each particle adds on its own after the pair pass (gravity is set by
//! the drift): its wall contacts (normal, and with rotation tangential and rolling), with
//! `[thermal]` its boundary heat and laser power, and the wall overlaps for the run's guard;
//! then it tests each chunk's finished forces for NaN and infinities (the guard's other input,
//! [`ForceSummary::first_non_finite_force`]). Parallel over chunks of particles, each particle
//! writing only its own entries, through accessors opened once per chunk. A chunk's wall
//! contacts fill lanes of 16, whose laws run vectorised ([`super::wall_lanes`]); each lane names
//! its particle and wall, a particle's walls fill consecutive lanes, and the write-back sums
//! them in wall order ([`WallRound`]). A
//! particle whose wall spring lets go (it left a wall) takes its walls one after the other
//! instead, so that the energy the spring held is summed in the same order. Its boundary heat
//! fills lanes of its own ([`crate::thermal::BoundaryLanes`], [`HeatRound`]).

use glam::DVec3;

use super::lanes::LANES;
use super::wall_lanes::{self, WallInput, WallLanes, WallOutput, wall_friction};
use super::{ForceSummary, ParticleReads, PassHeat, plane_overlap};
use crate::contact::tangential::TangentialSpring;
use crate::model::{Model, Wall};
use crate::particles::{Particles, Rotation};
use crate::scatter::{self, Member, Opened, ParticleChunk, PerParticle, Scatter};
use crate::simd::InstructionSet;
use crate::thermal::{BoundaryLanes, HeatSums, ThermalModel};
use crate::wall_history::{Chunk, PARTICLES_PER_CHUNK};

/// The particle pass: the wall contacts (normal, and with rotation tangential and rolling),
/// boundary heat and laser power, and the wall overlaps for the guard, over every particle or
/// the `listed` ones (ascending; they must include every particle that touches a wall or holds a
/// wall spring); then the finished forces of every particle, listed or not, tested for NaN and
/// infinities. Each particle writes only its own entries. Compiled for one combination of
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
    let _pass = crate::team::PassName::enter("particle pass (walls)");
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
    // The listed particles (those near a wall) lie spread over the arrays.
    let prefetch = listed.is_some() && super::worth_prefetching(count);
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
        let reads = ParticleReads::open(state, omega.filter(|_| ROTATION), chunk);
        let outputs = outputs.open(chunk);
        let mut round = WallRound::new(model);
        // A listed pass (heat without laser or exchange, `forces::compute`) has no heat to add
        // to a particle: its largest G_i / C_i is taken over the chunk's whole range below.
        // (Reading each listed particle's sums here as well, spread over the arrays, held 28 %
        // of this pass's samples on the heated 97.2k bed: docs/performance.md, fifty-second
        // round.)
        let mut heat_round = heat
            .filter(|_| listed.is_none())
            .map(|h| HeatRound::new(h, &model.walls));
        // The chunk's listed particles lie spread over the arrays: each particle's lines are
        // asked for `LISTED_AHEAD` particles before it is reached.
        let mut ahead = chunk.windows().take(if prefetch { usize::MAX } else { 0 });
        for window in ahead.by_ref().take(LISTED_AHEAD) {
            prefetch_particle(reads, &outputs, window.owner());
        }
        for window in chunk.windows() {
            if let Some(next) = ahead.next() {
                prefetch_particle(reads, &outputs, next.owner());
            }
            let particle = window.owner();
            let k = particle.index();
            let (position, radius) = (reads.position.get(particle), reads.radius.get(particle));
            let overlap_with = |wall: &Wall| plane_overlap(wall, position, radius);
            // Most particles touch no wall and hold no wall spring: their walls give nothing.
            // (The wall path below would add zeros to their force, lost energy and torque, which
            // changes no bit of a finite sum, and observe a zero overlap.)
            let touching = model
                .walls
                .iter()
                .filter(|wall| overlap_with(wall) > 0.0)
                .count();
            let holds = springs
                .as_deref_mut()
                .is_some_and(|chunk| chunk.holds_any(k));
            if touching > 0 || holds {
                let material = reads.material.get(particle);
                let motion = (
                    [radius, reads.mass.get(particle)],
                    [
                        reads.velocity.get(particle),
                        reads
                            .angular_velocity
                            .map_or(DVec3::ZERO, |omega| omega.get(particle)),
                    ],
                );
                let lets_go = holds
                    && touching < model.walls.len()
                    && springs.as_deref().is_some_and(|chunk| {
                        chunk.holds_any_where(k, |w| overlap_with(&model.walls[w]) <= 0.0)
                    });
                let max_overlap = if lets_go {
                    // A wall spring lets go (rare: a particle leaving a wall): the lanes' order
                    // of the sums would not hold the energy it releases, so this particle's walls
                    // are taken one after the other, after what the lanes hold is written.
                    round.write_back::<ROTATION>(
                        model,
                        (set, interval),
                        &outputs,
                        springs.as_deref_mut(),
                    );
                    round.finish(&outputs);
                    let mut sums = WallSums::default();
                    let mut max_overlap: f64 = 0.0;
                    for (w, wall) in model.walls.iter().enumerate() {
                        let overlap = overlap_with(wall);
                        let held = springs
                            .as_deref_mut()
                            .map_or_else(TangentialSpring::default, |chunk| chunk.take(k, w));
                        if overlap <= 0.0 {
                            // The spring vanishes with the contact: what it held is lost.
                            sums.lost += held.spring_energy;
                            continue;
                        }
                        max_overlap = max_overlap.max(overlap);
                        let input = wall_input(model, (w, material), overlap, motion, held);
                        let out = if ROTATION && input.friction.rolling != 0.0 {
                            wall_lanes::wall_step::<ROTATION, true>(interval, &input)
                        } else {
                            wall_lanes::wall_step::<ROTATION, false>(interval, &input)
                        };
                        sums.add::<ROTATION>(&out, wall.normal);
                        if let Some(chunk) = springs.as_deref_mut() {
                            chunk.keep(k, w, out.spring);
                        }
                    }
                    sums.write(&outputs, particle);
                    max_overlap
                } else {
                    // No spring lets go: every wall with a spring touches, and the others hold
                    // none to take.
                    let mut max_overlap: f64 = 0.0;
                    for (w, wall) in model.walls.iter().enumerate() {
                        let overlap = overlap_with(wall);
                        if overlap <= 0.0 {
                            continue;
                        }
                        // (`f64::max` without its NaN select: a NaN overlap fails both tests.)
                        if overlap > max_overlap {
                            max_overlap = overlap;
                        }
                        let held = springs
                            .as_deref_mut()
                            .map_or_else(TangentialSpring::default, |chunk| chunk.take(k, w));
                        if round.contact::<ROTATION>(
                            model,
                            (particle, material),
                            w,
                            (overlap, motion, held),
                        ) {
                            round.write_back::<ROTATION>(
                                model,
                                (set, interval),
                                &outputs,
                                springs.as_deref_mut(),
                            );
                        }
                    }
                    max_overlap
                };
                summary.observe_overlap_of(max_overlap, radius, k);
            }
            if let Some((h, heat_round)) = heat.zip(heat_round.as_mut()) {
                heat_round.add(h, state, set, particle);
            }
        }
        round.write_back::<ROTATION>(model, (set, interval), &outputs, springs);
        round.finish(&outputs);
        if let Some((h, heat_round)) = heat.zip(heat_round.as_mut()) {
            heat_round.finish(h, set);
        }
        // With heat, the largest G_i / C_i (M.49) of the chunk's range, from the sums as they
        // now stand: the pair pass's, and the boundary exchange's where the pass visits every
        // particle. One vector kernel over the chunk, whichever particles were visited.
        if let Some(h) = heat {
            let rate = h.sums.open_chunk(chunk).inspect_chunk_beside(
                chunk,
                h.heat_capacity,
                crate::thermal::max_heat_rate,
            );
            summary.max_heat_rate = summary.max_heat_rate.max(rate);
        }
        // The chunk's forces are finished (the walls were the last to add): every particle of
        // its range is tested, listed or not, while the chunk is at hand.
        let found = outputs.force.inspect_chunk(
            chunk,
            |forces, first| crate::integrate::first_non_finite_of(first, forces),
            chunk.range().start,
        );
        summary.first_non_finite_force =
            crate::integrate::lowest_particle(summary.first_non_finite_force, found);
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

/// How many listed particles ahead the particle pass asks for a particle's lines, where it
/// prefetches: on the 97.2k LIGGGHTS bed at 1 thread, 8 ahead made the step 1.02-1.04 times
/// faster than asking for all of a chunk's listed particles at once (two sets of 6 pairs of runs
/// at once, `benches/paired.sh`), 16 no faster than 8 and 4 no faster either
/// (docs/performance.md, forty-eighth round).
const LISTED_AHEAD: usize = 8;

/// Asks the cache for the lines of `particle`'s position, radius, velocity and force, and
/// with rotation its spin and torque: what its wall contacts read and write. The listed
/// particles (those near a wall) are spread over the arrays: on a bed larger than the cache
/// each one's lines were otherwise missed one after the other (docs/performance.md,
/// thirty-fourth round).
#[inline(always)]
fn prefetch_particle<'v>(
    reads: ParticleReads<'_, 'v>,
    outputs: &OpenOutputs<'_, 'v>,
    particle: Member<'v>,
) {
    reads.position.prefetch(particle);
    reads.radius.prefetch(particle);
    reads.velocity.prefetch(particle);
    outputs.force.prefetch(particle);
    if let Some(omega) = reads.angular_velocity {
        omega.prefetch(particle);
    }
    if let Some(torque) = &outputs.torque {
        torque.prefetch(particle);
    }
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
/// particles in its lanes; each is finished (its boundary flow and laser power) once its lane
/// has run. Without exchange each is finished at once.
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
                    self.finish(heat, set);
                }
            }
            None => finish_particle(heat, particle, None),
        }
    }

    /// Runs the boundary kernel over the filled lanes and finishes their particles.
    fn finish(&mut self, heat: &ParticleHeat<'_>, set: InstructionSet) {
        let Some(lanes) = self.lanes.as_mut().filter(|_| !self.particles.is_empty()) else {
            return;
        };
        lanes.run(set, heat.model);
        for (i, particle) in self.particles.drain(..).enumerate() {
            finish_particle(heat, particle, Some(lanes.output(i)));
        }
    }
}

/// Adds `particle`'s exchange with its boundaries (`outside`: flow \[W\] and conductance
/// [W/K]) and its laser power to its heat sums (whose `G_i / C_i` the chunk's end takes).
#[inline(always)]
fn finish_particle(heat: &ParticleHeat<'_>, particle: Member<'_>, outside: Option<(f64, f64)>) {
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
}

/// A particle's `[radius (m), mass (kg)]` and `[velocity (m/s), angular velocity (rad/s)]`
/// (zero without rotation), as its wall contacts take them.
type Motion = ([f64; 2], [DVec3; 2]);

/// The laws' input for a particle of `material` touching `wall` with `overlap` \[m\], its
/// `motion` and the spring `held` the last pass left.
#[inline(always)]
fn wall_input(
    model: &Model,
    (wall, material): (usize, u16),
    overlap: f64,
    ([radius, mass], [velocity, angular_velocity]): Motion,
    held: TangentialSpring,
) -> WallInput {
    let params = model.wall_params(wall, material);
    WallInput {
        overlap,
        into_domain: model.walls[wall].normal,
        radius,
        mass,
        velocity,
        effective_modulus: params.effective_modulus,
        damping_ratio: params.damping_ratio,
        angular_velocity,
        friction: wall_friction(model, wall, material),
        held,
    }
}

/// The per-particle arrays the wall contacts add into.
struct Outputs<'a> {
    force: Scatter<'a, DVec3, PerParticle>,
    lost: Scatter<'a, f64, PerParticle>,
    torque: Option<Scatter<'a, DVec3, PerParticle>>,
}

impl Outputs<'_> {
    /// The outputs for the particles of `chunk` alone, without a bounds check per access.
    fn open<'s, 'v>(&'s self, chunk: &ParticleChunk<'v>) -> OpenOutputs<'s, 'v> {
        OpenOutputs {
            force: self.force.open_chunk(chunk),
            lost: self.lost.open_chunk(chunk),
            torque: self.torque.as_ref().map(|t| t.open_chunk(chunk)),
        }
    }
}

/// [`Outputs`] opened for one chunk ([`Scatter::open_chunk`]).
struct OpenOutputs<'s, 'v> {
    force: Opened<'s, 'v, DVec3, PerParticle>,
    lost: Opened<'s, 'v, f64, PerParticle>,
    torque: Option<Opened<'s, 'v, DVec3, PerParticle>>,
}

/// One particle's wall contacts summed in the order of its walls: force \[N\], torque [N·m]
/// and lost energy \[J\].
#[derive(Debug, Clone, Copy, Default)]
struct WallSums {
    force: DVec3,
    torque: DVec3,
    lost: f64,
}

impl WallSums {
    /// Adds what the laws gave one contact with the wall of unit normal `normal`.
    #[inline(always)]
    fn add<const FRICTION: bool>(&mut self, out: &WallOutput, normal: DVec3) {
        self.force += out.normal_force * normal;
        self.lost += out.damper_lost;
        if FRICTION {
            self.force += out.tangential_force;
            self.torque += out.torque;
            self.lost += out.tangential_lost;
        }
    }

    /// Adds the sums to `particle`'s force, lost energy and torque.
    #[inline(always)]
    fn write<'v>(&self, outputs: &OpenOutputs<'_, 'v>, particle: Member<'v>) {
        outputs.force.update(particle, |f| f + self.force);
        outputs.lost.update(particle, |l| l + self.lost);
        if let Some(t) = &outputs.torque {
            t.update(particle, |t| t + self.torque);
        }
    }
}

/// The wall contacts of a chunk's particles on their way through the wall kernel: the lanes
/// being filled with the particle and wall of each, and the sums of the particle being written
/// back (a particle's contacts may straddle two rounds). A particle's contacts fill consecutive
/// lanes in the order of its walls, so its sums are complete when a lane of the next particle
/// comes, or the chunk ends.
struct WallRound<'c> {
    lanes: WallLanes,
    filled: usize,
    /// The particle and wall of each filled lane.
    particles: Vec<Member<'c>>,
    walls: [usize; LANES],
    /// The particle whose sums are being formed, and its sums so far.
    open: Option<(Member<'c>, WallSums)>,
}

impl<'c> WallRound<'c> {
    /// An empty round for the wall contacts of `model`.
    fn new(model: &Model) -> Self {
        Self {
            lanes: WallLanes::for_model(model),
            filled: 0,
            particles: Vec::with_capacity(LANES),
            walls: [0; LANES],
            open: None,
        }
    }

    /// `particle` (of `material`) touches wall `wall` with `(overlap, motion, held)` (as
    /// [`wall_input`] takes them): its laws go into the next lane. Returns whether the lanes
    /// are full, to be written back before the next contact.
    #[inline(always)]
    fn contact<const FRICTION: bool>(
        &mut self,
        model: &Model,
        (particle, material): (Member<'c>, u16),
        wall: usize,
        (overlap, (size, motion), held): (f64, Motion, TangentialSpring),
    ) -> bool {
        let lane = self.filled;
        // With one wall and one material the lanes hold its normal and parameters already.
        if !self.lanes.uniform_wall() {
            self.lanes
                .set_model_wall::<FRICTION>(lane, model, wall, material);
        }
        self.lanes
            .set_motion::<FRICTION>(lane, overlap, size, motion, held);
        self.walls[lane] = wall;
        self.particles.push(particle);
        self.filled += 1;
        self.filled == LANES
    }

    /// Runs the laws of the filled lanes and writes them back in order: each particle's force,
    /// lost energy and torque summed over its walls and added once, its springs kept. The last
    /// particle's sums stay open ([`Self::finish`]).
    fn write_back<const FRICTION: bool>(
        &mut self,
        model: &Model,
        (set, interval): (InstructionSet, f64),
        outputs: &OpenOutputs<'_, 'c>,
        mut springs: Option<&mut Chunk>,
    ) {
        if self.filled == 0 {
            return;
        }
        wall_lanes::run::<FRICTION>(set, interval, &mut self.lanes);
        // Held in locals for the loop (in the round, they were copied through memory at every
        // change of particle).
        let (mut open, mut sums) = match self.open {
            Some((particle, sums)) => (Some(particle), sums),
            None => (None, WallSums::default()),
        };
        for (lane, &particle) in self.particles.iter().enumerate() {
            if open.is_none_or(|open| open.index() != particle.index()) {
                if let Some(done) = open {
                    sums.write(outputs, done);
                }
                open = Some(particle);
                sums = WallSums::default();
            }
            let wall = self.walls[lane];
            let out = self.lanes.output::<FRICTION>(lane);
            sums.add::<FRICTION>(&out, model.walls[wall].normal);
            if let Some(chunk) = springs.as_deref_mut().filter(|_| FRICTION) {
                chunk.keep(particle.index(), wall, out.spring);
            }
        }
        self.open = open.map(|particle| (particle, sums));
        self.particles.clear();
        self.filled = 0;
    }

    /// Writes the open particle's sums (after the last [`Self::write_back`] of its lanes).
    fn finish(&mut self, outputs: &OpenOutputs<'_, 'c>) {
        debug_assert_eq!(self.filled, 0, "every lane written back");
        if let Some((particle, sums)) = self.open.take() {
            sums.write(outputs, particle);
        }
    }
}
