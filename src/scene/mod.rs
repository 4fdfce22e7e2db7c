//! The scene file (TOML): what the user writes. Serde structures with `deny_unknown_fields`,
//! loaded in two phases: parse/deserialize (type errors with the key path and line), then
//! [`validate`] (ranges and cross-field rules, all violations at once). Physics modules never see
//! this module; `crate::model` resolves a validated scene into plain numbers.
//!
//! Units are SI and every dimensional key names its unit as a suffix (`radius_m`, `dt_s`,
//! `youngs_modulus_pa`). The format is documented in `docs/scene-format.md`.

mod error;
pub mod validate;

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

pub use error::{SceneError, Violation};

/// Version of the scene format this build reads (`[scene] version`).
pub const FORMAT_VERSION: u32 = 1;

/// A whole scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// `[scene]`: format version and a free-text title.
    pub scene: SceneHeader,
    /// `[simulation]`: time step, duration, gravity, neighbour skin.
    pub simulation: SimulationConfig,
    /// `[materials.NAME]`: elastic data per material, keyed by name.
    pub materials: BTreeMap<String, MaterialConfig>,
    /// `[contact]`: the normal contact law.
    pub contact: ContactConfig,
    /// `[bond]`: the adhesive bond model; absent means no bonding is built.
    pub bond: Option<BondConfig>,
    /// `[[particles]]`: explicitly listed particles.
    #[serde(default)]
    pub particles: Vec<ParticleConfig>,
    /// `[[lattice]]`: particles generated on a simple cubic lattice in a box.
    #[serde(default)]
    pub lattice: Vec<LatticeConfig>,
    /// `[[import]]`: particles read from a file.
    #[serde(default)]
    pub import: Vec<ImportConfig>,
    /// `[[insert]]`: spheres of a size distribution placed at random, without overlaps, in a box.
    #[serde(default)]
    pub insert: Vec<InsertConfig>,
    /// `[deposition]`: let the particles settle under gravity before the run.
    pub deposition: Option<DepositionConfig>,
    /// Folder of the scene file: `[[import]]` files are relative to it (the working directory
    /// for scenes given as text).
    #[serde(skip)]
    pub base_dir: std::path::PathBuf,
    /// `[[walls]]`: infinite planes.
    #[serde(default)]
    pub walls: Vec<WallConfig>,
    /// `[output]`: what is written during the run.
    pub output: Option<OutputConfig>,
    /// `[thermal]`: per-particle temperatures; absent means no thermal arrays and no thermal pass.
    pub thermal: Option<ThermalConfig>,
    /// `[laser]`: a moving Gaussian beam (needs `[thermal]`).
    pub laser: Option<LaserConfig>,
    /// `[guards]`: limits at which a run stops (docs/stability.md); defaults apply when absent.
    pub guards: Option<GuardsConfig>,
    /// `[periodic]`: axes along which the domain repeats (M.77); absent: none.
    pub periodic: Option<PeriodicConfig>,
    /// `[domain]`: the box particles may occupy; those that leave it are removed (M.78).
    pub domain: Option<DomainConfig>,
}

/// `[domain]`: a particle whose centre leaves this box is removed from the run and counted
/// (M.78). Along periodic axes the box is not used (particles wrap instead).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DomainConfig {
    /// Lower corner \[m\].
    pub min_corner_m: [f64; 3],
    /// Upper corner \[m\].
    pub max_corner_m: [f64; 3],
}

/// `[periodic]`: the bounds `[lower, upper]` of each periodic axis \[m\]; an axis not given is not
/// periodic. The domain repeats with period `upper − lower`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeriodicConfig {
    /// Periodic in x between these bounds \[m\].
    pub x_m: Option<[f64; 2]>,
    /// Periodic in y between these bounds \[m\].
    pub y_m: Option<[f64; 2]>,
    /// Periodic in z between these bounds \[m\].
    pub z_m: Option<[f64; 2]>,
}

impl PeriodicConfig {
    /// `(key, axis index, bounds)` of the periodic axes given.
    #[must_use]
    pub fn axes(&self) -> Vec<(&'static str, usize, [f64; 2])> {
        [
            ("periodic.x_m", self.x_m),
            ("periodic.y_m", self.y_m),
            ("periodic.z_m", self.z_m),
        ]
        .into_iter()
        .enumerate()
        .filter_map(|(axis, (key, bounds))| bounds.map(|b| (key, axis, b)))
        .collect()
    }
}

