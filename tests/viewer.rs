//! `rtsl view` in a real window under Xvfb: scripted input (`--events`) drives an orbit drag, an
//! object drag and keys, and `--screenshot` saves what the window shows, which is checked. Without
//! Xvfb on the machine the tests say so and skip (CI installs it: `.ci/run`).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// An X server of our own, stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `Xvfb` on a free display (it picks one and tells us through `-displayfd`), or says why
/// not and returns `None`.
fn xvfb() -> Option<Xvfb> {
    let spawned = Command::new("Xvfb")
        // Without -noreset the server resets when its last client leaves, and a viewer connecting
        // during that reset is refused.
        .args(["-displayfd", "1", "-noreset", "-screen", "0", "320x240x24", "-nolisten", "tcp"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn();
    let mut child = match spawned {
        Ok(c) => c,
        Err(e) => {
            eprintln!(
                "SKIPPED: Xvfb is not installed ({e}); install it (`apt-get install xvfb`) to run the viewer tests"
            );
            return None;
        }
    };
    let mut line = String::new();
    let read = child.stdout.take().map(|out| BufReader::new(out).read_line(&mut line));
    let number = line.trim();
    if !matches!(read, Some(Ok(n)) if n > 0) || number.parse::<u32>().is_err() {
        let _ = child.kill();
        let _ = child.wait();
        eprintln!("SKIPPED: Xvfb did not start (it printed {line:?})");
        return None;
    }
    Some(Xvfb { display: format!(":{number}"), child })
}

/// Runs `rtsl view ARGS` on `display`, killed after two minutes (see [`run_retrying`]).
fn view(display: &str, dir: &Path, args: &[&str]) -> Output {
    run_retrying(display, dir, || {
        let mut command = Command::new(env!("CARGO_BIN_EXE_rtsl"));
        command.arg("view").args(args);
        command
    })
}

/// Runs the command `make` gives on `display`, killed after two minutes. An X connection refused,
/// or broken by the server (Xlib's "X connection to :N broken"), is the test machine's trouble, not
/// the viewer's, so the command is tried again a few times.
fn run_retrying(display: &str, dir: &Path, make: impl Fn() -> Command) -> Output {
    let mut attempt = 0;
    loop {
        let o = run_on(display, dir, make());
        let stderr = String::from_utf8_lossy(&o.stderr);
        let x_trouble = stderr.contains("connecting to the display")
            || (stderr.contains("X connection to") && stderr.contains("broken"));
        attempt += 1;
        if o.status.success() || !x_trouble || attempt == 3 {
            return o;
        }
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// Runs `command` on `display`, killed after two minutes.
fn run_on(display: &str, dir: &Path, mut command: Command) -> Output {
    let mut child = command
        .current_dir(dir)
        .env("DISPLAY", display)
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        match child.try_wait().expect("waiting for the viewer") {
            Some(_) => break,
            None if Instant::now() > deadline => {
                let _ = child.kill();
                break;
            }
            None => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    child.wait_with_output().expect("the viewer's output")
}

struct Shot {
    width: usize,
    height: usize,
    rgba: Vec<f32>,
}

impl Shot {
    fn mean(&self) -> [f32; 3] {
        let n = (self.width * self.height) as f32;
        let mut m = [0.0; 3];
        for p in self.rgba.chunks_exact(4) {
            for c in 0..3 {
                m[c] += p[c] / n;
            }
        }
        m
    }

    fn luminance_spread(&self) -> f32 {
        let l: Vec<f32> = self.rgba.chunks_exact(4).map(|p| (p[0] + p[1] + p[2]) / 3.0).collect();
        let mean = l.iter().sum::<f32>() / l.len() as f32;
        (l.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / l.len() as f32).sqrt()
    }

    fn mean_difference(&self, other: &Shot) -> f32 {
        self.rgba.iter().zip(&other.rgba).map(|(a, b)| (a - b).abs()).sum::<f32>() / self.rgba.len() as f32
    }

    /// Mean absolute difference over a band of rows.
    fn rows_difference(&self, other: &Shot, rows: std::ops::Range<usize>) -> f32 {
        let (a, b) = (4 * rows.start * self.width, 4 * rows.end * self.width);
        self.rgba[a..b].iter().zip(&other.rgba[a..b]).map(|(x, y)| (x - y).abs()).sum::<f32>() / (b - a) as f32
    }

    /// Pure white pixels (the overlay's text) in the top-left corner.
    fn white_in_corner(&self) -> usize {
        (0..24)
            .flat_map(|y| (0..80).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let i = 4 * (y * self.width + x);
                self.rgba[i..i + 3].iter().all(|v| *v >= 1.0)
            })
            .count()
    }
}

/// Runs the viewer on the default scene at 96x72 with `extra` flags and returns its screenshot.
fn screenshot(x: &Xvfb, dir: &Path, name: &str, extra: &[&str]) -> Shot {
    let path: PathBuf = dir.join(name);
    let mut args = vec!["--size", "96x72", "--threads", "2", "--frames", "2", "--no-watch", "--screenshot", name];
    args.extend_from_slice(extra);
    let o = view(&x.display, dir, &args);
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "rtsl view {args:?} failed\nstdout: {out}\nstderr: {err}");
    assert!(out.contains("still:") && out.contains("fps"), "the frame rates are printed: {out}");
    let img = rtsl::runtime::read_image(&path).expect("the screenshot is a PNG");
    Shot { width: img.width, height: img.height, rgba: img.pixels }
}

#[test]
fn scripted_input_changes_what_the_window_shows() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let still = screenshot(&x, dir.path(), "still.png", &["--no-overlay"]);
    assert_eq!((still.width, still.height), (96, 72), "the window's size");
    let m = still.mean();
    assert!(still.luminance_spread() > 0.03, "the screenshot is not blank: mean {m:?}");
    assert!(m.iter().all(|c| (0.02..0.9).contains(c)), "the default scene's colours: mean {m:?}");

    // The same view twice gives the same picture: samples depend on pixel and pass only.
    let again = screenshot(&x, dir.path(), "again.png", &["--no-overlay"]);
    assert!(still.mean_difference(&again) < 1e-3, "two still renders differ by {}", still.mean_difference(&again));

    // An orbit drag turns the scene; a key cycles anti-aliasing on the way.
    let orbit = screenshot(&x, dir.path(), "orbit.png", &["--no-overlay", "--events", "drag:30,36,60,36;key:x"]);
    assert_eq!((orbit.width, orbit.height), (96, 72));
    assert!(orbit.luminance_spread() > 0.03, "the orbited view is not blank");
    let d = still.mean_difference(&orbit);
    assert!(d > 0.01, "an orbit drag changes the view (mean difference {d})");

    // Dragging with shift moves the object under the cursor (the wooden block): the picture
    // changes, but the camera stays where it was, so the wall at the top does not, unlike after
    // an orbit.
    let moved = screenshot(&x, dir.path(), "moved.png", &["--no-overlay", "--events", "shiftdrag:33,45,60,45"]);
    let d = still.mean_difference(&moved);
    assert!(d > 0.002, "moving an object changes the view (mean difference {d})");
    let (wall_moved, wall_orbit) = (still.rows_difference(&moved, 0..10), still.rows_difference(&orbit, 0..10));
    assert!(wall_moved < 0.01, "the wall stays when an object moves (difference {wall_moved})");
    assert!(wall_orbit > 2.0 * wall_moved, "an orbit moves the wall ({wall_orbit})");

    // C switches to the fisheye camera shader: its image circle leaves the corners black.
    let fish = screenshot(&x, dir.path(), "fisheye.png", &["--no-overlay", "--events", "key:c"]);
    let corner = |s: &Shot| s.rgba[..4].iter().take(3).sum::<f32>();
    assert!(corner(&still) > 0.0 && corner(&fish) == 0.0, "the fisheye's corner is empty");
    assert!(fish.luminance_spread() > 0.03, "the fisheye view is not blank");

    // The overlay draws white text in the top-left corner.
    let overlay = screenshot(&x, dir.path(), "overlay.png", &[]);
    assert!(overlay.white_in_corner() > 20, "the overlay's text is visible");
    assert_eq!(still.white_in_corner(), 0);

    // G puts full quality under the cursor (here the centre) and lowers it away from it: within
    // the gaze's radius (12 pixels of 72) the picture is the full-quality one; beyond its falloff
    // pixels stop refining after one of the two passes, and the picture differs.
    let gaze = screenshot(&x, dir.path(), "gaze.png", &["--no-overlay", "--events", "move:48,36;key:g"]);
    let (mut near, mut far, mut far_n) = (0.0f32, 0.0f32, 0);
    for y in 0..72usize {
        for x in 0..96usize {
            let d = ((x as f32 + 0.5 - 48.0).powi(2) + (y as f32 + 0.5 - 36.0).powi(2)).sqrt();
            let i = 4 * (y * 96 + x);
            let diff: f32 = (0..3).map(|c| (gaze.rgba[i + c] - still.rgba[i + c]).abs()).sum();
            if d < 11.0 {
                near = near.max(diff);
            } else if d > 25.0 {
                far += diff;
                far_n += 1;
            }
        }
    }
    assert!(near < 1e-3, "the gaze region is at full quality (largest difference {near})");
    assert!(far / far_n as f32 > 1e-3, "beyond the falloff quality is lower (mean difference {})", far / far_n as f32);
}

#[test]
fn frameless_mode_converges_to_a_picture_too() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let frameless = screenshot(&x, dir.path(), "frameless.png", &["--no-overlay", "--frameless"]);
    let progressive = screenshot(&x, dir.path(), "progressive.png", &["--no-overlay"]);
    let d = frameless.mean_difference(&progressive);
    // Two sweeps take the same samples as two passes, in another order, and `--frames 2` stops
    // either mode after exactly two samples per pixel, however fast the build renders.
    assert!(d < 1e-3, "frameless and progressive images differ by {d}");
    assert!(frameless.luminance_spread() > 0.03);
}

#[test]
fn zero_still_frames_still_shows_one_and_exits() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let args = ["--size", "32x24", "--frames", "0", "--no-watch", "--no-overlay", "--screenshot", "zero.png"];
    for extra in [&[][..], &["--frameless"][..]] {
        let o = view(&x.display, dir.path(), &[&args[..], extra].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "rtsl view --frames 0 {extra:?} did not finish: {err}");
        assert!(dir.path().join("zero.png").exists(), "the screenshot is written");
    }
}

