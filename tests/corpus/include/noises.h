/*
 * noises.h -- signed noise, fractal sums (fBm, turbulence, ridged
 * multifractal), their filtered forms, and a cellular (Voronoi) basis.
 *
 * Exercises: include guards, #include of two other headers, function-like
 * macros over noise(), macros expanding to macros (filteredsnoise ->
 * snoise), #if / #elif with defined() and integer comparison, #undef and
 * redefinition, uniform loop counters, output function parameters,
 * cellnoise, triple-nested for loops.
 */
#ifndef NOISES_H
#define NOISES_H

#include "config.h"
#include "filterwidth.h"

/* Signed noise in [-1, 1]. */
#define snoise(x) (2 * noise(x) - 1)
#define snoise2(x, y) (2 * noise((x), (y)) - 1)
#define vsnoise(p) (2 * (vector noise(p)) - 1)

/* Noise that fades to its mean (zero) as the filter width grows. */
#define filteredsnoise(p, width) (snoise(p) * (1 - smoothstep(0.2, 0.75, (width))))
#define filteredvsnoise(p, width) (vsnoise(p) * (1 - smoothstep(0.2, 0.75, (width))))

/* Octave count: honour the shader's choice, but cap it. */
#if defined(NOISE_OCTAVES) && NOISE_OCTAVES > 12
#undef NOISE_OCTAVES
#define NOISE_OCTAVES 12
#elif !defined(NOISE_OCTAVES)
#define NOISE_OCTAVES DEFAULT_OCTAVES
#endif

/* Fractional Brownian motion: a sum of octaves of signed noise. */
float fBm(point p; uniform float octaves, lacunarity, gain)
{
    varying float sum = 0;
    varying point pp = p;
    uniform float amp = 1;
    uniform float i;

    for (i = 0; i < octaves; i += 1) {
        sum += amp * snoise(pp);
        amp *= gain;
        pp *= lacunarity;
    }
    return sum;
}

/* Vector-valued fBm, for warping domains. */
vector vfBm(point p; uniform float octaves, lacunarity, gain)
{
    varying vector sum = 0;
    varying point pp = p;
    uniform float amp = 1;
    uniform float i;

    for (i = 0; i < octaves; i += 1) {
        sum += amp * vsnoise(pp);
        amp *= gain;
        pp *= lacunarity;
    }
    return sum;
}

/* Turbulence: like fBm but summing |snoise|, which gives creases. */
float turbulence(point p; uniform float octaves, lacunarity, gain)
{
    varying float sum = 0;
    varying point pp = p;
    uniform float amp = 1;
    uniform float i;

    for (i = 0; i < octaves; i += 1) {
        sum += amp * abs(snoise(pp));
        amp *= gain;
        pp *= lacunarity;
    }
    return sum;
}

/*
 * Ridged multifractal: each octave is an inverted, sharpened |snoise|, and
 * its weight depends on the previous octave, so ridges grow detail while
 * valleys stay smooth.
 */
float ridged(point p; uniform float octaves, lacunarity, gain, offset)
{
    varying point pp = p;
    varying float signal = offset - abs(snoise(pp));
    varying float sum = signal * signal;
    varying float weight = 1;
    uniform float amp = 1;
    uniform float i;

    for (i = 1; i < octaves; i += 1) {
        pp *= lacunarity;
        amp *= gain;
        weight = clamp(signal * 2, 0, 1);
        signal = offset - abs(snoise(pp));
        signal *= signal * weight;
        sum += signal * amp;
    }
    return sum;
}

/*
 * fBm that stops adding octaves once they are finer than the filter width
 * (fw is the filter width of p, in the units of p).
 */
float filteredfBm(point p; float fw; uniform float octaves, lacunarity, gain)
{
    varying float sum = 0;
    varying point pp = p;
    varying float w = fw;
    varying float amp = 1;
    varying float i;        /* varying: the loop may break per point */

    for (i = 0; i < octaves; i += 1) {
        if (w > 1)
            break;
        sum += amp * filteredsnoise(pp, w);
        amp *= gain;
        pp *= lacunarity;
        w *= lacunarity;
    }
    return sum;
}

/*
 * Cellular noise (Worley): distance from p to the nearest of a set of
 * jittered feature points, one per unit cell.  The nearest feature point
 * itself is written to "nearest".
 */
float voronoi_f1(point p; float jitter; output point nearest)
{
    point cell = point(floor(xcomp(p)) + .5, floor(ycomp(p)) + .5,
                       floor(zcomp(p)) + .5);
    float best = 1.0e6;
    float i, j, k;

    nearest = cell;
    for (i = -1; i <= 1; i += 1) {
        for (j = -1; j <= 1; j += 1) {
            for (k = -1; k <= 1; k += 1) {
                point testcell = cell + vector(i, j, k);
                point pos = testcell + jitter * (vector cellnoise(testcell) - .5);
                vector offset = pos - p;
                float dist = offset . offset;
                if (dist < best) {
                    best = dist;
                    nearest = pos;
                }
            }
        }
    }
    return sqrt(best);
}

#endif /* NOISES_H */
