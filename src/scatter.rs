//! Shared write access to per-particle and per-pair arrays for the coloured passes.
//!
//! A pair pass adds each pair's force to both of its particles (Newton's third law, one
//! evaluation per pair). Several threads do that at once, each on the slabs of one colour phase
//! of the neighbour list ([`crate::neighbor::NeighborList::for_each_owner`]). The borrow checker
//! cannot see that the particles two concurrent slabs touch are disjoint, so the arrays are
//! written through a [`Scatter`], and every access presents a token that only the visit's
//! [`Window`] hands out: a [`Member`] (the owner, or the partner of one of its slots) or a
//! [`Slot`] (one of its slots). The tokens carry the window's lifetime and, like the window,
//! stay on the visiting thread.
//!
//! Which particles a window reaches is proven once per neighbour-list build, not at every
//! write: the list checks that every partner lies in its owner's slab or in the successor slab
//! (`NeighborList::build`), and concurrent windows have disjoint slab pairs. (Checking every
//! write against the window, as the first version did, took about 10 % of the LIGGGHTS bed's
//! step: a load of the partner's slab and two compares per write, three writes per contact.)
//! With debug assertions on, as in the tests, every token is still checked against the window's
//! slabs. That guarantee is the single `unsafe` contract of the crate ([`SlabVisit::new`], and
//! within this module `Window::pair` and `Window::particle`); the passes themselves are safe
//! code.
//!
//! Bounds are proven once per visit, too. A [`Scatter`] checks the index of every access, but a
//! pass may open it for a slab visit ([`Scatter::open`]): the array's length is then checked
//! once against the visit's list (its particle or slot count), and the [`Opened`] scatter
//! takes no bounds check after. It takes that visit's tokens only: their lifetime is the
//! visit's *brand*, invariant, and the list hands each visit to a closure generic over it, so no
//! other visit's tokens (of a longer list, say) have it. The pair pass writes through opened
//! scatters; checked at every access, the bounds had cost the 19.2k LIGGGHTS bed's step 6-8 %.
//! It reads the particles' positions, radii and velocities the same way ([`OpenedReads`]).
//!
//! No access hands out a reference that a nested access could alias: a per-particle or per-slot
//! element is read and written as a value (`update(token, |value| new_value)`), and a slab's own
//! element is changed by a plain function with a `'static` argument
//! ([`Opened::update_own`]), which cannot reach the scatter again.
//!
//! A task visits a whole slab ([`SlabVisit`]), owner by owner. The tokens of its windows live as
//! long as the slab visit, not just the owner's window: a pass may collect the contacts of
//! several owners and write their results afterwards (the batched pair pass in `forces`), still
//! only through tokens the list vouched for. They cannot outlive the visit, which is what keeps
//! them from reaching a slab another thread holds in a later colour phase.
//!
//! A visit may also keep a *near list* for its slab between passes ([`NearPair`],
//! [`NearVisit`]): the slots whose pairs were within a near skin at a refresh, recorded from the
//! visit's own tokens and handed back as tokens to the next visits of the same slab of the same
//! list build. The list (`crate::neighbor::NearPairs`) vouches for that, as for the partners.

#![allow(unsafe_code)]

use std::cell::RefCell;
use std::marker::PhantomData;
use std::ops::Range;

/// Marker: an array indexed by particle.
#[derive(Debug)]
pub enum PerParticle {}
/// Marker: an array indexed by pair slot of the neighbour list.
#[derive(Debug)]
pub enum PerSlot {}
/// Marker: an array indexed by slab of the neighbour list; a pair visit may touch its owner's
/// slab's element only.
#[derive(Debug)]
pub enum PerSlab {}

/// Makes a type neither `Send` nor `Sync`: windows and their tokens stay on the thread of the
/// visit, so a visit cannot hand one particle to two threads.
type ThreadBound = PhantomData<*const ()>;

/// Makes a type invariant in `'v`: the lifetime of a visit's tokens is then its *brand*. The
/// list hands each visit to a closure generic over that lifetime (`for<'v> Fn(&SlabVisit<'v>)`),
/// in which no other visit's tokens have it, and a lifetime that cannot shrink or grow cannot be
/// made to match another. A scatter opened for a visit ([`Scatter::open`]) takes that visit's
/// tokens only, whose indices its one check of the lengths covers.
type Brand<'v> = PhantomData<fn(&'v ()) -> &'v ()>;

/// What one visit may access: its owner, the partners of its slots, and those slots.
#[derive(Debug)]
pub struct Window<'a> {
    owner: usize,
    slots: Range<usize>,
    /// The partner of each slot, `partners[p − slots.start]`.
    partners: &'a [u32],
    /// Each particle's slab and the two slabs of the visit: what the debug checks of the tokens
    /// compare with (empty for a one-particle window).
    slab_of: &'a [u32],
    slabs: [u32; 2],
    /// See [`Window::needs_minimum_image`].
    crossing: bool,
    brand: Brand<'a>,
    thread: ThreadBound,
}

/// A particle the visit may read and write: its owner, or the partner of one of its slots.
#[derive(Debug, Clone, Copy)]
pub struct Member<'w> {
    /// (Particle counts fit in `u32`, as the list's partners do: a kept contact is smaller.)
    index: u32,
    window: Brand<'w>,
    thread: ThreadBound,
}

impl Member<'_> {
    /// The particle's index.
    #[must_use]
    #[inline]
    pub fn index(self) -> usize {
        self.index as usize
    }
}

/// One of the visit's pair slots.
#[derive(Debug, Clone, Copy)]
pub struct Slot<'w> {
    /// (Slot counts fit in `u32`, as the list's offsets do.)
    index: u32,
    window: Brand<'w>,
    thread: ThreadBound,
}

impl Slot<'_> {
    /// The slot's index in the neighbour list.
    #[must_use]
    #[inline]
    pub fn index(self) -> usize {
        self.index as usize
    }
}

/// The slab a visit owns: its pool of per-slab data ([`PerSlab`]).
#[derive(Debug, Clone, Copy)]
pub struct OwnSlab<'w> {
    index: u32,
    window: Brand<'w>,
    thread: ThreadBound,
}

/// One entry of a slab's near list, in 12 bytes (the near lists are about 2.7 entries per
/// particle on a packed bed): the owner, the slot and the slot's partner. The sift reads all it
/// needs from the entry: the partner's position is one load away, and the owner and the slot
/// take none. (An 8-byte entry with the owner's place among the slab's members and the slot's
/// place among the owner's slots needed the owner's first slot and its image flag loaded for
/// every entry: 2.5-2.9 % slower at 1 thread on the 19.2k bed, for 11 B per particle less.)
/// Only [`SlabVisit::record_near`] makes one, from a visit's own tokens.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NearPair {
    owner: u32,
    slot: u32,
    partner: u32,
}

