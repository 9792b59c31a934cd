//! The master and its workers as threads of this process (`LocalTransport`): workers that start
//! empty and are sent the master's context ([`ReplicaScene`]) make images bit for bit the
//! single-process ones, frame after frame of changes; failures are reported by the master, named
//! by rank, never a hang; damaged updates are errors.

mod common;

use common::BUMP_ONLY;
use rtsl_runtime::api::{Context, InheritedAppearance, Primitive, Replicator};
use rtsl_runtime::distributed::{
    serve, Demand, DistributedError, LocalTransport, Master, Message, ReplicaScene, TileQuarters, Traffic, Transport,
};
use rtsl_runtime::glam::{Affine3A, Vec3, Vec3A};
use rtsl_runtime::render::{render_frame, FilterKind, Framebuffer, PixelFilter, RayField};
use rtsl_runtime::shading::{ParamValue, ShaderProgram};
use std::path::{Path, PathBuf};
use std::time::Duration;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// A change the application makes to its context before a frame.
type Change = fn(&mut Context) -> Result<(), String>;

/// A scene a test starts from.
type Scene = fn() -> Result<Context, String>;

/// Each frame's image rendered distributed and alone, and the bytes of its update.
type Frames = Vec<(Framebuffer, Framebuffer, u64)>;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool")
}

/// Renders a frame after each change of `changes` (applied to the master's context `rt` only)
/// with `workers` worker threads of `threads` threads each, and in this process alone; returns
/// both images of each frame and the bytes of each frame's update.
fn both_ways(rt: Context, workers: usize, threads: usize, changes: &[Change]) -> Result<Frames, DistributedError> {
    Ok(both_ways_quartered(rt, workers, threads, changes, TileQuarters::AtTheEnd)?.0)
}

/// [`both_ways`] with the master handing out `quarters` of tiles in quarters; also returns how
/// many tiles went out in quarters each frame.
fn both_ways_quartered(
    mut rt: Context,
    workers: usize,
    threads: usize,
    changes: &[Change],
    quarters: TileQuarters,
) -> Result<(Frames, Vec<u64>), DistributedError> {
    let mut group = LocalTransport::group(workers + 1, Duration::from_secs(120)).into_iter();
    let master_end = group.next().expect("rank 0");
    let handles: Vec<_> =
        group.map(|t| std::thread::spawn(move || serve(&t, Ok(&mut ReplicaScene::new()), &pool(threads)))).collect();
    let mut master = Master::connect(master_end)?;
    master.check_workers()?;
    master.set_tile_quarters(quarters);
    let mut out = Vec::new();
    let mut quartered = Vec::new();
    for change in changes {
        change(&mut rt).expect("the change applies");
        let world = rt.build_world().expect("a world");
        let (distributed, report) = master.render_context(&rt, &world, None)?;
        assert_eq!(report.threads, workers * threads);
        assert!(report.primary_rays >= u64::from(world.options.width * world.options.height));
        // The workers' time is accounted within the master's frame, and they did render.
        let time = master.worker_time();
        quartered.push(time.helping.quartered);
        assert_eq!(time.frame, report.elapsed);
        assert!(time.rendering > Duration::ZERO && time.rendering <= time.share, "{time:?}");
        assert!(time.world + time.share <= time.frame, "{time:?}");
        let (alone, _) = pool(2).install(|| render_frame(&world, None));
        rt.return_scene(world);
        out.push((distributed, alone, master.traffic().updates));
    }
    master.shutdown()?;
    for h in handles {
        h.join().expect("a worker thread")?;
    }
    Ok((out, quartered))
}

/// Runs `f` with a master of two workers of one thread each, serving replicas that start empty
/// (receives give up after `timeout`), then stops them.
fn with_two_workers<R>(
    timeout: Duration,
    f: impl FnOnce(&mut Master<LocalTransport>) -> Result<R, DistributedError>,
) -> Result<R, DistributedError> {
    with_workers(2, timeout, f)
}

/// [`with_two_workers`] with `workers` workers.
fn with_workers<R>(
    workers: usize,
    timeout: Duration,
    f: impl FnOnce(&mut Master<LocalTransport>) -> Result<R, DistributedError>,
) -> Result<R, DistributedError> {
    let mut group = LocalTransport::group(workers + 1, timeout).into_iter();
    let master_end = group.next().expect("rank 0");
    let handles: Vec<_> =
        group.map(|t| std::thread::spawn(move || serve(&t, Ok(&mut ReplicaScene::new()), &pool(1)))).collect();
    let mut master = Master::connect(master_end)?;
    let result = f(&mut master);
    master.shutdown()?;
    for h in handles {
        h.join().expect("a worker thread")?;
    }
    result
}

fn nothing(_: &mut Context) -> Result<(), String> {
    Ok(())
}

/// Moves the first instance a step along x.
fn move_first(rt: &mut Context) -> Result<(), String> {
    let id = *rt.world_instance_ids().first().ok_or("no instance")?;
    let t = rt.instance_transform(id).map_err(|e| e.to_string())?;
    rt.set_instance_transform(id, Affine3A::from_translation([0.15, 0.0, 0.0].into()) * t).map_err(|e| e.to_string())
}

fn assert_same(frames: &[(Framebuffer, Framebuffer, u64)], what: &str) {
    for (k, (distributed, alone, _)) in frames.iter().enumerate() {
        assert_eq!((distributed.width, distributed.height), (alone.width, alone.height));
        let differ = distributed.rgba.iter().zip(&alone.rgba).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
        assert_eq!(differ, 0, "{what}, frame {k}: {differ} values differ");
        assert!(distributed.depth.iter().zip(&alone.depth).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(distributed.object_id, alone.object_id);
        assert!(alone.rgba.iter().any(|&v| v > 0.0), "{what}: the image is not black");
    }
}

fn office() -> Result<Context, String> {
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, repo("examples/office/office.rib")).map_err(|e| e.to_string())?;
    rt.options.width = 96;
    rt.options.height = 72;
    Ok(rt)
}

/// The library scene through a fisheye camera shader and an exposure pixel shader, 2x2 samples
/// splatted through a Gaussian filter (whose films the master adds up).
fn library_with_camera_and_pixel_shader() -> Result<Context, String> {
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, repo("examples/scenes/library.rib")).map_err(|e| e.to_string())?;
    rt.options.width = 80;
    rt.options.height = 56;
    rt.options.pixel_filter = PixelFilter::new(FilterKind::Gaussian, 2.0, 2.0)?;
    let fisheye = rt.find_shader("fisheye").map_err(|e| e.to_string())?;
    rt.camera_shader(Some(fisheye), &[("fov", ParamValue::Float(200.0))]).map_err(|e| e.to_string())?;
    let exposure = rt.find_shader("exposure").map_err(|e| e.to_string())?;
    rt.pixel_shader(Some(exposure), &[]).map_err(|e| e.to_string())?;
    Ok(rt)
}

#[test]
fn distributed_frames_are_bit_identical_to_single_process_frames() -> Result<(), DistributedError> {
    // Moving frames: each worker applies each frame's update before any of its tiles.
    let scene = office().expect("the office");
    let frames = both_ways(scene, 2, 1, &[nothing, move_first, nothing, move_first])?;
    assert_same(&frames, "the office");
    // The first update carries the scene; a move carries one instance; no change, nothing.
    let updates: Vec<u64> = frames.iter().map(|f| f.2).collect();
    assert!(updates[0] > 10_000, "{updates:?}");
    assert!(updates[1] < updates[0] / 20, "{updates:?}");
    assert!(updates[2] < updates[1], "{updates:?}");
    let library = library_with_camera_and_pixel_shader().expect("the library scene");
    assert_same(&both_ways(library, 3, 2, &[nothing])?, "the library scene");
    // A volume shader reading a grid file, which each worker reads from the texture path.
    let mut volume = Context::new();
    rtsl_runtime::rib::load::load_file(&mut volume, repo("examples/scenes/volume.rib")).expect("the volume scene");
    volume.options.width = 64;
    volume.options.height = 48;
    assert_same(&both_ways(volume, 2, 1, &[nothing])?, "the volume scene");
    // Ray parameters travel with the options: relevance around a gaze point lowers samples and
    // the mirror's reflections on the workers as here, and moving the gaze reaches them.
    let mut gazed = office().expect("the office");
    gazed.options.samples = (2, 2);
    gazed.set_ray_parameter("relevance", 0.0).expect("a value");
    let gaze = |x: f32| RayField::Gaze { centre: [x, 36.0], radius: 12.0, falloff: 12.0, inside: 1.0.into() };
    gazed.set_ray_field("relevance", Some(gaze(30.0))).expect("a field");
    fn look_right(rt: &mut Context) -> Result<(), String> {
        let gaze = RayField::Gaze { centre: [70.0, 36.0], radius: 12.0, falloff: 12.0, inside: 1.0.into() };
        rt.set_ray_field("relevance", Some(gaze)).map_err(|e| e.to_string())
    }
    assert_same(&both_ways(gazed, 2, 1, &[nothing, look_right])?, "the office under a moving gaze");
    Ok(())
}

#[test]
fn frames_that_keep_no_depth_or_ids_send_colour_alone() -> Result<(), DistributedError> {
    let blank =
        |fb: &Framebuffer| fb.depth.iter().all(|d| *d == f32::INFINITY) && fb.object_id.iter().all(|&i| i == u32::MAX);
    // Tiles that go straight into the image (the office) and tiles kept for a filter and a pixel
    // shader (the library): the same colours as one process, and neither keeps depth or ids.
    let mut colour_only = office().expect("the office");
    colour_only.options.depth_and_ids = false;
    let frames = both_ways(colour_only, 2, 1, &[nothing, move_first])?;
    assert_same(&frames, "the office without depth and ids");
    let mut library = library_with_camera_and_pixel_shader().expect("the library scene");
    library.options.depth_and_ids = false;
    let frames = [frames, both_ways(library, 2, 1, &[nothing])?].concat();
    assert_same(&frames, "the library without depth and ids");
    assert!(frames.iter().all(|(distributed, alone, _)| blank(distributed) && blank(alone)));
    // The office's tiles carry two thirds of the bytes they carry with depth and ids (each tile
    // once: no copies at the frame's end, which may arrive twice).
    let pixels = |keep: bool| {
        with_two_workers(Duration::from_secs(120), |master| {
            master.set_tile_copies(false);
            let mut rt = office().expect("the office");
            rt.options.depth_and_ids = keep;
            let world = rt.build_world().expect("a world");
            let (fb, _) = master.render_context(&rt, &world, None)?;
            assert_eq!(blank(&fb), !keep);
            Ok(master.traffic().pixels)
        })
    };
    let (with, without) = (pixels(true)?, pixels(false)?);
    // Eight bytes a pixel, a depth and an id, and a few more or fewer where the tiles went out
    // in more or fewer messages.
    let fewer = with.abs_diff(without);
    assert!(fewer.abs_diff(96 * 72 * 8) < 2048 && without < with, "{with} against {without} bytes");
    Ok(())
}

#[test]
fn bart_frames_are_bit_identical() -> Result<(), DistributedError> {
    let robots = repo("../shared/scenes/bart/robot/aff/Robot.aff");
    if !robots.exists() {
        eprintln!("skipped: {} is absent", robots.display());
        return Ok(());
    }
    let mut rt = Context::new();
    let mut scene = rtsl_runtime::bart::load_file(&mut rt, &robots).expect("the robots load");
    rt.options.width = 64;
    rt.options.height = 48;
    let t = scene.frame_time(40);
    scene.set_time(&mut rt, t).expect("frame 40");
    // The animation's next frames, played on the master only: the workers are sent what moved.
    thread_local! {
        static SCENE: std::cell::RefCell<Option<rtsl_runtime::bart::BartScene>> = const { std::cell::RefCell::new(None) };
    }
    SCENE.with(|s| *s.borrow_mut() = Some(scene));
    fn next_frame(rt: &mut Context) -> Result<(), String> {
        SCENE.with(|s| {
            let mut s = s.borrow_mut();
            let scene = s.as_mut().ok_or("no scene")?;
            let t = scene.frame_time(41);
            scene.set_time(rt, t).map_err(|e| e.to_string())
        })
    }
    assert_same(&both_ways(rt, 2, 1, &[nothing, next_frame])?, "BART robots frames");
    Ok(())
}

