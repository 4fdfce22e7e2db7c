//! Neighbour search: a cell list builds a Verlet half list of candidate pairs (centre distance
//! below `r_i + r_j + skin`), rebuilt when a particle moved more than half the skin since the last
//! build. Between builds no pair can come into contact unseen, because two particles close a gap
//! of at most `skin` in total.
//!
//! # Invariants
//! * Pairs are sorted by their key `(id_lo, id_hi)` of stable particle ids, so the per-pair history
//!   (the bond state) is carried over a rebuild by a linear merge-join, whatever the particle order.
//! * Every touching pair is in the list (its distance is below `r_i + r_j`). A bond breaks at
//!   `δ_crit ≥ 0`, so a bonded pair always touches and its state is never dropped (except by a
//!   step so far beyond the stability limit that a bonded pair jumps apart by more than the skin:
//!   the bond is then dropped, as the next pair pass would break it, and the run's guards stop it).
//! * The order of pairs, and of each particle's incident pairs (the CSR `incidence`), depends only
//!   on ids and positions, never on the thread count: the force gather sums in that fixed order.

use glam::DVec3;
use rayon::prelude::*;

use crate::contact::BondState;
use crate::periodic::Periodic;

/// One entry of a particle's incident pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Incidence {
    /// Index into `NeighborList::pairs`.
    pub pair: u32,
    /// The other particle of the pair (saves a lookup in `pairs` in the per-particle passes).
    pub other: u32,
    /// True when the particle is the pair's first member (the pair result is the force on it);
    /// false when it is the second (it receives the opposite force).
    pub first: bool,
}

/// Verlet half list with CSR incidence and rebuild bookkeeping.
#[derive(Debug, Clone, Default)]
pub struct NeighborList {
    /// `[first, second]` particle indices, `id[first] < id[second]`, sorted by `(id, id)`.
    pub pairs: Vec<[u32; 2]>,
    keys: Vec<(u64, u64)>,
    /// CSR offsets: particle k's incident pairs are `incidence[offsets[k]..offsets[k + 1]]`.
    pub offsets: Vec<u32>,
    /// Incident pairs of every particle, in increasing pair index.
    pub incidence: Vec<Incidence>,
    reference_positions: Vec<DVec3>,
    skin: f64,
    periodic: Option<Periodic>,
    /// Number of builds so far.
    pub builds: u64,
}

impl NeighborList {
    /// An empty list with the given skin [m], over a domain periodic along `periodic`'s axes.
    #[must_use]
    pub fn new(skin: f64, periodic: Option<Periodic>) -> Self {
        Self {
            skin,
            periodic,
            ..Self::default()
        }
    }

    /// True when some particle moved more than half the skin since the last build (or there was none).
    #[must_use]
    pub fn needs_rebuild(&self, positions: &[DVec3]) -> bool {
        if self.reference_positions.len() != positions.len() {
            return true;
        }
        let limit = 0.25 * self.skin * self.skin;
        let moved = |(x, x0): (&DVec3, &DVec3)| (*x - *x0).length_squared() > limit;
        if crate::worth_parallel(positions.len()) {
            positions
                .par_iter()
                .zip(&self.reference_positions)
                .any(moved)
        } else {
            positions.iter().zip(&self.reference_positions).any(moved)
        }
    }

    /// Rebuilds the list and carries each pair's state over by its id key; pairs that left the
    /// list drop their state (they are not touching, so it is `Unbonded`).
    pub fn rebuild(
        &mut self,
        positions: &[DVec3],
        radii: &[f64],
        ids: &[u64],
        states: &mut Vec<BondState>,
    ) {
        self.rebuild_with_history::<()>(positions, radii, ids, states, None);
    }

