//! Velocity Verlet (kick–drift–kick), the standard DEM integrator (LAMMPS `fix nve/sphere`):
//!
//! ```text
//! v(t + dt/2) = v(t) + dt/2 · F(t)/m                                   (M.30)
//! x(t + dt)   = x(t) + dt · v(t + dt/2)                                 (M.31)
//! F(t + dt)   = F(x(t + dt), v(t + dt/2))   (damping sees the half-step velocity)
//! v(t + dt)   = v(t + dt/2) + dt/2 · F(t + dt)/m                        (M.32)
//! ```
//!
//! Second order and time-reversible for conservative forces, so the undamped Hertz impact keeps
//! its energy to O(dt²) (tested in `tests/hertz_impact.rs`).

use glam::DVec3;

use crate::contact::rolling;
use crate::particles::{Particles, Rotation};
use crate::simd::{InstructionSet, Kernel, Largest, dispatch, fold_lanes};
use crate::team::{PARTICLES_PER_ITEM as CHUNK, optional_items};

/// The per-particle sums the force pass adds into besides the forces and torques (with
/// `[thermal]`: the net heat flows \[W\]), which [`kick_drift`] leaves at zero with them.
pub type Sums<'a> = Option<&'a mut [f64]>;

/// The opening half of a step, in one pass over the particles: the half kick and the drift
/// (M.30, M.31) and, with rotation, the half kick of ω (M.62). The half kick is the last reader
/// of the step's forces and torques: the pass leaves each force at the particle's weight
/// `m gravity` \[N\] (the contacts add to it) and the torques and `sums` at zero, ready for the
/// next force pass to add into (`forces::compute` with `cleared`): one parallel region and one
/// sweep of the arrays instead of five, seven with heat. Returns the largest speed of the drift,
/// which bounds every particle's displacement (the neighbour list's rebuild test and the near
/// lists' refresh test sum it).
///
/// With [`Opening::AfterClosingKick`] the pass first gives the velocities and spins the last
/// step's closing half kick (M.32, M.62), with the same forces and torques: `v + k F + k F`
/// evaluated as `(v + k F) + k F`, bitwise what the closing kick followed by this pass gives,
/// with one sweep of the arrays fewer (`Simulation::advance`).
pub fn kick_drift(
    particles: &mut Particles,
    rotation: Option<&mut Rotation>,
    sums: Sums<'_>,
    (dt, gravity): (f64, DVec3),
    opening: Opening,
) -> Drift {
    let _pass = crate::team::PassName::enter("opening pass (kicks, drift)");
    let Particles {
        position,
        velocity,
        force,
        mass,
        radius,
        ..
    } = particles;
    let (mass, radius) = (&*mass, &*radius);
    let parallel = crate::worth_parallel(position.len());
    let (omega, torque) = rotation
        .map(|r| (r.angular_velocity.as_mut_slice(), r.torque.as_mut_slice()))
        .unzip();
    let chunks: Vec<_> = position
        .chunks_mut(CHUNK)
        .zip(velocity.chunks_mut(CHUNK))
        .zip(
            force
                .chunks_mut(CHUNK)
                .zip(optional_items(omega).zip(optional_items(torque))),
        )
        .zip(optional_items(sums))
        .collect();
    let max_speed_squared = each_chunk(
        chunks,
        parallel,
        0.0,
        f64::max,
        |first, (((position, velocity), (force, angular)), sums)| {
            let mut max_speed_squared = 0.0;
            let set = InstructionSet::detect();
            let mass = &mass[first..first + position.len()];
            let kick_drift = KickDrift {
                position,
                velocity,
                force,
                mass,
                dt,
                gravity,
                max_speed_squared: &mut max_speed_squared,
            };
            let folded = opening == Opening::AfterClosingKick;
            dispatch_folded(set, kick_drift, folded);
            if let (Some(omega), Some(torque)) = angular {
                let radius = &radius[first..first + omega.len()];
                let kick = AngularKick {
                    omega,
                    torque,
                    mass,
                    radius,
                    dt,
                };
                dispatch_folded(set, kick, folded);
                torque.fill(DVec3::ZERO);
            }
            if let Some(sums) = sums {
                sums.fill(0.0);
            }
            max_speed_squared
        },
    );
    Drift {
        max_speed: max_speed_squared.sqrt(),
    }
}

/// Whether [`kick_drift`] opens a step after a complete one, or also gives the last step's
/// closing half kick, which was left to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Opening {
    /// The velocities and spins are those at the end of the last step (after its closing kick).
    AfterStep,
    /// The last step's closing kick is still to come: the pass gives it first.
    AfterClosingKick,
}

