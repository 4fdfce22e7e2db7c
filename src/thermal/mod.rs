//! Lumped heat transfer: one temperature per sphere (M.47),
//!
//! ```text
//! dE_i/dt = Σ_j H_ij (T_j − T_i) + Σ_walls H_iw (T_w − T_i) + h A_i (T_gas − T_i)
//!           + ε_i σ A_i (T_env⁴ − T_i⁴) + P_laser,i                                   [W]
//! ```
//!
//! with the enthalpy `E_i` carrying the latent heat of fusion (M.48) and `T_i = T(E_i)`. A
//! material with a boiling point evaporates there (M.80): enthalpy beyond `C T_b + m L` leaves
//! with the vapour, so its particles never pass `T_b`.
//!
//! # Time integration (M.49)
//! Sub-cycled explicit Euler on the enthalpy: the mechanical step is split into `n` substeps with
//! `n = ⌈dt · max_i(G_i / C_i) / θ⌉`, where `G_i` is particle i's total conductance (contacts,
//! walls, convection, linearised radiation) and `C_i = m_i c_i` its heat capacity. With `θ ≤ 1`
//! every substep writes each new temperature as a convex combination of old temperatures and the
//! ambient ones, so no temperature overshoots the range of its neighbours (discrete maximum
//! principle), however stiff the contact network. The count is fixed from the conductances at the
//! start of the step; contact conductances do not change within it, and radiation's is taken at
//! `max(T, T_m, T_env)`, so only a particle heated far past its melting point within one step can
//! exceed it, which the default θ = 1/2 leaves a factor of two for. The usual
//! powder bed has `G dt / C ≪ 1` and takes one substep. Heat is exchanged pairwise with
//! `±H (T_j − T_i)`, which IEEE arithmetic makes exactly antisymmetric, so conduction conserves the
//! total heat to round-off.
//!
//! A scene without `[thermal]` has no `ThermalState`: no arrays, no passes.

pub mod boundary;
pub mod conduction;
pub mod losses;

pub(crate) use boundary::BoundaryLanes;
pub use boundary::boundary_heat;

use glam::DVec3;

use crate::model::Wall;
use crate::neighbor::NeighborList;
use crate::particles::Particles;
use crate::team::{PARTICLES_PER_ITEM, optional_items};

/// Thermal data of one material (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalMaterial {
    /// Specific heat c [J/(kg·K)].
    pub specific_heat: f64,
    /// Thermal conductivity k [W/(m·K)].
    pub conductivity: f64,
    /// Melting point T_m \[K\].
    pub melting_point: f64,
    /// Latent heat of fusion L [J/kg] (0: melting takes no heat).
    pub latent_heat: f64,
    /// Emissivity ε (for radiation).
    pub emissivity: f64,
    /// Absorptivity of laser light (fraction of the incident power absorbed).
    pub absorptivity: f64,
    /// Where and at what cost the material evaporates (M.80); `None`: it never does, and its
    /// temperature has no bound.
    pub vaporization: Option<Vaporization>,
}

/// Evaporation of a material at its boiling point (M.80).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vaporization {
    /// Boiling point T_b \[K\], above the melting point.
    pub boiling_point: f64,
    /// Latent heat of vaporisation L_v [J/kg], `> 0`: what the heat carried off by the vapour
    /// weighs as evaporated mass.
    pub latent_heat: f64,
}

/// The contact conductance model chosen in the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConductionModel {
    /// No conduction through contacts.
    None,
    /// `H = 2 k* a` (M.41).
    BatchelorObrien,
    /// `H = k̄ π a² / d` (M.42).
    ThermalPipe,
    /// `H = 2 k* √(π a_g²)` over the spheres' geometric intersection (M.79), as LIGGGHTS.
    OverlapArea,
}

/// Resolved thermal parameters of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalModel {
    /// Per material, indexed like `Model::materials`.
    pub materials: Vec<ThermalMaterial>,
    /// Contact conductance model.
    pub conduction: ConductionModel,
    /// `(h [W/(m²·K)], T_gas [K])`, if convection is on.
    pub convection: Option<(f64, f64)>,
    /// Surroundings temperature T_env \[K\], if radiation is on.
    pub radiation: Option<f64>,
    /// Per wall: its fixed temperature \[K\], or `None` for an adiabatic wall.
    pub wall_temperatures: Vec<Option<f64>>,
    /// Initial temperature of every particle outside `initial_regions` \[K\].
    pub initial_temperature: f64,
    /// Boxes whose particles start at their own temperature, the later winning where they
    /// overlap (applied at the start of the run: [`ThermalModel::region_temperature`]).
    pub initial_regions: Vec<InitialRegion>,
    /// θ of (M.49): a substep is at most θ times the smallest `C_i / G_i`; `0 < θ ≤ 1`.
    pub substep_fraction: f64,
    /// `k*` of every pair of materials, `[a * materials.len() + b]`, derived from `materials` by
    /// [`ThermalModel::tabulated`] (so that the pair pass divides nothing).
    pub harmonic_conductivities: Vec<f64>,
}

/// A box of particles with their own initial temperature (`[[thermal.initial_region]]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialRegion {
    /// Lower corner \[m\] (components may be −∞).
    pub lower: DVec3,
    /// Upper corner \[m\] (components may be +∞).
    pub upper: DVec3,
    /// Temperature \[K\].
    pub temperature: f64,
}

impl InitialRegion {
    /// Whether `x` lies in the box, bounds included.
    #[must_use]
    pub fn contains(&self, x: DVec3) -> bool {
        x.cmpge(self.lower).all() && x.cmple(self.upper).all()
    }
}

impl ThermalModel {
    /// The initial temperature \[K\] of the last initial region holding `x`, if one does (a
    /// particle outside every region starts at `initial_temperature`).
    #[must_use]
    pub fn region_temperature(&self, x: DVec3) -> Option<f64> {
        self.initial_regions
            .iter()
            .rev()
            .find(|r| r.contains(x))
            .map(|r| r.temperature)
    }

    /// A model of `materials` with `conduction` and nothing else (no convection, radiation,
    /// held walls or initial regions; 300 K; θ = 0.5), tabulated: what tests start from.
    #[cfg(test)]
    pub(crate) fn bare(materials: Vec<ThermalMaterial>, conduction: ConductionModel) -> Self {
        Self {
            materials,
            conduction,
            convection: None,
            radiation: None,
            wall_temperatures: Vec::new(),
            initial_temperature: 300.0,
            initial_regions: Vec::new(),
            substep_fraction: 0.5,
            harmonic_conductivities: Vec::new(),
        }
        .tabulated()
    }

    /// The model with its per-pair tables derived from `materials`; every model is built with
    /// it, since the tables are what the pair pass reads.
    #[must_use]
    pub fn tabulated(mut self) -> Self {
        let conductivities: Vec<f64> = self.materials.iter().map(|m| m.conductivity).collect();
        self.harmonic_conductivities = conductivities
            .iter()
            .flat_map(|&ka| {
                conductivities
                    .iter()
                    .map(move |&kb| 2.0 * ka * kb / (ka + kb))
            })
            .collect();
        self
    }

    /// `k* = 2 k_a k_b / (k_a + k_b)` of materials a and b [W/(m·K)] (M.41), from the table.
    #[must_use]
    #[inline]
    pub fn harmonic_conductivity(&self, a: u16, b: u16) -> f64 {
        self.harmonic_conductivities[usize::from(a) * self.materials.len() + usize::from(b)]
    }

    /// What a contact between materials a and b needs for its conductance
    /// ([`contact_conductance`]).
    #[must_use]
    #[inline]
    pub fn pair_conductivities(&self, a: u16, b: u16) -> PairConductivities {
        PairConductivities {
            harmonic: self.harmonic_conductivity(a, b),
            each: [
                self.materials[usize::from(a)].conductivity,
                self.materials[usize::from(b)].conductivity,
            ],
        }
    }

