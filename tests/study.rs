//! The reduced convergence study (`am-sim study --quick`): the observed orders match the
//! integrators (velocity Verlet: 2; explicit Euler on the enthalpy: 1), the quantities read on the
//! step grid are first order within their one-step bounds, and the report and plots are written.
//! Nothing here is timed: the wall times in the report are not checked.

use am_sim::study::{self, Series, Study};

fn series<'a>(study: &'a Study, key: &str, quantity: &str, variant: &str) -> &'a Series {
    study
        .series(key, quantity, variant)
        .unwrap_or_else(|| panic!("no series {key}/{quantity}/{variant}"))
}

fn order(s: &Series) -> f64 {
    s.observed_order()
        .unwrap_or_else(|| panic!("{}: no order above round-off", s.label()))
}

/// Errors shrink with every halving of dt.
fn decreasing(s: &Series) -> bool {
    s.samples.windows(2).all(|w| w[1].error < w[0].error)
}

#[test]
fn quick_study_converges_at_the_orders_of_its_integrators_and_writes_its_report() {
    let dir = tempfile::tempdir().expect("temp dir");
    let study = study::run(&study::Options {
        quick: true,
        out: dir.path().to_path_buf(),
    })
    .expect("study written");
    for family in &study.families {
        for s in &family.series {
            eprintln!(
                "{}: errors {:?}, observed order {:?}",
                s.label(),
                s.samples.iter().map(|x| x.error).collect::<Vec<_>>(),
                s.observed_order()
            );
        }
    }

    // Velocity Verlet is second order. The quick sweep (t_c/16 … t_c/128) is in the asymptotic
    // range, where the full sweep measures 2.01–2.08 for these three: ±0.2 leaves room for the
    // next-order term and would still catch a first-order scheme or a half-step bug (p ≈ 1).
    for (key, quantity) in [
        ("hertz", "δ_max"),
        ("hertz", "t_c, interpolated"),
        ("onset", "onset velocity"),
    ] {
        let variant = if key == "hertz" { "ξ = 0" } else { "" };
        let s = series(&study, key, quantity, variant);
        assert!(decreasing(s), "{}: {:?}", s.label(), s.samples);
        let p = order(s);
        assert!((p - 2.0).abs() < 0.2, "{}: order {p}", s.label());
    }
    // At t_c/128 the onset is within 1e-4 of eq. 21 (measured 3.7e-5).
    let onset = series(&study, "onset", "onset velocity", "");
    assert!(onset.samples.last().unwrap().error < 1e-4);

    // Counting steps in contact misses the end of the contact by less than one step: first
    // order, and bounded by dt/t_c for every run.
    let grid = series(&study, "hertz", "t_c, on the step grid", "ξ = 0");
    assert!((order(grid) - 1.0).abs() < 0.1, "order {}", order(grid));
    for x in &grid.samples {
        assert!(x.error <= x.dt / grid.scale.1 * (1.0 + 1e-9), "{x:?}");
    }

    // Without damping the pair leaves with its impact speed: e − 1 shrinks with dt and is below
    // 1e-5 at t_c/128 (measured 1.3e-7); with damping e converges to its fine-step value.
    let elastic = series(&study, "hertz", "e", "ξ = 0");
    assert!(decreasing(elastic) && elastic.samples.last().unwrap().error < 1e-5);
    let damped = series(&study, "hertz", "e", "ξ = 0.3");
    assert!(damped.samples.last().unwrap().error < 1e-3, "{damped:?}");

    // Example 5.1: δ_eq is a fixed point of the discrete map, so the final overlap is exact to
    // round-off at every dt. Settling time and peak overlap inherit the O(dt) delay of the bond
    // formation: over the 8× range of the sweep a first-order error shrinks 8×; the phase of the
    // step grid scatters it (the full sweep shows local orders from −1 to 3), so ask for 4×.
    let final_overlap = series(&study, "bond", "final δ", "ξ_bond = 0.3");
    assert!(final_overlap.samples.iter().all(|x| x.error < 1e-10));
    for quantity in ["settling time", "peak δ"] {
        let s = series(&study, "bond", quantity, "ξ_bond = 0.3");
        let (first, last) = (s.samples[0].error, s.samples.last().unwrap().error);
        assert!(last < first / 4.0, "{quantity}: {first} → {last}");
    }

    // Explicit Euler: first order while one substep per step suffices (the two finest steps,
    // τ/16 and τ/32, are below θ C/G for every θ swept, so θ changes nothing there: the same
    // numbers bit for bit). At τ/4 the θ = 0.1 runs take substeps and are more accurate.
    for quantity in ["convection: T − T_gas", "two spheres: τ"] {
        let coarse = series(&study, "thermal", quantity, "θ = 1");
        let fine = series(&study, "thermal", quantity, "θ = 0.1");
        assert!(decreasing(coarse), "{quantity}: {:?}", coarse.samples);
        // The full sweep measures 1.00–1.01 from τ/32 on.
        assert!((order(coarse) - 1.0).abs() < 0.1, "{quantity}");
        let n = coarse.samples.len();
        for k in n - 2..n {
            let (a, b) = (coarse.samples[k].value, fine.samples[k].value);
            assert_eq!(a.to_bits(), b.to_bits(), "{quantity}, dt = τ/{}", 4 << k);
        }
        assert!(
            fine.samples[0].error < coarse.samples[0].error / 2.0,
            "{quantity}: θ = 0.1 {} vs θ = 1 {}",
            fine.samples[0].error,
            coarse.samples[0].error
        );
    }

    // The plateau is read on the step grid: each end is off by less than one step.
    let plateau = series(&study, "thermal", "latent plateau", "");
    for x in &plateau.samples {
        assert!(x.error <= x.dt / plateau.scale.1 * (1.0 + 1e-9), "{x:?}");
    }

    let report = std::fs::read_to_string(dir.path().join("accuracy.md")).expect("accuracy.md");
    assert!(report.contains("cargo run --release -- study"));
    for family in &study.families {
        let name = format!("images/accuracy-{}.png", family.key);
        assert!(report.contains(&name), "{name} not linked");
        let png = std::fs::read(dir.path().join(&name)).expect("plot written");
        assert!(
            png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 10_000,
            "{name}"
        );
    }
}
