//! The `am-sim` binary as a user runs it: run, check, refusal to overwrite, bad input.

mod common;

use std::path::Path;

use common::{am_sim, am_sim_failing, assert_contains_all, text};

fn scene(name: &str) -> String {
    format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn run_writes_the_series_and_reports_the_bond() {
    let dir = tempfile::tempdir().unwrap();
    let out = am_sim(
        dir.path(),
        &[&scene("paper_5_1_bond.toml"), "--threads", "1"],
    );
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    assert_contains_all(
        &stdout,
        &[
            "10000 steps",
            // The thread count in words, singular for one.
            ", 1 thread, contact kernel",
            "wall time (1 thread)",
            "particle-steps/s",
            "bonds: 1",
            "wall time",
            "energy: mechanical",
        ],
    );
    let csv = std::fs::read_to_string(dir.path().join("paper_5_1_bond.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        am_sim::output::SERIES_COLUMNS.map(|c| c.name).join(",")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 1001, "t = 0 and every 10 steps of 10000");
    let last = rows.last().unwrap();
    assert_eq!(last[0], "10000");
    assert_eq!(last[8], "1", "one bond at the end");
    let overlap: f64 = last[9].parse().unwrap();
    assert!(
        (overlap / 5e-5 - 1.0).abs() < 5e-3,
        "final overlap {overlap}"
    );
}

#[test]
fn an_existing_output_is_never_overwritten_silently() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("paper_5_1_bond.csv");
    std::fs::write(&file, "precious results\n").unwrap();
    let stderr = am_sim_failing(dir.path(), &[&scene("paper_5_1_bond.toml")]);
    assert!(
        stderr.contains("already exists") && stderr.contains("--overwrite"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(&file).unwrap(),
        "precious results\n"
    );
    let again = am_sim(
        dir.path(),
        &[&scene("paper_5_1_bond.toml"), "--overwrite", "--quiet"],
    );
    assert!(again.status.success(), "{}", text(&again.stderr));
    assert!(
        std::fs::read_to_string(&file)
            .unwrap()
            .starts_with("step,time_s")
    );
}

/// A run refused because its CSV exists makes no other file: the HDF5 file and its XDMF
/// companion are not created (they were, empty, before the CSV's name was checked first).
#[test]
fn a_run_refused_for_its_csv_leaves_no_new_hdf5_file() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("laser_track.csv");
    std::fs::write(&csv, "precious results\n").unwrap();
    let stderr = am_sim_failing(dir.path(), &[&scene("laser_track.toml")]);
    assert!(
        stderr.contains("laser_track.csv already exists"),
        "{stderr}"
    );
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["laser_track.csv"]);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "precious results\n");
}

#[test]
fn check_prints_the_derived_bond_quantities_and_runs_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = am_sim(dir.path(), &["check", &scene("paper_5_1_bond.toml")]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_contains_all(
        &stdout,
        &[
            "v_crit = 2.5744 m/s",
            "δ_eq = 5.0000e-5 m",
            "δ_crit = 2.2222e-5 m",
            "Rayleigh time",
            "Hertz contact time",
            "time step: OK",
        ],
    );
    assert!(
        !dir.path().join("paper_5_1_bond.csv").exists(),
        "check must not write output"
    );
}

#[test]
fn check_warns_when_dt_cannot_resolve_a_contact() {
    let dir = tempfile::tempdir().unwrap();
    let coarse = std::fs::read_to_string(scene("paper_5_1_bond.toml"))
        .unwrap()
        .replace("dt_s = 5e-7", "dt_s = 5e-6");
    std::fs::write(dir.path().join("coarse.toml"), coarse).unwrap();
    let stdout = text(&am_sim(dir.path(), &["check", "coarse.toml"]).stdout);
    assert!(
        stdout.contains("warning:")
            && stdout.contains("Hertz contact time")
            && stdout.contains("5.1 steps"),
        "{stdout}"
    );
    assert!(stdout.contains("recommended dt ≤ 5.071e-7 s"), "{stdout}");
}

