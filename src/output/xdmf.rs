//! XDMF (XML) companion of an HDF5 output file, so that ParaView opens it with File > Open and
//! plays the frames as a time series.
//!
//! Structure, checked with all three XDMF readers of ParaView 5.11 (`XDMFReader`,
//! `Xdmf3ReaderS`, `Xdmf3ReaderT`, see `scripts/check_paraview.py`):
//! * two temporal collections, `particles` and `bonds`, one uniform grid per frame with its
//!   `<Time>` (the XDMF Reader names the blocks `particles` and `bonds`; the Xdmf3 readers
//!   number them);
//! * particles are a Polyvertex topology whose connectivity is the first N entries (a
//!   HyperSlab) of the shared dataset `/xdmf/point_index` = 0, 1, 2, …: without explicit
//!   connectivity the Xdmf3 readers create no cells and nothing is drawn;
//! * bonds are a Polyline topology with 2 nodes per cell on the same points; a frame without
//!   bonds gets no bond grid, because `XDMFReader` fails on `NumberOfElements="0"`;
//! * 64-bit unsigned datasets (`id`, `bonds`, `contacts`) are declared `Int` precision 8: declared
//!   `UInt` 8 the readers read them as 32-bit and saturate values of 2³² and above. Flags are
//!   `UChar` precision 1.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use super::OutputError;
use super::frame::{Frame, Values};

/// Path of the shared Polyvertex connectivity dataset (i64 `0..len`) in the HDF5 file.
pub const POINT_INDEX: &str = "/xdmf/point_index";

/// How a point dataset is declared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// f64 scalar.
    Scalar,
    /// f64 3-vector.
    Vector,
    /// u64 scalar, declared `Int` 8.
    Integer,
    /// u8 flag.
    Flag,
}

impl Kind {
    /// The kind of a dataset's values.
    #[must_use]
    pub fn of(values: &Values) -> Self {
        match values {
            Values::F64(_) => Self::Scalar,
            Values::Vec3(_) => Self::Vector,
            Values::U64(_) => Self::Integer,
            Values::U8(_) => Self::Flag,
        }
    }
}

/// What the XDMF file needs to know about one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameMeta {
    /// Group name under `/frames`, e.g. `000012`.
    pub name: String,
    /// Simulated time \[s\].
    pub time: f64,
    /// Number of particles N.
    pub particles: usize,
    /// Number of bonds B (0 when none or not written).
    pub bonds: usize,
    /// Point datasets other than `position`, with their kinds.
    pub fields: Vec<(String, Kind)>,
}

impl FrameMeta {
    /// The description of `frame`, stored as group `name`.
    #[must_use]
    pub fn of(frame: &Frame, name: String) -> Self {
        Self {
            name,
            time: frame.time,
            particles: frame.points.first().map_or(0, |f| f.values.len()),
            bonds: frame.bonds.as_ref().map_or(0, Vec::len),
            fields: frame
                .points
                .iter()
                .filter(|f| f.name != "position")
                .map(|f| (f.name.to_string(), Kind::of(&f.values)))
                .collect(),
        }
    }
}

