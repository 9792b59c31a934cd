use super::*;
use crate::compile_source;

fn run_src(src: &str, bound: &[(&str, Value)]) -> (ShadingPoint, RunResult, TestHost) {
    let c = compile_source("test.sl", src, &crate::Options::default());
    assert!(c.ok(), "does not compile:\n{}", c.render());
    let m = c.module.expect("compiles");
    let kind = m.shader.as_ref().map(|s| s.kind).unwrap_or(ShaderKind::Surface);
    let mut point = ShadingPoint::new(kind);
    let mut host = TestHost::default();
    let r = run(&m, bound, &mut point, &mut host, Limits::default()).expect("runs");
    (point, r, host)
}

fn ci(p: &ShadingPoint) -> V3 {
    p.get("Ci").map(Value::v3).unwrap_or_default()
}

fn close(a: V3, b: V3) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5)
}

#[test]
fn matte_lit_by_the_test_host() {
    let src = include_str!("../../../stdlib_shaders/surface/matte.sl");
    let (p, _, _) = run_src(src, &[]);
    // Ka * ambient (0.1) + Kd * diffuse (the distant light straight on) = 1 + 0.1.
    assert!(close(ci(&p), [1.1; 3]), "{:?}", ci(&p));
    let (p, _, _) = run_src(src, &[("Kd", Value::Float(0.5))]);
    assert!(close(ci(&p), [0.6; 3]), "{:?}", ci(&p));
}

#[test]
fn control_flow_functions_and_outputs() {
    let src = r#"
        float twice(float x; output float y) { y = x + 1; return 2 * x; }
        surface t(output varying float o = 0; float n = 5;)
        {
            float acc = 0, i, j, extra;
            for (i = 0; i < n; i += 1) {
                for (j = 0; j < n; j++) {
                    if (j == 2) continue;
                    if (i == 3) break 2;
                    acc += 1;
                }
            }
            float arr[3] = {1, 2, 3};
            arr[1] = twice(arr[2], extra);
            float scale = 10;
            float scaled(float x) { extern float scale; scale += 1; return x * scale; }
            o = acc * 1000 + arr[1] * 100 + extra * 10 + scaled(1) - 11 + scale - 11;
            Ci = color "hsv" (0, 0, 1);
            printf("%f done\n", acc);
        }
    "#;
    let (p, r, host) = run_src(src, &[]);
    // 3 outer iterations x 4 inner counts (j = 2 skipped), arr[1] = 6, extra = 4, scale ends at 11.
    assert_eq!(r.params[0], ("o".to_string(), Value::Float(12.0 * 1000.0 + 600.0 + 40.0 + 11.0 - 11.0 + 0.0)));
    assert!(close(ci(&p), [1.0; 3]), "value 1, saturation 0 is white: {:?}", ci(&p));
    assert_eq!(host.printed.len(), 1);
    assert!(host.printed[0].starts_with("12"), "{:?}", host.printed);
}

#[test]
fn light_loops_and_cones() {
    let src = r#"
        surface t()
        {
            color sum = 0;
            float count = 0;
            illuminance(P, N, radians(10)) { sum += Cl; count += 1; }
            illuminance(P, -N, radians(10)) { count += 100; }
            Ci = sum + count;
        }
    "#;
    let (p, _, _) = run_src(src, &[]);
    assert!(close(ci(&p), [2.0; 3]), "one light within the cone, none behind: {:?}", ci(&p));
}

#[test]
fn runaway_loops_stop_with_an_error() {
    let c = compile_source(
        "t.sl",
        "surface t() { float x = 0; while (1) { x += 1; } Ci = x; }",
        &crate::Options::default(),
    );
    let m = c.module.expect("compiles");
    let mut point = ShadingPoint::new(ShaderKind::Surface);
    let r = run(&m, &[], &mut point, &mut TestHost::default(), Limits { steps: 1000 });
    assert_eq!(r.err(), Some(InterpError::Budget));
}

#[test]
fn the_small_regex_matcher() {
    use crate::shadeops::format::regex_match;
    assert!(regex_match("^foo", "foobar"));
    assert!(!regex_match("^bar", "foobar"));
    assert!(regex_match("o*b", "foobar"));
    assert!(regex_match("ar$", "foobar"));
    assert!(regex_match("f.o", "xfoo"));
    assert!(!regex_match("z", "foobar"));
}
