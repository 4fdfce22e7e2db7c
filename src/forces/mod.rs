//! The force pass: the only place that loops over pairs for forces.
//!
//! 1. **Pair pass**, a coloured traversal of the neighbour list slab by slab
//!    ([`NeighborList::for_each_slab_near`]), over each slab's near list between refreshes
//!    (`neighbor`'s "Near lists"): each pair is evaluated once for its owner, by the pure
//!    contact laws run over batches of contacts (`forces/lanes.rs`), and the result is added to
//!    both particles (Newton's third law), together with the torques, the energy the pair lost
//!    and, with `[thermal]`, the heat it conducts. The pair's own history (bond state,
//!    tangential spring) lives in its slot.
//! 2. **Particle pass** (parallel over particles): gravity, wall contacts, boundary heat and the
//!    per-step checks, each particle writing only its own entries.
//!
//! The colouring keeps concurrent writes disjoint, so there are no atomics, locks or per-thread
//! copies, and every sum is formed in an order fixed by the list: the result is bitwise the same
//! for any thread count.

use glam::DVec3;
use rayon::prelude::*;

use crate::contact::tangential::TangentialSpring;
use crate::contact::{self, BondState, FrictionParams, PairKinematics, rolling, tangential};
use crate::model::{Model, Wall};
use crate::neighbor::{NearPairs, NeighborList};
use crate::pair_history::{HistoryTargets, OpenHistories, TangentialHistories};
use crate::particles::{Particles, Rotation};
use crate::periodic::Periodic;
use crate::scatter::{
    self, Member, NearTokens, Opened, PerParticle, PerSlot, Scatter, SlabVisit, Slot, Window,
};
use crate::thermal::{self, ThermalModel};
use crate::wall_history::{Chunk, PARTICLES_PER_CHUNK};

mod lanes;

#[doc(hidden)]
pub use lanes::KernelBench;
pub use lanes::{kernel_build, kernel_builds, limit_kernel};

use lanes::{ContactInput, ContactLanes, InstructionSet, LANES, PairMaterial};

