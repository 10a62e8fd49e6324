//! Reading and writing PLY files (Turk's polygon file format), without outside crates.
//!
//! * [`read_point_cloud`] reads oriented points: the `vertex` element's `x y z nx ny nz`
//!   (any PLY scalar type), plus `red green blue [alpha]` (see [`COLOR_PROPERTIES`]) and
//!   `confidence` (or `value`) when present, and every other scalar vertex property as a named
//!   float channel (psr carries colours and channels onto the mesh).
//! * [`read_points`] reads the same, with normals when the file has them and none otherwise
//!   (for clouds whose normals psr estimates), and each point's sensor position when the file
//!   has one (see [`SENSOR_PROPERTIES`]).
//! * [`read_mesh`] reads a triangle mesh: `vertex` `x y z` and the `face` element's
//!   `vertex_indices` (or `vertex_index`) lists, with polygons split into fans of triangles.
//! * [`read_points_and_triangles`] reads both: the vertices with every property, as
//!   [`read_points`] does, and the faces as [`read_mesh`] does (a mesh with its densities,
//!   normals, colours and channels).
//! * [`write_mesh`] writes a [`Mesh`] as binary little-endian PLY, with the per-vertex density as
//!   `float value` (PoissonRecon's name for it), and the normals, colours and channels when the
//!   mesh has them ([`write_mesh_with`] chooses the colours' type and the format, ASCII
//!   included). The face indices are `int`, or `uint` past 2³¹ vertices; a mesh past 2³²
//!   vertices is refused with an error (PLY has no standard 64-bit integer), never wrapped.
//! * [`write_point_cloud`] writes oriented points, in any of the three PLY formats.
//!
//! The readers accept the three formats (`ascii`, `binary_little_endian`, `binary_big_endian`),
//! every scalar type under both its old and its sized name (`uchar` = `uint8`, `float` =
//! `float32`, …), and skip every property and element they do not need, list properties
//! included. A malformed, truncated or corrupt file gives a [`PlyError`] that says where the
//! problem is; the readers never panic, and never allocate for more entries than the file could
//! hold.

use std::fmt;
use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Read, Seek, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::{Channel, Colors, Mesh};

/// Oriented points read from a PLY file.
///
/// New fields may be added (the struct is `#[non_exhaustive]`): build one from
/// `PlyPoints::default()`.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct PlyPoints {
    /// The `x y z` of each vertex (rounded to `f32` when the file stores them as `double`).
    pub positions: Vec<[f32; 3]>,
    /// The `x y z` of each vertex as the file stores them, when any of the three is a
    /// `double` (georeferenced clouds): give them to [`crate::PointSet::extend_f64`] so that
    /// nothing is lost to `f32`. `None` for `float` (or integer) coordinates.
    pub positions_f64: Option<Vec<[f64; 3]>>,
    /// One normal per position, as stored (not normalised).
    pub normals: Vec<[f32; 3]>,
    /// The colours, when the vertex element has red, green and blue under one of the names of
    /// [`COLOR_PROPERTIES`] (RGBA when it has that convention's alpha too), scaled to 0..1:
    /// `uchar` (and other integer) values are divided by 255, `ushort` ones by 65535, float
    /// values are taken as they are.
    pub colors: Option<Colors>,
    /// The type the colours are stored as in the file ([`ColorType::U8`] when there are none),
    /// so that they can be written back alike.
    pub color_type: ColorType,
    /// The `confidence` property (or else `value`), when the vertex element has one.
    pub confidence: Option<Vec<f32>>,
    /// The position of the sensor that saw each point (for [`crate::Orientation::Sensors`]),
    /// when the vertex element has one of the triples of [`SENSOR_PROPERTIES`].
    pub sensors: Option<Vec<[f32; 3]>>,
    /// Every other scalar property of the vertex element, in the file's order, as a float
    /// channel named like the property: all but the positions, the normals, the colours read
    /// into `colors`, `confidence` and `value`, and the sensor properties (names starting with
    /// `sensor_`, `vp_` or `beamorigin`). A name the file repeats is read once.
    pub channels: Vec<Channel>,
}

/// The vertex properties read as colours, one quadruple (red, green, blue, alpha) per
/// convention, in the order tried: the first whose red, green and blue are all present wins,
/// and its alpha is read when present. `red green blue alpha` is the usual one (PoissonRecon,
/// Open3D, PCL, MeshLab, and what psr writes); `diffuse_*` comes from some exporters of
/// material colours; `r g b a` from a few scripts.
pub const COLOR_PROPERTIES: [[&str; 4]; 3] = [
    ["red", "green", "blue", "alpha"],
    [
        "diffuse_red",
        "diffuse_green",
        "diffuse_blue",
        "diffuse_alpha",
    ],
    ["r", "g", "b", "a"],
];

/// The PLY type colours are stored as; colours in psr are floats, 0..1 as [`PlyPoints`] reads
/// them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum ColorType {
    /// `uchar`, 0..255 (the usual type): written as round(255 × value), clamped.
    #[default]
    U8,
    /// `ushort`, 0..65535 (16-bit colours, e.g. from LAS): written as round(65535 × value),
    /// clamped.
    U16,
    /// `float`, written as it is.
    F32,
}

impl ColorType {
    /// The type of the PLY property `s` as a colour: floats are F32, `ushort` U16, any other
    /// integer type U8.
    fn of(s: Scalar) -> ColorType {
        match s {
            Scalar::F32 | Scalar::F64 => ColorType::F32,
            Scalar::U16 => ColorType::U16,
            _ => ColorType::U8,
        }
    }

    /// The stored value of 1.0 (stored values are divided by it).
    fn full(self) -> f64 {
        match self {
            ColorType::U8 => 255.0,
            ColorType::U16 => 65535.0,
            ColorType::F32 => 1.0,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ColorType::U8 => "uchar",
            ColorType::U16 => "ushort",
            ColorType::F32 => "float",
        }
    }

    /// One 0..1 colour component as stored, little- or big-endian.
    fn encode(self, v: f32, big: bool, out: &mut Vec<u8>) {
        match self {
            ColorType::U8 => out.push((v as f64 * 255.0).round().clamp(0.0, 255.0) as u8),
            ColorType::U16 => {
                let x = (v as f64 * 65535.0).round().clamp(0.0, 65535.0) as u16;
                out.extend_from_slice(&if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                });
            }
            ColorType::F32 => out.extend_from_slice(&if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }),
        }
    }

    /// One 0..1 colour component as ASCII text of its stored value.
    fn text(self, v: f32) -> String {
        match self {
            ColorType::U8 => ((v as f64 * 255.0).round().clamp(0.0, 255.0) as u8).to_string(),
            ColorType::U16 => ((v as f64 * 65535.0).round().clamp(0.0, 65535.0) as u16).to_string(),
            ColorType::F32 => v.to_string(),
        }
    }
}

/// Vertex properties that are sensor positions, whatever their axis (never channels).
const SENSOR_PREFIXES: [&str; 3] = ["sensor_", "vp_", "beamorigin"];

/// The vertex properties read as each point's sensor position, one triple per convention, in
/// the order tried (the first complete triple wins). There is no standard; these are the names
/// in use:
///
/// * `sensor_x sensor_y sensor_z`: plain names, used by mobile-mapping exports and scripts (and
///   what [`write_point_cloud`] writes);
/// * `vp_x vp_y vp_z`: PCL's `PointWithViewpoint`, as PCL's PLY writer saves it;
/// * `beamoriginx beamoriginy beamoriginz`: PDAL's `BeamOriginX/Y/Z` dimensions (the origin of
///   each laser shot, e.g. from `readers.rxp`), as PDAL's `writers.ply` spells them.
pub const SENSOR_PROPERTIES: [[&str; 3]; 3] = [
    ["sensor_x", "sensor_y", "sensor_z"],
    ["vp_x", "vp_y", "vp_z"],
    ["beamoriginx", "beamoriginy", "beamoriginz"],
];

impl PlyPoints {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

/// The encoding of a PLY body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyFormat {
    /// `format ascii 1.0`: one entry per line, values as text.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl PlyFormat {
    fn header_name(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------------

/// Why a PLY file could not be read. `Display` gives a complete message, starting with the
/// file's path when it is known.
#[derive(Debug)]
pub struct PlyError {
    path: Option<PathBuf>,
    kind: PlyErrorKind,
}

/// What went wrong, for callers that want to tell cases apart.
#[derive(Debug)]
#[non_exhaustive]
pub enum PlyErrorKind {
    /// The operating system failed to open or read the file.
    Io {
        /// "open" or "read"
        action: &'static str,
        /// the operating system's error
        source: io::Error,
    },
    /// The file does not start with the line `ply` (empty, or another format).
    NotPly,
    /// The header is malformed; `line` counts from 1.
    Header {
        /// the header line, from 1
        line: usize,
        /// what is wrong with it
        message: String,
    },
    /// The header declares more entries than the rest of the file could possibly hold.
    TooLarge {
        /// the element's name
        element: String,
        /// the entries it declares
        count: usize,
        /// Bytes the declared entries need at the very least (counted up to this element).
        min_bytes: u64,
        /// Bytes after the header.
        available: u64,
    },
    /// The file ends inside entry `index` of `element` (which declares `count` entries).
    Truncated {
        /// the element's name
        element: String,
        /// the entry the file ends in, from 0
        index: usize,
        /// the entries it declares
        count: usize,
    },
    /// A value in the body is malformed or out of range. `line` is given for ASCII files.
    BadValue {
        /// the line, from 1, in ASCII files
        line: Option<usize>,
        /// the element's name
        element: String,
        /// the entry, from 0
        index: usize,
        /// what is wrong with the value
        message: String,
    },
    /// A required element is absent.
    MissingElement {
        /// the element's name
        element: String,
    },
    /// A required property is absent from an element; `present` lists the ones it has.
    MissingProperty {
        /// the element's name
        element: String,
        /// the property needed
        wanted: String,
        /// the properties the element has
        present: Vec<String>,
    },
    /// The vertex element has no `nx ny nz`: the points are not oriented.
    MissingNormals {
        /// the properties the vertex element has
        present: Vec<String>,
    },
}

impl PlyError {
    fn new(kind: PlyErrorKind) -> Self {
        PlyError { path: None, kind }
    }

    fn with_path(mut self, path: &Path) -> Self {
        self.path = Some(path.to_path_buf());
        self
    }

    /// The file the error is about, when it was read from a path.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// What went wrong.
    pub fn kind(&self) -> &PlyErrorKind {
        &self.kind
    }
}

impl From<PlyErrorKind> for PlyError {
    fn from(kind: PlyErrorKind) -> Self {
        PlyError::new(kind)
    }
}

impl fmt::Display for PlyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.path {
            Some(p) => write!(f, "{}: ", p.display())?,
            None => write!(f, "PLY input: ")?,
        }
        match &self.kind {
            PlyErrorKind::Io { action, source } => write!(f, "cannot {action} the file: {source}"),
            PlyErrorKind::NotPly => write!(f, "not a PLY file (its first line is not \"ply\")"),
            PlyErrorKind::Header { line, message } => write!(f, "bad PLY header, line {line}: {message}"),
            PlyErrorKind::TooLarge { element, count, min_bytes, available } => write!(
                f,
                "the header declares {count} '{element}' entries, which need at least {min_bytes} bytes, \
                 but only {available} bytes follow the header: the file is truncated or its header is corrupt"
            ),
            PlyErrorKind::Truncated { element, index, count } => write!(
                f,
                "the file ends early, inside '{element}' entry {index} of {count}: it is truncated"
            ),
            PlyErrorKind::BadValue { line: Some(line), element, index, message } => {
                write!(f, "line {line} ('{element}' entry {index}): {message}")
            }
            PlyErrorKind::BadValue { line: None, element, index, message } => {
                write!(f, "'{element}' entry {index}: {message}")
            }
            PlyErrorKind::MissingElement { element } => write!(f, "the file has no '{element}' element"),
            PlyErrorKind::MissingProperty { element, wanted, present } => write!(
                f,
                "the '{element}' element has no {wanted} (its properties: {})",
                list_or_none(present)
            ),
            PlyErrorKind::MissingNormals { present } => write!(
                f,
                "the vertex element has no nx ny nz properties (its properties: {}): reconstruction needs \
                 oriented points, so estimate normals first (e.g. PCA over neighbours, oriented towards the scanner)",
                list_or_none(present)
            ),
        }
    }
}

fn list_or_none(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(" ")
    }
}

impl std::error::Error for PlyError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            PlyErrorKind::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

fn read_error(e: io::Error) -> PlyErrorKind {
    PlyErrorKind::Io {
        action: "read",
        source: e,
    }
}

// ---------------------------------------------------------------------------------------------
// Header
// ---------------------------------------------------------------------------------------------

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one value from the first `size()` bytes of `b` (which must hold them).
    fn decode(self, b: &[u8], big: bool) -> f64 {
        let b2 = || [b[0], b[1]];
        let b4 = || [b[0], b[1], b[2], b[3]];
        match (self, big) {
            (Scalar::I8, _) => b[0] as i8 as f64,
            (Scalar::U8, _) => b[0] as f64,
            (Scalar::I16, false) => i16::from_le_bytes(b2()) as f64,
            (Scalar::I16, true) => i16::from_be_bytes(b2()) as f64,
            (Scalar::U16, false) => u16::from_le_bytes(b2()) as f64,
            (Scalar::U16, true) => u16::from_be_bytes(b2()) as f64,
            (Scalar::I32, false) => i32::from_le_bytes(b4()) as f64,
            (Scalar::I32, true) => i32::from_be_bytes(b4()) as f64,
            (Scalar::U32, false) => u32::from_le_bytes(b4()) as f64,
            (Scalar::U32, true) => u32::from_be_bytes(b4()) as f64,
            (Scalar::F32, false) => f32::from_le_bytes(b4()) as f64,
            (Scalar::F32, true) => f32::from_be_bytes(b4()) as f64,
            (Scalar::F64, false) => {
                f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
            }
            (Scalar::F64, true) => {
                f64::from_be_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
            }
        }
    }

    /// Parses one ASCII value of this type.
    fn parse(self, token: &str) -> Option<f64> {
        if self.is_float() {
            return token.parse::<f64>().ok();
        }
        let v = token.parse::<i64>().ok()?;
        let (lo, hi) = match self {
            Scalar::I8 => (i8::MIN as i64, i8::MAX as i64),
            Scalar::U8 => (0, u8::MAX as i64),
            Scalar::I16 => (i16::MIN as i64, i16::MAX as i64),
            Scalar::U16 => (0, u16::MAX as i64),
            Scalar::I32 => (i32::MIN as i64, i32::MAX as i64),
            _ => (0, u32::MAX as i64),
        };
        (lo..=hi).contains(&v).then_some(v as f64)
    }
}

