//! The tangential springs of the pairs in contact, stored beside the neighbour list.
//!
//! A Verlet list holds every pair closer than the cut-off plus the skin: on the LIGGGHTS bed
//! about 4.8 slots per particle, of which about one touches. Only touching pairs have a
//! tangential spring, so a 32-byte history per slot would mostly hold zeros. Instead the springs
//! live in one pool per slab of the list, each with its slot, in the order the pair pass meets
//! them: slot order. The pass reads a contact's spring where the last pass left it, with a
//! cursor that only moves forwards, and appends its new spring to a second buffer: the one whose
//! springs its thread's last slab visit has just read to the end ([`Pool`]). The reads and the
//! writes therefore walk their buffers forwards, as the hardware prefetchers like (a pool with
//! reused entries was measured 15-18 % slower on the 20k bed), new contacts need no free list,
//! and the pools hold about one pass's springs and a buffer per thread (two buffers per slab
//! that swapped after each pass held two). One task visits a slab's owners at a time, in a fixed
//! order, so the pools need no locks and do not depend on the thread count.
//!
//! Because the pass meets the touching pairs in the order the last pass met them, the spring of
//! a contact is always the first the pass has not read yet, or no spring is: no slot needs an
//! entry number, and a slot's spring is found without a load per slot. A spring the pass passes
//! over belongs to a pair that came apart, and is released right there, in slot order
//! ([`Pool::read`]). (Each slot held a 4-byte entry number before, which the pair pass's sift
//! tested for every candidate: 1.6 % of the step, and 20 B per particle.) A rebuild carries the
//! non-zero springs over by id key.

use rayon::prelude::*;

use crate::contact::tangential::TangentialSpring;
use crate::neighbor::{HeldPairs, NeighborList};
use crate::scatter::{Opened, OwnSlab, PerSlab, Scatter, SlabVisit, Slot};

/// A spring and the slot of its pair.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct HeldSpring {
    spring: TangentialSpring,
    /// The pair's slot in the neighbour list.
    slot: u32,
}

/// What [`Pool::meet`] found at the front of the last pass's unread springs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Met {
    /// The spring of the slot asked for.
    Spring(TangentialSpring),
    /// A spring of an earlier slot, which the pass passed over: its pair came apart.
    PassedOver(HeldSpring),
    /// The slot holds no spring.
    Nothing,
}

/// The springs of one slab's contacts, each with its slot: those the last pass left (`springs`,
/// in ascending slot order, of which those from `read` on are not read yet by the running pass)
/// and those the running pass wrote (`next`, in ascending slot order). Outside a pass every
/// spring is in `springs`, unread, and `next` is empty: a pool is always ready for the next
/// pass, which needs no start.
///
/// The pass meets a slab's slots in ascending order at every pass, so it reads the last pass's
/// springs in ascending order too, with a cursor that only moves forwards. Its new springs go
/// into a second buffer: the one whose springs another visit of the same thread has just read
/// to the end (the end of that visit hands it to the thread, the next visit's first room
/// takes it), so a slab holds one buffer between visits and a thread one more: about one
/// pass's springs in all, as the ring in one buffer that this replaced held (the eleventh
/// round's ring: 32 B per contact less than two buffers per slab). Where the ring read and
/// wrote one buffer, wrapping, and counted its unread and free places at every read and append
/// (26 of the fill's 96 instructions per contact on the 19.2k LIGGGHTS bed,
/// docs/performance-log.md, sixty-fifth round), a read here is a test of the cursor against the
/// length (the step 321.0 → 311.7 instructions per particle-step, sixty-sixth round), and the
/// write-back writes a round of lanes' springs into room made once for the round
/// ([`Pool::room`]), its place in a register (311.7 → 308.8, sixty-eighth round).
///
/// The state is the pass's cursor itself, so that the pair pass takes a slab's pool out of the
/// histories for a round of its contacts ([`OpenHistories::with_own`]) and walks it as a value
/// of its own, which the compiler keeps in registers or the pass's stack frame. Reached through
/// the shared histories at every contact, the pool's fields had been loaded through a pointer,
/// tested and stored again for each read and append: taking the pool per round took 9.7 of the
/// 364.3 instructions per particle-step of the 19.2k LIGGGHTS bed (docs/performance-log.md,
/// fifty-ninth round).
#[derive(Debug, Clone, Default)]
pub struct Pool {
    /// The last pass's springs, in slot order.
    springs: Vec<HeldSpring>,
    /// The first of `springs` the running pass has not read yet.
    read: usize,
    /// The running pass's springs, in slot order.
    next: Vec<HeldSpring>,
    /// Taken out for a slab visit's walk ([`OpenHistories::with_own`]): this pool is the empty
    /// stand-in.
    #[cfg(debug_assertions)]
    taken: bool,
}

