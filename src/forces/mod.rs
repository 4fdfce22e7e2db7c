//! The force pass: the only place that loops over pairs for forces.
//!
//! 1. **Pair pass** (`forces/pair_pass.rs`), a coloured traversal of the neighbour list slab by
//!    slab ([`NeighborList::for_each_slab_near`]), over each slab's near list between refreshes
//!    (`neighbor`'s "Near lists"): each pair is evaluated once for its owner, by the pure
//!    contact laws run over batches of contacts (`forces/lanes.rs`), and the result is added to
//!    both particles (Newton's third law), together with the torques, the energy the pair lost
//!    and, with `[thermal]`, the heat it conducts. The pair's own history (bond state,
//!    tangential spring) lives in its slot.
//! 2. **Particle pass** (`forces/particle_pass.rs`, parallel over particles): wall contacts,
//!    boundary heat and the per-step checks, each particle writing only its own entries.
//!
//! This file holds what both passes share: [`compute`], which runs them for one combination of
//! the scene's optional physics, the tangential and rolling step of one contact (a pair's or a
//! wall's), the wall candidates and the pass's [`ForceSummary`].
//!
//! The colouring keeps concurrent writes disjoint, so there are no atomics, locks or per-thread
//! copies, and every sum is formed in an order fixed by the list: the result is bitwise the same
//! for any thread count.

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::contact::tangential::TangentialSpring;
use crate::contact::{BondState, FrictionParams, PairKinematics, rolling, tangential};
use crate::model::{Model, Wall};
use crate::neighbor::{NearPairs, NeighborList};
use crate::pair_history::TangentialHistories;
use crate::particles::{Particles, Rotation};
use crate::periodic::Periodic;
use crate::scatter::{OpenedReads, ParticleTokens, Scatter};
use crate::thermal::{HeatMaterials, HeatRateBound, ThermalModel};
use crate::wall_history::WallKey;

mod lanes;
mod pair_pass;
mod particle_pass;
mod wall_lanes;

use pair_pass::{HeatTargets, PairTargets};

pub use crate::simd::{kernel_build, kernel_builds, limit_kernel};
#[doc(hidden)]
pub use lanes::KernelBench;

use crate::simd::InstructionSet;

/// `x_b − x_a` \[m\] of particles at `x_a` and `x_b` \[m\], as its minimum image across the
/// periodic axes of `periodic` (M.77; `None` takes the plain difference, as for a pair the
/// neighbour list vouches needs no image).
#[inline(always)]
#[must_use]
pub fn pair_separation(periodic: Option<&Periodic>, x_a: DVec3, x_b: DVec3) -> DVec3 {
    let separation = x_b - x_a;
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
    let separation = pair_separation(periodic, particles.position[a], particles.position[b]);
    let distance = separation.length();
    (
        unit_normal(separation, distance),
        particles.radius[a] + particles.radius[b] - distance,
    )
}

/// [`pair_geometry`] of a touching pair (δ > 0), `None` for a pair apart: the same normal and
/// overlap, bit for bit, for every pair [`pair_geometry`] finds touching
/// ([`touching_geometry`]).
#[inline]
#[must_use]
pub fn touching_pair_geometry(
    periodic: Option<&Periodic>,
    particles: &Particles,
    a: usize,
    b: usize,
) -> Option<(DVec3, f64)> {
    let separation = pair_separation(periodic, particles.position[a], particles.position[b]);
    touching_geometry(separation, particles.radius[a] + particles.radius[b])
}

/// The unit normal and overlap δ = reach − |separation| of a pair at `separation` (x_b − x_a,
/// its minimum image) whose radii sum to `reach` \[m\], if it touches (δ > 0): as
/// [`pair_geometry`] computes them. Most candidates of a neighbour list are apart (about four
/// in five on a packed bed), and their square root and division are skipped: a pair whose
/// squared distance exceeds `reach²` is apart whatever the rounding. The margin of `1 + 2⁻²⁰`
/// on the computed `reach²` covers its rounding (a few units of 2⁻⁵³) with room to spare, so
/// that the pairs near contact take the exact test.
#[inline(always)]
#[must_use]
pub fn touching_geometry(separation: DVec3, reach: f64) -> Option<(DVec3, f64)> {
    let distance_squared = separation.length_squared();
    if distance_squared > reach * reach * (1.0 + 1.0 / f64::from(1 << 20)) {
        return None;
    }
    let distance = distance_squared.sqrt();
    let overlap = reach - distance;
    (overlap > 0.0).then(|| (unit_normal(separation, distance), overlap))
}

