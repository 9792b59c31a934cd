//! Pixel filters through the engine: the default box 1x1 is the plain per-pixel mean, other
//! filters spread samples over neighbouring pixels, deterministically whatever the threads, under
//! adaptive sampling and crop windows, before the pixel shader and exposure; RIB `PixelFilter`.

mod common;

use common::{context, load, quad, FLAT, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Context};
use rtsl_runtime::render::{render_frame, Antialiasing, FilterKind, Framebuffer, PixelFilter};
use rtsl_runtime::shading::ParamValue;

fn filter(kind: FilterKind, width: f32) -> PixelFilter {
    PixelFilter::new(kind, width, width).expect("valid widths")
}

/// A white half-plane on the left of the image, black and empty on the right. The edge runs down
/// the boundary between columns 31 and 32 when `slant` is 0, and leans by `slant` (world units at
/// the top and bottom of the plane) otherwise.
fn edge_scene(slant: f32) -> Result<Context, ApiError> {
    let mut rt = context();
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let plane = rt.begin_object()?;
    rt.bind_shader(flat)?;
    quad(&mut rt, [[-20.0, -20.0, 0.0], [slant, -20.0, 0.0], [-slant, 20.0, 0.0], [-20.0, 20.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(plane)?;
    Ok(rt)
}

/// A lit floor and a cube under a point light (soft colours, shadows: a busy image).
fn lit_scene() -> Result<Context, ApiError> {
    let mut rt = context();
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    rt.camera_look_at(Vec3A::new(0.0, 4.0, 7.0), Vec3A::new(0.0, 0.5, 0.0), Vec3A::Y, 45.0);
    let floor = rt.begin_object()?;
    rt.bind_shader(plastic)?;
    quad(&mut rt, [[-5.0, 0.0, 5.0], [5.0, 0.0, 5.0], [5.0, 0.0, -5.0], [-5.0, 0.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
    let cube = rt.begin_object()?;
    rt.color(0.9, 0.3, 0.2);
    for [a, b, c, d] in [
        [[-1., -1., 1.], [1., -1., 1.], [1., 1., 1.], [-1., 1., 1.]],
        [[-1., 1., 1.], [1., 1., 1.], [1., 1., -1.], [-1., 1., -1.]],
        [[1., -1., 1.], [1., -1., -1.], [1., 1., -1.], [1., 1., 1.]],
        [[-1., -1., -1.], [-1., -1., 1.], [-1., 1., 1.], [-1., 1., -1.]],
    ] {
        quad(&mut rt, [a, b, c, d])?;
    }
    rt.end_object()?;
    rt.push_matrix();
    rt.translate(0.0, 1.0, 0.0);
    rt.scale(0.6, 0.6, 0.6);
    rt.instantiate_object(cube)?;
    rt.pop_matrix()?;
    rt.light_source(light, &[("intensity", ParamValue::Float(30.0)), ("from", ParamValue::Point([1.0, 5.0, 1.0]))])?;
    Ok(rt)
}

fn render_with_threads(rt: &mut Context, threads: usize) -> Result<Framebuffer, ApiError> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool");
    let world = rt.build_world()?;
    let (fb, _) = pool.install(|| render_frame(&world, None));
    rt.return_scene(world);
    Ok(fb)
}

/// Summed absolute difference of the RGB channels.
fn distance(a: &Framebuffer, b: &Framebuffer) -> f32 {
    a.rgba.chunks(4).zip(b.rgba.chunks(4)).map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).sum::<f32>()).sum()
}

#[test]
fn an_explicit_unit_box_is_the_default_bit_for_bit() -> Result<(), ApiError> {
    let mut rt = lit_scene()?;
    rt.options.samples = (2, 2);
    let (default, _) = rt.render_frame()?;
    rt.options.pixel_filter = filter(FilterKind::Box, 1.0);
    let (boxed, _) = rt.render_frame()?;
    assert!(default == boxed);
    // A box of any other size is a real filter: two pixels wide, it mixes neighbours.
    rt.options.pixel_filter = filter(FilterKind::Box, 2.0);
    let (wide, _) = rt.render_frame()?;
    assert!(distance(&wide, &default) > 0.1);
    Ok(())
}

#[test]
fn a_gaussian_blurs_a_sharp_edge_and_leaves_flat_regions_flat() -> Result<(), ApiError> {
    let mut rt = edge_scene(0.0)?;
    let (sharp, _) = rt.render_frame()?;
    for y in 0..H {
        assert_eq!(sharp.pixel(31, y), [1.0; 4], "row {y}: one sample at each pixel's centre");
        assert_eq!(sharp.pixel(32, y), [0.0; 4], "row {y}");
    }
    rt.options.pixel_filter = filter(FilterKind::Gaussian, 2.0);
    let (soft, _) = rt.render_frame()?;
    // Under a gaussian 2 wide (RISpec: exp(-2 (x^2 + y^2)), x and y in half widths), the column on
    // either side of the edge sees the other's samples at one pixel with weight exp(-2) against 1
    // for its own column and exp(-2) for the one beyond it, whatever the row (the weights are
    // separable).
    let e = (-2.0f32).exp();
    let expected = e / (1.0 + 2.0 * e);
    for y in 0..H {
        let (left, right) = (soft.pixel(31, y), soft.pixel(32, y));
        assert!((right[0] - expected).abs() < 1e-5, "row {y}: {right:?}, expected {expected}");
        assert!((left[0] - (1.0 - expected)).abs() < 1e-5, "row {y}: {left:?}");
        assert!((right[3] - expected).abs() < 1e-5, "alpha is filtered too: {right:?}");
        // Beyond the support the image is exactly what it was.
        for x in (0..31).chain(33..W) {
            assert_eq!(soft.pixel(x, y), sharp.pixel(x, y), "({x}, {y})");
        }
    }
    Ok(())
}

#[test]
fn filtered_images_do_not_depend_on_the_thread_count() -> Result<(), ApiError> {
    for (f, aa) in [
        (filter(FilterKind::Gaussian, 2.0), Antialiasing::Grid { jitter: true }),
        (filter(FilterKind::Mitchell, 4.0), Antialiasing::Adaptive { threshold: 0.05 }),
        (filter(FilterKind::CatmullRom, 3.0), Antialiasing::Interleaved),
    ] {
        let mut rt = lit_scene()?;
        rt.options.samples = (2, 2);
        rt.options.antialiasing = aa;
        let boxed = render_with_threads(&mut rt, 2)?;
        rt.options.pixel_filter = f;
        let images = [1, 2, 3].map(|threads| render_with_threads(&mut rt, threads));
        let [one, two, three] = images;
        let (one, two, three) = (one?, two?, three?);
        assert!(one == two && two == three, "{f:?}, {aa:?}");
        assert!(distance(&one, &boxed) > 0.1, "{f:?} filters");
    }
    Ok(())
}

#[test]
fn adaptive_sampling_splats_its_extra_samples_through_the_filter() -> Result<(), ApiError> {
    // A slanted edge: one sample at each pixel's centre aliases it; the reference is 64 jittered
    // samples a pixel, all under the same gaussian.
    let gaussian = filter(FilterKind::Gaussian, 2.0);
    let render = |aa: Antialiasing, samples: (u32, u32)| -> Result<Framebuffer, ApiError> {
        let mut rt = edge_scene(6.0)?;
        rt.options.pixel_filter = gaussian;
        rt.options.antialiasing = aa;
        rt.options.samples = samples;
        Ok(rt.render_frame()?.0)
    };
    let reference = render(Antialiasing::Grid { jitter: true }, (8, 8))?;
    let centres = render(Antialiasing::Grid { jitter: false }, (1, 1))?;
    // Adaptive sampling's first samples are the same centres; its extra ones (2x2 where a pixel
    // differs from a neighbour, along the edge) change the image only if they are splatted.
    let adaptive = render(Antialiasing::Adaptive { threshold: 0.05 }, (1, 1))?;
    let (before, after) = (distance(&centres, &reference), distance(&adaptive, &reference));
    assert!(after < 0.8 * before, "error against the reference: {after} adaptive, {before} without");
    // Away from the edge nothing is refined, and the image is that of the centres.
    for y in 0..H {
        assert_eq!(adaptive.pixel(0, y), centres.pixel(0, y));
        assert_eq!(adaptive.pixel(W - 1, y), centres.pixel(W - 1, y));
    }
    Ok(())
}

#[test]
fn a_crop_window_stays_empty_outside_and_filtered_inside() -> Result<(), ApiError> {
    let mut rt = edge_scene(6.0)?;
    rt.options.samples = (2, 2);
    rt.options.pixel_filter = filter(FilterKind::Gaussian, 2.0);
    let (whole, _) = rt.render_frame()?;
    rt.options.crop_window = Some([0.25, 0.75, 0.25, 0.75]);
    let (cropped, _) = rt.render_frame()?;
    let (x0, x1, y0, y1) = rt.options.pixel_range();
    assert_eq!((x0, x1, y0, y1), (16, 48, 12, 36));
    for y in 0..H {
        for x in 0..W {
            let p = cropped.pixel(x, y);
            if !((x0..x1).contains(&x) && (y0..y1).contains(&y)) {
                assert_eq!(p, [0.0; 4], "({x}, {y}) is outside the crop");
            } else if x > x0 && x + 1 < x1 && y > y0 && y + 1 < y1 {
                // Every sample within the filter's reach was rendered: as without the crop.
                assert_eq!(p, whole.pixel(x, y), "({x}, {y})");
            }
        }
    }
    Ok(())
}

#[test]
fn the_pixel_shader_and_exposure_see_the_filtered_colours() -> Result<(), ApiError> {
    let mut rt = edge_scene(0.0)?;
    rt.options.pixel_filter = filter(FilterKind::Gaussian, 2.0);
    let (plain, _) = rt.render_frame()?;
    let grey = plain.pixel(32, H / 2)[0];
    assert!(grey > 0.05 && grey < 0.95, "an edge pixel is grey: {grey}");
    // Squaring before filtering would leave the grey as it is (0 and 1 are their own squares).
    let square = rt.compile_shader("square.sl", "imager square() { Ci = Ci * Ci; }")?;
    rt.pixel_shader(Some(square), &[])?;
    let (squared, _) = rt.render_frame()?;
    rt.pixel_shader(None, &[])?;
    rt.options.exposure = Some((1.0, 2.0));
    let (exposed, _) = rt.render_frame()?;
    for (i, ((p, s), e)) in plain.rgba.chunks(4).zip(squared.rgba.chunks(4)).zip(exposed.rgba.chunks(4)).enumerate() {
        for c in 0..3 {
            assert_eq!(s[c], p[c] * p[c], "pixel {i} channel {c}");
            assert_eq!(e[c], p[c].max(0.0).powf(0.5), "pixel {i} channel {c}");
        }
        assert_eq!((s[3], e[3]), (p[3], p[3]));
    }
    Ok(())
}

/// A RIB scene with `options` before the camera: a white square on black.
fn rib_scene(options: &str) -> String {
    format!(
        "Format 64 48 1\n{options}\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n\
         Surface \"constant\" Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\nWorldEnd\n"
    )
}

#[test]
fn rib_pixel_filter_is_honoured() {
    let render = |rt: &mut Context| {
        let world = rt.build_world().expect("a world");
        let (fb, _) = render_frame(&world, None);
        rt.return_scene(world);
        fb
    };
    let (mut none, warnings) = load(&rib_scene(""));
    assert!(warnings.is_empty(), "{warnings:?}");
    let plain = render(&mut none);
    let (mut boxed, warnings) = load(&rib_scene("PixelFilter \"box\" 1 1"));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(render(&mut boxed) == plain, "box 1x1 is the default");
    let (mut gaussian, warnings) = load(&rib_scene("PixelSamples 2 2\nPixelFilter \"gaussian\" 2 2"));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(gaussian.options.pixel_filter, filter(FilterKind::Gaussian, 2.0));
    assert!(distance(&render(&mut gaussian), &plain) > 0.1, "the square's edges are softened");
    for kind in FilterKind::ALL {
        let (rt, warnings) = load(&rib_scene(&format!("PixelFilter \"{}\" 3 2", kind.name())));
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(rt.options.pixel_filter, PixelFilter::new(kind, 3.0, 2.0).expect("valid"));
    }
}

#[test]
fn bad_rib_pixel_filters_are_located_warnings() {
    // An unknown name: the default filter, whatever came before.
    let (rt, warnings) = load(&rib_scene("PixelFilter \"sinc\" 4 4\nPixelFilter \"nonsense\" 2 2"));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].starts_with("test.rib:3:1: warning: unknown pixel filter \"nonsense\""), "{warnings:?}");
    assert!(rt.options.pixel_filter.is_unit_box());
    // Widths that are not positive and at most 16: the filter stays as it was.
    let (rt, warnings) = load(&rib_scene("PixelFilter \"catmull-rom\" 4 4\nPixelFilter \"gaussian\" 0 2"));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].starts_with("test.rib:3:1: warning: filter widths 0 2"), "{warnings:?}");
    assert_eq!(rt.options.pixel_filter, filter(FilterKind::CatmullRom, 4.0));
    let (rt, warnings) = load(&rib_scene("PixelFilter \"box\" -1 1"));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(rt.options.pixel_filter.is_unit_box());
    // A huge width would take memory per tile in proportion to the image.
    let (rt, warnings) = load(&rib_scene("PixelFilter \"gaussian\" 1e9 2"));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("at most 16 pixels"), "{warnings:?}");
    assert!(rt.options.pixel_filter.is_unit_box());
}
