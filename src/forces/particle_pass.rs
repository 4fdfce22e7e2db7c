//! The particle pass: what each particle adds on its own after the pair pass (gravity is set by
//! the drift): its wall contacts (normal, and with rotation tangential and rolling), with
//! `[thermal]` its boundary heat and laser power, and the wall overlaps for the run's guard;
//! then it tests each chunk's finished forces for NaN and infinities (the guard's other input,
//! [`ForceSummary::first_non_finite_force`]). Parallel over chunks of particles, each particle
//! writing only its own entries, through accessors opened once per chunk.
//!
//! The wall contacts come from the wall candidates (`WallCandidates`: the (particle, wall)
//! pairs that may touch before the next rebuild), whose springs the store keeps by candidate
//! ([`crate::wall_history`]). A chunk's candidates fill lanes of 16 one after the other, each
//! lane with its pair's overlap, motion and spring; a lane is kept for the kernel if its pair
//! touches or holds a spring, and the next candidate's overwrites it otherwise, so the fill has
//! no branch per candidate. The laws run vectorised ([`super::wall_lanes`]); the write-back
//! sums each particle's lanes in wall order ([`WallRound`]), and a lane whose pair is apart
//! (its spring lets go) adds the spring's energy to the lost energy in its place in that order.
//! The boundary heat fills lanes of its own ([`crate::thermal::BoundaryLanes`], [`HeatRound`]).

use glam::DVec3;

use super::lanes::LANES;
use super::wall_lanes::{self, WallLanes, WallOutput};
use super::{ForceSummary, ParticleReads, PassHeat, WallCandidates, plane_overlap};
use crate::contact::tangential::TangentialSpring;
use crate::model::Model;
use crate::particles::{Particles, Rotation};
use crate::scatter::{self, Member, Opened, ParticleChunk, PerParticle, Scatter};
use crate::simd::InstructionSet;
use crate::team::PARTICLES_PER_ITEM;
use crate::thermal::{BoundaryLanes, MaterialReads, ThermalModel};
use crate::wall_history::WallKey;

