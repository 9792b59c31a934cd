//! The `rtsl` binary, run as a user would, in temporary directories.

use std::path::Path;
use std::process::{Command, Output};

fn rtsl(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rtsl")).args(args).current_dir(dir).output().expect("the binary runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(dir: &Path, name: &str, text: &str) {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("mkdir");
    }
    std::fs::write(path, text).expect("write");
}

const GOOD: &str = "surface good(float Kd = .8; color tint = color \"hsv\" (0, 1, 1); float knots[3] = {0, .5, 1}; output varying float mask = 0;)\n{\n    normal Nf = faceforward(normalize(N), I);\n    mask = spline(s, knots[0], knots[0], knots[1], knots[2], knots[2]);\n    Ci = Cs * tint * Kd * diffuse(Nf);\n    Oi = Os;\n}\n";
const BAD: &str = "surface bad()\n{\n    Ci = Cs * normalise(N);\n    Oi = undefined_thing;\n}\n";
const WARN: &str = "surface warn()\n{\n    float unused = 1;\n    Ci = Cs;\n    Oi = Os;\n}\n";

#[test]
fn compile_a_directory_reports_failures_and_a_summary() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "lib/good.sl", GOOD);
    write(dir.path(), "lib/sub/bad.sl", BAD);
    write(dir.path(), "lib/sub/warn.sl", WARN);
    write(dir.path(), "lib/readme.txt", "not a shader");
    let o = rtsl(&["compile", "lib"], dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "one line per failure plus the summary:\n{out}");
    assert!(lines[0].starts_with("FAILED lib/sub/bad.sl:3:15: error[E0101]: unknown function `normalise`"), "{out}");
    assert!(lines[0].ends_with("(and 1 more)"), "{out}");
    assert_eq!(lines[1], "3 shaders: 2 ok, 1 failed, 1 warning");
}