#[test]
fn tiles_handed_out_in_quarters_make_the_same_image() -> Result<(), DistributedError> {
    fn cornell(file: &str) -> Result<Context, String> {
        let mut rt = Context::new();
        rtsl_runtime::rib::load::load_file(&mut rt, repo(file)).map_err(|e| e.to_string())?;
        (rt.options.width, rt.options.height) = (64, 48);
        Ok(rt)
    }
    // Without the imager that filters the interleaved samples (which reads other pixels).
    let unfiltered = |file: &str| -> Result<Context, String> {
        let mut rt = cornell(file)?;
        rt.pixel_shader(None, &[]).map_err(|e| e.to_string())?;
        Ok(rt)
    };
    let gi_box = || unfiltered("examples/scenes/gi_box.rib");
    let caustics = || unfiltered("examples/scenes/cornell_caustics.rib");
    // Every tile in quarters, each rendered apart by whichever worker took it: the office over
    // moving frames (a mirror's reflections), light paths and virtual lights of instant
    // radiosity, a photon map's caustics. The office's 96x72 have 24 whole tiles of 16x16.
    let (frames, quartered) =
        both_ways_quartered(office().expect("the office"), 3, 1, &[nothing, move_first], TileQuarters::Always)?;
    assert_same(&frames, "the office in quarters");
    assert_eq!(quartered, [24, 24]);
    for (name, rt) in [("the GI box", gi_box()), ("the Cornell box with caustics", caustics())] {
        let (frames, quartered) = both_ways_quartered(rt.expect(name), 2, 2, &[nothing], TileQuarters::Always)?;
        assert_same(&frames, name);
        assert!(quartered[0] > 0, "{name}: {quartered:?}");
    }
    // Tiles whose pixels depend on other tiles' or on their neighbours in the tile go whole: a
    // Gaussian filter's splats, an imager that reads other pixels, adaptive samples.
    let library = library_with_camera_and_pixel_shader().expect("the library");
    let (frames, quartered) = both_ways_quartered(library, 2, 1, &[nothing], TileQuarters::Always)?;
    assert_same(&frames, "the library");
    assert_eq!(quartered, [0]);
    let filtered = cornell("examples/scenes/gi_box.rib").expect("the GI box");
    let (frames, quartered) = both_ways_quartered(filtered, 2, 1, &[nothing], TileQuarters::Always)?;
    assert_same(&frames, "the GI box filtered");
    assert_eq!(quartered, [0]);
    let mut adaptive = office().expect("the office");
    adaptive.options.antialiasing = rtsl_runtime::render::Antialiasing::Adaptive { threshold: 0.05 };
    let (frames, quartered) = both_ways_quartered(adaptive, 2, 1, &[nothing], TileQuarters::Always)?;
    assert_same(&frames, "the office under adaptive sampling");
    assert_eq!(quartered, [0]);
    // By default, the last eighth of a frame's tiles (3 of 24, all whole at 96x64); none over
    // one worker of one thread, where no other could take a quarter.
    let mut whole_tiles = office().expect("the office");
    whole_tiles.options.height = 64;
    let (frames, quartered) = both_ways_quartered(whole_tiles, 2, 1, &[nothing], TileQuarters::AtTheEnd)?;
    assert_same(&frames, "the office at 96x64");
    assert_eq!(quartered, [3]);
    let (frames, quartered) =
        both_ways_quartered(office().expect("the office"), 1, 1, &[nothing], TileQuarters::AtTheEnd)?;
    assert_same(&frames, "the office over one worker");
    assert_eq!(quartered, [0]);
    Ok(())
}

/// A small scene of the application's own making: a floor, a box, a point light.
fn little_scene() -> Result<Context, String> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    rt.options.width = 48;
    rt.options.height = 40;
    rt.camera_look_at(Vec3A::new(0.0, 1.5, 4.0), Vec3A::new(0.0, 0.3, 0.0), Vec3A::Y, 45.0);
    let plastic = rt.find_shader("plastic").map_err(e)?;
    let floor = rt.begin_object().map_err(e)?;
    rt.bind_shader(plastic).map_err(e)?;
    rt.begin(Primitive::Quads).map_err(e)?;
    for (x, z) in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
        rt.vertex(x, 0.0, z).map_err(e)?;
    }
    rt.end().map_err(e)?;
    rt.end_object().map_err(e)?;
    rt.instantiate_object(floor).map_err(e)?;
    let block = rt.begin_object().map_err(e)?;
    rt.color(0.8, 0.3, 0.2);
    rt.bind_shader(plastic).map_err(e)?;
    rt.begin(Primitive::Triangles).map_err(e)?;
    for p in [[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        rt.vertex(p[0], p[1], p[2]).map_err(e)?;
    }
    rt.end().map_err(e)?;
    rt.end_object().map_err(e)?;
    rt.instantiate_object(block).map_err(e)?;
    // A second instance with an appearance of its own, which the workers must shade as it is.
    rt.color(0.2, 0.4, 0.9);
    rt.translate(1.1, 0.0, 0.0);
    rt.instantiate_object_inheriting(block, InheritedAppearance::ALL).map_err(e)?;
    rt.load_identity();
    let light = rt.find_shader("pointlight").map_err(e)?;
    rt.translate(1.0, 3.0, 2.0);
    rt.light_source(light, &[("intensity", ParamValue::Float(12.0))]).map_err(e)?;
    rt.load_identity();
    Ok(rt)
}

#[test]
fn every_kind_of_change_reaches_the_workers_before_their_frame() -> Result<(), DistributedError> {
    fn reload_plastic(rt: &mut Context) -> Result<(), String> {
        // Hot reload: the program behind an id replaced by code the workers never saw.
        let id = rt.find_shader("plastic").map_err(|e| e.to_string())?;
        let source = "surface plastic(float Kd = 0.5; float Ks = 0.5) { Ci = Cs * Kd * (1 - v) + Ks * s; Oi = Os; }";
        let program = ShaderProgram::from_source("plastic", source, &[]).map_err(|e| e.to_string())?;
        rt.replace_shader(id, program).map_err(|e| e.to_string())
    }
    fn new_object_and_texture(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        // A texture from memory, read by a shader compiled from a string.
        let texels: Vec<f32> = (0..8 * 8 * 3).map(|i| ((i * 37) % 11) as f32 / 10.0).collect();
        rt.tex_image_2d("checks", 8, 8, 3, &texels).map_err(e)?;
        let shader = rt
            .compile_shader("textured", "surface textured() { Ci = color texture(\"checks\", s, t); Oi = 1; }")
            .map_err(e)?;
        let quad = rt.begin_object().map_err(e)?;
        rt.bind_shader(shader).map_err(e)?;
        rt.begin(Primitive::Quads).map_err(e)?;
        rt.tex_coord(0.0, 0.0);
        rt.vertex(-1.5, 0.2, -1.0).map_err(e)?;
        rt.tex_coord(1.0, 0.0);
        rt.vertex(-0.6, 0.2, -1.0).map_err(e)?;
        rt.tex_coord(1.0, 1.0);
        rt.vertex(-0.6, 1.2, -1.0).map_err(e)?;
        rt.tex_coord(0.0, 1.0);
        rt.vertex(-1.5, 1.2, -1.0).map_err(e)?;
        rt.end().map_err(e)?;
        rt.end_object().map_err(e)?;
        rt.instantiate_object(quad).map_err(e)?;
        Ok(())
    }
    fn rebuild_and_delete(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        // The triangle becomes a bigger one; the floor goes.
        let block = rtsl_runtime::api::ObjectId(1);
        rt.redefine_object(block).map_err(e)?;
        rt.begin(Primitive::Triangles).map_err(e)?;
        for p in [[-0.9, 0.0, 0.3], [0.9, 0.0, 0.3], [0.0, 1.4, 0.0]] {
            rt.vertex(p[0], p[1], p[2]).map_err(e)?;
        }
        rt.end().map_err(e)?;
        rt.end_object().map_err(e)?;
        rt.delete_object(rtsl_runtime::api::ObjectId(0)).map_err(e)
    }
    fn holdout_and_hidden(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        // A holdout, and a triangle the camera does not see but shadows meet.
        rt.push_attributes();
        for (x, visible_to_camera, matte) in [(-1.2, true, true), (1.0, false, false)] {
            rt.matte(matte);
            rt.ray_visibility(rtsl_runtime::render::RayKind::Camera, visible_to_camera);
            let object = rt.begin_object().map_err(e)?;
            rt.begin(Primitive::Triangles).map_err(e)?;
            for p in [[x - 0.4, 0.6, 0.8], [x + 0.4, 0.6, 0.8], [x, 1.3, 0.8]] {
                rt.vertex(p[0], p[1], p[2]).map_err(e)?;
            }
            rt.end().map_err(e)?;
            rt.end_object().map_err(e)?;
            rt.instantiate_object(object).map_err(e)?;
        }
        rt.pop_attributes().map_err(e)
    }
    fn mirror_without_bounces(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        // A mirror whose rays may take no specular bounce: black where it would reflect.
        let mirror = rt
            .compile_shader("mirror", "surface mirror() { Oi = 1; Ci = 0.5 * trace(P, reflect(I, normalize(N))); }")
            .map_err(e)?;
        rt.push_attributes();
        rt.max_specular_depth(0);
        let object = rt.begin_object().map_err(e)?;
        rt.bind_shader(mirror).map_err(e)?;
        rt.begin(Primitive::Quads).map_err(e)?;
        for p in [[-1.0, 0.0, -1.8], [1.0, 0.0, -1.8], [1.0, 1.5, -1.8], [-1.0, 1.5, -1.8]] {
            rt.vertex(p[0], p[1], p[2]).map_err(e)?;
        }
        rt.end().map_err(e)?;
        rt.end_object().map_err(e)?;
        rt.instantiate_object(object).map_err(e)?;
        rt.pop_attributes().map_err(e)
    }
    fn settings(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        // Lights, camera, options and a pixel shader: the frame's settings.
        let light = rt.find_shader("distantlight").map_err(e)?;
        rt.light_source(light, &[("intensity", ParamValue::Float(0.7))]).map_err(e)?;
        rt.camera_look_at(Vec3A::new(1.0, 2.0, 3.5), Vec3A::new(0.0, 0.5, 0.0), Vec3A::Y, 50.0);
        rt.options.width = 40;
        rt.options.height = 52;
        rt.options.background = [0.1, 0.2, 0.3];
        let exposure = rt.find_shader("exposure").map_err(e)?;
        rt.pixel_shader(Some(exposure), &[]).map_err(e)
    }
    fn move_light(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        // The point light's space moved and its values changed, as an animated VRML light does.
        let light = rtsl_runtime::api::LightId(0);
        let at = rt.light_transform(light).map_err(e)?;
        rt.set_light_transform(light, Affine3A::from_translation(Vec3::new(1.5, 0.5, 0.0)) * at).map_err(e)?;
        rt.set_light_parameters(light, &[("intensity", ParamValue::Float(20.0))]).map_err(e)
    }
    let rt = little_scene().expect("the little scene");
    let frames = both_ways(
        rt,
        2,
        1,
        &[
            nothing,
            move_light,
            reload_plastic,
            new_object_and_texture,
            move_first,
            rebuild_and_delete,
            holdout_and_hidden,
            mirror_without_bounces,
            settings,
            nothing,
        ],
    )?;
    assert_same(&frames, "frames of changes");
    assert!(frames[0].1.rgba != frames[1].1.rgba, "the moved light lights the frame differently");
    let holes =
        |fb: &Framebuffer| fb.rgba.chunks_exact(4).zip(&fb.depth).filter(|(p, d)| d.is_finite() && p[3] == 0.0).count();
    assert!(holes(&frames[6].1) > 0 && holes(&frames[5].1) == 0, "the holdout leaves transparent pixels");
    Ok(())
}

/// A quad from `corners` (counter-clockwise, seen from the camera) with texture coordinates over
/// it, bound to `shader`, instanced once.
fn textured_quad(rt: &mut Context, shader: rtsl_runtime::api::ShaderId, corners: [[f32; 3]; 4]) -> Result<(), String> {
    textured_quad_with(rt, shader, &[], corners)
}

/// [`textured_quad`], the shader given `params`.
fn textured_quad_with(
    rt: &mut Context,
    shader: rtsl_runtime::api::ShaderId,
    params: &[(&str, ParamValue)],
    corners: [[f32; 3]; 4],
) -> Result<(), String> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let quad = rt.begin_object().map_err(e)?;
    rt.bind_shader(shader).map_err(e)?;
    rt.parameters(params).map_err(e)?;
    rt.begin(Primitive::Quads).map_err(e)?;
    for (k, p) in corners.iter().enumerate() {
        rt.tex_coord([0.0, 1.0, 1.0, 0.0][k], [0.0, 0.0, 1.0, 1.0][k]);
        rt.vertex(p[0], p[1], p[2]).map_err(e)?;
    }
    rt.end().map_err(e)?;
    rt.end_object().map_err(e)?;
    rt.instantiate_object(quad).map_err(e).map(|_| ())
}

/// The memory texture "checks", `side` texels square, their values made from `seed`.
fn checks(rt: &mut Context, side: usize, seed: usize) -> Result<(), String> {
    let texels: Vec<f32> = (0..side * side * 3).map(|i| ((i * seed) % 11) as f32 / 10.0).collect();
    rt.tex_image_2d("checks", side, side, 3, &texels).map_err(|e| e.to_string())
}

/// [`little_scene`] and more: four shaders, three objects and their instances, two lights, and a
/// quad showing the memory texture "checks".
fn busy_scene() -> Result<Context, String> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = little_scene()?;
    checks(&mut rt, 8, 37)?;
    let shader = rt
        .compile_shader("textured", "surface textured() { Ci = color texture(\"checks\", s, t); Oi = 1; }")
        .map_err(e)?;
    textured_quad(&mut rt, shader, [[-1.5, 0.2, -1.0], [-0.6, 0.2, -1.0], [-0.6, 1.2, -1.0], [-1.5, 1.2, -1.0]])?;
    let distant = rt.find_shader("distantlight").map_err(e)?;
    rt.light_source(distant, &[("intensity", ParamValue::Float(0.6))]).map_err(e)?;
    Ok(rt)
}

