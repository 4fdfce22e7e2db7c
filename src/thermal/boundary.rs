//! Exchange of each particle with its boundaries (M.43-M.46): conduction to the walls held at a
//! temperature, convection to the gas and radiation to the surroundings,
//!
//! ```text
//! Q_i = Σ_walls H_iw (T_w − T_i) + h A_i (T_gas − T_i) + ε_i σ A_i (T_env⁴ − T_i⁴)     [W]
//! G_i = Σ_walls H_iw + h A_i + 4 ε_i σ A_i max(T_i, T_m, T_env)³                    [W/K]
//! ```
//!
//! with the radiation's conductance linearised at `max(T, T_m, T_env)` (a laser may heat the
//! particle within the step). [`boundary_heat`] gives one particle's; `BoundaryLanes` gives
//! those of up to 16 particles at once with a vector kernel, as the wall laws run in
//! `forces`: with heat from a laser or any exchange every particle of the bed takes this every
//! step, and one particle at a time it was the largest single part of the flagship's scan (8.5 %
//! of its samples at 1 thread; its largest single share, 13 % of its own, on the instruction
//! after the square root behind the branch on touching the plate, which 45 % of the particles
//! do). Both evaluate the same laws (`add_wall`, `add_surroundings`) with
//! the same operations in the same order, so they give bitwise the same (tested below).

use glam::DVec3;

use super::{ConductionModel, ThermalModel, conduction, losses};
use crate::model::Wall;
use crate::particles::Particles;
use crate::simd::{InstructionSet, Kernel, LANES, Lane, dispatch};

/// A wall held at a temperature, with what its conduction law needs.
#[derive(Debug, Clone, Copy)]
struct HeldWall {
    /// A point of its plane \[m\] and its unit normal, into the domain.
    point: DVec3,
    normal: DVec3,
    /// Its temperature T_w \[K\] and its material's conductivity k_w [W/(m·K)].
    temperature: f64,
    conductivity: f64,
}

impl HeldWall {
    /// The walls of `walls` that `model` holds at a temperature, in their order.
    fn all<'w>(model: &'w ThermalModel, walls: &'w [Wall]) -> impl Iterator<Item = Self> + 'w {
        walls
            .iter()
            .zip(&model.wall_temperatures)
            .filter_map(|(wall, temperature)| {
                temperature.map(|temperature| Self {
                    point: wall.point,
                    normal: wall.normal,
                    temperature,
                    conductivity: model.materials[usize::from(wall.material)].conductivity,
                })
            })
    }

    /// Distance of a centre at `position` from the wall's plane, `s = (x − p)·n` \[m\].
    #[inline(always)]
    fn centre_distance(&self, position: DVec3) -> f64 {
        (position - self.point).dot(self.normal)
    }
}

/// Conductance between a sphere of `radius` whose centre is `centre_distance` from a plane wall
/// and that wall (M.41-M.43, M.79 with the plane as the second body) [W/K]; 0 apart:
///
/// ```text
/// BatchelorObrien: H = 2 k* a,            a = √(r δ),   δ = r − s,  k* = 2 k_i k_w / (k_i + k_w)
/// ThermalPipe:     H = k_i π a² / s       (the particle's half of the pipe; the wall conducts ideally)
/// OverlapArea:     H = 2 k* √π a_g,       a_g² = r² − s² (the circle the sphere cuts in the plane)
/// ```
#[must_use]
#[inline(always)]
pub fn wall_contact_conductance(
    conduction_model: ConductionModel,
    conductivity: f64,
    wall_conductivity: f64,
    radius: f64,
    centre_distance: f64,
) -> f64 {
    let overlap = radius - centre_distance;
    if overlap <= 0.0 {
        return 0.0;
    }
    let contact = conduction::contact_radius(radius, overlap);
    match conduction_model {
        ConductionModel::None => 0.0,
        ConductionModel::BatchelorObrien => {
            conduction::batchelor_obrien(conductivity, wall_conductivity, contact)
        }
        ConductionModel::ThermalPipe => conduction::thermal_pipe_wall(
            conductivity,
            contact,
            centre_distance.max(f64::MIN_POSITIVE),
        ),
        ConductionModel::OverlapArea => conduction::overlap_area(
            conductivity,
            wall_conductivity,
            (radius * radius - centre_distance * centre_distance)
                .max(0.0)
                .sqrt(),
        ),
    }
}

