/*
 * fractals.h -- fractal noise sums: fBm with an early exit when the
 * octaves get smaller than the filter width, turbulence, Musgrave-style
 * ridged multifractal, and a vector fBm for domain warping.
 *
 * Exercises: include guard, #include of another guarded header (so a
 * shader that also includes it directly sees it twice), #if/#elif/#else
 * on a numeric macro, uniform loop counters and amplitudes with a
 * uniform break, a varying octave loop that breaks on the filter width, pow() with a uniform
 * negative exponent, signed-noise macros, vector-valued noise casts.
 */
#ifndef FRACTALS_H
#define FRACTALS_H

#include "aa_filters.h"

#define snoise(p) (2 * (noise(p)) - 1)
#define vsnoise(p) (2 * (vector noise(p)) - 1)
/* Signed noise that fades to zero once its features are smaller than a sample. */
#define filteredsnoise(p, fw) (snoise(p) * (1 - smoothstep(0.2, 0.75, (fw))))

#ifndef FRACTAL_DETAIL
#define FRACTAL_DETAIL 2
#endif

#if FRACTAL_DETAIL >= 3
#define MAX_OCTAVES 12
#elif FRACTAL_DETAIL == 2
#define MAX_OCTAVES 8
#else
#define MAX_OCTAVES 4
#endif

/*
 * fBm that stops adding octaves once a lane's octave is below the
 * sampling rate.  The break is varying, so the counter and amplitude
 * are declared varying too (a uniform may not change under varying
 * control flow).
 */
float fBm_aa(point p; float fw; uniform float octaves, lacunarity, gain)
{
    varying float sum = 0;
    varying point pp = p;
    varying float fwo = fw;
    varying float amp = 1;
    varying float i;

    for (i = 0; i < min(octaves, MAX_OCTAVES); i += 1) {
        if (fwo > 1)
            break;
        sum += amp * filteredsnoise(pp, fwo);
        amp *= gain;
        pp *= lacunarity;
        fwo *= lacunarity;
    }
    return sum;
}

/* Turbulence with a uniform early exit once the amplitude is negligible. */
float turbulence_aa(point p; float fw; uniform float octaves, lacunarity, gain)
{
    float sum = 0;
    point pp = p;
    float fwo = fw;
    uniform float amp = 1;
    uniform float i;

    for (i = 0; i < octaves; i += 1) {
        if (amp < 0.002)
            break;              /* uniform: every lane leaves together */
        sum += amp * abs(filteredsnoise(pp, fwo));
        amp *= gain;
        pp *= lacunarity;
        fwo *= lacunarity;
    }
    return sum;
}

/*
 * Ridged multifractal: each octave is weighted by the previous one, so
 * detail piles up on the ridges and valleys stay smooth.
 */
float ridgedmf(point p; uniform float octaves, lacunarity, H, offset, gain)
{
    float sig = offset - abs(snoise(p));
    sig *= sig;
    float result = sig;
    float weight = 1;
    point pp = p;
    uniform float i;

    for (i = 1; i < octaves; i += 1) {
        pp *= lacunarity;
        weight = clamp(sig * gain, 0, 1);
        sig = offset - abs(snoise(pp));
        sig = sig * sig * weight;
        result += sig * pow(lacunarity, -i * H);
    }
    return result;
}

/* Vector fBm for warping a lookup point. */
vector vfBm(point p; uniform float octaves, lacunarity, gain)
{
    vector sum = 0;
    point pp = p;
    uniform float amp = 1;
    uniform float i;

    for (i = 0; i < octaves; i += 1) {
        sum += amp * vsnoise(pp);
        amp *= gain;
        pp *= lacunarity;
    }
    return sum;
}

#endif /* FRACTALS_H */
