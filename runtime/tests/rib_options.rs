//! The options and attributes of PRMan and 3Delight that RIB files carry: those rtsl honours
//! (`Option "limits" "othreshold"`, `"threads"`), those it accepts without a word because a ray
//! tracer has no use for them (REYES's buckets, grids and dicing), and those it still warns about.

mod common;

use common::{load, render};

/// Three full-screen squares in front of the camera: green at half opacity at z = 2 and z = 3,
/// opaque red behind them at z = 4; `before` goes before `WorldBegin`.
fn layers(before: &str) -> String {
    let square = |z: f32| format!("Polygon \"P\" [-9 -9 {z}  9 -9 {z}  9 9 {z}  -9 9 {z}]");
    format!(
        "Format 4 4 1\nProjection \"perspective\" \"fov\" [30]\n{before}\nWorldBegin\nSurface \"constant\"\n\
         AttributeBegin Color [0 1 0] Opacity [.5 .5 .5] {} {} AttributeEnd\n\
         Color [1 0 0] {}\nWorldEnd\n",
        square(2.0),
        square(3.0),
        square(4.0)
    )
}

/// The centre pixel's colour.
fn centre(before: &str) -> [f32; 4] {
    let (mut rt, warnings) = load(&layers(before));
    assert_eq!(warnings, Vec::<String>::new());
    render(&mut rt).pixel(2, 2)
}

#[test]
fn camera_rays_stop_where_the_opacity_reaches_the_threshold() {
    let close = |a: f32, b: f32| (a - b).abs() < 1e-5;
    // By default (255/256) a ray goes on through both green layers and sees a quarter of the red.
    let [r, g, _, _] = centre("");
    assert!(close(r, 0.25) && close(g, 0.75), "{r} {g}");
    // Opacity 0.75 after two layers reaches 0.7: the red is hidden.
    let [r, g, _, _] = centre("Option \"limits\" \"othreshold\" [0.7 0.7 0.7]");
    assert!(close(r, 0.0) && close(g, 0.75), "{r} {g}");
    // A float stands for the three; 0.5 after the first layer reaches 0.4.
    let [r, g, _, _] = centre("Option \"limits\" \"float othreshold\" [0.4]");
    assert!(close(r, 0.0) && close(g, 0.5), "{r} {g}");
    // The ray goes on while any channel is below its threshold.
    let [r, g, _, _] = centre("Option \"limits\" \"othreshold\" [0.7 0.7 0.9]");
    assert!(close(r, 0.25) && close(g, 0.75), "{r} {g}");
}

/// The centre pixel's camera-space depth.
fn centre_depth(before: &str) -> f32 {
    let (mut rt, warnings) = load(&layers(before));
    assert_eq!(warnings, Vec::<String>::new());
    let fb = render(&mut rt);
    fb.depth[(2 * fb.width + 2) as usize]
}

#[test]
fn a_pixel_s_depth_is_the_first_surface_opaque_enough() {
    let close = |a: f32, b: f32| (a - b).abs() < 1e-3;
    // PRMan's 0.996 by default: the half-transparent squares are left out.
    let d = centre_depth("");
    assert!(close(d, 4.0), "{d}");
    for (threshold, expected) in [("[0.5 0.5 0.5]", 2.0), ("[0 0 0]", 2.0), ("[0.5 0.5 0.6]", 4.0)] {
        let d = centre_depth(&format!("Option \"limits\" \"zthreshold\" {threshold}"));
        assert!(close(d, expected), "{threshold}: {d}");
    }
    // Where the ray stops before any surface opaque enough, the pixel is infinitely far.
    let d = centre_depth("Option \"limits\" \"othreshold\" [0.7 0.7 0.7]");
    assert!(d.is_infinite(), "{d}");
    // The API's default takes the first surface whatever its opacity.
    let (mut rt, _) = load(&layers(""));
    rt.options.depth_threshold = rtsl_runtime::render::RenderOptions::default().depth_threshold;
    let fb = render(&mut rt);
    let d = fb.depth[(2 * fb.width + 2) as usize];
    assert!(close(d, 2.0), "{d}");
}

