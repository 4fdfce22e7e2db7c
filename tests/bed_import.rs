//! `[[import]]`: particles read back from am-sim's CSV, LIGGGHTS dumps (plain and gzip) and
//! am-sim HDF5 frames are bit for bit the ones written; the shipped LIGGGHTS start configuration
//! has the benchmark's 19,200 spheres of r = 15 µm; bad files give errors naming key, file and line.

use std::path::Path;

use am_sim::bed::import::{parse_csv, parse_liggghts_dump, write_csv};
use am_sim::model::Model;
use am_sim::particles::Particles;
use am_sim::scene::Scene;
use glam::DVec3;

const HEAD: &str = r#"
[scene]
version = 1
[simulation]
dt_s = 1e-7
duration_s = 1e-6
gravity_m_s2 = [0.0, 0.0, -9.81]
[materials.steel]
density_kg_m3 = 7950
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
[materials.glass]
density_kg_m3 = 2500
youngs_modulus_pa = 1e8
poisson_ratio = 0.25
[contact]
model = "hertz"
damping_ratio = 0.5
"#;

/// Writes `scene.toml` with `body` into `dir` and builds it (relative files resolve from `dir`).
fn build_in(dir: &Path, body: &str) -> Result<Particles, String> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, format!("{HEAD}{body}")).unwrap();
    let scene = Scene::load(&path).map_err(|e| e.to_string())?;
    Model::try_build(&scene)
        .map(|(_, p)| p)
        .map_err(|e| e.in_file(&path).to_string())
}

/// A few hundred particles with awkward values (random bits, tiny and negative numbers).
fn sample_particles() -> Particles {
    let text = format!(
        "{HEAD}
[[insert]]
min_corner_m = [-1e-4, 0.0, 1e-5]
max_corner_m = [3e-4, 2e-4, 2e-4]
count = 300
seed = 99
velocity_m_s = [1e-3, -2.5e-17, 0.1]
material = \"steel\"
[insert.size]
distribution = \"lognormal\"
mean_m = 2e-5
std_m = 5e-6
"
    );
    let scene = Scene::from_toml(&text).unwrap();
    Model::try_build(&scene).unwrap().1
}

#[test]
fn csv_round_trip_is_exact() {
    let p = sample_particles();
    let text = write_csv(&p.id, &p.position, &p.velocity, &p.radius);
    let rows = parse_csv(&text).unwrap();
    assert_eq!(rows.len(), p.len());
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.id, Some(p.id[k]));
        assert_eq!(row.position, p.position[k]);
        assert_eq!(row.velocity, p.velocity[k]);
        assert_eq!(row.radius, p.radius[k]);
    }

    // Through a scene: a file beside it, relative path, scaled by 1 and not shifted.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bed.csv"), &text).unwrap();
    let imported = build_in(
        dir.path(),
        "[[import]]\nfile = \"bed.csv\"\nformat = \"csv\"\nmaterial = \"steel\"\n",
    )
    .unwrap();
    assert_eq!(imported.position, p.position);
    assert_eq!(imported.velocity, p.velocity);
    assert_eq!(imported.radius, p.radius);
    assert_eq!(imported.mass, p.mass);
}

#[test]
fn csv_columns_in_any_order_with_materials_ids_and_comments() {
    let text = "# made by hand\nmaterial, radius_m, z_m, y_m, x_m, id\n\
                glass, 1e-5, 3e-5, 2e-5, 1e-5, 7\n\n# a comment row\nsteel, 2e-5, 6e-5, 0, 0, 3\n";
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("hand.csv"), text).unwrap();
    // Millimetres in the file: scale 1e-3 on positions and radii, then a shift.
    let p = build_in(
        dir.path(),
        "[[import]]\nfile = \"hand.csv\"\nformat = \"csv\"\nscale = 1e3\nshift_m = [0.0, 0.0, 1.0]\n",
    )
    .unwrap();
    // Sorted by file id: id 3 (steel) first.
    assert_eq!(p.len(), 2);
    assert_eq!(p.radius, vec![2e-5 * 1e3, 1e-5 * 1e3]);
    assert_eq!(p.position[0], DVec3::new(0.0, 0.0, 6e-5 * 1e3 + 1.0));
    assert_eq!(
        p.position[1],
        DVec3::new(1e-5 * 1e3, 2e-5 * 1e3, 3e-5 * 1e3 + 1.0)
    );
    assert_eq!(
        p.material,
        vec![1, 0],
        "BTreeMap order: glass = 0, steel = 1"
    );
    assert_eq!(p.velocity, vec![DVec3::ZERO; 2]);
}

