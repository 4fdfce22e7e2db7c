//! The resolved run: a validated [`Scene`] turned into plain numbers (materials, a dense table of
//! contact parameters per material pair, walls, the bond criterion) and the initial particles.
//! Nothing downstream of this module reads TOML or strings.

use std::path::PathBuf;

use glam::{DVec2, DVec3};

use crate::bed::contact_history::ImportedRotation;
use crate::bed::deposition::Deposition;
use crate::bed::rng::SplitMix64;
use crate::contact::{BondParams, FrictionParams, NormalParams, bond, hertz, tangential};
use crate::laser::{self, Laser};
use crate::output::frame::{Needs, OptionalField};
use crate::particles::{ParticleInit, Particles};
use crate::periodic::Periodic;
use crate::scene::{
    Axis, ConductionConfig, CriterionConfig, LaserConfig, MeltingRule, PathConfig, Scene,
    SceneError, ThermalConfig, Violation, validate::lattice_sites,
};
use crate::thermal::{ConductionModel, InitialRegion, ThermalMaterial, ThermalModel, Vaporization};

/// Elastic data of one material (SI).
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name in the scene (`[materials.NAME]`).
    pub name: String,
    /// Density [kg/m³].
    pub density: f64,
    /// Young's modulus \[Pa\].
    pub youngs_modulus: f64,
    /// Poisson ratio.
    pub poisson_ratio: f64,
}

/// An infinite plane wall.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall {
    /// A point of the plane \[m\].
    pub point: DVec3,
    /// Unit normal, pointing into the domain.
    pub normal: DVec3,
    /// Index into `Model::materials`.
    pub material: u16,
}

/// The bond criterion of paper eq. 25: whether a pair may switch to the bonded branch. Evaluated
/// outside the force law, which receives only its `bool`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BondCriterion {
    /// Every pair, always.
    Always,
    /// No pair, ever.
    Never,
    /// The particles have reached their melting points (latched per particle, M.53): both of
    /// them, or with `either`, at least one.
    Melting {
        /// One melted particle suffices.
        either: bool,
    },
}

impl BondCriterion {
    /// Whether the criterion holds for a pair whose particles have (`melted_i`, `melted_j`)
    /// reached their melting points. Symmetric in its arguments, so the answer cannot depend on
    /// which particle is called i.
    #[must_use]
    #[inline]
    pub fn holds(self, melted_i: bool, melted_j: bool) -> bool {
        match self {
            Self::Always => true,
            Self::Never => false,
            Self::Melting { either: false } => melted_i && melted_j,
            Self::Melting { either: true } => melted_i || melted_j,
        }
    }
}

/// What the run writes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputSettings {
    /// HDF5 file, if asked for.
    pub file: Option<PathBuf>,
    /// Steps between frames (≥ 1).
    pub frame_every: u64,
    /// Optional fields written in each frame.
    pub fields: Vec<OptionalField>,
    /// Deflate level (0: none).
    pub deflate: u8,
    /// Whether frames carry restart data.
    pub restart: bool,
    /// CSV time series, if asked for.
    pub series_csv: Option<PathBuf>,
    /// Steps between series rows (≥ 1).
    pub series_every: u64,
}

impl OutputSettings {
    fn resolve(scene: &Scene, steps: u64) -> Self {
        let out = scene.output.as_ref();
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let frame_every = match (out.and_then(|o| o.every_steps), out.and_then(|o| o.every_s)) {
            (Some(n), _) => n,
            (None, Some(every)) => ((every / scene.simulation.dt_s).round() as u64).max(1),
            // 100 frames per run: enough to play in ParaView, small enough to write cheaply.
            (None, None) => (steps / 100).max(1),
        };
        let available = |f: &OptionalField| match f.needs() {
            Needs::Nothing => true,
            Needs::Bond => scene.bond.is_some(),
            Needs::Thermal => scene.thermal.is_some(),
            Needs::Evaporation => scene.has_evaporation(),
            Needs::Rotation => scene.contact.has_rotation(),
        };
        let fields = match out.and_then(|o| o.fields.as_ref()) {
            Some(names) => OptionalField::ALL
                .into_iter()
                .filter(|f| names.iter().any(|n| n == f.name()))
                .collect(),
            None => OptionalField::ALL.into_iter().filter(available).collect(),
        };
        Self {
            file: out.and_then(|o| o.file.as_ref()).map(PathBuf::from),
            frame_every,
            fields,
            deflate: out.and_then(|o| o.deflate).unwrap_or(0),
            restart: out.and_then(|o| o.restart).unwrap_or(true),
            series_csv: out.and_then(|o| o.series_csv.as_ref()).map(PathBuf::from),
            series_every: out
                .and_then(|o| o.series_every_steps)
                .unwrap_or(frame_every),
        }
    }
}

