//! The engine through its API: frames. Images that depend neither on the thread count nor on shader
//! timing, shaders bound when a frame is rendered, typed errors for misuse, adaptive sampling,
//! incremental rebuilds (a moved instance, an edited object) and materials reused between frames.

mod common;

use common::{context, cube, quad, shadow_scene, FLAT, H, W};
use glam::Vec3A;
use rtsl_runtime::api::{ApiError, Primitive};
use rtsl_runtime::render::Framebuffer;
use rtsl_runtime::shading::{ParamError, ParamValue, ShaderProgram};

#[test]
fn the_image_does_not_depend_on_the_thread_count() -> Result<(), ApiError> {
    let mut rt = context();
    shadow_scene(&mut rt)?;
    let mut images = Vec::new();
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool");
        let world = rt.build_world()?;
        let (fb, _) = pool.install(|| rtsl_runtime::render::render_frame(&world, None));
        rt.return_scene(world);
        images.push(fb);
    }
    assert!(images.windows(2).all(|w| w[0] == w[1]));
    Ok(())
}

#[test]
fn shader_timing_can_be_turned_off_without_changing_the_image() -> Result<(), ApiError> {
    use rtsl_compiler::interface::ShaderKind;
    let mut rt = context();
    shadow_scene(&mut rt)?;
    let (timed_image, timed) = rt.render_frame()?;
    assert!(timed.shading > std::time::Duration::ZERO, "{timed}");
    assert!(timed.shader_time(ShaderKind::Surface) > std::time::Duration::ZERO, "{timed}");
    assert!(!timed.by_shader.is_empty());
    rt.options.time_shaders = false;
    let (untimed_image, untimed) = rt.render_frame()?;
    assert_eq!(untimed.shading, std::time::Duration::ZERO, "{untimed}");
    assert!(untimed.by_kind.iter().all(|t| t.is_zero()), "{untimed}");
    assert!(untimed.by_shader.is_empty());
    assert_eq!((untimed.primary_rays, untimed.shadow_rays), (timed.primary_rays, timed.shadow_rays));
    assert!(untimed_image == timed_image);
    // Timing comes back with the option: nothing of the untimed frame stays switched off.
    rt.options.time_shaders = true;
    assert!(rt.render_frame()?.1.shader_time(ShaderKind::Surface) > std::time::Duration::ZERO);
    Ok(())
}

#[test]
fn frames_bind_shaders_when_rendered() -> Result<(), ApiError> {
    let mut rt = context();
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let o = rt.begin_object()?;
    rt.bind_shader(flat)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    let inst = rt.instantiate_object(o)?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2), [1.0; 4]);
    // Same id, new code: the next frame uses it.
    let half = ShaderProgram::from_source("flat.sl", "surface flat(color c = 1;) { Oi = 1; Ci = 0.5 * c; }", &[])?;
    rt.replace_shader(flat, half)?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2), [0.5, 0.5, 0.5, 1.0]);
    // A moved instance moves in the next frame.
    rt.set_instance_transform(inst, glam::Affine3A::from_translation(glam::Vec3::new(100.0, 0.0, 0.0)))?;
    let (fb, _) = rt.render_frame()?;
    assert_eq!(fb.pixel(W / 2, H / 2), [0.0; 4]);
    Ok(())
}

