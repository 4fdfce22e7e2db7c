//! The contact kernel of the pair pass: the laws of [`LANES`] contacts at once.
//!
//! A contact's laws form one long dependency chain of square roots and divisions (distance, unit
//! normal, √(r* δ), the damping's √(m* S), the history's rotation, the Coulomb scale): evaluated
//! one contact after the other, the processor waits on each link, and the pair pass ran at about
//! 200 cycles per contact on the LIGGGHTS bed. Here the contacts a slab's owners find are
//! gathered into lanes (one array per quantity, [`ContactLanes`]) and the laws run over the lanes
//! in one loop with no dependency between iterations, which the compiler turns into vector
//! instructions: two contacts per instruction with the x86-64 baseline (SSE2), four with AVX2,
//! eight with AVX-512. [`run`] takes the widest the processor has (detected at run time: the
//! binary stays built for generic x86-64); on the LIGGGHTS bed the AVX-512 build made the whole
//! step 3.7-5.5 % faster than the AVX2 one.
//!
//! The lanes hold the same numbers and the laws do the same operations in the same order as one
//! contact at a time: vector square roots and divisions round like scalar ones, and Rust never
//! fuses a multiply and an add by itself. The results are therefore bitwise the same whichever
//! instruction set runs (tested for every build the processor runs: `tests` below).
//!
//! The laws are those of `contact` (pure functions of the pair's kinematics and parameters); this
//! module only feeds them. Scenes with bonds use the same code, but the bond law's branches and
//! `powf` keep the compiler from vectorising it: a batch with a lane that is bonded or may bond
//! runs its lanes one after the other. A batch without one (in a powder bed under a laser, nearly
//! every batch: the bond criterion holds only where both particles melted) runs the build without
//! the bond law, vectorised, which gives bitwise the same (the normal law goes straight to its
//! Hertz branch there).

use glam::DVec3;

use crate::bed::rng::SplitMix64;
use crate::contact::tangential::TangentialSpring;
use crate::contact::{
    self, BondState, FrictionParams, NormalParams, PairKinematics, hertz, rolling,
};
use crate::model::Model;
use crate::simd::{InstructionSet, Kernel, dispatch};
use crate::thermal::{self, ConductionModel, PairConductivities, ThermalModel, conduction};

use super::{TangentialContact, tangential_step, unit_normal};

pub(super) use crate::simd::{LANES, Lane};

/// A vector quantity of every lane, one array per component.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Lane3 {
    x: Lane<f64>,
    y: Lane<f64>,
    z: Lane<f64>,
}

impl Lane3 {
    #[inline(always)]
    pub(super) fn get(&self, i: usize) -> DVec3 {
        DVec3::new(self.x[i], self.y[i], self.z[i])
    }

    #[inline(always)]
    pub(super) fn set(&mut self, i: usize, v: DVec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }
}

/// What the laws need of one contact (a touching pair: owner `a`, partner `b`).
#[derive(Debug, Clone, Copy)]
pub(super) struct ContactInput {
    /// `x_b − x_a` (the minimum image) \[m\].
    pub separation: DVec3,
    /// Radii \[m\] and masses \[kg\] of a and b.
    pub radius: [f64; 2],
    pub mass: [f64; 2],
    /// `v_a − v_b` [m/s]: the laws take the two velocities only through it (the overlap rate
    /// δ̇ = (v_a − v_b)·n of section 1, the contact velocity of M.60), so a contact's lane holds
    /// one vector where it held two. On the 19.2k LIGGGHTS bed the fill stores three values
    /// fewer per contact and the kernel loads and subtracts three fewer.
    pub relative_velocity: DVec3,
    /// Normal-law parameters of the material pair, without the bond's (see `materials`).
    pub effective_modulus: f64,
    pub damping_ratio: f64,
    /// The materials of a and b: what the bond parameters are looked up by, with bonds.
    pub materials: [u16; 2],
    /// The pair's bond state before the step, and whether the bond criterion holds (M.12).
    pub state: BondState,
    pub criterion: bool,
    /// With friction: angular velocities [rad/s], the material pair's friction parameters, and
    /// the spring the last pass left.
    pub angular_velocity: [DVec3; 2],
    pub friction: FrictionParams,
    pub held: TangentialSpring,
}

/// What the laws give for one contact over the step.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ContactOutput {
    /// Force on a \[N\] (b receives the opposite).
    pub force_on_a: DVec3,
    /// Energy the contact lost over the step \[J\] (M.35, M.63).
    pub lost: f64,
    /// Overlap δ \[m\].
    pub overlap: f64,
    /// Hertz contact radius `a = √(r* δ)` \[m\] (M.40), which the conduction models take: the
    /// normal law has it at hand, so the write-back takes no square root of its own.
    pub contact_radius: f64,
    /// δ over the smaller radius (the overlap guard's measure).
    pub overlap_ratio: f64,
    /// The bond state after the step.
    pub state: BondState,
    /// With friction: torques on a and b [N·m] and the spring after the step.
    pub torque_on_a: DVec3,
    pub torque_on_b: DVec3,
    pub spring: TangentialSpring,
}

/// What the laws gave one lane, read part by part where the write-back uses it. Read whole
/// ([`ContactLanes::output`]), the parts a pass uses (fourteen with friction) were loaded at
/// once and held across the write-back's stores; read at their use, the write-back of the
/// 19.2k LIGGGHTS bed took 58.5 instructions per particle-step instead of 61.8
/// (docs/performance-log.md, sixty-first round).
#[derive(Clone, Copy)]
pub(super) struct OutputOf<'l> {
    lanes: &'l ContactLanes,
    lane: usize,
}