/// The box particles may occupy (M.78): a particle whose centre is outside it on a non-periodic
/// axis is removed at the next neighbour-list build.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Domain {
    /// Lower corner \[m\].
    pub lower: DVec3,
    /// Upper corner \[m\].
    pub upper: DVec3,
    /// Axes along which the domain is periodic (the bounds do not apply there).
    pub periodic: [bool; 3],
}

impl Domain {
    /// Whether a centre at `x` is inside the box on every non-periodic axis.
    #[must_use]
    pub fn contains(&self, x: DVec3) -> bool {
        let (x, lo, hi) = (x.to_array(), self.lower.to_array(), self.upper.to_array());
        (0..3).all(|k| self.periodic[k] || (lo[k]..=hi[k]).contains(&x[k]))
    }
}

/// The run's guards: it stops, naming the step, the particles and the quantity, when one trips.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guards {
    /// Largest overlap relative to the smaller radius of its pair.
    pub max_overlap_ratio: f64,
    /// Largest relative mechanical energy created (M.35 residual).
    pub max_energy_residual: f64,
}

impl Guards {
    fn from_scene(config: Option<&crate::scene::GuardsConfig>) -> Self {
        let config = config.cloned().unwrap_or_default();
        Self {
            max_overlap_ratio: config
                .max_overlap_ratio
                .unwrap_or(crate::scene::DEFAULT_MAX_OVERLAP_RATIO),
            max_energy_residual: config
                .max_energy_residual
                .unwrap_or(crate::scene::DEFAULT_MAX_ENERGY_RESIDUAL),
        }
    }
}

/// Tangential and rolling parameters (M.56–M.61), dense tables like the normal ones; present when
/// the scene gives `contact.friction_coefficient` or `contact.rolling_friction_coefficient`.
#[derive(Debug, Clone, PartialEq)]
pub struct Friction {
    materials: usize,
    /// `[a * n + b]`: material pair (a, b); symmetric.
    pair: Vec<FrictionParams>,
    /// `[w * n + a]`: particle (material a) against wall w.
    wall: Vec<FrictionParams>,
}

impl Friction {
    /// Parameters of two particle materials.
    #[must_use]
    #[inline]
    pub fn pair(&self, a: u16, b: u16) -> &FrictionParams {
        &self.pair[usize::from(a) * self.materials + usize::from(b)]
    }

    /// Parameters of a particle material against wall `wall`.
    #[must_use]
    #[inline]
    pub fn wall(&self, wall: usize, material: u16) -> &FrictionParams {
        &self.wall[wall * self.materials + usize::from(material)]
    }

    fn build(scene: &Scene, materials: &[Material], walls: &[Wall]) -> Option<Self> {
        if !scene.contact.has_rotation() {
            return None;
        }
        let params = |a: &Material, b: &Material| FrictionParams {
            effective_shear_modulus: tangential::effective_shear_modulus(
                a.youngs_modulus,
                a.poisson_ratio,
                b.youngs_modulus,
                b.poisson_ratio,
            ),
            sliding: scene.contact.friction_coefficient.unwrap_or(0.0),
            rolling: scene.contact.rolling_friction_coefficient.unwrap_or(0.0),
        };
        let pair = materials
            .iter()
            .flat_map(|a| materials.iter().map(move |b| (a, b)))
            .map(|(a, b)| params(a, b))
            .collect();
        let wall = walls
            .iter()
            .flat_map(|w| materials.iter().map(move |a| (w, a)))
            .map(|(w, a)| params(a, &materials[usize::from(w.material)]))
            .collect();
        Some(Self {
            materials: materials.len(),
            pair,
            wall,
        })
    }
}