/// The particle pass: the wall contacts of the wall candidates `walls.0` (normal, and with
/// rotation tangential and rolling), boundary heat and laser power of every particle if
/// `walls.1` (else none), and the wall overlaps for the guard; then the finished forces of every
/// particle tested for NaN and infinities. Each particle writes only its own entries. Compiled
/// for one combination of optional physics: rotation with the wall springs (`ROTATION`) and
/// conduction (`HEAT`); what it leaves out is ignored even if given.
#[allow(clippy::too_many_lines)]
pub(super) fn run<const ROTATION: bool, const HEAT: bool>(
    model: &Model,
    interval: f64,
    particles: &mut Particles,
    rotation: Option<&mut Rotation>,
    heat: Option<PassHeat<'_>>,
    (candidates, every_particle): (&WallCandidates, bool),
    parallel: bool,
) -> ForceSummary {
    let _pass = crate::team::PassName::enter("particle pass (walls)");
    let mut forces = std::mem::take(&mut particles.force);
    let mut dissipated = std::mem::take(&mut particles.dissipated);
    let state = &*particles;
    let count = state.len();
    let (omega, torque, wall_springs) = match rotation.filter(|_| ROTATION) {
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
    // The pairs to visit, with rotation each with its spring: the store's keys are the
    // candidates', and any pair's that holds a spring without being one.
    let (keys, mut springs) = match wall_springs {
        Some(store) => {
            let (keys, springs) = store.align(candidates.keys(), candidates.taking());
            (keys, Some(springs))
        }
        None => (candidates.keys(), None),
    };
    // Each chunk of particles reads and writes the springs of its own pairs.
    let mut chunks: Vec<ChunkWalls<'_>> = Vec::with_capacity(count.div_ceil(PARTICLES_PER_ITEM));
    let mut rest = keys;
    for c in 0..count.div_ceil(PARTICLES_PER_ITEM) {
        let end = (c + 1) * PARTICLES_PER_ITEM;
        let (own, after) = rest.split_at(rest.partition_point(|key| (key.particle as usize) < end));
        let own_springs = springs.take().map(|all| {
            let (own_springs, after) = all.split_at_mut(own.len());
            springs = Some(after);
            own_springs
        });
        chunks.push((own, own_springs));
        rest = after;
    }
    assert!(
        rest.is_empty(),
        "wall candidates of particles past the {count} of the pass"
    );
    let prefetch = super::worth_prefetching(count);
    let force_out: Scatter<'_, DVec3, PerParticle> = Scatter::new(&mut forces);
    let lost_out: Scatter<'_, f64, PerParticle> = Scatter::new(&mut dissipated);
    let heat = heat.map(|h| ParticleHeat {
        model: h.model,
        temperature: h.temperature,
        laser_power: h.laser_power,
        materials: h.materials.reads(&state.mass),
        sums: Scatter::new(h.sums),
        totals: h.totals.map(Scatter::new),
        // Decided by the scene: a model without exchange has no flows to add or keep.
        boundary_flow: h.boundary_flow.map(Scatter::new),
    });
    let outputs = Outputs {
        force: force_out,
        lost: lost_out,
        torque,
    };
    let set = InstructionSet::detect();
    assert!(
        !ROTATION || model.friction.is_some(),
        "a scene with rotation has friction tables (`Model::build`)"
    );
    let visit = |summary: &mut ForceSummary,
                 (keys, springs): &mut ChunkWalls<'_>,
                 chunk: &ParticleChunk<'_>| {
        let mut springs = springs.as_deref_mut();
        let heat = heat.as_ref().filter(|_| HEAT);
        let reads = ParticleReads::open(state, omega, chunk);
        let outputs = outputs.open(chunk);
        let mut round = WallRound::new(model, chunk);
        // The candidates' particles lie spread over the arrays: each one's lines are asked
        // for `LISTED_AHEAD` candidates before it is reached.
        if prefetch {
            for key in keys.iter().take(LISTED_AHEAD) {
                prefetch_particle(reads, &outputs, chunk.member(key.particle as usize));
            }
        }
        let ahead = prefetch.then_some(&outputs);
        let mut next = 0;
        while next < keys.len() {
            next = round.fill::<ROTATION>(
                model,
                (reads, chunk, ahead),
                (keys, springs.as_deref()),
                next,
            );
            if round.full() {
                round.write_back::<ROTATION>(
                    model,
                    (set, interval),
                    &outputs,
                    springs.as_deref_mut(),
                    summary,
                );
            }
        }
        round.write_back::<ROTATION>(model, (set, interval), &outputs, springs, summary);
        round.finish(&outputs);
        // Without laser and exchange no particle has heat to add.
        if let Some(h) = heat.filter(|_| every_particle) {
            let mut heat_round = HeatRound::new(h, &model.walls);
            for window in chunk.windows() {
                heat_round.add(h, state, set, window.owner());
            }
            heat_round.finish(h, set);
            let bound = &mut summary.heat_rate_bound;
            bound.boundary_rate = bound.boundary_rate.max(heat_round.max_boundary_rate);
        }
        // The chunk's forces are finished (the walls were the last to add): every particle of
        // its range is tested, visited or not, while the chunk is at hand.
        let found = outputs.force.inspect_chunk(
            chunk,
            |forces, first| crate::integrate::first_non_finite_of(first, forces),
            chunk.range().start,
        );
        summary.first_non_finite_force =
            crate::integrate::lowest_particle(summary.first_non_finite_force, found);
    };
    // Windows only for the heat of every particle; the wall contacts come from the candidates.
    let summary = scatter::for_each_chunk(
        count,
        PARTICLES_PER_ITEM,
        HEAT && every_particle,
        &mut chunks,
        parallel,
        ForceSummary::default(),
        visit,
        ForceSummary::merge,
    );
    drop(chunks);
    particles.force = forces;
    particles.dissipated = dissipated;
    summary
}

/// A chunk's wall pairs, ascending, and with rotation their springs (one per pair).
type ChunkWalls<'a> = (&'a [WallKey], Option<&'a mut [TangentialSpring]>);

/// How many wall candidates ahead the particle pass asks for a candidate's lines, where it
/// prefetches: on the 97.2k LIGGGHTS bed at 1 thread, 8 ahead made the step 1.02-1.04 times
/// faster than asking for all of a chunk's particles near a wall at once (two sets of 6 pairs of runs
/// at once, `benches/paired.sh`), 16 no faster than 8 and 4 no faster either
/// (docs/performance-log.md, forty-eighth round).
const LISTED_AHEAD: usize = 8;

