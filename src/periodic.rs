//! Periodic boundaries (M.77): a box that repeats along some axes. A pair's separation is its
//! minimum image, and positions are wrapped back into the box at every neighbour-list build
//! (between builds they may stray by at most half the skin, which the minimum image absorbs).
//!
//! ```text
//! (M.77)  d_min = d − L ⌊d/L⌉             on each periodic axis (⌊·⌉: nearest integer)
//!         x ← lo + ((x − lo) mod L)       at each neighbour-list build
//! ```
//!
//! The minimum image is the only image as long as the interaction range (r_i + r_j + skin) is
//! below L/2; the neighbour search needs at least three cells of `2 r_max + skin` across L, which
//! `Model::try_build` checks.

use glam::DVec3;

/// The periodic axes of the domain and their extent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Periodic {
    /// Lower bound on each periodic axis \[m\] (unused on the others).
    pub lower: DVec3,
    /// Period L on each periodic axis \[m\]; `None` where the axis is not periodic.
    pub length: [Option<f64>; 3],
}

impl Periodic {
    /// The minimum image of a separation vector (M.77) \[m\].
    ///
    /// Positions are wrapped at every neighbour-list build and move less than half the skin
    /// between builds, so a separation is within (−3L/2, 3L/2) and one shift by L suffices: two
    /// compares instead of `round`, which on generic x86-64 (no SSE4.1) is a libm call and cost
    /// 5 % of a frictional step. Larger separations (only from far-apart test inputs) are folded
    /// by the exact formula, with a rounding of its own (`round_half_away`): with `round`'s
    /// libm call in it, the pair pass's sift kept its loop's pointers on the stack (the call may
    /// clobber every register the loop has spare) and reloaded them for every candidate.
    #[inline]
    #[must_use]
    pub fn minimum_image(&self, separation: DVec3) -> DVec3 {
        let mut d = separation.to_array();
        for (component, length) in d.iter_mut().zip(self.length) {
            if let Some(length) = length {
                let half = 0.5 * length;
                if *component > half {
                    *component -= length;
                } else if *component < -half {
                    *component += length;
                }
                if component.abs() > half {
                    *component -= length * round_half_away(*component / length);
                }
            }
        }
        DVec3::from_array(d)
    }

    /// `x` moved back into the box along the periodic axes (M.77) \[m\].
    #[inline]
    #[must_use]
    pub fn wrap(&self, position: DVec3) -> DVec3 {
        let mut x = position.to_array();
        let lower = self.lower.to_array();
        for ((component, length), lo) in x.iter_mut().zip(self.length).zip(lower) {
            if let Some(length) = length {
                let wrapped = lo + (*component - lo).rem_euclid(length);
                // rem_euclid can round up to exactly `length`; that point is the lower bound.
                *component = if wrapped >= lo + length { lo } else { wrapped };
            }
        }
        DVec3::from_array(x)
    }

    /// Whether axis `axis` (0, 1, 2 for x, y, z) is periodic.
    #[must_use]
    pub fn is_periodic(&self, axis: usize) -> bool {
        self.length[axis].is_some()
    }
}

/// `x.round()` (to the nearest integer, halves away from zero) without a call: on generic x86-64
/// (no SSE4.1) `f64::round` is a libm call. Exact, like `round`: `x as i64` truncates, and the
/// fraction `x − trunc(x)` is exact in binary floating point; beyond 2^52 every `f64` is an
/// integer already (and NaN and the infinities are returned as they are, as `round` does).
#[inline]
#[must_use]
fn round_half_away(x: f64) -> f64 {
    const ALL_INTEGERS: f64 = 4_503_599_627_370_496.0; // 2^52
    if !x.is_finite() || x.abs() >= ALL_INTEGERS {
        return x;
    }
    // |x| < 2^52: the cast neither saturates nor rounds.
    #[allow(clippy::cast_possible_truncation, clippy::cast_precision_loss)]
    let truncated = (x as i64) as f64;
    if (x - truncated).abs() >= 0.5 {
        truncated + 1.0_f64.copysign(x)
    } else {
        // (−0.3 as i64 is 0: the sign of a zero result is x's, as `round` gives it.)
        truncated.copysign(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit for bit `f64::round`, at the halves, just below them, at the limits of the exact
    /// integers, for zeros of both signs and the values that are not numbers, and over a sweep.
    #[test]
    fn the_call_free_rounding_is_f64_round() {
        let below_half = 0.5 - f64::EPSILON / 4.0; // 0.49999999999999994, whose x + 0.5 rounds to 1
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            below_half,
            1.5,
            2.5,
            1.0 - f64::EPSILON,
            4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            9_007_199_254_740_992.0,
            1e300,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NAN,
        ];
        let mut sweep = 0.123_456_789_f64;
        for _ in 0..10_000 {
            sweep = (sweep * 1.618_033_988_75 + 0.25) % 64.0;
            values.push(sweep - 32.0);
        }
        let negated: Vec<f64> = values.iter().map(|v| -v).collect();
        for &x in values.iter().chain(&negated) {
            let (ours, theirs) = (round_half_away(x), x.round());
            assert!(
                ours.to_bits() == theirs.to_bits() || (ours.is_nan() && theirs.is_nan()),
                "round({x:e}): {ours:e} against {theirs:e}"
            );
        }
    }

    fn box_xy() -> Periodic {
        Periodic {
            lower: DVec3::new(-1.0, 2.0, 0.0),
            length: [Some(4.0), Some(3.0), None],
        }
    }

    #[test]
    fn the_minimum_image_is_at_most_half_a_period_on_periodic_axes_only() {
        let p = box_xy();
        let d = p.minimum_image(DVec3::new(3.5, -2.9, 10.0));
        assert!((d - DVec3::new(-0.5, 0.1, 10.0)).length() < 1e-12);
    }

    #[test]
    fn wrapping_lands_in_the_half_open_box_and_keeps_images_equivalent() {
        let p = box_xy();
        for x in [
            DVec3::new(3.0, 5.0, 7.0),
            DVec3::new(-5.5, -1.5, -2.0),
            DVec3::new(-1.0, 2.0, 0.0),
        ] {
            let w = p.wrap(x);
            assert!(
                (-1.0..3.0).contains(&w.x) && (2.0..5.0).contains(&w.y),
                "{w}"
            );
            assert_eq!(w.z, x.z);
            assert!(p.minimum_image(w - x).length() < 1e-12);
        }
    }
}
