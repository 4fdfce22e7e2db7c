//! A team of threads for the passes of a step: every member takes the same share of each pass
//! and the members meet at a spinning barrier between passes, as OpenMP's threads do.
//!
//! Rayon hands out work by splitting and stealing, which balances any load but costs a few
//! microseconds per parallel region and scatters a pass's items over the threads anew each
//! time. A step of the 19.2k LIGGGHTS bed at 2 threads lasts about half a millisecond and opens
//! five regions: rayon's spinning and sleeping took about 6 % of the samples there, and a phase
//! of the pair pass lasted 2-6 % longer than its busier thread (docs/performance-log.md, thirteenth
//! round). A team member takes its share first (the same contiguous part of the particles and
//! slabs at every pass, so the same data in its cache), then helps the others from the back of
//! theirs, all but the item each is about to reach ([`Team::fold_items`]: on a shared machine a
//! member may lose its core for a while), and spins between regions instead of sleeping. A
//! wait longer than 100 µs naps between looks, so that a member the host took off its core can
//! have this one (`nap`); a member idle for longer than 200 µs (`SPIN`) sleeps until the next
//! job (outside the step loop).
//!
//! The team has as many members as the rayon pool the caller runs in (`--threads`): the caller is
//! member 0 and the others are threads of the team's own. Results are the same for any size and
//! any division of the work: the passes' partials are merged with associative, commutative
//! merges (`max`, the lowest index on ties), and every sum stays within a slab or a particle.
//!
//! `am-sim --team-times` times every pass per member (`team/timing.rs`): where the threads work
//! and where they wait.

#![allow(unsafe_code)]

use std::cell::UnsafeCell;
use std::collections::HashMap;
use std::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};

use crate::simd;

mod timing;
use timing::CallTimer;
pub use timing::{MemberTimes, PassName, PassTimes, take_pass_times, time_passes};

/// How long a member waits for the next job before it sleeps: far longer than the gaps between
/// the regions of a step (microseconds), far shorter than a human notices a busy core. For the
/// first half it spins ([`SPIN_BEFORE_NAPS`]), then it naps between looks ([`nap`]).
const SPIN: Duration = Duration::from_micros(200);

/// How long a wait of the team spins before it naps between looks ([`nap`]), half of [`SPIN`]:
/// above the waits of a quiet host's step (a member's imbalance, a few microseconds, tens on
/// cores far apart). At 25 µs the naps cost the 19.2k LIGGGHTS bed's 2-thread step about a
/// tenth on a quiet host (10 alternating runs, 0.75-0.97): a nap lasts longer than it asks
/// (the kernel's timer slack, 50 µs), and a member waiting for the next job napped past its
/// start.
const SPIN_BEFORE_NAPS: Duration = Duration::from_micros(100);

/// Gives the core away for a moment, in a wait of the team that has outlasted
/// [`SPIN_BEFORE_NAPS`]: on a host where another program takes a core, the member waited for
/// may be the one the scheduler took off, and only a core that falls idle runs it at once. A
/// yield (`std::thread::yield_now`) keeps the core where the scheduler sees nothing else to run
/// on it: the 19.2k LIGGGHTS bed at 2 threads beside one busy loop ran 5.6-10.0e6
/// particle-steps per second with yields (six runs), 0.95-1.06e7 with naps (three runs; 1.1e7
/// at 1 thread beside the loop). Alone, 22 alternating runs at 2 threads read no difference
/// within a noisy hour's spread (medians 0.946 and 0.973, pair medians 0.992 and 1.040;
/// docs/performance-log.md, fifty-ninth round).
fn nap() {
    std::thread::sleep(Duration::from_micros(20));
}

/// The clock of one wait of the team, shared by the caller's wait for the members
/// ([`Team::run`]) and a member's wait for the next job ([`next_job`]): both spin, then nap,
/// and only a member goes on to sleep.
struct Backoff {
    start: Instant,
    looks: u32,
}