impl OutputOf<'_> {
    /// Force on a \[N\] (b receives the opposite).
    #[inline(always)]
    pub(super) fn force_on_a(self) -> DVec3 {
        self.lanes.force_on_a.get(self.lane)
    }

    /// Energy the contact lost over the step \[J\] (M.35, M.63).
    #[inline(always)]
    pub(super) fn lost(self) -> f64 {
        self.lanes.lost[self.lane]
    }

    /// δ over the smaller radius (the overlap guard's measure).
    #[inline(always)]
    pub(super) fn overlap_ratio(self) -> f64 {
        self.lanes.overlap_ratio[self.lane]
    }

    /// The bond state after the step.
    #[inline(always)]
    pub(super) fn state(self) -> BondState {
        self.lanes.new_state[self.lane]
    }

    /// With friction: the torques on a and b \[N·m\].
    #[inline(always)]
    pub(super) fn torques(self) -> [DVec3; 2] {
        [
            self.lanes.torque_on_a.get(self.lane),
            self.lanes.torque_on_b.get(self.lane),
        ]
    }

    /// With friction: the tangential spring after the step.
    #[inline(always)]
    pub(super) fn spring(self) -> TangentialSpring {
        TangentialSpring {
            history: self.lanes.spring_history.get(self.lane),
            spring_energy: self.lanes.spring_energy[self.lane],
        }
    }
}

/// Up to [`LANES`] contacts, one array per quantity, and what the laws gave them.
#[derive(Debug, Clone, Default)]
pub(super) struct ContactLanes {
    separation: Lane3,
    radius: [Lane<f64>; 2],
    mass: [Lane<f64>; 2],
    relative_velocity: Lane3,
    effective_modulus: Lane<f64>,
    damping_ratio: Lane<f64>,
    materials: [Lane<u16>; 2],
    state: Lane<BondState>,
    criterion: Lane<bool>,
    angular_velocity: [Lane3; 2],
    shear_modulus: Lane<f64>,
    sliding: Lane<f64>,
    rolling: Lane<f64>,
    held_history: Lane3,
    held_energy: Lane<f64>,
    // Outputs.
    force_on_a: Lane3,
    lost: Lane<f64>,
    overlap: Lane<f64>,
    contact_radius: Lane<f64>,
    overlap_ratio: Lane<f64>,
    new_state: Lane<BondState>,
    torque_on_a: Lane3,
    torque_on_b: Lane3,
    spring_history: Lane3,
    spring_energy: Lane<f64>,
    // With conduction: the material pair's conductivities (input), the contact's conductance
    // [W/K] and that over the smaller mass of the pair [W/(K·kg)] (outputs of
    // `run_conductances`).
    harmonic_conductivity: Lane<f64>,
    conductivity: [Lane<f64>; 2],
    conductance: Lane<f64>,
    conductance_per_mass: Lane<f64>,
    /// Every lane holds the same material parameters, put there by [`Self::for_model`]: the
    /// model has one material (and its conductivities, with a thermal model). [`Self::set`]
    /// and [`Self::set_conductivities`] then leave them.
    uniform_material: bool,
}

/// The parameters of a scene without friction or rolling resistance.
const NO_FRICTION: FrictionParams = FrictionParams {
    effective_shear_modulus: 0.0,
    sliding: 0.0,
    rolling: 0.0,
};

/// What the laws need of a material pair: the normal law's parameters (without the bond's, which
/// the kernel looks up by the materials) and, with friction, the tangential and rolling ones.
#[derive(Debug, Clone, Copy)]
pub(super) struct PairMaterial {
    pub materials: [u16; 2],
    pub effective_modulus: f64,
    pub damping_ratio: f64,
    pub friction: FrictionParams,
}

impl PairMaterial {
    /// The parameters of materials `a` and `b` in `model` (zero friction without friction).
    #[inline(always)]
    pub(super) fn of(model: &Model, a: u16, b: u16) -> Self {
        let params = model.pair_params(a, b);
        Self {
            materials: [a, b],
            effective_modulus: params.effective_modulus,
            damping_ratio: params.damping_ratio,
            friction: model
                .friction
                .as_ref()
                .map_or(NO_FRICTION, |tables| *tables.pair(a, b)),
        }
    }
}

impl ContactLanes {
    /// Empty lanes for the contacts of `model`, with conduction by `thermal` (the pass's
    /// thermal model, with `model`'s materials). With one material, every pair has the same
    /// parameters: the lanes take them here, once, instead of one contact at a time (five
    /// stores per contact and the two materials' loads fewer; with conduction the
    /// conductivities too, three stores and a table look-up).
    pub(super) fn for_model(model: &Model, thermal: Option<&ThermalModel>) -> Self {
        let mut lanes = Self::default();
        if model.materials.len() == 1 {
            let material = PairMaterial::of(model, 0, 0);
            let conductivities = thermal.map(|thermal| thermal.pair_conductivities(0, 0));
            for i in 0..LANES {
                lanes.set_pair_material::<true, true>(i, &material);
                if let Some(k) = conductivities {
                    lanes.put_conductivities(i, k);
                }
            }
            lanes.uniform_material = true;
        }
        lanes
    }

    /// Whether every lane holds the parameters of the model's one material
    /// ([`Self::for_model`]): then no contact needs its own ([`Self::set_pair_material`]).
    #[inline(always)]
    pub(super) fn uniform_material(&self) -> bool {
        self.uniform_material
    }

    /// Puts `input` into lane `i`; what the combination leaves out is not stored, nor are the
    /// material parameters where every lane holds the same (`input` must then carry those).
    /// The pair pass stores the parts one by one as it has them ([`Self::set_pair`],
    /// [`Self::set_pair_material`], [`Self::set_bond`], [`Self::set_angular_velocity`],
    /// [`Self::set_held`]).
    #[inline(always)]
    pub(super) fn set<const BONDS: bool, const FRICTION: bool>(
        &mut self,
        i: usize,
        input: &ContactInput,
    ) {
        self.set_pair(
            i,
            input.separation,
            input.radius,
            input.mass,
            input.relative_velocity,
        );
        if !self.uniform_material {
            self.set_pair_material::<BONDS, FRICTION>(
                i,
                &PairMaterial {
                    materials: input.materials,
                    effective_modulus: input.effective_modulus,
                    damping_ratio: input.damping_ratio,
                    friction: input.friction,
                },
            );
        }
        if BONDS {
            self.set_bond(i, input.state, input.criterion);
        }
        if FRICTION {
            self.set_angular_velocity(i, input.angular_velocity);
            self.set_held(i, input.held);
        }
    }

