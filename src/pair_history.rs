//! The tangential springs of the pairs in contact, stored beside the neighbour list.
//!
//! A Verlet list holds every pair closer than the cut-off plus the skin: on the LIGGGHTS bed
//! about 4.8 slots per particle, of which about one touches. Only touching pairs have a
//! tangential spring, so a 32-byte history per slot would mostly hold zeros. Instead each slot
//! has a 4-byte entry number ([`NO_ENTRY`] when it is not in contact), and the springs live in
//! one pool per slab of the list, in the order the pair pass meets them. A pool is a ring: the
//! pass reads a contact's spring where the last pass left it and appends its new spring behind
//! the last pass's springs, into the places it has already read ([`Pool`]). The reads and the
//! writes therefore walk the ring forwards, as the hardware prefetchers like (a pool with reused
//! entries was measured 15-18 % slower on the 20k bed), new contacts need no free list, and a
//! pool holds about one pass's springs (two buffers that swapped after each pass held two). One
//! task visits a slab's owners at a time, in a fixed order, so the pools need no locks and the
//! entry numbers do not depend on the thread count. A rebuild carries the non-zero springs over
//! by id key.

use rayon::prelude::*;

use crate::contact::tangential::TangentialSpring;
use crate::neighbor::{HeldPairs, NeighborList};
use crate::scatter::{Opened, OwnSlab, PerSlab, PerSlot, Scatter, SlabVisit, Slot};

/// A slot without a history entry.
pub const NO_ENTRY: u32 = u32::MAX;

/// The springs of one slab's contacts, in one ring buffer: those the last pass left (entry numbers
/// `0..held`, from ring position `base` on, wrapping), followed by those the running pass writes
/// (entry numbers `0..written` of the next pass).
///
/// The pass meets a slab's contacts in the same order at every pass, so it reads the last pass's
/// springs in ascending entry order, and a spring's place is free for a new one as soon as the
/// pass has read past it. The new springs therefore go into the places the pass has read, and a
/// pool needs room for about one pass's springs, not two: the ring is only ever short of room
/// for the contacts that formed during the pass, and then it grows (32 B per contact saved:
/// 28 B per particle on the 97.2k LIGGGHTS bed, 405 → 381 B at its peak).
#[derive(Debug, Clone, Default)]
pub struct Pool {
    /// The ring; its length is its capacity.
    ring: Vec<TangentialSpring>,
    /// Ring position of the last pass's spring 0.
    base: usize,
    /// The number of springs the last pass left.
    held: usize,
    /// The last pass's springs below this entry number were read by the running pass (which
    /// reads in ascending order), so their places may be written.
    read_mark: usize,
    /// The number of springs the running pass wrote.
    written: usize,
    /// Ring position of the running pass's next spring.
    write_position: usize,
}

impl Pool {
    /// The ring position of the last pass's spring `e` (`base + e < 2 × capacity`).
    #[inline]
    fn position(&self, e: usize) -> usize {
        let position = self.base + e;
        if position >= self.ring.len() {
            position - self.ring.len()
        } else {
            position
        }
    }

    /// The last pass's spring `e`, outside a pass.
    fn get(&self, e: usize) -> TangentialSpring {
        self.ring[self.position(e)]
    }

    /// The last pass's springs, in entry order.
    fn springs(&self) -> impl Iterator<Item = &TangentialSpring> {
        (0..self.held).map(|e| &self.ring[self.position(e)])
    }

    /// Reads the last pass's spring `e` in a pass.
    ///
    /// # Panics
    /// If `e` is not above every entry the pass read before: the pass must meet the slab's
    /// springs in the order the last pass wrote them, or a new spring could overwrite one not
    /// yet read.
    #[inline(always)]
    fn read(&mut self, e: usize) -> TangentialSpring {
        if e < self.read_mark || e >= self.held {
            self.read_out_of_order(e);
        }
        self.read_mark = e + 1;
        self.ring[self.position(e)]
    }

    /// Out of line: the panic's formatting kept [`Self::read`] from being inlined.
    #[cold]
    #[inline(never)]
    fn read_out_of_order(&self, e: usize) -> ! {
        panic!(
            "tangential spring {e} read out of order (entries below {} were read, {} held)",
            self.read_mark, self.held
        );
    }

    /// Appends `value` for the next pass and returns its entry number.
    #[inline(always)]
    fn append(&mut self, value: TangentialSpring) -> u32 {
        // Its place held the last pass's spring `held + written - capacity`, if that is ≥ 0:
        // free once read.
        if self.held + self.written >= self.read_mark + self.ring.len() {
            self.grow();
        }
        self.ring[self.write_position] = value;
        self.write_position += 1;
        if self.write_position == self.ring.len() {
            self.write_position = 0;
        }
        self.written += 1;
        u32::try_from(self.written - 1).expect("fewer than 2^32 contacts in a slab")
    }