/// The particle arrays the force passes read, opened for one slab visit of the pair pass or one
/// chunk of the particle pass ([`OpenedReads::open`]): their lengths are checked once per visit
/// or chunk, and a read with one of its tokens takes no bounds check. (Cut to the particle count
/// and indexed by a pair's two indices, checked once per pair, they took a compare and a branch
/// per near-list entry and per contact in each of the sift, the fill and the write-back: about
/// 13 instructions per particle-step on the 19.2k LIGGGHTS bed.)
#[derive(Clone, Copy)]
struct ParticleReads<'p, 'v> {
    position: OpenedReads<'p, 'v, DVec3>,
    radius: OpenedReads<'p, 'v, f64>,
    mass: OpenedReads<'p, 'v, f64>,
    velocity: OpenedReads<'p, 'v, DVec3>,
    material: OpenedReads<'p, 'v, u16>,
    /// With rotation: the angular velocities \[rad/s\].
    angular_velocity: Option<OpenedReads<'p, 'v, DVec3>>,
}

impl<'p, 'v> ParticleReads<'p, 'v> {
    /// The arrays of `particles` and the angular velocities `omega`, for the particle tokens of
    /// `tokens` (a slab visit's or a chunk's).
    #[inline]
    fn open(
        particles: &'p Particles,
        omega: Option<&'p [DVec3]>,
        tokens: &impl ParticleTokens<'v>,
    ) -> Self {
        Self {
            position: OpenedReads::open(&particles.position, tokens),
            radius: OpenedReads::open(&particles.radius, tokens),
            mass: OpenedReads::open(&particles.mass, tokens),
            velocity: OpenedReads::open(&particles.velocity, tokens),
            material: OpenedReads::open(&particles.material, tokens),
            angular_velocity: omega.map(|omega| OpenedReads::open(omega, tokens)),
        }
    }
}

/// When the force passes ask the cache for lines ahead ([`worth_prefetching`]): `auto` (by the
/// bed's size), `on` or `off`, for the rest of the process (`am-sim --prefetch`). Results do
/// not change: a prefetch changes no value.
pub const PREFETCH_MODES: [&str; 3] = ["auto", "on", "off"];

/// The index in [`PREFETCH_MODES`] of the mode the passes follow.
static PREFETCH_MODE: AtomicUsize = AtomicUsize::new(0);

/// Sets the prefetch mode (one of [`PREFETCH_MODES`]) for the rest of the process.
///
/// # Errors
/// If `mode` names none.
pub fn set_prefetch(mode: &str) -> Result<(), String> {
    let index = PREFETCH_MODES
        .iter()
        .position(|m| *m == mode)
        .ok_or_else(|| {
            format!(
                "{mode:?} is not a prefetch mode ({})",
                PREFETCH_MODES.join(", ")
            )
        })?;
    PREFETCH_MODE.store(index, Ordering::Relaxed);
    Ok(())
}

/// Whether the force passes ask the cache for a particle's lines before they reach them
/// ([`crate::scatter::prefetch`]): the near sift for each partner's velocity, mass, force,
/// lost energy, spin and torque, which the fill and the write-back read and write next, and the
/// particle pass for the particles near a wall a few places ahead. On a bed whose arrays the
/// pair pass reaches (about 150 bytes per particle: position, velocity, spin, force and torque,
/// mass, radius, lost energy) outgrow the caches those lines are otherwise missed one contact
/// after the other: the 97.2k LIGGGHTS bed ran 1.13 times faster with them at 1 thread on a
/// shared Zen 4 host, whose 32 MiB third-level cache other machines use too, and 1.12-1.15
/// times on a Zen 3 host (512 KiB second-level cache), before the lost energy and torque were
/// added to the set (1.07 times more there). Where every line is in cache they cost
/// instructions and gain nothing: about 20 per particle-step on the 19.2k bed with the first
/// set (+5 %), and by the clock 0.94-0.98 there on the Zen 3 with the full set; so they are left
/// out below 8 MiB of those arrays (about 56,000 particles)
/// (docs/performance-log.md, thirty-fourth and thirty-fifth rounds).
/// `am-sim --prefetch on` or `off` overrides the rule.
#[must_use]
pub fn worth_prefetching(particles: usize) -> bool {
    /// The per-particle bytes of the arrays the pair pass reaches, and what they must exceed.
    const BYTES_PER_PARTICLE: usize = 150;
    const FROM_BYTES: usize = 8 << 20;
    match PREFETCH_MODES[PREFETCH_MODE.load(Ordering::Relaxed)] {
        "on" => true,
        "off" => false,
        _ => particles * BYTES_PER_PARTICLE > FROM_BYTES,
    }
}

/// `separation / distance`, the unit normal from a to b. Coincident centres have no direction;
/// any unit vector keeps the force finite, and the blown-up overlap is reported by the run's
/// overlap guard.
#[inline(always)]
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
    /// Where the heat capacities come from.
    pub materials: &'a HeatMaterials,
    /// Out: net heat flow \[W\].
    pub sums: &'a mut [f64],
    /// Out, at a step whose largest heat rate is taken (an output's): each particle's total
    /// conductance G_i [W/K] (M.49), added into (zero it first). `None` at the other steps,
    /// which only bound the rate (`ForceSummary::heat_rate_bound`).
    pub totals: Option<&'a mut [f64]>,
    /// Out: heat flow from walls, gas and surroundings \[W\], where the model exchanges heat
    /// with them.
    pub boundary_flow: Option<&'a mut [f64]>,
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

