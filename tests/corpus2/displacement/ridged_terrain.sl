/*
 * ridged_terrain.sl -- mountain terrain displacement: ridged
 * multifractal peaks above a flattened "sea level", eroded gullies from
 * turbulence, and fine fBm detail that stops adding octaves once they are
 * below the sampling rate.  Displaces along the normal in world units.
 *
 * Exercises: ridgedmf(), turbulence_aa() and fBm_aa() from a header with
 * MAX_OCTAVES chosen by #if on FRACTAL_DETAIL given on the command line
 * or defaulted, P += ...; N = calculatenormal(P);, transform("shader",
 * P), vtransform("world", N) to express the amount in world units,
 * filterwidthp() on the lookup point, a smooth max (softclamp) as a
 * user function, mix() of floats, and a uniform float array of
 * per-band weights indexed by a uniform loop counter.
 */
#include "fractals.h"

/* Smoothly clamp x from below at floor, with a soft knee of width k. */
float softfloor(float x, fl, k)
{
    float h = clamp(0.5 + 0.5 * (x - fl) / k, 0, 1);
    return mix(fl, x, h) + k * h * (1 - h);
}

displacement ridged_terrain(
    float Km = 0.3;
    float frequency = 0.5;
    uniform float octaves = 7;
    float H = 1, lacunarity = 2, offset = 1, gain = 2;
    float sealevel = 0.3, shore = 0.05;
    float erosion = 0.25;
    float detail = 0.05;
    uniform float bandweights[4] = {1, 0.6, 0.3, 0.15};)
{
    point PP = transform("shader", P) * frequency;
    float fw = filterwidthp(PP);

    float peaks = ridgedmf(PP, min(octaves, MAX_OCTAVES), lacunarity, H, offset, gain);
    float h = 0.25 * peaks;

    /* Gullies cut deeper where the terrain is high. */
    float gullies = turbulence_aa(PP * 3, fw * 3, 5, 2, 0.5);
    h -= erosion * smoothstep(0.4, 1, h) * gullies;

    /* Banded extra relief, weights from an array parameter. */
    uniform float b;
    float banded = 0;
    for (b = 0; b < 4; b += 1)
        banded += bandweights[b] * sin(ycomp(PP) * 6.2831853 * pow(2, b) + peaks);
    h += 0.02 * banded;

    /* Flatten below sea level with a soft shore. */
    h = softfloor(h, sealevel, shore);

    /* Fine detail only where it can be resolved. */
    h += detail * fBm_aa(PP * 16, fw * 16, 6, 2, 0.5);

    /* Amount in world units. */
    normal Nn = normalize(N);
    float worldscale = length(vtransform("world", vector Nn));
    P += Nn * (Km * h / max(worldscale, 1.0e-6));
    N = calculatenormal(P);
}
