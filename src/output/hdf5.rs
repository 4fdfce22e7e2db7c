//! HDF5 output: one file per run, one group per frame, the time series, restart data, and the
//! XDMF companion rewritten after every frame. Layout in `docs/output-format.md`:
//!
//! ```text
//! /                 attrs: format="am-sim", format_version=1 (u32), units="SI",
//!                          am_sim_version (str), scene (str: the full scene TOML)
//! /frames/000000    attrs: time (f64, s), step (u64), written last: they mark the frame complete
//!     id u64 [N], position f64 [N,3] m, velocity f64 [N,3] m/s, radius f64 [N] m,
//!     optional: force [N,3] N, contacts u64 [N], temperature [N] K, melted u8 [N],
//!               melt_fraction [N], bonds u64 [B,2] (rows of this frame), bond_overlap [B] m,
//!               bond_force [B] N
//!     restart/      what a resumed run needs besides the above (forces, bond ids, enthalpy, …)
//! /series/<column>  1-D, one row per series output (columns of `output::series_columns`)
//! /xdmf/point_index i64 0, 1, 2, …: Polyvertex connectivity for the XDMF file
//! ```
//!
//! Every frame is followed by `H5Fflush`: a killed run keeps every finished frame readable
//! (flush is not fsync: a power loss is another matter). While the file is open, other
//! processes need `HDF5_USE_FILE_LOCKING=FALSE` to read it (HDF5 1.10 file locking).

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, Group, H5Type};
use ndarray::{ArrayView1, ArrayView2};

use super::frame::{Frame, Values};
use super::xdmf::{self, FrameMeta, POINT_INDEX};
use super::{OutputError, SeriesColumn, SeriesKind, SeriesLayout, SeriesValue, series_columns};
use crate::laser::Snapshot;
use crate::simulation::{Removed, RestartState, RotationRestart, ThermalRestart};
use crate::thermal::LaserHeat;

/// Value of the root attribute `format`.
pub const FORMAT_NAME: &str = "am-sim";
/// Value of the root attribute `format_version`.
pub const FORMAT_VERSION: u32 = 1;
/// Rows per chunk of compressed frame datasets and of the series columns.
const CHUNK_ROWS: usize = 16_384;

type Result<T> = std::result::Result<T, OutputError>;

/// An output file being written frame by frame.
pub struct OutputFile {
    file: File,
    path: PathBuf,
    deflate: u8,
    frames: Vec<FrameMeta>,
    point_index_len: usize,
    columns: Vec<SeriesColumn>,
    /// When the XDMF file was last rewritten, and with how many frames.
    xdmf_written: Option<(std::time::Instant, usize)>,
}

/// Frames after which the XDMF file is rewritten at most every [`XDMF_REWRITE_INTERVAL`].
const XDMF_EAGER_FRAMES: usize = 16;
/// Shortest wall time between two XDMF rewrites once past [`XDMF_EAGER_FRAMES`].
const XDMF_REWRITE_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

impl std::fmt::Debug for OutputFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OutputFile")
            .field("path", &self.path)
            .field("frames", &self.frames.len())
            .finish_non_exhaustive()
    }
}

/// Converts library errors, naming the file.
trait Context<T> {
    fn on(self, path: &Path) -> Result<T>;
}