/// What the drift of [`kick_drift`] reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drift {
    /// The largest speed of the drift, |v(t + dt/2)| \[m/s\]: no particle moved more than
    /// `dt` times it (the bound of the rebuild and near-list tests, `neighbor`).
    pub max_speed: f64,
}

/// The closing half kick (M.32) and, with rotation, that of ω (M.62), in one pass. Returns the
/// lowest particle whose force is NaN or infinite, if any (the run's guard: the kick is the
/// pass that would carry it into the velocities, and it reads every force anyway).
#[must_use]
pub fn kick(particles: &mut Particles, rotation: Option<&mut Rotation>, dt: f64) -> Option<usize> {
    let _pass = crate::team::PassName::enter("closing kick");
    let Particles {
        velocity,
        force,
        mass,
        radius,
        ..
    } = particles;
    let (force, mass, radius) = (&*force, &*mass, &*radius);
    let parallel = crate::worth_parallel(velocity.len());
    let (omega, torque) = rotation
        .map(|r| (r.angular_velocity.as_mut_slice(), r.torque.as_mut_slice()))
        .unzip();
    let chunks: Vec<_> = velocity
        .chunks_mut(CHUNK)
        .zip(optional_items(omega).zip(optional_items(torque)))
        .collect();
    each_chunk(
        chunks,
        parallel,
        None,
        lowest_particle,
        |first, (velocity, angular)| {
            let mut finite = true;
            let set = InstructionSet::detect();
            let range = first..first + velocity.len();
            dispatch(
                set,
                Kick {
                    velocity,
                    force: &force[range.clone()],
                    mass: &mass[range.clone()],
                    dt,
                    finite: &mut finite,
                },
            );
            if let (Some(omega), Some(torque)) = angular {
                dispatch(
                    set,
                    AngularKick {
                        omega,
                        torque,
                        mass: &mass[range.clone()],
                        radius: &radius[range.clone()],
                        dt,
                    },
                );
            }
            first_non_finite_in(first, &force[range], finite)
        },
    )
}

/// The opening half kick and the drift of a chunk's particles (M.30, M.31), a [`Kernel`]: the
/// forces are left at the weights `m gravity` \[N\], and the largest |v(t + dt/2)|² goes to
/// `max_speed_squared` \[m²/s²\].
///
/// The three components of a particle's vectors lie side by side in memory, so the kicks and the
/// drift run over the components as flat arrays (`bytemuck`), block by block, each component
/// with its particle's factor spread to it first ([`kick_block`]): the compiler then does four or
/// eight components per instruction in the AVX2 and AVX-512 builds, where over the particles'
/// vectors it did one. The operations are those of the per-particle formula, in its order, so
/// every build gives bitwise the same (tested below).
struct KickDrift<'a> {
    position: &'a mut [DVec3],
    velocity: &'a mut [DVec3],
    force: &'a mut [DVec3],
    mass: &'a [f64],
    dt: f64,
    gravity: DVec3,
    max_speed_squared: &'a mut f64,
}

impl Kernel for KickDrift<'_> {
    #[inline(always)]
    fn run(self) {
        self.kick_and_drift::<false>();
    }
}

/// A kernel that first gives the last step's closing half kick, then its own (see
/// [`Opening::AfterClosingKick`]).
struct Folded<K>(K);

/// Runs `kernel` built for `set`, [`Folded`] if `folded`.
#[inline(always)]
fn dispatch_folded<K: Kernel>(set: InstructionSet, kernel: K, folded: bool)
where
    Folded<K>: Kernel,
{
    if folded {
        dispatch(set, Folded(kernel));
    } else {
        dispatch(set, kernel);
    }
}

impl Kernel for Folded<KickDrift<'_>> {
    #[inline(always)]
    fn run(self) {
        self.0.kick_and_drift::<true>();
    }
}

impl Kernel for Folded<AngularKick<'_>> {
    #[inline(always)]
    fn run(self) {
        self.0.kick::<true>();
    }
}

