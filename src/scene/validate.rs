//! Second phase of scene loading: ranges and cross-field rules on the deserialized [`Scene`].
//! Every violation is collected (not just the first), each naming key, value and reason.

use super::{
    DepositionConfig, DistributionKind, FORMAT_VERSION, ImportConfig, ImportFormat, InsertConfig,
    Scene, SizeConfig, Violation,
};
use crate::bed::psd::{Psd, Shape};

/// Largest number of particles a scene may generate (guards against a unit slip in a lattice box).
pub const MAX_PARTICLES: u64 = 100_000_000;
/// Largest initial overlap a lattice may be built with, as a fraction of the radius.
pub const MAX_INITIAL_OVERLAP: f64 = 0.2;
/// Largest number of steps a run may take (guards against `dt_s` given in the wrong unit).
pub const MAX_STEPS: f64 = 1e12;

struct Checker {
    violations: Vec<Violation>,
}

impl Checker {
    fn fail(&mut self, key: impl Into<String>, value: impl ToString, reason: impl Into<String>) {
        self.violations.push(Violation {
            key: key.into(),
            value: value.to_string(),
            reason: reason.into(),
        });
    }

    fn finite(&mut self, key: &str, value: f64) -> bool {
        if value.is_finite() {
            true
        } else {
            self.fail(key, value, "must be a finite number");
            false
        }
    }

    fn positive(&mut self, key: &str, value: f64) {
        if self.finite(key, value) && value <= 0.0 {
            self.fail(key, value, "must be > 0");
        }
    }

    fn non_negative(&mut self, key: &str, value: f64) {
        if self.finite(key, value) && value < 0.0 {
            self.fail(key, value, "must be ≥ 0");
        }
    }

    fn finite_vector(&mut self, key: &str, value: [f64; 3]) {
        if value.iter().any(|c| !c.is_finite()) {
            self.fail(
                key,
                format!("{value:?}"),
                "every component must be a finite number",
            );
        }
    }

    /// A box's upper corner must exceed its lower corner (`min_name` = `min`) on every axis.
    fn corners_ordered(&mut self, max_key: &str, max: [f64; 3], min_name: &str, min: [f64; 3]) {
        if (0..3).any(|a| max[a] <= min[a]) {
            self.fail(
                max_key,
                format!("{max:?}"),
                format!("must exceed {min_name} = {min:?} along every axis"),
            );
        }
    }

    fn material(&mut self, scene: &Scene, key: &str, name: &str) {
        if !scene.materials.contains_key(name) {
            let known: Vec<&str> = scene.materials.keys().map(String::as_str).collect();
            self.fail(
                key,
                format!("\"{name}\""),
                format!("no such material; defined: {known:?}"),
            );
        }
    }
}

/// Number of lattice sites along one axis for an interval of `length`: spheres of `radius` with
/// centres `spacing` apart, every sphere fully inside even when displaced by up to `jitter`
/// (the first centre is at `radius + jitter` from the lower face).
#[must_use]
pub fn lattice_sites(length: f64, radius: f64, spacing: f64, jitter: f64) -> u64 {
    let free = length - 2.0 * (radius + jitter);
    if free < 0.0 {
        0
    } else {
        // The small tolerance keeps a box of exactly n spacings from losing its last row to round-off.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = (free / spacing * (1.0 + 1e-12)).floor() as u64;
        n + 1
    }
}