/// Another scene, smaller than [`busy_scene`] in every count: one shader of another name
/// (`paintedplastic`) reading another "checks" texture over a quad filling most of the view,
/// and one light of another kind.
fn sparse_scene() -> Result<Context, String> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    rt.options.width = 40;
    rt.options.height = 32;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 4.0), Vec3A::ZERO, Vec3A::Y, 45.0);
    checks(&mut rt, 4, 53)?;
    let painted = rt.find_shader("paintedplastic").map_err(e)?;
    let quad = rt.begin_object().map_err(e)?;
    rt.bind_shader(painted).map_err(e)?;
    rt.parameter("texturename", ParamValue::String("checks".into())).map_err(e)?;
    rt.begin(Primitive::Quads).map_err(e)?;
    for (k, p) in [[-1.5, -1.2, 0.0], [1.5, -1.2, 0.0], [1.5, 1.2, 0.0], [-1.5, 1.2, 0.0]].iter().enumerate() {
        rt.tex_coord([0.0, 1.0, 1.0, 0.0][k], [0.0, 0.0, 1.0, 1.0][k]);
        rt.vertex(p[0], p[1], p[2]).map_err(e)?;
    }
    rt.end().map_err(e)?;
    rt.end_object().map_err(e)?;
    rt.instantiate_object(quad).map_err(e)?;
    let spot = rt.find_shader("spotlight").map_err(e)?;
    let params = [
        ("intensity", ParamValue::Float(14.0)),
        ("from", ParamValue::Point([0.5, 0.5, 3.0])),
        ("to", ParamValue::Point([0.0, 0.0, 0.0])),
        ("coneangle", ParamValue::Float(0.5)),
    ];
    rt.light_source(spot, &params).map_err(e)?;
    Ok(rt)
}

/// A frame of `rt` over `master`'s workers, and here; with the frame's update's bytes, and what
/// the workers fetched.
fn frame_both_ways(
    master: &mut Master<LocalTransport>,
    rt: &mut Context,
) -> Result<((Framebuffer, Framebuffer, u64), Demand), DistributedError> {
    let world = rt.build_world().expect("a world");
    let (distributed, _) = master.render_context(rt, &world, None)?;
    let (alone, _) = render_frame(&world, None);
    rt.return_scene(world);
    Ok(((distributed, alone, master.traffic().updates), master.demand()))
}

/// A context other than the last frame's is another scene (a RIB file's next frame): the workers
/// drop their copy, its ids, programs, meshes and textures, and are sent the new one whole, even
/// when it has fewer of everything, and a texture of the same name stands for other texels.
#[test]
fn each_new_context_is_a_scene_the_workers_start_again_from() -> Result<(), DistributedError> {
    let (frames, demands) = with_two_workers(Duration::from_secs(120), |master| {
        let mut busy = busy_scene().expect("the busy scene");
        let mut sparse = sparse_scene().expect("the sparse scene");
        let mut busy_again = busy_scene().expect("the busy scene");
        let mut frames = Vec::new();
        let mut demands = Vec::new();
        for rt in [&mut busy, &mut sparse, &mut busy_again] {
            let (frame, demand) = frame_both_ways(master, rt)?;
            frames.push(frame);
            demands.push(demand);
            if frames.len() == 2 {
                // Within a scene, frames send what changed, as ever.
                move_first(rt).expect("moved");
                let (frame, demand) = frame_both_ways(master, rt)?;
                frames.push(frame);
                demands.push(demand);
            }
        }
        // A viewer's pieces of work follow the same way.
        let mut viewed = sparse_scene().expect("the sparse scene");
        let world = viewed.build_world().expect("a world");
        let lattices = rtsl_runtime::render::progressive::pass_lattices(40, 32, 1);
        let every = |_: u32, _: u32| true;
        let (there, _) = master.trace_lattices(&viewed, &world, &lattices, 0, false, &every)?;
        let (here, _) = rtsl_runtime::render::progressive::trace_lattices(&world, &lattices, 0, false, &every);
        assert!(lattice_bits(&there) == lattice_bits(&here), "the new scene's samples differ");
        viewed.return_scene(world);
        Ok((frames, demands))
    })?;
    assert_same(&frames, "frames of scenes one after another");
    assert!(frames[0].1.rgba != frames[1].1.rgba && frames[1].1.rgba != frames[2].1.rgba, "the scenes differ");
    let updates: Vec<u64> = frames.iter().map(|f| f.2).collect();
    // A new scene is sent whole; a move within it is one instance.
    assert!(updates[1] > 10_000 && updates[3] > 10_000, "{updates:?}");
    assert!(updates[2] < updates[1] / 20, "{updates:?}");
    // The texture of the same name, fetched again by each scene from the master.
    for (k, d) in demands.iter().enumerate().filter(|(k, _)| *k != 2) {
        assert!(d.fetched_textures > 0, "frame {k}: {d:?}");
    }
    Ok(())
}

/// A worker whose frame failed (here, an update it cannot decode) renders none of that scene's
/// later frames, each reported as failed, and renders again once the master starts a new scene.
#[test]
fn a_worker_that_failed_renders_again_from_a_new_scene() -> Result<(), DistributedError> {
    with_two_workers(Duration::from_secs(60), |master| {
        let mut rt = little_scene().expect("the little scene");
        let world = rt.build_world().expect("a world");
        master.render_context(&rt, &world, None)?;
        let err = master.render_frame(&world, b"no update", None).expect_err("an update no worker can apply");
        assert!(err.to_string().contains("cannot be decoded"), "{err}");
        let again = master.render_context(&rt, &world, None).expect_err("the scene's next frame").to_string();
        assert!(again.contains("cannot be decoded"), "the same failure: {again}");
        rt.return_scene(world);
        let mut next = busy_scene().expect("the busy scene");
        let (frame, _) = frame_both_ways(master, &mut next)?;
        assert_same(&[frame], "the first frame of a new scene after a failure");
        Ok(())
    })
}

/// The texture file of [`textures_read_again_after_a_change_reach_the_workers`] (the changes it
/// renders are plain functions).
fn changing_texture() -> PathBuf {
    std::env::temp_dir().join(format!("rtsl-reloaded-texture-{}.exr", std::process::id()))
}

fn write_texel(value: f32) -> Result<(), String> {
    let texels = [value, value * 0.5, 0.25, 1.0].repeat(4);
    rtsl_runtime::write_image(changing_texture(), 2, 2, &texels, &Default::default()).map_err(|e| e.to_string())
}

#[test]
fn textures_read_again_after_a_change_reach_the_workers() -> Result<(), DistributedError> {
    fn textured(rt: &mut Context) -> Result<(), String> {
        let e = |e: rtsl_runtime::api::ApiError| e.to_string();
        write_texel(0.2)?;
        let tex = rt
            .compile_shader("tex", "surface tex(string name = \"\";) { Oi = 1; Ci = color texture(name, s, t); }")
            .map_err(e)?;
        let quad = rt.begin_object().map_err(e)?;
        rt.bind_shader(tex).map_err(e)?;
        rt.parameter("name", ParamValue::String(changing_texture().display().to_string())).map_err(e)?;
        rt.begin(Primitive::Quads).map_err(e)?;
        for (x, y) in [(-3.0, -3.0), (3.0, -3.0), (3.0, 3.0), (-3.0, 3.0)] {
            rt.vertex(x, y, -1.0).map_err(e)?;
        }
        rt.end().map_err(e)?;
        rt.end_object().map_err(e)?;
        rt.instantiate_object(quad).map_err(e).map(|_| ())
    }
    fn file_changed(_: &mut Context) -> Result<(), String> {
        write_texel(0.9)
    }
    fn reloaded(rt: &mut Context) -> Result<(), String> {
        rt.reload_textures();
        Ok(())
    }
    let mut rt = Context::new();
    rt.options.width = 24;
    rt.options.height = 20;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 4.0), Vec3A::ZERO, Vec3A::Y, 40.0);
    let frames = both_ways(rt, 2, 1, &[textured, file_changed, reloaded]);
    let _ = std::fs::remove_file(changing_texture());
    let frames = frames?;
    assert_same(&frames, "frames of a texture read again");
    let centre = |fb: &Framebuffer| {
        let i = ((fb.height / 2 * fb.width + fb.width / 2) * 4) as usize;
        fb.rgba[i]
    };
    // Read once and kept until told to read it again, then the new file, on the workers too
    // (`assert_same`).
    let near = |a: f32, b: f32| (a - b).abs() < 1e-5;
    assert!(near(centre(&frames[0].0), 0.2) && near(centre(&frames[1].0), 0.2), "kept until read again");
    assert!(near(centre(&frames[2].0), 0.9), "read again: {}", centre(&frames[2].0));
    Ok(())
}

#[test]
fn damaged_updates_are_errors_never_panics() {
    let mut rt = little_scene().expect("the little scene");
    let mut replicator = Replicator::new();
    let update = replicator.update(&rt, None).expect("an update");
    // The update makes a copy that renders the same world.
    let mut copy = Context::new();
    assert_eq!(copy.apply_update(&update).ok(), Some(true));
    let (a, _) = render_frame(&rt.build_world().expect("a world"), None);
    let (b, _) = render_frame(&copy.build_world().expect("the copy's world"), None);
    assert_eq!(a.rgba, b.rgba);
    // Truncated or with a byte changed: an error, or a context that still builds a world.
    let mut state = 0x9e3779b97f4a7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for cut in [0, 1, 7, update.len() / 3, update.len() - 1] {
        assert!(Context::new().apply_update(&update[..cut.max(1)]).is_err(), "cut at {cut}");
    }
    for _ in 0..400 {
        let mut damaged = update.clone();
        for _ in 0..1 + next() % 3 {
            let at = (next() % damaged.len() as u64) as usize;
            damaged[at] ^= 1 << (next() % 8);
        }
        let mut copy = Context::new();
        if copy.apply_update(&damaged).is_ok() {
            let _ = copy.build_world();
        }
    }
    // Ids beyond what the copy holds, or new records missing, are refused.
    let mut fresh = Context::new();
    assert!(fresh.apply_update(&update).is_ok());
    let mut moved = replicator.update(&rt, None).expect("no change");
    assert!(moved.is_empty());
    move_first(&mut rt).expect("moved");
    moved = replicator.update(&rt, None).expect("a move");
    assert!(!moved.is_empty() && moved.len() < update.len() / 20, "{} of {}", moved.len(), update.len());
    let err = Context::new().apply_update(&moved).expect_err("an update that assumes an earlier one");
    assert!(err.to_string().contains("missing"), "{err}");
}

#[test]
fn a_worker_whose_scene_failed_is_named_by_the_master() {
    let mut group = LocalTransport::group(3, Duration::from_secs(30)).into_iter();
    let master_end = group.next().expect("rank 0");
    let workers: Vec<_> = group
        .enumerate()
        .map(|(i, t)| {
            std::thread::spawn(move || {
                if i == 1 {
                    serve(&t, Err("scene.rib:3:1: no such shader \"nonesuch\"".into()), &pool(1))
                } else {
                    serve(&t, Ok(&mut ReplicaScene::new()), &pool(1))
                }
            })
        })
        .collect();
    let master = Master::connect(master_end).expect("the workers greet");
    let err = master.check_workers().expect_err("rank 2 cannot render").to_string();
    assert_eq!(err, "rank 2: scene.rib:3:1: no such shader \"nonesuch\"");
    drop(master);
    for w in workers {
        // Dropping the master told every worker to stop.
        w.join().expect("a worker thread").expect("a clean stop");
    }
}

#[test]
fn a_worker_refuses_units_that_are_no_tile_or_quarter_of_its_frame() {
    // A quarter of a tile of the library, whose Gaussian filter keeps its 70 tiles (at 80x56)
    // whole, and a unit past the last quarter of the office's 30 tiles: the frame fails on the
    // worker, which reports it and waits for what comes next.
    let library = library_with_camera_and_pixel_shader().expect("the library");
    let office = office().expect("the office");
    for (rt, unit) in [(&library, 70 + 4 * 3), (&office, 5 * 30)] {
        let mut group = LocalTransport::group(2, Duration::from_secs(60)).into_iter();
        let (master_end, worker_end) = (group.next().expect("rank 0"), group.next().expect("rank 1"));
        let worker = std::thread::spawn(move || serve(&worker_end, Ok(&mut ReplicaScene::new()), &pool(1)));
        let (rank, hello) = master_end.recv().expect("a greeting");
        assert!(rank == 1 && matches!(Message::decode(&hello), Ok(Message::Hello { .. })));
        let update = Replicator::new().update(rt, None).expect("an update");
        let frame = Message::Frame {
            frame: 1,
            update,
            light_paths: vec![],
            job: rtsl_runtime::distributed::Job::Tiles,
            units: vec![unit],
            lattices: vec![],
            last: true,
        };
        master_end.send(1, frame.encode()).expect("sent");
        let (_, done) = master_end.recv().expect("the frame's end");
        match Message::decode(&done) {
            Ok(Message::FrameDone { frame: 1, failure: Some(failure), .. }) => {
                assert!(failure.contains(&format!("unit {unit}, no tile or quarter of one")), "{failure}")
            }
            other => panic!("unit {unit}: {other:?}"),
        }
        master_end.send(1, Message::Quit.encode()).expect("sent");
        worker.join().expect("a worker thread").expect("a clean stop");
    }
}

#[test]
fn another_protocol_version_is_refused_at_start_up() {
    let mut group = LocalTransport::group(2, Duration::from_secs(10)).into_iter();
    let (master_end, worker_end) = (group.next().expect("rank 0"), group.next().expect("rank 1"));
    let hello = Message::Hello { protocol: 999, build: vec![], threads: 1, failure: None };
    worker_end.send(0, hello.encode()).expect("sent");
    let err = Master::connect(master_end).err().expect("refused").to_string();
    assert!(err.starts_with("rank 1 runs protocol version 999"), "{err}");
    // The refused worker is told to stop.
    let (_, quit) = worker_end.recv().expect("a message");
    assert_eq!(Message::decode(&quit), Ok(Message::Quit));
    // And another build is refused as well.
    let mut group = LocalTransport::group(2, Duration::from_secs(10)).into_iter();
    let (master_end, worker_end) = (group.next().expect("rank 0"), group.next().expect("rank 1"));
    let hello = Message::Hello {
        protocol: rtsl_runtime::distributed::PROTOCOL_VERSION,
        build: vec![0; 8],
        threads: 1,
        failure: None,
    };
    worker_end.send(0, hello.encode()).expect("sent");
    let err = Master::connect(master_end).err().expect("refused").to_string();
    assert!(err.contains("another build"), "{err}");
}

