//! `rtsl info`: shaders' interfaces, in the spirit of `oslinfo` and `sloinfo`.

use super::compile::CompilerFlags;
use anyhow::Context as _;
use rtsl_compiler::artifact::{self, Loaded};
use rtsl_compiler::interface::ShaderInterface;
use rtsl_compiler::{compile_file, Compilation, Options};
use rtsl_runtime::api::ShaderLocation;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The shaders: source files or artifacts (`.sl`, `.rtso`), directories (searched recursively
    /// for both), or names found on the shader search path (`-S` directories, then
    /// `RTSL_SHADER_PATH`, then the library).
    #[arg(value_name = "FILE|DIR|NAME", required = true)]
    pub files: Vec<PathBuf>,
    /// Directories searched for shaders by name, before the standard library (repeatable, or a list
    /// separated by `:` as in `RTSL_SHADER_PATH`).
    #[arg(short = 'S', long = "shader-path", value_delimiter = crate::cli::PATH_LIST_SEPARATOR)]
    pub shader_path: Vec<PathBuf>,
    /// Print only the file each name resolves to.
    #[arg(long)]
    pub which: bool,
    #[command(flatten)]
    pub flags: CompilerFlags,
    /// Print one JSON record per shader, one per line (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

/// Where `arg` is: itself when it is a file (or looks like one), else the shader of that name on
/// the search path or in the library.
fn resolve(arg: &Path, shader_path: &[PathBuf]) -> anyhow::Result<ShaderLocation> {
    let looks_like_file = arg.is_file() || arg.extension().is_some() || arg.components().count() > 1;
    if looks_like_file {
        return Ok(ShaderLocation::File(arg.to_path_buf()));
    }
    let mut search = shader_path.to_vec();
    if let Ok(env) = std::env::var("RTSL_SHADER_PATH") {
        search.extend(std::env::split_paths(&env));
    }
    let name = arg.display().to_string();
    rtsl_runtime::api::locate_shader(&name, &search).ok_or_else(|| {
        anyhow::anyhow!(
            "no shader named `{name}` on the search path (-S, RTSL_SHADER_PATH, RTSL_STDLIB) or in the library"
        )
    })
}

/// Every shader the arguments name: directories expanded, names resolved.
fn locations(args: &InfoArgs) -> anyhow::Result<Vec<ShaderLocation>> {
    let mut out = Vec::new();
    for arg in &args.files {
        if arg.is_dir() {
            let mut files = Vec::new();
            super::compile::walk(arg, &["sl", artifact::EXTENSION], &mut files)
                .with_context(|| format!("cannot list `{}`", arg.display()))?;
            if files.is_empty() {
                eprintln!("note: no .sl or .{} files below `{}`", artifact::EXTENSION, arg.display());
            }
            out.extend(files.into_iter().map(ShaderLocation::File));
        } else {
            let location = resolve(arg, &args.shader_path)?;
            if let ShaderLocation::File(file) = &location {
                std::fs::metadata(file).with_context(|| format!("cannot read `{}`", file.display()))?;
            }
            out.push(location);
        }
    }
    Ok(out)
}

/// Why a shader has no interface to print: its diagnostics (already rendered as text) or an error.
struct Failure {
    text: String,
    diagnostics: Vec<serde_json::Value>,
}

impl Failure {
    fn of(c: &Compilation) -> Failure {
        Failure {
            text: c.render(),
            diagnostics: c.diagnostics.iter().map(|d| serde_json::json!(d.to_json(&c.sources))).collect(),
        }
    }
}

/// The interface of a source file or of a compiled artifact (checked against its sources, and
/// recompiled from them when stale, with a note on stderr).
fn interface_of(file: &Path, options: &Options) -> Result<ShaderInterface, Failure> {
    let from_compilation = |c: &Compilation| {
        if !c.ok() {
            return Err(Failure::of(c));
        }
        c.interface.clone().ok_or_else(|| Failure {
            text: format!("{}: defines no shader (only functions or macros)\n", file.display()),
            diagnostics: Vec::new(),
        })
    };
    let error = |e: anyhow::Error| Failure { text: format!("error: {e:#}\n"), diagnostics: Vec::new() };
    if file.extension().is_some_and(|e| e == artifact::EXTENSION) {
        return match artifact::load(file, options).map_err(|e| error(e.into()))? {
            Loaded::Artifact(a) => Ok(a.interface),
            Loaded::Recompiled { compilation, reason } => {
                eprintln!("note: {reason}; showing the source as it is now");
                from_compilation(&compilation)
            }
        };
    }
    let c = compile_file(file, options).with_context(|| format!("cannot read `{}`", file.display())).map_err(error)?;
    from_compilation(&c)
}

/// The interface of a shader wherever it is: a file, or the library built into the binary.
fn interface_at(location: &ShaderLocation, options: &Options) -> Result<ShaderInterface, Failure> {
    match location {
        ShaderLocation::File(file) => interface_of(file, options),
        ShaderLocation::Library(shader) => {
            let c = rtsl_compiler::compile_source(&shader.label(), shader.source, options);
            match c.interface.clone() {
                Some(i) if c.ok() => Ok(i),
                _ => Err(Failure::of(&c)),
            }
        }
    }
}

/// The interface as `sloinfo` prints it: the type and name, then a parameter a line.
fn write_interface(out: &mut impl std::io::Write, iface: &ShaderInterface) -> std::io::Result<()> {
    writeln!(out, "{} \"{}\"", iface.kind.name(), iface.name)?;
    for p in &iface.parameters {
        let output = if p.output { "output " } else { "" };
        let array = p.array_length.map(|n| format!("[{n}]")).unwrap_or_default();
        let default = match &p.default {
            Some(v) => v.to_string(),
            None => format!("<{}>", p.default_source.split_whitespace().collect::<Vec<_>>().join(" ")),
        };
        writeln!(out, "    {output}{} {} {}{array} = {default}", p.storage, p.base, p.name)?;
    }
    Ok(())
}

pub fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let locations = locations(args)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.which {
        for location in &locations {
            writeln!(out, "{location}")?;
        }
        return Ok(ExitCode::SUCCESS);
    }
    // One shader named as such prints as `sloinfo` does; several (or a directory) get a header each.
    let headers = locations.len() > 1 || args.files.iter().any(|f| f.is_dir());
    let options = args.flags.options();
    let mut failed = 0usize;
    for (k, location) in locations.iter().enumerate() {
        match interface_at(location, &options) {
            Ok(iface) => {
                if args.json {
                    let mut value = serde_json::to_value(&iface)?;
                    value["path"] = serde_json::Value::String(location.to_string());
                    value["ok"] = serde_json::Value::Bool(true);
                    writeln!(out, "{value}")?;
                    continue;
                }
                if headers {
                    if k > 0 {
                        writeln!(out)?;
                    }
                    writeln!(out, "{location}:")?;
                }
                write_interface(&mut out, &iface)?;
            }
            Err(failure) => {
                failed += 1;
                out.flush()?;
                eprint!("{}", failure.text);
                if args.json {
                    let mut record = serde_json::json!({
                        "path": location.to_string(),
                        "ok": false,
                        "diagnostics": failure.diagnostics,
                    });
                    // What no diagnostic says: an unreadable file, no shader in it.
                    if failure.diagnostics.is_empty() {
                        record["error"] = failure.text.trim_end().into();
                    }
                    writeln!(out, "{record}")?;
                }
            }
        }
    }
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}
