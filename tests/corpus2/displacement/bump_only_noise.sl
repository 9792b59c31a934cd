/*
 * bump_only_noise.sl -- a classic bump-only "hammered metal" pattern:
 * the point is never moved; only the shading normal is recomputed from a
 * virtually displaced point, and the difference between N and Ng is
 * kept so smooth-shaded geometry stays smooth.
 *
 * Exercises: N = normalize(calculatenormal(P + amp * normalize(N))),
 * the (N - Ng) correction, ntransform("object", N) to measure object
 * scale, transform("object", P), filterwidthp() fading fine detail,
 * noise over a point with an added float (4D noise), cellnoise
 * dents, Du()/Dv() of a float pattern, and uniform parameters.
 */
#include "fractals.h"

displacement bump_only_noise(
    float Km = 0.01;
    float frequency = 10;
    float dentsize = 0.3, dentdepth = 1;
    float animspeed = 0;
    uniform float octaves = 4;)
{
    point Po = transform("object", P) * frequency;
    float fw = filterwidthp(Po);

    /* Hammer dents: one round dent per cell, randomly placed. */
    point cell = point(floor(xcomp(Po)), floor(ycomp(Po)), floor(zcomp(Po)));
    point centre = cell + point cellnoise(cell);
    float d = distance(Po, centre);
    float dent = -dentdepth * (1 - smoothstep(0, dentsize, d));

    /* Fine ripples over time, faded when they get smaller than a sample. */
    float ripple = fBm_aa(Po * 4, fw * 4, octaves, 2, 0.5)
                 + 0.2 * (2 * float noise(Po * 8, time * animspeed) - 1) * (1 - smoothstep(0.1, 0.4, fw * 8));

    float h = dent + 0.3 * ripple;

    /* Express Km in object-space units. */
    normal Nn = normalize(N);
    float objscale = length(ntransform("object", Nn));
    float amp = Km * h / max(objscale, 1.0e-6);

    normal Ndiff = Nn - normalize(Ng);
    N = normalize(calculatenormal(P + amp * Nn)) + Ndiff;

    /* Slope of the height field, for debugging very steep dents. */
    float slope = abs(Du(h) * du) + abs(Dv(h) * dv);
    if (slope > 10)
        N = Nn;
}
