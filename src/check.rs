//! `am-sim check`: derived quantities of a scene and time-step advice, without running it.
//!
//! Per material pair (for the smallest and the largest radii present): E*, r*, m*, and with a bond
//! δ_eq, δ_crit, v_crit (paper eqs. 13, 14, 21), the bond strength and its oscillation period;
//! Hertz contact time at the largest expected impact speed (M.8) and the Rayleigh time (M.9).

use std::fmt::{self, Write as _};

use crate::contact::{NormalParams, hertz, tangential};
use crate::integrate;
use crate::model::Model;
use crate::particles::Particles;
use crate::simulation::Simulation;

/// Fewer steps than this per Hertz contact or bond oscillation resolve it poorly (warning).
pub const MIN_STEPS_PER_CONTACT: f64 = 20.0;
/// Steps per contact time that `check` recommends (restitution within ~1 %).
pub const RECOMMENDED_STEPS_PER_CONTACT: f64 = 50.0;
/// Steps per damper relaxation time `m*/c` that `check` recommends (binds for ξ ≳ 1).
pub const STEPS_PER_DAMPING_TIME: f64 = 8.0;
/// Largest dt as a fraction of the Rayleigh time (the LIGGGHTS/EDEM convention).
pub const MAX_RAYLEIGH_FRACTION: f64 = 0.2;

/// One row of the per-pair table.
#[derive(Debug, Clone, PartialEq)]
pub struct PairRow {
    /// Material names.
    pub materials: (String, String),
    /// Radii of the two spheres \[m\] (a wall has radius ∞).
    pub radii: (f64, f64),
    /// E* \[Pa\].
    pub effective_modulus: f64,
    /// r* \[m\].
    pub effective_radius: f64,
    /// m* \[kg\].
    pub effective_mass: f64,
    /// Hertz contact time at the expected impact speed \[s\].
    pub contact_time: f64,
    /// Largest stable dt (M.70) of the contact at the largest overlap of the expected impact,
    /// and of the bond at δ_eq and at that overlap \[s\].
    pub stability_limit: f64,
    /// Relaxation time of the contact's damper at that overlap, `m*/c = 1/(2ξω)` \[s\] (∞ for
    /// ξ = 0): the fastest time scale of a heavily damped contact.
    pub damping_time: f64,
    /// Bond quantities, when the scene has a bond.
    pub bond: Option<BondRow>,
}

/// Bond quantities of one pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BondRow {
    /// k_adh [N·m^-α].
    pub adhesion_stiffness: f64,
    /// δ_eq \[m\].
    pub equilibrium_overlap: f64,
    /// δ_crit \[m\].
    pub critical_overlap: f64,
    /// v_crit [m/s].
    pub critical_velocity: f64,
    /// Bond strength (largest attraction) \[N\].
    pub strength: f64,
    /// Period of small oscillations about δ_eq \[s\].
    pub oscillation_period: f64,
}

/// Everything `check` prints.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// Time step \[s\].
    pub dt: f64,
    /// Steps of the run.
    pub steps: u64,
    /// Number of particles.
    pub particles: usize,
    /// The impact speed used for contact times [m/s], and where it comes from.
    pub impact_speed: (f64, &'static str),
    /// Per-pair rows.
    pub pairs: Vec<PairRow>,
    /// Smallest Rayleigh time over materials and radii \[s\].
    pub rayleigh_time: f64,
    /// Largest initial overlap relative to the smaller radius.
    pub initial_overlap_ratio: f64,
    /// Recommended dt \[s\].
    pub recommended_dt: f64,
    /// The stability limit of the scene (M.70) \[s\] and what sets it: the smallest over the pair
    /// rows and over the contacts of the initial state.
    pub stability_limit: (f64, String),
    /// Warnings (empty when dt is fine).
    pub warnings: Vec<String>,
    /// Thermal time scales, for scenes with `[thermal]`.
    pub thermal: Option<ThermalCheck>,
    /// Tangential time scale, for scenes with friction or rolling resistance.
    pub friction: Option<FrictionCheck>,
}

