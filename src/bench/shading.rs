//! The shading benchmark behind `rtsl bench shade`: nanoseconds per shaded point for the library's
//! `plastic` (with its light loop) and a noise-heavy marble-like shader, run (a) by the JIT, (b) by
//! the reference interpreter and (c) as the same shader hand-written in Rust over the same SoA data,
//! all three in one process, plus the compile cost of every library shader.
//!
//! The renderer's side is the same for all three: an ambient light of 0.1 grey and a white distant
//! light from +z (`interp::TestHost`'s lights; the JIT gets them through a minimal `HostTable`, the
//! Rust code reads them from the same table once per chunk, as the JIT's helpers do).

use rtsl_compiler::abi::{
    BatchData, HostLight, HostTable, LightLanes, MessageOut, StrRef, CONE_ROWS, EVERY_LIGHT, MAX_LIGHTS,
};
use rtsl_compiler::interp::{self, Limits, ShadingPoint, TestHost, Value};
use rtsl_compiler::jit;
use rtsl_compiler::shadeops::{geom, noise, V3};
use std::ffi::c_void;
use std::path::Path;
use std::time::Instant;

/// The noise-heavy shader: four octaves of turbulence into a colour ramp, lit diffusely.
pub const NOISY_SOURCE: &str = r#"
surface noisy(float Kd = .8; float freq = 4;)
{
    point PP = freq * P;
    float turb = 0, amp = 1, i;
    for (i = 0; i < 4; i += 1) {
        turb += amp * abs(noise(PP) - 0.5);
        PP *= 2;
        amp *= 0.5;
    }
    color c = mix(color(.9, .9, .85), color(.2, .2, .3), smoothstep(0.1, 0.4, turb));
    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * c * Kd * diffuse(Nf);
}
"#;

const PLASTIC_SOURCE: &str = include_str!("../../stdlib_shaders/surface/plastic.sl");

/// One row of the report.
#[derive(Clone, Debug)]
pub struct ShadingRow {
    pub shader: &'static str,
    pub jit_ns: f64,
    pub interpreter_ns: f64,
    pub rust_ns: f64,
    /// Largest difference between the JIT's and the Rust code's `Ci` over all points.
    pub max_difference: f32,
}

/// Compile cost of one shader: source to callable code.
#[derive(Clone, Debug)]
pub struct CompileRow {
    pub name: String,
    pub micros: f64,
}

/// The lights every back end sees (`TestHost`'s).
const LIGHTS: [HostLight; 2] = [
    HostLight { l: [0.0; 3], cl: [0.1; 3], ol: [0.0; 3], ambient: 1, nondiffuse: 0.0, nonspecular: 0.0, id: 0 },
    HostLight {
        l: [0.0, 0.0, 1000.0],
        cl: [1.0; 3],
        ol: [0.0; 3],
        ambient: 0,
        nondiffuse: 0.0,
        nonspecular: 0.0,
        id: 1,
    },
];

unsafe extern "C" fn fixed_matrix(_: *mut c_void, _: StrRef, _: StrRef, out: *mut f32) -> u32 {
    let id: [f32; 16] = std::array::from_fn(|i| if i % 5 == 0 { 1.0 } else { 0.0 });
    // SAFETY: `out` holds 16 floats (the table's contract).
    unsafe { std::ptr::copy_nonoverlapping(id.as_ptr(), out, 16) };
    1
}