impl KickDrift<'_> {
    /// The kick (twice if `FOLDED`, the closing kick's first) and the drift.
    #[inline(always)]
    fn kick_and_drift<const FOLDED: bool>(self) {
        let mut scratch = KickScratch::default();
        let mut fastest = Largest::new(0.0);
        for (((x, v), f), mass) in self
            .position
            .chunks_mut(BLOCK)
            .zip(self.velocity.chunks_mut(BLOCK))
            .zip(self.force.chunks_mut(BLOCK))
            .zip(self.mass.chunks(BLOCK))
        {
            let kicks = half_kicks(self.dt, mass, &mut scratch.factors);
            kick_block::<FOLDED>(v, f, kicks, &mut scratch.spread);
            for (x, &v) in components_mut(x).iter_mut().zip(components(v)) {
                *x += self.dt * v;
            }
            for (f, &mass) in f.iter_mut().zip(mass) {
                *f = mass * self.gravity;
            }
            // In a loop of their own the squares are vectorised (see `Largest`).
            let speeds_squared = &mut scratch.speeds_squared[..v.len()];
            for (speed_squared, v) in speeds_squared.iter_mut().zip(v.iter()) {
                *speed_squared = v.length_squared();
            }
            fastest.take(speeds_squared);
        }
        *self.max_speed_squared = fastest.value();
    }
}

/// The lowest particle whose vector in `vectors` (a force, a position, a velocity) is NaN or
/// infinite, if any: a vector kernel over the components, chunk by chunk on the team, and a
/// search of the chunk that holds one ([`first_non_finite_of`]): the output's test of the state
/// ([`first_non_finite`]). (The forces of a step whose closing kick is left to the next opening
/// pass are tested by the particle pass, chunk by chunk.)
#[must_use]
pub fn first_non_finite_vector(vectors: &[DVec3]) -> Option<usize> {
    let _pass = crate::team::PassName::enter("finite test");
    let chunks: Vec<&[DVec3]> = vectors.chunks(CHUNK).collect();
    each_chunk(
        chunks,
        crate::worth_parallel(vectors.len()),
        None,
        lowest_particle,
        first_non_finite_of,
    )
}

/// The lowest particle whose vector in `vectors` is NaN or infinite, if any, where `vectors`
/// are those of the particles from `first` on: the test of one chunk, by a vector kernel over
/// the components and a search of the chunk only if it holds one. [`first_non_finite_vector`]
/// runs it on every chunk, the particle pass on each of its chunks' finished forces
/// (`forces::ForceSummary::first_non_finite_force`).
#[must_use]
pub fn first_non_finite_of(first: usize, vectors: &[DVec3]) -> Option<usize> {
    let mut finite = true;
    dispatch(
        InstructionSet::detect(),
        FiniteVectors {
            vectors,
            finite: &mut finite,
        },
    );
    first_non_finite_in(first, vectors, finite)
}

/// The lower of two particles, either of which may be absent: how the chunks' findings of a
/// non-finite force merge.
#[must_use]
pub fn lowest_particle(a: Option<usize>, b: Option<usize>) -> Option<usize> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The first particle of the chunk `vectors` (whose first particle is `first`) with a
/// non-finite vector, unless the kernel found the chunk `finite`: searched only in the rare
/// chunk that has one.
fn first_non_finite_in(first: usize, vectors: &[DVec3], finite: bool) -> Option<usize> {
    (!finite).then(|| {
        first
            + vectors
                .iter()
                .position(|v| !v.is_finite())
                .expect("a chunk with a non-finite vector")
    })
}

/// Whether every component of `vectors` is finite, into `finite`.
struct FiniteVectors<'a> {
    vectors: &'a [DVec3],
    finite: &'a mut bool,
}

impl Kernel for FiniteVectors<'_> {
    #[inline(always)]
    fn run(self) {
        *self.finite = all_finite(self.vectors);
    }
}

/// The closing half kick of a chunk's particles (M.32), as [`KickDrift`] does its own; `finite`
/// is cleared if a force is NaN or infinite.
struct Kick<'a> {
    velocity: &'a mut [DVec3],
    force: &'a [DVec3],
    mass: &'a [f64],
    dt: f64,
    finite: &'a mut bool,
}

impl Kernel for Kick<'_> {
    #[inline(always)]
    fn run(self) {
        let mut scratch = KickScratch::default();
        for ((v, f), mass) in self
            .velocity
            .chunks_mut(BLOCK)
            .zip(self.force.chunks(BLOCK))
            .zip(self.mass.chunks(BLOCK))
        {
            let kicks = half_kicks(self.dt, mass, &mut scratch.factors);
            kick_block::<false>(v, f, kicks, &mut scratch.spread);
        }
        *self.finite = all_finite(self.force);
    }
}

/// Half kick of the angular velocities of a chunk's particles (M.62), `ω += (dt/2) τ / I` with
/// `I = (2/5) m r²`, over the components as [`KickDrift`] does. It goes with each half kick of
/// the velocities, so ω follows the same velocity Verlet scheme; the spheres' orientation is
/// not tracked (nothing depends on it).
struct AngularKick<'a> {
    omega: &'a mut [DVec3],
    torque: &'a [DVec3],
    mass: &'a [f64],
    radius: &'a [f64],
    dt: f64,
}