impl Backoff {
    fn new() -> Self {
        Self {
            start: Instant::now(),
            looks: 0,
        }
    }

    /// Pauses before the next look. A spin, while the wait has lasted less than
    /// [`SPIN_BEFORE_NAPS`]; past it, returns how long the wait has lasted, for the caller to
    /// nap ([`nap`]) or sleep. The clock is read only every 64th look: a read costs more than
    /// a look.
    #[inline]
    fn pause(&mut self) -> Option<Duration> {
        self.looks = self.looks.wrapping_add(1);
        if self.looks % 64 == 0 {
            let waited = self.start.elapsed();
            if waited >= SPIN_BEFORE_NAPS {
                return Some(waited);
            }
        }
        std::hint::spin_loop();
        None
    }
}

/// A job as the members see it: the caller's closure with its lifetime erased. It is called only
/// between the caller's posting it and the last member's reporting back, while the caller waits
/// in [`Team::run`], so the closure outlives every call.
type Job = *const (dyn Fn(usize) + Sync);

/// What the caller and the members share.
struct Shared {
    /// Posted jobs so far; a member runs each once.
    generation: AtomicUsize,
    /// Members (besides the caller) still running the current job.
    running: AtomicUsize,
    /// The current job, written before `generation` is raised and read after it is seen.
    job: UnsafeCell<Option<Job>>,
    /// A member's job panicked: the caller panics too, once every member is done. (Where a
    /// panic unwinds: the tests. The release build aborts on a panic, Cargo.toml.)
    panicked: AtomicBool,
    /// Members asleep or about to sleep (they wait on `wake`).
    sleeping: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
}

// SAFETY: `job` is written only by the caller while no member reads it (every member has
// reported back on the previous job, and `generation` is raised after the write, with release
// ordering) and read by the members only after they see the raised generation (acquire).
unsafe impl Sync for Shared {}
// SAFETY: as above; the job pointer is only dereferenced under that protocol.
unsafe impl Send for Shared {}

/// A team of `size` members; see the module's documentation.
pub struct Team {
    size: usize,
    shared: Arc<Shared>,
    /// One job at a time: a second caller waits.
    caller: Mutex<()>,
}

impl std::fmt::Debug for Team {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Team").field("size", &self.size).finish()
    }
}

impl Team {
    /// A team of `size` members (at least 1): the caller and `size − 1` threads.
    fn new(size: usize) -> Self {
        let size = size.max(1);
        let shared = Arc::new(Shared {
            generation: AtomicUsize::new(0),
            running: AtomicUsize::new(0),
            job: UnsafeCell::new(None),
            panicked: AtomicBool::new(false),
            sleeping: AtomicUsize::new(0),
            lock: Mutex::new(()),
            wake: Condvar::new(),
        });
        for member in 1..size {
            let shared = Arc::clone(&shared);
            std::thread::Builder::new()
                .name(format!("am-sim team {member}"))
                .spawn(move || serve(&shared, member))
                .expect("the operating system starts a thread");
        }
        Self {
            size,
            shared,
            caller: Mutex::new(()),
        }
    }

    /// The team for the rayon pool the caller runs in (as many members as it has threads),
    /// made at the first call for that size and kept for the program's life.
    #[must_use]
    pub fn current() -> Arc<Self> {
        thread_local! {
            static LAST: std::cell::RefCell<Option<Arc<Team>>> = const { std::cell::RefCell::new(None) };
        }
        let size = rayon::current_num_threads();
        LAST.with_borrow_mut(|last| {
            if let Some(team) = last.as_ref().filter(|team| team.size == size) {
                return Arc::clone(team);
            }
            static TEAMS: OnceLock<Mutex<HashMap<usize, Arc<Team>>>> = OnceLock::new();
            let team = Arc::clone(
                TEAMS
                    .get_or_init(Mutex::default)
                    .lock()
                    .expect("no team was made by a panicking thread")
                    .entry(size)
                    .or_insert_with(|| Arc::new(Self::new(size))),
            );
            *last = Some(Arc::clone(&team));
            team
        })
    }