/// Tangential part of the report (M.64).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionCheck {
    /// Smallest and largest `k_t/k_n = 4 G*/E*` over material pairs and walls.
    pub stiffness_ratio: (f64, f64),
    /// Sticking tangential oscillation time relative to the Hertz contact time,
    /// `√(2/7 · k_n/k_t)` at the largest stiffness ratio.
    pub time_factor: f64,
    /// Shortest Hertz contact time times `time_factor` \[s\].
    pub tangential_time: f64,
    /// The rotational state the run starts from (a bed imported from LIGGGHTS brings spins and
    /// springs; a fresh start has none).
    pub start: RotationStart,
}

/// Spins and tangential springs at t = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationStart {
    /// Spheres with a non-zero angular velocity.
    pub spinning: usize,
    /// Largest |ω| \[rad/s\].
    pub max_spin: f64,
    /// Pairs holding a stretched tangential spring (ξ ≠ 0) after the set-up evaluation: an
    /// import's springs, less those of contacts without normal load, whose Coulomb limit is zero.
    pub pair_springs: usize,
    /// Particle–wall contacts holding one.
    pub wall_springs: usize,
    /// The springs' energy ½ k_t |ξ|² \[J\] (M.63).
    pub spring_energy: f64,
}

impl RotationStart {
    fn of(sim: &Simulation) -> Self {
        let spins = sim
            .rotation
            .as_ref()
            .map_or(&[][..], |r| r.angular_velocity.as_slice());
        let (pair_springs, wall_springs, spring_energy) = sim.held_springs();
        Self {
            spinning: spins.iter().filter(|w| **w != glam::DVec3::ZERO).count(),
            max_spin: spins.iter().map(|w| w.length()).fold(0.0, f64::max),
            pair_springs,
            wall_springs,
            spring_energy,
        }
    }

    /// True when the run starts at rest, without springs.
    #[must_use]
    pub fn is_at_rest(&self) -> bool {
        self.spinning == 0 && self.pair_springs == 0 && self.wall_springs == 0
    }
}

impl fmt::Display for RotationStart {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the start holds {} spinning spheres (|ω| ≤ {:.4e} rad/s) and {} pair and {} wall tangential springs ({:.4e} J)",
            self.spinning, self.max_spin, self.pair_springs, self.wall_springs, self.spring_energy
        )
    }
}

/// k_t/k_n and the tangential time scale (M.64); lowers `recommended` and warns when dt resolves
/// the tangential oscillation too coarsely.
fn friction_check(
    sim: &Simulation,
    pairs: &[PairRow],
    recommended: &mut f64,
    warnings: &mut Vec<String>,
) -> Option<FrictionCheck> {
    let model = &sim.model;
    let friction = model.friction.as_ref()?;
    let n = u16::try_from(model.materials.len()).unwrap_or(u16::MAX);
    // (G*, E*) of every material pair and material–wall pair.
    let mut moduli = Vec::new();
    for a in 0..n {
        for b in 0..n {
            moduli.push((
                friction.pair(a, b).effective_shear_modulus,
                model.pair_params(a, b).effective_modulus,
            ));
        }
        for w in 0..model.walls.len() {
            moduli.push((
                friction.wall(w, a).effective_shear_modulus,
                model.wall_params(w, a).effective_modulus,
            ));
        }
    }
    let ratios = moduli.iter().map(|(shear, normal)| 4.0 * shear / normal);
    let lo = ratios.clone().fold(f64::INFINITY, f64::min);
    let hi = ratios.fold(0.0, f64::max);
    let time_factor = moduli
        .iter()
        .map(|&(shear, normal)| tangential::sticking_time_factor(shear, normal))
        .fold(f64::INFINITY, f64::min);
    let shortest = pairs
        .iter()
        .map(|row| row.contact_time)
        .fold(f64::INFINITY, f64::min);
    let tangential_time = shortest * time_factor;
    if tangential_time.is_finite() {
        *recommended = recommended.min(tangential_time / RECOMMENDED_STEPS_PER_CONTACT);
        if model.dt > tangential_time / MIN_STEPS_PER_CONTACT {
            warnings.push(format!(
                "dt = {:.3e} s resolves the tangential (sticking) time scale {tangential_time:.3e} s with only {:.1} steps (want ≥ {MIN_STEPS_PER_CONTACT})",
                model.dt,
                tangential_time / model.dt
            ));
        }
    }
    Some(FrictionCheck {
        stiffness_ratio: (lo, hi),
        time_factor,
        tangential_time,
        start: RotationStart::of(sim),
    })
}