    /// A larger ring with the unread springs of the last pass and the running pass's springs at
    /// the same entry numbers. It holds at least every spring of both (`held + written`), so that
    /// `base + e` stays below twice the capacity, and an eighth more: the number of a slab's
    /// contacts changes slowly. Out of line and cold: it runs a few times per build, while the
    /// pair pass appends once per contact and step, and it kept the append (and the pass's
    /// write) from being inlined.
    #[cold]
    #[inline(never)]
    fn grow(&mut self) {
        let live = self.held + self.written;
        let capacity = live + live / 8 + 16;
        let mut ring = vec![TangentialSpring::default(); capacity];
        // Entry `e` of the last pass goes to `e - read_mark`, the running pass's `j` after them.
        // (`%`, not `position`: the running pass's springs reach past twice the capacity.)
        let old = |seq: usize| self.ring[(self.base + seq) % self.ring.len()];
        for e in self.read_mark..self.held {
            ring[e - self.read_mark] = old(e);
        }
        let unread = self.held - self.read_mark;
        for j in 0..self.written {
            ring[unread + j] = old(self.held + j);
        }
        self.base = (capacity - self.read_mark % capacity) % capacity;
        self.write_position = unread + self.written;
        self.ring = ring;
    }

    /// An empty pool with room for `count` springs and an eighth more.
    fn with_room(count: usize) -> Self {
        Self {
            ring: vec![TangentialSpring::default(); count + count / 8 + 16],
            ..Self::default()
        }
    }

    /// Adds `value` to the last pass's springs, outside a pass, and returns its entry number.
    fn push(&mut self, value: TangentialSpring) -> u32 {
        if self.held == self.ring.len() {
            self.grow();
        }
        let position = self.position(self.held);
        self.ring[position] = value;
        self.held += 1;
        u32::try_from(self.held - 1).expect("fewer than 2^32 contacts in a slab")
    }

    /// The ring position just after the last pass's springs: where a pass writes its first.
    fn after_held(&self) -> usize {
        if self.ring.is_empty() {
            0
        } else {
            (self.base + self.held) % self.ring.len()
        }
    }

    /// Starts a pass: the springs the last pass left are all unread.
    fn start_pass(&mut self) {
        self.read_mark = 0;
        self.written = 0;
        self.write_position = self.after_held();
    }

    /// Ends a pass: the springs it wrote are the ones the next pass reads.
    fn finish_pass(&mut self) {
        self.base = self.after_held();
        self.held = self.written;
        self.read_mark = 0;
        self.written = 0;
    }
}

/// The tangential histories of one build of the neighbour list: an entry number per slot and a
/// pool per slab (see the module documentation).
#[derive(Debug, Clone, Default)]
pub struct TangentialHistories {
    /// Per slot: the index into its owner's slab's pool, or [`NO_ENTRY`].
    entry: Vec<u32>,
    /// Per slab: the histories of the contacts its owners hold.
    pools: Vec<Pool>,
}

impl TangentialHistories {
    /// No history, for every slot of `list`.
    #[must_use]
    pub fn new(list: &NeighborList) -> Self {
        Self {
            entry: vec![NO_ENTRY; list.pair_count()],
            pools: vec![Pool::default(); list.slab_count()],
        }
    }

