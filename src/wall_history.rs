//! The tangential springs of the particle-wall contacts, stored by wall candidate.
//!
//! A dense store (a 32-byte spring per particle and wall) costs `32 × walls` bytes per particle
//! although few particles come near a wall: on the LIGGGHTS bed about 7 % touch the plate, and
//! a box of five walls would hold 160 bytes per particle of mostly zeros. Instead the store
//! keeps one slot per *key*, a (particle, wall) pair, sorted by particle then wall: the wall
//! candidates of the neighbour list's current build (`forces::WallCandidates`, the pairs that
//! may touch before the next build), and any pair holding a spring that is not among them.
//! The particle pass reads and writes the slots in place, by position, as the pair pass does the
//! springs of its slots: no search, no merge, no second buffer. When the candidates are taken
//! anew, [`WallSprings::align`] carries the springs over to the new keys by a merge. A reorder
//! of the particles renumbers and re-sorts the keys, and the next pass aligns them again.

use crate::contact::tangential::TangentialSpring;

/// A particle-wall pair: particle index, then wall index, the order the pass visits them in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct WallKey {
    /// The particle's index.
    pub particle: u32,
    /// The wall's index in the model.
    pub wall: u32,
}

impl WallKey {
    /// The pair of particle `k` and wall `w`.
    ///
    /// # Panics
    /// With 2^32 particles or walls or more.
    #[must_use]
    pub fn new(k: usize, w: usize) -> Self {
        Self {
            particle: index(k),
            wall: index(w),
        }
    }
}

fn index(k: usize) -> u32 {
    u32::try_from(k).expect("fewer than 2^32 particles and walls")
}

/// The wall springs of every particle, one slot per key (see the module documentation). Two
/// stores are equal when they hold the same non-zero springs, whatever their zero slots.
#[derive(Debug, Clone, Default)]
pub struct WallSprings {
    /// Ascending.
    keys: Vec<WallKey>,
    /// The spring of each key (zero where the pair holds none).
    springs: Vec<TangentialSpring>,
    /// The taking of the candidates the keys were aligned to (the neighbour list's generation;
    /// 0: none since the last change from outside the pass).
    aligned_to: u64,
}

impl PartialEq for WallSprings {
    fn eq(&self, other: &Self) -> bool {
        self.entries().eq(other.entries())
    }
}

