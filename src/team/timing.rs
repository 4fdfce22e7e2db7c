//! The team's passes timed, for `am-sim --team-times`: where a step's threads work and where
//! they wait.
//!
//! Off unless [`time_passes`] switched it on: a pass then costs one relaxed load more. On, each
//! call of [`super::fold_items`] reads the clock when it is posted, when each member starts,
//! when it has done its own share and when it has done its last item (taken from the others
//! included), and adds them to the totals of the pass it belongs to, named by the calling
//! thread's [`PassName`]. The docs/performance-log.md rounds that took 2-thread runs apart per pass
//! (fifty-third and fifty-fourth) read these figures.

use std::cell::Cell;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Whether the passes are timed ([`time_passes`]).
static TIMING: AtomicBool = AtomicBool::new(false);

/// The totals of every pass timed so far, in the order first met.
static TOTALS: Mutex<Vec<PassTimes>> = Mutex::new(Vec::new());

thread_local! {
    /// The pass the thread runs and the part of it ([`PassName`]).
    static CURRENT: Cell<(&'static str, &'static str)> = const { Cell::new(("other passes", "")) };
}

/// Times the team's passes from now on (see the module's documentation).
pub fn time_passes() {
    TIMING.store(true, Ordering::Relaxed);
}

/// The totals of every pass timed since [`time_passes`] or the last call, the longest first;
/// the next totals start from zero (so that a run's stages can be reported one by one).
#[must_use]
pub fn take_pass_times() -> Vec<PassTimes> {
    let mut totals = std::mem::take(&mut *TOTALS.lock().unwrap_or_else(|e| e.into_inner()));
    totals.sort_by(|a, b| b.wall.total_cmp(&a.wall));
    totals
}

/// Names the passes the calling thread hands to the team while the guard lives; the name in
/// force before comes back when it drops.
#[must_use = "the name holds only while the guard lives"]
pub struct PassName {
    previous: (&'static str, &'static str),
}

impl PassName {
    /// A pass: "pair pass", "opening pass (kicks, drift)".
    pub fn enter(name: &'static str) -> Self {
        Self {
            previous: CURRENT.replace((name, "")),
        }
    }

    /// A part of the pass in force, timed apart: "even slabs".
    pub fn part(part: &'static str) -> Self {
        let previous = CURRENT.get();
        CURRENT.set((previous.0, part));
        Self { previous }
    }
}

impl Drop for PassName {
    fn drop(&mut self) {
        CURRENT.set(self.previous);
    }
}

/// One pass's (or part's) totals over its calls.
#[derive(Debug, Clone, PartialEq)]
pub struct PassTimes {
    /// The pass's name ([`PassName::enter`]).
    pub name: &'static str,
    /// The part's name, empty for the whole pass ([`PassName::part`]).
    pub part: &'static str,
    /// Calls.
    pub calls: u64,
    /// From each call's posting to its return, summed \[s\].
    pub wall: f64,
    /// From each call's posting until its last member had done its last item, summed \[s\]:
    /// the latest of the members' `done` in each call. Not the latest of their sums, which
    /// reads lower wherever the member that finishes last changes from call to call; the call's
    /// `wall` beyond this is the caller's noticing the last report and the call's own return.
    pub last_done: f64,
    /// Each member's times, in member order (one member when the pass ran on the caller alone).
    pub members: Vec<MemberTimes>,
}

/// One member's times within the calls of a pass, each from the call's posting, summed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MemberTimes {
    /// Until the member started \[s\].
    pub started: f64,
    /// Until it had done its own share \[s\].
    pub own_done: f64,
    /// Until it had done its last item, those taken from the others' shares included \[s\].
    pub done: f64,
    /// Items of its own share it did.
    pub own_items: u64,
    /// Items it took from the others' shares.
    pub taken_items: u64,
}

/// The clock of one call, or nothing when the passes are not timed.
pub(super) struct CallTimer {
    posted: Instant,
    members: Vec<Mutex<MemberTimes>>,
}

impl CallTimer {
    /// A timer for a call on `size` members, if the passes are timed.
    pub(super) fn start(size: usize) -> Option<Self> {
        TIMING.load(Ordering::Relaxed).then(|| Self {
            posted: Instant::now(),
            members: (0..size).map(|_| Mutex::default()).collect(),
        })
    }

    /// Seconds since the call was posted.
    pub(super) fn now(&self) -> f64 {
        self.posted.elapsed().as_secs_f64()
    }

    /// Member `member`'s times in this call.
    pub(super) fn mark(&self, member: usize, times: MemberTimes) {
        *self.members[member]
            .lock()
            .unwrap_or_else(|e| e.into_inner()) = times;
    }

