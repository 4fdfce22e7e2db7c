//! Tangential contact: a Mindlin-type spring with history, a viscous damper and a Coulomb limit
//! (docs/model.md section 27, M.56–M.59), the law of LIGGGHTS `tangential_model history` with its
//! Hertz–Mindlin stiffness.
//!
//! # Conventions
//! * `n` is the unit normal from the first body (i) to the second (j), as in `contact`.
//! * The relative tangential velocity `v_t` is that of i's contact point relative to j's (M.59).
//! * The history `ξ` \[m\] is the accumulated tangential displacement of the contact, stored in
//!   the world frame for the (first → second) direction: a pair's owner → partner, a particle →
//!   wall. It is projected into the current tangent plane at each use, keeping its length (M.57).
//! * The returned force is the force **on i** \[N\]; j receives the opposite one. SI units.

use glam::DVec3;

/// The tangential spring a contact carries from one step to the next (a pair in contact, or a
/// particle against a wall).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TangentialSpring {
    /// Tangential displacement ξ \[m\] of the first body relative to the second, world frame,
    /// turned into the current tangent plane at each use (M.58). A pair's spring changes sign
    /// when the pair's owner changes ends at a rebuild.
    pub history: DVec3,
    /// Spring energy `½ k_t |ξ|²` at the last evaluation \[J\] (M.63).
    pub spring_energy: f64,
}

impl TangentialSpring {
    /// The same spring seen from the other body.
    #[must_use]
    pub fn turned(self) -> Self {
        Self {
            history: -self.history,
            ..self
        }
    }
}

/// Effective shear modulus of two materials (M.56):
///
/// ```text
/// 1/G* = (2 − ν_i)/G_i + (2 − ν_j)/G_j,   G = E / (2 (1 + ν))      [Pa]
/// ```
///
/// Mindlin (1949); the form of LIGGGHTS `tangential_model history` with Hertz stiffness.
#[must_use]
pub fn effective_shear_modulus(
    youngs_i: f64,
    poisson_i: f64,
    youngs_j: f64,
    poisson_j: f64,
) -> f64 {
    let shear_i = youngs_i / (2.0 * (1.0 + poisson_i));
    let shear_j = youngs_j / (2.0 * (1.0 + poisson_j));
    1.0 / ((2.0 - poisson_i) / shear_i + (2.0 - poisson_j) / shear_j)
}

/// How much faster a sticking contact oscillates tangentially than normally, as the ratio of
/// their times (M.64):
///
/// ```text
/// t_t / t_n = √(2/7 · k_n/k_t),   k_t/k_n = 4 G*/E*      [–]
/// ```
///
/// The tangential spring k_t = 8 G* a acts against the reduced mass 2/7 m* (rotation included),
/// the normal one, k_n = 2 E* a, against m*. 0.589 for ν = 0.3. It scales the contact time and,
/// below 1, the stability limit of M.70.
#[must_use]
pub fn sticking_time_factor(effective_shear_modulus: f64, effective_modulus: f64) -> f64 {
    (2.0 / 7.0 * effective_modulus / (4.0 * effective_shear_modulus)).sqrt()
}

/// Mindlin tangential stiffness (M.57): `k_t = 8 G* a`, `a = √(r* δ)` [N/m]; 0 for δ ≤ 0.
#[inline(always)]
#[must_use]
pub fn stiffness(effective_shear_modulus: f64, effective_radius: f64, overlap: f64) -> f64 {
    if overlap <= 0.0 {
        return 0.0;
    }
    8.0 * effective_shear_modulus * (effective_radius * overlap).sqrt()
}

/// Tangential damping coefficient (M.57): `γ_t = 2 ξ √(m* k_t)` [N·s/m], the critical-damping
/// form of M.10 with the same damping ratio ξ as the normal law. With ξ from a restitution
/// coefficient (M.55) this is LIGGGHTS' `γ_t = 2 √(5/6) (−β) √(S_t m*)`, `S_t = k_t`.
#[inline(always)]
#[must_use]
pub fn damping_coefficient(damping_ratio: f64, effective_mass: f64, stiffness: f64) -> f64 {
    2.0 * damping_ratio * (effective_mass * stiffness.max(0.0)).sqrt()
}

