//! The wall kernel: the laws of up to [`LANES`] particle–wall contacts at once, as
//! [`super::lanes`] runs those of pairs.
//!
//! A wall contact's laws are the same chain of square roots and divisions as a pair's (√(r δ),
//! the damping's √(m k), the tangential spring's and the history's), and on a layer spread on a
//! plate nearly half the particles touch it (`scenes/bed.toml`: 4,565 wall contacts for 10,181
//! particles at the end of the run). One contact after the other, the particle pass took a
//! quarter of that scene's run; here the contacts of a chunk of particles are gathered into
//! lanes and the laws run over them in one loop, which the compiler vectorises. The lanes hold
//! the same numbers and the laws do the same operations in the same order as one contact at a
//! time, so every build gives bitwise the same (tested below), and so does the pass that wrote
//! each contact out one by one.

use glam::DVec3;

use super::lanes::{LANES, Lane, Lane3};
use super::{TangentialContact, tangential_step};
use crate::contact::tangential::TangentialSpring;
use crate::contact::{self, FrictionParams, PairKinematics, rolling};
use crate::model::Model;
use crate::simd::{InstructionSet, Kernel, dispatch};

/// What the laws need of one particle touching one plane wall.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct WallInput {
    /// Overlap δ = r − (x − p)·n > 0 \[m\].
    pub overlap: f64,
    /// The wall's unit normal n, into the domain.
    pub into_domain: DVec3,
    /// The particle's radius \[m\], mass \[kg\] and velocity \[m/s\]: a fixed plane is the limit
    /// r_j, m_j → ∞ of a pair, so r* = r and m* = m.
    pub radius: f64,
    pub mass: f64,
    pub velocity: DVec3,
    /// Normal-law parameters of the wall and the particle's material.
    pub effective_modulus: f64,
    pub damping_ratio: f64,
    /// With friction: the particle's angular velocity [rad/s], the friction parameters of the
    /// wall and its material, and the spring the last pass left.
    pub angular_velocity: DVec3,
    pub friction: FrictionParams,
    pub held: TangentialSpring,
}

/// What the laws give one wall contact over the step, in the parts the pass adds one after the
/// other (so that each particle's sums are formed in the same order as ever).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct WallOutput {
    /// Normal force along `into_domain` \[N\] (positive: pushes the particle off the wall).
    pub normal_force: f64,
    /// The wall's damper work over the step \[J\] (M.35).
    pub damper_lost: f64,
    /// With friction: tangential force \[N\] and torque [N·m] on the particle, the energy the
    /// tangential and rolling laws took \[J\] (M.63), and the spring after the step.
    pub tangential_force: DVec3,
    pub torque: DVec3,
    pub tangential_lost: f64,
    pub spring: TangentialSpring,
}

/// The laws of one particle touching one plane wall over one step: Hertz with viscous damping
/// (eq. 26, M.10) with r* = r and m* = m, the damper's work (M.35), and with `FRICTION` the
/// tangential spring and rolling resistance (M.57–M.63), the particle the first body and the
/// wall the second, with the lever arm to the middle of the overlap (M.60). Without `ROLLING`
/// the contact must have `μ_r = 0`, whose rolling torque is zero: it is then not evaluated.
#[inline(always)]
#[must_use]
pub(super) fn wall_step<const FRICTION: bool, const ROLLING: bool>(
    dt: f64,
    input: &WallInput,
) -> WallOutput {
    let kinematics = PairKinematics {
        overlap: input.overlap,
        overlap_rate: -input.velocity.dot(input.into_domain),
        effective_radius: input.radius,
        effective_mass: input.mass,
    };
    let (normal_force, elastic) =
        contact::hertz_parts(input.effective_modulus, input.damping_ratio, &kinematics);
    let mut out = WallOutput {
        normal_force,
        damper_lost: dt * (normal_force - elastic) * kinematics.overlap_rate,
        ..WallOutput::default()
    };
    if FRICTION {
        // The particle is the first body, the wall the second: the normal points into the wall.
        let normal = -input.into_domain;
        let arm = input.radius - 0.5 * input.overlap;
        let omega = input.angular_velocity;
        let contact = TangentialContact {
            normal,
            contact_velocity: input.velocity + (arm * omega).cross(normal),
            relative_angular_velocity: omega,
            // Only the rolling law needs it.
            inverse_inertia_sum: if ROLLING && input.friction.rolling > 0.0 {
                1.0 / rolling::sphere_inertia(input.mass, input.radius)
            } else {
                0.0
            },
            normal_force,
            elastic_normal_force: elastic,
            bonded: false,
        };
        let step = tangential_step::<ROLLING>(
            &input.friction,
            input.damping_ratio,
            dt,
            &kinematics,
            &contact,
            input.held,
        );
        out.tangential_force = step.force;
        out.torque = arm * normal.cross(step.force) + step.rolling_torque;
        out.tangential_lost = step.lost;
        out.spring = step.spring;
    }
    out
}