/// Returns every violation in `scene` (empty when the scene is valid).
#[must_use]
pub fn validate(scene: &Scene) -> Vec<Violation> {
    let mut c = Checker {
        violations: Vec::new(),
    };
    if scene.scene.version != FORMAT_VERSION {
        c.fail(
            "scene.version",
            scene.scene.version,
            format!("this am-sim reads scene format version {FORMAT_VERSION}"),
        );
    }

    let sim = &scene.simulation;
    c.positive("simulation.dt_s", sim.dt_s);
    c.positive("simulation.duration_s", sim.duration_s);
    if sim.dt_s > 0.0 && sim.duration_s > 0.0 && sim.duration_s / sim.dt_s > MAX_STEPS {
        c.fail(
            "simulation.duration_s",
            sim.duration_s,
            format!("gives {:.3e} steps of dt_s = {} (more than {MAX_STEPS:e}): check the units (seconds)", sim.duration_s / sim.dt_s, sim.dt_s),
        );
    }
    c.finite_vector("simulation.gravity_m_s2", sim.gravity_m_s2);
    if let Some(skin) = sim.skin_m {
        c.positive("simulation.skin_m", skin);
    }
    if let Some(speed) = sim.expected_impact_speed_m_s {
        c.positive("simulation.expected_impact_speed_m_s", speed);
    }

    if let Some(periodic) = &scene.periodic {
        let axes = periodic.axes();
        if axes.is_empty() {
            c.fail(
                "periodic",
                "{}",
                "give at least one of x_m, y_m, z_m (the bounds of a periodic axis)",
            );
        }
        let names = ["x", "y", "z"];
        for (key, axis, [lower, upper]) in axes {
            if lower.is_finite() && upper.is_finite() {
                if upper <= lower {
                    c.fail(
                        key,
                        format!("[{lower}, {upper}]"),
                        "the upper bound must exceed the lower",
                    );
                }
            } else {
                c.fail(
                    key,
                    format!("[{lower}, {upper}]"),
                    "both bounds must be finite numbers",
                );
            }
            if scene.simulation.gravity_m_s2[axis] != 0.0 {
                c.fail(
                    "simulation.gravity_m_s2",
                    format!("{:?}", scene.simulation.gravity_m_s2),
                    format!(
                        "has a component along the periodic axis {}: not supported (the gravitational energy would jump at every wrap)",
                        names[axis]
                    ),
                );
            }
            for (k, wall) in scene.walls.iter().enumerate() {
                if wall.normal[axis] != 0.0 {
                    c.fail(
                        format!("walls[{k}].normal"),
                        format!("{:?}", wall.normal),
                        format!(
                            "faces along the periodic axis {}: a wall across a periodic direction cuts the domain (remove it, or the axis from [periodic])",
                            names[axis]
                        ),
                    );
                }
            }
        }
    }

    if let Some(domain) = &scene.domain {
        c.finite_vector("domain.min_corner_m", domain.min_corner_m);
        c.finite_vector("domain.max_corner_m", domain.max_corner_m);
        c.corners_ordered(
            "domain.max_corner_m",
            domain.max_corner_m,
            "domain.min_corner_m",
            domain.min_corner_m,
        );
    }

    if let Some(guards) = &scene.guards {
        if let Some(ratio) = guards.max_overlap_ratio {
            c.positive("guards.max_overlap_ratio", ratio);
        }
        if let Some(residual) = guards.max_energy_residual {
            c.positive("guards.max_energy_residual", residual);
        }
    }

    if scene.materials.is_empty() {
        c.fail(
            "materials",
            "{}",
            "define at least one [materials.NAME] table",
        );
    }
    for (name, m) in &scene.materials {
        let key = |field: &str| format!("materials.{name}.{field}");
        c.positive(&key("density_kg_m3"), m.density_kg_m3);
        c.positive(&key("youngs_modulus_pa"), m.youngs_modulus_pa);
        if c.finite(&key("poisson_ratio"), m.poisson_ratio)
            && !(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5)
        {
            c.fail(
                key("poisson_ratio"),
                m.poisson_ratio,
                "must be in (-1, 0.5)",
            );
        }
    }

    validate_contact(&mut c, &scene.contact);

    if let Some(bond) = &scene.bond {
        validate_bond(&mut c, scene, bond);
    }

    let mut total: u64 = 0;
    for (k, p) in scene.particles.iter().enumerate() {
        let key = |field: &str| format!("particles[{k}].{field}");
        c.positive(&key("radius_m"), p.radius_m);
        c.finite_vector(&key("position_m"), p.position_m);
        c.finite_vector(&key("velocity_m_s"), p.velocity_m_s);
        c.material(scene, &key("material"), &p.material);
        total += 1;
    }
    let before_lattices = c.violations.len();
    for k in 0..scene.lattice.len() {
        total = total.saturating_add(validate_lattice(&mut c, scene, k));
    }
    for (k, insert) in scene.insert.iter().enumerate() {
        total = total.saturating_add(validate_insert(&mut c, scene, k, insert));
    }
    for (k, import) in scene.import.iter().enumerate() {
        validate_import(&mut c, scene, k, import);
    }
    if let Some(deposition) = &scene.deposition {
        validate_deposition(&mut c, scene, deposition);
    }
    // A lattice with a bad key counts no sites: do not add a misleading "no particles" on top.
    // Imported files are read when the scene is built; their particle count is not known here.
    if total == 0 && c.violations.len() == before_lattices && scene.import.is_empty() {
        c.fail("particles", "[]", "the scene has no particles: add [[particles]] or a [[lattice]] that fits at least one sphere");
    }
    if total > MAX_PARTICLES {
        c.fail(
            "lattice",
            total,
            format!("more than {MAX_PARTICLES} particles: check the units (metres)"),
        );
    }

    for (k, w) in scene.walls.iter().enumerate() {
        c.finite_vector(&format!("walls[{k}].point_m"), w.point_m);
        c.finite_vector(&format!("walls[{k}].normal"), w.normal);
        let length = w.normal.iter().map(|x| x * x).sum::<f64>().sqrt();
        if length.is_finite() && length == 0.0 {
            c.fail(
                format!("walls[{k}].normal"),
                format!("{:?}", w.normal),
                "must not be the zero vector",
            );
        }
        c.material(scene, &format!("walls[{k}].material"), &w.material);
    }

    validate_thermal(&mut c, scene);
    validate_laser(&mut c, scene);

    if let Some(out) = &scene.output {
        validate_output(&mut c, scene, out);
    }
    c.violations
}

