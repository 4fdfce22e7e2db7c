//! The tangential springs of the particle-wall contacts, only for the contacts that hold one.
//!
//! A dense store (a 32-byte spring per particle and wall) costs `32 × walls` bytes per particle
//! although few particles touch a wall: on the LIGGGHTS bed 7 % touch the plate, and a box of
//! five walls would hold 160 bytes per particle of mostly zeros. Instead the particles are cut
//! into chunks of [`PARTICLES_PER_CHUNK`] consecutive indices, and each chunk keeps a list of its
//! non-zero springs sorted by (particle, wall). The particle pass visits a chunk's particles in
//! ascending order, so it reads the list with a cursor (a merge, no search) and appends the new
//! springs to a second buffer in the same order; the two swap after the pass. The chunks are
//! fixed by the particle count, not by the threads, so the pass gives the same result for any
//! thread count. A reorder of the particles renumbers and re-sorts the entries.

use crate::contact::tangential::TangentialSpring;

/// Consecutive particles per chunk: the thread team's items of a pass over particles, so that a
/// chunk's springs are read and written by the member that takes its particles.
pub const PARTICLES_PER_CHUNK: usize = crate::team::PARTICLES_PER_ITEM;

/// One non-zero wall spring: particle index, wall index and the spring.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    particle: u32,
    wall: u32,
    spring: TangentialSpring,
}

impl Entry {
    fn key(&self) -> (u32, u32) {
        (self.particle, self.wall)
    }
}

/// The wall springs of one chunk: those the last pass left (`held`, sorted by (particle, wall)),
/// the running pass's cursor into them, and what the running pass writes (`next`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Chunk {
    held: Vec<Entry>,
    cursor: usize,
    next: Vec<Entry>,
}

impl Chunk {
    /// The spring particle `k` held against wall `w` at the last pass (zero if none). Within a
    /// pass, calls must come in ascending (particle, wall) order, each pair at most once.
    #[inline]
    #[must_use]
    pub fn take(&mut self, k: usize, w: usize) -> TangentialSpring {
        let key = (index(k), index(w));
        self.pass_before(key);
        match self.held.get(self.cursor) {
            Some(e) if e.key() == key => {
                self.cursor += 1;
                e.spring
            }
            _ => TangentialSpring::default(),
        }
    }

    /// Whether particle `k` held a spring against some wall at the last pass. Within a pass,
    /// calls come in ascending particle order, as for [`Chunk::take`] (which may follow for
    /// the same particle).
    #[inline]
    #[must_use]
    pub fn holds_any(&mut self, k: usize) -> bool {
        let particle = index(k);
        self.pass_before((particle, 0));
        self.held
            .get(self.cursor)
            .is_some_and(|e| e.particle == particle)
    }

    /// Whether particle `k` held a spring at the last pass against a wall `w` for which
    /// `apart(w)`: a spring that lets go at this pass. Call after [`Chunk::holds_any`] for `k`,
    /// before any [`Chunk::take`] for it; moves no cursor.
    #[inline]
    #[must_use]
    pub fn holds_any_where(&self, k: usize, apart: impl Fn(usize) -> bool) -> bool {
        let particle = index(k);
        self.held[self.cursor.min(self.held.len())..]
            .iter()
            .take_while(|e| e.particle == particle)
            .any(|e| apart(e.wall as usize))
    }

    /// Moves the cursor past the entries before `key`: they belong to pairs the pass has gone
    /// by, and the visit order makes this at most one step per entry over the whole pass.
    #[inline]
    fn pass_before(&mut self, key: (u32, u32)) {
        while self.held.get(self.cursor).is_some_and(|e| e.key() < key) {
            self.cursor += 1;
        }
    }

    /// Records the spring of (`k`, `w`) after this pass; a zero spring is not stored.
    #[inline]
    pub fn keep(&mut self, k: usize, w: usize, spring: TangentialSpring) {
        if spring != TangentialSpring::default() {
            debug_assert!(
                self.next
                    .last()
                    .is_none_or(|e| e.key() < (index(k), index(w)))
            );
            self.next.push(Entry {
                particle: index(k),
                wall: index(w),
                spring,
            });
        }
    }

    fn begin(&mut self) {
        self.cursor = 0;
        self.next.clear();
    }

