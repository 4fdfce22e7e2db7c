//! `scenes/laser_track.toml` end to end: the particles under the track melt and bond into a line
//! along the scan, nothing melts away from it, no particle passes the boiling point, and the heat
//! books balance with what the vapour carried off.

mod common;

#[test]
fn the_track_melts_and_bonds_into_a_line() {
    let text = common::scene_text("laser_track.toml");
    let mut sim = common::simulation(&text);
    let d0 = sim.diagnostics();
    let boiling = 3090.0;
    let mut hottest: f64 = 0.0;
    while sim.step < sim.model.steps {
        sim.step();
        let t = sim.thermal.as_ref().unwrap();
        hottest = t.temperature.iter().copied().fold(hottest, f64::max);
    }
    // The boiling point bounds every temperature of every step (M.80; T(E_b) rounds to within
    // a few ulps of T_b), and the beam drives the hottest particles to it.
    eprintln!("hottest particle of the run: {hottest} K");
    assert!(
        hottest <= boiling * (1.0 + 4.0 * f64::EPSILON),
        "{hottest} K"
    );
    assert!(
        hottest >= boiling * (1.0 - 4.0 * f64::EPSILON),
        "{hottest} K"
    );
    let (track_y, track_x) = (6.0e-4, (1.0e-4, 1.6e-3));
    let spot = sim.model.laser.as_ref().unwrap().spot_radius;
    let p = &sim.particles;
    let thermal = sim.thermal.as_ref().unwrap();
    let melted: Vec<usize> = (0..p.len()).filter(|&k| thermal.melted[k]).collect();
    assert!(melted.len() > 50, "melted {}", melted.len());
    for &k in &melted {
        // Beyond 2w the intensity is e^-8 of the peak: too little to melt anything.
        assert!(
            (p.position[k].y - track_y).abs() < 2.0 * spot,
            "particle {k} melted off the track at {:?}",
            p.position[k]
        );
    }
    // Bonds are named by ids; particles are stored in spatial order.
    let index = |id: u64| p.index_of(id).unwrap();
    let bonds = sim.bonds();
    assert!(bonds.len() > 50, "bonds {}", bonds.len());
    let xs: Vec<f64> = bonds
        .iter()
        .flat_map(|&(a, b)| [p.position[index(a)].x, p.position[index(b)].x])
        .collect();
    let (lo, hi) = xs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(*x), hi.max(*x))
        });
    eprintln!(
        "melted {}, bonds {}, bonded x from {lo:.3e} to {hi:.3e} m",
        melted.len(),
        bonds.len()
    );
    assert!(
        hi - lo > 0.8 * (track_x.1 - track_x.0),
        "the bonds span the track: {lo}..{hi}"
    );
    for &(a, b) in &bonds {
        assert!(
            thermal.melted[index(a)] && thermal.melted[index(b)],
            "rule \"both\""
        );
    }
    // Heat balance: stored = absorbed + exchanged with the plate, gas and surroundings − carried
    // off by the vapour.
    let d1 = sim.diagnostics();
    let (t0, t1) = (d0.thermal.unwrap(), d1.thermal.unwrap());
    let evaporated = t1.evaporation.expect("316L boils in this scene").heat;
    assert!(evaporated > 0.0 && evaporated < t1.laser_energy);
    let residual =
        (t1.enthalpy - t0.enthalpy) - (t1.laser_energy + t1.boundary_energy - evaporated);
    assert!(
        residual.abs() < 1e-10 * t1.laser_energy,
        "heat balance residual {residual} J"
    );
    // The laser delivered α P t_on: the beam is always over the bed (all of it lands on particles
    // or in the gaps, so no more than that).
    assert!(t1.laser_energy <= 0.6 * 20.0 * 3e-3 * (1.0 + 1e-9));
}