/// Smallest and largest radius of each material present (None for absent materials).
fn radius_range(model: &Model, particles: &Particles) -> Vec<Option<(f64, f64)>> {
    let mut ranges = vec![None; model.materials.len()];
    for (r, m) in particles.radius.iter().zip(&particles.material) {
        let slot: &mut Option<(f64, f64)> = &mut ranges[usize::from(*m)];
        *slot = Some(slot.map_or((*r, *r), |(lo, hi)| (lo.min(*r), hi.max(*r))));
    }
    ranges
}

/// The largest impact speed to expect: the scene's value, else the larger of twice the largest
/// initial speed and the free-fall speed over the height of the scene along gravity.
#[must_use]
pub fn expected_impact_speed(model: &Model, particles: &Particles) -> (f64, &'static str) {
    if let Some(v) = model.expected_impact_speed {
        return (v, "simulation.expected_impact_speed_m_s");
    }
    let initial = 2.0
        * particles
            .velocity
            .iter()
            .map(|v| v.length())
            .fold(0.0, f64::max);
    let g = model.gravity.length();
    let fall = if g > 0.0 {
        let up = -model.gravity / g;
        let heights = particles.position.iter().map(|x| x.dot(up));
        let top = heights.clone().fold(f64::NEG_INFINITY, f64::max);
        let bottom = model
            .walls
            .iter()
            .filter(|w| w.normal.dot(up) > 0.5)
            .map(|w| w.point.dot(up))
            .chain(heights)
            .fold(f64::INFINITY, f64::min);
        (2.0 * g * (top - bottom)).sqrt()
    } else {
        0.0
    };
    if fall > initial {
        (fall, "free fall over the scene height")
    } else {
        (initial, "2 × largest initial speed")
    }
}

/// Thermal part of the report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalCheck {
    /// Smallest thermal time constant `min C_i/G_i` at t = 0 \[s\] (M.49).
    pub time_constant: f64,
    /// Substeps per mechanical step this gives (M.49).
    pub substeps: f64,
    /// Laser ray-casting cell \[m\] and the smallest radius \[m\], with a laser.
    pub raster: Option<(f64, f64)>,
}

/// Substeps beyond this many per step make a run slow: `check` warns.
pub const MANY_SUBSTEPS: f64 = 100.0;