/// `[guards]`: when a run stops itself instead of writing a state that is no longer physical.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuardsConfig {
    /// Stop when an overlap exceeds this fraction of the smaller radius of its pair, `> 0`;
    /// default [`DEFAULT_MAX_OVERLAP_RATIO`].
    pub max_overlap_ratio: Option<f64>,
    /// Stop when the mechanical energy balance (M.35) shows more than this fraction of the
    /// energy scale created from nothing, `> 0`; default [`DEFAULT_MAX_ENERGY_RESIDUAL`].
    pub max_energy_residual: Option<f64>,
}

/// Default `guards.max_overlap_ratio`: at δ = 0.3 r Hertz theory (δ ≪ r) no longer describes
/// the contact, and a run that gets there has a time step or a scene problem.
pub const DEFAULT_MAX_OVERLAP_RATIO: f64 = 0.3;
/// Default `guards.max_energy_residual`: the energy balance of a sound run closes to a few
/// percent (first order in dt, docs/accuracy.md); 50 % more energy than the scale is a blow-up.
pub const DEFAULT_MAX_ENERGY_RESIDUAL: f64 = 0.5;

/// `[scene]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneHeader {
    /// Must equal [`FORMAT_VERSION`].
    pub version: u32,
    /// Free text, printed at the start of a run.
    #[serde(default)]
    pub title: String,
}

/// `[simulation]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationConfig {
    /// Time step \[s\], `> 0`.
    pub dt_s: f64,
    /// Simulated time \[s\], `> 0`; the run takes `ceil(duration_s / dt_s)` steps.
    pub duration_s: f64,
    /// Gravitational acceleration [m/s²]; default none.
    #[serde(default)]
    pub gravity_m_s2: [f64; 3],
    /// Verlet-list skin \[m\], `> 0`; default 10 % of the smallest particle diameter.
    pub skin_m: Option<f64>,
    /// Largest relative impact speed expected [m/s], for `am-sim check`'s time-step advice;
    /// default: twice the largest initial speed, or the free-fall speed over the scene height.
    pub expected_impact_speed_m_s: Option<f64>,
}

/// `[materials.NAME]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialConfig {
    /// Mass density [kg/m³], `> 0`.
    pub density_kg_m3: f64,
    /// Young's modulus \[Pa\], `> 0`.
    pub youngs_modulus_pa: f64,
    /// Poisson ratio, in `(−1, 0.5)`.
    pub poisson_ratio: f64,
    /// Specific heat c [J/(kg·K)], `> 0`; needed with `[thermal]`.
    pub specific_heat_j_kg_k: Option<f64>,
    /// Thermal conductivity k [W/(m·K)], `> 0`; needed with `[thermal]`.
    pub thermal_conductivity_w_m_k: Option<f64>,
    /// Melting point \[K\], `> 0`; needed with `[thermal]`.
    pub melting_point_k: Option<f64>,
    /// Latent heat of fusion L [J/kg], `≥ 0`; default 0 (melting takes no heat).
    pub latent_heat_j_kg: Option<f64>,
    /// Boiling point T_b \[K\], above `melting_point_k`: the material evaporates there (M.80), so
    /// its particles never pass it; absent: no evaporation, and no bound on the temperature.
    /// Needs `latent_heat_vaporization_j_kg`.
    pub boiling_point_k: Option<f64>,
    /// Latent heat of vaporisation L_v [J/kg], `> 0`: the mass the vapour carries off per joule
    /// (reported, not taken from the particle). Needs `boiling_point_k`.
    pub latent_heat_vaporization_j_kg: Option<f64>,
    /// Emissivity in `[0, 1]`; needed with `[thermal.radiation]`.
    pub emissivity: Option<f64>,
    /// Laser absorptivity in `[0, 1]`; needed with `[laser]`.
    pub absorptivity: Option<f64>,
}

/// `[contact]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactConfig {
    /// Normal contact model; only `"hertz"` (paper eqs. 12, 26).
    pub model: ContactModel,
    /// Contact damping ratio ξ_con of paper eq. 26, `≥ 0`; or give `restitution`.
    pub damping_ratio: Option<f64>,
    /// Restitution coefficient e in `(0, 1]`, converted to ξ_con as LIGGGHTS does (M.55); give
    /// exactly one of it and `damping_ratio`.
    pub restitution: Option<f64>,
    /// Sliding friction coefficient μ, `≥ 0`: Mindlin tangential spring with a Coulomb limit
    /// (M.56–M.60), and particle rotation; absent: no tangential force.
    pub friction_coefficient: Option<f64>,
    /// Rolling friction coefficient μ_r, `≥ 0`: constant directional torque (M.61), and particle
    /// rotation; absent: no rolling resistance.
    pub rolling_friction_coefficient: Option<f64>,
}