/// A dump with two snapshots, unsorted ids and columns LIGGGHTS adds (type, mass, forces).
const DUMP: &str = "ITEM: TIMESTEP
100
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS pp pp ff
0 1e-3
0 1e-3
0 1e-3
ITEM: ATOMS id type x y z vx vy vz fx radius
2 1 1e-4 2e-4 3e-4 0 0 0 0 1.5e-5
1 1 4e-4 5e-4 6e-4 0 0 0 0 1.5e-5
ITEM: TIMESTEP
200
ITEM: NUMBER OF ATOMS
3
ITEM: BOX BOUNDS pp pp ff
0 1e-3
0 1e-3
0 1e-3
ITEM: ATOMS id type x y z vx vy vz fx radius
9 1 7e-4 8e-4 9e-4 1 2 3 0 2e-5
2 1 1.5e-4 2e-4 3e-4 -1 0 0 0 1.5e-5
5 1 4e-4 5e-4 6e-4 0 0 0 0 1.5e-5
";

#[test]
fn a_liggghts_dump_gives_its_last_or_the_chosen_snapshot_sorted_by_id() {
    let last = parse_liggghts_dump(DUMP, None).unwrap();
    assert_eq!(last.timestep, 200);
    let ids: Vec<Option<u64>> = last.particles.iter().map(|p| p.id).collect();
    assert_eq!(ids, [Some(2), Some(5), Some(9)]);
    assert_eq!(last.particles[2].position, DVec3::new(7e-4, 8e-4, 9e-4));
    assert_eq!(last.particles[2].velocity, DVec3::new(1.0, 2.0, 3.0));
    assert_eq!(last.particles[2].radius, 2e-5);
    let first = parse_liggghts_dump(DUMP, Some(100)).unwrap();
    assert_eq!(first.particles.len(), 2);
    assert_eq!(first.particles[0].position, DVec3::new(4e-4, 5e-4, 6e-4));
    let missing = parse_liggghts_dump(DUMP, Some(150)).unwrap_err();
    assert!(missing.contains("timesteps [100, 200]"), "{missing}");
}

#[test]
fn a_dump_is_read_snapshot_by_snapshot() {
    // A broken row in a snapshot that is not chosen does not matter; in the chosen one it is an
    // error naming its line, and a truncated chosen snapshot names what it announced.
    let broken_first = DUMP.replacen("1 1 4e-4 5e-4 6e-4", "1 1 4e-4 oops 6e-4", 1);
    assert_eq!(
        parse_liggghts_dump(&broken_first, None).unwrap().timestep,
        200
    );
    let error = parse_liggghts_dump(&broken_first, Some(100)).unwrap_err();
    assert!(
        error.contains("line 11") && error.contains("oops"),
        "{error}"
    );
    let truncated = &DUMP[..DUMP.rfind("5 1 4e-4").unwrap()];
    let error = parse_liggghts_dump(truncated, None).unwrap_err();
    assert!(
        error.contains("3 atoms announced, the file ends after 2"),
        "{error}"
    );
    assert_eq!(
        parse_liggghts_dump(truncated, Some(100))
            .unwrap()
            .particles
            .len(),
        2
    );
}

#[test]
fn a_gzipped_dump_reads_like_the_plain_one() {
    use std::io::Write as _;
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("d.dump"), DUMP).unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(DUMP.as_bytes()).unwrap();
    std::fs::write(dir.path().join("d.dump.gz"), gz.finish().unwrap()).unwrap();
    let block = |file: &str| {
        format!("[[import]]\nfile = \"{file}\"\nformat = \"liggghts_dump\"\nmaterial = \"steel\"\n")
    };
    let plain = build_in(dir.path(), &block("d.dump")).unwrap();
    let gzipped = build_in(dir.path(), &block("d.dump.gz")).unwrap();
    assert_eq!(plain.position, gzipped.position);
    assert_eq!(plain.len(), 3);
}

#[test]
fn the_shipped_liggghts_start_configuration_has_the_benchmark_bed() {
    // shared/bench/liggghts/README.md: 19,200 spheres of R = 15 µm in a 1.32 × 1.32 mm box.
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let tmp = tempfile::tempdir().unwrap();
    let p = build_in(
        tmp.path(),
        &format!(
            "[[import]]\nfile = \"{dir}/data/liggghts_start_20k.dump.gz\"\nformat = \"liggghts_dump\"\nmaterial = \"steel\"\n"
        ),
    )
    .unwrap();
    assert_eq!(p.len(), 19_200);
    assert!(p.radius.iter().all(|&r| r == 1.5e-5));
    for x in &p.position {
        assert!((0.0..=1.32e-3).contains(&x.x) && (0.0..=1.32e-3).contains(&x.y));
        // Settled on the plate at z = 0 in a bed ≈ 318 µm deep: centres between r − δ and 0.4 mm.
        assert!(x.z > 1.4e-5 && x.z < 4e-4, "z = {}", x.z);
    }
}

