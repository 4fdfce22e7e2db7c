//! Neighbour search and the coloured traversal of the pairs.
//!
//! A cell list builds a Verlet half list of candidate pairs (centre distance below
//! `r_i + r_j + skin`), rebuilt when a particle moved more than half the skin since the last
//! build. Between builds no pair can come into contact unseen, because two particles close a gap
//! of at most `skin` in total.
//!
//! # Owners, slabs and colours
//! The cells are at least `2 r_max + skin` wide, so a candidate pair lies in the same or adjacent
//! cells. Across the domain's longest axis the cell layers form *slabs*. Each pair is stored once,
//! by its *owner*: within a slab the particle of lower index, across two slabs the particle of the
//! slab whose successor holds the other one. The owner's pairs are a contiguous range of pair
//! *slots* (CSR), where their history lives.
//!
//! A pass ([`NeighborList::for_each_owner`]) visits the slabs in two colour phases, even slabs
//! then odd slabs (a periodic slab axis gets an even number of layers from five on, each a little
//! wider than a cell must be; with only three layers the last slab runs alone in a third phase). A
//! slab's owners only reach particles of that slab and of its successor, so the slabs of one phase
//! touch disjoint particles and disjoint slots and run in parallel. A pass therefore evaluates each
//! pair once and adds its force to both particles directly, without atomics, locks or per-thread
//! copies, and every particle's sum is formed in an order fixed by the list, whatever the thread
//! count.
//!
//! # Near lists
//! Most candidate pairs of a packed bed are not touching, and whether they touch changes slowly:
//! in a step a particle moves a tiny fraction of the skin. The force pass therefore keeps, per
//! slab, the slots whose gap was below a *near skin* at its last refresh ([`NearPairs`]), and
//! tests only those. Between refreshes no other pair can come into contact as long as every
//! particle moved less than half the near skin (each end of a gap closes it by at most its own
//! displacement); the simulation bounds the displacement by the largest speed of each step and
//! refreshes before the bound reaches it (`Simulation::step`). The first lists use an eighth of
//! the skin ([`NeighborList::near_skin`]); from then on each refresh takes the near skin that
//! would have made the last period's sifting cheapest ([`NearSkinTuner`]): small for a settled
//! bed, larger for a lively one. A rebuild of the list invalidates the near lists (their slots
//! are renumbered): a new [`NeighborList::generation`].
//!
//! # Storage order
//! [`NeighborList::spatial_order`] sorts particles by cell, slab-major; the simulation stores them
//! in that order from every rebuild on, so that a particle's partners, its slots and its slab lie
//! close in memory. Pair histories follow their pair across a rebuild by the particles' ids
//! ([`NeighborList::held_pairs`], [`NeighborList::carry`]).
//!
//! # Invariants
//! * Every touching pair is in the list. A bond breaks at `δ_crit ≥ 0`, so a bonded pair always
//!   touches and its state is never dropped (except by a step so far beyond the stability limit
//!   that a bonded pair jumps apart by more than the skin: the run's guards report that).
//! * The list, and so the summation order of every pass, depends only on the positions at the
//!   build and on the storage order, never on the thread count.

use std::ops::Range;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::periodic::Periodic;
use crate::scatter::{NearList, NearVisit, SlabVisit, Window};

/// The first near lists' near skin as a fraction of the skin (the tuner takes over at the first
/// refresh): they hold about 2.7 slots per particle on the 19.2k LIGGGHTS bed, against 4.8
/// candidates and 0.65-0.8 touching pairs, and last about 250 steps there.
pub const NEAR_SKIN_FRACTION: f64 = 0.125;

thread_local! {
    /// Where a visit records its slab's near list before it is copied (`visit_slabs`), kept by
    /// the thread between visits.
    static RECORDING: std::cell::RefCell<NearList> =
        std::cell::RefCell::new(NearList::default());
}

/// Source of [`NeighborList::generation`]: unique over the process, so that near lists recorded
/// for one list (or one build of it) are never read with another.
static GENERATIONS: AtomicU64 = AtomicU64::new(1);

/// Verlet half list by owner, with its slabs and colour phases.
#[derive(Debug, Clone, Default)]
pub struct NeighborList {
    /// CSR offsets: owner k's pair slots are `offsets[k]..offsets[k + 1]`.
    offsets: Vec<u32>,
    /// The partner of every slot, ascending within an owner.
    partners: Vec<u32>,
    /// Whether an owner had a partner across a periodic face at the build: only these owners'
    /// separations need the minimum image until the next build
    /// ([`Window::needs_minimum_image`]).
    crossing: Vec<bool>,
    /// Particles of slab s: `slab_members[slab_offsets[s]..slab_offsets[s + 1]]`, ascending.
    slab_offsets: Vec<u32>,
    slab_members: Vec<u32>,
    /// Each particle's slab.
    slab_of: Vec<u32>,
    /// Each slab's successor (itself for the last slab of a non-wrapping axis).
    successor: Vec<u32>,
    /// Slabs of each colour phase, in the order they run.
    phases: Vec<Vec<u32>>,
    reference_positions: Vec<DVec3>,
    skin: f64,
    periodic: Option<Periodic>,
    /// The most slots any one particle is in, as owner or partner: no particle touches more
    /// particles than this until the next build ([`NeighborList::max_degree`]).
    max_degree: usize,
    /// Number of builds so far.
    pub builds: u64,
    /// Names the current build's slot numbering for [`NearPairs`] (0 before the first build).
    generation: u64,
}

/// Per slab, the slots the force pass tests between refreshes (the module's "Near lists"), and
/// the build of the list they were recorded for. Only [`NeighborList::for_each_slab_near`]
/// reads or writes them.
#[derive(Debug, Default)]
pub struct NearPairs {
    /// The [`NeighborList::generation`] the lists belong to (0: none).
    generation: u64,
    /// Each slab's entries, behind a lock only so that the concurrent visits of a colour phase
    /// can each take their own (never contended).
    slabs: Vec<Mutex<NearList>>,
    /// The near skin the next recording uses \[m\] (`None`: [`NeighborList::near_skin`]).
    skin: Option<f64>,
}

impl Clone for NearPairs {
    /// An empty store: a copied simulation records its near lists at its next force pass.
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl NearPairs {
    /// Whether the lists belong to the current build of `list` (if not, the next pass over
    /// them records them anew).
    #[must_use]
    pub fn belong_to(&self, list: &NeighborList) -> bool {
        self.generation != 0 && self.generation == list.generation
    }

    /// Number of entries over all slabs.
    #[must_use]
    pub fn len(&self) -> usize {
        self.slabs
            .iter()
            .map(|slab| slab.lock().expect("no visit panicked").len())
            .sum()
    }

    /// Whether no slab holds an entry.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The near skin \[m\] the lists are (or will next be) recorded with, for `list`: the one
    /// set by [`Self::set_skin`], else the list's default ([`NeighborList::near_skin`]).
    #[must_use]
    pub fn skin(&self, list: &NeighborList) -> f64 {
        self.skin.unwrap_or_else(|| list.near_skin())
    }

    /// Sets the near skin \[m\] of the next recording (the lists in hand keep theirs: only a
    /// recording may change it, [`NeighborList::for_each_slab_near`]).
    pub fn set_skin(&mut self, skin: f64) {
        self.skin = Some(skin);
    }
}

/// What one refresh period of the near lists showed: the data of [`NearSkinTuner::next`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearPeriod {
    /// The near skin the lists were recorded with \[m\].
    pub skin: f64,
    /// Steps the period lasted (from one recording to the next).
    pub steps: u64,
    /// The travel bound summed over those steps (`dt |v|max` per drift) \[m\].
    pub travel: f64,
    /// Entries the near lists held.
    pub entries: usize,
    /// The pairs touching when they were recorded.
    pub touching: usize,
}

