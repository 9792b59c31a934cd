//! Control flow in the packet JIT against the interpreter, lane by lane: divergent branches and
//! ternaries, loops with varying and uniform bounds, `break` and `continue`, user functions with
//! outputs and early returns, arrays and components.

mod common;

use common::check;

#[test]
fn divergent_if_else_and_ternary() {
    check(
        r#"
        surface t(output varying float o = 0;)
        {
            if (s > 0.5) {
                Ci = Cs;
                if (t < 0.3) Ci *= 2; else Ci = color(t, 0, 0);
            } else if (u > 0.2 && v < 0.8 || s < 0.1) {
                Ci = color(1, 0, 1);
            } else {
                Ci = 0;
            }
            o = s > t ? s - t : (u < 0.5 ? u : -v);
            float k = 0;
            k = (s > 0.5) ? (o += 1) : (o -= 1);
            Oi = color(k, o, !(s > 0.3) ? 1 : 0);
        }
        "#,
    );
}

#[test]
fn uniform_variables_kept_per_lane_flow_into_uniform_variables() {
    // A `uniform` variable assigned in a light loop (or under a varying `if`) is kept per lane, and
    // so are the `uniform` variables computed from it, here through a function that reads it as
    // an `extern` (the pattern of shaders that draw numbers from a uniform counter).
    check(
        r#"
        surface t(float seed = 7; output varying float o = 0;)
        {
            uniform float counter = 0;
            uniform float next() {
                extern uniform float counter, seed;
                counter += 1;
                return cellnoise(counter, seed);
            }
            if (s > 0.5) counter = 10;
            uniform float i;
            for (i = 0; i < 3; i += 1) {
                uniform float r = next();
                uniform float scaled = r * 4;
                if (scaled < 2) o += scaled; else o -= r;
            }
            illuminance (P) {
                counter = 20;
                uniform float inside = next() + counter;
                o += inside;
            }
            Ci = color(o, counter, 0);
        }
        "#,
    );
}

#[test]
fn loops_with_varying_bounds_break_continue() {
    check(
        r#"
        surface t(float n = 6; output varying float o = 0; output varying float cnt = 0;)
        {
            float i, j, acc = 0;
            for (i = 0; i < s * 10; i += 1) {
                if (i > t * 8) break;
                if (mod(i, 2) == 1) continue;
                acc += i;
            }
            for (i = 0; i < n; i += 1) {
                for (j = 0; j < 5; j += 1) {
                    if (j > u * 5) continue 2;
                    if (i * j > v * 12) break 2;
                    cnt += 1;
                }
            }
            float x = s;
            while (x < 4) { x = x * 2 + 0.1; }
            o = acc + x;
            Ci = color(acc, cnt, i);
        }
        "#,
    );
}

#[test]
fn uniform_loops_and_branches() {
    check(
        r#"
        surface t(float n = 4; float gain = 2; output float uo = 0;)
        {
            float i, total = 0;
            for (i = 0; i < n; i += 1) {
                if (i == 2) continue;
                total += i * gain;
                if (total > 100) break;
            }
            uo = total;
            if (gain > 1) Ci = Cs * total; else Ci = Cs;
            Oi = color(total > 3 ? 1 : 0.5);
        }
        "#,
    );
}

#[test]
fn functions_with_outputs_and_returns() {
    check(
        r#"
        float twice(float x; output float y) { y = x + 1; return 2 * x; }
        float early(float x) {
            if (x > 0.5) return 1;
            float k;
            for (k = 0; k < 10; k += 1) {
                if (k * 0.1 > x) return k;
            }
            return -1;
        }
        color shade_it(color c; float a) { return c * a + color(a); }
        void bump_it(output point p; float amt) { p += amt * N; }
        surface t(output varying float o = 0; output varying float e = 0;)
        {
            float y;
            o = twice(s, y) + y * 10;
            e = early(t) + early(0.7);
            float scale = 10;
            float scaled(float x) { extern float scale; scale += 1; return x * scale; }
            o += scaled(u) + scale;
            point p = P;
            bump_it(p, 0.1);
            Ci = shade_it(Cs, v) + color(p);
            Oi = Os;
        }
        "#,
    );
}

#[test]
fn arrays_and_components() {
    check(
        r#"
        surface t(float w[3] = {0.2, 0.3, 0.5}; varying float vw[2] = {1, 2}; output varying float o = 0;)
        {
            float a[4] = {s, t, u, v};
            color cs[2] = {Cs, color(1, 0, 0)};
            float i = floor(s * 6) - 1;
            a[i] = a[i] * 10 + w[t * 3];
            a[2] += vw[u * 2];
            cs[1][2] = a[3];
            point p = P;
            p[1] = p[2] + p[t * 3];
            o = a[0] + a[1] + a[2] + a[3] + a[-1] + a[9] + cs[s * 2][1] + cs[1][2] + p[1];
            Ci = cs[1];
        }
        "#,
    );
}
