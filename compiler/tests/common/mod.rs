//! Helpers shared by the integration tests: the shader files of the library and corpora, and the
//! harness that checks the packet JIT against the reference interpreter (`check`, `differential`).
//!
//! The JIT tests (`jit_*.rs`) compile a shader with both back ends, fill a batch with random inputs
//! under a random mask (inactive and padding lanes hold a NaN sentinel), shade it with the JIT and
//! run the interpreter once per active lane with the same inputs. Outputs (written globals and
//! output parameters) must agree within `TOL` relative (the JIT evaluates the interpreter's
//! operations in the same order and calls the same scalar code for transcendental and noise
//! functions, so they agree exactly in practice; the tolerance only absorbs what a future
//! polynomial may change), and inactive lanes must keep the sentinel's exact bits.
//!
//! Each test file is its own crate and uses only some of these.
#![allow(dead_code)]

use rtsl_compiler::back::jit::{self, BatchData, CompiledShader};
use rtsl_compiler::interp::{self, Limits, ShadingPoint, TestHost, Value};
use rtsl_compiler::ir::Module;
use rtsl_compiler::{compile_source, Options};
use std::path::{Path, PathBuf};

/// Every `.sl` file under `dir`, recursively, in a stable order.
pub fn shader_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    walk(dir, &mut out);
    out
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> =
        std::fs::read_dir(dir).expect("directory").filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            walk(&p, out);
        } else if p.extension().is_some_and(|e| e == "sl") {
            out.push(p);
        }
    }
}

/// Every shader of the library and both corpora, with the options (include paths) they need.
pub fn library_and_corpora() -> (Vec<PathBuf>, Options) {
    let mut files = Vec::new();
    for dir in ["../stdlib_shaders", "../tests/corpus", "../tests/corpus2"] {
        files.extend(shader_files(Path::new(dir)));
    }
    let mut options = Options::default();
    options.preprocessor.include_paths.push(PathBuf::from("../tests/corpus/include"));
    options.preprocessor.include_paths.push(PathBuf::from("../tests/corpus2/include"));
    (files, options)
}

// ---- The JIT against the interpreter ----

pub const TOL: f32 = 1e-5;
pub const SENTINEL: u32 = 0x7fc0_1234;

/// A small deterministic generator (xorshift64*).
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    /// Uniform in [lo, hi).
    pub fn f(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }
}

pub fn module(src: &str) -> Module {
    let c = compile_source("jit_test.sl", src, &Options::default());
    assert!(c.ok(), "does not compile:\n{}", c.render());
    c.module.expect("module")
}

pub fn value_of(floats: &[f32], comps: usize) -> Value {
    match (comps, floats.len()) {
        (1, 1) => Value::Float(floats[0]),
        (3, 3) => Value::Triple([floats[0], floats[1], floats[2]]),
        (16, 16) => Value::Matrix(std::array::from_fn(|i| floats[i])),
        (c, _) => Value::Array(floats.chunks(c).map(|e| value_of(e, c)).collect()),
    }
}

pub fn floats_of(v: &Value) -> Vec<f32> {
    match v {
        Value::Float(x) => vec![*x],
        Value::Triple(t) => t.to_vec(),
        Value::Matrix(m) => m.to_vec(),
        Value::Array(items) => items.iter().flat_map(floats_of).collect(),
        other => panic!("unexpected value {other:?}"),
    }
}

pub fn close(a: f32, b: f32) -> bool {
    (a.is_nan() && b.is_nan()) || a == b || (a - b).abs() <= TOL * b.abs().max(1.0)
}

/// Strings a random string parameter may hold: spaces (known and unknown), colour spaces, texture
/// names (readable and not), categories, message names.
pub const STRINGS: &[&str] =
    &["", "world", "object", "camera", "shader", "nowhere", "hsv", "rgb", "missing", "grid.tx", "Format"];