/// The two kinds of force pass of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Evaluation {
    /// The set-up evaluation: the forces of the state as it stands, F(t₀) from x(t₀), v(t₀) and
    /// the springs the particles start with. No time passes in it, so no spring advances
    /// (`ξ + v_t · 0`, M.59) and no damper or slip does work; a spring beyond its Coulomb limit
    /// is rescaled to it, as at any evaluation. LAMMPS and LIGGGHTS do the same in their setup
    /// pass (`shearupdate = 0`): an imported bed's first step starts from the forces LIGGGHTS'
    /// own start would have. The pass sets the forces, torques and heat sums before adding
    /// into them.
    SetUp,
    /// A step's evaluation after the drift: the contacts act over dt (the springs advance by
    /// `v_t dt`, the dampers and slips do work over dt). The step's opening pass
    /// (`integrate::kick_drift`) has left the forces at each particle's weight `m g` and the
    /// torques, heat flows and total conductances at zero, so the pass adds into them without
    /// setting them first (with heat: three parallel regions fewer per step).
    Step,
}

impl Evaluation {
    /// The time the contacts act over \[s\]: 0 at the set-up, `dt` in a step.
    #[must_use]
    pub fn interval(self, dt: f64) -> f64 {
        match self {
            Self::SetUp => 0.0,
            Self::Step => dt,
        }
    }
}

/// The force pass (steps 4-5 of the step order): every particle's force, with rotation its
/// torque, with `[thermal]` its first-substep heat flows and total conductances; bond states
/// (`states`, per slot, given when the scene has a bond law) and tangential histories advance by
/// one step (at a [`Evaluation::Step`]). Returns what the per-step guards need. `evaluation`:
/// which of the run's two kinds of force pass this is ([`Evaluation`]). `near`: the near lists,
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
    evaluation: Evaluation,
) -> ForceSummary {
    let cleared = evaluation == Evaluation::Step;
    let interval = evaluation.interval(model.dt);
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
        fill(h.sums, 0.0, parallel);
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
            sums: Scatter::new(h.sums),
            totals: h.totals.as_deref_mut().map(Scatter::new),
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
            (false, false, false) => pair_pass::run::<false, false, false>,
            (false, false, true) => pair_pass::run::<false, false, true>,
            (false, true, false) => pair_pass::run::<false, true, false>,
            (false, true, true) => pair_pass::run::<false, true, true>,
            (true, false, false) => pair_pass::run::<true, false, false>,
            (true, false, true) => pair_pass::run::<true, false, true>,
            (true, true, false) => pair_pass::run::<true, true, false>,
            (true, true, true) => pair_pass::run::<true, true, true>,
        };
        let summary = pass(
            model,
            state,
            list,
            (near, refresh_near),
            omega,
            &targets,
            (set, interval),
            parallel,
        );
        if let Some(h) = histories {
            h.finish_pass();
        }
        summary
    };
    particles.force = forces;
    particles.dissipated = dissipated;
    // Only the pairs that may touch have wall contacts to add. With heat from a laser, or
    // exchanged with the walls, gas or surroundings, every particle has heat to add as well.
    // There the particle pass takes the largest G_i / C_i of every chunk's particles at the
    // chunk's end; else the pair pass's largest G_i bounds it.
    let every_particle = heat
        .as_ref()
        .is_some_and(|h| h.laser_power.is_some() || h.boundary_flow.is_some());
    let walls = (&*walls, every_particle);
    // As for the pair pass: one compiled particle pass per combination of optional physics.
    let own = match (rotation.is_some(), heat.is_some()) {
        (false, false) => particle_pass::run::<false, false>(
            model, interval, particles, rotation, heat, walls, parallel,
        ),
        (false, true) => particle_pass::run::<false, true>(
            model, interval, particles, rotation, heat, walls, parallel,
        ),
        (true, false) => particle_pass::run::<true, false>(
            model, interval, particles, rotation, heat, walls, parallel,
        ),
        (true, true) => particle_pass::run::<true, true>(
            model, interval, particles, rotation, heat, walls, parallel,
        ),
    };
    pairs.merge(own)
}

/// Sets each particle's force to its weight `m g` \[N\], the force the contacts add to.
fn set_weights(forces: &mut [DVec3], mass: &[f64], gravity: DVec3) {
    for (force, &mass) in forces.iter_mut().zip(mass) {
        *force = mass * gravity;
    }
}