/// Resolved, immutable run parameters.
#[derive(Debug, Clone)]
pub struct Model {
    /// Scene title.
    pub title: String,
    /// Time step \[s\].
    pub dt: f64,
    /// Number of steps of the run.
    pub steps: u64,
    /// Gravitational acceleration [m/s²].
    pub gravity: DVec3,
    /// Verlet skin \[m\].
    pub skin: f64,
    /// Materials, indexed by `Particles::material`.
    pub materials: Vec<Material>,
    /// Walls.
    pub walls: Vec<Wall>,
    /// Bond criterion (only meaningful when the pair parameters carry a bond).
    pub bond_criterion: BondCriterion,
    /// User's largest expected impact speed [m/s], if given.
    pub expected_impact_speed: Option<f64>,
    /// When the run stops itself (docs/stability.md).
    pub guards: Guards,
    /// Output settings.
    pub output: OutputSettings,
    /// Thermal parameters, if the scene has `[thermal]`.
    pub thermal: Option<ThermalModel>,
    /// The laser, if the scene has `[laser]`.
    pub laser: Option<Laser>,
    /// Tangential and rolling parameters, if the scene has friction or rolling resistance
    /// (then the particles rotate).
    pub friction: Option<Friction>,
    /// Periodic axes, if the scene has `[periodic]` (M.77).
    pub periodic: Option<Periodic>,
    /// The box outside which particles are removed, if the scene has `[domain]` (M.78).
    pub domain: Option<Domain>,
    /// Settling under gravity before the run, if the scene has `[deposition]`.
    pub deposition: Option<Deposition>,
    /// Spins and contact springs read by `[[import]]` (a LIGGGHTS bed's rotational state):
    /// part of the start, not of the parameters, so [`crate::simulation::Simulation::new`] takes
    /// them out and gives them to the particles at t = 0.
    pub imported_rotation: ImportedRotation,
    /// `[a * n + b]`: normal-law parameters of material pair (a, b); symmetric.
    pair_params: Vec<NormalParams>,
    /// `[w * n + a]`: particle (material a) against wall w; never bonded.
    wall_params: Vec<NormalParams>,
}

impl Model {
    /// Normal-law parameters of two particle materials.
    #[must_use]
    #[inline]
    pub fn pair_params(&self, a: u16, b: u16) -> &NormalParams {
        &self.pair_params[usize::from(a) * self.materials.len() + usize::from(b)]
    }

    /// Normal-law parameters of a particle material against wall `wall`.
    #[must_use]
    #[inline]
    pub fn wall_params(&self, wall: usize, material: u16) -> &NormalParams {
        &self.wall_params[wall * self.materials.len() + usize::from(material)]
    }

    /// The mass \[kg\] of the vapour that carried off `heat` \[J\] from a particle of `material`
    /// (M.80): `heat / L_v`; 0 for a material that does not evaporate (or without `[thermal]`).
    #[must_use]
    pub fn evaporated_mass(&self, material: u16, heat: f64) -> f64 {
        self.thermal
            .as_ref()
            .and_then(|t| t.materials[usize::from(material)].vaporization)
            .map_or(0.0, |v| heat / v.latent_heat)
    }

    /// True when the scene has a `[bond]` section.
    #[must_use]
    pub fn has_bonds(&self) -> bool {
        self.pair_params.iter().any(|p| p.bond.is_some())
    }

    /// Resolves a validated scene into the model and the initial particles.
    ///
    /// # Panics
    /// If `[[import]]` files cannot be read or `[[insert]]` cannot place its spheres: scenes
    /// with those blocks should use [`Model::try_build`].
    #[must_use]
    pub fn build(scene: &Scene) -> (Self, Particles) {
        Self::try_build(scene).unwrap_or_else(|e| panic!("{e}"))
    }

