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
    /// Centre [m].
    pub position: DVec3,
    /// Velocity [m/s] (zero if the file has none).
    pub velocity: DVec3,
    /// Radius [m].
    pub radius: f64,
    /// Material name, if the file gives one (CSV `material` column).
    pub material: Option<String>,
}

/// Columns of am-sim's particle CSV: `x_m`, `y_m`, `z_m`, `radius_m` required, the rest optional.
pub const CSV_COLUMNS: [&str; 9] = [
    "id", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", "radius_m", "material",
];

/// Reads a whole text file, gunzipping it when its name ends in `.gz`.
///
/// # Errors
/// The I/O or decompression error, as text.
pub fn read_text(path: &Path) -> Result<String, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    let mut text = String::new();
    let gz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    let read = if gz {
        flate2::read::MultiGzDecoder::new(std::io::BufReader::new(file)).read_to_string(&mut text)
    } else {
        std::io::BufReader::new(file).read_to_string(&mut text)
    };
    read.map_err(|e| format!("cannot read{}: {e}", if gz { " (gzip)" } else { "" }))?;
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

/// Parses a LIGGGHTS/LAMMPS `dump custom` text file and returns the snapshot of `timestep`, or
/// the last one. The `ITEM: ATOMS` header names the columns: `x y z` (or unwrapped `xu yu zu`)
/// and `radius` (or `diameter`) are required, `id` and `vx vy vz` optional, other columns
/// (type, forces, ...) ignored. Values are taken as they are: SI for LIGGGHTS' `units si`.
///
/// # Errors
/// A message naming the line of the first problem, or the timesteps the file has.
pub fn parse_liggghts_dump(text: &str, timestep: Option<u64>) -> Result<DumpSnapshot, String> {
    let lines: Vec<&str> = text.lines().collect();
    // (timestep, index of its TIMESTEP line)
    let mut snapshots: Vec<(u64, usize)> = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        if line.trim_start().starts_with("ITEM: TIMESTEP") {
            let value = lines.get(k + 1).map_or("", |l| l.trim());
            let step = value
                .parse()
                .map_err(|_| format!("line {}: timestep \"{value}\" is not an integer", k + 2))?;
            snapshots.push((step, k));
        }
    }
    let &(step, start) = match timestep {
        None => snapshots
            .last()
            .ok_or("no `ITEM: TIMESTEP` line: not a LAMMPS/LIGGGHTS dump file")?,
        Some(t) => snapshots.iter().rev().find(|s| s.0 == t).ok_or_else(|| {
            let have: Vec<u64> = snapshots.iter().map(|s| s.0).collect();
            format!("no snapshot of timestep {t}; the file has timesteps {have:?}")
        })?,
    };
    let mut k = start + 2;
    let mut count: Option<usize> = None;
    while k < lines.len() {
        let line = lines[k].trim();
        k += 1;
        if line.starts_with("ITEM: NUMBER OF ATOMS") {
            let value = lines.get(k).map_or("", |l| l.trim());
            count = Some(value.parse().map_err(|_| {
                format!(
                    "line {}: number of atoms \"{value}\" is not an integer",
                    k + 1
                )
            })?);
        } else if let Some(columns) = line.strip_prefix("ITEM: ATOMS") {
            let n = count.ok_or(format!(
                "line {k}: `ITEM: ATOMS` before `ITEM: NUMBER OF ATOMS`"
            ))?;
            let particles = parse_dump_atoms(&lines, k, columns, n)?;
            return Ok(DumpSnapshot {
                timestep: step,
                particles: sort_by_id(particles)?,
            });
        } else if line.starts_with("ITEM: TIMESTEP") {
            break;
        }
    }
    Err(format!(
        "the snapshot of timestep {step} (line {}) has no `ITEM: ATOMS` section",
        start + 1
    ))
}

/// Rows `first..first + n` of `lines` under the `ITEM: ATOMS` header `columns`.
fn parse_dump_atoms(
    lines: &[&str],
    first: usize,
    columns: &str,
    n: usize,
) -> Result<Vec<ImportedParticle>, String> {
    let names: Vec<&str> = columns.split_whitespace().collect();
    let column = |name: &str| names.iter().position(|c| *c == name);
    let header = first; // 1-based number of the header line
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
    let id = column("id");
    if lines.len() < first + n {
        return Err(format!(
            "line {header}: {n} atoms announced, the file ends after {}",
            lines.len() - first
        ));
    }
    let mut rows = Vec::with_capacity(n);
    for (offset, text) in lines[first..first + n].iter().enumerate() {
        let line = first + offset + 1;
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
        let r = value(radius)?;
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
            radius: check_radius(if halve { 0.5 * r } else { r }, line, names[radius])?,
            material: None,
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
