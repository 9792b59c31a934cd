//! Global illumination by virtual point lights (`render/virtual_lights.rs`,
//! `docs/global_illumination.md`), checked against an independent estimate of the same light:
//! `indirectdiffuse()` sampling the hemisphere with rays that shade what they hit.

use rtsl_runtime::api::Context;
use rtsl_runtime::render::{render_frame, Framebuffer};
use std::path::Path;

/// A closed box (white floor, ceiling and back, a red wall on the left, a green one on the right)
/// under a point light, every surface matte with reflectance `Cs` and seen straight on. The
/// camera's primary hits show the indirect light arriving (`indirectdiffuse()`, the mean radiance
/// over the hemisphere); every other hit shows the direct light it reflects, `Cs E / pi`: so the
/// picture is exactly one bounce of indirect light, by whichever estimate is on.
fn box_scene(options: &str) -> (Context, Vec<String>) {
    box_scene_shaded(options, &box_scene_shader())
}

/// [`box_scene`]'s surface: the indirect light `indirectdiffuse()` gives at the first hit, the
/// direct light a matte surface reflects at later ones.
fn box_scene_shader() -> String {
    "surface onebounce() {
        normal Nf = faceforward(normalize(N), I);
        if (raydepth() == 0) {
            Ci = indirectdiffuse(P, Nf, 192);
        } else {
            Ci = Cs * diffuse(Nf) / PI;
        }
        Oi = 1;
    }"
    .to_string()
}

/// [`box_scene`] with every surface shaded by `shader` (a surface named `onebounce`).
fn box_scene_shaded(options: &str, shader: &str) -> (Context, Vec<String>) {
    box_scene_lit(options, r#"LightSource "pointlight" 1 "intensity" 3 "from" [0 0.8 0]"#, shader)
}

/// [`box_scene_shaded`] lit by `light` (a `LightSource` line) instead of its point light.
fn box_scene_lit(options: &str, light: &str, shader: &str) -> (Context, Vec<String>) {
    let rib = format!(
        r#"
        Format 32 24 1
        Projection "perspective" "fov" 60
        {options}
        Translate 0 0 2.6
        WorldBegin
          Attribute "light" "shadows" "on"
        {light}
        Surface "onebounce"
        Color [0.8 0.8 0.8]
        Polygon "P" [-1 -1 -1  1 -1 -1  1 -1 1  -1 -1 1]
        Polygon "P" [-1 1 -1  -1 1 1  1 1 1  1 1 -1]
        Polygon "P" [-1 -1 1  1 -1 1  1 1 1  -1 1 1]
        Color [0.85 0.15 0.1]
        Polygon "P" [-1 -1 -1  -1 -1 1  -1 1 1  -1 1 -1]
        Color [0.1 0.8 0.15]
        Polygon "P" [1 -1 -1  1 1 -1  1 1 1  1 -1 1]
        WorldEnd
        "#
    );
    let mut rt = Context::new();
    rt.compile_shader("onebounce", shader).expect("the test shader compiles");
    let loaded = rtsl_runtime::rib::load::load_str(&mut rt, &rib, Path::new("<box>")).expect("the box loads");
    rt.options.max_ray_depth = 1;
    (rt, loaded.warnings.iter().map(ToString::to_string).collect())
}

/// A batch whose shader gathers virtual lights (`indirectdiffuse` under instant radiosity) runs
/// twice so that its chunks' points gather together (`RenderOptions::trace_ahead`): the image is
/// the one of gathering chunk by chunk, bit for bit, also where a point's second gathering
/// depends on its first one's answer (the first run's placeholder sends it elsewhere, so it is
/// gathered again in the second); where nothing depends on an answer, each point gathers once
/// either way.
#[test]
fn gathering_a_batchs_virtual_lights_ahead_changes_no_pixel() {
    let options = r#"Option "gi" "integer virtuallights" [300] "integer interleave" [3]"#;
    let plain = "surface onebounce() {
        normal Nf = faceforward(normalize(N), I);
        Ci = Cs * (diffuse(Nf) / PI + indirectdiffuse(P, Nf, 16));
        Oi = 1;
    }";
    let dependent = "surface onebounce() {
        normal Nf = faceforward(normalize(N), I);
        color first = indirectdiffuse(P, Nf, 16);
        normal bent = Nf;
        if (comp(first, 0) > 0.02)
            bent = normalize(Nf + normal(0.3, 0.1, 0.2));
        Ci = Cs * (first + indirectdiffuse(P, bent, 16));
        Oi = 1;
    }";
    for (shader, independent) in [(plain, true), (dependent, false)] {
        let (mut rt, warnings) = box_scene_shaded(options, shader);
        assert!(warnings.is_empty(), "{warnings:?}");
        let (ahead, ahead_report) = rt.render_frame().expect("a frame");
        rt.options.trace_ahead = false;
        let (chunked, chunked_report) = rt.render_frame().expect("a frame");
        assert!(ahead == chunked, "independent: {independent}");
        let lit = (0..24).flat_map(|y| (0..32).map(move |x| (x, y))).filter(|&(x, y)| ahead.pixel(x, y)[0] > 0.01);
        assert!(lit.count() > 32 * 24 / 2, "independent: {independent}");
        if independent {
            assert_eq!(ahead_report.shadow_rays, chunked_report.shadow_rays);
        } else {
            assert!(ahead_report.shadow_rays > chunked_report.shadow_rays, "{ahead_report}\n{chunked_report}");
        }
    }
}

fn render(options: &str) -> Framebuffer {
    let (mut rt, warnings) = box_scene(options);
    assert!(warnings.is_empty(), "{warnings:?}");
    let world = rt.build_world().expect("a world");
    render_frame(&world, None).0
}

/// The mean of each colour channel over `rows` and `cols` of the image.
fn mean(fb: &Framebuffer, cols: std::ops::Range<u32>, rows: std::ops::Range<u32>) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    let n = (cols.len() * rows.len()) as f32;
    for y in rows {
        for x in cols.clone() {
            let i = 4 * (y * fb.width + x) as usize;
            for (s, v) in sum.iter_mut().zip(&fb.rgba[i..i + 3]) {
                *s += v / n;
            }
        }
    }
    sum
}

fn relative_error(a: [f32; 3], b: [f32; 3]) -> f32 {
    let (num, den): (f32, f32) =
        (0..3).map(|c| ((a[c] - b[c]).abs(), b[c])).fold((0.0, 0.0), |s, x| (s.0 + x.0, s.1 + x.1));
    num / den.max(1e-6)
}