#[test]
fn a_bad_scene_fails_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let bad = std::fs::read_to_string(scene("paper_5_1_bond.toml"))
        .unwrap()
        .replace("radius_m = 0.001", "radius_m = -0.001");
    std::fs::write(dir.path().join("bad.toml"), bad).unwrap();
    let stderr = am_sim_failing(dir.path(), &["bad.toml"]);
    assert!(
        stderr.contains("bad.toml")
            && stderr.contains("particles[0].radius_m = -0.001: must be > 0"),
        "{stderr}"
    );
    assert!(!dir.path().join("paper_5_1_bond.csv").exists());
}

#[test]
fn usage_errors_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    let none = am_sim(dir.path(), &[]);
    assert!(!none.status.success() && text(&none.stderr).contains("no scene given"));
    let zero = am_sim(
        dir.path(),
        &[&scene("paper_5_1_bond.toml"), "--threads", "0"],
    );
    assert!(!zero.status.success() && text(&zero.stderr).contains("--threads 0"));
    assert!(
        !dir.path().join("paper_5_1_bond.csv").exists(),
        "refused before opening the output"
    );
}

/// Every value of every row of a series CSV, parsed.
fn csv_values(path: &Path) -> Vec<f64> {
    let csv = std::fs::read_to_string(path).unwrap();
    csv.lines()
        .skip(1)
        .flat_map(|line| line.split(',').map(|v| v.parse::<f64>().unwrap()))
        .collect()
}

#[test]
fn a_dt_beyond_the_stability_limit_is_refused_and_a_forced_run_is_stopped_by_a_guard() {
    let dir = tempfile::tempdir().unwrap();
    // Example 5.1 at dt = 4e-5 s, 3.2 × its stability limit (1.26e-5 s, `am-sim check`).
    let fast = std::fs::read_to_string(scene("paper_5_1_bond.toml"))
        .unwrap()
        .replace("dt_s = 5e-7", "dt_s = 4e-5");
    std::fs::write(dir.path().join("fast.toml"), fast).unwrap();
    let stderr = am_sim_failing(dir.path(), &["fast.toml", "-q"]);
    assert!(
        stderr.contains("simulation.dt_s = 4.000e-5 s is beyond the stability limit 1.258e-5 s")
            && stderr.contains("--force"),
        "{stderr}"
    );
    assert!(
        !dir.path().join("paper_5_1_bond.h5").exists(),
        "refused runs write nothing"
    );

    let stderr = am_sim_failing(dir.path(), &["fast.toml", "-q", "--force"]);
    assert_contains_all(
        &stderr,
        &[
            "step 10 ",
            "particle id 1",
            "energy blow-up",
            "the run is stopped",
        ],
    );
    let values = csv_values(&dir.path().join("paper_5_1_bond.csv"));
    assert!(!values.is_empty() && values.iter().all(|v| v.is_finite()));
}

