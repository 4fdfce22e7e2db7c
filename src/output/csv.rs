//! The time series as CSV: one row per output step, header included, each row flushed so a
//! killed run keeps what it wrote. Same columns as the HDF5 `/series`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::{OutputError, SeriesLayout, SeriesValue, series_columns, series_row};
use crate::simulation::Diagnostics;

/// Writes the time series CSV.
#[derive(Debug)]
pub struct SeriesWriter {
    path: PathBuf,
    out: BufWriter<File>,
}

impl SeriesWriter {
    /// Creates the file and writes the header; `layout` names the optional column groups.
    ///
    /// # Errors
    /// [`OutputError::Exists`] if the file exists and `overwrite` is false; I/O errors.
    pub fn create(path: &Path, overwrite: bool, layout: SeriesLayout) -> Result<Self, OutputError> {
        if overwrite && path.exists() {
            // Unlink rather than truncate, as for the HDF5 file: a reader keeps the old rows.
            std::fs::remove_file(path).map_err(|source| OutputError::Io {
                path: path.to_owned(),
                source,
            })?;
        }
        let file = File::create_new(path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::AlreadyExists {
                OutputError::Exists(path.to_owned())
            } else {
                OutputError::Io {
                    path: path.to_owned(),
                    source: e,
                }
            }
        })?;
        let mut writer = Self {
            path: path.to_owned(),
            out: BufWriter::new(file),
        };
        let header: Vec<&str> = series_columns(layout).iter().map(|c| c.name).collect();
        writer.line(&header.join(","))?;
        Ok(writer)
    }
    /// Opens an existing CSV to continue a run resumed at `step`: rows after it (written by the
    /// run before it was killed) are dropped, so no step appears twice. Creates the file if missing.
    ///
    /// # Errors
    /// I/O errors.
    pub fn append(path: &Path, layout: SeriesLayout, step: u64) -> Result<Self, OutputError> {
        if !path.exists() {
            return Self::create(path, false, layout);
        }
        let io = |source| OutputError::Io {
            path: path.to_owned(),
            source,
        };
        let text = std::fs::read_to_string(path).map_err(io)?;
        let kept: Vec<&str> = text
            .lines()
            .enumerate()
            .filter(|(k, line)| {
                *k == 0
                    || line
                        .split(',')
                        .next()
                        .and_then(|s| s.parse::<u64>().ok())
                        .is_some_and(|s| s <= step)
            })
            .map(|(_, line)| line)
            .collect();
        let tmp = path.with_extension("csv.tmp");
        std::fs::write(&tmp, kept.join("\n") + "\n").map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)?;
        let file = File::options()
            .append(true)
            .open(path)
            .map_err(|source| OutputError::Io {
                path: path.to_owned(),
                source,
            })?;
        Ok(Self {
            path: path.to_owned(),
            out: BufWriter::new(file),
        })
    }

    /// Appends one row.
    ///
    /// # Errors
    /// I/O errors.
    pub fn write(&mut self, d: &Diagnostics, wall_time_s: f64) -> Result<(), OutputError> {
        let cells: Vec<String> = series_row(d, wall_time_s)
            .into_iter()
            .map(|v| match v {
                SeriesValue::F64(x) => format!("{x:.9e}"),
                SeriesValue::U64(n) => n.to_string(),
            })
            .collect();
        self.line(&cells.join(","))
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