unsafe extern "C" fn fixed_lights(
    _: *mut c_void,
    _: StrRef,
    _: u32,
    mask: *const i32,
    _: *const f32,
    _: *const f32,
    out: *mut LightLanes,
    counts: *mut u32,
    pending: *mut u32,
) {
    for l in 0..4 {
        // SAFETY: 4 mask entries and counts, room for MAX_LIGHTS rows of lights (the table's
        // contract).
        unsafe {
            let active = *mask.add(l) != 0;
            *counts.add(l) = if active { 2 } else { 0 };
            *pending.add(l) = 0;
            if active {
                (*out).set_lane(l, &LIGHTS[0]);
                (*out.add(1)).set_lane(l, &LIGHTS[1]);
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
unsafe extern "C" fn no_texture(
    _: *mut c_void,
    _: u32,
    _: StrRef,
    _: *const i32,
    _: *const f32,
    _: *const f32,
    _: u32,
    _: *mut f32,
    ok: *mut u32,
) {
    // SAFETY: 4 flags.
    unsafe { std::ptr::write_bytes(ok, 0, 4) };
}

unsafe extern "C" fn no_rays(
    _: *mut c_void,
    _: u32,
    _: u32,
    _: *const i32,
    _: *const f32,
    _: *const f32,
    _: *const f32,
    _: *mut f32,
) {
}
unsafe extern "C" fn no_gather(
    _: *mut c_void,
    _: StrRef,
    _: u32,
    _: *const i32,
    _: *const f32,
    _: *const f32,
    _: *const f32,
    out: *mut f32,
) {
    // SAFETY: row 0 (the hit flags) has 4 floats: everything misses.
    unsafe { std::ptr::write_bytes(out, 0, 4) };
}
unsafe extern "C" fn no_depth(_: *mut c_void, _: *const i32, _: *const f32, _: *mut f32) {}
unsafe extern "C" fn no_ray_depth(_: *mut c_void) -> f32 {
    0.0
}
unsafe extern "C" fn no_message(_: *mut c_void, _: u32, _: u32, _: u32, _: StrRef, _: *mut MessageOut) -> u32 {
    0
}

unsafe extern "C" fn no_other_message(_: *mut c_void, _: u32, _: StrRef, _: *mut MessageOut) -> u32 {
    0
}
unsafe extern "C" fn no_name(_: *mut c_void, _: u32, _: StrRef) -> StrRef {
    StrRef::new("")
}
unsafe extern "C" fn no_print(_: *mut c_void, _: StrRef) {}

fn fixed_table() -> HostTable {
    HostTable {
        ctx: std::ptr::null_mut(),
        matrix: fixed_matrix,
        lights: fixed_lights,
        texture: no_texture,
        rays: no_rays,
        gather: no_gather,
        depth: no_depth,
        ray_depth: no_ray_depth,
        message: no_message,
        light_message: no_other_message,
        volume_message: no_other_message,
        shader_name: no_name,
        print: no_print,
        pixels: std::ptr::null(),
        batch_lights: std::ptr::null(),
    }
}

/// Deterministic inputs: points in the unit cube, unit normals, a viewer at (0.5, 0.5, 3).
struct Inputs {
    p: Vec<V3>,
    n: Vec<V3>,
    i: Vec<V3>,
}

fn inputs(count: usize) -> Inputs {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut inp = Inputs { p: Vec::new(), n: Vec::new(), i: Vec::new() };
    for _ in 0..count {
        let p = [next(), next(), next()];
        let n = geom::normalize([next() - 0.5, next() - 0.5, next() + 0.2]);
        inp.i.push([p[0] - 0.5, p[1] - 0.5, p[2] - 3.0]);
        inp.p.push(p);
        inp.n.push(n);
    }
    inp
}

fn module(name: &str, src: &str) -> Result<rtsl_compiler::Module, String> {
    let c = rtsl_compiler::compile_source(name, src, &rtsl_compiler::Options::default());
    let rendered = c.render();
    c.module.ok_or(rendered)
}

fn batches(shader: &jit::CompiledShader, inp: &Inputs) -> Vec<BatchData> {
    let mut out = Vec::new();
    for start in (0..inp.p.len()).step_by(64) {
        let lanes = 64.min(inp.p.len() - start);
        let mut b = shader.batch(lanes);
        for l in 0..lanes {
            let k = start + l;
            b.set_global("P", l, &inp.p[k]);
            b.set_global("N", l, &inp.n[k]);
            b.set_global("I", l, &inp.i[k]);
            b.set_global("Cs", l, &[1.0, 0.8, 0.6]);
            b.set_global("Os", l, &[1.0; 3]);
        }
        out.push(b);
    }
    out
}

/// The lights of one point from the table (what the Rust shaders read, once per chunk in `run`).
fn lights_of_chunk(table: &HostTable, p: &[f32; 12]) -> ([HostLight; 8], [u32; 4]) {
    let mut out = [LightLanes::default(); MAX_LIGHTS];
    let mut counts = [0u32; 4];
    let mask = [-1i32; 4];
    let mut every = [0.0f32; 4 * CONE_ROWS];
    every[12..].fill(EVERY_LIGHT);
    // SAFETY: the sizes the table's contract gives.
    unsafe {
        (table.lights)(
            table.ctx,
            StrRef::new(""),
            u32::MAX,
            mask.as_ptr(),
            p.as_ptr(),
            every.as_ptr(),
            out.as_mut_ptr(),
            counts.as_mut_ptr(),
            [0u32; 4].as_mut_ptr(),
        )
    };
    // The Rust shaders read lane `l`'s light `k` at `4k + l`.
    let first = std::array::from_fn(|i| out[i / 4].lane(i % 4));
    (first, counts)
}

fn plastic_rust(n: V3, i: V3, cs: V3, lights: &[HostLight], lane: usize, count: u32) -> V3 {
    let (ks, kd, ka, roughness) = (0.5f32, 0.5f32, 1.0f32, 0.1f32);
    let nn = geom::normalize(n);
    let nf = geom::faceforward(nn, i, nn);
    let v = geom::normalize(i).map(|x| -x);
    let (mut amb, mut dif, mut spec) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 3]);
    for k in 0..count as usize {
        let light = &lights[4 * k + lane];
        if light.ambient != 0 {
            amb = std::array::from_fn(|c| amb[c] + light.cl[c]);
            continue;
        }
        if !geom::in_hemisphere(light.l, nf) {
            continue;
        }
        let ln = geom::normalize(light.l);
        let d = geom::dot(ln, nf).max(0.0);
        let s = geom::specular_brdf(ln, nf, v, roughness);
        dif = std::array::from_fn(|c| dif[c] + light.cl[c] * d);
        spec = std::array::from_fn(|c| spec[c] + light.cl[c] * s);
    }
    std::array::from_fn(|c| cs[c] * (ka * amb[c] + kd * dif[c]) + ks * spec[c])
}

fn noisy_rust(p: V3, n: V3, i: V3, lights: &[HostLight], lane: usize, count: u32) -> V3 {
    let (kd, freq) = (0.8f32, 4.0f32);
    let mut pp = p.map(|x| freq * x);
    let (mut turb, mut amp) = (0.0f32, 1.0f32);
    for _ in 0..4 {
        turb += amp * (noise::noise3(pp) - 0.5).abs();
        pp = pp.map(|x| x * 2.0);
        amp *= 0.5;
    }
    let t = geom::smoothstep(0.1, 0.4, turb);
    let c: V3 = std::array::from_fn(|k| geom::mix([0.9, 0.9, 0.85][k], [0.2, 0.2, 0.3][k], t));
    let nn = geom::normalize(n);
    let nf = geom::faceforward(nn, i, nn);
    let mut dif = [0.0f32; 3];
    for k in 0..count as usize {
        let light = &lights[4 * k + lane];
        if light.ambient != 0 || !geom::in_hemisphere(light.l, nf) {
            continue;
        }
        let d = geom::dot(geom::normalize(light.l), nf).max(0.0);
        dif = std::array::from_fn(|j| dif[j] + light.cl[j] * d);
    }
    std::array::from_fn(|j| c[j] * kd * dif[j])
}

fn plastic_case(p: V3, n: V3, i: V3, l: &[HostLight], lane: usize, c: u32) -> V3 {
    let _ = p;
    plastic_rust(n, i, [1.0, 0.8, 0.6], l, lane, c)
}

/// One shader of the benchmark, set up once and runnable by each back end (criterion's
/// `benches/shading.rs` and [`shading_benchmark`] both use it).
pub struct ShadingCase {
    pub name: &'static str,
    module: rtsl_compiler::Module,
    shader: jit::CompiledShader,
    batches: Vec<BatchData>,
    inp: Inputs,
    table: HostTable,
    /// The Rust code's `Ci` per point (after [`ShadingCase::rust`]).
    ci: Vec<V3>,
}

impl ShadingCase {
    /// `"plastic"` (the library's) or `"noisy"` ([`NOISY_SOURCE`]) over `points` points.
    pub fn new(name: &str, points: usize) -> Result<ShadingCase, String> {
        let (name, src): (&'static str, &str) = match name {
            "plastic" => ("plastic", PLASTIC_SOURCE),
            "noisy" => ("noisy", NOISY_SOURCE),
            other => return Err(format!("no benchmark shader `{other}`")),
        };
        let module = module(name, src)?;
        let shader = jit::compile(&module).map_err(|e| e.to_string())?;
        let inp = inputs(points.max(64));
        let batches = batches(&shader, &inp);
        let ci = vec![[0.0; 3]; inp.p.len()];
        Ok(ShadingCase { name, module, shader, batches, inp, table: fixed_table(), ci })
    }

    pub fn points(&self) -> usize {
        self.inp.p.len()
    }

    /// Shades every point once with the JIT code.
    pub fn jit(&mut self) {
        for b in &mut self.batches {
            self.shader.shade_with_table(b, &self.table);
        }
    }

    /// Shades every point once with the hand-written Rust code over SoA arrays, the lights asked
    /// once per chunk of four.
    pub fn rust(&mut self) {
        // Locals, so that the loop keeps them in registers (as hand-written code would).
        let (plastic, inp, table, ci) = (self.name == "plastic", &self.inp, &self.table, &mut self.ci[..]);
        let count = inp.p.len();
        for c in 0..count.div_ceil(4) {
            let mut chunk_p = [0.0f32; 12];
            for l in 0..4 {
                let k = (4 * c + l).min(count - 1);
                let p = inp.p[k];
                (chunk_p[l], chunk_p[4 + l], chunk_p[8 + l]) = (p[0], p[1], p[2]);
            }
            let (lights, counts) = lights_of_chunk(table, &chunk_p);
            for (l, &n) in counts.iter().enumerate() {
                let k = 4 * c + l;
                if k < count {
                    // A direct call (inlined), as hand-written code would make.
                    ci[k] = if plastic {
                        plastic_case(inp.p[k], inp.n[k], inp.i[k], &lights, l, n)
                    } else {
                        noisy_rust(inp.p[k], inp.n[k], inp.i[k], &lights, l, n)
                    };
                }
            }
        }
    }

    /// Shades point `k` with the reference interpreter.
    pub fn interpreter(&self, k: usize) -> Result<(), String> {
        let k = k % self.inp.p.len();
        let kind = self.module.shader.as_ref().map(|s| s.kind).ok_or("no shader")?;
        let mut point = ShadingPoint::new(kind);
        point.set("P", Value::Triple(self.inp.p[k]));
        point.set("N", Value::Triple(self.inp.n[k]));
        point.set("I", Value::Triple(self.inp.i[k]));
        point.set("Cs", Value::Triple([1.0, 0.8, 0.6]));
        interp::run(&self.module, &[], &mut point, &mut TestHost::default(), Limits::default())
            .map(|_| ())
            .map_err(|e| e.to_string())
    }

    /// The largest difference between the JIT's and the Rust code's last `Ci`.
    pub fn max_difference(&self) -> f32 {
        let mut max = 0.0f32;
        for (b, start) in self.batches.iter().zip((0..self.inp.p.len()).step_by(64)) {
            for l in 0..b.lanes() {
                let j = b.global("Ci", l).unwrap_or_default();
                for (a, r) in j.iter().zip(self.ci[start + l]) {
                    max = max.max((a - r).abs());
                }
            }
        }
        max
    }
}

/// Measures the three back ends on `points` points, `repeats` times over (the interpreter on an
/// eighth of them: it is slow).
pub fn shading_benchmark(points: usize, repeats: usize) -> Result<Vec<ShadingRow>, String> {
    let mut rows = Vec::new();
    for name in ["plastic", "noisy"] {
        let mut case = ShadingCase::new(name, points)?;
        let count = case.points();
        let start = Instant::now();
        for _ in 0..repeats {
            case.jit();
        }
        let jit_ns = start.elapsed().as_nanos() as f64 / (repeats * count) as f64;
        let start = Instant::now();
        for _ in 0..repeats {
            case.rust();
        }
        let rust_ns = start.elapsed().as_nanos() as f64 / (repeats * count) as f64;
        let sample = (count / 8).max(1);
        let start = Instant::now();
        for k in 0..sample {
            case.interpreter(k)?;
        }
        let interpreter_ns = start.elapsed().as_nanos() as f64 / sample as f64;
        rows.push(ShadingRow {
            shader: case.name,
            jit_ns,
            interpreter_ns,
            rust_ns,
            max_difference: case.max_difference(),
        });
    }
    Ok(rows)
}

/// Source to callable code (front end and JIT) for every `.sl` file under `dir`, one thread.
pub fn compile_benchmark(dir: &Path) -> Result<Vec<CompileRow>, String> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries = std::fs::read_dir(&d).map_err(|e| format!("{}: {e}", d.display()))?;
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "sl") {
                files.push(p);
            }
        }
    }
    files.sort();
    let mut rows = Vec::new();
    for f in files {
        let start = Instant::now();
        let c = rtsl_compiler::compile_file(&f, &rtsl_compiler::Options::default())
            .map_err(|e| format!("{}: {e}", f.display()))?;
        let rendered = if c.ok() { String::new() } else { c.render() };
        let m = c.module.ok_or(rendered)?;
        jit::compile(&m).map_err(|e| format!("{}: {e}", f.display()))?;
        rows.push(CompileRow { name: f.display().to_string(), micros: start.elapsed().as_secs_f64() * 1e6 });
    }
    Ok(rows)
}