    /// [`NeighborList::rebuild`], also carrying a second per-pair array (the tangential history
    /// of scenes with friction) by the same merge-join; new pairs get `T::default()`. Pairs that
    /// left the list were not touching, so their history was already reset.
    pub fn rebuild_with_history<T: Copy + Default>(
        &mut self,
        positions: &[DVec3],
        radii: &[f64],
        ids: &[u64],
        states: &mut Vec<BondState>,
        history: Option<&mut Vec<T>>,
    ) {
        let mut candidates =
            candidate_pairs(positions, radii, ids, self.skin, self.periodic.as_ref());
        candidates.par_sort_unstable_by_key(|(key, _)| *key);

        // For each new pair, its index in the old list, if it was there.
        let mut origins: Vec<Option<usize>> = Vec::with_capacity(candidates.len());
        let mut old = self.keys.iter().zip(states.iter()).enumerate().peekable();
        for (key, _) in &candidates {
            while let Some((_, (old_key, _))) = old.peek() {
                if *old_key < key {
                    // A pair that left the list was apart by more than the skin; were it bonded,
                    // it would break at the next pair pass anyway (δ < 0 ≤ δ_crit). Only a step
                    // far beyond the stability limit can do that, and the guards report it.
                    old.next();
                } else {
                    break;
                }
            }
            match old.peek() {
                Some((p, (old_key, _))) if *old_key == key => {
                    origins.push(Some(*p));
                    old.next();
                }
                _ => origins.push(None),
            }
        }
        *states = origins
            .iter()
            .map(|o| o.map_or(BondState::Unbonded, |p| states[p]))
            .collect();
        if let Some(history) = history {
            *history = origins
                .iter()
                .map(|o| o.map_or_else(T::default, |p| history[p]))
                .collect();
        }

        self.keys = candidates.iter().map(|(key, _)| *key).collect();
        self.pairs = candidates.into_iter().map(|(_, pair)| pair).collect();
        self.build_incidence(positions.len());
        self.reference_positions.clear();
        self.reference_positions.extend_from_slice(positions);
        self.builds += 1;
    }

