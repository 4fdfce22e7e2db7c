//! A moving Gaussian laser beam shining down the −z axis, and the power each particle absorbs.
//!
//! Intensity (M.50): `I(ρ) = 2P/(π w²) · exp(−2 ρ²/w²)` [W/m²], ρ the distance from the beam axis,
//! w the 1/e² radius. A particle absorbs `α` times the beam power falling on the part of its
//! projected disk that no particle above it covers (M.51).
//!
//! # Absorption: exact disk integral × visible fraction (M.51)
//! * The beam power falling on a particle's projected disk is integrated exactly over the disk
//!   (not taken at its centre: spot and particle sizes are comparable), by [`disk_fraction`].
//! * Which part of the disk the beam reaches is found by ray casting: the window `±3w` around the
//!   axis (all but e⁻¹⁸ ≈ 1.5e-8 of the power) is cut into square cells of side `h`; a vertical
//!   ray through each cell centre hits the sphere whose surface is highest there. The visible
//!   fraction of particle k is the beam power of the cells where k is hit over that of all cells
//!   whose rays cross k's disk (both weighted by the exact power of each cell). A particle fully
//!   under another gets 0; an unshadowed one gets exactly 1, so a flat layer absorbs exactly
//!   `α P` times the fraction of the beam its disks intercept, whatever `h`. The rays are cast
//!   disk by disk (`Raster`): each disk visits only the cells of its bounding square.
//! * Should the discretised fractions ever add up to more than the whole beam (disks overlapping in
//!   projection), all powers are scaled down: the total never exceeds `max α · P`.

use std::ops::Range;

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::particles::Particles;

/// One straight piece of the scan path, travelled at constant speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Start point (x, y) \[m\].
    pub from: DVec2,
    /// End point (x, y) \[m\].
    pub to: DVec2,
    /// Time at which the beam is at `from` \[s\].
    pub start: f64,
    /// Time to travel the segment \[s\].
    pub duration: f64,
    /// Whether the laser is on along it (false for jumps between hatch tracks).
    pub on: bool,
}

/// The laser: power, spot and path.
#[derive(Debug, Clone, PartialEq)]
pub struct Laser {
    /// Beam power P \[W\].
    pub power: f64,
    /// 1/e² radius w \[m\].
    pub spot_radius: f64,
    /// Raster cell side h \[m\].
    pub raster_cell: f64,
    /// The scan path, in time order.
    pub path: Vec<Segment>,
}

impl Laser {
    /// Beam axis position at time `t` \[s\], or `None` when the laser is off.
    #[must_use]
    pub fn beam_at(&self, t: f64) -> Option<DVec2> {
        let segment = self
            .path
            .iter()
            .find(|s| t >= s.start && t < s.start + s.duration)?;
        if !segment.on {
            return None;
        }
        let fraction = if segment.duration > 0.0 {
            (t - segment.start) / segment.duration
        } else {
            0.0
        };
        Some(segment.from.lerp(segment.to, fraction))
    }

    /// Time at which the path ends \[s\].
    #[must_use]
    pub fn end_time(&self) -> f64 {
        self.path.last().map_or(0.0, |s| s.start + s.duration)
    }

    /// Fraction of the beam power falling on `[lo, hi)` along one axis, the beam axis at `centre`:
    /// the Gaussian's marginal is normal with σ = w/2, so it is `½ [erf(√2 (hi−c)/w) − erf(√2 (lo−c)/w)]`.
    fn axis_share(&self, lo: f64, hi: f64, centre: f64) -> f64 {
        let s = std::f64::consts::SQRT_2 / self.spot_radius;
        0.5 * (libm::erf(s * (hi - centre)) - libm::erf(s * (lo - centre)))
    }