#[test]
fn misuse_is_a_typed_error() -> Result<(), ApiError> {
    let mut rt = context();
    assert!(matches!(rt.end(), Err(ApiError::Unbalanced(..))));
    assert!(matches!(rt.end_object(), Err(ApiError::Unbalanced(..))));
    assert!(matches!(rt.vertex(0.0, 0.0, 0.0), Err(ApiError::Unbalanced(..))));
    assert!(matches!(rt.begin(Primitive::Triangles), Err(ApiError::NoObject(_))));
    assert!(matches!(rt.pop_matrix(), Err(ApiError::MatrixStackEmpty)));
    assert!(matches!(rt.parameter("Kd", ParamValue::Float(1.0)), Err(ApiError::NoShaderBound(_))));
    assert!(matches!(rt.instantiate_object(rtsl_runtime::api::ObjectId(7)), Err(ApiError::UnknownObject(7))));
    assert!(matches!(rt.bind_shader(rtsl_runtime::api::ShaderId(3)), Err(ApiError::UnknownShader(3))));
    let plastic = rt.find_shader("plastic")?;
    let light = rt.find_shader("pointlight")?;
    assert!(matches!(rt.bind_shader(light), Err(ApiError::WrongKind { .. })));
    assert!(matches!(rt.light_source(plastic, &[]), Err(ApiError::WrongKind { .. })));
    rt.bind_shader(plastic)?;
    assert!(matches!(
        rt.parameter("Kd", ParamValue::String("x".into())),
        Err(ApiError::Param(ParamError::TypeMismatch { .. }))
    ));
    assert!(matches!(
        rt.parameter("nonsense", ParamValue::Float(1.0)),
        Err(ApiError::Param(ParamError::NoSuchParameter { .. }))
    ));
    assert!(matches!(rt.vertex_parameter("Kd", ParamValue::Float(1.0)), Err(ApiError::NotVarying { .. })));
    rt.begin_object()?;
    assert!(matches!(rt.begin_object(), Err(ApiError::Nested(..))));
    rt.begin(Primitive::Triangles)?;
    rt.vertex(0.0, 0.0, 0.0)?;
    rt.vertex(1.0, 0.0, 0.0)?;
    assert!(matches!(rt.end(), Err(ApiError::IncompletePrimitive(2, _))));
    assert!(matches!(rt.render_frame(), Err(ApiError::Nested(..))));
    rt.end_object()?;
    assert!(matches!(rt.find_shader("no_such_shader"), Err(ApiError::Shader(_))));
    assert!(matches!(rt.compile_shader("bad.sl", "surface bad( { }"), Err(ApiError::Shader(_))));
    Ok(())
}

#[test]
fn adaptive_sampling_adds_rays_only_where_neighbours_differ() -> Result<(), ApiError> {
    use rtsl_runtime::render::Antialiasing;
    let render = |aa: Antialiasing, samples: (u32, u32)| -> Result<(Framebuffer, u64), ApiError> {
        let mut rt = context();
        let flat = rt.compile_shader("flat.sl", FLAT)?;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 60.0);
        let o = rt.begin_object()?;
        rt.bind_shader(flat)?;
        // A square tilted in the image, so its edges cut pixels.
        rt.rotate(20.0, 0.0, 0.0, 1.0);
        quad(&mut rt, [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])?;
        rt.end_object()?;
        rt.load_identity();
        rt.instantiate_object(o)?;
        rt.options.samples = samples;
        rt.options.antialiasing = aa;
        let (fb, report) = rt.render_frame()?;
        Ok((fb, report.primary_rays))
    };
    let (one, one_rays) = render(Antialiasing::Grid { jitter: true }, (1, 1))?;
    let (_, grid_rays) = render(Antialiasing::Grid { jitter: true }, (2, 2))?;
    let (adaptive, adaptive_rays) = render(Antialiasing::Adaptive { threshold: 0.05 }, (2, 2))?;
    assert_eq!(one_rays, u64::from(W * H));
    assert_eq!(grid_rays, 4 * u64::from(W * H));
    assert!(adaptive_rays > one_rays && adaptive_rays < grid_rays / 2, "{adaptive_rays} rays");
    let mut edge_pixels = 0;
    for i in 0..(W * H) as usize {
        let (a, b) = (&one.rgba[4 * i..4 * i + 4], &adaptive.rgba[4 * i..4 * i + 4]);
        if a != b {
            edge_pixels += 1;
            // A refined pixel changed only because its samples disagree: it is partly covered.
            assert!(b[3] > 0.0 && b[3] < 1.0, "{a:?} -> {b:?}");
        }
    }
    assert!(edge_pixels > 0 && edge_pixels < (W * H / 4) as usize, "{edge_pixels} pixels refined");
    // Inside the square and in the empty corners, nothing changed.
    assert_eq!(adaptive.pixel(W / 2, H / 2), one.pixel(W / 2, H / 2));
    assert_eq!(adaptive.pixel(0, 0), one.pixel(0, 0));

    // Interleaved sampling: every sample within its pixel, neighbours on different points.
    let (inter, _) = render(Antialiasing::Interleaved, (2, 2))?;
    assert_eq!(inter.pixel(W / 2, H / 2), [1.0; 4]);
    assert!(Antialiasing::parse("adaptive:0.1") == Ok(Antialiasing::Adaptive { threshold: 0.1 }));
    assert!(Antialiasing::parse("qmc") == Ok(Antialiasing::Interleaved));
    assert!(Antialiasing::parse("adaptive:x").is_err() && Antialiasing::parse("fancy").is_err());
    Ok(())
}

