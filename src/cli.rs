//! The `am-sim` command line: `am-sim scene.toml` runs a scene, `am-sim check scene.toml`
//! validates it and prints derived quantities. Only I/O and error printing live here.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::check;
use crate::model::Model;
use crate::output::SeriesWriter;
use crate::scene::Scene;
use crate::simulation::{Diagnostics, Simulation};

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
}

#[derive(Debug, Args)]
struct RunArgs {
    /// Scene file (TOML).
    scene: Option<PathBuf>,
    /// Worker threads (default: all cores). Results are bitwise the same for any count.
    #[arg(long)]
    threads: Option<usize>,
    /// Replace existing output files instead of refusing to start.
    #[arg(long)]
    overwrite: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

/// Entry point of the binary.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Check { scene }) => run_check(&scene),
        Some(Command::Run(args)) => run(&args),
        None if cli.run.scene.is_some() => run(&cli.run),
        None => Err(
            "no scene given: usage `am-sim SCENE.toml` or `am-sim check SCENE.toml` (see --help)"
                .into(),
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn load(path: &Path) -> Result<Simulation, String> {
    let scene = Scene::load(path).map_err(|e| e.to_string())?;
    let (model, particles) = Model::build(&scene);
    Ok(Simulation::new(model, particles))
}

fn run_check(path: &Path) -> Result<(), String> {
    let sim = load(path)?;
    let report = check::report(&sim);
    say!("{}", report.to_string().trim_end());
    Ok(())
}

fn run(args: &RunArgs) -> Result<(), String> {
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
    // Set-up (neighbour list, first forces) already runs on the requested threads.
    let mut sim = pool.install(|| load(path))?;
    // Output files are opened last, after every check that can refuse the run.
    let series_path = sim.model.output.series_csv.clone();
    let mut series = match &series_path {
        Some(file) => Some(
            SeriesWriter::create(file, args.overwrite, sim.thermal.is_some())
                .map_err(|e| e.to_string())?,
        ),
        None => None,
    };

    let model = &sim.model;
    let report = check::report(&sim);
    let title = if model.title.is_empty() {
        String::new()
    } else {
        format!("{} — ", model.title)
    };
    say!(
        "am-sim {}: {title}{} particles, {} steps of dt = {:.3e} s ({:.4e} s), {threads} threads",
        env!("CARGO_PKG_VERSION"),
        sim.particles.len(),
        model.steps,
        model.dt,
        model.dt * model.steps as f64,
    );
    for w in &report.warnings {
        say!("warning: {w}");
    }

    let (initial, wall) = pool.install(|| run_loop(&mut sim, series.as_mut(), args.quiet))?;
    print_summary(&sim, &initial, wall, threads);
    if let Some(file) = &series_path {
        say!("time series written to {}", file.display());
    }
    Ok(())
}

/// Steps the simulation to the end, writing the series; stops on a non-finite value before
/// anything invalid is written. Returns the initial diagnostics and the wall time [s].
fn run_loop(
    sim: &mut Simulation,
    mut series: Option<&mut SeriesWriter>,
    quiet: bool,
) -> Result<(Diagnostics, f64), String> {
    let start = Instant::now();
    let initial = sim.diagnostics();
    if let Some(s) = series.as_deref_mut() {
        s.write(&initial, 0.0).map_err(|e| e.to_string())?;
    }
    let (steps, every) = (sim.model.steps, sim.model.output.every_steps);
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
    let bar_stride = (steps / 1000).max(1);
    for _ in 0..steps {
        sim.step();
        if sim.step % every == 0 || sim.step == steps {
            if let Some((id, field)) = sim.first_non_finite() {
                bar.abandon();
                return Err(format!(
                    "step {} (t = {:.6e} s): particle id {id} has a non-finite {field}; the run is stopped and nothing invalid was written (check dt with `am-sim check`)",
                    sim.step, sim.time
                ));
            }
            if let Some(s) = series.as_deref_mut() {
                s.write(&sim.diagnostics(), start.elapsed().as_secs_f64())
                    .map_err(|e| e.to_string())?;
            }
        }
        if sim.step % bar_stride == 0 {
            bar.set_position(sim.step);
            bar.set_message(format!("{:.4e} s", sim.time));
        }
    }
    bar.finish_and_clear();
    Ok((initial, start.elapsed().as_secs_f64()))
}

#[allow(clippy::cast_precision_loss)]
fn print_summary(sim: &Simulation, initial: &Diagnostics, wall: f64, threads: usize) {
    let d = sim.diagnostics();
    let particle_steps = sim.particles.len() as f64 * d.step as f64;
    say!(
        "done: {} steps, simulated {:.4e} s in {:.3} s wall time ({threads} threads)",
        d.step,
        d.time,
        wall
    );
    say!(
        "  speed: {:.3e} particle-steps/s ({:.3e} per thread)",
        particle_steps / wall.max(1e-9),
        particle_steps / wall.max(1e-9) / threads as f64
    );
    say!(
        "  contacts: {} particle-particle, {} particle-wall; bonds: {}; neighbour-list builds: {}",
        d.contacts,
        d.wall_contacts,
        d.bonds,
        d.neighbor_builds
    );
    let e0 = initial.mechanical_energy();
    let e1 = d.mechanical_energy();
    let scale = initial
        .kinetic_energy
        .abs()
        .max(e0.abs())
        .max(f64::MIN_POSITIVE);
    say!(
        "  energy: mechanical {e0:.6e} J → {e1:.6e} J (change {:+.3e} relative; damping and bond formation lower it, a rise means dt is too large)",
        (e1 - e0) / scale
    );
    say!(
        "  largest overlap now: {:.4e} m ({:.3} % of the smaller radius); kinetic energy {:.4e} J",
        d.max_overlap,
        100.0 * d.max_overlap_ratio,
        d.kinetic_energy
    );
    if let (Some(t0), Some(t1)) = (initial.thermal, d.thermal) {
        let stored = t1.enthalpy - t0.enthalpy;
        let supplied = t1.laser_energy + t1.boundary_energy;
        let scale = t1
            .laser_energy
            .abs()
            .max(t1.boundary_energy.abs())
            .max(t0.enthalpy.abs() * f64::EPSILON);
        say!(
            "  thermal: max temperature {:.1} K, {} particles melted; laser absorbed {:.4e} J, boundaries {:+.4e} J",
            t1.max_temperature,
            t1.melted,
            t1.laser_energy,
            t1.boundary_energy
        );
        say!(
            "  heat balance: stored {stored:+.6e} J vs supplied {supplied:+.6e} J (residual {:.2e} relative)",
            (stored - supplied).abs() / scale
        );
    }
}
