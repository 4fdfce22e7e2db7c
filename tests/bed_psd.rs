//! Particle size distributions: 1e5 draws reproduce the requested quantiles and moments within
//! their sampling error, truncation redraws (no pile-up at the bounds), and a seed always gives
//! the same diameters.

use am_sim::bed::psd::{Psd, Shape, Z90};
use am_sim::bed::rng::SplitMix64;

const DRAWS: usize = 100_000;

fn draws(psd: &Psd, seed: u64) -> Vec<f64> {
    let mut rng = SplitMix64(seed);
    let mut d: Vec<f64> = (0..DRAWS).map(|_| psd.sample(&mut rng)).collect();
    d.sort_by(f64::total_cmp);
    d
}

/// Sample p-quantile of sorted draws.
#[allow(
    clippy::cast_precision_loss,
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss
)]
fn sample_quantile(sorted: &[f64], p: f64) -> f64 {
    sorted[((p * sorted.len() as f64) as usize).min(sorted.len() - 1)]
}

/// Five standard errors of the sample p-quantile of n draws: sqrt(p(1−p)/n) / f(x_p), with the
/// density f(x_p) taken from the CDF by a central difference (asymptotic normality of sample
/// quantiles). A correct sampler misses by more with probability < 1e-6.
#[allow(clippy::cast_precision_loss)]
fn quantile_tolerance(psd: &Psd, p: f64, n: usize) -> f64 {
    let x = psd.quantile(p);
    let h = 1e-4 * x;
    let density = (psd.cdf(x + h) - psd.cdf(x - h)) / (2.0 * h);
    5.0 * (p * (1.0 - p) / n as f64).sqrt() / density
}

/// Kolmogorov–Smirnov distance between the sorted draws and the CDF.
#[allow(clippy::cast_precision_loss)]
fn ks_distance(psd: &Psd, sorted: &[f64]) -> f64 {
    let n = sorted.len() as f64;
    sorted
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            let f = psd.cdf(x);
            (f - k as f64 / n).abs().max(((k + 1) as f64 / n - f).abs())
        })
        .fold(0.0, f64::max)
}

/// KS critical value at significance 0.001: 1.95/√n (asymptotic Kolmogorov distribution).
#[allow(clippy::cast_precision_loss)]
fn ks_limit(n: usize) -> f64 {
    1.95 / (n as f64).sqrt()
}

#[test]
fn lognormal_from_d10_d50_d90_reproduces_the_quantiles() {
    // A 316L-like powder: D10 = 20, D50 = 30, D90 = 45 µm (D10·D90 = D50²: exactly log-normal).
    let psd = Psd::from_quantiles(Shape::LogNormal, 20e-6, 30e-6, 45e-6);
    let d = draws(&psd, 316);
    for (p, target) in [(0.1, 20e-6), (0.5, 30e-6), (0.9, 45e-6)] {
        let got = sample_quantile(&d, p);
        let tol = quantile_tolerance(&psd, p, DRAWS);
        assert!(
            (got - target).abs() < tol,
            "D{}: {got:e} vs {target:e} (±{tol:e})",
            p * 100.0
        );
    }
    assert!(ks_distance(&psd, &d) < ks_limit(DRAWS));
}

#[test]
fn an_asymmetric_quantile_triple_is_fitted_by_least_squares_about_the_median() {
    // ln(50/30) ≠ ln(30/20): no log-normal passes through all three; the median is kept and
    // σ = ln(D90/D10) / (2 z₀.₉) (M.73), so the
    // fitted ln D10 and ln D90 both miss by the same amount (the normal equation sets the two
    // residuals equal).
    let psd = Psd::from_quantiles(Shape::LogNormal, 20e-6, 30e-6, 50e-6);
    assert!((psd.quantile(0.5) - 30e-6).abs() < 1e-12 * 30e-6);
    let sigma = (50.0_f64 / 20.0).ln() / (2.0 * Z90);
    assert!((psd.scale - sigma).abs() < 1e-15);
    let miss10 = psd.quantile(0.1).ln() - 20e-6_f64.ln();
    let miss90 = psd.quantile(0.9).ln() - 50e-6_f64.ln();
    // Bisection to round-off in the quantile: relative 1e-12 is far above its error.
    assert!((miss10 - miss90).abs() < 1e-9, "{miss10} {miss90}");
    let d = draws(&psd, 7);
    assert!(ks_distance(&psd, &d) < ks_limit(DRAWS));
}

