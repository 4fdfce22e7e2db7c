//! Cost of writing one HDF5 frame of a 100k-particle bed (all fields, restart data, XDMF
//! rewrite, flush) against the cost of one step of the same bed, so the share of output in a run
//! is `write / (steps between frames × step)`. Run: `cargo bench --bench output`.
//!
//! Plain medians rather than criterion: each frame adds ~15 MB to the file, and criterion's
//! thousands of iterations would fill the disk.

use std::time::Instant;

use am_sim::model::Model;
use am_sim::output::{SeriesLayout, frame, hdf5::OutputFile};
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;

/// 47 × 47 × 46 = 101,614 spheres of 316L (r = 15 µm) on a plate, with heat conduction.
fn bed(file: &str) -> Simulation {
    let text = format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 1e-7
duration_s = 1e-3
gravity_m_s2 = [0.0, 0.0, -9.81]
[materials.ss316l]
density_kg_m3 = 7950
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
specific_heat_j_kg_k = 500
thermal_conductivity_w_m_k = 18
melting_point_k = 1700
[contact]
model = "hertz"
damping_ratio = 0.5
[bond]
adhesion_exponent = 1.0
equilibrium_overlap_m = 2e-7
damping_ratio = 1.0
criterion = "melting"
[thermal]
initial_temperature_k = 300
conduction = "batchelor_obrien"
[[lattice]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [1.41e-3, 1.41e-3, 1.38e-3]
radius_m = 1.5e-5
spacing_m = 2.99e-5
material = "ss316l"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "ss316l"
[output]
file = "{file}"
"#
    );
    let scene = Scene::from_toml(&text).expect("valid");
    let (model, particles) = Model::build(&scene);
    Simulation::new(model, particles)
}

fn median(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

fn main() {
    let dir = tempfile::tempdir().expect("scratch dir");
    let path = dir.path().join("bench.h5");
    let mut sim = bed(&path.display().to_string());
    // Settle a little so that contacts (and their conductances) exist.
    for _ in 0..200 {
        sim.step();
    }
    let d = sim.diagnostics();
    println!(
        "bed: {} particles, {} contacts",
        sim.particles.len(),
        d.contacts + d.wall_contacts
    );
    let steps: Vec<f64> = (0..15)
        .map(|_| {
            let start = Instant::now();
            sim.step();
            start.elapsed().as_secs_f64()
        })
        .collect();
    let mut file =
        OutputFile::create(&path, true, "bench", SeriesLayout::of(&sim), 0).expect("file");
    let fields = sim.model.output.fields.clone();
    let writes: Vec<f64> = (0..15)
        .map(|_| {
            let start = Instant::now();
            let restart = sim.restart_state();
            file.write_frame(&frame::capture(&sim, &fields), Some(&restart))
                .expect("write");
            start.elapsed().as_secs_f64()
        })
        .collect();
    file.close().expect("close");
    let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let (step, write) = (median(steps), median(writes));
    println!(
        "step: median {:.2} ms ({} threads)",
        1e3 * step,
        rayon::current_num_threads()
    );
    println!(
        "write_frame (all fields + restart data + XDMF): median {:.2} ms, {:.1} MB per frame",
        1e3 * write,
        size as f64 / 15.0 / 1e6
    );
    println!(
        "write / step = {:.2}: below 5 % of the time between frames for a cadence of ≥ {:.0} steps",
        write / step,
        (write / step / 0.05).ceil()
    );
    println!(
        "default cadence (100 frames per run) of a 10,000-step run: {:.2} % of the run",
        100.0 * write / (100.0 * step)
    );
}