fn validate_contact(c: &mut Checker, contact: &super::ContactConfig) {
    match (contact.damping_ratio, contact.restitution) {
        (Some(_), Some(_)) => c.fail(
            "contact.restitution",
            "given together with contact.damping_ratio",
            "give exactly one of them: restitution is converted to damping_ratio (docs/model.md M.55)",
        ),
        (None, None) => c.fail(
            "contact",
            "neither damping_ratio nor restitution",
            "give exactly one of them",
        ),
        (Some(xi), None) => c.non_negative("contact.damping_ratio", xi),
        (None, Some(e)) => {
            if c.finite("contact.restitution", e) && !(e > 0.0 && e <= 1.0) {
                c.fail("contact.restitution", e, "must be in (0, 1]");
            }
        }
    }
    if let Some(mu) = contact.friction_coefficient {
        c.non_negative("contact.friction_coefficient", mu);
    }
    if let Some(mu_r) = contact.rolling_friction_coefficient {
        c.non_negative("contact.rolling_friction_coefficient", mu_r);
    }
}

fn validate_bond(c: &mut Checker, scene: &Scene, bond: &super::BondConfig) {
    let alpha = bond.adhesion_exponent;
    if c.finite("bond.adhesion_exponent", alpha) && !(0.0..1.5).contains(&alpha) {
        c.fail(
            "bond.adhesion_exponent",
            alpha,
            "must be in [0, 1.5): the bond is stable only if the adhesion exponent is below the Hertz exponent 3/2 (paper eq. 9)",
        );
    }
    c.non_negative("bond.damping_ratio", bond.damping_ratio);
    match (bond.adhesion_stiffness, bond.equilibrium_overlap_m) {
        (Some(_), Some(_)) => c.fail(
            "bond.adhesion_stiffness",
            "given together with bond.equilibrium_overlap_m",
            "give exactly one of them: the other is derived by paper eq. 13",
        ),
        (None, None) => c.fail(
            "bond",
            "neither adhesion_stiffness nor equilibrium_overlap_m",
            "give exactly one of them",
        ),
        (Some(k), None) => c.non_negative("bond.adhesion_stiffness", k),
        (None, Some(d)) => c.positive("bond.equilibrium_overlap_m", d),
    }
    match (bond.reference_radius_m, bond.equilibrium_overlap_m) {
        (Some(r), Some(_)) => c.positive("bond.reference_radius_m", r),
        (Some(r), None) => c.fail(
            "bond.reference_radius_m",
            r,
            "only used with bond.equilibrium_overlap_m",
        ),
        (None, Some(_)) if !scene.insert.is_empty() || !scene.import.is_empty() => c.fail(
            "bond.reference_radius_m",
            "missing",
            "the radii of [[insert]] and [[import]] particles are known only when the scene is built: say for which sphere radius equilibrium_overlap_m holds",
        ),
        (None, Some(_)) => {
            let radii = all_radii(scene);
            // Bad radii are reported on their own keys; compare only the valid ones.
            let valid = radii.iter().all(|r| r.is_finite() && *r > 0.0);
            if valid && radii.iter().any(|r| *r != radii[0]) {
                let (lo, hi) = radii.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), r| {
                    (lo.min(*r), hi.max(*r))
                });
                c.fail(
                    "bond.reference_radius_m",
                    "missing",
                    format!("particle radii differ ({lo} to {hi} m): say for which sphere radius equilibrium_overlap_m holds"),
                );
            }
        }
        (None, None) => {}
    }
}

/// The radius of every particle source (explicit particles and lattices), for rules that need it.
fn all_radii(scene: &Scene) -> Vec<f64> {
    scene
        .particles
        .iter()
        .map(|p| p.radius_m)
        .chain(scene.lattice.iter().map(|l| l.radius_m))
        .collect()
}

