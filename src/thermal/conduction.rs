//! Conductance of a contact: heat flows `Q_i = H (T_j − T_i)` into particle i \[W\], with the
//! conductance H [W/K] from one of the named models. They differ by large factors for Hertzian
//! contacts (the pipe model scales with a², Batchelor & O'Brien with a), so the scene must choose.
//!
//! Both are functions of the Hertz contact radius `a = √(r* δ)` (M.40) \[m\]. A third, LIGGGHTS'
//! (M.79), takes the geometric intersection of the two spheres instead.

/// Hertz contact radius `a = √(r* δ)` (M.40) \[m\]; 0 without overlap.
#[must_use]
#[inline(always)]
pub fn contact_radius(effective_radius: f64, overlap: f64) -> f64 {
    if overlap > 0.0 {
        (effective_radius * overlap).sqrt()
    } else {
        0.0
    }
}

/// Batchelor & O'Brien (1977) conductance of two spheres pressed together (M.41) [W/K]:
///
/// ```text
/// H = 2 k* a,   k* = 2 k_i k_j / (k_i + k_j)
/// ```
///
/// Two constriction resistances `1/(4 k a)` in series. For a sphere on a plane wall the same form
/// holds with the wall's conductivity as k_j and `a = √(r_i δ)`.
#[must_use]
#[inline]
pub fn batchelor_obrien(conductivity_i: f64, conductivity_j: f64, contact_radius: f64) -> f64 {
    let k_star = 2.0 * conductivity_i * conductivity_j / (conductivity_i + conductivity_j);
    2.0 * k_star * contact_radius
}

/// Radius of the circle in which the surfaces of two spheres of radii `radius_i`, `radius_j`
/// intersect when their centres are `distance` apart (M.79) \[m\]; 0 when they do not touch:
///
/// ```text
/// a_g² = (r_i + r_j − d)(d + r_i − r_j)(d − r_i + r_j)(d + r_i + r_j) / (4 d²)
/// ```
///
/// For equal spheres a_g² = r δ − δ²/4, about twice the Hertz a² = r* δ.
#[must_use]
#[inline(always)]
pub fn intersection_radius(radius_i: f64, radius_j: f64, distance: f64) -> f64 {
    let product = (radius_i + radius_j - distance)
        * (distance + radius_i - radius_j)
        * (distance - radius_i + radius_j)
        * (distance + radius_i + radius_j);
    if product > 0.0 && distance > 0.0 {
        (product / (4.0 * distance * distance)).sqrt()
    } else {
        0.0
    }
}

/// Conductance through the geometric overlap (M.79) [W/K], the contact model of LIGGGHTS'
/// `fix heat/gran/conduction` with its default `contact_area overlap`:
///
/// ```text
/// H = 2 k* √A,   A = π a_g²,   k* = 2 k_i k_j / (k_i + k_j)
/// ```
///
/// M.41 with the side of a square of the intersection circle's area for the contact radius. For
/// equal spheres and δ ≪ r it is √(2π) ≈ 2.51 times M.41 with the Hertz radius.
#[must_use]
#[inline]
pub fn overlap_area(conductivity_i: f64, conductivity_j: f64, intersection_radius: f64) -> f64 {
    batchelor_obrien(
        conductivity_i,
        conductivity_j,
        std::f64::consts::PI.sqrt() * intersection_radius,
    )
}

/// "Thermal pipe" conductance of the coupled thermo-mechanical model of Quintana-Ruiz & Campello
/// (2020, J. Braz. Soc. Mech. Sci. Eng. 42:387, reference \[8\] of the bond paper) (M.42) [W/K]:
///
/// ```text
/// H = k̄ π a² / d,   k̄ = (r_i + r_j) / (r_i/k_i + r_j/k_j)
/// ```
///
/// a cylinder of cross-section π a² joining the two centres, `d = r_i + r_j − δ` apart, made of
/// the two materials in series over lengths r_i and r_j.
#[must_use]
#[inline(always)]
pub fn thermal_pipe(
    conductivity_i: f64,
    conductivity_j: f64,
    radius_i: f64,
    radius_j: f64,
    contact_radius: f64,
    distance: f64,
) -> f64 {
    let k_bar = (radius_i + radius_j) / (radius_i / conductivity_i + radius_j / conductivity_j);
    k_bar * std::f64::consts::PI * contact_radius * contact_radius / distance
}

