//! `--mpi` as a user runs it: `mpirun -n 3 rtsl ... --mpi` on this machine (ranks talking over
//! loopback and shared memory), against the same command in one process. Built only with the
//! `mpi` feature (`cargo test --features mpi --test mpi`); skips with a message where `mpirun`
//! is missing.
#![cfg(feature = "mpi")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn mpirun_present() -> bool {
    let found = Command::new("mpirun").arg("--version").output().is_ok_and(|o| o.status.success());
    if !found {
        eprintln!("skipped: mpirun is not installed (apt-get install openmpi-bin libopenmpi-dev)");
    }
    found
}

fn rtsl(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rtsl")).args(args).current_dir(dir).output().expect("the binary runs")
}

/// `rtsl ARGS --mpi` over `ranks` ranks, with two threads each (as root, Open MPI wants to be told).
fn mpirun(ranks: usize, args: &[&str], dir: &Path) -> Output {
    Command::new("mpirun")
        .args(["-n", &ranks.to_string(), "--oversubscribe", "--bind-to", "none"])
        .arg(env!("CARGO_BIN_EXE_rtsl"))
        .args(args)
        .args(["--mpi", "--threads", "2"])
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .current_dir(dir)
        .output()
        .expect("mpirun runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// The two images hold the same values, bit for bit.
fn assert_same_image(a: &Path, b: &Path) {
    let (a_img, b_img) =
        (rtsl_runtime::read_image(a).expect("an image"), rtsl_runtime::read_image(b).expect("an image"));
    assert_eq!((a_img.width, a_img.height), (b_img.width, b_img.height));
    let differ = a_img.pixels.iter().zip(&b_img.pixels).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
    assert_eq!(differ, 0, "{} and {}: {differ} values differ", a.display(), b.display());
    assert!(a_img.pixels.iter().any(|&v| v > 0.0), "{} is black", a.display());
}

#[test]
fn the_default_scene_renders_the_same_over_three_ranks() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let alone = rtsl(&["render", "--size", "96x72", "-o", "alone.exr", "-q"], dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let ranks = mpirun(3, &["render", "--size", "96x72", "-o", "mpi.exr"], dir.path());
    assert!(ranks.status.success(), "{}", text(&ranks));
    assert!(text(&ranks).contains("2 worker rank(s), 4 thread(s) in all"), "{}", text(&ranks));
    assert_same_image(&dir.path().join("alone.exr"), &dir.path().join("mpi.exr"));
}

#[test]
fn a_camera_shader_a_pixel_shader_and_a_filter_render_the_same_over_three_ranks() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let rib = "Format 80 60 1\nPixelSamples 2 2\nPixelFilter \"gaussian\" 2 2\nImager \"exposure\" \"gain\" 1.5\n\
               Projection \"perspective\" \"fov\" 45\nTranslate 0 0 5\nWorldBegin\n\
               LightSource \"pointlight\" 1 \"intensity\" 20 \"from\" [2 2 -3]\n\
               Surface \"marble\"\nSphere 1 -1 1 360\nTranslate 0 -1 0\nSurface \"checker\"\n\
               Polygon \"P\" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]\nWorldEnd\n";
    std::fs::write(dir.path().join("scene.rib"), rib).expect("write");
    let args = ["render", "scene.rib", "--camera", "fisheye:fov=200", "-o"];
    let alone = rtsl(&[&args[..], &["alone.exr", "-q"]].concat(), dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let ranks = mpirun(3, &[&args[..], &["mpi.exr", "-q"]].concat(), dir.path());
    assert!(ranks.status.success(), "{}", text(&ranks));
    assert_same_image(&dir.path().join("alone.exr"), &dir.path().join("mpi.exr"));
}

/// Two frames, each a scene of its own: the second has fewer objects, lights and shaders than the
/// first, and its `MakeTexture` writes another image to the texture file the first read.
const TWO_SCENES: &str = "Format 64 48 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" 45\nTranslate 0 0 5\n\
    FrameBegin 1\nMakeTexture \"a.exr\" \"tex.tx\" \"periodic\" \"periodic\" \"box\" 1 1\nWorldBegin\n\
    LightSource \"pointlight\" 1 \"intensity\" 20 \"from\" [2 2 -3]\nLightSource \"distantlight\" 2 \"intensity\" 0.4\n\
    AttributeBegin\nTranslate -1.2 0 0\nSurface \"paintedplastic\" \"texturename\" \"tex.tx\"\nSphere 0.9 -0.9 0.9 360\nAttributeEnd\n\
    AttributeBegin\nTranslate 1.2 0 0\nSurface \"marble\"\nSphere 0.9 -0.9 0.9 360\nAttributeEnd\n\
    Translate 0 -1 0\nSurface \"checker\"\nPolygon \"P\" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]\nWorldEnd\nFrameEnd\n\
    FrameBegin 2\nMakeTexture \"b.exr\" \"tex.tx\" \"periodic\" \"periodic\" \"box\" 1 1\nWorldBegin\n\
    LightSource \"pointlight\" 1 \"intensity\" 12 \"from\" [-2 1 -3]\n\
    Surface \"paintedplastic\" \"texturename\" \"tex.tx\"\nSphere 1.2 -1.2 1.2 360\nWorldEnd\nFrameEnd\n";

/// A VRML box moving and turning over two seconds.
const VRML_MOVING_BOX: &str = "#VRML V2.0 utf8
Viewpoint { position 0 0 10 }
DEF T Transform { children Shape { appearance Appearance { material Material { diffuseColor 1 0.2 0.1 } } geometry Box {} } }
DEF P PositionInterpolator { key [0 1] keyValue [-3 0 0, 3 0 0] }
DEF R OrientationInterpolator { key [0 1] keyValue [0 1 0 0, 0 1 0 3.14] }
DEF C TimeSensor { cycleInterval 2 loop TRUE }
ROUTE C.fraction_changed TO P.set_fraction
ROUTE C.fraction_changed TO R.set_fraction
ROUTE P.value_changed TO T.set_translation
ROUTE R.value_changed TO T.set_rotation
";

#[test]
fn every_frame_of_a_file_renders_the_same_over_three_ranks() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let texture = |name: &str, rgb: [f32; 3]| {
        let texels: Vec<f32> = (0..16)
            .flat_map(|i| if i % 3 == 0 { [rgb[0], rgb[1], rgb[2], 1.0] } else { [0.1, 0.1, 0.1, 1.0] })
            .collect();
        rtsl_runtime::write_image(dir.path().join(name), 4, 4, &texels, &Default::default()).expect("a texture");
    };
    texture("a.exr", [0.9, 0.2, 0.1]);
    texture("b.exr", [0.1, 0.3, 0.9]);
    std::fs::write(dir.path().join("frames.rib"), TWO_SCENES).expect("write");
    let alone = rtsl(&["render", "frames.rib", "-o", "alone.#f.exr", "-q"], dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let ranks = mpirun(3, &["render", "frames.rib", "-o", "mpi.#f.exr"], dir.path());
    let out = text(&ranks);
    assert!(ranks.status.success(), "{out}");
    // Each frame's summary, as one process prints it, with what travelled.
    for frame in ["1", "2"] {
        assert!(out.contains(&format!("mpi.{frame}.exr: 64x48, 4 sample(s) per pixel, 2 worker rank(s)")), "{out}");
        assert_same_image(&dir.path().join(format!("alone.{frame}.exr")), &dir.path().join(format!("mpi.{frame}.exr")));
    }
    assert_eq!(out.matches("demand loading, the frame").count(), 2, "{out}");
    let read = |name: &str| rtsl_runtime::read_image(dir.path().join(name)).expect("an image").pixels;
    assert!(read("mpi.1.exr") != read("mpi.2.exr"));
    // Frames whose images would overwrite each other are refused as in one process.
    let same = mpirun(3, &["render", "frames.rib", "-o", "same.exr", "-q"], dir.path());
    assert!(!same.status.success());
    assert!(text(&same).contains("frame 2 would overwrite same.exr"), "{}", text(&same));
    // A VRML animation's frames: one scene advanced from frame to frame.
    std::fs::write(dir.path().join("move.wrl"), VRML_MOVING_BOX).expect("write");
    let args = ["render", "move.wrl", "--size", "32x24", "--frames", "1..3", "--fps", "4", "-q", "-o"];
    let alone = rtsl(&[&args[..], &["alone.#f.png"]].concat(), dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let ranks = mpirun(3, &[&args[..], &["mpi.#f.png"]].concat(), dir.path());
    assert!(ranks.status.success(), "{}", text(&ranks));
    for n in 1..=3 {
        let (a, b) = (dir.path().join(format!("alone.{n}.png")), dir.path().join(format!("mpi.{n}.png")));
        assert_eq!(std::fs::read(&a).expect("a frame"), std::fs::read(&b).expect("a frame"), "frame {n}");
    }
}

/// A sphere whose displacement shader moves its points, truly displaced (its
/// `displacementbound`), casting its shadow on a floor.
const DISPLACED_RIB: &str = r#"Format 96 64 1
Projection "perspective" "fov" 45
Translate 0 0 6
WorldBegin
  LightSource "spotlight" 1 "from" [2 4 -2] "to" [0 0 0] "intensity" 40 "coneangle" 0.9
  AttributeBegin
    Attribute "displacementbound" "sphere" [0.3]
    Displacement "ridges"
    Surface "plastic"
    Sphere 1 -1 1 360
  AttributeEnd
  Surface "matte"
  Polygon "P" [-4 -1.3 -4  4 -1.3 -4  4 -1.3 4  -4 -1.3 4]
WorldEnd
"#;

/// Its displacement shader, kept beside it.
const RIDGES_SL: &str = "displacement ridges(float amount = 0.3) {
    point Po = transform(\"object\", P);
    P += amount * (0.5 + 0.5 * sin(12 * zcomp(Po))) * normalize(N);
    N = calculatenormal(P);
}
";

/// True displacement over ranks: the master displaces, the workers fetch the displaced mesh, and
/// the image is the one process's, bit for bit (silhouette and shadow displaced).
#[test]
fn truly_displaced_objects_render_the_same_over_three_ranks() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("ridges.sl"), RIDGES_SL).expect("write");
    std::fs::write(dir.path().join("displaced.rib"), DISPLACED_RIB).expect("write");
    let alone = rtsl(&["render", "displaced.rib", "-o", "alone.exr", "-q"], dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let ranks = mpirun(3, &["render", "displaced.rib", "-o", "mpi.exr", "-q"], dir.path());
    assert!(ranks.status.success(), "{}", text(&ranks));
    assert_same_image(&dir.path().join("alone.exr"), &dir.path().join("mpi.exr"));
    // Without its bound the same shader bump-maps: another outline, another image.
    std::fs::write(dir.path().join("bumped.rib"), DISPLACED_RIB.replace("[0.3]", "[0]")).expect("write");
    let bumped = rtsl(&["render", "bumped.rib", "-o", "bumped.exr", "-q"], dir.path());
    assert!(bumped.status.success(), "{}", text(&bumped));
    let read = |name: &str| rtsl_runtime::read_image(dir.path().join(name)).expect("an image").pixels;
    assert!(read("bumped.exr") != read("mpi.exr"));
}

/// A large texture (more than `--tile-textures-from-mb` as a file) seen close over a small part
/// of it: the workers fetch the tiles of its levels that their rays read, far less than the file,
/// and the image is the one process's, bit for bit.
#[test]
fn a_large_texture_seen_close_comes_in_tiles_and_renders_the_same() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    // 1300 x 1300 texels of 8-bit noise: about 5 MB, which deflating hardly shrinks.
    let side = 1300;
    let mut ppm = format!("P6\n{side} {side}\n255\n").into_bytes();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    ppm.extend((0..side * side * 3).map(|_| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 24) as u8
    }));
    std::fs::write(dir.path().join("noise.ppm"), &ppm).expect("write");
    let rib =
        "Format 96 72 1\nProjection \"perspective\" \"fov\" 30\nRotate -35 1 0 0\nTranslate 0 -1.2 0\nWorldBegin\n\
               LightSource \"distantlight\" 1 \"intensity\" 1.2 \"from\" [0 4 -1] \"to\" [0 0 0]\n\
               Surface \"paintedplastic\" \"texturename\" \"noise.ppm\"\n\
               Polygon \"P\" [-10 0 -4  10 0 -4  10 0 16  -10 0 16] \"st\" [0 0 1 0 1 1 0 1]\nWorldEnd\n";
    std::fs::write(dir.path().join("close.rib"), rib).expect("write");
    let alone = rtsl(&["render", "close.rib", "-o", "alone.exr", "-q"], dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let ranks = mpirun(3, &["render", "close.rib", "-o", "mpi.exr", "--tile-textures-from-mb", "4"], dir.path());
    let out = text(&ranks);
    assert!(ranks.status.success(), "{out}");
    assert_same_image(&dir.path().join("alone.exr"), &dir.path().join("mpi.exr"));
    let line = out.lines().find(|l| l.starts_with("demand loading, the frame")).unwrap_or_default();
    let number_before = |what: &str| -> f64 {
        line.split(what).next().and_then(|s| s.rsplit(' ').next()).and_then(|n| n.parse().ok()).unwrap_or(-1.0)
    };
    assert!(number_before(" tile(s) of levels") > 0.0, "{line}");
    let megabytes = number_before(" MB; cache hits");
    assert!((0.0..ppm.len() as f64 / 4e6).contains(&megabytes), "{line}");
}