/// A slab's near list: its entries in the order recorded, and the places of those whose
/// separation needs the minimum image (M.77), ascending.
///
/// An entry needs it if its partner lay across a periodic face at the refresh (the minimum
/// image of the stored positions' difference was not the difference itself), and then until
/// the next refresh: positions are wrapped only at list builds, so an entry's difference moves
/// continuously until then, and it would have to pass half the box, where the pair is apart
/// under either rule, to change its image (the argument of [`Window::needs_minimum_image`], per
/// entry). So the sift of the near entries runs without an image test in its loop, and takes
/// the entries that need one apart: the test of an image flag in each entry, held in the
/// slot's high bit for its owner, was 12.1 of the 19.2k LIGGGHTS bed's 89.3 sift instructions
/// per particle-step (docs/performance-log.md, sixty-fourth round). The places take 4 bytes per
/// crossing entry, about 2 % of that bed's entries.
#[derive(Debug, Clone, Default)]
pub struct NearList {
    pairs: Vec<NearPair>,
    crossing: Vec<u32>,
}

impl NearList {
    /// Number of entries.
    #[must_use]
    #[inline]
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether the list holds no entry.
    #[must_use]
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Removes every entry, keeping the allocations.
    pub fn clear(&mut self) {
        self.pairs.clear();
        self.crossing.clear();
    }

    /// Makes this list a copy of `recorded`, in the allocation it has if large enough, else in
    /// one of the size needed and a sixteenth more: the near lists are recorded into a thread's
    /// scratch and then copied into their slab's allocation. Grown by pushes, each slab's list
    /// would keep up to half its size as slack, and reallocated at every refresh, the heap
    /// would fill with holes (the near lists are a few per cent of the 97.2k bed's peak
    /// memory).
    pub fn copy_from(&mut self, recorded: &NearList) {
        fn copy<T: Copy>(to: &mut Vec<T>, from: &[T]) {
            if to.capacity() < from.len() {
                let size = from.len();
                *to = Vec::with_capacity(size + size / 16);
            }
            to.clear();
            to.extend_from_slice(from);
        }
        copy(&mut self.pairs, &recorded.pairs);
        copy(&mut self.crossing, &recorded.crossing);
    }

    /// The places of the entries `range` whose separation needs the minimum image, ascending.
    fn crossing_within(&self, range: Range<usize>) -> &[u32] {
        let place = |end: usize| self.crossing.partition_point(|&e| (e as usize) < end);
        &self.crossing[place(range.start)..place(range.end)]
    }
}

/// What a slab visit does with its slab's near list.
#[derive(Debug)]
pub enum NearVisit<'a> {
    /// The pass keeps no near list.
    Off,
    /// The list recorded at the last refresh, to read.
    Read(&'a NearList),
    /// The list to record anew, owner by owner and slot by slot (empty when the visit begins).
    Record(&'a RefCell<NearList>),
}

/// The tokens of one near-list entry: the owner, the slot and its partner.
#[derive(Debug, Clone, Copy)]
pub struct NearTokens<'a> {
    /// The owner of the slot.
    pub owner: Member<'a>,
    /// The slot.
    pub slot: Slot<'a>,
    /// Its partner.
    pub partner: Member<'a>,
}

/// One task's visit of one slab of a coloured pass: the windows of its owners, in ascending
/// order, and the slab's own per-slab data. The tokens it hands out live as long as the visit.
#[derive(Debug)]
pub struct SlabVisit<'a> {
    slab: u32,
    successor: u32,
    members: &'a [u32],
    /// CSR offsets of every owner's slots (`offsets[k]..offsets[k + 1]`).
    offsets: &'a [u32],
    partners: &'a [u32],
    slab_of: &'a [u32],
    crossing: &'a [bool],
    near: NearVisit<'a>,
    brand: Brand<'a>,
    thread: ThreadBound,
}

impl<'a> SlabVisit<'a> {
    /// The visit of slab `slab` with owners `members`, whose slots are given by `offsets` and
    /// `partners` (as in the neighbour list) and whose partners lie in `slab` or `successor`
    /// (by `slab_of`), with the slab's near list `near`.
    ///
    /// # Safety
    /// Every partner of the members' slots lies in slab `slab` or `successor`, and while the
    /// visit lives no other thread holds a visit or window that reaches a particle of these two
    /// slabs or one of these slots. A near list to read holds only entries recorded by visits of
    /// this slab with the same `members`, `offsets` and `partners`. Every member lies below
    /// `slab_of.len()` (the partners do, lying in a slab by `slab_of`).
    ///
    /// The visit's lifetime `'a` is the brand of its tokens ([`Scatter::open`]): the visit is
    /// handed only to code generic over `'a` (a `for<'a>` closure), where no other visit or
    /// window has it.
    #[must_use]
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn new(
        slab: u32,
        successor: u32,
        members: &'a [u32],
        offsets: &'a [u32],
        partners: &'a [u32],
        slab_of: &'a [u32],
        crossing: &'a [bool],
        near: NearVisit<'a>,
    ) -> Self {
        Self {
            slab,
            successor,
            members,
            offsets,
            partners,
            slab_of,
            crossing,
            near,
            brand: PhantomData,
            thread: PhantomData,
        }
    }

    /// The windows of the slab's owners, in ascending order.
    pub fn windows(&self) -> impl Iterator<Item = Window<'a>> + '_ {
        self.members.iter().map(move |&k| {
            let k = k as usize;
            let slots = self.offsets[k] as usize..self.offsets[k + 1] as usize;
            // SAFETY: the visit's contract covers the windows of its owners, whose tokens live
            // no longer than it does (the visit's lifetime bounds them).
            unsafe {
                Window::pair(
                    k,
                    slots,
                    self.partners,
                    self.slab_of,
                    self.slab,
                    self.successor,
                    self.crossing[k],
                )
            }
        })
    }