    /// Resolves a validated scene into the model and the initial particles, reading
    /// `[[import]]` files and placing `[[insert]]` spheres.
    ///
    /// # Errors
    /// [`SceneError::Invalid`] naming the block's key, value and reason for every file that
    /// cannot be read or parsed and every insertion that cannot place its spheres.
    pub fn try_build(scene: &Scene) -> Result<(Self, Particles), SceneError> {
        let materials: Vec<Material> = scene
            .materials
            .iter()
            .map(|(name, m)| Material {
                name: name.clone(),
                density: m.density_kg_m3,
                youngs_modulus: m.youngs_modulus_pa,
                poisson_ratio: m.poisson_ratio,
            })
            .collect();
        let material_index = |name: &str| -> u16 {
            let k = materials
                .iter()
                .position(|m| m.name == name)
                .expect("validated: material exists");
            u16::try_from(k).expect("fewer than 65536 materials")
        };
        let mut particles = initial_particles(scene, &materials, &material_index);
        let mut violations = Vec::new();
        let mut imported = ImportedStart::default();
        add_imported(
            scene,
            &materials,
            &mut particles,
            &mut imported,
            &mut violations,
        );
        add_inserted(
            scene,
            &materials,
            &material_index,
            &mut particles,
            &mut violations,
        );
        if !violations.is_empty() {
            return Err(SceneError::Invalid {
                path: None,
                violations,
            });
        }

        let e_star = |a: &Material, b: &Material| {
            hertz::effective_modulus(
                a.youngs_modulus,
                a.poisson_ratio,
                b.youngs_modulus,
                b.poisson_ratio,
            )
        };
        let mut pair_params = Vec::with_capacity(materials.len() * materials.len());
        for a in &materials {
            for b in &materials {
                let effective_modulus = e_star(a, b);
                let bond = scene.bond.as_ref().map(|cfg| {
                    let adhesion_stiffness = cfg.adhesion_stiffness.unwrap_or_else(|| {
                        let reference_radius =
                            cfg.reference_radius_m.unwrap_or(particles.radius[0]);
                        bond::adhesion_stiffness_for_equilibrium(
                            effective_modulus,
                            hertz::effective_radius(reference_radius, reference_radius),
                            cfg.adhesion_exponent,
                            cfg.equilibrium_overlap_m
                                .expect("validated: one of the two is given"),
                        )
                    });
                    BondParams {
                        adhesion_exponent: cfg.adhesion_exponent,
                        adhesion_stiffness,
                        damping_ratio: cfg.damping_ratio,
                    }
                });
                pair_params.push(NormalParams {
                    effective_modulus,
                    damping_ratio: scene.contact.resolved_damping_ratio(),
                    bond,
                });
            }
        }

        let walls: Vec<Wall> = scene
            .walls
            .iter()
            .map(|w| Wall {
                point: DVec3::from_array(w.point_m),
                normal: DVec3::from_array(w.normal).normalize(),
                material: material_index(&w.material),
            })
            .collect();
        let mut wall_params = Vec::with_capacity(walls.len() * materials.len());
        for w in &walls {
            for a in &materials {
                wall_params.push(NormalParams {
                    effective_modulus: e_star(a, &materials[usize::from(w.material)]),
                    damping_ratio: scene.contact.resolved_damping_ratio(),
                    bond: None,
                });
            }
        }

        let friction = Friction::build(scene, &materials, &walls);

        let sim = &scene.simulation;
        // Round-off in duration/dt (5e-3/5e-7 = 10000.000000000002) must not add a step.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let steps = (sim.duration_s / sim.dt_s * (1.0 - 1e-12)).ceil() as u64;
        let smallest_radius = particles
            .radius
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        // 10 % of the smallest diameter: LIGGGHTS and LAMMPS use 0.1-0.3 d for granular beds.
        let skin = sim.skin_m.unwrap_or(0.2 * smallest_radius);
        let periodic = periodic_box(scene, &particles, skin)?;
        let violations = check_imported_contacts(
            scene,
            &particles,
            &walls,
            periodic.as_ref(),
            skin,
            &imported,
        );
        if !violations.is_empty() {
            return Err(SceneError::Invalid {
                path: None,
                violations,
            });
        }
        let model = Self {
            title: scene.scene.title.clone(),
            dt: sim.dt_s,
            steps,
            gravity: DVec3::from_array(sim.gravity_m_s2),
            skin,
            materials,
            walls,
            bond_criterion: match scene.bond.as_ref().map(|b| (b.criterion, b.melting_rule)) {
                Some((CriterionConfig::Always, _)) => BondCriterion::Always,
                Some((CriterionConfig::Never, _)) | None => BondCriterion::Never,
                Some((CriterionConfig::Melting, rule)) => BondCriterion::Melting {
                    either: rule == Some(MeltingRule::Either),
                },
            },
            thermal: scene.thermal.as_ref().map(|t| thermal_model(scene, t)),
            laser: scene.laser.as_ref().map(|l| laser(l, smallest_radius)),
            expected_impact_speed: sim.expected_impact_speed_m_s,
            guards: Guards::from_scene(scene.guards.as_ref()),
            deposition: scene.deposition.as_ref().map(|d| {
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let max_steps = (d.max_duration_s / sim.dt_s * (1.0 - 1e-12)).ceil() as u64;
                Deposition {
                    max_steps,
                    check_every: d.check_every_steps.unwrap_or(1000),
                    kinetic_energy_ratio: d.kinetic_energy_ratio.unwrap_or(1e-4),
                    damping_time: d.damping_time_s,
                }
            }),
            output: OutputSettings::resolve(scene, steps),
            friction,
            periodic,
            domain: scene.domain.as_ref().map(|d| Domain {
                lower: DVec3::from_array(d.min_corner_m),
                upper: DVec3::from_array(d.max_corner_m),
                periodic: periodic.map_or([false; 3], |p| {
                    [p.is_periodic(0), p.is_periodic(1), p.is_periodic(2)]
                }),
            }),
            pair_params,
            wall_params,
            imported_rotation: imported.rotation,
        };
        Ok((model, particles))
    }
}

