//! One output frame: the per-particle and per-bond arrays of the current state, in the order of
//! the particle arrays (bonds refer to rows of the same frame), with names and SI units.

use crate::simulation::Simulation;

/// The values of one dataset.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    /// Scalars.
    F64(Vec<f64>),
    /// 3-vectors (one row per item).
    Vec3(Vec<[f64; 3]>),
    /// Unsigned integers (ids, counts).
    U64(Vec<u64>),
    /// Flags (0 or 1).
    U8(Vec<u8>),
}

impl Values {
    /// Number of rows.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::F64(v) => v.len(),
            Self::Vec3(v) => v.len(),
            Self::U64(v) => v.len(),
            Self::U8(v) => v.len(),
        }
    }

    /// True when there are no rows.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A named dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Dataset name.
    pub name: &'static str,
    /// SI unit (`1` for dimensionless values and counts).
    pub unit: &'static str,
    /// The data.
    pub values: Values,
}

/// The arrays of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Steps taken.
    pub step: u64,
    /// Simulated time \[s\].
    pub time: f64,
    /// Per-particle datasets, each of N rows: always `id`, `position`, `velocity`, `radius`,
    /// then the optional fields selected.
    pub points: Vec<Field>,
    /// Bonded pairs as row indices into this frame's particle arrays (`B × 2`), if selected.
    pub bonds: Option<Vec<[u64; 2]>>,
    /// Per-bond datasets, each of B rows.
    pub bond_fields: Vec<Field>,
}

/// Fields a scene may ask for beyond the always-written `id`, `position`, `velocity`, `radius`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OptionalField {
    /// Total force on each particle \[N\].
    Force,
    /// Number of contacts (particles and walls) of each particle.
    Contacts,
    /// Bonded pairs (row indices), drawn as lines in ParaView.
    Bonds,
    /// Overlap of each bond \[m\].
    BondOverlap,
    /// Normal force of each bond \[N\], positive when repulsive.
    BondForce,
    /// Temperature \[K\].
    Temperature,
    /// 1 once the particle has reached its melting point.
    Melted,
    /// Share of the latent heat taken [0, 1].
    MeltFraction,
    /// Mass the particle's vapour has carried off \[kg\] (M.80; the particle keeps its mass).
    EvaporatedMass,
    /// Angular velocity [rad/s] (scenes with friction or rolling resistance).
    AngularVelocity,
}

/// What an optional field needs from the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Needs {
    /// Nothing.
    Nothing,
    /// A `[bond]` section.
    Bond,
    /// A `[thermal]` section.
    Thermal,
    /// `[thermal]` and a material with `boiling_point_k`.
    Evaporation,
    /// `contact.friction_coefficient` or `contact.rolling_friction_coefficient` (rotation).
    Rotation,
}

impl OptionalField {
    /// Every optional field, in the order they are written.
    pub const ALL: [Self; 10] = [
        Self::Force,
        Self::Contacts,
        Self::AngularVelocity,
        Self::Temperature,
        Self::Melted,
        Self::MeltFraction,
        Self::EvaporatedMass,
        Self::Bonds,
        Self::BondOverlap,
        Self::BondForce,
    ];

    /// Name in the scene's `fields` list and in the file.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Force => "force",
            Self::Contacts => "contacts",
            Self::Bonds => "bonds",
            Self::BondOverlap => "bond_overlap",
            Self::BondForce => "bond_force",
            Self::Temperature => "temperature",
            Self::Melted => "melted",
            Self::MeltFraction => "melt_fraction",
            Self::EvaporatedMass => "evaporated_mass",
            Self::AngularVelocity => "angular_velocity",
        }
    }

    /// The field called `name`, if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// What the field needs from the scene.
    #[must_use]
    pub fn needs(self) -> Needs {
        match self {
            Self::Force | Self::Contacts => Needs::Nothing,
            Self::Bonds | Self::BondOverlap | Self::BondForce => Needs::Bond,
            Self::Temperature | Self::Melted | Self::MeltFraction => Needs::Thermal,
            Self::EvaporatedMass => Needs::Evaporation,
            Self::AngularVelocity => Needs::Rotation,
        }
    }
}