    /// Laser power absorbed by every particle with the beam axis at `beam` (M.51) \[W\], written
    /// into `power` (zeroed first). `absorptivity(k)` is particle k's absorptivity. Returns the
    /// particles inside the beam window (the only ones whose motion can change the result).
    pub fn absorb(
        &self,
        beam: DVec2,
        particles: &Particles,
        absorptivity: impl Fn(usize) -> f64 + Sync,
        power: &mut [f64],
    ) -> Vec<usize> {
        power.fill(0.0);
        let reach = 3.0 * self.spot_radius;
        let lit: Vec<usize> = (0..particles.len())
            .filter(|&k| {
                let x = particles.position[k];
                let r = particles.radius[k];
                (x.x - beam.x).abs() < reach + r && (x.y - beam.y).abs() < reach + r
            })
            .collect();
        if lit.is_empty() {
            return lit;
        }
        let disks: Vec<Disk> = lit
            .iter()
            .map(|&k| Disk {
                centre: particles.position[k],
                radius: particles.radius[k],
            })
            .collect();
        let raster = Raster::new(self, beam, reach);
        // Each disk's cells, found once for both passes (their roundings are calls to `floor`
        // and `ceil` in a generic x86-64 build).
        let cells: Vec<Cells> = disks.iter().map(|disk| raster.bounds(disk)).collect();
        let parallel = crate::worth_parallel(raster.cells * raster.cells);
        let top = raster.highest_disks(&disks, &cells, parallel);
        // Each disk's (crossed, hit) cell power, summed over its cells in raster order.
        let seen = |slot: usize| raster.crossed_and_hit(&disks[slot], &cells[slot], slot, &top);
        let sums: Vec<(f64, f64)> = if parallel {
            (0..disks.len()).into_par_iter().map(seen).collect()
        } else {
            (0..disks.len()).map(seen).collect()
        };
        let mut fractions: Vec<f64> = disks
            .iter()
            .zip(&sums)
            .enumerate()
            .map(|(slot, (disk, &(crossed, hit)))| {
                let share = if crossed > 0.0 {
                    hit / crossed
                } else if highest_at(&disks, disk.centre.truncate()) == Some(slot) {
                    // No ray crossed this (small) disk: one ray at its centre decides.
                    1.0
                } else {
                    0.0
                };
                share
                    * disk_fraction(
                        disk.centre.truncate().distance(beam),
                        disk.radius,
                        self.spot_radius,
                    )
            })
            .collect();
        let total: f64 = fractions.iter().sum();
        if total > 1.0 {
            fractions.iter_mut().for_each(|f| *f /= total);
        }
        for (&k, f) in lit.iter().zip(&fractions) {
            power[k] = absorptivity(k) * self.power * f;
        }
        lit
    }
}

/// A lit particle's projected disk: its centre \[m\] and radius \[m\].
struct Disk {
    centre: DVec3,
    radius: f64,
}

impl Disk {
    /// `ρ²` \[m²\], the squared distance of `ray` from the disk's centre, if the ray crosses the
    /// disk (`ρ < r`).
    #[inline]
    fn crossing(&self, ray: DVec2) -> Option<f64> {
        let rho2 = (ray - self.centre.truncate()).length_squared();
        (rho2 < self.radius * self.radius).then_some(rho2)
    }

    /// The height \[m\] of the sphere's surface above `ray`, if the ray crosses the disk.
    #[inline]
    fn surface_above(&self, ray: DVec2) -> Option<f64> {
        self.crossing(ray)
            .map(|rho2| self.centre.z + (self.radius * self.radius - rho2).sqrt())
    }
}

/// The raster's rows and columns whose rays may cross a disk ([`Raster::bounds`]).
type Cells = (Range<usize>, Range<usize>);

/// The disk (slot) whose surface is highest above `ray`: the first in slot order on ties.
fn highest_at(disks: &[Disk], ray: DVec2) -> Option<usize> {
    let mut top: Option<(usize, f64)> = None;
    for (slot, disk) in disks.iter().enumerate() {
        if let Some(height) = disk.surface_above(ray) {
            if top.is_none_or(|(_, z)| height > z) {
                top = Some((slot, height));
            }
        }
    }
    top.map(|(slot, _)| slot)
}

