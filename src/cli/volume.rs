//! `rtsl volume`: volume data for the `volumegrid` shader (`docs/volumes.md`).

use anyhow::Context as _;
use rtsl_runtime::texture::grid_data::{generate, GridKind};
use rtsl_runtime::texture::GridType;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct GenerateArgs {
    /// Which data set.
    #[arg(long, value_enum, default_value = "neghip-like")]
    pub kind: Kind,
    /// Samples along each axis (the grid is SIZE^3 over (-1,-1,-1)..(1,1,1)).
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u16).range(2..=512))]
    pub size: u16,
    /// Sample type in the file.
    #[arg(long = "type", value_enum, default_value = "u8")]
    pub sample_type: SampleType,
    /// The RTSLGRID file to write.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Kind {
    /// A noisy ball.
    Cloud,
    /// The potential of eight point charges, after the "neghip" protein data set.
    NeghipLike,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SampleType {
    U8,
    F32,
}

pub fn generate_cmd(args: &GenerateArgs) -> anyhow::Result<ExitCode> {
    let kind = match args.kind {
        Kind::Cloud => GridKind::Cloud,
        Kind::NeghipLike => GridKind::NeghipLike,
    };
    let ty = match args.sample_type {
        SampleType::U8 => GridType::U8,
        SampleType::F32 => GridType::F32,
    };
    let grid = generate(kind, args.size as usize).context("the size must be at least 2")?;
    let bytes = grid.to_bytes(ty);
    std::fs::write(&args.output, &bytes).with_context(|| format!("writing {}", args.output.display()))?;
    eprintln!("wrote {} ({} bytes, {}^3 samples)", args.output.display(), bytes.len(), args.size);
    Ok(ExitCode::SUCCESS)
}