    /// The visited slab.
    #[must_use]
    #[inline]
    pub fn own_slab(&self) -> OwnSlab<'a> {
        OwnSlab {
            index: self.slab,
            window: PhantomData,
            thread: PhantomData,
        }
    }

    /// The owner and partner of `slot`, a slot of one of the visit's owners.
    ///
    /// # Panics
    /// If `slot` belongs to no owner of the visit.
    #[must_use]
    pub fn pair_of_slot(&self, slot: u32) -> (Member<'a>, Member<'a>) {
        let slot_index = slot as usize;
        // Members ascend, and so do their first slots.
        let place = self
            .members
            .partition_point(|&k| self.offsets[k as usize] as usize <= slot_index);
        let owner = place
            .checked_sub(1)
            .map(|place| self.members[place])
            .filter(|&k| slot_index < self.offsets[k as usize + 1] as usize)
            .unwrap_or_else(|| panic!("slot {slot} belongs to no owner of slab {}", self.slab));
        let member = |index: u32| Member {
            index,
            window: PhantomData,
            thread: PhantomData,
        };
        (member(owner), member(self.partners[slot_index]))
    }

    /// Whether this visit records its slab's near list anew ([`SlabVisit::record_near`]).
    #[must_use]
    #[inline]
    pub fn records_near(&self) -> bool {
        matches!(self.near, NearVisit::Record(_))
    }

    /// Adds `slot` of `window` (a window of [`SlabVisit::windows`] of this visit) to the near
    /// list being recorded, with whether its separation needed the minimum image (`crossing`,
    /// see [`NearList`]); does nothing unless the visit records one.
    #[inline]
    pub fn record_near(&self, window: &Window<'a>, slot: Slot<'a>, crossing: bool) {
        debug_assert!(
            window.slots.contains(&slot.index()),
            "slot of another window"
        );
        debug_assert!(
            window.crossing || !crossing,
            "slot {} crosses a periodic face, its owner's window does not",
            slot.index
        );
        if let NearVisit::Record(list) = &self.near {
            let mut list = list.borrow_mut();
            if crossing {
                let place = u32::try_from(list.pairs.len()).expect("fewer than 2^32 near entries");
                list.crossing.push(place);
            }
            list.pairs.push(NearPair {
                owner: window.owner().index,
                slot: slot.index,
                partner: window.partners[slot.index() - window.slots.start],
            });
        }
    }

    /// Number of entries of the near list read by this visit (0 if it reads none).
    #[must_use]
    #[inline]
    pub fn near_count(&self) -> usize {
        match &self.near {
            NearVisit::Read(list) => list.len(),
            _ => 0,
        }
    }

    /// The places of the near list's entries `range` whose separation needs the minimum image,
    /// ascending (see [`NearList`]).
    ///
    /// # Panics
    /// If the visit reads no near list.
    #[must_use]
    #[inline]
    pub fn near_crossing(&self, range: Range<usize>) -> &[u32] {
        let NearVisit::Read(list) = &self.near else {
            panic!("this visit reads no near list")
        };
        list.crossing_within(range)
    }

    /// The tokens of the near list's entries `range`, in the order they were recorded.
    ///
    /// # Panics
    /// If the visit reads no near list or `range` is not within it.
    #[inline]
    pub fn near_pairs(
        &self,
        range: Range<usize>,
    ) -> impl ExactSizeIterator<Item = NearTokens<'a>> + Clone + '_ {
        let NearVisit::Read(list) = &self.near else {
            panic!("this visit reads no near list")
        };
        list.pairs[range].iter().map(move |pair| {
            let owner = pair.owner as usize;
            let slot = pair.slot as usize;
            let partner = pair.partner;
            debug_assert!(
                self.members.binary_search(&pair.owner).is_ok(),
                "near pair {pair:?}: owner not of this slab"
            );
            debug_assert!(
                slot < self.offsets[owner + 1] as usize && self.partners[slot] == partner,
                "near pair {pair:?}: not a slot of owner {owner} with that partner"
            );
            debug_assert!(
                self.slab_of
                    .get(partner as usize)
                    .is_some_and(|s| *s == self.slab || *s == self.successor),
                "near pair ({owner}, slot {slot}) outside the slabs of its visit"
            );
            NearTokens {
                owner: Member {
                    index: owner as u32,
                    window: PhantomData,
                    thread: PhantomData,
                },
                slot: Slot {
                    index: slot as u32,
                    window: PhantomData,
                    thread: PhantomData,
                },
                partner: Member {
                    index: partner,
                    window: PhantomData,
                    thread: PhantomData,
                },
            }
        })
    }
}

impl<'a> Window<'a> {
    /// The window of an owner's visit in a coloured pair pass: the owner, its pair slots
    /// `slots` and their partners `partners[slots]`.
    ///
    /// # Safety
    /// Every partner of these slots lies in slab `slab` or `successor` (by `slab_of`), and while
    /// the window lives no other thread holds a window that reaches a particle of these two
    /// slabs or one of these slots. (`crossing` is not part of the contract: see
    /// [`Window::needs_minimum_image`].) Its lifetime `'a` is that of the visit whose window
    /// it is, with the same `partners` and `slab_of`, or no visit's ([`SlabVisit::new`]).
    ///
    /// # Panics
    /// If `slots` is not a range of `partners`.
    #[must_use]
    unsafe fn pair(
        owner: usize,
        slots: Range<usize>,
        partners: &'a [u32],
        slab_of: &'a [u32],
        slab: u32,
        successor: u32,
        crossing: bool,
    ) -> Self {
        Self {
            owner,
            partners: &partners[slots.clone()],
            slots,
            slab_of,
            slabs: [slab, successor],
            crossing,
            brand: PhantomData,
            thread: PhantomData,
        }
    }

    /// The window of a per-particle visit: particle `k` alone, no slot.
    ///
    /// # Safety
    /// While the window lives no other thread holds a window that reaches particle `k`, and
    /// `k` fits in `u32` (its token holds it so). Its lifetime `'a` is no visit's
    /// ([`SlabVisit::new`]).
    #[must_use]
    unsafe fn particle(k: usize) -> Self {
        Self {
            owner: k,
            slots: 0..0,
            partners: &[],
            slab_of: &[],
            slabs: [u32::MAX; 2],
            crossing: false,
            brand: PhantomData,
            thread: PhantomData,
        }
    }

    /// The visited particle (the owner of a pair visit).
    #[must_use]
    #[inline]
    pub fn owner(&self) -> Member<'a> {
        Member {
            index: self.owner as u32,
            window: PhantomData,
            thread: PhantomData,
        }
    }

    /// Whether a partner lay across a periodic face at the neighbour-list build. If not, the
    /// plain difference of the stored positions is every touching partner's minimum image until
    /// the next build (M.77), and the pair pass skips the image test: positions are wrapped only
    /// at builds, so the difference moves continuously and stays below L/2 while the pair
    /// touches; a pair whose plain difference leaves the box is apart under either. The image
    /// test of every candidate cost 15 % of the pair pass's instructions on the 20k LIGGGHTS bed,
    /// where 12 % of the owners cross.
    #[must_use]
    #[inline]
    pub fn needs_minimum_image(&self) -> bool {
        self.crossing
    }

    /// The visit's pair slots with their partners, in slot order.
    #[inline]
    pub fn pairs(&self) -> impl Iterator<Item = (Slot<'a>, Member<'a>)> + '_ {
        self.partners
            .iter()
            .enumerate()
            .map(|(i, &b)| self.slot_and_partner(i, b))
    }

    /// Number of the visit's pair slots.
    #[must_use]
    #[inline]
    pub fn slot_count(&self) -> usize {
        self.partners.len()
    }

    /// The tokens of the `i`-th slot and its partner `b`: the one place a pair window mints
    /// them.
    #[inline]
    fn slot_and_partner(&self, i: usize, b: u32) -> (Slot<'a>, Member<'a>) {
        debug_assert!(
            self.slab_of
                .get(b as usize)
                .is_some_and(|s| self.slabs.contains(s)),
            "partner {b} of slot {} outside the slabs {:?} of its owner's window",
            self.slots.start + i,
            self.slabs
        );
        (
            Slot {
                index: (self.slots.start + i) as u32,
                window: PhantomData,
                thread: PhantomData,
            },
            Member {
                index: b,
                window: PhantomData,
                thread: PhantomData,
            },
        )
    }

    /// The owner's slab (its pool of per-slab data).
    ///
    /// # Panics
    /// If the window is not a pair window (a per-particle visit has no slab).
    #[must_use]
    #[inline]
    pub fn own_slab(&self) -> OwnSlab<'a> {
        let index = self.slabs[0];
        assert!(index != u32::MAX, "a one-particle window has no slab");
        OwnSlab {
            index,
            window: PhantomData,
            thread: PhantomData,
        }
    }
}

