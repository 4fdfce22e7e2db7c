//! HDF5 output of the `am-sim` binary: the refusal to overwrite, restart bit for bit, frames
//! surviving `kill -9` and Ctrl-C. (The in-memory comparison lives in `output_readback.rs`:
//! HDF5 opens files without close-on-exec, so a file held open by this process would be
//! inherited, lock and all, by the runs the other tests here spawn.)
#![cfg(feature = "hdf5")]

mod common;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use am_sim::output::hdf5::read_last_frame;

fn am_sim(dir: &Path, args: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_am-sim"));
    command
        .current_dir(dir)
        .args(args)
        .args(["--quiet", "--threads", "2"]);
    command
}

/// Runs am-sim to completion and fails the test, with its stderr, if it did not succeed.
fn run_ok(dir: &Path, args: &[&str]) -> std::process::Output {
    let out = am_sim(dir, args).output().unwrap();
    assert!(
        out.status.success(),
        "am-sim {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Step of the last complete frame of `laser_track.h5` in `dir`.
fn last_step(dir: &Path) -> u64 {
    read_last_frame(&dir.join("laser_track.h5"))
        .unwrap()
        .state
        .step
}

#[test]
fn an_existing_output_file_is_refused_and_kept() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("track.toml"),
        common::short_track(2e-5, 100),
    )
    .unwrap();
    std::fs::write(dir.path().join("laser_track.h5"), "precious").unwrap();
    let out = am_sim(dir.path(), &["track.toml"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("already exists"));
    assert_eq!(
        std::fs::read_to_string(dir.path().join("laser_track.h5")).unwrap(),
        "precious"
    );
    run_ok(dir.path(), &["track.toml", "--overwrite"]);
    assert_eq!(last_step(dir.path()), 200);
}

/// Positions, velocities, enthalpies, the heat evaporated (as bits) and bonds of a file's last
/// frame.
fn fingerprint(path: &Path) -> (Vec<u64>, Vec<(u64, u64)>, u64) {
    let saved = read_last_frame(path).unwrap();
    let mut bits: Vec<u64> = saved
        .position
        .iter()
        .chain(&saved.velocity)
        .flat_map(|v| v.to_array())
        .map(f64::to_bits)
        .collect();
    let thermal = saved.state.thermal.as_ref().unwrap();
    bits.extend(
        thermal
            .enthalpy
            .iter()
            .chain(thermal.evaporated.iter().flatten())
            .map(|e| e.to_bits()),
    );
    let mut bonds = saved.state.bonded.clone();
    bonds.sort_unstable();
    (bits, bonds, saved.state.step)
}

/// Writes the scenes of a restart test into `dir`: `full.toml` (writing `full.h5`),
/// `half.toml` (`half.h5`, over half the time) and `continue.toml`, the full run writing on
/// into `half.h5`.
fn write_halves(dir: &Path, full: &str, half: &str) {
    std::fs::write(dir.join("full.toml"), full).unwrap();
    std::fs::write(dir.join("half.toml"), half).unwrap();
    let continued = full.replace("full.h5", "half.h5");
    std::fs::write(dir.join("continue.toml"), continued).unwrap();
}

#[test]
fn a_run_of_2t_equals_t_plus_a_restart_of_t_bit_for_bit() {
    // The laser switches on at 0.2 ms; the restart at 0.5 ms falls in the middle of the track,
    // with particles melting and bonding on both sides of it.
    let dir = tempfile::tempdir().unwrap();
    let full = common::short_track(1e-3, 500).replace("laser_track.h5", "full.h5");
    let half = common::short_track(5e-4, 500).replace("laser_track.h5", "half.h5");
    write_halves(dir.path(), &full, &half);
    run_ok(dir.path(), &["full.toml"]);
    run_ok(dir.path(), &["half.toml"]);
    let resumed = run_ok(dir.path(), &["continue.toml", "--restart", "half.h5"]);
    assert!(String::from_utf8_lossy(&resumed.stdout).contains("resuming at step 5000"));
    let (a, b) = (
        fingerprint(&dir.path().join("full.h5")),
        fingerprint(&dir.path().join("half.h5")),
    );
    assert_eq!(a.2, 10_000);
    assert!(
        !a.1.is_empty(),
        "bonds formed, so the restart carried bond states"
    );
    assert_eq!(a, b, "2T and T + restart T differ");
    // laser_track's particles boil (M.80) before the restart point: the restart carried the
    // heat their vapour had taken.
    let file = hdf5::File::open(dir.path().join("half.h5")).unwrap();
    let evaporated: Vec<f64> = file
        .dataset("series/evaporated_heat_j")
        .unwrap()
        .read_raw()
        .unwrap();
    // Row 10 is step 5000, where the second run resumed.
    assert!(
        evaporated[10] > 0.0 && evaporated[20] > evaporated[10],
        "nothing evaporated before or after the restart point: {evaporated:?}"
    );
    // Frames and series continue in the restarted file without gaps or duplicates.
    let file = hdf5::File::open(dir.path().join("half.h5")).unwrap();
    let steps: Vec<u64> = file.dataset("series/step").unwrap().read_raw().unwrap();
    assert_eq!(steps, (0..=20).map(|k| k * 500).collect::<Vec<_>>());
}

#[test]
fn a_run_with_friction_restarts_bit_for_bit() {
    // The column with friction: at 8 ms the bottom layer rests on the floor and ~40 pairs touch,
    // so the restart must carry angular velocities, torques and pair and wall histories.
    let dir = tempfile::tempdir().unwrap();
    let column = common::scene_text("column.toml").replace(
        "damping_ratio = 0.3 ",
        "friction_coefficient = 0.5\nrolling_friction_coefficient = 0.05\ndamping_ratio = 0.3 ",
    );
    let full = column
        .replace("duration_s = 0.1", "duration_s = 0.016")
        .replace("column.h5", "full.h5");
    let half = column
        .replace("duration_s = 0.1", "duration_s = 0.008")
        .replace("column.h5", "half.h5");
    write_halves(dir.path(), &full, &half);
    run_ok(dir.path(), &["full.toml"]);
    run_ok(dir.path(), &["half.toml"]);
    let halfway = read_last_frame(&dir.path().join("half.h5")).unwrap();
    let saved = halfway
        .state
        .rotation
        .as_ref()
        .expect("rotation restart data");
    assert!(
        saved.pair_ids.len() > 20 && saved.wall_history.iter().any(|h| h.length() > 0.0),
        "the restart must carry pair and wall histories: {} pairs",
        saved.pair_ids.len()
    );
    run_ok(dir.path(), &["continue.toml", "--restart", "half.h5"]);
    let bits = |name: &str| -> Vec<u64> {
        let saved = read_last_frame(&dir.path().join(name)).unwrap();
        let rotation = saved.state.rotation.unwrap();
        assert_eq!(saved.state.step, 3200);
        saved
            .position
            .iter()
            .chain(&saved.velocity)
            .chain(&rotation.angular_velocity)
            .chain(&rotation.pair_history)
            .flat_map(|v| v.to_array())
            .map(f64::to_bits)
            .collect()
    };
    assert!(
        bits("full.h5") == bits("half.h5"),
        "2T and T + restart T differ"
    );
    // The frames carry the angular velocity.
    let file = hdf5::File::open(dir.path().join("full.h5")).unwrap();
    let names = file.group("frames").unwrap().member_names().unwrap();
    let last = file
        .dataset(&format!(
            "frames/{}/angular_velocity",
            names.last().unwrap()
        ))
        .unwrap();
    assert_eq!(last.shape(), vec![2000, 3]);
}

/// A bed that only conducts restarts bit for bit, and its restart data hold no laser or
/// boundary arrays (the scene has neither source, so the run keeps none). The packed cube of the
/// conducting column, its upper half at 1000 K over the lower at 300 K, 400 steps against 200 and
/// 200 more resumed: heat flows through the contacts across the restart.
#[test]
fn a_bed_that_only_conducts_restarts_bit_for_bit_without_laser_or_boundary_arrays() {
    let dir = tempfile::tempdir().unwrap();
    let cube = common::conducting::packed_cube("2e-3").replace(
        "\n[output]",
        "\n[[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 0.01]\n\
         max_corner_m = [inf, inf, inf]\ntemperature_k = 1000\n[output]",
    );
    let full = cube.replace("column.h5", "full.h5");
    let half = cube
        .replace("duration_s = 2e-3", "duration_s = 1e-3")
        .replace("column.h5", "half.h5");
    assert!(half != cube.replace("column.h5", "half.h5"), "the duration");
    write_halves(dir.path(), &full, &half);
    run_ok(dir.path(), &["full.toml"]);
    run_ok(dir.path(), &["half.toml"]);
    run_ok(dir.path(), &["continue.toml", "--restart", "half.h5"]);
    let (a, b) = (
        fingerprint(&dir.path().join("full.h5")),
        fingerprint(&dir.path().join("half.h5")),
    );
    assert_eq!(a.2, 400);
    assert_eq!(a, b, "2T and T + restart T differ");
    let file = hdf5::File::open(dir.path().join("half.h5")).unwrap();
    let frames = file.group("frames").unwrap().member_names().unwrap();
    let enthalpy = |frame: &str| -> Vec<f64> {
        let path = format!("frames/{frame}/restart/enthalpy");
        file.dataset(&path).unwrap().read_raw().unwrap()
    };
    let (first, last) = (frames.first().unwrap(), frames.last().unwrap());
    assert!(enthalpy(first) != enthalpy(last), "heat flowed");
    for frame in &frames {
        let restart = file.group(&format!("frames/{frame}/restart")).unwrap();
        assert!(restart.link_exists("enthalpy"), "{frame}");
        for absent in ["laser_power", "laser_energy", "boundary_energy"] {
            assert!(!restart.link_exists(absent), "{frame}: {absent}");
        }
    }
}

/// The long run of the interruption tests: frames every 200 steps, series rows every 50 (in
/// `/series` and in `series.csv`), so that a killed run leaves rows after its last frame.
fn long_track() -> String {
    common::short_track(3.5e-3, 200).replace(
        "[output]",
        "[output]\nseries_csv = \"series.csv\"\nseries_every_steps = 50",
    )
}

/// Starts a long run and waits until its XDMF file lists at least `frames` frames.
fn start_and_wait(dir: &Path, frames: usize) -> Child {
    std::fs::write(dir.join("long.toml"), long_track()).unwrap();
    let child = am_sim(dir, &["long.toml"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = child;
    let start = Instant::now();
    loop {
        let xmf = std::fs::read_to_string(dir.join("laser_track.xmf")).unwrap_or_default();
        if xmf.matches("<Grid Name=\"particles_").count() >= frames {
            return child;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("no frames appeared");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn frames_survive_kill_9_and_the_run_can_continue() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = start_and_wait(dir.path(), 3);
    child.kill().unwrap(); // SIGKILL: no chance to close the file
    child.wait().unwrap();
    let saved = read_last_frame(&dir.path().join("laser_track.h5")).unwrap();
    assert!(
        saved.frame >= 2 && saved.state.step >= 400,
        "frame {} step {}",
        saved.frame,
        saved.state.step
    );
    assert!(saved.position.iter().all(|x| x.is_finite()));
    // The killed run continues from its last complete frame.
    std::fs::write(
        dir.path().join("more.toml"),
        extended(saved.state.step + 400),
    )
    .unwrap();
    run_ok(dir.path(), &["more.toml", "--restart", "laser_track.h5"]);
    assert_eq!(last_step(dir.path()), saved.state.step + 400);
    // Rows written after the last frame by the killed run were dropped: every step once, in
    // order, the same in /series and in the CSV.
    let expected: Vec<u64> = (0..=(saved.state.step + 400) / 50)
        .map(|k| k * 50)
        .collect();
    let file = hdf5::File::open(dir.path().join("laser_track.h5")).unwrap();
    let series: Vec<u64> = file.dataset("series/step").unwrap().read_raw().unwrap();
    assert_eq!(series, expected);
    let csv = std::fs::read_to_string(dir.path().join("series.csv")).unwrap();
    let rows: Vec<u64> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(rows, expected);
}

/// The long run's scene, ending at `step` (to continue a stopped run a little further).
fn extended(step: u64) -> String {
    let scene = long_track();
    assert!(scene.contains("duration_s = 3.5e-3"));
    #[allow(clippy::cast_precision_loss)]
    let duration = step as f64 * 1e-7;
    scene.replace("duration_s = 3.5e-3", &format!("duration_s = {duration:e}"))
}

#[test]
fn ctrl_c_writes_a_last_frame_and_closes_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let child = start_and_wait(dir.path(), 2);
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("interrupted at step"), "{stdout}");
    let saved = read_last_frame(&dir.path().join("laser_track.h5")).unwrap();
    let step: u64 = stdout
        .split("interrupted at step ")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(
        saved.state.step, step,
        "the interrupted step is the last frame"
    );
    // The file was closed cleanly: the run continues from it.
    std::fs::write(dir.path().join("more.toml"), extended(step + 400)).unwrap();
    run_ok(dir.path(), &["more.toml", "--restart", "laser_track.h5"]);
    assert_eq!(last_step(dir.path()), step + 400);
}
