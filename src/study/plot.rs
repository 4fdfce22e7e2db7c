//! Error-against-run-time plots (log–log PNG), drawn with plotters' bitmap backend and an embedded
//! font (DejaVu Sans, `assets/fonts/`), so they need no system font library.

use std::error::Error;
use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use super::Family;

/// DejaVu Sans (Bitstream Vera license, `assets/fonts/LICENSE-DejaVu.txt`).
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

/// Distinguishable line colours (the "tab10" palette).
const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn register() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The font is compiled in, so a failure is a broken build, not a user error.
        assert!(
            register_font(FAMILY, FontStyle::Normal, FONT).is_ok(),
            "the embedded DejaVu Sans does not parse"
        );
    });
}

/// Lower and upper bounds of `values` (all > 0), widened by a factor `margin` each way.
fn log_range(values: impl Iterator<Item = f64>, margin: f64) -> (f64, f64) {
    let (low, high) = values.fold((f64::INFINITY, 0.0_f64), |(l, h), v| (l.min(v), h.max(v)));
    if high > 0.0 {
        (low / margin, high * margin)
    } else {
        (0.1, 10.0)
    }
}

/// Draws the relative error of every series of `family` against the wall time of its runs,
/// log–log, one line per series, into the PNG file `path`. Runs with an error of exactly 0
/// (below f64 resolution) have no place on a log axis and are left out.
///
/// # Errors
/// When the file cannot be written.
pub(super) fn error_against_time(family: &Family, path: &Path) -> Result<(), Box<dyn Error>> {
    register();
    let curves: Vec<(String, Vec<(f64, f64)>)> = family
        .series
        .iter()
        .map(|s| {
            let points = s
                .samples
                .iter()
                .filter(|p| p.error > 0.0 && p.wall_time > 0.0)
                .map(|p| (p.wall_time, p.error))
                .collect();
            (s.label(), points)
        })
        .collect();
    let all = || curves.iter().flat_map(|(_, p)| p.iter().copied());
    let (x_low, x_high) = log_range(all().map(|p| p.0), 1.5);
    let (y_low, y_high) = log_range(all().map(|p| p.1), 3.0);
    let root = BitMapBackend::new(path, (1100, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: relative error against run time", family.title),
            (FAMILY, 26),
        )
        .margin(20)
        .x_label_area_size(55)
        .y_label_area_size(85)
        .build_cartesian_2d((x_low..x_high).log_scale(), (y_low..y_high).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("wall time of the run [s]")
        .y_desc("relative error")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style((FAMILY, 16))
        .axis_desc_style((FAMILY, 18))
        .draw()?;
    for (k, (label, points)) in curves.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
            .label(label.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
            });
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::MiddleLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FAMILY, 16))
        .draw()?;
    root.present()?;
    Ok(())
}