    /// The share of `count` items member `member` takes: contiguous, in member order, sizes
    /// differing by at most one.
    #[must_use]
    pub fn share(&self, count: usize, member: usize) -> Range<usize> {
        let (base, extra) = (count / self.size, count % self.size);
        let start = member * base + member.min(extra);
        start..start + base + usize::from(member < extra)
    }

    /// Runs `job(member)` once on every member, the caller as member 0, and returns when all
    /// are done.
    ///
    /// # Panics
    /// If a member's job panicked (after every member is done).
    pub fn run(&self, job: &(dyn Fn(usize) + Sync)) {
        if self.size == 1 {
            job(0);
            return;
        }
        let _one_at_a_time = self.caller.lock().unwrap_or_else(|e| e.into_inner());
        let shared = &*self.shared;
        // SAFETY: erasing the lifetime is sound because the caller does not return (nor unwind)
        // before every member has reported back (`Wait` below), and the members call the job
        // only before they report.
        let erased: Job = unsafe {
            std::mem::transmute::<*const (dyn Fn(usize) + Sync + '_), Job>(std::ptr::from_ref(job))
        };
        // SAFETY: every member reported back on the last job; none reads `job` until it sees
        // the generation raised below.
        unsafe { *shared.job.get() = Some(erased) };
        shared.running.store(self.size - 1, Ordering::Relaxed);
        shared.generation.fetch_add(1, Ordering::SeqCst);
        if shared.sleeping.load(Ordering::SeqCst) > 0 {
            let _guard = shared.lock.lock().unwrap_or_else(|e| e.into_inner());
            shared.wake.notify_all();
        }
        /// Waits for the members even if the caller's share unwinds.
        struct Wait<'a>(&'a Shared);
        impl Drop for Wait<'_> {
            fn drop(&mut self) {
                let mut backoff = Backoff::new();
                while self.0.running.load(Ordering::Acquire) != 0 {
                    if backoff.pause().is_some() {
                        nap();
                    }
                }
                if std::thread::panicking() {
                    // The caller's own panic goes on; a member's panic in the same job must not
                    // fail the next job.
                    self.0.panicked.store(false, Ordering::Release);
                }
            }
        }
        let wait = Wait(shared);
        job(0);
        drop(wait);
        assert!(
            !shared.panicked.swap(false, Ordering::AcqRel),
            "a member of the thread team panicked"
        );
    }
}

impl Team {
    /// `visit(member)` on every member, the results merged in member order (`merge` should be
    /// associative and commutative, for the result not to depend on the team's size).
    fn map_reduce<R: Send>(
        &self,
        identity: R,
        visit: impl Fn(usize) -> R + Sync,
        merge: impl Fn(R, R) -> R,
    ) -> R {
        if self.size == 1 {
            return merge(identity, visit(0));
        }
        let results: Vec<Mutex<Option<R>>> = (0..self.size).map(|_| Mutex::new(None)).collect();
        self.run(&|member| {
            let result = visit(member);
            *results[member].lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
        });
        results.into_iter().fold(identity, |total, result| {
            let result = result.into_inner().unwrap_or_else(|e| e.into_inner());
            merge(total, result.expect("every member ran its share"))
        })
    }

