/*
 * dented.sl -- a battered metal look: turbulence makes large shallow dents
 * whose depth is controlled by a power curve, with an optional small
 * scratch pattern on top.
 *
 * Exercises: turbulence() from noises.h with DEFAULT_OCTAVES from
 * config.h, #ifndef and #if / #else, a locally #define'd and then
 * #undef'd macro, transform("shader", P), ntransform() to measure
 * lengths in shader space, pow() and abs(), += on P, N assigned
 * from calculatenormal(), and a user function with an output parameter.
 */
#include "noises.h"

#ifndef DENT_SCRATCHES
#define DENT_SCRATCHES 1
#endif

#define SCRATCHLINE(x, w) (1 - smoothstep(0, (w), abs(mod((x), 1) - .5)))

/* Scratch depth at p, and (as an output) the scratch direction used. */
float scratches(point p; float density; output vector scratchdir)
{
    scratchdir = normalize(vector(1, .3 * snoise(zcomp(p)), 0));
    float along = p . scratchdir;
    float line = SCRATCHLINE(along * density, .02);
    return line * step(.6, noise(p * .5));
}

displacement dented(
    float Km = 1;
    float power = 3;
    float frequency = 1;
    float maxoctaves = DEFAULT_OCTAVES;
    float scratchdepth = .002, scratchdensity = 40;)
{
    point Psh = transform("shader", P);
    float magnitude = 0;
    vector sdir;

    /* Large dents: turbulence raised to a power so most of it is flat. */
    magnitude = pow(turbulence(Psh * frequency, maxoctaves, 2, .5), power) * .25;

#if DENT_SCRATCHES
    magnitude += scratchdepth * scratches(Psh, scratchdensity, sdir)
                 * (1 + .1 * abs(xcomp(sdir)));
#else
    sdir = vector(0, 0, 0);
#endif

    /* Scale Km from shader space to current space along the normal. */
    normal Nsh = ntransform("shader", N);
    float shaderlen = length(Nsh) / max(length(N), 1.0e-6);
    P -= Km * magnitude * normalize(N) / shaderlen;
    N = calculatenormal(P);
}

#undef SCRATCHLINE
