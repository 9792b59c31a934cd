/*
 * leaf_translucent.sl -- a thin leaf: light from behind shines through
 * in a yellower green, a midrib and slanting side veins are drawn
 * procedurally, and the leaf picks up bounce light from its surroundings.
 *
 * Exercises: nested for loops over the two sides of the leaf and its
 * veins with "continue 2" (skip the rest of one side's veins) and
 * "break 2" (stop at the first vein hit), continue in the outer loop,
 * illuminance(P, N, angle) around the back-facing normal -Nf for
 * translucency, indirectdiffuse(P, N, samples), output varying
 * parameters, and the standard plastic terms.
 */
#include "config.h"

surface leaf_translucent(
    float Ka = .3, Kd = .7, Kt = .6, Ks = .2, roughness = .2, Kind = .4;
    float veins = 9, veinwidth = .012;
    color frontcolor = color(.18, .4, .08);
    color backcolor = color(.45, .7, .12);
    color veincolor = color(.5, .6, .3);
    output varying float veinmask = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    float side, k;
    float vein = 1 - smoothstep(veinwidth, 2 * veinwidth, abs(s - .5));

    /* Side veins leave the midrib at t = k / veins and rise towards the edge. */
    for (side = -1; side <= 1; side += 2) {
        if ((s - .5) * side < 0)
            continue;
        for (k = 1; k < veins; k += 1) {
            float tstart = k / veins;
            /* This vein and all later ones start above this point. */
            if (tstart > t)
                continue 2;
            float along = clamp(abs(s - .5) * 2, 0, 1);
            float d = abs(t - (tstart + .25 * along));
            if (d < veinwidth * (1 - .5 * along)) {
                vein = max(vein, 1 - .5 * along);
                break 2;
            }
        }
    }
    veinmask = vein;

    /* Light arriving through the back of the leaf. */
    color through = 0;
    illuminance(P, -Nf, HALFPI) {
        through += Cl * (normalize(L) . (-Nf));
    }

    color bounce = Kind * indirectdiffuse(P, Nf, DEFAULT_SAMPLES);
    color Cfront = mix(frontcolor, veincolor, vein);
    color Cback = mix(backcolor, veincolor, vein);

    Oi = Os;
    Ci = Os * (Cfront * (Ka * ambient() + Kd * diffuse(Nf) + bounce)
               + Kt * Cback * through + Ks * specular(Nf, V, roughness));
}