/// The friction parameters of wall `wall` and a particle of `material` in `model` (zero
/// without friction).
#[inline(always)]
pub(super) fn wall_friction(model: &Model, wall: usize, material: u16) -> FrictionParams {
    model
        .friction
        .as_ref()
        .map_or(FrictionParams::default(), |tables| {
            *tables.wall(wall, material)
        })
}

/// Up to [`LANES`] wall contacts, one array per quantity, and what the laws gave them.
#[derive(Debug, Clone, Default)]
pub(super) struct WallLanes {
    overlap: Lane<f64>,
    into_domain: Lane3,
    radius: Lane<f64>,
    mass: Lane<f64>,
    velocity: Lane3,
    effective_modulus: Lane<f64>,
    damping_ratio: Lane<f64>,
    angular_velocity: Lane3,
    shear_modulus: Lane<f64>,
    sliding: Lane<f64>,
    rolling: Lane<f64>,
    held_history: Lane3,
    held_energy: Lane<f64>,
    normal_force: Lane<f64>,
    damper_lost: Lane<f64>,
    tangential_force: Lane3,
    torque: Lane3,
    tangential_lost: Lane<f64>,
    spring_history: Lane3,
    spring_energy: Lane<f64>,
    /// Every lane holds the same wall (its normal) and the same parameters, put there by
    /// [`Self::for_model`]: the model has one wall and one material.
    uniform_wall: bool,
}

impl WallLanes {
    /// Empty lanes for the wall contacts of `model`. With one wall and one material every
    /// contact has the same normal and parameters: the lanes take them here, once, instead of
    /// one contact at a time (eight stores per contact, and the tables' look-ups, fewer).
    pub(super) fn for_model(model: &Model) -> Self {
        let mut lanes = Self::default();
        if model.walls.len() == 1 && model.materials.len() == 1 {
            for i in 0..LANES {
                lanes.set_model_wall::<true>(i, model, 0, 0);
            }
            lanes.uniform_wall = true;
        }
        lanes
    }

    /// Puts wall `wall` of `model`, touched by a particle of `material`, into lane `i`
    /// ([`Self::set_wall`] with the model's normal and parameters).
    #[inline(always)]
    pub(super) fn set_model_wall<const FRICTION: bool>(
        &mut self,
        i: usize,
        model: &Model,
        wall: usize,
        material: u16,
    ) {
        let params = model.wall_params(wall, material);
        self.set_wall::<FRICTION>(
            i,
            model.walls[wall].normal,
            [params.effective_modulus, params.damping_ratio],
            &wall_friction(model, wall, material),
        );
    }

    /// Whether every lane holds the model's one wall and its parameters ([`Self::for_model`]):
    /// then no contact needs its own ([`Self::set_wall`]).
    #[inline(always)]
    pub(super) fn uniform_wall(&self) -> bool {
        self.uniform_wall
    }

    /// Puts `input` into lane `i` (its wall and parameters too, even where every lane holds
    /// the same).
    #[cfg(test)]
    #[inline(always)]
    pub(super) fn set<const FRICTION: bool>(&mut self, i: usize, input: &WallInput) {
        self.set_wall::<FRICTION>(
            i,
            input.into_domain,
            [input.effective_modulus, input.damping_ratio],
            &input.friction,
        );
        self.set_motion::<FRICTION>(
            i,
            input.overlap,
            [input.radius, input.mass],
            [input.velocity, input.angular_velocity],
            input.held,
        );
    }

    /// Puts the wall of lane `i` into it: its normal into the domain, the normal law's
    /// `[E* (Pa), ξ]` and, with `FRICTION`, the friction parameters of the wall and the
    /// particle's material.
    #[inline(always)]
    pub(super) fn set_wall<const FRICTION: bool>(
        &mut self,
        i: usize,
        into_domain: DVec3,
        [effective_modulus, damping_ratio]: [f64; 2],
        friction: &FrictionParams,
    ) {
        self.into_domain.set(i, into_domain);
        self.effective_modulus[i] = effective_modulus;
        self.damping_ratio[i] = damping_ratio;
        if FRICTION {
            self.shear_modulus[i] = friction.effective_shear_modulus;
            self.sliding[i] = friction.sliding;
            self.rolling[i] = friction.rolling;
        }
    }