#[derive(Debug, Clone)]
enum PropType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    ty: PropType,
    /// Header line that declared it.
    line: usize,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

impl Element {
    fn find(&self, names: &[&str]) -> Option<usize> {
        names
            .iter()
            .find_map(|n| self.props.iter().position(|p| p.name == *n))
    }

    fn prop_names(&self) -> Vec<String> {
        self.props.iter().map(|p| p.name.clone()).collect()
    }

    /// Bytes one entry takes at the least (lists counted as empty).
    fn min_entry_bytes(&self, format: PlyFormat) -> u64 {
        match format {
            // Every ASCII value takes at least one character and one separator (the last line
            // may lack its newline, hence the − 1).
            PlyFormat::Ascii => (2 * self.props.len() as u64).saturating_sub(1),
            _ => self
                .props
                .iter()
                .map(|p| match p.ty {
                    PropType::Scalar(s) => s.size() as u64,
                    PropType::List { count, .. } => count.size() as u64,
                })
                .sum(),
        }
    }

    /// The entry size when the element has no list property.
    fn fixed_stride(&self) -> Option<usize> {
        self.props
            .iter()
            .map(|p| match p.ty {
                PropType::Scalar(s) => Some(s.size()),
                PropType::List { .. } => None,
            })
            .sum()
    }
}

#[derive(Debug, Clone)]
struct Header {
    format: PlyFormat,
    elements: Vec<Element>,
    /// Bytes of the header, through the newline after `end_header`.
    bytes: u64,
    /// Lines of the header, `end_header` included.
    lines: usize,
}

impl Header {
    fn element(&self, name: &str) -> Option<usize> {
        self.elements.iter().position(|e| e.name == name)
    }
}

const MAX_HEADER_LINE: u64 = 64 * 1024;
const MAX_HEADER_BYTES: u64 = 16 * 1024 * 1024;

fn parse_header<R: BufRead>(r: &mut R) -> Result<Header, PlyErrorKind> {
    let mut buf = Vec::with_capacity(256);
    let mut bytes = 0u64;
    let mut line = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let header_err = |line: usize, message: String| PlyErrorKind::Header { line, message };
    loop {
        buf.clear();
        let n = r
            .by_ref()
            .take(MAX_HEADER_LINE)
            .read_until(b'\n', &mut buf)
            .map_err(read_error)?;
        line += 1;
        bytes += n as u64;
        if !buf.ends_with(b"\n") {
            if line == 1 {
                return Err(PlyErrorKind::NotPly);
            }
            return Err(if n as u64 >= MAX_HEADER_LINE {
                header_err(line, format!("line longer than {MAX_HEADER_LINE} bytes"))
            } else {
                header_err(line, "the file ends before the end_header line".into())
            });
        }
        if bytes > MAX_HEADER_BYTES {
            return Err(header_err(
                line,
                format!("header longer than {MAX_HEADER_BYTES} bytes"),
            ));
        }
        let text = String::from_utf8_lossy(&buf);
        let mut words = text.split_ascii_whitespace();
        let Some(keyword) = words.next() else {
            if line == 1 {
                return Err(PlyErrorKind::NotPly);
            }
            continue; // tolerate blank lines
        };
        if line == 1 {
            if keyword != "ply" || words.next().is_some() {
                return Err(PlyErrorKind::NotPly);
            }
            continue;
        }
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                if format.is_some() {
                    return Err(header_err(line, "a second format line".into()));
                }
                let f = match words.next() {
                    Some("ascii") => PlyFormat::Ascii,
                    Some("binary_little_endian") => PlyFormat::BinaryLittleEndian,
                    Some("binary_big_endian") => PlyFormat::BinaryBigEndian,
                    other => {
                        return Err(header_err(
                            line,
                            format!(
                                "unknown format '{}': expected ascii, binary_little_endian or binary_big_endian",
                                other.unwrap_or("")
                            ),
                        ))
                    }
                };
                match words.next() {
                    Some(v) if v.starts_with('1') => {}
                    Some(v) => {
                        return Err(header_err(
                            line,
                            format!("unsupported PLY version '{v}' (only 1.0)"),
                        ))
                    }
                    None => {
                        return Err(header_err(
                            line,
                            "the format line has no version (expected 1.0)".into(),
                        ))
                    }
                }
                format = Some(f);
            }
            "element" => {
                let (Some(name), Some(count)) = (words.next(), words.next()) else {
                    return Err(header_err(line, "expected 'element <name> <count>'".into()));
                };
                let count: usize = count.parse().map_err(|_| {
                    header_err(
                        line,
                        format!("element {name}: count '{count}' is not a non-negative integer"),
                    )
                })?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(header_err(
                        line,
                        format!("element '{name}' is declared twice"),
                    ));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(header_err(
                        line,
                        "a property line before any element line".into(),
                    ));
                };
                let scalar = |word: Option<&str>| -> Result<Scalar, PlyErrorKind> {
                    let word = word.unwrap_or("");
                    Scalar::from_name(word).ok_or_else(|| {
                        header_err(
                            line,
                            format!(
                                "unknown property type '{word}': expected char uchar short ushort int uint float \
                                 double (or int8 … float64)"
                            ),
                        )
                    })
                };
                let first = words.next();
                let ty = if first == Some("list") {
                    let count = scalar(words.next())?;
                    let item = scalar(words.next())?;
                    if count.is_float() {
                        return Err(header_err(
                            line,
                            format!("a list count of type {}", count.name()),
                        ));
                    }
                    PropType::List { count, item }
                } else {
                    PropType::Scalar(scalar(first)?)
                };
                let Some(name) = words.next() else {
                    return Err(header_err(line, "the property has no name".into()));
                };
                if element.props.iter().any(|p| p.name == name) {
                    return Err(header_err(
                        line,
                        format!(
                            "property '{name}' is declared twice in element '{}'",
                            element.name
                        ),
                    ));
                }
                element.props.push(Property {
                    name: name.to_string(),
                    ty,
                    line,
                });
            }
            "end_header" => {
                let Some(format) = format else {
                    return Err(header_err(line, "end_header before any format line".into()));
                };
                return Ok(Header {
                    format,
                    elements,
                    bytes,
                    lines: line,
                });
            }
            other => return Err(header_err(line, format!("unknown keyword '{other}'"))),
        }
    }
}

