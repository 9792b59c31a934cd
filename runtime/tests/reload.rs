//! Hot reload: edits to a shader or a header it includes are seen by the watcher and swapped in at
//! the next frame; a broken edit keeps the last good code; values bound by name survive where they
//! still fit.

use rtsl_runtime::api::{Context, Primitive};
use rtsl_runtime::reload::{reload_changed, Reload, ShaderEvent, ShaderReloader, ShaderWatcher};
use rtsl_runtime::shading::ParamValue;
use std::time::Duration;

fn scene(rt: &mut Context, path: &std::path::Path) -> rtsl_runtime::api::ShaderId {
    rt.options.width = 16;
    rt.options.height = 12;
    let id = rt.shader_file(path).expect("compiles");
    rt.camera_look_at(glam::Vec3A::new(0.0, 0.0, 3.0), glam::Vec3A::ZERO, glam::Vec3A::Y, 60.0);
    let o = rt.begin_object().expect("object");
    rt.bind_shader(id).expect("bind");
    rt.parameter("k", ParamValue::Float(0.5)).expect("k");
    rt.begin(Primitive::Quads).expect("begin");
    for (x, y) in [(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)] {
        rt.vertex(x, y, 0.0).expect("vertex");
    }
    rt.end().expect("end");
    rt.end_object().expect("end_object");
    rt.instantiate_object(o).expect("instance");
    id
}

fn centre(rt: &mut Context) -> [f32; 4] {
    let (fb, _) = rt.render_frame().expect("a frame");
    fb.pixel(8, 6)
}

#[test]
fn edits_are_swapped_in_and_broken_edits_keep_the_last_good_code() {
    let dir = tempfile::tempdir().expect("tempdir");
    let header = dir.path().join("tint.h");
    let shader = dir.path().join("flat.sl");
    std::fs::write(&header, "#define TINT color(1, 0, 0)\n").expect("write");
    std::fs::write(&shader, "#include \"tint.h\"\nsurface flat(float k = 1;) { Oi = 1; Ci = k * TINT; }\n")
        .expect("write");
    let mut rt = Context::new();
    scene(&mut rt, &shader);
    assert_eq!(centre(&mut rt), [0.5, 0.0, 0.0, 1.0]);
    let watcher = ShaderWatcher::new(&rt).expect("a watcher");
    assert_eq!(watcher.files().len(), 2, "the source and its header");

    // An edit to the header: seen, recompiled, and the bound k = 0.5 still applies.
    std::fs::write(&header, "#define TINT color(0, 1, 0)\n").expect("write");
    let changed = watcher.wait(Duration::from_secs(10), Duration::from_millis(100));
    assert_eq!(changed.len(), 1, "{changed:?}");
    let reloads = reload_changed(&mut rt, &changed);
    assert!(reloads.len() == 1 && reloads[0].result.is_ok(), "{reloads:?}");
    assert_eq!(centre(&mut rt), [0.0, 0.5, 0.0, 1.0]);

    // A broken edit: diagnostics, and the last good code stays.
    std::fs::write(&shader, "surface flat(float k = 1;) { Oi = 1; Ci = k * undefined_thing; }\n").expect("write");
    let reloads = reload_changed(&mut rt, std::slice::from_ref(&shader));
    let err = reloads[0].result.as_ref().expect_err("does not compile");
    assert!(err.contains("undefined_thing"), "{err}");
    assert_eq!(centre(&mut rt), [0.0, 0.5, 0.0, 1.0]);

    // A new parameter list: `k` became a string, so the bound float no longer fits and is dropped
    // with a warning; a new parameter takes its default.
    std::fs::write(&shader, "surface flat(string k = \"\"; color c = color(0, 0, 1);) { Oi = 1; Ci = c; }\n")
        .expect("write");
    let reloads = reload_changed(&mut rt, std::slice::from_ref(&shader));
    assert!(reloads[0].result.is_ok(), "{reloads:?}");
    assert_eq!(centre(&mut rt), [0.0, 0.0, 1.0, 1.0]);
    let mut warnings = rt.take_warnings();
    // A build for plain x86-64 on a newer CPU also says so, in the process's first context.
    warnings.retain(|w| Some(w.as_str()) != rtsl_runtime::cpu::build_note());
    assert!(warnings.len() == 1 && warnings[0].contains("parameter k of shader flat is string"), "{warnings:?}");

    // The same story as events, in order: each reload, then the value the last one dropped.
    let events = rt.take_shader_events();
    assert_eq!(events.len(), 4, "{events:?}");
    assert!(
        matches!(&events[0], ShaderEvent::Reloaded { name, compile_ms, .. } if name == "flat" && *compile_ms > 0.0)
    );
    assert!(matches!(&events[1], ShaderEvent::Failed { diagnostics, .. } if diagnostics.contains("undefined_thing")));
    assert!(matches!(&events[2], ShaderEvent::Reloaded { path, .. } if *path == shader));
    match &events[3] {
        ShaderEvent::ParameterDropped { name, parameter, reason, .. } => {
            assert_eq!((name.as_str(), parameter.as_str()), ("flat", "k"));
            assert!(reason.contains("is string"), "{reason}");
        }
        e => panic!("expected the dropped k, got {e:?}"),
    }
    assert!(rt.take_shader_events().is_empty(), "drained");
}