impl ContactConfig {
    /// ξ_con: `damping_ratio`, or the one converted from `restitution` (M.55); 0 if neither is
    /// given (validation rejects that).
    #[must_use]
    pub fn resolved_damping_ratio(&self) -> f64 {
        match (self.damping_ratio, self.restitution) {
            (Some(xi), _) => xi,
            (None, Some(e)) => crate::contact::damping::damping_ratio_from_restitution(e),
            (None, None) => 0.0,
        }
    }

    /// True when the scene asks for tangential friction or rolling resistance, and hence rotation.
    #[must_use]
    pub fn has_rotation(&self) -> bool {
        self.friction_coefficient.is_some() || self.rolling_friction_coefficient.is_some()
    }
}

/// Normal contact models.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ContactModel {
    /// Hertz with the nonlinear viscous damping of paper eq. 26.
    Hertz,
}

/// `[bond]`: paper eqs. 13-25. Give exactly one of `adhesion_stiffness` and `equilibrium_overlap_m`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BondConfig {
    /// Adhesion exponent α_adh, `0 ≤ α_adh < 1.5`.
    pub adhesion_exponent: f64,
    /// Adhesion stiffness k_adh [N·m^(−α_adh)], `≥ 0`.
    pub adhesion_stiffness: Option<f64>,
    /// Equilibrium overlap δ_eq \[m\], `> 0`: k_adh is derived from it by paper eq. 13 (as in the
    /// paper's section 5.1) for two spheres of radius `reference_radius_m`.
    pub equilibrium_overlap_m: Option<f64>,
    /// Radius of the two equal spheres at which `equilibrium_overlap_m` holds \[m\]; default the
    /// radius of the particles when they all have the same one.
    pub reference_radius_m: Option<f64>,
    /// Bond damping ratio ξ_bond of paper eq. 23, `≥ 0`.
    pub damping_ratio: f64,
    /// When the bond criterion holds.
    pub criterion: CriterionConfig,
    /// With `criterion = "melting"`: whether both particles (default) or either must have melted.
    pub melting_rule: Option<MeltingRule>,
}

/// Which particles of a pair must have reached their melting point.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum MeltingRule {
    /// Both particles (default).
    #[default]
    Both,
    /// At least one of them.
    Either,
}

/// The bond criterion of paper eq. 25.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum CriterionConfig {
    /// Holds for every pair at all times (a bond forms whenever `δ ≥ δ_crit`).
    Always,
    /// Never holds (the bonded branch is never entered).
    Never,
    /// Holds once the particles' temperatures have reached their melting points (latched per
    /// particle); needs `[thermal]`.
    Melting,
}

/// `[[particles]]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleConfig {
    /// Centre \[m\].
    pub position_m: [f64; 3],
    /// Velocity [m/s]; default at rest.
    #[serde(default)]
    pub velocity_m_s: [f64; 3],
    /// Radius \[m\], `> 0`.
    pub radius_m: f64,
    /// Name of a `[materials.NAME]` table.
    pub material: String,
}

/// `[[lattice]]`: a simple cubic lattice of equal spheres filling a box.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LatticeConfig {
    /// Lower corner of the box \[m\]; every sphere lies fully inside the box, jitter included.
    pub min_corner_m: [f64; 3],
    /// Upper corner of the box \[m\].
    pub max_corner_m: [f64; 3],
    /// Radius \[m\], `> 0`.
    pub radius_m: f64,
    /// Distance between neighbouring lattice sites \[m\]; default `2 radius_m` (touching). Down to
    /// `1.8 radius_m` gives a pre-compressed lattice (initial overlaps up to 20 % of the radius).
    pub spacing_m: Option<f64>,
    /// Random displacement of each site, uniform in `[−jitter_m, jitter_m]` per axis \[m\];
    /// `jitter_m ≤ (spacing − 2 radius)/2` so that no two spheres overlap. Default 0.
    #[serde(default)]
    pub jitter_m: f64,
    /// Seed of the jitter's random sequence (the same seed gives the same positions).
    #[serde(default)]
    pub seed: u64,
    /// Velocity of every particle [m/s]; default at rest.
    #[serde(default)]
    pub velocity_m_s: [f64; 3],
    /// Name of a `[materials.NAME]` table.
    pub material: String,
}