/// Checks that the elements up to `last` (inclusive) fit in `available` bytes.
fn check_sizes(header: &Header, last: usize, available: u64) -> Result<(), PlyErrorKind> {
    let mut need = 0u64;
    for e in &header.elements[..=last] {
        need =
            need.saturating_add((e.count as u64).saturating_mul(e.min_entry_bytes(header.format)));
        if need > available {
            return Err(PlyErrorKind::TooLarge {
                element: e.name.clone(),
                count: e.count,
                min_bytes: need,
                available,
            });
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Body
// ---------------------------------------------------------------------------------------------

/// What to keep from one element: where each scalar property goes (a slot index) and which list
/// property, if any, to collect.
struct Plan {
    slots: Vec<Option<usize>>,
    list: Option<usize>,
}

impl Plan {
    fn skip(el: &Element) -> Plan {
        Plan {
            slots: vec![None; el.props.len()],
            list: None,
        }
    }

    fn keeps_nothing(&self) -> bool {
        self.list.is_none() && self.slots.iter().all(Option::is_none)
    }

    /// Number of values one entry hands over (one past the highest slot).
    fn width(&self) -> usize {
        self.slots.iter().flatten().max().map_or(0, |m| m + 1)
    }
}

/// Receives one entry: its index, the planned scalar values and the kept list's items; returns
/// an error message for a bad entry.
type Sink<'a> = dyn FnMut(usize, &[f64], &[f64]) -> Result<(), String> + 'a;

/// The body of a PLY file, read element by element.
struct Body<R> {
    r: R,
    format: PlyFormat,
    /// ASCII: number of the last line read.
    line: usize,
    line_buf: Vec<u8>,
    bin_buf: Vec<u8>,
    /// How to move `n` bytes ahead without reading them (a seek, in a file), giving how many
    /// bytes were there; `None`: they are read and dropped.
    skip_ahead: Option<SkipAhead<R>>,
}

/// Moves a reader `n` bytes ahead without reading them; gives how many bytes were there.
type SkipAhead<R> = fn(&mut R, u64) -> io::Result<u64>;

/// [`SkipAhead`] for a file: a seek, as far as the file goes.
fn seek_ahead_in_file(r: &mut BufReader<File>, n: u64) -> io::Result<u64> {
    let at = r.stream_position()?;
    let len = r.get_ref().metadata()?.len();
    let step = n.min(len.saturating_sub(at));
    let step_signed = i64::try_from(step)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "a skip past 2^63 bytes"))?;
    r.seek_relative(step_signed)?;
    Ok(step)
}

/// Reads the `n` bytes `buf` can take, or fewer at the end of the input; returns how many.
fn read_fully<R: Read>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

impl<R: BufRead> Body<R> {
    fn new(r: R, header: &Header) -> Self {
        Body {
            r,
            format: header.format,
            line: header.lines,
            line_buf: Vec::new(),
            bin_buf: Vec::new(),
            skip_ahead: None,
        }
    }

    /// Reads every entry of `el`, calling `sink(index, values, list)` for each one when the plan
    /// keeps anything. `sink` returns an error message for a bad entry.
    fn read_element(
        &mut self,
        el: &Element,
        plan: &Plan,
        sink: impl FnMut(usize, &[f64], &[f64]) -> Result<(), String>,
    ) -> Result<(), PlyErrorKind> {
        self.read_entries(el, plan, 0..el.count, sink)
    }

    /// As [`Body::read_element`], for a caller that wants only the entries of `wanted`: where
    /// entries have a fixed size in a binary file, the bytes of those before `wanted` are passed
    /// over undecoded and the reading stops after it (the body is then left inside the
    /// element); otherwise every entry is read and `sink` gets them all.
    fn read_entries(
        &mut self,
        el: &Element,
        plan: &Plan,
        wanted: Range<usize>,
        mut sink: impl FnMut(usize, &[f64], &[f64]) -> Result<(), String>,
    ) -> Result<(), PlyErrorKind> {
        match self.format {
            PlyFormat::Ascii => self.read_ascii(el, plan, &mut sink),
            PlyFormat::BinaryLittleEndian => self.read_binary(el, plan, false, wanted, &mut sink),
            PlyFormat::BinaryBigEndian => self.read_binary(el, plan, true, wanted, &mut sink),
        }
    }

    fn truncated(el: &Element, index: usize) -> PlyErrorKind {
        PlyErrorKind::Truncated {
            element: el.name.clone(),
            index,
            count: el.count,
        }
    }

    fn bad_value(&self, el: &Element, index: usize, message: String) -> PlyErrorKind {
        let line = (self.format == PlyFormat::Ascii).then_some(self.line);
        PlyErrorKind::BadValue {
            line,
            element: el.name.clone(),
            index,
            message,
        }
    }

    /// Skips exactly `n` bytes, or reports how many were there.
    fn skip_bytes(&mut self, n: u64) -> io::Result<u64> {
        match self.skip_ahead {
            Some(skip_ahead) => skip_ahead(&mut self.r, n),
            None => io::copy(&mut self.r.by_ref().take(n), &mut io::sink()),
        }
    }

    fn read_binary(
        &mut self,
        el: &Element,
        plan: &Plan,
        big: bool,
        wanted: Range<usize>,
        sink: &mut Sink<'_>,
    ) -> Result<(), PlyErrorKind> {
        let mut values = vec![0.0f64; plan.width()];
        if let Some(stride) = el.fixed_stride() {
            if stride == 0 {
                if !plan.keeps_nothing() {
                    for index in 0..el.count {
                        sink(index, &values, &[]).map_err(|m| self.bad_value(el, index, m))?;
                    }
                }
                return Ok(());
            }
            if plan.keeps_nothing() {
                let total = el.count as u64 * stride as u64;
                let got = self.skip_bytes(total).map_err(read_error)?;
                if got < total {
                    return Err(Self::truncated(el, (got / stride as u64) as usize));
                }
                return Ok(());
            }
            // Fixed-size entries: decode whole chunks of them at precomputed offsets.
            let mut fields = Vec::new();
            let mut offset = 0;
            for (p, slot) in el.props.iter().zip(&plan.slots) {
                if let PropType::Scalar(s) = p.ty {
                    if let Some(slot) = slot {
                        fields.push((offset, s, *slot));
                    }
                    offset += s.size();
                }
            }
            let per_chunk = (1usize << 16).div_ceil(stride).max(1);
            let end = wanted.end.min(el.count);
            let mut index = wanted.start.min(end);
            let skipped = index as u64 * stride as u64;
            let got = self.skip_bytes(skipped).map_err(read_error)?;
            if got < skipped {
                return Err(Self::truncated(el, (got / stride as u64) as usize));
            }
            let mut buf = std::mem::take(&mut self.bin_buf);
            buf.resize(per_chunk * stride, 0);
            while index < end {
                let n = per_chunk.min(end - index);
                let chunk = &mut buf[..n * stride];
                let got = read_fully(&mut self.r, chunk).map_err(read_error)?;
                let complete = got / stride;
                for entry in chunk[..complete * stride].chunks_exact(stride) {
                    for &(offset, s, slot) in &fields {
                        values[slot] = s.decode(&entry[offset..], big);
                    }
                    sink(index, &values, &[]).map_err(|m| self.bad_value(el, index, m))?;
                    index += 1;
                }
                if complete < n {
                    return Err(Self::truncated(el, index));
                }
            }
            self.bin_buf = buf;
            return Ok(());
        }
        // Entries with lists: property by property.
        let mut list = Vec::new();
        let mut bytes = [0u8; 8];
        for index in 0..el.count {
            list.clear();
            for (i, p) in el.props.iter().enumerate() {
                match p.ty {
                    PropType::Scalar(s) => {
                        let b = &mut bytes[..s.size()];
                        self.r
                            .read_exact(b)
                            .map_err(|e| eof_or_read(e, el, index))?;
                        if let Some(slot) = plan.slots[i] {
                            values[slot] = s.decode(b, big);
                        }
                    }
                    PropType::List { count, item } => {
                        let b = &mut bytes[..count.size()];
                        self.r
                            .read_exact(b)
                            .map_err(|e| eof_or_read(e, el, index))?;
                        let n = count.decode(b, big);
                        if n < 0.0 {
                            let m = format!("list '{}' has a negative length {n}", p.name);
                            return Err(self.bad_value(el, index, m));
                        }
                        let n = n as u64;
                        if plan.list == Some(i) {
                            for _ in 0..n {
                                let b = &mut bytes[..item.size()];
                                self.r
                                    .read_exact(b)
                                    .map_err(|e| eof_or_read(e, el, index))?;
                                list.push(item.decode(b, big));
                            }
                        } else {
                            let total = n * item.size() as u64;
                            if self.skip_bytes(total).map_err(read_error)? < total {
                                return Err(Self::truncated(el, index));
                            }
                        }
                    }
                }
            }
            if !plan.keeps_nothing() {
                sink(index, &values, &list).map_err(|m| self.bad_value(el, index, m))?;
            }
        }
        Ok(())
    }

    /// Reads the next line that is not blank into `line_buf`; false at the end of the input.
    fn next_line(&mut self) -> Result<bool, PlyErrorKind> {
        loop {
            self.line_buf.clear();
            let n = self
                .r
                .read_until(b'\n', &mut self.line_buf)
                .map_err(read_error)?;
            if n == 0 {
                return Ok(false);
            }
            self.line += 1;
            if self.line_buf.iter().any(|b| !b.is_ascii_whitespace()) {
                return Ok(true);
            }
        }
    }

    fn read_ascii(
        &mut self,
        el: &Element,
        plan: &Plan,
        sink: &mut Sink<'_>,
    ) -> Result<(), PlyErrorKind> {
        let mut values = vec![0.0f64; plan.width()];
        let mut list = Vec::new();
        if el.props.is_empty() {
            if !plan.keeps_nothing() {
                for index in 0..el.count {
                    sink(index, &values, &list).map_err(|m| self.bad_value(el, index, m))?;
                }
            }
            return Ok(());
        }
        for index in 0..el.count {
            if !self.next_line()? {
                return Err(Self::truncated(el, index));
            }
            if plan.keeps_nothing() {
                continue;
            }
            list.clear();
            let line_buf = std::mem::take(&mut self.line_buf);
            let result = self.parse_ascii_entry(el, plan, index, &line_buf, &mut values, &mut list);
            self.line_buf = line_buf;
            result?;
            sink(index, &values, &list).map_err(|m| self.bad_value(el, index, m))?;
        }
        Ok(())
    }

    fn parse_ascii_entry(
        &self,
        el: &Element,
        plan: &Plan,
        index: usize,
        line: &[u8],
        values: &mut [f64],
        list: &mut Vec<f64>,
    ) -> Result<(), PlyErrorKind> {
        let Ok(text) = std::str::from_utf8(line) else {
            return Err(self.bad_value(el, index, "the line is not ASCII text".into()));
        };
        let mut tokens = text.split_ascii_whitespace();
        let mut next = |what: &str, ty: Scalar| -> Result<f64, PlyErrorKind> {
            let Some(token) = tokens.next() else {
                return Err(self.bad_value(el, index, format!("the line ends before {what}")));
            };
            ty.parse(token).ok_or_else(|| {
                self.bad_value(
                    el,
                    index,
                    format!("'{token}' is not a valid {} for {what}", ty.name()),
                )
            })
        };
        for (i, p) in el.props.iter().enumerate() {
            match p.ty {
                PropType::Scalar(s) => {
                    let v = next(&format!("property '{}'", p.name), s)?;
                    if let Some(slot) = plan.slots[i] {
                        values[slot] = v;
                    }
                }
                PropType::List { count, item } => {
                    let n = next(&format!("the length of list '{}'", p.name), count)?;
                    if n < 0.0 {
                        let m = format!("list '{}' has a negative length {n}", p.name);
                        return Err(self.bad_value(el, index, m));
                    }
                    for k in 0..n as u64 {
                        let v = next(&format!("item {k} of list '{}'", p.name), item)?;
                        if plan.list == Some(i) {
                            list.push(v);
                        }
                    }
                }
            }
        }
        if tokens.next().is_some() {
            let m = format!(
                "more values than the header declares ({} properties)",
                el.props.len()
            );
            return Err(self.bad_value(el, index, m));
        }
        Ok(())
    }
}

fn eof_or_read(e: io::Error, el: &Element, index: usize) -> PlyErrorKind {
    if e.kind() == io::ErrorKind::UnexpectedEof {
        PlyErrorKind::Truncated {
            element: el.name.clone(),
            index,
            count: el.count,
        }
    } else {
        read_error(e)
    }
}

/// Initial capacity for `count` entries: all of them when the file size vouched for the count,
/// otherwise a bounded guess (the vectors grow as entries actually arrive).
fn capacity(count: usize, size_checked: bool) -> usize {
    if size_checked {
        count
    } else {
        count.min(1 << 16)
    }
}

// ---------------------------------------------------------------------------------------------
// Point clouds
// ---------------------------------------------------------------------------------------------

/// Opens a PLY file for reading, with its length when it is a regular file (so element counts
/// can be checked against it before anything is allocated).
fn open(path: &Path) -> Result<(BufReader<File>, Option<u64>), PlyError> {
    let file = File::open(path).map_err(|e| {
        PlyError::new(PlyErrorKind::Io {
            action: "open",
            source: e,
        })
        .with_path(path)
    })?;
    let len = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    Ok((BufReader::with_capacity(1 << 20, file), len))
}

/// Reads oriented points from a PLY file (see [`read_point_cloud_from`]).
pub fn read_point_cloud(path: &Path) -> Result<PlyPoints, PlyError> {
    let (reader, len) = open(path)?;
    read_vertex_points(reader, len, Normals::Required).map_err(|e| PlyError::new(e).with_path(path))
}

/// Reads oriented points from PLY data: the `vertex` element's `x y z nx ny nz`, and colours
/// ([`COLOR_PROPERTIES`]), `confidence` (or `value`) and sensor positions
/// ([`SENSOR_PROPERTIES`]) when present; every other scalar vertex property becomes a channel
/// ([`PlyPoints::channels`]). List properties and other elements are skipped. The normals
/// `normal_x normal_y normal_z` are accepted in place of `nx ny nz`.
pub fn read_point_cloud_from(reader: impl BufRead) -> Result<PlyPoints, PlyError> {
    read_vertex_points(reader, None, Normals::Required).map_err(PlyError::new)
}

/// Reads points that may lack normals (see [`read_points_from`]).
pub fn read_points(path: &Path) -> Result<PlyPoints, PlyError> {
    let (reader, len) = open(path)?;
    read_vertex_points(reader, len, Normals::IfPresent)
        .map_err(|e| PlyError::new(e).with_path(path))
}

/// [`read_point_cloud_from`] for clouds that may have no normals (a scanner's or
/// photogrammetry's `x y z` export): `normals` is empty when the vertex element has no
/// `nx ny nz`, for [`crate::estimate_normals`] to fill.
pub fn read_points_from(reader: impl BufRead) -> Result<PlyPoints, PlyError> {
    read_vertex_points(reader, None, Normals::IfPresent).map_err(PlyError::new)
}

/// The vertices and the faces of a PLY file (see [`read_points_and_triangles_from`]).
pub fn read_points_and_triangles(path: &Path) -> Result<PointsAndTriangles, PlyError> {
    let (reader, len) = open(path)?;
    read_vertices_and_faces(reader, len, Normals::IfPresent, true, None, None)
        .map_err(|e| PlyError::new(e).with_path(path))
}

/// Everything psr reads of a PLY file, a point cloud or a mesh: the `vertex` element as
/// [`read_points_from`] reads it (normals, colours, confidence or `value` — a mesh's density —,
/// sensors and channels when present), and the `face` element's `vertex_indices` (or
/// `vertex_index`) polygons as triangles, each n-gon a fan of n − 2 triangles around its first
/// corner, as [`read_mesh_from`] splits them (no triangles when the file has no `face`
/// element). The C API's psr_ply_read.
pub fn read_points_and_triangles_from(
    reader: impl BufRead,
) -> Result<PointsAndTriangles, PlyError> {
    read_vertices_and_faces(reader, None, Normals::IfPresent, true, None, None)
        .map_err(PlyError::new)
}

/// The vertices of a PLY file and its faces as triangles (indices into the vertices).
pub type PointsAndTriangles = (PlyPoints, Vec<[u32; 3]>);

/// Whether a point cloud must have normals.
#[derive(Clone, Copy, PartialEq)]
enum Normals {
    Required,
    IfPresent,
}

fn read_vertex_points<R: BufRead>(
    r: R,
    file_len: Option<u64>,
    normals: Normals,
) -> Result<PlyPoints, PlyErrorKind> {
    read_vertices_and_faces(r, file_len, normals, false, None, None).map(|(points, _)| points)
}

/// Reads the oriented points of a PLY file (as [`read_point_cloud`] does) in chunks of at most
/// `chunk` points, handing each to `each` in file order, so that a file larger than memory can
/// be read: nothing but one chunk is held. `each` returning an error stops the reading; that
/// error comes back as the inner result, a problem with the file as the outer one (found after
/// some chunks were handed over, whose use the caller then undoes).
#[cfg(test)]
pub(crate) fn read_point_cloud_chunks<E>(
    path: &Path,
    chunk: usize,
    mut each: impl FnMut(PlyPoints) -> Result<(), E>,
) -> Result<Result<(), E>, PlyError> {
    read_point_cloud_part_chunks(path, chunk, (0, 1), |_, points| each(points))
}

/// As [`read_point_cloud_chunks`], for the points of one part of the file: with `part` = (r, n),
/// the r-th of n runs of consecutive points of equal length (to one point), the first of them
/// at index ⌊count·r/n⌋. `each` gets each chunk with the index in the file of its first point.
/// In a binary file whose vertices have no list property, the points before the part are
/// sought past (neither read nor decoded) and the points after it are not read; otherwise
/// they are decoded and dropped.
pub(crate) fn read_point_cloud_part_chunks<E>(
    path: &Path,
    chunk: usize,
    part: (usize, usize),
    mut each: impl FnMut(u64, PlyPoints) -> Result<(), E>,
) -> Result<Result<(), E>, PlyError> {
    let (reader, len) = open(path)?;
    let mut failure = None;
    let mut hand_over = |first: u64, points: PlyPoints| match each(first, points) {
        Ok(()) => true,
        Err(e) => {
            failure = Some(e);
            false
        }
    };
    read_vertices_and_faces(
        reader,
        len,
        Normals::Required,
        false,
        Some(Chunks {
            size: chunk.max(1),
            part: (part.0.min(part.1.max(1) - 1), part.1.max(1)),
            each: &mut hand_over,
        }),
        Some(seek_ahead_in_file),
    )
    .map_err(|e| PlyError::new(e).with_path(path))?;
    Ok(failure.map_or(Ok(()), Err))
}

/// Where a chunked read hands its points: the chunk size, the part of the file to read (r of
/// n), and a consumer of a chunk and the index of its first point that returns false to stop.
struct Chunks<'a> {
    size: usize,
    part: (usize, usize),
    each: &'a mut dyn FnMut(u64, PlyPoints) -> bool,
}

/// Takes the points read so far out of `out`, `colors` and `channels` as one chunk.
fn take_chunk(
    out: &mut PlyPoints,
    colors: &mut Vec<f32>,
    channels: &mut [Vec<f32>],
    components: usize,
    channel_names: &[String],
) -> PlyPoints {
    use std::mem::take;
    PlyPoints {
        positions: take(&mut out.positions),
        positions_f64: out.positions_f64.as_mut().map(take),
        normals: take(&mut out.normals),
        colors: (components > 0).then(|| Colors::from_flattened(components, &take(colors))),
        color_type: out.color_type,
        confidence: out.confidence.as_mut().map(take),
        sensors: out.sensors.as_mut().map(take),
        channels: channel_names
            .iter()
            .zip(channels.iter_mut())
            .map(|(name, values)| Channel::new(name.clone(), take(values)))
            .collect(),
    }
}

/// The `face` element a reader reads along with the vertices: its index, how to read it, the
/// number of vertices its indices may name, and the triangles read so far.
struct Faces {
    index: usize,
    plan: Plan,
    vertex_count: usize,
    corners: Vec<u32>,
    triangles: Vec<[u32; 3]>,
}

impl Faces {
    /// Reads element `i` into the triangles when it is the face element, else skips it.
    fn read_or_skip<R: BufRead>(
        faces: &mut Option<Faces>,
        body: &mut Body<R>,
        i: usize,
        el: &Element,
    ) -> Result<(), PlyErrorKind> {
        match faces {
            Some(f) if f.index == i => {
                let Faces {
                    plan,
                    vertex_count,
                    corners,
                    triangles,
                    ..
                } = f;
                body.read_element(el, plan, |_, _, list| {
                    push_polygon(list, *vertex_count, corners, triangles)
                })
            }
            _ => body.read_element(el, &Plan::skip(el), |_, _, _| Ok(())),
        }
    }
}