    fn end(&mut self) {
        std::mem::swap(&mut self.held, &mut self.next);
        self.next.clear();
    }
}

fn index(k: usize) -> u32 {
    u32::try_from(k).expect("fewer than 2^32 particles and walls")
}

/// The wall springs of every particle, chunked (see the module documentation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WallSprings {
    chunks: Vec<Chunk>,
}

impl WallSprings {
    /// No spring, for `particles` particles.
    #[must_use]
    pub fn new(particles: usize) -> Self {
        Self {
            chunks: vec![Chunk::default(); particles.div_ceil(PARTICLES_PER_CHUNK)],
        }
    }

    /// The springs `(particle, wall, spring)`, non-zero ones only, for `particles` particles
    /// (the entries need not be sorted; a pair given twice keeps the last).
    ///
    /// # Panics
    /// If an entry names a particle at or beyond `particles`.
    #[must_use]
    pub fn from_entries(
        particles: usize,
        entries: impl IntoIterator<Item = (usize, usize, TangentialSpring)>,
    ) -> Self {
        let mut store = Self::new(particles);
        let mut all: Vec<Entry> = entries
            .into_iter()
            .filter(|(.., spring)| *spring != TangentialSpring::default())
            .map(|(k, w, spring)| {
                assert!(k < particles, "wall spring of particle {k} of {particles}");
                Entry {
                    particle: index(k),
                    wall: index(w),
                    spring,
                }
            })
            .collect();
        // Stable, so that of a pair given twice the last stays last and wins below.
        all.sort_by_key(Entry::key);
        for entry in all {
            let held = &mut store.chunks[entry.particle as usize / PARTICLES_PER_CHUNK].held;
            match held.last_mut() {
                Some(last) if last.key() == entry.key() => *last = entry,
                _ => held.push(entry),
            }
        }
        store
    }