#[test]
fn a_broken_scene_is_a_located_error_not_a_window() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("bad.rib"), "WorldBegin\nSurface \"plastic\nWorldEnd\n").expect("write");
    // No display is needed to fail: the scene loads before the window opens.
    let o = view(":99999", dir.path(), &["bad.rib", "--frames", "1"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("bad.rib:2"), "the error names file and line: {err}");
    let o = view(":99999", dir.path(), &["--events", "jump:1", "--frames", "1"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown step"));
}

/// `rtsl view --mpi` under `mpirun -n 3` on this machine: rank 0's window shows, pass for pass,
/// what one process shows, while an object is dragged, with adaptive anti-aliasing, in frameless
/// mode, and lit by virtual lights through the interleaving filter (the workers trace the
/// viewer's lattices; docs/distributed.md).
#[cfg(feature = "mpi")]
#[test]
fn the_viewer_over_three_mpi_ranks_shows_what_one_process_shows() {
    let found = Command::new("mpirun").arg("--version").output().is_ok_and(|o| o.status.success());
    if !found {
        eprintln!("SKIPPED: mpirun is not installed (apt-get install openmpi-bin libopenmpi-dev)");
        return;
    }
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let common = ["--size", "96x72", "--frames", "3", "--no-watch", "--no-overlay", "--threads", "1"];
    // Global illumination: each pass's virtual lights, and a pixel shader that reads other pixels
    // (run on rank 0 over the accumulated image).
    let gi = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes/gi_box.rib");
    let gi = gi.to_str().expect("a UTF-8 path");
    for extra in [&["--events", "shiftdrag:33,45,60,45"][..], &["--aa", "adaptive"], &["--frameless"], &[gi]] {
        let alone = view(&x.display, dir.path(), &[&common[..], extra, &["--screenshot", "alone.png"]].concat());
        assert!(alone.status.success(), "{}", String::from_utf8_lossy(&alone.stderr));
        let ranks = run_retrying(&x.display, dir.path(), || {
            let mut mpirun = Command::new("mpirun");
            mpirun
                .args(["-n", "3", "--oversubscribe", "--bind-to", "none", env!("CARGO_BIN_EXE_rtsl"), "view", "--mpi"])
                .args([&common[..], extra, &["--screenshot", "ranks.png"]].concat())
                .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
                .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
            mpirun
        });
        let out = String::from_utf8_lossy(&ranks.stdout);
        assert!(ranks.status.success(), "{extra:?}: {out}{}", String::from_utf8_lossy(&ranks.stderr));
        // Two workers of one thread each rendered.
        assert!(out.contains("96x72, 2 thread(s): still:"), "{out}");
        let (a, b) = (dir.path().join("alone.png"), dir.path().join("ranks.png"));
        let (a, b) = (rtsl::runtime::read_image(&a).expect("a PNG"), rtsl::runtime::read_image(&b).expect("a PNG"));
        let differ = a.pixels.iter().zip(&b.pixels).filter(|(p, q)| p.to_bits() != q.to_bits()).count();
        assert_eq!(differ, 0, "{extra:?}: {differ} values differ");
        assert!(a.pixels.iter().any(|&v| v > 0.05), "{extra:?}: the picture is not black");
    }
}

/// One still frame of `scene` at `size` after the `extra` arguments, saved as `name` and read back.
fn still_shot(x: &Xvfb, dir: &Path, (scene, size): (&str, &str), name: &str, extra: &[&str]) -> Shot {
    let mut args = vec![scene, "--size", size, "--frames", "1", "--no-watch", "--no-overlay", "--screenshot", name];
    args.extend_from_slice(extra);
    let o = view(&x.display, dir, &args);
    assert!(o.status.success(), "rtsl view {args:?}: {}", String::from_utf8_lossy(&o.stderr));
    let img = rtsl::runtime::read_image(dir.join(name)).expect("the screenshot is a PNG");
    Shot { width: img.width, height: img.height, rgba: img.pixels }
}

/// A VRML scene's animation held at a time (`--time`): the box is where that time puts it.
#[test]
fn a_vrml_animation_is_shown_at_the_time_asked() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("move.wrl"),
        "#VRML V2.0 utf8
Viewpoint { position 0 0 10 }
DEF T Transform { children Shape { appearance Appearance { material Material { diffuseColor 1 0.2 0.1 } } geometry Box {} } }
DEF P PositionInterpolator { key [0 1] keyValue [-3 0 0, 3 0 0] }
DEF C TimeSensor { cycleInterval 2 loop TRUE }
ROUTE C.fraction_changed TO P.set_fraction
ROUTE P.value_changed TO T.set_translation
",
    )
    .expect("write");
    let shot = |name: &str, extra: &[&str]| still_shot(&x, dir.path(), ("move.wrl", "48x36"), name, extra);
    let start = shot("start.png", &[]);
    let held = shot("zero.png", &["--time", "0"]);
    let later = shot("later.png", &["--time", "1"]);
    assert!(start.mean_difference(&held) < 1e-3, "a scripted run holds the animation at 0");
    assert!(start.mean_difference(&later) > 1e-3, "at time 1 the box has moved");
    assert_eq!((later.width, later.height), (48, 36));
}