/// `[[insert]]`: spheres with diameters drawn from `[insert.size]`, placed one by one (largest
/// first) at uniformly random positions in a box, none overlapping another or a particle of an
/// earlier source. Give `count` or `solid_fraction`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsertConfig {
    /// Lower corner of the box \[m\]; every sphere lies fully inside it.
    pub min_corner_m: [f64; 3],
    /// Upper corner of the box \[m\].
    pub max_corner_m: [f64; 3],
    /// Number of spheres, `≥ 1`.
    pub count: Option<u64>,
    /// Solid volume fraction of the box to fill, in `(0, 0.74]`: diameters are drawn until
    /// their volume reaches it (random sequential addition jams near 0.38).
    pub solid_fraction: Option<f64>,
    /// `[insert.size]`: the distribution of diameters.
    pub size: SizeConfig,
    /// Seed of the random sizes and positions (the same seed gives the same bed).
    #[serde(default)]
    pub seed: u64,
    /// Velocity of every sphere [m/s]; default at rest.
    #[serde(default)]
    pub velocity_m_s: [f64; 3],
    /// Name of a `[materials.NAME]` table.
    pub material: String,
}

/// Families of size distributions.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum DistributionKind {
    /// One diameter, `diameter_m`.
    Constant,
    /// Normal in D.
    Normal,
    /// Normal in ln D.
    Lognormal,
}

/// `[insert.size]`: a distribution of **diameters** (not radii), as powder data sheets give
/// them. `constant` takes `diameter_m`; `normal` and `lognormal` take either `mean_m` and
/// `std_m` (of D) or `d10_m`, `d50_m` and `d90_m`; all may be truncated to `[min_m, max_m]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SizeConfig {
    /// The family.
    pub distribution: DistributionKind,
    /// Diameter of a `constant` distribution \[m\].
    pub diameter_m: Option<f64>,
    /// Mean diameter \[m\].
    pub mean_m: Option<f64>,
    /// Standard deviation of the diameter \[m\].
    pub std_m: Option<f64>,
    /// 10 % of the particles (by number) are smaller \[m\].
    pub d10_m: Option<f64>,
    /// Median diameter \[m\].
    pub d50_m: Option<f64>,
    /// 90 % of the particles (by number) are smaller \[m\].
    pub d90_m: Option<f64>,
    /// Smallest diameter kept \[m\]; smaller draws are redrawn (truncation, not clamping).
    pub min_m: Option<f64>,
    /// Largest diameter kept \[m\]; larger draws are redrawn.
    pub max_m: Option<f64>,
}

/// File formats of `[[import]]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ImportFormat {
    /// am-sim particle CSV (header `x_m,y_m,z_m,radius_m[,vx_m_s,vy_m_s,vz_m_s,id,material]`).
    Csv,
    /// LIGGGHTS/LAMMPS `dump custom` text.
    LiggghtsDump,
    /// A frame of an am-sim HDF5 output file.
    AmSimH5,
}

/// `[[import]]`: particles read from a file (x' = scale·x + shift, r' = scale·r, v' = scale·v).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImportConfig {
    /// The file, relative to the scene file's folder; `.gz` text files are decompressed.
    pub file: String,
    /// Its format.
    pub format: ImportFormat,
    /// `am_sim_h5`: frame number to read; default the last complete frame.
    pub frame: Option<usize>,
    /// `liggghts_dump`: timestep of the snapshot to read; default the last snapshot.
    pub timestep: Option<u64>,
    /// Material of the particles (required unless every CSV row names one).
    pub material: Option<String>,
    /// Factor on positions, radii and velocities (e.g. 1e-3 for a file in mm); default 1.
    pub scale: Option<f64>,
    /// Added to every position after scaling \[m\]; default none.
    #[serde(default)]
    pub shift_m: [f64; 3],
    /// `liggghts_dump`: the tangential springs of the particles' contacts, a LIGGGHTS `dump
    /// local` of `compute ID all pair/gran/local id history` (`bed::contact_history`), relative
    /// to the scene file's folder; needs tangential contact (`contact.friction_coefficient`).
    pub pair_history_file: Option<String>,
    /// `liggghts_dump`: for each `[[walls]]` entry in order, the prefix `P` of the dump's columns
    /// `P[1] P[2] P[3]` holding the particles' tangential springs against that wall \[m\] (LIGGGHTS
    /// keeps those of `fix ID wall/gran ... tangential history` in `f_history_ID[1..3]`), or ""
    /// for a wall without; needs tangential contact.
    #[serde(default)]
    pub wall_history_columns: Vec<String>,
}