#[test]
fn virtual_lights_agree_with_sampling_the_hemisphere() {
    let sampled = render("");
    let virtual_lights = render(r#"Option "gi" "integer virtuallights" [6000] "integer interleave" [1]"#);
    let whole = (0..32, 0..24);
    let (a, b) = (mean(&virtual_lights, whole.0.clone(), whole.1.clone()), mean(&sampled, whole.0, whole.1));
    assert!(b.iter().all(|&v| v > 0.01), "the box has indirect light: {b:?}");
    let e = relative_error(a, b);
    eprintln!("image means: virtual lights {a:?}, hemisphere {b:?}, relative error {e}");
    assert!(e < 0.03, "image means: virtual lights {a:?}, hemisphere {b:?} (relative error {e})");
    // Region by region: the floor by the red wall is red, by the green wall green, in both.
    for (cols, rows) in [(0..10, 16..24), (22..32, 16..24), (10..22, 0..8), (10..22, 8..16)] {
        let (a, b) = (mean(&virtual_lights, cols.clone(), rows.clone()), mean(&sampled, cols.clone(), rows.clone()));
        let e = relative_error(a, b);
        assert!(e < 0.15, "columns {cols:?}, rows {rows:?}: virtual lights {a:?}, hemisphere {b:?} ({e})");
    }
    // The light arriving at the red wall (left) comes from the green wall across, and the other
    // way round.
    let (left, right) = (mean(&virtual_lights, 0..4, 6..18), mean(&virtual_lights, 28..32, 6..18));
    assert!(left[1] > 1.1 * left[0] && right[0] > 1.1 * right[1], "colour bleeds: left {left:?}, right {right:?}");
}

#[test]
fn interleaving_changes_which_lights_a_pixel_sees_not_how_much_light_there_is() {
    let all = render(r#"Option "gi" "integer virtuallights" [4000] "integer interleave" [1]"#);
    let interleaved = render(r#"Option "gi" "integer virtuallights" [4000] "integer interleave" [3]"#);
    let (a, b) = (mean(&interleaved, 0..30, 0..24), mean(&all, 0..30, 0..24));
    let e = relative_error(a, b);
    assert!(e < 0.05, "interleaved {a:?}, every light {b:?} ({e})");
    // Neighbours see different sets: the interleaved image differs pixel to pixel from the other.
    let differing = interleaved.rgba.iter().zip(&all.rgba).filter(|(x, y)| (*x - *y).abs() > 1e-4).count();
    assert!(differing > interleaved.rgba.len() / 4, "{differing} values differ");
}

#[test]
fn bad_gi_options_are_warnings_and_counts_are_clamped() {
    let (rt, warnings) =
        box_scene(r#"Option "gi" "integer virtuallights" [-5] "integer interleave" [1000] "float clamp" [-1]"#);
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings.iter().all(|w| w.contains("\"gi\"")), "{warnings:?}");
    assert_eq!(rt.options.gi.virtual_lights, 0);
    assert_eq!(rt.options.gi.interleave, rtsl_runtime::render::world::MAX_INTERLEAVE);
    let (rt, _) = box_scene(r#"Option "gi" "float virtuallights" [1e12]"#);
    assert_eq!(rt.options.gi.virtual_lights, rtsl_runtime::render::world::MAX_VIRTUAL_LIGHT_PATHS);
    let (rt, warnings) = box_scene(r#"Option "gi" "float globalphotons" [1e12] "string causticphotons" ["many"]"#);
    assert_eq!(rt.options.gi.global_photons, rtsl_runtime::render::world::MAX_VIRTUAL_LIGHT_PATHS);
    assert_eq!(rt.options.gi.caustic_photons, 0);
    assert!(warnings.len() == 1 && warnings[0].contains("\"causticphotons\" takes a number"), "{warnings:?}");
}

#[test]
fn progressive_passes_gather_fresh_virtual_lights_and_converge() {
    use rtsl_runtime::render::progressive::render_progressive;
    let reference = render(r#"Option "gi" "integer virtuallights" [8000] "integer interleave" [1]"#);
    let (mut rt, _) = box_scene(r#"Option "gi" "integer virtuallights" [200] "integer interleave" [3]"#);
    rt.options.antialiasing = rtsl_runtime::render::Antialiasing::Grid { jitter: false };
    let world = rt.build_world().expect("a world");
    let error = |passes: u32| {
        let image = render_progressive(&world, passes).0.resolve(&world);
        let n = image.rgba.len() as f32;
        image.rgba.iter().zip(&reference.rgba).map(|(a, b)| (a - b).abs()).sum::<f32>() / n
    };
    let (one, many) = (error(1), error(24));
    // Each pass's own paths: the pattern of one pass's sets averages out.
    assert!(many < one / 2.5, "mean difference from the reference: 1 pass {one}, 24 passes {many}");
}

/// The pixels of `fb` (indices) the interleave filter of size 3 averages for pixel `(x, y)`: those
/// of the 3x3 block around it, inside the image, that see its object at a depth within 5% of its
/// own (the scenes' walls are flat: the normals' test takes them all).
fn neighbours_taken(fb: &Framebuffer, x: i64, y: i64) -> Vec<usize> {
    let (w, h) = (fb.width as i64, fb.height as i64);
    let i = (y * w + x) as usize;
    let (z, id) = (fb.depth[i], fb.object_id[i]);
    let block = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)));
    block
        .filter(|&(nx, ny)| nx >= 0 && ny >= 0 && nx < w && ny < h)
        .map(|(nx, ny)| (ny * w + nx) as usize)
        .filter(|&j| fb.object_id[j] == id && (fb.depth[j] - z).abs() <= 0.05 * z)
        .collect()
}

#[test]
fn the_interleave_filter_removes_the_pattern_within_surfaces() {
    // Few paths: each pixel's ninth of them is noisy, the noise the filter is for.
    let every = r#"Option "gi" "integer virtuallights" [270] "integer interleave" [1]"#;
    let interleaved = r#"Option "gi" "integer virtuallights" [270] "integer interleave" [3]"#;
    let filtered = format!("{interleaved}\nImager \"interleavefilter\" \"size\" [3]");
    let (all, raw, smooth) = (render(every), render(interleaved), render(&filtered));
    let difference =
        |a: &Framebuffer| a.rgba.iter().zip(&all.rgba).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.rgba.len() as f32;
    // The pattern: how much neighbouring pixels differ.
    let roughness = |a: &Framebuffer| {
        let w = 4 * a.width as usize;
        let pairs = a.rgba.chunks(w).flat_map(|row| row.iter().zip(&row[4..]).map(|(x, y)| (x - y).abs()));
        pairs.sum::<f32>() / a.rgba.len() as f32
    };
    let (before, after) = (difference(&raw), difference(&smooth));
    let (rough_raw, rough_smooth, rough_all) = (roughness(&raw), roughness(&smooth), roughness(&all));
    eprintln!("difference from every light: interleaved {before}, filtered {after}; neighbours differ by {rough_raw}, {rough_smooth} (every light {rough_all})");
    assert!(after < 0.8 * before, "mean difference from every light: interleaved {before}, filtered {after}");
    // Beyond the image's own gradients (every light's), the pattern is mostly gone.
    let (pattern_raw, pattern_smooth) = (rough_raw - rough_all, rough_smooth - rough_all);
    assert!(pattern_smooth < pattern_raw / 3.0, "the pattern: {pattern_raw} interleaved, {pattern_smooth} filtered");
    // Pixel by pixel, what docs/shaders.md says: the mean over the 3x3 pixels around it (inside
    // the image) that see its object at a depth within 5% of its own (and with its normal: each
    // wall is flat); the walls are objects of their own, so none is mixed with another.
    let (w, h) = (raw.width as i64, raw.height as i64);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if raw.object_id[i] == u32::MAX {
                // Nothing seen: left as it is.
                assert_eq!(&smooth.rgba[4 * i..4 * i + 4], &raw.rgba[4 * i..4 * i + 4]);
                continue;
            }
            let mut sum = [0.0f32; 3];
            let taken = neighbours_taken(&raw, x, y);
            for &j in &taken {
                for (s, v) in sum.iter_mut().zip(&raw.rgba[4 * j..4 * j + 3]) {
                    *s += v;
                }
            }
            let n = taken.len() as f32;
            for (c, total) in sum.iter().enumerate() {
                let want = total / n;
                let got = smooth.rgba[4 * i + c];
                assert!((want - got).abs() < 1e-4 * want.max(1.0), "pixel {x}, {y}: {got}, the filter's {want}");
            }
        }
    }
}

/// A surface like `gimatte` whose reflectance is a checkerboard (texture detail the filter must
/// keep), saying which part of its colour is indirect light through `gimatte`'s outputs when
/// `outputs`, or keeping them to itself.
fn checkered_gimatte(outputs: bool) -> String {
    let (params, locals) = match outputs {
        true => ("output varying color indirect = 0; output varying color indirectweight = 0;", ""),
        false => ("", "color indirect = 0, indirectweight = 0;"),
    };
    format!(
        "surface onebounce({params}) {{
            {locals}
            normal Nf = faceforward(normalize(N), I);
            float check = mod(floor(3 * xcomp(P) + 3) + floor(3 * ycomp(P) + 3) + floor(3 * zcomp(P) + 3), 2);
            Oi = Os;
            indirectweight = Os * Cs * mix(0.15, 1, check);
            indirect = indirectdiffuse(P, Nf, 16);
            Ci = indirectweight * (diffuse(Nf) / PI + indirect);
        }}"
    )
}