    /// The non-zero springs as `(particle, wall, spring)`, by particle then wall.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, TangentialSpring)> + '_ {
        self.chunks
            .iter()
            .flat_map(|c| &c.held)
            .map(|e| (e.particle as usize, e.wall as usize, e.spring))
    }

    /// The spring of particle `k` against wall `w` (zero if none); a binary search, for tests
    /// and tools.
    #[must_use]
    pub fn get(&self, k: usize, w: usize) -> TangentialSpring {
        let held = &self.chunks[k / PARTICLES_PER_CHUNK].held;
        held.binary_search_by_key(&(index(k), index(w)), Entry::key)
            .map_or(TangentialSpring::default(), |i| held[i].spring)
    }

    /// Stored energy of the springs \[J\] (M.63), by particle then wall.
    #[must_use]
    pub fn spring_energy(&self) -> f64 {
        self.entries().map(|(.., s)| s.spring_energy).sum()
    }

    /// Follows a reorder of `particles` particles (`new[i] = old[order[i]]`, particles not named
    /// are dropped with their springs: the caller books their energy).
    pub fn select(&mut self, particles: usize, order: &[u32]) {
        let mut new_index = vec![u32::MAX; particles];
        for (new, &old) in order.iter().enumerate() {
            new_index[old as usize] = index(new);
        }
        let kept: Vec<(usize, usize, TangentialSpring)> = self
            .entries()
            .filter(|(k, ..)| new_index[*k] != u32::MAX)
            .map(|(k, w, spring)| (new_index[k] as usize, w, spring))
            .collect();
        *self = Self::from_entries(order.len(), kept);
    }

    /// The chunks, ready for a pass: each visits its particles in ascending order, with
    /// [`Chunk::take`] and [`Chunk::keep`]; [`WallSprings::end_pass`] ends it.
    ///
    /// # Panics
    /// If the store was not made for `particles` particles.
    pub fn begin_pass(&mut self, particles: usize) -> &mut [Chunk] {
        assert_eq!(
            self.chunks.len(),
            particles.div_ceil(PARTICLES_PER_CHUNK),
            "wall springs made for another particle count"
        );
        for chunk in &mut self.chunks {
            chunk.begin();
        }
        &mut self.chunks
    }

    /// Makes the springs the pass kept the current ones.
    pub fn end_pass(&mut self) {
        for chunk in &mut self.chunks {
            chunk.end();
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
            spring_energy: x * x,
        }
    }

    #[test]
    fn a_pass_reads_what_the_last_pass_kept() {
        let n = 3 * PARTICLES_PER_CHUNK + 5;
        let mut store = WallSprings::from_entries(n, [(7, 1, spring(1.0)), (2000, 0, spring(2.0))]);
        let chunks = store.begin_pass(n);
        let mut seen = Vec::new();
        for (c, chunk) in chunks.iter_mut().enumerate() {
            let first = c * PARTICLES_PER_CHUNK;
            for k in first..(first + PARTICLES_PER_CHUNK).min(n) {
                // Asked before the particle's springs are taken, as the particle pass does.
                assert_eq!(chunk.holds_any(k), k == 7 || k == 2000, "particle {k}");
                for w in 0..2 {
                    let held = chunk.take(k, w);
                    if held != TangentialSpring::default() {
                        seen.push((k, w, held));
                    }
                    // Particle 7 lets go of wall 1; particle n - 1 touches wall 0.
                    let now = match (k, w) {
                        (2000, 0) => spring(3.0),
                        (k, 0) if k == n - 1 => spring(4.0),
                        _ => TangentialSpring::default(),
                    };
                    chunk.keep(k, w, now);
                }
            }
        }
        store.end_pass();
        assert_eq!(seen, vec![(7, 1, spring(1.0)), (2000, 0, spring(2.0))]);
        let now: Vec<_> = store.entries().collect();
        assert_eq!(now, vec![(2000, 0, spring(3.0)), (n - 1, 0, spring(4.0))]);
        assert_eq!(store.get(2000, 0), spring(3.0));
        assert_eq!(store.get(7, 1), TangentialSpring::default());
        assert!((store.spring_energy() - 25.0).abs() < 1e-12);
    }

    /// The particle pass asks which walls a particle's springs belong to before it takes them:
    /// the answer names that particle's springs alone, and asking moves no cursor.
    #[test]
    fn a_particle_s_springs_are_told_by_wall_before_they_are_taken() {
        let n = 10;
        let mut store = WallSprings::from_entries(
            n,
            [
                (2, 0, spring(1.0)),
                (2, 3, spring(2.0)),
                (4, 1, spring(3.0)),
            ],
        );
        let chunk = &mut store.begin_pass(n)[0];
        assert!(!chunk.holds_any(1));
        assert!(
            !chunk.holds_any_where(1, |_| true),
            "particle 2's springs are not 1's"
        );
        assert!(chunk.holds_any(2));
        assert!(chunk.holds_any_where(2, |w| w == 3));
        assert!(chunk.holds_any_where(2, |w| w == 0));
        assert!(!chunk.holds_any_where(2, |w| w == 1 || w == 2));
        assert!(
            !chunk.holds_any_where(2, |w| w == 4),
            "particle 4's wall 1 is not 2's"
        );
        // Nothing was taken: both springs are still there.
        assert_eq!(chunk.take(2, 0), spring(1.0));
        assert_eq!(chunk.take(2, 3), spring(2.0));
        assert!(chunk.holds_any(4) && chunk.holds_any_where(4, |w| w == 1));
        assert_eq!(chunk.take(4, 1), spring(3.0));
        assert!(!chunk.holds_any_where(4, |_| true), "taken");
    }

    #[test]
    fn a_reorder_moves_the_springs_with_their_particles() {
        let n = PARTICLES_PER_CHUNK + 10;
        let mut store = WallSprings::from_entries(
            n,
            [
                (0, 0, spring(1.0)),
                (5, 2, spring(2.0)),
                (n - 1, 1, spring(3.0)),
            ],
        );
        // Reverse the order and drop particle 5.
        let order: Vec<u32> = (0..n as u32).rev().filter(|&k| k != 5).collect();
        store.select(n, &order);
        let moved: Vec<_> = store.entries().collect();
        assert_eq!(moved, vec![(0, 1, spring(3.0)), (n - 2, 0, spring(1.0))]);
        assert_eq!(store.begin_pass(n - 1).len(), 2);
    }

    #[test]
    #[should_panic(expected = "another particle count")]
    fn a_pass_for_another_particle_count_is_refused() {
        let mut store = WallSprings::new(10);
        let _ = store.begin_pass(PARTICLES_PER_CHUNK + 1);
    }
}
