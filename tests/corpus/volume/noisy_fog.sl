/*
 * noisy_fog.sl -- patchy ground fog: the fog density varies in space with
 * fBm, so the eye ray is marched in a fixed number of steps, integrating
 * density and attenuating the surface colour behind it.
 *
 * Exercises: a volume (atmosphere) shader reading P, I and E-relative
 * geometry, a uniform for loop marching along -I, fBm() from noises.h,
 * transform() to "world" space, exp() of accumulated optical depth,
 * mix() on Ci and Oi, an output varying parameter, and the DEFAULT_SAMPLES
 * macro from config.h through noises.h.
 */
#include "noises.h"

volume noisy_fog(
    float fogdistance = 5;
    float noisefreq = .3, noisiness = .8;
    float groundheight = 0, fogheight = 3;
    float steps = DEFAULT_SAMPLES;
    color fogcolor = color(.7, .72, .75);
    output varying float density = 0;)
{
    vector Iw = vtransform("world", I);
    point Pend = transform("world", P);
    point Pstart = Pend - Iw;
    float raylen = length(Iw);
    float stepsize = raylen / steps;
    float tau = 0;
    uniform float i;

    for (i = 0; i < steps; i += 1) {
        point Pstep = Pstart + (i + .5) / steps * Iw;
        float h = ycomp(Pstep) - groundheight;
        float base = 1 - smoothstep(0, fogheight, h);
        float n = .5 + .5 * fBm(Pstep * noisefreq, 3, 2, .5);
        float d = base * mix(1, n, noisiness);
        tau += d * stepsize / fogdistance;
    }

    density = tau / max(raylen / fogdistance, 1.0e-6);
    float fogamount = 1 - exp(-tau);
    Ci = mix(Ci, fogcolor, fogamount);
    Oi = mix(Oi, color(1, 1, 1), fogamount);
}