/// Renders the box shaded by `shader` (a surface named `onebounce`) under `options`, keeping the
/// output variables `kept`.
fn render_shaded(options: &str, shader: &str, kept: &[&str]) -> Framebuffer {
    let (mut rt, warnings) = box_scene_shaded(options, shader);
    assert!(warnings.is_empty(), "{warnings:?}");
    rt.options.max_ray_depth = 4;
    rt.options.outputs = kept.iter().map(ToString::to_string).collect();
    let world = rt.build_world().expect("a world");
    render_frame(&world, None).0
}

/// A viewer's pass, accumulated and resolved, keeps the output variables the interleave filter
/// reads, so the filter smooths the indirect light alone there as in a frame: one pass is the
/// frame's image, not the whole-colour filter's.
#[test]
fn an_accumulated_pass_gives_the_interleave_filter_the_outputs_it_reads() {
    use rtsl_runtime::render::progressive::render_progressive;
    let options = r#"Option "gi" "integer virtuallights" [270] "integer interleave" [3]
        Imager "interleavefilter" "size" [3]"#;
    let frame_and_pass = |shader: &str| {
        let (mut rt, warnings) = box_scene_shaded(options, shader);
        assert!(warnings.is_empty(), "{warnings:?}");
        rt.options.max_ray_depth = 4;
        rt.options.antialiasing = rtsl_runtime::render::Antialiasing::Grid { jitter: false };
        let world = rt.build_world().expect("a world");
        (render_frame(&world, None).0, render_progressive(&world, 1).0.resolve(&world))
    };
    let (frame, accumulated) = frame_and_pass(&checkered_gimatte(true));
    let (_, whole) = frame_and_pass(&checkered_gimatte(false));
    let largest = |a: &Framebuffer, b: &Framebuffer| {
        a.rgba.iter().zip(&b.rgba).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max)
    };
    let (from_frame, from_whole) = (largest(&frame, &accumulated), largest(&whole, &accumulated));
    assert!(from_frame < 1e-5, "largest difference from the frame {from_frame}");
    assert!(from_whole > 0.01, "largest difference from the whole-colour filter {from_whole}");
}

