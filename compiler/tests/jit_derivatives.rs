//! Derivatives in the packet JIT against the interpreter, lane by lane: every derivative built-in,
//! the difference rule, an analytic surface, texture footprints and bump mapping.

mod common;

use common::{check, differential, module, value_of};
use rtsl_compiler::back::jit;
use rtsl_compiler::interp::{self, Limits, ShadingPoint, TestHost};

#[test]
fn derivatives_agree_with_the_interpreter() {
    // Every derivative built-in, on values that reach them through the rules: arithmetic, user
    // functions (value, output and captured parameters, returns under varying conditions),
    // loops, arrays, selects, space casts, compound assignments and the built-ins with rules.
    check(
        r#"
        float wave(float x) { if (x > 0.5) return sin(x * 7); return cos(x * 3) * x; }
        void bend(output point p; float k) { p += vector(0, 0, k * xcomp(p) * ycomp(p)); }
        surface t(float amp = 0.3; output varying float o = 0; output varying vector ov = 0;
                  output varying normal on = 0; output varying float fa = 0;)
        {
            point q = P + N * amp * wave(s);
            bend(q, 2);
            float arr[3], i;
            for (i = 0; i < 3; i += 1) arr[i] = u * (i + 1) + v * v;
            float a = arr[1] * (s > 0.3 ? exp(t) : sqrt(abs(u - 0.5)));
            a += min(u, v, s) * max(t, u) + clamp(u * 3, 0.2, 0.9) + mix(s, t, v);
            vector dir = normalize(vector "object" (q)) * length(q - P);
            point w = transform("object", q);
            o = Du(a) + Dv(a) * 2 + Deriv(a, v) + Du(comp(dir, 1)) + filterstep(0.5, a);
            o += filterstep(0.3, u, "filter", "gaussian") + Dv(xcomp(w));
            ov = Du(dir) + Dv(q);
            on = calculatenormal(q);
            fa = area(q) + area(P);
            Ci = color(Du(s), Dv(t), Du(u) + Dv(v));
        }
        "#,
    );
}

#[test]
fn difference_rule_derivatives_agree_with_the_interpreter() {
    // noise, the space transforms and the other built-ins differentiated by a central difference
    // (`ir::deriv::has_difference_rule`), as bump mapping uses them.
    check(
        r#"
        surface t(float amp = 0.2; output varying normal nb = 0; output varying float o = 0;
                  output varying vector ov = 0;)
        {
            point pp = 4 * transform("object", P);
            float h = (float noise(pp) - .5) + .5 * (float pnoise(2 * pp, point(8, 8, 8)) - .5);
            vector n3 = vector noise(pp * 0.5);
            nb = calculatenormal(P + amp * h * normalize(N));
            o = Du(smoothstep(0.2, 0.8, u)) + Dv(distance(P, point(1, 2, 3)))
                + Du(spline(u, 0, 0.3, 0.9, 1)) + Dv(radians(degrees(v)))
                + Du(pow(u + 1, 2.5)) + Dv(log(v + 2)) + Du(tan(u)) + Dv(asin(v * 0.5))
                + Du(acos(u * 0.5)) + Dv(atan(v, u + 1)) + Du(inversesqrt(u + 1))
                + Du(mod(u * 4, 1)) + Dv(mod(v * 3, 0.5));
            ov = Du(vtransform("object", n3)) + Dv(reflect(normalize(I), normalize(N)))
                + Du(rotate(P, u, point(0, 0, 0), point(0, 1, 0)));
            Ci = color(o, 0, 1);
        }
        "#,
    );
}

/// Found by `random_expressions_agree`: where no argument moves along a screen direction the
/// derivative is zero, also where the function is NaN (pow of a negative base); the JIT's central
/// difference gave NaN - NaN.
#[test]
fn a_zero_tangent_gives_a_zero_difference_derivative_even_where_the_function_is_nan() {
    let e = "pow(min(a, xcomp(P)), a)";
    let src = format!(
        "surface t(float a = 0.5; varying float w = 0.25; output varying float o = 0, od = 0;) \
         {{ o = {e}; od = Du(o) + Dv(o) * 0.5; Ci = color(o, o * 0.5, 1 - o); }}"
    );
    let m = module(&src);
    let shader = jit::compile(&m).unwrap_or_else(|err| panic!("JIT: {err}\n{src}"));
    differential(&m, &shader, 13, 213, 0.5);
    differential(&m, &shader, 16, 214, 1.0);
}

