//! Strings in the packet JIT against the interpreter, lane by lane: uniform handles, strings that
//! differ between lanes, `format`, `concat` and `printf`.

mod common;

use common::check;

#[test]
fn strings_as_uniform_handles() {
    check(
        r#"
        surface t(string space = "world"; string other = "camera"; output varying float o = 0;
                  output string copy = "";)
        {
            string k = "hsv";
            if (space == "world") o = 1; else if (space != other) o = 2;
            if (k == "hsv" && other != "") o += 10;
            string pick = space == "object" ? space : other;
            copy = pick;
            o += (copy == other) ? 100 : 0;
            Ci = color(o);
        }
        "#,
    );
}

#[test]
fn varying_strings_select_format_and_split_calls_per_string() {
    // Strings that differ between lanes: assigned under varying conditions, selected, compared,
    // built by format/concat from varying values, matched, passed to and returned from functions,
    // indexed from arrays by varying indices, and used as texture names, space names, colour
    // spaces and environment names (calls run once per distinct string).
    check(
        r#"
        string pick(float x; string a, b) { return x > 0.5 ? a : b; }
        surface t(string tex = "grid"; string sp = "camera"; output varying float o = 0;
                  output varying color oc = 0; output varying point op = 0;)
        {
            string names[3] = {"missing", tex, "other"};
            string n = names[clamp(floor(s * 3), 0, 2)];
            string space = "shader";
            if (t > 0.3) space = sp;
            if (t > 0.7) space = "nowhere";
            string cs = pick(u, "hsv", "rgb");
            string label = format("%d-%s", floor(v * 4), n);
            string both = concat(label, "/", space);
            o = (n == "missing" ? 1 : 0) + (n != tex ? 10 : 0) + match("^1-", label) * 100
                + match("camera$", both) * 1000 + (label == "2-other" ? 10000 : 0);
            oc = color texture(n, s, t) + ctransform(cs, "rgb", color(s, t, 0.5)) + color environment(n, vector(u, v, 1));
            op = transform(space, P) + transform(space, "world", P) + vector "object" (s, 0, 0);
            float x = texture(names[1], s, t) + float texture(n[0], t, s);
            o += x + comp(ctransform(cs, color(s, t, u)), 1);
            if (u > 0.8)
                printf("%s %s %f\n", n, label, s);
            Ci = oc;
        }
        "#,
    );
}

#[test]
fn strings_format_concat_match_printf() {
    check(
        r#"
        surface t(string name = "quilt"; float k = 2; output string label = ""; output string f = "";
                  output varying float o = 0;)
        {
            uniform string a = concat("material(", name, ")");
            label = concat(a, "/", format("%d", k));
            f = format("%s %f %5.2f %c %p %m %g %s%%", name, k, 1 / 3, color(1, 0.5, 0.25), point(1, 2, 3),
                       matrix 1, k > 1, "");
            o = match("^q", name) + match("l.*t$", name) * 10 + match("x", "") * 100 + match("", name) * 1000;
            if (match("world", name) != 0) o += 5;
            printf("%s %f\n", label, k);
            if (s > 0.5) printf("lane at s=%f P=%p Cs=%c %s\n", s, P, Cs, f);
            printf("%f %d <%s>\n", t, k, a);
            Ci = color(o);
        }
        "#,
    );
}
