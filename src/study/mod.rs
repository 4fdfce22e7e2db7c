//! The convergence study of `am-sim study`: time-step sweeps over cases with analytic answers,
//! reported as error against run time.
//!
//! Each case family (`hertz`, `bond`, `thermal`) runs small scenes through the public API (scene
//! TOML → [`Model`](crate::model::Model) → [`Simulation`]), measures one or more quantities per
//! time step, and compares them with a reference: a closed form where one exists (paper eqs. 20,
//! 21, 23, Johnson's contact time, the thermal exponentials and the plateau `m L / P`), otherwise
//! the same run at a much finer step (said so in the table). The wall time of each run is
//! measured here with [`Instant`]: this is a report, not a test, and the times are those of the
//! machine that ran it.
//!
//! The observed order of a quantity is `p = ln(e₁/e₂) / ln(dt₁/dt₂)` between consecutive time
//! steps; the one reported is that of the finest pair whose errors are both above the round-off
//! floor [`ROUND_OFF`].
//!
//! [`run`] writes `accuracy.md` and `images/accuracy-<family>.png` into the output folder.

mod bond;
mod hertz;
mod plot;
mod report;
pub mod scenes;
mod thermal;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::simulation::Simulation;

/// Relative errors below this are round-off, not discretisation error: no order is fitted to
/// them (a few hundred ulps of f64, the noise of a run of 10⁴–10⁶ steps).
pub const ROUND_OFF: f64 = 1e-12;

/// What to run and where to write it.
#[derive(Debug, Clone)]
pub struct Options {
    /// Reduced sweep: four time steps per quantity, a coarser bisection, every run timed once.
    pub quick: bool,
    /// Folder for `accuracy.md` and `images/accuracy-*.png`.
    pub out: PathBuf,
}

/// How the reference value of a quantity was obtained.
#[derive(Debug, Clone, PartialEq)]
pub enum Reference {
    /// A closed form; the text names it (e.g. "paper eq. 20").
    ClosedForm(&'static str),
    /// The same run at this finer time step \[s\].
    FineStep(f64),
}

/// One run of a sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time step \[s\].
    pub dt: f64,
    /// Measured value (in the unit of its [`Series`]).
    pub value: f64,
    /// Relative error `|value / reference − 1|` (or `|value − reference|` for a reference of 0).
    pub error: f64,
    /// Wall time of the run \[s\] (stepping and measuring, not the scene setup).
    pub wall_time: f64,
}

/// One quantity (in one scheme variant) swept over the time step.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The quantity, e.g. "δ_max".
    pub quantity: String,
    /// Scheme variant or case parameter, e.g. "θ = 0.5" (may be empty).
    pub variant: String,
    /// Unit of the values, e.g. "m".
    pub unit: &'static str,
    /// The time scale the time step is compared with, e.g. ("t_c", 2.3e-5 s).
    pub scale: (&'static str, f64),
    /// Reference value.
    pub reference: f64,
    /// Where the reference comes from.
    pub reference_kind: Reference,
    /// The order the scheme and the way the quantity is read lead one to expect, and why.
    pub expected: &'static str,
    /// Runs, from the coarsest time step to the finest.
    pub samples: Vec<Sample>,
}

impl Series {
    fn new(
        quantity: &str,
        variant: &str,
        unit: &'static str,
        scale: (&'static str, f64),
        reference: f64,
        reference_kind: Reference,
    ) -> Self {
        Self {
            quantity: quantity.to_owned(),
            variant: variant.to_owned(),
            unit,
            scale,
            reference,
            reference_kind,
            expected: "",
            samples: Vec::new(),
        }
    }

    /// Sets the expected order (see [`Series::expected`]).
    fn expecting(mut self, expected: &'static str) -> Self {
        self.expected = expected;
        self
    }

    /// Adds a run whose measured value is `value`.
    fn push(&mut self, dt: f64, value: f64, wall_time: f64) {
        let error = if self.reference == 0.0 {
            (value - self.reference).abs()
        } else {
            (value / self.reference - 1.0).abs()
        };
        self.samples.push(Sample {
            dt,
            value,
            error,
            wall_time,
        });
    }

    /// Label of the series in tables and plot legends.
    #[must_use]
    pub fn label(&self) -> String {
        if self.variant.is_empty() {
            self.quantity.clone()
        } else {
            format!("{} ({})", self.quantity, self.variant)
        }
    }

    /// Local orders `p_k = ln(e_{k−1}/e_k) / ln(dt_{k−1}/dt_k)` for k ≥ 1 (`None` for the first
    /// run and wherever either error is below [`ROUND_OFF`]).
    #[must_use]
    pub fn local_orders(&self) -> Vec<Option<f64>> {
        let mut orders = vec![None];
        for pair in self.samples.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            orders.push(
                (a.error > ROUND_OFF && b.error > ROUND_OFF)
                    .then(|| (a.error / b.error).ln() / (a.dt / b.dt).ln()),
            );
        }
        orders
    }

    /// The observed order: the local order of the finest pair above round-off.
    #[must_use]
    pub fn observed_order(&self) -> Option<f64> {
        self.local_orders().into_iter().rev().flatten().next()
    }