/// A mutable slice written by several threads, each within its own [`Window`].
#[derive(Debug)]
pub struct Scatter<'a, T, Index> {
    start: *mut T,
    len: usize,
    borrow: PhantomData<(&'a mut [T], Index)>,
}

// SAFETY: a `Scatter` is a `&mut [T]` whose elements are reached only through the tokens of
// disjoint windows (see the module documentation); sending or sharing it is as safe as sending
// the elements.
unsafe impl<T: Send, I> Send for Scatter<'_, T, I> {}
// SAFETY: as above.
unsafe impl<T: Send, I> Sync for Scatter<'_, T, I> {}

impl<'a, T, I> Scatter<'a, T, I> {
    /// Borrows `slice` mutably for the lifetime of the scatter.
    #[must_use]
    pub fn new(slice: &'a mut [T]) -> Self {
        Self {
            start: slice.as_mut_ptr(),
            len: slice.len(),
            borrow: PhantomData,
        }
    }

    #[inline]
    fn element(&self, k: usize) -> *mut T {
        assert!(k < self.len, "index {k} outside the array of {}", self.len);
        // SAFETY: in bounds, checked above.
        unsafe { self.start.add(k) }
    }
}

impl<T: Copy> Scatter<'_, T, PerParticle> {
    /// Particle `k`'s element.
    #[inline]
    #[must_use]
    pub fn read(&self, k: Member<'_>) -> T {
        // SAFETY: k is a member of a live window on this thread, and no concurrent window
        // reaches it (`Window`'s contract); in bounds (`element`).
        unsafe { self.element(k.index()).read() }
    }

    /// Sets particle `k`'s element to `change` of it. (A value in, a value out: no reference
    /// to the element is alive while `change` runs, which could reach the element again.)
    #[inline]
    pub fn update(&self, k: Member<'_>, change: impl FnOnce(T) -> T) {
        let element = self.element(k.index());
        // SAFETY: as in `read`.
        unsafe { element.write(change(element.read())) }
    }
}

/// An index kind whose tokens a visit names below a count of its list: particles or slots.
/// (The unchecked accessors of [`Opened`] rest on these counts; they exist for this module's
/// index kinds only.)
pub trait Counted {
    /// What the count counts, for messages.
    const WHAT: &'static str;
    /// The count every token of `visit` of this kind is below.
    fn count(visit: &SlabVisit<'_>) -> usize;
}

impl Counted for PerParticle {
    const WHAT: &'static str = "particles";
    fn count(visit: &SlabVisit<'_>) -> usize {
        visit.slab_of.len()
    }
}

impl Counted for PerSlot {
    const WHAT: &'static str = "slots";
    fn count(visit: &SlabVisit<'_>) -> usize {
        visit.partners.len()
    }
}

impl<T, I: Counted> Scatter<'_, T, I> {
    /// This scatter for the tokens of `visit` alone, without a bounds check per access.
    ///
    /// # Panics
    /// If the array is shorter than the visit's list has particles (slots, for a per-slot
    /// array).
    #[inline]
    #[must_use]
    pub fn open<'s, 'v>(&'s self, visit: &SlabVisit<'v>) -> Opened<'s, 'v, T, I> {
        let count = I::count(visit);
        assert!(
            count <= self.len,
            "an array of {} for a list of {count} {}",
            self.len,
            I::WHAT
        );
        Opened::at(self.start)
    }
}

impl<T> Scatter<'_, T, PerParticle> {
    /// This scatter for the tokens of `chunk` alone (a chunk of [`for_each_chunk`]), without a
    /// bounds check per access, as [`Scatter::open`] does for a slab visit.
    ///
    /// # Panics
    /// If the array is shorter than the chunk's pass has particles.
    #[inline]
    #[must_use]
    pub fn open_chunk<'s, 'v>(
        &'s self,
        chunk: &ParticleChunk<'v>,
    ) -> Opened<'s, 'v, T, PerParticle> {
        assert!(
            chunk.count <= self.len,
            "an array of {} for a pass over {} particles",
            self.len,
            chunk.count
        );
        Opened::at(self.start)
    }
}

impl<T> Scatter<'_, T, PerSlab> {
    /// The element of `visit`'s own slab, for its tokens alone.
    ///
    /// # Panics
    /// If the array has no element for the visit's slab.
    #[inline]
    #[must_use]
    pub fn open<'s, 'v>(&'s self, visit: &SlabVisit<'v>) -> Opened<'s, 'v, T, PerSlab> {
        Opened::at(self.element(visit.slab as usize))
    }
}

/// What hands out particle tokens branded `'v`, each below a count: a slab visit of the pair
/// pass (below its list's particle count) or a chunk of a pass over particles (below the pass's,
/// [`for_each_chunk`]). Arrays opened for it ([`OpenedReads::open`]) are checked against that
/// count once. Sealed: only this module's visits vouch for their tokens.
pub trait ParticleTokens<'v>: sealed::Sealed {
    /// Every particle token handed out names a particle below this count.
    fn particle_count(&self) -> usize;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::SlabVisit<'_> {}
    impl Sealed for super::ParticleChunk<'_> {}
}

impl<'v> ParticleTokens<'v> for SlabVisit<'v> {
    fn particle_count(&self) -> usize {
        PerParticle::count(self)
    }
}

impl<'v> ParticleTokens<'v> for ParticleChunk<'v> {
    fn particle_count(&self) -> usize {
        self.count
    }
}

