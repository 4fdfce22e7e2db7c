//! The tangential springs of the pairs in contact, stored beside the neighbour list.
//!
//! A Verlet list holds every pair closer than the cut-off plus the skin: on the LIGGGHTS bed
//! about 4.8 slots per particle, of which about one touches. Only touching pairs have a
//! tangential spring, so a 32-byte history per slot would mostly hold zeros. Instead each slot
//! has a 4-byte entry number ([`NO_ENTRY`] when it is not in contact), and the histories live in
//! one pool per slab of the list. A contact that forms during the pair pass takes an entry from
//! its owner's slab's pool (a released one first) and gives it back when it ends: one task visits
//! a slab's owners at a time, in a fixed order, so the pool needs no synchronisation and the
//! entry numbers do not depend on the thread count. A pool grows by an eighth when full, not
//! twice its size: it holds the slab's simultaneous contacts, which change slowly. At a rebuild
//! the non-zero histories are carried over by id key into pools of exactly their size.

use rayon::prelude::*;

use crate::neighbor::{HeldPairs, NeighborList};
use crate::scatter::{PerSlab, PerSlot, Scatter, Window};
use glam::DVec3;

/// A slot without a history entry.
pub const NO_ENTRY: u32 = u32::MAX;

/// The tangential spring of one pair in contact.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairTangential {
    /// Tangential displacement ξ [m] of the owner relative to the partner, world frame, turned
    /// into the current tangent plane at each use (M.58). It changes sign when the pair's owner
    /// changes ends at a rebuild.
    pub history: DVec3,
    /// Spring energy `½ k_t |ξ|²` at the last evaluation [J] (M.63).
    pub spring_energy: f64,
}

impl PairTangential {
    /// The same spring seen from the other particle.
    #[must_use]
    pub fn turned(self) -> Self {
        Self {
            history: -self.history,
            ..self
        }
    }
}

/// The histories of one slab's contacts.
#[derive(Debug, Clone, Default)]
pub struct Pool {
    springs: Vec<PairTangential>,
    /// Released entries, reused first (the last released first).
    free: Vec<u32>,
}

impl Pool {
    /// Takes an entry for `value`.
    #[inline]
    fn take(&mut self, value: PairTangential) -> u32 {
        if let Some(e) = self.free.pop() {
            self.springs[e as usize] = value;
            return e;
        }
        if self.springs.len() == self.springs.capacity() {
            self.springs.reserve_exact(self.springs.len() / 8 + 16);
        }
        self.springs.push(value);
        u32::try_from(self.springs.len() - 1).expect("fewer than 2^32 contacts in a slab")
    }

    /// Gives entry `e` back and returns what it held.
    #[inline]
    fn release(&mut self, e: u32) -> PairTangential {
        if self.free.len() == self.free.capacity() {
            self.free.reserve_exact(self.free.len() / 8 + 16);
        }
        self.free.push(e);
        std::mem::take(&mut self.springs[e as usize])
    }

    fn in_use(&self) -> usize {
        self.springs.len() - self.free.len()
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
        value: impl Fn(&T, bool) -> PairTangential + Sync,
    ) -> Self {
        let mut histories = Self::new(list);
        if held.is_empty() {
            return histories;
        }
        let partners = list.partners();
        // Per slab: the slots that carry a history, found in parallel; then each pool is
        // allocated at its exact size.
        let found: Vec<Vec<(u32, PairTangential)>> = (0..list.slab_count())
            .into_par_iter()
            .map(|s| {
                let mut slots = Vec::new();
                for &k in list.slab_members(s) {
                    let k = k as usize;
                    for p in list.slots(k) {
                        let partner = ids[partners[p] as usize];
                        if let Some((v, turned)) = held.find(ids[k], partner) {
                            let spring = value(v, turned);
                            if spring != PairTangential::default() {
                                slots.push((p as u32, spring));
                            }
                        }
                    }
                }
                slots
            })
            .collect();
        for (pool, slots) in histories.pools.iter_mut().zip(found) {
            pool.springs.reserve_exact(slots.len());
            for (p, spring) in slots {
                histories.entry[p as usize] = pool.take(spring);
            }
        }
        histories
    }