impl<T> Context<T> for hdf5::Result<T> {
    fn on(self, path: &Path) -> Result<T> {
        self.map_err(|e| OutputError::Hdf5 {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }
}

impl OutputFile {
    /// Creates the file (refusing to replace an existing one unless `overwrite`), with the root
    /// attributes, the series columns (the optional groups of `layout`) and an empty XDMF file.
    ///
    /// # Errors
    /// [`OutputError::Exists`], HDF5 and I/O errors.
    pub fn create(
        path: &Path,
        overwrite: bool,
        scene_text: &str,
        layout: SeriesLayout,
        deflate: u8,
    ) -> Result<Self> {
        if path.exists() {
            if !overwrite {
                return Err(OutputError::Exists(path.to_path_buf()));
            }
            // Unlink rather than truncate: a reader that has the old file open keeps it intact
            // (HDF5 would truncate it first and only then fail on the reader's lock).
            std::fs::remove_file(path).map_err(|source| OutputError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        }
        // create_excl also fails if the file appeared since the check above.
        let file = File::create_excl(path).on(path)?;
        let build = || -> hdf5::Result<()> {
            string_attr(&file, "format", FORMAT_NAME)?;
            file.new_attr::<u32>()
                .create("format_version")?
                .write_scalar(&FORMAT_VERSION)?;
            string_attr(&file, "units", "SI")?;
            string_attr(&file, "am_sim_version", env!("CARGO_PKG_VERSION"))?;
            string_attr(&file, "scene", scene_text)?;
            file.create_group("frames")?;
            let series = file.create_group("series")?;
            for c in series_columns(layout) {
                let builder = series.new_dataset_builder().chunk(1024);
                let ds = match c.kind {
                    SeriesKind::F64 => builder.empty::<f64>(),
                    SeriesKind::U64 => builder.empty::<u64>(),
                }
                .shape(0..)
                .create(c.name)?;
                string_attr(&ds, "units", c.unit)?;
            }
            file.create_group("xdmf")?
                .new_dataset::<i64>()
                .chunk(65_536)
                .shape(0..)
                .create("point_index")?;
            file.flush()
        };
        build().on(path)?;
        let mut out = Self {
            file,
            path: path.to_path_buf(),
            deflate,
            frames: Vec::new(),
            point_index_len: 0,
            columns: series_columns(layout),
            xdmf_written: None,
        };
        out.write_xdmf()?;
        Ok(out)
    }
    /// Reopens a file to continue a run resumed at `step`: drops the frames after it (and an
    /// incomplete one: a run killed while writing it), and the series rows after it.
    ///
    /// # Errors
    /// HDF5 errors, or [`OutputError::Format`] if it is not an am-sim file.
    pub fn open_append(path: &Path, layout: SeriesLayout, deflate: u8, step: u64) -> Result<Self> {
        let file = File::open_rw(path).on(path)?;
        check_format(&file, path)?;
        let frames_group = file.group("frames").on(path)?;
        let mut names = frame_names(&frames_group).on(path)?;
        while let Some(last) = names.last() {
            let group = frames_group.group(last).on(path)?;
            let complete = frame_is_complete(&group);
            if complete
                && group
                    .attr("step")
                    .and_then(|a| a.read_scalar::<u64>())
                    .on(path)?
                    <= step
            {
                break;
            }
            frames_group.unlink(last).on(path)?;
            names.pop();
        }
        let mut frames = Vec::new();
        for name in &names {
            frames.push(meta_of_group(&frames_group.group(name).on(path)?, name).on(path)?);
        }
        let series = file.group("series").on(path)?;
        let steps: Vec<u64> = series.dataset("step").and_then(|d| d.read_raw()).on(path)?;
        let keep = steps.iter().take_while(|s| **s <= step).count();
        for c in series_columns(layout) {
            series
                .dataset(c.name)
                .and_then(|d| d.resize(keep))
                .on(path)?;
        }
        let point_index_len = file.dataset(POINT_INDEX).on(path)?.shape()[0];
        file.flush().on(path)?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
            deflate,
            frames,
            point_index_len,
            columns: series_columns(layout),
            xdmf_written: None,
        })
    }

    /// Path of the HDF5 file.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Path of the XDMF companion (`<stem>.xmf`).
    #[must_use]
    pub fn xdmf_path(&self) -> PathBuf {
        self.path.with_extension("xmf")
    }

    /// Number of complete frames.
    #[must_use]
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// Appends frame `/frames/NNNNNN` (with restart data if given), flushes the file and
    /// rewrites the XDMF file. Returns the frame number.
    ///
    /// # Errors
    /// HDF5 and I/O errors.
    pub fn write_frame(&mut self, frame: &Frame, restart: Option<&RestartState>) -> Result<usize> {
        let index = self.frames.len();
        let name = format!("{index:06}");
        let n = frame.points.first().map_or(0, |f| f.values.len());
        let written = self
            .write_frame_group(&name, frame, restart)
            .and_then(|()| self.extend_point_index(n))
            .on(&self.path);
        if let Err(error) = written {
            // Leave the file as before this frame; the original error is the one to report.
            if let Ok(group) = self.file.group("frames") {
                let _ = group.unlink(&name);
            }
            return Err(error);
        }
        self.file.flush().on(&self.path)?;
        self.frames.push(FrameMeta::of(frame, name));
        // Rewriting the XDMF file costs O(frames): doing it for every frame made long runs
        // quadratic (1000 frames of two particles: a third of the run). The first frames go out
        // at once, so ParaView can open a fresh run; later ones at most once a second; `close`
        // writes the rest.
        let stale = self
            .xdmf_written
            .is_none_or(|(at, _)| at.elapsed() >= XDMF_REWRITE_INTERVAL);
        if self.frames.len() <= XDMF_EAGER_FRAMES || stale {
            self.write_xdmf()?;
        }
        Ok(index)
    }

    /// Appends one row to `/series` (flushed with the next frame or at close).
    ///
    /// # Errors
    /// HDF5 errors.
    pub fn append_series(&mut self, row: &[SeriesValue]) -> Result<()> {
        let series = self.file.group("series").on(&self.path)?;
        for (column, value) in self.columns.iter().zip(row) {
            let append = || -> hdf5::Result<()> {
                let ds = series.dataset(column.name)?;
                let len = ds.shape()[0];
                ds.resize(len + 1)?;
                match value {
                    SeriesValue::F64(x) => ds.write_slice(&[*x], len..=len),
                    SeriesValue::U64(x) => ds.write_slice(&[*x], len..=len),
                }
            };
            append().on(&self.path)?;
        }
        Ok(())
    }

    /// Flushes and closes the file.
    ///
    /// # Errors
    /// HDF5 errors.
    pub fn close(mut self) -> Result<()> {
        if self
            .xdmf_written
            .is_none_or(|(_, n)| n != self.frames.len())
        {
            self.write_xdmf()?;
        }
        self.file.flush().on(&self.path)?;
        self.file.close().on(&self.path)
    }

    fn write_frame_group(
        &self,
        name: &str,
        frame: &Frame,
        restart: Option<&RestartState>,
    ) -> hdf5::Result<()> {
        let group = self.file.group("frames")?.create_group(name)?;
        for field in &frame.points {
            self.write_values(&group, field.name, &field.values, field.unit)?;
        }
        if let Some(bonds) = &frame.bonds {
            self.write_rows(&group, "bonds", bonds, "1")?;
            for field in &frame.bond_fields {
                self.write_values(&group, field.name, &field.values, field.unit)?;
            }
        }
        if let Some(state) = restart {
            write_restart(&group.create_group("restart")?, state)?;
        }
        // Written last: their presence marks the frame as complete.
        group
            .new_attr::<f64>()
            .create("time")?
            .write_scalar(&frame.time)?;
        group
            .new_attr::<u64>()
            .create("step")?
            .write_scalar(&frame.step)?;
        Ok(())
    }

    fn write_values(
        &self,
        group: &Group,
        name: &str,
        values: &Values,
        unit: &str,
    ) -> hdf5::Result<()> {
        match values {
            Values::F64(v) => self.write_1d(group, name, v, unit),
            Values::U64(v) => self.write_1d(group, name, v, unit),
            Values::U8(v) => self.write_1d(group, name, v, unit),
            Values::Vec3(v) => self.write_rows(group, name, v, unit),
        }
    }

    fn write_1d<T: H5Type>(
        &self,
        group: &Group,
        name: &str,
        data: &[T],
        unit: &str,
    ) -> hdf5::Result<()> {
        let mut builder = group.new_dataset_builder();
        if self.deflate > 0 && !data.is_empty() {
            builder = builder
                .chunk(data.len().min(CHUNK_ROWS))
                .shuffle()
                .deflate(self.deflate);
        }
        let ds = builder.with_data(ArrayView1::from(data)).create(name)?;
        string_attr(&ds, "units", unit)
    }

    fn write_rows<T: H5Type, const C: usize>(
        &self,
        group: &Group,
        name: &str,
        data: &[[T; C]],
        unit: &str,
    ) -> hdf5::Result<()> {
        let view = ArrayView2::from_shape((data.len(), C), data.as_flattened())
            .expect("rows of C columns");
        let mut builder = group.new_dataset_builder();
        if self.deflate > 0 && !data.is_empty() {
            builder = builder
                .chunk((data.len().min(CHUNK_ROWS), C))
                .shuffle()
                .deflate(self.deflate);
        }
        let ds = builder.with_data(view).create(name)?;
        string_attr(&ds, "units", unit)
    }

    /// Grows [`POINT_INDEX`] to at least `n` entries.
    fn extend_point_index(&mut self, n: usize) -> hdf5::Result<()> {
        let old = self.point_index_len;
        if n > old {
            let ds = self.file.dataset(POINT_INDEX)?;
            ds.resize(n)?;
            #[allow(clippy::cast_possible_wrap)]
            let values: Vec<i64> = (old as i64..n as i64).collect();
            ds.write_slice(&values, old..n)?;
            self.point_index_len = n;
        }
        Ok(())
    }

    fn write_xdmf(&mut self) -> Result<()> {
        self.xdmf_written = Some((std::time::Instant::now(), self.frames.len()));
        let h5_name = self
            .path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or("output.h5");
        xdmf::write_atomic(
            &self.xdmf_path(),
            &xdmf::render(h5_name, &self.frames, self.point_index_len),
        )
    }
}

fn write_restart(group: &Group, state: &RestartState) -> hdf5::Result<()> {
    let rows = |v: &[DVec3]| -> Vec<[f64; 3]> { v.iter().map(|x| x.to_array()).collect() };
    let plain = |name: &str, data: ArrayView1<'_, f64>| {
        group
            .new_dataset_builder()
            .with_data(data)
            .create(name)
            .map(|_| ())
    };
    let force = rows(&state.force);
    group
        .new_dataset_builder()
        .with_data(ArrayView2::from_shape((force.len(), 3), force.as_flattened()).expect("N×3"))
        .create("force")?;
    plain("dissipated_energy", ArrayView1::from(&state.dissipated))?;
    if !state.neighbor_reference.is_empty() {
        let reference = rows(&state.neighbor_reference);
        group
            .new_dataset_builder()
            .with_data(
                ArrayView2::from_shape((reference.len(), 3), reference.as_flattened())
                    .expect("N×3"),
            )
            .create("neighbor_reference_position")?;
    }
    if state.removed.particles > 0 {
        let r = &state.removed;
        #[allow(clippy::cast_precision_loss)]
        let removed = [
            r.particles as f64,
            r.mechanical_energy,
            r.dissipated_energy,
            r.enthalpy,
            r.laser_energy,
            r.boundary_energy,
            r.evaporated,
            r.evaporated_mass,
        ];
        plain("removed", ArrayView1::from(&removed))?;
    }
    let bonded: Vec<[u64; 2]> = state.bonded.iter().map(|&(a, b)| [a, b]).collect();
    group
        .new_dataset_builder()
        .with_data(ArrayView2::from_shape((bonded.len(), 2), bonded.as_flattened()).expect("B×2"))
        .create("bonded_ids")?;
    if let Some(t) = &state.thermal {
        plain("enthalpy", ArrayView1::from(&t.enthalpy))?;
        let melted: Vec<u8> = t.melted.iter().map(|m| u8::from(*m)).collect();
        group
            .new_dataset_builder()
            .with_data(ArrayView1::from(&melted))
            .create("melted")?;
        if let Some(laser) = &t.laser {
            plain("laser_power", ArrayView1::from(&laser.power))?;
            plain("laser_energy", ArrayView1::from(&laser.energy))?;
        }
        if let Some(energy) = &t.boundary_energy {
            plain("boundary_energy", ArrayView1::from(energy))?;
        }
        if let Some(evaporated) = &t.evaporated {
            plain("evaporated_heat", ArrayView1::from(evaporated))?;
        }
        group
            .new_attr::<u32>()
            .create("max_substeps")?
            .write_scalar(&t.max_substeps)?;
    }
    if let Some(r) = &state.rotation {
        let vectors = |name: &str, v: &[DVec3]| {
            let data = rows(v);
            group
                .new_dataset_builder()
                .with_data(
                    ArrayView2::from_shape((data.len(), 3), data.as_flattened()).expect("N×3"),
                )
                .create(name)
                .map(|_| ())
        };
        vectors("angular_velocity", &r.angular_velocity)?;
        vectors("torque", &r.torque)?;
        vectors("wall_tangential_history", &r.wall_history)?;
        plain(
            "wall_tangential_energy",
            ArrayView1::from(&r.wall_spring_energy),
        )?;
        let ids: Vec<[u64; 2]> = r.pair_ids.iter().map(|&(a, b)| [a, b]).collect();
        group
            .new_dataset_builder()
            .with_data(ArrayView2::from_shape((ids.len(), 2), ids.as_flattened()).expect("P×2"))
            .create("tangential_ids")?;
        vectors("tangential_history", &r.pair_history)?;
        plain("tangential_energy", ArrayView1::from(&r.pair_spring_energy))?;
    }
    if let Some(snapshot) = &state.laser {
        let lit: Vec<u64> = snapshot.lit.iter().map(|(k, _)| *k as u64).collect();
        let at: Vec<[f64; 3]> = snapshot.lit.iter().map(|(_, x)| x.to_array()).collect();
        group
            .new_dataset_builder()
            .with_data(ArrayView1::from(&lit))
            .create("laser_lit")?;
        group
            .new_dataset_builder()
            .with_data(ArrayView2::from_shape((at.len(), 3), at.as_flattened()).expect("L×3"))
            .create("laser_lit_position")?;
        let beam = snapshot.beam.map_or([f64::NAN, f64::NAN], |b| b.to_array());
        plain("laser_beam", ArrayView1::from(&beam))?;
        group
            .new_attr::<u8>()
            .create("laser_on")?
            .write_scalar(&u8::from(snapshot.beam.is_some()))?;
    }
    Ok(())
}

