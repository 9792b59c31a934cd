//! Compiled shader artifacts (`NAME.rtso`): one shader's checked IR, with the sources it came from,
//! so that loading it skips the front end.
//!
//! ## File layout (all integers little-endian)
//! ```text
//! offset  size  field
//!      0     8  magic "RTSLOBJ\n"
//!      8     4  format version (FORMAT_VERSION)
//!     12    32  compiler fingerprint: blake3 of the format version and the compiler's tables
//!               (built-in signatures and shader globals), which the IR indexes into
//!     44     4  length n of the main source path (UTF-8; 0 when the shader had no file)
//!     48     n  the main source path
//!   48+n     8  payload length m
//!   56+n    32  checksum: blake3 of every byte before it and of the payload
//!   88+n     m  payload: postcard encoding of the compiler version, the preprocessor options, every
//!               source file (name, path, content hash, text) and the IR module
//! ```
//! The fields up to the source path stay the same in every format version, so an artifact written by
//! another version can still name its source, and be recompiled from it.
//!
//! ## What loading guarantees
//! - A file that is not an artifact, is truncated, or whose payload does not match its checksum is
//!   an [`ArtifactError`], never a crash and never a wrong shader.
//! - Decoded IR is validated like freshly compiled IR (handles, types, spans, budgets), so back ends
//!   may rely on it. The checksum detects damage, not tampering: artifacts are not signed.
//! - IR whose blocks nest deeper than `ir::MAX_DECODED_NESTING` is refused while it is decoded, on a
//!   thread whose stack holds the decoder and the validator at that depth: a forged artifact cannot
//!   overflow the stack of the thread that loads it.
//! - [`load`] compares the content hash of every file the shader read with the file on disk now. An
//!   artifact whose sources changed, or that another compiler version wrote, is recompiled from source
//!   when the source is at hand, and refused with an error naming the file when it is not.

use crate::compile::{Compilation, Options, Session};
use crate::front::preprocess;
use crate::interface::ShaderInterface;
use crate::ir::{Block, Module, StmtKind};
use crate::source::{SourceMap, Span};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The file extension of artifacts.
pub const EXTENSION: &str = "rtso";
/// Bumped whenever the payload's encoding or the IR's shape changes.
pub const FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"RTSLOBJ\n";
const FIXED_HEADER: usize = 8 + 4 + 32 + 4;

/// Why an artifact could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ArtifactError {
    #[error("cannot read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path} is not an rtsl compiled shader (bad magic number)")]
    NotAnArtifact { path: PathBuf },
    #[error("{path} is truncated ({len} bytes; the header promises more); compile the shader again")]
    Truncated { path: PathBuf, len: usize },
    #[error("{path} is corrupted (its checksum does not match its contents); compile the shader again")]
    Corrupt { path: PathBuf },
    #[error("{path} cannot be decoded ({detail}); compile the shader again")]
    Undecodable { path: PathBuf, detail: String },
    #[error("{path} holds invalid IR ({detail}); compile the shader again")]
    Invalid { path: PathBuf, detail: String },
    #[error(
        "{path} was written by another version of the compiler (format {found}, this compiler reads {expected} with \
         other built-in tables) and its source {} is not at hand to recompile it",
        source_file.as_ref().map(|s| s.display().to_string()).unwrap_or_else(|| "(none recorded)".into())
    )]
    Outdated { path: PathBuf, found: u32, expected: u32, source_file: Option<PathBuf> },
    #[error(
        "{path} is out of date ({changed} changed since it was compiled) and its source {source_file} is not at hand"
    )]
    StaleWithoutSource { path: PathBuf, changed: String, source_file: String },
}

/// The preprocessor settings the shader was compiled with (recompiling uses them again).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StoredOptions {
    pub include_paths: Vec<PathBuf>,
    pub defines: Vec<(String, Option<String>)>,
    pub undefines: Vec<String>,
}

impl StoredOptions {
    fn from_options(o: &Options) -> StoredOptions {
        StoredOptions {
            include_paths: o.preprocessor.include_paths.clone(),
            defines: o.preprocessor.defines.clone(),
            undefines: o.preprocessor.undefines.clone(),
        }
    }

    pub fn to_options(&self) -> Options {
        Options {
            preprocessor: preprocess::Options {
                include_paths: self.include_paths.clone(),
                defines: self.defines.clone(),
                undefines: self.undefines.clone(),
            },
        }
    }
}

/// One file a shader was compiled from.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StoredFile {
    /// As diagnostics name it.
    pub name: String,
    /// Where it was read from (`None` for in-memory text such as `-D` definitions).
    pub path: Option<PathBuf>,
    /// blake3 of the text, in hex.
    pub hash: String,
    pub text: String,
}