/// A click on a shape under a TouchSensor: its touchTime starts a TimeSensor whose isActive
/// switches a light on (the animation held at time 0 in a scripted run, the light shows at once).
#[test]
fn a_click_on_a_touch_sensor_switches_the_light_it_starts() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("touch.wrl"),
        "#VRML V2.0 utf8
NavigationInfo { headlight FALSE }
Viewpoint { position 0 0 6 }
DEF L PointLight { location 0 0 4 on FALSE }
Group { children [ DEF Touch TouchSensor {} Shape { appearance Appearance { material Material { } } geometry Box { size 3 3 1 } } ] }
DEF C TimeSensor { cycleInterval 10 }
ROUTE Touch.touchTime TO C.startTime
ROUTE C.isActive TO L.on
",
    )
    .expect("write");
    let shot = |name: &str, extra: &[&str]| still_shot(&x, dir.path(), ("touch.wrl", "48x36"), name, extra);
    let dark = shot("dark.png", &[]);
    let lit = shot("lit.png", &["--events", "click:24,18"]);
    let (d, l) = (dark.mean(), lit.mean());
    assert!(d.iter().all(|c| *c < 0.01), "unlit before the click: {d:?}");
    assert!(l[0] > 0.05, "the light is on after it: {l:?}");
}

/// `V` moves the view to the scene's next Viewpoint: from the red box's to the green one's.
#[test]
fn v_steps_through_a_vrml_scenes_viewpoints() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("two.wrl"),
        "#VRML V2.0 utf8