/// The (particle, wall) pairs that may touch before the neighbour list's next rebuild: those
/// whose overlap at the list's reference positions exceeds −skin. Between rebuilds no particle
/// is more than half the skin from its reference position (the rebuild test,
/// `NeighborList::moved_too_far`), so no other pair can touch, nor take a wall spring (which
/// only a contact leaves). The particle pass visits these alone: on the LIGGGHTS bed about a
/// tenth of the particles, each with the one wall it is near, where the others would only have
/// been found apart (their weight is set by the drift).
#[derive(Debug, Clone, Default)]
pub struct WallCandidates {
    /// The [`NeighborList::generation`] the candidates were taken for (0: none, without a
    /// list, where they are taken at every pass).
    generation: u64,
    /// Ascending.
    keys: Vec<WallKey>,
}

impl WallCandidates {
    /// Takes the candidates anew if they belong to another build of `list` than its current.
    fn refresh(&mut self, model: &Model, list: &NeighborList, radius: &[f64]) {
        if self.generation == list.generation() && self.generation != 0 {
            return;
        }
        let reference = list.reference_positions();
        // Without a list of these particles there is no bound on their travel: every pair may
        // touch, and the candidates are taken anew at the next pass.
        let bounded = reference.len() == radius.len();
        // The whole skin, twice the bound, so that no rounding matters.
        let reach = -list.skin();
        self.keys.clear();
        for (k, &radius) in radius.iter().enumerate() {
            for (w, wall) in model.walls.iter().enumerate() {
                if !bounded || plane_overlap(wall, reference[k], radius) > reach {
                    self.keys.push(WallKey::new(k, w));
                }
            }
        }
        self.generation = if bounded { list.generation() } else { 0 };
    }

    /// The candidates, ascending.
    #[must_use]
    pub fn keys(&self) -> &[WallKey] {
        &self.keys
    }

    /// The name of this taking of the candidates, the list build's generation (unique over the
    /// process; 0: taken at every pass), which the spring store aligns to
    /// ([`crate::wall_history::WallSprings::align`]).
    #[must_use]
    pub fn taking(&self) -> u64 {
        self.generation
    }

    /// The candidates `keys` (ascending), taken now: for tests, which choose them.
    #[cfg(test)]
    fn of(keys: impl IntoIterator<Item = (usize, usize)>) -> Self {
        let keys: Vec<WallKey> = keys.into_iter().map(|(k, w)| WallKey::new(k, w)).collect();
        assert!(keys.is_sorted_by(|a, b| a < b));
        // (No list build: taken, and aligned to, at every pass.)
        Self {
            generation: 0,
            keys,
        }
    }

    /// Every (particle, wall) pair of `model` for `particles` particles, as without a list.
    #[cfg(test)]
    fn every(model: &Model, particles: usize) -> Self {
        let mut candidates = Self::default();
        candidates.refresh(model, &NeighborList::default(), &vec![0.0; particles]);
        candidates
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

/// Overlap of particle `k` with wall `w` \[m\] (positive in contact).
#[inline]
#[must_use]
pub fn wall_overlap(model: &Model, particles: &Particles, k: usize, w: usize) -> f64 {
    plane_overlap(&model.walls[w], particles.position[k], particles.radius[k])
}

/// Overlap of a sphere of `radius` at `position` with the plane of `wall` \[m\] (positive in
/// contact): `r − (x − p)·n`.
#[inline]
#[must_use]
pub(crate) fn plane_overlap(wall: &Wall, position: DVec3, radius: f64) -> f64 {
    radius - (position - wall.point).dot(wall.normal)
}

/// What the force pass saw, reduced in a thread-count-independent way (max, and the lowest
/// index on ties): the inputs of the run's per-step guards (docs/stability.md).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceSummary {
    /// With `[thermal]`: the largest conductance per mass of a contact, and the largest rate
    /// of the exchange with walls, gas and surroundings, which bound `max G_i / C_i` for the
    /// step's substep count ([`crate::thermal::HeatRate::at_most`]) without summing any
    /// particle's G_i. Zero without.
    pub heat_rate_bound: HeatRateBound,
    /// Largest overlap of any contact relative to the smaller radius of its pair (the
    /// particle's radius, against a wall).
    pub max_overlap_ratio: f64,
    /// The particle (index) with that smaller radius.
    pub max_overlap_particle: usize,
    /// Touching particle pairs the pass met (the near lists' choice of skin weighs them,
    /// `neighbor::NearSkinTuner`).
    pub pair_contacts: usize,
    /// The lowest particle (index) whose force is NaN or infinite once the pass is done, if any:
    /// the particle pass tests each chunk's finished forces as its last act, the test the
    /// closing kick makes, for a step whose closing kick is left to the next opening pass
    /// (`Simulation::advance`). (A pass of its own over the forces, as before, made the thread
    /// team meet once more per step: 2.5-4 % of a 2-thread step on the 19.2k LIGGGHTS bed.)
    pub first_non_finite_force: Option<usize>,
}

impl ForceSummary {
    /// Takes in one contact's overlap ratio, seen at particle `k`.
    #[inline]
    fn observe_overlap(&mut self, ratio: f64, k: usize) {
        self.observe_overlap_at(ratio, || k);
    }