/// The ray-casting raster: `cells × cells` square cells of side `h` covering the beam window,
/// a vertical ray through each cell's centre, and the beam's exact power share of each row and
/// column (M.51).
///
/// The rays are cast disk by disk rather than ray by ray: each disk visits only the cells of
/// its bounding square, first to leave in every cell the disk whose surface is highest there
/// ([`Raster::highest_disks`]), then to sum the power of the cells it crosses and of those
/// where it is the highest ([`Raster::crossed_and_hit`]). A cell's ray and every test on it are
/// the same as a ray-by-ray cast's, and each disk sums its cells in raster order, so the result
/// is the same to the bit; what goes is the search for the disks a ray crosses.
struct Raster {
    /// Corner of cell (0, 0) \[m\].
    start: DVec2,
    /// Cell side h \[m\].
    h: f64,
    /// Cells per side.
    cells: usize,
    /// The beam's share of each row, along y.
    row_shares: Vec<f64>,
    /// The beam's share of each column, along x.
    column_shares: Vec<f64>,
}

/// No disk crosses the cell's ray.
const NO_DISK: u32 = u32::MAX;

/// Rows of the raster per parallel task of [`Raster::highest_disks`].
const ROWS_PER_BAND: usize = 8;

impl Raster {
    fn new(laser: &Laser, beam: DVec2, reach: f64) -> Self {
        let h = laser.raster_cell;
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let cells = ((2.0 * reach) / h).ceil() as usize;
        #[allow(clippy::cast_precision_loss)]
        let start = beam - DVec2::splat(0.5 * cells as f64 * h);
        // Each row's and column's share, taken once, not once per cell (two `erf` per cell were
        // half of the absorption's time).
        let shares = |lo: f64, centre: f64| -> Vec<f64> {
            (0..cells)
                .map(|i| {
                    #[allow(clippy::cast_precision_loss)]
                    let edge = lo + i as f64 * h;
                    laser.axis_share(edge, edge + h, centre)
                })
                .collect()
        };
        Self {
            start,
            h,
            cells,
            row_shares: shares(start.y, beam.y),
            column_shares: shares(start.x, beam.x),
        }
    }

    /// The centre of cell (`row`, `col`), where its ray falls \[m\].
    #[inline]
    fn ray(&self, row: usize, col: usize) -> DVec2 {
        #[allow(clippy::cast_precision_loss)]
        let corner = DVec2::new(
            self.start.x + col as f64 * self.h,
            self.start.y + row as f64 * self.h,
        );
        corner + DVec2::splat(0.5 * self.h)
    }

    /// The cells (rows, columns) whose rays may cross `disk`: its bounding square, widened by a
    /// cell so that rounding never leaves one out (the test on each ray decides).
    fn bounds(&self, disk: &Disk) -> Cells {
        let span = |centre: f64, start: f64| -> Range<usize> {
            let lo = ((centre - disk.radius - start) / self.h - 0.5).floor() - 1.0;
            let hi = ((centre + disk.radius - start) / self.h - 0.5).ceil() + 1.0;
            #[allow(clippy::cast_precision_loss)]
            let last = (self.cells - 1) as f64;
            if hi < 0.0 || lo > last {
                return 0..0;
            }
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let range = (lo.max(0.0) as usize)..(hi.min(last) as usize + 1);
            range
        };
        (
            span(disk.centre.y, self.start.y),
            span(disk.centre.x, self.start.x),
        )
    }

    /// For every cell (row-major), the slot of the disk whose surface is highest above its ray
    /// (the first in slot order on ties, as a ray testing the disks in that order finds it), or
    /// [`NO_DISK`]. Parallel over bands of rows, each disk taken in slot order in every band, so
    /// the result does not depend on the thread count.
    fn highest_disks(&self, disks: &[Disk], cells_of: &[Cells], parallel: bool) -> Vec<u32> {
        let cells = self.cells;
        let mut top = vec![NO_DISK; cells * cells];
        let band = |(index, slots): (usize, &mut [u32])| {
            let first_row = index * ROWS_PER_BAND;
            let band_rows = first_row..first_row + slots.len() / cells;
            let mut heights = vec![f64::NEG_INFINITY; slots.len()];
            for (slot, (disk, (rows, cols))) in disks.iter().zip(cells_of).enumerate() {
                let slot = u32::try_from(slot).expect("fewer than 2^32 lit particles");
                for row in rows.start.max(band_rows.start)..rows.end.min(band_rows.end) {
                    for col in cols.clone() {
                        let Some(height) = disk.surface_above(self.ray(row, col)) else {
                            continue;
                        };
                        let cell = (row - first_row) * cells + col;
                        if slots[cell] == NO_DISK || height > heights[cell] {
                            slots[cell] = slot;
                            heights[cell] = height;
                        }
                    }
                }
            }
        };
        if parallel {
            top.par_chunks_mut(ROWS_PER_BAND * cells)
                .enumerate()
                .for_each(band);
        } else {
            top.chunks_mut(ROWS_PER_BAND * cells)
                .enumerate()
                .for_each(band);
        }
        top
    }

