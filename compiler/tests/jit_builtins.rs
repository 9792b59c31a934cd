//! Built-in functions in the packet JIT against the interpreter, lane by lane: every overload of
//! every built-in, splines, periodic noise, `filterstep` and `random`.

mod common;

use common::{check, differential};
use rtsl_compiler::back::jit;
use rtsl_compiler::{compile_source, Options};

/// A shader calling every overload of `bi` once, with arguments of exactly the overload's types
/// (locals seeded from the globals, so values vary per lane), or `None` for built-ins that only
/// make sense elsewhere (message passing into light shaders and the like is covered by the corpus).
fn every_overload_shader(bi: rtsl_compiler::builtins::Builtin) -> String {
    use rtsl_compiler::builtins::signatures;
    use rtsl_compiler::ir::BaseType as T;
    fn name(t: Option<T>) -> &'static str {
        match t {
            Some(T::Color) => "color",
            Some(T::Point) => "point",
            Some(T::Vector) => "vector",
            Some(T::Normal) => "normal",
            Some(T::Matrix) => "matrix",
            Some(T::String) => "string",
            _ => "float",
        }
    }
    let mut body = String::new();
    let mut sum = String::from("0");
    for (k, sig) in signatures(bi).iter().enumerate() {
        let mut args = Vec::new();
        for (j, p) in sig.params.iter().enumerate() {
            let ty = name(p.ty);
            let var = format!("a{k}_{j}");
            let init = match p.ty {
                Some(T::String) => format!("\"{}\"", ["grid", "shader", "catmull-rom", "%f %g"][j % 4]),
                Some(T::Matrix) => "matrix \"shader\" 1".to_string(),
                Some(T::Color | T::Point | T::Vector | T::Normal) => format!("{ty}(s + {j}, t * 2 - 1, u + 0.5)"),
                _ => format!("s * {} + t - 0.25", j + 1),
            };
            if p.array {
                body.push_str(&format!("    {ty} {var}[4] = {{{init}, {init}, {init}, {init}}};\n"));
            } else {
                body.push_str(&format!("    {ty} {var} = {init};\n"));
            }
            args.push(var);
        }
        let call = format!("{}({})", bi.name(), args.join(", "));
        match sig.ret {
            T::Void => body.push_str(&format!("    {call};\n")),
            T::String => body.push_str(&format!("    string r{k} = {call};\n    o += match(\"1\", r{k});\n")),
            T::Matrix => {
                body.push_str(&format!("    matrix r{k} = {call};\n"));
                sum.push_str(&format!(" + comp(r{k}, 1, 2) + comp(r{k}, 3, 0)"));
            }
            T::Float => {
                body.push_str(&format!("    float r{k} = float {call};\n"));
                sum.push_str(&format!(" + r{k}"));
            }
            t => {
                let ty = name(Some(t));
                body.push_str(&format!("    {ty} r{k} = {ty} {call};\n"));
                sum.push_str(&format!(" + comp(r{k}, 0) + comp(r{k}, 2)"));
            }
        }
        for (j, p) in sig.params.iter().enumerate() {
            if p.output && !p.array && matches!(p.ty, None | Some(T::Float)) {
                sum.push_str(&format!(" + a{k}_{j}"));
            }
        }
    }
    format!("surface every(output varying float o = 0;)\n{{\n{body}    o += {sum};\n    Ci = o;\n}}\n")
}

#[test]
fn every_builtin_overload_agrees_with_the_interpreter() {
    use rtsl_compiler::builtins::Builtin;
    let mut failed = Vec::new();
    let mut ran = 0;
    for bi in Builtin::ALL {
        let src = every_overload_shader(*bi);
        let c = compile_source("every.sl", &src, &Options::default());
        let ok = c.ok();
        let rendered = c.render();
        let Some(m) = c.module.filter(|_| ok) else {
            failed.push(format!("{}: does not check\n{src}\n{rendered}", bi.name()));
            continue;
        };
        match jit::compile(&m) {
            Ok(shader) => {
                for seed in 0..2 {
                    differential(&m, &shader, 13, seed, 0.0);
                }
                ran += 1;
            }
            Err(e) => failed.push(format!("{}: {e}", bi.name())),
        }
    }
    assert!(failed.is_empty(), "{} of {} built-ins:\n{}", failed.len(), Builtin::ALL.len(), failed.join("\n"));
    assert_eq!(ran, Builtin::ALL.len());
}