/// Random inputs for one lane: a global's value.
pub fn random_global(rng: &mut Rng, name: &str, comps: usize) -> Vec<f32> {
    if comps == 1 && !matches!(name, "s" | "t" | "u" | "v" | "du" | "dv") {
        return vec![rng.f(0.0, 1.0)];
    }
    match name {
        "s" | "t" | "u" | "v" => vec![rng.f(0.0, 1.0)],
        "du" | "dv" => vec![rng.f(0.001, 0.1)],
        "N" | "Ng" | "I" => {
            let v = [rng.f(-1.0, 1.0), rng.f(-1.0, 1.0), rng.f(-1.0, 1.0)];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-3);
            v.iter().map(|x| x / l).collect()
        }
        "Cs" | "Os" | "Ci" | "Oi" => vec![rng.f(0.0, 1.0), rng.f(0.0, 1.0), rng.f(0.0, 1.0)],
        _ => vec![rng.f(-2.0, 2.0), rng.f(-2.0, 2.0), rng.f(-2.0, 2.0)],
    }
}

/// A global's name and its d/dx and d/dy in one lane.
pub type LaneDerivs = (String, Vec<f32>, Vec<f32>);

/// Random screen-space derivatives (ray differentials) of a varying global: `u` mostly along x and
/// `v` along y (so the parameter Jacobian is well conditioned), small ones for everything else.
pub fn random_derivs(rng: &mut Rng, name: &str, comps: usize) -> (Vec<f32>, Vec<f32>) {
    match name {
        "u" => (vec![rng.f(0.005, 0.02)], vec![rng.f(-0.005, 0.005)]),
        "v" => (vec![rng.f(-0.005, 0.005)], vec![rng.f(0.005, 0.02)]),
        _ => ((0..comps).map(|_| rng.f(-0.05, 0.05)).collect(), (0..comps).map(|_| rng.f(-0.05, 0.05)).collect()),
    }
}

/// The test host with a point light among the random points, so that lanes differ in their
/// lights (direction, colour, which side of the surface).
pub fn lit_host() -> TestHost {
    TestHost {
        point_light: Some([0.5, 2.0, 1.0]),
        ray_parameters: vec![
            ("q".into(), Value::Float(0.375)),
            ("tint".into(), Value::Triple([0.1, 0.2, 0.3])),
            ("label".into(), Value::String("hero".into())),
        ],
        ..TestHost::default()
    }
}

/// The test host's image (`TestHost::pixel_value`) as the arrays a renderer's `PixelView` holds.
pub struct TestImage {
    size: (u32, u32),
    rgba: Vec<[f32; 4]>,
    depth: Vec<f32>,
    ids: (Vec<u32>, Vec<u32>),
    normal: Vec<[f32; 3]>,
}

impl TestImage {
    /// `host`'s channels at every pixel's centre.
    pub fn of(host: &mut TestHost) -> TestImage {
        use rtsl_compiler::interp::Services;
        let (w, h) = (8u32, 6u32);
        let mut image = TestImage {
            size: (w, h),
            rgba: Vec::new(),
            depth: Vec::new(),
            ids: (Vec::new(), Vec::new()),
            normal: Vec::new(),
        };
        for y in 0..h {
            for x in 0..w {
                let mut at = |name: &str| host.pixel_value(name, x as f32 + 0.5, y as f32 + 0.5).expect("a channel");
                let (ci, alpha) = (at("Ci"), at("alpha")[0]);
                image.rgba.push([ci[0], ci[1], ci[2], alpha]);
                image.depth.push(at("z")[0]);
                image.ids.0.push(at("objectid")[0] as u32);
                image.ids.1.push(at("shaderid")[0] as u32);
                image.normal.push(at("N"));
            }
        }
        image
    }

    pub fn view(&self) -> Option<jit::PixelView> {
        jit::PixelView::new(self.size, &self.rgba, &self.depth, (&self.ids.0, &self.ids.1), &self.normal)
    }
}

/// Shades `lanes` random lanes with both back ends and compares. Returns how many lanes ran.
pub fn differential(m: &Module, shader: &CompiledShader, lanes: usize, seed: u64, bind_prob: f32) -> usize {
    differential_with(m, shader, lanes, seed, bind_prob, Limits::default())
}