/// The last complete frame of a file, for a restart.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedRun {
    /// The scene text stored in the file.
    pub scene: String,
    /// Frame number.
    pub frame: usize,
    /// Particle ids of the frame, in row order.
    pub id: Vec<u64>,
    /// Positions \[m\].
    pub position: Vec<DVec3>,
    /// Velocities [m/s].
    pub velocity: Vec<DVec3>,
    /// Everything else the next step needs.
    pub state: RestartState,
}

/// Reads the last complete frame with restart data.
///
/// # Errors
/// HDF5 errors, or [`OutputError::Format`] if the file has no complete frame with restart data.
pub fn read_last_frame(path: &Path) -> Result<SavedRun> {
    let file = File::open(path).on(path)?;
    check_format(&file, path)?;
    let scene: VarLenUnicode = file.attr("scene").and_then(|a| a.read_scalar()).on(path)?;
    let frames = file.group("frames").on(path)?;
    let names = frame_names(&frames).on(path)?;
    let bad = |message: &str| OutputError::Format {
        path: path.to_path_buf(),
        message: message.to_string(),
    };
    let (index, group) = names
        .iter()
        .enumerate()
        .rev()
        .filter_map(|(k, name)| frames.group(name).ok().map(|g| (k, g)))
        .find(|(_, g)| frame_is_complete(g) && g.link_exists("restart"))
        .ok_or_else(|| {
            bad("no complete frame with restart data (was [output] restart = false?)")
        })?;
    let read = || -> hdf5::Result<SavedRun> {
        let restart = group.group("restart")?;
        let vec3 = |ds: Dataset| -> hdf5::Result<Vec<DVec3>> {
            Ok(ds
                .read_raw::<f64>()?
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0], c[1], c[2]))
                .collect())
        };
        let optional = |name: &str| -> hdf5::Result<Option<Vec<f64>>> {
            if restart.link_exists(name) {
                Ok(Some(restart.dataset(name)?.read_raw()?))
            } else {
                Ok(None)
            }
        };
        let thermal = if restart.link_exists("enthalpy") {
            Some(ThermalRestart {
                enthalpy: restart.dataset("enthalpy")?.read_raw()?,
                melted: restart
                    .dataset("melted")?
                    .read_raw::<u8>()?
                    .into_iter()
                    .map(|m| m != 0)
                    .collect(),
                // (A file of an earlier version holds the laser's and boundary's arrays for
                // every scene with heat: one without the source drops them on resuming.)
                laser: if restart.link_exists("laser_power") {
                    Some(LaserHeat {
                        power: restart.dataset("laser_power")?.read_raw()?,
                        energy: restart.dataset("laser_energy")?.read_raw()?,
                    })
                } else {
                    None
                },
                boundary_energy: optional("boundary_energy")?,
                evaporated: optional("evaporated_heat")?,
                max_substeps: restart.attr("max_substeps")?.read_scalar()?,
            })
        } else {
            None
        };
        let laser = if restart.link_exists("laser_lit") {
            let lit: Vec<u64> = restart.dataset("laser_lit")?.read_raw()?;
            let at = vec3(restart.dataset("laser_lit_position")?)?;
            let beam: Vec<f64> = restart.dataset("laser_beam")?.read_raw()?;
            let on: u8 = restart.attr("laser_on")?.read_scalar()?;
            #[allow(clippy::cast_possible_truncation)]
            Some(Snapshot {
                beam: (on != 0).then(|| DVec2::new(beam[0], beam[1])),
                lit: lit.into_iter().map(|k| k as usize).zip(at).collect(),
            })
        } else {
            None
        };
        let bonded: Vec<u64> = restart.dataset("bonded_ids")?.read_raw()?;
        let rotation = if restart.link_exists("angular_velocity") {
            let ids: Vec<u64> = restart.dataset("tangential_ids")?.read_raw()?;
            Some(RotationRestart {
                angular_velocity: vec3(restart.dataset("angular_velocity")?)?,
                torque: vec3(restart.dataset("torque")?)?,
                wall_history: vec3(restart.dataset("wall_tangential_history")?)?,
                wall_spring_energy: restart.dataset("wall_tangential_energy")?.read_raw()?,
                pair_ids: ids.chunks_exact(2).map(|c| (c[0], c[1])).collect(),
                pair_history: vec3(restart.dataset("tangential_history")?)?,
                pair_spring_energy: restart.dataset("tangential_energy")?.read_raw()?,
            })
        } else {
            None
        };
        Ok(SavedRun {
            scene: scene.as_str().to_string(),
            frame: index,
            id: group.dataset("id")?.read_raw()?,
            position: vec3(group.dataset("position")?)?,
            velocity: vec3(group.dataset("velocity")?)?,
            state: RestartState {
                step: group.attr("step")?.read_scalar()?,
                force: vec3(restart.dataset("force")?)?,
                dissipated: restart.dataset("dissipated_energy")?.read_raw()?,
                bonded: bonded.chunks_exact(2).map(|c| (c[0], c[1])).collect(),
                thermal,
                laser,
                rotation,
                removed: if restart.link_exists("removed") {
                    let r: Vec<f64> = restart.dataset("removed")?.read_raw()?;
                    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                    Removed {
                        particles: r[0] as u64,
                        mechanical_energy: r[1],
                        dissipated_energy: r[2],
                        enthalpy: r[3],
                        // The resumed run's heat balance starts anew (its start subtracts it).
                        enthalpy_change: 0.0,
                        laser_energy: r[4],
                        boundary_energy: r[5],
                        // Files written before evaporation was modelled hold six entries.
                        evaporated: r.get(6).copied().unwrap_or(0.0),
                        evaporated_mass: r.get(7).copied().unwrap_or(0.0),
                    }
                } else {
                    Removed::default()
                },
                neighbor_reference: if restart.link_exists("neighbor_reference_position") {
                    vec3(restart.dataset("neighbor_reference_position")?)?
                } else {
                    Vec::new()
                },
            },
        })
    };
    read().on(path)
}