/// What the payload holds; [`PayloadRef`] writes the same encoding without copying the IR.
#[derive(Deserialize)]
struct Payload {
    compiler_version: String,
    options: StoredOptions,
    /// Every file of the compilation's source map, in `FileId` order (spans index into it).
    files: Vec<StoredFile>,
    /// The front end's warnings, rendered.
    warnings: String,
    module: Module,
}

#[derive(Serialize)]
struct PayloadRef<'a> {
    compiler_version: &'a str,
    options: StoredOptions,
    files: Vec<StoredFile>,
    warnings: String,
    module: &'a Module,
}

/// A decoded, validated artifact.
#[derive(Debug)]
pub struct Artifact {
    /// The version of rtsl that wrote it.
    pub compiler_version: String,
    /// The main source file, when the shader came from one.
    pub source: Option<PathBuf>,
    pub options: StoredOptions,
    pub files: Vec<StoredFile>,
    pub warnings: String,
    pub module: Module,
    /// The stored sources, for diagnostics and runtime error messages.
    pub sources: SourceMap,
    pub interface: ShaderInterface,
}

/// The hash recorded for a file's text.
pub fn content_hash(text: &str) -> String {
    blake3::hash(text.as_bytes()).to_hex().to_string()
}

/// Paths are recorded absolute, so an artifact can be checked against its sources from any directory.
fn absolute(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).or_else(|_| std::path::absolute(p)).unwrap_or_else(|_| p.to_path_buf())
}

/// Identifies the tables the IR indexes into (built-in overloads, globals) and the format version:
/// an artifact is readable only by a compiler with the same fingerprint.
pub fn fingerprint() -> [u8; 32] {
    static FINGERPRINT: std::sync::OnceLock<[u8; 32]> = std::sync::OnceLock::new();
    *FINGERPRINT.get_or_init(|| {
        let mut h = blake3::Hasher::new();
        h.update(&FORMAT_VERSION.to_le_bytes());
        for b in crate::builtins::Builtin::ALL {
            h.update(format!("{}{:?};", b.name(), crate::builtins::signatures(*b)).as_bytes());
        }
        for g in crate::globals::GLOBALS {
            h.update(format!("{}{:?}{}{:?};", g.name, g.ty, g.varying, g.access).as_bytes());
        }
        h.update(format!("{:?}", crate::globals::UNIFORM_IN_CAMERA).as_bytes());
        *h.finalize().as_bytes()
    })
}

/// Encodes the shader of a successful compilation; `None` when it failed or defines no shader.
pub fn encode(c: &Compilation, options: &Options) -> Option<Vec<u8>> {
    if !c.ok() {
        return None;
    }
    let module = c.module.as_ref()?;
    let warnings = if c.warnings() > 0 { c.render() } else { String::new() };
    let source = c.files.first().and_then(|f| c.sources.get(*f).path.as_deref());
    encode_module(module, &c.sources, warnings, options, source)
}

/// Encodes a checked module with the sources it was compiled from (`source`: its main file), the
/// front end's rendered `warnings` and the `options` it was compiled with; `None` when the module
/// defines no shader. [`encode`] of a compilation's parts.
pub fn encode_module(
    module: &Module,
    sources: &SourceMap,
    warnings: String,
    options: &Options,
    source: Option<&Path>,
) -> Option<Vec<u8>> {
    module.shader.as_ref()?;
    let files = sources
        .files()
        .map(|(_, f)| StoredFile {
            name: f.name.clone(),
            path: f.path.as_deref().map(absolute),
            hash: content_hash(&f.text),
            text: f.text.to_string(),
        })
        .collect();
    let payload = PayloadRef {
        compiler_version: env!("CARGO_PKG_VERSION"),
        options: StoredOptions::from_options(options),
        files,
        warnings,
        module,
    };
    let body = postcard::to_stdvec(&payload).ok()?;
    let source = source.map(absolute).map(|p| p.display().to_string()).unwrap_or_default();
    let mut out = Vec::with_capacity(FIXED_HEADER + source.len() + 40 + body.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&fingerprint());
    out.extend_from_slice(&(source.len() as u32).to_le_bytes());
    out.extend_from_slice(source.as_bytes());
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    let checksum = checksum(&out, &body);
    out.extend_from_slice(&checksum);
    out.extend_from_slice(&body);
    Some(out)
}

/// Writes `bytes` to `path` through a temporary file and a rename, so that a reader (a watcher, a
/// renderer loading the library) never sees half a file.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(".tmp{}", std::process::id()));
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