/// Asks the cache for the lines of `particle`'s position, radius, velocity and force, and
/// with rotation its spin and torque: what its wall contacts read and write. The wall
/// candidates' particles are spread over the arrays: on a bed larger than the cache
/// each one's lines were otherwise missed one after the other (docs/performance-log.md,
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
    temperature: &'a [f64],
    laser_power: Option<&'a [f64]>,
    materials: MaterialReads<'a>,
    /// Net heat flow \[W\].
    sums: Scatter<'a, f64, PerParticle>,
    /// At a step whose largest heat rate is taken: total conductance G_i [W/K].
    totals: Option<Scatter<'a, f64, PerParticle>>,
    /// Heat flow from walls, gas and surroundings \[W\]: `None` without exchange.
    boundary_flow: Option<Scatter<'a, f64, PerParticle>>,
}

/// The heat of a chunk's particles on its way through the boundary kernel: with exchange, the
/// particles in its lanes; each is finished (its boundary flow and laser power) once its lane
/// has run. Without exchange each is finished at once.
struct HeatRound<'c> {
    /// `None` without exchange.
    lanes: Option<BoundaryLanes>,
    particles: Vec<Member<'c>>,
    /// The largest `G_out,i / C_i` [1/s] of the particles finished so far (M.49), 0 without
    /// exchange: it bounds the step's heat rates with the pair pass's contacts
    /// (`thermal::HeatRate::at_most`).
    max_boundary_rate: f64,
}

impl<'c> HeatRound<'c> {
    fn new(heat: &ParticleHeat<'_>, walls: &[crate::model::Wall]) -> Self {
        Self {
            lanes: heat
                .boundary_flow
                .as_ref()
                .map(|_| BoundaryLanes::new(heat.model, walls)),
            particles: Vec::with_capacity(LANES),
            max_boundary_rate: 0.0,
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
            let outside = lanes.output(i);
            if let Some(totals) = &heat.totals {
                totals.update(particle, |g| g + outside.1);
            }
            let rate = outside.1 / heat.materials.heat_capacity(particle.index());
            // (`>` passes over a NaN as `f64::max` does, in fewer instructions.)
            if rate > self.max_boundary_rate {
                self.max_boundary_rate = rate;
            }
            finish_particle(heat, particle, Some(outside));
        }
    }
}