fn meta_of_group(group: &Group, name: &str) -> hdf5::Result<FrameMeta> {
    let n = group.dataset("id")?.shape()[0];
    let mut fields = Vec::new();
    for member in group.member_names()? {
        if member == "position" || member == "restart" || member.starts_with("bond") {
            continue;
        }
        let ds = group.dataset(&member)?;
        let shape = ds.shape();
        let kind = if shape.len() == 2 {
            xdmf::Kind::Vector
        } else if ds.dtype()?.size() == 1 {
            xdmf::Kind::Flag
        } else if ds.dtype()?.is::<u64>() {
            xdmf::Kind::Integer
        } else {
            xdmf::Kind::Scalar
        };
        fields.push((member, kind));
    }
    Ok(FrameMeta {
        name: name.to_string(),
        time: group.attr("time")?.read_scalar()?,
        particles: n,
        bonds: if group.link_exists("bonds") {
            group.dataset("bonds")?.shape()[0]
        } else {
            0
        },
        fields,
    })
}

fn frame_names(frames: &Group) -> hdf5::Result<Vec<String>> {
    let mut names: Vec<(u64, String)> = frames
        .member_names()?
        .into_iter()
        .filter_map(|n| n.parse().ok().map(|i| (i, n)))
        .collect();
    names.sort_unstable();
    Ok(names.into_iter().map(|(_, n)| n).collect())
}