    /// Slot `p`'s history (owner `owner`); zero when it has none, or when the scene has no
    /// rotation (an empty store).
    #[must_use]
    pub fn get(&self, list: &NeighborList, p: usize, owner: usize) -> PairTangential {
        match self.entry.get(p) {
            None | Some(&NO_ENTRY) => PairTangential::default(),
            Some(&e) => self.pools[list.slab_of(owner)].springs[e as usize],
        }
    }

    /// Sets slot `p`'s history (owner `owner`), outside the pair pass.
    pub fn set(&mut self, list: &NeighborList, p: usize, owner: usize, value: PairTangential) {
        let pool = &mut self.pools[list.slab_of(owner)];
        match self.entry[p] {
            NO_ENTRY => self.entry[p] = pool.take(value),
            e => pool.springs[e as usize] = value,
        }
    }

    /// Forgets every history (a run starts with no tangential displacement).
    pub fn clear(&mut self) {
        self.entry.fill(NO_ENTRY);
        for pool in &mut self.pools {
            *pool = Pool::default();
        }
    }

    /// Energy stored in all pair springs [J] (M.63).
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
        self.pools.iter().map(Pool::in_use).sum()
    }

    /// Shared access for the pair pass.
    #[must_use]
    pub fn targets(&mut self) -> HistoryTargets<'_> {
        HistoryTargets {
            entry: Scatter::new(&mut self.entry),
            pools: Scatter::new(&mut self.pools),
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
    /// Asks the memory system for the histories of the window's slots, ahead of their use (a
    /// pool's entries are sparse in the pass's path, and the hardware prefetchers miss them).
    #[inline]
    pub fn prefetch(&self, window: &Window<'_>) {
        self.pools.update_own(window, |pool| {
            for p in window.slots() {
                let e = self.entry.read(window, p);
                if let Some(spring) = pool.springs.get(e as usize) {
                    crate::scatter::prefetch(spring);
                }
            }
        });
    }

    /// Slot `p`'s entry number and history (zero without an entry).
    #[inline]
    #[must_use]
    pub fn read(&self, window: &Window<'_>, p: usize) -> (u32, PairTangential) {
        match self.entry.read(window, p) {
            NO_ENTRY => (NO_ENTRY, PairTangential::default()),
            e => (
                e,
                self.pools
                    .update_own(window, |pool| pool.springs[e as usize]),
            ),
        }
    }

    /// Stores slot `p`'s history; `entry` is what [`Self::read`] gave. A zero history is not
    /// given an entry.
    #[inline]
    pub fn write(&self, window: &Window<'_>, p: usize, entry: u32, value: PairTangential) {
        if entry != NO_ENTRY {
            self.pools
                .update_own(window, |pool| pool.springs[entry as usize] = value);
        } else if value != PairTangential::default() {
            let e = self.pools.update_own(window, |pool| pool.take(value));
            self.entry.update(window, p, |slot| *slot = e);
        }
    }

    /// The contact of slot `p` ended: returns what its spring held and gives its entry back.
    #[inline]
    pub fn release(&self, window: &Window<'_>, p: usize) -> PairTangential {
        match self.entry.read(window, p) {
            NO_ENTRY => PairTangential::default(),
            e => {
                self.entry.update(window, p, |slot| *slot = NO_ENTRY);
                self.pools.update_own(window, |pool| pool.release(e))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spring(x: f64) -> PairTangential {
        PairTangential {
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
            (t != PairTangential::default()).then_some(t)
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
                assert_eq!(t, PairTangential::default());
            } else {
                let sign = if ids[owner] < ids[partner] { 1.0 } else { -1.0 };
                assert_eq!(t, spring(sign * lower as f64), "pair from id {lower}");
            }
        }
    }
}