fn validate_lattice(c: &mut Checker, scene: &Scene, k: usize) -> u64 {
    let l = &scene.lattice[k];
    let key = |field: &str| format!("lattice[{k}].{field}");
    let before = c.violations.len();
    c.positive(&key("radius_m"), l.radius_m);
    c.finite_vector(&key("min_corner_m"), l.min_corner_m);
    c.finite_vector(&key("max_corner_m"), l.max_corner_m);
    c.finite_vector(&key("velocity_m_s"), l.velocity_m_s);
    c.non_negative(&key("jitter_m"), l.jitter_m);
    c.material(scene, &key("material"), &l.material);
    let spacing = l.spacing_m.unwrap_or(2.0 * l.radius_m);
    if let Some(s) = l.spacing_m {
        // Below 2r the lattice starts pre-compressed; an initial overlap beyond 20 % of the
        // radius stores so much elastic energy that the spheres fly apart.
        let closest = (2.0 - MAX_INITIAL_OVERLAP) * l.radius_m;
        // Relative tolerance: exactly 1.8 r must pass despite round-off.
        if c.finite(&key("spacing_m"), s) && s < closest * (1.0 - 1e-9) {
            c.fail(
                key("spacing_m"),
                s,
                format!(
                    "must be ≥ {closest:.4e} (2 × radius_m less {MAX_INITIAL_OVERLAP} × radius_m): larger initial overlaps blow the lattice apart"
                ),
            );
        }
        if s < 2.0 * l.radius_m && l.jitter_m > 0.0 {
            c.fail(
                key("jitter_m"),
                l.jitter_m,
                "must be 0 when spacing_m < 2 × radius_m (a pre-compressed lattice has no room for jitter)",
            );
        }
    }
    // Relative tolerance: a jitter of exactly the documented limit must pass despite round-off.
    if spacing >= 2.0 * l.radius_m
        && l.jitter_m > 0.0
        && l.jitter_m > (spacing - 2.0 * l.radius_m) / 2.0 * (1.0 + 1e-9)
    {
        c.fail(
            key("jitter_m"),
            l.jitter_m,
            format!(
                "must be ≤ (spacing_m − 2 radius_m)/2 = {} so that jittered spheres cannot overlap",
                (spacing - 2.0 * l.radius_m) / 2.0
            ),
        );
    }
    if c.violations.len() > before {
        return 0;
    }
    let mut count: u64 = 1;
    for axis in 0..3 {
        let n = lattice_sites(
            l.max_corner_m[axis] - l.min_corner_m[axis],
            l.radius_m,
            spacing,
            l.jitter_m,
        );
        if n == 0 {
            c.fail(
                key("max_corner_m"),
                format!("{:?}", l.max_corner_m),
                format!(
                    "the box is thinner than one sphere diameter plus twice jitter_m along axis {}",
                    ["x", "y", "z"][axis]
                ),
            );
        }
        count = count.saturating_mul(n);
    }
    count
}

/// `[thermal]`, the thermal keys of materials and walls, and the melting criterion.
fn validate_thermal(c: &mut Checker, scene: &Scene) {
    let melting = scene
        .bond
        .as_ref()
        .is_some_and(|b| b.criterion == super::CriterionConfig::Melting);
    if let Some(bond) = &scene.bond {
        if bond.melting_rule.is_some() && !melting {
            c.fail(
                "bond.melting_rule",
                match bond.melting_rule {
                    Some(super::MeltingRule::Either) => "\"either\"",
                    _ => "\"both\"",
                },
                "only used with bond.criterion = \"melting\"",
            );
        }
    }
    let Some(thermal) = &scene.thermal else {
        if melting {
            c.fail(
                "bond.criterion",
                "\"melting\"",
                "needs a [thermal] section: particles have no temperature without it",
            );
        }
        if scene.laser.is_some() {
            c.fail(
                "laser",
                "[laser]",
                "needs a [thermal] section: the absorbed power heats particles",
            );
        }
        for (k, w) in scene.walls.iter().enumerate() {
            if let Some(t) = w.temperature_k {
                c.fail(
                    format!("walls[{k}].temperature_k"),
                    t,
                    "needs a [thermal] section",
                );
            }
        }
        return;
    };
    c.positive(
        "thermal.initial_temperature_k",
        thermal.initial_temperature_k,
    );
    for (k, region) in thermal.initial_region.iter().enumerate() {
        let key = |name: &str| format!("thermal.initial_region[{k}].{name}");
        c.positive(&key("temperature_k"), region.temperature_k);
        for (name, corner) in [
            ("min_corner_m", region.min_corner_m),
            ("max_corner_m", region.max_corner_m),
        ] {
            if corner.iter().any(|x| x.is_nan()) {
                c.fail(
                    key(name),
                    format!("{corner:?}"),
                    "every component must be a number (±inf leaves an axis unbounded)",
                );
            }
        }
        c.corners_ordered(
            &key("max_corner_m"),
            region.max_corner_m,
            "min_corner_m",
            region.min_corner_m,
        );
    }
    if let Some(theta) = thermal.substep_fraction {
        if c.finite("thermal.substep_fraction", theta) && !(theta > 0.0 && theta <= 1.0) {
            c.fail(
                "thermal.substep_fraction",
                theta,
                "must be in (0, 1]: above 1 the explicit substeps lose the maximum principle",
            );
        }
    }
    if let Some(conv) = &thermal.convection {
        c.non_negative(
            "thermal.convection.heat_transfer_coefficient_w_m2_k",
            conv.heat_transfer_coefficient_w_m2_k,
        );
        c.positive(
            "thermal.convection.gas_temperature_k",
            conv.gas_temperature_k,
        );
    }
    if let Some(rad) = &thermal.radiation {
        c.non_negative(
            "thermal.radiation.environment_temperature_k",
            rad.environment_temperature_k,
        );
    }
    for (k, w) in scene.walls.iter().enumerate() {
        if let Some(t) = w.temperature_k {
            c.positive(&format!("walls[{k}].temperature_k"), t);
        }
    }
    for (name, m) in &scene.materials {
        let key = |field: &str| format!("materials.{name}.{field}");
        let required = |c: &mut Checker, field: &str, value: Option<f64>, why: &str| match value {
            Some(v) => c.positive(&key(field), v),
            None => c.fail(key(field), "missing", format!("needed {why}")),
        };
        required(
            c,
            "specific_heat_j_kg_k",
            m.specific_heat_j_kg_k,
            "by [thermal]",
        );
        required(
            c,
            "thermal_conductivity_w_m_k",
            m.thermal_conductivity_w_m_k,
            "by [thermal]",
        );
        required(c, "melting_point_k", m.melting_point_k, "by [thermal]");
        if let Some(l) = m.latent_heat_j_kg {
            c.non_negative(&key("latent_heat_j_kg"), l);
        }
        // Evaporation (M.80): both keys or neither; the boiling point above the melting point and
        // the temperatures the run starts from.
        match (m.boiling_point_k, m.latent_heat_vaporization_j_kg) {
            (Some(boiling), latent) => {
                c.positive(&key("boiling_point_k"), boiling);
                let melting = m.melting_point_k.unwrap_or(0.0);
                if boiling.is_finite() && boiling <= melting {
                    c.fail(
                        key("boiling_point_k"),
                        boiling,
                        format!("must be above melting_point_k ({melting} K)"),
                    );
                }
                let starts = std::iter::once((
                    "thermal.initial_temperature_k".to_string(),
                    thermal.initial_temperature_k,
                ))
                .chain(thermal.initial_region.iter().enumerate().map(|(k, r)| {
                    (
                        format!("thermal.initial_region[{k}].temperature_k"),
                        r.temperature_k,
                    )
                }));
                for (start_key, start) in starts {
                    if boiling.is_finite() && start > boiling {
                        c.fail(
                            start_key,
                            start,
                            format!(
                                "is above {} ({boiling} K): the run would start by evaporating",
                                key("boiling_point_k")
                            ),
                        );
                    }
                }
                match latent {
                    Some(l) => c.positive(&key("latent_heat_vaporization_j_kg"), l),
                    None => c.fail(
                        key("latent_heat_vaporization_j_kg"),
                        "missing",
                        "needed by boiling_point_k (the evaporated mass is the heat carried off over it)",
                    ),
                }
            }
            (None, Some(l)) => c.fail(
                key("latent_heat_vaporization_j_kg"),
                l,
                "needs boiling_point_k (where the material evaporates)",
            ),
            (None, None) => {}
        }
        let fraction =
            |c: &mut Checker, field: &str, value: Option<f64>, needed: bool, why: &str| match value
            {
                Some(v) if c.finite(&key(field), v) && !(0.0..=1.0).contains(&v) => {
                    c.fail(key(field), v, "must be in [0, 1]");
                }
                Some(_) => {}
                None if needed => c.fail(key(field), "missing", format!("needed by {why}")),
                None => {}
            };
        fraction(
            c,
            "emissivity",
            m.emissivity,
            thermal.radiation.is_some(),
            "[thermal.radiation]",
        );
        fraction(
            c,
            "absorptivity",
            m.absorptivity,
            scene.laser.is_some(),
            "[laser]",
        );
    }
}