    /// Puts the particle's side of lane `i`'s contact into it: the overlap \[m\], `[radius
    /// (m), mass (kg)]`, `[velocity (m/s), angular velocity (rad/s)]` and the spring the last
    /// pass left (the last two with `FRICTION` only).
    #[inline(always)]
    pub(super) fn set_motion<const FRICTION: bool>(
        &mut self,
        i: usize,
        overlap: f64,
        [radius, mass]: [f64; 2],
        [velocity, angular_velocity]: [DVec3; 2],
        held: TangentialSpring,
    ) {
        self.overlap[i] = overlap;
        self.radius[i] = radius;
        self.mass[i] = mass;
        self.velocity.set(i, velocity);
        if FRICTION {
            self.angular_velocity.set(i, angular_velocity);
            self.held_history.set(i, held.history);
            self.held_energy[i] = held.spring_energy;
        }
    }

    #[inline(always)]
    fn input<const FRICTION: bool>(&self, i: usize) -> WallInput {
        let mut input = WallInput {
            overlap: self.overlap[i],
            into_domain: self.into_domain.get(i),
            radius: self.radius[i],
            mass: self.mass[i],
            velocity: self.velocity.get(i),
            effective_modulus: self.effective_modulus[i],
            damping_ratio: self.damping_ratio[i],
            ..WallInput::default()
        };
        if FRICTION {
            input.angular_velocity = self.angular_velocity.get(i);
            input.friction = FrictionParams {
                effective_shear_modulus: self.shear_modulus[i],
                sliding: self.sliding[i],
                rolling: self.rolling[i],
            };
            input.held = TangentialSpring {
                history: self.held_history.get(i),
                spring_energy: self.held_energy[i],
            };
        }
        input
    }

    #[inline(always)]
    fn store<const FRICTION: bool>(&mut self, i: usize, out: &WallOutput) {
        self.normal_force[i] = out.normal_force;
        self.damper_lost[i] = out.damper_lost;
        if FRICTION {
            self.tangential_force.set(i, out.tangential_force);
            self.torque.set(i, out.torque);
            self.tangential_lost[i] = out.tangential_lost;
            self.spring_history.set(i, out.spring.history);
            self.spring_energy[i] = out.spring.spring_energy;
        }
    }

    /// Lane `i`'s overlap \[m\], radius \[m\] and, with friction, the energy of the spring it
    /// held \[J\] (stale without).
    #[inline(always)]
    pub(super) fn taken(&self, i: usize) -> (f64, f64, f64) {
        (self.overlap[i], self.radius[i], self.held_energy[i])
    }

    /// What the laws gave lane `i` (after [`run`]).
    #[inline(always)]
    pub(super) fn output<const FRICTION: bool>(&self, i: usize) -> WallOutput {
        let mut out = WallOutput {
            normal_force: self.normal_force[i],
            damper_lost: self.damper_lost[i],
            ..WallOutput::default()
        };
        if FRICTION {
            out.tangential_force = self.tangential_force.get(i);
            out.torque = self.torque.get(i);
            out.tangential_lost = self.tangential_lost[i];
            out.spring = TangentialSpring {
                history: self.spring_history.get(i),
                spring_energy: self.spring_energy[i],
            };
        }
        out
    }
}

/// The laws over every lane (those past the batch's count hold stale inputs, which cost the
/// same and whose results nobody reads).
struct WallKernel<'l, const FRICTION: bool, const ROLLING: bool> {
    dt: f64,
    lanes: &'l mut WallLanes,
}

impl<const FRICTION: bool, const ROLLING: bool> Kernel for WallKernel<'_, FRICTION, ROLLING> {
    #[inline(always)]
    fn run(self) {
        for i in 0..LANES {
            let input = self.lanes.input::<FRICTION>(i);
            let out = wall_step::<FRICTION, ROLLING>(self.dt, &input);
            self.lanes.store::<FRICTION>(i, &out);
        }
    }
}