#[test]
fn derivatives_of_an_analytic_surface() {
    // P = (u, v, uv) built from u and v: Du(P) = (1, 0, v), Dv(P) = (0, 1, u),
    // calculatenormal(P) = (-v, -u, 1) (Ng agrees with dPdu ^ dPdv), area = du dv |(-v, -u, 1)|.
    // Through built-ins with a difference rule: Du(smoothstep(-1, 2, u)) = 2 w (1 - w) with
    // w = (u + 1) / 3, up to the central difference's error; a noise bump turns the normal.
    let m = module(
        "surface t(output varying vector pu = 0, pv = 0; output varying normal n = 0; output varying float ar = 0;
                   output varying float sm = 0; output varying normal bn = 0;)
         { point q = point(u, v, u * v); pu = Du(q); pv = Dv(q); n = calculatenormal(q); ar = area(q);
           sm = Du(smoothstep(-1, 2, u));
           bn = calculatenormal(q + normal(0, 0, 1) * 0.2 * float noise(q * 4)); }",
    );
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(5);
    for l in 0..5 {
        let (u, v) = (0.1 * l as f32, 0.9 - 0.1 * l as f32);
        assert!(batch.set_global("u", l, &[u]) && batch.set_global("v", l, &[v]));
        assert!(batch.set_global("du", l, &[0.01]) && batch.set_global("dv", l, &[0.02]));
        assert!(batch.set_global("dPdu", l, &[1.0, 0.0, 0.0]) && batch.set_global("dPdv", l, &[0.0, 1.0, 0.0]));
        assert!(batch.set_global("Ng", l, &[0.0, 0.0, 1.0]));
        assert!(batch.set_global_derivs("u", l, &[0.3], &[0.1]));
        assert!(batch.set_global_derivs("v", l, &[-0.05], &[0.2]));
    }
    // The raw layout a renderer fills: u's d/dy of lane 2.
    let (slot, stride) = (batch.global_slot("u").expect("u is varying"), batch.stride());
    assert_eq!(batch.derivs_mut()[(2 * slot + 1) * stride + 2], 0.1);
    shader.shade(&mut batch);
    let near = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5);
    for l in 0..5 {
        let (u, v) = (0.1 * l as f32, 0.9 - 0.1 * l as f32);
        assert!(near(&batch.param("pu", l).unwrap(), &[1.0, 0.0, v]), "lane {l}: {:?}", batch.param("pu", l));
        assert!(near(&batch.param("pv", l).unwrap(), &[0.0, 1.0, u]), "lane {l}: {:?}", batch.param("pv", l));
        assert!(near(&batch.param("n", l).unwrap(), &[-v, -u, 1.0]), "lane {l}: {:?}", batch.param("n", l));
        let want = 0.01 * 0.02 * (v * v + u * u + 1.0f32).sqrt();
        assert!(near(&batch.param("ar", l).unwrap(), &[want]), "lane {l}: {:?}", batch.param("ar", l));
        let sm = batch.param("sm", l).unwrap()[0];
        let w = (u + 1.0) / 3.0;
        assert!((sm - 2.0 * w * (1.0 - w)).abs() < 0.01, "lane {l}: Du(smoothstep) {sm}");
    }
    let bumped = (0..5)
        .filter(|&l| {
            let (u, v) = (0.1 * l as f32, 0.9 - 0.1 * l as f32);
            let bn = batch.param("bn", l).unwrap();
            bn.iter().zip([-v, -u, 1.0]).any(|(a, b)| (a - b).abs() > 1e-2)
        })
        .count();
    assert!(bumped >= 4, "the noise bump turned the normal on only {bumped} of 5 lanes");
    // Without derivatives (a fresh batch), every derivative is 0.
    let mut batch = shader.batch(4);
    shader.shade(&mut batch);
    assert_eq!(batch.param("pu", 0).unwrap(), vec![0.0; 3]);
}