/// What a particle's exchange needs of its material.
#[derive(Debug, Clone, Copy)]
struct Surface {
    radius: f64,
    emissivity: f64,
    melting_point: f64,
}

/// `(flow, conductance)` with a held wall's conductance `h` added: `h (T_w − T)` and `h`.
#[inline(always)]
fn add_wall(
    (flow, conductance): (f64, f64),
    h: f64,
    wall_temperature: f64,
    temperature: f64,
) -> (f64, f64) {
    (flow + h * (wall_temperature - temperature), conductance + h)
}

/// `(flow, conductance)` with convection (M.44) and radiation (M.45, its conductance M.46 at
/// `max(T, T_m, T_env)`) added, as `model` has them.
#[inline(always)]
fn add_surroundings(
    model: &ThermalModel,
    (mut flow, mut conductance): (f64, f64),
    surface: Surface,
    temperature: f64,
) -> (f64, f64) {
    let area = losses::sphere_area(surface.radius);
    if let Some((h, t_gas)) = model.convection {
        flow += losses::convection(h, area, temperature, t_gas);
        conductance += h * area;
    }
    if let Some(environment) = model.radiation {
        flow += losses::radiation(surface.emissivity, area, temperature, environment);
        conductance += losses::radiation_conductance(
            surface.emissivity,
            area,
            temperature.max(surface.melting_point),
            environment,
        );
    }
    (flow, conductance)
}

/// Exchange of particle `k` at temperature `t` \[K\] with isothermal walls, the gas and the
/// surroundings: `(heat flow into it [W], total conductance [W/K])`, radiation linearised at
/// `max(T, T_m, T_env)` (a laser may heat the particle within the step).
#[must_use]
pub fn boundary_heat(
    model: &ThermalModel,
    walls: &[Wall],
    particles: &Particles,
    k: usize,
    t: f64,
) -> (f64, f64) {
    if !model.has_boundary_exchange() {
        return (0.0, 0.0);
    }
    let material = &model.materials[usize::from(particles.material[k])];
    let radius = particles.radius[k];
    let mut sums = (0.0, 0.0);
    for wall in HeldWall::all(model, walls) {
        let h = wall_contact_conductance(
            model.conduction,
            material.conductivity,
            wall.conductivity,
            radius,
            wall.centre_distance(particles.position[k]),
        );
        sums = add_wall(sums, h, wall.temperature, t);
    }
    let surface = Surface {
        radius,
        emissivity: material.emissivity,
        melting_point: material.melting_point,
    };
    add_surroundings(model, sums, surface, t)
}

/// The boundary exchange of up to [`LANES`] particles at once: [`BoundaryLanes::set`] puts a
/// particle into a lane, [`BoundaryLanes::run`] evaluates every lane with the widest vector
/// build, [`BoundaryLanes::output`] reads a lane's `(flow, conductance)`.
#[derive(Debug, Clone)]
pub(crate) struct BoundaryLanes {
    held: Vec<HeldWall>,
    temperature: Lane<f64>,
    radius: Lane<f64>,
    conductivity: Lane<f64>,
    emissivity: Lane<f64>,
    melting_point: Lane<f64>,
    /// The particles' centres \[m\], one array per component.
    x: Lane<f64>,
    y: Lane<f64>,
    z: Lane<f64>,
    flow: Lane<f64>,
    conductance: Lane<f64>,
}

impl BoundaryLanes {
    /// Lanes for the walls of `walls` that `model` holds at a temperature.
    #[must_use]
    pub(crate) fn new(model: &ThermalModel, walls: &[Wall]) -> Self {
        Self {
            held: HeldWall::all(model, walls).collect(),
            temperature: [0.0; LANES],
            radius: [0.0; LANES],
            conductivity: [0.0; LANES],
            emissivity: [0.0; LANES],
            melting_point: [0.0; LANES],
            x: [0.0; LANES],
            y: [0.0; LANES],
            z: [0.0; LANES],
            flow: [0.0; LANES],
            conductance: [0.0; LANES],
        }
    }

