//! Parity with LIGGGHTS 3.8 on its benchmark bed, without LIGGGHTS. Both programs start from
//! the settled restart of shared/bench/liggghts: am-sim imports it as benches/liggghts_export.sh
//! wrote it (scenes/data/liggghts_start_20k*.dump.gz: positions, velocities, spins, and the
//! tangential springs of the pairs and of the plate). LIGGGHTS' results, written by the same
//! script's `--references`, are stored in tests/reference:
//! * one step (`liggghts_one_step.txt.gz`): the velocities and spins after the first step, which
//!   test the imported springs, their sign and frame included;
//! * mechanics (`liggghts_contacts_2000_steps.txt`): the particle-particle contacts (overlap > 0)
//!   and the wall contacts after 500 + 1500 steps;
//! * heat conduction (`liggghts_heat_2000_steps.txt.gz`): every particle's temperature after
//!   `in.bench -var heat 1` against `scenes/liggghts_bed_20k_heat.toml`. The two programs
//!   integrate the same contact network with the same conductance model (M.79), so the heat
//!   that reaches the initially cold particles agrees to a few per cent; per particle, the
//!   contacts that open and close differently leave differences of a few kelvin.

mod common;

use std::io::Read;

/// The text of a gzipped reference file of tests/reference.
fn gzipped_reference(name: &str) -> String {
    let path = format!("{}/tests/reference/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(path).expect("reference file"))
        .read_to_string(&mut text)
        .expect("gzip text");
    text
}

/// LIGGGHTS' temperatures [K], indexed like am-sim's particles (ids in file order).
fn liggghts_temperatures() -> Vec<f64> {
    let text = gzipped_reference("liggghts_heat_2000_steps.txt.gz");
    let mut rows: Vec<(u64, f64)> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let mut fields = l.split_whitespace();
            let id = fields.next().unwrap().parse().unwrap();
            (id, fields.next().unwrap().parse().unwrap())
        })
        .collect();
    rows.sort_by_key(|r| r.0);
    rows.into_iter().map(|r| r.1).collect()
}

/// `key=value` from the stored coord.py line, e.g. `contacts(overlap>0)=15694`.
fn coord_field(key: &str) -> f64 {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/reference/liggghts_contacts_2000_steps.txt"
    ))
    .expect("reference file");
    let line = text
        .lines()
        .find(|l| !l.starts_with('#'))
        .expect("data line");
    let start = line.find(&format!("{key}=")).expect("key") + key.len() + 1;
    line[start..]
        .split([' ', '|'])
        .next()
        .unwrap()
        .parse()
        .expect("number")
}

#[test]
fn the_bed_keeps_as_many_contacts_as_in_liggghts() {
    let mut sim = common::liggghts_scene("liggghts_bed_20k.toml");
    for _ in 0..2000 {
        sim.step();
    }
    let d = sim.diagnostics();
    #[allow(clippy::cast_precision_loss)]
    let (contacts, walls) = (d.contacts as f64, d.wall_contacts as f64);
    let (lig_contacts, lig_walls) = (
        coord_field("contacts(overlap>0)"),
        coord_field("wall contacts"),
    );
    eprintln!(
        "contacts {contacts} vs LIGGGHTS {lig_contacts} ({:+.2} %), wall contacts {walls} vs \
         {lig_walls} ({:+.2} %)",
        100.0 * (contacts / lig_contacts - 1.0),
        100.0 * (walls / lig_walls - 1.0)
    );
    // Measured −2.0 % and −0.4 % (+0.4 % and −1.0 % at the end of the 5500-step window,
    // docs/performance-log.md). The coordination moves from 1.30 to 1.38 over these steps and the
    // contacts opening and closing differ in detail, hence 5 %. A start without the spins (a
    // plain `dump custom id x y z vx vy vz radius`) compacts instead, about 16 % above.
    assert!((contacts / lig_contacts - 1.0).abs() < 0.05);
    assert!((walls / lig_walls - 1.0).abs() < 0.05);
}

/// LIGGGHTS' velocities and spins after one step, by LIGGGHTS id (every fourth particle).
fn liggghts_one_step() -> Vec<(u64, [f64; 6])> {
    gzipped_reference("liggghts_one_step.txt.gz")
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let mut fields = l.split_whitespace();
            let id = fields.next().unwrap().parse().unwrap();
            let values: Vec<f64> = fields.map(|f| f.parse().unwrap()).collect();
            (id, values.try_into().unwrap())
        })
        .collect()
}

