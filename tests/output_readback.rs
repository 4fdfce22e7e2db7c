//! HDF5 output read back: shapes, attributes and values of the frames, the series and the XDMF
//! file against the in-memory state of the run that wrote them. Its own test binary, because
//! HDF5 opens files without close-on-exec: child processes spawned by other tests in the same
//! binary would inherit this file's lock.
#![cfg(feature = "hdf5")]

mod common;

use std::path::PathBuf;

use am_sim::output::Writers;

#[test]
fn frames_hold_the_in_memory_state() {
    let dir = tempfile::tempdir().unwrap();
    let text = common::short_track(6e-4, 1000);
    let mut sim = common::simulation(&text);
    let path: PathBuf = dir.path().join("laser_track.h5");
    let cwd = std::env::current_dir().unwrap();
    // Writers resolve the scene's relative file name against the working directory.
    sim.model.output.file = Some(path.clone());
    let mut writers = Writers::open(&sim, &text, false, None).unwrap();
    writers.write(&sim, &sim.diagnostics(), 0.0, false).unwrap();
    while sim.step < sim.model.steps {
        sim.step();
        let last = sim.step == sim.model.steps;
        if writers.due(sim.step, last) {
            writers.write(&sim, &sim.diagnostics(), 0.0, last).unwrap();
        }
    }
    writers.close().unwrap();
    assert_eq!(std::env::current_dir().unwrap(), cwd);

    let file = hdf5::File::open(&path).unwrap();
    let text_attr: hdf5::types::VarLenUnicode = file.attr("scene").unwrap().read_scalar().unwrap();
    assert_eq!(text_attr.as_str(), text);
    let format: hdf5::types::VarLenUnicode = file.attr("format").unwrap().read_scalar().unwrap();
    assert_eq!(format.as_str(), "am-sim");
    let units: hdf5::types::VarLenUnicode = file.attr("units").unwrap().read_scalar().unwrap();
    assert_eq!(units.as_str(), "SI");
    let frames = file.group("frames").unwrap();
    assert_eq!(
        frames.member_names().unwrap().len(),
        7,
        "t = 0 and every 1000 of 6000 steps"
    );
    let last = frames.group("000006").unwrap();
    assert_eq!(
        last.attr("step").unwrap().read_scalar::<u64>().unwrap(),
        6000
    );
    let n = sim.particles.len();
    let position: Vec<f64> = last.dataset("position").unwrap().read_raw().unwrap();
    assert_eq!(last.dataset("position").unwrap().shape(), vec![n, 3]);
    let flat: Vec<f64> = sim
        .particles
        .position
        .iter()
        .flat_map(|x| x.to_array())
        .collect();
    assert_eq!(position, flat, "positions bit for bit");
    let temperature: Vec<f64> = last.dataset("temperature").unwrap().read_raw().unwrap();
    assert_eq!(temperature, sim.thermal.as_ref().unwrap().temperature);
    let melted: Vec<u8> = last.dataset("melted").unwrap().read_raw().unwrap();
    assert_eq!(
        melted.iter().filter(|m| **m == 1).count(),
        sim.diagnostics().thermal.unwrap().melted
    );
    // The share of the latent heat taken (M.48), `(E − m c T_m) / (m L)` clamped to [0, 1],
    // with the scene's 316L (c = 500 J/(kg·K), T_m = 1700 K, L = 2.7e5 J/kg): a handful of
    // roundings on values of order 1 apart, so 1e-12 bounds any difference of their order.
    let fraction: Vec<f64> = last.dataset("melt_fraction").unwrap().read_raw().unwrap();
    let thermal = sim.thermal.as_ref().unwrap();
    assert_eq!(fraction.len(), n);
    for (k, f) in fraction.iter().enumerate() {
        let mass = sim.particles.mass[k];
        let above = thermal.enthalpy[k] - mass * 500.0 * 1700.0;
        let expected = (above / (mass * 2.7e5)).clamp(0.0, 1.0);
        assert!(
            (f - expected).abs() < 1e-12,
            "particle {k}: {f} against {expected}"
        );
    }
    assert!(fraction.contains(&1.0), "no particle melted through");
    let bonds: Vec<u64> = last.dataset("bonds").unwrap().read_raw().unwrap();
    let ids = &sim.particles.id;
    let mut from_file: Vec<(u64, u64)> = bonds
        .chunks_exact(2)
        .map(|r| {
            (
                ids[r[0] as usize].min(ids[r[1] as usize]),
                ids[r[0] as usize].max(ids[r[1] as usize]),
            )
        })
        .collect();
    from_file.sort_unstable();
    assert!(!from_file.is_empty());
    assert_eq!(from_file, sim.bonds());
    let series = file.group("series").unwrap();
    let steps: Vec<u64> = series.dataset("step").unwrap().read_raw().unwrap();
    assert_eq!(steps, (0..=6).map(|k| k * 1000).collect::<Vec<_>>());
    let laser: Vec<f64> = series
        .dataset("laser_energy_j")
        .unwrap()
        .read_raw()
        .unwrap();
    assert_eq!(
        *laser.last().unwrap(),
        sim.diagnostics().thermal.unwrap().laser_energy
    );
    // The XDMF companion names existing datasets only.
    let xmf = std::fs::read_to_string(path.with_extension("xmf")).unwrap();
    assert_eq!(xmf.matches("<Grid Name=\"particles_").count(), 7);
    for reference in xmf.split("laser_track.h5:").skip(1) {
        let dataset = &reference[..reference.find('<').unwrap()];
        assert!(
            file.dataset(dataset).is_ok(),
            "XDMF names missing {dataset}"
        );
    }
}