    /// Folds every item of `items` into a partial with `fold(partial, index, item)`, each
    /// member starting from `identity()`, and merges the members' partials into `identity()` in
    /// member order (`fold` and `merge` should give the same result in any grouping).
    ///
    /// Each member takes its share of the items (by [`Team::share`]) from the front, so that it
    /// works on the same items at every pass. A member done with its share then takes items
    /// from the back of the others' shares: a member whose core the host took for a while (this
    /// machine is shared) is helped instead of waited for. It leaves each share's next item to
    /// its owner, whose cache holds that item's data: on cores far apart, a helper took several
    /// times as long over it (docs/performance-log.md, fifty-sixth round).
    pub fn fold_items<T: Send, R: Send>(
        &self,
        items: Vec<T>,
        identity: impl Fn() -> R + Sync,
        fold: impl Fn(R, usize, T) -> R + Sync,
        merge: impl Fn(R, R) -> R,
    ) -> R {
        let count = items.len();
        if self.size == 1 {
            return fold_serially(items, identity, fold, merge);
        }
        let items = Items::new(items);
        let shares: Vec<Claims> = (0..self.size)
            .map(|member| Claims::new(self.share(count, member)))
            .collect();
        let timer = CallTimer::start(self.size);
        let folded = self.map_reduce(
            identity(),
            |member| {
                let started = timer.as_ref().map_or(0.0, CallTimer::now);
                let mut times = MemberTimes {
                    started,
                    ..MemberTimes::default()
                };
                let mut partial = identity();
                for (turn, claims) in shares
                    .iter()
                    .cycle()
                    .skip(member)
                    .take(self.size)
                    .enumerate()
                {
                    let own = turn == 0;
                    while let Some(index) = claims.claim(own) {
                        // SAFETY: `claim` hands out each index once.
                        partial = fold(partial, index, unsafe { items.take(index) });
                        if own {
                            times.own_items += 1;
                        } else {
                            times.taken_items += 1;
                        }
                    }
                    if own {
                        times.own_done = timer.as_ref().map_or(0.0, CallTimer::now);
                    }
                }
                if let Some(timer) = &timer {
                    times.done = timer.now();
                    timer.mark(member, times);
                }
                partial
            },
            merge,
        );
        if let Some(timer) = timer {
            timer.finish();
        }
        folded
    }
}

/// [`Team::fold_items`] on the team of the caller's rayon pool if `parallel`, else on the calling
/// thread (the same result: see [`Team::fold_items`]). The passes decide `parallel` by their size
/// (`crate::worth_parallel`).
pub fn fold_items<T: Send, R: Send>(
    parallel: bool,
    items: Vec<T>,
    identity: impl Fn() -> R + Sync,
    fold: impl Fn(R, usize, T) -> R + Sync,
    merge: impl Fn(R, R) -> R,
) -> R {
    if parallel {
        Team::current().fold_items(items, identity, fold, merge)
    } else {
        fold_serially(items, identity, fold, merge)
    }
}

/// Consecutive particles per item of the team's passes over particles: the drift, the particle
/// pass, the closing kick and the temperature update. One size for every such pass, so that a
/// member's share is the same particles in each (and their data stay in its cache from pass to
/// pass); small enough that a 19.2k-particle bed has 19 items to share, large enough that an
/// item's work dwarfs its claim.
pub const PARTICLES_PER_ITEM: usize = 1024;

/// A per-particle slice in items of [`PARTICLES_PER_ITEM`], or `None` for every item where the
/// scene has no such slice: zipped with the items of the particles' other slices, an optional
/// field neither shortens them nor costs anything per particle.
pub fn optional_items<T>(slice: Option<&mut [T]>) -> impl Iterator<Item = Option<&mut [T]>> {
    let mut items = slice.map(|slice| slice.chunks_mut(PARTICLES_PER_ITEM));
    std::iter::from_fn(move || match items.as_mut() {
        Some(items) => items.next().map(Some),
        None => Some(None),
    })
}

/// The largest `value(a[k], b[k])` over the particles `k` (0 without any, and NaN passed over as
/// `f64::max` does), in items of [`PARTICLES_PER_ITEM`] on the team if `parallel`. A largest
/// value is exact in any order, so the thread count does not change it. Each item runs in the
/// widest vector build (`simd::dispatch`): the values of a block of particles in a loop of
/// their own, then their maximum lane by lane (`simd::Largest`), so that `value` (a division,
/// a squared distance) takes a register of particles per instruction.
pub fn largest<A: Sync, B: Sync, F: Fn(&A, &B) -> f64 + Sync>(
    parallel: bool,
    (a, b): (&[A], &[B]),
    value: F,
) -> f64 {
    // Equal lengths, so that each block's values are all of the block (none left over from
    // the last one).
    assert_eq!(a.len(), b.len(), "one value of each slice per particle");
    let items: Vec<_> = a
        .chunks(PARTICLES_PER_ITEM)
        .zip(b.chunks(PARTICLES_PER_ITEM))
        .collect();
    let set = simd::InstructionSet::detect();
    fold_items(
        parallel,
        items,
        || 0.0,
        |largest: f64, _, (a, b)| largest_in(set, largest, (a, b), &value),
        f64::max,
    )
}

