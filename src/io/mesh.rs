//! Triangle-mesh files: reads Wavefront OBJ and Stanford PLY (ASCII and binary) files into
//! plain [`MeshData`] (positions plus triangle vertex indices), with no materials, normals or
//! texture coordinates, and writes binary PLY ([`ply_binary_f32`]). Coordinates are returned
//! exactly as stored, in scene units; polygons are fan-triangulated. Every malformed input is
//! a [`MeshIoError`] naming the file and, where it applies, the line or byte offset and the
//! offending token; the parsers never panic. What is accepted: docs/formats.md, "`io::mesh`".

use std::borrow::Cow;
use std::fmt;
use std::path::{Path, PathBuf};

/// Triangle mesh data as read from a file: positions in scene units, triangles as vertex indices.
///
/// `positions[i]` is the `[x, y, z]` of vertex `i`, in the file's own units
/// (the scene units the file was authored in). Each entry of `triangles`
/// holds three 0-based indices into `positions`, in the file's winding order.
/// Every index is guaranteed to be `< positions.len()`.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshData {
    /// Vertex positions `[x, y, z]` in scene units.
    pub positions: Vec<[f64; 3]>,
    /// Triangles as 0-based indices into [`MeshData::positions`].
    pub triangles: Vec<[u32; 3]>,
}

/// Where in a mesh file an error was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// 1-based line number (OBJ text, PLY header, or ASCII PLY body).
    Line(usize),
    /// Position in a binary PLY body: `offset` is the byte offset of the
    /// offending value from the start of the file (header included);
    /// `element` and `index` name the element instance being read
    /// (0-based, as PLY indices are).
    Byte {
        /// Byte offset from the start of the file.
        offset: usize,
        /// Name of the PLY element being read (e.g. `vertex`).
        element: String,
        /// 0-based index of the element instance.
        index: usize,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, "line {line}"),
            Location::Byte {
                offset,
                element,
                index,
            } => write!(f, "byte {offset} ({element} {index})"),
        }
    }
}

/// Everything that can go wrong while loading a mesh file.
///
/// Every variant carries the file path (shown with `Path::display`) and,
/// where one exists, the [`Location`] and offending token (shortened to at
/// most 64 characters) plus a description of what would have been accepted.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    /// The file holds more vertices or triangles than furnace accepts
    /// ([`crate::limits::MAX_VERTICES`], [`crate::limits::MAX_TRIANGLES`]).
    #[error("{}: {source}", .path.display())]
    TooLarge {
        /// File that was being read.
        path: PathBuf,
        /// The limit passed.
        #[source]
        source: crate::limits::LimitError,
    },
    /// The file could not be read.
    #[error("cannot read mesh file {}: {source}", .path.display())]
    Io {
        /// File that was being read.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file extension is not one of the supported formats.
    #[error(
        "{}: unsupported mesh file extension {}; allowed extensions: .obj, .ply (case-insensitive)",
        .path.display(),
        extension_label(.extension)
    )]
    UnsupportedExtension {
        /// File whose extension was rejected.
        path: PathBuf,
        /// The extension as written (without the dot); empty if there was none.
        extension: String,
    },
    /// A token that should be a number (coordinate, index, list length, PLY value) is not one.
    #[error("{}: {at}: invalid number {token:?}; expected {expected}", .path.display())]
    InvalidNumber {
        /// File containing the error.
        path: PathBuf,
        /// Where the token is.
        at: Location,
        /// The offending token.
        token: String,
        /// What would have been accepted.
        expected: String,
    },
    /// A vertex coordinate is NaN or infinite (including decimal overflow such as `1e999`).
    #[error(
        "{}: {at}: non-finite coordinate {token:?}; coordinates must be finite numbers (no NaN or infinity)",
        .path.display()
    )]
    NonFiniteCoordinate {
        /// File containing the error.
        path: PathBuf,
        /// Where the coordinate is.
        at: Location,
        /// The coordinate as written (OBJ / ASCII PLY) or as decoded (binary PLY).
        token: String,
    },
    /// A face refers to a vertex that does not exist (or uses the invalid OBJ index 0).
    #[error("{}: {at}: vertex index {token:?} is out of range; allowed: {allowed}", .path.display())]
    IndexOutOfRange {
        /// File containing the error.
        path: PathBuf,
        /// Where the index is.
        at: Location,
        /// The index as written (OBJ corner token, or PLY value).
        token: String,
        /// The valid range at that point of the file.
        allowed: String,
    },
    /// A face has fewer than three vertices.
    #[error(
        "{}: {at}: face has {count} vertices ({token:?}); a face needs at least 3 vertices",
        .path.display()
    )]
    TooFewFaceVertices {
        /// File containing the error.
        path: PathBuf,
        /// Where the face is.
        at: Location,
        /// The face statement (OBJ) or list length (PLY).
        token: String,
        /// Number of vertices the face has.
        count: usize,
    },
    /// A line ends before a required value (OBJ `v` with fewer than 3 coordinates, short ASCII PLY line).
    #[error("{}: {at}: line ends too early; expected {expected}", .path.display())]
    MissingValue {
        /// File containing the error.
        path: PathBuf,
        /// The line that is too short.
        at: Location,
        /// The value that is missing.
        expected: String,
    },
    /// A token that is well-formed text but not allowed here (extra ASCII PLY value, malformed OBJ face corner).
    #[error("{}: {at}: unexpected {token:?}; expected {expected}", .path.display())]
    UnexpectedToken {
        /// File containing the error.
        path: PathBuf,
        /// Where the token is.
        at: Location,
        /// The offending token.
        token: String,
        /// What would have been accepted.
        expected: String,
    },
    /// The PLY body ends before all elements declared in the header were read.
    #[error("{}: {at}: data ends too early; expected {expected}", .path.display())]
    Truncated {
        /// File containing the error.
        path: PathBuf,
        /// Where the data ran out (byte offset for binary, line after the last for ASCII).
        at: Location,
        /// What was still expected.
        expected: String,
    },
    /// The file contains no faces.
    #[error(
        "{}: no faces; a mesh file must contain at least one face with 3 or more vertices",
        .path.display()
    )]
    NoFaces {
        /// File without faces.
        path: PathBuf,
    },
    /// The PLY header is malformed.
    #[error("{}: line {line}: bad PLY header: found {token:?}; expected {expected}", .path.display())]
    BadHeader {
        /// File containing the error.
        path: PathBuf,
        /// 1-based header line.
        line: usize,
        /// The offending token (or `end of file`).
        token: String,
        /// What would have been accepted.
        expected: String,
    },
    /// The PLY `format` line names a format or version this reader does not support.
    #[error(
        "{}: line {line}: unsupported PLY format {token:?}; allowed: ascii 1.0, binary_little_endian 1.0, binary_big_endian 1.0",
        .path.display()
    )]
    UnsupportedFormat {
        /// File containing the error.
        path: PathBuf,
        /// 1-based header line of the `format` statement.
        line: usize,
        /// The format and version as written.
        token: String,
    },
    /// A required PLY property is missing.
    #[error(
        "{}: line {line}: PLY element {element:?} has no {property:?} property; required: {expected}",
        .path.display()
    )]
    MissingProperty {
        /// File containing the error.
        path: PathBuf,
        /// 1-based header line of the element declaration.
        line: usize,
        /// Element lacking the property (`vertex` or `face`).
        element: String,
        /// Name of the missing property.
        property: String,
        /// What the element must declare.
        expected: String,
    },
    /// A required PLY element (`vertex` or `face`) is not declared.
    #[error(
        "{}: PLY header declares no {element:?} element; required elements: vertex (with x, y, z) and face (with vertex_indices)",
        .path.display()
    )]
    MissingElement {
        /// File lacking the element.
        path: PathBuf,
        /// Name of the missing element.
        element: String,
    },
}