/// Renders `frames` frames of a BART scene alone and over `ranks` ranks; checks they are the same
/// and returns the distributed run's first-frame `demand loading` line (`None`: skipped).
fn bart_alone_and_over_ranks(scene: &str, frames: usize, size: &str, ranks: usize) -> Option<String> {
    let path = repo(scene);
    if !path.exists() {
        eprintln!("skipped: {} is absent", path.display());
        return None;
    }
    if !mpirun_present() {
        return None;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = path.to_string_lossy().into_owned();
    let count = frames.to_string();
    let args = ["bart", scene.as_str(), "--frames", count.as_str(), "--size", size, "-q", "-o"];
    let alone = rtsl(&[&args[..], &["alone"]].concat(), dir.path());
    assert!(alone.status.success(), "{}", text(&alone));
    let distributed = mpirun(ranks, &[&args[..], &["mpi"]].concat(), dir.path());
    assert!(distributed.status.success(), "{}", text(&distributed));
    let report = text(&distributed);
    assert!(report.contains("demand loading, the first frame"), "{report}");
    // Nothing is held before the first frame: every object its rays reach is a miss.
    let first = report.lines().find(|l| l.starts_with("demand loading, the first frame")).unwrap_or_default();
    assert!(first.contains("cache hits: 0.0% of the "), "{first}");
    for frame in (0..frames).map(|k| format!("frame_{k:04}.png")) {
        let (a, b) = (dir.path().join("alone").join(&frame), dir.path().join("mpi").join(&frame));
        assert_eq!(std::fs::read(&a).expect("a frame"), std::fs::read(&b).expect("a frame"), "{frame}");
    }
    Some(first.to_string())
}

#[test]
fn bart_frames_render_the_same_over_three_ranks() {
    let _ = bart_alone_and_over_ranks("../shared/scenes/bart/robot/aff/Robot.aff", 2, "64x48", 3);
}

/// Without `-q`, each frame's line is followed by its workers' line: what they rendered and
/// fetched for that frame (the first frame fetches what its rays reach; the same view again,
/// nothing).
#[test]
fn bart_over_ranks_prints_what_each_frame_fetched() {
    let path = repo("../shared/scenes/bart/robot/aff/Robot.aff");
    if !path.exists() || !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = path.to_string_lossy().into_owned();
    let out = mpirun(2, &["bart", scene.as_str(), "--frames", "2", "--size", "64x48"], dir.path());
    assert!(out.status.success(), "{}", text(&out));
    let report = text(&out);
    let lines: Vec<&str> = report.lines().collect();
    let frames: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].starts_with("frame ")).collect();
    assert_eq!(frames.len(), 2, "{report}");
    let objects = |line: &str| -> f64 {
        let after = line.split("fetched a worker: ").nth(1).unwrap_or_default();
        after.split(" objects").next().and_then(|n| n.parse().ok()).unwrap_or(-1.0)
    };
    for &i in &frames {
        let next = lines.get(i + 1).copied().unwrap_or_default();
        assert!(next.trim_start().starts_with("workers: rendering "), "{next}");
        assert!(objects(next) >= 0.0, "{next}");
    }
    assert!(objects(lines[frames[0] + 1]) > 0.0, "{report}");
}

