//! `rtsl compile`: check shaders in parallel, one line per failure and a summary; and
//! `rtsl bench frontend`: the front end's throughput.

use anyhow::Context as _;
use rtsl_compiler::{Compilation, Options, Session};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Preprocessor flags shared by the subcommands that compile.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct CompilerFlags {
    /// Add a directory to the `#include` search path.
    #[arg(short = 'I', value_name = "DIR")]
    pub include: Vec<PathBuf>,
    /// Define a macro: `-D NAME` (as 1) or `-D NAME=VALUE`.
    #[arg(short = 'D', value_name = "NAME[=VALUE]", value_parser = parse_define)]
    pub define: Vec<(String, Option<String>)>,
    /// Remove a predefined macro.
    #[arg(short = 'U', value_name = "NAME")]
    pub undefine: Vec<String>,
}

fn parse_define(s: &str) -> Result<(String, Option<String>), String> {
    let (name, value) = match s.split_once('=') {
        Some((n, v)) => (n, Some(v.to_string())),
        None => (s, None),
    };
    let valid = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !valid {
        return Err(format!("`{name}` is not a valid macro name"));
    }
    Ok((name.to_string(), value))
}

impl CompilerFlags {
    pub fn options(&self) -> Options {
        let mut o = Options::default();
        o.preprocessor.include_paths = self.include.clone();
        o.preprocessor.defines = self.define.clone();
        o.preprocessor.undefines = self.undefine.clone();
        o
    }
}

#[derive(clap::Args, Debug)]
pub struct CompileArgs {
    /// Shader files, or directories to search recursively for `.sl` files.
    #[arg(required = true, value_name = "PATH")]
    pub paths: Vec<PathBuf>,
    #[command(flatten)]
    pub flags: CompilerFlags,
    /// Treat warnings as errors.
    #[arg(long)]
    pub werror: bool,
    /// Print one JSON record per shader (one per line) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Show every diagnostic in full, also when compiling many files.
    #[arg(short, long)]
    pub verbose: bool,
    /// Print the checked IR of each shader that compiles (its text form).
    #[arg(long)]
    pub emit_ir: bool,
    /// Write a compiled artifact (`NAME.rtso`) for every shader into this directory, and the
    /// library's `index.json`.
    #[arg(short = 'o', long = "output", value_name = "OUTDIR")]
    pub output: Option<PathBuf>,
    /// Worker threads (default: every core).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
}

/// Every `.sl` file named or found under the paths, in a stable order.
pub fn collect_shaders(paths: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        let meta = std::fs::metadata(p).with_context(|| format!("cannot read `{}`", p.display()))?;
        if meta.is_dir() {
            walk(p, &["sl"], &mut out).with_context(|| format!("cannot list `{}`", p.display()))?;
        } else {
            out.push(p.clone());
        }
    }
    Ok(out)
}

/// The files below `dir` whose extension is one of `extensions`, in path order. Links to directories
/// are not followed (as `find` does), so a link loop cannot make the walk endless.
pub(crate) fn walk(dir: &Path, extensions: &[&str], out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for path in entries {
        let link = path.symlink_metadata().is_ok_and(|m| m.file_type().is_symlink());
        if path.is_dir() {
            if !link {
                walk(&path, extensions, out)?;
            }
        } else if path.extension().is_some_and(|e| extensions.iter().any(|x| e == *x)) {
            out.push(path);
        }
    }
    Ok(())
}

/// One file's outcome.
struct Outcome {
    path: PathBuf,
    result: Result<Compilation, std::io::Error>,
    /// The encoded artifact, when one was asked for and the shader compiled.
    artifact: Option<Vec<u8>>,
}

/// Compiles `files` on every thread of the current rayon pool, encoding an artifact of each shader
/// when `encode` is set. Each thread keeps one session (headers are read and lexed once per thread,
/// not once per shader) and takes the next file when it finishes one, so uneven files balance out.
fn compile_all(files: &[PathBuf], options: &Options, encode: bool) -> Vec<Outcome> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let per_thread = rayon::broadcast(|_| {
        let mut session = Session::new();
        let mut done = Vec::new();
        loop {
            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let Some(path) = files.get(i) else { break };
            let result = session.compile_file(path, options);
            let artifact = match (&result, encode) {
                (Ok(c), true) => rtsl_compiler::artifact::encode(c, options),
                _ => None,
            };
            done.push((i, Outcome { path: path.clone(), result, artifact }));
        }
        done
    });
    let mut all: Vec<(usize, Outcome)> = per_thread.into_iter().flatten().collect();
    all.sort_by_key(|(i, _)| *i);
    all.into_iter().map(|(_, o)| o).collect()
}