/// Result alias used by the private parsing helpers.
type Result<T> = std::result::Result<T, MeshIoError>;

/// Extensions [`load_mesh`] accepts (compared case-insensitively).
const OBJ_EXT: &str = "obj";
const PLY_EXT: &str = "ply";

/// Maximum number of characters of an offending token quoted in an error.
const MAX_TOKEN_CHARS: usize = 64;

/// Loads a triangle mesh from `path`, choosing the parser from the file
/// extension (`.obj` or `.ply`, case-insensitive).
///
/// Positions are returned in the file's units (scene units). OBJ files that
/// are not valid UTF-8 are decoded lossily (invalid bytes become U+FFFD).
///
/// # Errors
/// [`MeshIoError::UnsupportedExtension`] for any other extension (checked
/// before the file is opened), [`MeshIoError::Io`] if the file cannot be read,
/// and any error of [`parse_obj`] / [`parse_ply`].
pub fn load_mesh(path: &Path) -> std::result::Result<MeshData, MeshIoError> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let lower = extension.to_ascii_lowercase();
    if lower != OBJ_EXT && lower != PLY_EXT {
        return Err(MeshIoError::UnsupportedExtension {
            path: path.to_path_buf(),
            extension,
        });
    }
    let bytes =
        super::located::read_capped(path, crate::limits::MAX_MESH_BYTES).map_err(|source| {
            MeshIoError::Io {
                path: path.to_path_buf(),
                source,
            }
        })?;
    if lower == OBJ_EXT {
        parse_obj(&String::from_utf8_lossy(&bytes), path)
    } else {
        parse_ply(&bytes, path)
    }
}

/// Describes a file extension for error messages.
fn extension_label(extension: &str) -> String {
    if extension.is_empty() {
        "(none)".to_owned()
    } else {
        format!("{extension:?}")
    }
}

/// Shortens a token for quoting in an error message.
fn token_text(token: &str) -> String {
    match token.char_indices().nth(MAX_TOKEN_CHARS) {
        Some((cut, _)) => format!("{}…", token.get(..cut).unwrap_or(token)),
        None => token.to_owned(),
    }
}

/// Appends the fan triangulation of a polygon (given as vertex indices) to `out`; an error when
/// the file's triangles then pass [`crate::limits::MAX_TRIANGLES`].
fn fan_triangulate(corners: &[u32], out: &mut Vec<[u32; 3]>, path: &Path) -> Result<()> {
    if let Some((&first, rest)) = corners.split_first() {
        for pair in rest.windows(2) {
            if let &[b, c] = pair {
                out.push([first, b, c]);
            }
        }
    }
    within(
        out.len() as u64,
        crate::limits::MAX_TRIANGLES,
        "triangle",
        path,
    )
}

/// Names of the three coordinate axes, for messages.
const AXES: [&str; 3] = ["x", "y", "z"];

// ---------------------------------------------------------------------------
// OBJ
// ---------------------------------------------------------------------------

/// Parses Wavefront OBJ text into a triangle mesh; `path` is only used in error messages.
///
/// Positions are in the file's units (scene units); face indices are
/// converted from OBJ's 1-based (or negative, relative) form to 0-based.
/// Polygons are fan-triangulated (see the module documentation), and all
/// statements other than `v` and `f` are skipped.
///
/// # Errors
/// Non-numeric or missing coordinates, non-finite coordinates, malformed face
/// corners, face index 0 or out of range (relative to the vertices defined
/// before the face's line), faces with fewer than 3 vertices, and a file
/// with no faces.
pub fn parse_obj(text: &str, path: &Path) -> std::result::Result<MeshData, MeshIoError> {
    let mut mesh = MeshData {
        positions: Vec::new(),
        triangles: Vec::new(),
    };
    let mut corners: Vec<u32> = Vec::new();
    for (line_index, raw_line) in text.lines().enumerate() {
        let line = line_index + 1;
        let content = raw_line.split('#').next().unwrap_or_default();
        let mut tokens = content.split_whitespace();
        match tokens.next() {
            Some("v") => {
                let position = parse_obj_vertex(tokens, path, line)?;
                let n = mesh.positions.len() as u64 + 1;
                within(n, crate::limits::MAX_VERTICES, "vertex", path)?;
                mesh.positions.push(position);
            }
            Some("f") => {
                corners.clear();
                for token in tokens {
                    corners.push(parse_obj_corner(token, mesh.positions.len(), path, line)?);
                }
                if corners.len() < 3 {
                    return Err(MeshIoError::TooFewFaceVertices {
                        path: path.to_path_buf(),
                        at: Location::Line(line),
                        token: token_text(content.trim()),
                        count: corners.len(),
                    });
                }
                fan_triangulate(&corners, &mut mesh.triangles, path)?;
            }
            // Comments, blank lines, vt/vn/o/g/s/usemtl/mtllib/l/p and
            // unknown statements carry nothing this loader needs.
            _ => {}
        }
    }
    if mesh.triangles.is_empty() {
        return Err(MeshIoError::NoFaces {
            path: path.to_path_buf(),
        });
    }
    Ok(mesh)
}

/// Parses the coordinates of a `v` statement (the tokens after `v`).
fn parse_obj_vertex<'a>(
    mut tokens: impl Iterator<Item = &'a str>,
    path: &Path,
    line: usize,
) -> Result<[f64; 3]> {
    let mut position = [0.0; 3];
    for (slot, axis) in position.iter_mut().zip(AXES) {
        let token = tokens.next().ok_or_else(|| MeshIoError::MissingValue {
            path: path.to_path_buf(),
            at: Location::Line(line),
            expected: format!("the {axis} coordinate (a `v` statement needs x y z)"),
        })?;
        *slot = parse_text_coordinate(token, axis, path, Location::Line(line))?;
    }
    Ok(position)
}

/// Parses one coordinate token, rejecting non-numbers and non-finite values.
fn parse_text_coordinate(token: &str, axis: &str, path: &Path, at: Location) -> Result<f64> {
    let value: f64 = token.parse().map_err(|_| MeshIoError::InvalidNumber {
        path: path.to_path_buf(),
        at: at.clone(),
        token: token_text(token),
        expected: format!("a decimal number for the {axis} coordinate"),
    })?;
    if !value.is_finite() {
        return Err(MeshIoError::NonFiniteCoordinate {
            path: path.to_path_buf(),
            at,
            token: token_text(token),
        });
    }
    Ok(value)
}

/// Parses one face corner (`i`, `i/t`, `i//n`, `i/t/n`) into a 0-based vertex index.
fn parse_obj_corner(token: &str, vertex_count: usize, path: &Path, line: usize) -> Result<u32> {
    let mut parts = token.split('/');
    let vertex_part = parts.next().unwrap_or_default();
    if parts.count() > 2 {
        return Err(MeshIoError::UnexpectedToken {
            path: path.to_path_buf(),
            at: Location::Line(line),
            token: token_text(token),
            expected: "a face vertex written v, v/vt, v//vn or v/vt/vn".to_owned(),
        });
    }
    let index: i64 = vertex_part
        .parse()
        .map_err(|_| MeshIoError::InvalidNumber {
            path: path.to_path_buf(),
            at: Location::Line(line),
            token: token_text(token),
            expected:
                "an integer vertex index (1-based, or negative to count back from the last vertex)"
                    .to_owned(),
        })?;
    resolve_obj_index(index, vertex_count).ok_or_else(|| MeshIoError::IndexOutOfRange {
        path: path.to_path_buf(),
        at: Location::Line(line),
        token: token_text(token),
        allowed: obj_allowed_range(vertex_count),
    })
}