fn frame_is_complete(group: &Group) -> bool {
    group.attr("time").is_ok() && group.attr("step").is_ok()
}

fn check_format(file: &File, path: &Path) -> Result<()> {
    let bad = |message: String| OutputError::Format {
        path: path.to_path_buf(),
        message,
    };
    let format: VarLenUnicode = file
        .attr("format")
        .and_then(|a| a.read_scalar())
        .map_err(|_| bad("not an am-sim output file (no root attribute `format`)".into()))?;
    if format.as_str() != FORMAT_NAME {
        return Err(bad(format!(
            "format is {:?}, expected {FORMAT_NAME:?}",
            format.as_str()
        )));
    }
    let version: u32 = file
        .attr("format_version")
        .and_then(|a| a.read_scalar())
        .on(path)?;
    if version != FORMAT_VERSION {
        return Err(bad(format!(
            "format_version {version} is not supported (this am-sim reads {FORMAT_VERSION})"
        )));
    }
    Ok(())
}

fn string_attr(location: &hdf5::Location, name: &str, value: &str) -> hdf5::Result<()> {
    let value: VarLenUnicode = value
        .parse()
        .map_err(|e| hdf5::Error::from(format!("attribute {name}: {e}")))?;
    location
        .new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&value)
}

/// The particles of one frame (for `[[import]] format = "am_sim_h5"`).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameParticles {
    /// Frame number (`/frames/NNNNNN`).
    pub frame: usize,
    /// Particle ids, in row order.
    pub id: Vec<u64>,
    /// Positions \[m\].
    pub position: Vec<DVec3>,
    /// Velocities [m/s].
    pub velocity: Vec<DVec3>,
    /// Radii \[m\].
    pub radius: Vec<f64>,
}

