//! Hot reload under stress: a shader file rewritten 200 times in quick succession, alternating
//! versions that compile (each a distinct flat colour) and versions that do not, while frames
//! render on every thread and the background reloader's results are swapped in between frames.
//!
//! The JIT counters are process-wide, so this file holds one test: nothing else compiles shaders
//! in this process while it runs.

use rtsl_compiler::jit::{live_code_bytes, live_modules};
use rtsl_runtime::api::{Context, Primitive};
use rtsl_runtime::reload::{ShaderEvent, ShaderReloader};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const VERSIONS: usize = 200;
const W: u32 = 32;
const H: u32 = 24;

/// Version `i` compiles when `i` is odd (so the last one, 199, does).
fn valid(i: usize) -> bool {
    i % 2 == 1
}

/// The flat colour of valid version `i`: exact in binary, distinct for every `i`.
fn colour(i: usize) -> [f32; 3] {
    [i as f32 / 256.0, 0.25, 1.0 - i as f32 / 512.0]
}

fn source(i: usize) -> String {
    if valid(i) {
        let [r, g, b] = colour(i);
        format!("surface flat() {{ Oi = 1; Ci = color({r:?}, {g:?}, {b:?}); }}\n")
    } else if i % 4 == 0 {
        format!("surface flat() {{ Oi = 1; Ci = undefined_{i}; }}\n")
    } else {
        format!("surface flat() {{ Oi = 1; Ci = color(1, 0, 0) }}\n/* version {i} */\n")
    }
}

/// The version whose colour fills the whole frame; panics on a frame that mixes versions or shows
/// anything else.
fn version_of(fb: &rtsl_runtime::render::Framebuffer) -> usize {
    let first = fb.pixel(0, 0);
    for y in 0..H {
        for x in 0..W {
            assert_eq!(fb.pixel(x, y), first, "pixel ({x}, {y}) differs from pixel (0, 0): a frame mixes versions");
        }
    }
    (0..VERSIONS)
        .find(|&i| valid(i) && [first[0], first[1], first[2]] == colour(i) && first[3] == 1.0)
        .unwrap_or_else(|| panic!("{first:?} is the colour of no valid version"))
}

fn scene(rt: &mut Context, path: &Path) {
    rt.options.width = W;
    rt.options.height = H;
    let id = rt.shader_file(path).expect("version 1 compiles");
    rt.camera_look_at(glam::Vec3A::new(0.0, 0.0, 3.0), glam::Vec3A::ZERO, glam::Vec3A::Y, 60.0);
    let o = rt.begin_object().expect("object");
    rt.bind_shader(id).expect("bind");
    rt.begin(Primitive::Quads).expect("begin");
    for (x, y) in [(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)] {
        rt.vertex(x, y, 0.0).expect("vertex");
    }
    rt.end().expect("end");
    rt.end_object().expect("end_object");
    rt.instantiate_object(o).expect("instance");
}

#[test]
fn two_hundred_rewrites_while_rendering_swap_whole_shaders_and_leak_nothing() {
    let started = Instant::now();
    let baseline = (live_modules(), live_code_bytes());
    let dir = tempfile::tempdir().expect("tempdir");
    let shader = dir.path().join("flat.sl");
    std::fs::write(&shader, source(1)).expect("write");
    let mut rt = Context::new();
    scene(&mut rt, &shader);
    assert_eq!(live_modules(), baseline.0 + 1, "one shader loaded");
    let one_shader_bytes = live_code_bytes() - baseline.1;
    assert!(one_shader_bytes > 0, "the JIT counts the code it holds");
    let mut reloader = ShaderReloader::new(&rt).expect("a reloader");

    let done = Arc::new(AtomicBool::new(false));
    let writer = {
        let (shader, done) = (shader.clone(), done.clone());
        std::thread::spawn(move || {
            for i in 2..VERSIONS {
                std::fs::write(&shader, source(i)).expect("write");
                // Quick succession, unevenly: bursts shorter than the debounce window, and every
                // fifth write (a valid or a broken version in turn) a pause that lets the reloader
                // compile while the next burst is written.
                let pause = if i % 5 == 0 { 20_000 } else { 300 + 700 * (i as u64 % 3) };
                std::thread::sleep(Duration::from_micros(pause));
            }
            done.store(true, Ordering::SeqCst);
        })
    };

    // Frames on every thread (render_frame runs tiles over rayon's pool), reloads between them.
    let (mut frames, mut reloaded, mut failed, mut last) = (0, 0, 0, 1);
    let (mut finished_at, mut peak) = (None, 0);
    loop {
        for r in reloader.apply(&mut rt) {
            match &r.result {
                Ok(_) => reloaded += 1,
                Err(d) => {
                    failed += 1;
                    assert!(d.contains("flat.sl"), "diagnostics name the file: {d}");
                }
            }
        }
        let (fb, _) = rt.render_frame().expect("a frame");
        frames += 1;
        peak = peak.max(live_modules() - baseline.0);
        let v = version_of(&fb);
        assert!(v >= last, "frame {frames} shows version {v} after version {last}: reloads went backwards");
        last = v;
        if done.load(Ordering::SeqCst) {
            // The last write was seen and compiled when a frame shows it; wait a little longer
            // for any late (redundant) result, which must not change the picture.
            let at = *finished_at.get_or_insert_with(Instant::now);
            if v == VERSIONS - 1 && at.elapsed() > Duration::from_millis(300) {
                break;
            }
            assert!(at.elapsed() < Duration::from_secs(10), "the final version never showed (last {last})");
        }
    }
    writer.join().expect("the writer");
    assert_eq!(last, VERSIONS - 1, "the final image is the final valid source");
    assert!(reloaded >= 2, "several versions were swapped in while rendering ({reloaded})");

    // The events queued on the context say the same as the reloads returned.
    let events = rt.take_shader_events();
    let ok = events.iter().filter(|e| matches!(e, ShaderEvent::Reloaded { .. })).count();
    let bad = events.iter().filter(|e| matches!(e, ShaderEvent::Failed { .. })).count();
    assert_eq!((ok, bad), (reloaded, failed), "{events:?}");

    // No leak: with the reloader stopped (results not applied are freed) and no frame in flight,
    // the context's one program is all the JIT holds; dropping the context frees it too.
    drop(reloader);
    assert_eq!(live_modules(), baseline.0 + 1, "only the current program is alive after {reloaded} reloads");
    let current = rt.programs_by_id()[0].1.code.code_bytes();
    assert_eq!(live_code_bytes(), baseline.1 + current);
    drop(rt);
    assert_eq!((live_modules(), live_code_bytes()), baseline, "everything freed with the context");
    eprintln!(
        "{frames} frames, {reloaded} reloads, {failed} failed compilations shown, in {:.2} s; one shader holds \
         {one_shader_bytes} bytes of code; at most {peak} JIT modules alive between frames (the context's, and \
         compiled ones not yet applied); {} modules, {} bytes after the context is dropped",
        started.elapsed().as_secs_f64(),
        live_modules(),
        live_code_bytes()
    );
}