    /// The beam power of the cells whose rays cross `disk` and of those where `disk` (at
    /// `slot`) is the highest, each summed in raster order.
    fn crossed_and_hit(&self, disk: &Disk, cells: &Cells, slot: usize, top: &[u32]) -> (f64, f64) {
        let (rows, cols) = cells;
        let (mut crossed, mut hit) = (0.0, 0.0);
        for row in rows.clone() {
            let share_y = self.row_shares[row];
            for col in cols.clone() {
                if disk.crossing(self.ray(row, col)).is_none() {
                    continue;
                }
                let cell_power = share_y * self.column_shares[col];
                crossed += cell_power;
                if top[row * self.cells + col] as usize == slot {
                    hit += cell_power;
                }
            }
        }
        (crossed, hit)
    }
}

/// Fraction of a Gaussian beam (1/e² radius `w`) falling on a disk of radius `r` whose centre is
/// `d` from the beam axis (M.54):
///
/// ```text
/// F = (4/w²) ∫₀ʳ ρ exp(−2(ρ² + d²)/w²) I₀(4ρd/w²) dρ
/// ```
///
/// (the angular integral of the offset Gaussian is 2π e^{…} I₀). Composite 8-point Gauss–Legendre
/// in ρ, one panel per half spot radius, with the exponentially scaled I₀ so nothing overflows.
#[must_use]
pub fn disk_fraction(d: f64, r: f64, w: f64) -> f64 {
    const NODES: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const WEIGHTS: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let integrand = |rho: f64| {
        let x = 4.0 * rho * d / (w * w);
        // exp(−2(ρ² + d²)/w²) I₀(x) = exp(−2(ρ − d)²/w²) · e^{−x} I₀(x)
        rho * (-2.0 * (rho - d) * (rho - d) / (w * w)).exp() * scaled_bessel_i0(x)
    };
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let panels = ((2.0 * r / w).ceil() as usize).max(1);
    #[allow(clippy::cast_precision_loss)]
    let width = r / panels as f64;
    let mut sum = 0.0;
    for p in 0..panels {
        #[allow(clippy::cast_precision_loss)]
        let mid = (p as f64 + 0.5) * width;
        for (node, weight) in NODES.iter().zip(WEIGHTS) {
            let offset = 0.5 * width * node;
            sum += weight * 0.5 * width * (integrand(mid - offset) + integrand(mid + offset));
        }
    }
    4.0 / (w * w) * sum
}

/// `e^{−x} I₀(x)` for `x ≥ 0`, Abramowitz & Stegun 9.8.1-9.8.2 (relative error < 2e-7).
#[must_use]
pub fn scaled_bessel_i0(x: f64) -> f64 {
    if x < 3.75 {
        let t = (x / 3.75).powi(2);
        let i0 = 1.0
            + t * (3.515_622_9
                + t * (3.089_942_4
                    + t * (1.206_749_2 + t * (0.265_973_2 + t * (0.036_076_8 + t * 0.004_581_3)))));
        i0 * (-x).exp()
    } else {
        let t = 3.75 / x;
        let poly = 0.398_942_28
            + t * (0.013_285_92
                + t * (0.002_253_19
                    + t * (-0.001_575_65
                        + t * (0.009_162_81
                            + t * (-0.020_577_06
                                + t * (0.026_355_37 + t * (-0.016_476_33 + t * 0.003_923_77)))))));
        poly / x.sqrt()
    }
}