/// `[laser]` and its path.
fn validate_laser(c: &mut Checker, scene: &Scene) {
    let Some(laser) = &scene.laser else { return };
    c.positive("laser.power_w", laser.power_w);
    c.positive("laser.spot_radius_m", laser.spot_radius_m);
    c.non_negative("laser.start_time_s", laser.start_time_s);
    if let Some(h) = laser.raster_cell_m {
        c.positive("laser.raster_cell_m", h);
        if h > 0.0 && laser.spot_radius_m > 0.0 && 6.0 * laser.spot_radius_m / h > 4096.0 {
            c.fail("laser.raster_cell_m", h, format!("gives more than 4096 × 4096 rays over the ±3w window of the spot ({} m): use a larger cell", laser.spot_radius_m));
        }
    }
    match &laser.path {
        super::PathConfig::Polyline {
            points_m,
            speed_m_s,
        } => {
            if points_m.len() < 2 {
                c.fail(
                    "laser.path.points_m",
                    format!("{points_m:?}"),
                    "needs at least two points",
                );
            }
            for (k, p) in points_m.iter().enumerate() {
                if p.iter().any(|x| !x.is_finite()) {
                    c.fail(
                        format!("laser.path.points_m[{k}]"),
                        format!("{p:?}"),
                        "every component must be a finite number",
                    );
                }
            }
            c.positive("laser.path.speed_m_s", *speed_m_s);
        }
        super::PathConfig::Hatch {
            start_m,
            track_length_m,
            hatch_spacing_m,
            tracks,
            speed_m_s,
            jump_time_s,
            ..
        } => {
            if start_m.iter().any(|x| !x.is_finite()) {
                c.fail(
                    "laser.path.start_m",
                    format!("{start_m:?}"),
                    "every component must be a finite number",
                );
            }
            c.positive("laser.path.track_length_m", *track_length_m);
            c.positive("laser.path.hatch_spacing_m", *hatch_spacing_m);
            if *tracks == 0 {
                c.fail("laser.path.tracks", 0, "must be ≥ 1");
            }
            c.positive("laser.path.speed_m_s", *speed_m_s);
            c.non_negative("laser.path.jump_time_s", *jump_time_s);
        }
        super::PathConfig::Stationary {
            position_m,
            duration_s,
        } => {
            if position_m.iter().any(|x| !x.is_finite()) {
                c.fail(
                    "laser.path.position_m",
                    format!("{position_m:?}"),
                    "every component must be a finite number",
                );
            }
            c.positive("laser.path.duration_s", *duration_s);
        }
    }
}

