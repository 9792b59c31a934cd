/*
 * ridged_stone.sl -- weathered sandstone: ridged multifractal strata
 * warped by vector fBm, banded through a colour spline, with darker
 * turbulent pitting and lichen patches that fade out with distance.
 *
 * Exercises: a header included twice (fractals.h pulls in
 * aa_filters.h, which is also included directly), FRACTAL_DETAIL set
 * before the include to pick the #if branch, ridgedmf()/vfBm()/
 * turbulence_aa()/fBm_aa() with uniform octave counts, the
 * filterwidthp() macro on a shader-space point, spline() over a colour
 * array, a uniform float array parameter, transform("shader", P) and a
 * user "frequency" scale, and smoothstep masks combined with mix().
 */
#define FRACTAL_DETAIL 3
#include "aa_filters.h"
#include "fractals.h"
#include "aa_filters.h"

surface ridged_stone(
    float Ka = 1, Kd = 0.9, Ks = 0.05, roughness = 0.3;
    float frequency = 1.5;
    uniform float octaves = 6;
    float warp = 0.3;
    float H = 0.9, offset = 1, gain = 2;
    color bands[6] = {color(0.76, 0.6, 0.42), color(0.7, 0.5, 0.33),
                      color(0.82, 0.7, 0.52), color(0.6, 0.42, 0.28),
                      color(0.78, 0.64, 0.47), color(0.66, 0.48, 0.32)};
    float pitting = 0.4;
    color lichencolor = color(0.5, 0.55, 0.3);
    float lichen = 0.3;
    uniform float lacunarities[2] = {2.0, 2.17};)
{
    point PP = frequency * transform("shader", P);
    float fw = filterwidthp(PP);

    /* Domain warp, then strata. */
    point Pw = PP + warp * vfBm(PP, 4, lacunarities[0], 0.5);
    float strata = ridgedmf(point(0, ycomp(Pw) * 0.5, 0) + 0.2 * Pw, min(octaves, MAX_OCTAVES),
                            lacunarities[1], H, offset, gain);
    float bandpos = clamp(0.35 * strata, 0, 1);
    color Ct = spline(bandpos, bands);

    /* Pits: dark where turbulence peaks. */
    float pits = turbulence_aa(PP * 6, fw * 6, octaves, 2, 0.5);
    Ct *= 1 - pitting * smoothstep(0.55, 0.8, pits);

    /* Lichen: low-frequency fBm threshold, faded by filter width. */
    float lmask = smoothstep(0.1, 0.3, fBm_aa(PP * 0.7 + 13.1, fw * 0.7, 5, 2, 0.5));
    Ct = mix(Ct, lichencolor, lichen * lmask * (1 - smoothstep(0.1, 0.5, fw)));

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * specular(Nf, -normalize(I), roughness));
}