impl Kernel for AngularKick<'_> {
    #[inline(always)]
    fn run(self) {
        self.kick::<false>();
    }
}

impl AngularKick<'_> {
    /// The half kick (twice if `FOLDED`: see [`Opening::AfterClosingKick`]).
    #[inline(always)]
    fn kick<const FOLDED: bool>(self) {
        let mut scratch = KickScratch::default();
        for (((w, t), mass), radius) in self
            .omega
            .chunks_mut(BLOCK)
            .zip(self.torque.chunks(BLOCK))
            .zip(self.mass.chunks(BLOCK))
            .zip(self.radius.chunks(BLOCK))
        {
            let kicks = &mut scratch.factors[..mass.len()];
            for ((kick, &mass), &radius) in kicks.iter_mut().zip(mass).zip(radius) {
                *kick = 0.5 * self.dt / rolling::sphere_inertia(mass, radius);
            }
            kick_block::<FOLDED>(w, t, kicks, &mut scratch.spread);
        }
    }
}

/// The scratch of a kick over blocks: a block's factors, each spread to its three components,
/// and its particles' squared speeds.
struct KickScratch {
    factors: [f64; BLOCK],
    spread: [f64; 3 * BLOCK],
    speeds_squared: [f64; BLOCK],
}

impl Default for KickScratch {
    fn default() -> Self {
        Self {
            factors: [0.0; BLOCK],
            spread: [0.0; 3 * BLOCK],
            speeds_squared: [0.0; BLOCK],
        }
    }
}

/// One block's half kick, `vectors += factor × rates` (velocities by forces, spins by torques),
/// component by component, with each particle's `factors` spread to its components; twice if
/// `FOLDED`, as `(v + k r) + k r` (see [`Opening::AfterClosingKick`]).
#[inline(always)]
fn kick_block<const FOLDED: bool>(
    vectors: &mut [DVec3],
    rates: &[DVec3],
    factors: &[f64],
    spread_factors: &mut [f64; 3 * BLOCK],
) {
    let factors = spread(factors, spread_factors);
    for (v, (&rate, &factor)) in components_mut(vectors)
        .iter_mut()
        .zip(components(rates).iter().zip(factors))
    {
        let closed = if FOLDED { *v + factor * rate } else { *v };
        *v = closed + factor * rate;
    }
}

/// Whether every component of `vectors` is finite.
///
/// `c × 0` is exactly ±0 for a finite component and NaN for an infinite or NaN one, and a NaN
/// stays NaN through any sum, so the components are finite if and only if every lane's sum of
/// `c × 0` is 0. Two vector instructions per register of components, against five for the
/// lane-wise `is_finite` test with its masks packed and combined; no branch per component.
#[inline(always)]
fn all_finite(vectors: &[DVec3]) -> bool {
    let mut lanes = [0.0; FINITE_LANES];
    fold_lanes(&mut lanes, components(vectors), |lane, c| lane + c * 0.0);
    lanes.iter().all(|&lane| lane == 0.0)
}

/// Lanes of [`all_finite`]: two AVX-512 registers (four AVX2), so that two or more chains of
/// adds, each waiting only on its own register's last add, run side by side.
const FINITE_LANES: usize = 16;

/// Each of `factors` three times, into `spread` (at least three times as long): the factor of
/// every component of its particle's vector.
#[inline(always)]
fn spread<'s>(factors: &[f64], spread: &'s mut [f64]) -> &'s [f64] {
    let spread = &mut spread[..3 * factors.len()];
    for (components, &factor) in spread.chunks_exact_mut(3).zip(factors) {
        components.fill(factor);
    }
    spread
}

/// The components of `vectors`, x, y, z of the first, then of the next.
#[inline(always)]
fn components(vectors: &[DVec3]) -> &[f64] {
    bytemuck::cast_slice(vectors)
}

/// The components of `vectors`, to write.
#[inline(always)]
fn components_mut(vectors: &mut [DVec3]) -> &mut [f64] {
    bytemuck::cast_slice_mut(vectors)
}

/// Particles per block of [`half_kicks`]: the quotients stay in the first-level cache.
const BLOCK: usize = 64;

