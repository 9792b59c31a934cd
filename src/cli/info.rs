//! `rtsl info`: a shader's interface, in the spirit of `oslinfo` and `sloinfo`.

use super::compile::CompilerFlags;
use anyhow::Context as _;
use rtsl_compiler::compile_file;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The shader source file.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    #[command(flatten)]
    pub flags: CompilerFlags,
    /// Print the interface as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let c = compile_file(&args.file, &args.flags.options())
        .with_context(|| format!("cannot read `{}`", args.file.display()))?;
    if !c.ok() {
        eprint!("{}", c.render());
        return Ok(ExitCode::from(1));
    }
    let Some(iface) = &c.interface else {
        eprintln!("{}: defines no shader (only functions or macros)", args.file.display());
        return Ok(ExitCode::from(1));
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let mut value = serde_json::to_value(iface)?;
        value["path"] = serde_json::Value::String(args.file.display().to_string());
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