/// Writes each artifact as `OUTDIR/NAME.rtso` and the library's `index.json`. A shader name defined
/// by two files keeps the first (in path order), as a search path would, and the second is reported.
fn write_library(outdir: &Path, outcomes: &[Outcome], out: &mut impl std::io::Write) -> anyhow::Result<usize> {
    use rtsl_compiler::artifact::{self, Index, IndexEntry};
    std::fs::create_dir_all(outdir).with_context(|| format!("cannot create `{}`", outdir.display()))?;
    let mut entries: Vec<IndexEntry> = Vec::new();
    for o in outcomes {
        let (Ok(c), Some(bytes)) = (&o.result, &o.artifact) else { continue };
        let Some(name) = c.interface.as_ref().map(|i| i.name.clone()) else { continue };
        if let Some(first) = entries.iter().find(|e| e.name == name) {
            writeln!(
                out,
                "warning: {} defines shader `{name}` again; the library keeps the one from {}",
                o.path.display(),
                first.source.as_deref().unwrap_or("?")
            )?;
            continue;
        }
        let file_name = format!("{name}.{}", artifact::EXTENSION);
        let path = outdir.join(&file_name);
        artifact::write_atomically(&path, bytes).with_context(|| format!("cannot write `{}`", path.display()))?;
        if let Some(entry) = IndexEntry::new(c, &file_name) {
            entries.push(entry);
        }
    }
    let written = entries.len();
    let index = outdir.join("index.json");
    let json = serde_json::to_string_pretty(&Index::new(entries))?;
    artifact::write_atomically(&index, json.as_bytes())
        .with_context(|| format!("cannot write `{}`", index.display()))?;
    Ok(written)
}

impl Outcome {
    fn failed(&self, werror: bool) -> bool {
        match &self.result {
            Ok(c) => !c.ok() || (werror && c.warnings() > 0),
            Err(_) => true,
        }
    }
}