    /// The smallest specific heat of the model's materials [J/(kg·K)] (infinite for none):
    /// every particle's heat capacity is at least its mass times it ([`HeatRate::at_most`]).
    #[must_use]
    pub fn smallest_specific_heat(&self) -> f64 {
        (self.materials.iter()).fold(f64::INFINITY, |c, m| c.min(m.specific_heat))
    }

    /// Whether particles exchange heat with anything outside the bed (isothermal walls, gas,
    /// surroundings).
    #[must_use]
    pub fn has_boundary_exchange(&self) -> bool {
        self.convection.is_some()
            || self.radiation.is_some()
            || self.wall_temperatures.iter().any(Option::is_some)
    }

    /// Whether no heat can flow in `state` without a laser: every particle solid at one
    /// temperature T, which every boundary the model exchanges with (held walls, gas,
    /// surroundings) has too. Every term of the heat balance (M.40-M.47) is then a conductance
    /// times a difference of equal temperatures, and the temperatures can only move by the
    /// rounding of `T(E)` (M.48), an ulp of T. A scene whose bed deposits at room temperature is
    /// in this state until its laser starts.
    #[must_use]
    pub fn is_inert(&self, state: &ThermalState) -> bool {
        let Some(&t) = state.temperature.first() else {
            return true;
        };
        let mut boundaries = self
            .wall_temperatures
            .iter()
            .flatten()
            .chain(self.convection.as_ref().map(|(_, t_gas)| t_gas))
            .chain(self.radiation.as_ref());
        state.temperature.iter().all(|&t_k| t_k == t)
            && !state.melted.iter().any(|&m| m)
            && boundaries.all(|&t_b| t_b == t)
    }
}

/// Per-particle thermal state (structure of arrays, like `Particles`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ThermalState {
    /// Temperature \[K\], `T(E)` of (M.48).
    pub temperature: Vec<f64>,
    /// Enthalpy \[J\], the integrated state (M.48).
    pub enthalpy: Vec<f64>,
    /// Where each particle's heat capacity `C = m c`, melting point and latent heat `m L` come
    /// from: a scene of one material makes them from the masses, several keep a column each
    /// ([`ThermalState::heat_constants`] reads them).
    pub(crate) materials: HeatMaterials,
    /// With a material that evaporates: its particles' boiling enthalpies and the heat their
    /// vapour carried off (M.80). `None` otherwise: no arrays, and no test in the update.
    pub evaporation: Option<Evaporation>,
    /// Latched bond criterion: the particle has reached its melting point at some time.
    pub melted: Vec<bool>,
    /// With a `[laser]`: each particle's absorbed power and energy. `None` otherwise: no
    /// arrays, and neither the passes nor the output carry them.
    pub laser: Option<LaserHeat>,
    /// Per pair slot of the neighbour list: contact conductance H [W/K] of this step, stored
    /// only by a step that takes more than one thermal substep ([`advance`]); stale otherwise.
    pub conductance: Vec<f64>,
    /// Per particle: the net heat flow into it at the start of the current substep \[W\]
    /// (M.47), the sum of what its contacts, walls, gas and laser give it. Its total
    /// conductance G_i (M.49) is not kept: the force pass bounds the largest `G_i / C_i`
    /// without it ([`HeatRate::at_most`]), and only a step whose bound asks for more than one
    /// substep sums the G_i, in a pass of its own ([`max_stiffness`]).
    pub(crate) heat_flow: Vec<f64>,
    /// Where the model exchanges heat with held walls, a gas or the surroundings
    /// ([`ThermalModel::has_boundary_exchange`]): each particle's boundary flow and energy.
    /// `None` otherwise: no arrays, and no accumulation in the update.
    pub boundary: Option<BoundaryHeat>,
    /// Per particle: the enthalpy at the start of this run \[J\] ([`ThermalState::mark_start`]).
    /// The heat balance compares particle by particle: a sum of small changes, not the
    /// difference of two large sums, whose round-off would swamp a bed's conduction.
    pub start_enthalpy: Vec<f64>,
    /// Substeps taken in the last step.
    pub substeps: u32,
    /// Most substeps taken in one step so far.
    pub max_substeps: u32,
}

impl ThermalState {
    /// Reorders the thermal state like `Particles::select`; the per-pair conductances are
    /// rebuilt with the neighbour list.
    pub fn select(&mut self, order: &[u32]) {
        use crate::particles::select;
        select(&mut self.temperature, order);
        select(&mut self.enthalpy, order);
        self.materials.select(order);
        if let Some(evaporation) = &mut self.evaporation {
            select(&mut evaporation.boiling_enthalpy, order);
            select(&mut evaporation.evaporated, order);
        }
        select(&mut self.melted, order);
        select(&mut self.heat_flow, order);
        if let Some(laser) = &mut self.laser {
            select(&mut laser.power, order);
            select(&mut laser.energy, order);
        }
        if let Some(boundary) = &mut self.boundary {
            select(&mut boundary.flow, order);
            select(&mut boundary.energy, order);
        }
        select(&mut self.start_enthalpy, order);
    }

    /// Makes the current enthalpies the start of the heat balance.
    pub fn mark_start(&mut self) {
        self.start_enthalpy.clone_from(&self.enthalpy);
    }

    /// Since the start of this run, summed in index order (reproducible): `(Σ ΔE_i, ½ Σ |ΔE_i|)`
    /// \[J\], the heat stored and the heat that changed hands (moved between particles or came
    /// in), with `ΔE_i = E_i − E_i(start)`.
    #[must_use]
    pub fn enthalpy_change(&self) -> (f64, f64) {
        self.enthalpy
            .iter()
            .zip(&self.start_enthalpy)
            .fold((0.0, 0.0), |(stored, moved), (e, e0)| {
                (stored + (e - e0), moved + 0.5 * (e - e0).abs())
            })
    }
}

/// Per particle, the heat a `[laser]` brings (structure of arrays, like [`ThermalState`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LaserHeat {
    /// Laser power absorbed during the current step \[W\] (M.51).
    pub power: Vec<f64>,
    /// Laser energy absorbed since the start \[J\]. Kept per particle, so that the pass that adds
    /// to it writes only its own slot; totals are summed when asked for.
    pub energy: Vec<f64>,
}

/// Per particle, the heat exchanged with held walls, a gas and the surroundings (structure of
/// arrays, like [`ThermalState`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoundaryHeat {
    /// Heat flow into each particle at the start of the current substep \[W\] (M.43-M.45, part
    /// of the net flow M.47).
    pub(crate) flow: Vec<f64>,
    /// Heat received since the start \[J\] (negative: lost).
    pub energy: Vec<f64>,
}

/// Per particle, where evaporation begins and what it has carried off (M.80), structure of
/// arrays like [`ThermalState`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Evaporation {
    /// The boiling enthalpy `E_b = C T_b + m L` \[J\]: `+∞` for a particle whose material does
    /// not evaporate.
    pub boiling_enthalpy: Vec<f64>,
    /// Heat carried off by the particle's vapour since the start \[J\].
    pub evaporated: Vec<f64>,
}

/// Evaporation at the boiling point (M.80): a particle's enthalpy beyond its boiling enthalpy
/// `E_b = C T_b + m L` leaves with the vapour at once, so that `T(E) ≤ T_b`. Returns `(the
/// enthalpy kept, the heat carried off)` \[J\]; `E ≤ E_b` is kept whole.
#[must_use]
#[inline]
pub fn evaporate(enthalpy: f64, boiling_enthalpy: f64) -> (f64, f64) {
    if enthalpy > boiling_enthalpy {
        (boiling_enthalpy, enthalpy - boiling_enthalpy)
    } else {
        (enthalpy, 0.0)
    }
}

