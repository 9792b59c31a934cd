/*
 * stucco_dents.sl -- stucco wall displacement: scattered rounded dents
 * made by thresholding noise, optionally as a bump (normal only) rather
 * than a true displacement.  Publishes the displacement height for the
 * surface shader.
 *
 * Exercises: a displacement shader moving P along the normal and
 * recomputing N with calculatenormal(), the bump-only idiom (N from a
 * displaced copy of P), transform() to "shader" space, the vtransform
 * idiom for measuring displacement in shader units, pow() and
 * smoothstep() shaping of noise, output varying parameters read by
 * surfaces through displacement("bumpheight"), and filterwidthp().
 */
#include "filterwidth.h"

displacement stucco_dents(
    float Km = .02;
    float frequency = 6, power = 3;
    float dentsize = .6;
    float truedisp = 1;
    output varying float bumpheight = 0;
    output varying float dentmask = 0;)
{
    point Psh = transform("shader", P) * frequency;
    float fw = filterwidthp(Psh);

    /* Dents where noise exceeds a threshold, rounded by pow(). */
    float n = noise(Psh);
    float dent = pow(smoothstep(dentsize, 1, n), 1 / power);
    dent *= 1 - smoothstep(.25, .75, fw);
    dentmask = dent;

    /* Km is given in shader space: convert to current-space length. */
    normal Nn = normalize(N);
    vector Nsh = vtransform("shader", Nn);
    float kmscale = Km / max(length(Nsh), 1.0e-6);
    bumpheight = -dent * Km;

    if (truedisp > 0) {
        P += -dent * kmscale * Nn;
        N = calculatenormal(P);
    } else {
        N = calculatenormal(P - dent * kmscale * Nn);
    }
}