#[test]
fn bad_files_are_errors_naming_key_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let csv = |name: &str, text: &str| {
        std::fs::write(dir.path().join(name), text).unwrap();
        build_in(
            dir.path(),
            &format!("[[import]]\nfile = \"{name}\"\nformat = \"csv\"\nmaterial = \"steel\"\n"),
        )
        .unwrap_err()
    };
    let cases: [(String, &[&str]); 5] = [
        (
            csv("a.csv", "x_m,y_m,z_m,radius_m\n0,0,0,1e-5\n0,0,1e-4,abc\n"),
            &["import[0].file = \"a.csv\"", "line 3, column `radius_m`: \"abc\" is not a number"],
        ),
        (
            csv("b.csv", "x_m,y_m,z_m,radius\n0,0,0,1e-5\n"),
            &["line 1: unknown column `radius`", "radius_m"],
        ),
        (
            csv("c.csv", "x_m,y_m,z_m,radius_m\n0,0,0,-1e-5\n"),
            &["line 2, column `radius_m`: -0.00001 must be > 0"],
        ),
        (
            csv("d.csv", "x_m,y_m,z_m,radius_m,material\n0,0,0,1e-5,copper\n"),
            &["material \"copper\": no such material"],
        ),
        (
            build_in(
                dir.path(),
                "[[import]]\nfile = \"nowhere.dump\"\nformat = \"liggghts_dump\"\nmaterial = \"steel\"\n",
            )
            .unwrap_err(),
            &["import[0].file = \"nowhere.dump\"", "cannot open"],
        ),
    ];
    for (message, fragments) in &cases {
        for fragment in *fragments {
            assert!(message.contains(fragment), "lacks {fragment:?}:\n{message}");
        }
    }
}

#[cfg(feature = "hdf5")]
#[test]
fn an_am_sim_frame_round_trips_exactly() {
    use am_sim::output::Writers;
    use am_sim::simulation::Simulation;
    let dir = tempfile::tempdir().unwrap();
    let particles = sample_particles();
    let text = format!(
        "{HEAD}\n[[walls]]\npoint_m = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nmaterial = \"steel\"\n"
    );
    let scene = Scene::from_toml(&format!(
        "{text}[[particles]]\nposition_m = [0.0, 0.0, 1.0]\nradius_m = 1e-5\nmaterial = \"steel\"\n"
    ))
    .unwrap();
    let (mut model, _) = Model::try_build(&scene).unwrap();
    model.output.file = Some(dir.path().join("run.h5"));
    let mut sim = Simulation::new(model, particles);
    let mut writers = Writers::open(&sim, &text, false, None).unwrap();
    writers.write(&sim, &sim.diagnostics(), 0.0, false).unwrap();
    let first = sim.particles.clone();
    for _ in 0..10 {
        sim.step();
    }
    writers.write(&sim, &sim.diagnostics(), 0.0, true).unwrap();
    writers.close().unwrap();

    let block = |frame: &str| {
        format!(
            "[[import]]\nfile = \"run.h5\"\nformat = \"am_sim_h5\"\nmaterial = \"steel\"\n{frame}"
        )
    };
    // A frame stores the particles in the simulation's (spatial) storage order; the import
    // returns them sorted by id.
    let by_id = |p: &am_sim::particles::Particles| {
        let mut order: Vec<usize> = (0..p.len()).collect();
        order.sort_by_key(|&k| p.id[k]);
        let pick = |v: &[glam::DVec3]| order.iter().map(|&k| v[k]).collect::<Vec<_>>();
        let radius: Vec<f64> = order.iter().map(|&k| p.radius[k]).collect();
        (pick(&p.position), pick(&p.velocity), radius)
    };
    let (position, velocity, radius) = by_id(&sim.particles);
    let last = build_in(dir.path(), &block("")).unwrap();
    assert_eq!(last.position, position);
    assert_eq!(last.velocity, velocity);
    assert_eq!(last.radius, radius);
    let initial = build_in(dir.path(), &block("frame = 0\n")).unwrap();
    assert_eq!(initial.position, by_id(&first).0);
    let missing = build_in(dir.path(), &block("frame = 7\n")).unwrap_err();
    assert!(missing.contains("no complete frame 7"), "{missing}");
}

