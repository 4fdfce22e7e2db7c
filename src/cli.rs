//! The `am-sim` command line: `am-sim scene.toml` runs a scene, `am-sim check scene.toml`
//! validates it and prints derived quantities. Only I/O and error printing live here.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::check;
use crate::model::Model;
use crate::output::Writers;
use crate::scene::Scene;
use crate::simulation::{Diagnostics, GuardTrip, Simulation};

/// Prints to stdout. A closed pipe (`am-sim check scene.toml | head`) ends the output quietly
/// instead of panicking as `println!` does.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// Thermo-mechanical DEM of additive-manufacturing powder beds.
#[derive(Debug, Parser)]
#[command(
    name = "am-sim",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a scene (the same as `am-sim SCENE`).
    Run(RunArgs),
    /// Validate a scene and print derived quantities and time-step advice, without running it.
    Check {
        /// Scene file (TOML).
        scene: PathBuf,
    },
    /// Convergence study: error against run time on analytic cases (docs/accuracy.md).
    ///
    /// Sweeps the time step (and the thermal substep fraction) over cases with closed-form
    /// answers and writes OUT/accuracy.md and OUT/images/accuracy-*.png.
    Study {
        /// Reduced sweep: four time steps per quantity, every run timed once.
        #[arg(long)]
        quick: bool,
        /// Folder to write into.
        #[arg(long, default_value = "docs")]
        out: PathBuf,
    },
}

#[derive(Debug, Args)]
struct RunArgs {
    /// Scene file (TOML).
    scene: Option<PathBuf>,
    /// Worker threads (default: all cores). Results are bitwise the same for any count. Where
    /// other programs keep cores busy, give fewer: the threads meet several times per step.
    #[arg(long)]
    threads: Option<usize>,
    /// Replace existing output files instead of refusing to start.
    #[arg(long)]
    overwrite: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Continue the run saved in this HDF5 output file (from its last complete frame); the new
    /// frames are appended to it.
    #[arg(long, value_name = "FILE.h5")]
    restart: Option<PathBuf>,
    /// Run even when dt is beyond the scene's stability limit (see `am-sim check`).
    #[arg(long)]
    force: bool,
    /// The widest instruction set of the step's vector kernels: the contact laws of pairs and
    /// walls, the kicks and the drift (default: the widest this processor runs). Results are
    /// bitwise the same for any; keep `avx2` where AVX-512 runs slower.
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(crate::forces::kernel_builds()))]
    simd: Option<String>,
    /// Whether the force passes ask the cache for the partners' and the wall particles' lines
    /// ahead of their contacts: `auto` (default) does on beds above about 56,000 particles,
    /// whose arrays outgrow the caches. Results are bitwise the same either way.
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(crate::forces::PREFETCH_MODES))]
    prefetch: Option<String>,
    /// Time the thread team's passes and print, after the summary (and after the deposition's
    /// line, for its own), each pass's time per call and when its last thread was done, and each
    /// thread's part of it: when it started, finished its own share and its last item, and how
    /// many items it took from the others (where threads wait). Adds a few clock readings per
    /// pass; results are bitwise the same.
    #[arg(long)]
    team_times: bool,
}

/// How a run ended without error.
enum Ending {
    Finished,
    Interrupted,
}