    /// Puts particle `k` at temperature `t` \[K\] into lane `i < LANES`.
    #[inline(always)]
    pub(crate) fn set(
        &mut self,
        i: usize,
        model: &ThermalModel,
        particles: &Particles,
        k: usize,
        t: f64,
    ) {
        let material = &model.materials[usize::from(particles.material[k])];
        self.temperature[i] = t;
        self.radius[i] = particles.radius[k];
        self.conductivity[i] = material.conductivity;
        self.emissivity[i] = material.emissivity;
        self.melting_point[i] = material.melting_point;
        let position = particles.position[k];
        (self.x[i], self.y[i], self.z[i]) = (position.x, position.y, position.z);
    }

    /// Evaluates every lane (those not set since the last run hold stale inputs, which cost
    /// the same and whose results nobody reads) with the kernel built for `set`.
    #[inline]
    pub(crate) fn run(&mut self, set: InstructionSet, model: &ThermalModel) {
        dispatch(set, BoundaryKernel { model, lanes: self });
    }

    /// Lane `i`'s `(heat flow into it [W], total conductance [W/K])` from the last [`run`].
    ///
    /// [`run`]: BoundaryLanes::run
    #[must_use]
    #[inline]
    pub(crate) fn output(&self, i: usize) -> (f64, f64) {
        (self.flow[i], self.conductance[i])
    }
}

/// [`boundary_heat`] over every lane, one law at a time across the lanes, so that each loop
/// holds no branch the compiler cannot turn into a blend.
struct BoundaryKernel<'l> {
    model: &'l ThermalModel,
    lanes: &'l mut BoundaryLanes,
}

impl Kernel for BoundaryKernel<'_> {
    #[inline(always)]
    fn run(self) {
        let BoundaryLanes {
            held,
            temperature,
            radius,
            conductivity,
            emissivity,
            melting_point,
            x,
            y,
            z,
            flow,
            conductance,
        } = self.lanes;
        let model = self.model;
        *flow = [0.0; LANES];
        *conductance = [0.0; LANES];
        for wall in held.iter() {
            let lanes = HeldWallLanes {
                wall,
                conductivity,
                radius,
                centre: (x, y, z),
                temperature,
            };
            let sums = (&mut *flow, &mut *conductance);
            // One loop per conduction model: the match stays outside the lanes.
            let k_wall = wall.conductivity;
            match model.conduction {
                ConductionModel::None => lanes.add(sums, |k, r, s| {
                    wall_contact_conductance(ConductionModel::None, k, k_wall, r, s)
                }),
                ConductionModel::BatchelorObrien => lanes.add(sums, |k, r, s| {
                    wall_contact_conductance(ConductionModel::BatchelorObrien, k, k_wall, r, s)
                }),
                ConductionModel::ThermalPipe => lanes.add(sums, |k, r, s| {
                    wall_contact_conductance(ConductionModel::ThermalPipe, k, k_wall, r, s)
                }),
                ConductionModel::OverlapArea => lanes.add(sums, |k, r, s| {
                    wall_contact_conductance(ConductionModel::OverlapArea, k, k_wall, r, s)
                }),
            }
        }
        for i in 0..LANES {
            let surface = Surface {
                radius: radius[i],
                emissivity: emissivity[i],
                melting_point: melting_point[i],
            };
            (flow[i], conductance[i]) =
                add_surroundings(model, (flow[i], conductance[i]), surface, temperature[i]);
        }
    }
}

/// What the kernel's loop over one held wall reads.
struct HeldWallLanes<'l> {
    wall: &'l HeldWall,
    conductivity: &'l Lane<f64>,
    radius: &'l Lane<f64>,
    centre: (&'l Lane<f64>, &'l Lane<f64>, &'l Lane<f64>),
    temperature: &'l Lane<f64>,
}

