//! Run output. For now a CSV time series (one row per output step); HDF5 frames follow.
//! An existing file is never overwritten unless the user says so.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::simulation::Diagnostics;

/// Why an output file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The file exists and `--overwrite` was not given.
    #[error("output file {} already exists: remove it, choose another name, or pass --overwrite", .0.display())]
    Exists(PathBuf),
    /// An I/O error.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Column names of the series CSV, in order (SI units in the names).
pub const SERIES_COLUMNS: [&str; 12] = [
    "step",
    "time_s",
    "kinetic_energy_j",
    "gravitational_energy_j",
    "elastic_energy_j",
    "mechanical_energy_j",
    "contacts",
    "wall_contacts",
    "bonds",
    "max_overlap_m",
    "max_overlap_ratio",
    "wall_time_s",
];

/// Columns added for scenes with `[thermal]` (and only for them).
pub const THERMAL_COLUMNS: [&str; 6] = [
    "enthalpy_j",
    "laser_energy_j",
    "boundary_heat_j",
    "max_temperature_k",
    "melted",
    "thermal_substeps",
];

/// Writes the time series, flushing every row so a killed run keeps what it wrote.
#[derive(Debug)]
pub struct SeriesWriter {
    path: PathBuf,
    out: BufWriter<File>,
    thermal: bool,
}

impl SeriesWriter {
    /// Creates the file and writes the header.
    ///
    /// # Errors
    /// [`OutputError::Exists`] if the file exists and `overwrite` is false; I/O errors.
    /// `thermal` adds the [`THERMAL_COLUMNS`].
    pub fn create(path: &Path, overwrite: bool, thermal: bool) -> Result<Self, OutputError> {
        let io = |source| OutputError::Io {
            path: path.to_owned(),
            source,
        };
        let opened = if overwrite {
            File::create(path)
        } else {
            File::create_new(path)
        };
        let file = opened.map_err(|e| {
            if e.kind() == std::io::ErrorKind::AlreadyExists {
                OutputError::Exists(path.to_owned())
            } else {
                io(e)
            }
        })?;
        let mut writer = Self {
            path: path.to_owned(),
            out: BufWriter::new(file),
            thermal,
        };
        let mut header = SERIES_COLUMNS.join(",");
        if thermal {
            header = format!("{header},{}", THERMAL_COLUMNS.join(","));
        }
        writer.line(&header)?;
        Ok(writer)
    }

    /// Appends one row.
    ///
    /// # Errors
    /// I/O errors.
    pub fn write(&mut self, d: &Diagnostics, wall_time_s: f64) -> Result<(), OutputError> {
        let mut row = format!(
            "{},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{},{},{},{:.9e},{:.6e},{:.3}",
            d.step,
            d.time,
            d.kinetic_energy,
            d.gravitational_energy,
            d.elastic_energy,
            d.mechanical_energy(),
            d.contacts,
            d.wall_contacts,
            d.bonds,
            d.max_overlap,
            d.max_overlap_ratio,
            wall_time_s
        );
        if self.thermal {
            let t = d.thermal.unwrap_or_default();
            row += &format!(
                ",{:.9e},{:.9e},{:.9e},{:.6e},{},{}",
                t.enthalpy,
                t.laser_energy,
                t.boundary_energy,
                t.max_temperature,
                t.melted,
                t.substeps
            );
        }
        self.line(&row)
    }

    fn line(&mut self, text: &str) -> Result<(), OutputError> {
        writeln!(self.out, "{text}")
            .and_then(|()| self.out.flush())
            .map_err(|source| OutputError::Io {
                path: self.path.clone(),
                source,
            })
    }
}