/// The kitchen's meshes are large: the master sends them while the worker sends its pixels, and
/// neither send may wait for the other's receive. Its largest object travels in parts.
#[test]
fn bart_kitchen_frames_fetch_large_meshes_while_pixels_flow() {
    let Some(first) = bart_alone_and_over_ranks("../shared/scenes/bart/kitchen/aff/kitchen.aff", 3, "96x72", 2) else {
        return;
    };
    let parts: u64 =
        first.split(" BVH part(s)").next().and_then(|s| s.rsplit(' ').next()).and_then(|n| n.parse().ok()).unwrap_or(0);
    assert!(parts > 0, "{first}");
}

#[test]
fn a_scene_that_fails_to_load_is_reported_once_and_ends_the_job() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("bad.rib"), "WorldBegin\nSurface \"plastic\nWorldEnd\n").expect("write");
    let ranks = mpirun(3, &["render", "bad.rib", "-o", "x.png", "-q"], dir.path());
    let out = text(&ranks);
    assert!(!ranks.status.success(), "{out}");
    let alone = rtsl(&["render", "bad.rib", "-o", "x.png", "-q"], dir.path());
    let first_error = String::from_utf8_lossy(&alone.stderr).lines().find(|l| l.contains("error")).map(str::to_owned);
    let first_error = first_error.expect("the single process reports an error");
    assert_eq!(out.matches(first_error.as_str()).count(), 1, "the error once, as alone: {out}");
}