/// Thermal-pipe conductance of a sphere against an isothermal wall (M.43) [W/K]: the particle's
/// half of the pipe, `H = k_i π a² / s`, with `s = r_i − δ` the distance from the centre to the wall.
#[must_use]
#[inline]
pub fn thermal_pipe_wall(conductivity: f64, contact_radius: f64, centre_distance: f64) -> f64 {
    conductivity * std::f64::consts::PI * contact_radius * contact_radius / centre_distance
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_materials_reduce_to_the_textbook_forms() {
        let a = contact_radius(7.5e-6, 1e-8);
        assert!((a - (7.5e-14_f64).sqrt()).abs() < 1e-20);
        assert!((batchelor_obrien(20.0, 20.0, a) - 2.0 * 20.0 * a).abs() < 1e-18);
        let pipe = thermal_pipe(20.0, 20.0, 1.5e-5, 1.5e-5, a, 3e-5);
        assert!((pipe - 20.0 * std::f64::consts::PI * a * a / 3e-5).abs() < 1e-18);
    }

    #[test]
    fn the_intersection_circle_is_that_of_the_geometry() {
        // Unequal spheres: the plane of intersection lies x = (d² + r_i² − r_j²)/(2d) from
        // centre i, and a_g² = r_i² − x² (Pythagoras on sphere i); the same from sphere j.
        let (ri, rj, d) = (2.0e-5, 1.2e-5, 3.1e-5);
        let x = (d * d + ri * ri - rj * rj) / (2.0 * d);
        let a = intersection_radius(ri, rj, d);
        assert!((a * a / (ri * ri - x * x) - 1.0).abs() < 1e-12);
        assert!((a * a / (rj * rj - (d - x) * (d - x)) - 1.0).abs() < 1e-12);
        // Equal spheres: a_g² = r δ − δ²/4, against the Hertz a² = r* δ = r δ / 2.
        let (r, delta) = (1.5e-5, 1e-8);
        let a = intersection_radius(r, r, 2.0 * r - delta);
        assert!((a * a / (r * delta - 0.25 * delta * delta) - 1.0).abs() < 1e-9);
        // Apart, touching, or one inside the other: no circle.
        assert_eq!(intersection_radius(r, r, 2.0 * r + 1e-9), 0.0);
        assert_eq!(intersection_radius(r, r, 2.0 * r), 0.0);
        assert_eq!(intersection_radius(2.0 * r, r, 0.5 * r), 0.0);
        // LIGGGHTS' conductance is √(2π) × B&O with the Hertz radius for δ ≪ r (to δ/r).
        let ratio = overlap_area(20.0, 20.0, a)
            / batchelor_obrien(20.0, 20.0, contact_radius(0.5 * r, delta));
        assert!((ratio / (2.0 * std::f64::consts::PI).sqrt() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn the_two_models_differ_by_orders_of_magnitude_for_small_hertz_contacts() {
        // 316L, r = 15 µm, δ = 10 nm: a ≈ 0.27 µm, so a/d ≈ 0.01 and pipe/B&O = π a / (2 d) ≈ 0.014.
        let a = contact_radius(7.5e-6, 1e-8);
        let ratio = thermal_pipe(20.0, 20.0, 1.5e-5, 1.5e-5, a, 3e-5 - 1e-8)
            / batchelor_obrien(20.0, 20.0, a);
        assert!(ratio < 0.02 && ratio > 0.01, "{ratio}");
    }
}
