//! Deposition: the scene's particles fall under gravity onto the walls until the bed has
//! settled, before the scene's own run starts (docs/model.md, M.75).
//!
//! The criterion compares the mean kinetic energy per particle with `m̄ g d̄`, the energy that
//! lifts a sphere of the mean mass by the mean diameter: the scale of the rearrangements a
//! settling bed still makes (a sphere rolling over a neighbour). The default ratio 1e-4 means an
//! rms speed of 1 % of the free-fall speed over one diameter, `sqrt(2 g d̄)`: for d̄ = 30 µm,
//! 0.24 mm/s, or 1 % of a diameter per millisecond (the time a laser spot takes to pass).
//! Frictionless spheres creep on for a long time (tests/bed_deposition.rs: a ratio of 1e-4 took
//! 19 ms for 200 spheres; in trials 1e-6 was not reached within 50 ms); `damping_time_s` (M.76)
//! helps.
//!
//! A bed at rest before it falls also has no kinetic energy, so checks count only after the
//! free-fall time over the bed's initial height along gravity plus one mean diameter,
//! `t_ff = sqrt(2 (h + d̄) / g)`: no particle can have landed before it.
//!
//! The deposition is a pre-run: the laser is off (removed from the model while it runs),
//! nothing is written, and afterwards the step counter, the clock and the dissipated-energy
//! bookkeeping are reset, so the scene's `duration_s`, the laser's `start_time_s` and the
//! output's frames all count from the settled bed. At each check it measures its own error
//! indicators ([`DepositionReport::energy_residual`], with what the background damping took
//! booked as lost, and [`DepositionReport::peak_overlap_ratio`]), which `am-sim` prints.
//!
//! A bed that is at the temperature of everything it exchanges heat with, none of it melted
//! ([`ThermalModel::is_inert`]), would exchange no heat while the laser is off: the deposition
//! then leaves the heat model out as well (no contact conductances, boundary exchange or
//! temperature update at each step), and the temperatures stay exactly as they were. A powder
//! deposited at room temperature settles at the cost of a scene without `[thermal]`.

use crate::laser::Laser;
use crate::particles::Particles;
use crate::simulation::{GuardTrip, Simulation};
use crate::thermal::ThermalModel;

/// Resolved `[deposition]` settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deposition {
    /// Steps after which an unsettled bed is an error.
    pub max_steps: u64,
    /// Steps between two checks of the criterion.
    pub check_every: u64,
    /// Settled when the mean kinetic energy per particle ≤ this × m̄ g d̄ (M.75).
    pub kinetic_energy_ratio: f64,
    /// Relaxation time τ of the background damping (M.76): after every step all velocities are
    /// multiplied by exp(−dt/τ). `None`: no damping beyond the contacts'.
    pub damping_time: Option<f64>,
}

/// How a deposition ended.
#[derive(Debug, Clone, PartialEq)]
pub struct DepositionReport {
    /// Whether the criterion was met (otherwise `max_steps` ran out).
    pub settled: bool,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time \[s\].
    pub time: f64,
    /// Mean kinetic energy per particle over m̄ g d̄ at the last check (M.75).
    pub kinetic_energy_ratio: f64,
    /// The guard that stopped the deposition, if one tripped (docs/stability.md).
    pub stopped: Option<GuardTrip>,
    /// The deposition's mechanical energy balance (M.35) at its last check (its end, before
    /// the clock restarts), relative to its energy scale as a run's is, with what the
    /// background damping took booked as lost (M.76). Zero before the first check.
    pub energy_residual: f64,
    /// The largest overlap of any of the deposition's steps up to its last check, relative to
    /// the smaller radius of its pair. Zero before the first check.
    pub peak_overlap_ratio: f64,
}

/// `m̄ g d̄` \[J\]: mean mass × |gravity| × mean diameter (M.75).
#[must_use]
pub fn reference_energy(particles: &Particles, gravity: f64) -> f64 {
    #[allow(clippy::cast_precision_loss)]
    let n = particles.len().max(1) as f64;
    let mean_mass = particles.mass.iter().sum::<f64>() / n;
    let mean_diameter = 2.0 * particles.radius.iter().sum::<f64>() / n;
    mean_mass * gravity * mean_diameter
}

/// Mean kinetic energy per particle over `m̄ g d̄` (M.75).
#[must_use]
pub fn kinetic_energy_ratio(particles: &Particles, gravity: f64) -> f64 {
    #[allow(clippy::cast_precision_loss)]
    let n = particles.len().max(1) as f64;
    particles.kinetic_energy() / n / reference_energy(particles, gravity)
}

