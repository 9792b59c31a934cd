//! The master and its workers as threads of this process (`LocalTransport`): images bit for bit
//! the single-process ones, each frame's update applied before its tiles, and failures reported
//! by the master, named by rank, never a hang.

use rtsl_runtime::api::Context;
use rtsl_runtime::distributed::{serve, DistributedError, LocalTransport, Master, Message, Transport, WorkerScene};
use rtsl_runtime::render::{render_frame, FilterKind, Framebuffer, PixelFilter, World};
use rtsl_runtime::shading::ParamValue;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// A scene as every rank makes it: the same calls give the same world.
type MakeScene = fn() -> Result<Context, String>;

/// Each frame's update is a time step that moves the first instance.
struct Moving(Context);

fn apply(rt: &mut Context, update: &[u8]) -> Result<(), String> {
    if let [step] = update {
        let id = *rt.world_instance_ids().first().ok_or("no instance")?;
        let t = rt.instance_transform(id).map_err(|e| e.to_string())?;
        let moved = rtsl_runtime::glam::Affine3A::from_translation([0.05 * f32::from(*step), 0.0, 0.0].into()) * t;
        rt.set_instance_transform(id, moved).map_err(|e| e.to_string())?;
    }
    Ok(())
}

impl WorkerScene for Moving {
    fn world(&mut self, update: &[u8]) -> Result<World, String> {
        apply(&mut self.0, update)?;
        self.0.build_world().map_err(|e| e.to_string())
    }
    fn finished(&mut self, world: World) {
        self.0.return_scene(world);
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool")
}

/// A worker rank: makes the scene, then serves the master.
fn run_worker(transport: &LocalTransport, make: MakeScene, threads: usize) -> Result<(), DistributedError> {
    match make() {
        Ok(rt) => serve(transport, Ok(&mut Moving(rt)), &pool(threads)),
        Err(e) => serve(transport, Err(e), &pool(threads)),
    }
}

/// Renders the frames of `updates` with `workers` worker threads of `threads` threads each, and
/// in this process alone; returns both images of each frame.
fn both_ways(
    make: MakeScene,
    workers: usize,
    threads: usize,
    updates: &[&[u8]],
) -> Result<Vec<(Framebuffer, Framebuffer)>, DistributedError> {
    let mut group = LocalTransport::group(workers + 1, Duration::from_secs(120)).into_iter();
    let master_end = group.next().expect("rank 0");
    let handles: Vec<_> = group.map(|t| std::thread::spawn(move || run_worker(&t, make, threads))).collect();
    let mut master = Master::connect(master_end)?;
    master.check_workers()?;
    let mut here = make().expect("the scene loads");
    let mut out = Vec::new();
    for update in updates {
        apply(&mut here, update).expect("the update applies");
        let world = here.build_world().expect("a world");
        let (distributed, report) = master.render_frame(&world, update, None)?;
        assert_eq!(report.threads, workers * threads);
        assert!(report.primary_rays >= u64::from(world.options.width * world.options.height));
        let (alone, _) = pool(2).install(|| render_frame(&world, None));
        here.return_scene(world);
        out.push((distributed, alone));
    }
    master.shutdown()?;
    for h in handles {
        h.join().expect("a worker thread")?;
    }
    Ok(out)
}

fn assert_same(pairs: &[(Framebuffer, Framebuffer)], what: &str) {
    for (k, (distributed, alone)) in pairs.iter().enumerate() {
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
    rtsl_runtime::rib::load::load_file(&mut rt, &repo("examples/office/office.rib")).map_err(|e| e.to_string())?;
    rt.options.width = 96;
    rt.options.height = 72;
    Ok(rt)
}

/// The library scene through a fisheye camera shader and an exposure pixel shader, 2x2 samples
/// splatted through a Gaussian filter (whose films the master adds up).
fn library_with_camera_and_pixel_shader() -> Result<Context, String> {
    let mut rt = Context::new();
    rtsl_runtime::rib::load::load_file(&mut rt, &repo("examples/scenes/library.rib")).map_err(|e| e.to_string())?;
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
    assert_same(&both_ways(office, 2, 1, &[&[], &[3], &[7]])?, "the office");
    assert_same(&both_ways(library_with_camera_and_pixel_shader, 3, 2, &[&[]])?, "the library scene");
    Ok(())
}

#[test]
fn a_bart_frame_is_bit_identical() -> Result<(), DistributedError> {
    let robots = repo("../shared/scenes/bart/robot/aff/Robot.aff");
    if !robots.exists() {
        eprintln!("skipped: {} is absent", robots.display());
        return Ok(());
    }
    fn robots_scene() -> Result<Context, String> {
        let mut rt = Context::new();
        let path = repo("../shared/scenes/bart/robot/aff/Robot.aff");
        let mut scene = rtsl_runtime::bart::load_file(&mut rt, &path).map_err(|e| e.to_string())?;
        rt.options.width = 64;
        rt.options.height = 48;
        let t = scene.frame_time(40);
        scene.set_time(&mut rt, t).map_err(|e| e.to_string())?;
        Ok(rt)
    }
    assert_same(&both_ways(robots_scene, 2, 1, &[&[]])?, "a BART robots frame");
    Ok(())
}

#[test]
fn a_worker_whose_scene_failed_is_named_by_the_master() {
    fn broken() -> Result<Context, String> {
        Err("scene.rib:3:1: no such shader \"nonesuch\"".into())
    }
    let mut group = LocalTransport::group(3, Duration::from_secs(30)).into_iter();
    let master_end = group.next().expect("rank 0");
    let workers: Vec<_> = group
        .enumerate()
        .map(|(i, t)| {
            std::thread::spawn(move || {
                let make: MakeScene = if i == 1 { broken } else { office };
                run_worker(&t, make, 1)
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
fn another_protocol_version_is_refused_at_start_up() {
    let mut group = LocalTransport::group(2, Duration::from_secs(10)).into_iter();
    let (master_end, worker_end) = (group.next().expect("rank 0"), group.next().expect("rank 1"));
    let hello = Message::Hello { protocol: 999, build: vec![], threads: 1, failure: None };
    worker_end.send(0, &hello.encode()).expect("sent");
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
    worker_end.send(0, &hello.encode()).expect("sent");
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
    worker_end.send(0, &hello.encode()).expect("sent");
    let mut master = Master::connect(master_end).expect("greeted");
    let mut rt = office().expect("the office");
    let world = rt.build_world().expect("a world");
    // The worker takes its tiles and never answers.
    assert!(master.render_frame(&world, &[], None).is_err());
    drop(worker_end);
}

#[test]
fn a_tile_decodes_to_itself_and_damaged_tiles_are_errors() {
    use rtsl_runtime::render::{RenderedTile, TileRenderer};
    for make in [office as MakeScene, library_with_camera_and_pixel_shader] {
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
    }
}