/// `x_b − x_a` \[m\] of particles `a` and `b` at `position`, as its minimum image across
/// periodic axes (M.77).
#[inline(always)]
#[must_use]
pub fn pair_separation(
    periodic: Option<&Periodic>,
    position: &[DVec3],
    a: usize,
    b: usize,
) -> DVec3 {
    let separation = position[b] - position[a];
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
    let separation = pair_separation(periodic, &particles.position, a, b);
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
/// and the energy they took (M.63): `−F_t·v_t dt − ΔU_t + (−M_r·ω_rel) dt`. Without `ROLLING`
/// the rolling torque is zero, as the rolling law gives for `μ_r = 0`, without evaluating it.
#[inline(always)]
fn tangential_step<const ROLLING: bool>(
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
    let rolling_torque = if ROLLING {
        rolling::rolling_torque(
            params.rolling,
            kinematics.effective_radius,
            contact.elastic_normal_force,
            contact.relative_angular_velocity,
            contact.inverse_inertia_sum,
            dt,
        )
    } else {
        DVec3::ZERO
    };
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
/// one step. Returns what the per-step guards need. `cleared`: the forces hold each particle's
/// weight `m g` and the torques, heat flows and total conductances are zero (the step's opening
/// pass, `integrate::kick_drift`, leaves them so), and the pass adds into them without setting
/// them first (with heat: three parallel regions fewer per step). `near`: the near lists,
/// recorded anew if `refresh_near` (or if they do not belong to the list's build), read
/// otherwise. `walls`: the particles that may touch a wall, taken anew from the list's
/// reference positions if they belong to another build.
#[allow(clippy::too_many_arguments)]
pub fn compute(
    model: &Model,
    particles: &mut Particles,
    list: &NeighborList,
    (near, refresh_near): (&mut NearPairs, bool),
    walls: &mut WallCandidates,
    states: Option<&mut [BondState]>,
    rotation: Option<PassRotation<'_>>,
    mut heat: Option<PassHeat<'_>>,
    cleared: bool,
) -> ForceSummary {
    let parallel = crate::worth_parallel(particles.len());
    let set = InstructionSet::detect();
    walls.refresh(model, list, &particles.radius);
    let mut forces = std::mem::take(&mut particles.force);
    let mut dissipated = std::mem::take(&mut particles.dissipated);
    if !cleared {
        set_weights(&mut forces, &particles.mass, model.gravity);
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
    if let Some(h) = heat.as_mut().filter(|_| !cleared) {
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
        let summary = pass(
            model,
            state,
            list,
            (near, refresh_near),
            omega,
            &targets,
            set,
            parallel,
        );
        if let Some(h) = histories {
            h.finish_pass();
        }
        summary
    };
    particles.force = forces;
    particles.dissipated = dissipated;
    // Only the particles that may touch a wall have anything to add, unless heat comes from a
    // laser or is exchanged with the walls, gas or surroundings: then every particle has. With
    // heat, the largest G_i / C_i of all is then taken from the sums as they stand.
    let every_particle = heat
        .as_ref()
        .is_some_and(|h| h.laser_power.is_some() || h.model.has_boundary_exchange());
    let listed = (!every_particle).then_some(walls.particles.as_slice());
    let heat_rate = heat.as_ref().filter(|_| listed.is_some()).map_or(0.0, |h| {
        thermal::max_heat_rate(h.total_conductance, h.heat_capacity, parallel)
    });
    // As for the pair pass: one compiled particle pass per combination of optional physics.
    let own = match (rotation.is_some(), heat.is_some()) {
        (false, false) => {
            particle_pass::<false, false>(model, particles, rotation, heat, listed, parallel)
        }
        (false, true) => {
            particle_pass::<false, true>(model, particles, rotation, heat, listed, parallel)
        }
        (true, false) => {
            particle_pass::<true, false>(model, particles, rotation, heat, listed, parallel)
        }
        (true, true) => {
            particle_pass::<true, true>(model, particles, rotation, heat, listed, parallel)
        }
    };
    let mut summary = pairs.merge(own);
    summary.max_heat_rate = summary.max_heat_rate.max(heat_rate);
    summary
}

/// Sets each particle's force to its weight `m g` \[N\], the force the contacts add to.
fn set_weights(forces: &mut [DVec3], mass: &[f64], gravity: DVec3) {
    for (force, &mass) in forces.iter_mut().zip(mass) {
        *force = mass * gravity;
    }
}

/// The particles that may touch a wall before the neighbour list's next rebuild: those whose
/// overlap with some wall at the list's reference positions exceeds −skin. Between rebuilds no
/// particle is more than half the skin from its reference position (the rebuild test,
/// `NeighborList::moved_too_far`), so no other particle can touch a wall, nor hold a wall spring
/// (which only a contact of the last step leaves). Without heat the particle pass visits these
/// alone: on the LIGGGHTS bed about a tenth of the particles, where the others would only have
/// been found apart (their weight is set by the drift).
#[derive(Debug, Clone, Default)]
pub struct WallCandidates {
    /// The [`NeighborList::generation`] the candidates were taken for (0: none).
    generation: u64,
    /// Ascending particle indices.
    particles: Vec<u32>,
}

impl WallCandidates {
    /// Takes the candidates anew if they belong to another build of `list` than its current.
    fn refresh(&mut self, model: &Model, list: &NeighborList, radius: &[f64]) {
        if self.generation == list.generation() && self.generation != 0 {
            return;
        }
        let reference = list.reference_positions();
        // Without a list of these particles there is no bound on their travel: every one may
        // touch, and the candidates are taken anew at the next pass.
        let bounded = reference.len() == radius.len();
        // The whole skin, twice the bound, so that no rounding matters.
        let reach = -list.skin();
        self.particles.clear();
        self.particles.extend(
            (0..radius.len())
                .filter(|&k| {
                    !bounded
                        || model
                            .walls
                            .iter()
                            .any(|wall| plane_overlap(wall, reference[k], radius[k]) > reach)
                })
                .map(|k| u32::try_from(k).expect("fewer than 2^32 particles")),
        );
        self.generation = if bounded { list.generation() } else { 0 };
    }

    /// The candidates, ascending.
    #[must_use]
    pub fn particles(&self) -> &[u32] {
        &self.particles
    }
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

impl PairTargets<'_> {
    /// The targets for the tokens of `visit` alone, with the physics of one compiled pass:
    /// those it leaves out are `None`.
    #[inline(always)]
    fn open<'t, 'v, const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
        &'t self,
        visit: &SlabVisit<'v>,
    ) -> OpenTargets<'t, 'v> {
        OpenTargets {
            force: self.force.open(visit),
            lost: self.lost.open(visit),
            states: self
                .states
                .as_ref()
                .filter(|_| BONDS)
                .map(|s| s.open(visit)),
            torque: self
                .torque
                .as_ref()
                .filter(|_| FRICTION)
                .map(|t| t.open(visit)),
            tangential: self
                .tangential
                .as_ref()
                .filter(|_| FRICTION)
                .map(|h| h.open(visit)),
            heat: self.heat.as_ref().filter(|_| HEAT).map(|h| OpenHeat {
                model: h.model,
                melted: h.melted,
                temperature: h.temperature,
                heat_flow: h.heat_flow.open(visit),
                total_conductance: h.total_conductance.open(visit),
            }),
        }
    }
}

/// [`PairTargets`] opened for one slab visit ([`Scatter::open`]): its tokens write them without
/// a bounds check per access. What the compiled pass leaves out is `None`.
struct OpenTargets<'t, 'v> {
    force: Opened<'t, 'v, DVec3, PerParticle>,
    lost: Opened<'t, 'v, f64, PerParticle>,
    states: Option<Opened<'t, 'v, BondState, PerSlot>>,
    torque: Option<Opened<'t, 'v, DVec3, PerParticle>>,
    tangential: Option<OpenHistories<'t, 'v>>,
    heat: Option<OpenHeat<'t, 'v>>,
}

/// [`HeatTargets`] opened for one slab visit.
struct OpenHeat<'t, 'v> {
    model: &'t ThermalModel,
    melted: &'t [bool],
    temperature: &'t [f64],
    heat_flow: Opened<'t, 'v, f64, PerParticle>,
    total_conductance: Opened<'t, 'v, f64, PerParticle>,
}

/// The pair pass over every slab, compiled for one combination of optional physics: bond
/// states (`BONDS`), tangential springs and torques (`FRICTION`), conduction (`HEAT`). A target
/// the combination leaves out is ignored even if present. A slab visit that records its near
/// list sifts every slot of its owners; the others sift their near lists only.
#[allow(clippy::too_many_arguments)]
fn pair_pass<const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    particles: &Particles,
    list: &NeighborList,
    (near, refresh_near): (&mut NearPairs, bool),
    omega: Option<&[DVec3]>,
    targets: &PairTargets<'_>,
    set: InstructionSet,
    parallel: bool,
) -> ForceSummary {
    let near_skin = list.near_skin();
    list.for_each_slab_near(
        parallel,
        near,
        refresh_near,
        ForceSummary::default(),
        |summary, slab| {
            let targets = &targets.open::<BONDS, FRICTION, HEAT>(slab);
            let mut batch = Batch::new(model, slab);
            if slab.records_near() {
                for window in slab.windows() {
                    sift::<BONDS, FRICTION>(
                        model, particles, targets, &window, near_skin, &mut batch,
                    );
                    if batch.kept_count >= KEPT_PER_ROUND {
                        handle_kept::<BONDS, FRICTION, HEAT>(
                            model, particles, omega, targets, &mut batch, set, summary,
                        );
                    }
                }
            } else {
                let count = slab.near_count();
                for start in (0..count).step_by(NEAR_PER_ROUND) {
                    let entries = slab.near_pairs(start..(start + NEAR_PER_ROUND).min(count));
                    sift_near::<BONDS, FRICTION>(model, particles, targets, entries, &mut batch);
                    handle_kept::<BONDS, FRICTION, HEAT>(
                        model, particles, omega, targets, &mut batch, set, summary,
                    );
                }
            }
            handle_kept::<BONDS, FRICTION, HEAT>(
                model, particles, omega, targets, &mut batch, set, summary,
            );
            batch.flush::<BONDS, FRICTION, HEAT>(model, particles, targets, set, summary);
            batch.finish_owner(targets);
            batch.release_buffers();
        },
        ForceSummary::merge,
    )
}

/// The particle arrays the pair pass reads, each cut to the particle count. A pair's two indices
/// checked once against that count ([`Self::pair`]) let the compiler drop the bounds checks of
/// every array indexed by them (each array's length is then known to be the count): one compare
/// per pair instead of one per load. In the near sift and the lanes' fill this made the 19.2k
/// LIGGGHTS bed's step 3.9-4.6 % faster at 1 thread, 3.8-4.1 % at 2, 4.3-4.7 % with heat.
struct ParticleReads<'p> {
    count: usize,
    position: &'p [DVec3],
    radius: &'p [f64],
    mass: &'p [f64],
    velocity: &'p [DVec3],
    material: &'p [u16],
}