/// Where the surface gives its indirect light and its weight (`gimatte`'s outputs), the interleave
/// filter smooths that light alone: each pixel keeps its own colour but for its indirect light,
/// which becomes its weight times the mean indirect light of the neighbours the discontinuity
/// buffer takes, so the checkerboard and the direct light stay as sharp as unfiltered; the same
/// surface hiding its outputs has its whole colour smoothed, the checkerboard's edges with it.
#[test]
fn the_interleave_filter_smooths_the_indirect_light_alone_where_the_surface_gives_it() {
    let gi = r#"Option "gi" "integer virtuallights" [270] "integer interleave" [3]"#;
    let filtered = format!("{gi}\nImager \"interleavefilter\" \"size\" [3]");
    let kept = ["indirect", "indirectweight"];
    let (with_outputs, without) = (checkered_gimatte(true), checkered_gimatte(false));
    let raw = render_shaded(gi, &with_outputs, &kept);
    let split = render_shaded(&filtered, &with_outputs, &kept);
    let whole = render_shaded(&filtered, &without, &[]);
    let output = |fb: &Framebuffer, name: &str| -> Vec<[f32; 3]> {
        let kept = fb.outputs.iter().find(|(n, _)| n == name);
        kept.unwrap_or_else(|| panic!("the frame keeps {name}")).1.clone()
    };
    // The filter reading them is enough for the frame to keep them (`CompiledShader::pixel_outputs`).
    let unasked = render_shaded(&filtered, &with_outputs, &[]);
    assert!(unasked.outputs.is_empty() && unasked.rgba == split.rgba, "the filter gets its outputs unasked");
    let (indirect, weight) = (output(&raw, "indirect"), output(&raw, "indirectweight"));
    assert_eq!(indirect, output(&split, "indirect"), "the pixel shader changes no surface's outputs");
    let seen = |i: usize| raw.object_id[i] != u32::MAX;
    let lit = (0..weight.len()).filter(|&i| seen(i)).all(|i| weight[i].iter().all(|&c| c > 0.0));
    assert!(lit, "every pixel that sees the box has a weight");
    assert!((0..weight.len()).filter(|&i| seen(i)).count() > weight.len() / 2, "the box fills most of the image");
    // Pixel by pixel: the colour unfiltered, plus the weight times the neighbours' mean indirect
    // light less the pixel's own (the neighbours as the whole-colour filter takes them).
    let (w, h) = (raw.width as i64, raw.height as i64);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if !seen(i) {
                assert_eq!(&split.rgba[4 * i..4 * i + 4], &raw.rgba[4 * i..4 * i + 4], "nothing seen: left as it is");
                continue;
            }
            let mut sum = [0.0f32; 3];
            let taken = neighbours_taken(&raw, x, y);
            for &j in &taken {
                for (s, v) in sum.iter_mut().zip(&indirect[j]) {
                    *s += v;
                }
            }
            let n = taken.len() as f32;
            for c in 0..3 {
                let want = raw.rgba[4 * i + c] + weight[i][c] * (sum[c] / n - indirect[i][c]);
                let got = split.rgba[4 * i + c];
                assert!((want - got).abs() < 1e-4 * want.abs().max(1.0), "pixel {x}, {y}: {got}, the filter's {want}");
            }
        }
    }
    // The whole colour smoothed moves pixels much further from the unfiltered image (the
    // checkerboard's edges and the direct light's gradients are averaged too).
    let mean_difference =
        |a: &Framebuffer| a.rgba.iter().zip(&raw.rgba).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.rgba.len() as f32;
    let (by_split, by_whole) = (mean_difference(&split), mean_difference(&whole));
    eprintln!("mean difference from unfiltered: indirect light smoothed {by_split}, whole colour {by_whole}");
    assert!(by_split < 0.5 * by_whole, "indirect light smoothed {by_split}, whole colour {by_whole}");
    // And the interleaving's pattern is smoothed as before: the image comes nearer to the one of
    // every light at every pixel.
    let every =
        render_shaded(r#"Option "gi" "integer virtuallights" [270] "integer interleave" [1]"#, &with_outputs, &[]);
    let from_every =
        |a: &Framebuffer| a.rgba.iter().zip(&every.rgba).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.rgba.len() as f32;
    let (before, after) = (from_every(&raw), from_every(&split));
    eprintln!("mean difference from every light: interleaved {before}, indirect light smoothed {after}");
    assert!(after < 0.8 * before, "mean difference from every light: interleaved {before}, smoothed {after}");
}

#[test]
fn a_pixel_shader_reading_pixels_sees_the_same_image_tile_by_tile_and_accumulated() {
    use rtsl_runtime::render::progressive::render_progressive;
    let options =
        "Option \"gi\" \"integer virtuallights\" [500] \"integer interleave\" [3]\nImager \"interleavefilter\"";
    let (mut rt, warnings) = box_scene(options);
    assert!(warnings.is_empty(), "{warnings:?}");
    rt.options.antialiasing = rtsl_runtime::render::Antialiasing::Grid { jitter: false };
    let world = rt.build_world().expect("a world");
    let (frame, _) = render_frame(&world, None);
    let accumulated = render_progressive(&world, 1).0.resolve(&world);
    let worst = frame.rgba.iter().zip(&accumulated.rgba).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "largest difference {worst}");
}

/// Loads `rib` (a whole scene) with the pixel shader `source` compiled as `name`.
fn scene_with_pixel_shader(rib: &str, name: &str, source: &str) -> Context {
    let mut rt = Context::new();
    rt.compile_shader(name, source).expect("the test shader compiles");
    let loaded = rtsl_runtime::rib::load::load_str(&mut rt, rib, Path::new("<test>")).expect("the scene loads");
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    rt
}

#[test]
fn pixelvalue_n_is_the_normal_each_pixel_sees() {
    // A floor (normal +y) and, on the right, a wall turned 37 degrees about y (its normal, facing
    // the camera, (0.6, 0, -0.8)); the upper left sees nothing. Each pixel shows the normal
    // `pixelvalue` gives for its mirror image across the middle column: another pixel's.
    let rib = r#"
        Format 32 24 1
        Projection "perspective" "fov" 60
        Imager "mirrornormal"
        WorldBegin
          Attribute "light" "shadows" "on"
        Surface "matte"
        AttributeBegin
        Color [0.8 0.8 0.8]
        Polygon "P" [-20 -1 0.5  20 -1 0.5  20 -1 20  -20 -1 20]
        AttributeEnd
        AttributeBegin
        Color [0.8 0.3 0.2]
        Polygon "P" [0 -1 5  12 -1 14  12 10 14  0 10 5]
        AttributeEnd
        WorldEnd
    "#;
    let shader = r#"pixel mirrornormal() {
        float format[3];
        option("Format", format);
        Ci = color pixelvalue("N", format[0] - xcomp(P), ycomp(P));
    }"#;
    let mut rt = scene_with_pixel_shader(rib, "mirrornormal", shader);
    rt.options.antialiasing = rtsl_runtime::render::Antialiasing::Grid { jitter: false };
    let world = rt.build_world().expect("a world");
    let (frame, _) = render_frame(&world, None);
    // The viewer's way (an accumulated pass, resolved) gives the same normals.
    let accumulated = rtsl_runtime::render::progressive::render_progressive(&world, 1).0.resolve(&world);
    let (w, h) = (frame.width, frame.height);
    let id = |x: u32, y: u32| frame.object_id[(y * w + x) as usize];
    // The bottom left pixel sees the floor, the middle of the right edge the wall.
    let (floor, wall) = (id(0, h - 1), id(w - 1, h / 2));
    assert!(floor != u32::MAX && wall != u32::MAX && floor != wall, "floor {floor}, wall {wall}");
    let mut seen = [0; 3];
    for image in [&frame, &accumulated] {
        seen = [0; 3];
        for y in 0..h {
            for x in 0..w {
                let mirror = id(w - 1 - x, y);
                let (want, k) = match mirror {
                    m if m == floor => ([0.0, 1.0, 0.0], 0),
                    m if m == wall => ([0.6, 0.0, -0.8], 1),
                    u32::MAX => ([0.0; 3], 2),
                    m => panic!("pixel {x}, {y}: object {m}"),
                };
                seen[k] += 1;
                let got = image.pixel(x, y);
                for c in 0..3 {
                    assert!((got[c] - want[c]).abs() < 1e-3, "pixel {x}, {y} reads {got:?}, the normal {want:?}");
                }
            }
        }
    }
    assert!(seen.iter().all(|&n| n > 20), "floor, wall and nothing: {seen:?} pixels");
}