#[test]
fn a_worker_that_goes_silent_is_an_error_not_a_hang() {
    let mut group = LocalTransport::group(2, Duration::from_millis(300)).into_iter();
    let (master_end, worker_end) = (group.next().expect("rank 0"), group.next().expect("rank 1"));
    let hello = Message::Hello {
        protocol: rtsl_runtime::distributed::PROTOCOL_VERSION,
        build: rtsl_runtime::distributed::message::build_fingerprint(),
        threads: 1,
        failure: None,
    };
    worker_end.send(0, hello.encode()).expect("sent");
    let mut master = Master::connect(master_end).expect("greeted");
    let mut rt = office().expect("the office");
    let world = rt.build_world().expect("a world");
    // The worker takes its tiles and never answers.
    assert!(master.render_frame(&world, &[], None).is_err());
    drop(worker_end);
}

/// The GI box of `examples/scenes/gi_box.rib` at 40x30, whose pixel shader (`interleavefilter`)
/// reads other pixels, their normals among them: its tiles go to the master unfinished.
fn gi_box() -> Result<Context, String> {
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, repo("examples/scenes/gi_box.rib")).map_err(|e| e.to_string())?;
    (rt.options.width, rt.options.height) = (40, 30);
    Ok(rt)
}

/// [`gi_box`] splatted through a Gaussian filter: its tiles carry films and normals.
fn gi_box_gaussian() -> Result<Context, String> {
    let mut rt = gi_box()?;
    rt.options.pixel_filter = PixelFilter::new(FilterKind::Gaussian, 2.0, 2.0)?;
    Ok(rt)
}

#[test]
fn a_tile_decodes_to_itself_and_damaged_tiles_are_errors() {
    use rtsl_runtime::render::{RenderedTile, TileRenderer};
    // Which scenes' tiles carry normals: those whose pixel shader reads other pixels.
    /// The office keeping two output variables per pixel (arbitrary output variables travel with
    /// the tile).
    fn office_keeping_outputs() -> Result<Context, String> {
        let mut rt = office()?;
        rt.options.outputs = vec!["Kd".into(), "__nondiffuse".into()];
        Ok(rt)
    }
    let scenes: [(Scene, bool); 5] = [
        (office, false),
        (office_keeping_outputs, false),
        (library_with_camera_and_pixel_shader, false),
        (gi_box, true),
        (gi_box_gaussian, true),
    ];
    for (make, normals) in scenes {
        let mut rt = make().expect("the scene loads");
        let world = rt.build_world().expect("a world");
        let renderer = TileRenderer::new(&world);
        let tile = renderer.tiles()[5];
        let mut bytes = Vec::new();
        renderer.render_tile(&tile).encode(&mut bytes);
        let decoded = RenderedTile::decode(&world, tile, &bytes).expect("a whole tile");
        let mut again = Vec::new();
        decoded.encode(&mut again);
        assert_eq!(again, bytes);
        for cut in [0, 1, bytes.len() / 2, bytes.len() - 1] {
            assert!(RenderedTile::decode(&world, tile, &bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(RenderedTile::decode(&world, tile, &longer).is_err());
        // The pixels of another tile's size do not fit this one.
        let other = renderer.tiles().last().copied().expect("tiles");
        if (other.width, other.height) != (tile.width, tile.height) {
            assert!(RenderedTile::decode(&world, other, &bytes).is_err());
        }
        let n = (tile.width * tile.height) as usize;
        if normals {
            // Colours, depths and ids (28 bytes a pixel), the outputs the frame keeps (those the
            // interleave filter reads: 12 floats a pixel), the kind, the shader ids (4), then the
            // normals: the first normal's x made 2 is no normal.
            let outputs = 12 * rtsl_runtime::render::world::MAX_FRAME_OUTPUTS * n;
            let normals = 32 * n + outputs + 1;
            let x = f32::from_ne_bytes(bytes[normals..normals + 4].try_into().expect("four bytes"));
            assert!(x.abs() <= 1.0, "a normal's x is {x}");
            let mut damaged = bytes.clone();
            damaged[normals..normals + 4].copy_from_slice(&2.0f32.to_ne_bytes());
            assert!(RenderedTile::decode(&world, tile, &damaged).is_err(), "a damaged normal");
            // A frame whose pixel shader reads no pixels takes no normals.
            let mut plain = make().expect("the scene loads");
            plain.pixel_shader(None, &[]).expect("no pixel shader");
            let plain = plain.build_world().expect("a world");
            assert!(RenderedTile::decode(&plain, tile, &bytes).is_err(), "normals where none are read");
        }
    }
}

#[test]
fn tiles_assembled_as_they_arrive_make_the_finished_image() {
    use rtsl_runtime::render::{RenderedTile, TileRenderer};
    // Rows copied as they lie, and pixels put through the exposure one by one.
    for exposure in [None, Some((1.7, 2.2))] {
        let mut rt = office().expect("the office loads");
        rt.options.exposure = exposure;
        let world = rt.build_world().expect("a world");
        let renderer = TileRenderer::new(&world);
        let mut assembly = renderer.start_assembly().expect("the office's tiles are final where rendered");
        let tiles = renderer.tiles();
        let rendered: Vec<RenderedTile> = tiles.iter().map(|t| renderer.render_tile(t)).collect();
        // Last tile first, each from an odd offset in its buffer (unaligned for its floats).
        for (tile, r) in tiles.iter().zip(&rendered).rev() {
            let mut bytes = vec![0u8];
            r.encode(&mut bytes);
            let bytes = &bytes[1..];
            assert!(assembly.add(*tile, &bytes[..bytes.len() - 1]).is_err(), "a short tile");
            let mut unfinished = bytes.to_vec();
            *unfinished.last_mut().expect("a byte") = 1;
            assert!(assembly.add(*tile, &unfinished).is_err(), "a tile said to be unfinished");
            assembly.add(*tile, bytes).expect("a whole tile");
        }
        let start = std::time::Instant::now();
        let (assembled, _) = assembly.finish(renderer, start);
        let (finished, _) = TileRenderer::new(&world).finish(rendered, start);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&assembled.rgba), bits(&finished.rgba));
        assert_eq!(bits(&assembled.depth), bits(&finished.depth));
        assert_eq!(assembled.object_id, finished.object_id);
        assert!(finished.rgba.iter().any(|&v| v > 0.0 && v < 1.0), "something was rendered");
    }
    // A tile of colour alone goes into an image that keeps no depth or ids, and a tile of either
    // kind is refused, not misread, by an image that expects the other.
    let encoded = |keep: bool| {
        let mut rt = office().expect("the office loads");
        rt.options.depth_and_ids = keep;
        let world = rt.build_world().expect("a world");
        let renderer = TileRenderer::new(&world);
        let tile = renderer.tiles()[0];
        let mut bytes = Vec::new();
        renderer.render_tile(&tile).encode(&mut bytes);
        (tile, bytes, world)
    };
    let (tile, full, full_world) = encoded(true);
    let (_, colour, colour_world) = encoded(false);
    assert_eq!(full.len() - colour.len(), 8 * (tile.width * tile.height) as usize);
    let mut keeps = TileRenderer::new(&full_world).start_assembly().expect("an assembly");
    let mut keeps_none = TileRenderer::new(&colour_world).start_assembly().expect("an assembly");
    assert!(keeps.add(tile, &colour).is_err() && keeps_none.add(tile, &full).is_err());
    keeps_none.add(tile, &colour).expect("a tile of colour alone");
    // Tiles that are not final where rendered are kept for the frame's filter.
    let gaussian = gi_box_gaussian().expect("the scene loads").build_world().expect("a world");
    assert!(TileRenderer::new(&gaussian).start_assembly().is_none());
}

/// Three frames of `rt` over `master`'s workers, the first instance moved before frame `moved_at`,
/// each checked against this process's render; what each frame fetched and moved.
fn frames_moving_once(
    master: &mut Master<LocalTransport>,
    rt: &mut Context,
    moved_at: usize,
    what: &str,
) -> Result<Vec<(Demand, Traffic)>, DistributedError> {
    let mut out = Vec::new();
    for frame in 0..3 {
        if frame == moved_at {
            move_first(rt).expect("moved");
        }
        let world = rt.build_world().expect("a world");
        let (distributed, _) = master.render_context(rt, &world, None)?;
        let (alone, _) = render_frame(&world, None);
        rt.return_scene(world);
        assert_same(&[(distributed, alone, 0)], what);
        out.push((master.demand(), master.traffic()));
    }
    Ok(out)
}

/// A sphere and two quads deforming over the shutter.
const DEFORMING: &str = r#"
        Format 64 48 1
        PixelSamples 2 2
        Shutter 0 1
        Projection "perspective" "fov" 50
        Translate 0 0 6
        WorldBegin
          LightSource "distantlight" 1 "from" [0 0 -1] "to" [0 0 0]
          Surface "plastic"
          MotionBegin [0 1]
            Sphere 0.6 -0.6 0.6 360
            Sphere 1.4 -1.4 1.4 360
          MotionEnd
          Surface "matte"
          MotionBegin [0 1]
            Polygon "P" [-3 -1 1  -1 -1 1  -1 1 1  -3 1 1]
            Polygon "P" [1 -1 1  3 -1 1  3 1 1  1 1 1]
          MotionEnd
        WorldEnd
    "#;

/// Deformation blur on workers: a deforming mesh travels (fetched on demand) with its second
/// set of positions and normals, and the frame is the one rendered here, bit for bit.
#[test]
fn deforming_meshes_render_the_same_on_workers() -> Result<(), DistributedError> {
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_str(&mut rt, DEFORMING, std::path::Path::new(".")).expect("the scene loads");
    let frames = both_ways(rt, 2, 1, &[nothing, move_first])?;
    assert_same(&frames, "a deforming scene");
    Ok(())
}

#[test]
fn the_master_sends_the_bvh_it_built_for_the_mesh_it_sends() {
    use rtsl_runtime::api::ObjectId;
    use rtsl_runtime::geometry::Mesh;
    let mut rt = office().expect("the office loads");
    let world = rt.build_world().expect("a world");
    let ids: Vec<ObjectId> = (0..).map(ObjectId).take_while(|&id| rt.object_mesh(id).is_some()).collect();
    assert!(ids.len() > 3, "the office has objects");
    for &id in &ids {
        let mesh = rt.object_mesh(id).expect("a mesh");
        let bvh = rt.object_bvh(id, &world).expect("the world's BVH of the mesh");
        let placed = bvh.prim_order.iter().filter(|&&p| p != rtsl_runtime::accel::object::NO_TRIANGLE).count();
        assert_eq!(placed, mesh.triangle_count());
    }
    rt.return_scene(world);
    // A mesh replaced since the world was built: the world's BVH is not for it.
    let first = ids[0];
    let world = rt.build_world().expect("a world");
    rt.redefine_object(first).expect("an object to redefine");
    rt.mesh(
        &Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0].into(), [1.0, 0.0, 0.0].into(), [0.0, 1.0, 0.0].into()],
            vec![[0, 1, 2]],
        )
        .expect("a triangle"),
    )
    .expect("the new mesh");
    rt.end_object().expect("the object ends");
    assert!(rt.object_bvh(first, &world).is_none());
    assert!(rt.object_bvh(ObjectId(ids.len() as u32 + 10), &world).is_none());
}

#[test]
fn workers_fetch_only_the_objects_rays_reach_and_keep_them() -> Result<(), DistributedError> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = little_scene().expect("the little scene");
    // A large object behind the camera, which no ray reaches: never sent.
    let hidden = rt.begin_object().map_err(e).expect("an object");
    rt.begin(Primitive::Triangles).map_err(e).expect("triangles");
    for k in 0..3000 {
        let x = (k % 60) as f32 * 0.1;
        let y = (k / 60) as f32 * 0.1;
        for p in [[x, y, 9.0], [x + 0.1, y, 9.0], [x, y + 0.1, 9.0]] {
            rt.vertex(p[0], p[1], p[2]).map_err(e).expect("a vertex");
        }
    }
    rt.end().map_err(e).expect("end");
    rt.end_object().map_err(e).expect("end_object");
    rt.instantiate_object(hidden).map_err(e).expect("an instance");

    let demands =
        with_two_workers(Duration::from_secs(60), |m| frames_moving_once(m, &mut rt, 2, "a demand-loaded frame"))?;
    let (first, traffic) = demands[0];
    // The floor and the triangle, by each of the two workers at most; never the hidden object.
    assert!((2..=4).contains(&first.fetched_objects), "{first:?}");
    assert!(first.most_resident_objects <= 2, "{first:?}");
    // Every object the first frame's rays reached was a miss: fetched.
    assert_eq!(first.reached_objects, first.fetched_objects, "{first:?}");
    assert_eq!(first.hit_rate(), Some(0.0));
    assert!(traffic.fetches > 0 && first.fetched_bytes < 3000 * 36, "{first:?} {traffic:?}");
    // Kept: later frames, even when an instance moves, fetch only what a worker had not reached
    // (a tile of the other worker's, handed to it to balance the frame), each object once.
    let mut resident = first.resident_objects;
    let mut fetched = first.fetched_objects;
    for (later, traffic) in &demands[1..] {
        assert_eq!(traffic.fetches > 0, later.fetched_objects > 0, "{later:?} {traffic:?}");
        assert_eq!(later.resident_objects, resident + later.fetched_objects, "{later:?}");
        (resident, fetched) = (later.resident_objects, fetched + later.fetched_objects);
        // The floor and the triangle, at least, reached again.
        assert!(later.reached_objects >= 2, "{later:?}");
    }
    assert!(fetched <= 4, "each worker fetches the floor and the triangle once at most: {demands:?}");
    Ok(())
}