impl<'p> ParticleReads<'p> {
    /// The arrays of `particles`.
    #[inline(always)]
    fn of(particles: &'p Particles) -> Self {
        let count = particles.len();
        Self {
            count,
            position: &particles.position[..count],
            radius: &particles.radius[..count],
            mass: &particles.mass[..count],
            velocity: &particles.velocity[..count],
            material: &particles.material[..count],
        }
    }

    /// Another per-particle array, cut to the particle count.
    #[inline(always)]
    fn cut<'a, T>(&self, values: &'a [T]) -> &'a [T] {
        &values[..self.count]
    }

    /// The indices of `owner` and `partner`.
    ///
    /// # Panics
    /// If either is not a particle (the neighbour list names only particles).
    #[inline(always)]
    fn pair(&self, owner: Member<'_>, partner: Member<'_>) -> (usize, usize) {
        let (a, b) = (owner.index(), partner.index());
        assert!(a.max(b) < self.count, "a pair beyond the particles");
        (a, b)
    }
}

/// Near-list entries sifted before their kept slots are handled: about a hundred kept slots, as
/// [`KEPT_PER_ROUND`] owners give when all slots are sifted.
const NEAR_PER_ROUND: usize = 256;

/// Appends the near-list entries that need work to the batch's kept slots, as [`sift`] does
/// for a window's slots: without a branch on whether a pair touches. The owner changes from
/// entry to entry here, so its position is loaded each time (it is in cache: the entries come
/// owner by owner).
#[inline(always)]
fn sift_near<'s, const BONDS: bool, const FRICTION: bool>(
    model: &Model,
    particles: &Particles,
    targets: &OpenTargets<'_, 's>,
    entries: impl ExactSizeIterator<Item = NearTokens<'s>>,
    batch: &mut Batch<'_, 's>,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    let histories = targets.tangential.as_ref().filter(|_| FRICTION);
    let mut count = batch.kept_count;
    let room = count + entries.len();
    if batch.kept.len() < room {
        batch.kept.resize(room, None);
    }
    let reads = ParticleReads::of(particles);
    for NearTokens {
        owner,
        slot,
        partner,
        minimum_image,
    } in entries
    {
        let (a, b) = reads.pair(owner, partner);
        let periodic = model.periodic.as_ref().filter(|_| minimum_image);
        let separation = pair_separation(periodic, reads.position, a, b);
        let reach = reads.radius[a] + reads.radius[b];
        let touching = separation.length_squared() < reach * reach;
        let kept_slot = KeptSlot {
            owner,
            partner,
            slot,
            separation,
        };
        count = keep(
            &mut batch.kept,
            count,
            kept_slot,
            touching,
            states,
            histories,
        );
    }
    batch.kept_count = count;
}

