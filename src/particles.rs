//! Particle state as a structure of arrays: one `Vec` per field, all of the same length, so a pass
//! borrows only the fields it needs and each field maps one-to-one onto an output dataset.
//! SI units: m, m/s, kg, N.

use glam::DVec3;

/// Everything needed to add one particle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleInit {
    /// Centre [m].
    pub position: DVec3,
    /// Velocity [m/s].
    pub velocity: DVec3,
    /// Radius [m].
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
    /// Radius [m].
    pub radius: Vec<f64>,
    /// Mass [kg].
    pub mass: Vec<f64>,
    /// Centre [m].
    pub position: Vec<DVec3>,
    /// Velocity [m/s].
    pub velocity: Vec<DVec3>,
    /// Total force at the current positions [N].
    pub force: Vec<DVec3>,
    /// Mechanical energy lost so far by the particle's contacts (damping, bond formation; half of
    /// each pair's share) [J] (M.35). Per particle, so the gather writes only its own slot.
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

    /// Total kinetic energy `Σ ½ m v²` [J] (summed in index order: reproducible).
    #[must_use]
    pub fn kinetic_energy(&self) -> f64 {
        self.mass
            .iter()
            .zip(&self.velocity)
            .map(|(m, v)| 0.5 * m * v.length_squared())
            .sum()
    }

    /// Mechanical energy lost so far by damping and bond formation [J] (M.35), summed in index order.
    #[must_use]
    pub fn dissipated_energy(&self) -> f64 {
        self.dissipated.iter().sum()
    }

    /// Gravitational potential energy `−Σ m g·x` [J] (zero at the origin).
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
