/*
 * velvet_sheen.sl -- velvet and other pile fabrics: a soft retro-reflective
 * backscatter lobe, a bright sheen at grazing angles, and a dim diffuse
 * base, all from one custom illuminance loop.
 *
 * Exercises: #include by a relative path ("../include/config.h"),
 * illuminance(P, N, angle) with PI/2 from config.h, the
 * whole-sphere form illuminance(P) for light arriving from behind,
 * normalize(L), dot products, pow(), max(), += on colours inside the
 * loops, and faceforward.
 */
#include "../include/config.h"

surface velvet_sheen(
    float Ka = .05, Kd = .1, Ks = .3;
    float backscatter = .15, edginess = 10;
    float roughness = .15;
    color sheen = color(.9, .8, 1);)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color shiny = 0, back = 0;
    float cosview = max(Nf . V, 0);

    illuminance(P, Nf, PI / 2) {
        vector Ln = normalize(L);

        /* Retro-reflection: strongest when the light is behind the eye. */
        float cosine = max(Ln . V, 0);
        shiny += pow(cosine, 1 / roughness) * backscatter * Cl;

        /* Grazing sheen: fibres catch light along the silhouette. */
        float sine = sqrt(1 - cosview * cosview);
        shiny += pow(sine, edginess) * (Ln . Nf) * Cl;
    }

    /* A little light leaks through the thin pile from behind. */
    illuminance(P) {
        float behind = max(-(normalize(L) . Nf), 0);
        back += .1 * behind * Cl;
    }

    Oi = Os;
    Ci = Os * (Cs * (Ka * ambient() + Kd * diffuse(Nf) + back) + Ks * sheen * shiny);
}