/// The largest of `start` and the values `value(a[k], b[k])` over two slices of one item or
/// chunk, on the calling thread, as [`largest`] takes each item's.
#[inline]
pub(crate) fn largest_in<A, B, F: Fn(&A, &B) -> f64>(
    set: simd::InstructionSet,
    start: f64,
    (a, b): (&[A], &[B]),
    value: &F,
) -> f64 {
    assert_eq!(a.len(), b.len(), "one value of each slice per particle");
    let mut lanes = simd::Largest::new(start);
    simd::dispatch(
        set,
        LargestOf {
            a,
            b,
            value,
            lanes: &mut lanes,
        },
    );
    lanes.value()
}

/// Particles per block of [`LargestOf`]: the block's values stay in the first-level cache.
const LARGEST_BLOCK: usize = 64;

/// The values `value(a[k], b[k])` of an item's particles taken into `lanes`, a
/// [`simd::Kernel`].
struct LargestOf<'a, A, B, F> {
    a: &'a [A],
    b: &'a [B],
    value: &'a F,
    lanes: &'a mut simd::Largest,
}

impl<A, B, F: Fn(&A, &B) -> f64> simd::Kernel for LargestOf<'_, A, B, F> {
    #[inline(always)]
    fn run(self) {
        let mut values = [0.0; LARGEST_BLOCK];
        for (a, b) in self
            .a
            .chunks(LARGEST_BLOCK)
            .zip(self.b.chunks(LARGEST_BLOCK))
        {
            let values = &mut values[..a.len()];
            for ((value, a), b) in values.iter_mut().zip(a).zip(b) {
                *value = (self.value)(a, b);
            }
            self.lanes.take(values);
        }
    }
}

/// The items folded in order into one partial, merged into `identity()` (timed as a team of
/// one when the passes are timed).
fn fold_serially<T, R>(
    items: Vec<T>,
    identity: impl Fn() -> R,
    fold: impl Fn(R, usize, T) -> R,
    merge: impl Fn(R, R) -> R,
) -> R {
    let timer = CallTimer::start(1);
    let count = items.len() as u64;
    let folded = items
        .into_iter()
        .enumerate()
        .fold(identity(), |partial, (index, item)| {
            fold(partial, index, item)
        });
    if let Some(timer) = timer {
        let done = timer.now();
        timer.mark(
            0,
            MemberTimes {
                started: 0.0,
                own_done: done,
                done,
                own_items: count,
                taken_items: 0,
            },
        );
        timer.finish();
    }
    merge(identity(), folded)
}

/// Items handed out one at a time by index; see [`Claims`].
struct Items<T>(Vec<UnsafeCell<Option<T>>>);

// SAFETY: an item is taken only by the member that claimed its index, and each index is
// claimed once (`Claims`), so no two threads reach the same item.
unsafe impl<T: Send> Sync for Items<T> {}

impl<T> Items<T> {
    fn new(items: Vec<T>) -> Self {
        Self(
            items
                .into_iter()
                .map(|item| UnsafeCell::new(Some(item)))
                .collect(),
        )
    }

    /// The item at `index`.
    ///
    /// # Safety
    /// No other thread takes the same index (each is claimed once).
    unsafe fn take(&self, index: usize) -> T {
        // SAFETY: see above.
        unsafe { (*self.0[index].get()).take() }.expect("each item is claimed once")
    }
}