/// A [`Scatter`] opened for one slab visit, whose lifetime `'v` brands its tokens: it takes that
/// visit's tokens only, and its length was checked once, when it was opened, against every index
/// they can name (the list's particle or slot count; a per-slab scatter holds the visit's own
/// slab's element). Its accesses then take no bounds check. (Checked at every access, as
/// [`Scatter`] does, the checks cost the 19.2k LIGGGHTS bed's step 6-8 %: three to six per
/// contact in the write-back alone.) It stays on the visiting thread, as the tokens do.
///
/// The brand at work: below, a scatter of two particles is opened for the visit of a
/// two-particle list, inside the visit of a three-particle list whose tokens live longer. With
/// tokens of the visit it was opened for, the write compiles:
///
/// ```
/// use am_sim::scatter::{NearVisit, PerParticle, Scatter, SlabVisit};
/// // Particles 0..n in slab 0; particle 0 owns one slot, whose partner is the last particle.
/// fn visit<R>(n: usize, f: impl for<'v> FnOnce(&SlabVisit<'v>) -> R) -> R {
///     let members: Vec<u32> = (0..n as u32).collect();
///     let mut offsets = vec![1u32; n + 1];
///     offsets[0] = 0;
///     let (partners, slab_of, crossing) = ([n as u32 - 1], vec![0; n], vec![false; n]);
///     // SAFETY: one thread; the partner lies in slab 0; the visit goes to a `for<'v>` closure.
///     let visit = unsafe {
///         SlabVisit::new(0, 0, &members, &offsets, &partners, &slab_of, &crossing, NearVisit::Off)
///     };
///     f(&visit)
/// }
/// let mut forces = vec![0.0; 2];
/// let forces = Scatter::<f64, PerParticle>::new(&mut forces);
/// visit(3, |_long| {
///     visit(2, |short| {
///         let opened = forces.open(short);
///         for window in short.windows() {
///             for (_, partner) in window.pairs() {
///                 opened.update(partner, |f| f + 1.0);
///             }
///         }
///     })
/// });
/// ```
///
/// With a token of the three-particle list's visit (its partner is particle 2, past the array's
/// end), it does not:
///
/// ```compile_fail
/// # use am_sim::scatter::{NearVisit, PerParticle, Scatter, SlabVisit};
/// # fn visit<R>(n: usize, f: impl for<'v> FnOnce(&SlabVisit<'v>) -> R) -> R {
/// #     let members: Vec<u32> = (0..n as u32).collect();
/// #     let mut offsets = vec![1u32; n + 1];
/// #     offsets[0] = 0;
/// #     let (partners, slab_of, crossing) = ([n as u32 - 1], vec![0; n], vec![false; n]);
/// #     let visit = unsafe {
/// #         SlabVisit::new(0, 0, &members, &offsets, &partners, &slab_of, &crossing, NearVisit::Off)
/// #     };
/// #     f(&visit)
/// # }
/// let mut forces = vec![0.0; 2];
/// let forces = Scatter::<f64, PerParticle>::new(&mut forces);
/// visit(3, |long| {
///     visit(2, |short| {
///         let opened = forces.open(short);
///         for window in long.windows() {
///             for (_, partner) in window.pairs() {
///                 opened.update(partner, |f| f + 1.0);
///             }
///         }
///     })
/// });
/// ```
#[derive(Debug)]
pub struct Opened<'s, 'v, T, Index> {
    /// The array's first element, or the own slab's element of a per-slab scatter.
    start: *mut T,
    scatter: PhantomData<&'s Scatter<'s, T, Index>>,
    brand: Brand<'v>,
}

impl<T, I> Opened<'_, '_, T, I> {
    #[inline]
    fn at(start: *mut T) -> Self {
        Self {
            start,
            scatter: PhantomData,
            brand: PhantomData,
        }
    }
}

impl<'v, T: Copy> Opened<'_, 'v, T, PerParticle> {
    /// Particle `k`'s element.
    #[inline(always)]
    #[must_use]
    pub fn read(&self, k: Member<'v>) -> T {
        // SAFETY: k is a token of the visit or chunk this scatter was opened for (its brand),
        // below its list's particle count (`SlabVisit::new`) or its pass's (`for_each_chunk`),
        // which the array's length was checked against (`open`, `open_chunk`); no concurrent
        // window reaches it (`Window`'s contract).
        unsafe { self.start.add(k.index()).read() }
    }

    /// Sets particle `k`'s element to `change` of it.
    #[inline(always)]
    pub fn update(&self, k: Member<'v>, change: impl FnOnce(T) -> T) {
        // SAFETY: as in `read`.
        unsafe {
            let element = self.start.add(k.index());
            element.write(change(element.read()));
        }
    }

    /// Asks for particle `k`'s element to be brought into the cache ([`prefetch`]).
    #[inline(always)]
    pub fn prefetch(&self, k: Member<'v>) {
        prefetch(self.start.wrapping_add(k.index()));
    }
}

impl<'v, T> Opened<'_, 'v, T, PerParticle> {
    /// `inspect(elements, argument)` on the elements of every particle in `chunk`'s range
    /// (windowed or not), as one slice: what a pass over particles tests at
    /// the end of a chunk (the particle pass's test of the finished forces for NaN and
    /// infinities, `forces::particle_pass`). A function and a `'static` argument, not a closure,
    /// as for [`Opened::update_own`]: `inspect` cannot reach this scatter, so nothing writes the
    /// elements while the slice lives.
    #[inline]
    pub fn inspect_chunk<A: 'static, R>(
        &self,
        chunk: &ParticleChunk<'v>,
        inspect: fn(&[T], A) -> R,
        argument: A,
    ) -> R {
        // SAFETY: only `inspect` sees the slice, and it cannot reach this scatter (see above).
        inspect(unsafe { self.chunk_elements(chunk) }, argument)
    }

    /// As [`Opened::inspect_chunk`], with the elements of the chunk's range of another
    /// per-particle array, `beside.0`, which the pass only reads (heat capacities beside the
    /// heat sums, say), and a value `beside.1` for every element (a material's specific heat
    /// beside the masses, say). Both are plain values (`Copy`, `'static`: no reference that
    /// could reach this scatter).
    ///
    /// # Panics
    /// If `beside.0` is shorter than the chunk's range reaches.
    #[inline]
    pub fn inspect_chunk_beside<U: Copy + 'static, C: Copy + 'static, R>(
        &self,
        chunk: &ParticleChunk<'v>,
        (beside, context): (&[U], C),
        inspect: fn(&[T], &[U], C) -> R,
    ) -> R {
        let beside = &beside[chunk.range()];
        // SAFETY: only `inspect` sees the slice, and neither it nor `beside` (another array,
        // read only, of plain values) nor `context` (a plain value) can reach this scatter.
        inspect(unsafe { self.chunk_elements(chunk) }, beside, context)
    }

    /// The elements of every particle in `chunk`'s range, as one slice.
    ///
    /// # Safety
    /// Nothing may write them while the slice lives: the caller hands it only to code that
    /// cannot reach this scatter or a token of the chunk (a plain function, as above).
    #[inline]
    unsafe fn chunk_elements(&self, chunk: &ParticleChunk<'v>) -> &[T] {
        let range = chunk.range();
        // SAFETY: the brand `'v` is fresh for each chunk's visit (`for_each_chunk`), so this
        // scatter was opened for `chunk` ([`Scatter::open_chunk`]), whose check of the length
        // covers `range` (it lies below the pass's count). No other thread reaches a particle of
        // the range: the chunks' ranges are disjoint and each is visited by one thread, which
        // neither the chunk nor its windows can leave. On this thread, the caller's contract.
        unsafe { std::slice::from_raw_parts(self.start.add(range.start), range.len()) }
    }
}