/// Steps of `dt` in the free-fall time `sqrt(2 (h + d̄) / g)` over the particles' extent `h`
/// along `gravity` plus the mean diameter `d̄`: before it, a small kinetic energy does not mean
/// that the bed has settled.
#[must_use]
pub fn free_fall_steps(particles: &Particles, gravity: glam::DVec3, dt: f64) -> u64 {
    let g = gravity.length();
    if g == 0.0 || particles.is_empty() {
        return 0;
    }
    let down = gravity / g;
    let (lo, hi) = particles
        .position
        .iter()
        .map(|x| x.dot(down))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| {
            (lo.min(h), hi.max(h))
        });
    #[allow(clippy::cast_precision_loss)]
    let mean_diameter = 2.0 * particles.radius.iter().sum::<f64>() / particles.len() as f64;
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let steps = ((2.0 * (hi - lo + mean_diameter) / g).sqrt() / dt).ceil() as u64;
    steps
}

/// Steps `sim` with the laser off until the criterion of `settings` holds at a check, or
/// `max_steps` have run; then resets the step counter, the clock and the dissipated energy (the
/// settled bed is the scene's starting state). Calls `progress` after every check. A tripped
/// guard stops it ([`DepositionReport::stopped`]): the per-step guards after every step, the
/// energy guard at every check, as a run checks it at its output steps (docs/stability.md).
pub fn settle(
    sim: &mut Simulation,
    settings: &Deposition,
    mut progress: impl FnMut(&DepositionReport),
) -> DepositionReport {
    let gravity = sim.model.gravity.length();
    let earliest = free_fall_steps(&sim.particles, sim.model.gravity, sim.model.dt);
    let laser = sim.model.laser.take();
    let inert = sim
        .model
        .thermal
        .as_ref()
        .zip(sim.thermal.as_ref())
        .is_some_and(|(model, state)| model.is_inert(state));
    let heat = sim.model.thermal.take_if(|_| inert);
    let mut report = DepositionReport {
        settled: false,
        steps: 0,
        time: 0.0,
        kinetic_energy_ratio: kinetic_energy_ratio(&sim.particles, gravity),
        stopped: None,
        energy_residual: 0.0,
        peak_overlap_ratio: 0.0,
    };
    // The factor e^{−Δt/τ} of M.76, and the share 1 − e^{−2Δt/τ} of a particle's kinetic energy
    // it takes (without the cancellation of 1 − factor²).
    let decay = settings.damping_time.map(|tau| {
        let interval = sim.model.dt / tau;
        (libm::exp(-interval), -libm::expm1(-2.0 * interval))
    });
    while report.steps < settings.max_steps {
        let chunk = settings.check_every.min(settings.max_steps - report.steps);
        // Without the decay nothing acts between the steps: they run in one call, which leaves
        // each closing kick to the next opening pass (`Simulation::advance`).
        let per_call = if decay.is_some() { 1 } else { chunk };
        for _ in 0..chunk / per_call {
            sim.advance(per_call, || true);
            if let Some(trip) = sim.guard_trip() {
                report.stopped = Some(trip);
                report.steps = sim.step;
                report.time = sim.time;
                hand_back(sim, laser, heat);
                return report;
            }
            if let Some((factor, taken)) = decay {
                let particles = &mut sim.particles;
                for ((v, m), lost) in particles
                    .velocity
                    .iter_mut()
                    .zip(&particles.mass)
                    .zip(&mut particles.dissipated)
                {
                    // Booked as lost, so that the energy balance (M.35) closes.
                    *lost += taken * 0.5 * m * v.length_squared();
                    *v *= factor;
                }
            }
        }
        report.steps += chunk;
        report.time = sim.time;
        // At each check, the deposition's error indicators, and the energy guard a run applies
        // at its output steps: a blow-up slow enough to pass the per-step guards stops the
        // deposition too. The last check is the deposition's end.
        let measured = sim.diagnostics();
        report.energy_residual = measured.energy_residual;
        report.peak_overlap_ratio = measured.peak_overlap_ratio;
        if let Some(trip) = sim.energy_guard_trip(&measured) {
            report.stopped = Some(trip);
            hand_back(sim, laser, heat);
            return report;
        }
        report.kinetic_energy_ratio = kinetic_energy_ratio(&sim.particles, gravity);
        report.settled = report.steps >= earliest
            && report.kinetic_energy_ratio <= settings.kinetic_energy_ratio;
        progress(&report);
        if report.settled {
            break;
        }
    }
    hand_back(sim, laser, heat);
    sim.restart_clock();
    report
}

/// Puts back into the model what the deposition took out of it: the laser, and the heat model
/// if the bed was inert.
fn hand_back(sim: &mut Simulation, laser: Option<Laser>, heat: Option<ThermalModel>) {
    sim.model.laser = laser;
    if heat.is_some() {
        sim.model.thermal = heat;
    }
}