    /// The histories of the rebuilt `list`: `value(held, turned)` for each pair `held` before the
    /// rebuild that is still in the list (`turned` when its owner changed ends), none for the
    /// rest; `origin[k]` is particle `k`'s index when the pairs were held (see
    /// [`NeighborList::carry`]). Each slab's pool is filled in parallel, in the order its owners
    /// are visited.
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
            for (p, e, turned) in slots {
                let spring = value(held.value(e as usize), turned);
                if spring != TangentialSpring::default() {
                    histories.entry[p as usize] = pool.push(spring);
                }
            }
        }
        histories
    }

    /// Slot `p`'s history (owner `owner`); zero when it has none, or when the scene has no
    /// rotation (an empty store).
    #[must_use]
    pub fn get(&self, list: &NeighborList, p: usize, owner: usize) -> TangentialSpring {
        match self.entry.get(p) {
            None | Some(&NO_ENTRY) => TangentialSpring::default(),
            Some(&e) => self.pools[list.slab_of(owner)].get(e as usize),
        }
    }

    /// Sets slot `p`'s history (owner `owner`), outside the pair pass. Slots that had no history
    /// must be given theirs in slot order within each slab (as [`NeighborList::pairs`] lists
    /// them): the pass reads each pool in the order the springs were added.
    pub fn set(&mut self, list: &NeighborList, p: usize, owner: usize, value: TangentialSpring) {
        let pool = &mut self.pools[list.slab_of(owner)];
        match self.entry[p] {
            NO_ENTRY => self.entry[p] = pool.push(value),
            e => {
                let position = pool.position(e as usize);
                pool.ring[position] = value;
            }
        }
    }

    /// Forgets every history (a run starts with no tangential displacement).
    pub fn clear(&mut self) {
        self.entry.fill(NO_ENTRY);
        for pool in &mut self.pools {
            *pool = Pool::default();
        }
    }

    /// Energy stored in all pair springs \[J\] (M.63).
    #[must_use]
    pub fn spring_energy(&self) -> f64 {
        self.pools
            .iter()
            .flat_map(Pool::springs)
            .map(|t| t.spring_energy)
            .sum()
    }

    /// Number of entries in use (pairs with a spring).
    #[must_use]
    pub fn entries(&self) -> usize {
        self.pools.iter().map(|pool| pool.held).sum()
    }

    /// Shared access for one pair pass, which must visit every owner once; call
    /// [`Self::finish_pass`] after it.
    #[must_use]
    pub fn start_pass(&mut self) -> HistoryTargets<'_> {
        for pool in &mut self.pools {
            pool.start_pass();
        }
        HistoryTargets {
            entry: Scatter::new(&mut self.entry),
            pools: Scatter::new(&mut self.pools),
        }
    }

    /// Makes the springs the pass wrote the ones the next pass reads.
    pub fn finish_pass(&mut self) {
        for pool in &mut self.pools {
            pool.finish_pass();
        }
    }
}

/// The histories as the pair pass reaches them, within each visit's window.
#[derive(Debug)]
pub struct HistoryTargets<'a> {
    entry: Scatter<'a, u32, PerSlot>,
    pools: Scatter<'a, Pool, PerSlab>,
}

impl HistoryTargets<'_> {
    /// The histories for the tokens of `visit` alone ([`Scatter::open`]).
    #[inline]
    #[must_use]
    pub fn open<'s, 'v>(&'s self, visit: &SlabVisit<'v>) -> OpenHistories<'s, 'v> {
        OpenHistories {
            entry: self.entry.open(visit),
            pool: self.pools.open(visit),
        }
    }
}

/// The histories as one slab visit reaches them: its slots' entries and its slab's pool.
#[derive(Debug)]
pub struct OpenHistories<'s, 'v> {
    entry: Opened<'s, 'v, u32, PerSlot>,
    pool: Opened<'s, 'v, Pool, PerSlab>,
}