#[test]
fn splines_all_bases_forms_and_shapes() {
    check(
        r#"
        surface t(string basis = "bezier"; float knots[5] = {0, 1, 0.5, 2, 1};
                  varying float vk[4] = {0, 1, 2, 3};
                  output varying float o = 0; output varying color oc = 0; output float uo = 0;)
        {
            float x = s * 1.4 - 0.2;
            o = spline(x, 0, 1, 4, 2, 3) + spline("catmull-rom", t, 1, 2, 3, 4);
            o += spline("bspline", x, 5, -1, 2, 0, 3, 7) + spline("b-spline", u, 0, 1, 2, 3);
            o += spline("bezier", x, 1, 5, -3, 2, 8, 0, 6) + spline("Bezier", v, 1, 5, -3, 2, 100);
            o += spline("hermite", x, 1, 0, 3, 0, 2, 1) + spline("linear", x, -100, 10, 20, 40, 100);
            o += spline("constant", x, 1, 2, 3, 4, 5, 6) + spline("nonsense", x, 0, 1, 2, 3);
            o += spline(basis, x, knots) + spline(x, knots) + spline("linear", t, vk) + spline(basis, x, s, t, u, v);
            float k3[3] = {7, 8, 9};
            o += spline(x, k3) + spline("bezier", x * 3, vk);
            uo = spline(basis, 0.3, knots) + spline("hermite", 0.7, 1, 0, 3, 0, 2, 1);
            color cols[6] = {color(1, 0, 0), color(0, 1, 0), color(0, 0, 1), Cs, color(s, t, u), color(0.5)};
            oc = spline(x, color(1, 0, 0), color(0, 1, 0), Cs, color(0, 0, 1))
                + spline("bspline", t, cols) + spline(basis, u, cols) + spline("linear", 0.5, cols);
            point p = spline("catmull-rom", v, P, point(1, 2, 3), point(0), point(-1, 1, 0), P * 2);
            if (s > 0.5) oc += color spline("constant", t, vector(1), vector(2), vector(3), vector(4));
            Ci = oc + color(p);
        }
        "#,
    );
}

#[test]
fn pnoise_every_form() {
    check(
        r#"
        surface t(float per = 4; output varying float o = 0; output varying vector ov = 0;)
        {
            o = pnoise(s * 8, per) + pnoise(s * 8, t * 8, per, 3) + pnoise(P * 3, point(per, 2, 5))
              + pnoise(P * 3, u * 4, point(2, per, 3), 2) + float pnoise(1.5, per);
            ov = vector pnoise(s * 8, per) + vector pnoise(s * 8, t * 8, per, 3)
               + vector pnoise(P * 3, point(per, 2, 5)) + vector pnoise(P * 3, u * 4, point(2, 3, 4), per);
            color c = color pnoise(P, point(1, 1, 1));
            Ci = c + color(o);
        }
        "#,
    );
}

#[test]
fn filterstep_with_explicit_widths() {
    check(
        r#"
        surface t(float w = 0.1; output varying float o = 0; output float uo = 0;)
        {
            o = filterstep(0.5, s, "width", w) + filterstep(0.5, t, "width", u * 0.5);
            o += filterstep(0.3, s, s + v * 0.2) + filterstep(0.5, t, t - 0.1, "filter", "box");
            o += filterstep(0.5, s, "width", 0) + filterstep(0.5, s, "width", -1);
            o += filterstep(0.5, s, "swidth", w * 3) + filterstep(0.4, s, t, "width", w * 20);
            uo = filterstep(0.2, 0.25, "width", w) + filterstep(0.2, 0.25, 0.4) + filterstep(0.3, 0.25, 0.4, "swidth", 3);
            Ci = color(o);
        }
        "#,
    );
}

#[test]
fn random_per_lane_and_per_call() {
    check(
        r#"
        float jitter(float a) { return a + random() - 0.5; }
        surface t(output varying float o = 0; output varying float cnt = 0;)
        {
            o = random();
            if (s > 0.5) o += random() * 10;
            else { color c = random(); o += comp(c, 0) + comp(c, 2) * 100; }
            float i;
            for (i = 0; i < t * 5; i += 1) {
                if (random() > 0.5) { cnt += 1; continue; }
                o += jitter(i);
            }
            o += jitter(0.25);
            point p = point random();
            Ci = color(p) + color(random());
        }
        "#,
    );
}

/// `random()` assigned to a uniform variable is one number for the batch's chunk (RenderMan's grid),
/// the first running lane's; assigned to a varying one it is each lane's own. (The interpreter runs
/// one point at a time, so the differential harness cannot compare the uniform case.)
#[test]
fn random_in_uniform_context_is_one_number_a_chunk() {
    let run = |src: &str| {
        let m = common::module(src);
        let shader = rtsl_compiler::back::jit::compile(&m).expect("the JIT compiles it");
        let mut batch = shader.batch(8);
        for l in 0..8 {
            batch.set_active(l, l != 0);
            assert!(batch.set_seed(l, 0x9e37_79b9 * (l as u64 + 1)));
        }
        let mut host = common::lit_host();
        shader.shade_with(&mut batch, &mut host);
        (0..8).map(|l| batch.param("o", l).expect("an output")[0]).collect::<Vec<f32>>()
    };
    let shared = run("surface t(output varying float o = 0;) { uniform float r = random(); o = r; Ci = o; }\n");
    let own = run("surface t(output varying float o = 0;) { o = random(); Ci = o; }\n");
    // Lanes 1 to 3 share lane 1's number (lane 0 does not run); lanes 4 to 7 share lane 4's.
    for chunk in [1..4, 4..8] {
        assert!(chunk.clone().all(|l| shared[l] == own[chunk.start]), "{shared:?} {own:?}");
    }
    assert_ne!(own[1], own[2], "varying, each lane has its own");
}