impl HeldWallLanes<'_> {
    /// Adds the wall's exchange by `law(k_i, r_i, s_i)` to every lane's sums.
    #[inline(always)]
    fn add(
        &self,
        (flow, conductance): (&mut Lane<f64>, &mut Lane<f64>),
        law: impl Fn(f64, f64, f64) -> f64,
    ) {
        let (x, y, z) = self.centre;
        for i in 0..LANES {
            let centre_distance = self.wall.centre_distance(DVec3::new(x[i], y[i], z[i]));
            let h = law(self.conductivity[i], self.radius[i], centre_distance);
            (flow[i], conductance[i]) = add_wall(
                (flow[i], conductance[i]),
                h,
                self.wall.temperature,
                self.temperature[i],
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::ParticleInit;
    use crate::thermal::{ThermalMaterial, losses::STEFAN_BOLTZMANN};

    fn material(conductivity: f64, emissivity: f64, melting_point: f64) -> ThermalMaterial {
        ThermalMaterial {
            specific_heat: 500.0,
            conductivity,
            melting_point,
            latent_heat: 2.7e5,
            emissivity,
            absorptivity: 0.6,
            vaporization: None,
        }
    }

    /// Two particle materials and a plate of a third; a floor held at 300 K, an adiabatic side
    /// wall at x = 0 and a held side wall at y = 0 tilted a little.
    fn model(conduction: ConductionModel, surroundings: bool) -> (ThermalModel, Vec<Wall>) {
        let walls = vec![
            Wall {
                point: DVec3::ZERO,
                normal: DVec3::Z,
                material: 2,
            },
            Wall {
                point: DVec3::ZERO,
                normal: DVec3::X,
                material: 2,
            },
            Wall {
                point: DVec3::new(0.0, 1e-6, 0.0),
                normal: DVec3::new(0.0, 0.8, 0.6),
                material: 0,
            },
        ];
        let model = ThermalModel {
            convection: surroundings.then_some((10.0, 320.0)),
            radiation: surroundings.then_some(290.0),
            wall_temperatures: vec![Some(300.0), None, Some(900.0)],
            ..ThermalModel::bare(
                vec![
                    material(18.0, 0.4, 1700.0),
                    material(200.0, 0.1, 930.0),
                    material(50.0, 0.3, 1800.0),
                ],
                conduction,
            )
        };
        (model, walls)
    }

    /// Particles from well off every wall to 3 % of their radius into the floor or the tilted
    /// wall, of both materials, with temperatures from below the surroundings' to past the
    /// melting points, so that lanes of one batch take both sides of every branch.
    fn particles(count: usize) -> (Particles, Vec<f64>) {
        let mut random = crate::bed::rng::SplitMix64(0xb0_0da7);
        let mut particles = Particles::default();
        let mut temperatures = Vec::new();
        for k in 0..count {
            let radius = 1e-5 * (0.75 + 0.5 * random.unit());
            let height = radius * (0.97 + 0.05 * random.unit());
            let position = DVec3::new(
                1e-4 * (0.5 + random.unit()),
                1e-4 * (0.5 + random.unit()),
                if k % 4 == 0 { 1e-4 } else { height },
            );
            particles.push(
                ParticleInit {
                    position,
                    velocity: DVec3::ZERO,
                    radius,
                    material: u16::from(k % 5 == 1),
                },
                7950.0,
            );
            temperatures.push(250.0 + 2500.0 * random.unit());
        }
        // One 2 % of its radius into the tilted wall (and into the floor), one behind it.
        let tilted = DVec3::new(0.0, 0.8, 0.6);
        particles.position[1] = DVec3::new(5e-5, 1e-6, 0.0) + 0.98 * particles.radius[1] * tilted;
        particles.position[2].y = -1e-4;
        (particles, temperatures)
    }

    /// Every build of the kernel gives bitwise what [`boundary_heat`] gives one particle at a
    /// time, for every conduction model, with and without the surroundings, with lanes reused
    /// from batch to batch and a last batch that fills only some of them.
    #[test]
    fn the_lanes_give_bitwise_what_one_particle_at_a_time_gives() {
        let count = 5 * LANES + 3;
        let (particles, temperatures) = particles(count);
        let touching = (0..count)
            .filter(|&k| particles.position[k].z < particles.radius[k])
            .count();
        // About 45 % touch: both sides of the branch in every batch.
        assert!(
            touching > count / 4 && touching < 3 * count / 4,
            "{touching} of {count} touch"
        );
        for conduction in [
            ConductionModel::None,
            ConductionModel::BatchelorObrien,
            ConductionModel::ThermalPipe,
            ConductionModel::OverlapArea,
        ] {
            for surroundings in [false, true] {
                let (model, walls) = model(conduction, surroundings);
                let one_by_one: Vec<(f64, f64)> = (0..count)
                    .map(|k| boundary_heat(&model, &walls, &particles, k, temperatures[k]))
                    .collect();
                // The exchange is not trivially zero where the scene has any.
                let nonzero = one_by_one.iter().filter(|(_, g)| *g > 0.0).count();
                let expected = if surroundings {
                    count
                } else if conduction == ConductionModel::None {
                    0
                } else {
                    touching
                };
                assert!(nonzero >= expected, "{conduction:?}: {nonzero} of {count}");
                for set in InstructionSet::available() {
                    let mut lanes = BoundaryLanes::new(&model, &walls);
                    for first in (0..count).step_by(LANES) {
                        let batch = first..count.min(first + LANES);
                        for (i, k) in batch.clone().enumerate() {
                            lanes.set(i, &model, &particles, k, temperatures[k]);
                        }
                        lanes.run(set, &model);
                        for (i, k) in batch.enumerate() {
                            let (flow, conductance) = lanes.output(i);
                            let (want_flow, want_conductance) = one_by_one[k];
                            assert_eq!(
                                (flow.to_bits(), conductance.to_bits()),
                                (want_flow.to_bits(), want_conductance.to_bits()),
                                "{} build, {conduction:?}, particle {k}",
                                set.name()
                            );
                        }
                    }
                }
            }
        }
    }

    /// One sphere pressed into the held floor, with the closed forms of M.41 and M.44-M.46:
    /// `H = 2 k* √(r δ)`, `h A (T_gas − T)`, `ε σ A (T_env⁴ − T⁴)` and `4 ε σ A T_m³` below the
    /// melting point. Tolerance: a few roundings of each sum (1e-12 relative).
    #[test]
    fn a_sphere_on_the_plate_exchanges_the_closed_forms() {
        let (model, walls) = model(ConductionModel::BatchelorObrien, true);
        let (radius, overlap, temperature) = (1.5e-5, 2e-7, 1000.0);
        let mut particles = Particles::default();
        particles.push(
            ParticleInit {
                position: DVec3::new(5e-4, 5e-4, radius - overlap),
                velocity: DVec3::ZERO,
                radius,
                material: 0,
            },
            7950.0,
        );
        let (flow, conductance) = boundary_heat(&model, &walls, &particles, 0, temperature);
        let k_star = 2.0 * 18.0 * 50.0 / (18.0 + 50.0);
        let wall = 2.0 * k_star * (radius * overlap).sqrt();
        let area = 4.0 * std::f64::consts::PI * radius * radius;
        let convection = 10.0 * area;
        let emitted = 0.4 * STEFAN_BOLTZMANN * area;
        let expected_flow = wall * (300.0 - temperature)
            + convection * (320.0 - temperature)
            + emitted * (290.0_f64.powi(4) - temperature.powi(4));
        let expected_conductance = wall + convection + 4.0 * emitted * 1700.0_f64.powi(3);
        assert!(
            (flow / expected_flow - 1.0).abs() < 1e-12,
            "{flow} {expected_flow}"
        );
        assert!(
            (conductance / expected_conductance - 1.0).abs() < 1e-12,
            "{conductance} {expected_conductance}"
        );
        // The adiabatic side wall at x = 0 is far; so is the tilted one. Off the plate only the
        // surroundings remain.
        particles.position[0].z = 2.0 * radius;
        let (flow, conductance) = boundary_heat(&model, &walls, &particles, 0, temperature);
        let expected_flow = expected_flow - wall * (300.0 - temperature);
        assert!(
            (flow / expected_flow - 1.0).abs() < 1e-12,
            "{flow} {expected_flow}"
        );
        assert!(((conductance + wall) / expected_conductance - 1.0).abs() < 1e-12);
    }
}
