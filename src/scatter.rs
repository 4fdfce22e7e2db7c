//! Shared write access to per-particle and per-pair arrays for the coloured passes.
//!
//! A pair pass adds each pair's force to both of its particles (Newton's third law, one
//! evaluation per pair). Several threads do that at once, each on the slabs of one colour phase
//! of the neighbour list ([`crate::neighbor::NeighborList::for_each_owner`]). The borrow checker
//! cannot see that the particles two concurrent slabs touch are disjoint, so the arrays are
//! written through a [`Scatter`] and every access names a [`Window`]: the particles and pair
//! slots its holder may touch. Each access checks its index against the window (a wrong index
//! panics instead of racing), and windows are created only by the passes, which guarantee that
//! concurrent windows are disjoint. That guarantee is the single `unsafe` contract of the crate
//! ([`Window::pair`], [`Window::particle`]); the passes themselves are safe code.

#![allow(unsafe_code)]

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

/// What one visit may access: particles (the owner, or every particle of two slabs) and a range
/// of slots.
#[derive(Debug)]
pub struct Window<'a> {
    owner: usize,
    slots: Range<usize>,
    /// Each particle's slab, and the two slabs the visit may write (empty for a one-particle
    /// window).
    slab_of: &'a [u32],
    slabs: [u32; 2],
}

impl<'a> Window<'a> {
    /// The window of an owner's visit in a coloured pair pass: every particle of slabs `slab` and
    /// `successor` (by `slab_of`), and the owner's pair slots.
    ///
    /// # Safety
    /// While the window lives, no other thread holds a window that allows any of these particles
    /// or slots.
    #[must_use]
    pub unsafe fn pair(
        owner: usize,
        slots: Range<usize>,
        slab_of: &'a [u32],
        slab: u32,
        successor: u32,
    ) -> Self {
        Self {
            owner,
            slots,
            slab_of,
            slabs: [slab, successor],
        }
    }

    /// The window of a per-particle visit: particle `k` alone, no slot.
    ///
    /// # Safety
    /// As for [`Window::pair`].
    #[must_use]
    pub unsafe fn particle(k: usize) -> Self {
        Self {
            owner: k,
            slots: 0..0,
            slab_of: &[],
            slabs: [u32::MAX; 2],
        }
    }

    /// The visited particle (the owner of a pair visit).
    #[must_use]
    #[inline]
    pub fn owner(&self) -> usize {
        self.owner
    }

    /// The visit's slots.
    #[must_use]
    #[inline]
    pub fn slots(&self) -> Range<usize> {
        self.slots.clone()
    }

    #[inline]
    fn allows_particle(&self, k: usize) -> bool {
        k == self.owner
            || self
                .slab_of
                .get(k)
                .is_some_and(|s| *s == self.slabs[0] || *s == self.slabs[1])
    }
}

/// A mutable slice written by several threads, each within its own [`Window`].
#[derive(Debug)]
pub struct Scatter<'a, T, Index> {
    start: *mut T,
    len: usize,
    borrow: PhantomData<(&'a mut [T], Index)>,
}

// SAFETY: a `Scatter` is a `&mut [T]` whose elements are reached only through disjoint windows
// (see the module documentation); sending or sharing it is as safe as sending the elements.
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
    fn element(&self, k: usize, allowed: bool) -> *mut T {
        assert!(
            allowed && k < self.len,
            "index {k} outside the visit's window (or the array of {})",
            self.len
        );
        // SAFETY: in bounds, checked above.
        unsafe { self.start.add(k) }
    }
}

impl<T> Scatter<'_, T, PerParticle> {
    /// Applies `change` to particle `k`'s element.
    ///
    /// # Panics
    /// If the window does not allow particle `k`.
    #[inline]
    pub fn update(&self, window: &Window<'_>, k: usize, change: impl FnOnce(&mut T)) {
        let element = self.element(k, window.allows_particle(k));
        // SAFETY: the window allows k, and no concurrent window does (`Window`'s contract).
        change(unsafe { &mut *element });
    }

    /// Reads particle `k`'s element.
    ///
    /// # Panics
    /// If the window does not allow particle `k`.
    #[inline]
    #[must_use]
    pub fn read(&self, window: &Window<'_>, k: usize) -> T
    where
        T: Copy,
    {
        let element = self.element(k, window.allows_particle(k));
        // SAFETY: as in `update`.
        unsafe { *element }
    }
}