#[test]
fn an_overlap_beyond_the_guard_stops_at_once_naming_both_particles() {
    let dir = tempfile::tempdir().unwrap();
    // Two 1 mm spheres overlapping by 35 % of the radius (the default guard is 30 %).
    let scene_text = r#"
[scene]
version = 1
[simulation]
dt_s = 1e-8
duration_s = 1e-6
[materials.m]
density_kg_m3 = 2000
youngs_modulus_pa = 1e9
poisson_ratio = 0.0
[contact]
model = "hertz"
damping_ratio = 0.0
[[particles]]
position_m = [0.0, 0.0, 0.0]
radius_m = 1e-3
material = "m"
[[particles]]
position_m = [1.65e-3, 0.0, 0.0]
radius_m = 1e-3
material = "m"
[output]
series_csv = "overlap.csv"
"#;
    std::fs::write(dir.path().join("overlap.toml"), scene_text).unwrap();
    let stderr = am_sim_failing(dir.path(), &["overlap.toml", "-q"]);
    assert_contains_all(
        &stderr,
        &[
            "step 0 ",
            "particle ids 0, 1",
            "an overlap of 0.350 × the radius",
            "guards.max_overlap_ratio = 0.3",
        ],
    );
    // Raising the guard lets the same scene run: the spheres push apart.
    std::fs::write(
        dir.path().join("overlap.toml"),
        format!("{scene_text}[guards]\nmax_overlap_ratio = 0.4\n"),
    )
    .unwrap();
    let out = am_sim(dir.path(), &["overlap.toml", "-q", "--overwrite"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let values = csv_values(&dir.path().join("overlap.csv"));
    assert!(values.iter().all(|v| v.is_finite()));
}

/// `--simd` caps the contact kernel's instruction set: the header names the build that ran, the
/// series is bitwise that of the default build (every build gives bitwise the same), and a name
/// that is no build is refused before anything is written.
#[test]
fn simd_caps_the_kernel_without_changing_a_bit_of_the_results() {
    let text_of_scene = short_friction_pile();
    let (default_stdout, default_series) = run_short_pile(&["--quiet"]);
    let (baseline_stdout, baseline_series) = run_short_pile(&["--quiet", "--simd", "baseline"]);
    assert!(
        baseline_stdout.contains("contact kernel baseline"),
        "{baseline_stdout}"
    );
    assert!(
        default_stdout.contains("contact kernel "),
        "{default_stdout}"
    );
    assert!(default_series.lines().count() > 20, "{default_series}");
    assert_eq!(
        without_wall_time(&baseline_series),
        without_wall_time(&default_series)
    );

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("pile.toml"), &text_of_scene).unwrap();
    let bad = am_sim(dir.path(), &["pile.toml", "--simd", "avx1024"]);
    assert!(!bad.status.success());
    assert!(
        text(&bad.stderr).contains("avx1024"),
        "{}",
        text(&bad.stderr)
    );
    assert!(!dir.path().join("friction_pile.csv").exists());
}

/// The friction pile's first 0.01 s (2000 steps, a row of the series every 100): frictional
/// pair contacts by the hundred, and the plate's.
fn short_friction_pile() -> String {
    std::fs::read_to_string(scene("friction_pile.toml"))
        .unwrap()
        .replace("duration_s = 0.4", "duration_s = 0.01")
        .replace("every_steps = 2000", "every_steps = 100")
}

/// The short friction pile run at 2 threads with `extra` arguments, in a folder of its own:
/// its stdout and its series (`friction_pile.csv`), once the run succeeded.
fn run_short_pile(extra: &[&str]) -> (String, String) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("pile.toml"), short_friction_pile()).unwrap();
    let mut args = vec!["pile.toml", "--threads", "2"];
    args.extend_from_slice(extra);
    let out = am_sim(dir.path(), &args);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let series = std::fs::read_to_string(dir.path().join("friction_pile.csv")).unwrap();
    (text(&out.stdout), series)
}

/// The rows of a series (CSV) without the wall time, which no two runs share.
fn without_wall_time(series: &str) -> Vec<Vec<String>> {
    let wall_time = am_sim::output::SERIES_COLUMNS
        .iter()
        .position(|c| c.name == "wall_time_s")
        .expect("a wall time column");
    series
        .lines()
        .map(|line| {
            line.split(',')
                .enumerate()
                .filter(|(i, _)| *i != wall_time)
                .map(|(_, v)| v.to_owned())
                .collect()
        })
        .collect()
}