/// Temperature of a particle from its enthalpy (M.48) \[K\]:
///
/// ```text
/// T = E / C                     for E < C T_m          (solid)
/// T = T_m                       for C T_m ≤ E ≤ C T_m + m L   (melting)
/// T = (E − m L) / C             above                  (liquid)
/// ```
#[must_use]
#[inline]
pub fn temperature_from_enthalpy(
    enthalpy: f64,
    heat_capacity: f64,
    melting_point: f64,
    latent_heat: f64,
) -> f64 {
    let solidus = heat_capacity * melting_point;
    if enthalpy < solidus {
        enthalpy / heat_capacity
    } else if enthalpy <= solidus + latent_heat {
        melting_point
    } else {
        (enthalpy - latent_heat) / heat_capacity
    }
}

/// Enthalpy of a particle at temperature `T` (M.48) \[J\]; a particle at exactly T_m is solid.
#[must_use]
#[inline]
pub fn enthalpy_from_temperature(
    temperature: f64,
    heat_capacity: f64,
    melting_point: f64,
    latent_heat: f64,
) -> f64 {
    if temperature <= melting_point {
        heat_capacity * temperature
    } else {
        heat_capacity * temperature + latent_heat
    }
}

/// Melt fraction in [0, 1] (M.48): the share of the latent heat taken so far.
#[must_use]
pub fn melt_fraction(
    enthalpy: f64,
    heat_capacity: f64,
    melting_point: f64,
    latent_heat: f64,
) -> f64 {
    let above = enthalpy - heat_capacity * melting_point;
    if latent_heat > 0.0 {
        (above / latent_heat).clamp(0.0, 1.0)
    } else if above > 0.0 {
        1.0
    } else {
        0.0
    }
}

impl ThermalState {
    /// Every particle at the model's initial temperature; with the laser's arrays if the scene
    /// has a `[laser]` (`laser`), with the boundary's if the model exchanges heat with walls, gas
    /// or surroundings.
    #[must_use]
    pub fn new(model: &ThermalModel, particles: &Particles, laser: bool) -> Self {
        let n = particles.len();
        let mut state = Self {
            materials: HeatMaterials::of(model, particles),
            ..Self::default()
        };
        let constants = state.materials.reads(&particles.mass);
        let t0 = model.initial_temperature;
        (state.enthalpy, state.melted) = (0..n)
            .map(|k| {
                let (capacity, melting_point, latent) = constants.at(k);
                (
                    enthalpy_from_temperature(t0, capacity, melting_point, latent),
                    t0 >= melting_point,
                )
            })
            .unzip();
        state.temperature = vec![t0; n];
        state.heat_flow = vec![0.0; n];
        state.laser = laser.then(|| LaserHeat {
            power: vec![0.0; n],
            energy: vec![0.0; n],
        });
        state.boundary = model.has_boundary_exchange().then(|| BoundaryHeat {
            flow: vec![0.0; n],
            energy: vec![0.0; n],
        });
        if model.materials.iter().any(|m| m.vaporization.is_some()) {
            let constants = state.materials.reads(&particles.mass);
            let boiling_enthalpy = (0..n)
                .map(|k| {
                    let material = &model.materials[usize::from(particles.material[k])];
                    material.vaporization.map_or(f64::INFINITY, |v| {
                        let (capacity, melting_point, latent) = constants.at(k);
                        enthalpy_from_temperature(v.boiling_point, capacity, melting_point, latent)
                    })
                })
                .collect();
            state.evaporation = Some(Evaporation {
                boiling_enthalpy,
                evaporated: vec![0.0; n],
            });
        }
        state.mark_start();
        state
    }

    /// Total enthalpy `Σ E_i` \[J\], summed in index order (reproducible).
    #[must_use]
    pub fn total_enthalpy(&self) -> f64 {
        self.enthalpy.iter().sum()
    }

    /// Laser energy absorbed by all particles since the start \[J\] (summed in index order; 0
    /// without a laser).
    #[must_use]
    pub fn total_laser_energy(&self) -> f64 {
        self.laser.as_ref().map_or(0.0, |l| l.energy.iter().sum())
    }

    /// Heat received from walls, gas and surroundings since the start \[J\] (negative: lost; 0
    /// without boundary exchange).
    #[must_use]
    pub fn total_boundary_energy(&self) -> f64 {
        self.boundary
            .as_ref()
            .map_or(0.0, |b| b.energy.iter().sum())
    }

    /// Sets particle `k`'s temperature \[K\] (and its enthalpy consistently), e.g. for tests;
    /// `particles` are the state's own.
    pub fn set_temperature(&mut self, particles: &Particles, k: usize, temperature: f64) {
        let (capacity, melting_point, latent) = self.materials.reads(&particles.mass).at(k);
        self.enthalpy[k] = enthalpy_from_temperature(temperature, capacity, melting_point, latent);
        self.temperature[k] = temperature;
        self.melted[k] |= temperature >= melting_point;
    }

    /// Particle `k`'s heat capacity, melting point and latent heat (M.48), made from its mass
    /// as the passes make them; `particles` are the state's own.
    #[must_use]
    pub fn heat_constants(&self, particles: &Particles, k: usize) -> HeatConstants {
        let (heat_capacity, melting_point, latent_heat) =
            self.materials.reads(&particles.mass).at(k);
        HeatConstants {
            heat_capacity,
            melting_point,
            latent_heat,
        }
    }
}

/// What a contact's conductance needs of its material pair [W/(m·K)]: `k* = 2 k_a k_b /
/// (k_a + k_b)` (M.41) for Batchelor & O'Brien and the geometric overlap, and `k_a`, `k_b` for
/// the thermal pipe (M.42).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairConductivities {
    /// `k*` (M.41) [W/(m·K)], from [`ThermalModel::harmonic_conductivity`]'s table.
    pub harmonic: f64,
    /// The two materials' conductivities `[k_a, k_b]` [W/(m·K)].
    pub each: [f64; 2],
}

/// Conductance of the contact between two particles of radii `[ra, rb]` \[m\] with the
/// conductivities `k` at `overlap` \[m\], with the Hertz contact radius `contact = √(r* δ)`
/// \[m\] ([`conduction::contact_radius`], M.40), by the conduction model `conduction` [W/K];
/// 0 without overlap:
///
/// ```text
/// BatchelorObrien: H = 2 k* a                  (M.41)
/// OverlapArea:     H = 2 k* √π a_g              (M.79, a_g the intersection radius)
/// ThermalPipe:     H = k̄ π a² / d,  d = r_a + r_b − δ   (M.42)
/// ```
///
/// The pair pass takes the contact radius from its contact kernel, which computes it for the
/// Hertz force, and evaluates this over a batch of contacts at once with `conduction` fixed
/// (`forces::lanes`), so that the model's `match` leaves the loop and the intersection radius's
/// division and square root run on vectors.
#[must_use]
#[inline(always)]
pub fn contact_conductance(
    conduction: ConductionModel,
    k: PairConductivities,
    [ra, rb]: [f64; 2],
    overlap: f64,
    contact: f64,
) -> f64 {
    if overlap <= 0.0 {
        return 0.0;
    }
    match conduction {
        ConductionModel::None => 0.0,
        ConductionModel::BatchelorObrien => 2.0 * k.harmonic * contact,
        ConductionModel::OverlapArea => {
            2.0 * k.harmonic
                * std::f64::consts::PI.sqrt()
                * conduction::intersection_radius(ra, rb, ra + rb - overlap)
        }
        ConductionModel::ThermalPipe => {
            let [ka, kb] = k.each;
            conduction::thermal_pipe(ka, kb, ra, rb, contact, ra + rb - overlap)
        }
    }
}

