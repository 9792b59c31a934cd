//! `rtsl bench trace`: the command-line side of the tracer benchmark. Parses the flags into
//! [`rtsl_runtime::BenchOptions`], runs [`rtsl_runtime::run_bench`] and prints one `name: value`
//! line per figure.

use anyhow::Context as _;
use rtsl_runtime::{run_bench, BenchOptions, BuildQuality};
use std::path::PathBuf;

/// Flags of `rtsl bench trace`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchTraceArgs {
    /// The mesh to trace (OBJ or PLY).
    #[arg(long)]
    pub mesh: PathBuf,
    /// Camera position, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "0,130,-170")]
    pub eye: [f32; 3],
    /// Point the camera looks at, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,-53")]
    pub look: [f32; 3],
    /// Camera up vector, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 45.0)]
    pub fov: f32,
    /// Point light position, `X,Y,Z`.
    #[arg(long, value_parser = parse_vec3, default_value = "60,220,40")]
    pub light: [f32; 3],
    /// Image size, `WxH`.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Timed repetitions of each pass; the median is printed.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// BVH build quality: fast, medium, high or best.
    #[arg(long, value_parser = parse_quality, default_value = "high")]
    pub quality: BuildQuality,
    /// Passes to time, comma-separated: pp (primary packets), ps (primary single rays), sp (shadow
    /// packets), ss (shadow single rays). Passes left out print 0.
    #[arg(long, value_parser = parse_passes, default_value = "pp,ps,sp,ss")]
    pub passes: [bool; 4],
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers X,Y,Z, got `{s}`"));
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        let x: f32 = p.parse().map_err(|_| format!("`{p}` is not a number (in `{s}`)"))?;
        if !x.is_finite() {
            return Err(format!("`{p}` is not a finite number (in `{s}`)"));
        }
        *slot = x;
    }
    Ok(v)
}

pub(crate) fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) =
        s.split_once(['x', 'X']).ok_or_else(|| format!("expected an image size WxH such as 1024x768, got `{s}`"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("width `{w}` is not a positive integer"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("height `{h}` is not a positive integer"))?;
    if w == 0 || h == 0 {
        return Err(format!("image size `{s}` must be at least 1x1"));
    }
    Ok((w, h))
}

fn parse_passes(s: &str) -> Result<[bool; 4], String> {
    let mut on = [false; 4];
    for p in s.split(',').map(str::trim) {
        let i = ["pp", "ps", "sp", "ss"]
            .iter()
            .position(|&n| n == p)
            .ok_or_else(|| format!("unknown pass `{p}` (expected pp, ps, sp or ss)"))?;
        on[i] = true;
    }
    Ok(on)
}

fn parse_quality(s: &str) -> Result<BuildQuality, String> {
    match s {
        "fast" => Ok(BuildQuality::Fast),
        "medium" => Ok(BuildQuality::Medium),
        "high" => Ok(BuildQuality::High),
        "best" => Ok(BuildQuality::Best),
        _ => Err(format!("unknown build quality `{s}` (expected fast, medium, high or best)")),
    }
}

/// Runs `rtsl bench trace` and prints its report as `name: value` lines.
pub fn run_trace(args: &BenchTraceArgs) -> anyhow::Result<()> {
    let mut o = BenchOptions::new(&args.mesh);
    o.eye = args.eye.into();
    o.look = args.look.into();
    o.up = args.up.into();
    o.fov_deg = args.fov;
    o.light = args.light.into();
    (o.width, o.height) = args.size;
    o.threads = args.threads;
    o.repeats = args.repeats.max(1);
    o.quality = args.quality;
    o.passes = args.passes;
    let r = run_bench(&o).with_context(|| format!("benchmark of {} failed", args.mesh.display()))?;
    let per_tri = r.memory_bytes as f64 / r.triangles.max(1) as f64;
    println!("mesh: {}", args.mesh.display());
    println!("triangles: {}", r.triangles);
    println!("threads: {}", r.threads);
    println!("load_ms: {:.1}", r.load_ms);
    println!("build_ms: {:.1}", r.build_ms);
    println!("memory_bytes: {}", r.memory_bytes);
    println!("memory_bytes_per_triangle: {per_tri:.1}");
    println!("primary_rays: {}", r.primary_rays);
    println!("hits: {}", r.hits);
    println!("hit_distance_sum: {:.3}", r.hit_distance_sum);
    println!("shadow_rays: {}", r.hits);
    println!("occluded: {}", r.occluded);
    println!("packet_single_mismatches: {}", r.mismatches);
    println!("primary_packet_mrays: {:.2}", r.primary_packet_mrays);
    println!("primary_single_mrays: {:.2}", r.primary_single_mrays);
    println!("shadow_packet_mrays: {:.2}", r.shadow_packet_mrays);
    println!("shadow_single_mrays: {:.2}", r.shadow_single_mrays);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vectors_and_sizes() {
        assert_eq!(parse_vec3("1, 2,-3.5"), Ok([1.0, 2.0, -3.5]));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,x,2").unwrap_err().contains("`x`"));
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").is_err());
        assert!(parse_size("0x480").is_err());
        assert_eq!(parse_passes("ss,pp"), Ok([true, false, false, true]));
        assert!(parse_passes("pp,xx").is_err());
    }
}