/// The half kicks' factors `(dt/2) / m` [s/kg] of a block of particles of `mass` \[kg\] (at
/// most [`BLOCK`]), into `kicks`. In a loop of their own the divisions are vectorised (two per
/// instruction even in the x86-64 baseline), where a division per particle inside the kick's
/// loop ran one at a time; the quotients are the same numbers. On the 19.2k LIGGGHTS bed the
/// step ran 2.6-5.6 % faster at 1 thread. The angular half kick's divisions by the inertia, done
/// the same way, gained nothing measurable (1.00) and stay in their loop.
#[inline(always)]
fn half_kicks<'k>(dt: f64, mass: &[f64], kicks: &'k mut [f64; BLOCK]) -> &'k [f64] {
    let kicks = &mut kicks[..mass.len()];
    for (kick, &mass) in kicks.iter_mut().zip(mass) {
        *kick = 0.5 * dt / mass;
    }
    kicks
}

/// Runs `visit(first, chunk)` for every chunk (`first`: the index of its first particle), in
/// parallel when `parallel`, and returns what they returned merged into `identity` by `merge`
/// (associative and commutative, so the thread count does not change the result).
fn each_chunk<T: Send, R: Copy + Send + Sync>(
    chunks: Vec<T>,
    parallel: bool,
    identity: R,
    merge: impl Fn(R, R) -> R + Sync,
    visit: impl Fn(usize, T) -> R + Sync,
) -> R {
    // The members of the thread team take the same share of the chunks at every pass.
    crate::team::fold_items(
        parallel,
        chunks,
        || identity,
        |partial, c, chunk| merge(partial, visit(c * CHUNK, chunk)),
        &merge,
    )
}

/// The first particle field that is NaN or infinite, as `(index, field name)`: the lowest
/// such particle, and of its fields the first of position, velocity, force. Each field is
/// tested by the vector kernel of [`first_non_finite_vector`] (the scalar test of every
/// particle's three vectors cost about a step's tenth at each output on the 19.2k LIGGGHTS
/// bed).
#[must_use]
pub fn first_non_finite(particles: &Particles) -> Option<(usize, &'static str)> {
    [
        (&particles.position, "position"),
        (&particles.velocity, "velocity"),
        (&particles.force, "force"),
    ]
    .into_iter()
    .filter_map(|(vectors, field)| first_non_finite_vector(vectors).map(|k| (k, field)))
    // The lowest particle; of its fields, the first listed (`min_by_key` keeps the first of
    // equal keys).
    .min_by_key(|&(k, _)| k)
}

