//! Reading particles from files: am-sim's CSV, LIGGGHTS/LAMMPS `dump custom` text, and a frame
//! of an am-sim HDF5 output file. Text files may be gzip-compressed (name ending in `.gz`).
//! All values are SI (m, m/s); a scene's `[[import]]` may scale and shift them.

use std::io::Read;
use std::path::Path;

use glam::DVec3;

/// One particle as read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedParticle {
    /// The file's id, if it has one (rows are sorted by it).
    pub id: Option<u64>,
    /// Centre \[m\].
    pub position: DVec3,
    /// Velocity [m/s] (zero if the file has none).
    pub velocity: DVec3,
    /// Radius \[m\].
    pub radius: f64,
    /// Material name, if the file gives one (CSV `material` column).
    pub material: Option<String>,
    /// Angular velocity ω [rad/s], if the file gives one (dump `omegax omegay omegaz`).
    pub angular_velocity: Option<DVec3>,
    /// Tangential springs ξ \[m\] against walls, one per requested column prefix of a dump
    /// (see [`read_liggghts_dump`]); empty otherwise, and when all of them are zero.
    pub wall_history: Vec<DVec3>,
}

/// Columns of am-sim's particle CSV: `x_m`, `y_m`, `z_m`, `radius_m` required, the rest optional.
pub const CSV_COLUMNS: [&str; 9] = [
    "id", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", "radius_m", "material",
];

/// True when `path` names a gzip file (its name ends in `.gz`).
fn is_gzip(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"))
}

/// Opens a text file for reading line by line, gunzipping it when its name ends in `.gz`.
///
/// # Errors
/// The I/O error, as text.
pub fn open_text(path: &Path) -> Result<Box<dyn std::io::BufRead>, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    Ok(if is_gzip(path) {
        Box::new(std::io::BufReader::new(flate2::read::MultiGzDecoder::new(
            std::io::BufReader::new(file),
        )))
    } else {
        Box::new(std::io::BufReader::new(file))
    })
}

/// Reads a whole text file, gunzipping it when its name ends in `.gz`.
///
/// # Errors
/// The I/O or decompression error, as text.
pub fn read_text(path: &Path) -> Result<String, String> {
    let mut text = String::new();
    open_text(path)?.read_to_string(&mut text).map_err(|e| {
        format!(
            "cannot read{}: {e}",
            if is_gzip(path) { " (gzip)" } else { "" }
        )
    })?;
    Ok(text)
}

fn number(text: &str, line: usize, column: &str) -> Result<f64, String> {
    let value: f64 = text
        .parse()
        .map_err(|_| format!("line {line}, column `{column}`: \"{text}\" is not a number"))?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(format!(
            "line {line}, column `{column}`: {text} is not finite"
        ))
    }
}

fn particle_id(text: &str, line: usize) -> Result<u64, String> {
    text.parse()
        .map_err(|_| format!("line {line}, column `id`: \"{text}\" is not a non-negative integer"))
}

fn check_radius(radius: f64, line: usize, column: &str) -> Result<f64, String> {
    if radius > 0.0 {
        Ok(radius)
    } else {
        Err(format!(
            "line {line}, column `{column}`: {radius} must be > 0"
        ))
    }
}

/// Sorts by file id when every row has one, and rejects repeated ids.
fn sort_by_id(mut rows: Vec<ImportedParticle>) -> Result<Vec<ImportedParticle>, String> {
    if rows.iter().all(|p| p.id.is_some()) {
        rows.sort_by_key(|p| p.id);
        if let Some(w) = rows.windows(2).find(|w| w[0].id == w[1].id) {
            return Err(format!(
                "id {} appears more than once",
                w[0].id.unwrap_or_default()
            ));
        }
    }
    Ok(rows)
}