#[test]
fn a_full_cache_evicts_the_least_recently_used_meshes_and_fetches_them_again() -> Result<(), DistributedError> {
    let mut rt = little_scene().expect("the little scene");
    let mut group = LocalTransport::group(2, Duration::from_secs(60)).into_iter();
    let master_end = group.next().expect("rank 0");
    let worker_end = group.next().expect("rank 1");
    // Room for nothing: every frame starts with an empty cache.
    let worker = std::thread::spawn(move || serve(&worker_end, Ok(&mut ReplicaScene::with_cache_limit(1)), &pool(2)));
    let mut master = Master::connect(master_end)?;
    let demands: Vec<Demand> = frames_moving_once(&mut master, &mut rt, 1, "a frame rendered from an evicted cache")?
        .into_iter()
        .map(|(demand, _)| demand)
        .collect();
    master.shutdown()?;
    worker.join().expect("the worker thread")?;
    assert_eq!(demands[0].evicted_objects, 0, "{demands:?}");
    for d in &demands[1..] {
        // Both objects dropped before the frame, and fetched again by it.
        assert_eq!((d.evicted_objects, d.fetched_objects), (2, 2), "{demands:?}");
        assert_eq!((d.reached_objects, d.hit_rate()), (2, Some(0.0)), "{demands:?}");
    }
    Ok(())
}

#[test]
fn a_texture_the_workers_cannot_load_is_reported_by_the_master_once() -> Result<(), DistributedError> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = little_scene().expect("the little scene");
    let shader = rt
        .compile_shader("grainy", "surface grainy() { Ci = color texture(\"no-such-grain.tx\", s, t); Oi = 1; }")
        .map_err(e)
        .expect("a shader");
    let floor = rtsl_runtime::api::ObjectId(0);
    rt.redefine_object(floor).map_err(e).expect("redefined");
    rt.bind_shader(shader).map_err(e).expect("bound");
    rt.begin(Primitive::Quads).map_err(e).expect("quads");
    for (x, z) in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
        rt.vertex(x, 0.0, z).map_err(e).expect("a vertex");
    }
    rt.end().map_err(e).expect("end");
    rt.end_object().map_err(e).expect("end_object");
    let world = rt.build_world().expect("a world");
    let (alone, _) = render_frame(&world, None);
    let expected: Vec<String> = world.textures.take_warnings().iter().map(ToString::to_string).collect();
    assert_eq!(expected.len(), 1, "{expected:?}");
    rt.return_scene(world);

    let world = rt.build_world().expect("a world");
    let (distributed, _) = with_two_workers(Duration::from_secs(60), |m| m.render_context(&rt, &world, None))?;
    let reported: Vec<String> = world.textures.take_warnings().iter().map(ToString::to_string).collect();
    assert_eq!(reported, expected);
    assert_same(&[(distributed, alone, 0)], "a frame with a missing texture");
    Ok(())
}

/// A texture seen far away reaches the workers as the coarse levels of its pyramid; brought
/// near, the finer levels its lookups read follow. Every frame is bit for bit this process's.
#[test]
fn workers_fetch_the_mip_levels_their_lookups_read() -> Result<(), DistributedError> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    rt.options.width = 40;
    rt.options.height = 32;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 4.0), Vec3A::ZERO, Vec3A::Y, 45.0);
    let side = 512;
    checks(&mut rt, side, 37).expect("a texture");
    let shader = rt
        .compile_shader("textured", "surface textured() { Ci = color texture(\"checks\", s, t); Oi = 1; }")
        .map_err(e)
        .expect("a shader");
    // A quad 60 units away: a few pixels wide, its lookups read the pyramid's coarsest levels.
    textured_quad(&mut rt, shader, [[-1.5, -1.5, -60.0], [1.5, -1.5, -60.0], [1.5, 1.5, -60.0], [-1.5, 1.5, -60.0]])
        .expect("a quad");
    let texture_bytes = (side * side * 3 * 4) as u64;
    let demands = with_two_workers(Duration::from_secs(60), |m| {
        let (far, far_demand) = frame_both_ways(m, &mut rt)?;
        // Brought up to fill the view.
        let id = *rt.world_instance_ids().first().expect("the quad");
        rt.set_instance_transform(id, Affine3A::from_translation([0.0, 0.0, 61.0].into())).map_err(e).expect("moved");
        let (near, near_demand) = frame_both_ways(m, &mut rt)?;
        assert_same(&[far, near], "a texture far away, then near");
        Ok([far_demand, near_demand])
    })?;
    let [far, near] = demands;
    // Far: each worker's first lookup brought the pyramid's coarsest levels, and nothing more.
    assert!((1..=2).contains(&far.fetched_textures), "{far:?}");
    assert_eq!(far.fetched_texture_levels, 0, "{far:?}");
    assert!(far.fetched_texture_bytes < texture_bytes / 50, "{far:?}");
    // Near: finer levels, and still less than the texture to each worker. The texture itself
    // reaches each worker once: now only where the far quad's few tiles all went to the other
    // (as a busy host may hand them out).
    assert!(far.fetched_textures + near.fetched_textures <= 2, "{far:?} {near:?}");
    assert!(near.fetched_texture_levels >= 1, "{near:?}");
    assert!(near.fetched_texture_bytes < texture_bytes, "{near:?}");
    Ok(())
}

/// The bits of every traced lane of each lattice's samples, for exact comparison.
fn lattice_bits(results: &[rtsl_runtime::render::progressive::LatticeSamples]) -> Vec<(u32, u32, u64, Vec<u32>)> {
    results
        .iter()
        .map(|r| {
            let mut bits = Vec::new();
            for lane in (0..64).filter(|l| r.active >> l & 1 != 0) {
                let s = &r.samples[lane];
                bits.extend([s.color.x, s.color.y, s.color.z, s.alpha, s.depth, r.depth[lane]].map(f32::to_bits));
                bits.extend([s.object_id, s.shader_id]);
                bits.extend(s.normal.to_array().map(f32::to_bits));
                bits.extend(s.outputs.iter().flatten().map(|v| v.to_bits()));
            }
            (r.lattice.x0, r.lattice.y0, r.active, bits)
        })
        .collect()
}

#[test]
fn lattices_traced_by_workers_are_the_samples_traced_here() -> Result<(), DistributedError> {
    use rtsl_runtime::render::progressive::{frameless_order, pass_lattices, trace_lattices};
    use rtsl_runtime::render::Antialiasing;
    let mut rt = office().expect("the office");
    let (w, h) = (rt.options.width, rt.options.height);
    let mut group = LocalTransport::group(3, Duration::from_secs(120)).into_iter();
    let master_end = group.next().expect("rank 0");
    let handles: Vec<_> =
        group.map(|t| std::thread::spawn(move || serve(&t, Ok(&mut ReplicaScene::new()), &pool(1)))).collect();
    let mut master = Master::connect(master_end)?;
    // What a viewer does: a preview while moving, a full pass in pieces, an adaptive pass over
    // the lanes that need it after a change to the scene, and a piece of a frameless sweep.
    let every = |_: u32, _: u32| true;
    let some = |x: u32, y: u32| (x + 2 * y) % 3 != 0;
    let full = pass_lattices(w, h, 1);
    let frameless = frameless_order(w, h);
    let pieces: Vec<(Vec<_>, u32, bool, bool)> = vec![
        (pass_lattices(w, h, 4), 0, true, false),
        (full[..13].to_vec(), 0, false, false),
        (full[13..].to_vec(), 0, false, false),
        (full.clone(), 1, false, true),
        (frameless[..50].to_vec(), 2, false, false),
    ];
    for (k, (lattices, pass, preview, after_change)) in pieces.into_iter().enumerate() {
        if after_change {
            move_first(&mut rt).expect("moved");
            rt.options.antialiasing = Antialiasing::Adaptive { threshold: 0.05 };
        }
        let world = rt.build_world().expect("a world");
        let wanted: &(dyn Fn(u32, u32) -> bool + Sync) = if after_change { &some } else { &every };
        let (there, report) = master.trace_lattices(&rt, &world, &lattices, pass, preview, wanted)?;
        let (here, local) = pool(2).install(|| trace_lattices(&world, &lattices, pass, preview, wanted));
        rt.return_scene(world);
        assert_eq!(there.len(), lattices.len());
        assert_eq!(report.primary_rays, local.primary_rays, "piece {k}");
        assert!(report.primary_rays > 0, "piece {k} traced nothing");
        assert!(lattice_bits(&there) == lattice_bits(&here), "piece {k}: the workers' samples differ");
        assert!(master.traffic().pixels > 0);
    }
    master.shutdown()?;
    for h in handles {
        h.join().expect("a worker thread")?;
    }
    Ok(())
}

#[test]
fn lattice_samples_decode_to_themselves_and_damaged_ones_are_errors() {
    use rtsl_runtime::render::progressive::{pass_lattices, trace_lattices, LatticeSamples};
    // The office's samples carry no normals and no output variables; the GI box's carry both (its
    // pixel shader reads the normals and `gimatte`'s indirect light).
    let office = office().expect("the office").build_world().expect("a world");
    let gi = gi_box().expect("the GI box").build_world().expect("a world");
    for (world, other_world, normals) in [(&office, &gi, false), (&gi, &office, true)] {
        let lattices = pass_lattices(world.options.width, world.options.height, 1);
        let wanted = |x: u32, _: u32| x % 2 == 0;
        let (traced, _) = trace_lattices(world, &lattices[..4], 0, false, &wanted);
        let seen = traced.iter().flat_map(|r| r.samples.iter()).filter(|s| s.normal.length() > 0.999).count();
        assert_eq!(seen > 0, normals, "samples with unit normals: {seen}");
        let with_outputs = traced.iter().flat_map(|r| r.samples.iter()).filter(|s| s.outputs[0] != [0.0; 3]).count();
        assert_eq!(with_outputs > 0, normals, "samples with an output variable: {with_outputs}");
        for r in &traced {
            let mut bytes = Vec::new();
            r.encode(&mut bytes);
            let back = LatticeSamples::decode(world, r.lattice, r.active, &bytes).expect("decodes");
            assert!(lattice_bits(&[back]) == lattice_bits(std::slice::from_ref(r)));
            for end in 0..bytes.len() {
                assert!(LatticeSamples::decode(world, r.lattice, r.active, &bytes[..end]).is_err(), "cut at {end}");
            }
            // Lanes that were not asked for, or another lattice's samples, are refused.
            assert!(LatticeSamples::decode(world, r.lattice, r.active >> 1, &bytes).is_err() || r.active == 0);
            let mut other = r.lattice;
            other.x0 += 8;
            assert!(LatticeSamples::decode(world, other, r.active, &bytes).is_err());
            // Samples with normals where none are read, or without where they are, are refused.
            assert!(LatticeSamples::decode(other_world, r.lattice, r.active, &bytes).is_err() || r.active == 0);
            if normals && r.active != 0 {
                // The first lane's normal (after the 20-byte header and its 32 bytes) made long.
                let mut damaged = bytes.clone();
                damaged[52..56].copy_from_slice(&1.5f32.to_le_bytes());
                assert!(LatticeSamples::decode(world, r.lattice, r.active, &damaged).is_err(), "a damaged normal");
            }
        }
    }
}