#[test]
fn adaptive_sampling_refines_on_what_the_application_names() -> Result<(), ApiError> {
    use rtsl_runtime::render::{Antialiasing, RefineOn};
    // Two quads of one colour side by side (two objects, two materials), shaded by a shader with
    // an output that steps across the left quad. (Neither edge is on a tile's border: a pixel is
    // compared with its neighbours in its tile.)
    let mut rt = context();
    let src = "surface stepped(output varying float mask = 0;) { mask = xcomp(P) < -1 ? 1 : 0; Oi = 1; Ci = 0.5; }";
    let stepped = rt.compile_shader("stepped.sl", src)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    for (x0, x1) in [(-10.0, 0.3), (0.3, 10.0)] {
        let o = rt.begin_object()?;
        rt.bind_shader(stepped)?;
        quad(&mut rt, [[x0, -10.0, 0.0], [x1, -10.0, 0.0], [x1, 10.0, 0.0], [x0, 10.0, 0.0]])?;
        rt.end_object()?;
        rt.instantiate_object(o)?;
    }
    rt.options.antialiasing = Antialiasing::Adaptive { threshold: 0.05 };
    let mut rays = |on: &str| -> Result<u64, ApiError> {
        rt.options.refine_on = RefineOn::parse(on).expect("a list");
        Ok(rt.render_frame()?.1.primary_rays)
    };
    let one = u64::from(W * H);
    // One colour everywhere: colour alone refines nothing.
    assert_eq!(rays("color")?, one);
    // The seam between the objects (and their materials) is a column of pixels each side.
    let (object, shader) = (rays("object")?, rays("shader")?);
    assert!(object > one && object == shader, "{object} {shader}");
    assert_eq!(object - one, 2 * u64::from(H) * 4, "two columns of 2x2 extra samples");
    // The output's step is another column, on the left quad only.
    let output = rays("output:mask")?;
    assert_eq!(output - one, 2 * u64::from(H) * 4, "{output}");
    assert_eq!(rays("object,output:mask")?, one + 4 * u64::from(H) * 4);
    // A viewer's passes refine on the output's mean as the accumulator keeps it: the second pass
    // samples the two columns beside the step again, and nothing for colour alone.
    let mut second_pass_rays = |on: &str| -> Result<u64, ApiError> {
        use rtsl_runtime::render::progressive::render_progressive;
        rt.options.refine_on = RefineOn::parse(on).expect("a list");
        let world = rt.build_world()?;
        let rays = render_progressive(&world, 2).1.primary_rays - render_progressive(&world, 1).1.primary_rays;
        rt.return_scene(world);
        Ok(rays)
    };
    assert_eq!(second_pass_rays("color")?, 0);
    assert_eq!(second_pass_rays("output:mask")?, 2 * u64::from(H));
    assert!(RefineOn::parse("").is_err() && RefineOn::parse("depth").is_err() && RefineOn::parse("output:").is_err());
    Ok(())
}

