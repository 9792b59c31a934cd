/*
 * ao_occlusion.sl -- diffuse surface lit by direct lights plus ray-traced
 * ambient occlusion and one-bounce indirect diffuse light, with the
 * occlusion written to an output parameter for compositing.
 *
 * Exercises: occlusion(P, N, samples) with optional "maxdist" and
 * "coneangle" parameters, indirectdiffuse(P, N, samples), samples chosen
 * by the DEFAULT_SAMPLES macro from config.h (set via QUALITY), raydepth()
 * to skip the expensive part in secondary rays, output varying float and
 * color parameters, and the diffuse() built-in.
 */
#define QUALITY 0
#define FORCE_MEDIUM
#include "config.h"

surface ao_occlusion(
    float Ka = 1, Kd = .8, Kind = 1;
    float maxdist = 1e30;
    float conewidth = 1;
    output varying float occ = 0;
    output varying color indirect = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    uniform float nsamp = DEFAULT_SAMPLES;

    if (raydepth() == 0) {
        occ = occlusion(P, Nf, nsamp, "maxdist", maxdist,
                        "coneangle", conewidth * HALFPI);
        indirect = Kind * indirectdiffuse(P, Nf, nsamp);
    } else {
        occ = 0;
        indirect = 0;
    }

    color amb = Ka * (1 - occ) * ambient() + indirect;
    Oi = Os;
    Ci = Os * Cs * (amb + Kd * diffuse(Nf));
}