/// Renders the XDMF document for the frames of the HDF5 file `h5_name` (a bare file name, so
/// that the two files can be moved together). `point_index_len` is the length of
/// [`POINT_INDEX`], at least the largest N.
#[must_use]
pub fn render(h5_name: &str, frames: &[FrameMeta], point_index_len: usize) -> String {
    let h5 = escape(h5_name);
    let mut x = String::from("<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n");
    x.push_str("  <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n");
    for f in frames.iter().filter(|f| f.particles > 0) {
        let n = f.particles;
        let path = |field: &str| format!("{h5}:/frames/{}/{field}", f.name);
        let _ = writeln!(
            x,
            "   <Grid Name=\"particles_{}\" GridType=\"Uniform\">",
            f.name
        );
        // `{:?}` prints the shortest decimal that reads back as the same f64.
        let _ = writeln!(x, "    <Time Value=\"{:?}\"/>", f.time);
        let _ = writeln!(
            x,
            "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"{n}\" NodesPerElement=\"1\">"
        );
        let _ = writeln!(
            x,
            "     <DataItem ItemType=\"HyperSlab\" Dimensions=\"{n}\" Type=\"HyperSlab\">"
        );
        let _ = writeln!(
            x,
            "      <DataItem Dimensions=\"3 1\" Format=\"XML\">0 1 {n}</DataItem>"
        );
        data_item(
            &mut x,
            6,
            &point_index_len.to_string(),
            "Int",
            8,
            &format!("{h5}:{POINT_INDEX}"),
        );
        x.push_str("     </DataItem>\n    </Topology>\n");
        geometry(&mut x, n, &path("position"));
        for (name, kind) in &f.fields {
            let (attribute, dims, number, precision) = match kind {
                Kind::Scalar => ("Scalar", n.to_string(), "Float", 8),
                Kind::Vector => ("Vector", format!("{n} 3"), "Float", 8),
                Kind::Integer => ("Scalar", n.to_string(), "Int", 8),
                Kind::Flag => ("Scalar", n.to_string(), "UChar", 1),
            };
            let _ = writeln!(
                x,
                "    <Attribute Name=\"{}\" AttributeType=\"{attribute}\" Center=\"Node\">",
                escape(name)
            );
            data_item(&mut x, 5, &dims, number, precision, &path(name));
            x.push_str("    </Attribute>\n");
        }
        x.push_str("   </Grid>\n");
    }
    x.push_str("  </Grid>\n");
    x.push_str("  <Grid Name=\"bonds\" GridType=\"Collection\" CollectionType=\"Temporal\">\n");
    for f in frames.iter().filter(|f| f.bonds > 0 && f.particles > 0) {
        let (n, b) = (f.particles, f.bonds);
        let path = |field: &str| format!("{h5}:/frames/{}/{field}", f.name);
        let _ = writeln!(
            x,
            "   <Grid Name=\"bonds_{}\" GridType=\"Uniform\">",
            f.name
        );
        let _ = writeln!(x, "    <Time Value=\"{:?}\"/>", f.time);
        let _ = writeln!(
            x,
            "    <Topology TopologyType=\"Polyline\" NumberOfElements=\"{b}\" NodesPerElement=\"2\">"
        );
        data_item(&mut x, 5, &format!("{b} 2"), "Int", 8, &path("bonds"));
        x.push_str("    </Topology>\n");
        geometry(&mut x, n, &path("position"));
        x.push_str("   </Grid>\n");
    }
    x.push_str("  </Grid>\n </Domain>\n</Xdmf>\n");
    x
}

fn geometry(x: &mut String, n: usize, path: &str) {
    x.push_str("    <Geometry GeometryType=\"XYZ\">\n");
    data_item(x, 5, &format!("{n} 3"), "Float", 8, path);
    x.push_str("    </Geometry>\n");
}

fn data_item(
    x: &mut String,
    indent: usize,
    dims: &str,
    number_type: &str,
    precision: u8,
    path: &str,
) {
    let _ = writeln!(
        x,
        "{:indent$}<DataItem Dimensions=\"{dims}\" NumberType=\"{number_type}\" Precision=\"{precision}\" Format=\"HDF\">{path}</DataItem>",
        ""
    );
}

/// Escapes the XML special characters.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

/// Writes `text` to `path` through a temporary file and a rename, so that a reader or a killed
/// writer never sees a half-written file.
///
/// # Errors
/// I/O errors.
pub fn write_atomic(path: &Path, text: &str) -> Result<(), OutputError> {
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let tmp = path.with_extension("xmf.tmp");
    let mut f = std::fs::File::create(&tmp).map_err(io)?;
    f.write_all(text.as_bytes()).map_err(io)?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(io)
}