#[test]
fn every_shipped_scene_builds_its_particles() {
    // Scene loading validates; building also reads `[[import]]` files (relative to scenes/) and
    // places `[[insert]]` spheres, which validation cannot check.
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    for entry in std::fs::read_dir(dir).expect("scenes/") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "toml") {
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let (_, particles) =
                Model::try_build(&scene).unwrap_or_else(|e| panic!("{}", e.in_file(&path)));
            assert!(!particles.is_empty(), "{}", path.display());
        }
    }
}

/// Two touching spheres on a plate as LIGGGHTS dumps them (file ids 7 and 3, with spins and the
/// plate's springs per atom), and the pairs' springs as its `dump local` of `compute
/// pair/gran/local id history` writes them; `edit` changes the texts before they are written.
fn spring_bed(
    dir: &Path,
    edit: impl Fn(&str) -> String,
) -> Result<am_sim::simulation::Simulation, String> {
    let head = "ITEM: TIMESTEP\n35000\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp ff\n0 1e-3\n0 1e-3\n0 1e-3\n";
    std::fs::write(
        dir.join("bed.dump"),
        edit(&format!(
            "{head}ITEM: ATOMS id x y z vx vy vz omegax omegay omegaz radius f_history_zwall[1] f_history_zwall[2] f_history_zwall[3]\n\
             7 1e-4 1e-4 0.99e-5 0 0 0 1 2 3 1e-5 1e-9 -2e-9 0\n\
             3 1.199e-4 1e-4 0.99e-5 0 0 0 -4 5 -6 1e-5 0 0 0\n"
        )),
    )
    .unwrap();
    std::fs::write(
        dir.join("pairs.dump"),
        edit(&format!(
            "{}ITEM: ENTRIES c_p[1] c_p[2] c_p[3] c_p[4] c_p[5] c_p[6]\n7 3 0 0 3e-9 4e-9\n",
            head.replace("NUMBER OF ATOMS\n2", "NUMBER OF ENTRIES\n1")
        )),
    )
    .unwrap();
    let body = edit(
        "friction_coefficient = 0.5\n\
         [[import]]\nfile = \"bed.dump\"\nformat = \"liggghts_dump\"\nmaterial = \"steel\"\n\
         pair_history_file = \"pairs.dump\"\nwall_history_columns = [\"f_history_zwall\"]\n\
         [[walls]]\npoint_m = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nmaterial = \"glass\"\n",
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, format!("{HEAD}{body}")).unwrap();
    let scene = Scene::load(&path).map_err(|e| e.to_string())?;
    let (model, particles) = Model::try_build(&scene).map_err(|e| e.in_file(&path).to_string())?;
    Ok(am_sim::simulation::Simulation::new(model, particles))
}

#[test]
fn a_liggghts_bed_brings_its_spins_and_springs() {
    use am_sim::contact::{hertz, tangential};
    let dir = tempfile::tempdir().unwrap();
    let sim = spring_bed(dir.path(), str::to_string).unwrap();
    let state = sim.restart_state().rotation.unwrap();
    // am-sim numbers the particles in the order of their file ids: file id 3 is particle 0.
    let index = |id: u64| sim.particles.id.iter().position(|&i| i == id).unwrap();
    assert_eq!(
        state.angular_velocity[index(0)],
        DVec3::new(-4.0, 5.0, -6.0)
    );
    assert_eq!(state.angular_velocity[index(1)], DVec3::new(1.0, 2.0, 3.0));
    // The file's spring is 7's displacement relative to 3; am-sim keeps the lower id's (0, file
    // id 3) relative to the higher: the same spring, negated.
    assert_eq!(state.pair_ids, vec![(0, 1)]);
    let history = DVec3::new(0.0, -3e-9, -4e-9);
    assert_eq!(state.pair_history, vec![history]);
    // With its energy ½ k_t |ξ|², k_t = 8 G* √(r* δ) (M.57, M.63): the spheres overlap by
    // 2e-5 − 1.99e-5 m, the plate by 1e-5 − 0.99e-5 m.
    let steel_steel = tangential::effective_shear_modulus(2e8, 0.3, 2e8, 0.3);
    let k_pair = tangential::stiffness(
        steel_steel,
        hertz::effective_radius(1e-5, 1e-5),
        2e-5 - 1.99e-5,
    );
    let expected = 0.5 * k_pair * history.length_squared();
    assert!(
        (state.pair_spring_energy[0] / expected - 1.0).abs() < 1e-9,
        "{state:?}"
    );
    let stride = 1;
    let plate = DVec3::new(1e-9, -2e-9, 0.0);
    assert_eq!(state.wall_history[index(1) * stride], plate);
    assert_eq!(state.wall_history[index(0) * stride], DVec3::ZERO);
    let steel_glass = tangential::effective_shear_modulus(2e8, 0.3, 1e8, 0.25);
    let k_wall = tangential::stiffness(steel_glass, 1e-5, 1e-5 - 0.99e-5);
    let expected = 0.5 * k_wall * plate.length_squared();
    assert!((state.wall_spring_energy[index(1)] / expected - 1.0).abs() < 1e-9);
    // `am-sim check` and the run's header say what the start holds.
    let start = am_sim::check::report(&sim).friction.unwrap().start;
    assert_eq!(
        (start.spinning, start.pair_springs, start.wall_springs),
        (2, 1, 1)
    );
    assert_eq!(start.max_spin, DVec3::new(-4.0, 5.0, -6.0).length());
    let energies = state.pair_spring_energy[0] + state.wall_spring_energy[index(1)];
    assert!((start.spring_energy / energies - 1.0).abs() < 1e-12);
    assert!(start.to_string().contains("2 spinning spheres"), "{start}");
}

