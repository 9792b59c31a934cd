//! The renderer's services in the packet JIT against the interpreter (through `TestHost` for both
//! back ends): textures, environments, shadows, rays, `gather`, messages, the volumes on either
//! side, 3D textures, point clouds, photon maps and the pixels of a pixel shader's image.

mod common;

use common::{check, module};
use rtsl_compiler::back::jit;
use rtsl_compiler::interp::TestHost;

#[test]
fn textures_rays_and_messages() {
    check(
        r#"
        surface t(string tex = "grid.tx"; output varying float o = 0; output varying float found = 0;)
        {
            color c = texture(tex) + color texture(tex, s * 2, t) + color texture("missing", s, t, "fill", 0.5);
            float x = float texture(tex[1], s, t) + texture(tex, s, t, "channel", 2);
            c += color environment("sky", I) + color environment("missing", I, "fill", 0.25);
            x += shadow("shad", P) + float trace(P, N) + occlusion(P, N) + occlusion(P, N, 8);
            c += trace(P, reflect(I, N)) + transmission(P, point(0, 0, 0)) + indirectdiffuse(P, N, 4);
            x += float visibility(P, point(1, 1, 1)) + raydepth();
            color kd = 0;
            float fmt[3];
            string r = "";
            found = surface("Kd", kd) + option("Format", fmt) * 10 + rendererinfo("renderer", r) * 100;
            found += attribute("identifier:name", r) * 1000 + (r == "rtsl" ? 10000 : 0);
            if (shadername() != "") found += 100000;
            o = x + fmt[0] + fmt[2];
            Ci = c + kd;
        }
        "#,
    );
}

#[test]
fn texture_channels_the_map_lacks_read_the_fill_value() {
    // The test host's textures have three channels: alpha and beyond read "fill" (varying here, so
    // each lane's own), also when filtered over a footprint and when the lookup starts past them.
    check(
        r#"
        surface t(string tex = "grid.tx"; output varying float o = 0; output varying float o2 = 0;)
        {
            color c = color texture(tex[1], s, t, "fill", 0.75) + color texture(tex[2], s, t, "fill", u);
            c += color texture(tex, s, t, "channel", 2 * u, "fill", v, "blur", 0.2 * t);
            o = float texture(tex[3], s, t, "fill", 0.5 + u) + float texture(tex[7], s, t);
            o2 = float texture(tex, s, t, "channel", 3, "fill", 0.25, "width", 4);
            Ci = c;
        }
        "#,
    );
}

#[test]
fn rayinfo_reads_the_ray_parameters() {
    // Into varying and uniform variables, through the `user:` namespace, of each type; an unknown
    // name leaves its variable alone, and "relevance" reads 1 unless set.
    check(
        r#"
        surface t(output varying float o = 0; output varying float found = 0;)
        {
            float q = -1, d = -1, r = -1, missing = 7;
            uniform float uq = -1;
            color tint = 0;
            string label = "";
            found = rayinfo("q", q) + 2 * rayinfo("user:tint", tint) + 4 * rayinfo("label", label);
            found += 8 * rayinfo("depth", d) + 16 * rayinfo("relevance", r) + 32 * rayinfo("nope", missing);
            found += 64 * rayinfo("q", uq) + 128 * rayinfo("q", tint[1]);
            o = q + d + r + missing + uq + (label == "hero" ? 100 : 0);
            Ci = tint;
        }
        "#,
    );
}

#[test]
fn shadow_lookups_pass_their_region_and_options() {
    // The test host's shadow() is a function of every field of the query (the point, the four
    // corners, each option), so the JIT and the interpreter agree only when both pass the same.
    check(
        r#"
        surface t(float b = 0.05; output varying float o = 0; output varying float o2 = 0;)
        {
            o = shadow("shad", P) + shadow("shad", P * 2, "bias", b, "samples", 4 + s);
            o += shadow("shad", P, "blur", 0.1, "tblur", 0.3 * t, "width", 2, "swidth", 0.5);
            o2 = shadow("shad", P, P + dPdu, P + dPdv, P + dPdu + dPdv, "sblur", 0.2);
            point q = P + vector(u, v, 0);
            if (u > 0.3)
                o2 += float shadow("shad", q, "twidth", 3);
            Ci = color shadow("shad", transform("shader", P));
        }
        "#,
    );
}