/// The history turned into the current tangent plane, keeping its length (M.58):
///
/// ```text
/// ξ' = ξ − (ξ·n) n,   ξ'' = ξ' |ξ| / |ξ'|      (ξ'' = 0 if ξ' = 0)
/// ```
///
/// The pair's frame rotates with the pair; dropping only the normal part would shrink the spring
/// (and its force) for no physical reason, so the length is restored, as LIGGGHTS and LAMMPS
/// (`rotate_rescale_vec`) do. A history parallel to `n` (a pair turned by 90° within one step)
/// has no tangential direction left and is reset.
#[inline(always)]
#[must_use]
pub fn rotate_history(history: DVec3, normal: DVec3) -> DVec3 {
    let length_squared = history.length_squared();
    if length_squared == 0.0 {
        return DVec3::ZERO;
    }
    let projected = history - history.dot(normal) * normal;
    let projected_squared = projected.length_squared();
    if projected_squared == 0.0 {
        return DVec3::ZERO;
    }
    projected * (length_squared / projected_squared).sqrt()
}

/// Outcome of [`tangential_force`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TangentialForce {
    /// Force on i \[N\], in the tangent plane.
    pub force: DVec3,
    /// History after this step \[m\].
    pub history: DVec3,
    /// True when the spring alone exceeded the Coulomb limit: the contact slides and its spring
    /// was rescaled. A sticking contact whose damper was capped at the limit is not sliding.
    pub sliding: bool,
}

/// The tangential force of one step (M.59), given the history already turned into the tangent
/// plane ([`rotate_history`]), the tangential relative velocity `v_t` and the time the contact
/// acts over (`dt`; 0 at the set-up evaluation, which takes the spring as it stands):
///
/// ```text
/// ξ ← ξ + v_t dt
/// F_s = −k_t ξ                                             (spring)
/// if |F_s| > F_max:  F_t = F_max F_s/|F_s|,  ξ ← −F_t/k_t    (sliding: the spring is rescaled)
/// else:              F_t = F_s − γ_t v_t,  scaled down to |F_t| = F_max if it is beyond   (sticking)
/// ```
///
/// `limit` is the Coulomb limit `F_max = μ |F_n|` \[N\], or `None` for a bonded neck, which sticks
/// (docs/model.md section 27.5). As in LIGGGHTS, whether the contact slides is decided by the
/// spring force alone, and a sliding contact carries no damping force: the slip itself
/// dissipates. Unlike LIGGGHTS, a sticking contact's damping force may not carry it beyond the
/// limit either (LAMMPS and MercuryDPM cap the total force): |F_t| ≤ F_max always. The two differ
/// only where a spring still short of its limit meets a fast slip, a contact met already sliding
/// (a sphere set down sliding, or the first step of a contact of a fast pair), whose spring has
/// had no time to load: there LIGGGHTS' damping force alone, `γ_t |v_t|`, can exceed Coulomb's
/// limit many times over.
#[inline(always)]
#[must_use]
pub fn tangential_force(
    history: DVec3,
    tangential_velocity: DVec3,
    dt: f64,
    stiffness: f64,
    damping: f64,
    limit: Option<f64>,
) -> TangentialForce {
    let history = history + tangential_velocity * dt;
    let spring = -stiffness * history;
    let Some(limit) = limit else {
        return TangentialForce {
            force: spring - damping * tangential_velocity,
            history,
            sliding: false,
        };
    };
    // Compared squared: no square root for a contact within its limit. One test for both
    // branches, so that a vector kernel takes one square root per lane.
    let sliding = spring.length_squared() > limit * limit;
    let force = if sliding {
        spring
    } else {
        spring - damping * tangential_velocity
    };
    let force_squared = force.length_squared();
    if force_squared > limit * limit {
        // A force of zero length cannot exceed a limit ≥ 0, so the division is safe; and
        // k_t > 0, so a sliding spring ξ = −F_t/k_t is ξ scaled like the force.
        let scale = limit / force_squared.sqrt();
        return TangentialForce {
            force: force * scale,
            history: if sliding { history * scale } else { history },
            sliding,
        };
    }
    TangentialForce {
        force,
        history,
        sliding,
    }
}