/// Converts a 1-based or negative OBJ index into a 0-based `u32`, if it is valid.
fn resolve_obj_index(index: i64, vertex_count: usize) -> Option<u32> {
    let count = i64::try_from(vertex_count).ok()?;
    let zero_based = if index > 0 {
        index - 1
    } else if index < 0 {
        count.checked_add(index)?
    } else {
        return None;
    };
    if (0..count).contains(&zero_based) {
        u32::try_from(zero_based).ok()
    } else {
        None
    }
}

/// Describes the valid OBJ face indices when `vertex_count` vertices are defined.
fn obj_allowed_range(vertex_count: usize) -> String {
    if vertex_count == 0 {
        "none, no vertices are defined before this line (0 is never a valid OBJ index)".to_owned()
    } else {
        format!(
            "1..={vertex_count} or -{vertex_count}..=-1 ({vertex_count} vertices defined before this line; 0 is never valid)"
        )
    }
}

// ---------------------------------------------------------------------------
// PLY header
// ---------------------------------------------------------------------------

/// Encoding of a PLY body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PlyFormat {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

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

/// Scalar type names accepted in PLY headers, for messages.
const SCALAR_NAMES: &str = "char, uchar, short, ushort, int, uint, float, double, int8, uint8, int16, uint16, int32, uint32, float32, float64";

impl Scalar {
    /// Parses a PLY type name (classic or sized alias).
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

    /// Size in bytes in a binary body.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
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

    /// Decodes a binary value; every PLY scalar is exactly representable as `f64`.
    fn decode(self, bytes: &[u8], big_endian: bool) -> Option<f64> {
        Some(match self {
            Scalar::I8 => f64::from(i8::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::U8 => f64::from(u8::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::I16 => f64::from(i16::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::U16 => f64::from(u16::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::I32 => f64::from(i32::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::U32 => f64::from(u32::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::F32 => f64::from(f32::from_le_bytes(ordered(bytes, big_endian)?)),
            Scalar::F64 => f64::from_le_bytes(ordered(bytes, big_endian)?),
        })
    }
}

/// Copies the first `N` bytes into little-endian order.
fn ordered<const N: usize>(bytes: &[u8], big_endian: bool) -> Option<[u8; N]> {
    let mut array: [u8; N] = bytes.get(..N)?.try_into().ok()?;
    if big_endian {
        array.reverse();
    }
    Some(array)
}

/// Type of a PLY property.
#[derive(Debug, Clone, Copy)]
enum PropertyKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: PropertyKind,
    line: usize,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
    line: usize,
}

#[derive(Debug)]
struct PlyHeader {
    format: PlyFormat,
    elements: Vec<Element>,
    /// Number of header lines, including `end_header`.
    line_count: usize,
    /// Byte offset of the first body byte.
    body_start: usize,
}

/// Builds a [`MeshIoError::BadHeader`].
fn bad_header(path: &Path, line: usize, token: &str, expected: impl Into<String>) -> MeshIoError {
    MeshIoError::BadHeader {
        path: path.to_path_buf(),
        line,
        token: token_text(token),
        expected: expected.into(),
    }
}

/// Parses the PLY header, up to and including the `end_header` line.
fn parse_ply_header(bytes: &[u8], path: &Path) -> Result<PlyHeader> {
    let mut pos = 0usize;
    let mut line = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line += 1;
        let rest = bytes.get(pos..).unwrap_or_default();
        let Some(newline) = rest.iter().position(|&b| b == b'\n') else {
            let expected = if line == 1 {
                "\"ply\" on the first line"
            } else {
                "more header lines, ending with end_header"
            };
            return Err(bad_header(path, line, "end of file", expected));
        };
        let raw = rest.get(..newline).unwrap_or_default();
        pos = pos.saturating_add(newline).saturating_add(1);
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let text = std::str::from_utf8(raw).map_err(|_| {
            bad_header(
                path,
                line,
                &String::from_utf8_lossy(raw),
                "ASCII header text",
            )
        })?;
        let mut tokens = text.split_whitespace();
        let keyword = tokens.next().unwrap_or_default();
        if line == 1 {
            if text.trim() != "ply" {
                return Err(bad_header(path, line, text, "\"ply\" on the first line"));
            }
            continue;
        }
        match keyword {
            "" | "comment" | "obj_info" => {}
            "format" => {
                if format.is_some() {
                    return Err(bad_header(path, line, text, "a single format line"));
                }
                let rest: Vec<&str> = tokens.collect();
                format = Some(match rest.as_slice() {
                    ["ascii", "1.0"] => PlyFormat::Ascii,
                    ["binary_little_endian", "1.0"] => PlyFormat::BinaryLittleEndian,
                    ["binary_big_endian", "1.0"] => PlyFormat::BinaryBigEndian,
                    _ => {
                        return Err(MeshIoError::UnsupportedFormat {
                            path: path.to_path_buf(),
                            line,
                            token: token_text(&rest.join(" ")),
                        })
                    }
                });
            }
            "element" => {
                let (Some(name), Some(count), None) = (tokens.next(), tokens.next(), tokens.next())
                else {
                    return Err(bad_header(path, line, text, "element <name> <count>"));
                };
                let count: usize = count.parse().map_err(|_| {
                    bad_header(path, line, count, "a non-negative integer element count")
                })?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(bad_header(path, line, name, "a unique element name"));
                }
                elements.push(Element {
                    name: name.to_owned(),
                    count,
                    properties: Vec::new(),
                    line,
                });
            }
            "property" => {
                let property = parse_ply_property(tokens, text, path, line)?;
                let Some(element) = elements.last_mut() else {
                    return Err(bad_header(
                        path,
                        line,
                        text,
                        "an element line before the first property",
                    ));
                };
                if element.properties.iter().any(|p| p.name == property.name) {
                    return Err(bad_header(
                        path,
                        line,
                        &property.name,
                        "a property name unique within its element",
                    ));
                }
                element.properties.push(property);
            }
            "end_header" => break,
            other => {
                return Err(bad_header(
                    path,
                    line,
                    other,
                    "one of format, comment, obj_info, element, property, end_header",
                ))
            }
        }
    }
    let format = format
        .ok_or_else(|| bad_header(path, line, "end_header", "a format line before end_header"))?;
    Ok(PlyHeader {
        format,
        elements,
        line_count: line,
        body_start: pos,
    })
}

/// Parses the tokens after `property` on a header line.
fn parse_ply_property<'a>(
    mut tokens: impl Iterator<Item = &'a str>,
    text: &str,
    path: &Path,
    line: usize,
) -> Result<Property> {
    let scalar = |name: &str| {
        Scalar::from_name(name).ok_or_else(|| {
            bad_header(
                path,
                line,
                name,
                format!("a PLY scalar type ({SCALAR_NAMES})"),
            )
        })
    };
    let first = tokens.next().unwrap_or_default();
    let (kind, name) = if first == "list" {
        let (Some(count), Some(item), Some(name), None) =
            (tokens.next(), tokens.next(), tokens.next(), tokens.next())
        else {
            return Err(bad_header(
                path,
                line,
                text,
                "property list <count type> <item type> <name>",
            ));
        };
        let count_type = scalar(count)?;
        if !count_type.is_integer() {
            return Err(bad_header(path, line, count, "an integer list count type"));
        }
        (
            PropertyKind::List {
                count: count_type,
                item: scalar(item)?,
            },
            name,
        )
    } else {
        let (Some(name), None) = (tokens.next(), tokens.next()) else {
            return Err(bad_header(path, line, text, "property <type> <name>"));
        };
        (PropertyKind::Scalar(scalar(first)?), name)
    };
    Ok(Property {
        name: name.to_owned(),
        kind,
        line,
    })
}

/// What the body reader does with each element.
#[derive(Debug, Clone, Copy)]
enum Role {
    /// Vertex element: indices of the x, y, z properties.
    Vertex([usize; 3]),
    /// Face element: index of the vertex-index list property.
    Face(usize),
    /// Any other element: read and discard.
    Skip,
}

/// Finds the vertex and face elements and the properties this loader needs.
/// Returns the role of each element and the declared vertex count.
fn plan_ply(header: &PlyHeader, path: &Path) -> Result<(Vec<Role>, usize)> {
    let missing_element = |name: &str| MeshIoError::MissingElement {
        path: path.to_path_buf(),
        element: name.to_owned(),
    };
    let mut roles = vec![Role::Skip; header.elements.len()];

    let (vertex_slot, vertex) = header
        .elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.name == "vertex")
        .ok_or_else(|| missing_element("vertex"))?;
    let mut xyz = [0usize; 3];
    for (slot, axis) in xyz.iter_mut().zip(AXES) {
        let (index, property) = vertex
            .properties
            .iter()
            .enumerate()
            .find(|(_, p)| p.name == axis)
            .ok_or_else(|| MeshIoError::MissingProperty {
                path: path.to_path_buf(),
                line: vertex.line,
                element: vertex.name.clone(),
                property: axis.to_owned(),
                expected: "scalar properties x, y and z (any PLY scalar type)".to_owned(),
            })?;
        if !matches!(property.kind, PropertyKind::Scalar(_)) {
            return Err(bad_header(
                path,
                property.line,
                axis,
                "x, y and z as scalar properties, not lists",
            ));
        }
        *slot = index;
    }
    if let Some(role) = roles.get_mut(vertex_slot) {
        *role = Role::Vertex(xyz);
    }

    let (face_slot, face) = header
        .elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.name == "face")
        .ok_or_else(|| missing_element("face"))?;
    let (list_index, list) = face
        .properties
        .iter()
        .enumerate()
        .find(|(_, p)| p.name == "vertex_indices" || p.name == "vertex_index")
        .ok_or_else(|| MeshIoError::MissingProperty {
            path: path.to_path_buf(),
            line: face.line,
            element: face.name.clone(),
            property: "vertex_indices".to_owned(),
            expected: "a list property named vertex_indices or vertex_index".to_owned(),
        })?;
    match list.kind {
        PropertyKind::List { item, .. } if item.is_integer() => {}
        PropertyKind::List { item, .. } => {
            return Err(bad_header(
                path,
                list.line,
                item.name(),
                "an integer vertex index type",
            ));
        }
        PropertyKind::Scalar(_) => {
            return Err(bad_header(
                path,
                list.line,
                &list.name,
                "vertex indices declared as `property list <count type> <index type> vertex_indices`",
            ));
        }
    }
    if let Some(role) = roles.get_mut(face_slot) {
        *role = Role::Face(list_index);
    }
    Ok((roles, vertex.count))
}

