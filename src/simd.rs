//! The vector builds of the step's hot loops, chosen at run time.
//!
//! The binary is built for generic x86-64 (SSE2, two `f64` per instruction), so that speed
//! figures are about the code, not the build flags. A loop written as a `Kernel` is compiled
//! three times, for the baseline, AVX2 (four `f64` per instruction) and AVX-512 (eight), and
//! `dispatch` runs the widest this processor has (`InstructionSet::detect`, within the cap of
//! `am-sim --simd`, [`limit_kernel`]). The builds do the same IEEE operations in the same
//! order (Rust never fuses a multiply and an add by itself), so they give bitwise the same
//! results: the choice changes speed only.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Contacts (or particles) per batch of a vector kernel: at least two vectors of `f64` in every
/// build, so that two or more independent chains of square roots and divisions overlap. With 8
/// (one AVX-512 vector, a single chain) the pair kernel's AVX-512 build took 12.8 ns per contact
/// in `benches/pair_kernel.rs` and 11.3 ns with 16; the 19.2k LIGGGHTS bed's step ran 1.8 %
/// faster at 1 thread, 2.2 % at 2 and 3.1 % with heat. The AVX2 build, with two chains at 8
/// already, stays within ±2 %.
pub(crate) const LANES: usize = 16;

/// One quantity of every lane.
pub(crate) type Lane<T> = [T; LANES];

/// A loop whose body [`dispatch`] compiles for each build (the pair and wall kernels of
/// `forces`, the kicks and drift of `integrate`): its `run` must be `#[inline(always)]`, so that
/// it is compiled into the build's function, with its instructions. So must every function of
/// am-sim's it reaches (the contact laws of `contact`, for one): one the compiler leaves out of
/// line is built for the baseline and called lane by lane, and the vector is lost.
/// `scripts/check_kernels.py`, run by CI, reads the release binary's disassembly for such calls.
pub(crate) trait Kernel {
    /// The loop.
    fn run(self);
}

/// Runs `kernel` compiled for `set`.
#[inline]
#[allow(unsafe_code)]
pub(crate) fn dispatch<K: Kernel>(set: InstructionSet, kernel: K) {
    #[cfg(target_arch = "x86_64")]
    match set.width {
        // SAFETY: a width above the baseline is only made where the processor has its
        // instructions (`InstructionSet::available`).
        Width::Avx512 => unsafe { loop_avx512(kernel) },
        // SAFETY: as above.
        Width::Avx2 => unsafe { loop_avx2(kernel) },
        Width::Baseline => kernel.run(),
    }
    #[cfg(not(target_arch = "x86_64"))]
    kernel.run();
}

/// A [`Kernel`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn loop_avx2<K: Kernel>(kernel: K) {
    kernel.run();
}

/// A [`Kernel`] compiled for AVX-512 (F, DQ, VL): eight `f64` per instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl")]
fn loop_avx512<K: Kernel>(kernel: K) {
    kernel.run();
}

/// Lanes of [`Largest`]: as many `f64` as an AVX-512 register holds.
const LARGEST_LANES: usize = 8;

/// The largest of a stream of values, kept lane by lane, for the maxima the step takes over the
/// particles (the drift's largest speed, the largest heat rate, the largest displacement since
/// the last build). `f64::max` over the values one at a time is a scalar chain, each value's
/// `max` waiting on the last with a NaN select per value (`vmaxsd`, `vcmpunordsd`,
/// `vblendvpd`: about 10 instructions per particle for the drift's speed, forty-second round of
/// docs/performance-log.md); here each lane keeps its larger value by a comparison, one vector
/// `max` per register of values in a [`Kernel`]'s vector builds. A maximum is exact in any
/// order, so the result is bitwise that of the chain, and a NaN value is passed over as
/// `f64::max` passes it (a comparison with NaN is false).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Largest {
    lanes: [f64; LARGEST_LANES],
}

impl Largest {
    /// No value yet: [`Largest::value`] gives `start` (not NaN) until a larger one is taken.
    pub(crate) fn new(start: f64) -> Self {
        Self {
            lanes: [start; LARGEST_LANES],
        }
    }

    /// Takes in `values`.
    #[inline(always)]
    pub(crate) fn take(&mut self, values: &[f64]) {
        fold_lanes(&mut self.lanes, values, larger);
    }

    /// The largest value taken in, or the start.
    #[inline(always)]
    pub(crate) fn value(&self) -> f64 {
        self.lanes[1..]
            .iter()
            .fold(self.lanes[0], |largest, &lane| larger(largest, lane))
    }
}

/// `values` folded into `lanes`, value k into lane k mod N: `lane = fold(lane, value)`. With
/// the lanes independent, a [`Kernel`]'s vector builds fold a register of values per
/// instruction, where one accumulator would be a chain of scalar operations. `fold` must give
/// the same result in any order of the values for the result to be that of a one-by-one fold
/// (a maximum; a sum of exact zeros and NaNs, as `integrate`'s finite test folds).
#[inline(always)]
pub(crate) fn fold_lanes<const N: usize>(
    lanes: &mut [f64; N],
    values: &[f64],
    fold: impl Fn(f64, f64) -> f64,
) {
    let mut groups = values.chunks_exact(N);
    for group in &mut groups {
        for (lane, &value) in lanes.iter_mut().zip(group) {
            *lane = fold(*lane, value);
        }
    }
    for (lane, &value) in lanes.iter_mut().zip(groups.remainder()) {
        *lane = fold(*lane, value);
    }
}

/// `candidate` if it is larger than `kept`, else `kept` (so a NaN candidate is passed over).
#[inline(always)]
fn larger(kept: f64, candidate: f64) -> f64 {
    if candidate > kept { candidate } else { kept }
}

