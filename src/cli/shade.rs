//! `rtsl shade`: runs a shader of any type over a grid of points with no scene and writes its
//! results as images (like OSL's `testshade`); `rtsl bench shade`: the JIT against the interpreter and
//! hand-written Rust, and the compile cost of a shader library.

use anyhow::Context as _;
use rtsl::bench::shading::{compile_benchmark, shading_benchmark};
use rtsl_compiler::interface::ShaderKind;
use rtsl_compiler::interp::{TestHost, Value};
use rtsl_compiler::testshade::{parse_param, EntryValue, Grid, ParamArg};
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Flags of `rtsl shade`.
#[derive(clap::Args, Debug, Clone)]
pub struct ShadeArgs {
    /// The shader, of any type (`docs/shaders.md`, "Testing shaders"); required.
    #[arg(value_name = "FILE")]
    pub file: Option<PathBuf>,
    /// Grid size: width and height in points.
    #[arg(short = 'g', long = "grid", num_args = 2, value_names = ["W", "H"], default_values_t = [256, 256])]
    pub grid: Vec<usize>,
    /// A parameter value, `NAME=VALUE` (`0.5`, `1,0,0`, or text for strings); repeatable.
    #[arg(long = "param", value_parser = parse_param)]
    pub params: Vec<(String, ParamArg)>,
    /// A ray parameter that `rayinfo` reads, `NAME=VALUE` (`0.5`, `1,0,0` for a colour or point,
    /// or text); repeatable (`docs/ray_parameters.md`).
    #[arg(long = "ray-param", value_parser = parse_ray_param)]
    pub ray_params: Vec<(String, ParamArg)>,
    /// A global's value on entry in place of the type's own, `NAME=VALUE`: numbers (`0.5`,
    /// `0,1,0`) at every point, or an image file read at each point's `(s, t)` (a triple global
    /// takes its RGB, a float its first channel); repeatable.
    #[arg(long = "global", value_parser = parse_param)]
    pub globals: Vec<(String, ParamArg)>,
    /// The image arriving at an imager (its `Ci` and `alpha`) or at a volume (`Ci`, and `Oi` from
    /// the alpha), read at each point's `(s, t)`.
    #[arg(long = "input", value_name = "IMAGE")]
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub outputs: Outputs,
    /// Shade the grid this many times and print shaded points per second.
    #[arg(long, default_value_t = 1)]
    pub iters: usize,
    /// Directories searched for `#include`.
    #[arg(short = 'I', long = "include")]
    pub include: Vec<PathBuf>,
}

/// The `-o` flags of `rtsl shade`, each one or two values: clap's derive has no type for groups
/// of values per occurrence, so this one is built by hand.
#[derive(Debug, Clone, Default)]
pub struct Outputs(pub Vec<Vec<String>>);

