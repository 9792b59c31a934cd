//! The engine through its API: ray parameters. Shaders read the application's values with
//! `rayinfo` per pixel (regions, a gaze point, a callback's image), objects override them for the
//! rays that reach them and the rays those spawn, secondary rays inherit their pixel's, unknown
//! names are reported once, and relevance sets how many samples a pixel takes.

mod common;

use common::{context, load, quad, FLAT, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context, ShaderId};
use rtsl_runtime::render::{RayField, RayValue};

/// Shows ray parameter `q` as grey (`-1` where it is not found).
const SHOW: &str = "surface show() { float q = -1; rayinfo(\"q\", q); Oi = 1; Ci = q; }";

/// Shows what the mirrored direction sees.
const MIRROR: &str = "surface mirrored() { Oi = 1; Ci = trace(P, reflect(I, normalize(N))); }";

/// A quad filling the view at z = 0, shaded by `surface`, with the camera at z = 5.
fn facing_quad(rt: &mut Context, surface: ShaderId) -> Result<(), ApiError> {
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    let m = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(m)?;
    Ok(())
}

#[test]
fn shaders_read_the_frames_value_and_its_regions_per_pixel() -> Result<(), ApiError> {
    let mut rt = context();
    let show = rt.compile_shader("show.sl", SHOW)?;
    facing_quad(&mut rt, show)?;
    rt.set_ray_parameter("q", 0.25)?;
    let (fb, _) = rt.render_frame()?;
    assert!((fb.pixel(W / 2, H / 2)[0] - 0.25).abs() < 1e-6);

    // The left half reads 0.75; the names with `user:` are the same parameter.
    rt.set_ray_field("user:q", Some(RayField::Regions(vec![([0, 0, W / 2, H], 0.75.into())])))?;
    let (fb, report) = rt.render_frame()?;
    assert!((fb.pixel(2, H / 2)[0] - 0.75).abs() < 1e-6);
    assert!((fb.pixel(W - 3, H / 2)[0] - 0.25).abs() < 1e-6);
    assert!(report.shader_messages.is_empty(), "{:?}", report.shader_messages);
    Ok(())
}

#[test]
fn a_gaze_and_a_callback_vary_over_the_image() -> Result<(), ApiError> {
    let mut rt = context();
    let show = rt.compile_shader("show.sl", SHOW)?;
    facing_quad(&mut rt, show)?;
    rt.set_ray_parameter("q", 0.0)?;
    let centre = [W as f32 / 2.0, H as f32 / 2.0];
    rt.set_ray_field("q", Some(RayField::Gaze { centre, radius: 6.0, falloff: 10.0, inside: 1.0.into() }))?;
    let (fb, _) = rt.render_frame()?;
    let (near, mid, far) = (fb.pixel(W / 2, H / 2)[0], fb.pixel(W / 2 + 11, H / 2)[0], fb.pixel(1, 1)[0]);
    assert!((near - 1.0).abs() < 1e-6 && far.abs() < 1e-6, "{near} {far}");
    assert!(mid > 0.0 && mid < 1.0, "the falloff blends: {mid}");

    rt.set_ray_parameter_fn("q", |x, _| RayValue::Float(x as f32 / W as f32))?;
    let (fb, _) = rt.render_frame()?;
    assert!((fb.pixel(16, 5)[0] - 0.25).abs() < 1e-6);
    assert!((fb.pixel(48, 40)[0] - 0.75).abs() < 1e-6);
    Ok(())
}