/// What happened at one slot, in the order the owners and their slots come: what the write-back
/// ([`Batch::flush`]) replays, so that every sum is formed in the list's order.
#[derive(Debug, Clone, Copy)]
enum Event<'s> {
    /// A touching pair, whose laws run in the next lane of the batch.
    Contact {
        owner: Member<'s>,
        partner: Member<'s>,
        slot: Slot<'s>,
    },
    /// A pair that came apart while its tangential spring held `energy` \[J\]: lost, half to
    /// each particle.
    Released {
        owner: Member<'s>,
        partner: Member<'s>,
        energy: f64,
    },
}

/// What one owner's pairs add to the owner itself, summed over its slots in order and written
/// once when the next owner begins.
#[derive(Debug, Clone, Copy)]
struct OwnerSums<'s> {
    owner: Member<'s>,
    force: DVec3,
    lost: f64,
    torque: DVec3,
    heat: f64,
    conductance: f64,
}

/// A slab's contacts on their way through the kernel: the lanes being filled, the events of the
/// slots found since the last flush, and the sums of the owner being written back.
struct Batch<'r, 's> {
    slab: &'r SlabVisit<'s>,
    lanes: ContactLanes,
    filled: usize,
    events: Vec<Event<'s>>,
    owner: Option<OwnerSums<'s>>,
    /// The slots that need work, of the owners sifted since the last [`handle_kept`], in order:
    /// the first `kept_count` entries (those beyond are the sift's scratch).
    kept: Vec<Option<KeptSlot<'s>>>,
    kept_count: usize,
}

/// A slot that needs work: touching, or holding a bond state or a spring.
#[derive(Debug, Clone, Copy)]
struct KeptSlot<'s> {
    owner: Member<'s>,
    partner: Member<'s>,
    slot: Slot<'s>,
    /// x_b − x_a \[m\], as the sift found it (its minimum image where the owner needs one):
    /// handling the slot does not load the two positions again.
    separation: DVec3,
}

/// Owners' kept slots gathered before they are handled. Handling many owners' slots in one loop,
/// rather than each owner's in its own, spares the branch predictor a loop exit per owner, which
/// it cannot foresee (an owner has 0-3 contacts).
const KEPT_PER_ROUND: usize = 64;

/// The buffers of a [`Batch`] between slab visits, empty, kept per thread: a visit takes them
/// over instead of allocating its own (with two threads, the allocator's locks and the frees of
/// another thread's blocks cost 3 % of the step). Their elements hold a visit's tokens, so an
/// empty buffer changes its element type's lifetime on the way in and out ([`recycle`]).
#[derive(Default)]
struct BatchBuffers {
    events: Vec<Event<'static>>,
    kept: Vec<Option<KeptSlot<'static>>>,
}

thread_local! {
    static BATCH_BUFFERS: std::cell::RefCell<BatchBuffers> =
        std::cell::RefCell::new(BatchBuffers::default());
}

/// An empty vector of `T` as one of `U`, of the same size and alignment: the standard library
/// collects a vector's `into_iter().map(..)` into the vector's own allocation then, so the
/// capacity carries over (if it did not, the buffer would only be allocated anew).
fn recycle<T, U>(mut empty: Vec<T>) -> Vec<U> {
    debug_assert_eq!(std::mem::size_of::<T>(), std::mem::size_of::<U>());
    debug_assert_eq!(std::mem::align_of::<T>(), std::mem::align_of::<U>());
    empty.clear();
    empty
        .into_iter()
        .map(|_| unreachable!("the vector is empty"))
        .collect()
}

impl<'r, 's> Batch<'r, 's> {
    /// A batch for the visit of `slab` with `model`'s contacts, with this thread's buffers.
    fn new(model: &Model, slab: &'r SlabVisit<'s>) -> Self {
        let buffers = BATCH_BUFFERS.with_borrow_mut(std::mem::take);
        Self {
            slab,
            lanes: ContactLanes::for_model(model),
            filled: 0,
            events: recycle(buffers.events),
            owner: None,
            kept: recycle(buffers.kept),
            kept_count: 0,
        }
    }

