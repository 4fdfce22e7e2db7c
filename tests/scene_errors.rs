//! Bad scenes are rejected before the run with a message naming the key, the value and the reason;
//! every shipped scene loads. Each bad case changes one thing in a valid base scene.

use am_sim::scene::Scene;

const BASE: &str = r#"
[scene]
version = 1
[simulation]
dt_s = 1e-6
duration_s = 1e-3
gravity_m_s2 = [0.0, 0.0, -9.81]
[materials.steel]
density_kg_m3 = 7800
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
[contact]
model = "hertz"
damping_ratio = 0.2
[bond]
adhesion_exponent = 1.0
equilibrium_overlap_m = 1e-6
damping_ratio = 0.5
criterion = "always"
[[particles]]
position_m = [0.0, 0.0, 2e-5]
radius_m = 1.5e-5
material = "steel"
[[lattice]]
min_corner_m = [0.0, 0.0, 1e-4]
max_corner_m = [1e-4, 1e-4, 2e-4]
radius_m = 1.5e-5
material = "steel"
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "steel"
[output]
every_steps = 10
"#;

/// `(replace this, with this, every fragment the message must contain)`.
const CASES: &[(&str, &str, &[&str])] = &[
    // Syntax and types: the parser's message with the key path and the line.
    ("dt_s = 1e-6", "dt_s = 1e-6 +", &["line 5"]),
    (
        "radius_m = 1.5e-5\nmaterial",
        "radius_m = \"15 um\"\nmaterial",
        &[
            "particles[0].radius_m",
            "invalid type: string \"15 um\"",
            "expected f64",
        ],
    ),
    (
        "dt_s = 1e-6",
        "dt_s = [1e-6]",
        &["simulation.dt_s", "invalid type"],
    ),
    (
        "duration_s = 1e-3",
        "",
        &["simulation", "missing field `duration_s`"],
    ),
    // Unknown keys, in every table, and typos in every enum.
    (
        "damping_ratio = 0.2",
        "damping_ratio = 0.2\ndampng = 1",
        &["contact.dampng", "unknown field `dampng`"],
    ),
    (
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.3\nposson = 0.3",
        &["materials.steel.posson", "unknown field"],
    ),
    ("[output]", "[outptu]", &["unknown field `outptu`"]),
    (
        "model = \"hertz\"",
        "model = \"hooke\"",
        &[
            "contact.model",
            "unknown variant `hooke`",
            "expected `hertz`",
        ],
    ),
    (
        "criterion = \"always\"",
        "criterion = \"melted\"",
        &[
            "bond.criterion",
            "unknown variant `melted`",
            "`always`, `never`, `melting`",
        ],
    ),
    (
        "criterion = \"always\"",
        "criterion = \"always\"\nk_adh = 1e5",
        &["bond.k_adh", "unknown field"],
    ),
    // Values out of range: key = value: reason.
    (
        "dt_s = 1e-6",
        "dt_s = 0.0",
        &["simulation.dt_s = 0: must be > 0"],
    ),
    (
        "dt_s = 1e-6",
        "dt_s = -1e-6",
        &["simulation.dt_s = -0.000001: must be > 0"],
    ),
    (
        "duration_s = 1e-3",
        "duration_s = 1e9",
        &[
            "simulation.duration_s = 1000000000",
            "steps",
            "check the units",
        ],
    ),
    (
        "radius_m = 1.5e-5\nmaterial",
        "radius_m = -1.5e-5\nmaterial",
        &["particles[0].radius_m = -0.000015: must be > 0"],
    ),
    (
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.5",
        &["materials.steel.poisson_ratio = 0.5: must be in (-1, 0.5)"],
    ),
    (
        "youngs_modulus_pa = 2e8",
        "youngs_modulus_pa = nan",
        &["materials.steel.youngs_modulus_pa = NaN: must be a finite number"],
    ),
    (
        "damping_ratio = 0.2",
        "damping_ratio = -0.2",
        &["contact.damping_ratio = -0.2: must be ≥ 0"],
    ),
    (
        "damping_ratio = 0.2",
        "damping_ratio = 0.2\nrestitution = 0.5",
        &[
            "contact.restitution = given together with contact.damping_ratio",
            "exactly one",
        ],
    ),
    (
        "damping_ratio = 0.2",
        "model2 = 1",
        &["contact.model2", "unknown field"],
    ),
    (
        "damping_ratio = 0.2",
        "friction_coefficient = 0.5",
        &["contact = neither damping_ratio nor restitution: give exactly one of them"],
    ),
    (
        "damping_ratio = 0.2",
        "restitution = 0.0",
        &["contact.restitution = 0: must be in (0, 1]"],
    ),
    (
        "damping_ratio = 0.2",
        "restitution = 1.5",
        &["contact.restitution = 1.5: must be in (0, 1]"],
    ),
    (
        "damping_ratio = 0.2",
        "damping_ratio = 0.2\nfriction_coefficient = -0.5",
        &["contact.friction_coefficient = -0.5: must be ≥ 0"],
    ),
    (
        "damping_ratio = 0.2",
        "damping_ratio = 0.2\nrolling_friction_coefficient = nan",
        &["contact.rolling_friction_coefficient = NaN: must be a finite number"],
    ),
    (
        "adhesion_exponent = 1.0",
        "adhesion_exponent = 1.5",
        &[
            "bond.adhesion_exponent = 1.5",
            "below the Hertz exponent 3/2",
            "eq. 9",
        ],
    ),
    (
        "adhesion_exponent = 1.0",
        "adhesion_exponent = -0.1",
        &["bond.adhesion_exponent = -0.1: must be in [0, 1.5)"],
    ),
    (
        "equilibrium_overlap_m = 1e-6",
        "equilibrium_overlap_m = 1e-6\nadhesion_stiffness = 1e5",
        &["bond.adhesion_stiffness", "exactly one"],
    ),
    (
        "equilibrium_overlap_m = 1e-6",
        "",
        &["bond = neither adhesion_stiffness nor equilibrium_overlap_m"],
    ),
    (
        "equilibrium_overlap_m = 1e-6",
        "adhesion_stiffness = 1e5\nreference_radius_m = 1e-5",
        &["bond.reference_radius_m = 0.00001: only used with bond.equilibrium_overlap_m"],
    ),
    (
        "radius_m = 1.5e-5\nmaterial",
        "radius_m = 2e-5\nmaterial",
        &["bond.reference_radius_m = missing", "radii differ"],
    ),
    (
        "material = \"steel\"\n[[lattice]]",
        "material = \"inconel\"\n[[lattice]]",
        &[
            "particles[0].material = \"inconel\": no such material",
            "[\"steel\"]",
        ],
    ),
    (
        "normal = [0.0, 0.0, 1.0]",
        "normal = [0.0, 0.0, 0.0]",
        &["walls[0].normal", "zero vector"],
    ),
    (
        "max_corner_m = [1e-4, 1e-4, 2e-4]",
        "max_corner_m = [1e-4, 1e-4, 1.1e-4]",
        &[
            "lattice[0].max_corner_m",
            "thinner than one sphere diameter plus twice jitter_m along axis z",
        ],
    ),
    (
        "radius_m = 1.5e-5\nmaterial = \"steel\"\n[[walls]]",
        "radius_m = 1.5e-5\nspacing_m = 2.6e-5\nmaterial = \"steel\"\n[[walls]]",
        &[
            "lattice[0].spacing_m = 0.000026: must be ≥ 2.7000e-5",
            "initial overlaps",
        ],
    ),
    (
        "radius_m = 1.5e-5\nmaterial = \"steel\"\n[[walls]]",
        "radius_m = 1.5e-5\nspacing_m = 2.9e-5\njitter_m = 1e-7\nmaterial = \"steel\"\n[[walls]]",
        &["lattice[0].jitter_m = 0.0000001: must be 0 when spacing_m < 2 × radius_m"],
    ),
    (
        "radius_m = 1.5e-5\nmaterial = \"steel\"\n[[walls]]",
        "radius_m = 1.5e-5\nspacing_m = 3.2e-5\njitter_m = 2e-6\nmaterial = \"steel\"\n[[walls]]",
        &["lattice[0].jitter_m = 0.000002", "cannot overlap"],
    ),
    (
        "every_steps = 10",
        "every_steps = 0",
        &["output.every_steps = 0: must be ≥ 1"],
    ),
    (
        "version = 1",
        "version = 2",
        &["scene.version = 2", "version 1"],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nfields = [\"velocity\"]",
        &["output.fields[0] = \"velocity\": is always written"],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nfields = [\"temprature\"]",
        &[
            "output.fields[0] = \"temprature\": unknown field",
            "\"temperature\"",
        ],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nfields = [\"temperature\"]",
        &["output.fields[0] = \"temperature\": needs a [thermal] section"],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nfields = [\"bond_force\"]",
        &["output.fields = \"bond_force\": needs \"bonds\" in the list too"],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nevery_s = 1e-4",
        &["output.every_s = 0.0001: give either every_steps or every_s"],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\ndeflate = 10",
        &["output.deflate = 10: must be 0 (none) to 9"],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nfile = \"\"",
        &["output.file = \"\": must be a file name"],
    ),
];

/// Changes to BASE that give it a thermal model and a laser (valid).
fn thermal_base() -> String {
    BASE.replacen(
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.3\nspecific_heat_j_kg_k = 500\nthermal_conductivity_w_m_k = 20\nmelting_point_k = 1700\nemissivity = 0.4\nabsorptivity = 0.6",
        1,
    )
    .replacen("criterion = \"always\"", "criterion = \"melting\"\nmelting_rule = \"either\"", 1)
    .replacen("material = \"steel\"\n[output]", "material = \"steel\"\ntemperature_k = 300\n[output]", 1)
    .replacen(
        "[output]",
        "[thermal]\ninitial_temperature_k = 300\nconduction = \"batchelor_obrien\"\n[thermal.radiation]\nenvironment_temperature_k = 300\n\
         [laser]\npower_w = 50\nspot_radius_m = 4e-5\n[laser.path]\nkind = \"hatch\"\nstart_m = [0.0, 0.0]\ntrack_length_m = 1e-4\n\
         hatch_spacing_m = 3e-5\ntracks = 3\nspeed_m_s = 0.5\n[output]",
        1,
    )
}

/// Thermal and laser cases, applied to [`thermal_base`].
const THERMAL_CASES: &[(&str, &str, &[&str])] = &[
    // Evaporation (M.80): both keys or neither, above the melting point and the start.
    (
        "melting_point_k = 1700",
        "melting_point_k = 1700\nboiling_point_k = 1600\nlatent_heat_vaporization_j_kg = 6e6",
        &["materials.steel.boiling_point_k = 1600: must be above melting_point_k (1700 K)"],
    ),
    (
        "melting_point_k = 1700",
        "melting_point_k = 1700\nboiling_point_k = 3000",
        &["materials.steel.latent_heat_vaporization_j_kg = missing: needed by boiling_point_k"],
    ),
    (
        "melting_point_k = 1700",
        "melting_point_k = 1700\nlatent_heat_vaporization_j_kg = 6e6",
        &["materials.steel.latent_heat_vaporization_j_kg = 6000000: needs boiling_point_k"],
    ),
    (
        "melting_point_k = 1700",
        "melting_point_k = 1700\nboiling_point_k = 3000\nlatent_heat_vaporization_j_kg = -1",
        &["materials.steel.latent_heat_vaporization_j_kg = -1: must be > 0"],
    ),
    (
        "melting_point_k = 1700",
        "melting_point_k = 1700\nboiling_point_k = 250\nlatent_heat_vaporization_j_kg = 6e6",
        &[
            "materials.steel.boiling_point_k = 250: must be above melting_point_k",
            "thermal.initial_temperature_k = 300: is above materials.steel.boiling_point_k (250 K)",
        ],
    ),
    (
        "every_steps = 10",
        "every_steps = 10\nfields = [\"temperature\", \"evaporated_mass\"]",
        &[
            "output.fields[1] = \"evaporated_mass\": needs a [thermal] section and a material with boiling_point_k",
        ],
    ),
    (
        "conduction = \"batchelor_obrien\"",
        "conduction = \"batchelor\"",
        &[
            "thermal.conduction",
            "unknown variant `batchelor`",
            "`thermal_pipe`",
        ],
    ),
    (
        "conduction = \"batchelor_obrien\"",
        "",
        &["thermal", "missing field `conduction`"],
    ),
    (
        "kind = \"hatch\"",
        "kind = \"hatched\"",
        &[
            "laser.path",
            "unknown variant `hatched`",
            "`polyline`, `hatch`, `stationary`",
        ],
    ),
    (
        "tracks = 3",
        "tracks = 3\nlength = 1e-4",
        &["laser.path", "unknown field `length`"],
    ),
    (
        "tracks = 3",
        "tracks = 0",
        &["laser.path.tracks = 0: must be ≥ 1"],
    ),
    (
        "power_w = 50",
        "power_w = -50",
        &["laser.power_w = -50: must be > 0"],
    ),
    (
        "specific_heat_j_kg_k = 500\n",
        "",
        &["materials.steel.specific_heat_j_kg_k = missing: needed by [thermal]"],
    ),
    (
        "emissivity = 0.4",
        "emissivity = 1.4",
        &["materials.steel.emissivity = 1.4: must be in [0, 1]"],
    ),
    (
        "emissivity = 0.4\n",
        "",
        &["materials.steel.emissivity = missing: needed by [thermal.radiation]"],
    ),
    (
        "absorptivity = 0.6",
        "",
        &["materials.steel.absorptivity = missing: needed by [laser]"],
    ),
    (
        "initial_temperature_k = 300",
        "initial_temperature_k = 300\nsubstep_fraction = 1.5",
        &["thermal.substep_fraction = 1.5: must be in (0, 1]"],
    ),
    (
        "temperature_k = 300\n[thermal]",
        "temperature_k = -5\n[thermal]",
        &["walls[0].temperature_k = -5: must be > 0"],
    ),
    (
        "[thermal.radiation]",
        "[[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 1e-4]\nmax_corner_m = [inf, inf, inf]\ntemperature_k = 0\n[thermal.radiation]",
        &["thermal.initial_region[0].temperature_k = 0: must be > 0"],
    ),
    (
        "[thermal.radiation]",
        "[[thermal.initial_region]]\nmin_corner_m = [-inf, nan, 1e-4]\nmax_corner_m = [inf, inf, inf]\ntemperature_k = 1000\n[thermal.radiation]",
        &[
            "thermal.initial_region[0].min_corner_m = [-inf, NaN, 0.0001]: every component must be a number",
        ],
    ),
    (
        "[thermal.radiation]",
        "[[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 1e-4]\nmax_corner_m = [inf, inf, 1e-4]\ntemperature_k = 1000\n[thermal.radiation]",
        &[
            "thermal.initial_region[0].max_corner_m = [inf, inf, 0.0001]: must exceed min_corner_m = [-inf, -inf, 0.0001] along every axis",
        ],
    ),
    (
        "[thermal.radiation]",
        "[[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 1e-4]\nmax_corner_m = [inf, inf, inf]\ntemperature = 1000\n[thermal.radiation]",
        &["thermal.initial_region", "unknown field `temperature`"],
    ),
];

#[test]
fn the_base_scenes_are_valid() {
    Scene::from_toml(BASE).expect("base scene");
    Scene::from_toml(&thermal_base()).expect("thermal base scene");
}

/// An initial region may be unbounded along axes (TOML's `inf`), like LIGGGHTS' `INF`.
#[test]
fn an_initial_region_with_infinite_bounds_is_valid() {
    let text = thermal_base().replacen("[thermal.radiation]", "[[thermal.initial_region]]\nmin_corner_m = [-inf, -inf, 1e-4]\nmax_corner_m = [inf, inf, inf]\ntemperature_k = 1000\n[thermal.radiation]", 1);
    Scene::from_toml(&text).expect("scene with an initial region");
}

#[test]
fn every_bad_thermal_scene_is_rejected_with_key_value_and_reason() {
    check_cases(&thermal_base(), THERMAL_CASES);
}

#[test]
fn thermal_physics_without_a_thermal_section_is_refused_with_both_keys_named() {
    let text = thermal_base();
    let start = text.find("[thermal]").unwrap();
    let end = text.find("[laser]").unwrap();
    let without = format!("{}{}", &text[..start], &text[end..]);
    let message = Scene::from_toml(&without).unwrap_err().to_string();
    for fragment in [
        "bond.criterion = \"melting\": needs a [thermal] section",
        "laser = [laser]: needs a [thermal] section",
        "walls[0].temperature_k = 300: needs a [thermal] section",
    ] {
        assert!(message.contains(fragment), "lacks {fragment:?}:\n{message}");
    }
    let rule_without_melting = BASE.replacen(
        "criterion = \"always\"",
        "criterion = \"always\"\nmelting_rule = \"both\"",
        1,
    );
    let message = Scene::from_toml(&rule_without_melting)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("bond.melting_rule")
            && message.contains("only used with bond.criterion = \"melting\""),
        "{message}"
    );
}

/// Applies each `(from, to, fragments)` case to `base` and checks that the scene is refused with
/// every fragment in the message.
fn check_cases(base: &str, cases: &[(&str, &str, &[&str])]) {
    for (from, to, fragments) in cases {
        assert!(base.contains(from), "case does not apply: {from:?}");
        let message = match Scene::from_toml(&base.replacen(from, to, 1)) {
            Ok(_) => panic!("accepted a bad scene ({from:?} → {to:?})"),
            Err(e) => e.to_string(),
        };
        for fragment in *fragments {
            assert!(
                message.contains(fragment),
                "({from:?} → {to:?}): message lacks {fragment:?}:\n{message}"
            );
        }
    }
}

#[test]
fn every_bad_scene_is_rejected_with_key_value_and_reason() {
    check_cases(BASE, CASES);
}

#[test]
fn a_jitter_at_exactly_its_limit_is_accepted() {
    // (spacing − 2r)/2 = (4.4e-5 − 3e-5)/2 = 7e-6 up to round-off.
    let text = BASE.replacen(
        "radius_m = 1.5e-5\nmaterial = \"steel\"\n[[walls]]",
        "radius_m = 1.5e-5\nspacing_m = 4.4e-5\njitter_m = 7e-6\nmaterial = \"steel\"\n[[walls]]",
        1,
    );
    let text = text.replace(
        "max_corner_m = [1e-4, 1e-4, 2e-4]",
        "max_corner_m = [2e-4, 2e-4, 2e-4]",
    );
    Scene::from_toml(&text).expect("jitter at the limit");
}

#[test]
fn a_bad_radius_is_reported_once_on_its_own_key() {
    let text = BASE.replacen(
        "radius_m = 1.5e-5\nmaterial",
        "radius_m = -1.5e-5\nmaterial",
        1,
    );
    let keys: Vec<String> = Scene::from_toml(&text)
        .unwrap_err()
        .violations()
        .iter()
        .map(|v| v.key.clone())
        .collect();
    assert_eq!(keys, ["particles[0].radius_m"]);
}

#[test]
fn all_violations_are_reported_at_once() {
    let text = BASE.replacen("dt_s = 1e-6", "dt_s = -1.0", 1).replacen(
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.7",
        1,
    );
    let err = Scene::from_toml(&text).unwrap_err();
    let keys: Vec<&str> = err.violations().iter().map(|v| v.key.as_str()).collect();
    assert_eq!(keys, ["simulation.dt_s", "materials.steel.poisson_ratio"]);
}

#[test]
fn every_shipped_scene_loads() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let mut count = 0;
    for entry in std::fs::read_dir(dir).expect("scenes/") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "toml") {
            Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            count += 1;
        }
    }
    assert!(count >= 3, "found {count} scenes");
}