/// The unclaimed part of a share, `front..back` packed in one word, so that its owner (from the
/// front) and the other members (from the back) claim each index exactly once.
struct Claims(AtomicU64);

impl Claims {
    fn new(share: Range<usize>) -> Self {
        let (front, back) = (
            u32::try_from(share.start).expect("fewer than 2^32 items"),
            u32::try_from(share.end).expect("fewer than 2^32 items"),
        );
        Self(AtomicU64::new(u64::from(front) << 32 | u64::from(back)))
    }

    /// Claims the next index from the front (`own`), or from the back for a helper, if any is
    /// left. A helper leaves the owner its next item: the call waits for the owner to come back
    /// to its share in any case (every member reports back), and the item's data are in the
    /// owner's cache, so a helper that takes it takes longer than its owner would. Taking it
    /// while the owner finished the one before made the opening pass's calls (kicks and drift)
    /// on the flagship's deposition at 2 threads last 51-55 µs instead of 34, on cores far apart
    /// (docs/performance-log.md, fifty-sixth round).
    fn claim(&self, own: bool) -> Option<usize> {
        let mut current = self.0.load(Ordering::Acquire);
        loop {
            #[allow(clippy::cast_possible_truncation)]
            let (front, back) = ((current >> 32) as u32, current as u32);
            if front >= back || (!own && back - front < 2) {
                // (The second: a helper's turn, and only the owner's next item left.)
                return None;
            }
            let (claimed, next) = if own {
                (front, u64::from(front + 1) << 32 | u64::from(back))
            } else {
                (back - 1, u64::from(front) << 32 | u64::from(back - 1))
            };
            match self
                .0
                .compare_exchange_weak(current, next, Ordering::AcqRel, Ordering::Acquire)
            {
                Ok(_) => return Some(claimed as usize),
                Err(actual) => current = actual,
            }
        }
    }
}