/// Parses am-sim's particle CSV: a header row naming the columns (any order, from
/// [`CSV_COLUMNS`]), then one particle a row. Blank lines and lines starting with `#` are
/// skipped. With an `id` column the rows are returned sorted by id.
///
/// # Errors
/// A message naming the line and column of the first problem.
pub fn parse_csv(text: &str) -> Result<Vec<ImportedParticle>, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (header_line, header) = lines.next().ok_or("the file has no header row")?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    for name in &names {
        if !CSV_COLUMNS.contains(name) {
            return Err(format!(
                "line {header_line}: unknown column `{name}`; known columns: {}",
                CSV_COLUMNS.join(", ")
            ));
        }
        if names.iter().filter(|n| *n == name).count() > 1 {
            return Err(format!("line {header_line}: column `{name}` appears twice"));
        }
    }
    let column = |name: &str| names.iter().position(|n| *n == name);
    let required = |name: &str| {
        column(name).ok_or_else(|| {
            format!("line {header_line}: the header has no `{name}` column (x_m, y_m, z_m and radius_m are required)")
        })
    };
    let position = [required("x_m")?, required("y_m")?, required("z_m")?];
    let radius = required("radius_m")?;
    let velocity = [column("vx_m_s"), column("vy_m_s"), column("vz_m_s")];
    let (id, material) = (column("id"), column("material"));
    let mut rows = Vec::new();
    for (line, text) in lines {
        let cells: Vec<&str> = text.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            return Err(format!(
                "line {line}: {} cells, the header names {}",
                cells.len(),
                names.len()
            ));
        }
        let value = |k: usize| number(cells[k], line, names[k]);
        let optional = |k: Option<usize>| k.map_or(Ok(0.0), value);
        rows.push(ImportedParticle {
            id: id.map(|k| particle_id(cells[k], line)).transpose()?,
            position: DVec3::new(
                value(position[0])?,
                value(position[1])?,
                value(position[2])?,
            ),
            velocity: DVec3::new(
                optional(velocity[0])?,
                optional(velocity[1])?,
                optional(velocity[2])?,
            ),
            radius: check_radius(value(radius)?, line, "radius_m")?,
            material: material
                .map(|k| cells[k].to_string())
                .filter(|m| !m.is_empty()),
            angular_velocity: None,
            wall_history: Vec::new(),
        });
    }
    sort_by_id(rows)
}

/// Writes particles as am-sim's particle CSV (all columns but `material`), with Rust's
/// shortest round-trip formatting of `f64`, so [`parse_csv`] reads back the same bits.
#[must_use]
pub fn write_csv(id: &[u64], position: &[DVec3], velocity: &[DVec3], radius: &[f64]) -> String {
    let mut out = String::from("id,x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s,radius_m\n");
    for k in 0..id.len() {
        let (x, v) = (position[k], velocity[k]);
        out += &format!(
            "{},{:?},{:?},{:?},{:?},{:?},{:?},{:?}\n",
            id[k], x.x, x.y, x.z, v.x, v.y, v.z, radius[k]
        );
    }
    out
}

/// A snapshot of a LIGGGHTS/LAMMPS dump.
#[derive(Debug, Clone, PartialEq)]
pub struct DumpSnapshot {
    /// Its `ITEM: TIMESTEP`.
    pub timestep: u64,
    /// Its atoms, sorted by id when the dump has an `id` column.
    pub particles: Vec<ImportedParticle>,
}

/// Parses a LIGGGHTS/LAMMPS `dump custom` text and returns the snapshot of `timestep`, or the
/// last one; see [`read_liggghts_dump`].
///
/// # Errors
/// As [`read_liggghts_dump`].
pub fn parse_liggghts_dump(text: &str, timestep: Option<u64>) -> Result<DumpSnapshot, String> {
    read_liggghts_dump(text.as_bytes(), timestep, &[])
}