/// Entry point of the binary.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Check { scene }) => run_check(&scene).map(|()| Ending::Finished),
        Some(Command::Run(args)) => run(&args),
        Some(Command::Study { quick, out }) => {
            crate::study::run(&crate::study::Options { quick, out }).map(|_| Ending::Finished)
        }
        None if cli.run.scene.is_some() => run(&cli.run),
        None => Err(
            "no scene given: usage `am-sim SCENE.toml` or `am-sim check SCENE.toml` (see --help)"
                .into(),
        ),
    };
    match result {
        Ok(Ending::Finished) => ExitCode::SUCCESS,
        // 128 + SIGINT, as shells report a program stopped by Ctrl-C.
        Ok(Ending::Interrupted) => ExitCode::from(130),
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn load(path: &Path) -> Result<Simulation, String> {
    let scene = Scene::load(path).map_err(|e| e.to_string())?;
    let (model, particles) = Model::try_build(&scene).map_err(|e| e.in_file(path).to_string())?;
    Ok(Simulation::new(model, particles))
}

/// Sets up the scene at the state saved in `file` (its last complete frame).
#[cfg(feature = "hdf5")]
fn resume(scene_path: &Path, file: &Path) -> Result<Simulation, String> {
    let scene = Scene::load(scene_path).map_err(|e| e.to_string())?;
    let (model, mut particles) =
        Model::try_build(&scene).map_err(|e| e.in_file(scene_path).to_string())?;
    let saved = crate::output::hdf5::read_last_frame(file).map_err(|e| e.to_string())?;
    // The frames hold the particles in the run's storage order (spatially sorted, without those
    // that left [domain], M.78): put the scene's particles in that order, by id.
    let index_of: std::collections::HashMap<u64, u32> = particles
        .id
        .iter()
        .enumerate()
        .map(|(k, id)| (*id, u32::try_from(k).expect("fewer than 2^32 particles")))
        .collect();
    let order: Option<Vec<u32>> = saved
        .id
        .iter()
        .map(|id| index_of.get(id).copied())
        .collect();
    let Some(order) = order else {
        return Err(format!(
            "{}: its frames hold particle ids the scene {} does not build ({} particles saved, {} built): restart with the scene that made the file",
            file.display(),
            scene_path.display(),
            saved.id.len(),
            particles.len()
        ));
    };
    particles.select(&order);
    if saved.scene != std::fs::read_to_string(scene_path).unwrap_or_default() {
        eprintln!(
            "warning: {} differs from the scene stored in {}: the run continues with {}",
            scene_path.display(),
            file.display(),
            scene_path.display()
        );
    }
    particles.position = saved.position;
    particles.velocity = saved.velocity;
    let sim = Simulation::resume(model, particles, saved.state)
        .map_err(|e| format!("{}: {e}", file.display()))?;
    if sim.step >= sim.model.steps {
        return Err(format!(
            "{} already reaches step {} of the scene's {} steps: raise simulation.duration_s to continue",
            file.display(),
            sim.step,
            sim.model.steps
        ));
    }
    Ok(sim)
}

#[cfg(not(feature = "hdf5"))]
fn resume(_scene_path: &Path, _file: &Path) -> Result<Simulation, String> {
    Err("--restart needs HDF5 output: this am-sim was built without the `hdf5` feature".into())
}

fn run_check(path: &Path) -> Result<(), String> {
    let sim = load(path)?;
    let report = check::report(&sim);
    say!("{}", report.to_string().trim_end());
    Ok(())
}

fn run(args: &RunArgs) -> Result<Ending, String> {
    let path = args.scene.as_deref().ok_or("no scene given")?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        if n == 0 {
            return Err("--threads 0: give at least one thread".into());
        }
        builder = builder.num_threads(n);
    }
    let pool = builder
        .build()
        .map_err(|e| format!("cannot start the thread pool: {e}"))?;
    let threads = pool.current_num_threads();
    let kernel = match &args.simd {
        Some(build) => crate::forces::limit_kernel(build).map_err(|e| format!("--simd: {e}"))?,
        None => crate::forces::kernel_build(),
    };
    if let Some(mode) = &args.prefetch {
        crate::forces::set_prefetch(mode).map_err(|e| format!("--prefetch: {e}"))?;
    }
    // Set-up (neighbour list, first forces) already runs on the requested threads.
    let mut sim = match &args.restart {
        Some(file) => pool.install(|| resume(path, file))?,
        None => pool.install(|| load(path))?,
    };
    let scene_text =
        std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let report = check::report(&sim);
    let instability = report.instability();
    if let (Some(reason), false) = (&instability, args.force) {
        return Err(format!("{}: {reason}", path.display()));
    }
    // Output files are opened last, after every check that can refuse the run.
    let mut writers = Writers::open(&sim, &scene_text, args.overwrite, args.restart.as_deref())
        .map_err(|e| e.to_string())?;

    let model = &sim.model;
    let title = if model.title.is_empty() {
        String::new()
    } else {
        format!("{} — ", model.title)
    };
    let from = if sim.step > 0 {
        format!(" (resuming at step {})", sim.step)
    } else {
        String::new()
    };
    say!(
        "am-sim {}: {title}{} particles, {} steps of dt = {:.3e} s ({:.4e} s){from}, {}, contact kernel {kernel}{}",
        env!("CARGO_PKG_VERSION"),
        sim.particles.len(),
        model.steps,
        model.dt,
        model.dt * model.steps as f64,
        thread_count(threads),
        if crate::forces::worth_prefetching(sim.particles.len()) {
            ", prefetching"
        } else {
            ""
        },
    );
    for w in report.warnings.iter().chain(&instability) {
        say!("warning: {w}");
    }
    if let Some(start) = report.friction.map(|f| f.start).filter(|s| !s.is_at_rest()) {
        say!("{start}");
    }

    if args.team_times {
        crate::team::time_passes();
    }
    // [deposition] (not on --restart: the saved frames are already of the settled bed).
    if let (Some(settings), None) = (sim.model.deposition, &args.restart) {
        let bar = if args.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::with_draw_target(Some(settings.max_steps), ProgressDrawTarget::stderr())
        };
        bar.set_style(
            ProgressStyle::with_template(
                "deposition {wide_bar} {pos}/{len} steps | E_kin/(m g d) = {msg} | {elapsed}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let started = Instant::now();
        let report = pool.install(|| {
            crate::bed::deposition::settle(&mut sim, &settings, |r| {
                bar.set_position(r.steps);
                bar.set_message(format!("{:.2e}", r.kinetic_energy_ratio));
            })
        });
        bar.finish_and_clear();
        if let Some(trip) = &report.stopped {
            let message = format!("deposition: {}", stop(&sim, &mut writers, trip, 0.0));
            let _ = writers.close();
            return Err(message);
        }
        let wall = started.elapsed().as_secs_f64();
        #[allow(clippy::cast_precision_loss)]
        let speed = (report.steps as f64) * (sim.particles.len() as f64) / wall.max(1e-9);
        let line = format!(
            "deposition: {} steps ({:.4e} s) in {wall:.3} s wall time ({speed:.3e} particle-steps/s), kinetic energy per particle {:.2e} m̄ g d̄ (criterion {:.1e})",
            report.steps, report.time, report.kinetic_energy_ratio, settings.kinetic_energy_ratio
        );
        // The deposition's own error indicators, as the run's summary gives the run's.
        let indicators = format!(
            "  deposition's error indicators: energy balance residual {:.2e} relative (M.35); largest overlap {:.3} % of the smaller radius (every step)",
            report.energy_residual.abs(),
            100.0 * report.peak_overlap_ratio
        );
        if !report.settled {
            let _ = writers.close();
            return Err(format!(
                "{line}: not settled within deposition.max_duration_s; raise it, or raise deposition.kinetic_energy_ratio\n{indicators}"
            ));
        }
        say!("{line}: settled; the run starts now (t = 0)");
        say!("{indicators}");
        if args.team_times {
            print_team_times("deposition's team passes", &crate::team::take_pass_times());
        }
    }

    // Ctrl-C asks the loop to stop after the current step; the last state is then written.
    let interrupted = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&interrupted);
    // A second handler cannot be installed (tests run several loops in one process): the
    // first one keeps working for its own flag, and this run simply cannot be interrupted.
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));

    let outcome = pool.install(|| run_loop(&mut sim, &mut writers, args.quiet, &interrupted));
    // Taken before the summary, whose own measurements use the team.
    let team_times = args.team_times.then(crate::team::take_pass_times);
    let files = writers.files(&sim);
    let closed = writers.close().map_err(|e| e.to_string());
    let outcome = outcome?;
    closed?;
    print_summary(&sim, &outcome, threads);
    if let Some(times) = team_times {
        print_team_times("team passes", &times);
    }
    let ending = outcome.ending;
    for line in files {
        say!("{line}");
    }
    if matches!(ending, Ending::Interrupted) {
        say!(
            "interrupted at step {} (t = {:.6e} s): the last state is in the output; continue with --restart",
            sim.step,
            sim.time
        );
    }
    Ok(ending)
}