#[test]
fn the_max_depth_filter_keeps_the_farthest_surface_opaque_enough() {
    let close = |a: f32, b: f32| (a - b).abs() < 1e-3;
    for (before, expected) in [
        // Every layer counts: the last the ray reaches, the red square.
        ("Option \"limits\" \"zthreshold\" [0 0 0]", 4.0),
        // Only the red square counts.
        ("", 4.0),
        // The ray stops after the second green square (opacity 0.75), the last that counts.
        ("Option \"limits\" \"zthreshold\" [0.5 0.5 0.5] \"othreshold\" [0.7 0.7 0.7]", 3.0),
        // It stops there before any surface counts.
        ("Option \"limits\" \"othreshold\" [0.7 0.7 0.7]", f32::INFINITY),
    ] {
        let d = centre_depth(&format!("Hider \"hidden\" \"depthfilter\" \"max\"\n{before}"));
        assert!(close(d, expected) || d == expected, "{before}: {d}");
    }
}

#[test]
fn a_malformed_opacity_threshold_warns_and_changes_nothing() {
    let (rt, warnings) = load("Option \"limits\" \"float[2] othreshold\" [0.5 0.5]\n");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("othreshold"), "{warnings:?}");
    assert_eq!(rt.options.opacity_threshold, rtsl_runtime::render::RenderOptions::default().opacity_threshold);
}

#[test]
fn a_rib_scene_s_images_are_linear_unless_it_asks_for_srgb() {
    use rtsl_runtime::Transfer;
    for (rib, transfer, stored) in [
        ("", Transfer::Linear, true),
        ("Option \"image\" \"string transfer\" [\"srgb\"]\n", Transfer::Srgb, false),
        ("Option \"image\" \"string transfer\" \"sRGB\"\n", Transfer::Srgb, false),
        ("Option \"image\" \"string transfer\" [\"srgb\"] \"string transfer\" [\"linear\"]\n", Transfer::Linear, true),
        // A gamma of the scene's own makes the files linear, the textures as the option says.
        ("Option \"image\" \"string transfer\" [\"srgb\"]\nExposure 1 2.2\n", Transfer::Linear, false),
    ] {
        let (rt, warnings) = load(rib);
        assert_eq!(warnings, Vec::<String>::new(), "{rib}");
        assert_eq!((rt.options.transfer(), rt.options.textures_as_stored()), (transfer, stored), "{rib}");
    }
    // The API's default stays sRGB.
    let api = rtsl_runtime::render::RenderOptions::default();
    assert_eq!((api.transfer(), api.textures_as_stored()), (Transfer::Srgb, false));
    let (rt, warnings) = load("Option \"image\" \"string transfer\" [\"gamma\"]\n");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("not a transfer: srgb or linear"), "{warnings:?}");
    assert_eq!(rt.options.transfer(), Transfer::Linear);
}

#[test]
fn the_scene_names_its_thread_count() {
    for (rib, threads) in [
        ("Option \"limits\" \"int threads\" [3]\n", Some(3)),
        ("Option \"render\" \"integer nthreads\" [5]\n", Some(5)),
        ("", None),
    ] {
        let (rt, warnings) = load(rib);
        assert_eq!((rt.options.threads, warnings.len()), (threads, 0), "{rib}");
    }
    let (rt, warnings) = load("Option \"limits\" \"int threads\" [0]\n");
    assert_eq!((rt.options.threads, warnings.len()), (None, 1), "{warnings:?}");
}

#[test]
fn the_shadow_bias_option_sets_both_ends_and_bias0_and_bias1_each_one() {
    for (rib, biases) in [
        ("", [0.0, 0.0]),
        ("Option \"shadow\" \"float bias\" [0.3]\n", [0.3, 0.3]),
        ("Option \"shadow\" \"float bias0\" [0.1] \"float bias1\" [0.4]\n", [0.1, 0.4]),
        ("Option \"shadow\" \"float bias\" [0.3] \"float bias1\" [0.5]\n", [0.3, 0.5]),
    ] {
        let (rt, warnings) = load(rib);
        assert_eq!((rt.options.shadow_bias, warnings.len()), (biases, 0), "{rib}");
    }
    let (rt, warnings) = load("Option \"shadow\" \"string bias\" [\"x\"]\n");
    assert_eq!((rt.options.shadow_bias, warnings.len()), ([0.0; 2], 1), "{warnings:?}");
}