/// The checksum covers everything but itself: the header before it and the payload after it.
fn checksum(header: &[u8], body: &[u8]) -> [u8; 32] {
    let mut h = blake3::Hasher::new();
    h.update(header);
    h.update(body);
    *h.finalize().as_bytes()
}

/// The header fields every format version shares.
struct Header {
    version: u32,
    fingerprint: [u8; 32],
    source: Option<PathBuf>,
    /// Offset of the payload length.
    rest: usize,
}

fn read_header(path: &Path, bytes: &[u8]) -> Result<Header, ArtifactError> {
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(ArtifactError::NotAnArtifact { path: path.to_path_buf() });
    }
    let truncated = || ArtifactError::Truncated { path: path.to_path_buf(), len: bytes.len() };
    let fixed = bytes.get(..FIXED_HEADER).ok_or_else(truncated)?;
    let version = u32::from_le_bytes(fixed[8..12].try_into().map_err(|_| truncated())?);
    let fingerprint: [u8; 32] = fixed[12..44].try_into().map_err(|_| truncated())?;
    let source_len = u32::from_le_bytes(fixed[44..48].try_into().map_err(|_| truncated())?) as usize;
    let source_bytes = bytes.get(FIXED_HEADER..FIXED_HEADER.saturating_add(source_len)).ok_or_else(truncated)?;
    let source = match std::str::from_utf8(source_bytes) {
        Ok("") => None,
        Ok(s) => Some(PathBuf::from(s)),
        Err(_) => return Err(ArtifactError::Corrupt { path: path.to_path_buf() }),
    };
    Ok(Header { version, fingerprint, source, rest: FIXED_HEADER + source_len })
}

/// `bytes` with its header's version and fingerprint made this compiler's, its payload length
/// made the length of what follows the checksum, and the checksum recomputed: what a forger (or a
/// fuzzer) changing the payload would write. `None` when the header itself is unreadable. Loading
/// such bytes must still never crash: the payload is validated, not trusted.
pub fn reframe(bytes: &[u8]) -> Option<Vec<u8>> {
    let header = read_header(Path::new(""), bytes).ok()?;
    let at = header.rest;
    let body = bytes.get(at + 40..)?;
    let mut out = bytes.get(..at)?.to_vec();
    out[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    out[12..44].copy_from_slice(&fingerprint());
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    let sum = checksum(&out, body);
    out.extend_from_slice(&sum);
    out.extend_from_slice(body);
    Some(out)
}

/// Decodes and validates an artifact's bytes (no look at the files on disk). `path` names it in errors.
pub fn decode(path: &Path, bytes: &[u8]) -> Result<Artifact, ArtifactError> {
    let header = read_header(path, bytes)?;
    if header.version != FORMAT_VERSION || header.fingerprint != fingerprint() {
        return Err(ArtifactError::Outdated {
            path: path.to_path_buf(),
            found: header.version,
            expected: FORMAT_VERSION,
            source_file: header.source,
        });
    }
    let truncated = || ArtifactError::Truncated { path: path.to_path_buf(), len: bytes.len() };
    let at = header.rest;
    let len_bytes = bytes.get(at..at + 8).ok_or_else(truncated)?;
    let len = u64::from_le_bytes(len_bytes.try_into().map_err(|_| truncated())?);
    let checksum_stored = bytes.get(at + 8..at + 40).ok_or_else(truncated)?;
    let body_start = at + 40;
    let body_end = usize::try_from(len).ok().and_then(|l| body_start.checked_add(l)).ok_or_else(truncated)?;
    let body = bytes.get(body_start..body_end).ok_or_else(truncated)?;
    if body_end != bytes.len() || checksum(&bytes[..at + 8], body) != checksum_stored {
        return Err(ArtifactError::Corrupt { path: path.to_path_buf() });
    }
    let (payload, sources, interface) = on_decoding_stack(|| decode_payload(path, body))?;
    Ok(Artifact {
        compiler_version: payload.compiler_version,
        source: header.source,
        options: payload.options,
        files: payload.files,
        warnings: payload.warnings,
        module: payload.module,
        sources,
        interface,
    })
}

/// The stack an artifact is decoded and validated on: both recurse over blocks, as deep as
/// `ir::MAX_DECODED_NESTING`, and an unoptimised build takes some kilobytes a level. Its own thread,
/// so that any thread may load an artifact; the memory is reserved, and used only as deep as the IR
/// goes.
const DECODING_STACK: usize = 64 << 20;

/// Runs `f` on a thread with [`DECODING_STACK`] (on this one when no thread can be started).
fn on_decoding_stack<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    let slot = std::sync::Mutex::new(Some(f));
    let take = || slot.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take();
    let ran = std::thread::scope(|scope| {
        let thread = std::thread::Builder::new().stack_size(DECODING_STACK).spawn_scoped(scope, || take().map(|f| f()));
        match thread.map(|t| t.join()) {
            Ok(Ok(out)) => out,
            Ok(Err(panic)) => std::panic::resume_unwind(panic),
            Err(_) => None,
        }
    });
    match ran {
        Some(out) => out,
        None => match take() {
            Some(f) => f(),
            None => unreachable!("`f` ran on the thread, which returned its result"),
        },
    }
}