/// [`read_vertex_points`], and with `faces` the `face` element's polygons as triangles too
/// (none when the file has no `face` element). With `chunks`, the points are handed over in
/// chunks as they are read (the returned points are then empty), until the consumer says stop.
fn read_vertices_and_faces<R: BufRead>(
    mut r: R,
    file_len: Option<u64>,
    normals: Normals,
    faces: bool,
    mut chunks: Option<Chunks<'_>>,
    skip_ahead: Option<SkipAhead<R>>,
) -> Result<(PlyPoints, Vec<[u32; 3]>), PlyErrorKind> {
    let header = parse_header(&mut r)?;
    let Some(vi) = header.element("vertex") else {
        return Err(PlyErrorKind::MissingElement {
            element: "vertex".into(),
        });
    };
    let vertex = &header.elements[vi];
    let find3 = |names: [[&str; 2]; 3]| -> Option<[usize; 3]> {
        Some([
            vertex.find(&names[0])?,
            vertex.find(&names[1])?,
            vertex.find(&names[2])?,
        ])
    };
    let Some(pos) = find3([["x", "x"], ["y", "y"], ["z", "z"]]) else {
        return Err(PlyErrorKind::MissingProperty {
            element: "vertex".into(),
            wanted: "x y z properties".into(),
            present: vertex.prop_names(),
        });
    };
    let nrm = find3([["nx", "normal_x"], ["ny", "normal_y"], ["nz", "normal_z"]]);
    if nrm.is_none() && normals == Normals::Required {
        return Err(PlyErrorKind::MissingNormals {
            present: vertex.prop_names(),
        });
    }
    let rgba = COLOR_PROPERTIES.iter().find_map(|[r, g, b, a]| {
        let rgb = [vertex.find(&[r])?, vertex.find(&[g])?, vertex.find(&[b])?];
        Some((rgb, vertex.find(&[a])))
    });
    let conf = vertex.find(&["confidence", "value"]);
    let sensor = SENSOR_PROPERTIES
        .iter()
        .find_map(|[x, y, z]| Some([vertex.find(&[x])?, vertex.find(&[y])?, vertex.find(&[z])?]));

    // Slots: position 0-2, normal 3-5, colour 6-9, confidence 10, sensor 11-13, channels 14...
    let mut plan = Plan::skip(vertex);
    for (slot, &p) in pos.iter().chain(nrm.iter().flatten()).enumerate() {
        plan.slots[p] = Some(slot);
    }
    let mut color_type = ColorType::U8;
    let mut color_full = [1.0; 4];
    if let Some((rgb, alpha)) = rgba {
        for (k, p) in rgb.into_iter().map(Some).chain([alpha]).enumerate() {
            if let Some(p) = p {
                plan.slots[p] = Some(6 + k);
                if let PropType::Scalar(s) = vertex.props[p].ty {
                    color_full[k] = ColorType::of(s).full();
                    if k == 0 {
                        color_type = ColorType::of(s);
                    }
                }
            }
        }
    }
    if let Some(c) = conf {
        plan.slots[c] = Some(10);
    }
    for (k, &p) in sensor.iter().flatten().enumerate() {
        plan.slots[p] = Some(11 + k);
    }
    for (p, slot) in vertex.props.iter().zip(&plan.slots) {
        if slot.is_some() && !matches!(p.ty, PropType::Scalar(_)) {
            return Err(PlyErrorKind::Header {
                line: p.line,
                message: format!(
                    "vertex property '{}' is a list, expected a single number",
                    p.name
                ),
            });
        }
    }
    // Every other scalar property is a channel (the first of a repeated name).
    let interpreted = |name: &str| {
        [
            "x", "y", "z", "nx", "ny", "nz", "normal_x", "normal_y", "normal_z",
        ]
        .contains(&name)
            || ["confidence", "value"].contains(&name)
            || SENSOR_PREFIXES
                .iter()
                .any(|prefix| name.starts_with(prefix))
    };
    let mut channel_names: Vec<String> = Vec::new();
    for (p, prop) in vertex.props.iter().enumerate() {
        if plan.slots[p].is_none()
            && matches!(prop.ty, PropType::Scalar(_))
            && !interpreted(&prop.name)
            && !channel_names.contains(&prop.name)
        {
            plan.slots[p] = Some(14 + channel_names.len());
            channel_names.push(prop.name.clone());
        }
    }

    let face_index = header.element("face").filter(|_| faces);
    let last = face_index.map_or(vi, |fi| vi.max(fi));
    let size_checked = match file_len {
        Some(len) => {
            check_sizes(&header, last, len.saturating_sub(header.bytes))?;
            true
        }
        None => false,
    };
    let mut faces = match face_index {
        Some(index) => {
            let el = &header.elements[index];
            Some(Faces {
                index,
                plan: face_plan(el)?,
                vertex_count: vertex.count,
                corners: Vec::new(),
                triangles: Vec::with_capacity(capacity(el.count, size_checked)),
            })
        }
        None => None,
    };
    let cap =
        capacity(vertex.count, size_checked).min(chunks.as_ref().map_or(usize::MAX, |c| c.size));
    let components = match rgba {
        Some((_, Some(_))) => 4,
        Some((_, None)) => 3,
        None => 0,
    };
    let mut colors: Vec<f32> = Vec::with_capacity(cap * components);
    let mut channels: Vec<Vec<f32>> = channel_names
        .iter()
        .map(|_| Vec::with_capacity(cap))
        .collect();
    let double = pos
        .iter()
        .any(|&p| matches!(vertex.props[p].ty, PropType::Scalar(Scalar::F64)));
    let mut out = PlyPoints {
        positions: Vec::with_capacity(cap),
        positions_f64: double.then(|| Vec::with_capacity(cap)),
        normals: Vec::with_capacity(if nrm.is_some() { cap } else { 0 }),
        colors: None,
        color_type,
        confidence: conf.map(|_| Vec::with_capacity(cap)),
        sensors: sensor.map(|_| Vec::with_capacity(cap)),
        channels: Vec::new(),
    };
    let mut body = Body::new(r, &header);
    body.skip_ahead = skip_ahead;
    for (i, el) in header.elements[..vi].iter().enumerate() {
        Faces::read_or_skip(&mut faces, &mut body, i, el)?;
    }
    let mut stopped = false;
    let wanted = match &chunks {
        Some(Chunks { part: (r, n), .. }) => {
            let at = |i: usize| (vertex.count as u128 * i as u128 / *n as u128) as usize;
            at(*r)..at(r + 1)
        }
        None => 0..vertex.count,
    };
    let mut chunk_first = wanted.start as u64;
    let read = body.read_entries(vertex, &plan, wanted.clone(), |index, v, _| {
        if !wanted.contains(&index) {
            return Ok(());
        }
        if out.positions.is_empty() {
            chunk_first = index as u64;
        }
        out.positions.push([v[0] as f32, v[1] as f32, v[2] as f32]);
        if let Some(exact) = &mut out.positions_f64 {
            exact.push([v[0], v[1], v[2]]);
        }
        if nrm.is_some() {
            out.normals.push([v[3] as f32, v[4] as f32, v[5] as f32]);
        }
        for k in 0..components {
            colors.push((v[6 + k] / color_full[k]) as f32);
        }
        if let Some(c) = &mut out.confidence {
            c.push(v[10] as f32);
        }
        if let Some(s) = &mut out.sensors {
            s.push([v[11] as f32, v[12] as f32, v[13] as f32]);
        }
        for (k, channel) in channels.iter_mut().enumerate() {
            channel.push(v[14 + k] as f32);
        }
        if let Some(Chunks { size, each, .. }) = chunks.as_mut() {
            if out.positions.len() >= *size {
                let chunk = take_chunk(
                    &mut out,
                    &mut colors,
                    &mut channels,
                    components,
                    &channel_names,
                );
                if !each(chunk_first, chunk) {
                    stopped = true;
                    return Err("the consumer of the points stopped the reading".into());
                }
            }
        }
        Ok(())
    });
    if stopped {
        return Ok((out, Vec::new()));
    }
    read?;
    if let Some(Chunks { each, .. }) = chunks.as_mut() {
        if !out.positions.is_empty() {
            let chunk = take_chunk(
                &mut out,
                &mut colors,
                &mut channels,
                components,
                &channel_names,
            );
            each(chunk_first, chunk);
        }
        return Ok((out, Vec::new()));
    }
    if components > 0 {
        out.colors = Some(Colors::from_flattened(components, &colors));
    }
    out.channels = channel_names
        .into_iter()
        .zip(channels)
        .map(|(name, values)| Channel::new(name, values))
        .collect();
    for (i, el) in header
        .elements
        .iter()
        .enumerate()
        .take(last + 1)
        .skip(vi + 1)
    {
        Faces::read_or_skip(&mut faces, &mut body, i, el)?;
    }
    Ok((out, faces.map(|f| f.triangles).unwrap_or_default()))
}

/// How to read a `face` element: its `vertex_indices` (or `vertex_index`) list.
fn face_plan(face: &Element) -> Result<Plan, PlyErrorKind> {
    let mut plan = Plan::skip(face);
    match face.find(&["vertex_indices", "vertex_index"]) {
        Some(p) if matches!(face.props[p].ty, PropType::List { .. }) => plan.list = Some(p),
        _ => {
            return Err(PlyErrorKind::MissingProperty {
                element: "face".into(),
                wanted: "vertex_indices list".into(),
                present: face.prop_names(),
            })
        }
    }
    Ok(plan)
}

/// Adds the polygon whose corners are `list` (vertex indices, checked against `vertex_count`)
/// to `triangles` as a fan around its first corner; fewer than 3 corners add nothing.
fn push_polygon(
    list: &[f64],
    vertex_count: usize,
    corners: &mut Vec<u32>,
    triangles: &mut Vec<[u32; 3]>,
) -> Result<(), String> {
    corners.clear();
    for &v in list {
        if !(v >= 0.0 && v.fract() == 0.0 && v < vertex_count as f64) {
            return Err(format!(
                "vertex index {v} is out of range (the file has {vertex_count} vertices)"
            ));
        }
        // Exact: v is a whole number below vertex_count (a usize).
        let Ok(v) = u32::try_from(v as u64) else {
            return Err(format!(
                "vertex index {v} is beyond the 2^32 vertices psr's meshes can index"
            ));
        };
        corners.push(v);
    }
    for k in 2..corners.len() {
        triangles.push([corners[0], corners[k - 1], corners[k]]);
    }
    Ok(())
}

/// Writes oriented points as PLY (see [`write_point_cloud_to`]).
pub fn write_point_cloud(path: &Path, points: &PlyPoints, format: PlyFormat) -> io::Result<()> {
    write_file(path, |w| write_point_cloud_to(w, points, format))
}

/// Writes oriented points as PLY in the given format: `float x y z nx ny nz`, then
/// `red green blue [alpha]` as `points.color_type`, `float confidence`,
/// `float sensor_x sensor_y sensor_z` and a `float` property per channel when present.
pub fn write_point_cloud_to(
    mut w: impl Write,
    points: &PlyPoints,
    format: PlyFormat,
) -> io::Result<()> {
    let n = points.positions.len();
    let lengths_ok = points.normals.len() == n
        && points.colors.as_ref().is_none_or(|c| c.len() == n)
        && points.confidence.as_ref().is_none_or(|c| c.len() == n)
        && points.sensors.as_ref().is_none_or(|s| s.len() == n)
        && points.channels.iter().all(|c| c.values.len() == n);
    if !lengths_ok {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "PlyPoints: normals, colors, confidence, sensors and channels must have one entry per \
             position",
        ));
    }
    let mut names: Vec<&str> = vec!["x", "y", "z", "nx", "ny", "nz"];
    let mut header = format!(
        "ply\nformat {} 1.0\ncomment written by psr {}\nelement vertex {n}\n",
        format.header_name(),
        env!("CARGO_PKG_VERSION")
    );
    for p in ["x", "y", "z", "nx", "ny", "nz"] {
        header.push_str(&format!("property float {p}\n"));
    }
    let components = points.colors.as_ref().map_or(0, Colors::components);
    for name in &COLOR_PROPERTIES[0][..components] {
        header.push_str(&format!("property {} {name}\n", points.color_type.name()));
        names.push(name);
    }
    if points.confidence.is_some() {
        header.push_str("property float confidence\n");
        names.push("confidence");
    }
    if points.sensors.is_some() {
        for p in SENSOR_PROPERTIES[0] {
            header.push_str(&format!("property float {p}\n"));
            names.push(p);
        }
    }
    add_channels(&mut header, &mut names, &points.channels)?;
    header.push_str("end_header\n");
    w.write_all(header.as_bytes())?;

    let colors = points.colors.as_ref().map(Colors::as_flattened);
    let mut chunk = Chunk::new(w);
    let mut record = Vec::with_capacity(64);
    for i in 0..n {
        let floats = points.positions[i].iter().chain(&points.normals[i]);
        let rgb = colors.map(|c| &c[i * components..(i + 1) * components]);
        let conf = points.confidence.as_ref().map(|c| c[i]);
        let sensor = points.sensors.as_ref().map(|s| s[i]);
        let channels = points.channels.iter().map(|c| c.values[i]);
        match format {
            PlyFormat::Ascii => {
                let mut line = String::with_capacity(96);
                for (k, v) in floats.enumerate() {
                    if k > 0 {
                        line.push(' ');
                    }
                    line.push_str(&v.to_string());
                }
                for &c in rgb.into_iter().flatten() {
                    line.push(' ');
                    line.push_str(&points.color_type.text(c));
                }
                if let Some(c) = conf {
                    line.push_str(&format!(" {c}"));
                }
                for v in sensor.iter().flatten() {
                    line.push_str(&format!(" {v}"));
                }
                for v in channels {
                    line.push_str(&format!(" {v}"));
                }
                line.push('\n');
                chunk.put(line.as_bytes())?;
            }
            PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                let big = format == PlyFormat::BinaryBigEndian;
                let f32_bytes = |v: f32| {
                    if big {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    }
                };
                record.clear();
                for &v in floats {
                    record.extend_from_slice(&f32_bytes(v));
                }
                for &c in rgb.into_iter().flatten() {
                    points.color_type.encode(c, big, &mut record);
                }
                for v in conf.into_iter().chain(sensor.into_iter().flatten()) {
                    record.extend_from_slice(&f32_bytes(v));
                }
                for v in channels {
                    record.extend_from_slice(&f32_bytes(v));
                }
                chunk.put(&record)?;
            }
        }
    }
    chunk.finish()
}