pub fn run(args: &CompileArgs) -> anyhow::Result<ExitCode> {
    let files = collect_shaders(&args.paths)?;
    let options = args.flags.options();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(super::thread_count(args.threads.unwrap_or(0))?).build()?;
    let start = Instant::now();
    let outcomes = pool.install(|| compile_all(&files, &options, args.output.is_some()));
    let stdout = super::color::stdout();
    let mut out = stdout.lock();
    let full = args.verbose || (files.len() == 1 && !args.json);
    let (mut ok, mut failed, mut warnings, mut no_shader) = (0usize, 0usize, 0usize, 0usize);
    for o in &outcomes {
        let fails = o.failed(args.werror);
        // A file that compiles but defines no shader (empty, or only functions for `#include`)
        // is not a shader, so it is counted apart.
        let shaderless = !fails && o.result.as_ref().is_ok_and(|c| c.shader.is_none());
        if fails {
            failed += 1;
        } else if shaderless {
            no_shader += 1;
        } else {
            ok += 1;
        }
        match &o.result {
            Err(e) => {
                if args.json {
                    let record = serde_json::json!({
                        "path": o.path.display().to_string(),
                        "ok": false,
                        "error": format!("cannot read file: {e}"),
                        "diagnostics": [],
                    });
                    writeln!(out, "{record}")?;
                } else {
                    writeln!(out, "FAILED {}: cannot read file: {e}", o.path.display())?;
                }
            }
            Ok(c) => {
                warnings += c.warnings();
                if let (true, Some(m)) = (args.emit_ir, &c.module) {
                    writeln!(out, "// {}\n{}", o.path.display(), m.to_text())?;
                }
                if args.json {
                    let record = serde_json::json!({
                        "path": o.path.display().to_string(),
                        "shader_type": c.shader.as_ref().map(|s| s.0.name()),
                        "name": c.shader.as_ref().map(|s| s.1.clone()),
                        "ok": !fails,
                        "errors": c.errors(),
                        "warnings": c.warnings(),
                        "diagnostics": c.diagnostics.iter().map(|d| d.to_json(&c.sources)).collect::<Vec<_>>(),
                    });
                    writeln!(out, "{record}")?;
                } else if full {
                    if !c.diagnostics.is_empty() {
                        rtsl_compiler::diagnostic::render_to(&c.sources, &c.diagnostics, &mut out);
                    }
                    if shaderless {
                        writeln!(out, "{}: defines no shader", o.path.display())?;
                    }
                } else if fails {
                    let first = c
                        .diagnostics
                        .iter()
                        .find(|d| d.is_error())
                        .or_else(|| c.diagnostics.first())
                        .map(|d| d.one_line(&c.sources))
                        .unwrap_or_default();
                    let more = c.errors().saturating_sub(1) + if args.werror { c.warnings() } else { 0 };
                    let more = if more > 0 && c.errors() > 0 { format!(" (and {more} more)") } else { String::new() };
                    writeln!(out, "FAILED {first}{more}")?;
                }
            }
        }
    }
    let written = match &args.output {
        Some(dir) => Some((write_library(dir, &outcomes, &mut out)?, dir)),
        None => None,
    };
    if !args.json {
        let shaders = outcomes.len() - no_shader;
        let shaderless = match no_shader {
            0 => String::new(),
            1 => "; 1 file defines no shader".to_string(),
            n => format!("; {n} files define no shader"),
        };
        writeln!(
            out,
            "{shaders} shader{}: {ok} ok, {failed} failed, {warnings} warning{}{shaderless}",
            if shaders == 1 { "" } else { "s" },
            if warnings == 1 { "" } else { "s" },
        )?;
        if let Some((n, dir)) = written {
            writeln!(
                out,
                "wrote {n} artifact{} and index.json to {} ({:.1} ms on {} thread{})",
                if n == 1 { "" } else { "s" },
                dir.display(),
                start.elapsed().as_secs_f64() * 1e3,
                pool.current_num_threads(),
                if pool.current_num_threads() == 1 { "" } else { "s" },
            )?;
        }
    }
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

#[derive(clap::Args, Debug)]
pub struct BenchFrontendArgs {
    /// Shader files or directories (default: the shader library and the test corpus).
    #[arg(value_name = "PATH")]
    pub paths: Vec<PathBuf>,
    #[command(flatten)]
    pub flags: CompilerFlags,
    /// How many times to compile everything; the median pass is reported.
    #[arg(long, default_value_t = 20)]
    pub repeats: usize,
}

/// The benchmarks' inputs: the given paths, or by default the shader library and the test corpus
/// (with the corpus's include directory).
fn paths_or_library(paths: &[PathBuf], flags: &CompilerFlags) -> (Vec<PathBuf>, Options) {
    let (paths, mut options) = if paths.is_empty() {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let mut flags = flags.clone();
        flags.include.push(root.join("tests/corpus/include"));
        (vec![root.join("stdlib_shaders"), root.join("tests/corpus")], flags.options())
    } else {
        (paths.to_vec(), flags.options())
    };
    options.preprocessor.include_paths.dedup();
    (paths, options)
}

/// Compiles every file `repeats` times on one thread and prints lines per second.
pub fn bench_frontend(args: &BenchFrontendArgs) -> anyhow::Result<ExitCode> {
    let (paths, options) = paths_or_library(&args.paths, &args.flags);
    let files = collect_shaders(&paths)?;
    // Read once, so that the timing covers the compiler, not the disk.
    let sources: Vec<(PathBuf, String)> = files
        .iter()
        .map(|p| {
            Ok((
                p.clone(),
                rtsl_compiler::source::read_source_text(p).with_context(|| format!("cannot read `{}`", p.display()))?,
            ))
        })
        .collect::<anyhow::Result<_>>()?;
    let mut lines = 0usize;
    let mut ok = 0usize;
    let mut times = Vec::with_capacity(args.repeats.max(1));
    for _ in 0..args.repeats.max(1) {
        // A new session per pass: each pass reads and lexes the headers again, once.
        let mut session = Session::new();
        let start = Instant::now();
        lines = 0;
        ok = 0;
        for (path, text) in &sources {
            let c = session.compile_source_at(path, text, &options);
            lines += c.lines;
            ok += usize::from(c.ok());
        }
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    println!("files: {}", files.len());
    println!("compiled ok: {ok}");
    println!("lines (with includes): {lines}");
    println!("pass time ms (median of {}): {:.3}", times.len(), median * 1e3);
    println!("lines per second: {:.0}", lines as f64 / median);
    Ok(ExitCode::SUCCESS)
}

#[derive(clap::Args, Debug)]
pub struct BenchLibraryArgs {
    /// Shader files or directories (default: the shader library and the test corpus).
    #[arg(value_name = "PATH")]
    pub paths: Vec<PathBuf>,
    #[command(flatten)]
    pub flags: CompilerFlags,
    /// Threads of the parallel run (default: every core).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// How many times to compile the library in each configuration; medians are reported.
    #[arg(long, default_value_t = 20)]
    pub repeats: usize,
}

/// `rtsl bench library`: what `rtsl compile DIR -o OUT` does (front end and artifact encoding, not
/// the disk writes), on one thread and on every core in the same process; prints both and the
/// speedup.
pub fn bench_library(args: &BenchLibraryArgs) -> anyhow::Result<ExitCode> {
    let (paths, options) = paths_or_library(&args.paths, &args.flags);
    let files = collect_shaders(&paths)?;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let all = rayon::ThreadPoolBuilder::new().num_threads(super::thread_count(args.threads.unwrap_or(0))?).build()?;
    let run = |pool: &rayon::ThreadPool| {
        let start = Instant::now();
        let outcomes = pool.install(|| compile_all(&files, &options, true));
        let elapsed = start.elapsed().as_secs_f64();
        (elapsed, outcomes.iter().filter(|o| o.artifact.is_some()).count())
    };
    // Alternate the two so that both see the same machine state.
    let (mut serial, mut parallel) = (Vec::new(), Vec::new());
    let mut artifacts = 0;
    run(&one);
    run(&all);
    for _ in 0..args.repeats.max(1) {
        let (t, n) = run(&one);
        serial.push(t);
        artifacts = n;
        parallel.push(run(&all).0);
    }
    let (serial, parallel) = (median(serial), median(parallel));
    println!("files: {}", files.len());
    println!("artifacts: {artifacts}");
    println!("1 thread ms (median of {}): {:.2}", args.repeats.max(1), serial * 1e3);
    println!("{} threads ms: {:.2}", all.current_num_threads(), parallel * 1e3);
    println!("speedup: {:.2}x", serial / parallel);
    Ok(ExitCode::SUCCESS)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
