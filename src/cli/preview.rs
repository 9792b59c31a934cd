//! `rtsl preview`: renders a surface or displacement shader on the standard ball-and-floor scene
//! ([`rtsl::preview`]), as shader libraries show their shaders.

use anyhow::Context as _;
use rtsl_compiler::interface::ShaderKind;
use rtsl_compiler::testshade::{parse_param, ParamArg};
use rtsl_runtime::api::Context;
use rtsl_runtime::render::render_frame;
use rtsl_runtime::rib::load::load_str;
use rtsl_runtime::{write_image, WriteOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Flags of `rtsl preview`.
#[derive(clap::Args, Debug, Clone)]
pub struct PreviewArgs {
    /// The shader: a `.sl` or `.rtso` file, or a name found on the shader path or in the library.
    pub shader: String,
    /// A parameter value, `NAME=VALUE` (`0.5`, `1,0,0`, or text for strings); repeatable.
    #[arg(long = "param", value_parser = parse_param)]
    pub params: Vec<(String, ParamArg)>,
    /// The image to write (.png, .exr, .tga, .ppm).
    #[arg(short, long, default_value = "preview.png")]
    pub output: PathBuf,
    /// Image size, `WxH`.
    #[arg(long, value_parser = super::bench::parse_size, default_value = "320x240")]
    pub size: (u32, u32),
    /// Samples per pixel along each axis (3: 3x3).
    #[arg(long, default_value_t = 3)]
    pub samples: u32,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Directories searched for shaders by name, before the standard library (repeatable, or a list
    /// separated by `:` as in `RTSL_SHADER_PATH`).
    #[arg(short = 'S', long = "shader-path", value_delimiter = crate::cli::PATH_LIST_SEPARATOR)]
    pub shader_path: Vec<PathBuf>,
    /// Directories searched for `#include`d shader headers.
    #[arg(short = 'I', long = "include")]
    pub include: Vec<PathBuf>,
}

pub fn run(args: &PreviewArgs) -> anyhow::Result<ExitCode> {
    let mut rt = Context::new();
    let mut search = args.shader_path.clone();
    if let Ok(env) = std::env::var("RTSL_SHADER_PATH") {
        search.extend(std::env::split_paths(&env));
    }
    rt.set_shader_search_path(search);
    rt.set_include_paths(args.include.clone());
    let file = Path::new(&args.shader);
    // A file is compiled here; the scene then finds it by its name, as loaded shaders are found.
    let id = if file.is_file() { rt.shader_file(file)? } else { rt.find_shader(&args.shader)? };
    let program = rt.program(id)?.clone();
    let statement = |request: &str| {
        rtsl::preview::shader_statement(request, &program.name, &args.params).map_err(anyhow::Error::msg)
    };
    let ball = match program.kind {
        ShaderKind::Surface => statement("Surface")?,
        ShaderKind::Displacement => format!("Surface \"plastic\"\n    {}", statement("Displacement")?),
        other => anyhow::bail!(
            "`{}` is {} shader; a preview shows surface and displacement shaders",
            program.name,
            other.with_article()
        ),
    };
    let (width, height) = args.size;
    let rib = rtsl::preview::scene(&ball, width, height, args.samples.clamp(1, 16));
    let loaded = load_str(&mut rt, &rib, Path::new("<preview>"))?;
    // The scene is ours: anything it warns about comes from the flags (a parameter the shader
    // lacks, a value of the wrong type).
    for w in &loaded.warnings {
        eprintln!("warning: {}", w.message);
    }
    anyhow::ensure!(loaded.warnings.is_empty(), "the parameters do not fit `{}`", program.name);
    let (_, pool) = super::worker_pool(args.threads)?;
    let world = rt.build_world()?;
    let (fb, report) = pool.install(|| render_frame(&world, None));
    let missing = world.textures.take_warnings();
    for w in &missing {
        eprintln!("warning: {w}");
    }
    write_image(&args.output, fb.width as usize, fb.height as usize, &fb.rgba, &WriteOptions::default())
        .with_context(|| format!("writing {}", args.output.display()))?;
    println!(
        "{}: {} ({}) on the preview ball, {width}x{height}, {:.0} ms",
        args.output.display(),
        program.name,
        program.kind.name(),
        report.elapsed.as_secs_f64() * 1e3
    );
    Ok(if missing.is_empty() { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}