/// Builds the report for a simulation set up at t = 0.
#[must_use]
pub fn report(sim: &Simulation) -> CheckReport {
    let (model, particles) = (&sim.model, &sim.particles);
    let initial_overlap_ratio = sim.diagnostics().max_overlap_ratio;
    let ranges = radius_range(model, particles);
    let (speed, source) = expected_impact_speed(model, particles);
    let mass = |material: usize, r: f64| {
        model.materials[material].density * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3)
    };
    let mut pairs = Vec::new();
    let mut rayleigh = f64::INFINITY;
    let names = |a: usize, b: Option<usize>| {
        (
            model.materials[a].name.clone(),
            b.map_or_else(|| "wall".to_string(), |b| model.materials[b].name.clone()),
        )
    };
    for a in 0..model.materials.len() {
        let Some((lo_a, hi_a)) = ranges[a] else {
            continue;
        };
        let m = &model.materials[a];
        rayleigh = rayleigh.min(hertz::rayleigh_time(
            lo_a,
            m.density,
            m.youngs_modulus,
            m.poisson_ratio,
        ));
        for (b, range_b) in ranges.iter().enumerate().skip(a) {
            let Some((lo_b, hi_b)) = *range_b else {
                continue;
            };
            let params =
                model.pair_params(u16::try_from(a).unwrap_or(0), u16::try_from(b).unwrap_or(0));
            let mut sizes = vec![(lo_a, lo_b)];
            if (hi_a, hi_b) != (lo_a, lo_b) {
                sizes.push((hi_a, hi_b));
            }
            for (ra, rb) in sizes {
                let r_star = hertz::effective_radius(ra, rb);
                let m_star = hertz::effective_mass(mass(a, ra), mass(b, rb));
                pairs.push(pair_row(
                    names(a, Some(b)),
                    (ra, rb),
                    params,
                    r_star,
                    m_star,
                    speed,
                ));
            }
        }
        for w in 0..model.walls.len() {
            let params = model.wall_params(w, u16::try_from(a).unwrap_or(0));
            pairs.push(pair_row(
                names(a, None),
                (lo_a, f64::INFINITY),
                params,
                lo_a,
                mass(a, lo_a),
                speed,
            ));
        }
    }
    pairs.dedup();

    let mut recommended = MAX_RAYLEIGH_FRACTION * rayleigh;
    let mut warnings = Vec::new();
    let dt = model.dt;
    let mut stability_limit = (f64::INFINITY, String::from("no contact expected"));
    if dt > MAX_RAYLEIGH_FRACTION * rayleigh {
        warnings.push(format!(
            "dt = {dt:.3e} s exceeds {MAX_RAYLEIGH_FRACTION} × the Rayleigh time {rayleigh:.3e} s"
        ));
    }
    for row in &pairs {
        let label = if row.radii.1.is_finite() {
            format!(
                "{}–{} (r = {:.3e}, {:.3e} m)",
                row.materials.0, row.materials.1, row.radii.0, row.radii.1
            )
        } else {
            format!("{}–wall (r = {:.3e} m)", row.materials.0, row.radii.0)
        };
        // A heavily damped contact relaxes faster than it oscillates: its damper's time m*/c
        // is resolved by STEPS_PER_DAMPING_TIME steps (ξ = 5: energy balance within 3 %,
        // tests/extreme_cases.rs); for moderate ξ the contact time binds first.
        recommended = recommended.min(row.damping_time / STEPS_PER_DAMPING_TIME);
        if row.stability_limit < stability_limit.0 {
            stability_limit = (
                row.stability_limit,
                format!("{label} at the largest overlap of a {speed:.3} m/s impact"),
            );
        }
        if row.contact_time.is_finite() {
            recommended = recommended.min(row.contact_time / RECOMMENDED_STEPS_PER_CONTACT);
            if dt > row.contact_time / MIN_STEPS_PER_CONTACT {
                warnings.push(format!(
                    "{label}: dt = {dt:.3e} s resolves the Hertz contact time {:.3e} s at {speed:.3} m/s with only {:.1} steps (want ≥ {MIN_STEPS_PER_CONTACT})",
                    row.contact_time,
                    row.contact_time / dt
                ));
            }
        }
        if let Some(bond) = &row.bond {
            if bond.oscillation_period > 0.0 && bond.oscillation_period.is_finite() {
                recommended =
                    recommended.min(bond.oscillation_period / RECOMMENDED_STEPS_PER_CONTACT);
                if dt > bond.oscillation_period / MIN_STEPS_PER_CONTACT {
                    warnings.push(format!(
                        "{label}: dt = {dt:.3e} s resolves the bond oscillation period {:.3e} s with only {:.1} steps (want ≥ {MIN_STEPS_PER_CONTACT})",
                        bond.oscillation_period,
                        bond.oscillation_period / dt
                    ));
                }
            }
        }
    }
    // With friction a sticking contact also oscillates tangentially, against the reduced mass
    // 2/7 m* (rotation included) and k_t = (4G*/E*) k_n: ω_t = ω_n / time_factor (M.64), so
    // the limit shrinks by that factor where it is below 1 (0.59 for ν = 0.3).
    let friction = friction_check(sim, &pairs, &mut recommended, &mut warnings);
    if let Some(f) = &friction {
        if f.time_factor < 1.0 {
            stability_limit.0 *= f.time_factor;
            stability_limit
                .1
                .push_str(&format!(", sticking tangentially (× {:.3})", f.time_factor));
        }
    }
    // Impacts are resolved by t_c/50 above; the limit keeps a margin of 2.
    recommended = recommended.min(0.5 * stability_limit.0);
    if let Some(now) = sim.stability_limit_now() {
        // A contact of the initial state has no impact time: resolve its own period, 50 steps
        // per 2π/ω = π dt_max when undamped (M.70).
        recommended =
            recommended.min(std::f64::consts::PI * now.dt_max / RECOMMENDED_STEPS_PER_CONTACT);
        if now.dt_max < stability_limit.0 {
            let pair = match now.ids {
                (a, Some(b)) => format!("particles {a} and {b}"),
                (a, None) => format!("particle {a} and a wall"),
            };
            stability_limit = (
                now.dt_max,
                format!("{pair} at their initial overlap {:.3e} m", now.overlap),
            );
        }
    }
    let smallest_radius = particles
        .radius
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let thermal = sim.smallest_thermal_time_constant().map(|tau| {
        let theta = model.thermal.as_ref().map_or(1.0, |t| t.substep_fraction);
        ThermalCheck {
            time_constant: tau,
            substeps: (dt / (theta * tau)).ceil().max(1.0),
            raster: model
                .laser
                .as_ref()
                .map(|l| (l.raster_cell, smallest_radius)),
        }
    });
    if let Some(t) = &thermal {
        if t.substeps > MANY_SUBSTEPS {
            warnings.push(format!(
                "the smallest thermal time constant {:.3e} s needs {:.0} thermal substeps per step: stable, but slow",
                t.time_constant, t.substeps
            ));
        }
        if let Some((cell, radius)) = t.raster {
            if cell > radius / 3.0 {
                warnings.push(format!(
                    "laser.raster_cell_m = {cell:.3e} m is coarser than a third of the smallest radius {radius:.3e} m: absorbed powers are rough"
                ));
            }
        }
    }
    CheckReport {
        thermal,
        friction,
        dt,
        steps: model.steps,
        particles: particles.len(),
        impact_speed: (speed, source),
        pairs,
        rayleigh_time: rayleigh,
        initial_overlap_ratio,
        recommended_dt: recommended,
        stability_limit,
        warnings,
    }
}