/// The periodic box of `[periodic]`, checked against the particles: the neighbour search needs
/// at least three cells of `2 r_max + skin` across each period (M.77).
fn periodic_box(
    scene: &Scene,
    particles: &Particles,
    skin: f64,
) -> Result<Option<Periodic>, SceneError> {
    let Some(config) = &scene.periodic else {
        return Ok(None);
    };
    let r_max = particles.radius.iter().copied().fold(0.0, f64::max);
    let cell = 2.0 * r_max + skin;
    let mut periodic = Periodic {
        lower: DVec3::ZERO,
        length: [None; 3],
    };
    let mut violations = Vec::new();
    for (key, axis, [lower, upper]) in config.axes() {
        let length = upper - lower;
        if length < 3.0 * cell {
            violations.push(crate::scene::Violation {
                key: key.into(),
                value: format!("[{lower}, {upper}]"),
                reason: format!(
                    "a period of {length:e} m is shorter than three neighbour cells of 2 r_max + skin = {cell:e} m: widen the box"
                ),
            });
        }
        periodic.length[axis] = Some(length);
        let mut lower_corner = periodic.lower.to_array();
        lower_corner[axis] = lower;
        periodic.lower = DVec3::from_array(lower_corner);
    }
    if violations.is_empty() {
        Ok(Some(periodic))
    } else {
        Err(SceneError::Invalid {
            path: None,
            violations,
        })
    }
}

fn thermal_model(scene: &Scene, config: &ThermalConfig) -> ThermalModel {
    ThermalModel {
        // BTreeMap order, the same as `Model::materials`.
        materials: scene
            .materials
            .values()
            .map(|m| ThermalMaterial {
                specific_heat: m.specific_heat_j_kg_k.unwrap_or(0.0),
                conductivity: m.thermal_conductivity_w_m_k.unwrap_or(0.0),
                melting_point: m.melting_point_k.unwrap_or(f64::INFINITY),
                latent_heat: m.latent_heat_j_kg.unwrap_or(0.0),
                emissivity: m.emissivity.unwrap_or(0.0),
                absorptivity: m.absorptivity.unwrap_or(0.0),
                // Validation requires both keys or neither.
                vaporization: m.boiling_point_k.zip(m.latent_heat_vaporization_j_kg).map(
                    |(boiling_point, latent_heat)| Vaporization {
                        boiling_point,
                        latent_heat,
                    },
                ),
            })
            .collect(),
        conduction: match config.conduction {
            ConductionConfig::BatchelorObrien => ConductionModel::BatchelorObrien,
            ConductionConfig::ThermalPipe => ConductionModel::ThermalPipe,
            ConductionConfig::OverlapArea => ConductionModel::OverlapArea,
            ConductionConfig::None => ConductionModel::None,
        },
        convection: config
            .convection
            .as_ref()
            .map(|c| (c.heat_transfer_coefficient_w_m2_k, c.gas_temperature_k)),
        radiation: config
            .radiation
            .as_ref()
            .map(|r| r.environment_temperature_k),
        wall_temperatures: scene.walls.iter().map(|w| w.temperature_k).collect(),
        initial_temperature: config.initial_temperature_k,
        initial_regions: config
            .initial_region
            .iter()
            .map(|r| InitialRegion {
                lower: DVec3::from_array(r.min_corner_m),
                upper: DVec3::from_array(r.max_corner_m),
                temperature: r.temperature_k,
            })
            .collect(),
        // θ = 1/2: half the largest monotone substep, a margin for the radiation conductance,
        // which grows with a temperature that rises within the step (contact ones are fixed).
        substep_fraction: config.substep_fraction.unwrap_or(0.5),
        harmonic_conductivities: Vec::new(),
    }
    .tabulated()
}

fn laser(config: &LaserConfig, smallest_radius: f64) -> Laser {
    let start = config.start_time_s;
    let path = match &config.path {
        PathConfig::Polyline {
            points_m,
            speed_m_s,
        } => {
            let points: Vec<DVec2> = points_m.iter().map(|p| DVec2::from_array(*p)).collect();
            laser::polyline(&points, *speed_m_s, start)
        }
        PathConfig::Hatch {
            start_m,
            track_length_m,
            hatch_spacing_m,
            tracks,
            speed_m_s,
            direction,
            jump_time_s,
        } => laser::Hatch {
            origin: DVec2::from_array(*start_m),
            length: *track_length_m,
            spacing: *hatch_spacing_m,
            tracks: *tracks,
            along_x: *direction == Axis::X,
            speed: *speed_m_s,
            jump_time: *jump_time_s,
        }
        .segments(start),
        PathConfig::Stationary {
            position_m,
            duration_s,
        } => {
            let at = DVec2::from_array(*position_m);
            vec![laser::Segment {
                from: at,
                to: at,
                start,
                duration: *duration_s,
                on: true,
            }]
        }
    };
    Laser {
        power: config.power_w,
        spot_radius: config.spot_radius_m,
        // A tenth of the smallest radius: ~300 rays per disk put the visible fraction of a
        // half-shadowed sphere within 0.1 % (tests/laser.rs; a fifth gave 4 %), but never more
        // than 1024 rays across the ±3w window.
        raster_cell: config
            .raster_cell_m
            .unwrap_or_else(|| (smallest_radius / 10.0).max(6.0 * config.spot_radius_m / 1024.0)),
        path,
    }
}