// ---------------------------------------------------------------------------
// PLY body
// ---------------------------------------------------------------------------

/// Parses a PLY file (header and body) into a triangle mesh; `path` is only used in error messages.
///
/// Accepts `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0`.
/// Positions are in the file's units (scene units); face indices are 0-based
/// as in the file. Polygons are fan-triangulated (see the module
/// documentation); properties and elements other than vertex x/y/z and face
/// vertex indices are skipped.
///
/// # Errors
/// Malformed header, unsupported format, missing `vertex` / `face` element or
/// x/y/z / vertex_indices property, truncated body, unparsable ASCII values,
/// wrong number of values on an ASCII line, non-finite coordinates, vertex
/// indices outside `0..vertex count`, faces with fewer than 3 vertices, and a
/// file with no faces.
pub fn parse_ply(bytes: &[u8], path: &Path) -> std::result::Result<MeshData, MeshIoError> {
    let header = parse_ply_header(bytes, path)?;
    let (roles, vertex_count) = plan_ply(&header, path)?;
    let body = bytes.get(header.body_start..).unwrap_or_default();
    let mesh = match header.format {
        PlyFormat::Ascii => {
            let text: Cow<'_, str> = String::from_utf8_lossy(body);
            let mut reader = AsciiReader::new(&text, header.line_count, path);
            read_ply_body(&mut reader, &header, &roles, vertex_count, body.len(), path)?
        }
        PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
            let mut reader = BinaryReader {
                path,
                bytes,
                pos: header.body_start,
                big_endian: header.format == PlyFormat::BinaryBigEndian,
                element: "",
                index: 0,
                last_start: header.body_start,
                last_value: 0.0,
            };
            read_ply_body(&mut reader, &header, &roles, vertex_count, body.len(), path)?
        }
    };
    if mesh.triangles.is_empty() {
        return Err(MeshIoError::NoFaces {
            path: path.to_path_buf(),
        });
    }
    Ok(mesh)
}

/// An error when `count` (vertices or triangles read so far, or announced) passes `limit`.
fn within(count: u64, limit: u64, what: &str, path: &Path) -> Result<()> {
    if count <= limit {
        return Ok(());
    }
    Err(MeshIoError::TooLarge {
        path: path.to_path_buf(),
        source: crate::limits::LimitError {
            what: format!("the {what} count (at least)"),
            value: count,
            limit,
            how: " per mesh file".into(),
        },
    })
}

/// Source of PLY body values, shared by the ASCII and binary encodings.
trait BodyReader<'a> {
    /// Begins instance `index` (0-based) of `count` instances of `element`.
    fn start(&mut self, element: &'a str, index: usize, count: usize) -> Result<()>;
    /// Reads a numeric value of type `ty` for property `property`.
    fn float(&mut self, ty: Scalar, property: &str) -> Result<f64>;
    /// Reads an integer value of type `ty` for property `property`.
    fn int(&mut self, ty: Scalar, property: &str) -> Result<i64>;
    /// Consumes a value of type `ty` without interpreting it.
    fn skip(&mut self, ty: Scalar, property: &str) -> Result<()>;
    /// Ends the current instance.
    fn finish(&mut self) -> Result<()>;
    /// Location and text of the most recently read value.
    fn last(&self) -> (Location, String);
}