/// The places a pool's buffer gets for `count` springs: an eighth more and 16, since the
/// number of a slab's contacts changes slowly (at a rebuild's carry and when a pass's buffer
/// grows).
fn room_for(count: usize) -> usize {
    count + count / 8 + 16
}

thread_local! {
    /// A buffer of springs a visit read to the end ([`Pool::end_visit`]), empty, for the next
    /// visit of the same thread to write its springs into ([`Pool::room`]): a slab's new
    /// springs go into the lines its thread has just read, with no allocation per visit.
    static SPARE: std::cell::Cell<Vec<HeldSpring>> = const { std::cell::Cell::new(Vec::new()) };
}

impl Pool {
    /// The number of the last pass's springs not read yet.
    #[inline]
    fn unread(&self) -> usize {
        self.springs.len() - self.read
    }

    /// The springs the last pass left, in slot order (outside a pass).
    fn springs(&self) -> impl Iterator<Item = &HeldSpring> {
        self.springs[self.read..].iter()
    }

    /// The index in `springs` of the last pass's spring of `slot`, or where it would go
    /// (outside a pass).
    fn find(&self, slot: u32) -> Result<usize, usize> {
        self.springs[self.read..]
            .binary_search_by_key(&slot, |held| held.slot)
            .map(|e| self.read + e)
            .map_err(|e| self.read + e)
    }

    /// Meets `slot` in a pass (the slots met must ascend): the first unread spring, taken if it
    /// belongs to `slot` or to a slot before it (passed over), left otherwise.
    #[inline(always)]
    fn meet(&mut self, slot: u32) -> Met {
        match self.springs.get(self.read) {
            Some(&first) if first.slot <= slot => {
                self.read += 1;
                if first.slot == slot {
                    Met::Spring(first.spring)
                } else {
                    Met::PassedOver(first)
                }
            }
            _ => Met::Nothing,
        }
    }

    /// Takes the first unread spring, if any: at the end of a pass, the springs it did not meet.
    fn take_unmet(&mut self) -> Option<HeldSpring> {
        let first = *self.springs.get(self.read)?;
        self.read += 1;
        Some(first)
    }

    /// Appends `value` for the next pass, as the pair pass's [`SpringRoom::write`] does.
    #[cfg(test)]
    fn append(&mut self, value: HeldSpring) {
        self.room(1).append(value);
    }

    /// Room in the running pass's buffer for the springs of `count` more contacts, written in
    /// slot order through the returned [`SpringRoom`]. The buffer is tested once for the
    /// `count`, not once per spring: the write-back writes a round of lanes' springs into the
    /// room with its place in a register, where a push per contact loaded, tested and stored
    /// the buffer's length and pointer through memory (the compiler cannot tell the buffer's
    /// header from the particles' sums the write-back adds to).
    #[inline(always)]
    pub fn room(&mut self, count: usize) -> SpringRoom<'_> {
        if self.next.capacity() - self.next.len() < count {
            self.grow(count);
        }
        SpringRoom::new(&mut self.next, count)
    }

    /// Room for `count` more springs in the running pass's buffer: the thread's spare buffer if
    /// the pass has written none yet (its first room of the visit), and where that lacks the
    /// room, room for the springs written and those still unread (each may be written again)
    /// and an eighth more and 16 (the number of a slab's contacts changes slowly), so that a
    /// spare taken from a smaller slab grows once, not by steps. Out of line and cold: it runs
    /// about once per visit and a few times per build, while the pair pass asks for room once
    /// per round of lanes.
    #[cold]
    #[inline(never)]
    fn grow(&mut self, count: usize) {
        if self.next.capacity() == 0 {
            self.next = SPARE.take();
            debug_assert!(self.next.is_empty(), "a spare buffer holding springs");
        }
        if self.next.capacity() - self.next.len() < count {
            // What this pass may still write (a spring per unread one) and what it wrote: the
            // springs the ring held, so its rule.
            let live = self.unread() + self.next.len();
            let room = (room_for(live) - self.next.len()).max(count);
            self.next.reserve_exact(room);
        }
    }

    /// At the end of the visit, after the springs it did not meet were released: the last
    /// pass's buffer, read to the end, goes to the thread for its next visit to write into.
    fn end_visit(&mut self) {
        debug_assert_eq!(self.unread(), 0, "a visit ended with springs unread");
        let mut read = std::mem::take(&mut self.springs);
        self.read = 0;
        read.clear();
        // The larger of the thread's spare and this one stays: both are empty.
        SPARE.with(|spare| {
            let held = spare.take();
            spare.set(if held.capacity() >= read.capacity() {
                held
            } else {
                read
            });
        });
    }

    /// An empty pool with room for `count` springs and an eighth more.
    fn with_room(count: usize) -> Self {
        Self {
            springs: Vec::with_capacity(room_for(count)),
            ..Self::default()
        }
    }

    /// Adds `value` after the last pass's springs, outside a pass.
    ///
    /// # Panics
    /// If its slot is not after theirs (the springs must stay in slot order).
    fn push(&mut self, value: HeldSpring) {
        debug_assert!(self.next.is_empty(), "a spring pushed during a pass");
        if let Some(last) = self.springs.last() {
            assert!(
                last.slot < value.slot,
                "spring of slot {} added after one of a later slot",
                value.slot
            );
        }
        self.springs.push(value);
    }

    /// Ends a pass: the springs it wrote are the ones the next pass reads; those it left unread
    /// are dropped.
    fn finish_pass(&mut self) {
        self.springs = std::mem::take(&mut self.next);
        self.read = 0;
    }
}