#[test]
fn normal_from_mean_and_std_has_that_mean_and_std() {
    let (mean, std) = (30e-6, 5e-6);
    let psd = Psd::normal(mean, std);
    let d = draws(&psd, 1);
    #[allow(clippy::cast_precision_loss)]
    let n = DRAWS as f64;
    let m = d.iter().sum::<f64>() / n;
    let s = (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    // Standard errors: σ/√n for the mean, σ/√(2n) for the standard deviation of a normal; five of
    // them. (The redraw of D ≤ 0 removes a mass of Φ(−6) ≈ 1e-9: negligible.)
    assert!((m - mean).abs() < 5.0 * std / n.sqrt(), "mean {m:e}");
    assert!((s - std).abs() < 5.0 * std / (2.0 * n).sqrt(), "std {s:e}");
    assert!(ks_distance(&psd, &d) < ks_limit(DRAWS));
}

#[test]
fn normal_from_quantiles_has_the_median_and_spread_asked_for() {
    let psd = Psd::from_quantiles(Shape::Normal, 20e-6, 30e-6, 40e-6);
    let d = draws(&psd, 2);
    for (p, target) in [(0.1, 20e-6), (0.5, 30e-6), (0.9, 40e-6)] {
        let got = sample_quantile(&d, p);
        let tol = quantile_tolerance(&psd, p, DRAWS);
        assert!((got - target).abs() < tol, "{p}: {got:e} vs {target:e}");
    }
}

#[test]
fn lognormal_from_mean_and_std_has_that_mean() {
    let (mean, std) = (30e-6, 9e-6);
    let psd = Psd::lognormal_from_moments(mean, std);
    let d = draws(&psd, 3);
    #[allow(clippy::cast_precision_loss)]
    let n = DRAWS as f64;
    let m = d.iter().sum::<f64>() / n;
    // Standard error of the mean: std/√n; five of them.
    assert!((m - mean).abs() < 5.0 * std / n.sqrt(), "mean {m:e}");
    assert!(ks_distance(&psd, &d) < ks_limit(DRAWS));
}

#[test]
fn truncation_redraws_instead_of_piling_up_at_the_bounds() {
    let full = Psd::from_quantiles(Shape::LogNormal, 20e-6, 30e-6, 45e-6);
    let psd = full.truncated(22e-6, 40e-6);
    let d = draws(&psd, 4);
    assert!(d[0] >= 22e-6 && d[DRAWS - 1] <= 40e-6);
    // Clamping would put F(22 µm) ≈ 0.15 of all draws exactly on the lower bound; redrawing puts
    // none there (a continuous draw hits a given f64 with probability ~1e-16).
    let on_bounds = d.iter().filter(|&&x| x == 22e-6 || x == 40e-6).count();
    assert_eq!(on_bounds, 0);
    // The draws follow the truncated CDF (M.74), clamping would fail this at the bounds.
    assert!(ks_distance(&psd, &d) < ks_limit(DRAWS));
    // And the kept fraction is the untruncated probability of the range.
    let kept = full.untruncated_cdf(40e-6) - full.untruncated_cdf(22e-6);
    assert!((psd.kept_fraction() - kept).abs() < 1e-15);
}

#[test]
fn a_seed_gives_the_same_diameters_every_time_and_another_seed_others() {
    let psd = Psd::from_quantiles(Shape::LogNormal, 20e-6, 30e-6, 45e-6);
    let sample = |seed| {
        let mut rng = SplitMix64(seed);
        (0..100).map(|_| psd.sample(&mut rng)).collect::<Vec<f64>>()
    };
    assert_eq!(sample(9), sample(9));
    assert_ne!(sample(9), sample(10));
}