/// Declares a `float` property per channel after the properties `names` already declared,
/// refusing a name that is taken or that a PLY header cannot hold.
fn add_channels<'a>(
    header: &mut String,
    names: &mut Vec<&'a str>,
    channels: &'a [Channel],
) -> io::Result<()> {
    for channel in channels {
        let name = channel.name.as_str();
        if name.is_empty() || name.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("channel name {name:?} cannot be a PLY property name (empty, or with whitespace)"),
            ));
        }
        if names.contains(&name) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("channel name {name:?} is already a property of the vertices: rename the channel"),
            ));
        }
        names.push(name);
        header.push_str(&format!("property float {name}\n"));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Meshes
// ---------------------------------------------------------------------------------------------

/// A triangle mesh as read from PLY: vertex positions and triangles (indices into them).
pub type MeshData = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// Reads a polygon mesh from a PLY file (see [`read_mesh_from`]).
pub fn read_mesh(path: &Path) -> Result<MeshData, PlyError> {
    let (reader, len) = open(path)?;
    read_mesh_impl(reader, len).map_err(|e| PlyError::new(e).with_path(path))
}

/// Reads a polygon mesh from PLY data: the `vertex` element's `x y z` and the `face` element's
/// `vertex_indices` (or `vertex_index`) lists. A polygon with n > 3 corners becomes a fan of
/// n − 2 triangles around its first corner; faces with fewer than 3 corners are dropped.
pub fn read_mesh_from(reader: impl BufRead) -> Result<MeshData, PlyError> {
    read_mesh_impl(reader, None).map_err(PlyError::new)
}

fn read_mesh_impl<R: BufRead>(mut r: R, file_len: Option<u64>) -> Result<MeshData, PlyErrorKind> {
    let header = parse_header(&mut r)?;
    let Some(vi) = header.element("vertex") else {
        return Err(PlyErrorKind::MissingElement {
            element: "vertex".into(),
        });
    };
    let Some(fi) = header.element("face") else {
        return Err(PlyErrorKind::MissingElement {
            element: "face".into(),
        });
    };
    let (vertex, face) = (&header.elements[vi], &header.elements[fi]);
    let mut vplan = Plan::skip(vertex);
    for (slot, name) in ["x", "y", "z"].iter().enumerate() {
        match vertex.find(&[name]) {
            Some(p) if matches!(vertex.props[p].ty, PropType::Scalar(_)) => {
                vplan.slots[p] = Some(slot)
            }
            _ => {
                return Err(PlyErrorKind::MissingProperty {
                    element: "vertex".into(),
                    wanted: "x y z properties".into(),
                    present: vertex.prop_names(),
                })
            }
        }
    }
    let fplan = face_plan(face)?;

    let size_checked = match file_len {
        Some(len) => {
            check_sizes(&header, vi.max(fi), len.saturating_sub(header.bytes))?;
            true
        }
        None => false,
    };
    let vertex_count = vertex.count;
    let mut positions = Vec::with_capacity(capacity(vertex_count, size_checked));
    let mut triangles = Vec::with_capacity(capacity(face.count, size_checked));
    let mut body = Body::new(r, &header);
    let mut corners: Vec<u32> = Vec::new();
    for (i, el) in header.elements.iter().enumerate().take(vi.max(fi) + 1) {
        if i == vi {
            body.read_element(el, &vplan, |_, v, _| {
                positions.push([v[0] as f32, v[1] as f32, v[2] as f32]);
                Ok(())
            })?;
        } else if i == fi {
            body.read_element(el, &fplan, |_, _, list| {
                push_polygon(list, vertex_count, &mut corners, &mut triangles)
            })?;
        } else {
            body.read_element(el, &Plan::skip(el), |_, _, _| Ok(()))?;
        }
    }
    Ok((positions, triangles))
}

/// How [`write_mesh_with`] writes a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct WriteOptions {
    /// The PLY type of the colours (default [`ColorType::U8`]); write the input's
    /// ([`PlyPoints::color_type`]) to give them back as they came.
    pub color_type: ColorType,
    /// The encoding of the body (default [`PlyFormat::BinaryLittleEndian`], compact and what
    /// PoissonRecon writes on little-endian machines; [`PlyFormat::Ascii`] is its `--ascii`).
    pub format: PlyFormat,
    /// Write `x y z` as `double`, [`Mesh::origin`] + each position added in `f64` (default
    /// false). They are written so anyway when the mesh's origin is not 0 (its points were
    /// given in `f64`), since `float` coordinates there would lose what the origin keeps.
    /// PoissonRecon: `--double` (its build templated on `double`).
    pub double_positions: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            color_type: ColorType::U8,
            format: PlyFormat::BinaryLittleEndian,
            double_positions: false,
        }
    }
}

impl WriteOptions {
    /// These options with [`WriteOptions::color_type`] set to `color_type`.
    pub fn with_color_type(mut self, color_type: ColorType) -> Self {
        self.color_type = color_type;
        self
    }

    /// These options with [`WriteOptions::format`] set to `format`.
    pub fn with_format(mut self, format: PlyFormat) -> Self {
        self.format = format;
        self
    }

    /// These options with [`WriteOptions::double_positions`] set to `double_positions`.
    pub fn with_double_positions(mut self, double_positions: bool) -> Self {
        self.double_positions = double_positions;
        self
    }
}

/// Writes a mesh as binary little-endian PLY (see [`write_mesh_to`]).
pub fn write_mesh(path: &Path, mesh: &Mesh) -> io::Result<()> {
    write_mesh_with(path, mesh, &WriteOptions::default())
}

/// Writes a mesh as PLY with `options` (see [`write_mesh_to_with`]).
pub fn write_mesh_with(path: &Path, mesh: &Mesh, options: &WriteOptions) -> io::Result<()> {
    write_file(path, |w| write_mesh_to_with(w, mesh, options))
}

/// [`write_mesh_to_with`] with the default options (binary little-endian, colours as `uchar`).
pub fn write_mesh_to(w: impl Write, mesh: &Mesh) -> io::Result<()> {
    write_mesh_to_with(w, mesh, &WriteOptions::default())
}

/// The most vertices a mesh written as PLY may have: `uint` indices address 2³² of them.
pub const MAX_PLY_MESH_VERTICES: u64 = 1 << 32;

/// The PLY type of the face element's vertex indices for a mesh of `vertex_count` vertices:
/// `int` while every index fits it (up to 2³¹ vertices), the type PoissonRecon, Open3D and
/// MeshLab write and every reader takes; `uint` up to 2³² vertices ([`MAX_PLY_MESH_VERTICES`]);
/// beyond that none, since PLY has no standard 64-bit integer type (PoissonRecon's BIG_DATA
/// build writes a `longlong` few readers know), and the error says to write OBJ instead.
fn face_index_type(vertex_count: u64) -> Result<Scalar, String> {
    if vertex_count <= 1 << 31 {
        Ok(Scalar::I32)
    } else if vertex_count <= MAX_PLY_MESH_VERTICES {
        Ok(Scalar::U32)
    } else {
        Err(format!(
            "mesh has {vertex_count} vertices: PLY's largest standard index type (uint) \
             addresses {MAX_PLY_MESH_VERTICES}; write OBJ instead, whose indices have no limit"
        ))
    }
}

/// One element entry (a vertex or a face) of a PLY body being put together, in either
/// encoding: values as text separated by spaces, or as bytes.
struct Entry {
    format: PlyFormat,
    buf: Vec<u8>,
}

impl Entry {
    fn new(format: PlyFormat) -> Self {
        Entry {
            format,
            buf: Vec::with_capacity(128),
        }
    }

    fn big(&self) -> bool {
        self.format == PlyFormat::BinaryBigEndian
    }

    /// Starts a value given as text in ASCII.
    fn text(&mut self, value: impl fmt::Display) {
        if !self.buf.is_empty() {
            self.buf.push(b' ');
        }
        // Writing to a Vec cannot fail.
        let _ = write!(self.buf, "{value}");
    }

    fn float(&mut self, v: f32) {
        match self.format {
            PlyFormat::Ascii => self.text(v),
            PlyFormat::BinaryLittleEndian => self.buf.extend_from_slice(&v.to_le_bytes()),
            PlyFormat::BinaryBigEndian => self.buf.extend_from_slice(&v.to_be_bytes()),
        }
    }

    fn double(&mut self, v: f64) {
        match self.format {
            PlyFormat::Ascii => self.text(v),
            PlyFormat::BinaryLittleEndian => self.buf.extend_from_slice(&v.to_le_bytes()),
            PlyFormat::BinaryBigEndian => self.buf.extend_from_slice(&v.to_be_bytes()),
        }
    }

    fn color(&mut self, ty: ColorType, v: f32) {
        match self.format {
            PlyFormat::Ascii => self.text(ty.text(v)),
            _ => ty.encode(v, self.big(), &mut self.buf),
        }
    }

    fn uchar(&mut self, v: u8) {
        match self.format {
            PlyFormat::Ascii => self.text(v),
            _ => self.buf.push(v),
        }
    }

    /// A vertex index as `ty` (from [`face_index_type`]); an index the type cannot hold is an
    /// error, never a wrapped value.
    fn index(&mut self, ty: Scalar, v: u32) -> io::Result<()> {
        let bytes = match ty {
            Scalar::I32 => {
                let v = i32::try_from(v).map_err(|_| {
                    io::Error::new(
                        io::ErrorKind::InvalidInput,
                        format!("vertex index {v} does not fit the PLY index type int"),
                    )
                })?;
                if self.big() {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                }
            }
            _ if self.big() => v.to_be_bytes(),
            _ => v.to_le_bytes(),
        };
        match self.format {
            PlyFormat::Ascii => self.text(v),
            _ => self.buf.extend_from_slice(&bytes),
        }
        Ok(())
    }

    /// The entry's bytes (a line in ASCII); the entry is empty again after `put`.
    fn put<W: Write>(&mut self, chunk: &mut Chunk<W>) -> io::Result<()> {
        if self.format == PlyFormat::Ascii {
            self.buf.push(b'\n');
        }
        chunk.put(&self.buf)?;
        self.buf.clear();
        Ok(())
    }
}

/// Checks that every per-vertex array of `mesh` (densities and normals when not empty,
/// colours, channels) has one entry per vertex and that every triangle's indices name a vertex:
/// what a writer needs before it writes anything.
pub(crate) fn check_mesh(mesh: &Mesh) -> io::Result<()> {
    let n = mesh.positions.len();
    let per_vertex = [
        ("densities", mesh.densities.len()),
        ("normals", mesh.normals.len()),
    ]
    .into_iter()
    .filter(|&(_, len)| len != 0)
    .chain(mesh.colors.as_ref().map(|c| ("colors", c.len())))
    .chain(
        mesh.channels
            .iter()
            .map(|c| (c.name.as_str(), c.values.len())),
    );
    for (what, len) in per_vertex {
        if len != n {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("mesh has {len} {what} for {n} vertices"),
            ));
        }
    }
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("mesh triangle {t:?} refers to a vertex beyond the {n} vertices"),
        ));
    }
    Ok(())
}

/// Writes a mesh as PLY in `options.format`: vertex `float x y z`, then whichever the mesh
/// has of `float nx ny nz` (its normals), `float value` (the per-vertex density),
/// `red green blue [alpha]` (its colours, as `options.color_type`) and a `float` property per
/// channel (named like it); and face `list uchar int vertex_indices` (`uint` for meshes of
/// more than 2³¹ vertices; more than 2³² are refused, see [`MAX_PLY_MESH_VERTICES`]). A channel
/// named like another vertex property is refused.
pub fn write_mesh_to_with(
    mut w: impl Write,
    mesh: &Mesh,
    options: &WriteOptions,
) -> io::Result<()> {
    check_mesh(mesh)?;
    let n = mesh.positions.len();
    let with_density = !mesh.densities.is_empty();
    let with_normals = !mesh.normals.is_empty();
    let index_type = face_index_type(n as u64)
        .map_err(|message| io::Error::new(io::ErrorKind::InvalidInput, message))?;
    let double = options.double_positions || mesh.origin != [0.0; 3];
    let position_type = if double { "double" } else { "float" };
    let mut header = format!(
        "ply\nformat {} 1.0\ncomment written by psr {}\nelement vertex {n}\n\
         property {position_type} x\nproperty {position_type} y\nproperty {position_type} z\n",
        options.format.header_name(),
        env!("CARGO_PKG_VERSION")
    );
    let mut names = vec!["x", "y", "z"];
    if with_normals {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        names.extend(["nx", "ny", "nz"]);
    }
    if with_density {
        header.push_str("property float value\n");
        names.push("value");
    }
    let components = mesh.colors.as_ref().map_or(0, Colors::components);
    for name in &COLOR_PROPERTIES[0][..components] {
        header.push_str(&format!("property {} {name}\n", options.color_type.name()));
        names.push(name);
    }
    add_channels(&mut header, &mut names, &mesh.channels)?;
    header.push_str(&format!(
        "element face {}\nproperty list uchar {} vertex_indices\nend_header\n",
        mesh.triangles.len(),
        index_type.name()
    ));
    w.write_all(header.as_bytes())?;

    let colors = mesh.colors.as_ref().map(Colors::as_flattened);
    let mut chunk = Chunk::new(w);
    let mut entry = Entry::new(options.format);
    for (i, p) in mesh.positions.iter().enumerate() {
        let normal = mesh.normals.get(i).into_iter().flatten();
        let density = mesh.densities.get(i);
        if double {
            for (o, &c) in mesh.origin.iter().zip(p) {
                entry.double(o + c as f64);
            }
            for &v in normal.chain(density) {
                entry.float(v);
            }
        } else {
            for &v in p.iter().chain(normal).chain(density) {
                entry.float(v);
            }
        }
        for &c in colors.map_or(&[][..], |c| &c[i * components..(i + 1) * components]) {
            entry.color(options.color_type, c);
        }
        for channel in &mesh.channels {
            entry.float(channel.values[i]);
        }
        entry.put(&mut chunk)?;
    }
    for t in &mesh.triangles {
        entry.uchar(3);
        for &v in t {
            entry.index(index_type, v)?;
        }
        entry.put(&mut chunk)?;
    }
    chunk.finish()
}