/// After one step from LIGGGHTS' state, how far am-sim's velocities are from LIGGGHTS', as
/// medians over the particles that touch the plate and over the others, each relative to the
/// median change LIGGGHTS' step made. `negate` turns the imported springs round (pairs, plate).
fn one_step_misfit(negate: bool) -> (f64, f64) {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/data/");
    let dir = tempfile::tempdir().unwrap();
    let mut text = common::scene_text("liggghts_bed_20k.toml")
        .replace("duration_s = 5.5e-4", "duration_s = 1e-7")
        .replace("file = \"data/", &format!("file = \"{data}"));
    if negate {
        // The same files with every spring's three components negated.
        let mut negated = |name: &str, first: usize| {
            let mut source = String::new();
            flate2::read::GzDecoder::new(std::fs::File::open(format!("{data}{name}")).unwrap())
                .read_to_string(&mut source)
                .unwrap();
            let mut out = String::new();
            for (k, line) in source.lines().enumerate() {
                let mut cells: Vec<String> = line.split_whitespace().map(String::from).collect();
                if k >= 9 {
                    for cell in &mut cells[first..first + 3] {
                        *cell = format!("{:e}", -cell.parse::<f64>().unwrap());
                    }
                }
                out += &(cells.join(" ") + "\n");
            }
            let path = dir.path().join(name.trim_end_matches(".gz"));
            std::fs::write(&path, out).unwrap();
            text = text.replace(&format!("{data}{name}"), path.to_str().unwrap());
        };
        negated("liggghts_start_20k.dump.gz", 11);
        negated("liggghts_start_20k_pairs.dump.gz", 3);
    }
    let mut sim = common::simulation(&text);
    let index_of: std::collections::HashMap<u64, usize> = sim
        .particles
        .id
        .iter()
        .enumerate()
        .map(|(k, id)| (*id, k))
        .collect();
    let start: Vec<_> = sim.particles.velocity.clone();
    let on_plate: Vec<bool> = (0..sim.particles.len())
        .map(|k| sim.particles.position[k].z < sim.particles.radius[k])
        .collect();
    sim.step();
    let (mut misfit, mut change) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
    for (id, values) in liggghts_one_step() {
        // am-sim numbers the imported particles 0.. in the order of their LIGGGHTS ids (1..).
        let k = index_of[&(id - 1)];
        let v = glam::DVec3::new(values[0], values[1], values[2]);
        let group = usize::from(on_plate[k]);
        misfit[group].push((v - sim.particles.velocity[k]).length());
        change[group].push((v - start[k]).length());
    }
    let median = |values: &mut Vec<f64>| {
        values.sort_by(f64::total_cmp);
        values[values.len() / 2]
    };
    let [mut misfit_off, mut misfit_on] = misfit;
    let [mut change_off, mut change_on] = change;
    (
        median(&mut misfit_on) / median(&mut change_on),
        median(&mut misfit_off) / median(&mut change_off),
    )
}

#[test]
fn the_imported_springs_act_as_in_liggghts() {
    let (plate, pairs) = one_step_misfit(false);
    let (plate_negated, pairs_negated) = one_step_misfit(true);
    eprintln!(
        "one step, median velocity misfit over LIGGGHTS' median change: on the plate {plate:.3e} \
         ({plate_negated:.3e} with the springs negated), elsewhere {pairs:.3e} ({pairs_negated:.3e})"
    );
    // Both programs take the t = 0 forces from the springs as they stand (am-sim's set-up
    // evaluation, LIGGGHTS' setup pass) and run the same laws, so the rounding of the 12-digit
    // dump and the order of sums would leave misfits near 1e-6 (5e-7 measured with LIGGGHTS'
    // Coulomb rule). What is left is the one rule am-sim does not share: its damping force may
    // not carry a sticking contact beyond μ |F_n| (docs/model.md M.59). That touches the plate's
    // fastest-sliding fresh contacts (1.4e-2 measured on the plate, 6e-6 elsewhere). The bounds
    // are about twice and twenty times those; an evaluation that advanced the springs at t = 0
    // (am-sim's earlier set-up: 4.2e-2 and 3e-3) fails them. A spring of the wrong sign or frame
    // moves a step's velocity change by its own size.
    assert!(plate < 0.03, "{plate}");
    assert!(pairs < 1e-4, "{pairs}");
    assert!(plate_negated > 1.0, "{plate_negated}");
    assert!(pairs_negated > 0.1, "{pairs_negated}");
}

#[test]
fn the_heat_variant_moves_the_heat_liggghts_moves() {
    let mut sim = common::liggghts_scene("liggghts_bed_20k_heat.toml");
    let n = sim.particles.len();
    // am-sim numbers imported particles 0.. in the order of their file ids; its storage order
    // is spatial, so temperatures are gathered by id.
    let by_id = |sim: &am_sim::simulation::Simulation| {
        let mut by_id = vec![0.0; n];
        let t = &sim.thermal.as_ref().unwrap().temperature;
        for (k, id) in sim.particles.id.iter().enumerate() {
            by_id[usize::try_from(*id).unwrap()] = t[k];
        }
        by_id
    };
    let start = by_id(&sim);
    for _ in 0..2000 {
        sim.step();
    }
    let am = by_id(&sim);
    let lig = liggghts_temperatures();
    assert_eq!(lig.len(), n);
    let cold: Vec<usize> = (0..n).filter(|&i| start[i] == 300.0).collect();
    assert!(
        cold.len() > n / 2 && cold.len() < n,
        "{} cold of {n}",
        cold.len()
    );
    let gained = |t: &[f64]| cold.iter().map(|&i| t[i] - 300.0).sum::<f64>();
    let (gained_am, gained_lig) = (gained(&am), gained(&lig));
    #[allow(clippy::cast_precision_loss)]
    let rms = (am
        .iter()
        .zip(&lig)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / n as f64)
        .sqrt();
    #[allow(clippy::cast_precision_loss)]
    let mean = |t: &[f64]| t.iter().sum::<f64>() / n as f64;
    eprintln!(
        "heat into the cold part: am-sim {gained_am:.4e} K, LIGGGHTS {gained_lig:.4e} K \
         ({:+.2} %); per particle rms {rms:.3} K; mean T {:.6} vs {:.6} K",
        100.0 * (gained_am / gained_lig - 1.0),
        mean(&am),
        mean(&lig)
    );
    // Both conserve heat (equal capacities, no boundary exchange): equal means, to the round-off
    // of LIGGGHTS' 13-digit dump.
    assert!((mean(&am) / mean(&lig) - 1.0).abs() < 1e-10);
    // Heat did move, and as much as in LIGGGHTS within 5 % (the 5500-step parity run gave
    // −2.6 % with a coordination 1 % lower; the margin is for that difference of networks).
    assert!(gained_lig > 1e3, "{gained_lig}");
    assert!((gained_am / gained_lig - 1.0).abs() < 0.05);
    // Per particle within a few kelvin (1.2 K rms after 5500 steps).
    assert!(rms < 3.0, "{rms}");
}
