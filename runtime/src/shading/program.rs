//! Compiled shader programs: source compiled by `rtsl-compiler`, JIT-compiled to packet code, with the
//! slots of the globals the renderer fills resolved once.
//!
//! A [`ShaderProgram`] is immutable and shared (`Arc`) by every object, light and thread that uses it;
//! parameter values live in [`super::ShaderInstance`]s.

use rtsl_compiler::artifact::{self, Artifact, ArtifactError, Loaded};
use rtsl_compiler::interface::ShaderInterface;
use rtsl_compiler::interface::ShaderKind;
use rtsl_compiler::jit::{self, CompiledShader, JitError, Layout};
use rtsl_compiler::source::SourceMap;
use rtsl_compiler::Module;
use rtsl_compiler::{Options, Session};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why a shader could not be made ready to run.
#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    // The cause is part of the message and not a `source`, so that an error chain does not say it
    // twice while a reload's one-line message still gives it.
    #[error("cannot read shader {path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    /// The front end reported errors; `diagnostics` is their rustc-style rendering.
    #[error("shader {name} does not compile:\n{diagnostics}")]
    Compile { name: String, diagnostics: String },
    #[error("{name}: the file defines no shader")]
    NoShader { name: String },
    #[error("shader {name}: {error}")]
    Jit { name: String, error: JitError },
    #[error("no shader named {name} on the shader search path")]
    NotFound { name: String },
    /// A compiled artifact that cannot be used (damaged, or stale with no source to recompile).
    #[error(transparent)]
    Artifact(#[from] ArtifactError),
}

pub use rtsl_compiler::jit::LightKind;

/// Where one global lives in the batch of a program (see `docs/packet-abi.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    pub varying: bool,
    pub offset: usize,
    pub written: bool,
    /// The shader assigns the global before any use of its value on entry (`GlobalSlot::entry_unused`):
    /// a caller need not fill it.
    pub entry_unused: bool,
    /// The shader reads the renderer's derivatives of the global (`GlobalSlot::derivs`): a caller
    /// need fill only these derivatives.
    pub derivs: bool,
}

/// The slots of the globals the renderer fills or reads, `None` where the shader does not use one.
#[derive(Clone, Debug, Default)]
pub struct GlobalSlots {
    pub p: Option<Slot>,
    pub n: Option<Slot>,
    pub ng: Option<Slot>,
    pub i: Option<Slot>,
    pub e: Option<Slot>,
    pub s: Option<Slot>,
    pub t: Option<Slot>,
    pub u: Option<Slot>,
    pub v: Option<Slot>,
    pub du: Option<Slot>,
    pub dv: Option<Slot>,
    pub dpdu: Option<Slot>,
    pub dpdv: Option<Slot>,
    pub cs: Option<Slot>,
    pub os: Option<Slot>,
    pub ci: Option<Slot>,
    pub oi: Option<Slot>,
    pub ps: Option<Slot>,
    pub l: Option<Slot>,
    pub cl: Option<Slot>,
    pub ol: Option<Slot>,
    pub time: Option<Slot>,
    pub dtime: Option<Slot>,
    pub ncomps: Option<Slot>,
    pub alpha: Option<Slot>,
    pub zdepth: Option<Slot>,
    pub objectid: Option<Slot>,
    pub shaderid: Option<Slot>,
    /// Pixie's `Ns` of light shaders (`rtsl_compiler::globals::VENDOR_GLOBALS`).
    pub ns: Option<Slot>,
}

impl GlobalSlots {
    fn from_layout(layout: &Layout) -> GlobalSlots {
        let g = |name: &str| {
            layout.global(name).map(|g| Slot {
                varying: g.varying,
                offset: g.offset,
                written: g.written,
                entry_unused: g.entry_unused,
                derivs: g.derivs,
            })
        };
        GlobalSlots {
            p: g("P"),
            n: g("N"),
            ng: g("Ng"),
            i: g("I"),
            e: g("E"),
            s: g("s"),
            t: g("t"),
            u: g("u"),
            v: g("v"),
            du: g("du"),
            dv: g("dv"),
            dpdu: g("dPdu"),
            dpdv: g("dPdv"),
            cs: g("Cs"),
            os: g("Os"),
            ci: g("Ci"),
            oi: g("Oi"),
            ps: g("Ps"),
            l: g("L"),
            cl: g("Cl"),
            ol: g("Ol"),
            time: g("time"),
            dtime: g("dtime"),
            ncomps: g("ncomps"),
            alpha: g("alpha"),
            zdepth: g("zdepth"),
            objectid: g("objectid"),
            shaderid: g("shaderid"),
            ns: g("Ns"),
        }
    }
}