/// Reads every element of the body, collecting positions and triangles.
fn read_ply_body<'a, R: BodyReader<'a>>(
    reader: &mut R,
    header: &'a PlyHeader,
    roles: &[Role],
    vertex_count: usize,
    body_len: usize,
    path: &Path,
) -> Result<MeshData> {
    within(
        vertex_count as u64,
        crate::limits::MAX_VERTICES,
        "vertex",
        path,
    )?;
    // at most one vertex per 3 bytes of body (three values of at least one byte)
    let mut mesh = MeshData {
        positions: Vec::with_capacity(vertex_count.min(body_len / 3)),
        triangles: Vec::new(),
    };
    let mut corners: Vec<u32> = Vec::new();
    for (element, role) in header.elements.iter().zip(roles.iter().copied()) {
        if element.properties.is_empty() {
            // Instances without properties occupy no data.
            continue;
        }
        for index in 0..element.count {
            reader.start(&element.name, index, element.count)?;
            let mut position = [0.0f64; 3];
            corners.clear();
            for (property_index, property) in element.properties.iter().enumerate() {
                match property.kind {
                    PropertyKind::Scalar(ty) => {
                        let axis = match role {
                            Role::Vertex(xyz) => xyz.iter().position(|&p| p == property_index),
                            _ => None,
                        };
                        match axis {
                            Some(axis) => {
                                let value = reader.float(ty, &property.name)?;
                                if !value.is_finite() {
                                    let (at, token) = reader.last();
                                    return Err(MeshIoError::NonFiniteCoordinate {
                                        path: path.to_path_buf(),
                                        at,
                                        token,
                                    });
                                }
                                if let Some(slot) = position.get_mut(axis) {
                                    *slot = value;
                                }
                            }
                            None => reader.skip(ty, &property.name)?,
                        }
                    }
                    PropertyKind::List { count, item } => {
                        let length = reader.int(count, &property.name)?;
                        let length = usize::try_from(length).map_err(|_| {
                            let (at, token) = reader.last();
                            MeshIoError::InvalidNumber {
                                path: path.to_path_buf(),
                                at,
                                token,
                                expected: format!(
                                    "a non-negative length for list {:?}",
                                    property.name
                                ),
                            }
                        })?;
                        let collect = matches!(role, Role::Face(list) if list == property_index);
                        if collect && length < 3 {
                            let (at, token) = reader.last();
                            return Err(MeshIoError::TooFewFaceVertices {
                                path: path.to_path_buf(),
                                at,
                                token,
                                count: length,
                            });
                        }
                        for _ in 0..length {
                            if collect {
                                let value = reader.int(item, &property.name)?;
                                corners.push(ply_vertex_index(value, vertex_count, reader, path)?);
                            } else {
                                reader.skip(item, &property.name)?;
                            }
                        }
                    }
                }
            }
            reader.finish()?;
            match role {
                Role::Vertex(_) => mesh.positions.push(position),
                Role::Face(_) => fan_triangulate(&corners, &mut mesh.triangles, path)?,
                Role::Skip => {}
            }
        }
    }
    Ok(mesh)
}

/// Validates a PLY vertex index against the declared vertex count.
fn ply_vertex_index<'a, R: BodyReader<'a>>(
    value: i64,
    vertex_count: usize,
    reader: &R,
    path: &Path,
) -> Result<u32> {
    match (u32::try_from(value), usize::try_from(value)) {
        (Ok(index), Ok(wide)) if wide < vertex_count => Ok(index),
        _ => {
            let (at, token) = reader.last();
            let allowed = match vertex_count.checked_sub(1) {
                None => "none, the header declares 0 vertices".to_owned(),
                Some(last) => format!("0..={last} (the header declares {vertex_count} vertices)"),
            };
            Err(MeshIoError::IndexOutOfRange {
                path: path.to_path_buf(),
                at,
                token,
                allowed,
            })
        }
    }
}

/// Reads an ASCII PLY body: one element instance per non-blank line.
struct AsciiReader<'a> {
    path: &'a Path,
    lines: std::str::Lines<'a>,
    /// 1-based number of the current line (header lines included).
    line: usize,
    tokens: std::str::SplitWhitespace<'a>,
    element: &'a str,
    index: usize,
    last: &'a str,
}

impl<'a> AsciiReader<'a> {
    fn new(body: &'a str, header_lines: usize, path: &'a Path) -> Self {
        AsciiReader {
            path,
            lines: body.lines(),
            line: header_lines,
            tokens: "".split_whitespace(),
            element: "",
            index: 0,
            last: "",
        }
    }

    /// Takes the next token of the current line.
    fn token(&mut self, ty: Scalar, property: &str) -> Result<&'a str> {
        let token = self
            .tokens
            .next()
            .ok_or_else(|| MeshIoError::MissingValue {
                path: self.path.to_path_buf(),
                at: Location::Line(self.line),
                expected: format!(
                    "a {} value for property {property:?} of {} {}",
                    ty.name(),
                    self.element,
                    self.index
                ),
            })?;
        self.last = token;
        Ok(token)
    }

    fn invalid(&self, token: &str, expected: String) -> MeshIoError {
        MeshIoError::InvalidNumber {
            path: self.path.to_path_buf(),
            at: Location::Line(self.line),
            token: token_text(token),
            expected,
        }
    }
}

impl<'a> BodyReader<'a> for AsciiReader<'a> {
    fn start(&mut self, element: &'a str, index: usize, count: usize) -> Result<()> {
        self.element = element;
        self.index = index;
        loop {
            let Some(text) = self.lines.next() else {
                return Err(MeshIoError::Truncated {
                    path: self.path.to_path_buf(),
                    at: Location::Line(self.line.saturating_add(1)),
                    expected: format!("a line for {element} {index} (the header declares {count})"),
                });
            };
            self.line = self.line.saturating_add(1);
            if !text.trim().is_empty() {
                self.tokens = text.split_whitespace();
                return Ok(());
            }
        }
    }

    fn float(&mut self, ty: Scalar, property: &str) -> Result<f64> {
        let token = self.token(ty, property)?;
        token.parse().map_err(|_| {
            self.invalid(
                token,
                format!("a number for property {property:?} ({})", ty.name()),
            )
        })
    }

    fn int(&mut self, ty: Scalar, property: &str) -> Result<i64> {
        let token = self.token(ty, property)?;
        token.parse().map_err(|_| {
            self.invalid(
                token,
                format!("an integer for property {property:?} ({})", ty.name()),
            )
        })
    }

    fn skip(&mut self, ty: Scalar, property: &str) -> Result<()> {
        self.token(ty, property).map(|_| ())
    }

    fn finish(&mut self) -> Result<()> {
        match self.tokens.next() {
            None => Ok(()),
            Some(extra) => Err(MeshIoError::UnexpectedToken {
                path: self.path.to_path_buf(),
                at: Location::Line(self.line),
                token: token_text(extra),
                expected: format!(
                    "end of line after the last property of {} {} (one element per line)",
                    self.element, self.index
                ),
            }),
        }
    }

    fn last(&self) -> (Location, String) {
        (Location::Line(self.line), token_text(self.last))
    }
}

/// Reads a binary PLY body of either byte order.
struct BinaryReader<'a> {
    path: &'a Path,
    /// The whole file, so offsets are file offsets.
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
    element: &'a str,
    index: usize,
    last_start: usize,
    last_value: f64,
}

impl BinaryReader<'_> {
    fn location(&self, offset: usize) -> Location {
        Location::Byte {
            offset,
            element: self.element.to_owned(),
            index: self.index,
        }
    }

    /// Reads and decodes one value, advancing past it.
    fn take(&mut self, ty: Scalar, property: &str) -> Result<f64> {
        let start = self.pos;
        let size = ty.size();
        let value = start
            .checked_add(size)
            .and_then(|end| self.bytes.get(start..end))
            .and_then(|chunk| ty.decode(chunk, self.big_endian));
        let Some(value) = value else {
            return Err(MeshIoError::Truncated {
                path: self.path.to_path_buf(),
                at: self.location(start),
                expected: format!(
                    "{size} bytes for property {property:?} ({}), but the file has {} bytes",
                    ty.name(),
                    self.bytes.len()
                ),
            });
        };
        self.pos = start.saturating_add(size);
        self.last_start = start;
        self.last_value = value;
        Ok(value)
    }
}