impl<T> Scatter<'_, T, PerSlot> {
    /// Applies `change` to slot `p`.
    ///
    /// # Panics
    /// If slot `p` is not the window's.
    #[inline]
    pub fn update(&self, window: &Window<'_>, p: usize, change: impl FnOnce(&mut T)) {
        let element = self.element(p, window.slots.contains(&p));
        // SAFETY: the window holds slot p, and no concurrent window does (`Window`'s contract).
        change(unsafe { &mut *element });
    }

    /// Reads slot `p`.
    ///
    /// # Panics
    /// If slot `p` is not the window's.
    #[inline]
    #[must_use]
    pub fn read(&self, window: &Window<'_>, p: usize) -> T
    where
        T: Copy,
    {
        let element = self.element(p, window.slots.contains(&p));
        // SAFETY: as in `update`.
        unsafe { *element }
    }
}

impl<T> Scatter<'_, T, PerSlab> {
    /// Applies `change` to the element of the owner's slab and returns what it returns.
    ///
    /// # Panics
    /// If the window is not a pair window (a per-particle visit has no slab).
    #[inline]
    pub fn update_own<R>(&self, window: &Window<'_>, change: impl FnOnce(&mut T) -> R) -> R {
        let slab = window.slabs[0];
        let element = self.element(slab as usize, slab != u32::MAX);
        // SAFETY: concurrent pair windows have disjoint slab pairs (`Window`'s contract), so no
        // other thread's window names this slab as its own; the owners of one slab are visited
        // one after the other by the same task.
        change(unsafe { &mut *element })
    }
}

/// Calls `visit(state, window)` once for every particle `0..count`, with a window allowing that
/// particle alone. The particles go in chunks of `chunk_len` consecutive indices: a chunk's
/// particles in ascending order with the chunk's own `states[c]` (so a visit may keep per-chunk
/// data sorted by particle), the chunks in parallel when `parallel`. The results are reduced
/// with `merge` (associative and commutative, for the result not to depend on the thread count).
///
/// # Panics
/// If `states` does not hold one state per chunk.
pub fn for_each_particle<S, R, V, M>(
    count: usize,
    chunk_len: usize,
    states: &mut [S],
    parallel: bool,
    identity: R,
    visit: V,
    merge: M,
) -> R
where
    S: Send,
    R: Clone + Send + Sync,
    V: Fn(&mut S, &Window<'_>) -> R + Sync,
    M: Fn(R, R) -> R + Sync + Send,
{
    use rayon::prelude::*;
    assert_eq!(
        states.len(),
        count.div_ceil(chunk_len),
        "one state per chunk"
    );
    let chunk = |(c, state): (usize, &mut S)| {
        let mut partial = identity.clone();
        for k in c * chunk_len..((c + 1) * chunk_len).min(count) {
            // SAFETY: every particle is visited exactly once.
            let window = unsafe { Window::particle(k) };
            partial = merge(partial, visit(state, &window));
        }
        partial
    };
    if parallel {
        states
            .par_iter_mut()
            .enumerate()
            .map(chunk)
            .reduce(|| identity.clone(), &merge)
    } else {
        states
            .iter_mut()
            .enumerate()
            .map(chunk)
            .fold(identity.clone(), &merge)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_admits_its_slabs_and_slots_only() {
        let slab_of = [0, 0, 1, 2, 1];
        // SAFETY: single-threaded test.
        let window = unsafe { Window::pair(0, 3..5, &slab_of, 0, 1) };
        let mut values = vec![0.0; 5];
        let particles: Scatter<'_, f64, PerParticle> = Scatter::new(&mut values);
        for k in [0, 1, 2, 4] {
            particles.update(&window, k, |v| *v += 1.0);
        }
        let outside = std::panic::catch_unwind(|| particles.read(&window, 3));
        assert!(outside.is_err(), "slab 2 is outside the window");
        let mut slots = vec![0u8; 6];
        let slots: Scatter<'_, u8, PerSlot> = Scatter::new(&mut slots);
        slots.update(&window, 4, |s| *s = 1);
        assert!(std::panic::catch_unwind(|| slots.read(&window, 5)).is_err());
        let mut pools = vec![Vec::new(), Vec::new(), Vec::new()];
        let pools: Scatter<'_, Vec<u8>, PerSlab> = Scatter::new(&mut pools);
        pools.update_own(&window, |pool| pool.push(7));
        // SAFETY: single-threaded test.
        let particle = unsafe { Window::particle(1) };
        assert!(std::panic::catch_unwind(|| pools.update_own(&particle, |_| ())).is_err());
        assert_eq!(pools.update_own(&window, |pool| pool.clone()), vec![7]);
    }
}
