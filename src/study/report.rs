//! The Markdown report `accuracy.md`: the command, the method, a summary of observed orders, and
//! per case family its description, plot, tables and reading.

use std::fmt::Write as _;

use super::{Family, Reference, Series, Study};

/// The report of `study` as Markdown (the images are referenced as `images/accuracy-<key>.png`).
#[must_use]
pub(super) fn markdown(study: &Study) -> String {
    let mut md = String::new();
    let sweep = if study.quick {
        "the reduced sweep (`--quick`)"
    } else {
        "the full sweep"
    };
    let timing = if study.quick {
        "The reduced sweep times every run once.".to_owned()
    } else {
        format!(
            "Each is the smallest of repeated runs (a case is rerun while its runs took less than \
             {:.0} ms in total): two-particle runs last micro- to milliseconds, and a single \
             timing of them is mostly noise.",
            1e3 * super::TIMING_BUDGET
        )
    };
    let _ = write!(
        md,
        "# Accuracy: error against run time\n\n\
         <!-- Written by `am-sim study`: edit src/study/, not this file. -->\n\n\
         This page and the plots in `images/accuracy-*.png` are written by one command:\n\n\
         ```sh\n\
         cargo run --release -- study            # full sweep into docs/ (seconds)\n\
         cargo run --release -- study --quick --out /tmp/study   # reduced sweep, seconds\n\
         ```\n\n\
         This version is {sweep}; the whole study took {:.2} s of wall time. It sweeps the time \
         step (and, for the heat balance, the substep fraction θ of M.49) over cases with an \
         analytic answer, runs each case through the same scene path as `am-sim scene.toml`, \
         and reports for every quantity the relative error against the reference and the wall \
         time of the run. Wall times are measured on the machine that wrote this page. {} \
         Compare them within a table, not across machines. `tests/study.rs` runs the reduced sweep and checks the \
         orders below.\n\n\
         **Method.** The relative error of a run is |value/reference − 1|. The reference is a \
         closed form where one exists; otherwise (damped restitution, settling time, peak \
         overlap of the bond) it is the same run at a much finer step, named in the table. The \
         local order between two consecutive steps is p = ln(e₁/e₂)/ln(dt₁/dt₂); the *observed \
         order* is the local order of the finest pair of runs whose errors are both above \
         round-off (10⁻¹²), the *fitted order* the least-squares slope of ln e against ln dt \
         over all runs above round-off. An error at round-off has no order (\"–\"); one on a floor \
         set by θ (an error that does not change with dt) shows a local order of 0.\n\n",
        study.wall_time, timing
    );
    md.push_str("## Observed orders\n\n");
    md.push_str(
        "| Case | Quantity | Reference | Finest dt | Error there | Observed order | Fitted order | Expected |\n",
    );
    md.push_str("|---|---|---|---|---|---|---|---|\n");
    for family in &study.families {
        for s in &family.series {
            let finest = s.samples.last().copied();
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                family.title,
                s.label(),
                reference_text(s),
                finest.map_or_else(|| "–".into(), |f| format!("{:.3e} s", f.dt)),
                finest.map_or_else(|| "–".into(), |f| format!("{:.2e}", f.error)),
                order_text(s.observed_order()),
                order_text(s.fitted_order()),
                s.expected,
            );
        }
    }
    md.push('\n');
    for family in &study.families {
        section(&mut md, family);
    }
    md
}

fn order_text(order: Option<f64>) -> String {
    order.map_or_else(|| "–".into(), |p| format!("{p:.2}"))
}

fn reference_text(s: &Series) -> String {
    match &s.reference_kind {
        Reference::ClosedForm(name) => (*name).to_string(),
        Reference::FineStep(dt) => format!("run at dt = {dt:.3e} s"),
    }
}

fn section(md: &mut String, family: &Family) {
    let _ = write!(
        md,
        "## {}\n\n{}\n\n![{}: relative error against wall time](images/accuracy-{}.png)\n\n",
        family.title, family.description, family.title, family.key
    );
    for s in &family.series {
        let unit = if s.unit.is_empty() {
            String::new()
        } else {
            format!(" [{}]", s.unit)
        };
        let _ = write!(
            md,
            "### {}\n\nReference: {:.10e}{} ({}). Expected order: {}.\n\n\
             | dt [s] | dt/{} | value{} | relative error | local order | wall time [s] |\n\
             |---|---|---|---|---|---|\n",
            s.label(),
            s.reference,
            if s.unit.is_empty() {
                String::new()
            } else {
                format!(" {}", s.unit)
            },
            reference_text(s),
            s.expected,
            s.scale.0,
            unit,
        );
        for (sample, order) in s.samples.iter().zip(s.local_orders()) {
            let _ = writeln!(
                md,
                "| {:.4e} | {:.4e} | {:.10e} | {:.3e} | {} | {:.2e} |",
                sample.dt,
                sample.dt / s.scale.1,
                sample.value,
                sample.error,
                order_text(order),
                sample.wall_time
            );
        }
        md.push('\n');
    }
    let _ = write!(md, "**Reading.** {}\n\n", family.reading);
}