/// The tangential histories of one build of the neighbour list: a pool per slab (see the module
/// documentation).
#[derive(Debug, Clone, Default)]
pub struct TangentialHistories {
    /// Per slab: the springs of the contacts its owners hold, in slot order.
    pools: Vec<Pool>,
}

impl TangentialHistories {
    /// No history, for every slot of `list`.
    #[must_use]
    pub fn new(list: &NeighborList) -> Self {
        Self {
            pools: vec![Pool::default(); list.slab_count()],
        }
    }

    /// The histories of the rebuilt `list`: `value(held, turned)` for each pair `held` before the
    /// rebuild that is still in the list (`turned` when its owner changed ends), none for the
    /// rest; `origin[k]` is particle `k`'s index when the pairs were held (see
    /// [`NeighborList::carry`]). Each slab's pool is filled in parallel, in slot order.
    #[must_use]
    pub fn carry<T: Sync>(
        list: &NeighborList,
        origin: &[u32],
        held: &HeldPairs<T>,
        value: impl Fn(&T, bool) -> TangentialSpring + Sync,
    ) -> Self {
        let mut histories = Self::new(list);
        if held.is_empty() {
            return histories;
        }
        let partners = list.partners();
        // Per slab: the slots that carry a history and their held entries (12 bytes each, not
        // the 40 of a copied spring: this is the rebuild's peak), found in parallel; then each
        // pool is allocated at its exact size and filled in slot order.
        let found: Vec<Vec<(u32, u32, bool)>> = (0..list.slab_count())
            .into_par_iter()
            .map(|s| {
                let mut slots = Vec::new();
                for &k in list.slab_members(s) {
                    let k = k as usize;
                    for p in list.slots(k) {
                        let partner = origin[partners[p] as usize];
                        if let Some((e, turned)) = held.position(origin[k], partner) {
                            let e = u32::try_from(e).expect("fewer than 2^32 held pairs");
                            slots.push((p as u32, e, turned));
                        }
                    }
                }
                slots.shrink_to_fit();
                slots
            })
            .collect();
        for (pool, slots) in histories.pools.iter_mut().zip(found) {
            *pool = Pool::with_room(slots.len());
            for (slot, e, turned) in slots {
                let spring = value(held.value(e as usize), turned);
                if spring != TangentialSpring::default() {
                    pool.push(HeldSpring { spring, slot });
                }
            }
        }
        histories
    }

    /// Slot `p`'s history (owner `owner`); zero when it has none, or when the scene has no
    /// rotation (an empty store).
    #[must_use]
    pub fn get(&self, list: &NeighborList, p: usize, owner: usize) -> TangentialSpring {
        self.pools
            .get(list.slab_of(owner))
            .and_then(|pool| {
                let e = pool.find(u32::try_from(p).ok()?).ok()?;
                Some(pool.springs[e].spring)
            })
            .unwrap_or_default()
    }

    /// Sets slot `p`'s history (owner `owner`), outside the pair pass. Slots that had no history
    /// must be given theirs in slot order within each slab (as [`NeighborList::pairs`] lists
    /// them): the pass meets each pool's springs in slot order.
    ///
    /// # Panics
    /// If `p` had no history and a later slot of its slab has one.
    pub fn set(&mut self, list: &NeighborList, p: usize, owner: usize, value: TangentialSpring) {
        let pool = &mut self.pools[list.slab_of(owner)];
        let slot = u32::try_from(p).expect("fewer than 2^32 slots");
        match pool.find(slot) {
            Ok(e) => pool.springs[e].spring = value,
            Err(_) => pool.push(HeldSpring {
                spring: value,
                slot,
            }),
        }
    }