    /// As [`Self::observe_overlap`] for the ratio `overlap / radius`, divided only where it can
    /// reach the largest so far: on the flagship's scan, where 45 % of the particles touch the
    /// plate, the particle pass took 299-302 µs a call at 1 thread this way against 305-312
    /// with a division for every one (docs/performance-log.md, fifty-fifth round).
    /// `fl(overlap / radius) ≥ M` needs `overlap ≥ M · radius · (1 − 2⁻⁵³)`; the test's margin of
    /// 1e-9 is far wider than the rounding of its products, so a ratio it skips could never
    /// have reached M, and the summary is the same to the bit.
    #[inline(always)]
    fn observe_overlap_of(&mut self, overlap: f64, radius: f64, k: usize) {
        if overlap < self.max_overlap_ratio * radius * (1.0 - 1e-9) {
            return;
        }
        self.observe_overlap(overlap / radius, k);
    }

    /// As [`Self::observe_overlap`], with the particle found by `particle()` only for a ratio
    /// that reaches the largest so far: most contacts' do not, and finding the particle (the
    /// smaller of two) costs two loads and a compare per contact of the pair pass.
    #[inline(always)]
    fn observe_overlap_at(&mut self, ratio: f64, particle: impl FnOnce() -> usize) {
        if ratio >= self.max_overlap_ratio {
            let k = particle();
            if ratio > self.max_overlap_ratio || k < self.max_overlap_particle {
                self.max_overlap_ratio = ratio;
                self.max_overlap_particle = k;
            }
        }
    }

    /// Combines two partial summaries; associative and commutative, so any reduction tree gives
    /// the same result.
    #[must_use]
    fn merge(mut self, other: Self) -> Self {
        self.observe_overlap(other.max_overlap_ratio, other.max_overlap_particle);
        self.heat_rate_bound = self.heat_rate_bound.merge(other.heat_rate_bound);
        self.pair_contacts += other.pair_contacts;
        self.first_non_finite_force = crate::integrate::lowest_particle(
            self.first_non_finite_force,
            other.first_non_finite_force,
        );
        self
    }
}

#[cfg(test)]
pub(in crate::forces) mod tests {
    use super::*;

    /// The particle pass with rotation and without heat, on one thread.
    fn wall_pass(
        model: &Model,
        particles: &mut Particles,
        rotation: &mut Rotation,
        candidates: &WallCandidates,
    ) -> ForceSummary {
        particle_pass::run::<true, false>(
            model,
            model.dt,
            particles,
            Some(rotation),
            None,
            (candidates, false),
            false,
        )
    }

    /// A scene of 20 µm steel-like spheres (given after it) on a plate at z = 0, with friction;
    /// `simulation` adds keys to `[simulation]`.
    pub(in crate::forces) fn plate_scene(simulation: &str) -> String {
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

    /// The particle pass tests every particle's finished force, a wall candidate or not, in every chunk,
    /// and names the lowest particle whose force is NaN or infinite, on one thread and on the
    /// team; it finds none when all are finite. (The run leaves a step's closing kick to the
    /// next opening pass only when the pass found none: `Simulation::advance`.)
    #[test]
    fn the_particle_pass_names_the_lowest_particle_with_a_non_finite_force() {
        // 13,500 spheres in 14 chunks, a layer of them nearest the plate: only those are
        // candidates.
        let mut text = plate_scene("");
        text += "[[lattice]]\nmin_corner_m = [0.0, 0.0, 2e-5]\nmax_corner_m = [2.4e-3, 2.4e-3, 1.2e-3]\nradius_m = 2e-5\nspacing_m = 8e-5\nmaterial = \"m\"\n";
        let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
        let (model, particles) = Model::build(&scene);
        let count = particles.len();
        assert!(
            count > 2 * crate::team::PARTICLES_PER_ITEM,
            "{count} spheres"
        );
        let lowest = particles
            .position
            .iter()
            .map(|x| x.z)
            .fold(f64::INFINITY, f64::min);
        let listed: Vec<u32> = (0..count)
            .filter(|&k| particles.position[k].z < lowest + 1e-6)
            .map(|k| u32::try_from(k).expect("few spheres"))
            .collect();
        assert!(
            !listed.is_empty() && listed.len() < count / 4,
            "{} of {count}",
            listed.len()
        );
        let near = WallCandidates::of(listed.iter().map(|&k| (k as usize, 0)));
        let every = WallCandidates::every(&model, count);
        let pass = |broken: &[(usize, f64)], candidates: &WallCandidates, parallel: bool| {
            let mut particles = particles.clone();
            set_weights(&mut particles.force, &particles.mass, model.gravity);
            for &(k, value) in broken {
                particles.force[k].y = value;
            }
            particle_pass::run::<false, false>(
                &model,
                model.dt,
                &mut particles,
                None,
                None,
                (candidates, false),
                parallel,
            )
            .first_non_finite_force
        };
        let unlisted = (0..count)
            .rev()
            .find(|k| {
                listed
                    .binary_search(&u32::try_from(*k).expect("few"))
                    .is_err()
            })
            .expect("an unlisted sphere");
        // Each case: the forces made non-finite (particle, value of a component), and the
        // particle the pass must name.
        type Case<'a> = (&'a [(usize, f64)], Option<usize>);
        let cases: [Case<'_>; 4] = [
            (&[], None),
            (&[(unlisted, f64::NAN)], Some(unlisted)),
            (&[(count - 1, f64::INFINITY), (1500, f64::NAN)], Some(1500)),
            (
                &[(2100, f64::NEG_INFINITY), (listed[0] as usize, f64::NAN)],
                Some((listed[0] as usize).min(2100)),
            ),
        ];
        for (broken, expected) in cases {
            for parallel in [false, true] {
                assert_eq!(pass(broken, &near, parallel), expected, "{broken:?}");
                assert_eq!(pass(broken, &every, parallel), expected, "{broken:?}");
            }
        }
    }