/// `[output]`: cadence, fields (known, and available in this scene), compression, files.
fn validate_output(c: &mut Checker, scene: &Scene, out: &super::OutputConfig) {
    use crate::output::frame::{Needs, OptionalField};
    if out.every_steps == Some(0) {
        c.fail("output.every_steps", 0, "must be ≥ 1");
    }
    if out.series_every_steps == Some(0) {
        c.fail("output.series_every_steps", 0, "must be ≥ 1");
    }
    if let Some(every) = out.every_s {
        c.positive("output.every_s", every);
        if out.every_steps.is_some() {
            c.fail(
                "output.every_s",
                every,
                "give either every_steps or every_s, not both",
            );
        }
    }
    for (key, value) in [
        ("output.series_csv", &out.series_csv),
        ("output.file", &out.file),
    ] {
        if value.as_deref() == Some("") {
            c.fail(key, "\"\"", "must be a file name");
        }
    }
    if cfg!(not(feature = "hdf5")) {
        if let Some(file) = &out.file {
            c.fail(
                "output.file",
                format!("\"{file}\""),
                "this am-sim was built without HDF5 (cargo feature `hdf5`)",
            );
        }
    }
    if out.deflate.is_some_and(|d| d > 9) {
        c.fail(
            "output.deflate",
            out.deflate.unwrap_or_default(),
            "must be 0 (none) to 9 (smallest)",
        );
    }
    let known: Vec<&str> = OptionalField::ALL.iter().map(|f| f.name()).collect();
    for (k, name) in out.fields.iter().flatten().enumerate() {
        let key = format!("output.fields[{k}]");
        match OptionalField::from_name(name) {
            None if ["id", "position", "velocity", "radius"].contains(&name.as_str()) => {
                c.fail(
                    key,
                    format!("\"{name}\""),
                    "is always written: list only optional fields",
                );
            }
            None => c.fail(
                key,
                format!("\"{name}\""),
                format!("unknown field; optional fields: {known:?}"),
            ),
            Some(field) => match field.needs() {
                Needs::Bond if scene.bond.is_none() => {
                    c.fail(key, format!("\"{name}\""), "needs a [bond] section")
                }
                Needs::Thermal if scene.thermal.is_none() => {
                    c.fail(key, format!("\"{name}\""), "needs a [thermal] section")
                }
                Needs::Evaporation if !scene.has_evaporation() => c.fail(
                    key,
                    format!("\"{name}\""),
                    "needs a [thermal] section and a material with boiling_point_k",
                ),
                Needs::Rotation if !scene.contact.has_rotation() => c.fail(
                    key,
                    format!("\"{name}\""),
                    "needs contact.friction_coefficient or contact.rolling_friction_coefficient",
                ),
                _ => {}
            },
        }
    }
    let listed = |f: OptionalField| {
        out.fields
            .as_ref()
            .is_some_and(|v| v.iter().any(|n| n == f.name()))
    };
    for f in [OptionalField::BondOverlap, OptionalField::BondForce] {
        if listed(f) && !listed(OptionalField::Bonds) {
            c.fail(
                "output.fields",
                format!("\"{}\"", f.name()),
                "needs \"bonds\" in the list too (its rows follow the bond list)",
            );
        }
    }
}

/// Smallest probability that a diameter drawn from an untruncated distribution falls inside
/// `[min_m, max_m]`: below it, truncation by redrawing would take over 1000 draws per sphere.
pub const MIN_KEPT_FRACTION: f64 = 1e-3;

/// The diameter distribution of `[insert.size]`, or `None` if its keys do not define one
/// (`validate` reports why).
#[must_use]
pub fn size_distribution(size: &SizeConfig) -> Option<Psd> {
    let shape = match size.distribution {
        DistributionKind::Constant => return size.diameter_m.map(Psd::constant),
        DistributionKind::Normal => Shape::Normal,
        DistributionKind::Lognormal => Shape::LogNormal,
    };
    let psd = match (size.mean_m, size.std_m, size.d10_m, size.d50_m, size.d90_m) {
        (Some(mean), Some(std), None, None, None) if shape == Shape::Normal => {
            Psd::normal(mean, std)
        }
        (Some(mean), Some(std), None, None, None) => Psd::lognormal_from_moments(mean, std),
        (None, None, Some(d10), Some(d50), Some(d90)) => Psd::from_quantiles(shape, d10, d50, d90),
        _ => return None,
    };
    Some(psd.truncated(
        size.min_m.unwrap_or(0.0),
        size.max_m.unwrap_or(f64::INFINITY),
    ))
}

