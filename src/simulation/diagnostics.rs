//! What a run measures of itself: the [`Diagnostics`] of the current state (energies, contacts,
//! overlaps, the energy and heat balances since the start), the stability limit of the stiffest
//! contact (M.70), and the per-step guards that stop a run before a blown-up state is written
//! ([`GuardTrip`], docs/stability.md).

use super::Simulation;
use crate::contact::{BondState, NormalParams, hertz, tangential};
use crate::forces;
use crate::integrate;
use crate::team::PARTICLES_PER_ITEM;
use crate::thermal;

/// Why a run stopped itself (docs/stability.md): the step, the particles and the quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct GuardTrip {
    /// What tripped, with its value and limit.
    pub quantity: String,
    /// The particle ids involved.
    pub ids: Vec<u64>,
    /// Whether the current state is finite and may be written as the last frame.
    pub state_is_finite: bool,
}

/// Quantities measured on the current state (all summed sequentially: reproducible).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Diagnostics {
    /// Steps taken.
    pub step: u64,
    /// Simulated time \[s\].
    pub time: f64,
    /// `Σ ½ m v²` \[J\].
    pub kinetic_energy: f64,
    /// `−Σ m g·x` \[J\].
    pub gravitational_energy: f64,
    /// Elastic energy stored in contacts and bonds (M.6, M.15) \[J\].
    pub elastic_energy: f64,
    /// Mechanical energy lost so far by damping and bond formation \[J\] (M.35).
    pub dissipated_energy: f64,
    /// Particle–particle pairs with δ > 0.
    pub contacts: usize,
    /// Particle–wall contacts.
    pub wall_contacts: usize,
    /// Bonded pairs.
    pub bonds: usize,
    /// Largest particle–particle or particle–wall overlap \[m\].
    pub max_overlap: f64,
    /// Largest overlap relative to the smaller radius of its pair.
    pub max_overlap_ratio: f64,
    /// Largest overlap ratio met at any step of this run so far (every step is checked).
    pub peak_overlap_ratio: f64,
    /// dt over the stability limit (M.70) of the stiffest contact now; > 1 is unstable.
    pub stability_ratio: f64,
    /// Mechanical energy balance (M.35) since the start of this run, relative to the energy
    /// scale of the run (see [`Simulation::diagnostics`]); positive when energy was created.
    pub energy_residual: f64,
    /// Neighbour-list builds so far.
    pub neighbor_builds: u64,
    /// Force passes so far that recorded the near lists anew (`neighbor`'s "Near lists"); the
    /// others tested only the near pairs.
    pub near_refreshes: u64,
    /// Steps so far whose rebuild test measured every particle's displacement since the build;
    /// at the others a bound showed that none can have moved half the skin.
    pub displacement_checks: u64,
    /// Particles removed so far because they left the domain (M.78); their energies stay in the
    /// totals (dissipated, thermal) and in the balances.
    pub removed_particles: u64,
    /// Thermal quantities, for scenes with `[thermal]`.
    pub thermal: Option<ThermalDiagnostics>,
}

/// One touching contact of the current state (see `Simulation::for_each_contact`).
pub(super) struct Contact<'a> {
    /// The particle (index), or the pair's first particle.
    pub(super) first: usize,
    /// The pair's second particle, for a particle pair.
    pub(super) second: Option<usize>,
    /// The wall, for a wall contact.
    wall: Option<usize>,
    /// δ > 0 \[m\].
    overlap: f64,
    /// The smaller radius of the two (the particle's, against a wall) \[m\].
    smaller_radius: f64,
    /// r* \[m\].
    effective_radius: f64,
    /// m* \[kg\].
    effective_mass: f64,
    /// Normal-law parameters of the pair or of the particle against the wall.
    params: &'a NormalParams,
    /// Whether the pair is bonded (never for a wall).
    bonded: bool,
}

