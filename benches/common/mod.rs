//! Scenes shared by the benches.

/// `scenes/column.toml` widened `scale` times in area (the far walls moved with it), without
/// output, and with 316L-like heat conduction (Batchelor & O'Brien) if `thermal`.
#[must_use]
pub fn wide_column(scale: f64, thermal: bool) -> String {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/column.toml"))
        .expect("scene");
    let width = 0.022 * scale.sqrt();
    let mut text = text
        .replace(
            "max_corner_m = [0.0220, 0.0220, 0.0440]",
            &format!("max_corner_m = [{width}, {width}, 0.0440]"),
        )
        .replace(
            "point_m = [0.0220, 0.0, 0.0]",
            &format!("point_m = [{width}, 0.0, 0.0]"),
        )
        .replace(
            "point_m = [0.0, 0.0220, 0.0]",
            &format!("point_m = [0.0, {width}, 0.0]"),
        );
    text.truncate(text.find("[output]").expect("output section"));
    if thermal {
        text = text.replace(
            "poisson_ratio = 0.3",
            "poisson_ratio = 0.3\nspecific_heat_j_kg_k = 500\nthermal_conductivity_w_m_k = 18\nmelting_point_k = 1700",
        ) + "[thermal]\ninitial_temperature_k = 300\nconduction = \"batchelor_obrien\"\n";
    }
    text
}