/// `[deposition]`: before the run, the particles fall under gravity with the laser off until
/// the mean kinetic energy per particle is at most `kinetic_energy_ratio` × m̄ g d̄ (M.75).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepositionConfig {
    /// Deposition time after which an unsettled bed stops the run with an error \[s\], `> 0`.
    pub max_duration_s: f64,
    /// Settling threshold, `> 0`; default 1e-4.
    pub kinetic_energy_ratio: Option<f64>,
    /// Steps between checks of the criterion, `≥ 1`; default 1000.
    pub check_every_steps: Option<u64>,
    /// Background damping during deposition (M.76): velocities decay as exp(−t/τ) besides the
    /// contacts' damping \[s\], `> 0`; default none. Frictionless spheres need it to come to rest.
    pub damping_time_s: Option<f64>,
}

/// `[[walls]]`: an infinite plane; particles stay on the side the normal points to.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallConfig {
    /// A point of the plane \[m\].
    pub point_m: [f64; 3],
    /// Normal pointing into the domain (any length `> 0`; normalised).
    pub normal: [f64; 3],
    /// Name of a `[materials.NAME]` table (for E* of the particle–wall contact).
    pub material: String,
    /// Fixed temperature of the wall \[K\] (needs `[thermal]`); absent: the wall is adiabatic.
    pub temperature_k: Option<f64>,
}

/// `[output]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// HDF5 file of frames, series and restart data, with an XDMF companion `<stem>.xmf`
    /// (relative to the working directory).
    pub file: Option<String>,
    /// Steps between two frames, `≥ 1`; or give `every_s`. Default: 100 frames per run.
    pub every_steps: Option<u64>,
    /// Simulated time between two frames \[s\], `> 0` (rounded to whole steps).
    pub every_s: Option<f64>,
    /// Optional per-particle and per-bond fields to write (`id`, `position`, `velocity` and
    /// `radius` always are); default: every field the scene has.
    pub fields: Option<Vec<String>>,
    /// Deflate level 0-9 of the frame datasets; default 0 (no compression: fastest).
    pub deflate: Option<u8>,
    /// Write restart data with every frame (`--restart` needs it); default true.
    pub restart: Option<bool>,
    /// CSV file with the time series (same columns as the HDF5 `/series`).
    pub series_csv: Option<String>,
    /// Steps between two series rows, `≥ 1`; default: the frame cadence.
    pub series_every_steps: Option<u64>,
}

impl Scene {
    /// True when the scene has `[thermal]` and a material with a boiling point (M.80).
    #[must_use]
    pub fn has_evaporation(&self) -> bool {
        self.thermal.is_some() && self.materials.values().any(|m| m.boiling_point_k.is_some())
    }

    /// Reads, parses and validates a scene file.
    ///
    /// # Errors
    /// [`SceneError`] naming the file, and the key, value and reason of every problem found.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_owned(),
            source,
        })?;
        let mut scene = Self::from_toml(&text).map_err(|e| e.in_file(path))?;
        scene.base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(scene)
    }

    /// Parses and validates scene text.
    ///
    /// # Errors
    /// [`SceneError::Parse`] for TOML syntax and type errors (with the dotted key path),
    /// [`SceneError::Invalid`] with every range and consistency violation.
    pub fn from_toml(text: &str) -> Result<Self, SceneError> {
        let deserializer = toml::Deserializer::parse(text).map_err(|e| SceneError::Parse {
            path: None,
            key: String::new(),
            message: e.to_string(),
        })?;
        let scene: Scene = serde_path_to_error::deserialize(deserializer).map_err(|e| {
            let key = e.path().to_string();
            SceneError::Parse {
                path: None,
                key,
                message: e.into_inner().to_string(),
            }
        })?;
        let violations = validate::validate(&scene);
        if violations.is_empty() {
            Ok(scene)
        } else {
            Err(SceneError::Invalid {
                path: None,
                violations,
            })
        }
    }
}