impl Contact<'_> {
    /// Elastic energy of the normal law \[J\]: Hertz, or on the bonded branch the bond law's
    /// (paper eq. 25).
    pub(super) fn elastic_energy(&self) -> f64 {
        let (e_star, r_star) = (self.params.effective_modulus, self.effective_radius);
        match (self.bonded, &self.params.bond) {
            (true, Some(bond)) => bond.elastic_energy(e_star, r_star, self.overlap),
            _ => hertz::elastic_energy(e_star, r_star, self.overlap),
        }
    }
}

/// The contact that limits the time step most (M.70).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityLimit {
    /// Largest stable dt for that contact \[s\].
    pub dt_max: f64,
    /// Its particle ids (the second is `None` for a wall).
    pub ids: (u64, Option<u64>),
    /// Its overlap \[m\].
    pub overlap: f64,
}

/// Thermal quantities of the current state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ThermalDiagnostics {
    /// `Σ E_i` \[J\] (M.48).
    pub enthalpy: f64,
    /// Laser energy absorbed since the start \[J\].
    pub laser_energy: f64,
    /// Heat received from walls, gas and surroundings since the start \[J\].
    pub boundary_energy: f64,
    /// Highest particle temperature \[K\].
    pub max_temperature: f64,
    /// Particles that have reached their melting point.
    pub melted: usize,
    /// Thermal substeps of the last step.
    pub substeps: u32,
    /// dt over the smallest thermal time constant `C_i/G_i` of the last step (M.49); the
    /// substeps keep each substep's share below the scene's `substep_fraction`.
    pub time_step_ratio: f64,
    /// Heat balance since the start of this run: (stored − supplied) / scale (M.48).
    pub heat_residual: f64,
    /// `Σ (E_i − E_i(start))` over the particles, with those removed at their removal \[J\]:
    /// the heat stored since the start of the run (less what it was at the start, for the
    /// removals before it).
    pub stored: f64,
    /// `½ Σ |E_i − E_i(start)|` \[J\]: the heat that changed hands since the start of the run.
    pub exchanged: f64,
    /// With a material that evaporates (M.80): what the vapour has carried off since the start.
    pub evaporation: Option<EvaporationDiagnostics>,
}

/// What evaporation has carried off since the start (M.80), removed particles included.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EvaporationDiagnostics {
    /// Heat \[J\].
    pub heat: f64,
    /// Mass \[kg\]: the heat over each material's latent heat of vaporisation. The particles keep
    /// their mass (docs/model.md section 26); this says how much a real bed would have lost.
    pub mass: f64,
    /// The largest share of one particle's mass evaporated (of those still in the domain).
    pub max_fraction: f64,
    /// Particles that have evaporated anything (of those still in the domain).
    pub particles: usize,
}

impl ThermalDiagnostics {
    /// Heat carried off by evaporation since the start \[J\]; 0 without it.
    #[must_use]
    pub fn evaporated(&self) -> f64 {
        self.evaporation.map_or(0.0, |e| e.heat)
    }

    /// The net heat that entered the particles since `start` \[J\]: laser and boundaries, less
    /// what the vapour carried off (M.48, M.80). The heat balance holds it equal to the heat
    /// stored.
    #[must_use]
    pub fn supplied_since(&self, start: &Self) -> f64 {
        (self.laser_energy - start.laser_energy) + (self.boundary_energy - start.boundary_energy)
            - (self.evaporated() - start.evaporated())
    }
}

impl Diagnostics {
    /// Kinetic + gravitational + elastic energy \[J\].
    #[must_use]
    pub fn mechanical_energy(&self) -> f64 {
        self.kinetic_energy + self.gravitational_energy + self.elastic_energy
    }
}