#[test]
fn workers_fetch_the_textures_shaders_look_up_and_only_those() -> Result<(), DistributedError> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let checks = |size: u32| {
        image::RgbImage::from_fn(size, size, |x, y| {
            image::Rgb(if (x + y) % 2 == 0 { [230, 40, 20] } else { [20, 90, 200] })
        })
    };
    checks(4).save(dir.path().join("seen.png")).expect("a PNG");
    checks(256).save(dir.path().join("unseen.png")).expect("a PNG");
    let unseen_bytes = std::fs::metadata(dir.path().join("unseen.png")).expect("written").len();

    let mut rt = little_scene().expect("the little scene");
    rt.add_texture_search_path(dir.path());
    let texels: Vec<f32> = (0..8 * 8 * 3).map(|i| ((i * 37) % 11) as f32 / 10.0).collect();
    rt.tex_image_2d("in-memory", 8, 8, 3, &texels).map_err(e).expect("a memory texture");
    let textured = |rt: &mut Context, name: &str| {
        let source = format!("surface t_{n}() {{ Ci = color texture(\"{name}\", s, t); Oi = 1; }}", n = name.len());
        rt.compile_shader(&format!("t_{}", name.len()), &source).map_err(e).expect("a shader")
    };
    let (seen, in_memory, unseen) =
        (textured(&mut rt, "seen.png"), textured(&mut rt, "in-memory"), textured(&mut rt, "unseen.png"));
    // The floor reads a file, the triangle a texture from memory; an object behind the camera
    // reads another file, which no ray ever asks for.
    for (object, shader) in [(0, seen), (1, in_memory)] {
        let id = rtsl_runtime::api::ObjectId(object);
        let corners: &[[f32; 3]] = if object == 0 {
            &[[-2.0, 0.0, -2.0], [2.0, 0.0, -2.0], [2.0, 0.0, 2.0], [-2.0, 0.0, 2.0]]
        } else {
            &[[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 1.0, 0.0], [-0.5, 1.0, 0.0]]
        };
        rt.redefine_object(id).map_err(e).expect("redefined");
        rt.bind_shader(shader).map_err(e).expect("bound");
        rt.begin(Primitive::Quads).map_err(e).expect("quads");
        for (k, p) in corners.iter().enumerate() {
            rt.tex_coord([0.0, 1.0, 1.0, 0.0][k], [0.0, 0.0, 1.0, 1.0][k]);
            rt.vertex(p[0], p[1], p[2]).map_err(e).expect("a vertex");
        }
        rt.end().map_err(e).expect("end");
        rt.end_object().map_err(e).expect("end_object");
    }
    let hidden = rt.begin_object().map_err(e).expect("an object");
    rt.bind_shader(unseen).map_err(e).expect("bound");
    rt.begin(Primitive::Triangles).map_err(e).expect("triangles");
    for p in [[0.0, 0.0, 9.0], [1.0, 0.0, 9.0], [0.0, 1.0, 9.0]] {
        rt.vertex(p[0], p[1], p[2]).map_err(e).expect("a vertex");
    }
    rt.end().map_err(e).expect("end");
    rt.end_object().map_err(e).expect("end_object");
    rt.instantiate_object(hidden).map_err(e).expect("an instance");

    let frames = with_two_workers(Duration::from_secs(60), |m| {
        frames_moving_once(m, &mut rt, 1, "a frame of fetched textures")
    })?;
    let (first, _) = frames[0];
    // Two textures, fetched by each of the two workers at most: the memory texture's 192 floats
    // (the first update said only that memory textures changed) and the small PNG, never the
    // large one.
    assert!((2..=4).contains(&first.fetched_textures), "{first:?}");
    assert!(first.fetched_texture_bytes > 0 && first.fetched_texture_bytes < unseen_bytes, "{first:?}");
    // Later frames fetch only what a worker had not looked up (a tile of the other worker's,
    // handed to it to balance the frame), each texture once, and never the large one.
    let mut fetched = first.fetched_textures;
    for (later, traffic) in &frames[1..] {
        // Fetches of anything: a worker may also meet an object for the first time in a tile it
        // never had before.
        let fetched_any = later.fetched_textures
            + later.fetched_texture_levels
            + later.fetched_texture_tiles
            + later.fetched_objects
            + later.fetched_parts;
        assert_eq!(traffic.fetches > 0, fetched_any > 0, "{later:?} {traffic:?}");
        assert!(later.fetched_texture_bytes < unseen_bytes, "{later:?}");
        fetched += later.fetched_textures;
    }
    assert!(fetched <= 4, "each worker fetches the two textures once at most: {frames:?}");
    Ok(())
}

#[test]
fn global_illumination_renders_the_same_on_workers() -> Result<(), DistributedError> {
    // Every worker traces the frame's light paths itself, from the same world and seed: the same
    // virtual lights, so the same image. The pixel shader reads other pixels: it runs on the
    // master over the whole image, the workers' tiles sent unfinished.
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, repo("examples/scenes/gi_box.rib")).expect("the scene loads");
    (rt.options.width, rt.options.height) = (40, 30);
    assert_same(&both_ways(rt, 2, 2, &[nothing, move_first])?, "a frame lit by virtual lights");
    Ok(())
}

/// The master traces a frame's light paths (virtual lights and caustic photons) once and sends
/// them to every worker: a frame of tiles carries its own, a viewer's pass sends them with its
/// first piece only, and the workers' samples are the ones traced here, bit for bit.
#[test]
fn the_master_traces_light_paths_once_and_sends_them() -> Result<(), DistributedError> {
    use rtsl_runtime::render::progressive::{pass_lattices, trace_lattices};
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, repo("examples/scenes/gi_box.rib")).expect("the scene loads");
    (rt.options.width, rt.options.height) = (32, 24);
    rt.options.gi.caustic_photons = 3000;
    rt.options.gi.global_photons = 1000;
    with_two_workers(Duration::from_secs(120), |master| {
        let world = rt.build_world().expect("a world");
        let (fb, _) = master.render_context(&rt, &world, None)?;
        let sent = master.traffic().light_paths;
        assert!(sent > 1000, "a frame of tiles sends its light paths: {sent} bytes");
        let (alone, _) = pool(2).install(|| rtsl_runtime::render::render_frame(&world, None));
        assert!(fb.rgba.iter().zip(&alone.rgba).all(|(a, b)| a.to_bits() == b.to_bits()), "the frame differs");

        let lattices = pass_lattices(32, 24, 1);
        let all = |_: u32, _: u32| true;
        let (first, rest) = lattices.split_at(lattices.len() / 2);
        let mut there = master.trace_lattices(&rt, &world, first, 2, false, &all)?.0;
        assert!(master.traffic().light_paths > 0, "the pass's first piece carries its paths");
        there.extend(master.trace_lattices(&rt, &world, rest, 2, false, &all)?.0);
        assert_eq!(master.traffic().light_paths, 0, "the pass's next piece does not");
        let (here, _) = pool(2).install(|| trace_lattices(&world, &lattices, 2, false, &all));
        assert!(lattice_bits(&there) == lattice_bits(&here), "the pass traced in pieces differs");
        master.trace_lattices(&rt, &world, first, 3, false, &all)?;
        assert!(master.traffic().light_paths > 0, "the next pass carries its own paths");
        rt.return_scene(world);
        Ok(())
    })
}

#[test]
fn light_paths_decode_to_themselves_and_damaged_ones_are_errors() {
    use rtsl_runtime::render::{LightPaths, TileRenderer};
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, repo("examples/scenes/gi_box.rib")).expect("the scene loads");
    rt.options.gi.caustic_photons = 2000;
    rt.options.gi.global_photons = 500;
    let world = rt.build_world().expect("a world");
    let renderer = TileRenderer::new(&world);
    renderer.prepare_light_paths();
    let paths = renderer.light_paths();
    assert!(paths.virtual_lights.is_some() && paths.caustics.is_some() && paths.global_photons.is_some());
    let mut bytes = Vec::new();
    paths.encode(&mut bytes);
    let back = LightPaths::decode(&bytes).expect("decodes");
    let mut again = Vec::new();
    back.encode(&mut again);
    assert!(again == bytes, "the paths decode to other paths");
    assert!(LightPaths::decode(&[]).expect("no paths").is_empty());
    for cut in [1, 5, 17, bytes.len() / 2, bytes.len() - 1] {
        assert!(LightPaths::decode(&bytes[..cut]).is_err(), "cut at {cut}");
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(LightPaths::decode(&longer).is_err(), "a byte too many");
    for at in [0, 3, 9, 20, bytes.len() - 2] {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0xff;
        let _ = LightPaths::decode(&damaged);
    }
    let mut huge = vec![1u8, 1, 0, 0, 0, 0, 0, 0, 0];
    huge.extend_from_slice(&1u64.to_le_bytes());
    huge.extend_from_slice(&u64::MAX.to_le_bytes());
    assert!(LightPaths::decode(&huge).is_err(), "a count no bytes hold");
}

/// An alpha mask is read when the world is built: a worker fetches its texture from the master
/// while it builds the frame's world, and cuts the object as one process does (a texture that
/// is missing leaves the object solid, with the same warning, instead of a worker waiting for
/// an answer no one sends).
#[test]
fn workers_fetch_alpha_masks_while_they_build_the_world() -> Result<(), DistributedError> {
    let dir = tempfile::tempdir().expect("a temporary directory");
    image::RgbaImage::from_fn(8, 8, |x, y| {
        image::Rgba([200, 200, 200, if (x / 2 + y / 2) % 2 == 0 { 255 } else { 0 }])
    })
    .save(dir.path().join("holes.png"))
    .expect("a PNG");
    let mut rt = little_scene().expect("the little scene");
    rt.add_texture_search_path(dir.path());
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let cut = |rt: &mut Context, name: &str| -> Result<(), String> {
        rt.alpha_mask(Some(name));
        let plastic = rt.find_shader("plastic").map_err(e)?;
        let quad = rt.begin_object().map_err(e)?;
        rt.bind_shader(plastic).map_err(e)?;
        rt.begin(Primitive::Quads).map_err(e)?;
        for (x, y) in [(-1.0, 0.2), (1.0, 0.2), (1.0, 1.6), (-1.0, 1.6)] {
            rt.vertex(x, y, 0.8).map_err(e)?;
        }
        rt.end().map_err(e)?;
        rt.end_object().map_err(e)?;
        rt.instantiate_object(quad).map_err(e)?;
        rt.alpha_mask(None);
        Ok(())
    };
    cut(&mut rt, "holes.png").expect("a cut-out quad");
    cut(&mut rt, "missing.png").expect("a solid quad");
    let frames = both_ways(rt, 2, 1, &[nothing])?;
    assert_same(&frames, "a scene with alpha masks");
    Ok(())
}

/// A new scene whose meshes the workers fetched for the scene just before (a RIB file's next
/// frame declaring its set again) takes them rather than fetching them again: the second of two
/// contexts of the same scene fetches no mesh and every object its rays reach is a hit; a scene
/// of other meshes fetches its own, and so does the first scene once more after it (the workers
/// keep the meshes of the scene before only). Every image is the single process's.
#[test]
fn a_new_scene_takes_the_meshes_the_scene_before_fetched() -> Result<(), DistributedError> {
    let demands = with_two_workers(Duration::from_secs(120), |master| {
        let mut frames = Vec::new();
        let mut demands = Vec::new();
        for scene in [little_scene(), little_scene(), sparse_scene(), little_scene()] {
            let (frame, demand) = frame_both_ways(master, &mut scene.expect("a scene"))?;
            frames.push(frame);
            demands.push(demand);
        }
        assert_same(&frames, "scenes one after another, sharing meshes");
        Ok(demands)
    })?;
    let [first, again, other, last] = &demands[..] else { panic!("four frames") };
    assert!(first.fetched_objects >= 2 && first.kept_objects == 0, "{first:?}");
    // The same meshes again: taken from the scene before, fetched only where a worker reached
    // one it had not (a tile of the other worker's, handed to it to balance the frame).
    assert_eq!(again.kept_objects, first.resident_objects, "{again:?}");
    assert!(first.fetched_objects + again.fetched_objects <= 4, "{first:?} {again:?}");
    assert!(again.reached_objects >= 2, "{again:?}");
    assert!(other.fetched_objects >= 1 && other.kept_objects == 0, "{other:?}");
    // After a scene of other meshes, none of the first scene's is held: fetched again.
    assert!(last.fetched_objects >= 2 && last.kept_objects == 0, "{last:?}");
    Ok(())
}

/// A new scene whose texture is the one the scene before showed under the same name (a RIB
/// file's next frame) takes the map the workers made of it, with the levels they fetched: the
/// master answers that it is unchanged, in a few bytes. A texture of the same name with other
/// texels is fetched anew. Every image is the single process's.
#[test]
fn a_new_scene_takes_the_texture_levels_the_scene_before_fetched() -> Result<(), DistributedError> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let textured = |seed: usize| -> Result<Context, String> {
        let mut rt = Context::new();
        // Near enough that lookups read finer levels than travel with the description.
        rt.options.width = 96;
        rt.options.height = 80;
        rt.camera_look_at(Vec3A::new(0.0, 0.0, 2.5), Vec3A::ZERO, Vec3A::Y, 45.0);
        checks(&mut rt, 512, seed)?;
        let shader = rt
            .compile_shader("textured", "surface textured() { Ci = color texture(\"checks\", s, t); Oi = 1; }")
            .map_err(e)?;
        textured_quad(&mut rt, shader, [[-1.5, -1.5, 0.0], [1.5, -1.5, 0.0], [1.5, 1.5, 0.0], [-1.5, 1.5, 0.0]])?;
        Ok(rt)
    };
    let demands = with_two_workers(Duration::from_secs(120), |master| {
        let mut frames = Vec::new();
        let mut demands = Vec::new();
        for seed in [37, 37, 41] {
            let (frame, demand) = frame_both_ways(master, &mut textured(seed).expect("a textured scene"))?;
            frames.push(frame);
            demands.push(demand);
        }
        assert_same(&frames, "scenes one after another, sharing a texture");
        assert!(frames[1].1.rgba != frames[2].1.rgba, "other texels show");
        Ok(demands)
    })?;
    let [first, again, other] = &demands[..] else { panic!("three frames") };
    assert!(first.fetched_texture_levels >= 1 && first.kept_textures == 0, "{first:?}");
    // Each worker that looked the texture up asked for it once more, with the digest of what it
    // held, and took its map.
    assert_eq!(again.fetched_texture_levels, 0, "{again:?}");
    assert!(again.kept_textures >= 1 && again.kept_textures == again.fetched_textures, "{again:?}");
    assert!(again.fetched_texture_bytes <= 8 * again.fetched_textures, "{first:?} {again:?}");
    assert_eq!(other.kept_textures, 0, "{other:?}");
    assert!(other.fetched_texture_levels >= 1, "{other:?}");
    Ok(())
}

/// The little scene with ground far wider than the view under its floor (28,160 triangles,
/// most of them outside the frustum); returns the ground's object.
fn little_scene_on_wide_ground() -> (Context, rtsl_runtime::api::ObjectId) {
    let mut rt = little_scene().expect("the little scene");
    let at =
        |i: u32, k: u32| [-40.0 + i as f32 * 0.5, -0.05 + 0.01 * ((i * 7 + k * 3) % 5) as f32, 3.9 - k as f32 * 0.5];
    let ground = grid_object(&mut rt, (160, 88), at);
    (rt, ground)
}

