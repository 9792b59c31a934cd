/*
 * skin_layers.sl -- a stylised skin: a warm "wrapped" diffuse term that
 * lets light bleed past the terminator (cheap subsurface look), a red
 * scattering tint near the shadow edge, an oily Fresnel sheen, and pores
 * from cellular noise.
 *
 * Exercises: illuminance(P) over the whole sphere with a manual wrap
 * computation, the lightsource("__nonspecular") message inside the loop,
 * fresnel() with output arguments, voronoi_f1() from noises.h with an
 * output point argument, smoothstep, mix on colours, output varying shader
 * parameters written for AOVs, and uniform locals computed from uniform
 * parameters.
 */
#include "noises.h"

surface skin_layers(
    float Ka = .5, Kd = .8, Ks = .35, roughness = .2;
    float wrap = .3;
    float eta = 1.4;
    float porefreq = 120, poredepth = .15;
    color skincolor = color(.85, .62, .52);
    color scattercolor = color(.8, .2, .1);
    output varying color diffuseaov = 0;
    output varying color specularaov = 0;)
{
    normal Nn = normalize(N);
    normal Nf = faceforward(Nn, I);
    vector V = -normalize(I);
    vector In = normalize(I);
    uniform float wrapnorm = 1 / (1 + wrap);
    color diff = 0, spec = 0, scatter = 0;

    illuminance(P) {
        vector Ln = normalize(L);
        float ndotl = Ln . Nf;
        float nonspec = 0;
        lightsource("__nonspecular", nonspec);

        /* Wrapped Lambert: reaches zero at -wrap instead of at 0. */
        float wrapped = max(0, (ndotl + wrap) * wrapnorm);
        diff += Cl * wrapped;

        /* Light scattered near the terminator picks up a red tint. */
        scatter += Cl * (smoothstep(-wrap, 0, ndotl) - smoothstep(0, wrap, ndotl));

        if (ndotl > 0 && nonspec < 1) {
            vector H = normalize(Ln + V);
            spec += Cl * (1 - nonspec) * pow(max(0, Nf . H), 1 / roughness);
        }
    }

    /* Oily film: Fresnel-weighted sheen. */
    float Kr, Kt;
    fresnel(In, Nf, 1 / eta, Kr, Kt);

    /* Pores: small dark dots at Voronoi cell centres. */
    point nearest;
    float dpore = voronoi_f1(transform("object", P) * porefreq, .8, nearest);
    float pore = 1 - smoothstep(.05, .2, dpore);

    color Cskin = skincolor * (1 - poredepth * pore);
    diffuseaov = Kt * (Cskin * (Ka * ambient() + Kd * diff) + scattercolor * scatter * .25);
    specularaov = Ks * (Kr + .25) * spec;

    Oi = Os;
    Ci = Os * (diffuseaov + specularaov);
}