#[test]
fn without_mpirun_the_flag_renders_on_one_rank() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["render", "--size", "32x24", "-o", "x.png", "--mpi", "-q"], dir.path());
    // A singleton MPI process may fail to start where no MPI runtime is installed; where one is,
    // it renders alone and says so.
    if mpirun_present() {
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains("no worker rank"), "{}", text(&o));
        assert!(dir.path().join("x.png").exists());
    }
}

#[test]
fn bench_render_times_frames_over_the_workers() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let o = mpirun(2, &["bench", "render", "--frames", "2", "--size", "128x96"], dir.path());
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    assert!(out.contains("worker ranks: 1, threads: 2"), "{out}");
    assert!(out.lines().any(|l| l.starts_with("fps: ")), "{out}");
    assert!(out.contains("MPI traffic per frame"), "{out}");
    // The last eighth of the 48 tiles go out in quarters, to the worker's two threads.
    assert!(out.contains("tiles handed out in quarters 6.0 a frame"), "{out}");
    // A spinning master, no copies and no quarters of tiles: the worker-time line counts none.
    let args = [
        "bench",
        "render",
        "--frames",
        "2",
        "--size",
        "128x96",
        "--master-spins",
        "--no-tile-copies",
        "--no-tile-quarters",
    ];
    let o = mpirun(2, &args, dir.path());
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    assert!(out.contains("tiles copied to idle workers at the frame's end 0.0 a frame"), "{out}");
    assert!(out.contains("tiles handed out in quarters 0.0 a frame"), "{out}");
    let refused = mpirun(2, &["bench", "render", "--frames", "1", "--native-plastic"], dir.path());
    assert!(!refused.status.success());
    assert!(text(&refused).contains("without --mpi"), "{}", text(&refused));
}