#[test]
fn a_frame_keeps_the_output_variables_it_names_as_pixel_means() -> Result<(), ApiError> {
    // An output that is 1 on the left of x = 0.3 and a colour that is u: each pixel's mean.
    let mut rt = context();
    let src = "surface aov(output varying float mask = 0; output varying color tint = 0;) \
               { mask = xcomp(P) < 0.3 ? 1 : 0; tint = color(u, v, 0.25); Oi = 1; Ci = 0.5; }";
    let aov = rt.compile_shader("aov.sl", src)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    let o = rt.begin_object()?;
    rt.bind_shader(aov)?;
    quad(&mut rt, [[-1.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-1.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    rt.options.outputs = vec!["mask".into(), "tint".into(), "nosuch".into()];
    rt.options.samples = (4, 4);
    let (fb, _) = rt.render_frame()?;
    let (mask, tint) = (fb.output("mask").expect("kept"), fb.output("tint").expect("kept"));
    let at = |x: u32, y: u32| (y * W + x) as usize;
    assert_eq!(mask[at(2, H / 2)], [0.0; 3], "nothing hit on the far left");
    assert_eq!(mask[at(20, H / 2)], [1.0, 0.0, 0.0], "a float in the first component");
    assert_eq!(mask[at(W - 2, H / 2)], [0.0; 3]);
    let edge: Vec<f32> = (0..W).map(|x| mask[at(x, H / 2)][0]).filter(|m| *m > 0.0 && *m < 1.0).collect();
    assert!(!edge.is_empty(), "pixels on the step average their samples");
    assert!((tint[at(W - 2, H / 2)][2] - 0.25).abs() < 1e-6, "{:?}", tint[at(W - 2, H / 2)]);
    assert_eq!(fb.output("nosuch").expect("kept")[at(W - 2, H / 2)], [0.0; 3], "no such output reads 0");
    assert!(fb.output("Ci").is_none(), "only what the options name");
    Ok(())
}

#[test]
fn displacement_shaders_report_their_runtime_messages_like_the_others() -> Result<(), ApiError> {
    // An index past the end of an array is clamped at run time and reported once, by shader name.
    let mut rt = context();
    let src = "displacement past() { float a[2] = {1, 2}; float i = 5 + u; N = N * a[i]; }";
    let past = rt.compile_shader("past.sl", src)?;
    let surface = rt.compile_shader("flat.sl", FLAT)?;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 5.0), Vec3A::ZERO, Vec3A::Y, 30.0);
    rt.displacement(Some(past), &[])?;
    let o = rt.begin_object()?;
    rt.bind_shader(surface)?;
    quad(&mut rt, [[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(o)?;
    let (_, report) = rt.render_frame()?;
    assert!(
        report.shader_messages.iter().any(|m| m.starts_with("shader past:")),
        "the displacement shader's message: {:?}",
        report.shader_messages
    );
    Ok(())
}

#[test]
fn a_moved_instance_costs_only_the_top_level_and_an_edited_object_only_its_own_bvh() -> Result<(), ApiError> {
    let mut rt = context();
    rt.camera_look_at(Vec3A::new(0.0, 2.0, 8.0), Vec3A::ZERO, Vec3A::Y, 45.0);
    let boxy = rt.begin_object()?;
    cube(&mut rt)?;
    rt.end_object()?;
    let floor = rt.begin_object()?;
    quad(&mut rt, [[-5.0, -1.0, 5.0], [5.0, -1.0, 5.0], [5.0, -1.0, -5.0], [-5.0, -1.0, -5.0]])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;
    let moving = rt.instantiate_object(boxy)?;
    rt.instantiate_object(boxy)?;

    let (_, first) = rt.render_frame()?;
    assert_eq!(first.accel.objects_rebuilt, 2, "both objects are built once");
    assert_eq!(first.accel.instances, 3);
    assert!(first.accel.memory_bytes > 0);

    rt.set_instance_transform(moving, glam::Affine3A::from_translation(glam::Vec3::new(2.0, 0.0, 0.0)))?;
    let (_, moved) = rt.render_frame()?;
    assert_eq!(moved.accel.objects_rebuilt, 0, "moving an instance rebuilds no object BVH");
    assert_eq!(moved.accel.instances, 3);

    rt.redefine_object(floor)?;
    quad(&mut rt, [[-6.0, -1.0, 6.0], [6.0, -1.0, 6.0], [6.0, -1.0, -6.0], [-6.0, -1.0, -6.0]])?;
    rt.end_object()?;
    let (_, edited) = rt.render_frame()?;
    assert_eq!(edited.accel.objects_rebuilt, 1, "only the edited object");
    assert_eq!(edited.accel.memory_bytes, moved.accel.memory_bytes, "same size of geometry");
    assert!(edited.to_string().contains("BVH update"), "{edited}");
    Ok(())
}

#[test]
fn frames_reuse_unchanged_materials_and_rebuild_them_for_a_new_program() -> Result<(), Box<dyn std::error::Error>> {
    const FLAT: &str = "surface flat(float k = 1;) { Oi = 1; Ci = k; }";
    let mut rt = context();
    let flat = rt.compile_shader("flat.sl", FLAT)?;
    rt.bind_shader(flat)?;
    rt.parameter("k", ParamValue::Float(0.5))?;
    let object = rt.begin_object()?;
    quad(&mut rt, [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])?;
    rt.end_object()?;
    rt.instantiate_object(object)?;
    let surface = |world: &rtsl_runtime::render::World| world.materials.get(1).and_then(|m| m.surface.clone());
    let first = rt.build_world()?;
    let built = surface(&first).ok_or("the object's material")?;
    rt.return_scene(first);
    let second = rt.build_world()?;
    let reused = surface(&second).ok_or("the object's material")?;
    rt.return_scene(second);
    assert!(std::sync::Arc::ptr_eq(&built, &reused), "nothing changed: the same shader instance");
    let program = ShaderProgram::from_source("flat.sl", "surface flat(float k = 1;) { Oi = 1; Ci = 2 * k; }", &[])?;
    rt.replace_shader(flat, program)?;
    let third = rt.build_world()?;
    let rebuilt = surface(&third).ok_or("the object's material")?;
    assert!(!std::sync::Arc::ptr_eq(&built, &rebuilt), "a new program: a new shader instance");
    assert!(!std::sync::Arc::ptr_eq(&built.program, &rebuilt.program));
    assert_eq!(rebuilt.params.len(), 1, "k stays bound");
    Ok(())
}

/// Contexts sharing a BVH store (`Context::share_bvhs`, as the frames of a RIB animation do) build
/// the BVH of each geometry once: a frame that declares the same meshes again (moved or not) takes
/// the earlier frame's BVHs, a mesh whose vertices changed builds its own, and every frame's
/// image is bit for bit the one rendered without the store.
#[test]
fn contexts_sharing_a_bvh_store_build_each_geometry_once() -> Result<(), Box<dyn std::error::Error>> {
    use rtsl_runtime::accel::store::BvhStore;
    use std::sync::Arc;
    let frame = |turn: f32, top: f32| {
        format!(
            r#"
            Format 24 18 1
            Projection "perspective" "fov" 45
            Translate 0 0 5
            Rotate {turn} 0 1 0
            WorldBegin
            LightSource "pointlight" 1 "intensity" [20] "from" [2 3 -4]
            Attribute "light" "shadows" "on"
            Surface "plastic"
            PointsPolygons [3 3] [0 1 2 0 2 3] "P" [-2 -1 -2  2 -1 -2  2 -1 2  -2 -1 2]
            AttributeBegin
              Translate {turn} 0 0
              Sphere 0.7 -0.7 0.7 360
            AttributeEnd
            PointsPolygons [3] [0 1 2] "P" [-1 0 1  1 0 1  0 {top} 1]
            WorldEnd
        "#
        )
    };
    let frames = [frame(0.0, 1.5), frame(10.0, 1.5), frame(20.0, 1.75)];
    let render = |rib: &str, store: Option<&Arc<BvhStore>>| -> Result<_, Box<dyn std::error::Error>> {
        let mut rt = rtsl_runtime::api::Context::new();
        if let Some(store) = store {
            rt.share_bvhs(store.clone());
        }
        rtsl_runtime::rib::load::load_str(&mut rt, rib, std::path::Path::new("<test>"))?;
        let world = rt.build_world()?;
        let (fb, _) = rtsl_runtime::render::render_frame(&world, None);
        let bvhs: Vec<_> =
            world.scene.objects().iter().filter_map(|o| o.resident_data()).map(|d| d.bvh.clone()).collect();
        if let Some(store) = store {
            store.end_frame();
        }
        Ok((fb.rgba, bvhs))
    };
    let store = Arc::new(BvhStore::new());
    let mut shared = Vec::new();
    for rib in &frames {
        let (alone, _) = render(rib, None)?;
        let (image, bvhs) = render(rib, Some(&store))?;
        assert_eq!(
            alone.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            image.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(bvhs.len(), 3, "the floor, the sphere and the triangle");
        shared.push(bvhs);
    }
    let same = |a: usize, b: usize, object: usize| Arc::ptr_eq(&shared[a][object], &shared[b][object]);
    assert!(same(0, 1, 0) && same(0, 1, 1) && same(0, 1, 2), "the second frame declares the same geometry");
    assert!(same(1, 2, 0) && same(1, 2, 1), "the third frame keeps the floor and the sphere");
    assert!(!same(1, 2, 2), "the triangle's apex moved");
    assert_eq!(store.reused(), 5);
    assert_eq!(store.len(), 3, "the first triangle's BVH was let go when a frame did not use it");
    Ok(())
}
