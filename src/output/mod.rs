//! Run output: HDF5 frames with an XDMF companion for ParaView (`hdf5` feature, on by default),
//! the per-step time series (in HDF5 `/series` and optionally CSV), and restart data.
//! The layout is documented in `docs/output-format.md`. Existing files are never overwritten
//! unless the user says so. SI units throughout.

pub mod csv;
pub mod frame;
#[cfg(feature = "hdf5")]
pub mod hdf5;
pub mod xdmf;

use std::path::{Path, PathBuf};

use crate::simulation::{Diagnostics, Simulation};

/// Why an output file could not be written or read.
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
    /// An error reported by the HDF5 library.
    #[error("HDF5 error on {}: {message}", path.display())]
    Hdf5 {
        /// The file.
        path: PathBuf,
        /// The library's message.
        message: String,
    },
    /// The file is not an am-sim output of a supported version, or lacks data.
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// Element type of a series column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesKind {
    /// 64-bit float.
    F64,
    /// 64-bit unsigned integer (counts, steps).
    U64,
}

/// One column of the time series: name (with its unit as a suffix, as in scene keys), unit and type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeriesColumn {
    /// Column name, e.g. `kinetic_energy_j`.
    pub name: &'static str,
    /// SI unit (`1` for counts).
    pub unit: &'static str,
    /// Element type.
    pub kind: SeriesKind,
}

const fn column(name: &'static str, unit: &'static str, kind: SeriesKind) -> SeriesColumn {
    SeriesColumn { name, unit, kind }
}

/// Columns of every run.
pub const SERIES_COLUMNS: [SeriesColumn; 17] = [
    column("step", "1", SeriesKind::U64),
    column("time_s", "s", SeriesKind::F64),
    column("kinetic_energy_j", "J", SeriesKind::F64),
    column("gravitational_energy_j", "J", SeriesKind::F64),
    column("elastic_energy_j", "J", SeriesKind::F64),
    column("mechanical_energy_j", "J", SeriesKind::F64),
    column("contacts", "1", SeriesKind::U64),
    column("wall_contacts", "1", SeriesKind::U64),
    column("bonds", "1", SeriesKind::U64),
    column("max_overlap_m", "m", SeriesKind::F64),
    column("max_overlap_ratio", "1", SeriesKind::F64),
    column("wall_time_s", "s", SeriesKind::F64),
    column("dissipated_energy_j", "J", SeriesKind::F64),
    column("energy_residual", "1", SeriesKind::F64),
    column("peak_overlap_ratio", "1", SeriesKind::F64),
    column("stability_ratio", "1", SeriesKind::F64),
    column("removed_particles", "1", SeriesKind::U64),
];

/// Columns added for scenes with `[thermal]` (and only for them).
pub const THERMAL_COLUMNS: [SeriesColumn; 8] = [
    column("enthalpy_j", "J", SeriesKind::F64),
    column("laser_energy_j", "J", SeriesKind::F64),
    column("boundary_heat_j", "J", SeriesKind::F64),
    column("max_temperature_k", "K", SeriesKind::F64),
    column("melted", "1", SeriesKind::U64),
    column("thermal_substeps", "1", SeriesKind::U64),
    column("thermal_step_ratio", "1", SeriesKind::F64),
    column("heat_residual", "1", SeriesKind::F64),
];

/// Columns added for scenes with a material that evaporates (M.80; and only for them).
pub const EVAPORATION_COLUMNS: [SeriesColumn; 2] = [
    column("evaporated_heat_j", "J", SeriesKind::F64),
    column("evaporated_mass_kg", "kg", SeriesKind::F64),
];

/// Which of the optional column groups a run's series has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SeriesLayout {
    /// [`THERMAL_COLUMNS`]: the scene has `[thermal]`.
    pub thermal: bool,
    /// [`EVAPORATION_COLUMNS`]: and a material with a boiling point.
    pub evaporation: bool,
}

impl SeriesLayout {
    /// The layout of `sim`'s series.
    #[must_use]
    pub fn of(sim: &Simulation) -> Self {
        Self {
            thermal: sim.thermal.is_some(),
            evaporation: sim
                .thermal
                .as_ref()
                .is_some_and(|t| t.evaporation.is_some()),
        }
    }
}

/// The columns of a run's series.
#[must_use]
pub fn series_columns(layout: SeriesLayout) -> Vec<SeriesColumn> {
    let mut columns = SERIES_COLUMNS.to_vec();
    if layout.thermal {
        columns.extend(THERMAL_COLUMNS);
        if layout.evaporation {
            columns.extend(EVAPORATION_COLUMNS);
        }
    }
    columns
}

/// One value of a series row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SeriesValue {
    /// A float.
    F64(f64),
    /// A count.
    U64(u64),
}

/// The row of [`series_columns`] for diagnostics `d` taken `wall_time_s` after the start.
#[must_use]
pub fn series_row(d: &Diagnostics, wall_time_s: f64) -> Vec<SeriesValue> {
    use SeriesValue::{F64, U64};
    let count = |n: usize| U64(n as u64);
    let mut row = vec![
        U64(d.step),
        F64(d.time),
        F64(d.kinetic_energy),
        F64(d.gravitational_energy),
        F64(d.elastic_energy),
        F64(d.mechanical_energy()),
        count(d.contacts),
        count(d.wall_contacts),
        count(d.bonds),
        F64(d.max_overlap),
        F64(d.max_overlap_ratio),
        F64(wall_time_s),
        F64(d.dissipated_energy),
        F64(d.energy_residual),
        F64(d.peak_overlap_ratio),
        F64(d.stability_ratio),
        U64(d.removed_particles),
    ];
    if let Some(t) = d.thermal {
        row.extend([
            F64(t.enthalpy),
            F64(t.laser_energy),
            F64(t.boundary_energy),
            F64(t.max_temperature),
            count(t.melted),
            U64(u64::from(t.substeps)),
            F64(t.time_step_ratio),
            F64(t.heat_residual),
        ]);
        if let Some(e) = t.evaporation {
            row.extend([F64(e.heat), F64(e.mass)]);
        }
    }
    row
}

