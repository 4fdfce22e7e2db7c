//! How far apart the host has put this machine's cores just now: the round trip of one cache
//! line between two threads, each waiting for the other's write before it writes back.
//!
//! On the 2-vCPU KVM guests am-sim is measured on (AMD EPYC, Zen 4), this reads about 55-80 ns
//! when the host runs both vCPUs on cores that share a third-level cache, about 120-140 ns at
//! times, and about 300-370 ns at others (cores farther apart: another die or socket); the host
//! moves between these every few minutes. A 2-thread run of the 19.2k LIGGGHTS bed reads about
//! 5.0e7 particle-steps/s on the near cores and 3.9e7 on the farthest, while two independent
//! 1-thread runs, one per core, lose nothing on either (docs/performance-log.md, fifty-third
//! round): what the team's members share (the slabs at the two cuts between their shares, an
//! item taken from the back of another's share) costs several times as much on far cores.
//! `benches/liggghts_compare.sh` prints this reading with each run of two threads or more.
//!
//! The two threads are pinned to the first two cores the process may run on (the team's members
//! are not pinned, but two busy threads on a 2-core machine run one on each core): unpinned, a
//! round now and then read several times the pinned figure while the pinned one held steady.
//!
//! Run: `cargo bench --bench core_latency` (prints the median of 5 rounds in ns).

#![allow(unsafe_code)]

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Round trips per round: about 10-40 ms a round.
const TRIPS: u64 = 100_000;

/// The first two cores this process may run on, if it may run on two.
fn two_cores() -> Option<(usize, usize)> {
    // SAFETY: `set` is a plain bit set that `sched_getaffinity` fills for this process.
    let set = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        (libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &raw mut set) == 0)
            .then_some(set)?
    };
    // SAFETY: `CPU_ISSET` reads the bit set filled above.
    let mut cores =
        (0..libc::CPU_SETSIZE as usize).filter(|&c| unsafe { libc::CPU_ISSET(c, &set) });
    Some((cores.next()?, cores.next()?))
}

/// Pins the calling thread to `core`.
fn pin(core: usize) {
    // SAFETY: a zeroed bit set with one bit set, passed with its size; 0 is the calling thread.
    let pinned = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(core, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &raw const set) == 0
    };
    assert!(pinned, "core {core} is one this process may run on");
}

/// One cache line of its own, so that nothing else shares it.
#[repr(align(128))]
struct Line(AtomicU64);

/// The mean round trip \[ns\] of `TRIPS` passes of the line: this thread writes odd values and
/// waits for the next even one, the other thread answers each odd value with the next even one.
fn round(line: &Arc<Line>, (first, second): (usize, usize)) -> f64 {
    pin(first);
    let other = {
        let line = Arc::clone(line);
        std::thread::spawn(move || {
            pin(second);
            for trip in 0..TRIPS {
                while line.0.load(Ordering::Acquire) != 2 * trip + 1 {
                    std::hint::spin_loop();
                }
                line.0.store(2 * trip + 2, Ordering::Release);
            }
        })
    };
    line.0.store(0, Ordering::Release);
    let start = Instant::now();
    for trip in 0..TRIPS {
        line.0.store(2 * trip + 1, Ordering::Release);
        while line.0.load(Ordering::Acquire) != 2 * trip + 2 {
            std::hint::spin_loop();
        }
    }
    let elapsed = start.elapsed();
    other.join().expect("the answering thread does not panic");
    #[allow(clippy::cast_precision_loss)]
    let trips = TRIPS as f64;
    elapsed.as_secs_f64() * 1e9 / trips
}

fn main() {
    // `cargo bench` passes `--bench`; nothing here takes arguments.
    let Some(cores) = two_cores() else {
        println!("core-to-core round trip: this process may run on one core only");
        return;
    };
    let line = Arc::new(Line(AtomicU64::new(0)));
    let mut rounds: Vec<f64> = (0..5).map(|_| round(&line, cores)).collect();
    rounds.sort_by(f64::total_cmp);
    println!(
        "core-to-core round trip: {:.0} ns (cores {} and {}, median of 5 rounds of {TRIPS}; {:.0}-{:.0} ns)",
        rounds[2], cores.0, cores.1, rounds[0], rounds[4]
    );
}