    /// The shortcut for pairs apart changes no touching pair: for pairs at distances stepped ulp
    /// by ulp across contact (where the rounding of `(r_a + r_b)²` and of the square root
    /// decide), at random distances within twice the reach, across a periodic face and at
    /// coincident centres, `touching_pair_geometry` gives `pair_geometry`'s normal and overlap
    /// bit for bit when the overlap is positive, and `None` otherwise.
    #[test]
    fn the_touching_geometry_is_the_full_geometry_of_every_touching_pair() {
        let periodic = crate::periodic::Periodic {
            lower: DVec3::ZERO,
            length: [Some(1e-3), None, None],
        };
        let mut rng = crate::bed::rng::SplitMix64(7);
        let mut checked = [0_usize; 2];
        for case in 0..4000 {
            let radii = [rng.uniform(1e-5, 2e-5), rng.uniform(1e-5, 2e-5)];
            let reach = radii[0] + radii[1];
            let direction =
                DVec3::new(rng.symmetric(), rng.symmetric(), rng.symmetric()).normalize();
            let distance = match case % 4 {
                // Within 40 ulps of contact, either side.
                0 | 1 => {
                    let steps = (rng.unit() * 80.0) as i64 - 40;
                    f64::from_bits((reach.to_bits() as i64 + steps) as u64)
                }
                2 => rng.uniform(0.0, 2.0 * reach),
                _ => 0.0,
            };
            let first = DVec3::new(1e-6, 5e-4, 5e-4);
            let mut second = first + direction * distance;
            if case % 8 == 1 {
                // The partner's stored position on the far side of the periodic box.
                second.x += 1e-3;
            }
            let mut particles = Particles::default();
            for (position, radius) in [(first, radii[0]), (second, radii[1])] {
                let init = crate::particles::ParticleInit {
                    position,
                    velocity: DVec3::ZERO,
                    radius,
                    material: 0,
                };
                particles.push(init, 7950.0);
            }
            let full = pair_geometry(Some(&periodic), &particles, 0, 1);
            let touching = touching_pair_geometry(Some(&periodic), &particles, 0, 1);
            if full.1 > 0.0 {
                let (normal, overlap) = touching.expect("a touching pair");
                assert_eq!(
                    normal.to_array().map(f64::to_bits),
                    full.0.to_array().map(f64::to_bits)
                );
                assert_eq!(overlap.to_bits(), full.1.to_bits());
            } else {
                assert_eq!(touching, None, "case {case}: overlap {:e}", full.1);
            }
            checked[usize::from(full.1 > 0.0)] += 1;
        }
        // Both branches were taken many times, near contact too.
        assert!(checked.iter().all(|&n| n > 1000), "{checked:?}");
    }

    /// A sphere off the plate that still holds the spring of its last contact with it lets
    /// the spring go: its energy is lost and the spring is gone, whether its pair is a wall
    /// candidate or not (a spring is kept until a pass finds its pair apart). The forces stay at
    /// the weights the drift set.
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
        let (model, start) = Model::build(&scene);
        let held = TangentialSpring {
            history: DVec3::new(1e-9, 0.0, 0.0),
            spring_energy: 3e-15,
        };
        for candidates in [
            WallCandidates::every(&model, start.len()),
            WallCandidates::of([(0, 0), (1, 0)]),
            WallCandidates::of([(1, 0)]),
            WallCandidates::of([]),
        ] {
            let mut particles = start.clone();
            let mut rotation = Rotation::new(particles.len(), model.walls.len());
            rotation.wall_springs =
                crate::wall_history::WallSprings::from_entries(particles.len(), [(0, 0, held)]);
            set_weights(&mut particles.force, &particles.mass, model.gravity);
            for _ in 0..2 {
                let summary = wall_pass(&model, &mut particles, &mut rotation, &candidates);
                assert_eq!(summary.max_overlap_ratio, 0.0);
            }
            let keys = candidates.keys().len();
            assert_eq!(particles.dissipated, [held.spring_energy, 0.0], "{keys}");
            assert_eq!(rotation.wall_springs.entries().count(), 0);
            for k in 0..2 {
                assert_eq!(particles.force[k], particles.mass[k] * model.gravity);
                assert_eq!(rotation.torque[k], DVec3::ZERO);
            }
        }
    }