/// All the writers of a run, with their cadences.
#[derive(Debug)]
pub struct Writers {
    #[cfg(feature = "hdf5")]
    hdf5: Option<hdf5::OutputFile>,
    csv: Option<csv::SeriesWriter>,
    frame_every: u64,
    series_every: u64,
    last_frame: Option<u64>,
    last_row: Option<u64>,
}

impl Writers {
    /// Opens the files the scene asks for. With `restart_from`, frames and series go on in that
    /// HDF5 file after the step the run resumes from (later frames and rows, from a run killed
    /// after its last restart point, are dropped), and likewise in the CSV.
    ///
    /// # Errors
    /// [`OutputError::Exists`] for an existing file without `overwrite`; I/O and HDF5 errors.
    pub fn open(
        sim: &Simulation,
        scene_text: &str,
        overwrite: bool,
        restart_from: Option<&Path>,
    ) -> Result<Self, OutputError> {
        let settings = &sim.model.output;
        let layout = SeriesLayout::of(sim);
        // Both names are checked before either file is made: a run refused for its CSV leaves
        // no new HDF5 file behind.
        if !overwrite && restart_from.is_none() {
            if let Some(path) = settings.series_csv.as_ref().filter(|p| p.exists()) {
                return Err(OutputError::Exists(path.clone()));
            }
        }
        // The HDF5 file first: if it cannot be opened, the CSV has not been touched.
        #[cfg(feature = "hdf5")]
        let hdf5 = match (restart_from, &settings.file) {
            (Some(path), _) => Some(hdf5::OutputFile::open_append(
                path,
                layout,
                settings.deflate,
                sim.step,
            )?),
            (None, Some(path)) => Some(hdf5::OutputFile::create(
                path,
                overwrite,
                scene_text,
                layout,
                settings.deflate,
            )?),
            (None, None) => None,
        };
        #[cfg(not(feature = "hdf5"))]
        let _ = scene_text;
        let csv = match &settings.series_csv {
            Some(path) if restart_from.is_some() => {
                Some(csv::SeriesWriter::append(path, layout, sim.step)?)
            }
            Some(path) => Some(csv::SeriesWriter::create(path, overwrite, layout)?),
            None => None,
        };
        let resumed = restart_from.map(|_| sim.step);
        Ok(Self {
            #[cfg(feature = "hdf5")]
            hdf5,
            csv,
            frame_every: settings.frame_every,
            series_every: settings.series_every,
            last_frame: resumed,
            last_row: resumed,
        })
    }

    /// Whether anything is due at the current step (`last`: the final step of the run, when a
    /// frame and a row are always written).
    #[must_use]
    pub fn due(&self, step: u64, last: bool) -> bool {
        let fresh = |done: Option<u64>| done != Some(step);
        (fresh(self.last_frame) && (last || step % self.frame_every == 0))
            || (fresh(self.last_row) && (last || step % self.series_every == 0))
    }

    /// The step of the last frame written (or of the restart point), if any.
    #[must_use]
    pub fn last_frame_step(&self) -> Option<u64> {
        self.last_frame
    }

    /// Writes what is due at the current state (see [`Writers::due`]); `d` are its diagnostics.
    ///
    /// # Errors
    /// I/O and HDF5 errors.
    pub fn write(
        &mut self,
        sim: &Simulation,
        d: &Diagnostics,
        wall_time_s: f64,
        last: bool,
    ) -> Result<(), OutputError> {
        let step = sim.step;
        if self.last_row != Some(step) && (last || step % self.series_every == 0) {
            if let Some(csv) = &mut self.csv {
                csv.write(d, wall_time_s)?;
            }
            #[cfg(feature = "hdf5")]
            if let Some(file) = &mut self.hdf5 {
                file.append_series(&series_row(d, wall_time_s))?;
            }
            self.last_row = Some(step);
        }
        if self.last_frame != Some(step) && (last || step % self.frame_every == 0) {
            #[cfg(feature = "hdf5")]
            if let Some(file) = &mut self.hdf5 {
                let settings = &sim.model.output;
                let restart = settings.restart.then(|| sim.restart_state());
                file.write_frame(&frame::capture(sim, &settings.fields), restart.as_ref())?;
            }
            self.last_frame = Some(step);
        }
        Ok(())
    }

    /// The files being written, for the end-of-run message.
    #[must_use]
    pub fn files(&self, sim: &Simulation) -> Vec<String> {
        let mut files = Vec::new();
        #[cfg(feature = "hdf5")]
        if let Some(file) = &self.hdf5 {
            files.push(format!(
                "{} frames in {} (ParaView: File > Open {})",
                file.frame_count(),
                file.path().display(),
                file.xdmf_path().display()
            ));
        }
        if let Some(path) = &sim.model.output.series_csv {
            files.push(format!("time series in {}", path.display()));
        }
        files
    }

    /// Flushes and closes everything.
    ///
    /// # Errors
    /// HDF5 errors.
    pub fn close(self) -> Result<(), OutputError> {
        #[cfg(feature = "hdf5")]
        if let Some(file) = self.hdf5 {
            file.close()?;
        }
        Ok(())
    }
}