/// [`contact_conductance`] of two particles of materials `[ma, mb]` in `model` [W/K].
#[must_use]
#[inline(always)]
pub fn pair_conductance(
    model: &ThermalModel,
    [ma, mb]: [u16; 2],
    radii: [f64; 2],
    overlap: f64,
    contact: f64,
) -> f64 {
    contact_conductance(
        model.conduction,
        model.pair_conductivities(ma, mb),
        radii,
        overlap,
        contact,
    )
}

/// Contact conductances of every pair slot from the current positions, for the flow passes of
/// a step's further thermal substeps (the force pass computes the first substep's flows with the
/// pair's data at hand and keeps none).
pub fn update_conductances(
    model: &ThermalModel,
    periodic: Option<&crate::periodic::Periodic>,
    particles: &Particles,
    list: &NeighborList,
    conductance: &mut Vec<f64>,
) {
    conductance.clear();
    conductance.extend(
        list.pairs()
            .map(|(_, a, b)| slot_conductance(model, periodic, particles, list, a, b)),
    );
}

/// The contact conductance H [W/K] of the listed pair of owner `a` and partner `b` at the
/// current positions (M.41, M.42, M.79; 0 where they do not touch).
#[inline(always)]
fn slot_conductance(
    model: &ThermalModel,
    periodic: Option<&crate::periodic::Periodic>,
    particles: &Particles,
    list: &NeighborList,
    a: usize,
    b: usize,
) -> f64 {
    // The minimum image only where the owner needs it, as in the pair pass.
    let image = periodic.filter(|_| list.needs_minimum_image(a));
    let Some((_, overlap)) = crate::forces::touching_pair_geometry(image, particles, a, b) else {
        return 0.0;
    };
    let radii = [particles.radius[a], particles.radius[b]];
    let effective_radius = crate::contact::hertz::effective_radius(radii[0], radii[1]);
    let contact = conduction::contact_radius(effective_radius, overlap);
    let materials = [particles.material[a], particles.material[b]];
    pair_conductance(model, materials, radii, overlap, contact)
}

/// Where a pass of heat flows finds each pair slot's contact conductance H [W/K].
#[derive(Clone, Copy)]
enum SlotConductances<'a> {
    /// In the state's per-slot array ([`update_conductances`]): a step of several substeps
    /// computes them once and reads them in each.
    Stored(&'a [f64]),
    /// From the positions, as the pass meets each pair (with the periodic axes): a measurement
    /// made once keeps no array of 8 B a pair slot, which would set the run's peak memory.
    FromPositions(Option<&'a crate::periodic::Periodic>),
}

/// The largest `G_i / C_i` [1/s] (M.49) of `state`'s particles, `total` being their total
/// conductances G_i [W/K] (exact in any order, on the thread team for a large state, as
/// [`crate::team::largest`] says).
#[must_use]
pub fn max_heat_rate(total: &[f64], state: &ThermalState, particles: &Particles) -> f64 {
    let parallel = crate::worth_parallel(total.len());
    match state.materials.reads(&particles.mass) {
        MaterialReads::One { mass, constants } => {
            let rate = |g: &f64, m: &f64| g / constants.heat_capacity(*m);
            crate::team::largest(parallel, (total, mass), rate)
        }
        MaterialReads::Columns { heat_capacity, .. } => {
            crate::team::largest(parallel, (total, heat_capacity), |g, c| g / c)
        }
    }
}

/// What a pass of heat flows reads of the state.
#[derive(Clone, Copy)]
struct FlowReads<'a> {
    temperature: &'a [f64],
    /// With a laser.
    laser_power: Option<&'a [f64]>,
}

/// What a pass of heat flows writes: each particle's net heat flow and, where the scene keeps
/// them, its boundary flows.
struct FlowSums<'a> {
    flows: &'a mut [f64],
    boundary_flow: Option<&'a mut [f64]>,
}

impl ThermalState {
    /// This state as a flow pass of the run takes it: what it reads, the stored per-slot
    /// conductances, and the run's own heat flows and boundary flows, which it writes.
    fn flow_pass_parts(&mut self) -> (FlowReads<'_>, &[f64], FlowSums<'_>) {
        let reads = FlowReads {
            temperature: &self.temperature,
            laser_power: self.laser.as_ref().map(|l| l.power.as_slice()),
        };
        let sums = FlowSums {
            flows: &mut self.heat_flow,
            boundary_flow: self.boundary.as_mut().map(|b| b.flow.as_mut_slice()),
        };
        (reads, &self.conductance, sums)
    }
}

/// Largest `G_i / C_i` over the particles [1/s] (M.49) for the current positions and
/// temperatures: its inverse is the smallest thermal time constant. Measured aside, the state
/// left as it was: each particle's total conductance G_i (its contacts', each computed as the
/// pass meets the pair, and its exchange with walls, gas and surroundings) is summed in an
/// array of its own, 8 B a particle while it runs, and no per-slot conductance is kept (8 B a
/// pair slot, which would set a heated bed's peak memory). The run's start takes it, the
/// diagnostics, and a step whose bound ([`HeatRate::at_most`]) asks for more than one substep.
#[must_use]
pub fn max_stiffness(
    model: &ThermalModel,
    walls: &[Wall],
    periodic: Option<&crate::periodic::Periodic>,
    particles: &Particles,
    list: &NeighborList,
    state: &ThermalState,
) -> f64 {
    let _pass = crate::team::PassName::enter("largest heat rate");
    let temperature = &state.temperature;
    let parallel = crate::worth_parallel(temperature.len());
    let mut total = vec![0.0; temperature.len()];
    add_pair_sums::<false>(list, parallel, temperature, &mut total, |_, a, b| {
        slot_conductance(model, periodic, particles, list, a, b)
    });
    let materials = state.materials.reads(&particles.mass);
    let chunks: Vec<_> = total.chunks(PARTICLES_PER_ITEM).collect();
    let largest = |c: usize, contacts: &[f64]| {
        let mut worst: f64 = 0.0;
        for (i, contacts) in contacts.iter().enumerate() {
            let k = c * PARTICLES_PER_ITEM + i;
            let (_, outside) = boundary_heat(model, walls, particles, k, temperature[k]);
            worst = worst.max((contacts + outside) / materials.heat_capacity(k));
        }
        worst
    };
    crate::team::fold_items(
        parallel,
        chunks,
        || 0.0,
        |worst: f64, c, chunk| worst.max(largest(c, chunk)),
        f64::max,
    )
}

/// A chunk's laser and boundary energy accumulators \[J\], each kept where the scene has its
/// source.
type Accumulators<'a> = (Option<&'a mut [f64]>, Option<&'a mut [f64]>);

/// A chunk of the temperature update: enthalpies, temperatures and melted flags, its
/// accumulators, and with evaporation the heat its vapour carried off.
type Chunk<'a> = (
    ((&'a mut [f64], &'a mut [f64]), &'a mut [bool]),
    (Accumulators<'a>, Option<&'a mut [f64]>),
);

/// One material's constants for the temperature update (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialConstants {
    /// Specific heat c [J/(kg·K)].
    specific_heat: f64,
    /// Melting point T_m \[K\].
    melting_point: f64,
    /// Latent heat of fusion L [J/kg].
    latent_heat: f64,
}

impl MaterialConstants {
    /// Specific heat c [J/(kg·K)].
    /// The heat capacity `C = m c` [J/K] of a particle of mass `mass` \[kg\] (M.48): the one
    /// product every reader makes, so that they agree to the bit.
    #[inline(always)]
    fn heat_capacity(self, mass: f64) -> f64 {
        mass * self.specific_heat
    }
}

/// A particle's constants of (M.48), SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatConstants {
    /// Heat capacity `C = m c` [J/K].
    pub heat_capacity: f64,
    /// Melting point T_m \[K\].
    pub melting_point: f64,
    /// Latent heat of the whole particle `m L` \[J\].
    pub latent_heat: f64,
}