/// A hint to the processor to bring the cache line at `address` into its first-level cache, so
/// that a read or write of it that comes later does not wait on memory. A prefetch changes no
/// value the program sees and cannot fault, whatever the address; on a processor other than
/// x86-64 it does nothing.
#[inline(always)]
pub fn prefetch<T>(address: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `prefetcht0` reads nothing into the program's state and does not fault on any
    // address (Intel SDM, PREFETCHh).
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>(address.cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = address;
}

impl<'v, T: Copy> Opened<'_, 'v, T, PerSlot> {
    /// Slot `p`'s element.
    #[inline(always)]
    #[must_use]
    pub fn read(&self, p: Slot<'v>) -> T {
        // SAFETY: p is a token of the visit this scatter was opened for (its brand), below its
        // list's slot count, which the array's length was checked against (`open`); no
        // concurrent window holds it (`Window`'s contract).
        unsafe { self.start.add(p.index()).read() }
    }

    /// Sets slot `p`'s element to `value`.
    #[inline(always)]
    pub fn write(&self, p: Slot<'v>, value: T) {
        // SAFETY: as in `read`.
        unsafe { self.start.add(p.index()).write(value) }
    }
}

impl<'v, T> Opened<'_, 'v, T, PerSlab> {
    /// `change(element, argument)` on the visit's own slab's element. A function and a
    /// `'static` argument, not a closure: `change` cannot reach this scatter, so no second
    /// reference to the element is made while it runs. (Always inlined: the spring pools' reads
    /// and appends go through it at every contact, and left to itself the compiler called it,
    /// 7 % of the step.)
    #[inline(always)]
    pub fn update_own<A: 'static, R>(
        &self,
        slab: OwnSlab<'v>,
        change: fn(&mut T, A) -> R,
        argument: A,
    ) -> R {
        debug_assert!(slab.index != u32::MAX);
        // SAFETY: the element of the visit's own slab (`open`); concurrent visits have disjoint
        // slab pairs (`SlabVisit`'s contract), so no other thread's visit names this slab as its
        // own, and `change` cannot make a second reference to the element (see above).
        change(unsafe { &mut *self.start }, argument)
    }
}

/// A per-particle array the pass only reads (positions, radii, velocities...), opened for one
/// slab visit as [`Opened`] is: its length was checked once against the visit's particle count,
/// so a read with one of the visit's tokens takes no bounds check. (A check per read cost the
/// pair pass about 13 instructions per particle-step on the 19.2k LIGGGHTS bed, one pair of
/// compares per near-list entry and two per contact, 2.8 % of the step.) Shared: nothing writes
/// the array while the reference lives.
///
/// The brand keeps out the tokens of another visit, as for [`Opened`]: radii of a two-particle
/// list do not take the partner of a three-particle list's visit (particle 2, past their end).
///
/// ```compile_fail
/// # use am_sim::scatter::{NearVisit, OpenedReads, SlabVisit};
/// # fn visit<R>(n: usize, f: impl for<'v> FnOnce(&SlabVisit<'v>) -> R) -> R {
/// #     let members: Vec<u32> = (0..n as u32).collect();
/// #     let mut offsets = vec![1u32; n + 1];
/// #     offsets[0] = 0;
/// #     let (partners, slab_of, crossing) = ([n as u32 - 1], vec![0; n], vec![false; n]);
/// #     let visit = unsafe {
/// #         SlabVisit::new(0, 0, &members, &offsets, &partners, &slab_of, &crossing, NearVisit::Off)
/// #     };
/// #     f(&visit)
/// # }
/// let radius = vec![1.0; 2];
/// visit(3, |long| {
///     visit(2, |short| {
///         let radii = OpenedReads::open(&radius, short);
///         for window in long.windows() {
///             for (_, partner) in window.pairs() {
///                 let _ = radii.get(partner);
///             }
///         }
///     })
/// });
/// ```
#[derive(Debug)]
pub struct OpenedReads<'s, 'v, T> {
    start: *const T,
    values: PhantomData<&'s [T]>,
    brand: Brand<'v>,
    thread: ThreadBound,
}

impl<T> Clone for OpenedReads<'_, '_, T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for OpenedReads<'_, '_, T> {}

impl<'s, 'v, T: Copy> OpenedReads<'s, 'v, T> {
    /// `values` for the particle tokens of `tokens` alone: a slab visit's, or a chunk's.
    ///
    /// # Panics
    /// If `values` is shorter than the visit's list (the chunk's pass) has particles.
    #[inline]
    #[must_use]
    pub fn open(values: &'s [T], tokens: &impl ParticleTokens<'v>) -> Self {
        let count = tokens.particle_count();
        assert!(
            count <= values.len(),
            "an array of {} for a list of {count} particles",
            values.len()
        );
        Self {
            start: values.as_ptr(),
            values: PhantomData,
            brand: PhantomData,
            thread: PhantomData,
        }
    }

    /// Particle `k`'s value.
    #[inline(always)]
    #[must_use]
    pub fn get(self, k: Member<'v>) -> T {
        // SAFETY: k is a token of the visit or chunk these values were opened for (its brand),
        // below its particle count (`ParticleTokens`: its list's, `SlabVisit::new`, or its
        // pass's, `for_each_chunk`), which their length was checked against (`open`); the
        // shared borrow keeps them alive and unwritten.
        unsafe { self.start.add(k.index()).read() }
    }

    /// Asks for particle `k`'s value to be brought into the cache ([`prefetch`]).
    #[inline(always)]
    pub fn prefetch(self, k: Member<'v>) {
        prefetch(self.start.wrapping_add(k.index()));
    }
}