/// Reads a LIGGGHTS/LAMMPS `dump custom` file line by line and returns the snapshot of
/// `timestep`, or the last one. The `ITEM: ATOMS` header names the columns: `x y z` (or
/// unwrapped `xu yu zu`) and `radius` (or `diameter`) are required, `id`, `vx vy vz` and
/// `omegax omegay omegaz` optional, other columns (type, forces, ...) ignored. For each prefix
/// `P` of `wall_history` the columns `P[1] P[2] P[3]` are required and read into
/// [`ImportedParticle::wall_history`] (LIGGGHTS keeps the tangential springs of a `fix ID
/// wall/gran ... tangential history` per atom, in the fix `history_ID`: `f_history_ID[1]` ...).
/// Values are taken as they are: SI for LIGGGHTS' `units si`. Only the rows of one snapshot are held at a time, never the file's text (a dump of
/// 100k spheres is about 10 MB of text, more than the particles it describes).
///
/// # Errors
/// A message naming the line of the first problem in the chosen snapshot, or the timesteps the
/// file has.
pub fn read_liggghts_dump(
    reader: impl std::io::BufRead,
    timestep: Option<u64>,
    wall_history: &[String],
) -> Result<DumpSnapshot, String> {
    let mut lines = reader.lines().enumerate().map(|(k, line)| {
        line.map(|l| (k + 1, l))
            .map_err(|e| format!("line {}: cannot read: {e}", k + 1))
    });
    let mut next = || lines.next().transpose();
    let mut timesteps: Vec<u64> = Vec::new();
    // The snapshot taken so far (a later one of the wanted timestep replaces it), or why it failed.
    let mut chosen: Option<Result<DumpSnapshot, String>> = None;
    let mut pending = next()?;
    while let Some((number, line)) = pending.take() {
        if !line.trim_start().starts_with("ITEM: TIMESTEP") {
            pending = next()?;
            continue;
        }
        let value = next()?.map(|(_, l)| l).unwrap_or_default();
        let step: u64 = value.trim().parse().map_err(|_| {
            format!(
                "line {}: timestep \"{}\" is not an integer",
                number + 1,
                value.trim()
            )
        })?;
        timesteps.push(step);
        let wanted = timestep.is_none_or(|t| t == step);
        // The snapshot's items, up to the next TIMESTEP line (left in `pending`) or the end.
        let mut count: Option<usize> = None;
        let mut snapshot: Option<Result<DumpSnapshot, String>> = None;
        while let Some((k, item)) = next()? {
            let item_text = item.trim();
            if item_text.starts_with("ITEM: TIMESTEP") {
                pending = Some((k, item));
                break;
            }
            if item_text.starts_with("ITEM: NUMBER OF ATOMS") {
                let value = next()?.map(|(_, l)| l).unwrap_or_default();
                count = Some(value.trim().parse().map_err(|_| {
                    format!(
                        "line {}: number of atoms \"{}\" is not an integer",
                        k + 1,
                        value.trim()
                    )
                })?);
            } else if let Some(columns) = item_text.strip_prefix("ITEM: ATOMS") {
                let n = count.ok_or(format!(
                    "line {k}: `ITEM: ATOMS` before `ITEM: NUMBER OF ATOMS`"
                ))?;
                let columns = columns.to_string();
                let rows = read_dump_atoms(&mut next, k, &columns, n, wanted, wall_history);
                snapshot = Some(rows.and_then(|rows| {
                    Ok(DumpSnapshot {
                        timestep: step,
                        particles: sort_by_id(rows)?,
                    })
                }));
            }
        }
        if wanted {
            chosen = Some(snapshot.unwrap_or_else(|| {
                Err(format!(
                    "the snapshot of timestep {step} (line {number}) has no `ITEM: ATOMS` section"
                ))
            }));
        }
    }
    match (chosen, timestep) {
        (Some(snapshot), _) => snapshot,
        (None, None) => Err("no `ITEM: TIMESTEP` line: not a LAMMPS/LIGGGHTS dump file".into()),
        (None, Some(t)) => Err(format!(
            "no snapshot of timestep {t}; the file has timesteps {timesteps:?}"
        )),
    }
}