#[test]
fn environment_lookups_pass_their_footprint_channel_and_options() {
    // The test host's environment() is moved by every field of the query (the direction's change
    // over a pixel, each option) and answers the fill past its three channels, so the JIT and the
    // interpreter agree only when both pass the same.
    check(
        r#"
        surface t(string sky = "sky.tx"; output varying float o = 0; output varying float o2 = 0;)
        {
            vector R = reflect(I, normalize(N));
            color c = color environment(sky, R) + color environment(sky, R * (1 + s), "blur", 0.1 * t);
            c += color environment(sky, R, "width", 2, "swidth", 0.5, "tblur", 0.3, "fill", 0.7);
            o = float environment(sky[1], R) + float environment(sky, R, "channel", 2 + s);
            o += float environment(sky[3], R, "fill", 0.4) + environment("missing", R, "fill", 0.25 + t);
            o2 = float environment(sky, R, R + dPdu, R + dPdv, R + dPdu + dPdv, "sblur", 0.2);
            if (u > 0.3)
                c += color environment(sky, vector(u, v, 1), "twidth", 3, "width", 0);
            Ci = c;
        }
        "#,
    );
}

#[test]
fn incident_and_opposite_ask_the_volume_on_each_side() {
    // The test host answers "side" 1 inside and 2 outside, and "ior" inside only; the globals I and
    // Ng are random per lane, so lanes see both sides.
    check(
        r#"
        surface t(output varying float a = 0; output varying float b = 0; output varying float c = 0;)
        {
            float side = 0, ior = 0;
            a = incident("side", side) * 10 + side;
            b = opposite("side", side) * 10 + side;
            c = incident("ior", ior) + opposite("ior", ior) * 2 + ior + incident("side", ior);
            color nope = 0;
            if (incident("side", nope) == 0 && opposite("nosuch", side) == 0)
                c += 100;
            Ci = color(a, b, c);
        }
        "#,
    );
}

#[test]
fn texture3d_grid_lookups() {
    // The test host's grids are the ramp x/4 + y/2 + z/8; "missing" cannot be read (fill).
    check(
        r#"
        surface t(string grid = "ramp.grid"; output varying float a = 0; output varying color b = 0;)
        {
            a = texture3d(grid, P) + texture3d("missing", P * 2, "fill", 0.25 + s);
            if (u > 0.5)
                b = color texture3d(grid, transform("shader", P));
            else
                b = texture3d("missing", P);
            Ci = b + a;
        }
        "#,
    );
    let mut host = TestHost::default();
    use rtsl_compiler::interp::Services;
    assert_eq!(host.texture3d("ramp.grid", [4.0, 2.0, 8.0]), Some(3.0));
    assert_eq!(host.texture3d("missing", [0.0; 3]), None);
}

#[test]
fn photon_map_lookups_pass_the_point_the_normal_and_the_estimator() {
    // The test host's "caustic" map answers a function of every argument; other maps are black.
    check(
        r#"
        surface t(float k = 30; output varying color a = 0;)
        {
            normal Nf = faceforward(normalize(N), I);
            a = photonmap("caustic", P, Nf) + photonmap("caustic", P * 2, Nf, "estimator", k + s);
            if (u > 0.5)
                a += photonmap("caustic", P) + photonmap("caustic.pmap", P, Nf);
            Ci = a;
        }
        "#,
    );
}

#[test]
fn pixel_shaders_read_other_pixels() {
    // The test host's image is 8 x 6 pixels, each channel a function of the pixel; "missing" is no
    // channel (0). A float context reads the first component; a colour cast reads all three.
    check(
        r#"
        pixel t(output varying float a = 0;)
        {
            float x = xcomp(P), y = ycomp(P);
            a = pixelvalue("z", x + 1, y - 1) + pixelvalue("objectid", x, y) * 100;
            if (pixelvalue("objectid", x - 1, y) == pixelvalue("objectid", x, y) - 1 && x > 2)
                a += pixelvalue("missing", x, y) + 1000;
            Ci = color pixelvalue("Ci", x - 2, y + 3) + pixelvalue("alpha", x, y);
        }
        "#,
    );
}

#[test]
fn gather_samples_outputs_branches_and_loop_exits() {
    // The test host's ceiling (z = P.z + 10) is hit by rays with a positive z component: axes
    // along N (random) and cones from 0.3 to 2.3 radians give hits and misses in one chunk.
    // Varying sample counts (0 to 5, and NaN-free negatives), options, every output kind,
    // `break`/`continue` in both branches, a `return` from a function, and "samplepattern".
    check(
        r#"
        float firsthit(point p; vector d; float cone)
        {
            float len = -1;
            gather("illuminance", p, d, cone, 8, "ray:length", len) {
                return len;
            }
            return -2;
        }
        surface t(float Kd = 0.5; string dist = "cosine"; output varying float o = 0;
                  output varying color oc = 0; output varying vector ov = 0;)
        {
            color hitc = 0, sum = 0, opac = 0;
            float len = 0, nhit = 0, nmiss = 0, k = 0;
            vector dir = 0; point org = 0, hp = 0; normal hn = 0;
            float arr[3] = {7, 8, 9};
            float cone = 0.3 + 2 * s;
            gather("illuminance", P, N, cone, floor(t * 6) - 0.5,
                   "surface:Ci", hitc, "surface:Oi", opac, "ray:length", len, "ray:direction", dir,
                   "ray:origin", org, "surface:P", hp, "surface:N", hn, "maxdist", 8 + 20 * u,
                   "bias", v * 0.01, "distribution", dist, "label", "x", "ray:length", arr[1],
                   "surface:Ci", len) {
                sum += hitc * opac + color(hp * 0.01 + hn);
                nhit += 1;
                if (len > 14) break;
                k += len;
            } else {
                nmiss += 1;
                ov += dir + org * 0.1;
                if (nmiss > 2) continue;
                k -= 1;
            }
            float pat = 0;
            gather("samplepattern", P, vector(0, 0, 1), 0.5, 3, "ray:direction", dir, "surface:Ci", hitc) {
                pat += zcomp(dir) + comp(hitc, 0);
            }
            o = nhit * 100 + nmiss * 10 + k + arr[1] + pat + firsthit(P, N, cone);
            oc = sum * Kd;
            ov += dir;
            Ci = oc;
        }
        "#,
    );
}

