//! The tangential springs of an imported bed's contacts, as LIGGGHTS and LAMMPS write them.
//!
//! A settled bed holds itself up by friction: each contact's tangential spring (its history,
//! the accumulated tangential displacement ξ, M.57-M.59) carries part of the load. A dump of
//! the particles alone loses the springs, and the bed compacts when it starts again (on the
//! LIGGGHTS benchmark bed the coordination climbs from 1.30 to about 2.0, where LIGGGHTS' own
//! restart holds 1.58). LIGGGHTS writes the springs with
//!
//! ```text
//! compute pairs all pair/gran/local id history
//! dump    pairs all local 1 pairs.dump c_pairs[1] c_pairs[2] c_pairs[3] c_pairs[4] c_pairs[5] c_pairs[6]
//! dump_modify pairs format "%.0f %.0f %.0f %.12e %.12e %.12e"
//! ```
//!
//! one line per contact: the two particle ids, a periodic-image flag, and ξ \[m\] in the world
//! frame (`units si`). The history is that of the first particle relative to the second (its
//! `shear` in `tangential_model_history`, from which the force on the first is `−k_t ξ`), the
//! convention of am-sim's springs ([`crate::contact::tangential`]). The `%.0f` keeps ids above
//! 999,999 exact (the default `%g` rounds them to six digits). Columns after the sixth are
//! ignored.

use glam::DVec3;

/// One contact's spring as read from the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImportedSpring {
    /// The file's ids of the two particles; ξ is the first's displacement relative to the
    /// second.
    pub ids: (u64, u64),
    /// Tangential displacement ξ \[m\], world frame.
    pub history: DVec3,
    /// The file's line, for messages.
    pub line: usize,
}

/// The rotational state imported with a bed, by am-sim particle id (`Particles::id`): what a
/// LIGGGHTS restart carries besides positions and velocities. `Simulation::new` gives it to the
/// particles and their contacts at t = 0.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImportedRotation {
    /// `(id, ω)`: angular velocities \[rad/s\].
    pub angular_velocity: Vec<(u64, DVec3)>,
    /// `((id₁, id₂), ξ)` with id₁ < id₂: the tangential spring of the pair's contact, id₁'s
    /// displacement relative to id₂ \[m\].
    pub pair_springs: Vec<((u64, u64), DVec3)>,
    /// `(id, wall, ξ)`: the tangential spring of a particle against wall `wall` (index into
    /// `Model::walls`) \[m\].
    pub wall_springs: Vec<(u64, usize, DVec3)>,
}

impl ImportedRotation {
    /// True when nothing was imported.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.angular_velocity.is_empty()
            && self.pair_springs.is_empty()
            && self.wall_springs.is_empty()
    }
}

/// A particle id written as an integer, or as a floating-point number with an integer value
/// (`dump local` writes every column as a double).
fn contact_id(text: &str, line: usize, column: usize) -> Result<u64, String> {
    if let Ok(id) = text.parse::<u64>() {
        return Ok(id);
    }
    match text.parse::<f64>() {
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        Ok(value) if value >= 0.0 && value.fract() == 0.0 && value < 2f64.powi(53) => {
            Ok(value as u64)
        }
        _ => Err(format!(
            "line {line}, column {column}: \"{text}\" is not a particle id (a non-negative integer)"
        )),
    }
}

/// Reads the springs of the snapshot of `timestep` (default: the last) of a `dump local` of
/// `compute pair/gran/local id history` (see the module documentation). Only one snapshot's
/// rows are held at a time.
///
/// # Errors
/// A message naming the line of the first problem: a row of fewer than six values, an id that
/// is not an integer, a value that is not a finite number, a pair given twice, or no snapshot of
/// `timestep`.
pub fn read_pair_history(
    reader: impl std::io::BufRead,
    timestep: Option<u64>,
) -> Result<Vec<ImportedSpring>, String> {
    let mut timesteps = Vec::new();
    let mut chosen: Option<Vec<ImportedSpring>> = None;
    let mut lines = reader.lines().enumerate();
    let mut step: Option<u64> = None;
    let mut count: Option<usize> = None;
    while let Some((k, line)) = lines.next() {
        let number = k + 1;
        let line = line.map_err(|e| format!("line {number}: cannot read: {e}"))?;
        let item = line.trim();
        // The integer on the line after an item's header.
        let mut next_integer = |what: &str| {
            let value = lines
                .next()
                .map(|(_, l)| l.unwrap_or_default())
                .unwrap_or_default();
            let value = value.trim();
            value
                .parse::<u64>()
                .map_err(|_| format!("line {}: {what} \"{value}\" is not an integer", number + 1))
        };
        if item.starts_with("ITEM: TIMESTEP") {
            step = Some(next_integer("timestep")?);
            timesteps.extend(step);
            count = None;
        } else if item.starts_with("ITEM: NUMBER OF ENTRIES") {
            count = Some(
                usize::try_from(next_integer("number of entries")?)
                    .map_err(|_| format!("line {}: too many entries", number + 1))?,
            );
        } else if item.starts_with("ITEM: ENTRIES") {
            let (Some(this_step), Some(n)) = (step, count) else {
                return Err(format!(
                    "line {number}: `ITEM: ENTRIES` before `ITEM: TIMESTEP` and `ITEM: NUMBER OF ENTRIES`: not a LIGGGHTS/LAMMPS `dump local` file"
                ));
            };
            let wanted = timestep.is_none_or(|t| t == this_step);
            let mut springs = Vec::with_capacity(if wanted { n } else { 0 });
            for read in 0..n {
                let Some((k, row)) = lines.next() else {
                    return Err(format!(
                        "line {number}: {n} entries announced, the file ends after {read}"
                    ));
                };
                if !wanted {
                    continue;
                }
                let line = k + 1;
                let row = row.map_err(|e| format!("line {line}: cannot read: {e}"))?;
                springs.push(parse_row(&row, line)?);
            }
            if wanted {
                chosen = Some(springs);
            }
        }
    }
    let springs = match (chosen, timestep) {
        (Some(springs), _) => springs,
        (None, None) => {
            return Err(
                "no `ITEM: ENTRIES` section: not a LIGGGHTS/LAMMPS `dump local` file".into(),
            );
        }
        (None, Some(t)) => {
            return Err(format!(
                "no snapshot of timestep {t}; the file has timesteps {timesteps:?}"
            ));
        }
    };
    let mut keys: Vec<((u64, u64), usize)> = springs
        .iter()
        .map(|s| ((s.ids.0.min(s.ids.1), s.ids.0.max(s.ids.1)), s.line))
        .collect();
    keys.sort_unstable();
    if let Some(w) = keys.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(format!(
            "lines {} and {}: the pair of particles {} and {} appears twice",
            w[0].1, w[1].1, w[0].0.0, w[0].0.1
        ));
    }
    Ok(springs)
}