NavigationInfo { headlight TRUE }
Viewpoint { position -20 0 4 description \"red\" }
Viewpoint { position 20 0 4 description \"green\" }
Transform { translation -20 0 0 children Shape { appearance Appearance { material Material { diffuseColor 1 0 0 } } geometry Box { size 6 6 1 } } }
Transform { translation 20 0 0 children Shape { appearance Appearance { material Material { diffuseColor 0 1 0 } } geometry Box { size 6 6 1 } } }
",
    )
    .expect("write");
    let shot = |name: &str, extra: &[&str]| still_shot(&x, dir.path(), ("two.wrl", "32x24"), name, extra);
    let centre = |s: &Shot| {
        let i = 4 * (12 * s.width + 16);
        [s.rgba[i], s.rgba[i + 1], s.rgba[i + 2]]
    };
    let first = centre(&shot("first.png", &[]));
    assert!(first[0] > 0.2 && first[1] < 0.05, "the first viewpoint looks at the red box: {first:?}");
    let second = centre(&shot("second.png", &["--events", "key:v"]));
    assert!(second[1] > 0.2 && second[0] < 0.05, "V moves to the green box's viewpoint: {second:?}");
    let again = centre(&shot("again.png", &["--events", "key:v;key:v"]));
    assert!(again[0] > 0.2 && again[1] < 0.05, "and round to the first: {again:?}");
}