/// Largest stable time step of this integrator for a contact of stiffness `k` [N/m] between
/// bodies of effective mass `m*` \[kg\] with damping ratio `ξ` (damping `2ξ√(m* k)`, eq. 26)
/// (M.70, derived in docs/stability.md):
///
/// ```text
/// dt_max = 2 (√(1 + ξ²) − ξ) / ω,     ω = √(k / m*)      [s]
/// ```
///
/// Velocity Verlet with the damper fed the half-step velocity (M.30-M.32) is, for a linear
/// spring, the map `v' = (1 − 2ξω dt) v − ω² dt x`, `x' = x + dt v'` on `(x, v(t − dt/2))`; its
/// eigenvalues stay in the unit disk iff `(ω dt)² + 4ξ (ω dt) ≤ 4`. ξ = 0 gives the familiar
/// `ω dt ≤ 2`; damping lowers it (ξ = 1: 0.83/ω, ξ = 5: 0.198/ω) because the damper is explicit.
/// Infinite for `k ≤ 0` (no restoring stiffness, nothing to go unstable).
#[must_use]
pub fn stability_limit(stiffness: f64, effective_mass: f64, damping_ratio: f64) -> f64 {
    if stiffness <= 0.0 {
        return f64::INFINITY;
    }
    let omega = (stiffness / effective_mass).sqrt();
    2.0 * ((1.0 + damping_ratio * damping_ratio).sqrt() - damping_ratio) / omega
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particles::ParticleInit;

    /// `count` spheres of radius 1 at x = k, moving along y at k m/s, with force (0, 0, k) N and
    /// torque (k, 0, 0) N·m on particle k.
    fn row(count: usize) -> (Particles, Rotation) {
        let mut particles = Particles::default();
        for k in 0..count {
            particles.push(
                ParticleInit {
                    position: DVec3::new(k as f64, 0.0, 0.0),
                    velocity: DVec3::new(0.0, k as f64, 0.0),
                    radius: 1.0,
                    material: 0,
                },
                3.0 / (4.0 * std::f64::consts::PI), // mass 1 kg
            );
            particles.force[k] = DVec3::new(0.0, 0.0, k as f64);
        }
        let mut rotation = Rotation::new(count, 0);
        for (k, t) in rotation.torque.iter_mut().enumerate() {
            *t = DVec3::new(k as f64, 0.0, 0.0);
        }
        (particles, rotation)
    }

    #[test]
    fn each_particle_is_kicked_by_its_own_mass() {
        // Masses that differ from one particle to the next, over chunks and blocks that do not
        // end together: a quotient taken for the wrong particle would change the velocities.
        let count = 2 * CHUNK + 3 * BLOCK + 5;
        let mut particles = Particles::default();
        for k in 0..count {
            particles.push(
                ParticleInit {
                    position: DVec3::ZERO,
                    velocity: DVec3::new(1.0, -2.0, 0.5),
                    radius: 1.0 + 0.1 * (k % 7) as f64,
                    material: 0,
                },
                1000.0 + (k % 11) as f64,
            );
            particles.force[k] = DVec3::new(3.0, k as f64, -1.0);
        }
        let (start, force) = (particles.velocity.clone(), particles.force.clone());
        let dt = 1e-3;
        kick_drift(
            &mut particles,
            None,
            None,
            (dt, DVec3::ZERO),
            Opening::AfterStep,
        );
        particles.force.clone_from(&force);
        assert_eq!(kick(&mut particles, None, dt), None);
        for k in 0..count {
            // The per-particle formula of (M.30) and (M.32), evaluated one particle at a time.
            let half_kick = 0.5 * dt / particles.mass[k] * force[k];
            assert_eq!(
                particles.velocity[k],
                start[k] + half_kick + half_kick,
                "particle {k}"
            );
        }
    }

    /// Every build of the kernels the processor runs gives bitwise what the per-particle
    /// formulas (M.30-M.32, M.62) give one particle at a time, over blocks that do not end
    /// together with the vectors: a factor spread to the wrong component, or an operation in
    /// another order, would change a bit somewhere among these irregular numbers.
    #[test]
    fn every_build_kicks_drifts_and_turns_as_the_formulas_do() {
        let count = 2 * BLOCK + 13;
        let irregular = |k: usize, c: f64| {
            let t = (k as f64 + 1.0) * c;
            DVec3::new(t.sin(), (1.7 * t).cos() * 3.0, (0.3 * t).sin() * 1e-3)
        };
        let position: Vec<DVec3> = (0..count).map(|k| irregular(k, 0.37) * 1e-4).collect();
        let velocity: Vec<DVec3> = (0..count).map(|k| irregular(k, 1.13)).collect();
        let force: Vec<DVec3> = (0..count).map(|k| irregular(k, 2.71) * 1e-5).collect();
        let omega: Vec<DVec3> = (0..count).map(|k| irregular(k, 0.91) * 1e2).collect();
        let torque: Vec<DVec3> = (0..count).map(|k| irregular(k, 1.61) * 1e-9).collect();
        let mass: Vec<f64> = (0..count)
            .map(|k| 1e-10 * (1.0 + 0.37 * (k % 13) as f64))
            .collect();
        let radius: Vec<f64> = (0..count)
            .map(|k| 1e-5 * (1.0 + 0.11 * (k % 7) as f64))
            .collect();
        let (dt, gravity) = (1.3e-7, DVec3::new(0.1, -0.2, -9.81));
        for set in InstructionSet::available() {
            // Folded: the last step's closing kick first, with the same forces (M.32, M.30).
            for folded in [false, true] {
                let (mut x, mut v, mut f) = (position.clone(), velocity.clone(), force.clone());
                let mut fastest = 0.0;
                let kick_drift = KickDrift {
                    position: &mut x,
                    velocity: &mut v,
                    force: &mut f,
                    mass: &mass,
                    dt,
                    gravity,
                    max_speed_squared: &mut fastest,
                };
                dispatch_folded(set, kick_drift, folded);
                let mut expected_fastest: f64 = 0.0;
                for k in 0..count {
                    let kick = 0.5 * dt / mass[k];
                    let closed = if folded {
                        velocity[k] + kick * force[k]
                    } else {
                        velocity[k]
                    };
                    let half = closed + kick * force[k];
                    expected_fastest = expected_fastest.max(half.length_squared());
                    let name = format!("{}, folded {folded}", set.name());
                    assert_eq!(v[k], half, "{name}: v of {k}");
                    assert_eq!(x[k], position[k] + dt * half, "{name}: x of {k}");
                    assert_eq!(f[k], mass[k] * gravity, "{name}: weight of {k}");
                }
                assert_eq!(fastest, expected_fastest, "{}", set.name());
            }

            let mut finite = false;
            let mut v = velocity.clone();
            dispatch(
                set,
                Kick {
                    velocity: &mut v,
                    force: &force,
                    mass: &mass,
                    dt,
                    finite: &mut finite,
                },
            );
            assert!(finite, "{}", set.name());
            for k in 0..count {
                let expected = velocity[k] + 0.5 * dt / mass[k] * force[k];
                assert_eq!(v[k], expected, "{}: closing kick of {k}", set.name());
            }

            for folded in [false, true] {
                let mut w = omega.clone();
                let kick = AngularKick {
                    omega: &mut w,
                    torque: &torque,
                    mass: &mass,
                    radius: &radius,
                    dt,
                };
                dispatch_folded(set, kick, folded);
                for k in 0..count {
                    let factor = 0.5 * dt / rolling::sphere_inertia(mass[k], radius[k]);
                    let closed = if folded {
                        omega[k] + factor * torque[k]
                    } else {
                        omega[k]
                    };
                    let expected = closed + factor * torque[k];
                    assert_eq!(w[k], expected, "{}: ω of {k}, folded {folded}", set.name());
                }
            }

            // A NaN in the last component of the last particle clears `finite`.
            let mut bad = force.clone();
            bad[count - 1].z = f64::NAN;
            let mut finite = true;
            dispatch(
                set,
                Kick {
                    velocity: &mut velocity.clone(),
                    force: &bad,
                    mass: &mass,
                    dt,
                    finite: &mut finite,
                },
            );
            assert!(!finite, "{}", set.name());
        }
    }

    /// The test a step makes of its forces when its closing kick is left to the next opening
    /// pass finds the lowest non-finite force in whichever chunk it is, and nothing in finite
    /// forces.
    #[test]
    fn the_lowest_non_finite_force_is_found_in_any_chunk() {
        let count = 3 * CHUNK + 17;
        let mut force: Vec<DVec3> = (0..count).map(|k| DVec3::splat(k as f64)).collect();
        assert_eq!(first_non_finite_vector(&force), None);
        force[count - 1].z = f64::INFINITY;
        assert_eq!(first_non_finite_vector(&force), Some(count - 1));
        force[CHUNK + 5].y = f64::NAN;
        assert_eq!(first_non_finite_vector(&force), Some(CHUNK + 5));
        force[2].x = f64::NEG_INFINITY;
        assert_eq!(first_non_finite_vector(&force[..10]), Some(2));
    }

    /// The output's test of the state names the lowest particle with a non-finite vector, and
    /// of its fields the first of position, velocity, force, whichever chunk the fields' first
    /// bad values lie in: the rule of the scalar search it replaced.
    #[test]
    fn the_state_test_names_the_lowest_particle_and_its_first_bad_field() {
        let count = 3 * CHUNK + 17;
        let (mut particles, _) = row(count);
        assert_eq!(first_non_finite(&particles), None);
        particles.force[count - 1].x = f64::NAN;
        assert_eq!(first_non_finite(&particles), Some((count - 1, "force")));
        particles.position[count - 1].y = f64::INFINITY;
        assert_eq!(first_non_finite(&particles), Some((count - 1, "position")));
        particles.velocity[CHUNK + 3].z = f64::NAN;
        particles.force[CHUNK + 3].z = f64::NAN;
        assert_eq!(first_non_finite(&particles), Some((CHUNK + 3, "velocity")));
        particles.force[7].x = f64::NEG_INFINITY;
        assert_eq!(first_non_finite(&particles), Some((7, "force")));
    }

    /// Any one infinite or NaN component, in any lane or the remainder, makes a set of vectors
    /// not finite; the extremes of the finite numbers (the largest, the smallest subnormal,
    /// both zeros) do not.
    #[test]
    fn one_non_finite_component_anywhere_is_found() {
        let count = 2 * FINITE_LANES + 5; // 111 components: six full groups and a remainder
        let extremes = [f64::MAX, f64::MIN, 5e-324, -0.0, 0.0, 1.0];
        let finite: Vec<DVec3> = (0..count)
            .map(|k| {
                let e = |i: usize| extremes[(3 * k + i) % extremes.len()];
                DVec3::new(e(0), e(1), e(2))
            })
            .collect();
        assert!(all_finite(&finite));
        assert!(all_finite(&[]));
        for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            for component in 0..3 * count {
                let mut vectors = finite.clone();
                components_mut(&mut vectors)[component] = bad;
                assert!(!all_finite(&vectors), "{bad} at component {component}");
            }
        }
    }

    /// The opening pass's largest |v|² is that of the fastest particle wherever it lies (in any
    /// lane, in a block's remainder, in a later block), in every build, and a NaN speed is
    /// passed over as `f64::max` passes it.
    #[test]
    fn the_fastest_particle_is_found_anywhere_in_every_build() {
        let count = 2 * BLOCK + 11;
        let slow: Vec<DVec3> = (0..count)
            .map(|k| DVec3::new(0.1, -0.2, 0.01 * (k % 11) as f64))
            .collect();
        let (mass, dt) = (vec![1.0; count], 1e-3);
        for set in InstructionSet::available() {
            for fastest in 0..count {
                let mut velocity = slow.clone();
                velocity[fastest] = DVec3::new(-0.3, 0.7, 2.0);
                velocity[(fastest + 5) % count].y = f64::NAN;
                let (mut position, mut force) =
                    (vec![DVec3::ZERO; count], vec![DVec3::ZERO; count]);
                let mut largest = 0.0;
                // No force: the kicks leave the velocities as they are.
                let kick_drift = KickDrift {
                    position: &mut position,
                    velocity: &mut velocity.clone(),
                    force: &mut force,
                    mass: &mass,
                    dt,
                    gravity: DVec3::ZERO,
                    max_speed_squared: &mut largest,
                };
                dispatch(set, kick_drift);
                let expected = velocity[fastest].length_squared();
                assert_eq!(largest, expected, "{}: fastest {fastest}", set.name());
            }
        }
    }

    #[test]
    fn one_pass_kicks_drifts_and_turns_and_the_kick_finds_non_finite_forces() {
        // Below and above the size from which the passes run in parallel, with the particle
        // whose force is not finite in the first and in the last chunk.
        for count in [10, 3 * CHUNK + 17] {
            for far in [3, count - 2] {
                let (mut particles, mut rotation) = row(count);
                let dt = 0.5;
                let mut heat_sums: Vec<f64> = (0..count).map(|k| k as f64 + 1.0).collect();
                let sums = Some(heat_sums.as_mut_slice());
                let gravity = DVec3::new(0.0, 0.0, -2.0);
                let drift = kick_drift(
                    &mut particles,
                    Some(&mut rotation),
                    sums,
                    (dt, gravity),
                    Opening::AfterStep,
                );
                // The fastest particle is the last, |v| = (count − 1) √(1 + 1/16); the square
                // root of the largest |v|² is exactly the largest |v| (rounding is monotone).
                let fastest = particles.velocity[count - 1].length();
                assert_eq!(drift.max_speed, fastest);
                assert!((fastest - (count - 1) as f64 * 1.0625_f64.sqrt()).abs() < 1e-12 * fastest);
                for k in 0..count {
                    let kf = k as f64;
                    // m = 1 kg, I = 2/5 kg·m².
                    let v = DVec3::new(0.0, kf, 0.25 * kf);
                    assert_eq!(particles.velocity[k], v);
                    assert_eq!(particles.position[k], DVec3::new(kf, 0.0, 0.0) + dt * v);
                    let w = rotation.angular_velocity[k].x;
                    assert!((w - 0.25 * kf / 0.4).abs() <= 1e-12 * kf, "ω of {k}: {w}");
                }
                // The half kick was the last reader: forces are left at the weights (m = 1 kg),
                // torques at zero.
                assert!(particles.force.iter().all(|f| *f == gravity));
                assert!(rotation.torque.iter().all(|t| *t == DVec3::ZERO));
                assert!(heat_sums.iter().all(|s| s.to_bits() == 0));
                // A force pass fills them again; the closing kick: v_z and ω grow by as much.
                let (refilled, _) = row(count);
                particles.force.clone_from(&refilled.force);
                let (_, refilled) = row(count);
                rotation.torque.clone_from(&refilled.torque);
                assert_eq!(kick(&mut particles, Some(&mut rotation), dt), None);
                for k in 0..count {
                    let kf = k as f64;
                    assert_eq!(particles.velocity[k].z, 0.5 * kf);
                    let w = rotation.angular_velocity[k].x;
                    assert!((w - 0.5 * kf / 0.4).abs() <= 1e-12 * kf, "ω of {k}: {w}");
                }
                // Without rotation the torques are neither used nor cleared.
                kick_drift(
                    &mut particles,
                    None,
                    None,
                    (dt, DVec3::ZERO),
                    Opening::AfterStep,
                );
                assert!(particles.force.iter().all(|f| *f == DVec3::ZERO));
                assert_eq!(rotation.torque, refilled.torque);
                for k in 0..count {
                    assert_eq!(particles.velocity[k].z, 0.75 * k as f64);
                }
                // The closing kick names the lowest particle whose force is not finite, in
                // whichever chunk it is.
                particles.force[count - 1].x = f64::INFINITY;
                assert_eq!(kick(&mut particles, None, dt), Some(count - 1));
                particles.force[far].y = f64::NAN;
                assert_eq!(kick(&mut particles, None, dt), Some(far.min(count - 1)));
            }
        }
    }
}