/// Where each particle's heat capacity `C = m c` \[J/K\], melting point T_m \[K\] and latent
/// heat `m L` \[J\] (M.48) come from.
#[derive(Debug, Clone, PartialEq)]
pub enum HeatMaterials {
    /// A scene of one material: made from each particle's mass and the material's constants
    /// wherever they are read, with the products the columns are made with (bitwise the same
    /// values), so that the state keeps no array of them: 24 B a particle less.
    One(MaterialConstants),
    /// Several materials: a column each, one entry a particle, made once from the particles'
    /// masses and materials.
    Columns {
        /// `C = m c` [J/K].
        heat_capacity: Vec<f64>,
        /// T_m \[K\].
        melting_point: Vec<f64>,
        /// `m L` \[J\].
        latent_heat: Vec<f64>,
    },
}

impl Default for HeatMaterials {
    fn default() -> Self {
        Self::Columns {
            heat_capacity: Vec::new(),
            melting_point: Vec::new(),
            latent_heat: Vec::new(),
        }
    }
}

impl HeatMaterials {
    /// The source for `particles` of `model`'s materials.
    fn of(model: &ThermalModel, particles: &Particles) -> Self {
        let constants = |m: &ThermalMaterial| MaterialConstants {
            specific_heat: m.specific_heat,
            melting_point: m.melting_point,
            latent_heat: m.latent_heat,
        };
        if let [material] = model.materials.as_slice() {
            return Self::One(constants(material));
        }
        // Each particle's as one material's would be.
        let at = |k: usize| {
            let material = &model.materials[usize::from(particles.material[k])];
            OneAt(&particles.mass, constants(material)).at(k)
        };
        let n = particles.len();
        Self::Columns {
            heat_capacity: (0..n).map(|k| at(k).0).collect(),
            melting_point: (0..n).map(|k| at(k).1).collect(),
            latent_heat: (0..n).map(|k| at(k).2).collect(),
        }
    }

    /// The constants as the passes read them, with the particles' masses `mass` \[kg\].
    pub(crate) fn reads<'a>(&'a self, mass: &'a [f64]) -> MaterialReads<'a> {
        match self {
            Self::One(constants) => MaterialReads::One {
                mass,
                constants: *constants,
            },
            Self::Columns {
                heat_capacity,
                melting_point,
                latent_heat,
            } => MaterialReads::Columns {
                heat_capacity,
                melting_point,
                latent_heat,
            },
        }
    }

    /// Reorders the columns like `Particles::select` (one material has none).
    fn select(&mut self, order: &[u32]) {
        use crate::particles::select;
        if let Self::Columns {
            heat_capacity,
            melting_point,
            latent_heat,
        } = self
        {
            select(heat_capacity, order);
            select(melting_point, order);
            select(latent_heat, order);
        }
    }
}

/// Where a pass finds the particles' heat capacities C \[J/K\], melting points T_m \[K\] and
/// latent heats m L \[J\] (M.48): [`HeatMaterials`] as read, over all particles or a chunk.
#[derive(Debug, Clone, Copy)]
pub(crate) enum MaterialReads<'a> {
    /// The state's columns, one entry a particle.
    Columns {
        heat_capacity: &'a [f64],
        melting_point: &'a [f64],
        latent_heat: &'a [f64],
    },
    /// One material: the particles' masses \[kg\] and its constants.
    One {
        mass: &'a [f64],
        constants: MaterialConstants,
    },
}

impl<'a> MaterialReads<'a> {
    /// The reads of the particles of `range`.
    fn cut(self, range: std::ops::Range<usize>) -> Self {
        match self {
            Self::Columns {
                heat_capacity,
                melting_point,
                latent_heat,
            } => Self::Columns {
                heat_capacity: &heat_capacity[range.clone()],
                melting_point: &melting_point[range.clone()],
                latent_heat: &latent_heat[range],
            },
            Self::One { mass, constants } => Self::One {
                mass: &mass[range],
                constants,
            },
        }
    }

    /// Particle `k`'s `(C, T_m, m L)`: a test of the source each time, for the readers outside
    /// the update's loops.
    #[inline]
    fn at(&self, k: usize) -> (f64, f64, f64) {
        match *self {
            Self::Columns {
                heat_capacity,
                melting_point,
                latent_heat,
            } => ColumnsAt(heat_capacity, melting_point, latent_heat).at(k),
            Self::One { mass, constants } => OneAt(mass, constants).at(k),
        }
    }

    /// Particle `k`'s heat capacity `C` \[J/K\].
    #[inline]
    pub(crate) fn heat_capacity(&self, k: usize) -> f64 {
        self.at(k).0
    }
}

/// Particle `i`'s `(C, T_m, m L)` (M.48), from slices of the chunk's length so that the update's
/// loop holds no bounds check.
trait MaterialAt {
    fn at(&self, i: usize) -> (f64, f64, f64);
}

/// [`MaterialReads::Columns`] cut to the chunk's length.
struct ColumnsAt<'a>(&'a [f64], &'a [f64], &'a [f64]);

impl MaterialAt for ColumnsAt<'_> {
    #[inline(always)]
    fn at(&self, i: usize) -> (f64, f64, f64) {
        (self.0[i], self.1[i], self.2[i])
    }
}

/// [`MaterialReads::One`] cut to the chunk's length: `C = m c` and `m L` made as
/// [`ThermalState::new`] makes the columns.
struct OneAt<'a>(&'a [f64], MaterialConstants);

impl MaterialAt for OneAt<'_> {
    #[inline(always)]
    fn at(&self, i: usize) -> (f64, f64, f64) {
        let (mass, constants) = (self.0[i], self.1);
        (
            constants.heat_capacity(mass),
            constants.melting_point,
            mass * constants.latent_heat,
        )
    }
}

/// One substep's explicit Euler update of a chunk's enthalpies, `E += dt Q` (M.49), with
/// evaporation past the boiling enthalpy where the material boils (M.80), then `T = T(E)`
/// (M.48) and the melt flags. Over slices of one length, so that the loop holds no bounds check
/// and runs in the vector builds (`simd`): bitwise the same in each.
struct EnthalpyUpdate<'a> {
    dt: f64,
    flows: &'a [f64],
    material: MaterialReads<'a>,
    /// Each particle's boiling enthalpy \[J\], if a material boils.
    boiling: Option<&'a [f64]>,
    enthalpy: &'a mut [f64],
    temperature: &'a mut [f64],
    melted: &'a mut [bool],
    /// The heat each particle has carried off with its vapour \[J\], if a material boils.
    evaporated: Option<&'a mut [f64]>,
}

impl crate::simd::Kernel for EnthalpyUpdate<'_> {
    #[inline(always)]
    fn run(self) {
        let n = self.enthalpy.len();
        // A loop of its own for each source, so that a scene of one material reads its masses
        // alone.
        match self.material {
            MaterialReads::Columns {
                heat_capacity,
                melting_point,
                latent_heat,
            } => self.update(&ColumnsAt(
                &heat_capacity[..n],
                &melting_point[..n],
                &latent_heat[..n],
            )),
            MaterialReads::One { mass, constants } => self.update(&OneAt(&mass[..n], constants)),
        }
    }
}

impl EnthalpyUpdate<'_> {
    #[inline(always)]
    fn update(self, material: &impl MaterialAt) {
        let Self {
            dt,
            flows,
            boiling,
            enthalpy,
            temperature,
            melted,
            evaporated,
            ..
        } = self;
        let n = enthalpy.len();
        let (temperature, melted, flows) = (&mut temperature[..n], &mut melted[..n], &flows[..n]);
        match (boiling, evaporated) {
            // A loop of its own, so that a scene without evaporation tests nothing more.
            (Some(boiling), Some(evaporated)) => {
                let (boiling, evaporated) = (&boiling[..n], &mut evaporated[..n]);
                for i in 0..n {
                    let (capacity, melting, latent) = material.at(i);
                    let (kept, carried_off) = evaporate(enthalpy[i] + dt * flows[i], boiling[i]);
                    enthalpy[i] = kept;
                    evaporated[i] += carried_off;
                    temperature[i] = temperature_from_enthalpy(kept, capacity, melting, latent);
                    melted[i] |= temperature[i] >= melting;
                }
            }
            _ => {
                for i in 0..n {
                    let (capacity, melting, latent) = material.at(i);
                    enthalpy[i] += dt * flows[i];
                    temperature[i] =
                        temperature_from_enthalpy(enthalpy[i], capacity, melting, latent);
                    melted[i] |= temperature[i] >= melting;
                }
            }
        }
    }
}

