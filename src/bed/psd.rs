//! Particle size distributions (PSD) of **diameters**, as powder data sheets give them:
//! constant, normal or log-normal, set by mean/std or by the quantiles D10/D50/D90, optionally
//! truncated to `[min, max]` (docs/model.md, M.71-M.74).

use super::rng::SplitMix64;

/// z₀.₉ = Φ⁻¹(0.9): the standard normal quantile of D90 (and −z₀.₉ that of D10).
pub const Z90: f64 = 1.281_551_565_544_600_5;

/// The shape of a distribution of diameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Every diameter equals `location`.
    Constant,
    /// D ~ N(location, scale²).
    Normal,
    /// ln D ~ N(location, scale²): `location` = ln(median), `scale` = σ of ln D.
    LogNormal,
}

/// A diameter distribution, possibly truncated to `[min, max]` (truncation, not clamping: draws
/// outside are redrawn, so the density inside is the untruncated one rescaled, M.74).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Psd {
    /// The family.
    pub shape: Shape,
    /// Mean \[m\] (normal), ln of the median [ln m] (log-normal), or the diameter (constant).
    pub location: f64,
    /// Standard deviation \[m\] (normal), σ of ln D [–] (log-normal); 0 for constant.
    pub scale: f64,
    /// Smallest diameter kept \[m\] (≥ 0; diameters ≤ 0 are never kept).
    pub min: f64,
    /// Largest diameter kept \[m\] (may be +∞).
    pub max: f64,
}

/// Standard normal CDF Φ(x) = erfc(−x/√2)/2.
#[must_use]
pub fn standard_normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
}

impl Psd {
    /// Every sphere has diameter `d` \[m\].
    #[must_use]
    pub fn constant(d: f64) -> Self {
        Self {
            shape: Shape::Constant,
            location: d,
            scale: 0.0,
            min: 0.0,
            max: f64::INFINITY,
        }
    }

    /// Normal with mean `mean` and standard deviation `std` \[m\].
    #[must_use]
    pub fn normal(mean: f64, std: f64) -> Self {
        Self {
            shape: Shape::Normal,
            location: mean,
            scale: std,
            min: 0.0,
            max: f64::INFINITY,
        }
    }

    /// Log-normal whose diameters have arithmetic mean `mean` and standard deviation `std` \[m\]
    /// (M.72): σ² = ln(1 + (std/mean)²), μ = ln(mean) − σ²/2.
    #[must_use]
    pub fn lognormal_from_moments(mean: f64, std: f64) -> Self {
        let sigma2 = libm::log1p((std / mean).powi(2));
        Self {
            shape: Shape::LogNormal,
            location: libm::log(mean) - 0.5 * sigma2,
            scale: libm::sqrt(sigma2),
            min: 0.0,
            max: f64::INFINITY,
        }
    }

    /// Fit to the quantiles D10 < D50 < D90 \[m\] (M.73): the median is D50 and the spread is the
    /// least-squares fit of D10 and D90 about it, which with z = ±z₀.₉ has the closed form
    /// σ = (g(D90) − g(D10)) / (2 z₀.₉), with g = ln for the log-normal and g(D) = D for the normal.
    #[must_use]
    pub fn from_quantiles(shape: Shape, d10: f64, d50: f64, d90: f64) -> Self {
        match shape {
            Shape::Constant => Self::constant(d50),
            Shape::Normal => Self::normal(d50, (d90 - d10) / (2.0 * Z90)),
            Shape::LogNormal => Self {
                shape,
                location: libm::log(d50),
                scale: (libm::log(d90) - libm::log(d10)) / (2.0 * Z90),
                min: 0.0,
                max: f64::INFINITY,
            },
        }
    }

    /// The same distribution truncated to `[min, max]` \[m\].
    #[must_use]
    pub fn truncated(self, min: f64, max: f64) -> Self {
        Self { min, max, ..self }
    }

