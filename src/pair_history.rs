//! The tangential springs of the pairs in contact, stored beside the neighbour list.
//!
//! A Verlet list holds every pair closer than the cut-off plus the skin: on the LIGGGHTS bed
//! about 4.8 slots per particle, of which about one touches. Only touching pairs have a
//! tangential spring, so a 32-byte history per slot would mostly hold zeros. Instead each slot
//! has a 4-byte entry number ([`NO_ENTRY`] when it is not in contact), and the springs live in
//! one pool per slab of the list, in the order the pair pass meets them. Each pool has two
//! buffers: the pass reads a contact's spring from the last pass's buffer and appends its new
//! spring to the other, then the two swap. The reads therefore walk each buffer forwards, as the
//! hardware prefetchers like (a pool with reused entries was measured 15-18 % slower on the 20k
//! bed), and new contacts need no free list. One task visits a slab's owners at a time, in a
//! fixed order, so the pools need no locks and the entry numbers do not depend on the thread
//! count. A rebuild carries the non-zero springs over by id key.

use rayon::prelude::*;

use crate::contact::tangential::TangentialSpring;
use crate::neighbor::{HeldPairs, NeighborList};
use crate::scatter::{OwnSlab, PerSlab, PerSlot, Scatter, Slot};

/// A slot without a history entry.
pub const NO_ENTRY: u32 = u32::MAX;

/// The springs of one slab's contacts: those the last pass left (`springs`, read by the next
/// pass) and those the running pass writes (`next`).
#[derive(Debug, Clone, Default)]
pub struct Pool {
    springs: Vec<TangentialSpring>,
    next: Vec<TangentialSpring>,
}

impl Pool {
    /// Appends `value` to `buffer` and returns its entry number. A full buffer grows by an
    /// eighth, not twice its size: it holds the slab's contacts, whose number changes slowly.
    #[inline]
    fn append(buffer: &mut Vec<TangentialSpring>, value: TangentialSpring) -> u32 {
        if buffer.len() == buffer.capacity() {
            Self::grow(buffer);
        }
        buffer.push(value);
        u32::try_from(buffer.len() - 1).expect("fewer than 2^32 contacts in a slab")
    }