/// Runs the laws over every lane with the kernel built for `set`, over a step of `dt` \[s\].
#[inline]
pub(super) fn run<const FRICTION: bool>(set: InstructionSet, dt: f64, lanes: &mut WallLanes) {
    // In a vector kernel every lane evaluates the rolling law, even where μ_r = 0; a batch
    // without rolling resistance skips it.
    if FRICTION && lanes.rolling.iter().any(|&coefficient| coefficient != 0.0) {
        dispatch(set, WallKernel::<FRICTION, true> { dt, lanes });
    } else {
        dispatch(set, WallKernel::<FRICTION, false> { dt, lanes });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::hertz;
    use crate::forces::lanes::tests::{assert_both_kinds, friction_of, held_scale};
    use crate::study::scenes::{PAPER_E_STAR, PAPER_RADIUS, paper_sphere_mass};

    const DT: f64 = 1e-7;

    /// A deterministic spread of wall contacts: overlaps from grazing to 2 % of the radius, on
    /// walls of three orientations, approach and separation, springs from none to far past the
    /// Coulomb limit (some lanes stick, some slide), spins with and without rolling resistance
    /// (every other batch has none, which the kernel runs without the rolling law): the pair
    /// kernel's test parameters (`lanes::tests`).
    fn inputs(count: usize) -> Vec<WallInput> {
        let mut random = crate::bed::rng::SplitMix64(0x5eed_0f3a);
        let mut vector =
            |scale: f64| DVec3::new(random.unit(), random.unit(), random.unit()) * scale;
        let mass = paper_sphere_mass(8000.0);
        let normals = [DVec3::Z, DVec3::X, DVec3::new(0.0, -0.6, 0.8)];
        (0..count)
            .map(|k| {
                let [u, v, w] = vector(1.0).to_array();
                WallInput {
                    overlap: 0.02 * PAPER_RADIUS * u,
                    into_domain: normals[k % 3],
                    radius: PAPER_RADIUS * (0.8 + 0.4 * v),
                    mass: mass * (0.5 + w),
                    velocity: vector(0.4) - DVec3::splat(0.2),
                    effective_modulus: PAPER_E_STAR,
                    damping_ratio: 0.2,
                    angular_velocity: vector(600.0) - DVec3::splat(300.0),
                    friction: friction_of(k),
                    held: TangentialSpring {
                        history: vector(held_scale(k)) - DVec3::splat(0.5 * held_scale(k)),
                        spring_energy: 1e-9 * vector(1.0).x,
                    },
                }
            })
            .collect()
    }

    /// With one wall and one material every lane holds the wall's normal and parameters from
    /// the start: lanes given only the particles' side of each contact give bitwise what lanes
    /// given every input do. With a second wall the lanes hold none.
    #[test]
    fn lanes_of_a_one_wall_one_material_model_hold_its_wall() {
        let text = crate::forces::tests::plate_scene("")
            .replace(
                "friction_coefficient = 0.5",
                "friction_coefficient = 0.5\nrolling_friction_coefficient = 0.1",
            )
            .replace("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.6, 0.8]")
            + "[[particles]]\nposition_m = [0.0, 0.0, 1e-3]\nradius_m = 2e-5\nmaterial = \"m\"\n";
        let scene = crate::scene::Scene::from_toml(&text).expect("the test's scene");
        let model = Model::build(&scene).0;
        let mut uniform = WallLanes::for_model(&model);
        assert!(uniform.uniform_wall());
        let params = model.wall_params(0, 0);
        let friction = *model.friction.as_ref().expect("friction").wall(0, 0);
        assert_eq!((friction.sliding, friction.rolling), (0.5, 0.1));
        let mut per_contact = WallLanes::default();
        for (i, mut input) in inputs(LANES).into_iter().enumerate() {
            input.into_domain = model.walls[0].normal;
            input.effective_modulus = params.effective_modulus;
            input.damping_ratio = params.damping_ratio;
            input.friction = friction;
            per_contact.set::<true>(i, &input);
            uniform.set_motion::<true>(
                i,
                input.overlap,
                [input.radius, input.mass],
                [input.velocity, input.angular_velocity],
                input.held,
            );
        }
        let set = InstructionSet::detect();
        run::<true>(set, DT, &mut per_contact);
        run::<true>(set, DT, &mut uniform);
        for i in 0..LANES {
            assert_eq!(
                bits(&uniform.output::<true>(i)),
                bits(&per_contact.output::<true>(i)),
                "lane {i}"
            );
        }
        let two = text.replace(
            "[[particles]]",
            "[[walls]]\npoint_m = [0.0, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\nmaterial = \"m\"\n[[particles]]",
        );
        let model = Model::build(&crate::scene::Scene::from_toml(&two).expect("two walls")).0;
        assert_eq!(model.walls.len(), 2);
        assert!(!WallLanes::for_model(&model).uniform_wall());
    }

    fn bits(out: &WallOutput) -> Vec<u64> {
        [out.tangential_force, out.torque, out.spring.history]
            .iter()
            .flat_map(|v| v.to_array())
            .chain([
                out.normal_force,
                out.damper_lost,
                out.tangential_lost,
                out.spring.spring_energy,
            ])
            .map(f64::to_bits)
            .collect()
    }

    /// Every build of the kernel gives bitwise what the laws give one contact at a time (with
    /// the rolling law always evaluated, as the particle pass once did), with lanes reused from
    /// round to round as the pass reuses them.
    fn check<const FRICTION: bool>() {
        let inputs = inputs(16 * LANES);
        let (mut sliding, mut sticking, mut rolling) = (0, 0, 0);
        let sets = InstructionSet::available();
        let mut reused = vec![WallLanes::default(); sets.len()];
        for batch in inputs.chunks(LANES) {
            rolling += usize::from(batch.iter().any(|input| input.friction.rolling != 0.0));
            let one_by_one: Vec<WallOutput> = batch
                .iter()
                .map(|input| wall_step::<FRICTION, true>(DT, std::hint::black_box(input)))
                .collect();
            for (&set, lanes) in sets.iter().zip(&mut reused) {
                for (i, input) in batch.iter().enumerate() {
                    lanes.set::<FRICTION>(i, input);
                }
                run::<FRICTION>(set, DT, lanes);
                for (i, expected) in one_by_one.iter().enumerate() {
                    let out = lanes.output::<FRICTION>(i);
                    assert_eq!(bits(&out), bits(expected), "{set:?}, lane {i}");
                }
            }
            for (input, out) in batch.iter().zip(&one_by_one) {
                if FRICTION && input.friction.sliding > 0.0 {
                    // A sliding spring is cut back to the Coulomb limit, by far more than the
                    // step's v_t dt can change its length.
                    if out.spring.history.length() < 0.9 * input.held.history.length() {
                        sliding += 1;
                    } else {
                        sticking += 1;
                    }
                }
            }
        }
        assert_both_kinds::<FRICTION>((sliding, sticking), rolling, inputs.len() / LANES);
    }

    #[test]
    fn every_build_gives_bitwise_the_contact_by_contact_laws_with_friction() {
        check::<true>();
    }

    #[test]
    fn every_build_gives_bitwise_the_contact_by_contact_laws_without_friction() {
        check::<false>();
    }

    /// A sphere resting on a wall (no approach) feels the Hertz force of a sphere against a
    /// half-space, F = (4/3) E* √r δ^{3/2} (r* = r), its damper does no work, and a spring-free
    /// contact at rest gets no tangential force; approaching, the damper adds to the force and
    /// takes energy, F_d δ̇ dt > 0.
    #[test]
    fn a_sphere_on_a_wall_feels_the_hertz_force_of_a_half_space() {
        let (radius, overlap) = (PAPER_RADIUS, 1e-3 * PAPER_RADIUS);
        let at_rest = WallInput {
            overlap,
            into_domain: DVec3::Z,
            radius,
            mass: paper_sphere_mass(8000.0),
            effective_modulus: PAPER_E_STAR,
            damping_ratio: 0.2,
            friction: FrictionParams {
                effective_shear_modulus: 0.4 * PAPER_E_STAR,
                sliding: 0.5,
                rolling: 0.1,
            },
            ..WallInput::default()
        };
        let out = wall_step::<true, true>(DT, &at_rest);
        let closed_form = 4.0 / 3.0 * PAPER_E_STAR * radius.sqrt() * overlap.powf(1.5);
        // Two square roots and a few products apart: a few ulps.
        assert!((out.normal_force - closed_form).abs() <= 1e-14 * closed_form);
        assert_eq!(
            out.normal_force,
            hertz::elastic_force(PAPER_E_STAR, radius, overlap)
        );
        assert_eq!(out.damper_lost, 0.0);
        assert_eq!(out.tangential_force, DVec3::ZERO);
        assert_eq!(out.torque, DVec3::ZERO);
        // Approaching the wall at 0.1 m/s.
        let approaching = WallInput {
            velocity: DVec3::new(0.0, 0.0, -0.1),
            ..at_rest
        };
        let out = wall_step::<true, true>(DT, &approaching);
        assert!(out.normal_force > closed_form);
        let damper = out.normal_force - closed_form;
        assert!((out.damper_lost - damper * 0.1 * DT).abs() <= 1e-12 * out.damper_lost);
    }
}