#[test]
fn an_objects_value_holds_for_rays_reaching_it_and_the_rays_it_spawns() -> Result<(), ApiError> {
    let mut rt = context();
    let show = rt.compile_shader("show.sl", SHOW)?;
    let mirror = rt.compile_shader("mirrored.sl", MIRROR)?;
    rt.set_ray_parameter("q", 0.25)?;
    rt.set_ray_field("q", Some(RayField::Regions(vec![([0, 0, W / 2, H], 0.5.into())])))?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    // A mirror on the left half of the view, a shown quad on the right; behind the camera, a
    // shown wall that the mirror reflects.
    let left = rt.begin_object()?;
    rt.bind_shader(mirror)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [0.0, -10.0, 0.0], [0.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.push_attributes();
    rt.ray_attribute("q", Some(RayValue::Float(0.9)))?;
    let right = rt.begin_object()?;
    rt.bind_shader(show)?;
    quad(&mut rt, [[0.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [0.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.pop_attributes()?;
    let wall = rt.begin_object()?;
    rt.bind_shader(show)?;
    quad(&mut rt, [[-20.0, 20.0, 8.0], [20.0, 20.0, 8.0], [20.0, -20.0, 8.0], [-20.0, -20.0, 8.0]])?;
    rt.end_object()?;
    for o in [left, right, wall] {
        rt.instantiate_object(o)?;
    }
    let (fb, _) = rt.render_frame()?;
    // The right quad's own value, whatever the pixel's.
    assert!((fb.pixel(W - 3, H / 2)[0] - 0.9).abs() < 1e-6, "{:?}", fb.pixel(W - 3, H / 2));
    // The wall seen in the mirror reads the value of the pixel the reflected ray serves.
    assert!((fb.pixel(3, H / 2)[0] - 0.5).abs() < 1e-6, "{:?}", fb.pixel(3, H / 2));

    // A mirror that sets the value passes it to the rays it reflects.
    let mut rt2 = context();
    let show = rt2.compile_shader("show.sl", SHOW)?;
    let mirror = rt2.compile_shader("mirrored.sl", MIRROR)?;
    rt2.set_ray_parameter("q", 0.25)?;
    rt2.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    rt2.ray_attribute("q", Some(RayValue::Float(0.6)))?;
    let m = rt2.begin_object()?;
    rt2.bind_shader(mirror)?;
    quad(&mut rt2, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt2.end_object()?;
    rt2.ray_attribute("q", None)?;
    let wall = rt2.begin_object()?;
    rt2.bind_shader(show)?;
    quad(&mut rt2, [[-20.0, 20.0, 8.0], [20.0, 20.0, 8.0], [20.0, -20.0, 8.0], [-20.0, -20.0, 8.0]])?;
    rt2.end_object()?;
    rt2.instantiate_object(m)?;
    rt2.instantiate_object(wall)?;
    let (fb, _) = rt2.render_frame()?;
    assert!((fb.pixel(W / 2, H / 2)[0] - 0.6).abs() < 1e-6, "{:?}", fb.pixel(W / 2, H / 2));
    Ok(())
}

#[test]
fn an_unknown_name_keeps_the_variable_and_is_reported_once() -> Result<(), ApiError> {
    let mut rt = context();
    let show = rt.compile_shader("show.sl", SHOW)?;
    facing_quad(&mut rt, show)?;
    let (fb, report) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2)[0], -1.0, "the variable keeps its value");
    assert_eq!(report.shader_messages.len(), 1, "{:?}", report.shader_messages);
    assert!(report.shader_messages[0].contains("rayinfo(\"q\")"), "{:?}", report.shader_messages);
    let (_, report) = rt.render_frame()?;
    assert!(report.shader_messages.is_empty(), "once: {:?}", report.shader_messages);

    // "relevance" reads 1 where nothing sets it, without a report.
    let mut rt = context();
    let src = "surface rel() { float r = -1; rayinfo(\"relevance\", r); Oi = 1; Ci = r; }";
    let rel = rt.compile_shader("rel.sl", src)?;
    facing_quad(&mut rt, rel)?;
    let (fb, report) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2)[0], 1.0);
    assert!(report.shader_messages.is_empty(), "{:?}", report.shader_messages);
    Ok(())
}

#[test]
fn values_of_the_wrong_type_are_api_errors() -> Result<(), ApiError> {
    let mut rt = context();
    rt.set_ray_parameter("q", 0.5)?;
    assert!(matches!(rt.set_ray_parameter("q", RayValue::Color([1.0; 3])), Err(ApiError::RayParameter(_))));
    let colours = RayField::Regions(vec![([0, 0, 1, 1], RayValue::String("x".into()))]);
    assert!(matches!(rt.set_ray_field("q", Some(colours)), Err(ApiError::RayParameter(_))));
    assert!(matches!(rt.set_ray_field("never_set", None), Err(ApiError::RayParameter(_))));
    assert!(rt.set_ray_parameter_fn("q", |_, _| RayValue::String("x".into())).is_err());
    assert!(rt.ray_attribute("", Some(1.0.into())).is_err());
    // A colour parameter reads as a colour.
    rt.set_ray_parameter("tint", RayValue::Color([0.1, 0.2, 0.3]))?;
    let src = "surface tint() { color c = 0; rayinfo(\"tint\", c); Oi = 1; Ci = c; }";
    let tint = rt.compile_shader("tint.sl", src)?;
    facing_quad(&mut rt, tint)?;
    let (fb, _) = rt.render_frame()?;
    let p = fb.pixel(W / 2, H / 2);
    assert!((p[0] - 0.1).abs() < 1e-6 && (p[2] - 0.3).abs() < 1e-6, "{p:?}");
    Ok(())
}

#[test]
fn relevance_sets_how_many_samples_a_pixel_takes() -> Result<(), ApiError> {
    let mut rt = context();
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    rt.light_source(light, rtsl_runtime::params!["intensity" => 20.0, "from" => [0.0, 2.0, 4.0]])?;
    facing_quad(&mut rt, plastic)?;
    rt.options.samples = (4, 4);
    let (uniform, full) = rt.render_frame()?;
    assert_eq!(full.primary_rays, 16 * u64::from(W * H));
    // Full relevance in the left half, none on the right: 16 samples there, 1 here.
    rt.set_ray_parameter("relevance", 0.0)?;
    rt.set_ray_field("relevance", Some(RayField::Regions(vec![([0, 0, W / 2, H], 1.0.into())])))?;
    let (adapted, report) = rt.render_frame()?;
    assert_eq!(report.primary_rays, 16 * u64::from(W * H / 2) + u64::from(W * H / 2));
    for y in 0..H {
        for x in 0..W / 2 {
            assert_eq!(uniform.pixel(x, y), adapted.pixel(x, y), "the full-quality half is unchanged at {x}, {y}");
        }
    }
    // A quarter relevance takes 4 of the 16.
    rt.set_ray_field("relevance", None)?;
    rt.set_ray_parameter("relevance", 0.25)?;
    let (_, report) = rt.render_frame()?;
    assert_eq!(report.primary_rays, 4 * u64::from(W * H));
    Ok(())
}

#[test]
fn relevance_sets_how_many_samples_an_area_light_takes() -> Result<(), ApiError> {
    // A square area light (16 samples) over a floor, a sphere casting a soft shadow between.
    let rib =
        "Format 64 48 1\nProjection \"perspective\" \"fov\" 50\nTranslate 0 -0.5 4\nRotate -30 1 0 0\nWorldBegin\n\
        AttributeBegin\nAttribute \"light\" \"shadows\" \"on\"\nAreaLightSource \"arealight\" 1 \"intensity\" [6]\n\
        Polygon \"P\" [-0.6 2 -0.6  0.6 2 -0.6  0.6 2 0.6  -0.6 2 0.6]\nAttributeEnd\nIlluminate 1 1\n\
        Surface \"matte\"\nPolygon \"P\" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]\n\
        AttributeBegin\nTranslate 0 0.8 0\nSphere 0.4 -0.4 0.4 360\nAttributeEnd\nWorldEnd\n";
    let (mut rt, warnings) = load(rib);
    assert!(warnings.is_empty(), "{warnings:?}");
    let (full, full_report) = rt.render_frame()?;
    rt.set_ray_parameter("relevance", 0.125)?;
    rt.set_ray_field("relevance", Some(RayField::Regions(vec![([0, 0, W / 2, H], 1.0.into())])))?;
    let (adapted, report) = rt.render_frame()?;
    assert!(report.shadow_rays < full_report.shadow_rays, "{} {}", report.shadow_rays, full_report.shadow_rays);
    let (mut same, mut changed, mut sum_full, mut sum_adapted) = (true, 0, 0.0f32, 0.0f32);
    for y in 0..H {
        for x in 0..W {
            let (a, b) = (full.pixel(x, y), adapted.pixel(x, y));
            if x < W / 2 {
                same &= a == b;
            } else {
                changed += usize::from(a != b);
                sum_full += a[0];
                sum_adapted += b[0];
            }
        }
    }
    assert!(same, "where relevance is 1 the frame is the full-quality one");
    assert!(changed > 0, "two samples of sixteen change the soft shadow");
    let ratio = sum_adapted / sum_full;
    assert!((ratio - 1.0).abs() < 0.1, "fewer samples weigh more: the light is as bright ({ratio})");
    Ok(())
}

#[test]
fn the_library_reflectors_trace_less_where_relevance_is_low() -> Result<(), ApiError> {
    for name in ["mirror", "glossy", "glass"] {
        let mut rt = context();
        let surface = rt.find_shader(name)?;
        let flat = rt.compile_shader("flat.sl", FLAT)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
        let m = rt.begin_object()?;
        rt.bind_shader(surface)?;
        quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
        rt.end_object()?;
        // A green wall behind the camera, which the reflector shows.
        let wall = rt.begin_object()?;
        rt.bind_shader(flat)?;
        rt.parameter("c", rtsl_runtime::shading::ParamValue::Color([0.0, 1.0, 0.0]))?;
        quad(&mut rt, [[-30.0, 30.0, 8.0], [30.0, 30.0, 8.0], [30.0, -30.0, 8.0], [-30.0, -30.0, 8.0]])?;
        rt.end_object()?;
        rt.instantiate_object(m)?;
        rt.instantiate_object(wall)?;
        let (fb, full) = rt.render_frame()?;
        assert!(fb.pixel(W / 2, H / 2)[1] > 0.02, "{name} reflects the wall: {:?}", fb.pixel(W / 2, H / 2));
        rt.set_ray_parameter("relevance", 0.0)?;
        let (fb, low) = rt.render_frame()?;
        assert!(fb.pixel(W / 2, H / 2)[1] < 1e-6, "{name} at relevance 0 traces nothing: {:?}", fb.pixel(W / 2, H / 2));
        assert_eq!(low.secondary_rays, 0, "{name}: {} rays of {}", low.secondary_rays, full.secondary_rays);
    }
    Ok(())
}