/// `[thermal]`: lumped heat transfer, one temperature per particle.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalConfig {
    /// Temperature of every particle at t = 0 \[K\], `> 0`.
    pub initial_temperature_k: f64,
    /// Contact conductance model (no default: the models differ by orders of magnitude).
    pub conduction: ConductionConfig,
    /// Sub-cycling safety factor θ in `(0, 1]` (docs/model.md, M.49); default 0.5.
    pub substep_fraction: Option<f64>,
    /// `[thermal.convection]`: Newton cooling to a gas.
    pub convection: Option<ConvectionConfig>,
    /// `[thermal.radiation]`: grey-body radiation to the surroundings.
    pub radiation: Option<RadiationConfig>,
    /// `[[thermal.initial_region]]`: boxes whose particles start at their own temperature.
    #[serde(default)]
    pub initial_region: Vec<InitialRegionConfig>,
}

/// `[[thermal.initial_region]]`: the particles whose centre lies in this box (bounds included)
/// at the start of the run start at `temperature_k` instead of `initial_temperature_k`; where
/// regions overlap, the later one wins, as successive `set region ... property/atom Temp` do in
/// LIGGGHTS. The start of the run is t = 0: after the `[deposition]` if the scene has one, so
/// that a region can name the top of the settled bed.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialRegionConfig {
    /// Lower corner \[m\]; `-inf` leaves an axis unbounded below (TOML writes it `-inf`).
    pub min_corner_m: [f64; 3],
    /// Upper corner \[m\]; `inf` leaves an axis unbounded above.
    pub max_corner_m: [f64; 3],
    /// Initial temperature of the particles in the box \[K\], `> 0`.
    pub temperature_k: f64,
}

/// Contact conductance models.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ConductionConfig {
    /// `H = 2 k* a` (Batchelor & O'Brien 1977).
    BatchelorObrien,
    /// `H = k̄ π a² / d` (the thermal pipe of Quintana-Ruiz & Campello 2020).
    ThermalPipe,
    /// `H = 2 k* √(π a_g²)` over the geometric intersection of the spheres (LIGGGHTS'
    /// `heat/gran/conduction`).
    OverlapArea,
    /// No conduction through contacts.
    None,
}

/// `[thermal.convection]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConvectionConfig {
    /// Heat-transfer coefficient h [W/(m²·K)], `≥ 0`.
    pub heat_transfer_coefficient_w_m2_k: f64,
    /// Gas temperature \[K\], `> 0`.
    pub gas_temperature_k: f64,
}

/// `[thermal.radiation]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadiationConfig {
    /// Temperature of the surroundings \[K\], `≥ 0`.
    pub environment_temperature_k: f64,
}

/// `[laser]`: a Gaussian beam shining down −z along a scan path.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaserConfig {
    /// Beam power P \[W\], `> 0`.
    pub power_w: f64,
    /// 1/e² radius w \[m\], `> 0`.
    pub spot_radius_m: f64,
    /// Time at which the scan path starts \[s\], `≥ 0`; default 0.
    #[serde(default)]
    pub start_time_s: f64,
    /// Side of the ray-casting cells \[m\], `> 0`; default a tenth of the smallest radius, but no
    /// smaller than 6w/1024 (at most 1024 rays across the ±3w window).
    pub raster_cell_m: Option<f64>,
    /// `[laser.path]`: where the beam goes.
    pub path: PathConfig,
}

/// The scan path, chosen by `kind`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PathConfig {
    /// Straight segments through the points, at constant speed, laser on throughout.
    Polyline {
        /// Points (x, y) \[m\], at least two.
        points_m: Vec<[f64; 2]>,
        /// Scan speed [m/s], `> 0`.
        speed_m_s: f64,
    },
    /// Parallel tracks in alternating directions (a meander), laser off while jumping.
    Hatch {
        /// Start of the first track (x, y) \[m\].
        start_m: [f64; 2],
        /// Length of each track \[m\], `> 0`.
        track_length_m: f64,
        /// Distance between neighbouring tracks \[m\], `> 0`.
        hatch_spacing_m: f64,
        /// Number of tracks, `≥ 1`.
        tracks: u32,
        /// Scan speed along a track [m/s], `> 0`.
        speed_m_s: f64,
        /// Axis of the tracks: `"x"` (default) or `"y"`; tracks step along the other axis.
        #[serde(default)]
        direction: Axis,
        /// Time the beam takes (laser off) to reach the next track \[s\], `≥ 0`; default 0.
        #[serde(default)]
        jump_time_s: f64,
    },
    /// A beam standing still.
    Stationary {
        /// Beam axis (x, y) \[m\].
        position_m: [f64; 2],
        /// How long it shines \[s\], `> 0`.
        duration_s: f64,
    },
}

/// A horizontal axis.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// Along x.
    #[default]
    X,
    /// Along y.
    Y,
}