#[test]
fn setting_a_component_carries_its_derivatives() {
    // q = (u, v, 0) with z set to uv: calculatenormal(q) = (-v, -u, 1), as for point(u, v, uv);
    // by setzcomp, setcomp and on an element of an array of points, in both back ends.
    let src = "surface t(output varying normal a = 0, b = 0, c = 0; output varying vector d = 0;)
         { point q = point(u, v, 0); setzcomp(q, u * v); a = calculatenormal(q);
           point r = point(u, 0, 0); setcomp(r, 1, v); setcomp(r, 2, u * v); b = calculatenormal(r);
           point ps[2]; ps[1] = point(u, v, 0); setzcomp(ps[1], u * v); c = calculatenormal(ps[1]);
           vector w = 0; setxcomp(w, u); setycomp(w, 2 * v); d = Du(w); }";
    let m = module(src);
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(3);
    for l in 0..3 {
        let (u, v) = (0.2 * l as f32 + 0.1, 0.7 - 0.2 * l as f32);
        assert!(batch.set_global("u", l, &[u]) && batch.set_global("v", l, &[v]));
        assert!(batch.set_global_derivs("u", l, &[1.0], &[0.0]));
        assert!(batch.set_global_derivs("v", l, &[0.0], &[1.0]));
    }
    shader.shade(&mut batch);
    let near = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5);
    for l in 0..3 {
        let (u, v) = (0.2 * l as f32 + 0.1, 0.7 - 0.2 * l as f32);
        for name in ["a", "b", "c"] {
            let n = batch.param(name, l).unwrap();
            assert!(near(&n, &[-v, -u, 1.0]), "lane {l}: {name} = {n:?}");
        }
        assert!(near(&batch.param("d", l).unwrap(), &[1.0, 0.0, 0.0]), "lane {l}: {:?}", batch.param("d", l));
    }
    check(src);
}

#[test]
fn texture_footprints_from_derivatives() {
    // The test host averages a lookup whose footprint exceeds a checker cell, so the outputs depend
    // on the footprint both back ends pass: every form, with the width and blur options.
    check(
        r#"
        surface t(output varying color a = 0, b = 0, c = 0, d = 0, f = 0, g = 0; output varying float e = 0;)
        {
            a = texture("grid.tx");
            b = texture("grid.tx", s * 3, t * u * 4);
            c = texture("grid.tx", s, t, "width", 2 + 4 * u, "blur", v * 0.1);
            d = texture("grid.tx", s, t, s + 0.1 * u, t, s, t + 0.2 * v, s, t, "swidth", 1, "twidth", 3);
            e = float texture("grid.tx"[1], s * 2, t, "fill", 0.5);
            f = texture("grid.tx", s, t, "tblur", v * 0.3, "blur", 0.01);
            g = texture("grid.tx", s, t, "sblur", u * 0.3) + texture("grid.tx", s, t, "blur", 0.2, "sblur", 0);
        }
        "#,
    );
    let mut host = TestHost::default();
    use rtsl_compiler::interp::Services;
    let fp = interp::TextureFootprint { dsdx: 0.1, dtdx: 0.0, dsdy: 0.1, dtdy: 0.0, sblur: 0.0, tblur: 0.0 };
    assert_eq!(host.texture_filtered("grid.tx", 0.01, 0.01, &fp, 0, 1), Some(vec![0.5]));
    // Blur in t alone widens the lookup as much as blur in both (the test host's rule).
    let still = interp::TextureFootprint::default();
    let blurred = interp::TextureFootprint { tblur: 0.2, ..still };
    assert_ne!(host.texture_filtered("grid.tx", 0.01, 0.01, &still, 0, 1), Some(vec![0.5]));
    assert_eq!(host.texture_filtered("grid.tx", 0.01, 0.01, &blurred, 0, 1), Some(vec![0.5]));
}