/// What the run loop hands to the summary.
struct LoopOutcome {
    initial: Diagnostics,
    wall: f64,
    ending: Ending,
    /// Largest dt / stability limit seen at a series row or frame.
    peak_stability_ratio: f64,
    /// Largest dt / smallest thermal time constant seen at a series row or frame.
    peak_thermal_ratio: f64,
    /// Highest particle temperature seen at the start, a series row or a frame \[K\] (0
    /// without `[thermal]`): under a laser it can lie far above the last state's.
    peak_temperature: f64,
}

/// How many steps the run loop advances between progress updates. Each update ends an
/// [`Simulation::advance`] call, and a call's end costs a closing kick of its own (a pass over
/// the particles' velocities, forces, spins and torques) that the steps within a call fold into
/// the next opening pass. A hidden bar needs no updates; a shown one gets a few a second: the
/// stride doubles while a whole stride takes under 50 ms and halves while it takes over 200 ms,
/// from 16 steps up to a hundredth of the run. (A fixed stride of a thousandth of the run, at
/// least 16 steps, cut the 19.2k LIGGGHTS bed's 5500 steps into 437 calls where its 100
/// outputs need 100.) Where the calls end does not change the results.
#[derive(Debug)]
struct ProgressStride {
    /// Steps per call while the bar is shown; `None` without a bar.
    steps: Option<u64>,
    /// The largest stride.
    most: u64,
}

