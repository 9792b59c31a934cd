/*
 * shade_models.h -- local illumination loops that honour the message
 * passing conventions of production lights: __nondiffuse,
 * __nonspecular, light categories and per-light shadow reporting.
 *
 * Exercises: include guard, #include of a sibling header, extern
 * declarations of shader globals inside plain functions, illuminance
 * with and without a category string (including a "-name" exclusion),
 * lightsource() reading float and colour outputs of lights, output
 * function parameters, specularbrdf(), functions returning colours.
 */
#ifndef SHADE_MODELS_H
#define SHADE_MODELS_H

#include "macros_util.h"

/* Lambert that skips lights flagged __nondiffuse. */
color diffuse_msg(normal Nn)
{
    extern point P;
    color C = 0;
    illuminance(P, Nn, PI / 2) {
        float nondiff = 0;
        lightsource("__nondiffuse", nondiff);
        C += (1 - nondiff) * Cl * max(0, normalize(L) . Nn);
    }
    return C;
}

/*
 * Blinn-ish highlight from every light except those in category
 * "nospec", scaled down for lights flagged __nonspecular.
 */
color specular_msg(normal Nn; vector V; float roughness)
{
    extern point P;
    color C = 0;
    illuminance("-nospec", P, Nn, PI / 2) {
        float nonspec = 0;
        lightsource("__nonspecular", nonspec);
        C += (1 - nonspec) * Cl * specularbrdf(normalize(L), Nn, V, roughness);
    }
    return C;
}

/* A sharp-edged glossy highlight, as in Advanced RenderMan's "glossy". */
color specular_glossy(normal Nn; vector V; float roughness, sharpness)
{
    extern point P;
    float w = 0.18 * (1 - sharpness);
    color C = 0;
    illuminance(P, Nn, PI / 2) {
        float nonspec = 0;
        lightsource("__nonspecular", nonspec);
        if (nonspec < 1) {
            vector H = normalize(normalize(L) + V);
            C += Cl * (1 - nonspec) *
                 smoothstep(0.72 - w, 0.72 + w, pow(max(0, Nn . H), 1 / roughness));
        }
    }
    return C;
}

/*
 * Diffuse light split into what arrives and what would arrive without
 * shadows, for lights that publish __unshadowed_Cl.  Returns the lit
 * colour; the unshadowed total comes back through an output argument.
 */
color diffuse_shadowsplit(normal Nn; output color unshadowed)
{
    extern point P;
    color lit = 0;
    unshadowed = 0;
    illuminance(P, Nn, PI / 2) {
        float cosang = max(0, normalize(L) . Nn);
        color ucl = Cl;
        lightsource("__unshadowed_Cl", ucl);
        lit += Cl * cosang;
        unshadowed += ucl * cosang;
    }
    return lit;
}

#endif /* SHADE_MODELS_H */