/// `--prefetch on` asks the cache for lines ahead of the contacts on a bed too small for `auto`
/// to: the header says so, and the series is bitwise that of `--prefetch off` (a prefetch
/// changes no value). An unknown mode is refused before anything is written.
#[test]
fn prefetching_changes_no_bit_of_the_results() {
    // The plate's contacts are the particle pass's listed particles.
    let text_of_scene = short_friction_pile();
    let run = |mode: &str| {
        let (stdout, series) = run_short_pile(&["--prefetch", mode]);
        (stdout, without_wall_time(&series))
    };
    let (on_stdout, on_series) = run("on");
    let (off_stdout, off_series) = run("off");
    assert!(on_stdout.contains(", prefetching"), "{on_stdout}");
    assert!(!off_stdout.contains("prefetching"), "{off_stdout}");
    assert!(on_series.len() > 20, "{on_series:?}");
    assert_eq!(on_series, off_series);

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("pile.toml"), &text_of_scene).unwrap();
    let bad = am_sim(dir.path(), &["pile.toml", "--prefetch", "sometimes"]);
    assert!(!bad.status.success());
    assert!(
        text(&bad.stderr).contains("sometimes"),
        "{}",
        text(&bad.stderr)
    );
    assert!(!dir.path().join("friction_pile.csv").exists());
}

/// `--team-times` prints, after the summary, a line per pass of the thread team with the
/// call's time, when its last thread was done and each thread's part, and changes no value of
/// the run.
#[test]
fn team_times_name_the_passes_and_change_no_bit_of_the_results() {
    let run = |extra: &[&str]| {
        let (stdout, series) = run_short_pile(extra);
        (stdout, without_wall_time(&series))
    };
    let (timed_stdout, timed_series) = run(&["--team-times"]);
    let (plain_stdout, plain_series) = run(&[]);
    let table = timed_stdout
        .split_once("team passes")
        .unwrap_or_else(|| panic!("no table of the team's passes: {timed_stdout}"))
        .1;
    for pass in [
        "pair pass, even slabs: ",
        "opening pass (kicks, drift): ",
        "particle pass (walls): ",
        "diagnostics: ",
    ] {
        let line = table
            .lines()
            .find(|l| l.trim_start().starts_with(pass))
            .unwrap_or_else(|| panic!("no line for {pass}: {table}"));
        assert!(
            line.contains(" calls, ")
                && line.contains(" µs (last done ")
                && line.contains(" | 0: "),
            "{line}"
        );
    }
    assert!(!plain_stdout.contains("team passes"), "{plain_stdout}");
    assert!(timed_series.len() > 20, "{timed_series:?}");
    assert_eq!(timed_series, plain_series);
}

/// The thermal example of docs/scene-format.md (`spot.toml`), as the page gives it.
fn spot_scene_of_the_docs() -> String {
    let page = std::fs::read_to_string(format!(
        "{}/docs/scene-format.md",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    page.split("```toml\n")
        .skip(1)
        .map(|block| block.split("```").next().unwrap_or_default())
        .find(|block| block.contains("series_csv = \"spot.csv\""))
        .expect("the spot.toml example in docs/scene-format.md")
        .to_string()
}

#[test]
fn the_summary_gives_the_highest_temperature_now_and_at_the_output_steps() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("spot.toml"), spot_scene_of_the_docs()).unwrap();
    let out = am_sim(dir.path(), &["spot.toml", "--threads", "2", "-q"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    let line = stdout
        .lines()
        .find(|l| l.contains("thermal: max temperature"))
        .expect("the thermal line");
    let (now, peak) = (
        common::number_after(line, "max temperature "),
        common::number_after(line, "K now, "),
    );
    // The highest of the series column is the peak the summary gives (to its 0.1 K print).
    let series = std::fs::read_to_string(dir.path().join("spot.csv")).unwrap();
    let header: Vec<&str> = series.lines().next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|h| *h == "max_temperature_k")
        .unwrap();
    let highest = series
        .lines()
        .skip(1)
        .map(|row| row.split(',').nth(column).unwrap().parse::<f64>().unwrap())
        .fold(f64::NEG_INFINITY, f64::max);
    assert!((peak - highest).abs() <= 0.05, "{line}: series {highest}");
    // The spot's hottest particle cools after the second track (2599.8 K at most, 2585.9 K at
    // the end): a summary that gave only the last state would hide the peak.
    assert!(peak > now + 1.0, "{line}");
}