    /// Spheres in a corner of three walls, touching one, two or three of them, some holding
    /// springs of walls they no longer touch: more contacts than one round of lanes holds, and
    /// a particle whose contacts straddle two rounds (particle 19's two contacts are the 32nd
    /// and 33rd). Each particle's force, torque, lost
    /// energy and springs are bitwise what the laws give its walls one at a time, summed in wall
    /// order ([`wall_lanes::wall_step`], the rolling law always evaluated).
    #[test]
    fn wall_contacts_in_lanes_sum_per_particle_in_wall_order() {
        let mut text = plate_scene("").replace(
            "friction_coefficient = 0.5",
            "friction_coefficient = 0.5\nrolling_friction_coefficient = 0.1",
        );
        text += r#"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
material = "m"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "m"
"#;
        let radius = 2e-5;
        let count = 30;
        for k in 0..count {
            // Bit w of (k % 7 + 1) says whether the sphere touches wall w (plate, x, y), by an
            // overlap that grows with k.
            let touching = k % 7 + 1;
            let position = |w: usize, along: f64| {
                if touching >> w & 1 == 1 {
                    radius * (1.0 - 1e-3 * (1.0 + k as f64))
                } else {
                    along
                }
            };
            let far = 2e-4 + 1e-4 * k as f64;
            text += &format!(
                "[[particles]]\nposition_m = [{:e}, {:e}, {:e}]\nvelocity_m_s = [{:e}, {:e}, {:e}]\nradius_m = {radius:e}\nmaterial = \"m\"\n",
                position(1, far),
                position(2, far),
                position(0, far),
                1e-3 * (k as f64 - 15.0),
                -2e-3,
                -1e-3 * (k % 3) as f64,
            );
        }
        let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
        let (model, mut particles) = Model::build(&scene);
        assert_eq!(model.walls.len(), 3);
        let mut rotation = Rotation::new(count, 3);
        for (k, omega) in rotation.angular_velocity.iter_mut().enumerate() {
            *omega = DVec3::new(100.0, -50.0 * (k % 4) as f64, 30.0);
        }
        // A spring on every (particle, wall) of every third particle: touching or not.
        let spring = |k: usize, w: usize| TangentialSpring {
            history: DVec3::new(1e-9, -2e-9, 0.5e-9) * (1.0 + (k + w) as f64),
            spring_energy: 1e-15 * (1.0 + (k * 3 + w) as f64),
        };
        let entries = (0..count)
            .filter(|k| k % 3 == 0)
            .flat_map(|k| (0..3).map(move |w| (k, w, spring(k, w))));
        rotation.wall_springs = crate::wall_history::WallSprings::from_entries(count, entries);
        let before = (rotation.wall_springs.clone(), particles.clone());
        set_weights(&mut particles.force, &particles.mass, model.gravity);
        let every = WallCandidates::every(&model, count);
        wall_pass(&model, &mut particles, &mut rotation, &every);
        let tables = model.friction.as_ref().expect("friction");
        let mut contacts = 0;
        for k in 0..count {
            let (mut force, mut torque, mut lost) = (DVec3::ZERO, DVec3::ZERO, 0.0);
            for w in 0..3 {
                let held = before.0.get(k, w);
                let overlap = wall_overlap(&model, &before.1, k, w);
                if overlap <= 0.0 {
                    lost += held.spring_energy;
                    assert_eq!(rotation.wall_springs.get(k, w), TangentialSpring::default());
                    continue;
                }
                contacts += 1;
                let params = model.wall_params(w, 0);
                let input = wall_lanes::WallInput {
                    overlap,
                    into_domain: model.walls[w].normal,
                    radius,
                    mass: particles.mass[k],
                    velocity: particles.velocity[k],
                    effective_modulus: params.effective_modulus,
                    damping_ratio: params.damping_ratio,
                    angular_velocity: rotation.angular_velocity[k],
                    friction: *tables.wall(w, 0),
                    held,
                };
                let out = wall_lanes::wall_step::<true, true>(model.dt, &input);
                force += out.normal_force * model.walls[w].normal;
                lost += out.damper_lost;
                force += out.tangential_force;
                torque += out.torque;
                lost += out.tangential_lost;
                assert_eq!(
                    rotation.wall_springs.get(k, w),
                    out.spring,
                    "spring ({k}, {w})"
                );
            }
            let weight = particles.mass[k] * model.gravity;
            assert_eq!(particles.force[k], weight + force, "force on {k}");
            assert_eq!(rotation.torque[k], torque, "torque on {k}");
            assert_eq!(particles.dissipated[k], lost, "lost by {k}");
        }
        // Several rounds of lanes.
        assert!(contacts > 3 * lanes::LANES, "{contacts} contacts");
    }

