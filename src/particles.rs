//! Particle state as a structure of arrays: one `Vec` per field, all of the same length, so a pass
//! borrows only the fields it needs and each field maps one-to-one onto an output dataset.
//! SI units: m, m/s, kg, N.

use glam::DVec3;

use crate::wall_history::WallSprings;

/// Everything needed to add one particle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleInit {
    /// Centre \[m\].
    pub position: DVec3,
    /// Velocity [m/s].
    pub velocity: DVec3,
    /// Radius \[m\].
    pub radius: f64,
    /// Index into `Model::materials`.
    pub material: u16,
}

/// All particles. Index `k` of every field belongs to the same particle.
#[derive(Debug, Clone, Default)]
pub struct Particles {
    /// Stable id (0-based, in scene order); pair history is keyed by ids, never by indices.
    pub id: Vec<u64>,
    /// Index into `Model::materials`.
    pub material: Vec<u16>,
    /// Radius \[m\].
    pub radius: Vec<f64>,
    /// Mass \[kg\].
    pub mass: Vec<f64>,
    /// Centre \[m\].
    pub position: Vec<DVec3>,
    /// Velocity [m/s].
    pub velocity: Vec<DVec3>,
    /// Total force at the current positions \[N\].
    pub force: Vec<DVec3>,
    /// Mechanical energy lost so far by the particle's contacts (damping, bond formation; half of
    /// each pair's share) \[J\] (M.35). Per particle, so the gather writes only its own slot.
    pub dissipated: Vec<f64>,
}

impl Particles {
    /// Number of particles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// True when there are no particles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    /// Appends a particle of density `density` [kg/m³]; mass = ρ (4/3) π r³. Ids are given in order.
    pub fn push(&mut self, init: ParticleInit, density: f64) {
        self.id.push(self.id.len() as u64);
        self.material.push(init.material);
        self.radius.push(init.radius);
        self.mass
            .push(density * 4.0 / 3.0 * std::f64::consts::PI * init.radius.powi(3));
        self.position.push(init.position);
        self.velocity.push(init.velocity);
        self.force.push(DVec3::ZERO);
        self.dissipated.push(0.0);
        debug_assert!(self.fields_in_step());
    }

    fn fields_in_step(&self) -> bool {
        let n = self.id.len();
        [
            self.material.len(),
            self.radius.len(),
            self.mass.len(),
            self.position.len(),
            self.velocity.len(),
            self.force.len(),
            self.dissipated.len(),
        ]
        .iter()
        .all(|&len| len == n)
    }

    /// Total kinetic energy `Σ ½ m v²` \[J\] (summed in index order: reproducible).
    #[must_use]
    pub fn kinetic_energy(&self) -> f64 {
        self.mass
            .iter()
            .zip(&self.velocity)
            .map(|(m, v)| 0.5 * m * v.length_squared())
            .sum()
    }

    /// Mechanical energy lost so far by damping and bond formation \[J\] (M.35), summed in index order.
    #[must_use]
    pub fn dissipated_energy(&self) -> f64 {
        self.dissipated.iter().sum()
    }

    /// Gravitational potential energy `−Σ m g·x` \[J\] (zero at the origin).
    #[must_use]
    pub fn gravitational_energy(&self, gravity: DVec3) -> f64 {
        // `+ 0.0` turns the −0.0 of a zero gravity into 0.0 for printing.
        self.mass
            .iter()
            .zip(&self.position)
            .map(|(m, x)| -m * gravity.dot(*x))
            .sum::<f64>()
            + 0.0
    }
}

/// Rotation of the spheres (M.62), only for scenes with friction or rolling resistance; indexed
/// like [`Particles`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Rotation {
    /// Angular velocity ω [rad/s].
    pub angular_velocity: Vec<DVec3>,
    /// Total torque about the centre [N·m].
    pub torque: Vec<DVec3>,
    /// Number of walls.
    pub walls: usize,
    /// Tangential springs of the particle-wall contacts that hold one (M.63).
    pub wall_springs: WallSprings,
}

impl Rotation {
    /// At rest, for `particles` particles and `walls` walls.
    #[must_use]
    pub fn new(particles: usize, walls: usize) -> Self {
        Self {
            angular_velocity: vec![DVec3::ZERO; particles],
            torque: vec![DVec3::ZERO; particles],
            walls,
            wall_springs: WallSprings::new(),
        }
    }

    /// Rotational kinetic energy `Σ ½ I ω²`, `I = (2/5) m r²` \[J\] (M.62), in index order.
    #[must_use]
    pub fn kinetic_energy(&self, particles: &Particles) -> f64 {
        self.angular_velocity
            .iter()
            .zip(particles.mass.iter().zip(&particles.radius))
            .map(|(w, (m, r))| {
                0.5 * crate::contact::rolling::sphere_inertia(*m, *r) * w.length_squared()
            })
            .sum()
    }

    /// Stored energy of the wall springs \[J\] (M.63), in index order.
    #[must_use]
    pub fn wall_spring_energy(&self) -> f64 {
        self.wall_springs.spring_energy()
    }
}

/// Puts the entries of `values` in the order `order` (`new[i] = old[order[i]]`); entries not
/// named are dropped.
pub(crate) fn select<T: Copy>(values: &mut Vec<T>, order: &[u32]) {
    *values = order.iter().map(|&k| values[k as usize]).collect();
}

/// The indices of the set `keep` flags, in order.
#[must_use]
pub fn kept_indices(keep: &[bool]) -> Vec<u32> {
    (0..keep.len())
        .filter(|&k| keep[k])
        .map(|k| u32::try_from(k).expect("fewer than 2^32 particles"))
        .collect()
}

impl Particles {
    /// Reorders the particles (`new[i] = old[order[i]]`), dropping those not named; ids stay
    /// with their particles.
    pub fn select(&mut self, order: &[u32]) {
        select(&mut self.id, order);
        select(&mut self.material, order);
        select(&mut self.radius, order);
        select(&mut self.mass, order);
        select(&mut self.position, order);
        select(&mut self.velocity, order);
        select(&mut self.force, order);
        select(&mut self.dissipated, order);
    }

    /// The index of the particle with id `id` (a linear search: for tests and tools, not for
    /// loops). A simulation stores its particles in a spatial order that changes at every
    /// neighbour-list rebuild, so indices do not identify particles across steps; ids do.
    #[must_use]
    pub fn index_of(&self, id: u64) -> Option<usize> {
        self.id.iter().position(|i| *i == id)
    }

    /// Keeps the particles whose `keep` flag is set, in order.
    pub fn retain(&mut self, keep: &[bool]) {
        self.select(&kept_indices(keep));
    }
}

impl Rotation {
    /// Reorders the rotation state like [`Particles::select`].
    pub fn select(&mut self, order: &[u32]) {
        let particles = self.angular_velocity.len();
        select(&mut self.angular_velocity, order);
        select(&mut self.torque, order);
        self.wall_springs.select(particles, order);
    }
}