fn initial_particles(
    scene: &Scene,
    materials: &[Material],
    material_index: &dyn Fn(&str) -> u16,
) -> Particles {
    let mut particles = Particles::default();
    let mut push = |init: ParticleInit| {
        let density = materials[usize::from(init.material)].density;
        particles.push(init, density);
    };
    for p in &scene.particles {
        push(ParticleInit {
            position: DVec3::from_array(p.position_m),
            velocity: DVec3::from_array(p.velocity_m_s),
            radius: p.radius_m,
            material: material_index(&p.material),
        });
    }
    for l in &scene.lattice {
        let spacing = l.spacing_m.unwrap_or(2.0 * l.radius_m);
        let lo = DVec3::from_array(l.min_corner_m);
        let extent = DVec3::from_array(l.max_corner_m) - lo;
        let counts =
            [0, 1, 2].map(|axis| lattice_sites(extent[axis], l.radius_m, spacing, l.jitter_m));
        let mut rng = SplitMix64(l.seed);
        let material = material_index(&l.material);
        for k in 0..counts[2] {
            for j in 0..counts[1] {
                for i in 0..counts[0] {
                    #[allow(clippy::cast_precision_loss)]
                    let site = lo
                        + DVec3::splat(l.radius_m + l.jitter_m)
                        + spacing * DVec3::new(i as f64, j as f64, k as f64);
                    let jitter = if l.jitter_m > 0.0 {
                        DVec3::new(rng.symmetric(), rng.symmetric(), rng.symmetric()) * l.jitter_m
                    } else {
                        DVec3::ZERO
                    };
                    push(ParticleInit {
                        position: site + jitter,
                        velocity: DVec3::from_array(l.velocity_m_s),
                        radius: l.radius_m,
                        material,
                    });
                }
            }
        }
    }
    particles
}

/// What the `[[import]]` blocks bring besides particles, with where each spring came from.
#[derive(Default)]
struct ImportedStart {
    /// Spins and springs, by am-sim id.
    rotation: ImportedRotation,
    /// Where each of `rotation.pair_springs` came from.
    pair_sources: Vec<SpringSource>,
    /// Where each of `rotation.wall_springs` came from.
    wall_sources: Vec<SpringSource>,
}

/// Where an imported spring came from, for the check that it is a contact of the particles
/// ([`check_imported_contacts`]): 16 bytes, not a message, because a bed brings a spring per
/// contact and this list lives at the import's peak of memory.
struct SpringSource {
    /// The `[[import]]` block.
    block: usize,
    /// What names it: the line of the pair file, or the particle's file id.
    at: u64,
}