impl ProgressStride {
    const FEWEST: u64 = 16;

    fn new(quiet: bool, run_steps: u64) -> Self {
        Self {
            steps: (!quiet).then_some(Self::FEWEST),
            most: (run_steps / 100).max(Self::FEWEST),
        }
    }

    /// The step of the next progress update after `step` (`u64::MAX` without a bar).
    fn next_update(&self, step: u64) -> u64 {
        self.steps
            .map_or(u64::MAX, |stride| step.saturating_add(stride))
    }

    /// Adapts the stride to the wall time `took` of a call, if it ran a whole stride (`whole`:
    /// a call cut short by an output or a stop says nothing about the stride).
    fn adapt(&mut self, whole: bool, took: std::time::Duration) {
        let Some(stride) = self.steps.as_mut().filter(|_| whole) else {
            return;
        };
        if took < std::time::Duration::from_millis(50) {
            *stride = (*stride * 2).min(self.most);
        } else if took > std::time::Duration::from_millis(200) {
            *stride = (*stride / 2).max(Self::FEWEST);
        }
    }
}

/// Steps the simulation to the end, writing frames and series. The guards (docs/stability.md)
/// are checked every step (non-finite forces, overlaps) and wherever diagnostics are taken
/// (energy blow-up, non-finite particle values): a tripped guard stops the run with the step, the
/// particles and the quantity, after writing the state as the last frame if it is finite, and
/// never writes anything invalid. Ctrl-C stops after the current step.
fn run_loop(
    sim: &mut Simulation,
    writers: &mut Writers,
    quiet: bool,
    interrupted: &AtomicBool,
) -> Result<LoopOutcome, String> {
    let start = Instant::now();
    let initial = sim.diagnostics();
    let steps = sim.model.steps;
    let mut peak_stability_ratio = initial.stability_ratio;
    let thermal_ratio = |d: &Diagnostics| d.thermal.map_or(0.0, |t| t.time_step_ratio);
    let mut peak_thermal_ratio = thermal_ratio(&initial);
    let temperature = |d: &Diagnostics| d.thermal.map_or(0.0, |t| t.max_temperature);
    let mut peak_temperature = temperature(&initial);
    let mut check_and_write =
        |sim: &Simulation, writers: &mut Writers, last: bool| -> Result<(), String> {
            if let Some(trip) = sim.guard_trip() {
                return Err(stop(sim, writers, &trip, start.elapsed().as_secs_f64()));
            }
            if !writers.due(sim.step, last) {
                return Ok(());
            }
            if let Some((id, field)) = sim.first_non_finite() {
                return Err(stop(
                    sim,
                    writers,
                    &GuardTrip {
                        quantity: format!("a non-finite {field}"),
                        ids: vec![id],
                        state_is_finite: false,
                    },
                    start.elapsed().as_secs_f64(),
                ));
            }
            let d = sim.diagnostics();
            peak_stability_ratio = peak_stability_ratio.max(d.stability_ratio);
            peak_thermal_ratio = peak_thermal_ratio.max(thermal_ratio(&d));
            peak_temperature = peak_temperature.max(temperature(&d));
            if let Some(trip) = sim.energy_guard_trip(&d) {
                return Err(stop(sim, writers, &trip, start.elapsed().as_secs_f64()));
            }
            writers
                .write(sim, &d, start.elapsed().as_secs_f64(), last)
                .map_err(|e| e.to_string())
        };
    check_and_write(sim, writers, false)?;
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::stderr())
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{wide_bar} {pos}/{len} steps | t = {msg} | {elapsed} elapsed, ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_position(sim.step);
    // The steps up to the next output or progress update run in one call, whose closing kicks
    // are folded into the next opening passes (`Simulation::advance`): a call's end costs a kick
    // pass of its own. Without a bar the calls end at the outputs only; with one, the updates
    // come a few times a second (`ProgressStride`), not every few steps.
    let mut stride = ProgressStride::new(quiet, steps);
    let mut ending = Ending::Finished;
    while sim.step < steps {
        let next_update = stride.next_update(sim.step).min(steps);
        let until = (sim.step + 1..next_update)
            .find(|&step| writers.due(step, false))
            .unwrap_or(next_update);
        let call = Instant::now();
        sim.advance(until - sim.step, || !interrupted.load(Ordering::Relaxed));
        stride.adapt(sim.step == next_update, call.elapsed());
        let stop = interrupted.load(Ordering::Relaxed);
        if let Err(message) = check_and_write(sim, writers, stop || sim.step == steps) {
            bar.abandon();
            return Err(message);
        }
        if stop {
            ending = Ending::Interrupted;
            break;
        }
        if !quiet {
            bar.set_position(sim.step);
            bar.set_message(format!("{:.4e} s", sim.time));
        }
    }
    bar.finish_and_clear();
    Ok(LoopOutcome {
        initial,
        wall: start.elapsed().as_secs_f64(),
        ending,
        peak_stability_ratio,
        peak_thermal_ratio,
        peak_temperature,
    })
}