fn validate_size(c: &mut Checker, prefix: &str, size: &SizeConfig) -> Option<Psd> {
    let key = |field: &str| format!("{prefix}.{field}");
    let before = c.violations.len();
    let given = |v: Option<f64>| v.is_some();
    if size.distribution == DistributionKind::Constant {
        match size.diameter_m {
            Some(d) => c.positive(&key("diameter_m"), d),
            None => c.fail(
                key("diameter_m"),
                "missing",
                "needed by distribution = \"constant\"",
            ),
        }
        for (field, value) in [
            ("mean_m", size.mean_m),
            ("std_m", size.std_m),
            ("d10_m", size.d10_m),
            ("d50_m", size.d50_m),
            ("d90_m", size.d90_m),
            ("min_m", size.min_m),
            ("max_m", size.max_m),
        ] {
            if let Some(v) = value {
                c.fail(
                    key(field),
                    v,
                    "not used with distribution = \"constant\" (give diameter_m)",
                );
            }
        }
        return (c.violations.len() == before)
            .then(|| size_distribution(size))
            .flatten();
    }
    if let Some(d) = size.diameter_m {
        c.fail(
            key("diameter_m"),
            d,
            "only used with distribution = \"constant\"",
        );
    }
    let moments = given(size.mean_m) || given(size.std_m);
    let quantiles = given(size.d10_m) || given(size.d50_m) || given(size.d90_m);
    if moments && quantiles {
        c.fail(
            key("mean_m"),
            "given together with d10_m/d50_m/d90_m",
            "give either mean_m and std_m or d10_m, d50_m and d90_m",
        );
    } else if moments {
        for (field, value) in [("mean_m", size.mean_m), ("std_m", size.std_m)] {
            match value {
                Some(v) => c.positive(&key(field), v),
                None => c.fail(key(field), "missing", "mean_m and std_m go together"),
            }
        }
    } else if quantiles {
        for (field, value) in [
            ("d10_m", size.d10_m),
            ("d50_m", size.d50_m),
            ("d90_m", size.d90_m),
        ] {
            match value {
                Some(v) => c.positive(&key(field), v),
                None => c.fail(key(field), "missing", "d10_m, d50_m and d90_m go together"),
            }
        }
        if let (Some(d10), Some(d50), Some(d90)) = (size.d10_m, size.d50_m, size.d90_m) {
            if !(d10 < d50 && d50 < d90) {
                c.fail(
                    key("d50_m"),
                    format!("{d50} (d10_m = {d10}, d90_m = {d90})"),
                    "must satisfy d10_m < d50_m < d90_m",
                );
            }
        }
    } else {
        c.fail(
            prefix,
            "no size keys",
            "give mean_m and std_m, or d10_m, d50_m and d90_m (diameters)",
        );
    }
    if let Some(min) = size.min_m {
        c.non_negative(&key("min_m"), min);
    }
    if let Some(max) = size.max_m {
        c.positive(&key("max_m"), max);
        if let Some(min) = size.min_m {
            if min >= max {
                c.fail(key("max_m"), max, format!("must be > min_m = {min}"));
            }
        }
    }
    if c.violations.len() > before {
        return None;
    }
    let psd = size_distribution(size)?;
    let kept = psd.kept_fraction();
    if kept.is_nan() || kept < MIN_KEPT_FRACTION {
        c.fail(
            prefix,
            format!("min_m = {:?}, max_m = {:?}", size.min_m, size.max_m),
            format!(
                "only a fraction {kept:.3e} of the distribution lies in [min_m, max_m] (and above 0): widen the range (at least {MIN_KEPT_FRACTION})"
            ),
        );
        return None;
    }
    Some(psd)
}

/// Checks one `[[insert]]`; returns its (estimated, for `solid_fraction`) particle count.
fn validate_insert(c: &mut Checker, scene: &Scene, k: usize, insert: &InsertConfig) -> u64 {
    let key = |field: &str| format!("insert[{k}].{field}");
    let before = c.violations.len();
    c.finite_vector(&key("min_corner_m"), insert.min_corner_m);
    c.finite_vector(&key("max_corner_m"), insert.max_corner_m);
    c.finite_vector(&key("velocity_m_s"), insert.velocity_m_s);
    c.material(scene, &key("material"), &insert.material);
    if c.violations.len() == before {
        c.corners_ordered(
            &key("max_corner_m"),
            insert.max_corner_m,
            "min_corner_m",
            insert.min_corner_m,
        );
    }
    let psd = validate_size(c, &key("size"), &insert.size);
    match (insert.count, insert.solid_fraction) {
        (Some(_), Some(f)) => c.fail(
            key("solid_fraction"),
            f,
            "give either count or solid_fraction, not both",
        ),
        (None, None) => c.fail(
            format!("insert[{k}]"),
            "neither count nor solid_fraction",
            "give one of them",
        ),
        (Some(0), None) => c.fail(key("count"), 0, "must be ≥ 1"),
        (None, Some(f)) => {
            if c.finite(&key("solid_fraction"), f) && !(f > 0.0 && f <= 0.74) {
                c.fail(
                    key("solid_fraction"),
                    f,
                    "must be in (0, 0.74] (0.74: the densest packing of equal spheres)",
                );
            }
        }
        (Some(_), None) => {}
    }
    if c.violations.len() > before {
        return 0;
    }
    match (insert.count, insert.solid_fraction, psd) {
        (Some(n), _, _) => n,
        (None, Some(f), Some(psd)) => {
            let volume: f64 = (0..3)
                .map(|a| insert.max_corner_m[a] - insert.min_corner_m[a])
                .product();
            let median = psd.quantile(0.5);
            let estimate = f * volume / (std::f64::consts::PI / 6.0 * median.powi(3));
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let count = estimate.min(1e18) as u64;
            count.max(1)
        }
        _ => 0,
    }
}