/// Calls `visit(partial, state, chunk)` once for every chunk of `chunk_len` consecutive
/// particles of `0..count`, which hands out a window for each of its particles in ascending
/// order (with `windows`; without, none: the visit reaches particles by tokens of its own
/// list, [`ParticleChunk::member`]), with the chunk's own `states[c]` (so a visit may keep
/// per-chunk data sorted by particle) and the chunk's own `partial` (from `identity`), which the
/// visit updates in place, the chunks in parallel when `parallel`. The partials are reduced with
/// `merge` (associative and commutative, for the result not to depend on the thread count), as
/// in [`crate::neighbor::NeighborList::for_each_owner`]. The windows of a chunk share its
/// lifetime, so a visit may hold the tokens of several of them at once (a batch of contacts
/// gathered over particles).
///
/// # Panics
/// If `states` does not hold one state per chunk, or with 2^32 particles or more.
#[allow(clippy::too_many_arguments)]
pub fn for_each_chunk<S, R, V, M>(
    count: usize,
    chunk_len: usize,
    windows: bool,
    states: &mut [S],
    parallel: bool,
    identity: R,
    visit: V,
    merge: M,
) -> R
where
    S: Send,
    R: Clone + Send + Sync,
    V: Fn(&mut R, &mut S, &ParticleChunk<'_>) + Sync,
    M: Fn(R, R) -> R + Sync + Send,
{
    assert_eq!(
        states.len(),
        count.div_ceil(chunk_len),
        "one state per chunk"
    );
    assert!(
        u32::try_from(count).is_ok(),
        "{count} particles: a particle's token holds its index in 32 bits"
    );
    // A chunk's particles add into the partial they are given.
    let chunk = |mut partial: R, c: usize, state: &mut S| {
        let range = c * chunk_len..((c + 1) * chunk_len).min(count);
        let chunk = ParticleChunk {
            windows,
            range,
            count,
            brand: PhantomData,
            thread: PhantomData,
        };
        visit(&mut partial, state, &chunk);
        partial
    };
    // The members of the thread team take the same share of the chunks at every pass.
    crate::team::fold_items(
        parallel,
        states.iter_mut().collect(),
        || identity.clone(),
        chunk,
        &merge,
    )
}

/// One chunk of a pass over particles ([`for_each_chunk`]): its particles, each handed out once
/// as a window of its own.
#[derive(Debug)]
pub struct ParticleChunk<'a> {
    /// Whether the chunk hands out a window for each particle of its range
    /// ([`ParticleChunk::windows`]), or none.
    windows: bool,
    /// The chunk's particles: no other chunk reaches them.
    range: Range<usize>,
    /// The pass's particle count: every particle of the chunk lies below it.
    count: usize,
    brand: Brand<'a>,
    thread: ThreadBound,
}

impl<'a> ParticleChunk<'a> {
    /// The chunk's range of particles: those it hands out windows and tokens for.
    #[must_use]
    #[inline]
    pub fn range(&self) -> Range<usize> {
        self.range.clone()
    }