    /// Puts a pair's geometry and motion into lane `i`: `x_b − x_a` \[m\], the radii \[m\]
    /// and masses \[kg\] of a and b, and `v_a − v_b` \[m/s\]. Stored as soon as the pass has
    /// them, so that they are not held in registers (or spilled) across the spring's look-up.
    #[inline(always)]
    pub(super) fn set_pair(
        &mut self,
        i: usize,
        separation: DVec3,
        radius: [f64; 2],
        mass: [f64; 2],
        relative_velocity: DVec3,
    ) {
        self.separation.set(i, separation);
        for end in 0..2 {
            self.radius[end][i] = radius[end];
            self.mass[end][i] = mass[end];
        }
        self.relative_velocity.set(i, relative_velocity);
    }

    /// Puts a material pair's parameters into lane `i` (not needed where every lane holds the
    /// same, [`Self::uniform_material`]); what the combination leaves out is not stored.
    #[inline(always)]
    pub(super) fn set_pair_material<const BONDS: bool, const FRICTION: bool>(
        &mut self,
        i: usize,
        material: &PairMaterial,
    ) {
        self.effective_modulus[i] = material.effective_modulus;
        self.damping_ratio[i] = material.damping_ratio;
        if BONDS {
            self.materials[0][i] = material.materials[0];
            self.materials[1][i] = material.materials[1];
        }
        if FRICTION {
            self.shear_modulus[i] = material.friction.effective_shear_modulus;
            self.sliding[i] = material.friction.sliding;
            self.rolling[i] = material.friction.rolling;
        }
    }

    /// Puts lane `i`'s bond state before the step and whether the bond criterion holds (M.12).
    #[inline(always)]
    pub(super) fn set_bond(&mut self, i: usize, state: BondState, criterion: bool) {
        self.state[i] = state;
        self.criterion[i] = criterion;
    }

    /// Puts lane `i`'s angular velocities \[rad/s\] of a and b.
    #[inline(always)]
    pub(super) fn set_angular_velocity(&mut self, i: usize, angular_velocity: [DVec3; 2]) {
        for (lane, &omega) in self.angular_velocity.iter_mut().zip(&angular_velocity) {
            lane.set(i, omega);
        }
    }

    /// Puts lane `i`'s spring as the last pass left it. Apart from the angular velocities
    /// ([`Self::set_angular_velocity`]), so that the pair pass stores those before the spring's
    /// look-up and holds no particle index across it.
    #[inline(always)]
    pub(super) fn set_held(&mut self, i: usize, held: TangentialSpring) {
        self.held_history.set(i, held.history);
        self.held_energy[i] = held.spring_energy;
    }

    /// Puts lane `i`'s conductivities ([`thermal::contact_conductance`]), unless every lane
    /// holds the model's one material's ([`Self::uniform_material`]).
    #[inline(always)]
    pub(super) fn set_conductivities(&mut self, i: usize, k: PairConductivities) {
        if !self.uniform_material {
            self.put_conductivities(i, k);
        }
    }

    #[inline(always)]
    fn put_conductivities(&mut self, i: usize, k: PairConductivities) {
        self.harmonic_conductivity[i] = k.harmonic;
        self.conductivity[0][i] = k.each[0];
        self.conductivity[1][i] = k.each[1];
    }

    /// The conductance of lane `i`'s contact [W/K] (after [`Self::run_conductances`]).
    #[inline(always)]
    pub(super) fn conductance(&self, i: usize) -> f64 {
        self.conductance[i]
    }

    /// The conductance of lane `i`'s contact over the smaller mass of its pair, `H / min(m_a,
    /// m_b)` [W/(K·kg)] (after [`Self::run_conductances`]): the largest of these bounds the
    /// step's heat rates (`thermal::HeatRate::at_most`).
    #[inline(always)]
    pub(super) fn conductance_per_mass(&self, i: usize) -> f64 {
        self.conductance_per_mass[i]
    }

    /// Every lane's contact conductance by the conduction model (M.41, M.42, M.79) from what
    /// [`run`] gave it (overlap, contact radius) and its conductivities, with the kernel built
    /// for `set`.
    #[inline]
    pub(super) fn run_conductances(&mut self, set: InstructionSet, conduction: ConductionModel) {
        dispatch(
            set,
            ConductanceKernel {
                conduction,
                lanes: self,
            },
        );
    }

    /// Whether a lane is bonded or its bond criterion holds: only then can the bond law change
    /// its force or state (lanes past the batch's count count too, harmlessly).
    #[inline(always)]
    fn any_bond_law(&self) -> bool {
        self.state
            .iter()
            .zip(&self.criterion)
            .any(|(&state, &criterion)| state == BondState::Bonded || criterion)
    }

    /// Radii of lane `i`'s two particles \[m\].
    #[inline(always)]
    pub(super) fn radii(&self, i: usize) -> [f64; 2] {
        [self.radius[0][i], self.radius[1][i]]
    }

    /// The bond state lane `i` had before the step.
    #[inline(always)]
    pub(super) fn state_before(&self, i: usize) -> BondState {
        self.state[i]
    }