    /// Adds the call to its pass's totals (the pass named on the calling thread).
    pub(super) fn finish(self) {
        let wall = self.now();
        let (name, part) = CURRENT.get();
        let members: Vec<MemberTimes> = self
            .members
            .into_iter()
            .map(|m| m.into_inner().unwrap_or_else(|e| e.into_inner()))
            .collect();
        let mut totals = TOTALS.lock().unwrap_or_else(|e| e.into_inner());
        let index = match totals
            .iter()
            .position(|t| t.name == name && t.part == part && t.members.len() == members.len())
        {
            Some(index) => index,
            None => {
                totals.push(PassTimes {
                    name,
                    part,
                    calls: 0,
                    wall: 0.0,
                    last_done: 0.0,
                    members: vec![MemberTimes::default(); members.len()],
                });
                totals.len() - 1
            }
        };
        let total = &mut totals[index];
        total.calls += 1;
        total.wall += wall;
        total.last_done += members.iter().map(|m| m.done).fold(0.0, f64::max);
        for (sum, call) in total.members.iter_mut().zip(&members) {
            sum.started += call.started;
            sum.own_done += call.own_done;
            sum.done += call.done;
            sum.own_items += call.own_items;
            sum.taken_items += call.taken_items;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Team, fold_items};
    use super::*;
    use std::time::Duration;

    /// The totals of the pass named `name` in `totals`.
    fn totals_of<'t>(totals: &'t [PassTimes], name: &str) -> &'t PassTimes {
        totals
            .iter()
            .find(|t| t.name == name)
            .unwrap_or_else(|| panic!("no pass named {name}: {totals:?}"))
    }

    /// Each timed call adds once to its own pass: every item is counted once, as its member's
    /// own or as taken (member 0 is held up at its first item until member 1 took one of its
    /// share, unless member 1 took them all first: either way member 1 takes at least one item
    /// a call), and each member's times are ordered as its life is (start ≤ own share done ≤
    /// last item ≤ the call's return). Serial calls count as a team of one. A name holds only
    /// while its guard lives.
    #[test]
    fn timed_passes_count_every_item_once_in_the_named_pass() {
        time_passes();
        let (count, calls) = (64_usize, 3_u64);
        let team = Team::new(2);
        {
            let _pass = PassName::enter("timing test: team of two");
            let first_share = team.share(count, 0);
            for _ in 0..calls {
                let helped = AtomicBool::new(false);
                team.fold_items(
                    (0..count).collect(),
                    || 0_usize,
                    |sum, index, item| {
                        if index == 0 {
                            // Member 0 waits here until member 1 took an item of its share:
                            // none but a helper can, while it waits.
                            let start = Instant::now();
                            while !helped.load(Ordering::Acquire)
                                && start.elapsed() < Duration::from_secs(10)
                            {
                                std::thread::sleep(Duration::from_millis(1));
                            }
                        } else if first_share.contains(&index) {
                            helped.store(true, Ordering::Release);
                        }
                        sum + item
                    },
                    |a, b| a + b,
                );
            }
        }
        {
            let _pass = PassName::enter("timing test: serial");
            let _part = PassName::part("its part");
            fold_items(
                false,
                (0..count).collect(),
                || 0,
                |s, _, i| s + i,
                |a, b| a + b,
            );
        }
        fold_items(false, vec![1, 2], || 0, |s, _, i| s + i, |a, b| a + b);

        // (Other tests of this process may add passes of their own, under other names.)
        let totals = take_pass_times();
        let team_of_two = totals_of(&totals, "timing test: team of two");
        assert_eq!(team_of_two.calls, calls);
        assert_eq!(team_of_two.members.len(), 2);
        let items: u64 = team_of_two
            .members
            .iter()
            .map(|m| m.own_items + m.taken_items)
            .sum();
        assert_eq!(items, calls * count as u64);
        assert!(
            team_of_two.members[1].taken_items >= calls,
            "{team_of_two:?}"
        );
        for m in &team_of_two.members {
            assert!(0.0 <= m.started && m.started <= m.own_done, "{m:?}");
            assert!(
                m.own_done <= m.done && m.done <= team_of_two.last_done,
                "{m:?}"
            );
        }
        // Each call's latest finish is at least each member's and at most the call's return,
        // so their sums are ordered the same way.
        assert!(team_of_two.last_done <= team_of_two.wall, "{team_of_two:?}");

        let serial = totals_of(&totals, "timing test: serial");
        assert_eq!((serial.part, serial.calls), ("its part", 1));
        assert_eq!(serial.members.len(), 1);
        assert_eq!(serial.members[0].own_items, count as u64);
        // A team of one: its latest finish is its only member's.
        assert_eq!(serial.last_done, serial.members[0].done);
        // Outside the guards the name in force is the default again.
        assert!(
            totals
                .iter()
                .any(|t| t.name == "other passes" && t.members[0].own_items >= 2)
        );
        // Taken, the totals start again from zero.
        assert!(
            take_pass_times()
                .iter()
                .all(|t| !t.name.starts_with("timing test"))
        );
    }
}