    /// Energy stored in all pair springs \[J\] (M.63).
    #[must_use]
    pub fn spring_energy(&self) -> f64 {
        self.pools
            .iter()
            .flat_map(Pool::springs)
            .map(|held| held.spring.spring_energy)
            .sum()
    }

    /// Number of pairs with a spring.
    #[must_use]
    pub fn entries(&self) -> usize {
        self.pools.iter().map(Pool::unread).sum()
    }

    /// Number of pairs whose spring is stretched (ξ ≠ 0).
    #[must_use]
    pub fn stretched(&self) -> usize {
        self.pools
            .iter()
            .flat_map(Pool::springs)
            .filter(|held| held.spring.history != glam::DVec3::ZERO)
            .count()
    }

    /// Shared access for one pair pass, which must visit every owner once; call
    /// [`Self::finish_pass`] after it.
    #[must_use]
    pub fn start_pass(&mut self) -> HistoryTargets<'_> {
        HistoryTargets {
            pools: Scatter::new(&mut self.pools),
        }
    }

    /// Makes the springs the pass wrote the ones the next pass reads.
    ///
    /// # Panics
    /// In debug builds, if a slab's pool is still out of the histories (a walk that unwound).
    pub fn finish_pass(&mut self) {
        for pool in &mut self.pools {
            #[cfg(debug_assertions)]
            assert!(!pool.taken, "a slab's springs left out of the histories");
            pool.finish_pass();
        }
    }
}

/// The histories as the pair pass reaches them, within each visit's window.
#[derive(Debug)]
pub struct HistoryTargets<'a> {
    pools: Scatter<'a, Pool, PerSlab>,
}

impl HistoryTargets<'_> {
    /// The histories for the tokens of `visit` alone ([`Scatter::open`]).
    #[inline]
    #[must_use]
    pub fn open<'s, 'v>(&'s self, visit: &SlabVisit<'v>) -> OpenHistories<'s, 'v> {
        OpenHistories {
            pool: self.pools.open(visit),
        }
    }
}

/// The histories as one slab visit reaches them: its slab's pool, which the visit walks as a
/// value of its own for a while ([`Self::with_own`]).
#[derive(Debug)]
pub struct OpenHistories<'s, 'v> {
    pool: Opened<'s, 'v, Pool, PerSlab>,
}

impl<'v> OpenHistories<'_, 'v> {
    /// `walk(pool)` on the visit's own slab's pool, taken out of the histories for the walk and
    /// put back when it returns: the walk reads and appends its springs through a value of its
    /// own, whose cursor the compiler keeps in hand (through the shared histories it was loaded
    /// and stored at every contact; see [`Pool`]). The histories hold an empty pool meanwhile;
    /// scoped, the pool cannot be left out of them by a visit that forgot to give it back.
    ///
    /// # Panics
    /// In debug builds, if a walk on the same slab's pool is already under way (the inner walk
    /// would find an empty pool).
    #[inline(always)]
    pub fn with_own<R>(&self, slab: OwnSlab<'v>, walk: impl FnOnce(&mut Pool) -> R) -> R {
        Self::with_own_or_empty(Some(self), slab, walk)
    }

    /// [`Self::with_own`] where the pass has histories; without them (a compiled pass without
    /// tangential springs), `walk` on an empty pool, which reads zero springs.
    #[inline(always)]
    pub fn with_own_or_empty<R>(
        histories: Option<&Self>,
        slab: OwnSlab<'v>,
        walk: impl FnOnce(&mut Pool) -> R,
    ) -> R {
        // One call of `walk` for both cases: the fill's loop is inlined once, not twice.
        let mut pool = histories.map_or_else(Pool::default, |h| {
            h.pool.update_own(slab, Pool::take_out, ())
        });
        let result = walk(&mut pool);
        if let Some(histories) = histories {
            histories.pool.update_own(slab, Pool::put_back, pool);
        }
        result
    }
}

impl Pool {
    /// The pool, leaving an empty one marked as taken in its place.
    fn take_out(&mut self, (): ()) -> Self {
        #[cfg(debug_assertions)]
        assert!(
            !self.taken,
            "a slab's springs taken while a walk holds them"
        );
        let taken = Self {
            #[cfg(debug_assertions)]
            taken: true,
            ..Self::default()
        };
        std::mem::replace(self, taken)
    }

    /// Puts `pool` back in the place it was taken from.
    fn put_back(&mut self, pool: Self) {
        #[cfg(debug_assertions)]
        assert!(self.taken, "a pool given back where none was taken");
        *self = pool;
    }

