//! Random sequential addition (RSA) of non-overlapping spheres in a box: each sphere, largest
//! first, is given uniformly random centres until one neither overlaps a sphere already placed
//! (or an obstacle: particles of other sources) nor sticks out of the box. A uniform cell grid of
//! side ≥ the largest diameter makes each try O(1), so a bed of N spheres costs O(N) tries when
//! the box is far from jammed (monodisperse RSA jams at a solid fraction of ≈ 0.38, Torquato et
//! al. 2006; polydisperse a little higher).

use glam::DVec3;

use super::rng::SplitMix64;

/// Tries per sphere before insertion gives up: at a solid fraction φ a try succeeds with
/// probability ≈ the free-volume fraction, which stays above ~1e-3 until very close to jamming.
pub const ATTEMPTS_PER_SPHERE: u64 = 10_000;

/// Why not every sphere could be placed.
#[derive(Debug, Clone, PartialEq)]
pub enum InsertionError {
    /// A sphere is wider than the box along an axis.
    TooLarge {
        /// Its radius \[m\].
        radius: f64,
        /// The axis (0, 1, 2).
        axis: usize,
    },
    /// [`ATTEMPTS_PER_SPHERE`] tries in a row failed.
    Jammed {
        /// Spheres placed before giving up.
        placed: usize,
        /// Spheres asked for.
        requested: usize,
        /// Solid fraction of the box reached by the placed spheres.
        solid_fraction: f64,
    },
}

/// Uniform grid over a box, each cell listing the spheres whose centres lie in it.
struct Grid {
    origin: DVec3,
    cell: f64,
    dims: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl Grid {
    fn new(lo: DVec3, hi: DVec3, cell: f64) -> Self {
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let dims = [0, 1, 2].map(|a| (((hi[a] - lo[a]) / cell).ceil() as usize).max(1));
        Self {
            origin: lo,
            cell,
            dims,
            cells: vec![Vec::new(); dims[0] * dims[1] * dims[2]],
        }
    }

    /// Cell coordinates of a point, clamped into the grid (obstacles just outside land in the
    /// border cells, which the 27-cell search still reaches).
    fn coords(&self, x: DVec3) -> [usize; 3] {
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        [0, 1, 2].map(|a| {
            (((x[a] - self.origin[a]) / self.cell).floor().max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    fn insert(&mut self, x: DVec3, index: u32) {
        let [i, j, k] = self.coords(x);
        self.cells[(k * self.dims[1] + j) * self.dims[0] + i].push(index);
    }

    /// Calls `f` on every sphere index in the 27 cells around `x`; stops when `f` returns true.
    fn any_near(&self, x: DVec3, mut f: impl FnMut(u32) -> bool) -> bool {
        let c = self.coords(x);
        let range = |a: usize| c[a].saturating_sub(1)..=(c[a] + 1).min(self.dims[a] - 1);
        for k in range(2) {
            for j in range(1) {
                for i in range(0) {
                    let cell = &self.cells[(k * self.dims[1] + j) * self.dims[0] + i];
                    if cell.iter().any(|&s| f(s)) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Places spheres of `radii` (placed in the order given: pass them largest first) in the box
/// `[lo, hi]`, none overlapping another or an `obstacles` sphere `(centre, radius)`, each fully
/// inside the box. Returns the centres in the order of `radii`.
///
/// # Errors
/// [`InsertionError`] if a sphere does not fit the box or [`ATTEMPTS_PER_SPHERE`] tries fail.
pub fn insert_spheres(
    lo: DVec3,
    hi: DVec3,
    radii: &[f64],
    obstacles: &[(DVec3, f64)],
    rng: &mut SplitMix64,
) -> Result<Vec<DVec3>, InsertionError> {
    let largest_new = radii.iter().copied().fold(0.0, f64::max);
    // Obstacles that can touch a sphere in the box: centre within r_obstacle + r_largest of it.
    let near: Vec<(DVec3, f64)> = obstacles
        .iter()
        .copied()
        .filter(|&(x, r)| {
            let reach = DVec3::splat(r + largest_new);
            x.cmpge(lo - reach).all() && x.cmple(hi + reach).all()
        })
        .collect();
    let largest = near.iter().map(|o| o.1).fold(largest_new, f64::max);
    // Two spheres overlap only if their centres are closer than r_a + r_b ≤ 2 r_largest = one
    // cell: the 27 cells around a centre hold every candidate. Cells no smaller than the mean
    // volume per sphere keep the grid's memory O(N) for tiny spheres in a big box.
    let volume = (hi - lo).element_product();
    #[allow(clippy::cast_precision_loss)]
    let per_sphere = (volume / (radii.len() + near.len() + 1) as f64).cbrt();
    let mut grid = Grid::new(lo, hi, (2.0 * largest).max(per_sphere));
    let mut centres: Vec<DVec3> = Vec::with_capacity(near.len() + radii.len());
    let mut sphere_radii: Vec<f64> = Vec::with_capacity(near.len() + radii.len());
    for (x, r) in near {
        grid.insert(x, u32::try_from(centres.len()).expect("< 2³² spheres"));
        centres.push(x);
        sphere_radii.push(r);
    }
    let first_new = centres.len();
    for (placed, &r) in radii.iter().enumerate() {
        let (a, b) = (lo + DVec3::splat(r), hi - DVec3::splat(r));
        if let Some(axis) = (0..3).find(|&k| a[k] > b[k]) {
            return Err(InsertionError::TooLarge { radius: r, axis });
        }
        let mut found = None;
        for _ in 0..ATTEMPTS_PER_SPHERE {
            let x = DVec3::new(
                rng.uniform(a.x, b.x),
                rng.uniform(a.y, b.y),
                rng.uniform(a.z, b.z),
            );
            let blocked = grid.any_near(x, |s| {
                let reach = r + sphere_radii[s as usize];
                centres[s as usize].distance_squared(x) < reach * reach
            });
            if !blocked {
                found = Some(x);
                break;
            }
        }
        let Some(x) = found else {
            let solid: f64 = radii[..placed]
                .iter()
                .map(|r| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3))
                .sum();
            return Err(InsertionError::Jammed {
                placed,
                requested: radii.len(),
                solid_fraction: solid / volume,
            });
        };
        grid.insert(x, u32::try_from(centres.len()).expect("< 2³² spheres"));
        centres.push(x);
        sphere_radii.push(r);
    }
    Ok(centres.split_off(first_new))
}