fn pair_row(
    materials: (String, String),
    radii: (f64, f64),
    params: &NormalParams,
    r_star: f64,
    m_star: f64,
    speed: f64,
) -> PairRow {
    let (e_star, damping_ratio, bond) = (
        params.effective_modulus,
        params.damping_ratio,
        params.bond.as_ref(),
    );
    let contact_time = if speed > 0.0 {
        hertz::contact_time(m_star, e_star, r_star, speed)
    } else {
        f64::INFINITY
    };
    let impact_overlap = hertz::max_overlap(m_star, e_star, r_star, speed);
    let mut stability_limit = integrate::stability_limit(
        hertz::stiffness(e_star, r_star, impact_overlap),
        m_star,
        damping_ratio,
    );
    let impact_stiffness = hertz::stiffness(e_star, r_star, impact_overlap);
    let damping_time = if damping_ratio > 0.0 && impact_stiffness > 0.0 {
        1.0 / (2.0 * damping_ratio * (impact_stiffness / m_star).sqrt())
    } else {
        f64::INFINITY
    };
    if let Some(b) = bond {
        for overlap in [b.equilibrium_overlap(e_star, r_star), impact_overlap] {
            stability_limit = stability_limit.min(integrate::stability_limit(
                b.stiffness(e_star, r_star, overlap),
                m_star,
                b.damping_ratio,
            ));
        }
    }
    PairRow {
        stability_limit,
        damping_time,
        materials,
        radii,
        effective_modulus: e_star,
        effective_radius: r_star,
        effective_mass: m_star,
        contact_time,
        bond: bond.map(|b| BondRow {
            adhesion_stiffness: b.adhesion_stiffness,
            equilibrium_overlap: b.equilibrium_overlap(e_star, r_star),
            critical_overlap: b.critical_overlap(e_star, r_star),
            critical_velocity: b.critical_velocity(e_star, r_star, m_star),
            strength: b.strength(e_star, r_star),
            oscillation_period: 2.0 * std::f64::consts::PI
                / b.oscillation_frequency(e_star, r_star, m_star),
        }),
    }
}