    /// Gives the buffers back to the thread, for its next visit.
    fn release_buffers(self) {
        let buffers = BatchBuffers {
            events: recycle(self.events),
            kept: recycle(self.kept),
        };
        BATCH_BUFFERS.with_borrow_mut(|held| *held = buffers);
    }

    /// Runs the laws of the filled lanes and writes back every event since the last flush, in
    /// order: the partners' shares at once, the owners' summed per owner.
    #[inline]
    fn flush<const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
        &mut self,
        model: &Model,
        particles: &Particles,
        targets: &OpenTargets<'_, 's>,
        set: InstructionSet,
        summary: &mut ForceSummary,
    ) {
        if self.filled > 0 {
            lanes::run::<BONDS, FRICTION>(set, model, &mut self.lanes);
        }
        let states = targets.states.as_ref().filter(|_| BONDS);
        let histories = targets.tangential.as_ref().filter(|_| FRICTION);
        let torque = targets.torque.as_ref().filter(|_| FRICTION);
        let own_slab = self.slab.own_slab();
        let reads = ParticleReads::of(particles);
        // With its temperatures cut to the particle count (one bounds check per pair).
        let heat = targets
            .heat
            .as_ref()
            .filter(|_| HEAT)
            .map(|h| (h, reads.cut(h.temperature)));
        let mut lane = 0;
        for k in 0..self.events.len() {
            match self.events[k] {
                Event::Released {
                    owner,
                    partner,
                    energy,
                } => {
                    self.begin_owner(owner, targets).lost += 0.5 * energy;
                    targets.lost.update(partner, |l| l + 0.5 * energy);
                }
                Event::Contact {
                    owner,
                    partner,
                    slot,
                } => {
                    let out = self.lanes.output(lane);
                    let [r_a, r_b] = self.lanes.radii(lane);
                    let state_before = self.lanes.state_before(lane);
                    lane += 1;
                    let (a, b) = reads.pair(owner, partner);
                    summary.observe_overlap(out.overlap_ratio, if r_a <= r_b { a } else { b });
                    if let Some(states) = states {
                        if out.state != state_before {
                            states.write(slot, out.state);
                        }
                    }
                    let sums = self.begin_owner(owner, targets);
                    if let Some(histories) = histories {
                        histories.write(own_slab, slot, out.spring);
                        sums.torque += out.torque_on_a;
                        if let Some(torque) = torque {
                            torque.update(partner, |t| t + out.torque_on_b);
                        }
                    }
                    sums.force += out.force_on_a;
                    sums.lost += 0.5 * out.lost;
                    targets.force.update(partner, |f| f - out.force_on_a);
                    targets.lost.update(partner, |l| l + 0.5 * out.lost);
                    if let Some((h, temperature)) = heat {
                        let conductance = thermal::pair_conductance(
                            h.model,
                            [reads.material[a], reads.material[b]],
                            [r_a, r_b],
                            out.overlap,
                            out.effective_radius,
                        );
                        let flow = conductance * (temperature[b] - temperature[a]);
                        sums.heat += flow;
                        sums.conductance += conductance;
                        h.heat_flow.update(partner, |q| q - flow);
                        h.total_conductance.update(partner, |g| g + conductance);
                    }
                }
            }
        }
        self.events.clear();
        self.filled = 0;
    }

    /// The sums of `owner`, begun if it is not the owner being written back (whose sums are
    /// then written first).
    #[inline]
    fn begin_owner(
        &mut self,
        owner: Member<'s>,
        targets: &OpenTargets<'_, 's>,
    ) -> &mut OwnerSums<'s> {
        if self
            .owner
            .is_none_or(|sums| sums.owner.index() != owner.index())
        {
            self.finish_owner(targets);
            self.owner = Some(OwnerSums {
                owner,
                force: DVec3::ZERO,
                lost: 0.0,
                torque: DVec3::ZERO,
                heat: 0.0,
                conductance: 0.0,
            });
        }
        self.owner.as_mut().expect("begun above")
    }

    /// Writes the sums of the owner being written back, if any.
    #[inline]
    fn finish_owner(&mut self, targets: &OpenTargets<'_, 's>) {
        if let Some(sums) = self.owner.take() {
            targets.force.update(sums.owner, |f| f + sums.force);
            targets.lost.update(sums.owner, |l| l + sums.lost);
            if let Some(torque) = &targets.torque {
                torque.update(sums.owner, |t| t + sums.torque);
            }
            if let Some(h) = &targets.heat {
                h.heat_flow.update(sums.owner, |q| q + sums.heat);
                h.total_conductance
                    .update(sums.owner, |g| g + sums.conductance);
            }
        }
    }
}

