//! Periodic boundaries (M.77): a collision across a periodic face is the same collision as in open
//! space; a periodic gas conserves momentum and energy; a frictional column with periodic sides
//! settles identically on one and two threads; bad periodic scenes are refused with their keys.

mod common;

use am_sim::model::Model;
use am_sim::scene::Scene;
use am_sim::simulation::Simulation;
use glam::DVec3;

const RADIUS: f64 = 1e-3;

/// Two spheres on the x axis: `a` at `xa` moving at −v/2, `b` at `xb` moving at +v/2; with
/// `periodic`, x is periodic over [0, 10 mm].
fn head_on(xa: f64, xb: f64, periodic: bool) -> Simulation {
    let periodic = if periodic {
        "[periodic]\nx_m = [0.0, 1.0e-2]\n"
    } else {
        ""
    };
    common::simulation(&format!(
        r#"
[scene]
version = 1
[simulation]
dt_s = 5e-8
duration_s = 6e-4
skin_m = 2e-4
[materials.m]
density_kg_m3 = 2000
youngs_modulus_pa = 1e9
poisson_ratio = 0.3
[contact]
model = "hertz"
damping_ratio = 0.2
friction_coefficient = 0.3
{periodic}
[[particles]]
position_m = [{xa:e}, 0.0, 0.0]
velocity_m_s = [-0.5, 0.1, 0.0]
radius_m = {RADIUS:e}
material = "m"
[[particles]]
position_m = [{xb:e}, 2e-4, 0.0]
velocity_m_s = [0.5, 0.0, 0.0]
radius_m = {RADIUS:e}
material = "m"
"#
    ))
}

#[test]
fn a_collision_across_a_periodic_face_is_the_open_space_collision() {
    // a at 1.2 mm runs towards x = 0; b at 9.0 mm towards x = 10 mm: their images are 2.2 mm
    // apart, 0.2 mm of gap; off-centre (0.2 mm in y) so friction and rotation take part. The open
    // reference puts a at 11.2 mm, the image position.
    let mut wrapped = head_on(1.2e-3, 9.0e-3, true);
    let mut open = head_on(11.2e-3, 9.0e-3, false);
    for _ in 0..wrapped.model.steps {
        wrapped.step();
        open.step();
    }
    let (w, o) = (&wrapped.particles, &open.particles);
    // Particles are stored in spatial order, which differs between the runs: compare by id.
    let (iw, io) = (
        |id: u64| w.index_of(id).unwrap(),
        |id: u64| o.index_of(id).unwrap(),
    );
    // The two runs differ only in the round-off of x_b − x_a (one subtraction of L: ~2e-18 m,
    // 1e-13 of the overlap), which the ~400 contact steps carry into the velocities at ~1e-11
    // relative; 1e-10 m/s bounds it. The collision really happened (b reversed).
    assert!(o.velocity[io(1)].x < 0.0, "no collision in the reference");
    for k in 0..2 {
        let (kw, ko) = (iw(k), io(k));
        assert!(
            (w.velocity[kw] - o.velocity[ko]).length() < 1e-10,
            "v{k}: {} vs {}",
            w.velocity[kw],
            o.velocity[ko]
        );
        let image = wrapped
            .model
            .periodic
            .unwrap()
            .minimum_image(w.position[kw] - o.position[ko]);
        assert!(image.length() < 1e-13, "x{k} differs by {image}");
    }
    let (rw, ro) = (
        wrapped.rotation.as_ref().unwrap(),
        open.rotation.as_ref().unwrap(),
    );
    assert!((rw.angular_velocity[iw(0)] - ro.angular_velocity[io(0)]).length() < 1e-7);
    assert!(
        ro.angular_velocity[io(0)].length() > 1.0,
        "friction must spin the spheres"
    );
}