/// The background reloader: compiles off the caller's thread, swaps only in `apply`, and follows a
/// header that a new version starts to include.
#[test]
fn the_background_reloader_swaps_between_frames_and_follows_new_headers() {
    let dir = tempfile::tempdir().expect("tempdir");
    let shader = dir.path().join("flat.sl");
    let header = dir.path().join("tint.h");
    std::fs::write(&shader, "surface flat(float k = 1;) { Oi = 1; Ci = k * color(1, 0, 0); }\n").expect("write");
    let mut rt = Context::new();
    let id = scene(&mut rt, &shader);
    let mut reloader = ShaderReloader::new(&rt).expect("a reloader");
    assert_eq!(reloader.watched_files(), 1);

    // Applies reloads until one satisfies `done` (a save may be seen as more than one change).
    let until = |reloader: &mut ShaderReloader, rt: &mut Context, done: &dyn Fn(&Reload) -> bool| loop {
        let reloads = reloader.wait_apply(rt, Duration::from_secs(10));
        assert!(!reloads.is_empty(), "no reload within 10 s");
        assert!(reloads.iter().all(|r| r.shader == id), "{reloads:?}");
        if let Some(r) = reloads.into_iter().find(|r| done(r)) {
            return r;
        }
    };
    std::fs::write(&header, "#define TINT color(0, 1, 0)\n").expect("write");
    std::fs::write(&shader, "#include \"tint.h\"\nsurface flat(float k = 1;) { Oi = 1; Ci = k * TINT; }\n")
        .expect("write");
    until(&mut reloader, &mut rt, &|r| r.result.is_ok());
    assert_eq!(centre(&mut rt), [0.0, 0.5, 0.0, 1.0]);

    // The header was not a file of the first version; the reloader watches it now.
    std::fs::write(&header, "#define TINT color(0, 0, 1)\n").expect("write");
    until(&mut reloader, &mut rt, &|r| r.result.is_ok());
    assert_eq!(centre(&mut rt), [0.0, 0.0, 0.5, 1.0]);

    // A broken header: reported, and the last good code stays.
    std::fs::write(&header, "#define TINT color(0, 0, \n").expect("write");
    let r = until(&mut reloader, &mut rt, &|r| r.result.is_err());
    let err = r.result.as_ref().expect_err("does not compile");
    assert!(err.contains("flat.sl") || err.contains("tint.h"), "{err}");
    assert_eq!(centre(&mut rt), [0.0, 0.0, 0.5, 1.0]);
    std::thread::sleep(Duration::from_millis(100));
    assert!(reloader.apply(&mut rt).is_empty());
}