/// Appends the window owner's slots that need work to the batch's kept slots: those touching,
/// and those apart that still hold a bond state or a spring. Most candidates are neither, and
/// whether one touches is a coin toss for the branch predictor (about one in five does on a
/// packed bed): the slots are sifted without a branch, each written to the list and kept by
/// advancing its end. The slots whose gap is below `near_skin` go into the slab's near list
/// (this sift runs only where the visit records it).
#[inline(always)]
fn sift<'s, const BONDS: bool, const FRICTION: bool>(
    model: &Model,
    particles: &Particles,
    targets: &OpenTargets<'_, 's>,
    window: &Window<'s>,
    near_skin: f64,
    batch: &mut Batch<'_, 's>,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    let histories = targets.tangential.as_ref().filter(|_| FRICTION);
    let owner = window.owner();
    let a = owner.index();
    let minimum_image = window.needs_minimum_image();
    let (x_a, r_a) = (particles.position[a], particles.radius[a]);
    let kept = batch.kept_count;
    let room = kept + window.slot_count();
    if batch.kept.len() < room {
        batch.kept.resize(room, None);
    }
    // One loop per image rule, so that the rule is not tested per slot.
    let slots = SiftedWindow {
        window,
        slab: batch.slab,
        states,
        histories,
        x_a,
        r_a,
        near_skin,
    };
    batch.kept_count = match model.periodic.as_ref().filter(|_| minimum_image) {
        Some(periodic) => slots.sift(particles, &mut batch.kept, kept, |separation| {
            periodic.minimum_image(separation)
        }),
        None => slots.sift(particles, &mut batch.kept, kept, |separation| separation),
    };
}

/// What [`sift`] needs of one window.
struct SiftedWindow<'w, 's, 't> {
    window: &'w Window<'s>,
    slab: &'w SlabVisit<'s>,
    states: Option<&'t Opened<'t, 's, BondState, PerSlot>>,
    histories: Option<&'t OpenHistories<'t, 's>>,
    x_a: DVec3,
    r_a: f64,
    near_skin: f64,
}