/// An object of `nx` by `nk` quads (two triangles each) whose corner `(i, k)` is `at(i, k)`, and
/// an instance of it.
fn grid_object(
    rt: &mut Context,
    (nx, nk): (u32, u32),
    at: impl Fn(u32, u32) -> [f32; 3],
) -> rtsl_runtime::api::ObjectId {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let object = rt.begin_object().map_err(e).expect("an object");
    rt.begin(Primitive::Triangles).map_err(e).expect("triangles");
    for k in 0..nk {
        for i in 0..nx {
            for [a, b] in [[(i, k), (i + 1, k)], [(i + 1, k), (i + 1, k + 1)]] {
                for p in [at(i, k), at(a.0, a.1), at(b.0, b.1)] {
                    rt.vertex(p[0], p[1], p[2]).map_err(e).expect("a vertex");
                }
            }
        }
    }
    rt.end().map_err(e).expect("end");
    rt.end_object().map_err(e).expect("end_object");
    rt.instantiate_object(object).map_err(e).expect("an instance");
    object
}

/// A large object travels in parts: a worker fetches its mesh and small tree, then only the
/// parts of its BVH that its rays reach, each once; frames are the single process's, bit for bit.
/// One worker renders every tile of every frame, so nothing is fetched for a frame that changes
/// nothing. Of two, one that runs ahead takes tiles the other had (`schedule.rs`), as timing has
/// it, and then fetches what those reach: still only what it does not hold.
#[test]
fn workers_fetch_the_parts_of_a_large_object_that_rays_reach() -> Result<(), DistributedError> {
    let (mut rt, ground) = little_scene_on_wide_ground();
    let world = rt.build_world().expect("a world");
    let bvh = rt.object_bvh(ground, &world).expect("the ground's BVH");
    let parts = rtsl_runtime::accel::parts::cut(bvh, 256).parts.len() as u64;
    rt.return_scene(world);
    assert!(parts > 50, "{parts} parts");

    for workers in [1, 2] {
        let demands = with_workers(workers, Duration::from_secs(60), |m| {
            m.set_parts(1000, 256);
            frames_moving_once(m, &mut rt, 2, "a frame with an object in parts")
        })?;
        let (first, _) = demands[0];
        // The workers reached the ground, and fetched fewer of its parts together than it has.
        assert!(first.fetched_parts > 2 && first.fetched_parts < parts, "{first:?} of {parts} parts");
        assert_eq!(first.resident_parts, first.fetched_parts, "{first:?}");
        let (mut objects, mut resident) = (first.resident_objects, first.resident_parts);
        for (frame, (later, traffic)) in demands.iter().enumerate().skip(1) {
            // The frame before the move sees what the first saw; after it, rays may reach parts
            // that none reached before (the moved object's shadow falls elsewhere).
            if workers == 1 && frame == 1 {
                assert_eq!((later.fetched_objects, later.fetched_parts, traffic.fetches), (0, 0, 0), "{later:?}");
            }
            // Nothing held is fetched again, and nothing is evicted.
            assert_eq!(later.resident_parts, resident + later.fetched_parts, "{later:?}");
            assert_eq!(later.resident_objects, objects + later.fetched_objects, "{later:?}");
            (objects, resident) = (later.resident_objects, later.resident_parts);
        }
    }
    Ok(())
}

/// An object in parts that a worker's rays reach whole (a wall in full view) has every part
/// fetched in the first frame; from the next frame the worker traverses it as the one tree the
/// master cut it from (`Object::join_parts`): it holds no parts any more, fetches nothing, and
/// its frames, the instance moved included, are still the single process's, bit for bit, whether
/// the parts travelled plain or deflated.
#[test]
fn an_object_reached_whole_is_joined_from_its_parts() -> Result<(), DistributedError> {
    let mut rt = little_scene().expect("the little scene");
    let at = |i: u32, k: u32| [-1.5 + i as f32 * 0.05, 1.0 + k as f32 * 0.05, -1.0 - 0.01 * ((i * 3 + k) % 4) as f32];
    let wall = grid_object(&mut rt, (60, 20), at);
    let world = rt.build_world().expect("a world");
    let bvh = rt.object_bvh(wall, &world).expect("the wall's BVH");
    let parts = rtsl_runtime::accel::parts::cut(bvh, 256).parts.len() as u64;
    rt.return_scene(world);
    assert!(parts > 8, "{parts} parts");

    // Plain (ranks that share memory) and deflated (between machines): the same frames.
    let mut part_bytes = Vec::new();
    for deflated in [false, true] {
        let demands = with_workers(1, Duration::from_secs(60), |m| {
            m.set_parts(1000, 256);
            m.set_deflate(deflated);
            frames_moving_once(m, &mut rt, 2, "frames of an object joined from its parts")
        })?;
        let (first, _) = demands[0];
        assert_eq!((first.fetched_parts, first.resident_parts), (parts, parts), "{first:?}");
        for (later, traffic) in &demands[1..] {
            assert_eq!((later.fetched_objects, later.fetched_parts, traffic.fetches), (0, 0, 0), "{later:?}");
            assert_eq!((later.resident_parts, later.resident_objects), (0, first.resident_objects), "{later:?}");
            assert_eq!((later.evicted_objects, later.evicted_parts), (0, 0), "{later:?}");
        }
        part_bytes.push(first.fetched_part_bytes);
    }
    assert!(part_bytes[1] < part_bytes[0], "deflated against plain: {part_bytes:?}");
    Ok(())
}

/// A cache too small for anything drops a large object's parts, then the object, before each
/// frame; the frame fetches what it reaches again and is still the single process's.
#[test]
fn a_full_cache_evicts_parts_and_fetches_them_again() -> Result<(), DistributedError> {
    let (mut rt, _) = little_scene_on_wide_ground();
    let mut group = LocalTransport::group(2, Duration::from_secs(60)).into_iter();
    let master_end = group.next().expect("rank 0");
    let worker_end = group.next().expect("rank 1");
    let worker = std::thread::spawn(move || serve(&worker_end, Ok(&mut ReplicaScene::with_cache_limit(1)), &pool(2)));
    let mut master = Master::connect(master_end)?;
    master.set_parts(1000, 256);
    let demands: Vec<Demand> = frames_moving_once(&mut master, &mut rt, 1, "a frame of parts from an evicted cache")?
        .into_iter()
        .map(|(demand, _)| demand)
        .collect();
    master.shutdown()?;
    worker.join().expect("the worker thread")?;
    let first = demands[0];
    assert!(first.fetched_parts > 2 && first.evicted_parts == 0, "{demands:?}");
    // Each frame drops all the frame before held and fetches again all it holds. How many parts
    // that is may differ from frame to frame: a render that asks ahead treats a part not yet
    // come as missed and goes on past it, to parts the finished frame's rays need not reach, and
    // what has come by then is a matter of timing.
    for (before, d) in demands.iter().zip(&demands[1..]) {
        assert_eq!(d.evicted_parts, before.resident_parts, "{demands:?}");
        assert_eq!(d.fetched_parts, d.resident_parts, "{demands:?}");
        assert!(d.fetched_parts > 2, "{demands:?}");
        assert_eq!(d.evicted_objects, 3, "{demands:?}");
    }
    Ok(())
}

/// A replica that takes a while to build its first world, as a worker does that must fetch much
/// before it renders, or that the system does not run for a while.
struct SlowToStart {
    scene: ReplicaScene,
    delay: Option<Duration>,
}

impl rtsl_runtime::distributed::WorkerScene for SlowToStart {
    fn world(&mut self, update: &[u8]) -> Result<rtsl_runtime::render::World, String> {
        if let Some(delay) = self.delay.take() {
            std::thread::sleep(delay);
        }
        self.scene.world(update)
    }
    fn finished(&mut self, world: rtsl_runtime::render::World) {
        self.scene.finished(world)
    }
    fn start_again(&mut self) {
        self.scene.start_again()
    }
    fn fetch_link(&self) -> Option<std::sync::Arc<rtsl_runtime::distributed::fetch::FetchLink>> {
        self.scene.fetch_link()
    }
}

/// Once every tile is handed out, a worker with nothing to do renders copies of the tiles a slow
/// worker holds and has not started; the slow one leaves out those delivered first, even when
/// it hears of them while it still builds its world. The frames are the single process's, bit
/// for bit, the first and the one after.
#[test]
fn idle_workers_render_copies_of_the_tiles_a_slow_worker_has_not_started() -> Result<(), DistributedError> {
    let mut rt = little_scene().map_err(|m| DistributedError::Worker { rank: 0, message: m })?;
    (rt.options.width, rt.options.height) = (160, 128);
    let mut group = LocalTransport::group(3, Duration::from_secs(120)).into_iter();
    let master_end = group.next().expect("rank 0");
    let fast = group.next().expect("rank 1");
    let slow = group.next().expect("rank 2");
    let handles = [
        std::thread::spawn(move || serve(&fast, Ok(&mut ReplicaScene::new()), &pool(1))),
        std::thread::spawn(move || {
            let mut scene = SlowToStart { scene: ReplicaScene::new(), delay: Some(Duration::from_secs(3)) };
            serve(&slow, Ok(&mut scene), &pool(1))
        }),
    ];
    let mut master = Master::connect(master_end)?;
    let mut frames = Vec::new();
    let mut helping = Vec::new();
    for change in [nothing as Change, move_first] {
        change(&mut rt).expect("the change applies");
        let (frame, _) = frame_both_ways(&mut master, &mut rt)?;
        frames.push(frame);
        helping.push(master.worker_time().helping);
    }
    master.shutdown()?;
    for h in handles {
        h.join().expect("a worker thread")?;
    }
    assert_same(&frames, "frames with a slow worker");
    // The slow worker was handed several tiles first: the fast one rendered all but the one it
    // renders first, and delivered them before it.
    let first = helping[0];
    assert!(first.helped > 0 && first.helped <= first.copies, "{first:?}");
    assert!(first.copies + first.twice <= 80, "{first:?}");
    Ok(())
}