/// Creates `path`, runs `write` on a buffered writer to it and flushes; errors name the path.
pub(crate) fn write_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    let with_path = |action: &str, e: io::Error| {
        io::Error::new(
            e.kind(),
            format!("{}: cannot {action}: {e}", path.display()),
        )
    };
    let file = File::create(path).map_err(|e| with_path("create the file", e))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    write(&mut w)
        .and_then(|()| w.flush())
        .map_err(|e| with_path("write the file", e))?;
    Ok(())
}

/// Gathers small records into large writes.
pub(crate) struct Chunk<W: Write> {
    w: W,
    buf: Vec<u8>,
}

const CHUNK_BYTES: usize = 1 << 20;

impl<W: Write> Chunk<W> {
    pub(crate) fn new(w: W) -> Self {
        Chunk {
            w,
            buf: Vec::with_capacity(CHUNK_BYTES),
        }
    }

    pub(crate) fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.buf.len() + bytes.len() > CHUNK_BYTES {
            self.w.write_all(&self.buf)?;
            self.buf.clear();
        }
        self.buf.extend_from_slice(bytes);
        Ok(())
    }

    pub(crate) fn finish(mut self) -> io::Result<()> {
        self.w.write_all(&self.buf)?;
        self.w.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_points(with_extras: bool) -> PlyPoints {
        let positions = vec![[0.5, -1.25, 3.0e-7], [1.0e6, 2.5, -0.1], [0.0, 0.0, 0.0]];
        let normals = vec![
            [0.0, 0.0, 1.0],
            [0.6, 0.8, 0.0],
            [-0.33333334, 0.6666667, -0.6666667],
        ];
        let uchar = |c: [u8; 3]| c.map(|v| (v as f64 / 255.0) as f32);
        PlyPoints {
            positions,
            positions_f64: None,
            normals,
            colors: with_extras.then(|| {
                Colors::Rgb(vec![
                    uchar([255, 0, 7]),
                    uchar([1, 2, 3]),
                    uchar([128, 64, 32]),
                ])
            }),
            confidence: with_extras.then(|| vec![0.25, 1.0, 7.5]),
            sensors: with_extras
                .then(|| vec![[0.0, 0.0, 10.0], [-3.5, 1.0e5, 0.0], [1.0, 2.0, 3.0]]),
            channels: if with_extras {
                vec![
                    Channel::new("intensity", vec![0.5, -2.0, 1.0e-3]),
                    Channel::new("label", vec![1.0, 2.0, 3.0]),
                ]
            } else {
                Vec::new()
            },
            ..PlyPoints::default()
        }
    }

    fn to_bytes(points: &PlyPoints, format: PlyFormat) -> Vec<u8> {
        let mut bytes = Vec::new();
        write_point_cloud_to(&mut bytes, points, format).unwrap();
        bytes
    }

    fn read(bytes: &[u8]) -> Result<PlyPoints, PlyError> {
        read_point_cloud_from(bytes)
    }

    /// A file name in the temporary directory, unique to this process and test.
    fn temp_path(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("psr-ply-test-{}-{name}", std::process::id()))
    }

    /// Proves: reading a file in chunks hands over every point once, in file order, with its
    /// normal, colour, confidence, sensor and channels, in chunks of the asked size (the last
    /// shorter), ASCII and binary; and a consumer's error stops the reading and comes back.
    #[test]
    fn chunks_hand_over_the_whole_cloud_in_order() {
        let one = sample_points(true);
        let mut points = one.clone();
        for _ in 0..4 {
            points.positions.extend_from_slice(&one.positions);
            points.normals.extend_from_slice(&one.normals);
            let (Some(Colors::Rgb(all)), Some(Colors::Rgb(more))) =
                (&mut points.colors, &one.colors)
            else {
                unreachable!("sample_points has RGB colours")
            };
            all.extend_from_slice(more);
            points
                .confidence
                .as_mut()
                .unwrap()
                .extend_from_slice(one.confidence.as_ref().unwrap());
            points
                .sensors
                .as_mut()
                .unwrap()
                .extend_from_slice(one.sensors.as_ref().unwrap());
            for (all, more) in points.channels.iter_mut().zip(&one.channels) {
                all.values.extend_from_slice(&more.values);
            }
        }
        for format in [PlyFormat::Ascii, PlyFormat::BinaryLittleEndian] {
            let path = temp_path(&format!("chunks-{format:?}.ply"));
            std::fs::write(&path, to_bytes(&points, format)).unwrap();
            let whole = read_point_cloud(&path).unwrap();
            for size in [1, 4, 15, 100] {
                let mut start = 0;
                let mut sizes = Vec::new();
                read_point_cloud_chunks(&path, size, |chunk: PlyPoints| -> Result<(), ()> {
                    let range = start..start + chunk.positions.len();
                    assert_eq!(chunk.positions, whole.positions[range.clone()]);
                    assert_eq!(chunk.normals, whole.normals[range.clone()]);
                    let Some(Colors::Rgb(colors)) = &chunk.colors else {
                        panic!("colours")
                    };
                    let Some(Colors::Rgb(all)) = &whole.colors else {
                        panic!("colours")
                    };
                    assert_eq!(colors[..], all[range.clone()]);
                    assert_eq!(
                        chunk.confidence.unwrap(),
                        whole.confidence.as_ref().unwrap()[range.clone()]
                    );
                    assert_eq!(
                        chunk.sensors.unwrap(),
                        whole.sensors.as_ref().unwrap()[range.clone()]
                    );
                    for (c, w) in chunk.channels.iter().zip(&whole.channels) {
                        assert_eq!(
                            (&c.name, &c.values[..]),
                            (&w.name, &w.values[range.clone()])
                        );
                    }
                    sizes.push(range.len());
                    start = range.end;
                    Ok(())
                })
                .unwrap()
                .unwrap();
                assert_eq!(start, 15, "{format:?}, chunks of {size}");
                assert!(
                    sizes.iter().rev().skip(1).all(|&n| n == size)
                        && sizes[sizes.len() - 1] <= size
                );
            }
            let mut calls = 0;
            let stopped = read_point_cloud_chunks(&path, 4, |_| {
                calls += 1;
                if calls == 2 {
                    Err("full disk")
                } else {
                    Ok(())
                }
            })
            .unwrap();
            assert_eq!((stopped, calls), (Err("full disk"), 2));
            std::fs::remove_file(&path).unwrap();
        }
    }

    /// Proves: the parts of a file (r of n) hand over every point once between them, each
    /// part's chunks in file order with the index of their first point, the parts' lengths
    /// within one of each other; ASCII, binary (the points before a part passed over
    /// undecoded) and binary with a list property among the vertices' (read and dropped).
    #[test]
    fn parts_hand_over_every_point_once_with_its_index() {
        let mut points = sample_points(true);
        for i in 0..200 {
            let t = i as f32 * 0.37;
            points.positions.push([t.sin(), t.cos(), t * 0.01]);
            points.normals.push([0.0, 0.0, 1.0]);
        }
        points.colors = None;
        points.confidence = None;
        points.sensors = None;
        points.channels.clear();
        let n = points.positions.len();
        let binary = to_bytes(&points, PlyFormat::BinaryLittleEndian);
        let binary_copy = binary.clone();
        // The same points with a list property after the vertex's scalars (entries of varying
        // size: no skipping by bytes).
        let header = "ply\nformat binary_little_endian 1.0\nelement vertex N\n\
                      property float x\nproperty float y\nproperty float z\n\
                      property float nx\nproperty float ny\nproperty float nz\n\
                      property list uchar int tags\nend_header\n"
            .replace('N', &n.to_string());
        let mut listed = header.into_bytes();
        for (i, (p, q)) in points.positions.iter().zip(&points.normals).enumerate() {
            for c in p.iter().chain(q) {
                listed.extend_from_slice(&c.to_le_bytes());
            }
            listed.push((i % 3) as u8);
            for t in 0..i % 3 {
                listed.extend_from_slice(&(t as i32).to_le_bytes());
            }
        }
        for (name, bytes) in [
            ("ascii", to_bytes(&points, PlyFormat::Ascii)),
            ("binary", binary),
            ("listed", listed),
        ] {
            let path = temp_path(&format!("parts-{name}.ply"));
            std::fs::write(&path, &bytes).unwrap();
            for parts in [1, 2, 3, 7] {
                let mut seen: Vec<[f32; 3]> = Vec::new();
                let mut lengths = Vec::new();
                for r in 0..parts {
                    let before = seen.len();
                    read_point_cloud_part_chunks(&path, 16, (r, parts), |first, chunk| {
                        assert_eq!(first as usize, seen.len(), "{name}: {r} of {parts}");
                        seen.extend_from_slice(&chunk.positions);
                        Ok::<(), ()>(())
                    })
                    .unwrap()
                    .unwrap();
                    lengths.push(seen.len() - before);
                }
                assert_eq!(seen, points.positions, "{name}, {parts} parts");
                let (lo, hi) = (lengths.iter().min(), lengths.iter().max());
                assert!(hi.unwrap() - lo.unwrap() <= 1, "{name}: {lengths:?}");
            }
            std::fs::remove_file(&path).unwrap();
        }
        // A binary file cut short before a part: sought past, the missing points are still
        // found missing, whichever part is read.
        let path = temp_path("parts-cut-short.ply");
        std::fs::write(&path, &binary_copy[..binary_copy.len() * 2 / 3]).unwrap();
        for r in 0..3 {
            let read = read_point_cloud_part_chunks(&path, 16, (r, 3), |_, _| Ok::<(), ()>(()));
            assert!(read.is_err(), "part {r} of a file cut short");
        }
        std::fs::remove_file(&path).unwrap();
    }

    /// Proves: read_points reads a cloud with no normals (empty normals), and reads the
    /// normals when they are there; read_point_cloud still refuses the first.
    #[test]
    fn points_without_normals_read_with_read_points_only() {
        let bare = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                    property float z\nend_header\n1 2 3\n4 5 6\n";
        let points = read_points_from(bare.as_bytes()).unwrap();
        assert_eq!(points.positions, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert!(points.normals.is_empty());
        let err = read_point_cloud_from(bare.as_bytes()).unwrap_err();
        assert!(matches!(err.kind(), PlyErrorKind::MissingNormals { .. }));
        let oriented =
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                        property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
                        end_header\n1 2 3 0 0 1\n";
        let points = read_points_from(oriented.as_bytes()).unwrap();
        assert_eq!(points.normals, vec![[0.0, 0.0, 1.0]]);
    }

    /// Proves: each convention of SENSOR_PROPERTIES is read as the points' sensors, in any
    /// order and type among other properties, the first complete triple wins, and an
    /// incomplete triple is no sensor at all.
    #[test]
    fn sensor_positions_are_read_under_each_convention() {
        for [x, y, z] in SENSOR_PROPERTIES {
            let text = format!(
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty double {z}\nproperty float x\n\
                 property float y\nproperty float z\nproperty uchar intensity\n\
                 property double {x}\nproperty int {y}\nend_header\n\
                 30 1 2 3 7 10 20\n-3 4 5 6 7 -1 -2\n"
            );
            let points = read_points_from(text.as_bytes()).unwrap();
            assert_eq!(points.positions, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
            assert_eq!(
                points.sensors,
                Some(vec![[10.0, 20.0, 30.0], [-1.0, -2.0, -3.0]]),
                "{x} {y} {z}"
            );
        }
        let both = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                    property float z\nproperty float vp_x\nproperty float vp_y\n\
                    property float vp_z\nproperty float sensor_x\nproperty float sensor_y\n\
                    property float sensor_z\nend_header\n0 0 0 1 1 1 2 2 2\n";
        let points = read_points_from(both.as_bytes()).unwrap();
        assert_eq!(
            points.sensors,
            Some(vec![[2.0, 2.0, 2.0]]),
            "sensor_* first"
        );
        let partial = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
                       property float y\nproperty float z\nproperty float sensor_x\n\
                       property float sensor_y\nproperty float vp_z\nend_header\n0 0 0 1 2 3\n";
        let points = read_points_from(partial.as_bytes()).unwrap();
        assert_eq!(points.sensors, None, "no complete triple");
        assert_eq!(points.positions, vec![[0.0, 0.0, 0.0]]);
    }

    #[test]
    fn round_trips_in_every_format() {
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            for extras in [false, true] {
                let points = sample_points(extras);
                let back = read(&to_bytes(&points, format)).unwrap();
                assert_eq!(back, points, "{format:?} extras={extras}");
            }
        }
    }

    #[test]
    fn round_trips_through_a_file_and_reads_the_header_we_write() {
        let path = temp_path("cloud.ply");
        let points = sample_points(true);
        write_point_cloud(&path, &points, PlyFormat::BinaryLittleEndian).unwrap();
        let back = read_point_cloud(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back, points);
    }

    /// Builds a binary file by hand: header text, then raw body bytes.
    fn binary_file(header: &str, body: &[u8]) -> Vec<u8> {
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(body);
        bytes
    }

    #[test]
    fn skips_other_properties_lists_and_elements_in_binary() {
        let header =
            "ply\r\nformat binary_little_endian 1.0\r\ncomment any text\r\nobj_info more\r\n\
            element camera 2\r\nproperty list uchar float path\r\nproperty int8 id\r\n\
            element vertex 2\r\nproperty uchar flags\r\nproperty double x\r\nproperty int16 y\r\n\
            property list ushort uint neighbours\r\nproperty float32 z\r\nproperty uint8 nx\r\n\
            property char ny\r\nproperty uint nz\r\nproperty float value\r\nproperty uchar red\r\n\
            element face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n";
        let mut body = Vec::new();
        // camera: a 2-float list then an id; a 0-length list then an id.
        body.extend_from_slice(&[2]);
        body.extend_from_slice(&1.0f32.to_le_bytes());
        body.extend_from_slice(&2.0f32.to_le_bytes());
        body.extend_from_slice(&[5, 0, 6]);
        for (i, &(x, y, z)) in [(1.5f64, -3i16, 0.25f32), (-2.0, 7, 8.0)]
            .iter()
            .enumerate()
        {
            body.push(0xAA);
            body.extend_from_slice(&x.to_le_bytes());
            body.extend_from_slice(&y.to_le_bytes());
            body.extend_from_slice(&(i as u16 + 1).to_le_bytes());
            for k in 0..=i as u32 {
                body.extend_from_slice(&(k * 1000).to_le_bytes());
            }
            body.extend_from_slice(&z.to_le_bytes());
            body.push(1);
            body.push((-2i8) as u8);
            body.extend_from_slice(&3u32.to_le_bytes());
            body.extend_from_slice(&0.5f32.to_le_bytes());
            body.push(9);
        }
        body.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]);
        let points = read(&binary_file(header, &body)).unwrap();
        assert_eq!(points.positions, vec![[1.5, -3.0, 0.25], [-2.0, 7.0, 8.0]]);
        assert_eq!(points.normals, vec![[1.0, -2.0, 3.0]; 2]);
        assert_eq!(points.confidence, Some(vec![0.5, 0.5]));
        assert_eq!(points.colors, None, "red alone is not a colour");
        let channels: Vec<(&str, &[f32])> = points
            .channels
            .iter()
            .map(|c| (c.name.as_str(), c.values.as_slice()))
            .collect();
        assert_eq!(
            channels,
            vec![("flags", &[170.0, 170.0][..]), ("red", &[9.0, 9.0][..])],
            "other scalar properties, lists excluded, are channels"
        );
        // The face element after the vertices is never needed, so a cut there does not matter;
        // a cut inside the vertices does.
        let cut = binary_file(header, &body[..body.len() - 20]);
        assert!(
            matches!(read(&cut).unwrap_err().kind(), PlyErrorKind::Truncated { element, index: 1, count: 2 } if element == "vertex")
        );
    }

    #[test]
    fn skips_other_properties_lists_and_elements_in_ascii() {
        let text = "ply\nformat ascii 1.0\nelement material 1\nproperty list uchar uchar name\n\
            element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
            property list uchar int junk\nproperty float nx\nproperty float ny\nproperty float nz\n\
            property float confidence\nproperty float value\n\
            element face 1\nproperty list uchar int vertex_indices\nend_header\n\
            3 65 66 67\n\
            1 2 3 2 10 11 0 0 1 0.5 9\n\
            \n\
            -1e-3 4.5 6 0 1 0 0 2 7\r\n\
            7 8 9 3 1 2 3 1 0 0 1 9\n\
            3 0 1 2\n";
        let points = read(text.as_bytes()).unwrap();
        assert_eq!(
            points.positions,
            vec![[1.0, 2.0, 3.0], [-1e-3, 4.5, 6.0], [7.0, 8.0, 9.0]]
        );
        assert_eq!(
            points.normals,
            vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
        );
        assert_eq!(
            points.confidence,
            Some(vec![0.5, 2.0, 1.0]),
            "confidence wins over value"
        );
    }

    #[test]
    fn reads_big_endian_doubles_and_float_colours() {
        let header = "ply\nformat binary_big_endian 1.0\nelement vertex 1\n\
            property float64 x\nproperty float64 y\nproperty float64 z\n\
            property double nx\nproperty double ny\nproperty double nz\n\
            property float red\nproperty float green\nproperty float blue\nend_header\n";
        let mut body = Vec::new();
        for v in [0.1f64, 0.2, 0.3, 0.0, -1.0, 0.0] {
            body.extend_from_slice(&v.to_be_bytes());
        }
        for v in [1.0f32, 0.5, 0.0] {
            body.extend_from_slice(&v.to_be_bytes());
        }
        let points = read(&binary_file(header, &body)).unwrap();
        assert_eq!(points.positions, vec![[0.1, 0.2, 0.3]]);
        assert_eq!(points.normals, vec![[0.0, -1.0, 0.0]]);
        assert_eq!(points.colors, Some(Colors::Rgb(vec![[1.0, 0.5, 0.0]])));
        assert_eq!(points.color_type, ColorType::F32);
    }

    /// Proves: colours are read under each convention of COLOR_PROPERTIES, with the
    /// convention's alpha when present, scaled to 0..1 by their type (uchar / 255, ushort /
    /// 65535, float as is); the properties psr interprets are never channels, the others are;
    /// and a cloud written with its colour type and channels reads back the same.
    #[test]
    fn colours_alpha_and_channels_are_read_and_written_back_alike() {
        let cases = [
            (
                "uchar",
                ["red", "green", "blue", "alpha"],
                ["255", "51", "0", "102"],
                ColorType::U8,
            ),
            (
                "ushort",
                [
                    "diffuse_red",
                    "diffuse_green",
                    "diffuse_blue",
                    "diffuse_alpha",
                ],
                ["65535", "0", "13107", "65535"],
                ColorType::U16,
            ),
            (
                "float",
                ["r", "g", "b", "a"],
                ["1", "0.2", "0.5", "0.25"],
                ColorType::F32,
            ),
        ];
        for (ty, names, values, color_type) in cases {
            for with_alpha in [false, true] {
                let count = if with_alpha { 4 } else { 3 };
                let mut header = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
                    property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
                    property float nz\nproperty float confidence\nproperty float sensor_x\n\
                    property float vp_y\nproperty float beamoriginz\nproperty short temperature\n"
                    .to_string();
                for name in &names[..count] {
                    header.push_str(&format!("property {ty} {name}\n"));
                }
                header.push_str("property double quality\nend_header\n");
                let line = format!(
                    "1 2 3 0 0 1 0.5 7 8 9 -40 {} 0.75\n",
                    values[..count].join(" ")
                );
                let points = read((header + &line).as_bytes()).unwrap();
                let full = match color_type {
                    ColorType::U8 => 255.0,
                    ColorType::U16 => 65535.0,
                    _ => 1.0,
                };
                let want: Vec<f32> = values[..count]
                    .iter()
                    .map(|v| (v.parse::<f64>().unwrap() / full) as f32)
                    .collect();
                let colors = points.colors.as_ref().expect("colours");
                assert_eq!(colors.as_flattened(), &want[..], "{ty} {names:?}");
                assert_eq!(colors.components(), count);
                assert_eq!(points.color_type, color_type);
                let names: Vec<&str> = points.channels.iter().map(|c| c.name.as_str()).collect();
                assert_eq!(names, ["temperature", "quality"], "{ty}");
                assert_eq!(points.channels[0].values, [-40.0]);
                for format in [PlyFormat::Ascii, PlyFormat::BinaryBigEndian] {
                    let mut copy = points.clone();
                    copy.sensors = None;
                    let back = read(&to_bytes(&copy, format)).unwrap();
                    assert_eq!(back, copy, "{ty} {format:?}");
                }
            }
        }
    }

    #[test]
    fn truncated_files_give_a_truncation_error() {
        for format in [
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
            PlyFormat::Ascii,
        ] {
            let bytes = to_bytes(&sample_points(true), format);
            let cut = if format == PlyFormat::Ascii {
                // Drop the whole last line.
                let body = &bytes[..bytes.len() - 1];
                &bytes[..body.iter().rposition(|&b| b == b'\n').unwrap() + 1]
            } else {
                &bytes[..bytes.len() - 3]
            };
            let err = read(cut).unwrap_err();
            assert!(
                matches!(
                    err.kind(),
                    PlyErrorKind::Truncated {
                        index: 2,
                        count: 3,
                        ..
                    }
                ),
                "{format:?}: {err}"
            );
            assert!(err.to_string().contains("truncated"), "{err}");
        }
    }

    #[test]
    fn every_prefix_and_many_corruptions_fail_cleanly() {
        for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
            let bytes = to_bytes(&sample_points(true), format);
            // An ASCII file cut inside its last line may still parse (as a shorter last number).
            let last_line = bytes[..bytes.len() - 1]
                .iter()
                .rposition(|&b| b == b'\n')
                .unwrap()
                + 1;
            for len in 0..bytes.len() {
                let result = read(&bytes[..len]);
                if format != PlyFormat::Ascii || len <= last_line {
                    assert!(result.is_err(), "{format:?} prefix {len}");
                }
            }
            // Flip bytes pseudo-randomly: any result is fine as long as nothing panics.
            let mut state = 0x9E37_79B9_7F4A_7C15u64;
            for _ in 0..2000 {
                let mut corrupt = bytes.clone();
                for _ in 0..3 {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let at = (state >> 33) as usize % corrupt.len();
                    corrupt[at] = (state >> 20) as u8;
                }
                let _ = read(&corrupt);
                let _ = read_mesh_from(&corrupt[..]);
            }
        }
    }

    #[test]
    fn missing_normals_are_named() {
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
            property float z\nproperty uchar red\nend_header\n1 2 3 4\n";
        let err = read(text.as_bytes()).unwrap_err();
        assert!(matches!(err.kind(), PlyErrorKind::MissingNormals { .. }));
        let message = err.to_string();
        assert!(message.contains("no nx ny nz"), "{message}");
        assert!(message.contains("x y z red"), "{message}");
    }

    #[test]
    fn bad_headers_are_reported_with_their_line() {
        let cases: &[(&str, &str)] = &[
            ("", "not a PLY file"),
            ("PLY\n", "not a PLY file"),
            ("\u{89}PNG\r\n", "not a PLY file"),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\n",
                "before the end_header",
            ),
            (
                "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
                "line 3",
            ),
            ("ply\nformat xml 1.0\nend_header\n", "unknown format 'xml'"),
            ("ply\nformat ascii 2.0\nend_header\n", "version"),
            ("ply\nelement vertex 1\nend_header\n", "before any format"),
            (
                "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
                "line 3",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
                "float128",
            ),
            (
                "ply\nformat ascii 1.0\nelement f 1\nproperty list float int v\nend_header\n",
                "list count",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n",
                "twice",
            ),
            (
                "ply\nformat ascii 1.0\nbogus\nend_header\n",
                "unknown keyword 'bogus'",
            ),
            (
                "ply\nformat ascii 1.0\nelement face 0\nend_header\n",
                "no 'vertex' element",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n",
                "no x y z",
            ),
        ];
        for (text, expected) in cases {
            let message = read(text.as_bytes()).unwrap_err().to_string();
            assert!(message.contains(expected), "{text:?}: {message}");
        }
    }

    #[test]
    fn bad_ascii_values_name_the_line() {
        let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
            property float z\nproperty float nx\nproperty float ny\nproperty uchar nz\nend_header\n";
        let cases = [
            ("1 2 3 0 0 1\n1 2 x 0 0 1\n", "line 12"),
            ("1 2 3 0 0 1\n1 2 3 0 0 256\n", "not a valid uchar"),
            ("1 2 3 0 0\n", "line 11"),
            ("1 2 3 0 0 1 5\n", "more values"),
        ];
        for (body, expected) in cases {
            let message = read(format!("{head}{body}").as_bytes())
                .unwrap_err()
                .to_string();
            assert!(message.contains(expected), "{body:?}: {message}");
        }
    }

    #[test]
    fn absurd_counts_are_refused_before_allocating() {
        let path = temp_path("absurd.ply");
        let header = "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n\
            property float x\nproperty float y\nproperty float z\nproperty float nx\n\
            property float ny\nproperty float nz\nend_header\n";
        std::fs::write(&path, binary_file(header, &[0; 48])).unwrap();
        let err = read_point_cloud(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(err.kind(), PlyErrorKind::TooLarge { .. }), "{err}");
        assert!(
            err.to_string().starts_with(&path.display().to_string()),
            "{err}"
        );
        // Without a file size to check against, the count only bounds nothing: reading stops at
        // the end of the data.
        let err = read(&binary_file(header, &[0; 48])).unwrap_err();
        assert!(
            matches!(err.kind(), PlyErrorKind::Truncated { index: 2, .. }),
            "{err}"
        );
        let faces = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
            property float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
        let err = read_mesh_from(&binary_file(faces, &u32::MAX.to_le_bytes())[..]).unwrap_err();
        assert!(
            matches!(err.kind(), PlyErrorKind::Truncated { .. }),
            "{err}"
        );
    }

    #[test]
    fn the_smallest_ascii_file_passes_the_size_check() {
        let path = temp_path("tiny.ply");
        let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
            property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n\
            0 0 0 0 0 1\n1 1 1 1 0 0";
        std::fs::write(&path, text).unwrap();
        let result = read_point_cloud(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(result.unwrap().positions, vec![[0.0; 3], [1.0; 3]]);
    }

    #[test]
    fn missing_files_name_the_path() {
        let path = temp_path("does-not-exist.ply");
        let err = read_point_cloud(&path).unwrap_err();
        assert!(matches!(
            err.kind(),
            PlyErrorKind::Io { action: "open", .. }
        ));
        assert!(std::error::Error::source(&err).is_some());
        let message = err.to_string();
        assert!(
            message.contains("does-not-exist.ply") && message.contains("cannot open"),
            "{message}"
        );
    }

    fn sample_mesh(densities: bool) -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, -1.5],
            ],
            triangles: vec![[0, 1, 2], [0, 3, 1], [3, 2, 1]],
            densities: if densities {
                vec![1.0, 2.0, 0.5, 0.0]
            } else {
                Vec::new()
            },
            ..Mesh::default()
        }
    }

    #[test]
    fn meshes_round_trip_with_and_without_density() {
        for densities in [false, true] {
            let mesh = sample_mesh(densities);
            let mut bytes = Vec::new();
            write_mesh_to(&mut bytes, &mesh).unwrap();
            let header_len = bytes
                .windows(11)
                .position(|w| w == b"end_header\n")
                .unwrap()
                + 11;
            let header = std::str::from_utf8(&bytes[..header_len]).unwrap();
            assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
            assert!(header.contains("element vertex 4\n") && header.contains("element face 3\n"));
            assert!(header.contains("property list uchar int vertex_indices\n"));
            assert_eq!(header.contains("property float value\n"), densities);
            let stride = if densities { 16 } else { 12 };
            assert_eq!(bytes.len(), header_len + 4 * stride + 3 * 13);
            let (positions, triangles) = read_mesh_from(&bytes[..]).unwrap();
            assert_eq!(positions, mesh.positions);
            assert_eq!(triangles, mesh.triangles);
            // The density comes back as a point cloud's `value` only with normals; check bytes.
            if densities {
                let v = &bytes[header_len + 12..header_len + 16];
                assert_eq!(f32::from_le_bytes([v[0], v[1], v[2], v[3]]), 1.0);
            }
        }
        let path = temp_path("mesh.ply");
        write_mesh(&path, &sample_mesh(true)).unwrap();
        let (positions, triangles) = read_mesh(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!((positions.len(), triangles.len()), (4, 3));
    }

    /// Proves: a mesh's normals, colours (in the type asked for) and channels are written as
    /// vertex properties that read back as they were, and the layout without them is the old
    /// one (x y z value).
    #[test]
    fn mesh_normals_colours_and_channels_are_written() {
        let mut mesh = sample_mesh(true);
        mesh.normals = vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.6, 0.0, -0.8],
        ];
        let uchar = |c: [u8; 4]| c.map(|v| (v as f64 / 255.0) as f32);
        mesh.colors = Some(Colors::Rgba(vec![
            uchar([255, 0, 0, 255]),
            uchar([0, 255, 0, 128]),
            uchar([0, 0, 255, 0]),
            uchar([10, 20, 30, 40]),
        ]));
        mesh.channels = vec![Channel::new("intensity", vec![0.0, 0.5, 1.0, 1.5])];
        for color_type in [ColorType::U8, ColorType::U16, ColorType::F32] {
            let mut bytes = Vec::new();
            let options = WriteOptions::default().with_color_type(color_type);
            write_mesh_to_with(&mut bytes, &mesh, &options).unwrap();
            let back = read_point_cloud_from(&bytes[..]).unwrap();
            assert_eq!(back.positions, mesh.positions);
            assert_eq!(back.normals, mesh.normals);
            assert_eq!(
                back.confidence.as_deref(),
                Some(&mesh.densities[..]),
                "value"
            );
            assert_eq!(back.colors, mesh.colors, "{color_type:?}");
            assert_eq!(back.color_type, color_type);
            assert_eq!(back.channels, mesh.channels);
            let (positions, triangles) = read_mesh_from(&bytes[..]).unwrap();
            assert_eq!(
                (positions, triangles),
                (mesh.positions.clone(), mesh.triangles.clone())
            );
        }
        for taken in ["value", "nx", "alpha", "intensity"] {
            let mut clash = mesh.clone();
            clash.channels.push(Channel::new(taken, vec![0.0; 4]));
            let err = write_mesh_to(io::sink(), &clash).unwrap_err();
            assert!(err.to_string().contains(taken), "{err}");
        }
        let mut short = mesh.clone();
        short.channels[0].values.pop();
        assert!(write_mesh_to(io::sink(), &short).is_err());
    }

    #[test]
    fn write_mesh_refuses_inconsistent_meshes() {
        let mut mesh = sample_mesh(true);
        mesh.densities.pop();
        assert!(write_mesh_to(io::sink(), &mesh).is_err());
        let mut mesh = sample_mesh(false);
        mesh.triangles.push([0, 1, 4]);
        assert!(write_mesh_to(io::sink(), &mesh).is_err());
        let err =
            write_mesh(&temp_path("no-such-dir").join("m.ply"), &sample_mesh(false)).unwrap_err();
        assert!(err.to_string().contains("no-such-dir"), "{err}");
    }

    /// Proves: a mesh with every attribute round-trips in each of the three formats (ASCII is
    /// PoissonRecon's --ascii): positions, normals, density, colours, channels and triangles
    /// come back exactly, and the header names the format and the `int` index type.
    #[test]
    fn meshes_round_trip_in_every_format() {
        let mut mesh = sample_mesh(true);
        mesh.positions[1] = [1.0e6, -3.3333333e-7, 0.1];
        mesh.normals = vec![
            [0.0, 0.0, 1.0],
            [0.6, 0.0, -0.8],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
        ];
        let uchar = |c: [u8; 3]| c.map(|v| (v as f64 / 255.0) as f32);
        mesh.colors = Some(Colors::Rgb(vec![
            uchar([255, 0, 0]),
            uchar([0, 255, 7]),
            uchar([0, 0, 255]),
            uchar([10, 20, 30]),
        ]));
        mesh.channels = vec![Channel::new("intensity", vec![0.0, 0.5, -1.0e-9, 1.5])];
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            let mut bytes = Vec::new();
            let options = WriteOptions::default().with_format(format);
            write_mesh_to_with(&mut bytes, &mesh, &options).unwrap();
            let text = String::from_utf8_lossy(&bytes);
            assert!(
                text.starts_with(&format!("ply\nformat {} 1.0\n", format.header_name())),
                "{format:?}"
            );
            assert!(text.contains("property list uchar int vertex_indices\n"));
            if format == PlyFormat::Ascii {
                assert!(text.ends_with("\n3 0 1 2\n3 0 3 1\n3 3 2 1\n"), "{text}");
            }
            let back = read_point_cloud_from(&bytes[..]).unwrap();
            assert_eq!(back.positions, mesh.positions, "{format:?}");
            assert_eq!(back.normals, mesh.normals, "{format:?}");
            assert_eq!(back.confidence.as_deref(), Some(&mesh.densities[..]));
            assert_eq!(back.colors, mesh.colors, "{format:?}");
            assert_eq!(back.channels, mesh.channels, "{format:?}");
            let (positions, triangles) = read_mesh_from(&bytes[..]).unwrap();
            assert_eq!(positions, mesh.positions, "{format:?}");
            assert_eq!(triangles, mesh.triangles, "{format:?}");
        }
    }

    /// Proves: the face index type follows the vertex count (int up to 2^31 vertices, uint up
    /// to 2^32) and a larger mesh is refused with a message that says why and what to do,
    /// without allocating such a mesh; an index that does not fit the chosen type is an error,
    /// never a wrapped value.
    #[test]
    fn face_indices_are_int_then_uint_and_never_wrap() {
        assert_eq!(face_index_type(0), Ok(Scalar::I32));
        assert_eq!(face_index_type(1 << 31), Ok(Scalar::I32));
        assert_eq!(face_index_type((1 << 31) + 1), Ok(Scalar::U32));
        assert_eq!(face_index_type(1 << 32), Ok(Scalar::U32));
        let message = face_index_type((1 << 32) + 1).unwrap_err();
        assert!(
            message.contains("4294967297 vertices") && message.contains("OBJ"),
            "{message}"
        );
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            let mut entry = Entry::new(format);
            assert!(entry.index(Scalar::I32, 1 << 31).is_err(), "{format:?}");
            entry.index(Scalar::I32, (1 << 31) - 1).unwrap();
            entry.index(Scalar::U32, u32::MAX).unwrap();
            let expected: Vec<u8> = match format {
                PlyFormat::Ascii => b"2147483647 4294967295".to_vec(),
                PlyFormat::BinaryLittleEndian => {
                    [0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff, 0xff].to_vec()
                }
                PlyFormat::BinaryBigEndian => {
                    [0x7f, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff].to_vec()
                }
            };
            assert_eq!(entry.buf, expected, "{format:?}");
        }
    }

    /// The same mesh (a unit square as a quad, plus a triangle above it) in each format, with a
    /// double coordinate, an extra vertex property, a list-typed face index and an element after
    /// the faces: every format gives the same positions, and the quad becomes a fan.
    #[test]
    fn meshes_with_quads_read_alike_in_every_format() {
        let positions = [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.5, 0.5, 1.0],
        ];
        let faces: [&[i32]; 2] = [&[0, 1, 2, 3], &[0, 1, 4]];
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            let header = format!(
                "ply\nformat {} 1.0\nelement vertex 5\nproperty double x\nproperty float y\n\
                 property float z\nproperty uchar red\nelement face 2\n\
                 property list uchar int vertex_indices\nelement edge 1\nproperty int a\n\
                 property int b\nend_header\n",
                format.header_name()
            );
            let mut body = Vec::new();
            let big = format == PlyFormat::BinaryBigEndian;
            let mut put = |bytes: &[u8]| {
                let mut bytes = bytes.to_vec();
                if big {
                    bytes.reverse();
                }
                body.extend_from_slice(&bytes);
            };
            if format == PlyFormat::Ascii {
                let mut text = String::new();
                for (i, p) in positions.iter().enumerate() {
                    text.push_str(&format!("{} {} {} {i}\n", p[0], p[1], p[2]));
                }
                for f in faces {
                    let corners: Vec<String> = f.iter().map(i32::to_string).collect();
                    text.push_str(&format!("{} {}\n", f.len(), corners.join(" ")));
                }
                text.push_str("0 1\n");
                put(text.as_bytes());
            } else {
                // Little-endian bytes, reversed value by value for big-endian.
                for (i, p) in positions.iter().enumerate() {
                    put(&(p[0] as f64).to_le_bytes());
                    put(&p[1].to_le_bytes());
                    put(&p[2].to_le_bytes());
                    put(&[i as u8]);
                }
                for f in faces {
                    put(&[f.len() as u8]);
                    for &v in f {
                        put(&v.to_le_bytes());
                    }
                }
                put(&0i32.to_le_bytes());
                put(&1i32.to_le_bytes());
            }
            let (read_positions, triangles) =
                read_mesh_from(&binary_file(&header, &body)[..]).unwrap();
            assert_eq!(read_positions, positions, "{format:?}");
            assert_eq!(
                triangles,
                vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]],
                "{format:?}"
            );
        }
    }

    #[test]
    fn polygons_become_fans_and_bad_indices_are_errors() {
        let text = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
            property float z\nelement face 3\nproperty uchar flags\nproperty list uchar uint vertex_index\n\
            end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n7 4 0 1 2 3\n0 2 0 1\n1 5 0 1 2 3 4\n";
        let (positions, triangles) = read_mesh_from(text.as_bytes()).unwrap();
        assert_eq!(positions.len(), 5);
        assert_eq!(
            triangles,
            vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4]]
        );
        let bad = text.replace("0 2 0 1\n", "0 3 0 1 5\n");
        let message = read_mesh_from(bad.as_bytes()).unwrap_err().to_string();
        assert!(
            message.contains("out of range") && message.contains("line 17"),
            "{message}"
        );
        let no_faces =
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
            property float z\nend_header\n";
        let message = read_mesh_from(no_faces.as_bytes()).unwrap_err().to_string();
        assert!(message.contains("no 'face' element"), "{message}");
    }

    /// Proves: read_points_and_triangles reads a mesh's vertex properties as read_points does
    /// (value as the confidence, normals, colours, channels) and its faces as read_mesh does,
    /// in every format, with the face element before or after the vertices; a cloud has no
    /// triangles, and a bad index is an error.
    #[test]
    fn points_and_triangles_read_a_whole_mesh() {
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.5],
                [1.0, 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [2, 1, 3]],
            densities: vec![0.5, 1.5, 2.5, 3.5],
            normals: vec![[0.0, 0.0, 1.0]; 4],
            colors: Some(Colors::Rgb(vec![[1.0, 0.0, 0.0]; 4])),
            channels: vec![Channel::new("t", vec![4.0, 3.0, 2.0, 1.0])],
            ..Mesh::default()
        };
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            let mut bytes = Vec::new();
            let options = WriteOptions::default().with_format(format);
            write_mesh_to_with(&mut bytes, &mesh, &options).unwrap();
            let (points, triangles) = read_points_and_triangles_from(&bytes[..]).unwrap();
            assert_eq!(triangles, mesh.triangles, "{format:?}");
            assert_eq!(points.positions, mesh.positions);
            assert_eq!(points.confidence.as_deref(), Some(&mesh.densities[..]));
            assert_eq!(points.normals, mesh.normals);
            assert_eq!(points.colors, mesh.colors);
            assert_eq!(points.channels, mesh.channels);
            let alone = read_points_from(&bytes[..]).unwrap();
            assert_eq!(alone, points, "the vertices read as read_points reads them");
        }
        let faces_first = "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int \
            vertex_indices\nelement vertex 4\nproperty float x\nproperty float y\n\
            property float z\nend_header\n4 0 1 2 3\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n";
        let (points, triangles) = read_points_and_triangles_from(faces_first.as_bytes()).unwrap();
        assert_eq!(points.positions.len(), 4);
        assert_eq!(triangles, vec![[0, 1, 2], [0, 2, 3]]);
        let cloud = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
            property float y\nproperty float z\nend_header\n1 2 3\n";
        let (points, triangles) = read_points_and_triangles_from(cloud.as_bytes()).unwrap();
        assert_eq!((points.positions.len(), triangles.len()), (1, 0));
        let bad = faces_first.replace("4 0 1 2 3", "3 0 1 4");
        let message = read_points_and_triangles_from(bad.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(message.contains("out of range"), "{message}");
    }

    /// Proves: a face index past u32 (in a file that declares more vertices than that, faces
    /// first; double indices, as the reader knows no 64-bit integer type) is an error, not an index saturated or wrapped into psr's 32-bit triangles.
    #[test]
    fn face_indices_past_32_bits_are_errors() {
        let text =
            "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar double vertex_indices\n\
            element vertex 5000000000\nproperty float x\nproperty float y\nproperty float z\n\
            end_header\n3 0 1 4294967296\n";
        let message = read_mesh_from(text.as_bytes()).unwrap_err().to_string();
        assert!(
            message.contains("4294967296") && message.contains("2^32"),
            "{message}"
        );
    }
}