    /// Pairs that came apart while holding tangential springs: the pair pass does not meet
    /// them, finds their springs passed over (before a later contact of the slab) or unmet (at
    /// the end of the slab), and books each spring's energy as lost, half to each particle;
    /// no spring is left. Four spheres in a row, 1 µm apart, then touching, then 1 µm apart;
    /// at rest, so the one contact loses nothing.
    #[test]
    fn springs_of_pairs_that_came_apart_are_lost_half_to_each_particle() {
        let mut text = plate_scene("skin_m = 1e-5");
        for x in [0.0, 4.1e-5, 8e-5, 12.1e-5] {
            text += &format!(
                "[[particles]]\nposition_m = [{x:e}, 0.0, 1e-4]\nradius_m = 2e-5\nmaterial = \"m\"\n"
            );
        }
        let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
        let (model, mut particles) = Model::build(&scene);
        let mut list = NeighborList::new(model.skin, None);
        list.build(&particles.position, &particles.radius);
        let pairs: Vec<_> = list.pairs().collect();
        let slot_of = |a: usize, b: usize| {
            pairs
                .iter()
                .find(|&&(_, o, q)| (o, q) == (a, b) || (o, q) == (b, a))
                .map(|&(p, o, _)| (p, o))
                .expect("the pair is in the list")
        };
        // Both apart pairs hold a spring; the touching pair in between holds none.
        let energies = [3e-15, 5e-15];
        let mut histories = TangentialHistories::new(&list);
        for ((a, b), energy) in [(0, 1), (2, 3)].into_iter().zip(energies) {
            let (p, owner) = slot_of(a, b);
            let spring = TangentialSpring {
                history: DVec3::new(0.0, 1e-9, 0.0),
                spring_energy: energy,
            };
            histories.set(&list, p, owner, spring);
        }
        assert_eq!(histories.entries(), 2);
        let mut rotation = Rotation::new(particles.len(), model.walls.len());
        let mut near = NearPairs::default();
        let mut walls = WallCandidates::default();
        let rotation_pass = PassRotation {
            rotation: &mut rotation,
            histories: &mut histories,
        };
        let _ = compute(
            &model,
            &mut particles,
            &list,
            (&mut near, true),
            &mut walls,
            None,
            Some(rotation_pass),
            None,
            Evaluation::SetUp,
        );
        let half = energies.map(|e| 0.5 * e);
        assert_eq!(particles.dissipated, [half[0], half[0], half[1], half[1]]);
        assert_eq!(histories.entries(), 0);
    }

    /// The wall candidates are the (particle, wall) pairs within the skin at the list's
    /// reference positions (here the skin is 10 µm and the radius 20 µm), taken anew for a new
    /// build only; and the particle pass over them gives bitwise what it gives over every pair.
    #[test]
    fn the_wall_candidates_are_the_pairs_within_the_skin() {
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
        // The model keeps the scene's order; each particle with the wall it is near.
        let pairs = |c: &WallCandidates| -> Vec<(u32, u32)> {
            c.keys()
                .iter()
                .map(|key| (key.particle, key.wall))
                .collect()
        };
        assert_eq!(pairs(&candidates), [(0, 0), (1, 0), (4, 1)]);
        let taking = candidates.taking();
        assert_ne!(taking, 0);
        // The same build: kept, even for other radii; a new build: taken anew (particle 2,
        // now 1 mm across, reaches both walls).
        let grown = [2e-5, 2e-5, 1e-3, 2e-5, 2e-5];
        candidates.refresh(&model, &list, &grown);
        assert_eq!((candidates.keys().len(), candidates.taking()), (3, taking));
        list.build(&particles.position, &particles.radius);
        candidates.refresh(&model, &list, &grown);
        assert_eq!(pairs(&candidates), [(0, 0), (1, 0), (2, 0), (2, 1), (4, 1)]);
        assert_ne!(candidates.taking(), taking);
        // The pass over the candidates and over every pair.
        let pass = |candidates: &WallCandidates| {
            let mut particles = particles.clone();
            let mut rotation = Rotation::new(particles.len(), model.walls.len());
            set_weights(&mut particles.force, &particles.mass, model.gravity);
            let summary = wall_pass(&model, &mut particles, &mut rotation, candidates);
            (
                particles.force,
                particles.dissipated,
                rotation.torque,
                summary,
            )
        };
        candidates.refresh(&model, &NeighborList::default(), &particles.radius);
        assert_eq!(
            (candidates.keys().len(), candidates.taking()),
            (10, 0),
            "no list: every pair, taken at every pass"
        );
        list.build(&particles.position, &particles.radius);
        candidates.refresh(&model, &list, &particles.radius);
        let (all, near) = (
            pass(&WallCandidates::every(&model, particles.len())),
            pass(&candidates),
        );
        assert_eq!(format!("{all:?}"), format!("{near:?}"));
        // The touching sphere got the plate's push.
        assert!(all.0.iter().any(|f| f.z > 0.0));
    }
}