/// Captures the current state with the `selected` optional fields.
#[must_use]
pub fn capture(sim: &Simulation, selected: &[OptionalField]) -> Frame {
    let p = &sim.particles;
    let vec3 = |v: &[glam::DVec3]| Values::Vec3(v.iter().map(|x| x.to_array()).collect());
    let mut points = vec![
        Field {
            name: "id",
            unit: "1",
            values: Values::U64(p.id.clone()),
        },
        Field {
            name: "position",
            unit: "m",
            values: vec3(&p.position),
        },
        Field {
            name: "velocity",
            unit: "m/s",
            values: vec3(&p.velocity),
        },
        Field {
            name: "radius",
            unit: "m",
            values: Values::F64(p.radius.clone()),
        },
    ];
    let has = |f: OptionalField| selected.contains(&f);
    if has(OptionalField::Force) {
        points.push(Field {
            name: "force",
            unit: "N",
            values: vec3(&p.force),
        });
    }
    if has(OptionalField::Contacts) {
        points.push(Field {
            name: "contacts",
            unit: "1",
            values: Values::U64(sim.contact_counts()),
        });
    }
    if let (Some(r), true) = (&sim.rotation, has(OptionalField::AngularVelocity)) {
        points.push(Field {
            name: "angular_velocity",
            unit: "rad/s",
            values: vec3(&r.angular_velocity),
        });
    }
    if let Some(t) = &sim.thermal {
        if has(OptionalField::Temperature) {
            points.push(Field {
                name: "temperature",
                unit: "K",
                values: Values::F64(t.temperature.clone()),
            });
        }
        if has(OptionalField::Melted) {
            let melted = t.melted.iter().map(|m| u8::from(*m)).collect();
            points.push(Field {
                name: "melted",
                unit: "1",
                values: Values::U8(melted),
            });
        }
        if has(OptionalField::MeltFraction) {
            let fraction = (0..p.len())
                .map(|k| {
                    let constants = t.heat_constants(p, k);
                    crate::thermal::melt_fraction(
                        t.enthalpy[k],
                        constants.heat_capacity,
                        constants.melting_point,
                        constants.latent_heat,
                    )
                })
                .collect();
            points.push(Field {
                name: "melt_fraction",
                unit: "1",
                values: Values::F64(fraction),
            });
        }
        if let (Some(evaporation), true) = (&t.evaporation, has(OptionalField::EvaporatedMass)) {
            let mass = (0..p.len())
                .map(|k| {
                    sim.model
                        .evaporated_mass(p.material[k], evaporation.evaporated[k])
                })
                .collect();
            points.push(Field {
                name: "evaporated_mass",
                unit: "kg",
                values: Values::F64(mass),
            });
        }
    }
    let (mut bonds, mut bond_fields) = (None, Vec::new());
    if has(OptionalField::Bonds) {
        let pairs = sim.bonded_pairs();
        bonds = Some(
            pairs
                .iter()
                .map(|&(a, b, _, _)| [a as u64, b as u64])
                .collect(),
        );
        if has(OptionalField::BondOverlap) {
            let overlap = pairs.iter().map(|&(_, _, o, _)| o).collect();
            bond_fields.push(Field {
                name: "bond_overlap",
                unit: "m",
                values: Values::F64(overlap),
            });
        }
        if has(OptionalField::BondForce) {
            let force = pairs.iter().map(|&(_, _, _, f)| f).collect();
            bond_fields.push(Field {
                name: "bond_force",
                unit: "N",
                values: Values::F64(force),
            });
        }
    }
    Frame {
        step: sim.step,
        time: sim.time,
        points,
        bonds,
        bond_fields,
    }
}