#[test]
fn reyes_controls_are_accepted_quietly_and_unknown_names_still_warn() {
    let quiet = "Option \"searchpath\" \"string archive\" [\".\"] \"string procedural\" [\".\"] \
                 \"string display\" [\".\"] \"string resource\" [\".\"]\n\
                 Option \"limits\" \"bucketsize\" [16 16] \"gridsize\" [256] \"texturememory\" [65536] \
                 \"int eyesplits\" [10]\n\
                 Option \"bucket\" \"string order\" [\"horizontal\"]\n\
                 Option \"statistics\" \"int endofframe\" [1] \"int level\" [1]\n\
                 Option \"render\" \"int prmanspecular\" [1]\n\
                 WorldBegin\n\
                 Attribute \"cull\" \"int backfacing\" [0] \"int hidden\" [0]\n\
                 Attribute \"dice\" \"int rasterorient\" [0] \"int binary\" [1]\n\
                 Attribute \"displacementbound\" \"float sphere\" [0.1]\n\
                 Attribute \"shade\" \"float relativeshadingrate\" [1]\n\
                 Attribute \"sides\" \"int doubleshaded\" [0]\n\
                 Attribute \"stochastic\" \"int sigma\" [0]\n\
                 Attribute \"derivatives\" \"int centered\" [1]\n\
                 Attribute \"trace\" \"int decimationrate\" [1]\n\
                 Attribute \"irradiance\" \"float maxerror\" [0.5] \"float maxpixeldist\" [30]\n\
                 WorldEnd\n";
    let (_, warnings) = load(quiet);
    assert_eq!(warnings, Vec::<String>::new());
    let (_, warnings) = load(
        "Option \"limits\" \"int nonsense\" [1]\nWorldBegin\nAttribute \"trace\" \"int nonsense\" [1]\nWorldEnd\n",
    );
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0].contains("\"limits\" \"nonsense\" is not supported"), "{warnings:?}");
    assert!(warnings[1].contains("\"trace\" \"nonsense\" is not supported"), "{warnings:?}");
    // BMRT's own highlight, which rtsl does not have, is said.
    let (_, warnings) = load("Option \"render\" \"int prmanspecular\" [0]\n");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("prmanspecular"), "{warnings:?}");
}

/// The requests that ask for true displacement, or bound it, are read quietly: displacement
/// shaders move the geometry where they ask (`tests/true_displacement.rs`).
#[test]
fn true_displacement_requests_are_read_quietly() {
    let world = |attributes: &str| format!("WorldBegin\n{attributes}\nWorldEnd\n");
    let displaced = "Displacement \"bumpy\"";
    for on in ["Attribute \"trace\" \"int displacements\" [1]", "Attribute \"render\" \"int truedisplacement\" [1]"] {
        for rib in [format!("{on}\n{displaced}\n{displaced}"), format!("{displaced}\n{on}\n{on}")] {
            assert_eq!(load(&world(&rib)).1, Vec::<String>::new(), "{rib}");
        }
        assert_eq!(load(&world(&on.replace("[1]", "[0]"))).1, Vec::<String>::new());
    }
    let bounds = "Attribute \"bound\" \"float displacement\" [0.2]\n\
                  Attribute \"displacementbound\" \"float sphere\" [0.2] \"string coordinatesystem\" [\"shader\"]\n\
                  ShadingRate 4";
    assert_eq!(load(&world(bounds)).1, Vec::<String>::new());
}

/// PRMan's `RiCamera`, which names the camera description (RenderMan for Maya writes
/// `Camera "world" "float[2] shutteropening" [0 1]` in every file), binds no camera shader and says
/// nothing; a `Camera` request without its parameters still names a camera shader, which must exist.
#[test]
fn prman_s_named_camera_is_told_from_a_camera_shader_by_its_parameters() {
    let (rt, warnings) =
        load("Projection \"perspective\"\nCamera \"world\" \"float[2] shutteropening\" [0 1]\nWorldBegin\nWorldEnd\n");
    assert_eq!(warnings, Vec::<String>::new());
    assert!(rt.camera_shader_id().is_none());
    let (rt, warnings) = load("Projection \"perspective\"\nCamera \"fisheye\"\nWorldBegin\nWorldEnd\n");
    assert_eq!(warnings, Vec::<String>::new());
    assert!(rt.camera_shader_id().is_some());
    let (_, warnings) = load("Camera \"nosuchcamera\"\nWorldBegin\nWorldEnd\n");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("nosuchcamera"), "{warnings:?}");
}
