/*
 * leopard_spots.sl -- a fur-like spotted coat: each cell of a jittered
 * cellular pattern carries a rosette (a dark broken ring around a
 * slightly darker centre), with the rings broken up by noise.
 *
 * Exercises: voronoi_f1() from noises.h with its output nearest-point
 * argument, atan(y, x), cellnoise() keyed on the returned feature point,
 * snoise() and filteredsnoise() macros, filterwidth(), a user function
 * with an early return, the ?: operator, and velvet-like sheen via an
 * illuminance(P, N, angle) loop.
 */
#include "noises.h"

/* Ring profile: 1 on a ring of radius r0 and width w, 0 elsewhere. */
float ringprofile(float d, r0, w)
{
    if (w <= 0)
        return 0;
    return smoothstep(r0 - w, r0, d) * (1 - smoothstep(r0, r0 + w, d));
}

surface leopard_spots(
    float Ka = 1, Kd = .8, Ksheen = .2;
    float spotfreq = 6, jitter = .8;
    float ringradius = .28, ringwidth = .08, breakup = .5;
    color furcolor = color(.85, .62, .3);
    color centercolor = color(.7, .45, .2);
    color ringcolor = color(.12, .08, .05);)
{
    point PP = transform("shader", P) * spotfreq;
    point feature;
    float d = voronoi_f1(PP, jitter, feature);
    float fw = filterwidth(d);

    /* Each rosette has its own size and ring gaps. */
    float sizevar = .8 + .4 * float cellnoise(feature);
    float angle = atan(ycomp(PP - feature), xcomp(PP - feature));
    float gaps = filteredsnoise(point(angle * 2, float cellnoise(feature + 1) * 10, 0), fw);
    float ring = ringprofile(d, ringradius * sizevar, max(ringwidth, fw));
    ring *= (gaps > breakup - 1) ? 1 : 0;

    float centre = 1 - smoothstep(.5 * ringradius * sizevar, ringradius * sizevar, d);
    color C = mix(furcolor, centercolor, centre * .8);
    C = mix(C, ringcolor, ring);

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color sheen = 0;
    illuminance(P, Nf, PI / 2) {
        float grazing = 1 - max(0, Nf . V);
        sheen += Cl * pow(grazing, 4) * (normalize(L) . Nf);
    }

    Oi = Os;
    Ci = Os * (C * (Ka * ambient() + Kd * diffuse(Nf)) + Ksheen * sheen);
}