impl Simulation {
    /// Measures the current state.
    #[must_use]
    pub fn diagnostics(&self) -> Diagnostics {
        let p = &self.particles;
        let mut d = Diagnostics {
            step: self.step,
            time: self.time,
            kinetic_energy: p.kinetic_energy(),
            dissipated_energy: p.dissipated_energy() + self.removed.dissipated_energy,
            removed_particles: self.removed.particles,
            gravitational_energy: p.gravitational_energy(self.model.gravity),
            neighbor_builds: self.neighbors.builds,
            near_refreshes: self.near_refreshes,
            displacement_checks: self.displacement_checks,
            ..Diagnostics::default()
        };
        let mut tightest = f64::INFINITY;
        let partials = self.fold_contacts(
            || (Diagnostics::default(), f64::INFINITY),
            |(d, tightest), contact| {
                if contact.second.is_some() {
                    d.contacts += 1;
                } else {
                    d.wall_contacts += 1;
                }
                d.max_overlap = d.max_overlap.max(contact.overlap);
                d.max_overlap_ratio = d
                    .max_overlap_ratio
                    .max(contact.overlap / contact.smaller_radius);
                if contact.bonded && contact.params.bond.is_some() {
                    d.bonds += 1;
                }
                d.elastic_energy += contact.elastic_energy();
                *tightest = tightest.min(self.stability_limit_of(&contact));
            },
        );
        for (chunk, chunk_tightest) in partials {
            d.contacts += chunk.contacts;
            d.wall_contacts += chunk.wall_contacts;
            d.max_overlap = d.max_overlap.max(chunk.max_overlap);
            d.max_overlap_ratio = d.max_overlap_ratio.max(chunk.max_overlap_ratio);
            d.bonds += chunk.bonds;
            d.elastic_energy += chunk.elastic_energy;
            tightest = tightest.min(chunk_tightest);
        }
        if let Some(rotation) = &self.rotation {
            // (M.63): rotation is kinetic energy, the tangential springs store elastic energy.
            d.kinetic_energy += rotation.kinetic_energy(p);
            d.elastic_energy += self.tangential.spring_energy() + rotation.wall_spring_energy();
        }
        d.thermal = self.thermal.as_ref().map(|t| {
            let (stored, exchanged) = t.enthalpy_change();
            ThermalDiagnostics {
                enthalpy: t.total_enthalpy() + self.removed.enthalpy,
                laser_energy: t.total_laser_energy() + self.removed.laser_energy,
                boundary_energy: t.total_boundary_energy() + self.removed.boundary_energy,
                max_temperature: t
                    .temperature
                    .iter()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max),
                melted: t.melted.iter().filter(|m| **m).count(),
                substeps: t.substeps,
                // Where the step took no largest G_i / C_i (its bound sufficed), it is
                // measured here, at the step's positions and its new temperatures. (A
                // deposition of an inert bed runs without the heat model: nothing flows.)
                time_step_ratio: self.model.dt
                    * self.max_heat_rate.unwrap_or_else(|| {
                        self.model.thermal.as_ref().map_or(0.0, |model| {
                            thermal::max_stiffness(
                                model,
                                &self.model.walls,
                                self.model.periodic.as_ref(),
                                &self.particles,
                                &self.neighbors,
                                t,
                            )
                        })
                    }),
                heat_residual: 0.0,
                stored: stored + self.removed.enthalpy_change,
                exchanged,
                evaporation: t.evaporation.as_ref().map(|e| {
                    let mut d = EvaporationDiagnostics {
                        heat: self.removed.evaporated,
                        mass: self.removed.evaporated_mass,
                        ..EvaporationDiagnostics::default()
                    };
                    for (k, &heat) in e.evaporated.iter().enumerate() {
                        let mass = self.model.evaporated_mass(p.material[k], heat);
                        d.heat += heat;
                        d.mass += mass;
                        d.max_fraction = d.max_fraction.max(mass / p.mass[k]);
                        d.particles += usize::from(heat > 0.0);
                    }
                    d
                }),
            }
        });
        d.peak_overlap_ratio = self.peak_overlap_ratio.max(d.max_overlap_ratio);
        d.stability_ratio = self.model.dt / tightest;
        self.close_balances(&mut d);
        d
    }

    /// The balances of this run, against its start (M.35, M.48). The mechanical residual is
    /// `(E(t) + W_lost − E(0)) / scale`, with the scale the energy the run had or exchanged:
    /// kinetic and elastic energy at the start, the change of gravitational energy and the energy
    /// lost (not the gravitational energy itself, which depends on where z = 0 is; and not the
    /// current energies, so that a blow-up shows as a large residual instead of saturating at 1).
    fn close_balances(&self, d: &mut Diagnostics) {
        let start = &self.start;
        let created = d.mechanical_energy() + d.dissipated_energy + self.removed.mechanical_energy
            - (start.kinetic
                + start.gravitational
                + start.elastic
                + start.dissipated
                + start.removed);
        let scale = [
            start.kinetic,
            start.elastic,
            d.gravitational_energy - start.gravitational,
            d.dissipated_energy - start.dissipated,
            // Round-off of the sums, for a run where nothing moves.
            f64::EPSILON * (d.gravitational_energy.abs() + d.mechanical_energy().abs()),
        ]
        .iter()
        .fold(f64::MIN_POSITIVE, |m, x| m.max(x.abs()));
        d.energy_residual = created / scale;
        if let (Some(t), Some(t0)) = (&mut d.thermal, &start.thermal) {
            let stored = t.stored - t0.stored;
            let supplied = t.supplied_since(t0);
            // The heat supplied, stored or moved between particles: conduction alone supplies
            // and stores nothing, and its balance is measured against what it moved.
            let scale = t
                .laser_energy
                .abs()
                .max(t.boundary_energy.abs())
                .max(t.evaporated())
                .max(stored.abs())
                .max(t.exchanged)
                .max(t0.enthalpy.abs() * f64::EPSILON);
            t.heat_residual = (stored - supplied) / scale;
        }
    }

    /// The per-step guards (docs/stability.md), from what the last force pass saw: a NaN or
    /// infinite force, or an overlap beyond `guards.max_overlap_ratio`. Costs nothing extra:
    /// the gather pass reduces both while summing forces.
    #[must_use]
    pub fn guard_trip(&self) -> Option<GuardTrip> {
        let summary = &self.force_summary;
        if let Some(k) = self.non_finite_force {
            return Some(GuardTrip {
                quantity: "a non-finite (NaN or infinite) force".into(),
                ids: vec![self.particles.id[k]],
                state_is_finite: false,
            });
        }
        let limit = self.model.guards.max_overlap_ratio;
        if summary.max_overlap_ratio > limit {
            let k = summary.max_overlap_particle;
            return Some(GuardTrip {
                quantity: format!(
                    "an overlap of {:.3} × the radius (guards.max_overlap_ratio = {limit})",
                    summary.max_overlap_ratio
                ),
                ids: self.deepest_contact_of(k),
                state_is_finite: integrate::first_non_finite(&self.particles).is_none(),
            });
        }
        None
    }

    /// The energy guard on measured diagnostics: energy created beyond
    /// `guards.max_energy_residual` of the run's energy scale.
    #[must_use]
    pub fn energy_guard_trip(&self, d: &Diagnostics) -> Option<GuardTrip> {
        let limit = self.model.guards.max_energy_residual;
        (d.energy_residual > limit).then(|| {
            let p = &self.particles;
            let fastest = (0..p.len()).max_by(|&a, &b| {
                p.velocity[a]
                    .length_squared()
                    .total_cmp(&p.velocity[b].length_squared())
            });
            GuardTrip {
                quantity: format!(
                    "an energy blow-up (the fastest particle): the mechanical energy balance gained {:.3} × the run's energy scale (guards.max_energy_residual = {limit})",
                    d.energy_residual
                ),
                ids: fastest.map(|k| vec![p.id[k]]).unwrap_or_default(),
                state_is_finite: integrate::first_non_finite(p).is_none(),
            }
        })
    }

    /// Particle `k` and the partner of its deepest contact (ids; one id for a wall).
    fn deepest_contact_of(&self, k: usize) -> Vec<u64> {
        let p = &self.particles;
        let mut deepest = (f64::NEG_INFINITY, None);
        self.for_each_touching_pair(|_, a, b, _, overlap| {
            if (a == k || b == k) && overlap > deepest.0 {
                deepest = (overlap, Some(p.id[a + b - k]));
            }
        });
        for w in 0..self.model.walls.len() {
            let overlap = forces::wall_overlap(&self.model, p, k, w);
            if overlap > deepest.0 {
                deepest = (overlap, None);
            }
        }
        std::iter::once(p.id[k]).chain(deepest.1).collect()
    }

    /// The tightest time-step stability limit (M.70) over the contacts of the current state:
    /// each touching pair or wall contact with its tangent stiffness at its overlap (Hertz M.5,
    /// or eq. 24 when bonded) and its damping ratio. `None` without contacts.
    #[must_use]
    pub fn stability_limit_now(&self) -> Option<StabilityLimit> {
        let mut tightest: Option<StabilityLimit> = None;
        self.for_each_contact(|contact| {
            let limit = self.stability_limit_of(&contact);
            if tightest.is_none_or(|t| limit < t.dt_max) {
                let p = &self.particles;
                tightest = Some(StabilityLimit {
                    dt_max: limit,
                    ids: (p.id[contact.first], contact.second.map(|b| p.id[b])),
                    overlap: contact.overlap,
                });
            }
        });
        tightest
    }

    /// The stability limit (M.70) of one contact: its tangent stiffness at its overlap (Hertz
    /// M.5, or eq. 24 when bonded) with its damping ratio, lowered by the sticking tangential
    /// spring (M.64) when the scene has friction.
    fn stability_limit_of(&self, contact: &Contact<'_>) -> f64 {
        let p = &self.particles;
        let (a, params) = (contact.first, contact.params);
        let (stiffness, damping_ratio) = match (contact.bonded, &params.bond) {
            (true, Some(bond)) => (
                bond.stiffness(
                    params.effective_modulus,
                    contact.effective_radius,
                    contact.overlap,
                ),
                bond.damping_ratio,
            ),
            _ => (
                hertz::stiffness(
                    params.effective_modulus,
                    contact.effective_radius,
                    contact.overlap,
                ),
                params.damping_ratio,
            ),
        };
        let sticking = self.model.friction.as_ref().map_or(1.0, |f| {
            let friction = match (contact.second, contact.wall) {
                (Some(b), _) => f.pair(p.material[a], p.material[b]),
                (None, Some(w)) => f.wall(w, p.material[a]),
                (None, None) => unreachable!("a contact has a second particle or a wall"),
            };
            tangential::sticking_time_factor(
                friction.effective_shear_modulus,
                params.effective_modulus,
            )
            .min(1.0)
        });
        sticking * integrate::stability_limit(stiffness, contact.effective_mass, damping_ratio)
    }

    /// Visits every touching contact of the current state, particles' chunk by chunk
    /// ([`PARTICLES_PER_ITEM`] consecutive particles): the chunk's pairs with δ > 0 in the
    /// neighbour list's order (the pairs it owns), then its particles' wall contacts (a wall is
    /// the limit r, m → ∞: r* = r, m* = m). The measurements of the state (diagnostics,
    /// stability limit) all walk the contacts in this order, serially or
    /// ([`Simulation::fold_contacts`]) chunk by chunk on the team.
    pub(super) fn for_each_contact(&self, mut visit: impl FnMut(Contact<'_>)) {
        for first in (0..self.particles.len()).step_by(PARTICLES_PER_ITEM) {
            self.contacts_of_chunk(first, &mut visit);
        }
    }

    /// The partials `visit` folds from `identity()` over each chunk's contacts (in the order of
    /// [`Simulation::for_each_contact`]), in chunk order: the chunks run on the thread team when
    /// the state is large, and the caller merges the partials in this order, so the thread
    /// count does not change a sum.
    fn fold_contacts<R: Send>(
        &self,
        identity: impl Fn() -> R + Sync,
        visit: impl Fn(&mut R, Contact<'_>) + Sync,
    ) -> Vec<R> {
        let _pass = crate::team::PassName::enter("diagnostics");
        let count = self.particles.len();
        let chunks: Vec<usize> = (0..count).step_by(PARTICLES_PER_ITEM).collect();
        let mut partials = crate::team::fold_items(
            crate::worth_parallel(count),
            chunks,
            Vec::new,
            |mut partials, c, first| {
                let mut partial = identity();
                self.contacts_of_chunk(first, |contact| visit(&mut partial, contact));
                partials.push((c, partial));
                partials
            },
            |mut a, b| {
                a.extend(b);
                a
            },
        );
        // The team's members may take each other's chunks: the order is restored here.
        partials.sort_unstable_by_key(|(c, _)| *c);
        partials.into_iter().map(|(_, partial)| partial).collect()
    }

    /// The contacts of the chunk of particles from `first` (see [`Simulation::for_each_contact`]).
    fn contacts_of_chunk(&self, first: usize, mut visit: impl FnMut(Contact<'_>)) {
        let p = &self.particles;
        let chunk = first..(first + PARTICLES_PER_ITEM).min(p.len());
        self.for_each_touching_pair_of(chunk.clone(), |slot, a, b, _, overlap| {
            visit(Contact {
                first: a,
                second: Some(b),
                wall: None,
                overlap,
                smaller_radius: p.radius[a].min(p.radius[b]),
                effective_radius: hertz::effective_radius(p.radius[a], p.radius[b]),
                effective_mass: hertz::effective_mass(p.mass[a], p.mass[b]),
                params: self.model.pair_params(p.material[a], p.material[b]),
                bonded: self.slot_bond_state(slot) == BondState::Bonded,
            });
        });
        for k in chunk {
            for w in 0..self.model.walls.len() {
                let overlap = forces::wall_overlap(&self.model, p, k, w);
                if overlap > 0.0 {
                    visit(Contact {
                        first: k,
                        second: None,
                        wall: Some(w),
                        overlap,
                        smaller_radius: p.radius[k],
                        effective_radius: p.radius[k],
                        effective_mass: p.mass[k],
                        params: self.model.wall_params(w, p.material[k]),
                        bonded: false,
                    });
                }
            }
        }
    }

    /// Smallest thermal time constant `min C_i/G_i` \[s\] at the current state (M.49), for scenes
    /// with `[thermal]`; infinite when nothing exchanges heat.
    #[must_use]
    pub fn smallest_thermal_time_constant(&self) -> Option<f64> {
        let model = self.model.thermal.as_ref()?;
        // Measured aside: `max_stiffness` leaves the state as it was.
        Some(
            1.0 / thermal::max_stiffness(
                model,
                &self.model.walls,
                self.model.periodic.as_ref(),
                &self.particles,
                &self.neighbors,
                self.thermal.as_ref()?,
            ),
        )
    }

    /// The first non-finite particle value as `(particle id, field)`.
    #[must_use]
    pub fn first_non_finite(&self) -> Option<(u64, &'static str)> {
        let thermal = self.thermal.as_ref().and_then(|t| {
            t.temperature
                .iter()
                .position(|x| !x.is_finite())
                .map(|k| (k, "temperature"))
        });
        let rotation = self.rotation.as_ref().and_then(|r| {
            r.angular_velocity
                .iter()
                .position(|w| !w.is_finite())
                .map(|k| (k, "angular_velocity"))
        });
        integrate::first_non_finite(&self.particles)
            .or(thermal)
            .or(rotation)
            .map(|(k, field)| (self.particles.id[k], field))
    }
}