/// Appends the particles of every `[[import]]` file (rows in file-id order when the file has
/// ids) and gathers what they bring of the rotational state (spins, springs) into `rotation`,
/// with where each spring came from; problems are added to `violations` under the block's keys.
fn add_imported(
    scene: &Scene,
    materials: &[Material],
    particles: &mut Particles,
    start: &mut ImportedStart,
    violations: &mut Vec<Violation>,
) {
    use crate::bed::{contact_history, import};
    use crate::scene::ImportFormat;
    let has_rotation = scene.contact.has_rotation();
    for (k, cfg) in scene.import.iter().enumerate() {
        let path = scene.base_dir.join(&cfg.file);
        let fail = |violations: &mut Vec<Violation>, key: &str, reason: String| {
            violations.push(Violation {
                key: format!("import[{k}].{key}"),
                value: format!("\"{}\" ({})", cfg.file, path.display()),
                reason,
            });
        };
        let rows = match cfg.format {
            ImportFormat::Csv => import::read_text(&path).and_then(|t| import::parse_csv(&t)),
            ImportFormat::LiggghtsDump => import::open_text(&path)
                .and_then(|reader| {
                    import::read_liggghts_dump(reader, cfg.timestep, &cfg.wall_history_columns)
                })
                .map(|snapshot| snapshot.particles),
            ImportFormat::AmSimH5 => import::read_am_sim_h5(&path, cfg.frame),
        };
        let rows = match rows {
            Ok(rows) if rows.is_empty() => {
                fail(violations, "file", "the file holds no particles".into());
                continue;
            }
            Ok(rows) => rows,
            Err(e) => {
                fail(violations, "file", e);
                continue;
            }
        };
        let scale = cfg.scale.unwrap_or(1.0);
        let shift = DVec3::from_array(cfg.shift_m);
        let mut inits = Vec::with_capacity(rows.len());
        for (row, p) in rows.iter().enumerate() {
            let Some(name) = p.material.as_deref().or(cfg.material.as_deref()) else {
                fail(
                    violations,
                    "material",
                    format!(
                        "missing: particle {row} of the file (in id order) names no material; give import[{k}].material"
                    ),
                );
                break;
            };
            let Some(material) = materials.iter().position(|m| m.name == name) else {
                let known: Vec<&str> = materials.iter().map(|m| m.name.as_str()).collect();
                fail(
                    violations,
                    "file",
                    format!(
                        "particle {row} (in id order) has material \"{name}\": no such material; defined: {known:?}"
                    ),
                );
                break;
            };
            inits.push(ParticleInit {
                position: scale * p.position + shift,
                velocity: scale * p.velocity,
                radius: scale * p.radius,
                material: u16::try_from(material).expect("fewer than 65536 materials"),
            });
        }
        if inits.len() != rows.len() {
            continue;
        }
        // am-sim numbers the block's particles on from here, in the order of the rows.
        let first_id = particles.len() as u64;
        for init in inits {
            particles.push(init, materials[usize::from(init.material)].density);
        }
        if !has_rotation {
            // Without friction or rolling resistance the spheres do not turn: a file's spins
            // have nothing to act on (the springs were refused by the scene's validation).
            continue;
        }
        let ImportedStart {
            rotation: imported,
            pair_sources,
            wall_sources,
        } = start;
        for (row, p) in (first_id..).zip(&rows) {
            if let Some(omega) = p.angular_velocity {
                imported.angular_velocity.push((row, omega));
            }
            for (wall, history) in p.wall_history.iter().enumerate() {
                if *history != DVec3::ZERO && !cfg.wall_history_columns[wall].is_empty() {
                    imported.wall_springs.push((row, wall, scale * *history));
                    wall_sources.push(SpringSource {
                        block: k,
                        at: p.id.unwrap_or(row - first_id),
                    });
                }
            }
        }
        let Some(file) = &cfg.pair_history_file else {
            continue;
        };
        // The pair file names particles by their file ids; the rows are sorted by them (and
        // unique) when every row has one. Only the ids are kept while the pairs are read.
        let file_ids: Option<Vec<u64>> = rows.iter().map(|p| p.id).collect();
        drop(rows);
        let pair_path = scene.base_dir.join(file);
        let springs = import::open_text(&pair_path)
            .and_then(|reader| contact_history::read_pair_history(reader, cfg.timestep));
        let fail_pairs = |violations: &mut Vec<Violation>, reason: String| {
            violations.push(Violation {
                key: format!("import[{k}].pair_history_file"),
                value: format!("\"{file}\" ({})", pair_path.display()),
                reason,
            });
        };
        let springs = match springs {
            Ok(springs) => springs,
            Err(e) => {
                fail_pairs(violations, e);
                continue;
            }
        };
        let Some(file_ids) = file_ids else {
            fail_pairs(
                violations,
                format!(
                    "{} has no `id` column, so its particles cannot be named by the pairs",
                    cfg.file
                ),
            );
            continue;
        };
        let row_of = |id: u64| {
            file_ids
                .binary_search(&id)
                .ok()
                .map(|row| first_id + row as u64)
        };
        for spring in springs {
            let [Some(first), Some(second)] = [spring.ids.0, spring.ids.1].map(row_of) else {
                fail_pairs(
                    violations,
                    format!(
                        "line {}: the pair ({}, {}) names a particle id that {} does not hold",
                        spring.line, spring.ids.0, spring.ids.1, cfg.file
                    ),
                );
                break;
            };
            // Stored for the lower am-sim id, relative to the higher (`ImportedRotation`).
            let history = scale * spring.history;
            let (key, history) = if first < second {
                ((first, second), history)
            } else {
                ((second, first), -history)
            };
            imported.pair_springs.push((key, history));
            pair_sources.push(SpringSource {
                block: k,
                at: spring.line as u64,
            });
        }
    }
}