impl<'a> BodyReader<'a> for BinaryReader<'a> {
    fn start(&mut self, element: &'a str, index: usize, _count: usize) -> Result<()> {
        self.element = element;
        self.index = index;
        Ok(())
    }

    fn float(&mut self, ty: Scalar, property: &str) -> Result<f64> {
        self.take(ty, property)
    }

    fn int(&mut self, ty: Scalar, property: &str) -> Result<i64> {
        let value = self.take(ty, property)?;
        // Integer types decode exactly; the header only allows integer types
        // where integers are read, so this check is purely defensive.
        if value.fract() == 0.0 && value.abs() <= 9.0e15 {
            Ok(value as i64)
        } else {
            Err(MeshIoError::InvalidNumber {
                path: self.path.to_path_buf(),
                at: self.location(self.last_start),
                token: value.to_string(),
                expected: format!("an integer for property {property:?}"),
            })
        }
    }

    fn skip(&mut self, ty: Scalar, property: &str) -> Result<()> {
        self.take(ty, property).map(|_| ())
    }

    fn finish(&mut self) -> Result<()> {
        Ok(())
    }

    fn last(&self) -> (Location, String) {
        (self.location(self.last_start), self.last_value.to_string())
    }
}

/// A binary little-endian PLY file: float32 positions (scene units, rounded from f64; what
/// Mitsuba stores), int32 triangle indices.
pub fn ply_binary_f32(positions: &[crate::math::Vec3], triangles: &[[u32; 3]]) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        positions.len(),
        triangles.len()
    )
    .into_bytes();
    for p in positions {
        for c in [p.x, p.y, p.z] {
            b.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    for t in triangles {
        b.push(3);
        for &k in t {
            b.extend_from_slice(&(k as i32).to_le_bytes());
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(name: &str) -> PathBuf {
        PathBuf::from(name)
    }

    fn obj(text: &str) -> std::result::Result<MeshData, MeshIoError> {
        parse_obj(text, &p("test.obj"))
    }

    fn obj_err(text: &str) -> String {
        match obj(text) {
            Ok(mesh) => panic!("expected an error, got {mesh:?}"),
            Err(e) => e.to_string(),
        }
    }

    fn ply_err(bytes: &[u8]) -> String {
        match parse_ply(bytes, &p("test.ply")) {
            Ok(mesh) => panic!("expected an error, got {mesh:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_ply_announcing_more_vertices_than_the_limit_is_refused_before_storing_any() {
        // a lying header: 2^25 + 1 one-byte vertices announced over a body of 6 bytes
        let n = crate::limits::MAX_VERTICES + 1;
        let mut bytes = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty uchar x\n\
             property uchar y\nproperty uchar z\nelement face 1\n\
             property list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes();
        bytes.extend([0u8; 6]);
        let e = ply_err(&bytes);
        assert_contains(
            &e,
            &[
                "test.ply",
                "vertex count",
                "limit is 33554432 per mesh file",
            ],
        );
    }

    #[test]
    fn mesh_counts_past_their_limits_are_named_errors() {
        let path = p("m.obj");
        let e = within(
            crate::limits::MAX_VERTICES + 1,
            crate::limits::MAX_VERTICES,
            "vertex",
            &path,
        )
        .unwrap_err()
        .to_string();
        assert_contains(&e, &["m.obj", "the vertex count (at least) is 33554433"]);
        assert!(within(
            crate::limits::MAX_TRIANGLES,
            crate::limits::MAX_TRIANGLES,
            "triangle",
            &path
        )
        .is_ok());
    }

    fn assert_contains(message: &str, parts: &[&str]) {
        for part in parts {
            assert!(
                message.contains(part),
                "{message:?} should contain {part:?}"
            );
        }
    }

    const CUBE_OBJ: &str = "\
# unit cube
mtllib cube.mtl
o Cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vn 0 0 1
g faces
usemtl grey
s off
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
";

    #[test]
    fn cube_quads_are_fan_triangulated() {
        let mesh = obj(CUBE_OBJ).unwrap();
        assert_eq!(mesh.positions.len(), 8);
        assert_eq!(mesh.triangles.len(), 12);
        assert_eq!(mesh.positions[6], [1.0, 1.0, 1.0]);
        assert_eq!(mesh.triangles[0], [0, 3, 2]);
        assert_eq!(mesh.triangles[1], [0, 2, 1]);
        assert_eq!(mesh.triangles[11], [3, 4, 7]);
        for tri in &mesh.triangles {
            assert!(tri.iter().all(|&i| (i as usize) < mesh.positions.len()));
        }
    }

    #[test]
    fn obj_negative_indices_are_relative() {
        let mesh = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -1 -2\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 3, 2]]);
    }

    #[test]
    fn obj_corner_forms_and_skipped_statements() {
        let text = "\
v 0 0 0 1.0
v 1 0 0 0.5 0.2 0.3
v 1 1 0
v 0 1 0 # trailing comment
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1

f 1/1/1 2/2/1 3/3/1
f 1//1 3//1 4//1
f 1/1 2/2 3/3
f 1 2 3 4 # quad
curv 0 1 1 2
frobnicate something else
l 1 2
p 1
";
        let mesh = obj(text).unwrap();
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.positions[1], [1.0, 0.0, 0.0]);
        assert_eq!(
            mesh.triangles,
            vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 1, 2], [0, 2, 3]]
        );
    }

    #[test]
    fn obj_crlf_line_endings() {
        let mesh = obj("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn obj_index_zero_is_rejected() {
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
        assert_contains(&m, &["test.obj", "line 4", "\"0\"", "1..=3", "-3..=-1"]);
    }

    #[test]
    fn obj_index_out_of_range() {
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4/1/1\n");
        assert_contains(&m, &["line 4", "\"4/1/1\"", "1..=3"]);
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n");
        assert_contains(&m, &["line 4", "\"-4\"", "out of range"]);
        // Vertices defined after the face do not count.
        let m = obj_err("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
        assert_contains(&m, &["line 1", "\"1\"", "no vertices are defined"]);
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n");
        assert_contains(&m, &["line 4", "99999999999999999999", "invalid number"]);
    }

    #[test]
    fn obj_face_with_too_few_vertices() {
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n");
        assert_contains(&m, &["line 5", "\"f 1 2\"", "2 vertices", "at least 3"]);
        let m = obj_err("v 0 0 0\nf\n");
        assert_contains(&m, &["line 2", "0 vertices"]);
    }

    #[test]
    fn obj_non_numeric_coordinate() {
        let m = obj_err("v 0 0 0\nv 1 zero 0\n");
        assert_contains(&m, &["line 2", "\"zero\"", "y coordinate"]);
    }

    #[test]
    fn obj_missing_coordinate() {
        let m = obj_err("v 0 0\n");
        assert_contains(&m, &["line 1", "z coordinate"]);
    }

    #[test]
    fn obj_non_finite_coordinates() {
        for token in ["nan", "NaN", "inf", "-infinity", "1e999"] {
            let m = obj_err(&format!("v 0 0 0\nv 0 {token} 0\nv 1 1 1\nf 1 2 3\n"));
            assert_contains(
                &m,
                &["line 2", "non-finite coordinate", &format!("\"{token}\"")],
            );
        }
    }

    #[test]
    fn obj_malformed_corners() {
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2/1/1/1 3\n");
        assert_contains(&m, &["line 4", "\"2/1/1/1\"", "v/vt/vn"]);
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x/1\n");
        assert_contains(&m, &["line 4", "\"x/1\"", "integer vertex index"]);
        let m = obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 //1\n");
        assert_contains(&m, &["line 4", "\"//1\""]);
    }

    #[test]
    fn obj_without_faces() {
        let m = obj_err("# nothing\nv 0 0 0\n");
        assert_contains(&m, &["test.obj", "no faces"]);
        assert_contains(&obj_err(""), &["no faces"]);
    }

    #[test]
    fn long_tokens_are_shortened() {
        let long = "x".repeat(1000);
        let m = obj_err(&format!("v {long} 0 0\n"));
        assert!(m.len() < 300, "{m}");
        assert_contains(&m, &["line 1", "…"]);
    }

    const ASCII_PLY: &str = "\
ply
format ascii 1.0
comment made by hand
element vertex 4
property float x
property float y
property float z
property uchar red
element face 2
property list uchar int vertex_indices
end_header
0 0 0 255
1 0 0 0
1 1 0 0

0 1 0.5 7
4 0 1 2 3
3 3 2 1
";

    #[test]
    fn ascii_ply() {
        let mesh = parse_ply(ASCII_PLY.as_bytes(), &p("a.ply")).unwrap();
        assert_eq!(
            mesh.positions,
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.5]
            ]
        );
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
    }

    #[test]
    fn ascii_ply_errors() {
        let m = ply_err(ASCII_PLY.replace("3 3 2 1", "3 3 2 4").as_bytes());
        assert_contains(&m, &["line 18", "\"4\"", "0..=3"]);
        let m = ply_err(ASCII_PLY.replace("1 1 0 0", "1 one 0 0").as_bytes());
        assert_contains(&m, &["line 14", "\"one\"", "property \"y\""]);
        let m = ply_err(ASCII_PLY.replace("1 1 0 0", "1 1 nan 0").as_bytes());
        assert_contains(&m, &["line 14", "non-finite coordinate", "\"nan\""]);
        let m = ply_err(ASCII_PLY.replace("1 1 0 0", "1 1 0").as_bytes());
        assert_contains(&m, &["line 14", "property \"red\"", "vertex 2"]);
        let m = ply_err(ASCII_PLY.replace("1 1 0 0", "1 1 0 0 9").as_bytes());
        assert_contains(&m, &["line 14", "\"9\"", "end of line"]);
        let m = ply_err(ASCII_PLY.replace("3 3 2 1", "2 3 2").as_bytes());
        assert_contains(&m, &["line 18", "\"2\"", "at least 3"]);
        let m = ply_err(ASCII_PLY.replace("3 3 2 1\n", "").as_bytes());
        assert_contains(
            &m,
            &["line 18", "a line for face 1 (the header declares 2)"],
        );
        let m = ply_err(ASCII_PLY.replace("3 3 2 1", "-1 3 2 1").as_bytes());
        assert_contains(&m, &["line 18", "\"-1\"", "non-negative length"]);
    }

    #[test]
    fn ply_header_errors() {
        let m = ply_err(b"plx\nformat ascii 1.0\nend_header\n");
        assert_contains(&m, &["line 1", "\"plx\"", "\"ply\""]);
        let m = ply_err(b"");
        assert_contains(&m, &["line 1", "end of file"]);
        let m = ply_err(
            ASCII_PLY
                .replace("ascii 1.0", "binary_middle_endian 1.0")
                .as_bytes(),
        );
        assert_contains(
            &m,
            &[
                "line 2",
                "\"binary_middle_endian 1.0\"",
                "allowed: ascii 1.0",
            ],
        );
        let m = ply_err(ASCII_PLY.replace("ascii 1.0", "ascii 2.0").as_bytes());
        assert_contains(&m, &["line 2", "\"ascii 2.0\""]);
        let m = ply_err(
            ASCII_PLY
                .replace("property float z\n", "property float w\n")
                .as_bytes(),
        );
        assert_contains(&m, &["line 4", "\"vertex\"", "\"z\""]);
        let m = ply_err(
            ASCII_PLY
                .replace("property float y", "property quad y")
                .as_bytes(),
        );
        assert_contains(&m, &["line 6", "\"quad\"", "uchar"]);
        let m = ply_err(
            ASCII_PLY
                .replace("element face", "element faces")
                .as_bytes(),
        );
        assert_contains(&m, &["no \"face\" element"]);
        let m = ply_err(ASCII_PLY.replace("vertex_indices", "corners").as_bytes());
        assert_contains(&m, &["line 9", "\"vertex_indices\"", "vertex_index"]);
        let m = ply_err(
            ASCII_PLY
                .replace("element vertex 4", "element vertex four")
                .as_bytes(),
        );
        assert_contains(&m, &["line 4", "\"four\"", "element count"]);
        let m = ply_err(
            ASCII_PLY
                .replace("list uchar int", "list float int")
                .as_bytes(),
        );
        assert_contains(&m, &["line 10", "\"float\"", "integer list count"]);
        let m = ply_err(ASCII_PLY.replace("comment", "remark").as_bytes());
        assert_contains(&m, &["line 3", "\"remark\""]);
        let m = ply_err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
        assert_contains(&m, &["line 5", "end_header"]);
        let m = ply_err(b"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n");
        assert_contains(&m, &["no \"vertex\" element"]);
        let m = ply_err(
            ASCII_PLY
                .replace("element face 2", "element face 0")
                .replace("4 0 1 2 3\n3 3 2 1\n", "")
                .as_bytes(),
        );
        assert_contains(&m, &["no faces"]);
    }

    /// Appends a value in the chosen byte order.
    fn put(out: &mut Vec<u8>, le: &[u8], big_endian: bool) {
        if big_endian {
            out.extend(le.iter().rev());
        } else {
            out.extend_from_slice(le);
        }
    }

    /// A binary PLY with extra vertex properties, extra face properties and an
    /// extra `edge` element, in either byte order.
    fn binary_ply(big_endian: bool) -> Vec<u8> {
        let order = if big_endian {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut out = format!(
            "ply\r\nformat {order} 1.0\nelement vertex 4\nproperty float x\nproperty float32 y\nproperty double z\n\
             property float nx\nproperty uchar red\nproperty list uint8 int16 neighbours\n\
             element face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\n\
             element edge 1\nproperty int vertex1\nproperty int vertex2\nproperty short crease\n\
             element empty 1000000000\n\
             end_header\n"
        )
        .into_bytes();
        let verts = [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 2.5],
        ];
        for (i, v) in verts.iter().enumerate() {
            put(&mut out, &v[0].to_le_bytes(), big_endian);
            put(&mut out, &v[1].to_le_bytes(), big_endian);
            put(&mut out, &f64::from(v[2]).to_le_bytes(), big_endian);
            put(&mut out, &0.5f32.to_le_bytes(), big_endian);
            out.push(200);
            out.push(i as u8); // neighbour list length
            for n in 0..i {
                put(&mut out, &(n as i16).to_le_bytes(), big_endian);
            }
        }
        // Quad 0 1 2 3, then triangle 3 2 1.
        out.push(7);
        out.push(4);
        for i in [0i32, 1, 2, 3] {
            put(&mut out, &i.to_le_bytes(), big_endian);
        }
        out.push(2);
        put(&mut out, &0.25f32.to_le_bytes(), big_endian);
        put(&mut out, &0.75f32.to_le_bytes(), big_endian);
        out.push(0);
        out.push(3);
        for i in [3i32, 2, 1] {
            put(&mut out, &i.to_le_bytes(), big_endian);
        }
        out.push(0);
        // Edge.
        put(&mut out, &0i32.to_le_bytes(), big_endian);
        put(&mut out, &1i32.to_le_bytes(), big_endian);
        put(&mut out, &(-3i16).to_le_bytes(), big_endian);
        out
    }

    fn expected_binary_mesh() -> MeshData {
        MeshData {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 2.5],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]],
        }
    }

    /// Byte offset of the first body byte of `binary_ply`.
    fn body_start(bytes: &[u8]) -> usize {
        let marker = b"end_header\n";
        bytes
            .windows(marker.len())
            .position(|w| w == marker)
            .unwrap()
            + marker.len()
    }

    #[test]
    fn binary_little_endian_ply_skips_extra_properties() {
        let bytes = binary_ply(false);
        assert_eq!(
            parse_ply(&bytes, &p("b.ply")).unwrap(),
            expected_binary_mesh()
        );
    }

    #[test]
    fn binary_big_endian_ply() {
        let bytes = binary_ply(true);
        assert_eq!(
            parse_ply(&bytes, &p("b.ply")).unwrap(),
            expected_binary_mesh()
        );
    }

    #[test]
    fn binary_ply_trailing_bytes_are_ignored() {
        let mut bytes = binary_ply(false);
        bytes.extend_from_slice(b"\0\0\0junk");
        assert_eq!(
            parse_ply(&bytes, &p("b.ply")).unwrap(),
            expected_binary_mesh()
        );
    }

    #[test]
    fn truncated_binary_ply() {
        let bytes = binary_ply(false);
        let start = body_start(&bytes);
        // Cut in the middle of vertex 1's y coordinate: vertex 0 is 4+4+8+4+1+1 = 22 bytes.
        let cut = start + 22 + 4 + 2;
        let m = ply_err(&bytes[..cut]);
        let offset = format!("byte {}", start + 26);
        assert_contains(
            &m,
            &[
                &offset,
                "(vertex 1)",
                "property \"y\"",
                "data ends too early",
            ],
        );
        // Cutting the last byte of the edge element is also reported.
        let m = ply_err(&bytes[..bytes.len() - 1]);
        assert_contains(&m, &["(edge 0)", "\"crease\""]);
    }

    #[test]
    fn binary_ply_index_out_of_range() {
        let mut bytes = binary_ply(false);
        let start = body_start(&bytes);
        // Vertex block: sizes 22, 24, 26, 28 bytes; face 0 is flags, count, then indices.
        let first_index = start + 22 + 24 + 26 + 28 + 2;
        bytes[first_index..first_index + 4].copy_from_slice(&4i32.to_le_bytes());
        let m = ply_err(&bytes);
        let offset = format!("byte {first_index}");
        assert_contains(&m, &[&offset, "(face 0)", "\"4\"", "0..=3"]);
        bytes[first_index..first_index + 4].copy_from_slice(&(-1i32).to_le_bytes());
        let m = ply_err(&bytes);
        assert_contains(&m, &[&offset, "\"-1\"", "out of range"]);
    }

    #[test]
    fn binary_ply_non_finite_coordinate() {
        let mut bytes = binary_ply(false);
        let start = body_start(&bytes);
        let z = start + 22 + 8;
        bytes[z..z + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let m = ply_err(&bytes);
        let offset = format!("byte {z}");
        assert_contains(
            &m,
            &[&offset, "(vertex 1)", "non-finite coordinate", "\"NaN\""],
        );
        bytes[z..z + 8].copy_from_slice(&f64::NEG_INFINITY.to_le_bytes());
        assert_contains(&ply_err(&bytes), &[&offset, "\"-inf\""]);
    }

    #[test]
    fn binary_ply_small_face() {
        let mut bytes = binary_ply(false);
        let start = body_start(&bytes);
        let count = start + 22 + 24 + 26 + 28 + 1;
        bytes[count] = 2;
        let m = ply_err(&bytes);
        let offset = format!("byte {count}");
        assert_contains(&m, &[&offset, "(face 0)", "\"2\"", "at least 3"]);
    }

    #[test]
    fn every_prefix_is_handled_without_panic() {
        let bytes = binary_ply(false);
        for len in 0..=bytes.len() {
            let result = parse_ply(&bytes[..len], &p("prefix.ply"));
            if len < bytes.len() {
                assert!(result.is_err(), "prefix of {len} bytes parsed");
            }
        }
        let ascii = ASCII_PLY.as_bytes();
        for len in 0..=ascii.len() {
            let _ = parse_ply(&ascii[..len], &p("prefix.ply"));
        }
        for len in 0..=CUBE_OBJ.len() {
            let _ = parse_obj(&CUBE_OBJ[..len], &p("prefix.obj"));
        }
    }

    #[test]
    fn byte_mutations_are_handled_without_panic() {
        let original = binary_ply(false);
        for i in 0..original.len() {
            for value in [0x00, 0x01, 0x7f, 0x80, 0xff, b'\n', b' '] {
                let mut bytes = original.clone();
                bytes[i] = value;
                let _ = parse_ply(&bytes, &p("mutant.ply"));
            }
        }
        let ascii = ASCII_PLY.as_bytes();
        for i in 0..ascii.len() {
            for value in [b'0', b'9', b'-', b' ', b'\n', b'x', 0xff] {
                let mut bytes = ascii.to_vec();
                bytes[i] = value;
                let _ = parse_ply(&bytes, &p("mutant.ply"));
                let _ = parse_obj(&String::from_utf8_lossy(&bytes), &p("mutant.obj"));
            }
        }
    }

    /// A fresh path in the system temp directory.
    fn temp_path(name: &str) -> PathBuf {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        std::env::temp_dir().join(format!(
            "furnace-meshio-{}-{nanos}-{name}",
            std::process::id()
        ))
    }

    #[test]
    fn load_mesh_from_files() {
        let obj_path = temp_path("cube.OBJ");
        std::fs::write(&obj_path, CUBE_OBJ).unwrap();
        let result = load_mesh(&obj_path);
        std::fs::remove_file(&obj_path).unwrap();
        assert_eq!(result.unwrap().triangles.len(), 12);

        let ply_path = temp_path("mesh.ply");
        std::fs::write(&ply_path, binary_ply(false)).unwrap();
        let result = load_mesh(&ply_path);
        std::fs::remove_file(&ply_path).unwrap();
        assert_eq!(result.unwrap(), expected_binary_mesh());
    }

    #[test]
    fn load_mesh_missing_file() {
        let path = temp_path("missing.obj");
        let err = load_mesh(&path).unwrap_err();
        assert!(matches!(err, MeshIoError::Io { .. }), "{err:?}");
        assert_contains(
            &err.to_string(),
            &[&path.display().to_string(), "cannot read"],
        );
        assert!(std::error::Error::source(&err).is_some());
    }

    #[test]
    fn load_mesh_unsupported_extension() {
        let m = load_mesh(Path::new("scene/teapot.stl"))
            .unwrap_err()
            .to_string();
        assert_contains(&m, &["scene/teapot.stl", "\"stl\"", ".obj, .ply"]);
        let m = load_mesh(Path::new("scene/teapot"))
            .unwrap_err()
            .to_string();
        assert_contains(&m, &["(none)", ".obj, .ply"]);
    }
}
