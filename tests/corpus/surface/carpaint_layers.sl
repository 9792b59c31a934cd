/*
 * carpaint_layers.sl -- a metallic car paint built from three layers: a
 * base coat whose colour shifts with viewing angle, sparkling metallic
 * flakes, and a clear coat with Fresnel reflections.
 *
 * Exercises: spline() with the "bezier" basis over colours, cellnoise
 * giving a per-flake normal perturbation, voronoi_f1() with an output
 * point, MaterialClearcoat and LocIllumGlossy from material.h, trace()
 * limited by rayinfo("depth") and raydepth(), fresnel() with seven
 * arguments via FresnelRays() in raytrace.h, token-pasted parameter
 * names through LAYERPARAM, and uniform/varying locals.
 */
#include "material.h"
#include "raytrace.h"
#include "noises.h"

surface carpaint_layers(
    float Ka = .3;
    float LAYERPARAM(Kd, base) = .7;
    float LAYERPARAM(Ks, flake) = .8;
    float LAYERPARAM(Kr, coat) = 1;
    float flakefreq = 400, flakedensity = .4, flakespread = .35;
    float coatroughness = .02, eta = 1.5;
    uniform float maxdepth = 2;
    color facecolor = color(.55, .02, .03);
    color midcolor = color(.35, .01, .05);
    color edgecolor = color(.08, .0, .06);)
{
    normal Nf = faceforward(normalize(N), I);
    vector In = normalize(I);
    vector V = -In;
    float facing = max(0, Nf . V);

    /* Base coat: colour travels from face to edge along a Bezier curve. */
    color Cbase = color spline("bezier", 1 - facing,
                               facecolor, facecolor, midcolor, edgecolor);
    color base = Kd_base * Cbase * (Ka * ambient() + diffuse(Nf));

    /* Clear coat Fresnel split: reflected and transmitted rays. */
    float Kr, Kt;
    vector R, T;
    FresnelRays(In, Nf, 1 / eta, Kr, Kt, R, T);
    float throughcoat = Kt * max(0, -(T . Nf));

    /* Flakes: each Voronoi cell is a flake with its own tilted normal. */
    point nearest;
    float dflake = voronoi_f1(transform("object", P) * flakefreq, 1, nearest);
    float isflake = step(float cellnoise(nearest), flakedensity) * (1 - smoothstep(.3, .5, dflake));
    vector tilt = flakespread * (vector cellnoise(nearest + 3) - .5);
    normal Nflake = normalize(Nf + tilt);
    color flakes = Ks_flake * isflake * LocIllumGlossy(Nflake, V, .01, .8) * Cbase;
    flakes *= .5 + .5 * throughcoat;

    /* Clear coat over both, plus a traced reflection if not too deep. */
    color coat = MaterialClearcoat(Nf, base + flakes, eta, coatroughness);

    uniform float depthnow = 0;
    rayinfo("depth", depthnow);
    color refl = 0;
    if (depthnow < maxdepth && raydepth() < maxdepth)
        refl = trace(P, R);

    Oi = Os;
    Ci = Os * (coat + Kr_coat * Kr * refl);
}