    fn build_incidence(&mut self, particle_count: usize) {
        let mut counts = vec![0u32; particle_count + 1];
        for [a, b] in &self.pairs {
            counts[*a as usize + 1] += 1;
            counts[*b as usize + 1] += 1;
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        self.offsets = counts;
        let mut fill = self.offsets.clone();
        self.incidence = vec![
            Incidence {
                pair: 0,
                other: 0,
                first: true
            };
            self.pairs.len() * 2
        ];
        for (p, [a, b]) in self.pairs.iter().enumerate() {
            let pair = u32::try_from(p).expect("fewer than 2^32 pairs");
            for (particle, other, first) in [(*a, *b, true), (*b, *a, false)] {
                let slot = &mut fill[particle as usize];
                self.incidence[*slot as usize] = Incidence { pair, other, first };
                *slot += 1;
            }
        }
    }

    /// Incident pairs of particle `k`.
    #[must_use]
    #[inline]
    pub fn incident(&self, k: usize) -> &[Incidence] {
        &self.incidence[self.offsets[k] as usize..self.offsets[k + 1] as usize]
    }

    /// The id key `(id_lo, id_hi)` of pair `p`.
    #[must_use]
    pub fn key(&self, p: usize) -> (u64, u64) {
        self.keys[p]
    }
}

type Candidate = ((u64, u64), [u32; 2]);

/// All pairs closer than `r_i + r_j + skin`, found through a uniform cell grid of edge
/// `2 r_max + skin`: a pair within the cutoff lies in the same or an adjacent cell. Cells are found
/// by sorting the particles by cell (no dense grid), so stray particles far away cost no memory.
fn candidate_pairs(
    positions: &[DVec3],
    radii: &[f64],
    ids: &[u64],
    skin: f64,
    periodic: Option<&Periodic>,
) -> Vec<Candidate> {
    if positions.is_empty() {
        return Vec::new();
    }
    let r_max = radii.iter().copied().fold(0.0, f64::max);
    let cell = 2.0 * r_max + skin;
    let origin = positions
        .iter()
        .copied()
        .fold(DVec3::splat(f64::INFINITY), DVec3::min)
        .to_array();
    // Per axis: where cell 0 starts, the cell size, and on a periodic axis the number of cells
    // across the period (≥ 3, checked when the model is built), so neighbour cells wrap around.
    let mut grid = [(0.0, cell, None::<i64>); 3];
    for (axis, g) in grid.iter_mut().enumerate() {
        *g = match periodic.and_then(|p| p.length[axis].map(|l| (p.lower.to_array()[axis], l))) {
            #[allow(clippy::cast_possible_truncation)]
            Some((lower, length)) => {
                let count = ((length / cell).floor() as i64).max(1);
                #[allow(clippy::cast_precision_loss)]
                let size = length / count as f64;
                (lower, size, Some(count))
            }
            None => (origin[axis], cell, None),
        };
    }
    #[allow(clippy::cast_possible_truncation)]
    let cell_of = |x: DVec3| -> [i64; 3] {
        let x = x.to_array();
        let mut c = [0i64; 3];
        for axis in 0..3 {
            let (start, size, count) = grid[axis];
            let index = ((x[axis] - start) / size).floor() as i64;
            c[axis] = count.map_or(index, |n| index.rem_euclid(n));
        }
        c
    };
    let neighbour_cell = |c: [i64; 3], offset: [i64; 3]| -> [i64; 3] {
        let mut n = [0i64; 3];
        for axis in 0..3 {
            let shifted = c[axis] + offset[axis];
            n[axis] = grid[axis]
                .2
                .map_or(shifted, |count| shifted.rem_euclid(count));
        }
        n
    };
    let separation = |i: usize, j: usize| {
        let d = positions[j] - positions[i];
        periodic.map_or(d, |p| p.minimum_image(d))
    };
    let mut order: Vec<([i64; 3], u32)> = positions
        .iter()
        .enumerate()
        .map(|(k, x)| {
            (
                cell_of(*x),
                u32::try_from(k).expect("fewer than 2^32 particles"),
            )
        })
        .collect();
    order.par_sort_unstable();
    // Distinct cells with the start of their run in `order`.
    let mut cells: Vec<([i64; 3], usize)> = Vec::new();
    for (k, (c, _)) in order.iter().enumerate() {
        if cells.last().is_none_or(|(last, _)| last != c) {
            cells.push((*c, k));
        }
    }
    let members = |c: [i64; 3]| -> &[([i64; 3], u32)] {
        match cells.binary_search_by(|(key, _)| key.cmp(&c)) {
            Ok(pos) => {
                let start = cells[pos].1;
                let end = cells.get(pos + 1).map_or(order.len(), |(_, s)| *s);
                &order[start..end]
            }
            Err(_) => &[],
        }
    };

    (0..positions.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let c = cell_of(positions[i]);
            let mut found = Vec::new();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        for &(_, j) in members(neighbour_cell(c, [dx, dy, dz])) {
                            let j = j as usize;
                            if j <= i {
                                continue;
                            }
                            let cutoff = radii[i] + radii[j] + skin;
                            if separation(i, j).length_squared() < cutoff * cutoff {
                                #[allow(clippy::cast_possible_truncation)]
                                let (a, b) = if ids[i] < ids[j] {
                                    (i as u32, j as u32)
                                } else {
                                    (j as u32, i as u32)
                                };
                                found.push(((ids[a as usize], ids[b as usize]), [a, b]));
                            }
                        }
                    }
                }
            }
            found
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_exactly_the_pairs_within_the_cutoff() {
        // A 5×5×5 jittered cloud, checked against the O(n²) definition.
        let mut positions = Vec::new();
        let mut seed = 1u64;
        for k in 0..125u32 {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            #[allow(clippy::cast_precision_loss)]
            let jitter = (seed >> 40) as f64 / (1u64 << 24) as f64 * 0.5;
            positions.push(
                DVec3::new(f64::from(k % 5), f64::from((k / 5) % 5), f64::from(k / 25)) * 1.9
                    + DVec3::splat(jitter),
            );
        }
        let radii = vec![1.0; positions.len()];
        let ids: Vec<u64> = (0..positions.len() as u64).rev().collect(); // ids opposite to indices
        let mut list = NeighborList::new(0.3, None);
        let mut states = Vec::new();
        list.rebuild(&positions, &radii, &ids, &mut states);
        let mut expected = 0;
        for i in 0..positions.len() {
            for j in i + 1..positions.len() {
                if positions[i].distance(positions[j]) < 2.3 {
                    expected += 1;
                }
            }
        }
        assert_eq!(list.pairs.len(), expected);
        assert!(list.keys.windows(2).all(|w| w[0] < w[1]));
        for [a, b] in &list.pairs {
            assert!(ids[*a as usize] < ids[*b as usize]);
        }
        assert_eq!(list.incidence.len(), 2 * expected);
    }

    #[test]
    fn finds_exactly_the_minimum_image_pairs_in_a_periodic_box() {
        // 300 random spheres of radius 1 in a box periodic in x (period 9.3, four cells) and y
        // (period 7.0, three cells: the smallest allowed), open in z: the list must equal the O(n²)
        // definition with minimum-image distances, including pairs across the faces.
        let periodic = Periodic {
            lower: DVec3::new(-2.0, 1.0, 0.0),
            length: [Some(9.3), Some(7.0), None],
        };
        let mut seed = 7u64;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            #[allow(clippy::cast_precision_loss)]
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            u
        };
        let positions: Vec<DVec3> = (0..300)
            .map(|_| {
                DVec3::new(
                    -2.0 + 9.3 * uniform(),
                    1.0 + 7.0 * uniform(),
                    12.0 * uniform(),
                )
            })
            .collect();
        let radii = vec![1.0; positions.len()];
        let ids: Vec<u64> = (0..positions.len() as u64).collect();
        let mut list = NeighborList::new(0.3, Some(periodic));
        list.rebuild(&positions, &radii, &ids, &mut Vec::new());
        let mut expected = Vec::new();
        let mut across = 0;
        for i in 0..positions.len() {
            for j in i + 1..positions.len() {
                let d = positions[j] - positions[i];
                if periodic.minimum_image(d).length() < 2.3 {
                    expected.push((ids[i], ids[j]));
                    across += usize::from(d.length() >= 2.3);
                }
            }
        }
        assert!(
            across > 10,
            "the case must have pairs across the faces ({across})"
        );
        assert_eq!(list.keys, expected);
    }

    #[test]
    fn history_follows_the_pair_across_rebuilds() {
        let mut positions = vec![DVec3::ZERO, DVec3::X * 1.9, DVec3::X * 10.0];
        let radii = vec![1.0; 3];
        let ids = vec![7, 3, 5];
        let mut list = NeighborList::new(0.5, None);
        let (mut states, mut history) = (Vec::new(), Vec::new());
        list.rebuild_with_history(&positions, &radii, &ids, &mut states, Some(&mut history));
        history[0] = 42u32;
        positions[2] = DVec3::new(-1.9, 0.0, 0.0);
        list.rebuild_with_history(&positions, &radii, &ids, &mut states, Some(&mut history));
        let kept = list.keys.iter().position(|k| *k == (3, 7)).unwrap();
        assert_eq!(history[kept], 42);
        assert_eq!(history[1 - kept], 0);
    }

    #[test]
    fn bond_state_follows_the_pair_across_rebuilds() {
        let mut positions = vec![DVec3::ZERO, DVec3::X * 1.9, DVec3::X * 10.0];
        let radii = vec![1.0; 3];
        let ids = vec![7, 3, 5];
        let mut list = NeighborList::new(0.5, None);
        let mut states = Vec::new();
        list.rebuild(&positions, &radii, &ids, &mut states);
        assert_eq!(list.pairs, vec![[1, 0]]);
        states[0] = BondState::Bonded;
        // A new pair (ids 5 and 7) appears in front of the old one in key order.
        positions[2] = DVec3::new(-1.9, 0.0, 0.0);
        list.rebuild(&positions, &radii, &ids, &mut states);
        assert_eq!(list.pairs.len(), 2);
        let bonded = list.keys.iter().position(|k| *k == (3, 7)).unwrap();
        assert_eq!(states[bonded], BondState::Bonded);
        assert_eq!(states[1 - bonded], BondState::Unbonded);
    }
}