/// The mean column of the pixels brighter than `threshold` (the image's bright shape).
fn bright_column(s: &Shot, threshold: f32) -> f32 {
    let (mut sum, mut n) = (0.0, 0.0);
    for y in 0..s.height {
        for x in 0..s.width {
            let i = 4 * (y * s.width + x);
            if s.rgba[i] + s.rgba[i + 1] + s.rgba[i + 2] > threshold {
                sum += x as f32;
                n += 1.0;
            }
        }
    }
    assert!(n > 0.0, "no bright pixels");
    sum / n
}

/// A drag on a box under a PlaneSensor moves it with the pointer; a drag beside it orbits.
#[test]
fn a_drag_on_a_plane_sensor_moves_its_shape() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("drag.wrl"),
        "#VRML V2.0 utf8
Viewpoint { position 0 0 10 }
Group { children [
  DEF Drag PlaneSensor { }
  DEF T Transform { children Shape { appearance Appearance { material Material { diffuseColor 1 1 1 } } geometry Box { size 2 2 2 } } }
] }
ROUTE Drag.translation_changed TO T.set_translation
",
    )
    .expect("write");
    let shot = |name: &str, extra: &[&str]| still_shot(&x, dir.path(), ("drag.wrl", "64x48"), name, extra);
    let still = bright_column(&shot("still.png", &[]), 0.5);
    assert!((still - 31.5).abs() < 1.5, "the box is in the middle: {still}");
    let dragged = bright_column(&shot("dragged.png", &["--events", "drag:32,24,48,24"]), 0.5);
    assert!((dragged - still - 16.0).abs() < 3.0, "the box follows the pointer 16 pixels right: {still} {dragged}");
}

/// The pointer over a shape under a TouchSensor: its isOver switches a light on.
#[test]
fn hovering_over_a_touch_sensor_sends_is_over() {
    let Some(x) = xvfb() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("hover.wrl"),
        "#VRML V2.0 utf8
NavigationInfo { headlight FALSE }
Viewpoint { position 0 0 6 }
DEF L PointLight { location 0 0 4 on FALSE }
Group { children [ DEF Touch TouchSensor {} Shape { appearance Appearance { material Material { } } geometry Box { size 3 3 1 } } ] }
ROUTE Touch.isOver TO L.on
",
    )
    .expect("write");
    let shot = |name: &str, extra: &[&str]| still_shot(&x, dir.path(), ("hover.wrl", "48x36"), name, extra);
    let away = shot("away.png", &["--events", "move:2,2"]).mean();
    let over = shot("over.png", &["--events", "move:24,18"]).mean();
    let left = shot("left.png", &["--events", "move:24,18;wait:1;move:2,2"]).mean();
    assert!(away.iter().all(|c| *c < 0.01), "unlit with the pointer beside it: {away:?}");
    assert!(over[0] > 0.05, "lit with the pointer over it: {over:?}");
    assert!(left.iter().all(|c| *c < 0.01), "unlit again once the pointer left: {left:?}");
}