#[test]
fn the_interleave_filter_keeps_the_faces_of_a_crease_apart() {
    // One object folded along a vertical crease that points at the camera: its faces meet at one
    // depth, so object and depth alone do not tell them apart. A red light from the left lights
    // the left face, a blue one from the right the right face: each face one flat colour.
    let rib = |imager: &str| {
        format!(
            r#"
            Format 32 24 1
            Projection "perspective" "fov" 60
            {imager}
            WorldBegin
              Attribute "light" "shadows" "on"
            LightSource "distantlight" 1 "intensity" 1 "lightcolor" [1 0 0] "from" [0 0 0] "to" [1 0 0.3]
            LightSource "distantlight" 2 "intensity" 1 "lightcolor" [0 0 1] "from" [0 0 0] "to" [-1 0 0.3]
            Surface "matte"
            PointsPolygons [4 4] [0 1 2 3  1 4 5 2]
                "P" [-3 -3 7  0 -3 4  0 3 4  -3 3 7  3 -3 7  3 3 7]
            WorldEnd
            "#
        )
    };
    let render = |imager: &str| {
        let mut rt = Context::new();
        let loaded =
            rtsl_runtime::rib::load::load_str(&mut rt, &rib(imager), Path::new("<crease>")).expect("the scene loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        render_frame(&rt.build_world().expect("a world"), None).0
    };
    let raw = render("");
    let filtered = render(r#"Imager "interleavefilter""#);
    let mixed = render(r#"Imager "interleavefilter" "normaltolerance" [-1]"#);
    let (w, h) = (raw.width, raw.height);
    // The crease: the pixels of each row where red gives way to blue, same object, same depth.
    let mut crease = Vec::new();
    for y in 0..h {
        for x in 0..w - 1 {
            let (a, b) = (raw.pixel(x, y), raw.pixel(x + 1, y));
            if a[0] > 0.1 && a[2] == 0.0 && b[2] > 0.1 && b[0] == 0.0 {
                let (i, j) = ((y * w + x) as usize, (y * w + x + 1) as usize);
                assert_eq!(raw.object_id[i], raw.object_id[j], "row {y}: one object");
                assert!((raw.depth[i] - raw.depth[j]).abs() < 0.05 * raw.depth[i], "row {y}: one depth");
                crease.push((x, y));
            }
        }
    }
    assert!(crease.len() >= 10, "the crease is seen in {} rows", crease.len());
    let largest = |a: &Framebuffer, b: &Framebuffer| {
        a.rgba.iter().zip(&b.rgba).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max)
    };
    // With the normal test each pixel's neighbours are its own face's, all of its colour: the
    // filter leaves the image as it was.
    let kept = largest(&filtered, &raw);
    assert!(kept < 1e-5, "the filtered image differs from the unfiltered one by up to {kept}");
    // Without it, the pixels beside the crease take in the other face's colour.
    for &(x, y) in &crease {
        let (left, right) = (mixed.pixel(x, y), mixed.pixel(x + 1, y));
        assert!(left[2] > 0.05 && right[0] > 0.05, "row {y}: {left:?} and {right:?} should be mixed");
    }
    let mixed_pixels = (0..(w * h) as usize)
        .filter(|&i| (0..3).any(|c| (mixed.rgba[4 * i + c] - raw.rgba[4 * i + c]).abs() > 0.05))
        .count();
    assert!(mixed_pixels >= 2 * crease.len(), "{mixed_pixels} pixels mixed without the normal test");
}

/// A floor (matte) under a horizontal mirror (chrome, reflectance 0.8) with a point light between
/// them: every photon that reaches the floor by the mirror comes from the light's mirror image,
/// so the caustic irradiance on the floor is that of a point light of 0.8 times the intensity at
/// the image: `E = 0.8 I h / d^3` (`h` the image's height over the floor, `d` the distance).
/// How the red channel of the central 16x16 pixels of a 24x24 image of the floor `y = 0` (seen
/// from above) compares with the irradiance a point source of intensity `intensity` at `source`
/// gives it, `I h / d^3`: the relative error of the sum, and of the worst pixel.
fn against_a_point_source(
    world: &rtsl_runtime::render::World,
    fb: &Framebuffer,
    source: rtsl_runtime::glam::Vec3A,
    intensity: f32,
) -> (f64, f32) {
    let (mut got, mut want, mut worst) = (0.0f64, 0.0f64, 0.0f32);
    for y in 4..20 {
        for x in 4..20 {
            let i = (y * 24 + x) as usize;
            assert_ne!(fb.object_id[i], u32::MAX, "pixel {x}, {y} sees the floor");
            // The floor point this pixel sees: along its camera ray to y = 0.
            let ray = rtsl_runtime::render::camera_ray(world, x, y, 0.5, 0.5);
            let p = ray.origin + ray.direction * (-ray.origin.y / ray.direction.y);
            let d = (p - source).length();
            let analytic = intensity * source.y / (d * d * d);
            let estimate = fb.rgba[4 * i];
            got += f64::from(estimate);
            want += f64::from(analytic);
            worst = worst.max((estimate / analytic - 1.0).abs());
        }
    }
    assert!(want > 0.0, "no light arrives");
    ((got / want - 1.0).abs(), worst)
}

/// A 24x24 image, seen from above, of the floor `y = 0` (6 x 6, colour 0.8) showing the
/// irradiance the frame's photon map `map` (`"caustic"` or `"global"`, 300000 paths) estimates
/// from 300 photons, under a point light of intensity 4 at height 2, with a horizontal chrome
/// mirror of the same size at height 3 when `mirror`.
fn photons_on_a_floor(map: &str, mirror: bool) -> (rtsl_runtime::render::World, Framebuffer) {
    use rtsl_runtime::api::Primitive;
    use rtsl_runtime::glam::Vec3A;
    use rtsl_runtime::render::world::PhotonModel;
    use rtsl_runtime::shading::ParamValue;
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    rt.options.width = 24;
    rt.options.height = 24;
    rt.options.antialiasing = rtsl_runtime::render::Antialiasing::Grid { jitter: false };
    match map {
        "caustic" => rt.options.gi.caustic_photons = 300_000,
        _ => rt.options.gi.global_photons = 300_000,
    }
    rt.camera_look_at(Vec3A::new(0.0, 2.5, 0.01), Vec3A::ZERO, Vec3A::Z, 50.0);
    let probe = format!(
        "surface probe() {{ normal Nf = faceforward(normalize(N), I); Ci = photonmap(\"{map}\", P, Nf, \"estimator\", 300); Oi = 1; }}"
    );
    let shader = rt.compile_shader("probe", &probe).map_err(e).expect("compiles");
    let quad = |rt: &mut Context, y: f32, model: PhotonModel| {
        rt.photon_shading_model(model);
        let object = rt.begin_object().map_err(e).expect("an object");
        rt.bind_shader(shader).map_err(e).expect("bound");
        rt.begin(Primitive::Quads).map_err(e).expect("quads");
        for (x, z) in [(-3.0, -3.0), (3.0, -3.0), (3.0, 3.0), (-3.0, 3.0)] {
            rt.vertex(x, y, z).map_err(e).expect("a vertex");
        }
        rt.end().map_err(e).expect("end");
        rt.end_object().map_err(e).expect("end_object");
        rt.instantiate_object(object).map_err(e).expect("an instance");
    };
    rt.color(0.8, 0.8, 0.8);
    quad(&mut rt, 0.0, PhotonModel::Matte);
    if mirror {
        quad(&mut rt, 3.0, PhotonModel::Chrome);
    }
    let light = rt.find_shader("pointlight").map_err(e).expect("pointlight");
    rt.light_source(light, &[("intensity", ParamValue::Float(4.0)), ("from", ParamValue::Point([0.0, 2.0, 0.0]))])
        .map_err(e)
        .expect("a light");
    let world = rt.build_world().expect("a world");
    let fb = render_frame(&world, None).0;
    (world, fb)
}

#[test]
fn caustic_photons_under_a_mirror_give_the_mirror_images_light() {
    use rtsl_runtime::glam::Vec3A;
    let (world, fb) = photons_on_a_floor("caustic", true);
    // The mirror image of the light, at height 4, lights the floor through the mirror.
    let (relative, worst) = against_a_point_source(&world, &fb, Vec3A::new(0.0, 4.0, 0.0), 0.8 * 4.0);
    eprintln!("caustic irradiance: relative error {relative}, worst pixel {worst}");
    assert!(relative < 0.02, "the estimate is off by {relative}");
    assert!(worst < 0.1, "the worst pixel is off by {worst}");
}

#[test]
fn photon_shading_models_are_read_from_rib_and_bad_ones_are_warnings() {
    use rtsl_runtime::render::world::PhotonModel;
    let rib = r#"
        WorldBegin
        Attribute "photon" "shadingmodel" "refractive:ior=1.2"
        Polygon "P" [0 0 0  1 0 0  1 1 0]
        Attribute "photon" "shadingmodel" "plasma"
        Polygon "P" [0 0 1  1 0 1  1 1 1]
        Attribute "photon" "shadingmodel" "water"
        Polygon "P" [0 0 2  1 0 2  1 1 2]
        WorldEnd
    "#;
    let mut rt = Context::new();
    let loaded = rtsl_runtime::rib::load::load_str(&mut rt, rib, Path::new("<models>")).expect("loads");
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    assert!(
        loaded.warnings[0].to_string().contains("<models>:5") && loaded.warnings[0].message.contains("\"plasma\""),
        "{:?}",
        loaded.warnings
    );
    let world = rt.build_world().expect("a world");
    let mut models: Vec<PhotonModel> = world.materials.iter().map(|m| m.photon).collect();
    models.dedup();
    assert!(
        models.contains(&PhotonModel::Glass { eta: 1.2 }) && models.contains(&PhotonModel::Glass { eta: 1.33 }),
        "{models:?}"
    );
}

/// The Cornell box of `../shared/scenes` lit by virtual lights (one bounce), frames with fresh
/// lights averaged, against a converged path-traced reference from Mitsuba 3 stored at 32x24 (the
/// 20x20-pixel block means of a 640x480, 1024-sample image: `benches/gi_against_mitsuba.py`
/// renders it). Every surface is diffuse grey 0.7. Sixteen frames accumulated need no filter (which
/// at this size would blur the direct light's shadow edges into the blocks).
#[test]
fn the_cornell_box_matches_mitsubas_path_traced_reference() {
    let obj = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes/cornell_box/cornell_box.obj");
    let Ok(text) = std::fs::read_to_string(&obj) else {
        eprintln!("SKIPPED: {} is not there (the shared scenes)", obj.display());
        return;
    };
    let dir = tempfile::tempdir().expect("a temporary directory");
    // The box without its materials: grey everywhere, as in the reference.
    let grey: String = text
        .lines()
        .filter(|l| !l.starts_with("mtllib") && !l.starts_with("usemtl"))
        .map(|l| format!("{l}\n"))
        .collect();
    let mesh = dir.path().join("box.obj");
    std::fs::write(&mesh, grey).expect("written");
    let (w, h, frames) = (160u32, 120u32, 16u32);
    let mut sum = vec![0.0f32; (3 * w * h) as usize];
    for seed in 0..frames {
        let rib = format!(
            r#"
            Format {w} {h} 1
            Projection "perspective" "fov" [39.3]
            Option "gi" "integer virtuallights" [256] "integer bounces" [1] "integer interleave" [3] "integer seed" [{seed}]
            Scale -1 1 1
            Translate -278 -273 800
            WorldBegin
              Attribute "light" "shadows" "on"
              LightSource "pointlight" 1 "intensity" [282743.34] "from" [278 540 279.5]
              Color [0.7 0.7 0.7]
              Surface "gimatte"
              ReadArchive "{}"
            WorldEnd
            "#,
            mesh.display()
        );
        let mut rt = Context::new();
        let loaded =
            rtsl_runtime::rib::load::load_str(&mut rt, &rib, dir.path().join("box.rib")).expect("the box loads");
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let world = rt.build_world().expect("a world");
        let (fb, _) = render_frame(&world, None);
        for (i, s) in sum.iter_mut().enumerate() {
            *s += fb.rgba[4 * (i / 3) + i % 3] / frames as f32;
        }
    }
    let reference =
        rtsl_runtime::read_image(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cornell_gi_reference.exr"))
            .expect("the stored reference");
    assert_eq!((reference.width, reference.height), (32, 24));
    // rtsl's image in the reference's blocks: 5x5 pixels each.
    let mut error = 0.0f32;
    for by in 0..24 {
        for bx in 0..32 {
            for c in 0..3 {
                let mut mean = 0.0;
                for y in 5 * by..5 * by + 5 {
                    for x in 5 * bx..5 * bx + 5 {
                        mean += sum[(3 * (y * w + x) + c) as usize] / 25.0;
                    }
                }
                let r = reference.pixels[4 * (by * 32 + bx) as usize + c as usize];
                error += (mean - r).abs() / (r + 0.01);
            }
        }
    }
    let error = error / (32.0 * 24.0 * 3.0);
    eprintln!("mean relative error of the 20x20-pixel blocks against Mitsuba: {error}");
    assert!(error < 0.05, "mean relative error {error}");
}

/// A pass traced in pieces that share a `LightPathCache` (the viewer's slices, a worker's
/// lattices) gets exactly the samples of the pass traced whole, with its light paths traced once:
/// the cache lends them to the pass's later pieces, never to another pass or a changed world.
#[test]
fn the_pieces_of_a_pass_share_its_light_paths() {
    use rtsl_runtime::render::progressive::{pass_lattices, trace_lattices, trace_lattices_keeping, LatticeTracer};
    use rtsl_runtime::render::LightPathCache;
    let (mut rt, _) = box_scene(
        r#"Option "gi" "integer virtuallights" [300] "integer interleave" [3] "integer causticphotons" [2000]"#,
    );
    rt.options.antialiasing = rtsl_runtime::render::Antialiasing::Grid { jitter: false };
    let mut world = rt.build_world().expect("a world");
    let lattices = pass_lattices(32, 24, 1);
    assert!(lattices.len() >= 4, "{} lattices", lattices.len());
    let all = |_: u32, _: u32| true;
    let colours = |traced: &[rtsl_runtime::render::progressive::LatticeSamples]| -> Vec<u32> {
        traced.iter().flat_map(|l| l.samples.iter().flat_map(|s| s.color.to_array().map(f32::to_bits))).collect()
    };
    for pass in [0, 3] {
        let whole = colours(&trace_lattices(&world, &lattices, pass, false, &all).0);
        let cache = LightPathCache::default();
        let mut pieces = Vec::new();
        for piece in lattices.chunks(lattices.len().div_ceil(3)) {
            pieces.extend(trace_lattices_keeping(&world, piece, pass, false, &all, &cache).0);
        }
        assert_eq!(colours(&pieces), whole, "pass {pass} in pieces");
        assert!(LatticeTracer::new(&world, pass, false).reuse_light_paths(&cache), "pass {pass} kept");
        assert!(!LatticeTracer::new(&world, pass + 1, false).reuse_light_paths(&cache), "another pass");
    }
    let cache = LightPathCache::default();
    trace_lattices_keeping(&world, &lattices[..1], 0, false, &all, &cache);
    world.prepare();
    assert!(!LatticeTracer::new(&world, 0, false).reuse_light_paths(&cache), "a changed world");
}

/// The global photon map's estimate on a floor lit by a point light alone (nothing to bounce
/// light back) is the direct irradiance, `I h / d^3`; in a closed box it adds the light that
/// arrives after bounces, as virtual lights count it.
#[test]
fn global_photons_give_the_irradiance_of_direct_and_bounced_light() {
    use rtsl_runtime::glam::Vec3A;
    let (world, fb) = photons_on_a_floor("global", false);
    let (relative, worst) = against_a_point_source(&world, &fb, Vec3A::new(0.0, 2.0, 0.0), 4.0);
    eprintln!("global irradiance: relative error {relative}, worst pixel {worst}");
    assert!(relative < 0.02, "the estimate is off by {relative}");
    assert!(worst < 0.1, "the worst pixel is off by {worst}");

    // In the closed box, the global map's irradiance less the direct part is the indirect light
    // that virtual lights give: `indirectdiffuse()` is irradiance over pi.
    let gathered = |options: &str, shader: &str| {
        let (mut rt, warnings) = box_scene_shaded(options, shader);
        assert!(warnings.is_empty(), "{warnings:?}");
        let world = rt.build_world().expect("a world");
        let fb = render_frame(&world, None).0;
        mean(&fb, 4..28, 4..20)
    };
    let from_photons = gathered(
        r#"Option "gi" "integer globalphotons" [400000]"#,
        "surface onebounce() {
            normal Nf = faceforward(normalize(N), I);
            Ci = (photonmap(\"global\", P, Nf, \"estimator\", 200) - diffuse(Nf)) / PI;
            Oi = 1;
        }",
    );
    let from_lights = gathered(
        r#"Option "gi" "integer virtuallights" [20000] "integer interleave" [1]"#,
        "surface onebounce() {
            normal Nf = faceforward(normalize(N), I);
            Ci = indirectdiffuse(P, Nf, 1);
            Oi = 1;
        }",
    );
    let error = relative_error(from_photons, from_lights);
    eprintln!("indirect light: global photons {from_photons:?}, virtual lights {from_lights:?} ({error})");
    assert!(from_lights.iter().all(|&c| c > 0.0) && error < 0.08, "{from_photons:?} against {from_lights:?}");
}

/// The office of `examples/office/office_gi.rib` (the paper's GI figure, measured for speed in
/// `docs/global_illumination.md`): it loads whole, and its virtual lights add light to the walls
/// (against the same frame with every virtual light clamped to count from far away, which leaves
/// the direct light alone).
#[test]
fn the_office_in_gi_loads_whole_and_its_virtual_lights_light_the_walls() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/office/office_gi.rib");
    let mut rt = Context::new();
    let loaded = rtsl_runtime::rib::load::load_file(&mut rt, &path).expect("the office loads");
    assert_eq!(loaded.omissions(), 0, "{:?}", loaded.warnings);
    assert_eq!(rt.options.gi.virtual_lights, 256);
    (rt.options.width, rt.options.height) = (48, 36);
    let world = rt.build_world().expect("a world");
    let with_bounce = render_frame(&world, None).0;
    rt.return_scene(world);
    rt.options.gi.clamp = 1.0e6;
    let direct = render_frame(&rt.build_world().expect("a world"), None).0;
    // The back wall, above the desk (the top fifth of the picture's middle).
    let (cols, rows) = (12..36, 1..7);
    let (a, b) = (mean(&with_bounce, cols.clone(), rows.clone()), mean(&direct, cols, rows));
    assert!(a.iter().chain(&b).all(|c| c.is_finite() && *c > 0.0), "{a:?} {b:?}");
    let (a_sum, b_sum) = (a.iter().sum::<f32>(), b.iter().sum::<f32>());
    assert!(a_sum > 1.5 * b_sum, "with the bounce {a:?}, direct light alone {b:?}");
}

/// Caustic paths leave a light toward the instances with specular surfaces only
/// (`render/caustic_aim.rs`): under a small mirror (0.5 x 0.5, 1 above a point light: 0.235 of the
/// sphere's 4 pi steradians) most paths reach it and leave a photon, where paths over the whole
/// sphere would leave one in 53; and the photons carry the power the mirror reflects, its
/// reflectance times the light's intensity times the mirror's solid angle.
#[test]
fn caustic_paths_go_toward_specular_instances_and_carry_what_these_reflect() {
    use rtsl_runtime::api::Primitive;
    use rtsl_runtime::glam::Vec3A;
    use rtsl_runtime::render::progressive::LatticeTracer;
    use rtsl_runtime::render::world::PhotonModel;
    use rtsl_runtime::shading::ParamValue;
    let e = |e: rtsl_runtime::api::ApiError| e.to_string();
    let mut rt = Context::new();
    let paths = 100_000;
    rt.options.gi.caustic_photons = paths;
    let matte = rt.find_shader("matte").map_err(e).expect("matte");
    let quad = |rt: &mut Context, half: f32, y: f32, model: PhotonModel| {
        rt.photon_shading_model(model);
        let object = rt.begin_object().map_err(e).expect("an object");
        rt.bind_shader(matte).map_err(e).expect("bound");
        rt.begin(Primitive::Quads).map_err(e).expect("quads");
        for (x, z) in [(-half, -half), (half, -half), (half, half), (-half, half)] {
            rt.vertex(x, y, z).map_err(e).expect("a vertex");
        }
        rt.end().map_err(e).expect("end");
        rt.end_object().map_err(e).expect("end_object");
        rt.instantiate_object(object).map_err(e).expect("an instance");
    };
    rt.color(0.8, 0.8, 0.8);
    quad(&mut rt, 3.0, 0.0, PhotonModel::Matte);
    quad(&mut rt, 0.25, 3.0, PhotonModel::Chrome);
    let light = rt.find_shader("pointlight").map_err(e).expect("pointlight");
    rt.light_source(light, &[("intensity", ParamValue::Float(4.0)), ("from", ParamValue::Point([0.0, 2.0, 0.0]))])
        .map_err(e)
        .expect("a light");
    let world = rt.build_world().expect("a world");
    let tracer = LatticeTracer::new(&world, 0, false);
    tracer.prepare_light_paths();
    let map = tracer.light_paths().caustics.expect("a caustic map");
    // A square of half side a at distance h, centred: 4 asin(a^2 / (a^2 + h^2)) steradians.
    let (a, h) = (0.25f32, 1.0f32);
    let solid_angle = 4.0 * (a * a / (a * a + h * h)).asin();
    let everywhere = solid_angle / (4.0 * std::f32::consts::PI);
    let kept = map.len() as f32 / paths as f32;
    eprintln!("photons per path: {kept} (over the whole sphere: {everywhere})");
    assert!(kept > 0.5 && kept > 25.0 * everywhere, "{kept} photons a path");
    let photons = map.photons();
    // All on the floor, inside the light's mirror image's view of the mirror (4 below it: 4 x 0.25).
    assert!(photons.iter().all(|p| p.p.y.abs() < 1e-4 && p.p.x.abs() <= 1.0 + 1e-3 && p.p.z.abs() <= 1.0 + 1e-3));
    let power: f32 = photons.iter().map(|p| p.power.x).sum();
    let reflected = 0.8 * 4.0 * solid_angle;
    eprintln!("caustic power {power}, reflected {reflected}");
    assert!((power / reflected - 1.0).abs() < 0.01, "caustic power {power}, reflected {reflected}");
    assert!(photons.iter().all(|p| p.power == Vec3A::splat(p.power.x)), "grey light, grey mirror");
}

/// A spotlight's paths leave it where it shines (`render/emission.rs`): in the box under a
/// spotlight aimed at the floor (a cone of 0.3 radians: 0.28 of the sphere's 4 pi steradians),
/// nine paths in ten leave a virtual light, where paths over the whole sphere would leave one in
/// 45; and the indirect light they give agrees with sampling the hemisphere.
#[test]
fn a_spotlights_paths_go_into_its_cone() {
    use rtsl_runtime::render::progressive::LatticeTracer;
    let spot = r#"LightSource "spotlight" 1 "intensity" 3 "from" [0 0.8 0] "to" [0 -1 0] "coneangle" 0.3 "conedeltaangle" 0.05"#;
    let onebounce = box_scene_shader();
    let lit = |options: &str| {
        let (mut rt, warnings) = box_scene_lit(options, spot, &onebounce);
        assert!(warnings.is_empty(), "{warnings:?}");
        rt.build_world().expect("a world")
    };
    let paths = 2000;
    let world = lit(&format!(r#"Option "gi" "integer virtuallights" [{paths}] "integer interleave" [1]"#));
    let tracer = LatticeTracer::new(&world, 0, false);
    tracer.prepare_light_paths();
    let lights = tracer.light_paths().virtual_lights.expect("virtual lights");
    let left: usize = lights.sets.iter().map(Vec::len).sum();
    eprintln!("virtual lights: {left} of {paths} paths");
    assert!(left as f32 > 0.8 * paths as f32, "{left} virtual lights of {paths} paths");
    let (gathered, sampled) = (render_frame(&world, None).0, render_frame(&lit(""), None).0);
    let whole = (0..32, 0..24);
    let (a, b) = (mean(&gathered, whole.0.clone(), whole.1.clone()), mean(&sampled, whole.0, whole.1));
    let e = relative_error(a, b);
    eprintln!("image means: virtual lights {a:?}, hemisphere {b:?}, relative error {e}");
    assert!(b.iter().all(|&v| v > 0.002) && e < 0.05, "virtual lights {a:?}, hemisphere {b:?} ({e})");
}

/// A frame whose light paths run surface shaders that ask for the frame's own virtual lights and
/// caustic photons (`gimatte` under `transmissionhitmode "shader"`, lit by a shadowed light inside
/// the walls) renders, the same on one thread as on two: while the paths are traced, the shaders
/// on them find neither, instead of waiting for the tracing they are part of. Each frame renders
/// on a thread of its own, so that a wait shows as a failure after a deadline rather than as a
/// test run that never ends (the frame itself takes milliseconds).
#[test]
fn shaders_that_light_paths_run_do_not_wait_on_the_paths() {
    let rib = "Format 24 18 1 Projection \"perspective\" \"fov\" 50 Translate 0 -1 5
        Option \"gi\" \"integer virtuallights\" [32] \"integer causticphotons\" [500]
        WorldBegin
        Attribute \"light\" \"shadows\" \"on\"
        LightSource \"pointlight\" 1 \"intensity\" [20] \"from\" [0 2 0]
        Attribute \"shade\" \"transmissionhitmode\" \"shader\"
        Surface \"gimatte\"
        Polygon \"P\" [-3 0 -3  3 0 -3  3 0 3  -3 0 3]
        Polygon \"P\" [-3 0 3  3 0 3  3 3 3  -3 3 3]
        AttributeBegin Attribute \"photon\" \"shadingmodel\" \"glass\" Surface \"glass\" Translate 0 1 0
        Sphere 0.5 -0.5 0.5 360 AttributeEnd
        WorldEnd";
    let frame = |threads: usize| {
        let (done, finished) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
            let rgba = pool.install(|| {
                let mut rt = Context::new();
                let loaded = rtsl_runtime::rib::load::load_str(&mut rt, rib, Path::new("paths.rib")).expect("loads");
                assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
                let world = rt.build_world().expect("a world");
                render_frame(&world, None).0.rgba
            });
            let _ = done.send(rgba);
        });
        finished
            .recv_timeout(std::time::Duration::from_secs(120))
            .unwrap_or_else(|e| panic!("a frame on {threads} thread(s) did not finish: {e}"))
    };
    let one = frame(1);
    assert!(one.chunks_exact(4).any(|p| p[0] > 0.0), "the floor is lit");
    assert_eq!(one, frame(2));
}