    /// What the laws gave lane `i` (after [`run`]), each part read where it is used
    /// ([`OutputOf`]).
    #[inline(always)]
    pub(super) fn output_of(&self, i: usize) -> OutputOf<'_> {
        OutputOf {
            lanes: self,
            lane: i,
        }
    }

    /// What the laws gave lane `i` (after [`run`]).
    #[inline(always)]
    pub(super) fn output(&self, i: usize) -> ContactOutput {
        // The parts the write-back reads through the view, taken the same way here, so that the
        // kernels' tests, which compare this output bit for bit, check the view's reads too.
        let out = self.output_of(i);
        let [torque_on_a, torque_on_b] = out.torques();
        ContactOutput {
            force_on_a: out.force_on_a(),
            lost: out.lost(),
            overlap: self.overlap[i],
            contact_radius: self.contact_radius[i],
            overlap_ratio: out.overlap_ratio(),
            state: out.state(),
            torque_on_a,
            torque_on_b,
            spring: out.spring(),
        }
    }

    #[inline(always)]
    fn input<const BONDS: bool, const FRICTION: bool>(&self, i: usize) -> ContactInput {
        ContactInput {
            separation: self.separation.get(i),
            radius: [self.radius[0][i], self.radius[1][i]],
            mass: [self.mass[0][i], self.mass[1][i]],
            relative_velocity: self.relative_velocity.get(i),
            effective_modulus: self.effective_modulus[i],
            damping_ratio: self.damping_ratio[i],
            materials: if BONDS {
                [self.materials[0][i], self.materials[1][i]]
            } else {
                [0; 2]
            },
            state: if BONDS {
                self.state[i]
            } else {
                BondState::Unbonded
            },
            criterion: BONDS && self.criterion[i],
            angular_velocity: if FRICTION {
                [
                    self.angular_velocity[0].get(i),
                    self.angular_velocity[1].get(i),
                ]
            } else {
                [DVec3::ZERO; 2]
            },
            friction: FrictionParams {
                effective_shear_modulus: if FRICTION { self.shear_modulus[i] } else { 0.0 },
                sliding: if FRICTION { self.sliding[i] } else { 0.0 },
                rolling: if FRICTION { self.rolling[i] } else { 0.0 },
            },
            held: if FRICTION {
                TangentialSpring {
                    history: self.held_history.get(i),
                    spring_energy: self.held_energy[i],
                }
            } else {
                TangentialSpring::default()
            },
        }
    }

    #[inline(always)]
    fn store<const BONDS: bool, const FRICTION: bool>(&mut self, i: usize, out: &ContactOutput) {
        self.force_on_a.set(i, out.force_on_a);
        self.lost[i] = out.lost;
        self.overlap[i] = out.overlap;
        self.contact_radius[i] = out.contact_radius;
        self.overlap_ratio[i] = out.overlap_ratio;
        if BONDS {
            self.new_state[i] = out.state;
        }
        if FRICTION {
            self.torque_on_a.set(i, out.torque_on_a);
            self.torque_on_b.set(i, out.torque_on_b);
            self.spring_history.set(i, out.spring.history);
            self.spring_energy[i] = out.spring.spring_energy;
        }
    }
}

/// The laws of one touching pair acting over `interval` \[s\] (a step's dt, or 0 at the set-up
/// evaluation, `forces::Evaluation`): the normal law with the bond's branch switch and its
/// energy jump (M.35), and with friction the tangential spring and rolling resistance
/// (M.57–M.63) with lever arms to the middle of the overlap (M.60). Without `ROLLING` the pair
/// must have `μ_r = 0`, whose rolling torque is zero: it is then not evaluated.
#[inline(always)]
pub(super) fn contact_step<const BONDS: bool, const FRICTION: bool, const ROLLING: bool>(
    model: &Model,
    interval: f64,
    input: &ContactInput,
) -> ContactOutput {
    let [r_a, r_b] = input.radius;
    let [m_a, m_b] = input.mass;
    let relative_velocity = input.relative_velocity;
    let distance = input.separation.length_squared().sqrt();
    let normal = unit_normal(input.separation, distance);
    let overlap = r_a + r_b - distance;
    let kinematics = PairKinematics {
        overlap,
        overlap_rate: relative_velocity.dot(normal),
        effective_radius: hertz::effective_radius(r_a, r_b),
        effective_mass: hertz::effective_mass(m_a, m_b),
    };
    let params = NormalParams {
        effective_modulus: input.effective_modulus,
        damping_ratio: input.damping_ratio,
        bond: if BONDS {
            model
                .pair_params(input.materials[0], input.materials[1])
                .bond
        } else {
            None
        },
    };
    let outcome = contact::normal_force(&params, &kinematics, input.state, input.criterion);
    // (M.35): damper work over the step, at the half-step velocity the force used.
    let mut lost = interval * (outcome.force - outcome.elastic) * kinematics.overlap_rate;
    if BONDS && outcome.state != input.state {
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
    }
    let mut out = ContactOutput {
        force_on_a: -outcome.force * normal,
        lost,
        overlap,
        // The same operations as the Hertz force's √(r* δ), which the compiler shares with it.
        contact_radius: conduction::contact_radius(kinematics.effective_radius, overlap),
        overlap_ratio: overlap / r_a.min(r_b),
        state: outcome.state,
        ..ContactOutput::default()
    };
    if FRICTION {
        let [omega_a, omega_b] = input.angular_velocity;
        let friction = &input.friction;
        let arm_a = r_a - 0.5 * overlap;
        let arm_b = r_b - 0.5 * overlap;
        let contact = TangentialContact {
            normal,
            contact_velocity: relative_velocity + (arm_a * omega_a + arm_b * omega_b).cross(normal),
            relative_angular_velocity: omega_a - omega_b,
            // Only the rolling law needs it.
            inverse_inertia_sum: if ROLLING && friction.rolling > 0.0 {
                1.0 / rolling::sphere_inertia(m_a, r_a) + 1.0 / rolling::sphere_inertia(m_b, r_b)
            } else {
                0.0
            },
            normal_force: outcome.force,
            elastic_normal_force: outcome.elastic,
            bonded: outcome.state == BondState::Bonded,
        };
        let step = tangential_step::<ROLLING>(
            friction,
            params.damping_ratio,
            interval,
            &kinematics,
            &contact,
            input.held,
        );
        out.force_on_a += step.force;
        out.lost += step.lost;
        let lever = normal.cross(step.force);
        out.torque_on_a = arm_a * lever + step.rolling_torque;
        out.torque_on_b = arm_b * lever - step.rolling_torque;
        out.spring = step.spring;
    }
    out
}

/// The laws over every lane (those past the batch's count hold stale inputs, which cost the same
/// and whose results nobody reads), compiled for each build by [`dispatch`].
struct PairKernel<'a, const BONDS: bool, const FRICTION: bool, const ROLLING: bool> {
    model: &'a Model,
    interval: f64,
    lanes: &'a mut ContactLanes,
}