/// Work of a full sift per candidate over the work of a near sift per entry, fitted to the
/// instruction counts of the 19.2k LIGGGHTS bed at four fixed near skins (skin/8 … skin/128:
/// about 68 and 56 instructions, `benches/instructions.sh`).
const FULL_SIFT_COST_RATIO: f64 = 1.2;

/// Chooses the near skin of each refresh period from the periods before it.
///
/// Per step the force pass sifts the near entries, `n(s)`: the touching pairs and those whose
/// gap is below the near skin s. Every `s / (2 τ)` steps it sifts all C candidates instead
/// (τ: the travel bound per step). Their sum per step, with the full sift's cost per candidate
/// `b` (`FULL_SIFT_COST_RATIO`, 1.2, fitted to instruction counts) times the near sift's per entry,
///
/// ```text
/// W(s) = n(s) + 2 b C τ / s          is least where    n'(s) = 2 b C τ / s²,   s* = √(2 b C τ / n'(s))
/// ```
///
/// The slope n'(s) is measured, not modelled: a packed bed has most of its near pairs within
/// a few tens of nanometres of touching (n − n_touching grows only as about s^0.25 between
/// skin/256 and skin/8 on the 19.2k LIGGGHTS bed), so the mean density (n − n_touching)/s would
/// overstate it fourfold. Each period's entries beyond the touching pairs, against the last
/// period's at another skin, give the slope; τ is the last period's. A static bed gets a small
/// near skin (about skin/71 on that bed, refreshed every 26 steps), a lively one a larger one
/// (a fixed skin/32 made that bed's step 4 % faster, and the flagship's deposition 15 % slower,
/// than skin/8). The skin stays between skin/256 and skin/4 and moves by at most a factor of two
/// per period. Which pairs a near list holds beyond the touching ones changes no force, so no
/// result depends on the choice.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NearSkinTuner {
    /// The last period's near skin \[m\] and entries beyond the touching pairs.
    last: Option<(f64, f64)>,
    /// The last measured slope n'(s) [1/m].
    slope: Option<f64>,
}

impl NearSkinTuner {
    /// The near skin for the next period \[m\], given the one that ended, the list's `candidates`
    /// and its `skin` \[m\].
    pub fn next(&mut self, period: NearPeriod, candidates: usize, skin: f64) -> f64 {
        let bounds = |s: f64| s.clamp(skin / 256.0, skin / 4.0);
        #[allow(clippy::cast_precision_loss)]
        let beyond = period.entries.saturating_sub(period.touching) as f64;
        if let Some((last_skin, last_beyond)) = self.last {
            // Skins 20 % apart or more: a slope the entries' own scatter does not swamp.
            if (period.skin - last_skin).abs() > 0.2 * period.skin.min(last_skin) {
                let slope = (beyond - last_beyond) / (period.skin - last_skin);
                if slope > 0.0 {
                    self.slope = Some(slope);
                }
            }
        }
        self.last = Some((period.skin, beyond));
        if period.steps == 0 || period.skin.is_nan() || period.skin <= 0.0 {
            return bounds(period.skin);
        }
        #[allow(clippy::cast_precision_loss)]
        let travel_per_step = period.travel / period.steps as f64;
        let best = match self.slope {
            #[allow(clippy::cast_precision_loss)]
            Some(slope) => {
                (2.0 * FULL_SIFT_COST_RATIO * candidates as f64 * travel_per_step / slope).sqrt()
            }
            // No slope yet: halve the skin (the default is large for a settled bed), so that
            // the next period measures one.
            None => 0.5 * period.skin,
        };
        bounds(best.clamp(0.5 * period.skin, 2.0 * period.skin))
    }
}

/// Pairs that carry state, with their values `T`, taken from a list before it is rebuilt (see
/// [`NeighborList::held_pairs`]) and keyed by the particles' indices at that time, which the
/// reorder of the rebuild maps to the new ones (its `order`, the `origin` of
/// [`NeighborList::carry`]). Holding the values (not slots of the old arrays) lets the old
/// per-slot arrays be freed before the new ones are allocated.
#[derive(Debug, Clone)]
pub struct HeldPairs<T> {
    /// `(lower << 32 | higher | OWNER_WAS_LOWER, value)`, sorted by key: the two old indices in
    /// 8 bytes, and the flag (whether the old owner had the lower index) in bit 31, which the
    /// indices never reach (fewer than 2^31 particles). An entry is then 8 bytes plus the value,
    /// 40 for a spring (16 with ids as the key): these entries are the rebuild's peak memory.
    entries: Vec<(u64, T)>,
}

/// The flag bit of a held pair's key (see [`HeldPairs`]).
const OWNER_WAS_LOWER: u64 = 1 << 31;

/// The key of the pair of old indices `a` and `b`, without the flag.
fn held_key(a: u32, b: u32) -> u64 {
    (u64::from(a.min(b)) << 32) | u64::from(a.max(b))
}

impl<T> HeldPairs<T> {
    /// The value held for the pair of the particles that had the indices `owner` and
    /// `partner` when it was held, and whether its owner changed ends (a history oriented
    /// owner → partner then flips sign).
    #[must_use]
    pub fn find(&self, owner: u32, partner: u32) -> Option<(&T, bool)> {
        let (e, turned) = self.position(owner, partner)?;
        Some((&self.entries[e].1, turned))
    }

    /// Where [`Self::find`] finds the pair: its entry number (for [`Self::value`]) and whether
    /// its owner changed ends.
    #[must_use]
    pub fn position(&self, owner: u32, partner: u32) -> Option<(usize, bool)> {
        let key = held_key(owner, partner);
        let e = self
            .entries
            .binary_search_by(|(k, _)| (k & !OWNER_WAS_LOWER).cmp(&key))
            .ok()?;
        let owner_was_lower = self.entries[e].0 & OWNER_WAS_LOWER != 0;
        Some((e, owner_was_lower != (owner < partner)))
    }

    /// The value of entry `e`.
    #[must_use]
    pub fn value(&self, e: usize) -> &T {
        &self.entries[e].1
    }