/// What the force pass knows of `max_i G_i / C_i` [1/s] (M.49), which sets a step's substep
/// count ([`advance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HeatRate {
    /// The largest `G_i / C_i` itself.
    Exact(f64),
    /// A bound from above ([`HeatRate::at_most`]). A step whose bound asks for one substep
    /// takes one, as the exact rate would have it (the count only grows with the rate); only a
    /// step whose bound asks for more takes the largest `G_i / C_i` itself, in a pass of its
    /// own ([`max_stiffness`]).
    AtMost(f64),
}

/// What the force pass saw of the heat rates, without summing any particle's total
/// conductance G_i: the inputs of [`HeatRate::at_most`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HeatRateBound {
    /// The largest `H_ij / min(m_i, m_j)` of a contact [W/(K·kg)]: its conductance H_ij over
    /// the smaller mass of its pair.
    pub contact_conductance_per_mass: f64,
    /// The largest `G_out,i / C_i` [1/s] of the exchange with walls, gas and surroundings
    /// (M.43-M.46), 0 without it.
    pub boundary_rate: f64,
}

impl HeatRateBound {
    /// The larger of two bounds' inputs, each taken alone (associative and commutative).
    #[must_use]
    pub fn merge(self, other: Self) -> Self {
        Self {
            contact_conductance_per_mass: self
                .contact_conductance_per_mass
                .max(other.contact_conductance_per_mass),
            boundary_rate: self.boundary_rate.max(other.boundary_rate),
        }
    }
}

impl HeatRate {
    /// A bound on `max_i G_i / C_i` [1/s] (M.49) of what the force pass saw (`seen`), no
    /// particle having more than `max_degree` contacts (the neighbour list's
    /// `max_degree`), and no material a specific heat below `min_specific_heat`
    /// [J/(kg·K)]:
    ///
    /// `G_i / C_i = Σ_j H_ij / (m_i c_i) + G_out,i / C_i ≤ (D P / c_min + Q) (1 + (D + 8) ε)`
    ///
    /// with P the largest `H_ij / min(m_i, m_j)`, Q the largest `G_out,i / C_i`, D the most
    /// contacts, and ε the machine epsilon. Each of particle i's contacts gives it at most
    /// `H_ij / m_i ≤ P` a unit mass, and `C_i = m_i c_i ≥ m_i c_min`. The factor
    /// `1 + (D + 8) ε` covers the rounding of the sum of D conductances and of the quotients
    /// (some D + 6 half-ulps), so that the bound holds for the rates as computed, not only
    /// for exact ones. NaN (which asks for the exact rate) where an input is NaN.
    ///
    /// On the heated 19.2k LIGGGHTS bed (D = 15) it is 4.8 times the rate, whose `dt G/C` is
    /// 2e-4: far from asking for a second substep.
    #[must_use]
    pub fn at_most(seen: HeatRateBound, max_degree: usize, min_specific_heat: f64) -> Self {
        #[allow(clippy::cast_precision_loss)]
        let degree = max_degree as f64;
        let contacts = degree * seen.contact_conductance_per_mass / min_specific_heat;
        Self::AtMost((contacts + seen.boundary_rate) * (1.0 + (degree + 8.0) * f64::EPSILON))
    }
}

/// What [`advance`] needs to know about the step besides the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInfo<'a> {
    /// Mechanical time step \[s\].
    pub dt: f64,
    /// When the force gather already computed the first substep's heat flows: what it knows of
    /// their `max G_i / C_i`.
    pub first_flows: Option<HeatRate>,
    /// The periodic axes, for the contact conductances of a step that needs more substeps.
    pub periodic: Option<&'a crate::periodic::Periodic>,
}

/// Advances the temperatures over one mechanical step `dt` \[s\] by (M.49), using the laser
/// powers already stored in `state`.
///
/// Per substep: one pass over the particles computes every heat flow, a second streams the
/// enthalpy update. The first pass may already have been made by the force gather (see
/// [`StepInfo`]); else it computes each contact conductance as it meets the pair. The substep
/// count comes from the largest `G_i / C_i`: from the force gather's bound where that asks for
/// one substep, else from a pass that sums each G_i ([`max_stiffness`]). Only a step that
/// needs more than one substep stores the contact conductances per pair slot, computed anew
/// from the positions, for its further flow passes: most steps of a bed take one substep, and
/// keep no per-slot conductance at all.
///
/// Returns the first substep's `max G_i / C_i` [1/s] where it was taken, `None` where the
/// bound sufficed ([`HeatRate::AtMost`]).
pub fn advance(
    model: &ThermalModel,
    walls: &[Wall],
    particles: &Particles,
    list: &NeighborList,
    state: &mut ThermalState,
    step: StepInfo,
) -> Option<f64> {
    let _pass = crate::team::PassName::enter("temperature update");
    let StepInfo {
        dt,
        first_flows,
        periodic,
    } = step;
    let n = particles.len();
    // The share of dt over the smallest time constant C_i/G_i that one substep may take.
    let share = |rate: f64| dt * rate / model.substep_fraction;
    let worst = match first_flows {
        Some(HeatRate::Exact(worst)) => Some(worst),
        // (A NaN bound fails the test and takes the exact rate.)
        Some(HeatRate::AtMost(bound)) if share(bound) <= 1.0 => None,
        Some(HeatRate::AtMost(_)) => Some(max_stiffness(
            model, walls, periodic, particles, list, state,
        )),
        None => {
            let (reads, _, sums) = state.flow_pass_parts();
            let conductances = SlotConductances::FromPositions(periodic);
            heat_flows(model, walls, particles, list, reads, conductances, sums);
            Some(max_stiffness(
                model, walls, periodic, particles, list, state,
            ))
        }
    };
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let substeps = worst.map_or(1, |worst| (share(worst).ceil() as u32).max(1));
    if substeps > 1 {
        update_conductances(model, periodic, particles, list, &mut state.conductance);
    }
    let dt_sub = dt / f64::from(substeps);
    for substep in 0..substeps {
        if substep > 0 {
            let (reads, stored, sums) = state.flow_pass_parts();
            let conductances = SlotConductances::Stored(stored);
            heat_flows(model, walls, particles, list, reads, conductances, sums);
        }
        let ThermalState {
            enthalpy,
            temperature,
            materials,
            evaporation,
            melted,
            heat_flow,
            laser,
            boundary,
            ..
        } = state;
        let materials = materials.reads(&particles.mass);
        // Each energy accumulator costs two more streams, paid only where the scene has its
        // source.
        let (laser_power, laser_energy) = laser
            .as_mut()
            .map(|l| (l.power.as_slice(), l.energy.as_mut_slice()))
            .unzip();
        let (boundary_flow, boundary_energy) = boundary
            .as_mut()
            .map(|b| (b.flow.as_slice(), b.energy.as_mut_slice()))
            .unzip();
        let accumulators = optional_items(laser_energy).zip(optional_items(boundary_energy));
        let (boiling_enthalpy, evaporated) = evaporation
            .as_mut()
            .map(|e| (e.boiling_enthalpy.as_slice(), e.evaporated.as_mut_slice()))
            .unzip();
        let chunks: Vec<_> = enthalpy
            .chunks_mut(PARTICLES_PER_ITEM)
            .zip(temperature.chunks_mut(PARTICLES_PER_ITEM))
            .zip(melted.chunks_mut(PARTICLES_PER_ITEM))
            .zip(accumulators.zip(optional_items(evaporated)))
            .collect();
        let set = crate::simd::InstructionSet::detect();
        let update = |c: usize, (((e, t), m), (accumulated, evaporated)): Chunk<'_>| {
            let particles = c * PARTICLES_PER_ITEM..c * PARTICLES_PER_ITEM + e.len();
            let material = materials.cut(particles.clone());
            let flows = &heat_flow[particles.clone()];
            crate::simd::dispatch(
                set,
                EnthalpyUpdate {
                    dt: dt_sub,
                    flows,
                    material,
                    boiling: boiling_enthalpy.map(|b| &b[particles.clone()]),
                    enthalpy: e,
                    temperature: t,
                    melted: m,
                    evaporated,
                },
            );
            let (laser_energy, boundary_energy) = accumulated;
            accumulate(laser_energy, laser_power, particles.clone(), dt_sub);
            accumulate(boundary_energy, boundary_flow, particles, dt_sub);
        };
        // The members of the thread team take the same share of the chunks as in the step's
        // other passes.
        crate::team::fold_items(
            crate::worth_parallel(n),
            chunks,
            || (),
            |(), c, chunk| update(c, chunk),
            |(), ()| (),
        );
    }
    state.substeps = substeps;
    state.max_substeps = state.max_substeps.max(substeps);
    worst
}