/// The state in which absorbed powers were last computed. While neither the beam nor any lit
/// particle has moved by more than half a ray-casting cell, a new ray cast would change the
/// result by less than its own discretisation error, so it is skipped (the beam moves `v dt`, some
/// 50 nm, per step: a cast every ~15 steps instead of every step).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    /// Beam axis at the last cast (`None`: laser off).
    pub beam: Option<DVec2>,
    /// Lit particles (index) and their positions at the last cast \[m\].
    pub lit: Vec<(usize, DVec3)>,
}

impl Snapshot {
    /// Whether powers computed in this snapshot still hold for `beam` and the current positions.
    #[must_use]
    pub fn still_valid(&self, beam: Option<DVec2>, particles: &Particles, cell: f64) -> bool {
        let tolerance = 0.5 * cell;
        match (self.beam, beam) {
            (None, None) => true,
            (Some(old), Some(new)) => {
                old.distance_squared(new) <= tolerance * tolerance
                    && self.lit.iter().all(|(k, x)| {
                        particles.position[*k].distance_squared(*x) <= tolerance * tolerance
                    })
            }
            _ => false,
        }
    }

    /// Follows the particles to their new indices (`new[i] = old[order[i]]`); if a lit particle
    /// was dropped, the snapshot is cleared and the next step casts again.
    pub fn renumber(&mut self, order: &[u32]) {
        if self.lit.is_empty() {
            return;
        }
        let mut new_index =
            vec![usize::MAX; order.iter().map(|&k| k as usize + 1).max().unwrap_or(0)];
        for (new, &old) in order.iter().enumerate() {
            new_index[old as usize] = new;
        }
        let renumbered: Option<Vec<(usize, DVec3)>> = self
            .lit
            .iter()
            .map(|&(k, x)| {
                new_index
                    .get(k)
                    .copied()
                    .filter(|n| *n != usize::MAX)
                    .map(|n| (n, x))
            })
            .collect();
        match renumbered {
            Some(lit) => self.lit = lit,
            None => *self = Self::default(),
        }
    }

    /// Records the state of a new ray cast.
    pub fn record(&mut self, beam: Option<DVec2>, lit: &[usize], particles: &Particles) {
        self.beam = beam;
        self.lit.clear();
        self.lit
            .extend(lit.iter().map(|&k| (k, particles.position[k])));
    }
}

/// Builds the segments of a polyline path through `points` at `speed` [m/s], from `start` \[s\].
#[must_use]
pub fn polyline(points: &[DVec2], speed: f64, start: f64) -> Vec<Segment> {
    let mut t = start;
    points
        .windows(2)
        .map(|w| {
            let duration = w[0].distance(w[1]) / speed;
            let s = Segment {
                from: w[0],
                to: w[1],
                start: t,
                duration,
                on: true,
            };
            t += duration;
            s
        })
        .collect()
}

/// A hatch pattern (M.52): parallel tracks in alternating directions (a meander).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hatch {
    /// Start of the first track (x, y) \[m\].
    pub origin: DVec2,
    /// Track length \[m\].
    pub length: f64,
    /// Distance between tracks \[m\].
    pub spacing: f64,
    /// Number of tracks.
    pub tracks: u32,
    /// Tracks along x (true) or y (false); they step along the other axis.
    pub along_x: bool,
    /// Scan speed [m/s].
    pub speed: f64,
    /// Time with the laser off to reach the next track \[s\].
    pub jump_time: f64,
}

