//! The conducting column: `scenes/column.toml` turned into a copper-like bed that conducts heat
//! through its contacts only (no gas, no surroundings, adiabatic walls). Shared by the
//! integration tests (`tests/common`) and the crate's own unit tests (`src/simulation/tests.rs`,
//! by `#[path]`), which read crate-private state and so cannot call the integration helpers:
//! text only, no types of the crate.

/// The text of `scenes/column.toml`.
fn column_text() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/column.toml"))
        .expect("scenes/column.toml")
}

/// `text` with `from` replaced by `to`, which must be there: a scene changed under the tests
/// fails them here rather than leaving them to run on a bed they did not ask for.
fn replaced(text: &str, from: &str, to: &str) -> String {
    assert!(
        text.contains(from),
        "scenes/column.toml no longer holds `{from}`"
    );
    text.replace(from, to)
}

/// The column in a box up to `max_corner` (a TOML array in metres) for `duration` (TOML, in
/// seconds), its spheres copper-like (c = 800 J/(kg·K), k = 400 W/(m·K), T_m = 1900 K) and
/// conducting by Batchelor & O'Brien from 300 K. The copper-like conductivity makes the contact
/// time constants (~0.1 s) short enough for heat to spread visibly within half a second.
#[must_use]
pub fn conducting_column(max_corner: &str, duration: &str) -> String {
    let text = column_text();
    let text = replaced(
        &text,
        "max_corner_m = [0.0220, 0.0220, 0.0440]",
        &format!("max_corner_m = {max_corner}"),
    );
    let text = replaced(
        &text,
        "duration_s = 0.1",
        &format!("duration_s = {duration}"),
    );
    let text = replaced(
        &text,
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.3\nspecific_heat_j_kg_k = 800\nthermal_conductivity_w_m_k = 400\n\
         melting_point_k = 1900",
    );
    replaced(
        &text,
        "[output]",
        "[thermal]\ninitial_temperature_k = 300\nconduction = \"batchelor_obrien\"\n[output]",
    )
}

/// The conducting column's lattice packed into a 20 mm cube of 1000 spheres for `duration`:
/// spacing 1.99 mm for r = 1 mm and no jitter, so that each sphere is pressed a little into its
/// six neighbours and the inner ones hold the most contacts, none of them near a wall.
#[must_use]
pub fn packed_cube(duration: &str) -> String {
    let text = conducting_column("[0.0200, 0.0200, 0.0200]", duration);
    let text = replaced(&text, "spacing_m = 2.2e-3", "spacing_m = 1.99e-3");
    replaced(&text, "jitter_m = 9e-5", "jitter_m = 0.0")
}