/// A shader ready to run: its interface, its packet code and the slots of its globals.
pub struct ShaderProgram {
    pub name: String,
    pub kind: ShaderKind,
    /// The file it came from (`None` for source given as a string).
    pub path: Option<PathBuf>,
    pub interface: ShaderInterface,
    pub code: CompiledShader,
    pub slots: GlobalSlots,
    /// For light shaders: how the light emits.
    pub light_kind: LightKind,
    /// Every lane of a batch gets the same results: the code reads no global's value on entry,
    /// calls no function or built-in (no lookups, messages, noise or `random()`) and has no
    /// `illuminance`, `illuminate`, `solar` or `gather`. Its outputs are then functions of its
    /// parameters alone, and one lane may be run for all (an `ambientlight`, for instance).
    pub lane_invariant: bool,
    /// For light shaders: where the code leaves its `__nondiffuse` and `__nonspecular` outputs,
    /// where it has them as single floats (found once: every light evaluation reads them).
    pub light_flags: [Option<FlagSlot>; 2],
    /// The front end's warnings, rendered.
    pub warnings: String,
    /// Every file the compilation read (the source and its includes), for hot reload.
    pub files: Vec<PathBuf>,
    /// What the code was compiled from, to send the program elsewhere ([`ShaderProgram::artifact`]).
    origin: Origin,
}

/// A program's checked IR and sources: what an artifact holds.
struct Origin {
    module: Module,
    sources: SourceMap,
    /// The front end's rendered warnings (without notes about how the program was loaded).
    front_warnings: String,
    options: Options,
    source: Option<PathBuf>,
}

impl std::fmt::Debug for ShaderProgram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShaderProgram").field("name", &self.name).field("kind", &self.kind).finish()
    }
}

impl ShaderProgram {
    pub fn layout(&self) -> &Layout {
        self.code.layout()
    }

    /// Compiles the shader in `path` (with `#include` searched in `include_paths`), or loads it when
    /// `path` is a compiled artifact (`.rtso`, see [`ShaderProgram::from_artifact`]).
    pub fn from_file(path: &Path, include_paths: &[PathBuf]) -> Result<ShaderProgram, ShaderError> {
        if path.extension().is_some_and(|e| e == artifact::EXTENSION) {
            return Self::from_artifact(path, include_paths);
        }
        // As the compiler reads files: Latin-1 in an old shader's comments is not a reason to refuse it.
        let text = rtsl_compiler::source::read_source_text(path)
            .map_err(|cause| ShaderError::Io { path: path.to_path_buf(), cause })?;
        let mut session = Session::new();
        let options = options(include_paths);
        let c = session.compile_source_at(path, &text, &options);
        let name = path.display().to_string();
        Self::from_compilation(c, &name, Some(path.to_path_buf()), String::new(), options)
    }

    /// Loads a compiled artifact, skipping the front end. A stale artifact (its source or an include
    /// changed) or one from another compiler version is recompiled from its source when that is at
    /// hand (`include_paths` serve only an artifact whose own settings cannot be read); a damaged one,
    /// or a stale one without its source, is an error. The program's `path` is the artifact's, so hot
    /// reload goes through the same checks; its `files` are the sources the artifact was made from.
    pub fn from_artifact(path: &Path, include_paths: &[PathBuf]) -> Result<ShaderProgram, ShaderError> {
        match artifact::load(path, &options(include_paths))? {
            Loaded::Artifact(a) => Self::from_decoded(*a, Some(path.to_path_buf())),
            Loaded::Recompiled { compilation, reason } => {
                let name = path.display().to_string();
                Self::from_compilation(
                    *compilation,
                    &name,
                    Some(path.to_path_buf()),
                    format!("note: {reason}; recompiled from source\n"),
                    options(include_paths),
                )
            }
        }
    }