/// Adds `particle`'s exchange with its boundaries (`outside`: flow \[W\] and conductance
/// [W/K]) and its laser power to its net heat flow.
#[inline(always)]
fn finish_particle(heat: &ParticleHeat<'_>, particle: Member<'_>, outside: Option<(f64, f64)>) {
    let k = particle.index();
    let added = match (outside, heat.laser_power) {
        (Some((outside, _)), Some(laser_power)) => Some(outside + laser_power[k]),
        (Some((outside, _)), None) => Some(outside),
        // (As ever: `0.0 +` turns a power of −0 into +0.)
        (None, Some(laser_power)) => Some(0.0 + laser_power[k]),
        (None, None) => None,
    };
    if let Some(added) = added {
        heat.sums.update(particle, |q| q + added);
    }
    if let (Some((outside, _)), Some(flows)) = (outside, &heat.boundary_flow) {
        flows.update(particle, |_| outside);
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

/// The wall contacts of a chunk's candidates on their way through the wall kernel: the lanes
/// being filled with the particle, wall and spring slot of each, and the sums of the particle
/// being written back (a particle's contacts may straddle two rounds). A particle's candidates
/// fill consecutive lanes in the order of its walls, so its sums are complete when a lane of the
/// next particle comes, or the chunk ends.
struct WallRound<'c> {
    lanes: WallLanes,
    /// The lanes kept for the kernel.
    filled: usize,
    /// The particle, wall and spring slot (the candidate's place in its chunk) of each lane.
    particles: [Member<'c>; LANES],
    walls: [usize; LANES],
    slots: [usize; LANES],
    /// The particle whose sums are being formed, and its sums so far.
    open: Option<(Member<'c>, WallSums)>,
}

impl<'c> WallRound<'c> {
    /// An empty round for the wall contacts of `model` in `chunk`.
    fn new(model: &Model, chunk: &ParticleChunk<'c>) -> Self {
        Self {
            lanes: WallLanes::for_model(model),
            filled: 0,
            // (A placeholder: a lane's particle is set with the lane.)
            particles: [chunk.member(chunk.range().start); LANES],
            walls: [0; LANES],
            slots: [0; LANES],
            open: None,
        }
    }

    /// Whether every lane is kept: the round must be written back before the next fill.
    fn full(&self) -> bool {
        self.filled == LANES
    }

    /// Fills the lanes from the chunk's candidates `keys[from..]` (with `FRICTION`, `springs`
    /// holds the spring of each from the last pass) until every lane is kept or the candidates
    /// end, and returns where it stopped. Each candidate's overlap, motion and spring go into
    /// the next lane, which is kept if the pair touches or holds a spring (without `FRICTION`:
    /// if it touches); a lane not kept is overwritten by the next candidate's, so the fill has
    /// no branch per candidate. With `ahead`, each candidate's lines are asked for
    /// [`LISTED_AHEAD`] candidates before it is reached.
    #[inline(always)]
    fn fill<const FRICTION: bool>(
        &mut self,
        model: &Model,
        (reads, chunk, ahead): (
            ParticleReads<'_, 'c>,
            &ParticleChunk<'c>,
            Option<&OpenOutputs<'_, 'c>>,
        ),
        (keys, springs): (&[WallKey], Option<&[TangentialSpring]>),
        from: usize,
    ) -> usize {
        let springs = springs.filter(|_| FRICTION).unwrap_or(&[]);
        assert!(!FRICTION || springs.len() == keys.len());
        let uniform = self.lanes.uniform_wall();
        let mut filled = self.filled;
        let mut c = from;
        while c < keys.len() && filled < LANES {
            if let (Some(outputs), Some(key)) = (ahead, keys.get(c + LISTED_AHEAD)) {
                prefetch_particle(reads, outputs, chunk.member(key.particle as usize));
            }
            let key = keys[c];
            let particle = chunk.member(key.particle as usize);
            let wall = key.wall as usize;
            let held = if FRICTION {
                springs[c]
            } else {
                TangentialSpring::default()
            };
            let radius = reads.radius.get(particle);
            let overlap = plane_overlap(&model.walls[wall], reads.position.get(particle), radius);
            // With one wall and one material the lanes hold its normal and parameters already.
            if !uniform {
                let material = reads.material.get(particle);
                self.lanes
                    .set_model_wall::<FRICTION>(filled, model, wall, material);
            }
            let spin = match reads.angular_velocity {
                Some(omega) if FRICTION => omega.get(particle),
                _ => DVec3::ZERO,
            };
            self.lanes.set_motion::<FRICTION>(
                filled,
                overlap,
                [radius, reads.mass.get(particle)],
                [reads.velocity.get(particle), spin],
                held,
            );
            self.particles[filled] = particle;
            self.walls[filled] = wall;
            self.slots[filled] = c;
            // (A NaN overlap touches not: as ever, such a particle is found by the guard.)
            let kept = overlap > 0.0 || (FRICTION && held != TangentialSpring::default());
            filled += usize::from(kept);
            c += 1;
        }
        self.filled = filled;
        c
    }

    /// Runs the laws of the kept lanes and writes them back in order: each particle's force,
    /// lost energy and torque summed over its walls and added once, its springs kept, its
    /// overlaps observed for the guard. A lane whose pair is apart lets its spring go: its
    /// energy is lost. The last particle's sums stay open ([`Self::finish`]).
    fn write_back<const FRICTION: bool>(
        &mut self,
        model: &Model,
        (set, interval): (InstructionSet, f64),
        outputs: &OpenOutputs<'_, 'c>,
        mut springs: Option<&mut [TangentialSpring]>,
        summary: &mut ForceSummary,
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
        for (lane, &particle) in self.particles.iter().enumerate().take(self.filled) {
            if open.is_none_or(|open| open.index() != particle.index()) {
                if let Some(done) = open {
                    sums.write(outputs, done);
                }
                open = Some(particle);
                sums = WallSums::default();
            }
            let (overlap, radius, held_energy) = self.lanes.taken(lane);
            let spring = if overlap > 0.0 {
                let out = self.lanes.output::<FRICTION>(lane);
                sums.add::<FRICTION>(&out, model.walls[self.walls[lane]].normal);
                summary.observe_overlap_of(overlap, radius, particle.index());
                // A spring equal to none is stored as none (+0, not −0), as the last pass
                // will find it.
                if out.spring == TangentialSpring::default() {
                    TangentialSpring::default()
                } else {
                    out.spring
                }
            } else {
                // Apart, with a spring from the last pass: the spring vanishes with the
                // contact, and what it held is lost.
                sums.lost += held_energy;
                summary.observe_overlap_of(0.0, radius, particle.index());
                TangentialSpring::default()
            };
            if let Some(springs) = springs.as_deref_mut().filter(|_| FRICTION) {
                springs[self.slots[lane]] = spring;
            }
        }
        self.open = open.map(|particle| (particle, sums));
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