/// Adds `dt_sub` \[s\] times each of the chunk `particles`' powers \[W\] to its energy \[J\], where
/// the scene keeps both.
fn accumulate(
    energy: Option<&mut [f64]>,
    power: Option<&[f64]>,
    particles: std::ops::Range<usize>,
    dt_sub: f64,
) {
    if let (Some(energy), Some(power)) = (energy, power) {
        for (energy, power) in energy.iter_mut().zip(&power[particles]) {
            *energy += dt_sub * power;
        }
    }
}

/// Net heat flow into every particle at the current temperatures \[W\], into `out`: a
/// coloured pass over the pairs (each pair's flow added to both particles, in the list's fixed
/// order), then the boundary exchange and laser power per particle (M.47). The first substep of
/// a step gets these from the force pass instead.
fn heat_flows(
    model: &ThermalModel,
    walls: &[Wall],
    particles: &Particles,
    list: &NeighborList,
    reads: FlowReads<'_>,
    conductances: SlotConductances,
    out: FlowSums<'_>,
) {
    let _pass = crate::team::PassName::enter("heat flows");
    let FlowReads {
        temperature,
        laser_power,
    } = reads;
    let FlowSums {
        flows: heat_flow,
        boundary_flow,
    } = out;
    let parallel = crate::worth_parallel(temperature.len());
    heat_flow.fill(0.0);
    // One loop for each source, so that no pair tests which it is.
    match conductances {
        SlotConductances::Stored(stored) => {
            add_pair_sums::<true>(list, parallel, temperature, heat_flow, |slot, _, _| {
                stored[slot]
            });
        }
        SlotConductances::FromPositions(periodic) => {
            add_pair_sums::<true>(list, parallel, temperature, heat_flow, |_, a, b| {
                slot_conductance(model, periodic, particles, list, a, b)
            });
        }
    }
    let chunks: Vec<_> = heat_flow
        .chunks_mut(PARTICLES_PER_ITEM)
        .zip(optional_items(boundary_flow))
        .collect();
    let finish = |c: usize, (sums, mut flows): (&mut [f64], Option<&mut [f64]>)| {
        for (i, s) in sums.iter_mut().enumerate() {
            let k = c * PARTICLES_PER_ITEM + i;
            let (outside, _) = boundary_heat(model, walls, particles, k, temperature[k]);
            if let Some(flows) = flows.as_deref_mut() {
                flows[i] = outside;
            }
            // (Without a laser its power is +0, as the arrays once held.)
            *s += outside + laser_power.map_or(0.0, |p| p[k]);
        }
    };
    crate::team::fold_items(
        parallel,
        chunks,
        || (),
        |(), c, chunk| finish(c, chunk),
        |(), ()| (),
    );
}