/// Ends a run on a tripped guard: writes the current state as the last frame when it is finite,
/// and returns the message naming the step, the particles and the quantity.
fn stop(sim: &Simulation, writers: &mut Writers, trip: &GuardTrip, wall: f64) -> String {
    let ids: Vec<String> = trip.ids.iter().map(u64::to_string).collect();
    let particles = match ids.len() {
        1 => format!("particle id {}", ids[0]),
        _ => format!("particle ids {}", ids.join(", ")),
    };
    let mut message = format!(
        "step {} (t = {:.6e} s): {particles}: {}; the run is stopped",
        sim.step, sim.time, trip.quantity
    );
    let written = trip.state_is_finite && {
        // A finite state is worth keeping: it shows where the run went wrong.
        let d = sim.diagnostics();
        d.mechanical_energy().is_finite() && writers.write(sim, &d, wall, true).is_ok()
    };
    if written {
        message.push_str(", and this state (finite) is the last frame of the output");
    } else {
        match writers.last_frame_step() {
            Some(step) => message.push_str(&format!(
                "; nothing invalid was written: the last good frame is step {step}"
            )),
            None => message.push_str("; nothing invalid was written"),
        }
    }
    message.push_str(" (check dt and the scene with `am-sim check`; docs/stability.md)");
    message
}

/// The team's passes of a stage of the run (`--team-times`), the longest first, per call.
fn print_team_times(title: &str, times: &[crate::team::PassTimes]) {
    say!(
        "  {title} (µs per call: the call, and when its last thread was done; then each thread's start, own share done, last item done, and items of its own + taken from the others):"
    );
    for pass in times {
        let calls = pass.calls.max(1) as f64;
        let name = if pass.part.is_empty() {
            pass.name.to_owned()
        } else {
            format!("{}, {}", pass.name, pass.part)
        };
        let mut line = format!(
            "    {name}: {} calls, {:.2} µs (last done {:.2})",
            pass.calls,
            1e6 * pass.wall / calls,
            1e6 * pass.last_done / calls
        );
        for (member, m) in pass.members.iter().enumerate() {
            line.push_str(&format!(
                " | {member}: {:.2}, {:.2}, {:.2} ({:.1} + {:.1})",
                1e6 * m.started / calls,
                1e6 * m.own_done / calls,
                1e6 * m.done / calls,
                m.own_items as f64 / calls,
                m.taken_items as f64 / calls
            ));
        }
        say!("{line}");
    }
}

/// "1 thread", "2 threads".
fn thread_count(threads: usize) -> String {
    if threads == 1 {
        "1 thread".to_string()
    } else {
        format!("{threads} threads")
    }
}