    /// Compiles shader source given as a string; `name` names it in diagnostics.
    pub fn from_source(name: &str, text: &str, include_paths: &[PathBuf]) -> Result<ShaderProgram, ShaderError> {
        let mut session = Session::new();
        let options = options(include_paths);
        let c = session.compile_source(name, text, &options);
        Self::from_compilation(c, name, None, String::new(), options)
    }

    fn from_compilation(
        c: rtsl_compiler::Compilation,
        name: &str,
        path: Option<PathBuf>,
        note: String,
        options: Options,
    ) -> Result<ShaderProgram, ShaderError> {
        if !c.ok() {
            return Err(ShaderError::Compile { name: name.to_string(), diagnostics: format!("{note}{}", c.render()) });
        }
        let front_warnings = if c.warnings() > 0 { c.render() } else { String::new() };
        let warnings = format!("{note}{front_warnings}");
        let files = c.files.iter().filter_map(|f| c.sources.get(*f).path.clone()).collect();
        let source = c.files.first().and_then(|f| c.sources.get(*f).path.clone());
        let (Some(module), Some(interface)) = (c.module, c.interface) else {
            return Err(ShaderError::NoShader { name: name.to_string() });
        };
        let origin = Origin { module, sources: c.sources, front_warnings, options, source };
        Self::build(origin, interface, warnings, files, path)
    }

    /// Loads a program from an artifact's bytes held in memory ([`ShaderProgram::artifact`] made
    /// them, here or in another process of the same build); `label` names it in errors. Nothing is
    /// read from disk: the bytes carry the IR and its sources.
    pub fn from_artifact_bytes(label: &str, bytes: &[u8]) -> Result<ShaderProgram, ShaderError> {
        let a = artifact::decode(Path::new(label), bytes)?;
        let path = a.source.clone();
        Self::from_decoded(a, path)
    }

    /// A program from a decoded artifact; `path` is the program's (see [`ShaderProgram::path`]).
    fn from_decoded(a: Artifact, path: Option<PathBuf>) -> Result<ShaderProgram, ShaderError> {
        let files = a.files.iter().filter_map(|f| f.path.clone()).collect();
        let origin = Origin {
            module: a.module,
            sources: a.sources,
            front_warnings: a.warnings.clone(),
            options: a.options.to_options(),
            source: a.source,
        };
        Self::build(origin, a.interface, a.warnings, files, path)
    }

    /// The program as a compiled artifact's bytes (the format of `rtsl compile -o`): its IR and
    /// the sources it came from, which [`ShaderProgram::from_artifact_bytes`] loads without the
    /// front end. `None` only if the IR cannot be encoded.
    pub fn artifact(&self) -> Option<Vec<u8>> {
        let o = &self.origin;
        artifact::encode_module(&o.module, &o.sources, o.front_warnings.clone(), &o.options, o.source.as_deref())
    }

    fn build(
        origin: Origin,
        interface: ShaderInterface,
        warnings: String,
        files: Vec<PathBuf>,
        path: Option<PathBuf>,
    ) -> Result<ShaderProgram, ShaderError> {
        let (module, sources) = (&origin.module, &origin.sources);
        let code = jit::compile_with(module, Some(sources), &jit::JitOptions::default())
            .map_err(|error| ShaderError::Jit { name: interface.name.clone(), error })?;
        Ok(ShaderProgram {
            name: interface.name.clone(),
            kind: interface.kind,
            path,
            slots: GlobalSlots::from_layout(code.layout()),
            light_kind: code.light_kind(),
            lane_invariant: code.lane_invariant(),
            light_flags: light_flags(code.layout()),
            interface,
            code,
            warnings,
            files,
            origin,
        })
    }
}

fn options(include_paths: &[PathBuf]) -> Options {
    let mut o = Options::default();
    o.preprocessor.include_paths = include_paths.to_vec();
    o
}

/// Where a light shader leaves one of its light flags: a float slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlagSlot {
    pub offset: usize,
    pub varying: bool,
}

/// See [`ShaderProgram::light_flags`].
fn light_flags(layout: &Layout) -> [Option<FlagSlot>; 2] {
    ["__nondiffuse", "__nonspecular"].map(|name| {
        let (_, slot) = layout.param(name)?;
        (slot.components == 1 && slot.len == 1 && !slot.string)
            .then_some(FlagSlot { offset: slot.offset, varying: slot.varying })
    })
}

/// Shared handle to a program.
pub type Program = Arc<ShaderProgram>;