impl<'v> OpenHistories<'_, 'v> {
    /// Slot `p`'s spring as the last pass left it (zero without an entry).
    #[inline(always)]
    #[must_use]
    pub fn read(&self, slab: OwnSlab<'v>, p: Slot<'v>) -> TangentialSpring {
        match self.entry.read(p) {
            NO_ENTRY => TangentialSpring::default(),
            e => self.pool.update_own(slab, Pool::read, e as usize),
        }
    }

    /// Stores slot `p`'s spring for the next pass (a zero spring takes no entry).
    #[inline(always)]
    pub fn write(&self, slab: OwnSlab<'v>, p: Slot<'v>, value: TangentialSpring) {
        let e = if value == TangentialSpring::default() {
            NO_ENTRY
        } else {
            self.pool.update_own(slab, Pool::append, value)
        };
        self.entry.write(p, e);
    }

    /// Whether slot `p` holds a spring (from the last pass).
    #[inline]
    #[must_use]
    pub fn holds(&self, p: Slot<'v>) -> bool {
        self.entry.read(p) != NO_ENTRY
    }

    /// The contact of slot `p` ended: returns what its spring held, and the slot keeps none.
    #[inline(always)]
    pub fn release(&self, slab: OwnSlab<'v>, p: Slot<'v>) -> TangentialSpring {
        match self.entry.read(p) {
            NO_ENTRY => TangentialSpring::default(),
            e => {
                self.entry.write(p, NO_ENTRY);
                self.pool.update_own(slab, Pool::read, e as usize)
            }
        }
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

    /// One pass over a slab of `slots.len()` slots, as the pair pass makes it: each slot in order
    /// reads its spring if it holds one, then keeps it (one more), releases it, or, holding
    /// none, may start one. `model` holds what every slot should hold.
    fn ring_pass(
        pool: &mut Pool,
        slots: &mut [u32],
        model: &mut [Option<f64>],
        mut choose: impl FnMut(usize) -> u32,
    ) {
        pool.start_pass();
        for (slot, entry) in slots.iter_mut().enumerate() {
            let roll = choose(slot);
            match (*entry, model[slot]) {
                (NO_ENTRY, None) => {
                    if roll < 30 {
                        *entry = pool.append(spring(slot as f64));
                        model[slot] = Some(slot as f64);
                    }
                }
                (e, Some(expected)) => {
                    let before = pool.read(e as usize);
                    assert_eq!(before, spring(expected), "slot {slot}");
                    if roll < 10 {
                        *entry = NO_ENTRY;
                        model[slot] = None;
                    } else {
                        *entry = pool.append(spring(expected + 1.0));
                        model[slot] = Some(expected + 1.0);
                    }
                }
                (e, None) => panic!("slot {slot} has entry {e} but no spring"),
            }
        }
        pool.finish_pass();
    }

    #[test]
    fn a_ring_pool_keeps_every_unread_spring_through_births_deaths_and_growth() {
        let mut pool = Pool::default();
        let mut slots = vec![NO_ENTRY; 500];
        let mut model = vec![None; 500];
        // A fixed pseudo-random sequence (a 64-bit LCG), so the test is the same at every run.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut roll = |bias: u32| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) as u32 % 100).saturating_sub(bias)
        };
        let mut largest_pass = 0;
        for pass in 0..40 {
            // Every eighth pass is a burst: most slots without a spring start one (the ring must
            // grow in the middle of a pass, with unread springs behind the write position).
            let bias = if pass % 8 == 3 { 60 } else { 0 };
            let held = pool.held;
            ring_pass(&mut pool, &mut slots, &mut model, |_| roll(bias));
            largest_pass = largest_pass.max(held + pool.held);
            for (slot, &entry) in slots.iter().enumerate() {
                let stored = (entry != NO_ENTRY).then(|| pool.get(entry as usize).history.x);
                assert_eq!(stored, model[slot], "pass {pass}, slot {slot}");
            }
            assert_eq!(pool.held, model.iter().flatten().count());
            // The growth rule: every spring of one pass's reads and writes, and an eighth more.
            assert!(pool.ring.len() <= largest_pass + largest_pass / 8 + 16);
        }
        // A steady contact set (no births, no deaths) never grows the ring: the pass writes each
        // spring into the place of one it has read. (Two buffers would need twice the springs.)
        let capacity = pool.ring.len();
        for pass in 0..20 {
            ring_pass(&mut pool, &mut slots, &mut model, |_| 50);
            assert_eq!(pool.ring.len(), capacity, "steady pass {pass}");
        }
        assert!(
            pool.held > 100,
            "the test must hold many springs: {}",
            pool.held
        );
        assert!(
            pool.ring.len() < 2 * pool.held,
            "one pass's springs, not two: {} places for {} springs",
            pool.ring.len(),
            pool.held
        );
    }

    #[test]
    #[should_panic(expected = "read out of order")]
    fn a_ring_pool_refuses_a_read_out_of_order() {
        let mut pool = Pool::with_room(4);
        for x in 1..=3 {
            pool.push(spring(f64::from(x)));
        }
        pool.start_pass();
        let _ = pool.read(1);
        let _ = pool.read(0);
    }

    #[test]
    fn a_pass_reads_the_last_pass_springs_and_drops_released_ones() {
        // A row of five spheres: four touching pairs, over at least two slabs.
        let positions: Vec<DVec3> = (0..5).map(|i| DVec3::X * (1.9 * f64::from(i))).collect();
        let mut list = NeighborList::new(0.5, None);
        list.build(&positions, &[1.0; 5]);
        let mut histories = TangentialHistories::new(&list);
        // Each pass adds 1 to every spring, except that the pair of slot 0 ends at pass 3.
        for pass in 1..=4 {
            let targets = histories.start_pass();
            list.for_each_slab(
                false,
                (),
                |(), visit| {
                    let targets = targets.open(visit);
                    for window in visit.windows() {
                        for (p, _) in window.pairs() {
                            if p.index() == 0 && pass >= 3 {
                                let released = targets.release(window.own_slab(), p);
                                assert_eq!(released, spring(if pass == 3 { 2.0 } else { 0.0 }));
                            } else {
                                let before = targets.read(window.own_slab(), p);
                                let after = spring(before.history.x + 1.0);
                                targets.write(window.own_slab(), p, after);
                            }
                        }
                    }
                },
                |(), ()| (),
            );
            histories.finish_pass();
        }
        assert_eq!(histories.entries(), 3);
        for (p, owner, _) in list.pairs() {
            let expected = if p == 0 { 0.0 } else { 4.0 };
            assert_eq!(histories.get(&list, p, owner), spring(expected), "slot {p}");
        }
        assert_eq!(histories.spring_energy(), 12.0);
    }
}