#[allow(clippy::cast_precision_loss)]
fn print_summary(sim: &Simulation, outcome: &LoopOutcome, threads: usize) {
    let d = sim.diagnostics();
    let (initial, wall) = (&outcome.initial, outcome.wall);
    let particle_steps = sim.particles.len() as f64 * (d.step - initial.step) as f64;
    say!(
        "done: {} steps, simulated {:.4e} s in {:.3} s wall time ({})",
        d.step,
        d.time,
        wall,
        thread_count(threads)
    );
    say!(
        "  speed: {:.3e} particle-steps/s ({:.3e} per thread)",
        particle_steps / wall.max(1e-9),
        particle_steps / wall.max(1e-9) / threads as f64
    );
    say!(
        "  contacts: {} particle-particle, {} particle-wall; bonds: {}; neighbour-list builds: {} (displacements measured at {} steps); near-list refreshes: {}",
        d.contacts,
        d.wall_contacts,
        d.bonds,
        d.neighbor_builds,
        d.displacement_checks,
        d.near_refreshes
    );
    if d.removed_particles > 0 {
        say!(
            "  removed: {} particles left the domain ([domain]); {} remain",
            d.removed_particles,
            sim.particles.len()
        );
    }
    // The run's own error indicators, beside its wall time (docs/stability.md, docs/accuracy.md).
    let lost = d.dissipated_energy - initial.dissipated_energy;
    say!(
        "  energy: mechanical {:.6e} J → {:.6e} J, lost to damping, friction and bonding {lost:.6e} J",
        initial.mechanical_energy(),
        d.mechanical_energy()
    );
    say!(
        "  error indicators: energy balance residual {:.2e} relative (M.35); largest overlap {:.3} % of the smaller radius (every step); dt = {:.3} × the stability limit at most (M.70, at output steps)",
        d.energy_residual.abs(),
        100.0 * d.peak_overlap_ratio,
        outcome.peak_stability_ratio.max(d.stability_ratio)
    );
    say!(
        "  now: largest overlap {:.4e} m ({:.3} % of the smaller radius); kinetic energy {:.4e} J",
        d.max_overlap,
        100.0 * d.max_overlap_ratio,
        d.kinetic_energy
    );
    if let (Some(t0), Some(t1)) = (initial.thermal, d.thermal) {
        say!(
            "  thermal: max temperature {:.1} K now, {:.1} K at most (at output steps); {} particles melted; laser absorbed {:.4e} J, boundaries {:+.4e} J",
            t1.max_temperature,
            outcome.peak_temperature.max(t1.max_temperature),
            t1.melted,
            t1.laser_energy,
            t1.boundary_energy
        );
        if let Some(e) = t1.evaporation {
            say!(
                "  evaporation: {:.4e} J carried off by {:.4e} kg of vapour from {} particles, at most {:.2} % of one particle's mass (M.80; the particles keep their mass)",
                e.heat,
                e.mass,
                e.particles,
                100.0 * e.max_fraction
            );
        }
        // Since the start of this run (a resumed run starts with the energies it had), particle
        // by particle (`ThermalDiagnostics::stored`).
        let stored = t1.stored - t0.stored;
        // Laser and boundaries, less what the vapour carried off.
        let supplied = t1.supplied_since(&t0);
        let net = if t1.evaporation.is_some() {
            "supplied less evaporated"
        } else {
            "supplied"
        };
        say!(
            "  heat balance: stored {stored:+.6e} J vs {net} {supplied:+.6e} J (residual {:.2e} relative); dt over the smallest thermal time constant {:.3e} at most (at output steps), {} substeps per step at most",
            t1.heat_residual.abs(),
            outcome.peak_thermal_ratio.max(t1.time_step_ratio),
            sim.thermal.as_ref().map_or(0, |t| t.max_substeps)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::ProgressStride;
    use std::time::Duration;

    /// Without a bar the calls end only at the outputs; with one the stride doubles on quick
    /// calls up to a hundredth of the run, halves on slow ones down to 16 steps, and ignores
    /// calls an output cut short.
    #[test]
    fn the_progress_stride_follows_the_wall_time_of_whole_calls() {
        let hidden = ProgressStride::new(true, 5500);
        assert_eq!(hidden.next_update(100), u64::MAX);

        let mut shown = ProgressStride::new(false, 5500);
        assert_eq!(shown.next_update(100), 116);
        let quick = Duration::from_millis(10);
        shown.adapt(true, quick);
        assert_eq!(shown.next_update(0), 32);
        shown.adapt(false, quick);
        assert_eq!(shown.next_update(0), 32, "a call cut short says nothing");
        shown.adapt(true, quick);
        assert_eq!(
            shown.next_update(0),
            55,
            "at most a hundredth of 5500 steps"
        );
        shown.adapt(true, Duration::from_millis(100));
        assert_eq!(shown.next_update(0), 55, "within 50-200 ms it stays");
        for _ in 0..5 {
            shown.adapt(true, Duration::from_millis(500));
        }
        assert_eq!(shown.next_update(0), 16, "never below 16 steps");
    }
}