    /// The token of particle `k` of the chunk's range, windowed or not: a pass that reaches
    /// particles by a list of its own (the wall candidates) takes their tokens here. A particle
    /// may be named more than once: tokens give access by value only (no reference an access
    /// could alias), and the chunk's whole range is its own, on its own thread.
    ///
    /// # Panics
    /// If `k` lies outside the chunk's range.
    #[must_use]
    #[inline(always)]
    pub fn member(&self, k: usize) -> Member<'a> {
        assert!(
            self.range.contains(&k),
            "particle {k} outside the chunk's {:?}",
            self.range
        );
        Member {
            // (k < count < 2^32: `for_each_chunk`.)
            index: k as u32,
            window: PhantomData,
            thread: PhantomData,
        }
    }

    /// A window for each of the chunk's particles, in ascending order; none if the pass asked
    /// for none ([`for_each_chunk`]'s `windows`).
    pub fn windows(&self) -> impl Iterator<Item = Window<'a>> + '_ {
        let range = if self.windows {
            self.range.clone()
        } else {
            0..0
        };
        range.map(move |k| {
            // SAFETY: no other thread holds a window of particle k: each chunk hands out its
            // own range once (`for_each_chunk`), the ranges do not meet, each chunk is visited
            // by one thread, and neither the chunk nor its windows can
            // leave that thread (`ThreadBound`). The brand `'a` is the chunk's, fresh for each
            // visit (`for_each_chunk`'s `visit` is generic over it), so it is no slab visit's.
            // And k < count < 2^32 (`for_each_chunk`).
            unsafe { Window::particle(k) }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_hands_out_its_owner_slots_and_partners_only() {
        let slab_of = [0, 0, 1, 2, 1];
        // Owner 0's slots are 3 and 4, with partners 4 and 2 (slab 1, the successor).
        let partners = [9, 9, 9, 4, 2, 9];
        // SAFETY: single-threaded test; the partners lie in slabs 0 and 1; no visit shares the
        // window's lifetime.
        let window = unsafe { Window::pair(0, 3..5, &partners, &slab_of, 0, 1, false) };
        let pairs: Vec<(usize, usize)> = window
            .pairs()
            .map(|(slot, partner)| (slot.index(), partner.index()))
            .collect();
        assert_eq!(pairs, [(3, 4), (4, 2)]);
        let mut values = vec![0.0; 5];
        let particles: Scatter<'_, f64, PerParticle> = Scatter::new(&mut values);
        // (Per-slot arrays are written through a scatter opened for a slab visit only: see the
        // next test.)
        let mut slot_values = vec![0u8; 6];
        particles.update(window.owner(), |v| v + 1.0);
        for (slot, partner) in window.pairs() {
            particles.update(partner, |v| v + 2.0);
            slot_values[slot.index()] = 1;
        }
        assert_eq!(particles.read(window.owner()), 1.0);
        // SAFETY: single-threaded test.
        let particle = unsafe { Window::particle(1) };
        assert_eq!(particle.pairs().count(), 0);
        assert!(std::panic::catch_unwind(|| particle.own_slab()).is_err());
        assert_eq!(values, [1.0, 0.0, 2.0, 0.0, 2.0]);
        assert_eq!(slot_values, [0, 0, 0, 1, 1, 0]);
    }

    /// A scatter opened for a slab visit reaches every element the visit's tokens name (the
    /// owners, their partners and slots, the slab's own element) and no other, and so do opened
    /// reads; neither can be opened for a list longer than its array.
    #[test]
    fn an_opened_scatter_writes_what_the_visit_names_and_checks_its_length_once() {
        // Five particles; slab 0 holds 0 and 1, whose slots 0-2 have partners in slabs 0 and 1.
        let slab_of = [0, 0, 1, 2, 1];
        let members = [0, 1];
        let offsets = [0, 2, 3, 3, 3, 3];
        let partners = [4, 2, 4];
        let crossing = [false; 5];
        // SAFETY: single-threaded test; the partners lie in slabs 0 and 1, the members below 5.
        let visit = unsafe {
            SlabVisit::new(
                0,
                1,
                &members,
                &offsets,
                &partners,
                &slab_of,
                &crossing,
                NearVisit::Off,
            )
        };
        let mut forces = vec![0.0; 5];
        let mut states = vec![0u8; 3];
        let mut pools = vec![Vec::new(), Vec::new()];
        let radius = [1.0, 2.0, 3.0, 4.0, 5.0];
        let radius_reads = OpenedReads::open(&radius, &visit);
        let mut reach = Vec::new();
        {
            let forces = Scatter::<_, PerParticle>::new(&mut forces);
            let states = Scatter::<_, PerSlot>::new(&mut states);
            let pools = Scatter::<_, PerSlab>::new(&mut pools);
            let (opened_forces, opened_states) = (forces.open(&visit), states.open(&visit));
            let opened_pools = pools.open(&visit);
            for window in visit.windows() {
                for (slot, partner) in window.pairs() {
                    // Each pair adds 1 to its owner and 10 to its partner.
                    opened_forces.update(window.owner(), |f| f + 1.0);
                    opened_forces.update(partner, |f| f + 10.0);
                    reach.push(radius_reads.get(window.owner()) + radius_reads.get(partner));
                    opened_states.write(slot, opened_states.read(slot) + 1);
                    let pushed = opened_pools.update_own(
                        window.own_slab(),
                        |pool: &mut Vec<usize>, b| {
                            pool.push(b);
                            pool.len()
                        },
                        partner.index(),
                    );
                    assert!(pushed <= 3);
                }
                assert!(opened_forces.read(window.owner()) >= 1.0);
            }
        }
        assert_eq!(forces, [2.0, 1.0, 10.0, 0.0, 20.0]);
        assert_eq!(states, [1, 1, 1]);
        assert_eq!(pools, [vec![4, 2, 4], vec![]]);
        assert_eq!(reach, [6.0, 4.0, 7.0]);
        // An array shorter than the list's particles, slots or slabs is refused when opened.
        let refused =
            |open: &dyn Fn()| std::panic::catch_unwind(std::panic::AssertUnwindSafe(open)).is_err();
        let mut short = vec![0.0; 4];
        let short = Scatter::<f64, PerParticle>::new(&mut short);
        assert!(refused(&|| drop(short.open(&visit))));
        let mut short = vec![0u8; 2];
        let short = Scatter::<u8, PerSlot>::new(&mut short);
        assert!(refused(&|| drop(short.open(&visit))));
        let mut short: Vec<Vec<usize>> = Vec::new();
        let short = Scatter::<_, PerSlab>::new(&mut short);
        assert!(refused(&|| drop(short.open(&visit))));
        assert!(refused(&|| {
            let _ = OpenedReads::open(&radius[..4], &visit);
        }));
    }

    /// A near list recorded by one visit reads back, in a later visit of the same slab, as the
    /// tokens of the slots recorded, and the places of those recorded as crossing a periodic
    /// face, within any range; also past an owner's 256th slot (the 8-bit place of earlier
    /// entries).
    #[test]
    fn a_near_list_reads_back_the_slots_it_recorded() {
        // Particles 0 and 2 own slabs 0's slots: owner 2 has 300 slots, all with partner 1.
        let members = [0, 2];
        let offsets = [0, 2, 2, 302];
        let mut partners = vec![1; 302];
        partners[0] = 3;
        let slab_of = [0, 1, 0, 1];
        let crossing = [false, false, true, false];
        let recording = RefCell::new(NearList::default());
        let visit = |near| {
            // SAFETY: single-threaded test; the partners (1 and 3) lie in slab 1, the successor.
            unsafe {
                SlabVisit::new(
                    0, 1, &members, &offsets, &partners, &slab_of, &crossing, near,
                )
            }
        };
        let recorder = visit(NearVisit::Record(&recording));
        assert!(recorder.records_near());
        for window in recorder.windows() {
            for (i, (slot, _)) in window.pairs().enumerate() {
                if [0, 1, 7, 255, 256, 299].contains(&i) {
                    // Some of the crossing owner's slots cross, not all.
                    let crosses = window.needs_minimum_image() && i % 2 == 1;
                    recorder.record_near(&window, slot, crosses);
                }
            }
        }
        let recorded = recording.take();
        assert_eq!(recorded.len(), 8);
        let reader = visit(NearVisit::Read(&recorded));
        assert!(!reader.records_near());
        let read: Vec<_> = reader
            .near_pairs(0..reader.near_count())
            .map(|t| (t.owner.index(), t.slot.index(), t.partner.index()))
            .collect();
        assert_eq!(
            read,
            [
                (0, 0, 3),
                (0, 1, 1),
                (2, 2, 1),
                (2, 3, 1),
                (2, 9, 1),
                (2, 257, 1),
                (2, 258, 1),
                (2, 301, 1)
            ]
        );
        // Owner 2's slots 3, 9, 257 and 301 (its 1st, 7th, 255th and 299th) crossed: entries
        // 3, 4, 5 and 7.
        assert_eq!(reader.near_crossing(0..8), [3, 4, 5, 7]);
        assert_eq!(reader.near_crossing(4..7), [4, 5]);
        assert_eq!(reader.near_crossing(5..6), [5]);
        assert_eq!(reader.near_crossing(6..7), [] as [u32; 0]);
        assert_eq!(reader.near_crossing(7..8), [7]);
        assert_eq!(reader.near_crossing(0..3), [] as [u32; 0]);
    }

    #[test]
    #[cfg(debug_assertions)]
    fn with_debug_assertions_a_partner_outside_the_window_panics() {
        let slab_of = [0, 0, 1, 2, 1];
        // Partner 3 lies in slab 2, outside slabs 0 and 1: a list that broke its invariant.
        let partners = [3];
        // SAFETY: single-threaded test; nothing is written.
        let window = unsafe { Window::pair(0, 0..1, &partners, &slab_of, 0, 1, false) };
        assert!(std::panic::catch_unwind(|| window.pairs().count()).is_err());
    }

    /// A pass over chunks covers each particle once, in its own chunk's range: with windows, one
    /// window for each, ascending; without, none. And it merges the chunks' partials.
    #[test]
    fn a_pass_over_chunks_hands_out_each_particle_once_in_its_chunk() {
        let count: usize = 23;
        let chunk_len = 5;
        for (windows, parallel) in [(true, false), (true, true), (false, true)] {
            let mut chunks: Vec<usize> = (0..count.div_ceil(chunk_len)).collect();
            let (ranges, windowed) = for_each_chunk(
                count,
                chunk_len,
                windows,
                &mut chunks,
                parallel,
                (Vec::new(), Vec::new()),
                |(ranges, windowed): &mut (Vec<usize>, Vec<usize>), &mut c, chunk| {
                    let particles: Vec<usize> =
                        chunk.windows().map(|w| w.owner().index()).collect();
                    assert!(particles.is_sorted(), "chunk {c}: {particles:?}");
                    assert!(particles.iter().all(|k| k / chunk_len == c), "chunk {c}");
                    windowed.extend(particles);
                    assert!(chunk.range().all(|k| k / chunk_len == c), "chunk {c}");
                    // Every particle of the range has a token, windowed or not.
                    ranges.extend(chunk.range().map(|k| chunk.member(k).index()));
                },
                |(mut ranges, mut windowed), (more_ranges, more_windowed)| {
                    ranges.extend(more_ranges);
                    windowed.extend(more_windowed);
                    (ranges, windowed)
                },
            );
            let (mut ranges, mut windowed) = (ranges, windowed);
            ranges.sort_unstable();
            windowed.sort_unstable();
            let every: Vec<usize> = (0..count).collect();
            assert_eq!(ranges, every);
            assert_eq!(windowed, if windows { every } else { Vec::new() });
        }
    }
}