/// Refuses imported springs that are no contact of the imported particles: a pair farther
/// apart, or a particle farther from its wall, than the skin (the neighbour list and the wall
/// candidates would never meet them, so the springs could not act).
fn check_imported_contacts(
    scene: &Scene,
    particles: &Particles,
    walls: &[Wall],
    periodic: Option<&Periodic>,
    skin: f64,
    start: &ImportedStart,
) -> Vec<Violation> {
    let ImportedStart {
        rotation: imported,
        pair_sources,
        wall_sources,
    } = start;
    let mut violations = Vec::new();
    // Until the first neighbour-list build, index k holds the particle of id k.
    let index = |id: u64| usize::try_from(id).expect("ids index the particles");
    for (((a, b), _), source) in imported.pair_springs.iter().zip(pair_sources) {
        let (_, overlap) = crate::forces::pair_geometry(periodic, particles, index(*a), index(*b));
        let gap = -overlap;
        if gap >= skin {
            let cfg = &scene.import[source.block];
            violations.push(Violation {
                key: format!("import[{}].pair_history_file", source.block),
                value: format!("\"{}\"", cfg.pair_history_file.as_deref().unwrap_or_default()),
                reason: format!(
                    "line {} of {}: the two particles' surfaces are {gap:e} m apart, more than the skin ({skin:e} m): not a contact of the particles of {}",
                    source.at,
                    cfg.pair_history_file.as_deref().unwrap_or_default(),
                    cfg.file
                ),
            });
            break;
        }
    }
    for ((id, wall, _), source) in imported.wall_springs.iter().zip(wall_sources) {
        let k = index(*id);
        let gap = -crate::forces::plane_overlap(
            &walls[*wall],
            particles.position[k],
            particles.radius[k],
        );
        if gap >= skin {
            let cfg = &scene.import[source.block];
            violations.push(Violation {
                key: format!("import[{}].wall_history_columns", source.block),
                value: format!("{:?}", cfg.wall_history_columns),
                reason: format!(
                    "the particle of file id {} ({}) has a spring against wall {wall} but is {gap:e} m from it, more than the skin ({skin:e} m)",
                    source.at, cfg.wall_history_columns[*wall]
                ),
            });
            break;
        }
    }
    violations
}

/// Appends the spheres of every `[[insert]]`: diameters drawn from the size distribution,
/// sorted largest first, placed by random sequential addition around the particles already
/// built; problems are added to `violations` under the block's keys.
fn add_inserted(
    scene: &Scene,
    materials: &[Material],
    material_index: &dyn Fn(&str) -> u16,
    particles: &mut Particles,
    violations: &mut Vec<Violation>,
) {
    use crate::bed::insertion::{ATTEMPTS_PER_SPHERE, InsertionError, insert_spheres};
    use crate::scene::validate::size_distribution;
    for (k, cfg) in scene.insert.iter().enumerate() {
        let psd = size_distribution(&cfg.size).expect("validated: the size keys define a PSD");
        let (lo, hi) = (
            DVec3::from_array(cfg.min_corner_m),
            DVec3::from_array(cfg.max_corner_m),
        );
        let mut rng = SplitMix64(cfg.seed);
        let mut diameters = Vec::new();
        if let Some(n) = cfg.count {
            diameters.extend((0..n).map(|_| psd.sample(&mut rng)));
        } else if let Some(fraction) = cfg.solid_fraction {
            let target = fraction * (hi - lo).element_product();
            let mut solid = 0.0;
            while solid < target {
                let d = psd.sample(&mut rng);
                solid += std::f64::consts::PI / 6.0 * d.powi(3);
                diameters.push(d);
            }
        }
        let mut radii: Vec<f64> = diameters.iter().map(|d| 0.5 * d).collect();
        radii.sort_by(|a, b| b.total_cmp(a));
        let obstacles: Vec<(DVec3, f64)> = particles
            .position
            .iter()
            .copied()
            .zip(particles.radius.iter().copied())
            .collect();
        match insert_spheres(lo, hi, &radii, &obstacles, &mut rng) {
            Ok(centres) => {
                let material = material_index(&cfg.material);
                let density = materials[usize::from(material)].density;
                for (x, r) in centres.into_iter().zip(radii) {
                    particles.push(
                        ParticleInit {
                            position: x,
                            velocity: DVec3::from_array(cfg.velocity_m_s),
                            radius: r,
                            material,
                        },
                        density,
                    );
                }
            }
            Err(InsertionError::TooLarge { radius, axis }) => violations.push(Violation {
                key: format!("insert[{k}].max_corner_m"),
                value: format!("{:?} (min_corner_m = {:?})", cfg.max_corner_m, cfg.min_corner_m),
                reason: format!(
                    "a sphere of diameter {:.4e} m drawn from insert[{k}].size does not fit the box along {}: enlarge the box or set size.max_m",
                    2.0 * radius,
                    ["x", "y", "z"][axis]
                ),
            }),
            Err(InsertionError::Jammed {
                placed,
                requested,
                solid_fraction,
            }) => violations.push(Violation {
                key: format!(
                    "insert[{k}].{}",
                    if cfg.count.is_some() { "count" } else { "solid_fraction" }
                ),
                value: cfg
                    .count
                    .map_or_else(|| format!("{:?}", cfg.solid_fraction.unwrap_or_default()), |n| n.to_string()),
                reason: format!(
                    "placed only {placed} of {requested} spheres (solid fraction {solid_fraction:.3}) before {ATTEMPTS_PER_SPHERE} random positions in a row overlapped: random sequential addition jams near a solid fraction of 0.38; enlarge the box or ask for fewer spheres"
                ),
            }),
        }
    }
}
