//! Bed generation through the `am-sim` binary: `[[import]]` paths resolve from the scene file's
//! folder, `[deposition]` settles the bed before the run and the run's clock starts on the
//! settled bed, and an unsettled bed stops the run with an error.

mod common;

use std::path::Path;

use common::{am_sim, am_sim_failing, assert_contains_all, text};

/// 40 spheres: 10 from `spheres.csv` resting in the lower part of a 5 × 5 d box, 30 inserted
/// above them; they settle on the plate, then 100 steps run with a series row every 10.
fn scene(max_duration_s: f64) -> String {
    format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 1e-7
duration_s = 1e-5
gravity_m_s2 = [0.0, 0.0, -9.81]
[materials.steel]
density_kg_m3 = 7950
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
[contact]
model = "hertz"
damping_ratio = 0.5
[[import]]
file = "data/spheres.csv"
format = "csv"
material = "steel"
[[insert]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [1.5e-4, 1.5e-4, 2e-4]
count = 30
seed = 3
material = "steel"
[insert.size]
distribution = "constant"
diameter_m = 3e-5
[deposition]
max_duration_s = {max_duration_s}
damping_time_s = 3e-3
[output]
series_csv = "series.csv"
series_every_steps = 10
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "steel"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
material = "steel"
[[walls]]
point_m = [1.5e-4, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
material = "steel"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "steel"
[[walls]]
point_m = [0.0, 1.5e-4, 0.0]
normal = [0.0, -1.0, 0.0]
material = "steel"
"#
    )
}

/// Writes the scene and its CSV into `scenes/` (the CSV under `scenes/data/`) below `root`.
fn write_scene(root: &Path, max_duration_s: f64) -> String {
    let scenes = root.join("scenes");
    std::fs::create_dir_all(scenes.join("data")).unwrap();
    let mut csv = String::from("x_m,y_m,z_m,radius_m\n");
    for k in 0..10 {
        let (i, j) = (f64::from(k % 5), f64::from(k / 5));
        csv += &format!("{},{},2e-5,1.5e-5\n", 1.5e-5 + 3e-5 * i, 1.5e-5 + 3e-5 * j);
    }
    std::fs::write(scenes.join("data/spheres.csv"), csv).unwrap();
    let path = scenes.join("deposit.toml");
    std::fs::write(&path, scene(max_duration_s)).unwrap();
    path.to_string_lossy().into_owned()
}

#[test]
fn the_run_starts_on_the_settled_bed() {
    let root = tempfile::tempdir().unwrap();
    let path = write_scene(root.path(), 0.1);
    // Run from another folder: the import resolves from the scene's, the output from the cwd.
    let cwd = tempfile::tempdir().unwrap();
    let out = am_sim(cwd.path(), &[&path, "--threads", "1", "-q"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    assert!(stdout.contains("40 particles"), "{stdout}");
    assert!(
        stdout.contains("settled; the run starts now (t = 0)"),
        "{stdout}"
    );
    assert!(stdout.contains("done: 100 steps"), "{stdout}");
    // The deposition reports its run time and its own error indicators, as a run does: its
    // energy balance closes to its first-order damper error (a few per cent at most here, as in
    // tests/bed_deposition.rs), the background damping's share booked as lost.
    let deposition = stdout
        .lines()
        .find(|l| l.starts_with("deposition: "))
        .expect("a deposition line");
    assert!(deposition.contains(" s wall time ("), "{deposition}");
    let indicators = stdout
        .lines()
        .find(|l| l.contains("deposition's error indicators"))
        .expect("the deposition's error indicators");
    let residual = common::number_after(indicators, "energy balance residual ");
    assert!(residual.abs() < 0.05, "{indicators}");
    let series = std::fs::read_to_string(cwd.path().join("series.csv")).unwrap();
    let rows: Vec<Vec<f64>> = series
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|c| c.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let header: Vec<&str> = series.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (step, time, kinetic) = (column("step"), column("time_s"), column("kinetic_energy_j"));
    // Rows at steps 0, 10, …, 100 of the run proper: the deposition's steps are not counted.
    assert_eq!(rows.len(), 11);
    assert_eq!((rows[0][step], rows[0][time]), (0.0, 0.0));
    assert_eq!(rows[10][step], 100.0);
    // Settled: E_kin per particle ≤ 1e-4 m g d (M.75) with m = ρ π d³/6, d = 30 µm.
    let m = 7950.0 * std::f64::consts::PI / 6.0 * 3e-5_f64.powi(3);
    assert!(
        rows[0][kinetic] / 40.0 <= 1e-4 * m * 9.81 * 3e-5,
        "{}",
        rows[0][kinetic]
    );
}

/// `--team-times` reports the deposition's passes after its line and the run's after the
/// summary, each stage's own: the run's opening pass is called once per step of the run (100),
/// the deposition's once per step of its own.
#[test]
fn team_times_report_the_deposition_and_the_run_apart() {
    let root = tempfile::tempdir().unwrap();
    let path = write_scene(root.path(), 0.1);
    let cwd = tempfile::tempdir().unwrap();
    let out = am_sim(cwd.path(), &[&path, "--threads", "2", "-q", "--team-times"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    let deposition_steps = common::number_after(
        stdout
            .lines()
            .find(|l| l.starts_with("deposition: "))
            .expect("a deposition line"),
        "deposition: ",
    );
    let (deposition, run) = stdout
        .split_once("  team passes (")
        .unwrap_or_else(|| panic!("no table of the run's passes: {stdout}"));
    let (_, deposition) = deposition
        .split_once("  deposition's team passes (")
        .unwrap_or_else(|| panic!("no table of the deposition's passes: {stdout}"));
    assert!(
        !run.contains("\ndone: ") && deposition.contains("\ndone: "),
        "the run's table follows its summary: {stdout}"
    );
    let calls_of_opening = |table: &str| {
        let line = table
            .lines()
            .find(|l| l.trim_start().starts_with("opening pass (kicks, drift): "))
            .unwrap_or_else(|| panic!("no opening pass in {table}"));
        common::number_after(line, "opening pass (kicks, drift): ")
    };
    assert_eq!(calls_of_opening(run), 100.0);
    assert_eq!(calls_of_opening(deposition), deposition_steps);
}

#[test]
fn a_bed_that_does_not_settle_in_time_stops_the_run() {
    let root = tempfile::tempdir().unwrap();
    // 1 ms: the inserted spheres are still falling (free fall over 0.2 mm takes 6 ms).
    let path = write_scene(root.path(), 1e-3);
    let stderr = am_sim_failing(root.path(), &[&path, "--threads", "1", "-q"]);
    assert!(
        stderr.contains("deposition: 10000 steps")
            && stderr.contains("not settled within deposition.max_duration_s"),
        "{stderr}"
    );
}

#[test]
fn an_energy_blow_up_stops_the_deposition_at_its_next_check() {
    let root = tempfile::tempdir().unwrap();
    let path = write_scene(root.path(), 0.1);
    // dt = 1.2 µs is 1.5 × the stability limit of this bed (7.9e-7 s, `am-sim check`): too
    // little for an overlap beyond the guard's 30 % soon (that first comes at step 6335), enough
    // to create energy. With the guard at 0.1 of the energy scale, the first check, at step
    // 1000, finds about twice that (0.22).
    let scene = std::fs::read_to_string(&path)
        .unwrap()
        .replace("dt_s = 1e-7", "dt_s = 1.2e-6")
        + "[guards]\nmax_energy_residual = 0.1\n";
    std::fs::write(&path, scene).unwrap();
    let stderr = am_sim_failing(root.path(), &[&path, "--threads", "1", "-q", "--force"]);
    assert_contains_all(
        &stderr,
        &[
            "deposition: step 1000 ",
            "an energy blow-up",
            "guards.max_energy_residual = 0.1",
        ],
    );
}