#[test]
fn a_periodic_gas_conserves_momentum_and_energy() {
    // 343 spheres on a jittered 7³ lattice with random velocities in a box periodic along x, y
    // and z, no gravity, elastic (ξ = 0) and frictionless: momentum is conserved to round-off and
    // energy to the integrator's O(dt²) error.
    let mut text = String::from(
        r#"
[scene]
version = 1
[simulation]
dt_s = 2e-7
duration_s = 4e-3
skin_m = 2e-4
[materials.m]
density_kg_m3 = 2000
youngs_modulus_pa = 1e8
poisson_ratio = 0.3
[contact]
model = "hertz"
damping_ratio = 0.0
[periodic]
x_m = [0.0, 1.61e-2]
y_m = [0.0, 1.61e-2]
z_m = [0.0, 1.61e-2]
"#,
    );
    let mut rng = am_sim::bed::rng::SplitMix64(11);
    for i in 0..7 {
        for j in 0..7 {
            for k in 0..7 {
                let x = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * 2.3e-3
                    + DVec3::splat(1.2e-3);
                let v = DVec3::new(rng.symmetric(), rng.symmetric(), rng.symmetric());
                text.push_str(&format!(
                    "[[particles]]\nposition_m = [{:e}, {:e}, {:e}]\nvelocity_m_s = [{:e}, {:e}, {:e}]\nradius_m = {RADIUS:e}\nmaterial = \"m\"\n",
                    x.x, x.y, x.z, v.x, v.y, v.z
                ));
            }
        }
    }
    let mut sim = common::simulation(&text);
    let momentum = |s: &Simulation| -> DVec3 {
        let p = &s.particles;
        p.velocity.iter().zip(&p.mass).map(|(v, m)| *m * *v).sum()
    };
    let scale: f64 = sim
        .particles
        .velocity
        .iter()
        .zip(&sim.particles.mass)
        .map(|(v, m)| m * v.length())
        .sum();
    let before = momentum(&sim);
    let mut collisions = 0;
    for _ in 0..sim.model.steps {
        sim.step();
        collisions = collisions.max(sim.diagnostics().contacts);
    }
    assert!(
        collisions > 5,
        "the gas must collide ({collisions} contacts at most)"
    );
    assert!(
        sim.diagnostics().neighbor_builds > 3,
        "particles must cross the faces"
    );
    // Round-off: each pair force cancels exactly; ~1e-16 of Σ m|v| per step over 2e4 steps.
    assert!(
        (momentum(&sim) - before).length() < 1e-12 * scale,
        "momentum drifted by {}",
        (momentum(&sim) - before).length() / scale
    );
    let residual = sim.diagnostics().energy_residual;
    assert!(residual.abs() < 1e-4, "energy residual {residual}");
    // Wrapped at every build: no particle is more than half a skin outside the box.
    for x in &sim.particles.position {
        for c in x.to_array() {
            assert!((-1e-4..1.61e-2 + 1e-4).contains(&c), "{x}");
        }
    }
}

/// scenes/column.toml without its side walls (only the floor).
fn column_without_side_walls() -> String {
    let text = common::scene_text("column.toml");
    let floor_end = text
        .find("[[walls]]\npoint_m = [0.0, 0.0, 0.0]\nnormal = [1.0")
        .unwrap();
    let output = text.find("[output]").unwrap();
    format!("{}{}", &text[..floor_end], &text[output..])
}

/// scenes/column.toml with its side walls replaced by periodic x and y, friction on, 60 ms: the
/// column has landed.
fn periodic_column(threads: usize) -> Simulation {
    let text = column_without_side_walls()
        .replace(
            "[output]",
            "[periodic]\nx_m = [0.0, 0.0220]\ny_m = [0.0, 0.0220]\n\n[output]",
        )
        .replace("duration_s = 0.1", "duration_s = 0.06")
        .replace(
            "damping_ratio = 0.3      # restitution ≈ 0.42 (tests/hertz_impact.rs)",
            "damping_ratio = 0.3\nfriction_coefficient = 0.5",
        );
    common::run_on_threads(&text, threads)
}

#[test]
fn a_periodic_frictional_column_is_bitwise_identical_on_one_and_two_threads() {
    let (one, two) = (periodic_column(1), periodic_column(2));
    assert_eq!(
        common::position_velocity_bits(&one),
        common::position_velocity_bits(&two)
    );
    // Spheres touch across the faces: pairs in contact by their minimum image only (O(n²)).
    let p = &one.particles;
    let periodic = one.model.periodic.unwrap();
    let mut across = 0;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            let d = p.position[j] - p.position[i];
            let reach = p.radius[i] + p.radius[j];
            if periodic.minimum_image(d).length() < reach && d.length() >= reach {
                across += 1;
            }
        }
    }
    assert!(across > 20, "{across} contacts across the faces");
}

#[test]
fn bad_periodic_scenes_name_the_key_value_and_reason() {
    let open = column_without_side_walls();
    let walled = common::scene_text("column.toml");
    let cases: [(&str, &str, &[&str]); 3] = [
        // A period shorter than three neighbour cells (2 r_max + skin = 2.2 mm).
        (
            &open,
            "[periodic]\nx_m = [0.0, 6e-3]\n",
            &["periodic.x_m = [0, 0.006]", "three neighbour cells"],
        ),
        // Gravity along a periodic axis.
        (
            &open,
            "[periodic]\nz_m = [0.0, 0.1]\n",
            &["simulation.gravity_m_s2", "periodic axis z"],
        ),
        // The column's side walls face along x: a wall across a periodic direction.
        (
            &walled,
            "[periodic]\nx_m = [0.0, 0.0220]\n",
            &["walls[1].normal", "periodic axis x"],
        ),
    ];
    for (base, section, expected) in cases {
        let text = base.replace("[output]", &format!("{section}\n[output]"));
        let message = match Scene::from_toml(&text) {
            Err(e) => e.to_string(),
            Ok(scene) => match Model::try_build(&scene) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("accepted {section}"),
            },
        };
        for part in expected {
            assert!(
                message.contains(part),
                "{section}: lacks {part:?}: {message}"
            );
        }
    }
}