/// Decodes an artifact's payload and checks its IR (see [`decode`]).
fn decode_payload(path: &Path, body: &[u8]) -> Result<(Payload, SourceMap, ShaderInterface), ArtifactError> {
    let (payload, too_deep) = crate::ir::decode_nested(|| postcard::from_bytes::<Payload>(body));
    let payload = payload.map_err(|e| ArtifactError::Undecodable {
        path: path.to_path_buf(),
        detail: if too_deep {
            format!("its statements nest more than {} levels deep", crate::ir::MAX_DECODED_NESTING)
        } else {
            e.to_string()
        },
    })?;
    let mut sources = SourceMap::new();
    for f in &payload.files {
        sources.add(f.name.clone(), f.path.clone(), f.text.as_str());
    }
    let invalid = |detail: String| ArtifactError::Invalid { path: path.to_path_buf(), detail };
    check_module(&payload.module, &sources).map_err(invalid)?;
    let interface =
        ShaderInterface::from_module(&payload.module, &sources).ok_or_else(|| invalid("it holds no shader".into()))?;
    Ok((payload, sources, interface))
}

/// What decoded IR must satisfy beyond the validator's rules: a shader whose handles are in range,
/// and spans inside the stored sources (diagnostics and runtime errors index the text with them).
fn check_module(m: &Module, sources: &SourceMap) -> Result<(), String> {
    crate::valid::validate(m).map_err(|problems| problems.into_iter().take(3).collect::<Vec<_>>().join("; "))?;
    let shader = m.shader.as_ref().ok_or("no shader")?;
    let body = m.functions.get(shader.body.0 as usize).ok_or("the shader's body is not a function")?;
    for p in &shader.params {
        if p.var.0 as usize >= body.vars.len() || p.default.0 as usize >= body.exprs.len() {
            return Err(format!("parameter {} refers outside its function", p.name));
        }
    }
    let n = sources.files().count();
    let span_ok = |s: Span| {
        (s.file.0 as usize) < n && s.start <= s.end && {
            let text = &sources.get(s.file).text;
            text.is_char_boundary(s.start as usize) && text.is_char_boundary(s.end as usize)
        }
    };
    fn block_spans(b: &Block, ok: &dyn Fn(Span) -> bool) -> bool {
        b.stmts.iter().all(|s| {
            ok(s.span)
                && match &s.kind {
                    StmtKind::If { then, otherwise, .. } => block_spans(then, ok) && block_spans(otherwise, ok),
                    StmtKind::Loop { body, step, .. } => block_spans(body, ok) && block_spans(step, ok),
                    StmtKind::Gather { body, otherwise, .. } => block_spans(body, ok) && block_spans(otherwise, ok),
                    StmtKind::Illuminance { body, .. }
                    | StmtKind::Illuminate { body, .. }
                    | StmtKind::Solar { body, .. } => block_spans(body, ok),
                    StmtKind::Expr(_) | StmtKind::Break(_) | StmtKind::Continue(_) | StmtKind::Return(_) => true,
                }
        })
    }
    let all_ok = span_ok(shader.span)
        && shader.params.iter().all(|p| span_ok(p.span))
        && m.functions.iter().all(|f| {
            span_ok(f.span)
                && f.vars.iter().all(|v| span_ok(v.span))
                && f.exprs.iter().all(|e| span_ok(e.span))
                && block_spans(&f.body, &span_ok)
        });
    if all_ok {
        Ok(())
    } else {
        Err("a source position lies outside the stored sources".into())
    }
}

/// Reads and decodes an artifact file, without comparing it with the sources on disk.
pub fn read(path: &Path) -> Result<Artifact, ArtifactError> {
    let bytes = std::fs::read(path).map_err(|source| ArtifactError::Io { path: path.to_path_buf(), source })?;
    decode(path, &bytes)
}