    /// Slot `p`'s spring as the last pass left it (zero if it holds none), for a touching pair
    /// met after every earlier slot of the visit: first, each spring of an earlier slot that the
    /// visit passed over (its pair came apart) goes to `released(slot, spring)`, in slot order.
    ///
    /// The visit meets its touching pairs in slot order, as the last pass met the springs it
    /// left, so it finds each contact's spring at the front of the unread ones. A spring it
    /// passes over, or does not reach by the end of the visit ([`Self::release_unmet`]),
    /// belongs to a pair that came apart, without a test of every candidate slot for a spring.
    #[inline(always)]
    pub fn read(
        &mut self,
        p: Slot<'_>,
        mut released: impl FnMut(u32, TangentialSpring),
    ) -> TangentialSpring {
        let slot = u32::try_from(p.index()).expect("slots fit in u32");
        loop {
            match self.meet(slot) {
                Met::Spring(spring) => return spring,
                Met::Nothing => return TangentialSpring::default(),
                Met::PassedOver(held) => released(held.slot, held.spring),
            }
        }
    }

    /// At the end of the visit: each spring the visit did not meet (its pair came apart) goes to
    /// `released(slot, spring)`, in slot order.
    pub fn release_unmet(&mut self, mut released: impl FnMut(u32, TangentialSpring)) {
        while let Some(held) = self.take_unmet() {
            released(held.slot, held.spring);
        }
        self.end_visit();
    }
}

/// Room made in a pass's buffer of springs for a number of contacts ([`Pool::room`]): the
/// springs written go into places reserved beforehand, counted in a register, and the buffer
/// takes them when the room is dropped.
pub struct SpringRoom<'p> {
    /// The running pass's buffer, whose length is set when the room is dropped.
    next: &'p mut Vec<HeldSpring>,
    /// The buffer's first place; places `len..end` are reserved and not yet written.
    base: *mut HeldSpring,
    /// The places written, the buffer's springs before the room included.
    len: usize,
    /// The end of the room: the buffer's length when it was made and the room's count.
    end: usize,
}

impl<'p> SpringRoom<'p> {
    /// Room for `count` springs after those of `next`, which must have the capacity for them.
    ///
    /// # Panics
    /// If `next` lacks the capacity.
    fn new(next: &'p mut Vec<HeldSpring>, count: usize) -> Self {
        assert!(
            next.capacity() - next.len() >= count,
            "room for {count} springs made in a buffer without it"
        );
        Self {
            base: next.as_mut_ptr(),
            len: next.len(),
            end: next.len() + count,
            next,
        }
    }

    /// Stores slot `p`'s spring for the next pass (a zero spring takes no place); the slots
    /// written must ascend.
    ///
    /// # Panics
    /// If the room is full: more springs written than it was made for.
    #[inline(always)]
    pub fn write(&mut self, p: Slot<'_>, value: TangentialSpring) {
        self.write_slot(u32::try_from(p.index()).expect("slots fit in u32"), value);
    }

    /// [`Self::write`] by slot number (which the tests name without a list's slot token).
    #[inline(always)]
    fn write_slot(&mut self, slot: u32, value: TangentialSpring) {
        if value != TangentialSpring::default() {
            self.append(HeldSpring {
                spring: value,
                slot,
            });
        }
    }

    /// Appends `value` for the next pass. The pass must append in ascending slot order: the
    /// next pass meets the springs in that order (checked in debug builds, which the test suite
    /// runs; the old per-slot entry numbers had made any order work).
    #[inline(always)]
    #[allow(unsafe_code)]
    fn append(&mut self, value: HeldSpring) {
        assert!(
            self.len < self.end,
            "more springs written than the room was made for"
        );
        // SAFETY: `len < end`, and `end` is within the buffer's capacity (`new`), so the place is
        // within its allocation; the buffer is borrowed by the room, so nothing else moves or
        // reads it meanwhile.
        unsafe {
            debug_assert!(
                self.len == 0 || (*self.base.add(self.len - 1)).slot < value.slot,
                "spring of slot {} appended after one of a later slot",
                value.slot
            );
            self.base.add(self.len).write(value);
        }
        self.len += 1;
    }
}