/// Adds to both particles of every listed pair, with `FLOWS`, its heat flow `H (T_b − T_a)`
/// (M.40: into the owner a, out of the partner b), else its conductance H (M.49: to each
/// particle's total conductance G_i), in a coloured pass over the slabs in the list's fixed
/// order, H of a slot from `conductance(slot, owner, partner)`.
fn add_pair_sums<const FLOWS: bool>(
    list: &NeighborList,
    parallel: bool,
    temperature: &[f64],
    sums: &mut [f64],
    conductance: impl Fn(usize, usize, usize) -> f64 + Sync,
) {
    use crate::scatter::{PerParticle, Scatter};
    let sums: Scatter<'_, f64, PerParticle> = Scatter::new(sums);
    list.for_each_slab(
        parallel,
        (),
        |(), visit| {
            // Opened for the visit: its writes take no bounds check (`scatter`).
            let sums = sums.open(visit);
            for window in visit.windows() {
                let owner = window.owner();
                let t = temperature[owner.index()];
                let mut owner_sum = 0.0;
                for (p, partner) in window.pairs() {
                    let h = conductance(p.index(), owner.index(), partner.index());
                    if h > 0.0 {
                        if FLOWS {
                            let q = h * (temperature[partner.index()] - t);
                            owner_sum += q;
                            sums.update(partner, |s| s - q);
                        } else {
                            owner_sum += h;
                            sums.update(partner, |s| s + h);
                        }
                    }
                }
                sums.update(owner, |s| s + owner_sum);
            }
        },
        |(), ()| (),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 316L-like material (c = 500 J/(kg·K), k = 20 W/(m·K), T_m = 1700 K, L = 2.7e5 J/kg).
    fn steel_like(vaporization: Option<Vaporization>) -> ThermalMaterial {
        ThermalMaterial {
            specific_heat: 500.0,
            conductivity: 20.0,
            melting_point: 1700.0,
            latent_heat: 2.7e5,
            emissivity: 0.4,
            absorptivity: 0.6,
            vaporization,
        }
    }

    #[test]
    fn evaporation_keeps_the_boiling_enthalpy_and_carries_off_the_rest() {
        // C = 2 J/K, m L = 3 J, T_m = 1000 K, T_b = 2500 K: E_b = 5003 J.
        let (capacity, latent, melting) = (2.0, 3.0, 1000.0);
        let boiling_enthalpy = enthalpy_from_temperature(2500.0, capacity, melting, latent);
        assert_eq!(boiling_enthalpy, 5003.0);
        assert_eq!(evaporate(4000.0, boiling_enthalpy), (4000.0, 0.0));
        assert_eq!(evaporate(boiling_enthalpy, boiling_enthalpy), (5003.0, 0.0));
        assert_eq!(evaporate(5010.5, boiling_enthalpy), (5003.0, 7.5));
        assert_eq!(
            temperature_from_enthalpy(boiling_enthalpy, capacity, melting, latent),
            2500.0
        );
        // A material without a boiling point: nothing leaves, however hot.
        assert_eq!(evaporate(1e30, f64::INFINITY), (1e30, 0.0));
    }

    #[test]
    fn only_the_particles_of_a_material_that_boils_get_a_finite_boiling_enthalpy() {
        use crate::particles::ParticleInit;
        let mut model = ThermalModel::bare(
            vec![
                steel_like(None),
                steel_like(Some(Vaporization {
                    boiling_point: 3090.0,
                    latent_heat: 6.1e6,
                })),
            ],
            ConductionModel::BatchelorObrien,
        );
        let mut particles = Particles::default();
        for material in [0, 1, 1, 0] {
            particles.push(
                ParticleInit {
                    position: glam::DVec3::ZERO,
                    velocity: glam::DVec3::ZERO,
                    radius: 1e-5,
                    material,
                },
                7950.0,
            );
        }
        let state = ThermalState::new(&model, &particles, false);
        let evaporation = state.evaporation.as_ref().expect("one material boils");
        for k in 0..4 {
            let constants = state.heat_constants(&particles, k);
            let expected = if particles.material[k] == 1 {
                constants.heat_capacity * 3090.0 + constants.latent_heat
            } else {
                f64::INFINITY
            };
            assert_eq!(evaporation.boiling_enthalpy[k], expected, "particle {k}");
        }
        assert_eq!(evaporation.evaporated, vec![0.0; 4]);
        // Without a material that boils, the state carries no evaporation arrays.
        model.materials[1].vaporization = None;
        assert!(
            ThermalState::new(&model, &particles, false)
                .evaporation
                .is_none()
        );
    }

    /// A bed at 300 K is inert only while every boundary it exchanges with is at 300 K and no
    /// particle melted; each condition alone breaks it.
    #[test]
    fn a_bed_is_inert_only_at_the_temperature_of_all_its_boundaries() {
        let model = ThermalModel {
            convection: Some((10.0, 300.0)),
            radiation: Some(300.0),
            wall_temperatures: vec![None, Some(300.0)],
            ..ThermalModel::bare(Vec::new(), ConductionModel::BatchelorObrien)
        };
        let state = ThermalState {
            temperature: vec![300.0; 4],
            melted: vec![false; 4],
            ..ThermalState::default()
        };
        assert!(model.is_inert(&state));
        let warmer = |change: &dyn Fn(&mut ThermalModel)| {
            let mut other = model.clone();
            change(&mut other);
            other
        };
        for other in [
            warmer(&|m| m.convection = Some((10.0, 301.0))),
            warmer(&|m| m.radiation = Some(301.0)),
            warmer(&|m| m.wall_temperatures[0] = Some(301.0)),
        ] {
            assert!(!other.is_inert(&state), "{other:?}");
        }
        // An adiabatic wall and no gas or surroundings exchange nothing.
        let closed = warmer(&|m| {
            m.convection = None;
            m.radiation = None;
            m.wall_temperatures = vec![None];
        });
        assert!(closed.is_inert(&state));
        let mut uneven = state.clone();
        uneven.temperature[3] = 300.0 + 1e-9;
        assert!(!model.is_inert(&uneven));
        let mut melted = state.clone();
        melted.melted[0] = true;
        assert!(!model.is_inert(&melted));
    }

    /// A scene of one material reads its constants from the masses and the material, a scene
    /// of several from the columns: for one material (the columns those of a model whose two
    /// materials are the same) both give the same enthalpies, temperatures, melt flags and
    /// evaporated heats to the bit, in every vector build, on particles of many sizes heated
    /// across the melting plateau and past boiling; and the same constants for each particle.
    #[test]
    fn a_one_material_update_matches_the_columns_to_the_bit() {
        use crate::particles::ParticleInit;
        use crate::simd::InstructionSet;
        for vaporization in [
            None,
            Some(Vaporization {
                boiling_point: 3090.0,
                latent_heat: 6.1e6,
            }),
        ] {
            let model = ThermalModel::bare(
                vec![steel_like(vaporization)],
                ConductionModel::BatchelorObrien,
            );
            let mut particles = Particles::default();
            let n = 203;
            for k in 0..n {
                #[allow(clippy::cast_precision_loss)]
                let radius = 1e-5 * (1.0 + 0.7 * (k as f64 * 0.61).sin());
                let init = ParticleInit {
                    position: glam::DVec3::ZERO,
                    velocity: glam::DVec3::ZERO,
                    radius,
                    material: 0,
                };
                particles.push(init, 7950.0);
            }
            let mut state = ThermalState::new(&model, &particles, false);
            let HeatMaterials::One(constants) = state.materials else {
                panic!("one material without its constants")
            };
            let twice = ThermalModel::bare(vec![model.materials[0]; 2], model.conduction);
            let columns = HeatMaterials::of(&twice, &particles);
            let column_reads = columns.reads(&particles.mass);
            assert!(matches!(column_reads, MaterialReads::Columns { .. }));
            for k in 0..n {
                // From 300 K to 3300 K, past the plateau and the boiling point.
                #[allow(clippy::cast_precision_loss)]
                state.set_temperature(&particles, k, 1800.0 + 1500.0 * (k as f64 * 1.37).cos());
                // Flows that move a particle by up to some 400 K in one step of 1e-6 s.
                #[allow(clippy::cast_precision_loss)]
                let flow = 4e8 * column_reads.heat_capacity(k) * (k as f64 * 0.29).sin();
                state.heat_flow[k] = flow;
                let bits = |(c, t, l): (f64, f64, f64)| [c, t, l].map(f64::to_bits);
                assert_eq!(
                    bits(column_reads.at(k)),
                    bits(state.materials.reads(&particles.mass).at(k))
                );
            }
            let mut crossed = 0;
            for set in InstructionSet::available() {
                let mut from_columns = state.clone();
                let mut from_masses = state.clone();
                for (updated, materials) in [
                    (&mut from_columns, column_reads),
                    (
                        &mut from_masses,
                        MaterialReads::One {
                            mass: &particles.mass,
                            constants,
                        },
                    ),
                ] {
                    let update = EnthalpyUpdate {
                        dt: 1e-6,
                        flows: &state.heat_flow,
                        material: materials,
                        boiling: state.evaporation.as_ref().map(|e| &e.boiling_enthalpy[..]),
                        enthalpy: &mut updated.enthalpy,
                        temperature: &mut updated.temperature,
                        melted: &mut updated.melted,
                        evaporated: updated.evaporation.as_mut().map(|e| &mut e.evaporated[..]),
                    };
                    crate::simd::dispatch(set, update);
                }
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&from_columns.enthalpy), bits(&from_masses.enthalpy));
                assert_eq!(
                    bits(&from_columns.temperature),
                    bits(&from_masses.temperature)
                );
                assert_eq!(from_columns.melted, from_masses.melted);
                let evaporated =
                    |s: &ThermalState| s.evaporation.as_ref().map(|e| bits(&e.evaporated));
                assert_eq!(evaporated(&from_columns), evaporated(&from_masses));
                // The update did move the temperatures, some of them across the melting point.
                assert_ne!(bits(&from_masses.temperature), bits(&state.temperature));
                crossed = (0..n)
                    .filter(|&k| from_masses.melted[k] && !state.melted[k])
                    .count();
            }
            assert!(crossed > 0, "no particle melted in the update");
        }
        // One material keeps no column; several keep one each.
        let one = ThermalModel::bare(vec![steel_like(None)], ConductionModel::BatchelorObrien);
        let two = ThermalModel::bare(vec![steel_like(None); 2], ConductionModel::BatchelorObrien);
        let state = |model| ThermalState::new(model, &Particles::default(), false).materials;
        assert!(matches!(state(&one), HeatMaterials::One(_)));
        assert!(matches!(state(&two), HeatMaterials::Columns { .. }));
    }

    #[test]
    fn enthalpy_and_temperature_are_inverse_outside_the_plateau() {
        let (c, tm, l) = (1e-3, 1700.0, 0.5);
        for t in [300.0, 1699.0, 1701.0, 2500.0] {
            let e = enthalpy_from_temperature(t, c, tm, l);
            assert!((temperature_from_enthalpy(e, c, tm, l) - t).abs() < 1e-9);
        }
        // On the plateau the temperature is pinned while the melt fraction grows.
        let start = c * tm;
        for f in [0.0, 0.3, 1.0] {
            assert_eq!(temperature_from_enthalpy(start + f * l, c, tm, l), tm);
            assert!((melt_fraction(start + f * l, c, tm, l) - f).abs() < 1e-12);
        }
    }
}