/// Which build the kernels take. Made only by [`InstructionSet::detect`] and
/// [`InstructionSet::available`], so that a build runs only where the processor has its
/// instructions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct InstructionSet {
    width: Width,
}

/// The builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Width {
    /// The build's own target (x86-64: SSE2, two contacts per instruction).
    Baseline,
    /// AVX2: four contacts per instruction.
    Avx2,
    /// AVX-512 (F, DQ, VL): eight contacts per instruction.
    Avx512,
}

/// How many of [`Width::ALL`], narrowest first, the kernels may take ([`limit_kernel`]): all of
/// them unless the run asked for fewer.
static ALLOWED_WIDTHS: AtomicUsize = AtomicUsize::new(Width::ALL.len());

impl Width {
    /// Every build, narrowest first.
    const ALL: [Self; 3] = [Self::Baseline, Self::Avx2, Self::Avx512];

    /// The build's name.
    fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }

    /// The widest build this processor runs among the first `allowed` of [`Width::ALL`] (at
    /// least the baseline).
    fn widest(allowed: usize) -> Self {
        Self::ALL[..allowed.clamp(1, Self::ALL.len())]
            .iter()
            .rev()
            .copied()
            .find(|width| width.runs())
            .unwrap_or(Self::Baseline)
    }

    /// Whether this processor has the build's instructions.
    fn runs(self) -> bool {
        match self {
            Self::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => {
                std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }
}

impl InstructionSet {
    /// The widest this processor runs, within the run's cap ([`limit_kernel`]).
    #[must_use]
    pub(crate) fn detect() -> Self {
        Self {
            width: Width::widest(ALLOWED_WIDTHS.load(Ordering::Relaxed)),
        }
    }

    /// Every build this processor runs, narrowest first.
    #[must_use]
    pub(crate) fn available() -> Vec<Self> {
        Width::ALL
            .into_iter()
            .filter(|width| width.runs())
            .map(|width| Self { width })
            .collect()
    }

    /// The build's name: `baseline`, `avx2` or `avx512`.
    #[must_use]
    pub(crate) fn name(self) -> &'static str {
        self.width.name()
    }
}

/// Caps the kernels' build at `build` (`baseline`, `avx2` or `avx512`) for the rest of
/// the process (`am-sim --simd`), for a processor on which the wider builds run slower (some
/// lower their clock for 512-bit instructions) or to compare the builds. The results do not
/// change: every build gives bitwise the same. Returns the build the kernels take from now on:
/// `build`, or the widest below it that this processor runs.
///
/// # Errors
/// If `build` names no build.
pub fn limit_kernel(build: &str) -> Result<&'static str, String> {
    let position = Width::ALL
        .iter()
        .position(|width| width.name() == build)
        .ok_or_else(|| {
            format!(
                "{build:?} is not a build of the step's vector kernels ({})",
                kernel_builds().join(", ")
            )
        })?;
    ALLOWED_WIDTHS.store(position + 1, Ordering::Relaxed);
    Ok(Width::widest(position + 1).name())
}

/// The names of the builds, narrowest first (whether or not this processor
/// runs them): what [`limit_kernel`] accepts.
#[must_use]
pub fn kernel_builds() -> [&'static str; 3] {
    Width::ALL.map(Width::name)
}

/// The build the kernels take: `baseline`, `avx2` or `avx512`.
#[must_use]
pub fn kernel_build() -> &'static str {
    InstructionSet::detect().name()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes' largest value is the largest taken in wherever it lies (in any lane, in a
    /// remainder, in a later call), NaN is passed over, and the start stays the value until a
    /// larger one comes.
    #[test]
    fn the_largest_value_is_found_in_any_lane_and_call() {
        let count = 3 * LARGEST_LANES + 5;
        #[allow(clippy::cast_precision_loss)]
        let small: Vec<f64> = (0..count).map(|k| -1.0 - (k % 7) as f64).collect();
        for largest in 0..count {
            let mut values = small.clone();
            values[largest] = 2.5;
            values[(largest + 3) % count] = f64::NAN;
            // Calls of 13, 13 and 3 values: each leaves a remainder.
            let mut lanes = Largest::new(-100.0);
            for part in values.chunks(13) {
                lanes.take(part);
            }
            assert_eq!(lanes.value(), 2.5, "largest at {largest}");
        }
        let mut lanes = Largest::new(0.0);
        lanes.take(&small);
        assert_eq!(lanes.value(), 0.0);
        lanes.take(&[f64::NAN; 3]);
        assert_eq!(lanes.value(), 0.0);
        assert_eq!(Largest::new(-3.0).value(), -3.0);
    }

    /// A cap keeps the kernels at or below it, never below the baseline, and takes the widest
    /// build the processor runs within it.
    #[test]
    fn a_cap_on_the_builds_takes_the_widest_the_processor_runs_within_it() {
        let runs: Vec<Width> = Width::ALL.into_iter().filter(|w| w.runs()).collect();
        assert_eq!(Width::widest(0), Width::Baseline);
        assert_eq!(Width::widest(1), Width::Baseline);
        assert_eq!(Width::widest(Width::ALL.len()), *runs.last().unwrap());
        assert_eq!(Width::widest(usize::MAX), *runs.last().unwrap());
        for allowed in 1..=Width::ALL.len() {
            let widest = Width::widest(allowed);
            assert!(widest.runs());
            let position = Width::ALL.iter().position(|w| *w == widest).unwrap();
            assert!(position < allowed, "{widest:?} beyond a cap of {allowed}");
            // Nothing wider within the cap runs.
            assert!(Width::ALL[position + 1..allowed].iter().all(|w| !w.runs()));
        }
        assert!(limit_kernel("avx1024").unwrap_err().contains("avx1024"));
    }
}