impl Drop for SpringRoom<'_> {
    #[inline(always)]
    #[allow(unsafe_code)]
    fn drop(&mut self) {
        // SAFETY: the places below `len` were initialised: those before the room by the buffer,
        // the others by `append`; `len <= end`, within the capacity (`new`, `append`).
        unsafe { self.next.set_len(self.len) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn spring(x: f64) -> TangentialSpring {
        TangentialSpring {
            history: DVec3::new(x, 0.0, 0.0),
            spring_energy: x.abs(),
        }
    }

    #[test]
    fn only_held_springs_take_entries_and_they_turn_with_their_owner() {
        // A row of four spheres 1.9 apart (radius 1, skin 0.5): three touching pairs.
        let mut positions: Vec<DVec3> = (0..4).map(|i| DVec3::X * (1.9 * f64::from(i))).collect();
        let radii = vec![1.0; 4];
        let mut ids: Vec<u64> = vec![10, 11, 12, 13];
        let mut list = NeighborList::new(0.5, None);
        list.build(&positions, &radii);
        assert_eq!(list.pair_count(), 3);
        let mut histories = TangentialHistories::new(&list);
        assert_eq!(histories.entries(), 0);
        // Springs on two pairs, oriented owner → partner: +lower id when the owner is the lower.
        let pairs: Vec<_> = list.pairs().collect();
        for &(p, owner, partner) in &pairs[..2] {
            let sign = if ids[owner] < ids[partner] { 1.0 } else { -1.0 };
            histories.set(
                &list,
                p,
                owner,
                spring(sign * ids[owner.min(partner)] as f64),
            );
        }
        assert_eq!(histories.entries(), 2);
        assert_eq!(histories.spring_energy(), 10.0 + 11.0);
        let held = list.held_pairs(|p, owner| {
            let t = histories.get(&list, p, owner);
            (t != TangentialSpring::default()).then_some(t)
        });
        // Reverse the storage order (a reorder with `order` [3, 2, 1, 0]): every owner changes
        // ends.
        let origin: Vec<u32> = (0..4).rev().collect();
        positions.reverse();
        ids.reverse();
        list.build(&positions, &radii);
        let carried =
            TangentialHistories::carry(
                &list,
                &origin,
                &held,
                |t, turned| {
                    if turned { t.turned() } else { *t }
                },
            );
        assert_eq!(carried.entries(), 2, "the empty third pair takes no entry");
        for (p, owner, partner) in list.pairs() {
            let lower = ids[owner].min(ids[partner]);
            let t = carried.get(&list, p, owner);
            if lower == 12 {
                assert_eq!(t, TangentialSpring::default());
            } else {
                let sign = if ids[owner] < ids[partner] { 1.0 } else { -1.0 };
                assert_eq!(t, spring(sign * lower as f64), "pair from id {lower}");
            }
        }
    }

    /// The spring the pool holds for `slot` from the last pass, as its `history.x`.
    fn stored(pool: &Pool, slot: usize) -> Option<f64> {
        let e = pool.find(u32::try_from(slot).unwrap()).ok()?;
        Some(pool.springs[e].spring.history.x)
    }

    /// Meets `slot` as the pair pass does for a touching pair, collecting the springs passed
    /// over on the way.
    fn meet(pool: &mut Pool, slot: usize, passed_over: &mut Vec<(u32, f64)>) -> Option<f64> {
        loop {
            match pool.meet(u32::try_from(slot).unwrap()) {
                Met::Spring(spring) => return Some(spring.history.x),
                Met::Nothing => return None,
                Met::PassedOver(held) => passed_over.push((held.slot, held.spring.history.x)),
            }
        }
    }

    /// One pass over a slab of `model.len()` slots, as the pair pass makes it: it meets the
    /// slots of the touching pairs in order, reads the spring a slot holds, and writes one more;
    /// a pair that comes apart is not met, and its spring must come back as released, in slot
    /// order, from the meetings after it or at the end of the visit, which then hands its read
    /// buffer to the thread ([`Pool::end_visit`]). `model` holds what every slot should hold.
    fn pool_pass(pool: &mut Pool, model: &mut [Option<f64>], mut choose: impl FnMut() -> u32) {
        let mut passed_over = Vec::new();
        let mut came_apart = Vec::new();
        for (slot, modelled) in model.iter_mut().enumerate() {
            let roll = choose();
            let next = match *modelled {
                // A new contact (or none).
                None => (roll < 30).then(|| {
                    assert_eq!(meet(pool, slot, &mut passed_over), None, "slot {slot}");
                    slot as f64
                }),
                // The pair came apart: the pass does not meet it.
                Some(expected) if roll < 10 => {
                    came_apart.push((u32::try_from(slot).unwrap(), expected));
                    None
                }
                Some(expected) => {
                    let before = meet(pool, slot, &mut passed_over);
                    assert_eq!(before, Some(expected), "slot {slot}");
                    Some(expected + 1.0)
                }
            };
            if let Some(x) = next {
                pool.append(HeldSpring {
                    spring: spring(x),
                    slot: u32::try_from(slot).unwrap(),
                });
            }
            *modelled = next;
        }
        while let Some(held) = pool.take_unmet() {
            passed_over.push((held.slot, held.spring.history.x));
        }
        assert_eq!(
            passed_over, came_apart,
            "the released springs, in slot order"
        );
        pool.end_visit();
        pool.finish_pass();
    }

    #[test]
    fn a_pool_keeps_every_unread_spring_through_births_deaths_and_growth() {
        let mut pool = Pool::default();
        let mut model = vec![None; 500];
        // A fixed pseudo-random sequence (a 64-bit LCG), so the test is the same at every run.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut roll = |bias: u32| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) as u32 % 100).saturating_sub(bias)
        };
        let spare_capacity = || {
            let spare = SPARE.take();
            let capacity = spare.capacity();
            SPARE.set(spare);
            capacity
        };
        let mut largest_pass = 0;
        for pass in 0..40 {
            // Every eighth pass is a burst: most slots without a spring start one (the buffer
            // the pass writes must grow in the middle of the pass, with unread springs left).
            let bias = if pass % 8 == 3 { 60 } else { 0 };
            let held = pool.unread();
            pool_pass(&mut pool, &mut model, || roll(bias));
            largest_pass = largest_pass.max(held + pool.unread());
            for (slot, &expected) in model.iter().enumerate() {
                assert_eq!(stored(&pool, slot), expected, "pass {pass}, slot {slot}");
            }
            assert_eq!(pool.unread(), model.iter().flatten().count());
            // Between visits a pool holds one buffer, grown by the rule: every spring of one
            // pass's reads and writes, and an eighth more.
            assert_eq!(pool.next.capacity(), 0, "pass {pass}");
            for capacity in [pool.springs.capacity(), spare_capacity()] {
                assert!(
                    capacity <= largest_pass + largest_pass / 8 + 16,
                    "pass {pass}"
                );
            }
        }
        // A steady contact set (no births, no deaths) allocates nothing: each pass writes into
        // the buffer the last one read, and the two take turns.
        pool_pass(&mut pool, &mut model, || 50);
        let turns = [pool.springs.capacity(), spare_capacity()];
        for pass in 0..20 {
            pool_pass(&mut pool, &mut model, || 50);
            let (kept, spare) = (pool.springs.capacity(), spare_capacity());
            assert!(
                [kept, spare] == turns || [spare, kept] == turns,
                "steady pass {pass}: {kept} and {spare} places, {turns:?} before"
            );
        }
        assert!(
            pool.unread() > 100,
            "the test must hold many springs: {}",
            pool.unread()
        );
        assert!(
            pool.springs.capacity() < 2 * pool.unread(),
            "one pass's springs, not two: {} places for {} springs",
            pool.springs.capacity(),
            pool.unread()
        );
    }

    #[test]
    fn a_pass_given_a_small_spare_grows_its_buffer_once() {
        // A slab of 1000 springs visited by a thread whose spare came from a slab of a few:
        // the pass's first append takes the spare, fills it, and must then make room for every
        // spring it may still write (a spring per unread one), not an eighth at a time.
        let springs = 1000_u32;
        let mut pool = Pool::with_room(springs as usize);
        for slot in 0..springs {
            pool.push(HeldSpring {
                spring: spring(f64::from(slot)),
                slot,
            });
        }
        SPARE.set(Vec::with_capacity(4));
        let mut capacities = Vec::new();
        for slot in 0..springs {
            assert!(matches!(pool.meet(slot), Met::Spring(_)), "slot {slot}");
            pool.append(HeldSpring {
                spring: spring(f64::from(slot) + 1.0),
                slot,
            });
            if capacities.last() != Some(&pool.next.capacity()) {
                capacities.push(pool.next.capacity());
            }
        }
        // The spare's 4 places, then one growth to the 1000 springs and the rule's slack (an
        // eighth more and 16). Growing by an eighth of the springs at a time, the sixty-sixth
        // round's code took 4, 145, 304, 483, 684, 910 and 1164 places.
        assert_eq!(capacities.len(), 2, "capacities taken: {capacities:?}");
        assert!(capacities[0] >= 4, "{capacities:?}");
        assert!(
            (1000..=1000 + 1000 / 8 + 16).contains(&capacities[1]),
            "{capacities:?}"
        );
        pool.end_visit();
        pool.finish_pass();
        assert_eq!(pool.unread(), springs as usize);
    }

    #[test]
    fn a_room_keeps_the_springs_written_into_it_and_no_zero_spring() {
        let mut pool = Pool::default();
        {
            let mut room = pool.room(3);
            for (slot, x) in [(2, 1.0), (5, 0.0), (9, 3.0)] {
                room.write_slot(slot, spring(x));
            }
        }
        let held: Vec<_> = pool
            .next
            .iter()
            .map(|h| (h.slot, h.spring.history.x))
            .collect();
        assert_eq!(held, [(2, 1.0), (9, 3.0)]);
        // The next room starts after them.
        pool.room(1).write_slot(12, spring(4.0));
        assert_eq!(pool.next.len(), 3);
        assert_eq!(pool.next[2].slot, 12);
    }

    #[test]
    #[should_panic(expected = "more springs written than the room was made for")]
    fn a_room_refuses_more_springs_than_it_was_made_for() {
        // The buffer has capacity to spare (an eighth more and 16): the room's count, not the
        // capacity, bounds what is written.
        let mut pool = Pool::default();
        let mut room = pool.room(2);
        for slot in 0..3 {
            room.write_slot(slot, spring(1.0));
        }
    }

    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "appended after one of a later slot")]
    fn a_pass_refuses_a_spring_appended_out_of_slot_order() {
        let mut pool = Pool::default();
        for slot in [2, 7, 4] {
            pool.append(HeldSpring {
                spring: spring(f64::from(slot)),
                slot,
            });
        }
    }

    #[test]
    #[should_panic(expected = "added after one of a later slot")]
    fn a_pool_refuses_a_spring_pushed_out_of_slot_order() {
        let mut pool = Pool::with_room(4);
        for slot in [1, 5, 3] {
            pool.push(HeldSpring {
                spring: spring(f64::from(slot)),
                slot,
            });
        }
    }

    /// A walk nested in another on the same slab would find the empty stand-in and lose the
    /// springs the outer walk holds: debug builds refuse it.
    #[cfg(debug_assertions)]
    #[test]
    #[should_panic(expected = "a slab's springs taken while a walk holds them")]
    fn a_walk_nested_in_another_on_the_same_slab_panics_in_debug_builds() {
        let positions: Vec<DVec3> = (0..3).map(|i| DVec3::X * (1.9 * f64::from(i))).collect();
        let mut list = NeighborList::new(0.5, None);
        list.build(&positions, &[1.0; 3]);
        let mut histories = TangentialHistories::new(&list);
        let targets = histories.start_pass();
        list.for_each_slab(
            false,
            (),
            |(), visit| {
                let targets = targets.open(visit);
                targets.with_own(visit.own_slab(), |_| {
                    targets.with_own(visit.own_slab(), |_| ());
                });
            },
            |(), ()| (),
        );
    }

    #[test]
    fn a_pass_reads_the_last_pass_springs_and_releases_those_it_does_not_meet() {
        // A row of five spheres: four touching pairs, over at least two slabs.
        let positions: Vec<DVec3> = (0..5).map(|i| DVec3::X * (1.9 * f64::from(i))).collect();
        let mut list = NeighborList::new(0.5, None);
        list.build(&positions, &[1.0; 5]);
        let mut histories = TangentialHistories::new(&list);
        // Each pass adds 1 to every spring, except that the pair of slot 0 ends at pass 3 (the
        // pass no longer meets it) and that of the last slot at pass 4.
        let last = list.pair_count() - 1;
        for pass in 1..=4 {
            let released = std::sync::Mutex::new(Vec::new());
            let targets = histories.start_pass();
            list.for_each_slab(
                false,
                (),
                |(), visit| {
                    let targets = targets.open(visit);
                    let mut note = |slot: u32, spring: TangentialSpring| {
                        let (owner, partner) = visit.pair_of_slot(slot);
                        released.lock().unwrap().push((
                            slot,
                            owner.index(),
                            partner.index(),
                            spring,
                        ));
                    };
                    targets.with_own(visit.own_slab(), |springs| {
                        for window in visit.windows() {
                            for (p, _) in window.pairs() {
                                let apart = (p.index() == 0 && pass >= 3)
                                    || (p.index() == last && pass >= 4);
                                if !apart {
                                    let before = springs.read(p, &mut note);
                                    let after = spring(before.history.x + 1.0);
                                    springs.room(1).write(p, after);
                                }
                            }
                        }
                        springs.release_unmet(&mut note);
                    });
                },
                |(), ()| (),
            );
            histories.finish_pass();
            let released = released.into_inner().unwrap();
            let pair = |slot: usize| list.pairs().find(|&(p, ..)| p == slot).unwrap();
            let expected: Vec<_> = match pass {
                // Slot 0 is passed over when the pass meets slot 1.
                3 => vec![(0, pair(0).1, pair(0).2, spring(2.0))],
                // The last slot is not met at all: released at the end of its slab's visit.
                4 => vec![(
                    u32::try_from(last).unwrap(),
                    pair(last).1,
                    pair(last).2,
                    spring(3.0),
                )],
                _ => vec![],
            };
            assert_eq!(released, expected, "pass {pass}");
        }
        assert_eq!(histories.entries(), 2);
        for (p, owner, _) in list.pairs() {
            let expected = match p {
                0 => 0.0,
                p if p == last => 0.0,
                _ => 4.0,
            };
            assert_eq!(histories.get(&list, p, owner), spring(expected), "slot {p}");
        }
        assert_eq!(histories.spring_energy(), 8.0);
    }
}