    /// The least-squares slope of ln e against ln dt over the runs above round-off (`None` with
    /// fewer than two).
    #[must_use]
    pub fn fitted_order(&self) -> Option<f64> {
        let points: Vec<(f64, f64)> = self
            .samples
            .iter()
            .filter(|s| s.error > ROUND_OFF)
            .map(|s| (s.dt.ln(), s.error.ln()))
            .collect();
        if points.len() < 2 {
            return None;
        }
        #[allow(clippy::cast_precision_loss)]
        let n = points.len() as f64;
        let (mx, my) = (
            points.iter().map(|p| p.0).sum::<f64>() / n,
            points.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
        Some(sxy / sxx)
    }
}

/// The results of one case family: what was run, and its series.
#[derive(Debug, Clone, PartialEq)]
pub struct Family {
    /// Short name, used in file names (`images/accuracy-<key>.png`).
    pub key: &'static str,
    /// Section title.
    pub title: &'static str,
    /// What the case is (Markdown).
    pub description: String,
    /// How to read the results (Markdown).
    pub reading: &'static str,
    /// The swept quantities.
    pub series: Vec<Series>,
}

/// Everything the study measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// Whether this was the reduced sweep.
    pub quick: bool,
    /// The case families in report order.
    pub families: Vec<Family>,
    /// Wall time of the whole study \[s\].
    pub wall_time: f64,
}

impl Study {
    /// The series named `quantity` (and `variant`) in family `key`.
    #[must_use]
    pub fn series(&self, key: &str, quantity: &str, variant: &str) -> Option<&Series> {
        self.families
            .iter()
            .filter(|f| f.key == key)
            .flat_map(|f| &f.series)
            .find(|s| s.quantity == quantity && s.variant == variant)
    }
}

/// Runs every case family (printing progress to stderr) without writing anything.
#[must_use]
pub fn measure(quick: bool) -> Study {
    let start = Instant::now();
    let mut families = Vec::new();
    for (name, run) in [
        ("hertz", hertz::family as fn(bool) -> Family),
        ("bond", bond::family),
        ("onset", bond::onset_family),
        ("thermal", thermal::family),
    ] {
        let family_start = Instant::now();
        families.push(run(quick));
        eprintln!(
            "study: {name} done in {:.1} s",
            family_start.elapsed().as_secs_f64()
        );
    }
    Study {
        quick,
        families,
        wall_time: start.elapsed().as_secs_f64(),
    }
}

/// Runs the study and writes `accuracy.md` and `images/accuracy-<family>.png` into
/// `options.out`. Returns the measurements.
///
/// # Errors
/// A message naming the file that could not be written.
pub fn run(options: &Options) -> Result<Study, String> {
    let study = measure(options.quick);
    write(&study, &options.out)?;
    eprintln!(
        "study: wrote {} and {}",
        options.out.join("accuracy.md").display(),
        options.out.join("images/accuracy-*.png").display()
    );
    Ok(study)
}

/// Writes the report and plots of `study` into `out`.
///
/// # Errors
/// A message naming the file that could not be written.
pub fn write(study: &Study, out: &Path) -> Result<(), String> {
    let images = out.join("images");
    std::fs::create_dir_all(&images)
        .map_err(|e| format!("cannot create {}: {e}", images.display()))?;
    for family in &study.families {
        let path = images.join(format!("accuracy-{}.png", family.key));
        plot::error_against_time(family, &path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    let path = out.join("accuracy.md");
    std::fs::write(&path, report::markdown(study))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Steps `sim` until `done` returns true or the run's step count is reached; returns the wall
/// time of the loop \[s\].
fn timed_steps(sim: &mut Simulation, mut done: impl FnMut(&Simulation) -> bool) -> f64 {
    let start = Instant::now();
    while sim.step < sim.model.steps {
        sim.step();
        if done(sim) {
            break;
        }
    }
    start.elapsed().as_secs_f64()
}

/// Runs `case` and reports its result with the smallest wall time (as read by `wall`) of
/// repeated runs: in the full study a case is run again while its runs took less than
/// [`TIMING_BUDGET`] in total (at most 1000 times), since a run of a few microseconds timed once
/// mostly measures cache warm-up and scheduler noise. The runs are deterministic, so the result
/// of the first one stands for all. The quick study runs every case once.
fn best_of<T>(quick: bool, mut case: impl FnMut() -> T, wall: impl Fn(&T) -> f64) -> (T, f64) {
    let first = case();
    let (mut best, mut total) = (wall(&first), wall(&first));
    let mut runs = 1;
    while !quick && total < TIMING_BUDGET && runs < 1000 {
        let time = wall(&case());
        best = best.min(time);
        total += time;
        runs += 1;
    }
    (first, best)
}

/// Time spent re-running a short case to time it \[s\] (see [`best_of`]).
const TIMING_BUDGET: f64 = 0.02;

/// Time steps `scale / n` for the step counts `n` of the full or quick sweep.
fn steps(scale: f64, counts: &[u32]) -> Vec<f64> {
    counts.iter().map(|&n| scale / f64::from(n)).collect()
}