/// The `n` rows under the `ITEM: ATOMS` header `columns` (on line `header`), read from `next`;
/// parsed when `wanted`, otherwise only skipped. `wall_history` as in [`read_liggghts_dump`].
fn read_dump_atoms(
    next: &mut impl FnMut() -> Result<Option<(usize, String)>, String>,
    header: usize,
    columns: &str,
    n: usize,
    wanted: bool,
    wall_history: &[String],
) -> Result<Vec<ImportedParticle>, String> {
    let names: Vec<&str> = columns.split_whitespace().collect();
    let column = |name: &str| names.iter().position(|c| *c == name);
    let either = |a: &str, b: &str| column(a).or_else(|| column(b));
    let position = match [either("x", "xu"), either("y", "yu"), either("z", "zu")] {
        [Some(x), Some(y), Some(z)] => [x, y, z],
        _ if column("xs").is_some() => {
            return Err(format!(
                "line {header}: scaled coordinates (xs ys zs) are not supported: dump `x y z`"
            ));
        }
        _ => {
            return Err(format!(
                "line {header}: the ATOMS header [{columns}] lacks x, y or z"
            ));
        }
    };
    let (radius, halve) = match (column("radius"), column("diameter")) {
        (Some(k), _) => (k, false),
        (None, Some(k)) => (k, true),
        (None, None) => {
            return Err(format!(
                "line {header}: the ATOMS header [{columns}] has no `radius` (or `diameter`) column"
            ));
        }
    };
    let velocity = [column("vx"), column("vy"), column("vz")];
    let spin = match [column("omegax"), column("omegay"), column("omegaz")] {
        [Some(x), Some(y), Some(z)] => Some([x, y, z]),
        [None, None, None] => None,
        _ => {
            return Err(format!(
                "line {header}: the ATOMS header [{columns}] has some of omegax, omegay, omegaz but not all three"
            ));
        }
    };
    let walls = wall_history
        .iter()
        .map(|prefix| {
            let [x, y, z] = [1, 2, 3].map(|c| column(&format!("{prefix}[{c}]")));
            match (x, y, z) {
                (Some(x), Some(y), Some(z)) => Ok([x, y, z]),
                _ => Err(format!(
                    "line {header}: the ATOMS header [{columns}] lacks {prefix}[1], {prefix}[2] or {prefix}[3] (the wall springs asked for)"
                )),
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let id = column("id");
    let mut rows = Vec::with_capacity(if wanted { n } else { 0 });
    for read in 0..n {
        let Some((line, text)) = next()? else {
            return Err(format!(
                "line {header}: {n} atoms announced, the file ends after {read}"
            ));
        };
        if !wanted {
            continue;
        }
        let cells: Vec<&str> = text.split_whitespace().collect();
        if cells.len() != names.len() {
            return Err(format!(
                "line {line}: {} values, the ATOMS header names {}",
                cells.len(),
                names.len()
            ));
        }
        let value = |k: usize| number(cells[k], line, names[k]);
        let optional = |k: Option<usize>| k.map_or(Ok(0.0), value);
        // Three columns [x, y, z] as a vector.
        let vector =
            |[x, y, z]: [usize; 3]| Ok::<_, String>(DVec3::new(value(x)?, value(y)?, value(z)?));
        let r = value(radius)?;
        rows.push(ImportedParticle {
            id: id.map(|k| particle_id(cells[k], line)).transpose()?,
            position: vector(position)?,
            velocity: DVec3::new(
                optional(velocity[0])?,
                optional(velocity[1])?,
                optional(velocity[2])?,
            ),
            radius: check_radius(if halve { 0.5 * r } else { r }, line, names[radius])?,
            material: None,
            angular_velocity: spin.map(vector).transpose()?,
            wall_history: {
                let springs = walls
                    .iter()
                    .map(|&columns| vector(columns))
                    .collect::<Result<Vec<_>, String>>()?;
                // Most particles touch no wall: no allocation for them.
                if springs.iter().all(|s| *s == DVec3::ZERO) {
                    Vec::new()
                } else {
                    springs
                }
            },
        });
    }
    Ok(rows)
}

/// Reads frame `frame` (default: the last complete one) of an am-sim HDF5 output file, rows
/// sorted by particle id.
///
/// # Errors
/// The HDF5 or format error as text.
#[cfg(feature = "hdf5")]
pub fn read_am_sim_h5(path: &Path, frame: Option<usize>) -> Result<Vec<ImportedParticle>, String> {
    let f = crate::output::hdf5::read_frame_particles(path, frame).map_err(|e| e.to_string())?;
    let rows = (0..f.id.len())
        .map(|k| ImportedParticle {
            id: Some(f.id[k]),
            position: f.position[k],
            velocity: f.velocity[k],
            radius: f.radius[k],
            material: None,
            angular_velocity: None,
            wall_history: Vec::new(),
        })
        .collect();
    sort_by_id(rows)
}

/// Without the `hdf5` feature: always an error saying so.
///
/// # Errors
/// Always.
#[cfg(not(feature = "hdf5"))]
pub fn read_am_sim_h5(
    _path: &Path,
    _frame: Option<usize>,
) -> Result<Vec<ImportedParticle>, String> {
    Err("this am-sim was built without HDF5 (cargo feature `hdf5`)".into())
}