    /// True when no pair is held.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

impl<T> Default for HeldPairs<T> {
    fn default() -> Self {
        Self {
            entries: Vec::new(),
        }
    }
}

/// The cell grid of one build.
struct Grid {
    /// Per axis: where cell 0 starts \[m\], the cell edge \[m\], and on a periodic axis the number of
    /// cells across the period (≥ 3, checked when the model is built), so neighbour cells wrap.
    axes: [(f64, f64, Option<i64>); 3],
    /// The axis across which the cell layers form slabs (the longest extent).
    slab_axis: usize,
}

impl Grid {
    fn new(positions: &[DVec3], radii: &[f64], skin: f64, periodic: Option<&Periodic>) -> Self {
        let r_max = radii.iter().copied().fold(0.0, f64::max);
        let cell = 2.0 * r_max + skin;
        let lower = positions
            .iter()
            .copied()
            .fold(DVec3::splat(f64::INFINITY), DVec3::min)
            .to_array();
        let upper = positions
            .iter()
            .copied()
            .fold(DVec3::splat(f64::NEG_INFINITY), DVec3::max)
            .to_array();
        let mut axes = [(0.0, cell, None::<i64>); 3];
        let mut extent = [0.0; 3];
        for (axis, g) in axes.iter_mut().enumerate() {
            match periodic.and_then(|p| p.length[axis].map(|l| (p.lower.to_array()[axis], l))) {
                Some((start, length)) => {
                    #[allow(clippy::cast_possible_truncation)]
                    let count = ((length / cell).floor() as i64).max(1);
                    #[allow(clippy::cast_precision_loss)]
                    let size = length / count as f64;
                    *g = (start, size, Some(count));
                    extent[axis] = length;
                }
                None => {
                    *g = (lower[axis], cell, None);
                    extent[axis] = upper[axis] - lower[axis];
                }
            }
        }
        let slab_axis = (0..3)
            .max_by(|&a, &b| extent[a].total_cmp(&extent[b]).then(b.cmp(&a)))
            .unwrap_or(0);
        if let (start, _, Some(count)) = axes[slab_axis] {
            if count >= 5 && count % 2 == 1 {
                // An even number of slabs around a periodic axis pairs them up into two colour
                // phases of equal work. One layer fewer, each 1/(count − 1) wider, keeps the
                // cells at least `cell` wide; merging two layers into one slab instead made one
                // slab twice the others, and the phase that held it waited for it.
                #[allow(clippy::cast_precision_loss)]
                let size = extent[slab_axis] / (count - 1) as f64;
                axes[slab_axis] = (start, size, Some(count - 1));
            }
        }
        Self { axes, slab_axis }
    }

    #[inline]
    fn cell_of(&self, x: DVec3) -> [i64; 3] {
        let x = x.to_array();
        let mut c = [0i64; 3];
        for axis in 0..3 {
            let (start, size, count) = self.axes[axis];
            #[allow(clippy::cast_possible_truncation)]
            let index = ((x[axis] - start) / size).floor() as i64;
            c[axis] = count.map_or(index, |n| index.rem_euclid(n));
        }
        c
    }

    #[inline]
    fn neighbour_cell(&self, c: [i64; 3], offset: [i64; 3]) -> [i64; 3] {
        let mut n = [0i64; 3];
        for axis in 0..3 {
            // Saturating: a particle flung to an absurd place (1e301 m, by a blow-up that the
            // force pass's guards then report) sits in a cell at the end of the index range,
            // and its neighbours' indices must not overflow there.
            let shifted = c[axis].saturating_add(offset[axis]);
            n[axis] = self.axes[axis]
                .2
                .map_or(shifted, |count| shifted.rem_euclid(count));
        }
        n
    }

    /// The sort key of a cell: slab coordinate first.
    #[inline]
    fn key(&self, c: [i64; 3]) -> [i64; 3] {
        let a = self.slab_axis;
        [c[a], c[(a + 1) % 3], c[(a + 2) % 3]]
    }

    /// Slab indices wrap around a periodic slab axis with at least three slabs.
    fn wraps(&self) -> bool {
        self.axes[self.slab_axis].2.is_some_and(|n| n >= 3)
    }
}

impl NeighborList {
    /// An empty list with the given skin \[m\], over a domain periodic along `periodic`'s axes.
    #[must_use]
    pub fn new(skin: f64, periodic: Option<Periodic>) -> Self {
        Self {
            skin,
            periodic,
            ..Self::default()
        }
    }

    /// The square of the largest distance \[m²\] of a particle at `positions` from its position
    /// at the last build (infinite if the build had another number of particles): the rebuild
    /// test measures it only when a bound on it comes near half the skin
    /// ([`NeighborList::moved_too_far`]), so that the drift of every step need not stream the
    /// reference positions. The largest of the squares is exact in any order, so the thread
    /// count does not change it.
    #[must_use]
    pub fn largest_displacement_squared(&self, positions: &[DVec3]) -> f64 {
        if self.is_stale(positions.len()) {
            return f64::INFINITY;
        }
        let _pass = crate::team::PassName::enter("displacement test");
        crate::team::largest(
            crate::worth_parallel(positions.len()),
            (positions, &self.reference_positions),
            |x, x0| (*x - *x0).length_squared(),
        )
    }

    /// The rebuild test: whether a particle lies more than half the skin from its position at
    /// the last build, given the square of the largest such distance \[m²\]
    /// ([`NeighborList::largest_displacement_squared`]). Two particles that both moved less
    /// than half the skin closed their gap by less than the skin, so every pair that can touch
    /// is still in the list (its invariant).
    #[must_use]
    pub fn moved_too_far(&self, largest_displacement_squared: f64) -> bool {
        largest_displacement_squared > 0.25 * self.skin * self.skin
    }

    /// Whether the last build had a different number of particles than `count` (or there was
    /// none): the list must be rebuilt whatever the displacements.
    #[must_use]
    pub fn is_stale(&self, count: usize) -> bool {
        self.reference_positions.len() != count
    }

    /// The positions of the last build \[m\] (a restart saves them, so that a resumed run builds
    /// the same list and sums in the same order).
    #[must_use]
    pub fn reference_positions(&self) -> &[DVec3] {
        &self.reference_positions
    }

    /// The storage order that sorts the particles with `keep[k]` by cell, slab-major:
    /// `order[new] = old`. Particles of one cell keep their relative order.
    #[must_use]
    pub fn spatial_order(&self, positions: &[DVec3], radii: &[f64], keep: &[bool]) -> Vec<u32> {
        let grid = Grid::new(positions, radii, self.skin, self.periodic.as_ref());
        let mut keyed: Vec<([i64; 3], u32)> = positions
            .iter()
            .enumerate()
            .filter(|(k, _)| keep[*k])
            .map(|(k, x)| {
                (
                    grid.key(grid.cell_of(*x)),
                    u32::try_from(k).expect("fewer than 2^32 particles"),
                )
            })
            .collect();
        keyed.par_sort_unstable();
        keyed.into_iter().map(|(_, k)| k).collect()
    }