/// A change to the texts of [`spring_bed`].
type Edit = dyn Fn(&str) -> String;

#[test]
fn bad_springs_are_errors_naming_key_value_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let error = |edit: &Edit| match spring_bed(dir.path(), edit) {
        Ok(_) => panic!("accepted"),
        Err(e) => e,
    };
    let cases: [(&Edit, &[&str]); 9] = [
        (
            &|t| t.replace("friction_coefficient = 0.5\n", ""),
            &[
                "import[0].pair_history_file = \"pairs.dump\"",
                "no tangential contact",
            ],
        ),
        (
            &|t| {
                t.replace(
                    "[\"f_history_zwall\"]",
                    "[\"f_history_zwall\", \"f_history_top\"]",
                )
            },
            &[
                "import[0].wall_history_columns",
                "2 column prefixes for 1 [[walls]]",
            ],
        ),
        (
            &|t| t.replace("f_history_zwall[2]", "f_history_zwall[5]"),
            &[
                "import[0].file",
                "lacks f_history_zwall[1], f_history_zwall[2] or f_history_zwall[3]",
            ],
        ),
        (
            &|t| t.replace(" omegay omegaz", " omegay omz"),
            &["some of omegax, omegay, omegaz but not all three"],
        ),
        (
            &|t| t.replace("7 3 0 0 3e-9", "7 9 0 0 3e-9"),
            &[
                "import[0].pair_history_file = \"pairs.dump\"",
                "line 10: the pair (7, 9) names a particle id that bed.dump does not hold",
            ],
        ),
        (
            // Particle 3 moved 10 µm away: no contact, and no slot of the neighbour list.
            &|t| t.replace("3 1.199e-4", "3 1.299e-4"),
            &[
                "import[0].pair_history_file = \"pairs.dump\"",
                "line 10 of pairs.dump: the two particles' surfaces are 9.9",
                "m apart, more than the skin (2.0000000000000003e-6 m): not a contact of the particles of bed.dump",
            ],
        ),
        (
            // Particle 7 lifted 50 µm off the plate, its plate spring kept.
            &|t| {
                t.replace("7 1e-4 1e-4 0.99e-5", "7 1e-4 1e-4 5.99e-5")
                    .replace("3 1.199e-4 1e-4 0.99e-5", "3 1.199e-4 1e-4 5.99e-5")
            },
            &[
                "import[0].wall_history_columns",
                "the particle of file id 7 (f_history_zwall) has a spring against wall 0 but is",
            ],
        ),
        (
            &|t| t.replace("7 3 0 0 3e-9 4e-9", "7 3 0 0 3e-9"),
            &[
                "import[0].pair_history_file",
                "line 10: 5 values; a contact needs six",
            ],
        ),
        (
            &|t| t.replace("ATOMS id x", "ATOMS type x"),
            &[
                "import[0].pair_history_file",
                "bed.dump has no `id` column, so its particles cannot be named by the pairs",
            ],
        ),
    ];
    for (edit, fragments) in cases {
        let message = error(edit);
        for fragment in fragments {
            assert!(message.contains(fragment), "lacks {fragment:?}:\n{message}");
        }
    }
    // The keys belong to LIGGGHTS dumps only.
    let csv = build_in(
        dir.path(),
        "[[import]]\nfile = \"a.csv\"\nformat = \"csv\"\nmaterial = \"steel\"\npair_history_file = \"p.dump\"\n",
    )
    .unwrap_err();
    assert!(
        csv.contains("import[0].pair_history_file = \"p.dump\"")
            && csv.contains("only used with format = \"liggghts_dump\""),
        "{csv}"
    );
}