/// A member's life: wait for a job, run its share, report back.
fn serve(shared: &Shared, member: usize) {
    // The generation at the team's making (not at this thread's start: a job may be posted
    // before the thread runs).
    let mut seen = 0;
    loop {
        seen = next_job(shared, seen);
        // SAFETY: the caller wrote the job before raising the generation just seen, and waits
        // for this member's report before it returns.
        let job = unsafe { (*shared.job.get()).expect("a job is posted with its generation") };
        // SAFETY: see `Job`: the closure lives until this member reports back.
        let outcome = catch_unwind(AssertUnwindSafe(|| unsafe { (*job)(member) }));
        if outcome.is_err() {
            shared.panicked.store(true, Ordering::Release);
        }
        shared.running.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Waits until a generation after `seen` is posted and returns it: spinning for [`SPIN`], then
/// asleep.
fn next_job(shared: &Shared, seen: usize) -> usize {
    let mut backoff = Backoff::new();
    loop {
        let generation = shared.generation.load(Ordering::Acquire);
        if generation != seen {
            return generation;
        }
        let Some(waited) = backoff.pause() else {
            continue;
        };
        if waited < SPIN {
            // Another thread may want the core meanwhile: the caller, if the host took its core
            // (then the job is late), or another pool's (rayon's, in the passes outside the
            // team, or the neighbour-list build).
            nap();
            continue;
        }
        let guard = shared.lock.lock().unwrap_or_else(|e| e.into_inner());
        shared.sleeping.fetch_add(1, Ordering::SeqCst);
        // Checked again after announcing the sleep: a caller that raised the generation before
        // seeing `sleeping` is caught here, one that raised it after will notify.
        let generation = shared.generation.load(Ordering::SeqCst);
        if generation == seen {
            drop(
                shared
                    .wake
                    .wait_while(guard, |()| shared.generation.load(Ordering::SeqCst) == seen)
                    .unwrap_or_else(|e| e.into_inner()),
            );
        } else {
            drop(guard);
        }
        shared.sleeping.fetch_sub(1, Ordering::SeqCst);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slice is cut into the same items as the particles' other slices; a field the scene
    /// does not have gives `None` for as many items as they have.
    #[test]
    fn optional_items_cut_like_the_other_slices_or_give_none_for_each() {
        let count = 2 * PARTICLES_PER_ITEM + 5;
        let mut values: Vec<u32> = (0..u32::try_from(count).expect("small")).collect();
        let mut kept = vec![0.0_f64; count];
        let items: Vec<_> = values
            .chunks_mut(PARTICLES_PER_ITEM)
            .zip(optional_items(Some(kept.as_mut_slice())))
            .zip(optional_items::<f64>(None))
            .map(|((item, kept), none)| (item[0], item.len(), kept.map(|k| k.len()), none))
            .collect();
        assert_eq!(
            items,
            [
                (0, PARTICLES_PER_ITEM, Some(PARTICLES_PER_ITEM), None),
                (1024, PARTICLES_PER_ITEM, Some(PARTICLES_PER_ITEM), None),
                (2048, 5, Some(5), None),
            ]
        );
    }

    /// The largest value over two slices of several items, on the team as on one thread, is
    /// the plain maximum: the last particle's in the last item, or the first item's when it is
    /// made the largest; a NaN is passed over.
    #[test]
    fn the_largest_value_over_items_is_the_maximum_on_any_thread_count() {
        let count = 3 * PARTICLES_PER_ITEM + 7;
        #[allow(clippy::cast_precision_loss)]
        let mut a: Vec<f64> = (0..count).map(|k| k as f64).collect();
        let b = vec![2.0; count];
        a[5] = f64::NAN;
        let half = |a: &f64, b: &f64| a / b;
        #[allow(clippy::cast_precision_loss)]
        let last = (count - 1) as f64 / 2.0;
        for parallel in [false, true] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .expect("pool");
            assert_eq!(pool.install(|| largest(parallel, (&a, &b), half)), last);
            a[3] = 1e9;
            assert_eq!(pool.install(|| largest(parallel, (&a, &b), half)), 5e8);
            a[3] = 3.0;
        }
        assert_eq!(largest(true, (&[] as &[f64], &[] as &[f64]), half), 0.0);
    }

    /// A helper takes from the back but leaves the owner the next item of its share; the owner
    /// takes it, and nobody takes an item twice.
    #[test]
    fn helpers_leave_the_owner_its_next_item() {
        let claims = Claims::new(4..7);
        assert_eq!(claims.claim(false), Some(6));
        assert_eq!(claims.claim(false), Some(5));
        assert_eq!(claims.claim(false), None, "item 4 is left to its owner");
        assert_eq!(claims.claim(true), Some(4));
        assert_eq!(claims.claim(true), None);
        assert_eq!(claims.claim(false), None);
        let single = Claims::new(9..10);
        assert_eq!(single.claim(false), None);
        assert_eq!(single.claim(true), Some(9));
        let empty = Claims::new(3..3);
        assert_eq!((empty.claim(true), empty.claim(false)), (None, None));
    }

    #[test]
    fn shares_cover_the_items_once_in_order() {
        for size in 1..5 {
            let team = Team::new(size);
            for count in [0, 1, 3, 7, 100] {
                let mut next = 0;
                for member in 0..size {
                    let share = team.share(count, member);
                    assert_eq!(share.start, next);
                    assert!(share.len() == count / size || share.len() == count / size + 1);
                    next = share.end;
                }
                assert_eq!(next, count);
            }
        }
    }

    #[test]
    fn every_member_runs_every_job_once_also_after_sleeping() {
        let team = Team::new(3);
        let counts: Vec<AtomicUsize> = (0..3).map(|_| AtomicUsize::new(0)).collect();
        for round in 0..200 {
            if round % 50 == 49 {
                // Long enough for the members to fall asleep.
                std::thread::sleep(SPIN * 5);
            }
            team.run(&|member| {
                counts[member].fetch_add(1, Ordering::Relaxed);
            });
            for count in &counts {
                assert_eq!(count.load(Ordering::Relaxed), round + 1);
            }
        }
    }

    /// A member held up longer than the caller spins: the caller, napping between looks by
    /// then, returns after that member's report and never before it (the member's write is
    /// seen after `run` returns), whether the hold ends well past the spin, about at its end,
    /// or not at all.
    #[test]
    fn the_caller_returns_after_a_held_up_member_reports_and_not_before() {
        let team = Team::new(3);
        let done: Vec<AtomicUsize> = (0..3).map(|_| AtomicUsize::new(0)).collect();
        for round in 0..60 {
            let hold = [SPIN_BEFORE_NAPS * 3, SPIN_BEFORE_NAPS, Duration::ZERO][round % 3];
            let late = 1 + round % 2;
            team.run(&|member| {
                if member == late {
                    std::thread::sleep(hold);
                }
                done[member].fetch_add(1, Ordering::Release);
            });
            for count in &done {
                assert_eq!(count.load(Ordering::Acquire), round + 1);
            }
        }
    }

    /// Every item is folded once, the partials come back in member order, and a member held
    /// up on its first item is helped: the others take the rest of its share from the back, all
    /// but its next item.
    #[test]
    fn items_are_folded_once_and_a_held_up_member_is_helped() {
        let team = Team::new(3);
        let count = 1000;
        let first_share = team.share(count, 0);
        let (waiting, stolen) = (AtomicBool::new(false), AtomicBool::new(false));
        // Each partial is a list of one list: the items its member folded, in order.
        let folded = team.fold_items(
            (0..count).collect(),
            || vec![Vec::new()],
            |mut partial: Vec<Vec<usize>>, index, item| {
                assert_eq!(index, item);
                if index == 0 {
                    // Member 0 waits here until another member took an item of its share:
                    // none but a helper can, while it waits.
                    waiting.store(true, Ordering::Release);
                    let start = Instant::now();
                    while !stolen.load(Ordering::Acquire)
                        && start.elapsed() < Duration::from_secs(10)
                    {
                        std::thread::yield_now();
                    }
                    waiting.store(false, Ordering::Release);
                } else if first_share.contains(&index) && waiting.load(Ordering::Acquire) {
                    stolen.store(true, Ordering::Release);
                }
                partial[0].push(index);
                partial
            },
            |mut all, partial| {
                all.extend(partial);
                all
            },
        );
        assert!(
            stolen.load(Ordering::Acquire),
            "nobody helped the held-up member"
        );
        assert_eq!(folded.len(), 4, "the identity and one partial per member");
        assert_eq!(
            folded[1][0], 0,
            "member 0's partial comes first and begins its share"
        );
        let mut every: Vec<usize> = folded.concat();
        every.sort_unstable();
        assert_eq!(every, (0..count).collect::<Vec<_>>());
    }

    #[test]
    fn a_panicking_member_makes_the_caller_panic_after_all_are_done() {
        let team = Team::new(2);
        let done = AtomicUsize::new(0);
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            team.run(&|member| {
                done.fetch_add(1, Ordering::Relaxed);
                assert!(member != 1, "member 1 fails");
            });
        }));
        assert!(outcome.is_err());
        assert_eq!(done.load(Ordering::Relaxed), 2);
        // The team still works.
        team.run(&|_| {
            done.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(done.load(Ordering::Relaxed), 4);
    }

    /// When the caller and a member both panic in one job, the caller's panic goes on and the
    /// member's is not carried into the next job, which succeeds.
    #[test]
    fn a_job_after_one_where_every_member_panicked_succeeds() {
        let team = Team::new(2);
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            team.run(&|member| panic!("member {member} fails"));
        }));
        let message = outcome.expect_err("the job panicked");
        assert_eq!(
            message.downcast_ref::<String>().map(String::as_str),
            Some("member 0 fails")
        );
        let done = AtomicUsize::new(0);
        team.run(&|_| {
            done.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(done.load(Ordering::Relaxed), 2);
    }
}