#[test]
fn werror_fails_on_warnings() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "warn.sl", WARN);
    assert_eq!(rtsl(&["compile", "warn.sl"], dir.path()).status.code(), Some(0));
    let o = rtsl(&["compile", "--werror", "warn.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    // A single file shows its diagnostics in full.
    assert!(stdout(&o).contains("warning[W0001]: unused variable `unused`"), "{}", stdout(&o));
    assert!(stdout(&o).contains("3 │     float unused = 1;"), "{}", stdout(&o));
}

#[test]
fn json_records_one_per_shader() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "a/good.sl", GOOD);
    write(dir.path(), "a/bad.sl", BAD);
    let o = rtsl(&["compile", "--json", "a"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    let records: Vec<serde_json::Value> =
        stdout(&o).lines().map(|l| serde_json::from_str(l).expect("each line is JSON")).collect();
    assert_eq!(records.len(), 2);
    let bad = &records[0];
    assert_eq!(bad["path"], "a/bad.sl");
    assert_eq!(bad["shader_type"], "surface");
    assert_eq!(bad["name"], "bad");
    assert_eq!(bad["ok"], false);
    let d = &bad["diagnostics"][0];
    assert_eq!(d["code"], "E0101");
    assert_eq!(d["span"]["line"], 3);
    assert_eq!(d["span"]["column"], 15);
    assert_eq!(records[1]["ok"], true);
}

#[test]
fn defines_and_include_paths_reach_the_preprocessor() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "inc/tint.h", "#define TINT color (1, 0, 0)\n");
    write(
        dir.path(),
        "s.sl",
        "#include <tint.h>\n#ifndef STRENGTH\n#error STRENGTH must be defined\n#endif\nsurface s(float k = STRENGTH;) { Ci = TINT * k; Oi = Os; }\n",
    );
    let o = rtsl(&["compile", "s.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(stdout(&o).contains("E0001"), "missing include reported: {}", stdout(&o));
    let o = rtsl(&["compile", "-I", "inc", "s.sl"], dir.path());
    assert!(stdout(&o).contains("#error STRENGTH must be defined"), "{}", stdout(&o));
    let o = rtsl(&["compile", "-I", "inc", "-D", "STRENGTH=2", "s.sl"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
}

#[test]
fn info_prints_the_interface() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "good.sl", GOOD);
    let o = rtsl(&["info", "good.sl"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert_eq!(
        out,
        "surface \"good\"\n    uniform float Kd = 0.8\n    uniform color tint = \"hsv\" [0 1 1]\n    uniform float knots[3] = {0, 0.5, 1}\n    output varying float mask = 0\n"
    );
    let o = rtsl(&["info", "--json", "good.sl"], dir.path());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("JSON");
    assert_eq!(v["type"], "surface");
    assert_eq!(v["parameters"][2]["array_length"], 3);
    assert_eq!(v["parameters"][3]["output"], true);
    assert_eq!(v["parameters"][3]["storage"], "varying");
}

#[test]
fn bad_input_gives_clear_errors_not_panics() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["compile", "missing.sl"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read `missing.sl`"), "{}", stderr(&o));
    let o = rtsl(&["compile", "-D", "1BAD", "x.sl"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("`1BAD` is not a valid macro name"), "{}", stderr(&o));
    write(dir.path(), "binary.sl", "\u{0}\u{1}\u{fffd}surface {{{{");
    let o = rtsl(&["compile", "binary.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(stdout(&o).contains("error["), "{}", stdout(&o));
    write(dir.path(), "bad.sl", BAD);
    let o = rtsl(&["info", "bad.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("error[E0101]"), "{}", stderr(&o));
    write(dir.path(), "lib.sl", "float twice(float x) { return 2 * x; }\n");
    let o = rtsl(&["info", "lib.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("defines no shader"), "{}", stderr(&o));
    // A missing BART scene: the file and the system's reason, each said once.
    let o = rtsl(&["bart", "missing.aff"], dir.path());
    assert_ne!(o.status.code(), Some(0));
    let err = stderr(&o);
    assert!(err.contains("cannot read missing.aff"), "{err}");
    assert_eq!(err.matches("missing.aff").count(), 1, "{err}");
    assert_eq!(err.matches("(os error").count(), 1, "{err}");
}

#[test]
fn render_with_no_scene_renders_the_default_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["render", "-o", "out.png", "--size", "64x48", "--samples", "1", "--threads", "2"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.starts_with("out.png: 64x48, 1 sample(s) per pixel, 2 thread(s)"), "{out}");
    assert!(out.contains("M rays") && out.contains("shading"), "statistics: {out}");
    let image = rtsl_runtime::read_image(dir.path().join("out.png")).expect("a PNG");
    assert_eq!((image.width, image.height), (64, 48));
    assert!(image.pixels.chunks(4).filter(|p| p[0] + p[1] + p[2] > 0.1).count() > 1000, "the scene is lit");
}

#[test]
fn render_writes_exr_and_reports_bad_scenes_with_their_location() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(
        dir.path(),
        "scene.rib",
        "Format 32 24 1\nTranslate 0 0 5\nWorldBegin\nLightSource \"distantlight\" 1\nSurface \"plastic\"\nSphere 1 -1 1 360\nWorldEnd\n",
    );
    let o = rtsl(&["render", "scene.rib", "-o", "out.exr", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).is_empty());
    let image = rtsl_runtime::read_image(dir.path().join("out.exr")).expect("an EXR");
    assert_eq!(image.pixels[4 * (12 * 32 + 16) + 3], 1.0, "the sphere covers the centre");

    // A request that cannot be read is skipped and the rest renders, as RenderMan does; the exit
    // status says that something is missing.
    write(dir.path(), "broken.rib", "WorldBegin\nSphere 1 ]\nWorldEnd\n");
    let o = rtsl(&["render", "broken.rib", "-o", "broken.png", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("broken.rib:2:"), "{}", stderr(&o));
    assert!(dir.path().join("broken.png").exists());

    let o = rtsl(&["render", "missing.rib"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.rib"), "{}", stderr(&o));

    let o = rtsl(&["render", "--size", "0x10"], dir.path());
    assert_eq!(o.status.code(), Some(2), "a clap usage error");
    assert!(stderr(&o).contains("at least 1x1"), "{}", stderr(&o));
}

#[test]
fn shade_runs_a_surface_shader_over_a_grid() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "st.sl", "surface st(float k = 1;) { Oi = 1; Ci = color(s, t, k); }\n");
    let o = rtsl(&["shade", "st.sl", "-g", "8", "4", "--param", "k=0.5", "-o", "st.exr", "--iters", "3"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("M points/s"), "{}", stdout(&o));
    let image = rtsl_runtime::read_image(dir.path().join("st.exr")).expect("an EXR");
    assert_eq!((image.width, image.height), (8, 4));
    // Point (3, 1): s = 3.5 / 8, t = 1.5 / 4.
    let p = &image.pixels[4 * (8 + 3)..4 * (8 + 4)];
    assert_eq!(p, &[3.5 / 8.0, 1.5 / 4.0, 0.5, 1.0]);
    let o = rtsl(&["shade", "st.sl", "--param", "nosuch=1"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no parameter `nosuch`"), "{}", stderr(&o));
}

#[test]
fn ray_parameters_reach_rayinfo_from_the_command_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let src =
        "surface rp() { float q = -1; color c = 0; rayinfo(\"q\", q); rayinfo(\"user:c\", c); Oi = 1; Ci = c + q; }\n";
    write(dir.path(), "rp.sl", src);
    // The shader test harness (the JIT, through the interpreter's host).
    let o = rtsl(
        &["shade", "rp.sl", "-g", "2", "2", "--ray-param", "q=0.25", "--ray-param", "c=0,0.5,0", "-o", "rp.exr"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let image = rtsl_runtime::read_image(dir.path().join("rp.exr")).expect("an EXR");
    assert_eq!(&image.pixels[..4], &[0.25, 0.75, 0.25, 1.0]);
    // A scene: the rays of a render carry them, and a gaze lowers the samples away from it.
    write(
        dir.path(),
        "scene.rib",
        "Format 32 24 1\nTranslate 0 0 5\nWorldBegin\nSurface \"rp\"\nPolygon \"P\" [-9 -9 0 9 -9 0 9 9 0 -9 9 0]\nWorldEnd\n",
    );
    let render = |extra: &[&str]| {
        let mut args = vec!["render", "scene.rib", "-S", ".", "-o", "out.exr", "--samples", "16", "--threads", "1"];
        args.extend_from_slice(extra);
        let o = rtsl(&args, dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        (stdout(&o), rtsl_runtime::read_image(dir.path().join("out.exr")).expect("an EXR"))
    };
    let (_, image) = render(&["--ray-param", "q=0.5", "--ray-param", "c=0.1,0.2,0.3"]);
    let p = &image.pixels[4 * (12 * 32 + 16)..4 * (12 * 32 + 16) + 3];
    assert!((p[0] - 0.6).abs() < 1e-5 && (p[2] - 0.8).abs() < 1e-5, "{p:?}");
    // `--gaze`: relevance 1 around the point, 0 beyond the falloff.
    write(dir.path(), "rel.rib", &std::fs::read_to_string(dir.path().join("scene.rib")).unwrap().replace("rp", "rel"));
    write(dir.path(), "rel.sl", "surface rel() { float r = -1; rayinfo(\"relevance\", r); Oi = 1; Ci = r; }\n");
    let o =
        rtsl(&["render", "rel.rib", "-S", ".", "-o", "rel.exr", "--gaze", "16,12,4,2", "--threads", "1"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let image = rtsl_runtime::read_image(dir.path().join("rel.exr")).expect("an EXR");
    assert_eq!(image.pixels[4 * (12 * 32 + 16)], 1.0);
    assert_eq!(image.pixels[0], 0.0);
    for bad in [&["--gaze", "1,2"][..], &["--ray-param", "q"], &["--refine-on", "depth"]] {
        let mut args = vec!["render", "scene.rib", "-S", "."];
        args.extend_from_slice(bad);
        assert_eq!(rtsl(&args, dir.path()).status.code(), Some(2), "{bad:?} is a usage error");
    }
}

#[test]
fn display_writes_arbitrary_output_variables() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(
        dir.path(),
        "aov.sl",
        "surface aov(output varying color base = 0;) { base = color(0.25, 0.5, 1); Oi = 1; Ci = 0.1; }\n",
    );
    write(
        dir.path(),
        "scene.rib",
        "Format 32 24 1\nDisplay \"beauty.exr\" \"file\" \"rgba\"\nDisplay \"+base.exr\" \"file\" \"varying color base\"\n\
         Display \"+missing.exr\" \"file\" \"nosuch\"\nTranslate 0 0 5\nWorldBegin\nSurface \"aov\"\n\
         Polygon \"P\" [-9 -9 0 9 -9 0 9 9 0 -9 9 0]\nWorldEnd\n",
    );
    let o = rtsl(&["render", "scene.rib", "-S", ".", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let beauty = rtsl_runtime::read_image(dir.path().join("beauty.exr")).expect("the beauty image");
    assert!((beauty.pixels[4 * (12 * 32 + 16)] - 0.1).abs() < 1e-6);
    let base = rtsl_runtime::read_image(dir.path().join("base.exr")).expect("the output variable's image");
    assert_eq!(&base.pixels[4 * (12 * 32 + 16)..4 * (12 * 32 + 16) + 3], &[0.25, 0.5, 1.0]);
    let missing = rtsl_runtime::read_image(dir.path().join("missing.exr")).expect("a variable no shader has");
    assert!(missing.pixels.chunks(4).all(|p| p[..3] == [0.0; 3]));
    // Displays naming one EXR file are layers of it: the beauty's channels, then `base.R`...
    let layered = std::fs::read_to_string(dir.path().join("scene.rib"))
        .expect("the scene")
        .replace("\"+base.exr\"", "\"+beauty.exr\"");
    write(dir.path(), "layers.rib", &layered);
    let o = rtsl(&["render", "layers.rib", "-S", ".", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let exr = rtsl_runtime::image_io::read_exr(&dir.path().join("beauty.exr")).expect("one EXR");
    let centre = 12 * 32 + 16;
    assert!((exr.channel("R").expect("the beauty")[centre] - 0.1).abs() < 1e-6);
    assert_eq!(exr.channel("base.G").expect("the base layer")[centre], 0.5);
    assert_eq!(exr.channels.len(), 7, "{:?}", exr.channels.iter().map(|c| &c.0).collect::<Vec<_>>());
    // A mode that is neither channels nor a variable name is skipped, a part missing.
    write(dir.path(), "bad.rib", "Display \"x.exr\" \"file\" \"float 3x\"\nWorldBegin\nWorldEnd\n");
    let o = rtsl(&["render", "bad.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("bad.rib:1:"), "{}", stderr(&o));
}

/// Pixel `(x, y)` of an image as RGBA.
fn pixel(image: &rtsl_runtime::RgbaImage, x: usize, y: usize) -> [f32; 4] {
    let k = 4 * (y * image.width + x);
    [image.pixels[k], image.pixels[k + 1], image.pixels[k + 2], image.pixels[k + 3]]
}

fn assert_close(got: [f32; 4], want: [f32; 4], what: &str) {
    assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-5), "{what}: got {got:?}, want {want:?}");
}

/// Runs `rtsl shade` in `dir` and reads back the images `-o` named.
fn shade(dir: &Path, args: &[&str], images: &[&str]) -> Vec<rtsl_runtime::RgbaImage> {
    let mut all = vec!["shade"];
    all.extend_from_slice(args);
    let o = rtsl(&all, dir);
    assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
    images.iter().map(|f| rtsl_runtime::read_image(dir.join(f)).expect("an image")).collect()
}

/// `-o VAR FILE` writes any global or output parameter; `-o FILE` the shader type's main result.
#[test]
fn shade_writes_globals_and_output_parameters() {
    let dir = tempfile::tempdir().expect("tempdir");
    let src = "surface o(output varying float mask = 0; output string label = \"\";)\n{ mask = s; Oi = 0.5; Ci = color(t, 0, 1); }\n";
    write(dir.path(), "o.sl", src);
    let images = shade(
        dir.path(),
        &[
            "o.sl",
            "-g",
            "4",
            "2",
            "-o",
            "Ci",
            "ci.exr",
            "-o",
            "mask",
            "mask.exr",
            "-o",
            "N",
            "n.exr",
            "-o",
            "plain.exr",
        ],
        &["ci.exr", "mask.exr", "n.exr", "plain.exr"],
    );
    // Point (1, 1): s = 1.5 / 4, t = 1.5 / 2; Ci's alpha is the mean of Oi.
    assert_close(pixel(&images[0], 1, 1), [0.75, 0.0, 1.0, 0.5], "Ci");
    assert_close(pixel(&images[1], 1, 1), [0.375, 0.375, 0.375, 1.0], "mask as grey");
    assert_close(pixel(&images[2], 1, 1), [0.0, 0.0, 1.0, 1.0], "N, untouched: its entry value");
    assert_eq!(images[3].pixels, images[0].pixels, "-o FILE is Ci for a surface");
    // Unknown names and outputs that are not images are usage errors naming what can be written.
    let o = rtsl(&["shade", "o.sl", "-o", "Cout", "x.exr"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("no global or output parameter `Cout`") && err.contains("P, N, Ci, Oi, mask, label"), "{err}");
    let o = rtsl(&["shade", "o.sl", "-o", "label", "x.exr"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("`label` is not a float or a triple"), "{}", stderr(&o));
    assert!(!dir.path().join("x.exr").exists(), "nothing is written after a usage error");
}

/// A displacement shader moves `P` and `N`; `-o FILE` is the displaced `P`.
#[test]
fn shade_runs_a_displacement_shader() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(
        dir.path(),
        "d.sl",
        "displacement d(float h = 0.5;) { P += h * s * N; N = normalize(calculatenormal(P)); }\n",
    );
    let images = shade(dir.path(), &["d.sl", "-g", "4", "2", "-o", "p.exr", "-o", "N", "n.exr"], &["p.exr", "n.exr"]);
    // Point (3, 0): s = 0.875, t = 0.25; P moved up by h s; the surface z = h s tilts N against +x.
    assert_close(pixel(&images[0], 3, 0), [0.875, 0.25, 0.4375, 1.0], "P");
    let len = (0.25f32 + 1.0).sqrt();
    assert_close(pixel(&images[1], 3, 0), [-0.5 / len, 0.0, 1.0 / len, 1.0], "N");
}

/// A light shader lights every grid point: `Ps` is the point, `Cl` and `L` what it leaves.
#[test]
fn shade_runs_a_light_shader_at_each_grid_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    let src = "light pl(float intensity = 1; point from = point \"shader\" (0, 0, 0);)\n{ illuminate(from) { Cl = intensity / (L . L); } }\n";
    write(dir.path(), "pl.sl", src);
    // The default `from`: the origin of the test host's "shader" space, (1, 2, 3).
    let images =
        shade(dir.path(), &["pl.sl", "-g", "4", "2", "-o", "cl.exr", "-o", "L", "l.exr"], &["cl.exr", "l.exr"]);
    // Point (1, 0): Ps = (0.375, 0.25, 0), so L = Ps - from = (-0.625, -1.75, -3).
    let cl = 1.0 / (0.625f32 * 0.625 + 1.75 * 1.75 + 9.0);
    assert_close(pixel(&images[0], 1, 0), [cl, cl, cl, 1.0], "Cl");
    assert_close(pixel(&images[1], 1, 0), [-0.625, -1.75, -3.0, 1.0], "L");
    // A light above the grid's centre: brightest under it.
    let images = shade(
        dir.path(),
        &["pl.sl", "-g", "4", "2", "--param", "from=0.5,0.5,1", "--param", "intensity=2", "-o", "cl.exr"],
        &["cl.exr"],
    );
    let cl = 2.0 / (0.125f32 * 0.125 + 0.25 * 0.25 + 1.0);
    assert_close(pixel(&images[0], 1, 0), [cl, cl, cl, 1.0], "Cl from (0.5, 0.5, 1)");
    assert_close(pixel(&images[0], 2, 1), [cl, cl, cl, 1.0], "the mirror image point");
}

/// A volume shader changes the colour arriving along the eye ray `I` to each grid point.
#[test]
fn shade_runs_a_volume_shader_along_the_eye_rays() {
    let dir = tempfile::tempdir().expect("tempdir");
    let src = "volume fog(float distance = 1; color background = color(0, 0, 1);)\n{ float d = 1 - exp(-length(I) / distance); Ci = mix(Ci, background, d); Oi = mix(Oi, color(1, 1, 1), d); }\n";
    write(dir.path(), "fog.sl", src);
    let images = shade(dir.path(), &["fog.sl", "-g", "4", "2", "--param", "distance=2", "-o", "ci.exr"], &["ci.exr"]);
    // Point (0, 1): the surface's colour (s, t, 0) = (0.125, 0.75, 0), seen from (0.5, 0.5, 1).
    let length = (0.375f32 * 0.375 + 0.25 * 0.25 + 1.0).sqrt();
    let d = 1.0 - (-length / 2.0).exp();
    assert_close(pixel(&images[0], 0, 1), [0.125 * (1.0 - d), 0.75 * (1.0 - d), d, 1.0], "fogged Ci");
}

/// An imager (pixel) shader runs over an image whose pixels are the grid's colours.
#[test]
fn shade_runs_an_imager_shader_over_a_grid_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "ex.sl", "imager ex(float gain = 2;) { Ci *= gain; alpha = xcomp(P) / 4 + zdepth; }\n");
    let images = shade(dir.path(), &["ex.sl", "-g", "4", "2", "-o", "ex.exr"], &["ex.exr"]);
    // Pixel (1, 0): Ci = (0.375, 0.25, 0) in; P = (1.5, 0.5, 0), zdepth 1; alpha is the alpha channel.
    assert_close(pixel(&images[0], 1, 0), [0.75, 0.5, 0.0, 1.375], "Ci and alpha");
}

/// `--input` gives an imager or a volume its incoming image, `--global` any global a value or an
/// image on entry; each image is read at the nearest pixel to each grid point's (s, t).
#[test]
fn shade_takes_an_incoming_image_and_globals_on_entry() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Two pixels: the left half of the grid reads the first, the right half the second.
    let pixels = [0.2, 0.4, 0.6, 0.25, 1.0, 0.0, 0.0, 0.5];
    rtsl_runtime::write_image(dir.path().join("in.exr"), 2, 1, &pixels, &rtsl_runtime::WriteOptions::default())
        .expect("writes");
    write(dir.path(), "half.sl", "imager half() { Ci *= 0.5; alpha *= 2; }\n");
    let images = shade(dir.path(), &["half.sl", "-g", "4", "2", "--input", "in.exr", "-o", "out.exr"], &["out.exr"]);
    assert_close(pixel(&images[0], 0, 0), [0.1, 0.2, 0.3, 0.5], "the left pixel, halved, its alpha doubled");
    assert_close(pixel(&images[0], 3, 1), [0.5, 0.0, 0.0, 1.0], "the right pixel");

    write(dir.path(), "thin.sl", "volume thin() { Ci *= Oi; }\n");
    let images = shade(dir.path(), &["thin.sl", "-g", "2", "1", "--input", "in.exr", "-o", "out.exr"], &["out.exr"]);
    assert_close(pixel(&images[0], 1, 0), [0.5, 0.0, 0.0, 0.5], "a volume's Oi is the alpha");

    write(dir.path(), "n.sl", "surface n() { Ci = color(N) + Cs; }\n");
    let args = ["n.sl", "-g", "2", "1", "--global", "N=0,1,0", "--global", "Cs=in.exr", "-o", "out.exr"];
    let images = shade(dir.path(), &args, &["out.exr"]);
    assert_close(pixel(&images[0], 0, 0), [0.2, 1.4, 0.6, 1.0], "N given, Cs from the image");

    for (args, says) in [
        (&["n.sl", "--global", "nosuch=1"][..], "no float or triple global `nosuch`"),
        (&["n.sl", "--global", "N=1,2"][..], "takes 3 numbers, 2 given"),
        (&["n.sl", "--input", "in.exr"][..], "not a surface shader"),
        (&["half.sl", "--input", "missing.exr"][..], "missing.exr"),
    ] {
        let mut all = vec!["shade"];
        all.extend_from_slice(args);
        let o = rtsl(&all, dir.path());
        assert_ne!(o.status.code(), Some(0), "{args:?}");
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
    }
}

/// A camera shader makes a ray per pixel: `-o FILE` is its direction `I`, `-o E` its origin.
#[test]
fn shade_runs_a_camera_shader_per_pixel() {
    let dir = tempfile::tempdir().expect("tempdir");
    let src = "camera c(float fov = 90;)\n{ float hw = tan(radians(fov) / 2); E = point \"camera\" (0, 0, 0); I = vector \"camera\" (s * hw, t * hw, 1); Ci = 1; }\n";
    write(dir.path(), "c.sl", src);
    let images = shade(dir.path(), &["c.sl", "-g", "4", "2", "-o", "i.exr", "-o", "E", "e.exr"], &["i.exr", "e.exr"]);
    // Pixel (1, 0) of 4x2: the shorter side spans [-1, 1], so s = -0.5 and t = 0.5 (up).
    assert_close(pixel(&images[0], 1, 0), [-0.5, 0.5, 1.0, 1.0], "I");
    // The test host's camera space is translated by (0, 0, 5).
    assert_close(pixel(&images[1], 1, 0), [0.0, 0.0, 5.0, 1.0], "E");
    // The library's pinhole takes the test host's field of view, 90 degrees: the same rays.
    let pinhole = Path::new(env!("CARGO_MANIFEST_DIR")).join("stdlib_shaders/camera/pinhole.sl");
    let pinhole = pinhole.to_str().expect("a UTF-8 path");
    let library = shade(dir.path(), &[pinhole, "-g", "4", "2", "-o", "pinhole.exr"], &["pinhole.exr"]);
    assert_eq!(library[0].pixels, images[0].pixels);
}

/// A grid is refused past the renderer's image limits, before its points are allocated.
#[test]
fn shade_refuses_a_grid_past_the_image_limits() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "st.sl", "surface st() { Oi = 1; Ci = color(s, t, 0); }\n");
    for (grid, says) in [
        (["100000", "100000"], "at most 32768 pixels a side"),
        (["8192", "8192"], "at most 33554432"),
        (["18446744073709551615", "2"], "at most 32768 pixels a side"),
    ] {
        let o = rtsl(&["shade", "st.sl", "-g", grid[0], grid[1]], dir.path());
        assert_eq!(o.status.code(), Some(2), "{grid:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(&format!("-g {} {}", grid[0], grid[1])), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{grid:?}: {}", stderr(&o));
    }
}

/// Several files and directories: each interface under its file's name; a broken file reports its
/// diagnostics, the others still print, and the status is 1.
#[test]
fn info_prints_every_shader_of_files_and_directories() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "lib/good.sl", GOOD);
    write(dir.path(), "lib/light/pl.sl", "light pl(float intensity = 1;) { Cl = intensity; }\n");
    write(dir.path(), "lib/readme.txt", "not a shader");
    write(dir.path(), "bad.sl", BAD);
    write(dir.path(), "warn.sl", WARN);
    // A link back up the tree is not followed.
    #[cfg(unix)]
    std::os::unix::fs::symlink(dir.path().join("lib"), dir.path().join("lib/light/loop")).expect("a symlink");
    let o = rtsl(&["info", "lib", "bad.sl", "warn.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1), "bad.sl failed");
    assert!(stderr(&o).contains("error[E0101]") && stderr(&o).contains("bad.sl:3:"), "{}", stderr(&o));
    assert_eq!(
        stdout(&o),
        "lib/good.sl:\nsurface \"good\"\n    uniform float Kd = 0.8\n    uniform color tint = \"hsv\" [0 1 1]\n    uniform float knots[3] = {0, 0.5, 1}\n    output varying float mask = 0\n\nlib/light/pl.sl:\nlight \"pl\"\n    uniform float intensity = 1\n\nwarn.sl:\nsurface \"warn\"\n"
    );
    // Two files, one broken, as JSON: one record per line.
    let o = rtsl(&["info", "--json", "bad.sl", "lib/good.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    let records: Vec<serde_json::Value> =
        stdout(&o).lines().map(|l| serde_json::from_str(l).expect("each line is JSON")).collect();
    assert_eq!(records.len(), 2);
    assert_eq!((&records[0]["path"], &records[0]["ok"]), (&"bad.sl".into(), &false.into()));
    assert_eq!(records[0]["diagnostics"][0]["code"], "E0101");
    assert_eq!((&records[1]["path"], &records[1]["ok"]), (&"lib/good.sl".into(), &true.into()));
    assert_eq!(records[1]["name"], "good");
    assert_eq!(records[1]["parameters"][0]["name"], "Kd");
    write(dir.path(), "lib.sl", "float twice(float x) { return 2 * x; }\n");
    let o = rtsl(&["info", "--json", "lib.sl"], dir.path());
    assert_eq!(o.status.code(), Some(1));
    let record: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("JSON");
    assert!(record["error"].as_str().is_some_and(|e| e.contains("defines no shader")), "{record}");
    // Every file good: status 0; a directory alone gets headers too.
    let o = rtsl(&["info", "lib/light"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stdout(&o), "lib/light/pl.sl:\nlight \"pl\"\n    uniform float intensity = 1\n");
}

#[test]
fn info_finds_shaders_by_name_on_the_search_path() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "mine/plastic.sl", "surface plastic(float mine = 1;) { Ci = Cs * mine; Oi = Os; }\n");
    // The library's plastic, then ours first on the search path.
    let o = rtsl(&["info", "plastic", "--which"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stdout(&o).trim_end(), "surface/plastic.sl (built in)");
    let o = rtsl(&["info", "plastic", "--which", "-S", "mine"], dir.path());
    assert_eq!(stdout(&o).trim_end(), "mine/plastic.sl");
    let o = rtsl(&["info", "plastic", "-S", "mine"], dir.path());
    assert!(stdout(&o).contains("uniform float mine = 1"), "{}", stdout(&o));
    let o = rtsl(&["info", "no_such_shader"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no shader named `no_such_shader`"), "{}", stderr(&o));
}

#[test]
fn compile_writes_a_library_of_artifacts_that_info_and_the_search_path_use() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "src/inc/tint.h", "#define TINT 0.25\n");
    write(dir.path(), "src/tinted.sl", "#include \"tint.h\"\nsurface tinted(float k = TINT;) { Ci = k; Oi = 1; }\n");
    write(dir.path(), "src/zz/tinted.sl", "surface tinted(float j = 1;) { Ci = j; }\n");
    write(dir.path(), "src/broken.sl", "surface broken() { Ci = nosuch; }\n");
    let o = rtsl(&["compile", "src", "-I", "src/inc", "-o", "lib", "--threads", "2"], dir.path());
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(1), "a shader failed: {out}");
    assert!(out.contains("3 shaders: 2 ok, 1 failed") && out.contains("on 2 threads)"), "{out}");
    assert!(out.contains("defines shader `tinted` again"), "{out}");
    assert!(out.contains("wrote 1 artifact and index.json"), "{out}");

    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("lib/index.json")).expect("index"))
            .expect("json");
    let shaders = index["shaders"].as_array().expect("shaders");
    assert_eq!(shaders.len(), 1);
    let tinted = &shaders[0];
    assert_eq!(tinted["name"], "tinted");
    assert_eq!(tinted["type"], "surface");
    assert_eq!(tinted["artifact"], "tinted.rtso");
    assert_eq!(tinted["parameters"][0]["name"], "k");
    let files = tinted["files"].as_array().expect("files");
    assert_eq!(files.len(), 2, "the source and its include: {files:?}");
    assert!(files[1]["path"].as_str().expect("path").ends_with("tint.h"));
    assert_eq!(files[1]["blake3"].as_str().expect("hash").len(), 64);
    assert_eq!(index["format_version"], 1);

    // `info` reads the artifact, and finds it by name on the search path before any source.
    let o = rtsl(&["info", "lib/tinted.rtso"], dir.path());
    assert!(stdout(&o).contains("uniform float k = 0.25"), "{}{}", stdout(&o), stderr(&o));
    let o = rtsl(&["info", "tinted", "--which", "-S", "lib"], dir.path());
    assert_eq!(stdout(&o).trim_end(), "lib/tinted.rtso");

    // An edited include makes the artifact stale: info says so and shows the source as it is now.
    write(dir.path(), "src/inc/tint.h", "#define TINT 0.75\n");
    let o = rtsl(&["info", "lib/tinted.rtso"], dir.path());
    assert!(stdout(&o).contains("uniform float k = 0.75"), "{}", stdout(&o));
    assert!(stderr(&o).contains("tint.h changed since"), "{}", stderr(&o));

    // A damaged artifact is a clear error.
    let artifact = dir.path().join("lib/tinted.rtso");
    let bytes = std::fs::read(&artifact).expect("read");
    std::fs::write(&artifact, &bytes[..bytes.len() / 2]).expect("write");
    let o = rtsl(&["info", "lib/tinted.rtso"], dir.path());
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("is truncated"), "{}", stderr(&o));
}

#[test]
fn render_watch_prints_one_line_per_reload_and_diagnostics_for_broken_edits() {
    use std::io::{BufRead, BufReader};
    use std::time::Duration;
    let dir = tempfile::tempdir().expect("tempdir");
    let flat = |c: &str| format!("surface flat(float k = 1;) {{ Oi = 1; Ci = k * {c}; }}\n");
    write(dir.path(), "shaders/flat.sl", &flat("color(1, 0, 0)"));
    write(
        dir.path(),
        "shaders/tex.sl",
        "surface tex(string name = \"\";) { Oi = 1; Ci = color texture(name, 0.5, 0.5); }\n",
    );
    let scene = |surface: &str| {
        format!(
            "Format 32 24 1\nProjection \"perspective\" \"fov\" [60]\nTranslate 0 0 3\nWorldBegin\n  Surface {surface}\n  \
             Polygon \"P\" [-5 -5 0  5 -5 0  5 5 0  -5 5 0]\nWorldEnd\n"
        )
    };
    write(dir.path(), "scene.rib", &scene("\"flat\" \"k\" [0.5]"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_rtsl"))
        .args(["render", "scene.rib", "-o", "out.exr", "-S", "shaders", "--watch"])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let lines = |pipe: Box<dyn std::io::Read + Send>| {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        rx
    };
    let out = lines(Box::new(child.stdout.take().expect("stdout")));
    let err = lines(Box::new(child.stderr.take().expect("stderr")));
    let next = |rx: &std::sync::mpsc::Receiver<String>, what: &str| {
        rx.recv_timeout(Duration::from_secs(30)).unwrap_or_else(|_| panic!("no {what} within 30 s"))
    };
    // Saves by rename, as many editors do: one event per save.
    let save_as = |name: &str, text: &str| {
        write(dir.path(), "save.tmp", text);
        std::fs::rename(dir.path().join("save.tmp"), dir.path().join(name)).expect("rename");
    };
    let save = |text: &str| save_as("shaders/flat.sl", text);
    let first_pixel = || rtsl_runtime::read_image(dir.path().join("out.exr")).expect("the image").pixels[..4].to_vec();
    while !next(&out, "start-up output").starts_with("watching 1 shader file") {}

    save(&flat("color(0, 1, 0)"));
    let line = next(&out, "reload line");
    assert!(
        line.starts_with("reloaded flat: compile ") && line.contains(" ms, frame ") && line.ends_with("ms -> out.exr"),
        "{line}"
    );
    let image = rtsl_runtime::read_image(dir.path().join("out.exr")).expect("the image");
    assert_eq!(&image.pixels[..4], &[0.0, 0.5, 0.0, 1.0], "the rewritten image uses the new code");

    save(&flat("nope"));
    let mut line = next(&err, "diagnostics");
    // (A build for plain x86-64 on a processor with AVX2 says so first: `rtsl_runtime::cpu`.)
    if line.starts_with("warning: rtsl-runtime was compiled without AVX2") {
        line = next(&err, "diagnostics");
    }
    assert!(line.starts_with("flat (") && line.ends_with("did not compile; the last good version stays:"), "{line}");
    let mut diagnostics = String::new();
    while !diagnostics.contains("undefined variable `nope`") {
        diagnostics += &next(&err, "the diagnostics");
    }
    save(&flat("color(0, 0, 1)"));
    let line = next(&out, "reload line");
    assert!(line.starts_with("reloaded flat: compile "), "{line}");
    // Exactly one line per reload: nothing more came for the broken save or after.
    assert!(out.recv_timeout(Duration::from_millis(300)).is_err(), "one line per reload");

    // The scene file is watched too: an edit loads it again, a broken one keeps the last good scene.
    save_as("scene.rib", &scene("\"flat\" \"k\" [0.25]"));
    let line = next(&out, "scene reload line");
    assert!(line.starts_with("reloaded scene (") && line.contains("scene.rib), frame "), "{line}");
    assert_eq!(first_pixel(), [0.0, 0.0, 0.25, 1.0], "the new scene is rendered");
    save_as("scene.rib", "WorldBegin\nSphere 1 ]\nWorldEnd\n");
    while !next(&err, "the scene's error").contains("the last good scene stays") {}
    assert!(out.recv_timeout(Duration::from_millis(300)).is_err(), "a broken scene renders nothing");

    // And so are the textures a frame read.
    let texel = |v: f32| {
        let path = dir.path().join("t.tmp.exr");
        rtsl_runtime::write_image(&path, 2, 2, &[v, v, v, 1.0].repeat(4), &Default::default()).expect("written");
        std::fs::rename(&path, dir.path().join("t.exr")).expect("rename");
    };
    texel(0.125);
    save_as("scene.rib", &scene("\"tex\" \"string name\" \"t.exr\""));
    let line = next(&out, "scene reload line");
    assert!(line.starts_with("reloaded scene ("), "{line}");
    assert_eq!(first_pixel(), [0.125, 0.125, 0.125, 1.0]);
    texel(0.75);
    let line = next(&out, "texture reload line");
    assert!(line.starts_with("reloaded 1 texture(s), frame "), "{line}");
    assert_eq!(first_pixel(), [0.75, 0.75, 0.75, 1.0], "the texture is read again");
    child.kill().expect("stop the watcher");
    let _ = child.wait();
}

#[test]
fn bart_plays_a_scene_at_its_timing_and_writes_the_frames() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(
        dir.path(),
        "scene.aff",
        "v\nfrom 0 2 6\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.01\nresolution 32 24\nl 0 5 5\n\
         fm 0.2 0.2 0.2 0.7 0.7 0.7 0 0 0 1 0 0\nx spin\n{\ns 0 0 0 1\n}\na 0 1 10\n\
         k spin\n{\ntransl 2\n0 -1 0 0 0 0 0\n1 1 0 0 0 0 0\n}\n",
    );
    let o = rtsl(&["bart", "scene.aff", "--frames", "3", "-o", "frames", "--threads", "1"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("1 moving instances of 1 animated nodes"), "{out}");
    let frames: Vec<&str> = out.lines().filter(|l| l.starts_with("frame ")).collect();
    assert_eq!(frames.len(), 3, "{out}");
    assert!(frames[1].contains("scene frame    3, t =    0.300 s") && frames[1].contains("M rays/s"), "{out}");
    // 32x24 camera rays a frame, each lit point one shadow ray toward the one light.
    let rays = out.lines().find(|l| l.starts_with("rays per frame: ")).unwrap_or_default();
    assert!(rays.contains("(768 primary, ") && !rays.contains(" 0 shadow"), "{out}");
    let summary = out.lines().last().unwrap_or_default();
    assert!(
        summary.starts_with("3 frames:") && summary.contains(", median ") && summary.contains("% of a frame"),
        "{out}"
    );
    for k in 0..3 {
        let image = rtsl_runtime::read_image(dir.path().join(format!("frames/frame_{k:04}.png"))).expect("a frame");
        assert_eq!((image.width, image.height), (32, 24));
    }

    write(dir.path(), "broken.aff", "p 3\n0 0 0\n1 0 x\n");
    let o = rtsl(&["bart", "broken.aff"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("broken.aff:3:5:"), "{}", stderr(&o));
}

#[test]
fn volume_generate_reproduces_the_shipped_data_sets() {
    let dir = tempfile::tempdir().unwrap();
    for (kind, file) in [("neghip-like", "neghip32.grid"), ("cloud", "cloud32.grid")] {
        let out = rtsl(&["volume", "generate", "--kind", kind, "--size", "32", "-o", file], dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        let made = std::fs::read(dir.path().join(file)).unwrap();
        let shipped =
            std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/office/data").join(file)).unwrap();
        assert!(made == shipped, "{file} differs from what `rtsl volume generate --kind {kind}` writes");
    }
    let bad = rtsl(&["volume", "generate", "--size", "1", "-o", "x.grid"], dir.path());
    assert!(!bad.status.success());
}

/// `rtsl bench render --compare-trace-ahead` times a scene with reflections both ways and prints
/// the ratio.
#[test]
fn bench_render_compares_tracing_ahead_with_chunk_by_chunk() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = r#"Format 32 24 1
Projection "perspective" "fov" [40]
Translate 0 -0.5 4
WorldBegin
  LightSource "pointlight" 1 "intensity" [20] "from" [1 3 -1]
  Surface "mirror"
  Polygon "P" [-3 0 -3  3 0 -3  3 0 3  -3 0 3]
  Surface "plastic"
  Translate 0 0.6 0
  Sphere 0.5 -0.5 0.5 360
WorldEnd
"#;
    std::fs::write(dir.path().join("mirror.rib"), scene).expect("scene written");
    let args = ["bench", "render", "mirror.rib", "--frames", "3", "--threads", "1", "--compare-trace-ahead"];
    let o = rtsl(&args, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let value = |name: &str| -> f64 {
        let line = out.lines().find(|l| l.starts_with(name)).unwrap_or_else(|| panic!("no {name} in {out}"));
        line.split(' ').nth(1).and_then(|v| v.parse().ok()).expect("a number")
    };
    assert!(value("chunk_by_chunk_trace_frame_ms: ") > 0.0, "{out}");
    // The median of the timed frames lies within their spread.
    let spread = out.lines().find(|l| l.starts_with("frame_ms_spread: ")).expect("spread line");
    let words: Vec<&str> = spread.split(' ').collect();
    let (fastest, slowest): (f64, f64) = (words[1].parse().expect("fastest"), words[3].parse().expect("slowest"));
    let median = value("frame_ms: ");
    assert!(fastest <= median && median <= slowest && spread.ends_with("over 3 frames"), "{spread} {median}");
    let ratio = value("trace_ahead_over_chunk_by_chunk: ");
    assert!(ratio.is_finite() && ratio > 0.0, "{out}");
    // Which packet kernels traced the frames.
    assert!(out.lines().any(|l| l == "packet_kernels: avx512" || l == "packet_kernels: avx2"), "{out}");
    // The floor reflects: the frame traced secondary rays.
    let rays = out.lines().find(|l| l.starts_with("rays_per_frame: ")).expect("rays line");
    assert!(!rays.contains("secondary 0,"), "{rays}");
    // The points shaded and the light batches that lit them: both shaders here ask for lights,
    // and a light batch lights at most a packet's lanes.
    let batches = out.lines().find(|l| l.starts_with("shaded_points: ")).expect("batches line");
    let words: Vec<&str> = batches.split([' ', ',', '(']).filter(|w| !w.is_empty()).collect();
    let (points, lights): (u64, u64) = (words[1].parse().expect("points"), words[3].parse().expect("batches"));
    assert!(points > 0 && lights > 0 && points <= 64 * lights, "{batches}");
    // The last frame's tiles (32x24 pixels: two rows of two), and how busy their hand-out keeps
    // threads.
    let tiles = out.lines().find(|l| l.starts_with("tiles: ")).expect("tiles line");
    assert!(tiles.starts_with("tiles: 4, longest ") && tiles.contains("% over 16"), "{tiles}");
}

#[test]
fn bench_instances_and_camera_report_their_numbers() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["bench", "instances", "--counts", "10,200", "--repeats", "3"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for n in [10, 200] {
        let line =
            out.lines().find(|l| l.starts_with(&format!("instances_{n}_top_level_ms: "))).expect("a line per count");
        let ms: f64 = line.rsplit(' ').next().and_then(|v| v.parse().ok()).expect("a number");
        assert!(ms.is_finite() && ms >= 0.0, "{line}");
    }
    let o = rtsl(&["bench", "camera", "--size", "32x24", "--frames", "1", "--cameras", "fisheye"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("builtin_mrays: ") && out.contains("fisheye_mrays: "), "{out}");
    // The fisheye makes no rays outside its image circle: fewer rays than the built-in camera.
    let rays = |name: &str| -> u64 {
        let line = out.lines().find(|l| l.starts_with(name)).expect("line");
        line.split('(').nth(1).and_then(|r| r.split(' ').next()).and_then(|v| v.parse().ok()).expect("rays")
    };
    assert_eq!(rays("builtin_mrays"), 32 * 24);
    assert!(rays("fisheye_mrays") < 32 * 24);
    // Making the rays alone: only the making lines, each with a time and a ratio.
    let o = rtsl(
        &["bench", "camera", "--size", "32x24", "--frames", "1", "--cameras", "thinlens", "--make-only"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(!out.contains("_mrays: "), "{out}");
    for name in ["builtin", "thinlens"] {
        let line = out.lines().find(|l| l.starts_with(&format!("{name}_make_ns_per_pixel: "))).expect("a line");
        let ns: f64 = line.split(' ').nth(1).and_then(|v| v.parse().ok()).expect("a number");
        assert!(ns.is_finite() && ns > 0.0, "{line}");
    }
}

#[test]
fn bench_aa_reports_rays_and_error_per_mode() {
    let dir = tempfile::tempdir().expect("tempdir");
    let args = ["bench", "aa", "--size", "32x24", "--reference", "16", "--samples", "4", "--thresholds", "0.1,0"];
    let o = rtsl(&args, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let field = |mode: &str, name: &str| -> f64 {
        let line = out.lines().find(|l| l.starts_with(&format!("{mode}: "))).unwrap_or_else(|| panic!("{mode}: {out}"));
        let at = line.find(name).unwrap_or_else(|| panic!("{name} in {line}")) + name.len() + 1;
        line[at..].split([' ', ',']).next().and_then(|v| v.parse().ok()).unwrap_or_else(|| panic!("{line}"))
    };
    for mode in ["regular", "jittered", "interleaved"] {
        assert_eq!(field(mode, "primary_rays_per_pixel"), 4.0, "{out}");
    }
    assert_eq!(field("one_sample", "primary_rays_per_pixel"), 1.0);
    // Threshold 0 refines every pixel that differs at all from a neighbour: more rays than 0.1.
    let (loose, strict) =
        (field("adaptive:0.1", "primary_rays_per_pixel"), field("adaptive:0", "primary_rays_per_pixel"));
    assert!((1.0..=5.0).contains(&loose) && loose < strict && strict <= 5.0, "{out}");
    // Bad flags and scenes are clear errors.
    for (bad, says) in [
        (&["--size", "0x0"][..], "at least 1x1"),
        (&["--reference", "0"], "--reference"),
        (&["--thresholds", "abc"], "--thresholds"),
        (&["no_such_scene.rib"], "no_such_scene.rib"),
    ] {
        let o = rtsl(&[&["bench", "aa"][..], bad].concat(), dir.path());
        assert!(!o.status.success() && stderr(&o).contains(says), "{bad:?}: {}", stderr(&o));
    }
    // Four samples a pixel are closer to the reference than one.
    for mode in ["regular", "jittered", "interleaved"] {
        let (e, one) = (field(mode, "rmse"), field("one_sample", "rmse"));
        assert!(e.is_finite() && e < one, "{mode}: {e} against one sample's {one}\n{out}");
    }
}

#[test]
fn bad_camera_and_lightfield_flags_are_clear_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["render", "--camera", "nosuchcamera", "-o", "x.png", "--size", "8x8"], dir.path());
    assert!(!o.status.success());
    assert!(stderr(&o).contains("nosuchcamera"), "{}", stderr(&o));
    let o = rtsl(&["render", "--camera", "plastic", "-o", "x.png", "--size", "8x8"], dir.path());
    assert!(!o.status.success());
    assert!(stderr(&o).contains("camera"), "a surface shader is not a camera: {}", stderr(&o));
    for args in [&["--views", "1"][..], &["--view-size", "0"], &["--distance=-2"], &["--half-size", "0"]] {
        let mut all = vec!["lightfield", "capture", "-o", "lf.png"];
        all.extend_from_slice(args);
        let o = rtsl(&all, dir.path());
        assert!(!o.status.success(), "{args:?} is refused");
        let flag = args[0].split('=').next().unwrap_or(args[0]);
        assert!(stderr(&o).contains(flag), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    assert!(!dir.path().join("lf.png").exists());
    // Each in range, but an atlas past the image limits: refused before the scene is read.
    for (views, size, says) in [("64", "1024", "at most 32768 pixels a side"), ("64", "128", "at most 33554432")] {
        let o = rtsl(
            &["lightfield", "capture", "missing.rib", "-o", "lf.png", "--views", views, "--view-size", size],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(&format!("--views {views} --view-size {size}")), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
        assert!(!stderr(&o).contains("missing.rib"), "{}", stderr(&o));
    }
}

/// The settings of `--mpi` runs are checked as flags, whether or not the run is distributed: a
/// value out of their kind is refused naming the flag (and, for `--deflate`, what it takes), with
/// no image written and no panic.
#[test]
fn bad_worker_flags_are_clear_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (command, flag, value) in [
        (&["render", "-o", "x.png", "--size", "8x8"][..], "--deflate", "sometimes"),
        (&["bench", "render", "--frames", "1", "--size", "8x8"], "--parts-above", "-3"),
        (&["render", "-o", "x.png", "--size", "8x8"], "--mesh-cache-mb", "lots"),
        (&["bench", "render", "--frames", "1", "--size", "8x8"], "--tile-textures-from-mb", "1.5"),
    ] {
        let mut args = command.to_vec();
        let given = format!("{flag}={value}");
        args.push(&given);
        let o = rtsl(&args, dir.path());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(flag) && stderr(&o).contains(value), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    }
    let o = rtsl(&["render", "-o", "x.png", "--deflate", "sometimes"], dir.path());
    assert!(
        stderr(&o).contains("auto") && stderr(&o).contains("always") && stderr(&o).contains("never"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("x.png").exists());
    // Values past any machine's memory are valid settings (a cache or a threshold nothing
    // reaches, saturated into bytes where they are used): a frame without --mpi renders.
    let huge = usize::MAX.to_string();
    let args = ["render", "-o", "x.png", "--size", "8x8", "--mesh-cache-mb", &huge, "--tile-textures-from-mb", &huge];
    let o = rtsl(&args, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A small RIB scene: a plastic sphere in front of the camera.
const SPHERE_RIB: &str =
    "Format 32 32 1\nTranslate 0 0 5\nWorldBegin\nLightSource \"distantlight\" 1\nSurface \"plastic\"\nSphere 1 -1 1 360\nWorldEnd\n";

#[test]
fn thread_counts_beyond_the_cap_are_refused_and_the_cap_renders() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "s.rib", SPHERE_RIB);
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--threads", "10000", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--threads 10000 is too many: at most 256"), "{}", stderr(&o));
    assert!(!dir.path().join("out.png").exists());
    let start = std::time::Instant::now();
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--threads", "256", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(start.elapsed() < std::time::Duration::from_secs(60), "256 threads took {:?}", start.elapsed());
}

#[test]
fn image_sizes_beyond_the_limits_are_clear_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["render", "--size", "100000x100000", "-o", "out.png"], dir.path());
    assert_eq!(o.status.code(), Some(2), "a usage error");
    assert!(stderr(&o).contains("at most 32768 pixels a side"), "{}", stderr(&o));
    write(dir.path(), "big.rib", &SPHERE_RIB.replace("Format 32 32 1", "Format 100000 100000 1"));
    let o = rtsl(&["render", "big.rib", "-o", "out.png"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("image size 100000x100000 is too large"), "{}", stderr(&o));
    // `--size` replaces the file's size, so the frame renders.
    let o = rtsl(&["render", "big.rib", "-o", "out.png", "--size", "16x16", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// `--samples` takes what RIB's `PixelSamples` does, at most 64 a side, in every command that has
/// it; refused when the command line is read, before the scene is.
#[test]
fn sample_counts_beyond_the_cap_are_refused_in_every_command() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "s.rib", SPHERE_RIB);
    let refused: [&[&str]; 6] = [
        &["render", "s.rib", "-o", "out.png", "--samples", "4225"],
        &["render", "s.rib", "-o", "out.png", "--samples", "65"],
        &["render", "s.rib", "-o", "out.png", "--samples", "4294967295"],
        &["bart", "missing.aff", "--samples", "100000"],
        &["bench", "render", "s.rib", "--samples", "5000"],
        &["lightfield", "capture", "s.rib", "-o", "lf.png", "--samples", "65"],
    ];
    for args in refused {
        let o = rtsl(args, dir.path());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("64"), "{args:?}: {}", stderr(&o));
        assert!(!dir.path().join("out.png").exists() && !dir.path().join("lf.png").exists());
    }
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--samples", "4225"], dir.path());
    assert!(stderr(&o).contains("a square number up to 4096 (64x64)"), "{}", stderr(&o));
    // The largest grid renders.
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--size", "2x2", "--samples", "4096", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn a_full_disk_is_an_error_for_every_image_format() {
    let dev_full = Path::new("/dev/full");
    if !dev_full.exists() {
        eprintln!("skipped: there is no /dev/full on this system");
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "s.rib", SPHERE_RIB);
    for ext in ["png", "tga", "ppm", "exr"] {
        let name = format!("full.{ext}");
        std::os::unix::fs::symlink(dev_full, dir.path().join(&name)).expect("a symlink");
        let o = rtsl(&["render", "s.rib", "-o", &name, "--quiet"], dir.path());
        assert_ne!(o.status.code(), Some(0), "{ext}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(&name) && err.contains("No space left on device"), "{ext}: {err}");
        assert_eq!(err.matches("No space left").count(), 1, "{ext}: said once: {err}");
        let link = std::fs::symlink_metadata(dir.path().join(&name)).expect("the link");
        assert!(link.file_type().is_symlink(), "{ext}: the link is left as it was");
    }
    // An ordinary file is replaced whole, and no temporary is left beside it.
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.ends_with(".tmp")), "{names:?}");
}

#[test]
fn messages_say_each_thing_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "s.rib", SPHERE_RIB);
    // An output path that is a directory: the system's reason, once.
    std::fs::create_dir(dir.path().join("out.png")).expect("mkdir");
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--quiet"], dir.path());
    assert_ne!(o.status.code(), Some(0));
    assert_eq!(stderr(&o).matches("Is a directory").count(), 1, "{}", stderr(&o));

    // A RIB syntax error: the location once, the reason once.
    write(dir.path(), "case.rib", "WorldBegin\nSphere 1 ]\nWorldEnd\n");
    let o = rtsl(&["render", "case.rib", "-o", "case.png", "--keep-going", "--color", "never"], dir.path());
    let err = stderr(&o);
    assert!(err.starts_with("error: `]` without a matching `[`"), "{err}");
    assert_eq!(err.matches("case.rib:2:10").count(), 1, "{err}");
    assert_eq!(err.matches("without a matching").count(), 1, "{err}");

    // A malformed OBJ: file and line, the reason once.
    write(dir.path(), "bad.obj", "v 0 0 0\nv 1 0\nf 1 2 3\n");
    let o = rtsl(&["render", "bad.obj", "-o", "bad.png"], dir.path());
    let err = stderr(&o);
    assert!(err.contains("bad.obj:2: `v` needs three numbers"), "{err}");
    assert_eq!(err.matches("needs three numbers").count(), 1, "{err}");

    // A texture that is not there, from a RIB named without a folder: no empty search list.
    write(
        dir.path(),
        "tex.rib",
        &SPHERE_RIB.replace("Surface \"plastic\"", "Surface \"texmap\" \"string texturename\" \"nope.png\""),
    );
    let o = rtsl(&["render", "tex.rib", "-o", "tex.png", "--keep-going"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("nope.png") && err.contains("file not found"), "{err}");
    assert!(!err.contains("searched  and"), "{err}");
}

#[test]
fn an_unsupported_output_format_is_refused_before_rendering() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(
        dir.path(),
        "s.rib",
        &SPHERE_RIB.replace("Format 32 32 1", "Format 32 32 1\nDisplay \"out.bmp\" \"file\" \"rgba\""),
    );
    for args in [&["render", "s.rib"][..], &["render", "s.rib", "-o", "x.gif"][..]] {
        let o = rtsl(args, dir.path());
        assert_ne!(o.status.code(), Some(0));
        let err = stderr(&o);
        assert!(err.contains("unsupported image format") && !err.contains("writing"), "{err}");
    }
}

#[test]
fn transfer_chooses_how_8_bit_images_encode_colour() {
    let dir = tempfile::tempdir().expect("tempdir");
    let grey = SPHERE_RIB.replace("Surface \"plastic\"", "Color [0.2 0.2 0.2] Surface \"constant\"");
    write(dir.path(), "s.rib", &grey);
    let srgb = "Option \"image\" \"string transfer\" [\"srgb\"]\n";
    write(dir.path(), "srgb.rib", &format!("{srgb}{grey}"));
    let centre = |scene: &str, args: &[&str]| {
        let o = rtsl(&[&["render", scene, "-o", "out.png", "-q"], args].concat(), dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let v = rtsl_runtime::read_image(dir.path().join("out.png")).expect("the image").pixel(16, 16)[0];
        (v * 255.0).round()
    };
    // Linear 0.2 is stored as 51/255; sRGB-encoded, 124/255. A RIB file is written as RenderMan
    // writes it, linear, unless it asks for sRGB; --transfer overrides both.
    assert_eq!(centre("s.rib", &[]), 51.0);
    assert_eq!(centre("srgb.rib", &[]), 124.0);
    assert_eq!(centre("s.rib", &["--transfer", "srgb"]), 124.0);
    assert_eq!(centre("srgb.rib", &["--transfer", "linear"]), 51.0);
    let o = rtsl(&["render", "s.rib", "--transfer", "gamma"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("is not a transfer: srgb or linear"), "{}", stderr(&o));

    // An 8-bit texture of 128/255: a RIB file's shaders read it as stored (0.502), unless the
    // file asks for sRGB, which decodes it (0.216, 55/255 written linear).
    let texel = vec![128.0 / 255.0; 4 * 4 * 4];
    let opts = rtsl_runtime::WriteOptions { transfer: rtsl_runtime::Transfer::Linear, ..Default::default() };
    rtsl_runtime::write_image(dir.path().join("t.png"), 4, 4, &texel, &opts).expect("the texture");
    write(dir.path(), "tex.sl", "surface tex(string name = \"\") { Ci = color texture(name, s, t); Oi = 1; }\n");
    let textured = SPHERE_RIB.replace("Surface \"plastic\"", "Surface \"tex\" \"string name\" \"t.png\"");
    write(dir.path(), "t.rib", &textured);
    write(dir.path(), "tsrgb.rib", &format!("{srgb}{textured}"));
    assert_eq!(centre("t.rib", &[]), 128.0);
    assert_eq!(centre("t.rib", &["--transfer", "srgb"]), 188.0);
    assert_eq!(centre("tsrgb.rib", &["--transfer", "linear"]), 55.0);
    assert_eq!(centre("tsrgb.rib", &[]), 128.0);
}

#[test]
fn a_render_missing_part_of_its_scene_fails_unless_told_to_keep_going() {
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = [
        ("shader", SPHERE_RIB.replace("\"plastic\"", "\"nosuchshader\""), "nosuchshader"),
        (
            "texture",
            SPHERE_RIB.replace("Surface \"plastic\"", "Surface \"texmap\" \"string texturename\" \"nope.png\""),
            "nope.png",
        ),
        ("archive", SPHERE_RIB.replace("Sphere", "ReadArchive \"gone.obj\"\nSphere"), "gone.obj"),
        ("request", SPHERE_RIB.replace("Sphere", "Shader \"coshader\" \"h\"\nSphere"), "Shader"),
    ];
    for (what, rib, named) in missing {
        write(dir.path(), "s.rib", &rib);
        let _ = std::fs::remove_file(dir.path().join("out.png"));
        let o = rtsl(&["render", "s.rib", "-o", "out.png", "--quiet"], dir.path());
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "a missing {what}: {err}");
        assert!(err.contains(named), "a missing {what} is named: {err}");
        assert!(err.contains("error: 1 part of the scene missing from the image"), "{what}: {err}");
        assert!(dir.path().join("out.png").exists(), "the image is written all the same ({what})");
        let o = rtsl(&["render", "s.rib", "-o", "out.png", "--quiet", "--keep-going"], dir.path());
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(0), "a missing {what} with --keep-going: {err}");
        assert!(err.contains(named) && err.contains("warning: 1 part of the scene missing"), "{what}: {err}");
    }
    // What is only ignored or approximated warns and succeeds.
    let approximated = SPHERE_RIB.replace("WorldBegin", "Option \"ribparse\" \"string varsubst\" [\"$\"]\nWorldBegin");
    write(dir.path(), "s.rib", &approximated);
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("\"ribparse\""), "{}", stderr(&o));
}

#[test]
fn a_file_without_a_shader_is_not_counted_as_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "empty.sl", "");
    let o = rtsl(&["compile", "empty.sl"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stdout(&o));
    let out = stdout(&o);
    assert!(out.contains("empty.sl: defines no shader"), "{out}");
    assert!(out.contains("0 shaders: 0 ok, 0 failed, 0 warnings; 1 file defines no shader"), "{out}");
    write(dir.path(), "lib/good.sl", GOOD);
    write(dir.path(), "lib/empty.sl", "");
    let o = rtsl(&["compile", "lib"], dir.path());
    assert!(stdout(&o).contains("1 shader: 1 ok, 0 failed, 0 warnings; 1 file defines no shader"), "{}", stdout(&o));
}

#[test]
fn shade_names_the_shader_type_with_the_right_article() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "img.sl", "imager img() { Ci = Ci * 0.5; }\n");
    let o = rtsl(&["shade", "img.sl", "-o", "Cl", "cl.exr"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("an imager shader has no global or output parameter `Cl`: it can write Ci, Oi, alpha"),
        "{err}"
    );
}

/// A copied binary carries its shader library: run from a directory far from the source tree, it
/// renders a scene with the library's shaders, and `RTSL_STDLIB` points it at a library kept
/// elsewhere (searched before the built-in one).
#[test]
fn a_copied_binary_renders_with_its_built_in_library() {
    let dir = tempfile::tempdir().expect("tempdir");
    let binary = dir.path().join("bin").join("rtsl");
    std::fs::create_dir_all(binary.parent().expect("a parent")).expect("bin/");
    std::fs::copy(env!("CARGO_BIN_EXE_rtsl"), &binary).expect("the binary copied");
    write(
        dir.path(),
        "scene.rib",
        "Format 32 24 1\nProjection \"perspective\" \"fov\" 40\nTranslate 0 0 4\nWorldBegin\n\
         LightSource \"pointlight\" 1 \"from\" [1 2 -3] \"intensity\" 20\nSurface \"plastic\"\n\
         Sphere 1 -1 1 360\nWorldEnd\n",
    );
    let run = |args: &[&str], library: Option<&Path>| {
        let mut c = Command::new(&binary);
        c.args(args).current_dir(dir.path()).env_remove("RTSL_SHADER_PATH").env_remove("RTSL_STDLIB");
        if let Some(library) = library {
            c.env("RTSL_STDLIB", library);
        }
        // A binary just written may be busy for a moment (ETXTBSY): another test thread forking
        // then holds the copy's write descriptor until its child execs.
        let mut attempts = 0;
        loop {
            match c.output() {
                Err(e) if e.raw_os_error() == Some(26) && attempts < 50 => {
                    attempts += 1;
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
                r => break r.expect("the copied binary runs"),
            }
        }
    };
    let o = run(&["render", "scene.rib", "-o", "out.png", "-q"], None);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("not found") && !stderr(&o).contains("no shader"), "{}", stderr(&o));
    let image = rtsl_runtime::read_image(dir.path().join("out.png")).expect("an image");
    let centre = image.pixel(16, 12);
    assert!(centre[..3].iter().any(|&c| c > 0.15), "the sphere is lit: {centre:?}");

    write(dir.path(), "lib/surface/plastic.sl", "surface plastic(float mine = 1;) { Ci = Cs * mine; Oi = Os; }\n");
    let o = run(&["info", "plastic", "--which"], Some(&dir.path().join("lib")));
    assert!(stdout(&o).trim_end().ends_with("lib/surface/plastic.sl"), "{}", stdout(&o));
    let o = run(&["info", "pointlight", "--which"], Some(&dir.path().join("lib")));
    assert_eq!(stdout(&o).trim_end(), "light/pointlight.sl (built in)");
}

#[test]
fn preview_renders_a_shader_on_the_ball_and_refuses_what_does_not_fit() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "mine.sl", "surface flatcolour(color c = 1;) { Oi = 1; Ci = c; }\n");
    let o = rtsl(&["preview", "mine.sl", "--param", "c=0,1,0", "--size", "40x30", "--samples", "1"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("flatcolour (surface) on the preview ball"), "{}", stdout(&o));
    let image = rtsl_runtime::read_image(dir.path().join("preview.png")).expect("the preview");
    // The ball fills the middle of the image, in the colour given, before a grey wall.
    assert_eq!(image.pixel(20, 12), [0.0, 1.0, 0.0, 1.0]);
    let wall = image.pixel(2, 1);
    assert!(wall[0] > 0.0 && wall[0] == wall[1] && wall[1] == wall[2] && wall[3] == 1.0, "{wall:?}");
    let o = rtsl(&["preview", "bumpy", "-o", "bumpy.exr", "--size", "40x30", "--samples", "1"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("bumpy (displacement)"), "{}", stdout(&o));

    let o = rtsl(&["preview", "plastic", "--param", "nope=1", "--size", "8x8"], dir.path());
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("warning: shader plastic has no parameter nope"), "{}", stderr(&o));
    let o = rtsl(&["preview", "pointlight", "--size", "8x8"], dir.path());
    assert!(stderr(&o).contains("`pointlight` is a light shader"), "{}", stderr(&o));
    let o = rtsl(&["preview", "nosuchshader", "--size", "8x8"], dir.path());
    assert!(stderr(&o).contains("nosuchshader"), "{}", stderr(&o));
    assert_ne!(o.status.code(), Some(0));
}

#[test]
fn diagnostics_are_coloured_when_asked_and_plain_in_a_pipe() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "bad.sl", "surface bad() { Ci = nope; }\n");
    write(dir.path(), "s.rib", &SPHERE_RIB.replace("Sphere", "Frobnicate 3\nSphere"));
    let escape = "\u{1b}[";
    // Piped (as here), `auto` is plain; `always` colours the compiler's and the RIB reader's.
    let o = rtsl(&["compile", "bad.sl"], dir.path());
    assert!(stdout(&o).contains("error[E0100]") && !stdout(&o).contains(escape), "{}", stdout(&o));
    let o = rtsl(&["--color", "always", "compile", "bad.sl"], dir.path());
    assert!(stdout(&o).contains(escape) && stdout(&o).contains("E0100"), "{}", stdout(&o));
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "-q", "--keep-going"], dir.path());
    let err = stderr(&o);
    assert!(!err.contains(escape), "{err}");
    // A RIB warning shows its line with the request underlined.
    assert!(err.contains("warning: unknown request `Frobnicate` skipped\n"), "{err}");
    assert!(err.contains("┌─ s.rib:6:1") && err.contains("6 │ Frobnicate 3\n  │ ^^^^^^^^^^"), "{err}");
    let o = rtsl(&["render", "s.rib", "-o", "out.png", "-q", "--keep-going", "--color", "always"], dir.path());
    assert!(stderr(&o).contains(escape), "{}", stderr(&o));
    let o = rtsl(&["--color", "sometimes", "compile", "bad.sl"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn every_frame_renders_its_own_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Options outside the frames hold for both; each frame has its own world, colour and Display.
    let frame = |n: i32, grey: f32| {
        format!(
            "FrameBegin {n}\nDisplay \"frame.#3f.png\" \"file\" \"rgb\"\nTranslate 0 0 5\nWorldBegin\n\
             Color [{grey} {grey} {grey}]\nSurface \"constant\"\nSphere 1 -1 1 360\nWorldEnd\nFrameEnd\n"
        )
    };
    write(dir.path(), "anim.rib", &format!("Format 16 16 1\n{}{}", frame(7, 0.2), frame(9, 1.0)));
    let centre =
        |name: &str| rtsl_runtime::read_image(dir.path().join(name)).expect("the frame's image").pixel(8, 8)[0];
    let o = rtsl(&["render", "anim.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!((centre("frame.007.png") * 255.0).round(), 51.0);
    assert_eq!(centre("frame.009.png"), 1.0);

    // One frame by its number, named by -o with the same patterns.
    let o = rtsl(&["render", "anim.rib", "--frame", "9", "-o", "only.#f.png", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(centre("only.9.png"), 1.0);
    assert!(!dir.path().join("only.7.png").exists());

    let o = rtsl(&["render", "anim.rib", "--frame", "8"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("there is no frame 8; the scene's frames are 7, 9"), "{}", stderr(&o));
    // Two frames into one file is refused before the second overwrites the first.
    let o = rtsl(&["render", "anim.rib", "-o", "same.png", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("would overwrite same.png of an earlier frame"), "{}", stderr(&o));
    let o = rtsl(&["render", "anim.rib", "--watch"], dir.path());
    assert!(stderr(&o).contains("the scene has 2 frames and --watch renders one"), "{}", stderr(&o));

    // World blocks outside frames are frames too, numbered by their place.
    write(
        dir.path(),
        "worlds.rib",
        &format!(
            "Format 16 16 1\nTranslate 0 0 5\n{0}{0}",
            "WorldBegin\nSurface \"constant\"\nSphere 1 -1 1 360\nWorldEnd\n"
        ),
    );
    let o = rtsl(&["render", "worlds.rib", "-o", "w#f.png", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(dir.path().join("w1.png").exists() && dir.path().join("w2.png").exists());
}

/// Several RIB files render in turn, as `prman a.rib b.rib` renders them (one file a frame, as
/// renderers' exporters write them): each its own frames and images, written apart.
#[test]
fn several_rib_files_render_in_turn() {
    let dir = tempfile::tempdir().expect("tempdir");
    let frame = |n: i32, grey: f32| {
        format!(
            "Format 16 16 1\nFrameBegin {n}\nDisplay \"shot.#4f.png\" \"file\" \"rgb\"\nTranslate 0 0 5\nWorldBegin\n\
             Color [{grey} {grey} {grey}]\nSurface \"constant\"\nSphere 1 -1 1 360\nWorldEnd\nFrameEnd\n"
        )
    };
    write(dir.path(), "shot.0001.rib", &frame(1, 0.2));
    write(dir.path(), "shot.0002.rib", &frame(2, 1.0));
    let centre =
        |name: &str| rtsl_runtime::read_image(dir.path().join(name)).expect("the frame's image").pixel(8, 8)[0];
    let o = rtsl(&["render", "shot.0001.rib", "shot.0002.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!((centre("shot.0001.png") * 255.0).round(), 51.0);
    assert_eq!(centre("shot.0002.png"), 1.0);
    // One output name for both is refused before the second overwrites the first.
    let o = rtsl(&["render", "shot.0001.rib", "shot.0002.rib", "-o", "same.png", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("frame 2 would overwrite same.png of an earlier frame"), "{}", stderr(&o));
    // Only RIB files render in turn; --watch and --frame take one.
    write(dir.path(), "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let o = rtsl(&["render", "shot.0001.rib", "tri.obj"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("tri.obj: several scenes are RIB files"), "{}", stderr(&o));
    for flag in [&["--watch"][..], &["--frame", "1"]] {
        let o = rtsl(&[&["render", "shot.0001.rib", "shot.0002.rib"][..], flag].concat(), dir.path());
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains("--watch and --frame take one scene file"), "{}", stderr(&o));
    }
    // A file that cannot be read stops the run with its name, after the files before it.
    let o = rtsl(&["render", "shot.0001.rib", "missing.rib", "-q"], dir.path());
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("missing.rib"), "{}", stderr(&o));
}

#[test]
fn without_a_projection_the_camera_is_orthographic() {
    let dir = tempfile::tempdir().expect("tempdir");
    let white = SPHERE_RIB.replace("Surface \"plastic\"", "Color [1 1 1] Surface \"constant\"");
    // The unit sphere five units away: orthographic, it fills the screen window [-1, 1]^2; seen
    // through a 90-degree perspective, it covers a fifth of it.
    let near_the_edge = |rib: &str| {
        write(dir.path(), "s.rib", rib);
        let o = rtsl(&["render", "s.rib", "-o", "out.png", "-q"], dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        rtsl_runtime::read_image(dir.path().join("out.png")).expect("the image").pixel(4, 16)[0]
    };
    assert_eq!(near_the_edge(&white), 1.0);
    assert_eq!(near_the_edge(&white.replace("Translate", "Projection \"perspective\" \"fov\" 90\nTranslate")), 0.0);
}

#[test]
fn displays_write_their_modes_depths_and_additional_images() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = |displays: &str| {
        SPHERE_RIB
            .replace("Format 32 32 1", &format!("Format 32 32 1\nProjection \"perspective\" \"fov\" 30\n{displays}"))
    };
    write(
        dir.path(),
        "s.rib",
        &scene(
            "Quantize \"rgba\" 65535 0 65535 0\nDisplay \"colour.tif\" \"tiff\" \"rgb\"\n\
             Display \"+depth.exr\" \"file\" \"z\"\nDisplay \"+alpha.png\" \"file\" \"a\"\n\
             Display \"+depth.tif\" \"zfile\" \"z\"",
        ),
    );
    let o = rtsl(&["render", "s.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let read = |name: &str| rtsl_runtime::read_image(dir.path().join(name)).expect(name);
    // 16-bit colour: a shade between two 8-bit codes survives.
    let colour = read("colour.tif").pixel(16, 16);
    assert!(colour[0] > 0.0 && ((colour[0] * 255.0) - (colour[0] * 255.0).round()).abs() > 1e-3, "{colour:?}");
    // The front of the unit sphere five units away is four units deep; the background is infinitely far.
    for name in ["depth.exr", "depth.tif"] {
        let depth = read(name);
        assert!((depth.pixel(16, 16)[0] - 4.0).abs() < 0.01, "{name}: {:?}", depth.pixel(16, 16));
        assert_eq!(depth.pixel(0, 0)[0], f32::INFINITY, "{name}");
    }
    let alpha = read("alpha.png");
    assert_eq!((alpha.pixel(16, 16)[0], alpha.pixel(0, 0)[0]), (1.0, 0.0));

    // `-o` replaces the first display's file, and the additional displays are still written.
    for name in ["colour.tif", "alpha.png"] {
        std::fs::remove_file(dir.path().join(name)).expect("written by the render above");
    }
    let o = rtsl(&["render", "s.rib", "-q", "-o", "instead.png"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(dir.path().join("instead.png").exists());
    assert!(!dir.path().join("colour.tif").exists(), "-o replaces the scene's own image");
    assert!(dir.path().join("alpha.png").exists(), "the + displays are still written");

    // A window display writes render.png, with a note; depth in an 8-bit file is refused before rendering.
    write(dir.path(), "w.rib", &scene("Display \"view\" \"framebuffer\" \"rgba\""));
    let o = rtsl(&["render", "w.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("is a window") && dir.path().join("render.png").exists(), "{}", stderr(&o));
    // Beside a file, the window is left out, with one note.
    let both = "Display \"both.png\" \"file\" \"rgba\" Display \"+view\" \"framebuffer\" \"rgba\" \
                Display \"+it\" \"it\" \"rgba\"";
    write(dir.path(), "wf.rib", &scene(both));
    let o = rtsl(&["render", "wf.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches("is a window").count(), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("it is left out") && dir.path().join("both.png").exists(), "{}", stderr(&o));
    write(dir.path(), "z.rib", &scene("Display \"z.png\" \"file\" \"z\""));
    let o = rtsl(&["render", "z.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("z.png: depth needs a float image"), "{}", stderr(&o));
    // A global the surface shader uses is an output variable too: plastic's normal.
    write(dir.path(), "aov.rib", &scene("Display \"n.exr\" \"file\" \"normal N\""));
    let o = rtsl(&["render", "aov.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let n = read("n.exr").pixel(16, 16);
    assert!(n[2] < -0.9, "N in current (camera) space: the sphere's front faces the camera, -z: {n:?}");
}

/// Display drivers name the format (RenderMan's `file` is TIFF where the name's extension names
/// none), renderers' viewers are windows, and a driver rtsl does not have is left out with a
/// warning while the frame renders.
#[test]
fn display_drivers_choose_the_format_and_viewers_are_windows() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = |displays: &str| SPHERE_RIB.replace("Format 32 32 1", &format!("Format 32 32 1\n{displays}"));
    let drivers = "Display \"ri.pic\" \"file\" \"rgba\"\nDisplay \"+tiled\" \"tiff\" \"rgb\"\n\
                   Display \"+layers\" \"openexr\" \"rgba\"\nDisplay \"+shot.img\" \"png\" \"rgba\"\n\
                   Display \"+render\" \"piqsl\" \"rgb\"\nDisplay \"+view\" \"idisplay\" \"rgb\"";
    write(dir.path(), "d.rib", &scene(drivers));
    let o = rtsl(&["render", "d.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches("is a window").count(), 1, "{}", stderr(&o));
    let magic = |name: &str| std::fs::read(dir.path().join(name)).map(|b| b[..4].to_vec()).expect(name);
    let tiff = |m: &[u8]| m == b"II*\0" || m == b"MM\0*";
    assert!(tiff(&magic("ri.pic")) && tiff(&magic("tiled")), "RenderMan's file and tiff drivers write TIFF");
    assert_eq!(magic("layers"), vec![0x76, 0x2f, 0x31, 0x01], "openexr writes EXR");
    assert_eq!(magic("shot.img"), b"\x89PNG".to_vec());
    assert!(!dir.path().join("render").exists() && !dir.path().join("view").exists());

    write(dir.path(), "u.rib", &scene("Display \"u.png\" \"file\" \"rgba\"\nDisplay \"+odd\" \"sgi\" \"rgba\""));
    let o = rtsl(&["render", "u.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(1), "the display is missing from the output: {}", stderr(&o));
    assert!(stderr(&o).contains("display driver \"sgi\" is not one rtsl has"), "{}", stderr(&o));
    assert!(dir.path().join("u.png").exists());
}

/// PRMan's built-in `background` imager takes its colour as `"color"`, a name no shader
/// parameter can have: it is the `background` parameter of ours.
#[test]
fn the_background_imager_takes_prmans_color_parameter() {
    let dir = tempfile::tempdir().expect("tempdir");
    let imager = "Display \"bg.exr\" \"file\" \"rgba\"\nImager \"background\" \"color\" [0.25 0.5 1]";
    write(dir.path(), "bg.rib", &SPHERE_RIB.replace("Format 32 32 1", &format!("Format 32 32 1\n{imager}")));
    let o = rtsl(&["render", "bg.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("no parameter"), "{}", stderr(&o));
    let image = rtsl_runtime::read_image(dir.path().join("bg.exr")).expect("bg.exr");
    assert_eq!(image.pixel(0, 0), [0.25, 0.5, 1.0, 1.0]);
}

#[test]
fn a_shadow_map_pass_feeds_the_frame_after_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A floor at y = 0 and a square occluder over the origin at y = 2; the light 5 above, looking
    // down. Frame 1 renders its depth map from the light; frame 2 makes it a shadow map and lights
    // the floor with it, ray-traced shadows off so that only the map shadows.
    let world = "Surface \"matte\"\n\
                 Polygon \"P\" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]\n\
                 Polygon \"P\" [-0.5 2 -0.5  0.5 2 -0.5  0.5 2 0.5  -0.5 2 0.5]\n";
    let light_camera = "Projection \"perspective\" \"fov\" 60\nRotate -90 1 0 0\nTranslate 0 -5 0\n";
    // The beauty camera looks down from beside the light, so the shadow is not behind the occluder.
    let camera = "Projection \"perspective\" \"fov\" 60\nRotate -90 1 0 0\nTranslate -2 -5 0\n";
    let beauty = |shadowname: &str| {
        format!(
            "FrameBegin 2\nMakeShadow \"light.z\" \"light.shd\"\nDisplay \"beauty.exr\" \"file\" \"rgba\"\n\
             {camera}WorldBegin\nAttribute \"light\" \"shadows\" \"off\"\n\
             LightSource \"shadowspot\" 1 \"from\" [0 5 0] \"to\" [0 0 0] \"coneangle\" [0.9] \"intensity\" [25] \
             \"shadowname\" [\"{shadowname}\"]\n{world}WorldEnd\nFrameEnd\n"
        )
    };
    let depth_pass = format!(
        "Format 64 64 1\nFrameBegin 1\nDisplay \"light.z\" \"zfile\" \"z\"\n{light_camera}WorldBegin\n{world}WorldEnd\nFrameEnd\n"
    );
    write(dir.path(), "shadows.rib", &format!("{depth_pass}{}", beauty("light.shd")));
    let o = rtsl(&["render", "shadows.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));

    // The map projects the world as the light's camera saw it: the floor under the occluder is in
    // shadow, the floor beside it is not.
    let map = rtsl_runtime::texture::ShadowMap::load(&dir.path().join("light.shd")).expect("a shadow map");
    let opts = rtsl_runtime::texture::LookupOptions { bias: 0.05, ..Default::default() };
    assert_eq!(map.shadow([0.0, 0.0, 0.0], &opts), 1.0);
    assert_eq!(map.shadow([1.5, 0.0, 0.3], &opts), 0.0);
    assert_eq!(map.shadow([0.0, 2.5, 0.0], &opts), 0.0, "above the occluder");
    // Without a bias, the nearest surface's depth shadows the floor in places by itself.
    let unbiased = rtsl_runtime::texture::LookupOptions { bias: 0.0, ..Default::default() };
    let self_shadow = |map: &rtsl_runtime::texture::ShadowMap| -> f32 {
        (0..40).map(|i| map.shadow([-3.0 + 0.15 * i as f32, 0.0, 1.7], &unbiased)).sum()
    };
    assert!(self_shadow(&map) > 0.0);

    // The floor's shadow darkens a good part of the frame, against one lit without the map.
    let mean = |name: &str| {
        let image = rtsl_runtime::read_image(dir.path().join(name)).expect(name);
        image.pixels.chunks_exact(4).map(|p| p[0]).sum::<f32>()
    };
    let with_map = mean("beauty.exr");
    write(dir.path(), "lit.rib", &format!("Format 64 64 1\n{}", beauty("")));
    let o = rtsl(&["render", "lit.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let without = mean("beauty.exr");
    assert!(with_map < 0.9 * without, "the map darkens the frame: {with_map} against {without}");

    // A midpoint map stores depth halfway to the next surface: with no bias at all, the floor
    // does not shadow itself, and under the occluder it is still in shadow.
    let midpoint = depth_pass.replace("FrameBegin 1", "Hider \"hidden\" \"depthfilter\" \"midpoint\"\nFrameBegin 1");
    write(dir.path(), "midpoint.rib", &format!("{midpoint}{}", beauty("light.shd")));
    let o = rtsl(&["render", "midpoint.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let map = rtsl_runtime::texture::ShadowMap::load(&dir.path().join("light.shd")).expect("a shadow map");
    assert_eq!(self_shadow(&map), 0.0);
    assert_eq!(map.shadow([0.0, 0.0, 0.0], &unbiased), 1.0);
    assert_eq!(map.shadow([1.5, 0.0, 0.3], &unbiased), 0.0);
    assert_eq!(map.shadow([-2.0, 0.0, 1.0], &unbiased), 0.0);
    assert_eq!(map.shadow([0.0, 2.0, 0.0], &unbiased), 0.0, "the occluder itself");

    // A shadow map through a camera shader has no matrix: refused before rendering.
    write(
        dir.path(),
        "fish.rib",
        "Format 8 8 1\nCamera \"fisheye\"\nDisplay \"f.z\" \"zfile\" \"z\"\nWorldBegin\nWorldEnd\n",
    );
    let o = rtsl(&["render", "fish.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("a shadow map needs the built-in perspective camera"), "{}", stderr(&o));
}

#[test]
fn rib_conditionals_choose_each_frames_branch_in_a_shared_archive() {
    let dir = tempfile::tempdir().expect("tempdir");
    // One archive read by both frames: its colour depends on the frame and on the pass option.
    write(
        dir.path(),
        "ball.rib",
        "IfBegin \"$user:pass == 'key'\"\n  Color [0 0 0]\nElseIf \"$Frame >= 9\"\n  Color [1 1 1]\nElse\n  \
         Color [0.2 0.2 0.2]\nIfEnd\nSurface \"constant\"\nSphere 1 -1 1 360\n",
    );
    let frame = |n: i32| {
        format!(
            "FrameBegin {n}\nDisplay \"cond.#f.png\" \"file\" \"rgb\"\nTranslate 0 0 5\nWorldBegin\n\
             ReadArchive \"ball.rib\"\nWorldEnd\nFrameEnd\n"
        )
    };
    write(
        dir.path(),
        "anim.rib",
        &format!("Format 16 16 1\nOption \"user\" \"string pass\" \"beauty\"\n{}{}", frame(7), frame(9)),
    );
    let centre =
        |name: &str| rtsl_runtime::read_image(dir.path().join(name)).expect("the frame's image").pixel(8, 8)[0];
    let o = rtsl(&["render", "anim.rib", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!((centre("cond.7.png") * 255.0).round(), 51.0);
    assert_eq!(centre("cond.9.png"), 1.0);
    // One frame on its own takes the same branch.
    let o = rtsl(&["render", "anim.rib", "--frame", "9", "-o", "only.png", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(centre("only.png"), 1.0);
    // A malformed condition is an error with its place, and the render counts a part missing.
    write(dir.path(), "bad.rib", "Format 16 16 1\nWorldBegin\nIfBegin \"$Frame ==\"\nIfEnd\nWorldEnd\n");
    let o = rtsl(&["render", "bad.rib", "-o", "bad.png", "--color", "never"], dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("bad.rib:3:1"), "{}", stderr(&o));
}

/// A box that slides and turns, and a route of the wrong type.
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
ROUTE C.fraction_changed TO T.set_scale
";

#[test]
fn vrml_animation_renders_times_and_frame_ranges() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "move.wrl", VRML_MOVING_BOX);
    let render = |extra: &[&str]| {
        let mut args = vec!["render", "move.wrl", "--size", "32x24", "-q"];
        args.extend_from_slice(extra);
        let o = rtsl(&args, dir.path());
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        o
    };
    let o = render(&["--time", "0.25", "-o", "early.png"]);
    // The bad route is a warning with its place; the others run.
    let err = stderr(&o);
    assert!(err.contains("warning: ROUTE C.fraction_changed TO T.set_scale: it joins an SFFloat"), "{err}");
    assert!(err.contains("move.wrl:11:1"), "{err}");
    render(&["--time", "1", "-o", "later.png"]);
    let read = |name: &str| std::fs::read(dir.path().join(name)).expect("written");
    assert_ne!(read("early.png"), read("later.png"), "the box moved");
    // Frames 1 to 3 at 4 per second show times 0, 0.25 and 0.5; #f numbers them.
    render(&["--frames", "1..3", "--fps", "4", "-o", "f.#2f.png"]);
    for n in ["01", "02", "03"] {
        assert!(dir.path().join(format!("f.{n}.png")).is_file(), "frame {n}");
    }
    assert_eq!(read("f.02.png"), read("early.png"));
    assert_ne!(read("f.01.png"), read("f.02.png"));
    render(&["--frame", "5", "--fps", "4", "-o", "one.#f.png"]);
    assert_eq!(read("one.5.png"), read("later.png"));
    // Frames must be named apart, and --time is for VRML scenes.
    let o = rtsl(&["render", "move.wrl", "--size", "8x8", "--frames", "1..2", "-o", "same.png"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("would overwrite same.png"), "{}", stderr(&o));
    write(dir.path(), "s.rib", "WorldBegin\nSphere 1 -1 1 360\nWorldEnd\n");
    let o = rtsl(&["render", "s.rib", "--size", "8x8", "--time", "1"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--time and --frames animate VRML scenes"), "{}", stderr(&o));
    let o = rtsl(&["render", "move.wrl", "--frames", "3..1"], dir.path());
    assert_eq!(o.status.code(), Some(2));
}

/// The MGF office of `../shared/scenes/office_mgf_vrml1/` (VRML 1.0: 301 Separators, a
/// MatrixTransform, per-vertex normals, clockwise faces): on its own, framed, and inlined by a
/// VRML 97 file that gives it the reference screenshot's viewpoint and lights.
#[test]
fn the_vrml1_office_renders_on_its_own_and_inlined() {
    let office = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/office_mgf_vrml1/office.wrl");
    if !office.is_file() {
        eprintln!("SKIPPED: {} is not here (the shared scenes are not checked out)", office.display());
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let o = rtsl(&["render", &office.to_string_lossy(), "--size", "48x27", "-o", "alone.png"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("299 instances"), "{}", stdout(&o));
    std::fs::copy(&office, dir.path().join("office.wrl")).expect("copied");
    write(
        dir.path(),
        "final.wrl",
        "#VRML V2.0 utf8
NavigationInfo { headlight FALSE }
PointLight { location 0.136 2.596 6.522 }
PointLight { location -1.848 2.173 0.326 color 1 1 0 intensity 0.5 }
Viewpoint { position 2.194 2.534 0.678 orientation 0 1 0 1.786 }
Inline { url \"office.wrl\" }
",
    );
    let o = rtsl(&["render", "final.wrl", "--size", "48x27", "-o", "final.png"], dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let image = rtsl::runtime::read_image(dir.path().join("final.png")).expect("a PNG");
    // The room from inside: walls, desk and chairs fill the view but for the window on the left,
    // and the lights light them.
    let opaque = image.pixels.chunks_exact(4).filter(|p| p[3] > 0.99).count();
    assert!(opaque > 48 * 27 * 7 / 10 && opaque < 48 * 27, "{opaque} pixels see the room");
    let lit = image.pixels.chunks_exact(4).filter(|p| p[0] + p[1] + p[2] > 0.3).count();
    assert!(lit > 48 * 27 / 4, "{lit} lit pixels");
}

/// `rtsl bench trace` reports its figures as `name: value` lines, the page faults of each timed
/// build among them, and its packet and single-ray passes agree.
#[test]
fn bench_trace_reports_each_builds_page_faults() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A grid of quads facing the default camera, which looks down at the origin from above.
    let mut obj = String::new();
    let n = 24;
    for j in 0..=n {
        for i in 0..=n {
            obj += &format!("v {} 0 {}\n", i as f32 * 10.0 - 120.0, j as f32 * 10.0 - 170.0);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let v = j * (n + 1) + i + 1;
            obj += &format!("f {} {} {} {}\n", v, v + 1, v + n + 2, v + n + 1);
        }
    }
    write(dir.path(), "grid.obj", &obj);
    let args = ["bench", "trace", "--mesh", "grid.obj", "--size", "64x48", "--threads", "1", "--repeats", "2"];
    let o = rtsl(&args, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let field = |name: &str| {
        let prefix = format!("{name}: ");
        out.lines().find_map(|l| l.strip_prefix(&prefix)).unwrap_or_else(|| panic!("no {name} in {out}")).to_string()
    };
    assert_eq!(field("triangles"), (2 * n * n).to_string());
    assert_ne!(field("hits"), "0", "{out}");
    assert_eq!(field("packet_single_mismatches"), "0", "{out}");
    if cfg!(unix) {
        let faults: Vec<u64> =
            field("build_page_faults").split(", ").map(|f| f.parse().expect("a count of faults")).collect();
        assert_eq!(faults.len(), 2, "one count for each timed build: {out}");
        // Untimed builds after the first are listed only while they faulted in fresh pages.
        if let Some(warmup) = out.lines().find_map(|l| l.strip_prefix("warmup_builds: ")) {
            let counts: Vec<u64> = warmup
                .split(", ")
                .map(|b| b.rsplit_once("ms/").and_then(|(_, f)| f.parse().ok()).expect("`MS ms/FAULTS`"))
                .collect();
            assert!((1..=4).contains(&counts.len()) && counts.iter().all(|&f| f > 0), "{out}");
        }
    }
    // The packet kernels it ran with: AVX-512 where the processor has it, unless `RTSL_ISA` says
    // `avx2`, which keeps the build's own set (SSE2 in a build for plain x86-64, such as an
    // application's built with cargo's default flags); a value it does not know is reported and
    // ignored.
    let built = if cfg!(all(target_feature = "avx2", target_feature = "fma")) { "avx2" } else { "sse2" };
    let kernels = field("packet_kernels");
    assert!(["avx512", built].contains(&kernels.as_str()), "{out}");
    let with_isa = |isa: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_rtsl"))
            .args(args)
            .env("RTSL_ISA", isa)
            .current_dir(dir.path())
            .output()
            .expect("the binary runs");
        assert!(o.status.success(), "{}", stderr(&o));
        let kernels = stdout(&o).lines().find_map(|l| l.strip_prefix("packet_kernels: ").map(str::to_string));
        (kernels.unwrap_or_default(), stderr(&o))
    };
    assert_eq!(with_isa("avx2").0, built);
    assert_eq!(with_isa("avx512").0, kernels);
    let (bogus, said) = with_isa("avx1024");
    assert_eq!(bogus, kernels);
    assert!(said.contains("RTSL_ISA=\"avx1024\"") && said.contains("ignored"), "{said}");
}

/// `-S` takes a list of directories separated by `:`, as `RTSL_SHADER_PATH` does, and says which
/// of them does not exist.
#[test]
fn shader_path_lists_are_split_and_missing_directories_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "shaders/flat.sl", "surface flat() { Ci = color(0.25, 0.5, 1); Oi = 1; }\n");
    write(
        dir.path(),
        "scenes/scene.rib",
        "Format 16 12 1\nDisplay \"out.exr\" \"file\" \"rgba\"\nTranslate 0 0 5\nWorldBegin\nSurface \"flat\"\n\
         Polygon \"P\" [-9 -9 0 9 -9 0 9 9 0 -9 9 0]\nWorldEnd\n",
    );
    let scenes = dir.path().join("scenes");
    let o = rtsl(&["render", "scene.rib", "-S", "../nowhere:../shaders", "-q"], &scenes);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains("shader search directory ../nowhere does not exist"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("no shader named"), "{}", stderr(&o));
    let image = rtsl_runtime::read_image(scenes.join("out.exr")).expect("the image");
    assert_eq!(&pixel(&image, 8, 6)[..3], &[0.25, 0.5, 1.0]);
}
