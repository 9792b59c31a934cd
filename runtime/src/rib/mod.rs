//! The RIB reader: ASCII RenderMan Interface Bytestream files parsed into typed [`Request`]s, and
//! the conversion of their geometry into [`Mesh`](crate::geometry::Mesh)es ([`mesh`]).
//!
//! The reader parses; it builds no scene. An engine walks the requests in order, keeping the
//! graphics state (attribute and transform stacks, current shaders) itself.
//!
//! Invariants:
//! - parsing never fails and never panics: [`parse_str`] returns every request it could read and
//!   a diagnostic for everything it could not. A syntax error drops the request it is in, and
//!   reading resumes at the next request name, so one run reports every error;
//! - unknown requests and parameters of unknown type are warnings, and are skipped;
//! - `ReadArchive` is expanded in place, so the request list never contains it: an inline archive
//!   (`ArchiveBegin`/`ArchiveEnd`, whose requests are kept by name rather than listed where they
//!   stand) or a file, a relative path looked up along the `archive` search path, in the current
//!   directory, then beside the including file; cycles and nesting deeper than
//!   [`MAX_ARCHIVE_DEPTH`] are errors, and inline-archive copies are bounded by
//!   [`INLINE_ARCHIVE_BUDGET`];
//! - a stream is ASCII or binary RIB (RISpec 3.2 appendix C, the two may mix) and may be
//!   gzip-compressed, told apart by content, never by file name;
//! - `Declare` is global, as in RenderMan: a declaration holds for the rest of the stream, archives
//!   included;
//! - every parameter's value count is checked against its declaration (see [`request`]);
//! - conditional RIB (`IfBegin`, `ElseIf`, `Else`, `IfEnd`) is evaluated as the stream is read
//!   ([`cond`]): the requests of branches not taken are never read further (their archives are not
//!   opened, their declarations not made), so the request list holds none of them, nor the
//!   conditionals, except inside an inline archive, whose conditions are evaluated where it is read.

pub mod blobby;
pub mod cond;
pub mod curves;
pub mod decl;
pub mod lex;
pub mod load;
pub mod mesh;
pub mod nurbs;
mod parse;
pub mod patch;
pub mod points;
mod primitive;
pub mod report;
pub mod request;
pub mod spline;
pub mod subdiv;
pub mod teapot;
pub mod trim;
pub mod view;

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use decl::{Class, Decl, DeclTable, Ty};
pub use mesh::MeshOptions;
pub use parse::{INLINE_ARCHIVE_BUDGET, MAX_INFLATED_RIB};
pub use patch::DEFAULT_PATCH_SEGMENTS;
pub use primitive::{mesh_from_request, mesh_from_request_with, request_triangles};
pub use request::{
    find_param, Basis, CurveType, Handle, Location, NuDirection, Orientation, Param, ParamValue, PatchType, Request,
    RequestKind, Shader, TrimCurve, Wrap,
};

/// How deeply `ReadArchive` may nest.
pub const MAX_ARCHIVE_DEPTH: usize = 32;

/// How deep `AttributeBegin` and `TransformBegin` blocks may nest (together): each open block
/// holds a copy of the state it restores, so a stream of nothing but `AttributeBegin` would
/// otherwise take memory in proportion to its length, many times over. A block opened past it is
/// an omission: its requests apply to the block around it, and its end restores nothing.
pub const MAX_BLOCK_DEPTH: usize = 1 << 16;

/// The most triangles the geometry requests of one RIB load may make, quadrics, patches, NURBS
/// patches, subdivision meshes, the teapot, points, curves and blobbies counted as tessellated: a line of
/// text can ask for thousands, and memory runs out long before a file does (`docs/rendering.md`,
/// "Limits"). Meshes read from OBJ, PLY or glTF files are not counted. Those requests are counted
/// before they are tessellated ([`request_triangles`]); a `Blobby`, whose size only sampling its
/// field tells, once built (its own grid bounds it: [`blobby::MAX_BLOBBY_CELLS`]).
pub const MAX_RIB_TRIANGLES: usize = 1 << 24;

/// An error at a place in a RIB file.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{loc}: {message}")]
pub struct RibError {
    /// Where.
    pub loc: Location,
    /// What went wrong.
    pub message: String,
}

/// How bad a diagnostic is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// Something was ignored or approximated, but the file is otherwise fine.
    Warning,
    /// A request was skipped: what it asks for is missing from the picture (an unknown or
    /// unsupported request). Shown as a warning; `rtsl render` fails on it unless lenient.
    Omission,
    /// Part of the file could not be read.
    Error,
}

/// A message about a RIB file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RibDiagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// Where.
    pub loc: Location,
    /// What.
    pub message: String,
}

impl RibDiagnostic {
    /// An error at `loc`.
    pub fn error(loc: &Location, message: impl Into<String>) -> Self {
        RibDiagnostic { severity: Severity::Error, loc: loc.clone(), message: message.into() }
    }

