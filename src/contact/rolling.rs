//! Rolling resistance: the constant directional torque (CDT) model of LIGGGHTS
//! `rolling_model cdt` (docs/model.md section 27.4, M.61), with a guard that keeps it from
//! reversing the relative rotation within one step.
//!
//! Conventions as in [`super::tangential`]: the torque returned acts **on i**, j receives the
//! opposite one; `ω_rel = ω_i − ω_j` (for a wall, `ω_rel = ω_i`). SI units.

use glam::DVec3;

/// Rolling-resistance torque on i (M.61):
///
/// ```text
/// M_r = −min(μ_r r* |F_n,el|,  |ω_rel| / (dt (1/I_i + 1/I_j))) ω_rel/|ω_rel|      [N·m]
/// ```
///
/// `μ_r` [–] is the rolling friction coefficient, `r*` \[m\] the effective radius, `F_n,el` \[N\] the
/// elastic normal force, `inverse_inertia_sum` = 1/I_i + 1/I_j [1/(kg·m²)] (1/I_i for a wall).
///
/// **The guard.** The CDT torque has a constant magnitude and jumps at ω_rel = 0. Applied for a
/// whole step to a relative rotation slower than `μ_r r* F dt (1/I_i + 1/I_j)`, it would reverse
/// ω_rel, and could leave it faster than before: rotational energy would be injected and the
/// sign would flip every step. The second argument of `min` is the torque that brings ω_rel
/// exactly to zero in one step (velocity Verlet applies a torque for one dt between two
/// evaluations). Below that speed the torque is viscous (∝ ω_rel), so its power −M_r·ω_rel stays
/// ≥ 0: it never adds energy, and a pair at rest relative to each other stays at rest.
#[inline(always)]
#[must_use]
pub fn rolling_torque(
    coefficient: f64,
    effective_radius: f64,
    elastic_normal_force: f64,
    relative_angular_velocity: DVec3,
    inverse_inertia_sum: f64,
    dt: f64,
) -> DVec3 {
    if coefficient == 0.0 {
        return DVec3::ZERO;
    }
    let speed = relative_angular_velocity.length();
    if speed == 0.0 {
        return DVec3::ZERO;
    }
    let full = coefficient * effective_radius * elastic_normal_force.abs();
    let stopping = speed / (dt * inverse_inertia_sum);
    -full.min(stopping) / speed * relative_angular_velocity
}

/// Moment of inertia of a solid sphere (M.62): `I = (2/5) m r²` [kg·m²].
#[inline(always)]
#[must_use]
pub fn sphere_inertia(mass: f64, radius: f64) -> f64 {
    0.4 * mass * radius * radius
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_torque_opposes_the_relative_rotation() {
        let omega = DVec3::new(0.0, 300.0, 400.0); // |ω| = 500 rad/s
        let m = rolling_torque(0.1, 1e-5, 2e-3, omega, 1.0, 1e-7);
        // μ_r r* F = 2e-9 N·m, far below the stopping torque 500 / 1e-7.
        assert!((m - DVec3::new(0.0, -1.2e-9, -1.6e-9)).length() < 1e-24);
        assert!(m.dot(omega) < 0.0);
    }

    #[test]
    fn a_slow_relative_rotation_is_stopped_not_reversed() {
        let omega = DVec3::new(1e-3, 0.0, 0.0);
        let (inverse_inertia_sum, dt) = (1e3, 1e-4);
        // μ_r r* F = 5e-2 N·m exceeds the stopping torque |ω| / (dt Σ 1/I) = 1e-2 N·m.
        let m = rolling_torque(0.5, 1e-3, 100.0, omega, inverse_inertia_sum, dt);
        // One step of this torque changes ω_rel by exactly −ω_rel.
        let change = m * dt * inverse_inertia_sum;
        assert!((change + omega).length() < 1e-18);
        assert_eq!(
            rolling_torque(0.5, 1e-3, 10.0, DVec3::ZERO, 1e3, dt),
            DVec3::ZERO
        );
    }
}