impl<const BONDS: bool, const FRICTION: bool, const ROLLING: bool> Kernel
    for PairKernel<'_, BONDS, FRICTION, ROLLING>
{
    #[inline(always)]
    fn run(self) {
        for i in 0..LANES {
            let input = self.lanes.input::<BONDS, FRICTION>(i);
            let out = contact_step::<BONDS, FRICTION, ROLLING>(self.model, self.interval, &input);
            self.lanes.store::<BONDS, FRICTION>(i, &out);
        }
    }
}

/// [`thermal::contact_conductance`] over every lane (those past the batch's count hold stale
/// inputs, whose results nobody reads), one loop per conduction model: the model's `match`
/// stays outside the lanes, and the overlap-area model's division and square root run on
/// vectors. Per contact of the 19.2k heat bed, the write-back had spent about 9 instructions on
/// the `match` (a jump table), 12 on the conductivity table and 30 on the intersection radius.
struct ConductanceKernel<'a> {
    conduction: ConductionModel,
    lanes: &'a mut ContactLanes,
}

impl ConductanceKernel<'_> {
    /// Every lane's conductance by `conduction`, a constant in each of [`Kernel::run`]'s arms.
    #[inline(always)]
    fn fill(self, conduction: ConductionModel) {
        let lanes = self.lanes;
        for i in 0..LANES {
            let k = PairConductivities {
                harmonic: lanes.harmonic_conductivity[i],
                each: [lanes.conductivity[0][i], lanes.conductivity[1][i]],
            };
            let conductance = thermal::contact_conductance(
                conduction,
                k,
                [lanes.radius[0][i], lanes.radius[1][i]],
                lanes.overlap[i],
                lanes.contact_radius[i],
            );
            lanes.conductance[i] = conductance;
            // On vectors here, with the conductance: the write-back takes only the largest.
            // (`<` rather than `f64::min`, which orders NaN with more instructions: no mass is
            // NaN.)
            let [m_a, m_b] = [lanes.mass[0][i], lanes.mass[1][i]];
            lanes.conductance_per_mass[i] = conductance / if m_a < m_b { m_a } else { m_b };
        }
    }
}

impl Kernel for ConductanceKernel<'_> {
    #[inline(always)]
    fn run(self) {
        match self.conduction {
            ConductionModel::None => self.fill(ConductionModel::None),
            ConductionModel::BatchelorObrien => self.fill(ConductionModel::BatchelorObrien),
            ConductionModel::OverlapArea => self.fill(ConductionModel::OverlapArea),
            ConductionModel::ThermalPipe => self.fill(ConductionModel::ThermalPipe),
        }
    }
}

/// Runs the laws over every lane with the kernel built for `set`, the contacts acting over
/// `interval` \[s\].
#[inline]
pub(super) fn run<const BONDS: bool, const FRICTION: bool>(
    set: InstructionSet,
    model: &Model,
    interval: f64,
    lanes: &mut ContactLanes,
) {
    // In a vector kernel every lane evaluates the rolling law (a square root and four
    // divisions), even where μ_r = 0; a batch without rolling resistance skips it.
    let rolling = FRICTION && lanes.rolling.iter().any(|&coefficient| coefficient != 0.0);
    if BONDS && !lanes.any_bond_law() {
        // No lane is bonded or may bond: `contact::normal_force` would take the Hertz branch
        // in every lane and keep every state unbonded, which the build without bonds does
        // with the same operations, vectorised.
        run_build::<false, FRICTION>(set, model, interval, lanes, rolling);
        lanes.new_state = [BondState::Unbonded; LANES];
    } else {
        run_build::<BONDS, FRICTION>(set, model, interval, lanes, rolling);
    }
}

/// [`run`] for one combination, with the rolling law if `rolling`.
#[inline]
fn run_build<const BONDS: bool, const FRICTION: bool>(
    set: InstructionSet,
    model: &Model,
    interval: f64,
    lanes: &mut ContactLanes,
    rolling: bool,
) {
    if rolling {
        dispatch(
            set,
            PairKernel::<BONDS, FRICTION, true> {
                model,
                interval,
                lanes,
            },
        );
    } else {
        dispatch(
            set,
            PairKernel::<BONDS, FRICTION, false> {
                model,
                interval,
                lanes,
            },
        );
    }
}

/// The step's contact kernel on a fixed set of contacts, for `benches/pair_kernel.rs`: the lanes
/// filled [`LANES`] contacts at a time as the pair pass fills them, the laws run over them, and
/// their results read back. Not part of the simulator's interface.
#[doc(hidden)]
#[derive(Debug)]
pub struct KernelBench {
    model: Model,
    inputs: Vec<ContactInput>,
    lanes: ContactLanes,
    set: InstructionSet,
}

