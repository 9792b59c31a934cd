//! Lights in the packet JIT against the interpreter, lane by lane: illuminance loops and shading
//! models, light shaders (`illuminate`, `solar`), and the other shader types (imager, volume).

mod common;

use common::check;

#[test]
fn lights_loops_and_shading_models() {
    check(
        r#"
        surface t(float Ks = 0.5; float roughness = 0.2; output varying float cnt = 0;)
        {
            normal Nf = faceforward(normalize(N), I);
            vector V = -normalize(I);
            color c = 0;
            illuminance(P, Nf, 1.5707964) {
                cnt += 1;
                c += Cl * (normalize(L) . Nf);
            }
            illuminance("-ambient", P) {
                if (s > 0.5) break;
                cnt += 10;
            }
            illuminance(P, vector(0, 0, 1), 0.1 + s) { cnt += 100; }
            Ci = c + ambient() + diffuse(Nf) + Ks * specular(Nf, V, roughness) + phong(Nf, V, 20);
            Oi = Os;
        }
        "#,
    );
}

/// Light loops run many times and nested: each loop's lights are kept at its nesting depth, so a
/// loop replaces the set of the last one at its depth and the inner loops' sets, never one that
/// an enclosing loop still reads.
#[test]
fn light_loops_in_loops_and_nested_read_their_own_lights() {
    check(
        r#"
        surface t(output varying float cnt = 0;)
        {
            color c = 0;
            float i;
            for (i = 0; i < 40; i += 1) {
                illuminance(P + vector(i * 0.01, 0, 0)) {
                    c += Cl * (1 + i);
                    vector outer = L;
                    illuminance("-ambient", P - vector(0, i * 0.02, 0)) {
                        cnt += 1;
                        c += Cl * length(L - outer);
                    }
                    c += color(length(L - outer));
                }
            }
            Ci = c;
        }
        "#,
    );
}

#[test]
fn light_shaders_illuminate_and_solar() {
    check(
        r#"
        light spot(point from = point(0, 0, 0); vector axis = vector(0, 0, 1); float angle = 0.8;)
        {
            illuminate(from, axis, angle) {
                Cl = color(1, 0.5, 0.25) / (L . L + 1);
            }
        }
        "#,
    );
    check(
        r#"
        light pt(point from = point(0.2, 0.1, 0);)
        {
            illuminate(from) { Cl = color(length(L)); }
        }
        "#,
    );
    check(
        r#"
        light sun(vector to = vector(0, 0, -1);)
        {
            solar(to, 0) { Cl = color(1, 1, 0.9) * s; }
        }
        "#,
    );
}

#[test]
fn imager_and_volume_shaders() {
    check(
        r#"
        imager background(color background = 1;)
        {
            Ci += (1 - alpha) * background;
            Oi = 1;
            alpha = 1;
        }
        "#,
    );
    check(
        r#"
        volume fogish(float distance = 1; color background = 0;)
        {
            float d = 1 - exp(-length(I) / distance);
            Ci = mix(Ci, background, d);
            Oi = mix(Oi, color(1, 1, 1), d);
        }
        "#,
    );
}

/// A light category that differs between lanes (a string chosen per point) runs the loop once per
/// distinct category, each under the lanes that asked for it, as the interpreter does per point;
/// `break` and a `return` inside leave only their own lanes.
#[test]
fn illuminance_with_a_category_per_lane() {
    check(
        r#"
        float firstlight(string cat) { illuminance(cat, P) { return comp(Cl, 1); } return -1; }
        surface t(output varying float cnt = 0; output varying float first = 0;)
        {
            string cat = s < 0.3 ? "key" : (s < 0.6 ? "-key" : "fill");
            if (t > 0.8) cat = "";
            color c = 0;
            illuminance(cat, P, N, 1.2) {
                cnt += 1;
                if (u > 0.9) break;
                c += Cl;
            }
            first = firstlight(t < 0.5 ? "fill" : "-fill");
            Ci = c;
        }
        "#,
    );
}

#[test]
fn light_parameters_into_uniform_variables_declared_outside_the_loop() {
    // The idiom of RenderMan's shading models: `__nondiffuse` and friends read into a uniform
    // declared before the loop (kept per lane: each lane's light answers for it), and values
    // computed from it assigned to other uniform variables.
    check(
        r#"
        surface t(output varying float o = 0;)
        {
            uniform float nondiffuse = 0, nonspecular = 0;
            color c = 0;
            illuminance (P, N, PI / 2) {
                if (lightsource("__nondiffuse", nondiffuse) == 0)
                    nondiffuse = 0;
                lightsource("__nonspecular", nonspecular);
                uniform float weight = 1 - nondiffuse;
                c += weight * Cl * max(0, normalize(L) . normalize(N));
                o += nonspecular + weight;
            }
            Ci = c;
        }
        "#,
    );
}