impl clap::FromArgMatches for Outputs {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let groups = matches.get_occurrences::<String>("output").map(|o| o.map(|g| g.cloned().collect()).collect());
        Ok(Outputs(groups.unwrap_or_default()))
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl clap::Args for Outputs {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        cmd.arg(
            clap::Arg::new("output")
                .short('o')
                .long("output")
                .num_args(1..=2)
                .value_names(["VAR", "FILE"])
                .action(clap::ArgAction::Append)
                .help(
                    "`-o VAR FILE`: write a global or output parameter to an image (.png, .exr, .tga, .ppm), a float \
                     as grey, a triple as RGB; repeatable. `-o FILE`: the shader type's main result (`Ci` of a \
                     surface, `P` of a displacement, `Cl` of a light, `I` of a camera)",
                ),
        )
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

/// `NAME=VALUE` of `--ray-param`: a float, a triple or a string.
fn parse_ray_param(arg: &str) -> Result<(String, ParamArg), String> {
    let (name, value) = parse_param(arg)?;
    match &value {
        ParamArg::Floats(f) if f.len() != 1 && f.len() != 3 => {
            Err(format!("`{arg}`: a ray parameter is a float or three (a colour or point), not {}", f.len()))
        }
        _ => Ok((name, value)),
    }
}

pub fn run(args: &ShadeArgs) -> anyhow::Result<ExitCode> {
    // Optional for clap only, so that `-o out.exr shader.sl` (read as `-o VAR FILE`) gets a hint.
    let Some(file) = &args.file else {
        match args.outputs.0.iter().find(|o| o.len() == 2) {
            Some(o) => anyhow::bail!(
                "no shader file: `-o {} {}` reads as `-o VAR FILE`; put `-o FILE` after the shader's file name",
                o[0],
                o[1]
            ),
            None => anyhow::bail!("no shader file: rtsl shade FILE.sl [-o [VAR] FILE]..."),
        }
    };
    let (w, h) = (args.grid[0].max(1), args.grid[1].max(1));
    // The grid is written as an image: the renderer's image limits, before anything is allocated.
    rtsl_runtime::render::check_image_size(w as u64, h as u64).map_err(|e| anyhow::anyhow!("-g {w} {h}: {e}"))?;
    let mut options = rtsl_compiler::Options::default();
    options.preprocessor.include_paths = args.include.clone();
    let c = rtsl_compiler::compile_file(file, &options).with_context(|| format!("reading {}", file.display()))?;
    rtsl_compiler::diagnostic::render_to(&c.sources, &c.diagnostics, &mut super::color::stderr());
    let Some(module) = c.module.as_ref() else { return Ok(ExitCode::from(1)) };
    let mut grid = Grid::with_sources(module, Some(&c.sources), w, h, &args.params)
        .with_context(|| format!("{}", file.display()))?;
    set_entries(&mut grid, args).with_context(|| format!("{}", file.display()))?;
    // Every `-o` is checked before anything is shaded.
    let outputs: Vec<(String, PathBuf)> = args
        .outputs
        .0
        .iter()
        .filter_map(|o| match o.as_slice() {
            [image] => Some((grid.default_output().to_string(), PathBuf::from(image))),
            [var, image, ..] => Some((var.clone(), PathBuf::from(image))),
            [] => None,
        })
        .collect();
    for (var, _) in &outputs {
        grid.check_output(var).with_context(|| format!("-o {var}: {}", file.display()))?;
    }
    let ray_parameters = args
        .ray_params
        .iter()
        .map(|(name, v)| {
            let value = match v {
                ParamArg::Floats(f) if f.len() == 1 => Value::Float(f[0]),
                ParamArg::Floats(f) => Value::Triple([f[0], f[1], f[2]]),
                ParamArg::String(s) => Value::String(s.as_str().into()),
            };
            (name.strip_prefix("user:").unwrap_or(name).to_string(), value)
        })
        .collect();
    let mut host = TestHost { ray_parameters, ..TestHost::default() };
    let start = Instant::now();
    for _ in 0..args.iters.max(1) {
        grid.shade(&mut host);
    }
    let elapsed = start.elapsed().as_secs_f64();
    for m in grid.runtime_errors() {
        eprintln!("warning: {m}");
    }
    for line in &host.printed {
        print!("{line}");
    }
    if args.iters > 1 {
        let points = (grid.points() * args.iters) as f64;
        println!(
            "{:.2} M points/s ({:.1} ns per point, {} x {w}x{h})",
            points / elapsed / 1e6,
            elapsed * 1e9 / points,
            args.iters
        );
    }
    for (var, out) in &outputs {
        let image = grid.image_of(var)?;
        rtsl_runtime::write_image(out, w, h, &image, &rtsl_runtime::WriteOptions::default())
            .with_context(|| format!("writing {} to {}", var, out.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The `--global` and `--input` values, given to the grid.
fn set_entries(grid: &mut Grid, args: &ShadeArgs) -> anyhow::Result<()> {
    let (w, h) = grid.size();
    // An image's channels at each grid point, the nearest pixel to its (s, t).
    let sampled = |path: &PathBuf, channels: &[usize]| -> anyhow::Result<Vec<f32>> {
        let img = rtsl_runtime::read_image(path).with_context(|| format!("reading {}", path.display()))?;
        anyhow::ensure!(img.width > 0 && img.height > 0, "{} is an empty image", path.display());
        let mut out = Vec::with_capacity(w * h * channels.len());
        for y in 0..h {
            let py = ((y as f64 + 0.5) / h as f64 * img.height as f64) as usize;
            for x in 0..w {
                let px = ((x as f64 + 0.5) / w as f64 * img.width as f64) as usize;
                let at = 4 * (py.min(img.height - 1) * img.width + px.min(img.width - 1));
                out.extend(channels.iter().map(|c| img.pixels[at + c]));
            }
        }
        Ok(out)
    };
    if let Some(path) = &args.input {
        let (colour, alpha) = match grid.kind() {
            ShaderKind::Imager => ("Ci", "alpha"),
            ShaderKind::Volume => ("Ci", "Oi"),
            other => anyhow::bail!(
                "--input gives an imager or a volume its incoming image, not {} shader (use --global NAME=IMAGE)",
                other.with_article()
            ),
        };
        grid.set_entry(colour, EntryValue::PerPoint(sampled(path, &[0, 1, 2])?))?;
        let a = if alpha == "Oi" { sampled(path, &[3, 3, 3])? } else { sampled(path, &[3])? };
        grid.set_entry(alpha, EntryValue::PerPoint(a))?;
    }
    for (name, value) in &args.globals {
        let entry = match value {
            ParamArg::Floats(f) => EntryValue::Constant(f.clone()),
            ParamArg::String(path) => {
                let comps = grid.check_output(name).unwrap_or(3);
                let channels: &[usize] = if comps == 1 { &[0] } else { &[0, 1, 2] };
                EntryValue::PerPoint(sampled(&PathBuf::from(path), channels)?)
            }
        };
        grid.set_entry(name, entry).with_context(|| format!("--global {name}"))?;
    }
    Ok(())
}

/// Flags of `rtsl bench shade`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchShadeArgs {
    /// Points shaded per repeat.
    #[arg(long, default_value_t = 16384)]
    pub points: usize,
    /// Repeats for the JIT and the Rust code.
    #[arg(long, default_value_t = 20)]
    pub repeats: usize,
    /// The library whose compile cost is measured (default: the library built into the binary).
    #[arg(long)]
    pub library: Option<PathBuf>,
}

pub fn bench(args: &BenchShadeArgs) -> anyhow::Result<ExitCode> {
    let rows = shading_benchmark(args.points, args.repeats.max(1)).map_err(anyhow::Error::msg)?;
    // Written with `?`, so a closed pipe (`| head`) ends quietly instead of panicking.
    let mut out = std::io::stdout().lock();
    writeln!(out, "shader   jit ns/pt  interpreter ns/pt  rust ns/pt  jit/rust  interpreter/jit  max |jit-rust|")?;
    for r in &rows {
        writeln!(
            out,
            "{:<8} {:>9.1} {:>18.1} {:>11.1} {:>9.3} {:>16.1} {:>15.2e}",
            r.shader,
            r.jit_ns,
            r.interpreter_ns,
            r.rust_ns,
            r.jit_ns / r.rust_ns.max(1e-9),
            r.interpreter_ns / r.jit_ns.max(1e-9),
            r.max_difference
        )?;
    }
    let built_in = super::ScratchDir::new("bench-shade")?;
    let library = match &args.library {
        Some(dir) => dir.clone(),
        None => {
            rtsl_runtime::shading::library::write_to(&built_in.0).context("writing the shader library")?;
            built_in.0.clone()
        }
    };
    let mut compile = compile_benchmark(&library).map_err(anyhow::Error::msg)?;
    compile.sort_by(|a, b| a.micros.total_cmp(&b.micros));
    if let (Some(max), false) = (compile.last(), compile.is_empty()) {
        let median = compile[compile.len() / 2].micros;
        let total: f64 = compile.iter().map(|r| r.micros).sum();
        writeln!(
            out,
            "compile (source to callable code, one thread): {} shaders, median {:.2} ms, max {:.2} ms ({}), total {:.1} ms",
            compile.len(),
            median / 1e3,
            max.micros / 1e3,
            max.name,
            total / 1e3
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
