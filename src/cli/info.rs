//! `rtsl info`: a shader's interface, in the spirit of `oslinfo` and `sloinfo`.

use super::compile::CompilerFlags;
use anyhow::Context as _;
use rtsl_compiler::artifact::{self, Loaded};
use rtsl_compiler::interface::ShaderInterface;
use rtsl_compiler::{compile_file, Compilation, Options};
use rtsl_runtime::api::ShaderLocation;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The shader: a source file, or a name found on the shader search path (`-S` directories, then
    /// `RTSL_SHADER_PATH`, then the library).
    #[arg(value_name = "FILE|NAME")]
    pub file: PathBuf,
    /// Directories searched for shaders by name, before the standard library.
    #[arg(short = 'S', long = "shader-path")]
    pub shader_path: Vec<PathBuf>,
    /// Print only the file the name resolves to.
    #[arg(long)]
    pub which: bool,
    #[command(flatten)]
    pub flags: CompilerFlags,
    /// Print the interface as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Where `arg` is: itself when it is a file (or looks like one), else the shader of that name on
/// the search path or in the library.
fn resolve(arg: &std::path::Path, shader_path: &[PathBuf]) -> anyhow::Result<ShaderLocation> {
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

/// The interface of a source file or of a compiled artifact (checked against its sources, and
/// recompiled from them when stale, with a note). `None` after printing why there is none.
fn interface_of(file: &std::path::Path, options: &Options) -> anyhow::Result<Option<ShaderInterface>> {
    let from_compilation = |c: &Compilation| {
        if !c.ok() {
            eprint!("{}", c.render());
            return None;
        }
        if c.interface.is_none() {
            eprintln!("{}: defines no shader (only functions or macros)", file.display());
        }
        c.interface.clone()
    };
    if file.extension().is_some_and(|e| e == artifact::EXTENSION) {
        return Ok(match artifact::load(file, options)? {
            Loaded::Artifact(a) => Some(a.interface),
            Loaded::Recompiled { compilation, reason } => {
                eprintln!("note: {reason}; showing the source as it is now");
                from_compilation(&compilation)
            }
        });
    }
    let c = compile_file(file, options).with_context(|| format!("cannot read `{}`", file.display()))?;
    Ok(from_compilation(&c))
}

/// The interface of a shader wherever it is: a file, or the library built into the binary.
fn interface_at(location: &ShaderLocation, options: &Options) -> anyhow::Result<Option<ShaderInterface>> {
    match location {
        ShaderLocation::File(file) => interface_of(file, options),
        ShaderLocation::Library(shader) => {
            let c = rtsl_compiler::compile_source(&shader.label(), shader.source, options);
            if !c.ok() {
                eprint!("{}", c.render());
            }
            Ok(c.interface)
        }
    }
}

pub fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let file = resolve(&args.file, &args.shader_path)?;
    if args.which {
        println!("{file}");
        return Ok(ExitCode::SUCCESS);
    }
    let Some(iface) = interface_at(&file, &args.flags.options())? else {
        return Ok(ExitCode::from(1));
    };
    let iface = &iface;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let mut value = serde_json::to_value(iface)?;
        value["path"] = serde_json::Value::String(file.to_string());
        writeln!(out, "{}", serde_json::to_string_pretty(&value)?)?;
        return Ok(ExitCode::SUCCESS);
    }
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
    Ok(ExitCode::SUCCESS)
}