/// The process of rank `rank` of an mpirun job started in `dir` (found by its environment and
/// working directory), if it is running.
fn rank_process(dir: &Path, rank: usize) -> Option<u32> {
    let marker = format!("OMPI_COMM_WORLD_RANK={rank}");
    std::fs::read_dir("/proc").ok()?.flatten().find_map(|entry| {
        let pid: u32 = entry.file_name().to_str()?.parse().ok()?;
        let cwd = std::fs::read_link(entry.path().join("cwd")).ok()?;
        let environ = std::fs::read(entry.path().join("environ")).ok()?;
        let ours = cwd == dir && environ.split(|&b| b == 0).any(|v| v == marker.as_bytes());
        ours.then_some(pid)
    })
}

#[test]
fn a_worker_that_dies_ends_the_job_with_its_rank_named() {
    if !mpirun_present() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let dir_path = dir.path().canonicalize().expect("a real path");
    // Frames enough to outlast the test by far.
    let mut job = Command::new("mpirun")
        .args(["-n", "3", "--oversubscribe", "--bind-to", "none"])
        .arg(env!("CARGO_BIN_EXE_rtsl"))
        .args(["bench", "render", "--frames", "1000000", "--size", "64x48", "--threads", "1", "--mpi"])
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .current_dir(&dir_path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("mpirun runs");
    let start = std::time::Instant::now();
    let victim = loop {
        if let Some(pid) = rank_process(&dir_path, 2) {
            break pid;
        }
        assert!(start.elapsed().as_secs() < 60, "rank 2 never started");
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    // Let the frames begin, then kill the worker outright.
    std::thread::sleep(std::time::Duration::from_secs(3));
    let killed = Command::new("kill").args(["-9", &victim.to_string()]).status().expect("kill runs");
    assert!(killed.success());
    let waited = std::time::Instant::now();
    let status = loop {
        if let Some(status) = job.try_wait().expect("mpirun's status") {
            break status;
        }
        if waited.elapsed().as_secs() > 60 {
            let _ = job.kill();
            panic!("the job went on for a minute after rank 2 died");
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    let out = job.wait_with_output().expect("mpirun's output");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(!status.success(), "{text}");
    assert!(text.contains("rank 2"), "{text}");
}