/// Elastic energy of the tangential spring (M.63): `U_t = ½ k_t |ξ|²` \[J\].
#[inline(always)]
#[must_use]
pub fn spring_energy(stiffness: f64, history: DVec3) -> f64 {
    0.5 * stiffness * history.length_squared()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shear_modulus_of_equal_materials() {
        // E = 2e8, ν = 0.3: G = 7.6923e7, G* = G / (2 (2 − ν)) = 2.2624e7.
        let g = 2e8 / 2.6;
        let expected = g / (2.0 * 1.7);
        let g_star = effective_shear_modulus(2e8, 0.3, 2e8, 0.3);
        assert!((g_star / expected - 1.0).abs() < 1e-14);
        // Mindlin ratio k_t/k_n = 8 G* / (2 E*) = 2 (1 − ν) / (2 − ν) for equal materials.
        let e_star = super::super::hertz::effective_modulus(2e8, 0.3, 2e8, 0.3);
        let ratio =
            stiffness(g_star, 1e-5, 1e-7) / super::super::hertz::stiffness(e_star, 1e-5, 1e-7);
        assert!((ratio - 2.0 * 0.7 / 1.7).abs() < 1e-14, "{ratio}");
    }

    #[test]
    fn rotating_the_history_keeps_its_length_and_makes_it_tangential() {
        let history = DVec3::new(1e-6, 2e-6, -0.5e-6);
        let normal = DVec3::new(0.3, -0.2, 1.0).normalize();
        let turned = rotate_history(history, normal);
        assert!((turned.length() / history.length() - 1.0).abs() < 1e-14);
        assert!(turned.dot(normal).abs() < 1e-15 * history.length());
        // Already tangential: unchanged (to round-off).
        let tangential = DVec3::new(1e-6, 0.0, 0.0);
        assert!((rotate_history(tangential, DVec3::Z) - tangential).length() < 1e-22);
        // Parallel to the normal: nothing tangential is left.
        assert_eq!(rotate_history(DVec3::Z * 1e-6, DVec3::Z), DVec3::ZERO);
    }

    #[test]
    fn zero_tangential_velocity_gives_the_spring_force_alone() {
        let history = DVec3::new(2e-7, 0.0, 0.0);
        let out = tangential_force(history, DVec3::ZERO, 1e-7, 1e4, 3.0, Some(1.0));
        assert_eq!(out.force, DVec3::new(-2e-3, 0.0, 0.0));
        assert_eq!(out.history, history);
        assert!(!out.sliding);
    }

    #[test]
    fn coulomb_cap_limits_the_force_and_rescales_the_spring() {
        let (k, dt, v) = (1e4, 1e-6, DVec3::new(0.0, 3.0, 0.0));
        let history = DVec3::new(0.0, 1e-4, 0.0);
        // Spring force after the increment: −1e4 × (1e-4 + 3e-6) = −1.03 N, above a 0.5 N limit.
        let out = tangential_force(history, v, dt, k, 2.0, Some(0.5));
        assert!(out.sliding);
        assert!((out.force - DVec3::new(0.0, -0.5, 0.0)).length() < 1e-15);
        assert!((out.history - DVec3::new(0.0, 0.5e-4, 0.0)).length() < 1e-19);
        // The rescaled spring gives exactly the capped force.
        assert!((-k * out.history - out.force).length() < 1e-15);
        // Below the limit: spring plus damper.
        let out = tangential_force(history, v, dt, k, 2.0, Some(10.0));
        assert!(!out.sliding);
        assert!((out.force - DVec3::new(0.0, -1.03 - 6.0, 0.0)).length() < 1e-12);
        // A bonded neck (no limit) never slides.
        assert!(!tangential_force(history, v, dt, k, 2.0, None).sliding);
    }

    /// A contact met sliding fast with an unloaded spring (a sphere set down sliding, at the
    /// set-up evaluation, which takes the spring as it stands): its damping force alone would be
    /// γ_t |v_t| = 2 × 3 = 6 N, twelve times a 0.5 N limit (LIGGGHTS applies it whole).
    #[test]
    fn a_damper_may_not_carry_a_sticking_contact_beyond_the_limit() {
        let (k, v) = (1e4, DVec3::new(0.0, 3.0, 0.0));
        let out = tangential_force(DVec3::ZERO, v, 0.0, k, 2.0, Some(0.5));
        // At the limit, against the slip; the spring, within its own limit, is kept as it is.
        assert!((out.force - DVec3::new(0.0, -0.5, 0.0)).length() < 1e-15);
        assert_eq!(out.history, DVec3::ZERO);
        assert!(!out.sliding);
        // A spring loaded to 0.4 N, against a slip that adds 6 N: capped at 0.5 N too.
        let history = DVec3::new(0.0, 0.4 / k, 0.0);
        let out = tangential_force(history, v, 0.0, k, 2.0, Some(0.5));
        assert!((out.force.length() - 0.5).abs() < 1e-15);
        assert_eq!(out.history, history);
    }

    #[test]
    fn a_zero_limit_gives_no_force_and_no_history() {
        let out = tangential_force(DVec3::X * 1e-6, DVec3::Y, 1e-7, 1e4, 1.0, Some(0.0));
        assert_eq!(out.force.length(), 0.0);
        assert_eq!(out.history.length(), 0.0);
    }
}