    /// A warning at `loc`.
    pub fn warning(loc: &Location, message: impl Into<String>) -> Self {
        RibDiagnostic { severity: Severity::Warning, loc: loc.clone(), message: message.into() }
    }

    /// A skipped request at `loc`.
    pub fn omission(loc: &Location, message: impl Into<String>) -> Self {
        RibDiagnostic { severity: Severity::Omission, loc: loc.clone(), message: message.into() }
    }
}

impl fmt::Display for RibDiagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let level = match self.severity {
            Severity::Warning | Severity::Omission => "warning",
            Severity::Error => "error",
        };
        write!(f, "{}: {level}: {}", self.loc, self.message)
    }
}

/// What reading a RIB stream produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RibParse {
    /// The requests, in order, archives expanded.
    pub requests: Vec<Request>,
    /// Errors and warnings, in the order they were found.
    pub diagnostics: Vec<RibDiagnostic>,
    /// The RIB archives read (`ReadArchive` of RIB files, expanded in `requests`), canonical paths
    /// in the order read.
    pub archives: Vec<PathBuf>,
}

impl RibParse {
    /// Whether any diagnostic is an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(|d| d.severity == Severity::Error)
    }

    /// The errors only.
    pub fn errors(&self) -> impl Iterator<Item = &RibDiagnostic> {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Error)
    }
}

/// Parses RIB text. `file_name` names it in locations, and its directory is where relative
/// `ReadArchive` paths are looked up.
pub fn parse_str(text: &str, file_name: impl AsRef<Path>) -> RibParse {
    parse_bytes(text.as_bytes(), file_name.as_ref())
}

/// Parses RIB bytes (non-ASCII bytes outside strings are errors; strings are read as UTF-8,
/// invalid sequences replaced).
pub fn parse_bytes(bytes: &[u8], file_name: &Path) -> RibParse {
    read_stream(parse::Parser::new(), bytes, file_name)
}

/// Where a streamed read ([`parse_bytes_into`], [`parse_file_into`]) puts what it reads, in
/// stream order. Any `FnMut(Request)` is one that takes every request and no diagnostics.
pub trait RibSink {
    /// The next request; `Break` stops the reading (nothing more is read or reported).
    fn request(&mut self, request: Request) -> std::ops::ControlFlow<()>;
    /// Whether diagnostics go to [`RibSink::diagnostic`] as they arise rather than into the
    /// result: a diagnostic then comes before the requests read after it.
    fn takes_diagnostics(&self) -> bool {
        false
    }
    /// A diagnostic, when the sink takes them.
    fn diagnostic(&mut self, _diagnostic: RibDiagnostic) {}
    /// A RIB archive file about to be read (its canonical path).
    fn archive(&mut self, _path: &Path) {}
}

impl<F: FnMut(Request)> RibSink for F {
    fn request(&mut self, request: Request) -> std::ops::ControlFlow<()> {
        self(request);
        std::ops::ControlFlow::Continue(())
    }
}

/// [`parse_bytes`] handing each request to `sink` as it is read, in stream order, rather than
/// keeping them: a stream is then read in memory proportional to its largest request (and its
/// inline archives), not to its length. The result holds the diagnostics (those the sink does
/// not take) and the archives read, no requests.
pub fn parse_bytes_into(bytes: &[u8], file_name: &Path, sink: &mut dyn RibSink) -> RibParse {
    read_stream(parse::Parser::with_sink(sink), bytes, file_name)
}

fn read_stream(mut parser: parse::Parser, bytes: &[u8], file_name: &Path) -> RibParse {
    let file: Arc<Path> = Arc::from(file_name);
    parser.include_stack.extend(std::fs::canonicalize(file_name).ok());
    parser.parse_file_text(bytes, file);
    parser.finish()
}

/// Reads and parses a RIB file. Only failing to read `path` itself is an `Err`; everything else,
/// archives that cannot be read included, is a diagnostic.
pub fn parse_file(path: impl AsRef<Path>) -> Result<RibParse, RibError> {
    let path = path.as_ref();
    Ok(parse_bytes(&read_file(path)?, path))
}

/// [`parse_file`] handing each request to `sink` as it is read ([`parse_bytes_into`]).
pub fn parse_file_into(path: impl AsRef<Path>, sink: &mut dyn RibSink) -> Result<RibParse, RibError> {
    let path = path.as_ref();
    Ok(parse_bytes_into(&read_file(path)?, path, sink))
}

fn read_file(path: &Path) -> Result<Vec<u8>, RibError> {
    std::fs::read(path).map_err(|e| RibError {
        loc: Location { file: Arc::from(path), line: 0, column: 0 },
        message: format!("cannot read RIB file: {e}"),
    })
}

/// The directory relative `ReadArchive` paths in `file` are resolved against.
fn base_dir(file: &Path) -> PathBuf {
    file.parent().map(Path::to_path_buf).unwrap_or_default()
}