#[test]
fn a_missing_file_names_the_file() {
    let err = Scene::load(std::path::Path::new("no/such/scene.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("no/such/scene.toml"), "{err}");
}

/// BASE without the bond (its δ_eq needs a reference radius with generated beds), plus an
/// insertion, an import and a deposition (valid; the import file is read only when built).
fn bed_base() -> String {
    let start = BASE.find("[bond]").unwrap();
    let end = BASE.find("[[particles]]").unwrap();
    format!(
        "{}{}",
        &BASE[..start],
        &BASE[end..].replacen(
            "[[walls]]",
            "[[insert]]\nmin_corner_m = [0.0, 0.0, 3e-4]\nmax_corner_m = [4e-4, 4e-4, 6e-4]\n\
             count = 100\nseed = 1\nmaterial = \"steel\"\n[insert.size]\ndistribution = \"lognormal\"\n\
             d10_m = 2e-5\nd50_m = 3e-5\nd90_m = 4.5e-5\nmin_m = 1.5e-5\nmax_m = 6e-5\n\
             [[import]]\nfile = \"data/bed.dump.gz\"\nformat = \"liggghts_dump\"\nmaterial = \"steel\"\n\
             [deposition]\nmax_duration_s = 0.05\n[[walls]]",
            1,
        )
    )
}

/// Bed-generation cases, applied to [`bed_base`].
const BED_CASES: &[(&str, &str, &[&str])] = &[
    (
        "distribution = \"lognormal\"",
        "distribution = \"weibull\"",
        &["insert[0].size.distribution", "unknown variant `weibull`"],
    ),
    (
        "count = 100",
        "count = 100\nsolid_fraction = 0.3",
        &["insert[0].solid_fraction = 0.3: give either count or solid_fraction, not both"],
    ),
    (
        "count = 100",
        "",
        &["insert[0] = neither count nor solid_fraction: give one of them"],
    ),
    (
        "count = 100",
        "solid_fraction = 0.9",
        &["insert[0].solid_fraction = 0.9: must be in (0, 0.74]"],
    ),
    (
        "d50_m = 3e-5",
        "d50_m = 5e-5",
        &[
            "insert[0].size.d50_m = 0.00005 (d10_m = 0.00002, d90_m = 0.000045): must satisfy d10_m < d50_m < d90_m",
        ],
    ),
    (
        "d90_m = 4.5e-5",
        "",
        &["insert[0].size.d90_m = missing: d10_m, d50_m and d90_m go together"],
    ),
    (
        "d10_m = 2e-5",
        "mean_m = 3e-5\nd10_m = 2e-5",
        &["insert[0].size.mean_m = given together with d10_m/d50_m/d90_m"],
    ),
    (
        "max_m = 6e-5",
        "max_m = 1.2e-5",
        &["insert[0].size.max_m = 0.000012: must be > min_m = 0.000015"],
    ),
    (
        "min_m = 1.5e-5\nmax_m = 6e-5",
        "min_m = 1e-4",
        &[
            "insert[0].size = min_m = Some(0.0001), max_m = None",
            "of the distribution lies in [min_m, max_m]",
        ],
    ),
    (
        "distribution = \"lognormal\"",
        "distribution = \"constant\"",
        &[
            "insert[0].size.diameter_m = missing",
            "insert[0].size.d10_m = 0.00002: not used with distribution = \"constant\"",
        ],
    ),
    (
        "max_corner_m = [4e-4, 4e-4, 6e-4]",
        "max_corner_m = [4e-4, 4e-4, 2e-4]",
        &["insert[0].max_corner_m = [0.0004, 0.0004, 0.0002]: must exceed min_corner_m"],
    ),
    (
        "format = \"liggghts_dump\"",
        "format = \"xyz\"",
        &[
            "import[0].format",
            "unknown variant `xyz`",
            "`csv`, `liggghts_dump`, `am_sim_h5`",
        ],
    ),
    (
        "format = \"liggghts_dump\"\nmaterial = \"steel\"",
        "format = \"liggghts_dump\"",
        &["import[0].material = missing: needed: only a CSV file can name materials"],
    ),
    (
        "format = \"liggghts_dump\"",
        "format = \"liggghts_dump\"\nframe = 3\nscale = 0",
        &[
            "import[0].frame = 3: only used with format = \"am_sim_h5\"",
            "import[0].scale = 0: must be > 0",
        ],
    ),
    (
        "max_duration_s = 0.05",
        "max_duration_s = 0.05\nkinetic_energy_ratio = -1\ncheck_every_steps = 0",
        &[
            "deposition.kinetic_energy_ratio = -1: must be > 0",
            "deposition.check_every_steps = 0: must be ≥ 1",
        ],
    ),
    (
        "gravity_m_s2 = [0.0, 0.0, -9.81]",
        "gravity_m_s2 = [0.0, 0.0, 0.0]",
        &["deposition = [deposition]: needs simulation.gravity_m_s2 ≠ 0"],
    ),
    (
        "max_duration_s = 0.05",
        "max_duration_s = 0.05\ntimeout = 1",
        &["deposition.timeout", "unknown field"],
    ),
];

#[test]
fn every_bad_bed_generation_scene_is_rejected_with_key_value_and_reason() {
    Scene::from_toml(&bed_base()).expect("bed base scene");
    check_cases(&bed_base(), BED_CASES);
}

#[test]
fn a_bond_overlap_with_generated_radii_needs_a_reference_radius() {
    let text = BASE.replacen(
        "[[walls]]",
        "[[insert]]\nmin_corner_m = [0.0, 0.0, 3e-4]\nmax_corner_m = [4e-4, 4e-4, 6e-4]\ncount = 10\n\
         material = \"steel\"\n[insert.size]\ndistribution = \"constant\"\ndiameter_m = 3e-5\n[[walls]]",
        1,
    );
    let message = Scene::from_toml(&text).unwrap_err().to_string();
    assert!(
        message.contains(
            "bond.reference_radius_m = missing: the radii of [[insert]] and [[import]] particles"
        ),
        "{message}"
    );
}