    /// Builds the list for the particles as stored, with `positions` as the reference of the
    /// next rebuild test. Pair slots start empty: carry histories over with [`NeighborList::carry`].
    pub fn build(&mut self, positions: &[DVec3], radii: &[f64]) {
        // No near list belongs to a list being built (not even if the build is cut short).
        self.generation = 0;
        // The old list goes first, so that the old and new never coexist (peak memory).
        for v in [
            &mut self.offsets,
            &mut self.partners,
            &mut self.slab_offsets,
        ] {
            *v = Vec::new();
        }
        self.slab_members = Vec::new();
        self.slab_of = Vec::new();
        self.crossing = Vec::new();
        let n = positions.len();
        let grid = Grid::new(positions, radii, self.skin, self.periodic.as_ref());
        // Cells are recomputed where needed rather than stored (24 bytes per particle less at
        // the rebuild's peak). Particle indices by cell, slab-major: after a rebuild's
        // reordering (`spatial_order`) the particles already are in this order, and no sort runs.
        let cell_key = |k: u32| grid.key(grid.cell_of(positions[k as usize]));
        let mut order: Vec<u32> =
            (0..u32::try_from(n).expect("fewer than 2^32 particles")).collect();
        if !order.is_sorted_by_key(|&k| cell_key(k)) {
            order.par_sort_unstable_by_key(|&k| (cell_key(k), k));
        }
        // Distinct cells (by key) with the start of their run in `order`, at exact size.
        let distinct = 1 + order
            .windows(2)
            .filter(|w| cell_key(w[0]) != cell_key(w[1]))
            .count();
        let mut runs: Vec<([i64; 3], u32)> = Vec::with_capacity(distinct);
        for (i, &k) in order.iter().enumerate() {
            let key = cell_key(k);
            if runs.last().is_none_or(|(last, _)| *last != key) {
                runs.push((key, u32::try_from(i).expect("fewer than 2^32 particles")));
            }
        }
        // The members of cell `c`, found from `cursor`, the run where the last search for the
        // same neighbour offset ended ([`seek_run`]).
        let members = |c: [i64; 3], cursor: &mut usize| -> &[u32] {
            let key = grid.key(c);
            *cursor = seek_run(&runs, *cursor, &key);
            match runs.get(*cursor) {
                Some((run, start)) if *run == key => {
                    let end = runs
                        .get(*cursor + 1)
                        .map_or(order.len(), |(_, s)| *s as usize);
                    &order[*start as usize..end]
                }
                _ => &[],
            }
        };

        let (slab_of, slab_count) = slabs(&grid, positions);
        let wrapping = grid.wraps();
        let owns = |i: usize, j: usize| -> bool {
            let (si, sj) = (slab_of[i], slab_of[j]);
            if si == sj {
                i < j
            } else if wrapping {
                (si + 1) % slab_count == sj
            } else {
                si < sj
            }
        };
        let periodic = self.periodic;
        let skin = self.skin;
        // The members of cell `c` and of its 26 neighbours, dz, dy, dx from −1 to 1.
        let neighbourhood = |c: [i64; 3], cursors: &mut [usize; 27]| -> [&[u32]; 27] {
            let mut cells: [&[u32]; 27] = [&[]; 27];
            let offsets = (-1..=1)
                .flat_map(|dz| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dx| [dx, dy, dz])));
            for ((cell, offset), cursor) in cells.iter_mut().zip(offsets).zip(cursors) {
                *cell = members(grid.neighbour_cell(c, offset), cursor);
            }
            cells
        };
        // Returns whether a partner lies across a periodic face (its minimum image is not the
        // plain difference of the stored positions).
        let partners_of = |i: usize, cells: &[&[u32]; 27], found: &mut Vec<u32>| -> bool {
            let start = found.len();
            let mut crossing = false;
            for &j in cells.iter().copied().flatten() {
                let j = j as usize;
                if j == i || !owns(i, j) {
                    continue;
                }
                let plain = positions[j] - positions[i];
                let d = periodic.as_ref().map_or(plain, |p| p.minimum_image(plain));
                let cutoff = radii[i] + radii[j] + skin;
                if d.length_squared() < cutoff * cutoff {
                    #[allow(clippy::cast_possible_truncation)]
                    found.push(j as u32);
                    crossing |= d != plain;
                }
            }
            found[start..].sort_unstable();
            crossing
        };
        const CHUNK: usize = 2048;
        let chunks: Vec<(Vec<u32>, Vec<bool>, Vec<u32>)> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let (mut counts, mut crossing, mut found) = (Vec::new(), Vec::new(), Vec::new());
                // Stored by cell (as every rebuild stores them), consecutive particles mostly
                // share one: its neighbourhood is found once per cell, not once per particle.
                // The cells then come in key order, and so do their neighbours at each offset:
                // each offset's search starts where its last one ended.
                let mut last: Option<([i64; 3], [&[u32]; 27])> = None;
                let mut cursors = [0; 27];
                let owners = chunk * CHUNK..((chunk + 1) * CHUNK).min(n);
                for (i, &x) in owners.clone().zip(&positions[owners]) {
                    let c = grid.cell_of(x);
                    let cells = match last {
                        Some((cell, cells)) if cell == c => cells,
                        _ => last.insert((c, neighbourhood(c, &mut cursors))).1,
                    };
                    let before = found.len();
                    crossing.push(partners_of(i, &cells, &mut found));
                    counts.push(u32::try_from(found.len() - before).expect("< 2^32 pairs"));
                }
                (counts, crossing, found)
            })
            .collect();
        // Exact sizes: a growing `Vec` would keep up to twice the slots for the list's lifetime.
        let total: usize = chunks.iter().map(|(_, _, found)| found.len()).sum();
        // The offsets and a near-list entry hold a slot's number in 32 bits (`scatter::NearPair`):
        // far beyond any bed this machine holds (about 880 million spheres on a packed bed).
        assert!(
            u32::try_from(total).is_ok(),
            "{total} pair slots: the neighbour list holds fewer than 2^32"
        );
        self.offsets = Vec::with_capacity(n + 1);
        self.offsets.push(0);
        self.partners = Vec::with_capacity(total);
        self.crossing = Vec::with_capacity(n);
        for (counts, crossing, found) in chunks {
            self.crossing.extend_from_slice(&crossing);
            for count in counts {
                let last = *self.offsets.last().unwrap_or(&0);
                self.offsets
                    .push(last.checked_add(count).expect("fewer than 2^32 pairs"));
            }
            self.partners.extend_from_slice(&found);
        }

        // Particles by slab (counting sort, ascending within a slab).
        let mut slab_offsets = vec![0u32; slab_count as usize + 1];
        for s in &slab_of {
            slab_offsets[*s as usize + 1] += 1;
        }
        for s in 1..slab_offsets.len() {
            slab_offsets[s] += slab_offsets[s - 1];
        }
        let mut fill = slab_offsets.clone();
        let mut slab_members = vec![0u32; n];
        for (k, s) in slab_of.iter().enumerate() {
            let slot = &mut fill[*s as usize];
            slab_members[*slot as usize] = u32::try_from(k).expect("fewer than 2^32 particles");
            *slot += 1;
        }
        self.slab_offsets = slab_offsets;
        self.slab_members = slab_members;
        self.phases = colour_phases(slab_count, wrapping);
        self.successor = (0..slab_count)
            .map(|s| match (wrapping, s + 1 < slab_count) {
                (true, _) => (s + 1) % slab_count,
                (false, true) => s + 1,
                (false, false) => s,
            })
            .collect();
        self.slab_of = slab_of;
        self.max_degree = self.largest_degree();
        // The pair passes write to partners without checking each write (`scatter`): this is
        // the proof they rely on, one pass over the slots per build.
        assert!(
            self.owners_reach_their_partners(),
            "neighbour list: a partner outside its owner's slab and the successor"
        );
        self.reference_positions.clear();
        self.reference_positions.extend_from_slice(positions);
        self.builds += 1;
        self.generation = GENERATIONS.fetch_add(1, Ordering::Relaxed);
    }

    /// The skin \[m\]: the list holds every pair whose gap was below it at the build, and is
    /// rebuilt before any particle moves more than half of it from its reference position.
    #[must_use]
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// The default near skin \[m\] ([`NEAR_SKIN_FRACTION`] of the skin): a pair whose gap is below
    /// it at a refresh is in its slab's near list, until the simulation chooses another
    /// ([`NearSkinTuner`]).
    #[must_use]
    pub fn near_skin(&self) -> f64 {
        NEAR_SKIN_FRACTION * self.skin
    }

    /// Names the slot numbering of the current build, unique over the process (0 before the
    /// first build).
    #[must_use]
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Whether every partner lies in its owner's slab or in the successor slab: what makes the
    /// windows of one colour phase disjoint.
    fn owners_reach_their_partners(&self) -> bool {
        self.offsets.windows(2).enumerate().all(|(owner, range)| {
            let slab = self.slab_of[owner];
            let successor = self.successor[slab as usize];
            self.partners[range[0] as usize..range[1] as usize]
                .iter()
                .all(|&b| {
                    let s = self.slab_of[b as usize];
                    s == slab || s == successor
                })
        })
    }

    /// The most slots any one particle is in, as owner or partner (0 before the first build).
    /// Every pair in contact is in a slot until the next build, so no particle has more
    /// contacts than this: with the largest conductance of a contact it bounds a particle's
    /// total conductance (`thermal::HeatRate::at_most`).
    #[must_use]
    pub fn max_degree(&self) -> usize {
        self.max_degree
    }

    /// [`Self::max_degree`] counted over the slots: each owner's slots, and each partner's
    /// appearances. Made at the end of a build, once the build's own temporaries are gone, so
    /// that its 4 B a particle do not add to the build's peak.
    fn largest_degree(&self) -> usize {
        let mut degree: Vec<u32> = self.offsets.windows(2).map(|w| w[1] - w[0]).collect();
        for &partner in &self.partners {
            degree[partner as usize] += 1;
        }
        degree.into_iter().max().map_or(0, |d| d as usize)
    }

    /// Number of pair slots.
    #[must_use]
    pub fn pair_count(&self) -> usize {
        self.partners.len()
    }

    /// The partner of every slot.
    #[must_use]
    pub fn partners(&self) -> &[u32] {
        &self.partners
    }

    /// Number of slabs (the units of the colour phases).
    #[must_use]
    pub fn slab_count(&self) -> usize {
        self.slab_offsets.len().saturating_sub(1)
    }

    /// The particles of slab `s`, ascending.
    #[must_use]
    pub fn slab_members(&self, s: usize) -> &[u32] {
        &self.slab_members[self.slab_offsets[s] as usize..self.slab_offsets[s + 1] as usize]
    }

    /// Particle `k`'s slab.
    #[must_use]
    #[inline]
    pub fn slab_of(&self, k: usize) -> usize {
        self.slab_of[k] as usize
    }

    /// Owner `k`'s slots.
    #[must_use]
    #[inline]
    pub fn slots(&self, k: usize) -> Range<usize> {
        self.offsets[k] as usize..self.offsets[k + 1] as usize
    }

    /// Whether owner `k` had a partner across a periodic face at the build. If not, the plain
    /// difference of the stored positions is the minimum image of each of its touching pairs
    /// until the next build, and its pairs apart are apart under either
    /// ([`Window::needs_minimum_image`], whose rule this is).
    #[must_use]
    #[inline]
    pub fn needs_minimum_image(&self, k: usize) -> bool {
        self.crossing[k]
    }

    /// Every pair as `(slot, owner, partner)`, in slot order.
    pub fn pairs(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        self.pairs_of(0..self.offsets.len().saturating_sub(1))
    }

    /// The pairs of the owners `owners` as `(slot, owner, partner)`, in slot order.
    pub fn pairs_of(
        &self,
        owners: Range<usize>,
    ) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        owners.flat_map(move |k| {
            self.slots(k)
                .map(move |p| (p, k, self.partners[p] as usize))
        })
    }

    /// Calls `visit(&mut partial, slab)` for every slab, in the colour phases (see the module
    /// documentation), the slabs of a phase in parallel when `parallel`, and returns the partials
    /// reduced by `merge` (associative and commutative, for the result not to depend on the
    /// thread count). The visit's windows allow each owner's slots and the particles of the slab
    /// and of the successor slab, which hold all its partners.
    pub fn for_each_slab<R, V, M>(&self, parallel: bool, identity: R, visit: V, merge: M) -> R
    where
        R: Clone + Send + Sync,
        V: Fn(&mut R, &SlabVisit<'_>) + Sync,
        M: Fn(R, R) -> R + Sync + Send,
    {
        self.visit_slabs(parallel, None, identity, visit, merge)
    }

    /// As [`NeighborList::for_each_slab`], with each slab's near list in `near`: the visits
    /// record them anew ([`SlabVisit::records_near`]) if `refresh` or if they do not belong to
    /// this build, and read them otherwise ([`SlabVisit::near_pairs`]).
    pub fn for_each_slab_near<R, V, M>(
        &self,
        parallel: bool,
        near: &mut NearPairs,
        refresh: bool,
        identity: R,
        visit: V,
        merge: M,
    ) -> R
    where
        R: Clone + Send + Sync,
        V: Fn(&mut R, &SlabVisit<'_>) + Sync,
        M: Fn(R, R) -> R + Sync + Send,
    {
        let record = refresh || !near.belong_to(self) || near.slabs.len() != self.slab_count();
        // (Recording empties each slab's list before it writes it: no stale entry survives.)
        if record {
            near.generation = 0;
            near.slabs.resize_with(self.slab_count(), Mutex::default);
        }
        let total = self.visit_slabs(parallel, Some((&*near, record)), identity, visit, merge);
        if record {
            near.generation = self.generation;
        }
        total
    }

    /// The traversal of [`NeighborList::for_each_slab`], with near lists to read or record.
    #[allow(unsafe_code)]
    fn visit_slabs<R, V, M>(
        &self,
        parallel: bool,
        near: Option<(&NearPairs, bool)>,
        identity: R,
        visit: V,
        merge: M,
    ) -> R
    where
        R: Clone + Send + Sync,
        V: Fn(&mut R, &SlabVisit<'_>) + Sync,
        M: Fn(R, R) -> R + Sync + Send,
    {
        let run_slab = |s: &u32| {
            let slab = *s as usize;
            let mut partial = identity.clone();
            let mut held =
                near.map(|(pairs, _)| pairs.slabs[slab].lock().expect("no visit panicked"));
            let record = near.is_some_and(|(_, record)| record);
            // A list is recorded into this thread's scratch and then copied into the slab's
            // allocation (`NearList::copy_from`).
            let scratch = RECORDING.with(|scratch| {
                let mut list = scratch.take();
                list.clear();
                std::cell::RefCell::new(list)
            });
            let near_visit = match held.as_ref() {
                None => NearVisit::Off,
                Some(_) if record => NearVisit::Record(&scratch),
                Some(list) => NearVisit::Read(list),
            };
            // SAFETY: every partner lies in its owner's slab or the successor (checked at the
            // end of `build`); the slabs running concurrently are those of one colour phase,
            // whose sets {slab, successor} are disjoint (`colour_phases`; tested below); an
            // owner's slots belong to it alone; and a near list read belongs to this slab of
            // this build (`for_each_slab_near` records them anew for any other).
            let visit_of_slab = unsafe {
                SlabVisit::new(
                    *s,
                    self.successor[slab],
                    self.slab_members(slab),
                    &self.offsets,
                    &self.partners,
                    &self.slab_of,
                    &self.crossing,
                    near_visit,
                )
            };
            visit(&mut partial, &visit_of_slab);
            let recorded = scratch.into_inner();
            if let Some(list) = held.as_mut().filter(|_| record) {
                list.copy_from(&recorded);
            }
            RECORDING.with(|kept| kept.replace(recorded));
            partial
        };
        let mut total = identity.clone();
        for (k, phase) in self.phases.iter().enumerate() {
            let _part =
                crate::team::PassName::part(["even slabs", "odd slabs", "the last slab"][k]);
            // The members of the thread team take the same share of every phase's slabs at
            // every pass.
            let part = crate::team::fold_items(
                parallel && phase.len() > 1,
                phase.iter().collect(),
                || identity.clone(),
                |partial, _, slab| merge(partial, run_slab(slab)),
                &merge,
            );
            total = merge(total, part);
        }
        total
    }

    /// Calls `visit(&mut partial, window)` for every particle as owner, slab by slab as in
    /// [`NeighborList::for_each_slab`], and returns the partials reduced by `merge`.
    pub fn for_each_owner<R, V, M>(&self, parallel: bool, identity: R, visit: V, merge: M) -> R
    where
        R: Clone + Send + Sync,
        V: Fn(&mut R, &Window<'_>) + Sync,
        M: Fn(R, R) -> R + Sync + Send,
    {
        self.for_each_slab(
            parallel,
            identity,
            |partial, slab| {
                for window in slab.windows() {
                    visit(partial, &window);
                }
            },
            merge,
        )
    }

    /// The pairs for which `held(slot, owner)` gives a value (those with state worth keeping),
    /// keyed by the particles' current indices, before the particles are reordered and the list
    /// rebuilt.
    ///
    /// # Panics
    /// With 2^31 particles or more (the key's flag bit).
    #[must_use]
    pub fn held_pairs<T>(&self, held: impl Fn(usize, usize) -> Option<T>) -> HeldPairs<T> {
        // Counted first, so that the entries take exactly their size (they coexist with the old
        // and the new list: the rebuild's peak memory).
        let count = self
            .pairs()
            .filter(|&(p, owner, _)| held(p, owner).is_some())
            .count();
        let index = |k: usize| -> u32 {
            u32::try_from(k)
                .ok()
                .filter(|&k| u64::from(k) < OWNER_WAS_LOWER)
                .expect("fewer than 2^31 particles")
        };
        let mut entries: Vec<(u64, T)> = Vec::with_capacity(count);
        entries.extend(self.pairs().filter_map(|(p, owner, partner)| {
            let (a, b) = (index(owner), index(partner));
            let flag = if a < b { OWNER_WAS_LOWER } else { 0 };
            held(p, owner).map(|value| (held_key(a, b) | flag, value))
        }));
        entries.sort_unstable_by_key(|(key, _)| key & !OWNER_WAS_LOWER);
        HeldPairs { entries }
    }

    /// Per-slot values of the rebuilt list: `value(held, turned)` for each held pair, `turned`
    /// when its owner changed ends (a history oriented owner → partner flips sign), and
    /// `U::default()` for the rest. `origin[k]`: particle `k`'s index when the pairs were held
    /// (the reorder's `order`). A held pair that left the list was apart by more than the skin;
    /// were it bonded, it would break at the next pass anyway (δ < 0 ≤ δ_crit).
    #[must_use]
    pub fn carry<T: Sync, U: Copy + Default + Send>(
        &self,
        origin: &[u32],
        held: &HeldPairs<T>,
        value: impl Fn(&T, bool) -> U + Sync,
    ) -> Vec<U> {
        if held.entries.is_empty() {
            return vec![U::default(); self.partners.len()];
        }
        let lookup = |owner: usize, partner: usize| -> U {
            held.find(origin[owner], origin[partner])
                .map_or_else(U::default, |(v, turned)| value(v, turned))
        };
        // Filled in place, by chunks of owners (a parallel `collect` would hold its pieces and
        // the result at once).
        let mut values = vec![U::default(); self.partners.len()];
        let owners = self.offsets.len().saturating_sub(1);
        const CHUNK: usize = 4096;
        let mut chunks = Vec::with_capacity(owners.div_ceil(CHUNK));
        let mut rest = values.as_mut_slice();
        for first in (0..owners).step_by(CHUNK) {
            let last = (first + CHUNK).min(owners);
            let len = (self.offsets[last] - self.offsets[first]) as usize;
            let (chunk, tail) = rest.split_at_mut(len);
            chunks.push((first..last, chunk));
            rest = tail;
        }
        chunks.into_par_iter().for_each(|(owners, chunk)| {
            let start = self.offsets[owners.start] as usize;
            for k in owners {
                for p in self.slots(k) {
                    chunk[p - start] = lookup(k, self.partners[p] as usize);
                }
            }
        });
        values
    }
}

/// Each particle's slab and the number of slabs. On a periodic slab axis the slab is the cell
/// layer (an even number of them from five on, see [`Grid::new`]); otherwise the occupied layers
/// are numbered in order (empty layers dropped, so that a stray particle far away costs no
/// memory), which keeps "successor" meaning "the next occupied layer", the only one besides its
/// own that an owner's partners can lie in.
fn slabs(grid: &Grid, positions: &[DVec3]) -> (Vec<u32>, u32) {
    let axis = grid.slab_axis;
    let layer_of = |x: &DVec3| grid.cell_of(*x)[axis];
    let slab = |s: i64| u32::try_from(s).expect("fewer than 2^32 slabs");
    if let Some(count) = grid.axes[axis].2 {
        return (
            positions.iter().map(|x| slab(layer_of(x))).collect(),
            slab(count),
        );
    }
    let mut layers: Vec<i64> = positions.iter().map(layer_of).collect();
    layers.sort_unstable();
    layers.dedup();
    let rank = |layer: i64| -> u32 {
        u32::try_from(layers.binary_search(&layer).unwrap_or(0)).expect("fewer than 2^32 slabs")
    };
    let slab_of = positions.iter().map(|x| rank(layer_of(x))).collect();
    (
        slab_of,
        u32::try_from(layers.len()).expect("fewer than 2^32 slabs"),
    )
}

/// The position in `runs` (sorted by key) of the first run whose key is not below `key`,
/// searched from `from`, where the search for a nearby key ended: forward by doubling steps
/// (galloping), then by halving; from the start if `key` lies before `from` (a wrap of a
/// periodic axis). A neighbour list's build asks for each particle's 27 neighbour cells in the
/// particles' cell order: from the last position the next is a few runs on, found in a few
/// predictable steps where a search of all runs took about 14 mispredicted ones.
fn seek_run(runs: &[([i64; 3], u32)], from: usize, key: &[i64; 3]) -> usize {
    let before = |at: usize| runs.get(at).is_some_and(|(run, _)| run < key);
    if from > 0 && !before(from - 1) {
        return runs.partition_point(|(run, _)| run < key);
    }
    let (mut low, mut step) = (from, 1);
    while before(low + step - 1) {
        low += step;
        step *= 2;
    }
    // The first run not below `key` lies in low..low + step.
    let high = (low + step).min(runs.len());
    low + runs[low..high].partition_point(|(run, _)| run < key)
}

/// The colour phases: even slabs, then odd slabs; on a wrapping axis with an odd count (three
/// slabs: see [`Grid::new`]) the last slab (an even one, whose successor is slab 0) runs alone in a
/// third phase.
fn colour_phases(slab_count: u32, wrapping: bool) -> Vec<Vec<u32>> {
    let lonely_last = wrapping && slab_count % 2 == 1;
    let mut even: Vec<u32> = (0..slab_count).step_by(2).collect();
    let odd: Vec<u32> = (1..slab_count).step_by(2).collect();
    let last = lonely_last.then(|| even.pop()).flatten();
    let mut phases = vec![even, odd];
    if let Some(last) = last {
        phases.push(vec![last]);
    }
    phases.retain(|p| !p.is_empty());
    phases
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bed::rng::SplitMix64;

    /// A bed whose near entries beyond the touching pairs grow as `A s^α` (a packed bed has
    /// most of them within nanometres of touching, α ≈ 0.25), with `candidates` pairs in the
    /// list and a travel bound of `tau` \[m\] per step: the periods the tuner would see.
    fn period(skin: f64, alpha: f64, tau: f64) -> NearPeriod {
        let steps = (skin / (2.0 * tau)).floor().max(1.0);
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        NearPeriod {
            skin,
            steps: steps as u64,
            travel: steps * tau,
            entries: 10_000 + (40_000.0 * (skin / 1e-6).powf(alpha)) as usize,
            touching: 10_000,
        }
    }

    #[test]
    fn the_near_skin_settles_where_the_sift_costs_least() {
        let (skin, candidates) = (9e-6, 90_000);
        for (alpha, tau) in [(0.25, 2.3e-9), (1.0, 2.3e-9), (0.25, 2e-8), (0.5, 1e-9)] {
            // The work per step in near-entry units, W(s) = n(s) + 2 b C τ / s, at its least
            // on a fine grid of skins: what the tuner aims at.
            #[allow(clippy::cast_precision_loss)]
            let work = |s: f64| {
                let p = period(s, alpha, tau);
                p.entries as f64 + 2.0 * FULL_SIFT_COST_RATIO * candidates as f64 * tau / s
            };
            let best = (0..2000)
                .map(|k| skin / 256.0 * (256.0_f64 / 4.0).powf(f64::from(k) / 1999.0))
                .min_by(|a, b| work(*a).total_cmp(&work(*b)))
                .unwrap();
            let mut tuner = NearSkinTuner::default();
            let mut near_skin = skin / 8.0;
            for _ in 0..40 {
                let next = tuner.next(period(near_skin, alpha, tau), candidates, skin);
                // Within the bounds, and within a factor of two of the last skin.
                assert!((skin / 256.0..=skin / 4.0).contains(&next), "{next}");
                assert!(next <= 2.0 * near_skin && next >= 0.5 * near_skin);
                near_skin = next;
            }
            // The secant slope of a power law is not its tangent: the work, not the skin, is
            // what must come out near its least (within 2 %).
            let ratio = work(near_skin) / work(best);
            eprintln!(
                "α {alpha}, τ {tau:e}: settled at {near_skin:.3e} m, least work at {best:.3e} m, work ratio {ratio:.4}"
            );
            assert!(ratio < 1.02, "{ratio}");
        }
    }

    #[test]
    fn a_bed_at_rest_gets_the_smallest_near_skin_and_a_lively_one_a_larger_one() {
        let (skin, candidates) = (9e-6, 90_000);
        let mut resting = NearSkinTuner::default();
        let mut near_skin = skin / 8.0;
        for _ in 0..10 {
            let mut p = period(near_skin, 0.25, 1e-12);
            p.travel = 0.0;
            near_skin = resting.next(p, candidates, skin);
        }
        assert_eq!(near_skin, skin / 256.0);
        // A lively bed (1 µm per step, skins of a period of a few steps) goes the other way,
        // up to a quarter of the skin.
        let mut lively = NearSkinTuner::default();
        let mut near_skin = skin / 8.0;
        for _ in 0..10 {
            near_skin = lively.next(period(near_skin, 1.0, 1e-6), candidates, skin);
        }
        assert_eq!(near_skin, skin / 4.0);
        // A period of no steps (two refreshes in a row) keeps the skin.
        let mut tuner = NearSkinTuner::default();
        let mut p = period(skin / 16.0, 0.25, 1e-9);
        p.steps = 0;
        assert_eq!(tuner.next(p, candidates, skin), skin / 16.0);
    }

    fn random_cloud(count: usize, size: DVec3, seed: u64) -> Vec<DVec3> {
        let mut rng = SplitMix64(seed);
        (0..count)
            .map(|_| DVec3::new(rng.unit(), rng.unit(), rng.unit()) * size)
            .collect()
    }

    fn keys(list: &NeighborList, ids: &[u64]) -> Vec<(u64, u64)> {
        let mut keys: Vec<(u64, u64)> = list
            .pairs()
            .map(|(_, a, b)| (ids[a].min(ids[b]), ids[a].max(ids[b])))
            .collect();
        keys.sort_unstable();
        keys
    }

    /// The soundness of the coloured passes: every partner lies in its owner's window (the
    /// owner's slab or the successor), the windows of one phase are disjoint, and every particle
    /// is visited exactly once.
    fn assert_colouring_is_sound(list: &NeighborList, n: usize) {
        let mut visited = vec![0u32; n];
        for phase in &list.phases {
            let mut writer = vec![u32::MAX; n];
            for &s in phase {
                let range = list.slab_offsets[s as usize] as usize
                    ..list.slab_offsets[s as usize + 1] as usize;
                for &k in &list.slab_members[range] {
                    visited[k as usize] += 1;
                    for p in list.slots(k as usize) {
                        let slab = list.slab_of[list.partners[p] as usize];
                        assert!(slab == s || slab == list.successor[s as usize]);
                    }
                }
                // The window of slab s: every particle of s and of its successor.
                for (k, (slab, w)) in list.slab_of.iter().zip(&mut writer).enumerate() {
                    if *slab == s || *slab == list.successor[s as usize] {
                        assert!(
                            *w == u32::MAX || *w == s,
                            "slabs {} and {s} of one phase both reach particle {k}",
                            *w
                        );
                        *w = s;
                    }
                }
            }
        }
        assert!(visited.iter().all(|v| *v == 1), "every particle once");
    }

    #[test]
    fn a_run_is_sought_from_anywhere_as_a_search_of_all_runs_finds_it() {
        // Sorted keys with gaps and repeats of the first two components, as cells' keys are.
        let mut rng = SplitMix64(7);
        #[allow(clippy::cast_possible_wrap)]
        let mut below = |n: u64| (rng.next_u64() % n) as i64;
        let mut runs: Vec<([i64; 3], u32)> = (0..300)
            .map(|k| ([below(4), below(5), below(9)], k))
            .collect();
        runs.sort_unstable();
        runs.dedup_by_key(|(key, _)| *key);
        for from in 0..=runs.len() {
            for a in -1..5 {
                for c in -1..10 {
                    let key = [a, 2, c];
                    let expected = runs.partition_point(|(run, _)| *run < key);
                    assert_eq!(seek_run(&runs, from, &key), expected, "{key:?} from {from}");
                }
            }
        }
    }

    #[test]
    fn finds_exactly_the_pairs_within_the_cutoff() {
        let positions = random_cloud(400, DVec3::new(14.0, 9.0, 6.0), 1);
        let radii = vec![1.0; positions.len()];
        let ids: Vec<u64> = (0..positions.len() as u64).rev().collect(); // ids opposite to indices
        let mut list = NeighborList::new(0.3, None);
        list.build(&positions, &radii);
        let mut expected = Vec::new();
        for i in 0..positions.len() {
            for j in i + 1..positions.len() {
                if positions[i].distance(positions[j]) < 2.3 {
                    expected.push((ids[i].min(ids[j]), ids[i].max(ids[j])));
                }
            }
        }
        expected.sort_unstable();
        assert!(expected.len() > 300, "the cloud must be dense enough");
        assert_eq!(keys(&list, &ids), expected);
        assert_colouring_is_sound(&list, positions.len());
        assert!(list.phases.len() == 2 && list.phases[0].len() > 2);
    }

    #[test]
    fn finds_exactly_the_minimum_image_pairs_in_a_periodic_box() {
        // Random spheres of radius 1 in a box periodic in x and y, open in z, with 3, 4, 5 and 7
        // cells' room across x (3 cells need a third colour phase; 5 and 7 become 4 and 6 wider
        // layers, for two phases of equal slabs): the list must equal the O(n²) definition with
        // minimum-image distances, including pairs across the faces, and the colouring must stay
        // sound across the wrap.
        for (length_x, room_x) in [(7.0, 3), (9.3, 4), (11.6, 5), (16.2, 7)] {
            let cells_x = if room_x >= 5 && room_x % 2 == 1 {
                room_x - 1
            } else {
                room_x
            };
            let periodic = Periodic {
                lower: DVec3::new(-2.0, 1.0, 0.0),
                length: [Some(length_x), Some(7.0), None],
            };
            let positions: Vec<DVec3> = random_cloud(300, DVec3::new(length_x, 7.0, 4.0), 7)
                .into_iter()
                .map(|x| x + periodic.lower)
                .collect();
            let radii = vec![1.0; positions.len()];
            let ids: Vec<u64> = (0..positions.len() as u64).collect();
            let mut list = NeighborList::new(0.3, Some(periodic));
            list.build(&positions, &radii);
            let grid = Grid::new(&positions, &radii, 0.3, Some(&periodic));
            assert_eq!(grid.slab_axis, 0);
            assert_eq!(grid.axes[0].2, Some(cells_x));
            let mut expected = Vec::new();
            let mut across = 0;
            for i in 0..positions.len() {
                for j in i + 1..positions.len() {
                    let d = positions[j] - positions[i];
                    if periodic.minimum_image(d).length() < 2.3 {
                        expected.push((ids[i], ids[j]));
                        across += usize::from(d.length() >= 2.3);
                    }
                }
            }
            assert!(across > 10, "pairs across the faces ({across})");
            assert_eq!(keys(&list, &ids), expected);
            assert_colouring_is_sound(&list, positions.len());
            assert_eq!(list.phases.len(), if cells_x == 3 { 3 } else { 2 });
            let slab_count = list.slab_offsets.len() - 1;
            assert_eq!(slab_count as i64, cells_x);
            // The owners flagged for the minimum image are exactly those with a partner whose
            // plain difference is not its minimum image.
            let crossing: Vec<bool> = (0..positions.len())
                .map(|a| {
                    list.slots(a).any(|p| {
                        let d = positions[list.partners[p] as usize] - positions[a];
                        periodic.minimum_image(d) != d
                    })
                })
                .collect();
            assert!(crossing.iter().any(|c| *c) && !crossing.iter().all(|c| *c));
            let flagged = list.for_each_owner(
                false,
                vec![false; positions.len()],
                |flags, window| flags[window.owner().index()] = window.needs_minimum_image(),
                |a, b| a.iter().zip(&b).map(|(x, y)| *x || *y).collect(),
            );
            assert_eq!(flagged, crossing);
        }
    }

    #[test]
    fn spatial_order_groups_cells_and_drops_removed_particles() {
        let positions = random_cloud(500, DVec3::new(20.0, 5.0, 5.0), 3);
        let radii = vec![1.0; positions.len()];
        let keep: Vec<bool> = (0..positions.len()).map(|k| k % 7 != 0).collect();
        let list = NeighborList::new(0.3, None);
        let order = list.spatial_order(&positions, &radii, &keep);
        assert_eq!(order.len(), keep.iter().filter(|k| **k).count());
        assert!(order.iter().all(|&k| keep[k as usize]));
        // Slab-major (x is the longest axis): the x cell never decreases along the order.
        let min_x = positions.iter().map(|x| x.x).fold(f64::INFINITY, f64::min);
        let cell = |k: u32| ((positions[k as usize].x - min_x) / 2.3).floor();
        assert!(order.windows(2).all(|w| cell(w[0]) <= cell(w[1])));
    }

    #[test]
    fn history_follows_the_pair_and_turns_with_its_owner() {
        // Ids 7, 3, 5. The pair (3, 7) touches; its history is oriented owner → partner.
        let mut positions = vec![DVec3::ZERO, DVec3::X * 1.9, DVec3::X * 10.0];
        let radii = vec![1.0; 3];
        let mut ids = [7, 3, 5];
        let mut list = NeighborList::new(0.5, None);
        list.build(&positions, &radii);
        assert_eq!(list.pair_count(), 1);
        let (_, owner, _) = list.pairs().next().unwrap();
        let history = if ids[owner] == 7 { 1.0 } else { -1.0 };
        let held = list.held_pairs(|_, _| Some(history));
        // Swap the storage order of the two particles (a reorder with `order` [1, 0, 2]) and
        // bring id 5 close: the pair (3, 7) must keep its history, turned if its owner changed
        // ends; the new pair starts empty.
        let origin = [1, 0, 2];
        positions.swap(0, 1);
        ids.swap(0, 1);
        positions[2] = DVec3::new(3.8, 0.0, 0.0);
        list.build(&positions, &radii);
        assert_eq!(list.pair_count(), 2);
        let carried = list.carry(
            &origin,
            &held,
            |h: &f64, turned| if turned { -h } else { *h },
        );
        let mut seen = 0;
        for (p, owner, partner) in list.pairs() {
            let key = (ids[owner].min(ids[partner]), ids[owner].max(ids[partner]));
            if key == (3, 7) {
                let expected = if ids[owner] == 7 { 1.0 } else { -1.0 };
                assert_eq!(carried[p], expected);
                seen += 1;
            } else {
                assert_eq!(carried[p], 0.0);
            }
        }
        assert_eq!(seen, 1);
    }

    #[test]
    fn a_stray_particle_costs_no_empty_slabs() {
        let positions = vec![DVec3::ZERO, DVec3::new(1e6, 0.0, 0.0)];
        let mut list = NeighborList::new(0.3, None);
        list.build(&positions, &[1.0, 1.0]);
        assert_eq!(list.pair_count(), 0);
        // Two occupied layers, not half a million empty ones between them.
        assert_eq!(list.slab_offsets.len(), 3);
        assert_colouring_is_sound(&list, 2);
    }
}