impl KernelBench {
    /// `count` contacts between spheres of `radius` \[m\] of the model's first material (with
    /// the model's friction, if any), spread over what a settled bed holds: overlaps up to
    /// 0.1 % of the radius, speeds up to 1 mm/s, spins up to 100 rad/s, and tangential springs
    /// from none to twice the Coulomb limit (so that some lanes slide). `build`: the kernel's
    /// build, `baseline`, `avx2` or `avx512`; `None` if this processor does not run it.
    #[must_use]
    pub fn new(model: Model, radius: f64, count: usize, build: &str) -> Option<Self> {
        let set = InstructionSet::available()
            .into_iter()
            .find(|set| set.name() == build)?;
        let material = PairMaterial::of(&model, 0, 0);
        let mass = model.materials[0].density * 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3);
        let mut random = SplitMix64(0x9e37_79b9_7f4a_7c15);
        let vector = |random: &mut SplitMix64, scale: f64| {
            DVec3::new(random.symmetric(), random.symmetric(), random.symmetric()) * scale
        };
        let inputs = (0..count)
            .map(|_| {
                let overlap = 1e-3 * radius * (0.05 + 0.95 * random.unit());
                let normal = vector(&mut random, 1.0).normalize_or(DVec3::Z);
                // The Coulomb limit's spring length, μ F_n / k_t = μ (E*/6G*) δ (M.57, M.59).
                let limit = material.friction.sliding * material.effective_modulus
                    / (6.0
                        * material
                            .friction
                            .effective_shear_modulus
                            .max(f64::MIN_POSITIVE))
                    * overlap;
                let history = vector(&mut random, 1.0) * (2.0 * limit * random.unit());
                ContactInput {
                    separation: normal * (2.0 * radius - overlap),
                    radius: [radius; 2],
                    mass: [mass; 2],
                    relative_velocity: vector(&mut random, 1e-3) - vector(&mut random, 1e-3),
                    effective_modulus: material.effective_modulus,
                    damping_ratio: material.damping_ratio,
                    materials: material.materials,
                    state: BondState::Unbonded,
                    criterion: false,
                    angular_velocity: [vector(&mut random, 100.0), vector(&mut random, 100.0)],
                    friction: material.friction,
                    held: TangentialSpring {
                        history: history - history.dot(normal) * normal,
                        spring_energy: 0.0,
                    },
                }
            })
            .collect();
        Some(Self {
            lanes: ContactLanes::for_model(&model, model.thermal.as_ref()),
            model,
            inputs,
            set,
        })
    }

    /// Number of contacts.
    #[must_use]
    pub fn len(&self) -> usize {
        self.inputs.len()
    }

    /// Whether there are no contacts.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty()
    }

    /// Runs the kernel over every contact and returns the sum of the forces' x components (so
    /// that nothing is left out as unused).
    pub fn run(&mut self) -> f64 {
        let friction = self.model.friction.is_some();
        let mut sum = 0.0;
        for batch in self.inputs.chunks(LANES) {
            for (i, input) in batch.iter().enumerate() {
                if friction {
                    self.lanes.set::<false, true>(i, input);
                } else {
                    self.lanes.set::<false, false>(i, input);
                }
            }
            if friction {
                run::<false, true>(self.set, &self.model, self.model.dt, &mut self.lanes);
            } else {
                run::<false, false>(self.set, &self.model, self.model.dt, &mut self.lanes);
            }
            sum += (0..batch.len())
                .map(|i| self.lanes.output(i).force_on_a.x)
                .sum::<f64>();
        }
        sum
    }
}

#[cfg(test)]
pub(in crate::forces) mod tests {
    use super::*;
    use crate::contact::BondParams;
    use crate::scene::Scene;
    use crate::study::scenes::{PAPER_E_STAR, PAPER_RADIUS, paper_sphere_mass, two_spheres_text};

    /// A model of the paper's spheres (r = 1 mm, E* = 0.5 GPa), with a bond law whose criterion
    /// always holds: what the kernel reads of the model is `dt` and the bond parameters.
    fn model() -> Model {
        let bond = BondParams {
            adhesion_exponent: 1.0,
            adhesion_stiffness: 0.1,
            damping_ratio: 0.3,
        };
        let text = two_spheres_text(
            8000.0,
            2.0 * PAPER_RADIUS,
            0.1,
            0.2,
            Some((bond, "always")),
            1e-7,
            1e-6,
        );
        let scene = Scene::from_toml(&text).expect("the study's scene");
        Model::build(&scene).0
    }

    /// A deterministic spread of contacts: overlaps from grazing to 2 % of the radius, approach
    /// and separation, springs from none to far past the Coulomb limit (so that some lanes stick
    /// and some slide), spins with and without rolling resistance, both bond states.
    fn inputs(count: usize) -> Vec<ContactInput> {
        struct Xorshift(u64);
        impl Xorshift {
            fn uniform(&mut self) -> f64 {
                self.0 ^= self.0 << 13;
                self.0 ^= self.0 >> 7;
                self.0 ^= self.0 << 17;
                (self.0 >> 11) as f64 / (1u64 << 53) as f64
            }
            fn vector(&mut self, scale: f64) -> DVec3 {
                DVec3::new(self.uniform(), self.uniform(), self.uniform()) * scale
                    - DVec3::splat(0.5 * scale)
            }
        }
        let mut random = Xorshift(0x9e37_79b9_7f4a_7c15);
        let mass = paper_sphere_mass(8000.0);
        (0..count)
            .map(|k| {
                let radius = [PAPER_RADIUS * (0.8 + 0.4 * random.uniform()), PAPER_RADIUS];
                let overlap = 0.02 * PAPER_RADIUS * random.uniform();
                let direction = random.vector(1.0).normalize();
                ContactInput {
                    separation: direction * (radius[0] + radius[1] - overlap),
                    radius,
                    mass: [mass * (0.5 + random.uniform()), mass],
                    relative_velocity: random.vector(0.2) - random.vector(0.2),
                    effective_modulus: PAPER_E_STAR,
                    damping_ratio: 0.2,
                    materials: [0, 0],
                    // Of every three batches, one has bonded lanes (without the criterion),
                    // one lanes that may bond (the criterion holds) but none bonded, and one
                    // no lane that is bonded or may bond, which the kernel runs without the
                    // bond law.
                    state: if k % 3 == 0 && (k / LANES) % 3 == 0 {
                        BondState::Bonded
                    } else {
                        BondState::Unbonded
                    },
                    criterion: k % 2 == 0 && (k / LANES) % 3 == 2,
                    angular_velocity: [random.vector(300.0), random.vector(300.0)],
                    friction: friction_of(k),
                    held: TangentialSpring {
                        history: random.vector(held_scale(k)),
                        spring_energy: 1e-9 * random.uniform(),
                    },
                }
            })
            .collect()
    }

    /// The friction parameters of test contact `k` (of the paper's material): every fifth
    /// without sliding friction, every other batch of [`LANES`] without rolling resistance,
    /// which the kernels skip.
    pub(in crate::forces) fn friction_of(k: usize) -> FrictionParams {
        FrictionParams {
            effective_shear_modulus: 0.4 * PAPER_E_STAR,
            sliding: if k % 5 == 0 { 0.0 } else { 0.5 },
            rolling: if k % 4 == 0 || (k / LANES) % 2 == 0 {
                0.0
            } else {
                0.1
            },
        }
    }

    /// The size of test contact `k`'s held spring \[m\]: within the Coulomb limit for four of
    /// every seven, far past it for the others (so that some lanes stick and some slide).
    pub(in crate::forces) fn held_scale(k: usize) -> f64 {
        if k % 7 < 4 { 1e-7 } else { 1e-4 }
    }

