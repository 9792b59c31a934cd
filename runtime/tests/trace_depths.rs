//! The bounces rays may take beyond a surface (RenderMan's `Attribute "trace" "maxdiffusedepth"`
//! and `"maxspeculardepth"`; `TraceDepths`): `trace()` rays take specular bounces and
//! `indirectdiffuse()` rays diffuse ones, each bounded apart from the other and from the ray depth;
//! RIB files get PRMan's bounds (1 and 2), the API none; shaders read them with `attribute()` and
//! the bounces taken with `rayinfo()`.

mod common;

use common::{context, cube, quad, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::rib::load::load_str;
use std::path::Path;

const MIRROR: &str = "surface mirrored() { Oi = 1; Ci = 0.5 * trace(P, reflect(I, normalize(N))); }";

/// Glows 0.1 and gives back half of what reaches its front over the hemisphere, four rays a point.
const BOUNCE: &str =
    "surface bounce() { Oi = 1; Ci = 0.1 + 0.5 * indirectdiffuse(P, faceforward(normalize(N), I), 4); }";

/// One object shaded by `shader` and made by `geometry`, seen from `eye` toward `look`, rays 6
/// deep at most; `depths` sets the bounces before it is built.
fn one_object(
    shader: &str,
    (eye, look): (Vec3A, Vec3A),
    geometry: impl FnOnce(&mut Context) -> Result<(), ApiError>,
    depths: impl FnOnce(&mut Context),
) -> Result<Context, ApiError> {
    let mut rt = context();
    let id = rt.compile_shader("object.sl", shader)?;
    rt.options.max_ray_depth = 6;
    rt.camera_look_at(eye, look, Vec3A::Y, 30.0);
    depths(&mut rt);
    let m = rt.begin_object()?;
    rt.bind_shader(id)?;
    geometry(&mut rt)?;
    rt.end_object()?;
    rt.instantiate_object(m)?;
    Ok(rt)
}

/// The camera between two facing quads, wide enough that every ray between them meets one,
/// shaded by `shader`.
fn between_facing_quads(shader: &str, depths: impl FnOnce(&mut Context)) -> Result<Context, ApiError> {
    let quads = |rt: &mut Context| {
        let far = 1000.0;
        quad(rt, [[-far, -far, 0.0], [far, -far, 0.0], [far, far, 0.0], [-far, far, 0.0]])?;
        quad(rt, [[-far, far, 8.0], [far, far, 8.0], [far, -far, 8.0], [-far, -far, 8.0]])
    };
    one_object(shader, (Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO), quads, depths)
}

#[test]
fn trace_rays_stop_at_the_specular_bounces_whatever_the_batching() -> Result<(), ApiError> {
    let pixels = u64::from(W * H);
    for (bounces, rays) in [(Some(0), 0), (Some(1), 1), (Some(2), 2), (Some(4), 4), (None, 6)] {
        let mut rt = between_facing_quads(MIRROR, |rt| {
            if let Some(n) = bounces {
                rt.max_specular_depth(n);
            }
        })?;
        let (ahead, report) = rt.render_frame()?;
        // Every camera ray meets a mirror, and each reflection the other one, until the bound
        // (or, unbounded, the ray depth) ends the chain.
        assert_eq!(report.secondary_rays, rays * pixels, "{bounces:?}: {report}");
        rt.options.trace_ahead = false;
        let (chunked, chunked_report) = rt.render_frame()?;
        assert_eq!(chunked_report.secondary_rays, rays * pixels, "{bounces:?}: {chunked_report}");
        assert!(ahead == chunked, "{bounces:?}: tracing ahead changes no pixel");
        // The diffuse bound does not stop specular rays.
        let mut rt = between_facing_quads(MIRROR, |rt| {
            rt.max_diffuse_depth(0);
            if let Some(n) = bounces {
                rt.max_specular_depth(n);
            }
        })?;
        assert_eq!(rt.render_frame()?.1.secondary_rays, rays * pixels);
    }
    Ok(())
}

/// The camera inside a closed box shaded with `BOUNCE`, so that every ray meets a wall.
fn inside_a_box(depths: impl FnOnce(&mut Context)) -> Result<Context, ApiError> {
    one_object(BOUNCE, (Vec3A::new(0.0, 0.0, 0.5), Vec3A::new(0.0, 0.0, -1.0)), cube, depths)
}

#[test]
fn indirectdiffuse_stops_at_the_diffuse_bounces() -> Result<(), ApiError> {
    let pixels = u64::from(W * H);
    let frame = |diffuse: u32, specular: Option<u32>| -> Result<_, ApiError> {
        let mut rt = inside_a_box(|rt| {
            rt.max_diffuse_depth(diffuse);
            if let Some(s) = specular {
                rt.max_specular_depth(s);
            }
        })?;
        rt.render_frame()
    };
    // No bounce: direct light only, which here is the glow.
    let (none, report) = frame(0, None)?;
    assert_eq!(report.secondary_rays, 0);
    let p = none.pixel(W / 2, H / 2);
    assert!((p[0] - 0.1).abs() < 1e-6, "{p:?}");
    // One: each camera hit's four rays, whose hits spawn none; they bring back their glow.
    let (one, report) = frame(1, None)?;
    assert_eq!(report.secondary_rays, 4 * pixels, "{report}");
    let p = one.pixel(W / 2, H / 2);
    assert!((p[0] - 0.15).abs() < 1e-5, "0.1 + 0.5 x 0.1: {p:?}");
    // Two: their hits spawn four each, and a second bounce's light comes back.
    let (two, report) = frame(2, None)?;
    assert_eq!(report.secondary_rays, 20 * pixels, "{report}");
    assert!(two.pixel(W / 2, H / 2)[0] > p[0] + 0.02);
    // The specular bound does not stop diffuse rays.
    assert_eq!(frame(2, Some(0))?.1.secondary_rays, 20 * pixels);
    Ok(())
}

/// A RIB scene: the camera between two facing mirrors `Surface "mirrored"`, after `attributes`.
fn mirrors_rib(attributes: &str) -> String {
    format!(
        "Format {W} {H} 1 Projection \"perspective\" \"fov\" 30 Translate 0 0 5
         WorldBegin
         {attributes}
         Surface \"mirrored\"
         Polygon \"P\" [-1000 -1000 0  1000 -1000 0  1000 1000 0  -1000 1000 0]
         Polygon \"P\" [-1000 1000 -8  1000 1000 -8  1000 -1000 -8  -1000 -1000 -8]
         WorldEnd"
    )
}

/// `rib` loaded into a context that has compiled `shaders` (name, source), with the load's
/// warnings.
fn load_with(shaders: &[(&str, &str)], rib: &str) -> Result<(Context, Vec<String>), ApiError> {
    let mut rt = Context::new();
    for (name, source) in shaders {
        rt.compile_shader(&format!("{name}.sl"), source)?;
    }
    let loaded = load_str(&mut rt, rib, Path::new("bounces.rib")).unwrap_or_else(|e| panic!("{e}"));
    Ok((rt, loaded.warnings.iter().map(ToString::to_string).collect()))
}

#[test]
fn rib_files_get_prmans_bounds_and_set_their_own() -> Result<(), ApiError> {
    let pixels = u64::from(W * H);
    for (attributes, rays) in [
        ("", 2),
        ("Attribute \"trace\" \"maxspeculardepth\" [4]", 4),
        ("Attribute \"trace\" \"int maxspeculardepth\" [1]", 1),
        ("Option \"trace\" \"maxdepth\" [3] Attribute \"trace\" \"maxspeculardepth\" [9]", 3),
    ] {
        let (mut rt, warnings) = load_with(&[("mirrored", MIRROR)], &mirrors_rib(attributes))?;
        assert!(warnings.is_empty(), "{warnings:?}");
        let (_, report) = rt.render_frame()?;
        assert_eq!(report.secondary_rays, rays * pixels, "{attributes}: {report}");
    }
    Ok(())
}

#[test]
fn shaders_read_the_bounds_and_the_bounces_taken() -> Result<(), ApiError> {
    // The bound its own object has, a tenth of it in red.
    let bound = "surface bound() { float d = -1; attribute(\"trace:maxspeculardepth\", d); \
                 float e = -1; attribute(\"trace:maxdiffusedepth\", e); Ci = color(d / 10, e / 10, 0); }";
    let rib = |attributes: &str| {
        format!(
            "Format 4 4 1 Projection \"perspective\" \"fov\" 30 Translate 0 0 5 WorldBegin {attributes}
             Surface \"bound\" Polygon \"P\" [-9 -9 0  9 -9 0  9 9 0  -9 9 0] WorldEnd"
        )
    };
    for (attributes, expected) in [("", [0.2, 0.1]), ("Attribute \"trace\" \"maxspeculardepth\" [5]", [0.5, 0.1])] {
        let (mut rt, _) = load_with(&[("bound", bound)], &rib(attributes))?;
        let (fb, _) = rt.render_frame()?;
        let p = fb.pixel(2, 2);
        assert!((p[0] - expected[0]).abs() < 1e-6 && (p[1] - expected[1]).abs() < 1e-6, "{attributes}: {p:?}");
    }
    // A wall seen in a mirror shows the specular bounces its ray took (one), and none diffuse.
    let taken = "surface taken() { float s = -1; rayinfo(\"speculardepth\", s); \
                 float d = -1; rayinfo(\"diffusedepth\", d); Oi = 1; Ci = color(s, d, 0); }";
    let rib = "Format 4 4 1 Projection \"perspective\" \"fov\" 30 Translate 0 0 5 WorldBegin
         Surface \"mirrored\" Polygon \"P\" [-9 -9 0  9 -9 0  9 9 0  -9 9 0]
         Surface \"taken\" Polygon \"P\" [-99 99 -8  99 99 -8  99 -99 -8  -99 -99 -8]
         WorldEnd";
    let (mut rt, warnings) = load_with(&[("mirrored", MIRROR), ("taken", taken)], rib)?;
    assert!(warnings.is_empty(), "{warnings:?}");
    let (fb, _) = rt.render_frame()?;
    let p = fb.pixel(2, 2);
    assert!((p[0] - 0.5).abs() < 1e-6 && p[1] == 0.0, "half of (1, 0): {p:?}");
    Ok(())
}

#[test]
fn a_bad_bound_is_a_warning_and_changes_nothing() -> Result<(), ApiError> {
    let pixels = u64::from(W * H);
    for bad in ["[-1]", "\"many\""] {
        let attributes = format!("Attribute \"trace\" \"maxspeculardepth\" {bad}");
        let (mut rt, warnings) = load_with(&[("mirrored", MIRROR)], &mirrors_rib(&attributes))?;
        assert_eq!(warnings.len(), 1, "{bad}: {warnings:?}");
        assert!(warnings[0].contains("maxspeculardepth"), "{warnings:?}");
        let (_, report) = rt.render_frame()?;
        assert_eq!(report.secondary_rays, 2 * pixels, "{bad}: PRMan's bound stays");
    }
    Ok(())
}

/// Under instant radiosity `indirectdiffuse()` gathers virtual lights instead of tracing rays, and
/// the bound still holds: with no diffuse bounce a surface gets no indirect light.
#[test]
fn virtual_lights_are_a_diffuse_bounce_too() -> Result<(), ApiError> {
    let rib = |attributes: &str| {
        format!(
            "Format 16 12 1 Projection \"perspective\" \"fov\" 60
             Option \"gi\" \"integer virtuallights\" [64]
             Translate 0 0 2.6
             WorldBegin
             Attribute \"light\" \"shadows\" \"on\"
             LightSource \"pointlight\" 1 \"intensity\" [2] \"from\" [0 0.8 0]
             {attributes}
             Surface \"bounce\"
             Polygon \"P\" [-1 -1 -1  1 -1 -1  1 -1 1  -1 -1 1]
             Polygon \"P\" [-1 1 -1  -1 1 1  1 1 1  1 1 -1]
             Polygon \"P\" [-1 -1 1  1 -1 1  1 1 1  -1 1 1]
             WorldEnd"
        )
    };
    let glow_only = |attributes: &str| -> Result<bool, ApiError> {
        let (mut rt, warnings) = load_with(&[("bounce", BOUNCE)], &rib(attributes))?;
        assert!(warnings.is_empty(), "{warnings:?}");
        let (fb, _) = rt.render_frame()?;
        Ok(fb.rgba.chunks_exact(4).all(|p| p[3] == 0.0 || (p[0] - 0.1).abs() < 1e-6))
    };
    assert!(glow_only("Attribute \"trace\" \"maxdiffusedepth\" [0]")?);
    assert!(!glow_only("")?, "one bounce: the virtual lights add light");
    Ok(())
}