fn validate_import(c: &mut Checker, scene: &Scene, k: usize, import: &ImportConfig) {
    let key = |field: &str| format!("import[{k}].{field}");
    if import.file.is_empty() {
        c.fail(key("file"), "\"\"", "must be a file name");
    }
    if let Some(frame) = import.frame {
        if import.format != ImportFormat::AmSimH5 {
            c.fail(key("frame"), frame, "only used with format = \"am_sim_h5\"");
        }
    }
    if let Some(step) = import.timestep {
        if import.format != ImportFormat::LiggghtsDump {
            c.fail(
                key("timestep"),
                step,
                "only used with format = \"liggghts_dump\"",
            );
        }
    }
    // The springs of a bed's contacts: only LIGGGHTS writes them, and only a scene with
    // tangential contact has springs to carry them.
    let springs = [
        (
            "pair_history_file",
            import
                .pair_history_file
                .as_ref()
                .map(|f| format!("\"{f}\"")),
        ),
        (
            "wall_history_columns",
            (!import.wall_history_columns.is_empty())
                .then(|| format!("{:?}", import.wall_history_columns)),
        ),
    ];
    for (field, value) in springs {
        let Some(value) = value else { continue };
        if import.format != ImportFormat::LiggghtsDump {
            c.fail(
                key(field),
                &value,
                "only used with format = \"liggghts_dump\"",
            );
        } else if scene.contact.friction_coefficient.is_none() {
            c.fail(
                key(field),
                &value,
                "the scene has no tangential contact (contact.friction_coefficient), so no spring to carry these histories",
            );
        }
    }
    if import.wall_history_columns.len() > scene.walls.len() {
        c.fail(
            key("wall_history_columns"),
            format!("{:?}", import.wall_history_columns),
            format!(
                "{} column prefixes for {} [[walls]]: give one per wall, in order (\"\" for a wall without springs)",
                import.wall_history_columns.len(),
                scene.walls.len()
            ),
        );
    }
    match &import.material {
        Some(name) => c.material(scene, &key("material"), name),
        None if import.format != ImportFormat::Csv => c.fail(
            key("material"),
            "missing",
            "needed: only a CSV file can name materials (column `material`)",
        ),
        None => {}
    }
    if let Some(scale) = import.scale {
        c.positive(&key("scale"), scale);
    }
    c.finite_vector(&key("shift_m"), import.shift_m);
    if cfg!(not(feature = "hdf5")) && import.format == ImportFormat::AmSimH5 {
        c.fail(
            key("format"),
            "\"am_sim_h5\"",
            "this am-sim was built without HDF5 (cargo feature `hdf5`)",
        );
    }
}

fn validate_deposition(c: &mut Checker, scene: &Scene, deposition: &DepositionConfig) {
    c.positive("deposition.max_duration_s", deposition.max_duration_s);
    let dt = scene.simulation.dt_s;
    if dt > 0.0 && deposition.max_duration_s / dt > MAX_STEPS {
        c.fail(
            "deposition.max_duration_s",
            deposition.max_duration_s,
            format!(
                "gives more than {MAX_STEPS:e} steps of dt_s = {dt}: check the units (seconds)"
            ),
        );
    }
    if let Some(ratio) = deposition.kinetic_energy_ratio {
        c.positive("deposition.kinetic_energy_ratio", ratio);
    }
    if let Some(tau) = deposition.damping_time_s {
        c.positive("deposition.damping_time_s", tau);
    }
    if deposition.check_every_steps == Some(0) {
        c.fail("deposition.check_every_steps", 0, "must be ≥ 1");
    }
    if scene.simulation.gravity_m_s2.iter().all(|g| *g == 0.0) {
        c.fail(
            "deposition",
            "[deposition]",
            "needs simulation.gravity_m_s2 ≠ 0: particles settle under gravity",
        );
    }
    if scene.walls.is_empty() {
        c.fail(
            "deposition",
            "[deposition]",
            "needs a [[walls]] plane for the particles to settle on",
        );
    }
}