impl WallSprings {
    /// No spring.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
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
        let mut all: Vec<(WallKey, TangentialSpring)> = entries
            .into_iter()
            .filter(|(.., spring)| *spring != TangentialSpring::default())
            .map(|(k, w, spring)| {
                assert!(k < particles, "wall spring of particle {k} of {particles}");
                (WallKey::new(k, w), spring)
            })
            .collect();
        // Stable, so that of a pair given twice the last stays last and wins below.
        all.sort_by_key(|(key, _)| *key);
        let mut store = Self::default();
        for (key, spring) in all {
            if store.keys.last() == Some(&key) {
                *store.springs.last_mut().expect("as many springs as keys") = spring;
            } else {
                store.keys.push(key);
                store.springs.push(spring);
            }
        }
        store
    }

    /// The non-zero springs as `(particle, wall, spring)`, by particle then wall.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, TangentialSpring)> + '_ {
        self.keys
            .iter()
            .zip(&self.springs)
            .filter(|(_, spring)| **spring != TangentialSpring::default())
            .map(|(key, spring)| (key.particle as usize, key.wall as usize, *spring))
    }

    /// The spring of particle `k` against wall `w` (zero if none); a binary search, for tests
    /// and tools.
    #[must_use]
    pub fn get(&self, k: usize, w: usize) -> TangentialSpring {
        self.keys
            .binary_search(&WallKey::new(k, w))
            .map_or(TangentialSpring::default(), |i| self.springs[i])
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

    /// Makes the keys those of `candidates` (ascending, named by `taking`: the generation of the
    /// neighbour-list build they were taken for, unique over the process, 0 for none),
    /// and those of any spring held by a pair not among them (which cannot touch a wall before
    /// the next build, so that the pass finds it apart and books its energy: none should be
    /// left, but none is lost either), each with the spring it held. Does nothing if the keys
    /// are already aligned to `taking`. Returns the keys, with their springs.
    pub fn align(
        &mut self,
        candidates: &[WallKey],
        taking: u64,
    ) -> (&[WallKey], &mut [TangentialSpring]) {
        if taking == 0 || self.aligned_to != taking {
            debug_assert!(candidates.is_sorted_by(|a, b| a < b));
            let mut keys = Vec::with_capacity(candidates.len());
            let mut springs = Vec::with_capacity(candidates.len());
            let mut held = self
                .keys
                .iter()
                .zip(&self.springs)
                .filter(|(_, spring)| **spring != TangentialSpring::default())
                .peekable();
            for &candidate in candidates {
                // The held springs of pairs before this candidate, which are not candidates.
                while let Some((&key, &spring)) = held.next_if(|(key, _)| **key < candidate) {
                    keys.push(key);
                    springs.push(spring);
                }
                keys.push(candidate);
                springs.push(
                    held.next_if(|(key, _)| **key == candidate)
                        .map_or(TangentialSpring::default(), |(_, spring)| *spring),
                );
            }
            for (&key, &spring) in held {
                keys.push(key);
                springs.push(spring);
            }
            self.keys = keys;
            self.springs = springs;
            self.aligned_to = taking;
        }
        (&self.keys, &mut self.springs)
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

    fn keys(pairs: &[(usize, usize)]) -> Vec<WallKey> {
        pairs.iter().map(|&(k, w)| WallKey::new(k, w)).collect()
    }

    /// Aligned to a set of candidates, the store holds a slot for each, with the spring the pair
    /// held (zero for a new one), and keeps a held spring whose pair is not a candidate, in key
    /// order; aligned again to the same taking it changes nothing, to a new one it follows.
    #[test]
    fn aligned_keys_carry_the_springs_over() {
        let mut store = WallSprings::from_entries(
            3000,
            [
                (7, 1, spring(1.0)),
                (2000, 0, spring(2.0)),
                (5, 0, spring(5.0)),
            ],
        );
        let candidates = keys(&[(5, 0), (6, 0), (2000, 0), (2999, 1)]);
        let taking = 1;
        let (aligned, springs) = store.align(&candidates, taking);
        assert_eq!(
            aligned,
            keys(&[(5, 0), (6, 0), (7, 1), (2000, 0), (2999, 1)])
        );
        let zero = TangentialSpring::default();
        assert_eq!(springs, [spring(5.0), zero, spring(1.0), spring(2.0), zero]);
        // The pass writes in place: particle 7 let go, 2999 touched.
        springs[2] = zero;
        springs[4] = spring(4.0);
        let (again, _) = store.align(&candidates[..1], taking);
        assert_eq!(again.len(), 5, "the same taking: nothing changes");
        let now: Vec<_> = store.entries().collect();
        assert_eq!(
            now,
            vec![
                (5, 0, spring(5.0)),
                (2000, 0, spring(2.0)),
                (2999, 1, spring(4.0))
            ]
        );
        assert_eq!(store.get(2999, 1), spring(4.0));
        assert_eq!(store.get(7, 1), zero);
        assert!((store.spring_energy() - 45.0).abs() < 1e-12);
        // A new taking without particle 2000: its spring stays, as a key of its own.
        let (aligned, springs) = store.align(&keys(&[(5, 0), (2999, 1)]), 2);
        assert_eq!(aligned, keys(&[(5, 0), (2000, 0), (2999, 1)]));
        assert_eq!(springs, [spring(5.0), spring(2.0), spring(4.0)]);
        // Zero slots do not make two stores differ.
        assert_eq!(
            store,
            WallSprings::from_entries(
                3000,
                [
                    (5, 0, spring(5.0)),
                    (2000, 0, spring(2.0)),
                    (2999, 1, spring(4.0))
                ]
            )
        );
    }

    /// Candidates taken without a neighbour list have no taking (0): they are aligned at every
    /// pass.
    #[test]
    fn candidates_without_a_taking_are_aligned_every_time() {
        let mut store = WallSprings::from_entries(10, [(3, 0, spring(1.0))]);
        assert_eq!(store.align(&keys(&[(1, 0)]), 0).0.len(), 2);
        assert_eq!(store.align(&keys(&[(1, 0), (2, 0)]), 0).0.len(), 3);
    }

    #[test]
    fn a_reorder_moves_the_springs_with_their_particles() {
        let n = 1034;
        let mut store = WallSprings::from_entries(
            n,
            [
                (0, 0, spring(1.0)),
                (5, 2, spring(2.0)),
                (n - 1, 1, spring(3.0)),
            ],
        );
        let _ = store.align(&keys(&[(0, 0), (1, 0)]), 1);
        // Reverse the order and drop particle 5.
        let order: Vec<u32> = (0..n as u32).rev().filter(|&k| k != 5).collect();
        store.select(n, &order);
        let moved: Vec<_> = store.entries().collect();
        assert_eq!(moved, vec![(0, 1, spring(3.0)), (n - 2, 0, spring(1.0))]);
        assert_eq!(store.aligned_to, 0, "to be aligned again");
    }

    #[test]
    #[should_panic(expected = "wall spring of particle 10 of 10")]
    fn a_spring_of_a_particle_past_the_count_is_refused() {
        let _ = WallSprings::from_entries(10, [(10, 0, spring(1.0))]);
    }
}