impl Artifact {
    /// The recorded files (with a path) whose contents differ from what is on disk now, and whether
    /// the main source is still there.
    pub fn changed_files(&self) -> (Vec<PathBuf>, bool) {
        let mut changed = Vec::new();
        for f in &self.files {
            let Some(p) = &f.path else { continue };
            match crate::source::read_source_text(p) {
                Ok(text) if content_hash(&text) == f.hash => {}
                _ => changed.push(p.clone()),
            }
        }
        let source_present = self.source.as_ref().is_some_and(|s| s.is_file());
        (changed, source_present)
    }
}

/// What [`load`] produced.
#[derive(Debug)]
pub enum Loaded {
    /// The artifact is up to date (or its sources are not at hand and nothing says it is stale).
    Artifact(Box<Artifact>),
    /// The artifact was stale or from another compiler version, so its source was compiled again
    /// (the compilation may have failed: check [`Compilation::ok`]).
    Recompiled { compilation: Box<Compilation>, reason: String },
}

/// Loads an artifact for use: decoded and validated, checked against its sources, and recompiled
/// from them when it is stale or outdated (see the module documentation). `fallback` gives the
/// preprocessor settings for recompiling an artifact of another format, whose own cannot be read.
pub fn load(path: &Path, fallback: &Options) -> Result<Loaded, ArtifactError> {
    let bytes = std::fs::read(path).map_err(|source| ArtifactError::Io { path: path.to_path_buf(), source })?;
    let artifact = match decode(path, &bytes) {
        Ok(a) => a,
        Err(ArtifactError::Outdated { source_file: Some(source), found, .. }) if source.is_file() => {
            let reason =
                format!("{} was written by format {found}, this compiler reads {FORMAT_VERSION}", path.display());
            return recompile(&source, fallback, reason);
        }
        Err(e) => return Err(e),
    };
    let (changed, source_present) = artifact.changed_files();
    if changed.is_empty() || (!source_present && changed.iter().all(|p| !p.exists())) {
        // Up to date, or a library shipped without its sources.
        return Ok(Loaded::Artifact(Box::new(artifact)));
    }
    let names = changed.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ");
    match (&artifact.source, source_present) {
        (Some(source), true) => {
            let reason = format!("{names} changed since {} was compiled", path.display());
            recompile(source, &artifact.options.to_options(), reason)
        }
        _ => Err(ArtifactError::StaleWithoutSource {
            path: path.to_path_buf(),
            changed: names,
            source_file: artifact.source.as_ref().map(|s| s.display().to_string()).unwrap_or_else(|| "(none)".into()),
        }),
    }
}

fn recompile(source: &Path, options: &Options, reason: String) -> Result<Loaded, ArtifactError> {
    let compilation = Session::new()
        .compile_file(source, options)
        .map_err(|e| ArtifactError::Io { path: source.to_path_buf(), source: e })?;
    Ok(Loaded::Recompiled { compilation: Box::new(compilation), reason })
}

/// One shader of a compiled library, as `index.json` lists it.
#[derive(Clone, Debug, Serialize)]
pub struct IndexEntry {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: crate::ir::ShaderKind,
    /// The artifact, relative to the index.
    pub artifact: String,
    pub source: Option<String>,
    /// blake3 of the source and of every file it included.
    pub files: Vec<IndexFile>,
    pub parameters: Vec<crate::interface::ParamInfo>,
}

#[derive(Clone, Debug, Serialize)]
pub struct IndexFile {
    pub path: String,
    pub blake3: String,
}

impl IndexEntry {
    pub fn new(c: &Compilation, artifact: &str) -> Option<IndexEntry> {
        let iface = c.interface.as_ref()?;
        let files = c
            .files
            .iter()
            .map(|f| c.sources.get(*f))
            .map(|f| IndexFile {
                path: f.path.as_deref().map(|p| absolute(p).display().to_string()).unwrap_or_else(|| f.name.clone()),
                blake3: content_hash(&f.text),
            })
            .collect();
        Some(IndexEntry {
            name: iface.name.clone(),
            kind: iface.kind,
            artifact: artifact.to_string(),
            source: c
                .files
                .first()
                .and_then(|f| c.sources.get(*f).path.as_deref())
                .map(|p| absolute(p).display().to_string()),
            files,
            parameters: iface.parameters.clone(),
        })
    }
}

/// The whole `index.json` of a compiled library.
#[derive(Clone, Debug, Serialize)]
pub struct Index {
    pub format_version: u32,
    pub compiler_version: &'static str,
    pub shaders: Vec<IndexEntry>,
}

impl Index {
    pub fn new(shaders: Vec<IndexEntry>) -> Index {
        Index { format_version: FORMAT_VERSION, compiler_version: env!("CARGO_PKG_VERSION"), shaders }
    }
}
