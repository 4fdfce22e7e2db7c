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
use rayon::prelude::*;

use crate::contact::rolling;
use crate::particles::{Particles, Rotation};

/// First half: half kick then drift (M.30, M.31).
pub fn kick_drift(particles: &mut Particles, dt: f64) {
    let Particles {
        position,
        velocity,
        force,
        mass,
        ..
    } = particles;
    let update = |((x, v), (f, m)): ((&mut DVec3, &mut DVec3), (&DVec3, &f64))| {
        *v += 0.5 * dt / m * *f;
        *x += dt * *v;
    };
    if crate::worth_parallel(position.len()) {
        let rates = force.par_iter().zip(mass.par_iter());
        position
            .par_iter_mut()
            .zip(velocity.par_iter_mut())
            .zip(rates)
            .for_each(update);
    } else {
        let rates = force.iter().zip(mass.iter());
        position
            .iter_mut()
            .zip(velocity.iter_mut())
            .zip(rates)
            .for_each(update);
    }
}

/// Second half kick (M.32).
pub fn kick(particles: &mut Particles, dt: f64) {
    let Particles {
        velocity,
        force,
        mass,
        ..
    } = particles;
    let update = |(v, (f, m)): (&mut DVec3, (&DVec3, &f64))| *v += 0.5 * dt / m * *f;
    if crate::worth_parallel(velocity.len()) {
        velocity
            .par_iter_mut()
            .zip(force.par_iter().zip(mass.par_iter()))
            .for_each(update);
    } else {
        velocity
            .iter_mut()
            .zip(force.iter().zip(mass.iter()))
            .for_each(update);
    }
}

/// Half kick of the angular velocities (M.62): `ω += (dt/2) τ / I`, `I = (2/5) m r²`. Called
/// with each half kick of the velocities, so ω follows the same velocity Verlet scheme; the
/// spheres' orientation is not tracked (nothing depends on it).
pub fn kick_rotation(particles: &Particles, rotation: &mut Rotation, dt: f64) {
    let Rotation {
        angular_velocity,
        torque,
        ..
    } = rotation;
    let update = |(w, (t, (m, r))): (&mut DVec3, (&DVec3, (&f64, &f64)))| {
        *w += 0.5 * dt / rolling::sphere_inertia(*m, *r) * *t;
    };
    let shape = || particles.mass.iter().zip(&particles.radius);
    if crate::worth_parallel(angular_velocity.len()) {
        angular_velocity
            .par_iter_mut()
            .zip(
                torque
                    .par_iter()
                    .zip(particles.mass.par_iter().zip(particles.radius.par_iter())),
            )
            .for_each(update);
    } else {
        angular_velocity
            .iter_mut()
            .zip(torque.iter().zip(shape()))
            .for_each(update);
    }
}

/// The first particle field that is NaN or infinite, as `(index, field name)`.
#[must_use]
pub fn first_non_finite(particles: &Particles) -> Option<(usize, &'static str)> {
    let bad = |v: &DVec3| !v.is_finite();
    (0..particles.len()).find_map(|k| {
        if bad(&particles.position[k]) {
            Some((k, "position"))
        } else if bad(&particles.velocity[k]) {
            Some((k, "velocity"))
        } else if bad(&particles.force[k]) {
            Some((k, "force"))
        } else {
            None
        }
    })
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