    /// Out of line and cold: it runs a few times per build, while the pair pass appends once per
    /// contact and step, and it kept the append (and the pass's write) from being inlined.
    #[cold]
    #[inline(never)]
    fn grow(buffer: &mut Vec<TangentialSpring>) {
        buffer.reserve_exact(buffer.len() / 8 + 16);
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
    /// rest. Each slab's pool is filled in parallel, in the order its owners are visited.
    #[must_use]
    pub fn carry<T: Sync>(
        list: &NeighborList,
        ids: &[u64],
        held: &HeldPairs<T>,
        value: impl Fn(&T, bool) -> TangentialSpring + Sync,
    ) -> Self {
        let mut histories = Self::new(list);
        if held.is_empty() {
            return histories;
        }
        let partners = list.partners();
        // Per slab: the slots that carry a history and their held entries (8 bytes each, not
        // the 40 of a copied spring: this is the rebuild's peak), found in parallel; then each
        // pool is allocated at its exact size and filled in slot order.
        let found: Vec<Vec<(u32, u32, bool)>> = (0..list.slab_count())
            .into_par_iter()
            .map(|s| {
                let mut slots = Vec::new();
                for &k in list.slab_members(s) {
                    let k = k as usize;
                    for p in list.slots(k) {
                        let partner = ids[partners[p] as usize];
                        if let Some((e, turned)) = held.position(ids[k], partner) {
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
            pool.springs.reserve_exact(slots.len());
            for (p, e, turned) in slots {
                let spring = value(held.value(e as usize), turned);
                if spring != TangentialSpring::default() {
                    histories.entry[p as usize] = Pool::append(&mut pool.springs, spring);
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
            Some(&e) => self.pools[list.slab_of(owner)].springs[e as usize],
        }
    }

    /// Sets slot `p`'s history (owner `owner`), outside the pair pass.
    pub fn set(&mut self, list: &NeighborList, p: usize, owner: usize, value: TangentialSpring) {
        let pool = &mut self.pools[list.slab_of(owner)];
        match self.entry[p] {
            NO_ENTRY => self.entry[p] = Pool::append(&mut pool.springs, value),
            e => pool.springs[e as usize] = value,
        }
    }

    /// Frees the write buffers (scratch between passes; the next pass allocates them again).
    pub fn drop_spare_buffers(&mut self) {
        for pool in &mut self.pools {
            pool.next = Vec::new();
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
            .flat_map(|pool| &pool.springs)
            .map(|t| t.spring_energy)
            .sum()
    }

    /// Number of entries in use (pairs with a spring).
    #[must_use]
    pub fn entries(&self) -> usize {
        self.pools.iter().map(|pool| pool.springs.len()).sum()
    }

    /// Shared access for one pair pass, which must visit every owner once; call
    /// [`Self::finish_pass`] after it.
    #[must_use]
    pub fn start_pass(&mut self) -> HistoryTargets<'_> {
        for pool in &mut self.pools {
            pool.next.clear();
        }
        HistoryTargets {
            entry: Scatter::new(&mut self.entry),
            pools: Scatter::new(&mut self.pools),
        }
    }

    /// Makes the springs the pass wrote the ones the next pass reads.
    pub fn finish_pass(&mut self) {
        for pool in &mut self.pools {
            std::mem::swap(&mut pool.springs, &mut pool.next);
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
    /// Slot `p`'s spring as the last pass left it (zero without an entry).
    #[inline]
    #[must_use]
    pub fn read(&self, slab: OwnSlab<'_>, p: Slot<'_>) -> TangentialSpring {
        match self.entry.read(p) {
            NO_ENTRY => TangentialSpring::default(),
            e => self.pools.update_own(slab, |pool| pool.springs[e as usize]),
        }
    }

    /// Stores slot `p`'s spring for the next pass (a zero spring takes no entry).
    #[inline(always)]
    pub fn write(&self, slab: OwnSlab<'_>, p: Slot<'_>, value: TangentialSpring) {
        let e = if value == TangentialSpring::default() {
            NO_ENTRY
        } else {
            self.pools
                .update_own(slab, |pool| Pool::append(&mut pool.next, value))
        };
        self.entry.update(p, |slot| *slot = e);
    }

    /// Whether slot `p` holds a spring (from the last pass).
    #[inline]
    #[must_use]
    pub fn holds(&self, p: Slot<'_>) -> bool {
        self.entry.read(p) != NO_ENTRY
    }

    /// The contact of slot `p` ended: returns what its spring held, and the slot keeps none.
    #[inline]
    pub fn release(&self, slab: OwnSlab<'_>, p: Slot<'_>) -> TangentialSpring {
        match self.entry.read(p) {
            NO_ENTRY => TangentialSpring::default(),
            e => {
                self.entry.update(p, |slot| *slot = NO_ENTRY);
                self.pools.update_own(slab, |pool| pool.springs[e as usize])
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
        let held = list.held_pairs(&ids, |p, owner| {
            let t = histories.get(&list, p, owner);
            (t != TangentialSpring::default()).then_some(t)
        });
        // Reverse the storage order: every owner changes ends.
        positions.reverse();
        ids.reverse();
        list.build(&positions, &radii);
        let carried =
            TangentialHistories::carry(
                &list,
                &ids,
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
            list.for_each_owner(
                false,
                (),
                |(), window| {
                    for (p, _) in window.pairs() {
                        if p.index() == 0 && pass >= 3 {
                            let released = targets.release(window.own_slab(), p);
                            assert_eq!(released, spring(if pass == 3 { 2.0 } else { 0.0 }));
                        } else {
                            let before = targets.read(window.own_slab(), p);
                            targets.write(window.own_slab(), p, spring(before.history.x + 1.0));
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