    /// What a kernel test must have covered: with friction, lanes that slid and lanes that
    /// stuck; and among its `batches`, some with rolling resistance and some without, so that
    /// both kernels, with and without the rolling law, ran.
    pub(in crate::forces) fn assert_both_kinds<const FRICTION: bool>(
        (sliding, sticking): (usize, usize),
        rolling: usize,
        batches: usize,
    ) {
        if FRICTION {
            assert!(
                sliding > 0 && sticking > 0,
                "{sliding} sliding, {sticking} sticking"
            );
        }
        assert!(
            rolling > 0 && rolling < batches,
            "{rolling} of {batches} batches with rolling resistance"
        );
    }

    fn bits(out: &ContactOutput) -> Vec<u64> {
        let vectors = [
            out.force_on_a,
            out.torque_on_a,
            out.torque_on_b,
            out.spring.history,
        ];
        let scalars = [
            out.lost,
            out.overlap,
            out.contact_radius,
            out.overlap_ratio,
            out.spring.spring_energy,
            f64::from(u8::from(out.state == BondState::Bonded)),
        ];
        vectors
            .iter()
            .flat_map(|v| v.to_array())
            .chain(scalars)
            .map(f64::to_bits)
            .collect()
    }

    /// With one material, the lanes take its parameters once and [`ContactLanes::set`] leaves
    /// them: the kernel then gives bitwise what lanes filled contact by contact give. With two
    /// materials, the lanes hold none in advance.
    #[test]
    fn lanes_of_a_one_material_model_hold_its_parameters() {
        let text = two_spheres_text(8000.0, 2.0 * PAPER_RADIUS, 0.1, 0.2, None, 1e-7, 1e-6)
            .replace(
                "model = \"hertz\"",
                "model = \"hertz\"\nfriction_coefficient = 0.5\nrolling_friction_coefficient = 0.1",
            );
        let model = Model::build(&Scene::from_toml(&text).expect("the test's scene")).0;
        let material = PairMaterial::of(&model, 0, 0);
        assert_eq!(
            (material.friction.sliding, material.friction.rolling),
            (0.5, 0.1)
        );
        let mut uniform = ContactLanes::for_model(&model, model.thermal.as_ref());
        assert!(uniform.uniform_material());
        let mut per_contact = ContactLanes::default();
        for (i, mut input) in inputs(LANES).into_iter().enumerate() {
            input.effective_modulus = material.effective_modulus;
            input.damping_ratio = material.damping_ratio;
            input.materials = material.materials;
            input.friction = material.friction;
            per_contact.set::<false, true>(i, &input);
            uniform.set::<false, true>(i, &input);
        }
        let set = InstructionSet::detect();
        run::<false, true>(set, &model, model.dt, &mut per_contact);
        run::<false, true>(set, &model, model.dt, &mut uniform);
        for i in 0..LANES {
            assert_eq!(
                bits(&uniform.output(i)),
                bits(&per_contact.output(i)),
                "lane {i}"
            );
        }
        let two = text.replace(
            "[contact]",
            "[materials.other]\ndensity_kg_m3 = 5000.0\nyoungs_modulus_pa = 3e9\npoisson_ratio = 0.2\n[contact]",
        );
        let model = Model::build(&Scene::from_toml(&two).expect("the test's scene")).0;
        assert_eq!(model.materials.len(), 2);
        assert!(!ContactLanes::for_model(&model, model.thermal.as_ref()).uniform_material());
    }

    /// Every build of the conductance kernel gives bitwise what [`thermal::contact_conductance`]
    /// gives one contact at a time, for every conduction model, with each lane's own
    /// conductivities (two materials of different k) and a lane whose spheres are apart (0).
    #[test]
    fn conductances_of_every_build_are_those_of_one_contact() {
        let model = model();
        let mut inputs = inputs(LANES);
        // Lane 3 apart by 1 % of the radii: its overlap is negative.
        let apart = inputs[3].radius[0] + inputs[3].radius[1];
        inputs[3].separation = inputs[3].separation.normalize() * (1.01 * apart);
        let conductivities = |i: usize| {
            let [ka, kb] = [16.0 + i as f64, if i % 2 == 0 { 20.0 } else { 400.0 }];
            PairConductivities {
                harmonic: 2.0 * ka * kb / (ka + kb),
                each: [ka, kb],
            }
        };
        for conduction in [
            ConductionModel::None,
            ConductionModel::BatchelorObrien,
            ConductionModel::OverlapArea,
            ConductionModel::ThermalPipe,
        ] {
            for set in InstructionSet::available() {
                let mut lanes = ContactLanes::default();
                for (i, input) in inputs.iter().enumerate() {
                    lanes.set::<false, false>(i, input);
                    lanes.set_conductivities(i, conductivities(i));
                }
                run::<false, false>(set, &model, model.dt, &mut lanes);
                lanes.run_conductances(set, conduction);
                for i in 0..LANES {
                    let out = lanes.output(i);
                    let expected = thermal::contact_conductance(
                        std::hint::black_box(conduction),
                        conductivities(i),
                        lanes.radii(i),
                        out.overlap,
                        out.contact_radius,
                    );
                    let got = lanes.conductance(i);
                    assert_eq!(
                        got.to_bits(),
                        expected.to_bits(),
                        "{conduction:?}, {set:?}, lane {i}"
                    );
                    // Apart or without conduction nothing flows; otherwise every lane conducts.
                    let touching = i != 3;
                    assert_eq!(
                        got > 0.0,
                        touching && conduction != ConductionModel::None,
                        "{conduction:?}, {set:?}, lane {i}: {got}"
                    );
                }
            }
        }
    }