impl Hatch {
    /// The segments of the pattern, starting at time `start` \[s\].
    #[must_use]
    pub fn segments(&self, start: f64) -> Vec<Segment> {
        let (along, across) = if self.along_x {
            (DVec2::X, DVec2::Y)
        } else {
            (DVec2::Y, DVec2::X)
        };
        let mut segments: Vec<Segment> = Vec::new();
        let mut t = start;
        for k in 0..self.tracks {
            let base = self.origin + f64::from(k) * self.spacing * across;
            let end = base + self.length * along;
            let (from, to) = if k % 2 == 0 { (base, end) } else { (end, base) };
            if let Some(previous) = segments.last() {
                let jump = Segment {
                    from: previous.to,
                    to: from,
                    start: t,
                    duration: self.jump_time,
                    on: false,
                };
                segments.push(jump);
                t += self.jump_time;
            }
            let duration = self.length / self.speed;
            segments.push(Segment {
                from,
                to,
                start: t,
                duration,
                on: true,
            });
            t += duration;
        }
        segments
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The absorbed powers of a plain ray-by-ray cast (M.51): every ray tests every lit disk in
    /// index order and keeps the first of the highest; each particle sums its cells in raster
    /// order. Slow and direct: the reference for [`Laser::absorb`]'s disk-by-disk cast.
    fn absorb_ray_by_ray(laser: &Laser, beam: DVec2, p: &Particles, alpha: f64) -> Vec<f64> {
        let reach = 3.0 * laser.spot_radius;
        let lit: Vec<usize> = (0..p.len())
            .filter(|&k| {
                let (x, r) = (p.position[k], p.radius[k]);
                (x.x - beam.x).abs() < reach + r && (x.y - beam.y).abs() < reach + r
            })
            .collect();
        let h = laser.raster_cell;
        let cells = ((2.0 * reach) / h).ceil() as usize;
        let start = beam - DVec2::splat(0.5 * cells as f64 * h);
        let highest = |ray: DVec2| -> Option<usize> {
            let mut top: Option<(usize, f64)> = None;
            for &k in &lit {
                let (centre, r) = (p.position[k], p.radius[k]);
                let rho2 = (ray - centre.truncate()).length_squared();
                if rho2 < r * r {
                    let height = centre.z + (r * r - rho2).sqrt();
                    if top.is_none_or(|(_, z)| height > z) {
                        top = Some((k, height));
                    }
                }
            }
            top.map(|(k, _)| k)
        };
        let (mut crossed, mut hit) = (vec![0.0; p.len()], vec![0.0; p.len()]);
        for row in 0..cells {
            let y_lo = start.y + row as f64 * h;
            let share_y = laser.axis_share(y_lo, y_lo + h, beam.y);
            for col in 0..cells {
                let x_lo = start.x + col as f64 * h;
                let ray = DVec2::new(x_lo + 0.5 * h, y_lo + 0.5 * h);
                let cell_power = share_y * laser.axis_share(x_lo, x_lo + h, beam.x);
                for &k in &lit {
                    let rho2 = (ray - p.position[k].truncate()).length_squared();
                    if rho2 < p.radius[k] * p.radius[k] {
                        crossed[k] += cell_power;
                    }
                }
                if let Some(k) = highest(ray) {
                    hit[k] += cell_power;
                }
            }
        }
        let mut fractions: Vec<f64> = lit
            .iter()
            .map(|&k| {
                let centre = p.position[k].truncate();
                let share = if crossed[k] > 0.0 {
                    hit[k] / crossed[k]
                } else if highest(centre) == Some(k) {
                    1.0
                } else {
                    0.0
                };
                share * disk_fraction(centre.distance(beam), p.radius[k], laser.spot_radius)
            })
            .collect();
        let total: f64 = fractions.iter().sum();
        if total > 1.0 {
            fractions.iter_mut().for_each(|f| *f /= total);
        }
        let mut power = vec![0.0; p.len()];
        for (&k, f) in lit.iter().zip(&fractions) {
            power[k] = alpha * laser.power * f;
        }
        power
    }

    /// A random pile around the beam, some disks reaching out of the window, some smaller than
    /// a raster cell, and two spheres at the very same place (a tie in every ray).
    fn random_pile(count: usize, seed: u64) -> Particles {
        let mut random = crate::bed::rng::SplitMix64(seed);
        let mut p = Particles::default();
        for i in 0..count {
            let radius = if i % 17 == 0 {
                0.4e-6
            } else {
                random.uniform(7.5e-6, 3.0e-5)
            };
            let init = crate::particles::ParticleInit {
                position: DVec3::new(
                    random.uniform(-1.5e-4, 1.5e-4),
                    random.uniform(-1.5e-4, 1.5e-4),
                    random.uniform(0.0, 1.0e-4),
                ),
                velocity: DVec3::ZERO,
                radius,
                material: 0,
            };
            p.push(init, 7950.0);
        }
        let twin = crate::particles::ParticleInit {
            position: DVec3::new(1.0e-5, -2.0e-5, 2.0e-4),
            velocity: DVec3::ZERO,
            radius: 2.0e-5,
            material: 0,
        };
        p.push(twin, 7950.0);
        p.push(twin, 7950.0);
        p
    }

    #[test]
    fn disk_by_disk_cast_gives_the_ray_by_ray_powers_to_the_bit() {
        // The fine raster casts in parallel bands, the coarse one (24² cells) serially.
        for (cell, seed) in [(2.0e-6, 1), (2.0e-6, 2), (1.0e-5, 3), (1.0e-5, 4)] {
            let laser = Laser {
                power: 40.0,
                spot_radius: 4.0e-5,
                raster_cell: cell,
                path: Vec::new(),
            };
            let p = random_pile(400, seed);
            let beam = DVec2::new(3.0e-6, -7.0e-6);
            let mut power = vec![f64::NAN; p.len()];
            let lit = laser.absorb(beam, &p, |_| 0.6, &mut power);
            let reference = absorb_ray_by_ray(&laser, beam, &p, 0.6);
            assert!(lit.len() > 100 && lit.len() < p.len(), "{} lit", lit.len());
            for (k, (a, b)) in power.iter().zip(&reference).enumerate() {
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "particle {k}: {a:e} against {b:e}"
                );
            }
            // The twins tie in every ray: the first (lower index) takes the light, the second
            // none, and something is absorbed at all.
            let twins = p.len() - 2;
            assert!(power[twins] > 0.0 && power[twins + 1] == 0.0);
        }
    }

