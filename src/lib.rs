//! # am-sim
//!
//! A thermo-mechanical discrete-element simulator of additive-manufacturing powder beds: spheres
//! in Hertz contact with viscous damping that switch to the adhesive bond model of
//! Quintana-Ruiz & Campello (2020) when a bond criterion holds and the overlap reaches δ_crit.
//!
//! * **Units**: SI everywhere (m, s, kg, N, Pa, J). Scene keys carry their unit as a suffix.
//! * **Signs**: `n_ij` points from i to j; the overlap δ is positive in contact; a scalar normal
//!   force is positive when repulsive (see [`contact`]).
//! * **Data flow**: [`scene`] (TOML, validated) → [`model`] (resolved numbers, initial
//!   [`particles`]) → [`simulation`] (step loop: [`integrate`], [`neighbor`], [`forces`], which call
//!   the pure laws in [`contact`]) → [`output`]. `docs/architecture.md` has the one-page map,
//!   `docs/model.md` the numbered equations cited in doc comments as (M.x).

pub mod bed;
pub mod check;
pub mod cli;
pub mod contact;
pub mod forces;
pub mod integrate;
pub mod laser;
pub mod memory;
pub mod model;
pub mod neighbor;
pub mod output;
pub mod pair_history;
pub mod particles;
pub mod periodic;
pub mod scatter;
pub mod scene;
pub mod simd;
pub mod simulation;
pub mod study;
pub mod team;
pub mod thermal;
pub mod wall_history;

/// Below this many items a pass runs on the calling thread: handing a few hundred items to the
/// thread team or the rayon pool costs more (a wake-up and a wait, up to tens of µs) than
/// computing them. Results are the same either way, since every item is computed independently.
pub const MIN_PARALLEL_ITEMS: usize = 1024;

/// Whether a pass over `items` items is worth running in parallel.
#[must_use]
#[inline]
pub fn worth_parallel(items: usize) -> bool {
    items >= MIN_PARALLEL_ITEMS
}