/// Reads ids, positions, velocities and radii of frame number `frame`, or of the last complete
/// frame when `None`.
///
/// # Errors
/// HDF5 errors, or [`OutputError::Format`] if the frame does not exist or is incomplete.
pub fn read_frame_particles(path: &Path, frame: Option<usize>) -> Result<FrameParticles> {
    let file = File::open(path).on(path)?;
    check_format(&file, path)?;
    let frames = file.group("frames").on(path)?;
    let names = frame_names(&frames).on(path)?;
    let bad = |message: String| OutputError::Format {
        path: path.to_path_buf(),
        message,
    };
    let complete = |name: &String| frames.group(name).is_ok_and(|g| frame_is_complete(&g));
    let (index, name) = match frame {
        None => names
            .iter()
            .enumerate()
            .rev()
            .find(|(_, n)| complete(n))
            .ok_or_else(|| bad("no complete frame".into()))?,
        Some(k) => names
            .iter()
            .enumerate()
            .find(|(_, n)| n.parse::<usize>().ok() == Some(k) && complete(n))
            .ok_or_else(|| {
                bad(format!(
                    "no complete frame {k}; the file has frames 0 to {}",
                    names.len().saturating_sub(1)
                ))
            })?,
    };
    let group = frames.group(name).on(path)?;
    let read = || -> hdf5::Result<FrameParticles> {
        let vec3 = |ds: Dataset| -> hdf5::Result<Vec<DVec3>> {
            Ok(ds
                .read_raw::<f64>()?
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0], c[1], c[2]))
                .collect())
        };
        Ok(FrameParticles {
            frame: index,
            id: group.dataset("id")?.read_raw()?,
            position: vec3(group.dataset("position")?)?,
            velocity: vec3(group.dataset("velocity")?)?,
            radius: group.dataset("radius")?.read_raw()?,
        })
    };
    read().on(path)
}