fn parse_row(row: &str, line: usize) -> Result<ImportedSpring, String> {
    let cells: Vec<&str> = row.split_whitespace().collect();
    if cells.len() < 6 {
        return Err(format!(
            "line {line}: {} values; a contact needs six (id₁ id₂ periodic-flag ξx ξy ξz of `compute pair/gran/local id history`)",
            cells.len()
        ));
    }
    let first = contact_id(cells[0], line, 1)?;
    let second = contact_id(cells[1], line, 2)?;
    if first == second {
        return Err(format!(
            "line {line}: particle {first} in contact with itself"
        ));
    }
    let mut history = [0.0; 3];
    for (c, value) in history.iter_mut().enumerate() {
        let text = cells[3 + c];
        *value = text
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                format!(
                    "line {line}, column {}: \"{text}\" is not a finite number",
                    4 + c
                )
            })?;
    }
    Ok(ImportedSpring {
        ids: (first, second),
        history: DVec3::from_array(history),
        line,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const DUMP: &str = "ITEM: TIMESTEP
100
ITEM: NUMBER OF ENTRIES
1
ITEM: BOX BOUNDS pp pp ff
0 1
0 1
0 1
ITEM: ENTRIES c_p[1] c_p[2] c_p[3] c_p[4] c_p[5] c_p[6]
1 2 0 1e-10 0 0
ITEM: TIMESTEP
200
ITEM: NUMBER OF ENTRIES
2
ITEM: BOX BOUNDS pp pp ff
0 1
0 1
0 1
ITEM: ENTRIES c_p[1] c_p[2] c_p[3] c_p[4] c_p[5] c_p[6] c_p[7]
5 3 1 -8.384110870862e-11 -1.832170473013e-10 -3.338852736968e-10 1.1e-9
1.181025e+06 7 0 2e-10 3e-10 4e-10 0
";

    #[test]
    fn reads_the_last_snapshot_or_the_one_asked_for() {
        let last = read_pair_history(DUMP.as_bytes(), None).unwrap();
        assert_eq!(last.len(), 2);
        assert_eq!(last[0].ids, (5, 3));
        assert_eq!(
            last[0].history,
            DVec3::new(
                -8.384110870862e-11,
                -1.832170473013e-10,
                -3.338852736968e-10
            )
        );
        assert_eq!(last[0].line, 20);
        // `dump local` writes ids as doubles: an integer value in exponent form is an id.
        assert_eq!(last[1].ids, (1_181_025, 7));
        let first = read_pair_history(DUMP.as_bytes(), Some(100)).unwrap();
        assert_eq!(first.len(), 1);
        assert_eq!(first[0].history, DVec3::new(1e-10, 0.0, 0.0));
        let missing = read_pair_history(DUMP.as_bytes(), Some(150)).unwrap_err();
        assert!(missing.contains("timesteps [100, 200]"), "{missing}");
    }

    #[test]
    fn bad_rows_are_named_by_line() {
        let error = |text: &str| read_pair_history(text.as_bytes(), None).unwrap_err();
        // An id written as a double must have an integer value.
        let fraction = DUMP.replace("1.181025e+06", "1.5");
        assert!(error(&fraction).contains("line 21, column 1: \"1.5\" is not a particle id"));
        let short = DUMP.replace("-3.338852736968e-10 1.1e-9", "");
        assert!(
            error(&short).contains("line 20: 5 values"),
            "{}",
            error(&short)
        );
        let nan = DUMP.replace("2e-10 3e-10", "2e-10 nan");
        assert!(error(&nan).contains("line 21, column 5: \"nan\" is not a finite number"));
        let twice = DUMP.replace("1.181025e+06 7", "3 5");
        assert!(
            error(&twice).contains("lines 20 and 21: the pair of particles 3 and 5 appears twice"),
            "{}",
            error(&twice)
        );
        let itself = DUMP.replace("5 3 1", "5 5 1");
        assert!(error(&itself).contains("line 20: particle 5 in contact with itself"));
        let truncated = &DUMP[..DUMP.len() - 40];
        assert!(error(truncated).contains("2 entries announced, the file ends after 1"));
        assert!(error("1 2 0 0 0 0\n").contains("not a LIGGGHTS/LAMMPS `dump local` file"));
        let particles =
            "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: ATOMS id x y z radius\n1 0 0 0 1\n";
        assert!(error(particles).contains("no `ITEM: ENTRIES` section"));
    }
}