    #[test]
    fn centred_disk_fraction_has_a_closed_form() {
        // d = 0: F = 1 − exp(−2 r²/w²).
        for (r, w) in [(1.5e-5_f64, 4e-5_f64), (1.5e-5, 5e-6), (3e-5, 1e-4)] {
            let exact = 1.0 - (-2.0 * r * r / (w * w)).exp();
            assert!(
                (disk_fraction(0.0, r, w) / exact - 1.0).abs() < 1e-6,
                "r = {r}, w = {w}"
            );
        }
    }

    #[test]
    fn offset_disk_fraction_matches_a_brute_force_integral() {
        let (r, w) = (1.5e-5, 3e-5);
        for d in [1e-5, 3e-5, 6e-5] {
            let n = 400;
            let mut sum = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let x = -r + (f64::from(i) + 0.5) * 2.0 * r / f64::from(n);
                    let y = -r + (f64::from(j) + 0.5) * 2.0 * r / f64::from(n);
                    if x * x + y * y < r * r {
                        sum += (-2.0 * ((x + d).powi(2) + y * y) / (w * w)).exp();
                    }
                }
            }
            let brute =
                2.0 / (std::f64::consts::PI * w * w) * sum * (2.0 * r / f64::from(n)).powi(2);
            assert!(
                (disk_fraction(d, r, w) / brute - 1.0).abs() < 2e-3,
                "d = {d}"
            );
        }
    }

    #[test]
    fn hatch_alternates_and_jumps_with_the_laser_off() {
        let hatch = Hatch {
            origin: DVec2::ZERO,
            length: 1e-3,
            spacing: 1e-4,
            tracks: 3,
            along_x: true,
            speed: 0.5,
            jump_time: 1e-4,
        };
        let segments = hatch.segments(1e-3);
        assert_eq!(segments.len(), 5);
        assert_eq!(
            (segments[0].from, segments[0].to),
            (DVec2::ZERO, DVec2::new(1e-3, 0.0))
        );
        assert_eq!(
            (segments[2].from, segments[2].to),
            (DVec2::new(1e-3, 1e-4), DVec2::new(0.0, 1e-4))
        );
        assert!(!segments[1].on && segments[2].on);
        let laser = Laser {
            power: 1.0,
            spot_radius: 1e-5,
            raster_cell: 1e-6,
            path: segments,
        };
        assert_eq!(laser.beam_at(0.5e-3), None, "before the start");
        assert!((laser.beam_at(2e-3).unwrap() - DVec2::new(0.5e-3, 0.0)).length() < 1e-12);
        assert_eq!(laser.beam_at(3.05e-3), None, "jumping");
        assert!((laser.end_time() - (1e-3 + 3.0 * 2e-3 + 2.0 * 1e-4)).abs() < 1e-15);
    }
}