impl CheckReport {
    /// Why the scene's dt is beyond its stability limit (M.70), or `None` if it is within.
    /// A run refuses such a scene unless forced.
    #[must_use]
    pub fn instability(&self) -> Option<String> {
        (self.dt > self.stability_limit.0).then(|| {
            format!(
                "simulation.dt_s = {:.3e} s is beyond the stability limit {:.3e} s of velocity Verlet for the stiffest contact ({}): the run would blow up. Use dt ≤ {:.3e} s (recommended), or run with --force to try anyway",
                self.dt, self.stability_limit.0, self.stability_limit.1, self.recommended_dt
            )
        })
    }
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "scene is valid: {} particles, {} steps of dt = {:.3e} s",
            self.particles, self.steps, self.dt
        )?;
        writeln!(
            f,
            "expected impact speed: {:.4} m/s ({})",
            self.impact_speed.0, self.impact_speed.1
        )?;
        writeln!(f)?;
        for row in &self.pairs {
            let mut line = format!(
                "{} – {} (r = {:.4e} m, {}):\n    E* = {:.4e} Pa, r* = {:.4e} m, m* = {:.4e} kg, Hertz contact time {}, stable dt ≤ {:.3e} s",
                row.materials.0,
                row.materials.1,
                row.radii.0,
                if row.radii.1.is_finite() {
                    format!("{:.4e} m", row.radii.1)
                } else {
                    "plane".into()
                },
                row.effective_modulus,
                row.effective_radius,
                row.effective_mass,
                if row.contact_time.is_finite() {
                    format!(
                        "{:.4e} s ({:.1} steps)",
                        row.contact_time,
                        row.contact_time / self.dt
                    )
                } else {
                    "n/a (no impact expected)".into()
                },
                row.stability_limit,
            );
            if let Some(b) = &row.bond {
                let _ = write!(
                    line,
                    "\n    bond: k_adh = {:.4e} N/m^α, δ_eq = {:.4e} m, δ_crit = {:.4e} m (ε_crit = {:.4e}), v_crit = {:.4} m/s,\n          strength {:.4e} N, oscillation period at δ_eq {:.4e} s ({:.1} steps)",
                    b.adhesion_stiffness,
                    b.equilibrium_overlap,
                    b.critical_overlap,
                    b.critical_overlap / row.effective_radius,
                    b.critical_velocity,
                    b.strength,
                    b.oscillation_period,
                    b.oscillation_period / self.dt
                );
            }
            writeln!(f, "{line}")?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "Rayleigh time (smallest sphere): {:.4e} s; dt = {:.3} × Rayleigh time",
            self.rayleigh_time,
            self.dt / self.rayleigh_time
        )?;
        writeln!(
            f,
            "largest initial overlap: {:.3} % of the smaller radius",
            100.0 * self.initial_overlap_ratio
        )?;
        writeln!(
            f,
            "stability limit: dt ≤ {:.3e} s (set by {}); dt = {:.3} × the limit",
            self.stability_limit.0,
            self.stability_limit.1,
            self.dt / self.stability_limit.0
        )?;
        writeln!(
            f,
            "recommended dt ≤ {:.3e} s (≥ {RECOMMENDED_STEPS_PER_CONTACT} steps per contact and per bond oscillation, ≤ {MAX_RAYLEIGH_FRACTION} × Rayleigh time)",
            self.recommended_dt
        )?;
        if let Some(t) = &self.thermal {
            writeln!(
                f,
                "smallest thermal time constant at t = 0: {:.4e} s (dt = {:.3e} of it); thermal substeps per step: {:.0}",
                t.time_constant,
                self.dt / t.time_constant,
                t.substeps
            )?;
            if let Some((cell, _)) = t.raster {
                writeln!(f, "laser ray-casting cell: {cell:.3e} m")?;
            }
        }
        if let Some(t) = &self.friction {
            writeln!(
                f,
                "tangential contact: k_t/k_n = {:.4}–{:.4}; sticking oscillation time = {:.4} × Hertz contact time = {:.4e} s ({:.1} steps)",
                t.stiffness_ratio.0,
                t.stiffness_ratio.1,
                t.time_factor,
                t.tangential_time,
                t.tangential_time / self.dt
            )?;
            if !t.start.is_at_rest() {
                writeln!(f, "{}", t.start)?;
            }
        }
        if let Some(reason) = self.instability() {
            writeln!(f, "error: {reason}")?;
        } else if self.warnings.is_empty() {
            writeln!(f, "time step: OK")?;
        } else {
            for w in &self.warnings {
                writeln!(f, "warning: {w}")?;
            }
        }
        Ok(())
    }
}