/// [`differential`] with the interpreter under `limits` (the JIT compiled with the same loop
/// budget). The budgets count differently by design (the JIT's loop budget per chunk of four
/// lanes, the interpreter's per point, and only the interpreter counts calls), so a run that met a
/// budget on either side is run to the end in both but not compared: the fuzz target runs with
/// small budgets, to spend its time on many shaders rather than on one long loop.
pub fn differential_with(
    m: &Module,
    shader: &CompiledShader,
    lanes: usize,
    seed: u64,
    bind_prob: f32,
    limits: Limits,
) -> usize {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let layout = shader.layout().clone();
    let mut batch: BatchData = shader.batch(lanes);
    batch.fill_varying(f32::from_bits(SENTINEL));
    let mut active = vec![false; lanes];
    // Random masks: sometimes all on, sometimes sparse.
    let density = match seed % 3 {
        0 => 1.0,
        1 => 0.5,
        _ => 0.15,
    };
    for (l, a) in active.iter_mut().enumerate() {
        *a = rng.f(0.0, 1.0) < density;
        batch.set_active(l, *a);
    }
    // Uniform globals and parameters: the same for every lane.
    let mut uniform_bound: Vec<(String, Vec<f32>)> = Vec::new();
    for g in layout.globals.iter().filter(|g| !g.varying) {
        let v = if g.name == "ncomps" { vec![3.0] } else { vec![rng.f(0.0, 1.0)] };
        batch.set_global(g.name, 0, &v);
        uniform_bound.push((g.name.to_string(), v));
    }
    let mut bound_params: Vec<(String, Option<Vec<f32>>)> = Vec::new();
    let mut bound_strings: Vec<(String, String)> = Vec::new();
    for p in &layout.params {
        let bind = rng.f(0.0, 1.0) < bind_prob;
        if bind && p.string {
            let s = STRINGS[(rng.next() % STRINGS.len() as u64) as usize];
            assert!(batch.set_string_param(&p.name, s));
            bound_strings.push((p.name.clone(), s.to_string()));
            bound_params.push((p.name.clone(), None));
        } else if bind && !p.varying {
            let v: Vec<f32> = (0..p.floats()).map(|_| rng.f(-1.0, 2.0)).collect();
            batch.set_param(&p.name, 0, &v);
            bound_params.push((p.name.clone(), Some(v)));
        } else {
            bound_params.push((p.name.clone(), if bind { Some(Vec::new()) } else { None }));
        }
    }
    // Every lane its own `random()` seed, in both back ends.
    let seeds: Vec<u64> = (0..lanes).map(|_| rng.next()).collect();
    let mut lane_inputs: Vec<Vec<(String, Vec<f32>)>> = vec![Vec::new(); lanes];
    let mut lane_derivs: Vec<Vec<LaneDerivs>> = vec![Vec::new(); lanes];
    let mut lane_params: Vec<Vec<(String, Vec<f32>)>> = vec![Vec::new(); lanes];
    for l in 0..lanes {
        if !active[l] {
            continue;
        }
        assert_eq!(batch.set_seed(l, seeds[l]), layout.seed.is_some());
        for g in layout.globals.iter().filter(|g| g.varying) {
            let v = random_global(&mut rng, g.name, g.components);
            assert!(batch.set_global(g.name, l, &v));
            lane_inputs[l].push((g.name.to_string(), v));
            let (dx, dy) = random_derivs(&mut rng, g.name, g.components);
            // Only shaders that differentiate have a derivative buffer.
            assert_eq!(batch.set_global_derivs(g.name, l, &dx, &dy), layout.deriv_slots > 0);
            lane_derivs[l].push((g.name.to_string(), dx, dy));
        }
        for (p, (_, b)) in layout.params.iter().zip(&bound_params) {
            if p.varying && b.is_some() {
                let v: Vec<f32> = (0..p.floats()).map(|_| rng.f(-1.0, 2.0)).collect();
                assert!(batch.set_param(&p.name, l, &v));
                lane_params[l].push((p.name.clone(), v));
            }
        }
    }
    let mut jit_host = lit_host();
    // Half the runs read `pixelvalue` of literal channels from the test host's image itself, as
    // a renderer's pixel shaders do; the others through the host's callback.
    let image = TestImage::of(&mut lit_host());
    shader.shade_with_pixels(&mut batch, &mut jit_host, image.view().filter(|_| seed % 2 == 0));
    let mut printed = Vec::new();
    let mut budget_met = shader.stopped_a_loop();

    let kind = m.shader.as_ref().expect("shader").kind;
    let mut ran = 0;
    for l in 0..lanes {
        if !active[l] {
            continue;
        }
        ran += 1;
        let mut point = ShadingPoint::new(kind);
        point.seed = seeds[l];
        for (name, v) in uniform_bound.iter().chain(&lane_inputs[l]) {
            point.set(name, value_of(v, v.len().min(3)));
        }
        for (name, dx, dy) in &lane_derivs[l] {
            point.set_derivs(name, value_of(dx, dx.len()), value_of(dy, dy.len()));
        }
        let mut bound: Vec<(&str, Value)> = Vec::new();
        for (p, (name, b)) in layout.params.iter().zip(&bound_params) {
            let floats = match b {
                Some(v) if !p.varying => v.clone(),
                Some(_) => lane_params[l].iter().find(|(n, _)| n == name).expect("bound").1.clone(),
                None => continue,
            };
            bound.push((name.as_str(), value_of(&floats, p.components)));
        }
        for (name, s) in &bound_strings {
            bound.push((name.as_str(), Value::String(s.as_str().into())));
        }
        let mut host = lit_host();
        let r = match interp::run(m, &bound, &mut point, &mut host, limits) {
            Err(interp::InterpError::Budget) => {
                budget_met = true;
                continue;
            }
            r => r.expect("the interpreter runs"),
        };
        budget_met |= !r.stopped_loops.is_empty();
        if budget_met {
            continue;
        }
        printed.extend(host.printed);
        for g in layout.globals.iter().filter(|g| g.written) {
            let want = floats_of(point.get(g.name).expect("global"));
            let got = batch.global(g.name, l).expect("global");
            for (a, b) in got.iter().zip(&want) {
                assert!(close(*a, *b), "lane {l}: {} is {got:?}, the interpreter says {want:?}", g.name);
            }
        }
        for (p, (name, value)) in layout.params.iter().zip(&r.params) {
            if !p.output {
                continue;
            }
            if p.string {
                assert_eq!(batch.string_param(name), Some(value.s()), "lane {l}: output {name}");
                continue;
            }
            let want = floats_of(value);
            let got = batch.param(name, l).expect("param");
            for (a, b) in got.iter().zip(&want) {
                assert!(close(*a, *b), "lane {l}: output {name} is {got:?}, the interpreter says {want:?}");
            }
        }
    }
    // The same lines printed (the JIT prints statement by statement over a chunk's lanes, the
    // interpreter lane by lane: compared as multisets).
    if budget_met {
        return ran;
    }
    let mut jit_printed = jit_host.printed;
    jit_printed.sort();
    printed.sort();
    assert_eq!(jit_printed, printed, "printf output");
    // Inactive and padding lanes keep the sentinel's bits in every varying slot.
    let stride = batch.stride();
    for (i, x) in batch.varying().iter().enumerate() {
        let lane = i % stride;
        if lane >= lanes || !active[lane] {
            assert_eq!(x.to_bits(), SENTINEL, "inactive lane {lane} of slot {} was written", i / stride);
        }
    }
    ran
}

pub fn check(src: &str) {
    let m = module(src);
    let shader = jit::compile(&m).unwrap_or_else(|e| panic!("JIT: {e}\n{src}"));
    for (seed, lanes) in [(1, 13), (2, 64), (3, 64), (4, 1), (5, 7), (6, 13)] {
        for bind in [0.0, 1.0] {
            differential(&m, &shader, lanes, seed, bind);
        }
    }
}