/// `gather` parameter names computed when the shader runs (per lane) and a category and
/// distribution that differ between lanes: each option and output applies under the lanes whose
/// name is its own, as the interpreter decides per point.
#[test]
fn gather_with_computed_names_and_strings_per_lane() {
    check(
        r#"
        surface t(string far = "maxdist"; output varying float o = 0; output varying vector ov = 0;
                  output varying color oc = 0;)
        {
            string out = s < 0.5 ? "surface:N" : "ray:direction";
            string opt = t < 0.5 ? far : "bias";
            string cname = u < 0.5 ? "surface:Ci" : "surface:Oi";
            string dist = v < 0.5 ? "cosine" : "uniform";
            string cat = s < 0.25 ? "samplepattern" : "illuminance";
            vector d = 0; color c = 0; float len = 0;
            gather(cat, P, N, 0.3 + 2 * t, 4, out, d, opt, 5 + 20 * u, cname, c, "ray:length", len,
                   "distribution", dist) {
                o += len;
                ov += d;
                oc += c;
            } else {
                o -= 1;
            }
        }
        "#,
    );
}

/// Aqsis's `occlusion(map, P, N, samples, ...)` traces like `occlusion(P, N, ...)`: its map and
/// positional sample count are not read, its "samples" option is.
#[test]
fn aqsis_occlusion_with_a_map_name_traces() {
    check(
        r#"
        light envlight(string filename = "occlmap.sm"; float samples = 8;
                       output varying float o = 0; output varying float same = 0;)
        {
            o = occlusion(filename, Ps, Ns, 0, "samples", samples, "bias", 0.01);
            same = o - occlusion(Ps, Ns, "samples", samples);
            Cl = 1 - o;
        }
        "#,
    );
}

#[test]
fn point_clouds_return_zero_and_are_reported_once() {
    let src = r#"
        surface t(output varying float o = 0; output varying color c = 1;)
        {
            if (s > 2) o = bake3d("cloud.ptc", "", P, N, "value", s);
            o += texture3d("cloud.ptc", P, N, "value", o) + 1;
            c = photonmap("global", P, N);
        }
    "#;
    check(src);
    let m = module(src);
    let shader = jit::compile(&m).expect("compiles");
    let mut batch = shader.batch(8);
    shader.shade_with(&mut batch, &mut TestHost::default());
    assert_eq!(batch.param("o", 3), Some(vec![1.0]));
    // A photon map the renderer does not have is black, and no error.
    assert_eq!(batch.param("c", 5), Some(vec![0.0; 3]));
    let errors = shader.runtime_errors();
    // `bake3d` sits under a condition no lane meets: only the call that ran is reported.
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].contains("`texture3d` at"), "{errors:?}");
    assert!(errors.iter().all(|e| e.contains("not supported")), "{errors:?}");
    shader.shade_with(&mut batch, &mut TestHost::default());
    assert!(shader.runtime_errors().is_empty(), "reported once");
}

#[test]
fn prmans_bake_is_accepted_returns_zero_and_is_reported_once() {
    let src = r#"
        surface t(output varying float o = 0;)
        {
            color c = color(s, t, 1);
            o = bake("out.bake", s, t, c) + bake("f.bake", s, t, 0.5) + 1;
            Ci = c;
        }
    "#;
    check(src);
    let shader = jit::compile(&module(src)).expect("compiles");
    let mut batch = shader.batch(4);
    shader.shade_with(&mut batch, &mut TestHost::default());
    assert_eq!(batch.param("o", 2), Some(vec![1.0]));
    let errors = shader.runtime_errors();
    assert_eq!(errors.len(), 2, "each call site once: {errors:?}");
    assert!(errors.iter().all(|e| e.contains("`bake` at") && e.contains("not supported")), "{errors:?}");
}