    /// With one material, the lanes take its conductivities from the pass's thermal model once
    /// and [`ContactLanes::set_conductivities`] leaves them: the conductances are those of the
    /// material pair (0, 0), whatever a contact would have put.
    #[test]
    fn lanes_of_a_one_material_model_hold_its_conductivities() {
        let model = model();
        assert_eq!(model.materials.len(), 1);
        let thermal = ThermalModel::bare(
            vec![thermal::ThermalMaterial {
                specific_heat: 500.0,
                conductivity: 17.0,
                melting_point: 1700.0,
                latent_heat: 2.7e5,
                emissivity: 0.4,
                absorptivity: 0.6,
                vaporization: None,
            }],
            ConductionModel::OverlapArea,
        );
        let k = thermal.pair_conductivities(0, 0);
        assert_eq!((k.harmonic, k.each), (17.0, [17.0, 17.0]));
        let set = InstructionSet::detect();
        let mut lanes = ContactLanes::for_model(&model, Some(&thermal));
        assert!(lanes.uniform_material());
        for (i, input) in inputs(LANES).iter().enumerate() {
            lanes.set::<false, false>(i, input);
            lanes.set_conductivities(
                i,
                PairConductivities {
                    harmonic: 1.0,
                    each: [1.0, 1.0],
                },
            );
        }
        run::<false, false>(set, &model, model.dt, &mut lanes);
        lanes.run_conductances(set, thermal.conduction);
        for i in 0..LANES {
            let out = lanes.output(i);
            let expected = thermal::pair_conductance(
                &thermal,
                [0, 0],
                lanes.radii(i),
                out.overlap,
                out.contact_radius,
            );
            assert!(expected > 0.0, "lane {i}");
            assert_eq!(
                lanes.conductance(i).to_bits(),
                expected.to_bits(),
                "lane {i}"
            );
        }
    }

    /// Every build of the kernel gives bitwise what the laws give one contact at a time.
    fn check<const BONDS: bool, const FRICTION: bool>(model: &Model) {
        let inputs = inputs(16 * LANES);
        let (mut sliding, mut sticking, mut switched, mut rolling) = (0, 0, 0, 0);
        let mut bond_law = 0;
        // One set of lanes per build this processor runs, each reused from batch to batch.
        let sets = InstructionSet::available();
        let mut reused = vec![ContactLanes::default(); sets.len()];
        for batch in inputs.chunks(LANES) {
            rolling += usize::from(batch.iter().any(|input| input.friction.rolling != 0.0));
            bond_law += usize::from(
                batch
                    .iter()
                    .any(|input| input.state == BondState::Bonded || input.criterion),
            );
            let one_by_one: Vec<ContactOutput> = batch
                .iter()
                .map(|input| {
                    contact_step::<BONDS, FRICTION, true>(
                        model,
                        model.dt,
                        std::hint::black_box(input),
                    )
                })
                .collect();
            // The lanes are reused from batch to batch, as the pair pass does: what one batch
            // left in them must not leak into the next.
            for (&set, lanes) in sets.iter().zip(&mut reused) {
                for (i, input) in batch.iter().enumerate() {
                    lanes.set::<BONDS, FRICTION>(i, input);
                }
                run::<BONDS, FRICTION>(set, model, model.dt, lanes);
                for (i, expected) in one_by_one.iter().enumerate() {
                    assert_eq!(bits(&lanes.output(i)), bits(expected), "{set:?}, lane {i}");
                }
            }
            for (input, out) in batch.iter().zip(&one_by_one) {
                let held = input.held.history.length();
                let kept = out.spring.history.length();
                if FRICTION && input.friction.sliding > 0.0 && out.state == BondState::Unbonded {
                    // A sliding spring is cut back to the Coulomb limit, here by far more than
                    // the step's v_t dt can change its length.
                    if kept < 0.9 * held {
                        sliding += 1;
                    } else {
                        sticking += 1;
                    }
                }
                switched += usize::from(BONDS && out.state != input.state);
            }
        }
        assert_both_kinds::<FRICTION>((sliding, sticking), rolling, inputs.len() / LANES);
        if BONDS {
            assert!(switched > 0, "no bond formed or broke");
            // Both kernels, with and without the bond law, ran.
            assert!(
                bond_law > 0 && bond_law < inputs.len() / LANES,
                "{bond_law} batches with the bond law"
            );
        }
    }

    /// The benchmark's contacts go through the laws: its sum is the laws' forces', batch by
    /// batch, and its spread of springs has lanes that stick and lanes that slide.
    #[test]
    fn the_kernel_bench_runs_the_laws_on_sticking_and_sliding_contacts() {
        let text = two_spheres_text(8000.0, 2.0 * PAPER_RADIUS, 0.1, 0.2, None, 1e-7, 1e-6)
            .replace(
                "model = \"hertz\"",
                "model = \"hertz\"\nfriction_coefficient = 0.5",
            );
        let model = Model::build(&Scene::from_toml(&text).expect("the test's scene")).0;
        let count = 10 * LANES + 3;
        let mut bench = KernelBench::new(model.clone(), PAPER_RADIUS, count, "baseline")
            .expect("the baseline runs everywhere");
        assert_eq!(bench.len(), count);
        let (mut expected, mut sliding, mut sticking) = (0.0, 0, 0);
        for batch in bench.inputs.chunks(LANES) {
            let outputs = batch
                .iter()
                .map(|input| contact_step::<false, true, false>(&model, model.dt, input));
            let mut batch_sum = 0.0;
            for (input, out) in batch.iter().zip(outputs) {
                batch_sum += out.force_on_a.x;
                // A sliding spring is cut back to the Coulomb limit, for most of these springs
                // by far more than the step's v_t dt (below 1e-8 m) can change its length.
                if out.spring.history.length() < 0.9 * input.held.history.length() {
                    sliding += 1;
                } else {
                    sticking += 1;
                }
            }
            expected += batch_sum;
        }
        assert_eq!(bench.run().to_bits(), expected.to_bits());
        assert!(
            sliding > 0 && sticking > 0,
            "{sliding} sliding, {sticking} sticking"
        );
    }

    #[test]
    fn every_build_of_the_kernel_matches_the_laws_bitwise() {
        let model = model();
        assert!(model.pair_params(0, 0).bond.is_some());
        check::<false, false>(&model);
        check::<false, true>(&model);
        check::<true, false>(&model);
        check::<true, true>(&model);
    }
}