/// The master decodes the textures the scene's shader parameters name before any worker asks,
/// and a worker still fetches only what its lookups read: a texture named by an object no ray
/// reaches is decoded on the master and never sent.
#[test]
fn the_master_decodes_named_textures_ahead_and_workers_fetch_only_what_they_read() -> Result<(), DistributedError> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let checks = |size: u32| {
        image::RgbImage::from_fn(size, size, |x, y| {
            image::Rgb(if (x / 2 + y) % 2 == 0 { [200, 60, 30] } else { [30, 60, 200] })
        })
    };
    checks(8).save(dir.path().join("seen.png")).expect("a PNG");
    checks(256).save(dir.path().join("unseen.png")).expect("a PNG");
    let unseen_bytes = std::fs::metadata(dir.path().join("unseen.png")).expect("written").len();
    let mut rt = little_scene().expect("the little scene");
    rt.add_texture_search_path(dir.path());
    let paper = "surface paper(string texname = \"\") { Ci = color texture(texname, s, t); Oi = 1; }";
    let paper = rt.compile_shader("paper", paper).map_err(e).expect("a shader");
    let named = |texture: &str| [("texname", ParamValue::from(texture))];
    let front = [[-1.0, 0.5, 0.5], [1.0, 0.5, 0.5], [1.0, 1.5, 0.5], [-1.0, 1.5, 0.5]];
    textured_quad_with(&mut rt, paper, &named("seen.png"), front).expect("a quad");
    let behind_the_camera = [[0.0, 0.0, 9.0], [1.0, 0.0, 9.0], [1.0, 1.0, 9.0], [0.0, 1.0, 9.0]];
    textured_quad_with(&mut rt, paper, &named("unseen.png"), behind_the_camera).expect("a quad");
    let (decoded, fetched_bytes) = with_two_workers(Duration::from_secs(60), |m| {
        let mut fetched_bytes = 0;
        // The master decodes one named texture at a time while a frame runs: a few frames
        // give it the time.
        for _ in 0..40 {
            let ((distributed, alone, _), demand) = frame_both_ways(m, &mut rt)?;
            assert_same(&[(distributed, alone, 0)], "a frame of a textured quad");
            fetched_bytes += demand.fetched_texture_bytes;
            if m.decoded_textures() == 2 {
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok((m.decoded_textures(), fetched_bytes))
    })?;
    assert_eq!(decoded, 2, "both named textures decoded on the master");
    assert!(fetched_bytes > 0 && fetched_bytes < unseen_bytes, "the workers fetched {fetched_bytes} bytes");
    Ok(())
}

/// A wall of `side` x `side` objects, a quad each, filling a view of 96x80 pixels, under a light
/// whose shadow rays reach the wall.
fn wall_of_objects(side: usize) -> Result<Context, String> {
    wall(side, None)
}

/// [`wall_of_objects`], each quad showing one of `textures` memory textures of 16x16 texels
/// ("wall0" and on), when given.
fn wall(side: usize, textures: Option<usize>) -> Result<Context, String> {
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    rt.options.width = 96;
    rt.options.height = 80;
    rt.camera_look_at(Vec3A::new(0.0, 0.0, 3.0), Vec3A::ZERO, Vec3A::Y, 60.0);
    let plastic = rt.find_shader("plastic").map_err(e)?;
    let textured = match textures {
        Some(n) => {
            for t in 0..n {
                let texels: Vec<f32> = (0..16 * 16 * 3).map(|i| ((i * (t + 3)) % 13) as f32 / 12.0).collect();
                rt.tex_image_2d(&format!("wall{t}"), 16, 16, 3, &texels).map_err(e)?;
            }
            let source = "surface wallpaper(string name = \"\") { Ci = color texture(name, s, t); Oi = 1; }";
            Some((rt.compile_shader("wallpaper", source).map_err(e)?, n))
        }
        None => None,
    };
    let step = 4.0 / side as f32;
    for k in 0..side * side {
        let (x, y) = (-2.0 + (k % side) as f32 * step, -2.0 + (k / side) as f32 * step);
        let quad = rt.begin_object().map_err(e)?;
        rt.color(0.3 + 0.6 * (k % 3) as f32 / 2.0, 0.5, 0.2 + 0.1 * (k % 5) as f32);
        match textured {
            Some((shader, n)) => {
                rt.bind_shader(shader).map_err(e)?;
                rt.parameter("name", ParamValue::String(format!("wall{}", k % n))).map_err(e)?;
            }
            None => rt.bind_shader(plastic).map_err(e)?,
        }
        rt.begin(Primitive::Quads).map_err(e)?;
        for (c, (dx, dy)) in [(0.0, 0.0), (step, 0.0), (step, step), (0.0, step)].into_iter().enumerate() {
            rt.tex_coord([0.0, 1.0, 1.0, 0.0][c], [0.0, 0.0, 1.0, 1.0][c]);
            rt.vertex(x + dx, y + dy, -0.1 * (k % 4) as f32).map_err(e)?;
        }
        rt.end().map_err(e)?;
        rt.end_object().map_err(e)?;
        rt.instantiate_object(quad).map_err(e)?;
    }
    let light = rt.find_shader("pointlight").map_err(e)?;
    rt.translate(0.5, 1.0, 2.0);
    rt.light_source(light, &[("intensity", ParamValue::Float(6.0))]).map_err(e)?;
    rt.load_identity();
    Ok(rt)
}

/// Two frames of `rt` (the second after [`move_first`]) over a master and one worker of one
/// thread asking ahead or not, each checked bit for bit against this process's; the tiles set
/// aside in each, and what each fetched.
fn two_frames_over_one_worker(mut rt: Context, ahead: bool) -> Result<(Vec<u64>, Vec<Demand>), DistributedError> {
    let mut group = LocalTransport::group(2, Duration::from_secs(60)).into_iter();
    let master_end = group.next().expect("rank 0");
    let worker_end = group.next().expect("rank 1");
    let worker =
        std::thread::spawn(move || serve(&worker_end, Ok(&mut ReplicaScene::new().asking_ahead(ahead)), &pool(1)));
    let mut master = Master::connect(master_end)?;
    let (mut set_aside, mut demands) = (Vec::new(), Vec::new());
    for change in [nothing as Change, move_first] {
        change(&mut rt).expect("the change applies");
        let (frame, demand) = frame_both_ways(&mut master, &mut rt)?;
        assert_same(&[frame], &format!("a frame asking ahead: {ahead}"));
        set_aside.push(master.worker_time().set_aside);
        demands.push(demand);
    }
    master.shutdown()?;
    worker.join().expect("the worker thread")?;
    Ok((set_aside, demands))
}

/// A worker's render thread with other tiles waiting asks ahead for the objects a tile reaches
/// and does not hold, sets the tile aside and renders it again once they are here: frames are the
/// single process's bit for bit, each object is fetched once, and a worker told not to ask ahead
/// waits instead and sets nothing aside.
#[test]
fn tiles_that_reach_objects_not_here_are_set_aside_and_rendered_again() -> Result<(), DistributedError> {
    for ahead in [true, false] {
        let (set_aside, demands) = two_frames_over_one_worker(wall_of_objects(6).expect("the wall"), ahead)?;
        // Every quad is reached, and fetched once: set-aside tiles take what they asked for.
        assert_eq!((demands[0].reached_objects, demands[0].fetched_objects), (36, 36), "{demands:?}");
        assert_eq!(demands[1].fetched_objects, 0, "{demands:?}");
        if ahead {
            assert!(set_aside[0] > 0, "tiles of the first frame reach objects not here: {set_aside:?}");
        } else {
            assert_eq!(set_aside[0], 0);
        }
        // Everything is here in the second frame: nothing to ask for.
        assert_eq!(set_aside[1], 0, "{set_aside:?}");
    }
    Ok(())
}

/// As [`tiles_that_reach_objects_not_here_are_set_aside_and_rendered_again`], for textures: a
/// tile asks ahead for the textures its lookups name and the worker does not hold, and each
/// texture is fetched once.
#[test]
fn tiles_ask_ahead_for_the_textures_their_lookups_name() -> Result<(), DistributedError> {
    let (set_aside, demands) = two_frames_over_one_worker(wall(4, Some(5)).expect("the textured wall"), true)?;
    assert!(set_aside[0] > 0, "{set_aside:?}");
    assert_eq!(demands[0].fetched_textures, 5, "{demands:?}");
    assert_eq!((demands[1].fetched_textures, demands[1].fetched_objects), (0, 0), "{demands:?}");
    Ok(())
}

/// A sphere truly displaced by the shaders `shading` binds, on a floor, lit by a spotlight.
fn displaced_sphere_on_a_floor(shading: &str) -> String {
    format!(
        r#"
        Format 80 60 1
        Projection "perspective" "fov" 50
        Translate 0 0 7
        WorldBegin
          LightSource "spotlight" 1 "from" [2 4 -2] "to" [0 0 0] "intensity" 40 "coneangle" 0.9
          AttributeBegin
            Attribute "displacementbound" "sphere" [0.3]
            {shading}
            Sphere 1 -1 1 360
          AttributeEnd
          Surface "matte"
          Polygon "P" [-5 -1.3 -5  5 -1.3 -5  5 -1.3 5  -5 -1.3 5]
        WorldEnd
    "#
    )
}

/// A sphere truly displaced into ridges (its `displacementbound` asks for it) over a floor, lit
/// so that its shadow falls on the floor; and an object of two spheres in parts, of which only
/// the first moves its points (the second is bump-mapped), placed twice.
fn displaced_scene() -> Result<Context, String> {
    const RIDGES: &str = "displacement ridges(float amount = 0.3) {
        point Po = transform(\"object\", P);
        P += amount * (0.5 + 0.5 * sin(12 * zcomp(Po))) * normalize(N);
        N = calculatenormal(P);
    }";
    let rib = displaced_sphere_on_a_floor("Displacement \"ridges\" Surface \"plastic\"");
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    rt.compile_shader("ridges.sl", RIDGES).map_err(e)?;
    let bump = rt.compile_shader("bumponly.sl", BUMP_ONLY).map_err(e)?;
    rtsl_runtime::rib::load::load_str(&mut rt, &rib, Path::new(".")).map_err(|e| e.to_string())?;
    let ridges = rt.find_shader("ridges").map_err(e)?;
    let plastic = rt.find_shader("plastic").map_err(e)?;
    rt.bind_shader(plastic).map_err(e)?;
    let sphere = rtsl_runtime::api::Quadric::Sphere { radius: 0.4, zmin: -0.4, zmax: 0.4, thetamax: 360.0 };
    let pair = rt.begin_object().map_err(e)?;
    rt.push_matrix();
    rt.translate(-0.5, 0.0, 0.0);
    rt.quadric(&sphere).map_err(e)?;
    rt.displacement(Some(ridges), &[("amount", ParamValue::Float(0.15))]).map_err(e)?;
    rt.true_displacement(Some(true));
    rt.end_part().map_err(e)?;
    rt.translate(1.0, 0.0, 0.0);
    rt.quadric(&sphere).map_err(e)?;
    rt.displacement(Some(bump), &[]).map_err(e)?;
    rt.true_displacement(None);
    rt.pop_matrix().map_err(e)?;
    rt.end_object().map_err(e)?;
    for (x, y) in [(-2.3, 1.2), (2.3, 1.2)] {
        rt.push_matrix();
        rt.translate(x, y, 1.0);
        rt.instantiate_object(pair).map_err(e)?;
        rt.pop_matrix().map_err(e)?;
    }
    Ok(rt)
}

/// Removes the first instance.
fn delete_first(rt: &mut Context) -> Result<(), String> {
    let id = *rt.world_instance_ids().first().ok_or("no instance")?;
    rt.delete_instance(id).map_err(|e| e.to_string())
}

/// True displacement on workers: the master dices and displaces, and the workers fetch the
/// displaced meshes as they fetch any other, so silhouettes and shadows are the displaced ones,
/// bit for bit the single process's, frame after frame: moved (displaced again), unchanged (the
/// update is empty), and with the first displaced instance gone.
#[test]
fn truly_displaced_objects_render_the_same_on_workers() -> Result<(), DistributedError> {
    let changes: [Change; 5] = [nothing, move_first, nothing, delete_first, nothing];
    let frames = both_ways(displaced_scene().expect("the scene"), 2, 2, &changes)?;
    assert_same(&frames, "truly displaced spheres");
    let updates: Vec<u64> = frames.iter().map(|f| f.2).collect();
    assert!(updates[0] > 0 && updates[1] > 0 && updates[3] > 0, "{updates:?}");
    assert_eq!((updates[2], updates[4]), (0, 0), "{updates:?}");
    Ok(())
}

/// A surface shader that moves `P` truly displaces too; its hits are shaded where its points
/// were before it moved them, which its displaced mesh carries to the workers with the points.
#[test]
fn surface_displaced_objects_render_the_same_on_workers() -> Result<(), DistributedError> {
    const RIDGED: &str = "surface ridged(float amount = 0.3) {
        point Po = transform(\"object\", P);
        P += amount * (0.5 + 0.5 * sin(12 * zcomp(Po))) * normalize(N);
        N = calculatenormal(P);
        normal Nf = faceforward(normalize(N), I);
        Oi = 1;
        Ci = Cs * (0.1 + diffuse(Nf)) + length(Po) * color(0, 0.2, 0);
    }";
    let mut rt = Context::new();
    rt.compile_shader("ridged.sl", RIDGED).expect("compiles");
    let rib = displaced_sphere_on_a_floor("Surface \"ridged\"");
    rtsl_runtime::rib::load::load_str(&mut rt, &rib, Path::new(".")).expect("the scene loads");
    let frames = both_ways(rt, 2, 1, &[nothing, move_first])?;
    assert_same(&frames, "a scene displaced by its surface shader");
    Ok(())
}

/// A displaced floor much nearer the camera at its front than at its back is split into pieces
/// before it is diced; the workers are told how many triangles each source triangle made, and
/// render the master's mesh.
#[test]
fn a_displaced_floor_split_before_dicing_renders_the_same_on_workers() -> Result<(), DistributedError> {
    const WAVES: &str = "displacement waves(float amount = 0.2) {
        point Pw = transform(\"world\", P);
        P += amount * sin(6 * xcomp(Pw)) * sin(6 * zcomp(Pw)) * normalize(N);
        N = calculatenormal(P);
    }";
    let mut rt = Context::new();
    rt.compile_shader("waves.sl", WAVES).expect("compiles");
    let rib = displaced_sphere_on_a_floor("Surface \"matte\"").replace(
        "Surface \"matte\"\n          Polygon",
        "Attribute \"displacementbound\" \"sphere\" [0.2] Displacement \"waves\" Surface \"matte\"\n          Polygon",
    );
    assert!(rib.contains("\"waves\" Surface \"matte\"\n          Polygon"), "{rib}");
    rtsl_runtime::rib::load::load_str(&mut rt, &rib, Path::new(".")).expect("the scene loads");
    let frames = both_ways(rt, 2, 1, &[nothing])?;
    assert_same(&frames, "a displaced floor split before dicing");
    Ok(())
}

/// A RIB file's next frame is a new scene whose displaced meshes come out the same: the worker
/// takes the displaced meshes it fetched for the frame before (by digest), fetching none. (One
/// worker, which renders every tile of both frames: two would each reach what their tiles reach,
/// which differs from frame to frame.)
#[test]
fn a_new_scene_takes_the_displaced_meshes_the_scene_before_fetched() -> Result<(), DistributedError> {
    let demands = with_workers(1, Duration::from_secs(120), |master| {
        let mut frames = Vec::new();
        let mut demands = Vec::new();
        for _ in 0..2 {
            let (frame, demand) = frame_both_ways(master, &mut displaced_scene().expect("the scene"))?;
            frames.push(frame);
            demands.push(demand);
        }
        assert_same(&frames, "truly displaced scenes one after another");
        Ok(demands)
    })?;
    let [first, again] = &demands[..] else { panic!("two frames") };
    // The displaced sphere and the displaced part of the pair, twice, with the floor.
    assert!(first.fetched_objects >= 4 && first.fetched_bytes > 100_000, "{first:?}");
    assert_eq!((again.fetched_objects, again.fetched_parts), (0, 0), "{again:?}");
    assert!(again.kept_objects >= first.fetched_objects, "{again:?}");
    Ok(())
}

/// Deforming meshes truly displaced (at both ends of their deformation) travel to the workers
/// with their displaced deformations: the motion-blurred frame is the one rendered here.
#[test]
fn deforming_displaced_meshes_render_the_same_on_workers() -> Result<(), DistributedError> {
    const INFLATE: &str = "displacement inflate(float amount = 0.25) {
        P += amount * normalize(N);
        N = calculatenormal(P);
    }";
    // Every object of the scene inflated, truly.
    let rib = DEFORMING.replacen(
        "Surface \"plastic\"",
        "Attribute \"displacementbound\" \"sphere\" [0.25] Displacement \"inflate\" Surface \"plastic\"",
        1,
    );
    let mut rt = Context::new();
    rt.compile_shader("inflate.sl", INFLATE).expect("compiles");
    rtsl_runtime::rib::load::load_str(&mut rt, &rib, Path::new(".")).expect("the scene loads");
    let frames = both_ways(rt, 2, 1, &[nothing, move_first])?;
    assert_same(&frames, "a deforming, truly displaced scene");
    Ok(())
}