    /// CDF of the untruncated distribution at diameter `d` \[m\].
    #[must_use]
    pub fn untruncated_cdf(&self, d: f64) -> f64 {
        match self.shape {
            Shape::Constant => f64::from(u8::from(d >= self.location)),
            Shape::Normal => standard_normal_cdf((d - self.location) / self.scale),
            Shape::LogNormal if d <= 0.0 => 0.0,
            Shape::LogNormal => standard_normal_cdf((libm::log(d) - self.location) / self.scale),
        }
    }

    /// Probability that an untruncated draw is kept: F(max) − F(max(min, 0)) (for a constant,
    /// 1 or 0 whether the diameter lies in the range).
    #[must_use]
    pub fn kept_fraction(&self) -> f64 {
        if self.shape == Shape::Constant {
            return f64::from(u8::from(
                self.location > 0.0 && self.location >= self.min && self.location <= self.max,
            ));
        }
        self.untruncated_cdf(self.max) - self.untruncated_cdf(self.min.max(0.0))
    }

    /// CDF of the truncated distribution (M.74): (F(d) − F(min)) / (F(max) − F(min)) inside.
    #[must_use]
    pub fn cdf(&self, d: f64) -> f64 {
        if self.shape == Shape::Constant {
            return self.untruncated_cdf(d);
        }
        let lo = self.untruncated_cdf(self.min.max(0.0));
        ((self.untruncated_cdf(d.clamp(self.min, self.max)) - lo) / self.kept_fraction())
            .clamp(0.0, 1.0)
    }

    /// Quantile of the truncated distribution: the d with `cdf(d) = p` (bisection to round-off).
    #[must_use]
    pub fn quantile(&self, p: f64) -> f64 {
        if self.shape == Shape::Constant {
            return self.location;
        }
        let (mut lo, mut hi) = (self.min.max(0.0), self.max);
        if !hi.is_finite() {
            hi = lo.max(1e-12);
            while self.cdf(hi) < p {
                hi *= 2.0;
            }
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if self.cdf(mid) < p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// One diameter \[m\]. Draws outside `[min, max]` (or ≤ 0) are redrawn; scene validation
    /// requires [`Psd::kept_fraction`] ≥ 1e-3, so a draw needs fewer than 1000 tries on average.
    pub fn sample(&self, rng: &mut SplitMix64) -> f64 {
        loop {
            let d = match self.shape {
                Shape::Constant => return self.location,
                Shape::Normal => self.location + self.scale * rng.standard_normal(),
                Shape::LogNormal => libm::exp(self.location + self.scale * rng.standard_normal()),
            };
            if d > 0.0 && d >= self.min && d <= self.max {
                return d;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z90_is_the_normal_quantile_of_0_9() {
        // Φ(z₀.₉) = 0.9 to the accuracy of erfc (≈ 1e-16).
        assert!((standard_normal_cdf(Z90) - 0.9).abs() < 1e-15);
    }

    #[test]
    fn quantile_fit_reproduces_symmetric_quantiles_exactly() {
        // D10·D90 = D50² (symmetric in ln D): the log-normal fit passes through all three.
        let psd = Psd::from_quantiles(Shape::LogNormal, 20e-6, 30e-6, 45e-6);
        for (p, d) in [(0.1, 20e-6), (0.5, 30e-6), (0.9, 45e-6)] {
            assert!((psd.quantile(p) - d).abs() < 1e-12 * d, "D{}", p * 100.0);
        }
    }

    #[test]
    fn moments_of_the_lognormal_are_the_requested_ones() {
        // E[D] = exp(μ + σ²/2), Var = (exp(σ²) − 1) E[D]² (closed forms of the log-normal).
        let psd = Psd::lognormal_from_moments(30e-6, 9e-6);
        let mean = libm::exp(psd.location + 0.5 * psd.scale.powi(2));
        let std = mean * libm::sqrt(libm::expm1(psd.scale.powi(2)));
        assert!((mean - 30e-6).abs() < 1e-15 * 30e-6 * 10.0);
        assert!((std - 9e-6).abs() < 1e-14 * 9e-6 * 10.0);
    }
}