#[test]
fn bump_agrees_lane_by_lane_across_height_steps() {
    // Lanes straddling the test host's checkerboard edge at s = 1/8 (heights 1 then 0), where
    // `bump` differences across cells, and lanes inside a cell; random lanes go through `check`.
    let src = r#"
        surface t(string map = "bumps"; output varying normal o = 0;)
        {
            o = bump(map, normalize(N), dPdu, dPdv);
            Ci = color(o);
        }
    "#;
    check(src);
    let m = module(src);
    let shader = jit::compile(&m).expect("compiles");
    let step = rtsl_compiler::shadeops::geom::BUMP_STEP;
    let ss = [0.125 - step / 2.0, 0.125 - 2.0 * step, 0.125 + step / 2.0, 0.3, 0.25 - step / 4.0, 0.01, 0.99, 0.5];
    let mut batch = shader.batch(ss.len());
    let lane_globals = |s: f32| {
        [
            ("s", vec![s]),
            ("t", vec![0.01]),
            ("N", vec![0.2, 0.1, 1.0]),
            ("dPdu", vec![1.0, 0.0, 0.1]),
            ("dPdv", vec![0.0, 2.0, 0.0]),
        ]
    };
    for (l, s) in ss.iter().enumerate() {
        for (name, v) in lane_globals(*s) {
            batch.set_global(name, l, &v);
        }
    }
    shader.shade_with(&mut batch, &mut TestHost::default());
    let mut bumped = 0;
    for (l, s) in ss.iter().enumerate() {
        let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
        for (name, v) in lane_globals(*s) {
            point.set(name, value_of(&v, v.len()));
        }
        let r = interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
        let want = r.params[1].1.v3();
        let got = batch.param("o", l).expect("o");
        assert_eq!(got, want.to_vec(), "lane {l} (s = {s})");
        bumped += usize::from(want != rtsl_compiler::shadeops::geom::normalize([0.2, 0.1, 1.0]));
    }
    assert_eq!(bumped, 2, "the two lanes less than a step short of an edge are bumped");
}

/// `mod` is linear between its wraps: the width rmannotes' `repeat(x, f)` (`mod(x * f, 1)`) gives
/// `filterwidth` is `f` times the width of `x`, as on a RenderMan grid, not 0 (which left filtered
/// pulse trains dividing by a zero width); across a wrap the footprint's difference crosses it.
#[test]
fn mod_is_differentiated_between_its_wraps() {
    let m = module(
        r#"
        surface t(output varying float o = 0; output varying float w = 0;)
        {
            o = Du(mod(u * 4, 1));
            // filterwidth.h's `filterwidth`.
            w = abs(Du(mod(u * 4, 1)) * du) + abs(Dv(mod(u * 4, 1)) * dv);
        }
        "#,
    );
    let run = |u: f32| -> (f32, f32) {
        let mut point = ShadingPoint::new(m.shader.as_ref().expect("shader").kind);
        point.set("u", value_of(&[u], 1));
        point.set("v", value_of(&[0.5], 1));
        point.set("du", value_of(&[0.01], 1));
        point.set("dv", value_of(&[0.01], 1));
        point.set_derivs("u", value_of(&[0.01], 1), value_of(&[0.0], 1));
        point.set_derivs("v", value_of(&[0.0], 1), value_of(&[0.01], 1));
        let r = interp::run(&m, &[], &mut point, &mut TestHost::default(), Limits::default()).expect("runs");
        (r.params[0].1.f(), r.params[1].1.f())
    };
    // Between wraps (4u = 1.2): the derivative of 4u.
    let (du, width) = run(0.3);
    assert!((du - 4.0).abs() < 1e-3, "Du {du}");
    assert!((width - 0.04).abs() < 1e-4, "filterwidth {width}");
    // A footprint across the wrap at 4u = 1 differences across it.
    let (du, _) = run(0.25);
    assert!(du < -50.0, "Du across the wrap {du}");
}
