//! `[[insert]]`: random sequential addition places the requested spheres (count or solid
//! fraction) with diameters from the size distribution, all inside the box, none overlapping
//! each other or earlier particles; a box that cannot take them is a clear scene error.

use am_sim::model::Model;
use am_sim::particles::Particles;
use am_sim::scene::Scene;
use am_sim::scene::validate::size_distribution;

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
[contact]
model = "hertz"
damping_ratio = 0.5
"#;

/// 2000 spheres of a 316L-like PSD (D10/D50/D90 = 20/30/45 µm, truncated to 15-60 µm) in a box
/// they fill to a solid fraction of about 0.17.
const INSERT: &str = r#"
[[insert]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [8e-4, 8e-4, 4e-4]
count = 2000
seed = 5
material = "steel"
[insert.size]
distribution = "lognormal"
d10_m = 20e-6
d50_m = 30e-6
d90_m = 45e-6
min_m = 15e-6
max_m = 60e-6
"#;

fn build(text: &str) -> Result<Particles, String> {
    let scene = Scene::from_toml(text).map_err(|e| e.to_string())?;
    Model::try_build(&scene)
        .map(|(_, p)| p)
        .map_err(|e| e.to_string())
}

/// Largest overlap of any two spheres relative to the sum of their radii (brute force).
fn worst_overlap(p: &Particles) -> f64 {
    let mut worst = f64::NEG_INFINITY;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            let gap = p.position[i].distance(p.position[j]) - (p.radius[i] + p.radius[j]);
            worst = worst.max(-gap / (p.radius[i] + p.radius[j]));
        }
    }
    worst
}

fn assert_inside(p: &Particles, range: std::ops::Range<usize>, lo: [f64; 3], hi: [f64; 3]) {
    for k in range {
        for a in 0..3 {
            let (x, r) = (p.position[k][a], p.radius[k]);
            assert!(
                x - r >= lo[a] && x + r <= hi[a],
                "particle {k} sticks out along {a}"
            );
        }
    }
}

#[test]
fn inserted_spheres_are_inside_the_box_and_never_overlap() {
    let text = format!("{HEAD}{INSERT}");
    let p = build(&text).expect("insertion");
    assert_eq!(p.len(), 2000);
    assert_inside(&p, 0..p.len(), [0.0; 3], [8e-4, 8e-4, 4e-4]);
    // Accepted positions satisfy |x_i − x_j| ≥ r_i + r_j in floating point; the distance
    // recomputed here may differ by a few ulps, hence the round-off margin.
    assert!(worst_overlap(&p) < 1e-12, "{}", worst_overlap(&p));
    // The same seed builds the same bed, bit for bit.
    assert_eq!(build(&text).expect("again").position, p.position);
}

#[test]
fn inserted_diameters_follow_the_truncated_distribution() {
    let text = format!("{HEAD}{INSERT}");
    let scene = Scene::from_toml(&text).expect("scene");
    let psd = size_distribution(&scene.insert[0].size).expect("psd");
    let (_, p) = Model::try_build(&scene).expect("build");
    let mut d: Vec<f64> = p.radius.iter().map(|r| 2.0 * r).collect();
    d.sort_by(f64::total_cmp);
    assert!(d[0] >= 15e-6 && d[d.len() - 1] <= 60e-6);
    #[allow(clippy::cast_precision_loss)]
    let n = d.len() as f64;
    let ks = d
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            #[allow(clippy::cast_precision_loss)]
            let (below, upto) = (k as f64 / n, (k + 1) as f64 / n);
            let f = psd.cdf(x);
            (f - below).abs().max((upto - f).abs())
        })
        .fold(0.0, f64::max);
    // Kolmogorov–Smirnov critical value at significance 0.001: 1.95/√n. Placement sorts the
    // radii but keeps every drawn diameter, so the sample is still the PSD's.
    assert!(ks < 1.95 / n.sqrt(), "KS distance {ks}");
}

#[test]
fn a_solid_fraction_fills_the_box_to_it_around_earlier_particles() {
    // A lattice in the lower half and a fixed sphere: the insertion must avoid both.
    let text = format!(
        "{HEAD}
[[particles]]
position_m = [2e-4, 2e-4, 2e-4]
radius_m = 5e-5
material = \"steel\"
[[lattice]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [4e-4, 4e-4, 1e-4]
radius_m = 1.5e-5
spacing_m = 5e-5
material = \"steel\"
[[insert]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [4e-4, 4e-4, 4e-4]
solid_fraction = 0.2
seed = 11
material = \"steel\"
[insert.size]
distribution = \"normal\"
mean_m = 3e-5
std_m = 4e-6
min_m = 2e-5
"
    );
    let p = build(&text).expect("insertion");
    let before = 1 + 128; // the sphere and 8 × 8 × 2 lattice sites (docs: lattice_sites)
    assert!(p.len() > before);
    assert!(p.radius[0] == 5e-5 && p.radius[1..before].iter().all(|&r| r == 1.5e-5));
    assert_inside(&p, before..p.len(), [0.0; 3], [4e-4; 3]);
    assert!(worst_overlap(&p) < 1e-12);
    let volume = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let solid: f64 = p.radius[before..].iter().map(|&r| volume(r)).sum();
    let target = 0.2 * 6.4e-11;
    let largest = p.radius[before..].iter().copied().fold(0.0, f64::max);
    // Diameters are drawn until their volume reaches the target: the last one overshoots by
    // less than one sphere.
    assert!(
        solid >= target && solid < target + volume(largest),
        "{solid:e} vs {target:e}"
    );
}

#[test]
fn a_box_too_full_to_fill_is_an_error_saying_how_many_were_placed() {
    let text = format!("{HEAD}{INSERT}").replace("count = 2000", "solid_fraction = 0.6");
    let message = build(&text).unwrap_err();
    for fragment in [
        "insert[0].solid_fraction = 0.6",
        "placed only",
        "random positions in a row overlapped",
    ] {
        assert!(message.contains(fragment), "lacks {fragment:?}: {message}");
    }
}

#[test]
fn a_sphere_wider_than_the_box_is_an_error_naming_the_box() {
    let text = format!("{HEAD}{INSERT}").replace(
        "max_corner_m = [8e-4, 8e-4, 4e-4]",
        "max_corner_m = [8e-4, 8e-4, 5e-5]",
    );
    let message = build(&text).unwrap_err();
    for fragment in ["insert[0].max_corner_m", "does not fit the box along z"] {
        assert!(message.contains(fragment), "lacks {fragment:?}: {message}");
    }
}