impl<'s> SiftedWindow<'_, 's, '_> {
    /// Writes every slot to `kept[count..]` and keeps those that need work by advancing
    /// `count`, which it returns, and records the near ones; `image` maps `x_b − x_a` to the
    /// separation.
    #[inline(always)]
    fn sift(
        &self,
        particles: &Particles,
        kept: &mut [Option<KeptSlot<'s>>],
        mut count: usize,
        image: impl Fn(DVec3) -> DVec3,
    ) -> usize {
        let owner = self.window.owner();
        for (slot, partner) in self.window.pairs() {
            let b = partner.index();
            let separation = image(particles.position[b] - self.x_a);
            let reach = self.r_a + particles.radius[b];
            let distance_squared = separation.length_squared();
            let touching = distance_squared < reach * reach;
            let kept_slot = KeptSlot {
                owner,
                partner,
                slot,
                separation,
            };
            count = keep(
                kept,
                count,
                kept_slot,
                touching,
                self.states,
                self.histories,
            );
            let near_reach = reach + self.near_skin;
            if distance_squared < near_reach * near_reach {
                self.slab.record_near(self.window, slot);
            }
        }
        count
    }
}

/// The rule of both sifts ([`sift`], [`sift_near`]): writes `slot` to `kept[count]` and returns
/// the end of the kept slots, advanced past it if the pair touches or its slot holds a bond state
/// or a spring (which must be cleared when it comes apart). Without a branch: whether a candidate
/// touches is a coin toss for the branch predictor.
#[inline(always)]
fn keep<'s>(
    kept: &mut [Option<KeptSlot<'s>>],
    count: usize,
    slot: KeptSlot<'s>,
    touching: bool,
    states: Option<&Opened<'_, 's, BondState, PerSlot>>,
    histories: Option<&OpenHistories<'_, 's>>,
) -> usize {
    let bonded = states.is_some_and(|states| states.read(slot.slot) != BondState::Unbonded);
    let sprung = histories.is_some_and(|histories| histories.holds(slot.slot));
    kept[count] = Some(slot);
    count + usize::from(touching | bonded | sprung)
}

/// The kept slots of the batch, in order: the pairs apart have their slot state cleared at once;
/// the touching ones go into the batch's lanes, which run and are written back whenever they are
/// full.
#[allow(clippy::too_many_arguments)]
#[inline]
fn handle_kept<'s, const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    particles: &Particles,
    omega: Option<&[DVec3]>,
    targets: &OpenTargets<'_, 's>,
    batch: &mut Batch<'_, 's>,
    set: InstructionSet,
    summary: &mut ForceSummary,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    let histories = targets.tangential.as_ref().filter(|_| FRICTION);
    let omega = omega.filter(|_| FRICTION);
    let heat = targets.heat.as_ref().filter(|_| HEAT);
    let own_slab = batch.slab.own_slab();
    let uniform = batch.lanes.uniform_material();
    let reads = ParticleReads::of(particles);
    let omega = omega.map(|omega| reads.cut(omega));
    let melted = heat.map(|h| reads.cut(h.melted));
    for k in 0..batch.kept_count {
        let KeptSlot {
            owner,
            partner,
            slot: p,
            separation,
        } = batch.kept[k].expect("the sift writes every entry it keeps");
        let (a, b) = reads.pair(owner, partner);
        let (r_a, r_b) = (reads.radius[a], reads.radius[b]);
        let reach = r_a + r_b;
        if separation.length_squared() >= reach * reach {
            // Apart: no square root, no division, and the slot's state cleared.
            if let Some(states) = states {
                if states.read(p) != BondState::Unbonded {
                    states.write(p, BondState::Unbonded);
                }
            }
            if let Some(histories) = histories {
                // The spring vanishes with the contact (k_t → 0 as δ → 0): what it held is
                // lost, half to each particle.
                let held = histories.release(own_slab, p);
                if held.spring_energy != 0.0 {
                    batch.events.push(Event::Released {
                        owner,
                        partner,
                        energy: held.spring_energy,
                    });
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
        // Loop-invariant with one material: then no material is loaded.
        let material = uniform
            .unwrap_or_else(|| PairMaterial::of(model, reads.material[a], reads.material[b]));
        let melted = melted.map_or((false, false), |melted| (melted[a], melted[b]));
        let (angular_velocity, held) = match (histories, omega) {
            (Some(histories), Some(omega)) => ([omega[a], omega[b]], histories.read(own_slab, p)),
            _ => ([DVec3::ZERO; 2], TangentialSpring::default()),
        };
        let input = ContactInput {
            separation,
            radius: [r_a, r_b],
            mass: [reads.mass[a], reads.mass[b]],
            velocity: [reads.velocity[a], reads.velocity[b]],
            effective_modulus: material.effective_modulus,
            damping_ratio: material.damping_ratio,
            materials: material.materials,
            state: states.map_or(BondState::Unbonded, |states| states.read(p)),
            criterion: model.bond_criterion.holds(melted.0, melted.1),
            angular_velocity,
            friction: material.friction,
            held,
        };
        batch.lanes.set::<BONDS, FRICTION>(batch.filled, &input);
        batch.filled += 1;
        batch.events.push(Event::Contact {
            owner,
            partner,
            slot: p,
        });
        if batch.filled == LANES {
            batch.flush::<BONDS, FRICTION, HEAT>(model, particles, targets, set, summary);
        }
    }
    batch.kept_count = 0;
}

/// The particle pass: the wall contacts (normal, and with rotation tangential and rolling),
/// boundary heat and laser power, and the wall overlaps for the guard, over every particle or
/// the `listed` ones (ascending; they must include every particle that touches a wall or holds a
/// wall spring). Each particle writes only its own entries. Compiled for one combination of
/// optional physics: rotation with the wall springs (`ROTATION`) and conduction (`HEAT`); what
/// it leaves out is ignored even if given.
#[allow(clippy::too_many_lines)]
fn particle_pass<const ROTATION: bool, const HEAT: bool>(
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
                h.total_conductance
                    .update(particle, |g| g + outside_conductance);
                added = Some(outside);
            }
            if let Some(laser_power) = h.laser_power {
                added = Some(added.unwrap_or(0.0) + laser_power[k]);
            }
            if let Some(added) = added {
                h.heat_flow.update(particle, |q| q + added);
            }
            h.total_conductance.read(particle) / h.heat_capacity[k]
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
    heat_flow: Scatter<'a, f64, PerParticle>,
    boundary_flow: Scatter<'a, f64, PerParticle>,
    total_conductance: Scatter<'a, f64, PerParticle>,
}

/// Overlap of particle `k` with wall `w` \[m\] (positive in contact) and the wall's normal.
#[inline]
#[must_use]
pub fn wall_overlap(model: &Model, particles: &Particles, k: usize, w: usize) -> f64 {
    plane_overlap(&model.walls[w], particles.position[k], particles.radius[k])
}

/// Overlap of a sphere of `radius` at `position` with the plane of `wall` \[m\] (positive in
/// contact): `r − (x − p)·n`.
#[inline]
#[must_use]
fn plane_overlap(wall: &Wall, position: DVec3, radius: f64) -> f64 {
    radius - (position - wall.point).dot(wall.normal)
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
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The particle pass with rotation and without heat, on one thread.
    fn wall_pass(
        model: &Model,
        particles: &mut Particles,
        rotation: &mut Rotation,
        listed: Option<&[u32]>,
    ) -> ForceSummary {
        particle_pass::<true, false>(model, particles, Some(rotation), None, listed, false)
    }

    /// A scene of 20 µm steel-like spheres (given after it) on a plate at z = 0, with friction;
    /// `simulation` adds keys to `[simulation]`.
    fn plate_scene(simulation: &str) -> String {
        format!(
            r#"
[scene]
version = 1
[simulation]
dt_s = 1e-8
duration_s = 1e-6
gravity_m_s2 = [0.0, 0.0, -9.81]
{simulation}
[materials.m]
density_kg_m3 = 7950
youngs_modulus_pa = 1e9
poisson_ratio = 0.3
[contact]
model = "hertz"
restitution = 0.5
friction_coefficient = 0.5
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "m"
"#
        )
    }

    /// The batch buffers' reuse rests on `recycle` keeping the allocation: a change of the
    /// standard library that lost it would cost an allocation per slab visit, which this test
    /// would show.
    #[test]
    fn recycling_an_empty_buffer_keeps_its_allocation() {
        let mut numbers: Vec<u64> = Vec::with_capacity(100);
        numbers.extend(0..50);
        let address = numbers.as_ptr() as usize;
        let floats: Vec<f64> = recycle(numbers);
        assert!(floats.is_empty());
        assert!(floats.capacity() >= 100, "capacity {}", floats.capacity());
        assert_eq!(floats.as_ptr() as usize, address);
    }

    /// A sphere off the plate that still holds the spring of its last contact with it takes
    /// the particle pass's full path: the spring's energy is lost and the spring is gone. The
    /// forces stay at the weights the drift set.
    #[test]
    fn a_sphere_off_the_wall_releases_its_spring_and_the_forces_stay_at_the_weights() {
        let text = plate_scene("")
            + r#"
[[particles]]
position_m = [0.0, 0.0, 2.1e-5]
radius_m = 2e-5
material = "m"
[[particles]]
position_m = [1e-4, 0.0, 2.1e-5]
radius_m = 2e-5
material = "m"
"#;
        let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
        let (model, mut particles) = Model::build(&scene);
        let mut rotation = Rotation::new(particles.len(), model.walls.len());
        let held = TangentialSpring {
            history: DVec3::new(1e-9, 0.0, 0.0),
            spring_energy: 3e-15,
        };
        rotation.wall_springs =
            crate::wall_history::WallSprings::from_entries(particles.len(), [(0, 0, held)]);
        set_weights(&mut particles.force, &particles.mass, model.gravity);
        for listed in [None, Some([0, 1].as_slice())] {
            let summary = wall_pass(&model, &mut particles, &mut rotation, listed);
            assert_eq!(summary.max_overlap_ratio, 0.0);
        }
        assert_eq!(particles.dissipated, [held.spring_energy, 0.0]);
        assert_eq!(rotation.wall_springs.entries().count(), 0);
        for k in 0..2 {
            assert_eq!(particles.force[k], particles.mass[k] * model.gravity);
            assert_eq!(rotation.torque[k], DVec3::ZERO);
        }
    }

    /// The wall candidates are the particles within the skin of a wall at the list's reference
    /// positions (here the skin is 10 µm and the radius 20 µm), taken anew for a new build
    /// only; and the particle pass over them gives bitwise what it gives over every particle.
    #[test]
    fn the_wall_candidates_are_the_particles_within_the_skin_of_a_wall() {
        let mut text = plate_scene("skin_m = 1e-5")
            + r#"
[[walls]]
point_m = [1e-3, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
material = "m"
"#;
        // Heights of the centres above the plate: touching, within the skin (gap 9.9 µm),
        // beyond it (gap 10.1 µm), far; the last one far from the plate but near the side wall.
        let places = [
            (1e-4, 1.9e-5),
            (2e-4, 2.99e-5),
            (3e-4, 3.01e-5),
            (4e-4, 1e-4),
            (1e-3 - 2.5e-5, 1e-4),
        ];
        for (x, z) in places {
            text += &format!(
                "[[particles]]\nposition_m = [{x:e}, 0.0, {z:e}]\nradius_m = 2e-5\nmaterial = \"m\"\n"
            );
        }
        let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
        let (model, particles) = Model::build(&scene);
        let mut list = NeighborList::new(model.skin, None);
        list.build(&particles.position, &particles.radius);
        let mut candidates = WallCandidates::default();
        candidates.refresh(&model, &list, &particles.radius);
        // The model keeps the scene's order.
        assert_eq!(candidates.particles(), [0, 1, 4]);
        // The same build: kept, even for other radii; a new build: taken anew.
        candidates.refresh(&model, &list, &[2e-5, 2e-5, 1e-3, 2e-5, 2e-5]);
        assert_eq!(candidates.particles().len(), 3);
        list.build(&particles.position, &particles.radius);
        candidates.refresh(&model, &list, &[2e-5, 2e-5, 1e-3, 2e-5, 2e-5]);
        assert_eq!(candidates.particles().len(), 4);
        // The pass over the candidates and over every particle.
        let pass = |listed: Option<&[u32]>| {
            let mut particles = particles.clone();
            let mut rotation = Rotation::new(particles.len(), model.walls.len());
            set_weights(&mut particles.force, &particles.mass, model.gravity);
            let summary = wall_pass(&model, &mut particles, &mut rotation, listed);
            (
                particles.force,
                particles.dissipated,
                rotation.torque,
                summary,
            )
        };
        candidates.refresh(&model, &NeighborList::default(), &particles.radius);
        assert_eq!(candidates.particles().len(), 5, "no list: every particle");
        list.build(&particles.position, &particles.radius);
        candidates.refresh(&model, &list, &particles.radius);
        let (all, listed) = (pass(None), pass(Some(candidates.particles())));
        assert_eq!(format!("{all:?}"), format!("{listed:?}"));
        // The touching sphere got the plate's push.
        assert!(all.0.iter().any(|f| f.z > 0.0));
    }
}
